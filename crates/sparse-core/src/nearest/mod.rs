//! Exact `s = 1` coding for large dictionaries (guerin2016 section 5.3: complete dictionaries of
//! 60,000-120,000 atoms).
//!
//! At `s = 1` OMP selects the atom of largest `|<d, x>|` (the atoms have unit norm) and its
//! coefficient `<d, x> / ||d||^2`; no Gram matrix is needed (Batch-OMP's `N x N` Gram matrix
//! alone would take 16 GiB at 65,536 atoms). [`nearest_atom`] computes the correlations of a
//! block of 256 signals with a block of 4096 atoms by one matrix product (the same kernel as
//! Batch-OMP's `alpha0`), keeps the running arg-max per signal (strict `>`: ties go to the
//! smallest index, as in Batch-OMP), and moves on to the next atom block; memory stays at one
//! `256 x 4096` buffer per worker whatever the dictionary size.
//!
//! A cluster index (spherical k-means, bound `|<c, x>| + r ||x||`) was tried first: on 8 x 8
//! terrain patches the cluster radii are so large (64 dimensions) that the bound pruned almost
//! nothing, and the per-signal scan was about 7x slower than this blocked product (34 s vs
//! 5 s for 16,384 signals and 65,536 atoms, `omp_large` bench).
//!
//! Deterministic: a signal's result depends only on the signal and the dictionary (fixed
//! blocks), not on the batch or the thread count.

use ndarray::{Array2, ArrayView2, s};
use rayon::prelude::*;

use relief_heightfield::Progress;

use crate::error::Result;

mod index;
use crate::codes::{OmpFloat, OmpSettings, SparseCodes, argmax_abs, validate_limit};
pub use index::{AtomIndex, AtomIndexSettings};

/// Largest dictionary [`nearest_atom`] accepts (2^22 atoms; indices stay exact in `f32`).
pub const MAX_NEAREST_ATOMS: usize = 1 << 22;

/// Signals per block.
const SIG_BLOCK: usize = 256;

/// Atoms per block (one `SIG_BLOCK x ATOM_BLOCK` correlation buffer per worker).
const ATOM_BLOCK: usize = 4096;

/// Per-signal output: `(atom, coefficient)` or none, and the squared residual.
pub(super) type Coded<T> = (Option<(u32, T)>, T);

/// Codes one block of signals.
fn code_block<T: OmpFloat>(
    dict: &ArrayView2<T>,
    norm2: &[T],
    x: ArrayView2<T>,
    tol: Option<f64>,
    buf: &mut Array2<T>,
) -> Vec<Coded<T>> {
    let n_atoms = dict.nrows();
    let m = x.nrows();
    // (|alpha|, atom, alpha) of the best atom so far.
    let mut best: Vec<(T, usize, T)> = vec![(T::zero(), usize::MAX, T::zero()); m];
    let mut a0 = 0;
    while a0 < n_atoms {
        let a1 = (a0 + ATOM_BLOCK).min(n_atoms);
        let mut sc = buf.slice_mut(s![..m, ..a1 - a0]);
        ndarray::linalg::general_mat_mul(
            T::one(),
            &x,
            &dict.slice(s![a0..a1, ..]).t(),
            T::zero(),
            &mut sc,
        );
        for (r, b) in best.iter_mut().enumerate() {
            let row = sc.row(r);
            let Some(row) = row.as_slice() else {
                continue;
            };
            if let Some(j) = argmax_abs(row) {
                let v = row[j].abs();
                if v > b.0 {
                    *b = (v, a0 + j, row[j]);
                }
            }
        }
        a0 = a1;
    }
    x.outer_iter()
        .zip(best)
        .map(|(row, (_, j, alpha))| {
            let j = (j != usize::MAX).then_some(j);
            finish_code(row, j.map(|j| (j, alpha, norm2[j])), tol)
        })
        .collect()
}

/// The code of one signal `row` from its best atom `(index, <d, x>, ||d||^2)` (none when no atom
/// correlates), with Batch-OMP's first-iteration arithmetic; no atom when the signal is already
/// within the tolerance or vanishes.
pub(super) fn finish_code<T: OmpFloat>(
    row: ndarray::ArrayView1<T>,
    best: Option<(usize, T, T)>,
    tol: Option<f64>,
) -> Coded<T> {
    let xx = row.iter().fold(T::zero(), |acc, &v| acc + v * v);
    let floor = T::from_f64(T::RESIDUAL_FLOOR) * xx;
    let Some((j, alpha, gjj)) = best else {
        return (None, xx);
    };
    if xx <= floor || tol.is_some_and(|t| xx <= T::from_f64(t)) {
        return (None, xx);
    }
    if gjj <= T::from_f64(T::PIVOT_FLOOR) * gjj {
        return (None, xx);
    }
    // Same arithmetic as Batch-OMP's first iteration.
    let lkk = gjj.sqrt();
    let cv = alpha / lkk;
    let mut res = xx - cv * cv;
    if res < T::zero() {
        res = T::zero();
    }
    (Some((j as u32, cv / lkk)), res)
}

/// Sparse codes from the per-signal results, in signal order.
pub(super) fn assemble<T: OmpFloat>(
    coded: impl Iterator<Item = Coded<T>>,
) -> Result<SparseCodes<T>> {
    let (lo, _) = coded.size_hint();
    let mut offsets = Vec::with_capacity(lo + 1);
    offsets.push(0usize);
    let mut indices = Vec::with_capacity(lo);
    let mut values = Vec::with_capacity(lo);
    let mut residuals = Vec::with_capacity(lo);
    for (atom, res) in coded {
        if let Some((j, v)) = atom {
            indices.push(j);
            values.push(v);
        }
        offsets.push(indices.len());
        residuals.push(res);
    }
    SparseCodes::from_parts(offsets, indices, values, residuals)
}

/// Exact `s = 1` OMP for dictionaries of any size up to [`MAX_NEAREST_ATOMS`]: for each signal
/// the atom of largest `|<d, x>|` (ties: smallest index), its coefficient `<d, x> / ||d||^2` and
/// the squared residual `||x||^2 - <d, x>^2 / ||d||^2`, by blocked matrix products (see the
/// module documentation). `settings.sparsity` must be 1; the tolerance
/// is honoured (a signal already within it gets no atom). [`crate::batch_omp`] calls this for
/// `s = 1` and dictionaries of more than [`crate::omp::NEAREST_MIN_ATOMS`] atoms.
pub fn nearest_atom<T: OmpFloat>(
    dict: ArrayView2<T>,
    signals: ArrayView2<T>,
    settings: &OmpSettings,
) -> Result<SparseCodes<T>> {
    nearest_atom_with_progress(dict, signals, settings, &relief_heightfield::NoProgress)
}

/// [`nearest_atom`] reporting the coded signals to `progress` (phase `"batch-omp"`).
pub fn nearest_atom_with_progress<T: OmpFloat>(
    dict: ArrayView2<T>,
    signals: ArrayView2<T>,
    settings: &OmpSettings,
    progress: &dyn Progress,
) -> Result<SparseCodes<T>> {
    if settings.sparsity != 1 {
        return Err(crate::SparseError::param(
            "sparsity",
            settings.sparsity,
            "nearest_atom codes with exactly one atom (s = 1)",
        ));
    }
    validate_limit(&dict, &signals, settings, MAX_NEAREST_ATOMS)?;
    progress.begin("batch-omp", signals.nrows() as u64);
    let n_atoms = dict.nrows();
    let norm2: Vec<T> = dict
        .outer_iter()
        .map(|r| r.iter().fold(T::zero(), |acc, &v| acc + v * v))
        .collect();
    let n = signals.nrows();
    let tol = settings.tolerance;
    let blocks: Vec<Vec<Coded<T>>> = (0..n.div_ceil(SIG_BLOCK))
        .into_par_iter()
        .map_init(
            || Array2::from_elem((SIG_BLOCK, ATOM_BLOCK.min(n_atoms)), T::zero()),
            |buf, b| {
                let lo = b * SIG_BLOCK;
                let hi = (lo + SIG_BLOCK).min(n);
                let x = signals.slice(s![lo..hi, ..]);
                let out = code_block(&dict, &norm2, x, tol, buf);
                progress.advance((hi - lo) as u64);
                out
            },
        )
        .collect();
    assemble(blocks.into_iter().flatten())
}
