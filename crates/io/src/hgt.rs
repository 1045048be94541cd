//! SRTM `.hgt` tiles: square big-endian int16, -32768 = void, size from the file length.

use relief_heightfield::{GeoRef, Heightfield};

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

/// Refuses a tile name of the SRTM pattern (`N47E011.hgt`) whose corner lies off the globe:
/// a north latitude above 89, a south latitude above 90, a longitude above 180 (east 179).
pub(crate) fn check_tile_name(name: &str) -> Result<()> {
    let b = name.as_bytes();
    if b.len() < 7 {
        return Ok(());
    }
    let ns = b[0].to_ascii_uppercase();
    let ew = b[3].to_ascii_uppercase();
    let (Some(lat), Some(lon)) = (
        name.get(1..3).and_then(|t| t.parse::<u32>().ok()),
        name.get(4..7).and_then(|t| t.parse::<u32>().ok()),
    ) else {
        return Ok(());
    };
    if !matches!(ns, b'N' | b'S') || !matches!(ew, b'E' | b'W') {
        return Ok(());
    }
    let lat_max = if ns == b'N' { 89 } else { 90 };
    let lon_max = if ew == b'E' { 179 } else { 180 };
    if lat > lat_max {
        return Err(IoError::malformed(
            F,
            format!(
                "tile name {name}: latitude {}{lat} is beyond +-90 degrees (a 1-degree tile's \
                 south-west corner is at most N89 or S90)",
                ns as char
            ),
        ));
    }
    if lon > lon_max {
        return Err(IoError::malformed(
            F,
            format!(
                "tile name {name}: longitude {}{lon} is beyond +-180 degrees (at most E179 or \
                 W180)",
                ew as char
            ),
        ));
    }
    Ok(())
}

/// Latitude and longitude of the south-west corner named by a tile name such as
/// `N47E011.hgt` or `s03w060.hgt`.
fn tile_corner(name: &str) -> Option<(f64, f64)> {
    let b = name.as_bytes();
    if b.len() < 7 {
        return None;
    }
    let ns = b[0].to_ascii_uppercase();
    let ew = b[3].to_ascii_uppercase();
    if !matches!(ns, b'N' | b'S') || !matches!(ew, b'E' | b'W') {
        return None;
    }
    let lat: f64 = name.get(1..3)?.parse().ok()?;
    let lon: f64 = name.get(4..7)?.parse().ok()?;
    let lat_max = if ns == b'S' { 90.0 } else { 89.0 };
    if lat > lat_max || lon > 180.0 {
        return None;
    }
    Some((
        if ns == b'S' { -lat } else { lat },
        if ew == b'W' { -lon } else { lon },
    ))
}

/// The EPSG:4326 georeference of the tile named `name` with `n` samples per side: SRTM samples
/// sit on whole 1/(n-1) degree lines (pixel-centre registration), so sample `(0, 0)` is centred
/// on the tile's north-west corner and the pixel-is-area grid starts half a cell further out.
pub(crate) fn tile_georef(name: &str, n: usize) -> Option<GeoRef> {
    let (lat, lon) = tile_corner(name)?;
    let d = 1.0 / (n - 1) as f64;
    let origin = (lon - d / 2.0, lat + 1.0 + d / 2.0);
    Some(GeoRef {
        pixel_scale: Some(vec![d, d, 0.0]),
        tiepoints: Some(vec![0.0, 0.0, 0.0, origin.0, origin.1, 0.0]),
        // GeoTIFF 1.1: geographic model, PixelIsArea, EPSG:4326.
        geo_key_directory: Some(vec![
            1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326,
        ]),
        crs: Some("EPSG:4326".into()),
        geotransform: Some([origin.0, d, 0.0, origin.1, 0.0, -d]),
        ..Default::default()
    })
}

/// Cell size of the tile whose south-west corner is at latitude `lat_sw` (from a name such as
/// `N47E011.hgt`): east-west and north-south metres at the tile's centre latitude.
pub(crate) fn tile_cell_from_name(name: &str, n: usize) -> Option<(f64, f64)> {
    let (lat, _) = tile_corner(name)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_name_gives_the_srtm_grid() {
        let g = tile_georef("N47E011.hgt", 1201).unwrap();
        let d = 1.0 / 1200.0;
        assert_eq!(
            g.geotransform.unwrap(),
            [11.0 - d / 2.0, d, 0.0, 48.0 + d / 2.0, 0.0, -d]
        );
        assert_eq!(g.crs.as_deref(), Some("EPSG:4326"));
        let g = tile_georef("s03w060.hgt", 3601).unwrap();
        let d = 1.0 / 3600.0;
        assert_eq!(
            g.geotransform.unwrap(),
            [-60.0 - d / 2.0, d, 0.0, -2.0 + d / 2.0, 0.0, -d]
        );
        assert!(tile_georef("dem.hgt", 1201).is_none());
        assert!(tile_georef("N47X011.hgt", 1201).is_none());
    }
}
