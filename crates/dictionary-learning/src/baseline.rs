//! The noise-amplification baseline of guerin2016 figure 15: the coarse terrain up-sampled
//! (bicubic) plus multifractal noise whose amplitude follows altitude and slope.
//!
//! The added detail is `A(p) * sum_o 2^-o n_o(p)` with ridged-multifractal octaves `n_o`
//! spanning the frequencies the up-sampling cannot represent (from the coarse Nyquist
//! frequency to the fine one), zero-mean per octave, and the amplitude
//! `A(p) = gain * cell_coarse * tan(slope(p)) * (0.25 + 0.75 * altitude(p))`, with `altitude`
//! normalised to `[0, 1]` over the input. Flat lowlands receive almost nothing, steep high
//! ground the most, as in the figure.

use rayon::prelude::*;
use relief_heightfield::Heightfield;

use crate::error::{LearnError, Result};
use crate::noise::{Perlin, item_seed};

/// Settings of [`noise_amplify`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseBaselineSettings {
    /// Integer up-sampling factor (>= 2).
    pub factor: usize,
    /// Amplitude gain (dimensionless, relative to `cell_coarse * tan(slope)`).
    pub gain: f64,
    /// Noise seed.
    pub seed: u64,
}

impl Default for NoiseBaselineSettings {
    fn default() -> Self {
        Self {
            factor: 4,
            gain: 0.35,
            seed: 0,
        }
    }
}

/// Amplifies `coarse` by `factor` with altitude- and slope-modulated multifractal noise.
pub fn noise_amplify(
    coarse: &Heightfield,
    settings: &NoiseBaselineSettings,
) -> Result<Heightfield> {
    coarse.require_complete()?;
    let f = settings.factor;
    if !(2..=256).contains(&f) {
        return Err(LearnError::param("factor", f, "must be in 2..=256"));
    }
    if !(settings.gain.is_finite() && settings.gain >= 0.0) {
        return Err(LearnError::param(
            "gain",
            settings.gain,
            "must be finite and >= 0",
        ));
    }
    let up = coarse.resample(coarse.width() * f, coarse.height() * f)?;
    let (lo, hi) = up.min_max().unwrap_or((0.0, 1.0));
    let span = (hi - lo).max(1e-6) as f64;
    let (cx, cy) = coarse.cell_size();
    let (fcx, fcy) = up.cell_size();
    let cell_coarse = (cx * cy).sqrt();
    let octaves = (f as f64).log2().ceil().max(1.0) as u32;
    let noise = Perlin::new(item_seed(settings.seed, 0xba5e, 0));
    let (w, h) = (up.width(), up.height());
    let src = up.as_slice();
    let mut out = vec![0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let v = src[y * w + x] as f64;
            let xl = x.saturating_sub(1);
            let xr = (x + 1).min(w - 1);
            let yu = y.saturating_sub(1);
            let yd = (y + 1).min(h - 1);
            let gx = (src[y * w + xr] - src[y * w + xl]) as f64 / ((xr - xl).max(1) as f64 * fcx);
            let gy = (src[yd * w + x] - src[yu * w + x]) as f64 / ((yd - yu).max(1) as f64 * fcy);
            let tan_slope = (gx * gx + gy * gy).sqrt();
            let alt = (v - lo as f64) / span;
            let amp = settings.gain * cell_coarse * tan_slope * (0.25 + 0.75 * alt);
            // Octave o has wavelength 2 f / 2^o fine pixels: from the coarse Nyquist down.
            let mut detail = 0.0;
            let mut a = 1.0;
            let mut weight = 1.0f64;
            for o in 0..octaves {
                let freq = (1u64 << o) as f64 / (2.0 * f as f64);
                let n = noise.noise(
                    x as f64 * freq + 13.1 * o as f64,
                    y as f64 * freq + 7.7 * o as f64,
                );
                // Ridged multifractal octave: sharp crests, weighted by the previous octave.
                let r = (1.0 - n.abs()).powi(2) * weight;
                weight = (r * 2.0).clamp(0.0, 1.0);
                detail += a * (r - 0.45);
                a *= 0.5;
            }
            *o = (v + amp * detail) as f32;
        }
    });
    Ok(up.with_data(out)?)
}
