//! The refine job as one unit: [`RefineSettings`] (serde, [`RefineSettings::check`]) run on a
//! heightfield by [`RefineSettings::run`], which returns the refined terrain and its
//! [`RefineFigures`]. The CLI (`relief refine`), the pipeline's `wavelet` stage and tiled runs
//! all go through this type, so a parameter is defined once.

use relief_heightfield::{Heightfield, Progress};
use serde::Serialize;

use crate::analysis::BandFit;
use crate::error::Result;
use crate::refine::{Method, Model, RefineSettings, Refiner};
use crate::wavelet::Wavelet;

/// What a refine job reports: sizes, the model actually used and the fitted statistics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RefineFigures {
    /// Input size `[width, height]` in cells.
    pub input_size: [usize; 2],
    /// Refined grid size `[width, height]` (the input's times `2^extra_levels`).
    pub output_size: [usize; 2],
    /// Synthesis model.
    pub model: Model,
    /// Basis used (the settings' or the model's default).
    pub wavelet: Wavelet,
    /// Statistics scope.
    pub method: Method,
    /// LSA statistics window side (`None` for GSA).
    pub stats_window: Option<usize>,
    /// The `(gamma, a)` fit per band (H, V, D) the new levels are drawn with.
    pub synthesis_fits: [BandFit; 3],
    /// Fallbacks taken (small inputs, clamped fits); empty when everything went as configured.
    pub notes: Vec<String>,
}

/// Result of [`RefineSettings::run`].
#[derive(Debug, Clone)]
pub struct Refined {
    /// The refined terrain (georeference kept, cell size divided by `2^extra_levels`).
    pub terrain: Heightfield,
    /// Its figures.
    pub figures: RefineFigures,
}

impl Refiner {
    /// The figures of this refinement (independent of which windows are rendered).
    pub fn figures(&self) -> RefineFigures {
        let s = self.settings();
        let (ow, oh) = self.output_size();
        let n = s.extra_levels;
        RefineFigures {
            input_size: [ow >> n, oh >> n],
            output_size: [ow, oh],
            model: s.model,
            wavelet: s.basis(),
            method: s.method,
            stats_window: (s.method == Method::Lsa).then_some(s.window),
            synthesis_fits: *self.synthesis_fits(),
            notes: self.notes().to_vec(),
        }
    }
}

impl RefineSettings {
    /// Runs the job: checks the settings, analyses the void-free `hf` and synthesises the whole
    /// refined grid. For one window or a streamed output, build a [`Refiner`] instead (same
    /// values, bit for bit).
    pub fn run(&self, hf: &Heightfield, progress: &dyn Progress) -> Result<Refined> {
        let refiner = Refiner::new(hf, self)?;
        let terrain = refiner.render(progress)?;
        Ok(Refined {
            terrain,
            figures: refiner.figures(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use relief_heightfield::NoProgress;

    #[test]
    fn settings_round_trip_through_json_and_refuse_unknown_fields() {
        let s = RefineSettings {
            model: Model::Paper,
            window: 5,
            extra_levels: 3,
            ..RefineSettings::default()
        };
        let json = serde_json::to_string(&s).unwrap();
        assert!(json.contains("\"stats_window\":5"), "{json}");
        assert_eq!(serde_json::from_str::<RefineSettings>(&json).unwrap(), s);
        assert_eq!(
            serde_json::from_str::<RefineSettings>("{}").unwrap(),
            RefineSettings::default()
        );
        let err = serde_json::from_str::<RefineSettings>(r#"{"levels": 2}"#).unwrap_err();
        assert!(err.to_string().contains("unknown field `levels`"), "{err}");
    }

    #[test]
    fn the_basis_follows_the_model_unless_given() {
        let paper: RefineSettings = serde_json::from_str(r#"{"model": "paper"}"#).unwrap();
        assert_eq!(paper.basis(), Wavelet::Cdf53);
        assert_eq!(RefineSettings::default().basis(), Wavelet::Cdf97);
        let haar: RefineSettings =
            serde_json::from_str(r#"{"model": "paper", "wavelet": "haar"}"#).unwrap();
        assert_eq!(haar.basis(), Wavelet::Haar);
    }

    #[test]
    fn run_equals_the_refiner_and_reports_its_figures() {
        let hf = Heightfield::from_fn(32, 24, 10.0, 10.0, |x, y| {
            let (x, y) = (x as f32, y as f32);
            40.0 * (x * 0.2).sin() * (y * 0.15).cos() + 5.0 * (x * 0.9 + y * 0.5).sin()
        });
        let s = RefineSettings {
            extra_levels: 2,
            seed: 3,
            ..RefineSettings::default()
        };
        let out = s.run(&hf, &NoProgress).unwrap();
        let direct = Refiner::new(&hf, &s).unwrap().render(&NoProgress).unwrap();
        assert_eq!(out.terrain.as_slice(), direct.as_slice());
        assert_eq!(out.figures.input_size, [32, 24]);
        assert_eq!(out.figures.output_size, [128, 96]);
        assert_eq!(out.figures.stats_window, Some(3));
        assert_eq!(out.figures.wavelet, Wavelet::Cdf97);
        let bad = RefineSettings {
            fine_levels: 1,
            ..s
        };
        assert!(bad.run(&hf, &NoProgress).is_err());
    }
}
