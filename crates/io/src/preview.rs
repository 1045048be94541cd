//! Preview and helper images (8-bit PNG), written atomically.

use std::path::Path;

use relief_heightfield::Heightfield;
use relief_heightfield::terrain::hillshade;

use crate::png_io::encode_8bit;
use crate::{IoError, Result, atomic};

/// Elevation colour ramp (hypsometric tints) from low (0) to high (1).
const RAMP: [(f32, [f32; 3]); 6] = [
    (0.0, [40.0, 100.0, 60.0]),
    (0.2, [110.0, 160.0, 80.0]),
    (0.45, [210.0, 200.0, 120.0]),
    (0.7, [170.0, 120.0, 80.0]),
    (0.88, [150.0, 140.0, 135.0]),
    (1.0, [250.0, 250.0, 250.0]),
];

fn ramp(t: f32) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0);
    for k in 1..RAMP.len() {
        let (t1, c1) = RAMP[k];
        if t <= t1 {
            let (t0, c0) = RAMP[k - 1];
            let u = (t - t0) / (t1 - t0);
            return [0, 1, 2].map(|i| c0[i] + u * (c1[i] - c0[i]));
        }
    }
    RAMP[RAMP.len() - 1].1
}

/// RGB bytes of the preview: Lambertian hillshade (light from the north-west at 45 degrees)
/// multiplied 65/35 with an elevation colour ramp over the finite range; voids are red.
pub fn preview_rgb(hf: &Heightfield) -> Result<Vec<u8>> {
    let (lo, hi) = hf.min_max().ok_or(IoError::AllVoid {
        format: crate::Format::Png,
    })?;
    let span = if hi > lo { hi - lo } else { 1.0 };
    let shade = hillshade(hf, 315.0, 45.0, 1.0);
    let mut out = Vec::with_capacity(hf.len() * 3);
    for (v, s) in hf.as_slice().iter().zip(shade.iter()) {
        if v.is_nan() {
            out.extend_from_slice(&[220, 30, 30]);
            continue;
        }
        let c = ramp((v - lo) / span);
        let k = 0.35 + 0.65 * s;
        out.extend(c.map(|x| (x * k).round().clamp(0.0, 255.0) as u8));
    }
    Ok(out)
}

/// Writes an 8-bit RGB preview of `hf` (see [`preview_rgb`]) to `path` atomically.
pub fn write_preview_png(path: &Path, hf: &Heightfield) -> Result<()> {
    let rgb = preview_rgb(hf).map_err(|e| e.in_file(path))?;
    write_rgb_png(path, hf.width(), hf.height(), &rgb)
}

/// Writes an 8-bit RGB PNG from row-major `rgb` (3 bytes per pixel) atomically.
pub fn write_rgb_png(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    let bytes = encode_8bit(width, height, 3, rgb).map_err(|e| e.in_file(path))?;
    atomic::write_atomic(path, &bytes)
}

/// Writes an 8-bit grey PNG from row-major `grey` (1 byte per pixel) atomically.
pub fn write_gray_png(path: &Path, width: usize, height: usize, grey: &[u8]) -> Result<()> {
    let bytes = encode_8bit(width, height, 1, grey).map_err(|e| e.in_file(path))?;
    atomic::write_atomic(path, &bytes)
}
