//! Bounds of a node's field over a region: Lipschitz constants (sphere tracing, skipping empty
//! cells) and interval ranges.

use super::*;

impl TerrainTree {
    /// Upper bound of the Lipschitz constant of node `id`'s field restricted to `region`
    /// (0 when the node's support misses `region`). Used for sphere tracing and for skipping
    /// empty chunks when meshing.
    pub fn lipschitz(&self, id: NodeId, region: &Aabb) -> f32 {
        self.lip(id.0, region)
    }

    fn lip(&self, id: u32, region: &Aabb) -> f32 {
        let node = self.nodes[id as usize];
        let prim = |e: f32, r: f32| {
            if self.bbox_of(id).intersects(region) {
                e.abs() * FALLOFF_LIPSCHITZ / r
            } else {
                0.0
            }
        };
        match node {
            Node::Sphere { r, e, .. } | Node::Capsule { r, e, .. } => prim(e, r),
            Node::Cone { a, b, ra, rb, e } => {
                let len = crate::math::norm(sub(b, a));
                prim(e, ra.min(rb)) * (1.0 + (ra - rb).abs() / len)
            }
            Node::Ellipsoid { axes, e, .. } => prim(e, axes[0].min(axes[1]).min(axes[2])),
            Node::Heightfield(k) => {
                let h = &self.hfs[k as usize];
                if h.bbox().intersects(region) {
                    h.lipschitz_over(region)
                } else {
                    0.0
                }
            }
            Node::Blend { first, count } => self
                .blended(first, count)
                .iter()
                .map(|&c| self.lip(c, region))
                .sum(),
            Node::Bvh { bbox, left, right } => {
                if bbox.intersects(region) {
                    self.lip(left, region) + self.lip(right, region)
                } else {
                    0.0
                }
            }
            Node::Union { a, b } | Node::Intersection { a, b } | Node::Difference { a, b } => {
                self.lip(a, region).max(self.lip(b, region))
            }
            Node::SmoothBlend { a, b, .. } => self.lip(a, region) + self.lip(b, region),
            Node::Warp {
                child, amp, freq, ..
            } => {
                if !self.bbox_of(id).intersects(region) {
                    return 0.0;
                }
                let grown = region.inflate(0.75 * amp);
                let jac = 1.0 + amp * freq * fbm_lipschitz(2) * 3f32.sqrt();
                self.lip(child, &grown) * jac
            }
        }
    }

    /// Conservative range `[lo, hi]` of node `id`'s field over `region` (interval arithmetic
    /// through the tree; exact bounds of the falloff from the box-to-skeleton distance and of
    /// the DEM elevations under the box). Used to skip empty chunks when meshing.
    pub fn interval(&self, id: NodeId, region: &Aabb) -> (f32, f32) {
        self.iv(id.0, region)
    }

    /// A lower bound of node `id`'s field anywhere (no region: cheap for leaves).
    fn field_min(&self, id: u32) -> f32 {
        match self.nodes[id as usize] {
            Node::Sphere { e, .. }
            | Node::Capsule { e, .. }
            | Node::Cone { e, .. }
            | Node::Ellipsoid { e, .. } => e.min(0.0),
            Node::Heightfield(_) => 0.0,
            Node::Blend { first, count } => self
                .blended(first, count)
                .iter()
                .map(|&c| self.field_min(c))
                .sum(),
            Node::Bvh { left, right, .. } => self.field_min(left) + self.field_min(right),
            Node::Union { a, b } => self.field_min(a).max(self.field_min(b)),
            Node::Intersection { a, b } | Node::SmoothBlend { a, b, .. } => {
                self.field_min(a).min(self.field_min(b)).min(0.0)
            }
            Node::Difference { a, .. } => self.field_min(a).min(0.0),
            Node::Warp { child, .. } => self.field_min(child),
        }
    }

    fn iv(&self, id: u32, region: &Aabb) -> (f32, f32) {
        let node = self.nodes[id as usize];
        let span = |e: f32, gmax: f32| {
            if e >= 0.0 {
                (0.0, e * gmax)
            } else {
                (e * gmax, 0.0)
            }
        };
        match node {
            Node::Sphere { c, r, e } => span(e, falloff(region.dist_sq(c) / (r * r))),
            Node::Ellipsoid { c, axes, e } => {
                let mut q = 0.0;
                for k in 0..3 {
                    let d = (region.min[k] - c[k]).max(0.0).max(c[k] - region.max[k]) / axes[k];
                    q += d * d;
                }
                span(e, falloff(q))
            }
            Node::Capsule { a, b, r, e } => seg_range(a, b, r, r, e, region),
            Node::Cone { a, b, ra, rb, e } => seg_range(a, b, ra.min(rb), ra.max(rb), e, region),
            Node::Heightfield(k) => {
                let h = &self.hfs[k as usize];
                if !h.bbox().intersects(region) {
                    return (0.0, 0.0);
                }
                let (hl, hh) = h.height_range(region);
                let (xm, ym) = h.extent();
                let comps = [
                    (region.min[0], region.max[0]),
                    (xm - region.max[0], xm - region.min[0]),
                    (region.min[1], region.max[1]),
                    (ym - region.max[1], ym - region.min[1]),
                    (region.min[2] - h.z_bottom, region.max[2] - h.z_bottom),
                ];
                let (mut dl, mut dh) = (hl - region.max[2], hh - region.min[2]);
                for (a, b) in comps {
                    dl = dl.min(a);
                    dh = dh.min(b);
                }
                (
                    THRESHOLD + THRESHOLD * cubic_step(dl / h.r),
                    THRESHOLD + THRESHOLD * cubic_step(dh / h.r),
                )
            }
            Node::Blend { first, count } => {
                self.blended(first, count)
                    .iter()
                    .fold((0.0, 0.0), |acc, &c| {
                        let v = self.iv(c, region);
                        (acc.0 + v.0, acc.1 + v.1)
                    })
            }
            Node::Bvh { bbox, left, right } => {
                if bbox.intersects(region) {
                    let (a, b) = (self.iv(left, region), self.iv(right, region));
                    (a.0 + b.0, a.1 + b.1)
                } else {
                    (0.0, 0.0)
                }
            }
            Node::Union { a, b } => {
                let (a, b) = (self.iv(a, region), self.iv(b, region));
                (a.0.max(b.0), a.1.max(b.1))
            }
            Node::Intersection { a, b } => {
                // `b` first: where it is at most 0 (e.g. a landform's shape missing the region)
                // so is the intersection, and `a`'s range (a DEM scan) is not needed.
                let bv = self.iv(b, region);
                if bv.1 <= 0.0 {
                    return (self.field_min(a).min(bv.0), bv.1);
                }
                let av = self.iv(a, region);
                (av.0.min(bv.0), av.1.min(bv.1))
            }
            Node::Difference { a, b } => {
                let (a, b) = (self.iv(a, region), self.iv(b, region));
                let (cl, ch) = (
                    (2.0 * THRESHOLD - b.1).max(0.0),
                    (2.0 * THRESHOLD - b.0).max(0.0),
                );
                (a.0.min(cl), a.1.min(ch))
            }
            Node::SmoothBlend { a, b, .. } => {
                let (a, b) = (self.iv(a, region), self.iv(b, region));
                (a.0.max(b.0).max(0.0), a.1.max(0.0) + b.1.max(0.0))
            }
            Node::Warp { child, amp, .. } => {
                if !self.bbox_of(id).intersects(region) {
                    return (0.0, 0.0);
                }
                self.iv(child, &region.inflate(0.75 * amp))
            }
        }
    }
}

/// Range over `region` of `e falloff(d^2 / r^2)`, `d` the distance to the segment `a`-`b` and
/// `r` between `rmin` and `rmax` (capsules, cones): the distance is at least the one to the
/// segment's box and at most the largest over the region's corners.
fn seg_range(a: V3, b: V3, rmin: f32, rmax: f32, e: f32, region: &Aabb) -> (f32, f32) {
    let near = region.dist_sq_box(&Aabb::new(a, b));
    if near >= rmax * rmax {
        return (0.0, 0.0);
    }
    // Only `falloff(far / rmin^2)` is used: 0 once a corner is that far.
    let far = region.max_dist_sq_to_segment_until(a, b, rmin * rmin);
    let (gmax, gmin) = (falloff(near / (rmax * rmax)), falloff(far / (rmin * rmin)));
    if e >= 0.0 {
        (e * gmin, e * gmax)
    } else {
        (e * gmax, e * gmin)
    }
}
