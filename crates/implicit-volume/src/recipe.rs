//! Ready-made scenes: a list of [`Feature`]s applied to a DEM with parameters scaled to its
//! cell size and relief ([`Recipe`], [`build_recipe`]). This is what the `relief volume`
//! command and the pipeline's `volume` stage run; the individual generators of
//! [`crate::scene::SceneBuilder`] stay available for finer control.
//!
//! Scaling: with `L` the larger DEM cell size, shallow-erosion samples are `0.75 L` apart with
//! `2 L` spheres (section 4.1), karst spheres are `1.2 L` with steps of `L` (section 4.2),
//! hoodoos are `6 L` tall, arches span `8 L`, islands have a radius of `4 L`. The geology is
//! [`Geology::layered_default`] with a period of a sixth of the relief (at least `2 L`).

use std::str::FromStr;

use relief_heightfield::Heightfield;

use crate::error::{Error, Result};
use crate::geology::Geology;
use crate::scene::{
    ArchSettings, EffectReport, HoodooSettings, ImplicitizeSettings, IslandSettings, KarstSettings,
    RainErosion, Region, Scene, SceneBuilder, SeaErosion, Weathering, WindErosion,
};

/// One landform effect of a [`Recipe`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Feature {
    /// Sea erosion of the shore band (section 4.1, figure 5): notches and cliff undercuts.
    Sea,
    /// Sea caves dug inland from the most eroded shore samples (implies the sea band).
    Caves,
    /// Karst network by invasion percolation from the sinkholes (section 4.2).
    Karst,
    /// Hoodoos on gentle ground (figure 3).
    Hoodoos,
    /// Natural arches.
    Arches,
    /// Floating islands.
    Islands,
    /// Wind and rain erosion of exposed and steep faces: cliffs with overhangs.
    Overhangs,
}

impl Feature {
    /// Every feature, in the order a recipe applies them.
    pub const ALL: [Feature; 7] = [
        Feature::Sea,
        Feature::Caves,
        Feature::Karst,
        Feature::Overhangs,
        Feature::Hoodoos,
        Feature::Arches,
        Feature::Islands,
    ];

    /// The name used on command lines and in specs.
    pub fn name(self) -> &'static str {
        match self {
            Feature::Sea => "sea",
            Feature::Caves => "caves",
            Feature::Karst => "karst",
            Feature::Hoodoos => "hoodoos",
            Feature::Arches => "arches",
            Feature::Islands => "islands",
            Feature::Overhangs => "overhangs",
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
                    "must be one of sea, caves, karst, hoodoos, arches, islands, overhangs",
                )
            })
    }
}

impl std::fmt::Display for Feature {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What to build on a DEM.
#[derive(Debug, Clone, PartialEq)]
pub struct Recipe {
    /// Effects to apply (any order; applied in [`Feature::ALL`] order).
    pub features: Vec<Feature>,
    /// Sea level (m); `None` = the 25th percentile of the DEM's elevations, so an inland DEM
    /// gets a lake shore to erode.
    pub sea_level: Option<f32>,
    /// Per-cell weights in `[0, 1]` (row-major, DEM size) limiting every effect; `None` =
    /// everywhere.
    pub mask: Option<Vec<f32>>,
    /// Multiplies every length of the scaled parameters (module docs); 1 = default.
    pub scale: f32,
    /// Karst budget (carving steps).
    pub karst_budget: usize,
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
            karst_budget: 600,
            seed: 1,
        }
    }
}

/// Deviation of the implicitised DEM's surface `f = T` from the DEM samples.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
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
    /// Length unit `L` of the scaled parameters (m).
    pub unit: f32,
    /// Implicitisation deviation of the plain DEM primitive.
    pub deviation: Deviation,
    /// A horizontal segment (scene x, y) crossing the most carvings: where a vertical section
    /// shows the tunnels and caves best (the middle west-east line when nothing was carved).
    pub section_line: ([f32; 2], [f32; 2]),
}

fn percentile(hf: &Heightfield, q: f32) -> f32 {
    let mut v: Vec<f32> = hf
        .as_slice()
        .iter()
        .copied()
        .filter(|z| z.is_finite())
        .collect();
    v.sort_by(f32::total_cmp);
    if v.is_empty() {
        return 0.0;
    }
    v[((v.len() - 1) as f32 * q).round() as usize]
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
    if !(recipe.scale.is_finite() && recipe.scale > 0.0) {
        return Err(Error::param(
            "scale",
            recipe.scale,
            "must be finite and > 0",
        ));
    }
    if let Some(s) = recipe.sea_level
        && !s.is_finite()
    {
        return Err(Error::param("sea_level", s, "must be finite"));
    }
    let (cx, cy) = hf.cell_size();
    let l = cx.max(cy) as f32 * recipe.scale;
    let (lo, hi) = hf
        .min_max()
        .ok_or(Error::param("heightfield", "all void", "needs samples"))?;
    let relief = (hi - lo).max(l);
    let mag = [
        (hf.width() - 1) as f32 * cx as f32,
        (hf.height() - 1) as f32 * cy as f32,
        lo.abs(),
        hi.abs(),
        1.0,
    ]
    .into_iter()
    .fold(0.0f32, f32::max);
    if !(1e-3 * mag..=5.0 * mag).contains(&l) {
        return Err(Error::param(
            "scale",
            recipe.scale,
            "makes the feature unit out of scale with the DEM (1e-3 to 5 times its extent)",
        ));
    }
    let center = [
        (hf.width() - 1) as f32 * cx as f32 * 0.5,
        (hf.height() - 1) as f32 * cy as f32 * 0.5,
        0.5 * (lo + hi),
    ];
    let geo = Geology::layered_default(center, (relief / 6.0).max(2.0 * l), recipe.seed)?;
    let mut b = SceneBuilder::new(hf, geo, &ImplicitizeSettings::default())?;
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
    if has(Feature::Sea) || has(Feature::Caves) {
        let s = SeaErosion {
            weathering: Weathering {
                spacing: 0.75 * l,
                radius: 2.0 * l,
                energy: 3.0,
                seed: sub(1),
                ..Default::default()
            },
            sea_level,
            depth: 0.5 * l,
            height: 3.0 * l,
            peak: 0.5 * l,
            reach: 4.0 * l,
            caves: if has(Feature::Caves) { 10 } else { 0 },
            cave_length: 6.0 * l,
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
        let k = KarstSettings {
            radius: 1.2 * l,
            step: l,
            poisson_radius: 0.7 * l,
            sub_spheres: 1,
            budget: recipe.karst_budget,
            max_sinkholes: 64,
            rho0: 0.55,
            seed: sub(2),
            ..Default::default()
        };
        effects.push((Feature::Karst, b.karst(&k, &region)?));
    }
    if has(Feature::Overhangs) {
        // Only strongly stressed faces (exposed to the wind, steep for the rain) are attacked.
        let w = Weathering {
            spacing: l,
            radius: 1.5 * l,
            energy: 2.0,
            threshold: 0.45,
            seed: sub(3),
            ..Default::default()
        };
        let mut rep = b.wind_erosion(
            &WindErosion {
                weathering: w,
                direction: [1.0, 0.3],
            },
            &region,
        )?;
        let r2 = b.rain_erosion(
            &RainErosion {
                weathering: Weathering { seed: sub(4), ..w },
                full_slope_deg: 40.0,
            },
            &region,
        )?;
        rep.candidates += r2.candidates;
        rep.primitives += r2.primitives;
        effects.push((Feature::Overhangs, rep));
    }
    if has(Feature::Hoodoos) {
        let h = HoodooSettings {
            count: 6,
            height: 6.0 * l,
            radius: 1.2 * l,
            spacing: 6.0 * l,
            max_slope_deg: 25.0,
            seed: sub(5),
        };
        effects.push((Feature::Hoodoos, b.hoodoos(&h, &region)?));
    }
    if has(Feature::Arches) {
        let a = ArchSettings {
            count: 2,
            span: 8.0 * l,
            height: 4.0 * l,
            thickness: 1.2 * l,
            seed: sub(6),
        };
        effects.push((Feature::Arches, b.arches(&a, &region)?));
    }
    if has(Feature::Islands) {
        let i = IslandSettings {
            count: 2,
            radius: 4.0 * l,
            altitude: (0.3 * relief).max(8.0 * l),
            seed: sub(7),
        };
        effects.push((Feature::Islands, b.floating_islands(&i, &region)?));
    }
    let section_line = best_section_line(&b);
    let scene = b.build(true)?;
    Ok((
        scene,
        RecipeReport {
            effects,
            sea_level,
            unit: l,
            deviation,
            section_line,
        },
    ))
}

/// The west-east line through the DEM row band holding the most carving spheres.
fn best_section_line(b: &SceneBuilder) -> ([f32; 2], [f32; 2]) {
    let f = b.frame();
    let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
    let mut counts = vec![0usize; f.height];
    for (c, _, _) in b.carvings() {
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
