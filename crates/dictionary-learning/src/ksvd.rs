//! K-SVD dictionary learning (Aharon, Elad & Bruckstein 2006; guerin2016 section 4.4,
//! problem (1)) and its approximate variant (Rubinstein, Zibulevsky & Elad 2008).
//!
//! Signals and atoms are rows (`n x K` and `N x K`), the transpose of the paper's `F` and `D`.
//! Each iteration codes every signal with Batch-OMP (`relief_sparse_core::batch_omp`), then
//! updates the atoms one after the other, keeping the sparsity pattern fixed:
//! * exact: `d_j, x_j` = the rank-1 SVD (faer) of the error `E_j` restricted to the signals
//!   using atom `j`, computed without atom `j`;
//! * approximate: one power-iteration step from the current coefficients,
//!   `d = E_j x_j / ||E_j x_j||`, `x_j = E_j^T d` (never forms an SVD).
//!
//! Atoms used by nobody, and atoms that became near-duplicates of an earlier atom
//! (`|<d_j, d_k>| > duplicate_threshold`), are replaced by the worst-represented training
//! signals (largest OMP residual), normalised.

use ndarray::{Array2, ArrayView2};
use rand::SeedableRng;
use rand::seq::index::sample;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use relief_heightfield::Progress;
use relief_sparse_core::{OmpSettings, SparseCodes, batch_omp};

use crate::error::{LearnError, Result};
use crate::noise::item_seed;

/// Which atom update K-SVD performs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KsvdVariant {
    /// Rank-1 SVD of the restricted error (Aharon et al. 2006), via faer.
    Exact,
    /// One power-iteration step (Rubinstein et al. 2008, "approximate K-SVD").
    #[default]
    Approximate,
}

/// Largest number of learning iterations accepted (K-SVD and constrained learning): far
/// beyond convergence (the paper uses tens), small enough that a typo cannot run for days.
pub const MAX_ITERATIONS: usize = 10_000;

/// Settings of [`ksvd`] (serde: missing fields take these defaults, unknown ones are an error).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct KsvdSettings {
    /// Number of atoms `N`.
    pub n_atoms: usize,
    /// Target sparsity `s` of the coding step.
    pub sparsity: usize,
    /// Number of (coding, update) iterations (at most [`MAX_ITERATIONS`]).
    pub iterations: usize,
    /// Atom update rule.
    pub variant: KsvdVariant,
    /// Seed of the random initialisation (random distinct training signals).
    pub seed: u64,
    /// Atoms whose |cosine| with an earlier atom exceeds this are replaced (in `(0, 1]`).
    pub duplicate_threshold: f64,
}

impl Default for KsvdSettings {
    fn default() -> Self {
        Self {
            n_atoms: 256,
            sparsity: 4,
            iterations: 10,
            variant: KsvdVariant::Approximate,
            seed: 0,
            duplicate_threshold: 0.99,
        }
    }
}

/// The checks shared by K-SVD and the constrained variant: at least one atom, at most
/// [`MAX_ITERATIONS`] iterations, a sparsity in `1..=min(64, n_atoms)`.
pub(crate) fn check_sizes(n_atoms: usize, sparsity: usize, iterations: usize) -> Result<()> {
    if n_atoms == 0 {
        return Err(LearnError::param("n_atoms", n_atoms, "must be >= 1"));
    }
    if iterations > MAX_ITERATIONS {
        return Err(LearnError::param(
            "iterations",
            iterations,
            "must be at most 10000",
        ));
    }
    if sparsity == 0 || sparsity > n_atoms || sparsity > 64 {
        return Err(LearnError::param(
            "sparsity",
            sparsity,
            "must be in 1..=min(64, n_atoms)",
        ));
    }
    Ok(())
}

impl KsvdSettings {
    /// Validates the settings against `n` training signals.
    pub fn check(&self, n: usize) -> Result<()> {
        check_sizes(self.n_atoms, self.sparsity, self.iterations)?;
        if !(self.duplicate_threshold > 0.0 && self.duplicate_threshold <= 1.0) {
            return Err(LearnError::param(
                "duplicate_threshold",
                self.duplicate_threshold,
                "must be in (0, 1]",
            ));
        }
        if n < self.n_atoms {
            return Err(LearnError::NotEnough {
                what: "training signals (n >= n_atoms)",
                needed: self.n_atoms,
                got: n,
            });
        }
        Ok(())
    }
}

/// One entry of the error trace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IterationStats {
    /// RMSE per coefficient of the coding step, `sqrt(||F - D X||_F^2 / (n K))`.
    pub rmse: f64,
    /// Atoms replaced in the update that followed (unused or duplicate).
    pub replaced: usize,
}

/// Output of [`ksvd`] and [`crate::constrained::constrained_learning`].
#[derive(Debug, Clone)]
pub struct LearnedDictionary {
    /// `N x K` unit-norm atoms, one per row.
    pub atoms: Array2<f32>,
    /// Codes of the training signals on the final dictionary.
    pub codes: SparseCodes<f32>,
    /// Error trace: one entry per iteration (coding error before that iteration's update),
    /// plus a last entry for the final coding.
    pub trace: Vec<IterationStats>,
    /// For constrained learning: index of the candidate each atom is (else empty).
    pub sources: Vec<usize>,
}

/// Checks a signal matrix: non-empty, finite.
pub(crate) fn check_signals(signals: &ArrayView2<f32>) -> Result<()> {
    if signals.nrows() == 0 || signals.ncols() == 0 {
        return Err(LearnError::NotEnough {
            what: "training signals",
            needed: 1,
            got: signals.nrows(),
        });
    }
    for (i, r) in signals.outer_iter().enumerate() {
        if r.iter().any(|v| !v.is_finite()) {
            return Err(LearnError::NonFinite {
                what: "training signals",
                row: i,
            });
        }
    }
    Ok(())
}

/// Squared L2 norms of the rows.
pub(crate) fn row_norms_sq(m: &ArrayView2<f32>) -> Vec<f64> {
    m.outer_iter()
        .map(|r| r.iter().map(|&v| v as f64 * v as f64).sum())
        .collect()
}

/// Mutable sparse codes with a per-atom user index, for the sequential atom updates.
pub(crate) struct CodeTable {
    pub(crate) idx: Vec<Vec<u32>>,
    pub(crate) val: Vec<Vec<f32>>,
    pub(crate) users: Vec<Vec<(u32, u8)>>,
}

impl CodeTable {
    pub(crate) fn new(codes: &SparseCodes<f32>, n_atoms: usize) -> Self {
        let n = codes.n_signals();
        let mut idx = Vec::with_capacity(n);
        let mut val = Vec::with_capacity(n);
        let mut users = vec![Vec::new(); n_atoms];
        for i in 0..n {
            let (ix, vx) = codes.signal(i);
            for (slot, &j) in ix.iter().enumerate() {
                users[j as usize].push((i as u32, slot as u8));
            }
            idx.push(ix.to_vec());
            val.push(vx.to_vec());
        }
        Self { idx, val, users }
    }

    /// Restricted error `E_j`: for every user of atom `j`, the signal minus the contribution
    /// of its other atoms (`m x K`, f64).
    pub(crate) fn restricted_error(
        &self,
        j: usize,
        signals: &ArrayView2<f32>,
        atoms: &Array2<f32>,
    ) -> Array2<f64> {
        let users = &self.users[j];
        let k = signals.ncols();
        let mut e = Array2::<f64>::zeros((users.len(), k));
        e.axis_chunks_iter_mut(ndarray::Axis(0), 64)
            .into_par_iter()
            .enumerate()
            .for_each(|(c, mut chunk)| {
                for (r, mut row) in chunk.outer_iter_mut().enumerate() {
                    let (sig, _) = users[c * 64 + r];
                    let sig = sig as usize;
                    row.iter_mut()
                        .zip(signals.row(sig))
                        .for_each(|(o, &y)| *o = y as f64);
                    for (&a, &x) in self.idx[sig].iter().zip(&self.val[sig]) {
                        if a as usize == j {
                            continue;
                        }
                        let x = x as f64;
                        row.iter_mut()
                            .zip(atoms.row(a as usize))
                            .for_each(|(o, &d)| *o -= x * d as f64);
                    }
                }
            });
        e
    }

    pub(crate) fn set_coefs(&mut self, j: usize, x: &[f64]) {
        for (&(sig, slot), &v) in self.users[j].iter().zip(x) {
            self.val[sig as usize][slot as usize] = v as f32;
        }
    }
}

/// RMSE per coefficient from the OMP residuals.
pub(crate) fn codes_rmse(codes: &SparseCodes<f32>, dim: usize) -> f64 {
    let n = codes.n_signals();
    let s: f64 = (0..n).map(|i| codes.residual_sq(i).max(0.0) as f64).sum();
    (s / (n * dim).max(1) as f64).sqrt()
}

/// The last step of every learner: codes the signals on the final atoms, closes the trace with
/// their error and assembles the result.
pub(crate) fn finish_learning(
    atoms: Array2<f32>,
    signals: ArrayView2<f32>,
    omp: &OmpSettings,
    mut trace: Vec<IterationStats>,
    sources: Vec<usize>,
) -> Result<LearnedDictionary> {
    let codes = batch_omp(atoms.view(), signals, omp)?;
    trace.push(IterationStats {
        rmse: codes_rmse(&codes, signals.ncols()),
        replaced: 0,
    });
    Ok(LearnedDictionary {
        atoms,
        codes,
        trace,
        sources,
    })
}

/// Indices of signals sorted by decreasing OMP residual (ties: lower index first).
pub(crate) fn worst_signals(codes: &SparseCodes<f32>, norms_sq: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..codes.n_signals())
        .filter(|&i| norms_sq[i] > 1e-20)
        .collect();
    order.sort_by(|&a, &b| {
        let (ra, rb) = (codes.residual_sq(a), codes.residual_sq(b));
        rb.partial_cmp(&ra)
            .unwrap_or(std::cmp::Ordering::Equal)
            .then(a.cmp(&b))
    });
    order
}

fn set_row_normalised(atoms: &mut Array2<f32>, j: usize, v: ndarray::ArrayView1<f32>) -> bool {
    let n: f64 = v.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt();
    if n <= 1e-12 {
        return false;
    }
    atoms
        .row_mut(j)
        .iter_mut()
        .zip(v)
        .for_each(|(o, &x)| *o = (x as f64 / n) as f32);
    true
}

/// Random initial dictionary: `n_atoms` distinct signals with energy, normalised.
pub fn init_from_signals(
    signals: ArrayView2<f32>,
    n_atoms: usize,
    seed: u64,
) -> Result<Array2<f32>> {
    check_signals(&signals)?;
    let norms = row_norms_sq(&signals);
    let usable: Vec<usize> = (0..signals.nrows()).filter(|&i| norms[i] > 1e-20).collect();
    if usable.len() < n_atoms {
        return Err(LearnError::NotEnough {
            what: "signals with energy for the initial dictionary",
            needed: n_atoms,
            got: usable.len(),
        });
    }
    let mut rng = Pcg64Mcg::seed_from_u64(item_seed(seed, 0x1417, 0));
    let mut pick: Vec<usize> = sample(&mut rng, usable.len(), n_atoms).into_vec();
    pick.sort_unstable();
    let mut atoms = Array2::zeros((n_atoms, signals.ncols()));
    for (j, &p) in pick.iter().enumerate() {
        set_row_normalised(&mut atoms, j, signals.row(usable[p]));
    }
    Ok(atoms)
}

/// Rank-1 approximation of `e` (`m x K`): returns `(d, x)` with `||d|| = 1` and `e ~ x d^T`.
fn rank1(
    e: &Array2<f64>,
    variant: KsvdVariant,
    x0: &[f64],
    atom: usize,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let (m, k) = e.dim();
    match variant {
        KsvdVariant::Exact => {
            let mat = faer::Mat::<f64>::from_fn(m, k, |i, c| e[(i, c)]);
            let svd = mat.thin_svd().map_err(|_| LearnError::Svd { atom })?;
            let s0 = svd.S().column_vector()[0];
            let d: Vec<f64> = (0..k).map(|c| svd.V()[(c, 0)]).collect();
            let x: Vec<f64> = (0..m).map(|i| svd.U()[(i, 0)] * s0).collect();
            Ok((d, x))
        }
        KsvdVariant::Approximate => {
            let mut d = vec![0.0f64; k];
            for (row, &g) in e.outer_iter().zip(x0) {
                d.iter_mut().zip(row).for_each(|(o, &v)| *o += g * v);
            }
            let n = d.iter().map(|v| v * v).sum::<f64>().sqrt();
            if n <= 1e-300 {
                return Err(LearnError::Svd { atom });
            }
            d.iter_mut().for_each(|v| *v /= n);
            let x = e
                .outer_iter()
                .map(|row| row.iter().zip(&d).map(|(a, b)| a * b).sum())
                .collect();
            Ok((d, x))
        }
    }
}

/// Updates every atom in turn (K-SVD step 2); returns the number of atoms replaced.
pub(crate) fn replace_unused_and_duplicates(
    atoms: &mut Array2<f32>,
    table: &CodeTable,
    signals: &ArrayView2<f32>,
    worst: &[usize],
    threshold: f64,
) -> usize {
    let n_atoms = atoms.nrows();
    let mut next = 0usize;
    let mut replaced = 0;
    let gram = atoms.dot(&atoms.t());
    for j in 0..n_atoms {
        let dup = (0..j).any(|k| (gram[(j, k)] as f64).abs() > threshold);
        if table.users[j].is_empty() || dup {
            while next < worst.len() {
                let cand = worst[next];
                next += 1;
                if set_row_normalised(atoms, j, signals.row(cand)) {
                    replaced += 1;
                    break;
                }
            }
        }
    }
    replaced
}

/// `Stopped` when `progress` asks the work to stop (its time budget ran out, or Ctrl-C from
/// Python), naming `what` and the iteration: the learning loops ask before every iteration,
/// after its coding and every 64 atoms.
pub(crate) fn stop_if_asked(
    progress: &dyn Progress,
    what: &str,
    it: usize,
    iterations: usize,
) -> Result<()> {
    progress
        .check_stop(|| LearnError::Stopped(format!("{what}, iteration {} of {iterations}", it + 1)))
}

/// K-SVD on `signals` (`n x K`, rows already mean-removed) from a random initialisation.
pub fn ksvd(
    signals: ArrayView2<f32>,
    settings: &KsvdSettings,
    progress: &dyn Progress,
) -> Result<LearnedDictionary> {
    settings.check(signals.nrows())?;
    let init = init_from_signals(signals, settings.n_atoms, settings.seed)?;
    ksvd_from(signals, init, settings, progress)
}

/// K-SVD from a given initial dictionary (`N x K`, rows are normalised here). Use it to learn
/// dictionaries mixing data and analytic atoms: rows `fixed` are kept unchanged (e.g. the
/// discretised function atoms), the others are learned.
pub fn ksvd_from(
    signals: ArrayView2<f32>,
    init: Array2<f32>,
    settings: &KsvdSettings,
    progress: &dyn Progress,
) -> Result<LearnedDictionary> {
    ksvd_with_fixed(signals, init, &[], settings, progress)
}

/// [`ksvd_from`] where atoms whose index is in `fixed` are never updated nor replaced.
pub fn ksvd_with_fixed(
    signals: ArrayView2<f32>,
    mut atoms: Array2<f32>,
    fixed: &[usize],
    settings: &KsvdSettings,
    progress: &dyn Progress,
) -> Result<LearnedDictionary> {
    check_signals(&signals)?;
    let s = KsvdSettings {
        n_atoms: atoms.nrows(),
        ..*settings
    };
    s.check(signals.nrows())?;
    if atoms.ncols() != signals.ncols() {
        return Err(LearnError::param(
            "init",
            format!("{} columns", atoms.ncols()),
            "initial atoms must have the signal dimension",
        ));
    }
    for j in 0..atoms.nrows() {
        let r = atoms.row(j).to_owned();
        if r.iter().any(|v| !v.is_finite()) || !set_row_normalised(&mut atoms, j, r.view()) {
            return Err(LearnError::param(
                "init",
                j,
                "initial atom is zero or not finite",
            ));
        }
    }
    let is_fixed = {
        let mut f = vec![false; atoms.nrows()];
        for &j in fixed {
            if j >= f.len() {
                return Err(LearnError::param("fixed", j, "atom index out of range"));
            }
            f[j] = true;
        }
        f
    };
    let norms = row_norms_sq(&signals);
    let omp = OmpSettings {
        sparsity: s.sparsity,
        tolerance: None,
    };
    let dim = signals.ncols();
    let mut trace = Vec::with_capacity(s.iterations + 1);
    progress.begin("k-svd", s.iterations as u64);
    let stop = |it: usize| stop_if_asked(progress, "k-svd", it, s.iterations);
    for it in 0..s.iterations {
        stop(it)?;
        let codes = batch_omp(atoms.view(), signals, &omp)?;
        stop(it)?;
        let rmse = codes_rmse(&codes, dim);
        let mut table = CodeTable::new(&codes, atoms.nrows());
        for j in 0..atoms.nrows() {
            if j % 64 == 63 {
                stop(it)?;
            }
            if table.users[j].is_empty() || is_fixed[j] {
                continue;
            }
            let e = table.restricted_error(j, &signals, &atoms);
            let x0: Vec<f64> = table.users[j]
                .iter()
                .map(|&(sig, slot)| table.val[sig as usize][slot as usize] as f64)
                .collect();
            let Ok((d, x)) = rank1(&e, s.variant, &x0, j) else {
                continue;
            };
            atoms
                .row_mut(j)
                .iter_mut()
                .zip(&d)
                .for_each(|(o, &v)| *o = v as f32);
            table.set_coefs(j, &x);
        }
        let worst = worst_signals(&codes, &norms);
        let replaced = if fixed.is_empty() {
            replace_unused_and_duplicates(
                &mut atoms,
                &table,
                &signals,
                &worst,
                s.duplicate_threshold,
            )
        } else {
            let mut t2 = CodeTable {
                idx: Vec::new(),
                val: Vec::new(),
                users: table.users.clone(),
            };
            // Fixed atoms never count as unused, so they are never replaced.
            for &j in fixed {
                if t2.users[j].is_empty() {
                    t2.users[j].push((0, 0));
                }
            }
            let before = atoms.clone();
            let r = replace_unused_and_duplicates(
                &mut atoms,
                &t2,
                &signals,
                &worst,
                s.duplicate_threshold,
            );
            for &j in fixed {
                atoms.row_mut(j).assign(&before.row(j));
            }
            r
        };
        trace.push(IterationStats { rmse, replaced });
        progress.advance(1);
    }
    finish_learning(atoms, signals, &omp, trace, Vec::new())
}
