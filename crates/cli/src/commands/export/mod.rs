//! `relief export --engine unreal|unity|godot|gaea DEM OUT`: a DEM as the heightmap a game
//! engine or terrain tool imports ([`engine`] has each one's conventions and sources): resized
//! to one of the engine's sizes with the workspace's resamplers (Lanczos-3 down, Keys cubic up,
//! then the cell corners, [`relief_heightfield::Heightfield::corner_samples`]), written as a
//! 16-bit PNG or little-endian raw in the engine's row order, optionally as tiles that share
//! their edge samples, with the drainage masks packed as the engine's layers (`--masks`), and
//! an import sheet (`NAME.json`, `NAME.txt`) giving the settings that turn the counts back
//! into metres (Unreal's Z scale and Location Z, Unity's terrain height, Terrain3D's height
//! range, Gaea's height). Everything appears together or not at all.
//!
//! ```text
//! relief export --engine unreal dem.tif out/
//! relief export --engine unity dem.tif worlds/alps --tiles 4x4 --masks
//! ```

mod engine;
mod write;

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use relief_heightfield::Heightfield;

use crate::ctx::Ctx;
use crate::outputs::OutKind;
pub(crate) use engine::{Engine, Fit, HeightFormat};
use engine::{Layout, SizeAsk, Vertical};

/// Arguments of `relief export`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input DEM (format detected from its content); it must be void-free (--fill-voids).
    pub(crate) input: PathBuf,
    /// Output folder (an existing folder, or a path ending in /, created when absent): the
    /// files are named after the input (or --name); otherwise a prefix DIR/NAME: NAME.png,
    /// NAME.json, ... in DIR (created when absent; its parent must exist).
    pub(crate) out: PathBuf,
    /// Engine or tool the heightmap is for: unreal (landscape), unity (terrain), godot
    /// (Terrain3D) or gaea. Sets the sizes, the file format and row order, the tile names and
    /// the mask packing.
    #[arg(long, value_enum)]
    pub(crate) engine: Engine,
    /// Heightmap side in samples, one of the engine's sizes (Unreal: 127, 253, 505, 1009,
    /// 2017, 4033, 8129; Unity: 2^n+1 from 33 to 4097; Godot: a multiple of --region-size; the
    /// long side for Godot and Gaea). Default: fitted to the DEM by --fit.
    #[arg(long, value_name = "N")]
    pub(crate) size: Option<usize>,
    /// How the size is fitted to the DEM: nearest (in ratio), up (the smallest size that keeps
    /// every DEM sample) or down (the largest size within the DEM's).
    #[arg(long, value_enum, default_value_t = Fit::Nearest)]
    pub(crate) fit: Fit,
    /// Tiles NxM (across x down) for large worlds (unreal, unity): each tile a heightmap of
    /// the engine's sizes, neighbours sharing their edge samples.
    #[arg(long, value_name = "NxM", value_parser = crate::args::parse_size)]
    pub(crate) tiles: Option<(usize, usize)>,
    /// Side of each tile in samples (one of the engine's sizes); the tile count is fitted to
    /// the DEM by --fit unless --tiles gives it.
    #[arg(long, value_name = "N")]
    pub(crate) tile_size: Option<usize>,
    /// Terrain3D region size (--engine godot; default 256): the long side is a multiple of
    /// it.
    #[arg(long, value_name = "N")]
    pub(crate) region_size: Option<usize>,
    /// Heightmap file format: png (16-bit greyscale) or r16 (16-bit little-endian raw).
    /// Default: png for unreal and gaea, r16 (.raw) for unity and godot (which read raw
    /// only).
    #[arg(long, value_enum)]
    pub(crate) format: Option<HeightFormat>,
    /// Also write the drainage masks (ground, rock, sediment, wet; `relief masks` defaults) on
    /// the heightmap's grid, packed as the engine takes them: 8-bit weight maps per layer
    /// (unreal, gaea) or an RGBA splat map (unity: one alphamap per terrain; godot).
    #[arg(long)]
    pub(crate) masks: bool,
    /// File name stem when OUT is a folder (default: the input's stem).
    #[arg(long, value_name = "NAME")]
    pub(crate) name: Option<String>,
    /// Print the import sheet as JSON instead of text.
    #[arg(long)]
    pub(crate) json: bool,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Working bytes per output sample: the resampled grid and its transposed copies (16), the
/// corner grid (4), one tile's copy (4) and its encoding (2).
const BYTES_PER_SAMPLE: f64 = 26.0;

/// Working bytes per output sample of `--masks` beside the routing's: nine f32 masks (36), the
/// splat weights (16) and the RGBA map (4).
const MASK_BYTES_PER_SAMPLE: f64 = 56.0;

/// The output folder and the file stem of `out` (see [`Args::out`]).
fn destination(out: &Path, name: Option<&str>, input: &Path) -> Result<(PathBuf, String)> {
    let text = out.as_os_str().to_string_lossy();
    let folder = out.is_dir() || text.ends_with('/') || text.ends_with(std::path::MAIN_SEPARATOR);
    let (dir, stem) = if folder {
        let stem = match name {
            Some(n) => n.to_string(),
            None => input
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
        };
        (out.to_path_buf(), stem)
    } else {
        if name.is_some() {
            bail!(
                "--name: {} is a prefix DIR/NAME already (give a folder to use --name)",
                out.display()
            );
        }
        let dir = match out.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let stem = out
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        (dir, stem)
    };
    let known = ["png", "raw", "r16", "json", "txt"];
    if let Some(ext) = Path::new(&stem).extension().and_then(|e| e.to_str())
        && known.iter().any(|k| ext.eq_ignore_ascii_case(k))
    {
        bail!(
            "{}: OUT is a folder or a prefix DIR/NAME, not a file name: drop the .{ext}",
            out.display()
        );
    }
    let ok = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.');
    if stem.is_empty() || !stem.chars().all(ok) || stem.starts_with('.') {
        bail!(
            "the file name `{stem}` must be letters, digits, '_', '-' or '.' (not first): \
             give --name or another OUT"
        );
    }
    Ok((dir, stem))
}

/// The pre-flight check of the export of `hf` to `layout` against `--max-memory` and
/// `--max-output-size`, before the resampling.
fn preflight(hf: &Heightfield, layout: &Layout, masks: bool, ctx: &Ctx) -> Result<()> {
    let (sx, sy) = layout.samples;
    let n = sx as f64 * sy as f64;
    let change = "a smaller --size or --tile-size (or fewer --tiles)";
    let mask_out = if masks { 4.0 } else { 0.0 };
    ctx.check_output_size("the heightmaps", n * (2.0 + mask_out), change)?;
    let mut parts = vec![crate::memory::part(
        format!("the {sx} x {sy} heightmap"),
        n * BYTES_PER_SAMPLE + 8.0 * hf.height() as f64 * sx as f64 + hf.len() as f64 * 4.0,
        change,
    )];
    if masks {
        let flow = relief_landscape::flow::job::FlowSettings::BYTES_PER_CELL as f64;
        parts.push(crate::memory::part(
            "the drainage masks",
            n * (flow + MASK_BYTES_PER_SAMPLE),
            format!("{change}, or no --masks"),
        ));
    }
    ctx.check_memory("export", &[&parts])
}

/// The DEM on the export's grid: its cells ((sx-1) x (sy-1), the grid Unity's alphamaps take)
/// and the heightmap's samples at their corners (sx x sy).
#[derive(Debug)]
pub(crate) struct Grids {
    pub(crate) cells: Heightfield,
    pub(crate) corners: Heightfield,
}

fn grids(hf: &Heightfield, (sx, sy): (usize, usize)) -> Result<Grids> {
    let cells = if (hf.width(), hf.height()) == (sx - 1, sy - 1) {
        hf.clone()
    } else {
        hf.resample(sx - 1, sy - 1)?
    };
    let corners = cells.corner_samples()?;
    Ok(Grids { cells, corners })
}

/// Reads the DEM, fits it to the engine, writes the heightmaps, masks and the sheet.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let engine = args.engine;
    let format = engine.format(args.format)?;
    let region = args.region_size.unwrap_or(256);
    engine::check_region(engine, region, args.region_size.is_some())?;
    let (dir, stem) = destination(&args.out, args.name.as_deref(), &args.input)?;
    let job = super::JobCells {
        command: "export",
        what: "the DEM",
        bytes_per_cell: 12,
        output_bytes_per_cell: 0,
    };
    let hf = super::read_raster_for(&args.input, &args.read, ctx, Some(job))?.heightfield;
    if hf.has_voids() {
        bail!(
            "{} has {} void cells, which no engine heightmap holds: fill them first \
             (--fill-voids)",
            args.input.display(),
            hf.void_count()
        );
    }
    let ask = SizeAsk {
        size: args.size,
        tiles: args.tiles,
        tile_size: args.tile_size,
        region,
    };
    let layout = engine::layout(engine, (hf.width(), hf.height()), args.fit, ask)?;
    let plan = write::Plan {
        engine,
        format,
        stem,
        layout,
        masks: args.masks,
    };
    let names = plan.files();
    let kinds: Vec<(&str, OutKind)> = names.iter().map(|(n, k)| (n.as_str(), *k)).collect();
    preflight(&hf, &layout, args.masks, ctx)?;
    let staged = crate::folder::FolderOutputs::new(&dir, &kinds, &[&args.input], ctx)?;
    let progress = ctx.progress();
    relief_heightfield::Progress::begin(&progress, "resampling", 0);
    let grids = grids(&hf, layout.samples)?;
    let vertical = match ctx.height_range {
        Some((lo, hi)) => Vertical::new(lo, hi),
        None => {
            let (lo, hi) = grids.corners.min_max().unwrap_or((0.0, 0.0));
            Vertical::new(f64::from(lo), f64::from(hi))
        }
    };
    if let (Some((lo, hi)), Some((a, b))) = (ctx.height_range, grids.corners.min_max())
        && (f64::from(a) < lo || f64::from(b) > hi)
    {
        ctx.note(format!(
            "warning: the heights {a:.2}..{b:.2} m reach past --height-range {lo},{hi}: \
             they are clipped to it"
        ));
    }
    let sheet = plan.write(&staged, &grids, vertical, &hf, &args.input, ctx, &progress)?;
    staged.write_json(&format!("{}.json", plan.stem), &sheet, true)?;
    let text = write::sheet_text(&sheet);
    relief_io::write_bytes_atomic(&staged.path(&format!("{}.txt", plan.stem)), text.as_bytes())
        .map_err(|e| anyhow::anyhow!("cannot write {}.txt: {e}", plan.stem))?;
    staged.commit()?;
    drop(progress);
    if args.json {
        crate::staging::print(&crate::staging::json_text(&sheet)?)
    } else {
        crate::staging::print(&text)
    }
}
