//! What the commands that build a sparse model by x4 steps share (`amplify`, `synthesize`,
//! `fit-procedural`, `tile plan`): the pre-flight estimate of the steps and of the output
//!, and writing the model as a `.sct` file or as a raster (whole, one window, or
//! streamed in bands of rows); and reading a model or dictionary file with the function atoms
//! every reader understands (`decompress`, `info`, `tree`, `tile`, `compress --dictionary`).

use relief_dictionary_learning::memory::{
    EXEMPLAR_BYTES_PER_CELL, LAST_STEP_INPUT_BYTES_PER_CELL, RASTER_OUT_BYTES_PER_CELL,
    STEP_BYTES_PER_COARSE_CELL, candidate_bytes,
};
use std::path::Path;

use anyhow::{Context, Result, bail};
use relief_dictionary_learning::{AmplifySettings, DictionaryChoice, register_function_atoms};
use relief_heightfield::Progress;
use relief_sparse_core::{FunctionAtomRegistry, RasterSettings, Sct, Window};

use crate::ctx::Ctx;

/// The flags `amplify` and `synthesize` share, flattened into their arguments where the
/// flags stand (`--help` lists them there).
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub(crate) struct SeedArg {
    /// Seed (candidate sampling and dictionary learning).
    #[arg(long, default_value_t = relief_dictionary_learning::AmplifySettings::default().seed)]
    pub(crate) seed: u64,
}

/// `--exemplar` and `--exemplar-cell-size` of `amplify` and `synthesize` (see [`SeedArg`]).
#[derive(Debug, Clone, Default, clap::Args)]
pub(crate) struct ExemplarArg {
    /// Exemplar DEM whose details are transferred (must have no voids). Each x4 step cuts its
    /// atoms from the exemplar box-down-sampled to the step's target cell size; a step finer
    /// than the exemplar uses it at native resolution (self-similarity), and says so.
    #[arg(long)]
    pub(crate) exemplar: std::path::PathBuf,
    /// Cell size of the exemplar in metres, `X` or `X,Y`, for an exemplar that does not store
    /// one (PNG, EXR, raw, NPY) or to override a stored one (GeoTIFF, sidecar).
    #[arg(long, value_parser = crate::args::parse_cell_size, value_name = "X[,Y]")]
    pub(crate) exemplar_cell_size: Option<(f64, f64)>,
}

impl ExemplarArg {
    /// Reads the exemplar; voids are an error naming it.
    pub(crate) fn read(&self, ctx: &Ctx) -> Result<relief_heightfield::Heightfield> {
        let raster =
            crate::read::read_raster(&self.exemplar, &crate::args::ReadArgs::default(), ctx)?;
        let hf = raster.heightfield;
        // The command's --fill-voids fills its input, not the exemplar: say how to fill it.
        let voids = hf.void_count();
        if voids > 0 && voids < hf.len() {
            bail!(
                "cannot use {} as exemplar: it has {voids} void cells and an exemplar must be \
                 complete (fill them first: relief convert --fill-voids {} FILLED.tif)",
                self.exemplar.display(),
                self.exemplar.display()
            );
        }
        hf.require_complete()
            .with_context(|| format!("cannot use {} as exemplar", self.exemplar.display()))?;
        Ok(hf)
    }
}

/// `--window` of `amplify` and `synthesize` (see [`SeedArg`]).
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub(crate) struct WindowArg {
    /// Only write this window of the output raster, `X,Y,W,H` in output pixels.
    #[arg(long, value_name = "X,Y,W,H")]
    pub(crate) window: Option<Window>,
}

/// How the result of an amplification is written (for [`preflight`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct OutputPlan {
    /// A `.sct` model (no raster).
    pub(crate) sct: bool,
    /// Only this window of the raster.
    pub(crate) window: Option<Window>,
    /// A GeoTIFF that is streamed in bands when large.
    pub(crate) stream: bool,
    /// The flag that sets the number of x4 steps (`--factor`, `--x4-steps`).
    pub(crate) steps_flag: &'static str,
    /// Only the steps before the last run here (`relief tile plan`): the last step's input
    /// raster is kept and its tasks compute the output window by window.
    pub(crate) last_step_tasked: bool,
    /// The landform pass runs over a raster held whole ([`crate::landform`]).
    pub(crate) landform: bool,
}

impl OutputPlan {
    /// The plan of a command writing `output` (a `.sct`, or a raster streamed when it is a
    /// GeoTIFF), whole or one `window`; `steps_flag` names its flag for x4 steps.
    pub(crate) fn of(output: &Path, window: Option<Window>, steps_flag: &'static str) -> Self {
        OutputPlan {
            last_step_tasked: false,
            sct: is_sct(output),
            window,
            stream: relief_io::Format::from_extension(output) == Some(relief_io::Format::GeoTiff),
            steps_flag,
            landform: false,
        }
    }

    /// The plan with the landform pass on or off.
    pub(crate) fn with_landform(self, landform: bool) -> Self {
        Self { landform, ..self }
    }
}

/// The dictionary of `--atoms N`: N learned atoms (3 learning iterations), 0 the complete
/// dictionary (every exemplar patch).
pub(crate) fn dictionary_choice(atoms: usize) -> DictionaryChoice {
    if atoms == 0 {
        DictionaryChoice::Complete
    } else {
        DictionaryChoice::learned_default(atoms)
    }
}

/// Pre-flight estimate of an amplification: the memory of each x4 step from the
/// coarse size and the settings, and that of the written raster, checked against
/// `--max-memory` (and the raster's size against `--max-output-size`) before any work. The
/// message names `--factor` when an intermediate step is too large, `--window` / `--stream` /
/// a `.sct` output when only the final raster is.
pub(crate) fn preflight(
    ctx: &Ctx,
    command: &str,
    coarse: (usize, usize),
    exemplar: (usize, usize),
    settings: &AmplifySettings,
    out: OutputPlan,
) -> Result<()> {
    use crate::memory::part;
    let a = settings.patch_size() as f64;
    let s = settings.grid_step().max(1.0);
    let shape = (a * a / (s * s)) / 16.0;
    let ex_cells = exemplar.0 as f64 * exemplar.1 as f64;
    let exemplar_part = part(
        "the exemplar and its dictionaries",
        ex_cells * EXEMPLAR_BYTES_PER_CELL + candidate_bytes(exemplar, settings),
        "a smaller --exemplar (or --atoms N, a learned dictionary)",
    );
    let coarse_cells = coarse.0 as f64 * coarse.1 as f64;
    let here = settings.steps - usize::from(out.last_step_tasked);
    let mut peaks: Vec<Vec<crate::memory::Part>> = Vec::new();
    for t in 0..here {
        let c = coarse_cells * 16f64.powi(t as i32);
        peaks.push(vec![
            part(
                format!(
                    "x4 step {} of {} on {} coarse cells",
                    t + 1,
                    settings.steps,
                    c as u64
                ),
                c * STEP_BYTES_PER_COARSE_CELL * shape.max(0.25),
                format!("a smaller {} (or a smaller input)", out.steps_flag),
            ),
            exemplar_part.clone(),
        ]);
    }
    if out.last_step_tasked {
        // The last step's input as a raster, its serialised copy, and the dictionary.
        let c = coarse_cells * 16f64.powi(here as i32);
        peaks.push(vec![
            part(
                "the last step's input raster",
                c * LAST_STEP_INPUT_BYTES_PER_CELL,
                format!("a smaller {} (or a smaller input)", out.steps_flag),
            ),
            exemplar_part.clone(),
        ]);
    }
    let out_cells = coarse_cells * 16f64.powi(settings.steps as i32);
    let written = match out.window {
        Some(w) => w.width as f64 * w.height as f64,
        None => out_cells,
    };
    if !out.sct {
        let change = if out.window.is_some() {
            "a smaller --window".to_string()
        } else {
            format!("--window, a .sct output or a smaller {}", out.steps_flag)
        };
        ctx.check_output_size("the output raster", written * 4.0, &change)?;
        let banded = out.stream && written > crate::ctx::STREAM_CELLS as f64;
        let in_memory = if banded {
            // One band computed while the previous one is written.
            2.0 * crate::ctx::STREAM_BAND_CELLS as f64
        } else {
            written
        };
        // The landform pass works on the whole raster (never on a window or bands).
        let landform = if out.landform && !banded && out.window.is_none() {
            relief_landscape::landform::WORKING_BYTES_PER_CELL
        } else {
            0.0
        };
        peaks.push(vec![part(
            if landform > 0.0 {
                "the output raster and its landform pass"
            } else {
                "the output raster"
            },
            in_memory * (RASTER_OUT_BYTES_PER_CELL + landform),
            if out.window.is_some() {
                "a smaller --window".to_string()
            } else {
                format!(
                    "--window, a .tif output (streamed), a .sct output or a smaller {}",
                    out.steps_flag
                )
            },
        )]);
    }
    let refs: Vec<&[crate::memory::Part]> = peaks.iter().map(Vec::as_slice).collect();
    ctx.check_memory(command, &refs)?;
    // Within the limits, each x4 step computed here places its primitives on one grid over
    // its whole input (a tasked last step only over a task's window): refused in the user's
    // terms, not by the step's internal settings.
    let geometry = settings.coarse_geometry();
    for t in 0..here {
        let m = 4usize.pow(t as u32);
        let (w, h) = (coarse.0.saturating_mul(m), coarse.1.saturating_mul(m));
        if geometry.grid(w, h).is_err() {
            bail!(
                "{command}: a {} x {} input is too large for x{}: its x4 step {} of {} would \
                 add detail to {w} x {h} cells, more than one step can (at most 2^24 detail \
                 primitives); use a smaller {} or a smaller input",
                coarse.0,
                coarse.1,
                4u64.saturating_pow(settings.steps as u32),
                t + 1,
                settings.steps,
                out.steps_flag
            );
        }
    }
    Ok(())
}

/// Whether `path` names a `.sct` model (by extension).
pub(crate) fn is_sct(path: &Path) -> bool {
    crate::outputs::has_extension(path, "sct")
}

/// Refuses an output path we could not write before any work is done: a window with a `.sct`
/// output, or a raster extension relief-io does not know.
pub(crate) fn check_output_path(path: &Path, window: Option<Window>) -> Result<()> {
    if is_sct(path) {
        if window.is_some() {
            bail!(
                "--window applies to raster outputs, not to the .sct model {}",
                path.display()
            );
        }
    } else if relief_io::Format::from_extension(path).is_none() {
        bail!(
            "cannot tell the output format of {} (use .sct or a raster extension: .tif, .png, \
             .exr, .npy, .r16, .r32)",
            path.display()
        );
    }
    Ok(())
}

/// Writes `sct` as a `.sct` model or rasterises it (whole, or one window) to a raster file.
/// The coarse input of a landform pass over a model's raster ([`write_model`]).
pub(crate) struct Landform<'a>(pub(crate) &'a relief_heightfield::Heightfield);

pub(crate) fn write_model(
    sct: &Sct,
    path: &Path,
    window: Option<Window>,
    stream: bool,
    finish: Option<&Landform<'_>>,
    ctx: &Ctx,
) -> Result<()> {
    if is_sct(path) {
        if finish.is_some() {
            crate::landform::skipped(ctx, "a .sct model");
        }
        let bytes = sct.to_bytes().context("cannot serialise the model")?;
        relief_io::write_bytes_atomic(path, &bytes)
            .with_context(|| format!("cannot write {}", path.display()))?;
        ctx.note(format!(
            "wrote {} ({} x {} model, {} bytes)",
            path.display(),
            sct.width(),
            sct.height(),
            bytes.len()
        ));
        return Ok(());
    }
    let (fw, fh) = sct
        .raster_size(1.0)
        .context("cannot size the output raster")?;
    let win = window.unwrap_or(Window {
        x: 0,
        y: 0,
        width: fw,
        height: fh,
    });
    if relief_io::Format::from_extension(path) == Some(relief_io::Format::GeoTiff)
        && (stream || win.width.saturating_mul(win.height) > crate::ctx::STREAM_CELLS)
    {
        if finish.is_some() {
            crate::landform::skipped(ctx, "a streamed output");
        }
        return stream_geotiff(sct, path, win, ctx);
    }
    let mut hf = {
        let progress = ctx.progress();
        sct.rasterize_with_progress(&RasterSettings { scale: 1.0, window }, &progress)
            .context("cannot rasterise the result")?
    };
    if let Some(coarse) = finish {
        if window.is_some() {
            crate::landform::skipped(ctx, "a --window");
        } else {
            hf = crate::landform::apply(hf, coarse.0, ctx)?;
        }
    }
    let progress = ctx.progress();
    progress.begin("writing", 0);
    ctx.write_raster(path, &hf)?;
    drop(progress);
    ctx.note(format!(
        "wrote {} ({} x {})",
        path.display(),
        hf.width(),
        hf.height()
    ));
    Ok(())
}

/// Rasterises `win` of `sct` in bands of rows and streams them into a GeoTIFF, so the whole
/// raster never exists in memory (a 16384^2 output needs two 16 MiB bands, not 1 GiB).
fn stream_geotiff(sct: &Sct, path: &Path, win: Window, ctx: &Ctx) -> Result<()> {
    let georef = sct.raster_georef(1.0, win);
    let size = (win.width, win.height);
    let band = ctx.stream_bands(
        path,
        size,
        sct.cell_size(),
        georef.as_ref(),
        "rasterising and writing",
        |y, rows| {
            let window = Window {
                y: win.y + y,
                height: rows,
                ..win
            };
            let hf = sct
                .rasterize(&RasterSettings {
                    scale: 1.0,
                    window: Some(window),
                })
                .context("cannot rasterise the result")?;
            Ok(hf.into_vec())
        },
    )?;
    ctx.note(format!(
        "wrote {} ({} x {}, streamed in bands of {band} rows)",
        path.display(),
        win.width,
        win.height
    ));
    Ok(())
}

/// Function atoms every `.sct` / `.dict` reader of the CLI understands (the noise atoms of
/// relief-dictionary-learning).
pub(crate) fn registry() -> FunctionAtomRegistry {
    let mut r = FunctionAtomRegistry::new();
    register_function_atoms(&mut r);
    r
}

/// Largest `.sct` / `.dict` file the CLI reads into memory.
pub(crate) const MAX_MODEL_BYTES: u64 = 1 << 32;

/// Reads a model file (`.sct` or `.dict`) into memory, refusing absurd sizes first: at most
/// [`MAX_MODEL_BYTES`] and a third of `--max-memory` (the decoded model takes about twice the
/// file). Devices and pipes (length 0) are read through the same cap, growing the buffer with
/// `try_reserve` so an impossible allocation is an error.
pub(crate) fn read_model_bytes(path: &Path, ctx: &Ctx) -> Result<Vec<u8>> {
    use std::io::Read as _;
    let cap = MAX_MODEL_BYTES.min(ctx.max_memory.bytes / 3);
    let len = std::fs::metadata(path)
        .with_context(|| format!("cannot read {}", path.display()))?
        .len();
    let too_big = |n: u64| {
        anyhow::anyhow!(
            "cannot read {}: {n} bytes or more, above the {} a model may take (a third of {})",
            path.display(),
            crate::memory::human(cap),
            ctx.max_memory
        )
    };
    if len > cap {
        return Err(too_big(len));
    }
    let file =
        std::fs::File::open(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut r = file.take(cap + 1);
    let mut bytes: Vec<u8> = Vec::new();
    let mut chunk = vec![0u8; 1 << 20];
    loop {
        let n = match r.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => {
                return Err(
                    anyhow::Error::new(e).context(format!("cannot read {}", path.display()))
                );
            }
        };
        if bytes.len() as u64 + n as u64 > cap {
            return Err(too_big(cap + 1));
        }
        bytes
            .try_reserve(n)
            .map_err(|_| anyhow::anyhow!("cannot read {}: out of memory", path.display()))?;
        bytes.extend_from_slice(&chunk[..n]);
    }
    Ok(bytes)
}

/// The storage figures of a model, as `relief decompress` prints them: its size and layers,
/// `t` against the `t0` samples of the terrain (rho) and the file size.
pub(crate) fn storage_text(path: &Path, sct: &Sct, bytes: usize) -> String {
    let (mut t, mut layers, mut s_max) = (0u64, 0usize, 0usize);
    for l in sct.layers() {
        t += relief_sparse_core::layer_storage_values(l.dictionary(), l.len(), l.max_sparsity());
        layers += 1;
        s_max = s_max.max(l.max_sparsity());
    }
    let fields = sct.fields();
    t += fields
        .iter()
        .map(|f| (f.width() * f.height()) as u64)
        .sum::<u64>();
    let fields = match fields.len() {
        0 => String::new(),
        n => format!(", {n} field(s)"),
    };
    let t0 = (sct.width() * sct.height()) as u64;
    format!(
        "model:       {} ({} x {} terrain, {layers} sparse layer(s){fields}, s = {s_max})\n\
         storage:     t = {t} values for t0 = {t0} samples: rho = {:.2} %\n\
         bytes:       {} ({:.2} % of the terrain as f32)\n",
        path.display(),
        sct.width(),
        sct.height(),
        100.0 * t as f64 / t0 as f64,
        bytes,
        100.0 * bytes as f64 / (4.0 * t0 as f64),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidate_memory_follows_the_dictionary_choice() {
        // 1024^2 exemplar: 256^2 reduced grid, 249^2 patches of side 8 (< 65,536).
        let complete = AmplifySettings {
            dictionary: DictionaryChoice::Complete,
            ..AmplifySettings::default()
        };
        let per_pair = 18.0 * 64.0 * 4.0 * 2.0;
        assert_eq!(
            candidate_bytes((1024, 1024), &complete),
            249.0 * 249.0 * per_pair
        );
        // 2048^2: capped at max_candidates = 65,536.
        assert_eq!(
            candidate_bytes((2048, 2048), &complete),
            65_536.0 * per_pair
        );
        // Learned: the 4096-patch pool.
        let learned = AmplifySettings::default();
        assert_eq!(candidate_bytes((2048, 2048), &learned), 4096.0 * per_pair);
        // Too small an exemplar: no patch.
        assert_eq!(candidate_bytes((16, 16), &complete), 0.0);
    }
}
