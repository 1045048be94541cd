//! Tests of the hoodoos: profiles from the strata, clusters, fins, gullies, hollows.

use super::*;
use crate::geology::{Geology, test_beds};

/// Strata of 4 m soft (0.1) under 2 m hard (0.9) beds, shifted up by `z0`.
fn beds(z0: f32) -> Geology {
    test_beds(z0, (4.0, 0.1), (2.0, 0.9))
}

fn one(geo: Geology) -> (Scene, EffectReport) {
    let hf = Heightfield::from_fn(24, 24, 1.0, 1.0, |_, _| 0.0);
    let mut b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
    let s = HoodooSettings {
        count: 1,
        height: 12.0,
        radius: 2.0,
        spacing: 8.0,
        min_slope_deg: 0.0,
        max_slope_deg: 90.0,
        per_cluster: 1,
        ..Default::default()
    };
    let rep = b.hoodoos(&s, &Region::everywhere()).unwrap();
    assert_eq!(rep.features, 1, "{rep:?}");
    (b.build(true).unwrap(), rep)
}

/// Height of the highest matter over `(x, y)` below 2 m.
fn surface_z(scene: &Scene, x: f32, y: f32) -> f32 {
    top_below(scene, x, y, 2.0)
}

/// Height of the highest matter over `(x, y)` below `z0` (0.02 m steps, 10 m down).
fn top_below(scene: &Scene, x: f32, y: f32, z0: f32) -> f32 {
    (0..500)
        .map(|k| z0 - 0.02 * k as f32)
        .find(|&z| scene.inside([x, y, z]))
        .unwrap_or(f32::NEG_INFINITY)
}

/// Radius of the matter's horizontal section at height `z` around `c` (from its area).
fn radius_at(scene: &Scene, c: V3, z: f32) -> f32 {
    let step = 0.1;
    let mut n = 0;
    for a in -80..=80 {
        for b in -80..=80 {
            let p = [c[0] + a as f32 * step, c[1] + b as f32 * step, z];
            if scene.inside(p) {
                n += 1;
            }
        }
    }
    (n as f32 * step * step / std::f32::consts::PI).sqrt()
}

/// The column narrows through soft rock and bulges at hard beds, and the cap (the bed
/// nearest 12 m above the floor of its hollow, 4.2 m under the ground: the 10-12 m bed)
/// is wider than both; on strata shifted by 3 m the same settings give another hoodoo (its
/// cap on another bed, its neck at another height).
#[test]
fn hoodoo_profile_follows_the_strata() {
    let (scene, rep) = one(beds(0.0));
    let c = rep.sites[0];
    assert!(
        (c[2] + 4.2).abs() < 1e-3,
        "stands on the floor of its hollow: {c:?}"
    );
    // The hollow: air half-way down it 4 m from the axis (outside the column), the ground
    // within 0.4 m of the slope's 15 m away.
    assert!(
        !scene.inside([c[0] - 4.0, c[1], -2.1]),
        "no hollow around the column"
    );
    assert!(
        scene.inside([c[0] - 15.0, c[1], -0.4]),
        "the hollow reaches too far"
    );
    // An amphitheatre, not a dish: a flat floor out to 6 m from the axis (6.4 m, fluted),
    // then a steep wall up to the rim by 9.5 m (the blended dish it replaced: -3.85 m at
    // 3 m from the axis, -2.3 at 6, -1.2 at 9.5, -0.75 at 11).
    for d in [[-1.0, 0.0], [0.0, 1.0], [-0.7, 0.7]] {
        let at = |r: f32| surface_z(&scene, c[0] + r * d[0], c[1] + r * d[1]);
        let (floor, foot, rim) = (at(4.0), at(6.0), at(9.5));
        assert!(
            (floor + 4.2).abs() < 0.8,
            "floor {floor} at 4 m along {d:?}"
        );
        assert!(
            foot < -3.0,
            "the wall starts before 6 m along {d:?}: {foot}"
        );
        assert!(rim > -0.6, "no rim by 9.5 m along {d:?}: {rim}");
    }
    // To the cap's top: 16.2 m when a cap was its whole 2 m bed, 15.45 m with the cap at
    // most 0.6 R (1.2 m) thick.
    assert!((rep.sizes_m[0] - 15.45).abs() < 0.3, "{rep:?}");
    let (soft, hard, cap) = (
        radius_at(&scene, c, 8.0),
        radius_at(&scene, c, 5.0),
        radius_at(&scene, c, 11.0),
    );
    assert!(soft < 0.8 * hard && hard < cap, "{soft} {hard} {cap}");
    assert!(soft > 0.5 && cap < 6.0, "{soft} {cap}");
    // Above the cap, air.
    assert!(radius_at(&scene, c, 12.8) < 0.3);
    // The cap is a broken block of the bed, not a lathe-turned disc: its top (the bed's
    // top, 12 m, flat to 0.05 m before [`CAP_BREAK`]) rises and falls by over 0.25 m.
    let tops: Vec<f32> = (0..12)
        .map(|k| {
            let a = k as f32 * std::f32::consts::TAU / 12.0;
            top_below(&scene, c[0] + 1.2 * a.cos(), c[1] + 1.2 * a.sin(), 16.0)
        })
        .collect();
    let lo = tops.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = tops.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    assert!(lo > 10.0 && hi - lo > 0.25, "cap top {lo}..{hi}");
    let (shifted, rep2) = one(beds(3.0));
    let c2 = rep2.sites[0];
    // Beds at 1-3, 7-9 and 13-15: the cap is the 7 m bed (11.2 m over the floor, its top
    // 1.2 m higher: 13.2 m when the cap was the whole bed), the
    // neck now at 3-7 m, where the first hoodoo bulges.
    assert!((rep2.sizes_m[0] - 12.45).abs() < 0.3, "{rep2:?}");
    let (neck, bulge) = (radius_at(&shifted, c2, 5.0), radius_at(&shifted, c2, 2.0));
    assert!(neck < 0.8 * bulge, "{neck} {bulge}");
    assert!(radius_at(&shifted, c2, 5.0) < 0.8 * radius_at(&scene, c, 5.0));
}

/// On a DEM with a steep band under the hard beds and gentle ground elsewhere, hoodoos
/// stand only on the band, in clusters (their nearest neighbours much closer than the
/// same count spread evenly over the band would be), the same whatever the thread count.
#[test]
fn hoodoos_cluster_on_steep_slopes_below_a_cap_bed() {
    let run = |threads| {
        with_threads(threads, || {
            let (rep, scene) = on_band(12, 6.0, 4);
            (rep, scene.stats())
        })
    };
    let (rep, st) = run(1);
    assert_eq!(run(3), (rep.clone(), st));
    assert!(rep.features >= 8, "{rep:?}");
    for p in &rep.sites {
        assert!((59.0..=101.0).contains(&p[0]), "off the slope: {p:?}");
    }
    // Clark-Evans: mean nearest-neighbour distance over that of a random pattern of the
    // same density on the band (40 x 160 m): clustered well below 1.
    let ce = crate::scene::clark_evans(&rep.sites, 40.0 * 160.0).unwrap();
    assert!(ce < 0.75, "Clark-Evans ratio {ce}");
}

/// `count` hoodoos 8 m tall, of radius 1.5 m, `spacing` apart, `per_cluster` a cluster, on
/// 160 x 160 m: flat at 0 m west, a 35 degree slope from x = 60 m to 100 m, flat at 28 m
/// east, over [`beds`].
fn on_band(count: usize, spacing: f32, per_cluster: usize) -> (EffectReport, Scene) {
    let hf = Heightfield::from_fn(81, 81, 2.0, 2.0, |x, _| {
        ((x as f32 * 2.0 - 60.0) * 0.7).clamp(0.0, 28.0)
    });
    let mut b = SceneBuilder::new(&hf, beds(0.0), &ImplicitizeSettings::default()).unwrap();
    let s = HoodooSettings {
        count,
        height: 8.0,
        radius: 1.5,
        spacing,
        per_cluster,
        ..Default::default()
    };
    let rep = b.hoodoos(&s, &Region::everywhere()).unwrap();
    (rep, b.build(true).unwrap())
}

/// A cluster is a field, not a row of pins: some hoodoos have lost their cap (spires well
/// under the cap bed), the others stand to it.
#[test]
fn clusters_hold_spires_and_capped_columns() {
    let (rep, _) = on_band(24, 4.8, 12);
    assert!(rep.features >= 12, "{rep:?}");
    // Cap beds here are 2 m thick and their base 4.8-11.2 m up: a capped hoodoo stands
    // at least 6.8 m, a spire at most 0.9 of 11.2 m.
    let capped = rep.sizes_m.iter().filter(|&&h| h >= 6.8).count();
    let spires = rep.sizes_m.iter().filter(|&&h| h < 6.0).count();
    assert!(capped >= 4 && spires >= 2, "{:?}", rep.sizes_m);
}

/// Neighbouring caps stand apart: two capped hoodoos 6 m apart (columns of 1.5 m, caps of
/// up to about 2.9 m) keep air between their caps when a cluster's shapes are joined by a
/// union; summed, as the scene sums its positive shapes, their fields bridge the gap and the
/// two caps fuse into one slab (pale blobs joined in pairs, seen from above).
#[test]
fn neighbouring_caps_stand_apart() {
    let s = HoodooSettings {
        radius: 1.5,
        ..Default::default()
    };
    let capped: Vec<u64> = (1..64u64)
        .filter(|&i| unit(hash(s.seed, i, 60, 0x6361_7073)) >= CAPLESS)
        .take(2)
        .collect();
    let d = 6.0;
    let joined = |union: bool| {
        let hf = Heightfield::from_fn(24, 16, 1.0, 1.0, |_, _| 0.0);
        let mut b = SceneBuilder::new(&hf, beds(0.0), &ImplicitizeSettings::default()).unwrap();
        b.hoodoo(&s, &flat_site(6.0, 8.0, capped[0])).unwrap();
        b.hoodoo(&s, &flat_site(6.0 + d, 8.0, capped[1])).unwrap();
        if union {
            b.join_positives_since(0).unwrap();
        }
        let scene = b.build(true).unwrap();
        // At some height of the cap bed (10-12 m), rock all along the line between the axes.
        (0..=20).any(|m| {
            let z = 10.0 + 0.1 * m as f32;
            (0..=40).all(|t| scene.inside([6.0 + d * t as f32 / 40.0, 8.0, z]))
        })
    };
    assert!(!joined(true), "caps 6 m apart join");
    assert!(joined(false), "summed caps 6 m apart stand apart");
}

/// A builder on `n x n` m of flat ground at 0 m over [`beds`], and hoodoos of radius
/// 1.5 m 4.8 m apart.
fn flat(n: usize) -> (SceneBuilder, HoodooSettings) {
    let hf = Heightfield::from_fn(n, n, 1.0, 1.0, |_, _| 0.0);
    let b = SceneBuilder::new(&hf, beds(0.0), &ImplicitizeSettings::default()).unwrap();
    let s = HoodooSettings {
        radius: 1.5,
        spacing: 4.8,
        ..Default::default()
    };
    (b, s)
}

/// A site on flat ground at 0 m under a hard bed from 10 to 12 m.
fn flat_site(x: f32, y: f32, idx: u64) -> Site {
    Site {
        p: [x, y, 0.0],
        bed: (10.0, 12.0),
        rho_cap: 0.9,
        slope: 30.0,
        idx,
    }
}

/// In rock of one hardness, a column still weathers into ledges and necks at the thin
/// beds, and two columns have theirs at the same heights (the beds are horizontal): their
/// radius profiles vary by more than 5 % and correlate (without the beds, only each
/// column's own jitter and flutes: uncorrelated).
#[test]
fn columns_share_ledges_at_the_thin_beds() {
    let s = HoodooSettings {
        radius: 1.5,
        ..Default::default()
    };
    let capped = (1..64u64)
        .filter(|&i| unit(hash(s.seed, i, 60, 0x6361_7073)) >= CAPLESS)
        .take(2);
    let profiles: Vec<Vec<f32>> = capped
        .map(|idx| {
            let hf = Heightfield::from_fn(16, 16, 1.0, 1.0, |_, _| 0.0);
            let geo = test_beds(0.0, (5.0, 0.3), (5.0, 0.3));
            let mut b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
            b.hoodoo(&s, &flat_site(8.0, 8.0, idx)).unwrap();
            let scene = b.build(true).unwrap();
            (0..26)
                .map(|k| radius_at(&scene, [8.0, 8.0, 0.0], 2.0 + 0.25 * k as f32))
                .collect()
        })
        .collect();
    let stats = |v: &[f32]| {
        let m = v.iter().sum::<f32>() / v.len() as f32;
        let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f32>() / v.len() as f32).sqrt();
        (m, sd)
    };
    let ((ma, sa), (mb, sb)) = (stats(&profiles[0]), stats(&profiles[1]));
    assert!(sa > 0.05 * ma && sb > 0.05 * mb, "{sa} {ma} {sb} {mb}");
    let cov = profiles[0]
        .iter()
        .zip(&profiles[1])
        .map(|(a, b)| (a - ma) * (b - mb))
        .sum::<f32>()
        / profiles[0].len() as f32;
    assert!(cov / (sa * sb) > 0.5, "correlation {}", cov / (sa * sb));
}

/// A fin between two hoodoo sites is a low wall: rock midway between them near the
/// ground, air there above 45 % of their height and beside the line joining them.
#[test]
fn a_fin_is_a_low_wall_between_two_columns() {
    let (mut b, s) = flat(24);
    let (a, c) = (flat_site(8.0, 12.0, 1), flat_site(14.0, 12.0, 2));
    b.hoodoo_fin(&s, &a, &c).unwrap();
    let scene = b.build(true).unwrap();
    assert!(scene.inside([11.0, 12.0, 1.0]));
    assert!(!scene.inside([11.0, 12.0, 4.6]));
    assert!(!scene.inside([11.0, 14.5, 1.0]) && !scene.inside([11.0, 9.5, 1.0]));
}

/// Clusters follow the region's two orthogonal joint sets: every cluster's row direction
/// is within 10 degrees of one of them, both sets are used, and other seeds turn them.
#[test]
fn cluster_rows_follow_two_orthogonal_joint_sets() {
    let (b, s) = flat(8);
    let angle = |s: &HoodooSettings, idx| {
        let (u, _) = b.joints(s, &flat_site(0.0, 0.0, idx));
        u[1].atan2(u[0]).to_degrees()
    };
    let dev = |a: f32, r: f32| {
        let d = (a - r).rem_euclid(90.0);
        d.min(90.0 - d)
    };
    let angles: Vec<f32> = (0..200).map(|k| angle(&s, k)).collect();
    let r = angles[0];
    assert!(angles.iter().all(|&a| dev(a, r) <= 20.0), "{angles:?}");
    let set_a = angles
        .iter()
        .filter(|&&a| {
            let d = (a - r).rem_euclid(180.0);
            !(25.0..=155.0).contains(&d)
        })
        .count();
    assert!(set_a > 50 && set_a < 150, "{set_a} of 200 in the first set");
    let turned = (4..16u64)
        .filter(|&seed| dev(angle(&HoodooSettings { seed, ..s }, 0), r) > 20.0)
        .count();
    assert!(turned >= 3, "other seeds, other joints: {turned} of 12");
}

/// Between two rows of a cluster the floor of its hollow is cut down into a gully along
/// the joint direction; beyond the rows' ends and far to the side it is untouched.
#[test]
fn a_gully_runs_between_two_rows() {
    let (mut b, s) = flat(40);
    let centre = flat_site(20.0, 20.0, 7);
    let (u, v) = b.joints(&s, &centre);
    let at = |along: f32, across: f32| {
        [
            20.0 + along * u[0] + across * v[0],
            20.0 + along * u[1] + across * v[1],
        ]
    };
    let across = 1.15 * s.spacing;
    let q = at(0.0, across);
    let members = [(centre, (0, 0)), (flat_site(q[0], q[1], 8), (1, 0))];
    assert_eq!(b.hoodoo_gullies(&s, &centre, &members).unwrap(), 1);
    let scene = b.build(true).unwrap();
    // Cut into the floor of the cluster's hollow ([`BOWL`] of the height under the ground).
    let z = -BOWL * s.height - 0.3;
    let mid = at(0.0, 0.5 * across);
    assert!(
        !scene.inside([mid[0], mid[1], z]),
        "no gully between the rows"
    );
    let side = at(0.0, 0.5 * across + 3.0 * s.radius);
    let beyond = at(3.0 * s.spacing, 0.5 * across);
    assert!(scene.inside([side[0], side[1], z]));
    assert!(scene.inside([beyond[0], beyond[1], z]));
}

/// Runs `f` on a pool of `threads` threads.
fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}
