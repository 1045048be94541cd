//! Terrain synthesis from a painted sketch (guerin2016 section 5.3, figures 1, 9 and 12): the
//! sketch is mapped to an elevation range, given the exemplar's cell size times `4^steps`, and
//! amplified step by step with [`crate::multires::amplify`].

use relief_heightfield::{Heightfield, Progress};
use relief_sparse_core::Sct;
use serde::{Deserialize, Serialize};

use crate::error::{LearnError, Result};
use crate::multires::{AmplifySettings, DictionaryChoice, STEP_FACTOR, amplify};

/// Settings of the sketch-synthesis job ([`synthesize`]); serde as [`AmplifySettings`] (fields
/// missing inside a JSON `amplify` object take [`AmplifySettings`]' defaults, not the ones
/// below; the pipeline merges a spec onto these defaults instead).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SynthesisSettings {
    /// Amplification settings; `steps` defaults to 3 (figure 12: three incremental steps) and
    /// the residual correction is off (the sketch's pixels are not to be reproduced).
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
                // A painted sketch is not a measurement: forcing the output to reduce to its
                // pixels would reproduce them. The detail blend is still energy-normalised.
                residual_correction: false,
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
