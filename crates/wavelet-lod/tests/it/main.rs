//! The integration tests of relief-wavelet-lod, in one test binary (one link for the crate); each
//! module is one area.

mod conformance;
mod real_dem;
mod refine;
mod settings;
