use relief_heightfield::{HeightfieldError, ParamError};
use thiserror::Error;

/// Errors of relief-landscape.
#[derive(Debug, Error)]
pub enum LandscapeError {
    /// A setting out of its valid range.
    #[error(transparent)]
    InvalidParameter(#[from] ParamError),
    /// An input raster that cannot be routed (no valid cell, wrong size of a companion raster).
    #[error("{0}")]
    InvalidInput(String),
    /// The run was cancelled or ran out of its time budget.
    #[error("stopped: {0}")]
    Stopped(String),
    /// An error of the heightfield type.
    #[error(transparent)]
    Heightfield(#[from] HeightfieldError),
}

/// Result with [`LandscapeError`].
pub type Result<T> = std::result::Result<T, LandscapeError>;
