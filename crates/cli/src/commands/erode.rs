//! `relief erode DEM -o OUT [--preset P] [overrides] [--uplift RATE|RASTER] [--erosion OUT]
//! [--deposition OUT]`: landscape evolution with relief-landscape's erode job
//! ([`ErodeSettings`]: a preset resolved into stream-power incision with uplift and hillslope
//! diffusion, hydraulic erosion and thermal relaxation, each field of the job a flag that
//! overrides the preset). Writes the eroded terrain (any raster format) and optionally the net
//! erosion and deposition depths (uplift left out), all together or nothing, with the input's
//! georeference. Before the run a pilot times every process on a crop and a run estimated over
//! `--max-time` is refused; a run that still overruns it is stopped. Progress (with an ETA on a
//! terminal and in logs) through `Ctx::progress`.
//!
//! ```text
//! relief erode dem.tif -o eroded.tif --preset badlands --erosion e.tif --deposition d.tif
//! relief erode dem.tif -o eroded.tif --years 1e5 --uplift 1e-4 --thermal-iterations 0
//! ```

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use relief_heightfield::{Heightfield, ParamError, Progress};
use relief_landscape::erode::job::{ErodeFigures, ErodeSettings, Preset};

use crate::args::{LibEnum, flag_error};
use crate::ctx::Ctx;
use crate::outputs::OutKind;

/// `--uplift`: a constant rate in m/yr, or a raster of rates on the DEM's grid.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum UpliftArg {
    /// m/yr away from the base levels.
    Rate(f64),
    /// A raster of m/yr per cell.
    Raster(PathBuf),
}

/// An existing file is a raster; otherwise a number is a rate; anything else a raster path
/// (whose read then fails naming it).
fn parse_uplift(s: &str) -> std::result::Result<UpliftArg, String> {
    if Path::new(s).exists() {
        return Ok(UpliftArg::Raster(PathBuf::from(s)));
    }
    match s.trim().parse::<f64>() {
        Ok(v) => Ok(UpliftArg::Rate(v)),
        Err(_) => Ok(UpliftArg::Raster(PathBuf::from(s))),
    }
}

/// Arguments of `relief erode`: [`ErodeSettings`] field by field (`None`: the preset's value).
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input DEM (format detected from its content); voids are base levels (flow leaves there).
    pub(crate) input: PathBuf,
    /// The eroded terrain (.tif, .exr, .npy, .png, .r16, .r32, ...).
    #[arg(short = 'o', long = "output", value_name = "OUT")]
    pub(crate) output: PathBuf,
    /// The landscape type to start from: gentle (soil-mantled hills), mountain (rivers
    /// incised from 1 km^2 channel heads, V-shaped valleys, scree), badlands (soft rock, dense
    /// gullies) or desert (flash floods, fans, long talus aprons). The flags below override
    /// its values.
    #[arg(long, value_name = "PRESET", default_value_t = LibEnum(ErodeSettings::default().preset))]
    pub(crate) preset: LibEnum<Preset>,
    /// Stream-power duration in years (0 skips stream power; default: the preset's).
    #[arg(long, value_name = "YR", allow_hyphen_values = true)]
    pub(crate) years: Option<f64>,
    /// Stream-power time step in years (default: the preset's).
    #[arg(long, value_name = "YR", allow_hyphen_values = true)]
    pub(crate) dt: Option<f64>,
    /// Rock uplift: a rate in m/yr away from the edges and voids, or a raster of rates on the
    /// DEM's grid (an existing file is read as a raster; default: the preset's rate).
    #[arg(long, value_name = "RATE|RASTER", value_parser = parse_uplift, allow_hyphen_values = true)]
    pub(crate) uplift: Option<UpliftArg>,
    /// With a `--uplift RASTER`: read it as a painted map in any units (an 8-bit PNG, say),
    /// scaled so that its highest value is this rate in m/yr and 0 stays 0.
    #[arg(long, value_name = "RATE", allow_hyphen_values = true)]
    pub(crate) uplift_max: Option<f64>,
    /// Erodibility K of the stream-power law (m^(1-2m)/yr; default: the preset's).
    #[arg(long, value_name = "K", allow_hyphen_values = true)]
    pub(crate) k: Option<f64>,
    /// Drainage-area exponent m (default: the preset's).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub(crate) m: Option<f64>,
    /// Slope exponent n (default: the preset's).
    #[arg(long, value_name = "N", allow_hyphen_values = true)]
    pub(crate) n: Option<f64>,
    /// Hillslope diffusivity in m^2/yr (default: the preset's).
    #[arg(long, value_name = "M2_PER_YR", allow_hyphen_values = true)]
    pub(crate) diffusion: Option<f64>,
    /// Channel-head drainage area in m^2: cells draining less are hillslopes, shaped by
    /// diffusion and not incised by stream power; 0 incises every cell (default: the preset's,
    /// 1 km^2 for mountain, 1000 m^2 for badlands).
    #[arg(long, value_name = "M2")]
    pub(crate) channel_area: Option<f64>,
    /// Gradient in degrees of the alluvial fans laid down below the valleys' mouths from the
    /// sediment eroded upstream; 0 builds none (default: the preset's: 2 gentle, 4 mountain,
    /// 5 badlands, 3 desert).
    #[arg(long, value_name = "DEG", allow_hyphen_values = true)]
    pub(crate) fan_gradient: Option<f64>,
    /// Hydraulic erosion iterations (0 skips it; default: the preset's on cells up to 10 m,
    /// fewer in proportion on coarser cells).
    #[arg(long, value_name = "N")]
    pub(crate) hydraulic_iterations: Option<u32>,
    /// Rain per hydraulic iteration in metres of water (default: the preset's).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub(crate) rain: Option<f64>,
    /// Sediment capacity of the hydraulic model (default: the preset's).
    #[arg(long, value_name = "C", allow_hyphen_values = true)]
    pub(crate) capacity: Option<f64>,
    /// Angle of repose of the thermal relaxation in degrees (default: the preset's).
    #[arg(long, value_name = "DEG", allow_hyphen_values = true)]
    pub(crate) talus_angle: Option<f64>,
    /// Thermal relaxation iterations (0 skips it; default: the preset's).
    #[arg(long, value_name = "N")]
    pub(crate) thermal_iterations: Option<u32>,
    /// Bedrock depth in metres each cell can weather into loose material for the thermal
    /// relaxation (cliffs keep their faces and shed talus); negative: the whole surface is
    /// loose, cliffs are levelled (default: the preset's).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub(crate) weathering: Option<f64>,
    /// Fill the closed depressions the erosion dug or dammed (the input's own stay, no
    /// deeper), so the result drains like the input: true or false (default: the preset's).
    #[arg(long, value_name = "BOOL", action = clap::ArgAction::Set)]
    pub(crate) fill_pits: Option<bool>,
    /// Seed of the random rain.
    #[arg(long, default_value_t = ErodeSettings::default().seed)]
    pub(crate) seed: u64,
    /// Also write the net erosion depth in metres (>= 0, uplift left out) as a raster.
    #[arg(long, value_name = "OUT")]
    pub(crate) erosion: Option<PathBuf>,
    /// Also write the net deposition depth in metres (>= 0) as a raster.
    #[arg(long, value_name = "OUT")]
    pub(crate) deposition: Option<PathBuf>,
    /// Also write a PNG of what the run changed: the eroded terrain's hillshade, blue where it
    /// was lowered, orange where it was raised (fans, talus, filled hollows), the tint full at
    /// 30 m of change.
    #[arg(long, value_name = "OUT.png")]
    pub(crate) change_map: Option<PathBuf>,
    /// Print the settings and figures as JSON instead of text.
    #[arg(long)]
    pub(crate) json: bool,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// The flags as checked [`ErodeSettings`] (an error names the flag; a `--uplift RASTER` is
/// given to the run, not to the settings).
pub(crate) fn settings(args: &Args) -> Result<ErodeSettings> {
    // Field by field onto the preset's settings.
    let mut s = ErodeSettings::preset(args.preset.0);
    s.years = args.years;
    s.dt = args.dt;
    s.uplift = match &args.uplift {
        Some(UpliftArg::Rate(r)) => Some(*r),
        _ => None,
    };
    s.k = args.k;
    s.m = args.m;
    s.n = args.n;
    s.diffusion = args.diffusion;
    s.channel_area = args.channel_area;
    s.fan_gradient = args.fan_gradient;
    s.hydraulic_iterations = args.hydraulic_iterations;
    s.rain = args.rain;
    s.capacity = args.capacity;
    s.talus_angle = args.talus_angle;
    s.thermal_iterations = args.thermal_iterations;
    s.weathering = args.weathering;
    s.fill_pits = args.fill_pits;
    s.seed = args.seed;
    s.check().map_err(|e| flag_error(erode_flag(&s, e)))?;
    if args.uplift_max.is_some() && !matches!(args.uplift, Some(UpliftArg::Raster(_))) {
        anyhow::bail!("--uplift-max scales a painted --uplift RASTER; give the raster too");
    }
    Ok(s)
}

/// A [`ErodeSettings::check`] error under the flag's name: the processes check an override
/// under their own field names (`rain_m`, `talus_angle_deg`, `iterations`).
fn erode_flag(s: &ErodeSettings, mut e: ParamError) -> ParamError {
    let plan = s.plan();
    e.name = match e.name {
        "rain_m" => "rain",
        "channel_area_m2" => "channel_area",
        "gradient_deg" => "fan_gradient",
        "talus_angle_deg" => "talus_angle",
        "weathering_m" => "weathering",
        "iterations" if plan.hydraulic.is_some_and(|h| h.check().is_err()) => {
            "hydraulic_iterations"
        }
        "iterations" => "thermal_iterations",
        other => other,
    };
    e
}

/// Working bytes per cell beside the job's ([`ErodeSettings::BYTES_PER_CELL`]): the uplift
/// raster and the encoding of one output.
const CLI_BYTES_PER_CELL: u64 = 12;

/// What `--json` prints.
#[derive(Debug, serde::Serialize)]
struct Report {
    #[serde(flatten)]
    input: super::InputGrid,
    settings: ErodeSettings,
    uplift_raster: Option<String>,
    seconds: f64,
    figures: ErodeFigures,
}

/// Reads the DEM, estimates, erodes, writes the outputs.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let settings = settings(&args)?;
    let uplift_path = match &args.uplift {
        Some(UpliftArg::Raster(p)) => Some(p.as_path()),
        _ => None,
    };
    let mut outputs = vec![(args.output.as_path(), OutKind::Raster)];
    outputs.extend(args.erosion.as_deref().map(|p| (p, OutKind::Raster)));
    outputs.extend(args.deposition.as_deref().map(|p| (p, OutKind::Raster)));
    outputs.extend(args.change_map.as_deref().map(|p| (p, OutKind::Png)));
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(uplift_path);
    ctx.check_outputs(&inputs, &outputs)?;
    let staged = crate::staging::Outputs::of(&outputs, None)?;
    let job = super::JobCells {
        command: "erode",
        what: "the erosion model",
        bytes_per_cell: ErodeSettings::BYTES_PER_CELL + CLI_BYTES_PER_CELL,
        output_bytes_per_cell: 4 * outputs.len() as u64,
    };
    let dem = super::read_raster_for(&args.input, &args.read, ctx, Some(job))?.heightfield;
    let uplift = match uplift_path {
        Some(p) => Some(read_uplift(p, &dem, args.uplift_max, ctx)?),
        None => None,
    };
    let est = settings
        .estimate_seconds(&dem)
        .context("cannot time the pilot run")?;
    ctx.check_time(
        "the erosion",
        est,
        "from every process on a crop of at most 256 x 256 cells for a few steps",
        "fewer --years, --hydraulic-iterations or --thermal-iterations, or a smaller input",
    )?;
    let progress = ctx.progress();
    let start = std::time::Instant::now();
    let max = ctx.max_time.0;
    let stop = || max.is_some_and(|m| start.elapsed().as_secs_f64() > m);
    let out = match settings.run(&dem, uplift.as_ref(), &progress, &stop) {
        Err(relief_landscape::LandscapeError::Stopped(what)) => anyhow::bail!(
            "the erosion ran past {} ({what} stopped after {}; the pilot estimated {}): \
             nothing was written",
            ctx.max_time,
            crate::budget::human_secs(start.elapsed().as_secs_f64()),
            crate::budget::human_secs(est)
        ),
        r => r.with_context(|| format!("cannot erode {}", args.input.display()))?,
    };
    let seconds = start.elapsed().as_secs_f64();
    progress.begin("writing", 0);
    ctx.write_raster(&staged.path(&args.output), &out.terrain)?;
    if let Some(p) = &args.erosion {
        ctx.write_raster(&staged.path(p), &out.erosion)?;
    }
    if let Some(p) = &args.deposition {
        ctx.write_raster(&staged.path(p), &out.deposition)?;
    }
    if let Some(p) = &args.change_map {
        let (w, h, rgb) = relief_pipeline::change::change_map(&out)?;
        staged.write_png(p, w, h, &rgb)?;
    }
    crate::budget::commit_in_time("erode", progress, || staged.commit())?;
    let report = Report {
        input: super::InputGrid::of(&args.input, &dem),
        settings,
        uplift_raster: uplift_path.map(|p| p.display().to_string()),
        seconds,
        figures: out.figures,
    };
    let text = if args.json {
        crate::staging::json_text(&report)?
    } else {
        let f = &report.figures;
        format!(
            "file:       {}\nsize:       {} x {}\npreset:     {}\nprocesses:  {}\neroded:     \
             {:.3e} m3 (deepest {:.2} m)\ndeposited:  {:.3e} m3 (highest {:.2} m)\ntime:       \
             {}\nwrote:      {}\n",
            report.input.file,
            report.input.width,
            report.input.height,
            LibEnum(report.settings.preset),
            processes(f),
            f.eroded_m3,
            f.max_erosion_m,
            f.deposited_m3,
            f.max_deposition_m,
            crate::budget::human_secs(seconds),
            [
                Some(&args.output),
                args.erosion.as_ref(),
                args.deposition.as_ref(),
                args.change_map.as_ref()
            ]
            .into_iter()
            .flatten()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
        )
    };
    crate::staging::print(&text)
}

/// The processes that ran, for the summary.
fn processes(f: &ErodeFigures) -> String {
    let mut v = Vec::new();
    if let Some(sp) = f.plan.stream_power {
        v.push(format!("stream power {} yr", sp.years));
    }
    if let Some(h) = f.plan.hydraulic {
        v.push(format!("hydraulic x{}", h.iterations));
    }
    if let Some(fans) = f.fans {
        v.push(format!(
            "{} fans ({:.3e} m3, up to {:.1} m thick)",
            fans.fans, fans.volume_m3, fans.max_thickness_m
        ));
    }
    if let Some(t) = f.plan.thermal {
        v.push(format!("thermal x{}", t.iterations));
    }
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// Reads a `--uplift` raster, which must be on the DEM's grid.
fn read_uplift(path: &Path, dem: &Heightfield, max: Option<f64>, ctx: &Ctx) -> Result<Heightfield> {
    let u = super::read_raster(path, &super::ReadArgs::default(), ctx)
        .with_context(|| format!("--uplift {}: not a readable raster", path.display()))?
        .heightfield;
    if (u.width(), u.height()) != (dem.width(), dem.height()) {
        anyhow::bail!(
            "--uplift {} is {} x {}, the DEM {} x {}: they must match",
            path.display(),
            u.width(),
            u.height(),
            dem.width(),
            dem.height()
        );
    }
    let Some(rate) = max else { return Ok(u) };
    if !(rate.is_finite() && rate.abs() <= 0.1) {
        anyhow::bail!("invalid --uplift-max {rate}: must be a rate in [-0.1, 0.1] m/yr");
    }
    let top = u
        .as_slice()
        .iter()
        .filter(|v| v.is_finite())
        .fold(0.0f32, |m, &v| m.max(v.abs()));
    if top == 0.0 {
        anyhow::bail!(
            "--uplift {}: the painted map is 0 everywhere",
            path.display()
        );
    }
    Ok(u.map(|v| (v as f64 / top as f64 * rate) as f32))
}
