//! Scenes: an implicitised DEM, a geology tree and the landform sub-trees attached to it by the
//! generators of paper section 4 ([`SceneBuilder`]).
//!
//! The builder's core (implicitisation, surface samples, weathering) is here; its effects live
//! in `erosion.rs` (sea caves, sea cliffs, wind, rain), `karst.rs` (invasion percolation) and
//! `hoodoos.rs`, `arches.rs`, `landforms.rs` (a hand-placed arch), `islands.rs` (floating islands), `undercuts.rs`; their settings in
//! `settings.rs`.

mod arches;
mod erosion;
mod hoodoos;
mod islands;
mod karst;
mod landforms;
mod settings;
mod undercuts;

pub use islands::{clark_evans, nearest_neighbour_cv, nearest_neighbour_distances};
pub use settings::*;

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use rustc_hash::FxHashMap;

use rayon::prelude::*;
use relief_heightfield::Heightfield;

use crate::error::{Error, Result};
use crate::geology::Geology;
use crate::math::{Aabb, V3, add, hash, mul, norm, normalize, sub, unit};
use crate::tree::{DemFrame, NodeId, THRESHOLD, TerrainTree, TreeStats};

/// Paper section 4.1: erosion intensity `e(rho, sigma) = sigma (1 - rho)(1 - beta) + sigma beta`.
#[inline]
pub fn erosion_intensity(rho: f32, sigma: f32, beta: f32) -> f32 {
    sigma * (1.0 - rho) * (1.0 - beta) + sigma * beta
}

/// Where an effect applies: a painted per-cell mask over the DEM and/or a 3D box. Both given:
/// the weight is the mask's inside the box and 0 outside.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Region {
    /// Per-cell weights in `[0, 1]`, row-major like the DEM (`width * height` values).
    pub mask: Option<Vec<f32>>,
    /// A 3D box in scene coordinates.
    pub bbox: Option<Aabb>,
}

impl Region {
    /// The whole scene with weight 1.
    pub fn everywhere() -> Self {
        Self::default()
    }
    /// Only inside `b`.
    pub fn in_box(b: Aabb) -> Self {
        Self {
            mask: None,
            bbox: Some(b),
        }
    }
    pub(crate) fn check(&self, f: &DemFrame) -> Result<()> {
        if let Some(m) = &self.mask {
            if m.len() != f.width * f.height {
                return Err(Error::param(
                    "region.mask length",
                    m.len(),
                    "must equal DEM width * height",
                ));
            }
            if let Some(v) = m.iter().find(|v| !(0.0..=1.0).contains(*v)) {
                return Err(Error::param("region.mask value", v, "must be in [0, 1]"));
            }
        }
        if let Some(b) = &self.bbox
            && (!b.is_finite() || b.is_empty())
        {
            return Err(Error::param(
                "region.bbox",
                format!("{b:?}"),
                "must be finite and non-empty",
            ));
        }
        Ok(())
    }
    /// Weight of the effect at `p` (0 = no effect).
    pub fn weight(&self, f: &DemFrame, p: V3) -> f32 {
        if let Some(b) = &self.bbox
            && !b.contains(p)
        {
            return 0.0;
        }
        match &self.mask {
            Some(m) => match f.cell(p) {
                Some((j, i)) => m[i * f.width + j],
                None => 0.0,
            },
            None => 1.0,
        }
    }
}

/// Builds a [`Scene`]: implicitises a DEM, then runs effects that add sub-trees.
#[derive(Debug, Clone)]
pub struct SceneBuilder {
    tree: TerrainTree,
    hf: NodeId,
    frame: DemFrame,
    geology: Geology,
    dem: Vec<f32>,
    negatives: Vec<NodeId>,
    /// Carvings with crisp edges (a CSG difference, not blended): walls that stand steep
    /// with a sharp rim, such as a hoodoo amphitheatre's.
    cuts: Vec<NodeId>,
    positives: Vec<NodeId>,
    /// Carving spheres' centres and radii, kept for reports and tests.
    carved: Vec<(V3, f32, bool)>,
    /// Smallest length an effect accepts: 1e-5 of the scene's coordinate magnitude (a metre
    /// at 100 km, about 80 f32 ulps; lengths are also at most `1e7 min_len`), so no primitive
    /// degenerates in f32.
    min_len: f32,
    /// Node stride of the site searches (hoodoos, arches): 1 on a DEM's own cells, the
    /// interpolation factor on a DEM interpolated finer ([`SceneBuilder::set_site_stride`]).
    site_stride: usize,
}

/// Length of a wind or rain weathering groove in support radii (see
/// [`SceneBuilder::groove_axis`]): samples about one radius apart along a contour overlap into
/// one continuous groove.
const GROOVE_LENGTH: f32 = 2.5;

/// Poisson elimination in order: keeps a point if no kept point is closer than `r`.
fn poisson_filter(points: &[V3], r: f32, mut keep: impl FnMut(usize) -> bool) -> Vec<usize> {
    let mut grid: FxHashMap<(i32, i32, i32), Vec<V3>> = FxHashMap::default();
    let key = |p: V3| {
        (
            (p[0] / r).floor() as i32,
            (p[1] / r).floor() as i32,
            (p[2] / r).floor() as i32,
        )
    };
    let mut out = Vec::new();
    for (k, &p) in points.iter().enumerate() {
        let (a, b, c) = key(p);
        let mut ok = true;
        'n: for da in -1..=1 {
            for db in -1..=1 {
                for dc in -1..=1 {
                    if let Some(v) = grid.get(&(a + da, b + db, c + dc))
                        && v.iter().any(|q| norm(sub(*q, p)) < r)
                    {
                        ok = false;
                        break 'n;
                    }
                }
            }
        }
        if ok && keep(k) {
            grid.entry((a, b, c)).or_default().push(p);
            out.push(k);
        }
    }
    out
}

impl SceneBuilder {
    /// [`check_len`](Self::check_len) of every `(name, value)` in turn.
    fn check_lens(&self, lens: &[(&'static str, f32)]) -> Result<()> {
        lens.iter().try_for_each(|&(n, v)| self.check_len(n, v))
    }

    fn check_len(&self, name: &'static str, v: f32) -> Result<()> {
        Error::check_positive(name, v)?;
        if name != "energy" && v < self.min_len {
            return Err(Error::param(
                name,
                v,
                "too small for the scene's coordinates (below 1e-5 of its extent)",
            ));
        }
        if name != "energy" && v > 1e7 * self.min_len {
            return Err(Error::param(
                name,
                v,
                "too large for the scene (above 100 times its extent)",
            ));
        }
        Ok(())
    }

    /// Implicitises `hf` (complete, no voids) with the geology `geology`.
    pub fn new(hf: &Heightfield, geology: Geology, settings: &ImplicitizeSettings) -> Result<Self> {
        let mut tree = TerrainTree::new();
        let (cx, cy) = hf.cell_size();
        let transition = if settings.transition == 0.0 {
            2.0 * cx.max(cy) as f32
        } else {
            settings.transition
        };
        let (node, frame) = tree.heightfield(hf, transition, settings.depth)?;
        let bb = tree.bbox(node);
        let mag = bb
            .min
            .iter()
            .chain(&bb.max)
            .fold(1.0f32, |m, v| m.max(v.abs()));
        Ok(Self {
            min_len: 1e-5 * mag,
            tree,
            hf: node,
            frame,
            geology,
            dem: hf.as_slice().to_vec(),
            negatives: Vec::new(),
            cuts: Vec::new(),
            positives: Vec::new(),
            carved: Vec::new(),
            site_stride: 1,
        })
    }

    /// Searches landform sites (hoodoos, arches) on every `k`-th node along each axis (`k >=
    /// 1`): on a DEM interpolated `k` times finer (stepped by its strata) the searches keep
    /// the cost and the node spacing of the DEM's own cells, and still see the stepped ground.
    pub fn set_site_stride(&mut self, k: usize) {
        self.site_stride = k.max(1);
    }

    /// The DEM's frame in scene coordinates.
    pub fn frame(&self) -> DemFrame {
        self.frame
    }
    /// The geology tree.
    pub fn geology(&self) -> &Geology {
        &self.geology
    }
    /// Mutable access to the terrain tree, to add hand-made sub-trees with
    /// [`SceneBuilder::add_matter`] / [`SceneBuilder::add_carving`].
    pub fn tree_mut(&mut self) -> &mut TerrainTree {
        &mut self.tree
    }
    /// Blends a hand-made sub-tree with negative energy into the terrain (carving).
    pub fn add_carving(&mut self, id: NodeId) {
        self.negatives.push(id);
    }
    /// Unions a hand-made sub-tree with the terrain (adding matter).
    pub fn add_matter(&mut self, id: NodeId) {
        self.positives.push(id);
    }
    /// Every carving sphere placed by the generators: (centre, support radius, is-karst).
    pub fn carvings(&self) -> &[(V3, f32, bool)] {
        &self.carved
    }

    /// Implicitisation deviation: at up to `max_samples` interior DEM nodes (a regular
    /// stride), the root of `f = T` of the heightfield primitive alone is found by bisection
    /// along the vertical and compared with the DEM sample.
    pub fn implicitization_deviation(&self, max_samples: usize) -> Deviation {
        let f = self.frame;
        let interior = (f.width.saturating_sub(2)) * (f.height.saturating_sub(2));
        if interior == 0 || max_samples == 0 {
            return Deviation::default();
        }
        let stride = ((interior as f64 / max_samples as f64).sqrt().ceil() as usize).max(1);
        let mut pts = Vec::new();
        for i in (1..f.height - 1).step_by(stride) {
            for j in (1..f.width - 1).step_by(stride) {
                pts.push((j, i));
            }
        }
        let floor = self.tree.dem_floor(self.hf).unwrap_or(f32::NEG_INFINITY);
        let devs: Vec<f32> = pts
            .par_iter()
            .map(|&(j, i)| {
                let z = self.dem_at(j, i);
                let p = f.node(j, i, z);
                // Inside half-way to the floor, air above the DEM's top.
                let d = 0.5 * (z - floor).min(1e4);
                let (mut lo, mut hi) = (z - d, z + d);
                for _ in 0..48 {
                    let m = 0.5 * (lo + hi);
                    if self.tree.eval(self.hf, [p[0], p[1], m]) > THRESHOLD {
                        lo = m;
                    } else {
                        hi = m;
                    }
                }
                (0.5 * (lo + hi) - z).abs()
            })
            .collect();
        let max = devs.iter().cloned().fold(0.0, f32::max);
        let mean = (devs.iter().map(|&d| d as f64).sum::<f64>() / devs.len() as f64) as f32;
        Deviation {
            max,
            mean,
            samples: devs.len(),
        }
    }

    /// Bilinear DEM elevation at scene `(x, y)`.
    pub fn ground(&self, x: f32, y: f32) -> f32 {
        self.tree.dem_height(self.hf, x, y).unwrap_or(0.0)
    }

    fn dem_at(&self, j: usize, i: usize) -> f32 {
        self.dem[i * self.frame.width + j]
    }

    fn slope_normal(&self, j: usize, i: usize) -> V3 {
        let f = self.frame;
        let (j0, j1) = (j.saturating_sub(1), (j + 1).min(f.width - 1));
        let (i0, i1) = (i.saturating_sub(1), (i + 1).min(f.height - 1));
        let dzdx = (self.dem_at(j1, i) - self.dem_at(j0, i)) / ((j1 - j0).max(1) as f32 * f.cx);
        // Rows grow southwards, y northwards.
        let dzdy = (self.dem_at(j, i0) - self.dem_at(j, i1)) / ((i1 - i0).max(1) as f32 * f.cy);
        normalize([-dzdx, -dzdy, 1.0])
    }

    /// Candidate points on (within one cell of) the DEM surface, `spacing` apart on average,
    /// including points spread up steep cells so cliffs get samples too. Deterministic.
    fn surface_candidates(&self, spacing: f32, seed: u64, zband: Option<(f32, f32)>) -> Vec<V3> {
        let f = self.frame;
        let per_xy = ((f.cx * f.cy) / (spacing * spacing)).ceil().max(1.0) as usize;
        let rows: Vec<Vec<V3>> = (0..f.height - 1)
            .into_par_iter()
            .map(|i| {
                let mut out = Vec::new();
                for j in 0..f.width - 1 {
                    let (lo, hi) = self.cell_range(j, i);
                    if let Some((a, b)) = zband
                        && (hi < a || lo > b)
                    {
                        continue;
                    }
                    let steep = hi - lo > f.cx.min(f.cy);
                    let n = per_xy * (1 + ((hi - lo) / spacing) as usize).min(32);
                    for k in 0..n {
                        let h = |s| unit(hash(seed, (i * f.width + j) as u64, k as u64, s));
                        let base = f.node(j, i + 1, 0.0);
                        let (x, y) = (base[0] + h(0) * f.cx, base[1] + h(1) * f.cy);
                        let z = if steep {
                            lo + h(2) * (hi - lo)
                        } else {
                            self.ground(x, y)
                        };
                        if let Some((a, b)) = zband
                            && (z < a || z > b)
                        {
                            continue;
                        }
                        out.push([x, y, z]);
                    }
                }
                out
            })
            .collect();
        let mut pts: Vec<V3> = rows.into_iter().flatten().collect();
        // Shuffle deterministically so the Poisson elimination has no directional bias.
        let mut keyed: Vec<(u64, V3)> = pts
            .drain(..)
            .enumerate()
            .map(|(k, p)| (hash(seed ^ 0xABCD, k as u64, 0, 0), p))
            .collect();
        keyed.sort_by_key(|x| x.0);
        keyed.into_iter().map(|x| x.1).collect()
    }

    /// Lowest and highest DEM sample of cell `(j, i)` (its four corner nodes).
    fn cell_range(&self, j: usize, i: usize) -> (f32, f32) {
        let zs = [
            self.dem_at(j, i),
            self.dem_at(j + 1, i),
            self.dem_at(j, i + 1),
            self.dem_at(j + 1, i + 1),
        ];
        let lo = zs.iter().cloned().fold(f32::INFINITY, f32::min);
        let hi = zs.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
        (lo, hi)
    }

    /// Number of surface samples a weathering effect (sea, wind, rain) at `spacing` metres
    /// would consider on this DEM, in the cells reaching into `zband` (all without one): what
    /// its cost grows with.
    pub fn candidate_count(&self, spacing: f32, zband: Option<(f32, f32)>) -> f64 {
        let f = self.frame;
        let per_xy = ((f.cx as f64 * f.cy as f64) / (spacing as f64 * spacing as f64))
            .ceil()
            .max(1.0);
        let mut n = 0.0;
        for i in 0..f.height - 1 {
            for j in 0..f.width - 1 {
                let (lo, hi) = self.cell_range(j, i);
                if let Some((a, b)) = zband
                    && (hi < a || lo > b)
                {
                    continue;
                }
                n += per_xy * (1.0 + ((hi - lo) / spacing).floor() as f64).min(32.0);
            }
        }
        n
    }

    /// [`Error::param`] on `spacing` when a surface effect at that spacing would consider
    /// more than 2^22 samples ([`SceneBuilder::candidate_count`]).
    fn check_candidates(&self, spacing: f32, zband: Option<(f32, f32)>) -> Result<()> {
        if self.candidate_count(spacing, zband) > (1u64 << 22) as f64 {
            return Err(Error::param(
                "spacing",
                spacing,
                "too small for this DEM: more than 2^22 candidate samples",
            ));
        }
        Ok(())
    }

    /// Places negative spheres at Poisson samples with energy from `e(rho, sigma)`.
    fn weather(
        &mut self,
        w: &Weathering,
        region: &Region,
        zband: Option<(f32, f32)>,
        groove: bool,
        stress: impl Fn(&Self, V3) -> f32 + Sync,
    ) -> Result<(EffectReport, Vec<(V3, f32)>)> {
        w.check(self.min_len)?;
        region.check(&self.frame)?;
        self.check_candidates(w.spacing, zband)?;
        let cand = self.surface_candidates(w.spacing, w.seed, zband);
        let kept = poisson_filter(&cand, w.spacing, |_| true);
        let me = &*self;
        let energies: Vec<(V3, f32)> = kept
            .par_iter()
            .map(|&k| {
                let p = cand[k];
                let wgt = region.weight(&me.frame, p);
                if wgt <= 0.0 {
                    return (p, 0.0);
                }
                let sigma = (stress(me, p) * wgt).clamp(0.0, 1.0);
                (
                    p,
                    erosion_intensity(me.geology.resistance(p), sigma, w.beta),
                )
            })
            .collect();
        let mut report = EffectReport {
            candidates: kept.len(),
            primitives: 0,
            ..Default::default()
        };
        let mut placed = Vec::new();
        for &(p, e) in &energies {
            if e < w.threshold || e <= 0.0 {
                continue;
            }
            let id = if groove {
                let (a, b) = self.groove_axis(p, w.radius);
                self.carved.push((mul(add(a, b), 0.5), w.radius, false));
                self.tree.capsule(a, b, w.radius, -w.energy * e)?
            } else {
                // With a height band (sea erosion), the sphere's nominal hole (0.7 of its
                // support) stops at the band's floor: a low shore (the 1-2 m coastal fringe of
                // SRTM next to its flat 0 m sea) is planed down to a platform just under the
                // water, not dug into trenches a radius deep under it.
                let p = match zband {
                    Some((lo, _)) => [p[0], p[1], p[2].max(lo + 0.7 * w.radius)],
                    None => p,
                };
                self.carved.push((p, w.radius, false));
                self.tree.sphere(p, w.radius, -w.energy * e)?
            };
            self.negatives.push(id);
            report.primitives += 1;
            placed.push((p, e));
        }
        Ok((report, placed))
    }

    /// Axis of a weathering groove at the surface sample `p` (wind and rain): a horizontal
    /// segment [`GROOVE_LENGTH`] radii long along the contour line of the DEM (so on a cliff it
    /// runs along the strata), its centre moved up or down by at most a third of the radius
    /// to the softest rock nearby (neighbouring grooves in one soft stratum line up and merge
    /// into a continuous undercut) and a quarter radius into the face (undercut, not a dent).
    fn groove_axis(&self, p: V3, r: f32) -> (V3, V3) {
        let f = self.frame;
        let (j, i) = f.cell(p).unwrap_or((0, 0));
        let n = self.slope_normal(j, i);
        let h = (n[0] * n[0] + n[1] * n[1]).sqrt();
        // Contour direction; on flat ground (no contour) a fixed one: the stress there is
        // near zero anyway for wind and rain.
        let (t, inward) = if h > 1e-4 {
            ([-n[1] / h, n[0] / h, 0.0], [-n[0] / h, -n[1] / h, 0.0])
        } else {
            ([1.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        };
        let mut best = (self.geology.resistance(p), 0.0f32);
        for k in [-2.0f32, -1.0, 1.0, 2.0] {
            let dz = k / 6.0 * r;
            let rho = self.geology.resistance([p[0], p[1], p[2] + dz]);
            if rho < best.0 - 1e-4 {
                best = (rho, dz);
            }
        }
        let c = add(add(p, [0.0, 0.0, best.1]), mul(inward, 0.25 * r));
        let half = 0.5 * GROOVE_LENGTH * r;
        (add(c, mul(t, -half)), add(c, mul(t, half)))
    }

    /// Horizontal distance (m) from every DEM cell to the nearest cell at or below `level` (sea),
    /// with `connected` only those connected to the DEM's border (two-pass chamfer transform).
    fn distance_to_sea(&self, level: f32, connected: bool) -> Vec<f32> {
        let f = self.frame;
        let (w, h) = (f.width, f.height);
        let mut d: Vec<f32> = if connected {
            border_connected(&self.dem, w, h, level)
                .into_iter()
                .map(|s| if s { 0.0 } else { f32::INFINITY })
                .collect()
        } else {
            self.dem
                .iter()
                .map(|&z| if z <= level { 0.0 } else { f32::INFINITY })
                .collect()
        };
        let dd = (f.cx * f.cx + f.cy * f.cy).sqrt();
        let steps_fwd = [
            (-1i32, 0i32, f.cx),
            (0, -1, f.cy),
            (-1, -1, dd),
            (1, -1, dd),
        ];
        for i in 0..h {
            for j in 0..w {
                for &(dj, di, c) in &steps_fwd {
                    let (jj, ii) = (j as i32 + dj, i as i32 + di);
                    if jj >= 0 && ii >= 0 && (jj as usize) < w {
                        let v = d[ii as usize * w + jj as usize] + c;
                        if v < d[i * w + j] {
                            d[i * w + j] = v;
                        }
                    }
                }
            }
        }
        for i in (0..h).rev() {
            for j in (0..w).rev() {
                for &(dj, di, c) in &steps_fwd {
                    let (jj, ii) = (j as i32 - dj, i as i32 - di);
                    if jj >= 0 && (jj as usize) < w && (ii as usize) < h {
                        let v = d[ii as usize * w + jj as usize] + c;
                        if v < d[i * w + j] {
                            d[i * w + j] = v;
                        }
                    }
                }
            }
        }
        d
    }

    /// Assembles the scene: `union(difference(blend(heightfield, carvings), cuts), matter)`.
    /// With `use_bvh` the carvings, the cuts and the matter are organised in BVHs; without, in
    /// flat n-ary blends (every primitive is visited by each query: for comparisons only).
    pub fn build(mut self, use_bvh: bool) -> Result<Scene> {
        let mut root = self.hf;
        let mut upper = self.hf;
        if !self.negatives.is_empty() {
            if use_bvh {
                let n = self.tree.bvh_blend(&self.negatives)?;
                root = self.tree.blend(&[root, n])?;
            } else {
                let mut all = vec![root];
                all.extend_from_slice(&self.negatives);
                root = self.tree.blend(&all)?;
            }
        }
        if !self.cuts.is_empty() {
            let c = group(&mut self.tree, &self.cuts, use_bvh)?;
            root = self.tree.difference(root, c)?;
        }
        if !self.positives.is_empty() {
            let p = group(&mut self.tree, &self.positives, use_bvh)?;
            root = self.tree.union(root, p)?;
            upper = self.tree.union(self.hf, p)?;
        }
        let mut scene = Scene::new(self.tree, root, self.geology, Some((self.hf, self.frame)))?;
        scene.upper = Some(upper);
        Ok(scene)
    }
}

/// `items` summed into one node: a BVH with `use_bvh`, else a flat n-ary blend.
fn group(tree: &mut TerrainTree, items: &[NodeId], use_bvh: bool) -> Result<NodeId> {
    if use_bvh {
        tree.bvh_blend(items)
    } else {
        tree.blend(items)
    }
}

/// A terrain tree with its root and geology: the field to mesh, render and query.
#[derive(Debug, Clone)]
pub struct Scene {
    tree: TerrainTree,
    root: NodeId,
    geology: Geology,
    dem: Option<(NodeId, DemFrame)>,
    bbox: Aabb,
    /// The tree without its carvings: `f <= upper` everywhere (carvings only lower the field),
    /// so `{f > T}` lies inside `{upper > T}`; the tracer steps by this cheaper bound in air.
    upper: Option<NodeId>,
}

impl Scene {
    /// A scene from any tree and root (e.g. hand-built shapes). `dem` names the heightfield
    /// primitive and its frame when there is one.
    pub fn new(
        tree: TerrainTree,
        root: NodeId,
        geology: Geology,
        dem: Option<(NodeId, DemFrame)>,
    ) -> Result<Self> {
        if root.0 as usize >= tree.stats().nodes {
            return Err(Error::param("root", root.0, "not a node of the tree"));
        }
        let bbox = tree.bbox(root);
        if !bbox.is_finite() || bbox.is_empty() {
            return Err(Error::param(
                "root bbox",
                format!("{bbox:?}"),
                "must be finite and non-empty",
            ));
        }
        Ok(Self {
            tree,
            root,
            geology,
            dem,
            bbox,
            upper: None,
        })
    }
    /// Upper bound `u >= f` from the tree without carvings, with its Lipschitz bound over
    /// `region`, when the scene was built by [`SceneBuilder::build`].
    pub fn upper_bound(&self, p: V3, region: &Aabb) -> Option<(f32, f32)> {
        let u = self.upper?;
        Some((self.tree.eval(u, p), self.tree.lipschitz(u, region)))
    }
    /// The Lipschitz bound over `region` of [`Scene::upper_bound`]'s tree (its value being
    /// [`Scene::upper_field`]).
    pub fn upper_lipschitz(&self, region: &Aabb) -> Option<f32> {
        Some(self.tree.lipschitz(self.upper?, region))
    }
    /// Upper end of a conservative range of `f` over `region`, from the carving-free tree when
    /// there is one (cheaper) or the whole tree: `<= T` proves `region` is air.
    pub fn max_over(&self, region: &Aabb) -> f32 {
        self.tree
            .interval(self.upper.unwrap_or(self.root), region)
            .1
    }
    /// Upper end of a conservative range of `f` over `region` from the whole tree, carvings
    /// included: `<= T` proves `region` is air inside a carved hollow.
    pub fn root_max_over(&self, region: &Aabb) -> f32 {
        self.tree.interval(self.root, region).1
    }
    /// Value of the carving-free upper bound at `p` (see [`Scene::upper_bound`]).
    pub fn upper_field(&self, p: V3) -> Option<f32> {
        self.upper.map(|u| self.tree.eval(u, p))
    }
    /// Field `f(p)`: matter where `f > T` ([`THRESHOLD`]).
    #[inline]
    pub fn field(&self, p: V3) -> f32 {
        self.tree.eval(self.root, p)
    }
    /// Whether `p` is inside matter.
    pub fn inside(&self, p: V3) -> bool {
        self.field(p) > THRESHOLD
    }
    /// Gradient of `f`: analytic through the tree ([`TerrainTree::eval_grad`]); central
    /// differences with step `h` (m) only inside cones and noise warps.
    pub fn gradient(&self, p: V3, h: f32) -> V3 {
        self.tree.eval_grad(self.root, p, h).1
    }
    /// Outward unit normal (`-grad f / |grad f|`).
    pub fn normal(&self, p: V3, h: f32) -> V3 {
        normalize(mul(self.gradient(p, h), -1.0))
    }
    /// Outward unit shading normal: [`Self::normal`] with the DEM surface's slopes
    /// interpolated from its nodes ([`TerrainTree::eval_shading_grad`]), so a render or a mesh
    /// shades the relief smoothly instead of as one facet per DEM cell.
    pub fn shading_normal(&self, p: V3, h: f32) -> V3 {
        normalize(mul(self.tree.eval_shading_grad(self.root, p, h).1, -1.0))
    }
    /// Conservative range of `f` over `region` (interval arithmetic through the tree).
    pub fn interval(&self, region: &Aabb) -> (f32, f32) {
        self.tree.interval(self.root, region)
    }
    /// Lipschitz bound of `f` over `region`.
    pub fn lipschitz(&self, region: &Aabb) -> f32 {
        self.tree.lipschitz(self.root, region)
    }
    /// Box outside which `f = 0` (air).
    pub fn bbox(&self) -> Aabb {
        self.bbox
    }
    /// Resistance `rho(p)` of the geology.
    pub fn resistance(&self, p: V3) -> f32 {
        self.geology.resistance(p)
    }
    /// The DEM's bilinear elevation at `(x, y)`, if the scene has a heightfield primitive.
    pub fn dem_height(&self, x: f32, y: f32) -> Option<f32> {
        let (id, _) = self.dem?;
        self.tree.dem_height(id, x, y)
    }
    /// Elevation of the implicitised DEM's closing floor, if the scene has one.
    pub fn dem_floor(&self) -> Option<f32> {
        let (id, _) = self.dem?;
        self.tree.dem_floor(id)
    }
    /// The DEM frame, if any.
    pub fn dem_frame(&self) -> Option<DemFrame> {
        self.dem.map(|d| d.1)
    }
    /// Node count and memory of the terrain tree.
    pub fn stats(&self) -> TreeStats {
        self.tree.stats()
    }
    /// The terrain tree and root.
    pub fn tree(&self) -> (&TerrainTree, NodeId) {
        (&self.tree, self.root)
    }
    /// The geology tree.
    pub fn geology(&self) -> &Geology {
        &self.geology
    }
}

/// Deviation of the implicitised DEM's surface `f = T` from the DEM samples.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Deviation {
    /// Largest absolute vertical distance (m).
    pub max: f32,
    /// Mean absolute vertical distance (m).
    pub mean: f32,
    /// Number of DEM nodes measured.
    pub samples: usize,
}

/// The samples at or below `level` connected to the DEM's border by 4-neighbour steps through
/// such samples (non-finite samples are never sea and block the fill).
pub fn border_connected_at_or_below(hf: &Heightfield, level: f32) -> Vec<bool> {
    border_connected(hf.as_slice(), hf.width(), hf.height(), level)
}

/// [`border_connected_at_or_below`] on a row-major `w x h` grid `z`.
pub(crate) fn border_connected(z: &[f32], w: usize, h: usize, level: f32) -> Vec<bool> {
    let low = |k: usize| z[k].is_finite() && z[k] <= level;
    let mut sea = vec![false; w * h];
    let mut stack = Vec::new();
    let seed = |k: usize, sea: &mut Vec<bool>, stack: &mut Vec<usize>| {
        if !sea[k] && low(k) {
            sea[k] = true;
            stack.push(k);
        }
    };
    for j in 0..w {
        seed(j, &mut sea, &mut stack);
        if h > 1 {
            seed((h - 1) * w + j, &mut sea, &mut stack);
        }
    }
    for i in 0..h {
        seed(i * w, &mut sea, &mut stack);
        if w > 1 {
            seed(i * w + w - 1, &mut sea, &mut stack);
        }
    }
    while let Some(k) = stack.pop() {
        let (i, j) = (k / w, k % w);
        if j > 0 {
            seed(k - 1, &mut sea, &mut stack);
        }
        if j + 1 < w {
            seed(k + 1, &mut sea, &mut stack);
        }
        if i > 0 {
            seed(k - w, &mut sea, &mut stack);
        }
        if i + 1 < h {
            seed(k + w, &mut sea, &mut stack);
        }
    }
    sea
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn erosion_intensity_matches_paper_constraints() {
        for beta in [0.0, 0.3, 1.0] {
            assert_eq!(erosion_intensity(0.4, 0.0, beta), 0.0);
            assert!((erosion_intensity(1.0, 1.0, beta) - beta).abs() < 1e-6);
            assert!((erosion_intensity(0.0, 1.0, beta) - 1.0).abs() < 1e-6);
        }
        assert!(erosion_intensity(0.2, 0.8, 0.2) > erosion_intensity(0.8, 0.8, 0.2));
    }

    /// With `connected`, a pit below the level inland is not sea (issue 19).
    #[test]
    fn distance_to_sea_skips_inland_pits_when_connected() {
        // Sea (0 m) on the western 4 columns, land at 20 m, a pit at -5 m at (12, 8).
        let hf = Heightfield::from_fn(16, 16, 10.0, 10.0, |x, y| match (x, y) {
            (x, _) if x < 4 => 0.0,
            (12, 8) => -5.0,
            _ => 20.0,
        });
        let geo = Geology::layered_default([80.0, 80.0, 10.0], 10.0, 1).unwrap();
        let b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
        let all = b.distance_to_sea(0.0, false);
        let sea = b.distance_to_sea(0.0, true);
        assert_eq!((all[8 * 16 + 12], sea[8 * 16 + 12]), (0.0, 90.0));
        assert_eq!((all[3], sea[3], sea[4]), (0.0, 0.0, 10.0));
    }
}
