//! Quality measures of a synthesis: guide fidelity, seam visibility and slope statistics.

use relief_heightfield::Heightfield;
use relief_heightfield::metrics::{histogram_emd, rmse, slope_histogram, stats};
use relief_heightfield::terrain::gradient;

use crate::error::{PatchSynthError, Result};
use crate::guide::lowpass_resample;
use crate::synth::SeamMap;

/// The three figures of the quality protocol.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QualityReport {
    /// RMSE (m) between the low-pass of the output and the guide.
    pub guide_rmse: f64,
    /// Standard deviation (m) of the guide, the scale `guide_rmse` is judged against.
    pub guide_std: f64,
    /// Mean gradient magnitude on seam cells divided by the mean elsewhere (1 = invisible).
    pub seam_ratio: f64,
    /// Mean absolute curvature on seam cells divided by the mean elsewhere (1 = no crease).
    pub seam_curvature_ratio: f64,
    /// Slope-angle histogram distance (EMD, degrees) of the output to the pooled exemplars.
    pub slope_distance: f64,
    /// The same distance between the guide's source and the exemplars, when known (else NaN):
    /// a baseline for `slope_distance`.
    pub slope_distance_baseline: f64,
}

/// RMSE of `lowpass_resample(output, factor)` against `guide`.
pub fn guide_fidelity(output: &Heightfield, guide: &Heightfield, factor: usize) -> Result<f64> {
    let low = lowpass_resample(output, factor)?;
    Ok(rmse(&low, guide)?)
}

/// Mean of `value(x, y)` on seam cells over its mean on the other cells (the outer one-cell
/// border excluded); 1 when either set is empty or the mean elsewhere is 0.
fn seam_ratio(
    output: &Heightfield,
    seams: &SeamMap,
    value: impl Fn(usize, usize) -> f64,
) -> Result<f64> {
    if (seams.width, seams.height) != (output.width(), output.height()) {
        return Err(PatchSynthError::InvalidControl {
            name: "seam_map",
            reason: "size differs from the output".into(),
        });
    }
    let (w, h) = (output.width(), output.height());
    let (mut s1, mut n1, mut s0, mut n0) = (0.0f64, 0usize, 0.0f64, 0usize);
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let v = value(x, y);
            if seams.seam[y * w + x] {
                s1 += v;
                n1 += 1;
            } else {
                s0 += v;
                n0 += 1;
            }
        }
    }
    if n1 == 0 || n0 == 0 || s0 == 0.0 {
        return Ok(1.0);
    }
    Ok((s1 / n1 as f64) / (s0 / n0 as f64))
}

/// Mean gradient magnitude on seam cells over the mean on the other cells (the outer one-cell
/// border excluded).
pub fn seam_visibility(output: &Heightfield, seams: &SeamMap) -> Result<f64> {
    let (gx, gy) = gradient(output);
    seam_ratio(output, seams, |x, y| {
        (gx[(y, x)] as f64).hypot(gy[(y, x)] as f64)
    })
}

/// Mean absolute curvature (5-point Laplacian) on seam cells over the mean on the other cells
/// (the outer one-cell border excluded): a crease along the cuts shows here even when the
/// gradient ratio of [`seam_visibility`] is 1.
pub fn seam_curvature(output: &Heightfield, seams: &SeamMap) -> Result<f64> {
    let w = output.width();
    let (cx, cy) = output.cell_size();
    let z = output.as_slice();
    seam_ratio(output, seams, |x, y| {
        let i = y * w + x;
        let c = z[i] as f64;
        let lx = (z[i - 1] as f64 + z[i + 1] as f64 - 2.0 * c) / (cx * cx);
        let ly = (z[i - w] as f64 + z[i + w] as f64 - 2.0 * c) / (cy * cy);
        (lx + ly).abs()
    })
}

/// Slope-histogram distance (EMD, degrees) between `output` and the pooled histogram of the
/// exemplars (each weighted by its cell count).
pub fn slope_distance(output: &Heightfield, exemplars: &[&Heightfield]) -> f64 {
    let mut pooled = vec![0.0f64; 90];
    let mut total = 0.0;
    for e in exemplars {
        let n = e.len() as f64;
        for (p, v) in pooled.iter_mut().zip(slope_histogram(e)) {
            *p += v * n;
        }
        total += n;
    }
    if total > 0.0 {
        pooled.iter_mut().for_each(|v| *v /= total);
    }
    histogram_emd(&slope_histogram(output), &pooled)
}

/// Runs the quality protocol: guide fidelity with the low-pass `factor` the guide was made
/// with, seam visibility and slope-histogram distance (plus the baseline distance of `source`,
/// the DEM the guide came from, when given).
pub fn assess(
    output: &Heightfield,
    seams: &SeamMap,
    guide: &Heightfield,
    factor: usize,
    exemplars: &[&Heightfield],
    source: Option<&Heightfield>,
) -> Result<QualityReport> {
    Ok(QualityReport {
        guide_rmse: guide_fidelity(output, guide, factor)?,
        guide_std: stats(guide)?.std,
        seam_ratio: seam_visibility(output, seams)?,
        seam_curvature_ratio: seam_curvature(output, seams)?,
        slope_distance: slope_distance(output, exemplars),
        slope_distance_baseline: source.map_or(f64::NAN, |s| slope_distance(s, exemplars)),
    })
}

/// Near reuse of exemplar patches: the pairs of placements within `radius` blocks of each other
/// (Chebyshev) whose sources (same exemplar) are less than half a patch (`patch` cells) apart,
/// i.e. the same terrain pasted twice nearby (what `Settings::reuse_penalty` discourages).
pub fn near_reuse_pairs(
    placements: &[crate::synth::Placement],
    patch: usize,
    radius: usize,
) -> usize {
    let half = (patch / 2) as i64;
    let mut n = 0;
    for (i, a) in placements.iter().enumerate() {
        for b in &placements[i + 1..] {
            if a.gx.abs_diff(b.gx) <= radius
                && a.gy.abs_diff(b.gy) <= radius
                && a.patch.exemplar == b.patch.exemplar
                && (a.patch.x as i64 - b.patch.x as i64).abs() < half
                && (a.patch.y as i64 - b.patch.y as i64).abs() < half
            {
                n += 1;
            }
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seams_at_column(w: usize, h: usize, col: usize) -> SeamMap {
        SeamMap {
            width: w,
            height: h,
            seam: (0..w * h).map(|i| i % w == col).collect(),
            source: vec![0; w * h],
        }
    }

    #[test]
    fn seam_curvature_sees_a_crease_the_gradient_ratio_misses() {
        let (w, h) = (24, 16);
        let seams = seams_at_column(w, h, 10);
        // Constant curvature everywhere: ratio 1.
        let bowl = Heightfield::from_fn(w, h, 1.0, 1.0, |x, _| (x as f32).powi(2));
        assert!((seam_curvature(&bowl, &seams).unwrap() - 1.0).abs() < 1e-6);
        // A V-shaped crease on the seam column, same slope magnitude on both sides.
        let crease = Heightfield::from_fn(w, h, 1.0, 1.0, |x, _| 5.0 * (x as f32 - 10.0).abs());
        let g = seam_visibility(&crease, &seams).unwrap();
        let k = seam_curvature(&crease, &seams).unwrap();
        assert!(g < 1.0, "gradient ratio {g}");
        assert_eq!(
            k, 1.0,
            "curvature is zero off the seam: the ratio falls back to 1"
        );
        let ridge = Heightfield::from_fn(w, h, 1.0, 1.0, |x, _| {
            5.0 * (x as f32 - 10.0).abs() + 0.1 * (x as f32).powi(2)
        });
        assert!(seam_curvature(&ridge, &seams).unwrap() > 10.0);
        let other = seams_at_column(w, h + 1, 10);
        assert!(seam_curvature(&ridge, &other).is_err());
    }
}
