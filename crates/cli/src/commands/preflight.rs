//! The pre-flight estimates of the commands: from the input size and the settings,
//! before any work, the peak working memory (checked against `--max-memory`) and the output
//! size (against `--max-output-size`), each part naming the flag that makes it smaller. The
//! limits and the checking are [`crate::memory`]; the sparse-model commands share
//! [`crate::sparse_model::preflight`].

use std::path::Path;

use anyhow::Result;
use relief_heightfield::Heightfield;
use relief_wavelet_lod::RefineSettings;

use crate::commands::{compress, refine};
use crate::ctx::Ctx;
use crate::memory::{Part, part};

/// Pre-flight estimate of `analyze`: the DWT pyramid, and with `--local` the fitted
/// maps of every band.
pub(crate) fn analyze(hf: &Heightfield, local: bool, ctx: &Ctx) -> Result<()> {
    ctx.check_memory(
        "analyze",
        &[&[part(
            format!("the analysis of {} cells", hf.len()),
            hf.len() as f64 * if local { 96.0 } else { 48.0 },
            "a smaller input (crop it)",
        )]],
    )
}

/// Pre-flight estimate of `compress`, before any patch is cut: the patch matrix
/// (f32 rows of `a^2`, with the working copies of K-SVD), the dictionary and its Gram matrix
/// (K^2: with `--dict complete`, K is the number of patches; none at `--sparsity 1` above 4096
/// atoms, where the exact nearest-atom search codes without it), the codes and the model.
pub(crate) fn compress(args: &compress::Args, hf: &Heightfield, ctx: &Ctx) -> Result<()> {
    let a = args.patch_size.unwrap_or(8) as f64;
    let spacing = args.spacing.unwrap_or(1.0);
    let step = args.step.unwrap_or(a * spacing / 2.0).max(0.25);
    let cells = hf.len() as f64;
    let patches = (hf.width() as f64 / step).ceil() * (hf.height() as f64 / step).ceil();
    let k = match (
        &args.dictionary,
        args.dict.unwrap_or(compress::DictSource::Ksvd),
    ) {
        (Some(_), _) => args.atoms as f64,
        (None, compress::DictSource::Complete) => patches,
        (None, _) => args.atoms as f64,
    };
    let change_k =
        if matches!(args.dict, Some(compress::DictSource::Complete)) && args.dictionary.is_none() {
            "--dict ksvd or sample with --atoms (the complete dictionary has one atom per patch), \
         or a smaller input"
        } else {
            "fewer --atoms"
        };
    let (patch_bytes, dict_bytes) =
        relief_dictionary_learning::memory::compress_bytes(cells, patches, a, k, args.sparsity);
    ctx.check_memory(
        "compress",
        &[&[
            part(
                format!(
                    "the {} patches of {} cells",
                    patches as u64,
                    a as u64 * a as u64
                ),
                patch_bytes,
                "a larger --step or --spacing, or a smaller input",
            ),
            part(
                format!("the dictionary of {} atoms and its Gram matrix", k as u64),
                dict_bytes,
                change_k,
            ),
        ]],
    )
}

/// Working bytes per input cell of the analysis (the DWT pyramid and the fitted statistics
/// maps of every band and level); calibrated on measured peak RSS.
const ANALYSIS_BYTES_PER_CELL: f64 = 80.0;

/// Working bytes per output cell synthesised in memory (the synthesis pyramid, the f32 result
/// and its encoding).
const RENDER_BYTES_PER_CELL: f64 = 24.0;

/// Pre-flight estimate: the analysis of the input and the synthesis of the output
/// (whole, one window, or one streamed band), checked against `--max-memory`, and the output
/// size against `--max-output-size`, before the analysis starts.
pub(crate) fn refine(
    args: &refine::Args,
    settings: &RefineSettings,
    hf: &relief_heightfield::Heightfield,
    window: Option<(usize, usize, usize, usize)>,
    ctx: &Ctx,
) -> Result<()> {
    let n = hf.width() as f64 * hf.height() as f64;
    let f = 2f64.powi(settings.extra_levels as i32);
    let (ow, oh) = (hf.width() as f64 * f, hf.height() as f64 * f);
    let written = window.map_or(ow * oh, |(_, _, w, h)| w as f64 * h as f64);
    let change = if window.is_some() {
        "a smaller --window"
    } else {
        "fewer --levels or --window"
    };
    ctx.check_output_size("the refined raster", written * 4.0, change)?;
    let streamed = relief_io::Format::from_extension(&args.output)
        == Some(relief_io::Format::GeoTiff)
        && (args.stream || written > crate::ctx::STREAM_CELLS as f64);
    let rendered = if streamed {
        written.min(2.0 * crate::ctx::STREAM_BAND_CELLS as f64 + 2.0 * ow)
    } else {
        written
    };
    let analysis = part(
        format!("the wavelet analysis of {} input cells", n as u64),
        n * ANALYSIS_BYTES_PER_CELL,
        "a smaller input (crop it)",
    );
    // The landform pass works on the whole raster (never on a window or bands).
    let landform = if args.landform_on() && !streamed && window.is_none() {
        relief_landscape::landform::WORKING_BYTES_PER_CELL
    } else {
        0.0
    };
    let synthesis = part(
        format!("the synthesis of {} output cells", rendered as u64),
        rendered * (RENDER_BYTES_PER_CELL + landform),
        if streamed {
            "fewer --levels"
        } else if window.is_some() {
            "a smaller --window (or a .tif output, streamed)"
        } else {
            "fewer --levels, --window or a .tif output (streamed)"
        },
    );
    ctx.check_memory(
        &format!("refine --levels {}", settings.extra_levels),
        &[&[analysis, synthesis]],
    )
}

/// Pre-flight of one task of a tiled refine plan: the analysis of the prepared input (its
/// size is the planned output's over `2^levels`) and the synthesis of the task's window.
pub(crate) fn refine_window(
    prepared_bytes: f64,
    m: &crate::tile_manifest::Manifest,
    win: relief_sparse_core::Window,
    change: &str,
    ctx: &Ctx,
) -> Result<()> {
    let levels = m.job["extra_levels"].as_u64().unwrap_or(0).min(30) as i32;
    let f = 2f64.powi(levels);
    let n = (m.output.width as f64 / f).ceil() * (m.output.height as f64 / f).ceil();
    tile_task(
        "refine",
        part(
            format!("the wavelet analysis of {} input cells", n as u64),
            n * ANALYSIS_BYTES_PER_CELL + prepared_bytes,
            "fewer --levels or a smaller input (plan again)",
        ),
        ("the synthesis of", RENDER_BYTES_PER_CELL),
        win,
        change,
        ctx,
    )
}

/// Pre-flight of one task of a tiled amplify plan: the decoded last step (its input raster
/// and dictionary, about twice the prepared file) and the window's x4 step (the step's
/// working bytes per coarse cell over the window's 1/16 coarse cells) and written raster.
pub(crate) fn last_step_window(
    prepared_bytes: f64,
    win: relief_sparse_core::Window,
    change: &str,
    ctx: &Ctx,
) -> Result<()> {
    tile_task(
        "amplify",
        part(
            "the prepared last step (its input and dictionary)",
            prepared_bytes * 3.0,
            "a smaller --factor or input (plan again)",
        ),
        (
            "the last x4 step over",
            relief_dictionary_learning::memory::STEP_BYTES_PER_COARSE_CELL / 16.0,
        ),
        win,
        change,
        ctx,
    )
}

/// Pre-flight of one task of a tiled `command` plan: what the task loads, then the work over
/// the window's output cells (`(what, working bytes per output cell)`) and its written raster.
fn tile_task(
    command: &str,
    loaded: Part,
    (work, bytes_per_cell): (&str, f64),
    win: relief_sparse_core::Window,
    change: &str,
    ctx: &Ctx,
) -> Result<()> {
    let cells = win.width as f64 * win.height as f64;
    ctx.check_memory(
        &format!("tile run ({command})"),
        &[&[
            loaded,
            part(
                format!("{work} {} output cells", cells as u64),
                cells
                    * (bytes_per_cell
                        + relief_dictionary_learning::memory::RASTER_OUT_BYTES_PER_CELL),
                change,
            ),
        ]],
    )
}

/// Pre-flight estimate of the mesh of `relief volume`: triangles from the polygonisation grid, memory
/// against `--max-memory` and file size against `--max-output-size`, both naming
/// `--resolution`.
fn volume_mesh(ctx: &Ctx, path: &Path, cells: [usize; 3], voxel_m: f64) -> Result<()> {
    let columns = cells[0] as f64 * cells[1] as f64;
    let triangles = columns * relief_implicit_volume::memory::TRIANGLES_PER_COLUMN;
    let change = format!(
        "a larger --voxel or a smaller --resolution (the voxel is now {voxel_m:.3} m; the grid is \
         {}x{}x{}) or a --crop",
        cells[0], cells[1], cells[2]
    );
    ctx.check_output_size(
        &format!("the mesh {}", path.display()),
        triangles * relief_implicit_volume::memory::FILE_BYTES_PER_TRIANGLE,
        &change,
    )?;
    ctx.check_memory(
        &format!("volume with {voxel_m:.3} m voxels"),
        &[&[part(
            format!("the mesh (about {:.0} M triangles)", triangles / 1e6),
            triangles * relief_implicit_volume::memory::MESH_BYTES_PER_TRIANGLE,
            change,
        )]],
    )
}

/// Pre-flight estimate of the render and section images of `relief volume` (`w x h`).
fn volume_images(ctx: &Ctx, (w, h): (usize, usize)) -> Result<()> {
    ctx.check_memory(
        "volume",
        &[&[part(
            "the render and section images",
            w as f64 * h as f64 * relief_implicit_volume::memory::IMAGE_BYTES_PER_PIXEL,
            "a smaller --image-size",
        )]],
    )
}

/// Pre-flight estimate of `decompress`: the raster in memory and its encoding, and the file
/// size.
pub(crate) fn decompress(
    win: relief_sparse_core::Window,
    scale: f64,
    model_bytes: usize,
    change: &str,
    ctx: &Ctx,
) -> Result<()> {
    let out_cells = win.width as f64 * win.height as f64;
    ctx.check_output_size("the output raster", out_cells * 4.0, change)?;
    ctx.check_memory(
        &format!("decompress --factor {scale}"),
        &[&[
            part(
                format!("the {} x {} output raster", win.width, win.height),
                out_cells * relief_dictionary_learning::memory::RASTER_OUT_BYTES_PER_CELL,
                change,
            ),
            part("the model", model_bytes as f64 * 3.0, "a smaller model"),
        ]],
    )
}

/// Pre-flight of a built volume scene: its mesh (to `mesh`), its images of `image_size`, and
/// their time estimated from a pilot render against `--max-time`.
pub(crate) fn volume(
    ctx: &Ctx,
    job: &relief_implicit_volume::VolumeJob,
    built: &relief_implicit_volume::Built,
    mesh: Option<&Path>,
    image_size: (usize, usize),
) -> Result<()> {
    use anyhow::Context as _;
    if let Some(path) = mesh {
        volume_mesh(
            ctx,
            path,
            built.mesh_grid(job),
            built.report.dims.voxel_m as f64,
        )?;
    }
    if job.render || job.section || job.closeups {
        volume_images(ctx, image_size)?;
    }
    if let Some(est) = job
        .estimate_image_seconds(built)
        .context("cannot time the pilot render")?
    {
        let (w, h) = image_size;
        ctx.check_time(
            &format!("rendering {w} x {h} images"),
            est,
            &format!(
                "from the same images at 1/{} of the size",
                relief_implicit_volume::job::PILOT_DIVISOR
            ),
            "a smaller --image-size",
        )?;
    }
    Ok(())
}

/// Pre-flight estimate of `learn`: every training patch is cut before the subsampling, then
/// the atoms and their Gram matrix.
pub(crate) fn learn(
    terrains: &[Heightfield],
    geometry: &relief_sparse_core::PatchGeometry,
    args: &crate::commands::learn::Args,
    ctx: &Ctx,
) -> Result<()> {
    let a = args.patch_size as f64;
    let step = geometry.step.max(0.25);
    let all: f64 = terrains
        .iter()
        .map(|t| (t.width() as f64 / step).ceil() * (t.height() as f64 / step).ceil())
        .sum();
    let kept = all.min(args.max_patches as f64);
    let k = args.atoms as f64;
    // Several exemplars' patch matrices are joined into one (a second copy).
    let copies = if terrains.len() > 1 { 2.0 } else { 1.0 };
    let cells: f64 = terrains.iter().map(|t| t.len() as f64).sum();
    ctx.check_memory(
        "learn",
        &[&[
            part(
                format!("the {} training patches", all as u64),
                cells * 4.0 + all * a * a * 4.0 * copies + kept * a * a * 4.0 * 3.0,
                "a larger --step, smaller exemplars or fewer --max-patches",
            ),
            part(
                format!("the {} atoms and their Gram matrix", k as u64),
                k * a * a * 8.0 + k * k * 8.0 + kept * args.sparsity as f64 * 16.0,
                "fewer --atoms",
            ),
        ]],
    )
}
