//! Stages of guerin2016 sections 5.2 and 5.3 (relief-dictionary-learning):
//!
//! * `amplify`: sparse amplification of real data. (1) The quality protocol of issue 15: the
//!   left half of the current terrain is the truth; it is box down-sampled x4 and x16 and
//!   amplified back with a multi-resolution dictionary learned (constrained learning, atoms are
//!   exemplar patches) from the RIGHT half, which the truth never overlaps. The table compares
//!   the sparse amplification (the library default, with residual correction and detail-energy
//!   normalisation, and the paper's plain method, `--paper`) with bicubic up-sampling and the
//!   noise-amplification baseline of figure 15: consistency (RMS of box-down(output) - input
//!   over relief), spectral-slope error over the added octaves, slope- and Laplacian-histogram
//!   distances, detail phase swing. The x16 amplification of the protocol is the stage's
//!   golden. (2) The enlargement: the left half at full resolution amplified x16 with the right
//!   half as exemplar (nothing finer exists, so it cannot have seen its answer), shown with
//!   zoomed hillshade crops beside bicubic and, unless `replace_terrain` is false, handed on to
//!   the next stages. (3) A centre window of the left half amplified x256 (`x256_window`,
//!   previews only): the phase swing of the detail every step added, and zoomed crops beside
//!   bicubic. On small inputs (the 128 x 128 golden crop) the factor drops to x4 and the radius
//!   to 1 so the exemplar still holds enough patches.
//! * `sketch`: synthesis from a painted sketch (a ridge stroke, a peak, a valley) with the
//!   input DEM as exemplar (the current terrain if the input has voids), in three incremental x4 steps (figure 12): the sketch of
//!   `n x n` cells becomes a `64 n x 64 n` terrain. The current terrain is unchanged.
//! * `procedural`: inverse procedural modelling (section 5.2, figures 7-8): a centre crop (at
//!   most `max_side`^2) of the input DEM as loaded (the current terrain if the input has
//!   voids; earlier stages may have made the current terrain synthetic) is fitted with
//!   Perlin, ridged multifractal and ridged-sum (figure 4) atoms and with a
//!   constrained-learning reduction of the ridged dictionary; PSNR per family (the paper:
//!   ridged 24.9 dB vs Perlin 20.0 dB on its data). The current terrain is unchanged.

use std::time::Instant;

use anyhow::{Context, Result, bail};
use relief_dictionary_learning::{
    AmplifySettings, BoxProtocolRow, DictionaryChoice, NoiseBaselineSettings, NoiseFamily,
    ProceduralSettings, SynthesisSettings, amplify, amplify_observed, box_protocol, corner_bicubic,
    detail_swing, fit_procedural, highpass_swing, noise_amplify, phase_swing, swing_floor,
    synthesize_with_figures,
};
use relief_heightfield::{Heightfield, Progress, metrics};
use relief_sparse_core::RasterSettings;
use serde::{Deserialize, Serialize};

use super::spec::StageParams;
use super::{Stage, StageCx, Tolerance};

mod amplify;
mod procedural;
mod sketch;

pub(crate) use self::amplify::AmplifyParams;
pub(crate) use self::procedural::ProceduralParams;
pub(crate) use self::sketch::SketchParams;
#[cfg(test)]
use self::sketch::painted_sketch;

/// Tolerance of the dictionary goldens: learning, coding and rasterising are deterministic for
/// a seed whatever the thread count, so reruns agree to float rounding; a different atom chosen
/// somewhere (a real change) moves the cells of a primitive by metres.
const DICT_TOLERANCE: Tolerance = Tolerance {
    max_abs_m: 0.5,
    rmse_m: 0.05,
};

/// Number of candidate positions of one exemplar at one step (coarse patch side `a`).
fn candidate_count(exemplar: (usize, usize), a: usize) -> usize {
    let (wl, hl) = (exemplar.0 / 4, exemplar.1 / 4);
    (wl + 1).saturating_sub(a) * (hl + 1).saturating_sub(a)
}

/// Smallest exemplar side the library accepts at radius `r` (6 fine patches).
fn min_exemplar_side(r: f64) -> usize {
    6 * 4 * 2 * r.ceil() as usize
}

/// The job's dictionary with its atom count capped at `cap` (a learned dictionary cannot have
/// more atoms than a quarter of the candidate patches), and that count (0 = complete).
fn capped_dictionary(d: DictionaryChoice, cap: usize) -> (DictionaryChoice, usize) {
    match d {
        DictionaryChoice::Complete => (d, 0),
        DictionaryChoice::Learned {
            n_atoms,
            iterations,
        } => {
            let n = n_atoms.min(cap).max(1);
            (
                DictionaryChoice::Learned {
                    n_atoms: n,
                    iterations,
                },
                n,
            )
        }
    }
}

/// `N = n` for a learned dictionary, `complete` for 0.
fn atoms_label(atoms: usize) -> String {
    if atoms == 0 {
        "complete".into()
    } else {
        format!("N = {atoms}")
    }
}

/// The centre `side x side` crop (clamped to the grid) of a grid.
fn centre_crop(hf: &Heightfield, side: usize) -> Result<Heightfield> {
    let (w, h) = (side.min(hf.width()), side.min(hf.height()));
    Ok(hf.crop((hf.width() - w) / 2, (hf.height() - h) / 2, w, h)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn painted_sketch_has_relief() {
        let s = painted_sketch(16, 8);
        let (lo, hi) = s.min_max().unwrap();
        assert!(lo >= 0.0 && hi <= 1.0 && hi - lo > 0.4, "{lo} {hi}");
    }

    #[test]
    fn sizes() {
        assert_eq!(min_exemplar_side(2.0), 96);
        assert_eq!(candidate_count((64, 128), 2), 15 * 31);
    }
}
