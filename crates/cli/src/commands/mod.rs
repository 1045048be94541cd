//! One module per subcommand. Each exposes `pub(crate) struct Args` (clap `Args`) and
//! `pub(crate) fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()>`; `main.rs` lists them in
//! `enum Command` and dispatches in one `match`.

pub(crate) mod amplify;
pub(crate) mod analyze;
pub(crate) mod compress;
pub(crate) mod convert;
pub(crate) mod decompress;
pub(crate) mod fit_procedural;
pub(crate) mod info;
pub(crate) mod learn;
pub(crate) mod preview;
pub(crate) mod quilt;
pub(crate) mod refine;
pub(crate) mod run;
pub(crate) mod synth_args;
pub(crate) mod synthesize;
pub(crate) mod tile;
pub(crate) mod tree;
pub(crate) mod validate;
pub(crate) mod volume;

use std::path::Path;

use anyhow::{Context, Result, bail};
use relief_heightfield::{Heightfield, Progress};

use crate::ctx::Ctx;

/// Input options shared by every subcommand that reads a raster (`#[command(flatten)]`).
#[derive(Debug, Clone, Default, clap::Args)]
pub(crate) struct ReadArgs {
    /// Width of a raw .r16/.r32 input (square assumed when neither size is given).
    #[arg(long)]
    pub(crate) width: Option<usize>,
    /// Height of a raw .r16/.r32 input (derived from the file length when omitted).
    #[arg(long)]
    pub(crate) height: Option<usize>,
    /// Cell size in metres, `X` or `X,Y`, for inputs that do not store one (PNG, EXR, raw,
    /// NPY); overrides a stored one.
    #[arg(long, value_parser = parse_cell_size)]
    pub(crate) cell_size: Option<(f64, f64)>,
    /// Largest input raster accepted, in cells (default 268435456 = 2^28, 1 GiB of f32): a
    /// file declaring more is refused before anything is allocated. Raise it for larger inputs.
    #[arg(long)]
    pub(crate) max_input_cells: Option<usize>,
    /// Fill voids (nodata cells) by harmonic interpolation right after reading; without it a
    /// command that needs complete data refuses an input with voids.
    #[arg(long)]
    pub(crate) fill_voids: bool,
    /// How a PNG input encodes heights: `auto` (relief's grey mapping or raw grey counts) or
    /// `terrain-rgb` (Mapbox Terrain-RGB colour PNG).
    #[arg(long, value_enum, default_value_t = PngEncoding::Auto)]
    pub(crate) png_encoding: PngEncoding,
}

/// `--png-encoding` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub(crate) enum PngEncoding {
    /// Grey PNG (relief's recorded mapping, else raw counts).
    #[default]
    Auto,
    /// Mapbox Terrain-RGB.
    TerrainRgb,
}

impl ReadArgs {
    fn options(&self) -> relief_io::ReadOptions {
        relief_io::ReadOptions {
            width: self.width,
            height: self.height,
            cell_size: self.cell_size,
            max_cells: self
                .max_input_cells
                .unwrap_or(relief_io::ReadOptions::default().max_cells),
            png: match self.png_encoding {
                PngEncoding::Auto => relief_io::PngMode::Auto,
                PngEncoding::TerrainRgb => relief_io::PngMode::TerrainRgb,
            },
            ..Default::default()
        }
    }
}

pub(crate) fn parse_cell_size(s: &str) -> std::result::Result<(f64, f64), String> {
    // 1 micrometre to 10 000 km, as relief-io accepts from files: `1e-320` or `1e308` are
    // typos, and would overflow extents.
    let parse = |t: &str| {
        t.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && (1e-6..=1e7).contains(v))
            .ok_or_else(|| format!("`{t}` is not a cell size in metres between 1e-6 and 1e7"))
    };
    match s.split_once(',') {
        Some((x, y)) => Ok((parse(x)?, parse(y)?)),
        None => parse(s).map(|v| (v, v)),
    }
}

/// `X,Y,W,H` crop of `relief volume --crop` (W, H >= 3).
pub(crate) fn parse_crop(s: &str) -> std::result::Result<(usize, usize, usize, usize), String> {
    let v: Vec<usize> = s
        .split(',')
        .map(|t| t.trim().parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("`{s}` is not X,Y,W,H (four non-negative integers)"))?;
    match v[..] {
        [x, y, w, h] if w >= 3 && h >= 3 => Ok((x, y, w, h)),
        _ => Err(format!("`{s}` is not X,Y,W,H with W, H >= 3")),
    }
}

/// `X,Y`: two finite numbers.
pub(crate) fn parse_pair(s: &str) -> std::result::Result<(f32, f32), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("`{s}` is not X,Y"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{s}` is not X,Y (two finite numbers)"))
    };
    Ok((p(a)?, p(b)?))
}

/// `WxH` image size, each side in 1..=8192.
pub(crate) fn parse_image_size(s: &str) -> std::result::Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}` is not WxH"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<usize>()
            .ok()
            .filter(|v| (1..=8192).contains(v))
            .ok_or_else(|| format!("`{s}`: each size must be in 1..=8192"))
    };
    Ok((p(w)?, p(h)?))
}

/// Largest raster read from a device or pipe without `--max-input-cells` (2^24 cells: the
/// stream is read up to 512 MiB).
const STREAM_CELLS: usize = 1 << 24;

/// [`read_raster`] of a terrain that must be void-free: `--fill-voids` (in `read`) fills
/// the voids on reading; without it they are an error naming the flag.
pub(crate) fn read_void_free(path: &Path, read: &ReadArgs, ctx: &Ctx) -> Result<Heightfield> {
    let hf = read_raster(path, read, ctx)?.heightfield;
    if hf.has_voids() {
        bail!(
            "{} has {} void cells; fill them first (--fill-voids)",
            path.display(),
            hf.void_count()
        );
    }
    Ok(hf)
}

/// Reads any raster relief-io knows, with a progress indicator, naming the file on error.
pub(crate) fn read_raster(path: &Path, read: &ReadArgs, ctx: &Ctx) -> Result<relief_io::Raster> {
    let progress = ctx.progress();
    progress.begin(&format!("reading {}", path.display()), 0);
    // Pre-flight: the cells a read may decode are bounded by --max-input-cells and by what
    // --max-memory leaves beside the file's bytes (decoded samples + f32 grid per cell), so a
    // decompression bomb or an endless device is refused before it is inflated.
    let mut opts = read.options();
    let meta = std::fs::metadata(path).ok();
    let file_len = meta.as_ref().map_or(0, |m| m.len());
    let mut memory_cells = crate::memory::readable_cells(ctx.max_memory, file_len).max(1);
    let stream = meta.is_some_and(|m| !m.is_file());
    if stream {
        // A device or pipe has no length: relief-io reads at most 32 bytes per cell of it, so
        // its cells are bounded tighter, and without --max-input-cells by STREAM_CELLS (an
        // endless `/dev/zero` is refused after 512 MiB, not after gigabytes).
        memory_cells /= 3;
        if read.max_input_cells.is_none() {
            opts.max_cells = opts.max_cells.min(STREAM_CELLS);
        }
    }
    let by_memory = memory_cells < opts.max_cells;
    if by_memory {
        opts.max_cells = memory_cells;
    }
    let mut raster = relief_io::read(path, &opts).map_err(|e| {
        let text = e.to_string();
        let limit_hit = text.contains("max_cells") || text.contains("cell limit");
        let what = if !limit_hit {
            format!("cannot read {}", path.display())
        } else if by_memory {
            format!(
                "cannot read {}: at most {memory_cells} cells fit in {} ({} bytes per cell \
                 while decoding, beside the {} file): raise --max-memory",
                path.display(),
                ctx.max_memory,
                crate::memory::READ_BYTES_PER_CELL,
                crate::memory::human(file_len)
            )
        } else if stream && read.max_input_cells.is_none() {
            format!(
                "cannot read {}: a device or pipe is read up to {STREAM_CELLS} cells unless \
                 --max-input-cells says more",
                path.display()
            )
        } else {
            format!(
                "cannot read {}: more than --max-input-cells {} cells (raise it for larger \
                 inputs)",
                path.display(),
                opts.max_cells
            )
        };
        if !limit_hit {
            return anyhow::Error::new(e).context(what);
        }
        // The library's cause names its own option (`ReadOptions::max_cells`), which means
        // nothing on the command line: say what the file declares instead.
        let mut root = &e;
        while let relief_io::IoError::InFile { source, .. } = root {
            root = source;
        }
        match root {
            relief_io::IoError::Dimensions { width, height, .. } => anyhow::anyhow!(
                "{what} (the file declares {width} x {height} = {} cells)",
                u128::from(*width) * u128::from(*height)
            ),
            relief_io::IoError::Param { reason, .. } => anyhow::anyhow!("{what}: {reason}"),
            other => anyhow::anyhow!("{what}: {other}"),
        }
    })?;
    if read.fill_voids && raster.heightfield.has_voids() {
        progress.begin("filling voids", 0);
        let rep = relief_heightfield::fill::fill_voids(
            &mut raster.heightfield,
            &relief_heightfield::fill::FillSettings::default(),
        )
        .with_context(|| format!("cannot fill the voids of {}", path.display()))?;
        drop(progress);
        ctx.note(format!(
            "filled {} voids of {} ({} CG iterations, relative residual {:.1e})",
            rep.filled,
            path.display(),
            rep.iterations,
            rep.relative_residual
        ));
    }
    Ok(raster)
}

#[cfg(test)]
mod tests {
    use super::parse_cell_size;

    #[test]
    fn cell_size_argument() {
        assert_eq!(parse_cell_size("30"), Ok((30.0, 30.0)));
        assert_eq!(parse_cell_size("62.8,92.6"), Ok((62.8, 92.6)));
        assert!(parse_cell_size("0").is_err());
        assert!(parse_cell_size("x,1").is_err());
        for bad in ["1e-320", "1e308", "inf", "NaN", "-30", "30 m"] {
            assert!(parse_cell_size(bad).is_err(), "{bad}");
        }
    }
}
