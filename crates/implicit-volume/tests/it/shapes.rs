//! Closed analytic shapes: watertightness, orientation and Euler characteristic of the mesher.
use relief_implicit_volume::*;

fn mesh_of(tree: TerrainTree, root: NodeId, cells: usize) -> Mesh {
    let scene = Scene::new(tree, root, Geology::new(), None).unwrap();
    let s = MeshSettings {
        cells: [cells; 3],
        chunk: 8,
        ..Default::default()
    };
    polygonize(&scene, &s).unwrap().0
}

/// A ring of `n` blended spheres (blend 1): the one at angle `a` has the centre and radius
/// `sphere(a)`.
fn blended_ring(n: usize, sphere: impl Fn(f32) -> ([f32; 3], f32)) -> (TerrainTree, NodeId) {
    let mut t = TerrainTree::new();
    let ids: Vec<NodeId> = (0..n)
        .map(|k| {
            let (c, r) = sphere(k as f32 / n as f32 * std::f32::consts::TAU);
            t.sphere(c, r, 1.0).unwrap()
        })
        .collect();
    let root = t.bvh_blend(&ids).unwrap();
    (t, root)
}

#[test]
fn sphere_is_a_closed_genus_0_surface() {
    let mut t = TerrainTree::new();
    let r = t.sphere([1.0, 2.0, 3.0], 10.0, 1.0).unwrap();
    let m = mesh_of(t, r, 30);
    let topo = topology(&m);
    assert_eq!(topo.bad_edges, 0, "{topo:?}");
    assert_eq!(topo.misoriented_edges, 0, "{topo:?}");
    assert_eq!(topo.euler, 2, "{topo:?}");
    // Surface radius of e (1 - d^2/R^2)^3 = T: R sqrt(1 - (T/e)^(1/3)).
    let want = 10.0 * (1.0f32 - 0.5f32.cbrt()).sqrt();
    for (p, n) in m.positions.iter().zip(&m.normals) {
        let d = [p[0] - 1.0, p[1] - 2.0, p[2] - 3.0];
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        assert!((r - want).abs() < 0.25, "{r} vs {want}");
        // Normals point outwards.
        assert!(n[0] * d[0] + n[1] * d[1] + n[2] * d[2] > 0.9 * r);
    }
}

#[test]
fn torus_of_blended_spheres_has_euler_0_and_chunks_weld() {
    let (t, root) = blended_ring(32, |a| ([20.0 * a.cos(), 20.0 * a.sin(), 0.0], 8.0));
    let m = mesh_of(t, root, 48);
    let topo = topology(&m);
    assert_eq!(topo.bad_edges, 0, "{topo:?}");
    assert_eq!(topo.misoriented_edges, 0, "{topo:?}");
    assert_eq!(topo.euler, 0, "{topo:?}");
}

#[test]
fn csg_operators_keep_the_mesh_manifold() {
    let mut t = TerrainTree::new();
    let a = t.ellipsoid([0.0; 3], [20.0, 14.0, 10.0], 1.0).unwrap();
    let b = t
        .capsule([-30.0, 0.0, 0.0], [30.0, 0.0, 0.0], 7.0, 1.0)
        .unwrap();
    let c = t
        .cone([0.0, 0.0, -10.0], [0.0, 0.0, 15.0], 9.0, 3.0, 1.0)
        .unwrap();
    let d = t.difference(a, b).unwrap(); // a tunnel through the ellipsoid
    let u = t.union(d, c).unwrap();
    let w = t.warp(u, 1.0, 0.1, 4).unwrap();
    let m = mesh_of(t, w, 48);
    let topo = topology(&m);
    assert_eq!(topo.bad_edges, 0, "{topo:?}");
    assert_eq!(topo.misoriented_edges, 0, "{topo:?}");
    assert!(topo.faces > 100);
}

#[test]
fn precomputed_grid_mesher_matches_and_rejects_bad_input() {
    let mut t = TerrainTree::new();
    let r = t.sphere([0.0; 3], 10.0, 1.0).unwrap();
    let scene = Scene::new(t, r, Geology::new(), None).unwrap();
    let b = Aabb::new([-11.0; 3], [11.0; 3]);
    let g = sample_grid(&scene, &b, [23, 23, 23]).unwrap();
    let m = polygonize_grid(&g, [23, 23, 23], b.min, [1.0; 3], THRESHOLD, 8).unwrap();
    let topo = topology(&m);
    assert_eq!((topo.bad_edges, topo.euler), (0, 2));
    assert!(polygonize_grid(&g, [23, 23, 22], b.min, [1.0; 3], THRESHOLD, 8).is_err());
    let e = polygonize(
        &scene,
        &MeshSettings {
            chunk: 1,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("chunk"));
}

/// Grid nodes exactly on the iso-surface (a flat DEM on a lattice plane) give coincident
/// vertices and zero-area triangles; their winding must still be consistent.
#[test]
fn iso_values_on_grid_nodes_keep_the_orientation_consistent() {
    let hf = relief_heightfield::Heightfield::from_fn(12, 12, 1.0, 1.0, |x, y| {
        if (3..8).contains(&x) && (4..9).contains(&y) {
            12.0
        } else {
            10.0
        }
    });
    let mut b = SceneBuilder::new(
        &hf,
        Geology::layered_default([5.0, 5.0, 10.0], 4.0, 1).unwrap(),
        &ImplicitizeSettings {
            transition: 1.0,
            depth: 4.0,
        },
    )
    .unwrap();
    let s = b.tree_mut().sphere([6.0, 6.0, 10.0], 3.0, -1.0).unwrap();
    b.add_carving(s);
    let scene = b.build(true).unwrap();
    let (m, _) = polygonize(
        &scene,
        &MeshSettings {
            bbox: Some(Aabb::new([-1.0, -1.0, 0.0], [12.0, 12.0, 20.0])),
            cells: [13, 13, 20],
            chunk: 4,
            ..Default::default()
        },
    )
    .unwrap();
    let topo = topology(&m);
    assert!(topo.faces > 100);
    assert_eq!((topo.bad_edges, topo.misoriented_edges), (0, 0), "{topo:?}");
}

/// Interval culling (blocks split down to 2^3 nodes) and the rolling edge slots give exactly
/// the mesh of marching tetrahedra on the dense grid, and the same on 1 and 2 threads.
#[test]
fn culled_chunked_mesh_equals_the_dense_grid_mesh() {
    let (t, root) = blended_ring(40, |a| {
        let r = 4.0 + 3.0 * (3.0 * a).sin().abs();
        ([20.0 * a.cos(), 20.0 * a.sin(), 2.0 * a.cos()], r)
    });
    let scene = Scene::new(t, root, Geology::new(), None).unwrap();
    let b = Aabb::new([-32.0, -32.0, -12.0], [32.0, 32.0, 12.0]);
    let cells = [70, 66, 30];
    let s = MeshSettings {
        bbox: Some(b),
        cells,
        chunk: 16,
        close_boundary: true,
        normals: false,
    };
    let run =
        |threads: usize| relief_testdata::with_threads(threads, || polygonize(&scene, &s).unwrap());
    let (m, rep) = run(2);
    assert_eq!(run(1).0, m);
    let dims = [cells[0] + 1, cells[1] + 1, cells[2] + 1];
    let g = sample_grid(&scene, &b, dims).unwrap();
    let sz = b.size();
    let step = [
        sz[0] / cells[0] as f32,
        sz[1] / cells[1] as f32,
        sz[2] / cells[2] as f32,
    ];
    let dense = polygonize_grid(&g, dims, b.min, step, THRESHOLD, 16).unwrap();
    assert_eq!(m.triangles.len(), dense.triangles.len());
    assert_eq!(m, dense);
    // The culling evaluated far fewer nodes than the dense grid holds.
    assert!(
        rep.evaluations * 3 < g.len(),
        "{} of {}",
        rep.evaluations,
        g.len()
    );
    let topo = topology(&m);
    assert_eq!((topo.bad_edges, topo.misoriented_edges), (0, 0));
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn norm(a: [f32; 3]) -> f32 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}
fn normalize(a: [f32; 3]) -> [f32; 3] {
    let n = norm(a);
    [a[0] / n, a[1] / n, a[2] / n]
}

/// The landscape camera sits over the DEM's footprint above all matter and looks down across
/// it; a close-up near the border stays over the DEM, and a pillar standing between the
/// target and the default eye position turns the eye to another side.
#[test]
fn cameras_stay_over_the_scene_and_look_past_occluders() {
    let hf = relief_heightfield::Heightfield::from_fn(41, 41, 10.0, 10.0, |x, _| 100.0 + x as f32);
    let mut b = SceneBuilder::new(&hf, Geology::new(), &ImplicitizeSettings::default()).unwrap();
    let target = [200.0, 200.0, 130.0];
    // A pillar 60 m south-west of the target, on the default close-up line of sight.
    let d = normalize([-0.55, -0.7, 0.0]);
    let foot = [200.0 + 60.0 * d[0], 200.0 + 60.0 * d[1], 100.0];
    let pillar = b
        .tree_mut()
        .capsule(foot, [foot[0], foot[1], 400.0], 12.0, 2.0)
        .unwrap();
    b.add_matter(pillar);
    let scene = b.build(true).unwrap();
    let bb = scene.bbox();

    let land = Camera::landscape(&scene);
    assert!(land.eye[2] > bb.max[2], "{land:?}");
    for k in 0..2 {
        assert!((0.0..=400.0).contains(&land.eye[k]), "{land:?}");
        assert!((0.0..=400.0).contains(&land.target[k]), "{land:?}");
    }
    assert!(land.target[2] < land.eye[2]);

    let far = 300.0;
    let cam = Camera::closeup(&scene, target, far);
    assert!(!scene.inside(cam.eye), "{cam:?}");
    // The pillar hides the target from the default side: the eye looks from another side at
    // the full distance (pressed in front of the pillar, as before, it stood under 60 m off)
    // and sees the target over a clear line, from over the DEM.
    let dist = norm(sub(cam.eye, target));
    let sight = sub(cam.eye, target);
    let clear = (1..48).all(|m| {
        let t = m as f32 / 48.0;
        !scene.inside([
            target[0] + t * sight[0],
            target[1] + t * sight[1],
            target[2] + t * sight[2],
        ])
    });
    assert!(clear, "eye behind the pillar: {cam:?}");
    assert!(dist > 150.0, "{cam:?}");
    for k in 0..2 {
        assert!((0.0..=400.0).contains(&cam.eye[k]), "{cam:?}");
    }
    // Without the pillar the eye goes the whole distance (or to the DEM's border).
    let mut b = SceneBuilder::new(&hf, Geology::new(), &ImplicitizeSettings::default()).unwrap();
    let p = b
        .tree_mut()
        .sphere([380.0, 380.0, 600.0], 5.0, 1.0)
        .unwrap();
    b.add_matter(p);
    let open = b.build(true).unwrap();
    let cam = Camera::closeup(&open, target, far);
    assert!(norm(sub(cam.eye, target)) > 150.0, "{cam:?}");
    // Near the border the eye stays over the DEM.
    let cam = Camera::closeup(&open, [30.0, 30.0, 110.0], far);
    assert!(cam.eye[0] >= -1e-3 && cam.eye[1] >= -1e-3, "{cam:?}");
}

/// A DEM that stores its sea as a flat surface at the sea level (SRTM: 0 m) and its land in
/// whole metres: the render draws all of that flat sea under water (no speckles where the
/// ground and the water plane coincide) and its coast along the half-metre contour, not
/// along the cells' edges.
#[test]
fn a_flat_sea_at_the_level_is_all_water_and_its_coast_follows_the_half_metre_contour() {
    // West half sea at 0 m, east half land rising 1 m per cell from 1 m.
    let hf = relief_heightfield::Heightfield::from_fn(40, 40, 10.0, 10.0, |x, _| {
        if x < 20 { 0.0 } else { (x - 19) as f32 }
    });
    let (w, h) = (64, 48);
    let (dry, wet) = dry_and_wet(&hf, [190.0, 200.0, 100.0], (w, h));
    // Straight down from 100 m: pixel column x sees the ground at world x = 190 + 100 u
    // (1.5 m per pixel); the last sea node is at 190 m, the first land node (1 m) at 200 m.
    let th = 20f32.to_radians().tan();
    let world_x = |x: usize| {
        190.0 + 100.0 * ((x as f32 + 0.5) / w as f32 * 2.0 - 1.0) * th * w as f32 / h as f32
    };
    // Under water, even at no depth, the water's blue tint shows (blue minus red rises by
    // more than 30 levels here); dry ground is drawn exactly as without the sea.
    let px = |img: &Image, x: usize, y: usize| {
        let k = 3 * (y * w + x);
        [img.rgb[k], img.rgb[k + 1], img.rgb[k + 2]]
    };
    let (mut sea, mut land) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let wx = world_x(x);
            let (d, v) = (px(&dry, x, y), px(&wet, x, y));
            if (145.0..189.0).contains(&wx) || (190.5..194.5).contains(&wx) {
                // The flat sea, all under water (no speckle of ground fighting the plane),
                // and the ground rising from it up to the half-metre contour at 195 m.
                let tint = |c: [u8; 3]| i32::from(c[2]) - i32::from(c[0]);
                assert!(
                    tint(v) > tint(d) + 30,
                    "sea pixel {x}, {y} (x = {wx} m) not under water: {v:?} vs {d:?}"
                );
                sea += 1;
            } else if (196.0..235.0).contains(&wx) {
                // Land above the contour: drawn dry.
                assert_eq!(v, d, "land pixel {x}, {y} (x = {wx} m) under water");
                land += 1;
            }
        }
    }
    assert!(sea > w * h / 3 && land > w * h / 4, "{sea} {land}");
}

/// A low coastal fringe (1 m cells between a flat 0 m sea and a 30 m headland, as SRTM
/// stores coasts) is planed by sea cliffs and sea erosion to a platform just under the water
/// (`depth` below the sea), not dug into trenches a sphere radius deeper.
#[test]
fn shore_erosion_planes_a_low_fringe_to_a_platform_under_the_water() {
    let hf = relief_heightfield::Heightfield::from_fn(40, 40, 10.0, 10.0, |x, _| match x {
        0..15 => 0.0,
        15..20 => 1.0,
        _ => 30.0,
    });
    // The default transition (twice the cell), as in `relief volume`: the rock is weak for
    // 20 m under the surface, where the spheres cut most of their support.
    let settings = ImplicitizeSettings::default();
    let fringe_is_rock_at = |scene: &Scene, z: f32| {
        (16..=19)
            .all(|j| (10..30).all(|i| scene.inside([j as f32 * 10.0 - 5.0, i as f32 * 10.0, z])))
    };
    // Sea cliffs: the cut stops within `depth` (3 m) under the sea (it reached 7 m when the
    // lowest sphere was centred `depth` under the sea).
    let mut b = SceneBuilder::new(&hf, Geology::new(), &settings).unwrap();
    let cliffs = SeaCliffs {
        depth: 3.0,
        retreat: 60.0,
        radius: 10.0,
        ..Default::default()
    };
    let rep = b.sea_cliffs(&cliffs, &Region::everywhere()).unwrap();
    assert!(rep.primitives > 0);
    let scene = b.build(true).unwrap();
    assert!(fringe_is_rock_at(&scene, -3.0 - 1.0));
    // The fringe itself is cut away down to the water.
    assert!(!scene.inside([175.0, 200.0, 0.5]));
    // Sea erosion: its holes stop at about the band's floor, `depth` (4 m) under the sea (they
    // reached 6 m with the spheres centred on the fringe's surface).
    let mut b = SceneBuilder::new(&hf, Geology::new(), &settings).unwrap();
    let sea = SeaErosion {
        caves: 0,
        ..Default::default()
    };
    let rep = b.sea_erosion(&sea, &Region::everywhere()).unwrap();
    assert!(rep.primitives > 0);
    let scene = b.build(true).unwrap();
    assert!(fringe_is_rock_at(&scene, -4.0 - 1.0));
}

/// The scene of `hf` alone (no geology, no features).
fn bare_scene(hf: &relief_heightfield::Heightfield) -> Scene {
    SceneBuilder::new(hf, Geology::new(), &ImplicitizeSettings::default())
        .unwrap()
        .build(true)
        .unwrap()
}

/// Straight-down renders (40 degrees, no shadows, north up) of `hf`'s scene from `eye`: without
/// water and with a sea at 0 m.
fn dry_and_wet(
    hf: &relief_heightfield::Heightfield,
    eye: [f32; 3],
    (width, height): (usize, usize),
) -> (Image, Image) {
    let scene = bare_scene(hf);
    let cam = Camera {
        eye,
        target: [eye[0], eye[1], 0.0],
        up: [0.0, 1.0, 0.0],
        fov_deg: 40.0,
    };
    let shot = |sea_level: Option<f32>| {
        let s = RenderSettings {
            width,
            height,
            sea_level,
            shadows: false,
            ..Default::default()
        };
        render(&scene, &cam, &s).unwrap()
    };
    (shot(None), shot(Some(0.0)))
}

/// Water tints the ground by its depth: under a seabed sloping from 1 m to 40 m deep, the share
/// of the ground's own red that shows through falls offshore.
#[test]
fn deeper_ground_shows_less_through_the_water() {
    let hf = relief_heightfield::Heightfield::from_fn(40, 40, 10.0, 10.0, |x, _| -1.0 - x as f32);
    let (w, h) = (64, 48);
    let (dry, wet) = dry_and_wet(&hf, [195.0, 195.0, 400.0], (w, h));
    // Share of the dry red left under water, averaged over each pixel column (x grows east,
    // deeper).
    let share = |x: usize| {
        (0..h)
            .map(|y| {
                let k = 3 * (y * w + x);
                f32::from(wet.rgb[k]) / f32::from(dry.rgb[k]).max(1.0)
            })
            .sum::<f32>()
            / h as f32
    };
    let (shallow, deep) = (share(4), share(w - 5));
    assert!(
        shallow > deep + 0.1,
        "shallow {shallow} vs deep {deep}: the tint ignores depth"
    );
}

/// Open water reflects the sky by its angle (Fresnel): seen from a low camera over a small deep
/// basin, the sea towards the horizon (grazing) is redder (more sky) than the sea at the
/// frame's foot; the water tint alone gave every row of open water the same flat blue.
#[test]
fn open_water_reflects_more_sky_towards_the_horizon() {
    let hf = relief_heightfield::Heightfield::from_fn(8, 8, 10.0, 10.0, |_, _| -200.0);
    let scene = bare_scene(&hf);
    let (w, h) = (32, 48);
    let cam = Camera {
        eye: [40.0, -400.0, 60.0],
        target: [40.0, 400.0, -40.0],
        up: [0.0, 0.0, 1.0],
        fov_deg: 50.0,
    };
    let s = RenderSettings {
        width: w,
        height: h,
        sea_level: Some(0.0),
        shadows: false,
        ..Default::default()
    };
    let img = render(&scene, &cam, &s).unwrap();
    let row = |y: usize| (0..w).map(|x| img.rgb[3 * (y * w + x)] as u32).sum::<u32>() / w as u32;
    // Red: the water tint has little, the sky's reflection much.
    let (far, near) = (row(h / 2 + 2), row(h - 1));
    assert!(
        far > near + 20,
        "red at the horizon {far} vs at the foot {near}"
    );
}

/// A ray that runs out of steps inside the scene (creeping along ground it grazes) is drawn as
/// ground, not as a hole of sky: a low camera over a plain with a 6-step budget.
#[test]
fn rays_out_of_steps_are_ground_not_sky() {
    let hf = relief_heightfield::Heightfield::from_fn(64, 64, 10.0, 10.0, |x, y| {
        ((x as f32) * 0.7).sin() + ((y as f32) * 0.5).cos()
    });
    let scene = bare_scene(&hf);
    let (w, h) = (48, 32);
    let s = RenderSettings {
        width: w,
        height: h,
        max_steps: 6,
        shadows: false,
        ..Default::default()
    };
    let cam = Camera {
        eye: [20.0, 20.0, 6.0],
        target: [600.0, 600.0, 0.0],
        up: [0.0, 0.0, 1.0],
        fov_deg: 40.0,
    };
    let img = render(&scene, &cam, &s).unwrap();
    // The lower rows look down at the plain: ground colours (red over blue), no sky.
    for y in h * 3 / 4..h {
        for x in 0..w {
            let k = 3 * (y * w + x);
            let (r, b) = (img.rgb[k], img.rgb[k + 2]);
            assert!(
                r > b,
                "pixel {x}, {y} is sky-blue: {:?}",
                &img.rgb[k..k + 3]
            );
        }
    }
}

/// Issue 44 item 5: the long loops ask `Progress::stopped` during the work and end with
/// `Error::Stopped`, no result: karst percolation (up to 2^22 steps) before every candidate,
/// meshing before every chunk.
#[test]
fn karst_and_meshing_stop_when_asked() {
    use relief_heightfield::{Heightfield, Progress};
    use relief_implicit_volume::{
        Error, Geology, ImplicitizeSettings, KarstSettings, MeshSettings, Region, SceneBuilder,
        polygonize_with_progress,
    };
    /// Says stop from its `after`-th question on.
    struct StopAfter(std::sync::atomic::AtomicUsize, usize);
    impl Progress for StopAfter {
        fn stopped(&self) -> bool {
            self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed) >= self.1
        }
    }
    // Dimples: interior local minima are the karst's sinkholes.
    let hf = Heightfield::from_fn(40, 40, 5.0, 5.0, |x, y| {
        20.0 + 3.0 * (x as f32 * 0.7).sin() * (y as f32 * 0.7).cos()
    });
    let geo = Geology::layered_default([100.0, 100.0, 20.0], 10.0, 1).unwrap();
    let mut b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
    let ks = KarstSettings {
        budget: 50,
        ..Default::default()
    };
    let stop = StopAfter(Default::default(), 0);
    let e = b.karst_with_progress(&ks, &Region::everywhere(), &stop);
    assert!(matches!(e, Err(Error::Stopped(_))), "{e:?}");
    let scene = b.build(true).unwrap();
    let settings = MeshSettings {
        cells: [24, 24, 16],
        ..Default::default()
    };
    let e = polygonize_with_progress(&scene, &settings, &StopAfter(Default::default(), 0));
    assert!(matches!(e, Err(Error::Stopped(_))), "{:?}", e.err());
    // Never asked to stop: the same calls succeed.
    assert!(polygonize_with_progress(&scene, &settings, &relief_heightfield::NoProgress).is_ok());
}
