//! `relief convert IN OUT [--fill-voids]`: converts a raster; the output format comes from
//! OUT's extension.

use std::path::PathBuf;

use anyhow::{Result, bail};
use relief_heightfield::Progress;

use crate::ctx::Ctx;

/// Arguments of `relief convert`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input raster (format detected from its content).
    pub(crate) input: PathBuf,
    /// Output raster: .tif/.tiff, .png (16-bit), .exr, .npy, .r16 or .r32.
    pub(crate) output: PathBuf,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Reads, optionally fills, writes atomically.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    ctx.check_outputs(
        &[&args.input],
        &[(&args.output, crate::outputs::OutKind::Raster)],
    )?;
    if crate::describe::is_model(&args.input) {
        bail!(
            "{} is a relief model (a construction tree or a dictionary), not a raster: \
             rasterise a .sct with `relief decompress {} OUT` (`relief info` describes either)",
            args.input.display(),
            args.input.display()
        );
    }
    let raster = super::read_raster(&args.input, &args.read, ctx)?;
    let hf = raster.heightfield;
    let progress = ctx.progress();
    progress.begin("writing", 0);
    ctx.write_raster(&args.output, &hf)?;
    drop(progress);
    ctx.note(format!(
        "wrote {} ({} x {})",
        args.output.display(),
        hf.width(),
        hf.height()
    ));
    Ok(())
}
