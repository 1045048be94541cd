//! Sparse layers (section 4.1): primitives blended by their weights, evaluated at a point or
//! stamped into a band of rows.

use std::ops::Range;

use super::*;

/// A set of sparse primitives over one dictionary, blended by the normalised weighted sum
/// (section 4.1). Primitive `i`: centre `c_i`, elevation `z_i`, coefficients `(j, x_i^j)`.
#[derive(Debug, Clone)]
pub struct SparseLayer {
    pub(super) dictionary: Arc<Dictionary>,
    pub(super) placement: Placement,
    pub(super) z: Vec<f32>,
    pub(super) offsets: Vec<u32>,
    pub(super) atoms: Vec<u32>,
    pub(super) coeffs: Vec<f32>,
    pub(super) centres: Vec<[f64; 2]>,
    pub(super) has_functions: Vec<bool>,
    pub(super) index: SpatialIndex,
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
            return Err(SparseError::non_finite("z", i));
        }
        if let Some(i) = coeffs.iter().position(|v| !v.is_finite()) {
            return Err(SparseError::non_finite("coefficients", i));
        }
        // In parallel (a x256 step has a million primitives); collected in order.
        let centres: Vec<[f64; 2]> = (0..n)
            .into_par_iter()
            .map(|k| placement.centre(k))
            .collect();
        SparseError::check_points("centres", &centres)?;
        let has_functions = (0..n)
            .into_par_iter()
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
    pub(super) fn patch(&self, i: usize, p: &mut [f64]) {
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

    /// `(coefficient, samples)` of primitive `i` when it is one data atom.
    #[inline]
    fn single_atom(&self, i: usize) -> Option<(f64, &[f32])> {
        match self.primitive(i) {
            ([j], [x]) => match &self.dictionary.atoms()[*j as usize] {
                Atom::Data(d) => Some((*x as f64, &d[..])),
                Atom::Function { .. } => None,
            },
            _ => None,
        }
    }

    /// Function-atom part of primitive `i` at offset `(dx, dy)`.
    pub(super) fn functions(&self, i: usize, dx: f64, dy: f64) -> f64 {
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
    pub(super) fn eval_parts(&self, x: f64, y: f64) -> (f64, f64) {
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
    /// `(X0 + c, Y0 + r)` at scale `scale`. On x86-64 with AVX2 the same code is compiled with
    /// AVX2 enabled (four f64 lanes in the accumulation runs instead of two); the output is
    /// bit-identical ([`avx2_dispatch!`](crate::avx2_dispatch)).
    pub(super) fn stamp(
        &self,
        band: &Band,
        num: &mut [f64],
        den: &mut [f64],
        scratch: &mut StampScratch<'_>,
    ) {
        stamp_dispatch(self, band, num, den, scratch);
    }

    /// The body of [`Self::stamp`].
    #[inline(always)]
    fn stamp_body(
        &self,
        band: &Band,
        num: &mut [f64],
        den: &mut [f64],
        scratch: &mut StampScratch<'_>,
    ) {
        let a = self.dictionary.patch_size();
        let delta = self.dictionary.spacing();
        let radius = self.dictionary.support_radius();
        let rr = radius * radius;
        let sc = band.scale;
        let (wx0, wx1) = (
            raster_coord(band.cols.start, sc),
            raster_coord(band.cols.end - 1, sc),
        );
        let (wy0, wy1) = (
            raster_coord(band.rows.start, sc),
            raster_coord(band.rows.end - 1, sc),
        );
        self.index
            .query_rect(wx0, wy0, wx1, wy1, &mut scratch.candidates);
        scratch.p.resize(a * a, 0.0);
        let ncols = band.cols.len();
        let candidates = std::mem::take(&mut scratch.candidates);
        for &id in &candidates {
            let i = id as usize;
            let [cx, cy] = self.centres[i];
            let Some(Frame { ex, ey, vx, kx, ky }) = Frame::of([cx, cy], radius, band) else {
                continue;
            };
            let w = (ex.1 - ex.0 + 1) as usize;
            // Offsets of the pixels from the centre. On a regular grid at a whole scale they
            // repeat from one primitive to the next: the weights and row taps are then reused
            // (the same values, computed by the same function, so bit for bit the same).
            scratch.dx.clear();
            scratch
                .dx
                .extend((ex.0..=ex.1).map(|xi| raster_coord_i(xi, sc) - cx));
            scratch.dy.clear();
            scratch
                .dy
                .extend((ey.0..=ey.1).map(|yi| raster_coord_i(yi, sc) - cy));
            scratch.refresh((rr, delta, a));
            // Every column on a patch sample (scale 1 with pixel-aligned samples, e.g.
            // amplification): the samples are read directly, else interpolated rows first.
            let direct = scratch.all_exact;
            // One data atom, every row and column on a sample, no function atom (amplification
            // at s = 1): its samples times the coefficient are read straight from the atom,
            // as `0.0 + x d`, the value `patch` would hold, so the patch is not summed.
            let single = self.single_atom(i).filter(|_| {
                direct
                    && !self.has_functions[i]
                    && scratch.rtaps[ky.0..ky.1].iter().all(|(_, wy)| is_exact(wy))
                    && scratch.spans[ky.0..ky.1].iter().all(Option::is_some)
            });
            if single.is_none() {
                self.patch(i, &mut scratch.p);
            }
            if !direct {
                scratch.interpolate_rows(a, w, kx);
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
            let plain = direct && !self.has_functions[i];
            for ry in ky.0..ky.1 {
                let yi = (ey.0 + ry as i64) as usize;
                let dy = scratch.dy[ry];
                let (rows, wy) = scratch.rtaps[ry];
                let exact_row = is_exact(&wy);
                // `row_off + k` is the band cell of frame column `k` (visible columns only).
                let row_off = ((yi - band.rows.start) * ncols + vx.0 as usize - band.cols.start)
                    .wrapping_sub(kx.0);
                let arow = &scratch.alpha[ry * w..ry * w + w];
                let span = scratch.spans[ry].map(|(k0, k1)| (k0.max(kx.0), k1.min(kx.1)));
                if span.is_some_and(|(k0, k1)| k0 >= k1) {
                    // No pixel of the support in the visible part of this row.
                    continue;
                }
                if let (Some((k0, k1)), Some((x, atom))) = (span, single) {
                    // The single-atom case above: the same operations as the run below.
                    let (o0, o1) = (row_off.wrapping_add(k0), row_off.wrapping_add(k1));
                    let run = (&mut num[o0..o1], &mut den[o0..o1], &arow[k0..k1]);
                    let src = (x, &atom[rows[1] * a..rows[1] * a + a]);
                    atom_run(run, z, src, (scratch.col0, &ctaps[k0..k1]), k0);
                    continue;
                }
                if let Some((k0, k1)) = span.filter(|_| plain && exact_row) {
                    // Samples read straight from the patch, no function atoms: the same
                    // operations as below on the support's run of the row, without the
                    // per-pixel tests (the common case of amplification and decompression).
                    let prow = &p[rows[1] * a..rows[1] * a + a];
                    let (o0, o1) = (row_off.wrapping_add(k0), row_off.wrapping_add(k1));
                    let (n, d, al) = (&mut num[o0..o1], &mut den[o0..o1], &arow[k0..k1]);
                    if let Some(c0) = scratch.col0 {
                        // Consecutive pixels read consecutive samples: plain slices, which
                        // the compiler vectorises.
                        let c0 = c0.wrapping_add(k0);
                        accumulate(n, d, al, z, prow[c0..c0 + (k1 - k0)].iter().copied());
                    } else {
                        let gather = ctaps[k0..k1].iter().map(|(_, (cols, _))| prow[cols[1]]);
                        accumulate(n, d, al, z, gather);
                    }
                    continue;
                }
                if let Some((k0, k1)) = span.filter(|_| !direct && !self.has_functions[i]) {
                    // Interpolated rows (atoms sampled more coarsely than the raster, e.g. the
                    // low layer of sketch synthesis, spacing 4): the same vertical pass as
                    // below, over the support's run of the row.
                    let (o0, o1) = (row_off.wrapping_add(k0), row_off.wrapping_add(k1));
                    let (n, d, al) = (&mut num[o0..o1], &mut den[o0..o1], &arow[k0..k1]);
                    let hrow = |r: usize| &h[r * w + k0..r * w + k1];
                    if exact_row {
                        accumulate(n, d, al, z, hrow(rows[1]).iter().copied());
                    } else {
                        let hs = [hrow(rows[0]), hrow(rows[1]), hrow(rows[2]), hrow(rows[3])];
                        let v = (0..k1 - k0).map(|k| vpass(&hs.map(|r| r[k]), &wy));
                        accumulate(n, d, al, z, v);
                    }
                    continue;
                }
                for (k, &alpha) in arow.iter().enumerate().take(kx.1).skip(kx.0) {
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
                    let o = row_off.wrapping_add(k);
                    num[o] += f * alpha;
                    den[o] += alpha;
                }
            }
        }
        scratch.candidates = candidates;
    }
}

crate::avx2_dispatch! {
    /// [`SparseLayer::stamp`]'s work, with AVX2 where the CPU has it.
    fn stamp_dispatch(
        layer: &SparseLayer,
        band: &Band,
        num: &mut [f64],
        den: &mut [f64],
        scratch: &mut StampScratch<'_>,
    ) => SparseLayer::stamp_body;
}

/// Where a primitive's support meets a band, in pixels: the frame of its cached offsets
/// (`ex`, `ey`: the whole support when it is small, so that primitives cut by the band's
/// edges reuse the cache too; else the part in the band), its columns inside the band (`vx`),
/// and the frame's visible columns `kx.0..kx.1` and rows `ky.0..ky.1`.
struct Frame {
    ex: (i64, i64),
    ey: (i64, i64),
    vx: (i64, i64),
    kx: (usize, usize),
    ky: (usize, usize),
}

impl Frame {
    /// The frame of the support of radius `radius` centred on `c` in `band`; `None` when it
    /// misses the band. The pixel ranges are conservative (the weight is the exact test).
    fn of(c: [f64; 2], radius: f64, band: &Band) -> Option<Self> {
        let sc = band.scale;
        let (fx, fy) = (
            support_pixels(c[0], radius, sc),
            support_pixels(c[1], radius, sc),
        );
        let clip = |f: (i64, i64), r: &std::ops::Range<usize>| {
            (f.0.max(r.start as i64), f.1.min(r.end as i64 - 1))
        };
        let (vx, vy) = (clip(fx, &band.cols), clip(fy, &band.rows));
        if vx.0 > vx.1 || vy.0 > vy.1 {
            return None;
        }
        let span_of = |r: (i64, i64)| r.1.saturating_sub(r.0).saturating_add(1);
        let whole = span_of(fx).saturating_mul(span_of(fy)) <= MAX_FRAME_CELLS;
        let (ex, ey) = if whole { (fx, fy) } else { (vx, vy) };
        let k = |v: (i64, i64), e: (i64, i64)| ((v.0 - e.0) as usize, (v.1 - e.0 + 1) as usize);
        Some(Frame {
            ex,
            ey,
            vx,
            kx: k(vx, ex),
            ky: k(vy, ey),
        })
    }
}

impl StampScratch<'_> {
    /// Whether the caller asks to stop (remembered once asked).
    pub(super) fn should_stop(&mut self) -> bool {
        if !self.stopped && self.progress.is_some_and(|p| p.stopped()) {
            self.stopped = true;
        }
        self.stopped
    }

    /// `h[r][k]`: patch row `r` of `p` (`a x a`) interpolated at the cached column `k`, for
    /// the visible columns `kx` of a frame `w` wide. On patch samples (taps (0, 1, 0, 0)) the
    /// sum is that sample exactly, so it is read directly.
    fn interpolate_rows(&mut self, a: usize, w: usize, kx: (usize, usize)) {
        self.h.resize(a * w, 0.0);
        for r in 0..a {
            let prow = &self.p[r * a..r * a + a];
            let hrow = &mut self.h[r * w + kx.0..r * w + kx.1];
            for (o, (_, (cols, wx))) in hrow.iter_mut().zip(&self.ctaps[kx.0..kx.1]) {
                *o = if is_exact(wx) {
                    prow[cols[1]]
                } else {
                    hpass(prow, cols, wx)
                };
            }
        }
    }

    /// Recomputes the cached taps, weights and support runs unless they were computed for
    /// these parameters `(R^2, delta, a)` and the current offsets `dx`, `dy`.
    fn refresh(&mut self, params: (f64, f64, usize)) {
        let (rr, delta, a) = params;
        if self.key == Some(params) && self.key_dx == self.dx && self.key_dy == self.dy {
            return;
        }
        self.ctaps.clear();
        self.ctaps
            .extend(self.dx.iter().map(|&dx| (dx, taps(dx, delta, a))));
        self.rtaps.clear();
        self.rtaps
            .extend(self.dy.iter().map(|&dy| taps(dy, delta, a)));
        self.alpha.clear();
        for &dy in &self.dy {
            for &dx in &self.dx {
                self.alpha.push(weight(dx, dy, rr).unwrap_or(f64::NAN));
            }
        }
        self.all_exact = self.ctaps.iter().all(|(_, (_, wx))| is_exact(wx));
        let nx = self.dx.len();
        self.spans.clear();
        self.spans.extend(self.alpha.chunks(nx.max(1)).map(|row| {
            let k0 = row.iter().position(|a| !a.is_nan()).unwrap_or(row.len());
            let k1 = row.iter().rposition(|a| !a.is_nan()).map_or(k0, |k| k + 1);
            row[k0..k1].iter().all(|a| !a.is_nan()).then_some((k0, k1))
        }));
        // Columns inside the support in some row: `k` reads patch column `col0 + k` there
        // when they are consecutive (the frame's outer columns may be clamped).
        let (kmin, kmax) =
            self.spans
                .iter()
                .flatten()
                .fold((usize::MAX, 0), |(lo, hi), &(k0, k1)| {
                    if k0 < k1 {
                        (lo.min(k0), hi.max(k1))
                    } else {
                        (lo, hi)
                    }
                });
        self.col0 = (self.all_exact && kmin < kmax)
            .then(|| self.ctaps[kmin].1.0[1].wrapping_sub(kmin))
            .filter(|&c0| (kmin..kmax).all(|k| self.ctaps[k].1.0[1] == c0.wrapping_add(k)));
        self.key = Some(params);
        self.key_dx.clone_from(&self.dx);
        self.key_dy.clone_from(&self.dy);
    }
}

/// `g(r) = (1 - r^2)^3` for `r < 1` with `r^2 = (dx^2 + dy^2) / R^2`.
#[inline]
pub(super) fn weight(dx: f64, dy: f64, rr: f64) -> Option<f64> {
    let r2 = (dx * dx + dy * dy) / rr;
    if r2 < 1.0 {
        let q = 1.0 - r2;
        Some(q * q * q)
    } else {
        None
    }
}

/// [`accumulate`] over a run of pixels (frame columns from `k0`) whose values are the samples
/// of one atom row `row` times the coefficient `x`, computed as `0.0 + x s` (what
/// [`SparseLayer::patch`] holds for a single atom); `col0` as in [`StampScratch::col0`], else
/// the run's column taps.
#[inline(always)]
fn atom_run(
    (n, d, al): (&mut [f64], &mut [f64], &[f64]),
    z: f64,
    (x, row): (f64, &[f32]),
    (col0, ctaps): (Option<usize>, &[(f64, Taps)]),
    k0: usize,
) {
    if let Some(c0) = col0 {
        let c0 = c0.wrapping_add(k0);
        let v = row[c0..c0 + ctaps.len()]
            .iter()
            .map(|&s| 0.0 + x * s as f64);
        accumulate(n, d, al, z, v);
    } else {
        let v = ctaps
            .iter()
            .map(|(_, (cols, _))| 0.0 + x * row[cols[1]] as f64);
        accumulate(n, d, al, z, v);
    }
}

/// `num += (z + v) * alpha` and `den += alpha` over a run of pixels with values `v`.
#[inline(always)]
fn accumulate(
    num: &mut [f64],
    den: &mut [f64],
    alpha: &[f64],
    z: f64,
    values: impl Iterator<Item = f64>,
) {
    for (((n, d), &a), v) in num.iter_mut().zip(den.iter_mut()).zip(alpha).zip(values) {
        let f = z + v;
        *n += f * a;
        *d += a;
    }
}

/// Largest frame (in pixels) of the cached offsets of a primitive's whole support: above,
/// only the part inside the band is cached (very large scales).
const MAX_FRAME_CELLS: i64 = 1 << 16;

/// Conservative pixel range `(first, last)` of the support `[c - radius, c + radius]` at scale
/// `sc`, unclamped ([`lo_pixel`] and [`hi_pixel`] clamp the same bounds to a band).
#[inline]
fn support_pixels(c: f64, radius: f64, sc: f64) -> (i64, i64) {
    (first_pixel(c - radius, sc), last_pixel(c + radius, sc))
}

/// [`raster_coord`] of a pixel index that may lie outside the raster (`raster_coord` of a
/// non-negative index, bit for bit).
#[inline]
fn raster_coord_i(i: i64, sc: f64) -> f64 {
    if sc == 1.0 {
        i as f64
    } else {
        (i as f64 + 0.5) / sc - 0.5
    }
}

/// First pixel (conservative: one before) whose coordinate at scale `sc` may be `>= v`.
/// Saturating, so huge or infinite extents cannot overflow.
#[inline]
fn first_pixel(v: f64, sc: f64) -> i64 {
    (raster_pixel(v, sc).floor() as i64).saturating_sub(1)
}

/// Last pixel (conservative: one after) whose coordinate at scale `sc` may be `<= v`.
#[inline]
fn last_pixel(v: f64, sc: f64) -> i64 {
    (raster_pixel(v, sc).ceil() as i64).saturating_add(1)
}

/// First pixel (conservative: one before, clamped to the band start `b0`) whose coordinate at
/// scale `sc` may be `>= v`. Saturating, so huge or infinite extents cannot overflow.
#[inline]
pub(super) fn lo_pixel(v: f64, sc: f64, b0: usize) -> i64 {
    first_pixel(v, sc).max(b0 as i64)
}

/// Terrain pixel coordinate sampled by raster pixel `i` at scale `sc`. Pixel-is-area: the
/// raster's cells tile the terrain's extent, so cell centres map to `(i + 1/2) / sc - 1/2`;
/// at scale 1 this is exactly `i`.
#[inline]
pub fn raster_coord(i: usize, sc: f64) -> f64 {
    raster_coord_i(i as i64, sc)
}

/// The (fractional) raster pixel of terrain coordinate `v` at scale `sc`: the inverse of
/// [`raster_coord`].
#[inline]
fn raster_pixel(v: f64, sc: f64) -> f64 {
    if sc == 1.0 { v } else { (v + 0.5) * sc - 0.5 }
}

/// Last pixel (conservative: one after, clamped to the band end `b1 - 1`) whose coordinate at
/// scale `sc` may be `<= v`.
#[inline]
pub(super) fn hi_pixel(v: f64, sc: f64, b1: usize) -> i64 {
    last_pixel(v, sc).min(b1 as i64 - 1)
}

/// Clamped sample indices and weights of a bicubic tap set.
pub(super) type Taps = ([usize; 4], [f64; 4]);

/// Bicubic taps (clamped sample indices and weights) of offset `d` in a patch of side `a`.
#[inline]
pub(super) fn taps(d: f64, delta: f64, a: usize) -> Taps {
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
pub(super) fn is_exact(w: &[f64; 4]) -> bool {
    w[1] == 1.0 && w[0] == 0.0 && w[2] == 0.0 && w[3] == 0.0
}

#[inline]
pub(super) fn hpass(row: &[f64], cols: &[usize; 4], wx: &[f64; 4]) -> f64 {
    let mut acc = 0.0;
    for c in 0..4 {
        acc += wx[c] * row[cols[c]];
    }
    acc
}

#[inline]
pub(super) fn vpass(h: &[f64; 4], wy: &[f64; 4]) -> f64 {
    let mut acc = 0.0;
    for r in 0..4 {
        acc += wy[r] * h[r];
    }
    acc
}

/// A rectangle of output pixels (`cols x rows`) at a scale factor.
#[derive(Debug, Clone)]
pub(super) struct Band {
    pub(super) cols: Range<usize>,
    pub(super) rows: Range<usize>,
    pub(super) scale: f64,
}

impl Band {
    /// Inclusive pixel ranges `[xa, xb, ya, yb]` of the band that may see the terrain box
    /// `[x0, y0, x1, y1]` (conservative: a pixel more on each side), or `None` when empty.
    #[inline]
    pub(super) fn pixels_over(&self, [x0, y0, x1, y1]: [f64; 4]) -> Option<[i64; 4]> {
        let sc = self.scale;
        let (xa, xb) = (
            lo_pixel(x0, sc, self.cols.start),
            hi_pixel(x1, sc, self.cols.end),
        );
        let (ya, yb) = (
            lo_pixel(y0, sc, self.rows.start),
            hi_pixel(y1, sc, self.rows.end),
        );
        (xa <= xb && ya <= yb).then_some([xa, xb, ya, yb])
    }
}

#[derive(Default)]
pub(super) struct StampScratch<'p> {
    /// The caller's progress, asked whether to stop between the children of wide operators.
    pub(super) progress: Option<&'p dyn relief_heightfield::Progress>,
    /// Set once `progress` asked to stop: the band's values are then unfinished.
    pub(super) stopped: bool,
    pub(super) candidates: Vec<u32>,
    pub(super) p: Vec<f64>,
    pub(super) h: Vec<f64>,
    pub(super) ctaps: Vec<(f64, Taps)>,
    pub(super) rtaps: Vec<Taps>,
    pub(super) dx: Vec<f64>,
    pub(super) dy: Vec<f64>,
    /// Weights of the cached offsets (NaN outside the support), row-major.
    pub(super) alpha: Vec<f64>,
    /// Whether every cached column tap set is a sample position.
    pub(super) all_exact: bool,
    /// With `all_exact`, `c0` (wrapping) such that offset `k` reads patch column `c0 + k`
    /// wherever a row's support holds it, when the columns are consecutive there.
    pub(super) col0: Option<usize>,
    /// `(R^2, delta, a)` and the offsets the cached taps and weights were computed for.
    pub(super) key: Option<(f64, f64, usize)>,
    pub(super) key_dx: Vec<f64>,
    pub(super) key_dy: Vec<f64>,
    /// Per cached row, the columns `k0..k1` inside the support (a disk: one run per row), or
    /// `None` when a row's support is not one run (never for the disk weight; kept general).
    pub(super) spans: Vec<Option<(usize, usize)>>,
    /// A child's values and weights while an operator node folds its children (reused from
    /// band to band instead of two fresh band-sized allocations per operator and band).
    pub(super) child: (Vec<f64>, Vec<f64>),
}
