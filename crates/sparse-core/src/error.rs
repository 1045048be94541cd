use relief_heightfield::HeightfieldError;
use thiserror::Error;

/// Errors of the sparse-coding and Sparse Construction Tree code.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SparseError {
    /// The caller asked the work to stop (`Progress::stopped`: its time budget ran out).
    #[error("stopped: {0} was cut short")]
    Stopped(&'static str),
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
    /// The dictionary holds no atom (or atoms of dimension zero).
    #[error("empty dictionary: {n_atoms} atoms of dimension {dim}")]
    EmptyDictionary {
        /// Number of atoms.
        n_atoms: usize,
        /// Atom dimension.
        dim: usize,
    },
    /// The sparsity asked for exceeds the number of atoms.
    #[error("sparsity s = {sparsity} exceeds the number of atoms N = {n_atoms}")]
    SparsityTooLarge {
        /// Requested sparsity.
        sparsity: usize,
        /// Number of atoms.
        n_atoms: usize,
    },
    /// Two sizes that must agree do not.
    #[error("dimension mismatch in {what}: expected {expected}, got {got}")]
    DimensionMismatch {
        /// What is being compared.
        what: &'static str,
        /// Expected size.
        expected: usize,
        /// Actual size.
        got: usize,
    },
    /// A NaN or infinite value where finite values are required.
    #[error("non-finite value in {what} (row {row})")]
    NonFinite {
        /// Which input.
        what: &'static str,
        /// Row (signal / atom) index.
        row: usize,
    },
    /// A dictionary atom does not have unit L2 norm (OMP needs normalised atoms).
    #[error("dictionary atom {atom} has L2 norm {norm}, expected 1 (normalise the rows)")]
    NotNormalised {
        /// Atom index.
        atom: usize,
        /// Its norm.
        norm: f64,
    },
    /// An atom has no energy left after removing its mean, so it cannot be normalised.
    #[error("atom {atom} is constant over the support (zero energy after mean removal)")]
    DegenerateAtom {
        /// Atom index (in the input that was being added).
        atom: usize,
    },
    /// A function-atom kind is not in the registry given to the reader.
    #[error("unknown function atom kind `{kind}` (register it in the FunctionAtomRegistry)")]
    UnknownFunctionAtom {
        /// Kind name found in the stream.
        kind: String,
    },
    /// A `.sct` byte stream is malformed, truncated or declares absurd sizes.
    #[error("invalid .sct data at byte {offset}: {reason}")]
    Format {
        /// Byte offset where the problem was detected.
        offset: usize,
        /// What is wrong.
        reason: String,
    },
    /// An error of the heightfield layer.
    #[error(transparent)]
    Heightfield(#[from] HeightfieldError),
}

impl SparseError {
    /// Shorthand for [`SparseError::InvalidParameter`].
    pub fn param(name: &'static str, value: impl std::fmt::Display, reason: &'static str) -> Self {
        Self::InvalidParameter {
            name,
            value: value.to_string(),
            reason,
        }
    }

    /// Shorthand for [`SparseError::NonFinite`].
    pub fn non_finite(what: &'static str, row: usize) -> Self {
        Self::NonFinite { what, row }
    }

    /// [`SparseError::NonFinite`] naming `what` and the first of `points` with a coordinate
    /// that is not finite.
    pub(crate) fn check_points(what: &'static str, points: &[[f64; 2]]) -> Result<()> {
        match points
            .iter()
            .position(|p| !(p[0].is_finite() && p[1].is_finite()))
        {
            Some(i) => Err(Self::non_finite(what, i)),
            None => Ok(()),
        }
    }
}

/// Result alias of this crate.
pub type Result<T, E = SparseError> = std::result::Result<T, E>;

impl From<relief_heightfield::ParamError> for SparseError {
    fn from(e: relief_heightfield::ParamError) -> Self {
        Self::InvalidParameter {
            name: e.name,
            value: e.value,
            reason: e.reason,
        }
    }
}
