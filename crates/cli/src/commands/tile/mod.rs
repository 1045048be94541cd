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
//! Every method renders a window exactly as the same window of a full run (an `.sct` window, a
//! wavelet window), so tiles need no halo and the mosaic equals the single run bit for bit,
//! whatever the tile size, the task order, kills and retries; seeds never depend on the task.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use clap::Parser as _;
use rayon::prelude::*;
use relief_heightfield::{GeoRef, Heightfield, Progress};
use relief_sparse_core::{RasterSettings, Sct, Window};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::ctx::Ctx;

mod mosaic;
mod plan;
mod task;

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
    /// Plan a windowable command (amplify, refine, decompress) as one task per output tile;
    /// writes DIR/manifest.json and the prepared inputs.
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
    /// The command to split, after `--`: amplify, refine or decompress with its arguments;
    /// its output must be a GeoTIFF (.tif) and it must not have --window.
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
    /// Only write DIR/mosaic.vrt (GDAL reads the tiles through it), not the GeoTIFF.
    #[arg(long)]
    vrt_only: bool,
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

/// `DIR/manifest.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Manifest {
    /// Always `relief-tile-plan`.
    format: String,
    version: u32,
    /// Subcommand (`amplify`, `refine`, `decompress`).
    command: String,
    /// Subcommand and arguments as planned, paths absolute.
    args: Vec<String>,
    /// The job's settings as the method crate defines them (serde): `RefineSettings` for
    /// refine, `AmplifySettings` for amplify (the model is prepared), `{"scale": s}` for
    /// decompress. Tasks run from these, not from re-parsed flags.
    job: serde_json::Value,
    /// The command's input files at plan time.
    inputs: Vec<FileSum>,
    /// The file in DIR every task reads (path relative to DIR).
    prepared: FileSum,
    /// The planned output.
    output: OutputGrid,
    /// Tile side and the tile grid.
    tile: usize,
    tiles_x: usize,
    tiles_y: usize,
    /// Number of tasks (one per tile, row-major from the north-west tile).
    tasks: usize,
    /// SHA-256 of the plan (every field above), recorded by every tile.
    plan_id: String,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
struct FileSum {
    path: String,
    bytes: u64,
    sha256: String,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct OutputGrid {
    path: String,
    width: usize,
    height: usize,
    cell_size: [f64; 2],
    georef: Option<GeoRef>,
}

/// `DIR/tiles/tile-NNNNNN.json`: a tile that is complete.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
struct TileRecord {
    plan_id: String,
    index: usize,
    window: [usize; 4],
    file: FileSum,
}

const MANIFEST: &str = "manifest.json";
const FORMAT: &str = "relief-tile-plan";

/// Manifest version (2: the job's settings are stored in `job`).
const VERSION: u32 = 2;
/// Rows of the output decoded at once by the mosaic (a 32768-wide output: 8 MiB).
const MOSAIC_ROWS: usize = 64;
/// Largest tile grid a plan accepts.
const MAX_TASKS: usize = 1 << 20;
/// Scheduler variables holding the task index, in the order they are consulted.
const INDEX_VARS: [&str; 3] = [
    "SLURM_ARRAY_TASK_ID",
    "JOB_COMPLETION_INDEX",
    "AWS_BATCH_JOB_ARRAY_INDEX",
];

/// Dispatches `relief tile ...`.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    match args.command {
        TileCommand::Plan(a) => plan(a, ctx),
        TileCommand::Run(a) => run_task(a, ctx),
        TileCommand::Status(a) => status(a, ctx),
        TileCommand::Mosaic(a) => mosaic(a, ctx),
    }
}

fn hex(d: impl AsRef<[u8]>) -> String {
    d.as_ref().iter().map(|b| format!("{b:02x}")).collect()
}

/// Checksum of a file, streamed.
fn file_sum(path: &Path, name: String) -> Result<FileSum> {
    use std::io::Read;
    let mut f =
        std::fs::File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = f
            .read(&mut buf)
            .with_context(|| format!("cannot read {}", path.display()))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
        bytes += n as u64;
    }
    Ok(FileSum {
        path: name,
        bytes,
        sha256: hex(h.finalize()),
    })
}

fn bytes_sum(bytes: &[u8], name: String) -> FileSum {
    FileSum {
        path: name,
        bytes: bytes.len() as u64,
        sha256: hex(Sha256::digest(bytes)),
    }
}

/// Reads and checks `DIR/manifest.json`.
fn load_manifest(dir: &Path) -> Result<Manifest> {
    let path = dir.join(MANIFEST);
    let bytes = std::fs::read(&path)
        .with_context(|| format!("cannot read {} (is this a plan folder?)", path.display()))?;
    let mut m: Manifest = serde_json::from_slice(&bytes)
        .with_context(|| format!("{} is not a tile plan manifest", path.display()))?;
    if m.format != FORMAT || m.version != VERSION {
        bail!(
            "{} is not a version-{VERSION} {FORMAT} manifest (plan again with this relief)",
            path.display()
        );
    }
    let id = std::mem::take(&mut m.plan_id);
    let want = hex(Sha256::digest(serde_json::to_vec(&m)?));
    if id != want {
        bail!(
            "{} was modified after planning (its plan_id does not match its content)",
            path.display()
        );
    }
    m.plan_id = id;
    if m.tile == 0
        || m.tiles_x != m.output.width.div_ceil(m.tile)
        || m.tiles_y != m.output.height.div_ceil(m.tile)
        || m.tasks != m.tiles_x * m.tiles_y
    {
        bail!("{} has an inconsistent tile grid", path.display());
    }
    Ok(m)
}

impl Manifest {
    /// Output window `[x, y, w, h]` of task `i`.
    fn window(&self, i: usize) -> [usize; 4] {
        let (c, r) = (i % self.tiles_x, i / self.tiles_x);
        let (x, y) = (c * self.tile, r * self.tile);
        [
            x,
            y,
            self.tile.min(self.output.width - x),
            self.tile.min(self.output.height - y),
        ]
    }
}

/// `hf` as a DEFLATE GeoTIFF in memory (tiles and the planned refine input).
fn deflate_geotiff(hf: &Heightfield) -> Result<Vec<u8>> {
    let options = relief_io::WriteOptions {
        compression: relief_io::TiffCompression::Deflate,
        ..Default::default()
    };
    Ok(relief_io::encode(hf, relief_io::Format::GeoTiff, &options)?)
}

fn tile_name(i: usize) -> String {
    format!("tile-{i:06}.tif")
}

fn record_path(dir: &Path, i: usize) -> PathBuf {
    dir.join("tiles").join(format!("tile-{i:06}.json"))
}

/// State of one tile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TileState {
    Done,
    Missing,
    /// A record whose tile file is absent, altered, or from another plan.
    Corrupt,
}

fn tile_state(dir: &Path, m: &Manifest, i: usize) -> TileState {
    let rec = record_path(dir, i);
    let Ok(bytes) = std::fs::read(&rec) else {
        return TileState::Missing;
    };
    let Ok(r) = serde_json::from_slice::<TileRecord>(&bytes) else {
        return TileState::Corrupt;
    };
    if r.plan_id != m.plan_id || r.index != i || r.window != m.window(i) {
        return TileState::Corrupt;
    }
    match file_sum(&dir.join("tiles").join(&r.file.path), r.file.path.clone()) {
        Ok(s) if s == r.file => TileState::Done,
        _ => TileState::Corrupt,
    }
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
    fn windows_cover_the_output_once() {
        let m = Manifest {
            format: FORMAT.into(),
            version: VERSION,
            command: "refine".into(),
            args: vec![],
            job: serde_json::Value::Null,
            inputs: vec![],
            prepared: bytes_sum(b"", "x".into()),
            output: OutputGrid {
                path: "o.tif".into(),
                width: 100,
                height: 37,
                cell_size: [1.0, 1.0],
                georef: None,
            },
            tile: 32,
            tiles_x: 4,
            tiles_y: 2,
            tasks: 8,
            plan_id: String::new(),
        };
        let mut seen = vec![0u8; 100 * 37];
        for i in 0..m.tasks {
            let [x, y, w, h] = m.window(i);
            for yy in y..y + h {
                for xx in x..x + w {
                    seen[yy * 100 + xx] += 1;
                }
            }
        }
        assert!(seen.iter().all(|&c| c == 1));
    }

    /// The plan id survives the manifest's JSON round trip: georeferences with awkward
    /// floats (a x64 cell of a Web-Mercator grid) read back to the same bits.
    #[test]
    fn manifests_round_trip_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let cell = 76.437_028_285_174_16 / 64.0;
        let mut m = Manifest {
            format: FORMAT.into(),
            version: VERSION,
            command: "refine".into(),
            args: vec!["refine".into()],
            job: serde_json::json!({"extra_levels": 2}),
            inputs: vec![],
            prepared: bytes_sum(b"abc", "input.tif".into()),
            output: OutputGrid {
                path: "/o.tif".into(),
                width: 32768,
                height: 32768,
                cell_size: [cell, cell * (1.0 + 1e-13)],
                georef: Some(GeoRef {
                    geotransform: Some([
                        -12_601_714.231_207_296,
                        cell,
                        0.0,
                        4_344_069.191_503_135_5,
                        0.0,
                        -cell,
                    ]),
                    crs: Some("EPSG:3857".into()),
                    ..Default::default()
                }),
            },
            tile: 4096,
            tiles_x: 8,
            tiles_y: 8,
            tasks: 64,
            plan_id: String::new(),
        };
        m.plan_id = hex(Sha256::digest(serde_json::to_vec(&m).unwrap()));
        let json = serde_json::to_string_pretty(&m).unwrap();
        std::fs::write(dir.path().join(MANIFEST), json).unwrap();
        let back = load_manifest(dir.path()).unwrap();
        assert_eq!(back.output.cell_size, m.output.cell_size);
        assert_eq!(back.plan_id, m.plan_id);
        std::fs::write(
            dir.path().join(MANIFEST),
            serde_json::to_string_pretty(&m)
                .unwrap()
                .replace("32768", "32769"),
        )
        .unwrap();
        assert!(load_manifest(dir.path()).is_err());
    }

    #[test]
    fn task_index_prefers_the_flag_then_the_scheduler() {
        assert_eq!(task_index(Some(5)).unwrap(), 5);
    }
}
