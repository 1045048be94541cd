//! Reading a command's raster inputs: formats, voids, `--max-input-cells` before any large
//! allocation, cell sizes and where they came from. The commands and the shared argument groups
//! ([`crate::synth_args`], [`crate::sparse_model`]) read through here.
use std::path::Path;

use anyhow::{Context, Result, bail};
use relief_heightfield::{Heightfield, Progress};

use crate::ctx::Ctx;

use crate::args::ReadArgs;

/// Largest raster read from a device or pipe without `--max-input-cells` (2^24 cells: the
/// stream is read up to 512 MiB).
const DEVICE_READ_CELLS: usize = 1 << 24;

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
    read_raster_for(path, read, ctx, None)
}

/// The working memory per cell of the job a raster is read for (`relief flow`, `masks`,
/// `erode`: a fixed number of grids of the input's size), so that [`read_raster_for`] refuses
/// a file whose header declares more cells than the job can hold under `--max-memory` before
/// decoding it, with the pre-flight message of [`crate::memory::check_memory`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct JobCells<'a> {
    /// The command ("flow").
    pub(crate) command: &'a str,
    /// What the memory is for ("the flow rasters").
    pub(crate) what: &'a str,
    /// Bytes of the job per input cell.
    pub(crate) bytes_per_cell: u64,
    /// Bytes the job writes per input cell (checked against `--max-output-size`).
    pub(crate) output_bytes_per_cell: u64,
}

impl JobCells<'_> {
    /// The pre-flight check of the job on `width x height` cells against `--max-memory` (and
    /// its outputs against `--max-output-size`).
    pub(crate) fn check(&self, width: u64, height: u64, ctx: &Ctx) -> Result<()> {
        let cells = width as f64 * height as f64;
        ctx.check_output_size(
            &format!("the outputs of {}", self.command),
            cells * self.output_bytes_per_cell as f64,
            "a smaller input (crop it)",
        )?;
        ctx.check_memory(
            self.command,
            &[&[crate::memory::part(
                format!("{} of {width} x {height} cells", self.what),
                cells * self.bytes_per_cell as f64,
                "a smaller input (crop it)",
            )]],
        )
    }

    /// The most cells the job holds under `--max-memory`.
    fn cells(&self, ctx: &Ctx) -> usize {
        usize::try_from(ctx.max_memory.bytes / self.bytes_per_cell.max(1)).unwrap_or(usize::MAX)
    }
}

/// [`read_raster`] for a job of `job` bytes per cell: a header declaring more cells than the
/// job holds under `--max-memory` is refused before the raster is decoded (the reader checks
/// declared sizes first), with the job's pre-flight message; the size read is checked again
/// (formats without a header size).
pub(crate) fn read_raster_for(
    path: &Path,
    read: &ReadArgs,
    ctx: &Ctx,
    job: Option<JobCells<'_>>,
) -> Result<relief_io::Raster> {
    let progress = ctx.progress();
    progress.begin(&format!("reading {}", path.display()), 0);
    // Pre-flight: the cells a read may decode are bounded by --max-input-cells and by what
    // --max-memory leaves beside the file's bytes (decoded samples + f32 grid per cell), so a
    // decompression bomb or an endless device is refused before it is inflated.
    let mut opts = read.options();
    // `--cell-size` is applied after reading, with the georeference (below).
    opts.cell_size = None;
    let meta = std::fs::metadata(path).ok();
    let file_len = meta.as_ref().map_or(0, |m| m.len());
    let mut memory_cells = crate::memory::readable_cells(ctx.max_memory, file_len).max(1);
    let stream = meta.is_some_and(|m| !m.is_file());
    if stream {
        // A device or pipe has no length: relief-io reads at most 32 bytes per cell of it, so
        // its cells are bounded tighter, and without --max-input-cells by DEVICE_READ_CELLS (an
        // endless `/dev/zero` is refused after 512 MiB, not after gigabytes).
        memory_cells /= 3;
        if read.max_input_cells.is_none() {
            opts.max_cells = opts.max_cells.min(DEVICE_READ_CELLS);
        }
    }
    // relief's own `.r16` states its vertical mapping (and size) in its sidecar; without it
    // the counts would be read back as metres.
    if relief_io::Format::from_extension(path) == Some(relief_io::Format::R16)
        && let Some(side) = heightmap_sidecar_of(path)
        && let Some(mapping) = side.mapping
        && side
            .size
            .0
            .checked_mul(side.size.1)
            .and_then(|c| c.checked_mul(2))
            == Some(file_len)
        && read.width.is_none_or(|w| w as u64 == side.size.0)
        && read.height.is_none_or(|h| h as u64 == side.size.1)
    {
        opts.r16_mapping = mapping;
        opts.width = usize::try_from(side.size.0).ok();
        opts.height = usize::try_from(side.size.1).ok();
    }
    let by_memory = memory_cells < opts.max_cells;
    if by_memory {
        opts.max_cells = memory_cells;
    }
    let by_job = job.is_some_and(|j| j.cells(ctx).max(1) < opts.max_cells);
    if let (true, Some(j)) = (by_job, job) {
        opts.max_cells = j.cells(ctx).max(1);
    }
    let mut raster = relief_io::read(path, &opts).map_err(|e| {
        let text = e.to_string();
        let limit_hit = text.contains("max_cells") || text.contains("cell limit");
        if let (true, true, Some(j)) = (limit_hit, by_job, job)
            && let Some((w, h)) = declared_size(&e)
            && let Err(refused) = j.check(w, h, ctx)
        {
            return refused;
        }
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
                "cannot read {}: a device or pipe is read up to {DEVICE_READ_CELLS} cells unless \
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
    if let Some(j) = job {
        let hf = &raster.heightfield;
        j.check(hf.width() as u64, hf.height() as u64, ctx)?;
    }
    if let Some((nx, ny)) = read.cell_size {
        // `--cell-size` overrides the stored cell size, and a georeference follows it: its
        // pixel size is scaled by the same ratio about the grid's centre (where a geographic
        // or Web-Mercator grid's ground cell is measured), so a GeoTIFF written from the
        // result states the cells the user gave instead of the file's.
        let hf = &mut raster.heightfield;
        let georef = cell_size_georef(
            hf.georef(),
            (hf.width(), hf.height()),
            hf.cell_size(),
            (nx, ny),
        );
        hf.set_cell_size(nx, ny)
            .with_context(|| format!("--cell-size {nx},{ny}"))?;
        hf.set_georef(georef);
    } else if let Some(cell) = heightmap_sidecar_cell(path, &raster.heightfield) {
        raster.heightfield.set_cell_size(cell.0, cell.1)?;
        ctx.note(format!(
            "{}: cell size {:.3} x {:.3} m from its sidecar {}",
            path.display(),
            cell.0,
            cell.1,
            crate::ctx::heightmap_sidecar(path).display()
        ));
    }
    if read.warn_assumed_cell {
        warn_if_cell_assumed(path, &raster, read, ctx);
    }
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

/// The georeference of a `width x height` grid of cells `old` once `--cell-size` makes them
/// `new`: its pixel size scaled by the same ratio about the grid's centre (see
/// [`read_raster_for`]).
pub(crate) fn cell_size_georef(
    georef: Option<&relief_heightfield::GeoRef>,
    (width, height): (usize, usize),
    (ox, oy): (f64, f64),
    (nx, ny): (f64, f64),
) -> Option<relief_heightfield::GeoRef> {
    let (sx, sy) = (nx / ox, ny / oy);
    let (cw, ch) = (width as f64 / 2.0, height as f64 / 2.0);
    georef.map(|g| g.window(cw * (1.0 - sx), ch * (1.0 - sy), sx, sy))
}

/// The width and height a file declares, from a reader's size error.
fn declared_size(e: &relief_io::IoError) -> Option<(u64, u64)> {
    let mut root = e;
    while let relief_io::IoError::InFile { source, .. } = root {
        root = source;
    }
    match root {
        relief_io::IoError::Dimensions { width, height, .. } => Some((*width, *height)),
        _ => None,
    }
}

pub(crate) use relief_io::heightmap16::{
    cell_size_stored, heightmap_sidecar_cell, heightmap_sidecar_of,
};

/// Whether the cell size of a raster read from `path` with `read` is the reader's 1 m
/// stand-in: the file stores none ([`cell_size_stored`]) and `--cell-size` did not give one.
pub(crate) fn cell_size_assumed(path: &Path, raster: &relief_io::Raster, read: &ReadArgs) -> bool {
    read.cell_size.is_none() && !cell_size_stored(path, raster)
}

/// The warning of an assumed cell size (see [`cell_size_assumed`]): every figure in metres
/// (slopes, drainage areas, feature sizes, volumes) is then only as right as that guess.
pub(crate) fn assumed_cell_warning(path: &Path) -> String {
    format!(
        "warning: {} stores no cell size: 1 x 1 m cells assumed (pass --cell-size X[,Y] in \
         metres)",
        path.display()
    )
}

/// Prints [`assumed_cell_warning`] (unless `--quiet`) when the main input's cell size is
/// assumed; returns whether it is.
pub(crate) fn warn_if_cell_assumed(
    path: &Path,
    raster: &relief_io::Raster,
    read: &ReadArgs,
    ctx: &Ctx,
) -> bool {
    let assumed = cell_size_assumed(path, raster, read);
    if assumed {
        ctx.note(assumed_cell_warning(path));
    }
    assumed
}
