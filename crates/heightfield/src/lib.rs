//! Core heightfield type of the relief workspace.
//!
//! A [`Heightfield`] is a regular grid of `f32` elevations in metres. Row 0 is the northern edge
//! and column 0 the western edge; cells may be non-square (`cell_x` east-west, `cell_y`
//! north-south, both in metres). Voids (nodata) are stored as `NaN`: every reader maps its nodata
//! value to `NaN` and every writer maps `NaN` back. A [`GeoRef`] is carried through unchanged by
//! every operation that keeps the grid's extent, so a GeoTIFF read and written again keeps its
//! georeference.
//!
//! This crate does no file I/O (that is `relief-io`'s job) so a project can depend on a method
//! crate without pulling image codecs in.
//!
//! # Coordinates
//! Continuous sampling uses *pixel coordinates*: sample `(row i, column j)` sits at `x = j`,
//! `y = i`. Resampling keeps the *extent* of the grid: output cell centres are placed at
//! `(j + 0.5) * w_in / w_out - 0.5` in input pixel coordinates, so a factor-4 reduction averages
//! 4x4 blocks with the right phase and a later factor-4 enlargement lines up with the input.
//!
//! # What it offers
//! * sampling ([`Heightfield::sample_bilinear`], [`Heightfield::sample_bicubic`]; both exact at
//!   grid nodes), resampling by any factor with a windowed-sinc low-pass when reducing
//!   ([`Heightfield::resample`]), crops;
//! * statistics, RMSE and PSNR over the elevation range ([`metrics`]);
//! * gradients, slopes and normals that respect non-square cells, and hillshade ([`terrain`]);
//! * harmonic void filling with a multigrid-initialised conjugate-gradient solver ([`fill`]);
//! * terrain-quality measures shared by the method crates: radial power spectrum slope and
//!   slope-angle histogram distance ([`metrics`]).
//!
//! ```
//! use relief_heightfield::Heightfield;
//! let hf = Heightfield::from_fn(64, 32, 10.0, 10.0, |x, y| (x as f32 * 0.1).sin() * 50.0 + y as f32);
//! let small = hf.resample(16, 8).unwrap();
//! assert_eq!((small.width(), small.height()), (16, 8));
//! assert_eq!(small.cell_size(), (40.0, 40.0));
//! ```
#![warn(missing_docs)]

pub mod bytes;
pub mod cg;
mod error;
pub mod fill;
mod grid;
pub mod metrics;
pub mod param;
mod progress;
mod resample;
pub mod rng;
mod sample;
pub mod terrain;
mod window;

pub use error::{HeightfieldError, Result};
pub use grid::{GeoRef, Heightfield, MAX_CELLS};
pub use param::ParamError;
pub use progress::{NoProgress, Progress, StopOnly};
pub use sample::{Kernel, cubic_weights, cubic_weights_f64};
pub use window::Window;
