//! The types both sparse solvers share ([`crate::omp`]'s Batch-OMP and [`crate::nearest`]'s
//! `s = 1` searches): the float types they run in, their settings, the compressed-row codes
//! they return, the input checks and the vectorised arg-max. The solvers' modules re-export
//! the public items at their old paths.

use std::fmt::{Debug, Display};
use std::ops::{AddAssign, Neg, SubAssign};

use ndarray::{Array2, ArrayView2, LinalgScalar};

use crate::error::{Result, SparseError};

/// Largest sparsity the solvers accept.
pub const MAX_SPARSITY: usize = 64;

/// Largest number of atoms the solvers accept at `s > 1` (both keep an `N x N` Gram matrix);
/// at `s = 1` [`crate::omp::batch_omp`] accepts up to [`crate::nearest::MAX_NEAREST_ATOMS`].
pub const MAX_ATOMS: usize = 1 << 15;

/// Dictionaries of more than this many atoms are coded at `s = 1` by
/// [`crate::nearest::nearest_atom`] (no Gram matrix, blocked correlations and a running arg-max);
/// smaller ones keep the Gram path, whose output is unchanged.
pub const NEAREST_MIN_ATOMS: usize = 4096;

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// Floating-point types the solvers run in (`f32` and `f64`).
pub trait OmpFloat:
    LinalgScalar
    + Send
    + Sync
    + Debug
    + Display
    + Default
    + PartialOrd
    + AddAssign
    + SubAssign
    + Neg<Output = Self>
    + sealed::Sealed
{
    /// Conversion from `f64` (rounding).
    fn from_f64(v: f64) -> Self;
    /// Conversion to `f64`.
    fn to_f64(self) -> f64;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// True when neither NaN nor infinite.
    fn is_finite(self) -> bool;
    /// Relative floor under which a Cholesky pivot counts as zero (linear dependence).
    const PIVOT_FLOOR: f64;
    /// Relative floor (of `||x||^2`) under which a squared residual counts as zero.
    const RESIDUAL_FLOOR: f64;
}

/// `OmpFloat` for a primitive float type with its two floors.
macro_rules! omp_float {
    ($t:ident, $pivot:expr, $residual:expr) => {
        impl OmpFloat for $t {
            fn from_f64(v: f64) -> Self {
                v as $t
            }
            fn to_f64(self) -> f64 {
                self as f64
            }
            fn sqrt(self) -> Self {
                $t::sqrt(self)
            }
            fn abs(self) -> Self {
                $t::abs(self)
            }
            fn is_finite(self) -> bool {
                $t::is_finite(self)
            }
            const PIVOT_FLOOR: f64 = $pivot;
            const RESIDUAL_FLOOR: f64 = $residual;
        }
    };
}

omp_float!(f32, 1e-5, 1e-9);
omp_float!(f64, 1e-10, 1e-20);

/// Settings of both OMP solvers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OmpSettings {
    /// Target sparsity `s` (maximum number of atoms per signal), `1..=64` and `<= n_atoms`.
    pub sparsity: usize,
    /// Optional residual target: stop as soon as `||r||^2 <= tolerance` (squared L2 norm of the
    /// residual, in signal units squared). Must be finite and `>= 0`.
    pub tolerance: Option<f64>,
}

impl Default for OmpSettings {
    fn default() -> Self {
        Self {
            sparsity: 4,
            tolerance: None,
        }
    }
}

impl OmpSettings {
    /// Validates the settings for a dictionary of `n_atoms` atoms: `sparsity` in `1..=64` and
    /// `<= n_atoms` ([`SparseError::SparsityTooLarge`]), `tolerance` finite and `>= 0`.
    pub fn check(&self, n_atoms: usize) -> Result<()> {
        if self.sparsity == 0 || self.sparsity > MAX_SPARSITY {
            return Err(SparseError::param(
                "sparsity",
                self.sparsity,
                "must be in 1..=64",
            ));
        }
        if self.sparsity > n_atoms {
            return Err(SparseError::SparsityTooLarge {
                sparsity: self.sparsity,
                n_atoms,
            });
        }
        if let Some(t) = self.tolerance
            && !(t.is_finite() && t >= 0.0)
        {
            return Err(SparseError::param(
                "tolerance",
                t,
                "must be finite and >= 0",
            ));
        }
        Ok(())
    }
}

/// Sparse codes of a batch of signals in compressed-row form: for signal `i`, the atom indices
/// in selection order and their coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct SparseCodes<T> {
    pub(crate) offsets: Vec<usize>,
    pub(crate) indices: Vec<u32>,
    pub(crate) values: Vec<T>,
    pub(crate) residuals: Vec<T>,
}

impl<T: OmpFloat> SparseCodes<T> {
    /// Builds codes from per-signal lists (offsets has `n_signals + 1` entries).
    pub fn from_parts(
        offsets: Vec<usize>,
        indices: Vec<u32>,
        values: Vec<T>,
        residuals: Vec<T>,
    ) -> Result<Self> {
        let n = offsets.len().saturating_sub(1);
        if offsets.is_empty()
            || offsets[0] != 0
            || offsets.windows(2).any(|w| w[1] < w[0])
            || *offsets.last().unwrap_or(&0) != indices.len()
            || indices.len() != values.len()
            || residuals.len() != n
        {
            return Err(SparseError::param(
                "offsets",
                offsets.len(),
                "offsets must start at 0, be non-decreasing and end at indices.len()",
            ));
        }
        Ok(Self {
            offsets,
            indices,
            values,
            residuals,
        })
    }

    /// Appends the codes of `other`'s signals after this one's (codes computed in batches).
    pub fn append(&mut self, other: &Self) {
        let base = self.indices.len();
        self.offsets
            .extend(other.offsets[1..].iter().map(|&o| base + o));
        self.indices.extend_from_slice(&other.indices);
        self.values.extend_from_slice(&other.values);
        self.residuals.extend_from_slice(&other.residuals);
    }

    /// Number of signals.
    pub fn n_signals(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Atom indices (selection order) and coefficient values of signal `i`.
    ///
    /// # Panics
    /// Panics if `i >= n_signals()`.
    pub fn signal(&self, i: usize) -> (&[u32], &[T]) {
        let (a, b) = (self.offsets[i], self.offsets[i + 1]);
        (&self.indices[a..b], &self.values[a..b])
    }

    /// Squared L2 norm of the residual of signal `i` as tracked by the solver.
    pub fn residual_sq(&self, i: usize) -> T {
        self.residuals[i]
    }

    /// Total number of non-zero coefficients.
    pub fn nnz(&self) -> usize {
        self.indices.len()
    }

    /// Dense `(n_signals, n_atoms)` coefficient matrix (`X^T` in the paper's notation).
    ///
    /// # Panics
    /// Panics if an index is `>= n_atoms`.
    pub fn to_dense(&self, n_atoms: usize) -> Array2<T> {
        let mut out = Array2::from_elem((self.n_signals(), n_atoms), T::zero());
        for i in 0..self.n_signals() {
            let (idx, val) = self.signal(i);
            for (&j, &v) in idx.iter().zip(val) {
                out[(i, j as usize)] = v;
            }
        }
        out
    }

    /// Reconstruction `codes . dict`, shape `(n_signals, dim)`.
    pub fn reconstruct(&self, dict: ArrayView2<T>) -> Array2<T> {
        let mut out = Array2::from_elem((self.n_signals(), dict.ncols()), T::zero());
        for i in 0..self.n_signals() {
            let (idx, val) = self.signal(i);
            let mut row = out.row_mut(i);
            for (&j, &v) in idx.iter().zip(val) {
                row.scaled_add(v, &dict.row(j as usize));
            }
        }
        out
    }
}

/// Checks a dictionary and signals for the solvers, with a caller-chosen atom limit.
pub(crate) fn validate_limit<T: OmpFloat>(
    dict: &ArrayView2<T>,
    signals: &ArrayView2<T>,
    settings: &OmpSettings,
    max_atoms: usize,
) -> Result<()> {
    let (n_atoms, dim) = dict.dim();
    if n_atoms == 0 || dim == 0 {
        return Err(SparseError::EmptyDictionary { n_atoms, dim });
    }
    if signals.ncols() != dim {
        return Err(SparseError::DimensionMismatch {
            what: "signal dimension vs atom dimension",
            expected: dim,
            got: signals.ncols(),
        });
    }
    if n_atoms > max_atoms {
        return Err(SparseError::param(
            "n_atoms",
            n_atoms,
            if max_atoms == MAX_ATOMS {
                "at most 2^15 atoms at s > 1 (the N x N Gram matrix must fit in memory)"
            } else {
                "at most 2^22 atoms"
            },
        ));
    }
    settings.check(n_atoms)?;
    for (i, row) in dict.outer_iter().enumerate() {
        let mut n2 = 0.0f64;
        for &v in row.iter() {
            if !v.is_finite() {
                return Err(SparseError::non_finite("dictionary", i));
            }
            n2 += v.to_f64() * v.to_f64();
        }
        let norm = n2.sqrt();
        if (norm - 1.0).abs() > 1e-3 {
            return Err(SparseError::NotNormalised { atom: i, norm });
        }
    }
    for (i, row) in signals.outer_iter().enumerate() {
        if row.iter().any(|v| !v.is_finite()) {
            return Err(SparseError::non_finite("signals", i));
        }
    }
    Ok(())
}

/// Index of the largest `|v|` (first one on ties); `None` when every value is 0 (or NaN).
/// Lane-wise maxima over fixed chunks let the compiler vectorise the scan; the result is the
/// same as a sequential scan with a strict `>`.
#[inline(always)]
pub(crate) fn argmax_abs<T: OmpFloat>(v: &[T]) -> Option<usize> {
    const LANES: usize = 16;
    // Indices are carried as floats (exact below 2^24, checked by the caller's validation of
    // the atom count) so that values and indices select with the same vector mask.
    let mut bv = [T::zero(); LANES];
    let mut bi = [T::zero(); LANES];
    let chunks = v.chunks_exact(LANES);
    let rem = chunks.remainder();
    let mut base = T::zero();
    let lanes: [T; LANES] = std::array::from_fn(|l| T::from_f64(l as f64));
    let step = T::from_f64(LANES as f64);
    for ch in chunks {
        for l in 0..LANES {
            let a = ch[l].abs();
            let gt = a > bv[l];
            bv[l] = if gt { a } else { bv[l] };
            bi[l] = if gt { base + lanes[l] } else { bi[l] };
        }
        base += step;
    }
    let mut best_v = T::zero();
    let mut best_i = usize::MAX;
    for l in 0..LANES {
        let i = bi[l].to_f64() as usize;
        if bv[l] > best_v || (bv[l] == best_v && bv[l] > T::zero() && i < best_i) {
            best_v = bv[l];
            best_i = i;
        }
    }
    let off = v.len() - rem.len();
    for (j, &x) in rem.iter().enumerate() {
        let a = x.abs();
        if a > best_v {
            best_v = a;
            best_i = off + j;
        }
    }
    (best_i != usize::MAX).then_some(best_i)
}
