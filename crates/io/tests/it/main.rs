//! The integration tests of relief-io, in one test binary (one link for the crate); each
//! module is one area.

mod bad_files;
mod format_variants;
mod mesh_and_images;
mod real_dems;
mod reliability;
mod round_trip;
