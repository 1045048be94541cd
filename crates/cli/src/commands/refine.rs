//! `relief refine IN OUT`: adds levels of detail with the wavelet synthesis of Perez et al.
//! (relief-wavelet-lod): the spectral model (default, `--model spectral`: coloured coefficients
//! that continue the terrain's spectrum, area-consistent) or the paper's (`--model paper`), GSA
//! (one statistics fit per band) or LSA (local, from a `W x W` window), any basis, a seed, and
//! optionally only one window of the refined
//! terrain (`--window x,y,w,h`, in output cells; equal bit for bit to the same window of a
//! full run, and costing memory proportional to the window).
//!
//! Large GeoTIFF outputs (above 16 M cells, or any size with `--stream`) are synthesised in
//! bands of rows and streamed to the file through [`relief_io::GeoTiffStripWriter`], so the
//! refined terrain never exists whole in memory (a 16384^2 output needs two bands of 256 rows,
//! not 1 GiB); the values are bit-identical to the in-memory path. Other formats are written
//! from memory.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use relief_heightfield::Progress;
use relief_wavelet_lod::{FitSettings, Method, RefineSettings, Refiner, Wavelet};

use crate::ctx::Ctx;

/// Statistics scope of the synthesis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum MethodArg {
    /// Global scope approach (section 5.1): one (gamma, a) per band.
    Gsa,
    /// Local scope approach (section 5.2): one (gamma, a) per band and location.
    Lsa,
}

/// Synthesis model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum ModelArg {
    /// Coloured coefficients continuing the spectrum fitted on the finest levels,
    /// area-consistent (the default; a departure from the paper).
    Spectral,
    /// The paper as written: independent Gaussian coefficients, fit from --min-level up.
    Paper,
}

/// Arguments of `relief refine`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input raster (format detected from its content; must be void-free or use --fill-voids).
    pub(crate) input: PathBuf,
    /// Output raster (format from the extension: .tif, .exr, .png, .npy, .r16, .r32).
    pub(crate) output: PathBuf,
    /// Number of synthesised levels: the output is 2^N times larger per side (1..=12).
    #[arg(long, default_value_t = RefineSettings::default().extra_levels)]
    pub(crate) levels: u32,
    /// Synthesis model: spectral (default) or paper.
    #[arg(long, value_enum, default_value_t = ModelArg::Spectral)]
    pub(crate) model: ModelArg,
    /// Statistics scope: gsa (global) or lsa (local, the paper's recommendation).
    #[arg(long, value_enum, default_value_t = MethodArg::Lsa)]
    pub(crate) method: MethodArg,
    /// LSA statistics window side (odd; the paper uses 1, 3, 5 or 7 and recommends 3).
    #[arg(long = "stats-window", value_name = "W", default_value_t = RefineSettings::default().window)]
    pub(crate) window: usize,
    /// Wavelet basis: haar, cdf53 (linear spline), cdf97, db4 (PyWavelets names too). Default:
    /// cdf97 for the spectral model, cdf53 (the paper's) for --model paper.
    #[arg(long)]
    pub(crate) wavelet: Option<String>,
    /// Seed of the coefficient hash (same seed = same output bytes).
    #[arg(long, default_value_t = RefineSettings::default().seed)]
    pub(crate) seed: u64,
    /// First level taking part in the fit of equation (3) (the paper uses 3).
    #[arg(long, default_value_t = FitSettings::default().min_level)]
    pub(crate) min_level: u32,
    /// Write only this window `X,Y,W,H` of the refined terrain (output cells).
    #[arg(long = "window", value_name = "X,Y,W,H")]
    pub(crate) window_of: Option<relief_heightfield::Window>,
    /// Stream a GeoTIFF output band by band instead of synthesising it whole (automatic above
    /// 16 M cells): memory stays at two bands of rows whatever the output size.
    #[arg(long)]
    pub(crate) stream: bool,
    #[command(flatten)]
    pub(crate) landform: crate::landform::LandformArg,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

impl Args {
    /// True when the landform pass runs (`--landform`, default off for `--model paper`).
    pub(crate) fn landform_on(&self) -> bool {
        self.landform.on(self.model == ModelArg::Paper)
    }

    /// The library settings (checked by the library itself when the refiner is built).
    pub(crate) fn settings(&self) -> Result<RefineSettings> {
        if self.levels == 0 {
            bail!("invalid --levels 0: at least one level must be synthesised");
        }
        let base = match self.model {
            ModelArg::Spectral => RefineSettings::default(),
            ModelArg::Paper => RefineSettings::paper(),
        };
        let wavelet = match &self.wavelet {
            Some(w) => Some(Wavelet::from_name(w).context("invalid --wavelet")?),
            None => None,
        };
        let settings = RefineSettings {
            wavelet,
            method: match self.method {
                MethodArg::Gsa => Method::Gsa,
                MethodArg::Lsa => Method::Lsa,
            },
            window: self.window,
            extra_levels: self.levels,
            seed: self.seed,
            fit: FitSettings {
                min_level: self.min_level,
                ..Default::default()
            },
            ..base
        };
        settings.check().context("invalid refine settings")?;
        Ok(settings)
    }
}

/// Reads, analyses, synthesises (all or one window), writes atomically.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    // Every argument is checked before the input is read, so a typo fails fast.
    let settings = args.settings()?;
    let window = args.window_of.map(|w| w.as_tuple());
    ctx.check_outputs(
        &[&args.input],
        &[(&args.output, crate::outputs::OutKind::Raster)],
    )?;
    // `--fill-voids` (ReadArgs) fills voids on reading; without it they are an error.
    let hf = super::read_void_free(&args.input, &args.read, ctx)?;
    crate::commands::preflight::refine(&args, &settings, &hf, window, ctx)?;
    let progress = ctx.progress();
    progress.begin("wavelet analysis", 0);
    let refiner = Refiner::new(&hf, &settings)
        .with_context(|| format!("cannot analyse {}", args.input.display()))?;
    for n in refiner.notes() {
        ctx.note(format!("note: {n}"));
    }
    let (ow, oh) = refiner.output_size();
    let (x, y, w, h) = window.unwrap_or((0, 0, ow, oh));
    let streamed = relief_io::Format::from_extension(&args.output)
        == Some(relief_io::Format::GeoTiff)
        && (args.stream || w.saturating_mul(h) > crate::ctx::STREAM_CELLS);
    let landform = args.landform_on();
    let band = if streamed {
        if landform {
            crate::landform::skipped(ctx, "a streamed output");
        }
        if x.checked_add(w).is_none_or(|e| e > ow) || y.checked_add(h).is_none_or(|e| e > oh) {
            bail!("invalid --window {x},{y},{w},{h}: outside the refined grid ({ow} x {oh})");
        }
        drop(progress);
        let band = stream_geotiff(&refiner, &args.output, (x, y, w, h), window.is_none(), ctx)?;
        Some(band)
    } else {
        let out = match window {
            Some((x, y, w, h)) => {
                progress.begin("synthesising the window", 0);
                refiner.render_window(x, y, w, h).with_context(|| {
                    format!("invalid --window (the refined grid is {ow} x {oh})")
                })?
            }
            None => refiner.render(&progress).context("cannot synthesise")?,
        };
        drop(progress);
        let out = match (landform, window) {
            (true, None) => crate::landform::apply(out, &hf, ctx)?,
            (true, Some(_)) => {
                crate::landform::skipped(ctx, "a --window");
                out
            }
            (false, _) => out,
        };
        let progress = ctx.progress();
        progress.begin("writing", 0);
        ctx.write_raster(&args.output, &out)?;
        drop(progress);
        None
    };
    let f = refiner.figures();
    let fits = f.synthesis_fits;
    ctx.note(format!(
        "wrote {} ({w} x {h} of the {ow} x {oh} refined grid{}; {} model, {} {}, gamma h/v/d \
         {:.3}/{:.3}/{:.3})",
        args.output.display(),
        band.map(|b| format!(", streamed in bands of {b} rows"))
            .unwrap_or_default(),
        f.model.name(),
        match f.stats_window {
            None => "gsa".to_string(),
            Some(w) => format!("lsa {w}x{w}"),
        },
        f.wavelet,
        fits[0].gamma,
        fits[1].gamma,
        fits[2].gamma
    ));
    Ok(())
}

/// Synthesises the window `(x, y, w, h)` of the refined terrain (inside the grid; the whole
/// grid when `whole`) in bands of rows and streams them into a GeoTIFF at `path`: memory is one
/// band plus the analysis, never the whole output. The whole grid goes through
/// [`Refiner::render_strips`] (tiles of a band in parallel), a window through
/// [`Refiner::render_window_values`] band by band; both are bit-identical to the in-memory
/// [`Refiner::render`] / [`Refiner::render_window`]. Returns the band height. On any error the
/// writer is dropped unfinished, which removes its temporary: no partial file under `path`.
fn stream_geotiff(
    refiner: &Refiner,
    path: &Path,
    (x, y, w, h): (usize, usize, usize, usize),
    whole: bool,
    ctx: &Ctx,
) -> Result<usize> {
    // Cell size and georeference of the window: those of its first cell (the refiner shifts
    // the georeference of a window to its origin, exactly as for the in-memory output).
    let corner = refiner
        .render_window(x, y, 1, 1)
        .context("cannot synthesise")?;
    if !whole {
        return ctx.stream_bands(
            path,
            (w, h),
            corner.cell_size(),
            corner.georef(),
            "synthesising and writing the window",
            |r, rows| {
                refiner
                    .render_window_values(x, y + r, w, rows)
                    .context("cannot synthesise")
            },
        );
    }
    let mut out = ctx.row_stream(path, (w, h), corner.cell_size(), corner.georef())?;
    let band = out.band;
    let progress = ctx.progress();
    refiner.render_strips(band, &progress, |_, rows| out.write(rows))?;
    out.finish()?;
    Ok(band)
}
