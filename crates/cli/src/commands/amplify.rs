//! `relief amplify IN OUT --exemplar EX --factor F`: adds detail to a coarse terrain with the
//! details of a high-resolution exemplar (guerin2016 section 5.3, x4 per step). OUT is a raster
//! (any format relief-io writes, optionally one `--window` of it) or a `.sct` model that can be
//! rasterised later at any resolution.
//! The pre-flight estimate and the writing of the model are shared with `synthesize`,
//! `fit-procedural` and `tile plan` (`crate::sparse_model`).

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use relief_dictionary_learning::{
    AmplifySettings, LastStep, amplify_with_figures, prepare_last_step,
};
use relief_heightfield::Heightfield;
use relief_sparse_core::Sct;

use crate::args::LibEnum;
use crate::ctx::Ctx;
use crate::sparse_model::{
    OutputPlan, check_output_path, dictionary_choice, preflight, write_model,
};

/// Arguments of `relief amplify`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Coarse input raster (no voids: fill them first with `relief convert --fill-voids`).
    pub(crate) input: PathBuf,
    /// Output: a raster (.tif, .png, .exr, .npy, .r16, .r32) or a `.sct` model.
    pub(crate) output: PathBuf,
    #[command(flatten)]
    pub(crate) exemplar: crate::sparse_model::ExemplarArg,
    /// Amplification factor per axis: a power of 4 (4, 16, 64, 256, ...; 4 per step).
    #[arg(long)]
    pub(crate) factor: usize,
    #[command(flatten)]
    pub(crate) seed: crate::sparse_model::SeedArg,
    /// Support radius R in cells of the input (its coarse pixels, figure 11): small follows
    /// the input, large imposes more of the exemplar.
    #[arg(long, default_value_t = AmplifySettings::default().radius)]
    pub(crate) radius: f64,
    /// Number of learned atoms N (constrained learning); 0 = the complete dictionary (every
    /// exemplar patch).
    #[arg(long, default_value_t = AmplifySettings::default().dictionary.n_atoms())]
    pub(crate) atoms: usize,
    /// Sparsity s of the coding (the paper uses 1).
    #[arg(long, default_value_t = AmplifySettings::default().sparsity)]
    pub(crate) sparsity: usize,
    /// Grid step S between primitive centres, in cells of the input (default: half the radius,
    /// the paper's grid; must be < radius * sqrt(2)). Larger is faster but shows the grid.
    #[arg(long)]
    pub(crate) step: Option<f64>,
    /// The paper's plain method (section 5.3), for comparison: no residual correction, no
    /// detail-energy normalisation and always the best-matching atom (less consistent with the
    /// input, a visible grid, details repeated along rows of primitives).
    #[arg(long)]
    pub(crate) paper: bool,
    /// Interpolation of the residual layer (not with --paper): lanczos3 (the default) keeps
    /// the input's finest relief at the same energy between its samples as on them; keys (the
    /// Keys cubic) keeps it on the samples and smooths it between them, a faint row-and-column
    /// pattern in the shaded relief.
    #[arg(long, value_name = "KERNEL", default_value_t = LibEnum(AmplifySettings::default().residual_kernel))]
    pub(crate) residual_kernel: LibEnum<relief_heightfield::Kernel>,
    /// With `--sparsity 1` and a complete dictionary of more than 4096 atoms (`--atoms 0`):
    /// clusters of the atom index searched per primitive; 0 = the exact search (about 15x
    /// slower at 65,536 atoms).
    #[arg(long, default_value_t = relief_sparse_core::DEFAULT_INDEX_PROBES)]
    pub(crate) index_probes: usize,
    #[command(flatten)]
    pub(crate) window: crate::sparse_model::WindowArg,
    /// Stream a GeoTIFF output band by band instead of rasterising it whole (automatic above
    /// 16 M cells): memory stays at two bands whatever the output size.
    #[arg(long)]
    pub(crate) stream: bool,
    #[command(flatten)]
    pub(crate) landform: crate::landform::LandformArg,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Number of x4 steps of a factor, or an error naming it.
pub(crate) fn steps_of_factor(factor: usize) -> Result<usize> {
    let mut f = factor;
    let mut steps = 0;
    while f > 1 && f.is_multiple_of(4) {
        f /= 4;
        steps += 1;
    }
    if f != 1 || steps == 0 || steps > 6 {
        bail!("invalid --factor {factor}: must be a power of 4 between 4 and 4096");
    }
    Ok(steps)
}

/// Reads, amplifies, writes.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    // Every argument is checked before any file is touched, so a typo fails fast.
    settings(&args)?;
    let window = args.window.window;
    check_output_path(&args.output, window)?;
    ctx.check_outputs(
        &[&args.input, &args.exemplar.exemplar],
        &[(&args.output, crate::outputs::OutKind::RasterOrSct)],
    )?;
    let plan = OutputPlan::of(&args.output, window, "--factor")
        .with_landform(args.landform.on(args.paper));
    let (sct, coarse) = build_keeping_input(&args, plan, ctx)?;
    let finish = args
        .landform
        .on(args.paper)
        .then_some(crate::sparse_model::Landform(&coarse));
    write_model(
        &sct,
        &args.output,
        window,
        args.stream,
        finish.as_ref(),
        ctx,
    )
}

/// The library settings of the arguments (checked).
pub(crate) fn settings(args: &Args) -> Result<AmplifySettings> {
    let steps = steps_of_factor(args.factor)?;
    let base = if args.paper {
        AmplifySettings::paper()
    } else {
        AmplifySettings::default()
    };
    let settings = AmplifySettings {
        radius: args.radius,
        step: args.step,
        steps,
        sparsity: args.sparsity,
        dictionary: dictionary_choice(args.atoms),
        seed: args.seed.seed,
        exemplar_cell_size: args.exemplar.exemplar_cell_size,
        index_probes: args.index_probes,
        residual_kernel: args.residual_kernel.0,
        ..base
    };
    settings.check().context("invalid amplification settings")?;
    Ok(settings)
}

/// Reads the input and the exemplar, checks them and the pre-flight estimate.
fn inputs(
    args: &Args,
    settings: &AmplifySettings,
    out: OutputPlan,
    ctx: &Ctx,
) -> Result<(Heightfield, Heightfield)> {
    let coarse = super::read_raster(&args.input, &args.read, ctx)?.heightfield;
    coarse
        .require_complete()
        .with_context(|| format!("cannot amplify {}", args.input.display()))?;
    let exemplar = args.exemplar.read(ctx)?;
    preflight(
        ctx,
        &format!("amplify x{}", args.factor),
        (coarse.width(), coarse.height()),
        (exemplar.width(), exemplar.height()),
        settings,
        out,
    )?;
    Ok((coarse, exemplar))
}

fn failed(args: &Args) -> String {
    format!(
        "cannot amplify {} x{} with {}",
        args.input.display(),
        args.factor,
        args.exemplar.exemplar.display()
    )
}

/// Reads the inputs, checks the pre-flight estimate for the output `out`, amplifies them into
/// a model; also returns the coarse input (for the landform pass).
fn build_keeping_input(args: &Args, out: OutputPlan, ctx: &Ctx) -> Result<(Sct, Heightfield)> {
    let settings = settings(args)?;
    let (coarse, exemplar) = inputs(args, &settings, out, ctx)?;
    let (sct, figures) = {
        let progress = ctx.progress();
        amplify_with_figures(&coarse, &exemplar, &settings, &progress)
            .with_context(|| failed(args))?
    };
    for step in &figures.steps {
        ctx.note(step.note.clone());
    }
    Ok((sct, coarse))
}

/// Every step but the last, and the last step's dictionary and input (`relief tile plan`:
/// the tasks compute the last step window by window). Also returns the georeference of the
/// amplified output.
pub(crate) fn prepare_last(
    args: &Args,
    out: OutputPlan,
    ctx: &Ctx,
) -> Result<(LastStep, Option<relief_heightfield::GeoRef>)> {
    let settings = settings(args)?;
    let (coarse, exemplar) = inputs(args, &settings, out, ctx)?;
    let (last, figures) = {
        let progress = ctx.progress();
        prepare_last_step(&coarse, &exemplar, &settings, &progress).with_context(|| failed(args))?
    };
    for step in &figures.steps {
        ctx.note(step.note.clone());
    }
    let f = 1.0 / 4f64.powi(settings.steps as i32);
    let georef = coarse.georef().map(|g| g.window(0.0, 0.0, f, f));
    Ok((last, georef))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors() {
        assert_eq!(steps_of_factor(4).unwrap(), 1);
        assert_eq!(steps_of_factor(16).unwrap(), 2);
        assert_eq!(steps_of_factor(256).unwrap(), 4);
        for bad in [0, 1, 2, 8, 12, 32, 4usize.pow(7)] {
            let e = steps_of_factor(bad).unwrap_err().to_string();
            assert!(e.contains("--factor"), "{e}");
        }
    }
}
