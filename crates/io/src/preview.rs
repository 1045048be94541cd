//! Preview and helper images.

use std::path::Path;

use relief_heightfield::Heightfield;

use crate::Result;

/// Writes an 8-bit RGB preview: hillshade blended with an elevation colour ramp.
pub fn write_preview_png(path: &Path, _hf: &Heightfield) -> Result<()> {
    Err(crate::IoError::unsupported(
        crate::Format::Png,
        format!("{}: not yet implemented", path.display()),
    ))
}

/// Writes an 8-bit RGB PNG from row-major `rgb` (3 bytes per pixel).
pub fn write_rgb_png(path: &Path, _width: usize, _height: usize, _rgb: &[u8]) -> Result<()> {
    Err(crate::IoError::unsupported(
        crate::Format::Png,
        format!("{}: not yet implemented", path.display()),
    ))
}

/// Writes an 8-bit grey PNG from row-major `grey` (1 byte per pixel).
pub fn write_gray_png(path: &Path, _width: usize, _height: usize, _grey: &[u8]) -> Result<()> {
    Err(crate::IoError::unsupported(
        crate::Format::Png,
        format!("{}: not yet implemented", path.display()),
    ))
}
