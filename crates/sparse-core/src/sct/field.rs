//! A raster of samples interpolated with a separable kernel: the smooth layers of an
//! amplification step (the residual that keeps the output consistent with its input), placed
//! in the tree directly instead of as overlapping primitives that all interpolate the same
//! field.

use super::*;
use relief_heightfield::Kernel;

/// Largest sample count of a [`Field`] (as [`relief_heightfield::MAX_CELLS`]).
const MAX_SAMPLES: usize = relief_heightfield::MAX_CELLS;

/// A `width x height` grid of samples; sample `(i, j)` sits at terrain pixel coordinates
/// `(origin[0] + i step, origin[1] + j step)` and the value at any point is the separable
/// [`Kernel`] interpolation of the samples, edges replicated (weight 1 everywhere).
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    width: usize,
    height: usize,
    samples: Arc<Vec<f32>>,
    origin: [f64; 2],
    step: f64,
    kernel: Kernel,
}

/// First sample index and weights of the kernel taps around grid coordinate `u`.
#[inline]
fn taps(kernel: Kernel, u: f64) -> (i64, [f64; Kernel::MAX_TAPS]) {
    let (first, t) = kernel.position(u);
    (first, kernel.weights(t))
}

/// [`taps`] with the weights of the fractional positions already met kept in `cache` (a
/// raster at a whole scale meets a few positions over and over; the weights are the same
/// function of the same position, so the values are bit for bit those of [`taps`]).
fn cached_taps(
    kernel: Kernel,
    u: f64,
    cache: &mut Vec<(u64, [f64; Kernel::MAX_TAPS])>,
) -> (i64, [f64; Kernel::MAX_TAPS]) {
    const MAX_CACHED: usize = 16;
    let (first, t) = kernel.position(u);
    if let Some((_, w)) = cache.iter().find(|(b, _)| *b == t.to_bits()) {
        return (first, *w);
    }
    let w = kernel.weights(t);
    if cache.len() < MAX_CACHED {
        cache.push((t.to_bits(), w));
    }
    (first, w)
}

impl Field {
    /// A field of `samples` (row-major, `width x height`, finite) placed by `origin` and
    /// `step` (terrain pixels, finite, step > 0) and interpolated with `kernel`.
    pub fn new(
        width: usize,
        height: usize,
        samples: Vec<f32>,
        origin: [f64; 2],
        step: f64,
        kernel: Kernel,
    ) -> Result<Self> {
        let n = width
            .checked_mul(height)
            .filter(|&n| n > 0 && n <= MAX_SAMPLES);
        if n != Some(samples.len()) {
            return Err(SparseError::param(
                "field size",
                format!("{width} x {height} with {} samples", samples.len()),
                "must be non-empty, at most MAX_CELLS and match the sample count",
            ));
        }
        if let Some(v) = samples.iter().find(|v| !v.is_finite()) {
            return Err(SparseError::param("field sample", v, "must be finite"));
        }
        if !(origin.iter().all(|o| o.is_finite()) && step.is_finite() && step > 0.0) {
            return Err(SparseError::param(
                "field placement",
                format!("origin {origin:?}, step {step}"),
                "must be finite with step > 0",
            ));
        }
        Ok(Self {
            width,
            height,
            samples: Arc::new(samples),
            origin,
            step,
            kernel,
        })
    }

    /// Samples along x.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Samples along y.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The samples (row-major).
    pub fn samples(&self) -> &[f32] {
        &self.samples
    }

    /// Terrain pixel coordinates of sample `(0, 0)`.
    pub fn origin(&self) -> [f64; 2] {
        self.origin
    }

    /// Spacing of the samples in terrain pixels.
    pub fn step(&self) -> f64 {
        self.step
    }

    /// The interpolation kernel.
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    #[inline]
    fn clamp_x(&self, i: i64) -> usize {
        i.clamp(0, self.width as i64 - 1) as usize
    }

    #[inline]
    fn clamp_y(&self, j: i64) -> usize {
        j.clamp(0, self.height as i64 - 1) as usize
    }

    /// Interpolation of row `row` at the taps `(first, w)` (the inner sum of [`Self::eval`]).
    #[inline]
    fn row_sum(&self, row: usize, (first, w): (i64, [f64; Kernel::MAX_TAPS])) -> f64 {
        let s = &self.samples[row * self.width..(row + 1) * self.width];
        let mut acc = 0.0;
        for (k, wk) in w.iter().enumerate().take(self.kernel.taps()) {
            acc += wk * s[self.clamp_x(first + k as i64)] as f64;
        }
        acc
    }

    /// The value at terrain pixel coordinates `(x, y)`.
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        let tx = taps(self.kernel, (x - self.origin[0]) / self.step);
        let (fy, wy) = taps(self.kernel, (y - self.origin[1]) / self.step);
        let mut acc = 0.0;
        for (k, wk) in wy.iter().enumerate().take(self.kernel.taps()) {
            acc += wk * self.row_sum(self.clamp_y(fy + k as i64), tx);
        }
        acc
    }

    /// Rasterises the band into `val` with the arithmetic of [`Self::eval`]: every sample row
    /// a band row reaches is interpolated once along x for all the band's columns, then each
    /// pixel sums its rows' values in the same order as `eval`.
    pub(super) fn raster(&self, band: &Band, val: &mut [f64]) {
        let sc = band.scale;
        let n = self.kernel.taps();
        let mut cache = Vec::new();
        let mut at = |v: f64, o: f64| cached_taps(self.kernel, (v - o) / self.step, &mut cache);
        let col_taps: Vec<_> = band
            .cols
            .clone()
            .map(|c| at(raster_coord(c, sc), self.origin[0]))
            .collect();
        let row_taps: Vec<_> = band
            .rows
            .clone()
            .map(|r| at(raster_coord(r, sc), self.origin[1]))
            .collect();
        let (Some(lo), Some(hi)) = (
            row_taps.iter().map(|t| self.clamp_y(t.0)).min(),
            row_taps
                .iter()
                .map(|t| self.clamp_y(t.0 + n as i64 - 1))
                .max(),
        ) else {
            return;
        };
        let ncols = col_taps.len();
        let mut rows = vec![0.0; (hi - lo + 1) * ncols];
        for (j, out) in rows.chunks_exact_mut(ncols).enumerate() {
            for (o, &t) in out.iter_mut().zip(&col_taps) {
                *o = self.row_sum(lo + j, t);
            }
        }
        for ((fy, wy), out) in row_taps.iter().zip(val.chunks_exact_mut(ncols)) {
            out.iter_mut().for_each(|v| *v = 0.0);
            for (k, wk) in wy.iter().enumerate().take(n) {
                let r = self.clamp_y(fy + k as i64) - lo;
                let src = &rows[r * ncols..(r + 1) * ncols];
                for (v, s) in out.iter_mut().zip(src) {
                    *v += wk * s;
                }
            }
        }
    }
}
