//! Multi-level 2-D separable DWT by lifting.
//!
//! One level transforms the rows (along x) and then the columns (along y). A length-`n` axis
//! splits into `ceil(n/2)` low-pass samples (the even samples, index `2i`) and `floor(n/2)`
//! high-pass samples (the odd samples, index `2i + 1`); a length-1 axis is left as it is (one
//! low-pass sample, no high-pass). The detail bands follow PyWavelets' `dwt2` naming:
//!
//! | band | PyWavelets | along y (rows, axis 0) | along x (columns, axis 1) | shape (w x h) |
//! |------|-----------|------------------------|---------------------------|---------------|
//! | [`Band::H`] | `cH` (horizontal detail) | high-pass | low-pass | `ceil(w/2) x floor(h/2)` |
//! | [`Band::V`] | `cV` (vertical detail)   | low-pass  | high-pass | `floor(w/2) x ceil(h/2)` |
//! | [`Band::D`] | `cD` (diagonal detail)   | high-pass | high-pass | `floor(w/2) x floor(h/2)` |
//!
//! `H` responds to horizontal edges (elevation changing from row to row).

use rayon::prelude::*;
use relief_heightfield::Heightfield;
use serde::{Deserialize, Serialize};

use crate::error::{Result, WaveletError};
pub(crate) use crate::lift::AxisPlan;
use crate::lift::{Boundary, Lifting, lane_maps};
use crate::wavelet::{Scheme, Wavelet};

/// A row-major `f32` grid (`height` rows of `width` values); either side may be 0 for an empty
/// detail band.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Grid {
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
    /// Row-major values, `width * height` of them.
    pub data: Vec<f32>,
}

impl Grid {
    /// A grid from row-major values; an error if the length does not match.
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Result<Self> {
        let expected = width.saturating_mul(height);
        if data.len() != expected {
            return Err(WaveletError::Shape {
                width,
                height,
                expected,
                got: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// A grid of zeros.
    pub fn zeros(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0.0; width * height],
        }
    }

    /// The samples of a heightfield.
    pub fn from_heightfield(hf: &Heightfield) -> Self {
        Self {
            width: hf.width(),
            height: hf.height(),
            data: hf.as_slice().to_vec(),
        }
    }

    /// Value at column `x`, row `y`.
    ///
    /// # Panics
    /// Panics when out of bounds.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[y * self.width + x]
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// True when the grid holds no value.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
}

/// A detail band of a 2-D level (see the module table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Band {
    /// Horizontal detail, PyWavelets `cH`: high-pass along y, low-pass along x.
    H,
    /// Vertical detail, PyWavelets `cV`: low-pass along y, high-pass along x.
    V,
    /// Diagonal detail, PyWavelets `cD`: high-pass along both axes.
    D,
}

impl Band {
    /// The three bands in PyWavelets' order.
    pub const ALL: [Band; 3] = [Band::H, Band::V, Band::D];

    /// Position in [`Band::ALL`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// One-letter name (`h`, `v`, `d`).
    pub fn name(self) -> &'static str {
        ["h", "v", "d"][self as usize]
    }
}

/// The three detail bands of one level.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct DetailLevel {
    /// Horizontal detail (`cH`).
    pub h: Grid,
    /// Vertical detail (`cV`).
    pub v: Grid,
    /// Diagonal detail (`cD`).
    pub d: Grid,
}

impl DetailLevel {
    /// The grid of a band.
    pub fn band(&self, band: Band) -> &Grid {
        match band {
            Band::H => &self.h,
            Band::V => &self.v,
            Band::D => &self.d,
        }
    }
}

/// A multi-level decomposition, ordered like PyWavelets' `wavedec2`: the coarsest
/// approximation, then the detail levels from coarsest (`details[0]`, depth `levels`) to finest
/// (`details[levels - 1]`, depth 1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decomposition {
    /// The basis.
    pub wavelet: Wavelet,
    /// The boundary rule.
    pub boundary: Boundary,
    /// Width of the decomposed signal.
    pub width: usize,
    /// Height of the decomposed signal.
    pub height: usize,
    /// Approximation at the coarsest depth.
    pub approx: Grid,
    /// Detail levels, coarsest first.
    pub details: Vec<DetailLevel>,
}

impl Decomposition {
    /// Number of levels.
    pub fn levels(&self) -> usize {
        self.details.len()
    }

    /// The detail level at `depth` (1 = finest, `levels()` = coarsest).
    pub fn at_depth(&self, depth: usize) -> Option<&DetailLevel> {
        let l = self.details.len();
        (depth >= 1 && depth <= l).then(|| &self.details[l - depth])
    }

    /// Reconstructs the signal (inverse transform of every level).
    pub fn reconstruct(&self) -> Grid {
        waverec2(self)
    }

    /// Checks that the shapes are those [`wavedec2`] produces for `width x height` and
    /// `levels()` levels (always true for its output; a decomposition edited by hand or
    /// deserialised from a file may not be).
    pub fn check(&self) -> Result<()> {
        let bad = |what: String| {
            Err(WaveletError::param(
                "decomposition",
                what,
                "inconsistent shapes",
            ))
        };
        let levels = self.details.len();
        if self.width == 0 || self.height == 0 || levels > max_levels(self.width, self.height) {
            return bad(format!(
                "{} x {} with {levels} levels",
                self.width, self.height
            ));
        }
        let grid_ok =
            |g: &Grid, w: usize, h: usize| g.width == w && g.height == h && g.data.len() == w * h;
        let (aw, ah) = (
            size_at_depth(self.width, levels),
            size_at_depth(self.height, levels),
        );
        if !grid_ok(&self.approx, aw, ah) {
            return bad(format!(
                "approximation {} x {} ({} values), expected {aw} x {ah}",
                self.approx.width,
                self.approx.height,
                self.approx.data.len()
            ));
        }
        for (i, lvl) in self.details.iter().enumerate() {
            let depth = levels - i;
            let (pw, ph) = (
                size_at_depth(self.width, depth - 1),
                size_at_depth(self.height, depth - 1),
            );
            if self.boundary == Boundary::Periodic
                && ((pw % 2 == 1 && pw > 1) || (ph % 2 == 1 && ph > 1))
            {
                return Err(WaveletError::OddPeriodic {
                    level: depth,
                    len: if pw % 2 == 1 { pw } else { ph },
                });
            }
            let (lw, hw, lh, hh) = (pw.div_ceil(2), pw / 2, ph.div_ceil(2), ph / 2);
            for (band, g, w, h) in [
                (Band::H, &lvl.h, lw, hh),
                (Band::V, &lvl.v, hw, lh),
                (Band::D, &lvl.d, hw, hh),
            ] {
                if !grid_ok(g, w, h) {
                    return bad(format!(
                        "band {} at depth {depth}: {} x {} ({} values), expected {w} x {h}",
                        band.name(),
                        g.width,
                        g.height,
                        g.data.len()
                    ));
                }
            }
        }
        Ok(())
    }
}

/// Number of levels after which both sides are 1 (`ceil(log2(max(w, h)))`).
pub fn max_levels(width: usize, height: usize) -> usize {
    let n = width.max(height).max(1);
    (usize::BITS - (n - 1).leading_zeros()) as usize
}

/// Size of an axis of length `n` after `depth` levels (`ceil(n / 2^depth)`).
pub fn size_at_depth(n: usize, depth: usize) -> usize {
    let mut n = n;
    for _ in 0..depth {
        n = n.div_ceil(2);
    }
    n
}

fn par_for(len: usize) -> bool {
    len >= 1 << 15
}

/// Runs `a` and `b`, side by side when `par`.
fn join_if(par: bool, a: impl FnOnce() + Send, b: impl FnOnce() + Send) {
    if par {
        rayon::join(a, b);
    } else {
        a();
        b();
    }
}

/// One forward level of the 2-D transform: `(LL, H, V, D)`.
pub(crate) fn forward_level(
    x: &Grid,
    scheme: &Scheme,
    boundary: Boundary,
    par: bool,
) -> (Grid, Grid, Grid, Grid) {
    let (w, h) = (x.width, x.height);
    let x = &x.data[..w * h];
    let (wl, wh) = (w.div_ceil(2), w / 2);
    let (hl, hh) = (h.div_ceil(2), h / 2);
    // The row pass (along x) writes even rows straight into the low-y lanes and odd rows into
    // the high-y lanes, so the column pass lifts in place without a copy.
    let mut sl = vec![0.0f32; hl * wl];
    let mut dl = vec![0.0f32; hh * wl];
    let mut sh = vec![0.0f32; hl * wh];
    let mut dh = vec![0.0f32; hh * wh];
    let (em, om) = lane_maps(w, boundary, 0, wl, 0, wh);
    let lifting = Lifting::forward(scheme);
    let row_pass = |lo: &mut [f32], hi: &mut [f32], parity: usize| {
        let one = |(i, (e, o)): (usize, (&mut [f32], &mut [f32]))| {
            let y = 2 * i + parity;
            let r = &x[y * w..(y + 1) * w];
            deinterleave(r, e, o);
            lifting.run_1d(e, o, &em, &om);
        };
        if wh == 0 {
            // A single column: nothing to transform along x.
            for (i, e) in lo.chunks_mut(wl).enumerate() {
                e[0] = x[(2 * i + parity) * w];
            }
        } else if par {
            lo.par_chunks_mut(wl)
                .zip(hi.par_chunks_mut(wh))
                .enumerate()
                .for_each(one);
        } else {
            lo.chunks_mut(wl)
                .zip(hi.chunks_mut(wh))
                .enumerate()
                .for_each(one);
        }
    };
    row_pass(&mut sl, &mut sh, 0);
    if hh > 0 {
        row_pass(&mut dl, &mut dh, 1);
    }
    // Column pass (along y): the low-x and high-x halves are independent, so with `par` they
    // run side by side (each one row-pipelined sweep).
    let (emy, omy) = lane_maps(h, boundary, 0, hl, 0, hh);
    join_if(
        par,
        || lifting.run_rows(&mut sl, &mut dl, &emy, &omy, wl, par),
        || lifting.run_rows(&mut sh, &mut dh, &emy, &omy, wh, par),
    );
    let grid = |width: usize, height: usize, data: Vec<f32>| Grid {
        width,
        height,
        data,
    };
    (
        grid(wl, hl, sl),
        grid(wl, hh, dl),
        grid(wh, hl, sh),
        grid(wh, hh, dh),
    )
}

/// Inverse of one level on a window: returns the `px.out x py.out` window of the finer level
/// from the lane regions of the four inputs given by the plans (approximation `even x even`,
/// `H` `x even, y odd`, `V` `x odd, y even`, `D` `odd x odd`).
pub(crate) fn inverse_level_window(
    scheme: &Scheme,
    boundary: Boundary,
    px: &AxisPlan,
    py: &AxisPlan,
    approx: Vec<f32>,
    hb: Vec<f32>,
    vb: Vec<f32>,
    db: Vec<f32>,
    par: bool,
) -> Vec<f32> {
    let (ex, ox) = (px.even.len(), px.odd.len());
    let (ey, oy) = (py.even.len(), py.odd.len());
    debug_assert_eq!(approx.len(), ex * ey);
    debug_assert_eq!(hb.len(), ex * oy);
    debug_assert_eq!(vb.len(), ox * ey);
    debug_assert_eq!(db.len(), ox * oy);
    let (emy, omy) = lane_maps(py.n, boundary, py.even.start, ey, py.odd.start, oy);
    let (mut s1, mut d1) = (approx, hb);
    let (mut s2, mut d2) = (vb, db);
    let lifting = Lifting::inverse(scheme);
    // The low-x and high-x halves of the column pass are independent.
    join_if(
        par,
        || lifting.run_rows(&mut s1, &mut d1, &emy, &omy, ex, par),
        || lifting.run_rows(&mut s2, &mut d2, &emy, &omy, ox, par),
    );
    // Row pass: each output row lifts its two lane rows in place (no copies) and interleaves
    // them. `lanes[r]` are the (even-x, odd-x) lane rows of output row `py.out.start + r`.
    let (emx, omx) = lane_maps(px.n, boundary, px.even.start, ex, px.odd.start, ox);
    let ow = px.out.len();
    let (mut r_s1, mut r_s2) = (rows_of(&mut s1, ex, ey), rows_of(&mut s2, ox, ey));
    let (mut r_d1, mut r_d2) = (rows_of(&mut d1, ex, oy), rows_of(&mut d2, ox, oy));
    let lanes: Vec<(&mut [f32], &mut [f32])> = py
        .out
        .clone()
        .map(|y| {
            if y.is_multiple_of(2) {
                let r = y / 2 - py.even.start;
                (std::mem::take(&mut r_s1[r]), std::mem::take(&mut r_s2[r]))
            } else {
                let r = (y - 1) / 2 - py.odd.start;
                (std::mem::take(&mut r_d1[r]), std::mem::take(&mut r_d2[r]))
            }
        })
        .collect();
    let mut out = vec![0.0f32; ow * py.out.len()];
    let body = |(orow, (e, o)): (&mut [f32], (&mut [f32], &mut [f32]))| {
        lifting.run_1d(e, o, &emx, &omx);
        interleave(orow, px, e, o);
    };
    if ow == 0 {
        return out;
    }
    if par {
        out.par_chunks_mut(ow).zip(lanes).for_each(body);
    } else {
        out.chunks_mut(ow).zip(lanes).for_each(body);
    }
    out
}

/// The rows of a row-major buffer `width` wide (`count` empty rows when `width` is 0).
fn rows_of(v: &mut [f32], width: usize, count: usize) -> Vec<&mut [f32]> {
    if width == 0 {
        (0..count).map(|_| <&mut [f32]>::default()).collect()
    } else {
        v.chunks_mut(width).collect()
    }
}

/// Splits a row into its even (`e`) and odd (`o`) samples.
fn deinterleave(r: &[f32], e: &mut [f32], o: &mut [f32]) {
    for ((e, o), p) in e.iter_mut().zip(o.iter_mut()).zip(r.chunks_exact(2)) {
        *e = p[0];
        *o = p[1];
    }
    if r.len() % 2 == 1 {
        e[r.len() / 2] = r[r.len() - 1];
    }
}

/// Writes the `px.out` range of a finer row from its lane segments `e` (from `px.even.start`)
/// and `o` (from `px.odd.start`).
fn interleave(orow: &mut [f32], px: &AxisPlan, e: &[f32], o: &[f32]) {
    let mut x = px.out.start;
    let mut k = 0;
    if !x.is_multiple_of(2) && !orow.is_empty() {
        orow[0] = o[(x - 1) / 2 - px.odd.start];
        k = 1;
        x += 1;
    }
    // From here `x` is even: pairs (e, o) until the end, then maybe one even sample.
    let pairs = (orow.len() - k) / 2;
    let (ei, oi) = (x / 2 - px.even.start, x / 2 - px.odd.start);
    if pairs > 0 {
        let (e, o) = (&e[ei..ei + pairs], &o[oi..oi + pairs]);
        for ((p, e), o) in orow[k..k + 2 * pairs].chunks_exact_mut(2).zip(e).zip(o) {
            p[0] = *e;
            p[1] = *o;
        }
    }
    if k + 2 * pairs < orow.len() {
        orow[k + 2 * pairs] = e[ei + pairs];
    }
}

/// Multi-level forward transform (PyWavelets `wavedec2`). `levels` may be 0 (no transform)
/// up to [`max_levels`].
pub fn wavedec2(
    x: &Grid,
    wavelet: Wavelet,
    levels: usize,
    boundary: Boundary,
) -> Result<Decomposition> {
    if x.data.len() != x.width * x.height || x.width == 0 || x.height == 0 {
        return Err(WaveletError::Shape {
            width: x.width,
            height: x.height,
            expected: x.width * x.height,
            got: x.data.len(),
        });
    }
    let maxl = max_levels(x.width, x.height);
    if levels > maxl {
        return Err(WaveletError::param(
            "levels",
            levels,
            "more levels than ceil(log2(max(width, height)))",
        ));
    }
    if boundary == Boundary::Periodic {
        for k in 0..levels {
            for n in [size_at_depth(x.width, k), size_at_depth(x.height, k)] {
                if n % 2 == 1 && n > 1 {
                    return Err(WaveletError::OddPeriodic {
                        level: k + 1,
                        len: n,
                    });
                }
            }
        }
    }
    let scheme = wavelet.scheme();
    // The first level reads `x` itself (no copy of the input).
    let mut approx: Option<Grid> = None;
    let mut details = Vec::with_capacity(levels);
    for _ in 0..levels {
        let src = approx.as_ref().unwrap_or(x);
        let (ll, h, v, d) = forward_level(src, scheme, boundary, par_for(src.len()));
        details.push(DetailLevel { h, v, d });
        approx = Some(ll);
    }
    let approx = approx.unwrap_or_else(|| x.clone());
    details.reverse();
    Ok(Decomposition {
        wavelet,
        boundary,
        width: x.width,
        height: x.height,
        approx,
        details,
    })
}

/// Multi-level inverse transform of a decomposition whose shapes are first checked
/// ([`Decomposition::check`]): use it for decompositions that did not come straight from
/// [`wavedec2`].
pub fn try_waverec2(dec: &Decomposition) -> Result<Grid> {
    dec.check()?;
    Ok(waverec2(dec))
}

/// Multi-level inverse transform (PyWavelets `waverec2`). `dec` is left untouched (its bands
/// are copied as lifting scratch); [`waverec2_owned`] avoids the copies.
///
/// # Panics
/// If the shapes of `dec` are inconsistent, which cannot happen for the output of
/// [`wavedec2`]; see [`try_waverec2`] for decompositions edited or read from elsewhere.
pub fn waverec2(dec: &Decomposition) -> Grid {
    inverse_all(
        dec.wavelet,
        dec.boundary,
        dec.width,
        dec.height,
        dec.approx.clone(),
        dec.details
            .iter()
            .map(|l| (l.h.data.clone(), l.v.data.clone(), l.d.data.clone())),
    )
}

/// [`waverec2`] of a decomposition that is no longer needed: its band buffers are lifted in
/// place instead of copied (same values bit for bit, less memory traffic).
///
/// # Panics
/// As [`waverec2`], if the shapes are inconsistent ([`Decomposition::check`]).
pub fn waverec2_owned(dec: Decomposition) -> Grid {
    let Decomposition {
        wavelet,
        boundary,
        width,
        height,
        approx,
        details,
    } = dec;
    inverse_all(
        wavelet,
        boundary,
        width,
        height,
        approx,
        details.into_iter().map(|l| (l.h.data, l.v.data, l.d.data)),
    )
}

fn inverse_all(
    wavelet: Wavelet,
    boundary: Boundary,
    width: usize,
    height: usize,
    mut approx: Grid,
    details: impl ExactSizeIterator<Item = (Vec<f32>, Vec<f32>, Vec<f32>)>,
) -> Grid {
    let scheme = wavelet.scheme();
    let levels = details.len();
    for (i, (hb, vb, db)) in details.enumerate() {
        let depth = levels - i - 1;
        let (w, h) = (size_at_depth(width, depth), size_at_depth(height, depth));
        let px = AxisPlan::new(w, 0..w, 0);
        let py = AxisPlan::new(h, 0..h, 0);
        let data = inverse_level_window(
            scheme,
            boundary,
            &px,
            &py,
            approx.data,
            hb,
            vb,
            db,
            par_for(w * h),
        );
        approx = Grid {
            width: w,
            height: h,
            data,
        };
    }
    approx
}

/// Single-level 1-D forward transform of a signal: `(low, high)` with `ceil(n/2)` and
/// `floor(n/2)` values.
pub fn dwt1(signal: &[f32], wavelet: Wavelet, boundary: Boundary) -> Result<(Vec<f32>, Vec<f32>)> {
    let n = signal.len();
    if n == 0 {
        return Err(WaveletError::param("signal", "[]", "must not be empty"));
    }
    if boundary == Boundary::Periodic && n % 2 == 1 && n > 1 {
        return Err(WaveletError::OddPeriodic { level: 1, len: n });
    }
    let mut e: Vec<f32> = signal.iter().step_by(2).copied().collect();
    let mut o: Vec<f32> = signal.iter().skip(1).step_by(2).copied().collect();
    let (em, om) = lane_maps(n, boundary, 0, e.len(), 0, o.len());
    Lifting::forward(wavelet.scheme()).run_1d(&mut e, &mut o, &em, &om);
    Ok((e, o))
}

/// Single-level 1-D inverse of [`dwt1`].
pub fn idwt1(low: &[f32], high: &[f32], wavelet: Wavelet, boundary: Boundary) -> Result<Vec<f32>> {
    if low.len() != high.len() && low.len() != high.len() + 1 || low.is_empty() {
        return Err(WaveletError::param(
            "high",
            high.len(),
            "needs len(low) - 1 or len(low) values",
        ));
    }
    let n = low.len() + high.len();
    if boundary == Boundary::Periodic && n % 2 == 1 && n > 1 {
        return Err(WaveletError::OddPeriodic { level: 1, len: n });
    }
    let (mut e, mut o) = (low.to_vec(), high.to_vec());
    let (em, om) = lane_maps(n, boundary, 0, e.len(), 0, o.len());
    Lifting::inverse(wavelet.scheme()).run_1d(&mut e, &mut o, &em, &om);
    let mut out = vec![0.0f32; n];
    for (i, v) in out.iter_mut().enumerate() {
        *v = if i % 2 == 0 { e[i / 2] } else { o[i / 2] };
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lift::test_values as values;

    fn bits(v: &[f32]) -> Vec<u32> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    /// One forward level the plain way: rows split sample by sample and lifted, then the
    /// columns lifted one whole step after the other.
    fn forward_reference(x: &Grid, scheme: &Scheme, boundary: Boundary) -> [Vec<f32>; 4] {
        let (w, h) = (x.width, x.height);
        let (wl, wh, hl, hh) = (w.div_ceil(2), w / 2, h.div_ceil(2), h / 2);
        let (em, om) = lane_maps(w, boundary, 0, wl, 0, wh);
        let lifting = Lifting::forward(scheme).stepwise();
        let (mut sl, mut sh, mut dl, mut dh) = (vec![], vec![], vec![], vec![]);
        for y in 0..h {
            let r = &x.data[y * w..(y + 1) * w];
            let mut e: Vec<f32> = r.iter().step_by(2).copied().collect();
            let mut o: Vec<f32> = r.iter().skip(1).step_by(2).copied().collect();
            lifting.run_1d(&mut e, &mut o, &em, &om);
            let (lo, hi) = if y % 2 == 0 {
                (&mut sl, &mut sh)
            } else {
                (&mut dl, &mut dh)
            };
            lo.extend(e);
            hi.extend(o);
        }
        let (emy, omy) = lane_maps(h, boundary, 0, hl, 0, hh);
        lifting.run_rows(&mut sl, &mut dl, &emy, &omy, wl, false);
        lifting.run_rows(&mut sh, &mut dh, &emy, &omy, wh, false);
        [sl, dl, sh, dh]
    }

    /// One inverse level on a window the plain way: columns step by step, then each output
    /// row from copies of its lane rows, sample by sample.
    fn inverse_reference(
        scheme: &Scheme,
        boundary: Boundary,
        px: &AxisPlan,
        py: &AxisPlan,
        bands: [Vec<f32>; 4],
    ) -> Vec<f32> {
        let [mut s1, mut d1, mut s2, mut d2] = bands;
        let (ex, ox) = (px.even.len(), px.odd.len());
        let (emy, omy) = lane_maps(
            py.n,
            boundary,
            py.even.start,
            py.even.len(),
            py.odd.start,
            py.odd.len(),
        );
        let lifting = Lifting::inverse(scheme).stepwise();
        lifting.run_rows(&mut s1, &mut d1, &emy, &omy, ex, false);
        lifting.run_rows(&mut s2, &mut d2, &emy, &omy, ox, false);
        let (emx, omx) = lane_maps(px.n, boundary, px.even.start, ex, px.odd.start, ox);
        let mut out = Vec::new();
        for y in py.out.clone() {
            let (lo, hi, r) = if y % 2 == 0 {
                (&s1, &s2, y / 2 - py.even.start)
            } else {
                (&d1, &d2, (y - 1) / 2 - py.odd.start)
            };
            let mut e = lo[r * ex..(r + 1) * ex].to_vec();
            let mut o = hi[r * ox..(r + 1) * ox].to_vec();
            lifting.run_1d(&mut e, &mut o, &emx, &omx);
            for x in px.out.clone() {
                out.push(if x % 2 == 0 {
                    e[x / 2 - px.even.start]
                } else {
                    o[(x - 1) / 2 - px.odd.start]
                });
            }
        }
        out
    }

    /// The fast forward and inverse levels (pipelined columns, split rows, in-place row pass,
    /// paired interleave, halves side by side) give the plain order's values bit for bit:
    /// every basis, both boundaries, odd sizes, full levels and windows, 1 and 2 threads.
    #[test]
    fn fast_levels_equal_the_plain_order() {
        let mut seed = 7;
        for wavelet in Wavelet::ALL {
            let scheme = wavelet.scheme();
            for boundary in [Boundary::Symmetric, Boundary::Periodic] {
                for (w, h) in [(1, 1), (1, 6), (7, 1), (2, 2), (9, 14), (16, 11), (33, 20)] {
                    let periodic = boundary == Boundary::Periodic;
                    if periodic && ((w % 2 == 1 && w > 1) || (h % 2 == 1 && h > 1)) {
                        continue;
                    }
                    seed += 1;
                    let x = Grid::new(w, h, values(w * h, seed)).unwrap();
                    let want = forward_reference(&x, scheme, boundary);
                    for par in [false, true] {
                        let (a, b, c, d) = forward_level(&x, scheme, boundary, par);
                        let got = [a.data, b.data, c.data, d.data];
                        for (g, r) in got.iter().zip(&want) {
                            assert_eq!(bits(g), bits(r), "forward {wavelet} {boundary:?} {w}x{h}");
                        }
                    }
                    let m = wavelet.synthesis_margin();
                    let windows = [
                        (0..w, 0..h),
                        (w / 3..w, h / 2..h),
                        (w / 2..w / 2 + 1, 1.min(h - 1)..h),
                    ];
                    for (xs, ys) in windows {
                        let (px, py) = (AxisPlan::new(w, xs, m), AxisPlan::new(h, ys, m));
                        let (ex, ox, ey, oy) =
                            (px.even.len(), px.odd.len(), py.even.len(), py.odd.len());
                        seed += 4;
                        let bands = [
                            values(ex * ey, seed),
                            values(ex * oy, seed + 1),
                            values(ox * ey, seed + 2),
                            values(ox * oy, seed + 3),
                        ];
                        let want = inverse_reference(scheme, boundary, &px, &py, bands.clone());
                        for par in [false, true] {
                            let [a, b, c, d] = bands.clone();
                            let got =
                                inverse_level_window(scheme, boundary, &px, &py, a, b, c, d, par);
                            assert_eq!(
                                bits(&got),
                                bits(&want),
                                "inverse {wavelet} {boundary:?} {w}x{h} {px:?} {py:?}"
                            );
                        }
                    }
                }
            }
        }
    }
}
