//! Real-DEM tests: implicitisation accuracy, sea erosion, karst, landforms, determinism and
//! watertight meshing on small crops of `alps_dem` (mountain) and `N57E011` (rocky coast).
#![allow(clippy::print_stderr)]

use relief_heightfield::Heightfield;
use relief_implicit_volume::*;
use relief_testdata::dem_crop;

fn alps() -> Option<Heightfield> {
    dem_crop("alps_dem", 1200, 300, 40, 40)
}
fn coast() -> Option<Heightfield> {
    dem_crop("N57E011", 888, 72, 48, 48)
}

/// `hf` resampled (bicubic) to `cell` metres: the surface features (hoodoos, arches, shore,
/// weathering) need cells at their own scale (issue 42; `relief volume` amplifies a window).
fn fine(hf: Option<Heightfield>, cell: f64) -> Option<Heightfield> {
    let hf = hf?;
    let (cx, cy) = hf.cell_size();
    let w = ((hf.width() as f64 * cx) / cell).round() as usize;
    let h = ((hf.height() as f64 * cy) / cell).round() as usize;
    Some(hf.resample(w, h).unwrap())
}

fn geology_for(hf: &Heightfield, period: f32) -> Geology {
    let (cx, cy) = hf.cell_size();
    let (lo, hi) = hf.min_max().unwrap();
    let c = [
        hf.width() as f32 * cx as f32 * 0.5,
        hf.height() as f32 * cy as f32 * 0.5,
        0.5 * (lo + hi),
    ];
    Geology::layered_default(c, period, 42).unwrap()
}

/// Four alternating beds `period` metres in all (soft 35 %, hard 15 %, soft 30 %, hard 20 %),
/// repeated: rock that every few metres of height offers the sea a soft bed to cut.
fn alternating_beds(period: f32) -> Geology {
    let layers = [(0.35, 0.15), (0.15, 0.85), (0.3, 0.35), (0.2, 0.7)].map(|(f, hardness)| Layer {
        thickness: f * period,
        hardness,
    });
    let mut g = Geology::new();
    let id = g.strata(0.0, &layers).unwrap();
    g.set_root(id).unwrap();
    g
}

/// Vertical root of `f = T` by bisection between `z_hi` (air) and `z_lo` (matter).
fn surface_z(scene: &Scene, x: f32, y: f32, mut z_lo: f32, mut z_hi: f32) -> f32 {
    for _ in 0..60 {
        let m = 0.5 * (z_lo + z_hi);
        if scene.inside([x, y, m]) {
            z_lo = m
        } else {
            z_hi = m
        }
    }
    0.5 * (z_lo + z_hi)
}

#[test]
fn implicitisation_matches_the_dem() {
    let Some(hf) = alps() else { return };
    let b =
        SceneBuilder::new(&hf, geology_for(&hf, 40.0), &ImplicitizeSettings::default()).unwrap();
    let f = b.frame();
    let scene = b.build(true).unwrap();
    // Root finding at every DEM node: the surface is the DEM.
    let (mut max, mut sum, mut n) = (0f32, 0f64, 0usize);
    for i in 2..hf.height() - 2 {
        for j in 2..hf.width() - 2 {
            let p = f.node(j, i, hf.get(j, i));
            let z = surface_z(&scene, p[0], p[1], p[2] - 20.0, p[2] + 20.0);
            let d = (z - p[2]).abs();
            max = max.max(d);
            sum += d as f64;
            n += 1;
        }
    }
    eprintln!(
        "implicitisation (alps 40x40): root deviation max {max:.4} m mean {:.5} m",
        sum / n as f64
    );
    assert!(max < 0.01, "{max}");
    // Mesh vertices of the top surface against the bilinear DEM.
    let (mesh, rep) = mesh_of(&scene, [80, 80, 60]);
    let topo = topology(&mesh);
    assert_eq!((topo.bad_edges, topo.misoriented_edges), (0, 0), "{topo:?}");
    let (lo, _) = hf.min_max().unwrap();
    let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
    let (mut mmax, mut msum, mut mn) = (0f32, 0f64, 0usize);
    for (p, nrm) in mesh.positions.iter().zip(&mesh.normals) {
        if p[0] < f.cx || p[1] < f.cy || p[0] > xm - f.cx || p[1] > ym - f.cy || p[2] < lo - 10.0 {
            continue;
        }
        let d = (p[2] - scene.dem_height(p[0], p[1]).unwrap()).abs();
        mmax = mmax.max(d);
        msum += d as f64;
        mn += 1;
        assert!(nrm[2] > 0.0, "top-surface normals point up");
    }
    let mean = msum / mn as f64;
    eprintln!("mesh vs DEM: max {mmax:.2} m mean {mean:.3} m over {mn} vertices; {rep:?}");
    // The grid is (2.2 x 3.0 x ~20 m) per cell: linear interpolation error stays below a cell.
    assert!(mean < 3.0 && mmax < 40.0, "{mean} {mmax}");
    assert!(rep.chunks_sampled < rep.chunks, "empty chunks are skipped");
}

fn sea_settings() -> SeaErosion {
    SeaErosion {
        weathering: Weathering {
            spacing: 10.0,
            radius: 25.0,
            energy: 3.0,
            ..Default::default()
        },
        depth: 3.0,
        height: 25.0,
        peak: 4.0,
        reach: 200.0,
        caves: 10,
        cave_length: 150.0,
        ..Default::default()
    }
}

#[test]
fn sea_erosion_carves_only_near_sea_level_and_makes_overhangs() {
    let Some(hf) = coast() else { return };
    let geo = geology_for(&hf, 15.0);
    let plain = SceneBuilder::new(&hf, geo.clone(), &ImplicitizeSettings::default())
        .unwrap()
        .build(true)
        .unwrap();
    let mut b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
    let s = sea_settings();
    let rep = b.sea_erosion(&s, &Region::everywhere()).unwrap();
    assert!(rep.primitives > 20, "{rep:?}");
    for (c, _, _) in b.carvings() {
        assert!(c[2] >= -s.depth - 1e-3 && c[2] <= s.height + 1e-3, "{c:?}");
    }
    let f = b.frame();
    let scene = b.build(true).unwrap();
    // Every point removed by erosion lies within one sphere radius of the sea band.
    let (mut removed, mut overhang) = (0, 0);
    for i in 0..hf.height() * 4 {
        for j in 0..hf.width() * 4 {
            let (x, y) = (j as f32 * f.cx / 4.0, i as f32 * f.cy / 4.0);
            let g = scene.dem_height(x, y).unwrap();
            let mut solid_above = false;
            for k in 0..60 {
                let z = g + 5.0 - k as f32;
                let p = [x, y, z];
                let was = plain.inside(p);
                let is = scene.inside(p);
                if was && !is {
                    removed += 1;
                    assert!(z > -s.depth - 25.0 && z < s.height + 25.0, "{p:?}");
                    if solid_above {
                        overhang += 1;
                    }
                }
                if is {
                    solid_above = true;
                }
            }
        }
    }
    eprintln!(
        "sea erosion (N57E011 48x48): {rep:?}, removed samples {removed}, under overhang {overhang}"
    );
    assert!(removed > 100);
    assert!(overhang > 0, "sea erosion must create overhangs or caves");
}

/// The karst of the alps-crop tests: passages of 10 m, steps of 8 m, 1500 steps at most.
fn alps_karst() -> KarstSettings {
    KarstSettings {
        budget: 1500,
        radius: 10.0,
        step: 8.0,
        poisson_radius: 5.0,
        ..Default::default()
    }
}

#[test]
fn karst_carves_soft_rock_below_the_surface_and_respects_masks() {
    let Some(hf) = alps() else { return };
    let geo = geology_for(&hf, 40.0);
    let mut b = SceneBuilder::new(&hf, geo.clone(), &ImplicitizeSettings::default()).unwrap();
    let ks = alps_karst();
    let rep = b.karst(&ks, &Region::everywhere()).unwrap();
    assert!(rep.primitives > 50, "{rep:?}");
    let mut deep = 0;
    for (c, r, karst) in b.carvings() {
        assert!(karst);
        assert!(geo.resistance(*c) < ks.rho0, "carved hard rock at {c:?}");
        if c[2] < b.ground(c[0], c[1]) - 2.0 * r {
            deep += 1;
        }
    }
    let scene = b.build(true).unwrap();
    // Tunnels: carved centres well below the surface are air.
    let tunnels = scene_tunnels(&scene, &geo, &ks, &hf);
    eprintln!(
        "karst (alps 40x40): {rep:?}, deep spheres {deep}, enclosed tunnel points {tunnels}, {:?}",
        scene.stats()
    );
    assert!(deep > 10 && tunnels > 10);

    // A mask that forbids the western half.
    let mut mask = vec![1.0; hf.width() * hf.height()];
    for i in 0..hf.height() {
        for j in 0..hf.width() / 2 {
            mask[i * hf.width() + j] = 0.0;
        }
    }
    let mut b2 = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
    let f = b2.frame();
    b2.karst(
        &ks,
        &Region {
            mask: Some(mask),
            bbox: None,
        },
    )
    .unwrap();
    assert!(!b2.carvings().is_empty());
    for (c, _, _) in b2.carvings() {
        let (j, _) = f.cell(*c).unwrap();
        assert!(j >= hf.width() / 2 - 1, "{c:?}");
    }
    let bad = Region {
        mask: Some(vec![0.5; 3]),
        bbox: None,
    };
    let e = b2.karst(&ks, &bad).unwrap_err();
    assert!(e.to_string().contains("region.mask"));
}

#[test]
fn karst_passages_stay_under_the_ground() {
    // Passages in thin soft rock near the surface used to dent the ground above them or break
    // through it as pits (the carving's support reached above the ground). Every point a few
    // metres under the ground that is rock without the karst stays rock with it.
    let Some(hf) = alps() else { return };
    let geo = geology_for(&hf, 40.0);
    let ks = alps_karst();
    let plain = SceneBuilder::new(&hf, geo.clone(), &ImplicitizeSettings::default())
        .unwrap()
        .build(true)
        .unwrap();
    let mut b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
    let rep = b.karst(&ks, &Region::everywhere()).unwrap();
    let scene = b.build(true).unwrap();
    let (cx, cy) = hf.cell_size();
    let (mut checked, mut lost) = (0, 0);
    for i in 0..hf.height() * 2 {
        for j in 0..hf.width() * 2 {
            let (x, y) = (j as f32 * cx as f32 / 2.0, i as f32 * cy as f32 / 2.0);
            let g = plain.dem_height(x, y).unwrap();
            for d in [0.5, 1.0, 2.0] {
                let p = [x, y, g - d];
                if plain.inside(p) {
                    checked += 1;
                    if !scene.inside(p) {
                        lost += 1;
                    }
                }
            }
        }
    }
    eprintln!("karst under the ground: {rep:?}; {lost} of {checked} shallow rock points lost");
    assert!(rep.features > 100 && rep.thin_cover > 0, "{rep:?}");
    assert!(checked > 10_000);
    assert_eq!(lost, 0, "shallow rock points turned to air by the karst");
}

fn scene_tunnels(scene: &Scene, _geo: &Geology, ks: &KarstSettings, hf: &Heightfield) -> usize {
    let (cx, cy) = hf.cell_size();
    let (cx, cy) = (cx as f32, cy as f32);
    let mut n = 0;
    for i in 0..hf.height() * 3 {
        for j in 0..hf.width() * 3 {
            let (x, y) = (j as f32 * cx / 3.0, i as f32 * cy / 3.0);
            let g = scene.dem_height(x, y).unwrap();
            let mut k = 1.0;
            while k < 300.0 {
                let p = [x, y, g - 3.0 * ks.radius - k];
                if !scene.inside(p) && scene.inside([x, y, g - ks.radius]) {
                    n += 1;
                    break;
                }
                k += 2.0;
            }
        }
    }
    n
}

/// The mesh of `scene` on a grid of `cells` (chunks of 16, the other settings default).
fn mesh_of(scene: &Scene, cells: [usize; 3]) -> (Mesh, MeshReport) {
    let settings = MeshSettings {
        cells,
        chunk: 16,
        ..Default::default()
    };
    polygonize(scene, &settings).unwrap()
}

/// The overview render of `scene`, `width x height` pixels, with a sea at `sea_level`.
fn overview(scene: &Scene, width: usize, height: usize, sea_level: Option<f32>) -> Image {
    let settings = RenderSettings {
        width,
        height,
        sea_level,
        ..Default::default()
    };
    render(scene, &Camera::overview(&scene.bbox()), &settings).unwrap()
}

fn full_scene(hf: &Heightfield) -> Scene {
    let all = Region::everywhere();
    let mut b =
        SceneBuilder::new(hf, geology_for(hf, 15.0), &ImplicitizeSettings::default()).unwrap();
    let karst = KarstSettings {
        budget: 400,
        ..Default::default()
    };
    let (hoodoos, arches, islands) = (
        HoodooSettings {
            count: 3,
            ..Default::default()
        },
        ArchSettings {
            count: 1,
            ..Default::default()
        },
        IslandSettings {
            count: 1,
            ..Default::default()
        },
    );
    b.sea_erosion(&sea_settings(), &all).unwrap();
    b.karst(&karst, &all).unwrap();
    b.wind_erosion(&WindErosion::default(), &all).unwrap();
    b.rain_erosion(&RainErosion::default(), &all).unwrap();
    b.hoodoos(&hoodoos, &all).unwrap();
    b.arches(&arches, &all).unwrap();
    b.floating_islands(&islands, &all).unwrap();
    b.build(true).unwrap()
}

#[test]
fn all_effects_are_deterministic_across_thread_counts_and_mesh_watertight() {
    let Some(hf) = coast() else { return };
    let run = |threads: usize| {
        relief_testdata::with_threads(threads, || {
            let scene = full_scene(&hf);
            let (mesh, _) = mesh_of(&scene, [64, 64, 48]);
            let img = overview(&scene, 64, 48, Some(0.0));
            (scene.stats(), mesh, img)
        })
    };
    let (s1, m1, i1) = run(1);
    let (s2, m2, i2) = run(2);
    assert_eq!(s1, s2);
    assert_eq!(m1, m2);
    assert_eq!(i1, i2);
    let topo = topology(&m1);
    eprintln!("full coast scene: {s1:?}, mesh {topo:?}");
    assert_eq!((topo.bad_edges, topo.misoriented_edges), (0, 0), "{topo:?}");
    // The render is not blank: terrain and sky colours both appear.
    let distinct: std::collections::HashSet<&[u8]> = i1.rgb.chunks(3).collect();
    assert!(distinct.len() > 50);
}

#[test]
fn landforms_add_matter_above_the_ground() {
    let Some(hf) = alps() else { return };
    let mut b =
        SceneBuilder::new(&hf, geology_for(&hf, 40.0), &ImplicitizeSettings::default()).unwrap();
    let f = b.frame();
    let isl = b
        .floating_islands(
            &IslandSettings {
                count: 1,
                radius: 60.0,
                altitude: 250.0,
                seed: 2,
                ..Default::default()
            },
            &Region::everywhere(),
        )
        .unwrap();
    let hd = b
        .hoodoos(
            &HoodooSettings {
                count: 2,
                min_slope_deg: 0.0,
                max_slope_deg: 60.0,
                height: 60.0,
                radius: 15.0,
                spacing: 200.0,
                cap_rho: 0.55,
                per_cluster: 2,
                seed: 1,
            },
            &Region::everywhere(),
        )
        .unwrap();
    assert!(
        isl.features == 1 && isl.primitives >= 10 && hd.primitives >= 10,
        "{isl:?} {hd:?}"
    );
    let scene = b.build(true).unwrap();
    // Some column has air, then matter (island), then air, then ground.
    let mut floating = 0;
    for i in 0..f.height {
        for j in 0..f.width {
            let p = f.node(j, i, 0.0);
            let g = scene.dem_height(p[0], p[1]).unwrap();
            let mut state = vec![];
            let mut z = g + 400.0;
            while z > g + 2.0 {
                let s = scene.inside([p[0], p[1], z]);
                if state.last() != Some(&s) {
                    state.push(s);
                }
                z -= 4.0;
            }
            if state.len() >= 3 {
                floating += 1;
            }
        }
    }
    assert!(floating > 0, "the island floats");
    let (img, st) = section(
        &scene,
        &SectionSettings {
            start: [0.0, 0.0],
            end: [(f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy],
            z_range: None,
            width: 64,
            height: 64,
        },
    )
    .unwrap();
    assert_eq!(img.rgb.len(), 64 * 64 * 3);
    assert!(st.solid > 0 && st.air > 0);
}

fn mesh_bytes(m: &Mesh) -> Vec<u8> {
    let mut v = Vec::new();
    for p in m.positions.iter().chain(&m.normals) {
        for c in p {
            v.extend_from_slice(&c.to_bits().to_le_bytes());
        }
    }
    for t in &m.triangles {
        for i in t {
            v.extend_from_slice(&i.to_le_bytes());
        }
    }
    v
}

/// Every recipe feature on a Grand Canyon crop: mesh bytes, render and section identical on 1
/// and 2 threads; the mesh is watertight; the implicitised DEM is exact.
#[test]
fn recipe_is_thread_count_independent_on_the_canyon() {
    let Some(hf) = fine(dem_crop("grandcanyon", 200, 160, 16, 16), 8.0) else {
        return;
    };
    // An explicit shore at the 25th percentile (the canyon has no sea of its own), so every
    // effect runs.
    let q25 = relief_heightfield::metrics::quantile(hf.as_slice(), 0.25).unwrap();
    let recipe = Recipe {
        features: Feature::ALL.to_vec(),
        sea_level: Some(q25),
        seed: 9,
        ..Default::default()
    };
    let run = |threads: usize| {
        relief_testdata::with_threads(threads, || {
            let (scene, rep) = build_recipe(&hf, &recipe).unwrap();
            let (mesh, _) = mesh_of(&scene, [48, 48, 24]);
            let img = overview(&scene, 48, 36, rep.sea_level);
            let (start, end) = rep.section_line;
            let (sec, st) = section(
                &scene,
                &SectionSettings {
                    start,
                    end,
                    z_range: None,
                    width: 48,
                    height: 24,
                },
            )
            .unwrap();
            // Vertex colours with the resistance under each steep vertex (rock, no soil).
            let colours = relief_implicit_volume::material::vertex_colours(&scene, &mesh);
            let steep_rho: Vec<(f32, [u8; 4])> = (mesh.positions.iter().zip(&mesh.normals))
                .zip(&colours)
                .filter(|((_, n), _)| n[2].abs() < 0.2)
                .map(|((p, _), c)| (scene.resistance(*p), *c))
                .collect();
            (
                mesh_bytes(&mesh),
                img,
                sec,
                st,
                rep,
                topology(&mesh),
                colours,
                steep_rho,
            )
        })
    };
    let a = run(1);
    let b = run(2);
    assert!(a.6 == b.6, "vertex colours differ between 1 and 2 threads");
    // Steep faces show their strata: soft rock redder (red over blue) than hard rock.
    let redness = |lo: f32, hi: f32| {
        let v: Vec<f32> = (a.7.iter())
            .filter(|(r, _)| (lo..hi).contains(r))
            .map(|(_, c)| c[0] as f32 / c[2].max(1) as f32)
            .collect();
        assert!(v.len() >= 5, "{} steep vertices in [{lo}, {hi})", v.len());
        v.iter().sum::<f32>() / v.len() as f32
    };
    let (soft, hard) = (redness(0.0, 0.35), redness(0.65, 1.01));
    assert!(soft > 1.4 * hard, "red/blue soft {soft} vs hard {hard}");
    assert!(a.0 == b.0, "mesh bytes differ between 1 and 2 threads");
    assert_eq!(a.1, b.1);
    assert_eq!((a.2.clone(), a.3), (b.2, b.3));
    assert_eq!(a.4, b.4);
    let rep = &a.4;
    // Sea and caves share one entry, overhangs hold wind and rain; on 8 m cells every
    // feature is placed.
    for f in [
        Feature::Cliffs,
        Feature::Sea,
        Feature::Karst,
        Feature::Overhangs,
        Feature::Hoodoos,
        Feature::Arches,
        Feature::Islands,
    ] {
        let noted = rep.dims.notes.iter().any(|n| n.starts_with(f.name()));
        assert!(
            rep.effects.iter().any(|e| e.0 == f) != noted,
            "{f}: placed or noted: {:?}",
            rep.dims.notes
        );
    }
    assert!(rep.effects.iter().all(|(_, e)| e.primitives > 0), "{rep:?}");
    assert!(rep.deviation.max < 0.01, "{:?}", rep.deviation);
    assert_eq!((a.5.bad_edges, a.5.misoriented_edges), (0, 0));
    assert!(a.3.carved > 0);
}

// ---- Issue 19: physical sizes, karst at scale, iterated erosion, cliffs, simplification ----

fn canyon() -> Option<Heightfield> {
    dem_crop("grandcanyon", 200, 160, 64, 64)
}

/// Air cells of the vertical section through `site` along the horizontal unit `side` (cells
/// of `step` metres, `u` and `z` within `half` of the site) connected to the site, and
/// whether that air reaches the section's border (is open to the sky or the sides).
fn section_air(
    scene: &Scene,
    site: [f32; 3],
    side: [f32; 3],
    half: f32,
    step: f32,
) -> (usize, bool) {
    let n = (2.0 * half / step).ceil() as usize + 1;
    let c = n / 2;
    let p = |i: usize, k: usize| {
        let (u, dz) = ((i as f32 - c as f32) * step, (k as f32 - c as f32) * step);
        [site[0] + side[0] * u, site[1] + side[1] * u, site[2] + dz]
    };
    relief_testdata::flood_fill(n, n, (c, c), |i, k| !scene.inside(p(i, k)))
}

/// Arches on the grandcanyon plateau (a 7.9 km crop): each opening, under the ridge before,
/// is air; the section along its fin shows that air enclosed (a bridge over it, legs beside
/// it, the floor under it); the ridge's rock before and behind the fin is cut away (the arch
/// stands free in its gap, not a tunnel through a wall); the legs are rock at the opening's
/// mid-height; the spans vary (drawn per arch) within the natural range.
#[test]
fn arches_on_the_plateau_stand_free_in_their_gaps() {
    let Some(hf) = fine(dem_crop("grandcanyon", 220, 180, 50, 50), 8.0) else {
        return;
    };
    let recipe = Recipe {
        features: vec![Feature::Arches],
        ..Default::default()
    };
    let (scene, rep) = build_recipe(&hf, &recipe).unwrap();
    let d = &rep.dims;
    let arches = rep
        .effects
        .iter()
        .find(|(f, _)| *f == Feature::Arches)
        .map(|(_, e)| e)
        .unwrap_or_else(|| panic!("arches on the plateau: {:?}", rep.dims.notes));
    eprintln!("arches: {arches:?}; median span {} m", d.arch_span_m);
    assert!(arches.features >= 2, "{arches:?}");
    let th = d.arch_thickness_m;
    let mut cut = 0;
    for ((site, axis), &span) in arches.sites.iter().zip(&arches.axes).zip(&arches.sizes_m) {
        assert!((1.0..=120.0).contains(&span), "{span}");
        let ground = |x: f32, y: f32| scene.dem_height(x, y).unwrap();
        let top = ground(site[0], site[1]);
        assert!(top > site[2], "{site:?} was under the ridge");
        assert!(!scene.inside(*site), "the opening at {site:?} is air");
        let side = [-axis[1], axis[0], 0.0];
        let (air, open) = section_air(&scene, *site, side, 1.5 * span, 0.05 * span);
        assert!(
            air > 20 && !open,
            "enclosed air at {site:?}: {air} cells, open {open}"
        );
        let bridge = (1..=40)
            .map(|k| site[2] + k as f32 * (top - site[2]) / 40.0)
            .find(|&z| scene.inside([site[0], site[1], z]))
            .expect("a bridge over the opening");
        for sign in [-1.0f32, 1.0] {
            let p = [
                site[0] + axis[0] * sign * 2.5 * th,
                site[1] + axis[1] * sign * 2.5 * th,
                bridge,
            ];
            assert!(!scene.inside(p), "rock beside the bridge at {p:?}");
            if ground(p[0], p[1]) > p[2] {
                cut += 1;
            }
            let u = sign * (0.7 * span + 0.6 * th);
            let leg = [site[0] + side[0] * u, site[1] + side[1] * u, site[2]];
            assert!(scene.inside(leg), "a leg at {leg:?}");
        }
    }
    assert!(
        cut >= arches.features,
        "the ridge beside the bridges was rock: {cut}"
    );
    let spans = &arches.sizes_m;
    assert!(
        spans.iter().any(|&s| (s - spans[0]).abs() > 0.5),
        "spans drawn per arch: {spans:?}"
    );
}

/// Default recipes on a plateau (grandcanyon) and a coast (N57E011): sizes in metres within
/// the ranges of the issue, counts from densities, karst passages between one voxel and half
/// the soft strata, the percolation ended by its threshold or an empty queue (not the budget).
/// The plateau and the coast are two tests so that they run in parallel (issue 45).
#[test]
fn recipe_sizes_are_physical_on_the_canyon() {
    if let Some(gc) = fine(dem_crop("grandcanyon", 200, 160, 16, 16), 8.0) {
        check_default_recipe_sizes("grandcanyon 64x64", gc);
    }
}

/// The coast half of [`recipe_sizes_are_physical_on_the_canyon`].
#[test]
fn recipe_sizes_are_physical_on_the_coast() {
    if let Some(co) = fine(dem_crop("N57E011", 888, 72, 32, 32), 8.0) {
        check_default_recipe_sizes("N57E011 48x48", co);
    }
}

fn check_default_recipe_sizes(name: &str, hf: Heightfield) {
    {
        let recipe = Recipe {
            features: Feature::ALL.to_vec(),
            // The coast's stepped slopes (most of its build time) are not what is checked;
            // the canyon keeps the default.
            benches: if name.starts_with("N57E011") {
                0.0
            } else {
                Recipe::default().benches
            },
            ..Default::default()
        };
        let (scene, rep) = build_recipe(&hf, &recipe).unwrap();
        let d = &rep.dims;
        eprintln!(
            "{name}: {} nodes; dims {d:?}; effects {:?}",
            scene.stats().nodes,
            rep.effects
                .iter()
                .map(|(f, e)| (f, e.primitives, e.features, e.length_m, e.stop))
                .collect::<Vec<_>>()
        );
        assert!(d.floor_depth_m >= 0.3 * d.relief_m - 1e-3, "{d:?}");
        if d.hoodoo_count > 0 {
            assert!((10.0..=300.0).contains(&d.hoodoo_height_m), "{d:?}");
            assert!(d.hoodoo_height_m < 0.5 * d.relief_m, "{d:?}");
        }
        if d.arch_count > 0 {
            assert!((10.0..=300.0).contains(&d.arch_span_m), "{d:?}");
            assert!(d.arch_span_m <= 0.5 * d.relief_m, "{d:?}");
            assert!(d.arch_thickness_m >= d.voxel_m, "{d:?}");
        }
        let soft = d
            .soft_thickness_m
            .expect("the default geology has soft strata");
        let karst = rep
            .effects
            .iter()
            .find(|(f, _)| *f == Feature::Karst)
            .map(|x| &x.1);
        let karst = karst.unwrap_or_else(|| panic!("{name}: no karst: {:?}", d.notes));
        // Issue 42: the physical radius, at most half the soft strata.
        let want = recipe::FeatureSizes::default()
            .karst_radius_m
            .min(0.5 * soft);
        assert!(
            (d.karst_radius_m - want).abs() < 1e-4 && d.karst_radius_m <= 0.5 * soft,
            "{d:?}"
        );
        assert!(d.karst_step_m <= 0.5 * soft, "{d:?}");
        assert!(karst.length_m > 0.0 && karst.features > 10, "{karst:?}");
        assert!(
            rep.effects.iter().all(|(_, e)| e.primitives > 0),
            "{:?}",
            rep.effects
        );
        // The plateau has no sea (issue 19: no lake at the 25th percentile), the coast has.
        let coast = name.starts_with("N57E011");
        assert_eq!(rep.has_sea, coast, "{name}: {:?}", d.notes);
        assert_eq!(rep.sea_level, coast.then_some(0.0), "{name}");
    }
}

/// The karst stop rule is reachable (the default geology's hard strata are above `rho_stop`),
/// passages spread sideways more than down, and the sphere poles of the carved steps are in
/// soft rock.
#[test]
fn karst_stops_on_its_threshold_and_follows_the_strata() {
    let Some(hf) = canyon() else { return };
    let (lo, hi) = hf.min_max().unwrap();
    let period = (hi - lo) / 6.0;
    let geo = geology_for(&hf, period);
    let mut b = SceneBuilder::new(
        &hf,
        geo.clone(),
        &ImplicitizeSettings {
            depth: 0.3 * (hi - lo),
            ..Default::default()
        },
    )
    .unwrap();
    let ks = KarstSettings {
        radius: 0.1 * period,
        min_radius: 0.05 * period,
        step: 0.1 * period,
        poisson_radius: 0.08 * period,
        budget: 1 << 22,
        cliff_spacing: period,
        ..Default::default()
    };
    let rep = b.karst(&ks, &Region::everywhere()).unwrap();
    eprintln!(
        "karst to its end on the canyon 64x64: {rep:?} (period {period} m)",
        rep = (rep.candidates, rep.primitives, rep.features, rep.stop)
    );
    assert!(
        matches!(rep.stop, Some(KarstStop::Threshold | KarstStop::Exhausted)),
        "{:?}",
        rep.stop
    );
    assert!(rep.features > 100, "{}", rep.features);
    let cs = b.carvings();
    let mean = |k: usize| cs.iter().map(|c| c.0[k] as f64).sum::<f64>() / cs.len() as f64;
    let m = [mean(0), mean(1), mean(2)];
    let var = |k: usize| {
        cs.iter()
            .map(|c| (c.0[k] as f64 - m[k]).powi(2))
            .sum::<f64>()
            / cs.len() as f64
    };
    let (sh, sv) = ((var(0) + var(1)).sqrt(), var(2).sqrt());
    assert!(sh > 3.0 * sv, "horizontal spread {sh} vs vertical {sv}");
    // The passages are flattened along the bedding: their vertical semi-axis is `high` times
    // the radius.
    let high = ks.axes().1;
    let mut soft_poles = 0;
    for (c, _, _) in cs {
        if [1.0f32, -1.0]
            .iter()
            .all(|s| geo.resistance([c[0], c[1], c[2] + s * high * ks.min_radius]) < ks.rho0)
        {
            soft_poles += 1;
        }
    }
    assert!(
        soft_poles * 10 >= cs.len() * 9,
        "{soft_poles} of {}",
        cs.len()
    );
}

/// Iterated sea erosion samples the carved surface again and cuts deeper inland than one pass.
#[test]
fn iterated_sea_erosion_cuts_deeper() {
    let Some(hf) = coast() else { return };
    // Soft beds at every height (a thick resistant bed at the waterline, as the default
    // column can put there, rightly holds the sea back whatever the passes).
    let geo = alternating_beds(15.0);
    let removed = |iterations: usize| {
        let mut b = SceneBuilder::new(&hf, geo.clone(), &ImplicitizeSettings::default()).unwrap();
        let s = SeaErosion {
            iterations,
            caves: 0,
            ..sea_settings()
        };
        let rep = b.sea_erosion(&s, &Region::everywhere()).unwrap();
        let f = b.frame();
        let scene = b.build(true).unwrap();
        let mut n = 0;
        for i in 0..hf.height() * 3 {
            for j in 0..hf.width() * 3 {
                let (x, y) = (j as f32 * f.cx / 3.0, i as f32 * f.cy / 3.0);
                let g = scene.dem_height(x, y).unwrap();
                let mut z = g - 0.5;
                while z > -5.0 {
                    if !scene.inside([x, y, z]) {
                        n += 1;
                    }
                    z -= 1.0;
                }
            }
        }
        (n, rep.primitives)
    };
    let (one, p1) = removed(1);
    let (three, p3) = removed(3);
    eprintln!("sea erosion removed points: 1 pass {one} ({p1} spheres), 3 passes {three} ({p3})");
    assert!(p3 > p1 && three as f64 > 1.1 * one as f64, "{one} {three}");
}

/// Sea cliffs cut only near the shore, and leave hard strata standing.
#[test]
fn sea_cliffs_cut_back_the_shore_only() {
    let Some(hf) = coast() else { return };
    let geo = geology_for(&hf, 40.0);
    // Rock saturates 3 m under the surface, as in the recipes (two voxels).
    let imp = ImplicitizeSettings {
        transition: 3.0,
        ..Default::default()
    };
    let plain = SceneBuilder::new(&hf, geo.clone(), &imp)
        .unwrap()
        .build(true)
        .unwrap();
    let mut b = SceneBuilder::new(&hf, geo.clone(), &imp).unwrap();
    let s = SeaCliffs {
        retreat: 60.0,
        radius: 4.0,
        ..Default::default()
    };
    // The northern half of the crop, to keep the test fast.
    let f0 = b.frame();
    let (xm, ym) = (
        (f0.width - 1) as f32 * f0.cx,
        (f0.height - 1) as f32 * f0.cy,
    );
    let region = Region::in_box(Aabb::new([0.0, 0.5 * ym, -100.0], [xm, ym, 500.0]));
    let rep = b.sea_cliffs(&s, &region).unwrap();
    assert!(rep.primitives > 100, "{rep:?}");
    let f = b.frame();
    let scene = b.build(true).unwrap();
    // The close-up looks from the sea: the site's axis points to lower ground.
    assert_eq!(rep.axes.len(), rep.sites.len());
    for (p, a) in rep.sites.iter().zip(&rep.axes) {
        let out = |t: f32| {
            let (x, y) = (p[0] + t * a[0], p[1] + t * a[1]);
            scene
                .dem_height(x.clamp(0.0, xm), y.clamp(0.0, ym))
                .unwrap()
        };
        assert!(out(60.0) < out(-60.0), "{p:?} {a:?}");
    }
    let (cx, cy) = (f.cx, f.cy);
    let near_sea = |x: f32, y: f32, d: f32| {
        let r = (d / cx.min(cy)).ceil() as i32 + 1;
        let (j0, i0) = f.to_grid([x, y, 0.0]);
        (-r..=r).any(|di| {
            (-r..=r).any(|dj| {
                let (j, i) = (j0.round() as i32 + dj, i0.round() as i32 + di);
                j >= 0
                    && i >= 0
                    && (j as usize) < hf.width()
                    && (i as usize) < hf.height()
                    && hf.get(j as usize, i as usize) <= s.sea_level
                    && {
                        let p = f.node(j as usize, i as usize, 0.0);
                        ((p[0] - x).powi(2) + (p[1] - y).powi(2)).sqrt() <= d
                    }
            })
        })
    };
    // Removed fraction of the rock in the cut band, by hardness: soft strata go first.
    let (mut removed, mut soft, mut soft_removed, mut hard, mut hard_removed) = (0, 0, 0, 0, 0);
    for i in 0..hf.height() * 2 {
        for j in 0..hf.width() * 3 {
            let (x, y) = (j as f32 * cx / 3.0, i as f32 * cy / 2.0);
            if y < 0.5 * ym - 2.0 * s.retreat {
                continue;
            }
            let g = scene.dem_height(x, y).unwrap();
            let mut z = g - 0.25;
            while z > s.sea_level {
                let p = [x, y, z];
                if plain.inside(p) {
                    let gone = !scene.inside(p);
                    if gone {
                        assert!(y >= 0.5 * ym - s.radius, "{p:?} outside the region");
                        removed += 1;
                        let diag = (cx * cx + cy * cy).sqrt();
                        assert!(near_sea(x, y, s.retreat + s.radius + diag), "{p:?}");
                    }
                    if near_sea(x, y, 0.5 * s.retreat) {
                        let rho = geo.resistance(p);
                        if rho < 0.4 {
                            soft += 1;
                            soft_removed += gone as usize;
                        } else if rho > 0.6 {
                            hard += 1;
                            hard_removed += gone as usize;
                        }
                    }
                }
                z -= 0.5;
            }
        }
    }
    let frac = |a: usize, b: usize| a as f64 / b.max(1) as f64;
    eprintln!(
        "sea cliffs: {} spheres in {} columns; removed {removed}; near the shore soft {soft_removed}/{soft}, hard {hard_removed}/{hard}",
        rep.primitives, rep.features
    );
    assert!(removed > 200, "{removed}");
    assert!(
        frac(soft_removed, soft) > frac(hard_removed, hard),
        "soft strata must retreat more than hard ones"
    );
}

/// A real scene mesh simplified to a quarter stays watertight with the same Euler
/// characteristic.
#[test]
fn simplified_scene_mesh_stays_watertight() {
    let Some(hf) = coast() else { return };
    let scene = full_scene(&hf);
    let (mesh, _) = mesh_of(&scene, [64, 64, 48]);
    let t0 = topology(&mesh);
    let (s, rep) = simplify(&mesh, mesh.triangles.len() / 4).unwrap();
    let t1 = topology(&s);
    eprintln!("simplify: {rep:?}, before {t0:?}, after {t1:?}");
    assert!(s.triangles.len() <= mesh.triangles.len() / 4 + 2);
    assert_eq!((t1.bad_edges, t1.misoriented_edges), (0, 0), "{t1:?}");
    assert_eq!(t0.euler, t1.euler);
}

/// Small closed pits that a recipe adds to the top surface of the bare DEM, and the mesh look.
/// Returns the pits added, the eroded look and the bare one (at the eroded scene's voxel).
/// Benches off on both (they are no weathering, and the bare DEM has none).
fn added_pits(hf: &Heightfield, features: Vec<Feature>) -> (usize, SurfaceLook, SurfaceLook) {
    let look = |features: Vec<Feature>, voxel: Option<f32>, r: Option<f32>| {
        let recipe = Recipe {
            features,
            seed: 1,
            voxel,
            benches: 0.0,
            ..Default::default()
        };
        let (scene, rep) = build_recipe(hf, &recipe).unwrap();
        let v = rep.dims.voxel_m;
        let r = r.unwrap_or(rep.dims.weathering_radius_m);
        let sz = scene.bbox().size();
        let cells = [0, 1, 2].map(|k| ((sz[k] / v).ceil() as usize).clamp(2, 512));
        let (mesh, _) = polygonize(
            &scene,
            &MeshSettings {
                cells,
                normals: false,
                ..Default::default()
            },
        )
        .unwrap();
        let max_cells = (std::f32::consts::PI * (2.0 * r / v).powi(2)).ceil() as usize;
        (surface_look(&mesh, v, 0.25 * v, max_cells), v, r)
    };
    let (eroded, v, r) = look(features, None, None);
    let (bare, ..) = look(Vec::new(), Some(v), Some(r));
    (
        eroded.small_pits.saturating_sub(bare.small_pits),
        eroded,
        bare,
    )
}

/// Issue #19: wind and rain weathering must read as grooves and undercuts along the strata of
/// exposed faces, not as "bubble-wrap" (many small round dents on cliffs and flats). Round
/// sphere pits on the grandcanyon 64x64 crop added 47 small closed pits to the top surface
/// (groove carving: 8), so at most 20 may be added; the faces are still undercut. Since issue
/// 42 on a 16x16 crop resampled to 8 m (hollows of 4 m need such cells).
#[test]
fn wind_and_rain_carve_grooves_not_pits() {
    let Some(hf) = fine(dem_crop("grandcanyon", 200, 160, 16, 16), 8.0) else {
        return;
    };
    let (added, look, bare) = added_pits(&hf, vec![Feature::Wind, Feature::Rain]);
    eprintln!(
        "wind+rain (grandcanyon 16x16 at 8 m): {added} small pits added, {look:?}, bare {bare:?}"
    );
    assert!(
        added <= 20,
        "bubble-wrap: {added} small pits added, {look:?}"
    );
    // Issue 42: 4 m hollows on a kilometre of smooth (resampled) canyon undercut a few per
    // mille of it, at least twice the bare DEM's.
    assert!(
        look.downward_share > 0.001 && look.downward_share > 2.0 * bare.downward_share,
        "no undercut at all: {look:?} vs bare {bare:?}"
    );
}

// ---- Issue 19: sea only where the DEM has sea ----

/// [`detect_sea`] on whole real DEMs: the Kattegat coast (SRTM sea at 0 m) and the Salish Sea
/// (bathymetry) have sea at 0 m; the inland DEMs have none, voids included (N47E011).
#[test]
fn sea_is_detected_on_coasts_only() {
    let mut seen = 0;
    for id in relief_testdata::DEM_IDS {
        let Some(hf) = relief_testdata::load_dem(id) else {
            return;
        };
        let s = detect_sea(&hf);
        eprintln!("{id}: {s:?}");
        match id {
            "N57E011" => {
                let s = s.expect("N57E011 has sea");
                assert_eq!((s.level, s.kind), (0.0, SeaKind::Zero));
                assert!((0.84..0.87).contains(&s.share), "{s:?}");
            }
            "topobathy" => {
                let s = s.expect("topobathy has sea");
                assert_eq!((s.level, s.kind), (0.0, SeaKind::Zero));
                assert!((0.40..0.50).contains(&s.share), "{s:?}");
            }
            _ => assert_eq!(s, None, "{id}"),
        }
        seen += 1;
    }
    assert_eq!(seen, relief_testdata::DEM_IDS.len());
}

/// A real coast lifted to a lake: the Kattegat crop raised by 372 m with +-0.25 m of speckle
/// on every sample (unflattened water in a DEM whose datum is not the lake's) is a lake at
/// about 372 m covering the crop's sea (the old rule, exactly the lowest value, found none);
/// the same speckle on the Grand Canyon crop still gives no sea.
#[test]
fn a_noisy_lake_on_real_dems_is_sea_and_the_canyon_still_is_not() {
    let (Some(co), Some(gc)) = (coast(), dem_crop("grandcanyon", 200, 160, 128, 128)) else {
        return;
    };
    let speckle = |hf: &Heightfield, lift: f32| {
        let (w, h) = (hf.width(), hf.height());
        let v: Vec<f32> = (0..w * h)
            .map(|k| {
                let u = (k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 40;
                hf.as_slice()[k] + lift + (u as f32 / (1u64 << 24) as f32 - 0.5) * 0.5
            })
            .collect();
        let (cx, cy) = hf.cell_size();
        Heightfield::new(w, h, v, cx, cy).unwrap()
    };
    let sea = detect_sea(&co).expect("the coast has sea");
    let lake = detect_sea(&speckle(&co, 372.0)).expect("a lake");
    eprintln!("coast {sea:?}, lifted {lake:?}");
    assert_eq!(lake.kind, SeaKind::FlatMinimum);
    assert!((lake.level - 372.0).abs() < 0.3, "{lake:?}");
    assert!(lake.share > 0.8 * sea.share, "{lake:?} vs {sea:?}");
    assert_eq!(detect_sea(&gc), None);
    assert_eq!(detect_sea(&speckle(&gc, 0.0)), None);
}

/// The shore features a report placed, with their primitive counts.
fn shore(rep: &RecipeReport) -> Vec<(Feature, usize)> {
    rep.effects
        .iter()
        .filter(|(f, _)| matches!(f, Feature::Sea | Feature::Caves | Feature::Cliffs))
        .map(|(f, e)| (*f, e.primitives))
        .collect()
}

/// Every feature, no mesh.
fn all_features_job() -> VolumeJob {
    VolumeJob {
        recipe: Recipe {
            features: Feature::ALL.to_vec(),
            // The stepped slopes are not what these tests check (they have their own), and
            // they are most of the build's time on these windows.
            benches: 0.0,
            ..Default::default()
        },
        mesh: false,
        ..Default::default()
    }
}

/// With every feature on and no `sea_level`, the Grand Canyon gets no sea: no shore
/// primitives, no water, a note (the old default flooded it at the 25th percentile); the
/// coast gets its sea at 0 m with shore features; an explicit level on the canyon still
/// carves a shore there (the old behaviour, on purpose).
#[test]
fn shore_features_only_where_the_dem_has_sea_unless_a_level_is_set() {
    let Some(gc) = fine(dem_crop("grandcanyon", 200, 160, 16, 16), 8.0) else {
        return;
    };
    let job = all_features_job();
    // The canyon, default: no sea.
    let built = job.build(&gc, &relief_heightfield::NoProgress).unwrap();
    let rep = &built.report;
    assert_eq!(shore(rep), vec![], "{:?}", rep.dims.notes);
    assert!(!rep.has_sea);
    assert_eq!((rep.sea_level, rep.sea), (None, None));
    let note = rep
        .dims
        .notes
        .iter()
        .find(|n| n.contains("no sea in this DEM"))
        .unwrap_or_else(|| panic!("no sea note: {:?}", rep.dims.notes));
    assert!(
        note.contains("cliffs, sea, caves") && note.contains("sea_level"),
        "{note}"
    );
    assert!(
        rep.highlights
            .iter()
            .all(|h| !matches!(h.feature, Feature::Sea | Feature::Caves | Feature::Cliffs)),
        "{:?}",
        rep.highlights
    );
    let f = &built.figures;
    assert_eq!((f.sea_level_m, f.water_drawn), (None, false));
    assert!(f.summary().contains("no sea"), "{}", f.summary());
    let json = serde_json::to_value(f).unwrap();
    assert!(json["sea_level_m"].is_null() && json["sea_detected"].is_null());
    assert!(json["notes"].to_string().contains("no sea in this DEM"));
    // The other features still run.
    assert!(
        rep.effects
            .iter()
            .any(|(f, e)| *f == Feature::Karst && e.primitives > 0),
        "{:?}",
        rep.effects
    );

    // The canyon with an explicit lake level: the shore is carved there, water drawn.
    let q25 = relief_heightfield::metrics::quantile(gc.as_slice(), 0.25).unwrap();
    let (_, rep) = build_recipe(
        &gc,
        &Recipe {
            sea_level: Some(q25),
            ..job.recipe.clone()
        },
    )
    .unwrap();
    let s = shore(&rep);
    assert!(
        s.len() == 2 && s.iter().all(|&(_, n)| n > 0),
        "{s:?} {:?}",
        rep.dims.notes
    );
    assert!(rep.has_sea && rep.sea_level == Some(q25) && rep.sea.is_none());
    assert!(!rep.dims.notes.iter().any(|n| n.contains("no sea")));
}

/// The coast half of [`shore_features_only_where_the_dem_has_sea_unless_a_level_is_set`], a
/// test of its own so that the two run in parallel (issue 45).
#[test]
fn shore_features_on_the_coast_where_the_dem_has_sea() {
    let Some(co) = fine(dem_crop("N57E011", 888, 72, 20, 20), 8.0) else {
        return;
    };
    let job = all_features_job();
    // The coast, default: sea at 0 m, detected, shore features placed.
    let built = job.build(&co, &relief_heightfield::NoProgress).unwrap();
    let rep = &built.report;
    let s = shore(rep);
    assert!(
        s.len() == 2 && s.iter().all(|&(_, n)| n > 0),
        "{s:?} {:?}",
        rep.dims.notes
    );
    assert!(rep.has_sea && rep.sea_level == Some(0.0));
    let d = rep.sea.expect("detected");
    assert_eq!(d.kind, SeaKind::Zero);
    assert!(d.share > 0.3, "{d:?}");
    assert!(built.figures.water_drawn);
    assert!(
        built
            .figures
            .summary()
            .contains("sea level 0.0 m (detected")
    );

    // The coast with karst only: no shore features, but its sea is still drawn.
    let (_, rep) = build_recipe(
        &co,
        &Recipe {
            features: vec![Feature::Karst],
            ..job.recipe.clone()
        },
    )
    .unwrap();
    assert_eq!(shore(&rep), vec![]);
    assert!(
        rep.has_sea && rep.sea_level == Some(0.0),
        "{:?}",
        rep.dims.notes
    );
}

/// Hoodoos stand along rims and canyon walls (the breaks where caprock is undercut), not spread
/// evenly over the plateau: their sites are mostly within three spacings of ground steeper
/// than 35 degrees, more often than the gentle ground they are chosen from.
#[test]
fn hoodoos_line_the_rims() {
    let Some(gc) = fine(dem_crop("grandcanyon", 200, 160, 40, 40), 8.0) else {
        return;
    };
    let (_, rep) = build_recipe(
        &gc,
        &Recipe {
            features: vec![Feature::Hoodoos],
            ..Default::default()
        },
    )
    .unwrap();
    let sites = &rep
        .effects
        .iter()
        .find(|(f, _)| *f == Feature::Hoodoos)
        .expect("hoodoos placed")
        .1
        .sites;
    assert!(sites.len() >= 10, "{} hoodoos", sites.len());
    let (cx, cy) = gc.cell_size();
    let (cx, cy) = (cx as f32, cy as f32);
    let (w, h) = (gc.width(), gc.height());
    let slope = |j: usize, i: usize| {
        let (j0, j1) = (j.saturating_sub(1), (j + 1).min(w - 1));
        let (i0, i1) = (i.saturating_sub(1), (i + 1).min(h - 1));
        let gx = (gc.get(j1, i) - gc.get(j0, i)) / ((j1 - j0) as f32 * cx);
        let gy = (gc.get(j, i1) - gc.get(j, i0)) / ((i1 - i0) as f32 * cy);
        (gx * gx + gy * gy).sqrt().atan().to_degrees()
    };
    let reach = 3.0 * 4.0 * rep.dims.hoodoo_radius_m;
    let near = |j: usize, i: usize| {
        let (rx, ry) = ((reach / cx).ceil() as isize, (reach / cy).ceil() as isize);
        (-ry..=ry).any(|di| {
            (-rx..=rx).any(|dj| {
                let (x, y) = (j as isize + dj, i as isize + di);
                let d2 = (dj as f32 * cx).powi(2) + (di as f32 * cy).powi(2);
                x >= 0
                    && y >= 0
                    && (x as usize) < w
                    && (y as usize) < h
                    && d2 <= reach * reach
                    && slope(x as usize, y as usize) > 35.0
            })
        })
    };
    // Site (x, y) in metres from the south-west node; row 0 of the DEM is north.
    let cell = |p: &[f32; 3]| {
        let j = (p[0] / cx).round() as usize;
        let i = h - 1 - (p[1] / cy).round() as usize;
        (j.min(w - 1), i.min(h - 1))
    };
    let share_sites = sites
        .iter()
        .filter(|p| {
            let (j, i) = cell(p);
            near(j, i)
        })
        .count() as f64
        / sites.len() as f64;
    let gentle: Vec<(usize, usize)> = (0..h)
        .flat_map(|i| (0..w).map(move |j| (j, i)))
        .filter(|&(j, i)| slope(j, i) < 25.0)
        .collect();
    let share_gentle =
        gentle.iter().filter(|&&(j, i)| near(j, i)).count() as f64 / gentle.len() as f64;
    eprintln!("hoodoos near rims {share_sites:.2}, gentle ground near rims {share_gentle:.2}");
    assert!(
        share_sites >= 0.8 && share_sites > share_gentle + 0.1,
        "{share_sites:.2} vs {share_gentle:.2}"
    );
}
