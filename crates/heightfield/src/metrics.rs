//! Statistics and comparison measures: summary statistics, RMSE, PSNR over the elevation range,
//! and the terrain-realism measures the method crates report (radial power-spectrum slope and
//! slope-angle histogram distance).

use rustfft::{FftPlanner, num_complex::Complex};
use serde::{Deserialize, Serialize};

use crate::error::{HeightfieldError, Result};
use crate::grid::Heightfield;
use crate::terrain::slope_degrees;

/// Summary statistics over valid cells.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    /// Smallest valid elevation.
    pub min: f64,
    /// Largest valid elevation.
    pub max: f64,
    /// Mean elevation.
    pub mean: f64,
    /// Standard deviation of the elevation.
    pub std: f64,
    /// Number of valid cells.
    pub valid: usize,
    /// Number of void cells.
    pub voids: usize,
}

/// Summary statistics; an error if every cell is void.
pub fn stats(hf: &Heightfield) -> Result<Stats> {
    let (mut n, mut s, mut s2) = (0usize, 0.0f64, 0.0f64);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &v in hf.as_slice() {
        if v.is_finite() {
            let v = v as f64;
            n += 1;
            s += v;
            s2 += v * v;
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if n == 0 {
        return Err(HeightfieldError::AllVoid { count: hf.len() });
    }
    let mean = s / n as f64;
    let var = (s2 / n as f64 - mean * mean).max(0.0);
    Ok(Stats {
        min: lo,
        max: hi,
        mean,
        std: var.sqrt(),
        valid: n,
        voids: hf.len() - n,
    })
}

fn same_size(a: &Heightfield, b: &Heightfield) -> Result<()> {
    if a.width() != b.width() || a.height() != b.height() {
        return Err(HeightfieldError::SizeMismatch {
            a_w: a.width(),
            a_h: a.height(),
            b_w: b.width(),
            b_h: b.height(),
        });
    }
    Ok(())
}

/// Root-mean-square difference over cells valid in both grids.
pub fn rmse(a: &Heightfield, b: &Heightfield) -> Result<f64> {
    same_size(a, b)?;
    let (mut n, mut s) = (0usize, 0.0f64);
    for (x, y) in a.as_slice().iter().zip(b.as_slice()) {
        if x.is_finite() && y.is_finite() {
            let d = (*x - *y) as f64;
            s += d * d;
            n += 1;
        }
    }
    if n == 0 {
        return Err(HeightfieldError::AllVoid { count: a.len() });
    }
    Ok((s / n as f64).sqrt())
}

/// Largest absolute difference over cells valid in both grids.
pub fn max_abs_diff(a: &Heightfield, b: &Heightfield) -> Result<f64> {
    same_size(a, b)?;
    Ok(a.as_slice()
        .iter()
        .zip(b.as_slice())
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .map(|(x, y)| (*x as f64 - *y as f64).abs())
        .fold(0.0, f64::max))
}

/// PSNR in dB of `test` against `reference`, with the reference's elevation range as the peak:
/// `20 log10(range / rmse)` (guerin2016 uses this in table 1). Infinite for identical grids.
pub fn psnr(reference: &Heightfield, test: &Heightfield) -> Result<f64> {
    let e = rmse(reference, test)?;
    let range = reference.relief() as f64;
    Ok(if e == 0.0 {
        f64::INFINITY
    } else {
        20.0 * (range.max(1e-12) / e).log10()
    })
}

/// Radially averaged power spectrum of the (mean-removed, Hann-windowed) grid: pairs
/// `(frequency in cycles per metre, power)`, one per integer radius in the centred spectrum.
/// Needs a void-free grid of at least 8 x 8.
pub fn radial_power_spectrum(hf: &Heightfield) -> Result<Vec<(f64, f64)>> {
    hf.require_complete()?;
    let (w, h) = (hf.width(), hf.height());
    if w < 8 || h < 8 {
        return Err(HeightfieldError::param(
            "size",
            format!("{w}x{h}"),
            "spectrum needs >= 8x8",
        ));
    }
    let mean = hf.as_slice().iter().map(|&v| v as f64).sum::<f64>() / hf.len() as f64;
    let hann = |i: usize, n: usize| {
        0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / (n - 1) as f64).cos()
    };
    let mut buf: Vec<Complex<f64>> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| Complex::new((hf.get(x, y) as f64 - mean) * hann(x, w) * hann(y, h), 0.0))
        .collect();
    let mut planner = FftPlanner::<f64>::new();
    let fr = planner.plan_fft_forward(w);
    for row in buf.chunks_exact_mut(w) {
        fr.process(row);
    }
    let fc = planner.plan_fft_forward(h);
    let mut col = vec![Complex::new(0.0, 0.0); h];
    for x in 0..w {
        for y in 0..h {
            col[y] = buf[y * w + x];
        }
        fc.process(&mut col);
        for y in 0..h {
            buf[y * w + x] = col[y];
        }
    }
    let (cx, cy) = hf.cell_size();
    // Radius in units of the frequency step of the shorter side's physical length.
    let (lx, ly) = (w as f64 * cx, h as f64 * cy);
    let df = 1.0 / lx.max(ly);
    let nbins = ((0.5 / cx.max(cy)) / df).floor() as usize + 1;
    let mut power = vec![0.0f64; nbins];
    let mut count = vec![0usize; nbins];
    // The signed frequency of FFT index `i` of `n` over a side of length `l`.
    let freq = |i: usize, n: usize, l: f64| {
        let k = if i <= n / 2 {
            i as f64
        } else {
            i as f64 - n as f64
        };
        k / l
    };
    for y in 0..h {
        let ky = freq(y, h, ly);
        for x in 0..w {
            let kx = freq(x, w, lx);
            let r = ((kx * kx + ky * ky).sqrt() / df).round() as usize;
            if r < nbins {
                power[r] += buf[y * w + x].norm_sqr();
                count[r] += 1;
            }
        }
    }
    Ok((1..nbins)
        .filter(|&r| count[r] > 0)
        .map(|r| (r as f64 * df, power[r] / count[r] as f64))
        .collect())
}

/// Least-squares slope of `log10 power` against `log10 frequency` for frequencies in
/// `[f_lo, f_hi]` (cycles per metre). Natural terrain gives about -2 to -3.5; white noise 0.
pub fn spectral_slope(spectrum: &[(f64, f64)], f_lo: f64, f_hi: f64) -> Result<f64> {
    let pts: Vec<(f64, f64)> = spectrum
        .iter()
        .filter(|(f, p)| *f >= f_lo && *f <= f_hi && *p > 0.0)
        .map(|(f, p)| (f.log10(), p.log10()))
        .collect();
    if pts.len() < 2 {
        return Err(HeightfieldError::param(
            "band",
            format!("[{f_lo}, {f_hi}]"),
            "fewer than 2 spectrum points",
        ));
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    Ok(if sxx > 0.0 { sxy / sxx } else { 0.0 })
}

/// Normalised histogram of slope angles in 1-degree bins over `[0, 90)`.
pub fn slope_histogram(hf: &Heightfield) -> Vec<f64> {
    let s = slope_degrees(hf);
    let mut hist = vec![0.0f64; 90];
    let mut n = 0usize;
    for v in s.iter().filter(|v| v.is_finite()) {
        hist[(*v as usize).min(89)] += 1.0;
        n += 1;
    }
    if n > 0 {
        hist.iter_mut().for_each(|h| *h /= n as f64);
    }
    hist
}

/// Earth mover's distance between two normalised 1-degree histograms, in degrees: how far, on
/// average, slope angles must move to turn one distribution into the other.
pub fn histogram_emd(a: &[f64], b: &[f64]) -> f64 {
    let (mut ca, mut cb, mut d) = (0.0, 0.0, 0.0);
    for i in 0..a.len().max(b.len()) {
        ca += a.get(i).copied().unwrap_or(0.0);
        cb += b.get(i).copied().unwrap_or(0.0);
        d += (ca - cb).abs();
    }
    d
}

/// Slope-angle histogram distance (EMD in degrees) between two terrains.
pub fn slope_histogram_distance(a: &Heightfield, b: &Heightfield) -> f64 {
    histogram_emd(&slope_histogram(a), &slope_histogram(b))
}

/// The detail `output - reference` (row-major, `f64`) and its mean, on which the
/// grid-artifact measures work ([`detail_swing`], and the phase swing and repeat score of
/// relief-dictionary-learning). The grids must have the same size.
pub fn difference_field(output: &Heightfield, reference: &Heightfield) -> Result<(Vec<f64>, f64)> {
    same_size(output, reference)?;
    let d: Vec<f64> = output
        .as_slice()
        .iter()
        .zip(reference.as_slice())
        .map(|(a, b)| *a as f64 - *b as f64)
        .collect();
    let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
    Ok((d, mean))
}

/// Grid-artifact swing of `output - reference` (the definition of
/// `shared/tools/terrain_quality.py`): the mean-removed squared difference is averaged into row
/// and column profiles; for periods 4, 8, 16 and 32 px (profiles of at least 12 periods) the
/// profile's sums per phase modulo the period are compared, max / min. The worst over periods
/// and axes is returned (1 = no phase dependence). A grid of primitives or dyadic blocks raises
/// it.
pub fn detail_swing(output: &Heightfield, reference: &Heightfield) -> Result<f64> {
    let (d, mean) = difference_field(output, reference)?;
    let (w, h) = (output.width(), output.height());
    let mut rows = vec![0.0f64; h];
    let mut cols = vec![0.0f64; w];
    for y in 0..h {
        for x in 0..w {
            let e = (d[y * w + x] - mean).powi(2);
            rows[y] += e / w as f64;
            cols[x] += e / h as f64;
        }
    }
    let mut worst = 1.0f64;
    for prof in [&rows, &cols] {
        for p in [4usize, 8, 16, 32] {
            let n = prof.len() / p * p;
            if n < 12 * p {
                continue;
            }
            let mut ph = vec![0.0f64; p];
            for (i, v) in prof[..n].iter().enumerate() {
                ph[i % p] += v;
            }
            let (lo, hi) = ph
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(l, u), &v| (l.min(v), u.max(v)));
            worst = worst.max(hi / lo.max(1e-12 * (n / p) as f64));
        }
    }
    Ok(worst)
}

/// The `q`-quantile (`0..=1`, nearest rank) of the finite values of `values`; `None` when none
/// is finite. Sorts a copy: O(n log n) time, O(n) memory.
///
/// ```
/// use relief_heightfield::metrics::quantile;
/// assert_eq!(quantile(&[3.0, f32::NAN, 1.0, 2.0], 0.5), Some(2.0));
/// assert_eq!(quantile(&[f32::NAN], 0.5), None);
/// ```
pub fn quantile(values: &[f32], q: f64) -> Option<f32> {
    let mut v: Vec<f32> = values.iter().copied().filter(|z| z.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f32::total_cmp);
    Some(v[((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize])
}

/// Linear-interpolated percentile (`q` in `0..=100`) of sorted values (numpy's default); 0
/// when empty.
///
/// ```
/// use relief_heightfield::metrics::percentile_sorted;
/// assert_eq!(percentile_sorted(&[1.0, 2.0, 3.0, 4.0], 50.0), 2.5);
/// assert_eq!(percentile_sorted(&[1.0, 2.0, 3.0, 4.0], 100.0), 4.0);
/// ```
pub fn percentile_sorted(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let pos = q / 100.0 * (sorted.len() - 1) as f64;
    let i = pos.floor() as usize;
    let f = pos - i as f64;
    let next = sorted[(i + 1).min(sorted.len() - 1)];
    sorted[i] * (1.0 - f) + next * f
}

/// Pearson correlation of two equally long series (0 when either is constant).
///
/// ```
/// use relief_heightfield::metrics::pearson;
/// assert!((pearson(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.5]) - 1.0).abs() < 0.01);
/// assert!((pearson(&[1.0, 2.0, 3.0], &[3.0, 2.0, 1.0]) + 1.0).abs() < 1e-9);
/// ```
pub fn pearson(a: &[f32], b: &[f32]) -> f64 {
    let n = a.len().min(b.len()).max(1) as f64;
    let ma = a.iter().map(|&v| v as f64).sum::<f64>() / n;
    let mb = b.iter().map(|&v| v as f64).sum::<f64>() / n;
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        let (dx, dy) = (x as f64 - ma, y as f64 - mb);
        sab += dx * dy;
        saa += dx * dx;
        sbb += dy * dy;
    }
    sab / (saa * sbb).sqrt().max(1e-300)
}
