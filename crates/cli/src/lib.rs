//! The application layer of `relief` shared by the `relief` binary and `cargo xtask`: the
//! [`pipeline`] (a JSON spec of stages run on one DEM, written as rasters, previews,
//! `summary.json` and `report.html`), run by `relief run SPEC.json` and by
//! `cargo xtask pipeline`.
//!
//! This is application code, not one of the method libraries: it reports errors with `anyhow`
//! and, when asked to be verbose, prints each stage's progress on stderr.

pub mod app;
#[doc(hidden)]
pub mod fuzzing;
pub mod pipeline;

mod args;
mod budget;
mod channels;
mod commands;
mod ctx;
mod describe;
mod folder;
mod interrupt;
mod landform;
mod memory;
mod outputs;
mod preflight;
mod sparse_model;
mod staging;
mod synth_args;
mod tile_manifest;
mod volume_io;

use std::path::{Path, PathBuf};

/// The workspace this crate was built from (its `fixtures/` and `docs/`), when it still exists:
/// the last place a relative path in a pipeline spec is looked up, so the bundled fixtures work
/// from a checkout. An installed binary whose sources are gone gets `None`.
pub fn workspace_root() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent()?.parent()?;
    root.join("Cargo.toml")
        .is_file()
        .then(|| root.to_path_buf())
}

/// Cargo's target directory of the workspace at `root` (`$CARGO_TARGET_DIR` or `root/target`).
pub fn target_dir(root: &Path) -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"))
}

#[cfg(test)]
pub(crate) fn test_root() -> PathBuf {
    workspace_root().expect("tests run from the workspace")
}
