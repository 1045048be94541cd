//! ESRI ASCII grid (`.asc`).

use relief_heightfield::Heightfield;

use crate::{Raster, ReadOptions, Result};

pub(crate) fn read(_bytes: &[u8], _opts: &ReadOptions) -> Result<Raster> {
    Err(crate::IoError::unsupported(
        crate::Format::AsciiGrid,
        "not yet implemented",
    ))
}

pub(crate) fn write(_hf: &Heightfield) -> Result<Vec<u8>> {
    Err(crate::IoError::unsupported(
        crate::Format::AsciiGrid,
        "not yet implemented",
    ))
}
