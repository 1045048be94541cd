//! The Sparse Construction Tree (guerin2016 sections 4.1 and 5.4): sparse layers of primitives
//! blended by `f(p) = sum_i f_i(p) alpha_i(p) / sum_i alpha_i(p)`, operator nodes and procedural
//! primitives, evaluation at any point and rasterisation of any window at any scale.
//!
//! # Value and weight
//! Every node evaluates to a pair `(value, weight)`. A [`SparseLayer`] gives
//! `(sum f_i alpha_i / sum alpha_i, sum alpha_i)` (value NaN where no support covers the point);
//! [`Node::Blend`] normalises the weighted sum of its children the same way, so blending layers
//! generalises the equation above to sub-trees. The other operators keep the weight of their
//! first child (the base) and combine values: [`Node::Add`] sums, [`Node::Max`]/[`Node::Min`]
//! take the extremum (carving: `Min(terrain, river bed)`), [`Node::Replace`] blends an overlay
//! into the base inside a [`Region`] with a smooth fall-off.
//!
//! # Rasterisation
//! [`Sct::rasterize`] splits the requested window into bands of rows processed in parallel.
//! A layer is rasterised by *stamping*: each primitive whose support meets the band first sums
//! its data atoms into one `a x a` patch `P_i = sum_j x_i^j d_j`, then adds
//! `(z_i + bicubic(P_i) + function atoms) alpha_i` and `alpha_i` into numerator and denominator
//! buffers, using a separable bicubic (one horizontal pass per patch row, then four taps per
//! pixel). Primitives are always visited in increasing index order and every pixel's value is
//! computed by the same arithmetic as [`Sct::eval`], so a window rasterised alone equals the
//! same window of the full raster bit for bit, and both equal point evaluation, whatever the
//! thread count.
//!
//! The other nodes are stamped too: a [`River`] stamps each segment over the pixels of its box
//! grown by the largest half width (carve) or over the band (bed profile, defined everywhere),
//! keeping per pixel the nearest segment in increasing segment order; [`Node::Replace`] stamps
//! its overlay only on the part of the band where the region's weight is non-zero; operators
//! combine their children's band buffers pixel by pixel with the same function as
//! [`Node::eval`]. Every node kind therefore rasterises bit for bit like point evaluation
//! (tested for each kind and for random trees).
//!
//! Point queries visit only nearby primitives: each layer and each carving river keeps a
//! uniform-grid index of its supports (disks, segment boxes).
//!
//! Pixel `(X, Y)` of the raster at scale factor `s` samples the terrain at pixel coordinates
//! `(X / s, Y / s)` of the encoded grid; the full raster has `floor((w - 1) s) + 1` columns.

use std::sync::Arc;

use rayon::prelude::*;
use relief_heightfield::{GeoRef, Heightfield, NoProgress, Progress};

use crate::dictionary::{Atom, Dictionary};
use crate::error::{Result, SparseError};
use crate::omp::SparseCodes;
use crate::patches::{CentreGrid, cubic_weights};

/// Where the primitives of a layer are.
#[derive(Debug, Clone, PartialEq)]
pub enum Placement {
    /// A regular grid (the compact representation stores no centre).
    Grid(CentreGrid),
    /// Explicit centres (authoring).
    Explicit(Vec<[f64; 2]>),
}

impl Placement {
    /// Number of centres.
    pub fn len(&self) -> usize {
        match self {
            Placement::Grid(g) => g.len(),
            Placement::Explicit(c) => c.len(),
        }
    }

    /// True when there is no centre.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Centre of primitive `k`.
    pub fn centre(&self, k: usize) -> [f64; 2] {
        match self {
            Placement::Grid(g) => g.centre(k),
            Placement::Explicit(c) => c[k],
        }
    }
}

/// Uniform-grid spatial index: each cell lists (in increasing order) the primitives whose
/// support bounding box meets it, so a point query visits only nearby primitives.
#[derive(Debug, Clone, PartialEq)]
struct SpatialIndex {
    origin: [f64; 2],
    cell: f64,
    nx: usize,
    ny: usize,
    starts: Vec<u32>,
    ids: Vec<u32>,
}

/// Largest number of cells per axis of a [`SpatialIndex`] (the cell grows beyond the preferred
/// size when the boxes are spread far apart, so the index never takes more than ~1M cells).
const INDEX_MAX_CELLS_PER_AXIS: f64 = 1024.0;

impl SpatialIndex {
    /// Index of disks of radius `radius` around `centres`.
    fn build(centres: &[[f64; 2]], radius: f64) -> Self {
        let boxes: Vec<[f64; 4]> = centres
            .iter()
            .map(|c| [c[0] - radius, c[1] - radius, c[0] + radius, c[1] + radius])
            .collect();
        Self::from_boxes(&boxes, 2.0 * radius)
    }

    /// Index of axis-aligned boxes `[x0, y0, x1, y1]` (finite) with preferred cell side `cell`.
    fn from_boxes(boxes: &[[f64; 4]], cell: f64) -> Self {
        if boxes.is_empty() {
            return Self {
                origin: [0.0, 0.0],
                cell: 1.0,
                nx: 1,
                ny: 1,
                starts: vec![0, 0],
                ids: Vec::new(),
            };
        }
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for b in boxes {
            x0 = x0.min(b[0]);
            y0 = y0.min(b[1]);
            x1 = x1.max(b[2]);
            y1 = y1.max(b[3]);
        }
        let extent = (x1 - x0).max(y1 - y0);
        let cell = cell.max(extent / INDEX_MAX_CELLS_PER_AXIS);
        let cell = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            f64::MAX
        };
        let count = |span: f64| -> usize {
            let n = (span / cell).floor();
            if n.is_finite() && n >= 0.0 {
                (n as usize).min(INDEX_MAX_CELLS_PER_AXIS as usize) + 1
            } else {
                1
            }
        };
        let nx = count(x1 - x0);
        let ny = count(y1 - y0);
        let mut idx = Self {
            origin: [x0, y0],
            cell,
            nx,
            ny,
            starts: Vec::new(),
            ids: Vec::new(),
        };
        let mut counts = vec![0u32; nx * ny];
        let ranges: Vec<(usize, usize, usize, usize)> = boxes
            .iter()
            .map(|b| {
                let (ia, ib) = idx.span(b[0], b[2], 0);
                let (ja, jb) = idx.span(b[1], b[3], 1);
                (ia, ib, ja, jb)
            })
            .collect();
        for &(ia, ib, ja, jb) in &ranges {
            for j in ja..=jb {
                for i in ia..=ib {
                    counts[j * nx + i] += 1;
                }
            }
        }
        let mut starts = vec![0u32; nx * ny + 1];
        for k in 0..nx * ny {
            starts[k + 1] = starts[k] + counts[k];
        }
        let mut fill = starts.clone();
        let mut ids = vec![0u32; starts[nx * ny] as usize];
        for (p, &(ia, ib, ja, jb)) in ranges.iter().enumerate() {
            for j in ja..=jb {
                for i in ia..=ib {
                    let c = j * nx + i;
                    ids[fill[c] as usize] = p as u32;
                    fill[c] += 1;
                }
            }
        }
        idx.starts = starts;
        idx.ids = ids;
        idx
    }

    /// Cell range (inclusive, clamped) covering `[lo, hi]` along `axis`.
    fn span(&self, lo: f64, hi: f64, axis: usize) -> (usize, usize) {
        let n = if axis == 0 { self.nx } else { self.ny };
        let f = |v: f64| -> usize {
            let c = ((v - self.origin[axis]) / self.cell).floor();
            c.clamp(0.0, (n - 1) as f64) as usize
        };
        (f(lo), f(hi))
    }

    fn cell_ids(&self, x: f64, y: f64) -> &[u32] {
        let i = ((x - self.origin[0]) / self.cell).floor();
        let j = ((y - self.origin[1]) / self.cell).floor();
        if i < 0.0 || j < 0.0 || i >= self.nx as f64 || j >= self.ny as f64 {
            return &[];
        }
        let c = j as usize * self.nx + i as usize;
        &self.ids[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// Sorted, deduplicated primitives whose bounding box meets the rectangle.
    fn query_rect(&self, x0: f64, y0: f64, x1: f64, y1: f64, out: &mut Vec<u32>) {
        out.clear();
        let gx1 = self.origin[0] + self.nx as f64 * self.cell;
        let gy1 = self.origin[1] + self.ny as f64 * self.cell;
        if x1 < self.origin[0] || y1 < self.origin[1] || x0 > gx1 || y0 > gy1 {
            return;
        }
        let (ia, ib) = self.span(x0, x1, 0);
        let (ja, jb) = self.span(y0, y1, 1);
        for j in ja..=jb {
            for i in ia..=ib {
                let c = j * self.nx + i;
                out.extend_from_slice(
                    &self.ids[self.starts[c] as usize..self.starts[c + 1] as usize],
                );
            }
        }
        out.sort_unstable();
        out.dedup();
    }
}

/// A set of sparse primitives over one dictionary, blended by the normalised weighted sum
/// (section 4.1). Primitive `i`: centre `c_i`, elevation `z_i`, coefficients `(j, x_i^j)`.
#[derive(Debug, Clone)]
pub struct SparseLayer {
    dictionary: Arc<Dictionary>,
    placement: Placement,
    z: Vec<f32>,
    offsets: Vec<u32>,
    atoms: Vec<u32>,
    coeffs: Vec<f32>,
    centres: Vec<[f64; 2]>,
    has_functions: Vec<bool>,
    index: SpatialIndex,
}

impl SparseLayer {
    /// Builds a layer from compressed-row coefficients (`offsets` has `n + 1` entries).
    pub fn from_parts(
        dictionary: Arc<Dictionary>,
        placement: Placement,
        z: Vec<f32>,
        offsets: Vec<u32>,
        atoms: Vec<u32>,
        coeffs: Vec<f32>,
    ) -> Result<Self> {
        let n = placement.len();
        if z.len() != n {
            return Err(SparseError::DimensionMismatch {
                what: "z values vs primitives",
                expected: n,
                got: z.len(),
            });
        }
        if offsets.len() != n + 1
            || offsets[0] != 0
            || offsets.windows(2).any(|w| w[1] < w[0])
            || offsets[n] as usize != atoms.len()
            || atoms.len() != coeffs.len()
        {
            return Err(SparseError::param(
                "offsets",
                offsets.len(),
                "need n + 1 non-decreasing offsets from 0 to the coefficient count",
            ));
        }
        if let Some(&j) = atoms.iter().find(|&&j| j as usize >= dictionary.len()) {
            return Err(SparseError::param(
                "atom index",
                j,
                "exceeds the dictionary size",
            ));
        }
        if let Some(i) = z.iter().position(|v| !v.is_finite()) {
            return Err(SparseError::NonFinite { what: "z", row: i });
        }
        if let Some(i) = coeffs.iter().position(|v| !v.is_finite()) {
            return Err(SparseError::NonFinite {
                what: "coefficients",
                row: i,
            });
        }
        let centres: Vec<[f64; 2]> = (0..n).map(|k| placement.centre(k)).collect();
        if let Some(i) = centres
            .iter()
            .position(|c| !(c[0].is_finite() && c[1].is_finite()))
        {
            return Err(SparseError::NonFinite {
                what: "centres",
                row: i,
            });
        }
        let has_functions = (0..n)
            .map(|k| {
                atoms[offsets[k] as usize..offsets[k + 1] as usize]
                    .iter()
                    .any(|&j| matches!(dictionary.atoms()[j as usize], Atom::Function { .. }))
            })
            .collect();
        let index = SpatialIndex::build(&centres, dictionary.support_radius());
        Ok(Self {
            dictionary,
            placement,
            z,
            offsets,
            atoms,
            coeffs,
            centres,
            has_functions,
            index,
        })
    }

    /// Builds a layer from OMP codes (one signal per primitive).
    pub fn from_codes(
        dictionary: Arc<Dictionary>,
        placement: Placement,
        z: Vec<f32>,
        codes: &SparseCodes<f32>,
    ) -> Result<Self> {
        let mut offsets = Vec::with_capacity(codes.n_signals() + 1);
        offsets.push(0u32);
        let mut atoms = Vec::with_capacity(codes.nnz());
        let mut coeffs = Vec::with_capacity(codes.nnz());
        for i in 0..codes.n_signals() {
            let (idx, val) = codes.signal(i);
            atoms.extend_from_slice(idx);
            coeffs.extend_from_slice(val);
            offsets.push(atoms.len() as u32);
        }
        Self::from_parts(dictionary, placement, z, offsets, atoms, coeffs)
    }

    /// The dictionary.
    pub fn dictionary(&self) -> &Arc<Dictionary> {
        &self.dictionary
    }

    /// The placement of the centres.
    pub fn placement(&self) -> &Placement {
        &self.placement
    }

    /// Number of primitives `n`.
    pub fn len(&self) -> usize {
        self.z.len()
    }

    /// True when the layer has no primitive.
    pub fn is_empty(&self) -> bool {
        self.z.is_empty()
    }

    /// Elevations `z_i`.
    pub fn z(&self) -> &[f32] {
        &self.z
    }

    /// Compressed-row offsets (`n + 1`).
    pub fn offsets(&self) -> &[u32] {
        &self.offsets
    }

    /// Atom indices of all primitives (see [`SparseLayer::offsets`]).
    pub fn atom_indices(&self) -> &[u32] {
        &self.atoms
    }

    /// Coefficients of all primitives (see [`SparseLayer::offsets`]).
    pub fn coefficients(&self) -> &[f32] {
        &self.coeffs
    }

    /// Atom indices and coefficients of primitive `i`.
    pub fn primitive(&self, i: usize) -> (&[u32], &[f32]) {
        let (a, b) = (self.offsets[i] as usize, self.offsets[i + 1] as usize);
        (&self.atoms[a..b], &self.coeffs[a..b])
    }

    /// Centre of primitive `i`.
    pub fn centre(&self, i: usize) -> [f64; 2] {
        self.centres[i]
    }

    /// Largest number of coefficients of a primitive (the sparsity `s`).
    pub fn max_sparsity(&self) -> usize {
        self.offsets
            .windows(2)
            .map(|w| (w[1] - w[0]) as usize)
            .max()
            .unwrap_or(0)
    }

    /// The primitives whose support holds `(x, y)`, in increasing order. The spatial index
    /// limits the visit to the primitives listed in one grid cell.
    pub fn primitives_at(&self, x: f64, y: f64) -> Vec<usize> {
        let rr = self.dictionary.support_radius() * self.dictionary.support_radius();
        self.index
            .cell_ids(x, y)
            .iter()
            .map(|&i| i as usize)
            .filter(|&i| {
                let [cx, cy] = self.centres[i];
                weight(x - cx, y - cy, rr).is_some()
            })
            .collect()
    }

    /// Number of primitives the index visits for a query at `(x, y)` (those listed in its cell).
    pub fn candidates_at(&self, x: f64, y: f64) -> usize {
        self.index.cell_ids(x, y).len()
    }

    /// Sums the data atoms of primitive `i` into `p` (`a * a`).
    fn patch(&self, i: usize, p: &mut [f64]) {
        p.iter_mut().for_each(|v| *v = 0.0);
        let (idx, val) = self.primitive(i);
        for (&j, &x) in idx.iter().zip(val) {
            if let Atom::Data(d) = &self.dictionary.atoms()[j as usize] {
                let x = x as f64;
                for (o, &dv) in p.iter_mut().zip(d) {
                    *o += x * dv as f64;
                }
            }
        }
    }

    /// Function-atom part of primitive `i` at offset `(dx, dy)`.
    fn functions(&self, i: usize, dx: f64, dy: f64) -> f64 {
        let (idx, val) = self.primitive(i);
        let mut acc = 0.0;
        for (&j, &x) in idx.iter().zip(val) {
            if let Some(v) = self.dictionary.eval_function(j as usize, dx, dy) {
                acc += x as f64 * v;
            }
        }
        acc
    }

    /// `(numerator, denominator)` of the blend at `(x, y)`.
    fn eval_parts(&self, x: f64, y: f64) -> (f64, f64) {
        let a = self.dictionary.patch_size();
        let delta = self.dictionary.spacing();
        let rr = self.dictionary.support_radius() * self.dictionary.support_radius();
        let mut p = vec![0.0; a * a];
        let (mut num, mut den) = (0.0, 0.0);
        for &id in self.index.cell_ids(x, y) {
            let i = id as usize;
            let [cx, cy] = self.centres[i];
            let (dx, dy) = (x - cx, y - cy);
            let Some(alpha) = weight(dx, dy, rr) else {
                continue;
            };
            self.patch(i, &mut p);
            let (cols, wx) = taps(dx, delta, a);
            let (rows, wy) = taps(dy, delta, a);
            let mut h = [0.0; 4];
            for r in 0..4 {
                let prow = &p[rows[r] * a..rows[r] * a + a];
                h[r] = if is_exact(&wx) {
                    prow[cols[1]]
                } else {
                    hpass(prow, &cols, &wx)
                };
            }
            // The same arithmetic as `stamp` (sample positions read directly).
            let mut v = if is_exact(&wy) { h[1] } else { vpass(&h, &wy) };
            if self.has_functions[i] {
                v += self.functions(i, dx, dy);
            }
            let f = self.z[i] as f64 + v;
            num += f * alpha;
            den += alpha;
        }
        (num, den)
    }

    /// Stamps the layer into a band: `num`/`den` are `ncols x nrows` buffers for pixels
    /// `(X0 + c, Y0 + r)` at scale `scale`.
    fn stamp(&self, band: &Band, num: &mut [f64], den: &mut [f64], scratch: &mut StampScratch) {
        let a = self.dictionary.patch_size();
        let delta = self.dictionary.spacing();
        let radius = self.dictionary.support_radius();
        let rr = radius * radius;
        let sc = band.scale;
        let (wx0, wx1) = (band.x0 as f64 / sc, (band.x1 - 1) as f64 / sc);
        let (wy0, wy1) = (band.y0 as f64 / sc, (band.y1 - 1) as f64 / sc);
        self.index
            .query_rect(wx0, wy0, wx1, wy1, &mut scratch.candidates);
        scratch.p.resize(a * a, 0.0);
        let ncols = band.x1 - band.x0;
        let candidates = std::mem::take(&mut scratch.candidates);
        for &id in &candidates {
            let i = id as usize;
            let [cx, cy] = self.centres[i];
            // Conservative pixel ranges of the support (exact test per pixel below).
            let xa = lo_pixel(cx - radius, sc, band.x0);
            let xb = hi_pixel(cx + radius, sc, band.x1);
            let ya = lo_pixel(cy - radius, sc, band.y0);
            let yb = hi_pixel(cy + radius, sc, band.y1);
            if xa > xb || ya > yb {
                continue;
            }
            self.patch(i, &mut scratch.p);
            let w = (xb - xa + 1) as usize;
            let hgt = (yb - ya + 1) as usize;
            // Offsets of the pixels from the centre. On a regular grid at a whole scale they
            // repeat from one primitive to the next: the weights and row taps are then reused
            // (the same values, computed by the same function, so bit for bit the same).
            scratch.dx.clear();
            scratch.dx.extend((xa..=xb).map(|xi| xi as f64 / sc - cx));
            scratch.dy.clear();
            scratch.dy.extend((ya..=yb).map(|yi| yi as f64 / sc - cy));
            let params = (rr, delta, a);
            if scratch.key != Some(params)
                || scratch.key_dx != scratch.dx
                || scratch.key_dy != scratch.dy
            {
                scratch.ctaps.clear();
                scratch
                    .ctaps
                    .extend(scratch.dx.iter().map(|&dx| (dx, taps(dx, delta, a))));
                scratch.rtaps.clear();
                scratch
                    .rtaps
                    .extend(scratch.dy.iter().map(|&dy| taps(dy, delta, a)));
                scratch.alpha.clear();
                for &dy in &scratch.dy {
                    for &dx in &scratch.dx {
                        scratch.alpha.push(weight(dx, dy, rr).unwrap_or(f64::NAN));
                    }
                }
                scratch.all_exact = scratch.ctaps.iter().all(|(_, (_, wx))| is_exact(wx));
                scratch.key = Some(params);
                scratch.key_dx.clone_from(&scratch.dx);
                scratch.key_dy.clone_from(&scratch.dy);
            }
            // h[r][k]: patch row r interpolated at column k. On patch samples (taps
            // (0, 1, 0, 0)) the sum is that sample exactly, so it is read directly: the same
            // value, only cheaper (scale 1 with pixel-aligned samples, e.g. amplification).
            let direct = scratch.all_exact;
            if !direct {
                scratch.h.resize(a * w, 0.0);
                for r in 0..a {
                    let prow = &scratch.p[r * a..r * a + a];
                    let hrow = &mut scratch.h[r * w..r * w + w];
                    for (o, (_, (cols, wx))) in hrow.iter_mut().zip(&scratch.ctaps) {
                        *o = if is_exact(wx) {
                            prow[cols[1]]
                        } else {
                            hpass(prow, cols, wx)
                        };
                    }
                }
            }
            let z = self.z[i] as f64;
            let (p, h, ctaps) = (&scratch.p, &scratch.h, &scratch.ctaps);
            let hv = |r: usize, k: usize| -> f64 {
                if direct {
                    p[r * a + ctaps[k].1.0[1]]
                } else {
                    h[r * w + k]
                }
            };
            for ry in 0..hgt {
                let yi = ya as usize + ry;
                let dy = scratch.dy[ry];
                let (rows, wy) = scratch.rtaps[ry];
                let exact_row = is_exact(&wy);
                let row_off = (yi - band.y0) * ncols + (xa as usize - band.x0);
                let arow = &scratch.alpha[ry * w..ry * w + w];
                for (k, &alpha) in arow.iter().enumerate() {
                    if alpha.is_nan() {
                        continue;
                    }
                    let mut v = if exact_row {
                        hv(rows[1], k)
                    } else {
                        let hh = [
                            hv(rows[0], k),
                            hv(rows[1], k),
                            hv(rows[2], k),
                            hv(rows[3], k),
                        ];
                        vpass(&hh, &wy)
                    };
                    if self.has_functions[i] {
                        v += self.functions(i, ctaps[k].0, dy);
                    }
                    let f = z + v;
                    let o = row_off + k;
                    num[o] += f * alpha;
                    den[o] += alpha;
                }
            }
        }
        scratch.candidates = candidates;
    }
}

/// `g(r) = (1 - r^2)^3` for `r < 1` with `r^2 = (dx^2 + dy^2) / R^2`.
#[inline]
fn weight(dx: f64, dy: f64, rr: f64) -> Option<f64> {
    let r2 = (dx * dx + dy * dy) / rr;
    if r2 < 1.0 {
        let q = 1.0 - r2;
        Some(q * q * q)
    } else {
        None
    }
}

/// First pixel (conservative: one before, clamped to the band start `b0`) whose coordinate at
/// scale `sc` may be `>= v`. Saturating, so huge or infinite extents cannot overflow.
#[inline]
fn lo_pixel(v: f64, sc: f64, b0: usize) -> i64 {
    ((v * sc).floor() as i64).saturating_sub(1).max(b0 as i64)
}

/// Last pixel (conservative: one after, clamped to the band end `b1 - 1`) whose coordinate at
/// scale `sc` may be `<= v`.
#[inline]
fn hi_pixel(v: f64, sc: f64, b1: usize) -> i64 {
    ((v * sc).ceil() as i64)
        .saturating_add(1)
        .min(b1 as i64 - 1)
}

/// Clamped sample indices and weights of a bicubic tap set.
type Taps = ([usize; 4], [f64; 4]);

/// Bicubic taps (clamped sample indices and weights) of offset `d` in a patch of side `a`.
#[inline]
fn taps(d: f64, delta: f64, a: usize) -> Taps {
    let u = d / delta + (a as f64 - 1.0) / 2.0;
    let f = u.floor();
    let w = cubic_weights(u - f);
    // Indices are clamped to the patch anyway; bounding `f` first keeps huge offsets (far
    // centres, tiny spacings in decoded data) from overflowing the integer arithmetic.
    let base = f.clamp(-8.0, a as f64 + 8.0) as i64 - 1;
    let last = a as i64 - 1;
    let idx = [
        base.clamp(0, last) as usize,
        (base + 1).clamp(0, last) as usize,
        (base + 2).clamp(0, last) as usize,
        (base + 3).clamp(0, last) as usize,
    ];
    (idx, w)
}

/// Whether bicubic weights are exactly `(0, 1, 0, 0)` (a sample position): the weighted sum
/// of finite values is then the second value, bit for bit (up to the sign of a zero).
#[inline]
fn is_exact(w: &[f64; 4]) -> bool {
    w[1] == 1.0 && w[0] == 0.0 && w[2] == 0.0 && w[3] == 0.0
}

#[inline]
fn hpass(row: &[f64], cols: &[usize; 4], wx: &[f64; 4]) -> f64 {
    let mut acc = 0.0;
    for c in 0..4 {
        acc += wx[c] * row[cols[c]];
    }
    acc
}

#[inline]
fn vpass(h: &[f64; 4], wy: &[f64; 4]) -> f64 {
    let mut acc = 0.0;
    for r in 0..4 {
        acc += wy[r] * h[r];
    }
    acc
}

/// A rectangle of output pixels `[x0, x1) x [y0, y1)` at a scale factor.
#[derive(Debug, Clone, Copy)]
struct Band {
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
    scale: f64,
}

#[derive(Debug, Default)]
struct StampScratch {
    candidates: Vec<u32>,
    p: Vec<f64>,
    h: Vec<f64>,
    ctaps: Vec<(f64, Taps)>,
    rtaps: Vec<Taps>,
    dx: Vec<f64>,
    dy: Vec<f64>,
    /// Weights of the cached offsets (NaN outside the support), row-major.
    alpha: Vec<f64>,
    /// Whether every cached column tap set is a sample position.
    all_exact: bool,
    /// `(R^2, delta, a)` and the offsets the cached taps and weights were computed for.
    key: Option<(f64, f64, usize)>,
    key_dx: Vec<f64>,
    key_dy: Vec<f64>,
}

/// A region of the plane for [`Node::Replace`] (terrain pixel coordinates).
#[derive(Debug, Clone, PartialEq)]
pub enum Region {
    /// Axis-aligned rectangle `[x0, x1] x [y0, y1]`.
    Rect {
        /// West edge.
        x0: f64,
        /// North edge.
        y0: f64,
        /// East edge.
        x1: f64,
        /// South edge.
        y1: f64,
    },
    /// Disk of centre `(cx, cy)` and radius `r`.
    Disk {
        /// Centre x.
        cx: f64,
        /// Centre y.
        cy: f64,
        /// Radius.
        r: f64,
    },
}

impl Region {
    /// Signed distance (negative inside).
    fn signed_distance(&self, x: f64, y: f64) -> f64 {
        match *self {
            Region::Rect { x0, y0, x1, y1 } => {
                let dx = (x0 - x).max(x - x1);
                let dy = (y0 - y).max(y - y1);
                if dx <= 0.0 && dy <= 0.0 {
                    dx.max(dy)
                } else {
                    (dx.max(0.0).powi(2) + dy.max(0.0).powi(2)).sqrt()
                }
            }
            Region::Disk { cx, cy, r } => ((x - cx).powi(2) + (y - cy).powi(2)).sqrt() - r,
        }
    }

    /// Box `[x0, y0, x1, y1]` outside which the overlay weight with `falloff` is 0.
    fn bounds(&self, falloff: f64) -> [f64; 4] {
        match *self {
            Region::Rect { x0, y0, x1, y1 } => {
                [x0 - falloff, y0 - falloff, x1 + falloff, y1 + falloff]
            }
            Region::Disk { cx, cy, r } => [
                cx - r - falloff,
                cy - r - falloff,
                cx + r + falloff,
                cy + r + falloff,
            ],
        }
    }

    /// Overlay weight: 1 inside, smooth (C1, `3t^2 - 2t^3`) decay to 0 at `falloff` outside.
    fn weight(&self, x: f64, y: f64, falloff: f64) -> f64 {
        let d = self.signed_distance(x, y);
        if d <= 0.0 {
            1.0
        } else if d >= falloff {
            0.0
        } else {
            let t = 1.0 - d / falloff;
            t * t * (3.0 - 2.0 * t)
        }
    }

    fn check(&self) -> Result<()> {
        let ok = match *self {
            Region::Rect { x0, y0, x1, y1 } => {
                [x0, y0, x1, y1].iter().all(|v| v.is_finite()) && x0 <= x1 && y0 <= y1
            }
            Region::Disk { cx, cy, r } => {
                cx.is_finite() && cy.is_finite() && r.is_finite() && r >= 0.0
            }
        };
        if ok {
            Ok(())
        } else {
            Err(SparseError::param(
                "region",
                format!("{self:?}"),
                "coordinates must be finite, x0 <= x1, y0 <= y1, r >= 0",
            ))
        }
    }
}

/// Cross-section of a [`River`].
#[derive(Debug, Clone, PartialEq)]
pub enum RiverMode {
    /// A relative carve, used under [`Node::Add`]: `-depth (1 - (d / w)^2)^2` for `d < w`,
    /// 0 outside (`d` distance to the polyline, `w` half width).
    Carve,
    /// An absolute bed, used under [`Node::Min`]: `bed + depth (d / w)^2` (a parabolic valley
    /// whose floor follows the per-vertex bed elevations), so `Min(terrain, river)` carves it.
    Bed(Vec<f64>),
}

/// A procedural river along a polyline (guerin2016 figures 12-13) with half width and depth
/// interpolated linearly along the path between vertices.
#[derive(Debug, Clone, PartialEq)]
pub struct River {
    path: Vec<[f64; 2]>,
    half_width: Vec<f64>,
    depth: Vec<f64>,
    mode: RiverMode,
    bbox: [f64; 4],
    /// Largest half width.
    wmax: f64,
    /// Segment boxes expanded by `wmax` (and a relative margin), for the carve's stamps.
    seg_boxes: Vec<[f64; 4]>,
    /// Index of `seg_boxes`: a point query visits only the segments near it.
    index: SpatialIndex,
}

impl River {
    /// A river through `path` (terrain pixel coordinates, >= 2 vertices) with per-vertex half
    /// widths (> 0) and depths (>= 0).
    pub fn new(
        path: Vec<[f64; 2]>,
        half_width: Vec<f64>,
        depth: Vec<f64>,
        mode: RiverMode,
    ) -> Result<Self> {
        if path.len() < 2 {
            return Err(SparseError::param(
                "path",
                path.len(),
                "a river needs at least 2 vertices",
            ));
        }
        let n = path.len();
        for (what, len) in [("half_width", half_width.len()), ("depth", depth.len())] {
            if len != n {
                return Err(SparseError::DimensionMismatch {
                    what,
                    expected: n,
                    got: len,
                });
            }
        }
        if let RiverMode::Bed(b) = &mode {
            if b.len() != n {
                return Err(SparseError::DimensionMismatch {
                    what: "bed elevations",
                    expected: n,
                    got: b.len(),
                });
            }
            if let Some(i) = b.iter().position(|v| !v.is_finite()) {
                return Err(SparseError::NonFinite {
                    what: "bed elevations",
                    row: i,
                });
            }
        }
        if let Some(i) = path
            .iter()
            .position(|p| !(p[0].is_finite() && p[1].is_finite()))
        {
            return Err(SparseError::NonFinite {
                what: "river path",
                row: i,
            });
        }
        if let Some(&w) = half_width.iter().find(|w| !(w.is_finite() && **w > 0.0)) {
            return Err(SparseError::param(
                "half_width",
                w,
                "must be finite and > 0",
            ));
        }
        if let Some(&d) = depth.iter().find(|d| !(d.is_finite() && **d >= 0.0)) {
            return Err(SparseError::param("depth", d, "must be finite and >= 0"));
        }
        let wmax = half_width.iter().fold(0.0f64, |m, &w| m.max(w));
        let mut bbox = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        for p in &path {
            bbox[0] = bbox[0].min(p[0] - wmax);
            bbox[1] = bbox[1].min(p[1] - wmax);
            bbox[2] = bbox[2].max(p[0] + wmax);
            bbox[3] = bbox[3].max(p[1] + wmax);
        }
        if !bbox.iter().all(|v| v.is_finite()) {
            return Err(SparseError::param(
                "path",
                format!("{bbox:?}"),
                "the river's extent (path +- half width) must be finite",
            ));
        }
        // Every segment within `wmax` of a point has the point inside its expanded box (the
        // margin absorbs rounding), so the index and the stamps see every segment that can
        // carve the point (see `River::eval`).
        let m =
            wmax * (1.0 + 1e-9) + 1e-9 * (1.0 + bbox.iter().fold(0.0f64, |a, v| a.max(v.abs())));
        let seg_boxes: Vec<[f64; 4]> = path
            .windows(2)
            .map(|w| {
                [
                    w[0][0].min(w[1][0]) - m,
                    w[0][1].min(w[1][1]) - m,
                    w[0][0].max(w[1][0]) + m,
                    w[0][1].max(w[1][1]) + m,
                ]
            })
            .collect();
        // Cell of about two half widths, grown so that the boxes cover at most ~4M cells.
        let area: f64 = seg_boxes
            .iter()
            .map(|b| (b[2] - b[0]) * (b[3] - b[1]))
            .sum();
        let cell = (2.0 * m).max((area / f64::from(1u32 << 22)).sqrt());
        let index = SpatialIndex::from_boxes(&seg_boxes, cell);
        Ok(Self {
            path,
            half_width,
            depth,
            mode,
            bbox,
            wmax,
            seg_boxes,
            index,
        })
    }

    /// The polyline.
    pub fn path(&self) -> &[[f64; 2]] {
        &self.path
    }

    /// Per-vertex half widths.
    pub fn half_width(&self) -> &[f64] {
        &self.half_width
    }

    /// Per-vertex depths.
    pub fn depth(&self) -> &[f64] {
        &self.depth
    }

    /// The cross-section mode.
    pub fn mode(&self) -> &RiverMode {
        &self.mode
    }

    /// Squared distance from `(x, y)` to segment `s` and the position `t` of the nearest point.
    #[inline]
    fn segment_d2(&self, s: usize, x: f64, y: f64) -> (f64, f64) {
        let [ax, ay] = self.path[s];
        let [bx, by] = self.path[s + 1];
        let (ux, uy) = (bx - ax, by - ay);
        let l2 = ux * ux + uy * uy;
        let t = if l2 > 0.0 {
            (((x - ax) * ux + (y - ay) * uy) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (px, py) = (ax + t * ux - x, ay + t * uy - y);
        (px * px + py * py, t)
    }

    /// Nearest of the segments `segs` (increasing order; the first of equal distances wins):
    /// `(squared distance, segment, t)`, or `None` when `segs` is empty.
    fn nearest_of(
        &self,
        segs: impl Iterator<Item = usize>,
        x: f64,
        y: f64,
    ) -> Option<(f64, usize, f64)> {
        let mut best: Option<(f64, usize, f64)> = None;
        for s in segs {
            let (d2, t) = self.segment_d2(s, x, y);
            if best.is_none_or(|b| d2 < b.0) {
                best = Some((d2, s, t));
            }
        }
        best
    }

    /// Value of the river for the nearest point `(segment s, t)` at squared distance `d2`;
    /// `None` (no nearest point) is only possible in carve mode and gives 0.
    #[inline]
    fn profile(&self, nearest: Option<(f64, usize, f64)>) -> f64 {
        let lerp = |v: &[f64], s: usize, t: f64| v[s] + (v[s + 1] - v[s]) * t;
        match (&self.mode, nearest) {
            (RiverMode::Carve, None) => 0.0,
            (RiverMode::Carve, Some((d2, s, t))) => {
                let d = d2.sqrt();
                let w = lerp(&self.half_width, s, t);
                if d >= w {
                    return 0.0;
                }
                let q = 1.0 - (d / w) * (d / w);
                -lerp(&self.depth, s, t) * q * q
            }
            (RiverMode::Bed(bed), Some((d2, s, t))) => {
                let d = d2.sqrt();
                let w = lerp(&self.half_width, s, t);
                lerp(bed, s, t) + lerp(&self.depth, s, t) * (d / w) * (d / w)
            }
            (RiverMode::Bed(_), None) => f64::NAN,
        }
    }

    fn outside_bbox(&self, x: f64, y: f64) -> bool {
        x < self.bbox[0] || y < self.bbox[1] || x > self.bbox[2] || y > self.bbox[3]
    }

    /// Value of the river at `(x, y)`.
    ///
    /// The carve is 0 farther than the largest half width `wmax` from the path, so it only
    /// looks at the segments the spatial index lists for the point's cell: those include every
    /// segment within `wmax`, hence the nearest segment whenever the value is not 0, and the
    /// first-of-equals rule picks the same segment as a scan of all segments. The bed profile
    /// is defined everywhere and scans every segment.
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        match &self.mode {
            RiverMode::Carve => {
                if self.outside_bbox(x, y) {
                    return 0.0;
                }
                let segs = self.index.cell_ids(x, y).iter().map(|&s| s as usize);
                self.profile(self.nearest_of(segs, x, y))
            }
            RiverMode::Bed(_) => self.profile(self.nearest_of(0..self.path.len() - 1, x, y)),
        }
    }

    /// Number of segments a carve point query at `(x, y)` visits (all of them in bed mode).
    pub fn candidates_at(&self, x: f64, y: f64) -> usize {
        match self.mode {
            RiverMode::Carve if self.outside_bbox(x, y) => 0,
            RiverMode::Carve => self.index.cell_ids(x, y).len(),
            RiverMode::Bed(_) => self.path.len() - 1,
        }
    }

    /// Rasterises the river into `val` (band-sized) by stamping segments: each segment updates
    /// the running nearest `(d2, segment, t)` of the pixels of its expanded box (carve) or of
    /// the whole band (bed), in increasing segment order, then every pixel takes
    /// [`River::profile`]. Same arithmetic and tie rule as [`River::eval`], so equal bit for
    /// bit.
    fn stamp(&self, band: &Band, val: &mut [f64]) {
        let ncols = band.x1 - band.x0;
        let sc = band.scale;
        let n = val.len();
        let mut best: Vec<Option<(f64, usize, f64)>> = vec![None; n];
        let carve = matches!(self.mode, RiverMode::Carve);
        for (s, b) in self.seg_boxes.iter().enumerate() {
            let (xa, xb, ya, yb) = if carve {
                let xa = lo_pixel(b[0], sc, band.x0);
                let xb = hi_pixel(b[2], sc, band.x1);
                let ya = lo_pixel(b[1], sc, band.y0);
                let yb = hi_pixel(b[3], sc, band.y1);
                (xa, xb, ya, yb)
            } else {
                (
                    band.x0 as i64,
                    band.x1 as i64 - 1,
                    band.y0 as i64,
                    band.y1 as i64 - 1,
                )
            };
            if xa > xb || ya > yb {
                continue;
            }
            for yi in ya..=yb {
                let y = yi as f64 / sc;
                let row = (yi as usize - band.y0) * ncols;
                for xi in xa..=xb {
                    let x = xi as f64 / sc;
                    let o = row + (xi as usize - band.x0);
                    let (d2, t) = self.segment_d2(s, x, y);
                    if best[o].is_none_or(|p| d2 < p.0) {
                        best[o] = Some((d2, s, t));
                    }
                }
            }
        }
        for (k, (v, b)) in val.iter_mut().zip(&best).enumerate() {
            if carve {
                let x = (band.x0 + k % ncols) as f64 / sc;
                let y = (band.y0 + k / ncols) as f64 / sc;
                if self.outside_bbox(x, y) {
                    *v = 0.0;
                    continue;
                }
            }
            *v = self.profile(*b);
        }
    }

    /// Largest half width.
    pub fn max_half_width(&self) -> f64 {
        self.wmax
    }
}

/// A node of the Sparse Construction Tree.
#[derive(Debug, Clone)]
pub enum Node {
    /// Sparse primitives blended by the normalised weighted sum (section 4.1).
    Layer(SparseLayer),
    /// A constant elevation (weight 1).
    Constant(f64),
    /// A procedural river (weight 1).
    River(River),
    /// Normalised weighted sum of the children (value NaN where every weight is 0).
    Blend(Vec<Node>),
    /// Sum of the children's values; weight of the first child.
    Add(Vec<Node>),
    /// Maximum of the children's values; weight of the first child.
    Max(Vec<Node>),
    /// Minimum of the children's values (carving); weight of the first child.
    Min(Vec<Node>),
    /// `base` outside `region`, `overlay` inside, smooth over `falloff` cells; weight of `base`.
    Replace {
        /// The node kept outside the region.
        base: Box<Node>,
        /// The node used inside the region.
        overlay: Box<Node>,
        /// The region.
        region: Region,
        /// Width of the transition outside the region (>= 0, terrain pixels).
        falloff: f64,
    },
}

/// Running `(value, weight)` of an operator node over its children (visited in order), before
/// [`acc_finish`]. Point evaluation and rasterisation use these same three functions, so they
/// agree bit for bit.
#[inline]
fn acc_init(kind: u8) -> (f64, f64) {
    match kind {
        // Blend: (numerator, denominator).
        0 => (0.0, 0.0),
        // Add: the sum starts at -0.0 (the identity of IEEE addition).
        1 => (-0.0, f64::NAN),
        // Max / Min.
        _ => (f64::NAN, f64::NAN),
    }
}

/// Adds one child `(v, w)` to the running value; `first` for the first child (whose weight
/// the non-blend operators keep).
#[inline]
fn acc_step(kind: u8, acc: (f64, f64), (v, w): (f64, f64), first: bool) -> (f64, f64) {
    let keep = if first { w } else { acc.1 };
    match kind {
        0 => {
            if w > 0.0 {
                (acc.0 + v * w, acc.1 + w)
            } else {
                acc
            }
        }
        1 => (acc.0 + v, keep),
        2 => (acc.0.max(v), keep),
        _ => (acc.0.min(v), keep),
    }
}

/// Final `(value, weight)`: blend normalises (NaN where every weight is 0).
#[inline]
fn acc_finish(kind: u8, acc: (f64, f64)) -> (f64, f64) {
    match kind {
        0 => (if acc.1 > 0.0 { acc.0 / acc.1 } else { f64::NAN }, acc.1),
        _ => acc,
    }
}

fn replace_combine(base: (f64, f64), over: (f64, f64), t: f64) -> (f64, f64) {
    let v = if t <= 0.0 {
        base.0
    } else if t >= 1.0 {
        over.0
    } else {
        base.0 + (over.0 - base.0) * t
    };
    (v, base.1)
}

impl Node {
    fn children_kind(&self) -> Option<(u8, &[Node])> {
        match self {
            Node::Blend(c) => Some((0, c)),
            Node::Add(c) => Some((1, c)),
            Node::Max(c) => Some((2, c)),
            Node::Min(c) => Some((3, c)),
            _ => None,
        }
    }

    /// Checks operator arities and parameters.
    pub fn check(&self) -> Result<()> {
        if let Some((_, c)) = self.children_kind() {
            if c.is_empty() {
                return Err(SparseError::param(
                    "children",
                    0,
                    "an operator node needs at least one child",
                ));
            }
            return c.iter().try_for_each(Node::check);
        }
        match self {
            Node::Constant(v) if !v.is_finite() => {
                Err(SparseError::param("constant", v, "must be finite"))
            }
            Node::Replace {
                base,
                overlay,
                region,
                falloff,
            } => {
                region.check()?;
                if !(falloff.is_finite() && *falloff >= 0.0) {
                    return Err(SparseError::param(
                        "falloff",
                        falloff,
                        "must be finite and >= 0",
                    ));
                }
                base.check()?;
                overlay.check()
            }
            _ => Ok(()),
        }
    }

    /// `(value, weight)` at `(x, y)` (terrain pixel coordinates).
    pub fn eval(&self, x: f64, y: f64) -> (f64, f64) {
        if let Some((kind, c)) = self.children_kind() {
            let mut acc = acc_init(kind);
            for (i, n) in c.iter().enumerate() {
                acc = acc_step(kind, acc, n.eval(x, y), i == 0);
            }
            return acc_finish(kind, acc);
        }
        match self {
            Node::Layer(l) => {
                let (num, den) = l.eval_parts(x, y);
                (if den > 0.0 { num / den } else { f64::NAN }, den)
            }
            Node::Constant(v) => (*v, 1.0),
            Node::River(r) => (r.eval(x, y), 1.0),
            Node::Replace {
                base,
                overlay,
                region,
                falloff,
            } => {
                let t = region.weight(x, y, *falloff);
                let b = base.eval(x, y);
                let o = if t > 0.0 {
                    overlay.eval(x, y)
                } else {
                    (f64::NAN, 0.0)
                };
                replace_combine(b, o, t)
            }
            _ => (f64::NAN, 0.0),
        }
    }

    /// Rasterises the node into `val`/`wt` (band-sized, row-major).
    fn raster(&self, band: &Band, val: &mut [f64], wt: &mut [f64], scratch: &mut StampScratch) {
        let ncols = band.x1 - band.x0;
        if let Some((kind, c)) = self.children_kind() {
            // Children are stamped one after the other into one scratch pair and folded into
            // the running value held in `val`/`wt` (memory: two buffers whatever the arity).
            let n = val.len();
            let (a0, w0) = acc_init(kind);
            val.iter_mut().for_each(|v| *v = a0);
            wt.iter_mut().for_each(|v| *v = w0);
            let mut cv = vec![0.0; n];
            let mut cw = vec![0.0; n];
            for (i, child) in c.iter().enumerate() {
                child.raster(band, &mut cv, &mut cw, scratch);
                for k in 0..n {
                    let a = acc_step(kind, (val[k], wt[k]), (cv[k], cw[k]), i == 0);
                    val[k] = a.0;
                    wt[k] = a.1;
                }
            }
            for k in 0..n {
                let a = acc_finish(kind, (val[k], wt[k]));
                val[k] = a.0;
                wt[k] = a.1;
            }
            return;
        }
        match self {
            Node::Layer(l) => {
                val.iter_mut().for_each(|v| *v = 0.0);
                wt.iter_mut().for_each(|v| *v = 0.0);
                l.stamp(band, val, wt, scratch);
                for (v, &w) in val.iter_mut().zip(wt.iter()) {
                    *v = if w > 0.0 { *v / w } else { f64::NAN };
                }
            }
            Node::Constant(c) => {
                val.iter_mut().for_each(|v| *v = *c);
                wt.iter_mut().for_each(|v| *v = 1.0);
            }
            Node::River(r) => {
                r.stamp(band, val);
                wt.iter_mut().for_each(|v| *v = 1.0);
            }
            Node::Replace {
                base,
                overlay,
                region,
                falloff,
            } => {
                base.raster(band, val, wt, scratch);
                // The overlay is only rasterised (stamped) on the part of the band where the
                // region's weight can be > 0: its box grown by the fall-off (and a pixel).
                // Elsewhere the weight is 0 and the base value is kept, as in `eval`.
                let [bx0, by0, bx1, by1] = region.bounds(*falloff);
                let sc = band.scale;
                let xa = lo_pixel(bx0, sc, band.x0);
                let xb = hi_pixel(bx1, sc, band.x1);
                let ya = lo_pixel(by0, sc, band.y0);
                let yb = hi_pixel(by1, sc, band.y1);
                if xa > xb || ya > yb {
                    return;
                }
                let sub = Band {
                    x0: xa as usize,
                    x1: xb as usize + 1,
                    y0: ya as usize,
                    y1: yb as usize + 1,
                    scale: sc,
                };
                let sw = sub.x1 - sub.x0;
                let sn = sw * (sub.y1 - sub.y0);
                let mut ov = vec![0.0; sn];
                let mut ow = vec![0.0; sn];
                overlay.raster(&sub, &mut ov, &mut ow, scratch);
                for j in 0..sn {
                    let (xi, yi) = (sub.x0 + j % sw, sub.y0 + j / sw);
                    let (x, y) = (xi as f64 / sc, yi as f64 / sc);
                    let t = region.weight(x, y, *falloff);
                    let k = (yi - band.y0) * ncols + (xi - band.x0);
                    let (v, w) = replace_combine((val[k], wt[k]), (ov[j], ow[j]), t);
                    val[k] = v;
                    wt[k] = w;
                }
            }
            _ => {}
        }
    }

    fn collect_layers<'a>(&'a self, out: &mut Vec<&'a SparseLayer>) {
        if let Some((_, c)) = self.children_kind() {
            c.iter().for_each(|n| n.collect_layers(out));
            return;
        }
        match self {
            Node::Layer(l) => out.push(l),
            Node::Replace { base, overlay, .. } => {
                base.collect_layers(out);
                overlay.collect_layers(out);
            }
            _ => {}
        }
    }
}

/// A window of the output raster, in output pixels at the requested scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
}

/// Settings of [`Sct::rasterize`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RasterSettings {
    /// Scale factor `s` (> 0): output pixel `(X, Y)` samples terrain pixel `(X / s, Y / s)`.
    pub scale: f64,
    /// Window of the output raster (`None` = the whole raster).
    pub window: Option<Window>,
}

impl Default for RasterSettings {
    fn default() -> Self {
        Self {
            scale: 1.0,
            window: None,
        }
    }
}

impl RasterSettings {
    /// Validates the settings on their own: `scale` finite and in `(0, 1024]`, a window (if
    /// any) non-empty and of at most `relief_heightfield::MAX_CELLS` cells. Whether the window
    /// lies inside the raster is checked by [`Sct::rasterize`].
    pub fn check(&self) -> Result<()> {
        if !(self.scale.is_finite() && self.scale > 0.0 && self.scale <= 1024.0) {
            return Err(SparseError::param(
                "scale",
                self.scale,
                "must be finite and in (0, 1024]",
            ));
        }
        if let Some(w) = self.window {
            let cells = (w.width as u128) * (w.height as u128);
            if cells == 0 || cells > relief_heightfield::MAX_CELLS as u128 {
                return Err(SparseError::param(
                    "window",
                    format!("{},{},{},{}", w.x, w.y, w.width, w.height),
                    "must be non-empty and hold at most MAX_CELLS cells",
                ));
            }
        }
        Ok(())
    }
}

/// Rows per parallel band.
const BAND_ROWS: usize = 16;

/// A Sparse Construction Tree over a `width x height` terrain domain.
#[derive(Debug, Clone)]
pub struct Sct {
    root: Node,
    width: usize,
    height: usize,
    cell_size: (f64, f64),
    georef: Option<GeoRef>,
}

impl Sct {
    /// A tree over a `width x height` domain with the given cell size (metres).
    pub fn new(root: Node, width: usize, height: usize, cell_size: (f64, f64)) -> Result<Self> {
        if width == 0 || height == 0 || width > 1 << 24 || height > 1 << 24 {
            return Err(SparseError::param(
                "width x height",
                format!("{width} x {height}"),
                "must be in 1..=2^24",
            ));
        }
        let (cx, cy) = cell_size;
        if !(cx.is_finite() && cy.is_finite() && cx > 0.0 && cy > 0.0) {
            return Err(SparseError::param(
                "cell_size",
                format!("{cx} x {cy}"),
                "must be finite and > 0",
            ));
        }
        root.check()?;
        Ok(Self {
            root,
            width,
            height,
            cell_size,
            georef: None,
        })
    }

    /// The georeference of the domain grid at scale 1 (pixel-is-area: domain pixel `(i, j)`
    /// covers `[i, i + 1) x [j, j + 1)` of the geotransform), carried into every raster.
    pub fn georef(&self) -> Option<&GeoRef> {
        self.georef.as_ref()
    }

    /// Sets the georeference of the domain grid (see [`Sct::georef`]).
    pub fn set_georef(&mut self, georef: Option<GeoRef>) {
        self.georef = georef;
    }

    /// Builder form of [`Sct::set_georef`].
    pub fn with_georef(mut self, georef: Option<GeoRef>) -> Self {
        self.georef = georef;
        self
    }

    /// The georeference of the raster window `win` at scale `s`: raster pixel `X` samples
    /// domain pixel `X / s`, whose centre is at `X / s + 1/2` of the domain grid, so the
    /// raster's cells (size `1 / s`) start at `X / s + (1 - 1 / s) / 2`.
    pub fn raster_georef(&self, scale: f64, win: Window) -> Option<GeoRef> {
        let off = 0.5 - 0.5 / scale;
        self.georef.as_ref().map(|g| {
            g.window(
                win.x as f64 / scale + off,
                win.y as f64 / scale + off,
                1.0 / scale,
                1.0 / scale,
            )
        })
    }

    /// The root node.
    pub fn root(&self) -> &Node {
        &self.root
    }

    /// Replaces the root (authoring: wrap the current root in operators), checked.
    pub fn set_root(&mut self, root: Node) -> Result<()> {
        root.check()?;
        self.root = root;
        Ok(())
    }

    /// Takes the root out, leaving a constant 0 in its place.
    pub fn take_root(&mut self) -> Node {
        std::mem::replace(&mut self.root, Node::Constant(0.0))
    }

    /// Domain width in terrain pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Domain height in terrain pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Cell size `(east-west, north-south)` in metres at scale 1.
    pub fn cell_size(&self) -> (f64, f64) {
        self.cell_size
    }

    /// Every sparse layer of the tree (depth-first order).
    pub fn layers(&self) -> Vec<&SparseLayer> {
        let mut v = Vec::new();
        self.root.collect_layers(&mut v);
        v
    }

    /// Elevation `f(p)` at terrain pixel coordinates `(x, y)` (NaN outside every support).
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        self.root.eval(x, y).0
    }

    /// Size `(columns, rows)` of the full raster at scale `scale`.
    pub fn raster_size(&self, scale: f64) -> Result<(usize, usize)> {
        if !(scale.is_finite() && scale > 0.0 && scale <= 1024.0) {
            return Err(SparseError::param(
                "scale",
                scale,
                "must be finite and in (0, 1024]",
            ));
        }
        let f = |n: usize| ((n as f64 - 1.0) * scale + 1e-9).floor() as usize + 1;
        let (w, h) = (f(self.width), f(self.height));
        if (w as u128) * (h as u128) > 1u128 << 34 {
            return Err(SparseError::param(
                "scale",
                scale,
                "the raster would exceed 2^34 cells",
            ));
        }
        Ok((w, h))
    }

    /// Rasterises a window at a scale factor, in parallel (see the module docs).
    pub fn rasterize(&self, settings: &RasterSettings) -> Result<Heightfield> {
        self.rasterize_with_progress(settings, &NoProgress)
    }

    /// [`Sct::rasterize`] reporting rows done to `progress` (phase `"rasterize"`).
    pub fn rasterize_with_progress(
        &self,
        settings: &RasterSettings,
        progress: &dyn Progress,
    ) -> Result<Heightfield> {
        settings.check()?;
        let (fw, fh) = self.raster_size(settings.scale)?;
        let win = settings.window.unwrap_or(Window {
            x: 0,
            y: 0,
            width: fw,
            height: fh,
        });
        if win.width == 0
            || win.height == 0
            || win.x.checked_add(win.width).is_none_or(|e| e > fw)
            || win.y.checked_add(win.height).is_none_or(|e| e > fh)
        {
            return Err(SparseError::param(
                "window",
                format!(
                    "{},{},{},{} (raster {fw} x {fh})",
                    win.x, win.y, win.width, win.height
                ),
                "must be non-empty and inside the raster",
            ));
        }
        if (win.width as u128) * (win.height as u128) > relief_heightfield::MAX_CELLS as u128 {
            return Err(SparseError::param(
                "scale",
                settings.scale,
                "the raster would exceed MAX_CELLS cells (ask for a window)",
            ));
        }
        let mut out = vec![0f32; win.width * win.height];
        progress.begin("rasterize", win.height as u64);
        out.par_chunks_mut(win.width * BAND_ROWS)
            .enumerate()
            .for_each_init(StampScratch::default, |scratch, (b, chunk)| {
                let rows = chunk.len() / win.width;
                let band = Band {
                    x0: win.x,
                    x1: win.x + win.width,
                    y0: win.y + b * BAND_ROWS,
                    y1: win.y + b * BAND_ROWS + rows,
                    scale: settings.scale,
                };
                let mut val = vec![0.0; chunk.len()];
                let mut wt = vec![0.0; chunk.len()];
                self.root.raster(&band, &mut val, &mut wt, scratch);
                for (o, v) in chunk.iter_mut().zip(&val) {
                    *o = *v as f32;
                }
                progress.advance(rows as u64);
            });
        let hf = Heightfield::new(
            win.width,
            win.height,
            out,
            self.cell_size.0 / settings.scale,
            self.cell_size.1 / settings.scale,
        )?
        .with_georef(self.raster_georef(settings.scale, win));
        Ok(hf)
    }
}
