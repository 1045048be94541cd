use thiserror::Error;

/// Errors of this crate.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    /// A parameter is out of its valid range.
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Offending value, formatted.
        value: String,
        /// What is expected.
        reason: &'static str,
    },
    /// The input heightfield was rejected.
    #[error(transparent)]
    Heightfield(#[from] relief_heightfield::HeightfieldError),
}

impl Error {
    pub(crate) fn param(
        name: &'static str,
        value: impl std::fmt::Display,
        reason: &'static str,
    ) -> Self {
        Self::InvalidParameter {
            name,
            value: value.to_string(),
            reason,
        }
    }
}

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
