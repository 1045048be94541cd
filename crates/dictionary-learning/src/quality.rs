//! Quality measures of amplification on real data (the protocol of the issue): a real DEM crop
//! is reduced, amplified back, and compared with the truth.

use relief_heightfield::{Heightfield, metrics};

use crate::error::{LearnError, Result};

/// One row of the quality table.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QualityRow {
    /// (a) consistency: RMSE between the output reduced to the input's size (Lanczos) and the
    /// input, divided by the input's relief (max - min).
    pub consistency: f64,
    /// (b) spectral slope of the output over the added octaves (frequencies above the input's
    /// Nyquist frequency).
    pub added_slope: f64,
    /// (b) the truth's spectral slope over the same band.
    pub truth_slope: f64,
    /// (c) slope-angle histogram distance (EMD, degrees) between output and truth.
    pub slope_hist_distance: f64,
    /// RMSE between output and truth, relative to the truth's relief (for information).
    pub truth_rmse: f64,
}

/// Evaluates `output` (same size as `truth`) amplified from `input` (the reduced truth).
pub fn evaluate(
    truth: &Heightfield,
    input: &Heightfield,
    output: &Heightfield,
) -> Result<QualityRow> {
    if truth.width() != output.width() || truth.height() != output.height() {
        return Err(LearnError::param(
            "output",
            format!("{}x{}", output.width(), output.height()),
            "must have the truth's size",
        ));
    }
    let reduced = output.resample(input.width(), input.height())?;
    let relief = (input.relief() as f64).max(1e-9);
    let consistency = metrics::rmse(&reduced, input)? / relief;
    let (cx, cy) = input.cell_size();
    let f_lo = 0.5 / cx.max(cy);
    let (tx, ty) = truth.cell_size();
    let f_hi = 0.5 / tx.max(ty);
    let st = metrics::radial_power_spectrum(truth)?;
    let so = metrics::radial_power_spectrum(output)?;
    let truth_slope = metrics::spectral_slope(&st, f_lo, f_hi)?;
    let added_slope = metrics::spectral_slope(&so, f_lo, f_hi)?;
    let slope_hist_distance = metrics::slope_histogram_distance(output, truth);
    let truth_rmse = metrics::rmse(output, truth)? / (truth.relief() as f64).max(1e-9);
    Ok(QualityRow {
        consistency,
        added_slope,
        truth_slope,
        slope_hist_distance,
        truth_rmse,
    })
}

/// One row of the box protocol of issue 15 (the measures of `shared/tools/terrain_quality.py`):
/// the coarse input is `box-down(truth, F)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoxProtocolRow {
    /// RMS of `box-down(output, F) - input`, over the truth's relief (max - min).
    pub consistency: f64,
    /// `|spectral slope(output) - spectral slope(truth)|` over the added octaves (from the
    /// input's Nyquist frequency to the output's).
    pub slope_error: f64,
    /// `spectral slope(output) - spectral slope(truth)` (negative: too little fine detail).
    pub slope_signed: f64,
    /// Slope-angle histogram distance (EMD, degrees, 1-degree bins) to the truth.
    pub slope_emd: f64,
    /// 5-point Laplacian histogram distance to the truth (90 bins clipped at the truth's 99th
    /// percentile of `|Laplacian|`, EMD divided by that percentile).
    pub curvature_emd: f64,
    /// Detail-energy phase swing of `output - bicubic(input)` ([`detail_swing`]), with the
    /// corner-aligned bicubic of the reference tool ([`corner_bicubic`]).
    pub swing: f64,
}

/// Cubic up-sampling to `w x h` exactly as the reference tool's `scipy.ndimage.zoom(C, F,
/// order=3)`: [`Heightfield::spline_zoom`] (corners aligned, so the detail `output - bicubic`
/// has little phase structure of its own at the factor's period and the swing measures the
/// method's grid, not the interpolation's).
pub fn corner_bicubic(input: &Heightfield, w: usize, h: usize) -> Result<Heightfield> {
    Ok(input.spline_zoom(w, h)?)
}

/// Box protocol: `truth` (cropped to a multiple of `factor`), `input = box-down(truth)`,
/// `output` of the truth's size. See [`BoxProtocolRow`].
pub fn box_protocol(
    truth: &Heightfield,
    input: &Heightfield,
    output: &Heightfield,
    factor: usize,
) -> Result<BoxProtocolRow> {
    if truth.width() != output.width()
        || truth.height() != output.height()
        || input.width() * factor != truth.width()
        || input.height() * factor != truth.height()
    {
        return Err(LearnError::param(
            "output",
            format!("{}x{}", output.width(), output.height()),
            "must have the truth's size, the input factor times smaller",
        ));
    }
    let relief = (truth.relief() as f64).max(1e-9);
    let consistency = metrics::rmse(&output.downsample_box(factor)?, input)? / relief;
    let (cx, cy) = input.cell_size();
    let f_lo = 0.5 / cx.max(cy);
    let (tx, ty) = truth.cell_size();
    let f_hi = 0.5 / tx.max(ty);
    let st = metrics::spectral_slope(&metrics::radial_power_spectrum(truth)?, f_lo, f_hi)?;
    let so = metrics::spectral_slope(&metrics::radial_power_spectrum(output)?, f_lo, f_hi)?;
    let bicubic = corner_bicubic(input, truth.width(), truth.height())?;
    Ok(BoxProtocolRow {
        consistency,
        slope_error: (so - st).abs(),
        slope_signed: so - st,
        slope_emd: metrics::slope_histogram_distance(output, truth),
        curvature_emd: laplacian_histogram_distance(output, truth),
        swing: detail_swing(output, &bicubic)?,
    })
}

/// Laplacian-curvature histogram distance of `a` to `truth` (see
/// [`BoxProtocolRow::curvature_emd`]); 0 for grids smaller than 3 x 3.
pub fn laplacian_histogram_distance(a: &Heightfield, truth: &Heightfield) -> f64 {
    let (la, lt) = (
        relief_heightfield::terrain::laplacian(a),
        relief_heightfield::terrain::laplacian(truth),
    );
    if la.is_empty() || lt.is_empty() {
        return 0.0;
    }
    let mut abs: Vec<f64> = lt.iter().map(|v| v.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let ls = abs[((abs.len() - 1) as f64 * 0.99).round() as usize].max(1e-12);
    let hist = |v: &[f64]| {
        let mut hi = vec![0.0f64; 90];
        for &x in v {
            let t = ((x.clamp(-ls, ls) + ls) / (2.0 * ls) * 90.0).floor() as usize;
            hi[t.min(89)] += 1.0;
        }
        let n = v.len() as f64;
        hi.iter_mut().for_each(|h| *h /= n);
        hi
    };
    metrics::histogram_emd(&hist(&la), &hist(&lt)) * (2.0 * ls / 90.0) / ls
}

/// Refuses a reference of another size than the output.
fn check_reference(output: &Heightfield, reference: &Heightfield) -> Result<()> {
    if output.width() != reference.width() || output.height() != reference.height() {
        return Err(LearnError::param(
            "reference",
            format!("{}x{}", reference.width(), reference.height()),
            "must have the output's size",
        ));
    }
    Ok(())
}

/// Detail-energy phase swing of `output - reference` (the reference is usually the bicubic
/// up-sampling of the input): the squared mean-removed detail averaged along rows and along
/// columns gives two profiles; for periods 4, 8, 16 and 32 (when the profile holds at least 12
/// periods) the profile's means per phase modulo the period are compared, max / min. The worst
/// over periods and axes is returned (1 = no phase dependence). A grid of primitives or dyadic
/// blocks raises it; real terrain gives about 1.06.
pub fn detail_swing(output: &Heightfield, reference: &Heightfield) -> Result<f64> {
    check_reference(output, reference)?;
    Ok(relief_heightfield::metrics::detail_swing(
        output, reference,
    )?)
}

/// Real terrain's own [`detail_swing`] at a given size: the median, over up to 3 x 3 crops of
/// `side x side` cells spread evenly over `terrain`, of the swing of each crop against the
/// [`corner_bicubic`] of its box-down by `factor` (the reference tool's "compare with TRUTH's
/// own swing"). Non-stationary relief makes the estimator far from 1 on real crops (1.3-1.5 at
/// 256^2-752^2 on alps_dem, carrizo and grandcanyon), so a step's swing is judged against this
/// floor at the same size when no truth exists (the finer steps of a x256 run). `side` is
/// clamped to the terrain and rounded down to a multiple of `factor`.
pub fn swing_floor(terrain: &Heightfield, side: usize, factor: usize) -> Result<f64> {
    if factor < 2 {
        return Err(LearnError::param("factor", factor, "must be at least 2"));
    }
    let side = side.min(terrain.width()).min(terrain.height()) / factor * factor;
    if side < 2 * factor {
        return Err(LearnError::param(
            "side",
            side,
            "must hold at least 2 x 2 cells of the factor",
        ));
    }
    let at = |n: usize, k: usize| (n - side) * k / 2;
    let mut corners: Vec<(usize, usize)> = (0..9)
        .map(|k| (at(terrain.width(), k % 3), at(terrain.height(), k / 3)))
        .collect();
    corners.sort_unstable();
    corners.dedup();
    let mut swings = Vec::with_capacity(corners.len());
    for (x, y) in corners {
        let crop = terrain.crop(x, y, side, side)?;
        let input = crop.downsample_box(factor)?;
        swings.push(detail_swing(&crop, &corner_bicubic(&input, side, side)?)?);
    }
    swings.sort_by(f64::total_cmp);
    Ok(swings[swings.len() / 2])
}

/// Phase swing of the output's own high-pass: [`detail_swing`] of the output against its
/// Gaussian blur of 2 pixels. No interpolated reference whose error depends on the phase
/// modulo the input's cells (the truth itself scores 1.4-2.0 against a bicubic reference), so
/// a pattern of the method shows alone; a real 512^2 DEM crop scores 1.2-1.3 (estimation noise
/// of heavy-tailed relief), and large outputs less.
pub fn highpass_swing(output: &Heightfield) -> Result<f64> {
    detail_swing(output, &output.gaussian_blur(2.0)?)
}

/// Phase swing of `output - reference` at one period `period` (pixels), robust to
/// non-stationary relief: the squared mean-removed detail of every aligned `period x period`
/// block is divided by the block's mean, these relative energies are averaged per phase over
/// the blocks, and the per-phase profiles along x and along y (averaged over the other axis)
/// give max / min; the worse axis is returned. Stationary detail gives 1 up to estimation
/// noise; a grid of primitives with that spacing raises it.
pub fn phase_swing(output: &Heightfield, reference: &Heightfield, period: usize) -> Result<f64> {
    check_reference(output, reference)?;
    let p = period;
    let (w, h) = (output.width(), output.height());
    if p < 2 || w < 2 * p || h < 2 * p {
        return Err(LearnError::param(
            "period",
            p,
            "must be >= 2 and leave at least 2 x 2 blocks",
        ));
    }
    let (d, mean) = metrics::difference_field(output, reference)?;
    let mut phase = vec![0.0f64; p * p];
    let mut blocks = 0usize;
    for by in 0..h / p {
        for bx in 0..w / p {
            let mut s = 0.0;
            for y in 0..p {
                for x in 0..p {
                    s += (d[(by * p + y) * w + bx * p + x] - mean).powi(2);
                }
            }
            if s <= 0.0 {
                continue;
            }
            let norm = (p * p) as f64 / s;
            for y in 0..p {
                for x in 0..p {
                    phase[y * p + x] += (d[(by * p + y) * w + bx * p + x] - mean).powi(2) * norm;
                }
            }
            blocks += 1;
        }
    }
    if blocks == 0 {
        return Ok(1.0);
    }
    let mut px = vec![0.0f64; p];
    let mut py = vec![0.0f64; p];
    for y in 0..p {
        for x in 0..p {
            px[x] += phase[y * p + x];
            py[y] += phase[y * p + x];
        }
    }
    let ratio = |v: &[f64]| {
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(l, u), &x| (l.min(x), u.max(x)));
        hi / lo.max(1e-300)
    };
    Ok(ratio(&px).max(ratio(&py)))
}

/// Repeat score of the detail `output - reference` at a lag of `lag` pixels (the fine grid
/// step of the primitives, `4 S` at each x4 step): the autocorrelation of the mean-removed
/// detail at `lag` along x (resp. y) minus the mean of its autocorrelations at `lag - 2` and
/// `lag + 2`; the larger of the two axes is returned. A natural detail's autocorrelation
/// decays smoothly with the lag (score `<= ~0.01`); one detail repeated on the grid of
/// primitives (the same atom picked by a row of neighbouring primitives) makes a peak at the
/// grid step, seen as short horizontal and vertical streaks and dotted rows in hillshades.
pub fn repeat_score(output: &Heightfield, reference: &Heightfield, lag: usize) -> Result<f64> {
    check_reference(output, reference)?;
    let (w, h) = (output.width(), output.height());
    if lag < 3 || w <= 2 * (lag + 2) || h <= 2 * (lag + 2) {
        return Err(LearnError::param(
            "lag",
            lag,
            "must be >= 3 and leave the grid at least twice lag + 2 wide",
        ));
    }
    let (d, mean) = metrics::difference_field(output, reference)?;
    let d: Vec<f64> = d.iter().map(|v| v - mean).collect();
    let var = d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64;
    if var <= 0.0 {
        return Ok(0.0);
    }
    // Autocorrelation at lag `k` along x (`dx = 1`) or y, over the pairs inside the grid.
    let corr = |k: usize, along_x: bool| -> f64 {
        let (mut s, mut c) = (0.0f64, 0usize);
        for y in 0..h - if along_x { 0 } else { k } {
            for x in 0..w - if along_x { k } else { 0 } {
                let q = if along_x {
                    y * w + x + k
                } else {
                    (y + k) * w + x
                };
                s += d[y * w + x] * d[q];
                c += 1;
            }
        }
        s / c.max(1) as f64 / var
    };
    let score = |along_x: bool| {
        corr(lag, along_x) - 0.5 * (corr(lag - 2, along_x) + corr(lag + 2, along_x))
    };
    Ok(score(true).max(score(false)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hash noise in `[-0.5, 0.5)`, one stream per `seed`.
    fn noise(seed: u64) -> impl Fn(usize, usize) -> f32 + Copy {
        move |x, y| {
            relief_heightfield::rng::unit_f32(relief_heightfield::rng::hash(
                0x5eed, x as u64, y as u64, seed,
            )) - 0.5
        }
    }

    #[test]
    fn repeat_score_sees_a_detail_repeated_on_the_grid() {
        // Hash noise (no structure) against the same noise plus one bump repeated every 8 px.
        let noise = noise(0);
        let flat = Heightfield::from_fn(96, 96, 1.0, 1.0, |_, _| 0.0);
        let n = Heightfield::from_fn(96, 96, 1.0, 1.0, noise);
        let bump = |x: usize| {
            let u = (x % 8) as f32 - 3.5;
            (-(u * u) / 2.0).exp()
        };
        let w = Heightfield::from_fn(96, 96, 1.0, 1.0, |x, y| noise(x, y) + bump(x) * bump(y));
        let (sn, sw) = (
            repeat_score(&n, &flat, 8).unwrap(),
            repeat_score(&w, &flat, 8).unwrap(),
        );
        assert!(sn.abs() < 0.03, "{sn}");
        assert!(sw > 0.2, "{sw}");
        assert!(repeat_score(&n, &flat, 2).is_err());
        assert!(repeat_score(&n, &n.crop(0, 0, 90, 96).unwrap(), 8).is_err());
    }

    #[test]
    fn corner_bicubic_is_scipy_zoom_order_3() {
        // scipy.ndimage.zoom(C, 4, order=3) of this 6 x 5 grid (scipy 1.17), at a few samples:
        // corners, edges (mirrored taps) and the interior.
        let c = Heightfield::from_fn(6, 5, 1.0, 1.0, |x, y| {
            ((y * 7 + x * 3) % 11) as f32 - 0.5 * y as f32
        });
        let z = corner_bicubic(&c, 24, 20).unwrap();
        for (y, x, want) in [
            (0, 0, 0.0),
            (0, 1, 0.24105323718600385),
            (1, 2, 1.5974158191508543),
            (7, 9, 4.522465630509616),
            (13, 22, 1.6385500253214935),
            (19, 23, 8.0),
            (10, 5, 4.581008435419623),
        ] {
            let got = f64::from(z.get(x, y));
            assert!((got - want).abs() < 1e-5, "({x}, {y}): {got} vs {want}");
        }
        assert_eq!(z.cell_size(), (0.25, 0.25));
        assert!(corner_bicubic(&c, 0, 20).is_err());
    }

    #[test]
    fn swing_floor_of_stationary_noise_is_near_one_and_sees_blocks() {
        let noise = noise(1);
        let flat = Heightfield::from_fn(320, 256, 1.0, 1.0, noise);
        let f = swing_floor(&flat, 192, 4).unwrap();
        assert!((1.0..1.15).contains(&f), "{f}");
        // The same noise, stronger on every 8th column: a grid the floor must see.
        let grid = Heightfield::from_fn(320, 256, 1.0, 1.0, |x, y| {
            noise(x, y) * if x % 8 == 0 { 3.0 } else { 1.0 }
        });
        let g = swing_floor(&grid, 192, 4).unwrap();
        assert!(g > 2.0, "{g}");
        // Side clamped to the terrain; too small or a factor below 2 is an error.
        assert!(swing_floor(&flat, 10_000, 4).is_ok());
        assert!(swing_floor(&flat, 7, 4).is_err());
        assert!(swing_floor(&flat, 64, 1).is_err());
    }
}
