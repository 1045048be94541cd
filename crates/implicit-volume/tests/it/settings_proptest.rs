//! Random settings (finite, zero, negative, huge, NaN, infinite) to every public entry point:
//! no panic, and every error is an `InvalidParameter` (or a heightfield error) whose message
//! names one of the fields that was given.

use proptest::prelude::*;
use relief_heightfield::Heightfield;
use relief_implicit_volume::*;

/// Interesting f32 values: ordinary ones around `scale`, and the edge cases.
fn num(scale: f32) -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => (0.01f32..3.0).prop_map(move |v| v * scale),
        1 => Just(0.0f32),
        1 => (-3.0f32..0.0).prop_map(move |v| v * scale),
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(-f32::INFINITY),
        1 => Just(1e-7f32),
        1 => Just(1e9f32),
    ]
}

fn unit() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => 0.0f32..=1.0,
        1 => Just(1.5f32),
        1 => Just(-0.2f32),
        1 => Just(f32::NAN),
    ]
}

fn count() -> impl Strategy<Value = usize> {
    prop_oneof![4 => 0usize..12, 1 => Just(100usize), 1 => Just(usize::MAX)]
}

fn dem() -> Heightfield {
    Heightfield::from_fn(14, 12, 10.0, 10.0, |x, y| {
        let (x, y) = (x as f32, y as f32);
        -5.0 + 3.0 * x
            + 6.0 * (0.7 * y).sin()
            + if (4..7).contains(&(x as i32)) {
                -8.0
            } else {
                0.0
            }
    })
}

fn builder() -> SceneBuilder {
    SceneBuilder::new(
        &dem(),
        Geology::layered_default([60.0, 55.0, 10.0], 12.0, 1).unwrap(),
        &ImplicitizeSettings::default(),
    )
    .unwrap()
}

/// Passes when `r` is `Ok`, or an error naming one of `fields`.
fn check<T>(r: Result<T>, fields: &[&str]) -> Result<(), TestCaseError> {
    if let Err(e) = r {
        let msg = e.to_string();
        prop_assert!(
            fields.iter().any(|f| msg.contains(f)),
            "error `{msg}` names none of {fields:?}"
        );
    }
    Ok(())
}

fn weathering() -> impl Strategy<Value = Weathering> {
    (num(8.0), num(12.0), num(2.0), unit(), unit(), any::<u64>()).prop_map(
        |(spacing, radius, energy, beta, threshold, seed)| Weathering {
            spacing,
            radius,
            energy,
            beta,
            threshold,
            seed,
        },
    )
}

const WEATHERING: &[&str] = &["spacing", "radius", "energy", "beta", "threshold"];

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn implicitise_settings(transition in num(10.0), depth in num(30.0)) {
        let r = SceneBuilder::new(
            &dem(),
            Geology::new(),
            &ImplicitizeSettings { transition, depth },
        );
        check(r, &["transition", "depth"])?;
    }

    #[test]
    fn primitives_and_operators(c in num(10.0), r in num(5.0), e in num(1.0), n in num(2.0),
                                amp in num(1.0), freq in num(0.1)) {
        let mut t = TerrainTree::new();
        check(t.sphere([c, 0.0, 1.0], r, e), &["sphere"])?;
        check(t.capsule([0.0; 3], [c, 1.0, 0.0], r, e), &["capsule"])?;
        check(t.cone([0.0; 3], [0.0, 0.0, c], r, n, e), &["cone"])?;
        check(t.ellipsoid([c; 3], [r, n, 1.0], e), &["ellipsoid"])?;
        let a = t.sphere([0.0; 3], 1.0, 1.0).unwrap();
        check(t.smooth_blend(a, a, n), &["smooth_blend.n"])?;
        check(t.warp(a, amp, freq, 3), &["warp.amp", "warp.freq"])?;
        check(t.union(a, NodeId(1000)), &["node id"])?;
    }

    #[test]
    fn geology_nodes(v in unit(), p in num(10.0), f in num(0.1), oct in 0u32..20) {
        let mut g = Geology::new();
        check(g.uniform(v), &["rho"])?;
        check(g.noise(v, v, f, oct, 1), &["base", "amp", "freq", "octaves"])?;
        check(g.strata(p, &[Layer { thickness: p, hardness: v }]), &["thickness", "hardness", "z0", "layers"])?;
        check(Geology::layered_default([0.0, 0.0, p], p, 1), &["period", "center"])?;
        let u = g.uniform(0.5).unwrap();
        check(g.warp(u, p, f, 1), &["amp", "freq"])?;
        check(g.fold(u, p, p, [f, 1.0]), &["amp", "wavelength", "dir"])?;
        check(g.fault(u, [p; 3], [f, 0.0, 1.0], [0.0, 0.0, p]), &["point", "normal", "offset"])?;
        check(g.blend(u, u, v), &["t"])?;
    }

    #[test]
    fn sea_wind_rain(w in weathering(), lvl in num(5.0), d in num(4.0), h in num(20.0),
                     peak in num(3.0), reach in num(100.0), caves in count(), len in num(60.0),
                     dir in num(1.0), slope in num(40.0), iters in 0usize..4,
                     retreat in num(30.0)) {
        let mut b = builder();
        let sea = SeaErosion { weathering: w, sea_level: lvl, depth: d, height: h, peak,
                               reach, caves, cave_length: len, iterations: iters,
                               border_connected: iters % 2 == 0 };
        let mut f = WEATHERING.to_vec();
        f.extend(["sea_level", "depth", "height", "peak", "reach", "cave_length", "iterations"]);
        check(b.sea_erosion(&sea, &Region::everywhere()), &f)?;
        let cl = SeaCliffs { sea_level: lvl, depth: d, retreat, radius: w.radius, beta: w.beta,
                             seed: 1, border_connected: iters % 2 == 1 };
        check(b.sea_cliffs(&cl, &Region::everywhere()),
              &["sea_level", "depth", "retreat", "radius", "beta"])?;
        check(b.wind_erosion(&WindErosion { weathering: w, direction: [dir, 0.0] },
                             &Region::everywhere()), &[WEATHERING, &["direction"]].concat())?;
        check(b.rain_erosion(&RainErosion { weathering: w, full_slope_deg: slope },
                             &Region::everywhere()), &[WEATHERING, &["full_slope_deg"]].concat())?;
        check(b.build(true), &["bbox"])?;
    }

    #[test]
    fn karst(rho0 in unit(), stop in unit(), eps in unit(), radius in num(8.0), energy in num(3.0),
             beta in unit(), sigma in unit(), step in num(6.0), pr in num(4.0),
             dirs in count(), subs in count(), budget in prop_oneof![0usize..400, Just(usize::MAX)],
             sinks in count(), seed in any::<u64>(), minr in num(2.0), vert in unit(),
             cliffs in count(), csp in num(50.0)) {
        let mut b = builder();
        let k = KarstSettings { rho0, rho_stop: stop, epsilon: eps, radius, min_radius: minr,
                                energy, beta, sigma, step, poisson_radius: pr, directions: dirs,
                                vertical: vert, sub_spheres: subs, budget, max_sinkholes: sinks,
                                cliff_seeds: cliffs, cliff_spacing: csp,
                                flatten: vert, radius_jitter: 0.9 * eps, seed };
        check(b.karst(&k, &Region::everywhere()), &["rho0", "rho_stop", "epsilon", "radius",
            "energy", "beta", "sigma", "step", "poisson_radius", "directions", "sub_spheres",
            "budget", "min_radius", "vertical", "cliff_spacing", "flatten"])?;
    }

    #[test]
    fn landforms_and_regions(n in count(), h in num(40.0), r in num(8.0), sp in num(40.0),
                             slope in num(20.0), mv in unit(), mlen in 0usize..200,
                             lo in num(10.0), hi in num(100.0), seed in any::<u64>()) {
        let mut b = builder();
        let region = Region {
            mask: Some(vec![mv; mlen]),
            bbox: Some(Aabb::new([lo, lo, lo], [hi, hi, hi])),
        };
        let names = ["region", "height", "radius", "spacing", "count", "span", "thickness",
                     "altitude", "per_cluster", "spread", "max_slope_deg", "min_slope_deg", "arch feet", "cap_rho", "max_length"];
        check(b.hoodoos(&HoodooSettings { count: n, height: h, radius: r, spacing: sp,
                                          min_slope_deg: 0.0, max_slope_deg: slope,
                                          cap_rho: mv, per_cluster: 1 + n % 70, seed },
                        &region),
              &names)?;
        check(b.arches(&ArchSettings { count: n, span: sp, thickness: r,
                                       max_length: 4.0 * sp, seed },
                       &Region::everywhere()), &names)?;
        check(b.floating_islands(&IslandSettings { count: n, radius: r, altitude: h,
                                                   per_cluster: n % 20, spread: sp, seed },
                                 &Region::everywhere()), &names)?;
        check(b.arch([lo, 10.0], [hi, 20.0], h, r, 1), &names)?;
        check(b.build(true), &["bbox"])?;
    }

    #[test]
    fn mesh_render_section(cx in 0usize..24, cy in 0usize..24, cz in 0usize..24,
                           chunk in 0usize..300, lo in num(10.0), hi in num(150.0),
                           w in 0usize..24, h in 0usize..24, fov in num(45.0),
                           eye in num(300.0), up in num(1.0), steps in 0u32..200,
                           sea in proptest::option::of(num(1.0)), z0 in num(-20.0), z1 in num(80.0)) {
        let mut b = builder();
        b.karst(&KarstSettings { budget: 40, ..Default::default() }, &Region::everywhere()).unwrap();
        let scene = b.build(true).unwrap();
        let ms = MeshSettings {
            bbox: Some(Aabb::new([lo, lo, lo], [hi, hi, hi])),
            cells: [cx, cy, cz],
            chunk,
            close_boundary: true,
            normals: true,
        };
        let r = polygonize(&scene, &ms);
        if let Ok((m, _)) = &r {
            let t = topology(m);
            prop_assert_eq!((t.bad_edges, t.misoriented_edges), (0, 0));
            prop_assert_eq!(m.normals.len(), m.positions.len());
        }
        check(r, &["cells", "chunk", "bbox"])?;
        let cam = Camera { eye: [eye, -eye, 200.0], target: [60.0, 50.0, 0.0],
                           up: [0.0, 0.0, up], fov_deg: fov };
        let rs = RenderSettings { width: w, height: h, light: [up, 0.3, 1.0], max_steps: steps,
                                  shadows: true, ambient_occlusion: true, sea_level: sea,
                                  cutaway: None, adaptive: sea.is_some() };
        check(render(&scene, &cam, &rs), &["image size", "fov_deg", "camera", "light", "sea_level"])?;
        let ss = SectionSettings { start: [lo, 0.0], end: [hi, 100.0], z_range: Some((z0, z1)),
                                   width: w, height: h };
        check(section(&scene, &ss), &["image size", "z_range", "start/end"])?;
        check(sample_grid(&scene, &scene.bbox(), [cx, cy, cz.min(8)]), &["dims"])?;
    }

    #[test]
    fn recipes(scale in num(1.0), sea in proptest::option::of(num(5.0)), budget in 0usize..300,
               mv in unit(), mlen in prop_oneof![Just(14usize * 12), 0usize..200],
               feats in proptest::sample::subsequence(Feature::ALL.to_vec(), 0..=10),
               seed in any::<u64>()) {
        let recipe = Recipe { features: feats, sea_level: sea, mask: Some(vec![mv; mlen]),
                              scale, karst_budget: Some(budget), seed, ..Default::default() };
        let mut f = WEATHERING.to_vec();
        f.extend(["scale", "sea_level", "region", "cave_length", "height", "radius", "span",
                  "thickness", "altitude", "step", "poisson_radius", "retreat", "depth",
                  "min_radius", "cliff_spacing", "voxel", "period"]);
        check(build_recipe(&dem(), &recipe), &f)?;
    }
}

#[test]
fn voids_and_tiny_dems_are_errors() {
    let mut hf = dem();
    hf.set(3, 3, f32::NAN);
    let e = build_recipe(&hf, &Recipe::default()).unwrap_err();
    assert!(e.to_string().contains("void"), "{e}");
    let tiny = Heightfield::from_fn(2, 2, 1.0, 1.0, |_, _| 0.0);
    let e = build_recipe(&tiny, &Recipe::default()).unwrap_err();
    assert!(e.to_string().contains("heightfield size"), "{e}");
}
