//! The refine and analyze jobs as units: [`RefineSettings`] (serde, [`RefineSettings::check`])
//! run on a heightfield by [`RefineSettings::run`], which returns the refined terrain and its
//! [`RefineFigures`]; [`AnalyzeSettings::run`] returns the statistics of equations (2)-(4) and
//! their [`AnalyzeFigures`]. The CLI (`relief refine`, `relief analyze`), the pipeline's
//! `wavelet` stage and tiled runs all go through these types, so a parameter is defined once.

use std::fmt::Write as _;

use relief_heightfield::{Heightfield, Progress};
use serde::{Deserialize, Serialize};

use crate::analysis::{BandFit, FitSettings, GlobalAnalysis, LocalMaps, analyze, analyze_local};
use crate::dwt::Band;
use crate::error::{Result, WaveletError};
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

/// Settings of the analyze job ([`AnalyzeSettings::run`]): the statistics of section 4 of a
/// void-free terrain, optionally with the local fits of equation (4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AnalyzeSettings {
    /// Analysis basis (the paper's linear spline, [`Wavelet::Cdf53`], by default).
    pub wavelet: Wavelet,
    /// Fit settings of equation (3) (first fitted level, variance floor, `gamma` clamp).
    pub fit: FitSettings,
    /// Also fit the local statistics (LSA, equation (4)) in a `W x W` window (odd).
    pub local_window: Option<usize>,
}

impl Default for AnalyzeSettings {
    fn default() -> Self {
        Self {
            wavelet: Wavelet::Cdf53,
            fit: FitSettings::default(),
            local_window: None,
        }
    }
}

/// Mean and 5/50/95th percentiles of a local map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MapSummary {
    /// Mean.
    pub mean: f64,
    /// 5th percentile.
    pub p5: f64,
    /// Median.
    pub p50: f64,
    /// 95th percentile.
    pub p95: f64,
}

impl MapSummary {
    /// Summary of a non-empty list of values (`None` when empty).
    pub fn of(values: &[f32]) -> Option<Self> {
        if values.is_empty() {
            return None;
        }
        let mut v: Vec<f32> = values.to_vec();
        v.sort_by(f32::total_cmp);
        let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize] as f64;
        Some(Self {
            mean: v.iter().map(|&x| x as f64).sum::<f64>() / v.len() as f64,
            p5: q(0.05),
            p50: q(0.5),
            p95: q(0.95),
        })
    }
}

/// The local fits of one band, summarised over the terrain.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LocalBand {
    /// Band.
    pub band: Band,
    /// `gamma` over the locations.
    pub gamma: MapSummary,
    /// Implied fractal dimension `3 - gamma / 2` over the locations.
    pub fractal_dimension: MapSummary,
}

/// What an analyze job reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AnalyzeFigures {
    /// Mean fractal dimension over the three bands.
    pub fractal_dimension: f64,
    /// `false` when the fractal dimension is below 2 (`gamma > 2`, `H > 1`): no fractional
    /// Brownian surface decays that fast, so the fBm reading of section 4 fails over the fitted
    /// levels (the terrain is smoother than any fractal surface there).
    pub fbm_holds: bool,
    /// The global analysis (variances per level and band, fits).
    pub analysis: GlobalAnalysis,
    /// LSA window side, when the local fits were asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub local_window: Option<usize>,
    /// The local fits summarised per band (empty without `local_window`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub local: Vec<LocalBand>,
}

impl AnalyzeFigures {
    /// The figures as text, as `relief analyze` prints them: the fit of equation (3) per band
    /// with its fractal dimension, the log2 variance per level (equation (2)) and, with a local
    /// window, the summary of the local fits (equation (4)).
    pub fn summary(&self) -> String {
        let f = self;
        let a = &f.analysis;
        let mut s = String::new();
        let used = a.levels.iter().filter(|l| l.fitted).count();
        let _ = writeln!(
            s,
            "wavelet:     {} (input = level {}, {} levels analysed, {} fitted from level {})",
            a.wavelet,
            a.top_level,
            a.levels.len(),
            used,
            a.settings.min_level
        );
        let _ = writeln!(s, "fit log2 Var = -j gamma + a (equation 3):");
        let _ = writeln!(s, "  band  gamma     a         r2      D (3 - gamma/2)");
        for (b, f) in Band::ALL.iter().zip(&a.fits) {
            let _ = writeln!(
                s,
                "  {:<4}  {:<8.4}  {:<8.3}  {:<6.4}  {:.4}{}",
                b.name(),
                f.gamma,
                f.a,
                f.r_squared,
                f.fractal_dimension(),
                if f.clamped {
                    format!("  (clamped; unconstrained gamma {:.4})", f.gamma_fit)
                } else {
                    String::new()
                }
            );
        }
        let _ = writeln!(
            s,
            "fractal dimension (mean of bands): {:.4}",
            f.fractal_dimension
        );
        if !f.fbm_holds {
            // gamma > 2 means H > 1: no fractional Brownian surface decays that fast, so the
            // fBm reading of section 4 does not hold over the fitted levels.
            let _ = writeln!(
                s,
                "warning: D < 2 (gamma > 2): the fBm assumption fails over the fitted levels; the \
             terrain is smoother than any fractal surface there and D is only a roughness index"
            );
        }
        let _ = writeln!(s, "log2 variance per level (equation 2):");
        let _ = writeln!(s, "  level  depth  h         v         d         fitted");
        for l in &a.levels {
            let lg = |v: f64| {
                if v > 0.0 {
                    format!("{:<8.3}", v.log2())
                } else {
                    "-inf    ".to_string()
                }
            };
            let _ = writeln!(
                s,
                "  {:<5}  {:<5}  {}  {}  {}  {}",
                l.level,
                l.depth,
                lg(l.variance[0]),
                lg(l.variance[1]),
                lg(l.variance[2]),
                if l.fitted { "yes" } else { "no" }
            );
        }
        if let Some(w) = f.local_window {
            let _ = writeln!(
                s,
                "local fit (equation 4), {w}x{w} window, over all locations:"
            );
            let _ = writeln!(
                s,
                "  band  gamma mean/p5/p50/p95          D mean/p5/p50/p95"
            );
            for l in &f.local {
                let _ = writeln!(
                    s,
                    "  {:<4}  {:.3}/{:.3}/{:.3}/{:.3}  {:.3}/{:.3}/{:.3}/{:.3}",
                    l.band.name(),
                    l.gamma.mean,
                    l.gamma.p5,
                    l.gamma.p50,
                    l.gamma.p95,
                    l.fractal_dimension.mean,
                    l.fractal_dimension.p5,
                    l.fractal_dimension.p50,
                    l.fractal_dimension.p95
                );
            }
        }
        s
    }
}

/// Result of [`AnalyzeSettings::run`].
#[derive(Debug, Clone)]
pub struct Analyzed {
    /// The local maps at input resolution (with `local_window`).
    pub local: Option<LocalMaps>,
    /// The figures (they hold the global analysis).
    pub figures: AnalyzeFigures,
}

impl Analyzed {
    /// The map of the implied fractal dimension, mean of the bands (`3 - mean(gamma) / 2`),
    /// at input resolution (with `local_window`).
    pub fn dimension_map(&self) -> Option<Vec<f32>> {
        let m = self.local.as_ref()?;
        Some(
            (0..m.gamma[0].data.len())
                .map(|i| 3.0 - (m.gamma[0].data[i] + m.gamma[1].data[i] + m.gamma[2].data[i]) / 6.0)
                .collect(),
        )
    }
}

impl AnalyzeSettings {
    /// Checks the settings (the fit, the window).
    pub fn check(&self) -> Result<()> {
        self.fit.check()?;
        if let Some(w) = self.local_window {
            crate::analysis::check_window(w)?;
        }
        Ok(())
    }

    /// Runs the job on a void-free terrain.
    pub fn run(&self, hf: &Heightfield, progress: &dyn Progress) -> Result<Analyzed> {
        self.check()?;
        hf.require_complete()?;
        progress.begin("wavelet analysis", 0);
        let analysis = analyze(hf, self.wavelet, &self.fit)?;
        let (local, summaries) = match self.local_window {
            Some(w) => {
                progress.begin("local fits", 0);
                let maps = analyze_local(hf, self.wavelet, w, &self.fit)?;
                let mut bands = Vec::with_capacity(3);
                for b in Band::ALL {
                    let summary = |data: &[f32]| {
                        MapSummary::of(data)
                            .ok_or_else(|| WaveletError::param("input", "empty", "must have cells"))
                    };
                    bands.push(LocalBand {
                        band: b,
                        gamma: summary(&maps.gamma[b.index()].data)?,
                        fractal_dimension: summary(&maps.fractal_dimension(b).data)?,
                    });
                }
                (Some(maps), bands)
            }
            None => (None, Vec::new()),
        };
        let d = analysis.fractal_dimension();
        Ok(Analyzed {
            local,
            figures: AnalyzeFigures {
                fractal_dimension: d,
                fbm_holds: d >= 2.0,
                analysis,
                local_window: self.local_window,
                local: summaries,
            },
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
        relief_testdata::assert_json_round_trip(&s, &["\"stats_window\":5"]);
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

    #[test]
    fn analyze_job_reports_the_fits_and_the_local_summaries() {
        let hf = Heightfield::from_fn(64, 64, 10.0, 10.0, |x, y| {
            let (x, y) = (x as f32, y as f32);
            40.0 * (x * 0.2).sin() * (y * 0.15).cos() + 5.0 * (x * 0.9 + y * 0.5).sin()
        });
        let s: AnalyzeSettings = serde_json::from_str(r#"{"local_window": 3}"#).unwrap();
        let out = s.run(&hf, &NoProgress).unwrap();
        let direct = analyze(&hf, Wavelet::Cdf53, &FitSettings::default()).unwrap();
        assert_eq!(out.figures.analysis, direct);
        assert_eq!(out.figures.fractal_dimension, direct.fractal_dimension());
        assert_eq!(out.figures.fbm_holds, direct.fractal_dimension() >= 2.0);
        assert_eq!(out.figures.local.len(), 3);
        let maps = out.local.as_ref().unwrap();
        let g = &maps.gamma[0].data;
        let mean = g.iter().map(|&v| v as f64).sum::<f64>() / g.len() as f64;
        assert!((out.figures.local[0].gamma.mean - mean).abs() < 1e-9);
        let l = out.figures.local[1].gamma;
        assert!(l.p5 <= l.p50 && l.p50 <= l.p95);
        let dims = out.dimension_map().unwrap();
        assert_eq!(dims.len(), hf.len());
        // A smooth terrain decays faster than any fBm over the fitted levels.
        let smooth = Heightfield::from_fn(64, 64, 10.0, 10.0, |x, y| (x * x + y * y) as f32);
        assert!(
            !AnalyzeSettings::default()
                .run(&smooth, &NoProgress)
                .unwrap()
                .figures
                .fbm_holds
        );
        for bad in [r#"{"local_window": 4}"#, r#"{"fit": {"min_level": 99}}"#] {
            let s: AnalyzeSettings = serde_json::from_str(bad).unwrap();
            assert!(s.run(&hf, &NoProgress).is_err(), "{bad}");
        }
        assert!(serde_json::from_str::<AnalyzeSettings>(r#"{"window": 3}"#).is_err());
    }
}
