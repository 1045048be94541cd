//! Ready-made scenes: a list of [`Feature`]s applied to a DEM with physical parameters in
//! metres derived from the DEM's relief and extent ([`Recipe`], [`build_recipe`],
//! [`Dimensions`]). This is what the `relief volume` command and the pipeline's `volume` stage
//! run; the individual generators of [`crate::scene::SceneBuilder`] stay available for finer
//! control.
//!
//! # Sizes (with `R` the relief, `v` the meshing voxel, `s` [`Recipe::scale`])
//! * voxel `v`: half the larger DEM cell, refined to `R / 32` for low relief, but never finer
//!   than 1/512 of the larger horizontal extent (the mesh stays within ~512 cells a side);
//! * closing floor `max(0.3 R, 8 v)` below the lowest sample;
//! * default geology [`GeologySpec::layered_default`] with a period of `max(R / 6, 9 v)` so that
//!   its soft strata are at least 2.5 voxels thick;
//! * karst passages: visible radius `clamp(0.4 t s, v, 0.5 t)` with `t` the median soft-stratum
//!   thickness measured on the geology, step = radius, budget from a passage density
//!   ([`Densities::karst_km_per_km2`]); skipped (with a note) when `0.5 t < v`;
//! * hoodoos `clamp(0.12 R, 15, 250) s` tall (at most `0.45 R`), radius a sixth of that (at
//!   least `v`); arches spanning `clamp(0.2 R, 30, 300) s` (at most `0.5 R`), rising half their
//!   span, a seventh of it thick; islands of radius `clamp(0.1 R, 20, 300) s`;
//! * sea and weathering spheres of radius `max(2.5 v, 0.05 R)`, `0.4` radius apart; sea
//!   cliffs cut `6 c` back with spheres of `c = max(1.5 v, min(that, 0.4 t))`;
//! * counts from densities per km^2 ([`Densities`]) over the DEM's area (at least one).
//!
//! Each size is checked against the voxel and the relief; a feature that cannot be resolved is
//! skipped and [`Dimensions::notes`] says why.

use std::str::FromStr;

use relief_heightfield::Heightfield;

use crate::error::{Error, Result};
use crate::geology::GeologySpec;
use crate::render::{Camera, Image, RenderSettings, render};
use crate::scene::{
    ArchSettings, EffectReport, HoodooSettings, ImplicitizeSettings, IslandSettings, KarstSettings,
    RainErosion, Region, Scene, SceneBuilder, SeaCliffs, SeaErosion, Weathering, WindErosion,
};

/// One landform effect of a [`Recipe`].
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Feature {
    /// Sea erosion of the shore band (section 4.1, figure 5): notches and cliff undercuts.
    Sea,
    /// Sea caves dug inland from the most eroded shore samples (implies the sea band).
    Caves,
    /// Sea cliffs: the shore cut back into a vertical face with ledges of hard strata.
    Cliffs,
    /// Karst network by invasion percolation from the sinkholes (section 4.2).
    Karst,
    /// Hoodoos on gentle ground (figure 3).
    Hoodoos,
    /// Natural arches.
    Arches,
    /// Floating islands.
    Islands,
    /// Wind and rain erosion of exposed and steep faces (both [`Feature::Wind`] and
    /// [`Feature::Rain`]).
    Overhangs,
    /// Wind erosion of the faces turned to the wind ([`Recipe::wind`]).
    Wind,
    /// Rain erosion of steep faces.
    Rain,
}

impl Feature {
    /// Every feature, in the order a recipe applies them.
    pub const ALL: [Feature; 10] = [
        Feature::Cliffs,
        Feature::Sea,
        Feature::Caves,
        Feature::Karst,
        Feature::Overhangs,
        Feature::Wind,
        Feature::Rain,
        Feature::Hoodoos,
        Feature::Arches,
        Feature::Islands,
    ];

    /// The name used on command lines and in specs.
    pub fn name(self) -> &'static str {
        match self {
            Feature::Sea => "sea",
            Feature::Caves => "caves",
            Feature::Cliffs => "cliffs",
            Feature::Karst => "karst",
            Feature::Hoodoos => "hoodoos",
            Feature::Arches => "arches",
            Feature::Islands => "islands",
            Feature::Overhangs => "overhangs",
            Feature::Wind => "wind",
            Feature::Rain => "rain",
        }
    }

    /// Parses a comma-separated list (`"sea,karst"`); duplicates are merged, order is
    /// [`Feature::ALL`]'s.
    pub fn parse_list(s: &str) -> Result<Vec<Feature>> {
        let mut v = Vec::new();
        for part in s.split(',') {
            let f: Feature = part.trim().parse()?;
            if !v.contains(&f) {
                v.push(f);
            }
        }
        v.sort();
        Ok(v)
    }
}

impl FromStr for Feature {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        Feature::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| {
                Error::param(
                    "feature",
                    format!("`{s}`"),
                    "must be one of cliffs, sea, caves, karst, hoodoos, arches, islands, overhangs, wind, rain",
                )
            })
    }
}

impl std::fmt::Display for Feature {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Landform densities used to derive counts from the DEM's area.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Densities {
    /// Hoodoos per km^2.
    pub hoodoos_per_km2: f32,
    /// Arches per km^2.
    pub arches_per_km2: f32,
    /// Floating islands per km^2.
    pub islands_per_km2: f32,
    /// Sea caves per km^2.
    pub caves_per_km2: f32,
    /// Karst passage length per km^2 (km), which sets the karst budget.
    pub karst_km_per_km2: f32,
    /// Karst seeds on steep faces per km^2.
    pub karst_cliff_seeds_per_km2: f32,
}
impl Default for Densities {
    fn default() -> Self {
        Self {
            hoodoos_per_km2: 1.0,
            arches_per_km2: 0.3,
            islands_per_km2: 0.1,
            caves_per_km2: 1.0,
            karst_km_per_km2: 6.0,
            karst_cliff_seeds_per_km2: 4.0,
        }
    }
}

/// What to build on a DEM.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Recipe {
    /// Effects to apply (any order; applied in [`Feature::ALL`] order).
    pub features: Vec<Feature>,
    /// Sea level (m); `None` = the 25th percentile of the DEM's elevations, so an inland DEM
    /// gets a lake shore to erode.
    pub sea_level: Option<f32>,
    /// Per-cell weights in `[0, 1]` (row-major, DEM size) limiting every effect; `None` =
    /// everywhere.
    pub mask: Option<Vec<f32>>,
    /// Multiplies every derived feature size (module docs); 1 = default.
    pub scale: f32,
    /// Meshing voxel edge (m) the sizes are checked against; `None` = derived (module docs).
    pub voxel: Option<f32>,
    /// Geology tree; `None` = [`GeologySpec::layered_default`] scaled to the DEM.
    pub geology: Option<GeologySpec>,
    /// Karst budget (carving steps); `None` = from [`Densities::karst_km_per_km2`].
    pub karst_budget: Option<usize>,
    /// Landform densities.
    pub densities: Densities,
    /// Direction the wind blows towards (x east, y north).
    pub wind: [f32; 2],
    /// Energy of wind erosion (negative sphere energy scale).
    pub wind_strength: f32,
    /// Energy of rain erosion.
    pub rain_strength: f32,
    /// Seed of every effect (each derives its own stream).
    pub seed: u64,
}

impl Default for Recipe {
    fn default() -> Self {
        Self {
            features: vec![
                Feature::Sea,
                Feature::Karst,
                Feature::Hoodoos,
                Feature::Arches,
                Feature::Islands,
            ],
            sea_level: None,
            mask: None,
            scale: 1.0,
            voxel: None,
            geology: None,
            karst_budget: None,
            densities: Densities::default(),
            wind: [1.0, 0.3],
            wind_strength: 2.0,
            rain_strength: 2.0,
            seed: 1,
        }
    }
}

/// The physical parameters a recipe derived from the DEM (metres, counts), for reports.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct Dimensions {
    /// Larger DEM cell size (m).
    pub cell_m: f32,
    /// Relief: highest minus lowest sample (m).
    pub relief_m: f32,
    /// Area of the DEM (km^2).
    pub area_km2: f32,
    /// Meshing voxel the sizes were checked against (m).
    pub voxel_m: f32,
    /// Depth of the closing floor below the lowest sample (m).
    pub floor_depth_m: f32,
    /// Period of the default geology's strata (m); `None` with a user geology.
    pub strata_period_m: Option<f32>,
    /// Median thickness of the soft strata (`rho < rho0`) measured on the geology (m).
    pub soft_thickness_m: Option<f32>,
    /// Karst passage radius (visible, m).
    pub karst_radius_m: f32,
    /// Karst step (m).
    pub karst_step_m: f32,
    /// Karst budget (steps).
    pub karst_budget: usize,
    /// Hoodoo height (m).
    pub hoodoo_height_m: f32,
    /// Hoodoo base radius (m).
    pub hoodoo_radius_m: f32,
    /// Hoodoos asked for.
    pub hoodoo_count: usize,
    /// Arch span (m).
    pub arch_span_m: f32,
    /// Arch rise above the higher foot (m).
    pub arch_height_m: f32,
    /// Arch thickness (m).
    pub arch_thickness_m: f32,
    /// Arches asked for.
    pub arch_count: usize,
    /// Floating island radius (m).
    pub island_radius_m: f32,
    /// Floating island height above the ground (m).
    pub island_altitude_m: f32,
    /// Islands asked for.
    pub island_count: usize,
    /// Radius of sea-erosion spheres (m).
    pub sea_radius_m: f32,
    /// Height above sea level still eroded (m).
    pub sea_height_m: f32,
    /// Sea caves asked for.
    pub cave_count: usize,
    /// Sea cave length (m).
    pub cave_length_m: f32,
    /// Radius of wind and rain spheres (m).
    pub weathering_radius_m: f32,
    /// How far sea cliffs cut the shore back (m).
    pub cliff_retreat_m: f32,
    /// Features skipped or adjusted, and why.
    pub notes: Vec<String>,
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

/// What [`build_recipe`] did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RecipeReport {
    /// One entry per applied feature.
    pub effects: Vec<(Feature, EffectReport)>,
    /// Sea level used (m).
    pub sea_level: f32,
    /// Whether the scene has sea features (sea erosion or caves), i.e. water to draw.
    pub has_sea: bool,
    /// The derived sizes and counts.
    pub dims: Dimensions,
    /// The geology used.
    pub geology: GeologySpec,
    /// Implicitisation deviation of the plain DEM primitive.
    pub deviation: Deviation,
    /// A horizontal segment (scene x, y) crossing the most carvings: where a vertical section
    /// shows the tunnels and caves best (the middle west-east line when nothing was carved).
    pub section_line: ([f32; 2], [f32; 2]),
    /// The placed landforms (hoodoos, arches, islands, cave mouths) and the densest karst
    /// area, for close-up cameras.
    pub highlights: Vec<Highlight>,
}

/// A landform worth a close-up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Highlight {
    /// Its kind.
    pub feature: Feature,
    /// Where to look (scene coordinates).
    pub at: [f32; 3],
    /// Horizontal direction from `at` towards a good eye position (arches: along the tunnel,
    /// to see through the opening); `None` = the default oblique view from the south-west.
    pub from: Option<[f32; 3]>,
    /// Underground (karst): the close-up is a cut-away through `at`, facing the eye.
    pub cutaway: bool,
}

fn percentile(hf: &Heightfield, q: f32) -> f32 {
    relief_heightfield::metrics::quantile(hf.as_slice(), q as f64).unwrap_or(0.0)
}

fn count(density: f32, area_km2: f32, cap: usize) -> usize {
    ((density.max(0.0) * area_km2).round() as usize).clamp(1, cap)
}

impl Recipe {
    /// Checks the settings that do not depend on the DEM (each error names the field and the
    /// rule); [`build_recipe`] also checks the sizes against the DEM.
    pub fn check(&self) -> Result<()> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(Error::param("scale", self.scale, "must be finite and > 0"));
        }
        if let Some(s) = self.sea_level
            && !s.is_finite()
        {
            return Err(Error::param("sea_level", s, "must be finite"));
        }
        for (n, v) in [
            ("wind_strength", self.wind_strength),
            ("rain_strength", self.rain_strength),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 100.0) {
                return Err(Error::param(n, v, "must be in (0, 100]"));
            }
        }
        let d = &self.densities;
        for (n, v) in [
            ("hoodoos_per_km2", d.hoodoos_per_km2),
            ("arches_per_km2", d.arches_per_km2),
            ("islands_per_km2", d.islands_per_km2),
            ("caves_per_km2", d.caves_per_km2),
            ("karst_km_per_km2", d.karst_km_per_km2),
            ("karst_cliff_seeds_per_km2", d.karst_cliff_seeds_per_km2),
        ] {
            if !(v.is_finite() && (0.0..=1e4).contains(&v)) {
                return Err(Error::param(n, v, "must be in [0, 10000]"));
            }
        }
        if let Some(v) = self.voxel
            && !(v.is_finite() && v > 0.0)
        {
            return Err(Error::param("voxel", v, "must be finite and > 0"));
        }
        if let Some(n) = self.karst_budget
            && n > 1 << 22
        {
            return Err(Error::param("karst_budget", n, "must be <= 2^22"));
        }
        if !self.wind.iter().all(|v| v.is_finite()) || self.wind == [0.0, 0.0] {
            return Err(Error::param(
                "wind",
                format!("{:?}", self.wind),
                "must be finite and non-zero",
            ));
        }
        if let Some(m) = &self.mask
            && let Some(v) = m.iter().find(|v| !(0.0..=1.0).contains(*v))
        {
            return Err(Error::param("region.mask value", v, "must be in [0, 1]"));
        }
        if let Some(g) = &self.geology {
            g.build()?;
        }
        Ok(())
    }
}

/// Builds the scene of `recipe` on `hf` (complete, at least 3 x 3 nodes). Deterministic in
/// `recipe.seed` whatever the thread count.
pub fn build_recipe(hf: &Heightfield, recipe: &Recipe) -> Result<(Scene, RecipeReport)> {
    hf.require_complete()?;
    if hf.width() < 3 || hf.height() < 3 {
        return Err(Error::param(
            "heightfield size",
            format!("{}x{}", hf.width(), hf.height()),
            "needs at least 3x3 nodes",
        ));
    }
    recipe.check()?;
    let d = &recipe.densities;
    let (cx, cy) = hf.cell_size();
    let (cx, cy) = (cx as f32, cy as f32);
    let l = cx.max(cy);
    let k = recipe.scale;
    let (lo, hi) = hf
        .min_max()
        .ok_or(Error::param("heightfield", "all void", "needs samples"))?;
    let (ex, ey) = ((hf.width() - 1) as f32 * cx, (hf.height() - 1) as f32 * cy);
    let area_km2 = ex * ey * 1e-6;
    let mag = [ex, ey, lo.abs(), hi.abs(), 1.0]
        .into_iter()
        .fold(0.0f32, f32::max);
    if !(1e-3 * mag..=5.0 * mag).contains(&(l * k)) {
        return Err(Error::param(
            "scale",
            recipe.scale,
            "makes the feature sizes out of scale with the DEM (1e-3 to 5 times its extent)",
        ));
    }
    let voxel = match recipe.voxel {
        Some(v) if v.is_finite() && v > 0.0 && v >= ex.max(ey) / 8192.0 => v,
        Some(v) => {
            return Err(Error::param(
                "voxel",
                v,
                "must be finite, > 0 and at least 1/8192 of the DEM's extent",
            ));
        }
        None => (0.5 * l).min((hi - lo) / 32.0).max(ex.max(ey) / 512.0),
    };
    let relief = (hi - lo).max(4.0 * voxel);
    let mut dims = Dimensions {
        cell_m: l,
        relief_m: hi - lo,
        area_km2,
        voxel_m: voxel,
        floor_depth_m: (0.3 * relief).max(8.0 * voxel),
        ..Default::default()
    };
    let center = [0.5 * ex, 0.5 * ey, 0.5 * (lo + hi)];
    let geology = match &recipe.geology {
        Some(g) => g.clone(),
        None => {
            let period = (relief / 6.0).max(9.0 * voxel);
            dims.strata_period_m = Some(period);
            GeologySpec::layered_default(center, period, recipe.seed)?
        }
    };
    let geo = geology.build()?;
    // Soft strata thickness over nine columns, from the floor to the top.
    let cols: Vec<[f32; 2]> = (0..9)
        .map(|i| {
            [
                ex * (0.2 + 0.3 * (i % 3) as f32),
                ey * (0.2 + 0.3 * (i / 3) as f32),
            ]
        })
        .collect();
    let rho0 = 0.5;
    let mut runs = geo.soft_runs(&cols, lo - dims.floor_depth_m, hi, rho0, 0.25 * voxel);
    runs.sort_by(f32::total_cmp);
    dims.soft_thickness_m = runs.get(runs.len() / 2).copied();
    let mut b = SceneBuilder::new(
        hf,
        geo,
        &ImplicitizeSettings {
            // Twice the cell (the default): a shorter transition saturates the rock closer to
            // the surface but raises the field's Lipschitz bound, which slows sphere tracing.
            transition: 0.0,
            depth: dims.floor_depth_m,
        },
    )?;
    let region = Region {
        mask: recipe.mask.clone(),
        bbox: None,
    };
    region.check(&b.frame())?;
    let deviation = b.implicitization_deviation(4096);
    let sea_level = recipe.sea_level.unwrap_or_else(|| percentile(hf, 0.25));
    let seed = recipe.seed;
    let sub = |k: u64| crate::math::hash(seed, k, 0x7265_6369, 0);
    let has = |f: Feature| recipe.features.contains(&f);
    let mut effects = Vec::new();
    let wr = (2.5 * voxel).max(0.05 * relief * k);
    dims.weathering_radius_m = wr;
    if has(Feature::Cliffs) {
        // Spheres finer than the soft strata, so hard ones survive as ledges.
        let cr = (1.5 * voxel).max(wr.min(0.4 * dims.soft_thickness_m.unwrap_or(wr)));
        let c = SeaCliffs {
            sea_level,
            depth: 0.3 * cr,
            retreat: 6.0 * cr,
            radius: cr,
            beta: 0.2,
            seed: sub(8),
        };
        dims.cliff_retreat_m = c.retreat;
        effects.push((Feature::Cliffs, b.sea_cliffs(&c, &region)?));
    }
    if has(Feature::Sea) || has(Feature::Caves) {
        let r = wr;
        dims.sea_radius_m = r;
        dims.sea_height_m = (0.15 * relief).max(2.0 * r);
        dims.cave_count = if has(Feature::Caves) {
            count(d.caves_per_km2, area_km2, 64)
        } else {
            0
        };
        dims.cave_length_m = (12.0 * r).min(0.25 * ex.min(ey));
        let s = SeaErosion {
            weathering: Weathering {
                spacing: 0.4 * r,
                radius: r,
                energy: 3.0,
                seed: sub(1),
                ..Default::default()
            },
            sea_level,
            depth: 0.3 * r,
            height: dims.sea_height_m,
            peak: 0.2 * dims.sea_height_m,
            reach: (6.0 * r).max(2.0 * l),
            caves: dims.cave_count,
            cave_length: dims.cave_length_m,
            iterations: 3,
        };
        let rep = b.sea_erosion(&s, &region)?;
        let f = if has(Feature::Sea) {
            Feature::Sea
        } else {
            Feature::Caves
        };
        effects.push((f, rep));
    }
    if has(Feature::Karst) {
        match dims.soft_thickness_m {
            Some(t) if 0.5 * t >= voxel => {
                let a = (0.4 * t * k).clamp(voxel, 0.5 * t);
                let step = a;
                dims.karst_radius_m = a;
                dims.karst_step_m = step;
                dims.karst_budget = recipe.karst_budget.unwrap_or(
                    ((d.karst_km_per_km2 * area_km2 * 1000.0 / step).round() as usize).min(1 << 22),
                );
                let ks = KarstSettings {
                    radius: a,
                    min_radius: voxel.min(a),
                    step,
                    poisson_radius: 0.8 * step,
                    sub_spheres: 4,
                    budget: dims.karst_budget,
                    max_sinkholes: 256,
                    cliff_seeds: (d.karst_cliff_seeds_per_km2 * area_km2).round() as usize,
                    cliff_spacing: 10.0 * a,
                    rho0,
                    rho_stop: 0.7,
                    seed: sub(2),
                    ..Default::default()
                };
                effects.push((Feature::Karst, b.karst(&ks, &region)?));
            }
            Some(t) => dims.notes.push(format!(
                "karst skipped: soft strata {t:.1} m thick, under two voxels of {voxel:.1} m \
                 (a finer --voxel or a thicker geology resolves them)"
            )),
            None => dims
                .notes
                .push("karst skipped: the geology has no soft strata (rho < 0.5)".into()),
        }
    }
    let wind = has(Feature::Wind) || has(Feature::Overhangs);
    let rain = has(Feature::Rain) || has(Feature::Overhangs);
    let w = Weathering {
        spacing: 0.5 * wr,
        radius: wr,
        energy: recipe.wind_strength,
        threshold: 0.45,
        seed: sub(3),
        ..Default::default()
    };
    let mut overhangs: Option<EffectReport> = None;
    if wind {
        let rep = b.wind_erosion(
            &WindErosion {
                weathering: w,
                direction: recipe.wind,
            },
            &region,
        )?;
        if has(Feature::Overhangs) {
            overhangs = Some(rep);
        } else {
            effects.push((Feature::Wind, rep));
        }
    }
    if rain {
        let rep = b.rain_erosion(
            &RainErosion {
                weathering: Weathering {
                    seed: sub(4),
                    energy: recipe.rain_strength,
                    ..w
                },
                full_slope_deg: 40.0,
            },
            &region,
        )?;
        match overhangs.as_mut() {
            Some(o) => {
                o.candidates += rep.candidates;
                o.primitives += rep.primitives;
            }
            None => effects.push((Feature::Rain, rep)),
        }
    }
    if let Some(o) = overhangs {
        effects.push((Feature::Overhangs, o));
    }
    if has(Feature::Hoodoos) {
        let height = (0.12 * relief).clamp(15.0, 250.0) * k;
        let radius = (height / 6.0).max(voxel);
        dims.hoodoo_height_m = height;
        dims.hoodoo_radius_m = radius;
        if height > 0.45 * relief || height < 4.0 * voxel {
            dims.notes.push(format!(
                "hoodoos skipped: {height:.0} m tall is not between four voxels ({:.0} m) and \
                 0.45 of the relief ({:.0} m)",
                4.0 * voxel,
                0.45 * relief
            ));
        } else {
            dims.hoodoo_count = count(d.hoodoos_per_km2, area_km2, 256);
            let h = HoodooSettings {
                count: dims.hoodoo_count,
                height,
                radius,
                spacing: 4.0 * radius,
                max_slope_deg: 25.0,
                cap_rho: 0.55,
                seed: sub(5),
            };
            effects.push((Feature::Hoodoos, b.hoodoos(&h, &region)?));
        }
    }
    if has(Feature::Arches) {
        let span = (0.2 * relief).clamp(30.0, 300.0) * k;
        let thickness = (span / 4.0).max(voxel);
        dims.arch_span_m = span;
        dims.arch_height_m = 0.6 * span;
        dims.arch_thickness_m = thickness;
        if span > 0.5 * relief || span < 3.0 * voxel {
            dims.notes.push(format!(
                "arches skipped: a {span:.0} m opening is over half the relief ({:.0} m) or \
                 under three {voxel:.1} m voxels",
                0.5 * relief
            ));
        } else {
            dims.arch_count = count(d.arches_per_km2, area_km2, 64);
            let a = ArchSettings {
                count: dims.arch_count,
                span,
                height: dims.arch_height_m,
                thickness,
                max_length: (5.0 * span).max(3.0 * l),
                seed: sub(6),
            };
            let rep = b.arches(&a, &region)?;
            if rep.features == 0 {
                dims.notes.push(format!(
                    "arches skipped: no ridge rises {:.0} m on both sides within {:.0} m",
                    a.height + a.thickness,
                    a.max_length
                ));
            } else {
                effects.push((Feature::Arches, rep));
            }
        }
    }
    if has(Feature::Islands) {
        let radius = (0.1 * relief).clamp(20.0, 300.0) * k;
        dims.island_radius_m = radius.max(2.0 * voxel);
        dims.island_altitude_m = (0.3 * relief).max(4.0 * dims.island_radius_m);
        dims.island_count = count(d.islands_per_km2, area_km2, 16);
        let i = IslandSettings {
            count: dims.island_count,
            radius: dims.island_radius_m,
            altitude: dims.island_altitude_m,
            seed: sub(7),
        };
        effects.push((Feature::Islands, b.floating_islands(&i, &region)?));
    }
    let section_line = best_section_line(&b);
    let mut highlights = Vec::new();
    for (f, e) in &effects {
        if *f == Feature::Karst {
            if let Some(c) = densest_karst(&b) {
                highlights.push(Highlight {
                    feature: *f,
                    at: c,
                    from: Some([-0.55, -0.7, 0.35]),
                    cutaway: true,
                });
            }
        } else if matches!(
            f,
            Feature::Hoodoos
                | Feature::Arches
                | Feature::Islands
                | Feature::Caves
                | Feature::Sea
                | Feature::Cliffs
        ) && let Some(k) = {
            // The first site away from the DEM's border (a close-up of a feature on the edge
            // looks at the side of the slab), else the first.
            let fr = b.frame();
            let (xm, ym) = (
                (fr.width - 1) as f32 * fr.cx,
                (fr.height - 1) as f32 * fr.cy,
            );
            let m = 0.12 * xm.min(ym);
            e.sites
                .iter()
                .position(|p| p[0] > m && p[0] < xm - m && p[1] > m && p[1] < ym - m)
                .or((!e.sites.is_empty()).then_some(0))
        } {
            highlights.push(Highlight {
                feature: *f,
                at: e.sites[k],
                from: e.axes.get(k).or(e.axes.first()).copied(),
                cutaway: false,
            });
        }
    }
    let has_sea = effects.iter().any(|(f, e)| {
        matches!(f, Feature::Sea | Feature::Caves | Feature::Cliffs) && e.primitives > 0
    });
    let scene = b.build(true)?;
    Ok((
        scene,
        RecipeReport {
            effects,
            sea_level,
            has_sea,
            dims,
            geology,
            deviation,
            section_line,
            highlights,
        },
    ))
}

/// Centre of the karst spheres in the densest column block (for a close-up camera).
fn densest_karst(b: &SceneBuilder) -> Option<[f32; 3]> {
    let f = b.frame();
    let cell = 8.0 * f.cx.max(f.cy);
    let mut bins: std::collections::BTreeMap<(i64, i64), (usize, [f64; 3])> = Default::default();
    for (c, _, karst) in b.carvings() {
        if !karst {
            continue;
        }
        let e = bins
            .entry(((c[0] / cell) as i64, (c[1] / cell) as i64))
            .or_insert((0, [0.0; 3]));
        e.0 += 1;
        for k in 0..3 {
            e.1[k] += c[k] as f64;
        }
    }
    bins.values()
        .max_by_key(|v| v.0)
        .map(|(n, s)| s.map(|v| (v / *n as f64) as f32))
}

/// The west-east line through the DEM row holding the most karst spheres (or carving
/// spheres when there is no karst).
fn best_section_line(b: &SceneBuilder) -> ([f32; 2], [f32; 2]) {
    let f = b.frame();
    let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
    let mut counts = vec![0usize; f.height];
    // Karst passages when there are any (weathering pits would win the count otherwise).
    let any_karst = b.carvings().iter().any(|c| c.2);
    for (c, _, karst) in b.carvings() {
        if any_karst && !karst {
            continue;
        }
        let i = ((c[1] / f.cy).round().max(0.0) as usize).min(f.height - 1);
        counts[i] += 1;
    }
    let best = counts
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0)))
        .filter(|x| *x.1 > 0)
        .map_or(0.5 * ym, |(i, _)| i as f32 * f.cy);
    ([0.0, best], [xm, best])
}

/// Close-up renders of the first landforms a recipe placed (up to four, one per highlight, each
/// framed by the size of its kind), side by side in one image, with their feature names; a
/// closer oblique view of the middle of the scene when nothing was placed. `tile` is the size
/// and shading of one close-up.
pub fn render_closeups(
    scene: &Scene,
    rep: &RecipeReport,
    tile: &RenderSettings,
) -> Result<(Image, Vec<String>)> {
    let d = &rep.dims;
    let mut tiles = Vec::new();
    let mut names = Vec::new();
    for h in rep.highlights.iter().take(4) {
        let size = match h.feature {
            Feature::Hoodoos => d.hoodoo_height_m * 3.5,
            Feature::Arches => d.arch_span_m * 3.0,
            Feature::Islands => d.island_radius_m * 8.0,
            Feature::Karst => d.karst_radius_m * 40.0,
            _ => d.sea_height_m * 6.0,
        };
        let dist = size.max(4.0 * d.voxel_m);
        if h.cutaway {
            // Eye in the removed rock, looking at the cut face through `at`.
            let v = h.from.unwrap_or([-0.55, -0.7, 0.35]);
            let dir = crate::math::normalize(v);
            let cam = Camera {
                eye: crate::math::add(h.at, crate::math::mul(dir, dist)),
                target: h.at,
                up: [0.0, 0.0, 1.0],
                fov_deg: 40.0,
            };
            let s = RenderSettings {
                cutaway: Some((h.at, crate::math::normalize([v[0], v[1], 0.0]))),
                sea_level: None,
                ..*tile
            };
            tiles.push(render(scene, &cam, &s)?);
            names.push(format!("{} (cut-away)", h.feature));
            continue;
        }
        // Hoodoos are placed by their foot: aim at mid-height.
        let at = if h.feature == Feature::Hoodoos {
            [h.at[0], h.at[1], h.at[2] + 0.5 * d.hoodoo_height_m]
        } else {
            h.at
        };
        let cam = match h.from {
            Some(v) => Camera::closeup_from(scene, at, dist, [v[0], v[1], 0.08]),
            None => Camera::closeup(scene, at, dist),
        };
        tiles.push(render(scene, &cam, tile)?);
        names.push(h.feature.to_string());
    }
    if tiles.is_empty() {
        let b = scene.bbox();
        let c = b.center();
        let z = scene.dem_height(c[0], c[1]).unwrap_or(c[2]);
        let dist = 0.3 * b.size()[0].max(b.size()[1]);
        tiles.push(render(
            scene,
            &Camera::closeup(scene, [c[0], c[1], z], dist),
            tile,
        )?);
        names.push("centre".into());
    }
    Ok((strip(&tiles), names))
}

/// Images side by side (top-aligned, black below the shorter ones).
fn strip(tiles: &[Image]) -> Image {
    let h = tiles.iter().map(|t| t.height).max().unwrap_or(1);
    let w: usize = tiles.iter().map(|t| t.width).sum::<usize>().max(1);
    let mut rgb = vec![0u8; w * h * 3];
    let mut x0 = 0;
    for t in tiles {
        for y in 0..t.height {
            let src = &t.rgb[y * t.width * 3..(y + 1) * t.width * 3];
            rgb[(y * w + x0) * 3..(y * w + x0 + t.width) * 3].copy_from_slice(src);
        }
        x0 += t.width;
    }
    Image {
        width: w,
        height: h,
        rgb,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feature_lists_parse_and_reject_unknown_names() {
        assert_eq!(
            Feature::parse_list("karst, sea,karst").unwrap(),
            vec![Feature::Sea, Feature::Karst]
        );
        let e = Feature::parse_list("sea,volcano").unwrap_err().to_string();
        assert!(e.contains("feature") && e.contains("volcano"), "{e}");
        for f in Feature::ALL {
            assert_eq!(f.name().parse::<Feature>().unwrap(), f);
        }
    }

    #[test]
    fn recipe_rejects_bad_settings() {
        let hf = Heightfield::from_fn(8, 8, 10.0, 10.0, |x, y| (x + y) as f32);
        let e = build_recipe(
            &hf,
            &Recipe {
                scale: f32::NAN,
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("scale"), "{e}");
        let e = build_recipe(
            &hf,
            &Recipe {
                mask: Some(vec![1.0; 3]),
                ..Default::default()
            },
        )
        .unwrap_err();
        assert!(e.to_string().contains("mask"), "{e}");
    }
}
