//! Cross-crate integration tests of the relief workspace live in `tests/tests/*.rs`; this
//! library is empty. Tests read the real DEM set through `relief-testdata` (skipped with a
//! notice when `../shared/data/dem` is absent, failing when `CI` is set).
#![warn(missing_docs)]
