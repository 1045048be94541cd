//! Sparse decomposition (guerin2016 section 4.3): the reference OMP written exactly as the
//! paper states it, and Batch-OMP (Rubinstein, Zibulevsky & Elad 2008) as the fast path.
//!
//! Conventions: the dictionary is an `(n_atoms, dim)` matrix with one unit-norm atom per **row**
//! (the transpose of the paper's `K x N` matrix `D`); signals are `(n_signals, dim)`, one per row.
//! Both solvers stop when `s` atoms are selected, when the squared residual drops to
//! [`OmpSettings::tolerance`], when the residual vanishes, or when the next atom would be
//! linearly dependent on the selected ones (the support then holds fewer than `s` atoms).
//!
//! Both solvers are deterministic: the result of a signal does not depend on the other signals
//! or on the number of rayon threads (signals are processed in fixed-size blocks).

use ndarray::{Array2, ArrayView2, s};
use rayon::prelude::*;

use relief_heightfield::{NoProgress, Progress};

pub use crate::codes::{
    MAX_ATOMS, MAX_SPARSITY, NEAREST_MIN_ATOMS, OmpFloat, OmpSettings, SparseCodes,
};
use crate::codes::{argmax_abs, validate_limit};
use crate::error::Result;

/// Number of signals per Batch-OMP block (fixed so results do not depend on the thread count).
const BLOCK: usize = 256;

/// Checks the inputs shared by both solvers.
fn validate<T: OmpFloat>(
    dict: &ArrayView2<T>,
    signals: &ArrayView2<T>,
    settings: &OmpSettings,
) -> Result<()> {
    validate_limit(dict, signals, settings, MAX_ATOMS)
}

/// Solves `A y = b` for a small symmetric positive definite `A` (row-major `m x m`) by Cholesky
/// in `f64`; `None` when `A` is not numerically positive definite.
fn spd_solve(a: &[f64], b: &[f64], m: usize) -> Option<Vec<f64>> {
    let mut l = vec![0.0f64; m * m];
    for i in 0..m {
        for j in 0..=i {
            let mut sum = a[i * m + j];
            for k in 0..j {
                sum -= l[i * m + k] * l[j * m + k];
            }
            if i == j {
                if sum <= 1e-12 * a[i * m + i].abs().max(1e-300) {
                    return None;
                }
                l[i * m + i] = sum.sqrt();
            } else {
                l[i * m + j] = sum / l[j * m + j];
            }
        }
    }
    let mut y = b.to_vec();
    for i in 0..m {
        for k in 0..i {
            y[i] -= l[i * m + k] * y[k];
        }
        y[i] /= l[i * m + i];
    }
    for i in (0..m).rev() {
        for k in i + 1..m {
            y[i] -= l[k * m + i] * y[k];
        }
        y[i] /= l[i * m + i];
    }
    Some(y)
}

/// Reference OMP, exactly as guerin2016 section 4.3 writes it (readable; the test oracle).
///
/// For each signal `T_i` the active set `Gamma` starts empty; each iteration selects
/// `(k^, beta^) = argmin_{k not in Gamma, beta} ||T_i - D_{Gamma u {k}} beta||_2^2` by solving the
/// least-squares problem of **every** candidate `k` (normal equations, Cholesky in `f64`), then
/// sets `Gamma = Gamma u {k^}`, `X_i^Gamma = beta^`. Ties go to the smallest index. It stops when
/// `|Gamma| = s`, when the squared residual is `<= tolerance`, or when it vanishes.
///
/// This literal criterion (smallest residual after the joint refit) coincides with the usual
/// "largest correlation with the residual" choice of [`batch_omp`] whenever the candidate atoms
/// are equally well separated from the span of the active set (orthogonal or well-conditioned
/// dictionaries; always at the first iteration); on coherent dictionaries the two may pick
/// different atoms. Cost is `O(N s K)` per iteration per signal: use it for tests only.
pub fn omp_reference<T: OmpFloat>(
    dict: ArrayView2<T>,
    signals: ArrayView2<T>,
    settings: &OmpSettings,
) -> Result<SparseCodes<T>> {
    validate(&dict, &signals, settings)?;
    let (n_atoms, dim) = dict.dim();
    let d: Vec<f64> = dict.iter().map(|v| v.to_f64()).collect();
    // Gram matrix in f64 (the normal equations of every candidate set are read from it).
    let mut gram = vec![0.0f64; n_atoms * n_atoms];
    for a in 0..n_atoms {
        for b in 0..=a {
            let g: f64 = (0..dim).map(|k| d[a * dim + k] * d[b * dim + k]).sum();
            gram[a * n_atoms + b] = g;
            gram[b * n_atoms + a] = g;
        }
    }
    let per_signal: Vec<(Vec<u32>, Vec<T>, T)> = signals
        .outer_iter()
        .into_par_iter()
        .map(|x| {
            let x: Vec<f64> = x.iter().map(|v| v.to_f64()).collect();
            let xx: f64 = x.iter().map(|v| v * v).sum();
            let corr: Vec<f64> = (0..n_atoms)
                .map(|a| (0..dim).map(|k| d[a * dim + k] * x[k]).sum())
                .collect();
            let mut gamma: Vec<usize> = Vec::new();
            let mut beta: Vec<f64> = Vec::new();
            let mut res = xx;
            while gamma.len() < settings.sparsity {
                if settings.tolerance.is_some_and(|t| res <= t) || res <= f64::RESIDUAL_FLOOR * xx {
                    break;
                }
                let m = gamma.len() + 1;
                let mut best: Option<(f64, usize, Vec<f64>)> = None;
                for k in 0..n_atoms {
                    if gamma.contains(&k) {
                        continue;
                    }
                    let set: Vec<usize> = gamma.iter().copied().chain([k]).collect();
                    let a: Vec<f64> = set
                        .iter()
                        .flat_map(|&p| set.iter().map(move |&q| (p, q)))
                        .map(|(p, q)| gram[p * n_atoms + q])
                        .collect();
                    let b: Vec<f64> = set.iter().map(|&p| corr[p]).collect();
                    let Some(y) = spd_solve(&a, &b, m) else {
                        continue;
                    };
                    // ||x - D_S y||^2 = ||x||^2 - b.y at the least-squares optimum.
                    let r = xx - b.iter().zip(&y).map(|(p, q)| p * q).sum::<f64>();
                    if best.as_ref().is_none_or(|(br, _, _)| r < *br) {
                        best = Some((r, k, y));
                    }
                }
                let Some((r, k, y)) = best else { break };
                gamma.push(k);
                beta = y;
                res = r.max(0.0);
            }
            let idx = gamma.iter().map(|&k| k as u32).collect();
            let val = beta.iter().map(|&v| T::from_f64(v)).collect();
            (idx, val, T::from_f64(res))
        })
        .collect();
    Ok(assemble(per_signal))
}

fn assemble<T: OmpFloat>(per_signal: Vec<(Vec<u32>, Vec<T>, T)>) -> SparseCodes<T> {
    let mut offsets = Vec::with_capacity(per_signal.len() + 1);
    offsets.push(0);
    let total: usize = per_signal.iter().map(|p| p.0.len()).sum();
    let mut indices = Vec::with_capacity(total);
    let mut values = Vec::with_capacity(total);
    let mut residuals = Vec::with_capacity(per_signal.len());
    for (i, v, r) in per_signal {
        indices.extend_from_slice(&i);
        values.extend_from_slice(&v);
        residuals.push(r);
        offsets.push(indices.len());
    }
    SparseCodes {
        offsets,
        indices,
        values,
        residuals,
    }
}

/// Per-thread scratch of Batch-OMP.
struct Scratch<T> {
    alpha0: Array2<T>,
    l: Vec<T>,
    u: Vec<T>,
    c: Vec<T>,
    gamma: Vec<T>,
    idx: Vec<usize>,
}

impl<T: OmpFloat> Scratch<T> {
    fn new(n_atoms: usize, s: usize) -> Self {
        Self {
            alpha0: Array2::from_elem((BLOCK, n_atoms), T::zero()),
            l: vec![T::zero(); s * s],
            u: vec![T::zero(); s * n_atoms],
            c: vec![T::zero(); s],
            gamma: vec![T::zero(); s],
            idx: Vec::with_capacity(s),
        }
    }
}

/// Output of one Batch-OMP block.
struct BlockOut<T> {
    counts: Vec<usize>,
    indices: Vec<u32>,
    values: Vec<T>,
    residuals: Vec<T>,
}

/// Batch-OMP (Rubinstein, Zibulevsky & Elad 2008, algorithm "Batch-OMP"): the Gram matrix
/// `G = D D^T` is computed once, the correlations `alpha0 = D x` of a block of signals by one
/// matrix product, and each iteration only updates a progressive Cholesky factor of `G_II`
/// and `alpha = alpha0 - G_I gamma` (no residual vector is ever formed). Selection is the usual
/// OMP rule `k = argmax |alpha_k|` (ties to the smallest index). The squared residual is tracked
/// as `||x||^2 - ||L^{-1} alpha0_I||^2`; each iteration costs one fused pass over the `N`
/// correlations per selected atom and `O(k)` scalar work (see `code_one`).
///
/// Runs in parallel over blocks of 256 signals with rayon, one scratch per worker; the result
/// does not depend on the thread count.
///
/// At `s = 1` with more than [`NEAREST_MIN_ATOMS`] atoms the exact nearest-atom search
/// [`crate::nearest::nearest_atom`] runs instead (same selection rule and coefficient, no Gram
/// matrix; dictionaries up to 2^22 atoms).
pub fn batch_omp<T: OmpFloat>(
    dict: ArrayView2<T>,
    signals: ArrayView2<T>,
    settings: &OmpSettings,
) -> Result<SparseCodes<T>> {
    batch_omp_with_progress(dict, signals, settings, &NoProgress)
}

/// [`batch_omp`] reporting the number of coded signals to `progress` (phase `"batch-omp"`).
pub fn batch_omp_with_progress<T: OmpFloat>(
    dict: ArrayView2<T>,
    signals: ArrayView2<T>,
    settings: &OmpSettings,
    progress: &dyn Progress,
) -> Result<SparseCodes<T>> {
    if settings.sparsity == 1 && dict.nrows() > NEAREST_MIN_ATOMS {
        return crate::nearest::nearest_atom_with_progress(dict, signals, settings, progress);
    }
    validate(&dict, &signals, settings)?;
    progress.begin("batch-omp", signals.nrows() as u64);
    let (n_atoms, _) = dict.dim();
    let s = settings.sparsity;
    let gram = dict.dot(&dict.t());
    let gram = gram.as_standard_layout();
    let gram = gram.as_slice().unwrap_or(&[]);
    let n = signals.nrows();
    let n_blocks = n.div_ceil(BLOCK);
    let tol = settings.tolerance;
    let outs: Vec<BlockOut<T>> = (0..n_blocks)
        .into_par_iter()
        .map_init(
            || Scratch::<T>::new(n_atoms, s),
            |sc, b| {
                let lo = b * BLOCK;
                let hi = (lo + BLOCK).min(n);
                let x = signals.slice(s![lo..hi, ..]);
                let mut a0 = sc.alpha0.slice_mut(s![..hi - lo, ..]);
                ndarray::linalg::general_mat_mul(T::one(), &x, &dict.t(), T::zero(), &mut a0);
                let mut out = BlockOut {
                    counts: Vec::with_capacity(hi - lo),
                    indices: Vec::with_capacity((hi - lo) * s),
                    values: Vec::with_capacity((hi - lo) * s),
                    residuals: Vec::with_capacity(hi - lo),
                };
                let block = Block {
                    x,
                    gram,
                    n_atoms,
                    s,
                    tol,
                };
                code_block_dispatch(sc, block, &mut out);
                progress.advance((hi - lo) as u64);
                out
            },
        )
        .collect();
    let mut offsets = Vec::with_capacity(n + 1);
    offsets.push(0usize);
    let total: usize = outs.iter().map(|o| o.indices.len()).sum();
    let mut indices = Vec::with_capacity(total);
    let mut values = Vec::with_capacity(total);
    let mut residuals = Vec::with_capacity(n);
    for o in outs {
        for c in o.counts {
            let last = *offsets.last().unwrap_or(&0);
            offsets.push(last + c);
        }
        indices.extend_from_slice(&o.indices);
        values.extend_from_slice(&o.values);
        residuals.extend_from_slice(&o.residuals);
    }
    Ok(SparseCodes {
        offsets,
        indices,
        values,
        residuals,
    })
}

/// A block of signals `x` to code (their correlations already in `sc.alpha0`) and what every
/// row is coded with: the Gram matrix of the `n_atoms` atoms (row-major), the sparsity `s` and
/// the optional residual tolerance.
#[derive(Clone, Copy)]
struct Block<'a, T> {
    x: ArrayView2<'a, T>,
    gram: &'a [T],
    n_atoms: usize,
    s: usize,
    tol: Option<f64>,
}

/// Codes every row of the block.
#[inline(always)]
fn code_block<T: OmpFloat>(sc: &mut Scratch<T>, block: Block<'_, T>, out: &mut BlockOut<T>) {
    for r in 0..block.x.nrows() {
        let xx = block.x.row(r).iter().fold(T::zero(), |acc, &v| acc + v * v);
        code_one(sc, r, xx, block, out);
    }
}

crate::avx2_dispatch! {
    /// [`code_block`], compiled with AVX2 where the CPU has it (wider vectors for the O(N)
    /// passes; bit-identical results, see [`avx2_dispatch!`](crate::avx2_dispatch)).
    fn code_block_dispatch[T: OmpFloat](
        sc: &mut Scratch<T>,
        block: Block<'_, T>,
        out: &mut BlockOut<T>,
    ) => code_block;
}

/// Codes row `r` of the block held in `sc.alpha0`.
///
/// Progressive Cholesky `G_II = L L^T` with the rows `u_m = (L^{-1} G_{I,:})_m` kept: the new
/// Cholesky row `w = L^{-1} G_{I,k}` is then read off as `w_m = u_m[k]` (no triangular solve),
/// `c = L^{-1} alpha0_I` grows by one forward-substitution step, the correlations follow from
/// `alpha = alpha0 - G_{:,I} gamma = alpha0 - sum_m c_m u_m` (one fused pass per iteration), the
/// squared residual is `||x||^2 - ||c||^2`, and `gamma = L^{-T} c` is solved once at the end.
#[inline(always)]
fn code_one<T: OmpFloat>(
    sc: &mut Scratch<T>,
    r: usize,
    xx: T,
    block: Block<'_, T>,
    out: &mut BlockOut<T>,
) {
    let Block {
        gram,
        n_atoms: n,
        s,
        tol,
        ..
    } = block;
    let Scratch {
        alpha0,
        l,
        u,
        c,
        gamma,
        idx,
    } = sc;
    // The correlations are updated in place: after k selections the row holds
    // `alpha = alpha0 - sum_m c_m u_m`, and `c_k = alpha[best] / l_kk`.
    let mut row = alpha0.row_mut(r);
    let Some(alpha) = row.as_slice_mut() else {
        return;
    };
    idx.clear();
    let floor = T::from_f64(T::RESIDUAL_FLOOR) * xx;
    let tol_t = tol.map(T::from_f64);
    let mut res = xx;
    let mut k = 0usize;
    while k < s {
        if res <= floor || tol_t.is_some_and(|t| res <= t) {
            break;
        }
        // Selection: largest |alpha| (ties: smallest index). Selected atoms have alpha set to
        // exactly 0 after each update, so they are never picked again.
        let Some(best) = argmax_abs(alpha) else {
            break;
        };
        let gjj = gram[best * n + best];
        let mut ww = T::zero();
        for m in 0..k {
            let w = u[m * n + best];
            l[k * s + m] = w;
            ww += w * w;
        }
        let piv = gjj - ww;
        if piv <= T::from_f64(T::PIVOT_FLOOR) * gjj {
            // The atom is (numerically) in the span of the selected ones.
            break;
        }
        let lkk = piv.sqrt();
        l[k * s + k] = lkk;
        // c_k = (alpha0[best] - sum_m w_m c_m) / l_kk, and the bracket is alpha[best].
        let cv = alpha[best] / lkk;
        c[k] = cv;
        idx.push(best);
        res -= cv * cv;
        if res < T::zero() {
            res = T::zero();
        }
        k += 1;
        if k < s {
            // u_k = (G_{best,:} - sum_m w_m u_m) / l_kk, then alpha -= c_k u_k.
            let (done, rest) = u.split_at_mut((k - 1) * n);
            let uk = &mut rest[..n];
            let grow = &gram[best * n..(best + 1) * n];
            let inv = T::one() / lkk;
            if k == 1 {
                for ((o, al), &g) in uk.iter_mut().zip(alpha.iter_mut()).zip(grow) {
                    let v = g * inv;
                    *o = v;
                    *al -= cv * v;
                }
            } else {
                let w0 = l[(k - 1) * s];
                for ((o, &g), &x) in uk.iter_mut().zip(grow).zip(&done[..n]) {
                    *o = g - w0 * x;
                }
                for m in 1..k - 1 {
                    let w = l[(k - 1) * s + m];
                    for (o, &x) in uk.iter_mut().zip(&done[m * n..(m + 1) * n]) {
                        *o -= w * x;
                    }
                }
                for (o, al) in uk.iter_mut().zip(alpha.iter_mut()) {
                    let v = *o * inv;
                    *o = v;
                    *al -= cv * v;
                }
            }
            for &j in idx.iter() {
                alpha[j] = T::zero();
            }
        }
    }
    // gamma = L^{-T} c.
    for i in (0..k).rev() {
        let mut v = c[i];
        for m in i + 1..k {
            v -= l[m * s + i] * gamma[m];
        }
        gamma[i] = v / l[i * s + i];
    }
    out.counts.push(k);
    out.indices.extend(idx.iter().map(|&j| j as u32));
    out.values.extend_from_slice(&gamma[..k]);
    out.residuals.push(res);
}
