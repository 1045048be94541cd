//! Close-up render timing on the grand canyon scene with every feature (the 128 x 128 crop of
//! the `implicit_volume` criterion group, lake at the crop's 25th percentile):
//! `cargo run -p relief-implicit-volume --features examples --example closeup_prof -- [WIDTH HEIGHT [THREADS [VIEW]]]`
//! (default 400 x 225, 1 thread, every view). Prints each view's CPU seconds and an FNV hash
//! of its bytes; `PPM=1` writes them to target/bench-data/closeup_<k>.ppm; `NO_SHADOWS=1` and
//! `NO_AO=1` turn the shadow rays and the ambient occlusion off (to see what each costs).
#![allow(clippy::print_stdout)]
use relief_implicit_volume::*;

use relief_testdata::cpu_seconds as cpu_s;

fn main() {
    let a: Vec<usize> = std::env::args()
        .skip(1)
        .map(|v| v.parse().expect("integer"))
        .collect();
    let (w, h) = (
        a.first().copied().unwrap_or(400),
        a.get(1).copied().unwrap_or(225),
    );
    let threads = a.get(2).copied().unwrap_or(1);
    let only = a.get(3).copied();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    let hf = relief_testdata::dem_crop("grandcanyon", 200, 160, 128, 128).expect("DEM set");
    let recipe = Recipe {
        features: Feature::ALL.to_vec(),
        sea_level: relief_heightfield::metrics::quantile(hf.as_slice(), 0.25),
        seed: 1,
        ..Default::default()
    };
    let c0 = cpu_s();
    let (scene, rep) = pool.install(|| build_recipe(&hf, &recipe).expect("recipe"));
    println!(
        "build {:.2} s cpu, {} nodes",
        cpu_s() - c0,
        scene.stats().nodes
    );
    let tile = RenderSettings {
        width: w,
        height: h,
        sea_level: rep.sea_level.filter(|_| rep.has_sea),
        ..Default::default()
    };
    let ppm = std::env::var_os("PPM").is_some();
    let mut total = 0.0;
    for (k, (cam, s, name)) in closeup_views(&scene, &rep, &tile).into_iter().enumerate() {
        if only.is_some_and(|o| o != k) {
            continue;
        }
        let mut s = s;
        s.shadows = std::env::var_os("NO_SHADOWS").is_none();
        s.ambient_occlusion = std::env::var_os("NO_AO").is_none();
        let c0 = cpu_s();
        let t0 = std::time::Instant::now();
        let img = pool.install(|| render(&scene, &cam, &s).expect("render"));
        let (cpu, wall) = (cpu_s() - c0, t0.elapsed().as_secs_f64());
        total += cpu;
        let hash = img.rgb.iter().fold(0xcbf29ce484222325u64, |h, &b| {
            (h ^ b as u64).wrapping_mul(0x100000001b3)
        });
        println!("view {k} {name}: {cpu:.2} s cpu, {wall:.2} s wall, hash {hash:016x}");
        if ppm {
            let dir = relief_testdata::workspace_root().join("target/bench-data");
            std::fs::create_dir_all(&dir).expect("dir");
            let mut bytes = format!("P6\n{} {}\n255\n", img.width, img.height).into_bytes();
            bytes.extend_from_slice(&img.rgb);
            std::fs::write(dir.join(format!("closeup_{k}.ppm")), bytes).expect("write");
        }
    }
    println!("total render {total:.2} s cpu");
}
