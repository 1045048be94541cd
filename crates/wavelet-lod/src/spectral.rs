//! The spectral synthesis model ([`crate::Model::Spectral`], the default; a departure from the
//! paper): coloured new coefficients whose output spectrum continues the fitted power law, and
//! a cubic smooth part that makes the refinement area-consistent (pixel-is-area).
//!
//! * **Target.** With the metric normalisation the detail variance of level `j` decays as
//!   `2^(-j gamma)`; for a surface whose radially averaged power spectrum is `P(k) ~ k^beta`
//!   that is `beta = -(gamma + 2)` (an octave annulus holds `k^(beta + 2)` of power). `gamma`
//!   is fitted on the finest observed levels only ([`crate::RefineSettings::fine_levels`]), so
//!   the new octaves continue the spectrum where it is closest to them.
//! * **Colour.** Independent coefficients give every new octave a flat-to-rising spectrum inside
//!   the octave (the synthesis high-pass peaks at the Nyquist frequency), whatever their
//!   variance: the added octaves then come out far too rough. Each new level and band therefore
//!   draws white numbers and filters them with a small 2-D kernel (`5 x 5`) designed in the
//!   frequency domain: for the coefficient frequency `nu`, the primary output frequency
//!   `omega(nu)` of the band (inverted on a high-pass axis) gets the power
//!   `|omega|^beta / |response(omega)|^2`, where `response` is the product of the basis'
//!   synthesis filters the coefficient passes through. The kernel is normalised to unit gain in
//!   variance, so the coefficient variance still follows the fitted line (equation (5)).
//! * **Area consistency.** An input cell is the mean of a `2^n x 2^n` block of the output
//!   (pixel-is-area). The smooth part is the Keys bicubic up-sampling (cell-centre aligned) of
//!   the coarse grid `q * (input - box-down(D))`, where `D` is the synthetic detail and `q` a
//!   17-tap separable filter, the least-squares inverse of `box-down(cubic(.))` (a 5-tap
//!   symmetric filter whose response stays above 0.6 at the coarse Nyquist frequency, so the
//!   inverse is short and well conditioned). Hence `box-down(output) = input`.

use crate::dwt::{Band, idwt1};
use crate::lift::Boundary;
use crate::wavelet::Wavelet;

/// Radius of the colouring kernels (`2 R + 1` taps per side).
pub(crate) const KR: usize = 2;
/// Side of the colouring kernels.
pub(crate) const KS: usize = 2 * KR + 1;

/// The 1-D synthesis filters `(low, high)` of a basis in the metric normalisation: the response
/// of one inverse level to a unit approximation (resp. detail) sample.
fn synthesis_filters(wavelet: Wavelet) -> (Vec<f64>, Vec<f64>) {
    const N: usize = 32;
    let mut delta = vec![0.0f32; N];
    delta[N / 2] = 1.0;
    let zero = vec![0.0f32; N];
    // Lengths match (N low, N high samples), so the inverse cannot fail.
    let lo = idwt1(&delta, &zero, wavelet, Boundary::Symmetric).unwrap_or_default();
    let hi = idwt1(&zero, &delta, wavelet, Boundary::Symmetric).unwrap_or_default();
    (
        lo.iter().map(|&v| v as f64).collect(),
        hi.iter().map(|&v| v as f64).collect(),
    )
}

/// `|sum_k h[k] e^(-i w k)|`.
fn magnitude(h: &[f64], w: f64) -> f64 {
    let (mut re, mut im) = (0.0, 0.0);
    for (k, &v) in h.iter().enumerate() {
        let p = w * k as f64;
        re += v * p.cos();
        im -= v * p.sin();
    }
    re.hypot(im)
}

/// Colouring kernels and the smooth part of one refinement.
#[derive(Debug, Clone)]
pub(crate) struct SpectralPlan {
    /// Per new level (coarsest first), per band: a `KS x KS` row-major kernel.
    pub(crate) kernels: Vec<[[f32; KS * KS]; 3]>,
    /// The smooth part: cubic up-sampling with its box-consistency inverse.
    pub(crate) cubic: CubicUp,
}

impl SpectralPlan {
    /// Designs the plan for `levels` new levels with spectral exponents `beta` per band.
    pub(crate) fn new(wavelet: Wavelet, levels: u32, beta: [f64; 3]) -> Self {
        let (g0, g1) = synthesis_filters(wavelet);
        let kernels = (0..levels)
            .map(|t| {
                let m = levels - t;
                Band::ALL.map(|b| design_kernel(&g0, &g1, m, b, beta[b.index()]))
            })
            .collect();
        Self {
            kernels,
            cubic: CubicUp::new(levels),
        }
    }
}

/// Output response of one axis of a coefficient `m` levels above the output: the high-pass (or
/// low-pass) synthesis filter at spacing `2^(m-1)`, then the low-pass at every finer spacing.
fn axis_response(g0: &[f64], g1: &[f64], m: u32, high: bool, w: f64) -> f64 {
    let first = if high { g1 } else { g0 };
    let mut r = magnitude(first, w * (1u64 << (m - 1)) as f64);
    for s in 0..m - 1 {
        r *= magnitude(g0, w * (1u64 << s) as f64);
    }
    r
}

/// The colouring kernel of a band `m` levels above the output for the spectral exponent `beta`.
fn design_kernel(g0: &[f64], g1: &[f64], m: u32, band: Band, beta: f64) -> [f32; KS * KS] {
    use std::f64::consts::PI;
    const N: usize = 32;
    let (high_x, high_y) = match band {
        Band::H => (false, true),
        Band::V => (true, false),
        Band::D => (true, true),
    };
    let scale = (1u64 << m) as f64;
    let omega = |nu: f64, high: bool| {
        if high {
            (2.0 * PI - nu.abs()) / scale
        } else {
            nu.abs() / scale
        }
    };
    let nus: Vec<f64> = (0..N)
        .map(|k| 2.0 * PI * (k as f64 - (N / 2) as f64) / N as f64)
        .collect();
    let rx: Vec<f64> = nus
        .iter()
        .map(|&n| axis_response(g0, g1, m, high_x, omega(n, high_x)))
        .collect();
    let ry: Vec<f64> = nus
        .iter()
        .map(|&n| axis_response(g0, g1, m, high_y, omega(n, high_y)))
        .collect();
    let max_r2 =
        rx.iter().fold(0.0f64, |a, v| a.max(v * v)) * ry.iter().fold(0.0f64, |a, v| a.max(v * v));
    // A response far below its peak would ask for huge gains at the band edges, where the
    // neighbouring band provides the power anyway.
    let floor = 1e-2 * max_r2.max(1e-300);
    let mut amp = vec![0.0f64; N * N];
    for (iy, &ny) in nus.iter().enumerate() {
        for (ix, &nx) in nus.iter().enumerate() {
            let (wx, wy) = (omega(nx, high_x), omega(ny, high_y));
            let k2 = (wx * wx + wy * wy).max(1e-12);
            let target = k2.powf(0.5 * beta);
            let r2 = (rx[ix] * ry[iy]).powi(2).max(floor);
            amp[iy * N + ix] = (target / r2).sqrt();
        }
    }
    // Zero-phase kernel: inverse DFT of the (even) amplitude, truncated to KS x KS.
    let mut kern = [0.0f64; KS * KS];
    for q in 0..KS {
        for p in 0..KS {
            let (dp, dq) = (p as f64 - KR as f64, q as f64 - KR as f64);
            let mut s = 0.0;
            for (iy, &ny) in nus.iter().enumerate() {
                for (ix, &nx) in nus.iter().enumerate() {
                    s += amp[iy * N + ix] * (nx * dp + ny * dq).cos();
                }
            }
            kern[q * KS + p] = s;
        }
    }
    let norm = kern.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut out = [0.0f32; KS * KS];
    if norm > 0.0 && norm.is_finite() {
        for (o, k) in out.iter_mut().zip(&kern) {
            *o = (k / norm) as f32;
        }
    } else {
        out[KR * KS + KR] = 1.0;
    }
    out
}

/// Cubic up-sampling by `2^levels` (Keys, `a = -0.5`, cell-centre aligned as
/// [`relief_heightfield::Heightfield::resample`]) and its box-consistency inverse: the smooth
/// part of the spectral model (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct CubicUp {
    /// Up-sampling factor `f = 2^levels`.
    pub(crate) factor: usize,
    /// Per output phase `r` in `0..f`: the offset of the first of the four coarse taps from the
    /// block index, and the weights.
    pub(crate) phases: Vec<(isize, [f32; 4])>,
    /// Coarse-grid pre-filter `q[-QL..=QL]` with `box-down(cubic(q * c)) = c` (1-D, applied
    /// separably).
    pub(crate) inverse: Vec<f32>,
}

/// Half-length of the box-consistency inverse filter (its taps decay by about 5x per tap, so
/// the truncated tail is about 1e-6 of the centre tap; the unit test bounds the resulting
/// block-mean error).
pub(crate) const QL: usize = 8;

impl CubicUp {
    pub(crate) fn new(levels: u32) -> Self {
        let f = 1usize << levels;
        let phases: Vec<(isize, [f32; 4])> = (0..f)
            .map(|r| {
                let c = (r as f64 + 0.5) / f as f64 - 0.5;
                let fl = c.floor();
                (
                    fl as isize - 1,
                    relief_heightfield::cubic_weights((c - fl) as f32),
                )
            })
            .collect();
        // 1-D response of box-down(cubic(.)) to a coarse unit sample: a[m], m in -2..=2.
        let mut a = [0.0f64; 5];
        for (off, w) in &phases {
            for (k, &wk) in w.iter().enumerate() {
                let m = off + k as isize;
                a[(m + 2) as usize] += wk as f64 / f as f64;
            }
        }
        Self {
            factor: f,
            phases,
            inverse: design_inverse(&a),
        }
    }

    /// Range of coarse indices `[lo, hi)` (whole-sample symmetric reflection into `[0, n)`)
    /// that output positions `[o0, o1)` read.
    pub(crate) fn coarse_range(&self, o0: usize, o1: usize, n: usize) -> (usize, usize) {
        let f = self.factor;
        let (mut lo, mut hi) = (usize::MAX, 0usize);
        for o in o0..o1 {
            let (off, _) = self.phases[o % f];
            let base = (o / f) as isize + off;
            for i in base..base + 4 {
                let r = reflect(i, n);
                lo = lo.min(r);
                hi = hi.max(r + 1);
            }
        }
        (lo.min(hi), hi)
    }
}

/// Whole-sample symmetric reflection of index `i` into `[0, n)`.
#[inline]
pub(crate) fn reflect(i: isize, n: usize) -> usize {
    if n <= 1 {
        return 0;
    }
    let period = 2 * (n as isize - 1);
    let mut i = i.rem_euclid(period);
    if i >= n as isize {
        i = period - i;
    }
    i as usize
}

/// Least-squares inverse `q[-QL..=QL]` of the symmetric 5-tap filter `a[-2..=2]`:
/// `(a * q)[d] = delta[d]` for every `d` the product reaches, with a tiny ridge.
fn design_inverse(a: &[f64; 5]) -> Vec<f32> {
    let np = 2 * QL + 1;
    let nd = np + 4;
    let mut ata = vec![0.0f64; np * np];
    let mut atb = vec![0.0f64; np];
    for d in 0..nd {
        let row: Vec<f64> = (0..np)
            .map(|j| {
                let i = d as isize - j as isize;
                if (0..5).contains(&i) {
                    a[i as usize]
                } else {
                    0.0
                }
            })
            .collect();
        let b = if d == QL + 2 { 1.0 } else { 0.0 };
        for r in 0..np {
            atb[r] += row[r] * b;
            for c in 0..np {
                ata[r * np + c] += row[r] * row[c];
            }
        }
    }
    for r in 0..np {
        ata[r * np + r] += 1e-9;
    }
    let q = solve(&mut ata, &mut atb, np);
    let sum: f64 = q.iter().sum();
    let sum = if sum.abs() > 1e-6 { sum } else { 1.0 };
    q.iter().map(|&v| (v / sum) as f32).collect()
}

/// Gaussian elimination with partial pivoting of a small dense system (positive definite here).
fn solve(a: &mut [f64], b: &mut [f64], n: usize) -> Vec<f64> {
    for c in 0..n {
        let piv = (c..n)
            .max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))
            .unwrap_or(c);
        if piv != c {
            for k in 0..n {
                a.swap(c * n + k, piv * n + k);
            }
            b.swap(c, piv);
        }
        let d = a[c * n + c];
        if d.abs() < 1e-300 {
            continue;
        }
        for r in c + 1..n {
            let f = a[r * n + c] / d;
            for k in c..n {
                a[r * n + k] -= f * a[c * n + k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0f64; n];
    for c in (0..n).rev() {
        let s: f64 = (c + 1..n).map(|k| a[c * n + k] * x[k]).sum();
        let d = a[c * n + c];
        x[c] = if d.abs() < 1e-300 {
            0.0
        } else {
            (b[c] - s) / d
        };
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubic_inverse_makes_box_down_of_the_cubic_up_sampling_the_identity() {
        for levels in 1..=5u32 {
            let up = CubicUp::new(levels);
            let f = up.factor;
            // A random-ish coarse signal, symmetric extension; box-down(cubic(q * c)) = c.
            let n = 40usize;
            let c: Vec<f64> = (0..n).map(|i| ((i * 7919) % 23) as f64 - 11.0).collect();
            let ql = QL as isize;
            let g: Vec<f64> = (0..n as isize)
                .map(|i| {
                    (-ql..=ql)
                        .map(|k| up.inverse[(k + ql) as usize] as f64 * c[reflect(i + k, n)])
                        .sum()
                })
                .collect();
            for (i, &ci) in c.iter().enumerate() {
                let mut s = 0.0;
                for r in 0..f {
                    let (off, w) = up.phases[r];
                    for (k, wk) in w.iter().enumerate() {
                        s += *wk as f64 * g[reflect(i as isize + off + k as isize, n)];
                    }
                }
                let err = (s / f as f64 - ci).abs();
                assert!(err < 1e-4, "levels {levels}, cell {i}: {err}");
            }
            let dc: f32 = up.inverse.iter().sum();
            assert!((dc - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn kernels_are_unit_variance_and_blue_along_high_pass_axes() {
        let (g0, g1) = synthesis_filters(Wavelet::Cdf97);
        let k = design_kernel(&g0, &g1, 1, Band::H, -5.0);
        let e: f32 = k.iter().map(|v| v * v).sum();
        assert!((e - 1.0).abs() < 1e-4);
        // Along y (high-pass) neighbours are anti-correlated: more power at high coefficient
        // frequencies, i.e. at the low end of the output octave.
        let centre = k[KR * KS + KR];
        let up = k[(KR - 1) * KS + KR];
        assert!(centre > 0.0 && up < 0.0, "centre {centre}, up {up}");
    }
}
