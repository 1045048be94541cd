//! The integration tests of relief-sparse-core, in one test binary (one link for the crate); each
//! module is one area.

mod dictionary_format;
mod field;
mod nearest;
mod omp_conformance;
mod patch_bands;
mod sct;
mod settings;
mod tree;
