//! Lifting steps on lane segments, shared by the whole-signal transforms and the windowed
//! (on-demand) synthesis. Every output value is computed by the same sequence of floating-point
//! operations whatever the segment, which is what makes a window bit-identical to the same
//! window of a full run.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::wavelet::{Lane, Scheme, Step};

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
        if taps.len() == 1 {
            let c = taps[0].1;
            if subtract {
                tgt.iter_mut().zip(a).for_each(|(t, a)| *t -= c * a);
            } else {
                tgt.iter_mut().zip(a).for_each(|(t, a)| *t += c * a);
            }
        } else {
            let sb = (f0 + taps[1].0 - smap.seg0) as usize;
            let b = &src[sb..sb + len];
            let (c0, c1) = (taps[0].1, taps[1].1);
            match (c0 == c1, subtract) {
                (true, false) => tgt
                    .iter_mut()
                    .zip(a.iter().zip(b))
                    .for_each(|(t, (a, b))| *t += c0 * (a + b)),
                (true, true) => tgt
                    .iter_mut()
                    .zip(a.iter().zip(b))
                    .for_each(|(t, (a, b))| *t -= c0 * (a + b)),
                (false, false) => tgt
                    .iter_mut()
                    .zip(a.iter().zip(b))
                    .for_each(|(t, (a, b))| *t += c0 * a + c1 * b),
                (false, true) => tgt
                    .iter_mut()
                    .zip(a.iter().zip(b))
                    .for_each(|(t, (a, b))| *t -= c0 * a + c1 * b),
            }
        }
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
        let a = &src[ra..ra + width];
        if taps.len() == 1 {
            let c = taps[0].1;
            if subtract {
                row.iter_mut().zip(a).for_each(|(t, a)| *t -= c * a);
            } else {
                row.iter_mut().zip(a).for_each(|(t, a)| *t += c * a);
            }
        } else {
            let rb = smap.local(i + taps[1].0) * width;
            let b = &src[rb..rb + width];
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

fn step_parts<'a>(
    step: &Step,
    even: &'a mut [f32],
    odd: &'a mut [f32],
    em: &'a LaneMap,
    om: &'a LaneMap,
) -> (&'a mut [f32], isize, &'a [f32], &'a LaneMap) {
    match step.target {
        Lane::Odd => (odd, om.seg0, even, em),
        Lane::Even => (even, em.seg0, odd, om),
    }
}

/// Forward lifting of one 1-D segment pair in place (analysis order, then scaling).
pub(crate) fn forward_1d(
    scheme: &Scheme,
    even: &mut [f32],
    odd: &mut [f32],
    em: &LaneMap,
    om: &LaneMap,
) {
    if odd.is_empty() {
        return;
    }
    for step in scheme.steps {
        let (t, t0, s, sm) = step_parts(step, even, odd, em, om);
        step_1d(t, t0, s, sm, step.taps, false);
    }
    scale(even, scheme.scale_even);
    scale(odd, scheme.scale_odd);
}

/// Inverse lifting of one 1-D segment pair in place (unscaling, then the steps reversed).
pub(crate) fn inverse_1d(
    scheme: &Scheme,
    even: &mut [f32],
    odd: &mut [f32],
    em: &LaneMap,
    om: &LaneMap,
) {
    if odd.is_empty() {
        return;
    }
    scale(even, 1.0 / scheme.scale_even);
    scale(odd, 1.0 / scheme.scale_odd);
    for step in scheme.steps.iter().rev() {
        let (t, t0, s, sm) = step_parts(step, even, odd, em, om);
        step_1d(t, t0, s, sm, step.taps, true);
    }
}

/// Forward lifting along columns of row-lane buffers (each `width` wide) in place.
pub(crate) fn forward_rows(
    scheme: &Scheme,
    even: &mut [f32],
    odd: &mut [f32],
    em: &LaneMap,
    om: &LaneMap,
    width: usize,
    par: bool,
) {
    if odd.is_empty() {
        return;
    }
    for step in scheme.steps {
        let (t, t0, s, sm) = step_parts(step, even, odd, em, om);
        step_rows(t, t0, s, sm, width, step.taps, false, par);
    }
    scale_par(even, scheme.scale_even, par);
    scale_par(odd, scheme.scale_odd, par);
}

/// Inverse lifting along columns of row-lane buffers in place.
pub(crate) fn inverse_rows(
    scheme: &Scheme,
    even: &mut [f32],
    odd: &mut [f32],
    em: &LaneMap,
    om: &LaneMap,
    width: usize,
    par: bool,
) {
    if odd.is_empty() {
        return;
    }
    scale_par(even, 1.0 / scheme.scale_even, par);
    scale_par(odd, 1.0 / scheme.scale_odd, par);
    for step in scheme.steps.iter().rev() {
        let (t, t0, s, sm) = step_parts(step, even, odd, em, om);
        step_rows(t, t0, s, sm, width, step.taps, true, par);
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
