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
