//! SRTM `.hgt` tiles: square big-endian int16, -32768 = void, size from the file length.

use relief_heightfield::Heightfield;

use crate::util::finish;
use crate::{Format, IoError, Raster, ReadOptions, Result};

const F: Format = Format::Hgt;

/// Nominal ground spacing of a 1-degree tile with `n` samples per side at latitude 0.
fn nominal_cell(n: usize) -> f64 {
    let (_, my) = crate::geotiff::metres_per_degree(0.0);
    my / (n - 1) as f64
}

pub(crate) fn read(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let n = match bytes.len() {
        2_884_802 => 1201,
        25_934_402 => 3601,
        len => {
            return Err(IoError::malformed(
                F,
                format!(
                    "file length {len} is neither 1201^2 * 2 (SRTM3) nor 3601^2 * 2 (SRTM1) bytes"
                ),
            ));
        }
    };
    crate::util::check_dims(F, n as u64, n as u64, opts)?;
    let data = bytes
        .chunks_exact(2)
        .map(|b| i16::from_be_bytes([b[0], b[1]]))
        .map(|v| if v == -32768 { f32::NAN } else { f32::from(v) })
        .collect();
    let c = nominal_cell(n);
    let mut r = finish(F, n, n, data, (c, c), Some(-32768.0), "int16 big-endian")?;
    r.nodata = Some(-32768.0);
    Ok(r)
}

/// Cell size of the tile whose south-west corner is at latitude `lat_sw` (from a name such as
/// `N47E011.hgt`): east-west and north-south metres at the tile's centre latitude.
pub(crate) fn tile_cell_from_name(name: &str, n: usize) -> Option<(f64, f64)> {
    let b = name.as_bytes();
    if b.len() < 7 || !(b[0] == b'N' || b[0] == b'S' || b[0] == b'n' || b[0] == b's') {
        return None;
    }
    let lat: f64 = name.get(1..3)?.parse().ok()?;
    let lat = if b[0] == b'S' || b[0] == b's' {
        -lat
    } else {
        lat
    };
    let (mx, my) = crate::geotiff::metres_per_degree(lat + 0.5);
    let d = 1.0 / (n - 1) as f64;
    Some((mx * d, my * d))
}

pub(crate) fn write(hf: &Heightfield) -> Result<Vec<u8>> {
    let (w, h) = (hf.width(), hf.height());
    if w != h || !(w == 1201 || w == 3601) {
        return Err(IoError::unsupported(
            F,
            format!("{w} x {h}: an SRTM tile must be 1201^2 or 3601^2"),
        ));
    }
    let mut out = Vec::with_capacity(w * h * 2);
    for &v in hf.as_slice() {
        let q = if v.is_nan() {
            -32768
        } else {
            v.round().clamp(-32767.0, 32767.0) as i16
        };
        out.extend_from_slice(&q.to_be_bytes());
    }
    Ok(out)
}
