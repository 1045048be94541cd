//! The error type of `relief-io`.

use std::path::PathBuf;

use relief_heightfield::{HeightfieldError, ParamError};

use crate::Format;

/// Everything that can go wrong while reading or writing a file. Messages are lowercase and
/// name the file (when known), the format and the offending value.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IoError {
    /// An operating-system I/O error on `path`.
    #[error("{path}: {source}")]
    Os {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The bytes are not a valid file of `format`.
    #[error("{format:?}: malformed file: {reason}")]
    Malformed {
        /// Format being decoded.
        format: Format,
        /// What is wrong.
        reason: String,
    },
    /// The file is shorter than its header says.
    #[error(
        "{format:?}: truncated file: {what} needs {needed} bytes but only {available} are present"
    )]
    Truncated {
        /// Format being decoded.
        format: Format,
        /// The part that does not fit.
        what: String,
        /// Bytes needed.
        needed: u64,
        /// Bytes present.
        available: u64,
    },
    /// Declared dimensions are zero, overflow or exceed the limit.
    #[error("{format:?}: invalid dimensions {width} x {height}: {reason}")]
    Dimensions {
        /// Format being decoded.
        format: Format,
        /// Declared width.
        width: u64,
        /// Declared height.
        height: u64,
        /// Why they are rejected.
        reason: String,
    },
    /// The format could not be recognised from the bytes or the file name.
    #[error("unknown format: {0}")]
    UnknownFormat(String),
    /// A valid file using a feature this crate does not read (e.g. a colour TIFF).
    #[error("{format:?}: unsupported: {reason}")]
    Unsupported {
        /// Format concerned.
        format: Format,
        /// The unsupported feature.
        reason: String,
    },
    /// Every sample is a void (NaN or nodata).
    #[error("{format:?}: the raster contains only voids (nodata/NaN); nothing to read")]
    AllVoid {
        /// Format being decoded.
        format: Format,
    },
    /// An invalid option or argument.
    #[error("invalid parameter `{name}` = {value}: {reason}")]
    Param {
        /// Parameter name.
        name: &'static str,
        /// Its value, formatted.
        value: String,
        /// Why it is invalid.
        reason: String,
    },
    /// The heightfield could not be built (invalid size or cell size).
    #[error(transparent)]
    Heightfield(#[from] HeightfieldError),
    /// Wrapped error with the file it came from.
    #[error("{path}: {source}")]
    InFile {
        /// The file concerned.
        path: PathBuf,
        /// The error.
        #[source]
        source: Box<IoError>,
    },
}

impl IoError {
    /// A `width x height` raster the format cannot hold, or refused for its size.
    pub(crate) fn dimensions(format: Format, width: usize, height: usize, reason: &str) -> Self {
        IoError::Dimensions {
            format,
            width: width as u64,
            height: height as u64,
            reason: reason.into(),
        }
    }

    pub(crate) fn malformed(format: Format, reason: impl Into<String>) -> Self {
        IoError::Malformed {
            format,
            reason: reason.into(),
        }
    }

    pub(crate) fn unsupported(format: Format, reason: impl Into<String>) -> Self {
        IoError::Unsupported {
            format,
            reason: reason.into(),
        }
    }

    pub(crate) fn truncated(
        format: Format,
        what: impl Into<String>,
        needed: u64,
        available: u64,
    ) -> Self {
        IoError::Truncated {
            format,
            what: what.into(),
            needed,
            available,
        }
    }

    pub(crate) fn param(
        name: &'static str,
        value: impl std::fmt::Display,
        reason: impl Into<String>,
    ) -> Self {
        IoError::Param {
            name,
            value: value.to_string(),
            reason: reason.into(),
        }
    }

    pub(crate) fn os(path: &std::path::Path, source: std::io::Error) -> Self {
        IoError::Os {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn in_file(self, path: &std::path::Path) -> Self {
        match self {
            e @ (IoError::Os { .. } | IoError::InFile { .. }) => e,
            e => IoError::InFile {
                path: path.to_path_buf(),
                source: Box::new(e),
            },
        }
    }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, IoError>;

impl From<ParamError> for IoError {
    fn from(e: ParamError) -> Self {
        Self::param(e.name, e.value, e.reason)
    }
}
