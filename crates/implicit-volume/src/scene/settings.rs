//! Settings of the implicitisation and of every effect, and what an effect reports.

use super::*;

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
    pub(super) fn check(&self, min_len: f32) -> Result<()> {
        for (n, v) in named_fields!(self; spacing, radius, energy) {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::param(n, v, "must be finite and > 0"));
            }
            if n != "energy" && !(min_len..=1e7 * min_len).contains(&v) {
                return Err(Error::param(
                    n,
                    v,
                    "out of scale with the scene (1e-5 to 100 times its extent)",
                ));
            }
        }
        let unit = named_fields!(self; beta, threshold);
        Error::check_all_in(&unit, 0.0..=1.0, "must be in [0, 1]")
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
    /// The sea is only the ground at or below `sea_level` connected to the DEM's border
    /// ([`crate::scene::border_connected_at_or_below`]), not closed depressions inland;
    /// `false` = every sample at or below `sea_level` (a lake level anywhere).
    pub border_connected: bool,
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
            border_connected: false,
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
    /// The sea is only the ground at or below `sea_level` connected to the DEM's border, as
    /// [`SeaErosion::border_connected`].
    pub border_connected: bool,
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
            border_connected: false,
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

/// Rain erosion: stress grows with the slope (runoff), zero below a third of `full_slope_deg`,
/// full at `full_slope_deg`.
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

/// Undercuts ([`SceneBuilder::undercuts`]): soft rock retreating under a resistant bed on
/// steep faces, leaving the bed overhanging.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UndercutSettings {
    /// Deepest retreat under a bed (m), for a contrast of 0.5 or more in resistance.
    pub depth: f32,
    /// Distance between face samples (m).
    pub spacing: f32,
    /// Gentlest face (degrees) undercut.
    pub min_slope_deg: f32,
    /// Rock under this resistance is soft (retreats).
    pub rho_soft: f32,
    /// Rock of at least this resistance is a resistant bed (stands out).
    pub rho_hard: f32,
    /// Seed of the face samples.
    pub seed: u64,
}
impl Default for UndercutSettings {
    fn default() -> Self {
        Self {
            depth: 4.0,
            spacing: 2.0,
            min_slope_deg: 40.0,
            rho_soft: 0.5,
            rho_hard: 0.55,
            seed: 17,
        }
    }
}

/// Karst by modified invasion percolation (paper section 4.2, figure 6).
///
/// Lengths are in metres. A carved step places a negative ellipsoid, flattened along the
/// bedding (`flatten`), whose *visible* passage radius is `radius` varied by `radius_jitter`
/// (the support radius follows from the energy, see [`KarstSettings::support_radius`]),
/// shrunk down to `min_radius` until every test point on the passage ellipsoid lies in soft
/// rock (`rho < rho0`), so passages follow the soft strata; `sub_spheres` smaller ellipsoids
/// widen it horizontally. New candidates are `step` away in
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
    /// Flattening of the passages along the bedding: a carved step is an ellipsoid
    /// `1 / sqrt(flatten)` times the passage radius wide and `sqrt(flatten)` times it high
    /// (the cross-section of a sphere of that radius), in `(0, 1]` (1 = spheres). Where a
    /// passage meets a cliff, its opening is a slot along the strata, not a round hole.
    pub flatten: f32,
    /// Relative variation of the passage radius from step to step, in `[0, 0.9]`: radius
    /// `radius (1 + radius_jitter (2 u - 1))` with `u` hashed per step.
    pub radius_jitter: f32,
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
            flatten: 0.45,
            radius_jitter: 0.3,
            seed: 7,
        }
    }
}

impl KarstSettings {
    /// Horizontal and vertical scale of a passage ellipsoid's axes relative to its radius:
    /// `(1 / sqrt(flatten), sqrt(flatten))`.
    pub fn axes(&self) -> (f32, f32) {
        let f = self.flatten.clamp(1e-3, 1.0);
        (1.0 / f.sqrt(), f.sqrt())
    }

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

/// Hoodoos (figure 3, [`SceneBuilder::hoodoos`]): columns of soft rock under a resistant cap
/// bed, their profile from the geology, in clusters on steep slopes below that bed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoodooSettings {
    /// Number of hoodoos (fewer if the region has no room).
    pub count: usize,
    /// Nominal height (m): each stands up to the resistant bed nearest this height above the
    /// floor of the hollow it stands in (0.35 of it under the slope), between 0.6 and 1.4
    /// times it.
    pub height: f32,
    /// Column radius (m) in rock of resistance 0.73 (`0.45 + 0.75 rho` times it elsewhere).
    pub radius: f32,
    /// Distance between neighbours of a cluster's row (m; none closer than 0.8 of it);
    /// clusters are `6 spacing` apart.
    pub spacing: f32,
    /// Gentlest ground slope (degrees) where a hoodoo may stand (badland slopes, not flats).
    pub min_slope_deg: f32,
    /// Steepest ground slope (degrees) where a hoodoo may stand.
    pub max_slope_deg: f32,
    /// Smallest resistance of the cap bed: sites without such a bed near the nominal height
    /// are skipped.
    pub cap_rho: f32,
    /// Most hoodoos per cluster, in `1..=64`.
    pub per_cluster: usize,
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
            min_slope_deg: 15.0,
            max_slope_deg: 55.0,
            cap_rho: 0.55,
            per_cluster: 5,
            seed: 3,
        }
    }
}

/// Natural arches ([`SceneBuilder::arches`]): a ridge narrowed to a fin and eroded through
/// along a soft stratum under a resistant bridge bed, the opening irregular, the span drawn
/// per arch around `span`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArchSettings {
    /// Number of arches (fewer when the DEM has no ridge narrow and high enough, or the
    /// geology no resistant bed over soft rock at the right height).
    pub count: usize,
    /// Median span (opening width, m): each arch's is drawn log-normal around it, within
    /// `[0.35, 3]` times it and at most 120 m, and shrunk to what its ridge holds.
    pub span: f32,
    /// Thickness of the fin (m, +-20 % per arch); the bridge keeps at least
    /// `max(0.4 thickness, 1 m)` of rock over the opening.
    pub thickness: f32,
    /// Thickest ridge cut through (the gap's length between its mouths, m).
    pub max_length: f32,
    /// Seed.
    pub seed: u64,
}
impl Default for ArchSettings {
    fn default() -> Self {
        Self {
            count: 2,
            span: 60.0,
            thickness: 12.0,
            max_length: 240.0,
            seed: 5,
        }
    }
}

/// Floating islands ([`SceneBuilder::floating_islands`]): clusters grown from high-relief
/// sites, each island a lobed flat-ish top over a jagged inverted mountain, warped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IslandSettings {
    /// Number of islands (all clusters together; fewer when the DEM has no room).
    pub count: usize,
    /// Radius of a cluster's main island (m): each main island is `[0.8, 1.2]` times it.
    pub radius: f32,
    /// Height of a cluster's tops above the local ground (m): `[0.8, 1.2]` times it, each
    /// island a further `+-15 %`, and always clear of the ground under it.
    pub altitude: f32,
    /// Islands per cluster, in `1..=16` (1 = lone islands).
    pub per_cluster: usize,
    /// Ratio of a cluster's main island radius to its smallest, in `[1, 10]`.
    pub spread: f32,
    /// Seed.
    pub seed: u64,
}
impl Default for IslandSettings {
    fn default() -> Self {
        Self {
            count: 2,
            radius: 40.0,
            altitude: 120.0,
            per_cluster: 3,
            spread: 3.0,
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
    /// Karst: soft-rock steps left uncarved because even the smallest passage would reach
    /// the surface (its support above the lowest ground around it); the percolation goes on
    /// through them.
    pub thin_cover: usize,
    /// Where the landforms were placed (hoodoo bases, arch openings, island centres, cave
    /// mouths; karst: the seeds).
    pub sites: Vec<V3>,
    /// Per site, the horizontal direction to look along to see it best (arches: the gap's
    /// axis, so a camera sees through the opening; floating islands: towards the lowest ground
    /// around, so a camera sees the underside; sea caves: out of the mouth, towards the sea; hoodoos: downslope, so a camera sees a
    /// cluster against its slope;
    /// undercuts: out of the face); empty for the other effects.
    pub axes: Vec<V3>,
    /// The landforms' sizes (m): floating islands' radii, hoodoo heights (ground to cap top),
    /// arch spans, sea caves' widest radii (one per site), karst passage radii (one per carved
    /// step); empty for the other effects.
    pub sizes_m: Vec<f32>,
}
