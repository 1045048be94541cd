//! `relief fit-procedural IN OUT.sct`: inverse procedural modelling (guerin2016 section 5.2):
//! the terrain's patches are coded on a dictionary of analytic noise atoms and the model is
//! written as a `.sct` whose atoms are functions (rebuild at any resolution). Prints the PSNR
//! of the fit on stdout.

use std::path::PathBuf;

use anyhow::{Context, Result};
use relief_dictionary_learning::{ProceduralSettings, fit_procedural};

use crate::ctx::Ctx;
use crate::sparse_model::{check_output_path, is_sct, write_model};

/// Arguments of `relief fit-procedural`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Terrain to fit (no voids).
    pub(crate) input: PathBuf,
    /// Output model (`.sct`; a raster extension writes the fitted terrain instead).
    pub(crate) output: PathBuf,
    /// Atom family: `ridged-field` (default: windows of one ridged multifractal field at
    /// terrain scale, 4-8 dB above the others on real DEMs), `perlin-field` (windows of one fBm
    /// field), or the paper's independent random atoms: `ridged` (sums of ridged noise,
    /// figure 4), `perlin` (fBm), `ridged-multifractal`.
    #[arg(long, default_value = "ridged-field")]
    pub(crate) family: String,
    /// Size of the analytic dictionary (random atom parameters).
    #[arg(long, default_value_t = 2048)]
    pub(crate) candidates: usize,
    /// Keep only N atoms chosen by constrained learning (problem (2)); 0 = keep all.
    #[arg(long, default_value_t = 0)]
    pub(crate) learned: usize,
    /// Patch side a in pixels.
    #[arg(long, default_value_t = 10)]
    pub(crate) patch_size: usize,
    /// Sparsity s.
    #[arg(long, default_value_t = 1)]
    pub(crate) sparsity: usize,
    /// Seed of the atom parameters.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Reads, fits, prints the PSNR, writes.
/// The library settings of the arguments (checked).
pub(crate) fn settings(args: &Args) -> Result<ProceduralSettings> {
    let settings = ProceduralSettings {
        family: crate::args::family(&args.family)?,
        n_candidates: args.candidates,
        learned_atoms: (args.learned > 0).then_some(args.learned),
        patch_size: args.patch_size,
        sparsity: args.sparsity,
        seed: args.seed,
        ..Default::default()
    };
    settings
        .check()
        .context("invalid fit-procedural settings")?;
    Ok(settings)
}

pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let settings = settings(&args)?;
    check_output_path(&args.output, None)?;
    ctx.check_outputs(
        &[&args.input],
        &[(&args.output, crate::outputs::OutKind::RasterOrSct)],
    )?;
    let hf = super::read_raster(&args.input, &args.read, ctx)?.heightfield;
    // Pre-flight: the patches of the input, the discretised candidate atoms and
    // their Gram matrix.
    {
        use crate::memory::part;
        let a = args.patch_size as f64;
        let step = (a / 2.0).max(1.0);
        let patches = (hf.width() as f64 / step).ceil() * (hf.height() as f64 / step).ceil();
        let k = args.candidates as f64;
        ctx.check_memory(
            "fit-procedural",
            &[&[
                part(
                    format!("the {} patches of the input", patches as u64),
                    patches * a * a * 4.0 * 4.0 + hf.len() as f64 * 16.0,
                    "a smaller input or --patch-size",
                ),
                part(
                    format!("the {} candidate atoms", k as u64),
                    k * a * a * 8.0 + k * k * 8.0,
                    "fewer --candidates",
                ),
            ]],
        )?;
    }
    let fit = {
        let progress = ctx.progress();
        fit_procedural(&hf, &settings, &progress)
            .with_context(|| format!("cannot fit {}", args.input.display()))?
    };
    write_model(&fit.sct, &args.output, None, false, None, ctx)?;
    let mut stdout = std::io::stdout().lock();
    let line = format!(
        "psnr: {:.2} dB ({} atoms `{}`, sparsity {}, {})\n",
        fit.psnr,
        fit.n_atoms,
        args.family,
        args.sparsity,
        if is_sct(&args.output) {
            "function atoms in the .sct"
        } else {
            "raster written"
        }
    );
    std::io::Write::write_all(&mut stdout, line.as_bytes()).context("cannot write to stdout")?;
    Ok(())
}
