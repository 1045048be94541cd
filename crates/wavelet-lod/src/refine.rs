//! New levels of detail: GSA (section 5.1) and LSA (section 5.2), generated on demand.

use rayon::prelude::*;
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
        if !(1..=12).contains(&self.extra_levels) {
            return Err(WaveletError::param(
                "extra_levels",
                self.extra_levels,
                "must be in 1..=12",
            ));
        }
        if !(2..=8).contains(&self.fine_levels) {
            return Err(WaveletError::param(
                "fine_levels",
                self.fine_levels,
                "must be in 2..=8",
            ));
        }
        if !(0.0..=8.0).contains(&self.min_gamma) {
            return Err(WaveletError::param(
                "min_gamma",
                self.min_gamma,
                "must be in [0, 8]",
            ));
        }
        if !(0.0..=4.0).contains(&self.amplitude_power) {
            return Err(WaveletError::param(
                "amplitude_power",
                self.amplitude_power,
                "must be in [0, 4]",
            ));
        }
        if !(0.0..=1.0).contains(&self.amplitude_persistence) {
            return Err(WaveletError::param(
                "amplitude_persistence",
                self.amplitude_persistence,
                "must be in [0, 1]",
            ));
        }
        if !(16..=65_536).contains(&self.tile) {
            return Err(WaveletError::param(
                "tile",
                self.tile,
                "must be in 16..=65536",
            ));
        }
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
    notes: Vec<String>,
}

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
        let input = Grid::from_heightfield(hf);
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
            let mut per_level = vec![narrow.clone()];
            if let Some(wide) = wide {
                per_level.extend((1..n).map(|t| {
                    let keep = r.powi(t as i32);
                    std::array::from_fn(|b| blend_amplitude(&narrow[b], &wide[b], keep))
                }));
            }
            per_level
        });
        Ok(Self {
            input,
            amplitude,
            cell: hf.cell_size(),
            georef: hf.georef().cloned(),
            settings: settings.clone(),
            global,
            local,
            synthesis_fits,
            spectral,
            notes,
        })
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

    /// Renders the window `[x, x + w) x [y, y + h)` of the refined terrain (output cells) into a
    /// row-major buffer. The values are bit-identical to the same window of [`Refiner::render`].
    pub fn render_window_values(&self, x: usize, y: usize, w: usize, h: usize) -> Result<Vec<f32>> {
        let (ow, oh) = self.output_size();
        if w == 0
            || h == 0
            || x.checked_add(w).is_none_or(|e| e > ow)
            || y.checked_add(h).is_none_or(|e| e > oh)
        {
            return Err(WaveletError::param(
                "window",
                format!("x={x} y={y} w={w} h={h}"),
                "must be non-empty and inside the refined grid",
            ));
        }
        Ok(self.render_region(x, y, w, h))
    }

    /// [`Refiner::render_window_values`] as a heightfield (cell size divided by
    /// `2^extra_levels`; the georeference follows, see the crate docs on alignment).
    pub fn render_window(&self, x: usize, y: usize, w: usize, h: usize) -> Result<Heightfield> {
        let data = self.render_window_values(x, y, w, h)?;
        self.wrap(x, y, w, h, data)
    }

    fn wrap(&self, x: usize, y: usize, w: usize, h: usize, data: Vec<f32>) -> Result<Heightfield> {
        let s = 1.0 / (1u64 << self.settings.extra_levels) as f64;
        let hf = Heightfield::new(w, h, data, self.cell.0 * s, self.cell.1 * s)?;
        // Refined sample k is centred on input pixel coordinate k * s (vertex-aligned lattice:
        // sample 2^n i lies on input sample i), so its corner is at k * s + (1 - s) / 2.
        // The spectral model is area-consistent: output block `[2^n i, 2^n (i + 1))` covers
        // input cell `i`, the extent is the input's.
        let shift = match self.settings.model {
            Model::Paper => 0.5 - 0.5 * s,
            Model::Spectral => 0.0,
        };
        Ok(hf.with_georef(
            self.georef
                .as_ref()
                .map(|g| g.window(x as f64 * s + shift, y as f64 * s + shift, s, s)),
        ))
    }

    /// Renders the whole refined terrain, tile by tile in parallel.
    pub fn render(&self, progress: &dyn Progress) -> Result<Heightfield> {
        let (ow, oh) = self.output_size();
        let t = self.settings.tile;
        let strips = oh.div_ceil(t);
        let tiles_x = ow.div_ceil(t);
        progress.begin("wavelet-lod: synthesise tiles", (strips * tiles_x) as u64);
        let mut data = vec![0.0f32; ow * oh];
        data.par_chunks_mut(ow * t)
            .enumerate()
            .for_each(|(sy, strip)| {
                let y0 = sy * t;
                let th = strip.len() / ow;
                for tx in 0..tiles_x {
                    let x0 = tx * t;
                    let tw = t.min(ow - x0);
                    let tile = self.render_region(x0, y0, tw, th);
                    for (r, row) in tile.chunks(tw).enumerate() {
                        strip[r * ow + x0..r * ow + x0 + tw].copy_from_slice(row);
                    }
                    progress.advance(1);
                }
            });
        self.wrap(0, 0, ow, oh, data)
    }

    /// Renders the whole refined terrain as horizontal strips of `strip` rows (the last one may
    /// be shorter), top to bottom, and hands each to `sink` as `(first row, row-major values of
    /// full width)`, in order. The tiles of a strip ([`RefineSettings::tile`] wide) are rendered
    /// in parallel. Memory is proportional to `strip * width` (plus the analysis), never to the
    /// whole refined terrain, so a terrain larger than memory can be streamed to a writer; the
    /// values are bit-identical to [`Refiner::render`]. The first error of `sink` stops the
    /// rendering and is returned.
    pub fn render_strips<E: From<WaveletError>>(
        &self,
        strip: usize,
        progress: &dyn Progress,
        mut sink: impl FnMut(usize, &[f32]) -> std::result::Result<(), E>,
    ) -> std::result::Result<(), E> {
        let (ow, oh) = self.output_size();
        if strip == 0 || strip.checked_mul(ow).is_none_or(|c| c > MAX_CELLS) {
            return Err(WaveletError::param(
                "strip",
                strip,
                "must be >= 1 and strip * width must stay within the cell limit",
            )
            .into());
        }
        let t = self.settings.tile;
        let tiles_x = ow.div_ceil(t);
        let strips = oh.div_ceil(strip);
        progress.begin("wavelet-lod: synthesise strips", strips as u64);
        let mut buf = vec![0.0f32; strip.min(oh) * ow];
        for s in 0..strips {
            let y0 = s * strip;
            let sh = strip.min(oh - y0);
            let tiles: Vec<Vec<f32>> = (0..tiles_x)
                .into_par_iter()
                .map(|tx| {
                    let x0 = tx * t;
                    self.render_region(x0, y0, t.min(ow - x0), sh)
                })
                .collect();
            // Row by row in parallel (a serial copy would leave the other threads idle).
            buf[..sh * ow]
                .par_chunks_mut(ow)
                .enumerate()
                .for_each(|(r, row)| {
                    for (tx, tile) in tiles.iter().enumerate() {
                        let x0 = tx * t;
                        let tw = t.min(ow - x0);
                        row[x0..x0 + tw].copy_from_slice(&tile[r * tw..(r + 1) * tw]);
                    }
                });
            sink(y0, &buf[..sh * ow])?;
            progress.advance(1);
        }
        Ok(())
    }

    /// The window at the finest level, computed from the input through every new level with
    /// only the lanes each inverse step needs (section 5, "generated when needed").
    fn render_region(&self, x: usize, y: usize, w: usize, h: usize) -> Vec<f32> {
        match &self.spectral {
            Some(plan) if self.settings.extra_levels > 0 => self.render_spectral(plan, x, y, w, h),
            _ => self.render_pass(x, y, w, h, true),
        }
    }

    /// The spectral model's window: the smooth part `cubic(q * (input - box-down(D)))` plus the
    /// synthetic detail `D` (the inverse DWT of the new levels over a zero approximation). `q`
    /// inverts `box-down(cubic(.))`, so the box down-sampling of the output is the input (up to
    /// rounding): the detail's own block means are taken out through the smooth part, as in a
    /// conditional simulation. Every value depends only on its position (fixed summation
    /// orders), so windows stay bit-identical to the full run.
    fn render_spectral(
        &self,
        plan: &SpectralPlan,
        x: usize,
        y: usize,
        w: usize,
        h: usize,
    ) -> Vec<f32> {
        let up = &plan.cubic;
        let f = up.factor;
        let (iw, ih) = (self.input.width, self.input.height);
        let correct = self.settings.consistency;
        // Coarse cells the cubic reads, then the cells the inverse filter reads around them.
        let (gx0, gx1) = up.coarse_range(x, x + w, iw);
        let (gy0, gy1) = up.coarse_range(y, y + h, ih);
        let ql = QL as isize;
        let span = |g0: usize, g1: usize, n: usize| {
            let (mut lo, mut hi) = (usize::MAX, 0usize);
            for i in g0 as isize - ql..g1 as isize + ql {
                let r = reflect(i, n);
                lo = lo.min(r);
                hi = hi.max(r + 1);
            }
            (lo, hi)
        };
        let (rx0, rx1) = span(gx0, gx1, iw);
        let (ry0, ry1) = span(gy0, gy1, ih);
        // The detail over the window, or over every block the correction reads (which holds
        // the window).
        let (dx0, dx1, dy0, dy1) = if correct {
            (
                (rx0 * f).min(x),
                (rx1 * f).max(x + w),
                (ry0 * f).min(y),
                (ry1 * f).max(y + h),
            )
        } else {
            (x, x + w, y, y + h)
        };
        let dw = dx1 - dx0;
        let detail = self.render_pass(dx0, dy0, dw, dy1 - dy0, false);
        // Coarse residual s = input - box-down(D) over [rx0, rx1) x [ry0, ry1).
        let sw = rx1 - rx0;
        let mut s = vec![0.0f32; sw * (ry1 - ry0)];
        let inv = 1.0 / (f * f) as f64;
        for (j, row) in s.chunks_mut(sw).enumerate() {
            let cy = ry0 + j;
            for (i, v) in row.iter_mut().enumerate() {
                let cx = rx0 + i;
                let mut mean = 0.0f64;
                if correct {
                    for r in 0..f {
                        let o = (cy * f + r - dy0) * dw + cx * f - dx0;
                        mean += detail[o..o + f].iter().map(|&z| z as f64).sum::<f64>();
                    }
                    mean *= inv;
                }
                *v = (self.input.data[cy * iw + cx] as f64 - mean) as f32;
            }
        }
        // g = q * s (separable, symmetric reflection) over [gx0, gx1) x [gy0, gy1).
        let q = &up.inverse;
        let gw = gx1 - gx0;
        let mut tq = vec![0.0f32; gw * (ry1 - ry0)];
        let qidx: Vec<usize> = (gx0..gx1)
            .flat_map(|c| {
                (0..q.len()).map(move |k| reflect(c as isize + k as isize - ql, iw) - rx0)
            })
            .collect();
        for (row, srow) in tq.chunks_mut(gw).zip(s.chunks(sw)) {
            for (v, idx) in row.iter_mut().zip(qidx.chunks(q.len())) {
                let mut acc = 0.0f32;
                for (&qk, &i) in q.iter().zip(idx) {
                    acc += qk * srow[i];
                }
                *v = acc;
            }
        }
        let mut g = vec![0.0f32; gw * (gy1 - gy0)];
        for (j, row) in g.chunks_mut(gw).enumerate() {
            let c = (gy0 + j) as isize;
            for (k, &qk) in q.iter().enumerate() {
                let src = reflect(c + k as isize - ql, ih) - ry0;
                row.iter_mut()
                    .zip(&tq[src * gw..(src + 1) * gw])
                    .for_each(|(a, b)| *a += qk * b);
            }
        }
        // Cubic up-sampling of g to the window, rows then columns, plus the detail.
        // Taps of every window column, computed once for all rows.
        let taps: Vec<([usize; 4], [f32; 4])> = (x..x + w)
            .map(|o| {
                let (off, wt) = up.phases[o % f];
                let base = (o / f) as isize + off;
                (
                    [0, 1, 2, 3].map(|t| reflect(base + t as isize, iw) - gx0),
                    wt,
                )
            })
            .collect();
        let mut th = vec![0.0f32; w * (gy1 - gy0)];
        for (row, grow) in th.chunks_mut(w).zip(g.chunks(gw)) {
            for (v, (idx, wt)) in row.iter_mut().zip(&taps) {
                let mut acc = 0.0f32;
                for (&i, &wv) in idx.iter().zip(wt) {
                    acc += wv * grow[i];
                }
                *v = acc;
            }
        }
        let mut out = vec![0.0f32; w * h];
        for (r, row) in out.chunks_mut(w).enumerate() {
            let o = y + r;
            let (off, wt) = up.phases[o % f];
            let base = (o / f) as isize + off;
            for (t, &wv) in wt.iter().enumerate() {
                let src = reflect(base + t as isize, ih) - gy0;
                row.iter_mut()
                    .zip(&th[src * w..(src + 1) * w])
                    .for_each(|(a, b)| *a += wv * b);
            }
            let d = &detail[(o - dy0) * dw + x - dx0..(o - dy0) * dw + x - dx0 + w];
            row.iter_mut().zip(d).for_each(|(a, b)| *a += b);
        }
        out
    }

    /// The inverse DWT of the new levels over the approximation `input` (`with_input`) or over
    /// a zero approximation (the spectral model's detail alone).
    fn render_pass(&self, x: usize, y: usize, w: usize, h: usize, with_input: bool) -> Vec<f32> {
        let n = self.settings.extra_levels;
        if n == 0 {
            let mut out = Vec::with_capacity(w * h);
            for r in y..y + h {
                out.extend_from_slice(
                    &self.input.data[r * self.input.width + x..r * self.input.width + x + w],
                );
            }
            return out;
        }
        let wavelet = self.settings.basis();
        let margin = wavelet.synthesis_margin();
        let (iw, ih) = (self.input.width, self.input.height);
        // Plans from the finest level down to the input.
        let mut plans = Vec::with_capacity(n as usize);
        let (mut ax, mut bx, mut ay, mut by) = (x, x + w, y, y + h);
        for t in (1..=n).rev() {
            let px = AxisPlan::new(iw << t, ax, bx, margin);
            let py = AxisPlan::new(ih << t, ay, by, margin);
            (ax, bx, ay, by) = (px.e0, px.e1, py.e0, py.e1);
            plans.push((px, py));
        }
        plans.reverse();
        // Level 0: the input itself is the approximation at level J (zero for the spectral
        // model's detail).
        let mut cur = Vec::with_capacity((bx - ax) * (by - ay));
        for r in ay..by {
            if with_input {
                cur.extend_from_slice(&self.input.data[r * iw + ax..r * iw + bx]);
            } else {
                cur.resize(cur.len() + bx - ax, 0.0);
            }
        }
        let (lx0, ly0, lw, lh) = (ax, ay, bx - ax, by - ay);
        let scheme = wavelet.scheme();
        let sigmas = self.sigma_maps(lx0, ly0, lw, lh);
        for (t, (px, py)) in plans.iter().enumerate() {
            let sig = &sigmas[t];
            let t = t as u32;
            let level = self.global.top_level + t as i64;
            let make_band = |band: Band, xs: (usize, usize), ys: (usize, usize)| -> Vec<f32> {
                let (cw, ch) = (xs.1 - xs.0, ys.1.max(ys.0) - ys.0);
                let mut out = vec![0.0f32; cw * ch];
                let s = &sig[band.index()];
                if let Some(plan) = &self.spectral {
                    let kern = &plan.kernels[t as usize][band.index()];
                    colour_noise(
                        self.settings.seed,
                        band,
                        level,
                        xs.0,
                        ys.0,
                        cw,
                        ch,
                        kern,
                        &mut out,
                    );
                    let sigma = s.first().copied().unwrap_or(0.0);
                    match &self.amplitude {
                        None => out.iter_mut().for_each(|v| *v *= sigma),
                        Some(maps) => {
                            let map = &maps[(t as usize).min(maps.len() - 1)][band.index()];
                            // Coefficient k of new level t lies at input coordinate
                            // (k + 1/2) / 2^t - 1/2; the amplitude grid at half the input
                            // resolution. Bilinear, so the amplitude has no steps.
                            let inv = 1.0 / (1u64 << t) as f32;
                            let coord = |k: usize| ((k as f32 + 0.5) * inv - 0.5) * 0.5 - 0.25;
                            let xw: Vec<(usize, usize, f32)> = (0..cw)
                                .map(|k| lerp_index(coord(xs.0 + k), map.width))
                                .collect();
                            for (r, row) in out.chunks_mut(cw.max(1)).enumerate().take(ch) {
                                let (y0, y1, fy) = lerp_index(coord(ys.0 + r), map.height);
                                let (r0, r1) = (
                                    &map.data[y0 * map.width..(y0 + 1) * map.width],
                                    &map.data[y1 * map.width..(y1 + 1) * map.width],
                                );
                                for (v, &(x0, x1, fx)) in row.iter_mut().zip(&xw) {
                                    let a = r0[x0] + fx * (r0[x1] - r0[x0]);
                                    let b = r1[x0] + fx * (r1[x1] - r1[x0]);
                                    *v *= sigma * (a + fy * (b - a));
                                }
                            }
                        }
                    }
                    return out;
                }
                for (r, row) in out.chunks_mut(cw.max(1)).enumerate().take(ch) {
                    let gy = ys.0 + r;
                    let key = row_key(self.settings.seed, band.index(), level, gy);
                    fill_normals(key, xs.0, row);
                    let sy = ((gy >> t) - ly0) * lw;
                    for (k, v) in row.iter_mut().enumerate() {
                        let sx = ((xs.0 + k) >> t) - lx0;
                        *v *= s[sy + sx];
                    }
                }
                out
            };
            let hb = make_band(Band::H, (px.e0, px.e1), (py.o0, py.o1));
            let vb = make_band(Band::V, (px.o0, px.o1), (py.e0, py.e1));
            let db = make_band(Band::D, (px.o0, px.o1), (py.o0, py.o1));
            cur = inverse_level_window(scheme, Boundary::Symmetric, px, py, cur, hb, vb, db, false);
        }
        cur
    }
}

/// Bilinear interpolation indices `(i0, i1, fraction)` of coordinate `u` on an axis of `n`
/// samples (clamped at the ends).
#[inline]
fn lerp_index(u: f32, n: usize) -> (usize, usize, f32) {
    if n <= 1 || u <= 0.0 {
        return (0, 0, 0.0);
    }
    let last = (n - 1) as f32;
    if u >= last {
        return (n - 1, n - 1, 0.0);
    }
    let i = u as usize;
    (i, i + 1, u - i as f32)
}

/// Side of the broad amplitude window, in statistics windows
/// ([`RefineSettings::amplitude_persistence`]).
const BROAD_WINDOW: usize = 5;

/// `m^keep M^(1 - keep)` per cell, renormalised to mean square 1 (a geometric blend, so an
/// exactly flat cell, `m = 0`, stays 0).
fn blend_amplitude(narrow: &Grid, wide: &Grid, keep: f64) -> Grid {
    let data: Vec<f64> = narrow
        .data
        .iter()
        .zip(&wide.data)
        .map(|(&m, &w)| (m as f64).powf(keep) * (w as f64).powf(1.0 - keep))
        .collect();
    let ms = data.iter().map(|v| v * v).sum::<f64>() / data.len().max(1) as f64;
    let norm = if ms > 0.0 { ms.sqrt().recip() } else { 1.0 };
    Grid {
        width: narrow.width,
        height: narrow.height,
        data: data.iter().map(|v| (v * norm) as f32).collect(),
    }
}

/// The local amplitude factors of the spectral model with LSA, per band: the square root of the
/// windowed mean square of the finest observed detail level over its mean (so the factor has
/// mean square 1 and the total variance of equation (5) is kept: this normalisation also removes
/// the bias a logarithmic average of local variances would have). Flat areas get a factor near 0,
/// rough ones above 1. `None` when the input has no detail level.
fn amplitude_maps(
    dec: &crate::dwt::Decomposition,
    window: usize,
    floor: f64,
    power: f64,
) -> Option<[Grid; 3]> {
    let finest = dec.details.last()?;
    if Band::ALL.iter().any(|&b| finest.band(b).is_empty()) {
        return None;
    }
    Some(Band::ALL.map(|b| {
        // The last coefficient of a high-pass lane of even length sees the mirrored boundary
        // (a first rather than a second difference on a slope): it is replaced by its
        // neighbour so that the border does not get a spuriously large amplitude.
        let mut band = finest.band(b).clone();
        let (w, h) = (band.width, band.height);
        if w >= 2 {
            for r in 0..h {
                band.data[r * w + w - 1] = band.data[r * w + w - 2];
            }
        }
        if h >= 2 {
            let (head, tail) = band.data.split_at_mut((h - 1) * w);
            tail[..w].copy_from_slice(&head[(h - 2) * w..]);
        }
        let g = crate::analysis::windowed_log_variance(&band, window, floor);
        let lin: Vec<f64> = g.data.iter().map(|&v| (power * v as f64).exp2()).collect();
        let mean = lin.iter().sum::<f64>() / lin.len() as f64;
        let mean = if mean > 0.0 { mean } else { 1.0 };
        Grid {
            width: g.width,
            height: g.height,
            data: lin.iter().map(|v| (v / mean).sqrt() as f32).collect(),
        }
    }))
}

/// Coloured coefficients of the spectral model for the band region `[x0, x0 + w) x
/// [y0, y0 + h)`: white numbers of the coefficient hash (the same stream as the paper model)
/// filtered by the `KS x KS` kernel. Every value depends only on its position, never on the
/// region, so windows and tiles agree bit for bit.
#[allow(clippy::too_many_arguments)]
fn colour_noise(
    seed: u64,
    band: Band,
    level: i64,
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
    kern: &[f32; KS * KS],
    out: &mut [f32],
) {
    if w == 0 || h == 0 {
        return;
    }
    let ew = w + 2 * KR;
    let mut white = vec![0.0f32; ew * (h + 2 * KR)];
    for (r, row) in white.chunks_mut(ew).enumerate() {
        let gy = (y0 + r).wrapping_sub(KR);
        fill_normals(
            row_key(seed, band.index(), level, gy),
            x0.wrapping_sub(KR),
            row,
        );
    }
    for (r, orow) in out.chunks_mut(w).enumerate().take(h) {
        orow.iter_mut().for_each(|v| *v = 0.0);
        for q in 0..KS {
            let src = &white[(r + q) * ew..(r + q + 1) * ew];
            let taps = &kern[q * KS..(q + 1) * KS];
            for (k, v) in orow.iter_mut().enumerate() {
                let win = &src[k..k + KS];
                let mut acc = 0.0f32;
                for (a, b) in taps.iter().zip(win) {
                    acc += a * b;
                }
                *v += acc;
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
