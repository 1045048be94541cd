//! `relief preview IN OUT.png [--azimuth D] [--altitude D] [--exaggeration F] [--no-sea]`:
//! shaded-relief preview (hillshade blended with an elevation colour ramp, sea colours by depth
//! below 0 m; voids drawn in a flat colour), square on the ground.

use std::path::PathBuf;

use anyhow::{Context, Result};
use relief_heightfield::Progress;

use crate::ctx::Ctx;

/// Arguments of `relief preview`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input raster (format detected from its content).
    pub(crate) input: PathBuf,
    /// Output PNG.
    pub(crate) output: PathBuf,
    /// Direction the light comes from, degrees clockwise from north.
    #[arg(long, default_value_t = 315.0, allow_hyphen_values = true)]
    pub(crate) azimuth: f32,
    /// Height of the light above the horizon, degrees in (0, 90].
    #[arg(long, default_value_t = 45.0)]
    pub(crate) altitude: f32,
    /// Vertical exaggeration of the hillshade (> 0).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) exaggeration: f32,
    /// Draw ground below 0 m with the land colours instead of sea colours by depth.
    #[arg(long)]
    pub(crate) no_sea: bool,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Reads the raster and writes its preview atomically.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let style = relief_io::PreviewStyle {
        azimuth_deg: args.azimuth,
        altitude_deg: args.altitude,
        exaggeration: args.exaggeration,
        sea: !args.no_sea,
    };
    if let Err(e) = style.check() {
        match e {
            relief_io::IoError::Param {
                name,
                value,
                reason,
            } => anyhow::bail!("invalid --{name} {value}: {reason}"),
            e => return Err(e.into()),
        }
    }
    ctx.check_outputs(
        &[&args.input],
        &[(&args.output, crate::outputs::OutKind::Png)],
    )?;
    let raster = super::read_raster(&args.input, &args.read, ctx)?;
    let progress = ctx.progress();
    progress.begin("rendering preview", 0);
    let hf = square_cells(raster.heightfield)?;
    relief_io::write_preview_png_with(&args.output, &hf, &style)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    drop(progress);
    ctx.note(format!("wrote {}", args.output.display()));
    Ok(())
}

/// Resamples a grid with non-square ground cells (geographic grids away from the equator:
/// N47E011's cells are 62.8 m x 92.6 m) so each preview pixel is square on the ground, stretching
/// the shorter side; grids already within 1 % of square are kept as they are.
fn square_cells(hf: relief_heightfield::Heightfield) -> Result<relief_heightfield::Heightfield> {
    let (cx, cy) = hf.cell_size();
    let ratio = cy / cx;
    if (ratio - 1.0).abs() <= 0.01 || hf.has_voids() {
        return Ok(hf);
    }
    let (w, h) = (hf.width() as f64, hf.height() as f64);
    let (nw, nh) = if ratio > 1.0 {
        (w, h * ratio)
    } else {
        (w / ratio, h)
    };
    hf.resample(nw.round().max(1.0) as usize, nh.round().max(1.0) as usize)
        .context("cannot resample the preview to square ground cells")
}
