use std::ops::RangeInclusive;

use relief_heightfield::ParamError;
use thiserror::Error;

/// `[("a", s.a), ("b", s.b)]`: fields of `s` paired with their own names, for the checks
/// whose errors name the offending field (so a name cannot drift from its field).
macro_rules! named_fields {
    ($s:expr; $($f:ident),+ $(,)?) => {
        [$((stringify!($f), $s.$f)),+]
    };
}

/// Errors of this crate.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum Error {
    /// The caller asked the work to stop (`Progress::stopped`: its time budget ran out).
    #[error("stopped: {0} was cut short")]
    Stopped(&'static str),
    /// A parameter is out of its valid range.
    #[error(transparent)]
    InvalidParameter(#[from] ParamError),
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
        Self::InvalidParameter(ParamError::new(name, value, reason))
    }

    /// [`in_range`](relief_heightfield::param::in_range) of every `(name, value)` in turn,
    /// against one range.
    pub(crate) fn check_all_in<T: PartialOrd + std::fmt::Display + Copy>(
        values: &[(&'static str, T)],
        range: RangeInclusive<T>,
        reason: &'static str,
    ) -> Result<()> {
        for &(n, v) in values {
            relief_heightfield::param::in_range(n, v, range.clone(), reason)?;
        }
        Ok(())
    }

    /// `id` when it is the index of one of `len` nodes, else [`Error::param`] naming `name`.
    pub(crate) fn check_node(name: &'static str, id: u32, len: usize) -> Result<u32> {
        if (id as usize) < len {
            Ok(id)
        } else {
            Err(Self::param(name, id, "not a node of this tree"))
        }
    }

    /// [`Error::param`] naming `name` unless `value` is finite and > 0.
    pub(crate) fn check_positive(name: &'static str, value: f32) -> Result<()> {
        let ok = value.is_finite() && value > 0.0;
        Ok(relief_heightfield::param::ensure(
            ok,
            name,
            value,
            "must be finite and > 0",
        )?)
    }
}

/// Result alias of this crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;
