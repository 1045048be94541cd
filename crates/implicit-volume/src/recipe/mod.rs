//! Ready-made scenes: a list of [`Feature`]s applied to a DEM with physical parameters in
//! metres derived from the DEM's relief and extent ([`Recipe`], [`build_recipe`],
//! [`Dimensions`]). This is what the `relief volume` command and the pipeline's `volume` stage
//! run; the individual generators of [`crate::scene::SceneBuilder`] stay available for finer
//! control.
//!
//! # Sizes
//! Every landform has a size in metres from geology and geomorphology ([`FeatureSizes`], sources
//! in `docs/VOLUME_SIZES.md`), times [`Recipe::scale`]: never from the DEM's cell, extent or
//! relief, so a feature is the same size on a 128 x 128 crop and on the whole DEM. What follows
//! the features, not the other way round:
//! * the meshing voxel `v`: a third of the smallest feature asked for
//!   ([`FeatureSizes::voxel_for`]), but never finer than 1/512 of the larger horizontal extent
//!   (the mesh stays within ~512 cells a side; a note then names the window that would mesh
//!   the features, [`Dimensions::affordable_extent_m`]); the scene itself (renders, close-ups,
//!   sections) holds the features at their size whatever the voxel;
//! * the DEM cell: a surface feature needs cells of at most [`FeatureSizes::needed_cell_m`]
//!   (hoodoos their height, arches half their span, shore features half the cliff retreat,
//!   weathering five hollows); on a coarser DEM the feature is refused with a note naming the
//!   cell it needs (`relief volume` amplifies a window of the DEM to it first);
//! * karst passages: radius [`FeatureSizes::karst_radius_m`], at most half the median soft
//!   stratum, budget from a passage density ([`Densities::karst_km_per_km2`]) capped at
//!   [`KARST_MAX_STEPS`] steps;
//! * weathering (sea notches, wind and rain hollows) considers at most
//!   [`WEATHERING_MAX_SAMPLES`] surface samples: beyond, the effect is refused with a note
//!   naming the window that fits;
//! * the default geology's strata: [`FeatureSizes::strata_period_m`], at fixed elevations;
//! * the stepped ground under the features ([`Recipe::benches`]): each resistant bed's cliff
//!   and bench are as tall as the bed is thick in the geology (metres), cut on the DEM
//!   interpolated to the voxel, and only when the voxel is finer than the beds;
//! * the closing floor `max(0.3 R, 8 v)` below the lowest sample (`R` the relief);
//! * counts from densities per km^2 ([`Densities`]) over the DEM's area (at least one).
//!
//! [`Dimensions::sizes`] gives, per feature, the distribution of the placed instances' sizes.
//!
//! # Sea
//! The shore features ([`Feature::Sea`], [`Feature::Caves`], [`Feature::Cliffs`]) need a sea
//! level. [`Recipe::sea_level`] `Some(z)` puts the shore at `z` whatever the DEM (a lake shore
//! in a canyon on purpose); `None` (the default) uses the sea the DEM has ([`detect_sea`]:
//! border-connected samples at or below 0 m, or a large flat border-connected minimum), and its
//! shore is that of the border-connected sea only (a closed depression below the level inland
//! is not eroded as a shore). When the DEM has none (an inland DEM), the shore features place nothing, a note says so, and
//! [`RecipeReport::has_sea`] is false, so no water is drawn.

use std::str::FromStr;

use relief_heightfield::Heightfield;

use crate::error::{Error, Result};
use crate::geology::GeologySpec;
use crate::render::{Camera, Image, RenderSettings, render};
use crate::scene::{
    ArchSettings, EffectReport, HoodooSettings, ImplicitizeSettings, IslandSettings, KarstSettings,
    RainErosion, Region, Scene, SceneBuilder, SeaCliffs, SeaErosion, UndercutSettings, Weathering,
    WindErosion,
};

mod benches;
mod build;
mod closeups;
mod sea;
mod sizes;

pub use self::build::{build_recipe, build_recipe_with_progress};
pub use self::closeups::{closeup_views, render_closeups};
pub use self::sizes::{FeatureSizes, SizeStats};

/// Largest default karst budget (carving steps), which keeps the tree within a few hundred
/// thousand nodes; a larger area gets the same passage size, sparser.
pub const KARST_MAX_STEPS: usize = 16_384;

/// Most surface samples a weathering effect (sea, wind, rain) may consider: at physical
/// sizes (1-2 m hollows) this is a window of about a kilometre; a larger DEM refuses the effect
/// with a note naming the window that fits.
pub const WEATHERING_MAX_SAMPLES: usize = 1 << 21;
use self::closeups::{best_section_line, densest_karst};
pub use self::sea::{
    FLAT_SEA_SHARE, SEA_FLAT_NOISE_M, SEA_MIN_CELLS, SEA_MIN_SHARE, SEA_PITS, SeaDetection,
    SeaKind, Seabed, detect_sea, sea_flat_tolerance, seabed,
};
/// The implicitisation deviation and the sea mask are the scene's (kept at these paths).
pub use crate::scene::{Deviation, border_connected_at_or_below};

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
    /// Overhangs: soft rock retreating under resistant beds on steep faces
    /// ([`SceneBuilder::undercuts`]), with wind and rain erosion of exposed and steep faces
    /// (both [`Feature::Wind`] and [`Feature::Rain`]).
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
    /// [`Feature::ALL`]'s. `"none"` is the empty list (the DEM alone).
    pub fn parse_list(s: &str) -> Result<Vec<Feature>> {
        let mut v = Vec::new();
        if s.trim() == "none" {
            return Ok(v);
        }
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
                    "must be one of cliffs, sea, caves, karst, hoodoos, arches, islands, overhangs, wind, rain (or none alone)",
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
            hoodoos_per_km2: 60.0,
            arches_per_km2: 2.0,
            islands_per_km2: 0.1,
            caves_per_km2: 10.0,
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
    /// Sea level (m) of the shore features (sea, caves, cliffs). `None` = the DEM's own sea
    /// ([`detect_sea`]: 0 m when enough border-connected samples are at or below 0 m, else a
    /// large flat border-connected minimum); on a DEM without sea the shore features are
    /// skipped with a note. `Some(z)` = a shore at `z` whatever the DEM (e.g. a lake in a
    /// canyon).
    pub sea_level: Option<f32>,
    /// Give the DEM's own sea a floor when it is stored flat (SRTM's 0 m; [`seabed`]): the
    /// coast's slope continued under the water down to a depth from the relief. `false` keeps
    /// the flat surface (the DEM exactly).
    pub seabed: bool,
    /// Per-cell weights in `[0, 1]` (row-major, DEM size) limiting every effect; `None` =
    /// everywhere.
    pub mask: Option<Vec<f32>>,
    /// Multiplies every feature size ([`FeatureSizes`]); 1 = default.
    pub scale: f32,
    /// The landforms' sizes in metres (before [`Recipe::scale`]).
    pub sizes: FeatureSizes,
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
    /// Stepped slopes (module `benches`): the fraction of a resistant bed's outcrop on a slope
    /// that becomes a bench on the bed's top, the rest its cliff; in `[0, 1)`, 0 = the DEM's
    /// smooth slopes. Cut when the meshing voxel resolves the beds (a bed a few metres thick
    /// on a refined window), with any feature asked for.
    pub benches: f32,
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
            seabed: true,
            mask: None,
            scale: 1.0,
            sizes: FeatureSizes::default(),
            voxel: None,
            geology: None,
            karst_budget: None,
            densities: Densities::default(),
            wind: [1.0, 0.3],
            wind_strength: 2.0,
            rain_strength: 2.0,
            benches: 0.8,
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
    /// Nominal hoodoo height (m): each stands to the resistant bed nearest it (0.6 to 1.4
    /// times it; `sizes` has the heights placed).
    pub hoodoo_height_m: f32,
    /// Hoodoo column radius in rock of resistance 0.73 (m; `0.45 + 0.75 rho` times it).
    pub hoodoo_radius_m: f32,
    /// Hoodoos asked for.
    pub hoodoo_count: usize,
    /// Median arch span (m): each arch's is drawn around it (`sizes` has the spans placed).
    pub arch_span_m: f32,
    /// Nominal opening height (m): 0.6 of the median span (each arch's opening runs from
    /// its floor up to its bridge bed, [`crate::scene::SceneBuilder::arches`]).
    pub arch_height_m: f32,
    /// Arch thickness (m).
    pub arch_thickness_m: f32,
    /// Arches asked for.
    pub arch_count: usize,
    /// Floating island radius (m): a cluster's main island, the others down to a third.
    pub island_radius_m: f32,
    /// The placed floating islands' radii (m).
    pub island_radii_m: Vec<f32>,
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
    /// The finest DEM cell the asked features need (m; [`FeatureSizes::needed_cell_for`]).
    pub needed_cell_m: Option<f32>,
    /// The largest window side (m) the mesh can afford at the voxel the features ask for
    /// (512 voxels of [`FeatureSizes::voxel_for`]).
    pub affordable_extent_m: Option<f32>,
    /// Per placed feature (by name), the distribution of its instances' sizes in metres: karst
    /// passage radii (per carved step), hoodoo heights, arch spans, sea cave radii, notch and
    /// weathering sphere radii, cliff retreat, floating island radii.
    pub sizes: std::collections::BTreeMap<String, SizeStats>,
    /// Features skipped or adjusted, and why.
    pub notes: Vec<String>,
}

/// What [`build_recipe`] did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RecipeReport {
    /// One entry per applied feature.
    pub effects: Vec<(Feature, EffectReport)>,
    /// Sea level of the shore features (m): the recipe's, else the detected one; `None` = the
    /// DEM has no sea and the recipe sets none (shore features skipped).
    pub sea_level: Option<f32>,
    /// The sea found in the DEM when the recipe sets no level ([`detect_sea`]).
    pub sea: Option<SeaDetection>,
    /// The floor given to a flat sea ([`Recipe::seabed`]), when one was.
    pub seabed: Option<Seabed>,
    /// Whether the scene has a sea (`sea_level` is set: detected in the DEM or given by the
    /// recipe), i.e. water to draw at `sea_level`, with or without shore features.
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
    /// Horizontal direction from `at` towards a good eye position (arches: along the gap,
    /// to see through the opening); `None` = the default oblique view from the south-west.
    pub from: Option<[f32; 3]>,
    /// Underground (karst): the close-up is a cut-away through `at`, facing the eye.
    pub cutaway: bool,
    /// The landform's own size (m) when measured ([`EffectReport::sizes_m`]: a hoodoo's
    /// height, an arch's span, an island's radius, an undercut's depth), which frames its
    /// close-up; `None` = the recipe's nominal size.
    pub size_m: Option<f32>,
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
        if !(0.0..1.0).contains(&self.benches) {
            return Err(Error::param("benches", self.benches, "must be in [0, 1)"));
        }
        for (n, v) in named_fields!(self; wind_strength, rain_strength) {
            if !(v.is_finite() && v > 0.0 && v <= 100.0) {
                return Err(Error::param(n, v, "must be in (0, 100]"));
            }
        }
        let densities = named_fields!(self.densities;
            hoodoos_per_km2, arches_per_km2, islands_per_km2,
            caves_per_km2, karst_km_per_km2, karst_cliff_seeds_per_km2,
        );
        Error::check_all_in(&densities, 0.0..=1e4, "must be in [0, 10000]")?;
        self.sizes.check()?;
        if let Some(v) = self.voxel {
            Error::check_positive("voxel", v)?;
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

#[cfg(test)]
mod tests;
