use relief_heightfield::{HeightfieldError, ParamError};
use thiserror::Error;

use crate::report::ValidationReport;

/// Errors of the patch-synthesis crate.
#[derive(Debug, Error)]
pub enum PatchSynthError {
    /// A parameter is out of its valid range (names the field and the value).
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Field name.
        name: &'static str,
        /// Offending value, formatted.
        value: String,
        /// What is expected.
        reason: String,
    },
    /// The exemplar set is empty.
    #[error("empty exemplar set: at least one exemplar heightfield is needed")]
    NoExemplars,
    /// An exemplar cannot be used (too small, voids, ...).
    #[error("exemplar {index} ({width} x {height}) is unusable: {reason}")]
    BadExemplar {
        /// Index of the exemplar in the set.
        index: usize,
        /// Exemplar width.
        width: usize,
        /// Exemplar height.
        height: usize,
        /// Why it is rejected.
        reason: String,
    },
    /// A control input (guide, categorisation map, output size) is inconsistent.
    #[error("invalid control input `{name}`: {reason}")]
    InvalidControl {
        /// Which input.
        name: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The settings differ from those the exemplar index was built with.
    #[error(
        "setting `{name}` = {value} differs from the exemplar index ({index_value}); rebuild the index"
    )]
    IndexMismatch {
        /// Field name.
        name: &'static str,
        /// Value in the settings.
        value: String,
        /// Value the index was built with.
        index_value: String,
    },
    /// The input validation (section 4) failed and `enforce_validation` is set.
    #[error("input validation failed: {0}")]
    Validation(Box<ValidationReport>),
    /// No candidate patch exists for a grid block (e.g. no exemplar of an allowed category).
    #[error("no candidate patch for grid block ({gx}, {gy}): {reason}")]
    NoCandidates {
        /// Grid column.
        gx: usize,
        /// Grid row.
        gy: usize,
        /// Why.
        reason: String,
    },
    /// A numerical step failed (e.g. the PCA eigen-decomposition).
    #[error("numerical failure in {0}")]
    Numerical(String),
    /// Error from the heightfield crate.
    #[error(transparent)]
    Heightfield(#[from] HeightfieldError),
}

impl PatchSynthError {
    pub(crate) fn setting(
        name: &'static str,
        value: impl std::fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        Self::InvalidParameter {
            name,
            value: value.to_string(),
            reason: reason.into(),
        }
    }
}

impl From<ParamError> for PatchSynthError {
    fn from(e: ParamError) -> Self {
        Self::setting(e.name, e.value, e.reason)
    }
}

/// Result alias of this crate.
pub type Result<T, E = PatchSynthError> = std::result::Result<T, E>;
