//! `relief quilt OUT --exemplar E [--exemplar E2 ...] (--guide G | --guide-from DEM --blur S)
//! [--categories MAP] --size WxH --patch P --overlap O --seed S`: guided patch-based terrain
//! synthesis (Cruz et al. 2015, relief-patch-synth). The inputs shared with `relief validate`
//! live in [`SynthArgs`] (`synth_args.rs`).

use std::path::PathBuf;

use anyhow::{Context, Result};
use relief_heightfield::{Heightfield, Progress};
use relief_patch_synth::{Blend, CutMethod, QuiltJob, Settings, ValidateJob};

use crate::ctx::Ctx;
use crate::synth_args::SynthArgs;

/// Seam blending of `relief quilt`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum BlendArg {
    /// Poisson blending over the overlap.
    Poisson,
    /// Screened Poisson over the whole patch: a height offset between neighbouring patches
    /// decays over half a patch instead of the overlap (no steps on plateaus; about 5x slower).
    Screened,
    /// Smooth feathering across the seam.
    Feather,
    /// Plain cut and paste.
    None,
}

/// Seam search of `relief quilt`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum CutArg {
    /// Minimum-error boundary cut by dynamic programming.
    Dp,
    /// Greedy path (for comparison).
    Greedy,
}

/// Arguments of `relief quilt`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Output raster (.tif, .exr, .npy, .png, .r16, .r32).
    pub(crate) output: PathBuf,
    #[command(flatten)]
    pub(crate) synth: SynthArgs,
    /// Also write a PNG of the seam map (one colour per patch, seams white).
    #[arg(long, value_name = "PNG")]
    pub(crate) seam_map: Option<PathBuf>,
    /// Seam blending.
    #[arg(long, value_enum, default_value_t = BlendArg::Poisson)]
    pub(crate) blend: BlendArg,
    /// Seam search.
    #[arg(long, value_enum, default_value_t = CutArg::Dp)]
    pub(crate) cut: CutArg,
    /// Synthesize even when the input validation fails (it still runs and is reported).
    #[arg(long)]
    pub(crate) no_validate: bool,
    /// Landform pass (default on): the quilt is drained and its channels carried across the
    /// seams, keeping its own box averages over blocks of a quarter patch (the relief the
    /// patches and the guide give).
    #[command(flatten)]
    pub(crate) landform: crate::landform::LandformArg,
}

/// The flags as a [`QuiltJob`] (checked; library defaults where a flag is absent).
pub(crate) fn job(args: &Args) -> Result<QuiltJob> {
    let v = args.synth.job()?;
    let mut settings = v.settings;
    settings.enforce_validation = !args.no_validate;
    settings.cut = match args.cut {
        CutArg::Dp => CutMethod::DynamicProgramming,
        CutArg::Greedy => CutMethod::Greedy,
    };
    settings.blend = match args.blend {
        BlendArg::Poisson => Settings::default().blend,
        BlendArg::Screened => Blend::Screened {
            max_iterations: 300,
            decay: (settings.patch_size / 2) as f32,
        },
        BlendArg::Feather => Blend::Feather {
            radius: (settings.overlap as f32 / 4.0).max(1.0),
        },
        BlendArg::None => Blend::None,
    };
    let job = QuiltJob(ValidateJob { settings, ..v });
    job.check().context("invalid quilt settings")?;
    Ok(job)
}

/// The landform pass over a quilt, keeping its box averages over blocks of `k` cells, `k` the
/// largest divisor of both sides up to a quarter of `patch` (`None`, with a note, when only 1
/// divides them).
fn landform(hf: &Heightfield, patch: usize, ctx: &Ctx) -> Result<Option<Heightfield>> {
    let (w, h) = (hf.width(), hf.height());
    let Some(k) = (2..=(patch / 4).max(2))
        .rev()
        .find(|k| w.is_multiple_of(*k) && h.is_multiple_of(*k))
    else {
        crate::landform::skipped(ctx, "a quilt whose sides have no common divisor");
        return Ok(None);
    };
    let coarse = hf.downsample_box(k)?;
    Ok(Some(crate::landform::apply(hf.clone(), &coarse, ctx)?))
}

/// Reads the inputs, synthesizes and writes OUT (and the guide as used, the seam map)
/// atomically.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let mut outputs = vec![(args.output.as_path(), crate::outputs::OutKind::Raster)];
    outputs.extend(args.synth.output_paths());
    outputs.extend(
        args.seam_map
            .as_deref()
            .map(|p| (p, crate::outputs::OutKind::Png)),
    );
    ctx.check_outputs(&args.synth.input_paths(), &outputs)?;
    let job = job(&args)?;
    let inputs = args.synth.inputs(ctx)?;
    args.synth.preflight(&job.validate_job(), &inputs, ctx)?;
    let progress = ctx.progress();
    let out = job
        .run(inputs, &progress)
        .map_err(|e| args.synth.job_error(e))
        .context("synthesis failed")?;
    drop(progress);
    let finished = if args.landform.on(false) {
        landform(&out.synthesis.heightfield, job.settings.patch_size, ctx)?
    } else {
        None
    };
    let progress = ctx.progress();
    progress.begin("writing", 0);
    // The terrain, the guide as used and the seam map appear together or not at all.
    let staged = crate::staging::Outputs::of(&outputs, None)?;
    let hf = finished.as_ref().unwrap_or(&out.synthesis.heightfield);
    ctx.write_raster(&staged.path(&args.output), hf)?;
    if let (Some(g), Some(p)) = (&out.guide, &args.synth.guide_out) {
        ctx.write_raster(&staged.path(p), g)?;
    }
    if let Some(png) = &args.seam_map {
        let m = &out.synthesis.seam_map;
        staged.write_png(png, m.width, m.height, &m.rgb())?;
    }
    crate::budget::commit_in_time("quilt", progress, || staged.commit())?;
    let f = &out.figures;
    args.synth.note_figures(&f.prepare, ctx);
    if let Some(r) = out.report.as_ref().filter(|r| !r.ok) {
        ctx.note(format!(
            "input validation failed, synthesized anyway (--no-validate): {} of {} guide \
             blocks have fewer than {} candidates",
            r.failing.len(),
            r.blocks.len(),
            r.min_candidates
        ));
    }
    ctx.note(format!(
        "wrote {} ({} x {}): {} patches on a {} x {} grid, {:.0} candidates per block, {} \
         translations applied, {} rejected (|h| > {} m), {:.0} % distinct source patches",
        args.output.display(),
        hf.width(),
        hf.height(),
        f.patches,
        f.grid.0,
        f.grid.1,
        f.mean_candidates,
        f.translations_applied,
        f.translations_rejected,
        job.settings.lambda,
        100.0 * f.distinct_source_share
    ));
    Ok(())
}
