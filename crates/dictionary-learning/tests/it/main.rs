//! The integration tests of relief-dictionary-learning, in one test binary (one link for the crate); each
//! module is one area.

mod api;
mod real_dem;
mod settings_proptest;
mod settings_serde;
mod sketch_structure;
