//! The x4 kernels of a step: Keys bicubic up-sampling, the detail gain of a primitive
//! lattice, the box x4 reduction and the back-projection through an interpolation kernel.

use super::*;
use relief_heightfield::Kernel;

// Keys cubic (Catmull-Rom) weights of the four taps around a fractional offset `t`.
use relief_heightfield::cubic_weights_f64 as keys;

/// x4 bicubic up-sampling of an `a x a` patch to `4a x 4a` (pixel-centre alignment, edges
/// clamped): the same interpolation as a layer of `a x a` atoms at spacing 4.
pub(crate) fn upsample4(p: &[f64], a: usize) -> Vec<f64> {
    let ah = STEP_FACTOR * a;
    let taps: Vec<([usize; 4], [f64; 4])> = (0..ah)
        .map(|o| {
            let u = (o as f64 + 0.5) / STEP_FACTOR as f64 - 0.5;
            let f = u.floor();
            let base = f as i64 - 1;
            let idx = [0, 1, 2, 3].map(|k| (base + k).clamp(0, a as i64 - 1) as usize);
            (idx, keys(u - f))
        })
        .collect();
    let mut rows = vec![0.0; a * ah];
    for r in 0..a {
        for (o, (idx, w)) in taps.iter().enumerate() {
            rows[r * ah + o] = (0..4).map(|k| w[k] * p[r * a + idx[k]]).sum();
        }
    }
    let mut out = vec![0.0; ah * ah];
    for (o, (idx, w)) in taps.iter().enumerate() {
        for c in 0..ah {
            out[o * ah + c] = (0..4).map(|k| w[k] * rows[idx[k] * ah + c]).sum();
        }
    }
    out
}

/// Detail gain `1 / sqrt(V(u))` at the samples of an `ah x ah` fine patch (offsets
/// `u = index - (ah - 1) / 2` from its centre), where `V(u) = sum a_k^2 / (sum a_k)^2` over
/// the primitives of a lattice of step `step` through the centre, with weights
/// `a_k = g(|u - k step| / radius)` of the sparse layer (see
/// [`AmplifySettings::normalize_detail`]). `V` is periodic, so the gain is the same for every
/// primitive of the lattice.
pub fn detail_gain(ah: usize, step: f64, radius: f64) -> Vec<f64> {
    let h = (ah as f64 - 1.0) / 2.0;
    let ks = |u: f64| {
        let lo = ((u - radius) / step).ceil() as i64;
        let hi = ((u + radius) / step).floor() as i64;
        lo..=hi
    };
    let mut out = vec![1.0; ah * ah];
    for r in 0..ah {
        let uy = r as f64 - h;
        for c in 0..ah {
            let ux = c as f64 - h;
            let (mut s1, mut s2) = (0.0f64, 0.0f64);
            for ky in ks(uy) {
                let dy = uy - ky as f64 * step;
                for kx in ks(ux) {
                    let dx = ux - kx as f64 * step;
                    let r2 = (dx * dx + dy * dy) / (radius * radius);
                    if r2 < 1.0 {
                        let w = (1.0 - r2).powi(3);
                        s1 += w;
                        s2 += w * w;
                    }
                }
            }
            if s1 > 0.0 && s2 > 0.0 {
                // V <= 1 always; the cap only guards sparse grids (S close to R sqrt 2).
                out[r * ah + c] = (s1 / s2.sqrt()).min(8.0);
            }
        }
    }
    out
}

/// Box x4 reduction of a `4a x 4a` patch to `a x a`.
pub(super) fn box_down4(p: &[f32], a: usize) -> Vec<f64> {
    let ah = STEP_FACTOR * a;
    let mut out = vec![0.0f64; a * a];
    for (r, row) in p.chunks_exact(ah).enumerate() {
        for (c, &v) in row.iter().enumerate() {
            out[(r / STEP_FACTOR) * a + c / STEP_FACTOR] += v as f64;
        }
    }
    let inv = 1.0 / (STEP_FACTOR * STEP_FACTOR) as f64;
    out.iter_mut().for_each(|v| *v *= inv);
    out
}

/// Taps of `box-down4(interp-up4(line))` for a line of `n` samples (the 1-D factor of the
/// separable operator, `kernel` the interpolation): for each output, the (clamped) input
/// indices and weights.
fn box_of_interp_taps(n: usize, kernel: Kernel) -> Vec<Vec<(usize, f64)>> {
    (0..n)
        .map(|i| {
            let mut taps: Vec<(usize, f64)> = Vec::with_capacity(8);
            for j in 0..STEP_FACTOR {
                let u = i as f64
                    + (2.0 * j as f64 + 1.0 - STEP_FACTOR as f64) / (2.0 * STEP_FACTOR as f64);
                let (b, t) = kernel.position(u);
                let w = kernel.weights(t);
                for (k, wk) in w.iter().enumerate().take(kernel.taps()) {
                    let idx = (b + k as i64).clamp(0, n as i64 - 1) as usize;
                    let wk = wk / STEP_FACTOR as f64;
                    match taps.iter_mut().find(|t| t.0 == idx) {
                        Some(t) => t.1 += wk,
                        None => taps.push((idx, wk)),
                    }
                }
            }
            taps
        })
        .collect()
}

/// Back-projection iterations of [`back_project`].
const BACK_PROJECTION_ITERATIONS: usize = 4;

/// Approximately solves `box-down4(interp-up4(r)) = d` on the coarse grid (`w x h`,
/// row-major; `kernel` the interpolation) by fixed-point iterations `r += d - BU(r)` from
/// `r = d`: the interpolation of `r` then reduces (box average of the 4 x 4 fine cells) to
/// `d`, so the output's box reduction matches the input closely instead of a low-passed copy
/// of it.
pub(super) fn back_project(d: &[f64], w: usize, h: usize, kernel: Kernel) -> Vec<f64> {
    use rayon::prelude::*;
    let (tx, ty) = (box_of_interp_taps(w, kernel), box_of_interp_taps(h, kernel));
    let mut r = d.to_vec();
    let mut tmp = vec![0.0; w * h];
    for _ in 0..BACK_PROJECTION_ITERATIONS {
        tmp.par_chunks_mut(w)
            .zip(r.par_chunks(w))
            .for_each(|(dst, src)| {
                for (o, taps) in dst.iter_mut().zip(&tx) {
                    *o = taps.iter().map(|&(i, wt)| wt * src[i]).sum();
                }
            });
        r.par_chunks_mut(w)
            .zip(d.par_chunks(w))
            .enumerate()
            .for_each(|(y, (row, drow))| {
                for (x, (o, dv)) in row.iter_mut().zip(drow).enumerate() {
                    let bu: f64 = ty[y].iter().map(|&(i, wt)| wt * tmp[i * w + x]).sum();
                    *o += dv - bu;
                }
            });
    }
    r
}
