//! PNG rasters: 8/16-bit grey with a relief vertical mapping, and Mapbox Terrain-RGB.

use relief_heightfield::Heightfield;

use crate::{Format, Raster, ReadOptions, Result};

pub(crate) fn read(_bytes: &[u8], format: Format, _opts: &ReadOptions) -> Result<Raster> {
    Err(crate::IoError::unsupported(format, "not yet implemented"))
}

pub(crate) fn write_png16(_hf: &Heightfield, _mapping: Option<(f64, f64)>) -> Result<Vec<u8>> {
    Err(crate::IoError::unsupported(
        Format::Png,
        "not yet implemented",
    ))
}

pub(crate) fn write_terrain_rgb(_hf: &Heightfield) -> Result<Vec<u8>> {
    Err(crate::IoError::unsupported(
        Format::TerrainRgb,
        "not yet implemented",
    ))
}
