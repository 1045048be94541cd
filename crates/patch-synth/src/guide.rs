//! Guide construction (section 3.1): low-pass filtering of an existing DEM, or interpolation of
//! painted seeds and sketch strokes.

use relief_heightfield::Heightfield;
use relief_heightfield::fill::{FillSettings, fill_voids};

use crate::error::{PatchSynthError, Result};

/// Low-pass guide by resampling: reduce by `factor` with the Lanczos low-pass, then enlarge
/// back (bicubic) to the original size.
pub fn lowpass_resample(dem: &Heightfield, factor: usize) -> Result<Heightfield> {
    dem.require_complete()?;
    if factor < 1 || factor > dem.width().min(dem.height()) {
        return Err(PatchSynthError::setting(
            "factor",
            factor,
            "must be in 1..=min(width, height)",
        ));
    }
    let (w, h) = (dem.width(), dem.height());
    let small = dem.resample((w / factor).max(1), (h / factor).max(1))?;
    let mut out = small.resample(w, h)?;
    out.set_cell_size(dem.cell_size().0, dem.cell_size().1)?;
    out.set_georef(dem.georef().cloned());
    Ok(out)
}

/// Separable Gaussian blur with standard deviation `sigma` cells (edges clamped).
pub fn gaussian_blur(dem: &Heightfield, sigma: f32) -> Result<Heightfield> {
    dem.require_complete()?;
    if !(sigma.is_finite() && sigma > 0.0 && sigma < 1e4) {
        return Err(PatchSynthError::setting(
            "sigma",
            sigma,
            "must be in (0, 1e4)",
        ));
    }
    let r = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * (sigma as f64).powi(2))).exp())
        .collect();
    let ksum: f64 = kernel.iter().sum();
    let (w, h) = (dem.width(), dem.height());
    let src = dem.as_slice();
    let mut tmp = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (k, &kv) in kernel.iter().enumerate() {
                let xx = (x as isize + k as isize - r).clamp(0, w as isize - 1) as usize;
                s += kv * src[y * w + xx] as f64;
            }
            tmp[y * w + x] = (s / ksum) as f32;
        }
    }
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (k, &kv) in kernel.iter().enumerate() {
                let yy = (y as isize + k as isize - r).clamp(0, h as isize - 1) as usize;
                s += kv * tmp[yy * w + x] as f64;
            }
            out[y * w + x] = (s / ksum) as f32;
        }
    }
    Ok(dem.with_data(out)?)
}

/// Largest stroke vertex coordinate (cells) accepted by [`guide_from_sketch`].
const MAX_COORD: f32 = 1e7;

/// A painted seed: a height at a point (pixel coordinates of the target).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seed {
    /// Column.
    pub x: f32,
    /// Row.
    pub y: f32,
    /// Height in metres.
    pub height: f32,
    /// Radius in cells of the disc the seed paints (0 = one cell).
    pub radius: f32,
}

/// A sketch stroke: a polyline whose height varies linearly between its vertices
/// (`(x, y, height)` in pixel coordinates and metres).
#[derive(Debug, Clone, PartialEq)]
pub struct Stroke {
    /// Vertices.
    pub points: Vec<(f32, f32, f32)>,
}

/// Interpolates a smooth guide of `width x height` cells from painted seeds and sketch strokes:
/// the painted cells are fixed and the rest is the harmonic (membrane) interpolation, then a
/// Gaussian blur of `smoothing` cells (0 = none) softens the creases at the seeds.
pub fn guide_from_sketch(
    width: usize,
    height: usize,
    cell_size: (f64, f64),
    seeds: &[Seed],
    strokes: &[Stroke],
    smoothing: f32,
) -> Result<Heightfield> {
    if width == 0
        || height == 0
        || width
            .checked_mul(height)
            .is_none_or(|n| n > crate::synth::MAX_OUTPUT_CELLS)
    {
        return Err(PatchSynthError::InvalidControl {
            name: "size",
            reason: format!("a {width} x {height} guide is empty or too large"),
        });
    }
    if seeds.is_empty() && strokes.iter().all(|s| s.points.is_empty()) {
        return Err(PatchSynthError::InvalidControl {
            name: "seeds",
            reason: "no seed and no stroke point".into(),
        });
    }
    let mut grid = vec![f32::NAN; width * height];
    let mut paint = |x: f32, y: f32, r: f32, v: f32| -> Result<()> {
        if !(x.is_finite() && y.is_finite() && v.is_finite() && r.is_finite() && r >= 0.0) {
            return Err(PatchSynthError::InvalidControl {
                name: "seeds",
                reason: format!("non-finite seed ({x}, {y}, r={r}, h={v})"),
            });
        }
        let (x0, x1) = (
            (x - r).floor().max(0.0) as usize,
            (x + r).ceil().max(0.0) as usize,
        );
        let (y0, y1) = (
            (y - r).floor().max(0.0) as usize,
            (y + r).ceil().max(0.0) as usize,
        );
        for yy in y0..=y1.min(height.saturating_sub(1)) {
            for xx in x0..=x1.min(width.saturating_sub(1)) {
                let d2 = (xx as f32 - x).powi(2) + (yy as f32 - y).powi(2);
                if d2 <= (r + 0.5).powi(2) {
                    grid[yy * width + xx] = v;
                }
            }
        }
        Ok(())
    };
    for s in seeds {
        paint(s.x, s.y, s.radius, s.height)?;
    }
    for st in strokes {
        if st.points.len() == 1 {
            let (x, y, v) = st.points[0];
            paint(x, y, 0.0, v)?;
        }
        for seg in st.points.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            if [a.0, a.1, b.0, b.1]
                .iter()
                .any(|v| !v.is_finite() || v.abs() > MAX_COORD)
            {
                return Err(PatchSynthError::InvalidControl {
                    name: "strokes",
                    reason: format!(
                        "stroke segment ({}, {}) - ({}, {}) is non-finite or beyond +-{MAX_COORD} cells",
                        a.0, a.1, b.0, b.1
                    ),
                });
            }
            let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
            let n = (len.ceil() as usize).max(1) * 2;
            for i in 0..=n {
                let t = i as f32 / n as f32;
                paint(
                    a.0 + t * (b.0 - a.0),
                    a.1 + t * (b.1 - a.1),
                    0.0,
                    a.2 + t * (b.2 - a.2),
                )?;
            }
        }
    }
    if grid.iter().all(|v| v.is_nan()) {
        return Err(PatchSynthError::InvalidControl {
            name: "seeds",
            reason: "every seed lies outside the grid".into(),
        });
    }
    let mut hf = Heightfield::new(width, height, grid, cell_size.0, cell_size.1)?;
    fill_voids(&mut hf, &FillSettings::default())?;
    if smoothing > 0.0 {
        hf = gaussian_blur(&hf, smoothing)?;
    }
    Ok(hf)
}
