//! Working-memory models of the jobs of this crate, beside the algorithms they model: the
//! pre-flight estimates `relief` checks against `--max-memory` before any work (the CLI's
//! commands, its tile tasks and the pipeline's stages use the same numbers). Calibrated on
//! measured peak RSS; each constant says what it counts.

use crate::{AmplifySettings, DictionaryChoice};

/// Bytes per cell of the last step's input kept by a tile plan (the raster, the intermediate
/// model's rasterisation buffers, the serialised copy).
pub const LAST_STEP_INPUT_BYTES_PER_CELL: f64 = 16.0;

/// Working bytes per coarse cell of one x4 step (patch matrices of the coding and training
/// grids, codes, residual layer, the x16 intermediate raster), for the default patch side
/// `a = 8` and grid step 2; scaled by `a^2 / S^2` for other settings. Calibrated on measured
/// peak RSS.
pub const STEP_BYTES_PER_COARSE_CELL: f64 = 200.0;

/// Working bytes per exemplar cell (resampled copies, candidate patches, the learned pair of
/// dictionaries).
pub const EXEMPLAR_BYTES_PER_CELL: f64 = 40.0;

/// Bytes per output cell of a raster written from memory (the f32 grid and its encoding).
pub const RASTER_OUT_BYTES_PER_CELL: f64 = 12.0;

/// Bytes of the candidate (L, H) pairs an exemplar gives (`min(max_candidates, patches of the
/// x4-reduced exemplar)` pairs for a complete dictionary, at most `max_learning_pool` for a
/// learned one): per pair the L patch (`a^2` floats), the H patch (`16 a^2`) and the L
/// footprint (`a^2`), held twice while the dictionaries are built (candidate matrices and
/// dictionary). A complete 65,536-atom dictionary of the default `a = 8` takes about 600 MB.
pub fn candidate_bytes(exemplar: (usize, usize), settings: &AmplifySettings) -> f64 {
    let a = settings.patch_size();
    let cs = settings.candidate_step.max(1);
    let (wl, hl) = (exemplar.0 / 4, exemplar.1 / 4);
    let per_axis = |l: usize| if l < a { 0 } else { (l - a) / cs + 1 };
    let patches = per_axis(wl) as f64 * per_axis(hl) as f64;
    let cap = match settings.dictionary {
        DictionaryChoice::Complete => settings.max_candidates,
        DictionaryChoice::Learned { .. } => settings.max_candidates.min(settings.max_learning_pool),
    };
    let pairs = patches.min(cap as f64);
    pairs * (18 * a * a) as f64 * 4.0 * 2.0
}

/// The peak working memory of an amplification of `coarse` cells with `exemplar` held whole
/// in memory, with the constants above: the largest of the last x4 step with the
/// exemplar's dictionaries, and the output raster. The pipeline's `amplify` and `sketch`
/// stages check it against `relief run --max-memory`.
pub fn amplify_working_bytes(
    coarse: (usize, usize),
    exemplar: (usize, usize),
    settings: &AmplifySettings,
) -> f64 {
    let a = settings.patch_size() as f64;
    let s = settings.grid_step().max(1.0);
    let shape = ((a * a / (s * s)) / 16.0).max(0.25);
    let ex = exemplar.0 as f64 * exemplar.1 as f64 * EXEMPLAR_BYTES_PER_CELL
        + candidate_bytes(exemplar, settings);
    let c0 = coarse.0 as f64 * coarse.1 as f64;
    let steps = settings.steps.min(64) as i32;
    let last = c0 * 16f64.powi((steps - 1).max(0));
    let out = c0 * 16f64.powi(steps);
    (last * STEP_BYTES_PER_COARSE_CELL * shape + ex).max(out * RASTER_OUT_BYTES_PER_CELL)
}

/// The two parts of a compression's working memory: the patch matrix (f32 rows of `a^2`, with
/// the working copies of K-SVD) over the input, and the dictionary of `k` atoms with its Gram
/// matrix (none at sparsity 1 above 4096 atoms, where the nearest-atom search codes without).
pub fn compress_bytes(cells: f64, patches: f64, a: f64, k: f64, sparsity: usize) -> (f64, f64) {
    let gram = if sparsity == 1 && k > relief_sparse_core::omp::NEAREST_MIN_ATOMS as f64 {
        // One 256 x 4096 correlation buffer per worker.
        8.0 * 256.0 * 4096.0 * 4.0
    } else {
        k * k * 4.0
    };
    (
        patches * a * a * 4.0 * 4.0 + cells * 16.0,
        k * a * a * 4.0 * 2.0 + gram,
    )
}

/// The working memory of compressing a `w x h` terrain with `job` at `sparsity` (the
/// pipeline's `sparse` stage checks it for its largest sparsity).
pub fn compress_job_bytes(
    (w, h): (usize, usize),
    job: &crate::CompressSettings,
    sparsity: usize,
) -> f64 {
    let a = job.patch_size as f64;
    let step = job.step.unwrap_or(a * job.spacing / 2.0).max(0.25);
    let patches = (w as f64 / step).ceil() * (h as f64 / step).ceil();
    let k = match job.source {
        crate::DictionarySource::Complete => patches,
        _ => job.atoms as f64,
    };
    let (p, d) = compress_bytes(w as f64 * h as f64, patches, a, k, sparsity);
    p + d
}
