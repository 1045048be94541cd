//! Steps chained: which exemplar scale each step uses, box resampling, and the `amplify`
//! drivers with their figures.

use super::*;

/// Minimum exemplar side used at a step, in units of the fine patch side.
const MIN_EXEMPLAR_PATCHES: usize = 6;

/// Largest pool of training patches cut from a step's input before subsampling (2^18
/// patches, 64 MiB at the default patch side).
const MAX_TRAINING_POOL: usize = 1 << 18;

/// Relative tolerance under which a cell-size ratio counts as 1 (no resampling).
const SCALE_TOLERANCE: f64 = 1e-6;

/// How one x4 step uses the exemplar (see [`AmplifySettings::exemplar_cell_size`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepScale {
    /// Step index (0: the first x4).
    pub step: usize,
    /// Cell size `(x, y)` in metres of the step's output: the coarse input's over `4^(step+1)`.
    pub target_cell_size: (f64, f64),
    /// Cell size `(x, y)` of the exemplar grid the step's `H` atoms are cut from.
    pub exemplar_cell_size: (f64, f64),
    /// Size `(width, height)` of that grid.
    pub exemplar_size: (usize, usize),
    /// Box down-sampling factor applied to the exemplar along x (1: native resolution).
    pub reduction: f64,
    /// True when the exemplar could not be brought to the target cell size (it is coarser
    /// than the target, or too small to be reduced that far): the step relies on the
    /// self-similarity of relief across scales.
    pub self_similar: bool,
    /// One line saying what the step does with the exemplar (printed by the CLI).
    pub note: String,
}

/// Figures of an amplification ([`amplify_with_figures`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AmplifyFigures {
    /// How every x4 step used the exemplar, first step first.
    pub steps: Vec<StepScale>,
}

fn fmt_cell((x, y): (f64, f64)) -> String {
    if (x - y).abs() <= SCALE_TOLERANCE * x.abs().max(y.abs()) {
        format!("{x:.4} m")
    } else {
        format!("{x:.4} x {y:.4} m")
    }
}

/// The exemplar grid of every step of an amplification of a coarse input of cell size
/// `coarse_cell` with an exemplar of `exemplar_size` cells of `exemplar_cell` metres (see
/// [`AmplifySettings::exemplar_cell_size`]): the target cell size of step `t` is
/// `coarse_cell / 4^(t+1)`; when the exemplar is at least that fine along both axes it is
/// box-down-sampled to it, as far as it stays at least 6 fine patches wide; otherwise it is
/// used at native resolution.
pub fn exemplar_plan(
    coarse_cell: (f64, f64),
    exemplar_size: (usize, usize),
    exemplar_cell: (f64, f64),
    settings: &AmplifySettings,
) -> Vec<StepScale> {
    let min_side = (MIN_EXEMPLAR_PATCHES * settings.patch_size() * STEP_FACTOR) as f64;
    (0..settings.steps)
        .map(|t| {
            let f = STEP_FACTOR.pow((t + 1) as u32) as f64;
            let target = (coarse_cell.0 / f, coarse_cell.1 / f);
            let g = grid_at(
                target,
                exemplar_size,
                exemplar_cell,
                min_side,
                SCALE_TOLERANCE,
            );
            let note = if !g.fine_enough && g.reduced {
                format!(
                    "step {}: target cell {} is finer than the exemplar's {}: exemplar \
                     box-down-sampled x{:.3} along one axis to {} (the target's cell aspect), \
                     then used at that resolution (self-similarity across scales)",
                    t + 1,
                    fmt_cell(target),
                    fmt_cell(exemplar_cell),
                    g.kx,
                    fmt_cell(g.cell)
                )
            } else if !g.fine_enough {
                format!(
                    "step {}: target cell {} is finer than the exemplar's {}: exemplar used at \
                     native resolution (self-similarity across scales)",
                    t + 1,
                    fmt_cell(target),
                    fmt_cell(exemplar_cell)
                )
            } else if g.self_similar {
                format!(
                    "step {}: target cell {}, exemplar too small to be reduced that far: \
                     box-down-sampled x{:.3} to {} only (self-similarity across scales)",
                    t + 1,
                    fmt_cell(target),
                    g.kx,
                    fmt_cell(g.cell)
                )
            } else if g.reduced {
                format!(
                    "step {}: target cell {}: exemplar box-down-sampled x{:.3} to {} ({} x {})",
                    t + 1,
                    fmt_cell(target),
                    g.kx,
                    fmt_cell(g.cell),
                    g.size.0,
                    g.size.1
                )
            } else {
                format!(
                    "step {}: target cell {}: exemplar used at native resolution",
                    t + 1,
                    fmt_cell(target)
                )
            };
            StepScale {
                step: t,
                target_cell_size: target,
                exemplar_cell_size: g.cell,
                exemplar_size: g.size,
                reduction: if g.reduced { g.kx } else { 1.0 },
                self_similar: g.self_similar,
                note,
            }
        })
        .collect()
}

/// The exemplar grid nearest a target cell size ([`grid_at`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GridAt {
    /// Size `(width, height)` of the grid (the exemplar's own when not reduced).
    pub(crate) size: (usize, usize),
    /// Its cell size `(x, y)` in metres.
    pub(crate) cell: (f64, f64),
    /// Reduction factor along x (meaningful when `reduced`; for a native grid reshaped to the
    /// target's cell aspect, along its one reduced axis).
    pub(crate) kx: f64,
    /// The exemplar is box-down-sampled (else used at native resolution).
    pub(crate) reduced: bool,
    /// The exemplar is at least as fine as the target along both axes.
    pub(crate) fine_enough: bool,
    /// The grid is not at the target cell size: the exemplar is coarser than the target, or
    /// too small to be reduced that far.
    pub(crate) self_similar: bool,
}

/// The native exemplar grid of a target finer than it, box-down-sampled along one axis so its
/// cells have the target's aspect (self-similarity scales both axes alike: an exemplar of
/// 42.65 x 61.76 m cells used on square cells would squash its relief 1.45 times along x and
/// show as east-west streaks). The reduced side stays `min_side` cells at least.
fn reshaped(native: GridAt, target: (f64, f64), min_side: f64, tolerance: f64) -> GridAt {
    let (ex, ey) = native.cell;
    let (w, h) = (native.size.0 as f64, native.size.1 as f64);
    let k = (target.0 / target.1) / (ex / ey);
    if (k - 1.0).abs() <= tolerance {
        return native;
    }
    // k > 1: the exemplar's x cells are relatively too fine; k < 1: its y cells.
    let (side, kk) = if k > 1.0 { (w, k) } else { (h, 1.0 / k) };
    let kk = kk.min(side / min_side).max(1.0);
    if kk <= 1.0 + tolerance {
        return native;
    }
    let n = ((side / kk).round() as usize).max(1);
    let (size, cell) = if k > 1.0 {
        ((n, native.size.1), (ex * w / n as f64, ey))
    } else {
        ((native.size.0, n), (ex, ey * h / n as f64))
    };
    GridAt {
        size,
        cell,
        kx: kk,
        reduced: true,
        ..native
    }
}

/// The exemplar (`exemplar_size` cells of `exemplar_cell` metres) brought to the `target`
/// cell size: box-down-sampled to it when it is at least that fine along both axes, as far as
/// it stays `min_side` cells wide; otherwise used at native resolution. Ratios within
/// `tolerance` of 1 count as equal. The one rule behind every x4 step's exemplar
/// ([`exemplar_plan`]) and the sketch structure's ([`crate::exemplar_structure`]).
pub(crate) fn grid_at(
    target: (f64, f64),
    exemplar_size: (usize, usize),
    exemplar_cell: (f64, f64),
    min_side: f64,
    tolerance: f64,
) -> GridAt {
    let (w, h) = (exemplar_size.0 as f64, exemplar_size.1 as f64);
    let (rx, ry) = (target.0 / exemplar_cell.0, target.1 / exemplar_cell.1);
    let native = GridAt {
        size: exemplar_size,
        cell: exemplar_cell,
        kx: 1.0,
        reduced: false,
        fine_enough: false,
        self_similar: true,
    };
    if !(rx >= 1.0 - tolerance && ry >= 1.0 - tolerance) {
        return reshaped(native, target, min_side, tolerance);
    }
    let (rx, ry) = (rx.max(1.0), ry.max(1.0));
    // The largest reduction that keeps the exemplar `min_side` cells wide.
    let limit = (w / min_side).min(h / min_side).max(1.0);
    let shrink = (limit / rx.max(ry)).min(1.0);
    let (kx, ky) = ((rx * shrink).max(1.0), (ry * shrink).max(1.0));
    let reduced = kx > 1.0 + tolerance || ky > 1.0 + tolerance;
    let (size, cell) = if reduced {
        let size = (
            ((w / kx).round() as usize).max(1),
            ((h / ky).round() as usize).max(1),
        );
        let cell = (
            exemplar_cell.0 * w / size.0 as f64,
            exemplar_cell.1 * h / size.1 as f64,
        );
        (size, cell)
    } else {
        (exemplar_size, exemplar_cell)
    };
    GridAt {
        size,
        cell,
        kx,
        reduced,
        fine_enough: true,
        self_similar: shrink < 1.0 - tolerance,
    }
}

/// Area-consistent box down-sampling of `hf` to `w x h` cells
/// ([`Heightfield::resample_area`]: every output cell the exact area average of the input
/// cells it covers).
pub fn box_resample(hf: &Heightfield, w: usize, h: usize) -> Result<Heightfield> {
    Ok(hf.resample_area(w, h)?)
}

/// Amplifies `coarse` by `4^steps` with details of `exemplar` (section 5.3). Step `t` targets
/// the input's cell size over `4^(t+1)` and cuts its atoms from the exemplar box-down-sampled
/// to that cell size ([`exemplar_plan`]; the exemplar's cell size is its grid's or
/// [`AmplifySettings::exemplar_cell_size`]). Intermediate results are rasterised at their own
/// resolution and fed to the next step; the last step's [`Sct`] is returned, to be rasterised
/// at any resolution or window.
pub fn amplify(
    coarse: &Heightfield,
    exemplar: &Heightfield,
    settings: &AmplifySettings,
    progress: &dyn Progress,
) -> Result<Sct> {
    amplify_observed(coarse, exemplar, settings, progress, &mut |_| {})
}

/// [`amplify`], also returning how every step used the exemplar.
pub fn amplify_with_figures(
    coarse: &Heightfield,
    exemplar: &Heightfield,
    settings: &AmplifySettings,
    progress: &dyn Progress,
) -> Result<(Sct, AmplifyFigures)> {
    let (last, figures) = prepare_last_step(coarse, exemplar, settings, progress)?;
    let sct = last.sct_with(progress)?;
    Ok((amplified_georef(sct, coarse, settings), figures))
}

/// What one x4 step of [`amplify_observed`] did.
#[derive(Debug)]
pub struct StepReport<'a> {
    /// Step index (0: the first x4).
    pub step: usize,
    /// The step's coarse input.
    pub input: &'a Heightfield,
    /// The step's result (input size times 4).
    pub output: &'a Sct,
    /// How the step used the exemplar (cell sizes, reduction, self-similarity).
    pub exemplar: &'a StepScale,
}

/// [`amplify`], calling `observe` after every x4 step (for per-step measures).
pub fn amplify_observed(
    coarse: &Heightfield,
    exemplar: &Heightfield,
    settings: &AmplifySettings,
    progress: &dyn Progress,
    observe: &mut dyn FnMut(&StepReport<'_>),
) -> Result<Sct> {
    let (last, scale) = run_until_last(coarse, exemplar, settings, progress, observe)?;
    let sct = last.sct_with(progress)?;
    observe(&StepReport {
        step: settings.steps - 1,
        input: &last.input,
        output: &sct,
        exemplar: &scale,
    });
    Ok(amplified_georef(sct, coarse, settings))
}

/// `sct` with the georeference of the amplified `coarse`: its extent with cells `4^steps`
/// times smaller (pixel-is-area).
fn amplified_georef(sct: Sct, coarse: &Heightfield, settings: &AmplifySettings) -> Sct {
    let f = 1.0 / STEP_FACTOR.pow(settings.steps as u32) as f64;
    sct.with_georef(coarse.georef().map(|g| g.window(0.0, 0.0, f, f)))
}

/// Runs every x4 step of an amplification but the last, and prepares the last one: its input
/// raster and its dictionary ([`LastStep`]). Any window of the amplified output can then be
/// computed alone ([`LastStep::render_window`]), equal bit for bit to the same window of
/// [`amplify`]'s result; the figures say how every step used the exemplar.
pub fn prepare_last_step(
    coarse: &Heightfield,
    exemplar: &Heightfield,
    settings: &AmplifySettings,
    progress: &dyn Progress,
) -> Result<(LastStep, AmplifyFigures)> {
    let mut steps = Vec::with_capacity(settings.steps);
    let (last, scale) = run_until_last(coarse, exemplar, settings, progress, &mut |r| {
        steps.push(r.exemplar.clone());
    })?;
    steps.push(scale);
    Ok((last, AmplifyFigures { steps }))
}

/// The steps before the last (each observed), then the last step's dictionary and input.
fn run_until_last(
    coarse: &Heightfield,
    exemplar: &Heightfield,
    settings: &AmplifySettings,
    progress: &dyn Progress,
    observe: &mut dyn FnMut(&StepReport<'_>),
) -> Result<(LastStep, StepScale)> {
    settings.check()?;
    coarse.require_complete()?;
    exemplar.require_complete()?;
    let ah = settings.patch_size() * STEP_FACTOR;
    let min_side = MIN_EXEMPLAR_PATCHES * ah;
    if exemplar.width().min(exemplar.height()) < min_side {
        return Err(LearnError::NotEnough {
            what: "exemplar side in pixels",
            needed: min_side,
            got: exemplar.width().min(exemplar.height()),
        });
    }
    let exemplar_cell = settings
        .exemplar_cell_size
        .unwrap_or_else(|| exemplar.cell_size());
    let plan = exemplar_plan(
        coarse.cell_size(),
        (exemplar.width(), exemplar.height()),
        exemplar_cell,
        settings,
    );
    let mut native = exemplar.clone();
    native.set_cell_size(exemplar_cell.0, exemplar_cell.1)?;
    let mut current = coarse.clone();
    let mut octave_ratio = None;
    for (t, scale) in plan.iter().enumerate() {
        let ex = if scale.exemplar_size == (native.width(), native.height()) {
            native.clone()
        } else {
            box_resample(&native, scale.exemplar_size.0, scale.exemplar_size.1)?
        };
        let step_settings = step_settings(settings, t);
        let training = training_patches(&current, settings)?;
        let mut dict = MultiResDictionary::from_exemplar(
            &ex,
            Some(training.view()),
            &step_settings,
            progress,
        )?;
        if settings.exemplar_detail {
            // The exemplar's x4 detail at this step's scale; under self-similarity, the
            // exemplar's detail one x4 octave coarser is `ratio` times larger.
            // `octaves` x4 octaves between the exemplar grid used and the target (negative
            // when the target is finer than the exemplar).
            let (t, e) = (scale.target_cell_size, scale.exemplar_cell_size);
            let octaves = ((t.0 * t.1) / (e.0 * e.1)).sqrt().ln() / (STEP_FACTOR as f64).ln();
            let gain = if scale.self_similar && octaves.abs() > SCALE_TOLERANCE {
                let ratio = *octave_ratio.get_or_insert_with(|| super::octave_ratio(exemplar));
                ratio.powf(octaves)
            } else {
                1.0
            };
            dict.detail_rms = super::x4_detail_rms(&ex).map(|r| r * gain);
        }
        if t + 1 == settings.steps {
            let last = LastStep {
                input: current,
                dictionary: dict,
                settings: *settings,
            };
            return Ok((last, scale.clone()));
        }
        let sct = dict.amplify_once_with(&current, &step_settings, progress)?;
        observe(&StepReport {
            step: t,
            input: &current,
            output: &sct,
            exemplar: scale,
        });
        current = sct.rasterize_with_progress(
            &RasterSettings::default(),
            &relief_heightfield::StopOnly(progress),
        )?;
    }
    Err(LearnError::param("steps", 0, "must be >= 1"))
}

/// Training signals of a step's dictionary: the input's patches one radius apart (subsampled
/// to `max_training` by the learning anyway: they are as representative as the coding grid's,
/// at a quarter of the extraction cost). On very large inputs (a tiled plan's last step) only
/// every `k`-th band of rows is cut, so the pool stays under [`MAX_TRAINING_POOL`] patches.
fn training_patches(current: &Heightfield, settings: &AmplifySettings) -> Result<Array2<f32>> {
    let geom = PatchGeometry {
        step: settings.grid_step().max(settings.radius.floor().max(1.0)),
        ..settings.coarse_geometry()
    };
    let (w, h) = (current.width(), current.height());
    let pool = (w as f64 / geom.step).ceil() * (h as f64 / geom.step).ceil();
    if pool <= MAX_TRAINING_POOL as f64 {
        return Ok(extract_patches(current, &geom)?.matrix);
    }
    let k = (pool / MAX_TRAINING_POOL as f64).ceil() as usize;
    let band = 16 * settings.patch_size();
    let mut rows: Vec<f32> = Vec::new();
    let mut y0 = 0;
    while y0 < h {
        let crop = current.crop(0, y0, w, band.min(h - y0))?;
        rows.extend(extract_patches(&crop, &geom)?.matrix.iter());
        y0 += band * k;
    }
    let dim = geom.patch_size * geom.patch_size;
    Array2::from_shape_vec((rows.len() / dim, dim), rows)
        .map_err(|_| LearnError::param("training", dim, "internal shape error"))
}

/// The settings of step `t` (its own seed).
pub(super) fn step_settings(settings: &AmplifySettings, t: usize) -> AmplifySettings {
    AmplifySettings {
        seed: item_seed(settings.seed, 0x57e9, t as u64),
        ..*settings
    }
}
