//! The quality protocol of issue 16 (a port of `shared/tools/terrain_quality.py`): a truth crop
//! `T` is box down-sampled by `F` to the coarse input `C`, refined back by `log2 F` levels, and
//! the output `O` is compared with `T`:
//!
//! * `consistency`: `RMS(box-down(O, F) - C) / (max - min of T)`;
//! * `dslope`: `|spectral slope(O) - spectral slope(T)|` of the radially averaged power spectrum
//!   (mean removed, Hann window, the largest top-left square), fitted over the added octaves
//!   (frequencies from `1/F` of the Nyquist frequency up to it);
//! * `slope_emd`: 1-D Wasserstein distance between the slope-angle histograms (degrees);
//! * `curv_emd`: the same for the 5-point Laplacian, clipped at `T`'s 99th percentile `L` of
//!   `|Laplacian|` (90 bins over `[-L, L]`), divided by `L`;
//! * `swing`: detail-energy swing, `e = (O - bicubic(C))^2` averaged along rows and along
//!   columns; for periods `P` in 4, 8, 16, 32 (profiles of at least 12 periods) the max/min of
//!   the phase means of `e` modulo `P`, the worst over periods and axes (dyadic blocks or grids
//!   raise it; compare with `T`'s own).
//!
//! Differences from the Python reference: slopes and Laplacians use the true east-west and
//! north-south cell sizes (the script takes one cell size), the bicubic baseline is
//! [`Heightfield::resample`] (Keys cubic, cell-centre aligned; the script uses a cubic spline
//! zoom), and spectrum radii are rounded rather than truncated.

use relief_heightfield::Heightfield;
use relief_heightfield::metrics::{
    radial_power_spectrum, slope_histogram_distance, spectral_slope,
};

use crate::error::{Result, WaveletError};

/// Scores of one output against the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scores {
    /// `RMS(box-down(O, F) - C) / relief(T)` (a fraction, not %).
    pub consistency: f64,
    /// Spectral slope of the output over the added octaves.
    pub spectral_slope: f64,
    /// `|spectral_slope - truth's|`.
    pub dslope: f64,
    /// Slope-angle histogram EMD (degrees).
    pub slope_emd: f64,
    /// Laplacian histogram EMD, relative to the truth's 99th percentile of `|Laplacian|`.
    pub curv_emd: f64,
    /// Detail-energy swing (1 = none).
    pub swing: f64,
}

/// The truth, its coarse version and the references the scores need.
#[derive(Debug, Clone)]
pub struct Protocol {
    /// The truth crop, trimmed to a multiple of `factor`.
    pub truth: Heightfield,
    /// `box-down(truth, factor)`: the input of the refinement.
    pub coarse: Heightfield,
    /// Bicubic up-sampling of `coarse` to the truth's size (the baseline).
    pub bicubic: Heightfield,
    /// Amplification factor `F` (a power of two for the wavelet refinement).
    pub factor: usize,
    /// Spectral slope of the truth over the added octaves.
    pub truth_slope: f64,
    /// Detail-energy swing of the truth (`truth - bicubic`).
    pub truth_swing: f64,
    lap_clip: f64,
    lap_hist: Vec<f64>,
}

impl Protocol {
    /// Prepares the protocol for a void-free truth and a factor `>= 2`.
    pub fn new(truth: &Heightfield, factor: usize) -> Result<Self> {
        if factor < 2 || truth.width() < 8 * factor || truth.height() < 8 * factor {
            return Err(WaveletError::param(
                "factor",
                factor,
                "must be >= 2 with a truth of at least 8 * factor cells per side",
            ));
        }
        truth.require_complete()?;
        let (w, h) = (
            truth.width() / factor * factor,
            truth.height() / factor * factor,
        );
        let truth = truth.crop(0, 0, w, h)?;
        let coarse = truth.downsample_box(factor)?;
        let bicubic = coarse.resample(w, h)?;
        let truth_slope = added_octave_slope(&truth, factor)?;
        let truth_swing = swing(&truth, &bicubic);
        let lt = laplacian(&truth);
        let mut abs: Vec<f64> = lt.iter().map(|v| v.abs()).collect();
        abs.sort_by(f64::total_cmp);
        let lap_clip = percentile(&abs, 99.0).max(1e-12);
        let lap_hist = histogram(&lt, lap_clip);
        Ok(Self {
            truth,
            coarse,
            bicubic,
            factor,
            truth_slope,
            truth_swing,
            lap_clip,
            lap_hist,
        })
    }

    /// Scores an output (at least the truth's size; cropped to it).
    pub fn score(&self, output: &Heightfield) -> Result<Scores> {
        let (w, h) = (self.truth.width(), self.truth.height());
        if output.width() < w || output.height() < h {
            return Err(WaveletError::param(
                "output",
                format!("{} x {}", output.width(), output.height()),
                "must be at least the truth's size",
            ));
        }
        let o = output.crop(0, 0, w, h)?;
        let down = o.downsample_box(self.factor)?;
        let se: f64 = down
            .as_slice()
            .iter()
            .zip(self.coarse.as_slice())
            .map(|(a, b)| (*a as f64 - *b as f64).powi(2))
            .sum();
        let consistency = (se / down.len() as f64).sqrt() / (self.truth.relief() as f64).max(1e-12);
        let spectral_slope = added_octave_slope(&o, self.factor)?;
        let curv = histogram(&laplacian(&o), self.lap_clip);
        let curv_emd = emd(&curv, &self.lap_hist) * (2.0 / 90.0);
        Ok(Scores {
            consistency,
            spectral_slope,
            dslope: (spectral_slope - self.truth_slope).abs(),
            slope_emd: slope_histogram_distance(&o, &self.truth),
            curv_emd,
            swing: swing(&o, &self.bicubic),
        })
    }
}

/// Spectral slope over the added octaves of the largest top-left square (frequencies in cycles
/// per sample, `[1 / (2F), 1/2]`).
pub fn added_octave_slope(hf: &Heightfield, factor: usize) -> Result<f64> {
    let n = hf.width().min(hf.height());
    let sq = hf.crop(0, 0, n, n)?;
    let unit = Heightfield::new(n, n, sq.as_slice().to_vec(), 1.0, 1.0)?;
    let spec = radial_power_spectrum(&unit)?;
    Ok(spectral_slope(&spec, 0.5 / factor as f64, 0.5)?)
}

/// 5-point Laplacian of the interior cells (m / m^2, true cell sizes).
fn laplacian(hf: &Heightfield) -> Vec<f64> {
    let (w, h) = (hf.width(), hf.height());
    let (cx, cy) = hf.cell_size();
    let z = hf.as_slice();
    let mut out = Vec::with_capacity(w.saturating_sub(2) * h.saturating_sub(2));
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let c = z[y * w + x] as f64;
            let dx = z[y * w + x - 1] as f64 + z[y * w + x + 1] as f64 - 2.0 * c;
            let dy = z[(y - 1) * w + x] as f64 + z[(y + 1) * w + x] as f64 - 2.0 * c;
            out.push(dx / (cx * cx) + dy / (cy * cy));
        }
    }
    out
}

/// Linear-interpolated percentile of sorted values (numpy's default).
fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let pos = q / 100.0 * (sorted.len() - 1) as f64;
    let i = pos.floor() as usize;
    let f = pos - i as f64;
    let next = sorted[(i + 1).min(sorted.len() - 1)];
    sorted[i] * (1.0 - f) + next * f
}

/// Normalised 90-bin histogram of values clipped into `[-l, l]`.
fn histogram(v: &[f64], l: f64) -> Vec<f64> {
    let mut hist = vec![0.0f64; 90];
    for &x in v {
        let t = ((x.clamp(-l, l) + l) / (2.0 * l) * 90.0).floor() as usize;
        hist[t.min(89)] += 1.0;
    }
    let n = v.len().max(1) as f64;
    hist.iter_mut().for_each(|b| *b /= n);
    hist
}

/// Sum of absolute differences of the cumulative histograms (bin width 1).
fn emd(a: &[f64], b: &[f64]) -> f64 {
    let (mut ca, mut cb, mut d) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        ca += x;
        cb += y;
        d += (ca - cb).abs();
    }
    d
}

/// Detail-energy swing of `a - reference` (see the module docs).
pub fn swing(a: &Heightfield, reference: &Heightfield) -> f64 {
    let (w, h) = (
        a.width().min(reference.width()),
        a.height().min(reference.height()),
    );
    let same = |hf: &Heightfield| {
        if (hf.width(), hf.height()) == (w, h) {
            Some(hf.clone())
        } else {
            hf.crop(0, 0, w, h).ok()
        }
    };
    match (same(a), same(reference)) {
        (Some(a), Some(r)) => relief_heightfield::metrics::detail_swing(&a, &r).unwrap_or(1.0),
        _ => 1.0,
    }
}
