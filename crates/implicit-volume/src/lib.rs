//! 3D landforms on implicit construction trees: Paris, Galin, Peytavie, Guérin, Gain,
//! *Terrain Amplification with Implicit 3D Features* (JFIG 2018).
//!
//! * [`geology`]: the geology tree G of section 3: resistance `rho(p)` in `[0, 1]` from strata
//!   with per-layer hardness, noise, blends, max/min, warps (folds) and faults (a half-space
//!   offset with a discontinuity).
//! * [`tree`]: the terrain tree T of section 3: field `f`, surface `f = T` ([`THRESHOLD`]),
//!   matter where `f > T`. Skeletal primitives (sphere, capsule, cone, ellipsoid) with the
//!   compact cubic falloff `e (1 - d^2/R^2)^3`, the heightfield primitive made by
//!   implicitisation of a DEM (its surface is exactly the DEM's bilinear interpolant),
//!   operators blend, union, intersection, difference (carve), smooth blend, noise warp, and a
//!   BVH of blend nodes over compact supports. Nodes are 40-byte records in a flat arena.
//! * [`scene`]: the generators of section 4. Shallow erosion (4.1): Poisson-sphere samples
//!   near the surface, a negative sphere per sample with energy from
//!   `e(rho, sigma) = sigma (1 - rho)(1 - beta) + sigma beta`, samples under a threshold
//!   discarded; sea (sigma from height above sea level, figure 5, times accessibility from the
//!   sea, plus sea caves), wind and rain. Karst (4.2): modified invasion percolation from the
//!   DEM's sinkholes, least resistance first with a random perturbation `epsilon`, carving only
//!   where `rho < rho0`, new candidates on the lower hemisphere, Poisson rejection, stop on a
//!   resistance threshold or a budget; passages are ellipsoids flattened along the bedding with
//!   radii varying step to step (slots, not round holes, where they meet a cliff). Landforms:
//!   hoodoos (figure 3), arches, floating islands (clusters grown from high-relief sites, flat
//!   tops over jagged strata-ledged undersides).
//!   Every effect takes a [`Region`] (painted per-cell mask and/or 3D box) and a seed.
//! * [`mesh`]: chunked marching tetrahedra with edge-key welding (watertight, manifold) and
//!   normals from the analytic field gradient (the DEM surface's slopes interpolated from its
//!   nodes, [`Scene::shading_normal`], so the relief shades smoothly rather than one facet per
//!   DEM cell); plain `Vec<[f32; 3]>` / `Vec<[u32; 3]>` output.
//! * [`mod@render`]: Lipschitz sphere tracing (interval-proven empty balls skipped, the carving-free
//!   tree bounding steps in air, cone-limited minimum step) to an RGB8 buffer (sun with shadows,
//!   ground-bounce and sky fill lights, the same shading normals), and vertical sections.
//! * [`mod@simplify`]: quadric edge-collapse simplification to a triangle budget that keeps the
//!   mesh watertight and manifold.
//! * [`job`]: the `volume` job (recipe + mesh + render settings, serde) run by `relief volume`
//!   and the pipeline's `volume` stage.
//! * [`recipe`]: feature lists (`sea,caves,karst,...`) with parameters scaled to the DEM, as used
//!   by `relief volume` and the pipeline's `volume` stage.
//!
//! # Guarantees
//! Same inputs and seeds give identical bytes whatever the rayon thread count: random numbers
//! are counter-based hashes of (seed, item), parallel loops collect in order, and the
//! percolation itself is sequential. Meshes of closed scenes are watertight 2-manifolds.
//! Not guaranteed: physical accuracy (the method is phenomenological, like the paper), nor
//! that an effect finds room (e.g. a karst needs sinkholes and soft rock).
//!
//! ```
//! use relief_heightfield::Heightfield;
//! use relief_implicit_volume::*;
//! let hf = Heightfield::from_fn(40, 40, 5.0, 5.0, |x, y| 20.0 + 0.3 * (x as f32 - 20.0).abs() + 0.1 * y as f32);
//! let geo = Geology::layered_default([100.0, 100.0, 20.0], 10.0, 1).unwrap();
//! let mut b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
//! b.karst(&KarstSettings { budget: 50, ..Default::default() }, &Region::everywhere()).unwrap();
//! let scene = b.build(true).unwrap();
//! let (mesh, _) = polygonize(&scene, &MeshSettings { cells: [24, 24, 16], ..Default::default() }).unwrap();
//! assert_eq!(topology(&mesh).bad_edges, 0);
//! ```
#![warn(missing_docs)]

#[macro_use]
mod error;
pub mod geology;
pub mod job;
pub mod look;
pub mod material;
pub mod math;
pub mod memory;
pub mod mesh;
pub mod recipe;
pub mod render;
pub mod scene;
pub mod simplify;
pub mod tree;

pub use error::{Error, Result};
pub use geology::{GeoId, Geology, GeologySpec, Layer};
pub use job::{Built, EffectFigures, VolumeFigures, VolumeJob, VolumeOutput};
pub use look::{Openings, SurfaceLook, surface_look, surface_openings};
pub use math::{Aabb, V3};
pub use mesh::{
    Mesh, MeshReport, MeshSettings, Topology, field_normals, polygonize, polygonize_grid,
    polygonize_with_progress, sample_grid, topology,
};
pub use recipe::{
    Densities, Deviation, Dimensions, Feature, Highlight, Recipe, RecipeReport, SeaDetection,
    SeaKind, build_recipe, build_recipe_with_progress, closeup_views, detect_sea, render_closeups,
};
pub use render::{Camera, Image, RenderSettings, SectionSettings, SectionStats, render, section};
pub use scene::{
    ArchSettings, EffectReport, HoodooSettings, ImplicitizeSettings, IslandSettings, KarstSettings,
    KarstStop, RainErosion, Region, Scene, SceneBuilder, SeaCliffs, SeaErosion, UndercutSettings,
    Weathering, WindErosion, erosion_intensity,
};
pub use simplify::{SimplifyReport, simplify, simplify_with_progress};
pub use tree::{DemFrame, NodeId, THRESHOLD, TerrainTree, TreeStats};
