//! Drainage and erosion on heightfields.
//!
//! * **Depressions** ([`depression`]): priority-flood filling (Barnes, Lehman and Mulla 2014,
//!   plain and epsilon), least-cost breaching (Lindsay 2016), drainage across flats (Barnes et
//!   al. 2014).
//! * **Flow** ([`flow`]): D8 and multiple-flow-direction routing, drainage area in m^2 on
//!   non-square cells, Strahler order, channel reaches as GeoJSON, watersheds, HAND.
//!
//! Voids (`NaN`) are flow off the map: a cell beside a void drains like a cell on the edge.
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
pub mod masks;
pub mod stats;

pub use error::{LandscapeError, Result};
