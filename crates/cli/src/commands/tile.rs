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
    /// Write a Cloud-Optimized GeoTIFF: tiled, overviews down to one tile, directories first.
    #[arg(long)]
    cog: bool,
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

fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("cannot resolve {}", p.display()))
}

/// The planned subcommand with every path argument made absolute (so tasks and the mosaic
/// can run from any directory), and its input and output paths.
fn absolutise(cmd: &mut Windowable) -> Result<(Vec<PathBuf>, PathBuf)> {
    Ok(match cmd {
        Windowable::Amplify(a) => {
            a.input = absolute(&a.input)?;
            a.output = absolute(&a.output)?;
            a.exemplar = absolute(&a.exemplar)?;
            (vec![a.input.clone(), a.exemplar.clone()], a.output.clone())
        }
        Windowable::Refine(a) => {
            a.input = absolute(&a.input)?;
            a.output = absolute(&a.output)?;
            (vec![a.input.clone()], a.output.clone())
        }
        Windowable::Decompress(a) => {
            a.input = absolute(&a.input)?;
            a.output = absolute(&a.output)?;
            (vec![a.input.clone()], a.output.clone())
        }
    })
}

/// Rewrites the argument list with absolute input/output paths (positional arguments and
/// `--exemplar`), leaving every other argument as typed.
fn absolute_args(args: &[String], inputs: &[PathBuf], output: &Path) -> Vec<String> {
    let mut out = Vec::with_capacity(args.len());
    let mut positional = 0;
    let mut i = 0;
    while i < args.len() {
        let a = &args[i];
        if i == 0 {
            out.push(a.clone());
        } else if a == "--exemplar" && i + 1 < args.len() {
            out.push(a.clone());
            out.push(inputs[1].display().to_string());
            i += 1;
        } else if a.starts_with("--exemplar=") {
            out.push(format!("--exemplar={}", inputs[1].display()));
        } else if a.starts_with('-') {
            out.push(a.clone());
        } else if positional < 2 && !takes_value(&args[i - 1]) {
            out.push(if positional == 0 {
                inputs[0].display().to_string()
            } else {
                output.display().to_string()
            });
            positional += 1;
        } else {
            out.push(a.clone());
        }
        i += 1;
    }
    out
}

/// Whether a flag consumes the next argument (`--factor 4`), judged by the windowable
/// commands' definitions.
fn takes_value(prev: &str) -> bool {
    use clap::CommandFactory;
    let Some(long) = prev.strip_prefix("--") else {
        return false;
    };
    if long.contains('=') {
        return false;
    }
    let cmd = Inner::command();
    cmd.get_subcommands().any(|s| {
        s.get_arguments()
            .any(|a| a.get_long() == Some(long) && a.get_action().takes_values())
    })
}

fn plan(a: PlanArgs, ctx: &Ctx) -> Result<()> {
    if a.tile < 16 || !a.tile.is_multiple_of(16) || a.tile > 1 << 15 {
        bail!(
            "invalid --tile {}: must be a multiple of 16 between 16 and 32768",
            a.tile
        );
    }
    let mut inner = Inner::try_parse_from(&a.command)
        .map_err(|e| anyhow::anyhow!("invalid command after `--`: {}", e.to_string().trim()))?;
    let (inputs, output) = absolutise(&mut inner.command)?;
    let name = a.command[0].clone();
    let args = absolute_args(&a.command, &inputs, &output);
    // The rewritten arguments must parse to the same command.
    Inner::try_parse_from(&args).context("cannot rewrite the command's paths")?;
    match &inner.command {
        Windowable::Amplify(x) if x.window.is_some() => bail!(
            "--window cannot be planned: a plan covers the whole output (the tiles are windows)"
        ),
        Windowable::Refine(x) if x.window_of.is_some() => bail!(
            "--window cannot be planned: a plan covers the whole output (the tiles are windows)"
        ),
        Windowable::Decompress(x) if x.window.is_some() => bail!(
            "--window cannot be planned: a plan covers the whole output (the tiles are windows)"
        ),
        _ => {}
    }
    if relief_io::Format::from_extension(&output) != Some(relief_io::Format::GeoTiff) {
        bail!(
            "the planned output {} must be a GeoTIFF (.tif): the mosaic is streamed into one",
            output.display()
        );
    }
    let dir = absolute(&a.dir)?;
    if dir.exists()
        && std::fs::read_dir(&dir)
            .with_context(|| format!("cannot read {}", dir.display()))?
            .next()
            .is_some()
    {
        bail!(
            "the plan folder {} is not empty (a plan is written into a new folder)",
            dir.display()
        );
    }
    let in_refs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    ctx.check_outputs(&in_refs, &[(&output, crate::outputs::OutKind::Raster)])?;
    if inputs.iter().any(|i| dir.starts_with(i)) || output.starts_with(&dir) {
        bail!(
            "the plan folder {} must not contain the output nor be an input",
            dir.display()
        );
    }
    let sums = inputs
        .iter()
        .map(|p| file_sum(p, p.display().to_string()))
        .collect::<Result<Vec<_>>>()?;
    // Prepare what every task reads, and the output grid.
    let (prepared_name, prepared_bytes, width, height, cell, georef) = match &inner.command {
        Windowable::Amplify(x) => {
            // The plan writes the model only; the tasks write windows of it.
            let out = super::amplify::OutputPlan {
                sct: true,
                window: None,
                stream: true,
                steps_flag: "--factor",
            };
            let sct = super::amplify::build(x, out, ctx)?;
            let (w, h) = sct.raster_size(1.0).context("cannot size the output")?;
            let win = Window {
                x: 0,
                y: 0,
                width: w,
                height: h,
            };
            let g = sct.raster_georef(1.0, win);
            let bytes = sct.to_bytes().context("cannot serialise the model")?;
            ("model.sct", bytes, w, h, sct.cell_size(), g)
        }
        Windowable::Decompress(x) => {
            let bytes = super::compress::read_model_bytes(&x.input, ctx)?;
            let sct = Sct::from_bytes(&bytes, &super::compress::registry())
                .with_context(|| format!("cannot read {}", x.input.display()))?;
            let (w, h) = sct
                .raster_size(x.scale)
                .context("invalid parameter `--scale`")?;
            let win = Window {
                x: 0,
                y: 0,
                width: w,
                height: h,
            };
            let g = sct.raster_georef(x.scale, win);
            let probe = sct.rasterize(&RasterSettings {
                scale: x.scale,
                window: Some(Window {
                    width: 1,
                    height: 1,
                    ..win
                }),
            })?;
            ("model.sct", bytes, w, h, probe.cell_size(), g)
        }
        Windowable::Refine(x) => {
            let settings = x.settings()?;
            let hf = super::read_raster(&x.input, &x.read, ctx)?.heightfield;
            if hf.has_voids() {
                bail!(
                    "{} has {} void cells; fill them first (--fill-voids)",
                    x.input.display(),
                    hf.void_count()
                );
            }
            let refiner = relief_wavelet_lod::Refiner::new(&hf, &settings)
                .with_context(|| format!("cannot analyse {}", x.input.display()))?;
            let (w, h) = refiner.output_size();
            let corner = refiner.render_window(0, 0, 1, 1)?;
            let bytes = relief_io::encode(
                &hf,
                relief_io::Format::GeoTiff,
                &relief_io::WriteOptions {
                    compression: relief_io::TiffCompression::Deflate,
                    ..Default::default()
                },
            )?;
            (
                "input.tif",
                bytes,
                w,
                h,
                corner.cell_size(),
                corner.georef().cloned(),
            )
        }
    };
    let (tx, ty) = (width.div_ceil(a.tile), height.div_ceil(a.tile));
    if tx.saturating_mul(ty) > MAX_TASKS {
        bail!(
            "{tx} x {ty} tiles exceed {MAX_TASKS} tasks: use a larger --tile than {}",
            a.tile
        );
    }
    std::fs::create_dir_all(dir.join("tiles"))
        .with_context(|| format!("cannot create {}", dir.display()))?;
    relief_io::write_bytes_atomic(&dir.join(prepared_name), &prepared_bytes)
        .with_context(|| format!("cannot write {}", dir.join(prepared_name).display()))?;
    let mut m = Manifest {
        format: FORMAT.into(),
        version: 1,
        command: name,
        args,
        inputs: sums,
        prepared: bytes_sum(&prepared_bytes, prepared_name.into()),
        output: OutputGrid {
            path: output.display().to_string(),
            width,
            height,
            cell_size: [cell.0, cell.1],
            georef,
        },
        tile: a.tile,
        tiles_x: tx,
        tiles_y: ty,
        tasks: tx * ty,
        plan_id: String::new(),
    };
    m.plan_id = hex(Sha256::digest(serde_json::to_vec(&m)?));
    let json = serde_json::to_string_pretty(&m)? + "\n";
    relief_io::write_bytes_atomic(&dir.join(MANIFEST), json.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join(MANIFEST).display()))?;
    ctx.note(format!(
        "planned {} x {} output {} as {} tasks of {} px tiles ({tx} x {ty}) in {}\n\
         run them with: sbatch --array=0-{} --wrap 'relief tile run {}'",
        width,
        height,
        output.display(),
        m.tasks,
        a.tile,
        dir.display(),
        m.tasks - 1,
        dir.display()
    ));
    Ok(())
}

/// Reads and checks `DIR/manifest.json`.
fn load_manifest(dir: &Path) -> Result<Manifest> {
    let path = dir.join(MANIFEST);
    let bytes = std::fs::read(&path)
        .with_context(|| format!("cannot read {} (is this a plan folder?)", path.display()))?;
    let mut m: Manifest = serde_json::from_slice(&bytes)
        .with_context(|| format!("{} is not a tile plan manifest", path.display()))?;
    if m.format != FORMAT || m.version != 1 {
        bail!("{} is not a version-1 {FORMAT} manifest", path.display());
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

/// The task index from `--index` or the scheduler's environment.
fn task_index(given: Option<usize>) -> Result<usize> {
    if let Some(i) = given {
        return Ok(i);
    }
    for var in INDEX_VARS {
        if let Ok(v) = std::env::var(var) {
            return v
                .trim()
                .parse()
                .with_context(|| format!("{var} = `{v}` is not a task index"));
        }
    }
    bail!(
        "no task index: pass --index or run under a job array ({})",
        INDEX_VARS.join(", ")
    )
}

fn run_task(a: RunArgs, ctx: &Ctx) -> Result<()> {
    let dir = absolute(&a.dir)?;
    let m = load_manifest(&dir)?;
    let i = task_index(a.index)?;
    if i >= m.tasks {
        bail!(
            "task index {i} is out of range: the plan has {} tasks (0..{})",
            m.tasks,
            m.tasks - 1
        );
    }
    if tile_state(&dir, &m, i) == TileState::Done {
        ctx.note(format!("tile {i} is already done"));
        return Ok(());
    }
    // Inputs still reachable must be those planned (a task on another machine may not see
    // them: it reads only the prepared file, which is always checked).
    for s in &m.inputs {
        let p = Path::new(&s.path);
        if p.exists() {
            let now = file_sum(p, s.path.clone())?;
            if now != *s {
                bail!(
                    "input {} changed since the plan (checksum {} instead of {}); plan again",
                    s.path,
                    &now.sha256[..12],
                    &s.sha256[..12]
                );
            }
        }
    }
    let prepared_path = dir.join(&m.prepared.path);
    let prepared = super::compress::read_model_bytes(&prepared_path, ctx)?;
    if bytes_sum(&prepared, m.prepared.path.clone()) != m.prepared {
        bail!(
            "{} does not match its checksum in the manifest (corrupt or replaced); plan again",
            prepared_path.display()
        );
    }
    let [x, y, w, h] = m.window(i);
    let inner = Inner::try_parse_from(&m.args).context("the manifest's command does not parse")?;
    let hf = render(
        &inner.command,
        &prepared,
        Window {
            x,
            y,
            width: w,
            height: h,
        },
    )?;
    let bytes = relief_io::encode(
        &hf,
        relief_io::Format::GeoTiff,
        &relief_io::WriteOptions {
            compression: relief_io::TiffCompression::Deflate,
            ..Default::default()
        },
    )?;
    let name = tile_name(i);
    let tile_path = dir.join("tiles").join(&name);
    relief_io::write_bytes_atomic(&tile_path, &bytes)
        .with_context(|| format!("cannot write {}", tile_path.display()))?;
    let rec = TileRecord {
        plan_id: m.plan_id.clone(),
        index: i,
        window: [x, y, w, h],
        file: bytes_sum(&bytes, name),
    };
    let json = serde_json::to_string_pretty(&rec)? + "\n";
    relief_io::write_bytes_atomic(&record_path(&dir, i), json.as_bytes())
        .with_context(|| format!("cannot write the record of tile {i}"))?;
    ctx.note(format!("tile {i} done ({w} x {h} at {x},{y})"));
    Ok(())
}

/// One window of the planned output, from the prepared file.
fn render(cmd: &Windowable, prepared: &[u8], win: Window) -> Result<Heightfield> {
    let sct_window = |scale: f64| -> Result<Heightfield> {
        let sct = Sct::from_bytes(prepared, &super::compress::registry())
            .context("cannot read the prepared model")?;
        Ok(sct.rasterize(&RasterSettings {
            scale,
            window: Some(win),
        })?)
    };
    match cmd {
        Windowable::Amplify(_) => sct_window(1.0),
        Windowable::Decompress(x) => sct_window(x.scale),
        Windowable::Refine(x) => {
            let settings = x.settings()?;
            let hf = relief_io::read_bytes(
                prepared,
                Some(Path::new("input.tif")),
                &relief_io::ReadOptions::default(),
            )
            .context("cannot read the prepared input")?
            .heightfield;
            let refiner = relief_wavelet_lod::Refiner::new(&hf, &settings)
                .context("cannot analyse the prepared input")?;
            Ok(refiner.render_window(win.x, win.y, win.width, win.height)?)
        }
    }
}

fn status(a: StatusArgs, ctx: &Ctx) -> Result<()> {
    let dir = absolute(&a.dir)?;
    let m = load_manifest(&dir)?;
    let (mut missing, mut corrupt) = (Vec::new(), Vec::new());
    for i in 0..m.tasks {
        match tile_state(&dir, &m, i) {
            TileState::Done => {}
            TileState::Missing => missing.push(i),
            TileState::Corrupt => corrupt.push(i),
        }
    }
    let done = m.tasks - missing.len() - corrupt.len();
    let mut text = format!(
        "{done}/{} tiles done, {} missing, {} corrupt\n",
        m.tasks,
        missing.len(),
        corrupt.len()
    );
    if !missing.is_empty() {
        text.push_str(&format!("missing: {}\n", ranges(&missing)));
    }
    if !corrupt.is_empty() {
        text.push_str(&format!("corrupt: {}\n", ranges(&corrupt)));
    }
    std::io::Write::write_all(&mut std::io::stdout().lock(), text.as_bytes())
        .context("cannot write to stdout")?;
    if done < m.tasks {
        bail!(
            "the plan is incomplete: run tasks {} again",
            ranges(&{
                let mut all = [missing, corrupt].concat();
                all.sort_unstable();
                all
            })
        );
    }
    ctx.note("every tile is done: relief tile mosaic can assemble them");
    Ok(())
}

/// `0-3,7,9-10`: the indices as Slurm `--array` ranges.
fn ranges(v: &[usize]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1] == v[j] + 1 {
            j += 1;
        }
        out.push(if i == j {
            v[i].to_string()
        } else {
            format!("{}-{}", v[i], v[j])
        });
        i = j + 1;
    }
    out.join(",")
}

fn mosaic(a: MosaicArgs, ctx: &Ctx) -> Result<()> {
    let dir = absolute(&a.dir)?;
    let m = load_manifest(&dir)?;
    let bad: Vec<usize> = (0..m.tasks)
        .filter(|&i| tile_state(&dir, &m, i) != TileState::Done)
        .collect();
    if !bad.is_empty() {
        bail!(
            "{} of {} tiles are missing or corrupt ({}): run them (relief tile status {})",
            bad.len(),
            m.tasks,
            ranges(&bad),
            dir.display()
        );
    }
    let out = PathBuf::from(&m.output.path);
    let inputs: Vec<PathBuf> = m.inputs.iter().map(|s| PathBuf::from(&s.path)).collect();
    let in_refs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let vrt = dir.join("mosaic.vrt");
    if !a.vrt_only {
        ctx.check_outputs(&in_refs, &[(&out, crate::outputs::OutKind::Raster)])?;
    }
    write_vrt(&vrt, &m)?;
    if a.vrt_only {
        ctx.note(format!("wrote {}", vrt.display()));
        return Ok(());
    }
    let opts = relief_io::TiledOptions {
        tile: 512,
        compression: match ctx.compress {
            crate::ctx::CompressArg::Deflate => relief_io::TiffCompression::Deflate,
            crate::ctx::CompressArg::None => relief_io::TiffCompression::None,
        },
        cog: a.cog,
        bigtiff: a.bigtiff,
    };
    let cell = (m.output.cell_size[0], m.output.cell_size[1]);
    let mut writer = relief_io::TiledGeoTiffWriter::create(
        &out,
        m.output.width,
        m.output.height,
        cell,
        m.output.georef.as_ref(),
        opts,
    )
    .with_context(|| format!("cannot write {}", out.display()))?;
    let progress = ctx.progress();
    progress.begin("mosaicking", m.output.height as u64);
    // Blocks of rows: every tile of a row of tiles decodes its part in parallel, then the
    // block goes to the writer (which compresses its tiles in parallel too).
    let width = m.output.width;
    let mut block: Vec<f32> = Vec::new();
    for r in 0..m.tiles_y {
        let mut readers = (0..m.tiles_x)
            .map(|c| {
                let p = dir.join("tiles").join(tile_name(r * m.tiles_x + c));
                relief_io::GeoTiffRowReader::open(&p)
                    .with_context(|| format!("cannot read {}", p.display()))
            })
            .collect::<Result<Vec<_>>>()?;
        let [_, _, _, h] = m.window(r * m.tiles_x);
        let mut y = 0;
        while y < h {
            let rows = MOSAIC_ROWS.min(h - y);
            let parts = readers
                .par_iter_mut()
                .map(|rd| {
                    let mut part = Vec::with_capacity(rows * rd.width());
                    for _ in 0..rows {
                        rd.read_row(&mut part)?;
                    }
                    Ok(part)
                })
                .collect::<Result<Vec<Vec<f32>>>>()?;
            block.clear();
            block.reserve(rows * width);
            for k in 0..rows {
                for (part, rd) in parts.iter().zip(&readers) {
                    let w = rd.width();
                    block.extend_from_slice(&part[k * w..(k + 1) * w]);
                }
            }
            writer.write_rows(&block)?;
            progress.advance(rows as u64);
            y += rows;
        }
    }
    writer
        .finish()
        .with_context(|| format!("cannot write {}", out.display()))?;
    drop(progress);
    ctx.note(format!(
        "wrote {} ({} x {}{}) and {}",
        out.display(),
        m.output.width,
        m.output.height,
        if a.cog { ", cloud-optimized" } else { "" },
        vrt.display()
    ));
    Ok(())
}

/// A GDAL VRT over the tiles (paths relative to the VRT).
fn write_vrt(path: &Path, m: &Manifest) -> Result<()> {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<VRTDataset rasterXSize=\"{}\" rasterYSize=\"{}\">",
        m.output.width, m.output.height
    );
    let g = m.output.georef.as_ref();
    if let Some(crs) = g
        .and_then(|g| g.crs.as_deref())
        .filter(|c| c.starts_with("EPSG:"))
    {
        let _ = writeln!(s, "  <SRS dataAxisToSRSAxisMapping=\"1,2\">{crs}</SRS>");
    }
    let t = g.and_then(|g| g.geotransform).unwrap_or([
        0.0,
        m.output.cell_size[0],
        0.0,
        0.0,
        0.0,
        -m.output.cell_size[1],
    ]);
    let _ = writeln!(
        s,
        "  <GeoTransform>{:e}, {:e}, {:e}, {:e}, {:e}, {:e}</GeoTransform>",
        t[0], t[1], t[2], t[3], t[4], t[5]
    );
    s.push_str("  <VRTRasterBand dataType=\"Float32\" band=\"1\">\n");
    for i in 0..m.tasks {
        let [x, y, w, h] = m.window(i);
        let _ = write!(
            s,
            "    <SimpleSource>\n      <SourceFilename relativeToVRT=\"1\">tiles/{}</SourceFilename>\n      \
             <SourceBand>1</SourceBand>\n      <SrcRect xOff=\"0\" yOff=\"0\" xSize=\"{w}\" ySize=\"{h}\"/>\n      \
             <DstRect xOff=\"{x}\" yOff=\"{y}\" xSize=\"{w}\" ySize=\"{h}\"/>\n    </SimpleSource>\n",
            tile_name(i)
        );
    }
    s.push_str("  </VRTRasterBand>\n</VRTDataset>\n");
    relief_io::write_bytes_atomic(path, s.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))
}

#[cfg(test)]
mod tests {
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
        assert_eq!(a.seed, 3);
    }

    #[test]
    fn windows_cover_the_output_once() {
        let m = Manifest {
            format: FORMAT.into(),
            version: 1,
            command: "refine".into(),
            args: vec![],
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
            version: 1,
            command: "refine".into(),
            args: vec!["refine".into()],
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
