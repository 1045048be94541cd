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

use crate::constrained::{ConstrainedSettings, constrained_learning};
use crate::error::{LearnError, Result};
use crate::noise::item_seed;

/// Amplification factor of one step.
pub const STEP_FACTOR: usize = 4;

/// How the multi-resolution dictionary is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
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

/// Settings of [`amplify`] and [`MultiResDictionary::from_exemplar`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AmplifySettings {
    /// Support radius `R` in coarse pixels (figure 11); patch side `a = 2 ceil(R)`.
    pub radius: f64,
    /// Step `S` between coarse centres (`None`: `R`). Must satisfy `R > S / sqrt(2)`.
    pub step: Option<f64>,
    /// Number of x4 steps (1: x4, 2: x16, 3: x64, 4: x256).
    pub steps: usize,
    /// Sparsity `s` of the coding (the paper uses 1).
    pub sparsity: usize,
    /// Complete or learned dictionary.
    pub dictionary: DictionaryChoice,
    /// Spacing, in coarse exemplar pixels, between candidate patch centres.
    pub candidate_step: usize,
    /// Cap on the number of candidate patches (evenly subsampled, seeded).
    pub max_candidates: usize,
    /// Cap on the number of training signals of constrained learning.
    pub max_training: usize,
    /// Seed (candidate subsampling, learning initialisation).
    pub seed: u64,
    /// Not in the paper: also add the coarse coding residual (input minus its reconstruction
    /// on `L`), interpolated by a second sparse layer (its complete dictionary, atoms sampled
    /// every 4 fine pixels, bicubic), so the output stays consistent with the input.
    pub residual_correction: bool,
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
            max_candidates: 4096,
            max_training: 8192,
            seed: 0,
            residual_correction: false,
        }
    }
}

impl AmplifySettings {
    /// Validates the settings.
    pub fn check(&self) -> Result<()> {
        if !(self.radius.is_finite() && self.radius >= 1.0 && self.radius <= 32.0) {
            return Err(LearnError::param(
                "radius",
                self.radius,
                "must be in [1, 32] coarse pixels",
            ));
        }
        let step = self.step.unwrap_or(self.radius);
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
        if self.max_candidates == 0 || self.max_training == 0 {
            return Err(LearnError::param(
                "max_candidates / max_training",
                0,
                "must be >= 1",
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
            step: self.step.unwrap_or(self.radius),
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
    if corners.len() > settings.max_candidates {
        let mut rng = Pcg64Mcg::seed_from_u64(item_seed(settings.seed, 0xca, corners.len() as u64));
        let mut pick = sample(&mut rng, corners.len(), settings.max_candidates).into_vec();
        pick.sort_unstable();
        corners = pick.into_iter().map(|i| corners[i]).collect();
    }
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
        let mut origins = Vec::with_capacity(chosen.len());
        for (j, &c) in chosen.iter().enumerate() {
            low.row_mut(j)
                .iter_mut()
                .zip(cand.low.row(c))
                .for_each(|(o, &v)| *o = (v as f64 / norms[c]) as f32);
            high.push_data(&cand.high[c])?;
            transfer.push((hnorms[c] / norms[c]) as f32);
            origins.push(cand.origins[c]);
        }
        Ok(Self {
            low,
            high: Arc::new(high),
            transfer,
            origins,
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
        let codes = batch_omp(
            self.low.view(),
            patches.matrix.view(),
            &OmpSettings {
                sparsity: settings.sparsity.min(self.len()),
                tolerance: None,
            },
        )?;
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
        let f = STEP_FACTOR as f64;
        let g = patches.grid;
        let fine = CentreGrid {
            origin: [f * g.origin[0] + 1.5, f * g.origin[1] + 1.5],
            step: f * g.step,
            nx: g.nx,
            ny: g.ny,
        };
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
            let res = self.residual_layer(coarse, &patches, &codes, settings, fine)?;
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

impl MultiResDictionary {
    /// The coding residual of `coarse` on `L` as a fine-grid layer (see
    /// [`AmplifySettings::residual_correction`]).
    fn residual_layer(
        &self,
        coarse: &Heightfield,
        patches: &relief_sparse_core::Patches,
        codes: &relief_sparse_core::SparseCodes<f32>,
        settings: &AmplifySettings,
        fine: CentreGrid,
    ) -> Result<SparseLayer> {
        let geom = settings.coarse_geometry();
        let low =
            Dictionary::from_matrix(self.low.view(), geom.patch_size, 1.0, geom.support_radius)?;
        let layer = SparseLayer::from_codes(
            Arc::new(low),
            Placement::Grid(patches.grid),
            patches.means.clone(),
            codes,
        )?;
        let rec = Sct::new(
            Node::Layer(layer),
            coarse.width(),
            coarse.height(),
            coarse.cell_size(),
        )?
        .rasterize(&RasterSettings::default())?;
        let res: Vec<f32> = coarse
            .as_slice()
            .iter()
            .zip(rec.as_slice())
            .map(|(a, b)| a - b)
            .collect();
        let res = coarse.with_data(res)?;
        let rp = extract_patches(&res, &geom)?;
        let f = STEP_FACTOR as f64;
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
            // A residual without relief: one harmless atom, used by nobody.
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
}

/// Minimum exemplar side used at a step, in units of the fine patch side.
const MIN_EXEMPLAR_PATCHES: usize = 6;

/// Amplifies `coarse` by `4^steps` with details of `exemplar` (section 5.3). The exemplar is
/// given at the final resolution; step `t` uses it reduced by `4^(steps - 1 - t)` (or the
/// smallest reduction still `>= 6` fine patches wide). Intermediate results are rasterised at
/// their own resolution and fed to the next step; the last step's [`Sct`] is returned, to be
/// rasterised at any resolution or window.
pub fn amplify(
    coarse: &Heightfield,
    exemplar: &Heightfield,
    settings: &AmplifySettings,
    progress: &dyn Progress,
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
    let mut current = coarse.clone();
    let mut result = None;
    for t in 0..settings.steps {
        let mut reduction = STEP_FACTOR.pow((settings.steps - 1 - t) as u32);
        while reduction > 1 && exemplar.width().min(exemplar.height()) / reduction < min_side {
            reduction /= STEP_FACTOR;
        }
        let ex = if reduction > 1 {
            exemplar.resample(exemplar.width() / reduction, exemplar.height() / reduction)?
        } else {
            exemplar.clone()
        };
        let step_settings = AmplifySettings {
            seed: item_seed(settings.seed, 0x57e9, t as u64),
            ..*settings
        };
        let training = extract_patches(&current, &settings.coarse_geometry())?;
        let dict = MultiResDictionary::from_exemplar(
            &ex,
            Some(training.matrix.view()),
            &step_settings,
            progress,
        )?;
        let sct = dict.amplify_once(&current, &step_settings)?;
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

/// Settings of [`synthesize`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthesisSettings {
    /// Amplification settings; `steps` defaults to 3 (figure 12: three incremental steps).
    pub amplify: AmplifySettings,
    /// Elevation range the sketch's `[min, max]` is mapped to (`None`: the exemplar's range).
    pub height_range: Option<(f32, f32)>,
}

impl Default for SynthesisSettings {
    fn default() -> Self {
        Self {
            amplify: AmplifySettings {
                steps: 3,
                dictionary: DictionaryChoice::Learned {
                    n_atoms: 64,
                    iterations: 3,
                },
                ..Default::default()
            },
            height_range: None,
        }
    }
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
    settings.amplify.check()?;
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
    let (cx, cy) = exemplar.cell_size();
    s.set_cell_size(cx * f, cy * f)?;
    amplify(&s, exemplar, &settings.amplify, progress)
}
