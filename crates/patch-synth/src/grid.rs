//! The synthesis grid's arithmetic, shared by the synthesis, the validation, the index and the
//! guide: output limits, grid and padding geometry, window means, the overlap-feature layouts,
//! block seeds and the guide's Gaussian blur. A leaf module: it names no other module of the
//! crate but the error.

use relief_heightfield::Heightfield;

use crate::error::{PatchSynthError, Result};

/// Largest output a synthesis accepts (`width * height`, 2^28 cells: the working canvases then
/// take a few GiB).
pub const MAX_OUTPUT_CELLS: usize = 1 << 28;

pub(crate) fn smoothstep(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Counter-based seed of a grid block: the choice at a block never depends on other blocks'
/// random draws or on the thread count.
pub(crate) fn block_seed(seed: u64, a: u64, b: u64) -> u64 {
    relief_heightfield::rng::hash(seed, a, b, 0)
}

/// Padded working canvas of the synthesis.
pub(crate) struct Grid {
    pub(crate) nx: usize,
    pub(crate) ny: usize,
    pub(crate) cw: usize,
    pub(crate) ch: usize,
}

pub(crate) fn grid_for(width: usize, height: usize, p: usize, o: usize) -> Grid {
    let s = p - o;
    let n = |len: usize| if len <= p { 1 } else { (len - o).div_ceil(s) };
    let (nx, ny) = (n(width), n(height));
    Grid {
        nx,
        ny,
        cw: o + nx * s,
        ch: o + ny * s,
    }
}

/// Clamp-pads a `w x h` raster to `cw x ch`.
pub(crate) fn pad<T: Copy>(src: &[T], w: usize, h: usize, cw: usize, ch: usize) -> Vec<T> {
    let mut out = Vec::with_capacity(cw * ch);
    for y in 0..ch {
        let sy = y.min(h - 1);
        for x in 0..cw {
            out.push(src[sy * w + x.min(w - 1)]);
        }
    }
    out
}

/// Squared distance between a target descriptor `d` and a patch (or centroid) descriptor `c`
/// after the vertical translation of equation (3), not applied when larger than `lambda`.
pub(crate) fn translated_dist2(d: &[f32], c: &[f32], lambda: f32) -> f32 {
    let n = d.len().max(1) as f32;
    let mut h = d.iter().zip(c).map(|(a, b)| a - b).sum::<f32>() / n;
    if h.abs() > lambda {
        h = 0.0;
    }
    d.iter().zip(c).map(|(a, b)| (b + h - a).powi(2)).sum()
}

/// Mean of a window of a row-major raster of width `cw`.
pub(crate) fn window_mean(v: &[f32], cw: usize, x: usize, y: usize, w: usize, h: usize) -> f32 {
    let mut s = 0.0f64;
    for yy in y..y + h {
        s += v[yy * cw + x..yy * cw + x + w]
            .iter()
            .map(|&a| a as f64)
            .sum::<f64>();
    }
    (s / (w * h) as f64) as f32
}

/// Cell boundaries splitting `len` into `n` nearly equal parts.
pub(crate) fn bounds(len: usize, n: usize) -> Vec<(usize, usize)> {
    (0..n)
        .map(|i| (i * len / n, (i + 1) * len / n - i * len / n))
        .collect()
}

/// Cell layout of the reduced overlap features of each shape: box means over `f x f` cells.
#[derive(Debug, Clone)]
pub(crate) struct Layouts {
    pub(crate) rects: [Vec<[usize; 4]>; 3],
}

impl Layouts {
    pub(crate) fn new(p: usize, o: usize) -> Self {
        let f = (((p * o) as f64 / 256.0).sqrt().ceil() as usize).max(1);
        let cells = |len: usize| len.div_ceil(f).max(1);
        let rect_grid = |x0: usize, y0: usize, w: usize, h: usize| {
            let mut r = Vec::new();
            for (y, hh) in bounds(h, cells(h)) {
                for (x, ww) in bounds(w, cells(w)) {
                    r.push([x0 + x, y0 + y, ww, hh]);
                }
            }
            r
        };
        let left = rect_grid(0, 0, o, p);
        let top = rect_grid(0, 0, p, o);
        let mut both = left.clone();
        both.extend(rect_grid(o, 0, p - o, o));
        Self {
            rects: [left, top, both],
        }
    }
}

/// Separable Gaussian blur with standard deviation `sigma` cells (edges clamped); see
/// [`Heightfield::gaussian_blur`].
pub fn gaussian_blur(dem: &Heightfield, sigma: f32) -> Result<Heightfield> {
    dem.require_complete()?;
    if !(sigma.is_finite() && sigma > 0.0 && sigma < 1e4) {
        return Err(PatchSynthError::setting(
            "sigma",
            sigma,
            "must be in (0, 1e4)",
        ));
    }
    Ok(dem.gaussian_blur(sigma)?)
}
