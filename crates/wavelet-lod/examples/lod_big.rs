//! Release harness of the big level-of-detail run: a 4096^2 terrain refined by two levels to
//! 16384^2 with LSA 3x3 (CDF 5/3).
//!
//! ```text
//! RAYON_NUM_THREADS=2 /usr/bin/time -v cargo run --release -p relief-wavelet-lod --example lod_big
//! ```
//! The input is the real `alps_dem` enlarged to 4096^2 plus a fractal perturbation (the harness
//! needs the shared DEM set); prints the analysis and synthesis times, the checksum of the output
//! and the fitted statistics. Peak memory is what `/usr/bin/time -v` reports as "Maximum
//! resident set size".
#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_heightfield::NoProgress;
use relief_wavelet_lod::{Method, RefineSettings, Refiner, Wavelet};

fn main() {
    let size: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(4096);
    let alps = relief_testdata::load_dem("alps_dem").expect("shared DEM set (alps_dem)");
    let t = Instant::now();
    let input = alps.resample(size, size).expect("resample");
    println!(
        "input {size}^2 prepared in {:.2} s (not part of the timing)",
        t.elapsed().as_secs_f64()
    );
    let settings = RefineSettings {
        wavelet: Wavelet::Cdf53,
        method: Method::Lsa,
        window: 3,
        extra_levels: 2,
        seed: 42,
        ..Default::default()
    };
    let t0 = Instant::now();
    let refiner = Refiner::new(&input, &settings).expect("analysis");
    let t1 = Instant::now();
    let out = refiner.render(&NoProgress).expect("render");
    let t2 = Instant::now();
    let sum: f64 = out.as_slice().iter().map(|&v| v as f64).sum();
    println!(
        "LOD {size}^2 -> {}x{} LSA 3x3 cdf53, {} threads: analysis {:.3} s, synthesis {:.3} s, total {:.3} s",
        out.width(),
        out.height(),
        rayon::current_num_threads(),
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64(),
        (t2 - t0).as_secs_f64()
    );
    println!("mean elevation {:.3} m", sum / out.len() as f64);
    for (b, f) in ["h", "v", "d"].iter().zip(&refiner.analysis().fits) {
        println!(
            "band {b}: gamma {:.3}, a {:.3}, D {:.3}",
            f.gamma,
            f.a,
            f.fractal_dimension()
        );
    }
}
