//! Drainage and erosion on heightfields.
//!
//! * **Depressions** ([`depression`]): priority-flood filling (Barnes, Lehman and Mulla 2014,
//!   plain and epsilon), least-cost breaching (Lindsay 2016), drainage across flats (Barnes et
//!   al. 2014).
//! * **Flow** ([`flow`]): D8 and multiple-flow-direction routing, drainage area in m^2 on
//!   non-square cells, Strahler order, channel reaches as GeoJSON, watersheds, HAND; the
//!   `relief flow` job ([`flow::job::FlowSettings`]).
//! * **Erosion** ([`erode`]): stream-power incision with uplift and hillslope diffusion
//!   (Braun and Willett 2013, step for step as fastscapelib), virtual-pipe hydraulic erosion
//!   with sediment transport (Mei et al. 2007, Št'ava et al. 2008), talus relaxation with a
//!   weathering depth (Musgrave et al. 1989); the `relief erode` job with presets
//!   ([`erode::job::ErodeSettings`]).
//! * **Masks** ([`masks`]): slope, curvatures, log area, wetness index, HAND, height bands,
//!   erosion and deposition, and RGBA splat weights.
//! * **Statistics** ([`stats`]): pits per km^2, closed-depression fill depth and the
//!   drainage-area exponent, exactly as `shared/tools/terrain_quality.py` defines them.
//!
//! Voids (`NaN`) are flow off the map: a cell beside a void drains like a cell on the edge, and
//! both are outlets (as in RichDEM and fastscapelib).
//!
//! Exactness (tests in `tests/`): plain filling equals RichDEM's cell for cell, epsilon filling
//! differs only where equal cells are queued in another order, D8 drainage area equals
//! fastscapelib's router and the stream-power step equals fastscapelib's, all on real or
//! non-square rasters. Same input, same bytes, whatever the thread count.
//!
//! ```
//! use relief_landscape::{flow, grid::Grid};
//! // A tilted plane with a pit: filled, routed, every cell drains to an edge (the edges are
//! // outlets), most of them to the west edge.
//! let (w, h) = (8, 5);
//! let mut z: Vec<f32> = (0..w * h).map(|i| (i % w) as f32).collect();
//! z[2 * w + 4] = -5.0;
//! let grid = Grid { width: w, height: h, cell_x: 10.0, cell_y: 10.0 };
//! let r = flow::route(z, grid, &flow::RouteOptions::default());
//! assert_eq!(r.sinks(), 0);
//! let area = r.accumulation(None);
//! let west: f64 = (0..h).map(|y| area[y * w]).sum();
//! let total: f64 = (0..w * h).filter(|&i| r.outlet[i]).map(|i| area[i]).sum();
//! assert_eq!(total, 100.0 * (w * h) as f64);
//! assert!(west > 0.5 * total);
//! ```
#![warn(missing_docs)]

pub mod depression;
pub mod elev;
pub mod erode;
mod error;
pub mod flow;
pub mod grid;
pub mod grow;
pub mod landform;
pub mod masks;
pub mod radix;
pub mod stats;

pub use error::{LandscapeError, Result};
