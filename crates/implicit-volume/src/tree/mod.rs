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

mod bounds;
mod eval;
mod heightfield;

pub use self::heightfield::DemFrame;

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
        /// Vertical frequency (at most `freq`: lower streaks the displacement vertically).
        zfreq: f32,
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
    /// Min/max pyramid of `data` for range queries over boxes (see [`HfPrim::height_range`]).
    mip: Vec<MipLevel>,
    /// Max pyramid of the cells' slope bounds (see [`HfPrim::lipschitz_over`]).
    slopes: MaxPyramid,
}

/// A max pyramid over a grid: `levels[0]` the values, `levels[k]` the max of each
/// `2^k x 2^k` block.
#[derive(Debug, Clone, Default)]
struct MaxPyramid {
    levels: Vec<(usize, usize, Vec<f32>)>,
}

/// One level of a min/max pyramid: `(min, max)` over blocks of `2^k x 2^k` DEM nodes.
#[derive(Debug, Clone)]
struct MipLevel {
    w: usize,
    h: usize,
    range: Vec<(f32, f32)>,
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
        Error::check_node("node id", id.0, self.nodes.len())
    }

    /// The children of a `Node::Blend { first, count }`.
    fn blended(&self, first: u32, count: u32) -> &[u32] {
        &self.children[first as usize..(first + count) as usize]
    }

    /// Sphere primitive: centre `c`, support radius `r`, energy `e` (negative carves).
    pub fn sphere(&mut self, c: V3, r: f32, e: f32) -> Result<NodeId> {
        fin("sphere.center", &c)?;
        Error::check_positive("sphere.radius", r)?;
        fin("sphere.energy", &[e])?;
        Ok(self.push(Node::Sphere { c, r, e }))
    }
    /// Capsule primitive: segment `a`-`b`, support radius `r`, energy `e`.
    pub fn capsule(&mut self, a: V3, b: V3, r: f32, e: f32) -> Result<NodeId> {
        fin("capsule.ends", &[a[0], a[1], a[2], b[0], b[1], b[2], e])?;
        Error::check_positive("capsule.radius", r)?;
        Ok(self.push(Node::Capsule { a, b, r, e }))
    }
    /// Cone primitive: axis `a`-`b` with support radius `ra` at `a` and `rb` at `b`.
    pub fn cone(&mut self, a: V3, b: V3, ra: f32, rb: f32, e: f32) -> Result<NodeId> {
        fin("cone.ends", &[a[0], a[1], a[2], b[0], b[1], b[2], e])?;
        Error::check_positive("cone.ra", ra)?;
        Error::check_positive("cone.rb", rb)?;
        Error::check_positive("cone.length", crate::math::norm(sub(b, a)))?;
        Ok(self.push(Node::Cone { a, b, ra, rb, e }))
    }
    /// Axis-aligned ellipsoid primitive: centre `c`, support semi-axes `axes`, energy `e`.
    pub fn ellipsoid(&mut self, c: V3, axes: V3, e: f32) -> Result<NodeId> {
        fin("ellipsoid.center", &c)?;
        for a in axes {
            Error::check_positive("ellipsoid.axes", a)?;
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
        Error::check_positive("transition", transition)?;
        Error::check_positive("depth", depth)?;
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
            mip: Vec::new(),
            slopes: MaxPyramid::default(),
        }
        .with_mip();
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
    /// CSG union of all `items`, folded in order (`union(union(a, b), c)`, ...); refused when
    /// empty.
    pub fn union_all(&mut self, items: &[NodeId]) -> Result<NodeId> {
        let (&first, rest) = items
            .split_first()
            .ok_or_else(|| Error::param("union_all.items", 0, "must not be empty"))?;
        rest.iter().try_fold(first, |acc, &q| self.union(acc, q))
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
        self.streaked_warp(child, amp, freq, freq, seed)
    }

    /// Noise warp stretched vertically: the child is evaluated at `p + amp * fbm3(q)` with
    /// `q = (x freq, y freq, z zfreq)`, `0 < zfreq <= freq`. The displacement changes slowly
    /// with height, so a surface gets vertical flutes and rills rather than round creases.
    pub fn streaked_warp(
        &mut self,
        child: NodeId,
        amp: f32,
        freq: f32,
        zfreq: f32,
        seed: u32,
    ) -> Result<NodeId> {
        Error::check_positive("warp.amp", amp)?;
        Error::check_positive("warp.freq", freq)?;
        Error::check_positive("warp.zfreq", zfreq)?;
        if zfreq > freq {
            return Err(Error::param(
                "warp.zfreq",
                zfreq,
                "must be at most warp.freq",
            ));
        }
        let child = self.id(child)?;
        let bx = self.warp_boxes.len() as u32;
        self.warp_boxes
            .push(self.bbox_of(child).inflate(0.75 * amp));
        Ok(self.push(Node::Warp {
            child,
            amp,
            freq,
            zfreq,
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
            Node::Blend { first, count } => self
                .blended(first, count)
                .iter()
                .fold(Aabb::empty(), |b, &c| b.union(&self.bbox_of(c))),
            Node::Bvh { bbox, .. } => bbox,
            Node::Union { a, b } | Node::SmoothBlend { a, b, .. } => {
                self.bbox_of(a).union(&self.bbox_of(b))
            }
            // `min(a, b)` is at most 0 (air) outside either box: a flat cap cutting a body
            // keeps the body's box, not the cap's.
            Node::Intersection { a, b } => self.bbox_of(a).intersection(&self.bbox_of(b)),
            Node::Difference { a, .. } => self.bbox_of(a),
            Node::Warp { bx, .. } => self.warp_boxes[bx as usize],
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
            heightfield_bytes: self.hfs.iter().map(HfPrim::bytes).sum(),
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
mod tests;
