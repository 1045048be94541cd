//! Checks of settings and arguments shared by every crate's `check()`: a value outside its
//! valid range becomes a [`ParamError`] naming the field, the value and what is expected, which
//! each crate's error enum turns into its own "invalid parameter" variant with `From`, so a
//! `check()` is one line per field instead of a five-line `if` block.

use std::fmt::Display;
use std::ops::RangeBounds;

use thiserror::Error;

/// A setting or argument out of its valid range.
#[derive(Debug, Error, Clone, PartialEq)]
#[error("invalid parameter `{name}` = {value}: {reason}")]
pub struct ParamError {
    /// Parameter name.
    pub name: &'static str,
    /// Offending value, formatted.
    pub value: String,
    /// What is expected.
    pub reason: &'static str,
}

impl ParamError {
    /// The error naming `name`, its `value` and the `reason` it is rejected.
    pub fn new(name: &'static str, value: impl Display, reason: &'static str) -> Self {
        Self {
            name,
            value: value.to_string(),
            reason,
        }
    }
}

/// `Ok` when `ok` holds, else the [`ParamError`] naming `name` and `value`.
pub fn ensure(
    ok: bool,
    name: &'static str,
    value: impl Display,
    reason: &'static str,
) -> Result<(), ParamError> {
    if ok {
        Ok(())
    } else {
        Err(ParamError::new(name, value, reason))
    }
}

/// `Ok` when `range` contains `value` (never for a NaN), else the [`ParamError`] naming `name`.
pub fn in_range<T: PartialOrd + Display>(
    name: &'static str,
    value: T,
    range: impl RangeBounds<T>,
    reason: &'static str,
) -> Result<(), ParamError> {
    ensure(range.contains(&value), name, value, reason)
}

/// `Ok` when `lo < value <= hi` (the half-open interval `(lo, hi]`, never for a NaN), else the
/// [`ParamError`] naming `name`: the range of a positive rate, fraction or size with a cap.
pub fn in_left_open<T: PartialOrd + Display>(
    name: &'static str,
    value: T,
    (lo, hi): (T, T),
    reason: &'static str,
) -> Result<(), ParamError> {
    ensure(value > lo && value <= hi, name, value, reason)
}

/// [`in_range`] on the field `$field` of `$settings`, named after the field, so that the name in
/// the error cannot drift from the field checked:
/// `check_field!(self, tile, 16..=65_536, "must be in 16..=65536")?` checks `self.tile`.
#[macro_export]
macro_rules! check_field {
    ($settings:ident, $field:ident, $range:expr, $reason:expr) => {
        $crate::param::in_range(stringify!($field), $settings.$field, $range, $reason)
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn in_range_names_the_value_and_rejects_nan() {
        assert!(in_range("k", 3usize, 1..=12, "must be in 1..=12").is_ok());
        let e = in_range("k", 13usize, 1..=12, "must be in 1..=12").unwrap_err();
        assert_eq!(
            e.to_string(),
            "invalid parameter `k` = 13: must be in 1..=12"
        );
        assert!(in_range("g", f64::NAN, 0.0..=8.0, "must be in [0, 8]").is_err());
        assert!(in_left_open("r", 0.5, (0.0, 0.5), "must be in (0, 0.5]").is_ok());
        for bad in [0.0, 0.51, f64::NAN] {
            let e = in_left_open("r", bad, (0.0, 0.5), "must be in (0, 0.5]").unwrap_err();
            assert_eq!(e.name, "r");
        }
        assert!(ensure(false, "x", 0.5, "must be > 1").is_err());
        struct S {
            tile: usize,
        }
        let s = S { tile: 8 };
        let e = crate::check_field!(s, tile, 16..=64, "must be in 16..=64").unwrap_err();
        assert_eq!((e.name, e.value.as_str()), ("tile", "8"));
    }
}
