//! The library half of the `relief` command-line tool: its commands, their flags and
//! pre-flight checks, outputs and tile plans ([`app`] parses and runs a command line). The
//! pipeline `relief run` runs is the `relief-pipeline` crate, re-exported as [`pipeline`].
//!
//! This is application code, not one of the method libraries: it reports errors with `anyhow`
//! and prints what a command line prints.

pub mod app;
#[doc(hidden)]
pub mod fuzzing;
/// The pipeline `relief run` runs (the `relief-pipeline` crate).
pub use relief_pipeline as pipeline;

mod args;
mod budget;
mod commands;
mod ctx;
mod describe;
mod folder;
mod interrupt;
mod landform;
mod memory;
mod outputs;
mod read;
mod sparse_model;
mod staging;
mod synth_args;
mod tile_manifest;
mod volume_io;

pub use relief_pipeline::{target_dir, workspace_root};
