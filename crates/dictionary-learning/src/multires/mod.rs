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
//! difference to the input is back-projected through the x4 interpolation (4 fixed-point
//! iterations of `r += d - box(interp(r))`) and placed as a field node on the coarse grid,
//! interpolated with Lanczos-3 ([`AmplifySettings::residual_kernel`]; the Keys cubic left a
//! row-and-column pattern of the input's finest relief). With `s = 1`, each primitive's atom is picked among the
//! near-best ones instead of always the best ([`AmplifySettings::diverse_atoms`]), so one
//! detail is not repeated along a row of primitives.
//!
//! The radius `R` (figure 11) sets the patch size `a = 2 ceil(R)` and the support: small `R`
//! follows the input closely, large `R` imposes more of the exemplar.

use relief_heightfield::param::in_range;
use std::sync::Arc;

use ndarray::Array2;
use rand::SeedableRng;
use rand::seq::index::sample;
use rand_pcg::Pcg64Mcg;
use relief_heightfield::{Heightfield, Progress};
use relief_sparse_core::{
    CentreGrid, Dictionary, Field, Node, OmpSettings, PatchGeometry, Placement, RasterSettings,
    Sct, SparseLayer, extract_patch_rows, extract_patches,
};
use serde::{Deserialize, Serialize};

use crate::constrained::{ConstrainedSettings, constrained_learning};
use crate::error::{LearnError, Result};
use crate::noise::item_seed;

mod build;
mod detail;
mod kernels;
mod last;
mod plan;
mod step;

pub(crate) use self::detail::{octave_ratio, x4_detail_rms};
pub use self::kernels::detail_gain;
pub(crate) use self::kernels::upsample4;
use self::kernels::{back_project, box_down4};
pub use self::last::LastStep;
pub(crate) use self::plan::grid_at;
pub use self::plan::{
    AmplifyFigures, StepReport, StepScale, amplify, amplify_observed, amplify_with_figures,
    box_resample, exemplar_plan, prepare_last_step,
};
pub(crate) use self::step::interpolation_layer;
pub use self::step::{DIVERSE_CHOICES, DIVERSE_MAX_ATOMS, DIVERSE_MIN_PATCH, DIVERSE_TOLERANCE};

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

impl DictionaryChoice {
    /// Learning iterations of the default learned dictionary (and of `--atoms N`).
    pub const DEFAULT_ITERATIONS: usize = 3;

    /// Number of atoms of a learned dictionary; 0 for the complete one (the CLI's `--atoms 0`).
    pub const fn n_atoms(&self) -> usize {
        match self {
            Self::Complete => 0,
            Self::Learned { n_atoms, .. } => *n_atoms,
        }
    }

    /// `n_atoms` atoms learned in [`Self::DEFAULT_ITERATIONS`] iterations.
    pub const fn learned_default(n_atoms: usize) -> Self {
        Self::learned(n_atoms, Self::DEFAULT_ITERATIONS)
    }

    /// [`DictionaryChoice::Learned`]: `n_atoms` atoms learned in `iterations` iterations.
    pub const fn learned(n_atoms: usize, iterations: usize) -> Self {
        DictionaryChoice::Learned {
            n_atoms,
            iterations,
        }
    }
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
    /// reconstruction on `L`), back-projected and interpolated x4 by a field node with
    /// [`Self::residual_kernel`], so the output stays consistent with the input.
    pub residual_correction: bool,
    /// Interpolation of the residual ([`Self::residual_correction`]; default Lanczos-3). The
    /// residual carries most of the input's content near its Nyquist frequency (the blend of
    /// single atoms is smooth); the Keys cubic keeps that content at the coarse samples and
    /// smooths it between them, so the output's high-pass energy swung with the phase modulo
    /// 4 (alps x4: 1.32x the mean on the sample rows, 0.68x between); Lanczos-3 keeps it within
    /// a few percent, as in the truth.
    pub residual_kernel: relief_heightfield::Kernel,
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
    /// With `s = 1` and more than 4096 atoms (a complete dictionary of a large exemplar, when
    /// [`Self::diverse_atoms`] does not apply): clusters of the inverted-list atom index
    /// searched per primitive (`relief_sparse_core::code_indexed`; 0 = the exact
    /// search, about 15x slower at 65,536 atoms). Default
    /// [`relief_sparse_core::DEFAULT_INDEX_PROBES`].
    pub index_probes: usize,
}

impl Default for AmplifySettings {
    fn default() -> Self {
        Self {
            radius: 4.0,
            step: None,
            steps: 1,
            sparsity: 1,
            dictionary: DictionaryChoice::learned_default(256),
            candidate_step: 1,
            max_candidates: 65_536,
            max_learning_pool: 4096,
            max_training: 8192,
            seed: 0,
            residual_correction: true,
            residual_kernel: relief_heightfield::Kernel::Lanczos3,
            normalize_detail: true,
            exemplar_detail: false,
            diverse_atoms: true,
            exemplar_cell_size: None,
            index_probes: relief_sparse_core::DEFAULT_INDEX_PROBES,
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
        in_range("steps", self.steps, 1..=6, "must be in 1..=6")?;
        in_range("sparsity", self.sparsity, 1..=64, "must be in 1..=64")?;
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

#[cfg(test)]
mod tests;
