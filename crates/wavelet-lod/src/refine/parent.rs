//! Parent conditioning of the spectral model ([`RefineSettings::parent_conditioning`]): the
//! magnitude of the new coefficients of level `t >= 1` follows the local magnitude of their
//! parents at level `t - 1` (same band), as in hidden-Markov-tree and Portilla-Simoncelli
//! texture models.
//!
//! The unit texture `u_t` of a new level is the coloured noise ([`colour_noise`]) times the
//! parent factor `F_t = c_t m^(kappa / 2)`, bilinearly interpolated at the coefficient, where
//! `m` is the mean of `u_(t-1)^2` over the `3 x 3` parents around a parent position (clipped at
//! the grid edges) and `c_t` makes `F_t` mean square 1. The texture is multiplied by the
//! level's standard deviation and local amplitude as without conditioning, so the variance of
//! equation (5) is kept. Every value is a pure function of its position (the parent region is
//! derived from the child region, sums run in a fixed order), so windows and tiles stay
//! bit-identical to the full run.

use super::*;

/// Radius of the parent window (`3 x 3` parents).
const PARENT_R: usize = 1;

/// Side of the square sample (coefficients of the conditioned level) `c_t` is measured on.
const NORM_SIDE: usize = 256;

/// Offset of the normalisation sample on a virtual grid (`2^30` coefficients per side at the
/// conditioned level) large enough to have no edge near it at any level.
const NORM_OFFSET: usize = 1 << 20;

/// A region of a band grid of a new level: the coefficients `xs x ys` of a grid of `dims`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct BandRegion {
    /// Columns.
    pub(super) xs: Range<usize>,
    /// Rows.
    pub(super) ys: Range<usize>,
    /// Size of the whole band grid (columns, rows).
    pub(super) dims: (usize, usize),
}

/// Bilinear parent coordinate of child coefficient `k`: children `2i` and `2i + 1` lie at
/// `i - 1/4` and `i + 1/4` on the parent grid.
#[inline]
fn parent_coord(k: usize) -> f32 {
    k as f32 * 0.5 - 0.25
}

impl Refiner {
    /// Measures the normalisation of the parent factor of every new level `t >= 1` (in order:
    /// the factor of level `t` reads the texture of level `t - 1`). Does nothing without
    /// parent conditioning.
    pub(super) fn normalise_parents(&mut self) {
        let n = self.settings.extra_levels;
        if self.spectral.is_none() || self.settings.parent_conditioning <= 0.0 {
            return;
        }
        let big = 1usize << 30;
        let range = NORM_OFFSET..NORM_OFFSET + NORM_SIDE;
        let region = BandRegion {
            xs: range.clone(),
            ys: range,
            dims: (big, big),
        };
        for t in 1..n {
            let norms = Band::ALL.map(|b| {
                let f = self.parent_factor(t, b, &region, 1.0);
                let ms = f.iter().map(|&v| v as f64 * v as f64).sum::<f64>() / f.len() as f64;
                if ms > 0.0 && ms.is_finite() {
                    ms.sqrt().recip() as f32
                } else {
                    1.0
                }
            });
            self.parent_norm.push(norms);
        }
    }

    /// The unit texture of new level `t` and `band` over `region` of its band grid: coloured
    /// noise, times the parent factor for `t >= 1` with parent conditioning.
    pub(super) fn texture(&self, t: u32, band: Band, region: &BandRegion) -> Vec<f32> {
        let (cw, ch) = (region.xs.len(), region.ys.len());
        let mut out = vec![0.0f32; cw * ch];
        let Some(plan) = &self.spectral else {
            return out;
        };
        let level = self.global.top_level + t as i64;
        let kern = &plan.kernels[t as usize][band.index()];
        colour_noise(
            self.settings.seed,
            band,
            level,
            region.xs.start,
            region.ys.start,
            cw,
            ch,
            kern,
            &mut out,
        );
        if t == 0 || cw == 0 || ch == 0 || self.settings.parent_conditioning <= 0.0 {
            return out;
        }
        let norm = self
            .parent_norm
            .get(t as usize)
            .map_or(1.0, |n| n[band.index()]);
        let f = self.parent_factor(t, band, region, norm);
        for (o, v) in out.iter_mut().zip(&f) {
            *o *= v;
        }
        out
    }

    /// The parent factor `F_t` (times `norm`) at the coefficients of `region` of new level `t`.
    fn parent_factor(&self, t: u32, band: Band, region: &BandRegion, norm: f32) -> Vec<f32> {
        let (dw, dh) = region.dims;
        let (pw, ph) = (dw.div_ceil(2).max(1), dh.div_ceil(2).max(1));
        let xw: Vec<(usize, usize, f32)> = region
            .xs
            .clone()
            .map(|k| lerp_index(parent_coord(k), pw))
            .collect();
        let yw: Vec<(usize, usize, f32)> = region
            .ys
            .clone()
            .map(|k| lerp_index(parent_coord(k), ph))
            .collect();
        let (Some(fx), Some(fy)) = (span_of(&xw), span_of(&yw)) else {
            return Vec::new();
        };
        // Parents the windows of [fx) x [fy) read.
        let parents = BandRegion {
            xs: fx.0.saturating_sub(PARENT_R)..(fx.1 + PARENT_R).min(pw),
            ys: fy.0.saturating_sub(PARENT_R)..(fy.1 + PARENT_R).min(ph),
            dims: (pw, ph),
        };
        let parent = self.texture(t - 1, band, &parents);
        let (qx, qy, qw) = (parents.xs.start, parents.ys.start, parents.xs.len());
        let kappa = 0.5 * self.settings.parent_conditioning as f32;
        let fw = fx.1 - fx.0;
        let mut f = vec![0.0f32; fw * (fy.1 - fy.0)];
        for (j, row) in f.chunks_mut(fw).enumerate() {
            let py = fy.0 + j;
            let (y0, y1) = (py.saturating_sub(PARENT_R), (py + PARENT_R + 1).min(ph));
            for (i, v) in row.iter_mut().enumerate() {
                let px = fx.0 + i;
                let (x0, x1) = (px.saturating_sub(PARENT_R), (px + PARENT_R + 1).min(pw));
                let mut s = 0.0f32;
                for yy in y0..y1 {
                    let prow = &parent[(yy - qy) * qw..(yy - qy + 1) * qw];
                    for u in &prow[x0 - qx..x1 - qx] {
                        s += u * u;
                    }
                }
                let m = s / ((y1 - y0) * (x1 - x0)) as f32;
                *v = m.powf(kappa) * norm;
            }
        }
        let mut out = Vec::with_capacity(xw.len() * yw.len());
        for &(y0, y1, ty) in &yw {
            let (r0, r1) = (
                &f[(y0 - fy.0) * fw..(y0 - fy.0 + 1) * fw],
                &f[(y1 - fy.0) * fw..(y1 - fy.0 + 1) * fw],
            );
            for &(x0, x1, tx) in &xw {
                let (a0, a1) = (r0[x0 - fx.0], r0[x1 - fx.0]);
                let (b0, b1) = (r1[x0 - fx.0], r1[x1 - fx.0]);
                let a = a0 + tx * (a1 - a0);
                let b = b0 + tx * (b1 - b0);
                out.push(a + ty * (b - a));
            }
        }
        out
    }
}

/// `[first lower index, last upper index + 1)` of a list of bilinear taps (monotone).
fn span_of(taps: &[(usize, usize, f32)]) -> Option<(usize, usize)> {
    let lo = taps.iter().map(|t| t.0).min()?;
    let hi = taps.iter().map(|t| t.1).max()?;
    Some((lo, hi + 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Correlation of the child energy (mean of `u_1^2` over the 2 x 2 children) with the
    /// parent energy (mean of `u_0^2` over the 3 x 3 parents around), and the mean square of `u_1`, on the band grid of a 64 x 64 input.
    fn child_parent(kappa: f64) -> (f64, f64) {
        let hf = Heightfield::from_fn(64, 64, 30.0, 30.0, |x, y| {
            (x as f32 * 0.37).sin() * 40.0 + (y as f32 * 0.21).cos() * 25.0 + (x * y) as f32 * 0.01
        });
        let s = RefineSettings {
            method: Method::Gsa,
            extra_levels: 2,
            seed: 3,
            parent_conditioning: kappa,
            ..Default::default()
        };
        let r = Refiner::new(&hf, &s).unwrap();
        let n = 64usize;
        let (mut sp, mut sc, mut spp, mut scc, mut spc, mut ms) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        let mut count = 0.0;
        for band in Band::ALL {
            let square = |side: usize| BandRegion {
                xs: 0..side,
                ys: 0..side,
                dims: (side, side),
            };
            let parent = r.texture(0, band, &square(n));
            let child = r.texture(1, band, &square(2 * n));
            ms += child.iter().map(|&v| (v * v) as f64).sum::<f64>();
            for y in 1..n - 1 {
                for x in 1..n - 1 {
                    // The parent energy over the 3 x 3 parents the factor reads.
                    let p = (0..9)
                        .map(|k| (parent[(y + k / 3 - 1) * n + x + k % 3 - 1] as f64).powi(2))
                        .sum::<f64>()
                        / 9.0;
                    let c = [(0, 0), (1, 0), (0, 1), (1, 1)]
                        .iter()
                        .map(|(dx, dy)| (child[(2 * y + dy) * 2 * n + 2 * x + dx] as f64).powi(2))
                        .sum::<f64>()
                        / 4.0;
                    sp += p;
                    sc += c;
                    spp += p * p;
                    scc += c * c;
                    spc += p * c;
                    count += 1.0;
                }
            }
        }
        let (mp, mc) = (sp / count, sc / count);
        let cov = spc / count - mp * mc;
        let corr = cov / ((spp / count - mp * mp) * (scc / count - mc * mc)).sqrt();
        (corr, ms / (3.0 * (4 * n * n) as f64))
    }

    #[test]
    fn parent_conditioning_correlates_child_and_parent_energy_and_keeps_the_variance() {
        let (free, ms_free) = child_parent(0.0);
        let (tied, ms_tied) = child_parent(1.0);
        // With kappa = 2 the raw factor m has mean square E[m^2] > 1: only the measured
        // normalisation brings the variance back.
        let (_, ms_strong) = child_parent(2.0);
        assert!(free.abs() < 0.08, "independent levels: correlation {free}");
        assert!(tied > 0.3, "conditioned levels: correlation {tied}");
        // Unit mean square in both cases (the normalisation is measured on another region).
        for ms in [ms_free, ms_tied, ms_strong] {
            assert!((ms - 1.0).abs() < 0.06, "mean square {ms}");
        }
    }
}
