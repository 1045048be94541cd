//! The terrain construction tree T (paper section 3, "Implicit terrain model").
//!
//! # Field convention
//! Every node defines a field `f : R^3 -> R` that is 0 outside the node's bounding box (compact
//! support). Matter is where `f > T`, air where `f < T`, and the surface is `f = T` with
//! [`THRESHOLD`] `T = 1/2`. Skeletal primitives add `e * g(d^2 / R^2)` with the cubic falloff
//! `g(q) = (1 - q)^3` ([`crate::math::falloff`]): a positive energy `e` adds matter, a negative
//! one carves. The heightfield primitive is `T + T s(min(H(x, y) - z, d_box) / r)` with the odd
//! cubic step `s`, so it is exactly `T` on the DEM surface and saturates to `0` (air) / `2T`
//! (rock) a distance `r` away.
//!
//! Nodes live in a flat arena ([`TerrainTree`]) of 40-byte records addressed by [`NodeId`];
//! n-ary blends keep their children in one shared index table. [`TerrainTree::bvh_blend`] builds
//! a bounding-volume hierarchy of blend nodes over compactly supported sub-trees, so a query
//! visits only the primitives whose box holds the point.

use relief_heightfield::Heightfield;

use crate::error::{Error, Result};
use crate::math::{
    Aabb, FALLOFF_LIPSCHITZ, V3, add, cubic_step, dot, falloff, fbm_lipschitz, fbm3, mul, sub,
};

/// The iso-value `T` of the terrain surface `f = T`.
pub const THRESHOLD: f32 = 0.5;

/// Index of a node in a [`TerrainTree`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub u32);

#[derive(Debug, Clone, Copy, PartialEq)]
enum Node {
    Sphere {
        c: V3,
        r: f32,
        e: f32,
    },
    Capsule {
        a: V3,
        b: V3,
        r: f32,
        e: f32,
    },
    Cone {
        a: V3,
        b: V3,
        ra: f32,
        rb: f32,
        e: f32,
    },
    Ellipsoid {
        c: V3,
        axes: V3,
        e: f32,
    },
    Heightfield(u32),
    Blend {
        first: u32,
        count: u32,
    },
    Bvh {
        bbox: Aabb,
        left: u32,
        right: u32,
    },
    Union {
        a: u32,
        b: u32,
    },
    Intersection {
        a: u32,
        b: u32,
    },
    Difference {
        a: u32,
        b: u32,
    },
    SmoothBlend {
        a: u32,
        b: u32,
        n: f32,
    },
    Warp {
        child: u32,
        amp: f32,
        freq: f32,
        seed: u32,
        /// Index of the warp's support box in `TerrainTree::warp_boxes` (outside it the
        /// field is 0: the displacement is below `0.75 amp`), so a query outside never
        /// evaluates the noise.
        bx: u32,
    },
}

/// The implicitised DEM (heightfield primitive).
#[derive(Debug, Clone)]
struct HfPrim {
    w: usize,
    h: usize,
    cx: f32,
    cy: f32,
    data: Vec<f32>,
    r: f32,
    z_bottom: f32,
    z_max: f32,
    /// Lipschitz constant of `min(H - z, d_box)`: `sqrt(1 + sx^2 + sy^2)`.
    slope_lip: f32,
}

impl HfPrim {
    #[inline]
    fn height(&self, x: f32, y: f32) -> f32 {
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
    fn extent(&self) -> (f32, f32) {
        ((self.w - 1) as f32 * self.cx, (self.h - 1) as f32 * self.cy)
    }
    #[inline]
    fn field(&self, p: V3) -> f32 {
        let (xm, ym) = self.extent();
        let db = p[0]
            .min(xm - p[0])
            .min(p[1])
            .min(ym - p[1])
            .min(p[2] - self.z_bottom);
        let dt = self.height(p[0], p[1]) - p[2];
        THRESHOLD + THRESHOLD * cubic_step(dt.min(db) / self.r)
    }
    /// Field and analytic gradient (the gradient of the active branch of the `min`, and of
    /// the bilinear patch of `H`).
    #[inline]
    fn field_grad(&self, p: V3) -> (f32, V3) {
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
            let dhdu = ((z01 - z00) * (1.0 - ty) + (z11 - z10) * ty) / self.cx;
            // v grows southwards, y northwards.
            let dhdv = -(b - a) / self.cy;
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

    /// Range of the bilinear DEM over the xy footprint of `b` (clamped to the grid).
    fn height_range(&self, b: &Aabb) -> (f32, f32) {
        let u0 = ((b.min[0] / self.cx).floor().max(0.0) as usize).min(self.w - 1);
        let u1 = ((b.max[0] / self.cx).ceil().max(0.0) as usize).min(self.w - 1);
        let top = (self.h - 1) as f32;
        let v0 = ((top - b.max[1] / self.cy).floor().max(0.0) as usize).min(self.h - 1);
        let v1 = ((top - b.min[1] / self.cy).ceil().max(0.0) as usize).min(self.h - 1);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for i in v0..=v1 {
            for &z in &self.data[i * self.w + u0..=i * self.w + u1] {
                lo = lo.min(z);
                hi = hi.max(z);
            }
        }
        (lo, hi)
    }
    fn bbox(&self) -> Aabb {
        let (xm, ym) = self.extent();
        Aabb::new([0.0, 0.0, self.z_bottom], [xm, ym, self.z_max]).inflate(self.r)
    }
    fn lipschitz(&self) -> f32 {
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

/// Node count and memory of a tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TreeStats {
    /// Number of nodes (primitives, operators and BVH nodes).
    pub nodes: usize,
    /// Number of leaf primitives.
    pub primitives: usize,
    /// Bytes of the node arena and the n-ary child table.
    pub node_bytes: usize,
    /// Bytes of the embedded DEM samples of heightfield primitives.
    pub heightfield_bytes: usize,
}

/// Flat arena of terrain-tree nodes (see module docs).
#[derive(Debug, Clone, Default)]
pub struct TerrainTree {
    nodes: Vec<Node>,
    children: Vec<u32>,
    hfs: Vec<HfPrim>,
    warp_boxes: Vec<Aabb>,
}

fn pos(name: &'static str, v: f32) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::param(name, v, "must be finite and > 0"))
    }
}
fn fin(name: &'static str, v: &[f32]) -> Result<()> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(Error::param(name, format!("{v:?}"), "must be finite"))
    }
}

impl TerrainTree {
    /// An empty tree.
    pub fn new() -> Self {
        Self::default()
    }

    fn push(&mut self, n: Node) -> NodeId {
        self.nodes.push(n);
        NodeId(self.nodes.len() as u32 - 1)
    }
    fn id(&self, id: NodeId) -> Result<u32> {
        if (id.0 as usize) < self.nodes.len() {
            Ok(id.0)
        } else {
            Err(Error::param("node id", id.0, "not a node of this tree"))
        }
    }

    /// Sphere primitive: centre `c`, support radius `r`, energy `e` (negative carves).
    pub fn sphere(&mut self, c: V3, r: f32, e: f32) -> Result<NodeId> {
        fin("sphere.center", &c)?;
        pos("sphere.radius", r)?;
        fin("sphere.energy", &[e])?;
        Ok(self.push(Node::Sphere { c, r, e }))
    }
    /// Capsule primitive: segment `a`-`b`, support radius `r`, energy `e`.
    pub fn capsule(&mut self, a: V3, b: V3, r: f32, e: f32) -> Result<NodeId> {
        fin("capsule.ends", &[a[0], a[1], a[2], b[0], b[1], b[2], e])?;
        pos("capsule.radius", r)?;
        Ok(self.push(Node::Capsule { a, b, r, e }))
    }
    /// Cone primitive: axis `a`-`b` with support radius `ra` at `a` and `rb` at `b`.
    pub fn cone(&mut self, a: V3, b: V3, ra: f32, rb: f32, e: f32) -> Result<NodeId> {
        fin("cone.ends", &[a[0], a[1], a[2], b[0], b[1], b[2], e])?;
        pos("cone.ra", ra)?;
        pos("cone.rb", rb)?;
        pos("cone.length", crate::math::norm(sub(b, a)))?;
        Ok(self.push(Node::Cone { a, b, ra, rb, e }))
    }
    /// Axis-aligned ellipsoid primitive: centre `c`, support semi-axes `axes`, energy `e`.
    pub fn ellipsoid(&mut self, c: V3, axes: V3, e: f32) -> Result<NodeId> {
        fin("ellipsoid.center", &c)?;
        for a in axes {
            pos("ellipsoid.axes", a)?;
        }
        fin("ellipsoid.energy", &[e])?;
        Ok(self.push(Node::Ellipsoid { c, axes, e }))
    }

    /// Implicitisation of a DEM (paper section 2, workflow): a heightfield primitive whose
    /// surface `f = T` is the bilinear interpolant of the DEM, closed by vertical walls at the
    /// DEM border and a floor `depth` metres below its lowest sample. `transition` is the
    /// distance `r` over which the field goes from `T` to saturation.
    pub fn heightfield(
        &mut self,
        hf: &Heightfield,
        transition: f32,
        depth: f32,
    ) -> Result<(NodeId, DemFrame)> {
        hf.require_complete()?;
        pos("transition", transition)?;
        pos("depth", depth)?;
        if hf.width() < 2 || hf.height() < 2 {
            return Err(Error::param(
                "heightfield size",
                format!("{}x{}", hf.width(), hf.height()),
                "needs at least 2x2 nodes",
            ));
        }
        let (cx, cy) = hf.cell_size();
        let (cx, cy) = (cx as f32, cy as f32);
        let data = hf.as_slice().to_vec();
        let (w, h) = (hf.width(), hf.height());
        let (mut sx, mut sy) = (0.0f32, 0.0f32);
        for i in 0..h {
            for j in 0..w {
                let z = data[i * w + j];
                if j + 1 < w {
                    sx = sx.max((data[i * w + j + 1] - z).abs() / cx);
                }
                if i + 1 < h {
                    sy = sy.max((data[(i + 1) * w + j] - z).abs() / cy);
                }
            }
        }
        let (lo, hi) =
            hf.min_max()
                .ok_or(Error::param("heightfield", "all void", "needs samples"))?;
        let prim = HfPrim {
            w,
            h,
            cx,
            cy,
            data,
            r: transition,
            z_bottom: lo - depth,
            z_max: hi,
            slope_lip: (1.0 + sx * sx + sy * sy).sqrt(),
        };
        self.hfs.push(prim);
        let id = self.push(Node::Heightfield(self.hfs.len() as u32 - 1));
        Ok((
            id,
            DemFrame {
                width: w,
                height: h,
                cx,
                cy,
            },
        ))
    }

    /// Elevation of the bilinear DEM surface of heightfield primitive `id` at `(x, y)`.
    pub fn dem_height(&self, id: NodeId, x: f32, y: f32) -> Option<f32> {
        match self.nodes.get(id.0 as usize)? {
            Node::Heightfield(k) => Some(self.hfs[*k as usize].height(x, y)),
            _ => None,
        }
    }

    /// Elevation of the closing floor of heightfield primitive `id`.
    pub fn dem_floor(&self, id: NodeId) -> Option<f32> {
        match self.nodes.get(id.0 as usize)? {
            Node::Heightfield(k) => Some(self.hfs[*k as usize].z_bottom),
            _ => None,
        }
    }

    /// N-ary blend (sum of the children's fields), evaluated by visiting every child.
    pub fn blend(&mut self, items: &[NodeId]) -> Result<NodeId> {
        let first = self.children.len() as u32;
        for &c in items {
            let c = self.id(c)?;
            self.children.push(c);
        }
        Ok(self.push(Node::Blend {
            first,
            count: items.len() as u32,
        }))
    }

    /// Blend (sum) of `items` organised as a bounding-volume hierarchy (median split on the
    /// longest axis of the centroids' box): a query skips every sub-tree whose box misses the
    /// point. The result equals [`TerrainTree::blend`] of the same items.
    pub fn bvh_blend(&mut self, items: &[NodeId]) -> Result<NodeId> {
        if items.is_empty() {
            return self.blend(items);
        }
        let mut v = Vec::with_capacity(items.len());
        for &c in items {
            let k = self.id(c)?;
            let b = self.bbox(c);
            v.push((k, b, b.center()));
        }
        Ok(NodeId(self.build_bvh(&mut v)))
    }

    fn build_bvh(&mut self, v: &mut [(u32, Aabb, V3)]) -> u32 {
        if v.len() == 1 {
            return v[0].0;
        }
        let mut cb = Aabb::empty();
        let mut bb = Aabb::empty();
        for (_, b, c) in v.iter() {
            cb = cb.union(&Aabb::new(*c, *c));
            bb = bb.union(b);
        }
        let s = cb.size();
        let axis = if s[0] >= s[1] && s[0] >= s[2] {
            0
        } else if s[1] >= s[2] {
            1
        } else {
            2
        };
        let mid = v.len() / 2;
        v.select_nth_unstable_by(mid, |x, y| {
            x.2[axis].total_cmp(&y.2[axis]).then(x.0.cmp(&y.0))
        });
        let (l, r) = v.split_at_mut(mid);
        let left = self.build_bvh(l);
        let right = self.build_bvh(r);
        self.push(Node::Bvh {
            bbox: bb,
            left,
            right,
        })
        .0
    }

    /// CSG union `max(a, b)`.
    pub fn union(&mut self, a: NodeId, b: NodeId) -> Result<NodeId> {
        let (a, b) = (self.id(a)?, self.id(b)?);
        Ok(self.push(Node::Union { a, b }))
    }
    /// CSG intersection `min(a, b)`.
    pub fn intersection(&mut self, a: NodeId, b: NodeId) -> Result<NodeId> {
        let (a, b) = (self.id(a)?, self.id(b)?);
        Ok(self.push(Node::Intersection { a, b }))
    }
    /// CSG difference (carve `b` out of `a`): `min(a, max(2T - b, 0))`.
    pub fn difference(&mut self, a: NodeId, b: NodeId) -> Result<NodeId> {
        let (a, b) = (self.id(a)?, self.id(b)?);
        Ok(self.push(Node::Difference { a, b }))
    }
    /// Smooth blend (Ricci): `(a+^n + b+^n)^(1/n)`, `n >= 1`; `n = 1` is the sum, large `n`
    /// tends to the union.
    pub fn smooth_blend(&mut self, a: NodeId, b: NodeId, n: f32) -> Result<NodeId> {
        if !(n.is_finite() && n >= 1.0) {
            return Err(Error::param("smooth_blend.n", n, "must be finite and >= 1"));
        }
        let (a, b) = (self.id(a)?, self.id(b)?);
        Ok(self.push(Node::SmoothBlend { a, b, n }))
    }
    /// Noise warp: the child is evaluated at `p + amp * fbm3(p * freq)` (creases, cracks).
    pub fn warp(&mut self, child: NodeId, amp: f32, freq: f32, seed: u32) -> Result<NodeId> {
        pos("warp.amp", amp)?;
        pos("warp.freq", freq)?;
        let child = self.id(child)?;
        let bx = self.warp_boxes.len() as u32;
        self.warp_boxes
            .push(self.bbox_of(child).inflate(0.75 * amp));
        Ok(self.push(Node::Warp {
            child,
            amp,
            freq,
            seed,
            bx,
        }))
    }

    /// Bounding box outside which the node's field is 0.
    pub fn bbox(&self, id: NodeId) -> Aabb {
        self.bbox_of(id.0)
    }
    fn bbox_of(&self, id: u32) -> Aabb {
        match self.nodes[id as usize] {
            Node::Sphere { c, r, .. } => Aabb::sphere(c, r),
            Node::Capsule { a, b, r, .. } => Aabb::new(a, b).inflate(r),
            Node::Cone { a, b, ra, rb, .. } => Aabb::new(a, b).inflate(ra.max(rb)),
            Node::Ellipsoid { c, axes, .. } => Aabb {
                min: sub(c, axes),
                max: add(c, axes),
            },
            Node::Heightfield(k) => self.hfs[k as usize].bbox(),
            Node::Blend { first, count } => self.children[first as usize..(first + count) as usize]
                .iter()
                .fold(Aabb::empty(), |b, &c| b.union(&self.bbox_of(c))),
            Node::Bvh { bbox, .. } => bbox,
            Node::Union { a, b } | Node::Intersection { a, b } | Node::SmoothBlend { a, b, .. } => {
                self.bbox_of(a).union(&self.bbox_of(b))
            }
            Node::Difference { a, .. } => self.bbox_of(a),
            Node::Warp { bx, .. } => self.warp_boxes[bx as usize],
        }
    }

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
            Node::Blend { first, count } => self.children[first as usize..(first + count) as usize]
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
                seed,
                bx,
            } => {
                if !self.warp_boxes[bx as usize].contains(p) {
                    return 0.0;
                }
                let d = fbm3(seed as u64, mul(p, freq), 2);
                self.ev(child, add(p, mul(d, amp)))
            }
        }
    }

    /// Field value and gradient of node `id` at `p`: analytic through primitives (sphere,
    /// capsule, ellipsoid, heightfield), sums, CSG branches and smooth blends; central
    /// differences with step `h` only for cones and noise warps (their analytic Jacobians are
    /// not worth the cost).
    pub fn eval_grad(&self, id: NodeId, p: V3, h: f32) -> (f32, V3) {
        self.evg(id.0, p, h)
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

    fn evg(&self, id: u32, p: V3, h: f32) -> (f32, V3) {
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
            Node::Heightfield(k) => self.hfs[k as usize].field_grad(p),
            Node::Blend { first, count } => self.children[first as usize..(first + count) as usize]
                .iter()
                .fold((0.0, [0.0; 3]), |acc, &c| {
                    let (v, g) = self.evg(c, p, h);
                    (acc.0 + v, add(acc.1, g))
                }),
            Node::Bvh { bbox, left, right } => {
                if bbox.contains(p) {
                    let (a, ga) = self.evg(left, p, h);
                    let (b, gb) = self.evg(right, p, h);
                    (a + b, add(ga, gb))
                } else {
                    (0.0, [0.0; 3])
                }
            }
            Node::Union { a, b } => {
                let (x, y) = (self.evg(a, p, h), self.evg(b, p, h));
                if x.0 >= y.0 { x } else { y }
            }
            Node::Intersection { a, b } => {
                let (x, y) = (self.evg(a, p, h), self.evg(b, p, h));
                if x.0 <= y.0 { x } else { y }
            }
            Node::Difference { a, b } => {
                let x = self.evg(a, p, h);
                let y = self.evg(b, p, h);
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
                let (x, gx) = self.evg(a, p, h);
                let (y, gy) = self.evg(b, p, h);
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
                    h.lipschitz()
                } else {
                    0.0
                }
            }
            Node::Blend { first, count } => self.children[first as usize..(first + count) as usize]
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
            Node::Capsule { e, .. } | Node::Cone { e, .. } => {
                if self.bbox_of(id).intersects(region) {
                    span(e, 1.0)
                } else {
                    (0.0, 0.0)
                }
            }
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
            Node::Blend { first, count } => self.children[first as usize..(first + count) as usize]
                .iter()
                .fold((0.0, 0.0), |acc, &c| {
                    let v = self.iv(c, region);
                    (acc.0 + v.0, acc.1 + v.1)
                }),
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
                let (a, b) = (self.iv(a, region), self.iv(b, region));
                (a.0.min(b.0), a.1.min(b.1))
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

    /// Node count and memory (see [`TreeStats`]).
    pub fn stats(&self) -> TreeStats {
        let primitives = self
            .nodes
            .iter()
            .filter(|n| {
                matches!(
                    n,
                    Node::Sphere { .. }
                        | Node::Capsule { .. }
                        | Node::Cone { .. }
                        | Node::Ellipsoid { .. }
                        | Node::Heightfield(_)
                )
            })
            .count();
        TreeStats {
            nodes: self.nodes.len(),
            primitives,
            node_bytes: self.nodes.len() * std::mem::size_of::<Node>() + self.children.len() * 4,
            heightfield_bytes: self.hfs.iter().map(|h| h.data.len() * 4).sum(),
        }
    }

    /// Node counts by kind (`sphere`, `capsule`, `cone`, `ellipsoid`, `heightfield`, `blend`,
    /// `bvh`, `union`, `intersection`, `difference`, `smooth_blend`, `warp`), in that order,
    /// kinds with no node left out; positive and negative spheres are counted apart
    /// (`sphere_carving`).
    pub fn kind_counts(&self) -> Vec<(&'static str, usize)> {
        const NAMES: [&str; 13] = [
            "sphere",
            "sphere_carving",
            "capsule",
            "cone",
            "ellipsoid",
            "heightfield",
            "blend",
            "bvh",
            "union",
            "intersection",
            "difference",
            "smooth_blend",
            "warp",
        ];
        let mut c = [0usize; 13];
        for n in &self.nodes {
            let k = match n {
                Node::Sphere { e, .. } if *e < 0.0 => 1,
                Node::Sphere { .. } => 0,
                Node::Capsule { .. } => 2,
                Node::Cone { .. } => 3,
                Node::Ellipsoid { .. } => 4,
                Node::Heightfield(_) => 5,
                Node::Blend { .. } => 6,
                Node::Bvh { .. } => 7,
                Node::Union { .. } => 8,
                Node::Intersection { .. } => 9,
                Node::Difference { .. } => 10,
                Node::SmoothBlend { .. } => 11,
                Node::Warp { .. } => 12,
            };
            c[k] += 1;
        }
        NAMES.into_iter().zip(c).filter(|x| x.1 > 0).collect()
    }

    /// Size in bytes of one node record.
    pub fn node_size() -> usize {
        std::mem::size_of::<Node>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use relief_heightfield::Heightfield;

    #[test]
    fn node_is_compact() {
        assert!(
            TerrainTree::node_size() <= 40,
            "{}",
            TerrainTree::node_size()
        );
    }

    #[test]
    fn bvh_equals_flat_blend_and_lipschitz_bounds_hold() {
        let mut t = TerrainTree::new();
        let mut ids = Vec::new();
        for k in 0..200u64 {
            let h = |s| crate::math::unit(crate::math::hash(3, k, s, 0)) * 100.0;
            let c = [h(0), h(1), h(2)];
            ids.push(match k % 4 {
                0 => t.sphere(c, 5.0 + h(3) * 0.1, 1.0).unwrap(),
                1 => t.capsule(c, add(c, [3.0, 1.0, 2.0]), 4.0, -0.7).unwrap(),
                2 => t.cone(c, add(c, [0.0, 0.0, 8.0]), 6.0, 2.0, 0.9).unwrap(),
                _ => t.ellipsoid(c, [6.0, 4.0, 3.0], 1.2).unwrap(),
            });
        }
        let flat = t.blend(&ids).unwrap();
        let bvh = t.bvh_blend(&ids).unwrap();
        let region = Aabb::new([0.0; 3], [100.0; 3]);
        let l = t.lipschitz(flat, &region);
        assert!((l - t.lipschitz(bvh, &region)).abs() < 1e-3 * l);
        for k in 0..2000u64 {
            let h = |s| crate::math::unit(crate::math::hash(9, k, s, 0)) * 100.0;
            let p = [h(0), h(1), h(2)];
            let (a, b) = (t.eval(flat, p), t.eval(bvh, p));
            assert!((a - b).abs() < 1e-5, "{a} {b}");
            let q = add(p, [0.3, -0.2, 0.1]);
            let small = Aabb::new(p, q);
            let lb = t.lipschitz(bvh, &small);
            let d = crate::math::norm(sub(q, p));
            assert!((t.eval(bvh, q) - b).abs() <= lb * d + 1e-5);
        }
    }

    #[test]
    fn intervals_contain_the_field() {
        let hf = Heightfield::from_fn(30, 20, 10.0, 10.0, |x, y| {
            50.0 + 20.0 * ((x as f32) * 0.3).sin() + y as f32
        });
        let mut t = TerrainTree::new();
        let (h, _) = t.heightfield(&hf, 15.0, 30.0).unwrap();
        let s1 = t.sphere([100.0, 100.0, 60.0], 30.0, -2.0).unwrap();
        let e1 = t
            .ellipsoid([150.0, 80.0, 90.0], [20.0, 10.0, 15.0], 1.0)
            .unwrap();
        let bv = t.bvh_blend(&[s1, e1]).unwrap();
        let bl = t.blend(&[h, bv]).unwrap();
        let w = t.warp(e1, 3.0, 0.1, 1).unwrap();
        let root = t.union(bl, w).unwrap();
        for k in 0..300u64 {
            let r = |s| crate::math::unit(crate::math::hash(5, k, s, 0));
            let c = [r(0) * 290.0, r(1) * 190.0, r(2) * 150.0];
            let b = Aabb::new(c, add(c, [r(3) * 40.0, r(4) * 40.0, r(5) * 40.0]));
            let (lo, hi) = t.interval(root, &b);
            for m in 0..20u64 {
                let q = |s| crate::math::unit(crate::math::hash(6, k, m, s));
                let p = [
                    b.min[0] + q(0) * (b.max[0] - b.min[0]),
                    b.min[1] + q(1) * (b.max[1] - b.min[1]),
                    b.min[2] + q(2) * (b.max[2] - b.min[2]),
                ];
                let v = t.eval(root, p);
                assert!(v >= lo - 1e-5 && v <= hi + 1e-5, "{v} not in [{lo}, {hi}]");
            }
        }
    }

    #[test]
    fn warp_skips_the_noise_outside_its_box_without_changing_the_field() {
        let mut t = TerrainTree::new();
        let e1 = t
            .ellipsoid([150.0, 80.0, 90.0], [20.0, 10.0, 15.0], 1.0)
            .unwrap();
        let (amp, freq) = (6.0, 0.1);
        let w = t.warp(e1, amp, freq, 3).unwrap();
        let b = t.bbox(w);
        assert_eq!(b, t.bbox(e1).inflate(0.75 * amp));
        let mut inside = 0;
        for k in 0..4000u64 {
            let r = |s| crate::math::unit(crate::math::hash(9, k, s, 0));
            let p = [110.0 + r(0) * 80.0, 60.0 + r(1) * 40.0, 65.0 + r(2) * 50.0];
            // The definition: the child at the displaced point.
            let d = fbm3(3, mul(p, freq), 2);
            let want = t.eval(e1, add(p, mul(d, amp)));
            assert_eq!(t.eval(w, p), want, "at {p:?}");
            if !b.contains(p) {
                assert_eq!(want, 0.0, "warp box too small at {p:?}");
            } else if want > 0.0 {
                inside += 1;
            }
        }
        assert!(inside > 100, "{inside}");
    }

    #[test]
    fn analytic_gradient_matches_central_differences() {
        let hf = Heightfield::from_fn(30, 20, 10.0, 10.0, |x, y| {
            50.0 + 20.0 * ((x as f32) * 0.3).sin() + y as f32
        });
        let mut t = TerrainTree::new();
        let (h, _) = t.heightfield(&hf, 15.0, 30.0).unwrap();
        let s1 = t.sphere([100.0, 100.0, 60.0], 30.0, -2.0).unwrap();
        let c1 = t
            .capsule([50.0, 50.0, 60.0], [120.0, 80.0, 70.0], 12.0, -1.5)
            .unwrap();
        let e1 = t
            .ellipsoid([150.0, 80.0, 90.0], [20.0, 10.0, 15.0], 1.0)
            .unwrap();
        let k1 = t
            .cone([200.0, 60.0, 60.0], [200.0, 60.0, 100.0], 15.0, 5.0, 1.0)
            .unwrap();
        let bv = t.bvh_blend(&[s1, c1]).unwrap();
        let bl = t.blend(&[h, bv]).unwrap();
        let sm = t.smooth_blend(e1, k1, 3.0).unwrap();
        let w = t.warp(e1, 3.0, 0.1, 1).unwrap();
        let u = t.union(bl, sm).unwrap();
        let d = t.difference(u, w).unwrap();
        let root = t.intersection(d, h).unwrap();
        let (mut n, mut worst) = (0, 0.0f32);
        for k in 0..4000u64 {
            let r = |s| crate::math::unit(crate::math::hash(8, k, s, 0));
            let p = [r(0) * 290.0, r(1) * 190.0, 20.0 + r(2) * 100.0];
            let (v, g) = t.eval_grad(root, p, 1e-3);
            assert!((v - t.eval(root, p)).abs() < 1e-5);
            let mut fd = [0.0; 3];
            let hh = 1e-2;
            for a in 0..3 {
                let (mut p1, mut p2) = (p, p);
                p1[a] += hh;
                p2[a] -= hh;
                fd[a] = (t.eval(root, p1) - t.eval(root, p2)) / (2.0 * hh);
            }
            let err = crate::math::norm(sub(g, fd));
            let scale = crate::math::norm(fd).max(1e-3);
            // Kinks (CSG switches, grid lines, clamps) can sit between the FD samples.
            if err > 0.05 * scale + 1e-4 {
                worst = worst.max(err / scale);
                n += 1;
            }
        }
        assert!(n < 40, "{n} points disagree (worst relative {worst})");
    }

    #[test]
    fn errors_name_the_parameter() {
        let mut t = TerrainTree::new();
        let e = t.sphere([0.0; 3], -1.0, 1.0).unwrap_err();
        assert!(e.to_string().contains("sphere.radius"));
        assert!(t.union(NodeId(5), NodeId(6)).is_err());
        assert!(t.smooth_blend(NodeId(0), NodeId(0), 0.5).is_err());
    }
}
