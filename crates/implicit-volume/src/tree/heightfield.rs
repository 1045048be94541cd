//! The heightfield primitive (the implicitised DEM: its field, analytic gradient, bounds) and
//! the DEM frame that places it in the scene.

use super::*;

impl HfPrim {
    #[inline]
    pub(super) fn height(&self, x: f32, y: f32) -> f32 {
        let u = (x / self.cx).clamp(0.0, (self.w - 1) as f32);
        let v = ((self.h - 1) as f32 - y / self.cy).clamp(0.0, (self.h - 1) as f32);
        let (j0, i0) = (u.floor() as usize, v.floor() as usize);
        let (j1, i1) = ((j0 + 1).min(self.w - 1), (i0 + 1).min(self.h - 1));
        let (tx, ty) = (u - j0 as f32, v - i0 as f32);
        let d = &self.data;
        let a = d[i0 * self.w + j0] * (1.0 - tx) + d[i0 * self.w + j1] * tx;
        let b = d[i1 * self.w + j0] * (1.0 - tx) + d[i1 * self.w + j1] * tx;
        a * (1.0 - ty) + b * ty
    }
    pub(super) fn extent(&self) -> (f32, f32) {
        ((self.w - 1) as f32 * self.cx, (self.h - 1) as f32 * self.cy)
    }
    #[inline]
    pub(super) fn field(&self, p: V3) -> f32 {
        let (xm, ym) = self.extent();
        let db = p[0]
            .min(xm - p[0])
            .min(p[1])
            .min(ym - p[1])
            .min(p[2] - self.z_bottom);
        let dt = self.height(p[0], p[1]) - p[2];
        THRESHOLD + THRESHOLD * cubic_step(dt.min(db) / self.r)
    }
    /// Slopes `(dH/du, dH/dv)` per grid unit at node `(j, i)` by central differences (one-sided
    /// at the grid's edges).
    #[inline]
    fn node_slopes(&self, j: usize, i: usize) -> (f32, f32) {
        let d = &self.data;
        let (jm, jp) = (j.saturating_sub(1), (j + 1).min(self.w - 1));
        let (im, ip) = (i.saturating_sub(1), (i + 1).min(self.h - 1));
        let su = if jp > jm {
            (d[i * self.w + jp] - d[i * self.w + jm]) / (jp - jm) as f32
        } else {
            0.0
        };
        let sv = if ip > im {
            (d[ip * self.w + j] - d[im * self.w + j]) / (ip - im) as f32
        } else {
            0.0
        };
        (su, sv)
    }

    /// Field and analytic gradient (the gradient of the active branch of the `min`, and of
    /// the bilinear patch of `H`), or with `smooth` the shading gradient: the same field value, and
    /// where the DEM surface is the active branch, the bilinear interpolation of the nodes'
    /// central-difference slopes in place of the bilinear patch's own (piecewise-constant
    /// across cells) slopes. The geometry is unchanged; normals become continuous across
    /// cell edges, so renders and mesh normals show the relief instead of one facet per cell.
    #[inline]
    pub(super) fn field_grad_with(&self, p: V3, smooth: bool) -> (f32, V3) {
        let (xm, ym) = self.extent();
        let cands = [
            (p[0], [1.0, 0.0, 0.0]),
            (xm - p[0], [-1.0, 0.0, 0.0]),
            (p[1], [0.0, 1.0, 0.0]),
            (ym - p[1], [0.0, -1.0, 0.0]),
            (p[2] - self.z_bottom, [0.0, 0.0, 1.0]),
        ];
        let mut m = cands[0];
        for c in &cands[1..] {
            if c.0 < m.0 {
                m = *c;
            }
        }
        // Bilinear height and its derivatives.
        let u = (p[0] / self.cx).clamp(0.0, (self.w - 1) as f32);
        let v = ((self.h - 1) as f32 - p[1] / self.cy).clamp(0.0, (self.h - 1) as f32);
        let (j0, i0) = (u.floor() as usize, v.floor() as usize);
        let (j1, i1) = ((j0 + 1).min(self.w - 1), (i0 + 1).min(self.h - 1));
        let (tx, ty) = (u - j0 as f32, v - i0 as f32);
        let d = &self.data;
        let (z00, z01) = (d[i0 * self.w + j0], d[i0 * self.w + j1]);
        let (z10, z11) = (d[i1 * self.w + j0], d[i1 * self.w + j1]);
        let a = z00 * (1.0 - tx) + z01 * tx;
        let b = z10 * (1.0 - tx) + z11 * tx;
        let hgt = a * (1.0 - ty) + b * ty;
        let dt = hgt - p[2];
        let (val, g) = if dt <= m.0 {
            let inside_x = p[0] > 0.0 && p[0] < xm;
            let inside_y = p[1] > 0.0 && p[1] < ym;
            let (dhdu, dhdv) = if smooth {
                let lerp = |p: (f32, f32), q: (f32, f32), t: f32| {
                    (p.0 + (q.0 - p.0) * t, p.1 + (q.1 - p.1) * t)
                };
                let top = lerp(self.node_slopes(j0, i0), self.node_slopes(j1, i0), tx);
                let bottom = lerp(self.node_slopes(j0, i1), self.node_slopes(j1, i1), tx);
                let (su, sv) = lerp(top, bottom, ty);
                // v grows southwards, y northwards.
                (su / self.cx, -sv / self.cy)
            } else {
                (
                    ((z01 - z00) * (1.0 - ty) + (z11 - z10) * ty) / self.cx,
                    -(b - a) / self.cy,
                )
            };
            (
                dt,
                [
                    if inside_x { dhdu } else { 0.0 },
                    if inside_y { dhdv } else { 0.0 },
                    -1.0,
                ],
            )
        } else {
            m
        };
        let x = val / self.r;
        let ds = if x.abs() < 1.0 {
            1.5 * (1.0 - x * x) / self.r
        } else {
            0.0
        };
        (
            THRESHOLD + THRESHOLD * cubic_step(x),
            mul(g, THRESHOLD * ds),
        )
    }

    /// Range of the DEM nodes under the box `b` (the bilinear surface stays within it), or of
    /// a few more: read from the pyramid level where the box spans at most four blocks a
    /// side, so a query costs at most 16 block reads whatever the box's size.
    pub(super) fn height_range(&self, b: &Aabb) -> (f32, f32) {
        let u0 = ((b.min[0] / self.cx).floor().max(0.0) as usize).min(self.w - 1);
        let u1 = ((b.max[0] / self.cx).ceil().max(0.0) as usize).min(self.w - 1);
        let top = (self.h - 1) as f32;
        let v0 = ((top - b.max[1] / self.cy).floor().max(0.0) as usize).min(self.h - 1);
        let v1 = ((top - b.min[1] / self.cy).ceil().max(0.0) as usize).min(self.h - 1);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let mut k = 0;
        while k < self.mip.len() && ((u1 >> k) - (u0 >> k) > 3 || (v1 >> k) - (v0 >> k) > 3) {
            k += 1;
        }
        if k == 0 {
            for i in v0..=v1 {
                for &z in &self.data[i * self.w + u0..=i * self.w + u1] {
                    lo = lo.min(z);
                    hi = hi.max(z);
                }
            }
            return (lo, hi);
        }
        let m = &self.mip[k - 1];
        for i in (v0 >> k)..=(v1 >> k).min(m.h - 1) {
            for &(a, b) in &m.range[i * m.w + (u0 >> k)..=i * m.w + (u1 >> k).min(m.w - 1)] {
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        (lo, hi)
    }
    /// This primitive with its min/max pyramid built: level `k` (1-based, `mip[k - 1]`) holds
    /// the range of each `2^k x 2^k` block of nodes, down to a single block.
    pub(super) fn with_mip(mut self) -> Self {
        let mut levels: Vec<MipLevel> = Vec::new();
        let (mut w, mut h) = (self.w, self.h);
        while w > 1 || h > 1 {
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let at = |i: usize, j: usize| match levels.last() {
                Some(l) => l.range[i * l.w + j],
                None => {
                    let z = self.data[i * self.w + j];
                    (z, z)
                }
            };
            let mut range = Vec::with_capacity(nw * nh);
            for i in 0..nh {
                for j in 0..nw {
                    let mut r = (f32::INFINITY, f32::NEG_INFINITY);
                    for (di, dj) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                        let (ii, jj) = (2 * i + di, 2 * j + dj);
                        if ii < h && jj < w {
                            let v = at(ii, jj);
                            r = (r.0.min(v.0), r.1.max(v.1));
                        }
                    }
                    range.push(r);
                }
            }
            levels.push(MipLevel {
                w: nw,
                h: nh,
                range,
            });
            (w, h) = (nw, nh);
        }
        self.mip = levels;
        // Per cell, a bound of the bilinear patch's slope: each partial derivative is linear
        // across the cell, so at most its larger edge difference.
        if self.w >= 2 && self.h >= 2 {
            let (cw, ch) = (self.w - 1, self.h - 1);
            let z = |i: usize, j: usize| self.data[i * self.w + j];
            let mut base = Vec::with_capacity(cw * ch);
            for i in 0..ch {
                for j in 0..cw {
                    let sx = (z(i, j + 1) - z(i, j))
                        .abs()
                        .max((z(i + 1, j + 1) - z(i + 1, j)).abs())
                        / self.cx;
                    let sy = (z(i + 1, j) - z(i, j))
                        .abs()
                        .max((z(i + 1, j + 1) - z(i, j + 1)).abs())
                        / self.cy;
                    base.push((sx * sx + sy * sy).sqrt());
                }
            }
            self.slopes = MaxPyramid::new(base, cw, ch);
        }
        self
    }
    /// Lipschitz constant of the field over `region`: [`HfPrim::lipschitz`] with the steepest
    /// cell under the region's footprint instead of the DEM's steepest (clamped to the grid,
    /// beyond which the walls have unit slope), so gentle ground far from a cliff is traced
    /// with long steps.
    pub(super) fn lipschitz_over(&self, region: &Aabb) -> f32 {
        if self.slopes.levels.is_empty() {
            return self.lipschitz();
        }
        let (cw, ch) = (self.w - 2, self.h - 2);
        let top = (self.h - 1) as f32;
        let cell = |v: f32, n: usize| (v.floor().max(0.0) as usize).min(n);
        let (u0, u1) = (
            cell(region.min[0] / self.cx, cw),
            cell(region.max[0] / self.cx, cw),
        );
        let (v0, v1) = (
            cell(top - region.max[1] / self.cy, ch),
            cell(top - region.min[1] / self.cy, ch),
        );
        let s = self.slopes.max(u0, u1, v0, v1);
        THRESHOLD * 1.5 / self.r * (1.0 + s * s).sqrt()
    }
    /// Bytes of the samples and the pyramids.
    pub(super) fn bytes(&self) -> usize {
        self.data.len() * 4
            + self.mip.iter().map(|l| l.range.len() * 8).sum::<usize>()
            + self
                .slopes
                .levels
                .iter()
                .map(|l| l.2.len() * 4)
                .sum::<usize>()
    }
    pub(super) fn bbox(&self) -> Aabb {
        let (xm, ym) = self.extent();
        Aabb::new([0.0, 0.0, self.z_bottom], [xm, ym, self.z_max]).inflate(self.r)
    }
    pub(super) fn lipschitz(&self) -> f32 {
        THRESHOLD * 1.5 / self.r * self.slope_lip
    }
}

/// Where a DEM becomes a heightfield primitive, and its geometry in the scene frame.
///
/// The scene frame has `x` east and `y` north in metres from the DEM's south-west node and `z`
/// up in the DEM's units: DEM node (row `i`, column `j`) of a `w x h` grid sits at
/// `(j cx, (h - 1 - i) cy)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DemFrame {
    /// Grid width (columns).
    pub width: usize,
    /// Grid height (rows).
    pub height: usize,
    /// East-west spacing (m).
    pub cx: f32,
    /// North-south spacing (m).
    pub cy: f32,
}

impl DemFrame {
    /// Scene position of node (column `j`, row `i`) at elevation `z`.
    pub fn node(&self, j: usize, i: usize, z: f32) -> V3 {
        [
            j as f32 * self.cx,
            (self.height - 1 - i) as f32 * self.cy,
            z,
        ]
    }
    /// Continuous (column, row) of a scene point.
    pub fn to_grid(&self, p: V3) -> (f32, f32) {
        (p[0] / self.cx, (self.height - 1) as f32 - p[1] / self.cy)
    }
    /// Nearest cell (column, row) of a scene point, if inside the grid.
    pub fn cell(&self, p: V3) -> Option<(usize, usize)> {
        let (u, v) = self.to_grid(p);
        let (j, i) = (u.round(), v.round());
        if j >= 0.0 && i >= 0.0 && (j as usize) < self.width && (i as usize) < self.height {
            Some((j as usize, i as usize))
        } else {
            None
        }
    }
}

impl MaxPyramid {
    /// The pyramid of `base` (`w x h`, row-major), down to a single block.
    pub(super) fn new(base: Vec<f32>, w: usize, h: usize) -> Self {
        let mut levels = vec![(w, h, base)];
        while let Some(&(w, h, ref v)) = levels.last() {
            if w <= 1 && h <= 1 {
                break;
            }
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let mut next = Vec::with_capacity(nw * nh);
            for i in 0..nh {
                for j in 0..nw {
                    let mut m = f32::NEG_INFINITY;
                    for (di, dj) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                        let (ii, jj) = (2 * i + di, 2 * j + dj);
                        if ii < h && jj < w {
                            m = m.max(v[ii * w + jj]);
                        }
                    }
                    next.push(m);
                }
            }
            levels.push((nw, nh, next));
        }
        Self { levels }
    }
    /// Max over the inclusive index ranges (or over a few more values): from the level where
    /// the ranges span at most four blocks a side.
    pub(super) fn max(&self, u0: usize, u1: usize, v0: usize, v1: usize) -> f32 {
        let mut k = 0;
        while k + 1 < self.levels.len() && ((u1 >> k) - (u0 >> k) > 3 || (v1 >> k) - (v0 >> k) > 3)
        {
            k += 1;
        }
        let (w, h, v) = &self.levels[k];
        let mut m = f32::NEG_INFINITY;
        for i in (v0 >> k)..=(v1 >> k).min(h - 1) {
            for &x in &v[i * w + (u0 >> k)..=i * w + (u1 >> k).min(w - 1)] {
                m = m.max(x);
            }
        }
        m
    }
}
