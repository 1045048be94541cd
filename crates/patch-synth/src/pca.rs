//! Principal component analysis of overlap regions (section 3.5): covariance with faer's
//! matrix product and its symmetric eigen-decomposition, both run sequentially so the basis
//! does not depend on the thread count.

use faer::diag::Diag;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::evd::{ComputeEigenvectors, self_adjoint_evd, self_adjoint_evd_scratch};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, Par};

use crate::error::{PatchSynthError, Result};

/// A PCA basis: mean vector and the `k` leading principal axes.
#[derive(Debug, Clone)]
pub struct Pca {
    /// Input dimension.
    pub dim: usize,
    /// Number of kept components.
    pub k: usize,
    /// Mean of the training vectors.
    pub mean: Vec<f32>,
    /// `k` unit axes of `dim` values, by decreasing variance.
    pub axes: Vec<f32>,
    /// Variance along each kept axis.
    pub variances: Vec<f32>,
    /// Fraction of the total variance the kept axes explain.
    pub explained: f32,
}

impl Pca {
    /// Fits `k` components to `samples` (`n * dim` values, `n >= 2`).
    pub fn fit(samples: &[f32], dim: usize, k: usize) -> Result<Self> {
        let n = samples.len() / dim.max(1);
        if dim == 0 || n < 2 || k == 0 || k > dim {
            return Err(PatchSynthError::Numerical(format!(
                "pca with {n} samples of dimension {dim} and {k} components"
            )));
        }
        let mut mean = vec![0.0f64; dim];
        for s in samples.chunks_exact(dim) {
            mean.iter_mut().zip(s).for_each(|(m, &v)| *m += v as f64);
        }
        mean.iter_mut().for_each(|m| *m /= n as f64);
        let x = Mat::<f64>::from_fn(n, dim, |i, j| samples[i * dim + j] as f64 - mean[j]);
        let mut cov = Mat::<f64>::zeros(dim, dim);
        matmul(
            cov.as_mut(),
            Accum::Replace,
            x.transpose(),
            x.as_ref(),
            1.0 / (n - 1) as f64,
            Par::Seq,
        );
        let mut s = Diag::<f64>::zeros(dim);
        let mut u = Mat::<f64>::zeros(dim, dim);
        let mut buf = MemBuffer::new(self_adjoint_evd_scratch::<f64>(
            dim,
            ComputeEigenvectors::Yes,
            Par::Seq,
            Default::default(),
        ));
        self_adjoint_evd(
            cov.as_ref(),
            s.as_mut(),
            Some(u.as_mut()),
            Par::Seq,
            MemStack::new(&mut buf),
            Default::default(),
        )
        .map_err(|e| PatchSynthError::Numerical(format!("pca eigen-decomposition: {e:?}")))?;
        let vals = s.column_vector();
        let total: f64 = (0..dim).map(|i| vals[i].max(0.0)).sum();
        let mut axes = Vec::with_capacity(k * dim);
        let mut variances = Vec::with_capacity(k);
        let mut kept = 0.0;
        // Eigenvalues come in nondecreasing order: the leading axes are the last columns.
        for c in (dim - k..dim).rev() {
            let col: Vec<f64> = (0..dim).map(|r| u[(r, c)]).collect();
            // Fix the sign (largest component positive) for a canonical basis.
            let big = col
                .iter()
                .copied()
                .fold(0.0f64, |a, v| if v.abs() > a.abs() { v } else { a });
            let sign = if big < 0.0 { -1.0 } else { 1.0 };
            axes.extend(col.iter().map(|v| (v * sign) as f32));
            variances.push(vals[c].max(0.0) as f32);
            kept += vals[c].max(0.0);
        }
        Ok(Self {
            dim,
            k,
            mean: mean.iter().map(|&m| m as f32).collect(),
            axes,
            variances,
            explained: if total > 0.0 {
                (kept / total) as f32
            } else {
                1.0
            },
        })
    }

    /// Projects `x` (`dim` values) onto the axes into `out` (`k` values).
    ///
    /// The dot products run on 8 independent partial sums (then added pairwise), which the
    /// compiler vectorises: a single running f32 sum cannot be reordered and kept the index
    /// build's projection of every patch scalar.
    pub fn project(&self, x: &[f32], out: &mut [f32]) {
        const L: usize = 8;
        for (o, axis) in out.iter_mut().zip(self.axes.chunks_exact(self.dim)) {
            let mut acc = [0.0f32; L];
            let (ac, ar) = axis.split_at(axis.len() / L * L);
            let (xc, xr) = x.split_at(ac.len());
            let (mc, mr) = self.mean.split_at(ac.len());
            for ((a, v), m) in ac
                .chunks_exact(L)
                .zip(xc.chunks_exact(L))
                .zip(mc.chunks_exact(L))
            {
                for l in 0..L {
                    acc[l] += a[l] * (v[l] - m[l]);
                }
            }
            let mut tail = 0.0f32;
            for ((a, v), m) in ar.iter().zip(xr).zip(mr) {
                tail += a * (v - m);
            }
            *o = ((acc[0] + acc[4]) + (acc[1] + acc[5]))
                + ((acc[2] + acc[6]) + (acc[3] + acc[7]))
                + tail;
        }
    }
}
