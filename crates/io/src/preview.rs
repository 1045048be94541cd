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
/// (Through [`RgbaPngWriter`]: the same bytes as a map written row by row.)
pub fn write_rgba_png(path: &Path, width: usize, height: usize, rgba: &[u8]) -> Result<()> {
    if width.checked_mul(height).and_then(|n| n.checked_mul(4)) != Some(rgba.len()) {
        return Err(IoError::param(
            "pixels",
            rgba.len(),
            format!("a {width} x {height} RGBA image needs {width} x {height} x 4 bytes"),
        ));
    }
    let mut w = RgbaPngWriter::create(path, width, height)?;
    w.write_rows(rgba)?;
    w.finish()
}

/// An 8-bit RGBA PNG written row by row into a temporary sibling and renamed into place by
/// [`RgbaPngWriter::finish`] (dropped unfinished: removed), so that a map far larger than
/// memory (a splat map assembled from tiles) is never held whole; [`write_rgba_png`] writes
/// through it, so both give the same bytes.
pub struct RgbaPngWriter {
    path: std::path::PathBuf,
    tmp: std::path::PathBuf,
    inner: Option<png::StreamWriter<'static, std::fs::File>>,
    /// The temporary file (for its final sync).
    file: std::fs::File,
    row_bytes: usize,
    rows_left: usize,
    done: bool,
}

impl RgbaPngWriter {
    /// Starts `path` (`width x height` pixels, neither 0 nor beyond 2^31).
    pub fn create(path: &Path, width: usize, height: usize) -> Result<Self> {
        let (Ok(w32), Ok(h32)) = (u32::try_from(width), u32::try_from(height)) else {
            return Err(IoError::dimensions(
                crate::Format::Png,
                width,
                height,
                "too large for PNG",
            ));
        };
        if width == 0 || height == 0 || w32 > i32::MAX as u32 || h32 > i32::MAX as u32 {
            return Err(IoError::dimensions(
                crate::Format::Png,
                width,
                height,
                "zero size or a side beyond 2^31",
            ));
        }
        atomic::remove_stale_temps(path);
        let tmp = atomic::temp_path(path);
        let file = atomic::create_temp(&tmp).map_err(|e| IoError::os(&tmp, e))?;
        let sync = match file.try_clone() {
            Ok(f) => f,
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                return Err(IoError::os(&tmp, e));
            }
        };
        let malformed =
            |e: png::EncodingError| IoError::malformed(crate::Format::Png, e.to_string());
        let start = || -> Result<_> {
            let mut enc = png::Encoder::new(file, w32, h32);
            enc.set_color(png::ColorType::Rgba);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_compression(png::Compression::Fast);
            let wr = enc.write_header().map_err(malformed)?;
            wr.into_stream_writer_with_size(1 << 20).map_err(malformed)
        };
        match start() {
            Ok(inner) => Ok(Self {
                path: path.to_path_buf(),
                tmp,
                inner: Some(inner),
                file: sync,
                row_bytes: width * 4,
                rows_left: height,
                done: false,
            }),
            Err(e) => {
                let _ = std::fs::remove_file(&tmp);
                Err(e.in_file(path))
            }
        }
    }

    /// Appends whole rows (`4 x width` bytes each, RGBA).
    pub fn write_rows(&mut self, rgba: &[u8]) -> Result<()> {
        use std::io::Write as _;
        let rows = rgba.len() / self.row_bytes;
        if !rgba.len().is_multiple_of(self.row_bytes) || rows > self.rows_left {
            return Err(IoError::param(
                "rows",
                rgba.len(),
                format!(
                    "must be whole rows of {} bytes, at most the {} rows left",
                    self.row_bytes, self.rows_left
                ),
            ));
        }
        let Some(inner) = self.inner.as_mut() else {
            return Err(IoError::param(
                "rows",
                rgba.len(),
                "the writer failed before",
            ));
        };
        if let Err(e) = inner.write_all(rgba) {
            self.inner = None;
            return Err(IoError::os(&self.path, e));
        }
        self.rows_left -= rows;
        Ok(())
    }

    /// Ends the image and renames it into place (every row must have been written).
    pub fn finish(mut self) -> Result<()> {
        if self.rows_left != 0 {
            return Err(IoError::param(
                "rows",
                self.rows_left,
                "rows are missing; the file is not written",
            ));
        }
        let Some(inner) = self.inner.take() else {
            return Err(IoError::param("rows", 0, "the writer failed before"));
        };
        let os = |e| IoError::os(&self.path, e);
        // The stream writer holds no buffer once finished: every byte went to the file.
        inner
            .finish()
            .map_err(|e| IoError::malformed(crate::Format::Png, e.to_string()))?;
        self.file.sync_all().map_err(os)?;
        atomic::rename_into_place(&self.tmp, &self.path)?;
        self.done = true;
        Ok(())
    }
}

impl std::fmt::Debug for RgbaPngWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RgbaPngWriter")
            .field("path", &self.path)
            .field("rows_left", &self.rows_left)
            .finish_non_exhaustive()
    }
}

impl Drop for RgbaPngWriter {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Writes an 8-bit grey PNG from row-major `grey` (1 byte per pixel) atomically.
pub fn write_gray_png(path: &Path, width: usize, height: usize, grey: &[u8]) -> Result<()> {
    let bytes = encode_8bit(width, height, 1, grey).map_err(|e| e.in_file(path))?;
    atomic::write_atomic(path, &bytes)
}
