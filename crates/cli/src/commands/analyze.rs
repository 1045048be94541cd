//! `relief analyze IN`: the wavelet detail statistics of Perez et al. (relief-wavelet-lod):
//! per band (h, v, d) the variance of the detail coefficients at every level (equation (2)),
//! the fitted line `log2 Var = -j gamma + a` (equation (3)) and the implied fractal dimension
//! `3 - gamma / 2`; optionally the local fits of equation (4) summarised over the terrain
//! (`--local W`) and written as rasters (`--maps PREFIX`), JSON output (`--json`) and the
//! log-variance plot as a PNG (`--plot`).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use relief_heightfield::{Heightfield, Progress};
use relief_wavelet_lod::{
    AnalyzeFigures, AnalyzeSettings, Band, FitSettings, Wavelet, render_log_variance_plot,
};
use serde::Serialize;

use crate::ctx::Ctx;

/// Arguments of `relief analyze`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input raster (format detected from its content; must be void-free or use --fill-voids).
    pub(crate) input: PathBuf,
    /// Wavelet basis: haar, cdf53 (linear spline, default), cdf97, db4 (PyWavelets names too).
    #[arg(long, default_value = "cdf53")]
    pub(crate) wavelet: String,
    /// First level taking part in the fit of equation (3) (the paper uses 3).
    #[arg(long, default_value_t = relief_wavelet_lod::FitSettings::default().min_level)]
    pub(crate) min_level: u32,
    /// Also fit the local statistics (LSA, equation (4)) in a W x W window (odd) and summarise
    /// their maps (mean and 5/50/95th percentiles of gamma and of the fractal dimension).
    #[arg(long, value_name = "W")]
    pub(crate) local: Option<usize>,
    /// With --local: also write the local maps at input resolution (same cell size and
    /// georeference) as `PREFIX_gamma_{h,v,d}.tif`, `PREFIX_a_{h,v,d}.tif` and
    /// `PREFIX_dimension.tif` (fractal dimension, mean of the bands).
    #[arg(long, value_name = "PREFIX", requires = "local")]
    pub(crate) maps: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub(crate) json: bool,
    /// Write the log-variance plot (measured levels, fitted lines, synthesised levels) as PNG.
    #[arg(long, value_name = "OUT.png")]
    pub(crate) plot: Option<PathBuf>,
    /// Number of synthesised levels drawn on the plot (model values of equation (5)).
    #[arg(long, default_value_t = 2)]
    pub(crate) plot_levels: u32,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Everything `--json` prints: the input and the job's figures.
#[derive(Debug, Serialize)]
pub(crate) struct Report {
    #[serde(flatten)]
    input: super::InputGrid,
    cell_size: (f64, f64),
    #[serde(flatten)]
    figures: AnalyzeFigures,
}

fn text(r: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "file:        {}", r.input.file);
    let _ = writeln!(
        s,
        "size:        {} x {} (cell {:.3} x {:.3} m)",
        r.input.width, r.input.height, r.cell_size.0, r.cell_size.1
    );
    s + &r.figures.summary()
}

/// The file of one local map: `PREFIX_<suffix>.tif`.
fn map_path(prefix: &std::path::Path, suffix: &str) -> PathBuf {
    PathBuf::from(format!("{}_{suffix}.tif", prefix.display()))
}

/// Every file `--maps PREFIX` writes (checked before the analysis starts).
fn map_paths(prefix: &std::path::Path) -> Vec<PathBuf> {
    let mut v = Vec::new();
    for b in Band::ALL {
        v.push(map_path(prefix, &format!("gamma_{}", b.name())));
        v.push(map_path(prefix, &format!("a_{}", b.name())));
    }
    v.push(map_path(prefix, "dimension"));
    v
}

/// Prints the analysis on stdout; writes the plot when asked.
/// The library settings of the arguments (checked, with the plot's own flag).
pub(crate) fn settings(args: &Args) -> Result<AnalyzeSettings> {
    let settings = AnalyzeSettings {
        wavelet: Wavelet::from_name(&args.wavelet).context("invalid --wavelet")?,
        fit: FitSettings {
            min_level: args.min_level,
            ..Default::default()
        },
        local_window: args.local,
    };
    if let Err(e) = settings.check() {
        // Name the flag, not the library's field.
        let text = e.to_string().replace("parameter `window`", "--local");
        bail!("invalid analysis settings: {text}");
    }
    if args.plot_levels > 12 {
        bail!("invalid --plot-levels {}: must be <= 12", args.plot_levels);
    }
    Ok(settings)
}

pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let settings = settings(&args)?;
    let map_paths = match &args.maps {
        Some(prefix) => map_paths(prefix),
        None => Vec::new(),
    };
    let mut outputs: Vec<(&std::path::Path, crate::outputs::OutKind)> = map_paths
        .iter()
        .map(|p| (p.as_path(), crate::outputs::OutKind::Raster))
        .collect();
    outputs.extend(
        args.plot
            .as_deref()
            .map(|p| (p, crate::outputs::OutKind::Png)),
    );
    ctx.check_outputs(&[&args.input], &outputs)?;
    // The maps and the plot appear together or not at all.
    let staged = crate::staging::Outputs::of(&outputs, None)?;
    // `--fill-voids` (ReadArgs) fills voids on reading; without it they are an error.
    let hf = super::read_void_free(&args.input, &args.read, ctx)?;
    crate::commands::preflight::analyze(&hf, args.local.is_some(), ctx)?;
    let progress = ctx.progress();
    let result = settings
        .run(&hf, &progress)
        .with_context(|| format!("cannot analyse {}", args.input.display()))?;
    let mut written: Vec<PathBuf> = Vec::new();
    if let (Some(prefix), Some(maps)) = (&args.maps, &result.local) {
        progress.begin("writing the local maps", 0);
        let (cx, cy) = hf.cell_size();
        let mut write = |suffix: &str, data: Vec<f32>| -> Result<()> {
            let path = map_path(prefix, suffix);
            let map = Heightfield::new(hf.width(), hf.height(), data, cx, cy)?
                .with_georef(hf.georef().cloned());
            ctx.write_raster(&staged.path(&path), &map)?;
            written.push(path);
            Ok(())
        };
        for b in Band::ALL {
            write(
                &format!("gamma_{}", b.name()),
                maps.gamma[b.index()].data.clone(),
            )?;
            write(&format!("a_{}", b.name()), maps.a[b.index()].data.clone())?;
        }
        write("dimension", result.dimension_map().unwrap_or_default())?;
    }
    if let Some(plot) = &args.plot {
        progress.begin("plotting", 0);
        let (w, h) = (720, 440);
        let rgb = render_log_variance_plot(&result.figures.analysis, args.plot_levels, None, w, h);
        staged.write_png(plot, w, h, &rgb)?;
    }
    staged.commit()?;
    drop(progress);
    let report = Report {
        input: super::InputGrid::of(&args.input, &hf),
        cell_size: hf.cell_size(),
        figures: result.figures,
    };
    let out = if args.json {
        crate::staging::json_text(&report)?
    } else {
        text(&report)
    };
    crate::staging::print(&out)?;
    if let Some(plot) = &args.plot {
        written.push(plot.clone());
    }
    for p in &written {
        ctx.note(format!("wrote {}", p.display()));
    }
    Ok(())
}
