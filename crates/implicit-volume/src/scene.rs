//! Scenes: an implicitised DEM, a geology tree and the landform sub-trees attached to it by the
//! generators of paper section 4 ([`SceneBuilder`]).

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

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

/// How the DEM is implicitised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImplicitizeSettings {
    /// Transition distance `r` of the heightfield primitive in metres; 0 = twice the larger
    /// cell size.
    pub transition: f32,
    /// Depth of the closing floor below the lowest DEM sample (m).
    pub depth: f32,
}
impl Default for ImplicitizeSettings {
    fn default() -> Self {
        Self {
            transition: 0.0,
            depth: 60.0,
        }
    }
}

/// Common parameters of the shallow (weathering) erosion of section 4.1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Weathering {
    /// Poisson-sphere radius between samples (m).
    pub spacing: f32,
    /// Support radius of each negative sphere (m).
    pub radius: f32,
    /// Energy scale: a sample gets energy `-energy * e(rho, sigma)`.
    pub energy: f32,
    /// `beta` of `e(rho, sigma)`: erosion of the hardest rock under full stress.
    pub beta: f32,
    /// Samples with `e` below this are discarded.
    pub threshold: f32,
    /// Seed.
    pub seed: u64,
}
impl Default for Weathering {
    fn default() -> Self {
        Self {
            spacing: 8.0,
            radius: 12.0,
            energy: 2.0,
            beta: 0.2,
            threshold: 0.1,
            seed: 1,
        }
    }
}
impl Weathering {
    fn check(&self, min_len: f32) -> Result<()> {
        for (n, v) in [
            ("spacing", self.spacing),
            ("radius", self.radius),
            ("energy", self.energy),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::param(n, v, "must be finite and > 0"));
            }
            if n != "energy" && !(min_len..=1e6 * min_len).contains(&v) {
                return Err(Error::param(
                    n,
                    v,
                    "out of scale with the scene (1e-4 to 100 times its extent)",
                ));
            }
        }
        for (n, v) in [("beta", self.beta), ("threshold", self.threshold)] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::param(n, v, "must be in [0, 1]"));
            }
        }
        Ok(())
    }
}

/// Sea erosion (figure 5): the stress `sigma` depends on the height above sea level (a bump
/// peaking at `peak` metres, zero below `-depth` and above `height`) times the accessibility
/// from the sea (1 at the shore, 0 at `reach` metres inland).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeaErosion {
    /// Sampling and energy parameters.
    pub weathering: Weathering,
    /// Sea level (m).
    pub sea_level: f32,
    /// Depth below sea level still eroded (m).
    pub depth: f32,
    /// Height above sea level still eroded (m).
    pub height: f32,
    /// Height above sea level of maximum stress (m), in `[-depth, height]`.
    pub peak: f32,
    /// Horizontal distance from the sea over which accessibility falls to 0 (m).
    pub reach: f32,
    /// Maximum number of sea caves dug inland from the most eroded samples.
    pub caves: usize,
    /// Length of each sea cave (m).
    pub cave_length: f32,
    /// Erosion passes: pass `k > 1` samples the *current* implicit surface (after the earlier
    /// passes' carvings) inland of the previous samples and carves there with the stress
    /// scaled by `0.8^(k-1)`, deepening notches into caves and arches (figure 4, left).
    pub iterations: usize,
}
impl Default for SeaErosion {
    fn default() -> Self {
        Self {
            weathering: Weathering::default(),
            sea_level: 0.0,
            depth: 4.0,
            height: 20.0,
            peak: 3.0,
            reach: 150.0,
            caves: 8,
            cave_length: 60.0,
            iterations: 1,
        }
    }
}

/// Sea cliffs: the shore is cut back `retreat` metres by columns of negative spheres from
/// below sea level up to the ground, each sphere's energy from `e(rho, sigma)` with `sigma`
/// falling with the distance from the sea. The energy is tuned so that soft strata are
/// removed and hard ones (`e` near `beta`) survive as ledges: a vertical, stepped cliff. This
/// assumes saturated rock (`f = 2T`) a little under the surface, i.e. a heightfield transition
/// ([`ImplicitizeSettings::transition`]) of about the sphere radius or less.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeaCliffs {
    /// Sea level (m).
    pub sea_level: f32,
    /// Depth below sea level cut (m).
    pub depth: f32,
    /// How far inland the shore retreats (m).
    pub retreat: f32,
    /// Support radius of the spheres (m); columns are about `0.75 radius` apart (a jittered grid).
    pub radius: f32,
    /// `beta` of `e(rho, sigma)`.
    pub beta: f32,
    /// Seed.
    pub seed: u64,
}
impl Default for SeaCliffs {
    fn default() -> Self {
        Self {
            sea_level: 0.0,
            depth: 3.0,
            retreat: 40.0,
            radius: 10.0,
            beta: 0.2,
            seed: 13,
        }
    }
}

/// Wind erosion: stress from exposure of the surface to a horizontal wind and from altitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindErosion {
    /// Sampling and energy parameters.
    pub weathering: Weathering,
    /// Direction the wind blows towards (x east, y north); need not be normalised.
    pub direction: [f32; 2],
}
impl Default for WindErosion {
    fn default() -> Self {
        Self {
            weathering: Weathering::default(),
            direction: [1.0, 0.0],
        }
    }
}

/// Rain erosion: stress grows with the slope (runoff), full at `full_slope_deg`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RainErosion {
    /// Sampling and energy parameters.
    pub weathering: Weathering,
    /// Slope (degrees) of full stress.
    pub full_slope_deg: f32,
}
impl Default for RainErosion {
    fn default() -> Self {
        Self {
            weathering: Weathering::default(),
            full_slope_deg: 40.0,
        }
    }
}

/// Karst by modified invasion percolation (paper section 4.2, figure 6).
///
/// Lengths are in metres. A carved step places a negative sphere whose *visible* passage
/// radius is `radius` (the support radius follows from the energy, see
/// [`KarstSettings::support_radius`]), shrunk down to `min_radius` until every test point on
/// the passage sphere lies in soft rock (`rho < rho0`), so passages follow the soft strata;
/// `sub_spheres` smaller spheres widen it horizontally. New candidates are `step` away in
/// directions of the lower hemisphere flattened to at most `vertical` (the sine of the dip),
/// following bedding planes as the authors' reference code does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KarstSettings {
    /// Carve only where `rho < rho0`.
    pub rho0: f32,
    /// Stop when the least resistant candidate (its perturbed resistance) is above this; must
    /// be reachable (below the hardest rock of the geology) to ever fire.
    pub rho_stop: f32,
    /// Range of the random perturbation of the resistance when ordering candidates.
    pub epsilon: f32,
    /// Visible passage radius (m).
    pub radius: f32,
    /// Smallest passage radius carved where the soft rock is thin (m); at least one meshing
    /// voxel for the passage to be seen.
    pub min_radius: f32,
    /// Energy scale: spheres get `-energy * e(rho, sigma)`.
    pub energy: f32,
    /// `beta` of `e(rho, sigma)`.
    pub beta: f32,
    /// Stress of the dissolution (`sigma`, scaled by the region weight).
    pub sigma: f32,
    /// Distance from a carved point to its new candidates (m).
    pub step: f32,
    /// Poisson-sphere radius: a candidate closer than this to a queued one is rejected (m).
    pub poisson_radius: f32,
    /// New candidate directions sampled per step.
    pub directions: usize,
    /// Largest sine of the dip of a new direction (0 = horizontal only, 1 = whole lower
    /// hemisphere).
    pub vertical: f32,
    /// Extra spheres scattered around each carved sphere (wider, rougher passages).
    pub sub_spheres: usize,
    /// Budget: maximum number of carving steps (the queue may run dry or the threshold stop
    /// the percolation before).
    pub budget: usize,
    /// Maximum number of initial sinkholes (the lowest first).
    pub max_sinkholes: usize,
    /// Maximum number of extra seeds on steep faces (resurgences on cliffs, as in the authors'
    /// karst scene), `cliff_spacing` apart.
    pub cliff_seeds: usize,
    /// Spacing of the cliff seeds (m).
    pub cliff_spacing: f32,
    /// Seed.
    pub seed: u64,
}
impl Default for KarstSettings {
    fn default() -> Self {
        Self {
            rho0: 0.5,
            rho_stop: 0.6,
            epsilon: 0.1,
            radius: 5.0,
            min_radius: 2.0,
            energy: 3.0,
            beta: 0.3,
            sigma: 1.0,
            step: 5.0,
            poisson_radius: 4.0,
            directions: 3,
            vertical: 0.3,
            sub_spheres: 2,
            budget: 5000,
            max_sinkholes: 64,
            cliff_seeds: 32,
            cliff_spacing: 50.0,
            seed: 7,
        }
    }
}

impl KarstSettings {
    /// Support radius of the sphere whose carved hole in solid rock (field `2T`) has the
    /// visible radius `a` at energy `energy * e`: `-energy e g(d^2/R^2) + 2T = T` at `d = a`.
    pub fn support_radius(&self, a: f32, e: f32) -> f32 {
        let k = (THRESHOLD / (self.energy * e).max(THRESHOLD + 1e-3)).cbrt();
        a / (1.0 - k).max(1e-3).sqrt()
    }
}

/// Why a karst percolation ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KarstStop {
    /// The budget of carving steps was used up.
    Budget,
    /// The least resistant candidate was harder than `rho_stop`.
    Threshold,
    /// The queue ran dry (every reachable soft pocket was visited).
    Exhausted,
}

/// Hoodoos (figure 3): stacked perturbed spheres on a cone, creased by a warp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoodooSettings {
    /// Number of hoodoos (fewer if the region has no room).
    pub count: usize,
    /// Height (m).
    pub height: f32,
    /// Base radius (m).
    pub radius: f32,
    /// Minimum distance between hoodoos (m).
    pub spacing: f32,
    /// Maximum ground slope (degrees) where a hoodoo may stand.
    pub max_slope_deg: f32,
    /// Smallest resistance of the caprock: sites without rock this hard near the hoodoo's top
    /// are skipped.
    pub cap_rho: f32,
    /// Seed.
    pub seed: u64,
}
impl Default for HoodooSettings {
    fn default() -> Self {
        Self {
            count: 5,
            height: 40.0,
            radius: 8.0,
            spacing: 40.0,
            max_slope_deg: 20.0,
            cap_rho: 0.55,
            seed: 3,
        }
    }
}

/// Natural arches: capsules along an arc between two feet, warped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArchSettings {
    /// Number of arches.
    pub count: usize,
    /// Distance between the feet (m).
    pub span: f32,
    /// Height of the arc above the higher foot (m).
    pub height: f32,
    /// Thickness (capsule radius, m).
    pub thickness: f32,
    /// Seed.
    pub seed: u64,
}
impl Default for ArchSettings {
    fn default() -> Self {
        Self {
            count: 2,
            span: 80.0,
            height: 35.0,
            thickness: 10.0,
            seed: 5,
        }
    }
}

/// Floating islands: an ellipsoidal top over an inverted cone, warped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IslandSettings {
    /// Number of islands.
    pub count: usize,
    /// Radius (m).
    pub radius: f32,
    /// Height of the island top above the local ground (m).
    pub altitude: f32,
    /// Seed.
    pub seed: u64,
}
impl Default for IslandSettings {
    fn default() -> Self {
        Self {
            count: 2,
            radius: 40.0,
            altitude: 120.0,
            seed: 11,
        }
    }
}

/// What an effect added.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EffectReport {
    /// Candidate samples considered.
    pub candidates: usize,
    /// Primitives added to the tree.
    pub primitives: usize,
    /// Landforms placed (hoodoos, arches, islands, caves; karst: carved steps).
    pub features: usize,
    /// Karst: length of the carved passages (carved steps times the step, m).
    pub length_m: f32,
    /// Karst: why the percolation ended.
    pub stop: Option<KarstStop>,
    /// Where the landforms were placed (hoodoo bases, arch middles, island centres, cave
    /// mouths; karst: the seeds).
    pub sites: Vec<V3>,
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
    positives: Vec<NodeId>,
    /// Carving spheres' centres and radii, kept for reports and tests.
    carved: Vec<(V3, f32, bool)>,
    /// Smallest length an effect accepts: 1e-4 of the scene's coordinate magnitude (lengths
    /// are also at most `1e6 min_len`), so no primitive degenerates in f32.
    min_len: f32,
}

fn check_pos(name: &'static str, v: f32) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::param(name, v, "must be finite and > 0"))
    }
}

/// Poisson elimination in order: keeps a point if no kept point is closer than `r`.
fn poisson_filter(points: &[V3], r: f32, mut keep: impl FnMut(usize) -> bool) -> Vec<usize> {
    let mut grid: HashMap<(i32, i32, i32), Vec<V3>> = HashMap::new();
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
    fn check_len(&self, name: &'static str, v: f32) -> Result<()> {
        check_pos(name, v)?;
        if name != "energy" && v < self.min_len {
            return Err(Error::param(
                name,
                v,
                "too small for the scene's coordinates (below 1e-4 of its extent)",
            ));
        }
        if name != "energy" && v > 1e6 * self.min_len {
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
            min_len: 1e-4 * mag,
            tree,
            hf: node,
            frame,
            geology,
            dem: hf.as_slice().to_vec(),
            negatives: Vec::new(),
            positives: Vec::new(),
            carved: Vec::new(),
        })
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
    pub fn implicitization_deviation(&self, max_samples: usize) -> crate::recipe::Deviation {
        let f = self.frame;
        let interior = (f.width.saturating_sub(2)) * (f.height.saturating_sub(2));
        if interior == 0 || max_samples == 0 {
            return crate::recipe::Deviation::default();
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
        crate::recipe::Deviation {
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
                    let zs = [
                        self.dem_at(j, i),
                        self.dem_at(j + 1, i),
                        self.dem_at(j, i + 1),
                        self.dem_at(j + 1, i + 1),
                    ];
                    let lo = zs.iter().cloned().fold(f32::INFINITY, f32::min);
                    let hi = zs.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
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

    /// Number of candidates [`Self::surface_candidates`] would generate (without a z band).
    fn candidate_count(&self, spacing: f32) -> f64 {
        let f = self.frame;
        let per_xy = ((f.cx as f64 * f.cy as f64) / (spacing as f64 * spacing as f64))
            .ceil()
            .max(1.0);
        let mut n = 0.0;
        for i in 0..f.height - 1 {
            for j in 0..f.width - 1 {
                let zs = [
                    self.dem_at(j, i),
                    self.dem_at(j + 1, i),
                    self.dem_at(j, i + 1),
                    self.dem_at(j + 1, i + 1),
                ];
                let lo = zs.iter().cloned().fold(f32::INFINITY, f32::min);
                let hi = zs.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
                n += per_xy * (1.0 + ((hi - lo) / spacing).floor() as f64).min(32.0);
            }
        }
        n
    }

    /// Places negative spheres at Poisson samples with energy from `e(rho, sigma)`.
    fn weather(
        &mut self,
        w: &Weathering,
        region: &Region,
        zband: Option<(f32, f32)>,
        stress: impl Fn(&Self, V3) -> f32 + Sync,
    ) -> Result<(EffectReport, Vec<(V3, f32)>)> {
        w.check(self.min_len)?;
        region.check(&self.frame)?;
        if self.candidate_count(w.spacing) > (1u64 << 22) as f64 {
            return Err(Error::param(
                "spacing",
                w.spacing,
                "too small for this DEM: more than 2^22 candidate samples",
            ));
        }
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
            let id = self.tree.sphere(p, w.radius, -w.energy * e)?;
            self.negatives.push(id);
            self.carved.push((p, w.radius, false));
            report.primitives += 1;
            placed.push((p, e));
        }
        Ok((report, placed))
    }

    /// Horizontal distance (m) from every DEM cell to the nearest cell at or below `level` (sea)
    /// (two-pass chamfer transform).
    fn distance_to_sea(&self, level: f32) -> Vec<f32> {
        let f = self.frame;
        let (w, h) = (f.width, f.height);
        let mut d: Vec<f32> = self
            .dem
            .iter()
            .map(|&z| if z <= level { 0.0 } else { f32::INFINITY })
            .collect();
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

    /// Sea erosion (section 4.1, figure 5), plus sea caves dug inland from the most eroded
    /// samples near sea level.
    pub fn sea_erosion(&mut self, s: &SeaErosion, region: &Region) -> Result<EffectReport> {
        for (n, v) in [
            ("depth", s.depth),
            ("height", s.height),
            ("reach", s.reach),
            ("cave_length", s.cave_length),
        ] {
            self.check_len(n, v)?;
        }
        if !s.sea_level.is_finite() {
            return Err(Error::param("sea_level", s.sea_level, "must be finite"));
        }
        if !(-s.depth..=s.height).contains(&s.peak) {
            return Err(Error::param("peak", s.peak, "must be in [-depth, height]"));
        }
        if s.cave_length / (0.5 * s.weathering.radius) > 4096.0 {
            return Err(Error::param(
                "cave_length",
                s.cave_length,
                "must be at most 2048 weathering radii",
            ));
        }
        if !(1..=8).contains(&s.iterations) {
            return Err(Error::param("iterations", s.iterations, "must be in 1..=8"));
        }
        let dist = self.distance_to_sea(s.sea_level);
        let frame = self.frame;
        let stress = |me: &Self, p: V3| {
            // A flat floor under water is not attacked by waves: only ground reaching up to the
            // sea level around the sample (shores, cliffs, skerries) is.
            let (u, v) = frame.to_grid(p);
            let (j, i) = (u.floor().max(0.0) as usize, v.floor().max(0.0) as usize);
            let (j1, i1) = ((j + 1).min(frame.width - 1), (i + 1).min(frame.height - 1));
            let top = [
                me.dem_at(j, i),
                me.dem_at(j1, i),
                me.dem_at(j, i1),
                me.dem_at(j1, i1),
            ]
            .into_iter()
            .fold(f32::NEG_INFINITY, f32::max);
            if top <= s.sea_level {
                return 0.0;
            }
            let hgt = p[2] - s.sea_level;
            let t = if hgt >= s.peak {
                (hgt - s.peak) / (s.height - s.peak).max(1e-3)
            } else {
                (s.peak - hgt) / (s.peak + s.depth).max(1e-3)
            };
            let band = if t < 1.0 { (1.0 - t * t).powi(2) } else { 0.0 };
            let acc = frame.cell(p).map_or(0.0, |(j, i)| {
                (1.0 - dist[i * frame.width + j] / s.reach).max(0.0)
            });
            band * acc
        };
        let band = Some((s.sea_level - s.depth, s.sea_level + s.height));
        let (mut report, mut placed) = self.weather(&s.weathering, region, band, stress)?;
        let inland = |p: V3| -> Option<V3> {
            let (j, i) = frame.cell(p)?;
            let (j0, j1) = (j.saturating_sub(1), (j + 1).min(frame.width - 1));
            let (i0, i1) = (i.saturating_sub(1), (i + 1).min(frame.height - 1));
            let gx = dist[i * frame.width + j1] - dist[i * frame.width + j0];
            let gy = dist[i0 * frame.width + j] - dist[i1 * frame.width + j];
            let g = (gx * gx + gy * gy).sqrt();
            (g.is_finite() && g > 0.0).then(|| [gx / g, gy / g, 0.0])
        };
        let r = s.weathering.radius;
        let w = &s.weathering;
        let mut all_placed = placed.clone();
        for pass in 1..s.iterations {
            // The current surface: the scene with every carving so far.
            let current = self.clone().build(true)?;
            let decay = 0.8f32.powi(pass as i32);
            let me = &*self;
            let next: Vec<Option<(V3, f32)>> = placed
                .par_iter()
                .enumerate()
                .map(|(k, &(p, _))| {
                    let dir = inland(p)?;
                    let h = |c: u64| unit(hash(w.seed, k as u64, pass as u64, 40 + c)) - 0.5;
                    let start = add(p, [0.0, 0.0, 0.4 * r * h(0)]);
                    // The nearest crossing of the current surface along inland, inland and
                    // down, down, and inland and up (the sample may sit in air left by the
                    // previous pass or still in rock).
                    let jit = [0.5 * h(1), 0.5 * h(2), 0.0];
                    let dirs = [
                        normalize(add(dir, jit)),
                        normalize(add(add(dir, jit), [0.0, 0.0, -0.7])),
                        normalize(add(jit, [0.0, 0.0, -1.0])),
                        normalize(add(add(dir, jit), [0.0, 0.0, 0.7])),
                    ];
                    let s_in = current.inside(start);
                    let mut hit = None;
                    'dirs: for d in dirs {
                        let mut a = 0.0f32;
                        for m in 1..=12 {
                            let t = m as f32 * 0.25 * r;
                            if current.inside(add(start, mul(d, t))) != s_in {
                                hit = Some((d, a, t));
                                break 'dirs;
                            }
                            a = t;
                        }
                    }
                    let (d, mut a, mut b) = hit?;
                    for _ in 0..12 {
                        let m = 0.5 * (a + b);
                        if current.inside(add(start, mul(d, m))) == s_in {
                            a = m;
                        } else {
                            b = m;
                        }
                    }
                    let q = add(start, mul(d, b));
                    let wgt = region.weight(&frame, q);
                    let sigma = (stress(me, q) * wgt * decay).clamp(0.0, 1.0);
                    let e = erosion_intensity(me.geology.resistance(q), sigma, w.beta);
                    (e >= w.threshold && e > 0.0).then_some((q, e))
                })
                .collect();
            let pts: Vec<(V3, f32)> = next.into_iter().flatten().collect();
            let keep = poisson_filter(
                &pts.iter().map(|x| x.0).collect::<Vec<_>>(),
                w.spacing,
                |_| true,
            );
            report.candidates += pts.len();
            placed = keep.into_iter().map(|k| pts[k]).collect();
            for &(q, e) in &placed {
                let id = self.tree.sphere(q, r, -w.energy * e)?;
                self.negatives.push(id);
                self.carved.push((q, r, false));
                report.primitives += 1;
            }
            all_placed.extend_from_slice(&placed);
            if placed.is_empty() {
                break;
            }
        }
        let placed = all_placed;
        // Sea caves: chains of carving spheres going inland (up the distance-to-sea gradient),
        // from the most eroded samples just above sea level.
        let mut best: Vec<(f32, usize)> = placed
            .iter()
            .enumerate()
            .filter(|(_, (p, _))| p[2] >= s.sea_level && p[2] <= s.sea_level + 0.5 * s.height)
            .map(|(k, (_, e))| (*e, k))
            .collect();
        best.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut mouths: Vec<V3> = Vec::new();
        for &(e, k) in &best {
            if mouths.len() >= s.caves {
                break;
            }
            let p = placed[k].0;
            if mouths.iter().any(|m| norm(sub(*m, p)) < s.cave_length) {
                continue;
            }
            let Some(mut dir) = inland(p) else {
                continue;
            };
            mouths.push(p);
            report.features += 1;
            report.sites.push(p);
            // A wandering passage: the heading turns by up to +-20 degrees a step and the
            // floor drifts a little, within the sea-erosion band.
            let n = (s.cave_length / (0.5 * r)).ceil() as usize;
            let mut c = p;
            for m in 1..=n {
                let t = m as f32 / n as f32;
                let h = |q: u64| unit(hash(w.seed, k as u64, m as u64, 90 + q)) - 0.5;
                let turn = 0.7 * h(0);
                dir = [
                    dir[0] * turn.cos() - dir[1] * turn.sin(),
                    dir[0] * turn.sin() + dir[1] * turn.cos(),
                    0.0,
                ];
                c = add(c, mul(dir, 0.5 * r));
                c[2] = (c[2] + 0.15 * r * h(1))
                    .clamp(s.sea_level - s.depth, s.sea_level + 0.5 * s.height);
                let rr = r * (1.0 - 0.5 * t) * (0.85 + 0.3 * (h(2) + 0.5));
                let id = self.tree.sphere(c, rr, -s.weathering.energy * e.max(0.5))?;
                self.negatives.push(id);
                self.carved.push((c, rr, false));
                report.primitives += 1;
            }
        }
        Ok(report)
    }

    /// Sea cliffs ([`SeaCliffs`]).
    pub fn sea_cliffs(&mut self, s: &SeaCliffs, region: &Region) -> Result<EffectReport> {
        for (n, v) in [
            ("depth", s.depth),
            ("retreat", s.retreat),
            ("radius", s.radius),
        ] {
            self.check_len(n, v)?;
        }
        if !s.sea_level.is_finite() {
            return Err(Error::param("sea_level", s.sea_level, "must be finite"));
        }
        if !(0.0..=1.0).contains(&s.beta) {
            return Err(Error::param("beta", s.beta, "must be in [0, 1]"));
        }
        region.check(&self.frame)?;
        let f = self.frame;
        let spacing = 0.75 * s.radius;
        let per_cell = ((f.cx / spacing).ceil() * (f.cy / spacing).ceil()) as usize;
        if per_cell as f64 * (f.width * f.height) as f64 > (1u64 << 24) as f64 {
            return Err(Error::param(
                "radius",
                s.radius,
                "too small for this DEM: more than 2^24 cliff columns",
            ));
        }
        let dist = self.distance_to_sea(s.sea_level);
        // Bilinear distance to the sea (m).
        let dist_at = |x: f32, y: f32| {
            let (u, v) = f.to_grid([x, y, 0.0]);
            let u = u.clamp(0.0, (f.width - 1) as f32);
            let v = v.clamp(0.0, (f.height - 1) as f32);
            let (j0, i0) = (u.floor() as usize, v.floor() as usize);
            let (j1, i1) = ((j0 + 1).min(f.width - 1), (i0 + 1).min(f.height - 1));
            let (tx, ty) = (u - j0 as f32, v - i0 as f32);
            let g = |j: usize, i: usize| dist[i * f.width + j].min(1e9);
            (g(j0, i0) * (1.0 - tx) + g(j1, i0) * tx) * (1.0 - ty)
                + (g(j0, i1) * (1.0 - tx) + g(j1, i1) * tx) * ty
        };
        // Columns: a jittered grid `spacing` apart over the cells near the shore.
        let reach_cells = (s.retreat / f.cx.min(f.cy)).ceil() + 1.0;
        let (nx, ny) = (
            (f.cx / spacing).ceil().max(1.0) as usize,
            (f.cy / spacing).ceil().max(1.0) as usize,
        );
        let mut pts: Vec<V3> = Vec::new();
        for i in 0..f.height - 1 {
            for j in 0..f.width - 1 {
                let dmin = [
                    dist[i * f.width + j],
                    dist[i * f.width + j + 1],
                    dist[(i + 1) * f.width + j],
                    dist[(i + 1) * f.width + j + 1],
                ]
                .into_iter()
                .fold(f32::INFINITY, f32::min);
                if dmin > reach_cells * f.cx.max(f.cy) {
                    continue;
                }
                let base = f.node(j, i + 1, 0.0);
                for a in 0..nx {
                    for c in 0..ny {
                        let k = (a * ny + c) as u64;
                        let h = |q| unit(hash(s.seed, (i * f.width + j) as u64, k, q));
                        pts.push([
                            base[0] + (a as f32 + 0.25 + 0.5 * h(0)) / nx as f32 * f.cx,
                            base[1] + (c as f32 + 0.25 + 0.5 * h(1)) / ny as f32 * f.cy,
                            0.0,
                        ]);
                    }
                }
            }
        }
        let kept: Vec<usize> = (0..pts.len()).collect();
        let mut report = EffectReport {
            candidates: kept.len(),
            ..Default::default()
        };
        // Energy per sphere: several supports of the lattice overlap at each point; the energy
        // is set so that, in saturated rock, soft strata (e ~ 0.8) go and hard ones
        // (e ~ beta + 0.15) mostly stay. Within the heightfield transition under the surface
        // the rock is weaker and both go.
        let energy = 0.25;
        let dz = 0.5 * s.radius;
        for k in kept {
            let [x, y, _] = pts[k];
            let d = dist_at(x, y);
            let ground = self.ground(x, y);
            if d <= 0.0 || d > s.retreat || ground <= s.sea_level {
                continue;
            }
            let sigma = (1.0 - d / s.retreat).sqrt();
            let mut z = s.sea_level - s.depth;
            let mut any = false;
            while z < ground + 0.5 * s.radius {
                let p = [x, y, z];
                let wgt = region.weight(&f, p);
                if wgt > 0.0 {
                    let e = erosion_intensity(self.geology.resistance(p), sigma * wgt, s.beta);
                    let id = self.tree.sphere(p, s.radius, -energy * e)?;
                    self.negatives.push(id);
                    self.carved.push((p, s.radius, false));
                    report.primitives += 1;
                    any = true;
                }
                z += dz;
            }
            if any {
                report.features += 1;
                if report.sites.is_empty() {
                    report.sites.push([x, y, s.sea_level]);
                }
            }
        }
        Ok(report)
    }

    /// Wind erosion: stress = exposure of the surface to the wind times relative altitude.
    pub fn wind_erosion(&mut self, s: &WindErosion, region: &Region) -> Result<EffectReport> {
        let n = (s.direction[0].powi(2) + s.direction[1].powi(2)).sqrt();
        if !(n.is_finite() && n > 0.0) {
            return Err(Error::param(
                "direction",
                format!("{:?}", s.direction),
                "must be non-zero",
            ));
        }
        let wind = [s.direction[0] / n, s.direction[1] / n, 0.0];
        let (lo, hi) = self
            .dem
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |a, &z| {
                (a.0.min(z), a.1.max(z))
            });
        let stress = move |me: &Self, p: V3| {
            let Some((j, i)) = me.frame.cell(p) else {
                return 0.0;
            };
            let nrm = me.slope_normal(j, i);
            // `-n . w` is sin(slope) cos(aspect to the wind): flat ground is not exposed, a
            // face turned to the wind at 30 degrees or more is fully exposed.
            let exposure = 2.0 * (-crate::math::dot(nrm, wind)).max(0.0);
            exposure.min(1.0) * ((p[2] - lo) / (hi - lo).max(1e-3)).clamp(0.0, 1.0).sqrt()
        };
        Ok(self.weather(&s.weathering, region, None, stress)?.0)
    }

    /// Rain erosion: stress grows with the slope of the ground.
    pub fn rain_erosion(&mut self, s: &RainErosion, region: &Region) -> Result<EffectReport> {
        if !(s.full_slope_deg > 0.0 && s.full_slope_deg <= 90.0) {
            return Err(Error::param(
                "full_slope_deg",
                s.full_slope_deg,
                "must be in (0, 90]",
            ));
        }
        let full = s.full_slope_deg;
        let stress = move |me: &Self, p: V3| {
            let Some((j, i)) = me.frame.cell(p) else {
                return 0.0;
            };
            let slope = me.slope_normal(j, i)[2]
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees();
            (slope / full).min(1.0)
        };
        Ok(self.weather(&s.weathering, region, None, stress)?.0)
    }

    /// Sinkholes of the DEM: strict local minima over the 8-neighbourhood (ties broken by index),
    /// lowest first.
    pub fn sinkholes(&self) -> Vec<(usize, usize)> {
        let f = self.frame;
        let mut out = Vec::new();
        for i in 1..f.height - 1 {
            for j in 1..f.width - 1 {
                let z = self.dem_at(j, i);
                let k = i * f.width + j;
                let mut min = true;
                for di in -1i32..=1 {
                    for dj in -1i32..=1 {
                        if di == 0 && dj == 0 {
                            continue;
                        }
                        let (jj, ii) = ((j as i32 + dj) as usize, (i as i32 + di) as usize);
                        let zz = self.dem_at(jj, ii);
                        let kk = ii * f.width + jj;
                        if zz < z || (zz == z && kk < k) {
                            min = false;
                        }
                    }
                }
                if min {
                    out.push((j, i));
                }
            }
        }
        out.sort_by(|a, b| {
            self.dem_at(a.0, a.1)
                .total_cmp(&self.dem_at(b.0, b.1))
                .then(a.1.cmp(&b.1))
                .then(a.0.cmp(&b.0))
        });
        out
    }

    /// Karst network by modified invasion percolation (section 4.2): seeds at the DEM's
    /// sinkholes and on steep faces, least (perturbed) resistance first, carving only where the
    /// passage sphere lies in rock softer than `rho0`, new candidates on the flattened lower
    /// hemisphere, Poisson rejection; ends on the budget, the `rho_stop` threshold or an empty
    /// queue ([`EffectReport::stop`]).
    pub fn karst(&mut self, s: &KarstSettings, region: &Region) -> Result<EffectReport> {
        for (n, v) in [
            ("rho0", s.rho0),
            ("rho_stop", s.rho_stop),
            ("epsilon", s.epsilon),
            ("beta", s.beta),
            ("sigma", s.sigma),
            ("vertical", s.vertical),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::param(n, v, "must be in [0, 1]"));
            }
        }
        for (n, v) in [
            ("radius", s.radius),
            ("min_radius", s.min_radius),
            ("energy", s.energy),
            ("step", s.step),
            ("poisson_radius", s.poisson_radius),
            ("cliff_spacing", s.cliff_spacing),
        ] {
            self.check_len(n, v)?;
        }
        if s.min_radius > s.radius {
            return Err(Error::param(
                "min_radius",
                s.min_radius,
                "must be <= radius",
            ));
        }
        if !(1..=64).contains(&s.directions) {
            return Err(Error::param(
                "directions",
                s.directions,
                "must be in 1..=64",
            ));
        }
        if s.sub_spheres > 16 {
            return Err(Error::param("sub_spheres", s.sub_spheres, "must be <= 16"));
        }
        if s.budget > 1 << 22 {
            return Err(Error::param("budget", s.budget, "must be <= 2^22"));
        }
        region.check(&self.frame)?;
        let frame = self.frame;
        let floor = self.tree.bbox(self.hf).min[2];
        let (xm, ym) = (
            (frame.width - 1) as f32 * frame.cx,
            (frame.height - 1) as f32 * frame.cy,
        );
        let mut cands: Vec<V3> = Vec::new();
        let mut heap: BinaryHeap<Reverse<(u32, u32)>> = BinaryHeap::new();
        let mut grid: HashMap<(i32, i32, i32), Vec<u32>> = HashMap::new();
        let pr = s.poisson_radius;
        let key = |p: V3| {
            (
                (p[0] / pr).floor() as i32,
                (p[1] / pr).floor() as i32,
                (p[2] / pr).floor() as i32,
            )
        };
        let mut report = EffectReport::default();
        let seed = s.seed;
        let geo = self.geology.clone();
        let geo = &geo;
        let push = |p: V3,
                    cands: &mut Vec<V3>,
                    heap: &mut BinaryHeap<Reverse<(u32, u32)>>,
                    grid: &mut HashMap<(i32, i32, i32), Vec<u32>>|
         -> bool {
            let (a, b, c) = key(p);
            for da in -1..=1 {
                for db in -1..=1 {
                    for dc in -1..=1 {
                        if let Some(v) = grid.get(&(a + da, b + db, c + dc))
                            && v.iter().any(|&q| norm(sub(cands[q as usize], p)) < pr)
                        {
                            return false;
                        }
                    }
                }
            }
            let idx = cands.len() as u32;
            let k = geo.resistance(p) + s.epsilon * unit(hash(seed, idx as u64, 1, 0));
            cands.push(p);
            grid.entry((a, b, c)).or_default().push(idx);
            heap.push(Reverse((k.to_bits(), idx)));
            true
        };
        // Test points of a passage sphere: its six poles and eight diagonal points.
        const D: f32 = 0.577_350_26;
        const DIRS: [V3; 14] = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [D, D, D],
            [D, D, -D],
            [D, -D, D],
            [D, -D, -D],
            [-D, D, D],
            [-D, D, -D],
            [-D, -D, D],
            [-D, -D, -D],
        ];
        let soft_radius = |p: V3| -> Option<f32> {
            let mut a = s.radius;
            loop {
                if DIRS
                    .iter()
                    .all(|d| geo.resistance(add(p, mul(*d, a))) < s.rho0)
                {
                    return Some(a);
                }
                if a <= s.min_radius {
                    return None;
                }
                a = (a * 0.75).max(s.min_radius);
            }
        };
        let sinks = self.sinkholes();
        let mut n_sinks = 0;
        for (j, i) in sinks {
            if n_sinks >= s.max_sinkholes {
                break;
            }
            // The sinkhole drains down to the first soft rock under it (its shaft through the
            // hard strata is not carved).
            let mut p = frame.node(j, i, self.dem_at(j, i) - s.radius);
            while geo.resistance(p) >= s.rho0 && p[2] > floor + 4.0 * s.radius {
                p[2] -= 0.5 * s.radius;
            }
            if region.weight(&frame, p) <= 0.0 || geo.resistance(p) >= s.rho0 {
                continue;
            }
            if push(p, &mut cands, &mut heap, &mut grid) {
                n_sinks += 1;
            }
        }
        // Resurgences on steep faces: Poisson-spaced steep cells, pushed into the rock.
        if s.cliff_seeds > 0 {
            let mut steep = Vec::new();
            for i in 1..frame.height - 1 {
                for j in 1..frame.width - 1 {
                    let n = self.slope_normal(j, i);
                    if n[2] < 0.8 {
                        steep.push((hash(seed, (i * frame.width + j) as u64, 5, 0), j, i, n));
                    }
                }
            }
            steep.sort_by_key(|x| x.0);
            let pts: Vec<V3> = steep
                .iter()
                .map(|&(_, j, i, _)| frame.node(j, i, self.dem_at(j, i)))
                .collect();
            let kept = poisson_filter(&pts, s.cliff_spacing, |_| true);
            let mut n_cliff = 0;
            for k in kept {
                if n_cliff >= s.cliff_seeds {
                    break;
                }
                let n = steep[k].3;
                let mut p = sub(pts[k], mul(n, 1.5 * s.radius));
                while geo.resistance(p) >= s.rho0 && p[2] > floor + 4.0 * s.radius {
                    p[2] -= 0.5 * s.radius;
                }
                if region.weight(&frame, p) <= 0.0 || p[2] < floor + 3.0 * s.radius {
                    continue;
                }
                if push(p, &mut cands, &mut heap, &mut grid) {
                    n_cliff += 1;
                }
            }
        }
        report.sites = cands.clone();
        let mut steps = 0usize;
        report.stop = Some(KarstStop::Exhausted);
        while let Some(Reverse((kbits, idx))) = heap.pop() {
            if steps >= s.budget {
                report.stop = Some(KarstStop::Budget);
                break;
            }
            if f32::from_bits(kbits) > s.rho_stop {
                report.stop = Some(KarstStop::Threshold);
                break;
            }
            let p = cands[idx as usize];
            report.candidates += 1;
            let wgt = region.weight(&frame, p);
            let rho = self.geology.resistance(p);
            if rho < s.rho0
                && wgt > 0.0
                && let Some(a) = soft_radius(p)
            {
                let e = erosion_intensity(rho, s.sigma * wgt, s.beta);
                if e > 0.0 {
                    steps += 1;
                    let r = s.support_radius(a, e);
                    let id = self.tree.sphere(p, r, -s.energy * e)?;
                    self.negatives.push(id);
                    self.carved.push((p, r, true));
                    report.primitives += 1;
                    for m in 0..s.sub_spheres {
                        let h =
                            |c: u64| unit(hash(seed, idx as u64, 100 + m as u64, c)) * 2.0 - 1.0;
                        // Mostly sideways: passages widen along the bedding.
                        let q = add(p, mul([h(0), h(1), 0.3 * h(2)], 0.6 * a));
                        let rq = self.geology.resistance(q);
                        if rq < s.rho0 {
                            let eq = erosion_intensity(rq, s.sigma * wgt, s.beta);
                            let rr = 0.7 * s.support_radius(a, eq);
                            let id = self.tree.sphere(q, rr, -s.energy * eq)?;
                            self.negatives.push(id);
                            self.carved.push((q, rr, true));
                            report.primitives += 1;
                        }
                    }
                }
            }
            // New candidates on the lower hemisphere, flattened towards the horizontal.
            for d in 0..s.directions {
                let h = |c: u64| unit(hash(seed, idx as u64, d as u64, 10 + c));
                let phi = h(0) * std::f32::consts::TAU;
                let dir = normalize([phi.cos(), phi.sin(), -s.vertical * h(1)]);
                let q = add(p, mul(dir, s.step));
                if q[0] < 0.0
                    || q[1] < 0.0
                    || q[0] > xm
                    || q[1] > ym
                    || q[2] < floor + 3.0 * s.radius
                {
                    continue;
                }
                if q[2] > self.ground(q[0], q[1]) - 0.5 * s.radius {
                    continue;
                }
                if region.weight(&frame, q) <= 0.0 {
                    continue;
                }
                push(q, &mut cands, &mut heap, &mut grid);
            }
        }
        report.features = steps;
        report.length_m = steps as f32 * s.step;
        Ok(report)
    }

    fn flat_sites(
        &self,
        spacing: f32,
        max_slope_deg: f32,
        seed: u64,
        region: &Region,
        margin: f32,
    ) -> Vec<V3> {
        let f = self.frame;
        let cos_max = max_slope_deg.to_radians().cos();
        let mut pts = Vec::new();
        for i in 0..f.height {
            for j in 0..f.width {
                let p = f.node(j, i, self.dem_at(j, i));
                let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
                if p[0] < margin || p[1] < margin || p[0] > xm - margin || p[1] > ym - margin {
                    continue;
                }
                if self.slope_normal(j, i)[2] >= cos_max && region.weight(&f, p) > 0.0 {
                    pts.push((hash(seed, (i * f.width + j) as u64, 0, 0), p));
                }
            }
        }
        pts.sort_by_key(|x| x.0);
        let pts: Vec<V3> = pts.into_iter().map(|x| x.1).collect();
        let kept = poisson_filter(&pts, spacing, |_| true);
        kept.into_iter().map(|k| pts[k]).collect()
    }

    /// Hoodoos (figure 3): a cone base blended with stacked perturbed spheres and a caprock,
    /// creased by a warp, unioned with the terrain on gentle ground.
    pub fn hoodoos(&mut self, s: &HoodooSettings, region: &Region) -> Result<EffectReport> {
        for (n, v) in [
            ("height", s.height),
            ("radius", s.radius),
            ("spacing", s.spacing),
        ] {
            self.check_len(n, v)?;
        }
        if !(0.0..=90.0).contains(&s.max_slope_deg) {
            return Err(Error::param(
                "max_slope_deg",
                s.max_slope_deg,
                "must be in [0, 90]",
            ));
        }
        if !(0.0..=1.0).contains(&s.cap_rho) {
            return Err(Error::param("cap_rho", s.cap_rho, "must be in [0, 1]"));
        }
        region.check(&self.frame)?;
        let sites = self.flat_sites(s.spacing, s.max_slope_deg, s.seed, region, 2.0 * s.radius);
        let mut report = EffectReport {
            candidates: sites.len(),
            primitives: 0,
            ..Default::default()
        };
        for (k, &p) in sites.iter().enumerate() {
            if report.features >= s.count {
                break;
            }
            let h = |c| unit(hash(s.seed, k as u64, c, 7));
            // A hoodoo survives under a resistant caprock: the cap sits at the hardest level
            // of the top quarter; sites without hard rock there are skipped.
            let rho = |z: f32| self.geology.resistance([p[0], p[1], z]);
            let mut cap = (f32::NEG_INFINITY, p[2] + s.height);
            for m in 0..=8 {
                let z = p[2] + s.height * (0.75 + 0.3 * m as f32 / 8.0);
                let r = rho(z);
                if r > cap.0 {
                    cap = (r, z);
                }
            }
            if cap.0 < s.cap_rho {
                continue;
            }
            let top = cap.1;
            let mut parts = Vec::new();
            let base = [p[0], p[1], p[2] - 0.2 * s.height];
            parts.push(self.tree.cone(
                base,
                [p[0], p[1], p[2] + 0.3 * (top - p[2])],
                1.8 * s.radius,
                1.0 * s.radius,
                1.0,
            )?);
            // The column: soft strata are narrow necks, hard strata bulges.
            let n = (((top - p[2]) / (0.45 * s.radius)).ceil() as usize).clamp(3, 64);
            for m in 0..n {
                let t = (m as f32 + 0.5) / n as f32;
                let z = p[2] + t * (top - p[2]);
                let c = [
                    p[0] + (h(10 + m as u64) - 0.5) * 0.15 * s.radius,
                    p[1] + (h(20 + m as u64) - 0.5) * 0.15 * s.radius,
                    z,
                ];
                let r = s.radius * (0.55 + 0.6 * rho(z)) * (0.9 + 0.2 * h(30 + m as u64));
                parts.push(self.tree.sphere(c, r, 0.6)?);
            }
            let cr = s.radius * (0.8 + 0.8 * cap.0);
            parts.push(self.tree.ellipsoid(
                [p[0], p[1], top],
                [1.3 * cr, 1.2 * cr, 0.45 * cr],
                1.5,
            )?);
            report.primitives += parts.len();
            report.features += 1;
            report.sites.push(p);
            let b = self.tree.blend(&parts)?;
            let w = self.tree.warp(
                b,
                0.12 * s.radius,
                1.0 / (0.6 * s.radius),
                (s.seed as u32).wrapping_add(k as u32),
            )?;
            self.positives.push(w);
        }
        Ok(report)
    }

    /// One arch between two feet given in scene `(x, y)`: capsules along an arc rising `height`
    /// above the higher foot, warped.
    pub fn arch(
        &mut self,
        a: [f32; 2],
        b: [f32; 2],
        height: f32,
        thickness: f32,
        seed: u32,
    ) -> Result<NodeId> {
        self.check_len("height", height)?;
        self.check_len("thickness", thickness)?;
        if !a.iter().chain(&b).all(|v| v.is_finite()) {
            return Err(Error::param(
                "arch feet",
                format!("{a:?} -> {b:?}"),
                "must be finite",
            ));
        }
        let za = self.ground(a[0], a[1]);
        let zb = self.ground(b[0], b[1]);
        let (pa, pb) = ([a[0], a[1], za - thickness], [b[0], b[1], zb - thickness]);
        let top = za.max(zb) + height;
        let n = 12;
        let pt = |t: f32| {
            let q = add(pa, mul(sub(pb, pa), t));
            let lift = (top - q[2]) * (std::f32::consts::PI * t).sin();
            [q[0], q[1], q[2] + lift]
        };
        let mut parts = Vec::new();
        for k in 0..n {
            let (t0, t1) = (k as f32 / n as f32, (k + 1) as f32 / n as f32);
            let r =
                thickness * (1.0 + 0.6 * (1.0 - (std::f32::consts::PI * (t0 + t1) * 0.5).sin()));
            parts.push(self.tree.capsule(pt(t0), pt(t1), r, 1.0)?);
        }
        let bl = self.tree.blend(&parts)?;
        let w = self
            .tree
            .warp(bl, 0.12 * thickness, 1.0 / thickness, seed)?;
        self.positives.push(w);
        Ok(w)
    }

    /// Arches at sampled gentle sites of the region.
    pub fn arches(&mut self, s: &ArchSettings, region: &Region) -> Result<EffectReport> {
        for (n, v) in [
            ("span", s.span),
            ("height", s.height),
            ("thickness", s.thickness),
        ] {
            self.check_len(n, v)?;
        }
        region.check(&self.frame)?;
        let sites = self.flat_sites(2.0 * s.span, 30.0, s.seed, region, s.span);
        let f = self.frame;
        let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
        let mut report = EffectReport {
            candidates: sites.len(),
            primitives: 0,
            ..Default::default()
        };
        for (k, &p) in sites.iter().enumerate() {
            if report.features >= s.count {
                break;
            }
            let ang = unit(hash(s.seed, k as u64, 3, 3)) * std::f32::consts::TAU;
            let (dx, dy) = (0.5 * s.span * ang.cos(), 0.5 * s.span * ang.sin());
            let (a, b) = ([p[0] - dx, p[1] - dy], [p[0] + dx, p[1] + dy]);
            if [a, b]
                .iter()
                .any(|q| q[0] < 0.0 || q[1] < 0.0 || q[0] > xm || q[1] > ym)
            {
                continue;
            }
            self.arch(
                a,
                b,
                s.height,
                s.thickness,
                (s.seed as u32).wrapping_add(k as u32),
            )?;
            report.primitives += 12;
            report.features += 1;
            report.sites.push([p[0], p[1], p[2] + 0.5 * s.height]);
        }
        Ok(report)
    }

    /// Floating islands: an ellipsoidal top blended with an inverted cone, warped, hovering
    /// `altitude` metres above the ground.
    pub fn floating_islands(
        &mut self,
        s: &IslandSettings,
        region: &Region,
    ) -> Result<EffectReport> {
        self.check_len("radius", s.radius)?;
        self.check_len("altitude", s.altitude)?;
        region.check(&self.frame)?;
        let sites = self.flat_sites(3.0 * s.radius, 90.0, s.seed, region, s.radius);
        let mut report = EffectReport {
            candidates: sites.len(),
            primitives: 0,
            ..Default::default()
        };
        for (k, &p) in sites.iter().take(s.count).enumerate() {
            let c = add(p, [0.0, 0.0, s.altitude]);
            let top =
                self.tree
                    .ellipsoid(c, [s.radius * 1.6, s.radius * 1.4, s.radius * 0.5], 1.0)?;
            let cone = self.tree.cone(
                add(c, [0.0, 0.0, -0.1 * s.radius]),
                add(c, [0.0, 0.0, -1.6 * s.radius]),
                1.2 * s.radius,
                0.25 * s.radius,
                1.0,
            )?;
            let b = self.tree.blend(&[top, cone])?;
            let w = self.tree.warp(
                b,
                0.15 * s.radius,
                1.0 / (0.5 * s.radius),
                (s.seed as u32).wrapping_add(k as u32),
            )?;
            self.positives.push(w);
            report.primitives += 2;
            report.features += 1;
            report.sites.push(c);
        }
        Ok(report)
    }

    /// Assembles the scene: `union(blend(heightfield, carvings), matter)`. With `use_bvh` the
    /// carvings and the matter are organised in BVHs; without, in flat n-ary blends (every
    /// primitive is visited by each query: for comparisons only).
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
        if !self.positives.is_empty() {
            let p = if use_bvh {
                self.tree.bvh_blend(&self.positives)?
            } else {
                self.tree.blend(&self.positives)?
            };
            root = self.tree.union(root, p)?;
            upper = self.tree.union(self.hf, p)?;
        }
        let mut scene = Scene::new(self.tree, root, self.geology, Some((self.hf, self.frame)))?;
        scene.upper = Some(upper);
        Ok(scene)
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
    /// Upper end of a conservative range of `f` over `region`, from the carving-free tree when
    /// there is one (cheaper) or the whole tree: `<= T` proves `region` is air.
    pub fn max_over(&self, region: &Aabb) -> f32 {
        self.tree
            .interval(self.upper.unwrap_or(self.root), region)
            .1
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
}
