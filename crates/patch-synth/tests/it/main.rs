//! The integration tests of relief-patch-synth, in one test binary (one link for the crate); each
//! module is one area.

mod control;
mod proptest_inputs;
mod real_dem;
