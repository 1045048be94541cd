//! `relief decompress IN.sct OUT [--factor F] [--window x,y,w,h]`: rasterises a Sparse
//! Construction Tree (guerin2016 section 4.1) at any resolution, or any window of it, into any
//! raster format relief writes (chosen from OUT's extension; written atomically). Prints the
//! storage figures of the model and, with `--reference`, the PSNR against a raster.
//!
//! ```text
//! relief decompress gc.sct gc.tif
//! relief decompress gc.sct gc_x4.exr --factor 4 --window 512,512,1024,1024
//! relief decompress gc.sct gc.tif --reference grandcanyon.tif
//! ```

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use relief_heightfield::metrics;
use relief_sparse_core::{RasterSettings, Sct, Window};

use crate::ctx::Ctx;
use crate::sparse_model::{read_model_bytes, registry};

/// Arguments of `relief decompress`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input `.sct` file (written by `relief compress`).
    pub(crate) input: PathBuf,
    /// Output raster: .tif/.tiff, .png (16-bit), .exr, .npy, .r16 or .r32.
    pub(crate) output: PathBuf,
    /// Magnification F, as amplify's and refine's --factor: output pixel (X, Y) samples the
    /// terrain at (X / F, Y / F); any positive real, not only powers of 4 (--scale is an alias).
    #[arg(
        long = "factor",
        visible_alias = "scale",
        value_name = "F",
        default_value_t = 1.0
    )]
    pub(crate) scale: f64,
    /// Window `X,Y,W,H` of the output raster (in output pixels at --factor).
    #[arg(long, value_name = "X,Y,W,H")]
    pub(crate) window: Option<Window>,
    /// Raster to compare with (same size as the output): prints PSNR and RMSE.
    #[arg(long)]
    pub(crate) reference: Option<PathBuf>,
    /// Refuse outputs larger than this many cells (the input's limit is --max-input-cells).
    #[arg(long = "max-output-cells", alias = "max-cells", default_value_t = 1 << 28)]
    pub(crate) max_cells: usize,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Reads the model, rasterises the window, writes it, prints the figures.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(args.reference.as_deref());
    ctx.check_outputs(&inputs, &[(&args.output, crate::outputs::OutKind::Raster)])?;
    let bytes = read_model_bytes(&args.input, ctx)?;
    let sct = Sct::from_bytes(&bytes, &registry())
        .with_context(|| format!("cannot read {}", args.input.display()))?;
    let (fw, fh) = sct.raster_size(args.scale).with_context(|| {
        format!(
            "cannot rasterise the {} x {} model {} at --factor {}",
            sct.width(),
            sct.height(),
            args.input.display(),
            args.scale
        )
    })?;
    let win = args.window.unwrap_or(Window {
        x: 0,
        y: 0,
        width: fw,
        height: fh,
    });
    let cells = (win.width as u128) * (win.height as u128);
    if cells > args.max_cells as u128 {
        bail!(
            "invalid output size {} x {} = {cells} cells: exceeds --max-output-cells {}",
            win.width,
            win.height,
            args.max_cells
        );
    }
    let change = if args.window.is_some() {
        "a smaller --window"
    } else {
        "a smaller --factor or --window"
    };
    crate::commands::preflight::decompress(win, args.scale, bytes.len(), change, ctx)?;
    let reference = match &args.reference {
        Some(p) => {
            // Only its heights are compared: its cell size does not matter.
            let read = super::ReadArgs {
                warn_assumed_cell: false,
                ..args.read.clone()
            };
            Some(super::read_raster(p, &read, ctx)?.heightfield)
        }
        None => None,
    };
    let settings = RasterSettings {
        scale: args.scale,
        window: Some(win),
    };
    if let Some((est, how)) = crate::budget::sct_raster_seconds(&sct, &settings)? {
        ctx.check_time(
            &format!("rasterising {} x {}", win.width, win.height),
            est,
            &how,
            change,
        )?;
    }
    let progress = ctx.progress();
    let hf = sct
        .rasterize_with_progress(&settings, &progress)
        .with_context(|| format!("cannot rasterise {}", args.input.display()))?;
    drop(progress);
    refuse_non_finite(hf.as_slice(), hf.width(), &win)
        .with_context(|| format!("cannot rasterise {}", args.input.display()))?;
    let quality = match (&reference, &args.reference) {
        (Some(r), Some(p)) => {
            if (r.width(), r.height()) != (hf.width(), hf.height()) {
                bail!(
                    "the reference {} is {} x {}, the output {} x {}",
                    p.display(),
                    r.width(),
                    r.height(),
                    hf.width(),
                    hf.height()
                );
            }
            Some((metrics::psnr(r, &hf)?, metrics::rmse(r, &hf)?))
        }
        _ => None,
    };
    ctx.write_raster(&args.output, &hf)?;
    let mut out = crate::sparse_model::storage_text(&args.input, &sct, bytes.len());
    out.push_str(&format!(
        "output:      {} x {} at scale {} (window {},{},{},{})\n",
        hf.width(),
        hf.height(),
        args.scale,
        win.x,
        win.y,
        win.width,
        win.height,
    ));
    if let Some((psnr, rmse)) = quality {
        out.push_str(&format!("PSNR:        {psnr:.2} dB (RMSE {rmse:.3} m)\n"));
    }
    out.push_str(&format!("wrote:       {}\n", args.output.display()));
    #[allow(clippy::print_stdout)]
    {
        print!("{out}");
    }
    Ok(())
}

/// `Err` naming the first cell of `values` (a `width`-wide raster of the window `win`) that is
/// not finite: a model whose values overflow (a tree of absurd constants or depths, a crafted
/// file) must not become a raster of infinities or NaNs that other tools read as terrain. A
/// model relief writes covers its whole grid, so it never has voids.
fn refuse_non_finite(values: &[f32], width: usize, win: &Window) -> Result<()> {
    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        bail!(
            "the model evaluates to {} at output cell ({}, {}): out of the range of a 32-bit \
             raster (a tree constant, depth or layer too large?); nothing written",
            values[k],
            win.x + k % width.max(1),
            win.y + k / width.max(1)
        );
    }
    Ok(())
}
