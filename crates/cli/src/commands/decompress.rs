//! `relief decompress IN.sct OUT [--scale F] [--window x,y,w,h]`: rasterises a Sparse
//! Construction Tree (guerin2016 section 4.1) at any resolution, or any window of it, into any
//! raster format relief writes (chosen from OUT's extension; written atomically). Prints the
//! storage figures of the model and, with `--reference`, the PSNR against a raster.
//!
//! ```text
//! relief decompress gc.sct gc.tif
//! relief decompress gc.sct gc_x4.exr --scale 4 --window 512,512,1024,1024
//! relief decompress gc.sct gc.tif --reference grandcanyon.tif
//! ```

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use rayon::prelude::*;
use relief_heightfield::metrics;
use relief_sparse_core::{RasterSettings, Sct, Window, layer_storage_values};

use crate::ctx::Ctx;
use crate::sparse_model::{read_model_bytes, registry};

/// Arguments of `relief decompress`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input `.sct` file (written by `relief compress`).
    pub(crate) input: PathBuf,
    /// Output raster: .tif/.tiff, .png (16-bit), .exr, .npy, .r16 or .r32.
    pub(crate) output: PathBuf,
    /// Scale factor: output pixel (X, Y) samples the terrain at (X / F, Y / F).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) scale: f64,
    /// Window `X,Y,W,H` of the output raster (in output pixels at --scale).
    #[arg(long, value_name = "X,Y,W,H")]
    pub(crate) window: Option<Window>,
    /// Raster to compare with (same size as the output): prints PSNR and RMSE.
    #[arg(long)]
    pub(crate) reference: Option<PathBuf>,
    /// Refuse outputs larger than this many cells.
    #[arg(long, default_value_t = 1 << 28)]
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
            "cannot rasterise the {} x {} model {} at --scale {}",
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
            "invalid output size {} x {} = {cells} cells: exceeds --max-cells {}",
            win.width,
            win.height,
            args.max_cells
        );
    }
    // Pre-flight (issue 18): the raster in memory and its encoding, and the file size.
    let out_cells = cells as f64;
    let change = if args.window.is_some() {
        "a smaller --window"
    } else {
        "a smaller --scale or --window"
    };
    ctx.check_output_size("the output raster", out_cells * 4.0, change)?;
    ctx.check_memory(
        &format!("decompress --scale {}", args.scale),
        &[&[
            crate::memory::part(
                format!("the {} x {} output raster", win.width, win.height),
                out_cells * crate::sparse_model::RASTER_OUT_BYTES_PER_CELL,
                change,
            ),
            crate::memory::part("the model", bytes.len() as f64 * 3.0, "a smaller model"),
        ]],
    )?;
    let reference = match &args.reference {
        Some(p) => Some(super::read_raster(p, &args.read, ctx)?.heightfield),
        None => None,
    };
    let settings = RasterSettings {
        scale: args.scale,
        window: Some(win),
    };
    if let Some((est, how)) = estimate_seconds(&sct, &settings)? {
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
    let (mut t, mut layers, mut s_max) = (0u64, 0usize, 0usize);
    for l in sct.layers() {
        let d = l.dictionary();
        t += layer_storage_values(d, l.len(), l.max_sparsity());
        layers += 1;
        s_max = s_max.max(l.max_sparsity());
    }
    let t0 = (sct.width() * sct.height()) as u64;
    let mut out = format!(
        "model:       {} ({} x {} terrain, {layers} sparse layer(s), s = {s_max})\n\
         storage:     t = {t} values for t0 = {t0} samples: rho = {:.2} %\n\
         bytes:       {} ({:.2} % of the terrain as f32)\n\
         output:      {} x {} at scale {} (window {},{},{},{})\n",
        args.input.display(),
        sct.width(),
        sct.height(),
        100.0 * t as f64 / t0 as f64,
        bytes.len(),
        100.0 * bytes.len() as f64 / (4.0 * t0 as f64),
        hf.width(),
        hf.height(),
        args.scale,
        win.x,
        win.y,
        win.width,
        win.height,
    );
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

/// Rasters of at least this many cells get a time estimate (smaller ones take seconds).
const PILOT_FROM_CELLS: usize = 1 << 20;
/// The pilot rasterises this many evenly spaced row strips ...
const PILOT_STRIPS: usize = 16;
/// ... covering about 1/this of the window's rows.
const PILOT_SHARE: usize = 64;

/// Estimated seconds to rasterise `settings`' window: times [`PILOT_STRIPS`] evenly spaced
/// full-width row strips covering about 1/[`PILOT_SHARE`] of it, in parallel as the run is,
/// and scales by the cell count (the cost of a cell is the atoms over it, which the strips
/// sample across the whole model). `None` for small windows. Returns the pilot's description.
pub(crate) fn estimate_seconds(
    sct: &Sct,
    settings: &RasterSettings,
) -> Result<Option<(f64, String)>> {
    let Some(win) = settings.window else {
        return Ok(None);
    };
    let cells = win.width * win.height;
    if cells < PILOT_FROM_CELLS {
        return Ok(None);
    }
    let rows = win.height.div_ceil(PILOT_SHARE * PILOT_STRIPS).max(1);
    let strips: Vec<Window> = (0..PILOT_STRIPS)
        .map(|i| Window {
            x: win.x,
            y: win.y + (i * (win.height - rows)) / (PILOT_STRIPS - 1),
            width: win.width,
            height: rows,
        })
        .collect();
    let t = std::time::Instant::now();
    strips.par_iter().try_for_each(|&w| {
        sct.rasterize(&RasterSettings {
            scale: settings.scale,
            window: Some(w),
        })
        .map(drop)
    })?;
    let pilot_cells = (PILOT_STRIPS * rows * win.width) as f64;
    let est = t.elapsed().as_secs_f64() * cells as f64 / pilot_cells;
    Ok(Some((
        est,
        format!(
            "from {PILOT_STRIPS} strips of {rows} rows, {:.1} % of the cells",
            100.0 * pilot_cells / cells as f64
        ),
    )))
}
