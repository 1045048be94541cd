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
    if let Some(nd) = nodata {
        if nd.is_nan() {
            // NaN is already a void.
        } else {
            let ndf = nd as f32;
            for v in &mut data {
                if *v == ndf {
                    *v = f32::NAN;
                }
            }
        }
    }
    // Infinite values, and magnitudes no terrain has (a float DEM whose GDAL nodata of
    // -3.4e38 lost its tag), are voids.
    for v in &mut data {
        if v.is_infinite() || v.abs() > VOID_MAGNITUDE {
            *v = f32::NAN;
        }
    }
    if data.iter().all(|v| v.is_nan()) {
        return Err(IoError::AllVoid { format });
    }
    let heightfield = Heightfield::new(width, height, data, cell.0, cell.1)?;
    Ok(Raster {
        heightfield,
        format,
        nodata,
        dtype: dtype.to_string(),
        rows_flipped: false,
    })
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
