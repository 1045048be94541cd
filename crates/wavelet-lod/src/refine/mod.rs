//! New levels of detail: GSA (section 5.1) and LSA (section 5.2), generated on demand.

use std::ops::Range;

use rayon::prelude::*;
use relief_heightfield::check_field;
use relief_heightfield::{Heightfield, MAX_CELLS, NoProgress, Progress};
use serde::{Deserialize, Serialize};

use crate::analysis::{
    BandFit, FitSettings, GlobalAnalysis, LocalMaps, LocalStats, check_window, decompose, fine_fit,
    global_lenient, maps_from,
};
use crate::dwt::{AxisPlan, Band, Grid, inverse_level_window, max_levels};
use crate::error::{Result, WaveletError};
use crate::lift::Boundary;
use crate::rng::{fill_normals, row_key};
use crate::spectral::{KR, KS, QL, SpectralPlan, reflect};
use crate::wavelet::Wavelet;

mod amplitude;
mod parent;
mod render;

use self::amplitude::{BROAD_WINDOW, amplitude_maps, blend_amplitude, colour_noise, lerp_index};
use self::parent::BandRegion;

/// Which statistics drive the synthesis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Global scope approach (section 5.1): one `(gamma, a)` per band.
    Gsa,
    /// Local scope approach (section 5.2): one `(gamma, a)` per band and input location, from a
    /// `window x window` neighbourhood ([`RefineSettings::window`]).
    #[default]
    Lsa,
}

/// How the new coefficients are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Model {
    /// The default, a departure from the paper (see the crate docs, "Spectral model"): `gamma`
    /// fitted on the finest [`RefineSettings::fine_levels`] levels, coloured coefficients whose
    /// output spectrum continues the fitted power law inside every new octave, and an
    /// area-consistent (pixel-is-area) placement of the input.
    #[default]
    Spectral,
    /// The paper as written (section 5): independent Gaussian coefficients, `gamma` fitted from
    /// [`FitSettings::min_level`] up, GSA or LSA, input samples on the even output samples.
    Paper,
}

impl Model {
    /// Lower-case name (`spectral`, `paper`).
    pub fn name(self) -> &'static str {
        match self {
            Model::Spectral => "spectral",
            Model::Paper => "paper",
        }
    }
}

/// Settings of the refine job ([`Refiner`], [`RefineSettings::run`]): the one definition of its
/// parameters, read by the CLI's flags, the pipeline spec (JSON, snake_case names, missing
/// fields take the defaults, unknown fields are an error) and tiled-run manifests.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RefineSettings {
    /// Synthesis model: [`Model::Spectral`] (default) or the paper's [`Model::Paper`].
    pub model: Model,
    /// Basis; `None` takes the model's ([`RefineSettings::basis`]): [`Wavelet::Cdf97`] for the
    /// spectral model, chosen by measurement (its smoother synthesis filters leak less of each
    /// coarser synthetic level into the finer octaves), the paper's linear spline
    /// [`Wavelet::Cdf53`] for [`Model::Paper`].
    pub wavelet: Option<Wavelet>,
    /// GSA or LSA. With [`Model::Paper`] as in section 5; with [`Model::Spectral`], GSA draws
    /// the same amplitude everywhere and LSA (default) modulates it by the bilinearly
    /// interpolated local amplitude of the finest observed level (`window x window` mean
    /// square), so flat areas stay flat.
    pub method: Method,
    /// LSA statistics window side (odd; the paper tests 1, 3, 5, 7 and recommends 3). Named
    /// `stats_window` in JSON, as the CLI's `--stats-window` (an output window is `--window`).
    #[serde(rename = "stats_window")]
    pub window: usize,
    /// Number of synthesised levels: the output is `2^extra_levels` times larger per side.
    pub extra_levels: u32,
    /// Seed of the coefficient hash.
    pub seed: u64,
    /// Fit settings.
    pub fit: FitSettings,
    /// Tile side (output cells, 16..=65536) of [`Refiner::render`]; only affects speed and
    /// memory, never the values.
    pub tile: usize,
    /// Spectral model: number of finest observed levels the synthesis `gamma` is fitted on
    /// (2..=8; fewer are used when the input has fewer levels, with a note).
    pub fine_levels: usize,
    /// Spectral model: take the synthetic detail's block means out through the smooth part, so
    /// that the box down-sampling of the refined terrain is the input (see the crate docs).
    /// Costs the synthesis of the detail over a slightly larger region.
    pub consistency: bool,
    /// Spectral model: smallest `gamma` of the continuation (in `[0, 8]`). With `gamma < 2`
    /// every added octave adds more slope variance than the one before, so the slopes of the
    /// refined terrain grow without bound with the number of levels, which real terrain does
    /// not do; a fit on few coarse levels (large factors) often comes out that low because
    /// terrain spectra steepen towards fine scales. The default 2.5 was chosen by measurement
    /// (`examples/quality.rs`, see the crate docs).
    pub min_gamma: f64,
    /// Spectral model with LSA: exponent `p` of the local amplitude. The local factor is
    /// `(m / mean(m^p))^(1/2)`-normalised `m^(p/2)` of the windowed mean square `m` of the finest
    /// observed level (mean square 1 over the terrain, so the total variance is kept). `1`
    /// follows the observed local energy; larger values put more of the detail on rough ground
    /// and less on smooth valley floors, glaciers and plains (in `[0, 4]`; the default 1, as 1.5
    /// and 2 measured no better overall: less grain on the alps glacier floors, too little
    /// texture on the other DEMs' smooth ground).
    pub amplitude_power: f64,
    /// Spectral model with LSA: how much of the narrow local amplitude each further new level
    /// keeps (in `[0, 1]`): new level `t` (0 = the first) gets the amplitude factor
    /// `m^(r^t) M^(1 - r^t)` (renormalised to mean square 1), where `m` is the local factor of
    /// the statistics window and `M` the same from a window 5 times wider: the finest texture
    /// spreads into the smooth ground next to rough ground (valley and glacier floors get some),
    /// while exactly flat ground (sea, lakes: `m = 0`) stays flat. `1`: every level follows the
    /// narrow window. The default 0.6 was chosen by measurement (`examples/quality.rs` with
    /// `holdout`: five DEMs at x4 and x16, against 0.4, 0.8 and 1): the curvature energy of
    /// the smoothest ground is closer to the truth's (`flat_excess` summed 15.9 against 21.1
    /// for 1), the Laplacian histogram distance lower (0.737 against 0.766), the spectral slope
    /// error about the same (3.93 against 3.84); 0.4 flattens further (14.2) at the cost of
    /// slope error and placement.
    pub amplitude_persistence: f64,
    /// Spectral model: parent conditioning, the exponent `kappa` (in `[0, 2]`) of the
    /// magnitude correlation across the new levels. `0` draws every new level independently of
    /// the one above it; `kappa > 0` multiplies the coloured numbers of new level `t >= 1` by
    /// `m^(kappa/2)` (normalised to mean square 1), where `m` is the mean square of the parent
    /// level's own (unit) coefficients of the same band in the `3 x 3` parents around the
    /// coefficient, bilinearly interpolated: fine detail is strong where the coarser synthetic
    /// detail is, as in hidden-Markov-tree and Portilla-Simoncelli texture models, so ridges
    /// and valleys of one new level continue into the next. The first new level is
    /// conditioned on the observed finest level through the local amplitude (LSA). See the
    /// crate docs for the measurement behind the default.
    pub parent_conditioning: f64,
}

impl Default for RefineSettings {
    fn default() -> Self {
        Self {
            model: Model::Spectral,
            wavelet: None,
            method: Method::Lsa,
            window: 3,
            extra_levels: 2,
            seed: 0,
            fit: FitSettings::default(),
            tile: 512,
            fine_levels: 4,
            min_gamma: 2.5,
            consistency: true,
            amplitude_power: 1.0,
            amplitude_persistence: 0.6,
            parent_conditioning: 0.0,
        }
    }
}

impl RefineSettings {
    /// The paper's defaults: [`Model::Paper`], the linear spline ([`Wavelet::Cdf53`]), LSA with
    /// a 3 x 3 window.
    pub fn paper() -> Self {
        Self {
            model: Model::Paper,
            ..Self::default()
        }
    }

    /// The basis used: [`RefineSettings::wavelet`], or the model's default.
    pub fn basis(&self) -> Wavelet {
        self.wavelet.unwrap_or(match self.model {
            Model::Spectral => Wavelet::Cdf97,
            Model::Paper => Wavelet::Cdf53,
        })
    }

    /// Checks the settings.
    pub fn check(&self) -> Result<()> {
        self.fit.check()?;
        if self.method == Method::Lsa {
            check_window(self.window)?;
        }
        check_field!(self, extra_levels, 1..=12, "must be in 1..=12")?;
        check_field!(self, fine_levels, 2..=8, "must be in 2..=8")?;
        check_field!(self, min_gamma, 0.0..=8.0, "must be in [0, 8]")?;
        check_field!(self, amplitude_power, 0.0..=4.0, "must be in [0, 4]")?;
        check_field!(self, amplitude_persistence, 0.0..=1.0, "must be in [0, 1]")?;
        check_field!(self, parent_conditioning, 0.0..=2.0, "must be in [0, 2]")?;
        check_field!(self, tile, 16..=65_536, "must be in 16..=65536")?;
        Ok(())
    }
}

/// A prepared refinement: the input, its analysis and the settings. Rendering any window costs
/// memory proportional to the window (plus the analysis, proportional to the input), never to
/// the whole refined terrain.
#[derive(Debug)]
pub struct Refiner {
    input: Grid,
    cell: (f64, f64),
    georef: Option<relief_heightfield::GeoRef>,
    settings: RefineSettings,
    global: GlobalAnalysis,
    local: Option<LocalStats>,
    /// The `(gamma, a)` per band the new levels are drawn with (the global fit for the paper
    /// model, the fit on the finest levels for the spectral model).
    synthesis_fits: [BandFit; 3],
    spectral: Option<SpectralPlan>,
    /// Spectral model with LSA: per new level and band, the local amplitude factor on the grid
    /// of the finest observed detail level (mean square 1 over the terrain); the levels after
    /// the first blend in the broad window ([`RefineSettings::amplitude_persistence`]). One
    /// entry when every level uses the same factor.
    amplitude: Option<Vec<[Grid; 3]>>,
    /// Spectral model with parent conditioning: per new level `t` (index 0 unused, 1), per band,
    /// the factor that gives the parent factor mean square 1.
    parent_norm: Vec<[f32; 3]>,
    /// Spectral model with consistency and a factor of at least [`BLOCK_MEAN_CACHE_FACTOR`]:
    /// the mean of the synthetic detail over each input cell's block, per group of blocks
    /// about a tile wide, computed once when a window first needs it (`block_mean`). A window's correction reads the blocks
    /// [`crate::spectral::QL`] input cells around it; rendering the detail over all of them for
    /// every tile cost `(tile + 2 QL 2^n)^2 / tile^2` times the window (81x at x256: `refine
    /// --levels 8 --stream` of a 64^2 input took 18 min instead of seconds).
    block_means: Vec<std::sync::OnceLock<Vec<f64>>>,
    /// Cells of every inverse-DWT pass rendered (the work a test bounds).
    #[cfg(test)]
    rendered_cells: std::sync::atomic::AtomicU64,
    notes: Vec<String>,
}

/// Smallest refinement factor `2^n` whose detail block means are cached (below, the halo of
/// a window's correction is small against a tile).
pub(crate) const BLOCK_MEAN_CACHE_FACTOR: usize = 16;

impl Refiner {
    /// Analyses a void-free terrain (forward DWT, equations (2)-(4)) and prepares the synthesis.
    ///
    /// An input too small for the requested fit is not an error: the fit falls back to the
    /// levels available (or, below two levels, to a default decay), and [`Refiner::notes`]
    /// says so.
    pub fn new(hf: &Heightfield, settings: &RefineSettings) -> Result<Self> {
        settings.check()?;
        let n = settings.extra_levels;
        let (ow, oh) = (
            hf.width().checked_shl(n).unwrap_or(usize::MAX),
            hf.height().checked_shl(n).unwrap_or(usize::MAX),
        );
        if ow.checked_mul(oh).is_none_or(|c| c > MAX_CELLS) || ow >> n != hf.width() {
            return Err(WaveletError::param(
                "extra_levels",
                n,
                "the refined grid would exceed the 2^31-cell limit",
            ));
        }
        let mut notes = Vec::new();
        let top = max_levels(hf.width(), hf.height());
        let mut levels = match settings.fit.plan(hf.width(), hf.height()) {
            Ok((_, levels, _)) => levels,
            Err(WaveletError::TooFewLevels { .. }) => top,
            Err(e) => return Err(e),
        };
        if settings.model == Model::Spectral {
            levels = levels.max(settings.fine_levels.min(top));
        }
        let top = top as i64;
        let dec = decompose(hf, settings.basis(), levels)?;
        let global = global_lenient(&dec, top, &settings.fit, &mut notes);
        let mut local = None;
        if settings.method == Method::Lsa && settings.model == Model::Paper {
            local = match LocalStats::new(&dec, top, settings.window, &settings.fit) {
                Ok(l) => Some(l),
                Err(WaveletError::TooFewLevels { .. }) => {
                    let all = FitSettings {
                        min_level: 0,
                        ..settings.fit.clone()
                    };
                    match LocalStats::new(&dec, top, settings.window, &all) {
                        Ok(l) => {
                            notes.push(format!(
                                "LSA: fewer than 2 levels >= {}; the local fit uses every \
                                 level of the {} x {} input",
                                settings.fit.min_level,
                                hf.width(),
                                hf.height()
                            ));
                            Some(l)
                        }
                        Err(_) => {
                            notes.push(format!(
                                "LSA: the {} x {} input has fewer than 2 detail levels; the \
                                 global fit is used everywhere",
                                hf.width(),
                                hf.height()
                            ));
                            None
                        }
                    }
                }
                Err(e) => return Err(e),
            };
        }
        let (synthesis_fits, spectral) = match settings.model {
            Model::Paper => (global.fits, None),
            Model::Spectral => {
                let fit = FitSettings {
                    gamma_min: settings.fit.gamma_min.max(settings.min_gamma),
                    gamma_max: settings.fit.gamma_max.max(settings.min_gamma),
                    ..settings.fit.clone()
                };
                let fits = fine_fit(&global, settings.fine_levels, &fit, &mut notes);
                let beta = fits.map(|f| -(f.gamma + 2.0));
                (fits, Some(SpectralPlan::new(settings.basis(), n, beta)))
            }
        };
        let lsa = settings.model == Model::Spectral && settings.method == Method::Lsa;
        let maps = |window: usize| {
            amplitude_maps(
                &dec,
                window,
                settings.fit.variance_floor,
                settings.amplitude_power,
            )
        };
        let amplitude = lsa.then(|| maps(settings.window)).flatten().map(|narrow| {
            let r = settings.amplitude_persistence;
            let wide = (r < 1.0 && n > 1)
                .then(|| maps(BROAD_WINDOW * settings.window))
                .flatten();
            // The blends first, so that `narrow` moves in without a copy (peak memory).
            let blends: Vec<[Grid; 3]> = wide.map_or_else(Vec::new, |wide| {
                (1..n)
                    .map(|t| {
                        let keep = r.powi(t as i32);
                        std::array::from_fn(|b| blend_amplitude(&narrow[b], &wide[b], keep))
                    })
                    .collect()
            });
            std::iter::once(narrow).chain(blends).collect()
        });
        // The coefficients are not needed past the fits and maps: free them before the input
        // is copied (the peak of a large analysis).
        drop(dec);
        let input = Grid::from_heightfield(hf);
        let cached = spectral.is_some()
            && settings.consistency
            && (1usize << n.min(63)) >= BLOCK_MEAN_CACHE_FACTOR;
        let block_means = if cached {
            let g = render::block_group(settings.tile, 1usize << n);
            let groups = input.width.div_ceil(g) * input.height.div_ceil(g);
            (0..groups).map(|_| std::sync::OnceLock::new()).collect()
        } else {
            Vec::new()
        };
        let mut refiner = Self {
            input,
            amplitude,
            parent_norm: vec![[1.0; 3]],
            block_means,
            #[cfg(test)]
            rendered_cells: std::sync::atomic::AtomicU64::new(0),
            cell: hf.cell_size(),
            georef: hf.georef().cloned(),
            settings: settings.clone(),
            global,
            local,
            synthesis_fits,
            spectral,
            notes,
        };
        refiner.normalise_parents();
        Ok(refiner)
    }

    /// Notes on the analysis: fallbacks taken for small inputs (fewer fitted levels than asked,
    /// a default decay). Empty when everything went as configured.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The `(gamma, a)` per band ([`Band::ALL`] order) the new levels are drawn with: the global
    /// fit of equation (3) for [`Model::Paper`] GSA, the fit on the finest levels for
    /// [`Model::Spectral`].
    pub fn synthesis_fits(&self) -> &[BandFit; 3] {
        &self.synthesis_fits
    }

    /// The global statistics (always computed, also for LSA).
    pub fn analysis(&self) -> &GlobalAnalysis {
        &self.global
    }

    /// The settings.
    pub fn settings(&self) -> &RefineSettings {
        &self.settings
    }

    /// The local statistics as maps at input resolution (`None` for GSA).
    pub fn local_maps(&self) -> Option<LocalMaps> {
        self.local
            .as_ref()
            .map(|l| maps_from(l, self.input.width, self.input.height))
    }

    /// Size `(width, height)` of the refined terrain.
    pub fn output_size(&self) -> (usize, usize) {
        let n = self.settings.extra_levels;
        (self.input.width << n, self.input.height << n)
    }

    /// Standard deviations of the new coefficients (equation (5)) for every new level `t`
    /// (0 = first) at the input locations `[x0, x0 + w) x [y0, y0 + h)`: per level, three grids
    /// (H, V, D).
    fn sigma_maps(&self, x0: usize, y0: usize, w: usize, h: usize) -> Vec<[Vec<f32>; 3]> {
        let n = self.settings.extra_levels;
        let js: Vec<f64> = (0..n)
            .map(|t| (self.global.top_level + t as i64) as f64)
            .collect();
        match &self.local {
            None => js
                .iter()
                .map(|&j| {
                    Band::ALL.map(|b| {
                        let f = &self.synthesis_fits[b.index()];
                        vec![(0.5 * (f.a - j * f.gamma)).exp2() as f32; w * h]
                    })
                })
                .collect(),
            Some(local) => {
                let fits = local.fit_region(x0, y0, w, h);
                js.iter()
                    .map(|&j| {
                        let j = j as f32;
                        [0, 1, 2].map(|b| {
                            let (g, a) = &fits[b];
                            g.iter()
                                .zip(a)
                                .map(|(g, a)| (0.5 * (a - j * g)).exp2())
                                .collect()
                        })
                    })
                    .collect()
            }
        }
    }
}

/// Refines a void-free terrain by `settings.extra_levels` levels (whole grid).
pub fn refine(hf: &Heightfield, settings: &RefineSettings) -> Result<Heightfield> {
    Refiner::new(hf, settings)?.render(&NoProgress)
}

/// Refines only the window `[x, x + w) x [y, y + h)` of the refined grid (output cells); equal
/// bit for bit to the same window of [`refine`].
pub fn refine_window(
    hf: &Heightfield,
    settings: &RefineSettings,
    x: usize,
    y: usize,
    w: usize,
    h: usize,
) -> Result<Heightfield> {
    Refiner::new(hf, settings)?.render_window(x, y, w, h)
}
