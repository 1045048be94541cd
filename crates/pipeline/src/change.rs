//! What an erosion run changed, drawn for a person: the eroded terrain's hillshade tinted
//! blue where the run lowered it and orange where it raised it (the pipeline's
//! `erode_change.png`, `relief erode --change-map`).

use anyhow::Result;
use relief_landscape::erode::job::ErodeOutput;

/// Net change (m) at which [`change_map`]'s tint is full.
pub const CHANGE_FULL_M: f32 = 30.0;

/// The eroded terrain's grey hillshade tinted blue where the run lowered it and orange where
/// it raised it, the tint growing with the logarithm of the change from 0.5 m to
/// [`CHANGE_FULL_M`]; voids light grey: `(width, height, rgb)`.
pub fn change_map(out: &ErodeOutput) -> Result<(usize, usize, Vec<u8>)> {
    let t = &out.terrain;
    let shade = relief_heightfield::terrain::hillshade(t, 315.0, 45.0, 1.0);
    let (w, h) = (t.width(), t.height());
    let (lowered, raised) = (out.erosion.as_slice(), out.deposition.as_slice());
    let tint = |d: f32| {
        if d.is_nan() || d < 0.5 {
            0.0
        } else {
            ((d / 0.5).ln() / (CHANGE_FULL_M / 0.5).ln()).min(1.0)
        }
    };
    let mut rgb = Vec::with_capacity(w * h * 3);
    let terrain = t.as_slice();
    for (i, s) in shade.iter().enumerate() {
        if terrain[i].is_nan() {
            // Voids: flat light grey, apart from any shade.
            rgb.extend([200u8; 3]);
            continue;
        }
        let g = 0.15 + 0.85 * s;
        let (a, b) = (tint(lowered[i]), tint(raised[i]));
        let (colour, k) = if a >= b {
            ([0.15, 0.45, 1.0], 0.75 * a)
        } else {
            ([1.0, 0.55, 0.1], 0.75 * b)
        };
        for c in colour {
            let v = g * (1.0 - k) + k * c * (0.4 + 0.6 * g);
            rgb.push((v.clamp(0.0, 1.0) * 255.0).round() as u8);
        }
    }
    Ok((w, h, rgb))
}
