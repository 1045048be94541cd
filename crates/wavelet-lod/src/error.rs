use relief_heightfield::{HeightfieldError, ParamError};
use thiserror::Error;

/// Errors of the wavelet transform, the statistics fit and the refinement.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum WaveletError {
    /// The caller asked the work to stop (`Progress::stopped`: its time budget ran out).
    #[error("stopped: {0} was cut short")]
    Stopped(&'static str),
    /// A setting or argument is out of its valid range.
    #[error(transparent)]
    InvalidParameter(#[from] ParamError),
    /// A wavelet name is not one of the supported bases.
    #[error("unknown wavelet `{0}` (expected haar, cdf53, cdf97 or db4)")]
    UnknownWavelet(String),
    /// The periodic boundary needs an even length at every decomposed level.
    #[error("periodic boundary needs even lengths, but level {level} has length {len}")]
    OddPeriodic {
        /// Decomposition depth (1 = finest) at which the odd length occurs.
        level: usize,
        /// The odd length.
        len: usize,
    },
    /// The data given does not match the declared shape.
    #[error("buffer holds {got} values but {width} x {height} = {expected} are needed")]
    Shape {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Expected number of values.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
    /// Too few levels take part in the fit of equation (3).
    #[error(
        "the fit needs at least 2 detail levels with index >= {min_level}, got {available} \
         (input {width} x {height}, {levels} analysed levels)"
    )]
    TooFewLevels {
        /// First level used by the fit.
        min_level: u32,
        /// Levels available for the fit.
        available: usize,
        /// Levels analysed.
        levels: usize,
        /// Input width.
        width: usize,
        /// Input height.
        height: usize,
    },
    /// An error of the underlying heightfield (voids, sizes, ...).
    #[error(transparent)]
    Heightfield(#[from] HeightfieldError),
}

/// Result alias of this crate.
pub type Result<T, E = WaveletError> = std::result::Result<T, E>;

impl WaveletError {
    /// Shorthand for [`WaveletError::InvalidParameter`].
    pub fn param(name: &'static str, value: impl std::fmt::Display, reason: &'static str) -> Self {
        Self::InvalidParameter(ParamError::new(name, value, reason))
    }
}
