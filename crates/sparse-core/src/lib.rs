//! The Sparse Construction Tree of Guérin et al. 2016, "Sparse representation of terrains for
//! procedural modeling" (sections 4.1-4.3, 5.1, 5.4).
//!
//! # Map to the paper
//! | paper | here |
//! |---|---|
//! | 4.1 dictionary `D` (K x N), data atoms (bicubic) and function atoms, zero-mean, unit L2 | [`Dictionary`], [`FunctionAtom`], [`dictionary::Atom`] |
//! | 4.1 sparse primitive `f_i(p) = z_i + sum_j x_i^j d_j(p - c_i)`, `alpha_i = g(\|p - c_i\| / R)`, `g(r) = (1 - r^2)^3` | [`sct::SparseLayer`] |
//! | 4.1 terrain `f(p) = sum f_i alpha_i / sum alpha_i`, construction tree, BVH | [`Sct`], [`sct::Node`] (uniform-grid index per layer) |
//! | 4.2 regular grid of disks, `z_i` = mean over the support, patches `T_i`, matrix `F` | [`PatchGeometry`], [`extract_patches`], [`Patches`] |
//! | 4.3 OMP (literal argmin of the residual) | [`omp_reference`] |
//! | 4.3 fast OMP: Batch-OMP (Rubinstein, Zibulevsky & Elad 2008) | [`batch_omp`] |
//! | 5.3 `s = 1` coding with complete dictionaries of 60,000-120,000 atoms (exact nearest-atom search, blocked correlations, no Gram matrix) | [`nearest::nearest_atom`] (used by [`batch_omp`] above 4096 atoms) |
//! | 5.3 the coder the encoder and the amplification steps call: Batch-OMP, or at `s = 1` with a large dictionary the inverted-list search | [`code_indexed`] (at the crate root since the `coding` module sits above both solvers; it was `nearest::code_indexed`) |
//! | 4.3 exact reconstruction with `s = 1` and the complete dictionary | `Dictionary::from_patches(&p, None)` + [`encode()`] (tested) |
//! | 5.1 compact representation, `t(s, N) = KN + n(2s + 2) + 1`, `rho = t / t0`, PSNR | [`encode()`], [`encode::compression_report`], [`format`](mod@format) (`.sct` bytes) |
//! | 5.4 authoring: operators (blend, add, max/min carve, replace in region), rivers (fig. 12-13) | [`sct::Node`], [`sct::River`] (carve or bed profile along a polyline, width/depth per vertex), [`sct::Region`] |
//! | 4.1 evaluation `f(p)` / rasterisation of any window at any scale, by stamping every node kind | [`Sct::eval`], [`Sct::rasterize`] |
//! | storage of `D` alone (learned dictionaries, `relief learn` / `relief compress --dictionary`) | [`Dictionary::to_bytes`], [`Dictionary::from_bytes`] |
//! | settings, validated once (errors name the field and the value) | [`PatchGeometry::check`], [`OmpSettings::check`], [`EncodeSettings::check`], [`RasterSettings::check`] |
//!
//! # Coordinates
//! Positions are continuous *pixel coordinates of the encoded grid* (x = column, east; y = row,
//! south); lengths (`delta`, `R`, step) are in cells. A raster at scale `s` covers the encoded
//! grid's extent with `round(w s) x round(h s)` cells (pixel-is-area) and its pixel `(X, Y)`
//! samples [`raster_coord`]`(X, s)`, [`raster_coord`]`(Y, s)`, so any window at any resolution
//! can be produced.
//!
//! # Guarantees
//! * Rasterisation is deterministic and tiled: a window rasterised alone is bit-for-bit the
//!   same window of the full raster, and equals [`Sct::eval`] at the pixel positions, for any
//!   thread count.
//! * [`batch_omp`] gives the same codes for a signal whatever the batch and thread count.
//! * Invalid input (empty dictionary, `s > N`, `s` outside `1..=64`, NaN, mismatched sizes,
//!   absurd sizes, corrupt `.sct` or dictionary bytes) is an `Err`, never a panic (property
//!   tests feed random settings to every entry point).
//! * [`encode()`] gives the same `.sct` bytes whatever the thread count.
//!
//! Not guaranteed: [`omp_reference`] and [`batch_omp`] may pick different atoms on coherent
//! dictionaries (they use different, though equivalent on orthogonal atoms, selection rules);
//! `f32` and `f64` Batch-OMP may differ in the last iterations on ill-conditioned data.
//!
//! # Example
//! ```
//! use relief_heightfield::Heightfield;
//! use relief_sparse_core::{Dictionary, EncodeSettings, PatchGeometry, RasterSettings, encode,
//!     extract_patches};
//! let hf = Heightfield::from_fn(40, 32, 10.0, 10.0, |x, y| {
//!     ((x as f32) * 0.3).sin() * 20.0 + ((y as f32) * 0.2).cos() * 15.0 + 100.0
//! });
//! // The complete dictionary (every patch its own atom) with s = 1 reconstructs exactly.
//! let patches = extract_patches(&hf, &PatchGeometry::with_patch_size(8)).unwrap();
//! let (dict, _) = Dictionary::from_patches(&patches, None).unwrap();
//! let sct = encode(&hf, &dict, &EncodeSettings { sparsity: 1, ..Default::default() }).unwrap();
//! let rec = sct.rasterize(&RasterSettings::default()).unwrap();
//! let err = relief_heightfield::metrics::max_abs_diff(&hf, &rec).unwrap();
//! assert!(err < 1e-3, "{err}");
//! // Any window at any scale, e.g. x4 (the same extent with 4 x 4 cells per cell):
//! let big = sct.rasterize(&RasterSettings { scale: 4.0, window: None }).unwrap();
//! assert_eq!((big.width(), big.height()), (160, 128));
//! ```
#![warn(missing_docs)]

mod codes;
mod coding;
pub mod dictionary;
pub mod encode;
mod error;
pub mod format;
pub mod nearest;
pub mod omp;
pub mod patches;
pub mod sct;
mod simd;

pub use coding::code_indexed;
pub use dictionary::{AtomDescriptor, Dictionary, FunctionAtom, FunctionAtomRegistry};
pub use encode::{
    CompressionReport, DEFAULT_INDEX_PROBES, EncodeSettings, compression_report, dictionary_values,
    encode, encode_shared, encode_with_progress, layer_storage_values, storage_values,
};
pub use error::{Result, SparseError};
pub use format::FormatOptions;
pub use omp::{
    OmpFloat, OmpSettings, SparseCodes, batch_omp, batch_omp_with_progress, omp_reference,
};
pub use patches::{
    CentreGrid, MAX_PATCH_SAMPLES, MAX_PRIMITIVES, PatchGeometry, Patches, extract_patch_rows,
    extract_patches,
};
pub use sct::{
    Field, Node, NodeSpec, Placement, Profile, RasterSettings, Region, RegionSpec, River,
    RiverMode, RiverSpec, RiverValleySpec, Sct, SparseLayer, TreeSpec, Window, raster_coord,
};
