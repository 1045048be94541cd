//! Inverted-list index for `s = 1` coding with very large dictionaries (guerin2016 section 5.3:
//! complete dictionaries of 60,000-120,000 atoms).
//!
//! The exact search of [`super::nearest_atom`] correlates every signal with every atom: at
//! 65,536 atoms that is 16x the work of a 4096-atom dictionary. The index groups the atoms into
//! `lists` clusters by sign-invariant spherical k-means (an atom and its negation code the same
//! signals, so a cluster's centre `c` is fitted to `sign(<c, d>) d` and atoms join the centre of
//! largest `|<c, d>|`). A signal is correlated with the centres, then only with the atoms of its
//! `probes` best clusters (largest `|<c, x>|`): with 256 lists and 8 probes, 256 + about 2048
//! correlations per signal instead of 65,536. The selection rule inside the probed atoms and
//! the coefficient are those of the exact search (largest `|<d, x>|`, ties to the smallest atom
//! index, coefficient `<d, x> / ||d||^2`); with `probes == lists` the search is exact.
//!
//! A cluster-bound search (prune a cluster when `|<c, x>| + r ||x||` cannot beat the best) was
//! measured first and pruned almost nothing on 8 x 8 terrain patches (see the parent module),
//! so the index trades a small recall loss for speed; [`AtomIndex::recall`] measures it and the
//! `omp_large` bench reports it beside the time.
//!
//! Deterministic: the clustering uses a fixed sample and fixed blocks, and a signal's result
//! depends only on the signal, the dictionary and the settings, not on the batch or the thread
//! count.

use ndarray::{Array2, ArrayView2, ArrayViewMut2, Axis, s};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use relief_heightfield::{NoProgress, Progress};

use super::{Coded, MAX_NEAREST_ATOMS, finish_code};
use crate::codes::{OmpFloat, OmpSettings, SparseCodes, argmax_abs, validate_limit};
use crate::error::{Result, SparseError};

/// Signals per block of the indexed search (one `block x lists` score buffer per worker).
const SIG_BLOCK: usize = 2048;

/// Rows per block of the clustering's assignment products.
const ASSIGN_BLOCK: usize = 4096;

/// Settings of an [`AtomIndex`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AtomIndexSettings {
    /// Number of clusters; 0 picks the power of two nearest to `sqrt(n_atoms)` (256 at 65,536
    /// atoms).
    pub lists: usize,
    /// Clusters searched per signal; more is slower and closer to the exact search
    /// (`probes >= lists` is exact). Default 8.
    pub probes: usize,
    /// Lloyd iterations of the clustering. Default 8.
    pub iterations: usize,
    /// Training atoms per cluster (a fixed stride sample of the dictionary). Default 32.
    pub sample_per_list: usize,
}

impl Default for AtomIndexSettings {
    fn default() -> Self {
        Self {
            lists: 0,
            probes: 8,
            iterations: 8,
            sample_per_list: 32,
        }
    }
}

impl AtomIndexSettings {
    /// The number of clusters used for a dictionary of `n_atoms` atoms.
    pub fn lists_for(&self, n_atoms: usize) -> usize {
        if self.lists > 0 {
            return self.lists.min(n_atoms.max(1));
        }
        let root = (n_atoms.max(1) as f64).sqrt();
        let p = root.log2().round().max(0.0) as u32;
        (1usize << p).min(n_atoms.max(1))
    }

    /// Validates the settings.
    pub fn check(&self) -> Result<()> {
        let bad = |name, value: usize, reason| Err(SparseError::param(name, value, reason));
        if self.lists > MAX_NEAREST_ATOMS {
            return bad("lists", self.lists, "must be <= 2^22 (0 = automatic)");
        }
        if self.probes == 0 {
            return bad("probes", self.probes, "must be >= 1");
        }
        if self.iterations > 100 {
            return bad("iterations", self.iterations, "must be <= 100");
        }
        if !(1..=4096).contains(&self.sample_per_list) {
            return bad(
                "sample_per_list",
                self.sample_per_list,
                "must be in 1..=4096",
            );
        }
        Ok(())
    }
}

/// A dictionary reordered by cluster, with the cluster centres (see the module documentation).
#[derive(Debug, Clone)]
pub struct AtomIndex<T> {
    /// Unit-norm cluster centres, one per row.
    centres: Array2<T>,
    /// The atoms, grouped by cluster (ascending original index inside a cluster).
    atoms: Array2<T>,
    /// Original index of each row of `atoms`.
    ids: Vec<u32>,
    /// `||d||^2` by original index.
    norm2: Vec<T>,
    /// Rows `offsets[l]..offsets[l + 1]` of `atoms` form cluster `l`.
    offsets: Vec<usize>,
    probes: usize,
}

/// Index of the row of largest `|.|` in each row of `x c^T`, with its signed value, computed
/// over fixed blocks of rows.
fn assign<T: OmpFloat>(x: ArrayView2<T>, c: ArrayView2<T>) -> Vec<(usize, T)> {
    let n = x.nrows();
    (0..n.div_ceil(ASSIGN_BLOCK))
        .into_par_iter()
        .flat_map_iter(|b| {
            let lo = b * ASSIGN_BLOCK;
            let hi = (lo + ASSIGN_BLOCK).min(n);
            let sc = x.slice(s![lo..hi, ..]).dot(&c.t());
            let sc = sc.as_standard_layout().into_owned();
            (0..hi - lo)
                .map(|r| {
                    let row = sc.row(r);
                    let row = row.as_slice().unwrap_or(&[]);
                    let j = argmax_abs(row).unwrap_or(0);
                    (j, row.get(j).copied().unwrap_or(T::zero()))
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Normalises each row to unit norm; rows of zero norm are left at zero.
fn normalise_rows<T: OmpFloat>(m: &mut Array2<T>) {
    for mut row in m.outer_iter_mut() {
        let n2 = row.iter().fold(T::zero(), |a, &v| a + v * v);
        if n2 > T::zero() {
            let inv = T::one() / n2.sqrt();
            row.mapv_inplace(|v| v * inv);
        }
    }
}

/// Sign-invariant spherical k-means on `sample` (unit-norm rows): `k` centres.
fn cluster<T: OmpFloat>(sample: &Array2<T>, k: usize, iterations: usize) -> Array2<T> {
    let n = sample.nrows();
    let dim = sample.ncols();
    let mut centres = Array2::zeros((k, dim));
    for l in 0..k {
        centres.row_mut(l).assign(&sample.row(l * n / k));
    }
    for _ in 0..iterations {
        let assigned = assign(sample.view(), centres.view());
        let mut sums = Array2::<T>::zeros((k, dim));
        let mut counts = vec![0usize; k];
        for (i, &(l, v)) in assigned.iter().enumerate() {
            counts[l] += 1;
            let neg = v < T::zero();
            let mut acc = sums.row_mut(l);
            for (a, &x) in acc.iter_mut().zip(sample.row(i)) {
                if neg { *a -= x } else { *a += x }
            }
        }
        // An empty cluster restarts at the sample atom worst served by its centre.
        let mut by_fit: Vec<usize> = (0..n).collect();
        by_fit.sort_by(|&a, &b| {
            let (fa, fb) = (assigned[a].1.abs(), assigned[b].1.abs());
            fa.partial_cmp(&fb)
                .unwrap_or(std::cmp::Ordering::Equal)
                .then(a.cmp(&b))
        });
        let mut spare = by_fit.into_iter();
        for l in 0..k {
            if counts[l] == 0
                && let Some(i) = spare.next()
            {
                sums.row_mut(l).assign(&sample.row(i));
            }
        }
        normalise_rows(&mut sums);
        centres = sums;
    }
    centres
}

impl<T: OmpFloat> AtomIndex<T> {
    /// Clusters the unit-norm atoms (rows) of `dict`. Errors: an empty dictionary, more than
    /// [`MAX_NEAREST_ATOMS`] atoms, atoms that are not finite or not unit-norm, invalid settings.
    pub fn build(dict: ArrayView2<T>, settings: &AtomIndexSettings) -> Result<Self> {
        settings.check()?;
        let empty = Array2::<T>::zeros((0, dict.ncols()));
        let one = OmpSettings {
            sparsity: 1,
            tolerance: None,
        };
        validate_limit(&dict, &empty.view(), &one, MAX_NEAREST_ATOMS)?;
        let n = dict.nrows();
        let k = settings.lists_for(n);
        let n_sample = (k * settings.sample_per_list).clamp(k, n);
        let rows: Vec<usize> = (0..n_sample).map(|i| i * n / n_sample).collect();
        let mut sample = dict.select(Axis(0), &rows);
        normalise_rows(&mut sample);
        let centres = cluster(&sample, k, settings.iterations);
        let assigned = assign(dict, centres.view());
        let mut offsets = vec![0usize; k + 1];
        for &(l, _) in &assigned {
            offsets[l + 1] += 1;
        }
        for l in 0..k {
            offsets[l + 1] += offsets[l];
        }
        let mut next = offsets.clone();
        let mut ids = vec![0u32; n];
        for (i, &(l, _)) in assigned.iter().enumerate() {
            ids[next[l]] = i as u32;
            next[l] += 1;
        }
        let rows: Vec<usize> = ids.iter().map(|&i| i as usize).collect();
        let atoms = dict.select(Axis(0), &rows);
        let norm2 = dict
            .outer_iter()
            .map(|r| r.iter().fold(T::zero(), |acc, &v| acc + v * v))
            .collect();
        Ok(Self {
            centres,
            atoms,
            ids,
            norm2,
            offsets,
            probes: settings.probes.min(k),
        })
    }

    /// Number of atoms.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// True when the index holds no atom (never: [`AtomIndex::build`] refuses that).
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }

    /// Number of clusters.
    pub fn lists(&self) -> usize {
        self.centres.nrows()
    }

    /// Clusters searched per signal.
    pub fn probes(&self) -> usize {
        self.probes
    }

    /// Atom count of the largest cluster.
    pub fn largest_list(&self) -> usize {
        self.offsets
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(0)
    }

    /// `s = 1` codes of the rows of `signals`, as [`super::nearest_atom`] gives them but
    /// searching only the probed clusters. The tolerance is honoured.
    pub fn code(&self, signals: ArrayView2<T>, tolerance: Option<f64>) -> Result<SparseCodes<T>> {
        self.code_with_progress(signals, tolerance, &NoProgress)
    }

    /// [`AtomIndex::code`] reporting the coded signals to `progress` (phase `"batch-omp"`).
    pub fn code_with_progress(
        &self,
        signals: ArrayView2<T>,
        tolerance: Option<f64>,
        progress: &dyn Progress,
    ) -> Result<SparseCodes<T>> {
        let settings = OmpSettings {
            sparsity: 1,
            tolerance,
        };
        settings.check(self.len())?;
        if signals.ncols() != self.atoms.ncols() {
            return Err(SparseError::DimensionMismatch {
                what: "signal dimension vs atom dimension",
                expected: self.atoms.ncols(),
                got: signals.ncols(),
            });
        }
        if let Some(i) = signals
            .outer_iter()
            .position(|r| r.iter().any(|v| !v.is_finite()))
        {
            return Err(SparseError::non_finite("signals", i));
        }
        progress.begin("batch-omp", signals.nrows() as u64);
        let n = signals.nrows();
        let blocks: Vec<Vec<Coded<T>>> = (0..n.div_ceil(SIG_BLOCK))
            .into_par_iter()
            .map_init(Scratch::default, |sc, b| {
                let lo = b * SIG_BLOCK;
                let hi = (lo + SIG_BLOCK).min(n);
                let out = self.code_block(signals.slice(s![lo..hi, ..]), tolerance, sc);
                progress.advance((hi - lo) as u64);
                out
            })
            .collect();
        super::assemble(blocks.into_iter().flatten())
    }

    /// Codes one block of signals.
    fn code_block(&self, x: ArrayView2<T>, tol: Option<f64>, sc: &mut Scratch<T>) -> Vec<Coded<T>> {
        let m = x.nrows();
        let dim = x.ncols();
        let k = self.lists();
        let p = self.probes;
        let scores = x.dot(&self.centres.t());
        // The `p` clusters of largest |score| per signal, then the signals of each cluster.
        sc.members.clear();
        sc.members.resize(k, Vec::new());
        let mut top: Vec<(T, usize)> = Vec::with_capacity(p + 1);
        for (r, row) in scores.outer_iter().enumerate() {
            top.clear();
            for (l, &v) in row.iter().enumerate() {
                let a = v.abs();
                if top.len() == p && a <= top[p - 1].0 {
                    continue;
                }
                let at = top.iter().position(|t| a > t.0).unwrap_or(top.len());
                top.insert(at, (a, l));
                top.truncate(p);
            }
            for &(_, l) in &top {
                sc.members[l].push(r as u32);
            }
        }
        let mut best: Vec<(T, u32, T)> = vec![(T::zero(), u32::MAX, T::zero()); m];
        for l in 0..k {
            let rows = &sc.members[l];
            let (a0, a1) = (self.offsets[l], self.offsets[l + 1]);
            if rows.is_empty() || a0 == a1 {
                continue;
            }
            let (cnt, na) = (rows.len(), a1 - a0);
            sc.gather.resize(cnt * dim, T::zero());
            for (q, &r) in rows.iter().enumerate() {
                let dst = &mut sc.gather[q * dim..(q + 1) * dim];
                for (d, &v) in dst.iter_mut().zip(x.row(r as usize)) {
                    *d = v;
                }
            }
            sc.prod.resize(cnt * na, T::zero());
            let (Ok(g), Ok(mut pr)) = (
                ArrayView2::from_shape((cnt, dim), &sc.gather[..cnt * dim]),
                ArrayViewMut2::from_shape((cnt, na), &mut sc.prod[..cnt * na]),
            ) else {
                continue;
            };
            ndarray::linalg::general_mat_mul(
                T::one(),
                &g,
                &self.atoms.slice(s![a0..a1, ..]).t(),
                T::zero(),
                &mut pr,
            );
            for (q, &r) in rows.iter().enumerate() {
                let row = &sc.prod[q * na..(q + 1) * na];
                let Some(j) = argmax_abs(row) else {
                    continue;
                };
                let (v, id) = (row[j].abs(), self.ids[a0 + j]);
                let b = &mut best[r as usize];
                if v > b.0 || (v == b.0 && v > T::zero() && id < b.1) {
                    *b = (v, id, row[j]);
                }
            }
        }
        x.outer_iter()
            .zip(best)
            .map(|(row, (_, j, alpha))| {
                let j = (j != u32::MAX).then_some(j as usize);
                finish_code(row, j.map(|j| (j, alpha, self.norm2[j])), tol)
            })
            .collect()
    }

    /// Fraction of `signals` whose indexed atom is the exact search's atom, and the mean ratio
    /// of the indexed `|<d, x>|` to the exact one (1 when every signal finds its best atom).
    pub fn recall(&self, dict: ArrayView2<T>, signals: ArrayView2<T>) -> Result<(f64, f64)> {
        let one = OmpSettings {
            sparsity: 1,
            tolerance: None,
        };
        let exact = super::nearest_atom(dict, signals, &one)?;
        let approx = self.code(signals, None)?;
        let (mut same, mut ratio, mut counted) = (0usize, 0.0f64, 0usize);
        for i in 0..signals.nrows() {
            let (ei, ev) = exact.signal(i);
            let (ai, av) = approx.signal(i);
            if ei == ai {
                same += 1;
            }
            if let (Some(&e), Some(&a)) = (ev.first(), av.first()) {
                let e = e.to_f64().abs() * self.norm2[ei[0] as usize].to_f64();
                let a = a.to_f64().abs() * self.norm2[ai[0] as usize].to_f64();
                if e > 0.0 {
                    ratio += a / e;
                    counted += 1;
                }
            }
        }
        let n = signals.nrows().max(1) as f64;
        Ok((same as f64 / n, ratio / counted.max(1) as f64))
    }
}

/// Per-worker buffers of the indexed search.
struct Scratch<T> {
    members: Vec<Vec<u32>>,
    gather: Vec<T>,
    prod: Vec<T>,
}

impl<T> Default for Scratch<T> {
    fn default() -> Self {
        Self {
            members: Vec::new(),
            gather: Vec::new(),
            prod: Vec::new(),
        }
    }
}
