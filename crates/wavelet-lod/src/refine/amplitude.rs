//! The spectral model's local amplitude maps and coloured coefficient noise.

use super::*;

/// Bilinear interpolation indices `(i0, i1, fraction)` of coordinate `u` on an axis of `n`
/// samples (clamped at the ends).
#[inline]
pub(super) fn lerp_index(u: f32, n: usize) -> (usize, usize, f32) {
    if n <= 1 || u <= 0.0 {
        return (0, 0, 0.0);
    }
    let last = (n - 1) as f32;
    if u >= last {
        return (n - 1, n - 1, 0.0);
    }
    let i = u as usize;
    (i, i + 1, u - i as f32)
}

/// Side of the broad amplitude window, in statistics windows
/// ([`RefineSettings::amplitude_persistence`]).
pub(super) const BROAD_WINDOW: usize = 5;

/// `m^keep M^(1 - keep)` per cell, renormalised to mean square 1 (a geometric blend, so an
/// exactly flat cell, `m = 0`, stays 0).
pub(super) fn blend_amplitude(narrow: &Grid, wide: &Grid, keep: f64) -> Grid {
    let data: Vec<f64> = narrow
        .data
        .iter()
        .zip(&wide.data)
        .map(|(&m, &w)| (m as f64).powf(keep) * (w as f64).powf(1.0 - keep))
        .collect();
    let ms = data.iter().map(|v| v * v).sum::<f64>() / data.len().max(1) as f64;
    let norm = if ms > 0.0 { ms.sqrt().recip() } else { 1.0 };
    Grid {
        width: narrow.width,
        height: narrow.height,
        data: data.iter().map(|v| (v * norm) as f32).collect(),
    }
}

/// The local amplitude factors of the spectral model with LSA, per band: the square root of the
/// windowed mean square of the finest observed detail level over its mean (so the factor has
/// mean square 1 and the total variance of equation (5) is kept: this normalisation also removes
/// the bias a logarithmic average of local variances would have). Flat areas get a factor near 0,
/// rough ones above 1. `None` when the input has no detail level.
pub(super) fn amplitude_maps(
    dec: &crate::dwt::Decomposition,
    window: usize,
    floor: f64,
    power: f64,
) -> Option<[Grid; 3]> {
    let finest = dec.details.last()?;
    if Band::ALL.iter().any(|&b| finest.band(b).is_empty()) {
        return None;
    }
    Some(Band::ALL.map(|b| {
        // The last coefficient of a high-pass lane of even length sees the mirrored boundary
        // (a first rather than a second difference on a slope): it is replaced by its
        // neighbour so that the border does not get a spuriously large amplitude.
        let mut band = finest.band(b).clone();
        let (w, h) = (band.width, band.height);
        if w >= 2 {
            for r in 0..h {
                band.data[r * w + w - 1] = band.data[r * w + w - 2];
            }
        }
        if h >= 2 {
            let (head, tail) = band.data.split_at_mut((h - 1) * w);
            tail[..w].copy_from_slice(&head[(h - 2) * w..]);
        }
        let g = crate::analysis::windowed_log_variance(&band, window, floor);
        let lin: Vec<f64> = g.data.iter().map(|&v| (power * v as f64).exp2()).collect();
        let mean = lin.iter().sum::<f64>() / lin.len() as f64;
        let mean = if mean > 0.0 { mean } else { 1.0 };
        Grid {
            width: g.width,
            height: g.height,
            data: lin.iter().map(|v| (v / mean).sqrt() as f32).collect(),
        }
    }))
}

/// Coloured coefficients of the spectral model for the band region `[x0, x0 + w) x
/// [y0, y0 + h)`: white numbers of the coefficient hash (the same stream as the paper model)
/// filtered by the `KS x KS` kernel. Every value depends only on its position, never on the
/// region, so windows and tiles agree bit for bit.
#[allow(clippy::too_many_arguments)]
pub(super) fn colour_noise(
    seed: u64,
    band: Band,
    level: i64,
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
    kern: &[f32; KS * KS],
    out: &mut [f32],
) {
    if w == 0 || h == 0 {
        return;
    }
    let ew = w + 2 * KR;
    let mut white = vec![0.0f32; ew * (h + 2 * KR)];
    for (r, row) in white.chunks_mut(ew).enumerate() {
        let gy = (y0 + r).wrapping_sub(KR);
        fill_normals(
            row_key(seed, band.index(), level, gy),
            x0.wrapping_sub(KR),
            row,
        );
    }
    for (r, orow) in out.chunks_mut(w).enumerate().take(h) {
        orow.iter_mut().for_each(|v| *v = 0.0);
        for q in 0..KS {
            let src = &white[(r + q) * ew..(r + q + 1) * ew];
            let taps = &kern[q * KS..(q + 1) * KS];
            for (k, v) in orow.iter_mut().enumerate() {
                let win = &src[k..k + KS];
                let mut acc = 0.0f32;
                for (a, b) in taps.iter().zip(win) {
                    acc += a * b;
                }
                *v += acc;
            }
        }
    }
}
