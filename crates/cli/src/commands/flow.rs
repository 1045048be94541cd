//! `relief flow DEM -o OUT_DIR`: drainage analysis of a DEM with relief-landscape's flow job
//! ([`FlowSettings`]: depressions filled or breached, D8 or MFD drainage area, channels from a
//! drainage area, Strahler order, watersheds, HAND). Writes into `OUT_DIR`, all together or
//! nothing ([`crate::folder`]): `filled.tif` (the conditioned DEM), `direction.tif` (ESRI
//! codes), `area.tif` (m^2), `strahler.tif`, `watersheds.tif`, `hand.tif`, `channels.geojson`,
//! `channels.png` (the network in blue over the hillshade, wider by order) and `flow.json`
//! (the settings and figures, which `--json` prints). GeoTIFFs keep the input's georeference.
//!
//! ```text
//! relief flow grandcanyon.tif -o gc_flow
//! relief flow dem.tif -o out --depressions breach --channel-area 2e5 --json
//! ```

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use relief_heightfield::{Heightfield, Progress};
use relief_landscape::flow::job::{FlowFigures, FlowOutput, FlowSettings};
use relief_landscape::flow::{Depressions, Directions};
use serde::Serialize;

use crate::args::{LibEnum, flag_error};
use crate::ctx::Ctx;
use crate::outputs::OutKind;

/// Arguments of `relief flow`: one flag per [`FlowSettings`] field ([`FlowArgs`]).
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input DEM (format detected from its content); voids are flow off the map.
    pub(crate) input: PathBuf,
    /// Output folder (created when absent; its parent must exist): filled.tif, direction.tif,
    /// area.tif, strahler.tif, watersheds.tif, hand.tif, channels.geojson, channels.png,
    /// flow.json.
    #[arg(short = 'o', long = "out", value_name = "OUT_DIR")]
    pub(crate) out: PathBuf,
    #[command(flatten)]
    pub(crate) flow: FlowArgs,
    /// Print the figures (flow.json) as JSON instead of text.
    #[arg(long)]
    pub(crate) json: bool,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// The flags of [`FlowSettings`], one per field, defaults from `FlowSettings::default()`
/// (shared by `relief flow` and `relief masks`, whose drainage masks route the same way).
#[derive(Debug, Clone, clap::Args)]
pub(crate) struct FlowArgs {
    /// Closed depressions: fill (priority-flood to the spill level, then drainage across the
    /// flats), epsilon (filled with a rising epsilon step), breach (least-cost channels within
    /// --breach-depth and --breach-length, the rest filled) or none (pits stay sinks).
    #[arg(long, value_name = "MODE", default_value_t = LibEnum(FlowSettings::default().depressions))]
    pub(crate) depressions: LibEnum<Depressions>,
    /// Deepest breach cut in metres (with --depressions breach).
    #[arg(long, value_name = "M", allow_hyphen_values = true, default_value_t = FlowSettings::default().breach_depth)]
    pub(crate) breach_depth: f64,
    /// Longest breach channel in metres (with --depressions breach).
    #[arg(long, value_name = "M", allow_hyphen_values = true, default_value_t = FlowSettings::default().breach_length)]
    pub(crate) breach_length: f64,
    /// Flow directions of the drainage area: d8 (steepest neighbour) or mfd (split among the
    /// lower neighbours; channels, watersheds and HAND follow D8 either way).
    #[arg(long, value_name = "D", default_value_t = LibEnum(FlowSettings::default().directions))]
    pub(crate) directions: LibEnum<Directions>,
    /// Exponent of the multiple-flow-direction split (with --directions mfd).
    #[arg(long, value_name = "P", allow_hyphen_values = true, default_value_t = FlowSettings::default().mfd_exponent)]
    pub(crate) mfd_exponent: f64,
    /// Drainage area in m^2 from which a cell is a channel (Strahler order, channels.geojson
    /// and HAND start there).
    #[arg(long, value_name = "M2", allow_hyphen_values = true, default_value_t = FlowSettings::default().channel_area)]
    pub(crate) channel_area: f64,
}

impl FlowArgs {
    /// The flags as [`FlowSettings`] (unchecked).
    pub(crate) fn settings(&self) -> FlowSettings {
        FlowSettings {
            depressions: self.depressions.0,
            breach_depth: self.breach_depth,
            breach_length: self.breach_length,
            directions: self.directions.0,
            mfd_exponent: self.mfd_exponent,
            channel_area: self.channel_area,
        }
    }
}

/// The files `relief flow` writes into its folder.
pub(crate) const FILES: [(&str, OutKind); 9] = [
    ("filled.tif", OutKind::Raster),
    ("direction.tif", OutKind::Raster),
    ("area.tif", OutKind::Raster),
    ("strahler.tif", OutKind::Raster),
    ("watersheds.tif", OutKind::Raster),
    ("hand.tif", OutKind::Raster),
    ("channels.geojson", OutKind::Json),
    ("channels.png", OutKind::Png),
    ("flow.json", OutKind::Json),
];

/// Bytes per cell of `relief flow` beside the job's own ([`FlowSettings::BYTES_PER_CELL`]):
/// the preview (RGB, coverage and order of the overlay: 8) and the encoding of one GeoTIFF (8).
const CLI_BYTES_PER_CELL: u64 = 16;

/// The job's memory per cell, checked from the input's header before it is decoded.
pub(crate) fn job_cells() -> super::JobCells<'static> {
    super::JobCells {
        command: "flow",
        what: "the flow rasters",
        bytes_per_cell: FlowSettings::BYTES_PER_CELL + CLI_BYTES_PER_CELL,
        // Six f32 rasters and the RGB preview (the GeoJSON is a fraction of it).
        output_bytes_per_cell: 6 * 4 + 3,
    }
}

/// The flags as checked [`FlowSettings`] (an error names the flag).
pub(crate) fn settings(args: &Args) -> Result<FlowSettings> {
    let s = args.flow.settings();
    s.check().map_err(flag_error)?;
    Ok(s)
}

/// `flow.json` and what `--json` prints: the input, the settings and the figures.
#[derive(Debug, Serialize)]
pub(crate) struct Report {
    #[serde(flatten)]
    pub(crate) input: super::InputGrid,
    pub(crate) cell_size: (f64, f64),
    pub(crate) crs: Option<String>,
    pub(crate) settings: FlowSettings,
    pub(crate) figures: FlowFigures,
    pub(crate) outputs: Vec<&'static str>,
}

fn text(r: &Report, out: &std::path::Path) -> String {
    let f = &r.figures;
    let mut s = String::new();
    let _ = writeln!(s, "file:        {}", r.input.file);
    let _ = writeln!(
        s,
        "size:        {} x {} (cell {:.3} x {:.3} m), {} voids",
        r.input.width, r.input.height, r.cell_size.0, r.cell_size.1, f.voids
    );
    let _ = writeln!(
        s,
        "conditioned: {} cells raised (deepest {:.2} m), {} lowered (deepest {:.2} m), {} sinks",
        f.raised_cells, f.max_fill_m, f.lowered_cells, f.max_cut_m, f.sinks
    );
    let _ = writeln!(
        s,
        "channels:    {:.2} km in {} reaches, highest Strahler order {}",
        f.channel_km, f.reaches, f.max_order
    );
    let _ = writeln!(
        s,
        "basins:      {} outlets, largest {:.3} km2",
        f.outlets, f.largest_basin_km2
    );
    let _ = writeln!(
        s,
        "wrote:       {}/{{{}}}",
        out.display(),
        r.outputs.join(",")
    );
    s
}

/// Reads the DEM, runs the flow job and writes the folder.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let settings = settings(&args)?;
    let staged = crate::folder::FolderOutputs::new(&args.out, &FILES, &[&args.input], ctx)?;
    let dem = super::read_raster_for(&args.input, &args.read, ctx, Some(job_cells()))?.heightfield;
    let progress = ctx.progress();
    if let Some((est, how)) =
        crate::budget::crop_pilot_seconds((dem.width(), dem.height()), |x, y, w, h| {
            let crop = dem.crop(x, y, w, h)?;
            // A crop of voids only has nothing to route: the pilot then times nothing.
            match settings.run(&crop, &relief_heightfield::NoProgress) {
                Ok(_) | Err(relief_landscape::LandscapeError::InvalidInput(_)) => Ok(()),
                Err(e) => Err(e.into()),
            }
        })?
    {
        ctx.check_time("the flow routing", est, &how, "a smaller input (crop it)")?;
    }
    let out = settings
        .run(&dem, &progress)
        .with_context(|| format!("cannot route {}", args.input.display()))?;
    progress.begin("writing", 0);
    write(&staged, &dem, &out, ctx)?;
    let report = Report {
        input: super::InputGrid::of(&args.input, &dem),
        cell_size: dem.cell_size(),
        crs: dem.georef().and_then(|g| g.crs.clone()),
        settings,
        figures: out.figures,
        outputs: FILES.iter().map(|(n, _)| *n).collect(),
    };
    staged.write_json("flow.json", &report, true)?;
    crate::budget::commit_in_time("flow", progress, || staged.commit())?;
    let text = if args.json {
        crate::staging::json_text(&report)?
    } else {
        text(&report, &args.out)
    };
    crate::staging::print(&text)
}

/// Writes the rasters, the network and its preview into the staged folder.
fn write(
    staged: &crate::folder::FolderOutputs,
    dem: &Heightfield,
    out: &FlowOutput,
    ctx: &Ctx,
) -> Result<()> {
    for (name, hf) in [
        ("filled.tif", &out.conditioned),
        ("direction.tif", &out.direction),
        ("area.tif", &out.area),
        ("strahler.tif", &out.strahler),
        ("watersheds.tif", &out.watersheds),
        ("hand.tif", &out.hand),
    ] {
        ctx.write_raster(&staged.path(name), hf)?;
    }
    staged.write_json("channels.geojson", &out.channels, false)?;
    let rgb = relief_pipeline::channels::channel_map(dem, &out.direction, &out.strahler)?;
    staged.write_png("channels.png", dem.width(), dem.height(), &rgb)
}
