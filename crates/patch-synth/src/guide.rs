//! Guide construction (section 3.1): low-pass filtering of an existing DEM, or interpolation of
//! painted seeds and sketch strokes.

use relief_heightfield::Heightfield;
use relief_heightfield::fill::{FillSettings, fill_voids};

use crate::error::{PatchSynthError, Result};
pub use crate::grid::gaussian_blur;

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

/// Errs (`size`, with `reason`) unless `width x height` is a non-empty grid of at most
/// [`crate::MAX_OUTPUT_CELLS`] cells.
fn check_size(width: usize, height: usize, reason: impl FnOnce() -> String) -> Result<()> {
    let cells = width.saturating_mul(height);
    if width == 0 || height == 0 || cells > crate::grid::MAX_OUTPUT_CELLS {
        return Err(PatchSynthError::InvalidControl {
            name: "size",
            reason: reason(),
        });
    }
    Ok(())
}

/// Largest stroke vertex coordinate (cells) accepted by [`guide_from_sketch`].
const MAX_COORD: f32 = 1e7;

/// A painted seed: a height at a point (pixel coordinates of the target).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Seed {
    /// Column.
    pub x: f32,
    /// Row.
    pub y: f32,
    /// Height in metres.
    pub height: f32,
    /// Radius in cells of the disc the seed paints (0 = one cell).
    #[serde(default)]
    pub radius: f32,
}

/// A sketch stroke: a polyline whose height varies linearly between its vertices
/// (`(x, y, height)` in pixel coordinates and metres).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
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
    check_size(width, height, || {
        format!("a {width} x {height} guide is empty or too large")
    })?;
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

/// A sketch guide as a file (`relief quilt --guide-sketch FILE.json`): the grid and the painted
/// seeds and strokes of [`guide_from_sketch`], in JSON:
///
/// ```json
/// {"width": 256, "height": 192, "cell_size": [30, 30], "smoothing": 4,
///  "seeds": [{"x": 60, "y": 50, "height": 1800, "radius": 6}],
///  "strokes": [{"points": [[10, 150, 900], [240, 120, 1100]]}]}
/// ```
///
/// Coordinates are cells of the guide (column, row), heights metres; `cell_size` (metres,
/// `[x, y]`) may be left out to take the exemplars'.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SketchGuide {
    /// Guide width in cells.
    pub width: usize,
    /// Guide height in cells.
    pub height: usize,
    /// Cell size in metres; `None` takes the exemplars'.
    #[serde(default)]
    pub cell_size: Option<(f64, f64)>,
    /// Gaussian blur in cells applied after the interpolation (default 2).
    #[serde(default = "default_sketch_smoothing")]
    pub smoothing: f32,
    /// Painted seeds.
    #[serde(default)]
    pub seeds: Vec<Seed>,
    /// Sketch strokes.
    #[serde(default)]
    pub strokes: Vec<Stroke>,
}

fn default_sketch_smoothing() -> f32 {
    2.0
}

impl SketchGuide {
    /// Rasterises the sketch ([`guide_from_sketch`]) at its cell size, or at `fallback_cell`
    /// when it names none.
    pub fn render(&self, fallback_cell: (f64, f64)) -> Result<Heightfield> {
        let cell = self.cell_size.unwrap_or(fallback_cell);
        check_cell(cell)?;
        if !(self.smoothing.is_finite() && (0.0..=1000.0).contains(&self.smoothing)) {
            return Err(PatchSynthError::setting(
                "smoothing",
                self.smoothing,
                "must be in [0, 1000] cells",
            ));
        }
        guide_from_sketch(
            self.width,
            self.height,
            cell,
            &self.seeds,
            &self.strokes,
            self.smoothing,
        )
    }
}

/// A target cell size must be finite and positive.
fn check_cell(cell: (f64, f64)) -> Result<()> {
    if !(cell.0.is_finite() && cell.1.is_finite() && cell.0 > 0.0 && cell.1 > 0.0) {
        return Err(PatchSynthError::setting(
            "cell_size",
            format!("{} x {}", cell.0, cell.1),
            "must be finite and > 0",
        ));
    }
    Ok(())
}

/// The guide resampled to `cell` metres per cell over its own ground extent, so that its
/// features keep their physical size on the exemplars' grid (patches are copied cell for cell).
pub fn to_cell_size(guide: &Heightfield, cell: (f64, f64)) -> Result<Heightfield> {
    guide.require_complete()?;
    check_cell(cell)?;
    let (gx, gy) = guide.cell_size();
    let w = (guide.width() as f64 * gx / cell.0).round().max(1.0);
    let h = (guide.height() as f64 * gy / cell.1).round().max(1.0);
    if w * h > crate::grid::MAX_OUTPUT_CELLS as f64 {
        return Err(PatchSynthError::InvalidControl {
            name: "guide",
            reason: format!(
                "{} x {} cells of {gx:.2} x {gy:.2} m become {w} x {h} cells of {:.2} x {:.2} m, \
                 more than a synthesis may produce",
                guide.width(),
                guide.height(),
                cell.0,
                cell.1
            ),
        });
    }
    let (w, h) = (w as usize, h as usize);
    let mut out = if (w, h) == (guide.width(), guide.height()) {
        guide.clone()
    } else {
        guide.resample(w, h)?
    };
    out.set_cell_size(cell.0, cell.1)?;
    // The same ground in `w x h` cells: the georeference keeps its origin, its pixel size
    // scaled by the resampling (the usual cross-DEM case, a guide coarser than the exemplars,
    // lost it).
    out.set_georef(guide.georef().map(|g| {
        g.window(
            0.0,
            0.0,
            guide.width() as f64 / w as f64,
            guide.height() as f64 / h as f64,
        )
    }));
    Ok(out)
}

/// How [`fit_to_size`] changed a guide: cells removed (crop) or added (mirror padding) along
/// each axis, split evenly between both sides.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct SizeFit {
    /// Columns and rows removed.
    pub cropped: (usize, usize),
    /// Columns and rows added.
    pub padded: (usize, usize),
}

/// Crops (centred) or pads (mirrored at the edges, so no flat band appears) the guide to
/// `width x height` cells without resampling: the guide keeps its cell size and scale (and its
/// georeference, moved to the new origin).
pub fn fit_to_size(
    guide: &Heightfield,
    width: usize,
    height: usize,
) -> Result<(Heightfield, SizeFit)> {
    guide.require_complete()?;
    check_size(width, height, || {
        format!("{width} x {height} is empty or too large")
    })?;
    let (gw, gh) = (guide.width(), guide.height());
    let fit = SizeFit {
        cropped: (gw.saturating_sub(width), gh.saturating_sub(height)),
        padded: (width.saturating_sub(gw), height.saturating_sub(gh)),
    };
    // Offset of the output's origin in guide cells (negative = padding).
    let ox = gw as isize / 2 - width as isize / 2;
    let oy = gh as isize / 2 - height as isize / 2;
    let mirror = |i: isize, n: usize| -> usize {
        let n = n as isize;
        if n == 1 {
            return 0;
        }
        let period = 2 * (n - 1);
        let m = i.rem_euclid(period);
        (if m < n { m } else { period - m }) as usize
    };
    let src = guide.as_slice();
    let mut data = Vec::with_capacity(width * height);
    for y in 0..height {
        let sy = mirror(oy + y as isize, gh);
        for x in 0..width {
            data.push(src[sy * gw + mirror(ox + x as isize, gw)]);
        }
    }
    let (cx, cy) = guide.cell_size();
    let mut out = Heightfield::new(width, height, data, cx, cy)?;
    // The output's origin is the guide's cell (ox, oy); padded cells extend the grid.
    out.set_georef(
        guide
            .georef()
            .map(|g| g.window(ox as f64, oy as f64, 1.0, 1.0)),
    );
    Ok((out, fit))
}

/// Target heights of [`map_range`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GuideRange {
    /// The exemplars' range: the 2-98 % quantiles of the patches' means, the heights a whole
    /// patch can actually bring.
    Auto,
    /// `lo..hi` metres.
    Metres(f32, f32),
}

/// The linear height mapping [`map_range`] applied.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RangeMapping {
    /// The guide's 2-98 % quantiles of its patch-sized window means (metres, before the
    /// mapping).
    pub from: (f32, f32),
    /// Where they were mapped (metres).
    pub to: (f32, f32),
}

/// Quantiles of the exemplar patches' means [`map_range`] maps onto.
const RANGE_Q: (f64, f64) = (0.02, 0.98);
/// Quantiles of the guide's window means [`map_range`] maps from: the extremes, so that no
/// part of the guide asks for heights beyond the exemplars' (window means are already robust
/// to single-cell outliers).
const GUIDE_Q: (f64, f64) = (0.0, 1.0);

fn quantiles(mut v: Vec<f32>, q: (f64, f64)) -> Option<(f32, f32)> {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return None;
    }
    v.sort_by(f32::total_cmp);
    let at = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    Some((at(q.0), at(q.1)))
}

/// Maps the guide's heights linearly so that the 2-98 % quantiles of its patch-sized window
/// means land on `range` (for [`GuideRange::Auto`], the same quantiles of the exemplar
/// patches' means): a guide from another DEM, or a sketch in grey levels, then asks for
/// heights the exemplars have at the scale of a patch (a narrow canyon floor has low cells but
/// no low patch). Its form (and so its correlation with the output) is kept.
pub fn map_range(
    guide: &Heightfield,
    index: &crate::ExemplarIndex,
    range: GuideRange,
) -> Result<(Heightfield, RangeMapping)> {
    map_range_q(guide, index, range, RANGE_Q)
}

/// Exemplar quantile pairs [`fit_range`] tries after the default 2-98 %: the top or the bottom
/// of the exemplars' range pulled in first (a guide's narrow ridges or flat lows may have no
/// counterpart at the exemplars' extremes), then both.
const FIT_Q: [(f64, f64); 9] = [
    (0.02, 0.98),
    (0.05, 0.98),
    (0.1, 0.98),
    (0.02, 0.995),
    (0.05, 0.995),
    (0.1, 0.995),
    (0.15, 0.995),
    (0.02, 0.95),
    (0.05, 0.95),
];

/// [`GuideRange::Auto`] checked by the input validation (section 4): the guide is mapped onto
/// the exemplar patches' 2-98 % mean range, and when some guide blocks then lack candidates,
/// onto narrower ranges of the exemplars (top, bottom, then both pulled in) until the
/// validation of `control` (its size and categorisation map; its guide is replaced) passes.
/// Returns the first mapping that passes, else the one with the fewest failing blocks, with
/// its validation report.
pub fn fit_range(
    guide: &Heightfield,
    index: &crate::ExemplarIndex,
    control: &crate::Control,
    settings: &crate::Settings,
) -> Result<(Heightfield, RangeMapping, crate::ValidationReport)> {
    let mut best: Option<(Heightfield, RangeMapping, crate::ValidationReport)> = None;
    for q in FIT_Q {
        let (g, m) = map_range_q(guide, index, GuideRange::Auto, q)?;
        let mut c = control.clone();
        c.guide = Some(g);
        let report = crate::validate(index, &c, settings)?;
        let g = c.guide.take().expect("guide set above");
        let ok = report.ok;
        if best
            .as_ref()
            .is_none_or(|b| report.failing.len() < b.2.failing.len())
        {
            best = Some((g, m, report));
        }
        if ok {
            break;
        }
    }
    best.ok_or(PatchSynthError::NoExemplars)
}

fn map_range_q(
    guide: &Heightfield,
    index: &crate::ExemplarIndex,
    range: GuideRange,
    exemplar_q: (f64, f64),
) -> Result<(Heightfield, RangeMapping)> {
    guide.require_complete()?;
    let b = index.built_with.patch_size;
    let (w, h) = (guide.width(), guide.height());
    let (bw, bh) = (b.min(w), b.min(h));
    let step = (b / 4).max(1);
    let src = guide.as_slice();
    let mut means = Vec::new();
    let mut y = 0;
    while y + bh <= h {
        let mut x = 0;
        while x + bw <= w {
            means.push(crate::grid::window_mean(src, w, x, y, bw, bh));
            x += step;
        }
        y += step;
    }
    let from = quantiles(means, GUIDE_Q).ok_or_else(|| PatchSynthError::InvalidControl {
        name: "guide",
        reason: "no block of the guide".into(),
    })?;
    let to = match range {
        GuideRange::Metres(lo, hi) => {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(PatchSynthError::setting(
                    "guide_range",
                    format!("{lo},{hi}"),
                    "must be two finite heights LO < HI",
                ));
            }
            (lo, hi)
        }
        GuideRange::Auto => quantiles(index.by_mean.iter().map(|v| v.0).collect(), exemplar_q)
            .ok_or(PatchSynthError::NoExemplars)?,
    };
    let span = (from.1 - from.0) as f64;
    let out = if span > 0.0 {
        let k = (to.1 - to.0) as f64 / span;
        guide.map(|v| (to.0 as f64 + (v - from.0) as f64 * k) as f32)
    } else {
        // A flat guide: centred on the target range.
        let mid = 0.5 * (to.0 + to.1);
        guide.map(|v| v - from.0 + mid)
    };
    Ok((out, RangeMapping { from, to }))
}

/// How [`fit_to_grid`] placed a guide on the output grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct GuideFit {
    /// The guide's ground extent in cells of the exemplars' cell size.
    pub extent: (usize, usize),
    /// Columns and rows cropped (centred) to reach the output size.
    pub cropped: (usize, usize),
    /// Columns and rows added by mirror padding to reach the output size.
    pub padded: (usize, usize),
}

/// The guide on the output grid at its own physical scale: resampled from its cell size to the
/// exemplars' `cell` (patches are copied cell for cell), then, with `size`, cropped (centred)
/// or mirror-padded to it ([`fit_to_size`]); without, the output covers the guide's ground and
/// keeps its georeference. A guide whose extent exceeds [`crate::MAX_OUTPUT_CELLS`] at `cell` is
/// cropped to the needed centre before the resampling (with `size`) or refused.
pub fn fit_to_grid(
    guide: &Heightfield,
    cell: (f64, f64),
    size: Option<(usize, usize)>,
) -> Result<(Heightfield, GuideFit)> {
    guide.require_complete()?;
    check_cell(cell)?;
    let (gx, gy) = guide.cell_size();
    let (kx, ky) = (gx / cell.0, gy / cell.1);
    let (rw, rh) = (
        (guide.width() as f64 * kx).round().max(1.0),
        (guide.height() as f64 * ky).round().max(1.0),
    );
    let mut g = std::borrow::Cow::Borrowed(guide);
    if rw * rh > crate::grid::MAX_OUTPUT_CELLS as f64 {
        let Some((w, h)) = size else {
            return Err(PatchSynthError::InvalidControl {
                name: "guide",
                reason: format!(
                    "it covers {rw} x {rh} cells of the exemplars' {:.2} x {:.2} m: give an \
                     output size (or the guide's cell size)",
                    cell.0, cell.1
                ),
            });
        };
        // Only the centre is used: crop it first (with a resampling margin).
        let need = |n: usize, k: f64| ((n as f64 / k).ceil() as usize).saturating_add(4);
        let (nw, nh) = (
            need(w, kx).min(guide.width()),
            need(h, ky).min(guide.height()),
        );
        g = std::borrow::Cow::Owned(guide.crop(
            (guide.width() - nw) / 2,
            (guide.height() - nh) / 2,
            nw,
            nh,
        )?);
    }
    let g = to_cell_size(&g, cell)?;
    let extent = (rw as usize, rh as usize);
    let Some((w, h)) = size else {
        return Ok((
            g,
            GuideFit {
                extent,
                ..Default::default()
            },
        ));
    };
    let (g2, fit) = fit_to_size(&g, w, h)?;
    Ok((
        g2,
        GuideFit {
            extent,
            cropped: (extent.0.saturating_sub(w), extent.1.saturating_sub(h)),
            padded: fit.padded,
        },
    ))
}

/// Length scale in cells below which `guide` carries no detail:
/// `sqrt(mean |grad g|^2 / mean (lap g)^2)` over the interior cells (central differences, the
/// 5-point Laplacian). A field blurred by a Gaussian of `sigma` cells scores about `sigma / 1.4`
/// for white noise and about `1.1 sigma` for real DEMs (alps, jacksboro at sigma 16: 19.5, 17.2);
/// a guide without curvature (flat or a plane) scores infinity, a guide under 3 x 3 cells 0.
pub fn smoothness_scale(guide: &Heightfield) -> f32 {
    let (w, h) = (guide.width(), guide.height());
    if w < 3 || h < 3 {
        return 0.0;
    }
    let v = guide.as_slice();
    let (mut g2, mut l2) = (0.0f64, 0.0f64);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            let (l, r, u, d, c) = (v[i - 1], v[i + 1], v[i - w], v[i + w], v[i]);
            if !(l.is_finite() && r.is_finite() && u.is_finite() && d.is_finite() && c.is_finite())
            {
                continue;
            }
            let (gx, gy) = (0.5 * (r - l) as f64, 0.5 * (d - u) as f64);
            let lap = (l + r + u + d) as f64 - 4.0 * c as f64;
            g2 += gx * gx + gy * gy;
            l2 += lap * lap;
        }
    }
    if l2 <= 0.0 {
        return f32::INFINITY;
    }
    (g2 / l2).sqrt() as f32
}
