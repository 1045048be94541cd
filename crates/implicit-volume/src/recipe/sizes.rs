//! Physical feature sizes ([`FeatureSizes`]): metres from geology and geomorphology, never from
//! the DEM's cell, extent or relief, and the DEM cell each feature needs
//! ([`FeatureSizes::needed_cell_m`]). The sources are in `docs/VOLUME_SIZES.md`.

use super::Feature;
use crate::error::{Error, Result};

/// Default sizes of the landforms in metres. [`super::Recipe::scale`] multiplies every one.
///
/// | size | default | natural range | source (`docs/VOLUME_SIZES.md`) |
/// |---|---|---|---|
/// | karst passage radius | 3 m | 0.5-15 m | Palmer 1991; Ford & Williams 2007 |
/// | strata period (default geology) | 20 m | beds 0.1-10 m, members 10-100 m | Boggs 2011 |
/// | hoodoo height | 12 m | 1.5-45 m | NPS Bryce Canyon |
/// | hoodoo column radius | 2 m | 0.5-5 m | NPS Bryce Canyon |
/// | arch span | 30 m | 1-120 m | NPS Arches; Natural Arch and Bridge Society |
/// | arch bridge thickness | 6 m | 2-30 m | NPS Arches (Landscape Arch 3 m at its thinnest) |
/// | sea notch and cave radius | 3 m | 1-15 m | Trenhaile 1987; Moore 1954 |
/// | height eroded above sea level | 8 m | 2-20 m (storm waves) | Trenhaile 1987 |
/// | sea cave length | 40 m | 5-300 m | Moore 1954; Waterstrat 2011 |
/// | cliff retreat | 30 m | 10-500 m | Sunamura 1992 |
/// | overhang (weathering) depth | 4 m | 0.1-10 m | Turkington & Paradise 2005 |
/// | floating island radius | 40 m | (fantasy) | - |
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FeatureSizes {
    /// Karst passage radius (visible, m); the step between passage spheres equals it.
    pub karst_radius_m: f32,
    /// Period of the default geology's strata (m; soft strata are about a third of it).
    pub strata_period_m: f32,
    /// Nominal hoodoo height (m); each stands up to the hard layer nearest that height.
    pub hoodoo_height_m: f32,
    /// Hoodoo column radius at its base (m).
    pub hoodoo_radius_m: f32,
    /// Arch span (opening width, m).
    pub arch_span_m: f32,
    /// Arch bridge thickness (m).
    pub arch_thickness_m: f32,
    /// Radius of the sea's notch-cutting spheres and of sea caves (m).
    pub sea_radius_m: f32,
    /// Height above sea level the waves still erode (m).
    pub sea_height_m: f32,
    /// Sea cave length inland (m).
    pub cave_length_m: f32,
    /// How far sea cliffs cut the shore back (m).
    pub cliff_retreat_m: f32,
    /// Depth of the wind and rain hollows and undercuts (m).
    pub overhang_depth_m: f32,
    /// Main floating island radius (m).
    pub island_radius_m: f32,
}

impl Default for FeatureSizes {
    fn default() -> Self {
        Self {
            karst_radius_m: 3.0,
            strata_period_m: 20.0,
            hoodoo_height_m: 12.0,
            hoodoo_radius_m: 2.0,
            arch_span_m: 30.0,
            arch_thickness_m: 6.0,
            sea_radius_m: 3.0,
            sea_height_m: 8.0,
            cave_length_m: 40.0,
            cliff_retreat_m: 30.0,
            overhang_depth_m: 4.0,
            island_radius_m: 40.0,
        }
    }
}

impl FeatureSizes {
    /// Every size multiplied by `k`.
    pub fn scaled(&self, k: f32) -> Self {
        let mut s = *self;
        for v in s.fields_mut() {
            *v *= k;
        }
        s
    }

    fn fields_mut(&mut self) -> [&mut f32; 12] {
        [
            &mut self.karst_radius_m,
            &mut self.strata_period_m,
            &mut self.hoodoo_height_m,
            &mut self.hoodoo_radius_m,
            &mut self.arch_span_m,
            &mut self.arch_thickness_m,
            &mut self.sea_radius_m,
            &mut self.sea_height_m,
            &mut self.cave_length_m,
            &mut self.cliff_retreat_m,
            &mut self.overhang_depth_m,
            &mut self.island_radius_m,
        ]
    }

    /// Checks every size is finite and in `[0.05, 5000]` m (the error names the field).
    pub fn check(&self) -> Result<()> {
        let s = *self;
        let fields = named_fields!(s;
            karst_radius_m, strata_period_m, hoodoo_height_m, hoodoo_radius_m, arch_span_m,
            arch_thickness_m, sea_radius_m, sea_height_m, cave_length_m, cliff_retreat_m,
            overhang_depth_m, island_radius_m,
        );
        Error::check_all_in(&fields, 0.05..=5000.0, "must be in [0.05, 5000] m")
    }

    /// The size across the feature the mesh should resolve with a few voxels (m): a karst
    /// passage's or a sea cave's diameter, a hoodoo column's, an arch's bridge, an
    /// overhang's depth, a cliff's ledge (the sea radius); `None` for the features that add
    /// nothing smaller than the others.
    pub fn smallest_m(&self, f: Feature) -> Option<f32> {
        match f {
            Feature::Karst => Some(2.0 * self.karst_radius_m),
            Feature::Hoodoos => Some(2.0 * self.hoodoo_radius_m),
            Feature::Arches => Some(self.arch_thickness_m),
            Feature::Sea | Feature::Caves | Feature::Cliffs => Some(2.0 * self.sea_radius_m),
            Feature::Overhangs | Feature::Wind | Feature::Rain => Some(2.0 * self.overhang_depth_m),
            Feature::Islands => Some(self.island_radius_m),
        }
    }

    /// The coarsest DEM cell (m) a feature can be built on: its surface must be resolved at
    /// the feature's scale (a hoodoo stands on a slope no wider than itself, an arch's fin is
    /// narrower than its span, a notch and a cave open on a shore resolved at the cliff's
    /// retreat, hollows on faces a few hollows across). `None` = any cell (karst is
    /// underground, in the geology; floating islands float).
    pub fn needed_cell_m(&self, f: Feature) -> Option<f32> {
        match f {
            Feature::Hoodoos => Some(self.hoodoo_height_m),
            Feature::Arches => Some(0.5 * self.arch_span_m),
            Feature::Sea | Feature::Caves | Feature::Cliffs => Some(0.5 * self.cliff_retreat_m),
            Feature::Overhangs | Feature::Wind | Feature::Rain => Some(5.0 * self.overhang_depth_m),
            Feature::Karst | Feature::Islands => None,
        }
    }

    /// The finest cell any of `features` needs (m); `None` when none needs one.
    pub fn needed_cell_for(&self, features: &[Feature]) -> Option<f32> {
        features
            .iter()
            .filter_map(|&f| self.needed_cell_m(f))
            .reduce(f32::min)
    }

    /// The meshing voxel the features ask for (m): a third of the smallest of them.
    pub fn voxel_for(&self, features: &[Feature]) -> Option<f32> {
        features
            .iter()
            .filter_map(|&f| self.smallest_m(f))
            .reduce(f32::min)
            .map(|s| s / 3.0)
    }
}

/// Summary of one feature's sizes (m) over its placed instances.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct SizeStats {
    /// What is measured (`passage radius`, `height`, `span`, `cave radius`, ...).
    pub measure: &'static str,
    /// Instances measured (karst: carved steps; sea: notch spheres; caves: caves).
    pub count: usize,
    /// Smallest (m).
    pub min: f32,
    /// 10th percentile (m).
    pub p10: f32,
    /// Median (m).
    pub median: f32,
    /// 90th percentile (m).
    pub p90: f32,
    /// Largest (m).
    pub max: f32,
    /// Mean (m).
    pub mean: f32,
}

impl SizeStats {
    /// The statistics of `sizes` (zeros when empty).
    pub fn of(measure: &'static str, sizes: &[f32]) -> Self {
        let mut v: Vec<f32> = sizes.iter().copied().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return Self {
                measure,
                ..Default::default()
            };
        }
        v.sort_by(f32::total_cmp);
        let q = |t: f32| v[((v.len() - 1) as f32 * t).round() as usize];
        Self {
            measure,
            count: v.len(),
            min: v[0],
            p10: q(0.1),
            median: q(0.5),
            p90: q(0.9),
            max: v[v.len() - 1],
            mean: (v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64) as f32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_in_the_natural_ranges_and_scale() {
        let s = FeatureSizes::default();
        s.check().unwrap();
        assert!((1.0..=15.0).contains(&s.karst_radius_m));
        assert!((1.5..=45.0).contains(&s.hoodoo_height_m));
        assert!(s.arch_span_m <= 120.0);
        assert!((2.0..=20.0).contains(&s.sea_height_m));
        let t = s.scaled(2.0);
        assert_eq!(t.arch_span_m, 60.0);
        assert_eq!(t.strata_period_m, 40.0);
        let bad = FeatureSizes {
            arch_span_m: f32::NAN,
            ..s
        };
        assert!(bad.check().unwrap_err().to_string().contains("arch_span_m"));
        // Hoodoos need cells of at most their height; karst any.
        assert_eq!(s.needed_cell_m(Feature::Hoodoos), Some(12.0));
        assert_eq!(s.needed_cell_m(Feature::Karst), None);
        assert_eq!(
            s.needed_cell_for(&[Feature::Karst, Feature::Arches, Feature::Hoodoos]),
            Some(12.0)
        );
        assert_eq!(s.voxel_for(&[Feature::Karst]), Some(2.0));
    }

    #[test]
    fn size_stats_are_order_statistics() {
        let v: Vec<f32> = (1..=11).map(|k| k as f32).collect();
        let s = SizeStats::of("radius", &v);
        assert_eq!(
            (s.count, s.min, s.p10, s.median, s.p90, s.max, s.mean),
            (11, 1.0, 2.0, 6.0, 10.0, 11.0, 6.0)
        );
        assert_eq!(SizeStats::of("radius", &[]).count, 0);
    }
}
