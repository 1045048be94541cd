//! The integration tests of relief-implicit-volume, in one test binary (one link for the crate); each
//! module is one area.

mod physical_sizes;
mod real_dem;
mod render;
mod settings_proptest;
mod shapes;
