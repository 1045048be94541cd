//! Evaluation of the tree: field values and gradients (analytic through primitives, finite
//! differences through operators).

use super::*;

impl TerrainTree {
    /// Field value of node `id` at `p`.
    pub fn eval(&self, id: NodeId, p: V3) -> f32 {
        self.ev(id.0, p)
    }

    fn ev(&self, id: u32, p: V3) -> f32 {
        match self.nodes[id as usize] {
            Node::Sphere { c, r, e } => {
                let d = sub(p, c);
                e * falloff(dot(d, d) / (r * r))
            }
            Node::Capsule { a, b, r, e } => {
                let ab = sub(b, a);
                let ap = sub(p, a);
                let t = (dot(ap, ab) / dot(ab, ab)).clamp(0.0, 1.0);
                let d = sub(ap, mul(ab, t));
                e * falloff(dot(d, d) / (r * r))
            }
            Node::Cone { a, b, ra, rb, e } => {
                let ab = sub(b, a);
                let ap = sub(p, a);
                let t = (dot(ap, ab) / dot(ab, ab)).clamp(0.0, 1.0);
                let d = sub(ap, mul(ab, t));
                let r = ra + (rb - ra) * t;
                e * falloff(dot(d, d) / (r * r))
            }
            Node::Ellipsoid { c, axes, e } => {
                let d = sub(p, c);
                let q =
                    (d[0] / axes[0]).powi(2) + (d[1] / axes[1]).powi(2) + (d[2] / axes[2]).powi(2);
                e * falloff(q)
            }
            Node::Heightfield(k) => self.hfs[k as usize].field(p),
            Node::Blend { first, count } => self
                .blended(first, count)
                .iter()
                .map(|&c| self.ev(c, p))
                .sum(),
            Node::Bvh { bbox, left, right } => {
                if bbox.contains(p) {
                    self.ev(left, p) + self.ev(right, p)
                } else {
                    0.0
                }
            }
            Node::Union { a, b } => self.ev(a, p).max(self.ev(b, p)),
            Node::Intersection { a, b } => self.ev(a, p).min(self.ev(b, p)),
            Node::Difference { a, b } => self
                .ev(a, p)
                .min((2.0 * THRESHOLD - self.ev(b, p)).max(0.0)),
            Node::SmoothBlend { a, b, n } => {
                let (x, y) = (self.ev(a, p).max(0.0), self.ev(b, p).max(0.0));
                let m = x.max(y);
                if m <= 0.0 {
                    0.0
                } else {
                    m * ((x / m).powf(n) + (y / m).powf(n)).powf(1.0 / n)
                }
            }
            Node::Warp {
                child,
                amp,
                freq,
                zfreq,
                seed,
                bx,
            } => {
                if !self.warp_boxes[bx as usize].contains(p) {
                    return 0.0;
                }
                let d = fbm3(seed as u64, [p[0] * freq, p[1] * freq, p[2] * zfreq], 2);
                self.ev(child, add(p, mul(d, amp)))
            }
        }
    }

    /// Field value and gradient of node `id` at `p`: analytic through primitives (sphere,
    /// capsule, ellipsoid, heightfield), sums, CSG branches and smooth blends; central
    /// differences with step `h` only for cones and noise warps (their analytic Jacobians are
    /// not worth the cost).
    pub fn eval_grad(&self, id: NodeId, p: V3, h: f32) -> (f32, V3) {
        self.evg(id.0, p, h, false)
    }

    /// [`Self::eval_grad`] with the heightfield primitive's shading gradient: its slopes
    /// interpolated from the DEM nodes' central differences, continuous across cell edges (the
    /// bilinear patches' own slopes jump there, which shades every DEM cell as a facet). The
    /// field value is the same; use it for normals (renders, mesh vertex normals), not where
    /// the exact gradient matters.
    pub fn eval_shading_grad(&self, id: NodeId, p: V3, h: f32) -> (f32, V3) {
        self.evg(id.0, p, h, true)
    }

    fn fd(&self, id: u32, p: V3, h: f32) -> (f32, V3) {
        let mut g = [0.0; 3];
        for k in 0..3 {
            let (mut a, mut b) = (p, p);
            a[k] += h;
            b[k] -= h;
            g[k] = (self.ev(id, a) - self.ev(id, b)) / (2.0 * h);
        }
        (self.ev(id, p), g)
    }

    fn evg(&self, id: u32, p: V3, h: f32, smooth: bool) -> (f32, V3) {
        // Falloff e g(q) with q = |d|^2 / r^2: gradient e g'(q) dq/dp, g'(q) = -3 (1 - q)^2.
        let radial = |e: f32, q: f32, dq: V3| {
            if q >= 1.0 {
                (0.0, [0.0; 3])
            } else {
                let t = 1.0 - q;
                (e * t * t * t, mul(dq, -3.0 * e * t * t))
            }
        };
        match self.nodes[id as usize] {
            Node::Sphere { c, r, e } => {
                let d = sub(p, c);
                radial(e, dot(d, d) / (r * r), mul(d, 2.0 / (r * r)))
            }
            Node::Capsule { a, b, r, e } => {
                let ab = sub(b, a);
                let ap = sub(p, a);
                let t = (dot(ap, ab) / dot(ab, ab)).clamp(0.0, 1.0);
                let d = sub(ap, mul(ab, t));
                radial(e, dot(d, d) / (r * r), mul(d, 2.0 / (r * r)))
            }
            Node::Ellipsoid { c, axes, e } => {
                let d = sub(p, c);
                let q =
                    (d[0] / axes[0]).powi(2) + (d[1] / axes[1]).powi(2) + (d[2] / axes[2]).powi(2);
                let dq = [
                    2.0 * d[0] / (axes[0] * axes[0]),
                    2.0 * d[1] / (axes[1] * axes[1]),
                    2.0 * d[2] / (axes[2] * axes[2]),
                ];
                radial(e, q, dq)
            }
            Node::Cone { .. } | Node::Warp { .. } => {
                if self.bbox_of(id).contains(p) {
                    self.fd(id, p, h)
                } else {
                    (0.0, [0.0; 3])
                }
            }
            Node::Heightfield(k) => self.hfs[k as usize].field_grad_with(p, smooth),
            Node::Blend { first, count } => {
                self.blended(first, count)
                    .iter()
                    .fold((0.0, [0.0; 3]), |acc, &c| {
                        let (v, g) = self.evg(c, p, h, smooth);
                        (acc.0 + v, add(acc.1, g))
                    })
            }
            Node::Bvh { bbox, left, right } => {
                if bbox.contains(p) {
                    let (a, ga) = self.evg(left, p, h, smooth);
                    let (b, gb) = self.evg(right, p, h, smooth);
                    (a + b, add(ga, gb))
                } else {
                    (0.0, [0.0; 3])
                }
            }
            Node::Union { a, b } => {
                let (x, y) = (self.evg(a, p, h, smooth), self.evg(b, p, h, smooth));
                if x.0 >= y.0 { x } else { y }
            }
            Node::Intersection { a, b } => {
                let (x, y) = (self.evg(a, p, h, smooth), self.evg(b, p, h, smooth));
                if x.0 <= y.0 { x } else { y }
            }
            Node::Difference { a, b } => {
                let x = self.evg(a, p, h, smooth);
                let y = self.evg(b, p, h, smooth);
                let c = 2.0 * THRESHOLD - y.0;
                if c <= 0.0 {
                    if x.0 <= 0.0 { x } else { (0.0, [0.0; 3]) }
                } else if x.0 <= c {
                    x
                } else {
                    (c, mul(y.1, -1.0))
                }
            }
            Node::SmoothBlend { a, b, n } => {
                let (x, gx) = self.evg(a, p, h, smooth);
                let (y, gy) = self.evg(b, p, h, smooth);
                let (x, y) = (x.max(0.0), y.max(0.0));
                let (gx, gy) = (
                    if x > 0.0 { gx } else { [0.0; 3] },
                    if y > 0.0 { gy } else { [0.0; 3] },
                );
                let m = x.max(y);
                if m <= 0.0 {
                    (0.0, [0.0; 3])
                } else {
                    let (u, v) = (x / m, y / m);
                    let s = u.powf(n) + v.powf(n);
                    let k = s.powf(1.0 / n - 1.0);
                    (
                        m * s.powf(1.0 / n),
                        add(mul(gx, k * u.powf(n - 1.0)), mul(gy, k * v.powf(n - 1.0))),
                    )
                }
            }
        }
    }
}
