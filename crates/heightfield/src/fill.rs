//! Harmonic void filling.
//!
//! Void cells (NaN) are replaced by the solution of Laplace's equation with the valid cells as
//! Dirichlet data and reflecting (Neumann) grid edges: the smoothest surface that meets the
//! surrounding terrain. The linear system over the void cells only is solved by a
//! Jacobi-preconditioned conjugate gradient started from a coarse-to-fine pyramid estimate
//! (each level averages the valid cells of 2x2 blocks), so large holes converge in few
//! iterations instead of the thousands a per-pixel relaxation needs. Valid cells are never
//! changed.

use crate::error::{HeightfieldError, Result};
use crate::grid::Heightfield;

/// Settings of [`fill_voids`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FillSettings {
    /// Relative residual at which CG stops (`|r| / |b|`).
    pub tolerance: f64,
    /// Iteration cap of the conjugate gradient.
    pub max_iterations: usize,
}

impl Default for FillSettings {
    fn default() -> Self {
        Self {
            tolerance: 1e-7,
            max_iterations: 5000,
        }
    }
}

/// What [`fill_voids`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FillReport {
    /// Number of cells filled.
    pub filled: usize,
    /// Conjugate-gradient iterations used.
    pub iterations: usize,
    /// Final relative residual.
    pub relative_residual: f64,
}

/// Coarse-to-fine estimate: averages valid cells into a half-size grid until no void is left,
/// then interpolates back into the voids only.
fn pyramid_guess(z: &[f32], w: usize, h: usize) -> Vec<f64> {
    let mut out: Vec<f64> = z.iter().map(|&v| v as f64).collect();
    if !out.iter().any(|v| v.is_nan()) {
        return out;
    }
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    let mut coarse = vec![f32::NAN; cw * ch];
    for cy in 0..ch {
        for cx in 0..cw {
            let (mut s, mut n) = (0.0f64, 0u32);
            for y in 2 * cy..(2 * cy + 2).min(h) {
                for x in 2 * cx..(2 * cx + 2).min(w) {
                    let v = z[y * w + x];
                    if v.is_finite() {
                        s += v as f64;
                        n += 1;
                    }
                }
            }
            if n > 0 {
                coarse[cy * cw + cx] = (s / n as f64) as f32;
            }
        }
    }
    let coarse = if cw * ch < w * h {
        pyramid_guess(&coarse, cw, ch)
    } else {
        coarse
            .iter()
            .map(|&v| if v.is_finite() { v as f64 } else { 0.0 })
            .collect()
    };
    for y in 0..h {
        for x in 0..w {
            if out[y * w + x].is_nan() {
                // Bilinear from the coarse grid (cell centres at 2c + 0.5).
                let fx = ((x as f64 - 0.5) / 2.0).clamp(0.0, (cw - 1) as f64);
                let fy = ((y as f64 - 0.5) / 2.0).clamp(0.0, (ch - 1) as f64);
                let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
                let (x1, y1) = ((x0 + 1).min(cw - 1), (y0 + 1).min(ch - 1));
                let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
                let c = |xx: usize, yy: usize| coarse[yy * cw + xx];
                out[y * w + x] = (c(x0, y0) * (1.0 - tx) + c(x1, y0) * tx) * (1.0 - ty)
                    + (c(x0, y1) * (1.0 - tx) + c(x1, y1) * tx) * ty;
            }
        }
    }
    out
}

/// Fills every void cell of `hf` in place; see the module docs. Errors if every cell is void or
/// the settings are invalid.
pub fn fill_voids(hf: &mut Heightfield, settings: &FillSettings) -> Result<FillReport> {
    if !(settings.tolerance.is_finite() && settings.tolerance > 0.0) {
        return Err(HeightfieldError::param(
            "tolerance",
            settings.tolerance,
            "must be > 0",
        ));
    }
    let (w, h) = (hf.width(), hf.height());
    let voids = hf.void_count();
    if voids == 0 {
        return Ok(FillReport {
            filled: 0,
            iterations: 0,
            relative_residual: 0.0,
        });
    }
    if voids == hf.len() {
        return Err(HeightfieldError::AllVoid { count: voids });
    }
    let z = hf.as_slice();
    // Unknown numbering.
    let mut index = vec![u32::MAX; w * h];
    let mut cells = Vec::with_capacity(voids);
    for (i, v) in z.iter().enumerate() {
        if !v.is_finite() {
            index[i] = cells.len() as u32;
            cells.push(i);
        }
    }
    let n = cells.len();
    // Row i of A: deg * u_i - sum(void neighbours); b_i = sum(valid neighbours).
    let mut deg = vec![0.0f64; n];
    let mut nbrs: Vec<[u32; 4]> = vec![[u32::MAX; 4]; n];
    let mut b = vec![0.0f64; n];
    for (k, &c) in cells.iter().enumerate() {
        let (x, y) = (c % w, c / w);
        let cand = [
            (x > 0).then(|| c - 1),
            (x + 1 < w).then(|| c + 1),
            (y > 0).then(|| c - w),
            (y + 1 < h).then(|| c + w),
        ];
        for (slot, nb) in cand.into_iter().enumerate() {
            if let Some(j) = nb {
                deg[k] += 1.0;
                if index[j] == u32::MAX {
                    b[k] += z[j] as f64;
                } else {
                    nbrs[k][slot] = index[j];
                }
            }
        }
    }
    let apply = |u: &[f64], out: &mut [f64]| {
        for k in 0..n {
            let mut s = deg[k] * u[k];
            for &j in &nbrs[k] {
                if j != u32::MAX {
                    s -= u[j as usize];
                }
            }
            out[k] = s;
        }
    };
    let guess = pyramid_guess(z, w, h);
    let mut u: Vec<f64> = cells.iter().map(|&c| guess[c]).collect();
    let mut r = vec![0.0; n];
    apply(&u, &mut r);
    for k in 0..n {
        r[k] = b[k] - r[k];
    }
    let bnorm = b.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-30);
    let iterations = crate::cg::pcg(
        apply,
        |r: &[f64], z: &mut [f64]| {
            for k in 0..n {
                z[k] = r[k] / deg[k];
            }
        },
        &mut u,
        &mut r,
        |it, rr| rr.sqrt() / bnorm > settings.tolerance && it < settings.max_iterations,
    );
    let rel = r.iter().map(|v| v * v).sum::<f64>().sqrt() / bnorm;
    let data = hf.as_mut_slice();
    for (k, &c) in cells.iter().enumerate() {
        data[c] = u[k] as f32;
    }
    Ok(FillReport {
        filled: n,
        iterations,
        relative_residual: rel,
    })
}
