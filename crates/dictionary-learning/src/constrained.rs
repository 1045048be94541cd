//! Constrained dictionary learning (guerin2016 section 4.4, problem (2)): every atom must be
//! one of the candidate terrain patches.
//!
//! The coding step is Batch-OMP, as in K-SVD. The update replaces atom `j` by the candidate `c`
//! (unit norm) minimising problem (2)'s objective with the other atoms and the sparsity pattern
//! fixed: with `E_j` the error of the users of `j` computed without `j`, the best coefficients
//! are `x = E_j c` and the objective is `||E_j||_F^2 - ||E_j c||^2`, so the substitute is
//! `argmax_c ||E_j c||^2`. The scores of ALL candidates are computed at once as the matrix
//! product `E_j C^T` (faer GEMM, `m x M`), or as `C (E_j^T E_j) . C` when the atom has more
//! users than the signal dimension, in fixed-size candidate blocks run in parallel (the result
//! does not depend on the thread count). The current atom is a candidate, so the objective
//! never increases during an update.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};
use ndarray::{Array2, ArrayView2};
use rand::SeedableRng;
use rand::seq::index::sample;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use relief_heightfield::Progress;
use relief_sparse_core::{OmpSettings, batch_omp};

use crate::error::{LearnError, Result};
use crate::ksvd::{
    CodeTable, IterationStats, LearnedDictionary, check_signals, codes_rmse, finish_learning,
    row_norms_sq,
};
use crate::noise::item_seed;

/// Settings of [`constrained_learning`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstrainedSettings {
    /// Number of atoms `N`.
    pub n_atoms: usize,
    /// Target sparsity `s`.
    pub sparsity: usize,
    /// Number of (coding, update) iterations.
    pub iterations: usize,
    /// Seed of the random initialisation (distinct random candidates).
    pub seed: u64,
}

impl Default for ConstrainedSettings {
    fn default() -> Self {
        Self {
            n_atoms: 256,
            sparsity: 1,
            iterations: 5,
            seed: 0,
        }
    }
}

const BLOCK: usize = 1024;

/// Scores `||E c||^2` of every candidate row of `cand` (unit rows, `M x K`). The products run
/// in `f32` (twice the throughput of `f64`; the scores only rank candidates, to about 1e-6),
/// the Gram matrix and the sums of products in `f64`.
fn candidate_scores(e: &Array2<f64>, cand: &Mat<f32>) -> Vec<f64> {
    let (m, k) = e.dim();
    let n_cand = cand.nrows();
    let e_mat = match e.as_slice() {
        Some(v) => Mat::<f64>::from_fn(m, k, |i, c| v[i * k + c]),
        None => Mat::<f64>::from_fn(m, k, |i, c| e[(i, c)]),
    };
    // m > K: C (E^T E), then the row-wise dot with C; else C E^T and its squared rows.
    let right = if m > k {
        let mut g = Mat::<f64>::zeros(k, k);
        matmul(
            g.as_mut(),
            Accum::Replace,
            e_mat.transpose(),
            e_mat.as_ref(),
            1.0,
            Par::Seq,
        );
        Mat::<f32>::from_fn(k, k, |r, c| g[(r, c)] as f32)
    } else {
        Mat::<f32>::from_fn(k, m, |r, c| e_mat[(c, r)] as f32)
    };
    let gram = m > k;
    let n_blocks = n_cand.div_ceil(BLOCK);
    let parts: Vec<Vec<f64>> = (0..n_blocks)
        .into_par_iter()
        .map(|b| {
            let r0 = b * BLOCK;
            let r1 = (r0 + BLOCK).min(n_cand);
            let c = cand.as_ref().subrows(r0, r1 - r0);
            let mut prod = Mat::<f32>::zeros(r1 - r0, right.ncols());
            matmul(
                prod.as_mut(),
                Accum::Replace,
                c,
                right.as_ref(),
                1.0,
                Par::Seq,
            );
            // Accumulated column by column (both matrices are column-major: contiguous).
            let mut acc = vec![0.0f64; r1 - r0];
            for t in 0..right.ncols() {
                let a = prod.col_as_slice(t);
                if gram {
                    match c.col(t).try_as_col_major().map(|v| v.as_slice()) {
                        Some(b) => acc
                            .iter_mut()
                            .zip(a.iter().zip(b))
                            .for_each(|(s, (x, y))| *s += *x as f64 * *y as f64),
                        None => acc
                            .iter_mut()
                            .enumerate()
                            .for_each(|(i, s)| *s += a[i] as f64 * c[(i, t)] as f64),
                    }
                } else {
                    acc.iter_mut()
                        .zip(a)
                        .for_each(|(s, x)| *s += *x as f64 * *x as f64);
                }
            }
            acc
        })
        .collect();
    parts.concat()
}

/// Learns a dictionary of `n_atoms` atoms taken among the rows of `candidates` (`M x K`,
/// mean-removed patches; they are normalised here) so as to sparsely code `signals` (`n x K`).
/// `result.sources[j]` is the candidate row that atom `j` is.
pub fn constrained_learning(
    signals: ArrayView2<f32>,
    candidates: ArrayView2<f32>,
    settings: &ConstrainedSettings,
    progress: &dyn Progress,
) -> Result<LearnedDictionary> {
    check_signals(&signals)?;
    check_signals(&candidates)?;
    let s = settings;
    crate::ksvd::check_sizes(s.n_atoms, s.sparsity, s.iterations)?;
    if candidates.ncols() != signals.ncols() {
        return Err(LearnError::param(
            "candidates",
            candidates.ncols(),
            "candidate dimension must equal the signal dimension",
        ));
    }
    let k = signals.ncols();
    let cn = row_norms_sq(&candidates);
    let usable: Vec<usize> = (0..candidates.nrows()).filter(|&i| cn[i] > 1e-20).collect();
    if usable.len() < s.n_atoms {
        return Err(LearnError::NotEnough {
            what: "candidate patches with energy",
            needed: s.n_atoms,
            got: usable.len(),
        });
    }
    // Unit-norm usable candidates as a faer matrix (rows).
    let cand = Mat::<f32>::from_fn(usable.len(), k, |i, c| {
        (candidates[(usable[i], c)] as f64 / cn[usable[i]].sqrt()) as f32
    });
    let mut rng = Pcg64Mcg::seed_from_u64(item_seed(s.seed, 0xc0, 0));
    let mut chosen: Vec<usize> = sample(&mut rng, usable.len(), s.n_atoms).into_vec();
    chosen.sort_unstable();
    let mut in_dict = vec![false; usable.len()];
    chosen.iter().for_each(|&c| in_dict[c] = true);
    let build =
        |chosen: &[usize]| Array2::from_shape_fn((chosen.len(), k), |(j, c)| cand[(chosen[j], c)]);
    let mut atoms = build(&chosen);
    let omp = OmpSettings {
        sparsity: s.sparsity,
        tolerance: None,
    };
    let mut trace = Vec::new();
    progress.begin("constrained learning", s.iterations as u64);
    let stop =
        |it: usize| crate::ksvd::stop_if_asked(progress, "constrained learning", it, s.iterations);
    for it in 0..s.iterations {
        stop(it)?;
        let codes = batch_omp(atoms.view(), signals, &omp)?;
        stop(it)?;
        let rmse = codes_rmse(&codes, k);
        let mut table = CodeTable::new(&codes, s.n_atoms);
        let mut replaced = 0;
        // Unused atoms: the error restricted to no user is empty, so every candidate scores 0.
        // Substitute the candidate closest to the worst-represented signal instead.
        let worst = crate::ksvd::worst_signals(&codes, &row_norms_sq(&signals));
        let mut next_worst = 0;
        for j in 0..s.n_atoms {
            if j % 64 == 63 {
                stop(it)?;
            }
            let scores = if table.users[j].is_empty() {
                let Some(&w) = worst.get(next_worst) else {
                    continue;
                };
                next_worst += 1;
                let e = signals
                    .row(w)
                    .mapv(|v| v as f64)
                    .insert_axis(ndarray::Axis(0))
                    .to_owned();
                candidate_scores(&e, &cand)
            } else {
                let e = table.restricted_error(j, &signals, &atoms);
                candidate_scores(&e, &cand)
            };
            let cur = chosen[j];
            let mut best = cur;
            let mut best_score = if table.users[j].is_empty() {
                f64::NEG_INFINITY
            } else {
                scores[cur]
            };
            for (c, &sc) in scores.iter().enumerate() {
                if !in_dict[c] && sc > best_score * (1.0 + 1e-12) {
                    best = c;
                    best_score = sc;
                }
            }
            if best != cur {
                in_dict[cur] = false;
                in_dict[best] = true;
                chosen[j] = best;
                atoms
                    .row_mut(j)
                    .iter_mut()
                    .enumerate()
                    .for_each(|(c, o)| *o = cand[(best, c)]);
                replaced += 1;
            }
            if !table.users[j].is_empty() {
                // Optimal coefficients of the users on the (possibly new) atom: x = E_j c.
                let e = table.restricted_error(j, &signals, &atoms);
                let x: Vec<f64> = e
                    .outer_iter()
                    .map(|r| r.iter().zip(atoms.row(j)).map(|(a, &b)| a * b as f64).sum())
                    .collect();
                table.set_coefs(j, &x);
            }
        }
        trace.push(IterationStats { rmse, replaced });
        progress.advance(1);
    }
    let sources = chosen.iter().map(|&c| usable[c]).collect();
    finish_learning(atoms, signals, &omp, trace, sources)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gemm_scores_match_scalar_objective() {
        // Both code paths (m < K: E C^T; m > K: C (E^T E) . C) against a scalar loop.
        for m in [3usize, 40] {
            let k = 9;
            let e = Array2::from_shape_fn((m, k), |(i, c)| ((i * 7 + c * 3) % 11) as f64 - 5.0);
            let cand = Mat::<f32>::from_fn(1500, k, |i, c| {
                (((i * 13 + c * 5) % 17) as f32 - 8.0) / 20.0
            });
            let s = candidate_scores(&e, &cand);
            for ci in [0usize, 17, 1499] {
                let mut want = 0.0;
                for r in 0..m {
                    let d: f64 = (0..k).map(|c| e[(r, c)] * cand[(ci, c)] as f64).sum();
                    want += d * d;
                }
                assert!((s[ci] - want).abs() <= 1e-5 * want.max(1.0), "{m} {ci}");
            }
        }
    }
}
