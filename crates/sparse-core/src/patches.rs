//! Patch geometry and extraction (guerin2016 section 4.2).
//!
//! Primitive centres lie on a regular grid of step `S` (default: half the patch width,
//! `a delta / 2`); every primitive has the disk support of radius `R` (default `a delta / 2`, the
//! disk inscribed in the patch). The first centre is placed at
//! `(a - 1) delta / 2 - ceil((a - 1) delta / 2)` (so with `delta = 1` the patch samples fall
//! on terrain samples) and the grid extends until the last centre reaches the far edge, so every
//! point of the terrain is within `S / sqrt(2)` of a centre; `R > S / sqrt(2)` is required, which
//! guarantees that `sum_i alpha_i(p) != 0` on the whole domain (section 4.2).
//!
//! Extraction samples the terrain at the `a x a` patch positions (exact samples when they fall
//! on the grid, bicubic otherwise; edges replicated), takes `z_i` as the mean over the samples
//! inside the support disk, and stores `T_i = samples - z_i` as row `i` of the patch matrix
//! (the transpose of the paper's `K x n` matrix `F`).

use ndarray::Array2;
use rayon::prelude::*;
use relief_heightfield::Heightfield;

use crate::error::{Result, SparseError};

/// Largest number of primitives of a centre grid.
pub const MAX_PRIMITIVES: usize = 1 << 24;
/// Largest number of samples of a patch matrix (`n K`, 1 GiB of `f32`).
pub const MAX_PATCH_SAMPLES: usize = 1 << 28;

/// Geometry of the primitives of a layer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchGeometry {
    /// Patch side `a` in samples (`K = a * a`).
    pub patch_size: usize,
    /// Sample spacing `delta` in terrain cells.
    pub spacing: f64,
    /// Grid step `S` between neighbouring centres, in terrain cells.
    pub step: f64,
    /// Support radius `R` of the weight `alpha_i(p) = g(|p - c_i| / R)`, in terrain cells.
    pub support_radius: f64,
}

impl Default for PatchGeometry {
    fn default() -> Self {
        Self::with_patch_size(8)
    }
}

impl PatchGeometry {
    /// The default geometry for `a x a` patches at spacing 1: step and radius `a / 2`.
    pub fn with_patch_size(patch_size: usize) -> Self {
        Self {
            patch_size,
            spacing: 1.0,
            step: patch_size as f64 / 2.0,
            support_radius: patch_size as f64 / 2.0,
        }
    }

    /// Validates the geometry (sizes positive, `R > S / sqrt(2)` so the weights cover the plane).
    pub fn check(&self) -> Result<()> {
        support_mask(self.patch_size, self.spacing, self.support_radius)?;
        if !(self.step.is_finite() && self.step > 0.0 && self.step <= 1e9) {
            return Err(SparseError::param(
                "step",
                self.step,
                "must be finite and in (0, 1e9] cells",
            ));
        }
        if self.support_radius * self.support_radius <= self.step * self.step / 2.0 {
            return Err(SparseError::param(
                "support_radius",
                self.support_radius,
                "must exceed step / sqrt(2) so that the weights never vanish",
            ));
        }
        Ok(())
    }

    /// The centre grid covering a `width x height` terrain (at most [`MAX_PRIMITIVES`]
    /// centres; the patch matrix of the whole grid is bounded separately, by
    /// [`extract_patches`], so a grid too large to extract at once can still be extracted in
    /// bands of rows with [`extract_patch_rows`]).
    pub fn grid(&self, width: usize, height: usize) -> Result<CentreGrid> {
        self.check()?;
        if width == 0 || height == 0 {
            return Err(SparseError::param(
                "width x height",
                format!("{width} x {height}"),
                "terrain must not be empty",
            ));
        }
        let h = (self.patch_size as f64 - 1.0) / 2.0 * self.spacing;
        let origin = h - h.ceil();
        // Counts stay in f64 until they are known to be small (a tiny step must not overflow).
        let count = |len: usize| -> f64 {
            let span = (len as f64 - 1.0) - origin;
            ((span / self.step) - 1e-9).ceil().max(0.0) + 1.0
        };
        let (fx, fy) = (count(width), count(height));
        if fx * fy > MAX_PRIMITIVES as f64 {
            return Err(SparseError::param(
                "step",
                self.step,
                "gives too many primitives for the terrain (at most 2^24)",
            ));
        }
        Ok(CentreGrid {
            origin: [origin, origin],
            step: self.step,
            nx: fx as usize,
            ny: fy as usize,
        })
    }
}

/// A regular grid of primitive centres: centre `(i, j)` (column i, row j) sits at
/// `origin + (i step, j step)`; primitive index `j * nx + i`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CentreGrid {
    /// Position of centre (0, 0) in terrain pixel coordinates.
    pub origin: [f64; 2],
    /// Step between centres.
    pub step: f64,
    /// Number of columns of centres.
    pub nx: usize,
    /// Number of rows of centres.
    pub ny: usize,
}

impl CentreGrid {
    /// Number of centres.
    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    /// True when the grid holds no centre.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Centre of primitive `k`.
    pub fn centre(&self, k: usize) -> [f64; 2] {
        let (i, j) = (k % self.nx, k / self.nx);
        [
            self.origin[0] + i as f64 * self.step,
            self.origin[1] + j as f64 * self.step,
        ]
    }

    /// All centres in primitive order.
    pub fn centres(&self) -> Vec<[f64; 2]> {
        (0..self.len()).map(|k| self.centre(k)).collect()
    }
}

/// Patches `T_i` of a terrain: the patch matrix, the centres and the means `z_i`.
#[derive(Debug, Clone)]
pub struct Patches {
    /// `n x K` matrix, row `i` = `T_i` (samples minus `z_i`), row-major `a x a`.
    pub matrix: Array2<f32>,
    /// Centres `c_i` in terrain pixel coordinates (x = column, y = row); for a band
    /// ([`extract_patch_rows`]) those of its primitives only.
    pub centres: Vec<[f64; 2]>,
    /// Means `z_i` over the support.
    pub means: Vec<f32>,
    /// The geometry used.
    pub geometry: PatchGeometry,
    /// The centre grid of the whole terrain (the patches of a band start at primitive
    /// `rows.start * grid.nx`, [`extract_patch_rows`]).
    pub grid: CentreGrid,
}

// Keys cubic weights (Catmull-Rom), `f64`.
pub(crate) use relief_heightfield::cubic_weights_f64 as cubic_weights;

fn sample(hf: &Heightfield, x: f64, y: f64) -> f64 {
    let (rx, ry) = (x.round(), y.round());
    if (x - rx).abs() < 1e-9 && (y - ry).abs() < 1e-9 {
        return hf.get_clamped(rx as isize, ry as isize) as f64;
    }
    let (xf, yf) = (x.floor(), y.floor());
    let (wx, wy) = (cubic_weights(x - xf), cubic_weights(y - yf));
    let (xi, yi) = (xf as isize, yf as isize);
    let mut acc = 0.0;
    for (dy, wyv) in wy.iter().enumerate() {
        let mut row = 0.0;
        for (dx, wxv) in wx.iter().enumerate() {
            row += wxv * hf.get_clamped(xi + dx as isize - 1, yi + dy as isize - 1) as f64;
        }
        acc += wyv * row;
    }
    acc
}

/// The whole pixel `(x, y)` when the spacing is 1 and `(x, y)` is within `sample`'s
/// tolerance of a pixel: every sample of the patch is then that pixel plus `(c, r)`.
fn integral_corner(x: f64, y: f64, spacing: f64) -> Option<(isize, isize)> {
    let (rx, ry) = (x.round(), y.round());
    let near = (x - rx).abs() < 1e-9 && (y - ry).abs() < 1e-9 && rx.abs() < 1e15 && ry.abs() < 1e15;
    (spacing == 1.0 && near).then_some((rx as isize, ry as isize))
}

/// The `a x a` pixels from `(x0, y0)` into `buf`, clamped at the borders like
/// [`Heightfield::get_clamped`].
fn copy_clamped(hf: &Heightfield, (x0, y0): (isize, isize), a: usize, buf: &mut [f64]) {
    let (w, h) = (hf.width() as isize, hf.height() as isize);
    let data = hf.as_slice();
    let inside = x0 >= 0 && x0 + a as isize <= w;
    for (r, out) in buf.chunks_exact_mut(a).enumerate() {
        let y = (y0 + r as isize).clamp(0, h - 1) as usize;
        let row = &data[y * w as usize..(y + 1) * w as usize];
        if inside {
            let x0 = x0 as usize;
            for (o, &v) in out.iter_mut().zip(&row[x0..x0 + a]) {
                *o = v as f64;
            }
        } else {
            for (c, o) in out.iter_mut().enumerate() {
                *o = row[(x0 + c as isize).clamp(0, w - 1) as usize] as f64;
            }
        }
    }
}

/// Extracts the patches `T_i` of a void-free heightfield (section 4.2). The patch matrix holds
/// at most [`MAX_PATCH_SAMPLES`] samples; [`extract_patch_rows`] extracts a larger grid in
/// bands.
pub fn extract_patches(hf: &Heightfield, geometry: &PatchGeometry) -> Result<Patches> {
    let grid = geometry.grid(hf.width(), hf.height())?;
    extract_patch_rows(hf, geometry, 0..grid.ny)
}

/// The patches of the centre rows `rows` of the grid covering `hf`
/// (`geometry.grid(hf.width(), hf.height())`): row `k` of the matrix, `means[k]` and
/// `centres[k]` belong to primitive `rows.start * nx + k` of that grid, which is the `grid`
/// returned. The patches are those [`extract_patches`] gives for the same primitives, so a
/// grid too large to extract at once (more than [`MAX_PATCH_SAMPLES`] samples) can be coded
/// band by band with the same result. The band itself must hold at most
/// [`MAX_PATCH_SAMPLES`] samples, and `rows` must lie within the grid's rows.
pub fn extract_patch_rows(
    hf: &Heightfield,
    geometry: &PatchGeometry,
    rows: std::ops::Range<usize>,
) -> Result<Patches> {
    hf.require_complete()?;
    let grid = geometry.grid(hf.width(), hf.height())?;
    if rows.start > rows.end || rows.end > grid.ny {
        return Err(SparseError::param(
            "rows",
            format!("{}..{}", rows.start, rows.end),
            "must lie within the centre grid's rows",
        ));
    }
    let k = geometry.patch_size * geometry.patch_size;
    let n = (rows.end - rows.start) * grid.nx;
    if n as f64 * k as f64 > MAX_PATCH_SAMPLES as f64 {
        return Err(SparseError::param(
            "step",
            geometry.step,
            "gives too many patch samples for the terrain (at most 2^28 at once)",
        ));
    }
    let base = rows.start * grid.nx;
    let mask = support_mask(
        geometry.patch_size,
        geometry.spacing,
        geometry.support_radius,
    )?;
    let a = geometry.patch_size;
    let half = (a as f64 - 1.0) / 2.0;
    // Every patch on its own (rows in parallel, each computed alike whatever the thread).
    let mut data = vec![0f32; n * a * a];
    let mut means = vec![0f32; n];
    data.par_chunks_mut((a * a).max(1))
        .zip(means.par_iter_mut())
        .enumerate()
        .for_each_init(
            || vec![0f64; a * a],
            |buf, (k, (row, mean))| {
                let [cx, cy] = grid.centre(base + k);
                if let Some((x0, y0)) = integral_corner(cx - half, cy - half, geometry.spacing) {
                    // Unit spacing from a whole pixel: every sample is a pixel (what
                    // `sample` returns there), read row by row.
                    copy_clamped(hf, (x0, y0), a, buf);
                } else {
                    for r in 0..a {
                        for c in 0..a {
                            let x = cx + (c as f64 - half) * geometry.spacing;
                            let y = cy + (r as f64 - half) * geometry.spacing;
                            buf[r * a + c] = sample(hf, x, y);
                        }
                    }
                }
                let (s, cnt) = buf
                    .iter()
                    .zip(&mask)
                    .filter(|(_, m)| **m)
                    .fold((0.0, 0usize), |(s, c), (v, _)| (s + v, c + 1));
                let z = (s / cnt as f64) as f32;
                *mean = z;
                for (o, v) in row.iter_mut().zip(buf.iter()) {
                    *o = (v - z as f64) as f32;
                }
            },
        );
    let matrix = Array2::from_shape_vec((n, a * a), data)
        .map_err(|_| SparseError::param("patch_size", a, "patch matrix shape mismatch"))?;
    Ok(Patches {
        matrix,
        centres: (base..base + n).map(|k| grid.centre(k)).collect(),
        means,
        geometry: *geometry,
        grid,
    })
}

/// Checks a patch frame and returns the support mask.
pub(crate) fn support_mask(patch_size: usize, spacing: f64, radius: f64) -> Result<Vec<bool>> {
    if patch_size == 0 || patch_size > 256 {
        return Err(SparseError::param(
            "patch_size",
            patch_size,
            "must be in 1..=256",
        ));
    }
    if !(spacing.is_finite() && spacing > 0.0 && spacing <= 1e6) {
        return Err(SparseError::param(
            "spacing",
            spacing,
            "must be finite and in (0, 1e6] cells",
        ));
    }
    if !(radius.is_finite() && radius > 0.0 && radius <= 1e9) {
        return Err(SparseError::param(
            "support_radius",
            radius,
            "must be finite and in (0, 1e9] cells",
        ));
    }
    let a = patch_size;
    let h = (a as f64 - 1.0) / 2.0;
    let mut mask = vec![false; a * a];
    for r in 0..a {
        for c in 0..a {
            let dx = (c as f64 - h) * spacing;
            let dy = (r as f64 - h) * spacing;
            mask[r * a + c] = dx * dx + dy * dy < radius * radius;
        }
    }
    if !mask.iter().any(|&m| m) {
        return Err(SparseError::param(
            "support_radius",
            radius,
            "the support disk holds no sample of the patch",
        ));
    }
    Ok(mask)
}
