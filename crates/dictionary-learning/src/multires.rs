//! Multi-resolution dictionaries, amplification and sketch synthesis (guerin2016 section 5.3,
//! figures 9-12 and 16).
//!
//! # One x4 step
//! 1. The exemplar `E` (cell size of the target) is reduced x4 with the Lanczos low-pass of
//!    [`Heightfield::resample`] into `E_L`. A candidate atom is a pair of co-located patches:
//!    `L_j`, an `a x a` patch of `E_L`, and `H_j`, the `4a x 4a` patch of `E` covering the same
//!    ground, so `L_j` is `H_j` down-sampled with a proper low-pass (figure 10).
//! 2. Both are mean-removed over their support disk; `L_j` is scaled to unit norm by `1 / l_j`
//!    and `H_j` by the SAME factor (the authors' "scale H by the L norms"), so a code `x` found
//!    on `L` rebuilds, on `H`, a patch whose x4 reduction is the coded coarse patch.
//! 3. The coarse input is cut into patches on the regular grid (section 4.2), coded on `L` by
//!    Batch-OMP, and the SAME codes are placed on `H` at the corresponding fine centres
//!    (`c_fine = 4 c_coarse + 1.5`, pixel-centre alignment of a x4 reduction), giving a
//!    sparse layer of a high-resolution [`Sct`] (stored with `H_j` normalised and the
//!    coefficient multiplied by `||H_j|| / l_j`).
//!
//! The dictionary is either complete (every candidate patch of the exemplar) or learned by
//! constrained learning (problem (2)) so every atom stays a real exemplar patch and keeps its
//! high-resolution twin. Steps repeat (x16, x64, x256); each step uses the exemplar reduced to
//! that step's resolution when it is large enough, otherwise the smallest usable reduction
//! (self-similarity of relief across scales; documented, not guaranteed).
//!
//! # Defaults that depart from the paper
//! Steps 1-3 are the paper's method ([`AmplifySettings::paper`]). By default two things are
//! added: the high-frequency part of every `H` atom is scaled by the detail gain of the grid
//! ([`detail_gain`], [`AmplifySettings::normalize_detail`]) so that the blended detail has a
//! flat variance, and a residual layer ([`AmplifySettings::residual_correction`]) makes the
//! box reduction of the output match the input: the footprint of every code (the box x4
//! reduction of its `H` atom) predicts `box-down(detail layer)` on the coarse grid, the
//! difference to the input is back-projected through the bicubic x4 interpolation (4 fixed-point
//! iterations of `r += d - box(bicubic(r))`) and placed as a layer of its own patches (spacing 4,
//! centres every `R` coarse pixels). With `s = 1`, each primitive's atom is picked among the
//! near-best ones instead of always the best ([`AmplifySettings::diverse_atoms`]), so one
//! detail is not repeated along a row of primitives.
//!
//! The radius `R` (figure 11) sets the patch size `a = 2 ceil(R)` and the support: small `R`
//! follows the input closely, large `R` imposes more of the exemplar.

use std::sync::Arc;

use ndarray::Array2;
use rand::SeedableRng;
use rand::seq::index::sample;
use rand_pcg::Pcg64Mcg;
use relief_heightfield::{Heightfield, Progress};
use relief_sparse_core::{
    CentreGrid, Dictionary, Node, OmpSettings, PatchGeometry, Placement, RasterSettings, Sct,
    SparseLayer, batch_omp, extract_patches,
};
use serde::{Deserialize, Serialize};

use crate::constrained::{ConstrainedSettings, constrained_learning};
use crate::error::{LearnError, Result};
use crate::noise::item_seed;

/// Amplification factor of one step.
pub const STEP_FACTOR: usize = 4;

/// How the multi-resolution dictionary is chosen. In JSON: `"complete"` or
/// `{"learned": {"n_atoms": 256, "iterations": 3}}`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum DictionaryChoice {
    /// Every candidate patch of the exemplar (at most `max_candidates`, spread evenly).
    Complete,
    /// `n_atoms` atoms chosen among the candidates by constrained learning (problem (2)).
    Learned {
        /// Number of atoms `N`.
        n_atoms: usize,
        /// Learning iterations.
        iterations: usize,
    },
}

/// Settings of the amplify job ([`amplify`], [`MultiResDictionary::from_exemplar`]): the one
/// definition of its parameters, read by the CLI's flags, the pipeline spec (JSON, missing
/// fields take these defaults, unknown fields are an error) and tiled-run manifests.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AmplifySettings {
    /// Support radius `R` in coarse pixels (figure 11); patch side `a = 2 ceil(R)`.
    pub radius: f64,
    /// Step `S` between coarse centres, a whole number of pixels (`None`: half the radius,
    /// `max(1, floor(R / 2))`, the paper's grid step, so that about `pi R^2 / S^2` (12)
    /// primitives overlap at every point). Must satisfy `R > S / sqrt(2)`.
    pub step: Option<f64>,
    /// Number of x4 steps (1: x4, 2: x16, 3: x64, 4: x256).
    pub steps: usize,
    /// Sparsity `s` of the coding (the paper uses 1).
    pub sparsity: usize,
    /// Complete or learned dictionary.
    pub dictionary: DictionaryChoice,
    /// Spacing, in coarse exemplar pixels, between candidate patch centres.
    pub candidate_step: usize,
    /// Cap on the number of candidate patches (evenly subsampled, seeded): the atoms of a
    /// complete dictionary. The default, 65,536, keeps every patch of a 1024^2 exemplar's
    /// 256^2 reduced grid (the paper's complete dictionaries have 60,000-120,000 atoms); `s = 1`
    /// coding of more than 4096 atoms runs the exact nearest-atom search of
    /// `relief_sparse_core::nearest` (no Gram matrix).
    pub max_candidates: usize,
    /// Cap on the candidate pool of a learned dictionary (the pool is `min(max_candidates,
    /// max_learning_pool)` patches). Constrained learning's cost grows with the pool: with
    /// 65,536 candidates a default x16 run of `examples/amplify_quality.rs` was 9-18x slower
    /// for no quality gain, so learning keeps the 4096-patch pool.
    pub max_learning_pool: usize,
    /// Cap on the number of training signals of constrained learning.
    pub max_training: usize,
    /// Seed (candidate subsampling, learning initialisation).
    pub seed: u64,
    /// Not in the paper (default on): also add the coarse coding residual (input minus its
    /// reconstruction on `L`), interpolated by a second sparse layer (its complete dictionary,
    /// atoms sampled every 4 fine pixels, bicubic, centres every `R` coarse pixels), so the
    /// output stays consistent with the input.
    pub residual_correction: bool,
    /// Not in the paper (default on): normalise the detail energy of the blend. The blend
    /// `sum a_i f_i / sum a_i` of details from unrelated atoms has the variance
    /// `V(p) = sum a_i^2 / (sum a_i)^2` times a single detail's, which depends on the position
    /// `p` modulo the grid step (a visible grid) and is well below 1 (washed-out detail). The
    /// high-frequency part of every `H` atom (`H_j` minus the bicubic up-sampling of `L_j`) is
    /// multiplied by `1 / sqrt(V)` at each of its samples; since all centres lie on the same
    /// lattice this is the same factor for every atom, so it is baked into the dictionary and
    /// the blended detail has a flat, undiminished variance. The low part (what the input
    /// constrains) is untouched, so consistency is kept.
    pub normalize_detail: bool,
    /// Not in the paper (default off; on in sketch synthesis, [`crate::SynthesisSettings`]):
    /// each primitive adds the detail of its atom (`H_j` minus the bicubic up-sampling of
    /// `L_j`) at the exemplar's own amplitude in metres (times the sign of the code), on top of
    /// the bicubic interpolation of the input, instead of scaling the whole `H_j` by the code.
    /// A coded amplitude is proportional to the input's local relief, so the flat or smooth
    /// parts of a painted sketch get no detail at all; this gives them the exemplar's ridges
    /// and valleys. Steps for which the exemplar is not fine enough (self-similarity) scale the
    /// detail by the exemplar's measured amplitude ratio per x4 octave. The residual correction
    /// does not apply in this mode.
    pub exemplar_detail: bool,
    /// Not in the paper (default on): with `s = 1`, at most [`DIVERSE_MAX_ATOMS`] atoms and a
    /// coarse patch of at least [`DIVERSE_MIN_PATCH`] pixels a side (radius >= 2),
    /// each primitive's atom is picked (seeded hash of the primitive) among the atoms whose
    /// correlation with its coarse patch is at least [`DIVERSE_TOLERANCE`] times the best
    /// one (at most [`DIVERSE_CHOICES`]), not always the best. Where the input is smooth,
    /// neighbouring patches are nearly the same and the best-matching atom is the same for a
    /// whole row or column of primitives: its detail is then repeated every grid step (4 `S`
    /// fine pixels), and the blend of ~12 shifted copies of one detail is periodic along the
    /// grid's axes, the short horizontal and vertical streaks and the dotted texture of the
    /// hillshades. The coarse fit loses at most `1 - 0.9^2` of the coded energy; the residual
    /// correction restores consistency.
    pub diverse_atoms: bool,
    /// Cell size `(x, y)` in metres of the exemplar, overriding the exemplar grid's own
    /// (`None`: the grid's, e.g. read from a GeoTIFF or a sidecar). Step `t` targets the cell
    /// size of the coarse input divided by `4^(t+1)`; its atoms come from the exemplar
    /// box-down-sampled (area average) to that cell size when the exemplar is at least that
    /// fine. A step finer than the exemplar uses it at native resolution and relies on the
    /// self-similarity of relief across scales ([`StepScale::self_similar`], [`StepScale::note`]).
    pub exemplar_cell_size: Option<(f64, f64)>,
}

impl Default for AmplifySettings {
    fn default() -> Self {
        Self {
            radius: 4.0,
            step: None,
            steps: 1,
            sparsity: 1,
            dictionary: DictionaryChoice::Learned {
                n_atoms: 256,
                iterations: 3,
            },
            candidate_step: 1,
            max_candidates: 65_536,
            max_learning_pool: 4096,
            max_training: 8192,
            seed: 0,
            residual_correction: true,
            normalize_detail: true,
            exemplar_detail: false,
            diverse_atoms: true,
            exemplar_cell_size: None,
        }
    }
}

impl AmplifySettings {
    /// The paper's plain method (section 5.3) for comparison: the default settings without the
    /// residual correction, the detail-energy normalisation and the diverse atom choice.
    pub fn paper() -> Self {
        Self {
            residual_correction: false,
            normalize_detail: false,
            diverse_atoms: false,
            ..Self::default()
        }
    }

    /// Coarse grid step `S` (see [`Self::step`]).
    pub fn grid_step(&self) -> f64 {
        self.step
            .unwrap_or_else(|| (self.radius / 2.0).floor().max(1.0))
    }

    /// Validates the settings.
    pub fn check(&self) -> Result<()> {
        if !(self.radius.is_finite() && self.radius >= 1.0 && self.radius <= 32.0) {
            return Err(LearnError::param(
                "radius",
                self.radius,
                "must be in [1, 32] coarse pixels",
            ));
        }
        let step = self.grid_step();
        if !(step.is_finite() && step >= 1.0 && step.fract() == 0.0) {
            return Err(LearnError::param(
                "step",
                step,
                "must be a whole number of pixels >= 1",
            ));
        }
        if self.radius * self.radius <= step * step / 2.0 {
            return Err(LearnError::param(
                "step",
                step,
                "must be < radius * sqrt(2)",
            ));
        }
        if self.steps == 0 || self.steps > 6 {
            return Err(LearnError::param("steps", self.steps, "must be in 1..=6"));
        }
        if self.sparsity == 0 || self.sparsity > 64 {
            return Err(LearnError::param(
                "sparsity",
                self.sparsity,
                "must be in 1..=64",
            ));
        }
        if self.candidate_step == 0 {
            return Err(LearnError::param("candidate_step", 0, "must be >= 1"));
        }
        if self.max_candidates == 0 || self.max_training == 0 || self.max_learning_pool == 0 {
            return Err(LearnError::param(
                "max_candidates / max_training / max_learning_pool",
                0,
                "must be >= 1",
            ));
        }
        if let Some((x, y)) = self.exemplar_cell_size
            && !(x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0)
        {
            return Err(LearnError::param(
                "exemplar_cell_size",
                format!("{x},{y}"),
                "must be finite and > 0 metres",
            ));
        }
        if let DictionaryChoice::Learned { n_atoms, .. } = self.dictionary
            && n_atoms < self.sparsity
        {
            return Err(LearnError::param("n_atoms", n_atoms, "must be >= sparsity"));
        }
        Ok(())
    }

    /// Coarse patch side `a = 2 ceil(R)`.
    pub fn patch_size(&self) -> usize {
        2 * self.radius.ceil() as usize
    }

    /// Coarse patch geometry.
    pub fn coarse_geometry(&self) -> PatchGeometry {
        PatchGeometry {
            patch_size: self.patch_size(),
            spacing: 1.0,
            step: self.grid_step(),
            support_radius: self.radius,
        }
    }
}

/// A multi-resolution dictionary `(H, L)` in one-to-one correspondence (section 4.1).
#[derive(Debug, Clone)]
pub struct MultiResDictionary {
    /// Low-resolution atoms, unit norm, `N x a^2` (what OMP codes on).
    pub low: Array2<f32>,
    /// High-resolution atoms as a sparse-core dictionary (`4a x 4a`, spacing 1, radius `4R`).
    pub high: Arc<Dictionary>,
    /// Coefficient transfer factors `||H_j|| / l_j` (code on `L` times this = code on `H`).
    pub transfer: Vec<f32>,
    /// Centre of each atom in the coarse exemplar (pixel coordinates), for inspection.
    pub origins: Vec<[f64; 2]>,
    /// Box x4 reduction of each `H` atom per unit code on `L` (`a x a`, the coarse footprint
    /// of the fine primitive), as a dictionary: atom `j` times `footprint_scale[j]` plus
    /// `footprint_mean[j]` (the mean over the coarse support) is the footprint. Used by the
    /// residual correction to predict `box-down(output)` on the coarse grid.
    pub footprint: Arc<Dictionary>,
    /// Norms of the footprints (0 for a footprint without relief).
    pub footprint_scale: Vec<f32>,
    /// Means of the footprints over the coarse support.
    pub footprint_mean: Vec<f32>,
    /// Norms `l_j` (metres) of the mean-removed low patches before normalisation.
    pub low_norm: Vec<f32>,
    /// Target RMS (metres) of the detail a step adds with [`AmplifySettings::exemplar_detail`]:
    /// the exemplar's x4 detail at the step's scale (`None`: the atoms' own amplitudes).
    pub detail_rms: Option<f64>,
}

struct Candidates {
    low: Array2<f32>,
    high: Vec<Vec<f32>>,
    origins: Vec<[f64; 2]>,
}

fn masked_mean_removed(v: &mut [f64], mask: &[bool]) {
    let (s, c) = v
        .iter()
        .zip(mask)
        .filter(|(_, m)| **m)
        .fold((0.0, 0usize), |(s, c), (x, _)| (s + x, c + 1));
    let mean = s / c.max(1) as f64;
    v.iter_mut().for_each(|x| *x -= mean);
}

/// Keys cubic (Catmull-Rom) weights of the four taps around a fractional offset `t`.
fn keys(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        -0.5 * t3 + t2 - 0.5 * t,
        1.5 * t3 - 2.5 * t2 + 1.0,
        -1.5 * t3 + 2.0 * t2 + 0.5 * t,
        0.5 * t3 - 0.5 * t2,
    ]
}

/// x4 bicubic up-sampling of an `a x a` patch to `4a x 4a` (pixel-centre alignment, edges
/// clamped): the same interpolation as a layer of `a x a` atoms at spacing 4.
pub(crate) fn upsample4(p: &[f64], a: usize) -> Vec<f64> {
    let ah = STEP_FACTOR * a;
    let taps: Vec<([usize; 4], [f64; 4])> = (0..ah)
        .map(|o| {
            let u = (o as f64 + 0.5) / STEP_FACTOR as f64 - 0.5;
            let f = u.floor();
            let base = f as i64 - 1;
            let idx = [0, 1, 2, 3].map(|k| (base + k).clamp(0, a as i64 - 1) as usize);
            (idx, keys(u - f))
        })
        .collect();
    let mut rows = vec![0.0; a * ah];
    for r in 0..a {
        for (o, (idx, w)) in taps.iter().enumerate() {
            rows[r * ah + o] = (0..4).map(|k| w[k] * p[r * a + idx[k]]).sum();
        }
    }
    let mut out = vec![0.0; ah * ah];
    for (o, (idx, w)) in taps.iter().enumerate() {
        for c in 0..ah {
            out[o * ah + c] = (0..4).map(|k| w[k] * rows[idx[k] * ah + c]).sum();
        }
    }
    out
}

/// Detail gain `1 / sqrt(V(u))` at the samples of an `ah x ah` fine patch (offsets
/// `u = index - (ah - 1) / 2` from its centre), where `V(u) = sum a_k^2 / (sum a_k)^2` over
/// the primitives of a lattice of step `step` through the centre, with weights
/// `a_k = g(|u - k step| / radius)` of the sparse layer (see
/// [`AmplifySettings::normalize_detail`]). `V` is periodic, so the gain is the same for every
/// primitive of the lattice.
pub fn detail_gain(ah: usize, step: f64, radius: f64) -> Vec<f64> {
    let h = (ah as f64 - 1.0) / 2.0;
    let ks = |u: f64| {
        let lo = ((u - radius) / step).ceil() as i64;
        let hi = ((u + radius) / step).floor() as i64;
        lo..=hi
    };
    let mut out = vec![1.0; ah * ah];
    for r in 0..ah {
        let uy = r as f64 - h;
        for c in 0..ah {
            let ux = c as f64 - h;
            let (mut s1, mut s2) = (0.0f64, 0.0f64);
            for ky in ks(uy) {
                let dy = uy - ky as f64 * step;
                for kx in ks(ux) {
                    let dx = ux - kx as f64 * step;
                    let r2 = (dx * dx + dy * dy) / (radius * radius);
                    if r2 < 1.0 {
                        let w = (1.0 - r2).powi(3);
                        s1 += w;
                        s2 += w * w;
                    }
                }
            }
            if s1 > 0.0 && s2 > 0.0 {
                // V <= 1 always; the cap only guards sparse grids (S close to R sqrt 2).
                out[r * ah + c] = (s1 / s2.sqrt()).min(8.0);
            }
        }
    }
    out
}

/// Candidate (L, H) patch pairs of an exemplar whose size is a multiple of 4.
fn candidates(exemplar: &Heightfield, settings: &AmplifySettings) -> Result<Candidates> {
    let a = settings.patch_size();
    let ah = STEP_FACTOR * a;
    let (w, h) = (
        exemplar.width() / STEP_FACTOR * STEP_FACTOR,
        exemplar.height() / STEP_FACTOR * STEP_FACTOR,
    );
    let ex = exemplar.crop(0, 0, w, h)?;
    let low = ex.resample(w / STEP_FACTOR, h / STEP_FACTOR)?;
    let (wl, hl) = (low.width(), low.height());
    if wl < a || hl < a {
        return Err(LearnError::NotEnough {
            what: "exemplar pixels (the x4-reduced exemplar must hold one patch)",
            needed: a * STEP_FACTOR,
            got: exemplar.width().min(exemplar.height()),
        });
    }
    let mask_l = Dictionary::new(a, 1.0, settings.radius)?
        .support_mask()
        .to_vec();
    let mask_h = Dictionary::new(ah, 1.0, settings.radius * STEP_FACTOR as f64)?
        .support_mask()
        .to_vec();
    // Patch top-left corners (x0, y0) in the reduced exemplar; the H patch starts at 4 x0.
    let cs = settings.candidate_step;
    let mut corners = Vec::new();
    let mut y0 = 0;
    while y0 + a <= hl {
        let mut x0 = 0;
        while x0 + a <= wl {
            corners.push((x0, y0));
            x0 += cs;
        }
        y0 += cs;
    }
    let cap = match settings.dictionary {
        DictionaryChoice::Complete => settings.max_candidates,
        DictionaryChoice::Learned { .. } => settings.max_candidates.min(settings.max_learning_pool),
    };
    if corners.len() > cap {
        let mut rng = Pcg64Mcg::seed_from_u64(item_seed(settings.seed, 0xca, corners.len() as u64));
        let mut pick = sample(&mut rng, corners.len(), cap).into_vec();
        pick.sort_unstable();
        corners = pick.into_iter().map(|i| corners[i]).collect();
    }
    let gain = settings.normalize_detail.then(|| {
        let f = STEP_FACTOR as f64;
        detail_gain(ah, f * settings.grid_step(), f * settings.radius)
    });
    let lv = low.view();
    let hv = ex.view();
    let mut lows = Vec::with_capacity(corners.len() * a * a);
    let mut highs = Vec::with_capacity(corners.len());
    let mut origins = Vec::with_capacity(corners.len());
    let mut buf = vec![0f64; a * a];
    let mut hbuf = vec![0f64; ah * ah];
    for &(x0, y0) in &corners {
        for r in 0..a {
            for c in 0..a {
                buf[r * a + c] = lv[(y0 + r, x0 + c)] as f64;
            }
        }
        masked_mean_removed(&mut buf, &mask_l);
        let (hx, hy) = (x0 * STEP_FACTOR, y0 * STEP_FACTOR);
        for r in 0..ah {
            for c in 0..ah {
                hbuf[r * ah + c] = hv[(hy + r, hx + c)] as f64;
            }
        }
        masked_mean_removed(&mut hbuf, &mask_h);
        if let Some(gain) = &gain {
            let up = upsample4(&buf, a);
            for ((hv, &lv), &g) in hbuf.iter_mut().zip(&up).zip(gain) {
                *hv = lv + g * (*hv - lv);
            }
            masked_mean_removed(&mut hbuf, &mask_h);
        }
        lows.extend(buf.iter().map(|&v| v as f32));
        highs.push(hbuf.iter().map(|&v| v as f32).collect());
        origins.push([
            x0 as f64 + (a as f64 - 1.0) / 2.0,
            y0 as f64 + (a as f64 - 1.0) / 2.0,
        ]);
    }
    let low = Array2::from_shape_vec((corners.len(), a * a), lows)
        .map_err(|_| LearnError::param("candidates", corners.len(), "internal shape error"))?;
    Ok(Candidates {
        low,
        high: highs,
        origins,
    })
}

impl MultiResDictionary {
    /// Builds `(H, L)` from an exemplar at the TARGET resolution. `training` (coarse patches to
    /// be coded, mean-removed rows) drives constrained learning when it is asked for; the
    /// exemplar's own low patches are added to it.
    pub fn from_exemplar(
        exemplar: &Heightfield,
        training: Option<ndarray::ArrayView2<f32>>,
        settings: &AmplifySettings,
        progress: &dyn Progress,
    ) -> Result<Self> {
        Self::from_exemplars(std::slice::from_ref(exemplar), training, settings, progress)
    }

    /// [`Self::from_exemplar`] over several exemplars at once (all at the target resolution):
    /// their candidate pairs are pooled (each exemplar capped at `max_candidates`).
    pub fn from_exemplars(
        exemplars: &[Heightfield],
        training: Option<ndarray::ArrayView2<f32>>,
        settings: &AmplifySettings,
        progress: &dyn Progress,
    ) -> Result<Self> {
        settings.check()?;
        if exemplars.is_empty() {
            return Err(LearnError::NotEnough {
                what: "exemplars",
                needed: 1,
                got: 0,
            });
        }
        let mut parts = Vec::with_capacity(exemplars.len());
        for (i, e) in exemplars.iter().enumerate() {
            e.require_complete()?;
            let st = AmplifySettings {
                seed: item_seed(settings.seed, 0xe7, i as u64),
                ..*settings
            };
            parts.push(candidates(e, &st)?);
        }
        let cand = if parts.len() == 1 {
            parts.pop().ok_or(LearnError::NotEnough {
                what: "exemplars",
                needed: 1,
                got: 0,
            })?
        } else {
            let views: Vec<_> = parts.iter().map(|p| p.low.view()).collect();
            let low = ndarray::concatenate(ndarray::Axis(0), &views)
                .map_err(|_| LearnError::param("exemplars", parts.len(), "internal shape error"))?;
            let mut high = Vec::new();
            let mut origins = Vec::new();
            for p in parts {
                high.extend(p.high);
                origins.extend(p.origins);
            }
            Candidates { low, high, origins }
        };
        let norms: Vec<f64> = cand
            .low
            .outer_iter()
            .map(|r| r.iter().map(|&v| v as f64 * v as f64).sum::<f64>().sqrt())
            .collect();
        let hnorms: Vec<f64> = cand
            .high
            .iter()
            .map(|r| r.iter().map(|&v| v as f64 * v as f64).sum::<f64>().sqrt())
            .collect();
        // Usable pairs: both patches carry relief.
        let usable: Vec<usize> = (0..norms.len())
            .filter(|&i| norms[i] > 1e-6 && hnorms[i] > 1e-6)
            .collect();
        let chosen: Vec<usize> = match settings.dictionary {
            DictionaryChoice::Complete => usable.clone(),
            DictionaryChoice::Learned {
                n_atoms,
                iterations,
            } => {
                if usable.len() < n_atoms {
                    return Err(LearnError::NotEnough {
                        what: "exemplar candidate patches for the learned dictionary",
                        needed: n_atoms,
                        got: usable.len(),
                    });
                }
                let cands = cand.low.select(ndarray::Axis(0), &usable);
                let mut train_rows: Vec<f32> = Vec::new();
                let k = cands.ncols();
                if let Some(t) = training {
                    if t.ncols() != k {
                        return Err(LearnError::param(
                            "training",
                            t.ncols(),
                            "dimension differs from the coarse patch",
                        ));
                    }
                    train_rows.extend(t.iter().copied());
                }
                train_rows.extend(cands.iter().copied());
                let all = Array2::from_shape_vec((train_rows.len() / k, k), train_rows)
                    .map_err(|_| LearnError::param("training", k, "internal shape error"))?;
                let train = if all.nrows() > settings.max_training {
                    let mut rng =
                        Pcg64Mcg::seed_from_u64(item_seed(settings.seed, 0x7a, all.nrows() as u64));
                    let mut pick = sample(&mut rng, all.nrows(), settings.max_training).into_vec();
                    pick.sort_unstable();
                    all.select(ndarray::Axis(0), &pick)
                } else {
                    all
                };
                let learned = constrained_learning(
                    train.view(),
                    cands.view(),
                    &ConstrainedSettings {
                        n_atoms,
                        sparsity: settings.sparsity.min(n_atoms),
                        iterations,
                        seed: settings.seed,
                    },
                    progress,
                )?;
                learned.sources.iter().map(|&s| usable[s]).collect()
            }
        };
        if chosen.is_empty() {
            return Err(LearnError::NotEnough {
                what: "exemplar patches with relief",
                needed: 1,
                got: 0,
            });
        }
        let a = settings.patch_size();
        let mut low = Array2::<f32>::zeros((chosen.len(), a * a));
        let mut high = Dictionary::new(STEP_FACTOR * a, 1.0, settings.radius * STEP_FACTOR as f64)?;
        let mut transfer = Vec::with_capacity(chosen.len());
        let mut low_norm = Vec::with_capacity(chosen.len());
        let mut origins = Vec::with_capacity(chosen.len());
        let mut footprint = Dictionary::new(a, 1.0, settings.radius)?;
        let mut footprint_scale = Vec::with_capacity(chosen.len());
        let mut footprint_mean = Vec::with_capacity(chosen.len());
        for (j, &c) in chosen.iter().enumerate() {
            low.row_mut(j)
                .iter_mut()
                .zip(cand.low.row(c))
                .for_each(|(o, &v)| *o = (v as f64 / norms[c]) as f32);
            high.push_data(&cand.high[c])?;
            transfer.push((hnorms[c] / norms[c]) as f32);
            low_norm.push(norms[c] as f32);
            origins.push(cand.origins[c]);
            let mut b = box_down4(&cand.high[c], a);
            b.iter_mut().for_each(|v| *v /= norms[c]);
            let (mean, cnt) = b
                .iter()
                .zip(footprint.support_mask())
                .filter(|(_, m)| **m)
                .fold((0.0, 0usize), |(s, c), (v, _)| (s + v, c + 1));
            let mean = mean / cnt.max(1) as f64;
            let norm = b
                .iter()
                .map(|v| (v - mean) * (v - mean))
                .sum::<f64>()
                .sqrt();
            let row: Vec<f32> = b.iter().map(|&v| v as f32).collect();
            match footprint.push_data(&row) {
                Ok(_) => footprint_scale.push(norm as f32),
                Err(relief_sparse_core::SparseError::DegenerateAtom { .. }) => {
                    let mut v = vec![0f32; a * a];
                    v[0] = 1.0;
                    footprint.push_data(&v)?;
                    footprint_scale.push(0.0);
                }
                Err(e) => return Err(e.into()),
            }
            footprint_mean.push(mean as f32);
        }
        Ok(Self {
            low,
            high: Arc::new(high),
            transfer,
            origins,
            footprint: Arc::new(footprint),
            footprint_scale,
            footprint_mean,
            low_norm,
            detail_rms: None,
        })
    }

    /// Number of atoms `N`.
    pub fn len(&self) -> usize {
        self.transfer.len()
    }

    /// True when there is no atom.
    pub fn is_empty(&self) -> bool {
        self.transfer.is_empty()
    }

    /// One x4 step: codes `coarse` on `L`, rebuilds on `H`; the result covers
    /// `4 w x 4 h` pixels of cell size `cell / 4`.
    pub fn amplify_once(&self, coarse: &Heightfield, settings: &AmplifySettings) -> Result<Sct> {
        settings.check()?;
        coarse.require_complete()?;
        let geom = settings.coarse_geometry();
        if geom.patch_size * geom.patch_size != self.low.ncols() {
            return Err(LearnError::param(
                "radius",
                settings.radius,
                "does not match the dictionary's patch size",
            ));
        }
        let patches = extract_patches(coarse, &geom)?;
        let f = STEP_FACTOR as f64;
        let g = patches.grid;
        let fine = CentreGrid {
            origin: [f * g.origin[0] + 1.5, f * g.origin[1] + 1.5],
            step: f * g.step,
            nx: g.nx,
            ny: g.ny,
        };
        if settings.exemplar_detail {
            return self.exemplar_detail_step(coarse, &patches, fine, settings);
        }
        let codes = if settings.diverse_atoms
            && settings.sparsity == 1
            && settings.patch_size() >= DIVERSE_MIN_PATCH
            && self.len() <= DIVERSE_MAX_ATOMS
        {
            self.diverse_codes(&patches.matrix, settings.seed)?
        } else {
            batch_omp(
                self.low.view(),
                patches.matrix.view(),
                &OmpSettings {
                    sparsity: settings.sparsity.min(self.len()),
                    tolerance: None,
                },
            )?
        };
        let n = codes.n_signals();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let mut atoms = Vec::with_capacity(codes.nnz());
        let mut coeffs = Vec::with_capacity(codes.nnz());
        for i in 0..n {
            let (idx, val) = codes.signal(i);
            for (&j, &x) in idx.iter().zip(val) {
                atoms.push(j);
                coeffs.push(x * self.transfer[j as usize]);
            }
            offsets.push(atoms.len() as u32);
        }
        let layer = SparseLayer::from_parts(
            self.high.clone(),
            Placement::Grid(fine),
            patches.means.clone(),
            offsets,
            atoms,
            coeffs,
        )?;
        let (cx, cy) = coarse.cell_size();
        let root = if settings.residual_correction {
            let res = self.residual_layer(coarse, &patches, &codes, settings)?;
            Node::Add(vec![Node::Layer(layer), Node::Layer(res)])
        } else {
            Node::Layer(layer)
        };
        Ok(Sct::new(
            root,
            coarse.width() * STEP_FACTOR,
            coarse.height() * STEP_FACTOR,
            (cx / f, cy / f),
        )?)
    }
}

/// Largest dictionary coded with the diverse atom choice ([`AmplifySettings::diverse_atoms`]);
/// larger ones keep the exact nearest-atom search.
pub const DIVERSE_MAX_ATOMS: usize = 4096;
/// Smallest coarse patch side coded with the diverse atom choice: a `2 x 2` patch (radius
/// below 2) has 3 degrees of freedom once mean-removed, so 90 % of the best correlation is no
/// near match (on the 128^2 golden crop at radius 1 the slope-histogram distance grew from
/// 0.75 to 1.14 degrees); the best atom is kept there.
pub const DIVERSE_MIN_PATCH: usize = 4;
/// Relative correlation an atom needs to be a choice of [`AmplifySettings::diverse_atoms`].
pub const DIVERSE_TOLERANCE: f32 = 0.9;
/// Most atoms a primitive chooses among ([`AmplifySettings::diverse_atoms`]).
pub const DIVERSE_CHOICES: usize = 8;

impl MultiResDictionary {
    /// `s = 1` codes of the rows of `signals` with the diverse atom choice (see
    /// [`AmplifySettings::diverse_atoms`]): correlations with every `L` atom by blocked matrix
    /// products, then a seeded pick among the near-best atoms. Deterministic whatever the
    /// thread count (the pick depends only on the seed and the signal index).
    pub fn diverse_codes(
        &self,
        signals: &Array2<f32>,
        seed: u64,
    ) -> Result<relief_sparse_core::SparseCodes<f32>> {
        use rayon::prelude::*;
        if signals.ncols() != self.low.ncols() {
            return Err(LearnError::param(
                "signals",
                signals.ncols(),
                "dimension differs from the coarse patch",
            ));
        }
        const BLOCK: usize = 512;
        let n = signals.nrows();
        let lt = self.low.t();
        let picks: Vec<Option<(u32, f32, f32)>> = (0..n.div_ceil(BLOCK))
            .into_par_iter()
            .flat_map_iter(|b| {
                let rows = signals.slice(ndarray::s![b * BLOCK..((b + 1) * BLOCK).min(n), ..]);
                let corr = rows.dot(&lt);
                let mut out = Vec::with_capacity(rows.nrows());
                let mut near: Vec<(f32, u32)> = Vec::new();
                for (r, (c, x)) in corr.outer_iter().zip(rows.outer_iter()).enumerate() {
                    let i = b * BLOCK + r;
                    let best = c.iter().fold(0.0f32, |m, v| m.max(v.abs()));
                    if !(best > 0.0 && best.is_finite()) {
                        out.push(None);
                        continue;
                    }
                    near.clear();
                    near.extend(
                        c.iter()
                            .enumerate()
                            .filter(|(_, v)| v.abs() >= DIVERSE_TOLERANCE * best)
                            .map(|(j, &v)| (v, j as u32)),
                    );
                    near.sort_by(|p, q| q.0.abs().total_cmp(&p.0.abs()).then(p.1.cmp(&q.1)));
                    let k = near.len().min(DIVERSE_CHOICES);
                    let (v, j) = near[(item_seed(seed, 0xd17e, i as u64) % k as u64) as usize];
                    let e: f32 = x.iter().map(|t| t * t).sum();
                    out.push(Some((j, v, (e - v * v).max(0.0))));
                }
                out
            })
            .collect();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0usize);
        let (mut idx, mut val, mut res) = (Vec::new(), Vec::new(), Vec::with_capacity(n));
        for (i, p) in picks.into_iter().enumerate() {
            match p {
                Some((j, v, r)) => {
                    idx.push(j);
                    val.push(v);
                    res.push(r);
                }
                None => res.push(signals.row(i).iter().map(|t| t * t).sum()),
            }
            offsets.push(idx.len());
        }
        Ok(relief_sparse_core::SparseCodes::from_parts(
            offsets, idx, val, res,
        )?)
    }

    /// The coarse prediction of `box-down(H layer)`: the footprints of the codes, rasterised
    /// on the coarse grid.
    fn footprint_raster(
        &self,
        coarse: &Heightfield,
        patches: &relief_sparse_core::Patches,
        codes: &relief_sparse_core::SparseCodes<f32>,
    ) -> Result<Heightfield> {
        let n = codes.n_signals();
        let mut z = patches.means.clone();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let (mut atoms, mut coeffs) = (Vec::new(), Vec::new());
        for (i, zi) in z.iter_mut().enumerate() {
            let (idx, val) = codes.signal(i);
            let mut shift = 0.0f64;
            for (&j, &x) in idx.iter().zip(val) {
                let j = j as usize;
                shift += x as f64 * self.footprint_mean[j] as f64;
                if self.footprint_scale[j] > 0.0 {
                    atoms.push(j as u32);
                    coeffs.push(x * self.footprint_scale[j]);
                }
            }
            *zi = (*zi as f64 + shift) as f32;
            offsets.push(atoms.len() as u32);
        }
        let layer = SparseLayer::from_parts(
            self.footprint.clone(),
            Placement::Grid(patches.grid),
            z,
            offsets,
            atoms,
            coeffs,
        )?;
        Ok(Sct::new(
            Node::Layer(layer),
            coarse.width(),
            coarse.height(),
            coarse.cell_size(),
        )?
        .rasterize(&RasterSettings::default())?)
    }

    /// The residual layer (see [`AmplifySettings::residual_correction`]): the difference
    /// between the input and the predicted `box-down` of the detail layer, back-projected so
    /// that its bicubic x4 interpolation reduces (box) to it, placed as a fine-grid layer.
    fn residual_layer(
        &self,
        coarse: &Heightfield,
        patches: &relief_sparse_core::Patches,
        codes: &relief_sparse_core::SparseCodes<f32>,
        settings: &AmplifySettings,
    ) -> Result<SparseLayer> {
        let rec = self.footprint_raster(coarse, patches, codes)?;
        let d: Vec<f64> = coarse
            .as_slice()
            .iter()
            .zip(rec.as_slice())
            .map(|(a, b)| *a as f64 - *b as f64)
            .collect();
        let r = back_project(&d, coarse.width(), coarse.height());
        let res = coarse.with_data(r.iter().map(|&v| v as f32).collect())?;
        interpolation_layer(&res, settings)
    }
}

/// A smooth field interpolated x4 as a fine-grid layer of its own patches (complete
/// dictionary, atoms sampled every 4 fine pixels, centres every `R` coarse pixels): the
/// residual layer, and the low part of [`AmplifySettings::exemplar_detail`].
pub(crate) fn interpolation_layer(
    field: &Heightfield,
    settings: &AmplifySettings,
) -> Result<SparseLayer> {
    // One smooth field: primitives one radius apart interpolate it as well as a denser grid,
    // at a quarter of the primitives.
    let geom = PatchGeometry {
        step: settings.radius.floor().max(1.0),
        ..settings.coarse_geometry()
    };
    let rp = extract_patches(field, &geom)?;
    let f = STEP_FACTOR as f64;
    let fine = CentreGrid {
        origin: [f * rp.grid.origin[0] + 1.5, f * rp.grid.origin[1] + 1.5],
        step: f * rp.grid.step,
        nx: rp.grid.nx,
        ny: rp.grid.ny,
    };
    let mut dict = Dictionary::new(geom.patch_size, f, geom.support_radius * f)?;
    let mut offsets = vec![0u32];
    let (mut atoms, mut coeffs) = (Vec::new(), Vec::new());
    for row in rp.matrix.outer_iter() {
        let v: Vec<f32> = row.iter().copied().collect();
        let norm = v.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt();
        match dict.push_data(&v) {
            Ok(j) => {
                atoms.push(j as u32);
                coeffs.push(norm as f32);
            }
            Err(relief_sparse_core::SparseError::DegenerateAtom { .. }) => {}
            Err(e) => return Err(e.into()),
        }
        offsets.push(atoms.len() as u32);
    }
    if dict.is_empty() {
        // A field without relief: one harmless atom, used by nobody.
        let mut v = vec![0f32; geom.patch_size * geom.patch_size];
        v[0] = 1.0;
        dict.push_data(&v)?;
    }
    Ok(SparseLayer::from_parts(
        Arc::new(dict),
        Placement::Grid(fine),
        rp.means.clone(),
        offsets,
        atoms,
        coeffs,
    )?)
}

/// Box x4 reduction of a `4a x 4a` patch to `a x a`.
fn box_down4(p: &[f32], a: usize) -> Vec<f64> {
    let ah = STEP_FACTOR * a;
    let mut out = vec![0.0f64; a * a];
    for (r, row) in p.chunks_exact(ah).enumerate() {
        for (c, &v) in row.iter().enumerate() {
            out[(r / STEP_FACTOR) * a + c / STEP_FACTOR] += v as f64;
        }
    }
    let inv = 1.0 / (STEP_FACTOR * STEP_FACTOR) as f64;
    out.iter_mut().for_each(|v| *v *= inv);
    out
}

/// Taps of `box-down4(bicubic-up4(line))` for a line of `n` samples (the 1-D factor of the
/// separable operator): for each output, the (clamped) input indices and weights.
fn box_of_bicubic_taps(n: usize) -> Vec<Vec<(usize, f64)>> {
    (0..n)
        .map(|i| {
            let mut taps: Vec<(usize, f64)> = Vec::with_capacity(6);
            for j in 0..STEP_FACTOR {
                let u = i as f64
                    + (2.0 * j as f64 + 1.0 - STEP_FACTOR as f64) / (2.0 * STEP_FACTOR as f64);
                let f = u.floor();
                let w = keys(u - f);
                let b = f as i64 - 1;
                for (k, wk) in w.iter().enumerate() {
                    let idx = (b + k as i64).clamp(0, n as i64 - 1) as usize;
                    let wk = wk / STEP_FACTOR as f64;
                    match taps.iter_mut().find(|t| t.0 == idx) {
                        Some(t) => t.1 += wk,
                        None => taps.push((idx, wk)),
                    }
                }
            }
            taps
        })
        .collect()
}

/// Back-projection iterations of [`back_project`].
const BACK_PROJECTION_ITERATIONS: usize = 4;

/// Approximately solves `box-down4(bicubic-up4(r)) = d` on the coarse grid (`w x h`,
/// row-major) by fixed-point iterations `r += d - BU(r)` from `r = d`: the bicubic
/// interpolation of `r` then reduces (box average of the 4 x 4 fine cells) to `d`, so the
/// output's box reduction matches the input closely instead of a low-passed copy of it.
fn back_project(d: &[f64], w: usize, h: usize) -> Vec<f64> {
    use rayon::prelude::*;
    let (tx, ty) = (box_of_bicubic_taps(w), box_of_bicubic_taps(h));
    let mut r = d.to_vec();
    let mut tmp = vec![0.0; w * h];
    for _ in 0..BACK_PROJECTION_ITERATIONS {
        tmp.par_chunks_mut(w)
            .zip(r.par_chunks(w))
            .for_each(|(dst, src)| {
                for (o, taps) in dst.iter_mut().zip(&tx) {
                    *o = taps.iter().map(|&(i, wt)| wt * src[i]).sum();
                }
            });
        r.par_chunks_mut(w)
            .zip(d.par_chunks(w))
            .enumerate()
            .for_each(|(y, (row, drow))| {
                for (x, (o, dv)) in row.iter_mut().zip(drow).enumerate() {
                    let bu: f64 = ty[y].iter().map(|&(i, wt)| wt * tmp[i * w + x]).sum();
                    *o += dv - bu;
                }
            });
    }
    r
}

/// Minimum exemplar side used at a step, in units of the fine patch side.
const MIN_EXEMPLAR_PATCHES: usize = 6;

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
    let (w, h) = (exemplar_size.0 as f64, exemplar_size.1 as f64);
    (0..settings.steps)
        .map(|t| {
            let f = STEP_FACTOR.pow((t + 1) as u32) as f64;
            let target = (coarse_cell.0 / f, coarse_cell.1 / f);
            let (rx, ry) = (target.0 / exemplar_cell.0, target.1 / exemplar_cell.1);
            let fine_enough = rx >= 1.0 - SCALE_TOLERANCE && ry >= 1.0 - SCALE_TOLERANCE;
            let native = |note: String| StepScale {
                step: t,
                target_cell_size: target,
                exemplar_cell_size: exemplar_cell,
                exemplar_size,
                reduction: 1.0,
                self_similar: true,
                note,
            };
            if !fine_enough {
                return native(format!(
                    "step {}: target cell {} is finer than the exemplar's {}: exemplar used at \
                     native resolution (self-similarity across scales)",
                    t + 1,
                    fmt_cell(target),
                    fmt_cell(exemplar_cell)
                ));
            }
            let (rx, ry) = (rx.max(1.0), ry.max(1.0));
            // The largest reduction that keeps the exemplar `min_side` cells wide.
            let limit = (w / min_side).min(h / min_side).max(1.0);
            let shrink = (limit / rx.max(ry)).min(1.0);
            let (kx, ky) = ((rx * shrink).max(1.0), (ry * shrink).max(1.0));
            let size = (
                ((w / kx).round() as usize).max(1),
                ((h / ky).round() as usize).max(1),
            );
            let cell = (
                exemplar_cell.0 * w / size.0 as f64,
                exemplar_cell.1 * h / size.1 as f64,
            );
            let reduced = kx > 1.0 + SCALE_TOLERANCE || ky > 1.0 + SCALE_TOLERANCE;
            let (size, cell) = if reduced {
                (size, cell)
            } else {
                (exemplar_size, exemplar_cell)
            };
            let self_similar = shrink < 1.0 - SCALE_TOLERANCE;
            let note = if self_similar {
                format!(
                    "step {}: target cell {}, exemplar too small to be reduced that far: \
                     box-down-sampled x{kx:.3} to {} only (self-similarity across scales)",
                    t + 1,
                    fmt_cell(target),
                    fmt_cell(cell)
                )
            } else if reduced {
                format!(
                    "step {}: target cell {}: exemplar box-down-sampled x{kx:.3} to {} ({} x {})",
                    t + 1,
                    fmt_cell(target),
                    fmt_cell(cell),
                    size.0,
                    size.1
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
                exemplar_cell_size: cell,
                exemplar_size: size,
                reduction: if reduced { kx } else { 1.0 },
                self_similar,
                note,
            }
        })
        .collect()
}

/// Area-consistent box down-sampling of `hf` to `w x h` cells: every output cell is the
/// exact area average of the input cells it covers (fractional overlaps weighted), so the
/// mean over any output region equals that of the input over the same ground. The cell size
/// is scaled to keep the extent.
pub fn box_resample(hf: &Heightfield, w: usize, h: usize) -> Result<Heightfield> {
    let (iw, ih) = (hf.width(), hf.height());
    if w == 0 || h == 0 || w > iw || h > ih {
        return Err(LearnError::param(
            "box_resample size",
            format!("{w}x{h}"),
            "must be in 1..=the input size (down-sampling only)",
        ));
    }
    // Per output index, the (input index, weight) taps of the 1-D area average.
    let taps = |n_in: usize, n_out: usize| -> Vec<Vec<(usize, f64)>> {
        let s = n_in as f64 / n_out as f64;
        (0..n_out)
            .map(|i| {
                let (a, b) = (i as f64 * s, ((i + 1) as f64 * s).min(n_in as f64));
                let lo = a.floor() as usize;
                let hi = (b.ceil() as usize).min(n_in);
                (lo..hi)
                    .filter_map(|j| {
                        let ov = (b.min((j + 1) as f64) - a.max(j as f64)) / s;
                        (ov > 0.0).then_some((j, ov))
                    })
                    .collect()
            })
            .collect()
    };
    let (tx, ty) = (taps(iw, w), taps(ih, h));
    let src = hf.as_slice();
    let mut rows = vec![0.0f64; ih * w];
    for y in 0..ih {
        let line = &src[y * iw..(y + 1) * iw];
        for (x, t) in tx.iter().enumerate() {
            rows[y * w + x] = t.iter().map(|&(j, wt)| wt * line[j] as f64).sum();
        }
    }
    let data = Array2::from_shape_fn((h, w), |(y, x)| {
        ty[y]
            .iter()
            .map(|&(j, wt)| wt * rows[j * w + x])
            .sum::<f64>() as f32
    });
    let (fx, fy) = (iw as f64 / w as f64, ih as f64 / h as f64);
    let (cx, cy) = hf.cell_size();
    let out = Heightfield::from_array(data, cx * fx, cy * fy)?;
    Ok(out.with_georef(hf.georef().map(|g| g.window(0.0, 0.0, fx, fy))))
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
    let mut steps = Vec::with_capacity(settings.steps);
    let sct = amplify_observed(coarse, exemplar, settings, progress, &mut |r| {
        steps.push(r.exemplar.clone());
    })?;
    Ok((sct, AmplifyFigures { steps }))
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
    let mut result = None;
    let mut octave_ratio = None;
    for (t, scale) in plan.iter().enumerate() {
        let ex = if scale.exemplar_size == (native.width(), native.height()) {
            native.clone()
        } else {
            box_resample(&native, scale.exemplar_size.0, scale.exemplar_size.1)?
        };
        let step_settings = AmplifySettings {
            seed: item_seed(settings.seed, 0x57e9, t as u64),
            ..*settings
        };
        // Training signals for constrained learning (subsampled to `max_training` anyway):
        // patches one radius apart are as representative as the coding grid's, at a quarter
        // of the extraction cost.
        let training = extract_patches(
            &current,
            &PatchGeometry {
                step: settings.grid_step().max(settings.radius.floor().max(1.0)),
                ..settings.coarse_geometry()
            },
        )?;
        let mut dict = MultiResDictionary::from_exemplar(
            &ex,
            Some(training.matrix.view()),
            &step_settings,
            progress,
        )?;
        if settings.exemplar_detail {
            // The exemplar's x4 detail at this step's scale; under self-similarity, the
            // exemplar's detail one x4 octave coarser is `ratio` times larger.
            // `octaves` x4 octaves between the exemplar grid used and the target (negative
            // when the target is finer than the exemplar).
            let octaves = (scale.target_cell_size.0 / scale.exemplar_cell_size.0).ln()
                / (STEP_FACTOR as f64).ln();
            let gain = if scale.self_similar && octaves.abs() > SCALE_TOLERANCE {
                let ratio =
                    *octave_ratio.get_or_insert_with(|| crate::sketch::octave_ratio(exemplar));
                ratio.powf(octaves)
            } else {
                1.0
            };
            dict.detail_rms = crate::sketch::x4_detail_rms(&ex).map(|r| r * gain);
        }
        let sct = dict.amplify_once(&current, &step_settings)?;
        observe(&StepReport {
            step: t,
            input: &current,
            output: &sct,
            exemplar: scale,
        });
        if t + 1 < settings.steps {
            current = sct.rasterize(&RasterSettings::default())?;
        }
        result = Some(sct);
    }
    // The result covers the coarse extent with cells 4^steps times smaller (pixel-is-area).
    let f = 1.0 / STEP_FACTOR.pow(settings.steps as u32) as f64;
    let georef = coarse.georef().map(|g| g.window(0.0, 0.0, f, f));
    result
        .map(|s| s.with_georef(georef))
        .ok_or(LearnError::param("steps", 0, "must be >= 1"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_resample_is_area_consistent() {
        let hf = Heightfield::from_fn(30, 21, 2.0, 3.0, |x, y| {
            (x as f32 * 0.7).sin() * 10.0 + y as f32 * 1.5 + ((x * y) % 7) as f32
        });
        // Integer factor: the exact box average.
        let a = box_resample(&hf, 10, 7).unwrap();
        let b = hf.downsample_box(3).unwrap();
        assert_eq!(a.cell_size(), (6.0, 9.0));
        for (p, q) in a.as_slice().iter().zip(b.as_slice()) {
            assert!((p - q).abs() < 1e-4, "{p} {q}");
        }
        // Fractional factor: the mean (over the whole extent) and the extent are kept.
        let c = box_resample(&hf, 13, 8).unwrap();
        let mean = |h: &Heightfield| {
            h.as_slice().iter().map(|&v| v as f64).sum::<f64>() / h.as_slice().len() as f64
        };
        assert!((mean(&c) - mean(&hf)).abs() < 1e-4);
        assert!((c.cell_size().0 * 13.0 - 60.0).abs() < 1e-9);
        assert!((c.cell_size().1 * 8.0 - 63.0).abs() < 1e-9);
        assert!(box_resample(&hf, 31, 21).is_err());
        assert!(box_resample(&hf, 0, 5).is_err());
    }

    #[test]
    fn exemplar_plan_relates_cell_sizes() {
        let s = AmplifySettings {
            steps: 3,
            radius: 2.0,
            ..AmplifySettings::default()
        };
        // Coarse 120 m, exemplar 10 m (1000 x 800): targets 30, 7.5, 1.875 m.
        let plan = exemplar_plan((120.0, 120.0), (1000, 800), (10.0, 10.0), &s);
        assert_eq!(plan.len(), 3);
        assert!((plan[0].reduction - 3.0).abs() < 1e-9 && !plan[0].self_similar);
        assert_eq!(plan[0].exemplar_size, (333, 267));
        assert!((plan[0].target_cell_size.0 - 30.0).abs() < 1e-9);
        for p in &plan[1..] {
            assert!(p.self_similar && p.reduction == 1.0, "{p:?}");
            assert_eq!(p.exemplar_size, (1000, 800));
            assert!(p.note.contains("finer than the exemplar"), "{}", p.note);
        }
        // Too small to be reduced to 30 m (min side 6 * 16 = 96 cells): reduced as far as
        // it can be, and said so.
        let small = exemplar_plan((120.0, 120.0), (200, 200), (10.0, 10.0), &s);
        assert!(small[0].self_similar && small[0].exemplar_size.0 >= 96);
        assert!((small[0].reduction - 200.0 / 96.0).abs() < 1e-9);
        assert!(small[0].note.contains("too small"), "{}", small[0].note);
        // Anisotropic cells.
        let an = exemplar_plan((160.0, 80.0), (800, 800), (10.0, 5.0), &s);
        assert_eq!(an[0].exemplar_size, (200, 200));
        assert!((an[0].exemplar_cell_size.0 - 40.0).abs() < 1e-9);
        assert!((an[0].exemplar_cell_size.1 - 20.0).abs() < 1e-9);
    }
}
