//! Dictionary learning for the Sparse Construction Tree of Guérin et al. 2016, "Sparse
//! representation of terrains for procedural modeling" (sections 4.4, 5.2, 5.3), on top of
//! `relief-sparse-core` (dictionaries, Batch-OMP, [`relief_sparse_core::Sct`]).
//!
//! # Map to the paper
//! | paper | here |
//! |---|---|
//! | 4.4 problem (1), K-SVD (Aharon et al. 2006), rank-1 SVD update | [`ksvd()`] with [`KsvdVariant::Exact`] (faer thin SVD) |
//! | approximate K-SVD (Rubinstein et al. 2008) | [`KsvdVariant::Approximate`] (default, fast) |
//! | 4.4 problem (2), atoms must be terrain patches | [`constrained_learning`] (GEMM scoring of all candidates) |
//! | 4.1 / 5.3 multi-resolution dictionary `(H, L)`, figure 10 | [`MultiResDictionary`] |
//! | 5.3 amplification (figures 9, 11, 16), x4 per step | [`amplify`] ([`AmplifySettings::radius`] = `R`) |
//! | 5.3 / 5.4 synthesis from a painted sketch, 3 incremental steps (figure 12) | [`synthesize`] |
//! | figure 11, larger `R`: less of the input, more of the exemplar (sketch landforms) | [`exemplar_structure`] |
//! | figure 15 noise amplification baseline | [`noise_amplify`] |
//! | 5.2 inverse procedural modelling, figure 4 atoms, figure 7-8 | [`noise`] atoms, [`fit_procedural`] |
//! | several exemplars / mixed data + analytic atoms | [`MultiResDictionary::from_exemplars`], [`training_patches`]; [`ksvd_with_fixed`] |
//! | quality protocol (consistency, spectral slope, slope histogram) | [`quality::evaluate`] |
//! | issue-15 box protocol (+ curvature histogram, detail phase swing) | [`quality::box_protocol`], example `amplify_quality` |
//!
//! # Guarantees
//! * Same inputs and seed give identical bytes whatever the rayon thread count (per-item
//!   seeds from a counter-based hash; parallel reductions in fixed blocks).
//! * The K-SVD error trace is non-increasing up to atom replacements; constrained learning
//!   never increases the objective within an atom update (the current atom is a candidate).
//! * Every atom of a constrained dictionary is a normalised candidate patch
//!   ([`LearnedDictionary::sources`]); amplification atoms are exemplar patches.
//! * Invalid parameters and NaN input are [`LearnError`]s naming the field, never panics.
//!
//! # Departures from the paper (amplification defaults)
//! The default [`AmplifySettings`] are not the paper's plain method, which stays available as
//! [`AmplifySettings::paper()`] (`relief amplify --paper`) for comparison:
//! * [`AmplifySettings::residual_correction`]: the paper's output is consistent with its input
//!   only up to the sparse coding error on `L` (with `s = 1`, 0.6-2.2 % of the relief at x4 and
//!   2-6 % at x16 on Alpine DEMs, a slope histogram worse than bicubic's). The default adds the
//!   input minus the predicted box reduction of the detail layer, back-projected through its
//!   x4 interpolation, so `box-down(output)` matches the input to 0.02-0.2 %. That residual
//!   carries most of the input's finest relief; it is interpolated with Lanczos-3
//!   ([`AmplifySettings::residual_kernel`]), not the Keys cubic, which keeps that relief on the
//!   coarse samples and smooths it between them: the high-pass energy of an alps x4 output
//!   swung 1.60x with the row phase modulo 4 (truth 1.21), and swings 1.21x with Lanczos-3.
//! * [`AmplifySettings::normalize_detail`]: the normalised blend of details from unrelated
//!   atoms has a variance `sum a_i^2 / (sum a_i)^2` that depends on the position modulo the
//!   grid step (a visible grid) and is well below 1; the high-frequency part of the atoms is
//!   scaled so the blended detail energy is flat and undiminished ([`detail_gain`]).
//! * The grid step defaults to half the support radius (the paper's grid), so about 12
//!   primitives overlap at every point instead of 1-4.
//! * [`AmplifySettings::diverse_atoms`]: with `s = 1` the paper codes every patch with its
//!   best-matching atom; where the input is smooth a whole row of primitives picks the same
//!   atom and its detail repeats every grid step (short horizontal and vertical streaks,
//!   dotted rows in hillshades, measured by [`repeat_score`]). The default picks, seeded per
//!   primitive, among the atoms within 90 % of the best correlation (at most 8; radius >= 2).
//! * Sketch synthesis ([`synthesize`]) sets [`AmplifySettings::exemplar_detail`]: a coded
//!   detail amplitude is proportional to the input's local relief, so a painted sketch's flat
//!   and smooth parts got no detail (a smooth blob following the sketch pixels); each primitive
//!   now adds its atom's detail at the exemplar's amplitude on the bicubic interpolation of the
//!   input.
//! * Sketch synthesis first adds the exemplar's landforms between the sketch's cell and its
//!   strokes ([`exemplar_structure`], [`SynthesisSettings::structure`]): every x4 step adds only
//!   the octave below its input, so the valleys and spurs a few sketch cells apart were never
//!   made and a painted ridge came out as a textured blob. Coherent exemplar patches (the
//!   paper's `s = 1` over a complete dictionary, matched on smooth parts, each continuing its
//!   neighbours' exemplar region where it can) add them at the sketch's resolution. Measured
//!   on a 64 x 128 painted sketch, slope-histogram distance to the exemplar without -> with
//!   (correlation of the output with the sketch): alps_dem two x4 steps 10.33 -> 4.55 deg
//!   (0.958), three steps 7.41 -> 6.67 deg (0.899); grandcanyon two steps 5.41 -> 5.91 deg
//!   (0.921), three steps 6.36 -> 6.32 deg (0.878): its bimodal plateau-and-wall slopes are
//!   not reproduced, but the hillshades show valleys and spurs where there was texture.
//!   Where the exemplar does not reach the sketch's scale its landforms stand in by
//!   self-similarity, with their band capped at a tenth of the sketch's range;
//!   [`SynthesisSettings::sketch_cell_size`] (`--sketch-cell-size`) avoids that. Radius 0
//!   (`--structure-radius 0`, `--paper`) is the paper's method.
//!
//! Exemplar scale: every x4 step cuts its atoms from the exemplar box-down-sampled to the
//! step's target cell size (the exemplar's cell size is its grid's, or
//! [`AmplifySettings::exemplar_cell_size`]). Not guaranteed: a step finer than the exemplar,
//! or for which the exemplar is too small to be reduced, relies on the self-similarity of
//! relief across scales ([`StepScale::self_similar`] and [`StepScale::note`] say so).
//!
//! # Example
//! ```
//! use relief_dictionary_learning::{KsvdSettings, ksvd};
//! use relief_heightfield::{Heightfield, NoProgress};
//! use relief_sparse_core::{PatchGeometry, extract_patches};
//! let hf = Heightfield::from_fn(64, 64, 10.0, 10.0, |x, y| {
//!     ((x as f32) * 0.31).sin() * 40.0 + ((y as f32) * 0.17 + (x as f32) * 0.05).cos() * 25.0
//! });
//! let patches = extract_patches(&hf, &PatchGeometry::with_patch_size(8)).unwrap();
//! let s = KsvdSettings { n_atoms: 16, sparsity: 2, iterations: 5, ..Default::default() };
//! let learned = ksvd(patches.matrix.view(), &s, &NoProgress).unwrap();
//! assert_eq!(learned.atoms.dim(), (16, 64));
//! assert!(learned.trace.last().unwrap().rmse <= learned.trace[0].rmse);
//! ```
#![warn(missing_docs)]

pub mod baseline;
pub mod compress;
pub mod constrained;
mod error;
pub mod ksvd;
pub mod memory;
pub mod multires;
pub mod noise;
pub mod procedural;
pub mod quality;
pub mod sketch;
pub mod structure;

pub use baseline::{NoiseBaselineSettings, noise_amplify};
pub use compress::{
    AnalyticAtoms, CompressFigures, CompressSettings, Compressed, DictionarySource,
};
pub use constrained::{ConstrainedSettings, constrained_learning};
pub use error::{LearnError, Result};
pub use ksvd::{
    IterationStats, KsvdSettings, KsvdVariant, LearnedDictionary, MAX_ITERATIONS, ksvd, ksvd_from,
    ksvd_with_fixed,
};
pub use multires::{
    AmplifyFigures, AmplifySettings, DIVERSE_CHOICES, DIVERSE_MAX_ATOMS, DIVERSE_TOLERANCE,
    DictionaryChoice, LastStep, MultiResDictionary, StepReport, StepScale, amplify,
    amplify_observed, amplify_with_figures, box_resample, detail_gain, exemplar_plan,
    prepare_last_step,
};
pub use noise::{NoiseFamily, register_function_atoms};
pub use procedural::{ProceduralFit, ProceduralSettings, fit_procedural};
pub use quality::{
    BoxProtocolRow, QualityRow, box_protocol, corner_bicubic, detail_swing, evaluate,
    highpass_swing, laplacian_histogram_distance, phase_swing, repeat_score, swing_floor,
};
pub use sketch::{
    SynthesisFigures, SynthesisSettings, synthesize, synthesize_with_figures,
    synthesize_with_strokes,
};
pub use structure::{StructureReport, StructureSettings, exemplar_structure};

/// Stacks the patch matrices of several terrains (same geometry) into one training matrix, for
/// learning one dictionary from several exemplars at once.
pub fn training_patches(
    terrains: &[&relief_heightfield::Heightfield],
    geometry: &relief_sparse_core::PatchGeometry,
) -> Result<ndarray::Array2<f32>> {
    let mut mats = Vec::with_capacity(terrains.len());
    for t in terrains {
        mats.push(relief_sparse_core::extract_patches(t, geometry)?.matrix);
    }
    if mats.is_empty() {
        return Err(LearnError::NotEnough {
            what: "terrains",
            needed: 1,
            got: 0,
        });
    }
    if mats.len() == 1 {
        // One terrain: its matrix as it is, without a second copy.
        return Ok(mats.swap_remove(0));
    }
    let views: Vec<_> = mats.iter().map(|m| m.view()).collect();
    ndarray::concatenate(ndarray::Axis(0), &views)
        .map_err(|_| LearnError::param("terrains", terrains.len(), "patch dimensions differ"))
}

/// At most `max` rows of `matrix`, picked evenly (row `i * n / max`; deterministic, spread over
/// the whole matrix, so over every exemplar of [`training_patches`]). Returns a copy of all
/// rows when there are no more than `max`.
pub fn subsample_rows(
    matrix: ndarray::ArrayView2<f32>,
    max: usize,
) -> Result<ndarray::Array2<f32>> {
    if max == 0 {
        return Err(LearnError::param("max", max, "must be >= 1"));
    }
    let n = matrix.nrows();
    if n <= max {
        return Ok(matrix.to_owned());
    }
    let pick: Vec<usize> = (0..max).map(|i| i * n / max).collect();
    Ok(matrix.select(ndarray::Axis(0), &pick))
}
