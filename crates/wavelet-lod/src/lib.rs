//! Wavelet detail synthesis for terrain: Perez, Fernandez and Lozano, "Adding Synthetic Detail
//! to Natural Terrain Using a Wavelet Approach" (section 5).
//!
//! A terrain is decomposed by a 2-D separable discrete wavelet transform ([`wavedec2`], lifting
//! implementation, four bases: [`Wavelet`]). Per detail band `(h, v, d)` and level `j` the
//! variance of the coefficients is measured, equation (2):
//! `sigma_j^2 = Var[d_j,k]` (taken as the mean square, the paper's zero-mean assumption), and a
//! line is fitted to the levels `j >= 3` (configurable, [`FitSettings::min_level`]),
//! equation (3): `log2 Var[d_j] = -j gamma + a`. New, finer levels `n` are drawn from
//! `N(0, 2^a 2^(-n gamma))`, equation (5), and the inverse DWT of the input (as the coarse
//! approximation) with the new detail levels gives the refined terrain.
//!
//! * **GSA** (section 5.1, [`Method::Gsa`]): one `(gamma, a)` per band for the whole terrain.
//! * **LSA** (section 5.2, [`Method::Lsa`]): equation (4), the same fit per input location from
//!   the coefficients of a `w x w` window around the location at every fitted level (the same
//!   number of coefficients at every level; `w` = 1, 3, 5, 7, the paper recommends 3), one
//!   `(gamma, a)` per band and location; new coefficients at level `n` above location `r` get
//!   the variance `2^a(r) 2^(-n gamma(r))`, equation (5).
//!
//! # Spectral model (the default; a departure from the paper)
//! On real DEMs the paper's independent Gaussian coefficients give added octaves with a
//! spectral slope of about -2 where the truth has -4.5 to -5.5 (every new octave comes out flat
//! inside), and LSA's `(gamma, a)` maps are constant on dyadic blocks. [`Model::Spectral`] (the
//! default, [`RefineSettings::default`]) therefore:
//! * fits `gamma` on the finest [`RefineSettings::fine_levels`] (4) observed levels only and
//!   keeps it at least [`RefineSettings::min_gamma`] (2.5: real spectra steepen towards fine
//!   scales, and the fit on a box-reduced input comes out below it);
//! * draws coloured coefficients: white numbers of the same hash filtered by a `5 x 5` kernel
//!   per new level and band, designed in the frequency domain so that the output's radially
//!   averaged power spectrum follows `k^-(gamma + 2)` inside every new octave (the basis'
//!   synthesis filters are divided out); the coefficient variance still follows equation (5);
//! * with LSA ([`Method::Lsa`], the default), modulates the amplitude by a local factor from
//!   the finest observed level (windowed mean square over its mean, so the total variance is
//!   kept), bilinearly interpolated to every coefficient position: no dyadic blocks, flat areas
//!   stay flat; the finer new levels blend that narrow amplitude with one from a 5 times wider
//!   window ([`RefineSettings::amplitude_persistence`]), so the finest texture also reaches
//!   smooth ground next to rough ground, while exactly flat ground (sea, lakes) stays flat;
//! * is area-consistent (pixel-is-area, the workspace convention): output block
//!   `[2^n i, 2^n (i + 1))` covers input cell `i`, and the box down-sampling of the output is
//!   the input (up to `f32` rounding). The output is `cubic(q * (input - box-down(D))) + D`,
//!   where `D` is the synthetic detail (the inverse DWT of the new levels over a zero
//!   approximation), `cubic` the Keys bicubic up-sampling (cell-centre aligned) and `q` a short
//!   coarse filter inverting `box-down(cubic(.))`: the smooth part carries the input and takes
//!   the detail's own block means out, as in a conditional simulation
//!   ([`RefineSettings::consistency`] switches the block-mean removal off);
//! * can condition the new coefficients on their parents ([`RefineSettings::parent_conditioning`]
//!   `kappa`, off by default): the coloured numbers of new level `t >= 1` are multiplied by
//!   `m^(kappa/2)` (normalised to mean square 1), `m` the mean square of the same band's
//!   coefficients of level `t - 1` in the `3 x 3` parents around (bilinear);
//! * uses CDF 9/7 by default (closer spectral slopes and histograms than CDF 5/3, whose
//!   linear-spline synthesis leaks each coarser synthetic level into the finer octaves).
//!
//! docs/WAVELET.md gives the measurements behind each choice (the `gamma` floor against the
//! per-DEM needs, the pivot and parent-conditioning trials, the flat-ground and swing figures)
//! and `examples/quality.rs` reproduces them.
//!
//! The paper's method stays available as [`Model::Paper`] ([`RefineSettings::paper`]: CDF 5/3,
//! LSA 3 x 3, vertex-aligned). Inputs too small for the fit are refined from the levels they
//! have, or with a default decay, and [`Refiner::notes`] says so. [`quality`] holds the
//! protocol of the measurements (spectral slope of the added octaves, slope and Laplacian
//! histogram distances, box consistency, detail-energy swing).
//!
//! # Levels, normalisation, alignment
//! * Level indices follow the paper: `j` grows towards finer levels; for an input whose larger
//!   side is `N`, `J = ceil(log2 N)`, the input is level `J`, its finest details are level
//!   `J - 1`, and the first synthesised level is `J` (so a 16 x 16 input has levels 0..=3 as in
//!   the paper's figures).
//! * The transform is "metric" (low-pass DC gain 1): approximations are in metres and details
//!   are elevation increments, so for a fractional Brownian surface `gamma = 2H` and the
//!   implied fractal dimension is `D = 3 - gamma / 2` ([`BandFit::fractal_dimension`]).
//!   Relation to PyWavelets: see [`Wavelet`].
//! * [`Model::Paper`]: the refined lattice is vertex-aligned with the input: refined sample
//!   `2^n i` lies on input sample `i`; with all new details zero the refinement is the basis'
//!   interpolation (linear for CDF 5/3). [`Model::Spectral`] is area-aligned (see above).
//! * Boundaries: whole-sample symmetric extension; any size, odd included (an axis of length
//!   `n` splits into `ceil(n/2)` low and `floor(n/2)` high samples).
//!
//! # On demand
//! The new coefficient of `(band, level, x, y)` is a pure function of
//! `(seed, band, level, x, y)` (SplitMix64 hash, Box-Muller), and [`Refiner::render_window`]
//! computes, level by level, only the lanes the inverse lifting steps need (the window plus
//! [`Wavelet::synthesis_margin`] samples per level). A window therefore equals the same window
//! of the full [`Refiner::render`] bit for bit, whatever the thread count, and costs memory
//! proportional to the window (the analysis, done once in [`Refiner::new`], is proportional to
//! the input). [`Refiner::render_strips`] streams the whole refined terrain strip by strip
//! (tiles in parallel) to a sink such as a file writer, so a refined grid larger than memory
//! never has to be held at once.
//!
//! # Guarantees and limits
//! * Perfect reconstruction up to `f32` rounding for every basis and size.
//! * Flat areas (zero variance) give finite statistics: variances are floored
//!   ([`FitSettings::variance_floor`]) and `gamma` is clamped into
//!   `[gamma_min, gamma_max]` (the intercept is refitted with the slope fixed), so no NaN
//!   appears; inputs with voids are rejected (fill them first).
//! * The synthesised detail is statistically, not geographically, faithful: it reproduces the
//!   variance decay, not the actual landforms, and it is Gaussian (no ridges or erosion).
//!
//! ```
//! use relief_heightfield::Heightfield;
//! use relief_wavelet_lod::{Method, RefineSettings, Refiner};
//!
//! // A rough test surface, 64 x 64 cells of 30 m.
//! let hf = Heightfield::from_fn(64, 64, 30.0, 30.0, |x, y| {
//!     let (x, y) = (x as f32, y as f32);
//!     100.0 * (x * 0.11).sin() * (y * 0.07).cos() + 20.0 * (x * 0.9 + y * 0.4).sin()
//! });
//! let settings = RefineSettings { method: Method::Lsa, window: 3, extra_levels: 2, seed: 7,
//!                                 ..Default::default() };
//! let refiner = Refiner::new(&hf, &settings).unwrap();
//! let fit = refiner.analysis().fits[0];
//! assert!(fit.gamma.is_finite());
//! let full = refiner.render(&relief_heightfield::NoProgress).unwrap();
//! assert_eq!((full.width(), full.height()), (256, 256));
//! // Any window alone is the same window of the full run.
//! let win = refiner.render_window(100, 40, 32, 16).unwrap();
//! assert_eq!(win.as_slice(), full.crop(100, 40, 32, 16).unwrap().as_slice());
//! ```
#![warn(missing_docs)]

mod analysis;
mod dwt;
mod error;
mod job;
mod lift;
mod plot;
pub mod quality;
mod refine;
pub mod rng;
mod spectral;
mod wavelet;

pub use analysis::{
    BandFit, FitSettings, GlobalAnalysis, LevelVariance, LocalMaps, analyze, analyze_local,
};
pub use dwt::{
    Band, Decomposition, DetailLevel, Grid, dwt1, idwt1, max_levels, size_at_depth, try_waverec2,
    wavedec2, waverec2, waverec2_owned,
};
pub use error::{Result, WaveletError};
pub use job::{
    AnalyzeFigures, AnalyzeSettings, Analyzed, LocalBand, MapSummary, RefineFigures, Refined,
};
pub use lift::Boundary;
pub use plot::{LogVariancePlot, PlotSeries, render_log_variance_plot};
pub use refine::{Method, Model, RefineSettings, Refiner, refine, refine_window};
pub use wavelet::Wavelet;
