//! Terrain synthesis from a painted sketch (guerin2016 section 5.3, figures 1, 9 and 12): the
//! sketch is mapped to an elevation range, given the exemplar's cell size times `4^steps`, and
//! amplified step by step with [`crate::multires::amplify`].
//!
//! A painted sketch is smooth: flat plateaus and soft strokes. With the paper's coded detail
//! amplitude (the whole `H_j` scaled by the code, so by the input patch's relief) its flat
//! parts get no detail and its strokes only a scaled copy of their own slope: a smooth blob
//! that follows the sketch pixels. Synthesis therefore defaults to
//! [`AmplifySettings::exemplar_detail`]: the input's bicubic interpolation plus each atom's
//! detail at the exemplar's own amplitude (ridges and valleys everywhere), scaled by the
//! exemplar's measured octave ratio for steps finer than the exemplar allows. `--paper` (CLI)
//! restores the coded amplitude.
//!
//! Before the x4 steps, [`crate::structure::exemplar_structure`] gives the sketch the
//! exemplar's landforms between its cell and its strokes (valleys and spurs a few sketch cells
//! apart), which no x4 step adds; see [`SynthesisSettings::structure`].

use relief_heightfield::{Heightfield, Progress};
use relief_sparse_core::Sct;
use serde::{Deserialize, Serialize};

use crate::error::{LearnError, Result};
use crate::multires::{
    AmplifySettings, DictionaryChoice, STEP_FACTOR, StepScale, amplify_with_figures,
};
use crate::structure::{StructureReport, StructureSettings, exemplar_structure};
use relief_landscape::grow::{GrowSettings, Strokes, grow_with_strokes};

/// Settings of the sketch-synthesis job ([`synthesize`]); serde as [`AmplifySettings`] (fields
/// missing inside a JSON `amplify` object take [`AmplifySettings`]' defaults, not the ones
/// below; the pipeline merges a spec onto these defaults instead).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SynthesisSettings {
    /// Amplification settings; `steps` defaults to 3 (figure 12: three incremental steps), the
    /// residual correction is off (the sketch's pixels are not to be reproduced) and
    /// `exemplar_detail` is on (see the module documentation).
    pub amplify: AmplifySettings,
    /// Elevation range the sketch's `[min, max]` is mapped to (`None`: the exemplar's range).
    pub height_range: Option<(f32, f32)>,
    /// The exemplar's landforms between the sketch's cell and its strokes, added at the
    /// sketch's resolution before the x4 steps ([`exemplar_structure`]; radius 0: off, the
    /// paper's method). The radius is capped at an eighth of the sketch's shorter side.
    pub structure: StructureSettings,
    /// Cell size `(x, y)` in metres of a sketch pixel, i.e. the sketch's extent on the ground
    /// (`None`: the exemplar's cell size times `4^steps`, so the last step is at the
    /// exemplar's resolution). A sketch of landform-sized strokes over an extent the
    /// exemplar covers takes the exemplar's landforms at their own scale instead of by
    /// self-similarity.
    pub sketch_cell_size: Option<(f64, f64)>,
    /// Landscape evolution from the sketch ([`relief_landscape::grow`]): the sketch is read as
    /// a rock uplift map, and stream-power incision with hillslope diffusion grows mountains
    /// whose ridges and dendritic valleys follow the strokes, on the sketch's grid x4 (the
    /// first x4 step), before the exemplar's detail is added by the remaining steps. The grown
    /// relief is mapped onto the height range. `None`: the paper's method (the sketch's
    /// pixels amplified directly, with the structure step when its radius is > 0).
    pub grow: Option<GrowSettings>,
}

impl Default for SynthesisSettings {
    fn default() -> Self {
        Self {
            amplify: AmplifySettings {
                steps: 3,
                dictionary: DictionaryChoice::learned(64, 3),
                // A painted sketch is not a measurement: forcing the output to reduce to its
                // pixels would reproduce them. The detail blend is still energy-normalised.
                residual_correction: false,
                exemplar_detail: true,
                ..Default::default()
            },
            height_range: None,
            structure: StructureSettings::default(),
            sketch_cell_size: None,
            grow: Some(GrowSettings::default()),
        }
    }
}

/// Figures of a synthesis ([`synthesize_with_figures`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SynthesisFigures {
    /// What the structure step did (`None`: off).
    pub structure: Option<StructureReport>,
    /// How every x4 step used the exemplar.
    pub steps: Vec<StepScale>,
    /// The relief grown from the sketch, mapped onto the height range, that the x4 steps
    /// amplified ([`SynthesisSettings::grow`]; `None`: off). The output is an integer
    /// multiple of it: the coarse input of a landform pass over the result.
    #[serde(skip)]
    pub grown: Option<Heightfield>,
}

/// Terrain synthesis from a painted coarse sketch (section 5.3, figures 1, 9 and 12): the sketch
/// values are mapped linearly to the elevation range, its cell size set to the exemplar's times
/// `4^steps`, and it is amplified step by step with the exemplar's details.
pub fn synthesize(
    sketch: &Heightfield,
    exemplar: &Heightfield,
    settings: &SynthesisSettings,
    progress: &dyn Progress,
) -> Result<Sct> {
    Ok(synthesize_with_figures(sketch, exemplar, settings, progress)?.0)
}

/// [`synthesize`], also returning what the structure step and every x4 step did with the
/// exemplar.
pub fn synthesize_with_figures(
    sketch: &Heightfield,
    exemplar: &Heightfield,
    settings: &SynthesisSettings,
    progress: &dyn Progress,
) -> Result<(Sct, SynthesisFigures)> {
    synthesize_with_strokes(sketch, &Strokes::default(), exemplar, settings, progress)
}

/// [`synthesize_with_figures`] with explicit ridge and river strokes painted beside the sketch
/// (figure 12's lines; [`Strokes`], each of the sketch's size or an integer fraction of it),
/// which the landscape evolution ([`SynthesisSettings::grow`]) follows: ridges raise the
/// uplift, rivers cancel it so they stay valley floors.
///
/// Errors: those of [`synthesize_with_figures`]; strokes without the landscape evolution
/// (`grow: None`), of another size, or with voids.
pub fn synthesize_with_strokes(
    sketch: &Heightfield,
    strokes: &Strokes,
    exemplar: &Heightfield,
    settings: &SynthesisSettings,
    progress: &dyn Progress,
) -> Result<(Sct, SynthesisFigures)> {
    if !strokes.is_empty() && settings.grow.is_none() {
        return Err(LearnError::param(
            "strokes",
            "ridges/rivers",
            "need the landscape evolution (grow); the paper's method reads the sketch alone",
        ));
    }
    strokes.check(sketch.width(), sketch.height())?;
    settings.amplify.check()?;
    settings.structure.check()?;
    sketch.require_complete()?;
    exemplar.require_complete()?;
    let (smin, smax) =
        sketch
            .min_max()
            .ok_or(LearnError::param("sketch", "empty", "needs values"))?;
    let (lo, hi) = match settings.height_range {
        Some(r) => r,
        None => exemplar
            .min_max()
            .ok_or(LearnError::param("exemplar", "empty", "needs values"))?,
    };
    if !(lo.is_finite() && hi.is_finite() && hi >= lo) {
        return Err(LearnError::param(
            "height_range",
            format!("{lo}..{hi}"),
            "must be finite, hi >= lo",
        ));
    }
    let span = (smax - smin).max(f32::MIN_POSITIVE);
    let mut s = sketch.map(|v| lo + (v - smin) / span * (hi - lo));
    let f = STEP_FACTOR.pow(settings.amplify.steps as u32) as f64;
    let (cx, cy) = settings
        .amplify
        .exemplar_cell_size
        .unwrap_or_else(|| exemplar.cell_size());
    let (sx, sy) = match settings.sketch_cell_size {
        Some((x, y)) if x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0 => (x, y),
        Some((x, y)) => {
            return Err(LearnError::param(
                "sketch_cell_size",
                format!("{x},{y}"),
                "must be finite and > 0",
            ));
        }
        None => (cx * f, cy * f),
    };
    s.set_cell_size(sx, sy)?;
    if let Some(g) = &settings.grow {
        return grown(&s, strokes, exemplar, (lo, hi), g, settings, progress);
    }
    let structure = if settings.structure.radius > 0.0 {
        // Patches at most half the sketch wide: a larger radius would paste one exemplar
        // patch over the whole sketch.
        let cap = (s.width().min(s.height()) / 8).max(1) as f64;
        let st = StructureSettings {
            radius: settings.structure.radius.min(cap),
            seed: settings.amplify.seed ^ settings.structure.seed,
        };
        let (enriched, report) = exemplar_structure(&s, exemplar, (cx, cy), (lo, hi), &st)?;
        s = enriched;
        Some(report)
    } else {
        None
    };
    let (sct, figures) = amplify_with_figures(&s, exemplar, &settings.amplify, progress)?;
    Ok((
        sct,
        SynthesisFigures {
            structure,
            steps: figures.steps,
            grown: None,
        },
    ))
}

/// The landscape-evolution synthesis ([`SynthesisSettings::grow`]) of the sketch `s` already
/// mapped to `(lo, hi)` at its cell size.
fn grown(
    s: &Heightfield,
    strokes: &Strokes,
    exemplar: &Heightfield,
    (lo, hi): (f32, f32),
    g: &GrowSettings,
    settings: &SynthesisSettings,
    progress: &dyn Progress,
) -> Result<(Sct, SynthesisFigures)> {
    let steps = settings.amplify.steps;
    // The network grows on the sketch's grid x4 (the first step) when there are steps left
    // for the exemplar's detail, on the sketch's own grid otherwise.
    let (map, rest) = if steps >= 2 {
        (
            s.resample(STEP_FACTOR * s.width(), STEP_FACTOR * s.height())?,
            steps - 1,
        )
    } else {
        (s.clone(), steps)
    };
    progress.begin("growing relief (landscape evolution)", 0);
    let relief = grow_with_strokes(
        &map,
        // Strokes of the sketch's size are an integer fraction of the map: `grow` resamples
        // them as the map was.
        strokes,
        &GrowSettings {
            seed: g.seed ^ settings.amplify.seed,
            ..*g
        },
        &|| false,
    )?;
    let (a, b) = relief
        .min_max()
        .ok_or(LearnError::param("sketch", "empty", "needs values"))?;
    let span = (b - a).max(f32::MIN_POSITIVE);
    let mapped = relief.map(|v| lo + (v - a) / span * (hi - lo));
    let amplify = AmplifySettings {
        steps: rest,
        ..settings.amplify
    };
    let (sct, figures) = amplify_with_figures(&mapped, exemplar, &amplify, progress)?;
    Ok((
        sct,
        SynthesisFigures {
            structure: None,
            steps: figures.steps,
            grown: Some(mapped),
        },
    ))
}
