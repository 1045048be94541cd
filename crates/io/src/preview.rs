//! Preview and helper images (8-bit PNG), written atomically.

use std::path::Path;

use relief_heightfield::Heightfield;
use relief_heightfield::param::ensure;
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

/// Sea colours (below 0 m) from the deepest (0) to the coast (1).
const SEA: [[f32; 3]; 2] = [[18.0, 45.0, 105.0], [95.0, 165.0, 215.0]];

/// How a preview is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreviewStyle {
    /// Direction the light comes from, degrees clockwise from north (default 315: north-west).
    pub azimuth_deg: f32,
    /// Height of the light above the horizon in degrees, in (0, 90] (default 45).
    pub altitude_deg: f32,
    /// Vertical exaggeration of the hillshade, > 0 (default 1).
    pub exaggeration: f32,
    /// Draw ground below 0 m in sea colours (by depth) when the raster also has ground above
    /// 0 m; the land ramp then spans 0 m to the highest point (default on).
    pub sea: bool,
}

impl Default for PreviewStyle {
    fn default() -> Self {
        Self {
            azimuth_deg: 315.0,
            altitude_deg: 45.0,
            exaggeration: 1.0,
            sea: true,
        }
    }
}

impl PreviewStyle {
    /// Checks the fields, naming the first invalid one.
    pub fn check(&self) -> Result<()> {
        let (az, alt, ex) = (self.azimuth_deg, self.altitude_deg, self.exaggeration);
        ensure(az.is_finite(), "azimuth", az, "must be finite")?;
        let ok = alt > 0.0 && alt <= 90.0;
        ensure(ok, "altitude", alt, "must be in (0, 90] degrees")?;
        let ok = ex > 0.0 && ex <= 1e4;
        ensure(ok, "exaggeration", ex, "must be in (0, 10000]")?;
        Ok(())
    }
}

/// RGB bytes of the preview in the default [`PreviewStyle`]: Lambertian hillshade (light from
/// the north-west at 45 degrees) multiplied 65/35 with an elevation colour ramp over the finite
/// range (sea colours below 0 m when there is land too); voids are red.
pub fn preview_rgb(hf: &Heightfield) -> Result<Vec<u8>> {
    preview_rgb_with(hf, &PreviewStyle::default())
}

/// [`preview_rgb`] in a given style.
pub fn preview_rgb_with(hf: &Heightfield, style: &PreviewStyle) -> Result<Vec<u8>> {
    style.check()?;
    let (lo, hi) = hf.min_max().ok_or(IoError::AllVoid {
        format: crate::Format::Png,
    })?;
    let sea = style.sea && lo < 0.0 && hi > 0.0;
    let land_lo = if sea { 0.0 } else { lo };
    let span = if hi > land_lo { hi - land_lo } else { 1.0 };
    let shade = hillshade(
        hf,
        style.azimuth_deg,
        style.altitude_deg,
        style.exaggeration,
    );
    let mut out = Vec::with_capacity(hf.len() * 3);
    for (v, s) in hf.as_slice().iter().zip(shade.iter()) {
        if v.is_nan() {
            out.extend_from_slice(&[220, 30, 30]);
            continue;
        }
        let c = if sea && *v < 0.0 {
            let t = (1.0 - v / lo).clamp(0.0, 1.0);
            [0, 1, 2].map(|i| SEA[0][i] + t * (SEA[1][i] - SEA[0][i]))
        } else {
            ramp((v - land_lo) / span)
        };
        let k = 0.35 + 0.65 * s;
        out.extend(c.map(|x| (x * k).round().clamp(0.0, 255.0) as u8));
    }
    Ok(out)
}

/// Writes an 8-bit RGB preview of `hf` (see [`preview_rgb`]) to `path` atomically.
pub fn write_preview_png(path: &Path, hf: &Heightfield) -> Result<()> {
    write_preview_png_with(path, hf, &PreviewStyle::default())
}

/// [`write_preview_png`] in a given style.
pub fn write_preview_png_with(path: &Path, hf: &Heightfield, style: &PreviewStyle) -> Result<()> {
    let rgb = preview_rgb_with(hf, style).map_err(|e| e.in_file(path))?;
    write_rgb_png(path, hf.width(), hf.height(), &rgb)
}

/// Writes an 8-bit RGB PNG from row-major `rgb` (3 bytes per pixel) atomically.
pub fn write_rgb_png(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<()> {
    let bytes = encode_8bit(width, height, 3, rgb).map_err(|e| e.in_file(path))?;
    atomic::write_atomic(path, &bytes)
}

/// Writes an 8-bit RGBA PNG from row-major `rgba` (4 bytes per pixel) atomically: colour
/// images with alpha, and four-channel weight maps (splat maps).
pub fn write_rgba_png(path: &Path, width: usize, height: usize, rgba: &[u8]) -> Result<()> {
    let bytes = encode_8bit(width, height, 4, rgba).map_err(|e| e.in_file(path))?;
    atomic::write_atomic(path, &bytes)
}

/// Writes an 8-bit grey PNG from row-major `grey` (1 byte per pixel) atomically.
pub fn write_gray_png(path: &Path, width: usize, height: usize, grey: &[u8]) -> Result<()> {
    let bytes = encode_8bit(width, height, 1, grey).map_err(|e| e.in_file(path))?;
    atomic::write_atomic(path, &bytes)
}
