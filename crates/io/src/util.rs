//! Shared checks used by every reader.

use relief_heightfield::Heightfield;

use crate::{Format, IoError, Raster, ReadOptions, Result};

/// Checks declared dimensions: non-zero, no overflow, within `opts.max_cells`. Returns the
/// number of cells.
pub(crate) fn check_dims(
    format: Format,
    width: u64,
    height: u64,
    opts: &ReadOptions,
) -> Result<usize> {
    let dims = |reason: String| IoError::Dimensions {
        format,
        width,
        height,
        reason,
    };
    if width == 0 || height == 0 {
        return Err(dims("zero size".into()));
    }
    let n = width
        .checked_mul(height)
        .ok_or_else(|| dims("width x height overflows".into()))?;
    if n > opts.max_cells as u64 {
        return Err(dims(format!(
            "{n} cells exceed the limit of {} (raise ReadOptions::max_cells to allow it)",
            opts.max_cells
        )));
    }
    Ok(n as usize)
}

/// Smallest and largest cell size accepted from a file or an option, in metres (1 micrometre
/// to 10 000 km): outside, products such as `width * cell` lose all precision or overflow.
pub(crate) const CELL_RANGE_M: (f64, f64) = (1e-6, 1e7);

/// Checks a cell size read from the file part `field`: finite, positive, within
/// [`CELL_RANGE_M`]; the error names the field and the value.
pub(crate) fn check_cell(format: Format, field: &str, cx: f64, cy: f64) -> Result<()> {
    for v in [cx, cy] {
        if !(v.is_finite() && v > 0.0) {
            return Err(IoError::malformed(
                format,
                format!("{field}: cell size {cx} x {cy} is not a finite positive number"),
            ));
        }
        if !(CELL_RANGE_M.0..=CELL_RANGE_M.1).contains(&v) {
            return Err(IoError::malformed(
                format,
                format!(
                    "{field}: cell size {cx} x {cy} m is outside {:e}..{:e} m",
                    CELL_RANGE_M.0, CELL_RANGE_M.1
                ),
            ));
        }
    }
    Ok(())
}

/// Checks an origin coordinate read from the file part `field`: finite.
pub(crate) fn check_origin(format: Format, field: &str, v: f64) -> Result<()> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(IoError::malformed(
            format,
            format!("{field} = {v} is not a finite coordinate"),
        ))
    }
}

/// A codec's error text, with the standard library's "failed to fill whole buffer" (an early
/// end of file) said as what it means for the file.
pub(crate) fn codec_reason(text: String) -> String {
    if text.contains("failed to fill whole buffer") || text.contains("unexpected end of file") {
        format!("truncated file: the data ends before the part being read ({text})")
    } else {
        text
    }
}

/// Checks that `needed` bytes are available.
#[allow(dead_code)]
pub(crate) fn need(format: Format, what: &str, needed: u64, available: usize) -> Result<()> {
    if needed > available as u64 {
        Err(IoError::truncated(format, what, needed, available as u64))
    } else {
        Ok(())
    }
}

/// Builds the raster: nodata -> NaN, rejects NaN-only grids.
/// Samples with a larger magnitude are read as voids (1e30 m: far beyond any elevation, far
/// below the f32 nodata markers such as -3.4028235e38).
pub(crate) const VOID_MAGNITUDE: f32 = 1e30;

pub(crate) fn finish(
    format: Format,
    width: usize,
    height: usize,
    mut data: Vec<f32>,
    cell: (f64, f64),
    nodata: Option<f64>,
    dtype: &str,
) -> Result<Raster> {
    voids_to_nan(&mut data, nodata);
    if data.iter().all(|v| v.is_nan()) {
        return Err(IoError::AllVoid { format });
    }
    check_cell(format, "cell size", cell.0, cell.1)?;
    let heightfield = Heightfield::new(width, height, data, cell.0, cell.1)?;
    Ok(Raster {
        heightfield,
        format,
        nodata,
        dtype: dtype.to_string(),
        rows_flipped: false,
    })
}

/// Turns the voids of decoded samples into NaN, cell by cell (so a band of rows gets the
/// values the whole raster gets): the declared `nodata` value, infinite values, and magnitudes
/// no terrain has (a float DEM whose GDAL nodata of -3.4e38 lost its tag).
pub(crate) fn voids_to_nan(data: &mut [f32], nodata: Option<f64>) {
    // A NaN nodata is already a void.
    let ndf = nodata.filter(|nd| !nd.is_nan()).map(|nd| nd as f32);
    for v in data {
        if Some(*v) == ndf || v.is_infinite() || v.abs() > VOID_MAGNITUDE {
            *v = f32::NAN;
        }
    }
}

/// Flips rows in place (row-major `width` columns).
pub(crate) fn flip_rows<T>(data: &mut [T], width: usize) {
    let height = data.len() / width;
    for y in 0..height / 2 {
        let (a, b) = data.split_at_mut((height - 1 - y) * width);
        a[y * width..(y + 1) * width].swap_with_slice(&mut b[..width]);
    }
}

/// The finite range of `hf`, or an error naming the format when there is none.
pub(crate) fn finite_range(hf: &Heightfield, format: Format) -> Result<(f32, f32)> {
    hf.min_max().ok_or(IoError::AllVoid { format })
}

/// Refuses a raster target without a file name or with a cell size that is not finite and
/// positive (the streamed and tiled GeoTIFF writers).
pub(crate) fn check_target(path: &std::path::Path, (cx, cy): (f64, f64)) -> Result<()> {
    if !(cx.is_finite() && cy.is_finite() && cx > 0.0 && cy > 0.0) {
        return Err(IoError::param(
            "cell_size",
            format!("({cx}, {cy})"),
            "must be finite and positive",
        ));
    }
    if path.file_name().is_none() {
        return Err(IoError::param("path", path.display(), "has no file name"));
    }
    Ok(())
}
