//! `relief preview IN OUT.png`: shaded-relief preview (hillshade blended with an elevation
//! colour ramp; voids drawn in a flat colour).

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
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Reads the raster and writes its preview atomically.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    ctx.check_outputs(
        &[&args.input],
        &[(&args.output, crate::outputs::OutKind::Png)],
    )?;
    let raster = super::read_raster(&args.input, &args.read, ctx)?;
    let progress = ctx.progress();
    progress.begin("rendering preview", 0);
    relief_io::write_preview_png(&args.output, &raster.heightfield)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    drop(progress);
    ctx.note(format!("wrote {}", args.output.display()));
    Ok(())
}
