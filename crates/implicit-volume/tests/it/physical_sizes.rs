//! Issue 42, physical sizes: the landforms are the same size in metres whatever the crop, the
//! voxel follows them, and a DEM too coarse for a surface feature refuses it naming the cell
//! size it needs.
#![allow(clippy::print_stderr)]

use relief_heightfield::Heightfield;
use relief_implicit_volume::recipe::{FeatureSizes, SizeStats};
use relief_implicit_volume::*;
use relief_testdata::dem_crop;

fn run(hf: &Heightfield, features: Vec<Feature>) -> RecipeReport {
    let recipe = Recipe {
        features,
        ..Default::default()
    };
    build_recipe(hf, &recipe).unwrap().1
}

fn stats<'a>(rep: &'a RecipeReport, key: &str) -> &'a SizeStats {
    rep.dims
        .sizes
        .get(key)
        .unwrap_or_else(|| panic!("no {key} sizes: {:?}; {:?}", rep.dims.sizes, rep.dims.notes))
}

/// A window of the grand canyon resampled (bicubic) to `cell` metres: a fine DEM for the
/// surface features.
fn fine_window(x: usize, y: usize, n: usize, cell: f64) -> Option<Heightfield> {
    let hf = dem_crop("grandcanyon", x, y, n, n)?;
    let m = ((n as f64 * hf.cell_size().0) / cell).round() as usize;
    Some(hf.resample(m, m).unwrap())
}

/// Karst passages and floating islands have the same size distribution on a 128 x 128 crop of
/// the grand canyon and on the whole 512 x 512 DEM (31.6 km), radii of metres (not the 34-74 m
/// that followed the crop's voxel); the voxel of the whole DEM is what 512 mesh cells afford,
/// and a note says so.
#[test]
fn karst_sizes_do_not_depend_on_the_crop() {
    let (Some(crop), Some(whole)) = (
        dem_crop("grandcanyon", 200, 160, 128, 128),
        dem_crop("grandcanyon", 0, 0, 512, 512),
    ) else {
        return;
    };
    let a = run(&crop, vec![Feature::Karst, Feature::Islands]);
    let b = run(&whole, vec![Feature::Karst, Feature::Islands]);
    let def = FeatureSizes::default();
    for key in ["karst", "islands"] {
        let (sa, sb) = (stats(&a, key), stats(&b, key));
        eprintln!("{key}: crop {sa:?}\n{key}: whole {sb:?}");
        assert!(sa.count > 0 && sb.count > 0);
        // Karst: thousands of steps, the same quantiles; islands: a few, the same mean.
        let pairs = if key == "karst" {
            vec![(sa.min, sb.min), (sa.median, sb.median), (sa.max, sb.max)]
        } else {
            vec![(sa.mean, sb.mean)]
        };
        for (x, y) in pairs {
            assert!((x - y).abs() <= 0.15 * x.max(y), "{key}: {sa:?} vs {sb:?}");
        }
    }
    let k = stats(&a, "karst");
    assert!(
        k.max <= def.karst_radius_m * 1.3 && k.min >= 0.4 * def.karst_radius_m,
        "{k:?}"
    );
    for r in [&a, &b] {
        let i = stats(r, "islands");
        let main = def.island_radius_m;
        assert!(i.max <= 1.2 * main && i.min >= 0.25 * main, "{i:?}");
    }
    assert_eq!(a.dims.strata_period_m, Some(def.strata_period_m));
    assert_eq!(a.dims.karst_radius_m, b.dims.karst_radius_m);
    // The voxel: 512 cells over the extent on both (the karst asks for 2 m), with a note.
    assert!(
        b.dims.voxel_m > 60.0 && a.dims.voxel_m > 15.0,
        "{:?}",
        b.dims
    );
    assert!(
        b.dims.notes.iter().any(|n| n.contains("mesh voxel")),
        "{:?}",
        b.dims.notes
    );
}

/// On the grand canyon's 61.7 m cells, hoodoos, arches and overhangs are refused, each note
/// naming the cell size it needs; on a sea level the shore features too. Nothing is carved
/// kilometres wide.
#[test]
fn coarse_dems_refuse_surface_features_naming_the_cell_they_need() {
    let Some(hf) = dem_crop("grandcanyon", 200, 160, 64, 64) else {
        return;
    };
    let recipe = Recipe {
        features: Feature::ALL.to_vec(),
        sea_level: Some(1200.0),
        ..Default::default()
    };
    let (_, rep) = build_recipe(&hf, &recipe).unwrap();
    let placed: Vec<Feature> = rep.effects.iter().map(|e| e.0).collect();
    assert_eq!(
        placed,
        vec![Feature::Karst, Feature::Islands],
        "{:?}",
        rep.dims.notes
    );
    for (name, cell) in [
        ("hoodoos", "12.0 m"),
        ("arches", "15.0 m"),
        ("overhangs", "20.0 m"),
        ("cliffs", "15.0 m"),
        ("sea", "15.0 m"),
    ] {
        assert!(
            rep.dims
                .notes
                .iter()
                .any(|n| n.starts_with(&format!("{name} refused")) && n.contains(cell)),
            "{name}: {:?}",
            rep.dims.notes
        );
    }
    assert_eq!(rep.dims.needed_cell_m, Some(12.0));
}

/// Hoodoos and arches on amplified (resampled to 4 m) windows of the grand canyon, a 1.5 km
/// and a 2.5 km one: heights and spans in metres within the natural ranges, the same
/// distribution on both.
#[test]
fn hoodoos_and_arches_are_physical_on_fine_windows() {
    let (Some(small), Some(large)) = (
        fine_window(234, 194, 24, 4.0),
        fine_window(224, 184, 40, 4.0),
    ) else {
        return;
    };
    let a = run(&small, vec![Feature::Hoodoos, Feature::Arches]);
    let b = run(&large, vec![Feature::Hoodoos, Feature::Arches]);
    let (ha, hb) = (stats(&a, "hoodoos"), stats(&b, "hoodoos"));
    eprintln!(
        "hoodoos: {ha:?}\n{hb:?}\narches: {:?}",
        b.dims.sizes.get("arches")
    );
    for h in [ha, hb] {
        assert!(h.count > 0 && h.min >= 1.5 && h.max <= 45.0, "{h:?}");
    }
    assert!(
        (ha.median - hb.median).abs() <= 0.25 * ha.median,
        "{ha:?} vs {hb:?}"
    );
    for r in [&a, &b] {
        if let Some(s) = r.dims.sizes.get("arches") {
            assert!(s.max <= 120.0 && s.min >= 1.0, "{s:?}");
        }
        assert!(
            r.dims.voxel_m <= 4.0 / 3.0 + 1e-3
                || r.dims.notes.iter().any(|n| n.contains("mesh voxel"))
        );
    }
}

/// A topobathy-like DEM of 567 m cells with a coast: no shore feature is built (refused, with
/// the cell it needs), so no cave is kilometres wide.
#[test]
fn a_567_m_coast_gets_no_kilometre_caves() {
    let hf = Heightfield::from_fn(48, 48, 567.0, 567.0, |x, _| (x as f32 - 20.0) * 30.0);
    let recipe = Recipe {
        features: vec![Feature::Sea, Feature::Caves, Feature::Cliffs],
        ..Default::default()
    };
    let (_, rep) = build_recipe(&hf, &recipe).unwrap();
    assert!(rep.has_sea, "{:?}", rep.dims.notes);
    assert!(rep.effects.is_empty(), "{:?}", rep.effects);
    assert!(
        rep.dims
            .notes
            .iter()
            .any(|n| n.contains("at most 15.0 m") && n.contains("567.0 m")),
        "{:?}",
        rep.dims.notes
    );
    // With the cells the shore needs (a 10 m cliffed coast: caves need rock rising over a
    // roof), caves of metres.
    let hf = Heightfield::from_fn(96, 96, 10.0, 10.0, |x, y| {
        ((x as f32 - 30.0) * 15.0).clamp(-10.0, 40.0) + 4.0 * ((y as f32) * 0.3).sin()
    });
    let (_, rep) = build_recipe(&hf, &recipe).unwrap();
    let caves = stats(&rep, "caves");
    assert!(caves.count > 0 && caves.max <= 5.0, "{caves:?}");
}
