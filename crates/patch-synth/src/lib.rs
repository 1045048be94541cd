//! Guided patch-based terrain synthesis after Cruz, Velho, Galin, Peytavie and Guérin,
//! "Patch-based Terrain Synthesis" (GRAPP 2015), `cruz2015` in the shared papers.
//!
//! A new terrain is quilted from square patches of real exemplar DEMs, placed in raster order
//! on an overlapping grid and controlled by
//! * a **guide** (section 3.1): a low-frequency DEM at the target resolution, made by low-pass
//!   filtering an existing DEM ([`guide::lowpass_resample`], [`guide::gaussian_blur`]) or by
//!   interpolating painted seeds and sketch strokes ([`guide::guide_from_sketch`]);
//! * exemplar **categories** and a **categorisation map** (sections 3.1 and 4): user-given per
//!   exemplar or by region of an exemplar (a painted raster, [`Exemplar::with_regions`]), or
//!   clustered per exemplar ([`categorize_exemplars`]) or per region ([`categorize_regions`],
//!   the patches clustered as section 4 says); the map comes from a user raster or from
//!   k-means of the guide's heights ([`CategoryMap::from_guide_heights`]).
//!
//! # Method
//! * Preprocessing ([`ExemplarIndex::build`], section 3.5): every patch gets the `N x N`
//!   block-average descriptor of section 3.2 (`N = 3`); k-means of the descriptors gives the
//!   keys of a hash table whose buckets are split by category. The overlap regions (left strip,
//!   top strip, L-shaped corner; reduced to box means of a few cells and mean-removed, so the
//!   match is invariant to the vertical translation) are projected on a PCA basis (faer
//!   symmetric eigen-decomposition of the covariance) and stored per bucket in kd-trees (kiddo).
//! * Candidates (section 3.2): the categories present in the map window filter the buckets;
//!   clusters are probed in order of closeness to the guide's block descriptor (after the
//!   vertical translation of equation 3, as the validation compares them) until
//!   `probe_candidates` patches are gathered; each probed bucket's kd-tree (PCA space) is asked
//!   for `knn * rerank` neighbours of the overlap, which are re-ranked by the exact
//!   full-resolution overlap error (means removed) and the best `knn` kept
//!   ([`ExemplarIndex::nearest_overlaps`] runs one such search on its own; the `search_quality`
//!   example measures it against the exhaustive search on the 201,601 patches of a 512 x 512
//!   exemplar: the kd-tree's own 24 hold 41 % of the exhaustive best 24 with 8 PCA dimensions,
//!   the best 24 of the re-ranked 240 per bucket 99.7 %). With a guide, the `knn` patches per
//!   probed bucket whose block descriptors best match the guide's (after the translation of
//!   equation 3) join them: the paper leaves open how the two criteria are combined, and overlap
//!   neighbours alone gave a guide RMSE about 1.5 times larger on the alps protocol.
//! * Choice (section 3.3, equation 1): `M = alpha G + beta O + gamma P` with `G` the RMS
//!   distance between `guide_cells x guide_cells` cell means of the patch and the guide, `O`
//!   the RMS overlap difference and `P` the RMS error along the cut; in two steps (the best
//!   `survivors` by `alpha G + beta O`, then the cut for those only). The final pick is uniform
//!   among survivors within `choice_tolerance` of the best.
//! * Guide low-pass (a departure from the paper, `Settings::guide_lowpass`, `Some(0.0)` = the
//!   paper): `G` compares the guide with the cell means of the *low-passed* exemplar (Gaussian
//!   of the guide's own [`guide::smoothness_scale`] by default, about 1.1 times the blur of a
//!   blurred DEM). The paper's `G` also compares the patch's detail with a guide that has
//!   none, so wherever the guide is smooth the flattest patches win and the output is flatter
//!   than the exemplar. Measured by the `guided_quality` example (grandcanyon exemplar, 512²,
//!   seeds 0 / 1 / 2), slope-histogram EMD to the exemplar in degrees, paper -> low-pass:
//!   jacksboro guide 1.75 / 1.48 / 1.98 -> 0.62 / 0.74 / 0.44, alps 2.03 / 2.38 / 2.39 -> 1.47 /
//!   1.47 / 1.65, painted sketch 4.14 / 4.08 / 3.58 -> 2.83 / 2.77 / 3.32; the low-pass of the
//!   output still correlates >= 0.957 with the guide (0.971 before). The block descriptors
//!   that rank the clusters against the guide and pick the guide's own candidates are read
//!   from the same low-passed exemplar (with the raw ones a smooth guide probes only clusters
//!   of flat patches): painted sketch 2.83 / 2.77 / 3.32 -> 0.64 / 0.85 / 1.28 (seeds 3 / 4:
//!   3.59 / 3.48 -> 0.76 / 0.96), jacksboro 0.87-1.46, alps 1.05-1.17. Where it loses: guides
//!   that are band-limited rather than blurred ([`guide::lowpass_resample`]) and a tiny DEM
//!   enlarged 6x under 16-cell patches (the pipeline's volcano run keeps the paper's `G`).
//! * Patch-reuse penalty (a departure from the paper, `Settings::reuse_penalty`, 0 = the
//!   paper): before the survivors are taken, `alpha G + beta O` of a candidate whose source
//!   lies within half a patch of the source of a block placed within `reuse_radius` blocks is
//!   multiplied by `1 + reuse_penalty` per such block. Without it the best match of
//!   neighbouring blocks is often the same exemplar region, shifted by a cell or two, and one
//!   canyon pattern wallpapers an area (hillshade of the `guided_quality` example). Default 0.5,
//!   measured: near-reuse pairs (sources less than half a patch apart within 3 blocks) 735 ->
//!   287 unguided on a grandcanyon crop and 227 -> 75 / 136 -> 57 guided (`guided_quality`),
//!   slope-histogram distance to the exemplar 2.28 -> 1.75 / 2.83 -> 2.03 deg; 1.0 halves the
//!   pairs again but raised the unguided seam visibility 0.94 -> 1.18.
//! * Vertical translation (section 3.4, equations 2-3): the patch is shifted by the mean
//!   difference `h` over the overlap (over the whole block against the guide for the first
//!   patch); when `|h| > lambda` the translation is not applied.
//! * Insertion: minimum-error boundary cut by dynamic programming ([`min_error_cut`]; the
//!   greedy variant is kept for comparison), then feathering or Poisson blending over the
//!   overlap ([`Blend`]), then `crease_passes` of smoothing on the cells next to the cut (the
//!   blended gradients agree across a cut but the curvature creases; measured by
//!   [`quality::seam_curvature`]).
//! * Guides from another DEM (issue 17, not in the paper): [`guide::to_cell_size`] keeps the
//!   guide's physical scale on the exemplars' grid, [`guide::fit_to_size`] crops or
//!   mirror-pads it without resampling, [`guide::map_range`] maps its heights linearly onto
//!   the exemplars' (or given) range and [`guide::fit_range`] picks such a mapping that passes
//!   the validation. The `guided_quality` example measures the result (grandcanyon exemplar,
//!   guides from jacksboro_fault and alps_dem, 512 x 512).
//! * Validation (section 4, [`validate`]): every guide block needs `min_candidates` (default
//!   500) patches whose `N x N` descriptor matches the guide's within an RMS tolerance (default
//!   half the guide's standard deviation) after the vertical translation; the report names
//!   failing blocks and the missing height ranges and
//!   proposes a small exemplar subset by greedy set cover. Without a guide, the exemplars'
//!   mutual compatibility is checked.
//!
//! # Guarantees and limits
//! * Same inputs and seed give identical output bytes whatever the rayon thread count: scoring
//!   is parallel but order-preserving, reductions use fixed chunks, and each block's random
//!   choice is seeded from `(seed, block)`.
//! * Errors name the offending setting and value and no public entry point panics on bad
//!   input (property-tested); library code never prints (progress goes to the [`Progress`]
//!   callback). Outputs are limited to [`MAX_OUTPUT_CELLS`] cells.
//! * Not guaranteed: that every block finds a well-matching patch (validation tells when the
//!   exemplars are too poor); the kd-tree search is exact in PCA space, not in the full overlap
//!   space; the guide fidelity is limited by the exemplars' detail.
//!
//! ```
//! use relief_heightfield::{Heightfield, NoProgress};
//! use relief_patch_synth::{Control, Exemplar, ExemplarIndex, Settings, guide, synthesize};
//! let ex = Heightfield::from_fn(96, 96, 30.0, 30.0, |x, y| {
//!     ((x as f32 * 0.21).sin() * (y as f32 * 0.17).cos()) * 40.0 + x as f32 * 2.0
//! });
//! let settings = Settings {
//!     patch_size: 24, overlap: 6, min_candidates: 20, kmeans_clusters: 4, pca_samples: 400,
//!     ..Default::default()
//! };
//! let target = ex.crop(8, 8, 64, 64).unwrap();
//! let g = guide::lowpass_resample(&target, 8).unwrap();
//! let index = ExemplarIndex::build(vec![Exemplar::new(ex, 0)], &settings, &NoProgress).unwrap();
//! let out = synthesize(&index, &Control::guided(g), &settings, &NoProgress).unwrap();
//! assert_eq!((out.heightfield.width(), out.heightfield.height()), (64, 64));
//! assert_eq!(out.seam_map.source.len(), 64 * 64);
//! ```
#![warn(missing_docs)]

mod blend;
mod block;
mod category;
mod control;
mod cut;
mod error;
mod grid;
pub mod guide;
mod index;
pub mod job;
pub mod kmeans;
pub mod pca;
pub mod quality;
mod report;
mod settings;
mod synth;
mod validate;

pub use category::{ANY_CATEGORY, CategoryMap, categorize_exemplars, categorize_regions};
pub use cut::{Cut, min_error_cut};
pub use error::{PatchSynthError, Result};
pub use guide::{GuideFit, GuideRange, RangeMapping, SizeFit};
pub use index::{Exemplar, ExemplarIndex, OverlapShape, PatchRef};
pub use job::{
    GuideSetup, JobInputs, MemoryEstimate, PrepareFigures, QuiltFigures, QuiltJob, QuiltOutput,
    ValidateJob, ValidateOutput,
};
pub use relief_heightfield::{NoProgress, Progress};
pub use settings::{Blend, CutMethod, DEFAULT_MIN_CANDIDATES_SHARE, SUPPORTED_PCA_DIMS, Settings};
pub use synth::{
    Control, MAX_OUTPUT_CELLS, Placement, SeamMap, Synthesis, SynthesisStats, quilt, synthesize,
};
pub use validate::{BlockReport, ExemplarCompatibility, ValidationReport, validate};
