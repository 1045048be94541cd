//! Lifting steps on lane segments, shared by the whole-signal transforms and the windowed
//! (on-demand) synthesis. Every output value is computed by the same sequence of floating-point
//! operations whatever the segment, which is what makes a window bit-identical to the same
//! window of a full run.
//!
//! Along columns the steps are row-pipelined ([`Pipeline`]): one sweep over the rows applies
//! every step, each one row behind the one before, so each lane row passes through the cache
//! once per level instead of once per step. The schedule is only used when it provably reads
//! every value at the stage the step-by-step order would, so it is an exact reordering.

use std::ops::Range;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::wavelet::{Lane, Scheme};

/// How a signal is extended past its ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Boundary {
    /// Whole-sample symmetric extension (`x[-k] = x[k]`, `x[n-1+k] = x[n-1-k]`) applied to the
    /// lanes at every lifting step. For the symmetric bases (CDF 5/3, CDF 9/7) this equals
    /// convolution with a whole-sample symmetric extension of the signal (PyWavelets mode
    /// `reflect`); for Haar and Daubechies-4 it is a boundary rule of the lifting steps. Works
    /// for every length.
    #[default]
    Symmetric,
    /// Periodic extension (PyWavelets mode `periodization`); every decomposed length must be
    /// even.
    Periodic,
}

/// Maps global lane indices of one lane of a length-`n` signal to local indices of a stored
/// segment `[seg0, seg0 + seglen)` of that lane. Indices past the signal ends are mirrored (or
/// wrapped); indices inside the signal but outside the segment are clamped into it: they only
/// feed values in the margin, which are discarded.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LaneMap {
    pub(crate) n: usize,
    pub(crate) odd: bool,
    pub(crate) boundary: Boundary,
    pub(crate) seg0: isize,
    pub(crate) seglen: usize,
}

impl LaneMap {
    pub(crate) fn lane_len(&self) -> usize {
        if self.odd {
            self.n / 2
        } else {
            self.n.div_ceil(2)
        }
    }

    #[inline]
    pub(crate) fn local(&self, g: isize) -> usize {
        let odd = self.odd as isize;
        let n = self.n as isize;
        let p = 2 * g + odd;
        let p = match self.boundary {
            Boundary::Symmetric => {
                let per = 2 * n - 2;
                if per <= 0 {
                    0
                } else {
                    let q = p.rem_euclid(per);
                    if q > n - 1 { per - q } else { q }
                }
            }
            Boundary::Periodic => p.rem_euclid(n),
        };
        let g2 = (p - odd) / 2;
        (g2 - self.seg0).clamp(0, self.seglen as isize - 1) as usize
    }

    /// The range of target indices `i` (global) for which `i + off` lies inside both the signal
    /// and the segment for every `off` in `[min_off, max_off]`.
    fn fast_range(&self, min_off: isize, max_off: isize) -> (isize, isize) {
        let lo = self.seg0.max(0);
        let hi = (self.seg0 + self.seglen as isize).min(self.lane_len() as isize);
        (lo - min_off, hi - max_off)
    }
}

#[inline]
fn tap_range(taps: &[(isize, f32)]) -> (isize, isize) {
    let min = taps.iter().map(|t| t.0).min().unwrap_or(0);
    let max = taps.iter().map(|t| t.0).max().unwrap_or(0);
    (min, max)
}

/// The step's increment from the source values at its taps. Two taps with equal weights use
/// `c * (a + b)` (fewer roundings, the symmetric form).
#[inline(always)]
fn combine(taps: &[(isize, f32)], vals: [f32; 2]) -> f32 {
    match taps.len() {
        1 => taps[0].1 * vals[0],
        _ if taps[0].1 == taps[1].1 => taps[0].1 * (vals[0] + vals[1]),
        _ => taps[0].1 * vals[0] + taps[1].1 * vals[1],
    }
}

/// Applies one lifting step to a 1-D target lane segment (`t0` = global index of
/// `target[0]`) from the source lane segment described by `smap`.
pub(crate) fn step_1d(
    target: &mut [f32],
    t0: isize,
    src: &[f32],
    smap: &LaneMap,
    taps: &[(isize, f32)],
    subtract: bool,
) {
    let (min_off, max_off) = tap_range(taps);
    let (f0, f1) = smap.fast_range(min_off, max_off);
    let tn = target.len() as isize;
    let f0 = f0.clamp(t0, t0 + tn);
    let f1 = f1.clamp(f0, t0 + tn);
    let slow = |target: &mut [f32], i: isize| {
        let mut vals = [0.0f32; 2];
        for (k, t) in taps.iter().enumerate() {
            vals[k] = src[smap.local(i + t.0)];
        }
        let inc = combine(taps, vals);
        let t = &mut target[(i - t0) as usize];
        if subtract { *t -= inc } else { *t += inc }
    };
    for i in t0..f0 {
        slow(target, i);
    }
    for i in f1..t0 + tn {
        slow(target, i);
    }
    if f1 > f0 {
        let len = (f1 - f0) as usize;
        let tgt = &mut target[(f0 - t0) as usize..(f0 - t0) as usize + len];
        let sa = (f0 + taps[0].0 - smap.seg0) as usize;
        let a = &src[sa..sa + len];
        let b = match taps.get(1) {
            Some(t) => {
                let sb = (f0 + t.0 - smap.seg0) as usize;
                &src[sb..sb + len]
            }
            None => a,
        };
        row_op(tgt, a, b, taps, subtract);
    }
}

/// `row (+|-)= taps . (a, b)` over one row, in the forms of [`combine`] (`c * (a + b)` for equal
/// weights), written as plain slice loops so they vectorise.
#[inline(always)]
fn row_op(row: &mut [f32], a: &[f32], b: &[f32], taps: &[(isize, f32)], subtract: bool) {
    if taps.len() == 1 {
        let c = taps[0].1;
        let a = &a[..row.len()];
        if subtract {
            row.iter_mut().zip(a).for_each(|(t, a)| *t -= c * a);
        } else {
            row.iter_mut().zip(a).for_each(|(t, a)| *t += c * a);
        }
        return;
    }
    let (a, b) = (&a[..row.len()], &b[..row.len()]);
    let (c0, c1) = (taps[0].1, taps[1].1);
    match (c0 == c1, subtract) {
        (true, false) => row
            .iter_mut()
            .zip(a.iter().zip(b))
            .for_each(|(t, (a, b))| *t += c0 * (a + b)),
        (true, true) => row
            .iter_mut()
            .zip(a.iter().zip(b))
            .for_each(|(t, (a, b))| *t -= c0 * (a + b)),
        (false, false) => row
            .iter_mut()
            .zip(a.iter().zip(b))
            .for_each(|(t, (a, b))| *t += c0 * a + c1 * b),
        (false, true) => row
            .iter_mut()
            .zip(a.iter().zip(b))
            .for_each(|(t, (a, b))| *t -= c0 * a + c1 * b),
    }
}

/// Applies one lifting step along columns: lanes are whole rows of `width` values; `target`
/// holds rows of the target lane starting at global lane row `t0`.
pub(crate) fn step_rows(
    target: &mut [f32],
    t0: isize,
    src: &[f32],
    smap: &LaneMap,
    width: usize,
    taps: &[(isize, f32)],
    subtract: bool,
    par: bool,
) {
    if width == 0 {
        return;
    }
    let body = |(r, row): (usize, &mut [f32])| {
        let i = t0 + r as isize;
        let ra = smap.local(i + taps[0].0) * width;
        let rb = smap.local(i + taps[taps.len() - 1].0) * width;
        row_op(
            row,
            &src[ra..ra + width],
            &src[rb..rb + width],
            taps,
            subtract,
        );
    };
    if par {
        target.par_chunks_mut(width).enumerate().for_each(body);
    } else {
        target.chunks_mut(width).enumerate().for_each(body);
    }
}

/// Lane maps of a segment pair: even lane from global index `e0`, odd from `o0`.
pub(crate) fn lane_maps(
    n: usize,
    boundary: Boundary,
    e0: usize,
    elen: usize,
    o0: usize,
    olen: usize,
) -> (LaneMap, LaneMap) {
    (
        LaneMap {
            n,
            odd: false,
            boundary,
            seg0: e0 as isize,
            seglen: elen,
        },
        LaneMap {
            n,
            odd: true,
            boundary,
            seg0: o0 as isize,
            seglen: olen,
        },
    )
}

/// The target lane of an operation on `target` with its map, and the other (source) lane
/// with its map.
fn parts<'a>(
    target: Lane,
    even: &'a mut [f32],
    odd: &'a mut [f32],
    em: &'a LaneMap,
    om: &'a LaneMap,
) -> (&'a mut [f32], &'a LaneMap, &'a [f32], &'a LaneMap) {
    match target {
        Lane::Even => (even, em, odd, om),
        Lane::Odd => (odd, om, even, em),
    }
}

/// One operation of a lifting: a step (`taps` not empty) or a scaling of the target lane by
/// `k` (`taps` empty).
#[derive(Debug, Clone, Copy)]
struct ColOp {
    target: Lane,
    taps: &'static [(isize, f32)],
    subtract: bool,
    k: f32,
}

/// The operations of one level of a scheme in one direction, in order, built once and applied
/// to every lane pair of the level: along rows ([`Lifting::run_1d`]) and along columns
/// ([`Lifting::run_rows`]).
pub(crate) struct Lifting {
    ops: Vec<ColOp>,
    /// Whether [`Lifting::run_rows`] may use the row-pipelined schedule.
    pipelined: bool,
}

impl Lifting {
    /// The forward (analysis) lifting: the steps, then the scalings that are not 1.
    pub(crate) fn forward(scheme: &Scheme) -> Self {
        let mut ops: Vec<ColOp> = scheme
            .steps
            .iter()
            .map(|s| ColOp {
                target: s.target,
                taps: s.taps,
                subtract: false,
                k: 1.0,
            })
            .collect();
        ops.extend(scale_ops(scheme.scale_even, scheme.scale_odd));
        Self {
            ops,
            pipelined: true,
        }
    }

    /// The inverse lifting: the unscalings that are not 1, then the steps reversed,
    /// subtracting.
    pub(crate) fn inverse(scheme: &Scheme) -> Self {
        let mut ops = scale_ops(1.0 / scheme.scale_even, 1.0 / scheme.scale_odd);
        ops.extend(scheme.steps.iter().rev().map(|s| ColOp {
            target: s.target,
            taps: s.taps,
            subtract: true,
            k: 1.0,
        }));
        Self {
            ops,
            pipelined: true,
        }
    }

    /// Lifts one 1-D segment pair in place.
    pub(crate) fn run_1d(&self, even: &mut [f32], odd: &mut [f32], em: &LaneMap, om: &LaneMap) {
        if odd.is_empty() {
            return;
        }
        for op in &self.ops {
            let (t, tm, s, sm) = parts(op.target, even, odd, em, om);
            if op.taps.is_empty() {
                scale(t, op.k);
            } else {
                step_1d(t, tm.seg0, s, sm, op.taps, op.subtract);
            }
        }
    }

    /// Lifts row-lane buffers (each `width` wide) along columns in place: row-pipelined when
    /// the schedule allows it ([`Pipeline`]), else one whole operation after the other (each
    /// parallel over rows when `par`).
    pub(crate) fn run_rows(
        &self,
        even: &mut [f32],
        odd: &mut [f32],
        em: &LaneMap,
        om: &LaneMap,
        width: usize,
        par: bool,
    ) {
        if odd.is_empty() || width == 0 {
            return;
        }
        if self.pipelined
            && let Some(p) = Pipeline::new(&self.ops, em, om)
        {
            p.run(&self.ops, even, odd, em, om, width);
            return;
        }
        for op in &self.ops {
            let (t, tm, s, sm) = parts(op.target, even, odd, em, om);
            if op.taps.is_empty() {
                scale_par(t, op.k, par);
            } else {
                step_rows(t, tm.seg0, s, sm, width, op.taps, op.subtract, par);
            }
        }
    }

    /// The same lifting whose [`Lifting::run_rows`] always goes one whole operation after the
    /// other: the reference order the pipelined schedule must reproduce.
    #[cfg(test)]
    pub(crate) fn stepwise(&self) -> Self {
        Self {
            ops: self.ops.clone(),
            pipelined: false,
        }
    }
}

fn scale_ops(ke: f32, ko: f32) -> Vec<ColOp> {
    [(Lane::Even, ke), (Lane::Odd, ko)]
        .into_iter()
        .filter(|&(_, k)| k != 1.0)
        .map(|(target, k)| ColOp {
            target,
            taps: &[],
            subtract: false,
            k,
        })
        .collect()
}

/// A row-pipelined schedule of column operations: in sweep `r`, operation `s` processes
/// target lane row `r - s` (global index), so every operation runs one row behind the one
/// before it and the whole transform is one pass over the rows (each row is loaded once
/// into cache instead of once per step). `rows[s][i]` are the local source rows of the taps
/// of operation `s` at local target row `i`.
///
/// The schedule is used only when every source row read by operation `s` is, at that point of
/// the sweep, already written by the last earlier operation on the source lane and not yet
/// overwritten by the next one, so every value goes through exactly the operations of the
/// step-by-step order (bit-identical, margins included). That holds for the symmetric boundary
/// (mirrored rows stay within one row of the target) and fails for periodic lanes, whose wrap
/// reaches the other end of the lane; those use the step-by-step order.
struct Pipeline {
    rows: Vec<Vec<[usize; 2]>>,
}

impl Pipeline {
    fn new(ops: &[ColOp], em: &LaneMap, om: &LaneMap) -> Option<Self> {
        let map = |l: Lane| if l == Lane::Even { em } else { om };
        let mut rows = Vec::with_capacity(ops.len());
        for (s, op) in ops.iter().enumerate() {
            let src_lane = if op.target == Lane::Even {
                Lane::Odd
            } else {
                Lane::Even
            };
            let (tm, sm) = (map(op.target), map(src_lane));
            let prev = ops[..s].iter().rposition(|o| o.target == src_lane);
            let next = ops[s + 1..]
                .iter()
                .position(|o| o.target == src_lane)
                .map(|p| p + s + 1);
            let mut table = Vec::with_capacity(if op.taps.is_empty() { 0 } else { tm.seglen });
            for i in 0..if op.taps.is_empty() { 0 } else { tm.seglen } {
                let ig = tm.seg0 + i as isize;
                let mut js = [0usize; 2];
                for (k, t) in op.taps.iter().enumerate() {
                    let j = sm.local(ig + t.0);
                    let jg = sm.seg0 + j as isize;
                    let late = prev.is_some_and(|p| jg > ig + (s - p) as isize);
                    let early = next.is_some_and(|n| jg < ig + s as isize - n as isize);
                    if late || early {
                        return None;
                    }
                    js[k] = j;
                }
                if op.taps.len() == 1 {
                    js[1] = js[0];
                }
                table.push(js);
            }
            rows.push(table);
        }
        Some(Self { rows })
    }

    /// Runs the schedule over row-lane buffers `width` wide.
    fn run(
        &self,
        ops: &[ColOp],
        even: &mut [f32],
        odd: &mut [f32],
        em: &LaneMap,
        om: &LaneMap,
        width: usize,
    ) {
        let g0 = em.seg0.min(om.seg0);
        let g1 = (em.seg0 + em.seglen as isize).max(om.seg0 + om.seglen as isize);
        for r in g0..g1 + ops.len() as isize {
            for (s, op) in ops.iter().enumerate() {
                let (tgt, tm, src, _) = parts(op.target, even, odd, em, om);
                let i = r - s as isize - tm.seg0;
                if i < 0 || i >= tm.seglen as isize {
                    continue;
                }
                let i = i as usize;
                let row = &mut tgt[i * width..(i + 1) * width];
                if op.taps.is_empty() {
                    scale(row, op.k);
                    continue;
                }
                let [ja, jb] = self.rows[s][i];
                let a = &src[ja * width..(ja + 1) * width];
                let b = &src[jb * width..(jb + 1) * width];
                row_op(row, a, b, op.taps, op.subtract);
            }
        }
    }
}

#[inline]
fn scale(v: &mut [f32], k: f32) {
    if k != 1.0 {
        v.iter_mut().for_each(|x| *x *= k);
    }
}

fn scale_par(v: &mut [f32], k: f32, par: bool) {
    if k == 1.0 {
        return;
    }
    if par {
        v.par_chunks_mut(1 << 14).for_each(|c| scale(c, k));
    } else {
        scale(v, k);
    }
}

/// The lane ranges one axis of a windowed inverse level needs.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct AxisPlan {
    /// Full length of the axis at the finer level.
    pub(crate) n: usize,
    /// Requested output range.
    pub(crate) out: Range<usize>,
    /// Even-lane (low-pass) range.
    pub(crate) even: Range<usize>,
    /// Odd-lane (high-pass) range (empty on an axis of length 1).
    pub(crate) odd: Range<usize>,
}

impl AxisPlan {
    /// The lanes the output range `out` of an axis of length `n` needs, with `margin` samples
    /// of the synthesis filter on each side.
    pub(crate) fn new(n: usize, out: Range<usize>, margin: usize) -> Self {
        let p0 = out.start.saturating_sub(margin) & !1;
        let p1 = (out.end + margin).min(n);
        Self {
            n,
            out,
            even: p0 / 2..p1.div_ceil(2),
            odd: p0 / 2..p1 / 2,
        }
    }
}

/// Deterministic test values in [-500, 500), a stream per `seed`.
#[cfg(test)]
pub(crate) fn test_values(len: usize, seed: u64) -> Vec<f32> {
    use relief_heightfield::rng::{hash, unit_f32};
    (0..len)
        .map(|i| unit_f32(hash(seed, i as u64, 0, 0)) * 1000.0 - 500.0)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wavelet::Wavelet;

    /// The lane segments of a full axis and of windows with the synthesis margin.
    fn segments(n: usize, margin: usize) -> Vec<(usize, usize, usize, usize)> {
        let mut segs = vec![(0, n.div_ceil(2), 0, n / 2)];
        for a in 0..n {
            for b in [a + 1, a + 3, n] {
                if b <= n && b > a {
                    let p = AxisPlan::new(n, a..b, margin);
                    segs.push((p.even.start, p.even.len(), p.odd.start, p.odd.len()));
                }
            }
        }
        segs
    }

    /// The row-pipelined column sweep gives the step-by-step values bit for bit (every row,
    /// margins included), for every basis, both directions and both boundaries, on full lanes
    /// and window segments; and the symmetric boundary always gets the pipelined schedule.
    #[test]
    fn pipelined_columns_equal_stepwise() {
        let mut seed = 1;
        for w in Wavelet::ALL {
            let scheme = w.scheme();
            for lifting in [Lifting::forward(scheme), Lifting::inverse(scheme)] {
                for boundary in [Boundary::Symmetric, Boundary::Periodic] {
                    for n in 2..=24 {
                        if boundary == Boundary::Periodic && n % 2 == 1 {
                            continue;
                        }
                        for (e0, el, o0, ol) in segments(n, w.synthesis_margin()) {
                            let (em, om) = lane_maps(n, boundary, e0, el, o0, ol);
                            let pipe = Pipeline::new(&lifting.ops, &em, &om);
                            if boundary == Boundary::Symmetric {
                                assert!(pipe.is_some(), "{w} n {n} seg {e0} {el} {o0} {ol}");
                            }
                            for width in [1, 3] {
                                seed += 1;
                                let even = test_values(el * width, seed);
                                let odd = test_values(ol * width, seed + 1000);
                                let (mut e1, mut o1) = (even.clone(), odd.clone());
                                let (mut e2, mut o2) = (even, odd);
                                lifting.run_rows(&mut e1, &mut o1, &em, &om, width, false);
                                lifting
                                    .stepwise()
                                    .run_rows(&mut e2, &mut o2, &em, &om, width, true);
                                let bits =
                                    |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                                assert_eq!(bits(&e1), bits(&e2), "{w} {boundary:?} n {n}");
                                assert_eq!(bits(&o1), bits(&o2), "{w} {boundary:?} n {n}");
                            }
                        }
                    }
                }
            }
        }
    }
}
