use relief_heightfield::HeightfieldError;
use relief_sparse_core::SparseError;
use thiserror::Error;

/// Errors of dictionary learning, amplification, synthesis and inverse procedural modelling.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum LearnError {
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
    /// Not enough training signals or candidate patches for the requested dictionary.
    #[error("not enough {what}: need {needed}, got {got}")]
    NotEnough {
        /// What is short.
        what: &'static str,
        /// How many are needed.
        needed: usize,
        /// How many there are.
        got: usize,
    },
    /// A NaN or infinite value where finite values are required.
    #[error("non-finite value in {what} (row {row})")]
    NonFinite {
        /// Which input.
        what: &'static str,
        /// Row index.
        row: usize,
    },
    /// The caller asked the work to stop (`Progress::stopped`: its time budget ran out); no
    /// partial result is returned.
    #[error("stopped: {0}")]
    Stopped(String),
    /// The SVD of a restricted error matrix failed to converge.
    #[error("svd failed for atom {atom}")]
    Svd {
        /// Atom being updated.
        atom: usize,
    },
    /// An error of the sparse-coding layer.
    #[error(transparent)]
    Sparse(#[from] SparseError),
    /// An error of the heightfield layer.
    #[error(transparent)]
    Heightfield(#[from] HeightfieldError),
    /// An error of the landscape-evolution stage of sketch synthesis (its message).
    #[error("{0}")]
    Landscape(String),
}

impl LearnError {
    /// Whether the work stopped because the caller asked it to (its own stop, or one of the
    /// sparse-coding layer it wraps transparently, which an error chain does not show).
    pub fn is_stopped(&self) -> bool {
        matches!(
            self,
            Self::Stopped(_) | Self::Sparse(SparseError::Stopped(_))
        )
    }

    /// Shorthand for [`LearnError::InvalidParameter`].
    pub fn param(name: &'static str, value: impl std::fmt::Display, reason: &'static str) -> Self {
        Self::InvalidParameter {
            name,
            value: value.to_string(),
            reason,
        }
    }
}

/// Result alias of this crate.
pub type Result<T, E = LearnError> = std::result::Result<T, E>;

impl From<relief_landscape::LandscapeError> for LearnError {
    fn from(e: relief_landscape::LandscapeError) -> Self {
        match e {
            relief_landscape::LandscapeError::InvalidParameter(p) => p.into(),
            relief_landscape::LandscapeError::Stopped(what) => Self::Stopped(what.to_string()),
            e => Self::Landscape(e.to_string()),
        }
    }
}

impl From<relief_heightfield::ParamError> for LearnError {
    fn from(e: relief_heightfield::ParamError) -> Self {
        Self::InvalidParameter {
            name: e.name,
            value: e.value,
            reason: e.reason,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_of_a_wrapped_layer_is_a_stop() {
        assert!(LearnError::from(SparseError::Stopped("rasterising the model")).is_stopped());
        let landscape = relief_landscape::LandscapeError::Stopped("the landform pass".into());
        let e = LearnError::from(landscape);
        assert!(e.is_stopped(), "{e}");
        assert!(
            !LearnError::from(SparseError::EmptyDictionary { n_atoms: 0, dim: 4 }).is_stopped()
        );
        assert!(!LearnError::Svd { atom: 3 }.is_stopped());
    }
}
