//! Settings of the synthesis, validated once by [`Settings::check`].

use serde::{Deserialize, Serialize};

use relief_heightfield::check_field;
use relief_heightfield::param::{ensure, in_left_open, in_range};

use crate::error::{PatchSynthError, Result};

/// How the seam through an overlap region is found (section 3.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CutMethod {
    /// Minimum-error boundary cut by dynamic programming (globally optimal path; the default).
    DynamicProgramming,
    /// Greedy path of local decisions (Efros and Freeman 2001), kept for comparison.
    Greedy,
}

/// How the transition across the seam is blended after the cut (section 3.3).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Blend {
    /// Plain cut and paste.
    None,
    /// Smooth feathering: a smoothstep weight across the seam over `radius` cells each side.
    Feather {
        /// Half-width of the transition in cells (> 0).
        radius: f32,
    },
    /// Poisson blending over the overlap region (Zhou et al. 2007): the overlap is re-solved so
    /// that its gradients follow the old terrain on the old side of the cut, the new patch on
    /// the new side and their average across the cut, with the surrounding terrain as boundary.
    Poisson {
        /// Maximum conjugate-gradient iterations per patch.
        max_iterations: usize,
    },
    /// Screened Poisson blending over the whole patch (a departure from the paper): the same
    /// guidance gradients, with the patch interior free too and a screening term that pulls
    /// every cell towards the cut-and-paste value, so a height offset between the new patch
    /// and the terrain around it decays over about `decay` cells inside the patch instead of
    /// being squeezed into the overlap (the steps of patches at slightly different heights on
    /// a plateau).
    Screened {
        /// Maximum conjugate-gradient iterations per patch.
        max_iterations: usize,
        /// Decay length in cells of a boundary offset (> 0): the screening weight is
        /// `1 / decay^2`.
        decay: f32,
    },
}

/// Parameters of the guided patch-based synthesis. Use as
/// `Settings { patch_size: 48, ..Default::default() }`; [`Settings::check`] validates them once.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Settings {
    /// Side of the square patches in cells.
    pub patch_size: usize,
    /// Width of the overlap between neighbouring patches in cells (< `patch_size` / 2).
    pub overlap: usize,
    /// Weight `alpha` of the guide distance `G` in equation (1).
    pub alpha: f32,
    /// Weight `beta` of the overlap distance `O` in equation (1).
    pub beta: f32,
    /// Weight `gamma` of the cut cost `P` in equation (1).
    pub gamma: f32,
    /// Largest vertical translation `lambda` in metres (section 3.4): a translation from
    /// equation (3) with `|h| > lambda` is not applied. 0 disables translations.
    pub lambda: f32,
    /// `N` of the `N x N` block-average descriptor (section 3.2; the paper uses 3).
    pub blocks: usize,
    /// The guide distance `G` compares `guide_cells x guide_cells` cell means of patch and guide.
    pub guide_cells: usize,
    /// Gaussian sigma in cells of the low-pass the guide distance `G` sees of a candidate
    /// patch (a departure from the paper, which compares the patch's own cell means). A guide
    /// only carries the low frequencies, so comparing it with the patch's detail too favours
    /// flat patches wherever the guide is smooth; with the low-pass, `G` measures only what the
    /// guide says and the detail comes from the overlap term. The same low-pass gives the block
    /// descriptors that rank the clusters against the guide and pick the guide's own candidates
    /// (section 3.2): with the paper's raw descriptors a smooth guide (a sketch) probes only
    /// clusters of flat patches, and the output is flatter than the exemplar (Grand Canyon
    /// under the painted sketch of `examples/guided_quality.rs`: mean slope 12.4-13.2 deg
    /// against 16.0 over 5 seeds; with low-passed descriptors 15.2-16.2). `None` (the default): the
    /// guide's own [`crate::guide::smoothness_scale`], at most `patch_size` (about 1.1 times
    /// the sigma of a Gaussian-blurred guide, the right scale for blurred DEMs and sketches);
    /// `Some(0.0)`: the paper, better for band-limited guides such as
    /// [`crate::guide::lowpass_resample`]'s, whose smoothness scale over-estimates their blur.
    pub guide_lowpass: Option<f32>,
    /// Number of k-means clusters keying the block-descriptor hash table (section 3.5).
    pub kmeans_clusters: usize,
    /// Lloyd iterations of every k-means run.
    pub kmeans_iterations: usize,
    /// Dimensions kept by the PCA of the overlap regions: one of 4, 6, 8, 12, 16.
    pub pca_dims: usize,
    /// Number of exemplar overlap strips sampled to fit each PCA basis.
    pub pca_samples: usize,
    /// Nearest neighbours taken from each probed bucket's kd-tree.
    pub knn: usize,
    /// Each probed bucket's kd-tree is asked for `knn * rerank` neighbours in PCA space, which
    /// are re-ranked by their exact full-resolution overlap error (means removed) and the best
    /// `knn` kept: the PCA keeps only part of the overlap's variance, so its own top `knn`
    /// misses most of the exact best (1 = no re-ranking).
    pub rerank: usize,
    /// Clusters are probed in order of closeness to the guide descriptor until this many
    /// candidate patches are gathered (at least one cluster is always probed).
    pub probe_candidates: usize,
    /// Candidates kept after the first step (`alpha G + beta O`) for the cut computation.
    pub survivors: usize,
    /// Final choice: uniformly among survivors whose energy is within `(1 + tolerance)` of the
    /// best (seeded, so deterministic).
    pub choice_tolerance: f32,
    /// Patch-reuse penalty: a survivor's energy is multiplied by `1 + reuse_penalty * n`, where
    /// `n` counts the blocks within `reuse_radius` blocks already filled from a source patch
    /// less than half a patch away from the survivor's (same exemplar), so one source region
    /// does not wallpaper an area (0 = off, the paper's choice).
    pub reuse_penalty: f32,
    /// Neighbourhood of the reuse penalty, in blocks (Chebyshev distance).
    pub reuse_radius: usize,
    /// Minimum number of candidate patches per guide block (section 4; the paper asks 500).
    pub min_candidates: usize,
    /// When set, the validation asks for `min(min_candidates, ceil(share * patches))` with
    /// `patches` the index's candidate patch count: 500 is 0.25 % of the 201,601 patches of
    /// a 512 x 512 exemplar (patch 64) but 5 % of the ~10,000 of a 128 x 128 crop (patch 16),
    /// and 89 % of the 561 of a 96 x 80 crop, where it fails blocks that have ample
    /// candidates for their size. Default `0.0025` (500 / 201,601: the paper's count where
    /// its exemplar size gives it, the same share of smaller exemplar sets; a departure from
    /// the paper's absolute count on small exemplars, which it does not discuss); `None` or
    /// `1`: the absolute `min_candidates`.
    pub min_candidates_share: Option<f32>,
    /// RMS tolerance in metres of the block-descriptor match counted by the validation; `None`
    /// uses 50 % of the guide's (or, without a guide, the exemplars') standard deviation.
    pub validation_tolerance: Option<f32>,
    /// When true, [`crate::synthesize`] refuses to run on inputs that fail the validation.
    pub enforce_validation: bool,
    /// Exemplar patch positions are taken every `exemplar_stride` cells (1 = every patch).
    pub exemplar_stride: usize,
    /// Seam search method.
    pub cut: CutMethod,
    /// Seam blending.
    pub blend: Blend,
    /// Passes of crease smoothing after the blending: the cells within one cell of each new
    /// cut are moved a third of the way towards the mean of their four neighbours, which removes the
    /// curvature crease a cut leaves even when the gradients agree (0 = off).
    pub crease_passes: usize,
    /// Seed of every random choice (k-means initialisation, PCA sampling, patch choice).
    pub seed: u64,
}

/// Default [`Settings::min_candidates_share`]: the paper's 500 candidates over the 201,601
/// patches of a 512 x 512 exemplar with 64-cell patches.
pub const DEFAULT_MIN_CANDIDATES_SHARE: f32 = 500.0 / 201_601.0;

impl Default for Settings {
    fn default() -> Self {
        Self {
            patch_size: 64,
            overlap: 16,
            alpha: 3.0,
            beta: 1.0,
            gamma: 0.5,
            lambda: 50.0,
            blocks: 3,
            guide_cells: 8,
            guide_lowpass: None,
            kmeans_clusters: 16,
            kmeans_iterations: 12,
            pca_dims: 8,
            pca_samples: 3000,
            knn: 24,
            rerank: 10,
            probe_candidates: 1500,
            survivors: 8,
            choice_tolerance: 0.05,
            reuse_penalty: 0.5,
            reuse_radius: 3,
            min_candidates: 500,
            min_candidates_share: Some(DEFAULT_MIN_CANDIDATES_SHARE),
            validation_tolerance: None,
            enforce_validation: true,
            exemplar_stride: 1,
            cut: CutMethod::DynamicProgramming,
            blend: Blend::Poisson {
                max_iterations: 300,
            },
            crease_passes: 1,
            seed: 0,
        }
    }
}

/// PCA dimensions the kd-trees are compiled for.
pub const SUPPORTED_PCA_DIMS: [usize; 5] = [4, 6, 8, 12, 16];

impl Settings {
    /// Validates every field; the error names the first offending field and its value.
    pub fn check(&self) -> Result<()> {
        self.check_geometry()?;
        self.check_energy()?;
        self.check_search()?;
        self.check_blend()
    }

    /// Patch, overlap, descriptor blocks, k-means and PCA sizes.
    fn check_geometry(&self) -> Result<()> {
        check_field!(self, patch_size, 8..=1024, "must be in 8..=1024")?;
        if self.overlap == 0 || 2 * self.overlap >= self.patch_size {
            return Err(PatchSynthError::setting(
                "overlap",
                self.overlap,
                format!(
                    "must be >= 1 and < patch_size / 2 = {}",
                    self.patch_size / 2
                ),
            ));
        }
        let p = self.patch_size;
        check_field!(self, blocks, 1..=p, "must be in 1..=patch_size")?;
        check_field!(self, guide_cells, 1..=p, "must be in 1..=patch_size")?;
        if let Some(s) = self.guide_lowpass {
            in_range(
                "guide_lowpass",
                s,
                0.0..=1024.0,
                "must be in 0..=1024 cells",
            )?;
        }
        check_field!(self, kmeans_clusters, 1..=4096, "must be in 1..=4096")?;
        check_field!(self, kmeans_iterations, 1.., "must be >= 1")?;
        let dims = self.pca_dims;
        let ok = SUPPORTED_PCA_DIMS.contains(&dims);
        ensure(ok, "pca_dims", dims, "must be one of 4, 6, 8, 12, 16")?;
        let features = crate::grid::Layouts::new(self.patch_size, self.overlap)
            .rects
            .iter()
            .map(Vec::len)
            .min()
            .unwrap_or(0);
        if self.pca_dims > features {
            return Err(PatchSynthError::setting(
                "pca_dims",
                self.pca_dims,
                format!(
                    "exceeds the {features} overlap features of a {} x {} overlap",
                    self.patch_size, self.overlap
                ),
            ));
        }
        check_field!(self, pca_samples, 2 * dims.., "must be >= 2 * pca_dims")?;
        Ok(())
    }

    /// Energy weights and the largest vertical translation (finite, >= 0).
    fn check_energy(&self) -> Result<()> {
        for (name, v) in [
            ("alpha", self.alpha),
            ("beta", self.beta),
            ("gamma", self.gamma),
        ] {
            check_non_negative(name, v)?;
        }
        // The weights are finite and >= 0 here, so a sum that is not > 0 means all zero.
        let any = self.alpha + self.beta + self.gamma > 0.0;
        ensure(
            any,
            "alpha",
            self.alpha,
            "alpha, beta and gamma are all zero",
        )?;
        check_non_negative("lambda", self.lambda)
    }

    /// Counts of the candidate search, the reuse penalty and the validation thresholds.
    fn check_search(&self) -> Result<()> {
        for (name, v) in [
            ("knn", self.knn),
            ("rerank", self.rerank),
            ("probe_candidates", self.probe_candidates),
            ("survivors", self.survivors),
            ("min_candidates", self.min_candidates),
            ("exemplar_stride", self.exemplar_stride),
        ] {
            in_range(name, v, 1.., "must be >= 1")?;
        }
        check_non_negative("choice_tolerance", self.choice_tolerance)?;
        check_field!(self, reuse_penalty, 0.0..=100.0, "must be in [0, 100]")?;
        check_field!(self, reuse_radius, ..=64, "must be <= 64 blocks")?;
        if let Some(f) = self.min_candidates_share {
            in_left_open("min_candidates_share", f, (0.0, 1.0), "must be in (0, 1]")?;
        }
        if let Some(t) = self.validation_tolerance {
            let ok = t.is_finite() && t > 0.0;
            ensure(ok, "validation_tolerance", t, "must be finite and > 0")?;
        }
        Ok(())
    }

    /// The blend's parameters.
    fn check_blend(&self) -> Result<()> {
        match self.blend {
            Blend::Feather { radius } if !(radius.is_finite() && radius > 0.0) => {
                return Err(PatchSynthError::setting(
                    "blend.radius",
                    radius,
                    "must be finite and > 0",
                ));
            }
            Blend::Screened { decay, .. } if !(decay.is_finite() && decay > 0.0) => {
                return Err(PatchSynthError::setting(
                    "blend.decay",
                    decay,
                    "must be finite and > 0",
                ));
            }
            Blend::Poisson { max_iterations: 0 }
            | Blend::Screened {
                max_iterations: 0, ..
            } => {
                return Err(PatchSynthError::setting(
                    "blend.max_iterations",
                    0,
                    "must be >= 1",
                ));
            }
            _ => {}
        }
        Ok(())
    }

    /// Candidates per guide block the validation asks for, out of `patches` candidate patches
    /// (see [`Settings::min_candidates_share`]).
    pub fn required_candidates(&self, patches: usize) -> usize {
        match self.min_candidates_share {
            Some(f) => self
                .min_candidates
                .min(((f as f64 * patches as f64).ceil() as usize).max(1)),
            None => self.min_candidates,
        }
    }

    /// Step between patch origins on the synthesis grid (`patch_size - overlap`).
    pub fn step(&self) -> usize {
        self.patch_size - self.overlap
    }
}

/// A weight or tolerance: finite and >= 0.
fn check_non_negative(name: &'static str, v: f32) -> Result<()> {
    Ok(ensure(
        v.is_finite() && v >= 0.0,
        name,
        v,
        "must be finite and >= 0",
    )?)
}
