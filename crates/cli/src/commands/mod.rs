//! One module per subcommand. Each exposes `pub(crate) struct Args` (clap `Args`) and
//! `pub(crate) fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()>`; `main.rs` lists them in
//! `enum Command` and dispatches in one `match`.

pub(crate) mod amplify;
pub(crate) mod analyze;
pub(crate) mod compress;
pub(crate) mod convert;
pub(crate) mod decompress;
pub(crate) mod erode;
pub(crate) mod export;
pub(crate) mod fit_procedural;
pub(crate) mod flow;
pub(crate) mod info;
pub(crate) mod learn;
pub(crate) mod masks;
pub(crate) mod preview;
pub(crate) mod quilt;
pub(crate) mod refine;
pub(crate) mod run;
pub(crate) mod synthesize;
pub(crate) mod tile;
pub(crate) mod tree;
pub(crate) mod validate;
pub(crate) mod volume;

pub(crate) mod preflight;

/// The input a command's report names (flattened into its JSON as `file`, `width`, `height`).
#[derive(Debug, serde::Serialize)]
pub(crate) struct InputGrid {
    pub(crate) file: String,
    pub(crate) width: usize,
    pub(crate) height: usize,
}

impl InputGrid {
    /// The input file `path` and the size of its grid `hf`.
    pub(crate) fn of(path: &std::path::Path, hf: &relief_heightfield::Heightfield) -> Self {
        Self {
            file: path.display().to_string(),
            width: hf.width(),
            height: hf.height(),
        }
    }
}

pub(crate) use crate::args::{ReadArgs, parse_crop, parse_image_size, parse_pair};
pub(crate) use crate::read::{
    JobCells, cell_size_assumed, cell_size_georef, read_raster, read_raster_for, read_void_free,
};
