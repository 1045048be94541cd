//! Renders: the adaptive image loop against tracing every pixel on the close-ups of a real
//! scene, the karst cut-away through passages, bedrock under the slab in a cut-away.

use relief_implicit_volume::*;

/// Every close-up of the grand canyon scene with every feature (lake at the crop's 25th
/// percentile, as the `implicit_volume` benchmark group), rendered at 400 x 225 with every
/// fourth pixel traced and the rest filled from them, matches tracing every pixel: the same
/// silhouettes, shadows and texture, only a few pixels off (0.03 % by more than 8 grey levels
/// at 1600 x 900). Dropping the depth check (filling across silhouettes: 0.77 % of the
/// islands view off) or copying the anchors' shadow where they disagree (mean 0.27) fails.
#[test]
fn the_adaptive_render_matches_tracing_every_pixel() {
    let Some(hf) = relief_testdata::dem_crop("grandcanyon", 200, 160, 128, 128) else {
        return;
    };
    let recipe = Recipe {
        features: Feature::ALL.to_vec(),
        sea_level: relief_heightfield::metrics::quantile(hf.as_slice(), 0.25),
        seed: 1,
        ..Default::default()
    };
    let (scene, rep) = build_recipe(&hf, &recipe).unwrap();
    let tile = RenderSettings {
        width: 400,
        height: 225,
        sea_level: rep.sea_level.filter(|_| rep.has_sea),
        ..Default::default()
    };
    let views = closeup_views(&scene, &rep, &tile);
    assert!(views.len() >= 2, "{}", views.len());
    for (cam, s, name) in views {
        assert!(s.adaptive, "adaptive by default");
        let fast = render(&scene, &cam, &s).unwrap();
        let full = render(
            &scene,
            &cam,
            &RenderSettings {
                adaptive: false,
                ..s
            },
        )
        .unwrap();
        let n = fast.width * fast.height;
        let (mut off, mut sum) = (0usize, 0u64);
        for (a, b) in fast.rgb.chunks(3).zip(full.rgb.chunks(3)) {
            let d = (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0);
            off += usize::from(d > 8);
            sum += a
                .iter()
                .zip(b)
                .map(|(x, y)| u64::from(x.abs_diff(*y)))
                .sum::<u64>();
        }
        let mean = sum as f64 / (3 * n) as f64;
        assert!(
            off * 200 < n && mean < 0.2,
            "{name}: {off} of {n} pixels off by more than 8, mean {mean:.3}"
        );
    }
}

/// The karst close-up cuts the rock where the cut face crosses passages: on the plane of
/// the cut, within 10 passage radii of its centre, some of the rock under the ground is
/// carved air, in at least two separate holes along the rows (the network, not one
/// tube). Cutting through the centroid of the densest block of passages showed none here.
#[test]
fn the_karst_cut_away_crosses_passages() {
    let Some(hf) = relief_testdata::dem_crop("grandcanyon", 200, 160, 128, 128) else {
        return;
    };
    let recipe = Recipe {
        features: vec![Feature::Karst],
        seed: 1,
        ..Default::default()
    };
    let (scene, rep) = build_recipe(&hf, &recipe).unwrap();
    let h = rep
        .highlights
        .iter()
        .find(|h| h.cutaway)
        .expect("a karst cut-away");
    let from = h.from.unwrap();
    let n = [from[0], from[1]];
    let len = n[0].hypot(n[1]);
    let along = [-n[1] / len, n[0] / len];
    let r = rep.dims.karst_radius_m;
    let (mut carved, mut under, mut holes) = (0usize, 0usize, 0usize);
    for j in -40..=40 {
        let z = h.at[2] + j as f32 * r / 4.0;
        let mut in_hole = false;
        for i in -40..=40 {
            let s = i as f32 * r / 4.0;
            let (x, y) = (h.at[0] + s * along[0], h.at[1] + s * along[1]);
            let ground = scene.dem_height(x, y).unwrap_or(f32::NEG_INFINITY);
            let air = z < ground - r && !scene.inside([x, y, z]);
            under += usize::from(z < ground - r);
            carved += usize::from(air);
            holes += usize::from(air && !in_hole);
            in_hole = air;
        }
    }
    assert!(
        carved * 100 > under && holes >= 2,
        "{carved} carved of {under} under the ground, {holes} hole runs"
    );
}

/// A flat plain at 100 m, 400 m square (10 m cells), on the layered default geology.
fn plain() -> SceneBuilder {
    let hf = relief_heightfield::Heightfield::from_fn(41, 41, 10.0, 10.0, |_, _| 100.0);
    let geo = Geology::layered_default([200.0, 200.0, 100.0], 20.0, 1).unwrap();
    SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap()
}

/// Renders `scene` at `w x h` from `eye` towards `target` (`fov` degrees) with the rock on
/// the eye's side of the plane `y = 200` cut away.
fn cut_view(scene: &Scene, eye: V3, target: V3, fov: f32, (w, h): (usize, usize)) -> Image {
    let cam = Camera {
        eye,
        target,
        up: [0.0, 0.0, 1.0],
        fov_deg: fov,
    };
    let s = RenderSettings {
        width: w,
        height: h,
        cutaway: Some(([200.0, 200.0, target[2]], [0.0, -1.0, 0.0])),
        ..Default::default()
    };
    render(scene, &cam, &s).unwrap()
}

/// A cut-away shows rock, not sky, below the modelled slab's floor within the DEM's
/// footprint (the bedrock goes on): a camera level with a point 30 m under the floor of a
/// flat plain's slab, facing the cut, sees rock colours (red over blue) there.
#[test]
fn a_cut_away_shows_bedrock_under_the_slab() {
    let scene = plain().build(true).unwrap();
    let z = scene.dem_floor().unwrap() - 30.0;
    let img = cut_view(
        &scene,
        [200.0, -100.0, z],
        [200.0, 200.0, z],
        20.0,
        (32, 24),
    );
    let k = 3 * (12 * 32 + 16);
    let (r, b) = (img.rgb[k], img.rgb[k + 2]);
    assert!(r > b, "sky under the slab: {:?}", &img.rgb[k..k + 3]);
}

/// A tunnel cut open by a cut-away is lit from the eye: under a flat plain, a horizontal
/// tunnel 6 m across runs 60 m away from the cut; looking down its axis from 50 m in front
/// of the cut, its far end (behind the cut face, under the ground) is as bright as the cut
/// face around it (1.26 times here). Lit by the sun it never sees, it was 0.54 times.
#[test]
fn a_cut_away_lights_the_caves_behind_its_face() {
    let mut b = plain();
    let z = 70.0;
    let tunnel = b
        .tree_mut()
        .capsule([200.0, 190.0, z], [200.0, 260.0, z], 3.0 / 0.4544, -1.0)
        .unwrap();
    b.add_carving(tunnel);
    let scene = b.build(true).unwrap();
    let img = cut_view(&scene, [200.0, 150.0, z], [200.0, 260.0, z], 10.0, (64, 48));
    let grey = |x: usize, y: usize| {
        let k = 3 * (y * 64 + x);
        img.rgb[k..k + 3].iter().map(|&v| f32::from(v)).sum::<f32>() / 3.0
    };
    // The view's centre looks down the tunnel; its corners see the cut face.
    let inside = (28..36)
        .flat_map(|x| (20..28).map(move |y| (x, y)))
        .map(|(x, y)| grey(x, y))
        .sum::<f32>()
        / 64.0;
    let face = [(2, 2), (61, 2), (2, 45), (61, 45)]
        .iter()
        .map(|&(x, y)| grey(x, y))
        .sum::<f32>()
        / 4.0;
    assert!(inside > 0.9 * face, "tunnel {inside}, cut face {face}");
}

/// Silhouettes are anti-aliased: the crest of a ridge 40 m high and 300 m away, seen from
/// 5 m with the camera rolled so the skyline runs diagonally, steps from ground to sky through
/// blended pixels in 34 of 46 columns (both pixels of an edge average five samples); with
/// one sample per pixel every column jumps from ground to sky in one step. (A plain's far
/// edge seen level, this test's old scene, is no silhouette test: its rays graze the ground
/// for hundreds of metres, and the blend it showed came from rays that ran out of steps and
/// were drawn as ground; on this ridge the old anti-aliasing blended none.)
#[test]
fn silhouettes_are_anti_aliased() {
    let hf = relief_heightfield::Heightfield::from_fn(64, 64, 10.0, 10.0, |_, y| {
        (40.0 - (y as f32 * 10.0 - 320.0).abs() * 0.4).max(0.0)
    });
    let scene = SceneBuilder::new(&hf, Geology::new(), &ImplicitizeSettings::default())
        .unwrap()
        .build(true)
        .unwrap();
    let cam = Camera {
        eye: [315.0, 20.0, 5.0],
        target: [315.0, 600.0, 5.0],
        up: [0.3, 0.0, 1.0],
        fov_deg: 20.0,
    };
    let (w, h) = (64, 48);
    let s = RenderSettings {
        width: w,
        height: h,
        shadows: false,
        ambient_occlusion: false,
        ..Default::default()
    };
    let img = render(&scene, &cam, &s).unwrap();
    let blue = |x: usize, y: usize| i32::from(img.rgb[3 * (y * w + x) + 2]);
    let (mut blended, mut columns) = (0, 0);
    for x in 8..w - 8 {
        let (sky, ground) = (blue(x, 0), blue(x, h - 1));
        let contrast = sky - ground;
        if contrast < 40 {
            continue;
        }
        columns += 1;
        let jump = (1..h)
            .map(|y| (blue(x, y - 1) - blue(x, y)).abs())
            .max()
            .unwrap_or(0);
        blended += usize::from(jump * 10 < contrast * 8);
    }
    assert!(
        columns > 20 && blended * 2 > columns,
        "{blended} of {columns} columns blended"
    );
}

/// A render reports each image row once to its progress, spread over its passes (a quarter of
/// the rows by the traced primary rays, ...), whatever the height, adaptive or not.
#[test]
fn a_render_reports_every_row_once() {
    struct Count(std::sync::atomic::AtomicU64);
    impl relief_heightfield::Progress for Count {
        fn advance(&self, n: u64) {
            self.0.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
        }
    }
    let hf = relief_heightfield::Heightfield::from_fn(16, 16, 10.0, 10.0, |i, j| (i * j) as f32);
    let scene = SceneBuilder::new(&hf, Geology::new(), &ImplicitizeSettings::default())
        .unwrap()
        .build(true)
        .unwrap();
    let cam = Camera::overview(&scene.bbox());
    for (height, adaptive) in [(13, true), (16, true), (7, false), (1, true)] {
        let s = RenderSettings {
            width: 11,
            height,
            adaptive,
            ..Default::default()
        };
        let count = Count(std::sync::atomic::AtomicU64::new(0));
        relief_implicit_volume::render::render_with_progress(&scene, &cam, &s, &count).unwrap();
        assert_eq!(count.0.into_inner(), height as u64, "{height} {adaptive}");
    }
}
