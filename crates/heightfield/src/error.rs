use thiserror::Error;

use crate::ParamError;

/// Errors of heightfield construction and processing.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum HeightfieldError {
    /// A width or height is zero or the cell count exceeds the limit.
    #[error("invalid dimensions {width} x {height}: {reason}")]
    InvalidDimensions {
        /// Requested width.
        width: usize,
        /// Requested height.
        height: usize,
        /// Why they are rejected.
        reason: &'static str,
    },
    /// The sample buffer does not hold `width * height` values.
    #[error("sample buffer holds {got} values but {width} x {height} = {expected} are needed")]
    LengthMismatch {
        /// Width of the grid.
        width: usize,
        /// Height of the grid.
        height: usize,
        /// Expected number of samples.
        expected: usize,
        /// Number of samples given.
        got: usize,
    },
    /// A cell size is not a finite positive number.
    #[error("invalid cell size {cell_x} x {cell_y} m: both must be finite and > 0")]
    InvalidCellSize {
        /// East-west cell size.
        cell_x: f64,
        /// North-south cell size.
        cell_y: f64,
    },
    /// The operation needs a grid without voids.
    #[error("heightfield has {count} void (NaN/nodata) cells; fill them first (--fill-voids)")]
    HasVoids {
        /// Number of void cells.
        count: usize,
    },
    /// Every cell is void.
    #[error("heightfield has no valid cell (all {count} cells are void)")]
    AllVoid {
        /// Number of cells.
        count: usize,
    },
    /// A window lies (partly) outside the grid.
    #[error("window x={x} y={y} w={w} h={h} is outside the {width} x {height} grid or empty")]
    WindowOutOfBounds {
        /// Window origin column.
        x: usize,
        /// Window origin row.
        y: usize,
        /// Window width.
        w: usize,
        /// Window height.
        h: usize,
        /// Grid width.
        width: usize,
        /// Grid height.
        height: usize,
    },
    /// Two grids that must have the same size do not.
    #[error("size mismatch: {a_w} x {a_h} vs {b_w} x {b_h}")]
    SizeMismatch {
        /// First width.
        a_w: usize,
        /// First height.
        a_h: usize,
        /// Second width.
        b_w: usize,
        /// Second height.
        b_h: usize,
    },
    /// A parameter is out of its valid range.
    #[error(transparent)]
    InvalidParameter(#[from] ParamError),
}

/// Result alias of this crate.
pub type Result<T, E = HeightfieldError> = std::result::Result<T, E>;

impl HeightfieldError {
    /// Shorthand for [`HeightfieldError::InvalidParameter`].
    pub fn param(name: &'static str, value: impl std::fmt::Display, reason: &'static str) -> Self {
        Self::InvalidParameter(ParamError::new(name, value, reason))
    }
}
