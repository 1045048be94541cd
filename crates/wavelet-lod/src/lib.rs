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
//! # Levels, normalisation, alignment
//! * Level indices follow the paper: `j` grows towards finer levels; for an input whose larger
//!   side is `N`, `J = ceil(log2 N)`, the input is level `J`, its finest details are level
//!   `J - 1`, and the first synthesised level is `J` (so a 16 x 16 input has levels 0..=3 as in
//!   the paper's figures).
//! * The transform is "metric" (low-pass DC gain 1): approximations are in metres and details
//!   are elevation increments, so for a fractional Brownian surface `gamma = 2H` and the
//!   implied fractal dimension is `D = 3 - gamma / 2` ([`BandFit::fractal_dimension`]).
//!   Relation to PyWavelets: see [`Wavelet`].
//! * The refined lattice is vertex-aligned with the input: refined sample `2^n i` lies on input
//!   sample `i`; with all new details zero the refinement is the basis' interpolation (linear
//!   for CDF 5/3).
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
mod lift;
mod plot;
mod refine;
pub mod rng;
mod wavelet;

pub use analysis::{
    BandFit, FitSettings, GlobalAnalysis, LevelVariance, LocalMaps, analyze, analyze_local,
};
pub use dwt::{
    Band, Decomposition, DetailLevel, Grid, dwt1, idwt1, max_levels, size_at_depth, try_waverec2,
    wavedec2, waverec2, waverec2_owned,
};
pub use error::{Result, WaveletError};
pub use lift::Boundary;
pub use plot::{LogVariancePlot, PlotSeries, render_log_variance_plot};
pub use refine::{Method, RefineSettings, Refiner, refine, refine_window};
pub use wavelet::Wavelet;
