//! NumPy `.npy` and `.npz`.

use relief_heightfield::Heightfield;

use crate::{Raster, ReadOptions, Result};

pub(crate) fn read_npy(_bytes: &[u8], _opts: &ReadOptions) -> Result<Raster> {
    Err(crate::IoError::unsupported(
        crate::Format::Npy,
        "not yet implemented",
    ))
}

pub(crate) fn read_npz(_bytes: &[u8], _opts: &ReadOptions) -> Result<Raster> {
    Err(crate::IoError::unsupported(
        crate::Format::Npz,
        "not yet implemented",
    ))
}

pub(crate) fn write_npy(_hf: &Heightfield) -> Vec<u8> {
    Vec::new()
}
