//! Release timing of the whole `relief volume` job on real crops (tree build, polygonisation at
//! the recipe's voxel, simplification to a triangle budget, render), 2 threads:
//! `cargo run --release -p relief-implicit-volume --features examples --example job_timing -- [DEM X Y W H [MAX_TRIANGLES]]`
//! (default: N57E011 888 72 48 48, then grandcanyon 200 160 128 128, 200000 triangles).
//! `FEATURES=wind,rain` builds only those features (default: all); `LOOK=1` meshes the scene at
//! the recipe's grid and prints its [`relief_implicit_volume::surface_look`] (downward-facing
//! area share, small closed pits of the top surface at the meshing voxel). `OPENINGS=1` prints
//! the carvings' openings through the DEM surface ([`relief_implicit_volume::surface_openings`]:
//! count, elongation).
#![allow(clippy::print_stdout)]

use relief_heightfield::NoProgress;
use relief_implicit_volume::job::VolumeJob;
use relief_implicit_volume::recipe::{Feature, Recipe};

use relief_testdata::cpu_seconds as cpu_s;

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let runs: Vec<(String, [usize; 4], usize)> = if a.len() >= 5 {
        let n = |k: usize| a[k].parse::<usize>().expect("integer");
        vec![(
            a[0].clone(),
            [n(1), n(2), n(3), n(4)],
            a.get(5).map_or(200_000, |_| n(5)),
        )]
    } else {
        vec![
            ("N57E011".into(), [888, 72, 48, 48], 200_000),
            ("grandcanyon".into(), [200, 160, 128, 128], 200_000),
        ]
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    // RENDER=1: write the overview, close-ups and section as PPM to target/bench-data/.
    let images = std::env::var_os("RENDER").is_some();
    for (name, [x, y, w, h], max) in runs {
        let hf = relief_testdata::dem_crop(&name, x, y, w, h).expect("DEM set");
        let job = VolumeJob {
            recipe: Recipe {
                features: match std::env::var("FEATURES") {
                    Ok(v) => v
                        .split(',')
                        .filter(|f| !f.trim().is_empty())
                        .map(|f| f.trim().parse::<Feature>().expect("feature"))
                        .collect(),
                    Err(_) => Feature::ALL.to_vec(),
                },
                seed: 1,
                ..Default::default()
            },
            max_triangles: Some(max),
            render: images,
            closeups: images,
            section: images,
            image_size: [960, 640],
            ..Default::default()
        };
        let out = pool.install(|| {
            let built = job.build(&hf, &NoProgress).expect("build");
            job.finish(built, &NoProgress).expect("finish")
        });
        let f = &out.figures;
        if images {
            let dir = relief_testdata::workspace_root().join("target/bench-data");
            std::fs::create_dir_all(&dir).expect("dir");
            for (kind, img) in [
                ("render", &out.render),
                ("closeups", &out.closeups),
                ("section", &out.section),
            ] {
                if let Some(img) = img {
                    let path = dir.join(format!("{name}_{kind}.ppm"));
                    let mut bytes = format!("P6\n{} {}\n255\n", img.width, img.height).into_bytes();
                    bytes.extend_from_slice(&img.rgb);
                    std::fs::write(&path, bytes).expect("write");
                    println!("wrote {}", path.display());
                }
            }
            println!(
                "  closeups {:?}, render {:.2} s, closeups {:.2} s",
                f.closeups,
                f.render_s.unwrap_or(0.0),
                f.closeups_s.unwrap_or(0.0)
            );
            for h in &out.report.highlights {
                println!("  highlight {h:?}");
            }
            println!("  effects {:?}", f.effects.keys().collect::<Vec<_>>());
        }
        println!(
            "{name} {x} {y} {w}x{h}: nodes {}, build {:.3} s, grid {:?}, mesh {:.3} s ({} triangles), simplify to {} in {:.3} s (refused {}), watertight {:?}",
            f.tree_nodes,
            f.build_s,
            f.mesh_grid,
            f.mesh_s.unwrap_or(0.0),
            f.mesh_triangles_polygonised.unwrap_or(0),
            f.mesh_triangles.unwrap_or(0),
            f.simplify_s.unwrap_or(0.0),
            f.simplify_refused.unwrap_or(0),
            f.mesh_watertight_manifold,
        );
        println!("  nodes by kind {:?}", f.tree_nodes_by_kind);
        for (feat, e) in &out.report.effects {
            if *feat == Feature::Islands {
                let mut r = e.sizes_m.clone();
                r.sort_by(f32::total_cmp);
                // Clark-Evans ratio (1 random, < 1 clustered, > 1 regular).
                let area = 1e6 * out.report.dims.area_km2 as f64;
                let ce =
                    relief_implicit_volume::scene::clark_evans(&e.sites, area).unwrap_or(f32::NAN);
                println!(
                    "  islands: radii {:?} m, nearest-neighbour spacing cv {:?}, clark-evans {ce:.2}, tops {:?}",
                    r.iter().map(|x| x.round()).collect::<Vec<_>>(),
                    relief_implicit_volume::scene::nearest_neighbour_cv(&e.sites),
                    e.sites
                        .iter()
                        .map(|p| p.map(f32::round))
                        .collect::<Vec<_>>()
                );
            }
        }
        println!(
            "  sea level {:?} m, water drawn {}, effects (primitives, count) {:?}",
            f.sea_level_m,
            f.water_drawn,
            f.effects
                .iter()
                .map(|(k, e)| (k.as_str(), e.primitives, e.count))
                .collect::<Vec<_>>()
        );
        for n in &f.notes {
            println!("  note: {n}");
        }
        if std::env::var_os("OPENINGS").is_some() {
            // Carvings through the surface: samples a quarter voxel apart, a quarter voxel under
            // it; openings of at least 8 samples.
            let v = out.report.dims.voxel_m;
            let t = std::time::Instant::now();
            let o = pool
                .install(|| {
                    relief_implicit_volume::surface_openings(&out.scene, 0.25 * v, 0.25 * v, 8)
                })
                .expect("dem");
            let round = o.aspects.iter().filter(|&&a| a < 1.5).count();
            println!(
                "  openings: {} (round, aspect < 1.5: {round}), median aspect {:?}, median samples {:?} ({:.1} s)",
                o.count,
                o.median_aspect(),
                {
                    let mut s = o.samples.clone();
                    s.sort();
                    s.get(s.len() / 2).copied()
                },
                t.elapsed().as_secs_f64()
            );
        }
        if std::env::var_os("LOOK").is_some() {
            let grid = f.mesh_grid.expect("grid");
            let ms = relief_implicit_volume::MeshSettings {
                cells: grid,
                normals: false,
                ..Default::default()
            };
            let (m, _) =
                pool.install(|| relief_implicit_volume::polygonize(&out.scene, &ms).expect("mesh"));
            let v = out.report.dims.voxel_m;
            let r = out.report.dims.weathering_radius_m;
            // Small pits: closed depressions deeper than a quarter voxel and no wider than about
            // two weathering spheres.
            let max_cells = (std::f32::consts::PI * (2.0 * r / v).powi(2)).ceil() as usize;
            let look = relief_implicit_volume::surface_look(&m, v, 0.25 * v, max_cells);
            println!(
                "  look (voxel {v:.2} m, weathering radius {r:.2} m, small = at most {max_cells} cells): {look:?}"
            );
        }
        if std::env::var_os("MESH_ONLY").is_some() {
            let scene = &out.scene;
            let ms = relief_implicit_volume::MeshSettings {
                cells: f.mesh_grid.expect("grid"),
                normals: false,
                ..Default::default()
            };
            for _ in 0..3 {
                let t = std::time::Instant::now();
                let c = cpu_s();
                let (m, r) =
                    pool.install(|| relief_implicit_volume::polygonize(scene, &ms).expect("mesh"));
                println!(
                    "  polygonize {:.3} s (cpu {:.2} s), {} triangles, {:?}",
                    t.elapsed().as_secs_f64(),
                    cpu_s() - c,
                    m.triangles.len(),
                    r
                );
                if std::env::var_os("NO_SIMPLIFY").is_some() {
                    continue;
                }
                let t = std::time::Instant::now();
                let (_, r) =
                    pool.install(|| relief_implicit_volume::simplify(&m, max).expect("simplify"));
                println!(
                    "  simplify to {max}: {:.3} s {r:?}",
                    t.elapsed().as_secs_f64()
                );
            }
        }
    }
}
