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
    if crate::describe::is_tree(&args.input) {
        // A construction tree is a terrain at any scale: converted at its own grid, as
        // `relief decompress MODEL OUT` (which takes --factor and --window) writes it.
        #[derive(Debug, clap::Parser)]
        struct Decompress {
            #[command(flatten)]
            args: super::decompress::Args,
        }
        use clap::Parser as _;
        let d = Decompress::try_parse_from([
            std::ffi::OsStr::new("decompress"),
            args.input.as_os_str(),
            args.output.as_os_str(),
        ])?;
        return super::decompress::run(d.args, ctx);
    }
    if crate::describe::is_model(&args.input) {
        bail!(
            "{} is a relief model (a dictionary of patches), not a terrain to convert \
             (`relief info` describes it; `relief compress --dictionary {}` uses it)",
            args.input.display(),
            args.input.display()
        );
    }
    let raster = super::read_raster(&args.input, &args.read, ctx)?;
    let hf = raster.heightfield;
    let progress = ctx.progress();
    progress.begin("writing", 0);
    ctx.write_raster(&args.output, &hf)?;
    // `--size-plus-one` writes the corner samples of a 16-bit heightmap: one more each way.
    let plus_one = usize::from(ctx.size_plus_one && crate::ctx::is_heightmap16(&args.output));
    drop(progress);
    ctx.note(format!(
        "wrote {} ({} x {})",
        args.output.display(),
        hf.width() + plus_one,
        hf.height() + plus_one
    ));
    Ok(())
}
