//! `relief tile plan|run|status|mosaic`: one windowable command (amplify, refine, decompress)
//! split into independent output tiles that any job-array scheduler runs (Slurm
//! `sbatch --array`, Kubernetes Indexed Jobs, AWS Batch array jobs), then mosaicked into the
//! output the single-machine command would have written, value for value.
//!
//! ```text
//! relief tile plan plan/ --tile 4096 -- amplify coarse.tif big.tif --exemplar ex.tif --factor 16
//! sbatch --array=0-63 --wrap 'relief tile run plan/'     # or: relief tile run plan/ --index 7
//! relief tile status plan/
//! relief tile mosaic plan/ --cog
//! ```
//!
//! - `plan` reads the inputs once, prepares what every task needs in `DIR` (the amplified
//!   `.sct` model, the decompressed model, or the void-filled input of `refine`) and writes
//!   `DIR/manifest.json`: the command and its arguments (paths made absolute), the checksums
//!   (SHA-256) of the inputs and of the prepared file, the output grid and georeference, and
//!   `"tasks"`, one per output tile.
//! - `run` renders one tile (index from `--index`, `SLURM_ARRAY_TASK_ID`,
//!   `JOB_COMPLETION_INDEX` or `AWS_BATCH_JOB_ARRAY_INDEX`) into `DIR/tiles/` atomically, then
//!   a small record with the tile's checksum. A tile whose record and file agree is skipped, so a
//!   killed or pre-empted task is simply run again. A prepared file or an (still reachable)
//!   input whose checksum changed since the plan is refused.
//! - `status` lists done / missing / corrupt tiles (exit code 1 while incomplete).
//! - `mosaic` checks every tile, streams them into the planned output (a tiled GeoTIFF, or a
//!   Cloud-Optimized GeoTIFF with overviews under `--cog`) with one band of tiles in memory, and
//!   writes `DIR/mosaic.vrt`, a GDAL VRT over the tiles.
//!
//! `relief tile plan DIR -- flow DEM -o OUT_DIR` plans drainage in seven phases instead
//! ([`flow`]): `tile run --phase P`, `tile status` names the phase to run next, and the mosaic
//! writes `OUT_DIR/{filled,direction,area,strahler,watersheds,hand}.tif`, `channels.geojson`
//! and `flow.json`, equal to `relief flow`'s (all but its `channels.png` preview).
//! `relief tile plan DIR -- masks DEM -o OUT_DIR` adds an eighth phase, the masks per tile,
//! and its mosaic writes the GeoTIFF masks, `splat.png` and `masks.json` of `relief masks`.
//!
//! Every method renders a window exactly as the same window of a full run (an `.sct` window, a
//! wavelet window), so tiles need no halo and the mosaic equals the single run bit for bit,
//! whatever the tile size, the task order, kills and retries; seeds never depend on the task.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Parser as _;
use rayon::prelude::*;
use relief_heightfield::{GeoRef, Heightfield, Progress};
use relief_sparse_core::{RasterSettings, Sct, Window};
use sha2::{Digest, Sha256};

use crate::ctx::Ctx;
use crate::tile_manifest::*;

mod flow;
mod mosaic;
mod plan;
mod task;

pub(crate) use flow::record_files;
use mosaic::{mosaic, status};
use plan::{absolute, plan};
use task::run_task;

/// Arguments of `relief tile`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    #[command(subcommand)]
    command: TileCommand,
}

#[derive(Debug, clap::Subcommand)]
enum TileCommand {
    /// Plan a windowable command (amplify, refine, decompress) as one task per output tile, or
    /// flow as seven phases (per tile, then one task, in turn, ending per tile) and masks as
    /// eight (flow's, then the masks per tile); writes DIR/manifest.json and the prepared
    /// inputs.
    Plan(PlanArgs),
    /// Run one task of a plan (index from --index, SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX
    /// or AWS_BATCH_JOB_ARRAY_INDEX); a tile already done is skipped.
    Run(RunArgs),
    /// Tiles done, missing and corrupt; exit code 1 while the plan is incomplete.
    Status(StatusArgs),
    /// Assemble the tiles into the planned output (GeoTIFF or COG) and DIR/mosaic.vrt.
    Mosaic(MosaicArgs),
}

/// Arguments of `relief tile plan`.
#[derive(Debug, clap::Args)]
struct PlanArgs {
    /// Plan folder (created; must be empty or absent; on a volume every task can read).
    dir: PathBuf,
    /// Tile side in output pixels (a multiple of 16).
    #[arg(long, default_value_t = 2048)]
    tile: usize,
    /// The command to split, after `--`: amplify, refine or decompress with its arguments
    /// (its output must be a GeoTIFF (.tif) and it must not have --window), or flow (a
    /// seven-phase plan of filling, D8 directions, drainage area, Strahler order, watersheds,
    /// HAND and channels, equal to the single run, without its channels.png preview;
    /// --depressions fill and --directions d8 only), or masks (flow's phases, then the masks
    /// and splat map per tile, equal to the single run; --format tif only, no erosion
    /// rasters). erode is refused: it has no exact multi-phase plan.
    #[arg(last = true, required = true, value_name = "COMMAND")]
    command: Vec<String>,
}

/// Arguments of `relief tile run`.
#[derive(Debug, clap::Args)]
struct RunArgs {
    /// Plan folder.
    dir: PathBuf,
    /// Task index (0-based; default: from the scheduler's environment).
    #[arg(long)]
    index: Option<usize>,
    /// Phase of a multi-phase plan (flow: 1 to 7, masks: 1 to 8; default: the first
    /// incomplete one); a phase refuses to run while an earlier one is incomplete.
    #[arg(long)]
    phase: Option<usize>,
}

/// Arguments of `relief tile status`.
#[derive(Debug, clap::Args)]
struct StatusArgs {
    /// Plan folder.
    dir: PathBuf,
}

/// Arguments of `relief tile mosaic`.
#[derive(Debug, clap::Args)]
struct MosaicArgs {
    /// Plan folder.
    dir: PathBuf,
    /// Always write BigTIFF (otherwise only when the file passes 4 GiB).
    #[arg(long)]
    bigtiff: bool,
    /// Only write DIR/mosaic.vrt (GDAL reads the tiles through it; flow plans:
    /// DIR/mosaic-{filled,direction,area,strahler,watersheds,hand}.vrt), not the GeoTIFF.
    #[arg(long)]
    vrt_only: bool,
    /// Write the mosaic here (a GeoTIFF; flow plans: a folder) instead of the planned output.
    /// Needed when the plan folder can be written by other users: the output path its
    /// manifest names is then not followed.
    #[arg(long, short = 'o', value_name = "PATH")]
    out: Option<PathBuf>,
}

/// The commands a plan can split.
#[derive(Debug, clap::Parser)]
#[command(name = "relief", no_binary_name = true)]
struct Inner {
    #[command(subcommand)]
    command: Windowable,
}

#[derive(Debug, clap::Subcommand)]
enum Windowable {
    Amplify(super::amplify::Args),
    Refine(super::refine::Args),
    Decompress(super::decompress::Args),
}

/// Dispatches `relief tile ...`.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    match args.command {
        TileCommand::Plan(a) => plan(a, ctx),
        TileCommand::Run(a) => run_task(a, ctx),
        TileCommand::Status(a) => status(a, ctx),
        TileCommand::Mosaic(a) => mosaic(a, ctx),
    }
}

/// The plan folder `dir` (made absolute) and its checked manifest: the start of `relief tile
/// status`, `run` and `mosaic`.
fn open_plan(dir: &Path) -> Result<(PathBuf, Manifest)> {
    let dir = absolute(dir)?;
    let m = load_manifest(&dir)?;
    Ok((dir, m))
}

#[cfg(test)]
mod tests {
    use super::mosaic::ranges;
    use super::plan::absolute_args;
    use super::task::task_index;
    use super::*;

    #[test]
    fn index_ranges() {
        assert_eq!(ranges(&[0, 1, 2, 3, 7, 9, 10]), "0-3,7,9-10");
        assert_eq!(ranges(&[5]), "5");
        assert_eq!(ranges(&[]), "");
    }

    #[test]
    fn paths_become_absolute_and_values_stay() {
        let args: Vec<String> = [
            "amplify",
            "--factor",
            "4",
            "in.tif",
            "out.tif",
            "--exemplar",
            "ex.tif",
            "--seed",
            "3",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let inputs = vec![PathBuf::from("/a/in.tif"), PathBuf::from("/a/ex.tif")];
        let got = absolute_args(&args, &inputs, Path::new("/a/out.tif"));
        assert_eq!(
            got,
            [
                "amplify",
                "--factor",
                "4",
                "/a/in.tif",
                "/a/out.tif",
                "--exemplar",
                "/a/ex.tif",
                "--seed",
                "3"
            ]
        );
        let parsed = Inner::try_parse_from(&got).unwrap();
        let Windowable::Amplify(a) = parsed.command else {
            panic!("not amplify")
        };
        assert_eq!(a.factor, 4);
        assert_eq!(a.seed.seed, 3);
    }

    #[test]
    fn task_index_prefers_the_flag_then_the_scheduler() {
        assert_eq!(task_index(Some(5)).unwrap(), 5);
    }
}
