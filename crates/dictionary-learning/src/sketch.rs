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

use std::sync::Arc;

use relief_heightfield::{Heightfield, Progress};
use relief_sparse_core::{
    CentreGrid, Dictionary, Node, Patches, Placement, Sct, SparseLayer, dictionary::Atom,
};
use serde::{Deserialize, Serialize};

use rayon::prelude::*;

use crate::error::{LearnError, Result};
use crate::multires::{
    AmplifySettings, DictionaryChoice, MultiResDictionary, STEP_FACTOR, StepScale,
    amplify_with_figures, detail_gain, interpolation_layer, upsample4,
};
use crate::noise::item_seed;
use crate::structure::{StructureReport, StructureSettings, exemplar_structure};
use relief_landscape::grow::{GrowSettings, grow};

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
        return grown(&s, exemplar, (lo, hi), g, settings, progress);
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
    let relief = grow(
        &map,
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

/// Ratio of an exemplar's detail amplitude one x4 octave coarser to its own (RMS of the grid
/// minus its x4 reduction up-sampled back, on the exemplar reduced x4 vs on the exemplar):
/// how much larger the detail of a step is than the exemplar's when the step relies on
/// self-similarity ([`AmplifySettings::exemplar_detail`]). Clamped to `[1, 4]` (4: relief
/// proportional to scale); 2 when the exemplar is too small to measure it.
pub(crate) fn octave_ratio(exemplar: &Heightfield) -> f64 {
    let detail = x4_detail_rms;
    let (w, h) = (exemplar.width(), exemplar.height());
    if w.min(h) < 128 {
        return 2.0;
    }
    let measured = exemplar
        .resample(w / 4, h / 4)
        .ok()
        .and_then(|e1| Some(detail(&e1)? / detail(exemplar)?));
    match measured {
        Some(r) if r.is_finite() => r.clamp(1.0, 4.0),
        _ => 2.0,
    }
}

/// Number of best-matching atoms a primitive's exemplar detail is picked from.
const DETAIL_CHOICES: usize = 8;

/// RMS (metres) of a grid's x4 detail: the grid minus its x4 reduction up-sampled back
/// (`None` below 16 x 16 cells).
pub(crate) fn x4_detail_rms(e: &Heightfield) -> Option<f64> {
    let (w, h) = (e.width() / 4 * 4, e.height() / 4 * 4);
    if w.min(h) < 16 {
        return None;
    }
    let e = e.crop(0, 0, w, h).ok()?;
    let back = e.resample(w / 4, h / 4).ok()?.resample(w, h).ok()?;
    let s: f64 = e
        .as_slice()
        .iter()
        .zip(back.as_slice())
        .map(|(a, b)| (*a as f64 - *b as f64).powi(2))
        .sum();
    Some((s / (w * h) as f64).sqrt())
}

impl MultiResDictionary {
    /// One x4 step of [`AmplifySettings::exemplar_detail`]: the bicubic interpolation of the
    /// input plus, for every primitive, the detail `D_j = H_j - up(L_j)` of its atom at the
    /// exemplar's amplitude (metres, scaled to [`MultiResDictionary::detail_rms`]) with the sign
    /// of its correlation with the input patch; the atom is one of the best-matching ones
    /// (seeded), so a smooth input does not repeat one detail on the grid.
    pub(crate) fn exemplar_detail_step(
        &self,
        coarse: &Heightfield,
        patches: &Patches,
        fine: CentreGrid,
        settings: &AmplifySettings,
    ) -> Result<Sct> {
        let a = settings.patch_size();
        let ah = STEP_FACTOR * a;
        let f = STEP_FACTOR as f64;
        let mut detail = Dictionary::new(ah, 1.0, settings.radius * f)?;
        let mask = detail.support_mask().to_vec();
        // The detail gain baked into the atoms (normalize_detail) restores the variance the
        // blend loses; the blended detail has the RMS of the atoms' details without it.
        let gmap = settings
            .normalize_detail
            .then(|| detail_gain(ah, f * settings.grid_step(), f * settings.radius));
        let support = mask.iter().filter(|m| **m).count().max(1) as f64;
        // Detail atom index, amplitude (metres) and per-sample RMS without the gain of every
        // dictionary atom.
        let mut slot: Vec<Option<(u32, f32, f64)>> = Vec::with_capacity(self.len());
        for (j, atom) in self.high.atoms().iter().enumerate() {
            let Atom::Data(vh) = atom else {
                return Err(LearnError::param(
                    "dictionary",
                    j,
                    "exemplar detail needs data atoms",
                ));
            };
            let low: Vec<f64> = self.low.row(j).iter().map(|&v| v as f64).collect();
            let up = upsample4(&low, a);
            let (l, tr) = (self.low_norm[j] as f64, self.transfer[j] as f64);
            let mut d: Vec<f64> = vh
                .iter()
                .zip(&up)
                .map(|(&h, &u)| l * (tr * h as f64 - u))
                .collect();
            let (sum, cnt) = d
                .iter()
                .zip(&mask)
                .filter(|(_, m)| **m)
                .fold((0.0, 0usize), |(s, c), (v, _)| (s + v, c + 1));
            let mean = sum / cnt.max(1) as f64;
            d.iter_mut().for_each(|v| *v -= mean);
            let norm = d
                .iter()
                .zip(&mask)
                .filter(|(_, m)| **m)
                .map(|(v, _)| v * v)
                .sum::<f64>()
                .sqrt();
            let raw = d
                .iter()
                .zip(&mask)
                .enumerate()
                .filter(|(_, (_, m))| **m)
                .map(|(i, (v, _))| (v / gmap.as_ref().map_or(1.0, |g| g[i])).powi(2))
                .sum::<f64>();
            let row: Vec<f32> = d.iter().map(|&v| v as f32).collect();
            slot.push(match detail.push_data(&row) {
                Ok(k) => Some((k as u32, norm as f32, (raw / support).sqrt())),
                Err(relief_sparse_core::SparseError::DegenerateAtom { .. }) => None,
                Err(e) => return Err(e.into()),
            });
        }
        if detail.is_empty() {
            let mut v = vec![0f32; ah * ah];
            v[0] = 1.0;
            detail.push_data(&v)?;
        }
        // Each primitive's detail atom: one of the best-matching atoms (at most
        // DETAIL_CHOICES, |correlation| >= half the best), picked by a seeded hash of the
        // primitive. A smooth input matches many atoms almost equally; always taking the best
        // one repeats the same detail on the grid (a wallpaper of one landform).
        let n = patches.matrix.nrows();
        let picks: Vec<Option<(u32, f32, f64)>> = (0..n)
            .into_par_iter()
            .map(|i| {
                let p = patches.matrix.row(i);
                let mut best: Vec<(f32, usize)> = self
                    .low
                    .outer_iter()
                    .enumerate()
                    .filter(|(j, _)| slot[*j].is_some())
                    .map(|(j, l)| (p.dot(&l), j))
                    .collect();
                best.sort_by(|x, y| y.0.abs().total_cmp(&x.0.abs()).then(x.1.cmp(&y.1)));
                let top = best.first()?.0.abs();
                let k = best
                    .iter()
                    .take(DETAIL_CHOICES)
                    .take_while(|(c, _)| c.abs() >= 0.5 * top)
                    .count()
                    .max(1);
                let (c, j) = best[(item_seed(settings.seed, 0xde7a, i as u64) % k as u64) as usize];
                let (atom, amp, rms) = slot[j]?;
                Some((atom, if c < 0.0 { -amp } else { amp }, rms))
            })
            .collect();
        // The learned atoms are not a fair sample of the exemplar's detail (constrained learning
        // favours atoms that code the smooth input well): the amplitudes are scaled so the
        // per-sample RMS of the picked details is the exemplar's at this step's scale.
        let (e2, used) = picks
            .iter()
            .flatten()
            .fold((0.0f64, 0usize), |(s, c), (_, _, r)| (s + r * r, c + 1));
        let gain = match self.detail_rms {
            Some(target) if used > 0 && e2 > 0.0 => target / (e2 / used as f64).sqrt(),
            _ => 1.0,
        };
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let (mut atoms, mut coeffs) = (Vec::new(), Vec::new());
        for pick in picks {
            if let Some((atom, amp, _)) = pick {
                atoms.push(atom);
                coeffs.push((amp as f64 * gain) as f32);
            }
            offsets.push(atoms.len() as u32);
        }
        let layer = SparseLayer::from_parts(
            Arc::new(detail),
            Placement::Grid(fine),
            vec![0.0; n],
            offsets,
            atoms,
            coeffs,
        )?;
        let low = interpolation_layer(coarse, settings)?;
        let (cx, cy) = coarse.cell_size();
        Ok(Sct::new(
            Node::Add(vec![Node::Layer(low), Node::Layer(layer)]),
            coarse.width() * STEP_FACTOR,
            coarse.height() * STEP_FACTOR,
            (cx / f, cy / f),
        )?)
    }
}
