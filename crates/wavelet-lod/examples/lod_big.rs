//! Release harness of the big level-of-detail run: a 4096^2 terrain refined by two levels to
//! 16384^2 with LSA 3x3, the default spectral model (CDF 9/7), or the paper's model (CDF 5/3)
//! with `paper`.
//!
//! ```text
//! RAYON_NUM_THREADS=2 /usr/bin/time -v target/release/examples/lod_big [SIZE] [full|strips] [STRIP] [spectral|paper]
//! ```
//! (build it first with `cargo build --release -p relief-wavelet-lod --features examples --example lod_big`).
//! `full` (default) renders the whole refined grid into one buffer with `Refiner::render`;
//! `strips` renders it with `Refiner::render_strips` (STRIP rows at a time, default 256) and
//! hands every strip to a sink that only folds a checksum, i.e. what a streaming writer would
//! receive: memory is the input, its analysis and one strip. The input is the real `alps_dem`
//! enlarged to SIZE^2 (the harness needs the shared DEM set); prints the analysis and synthesis
//! times, the checksum (equal in both modes) and the fitted statistics. Peak memory is what
//! `/usr/bin/time -v` reports as "Maximum resident set size".
//!
//! Measured 2026-12-04 (`strips`, default spectral model, 2 threads): 3.3-3.6 s (analysis
//! 0.9 s), peak 326 MB (goals of issue 16: 4 s, 400 MB); the criterion row
//! `wavelet_lod/lod_lsa3_x4_strips/4096` 3.6 s. Before the analysis freed its coefficients
//! ahead of the input copy and the amplitude maps stopped being cloned: 4.1 s, 434 MB.
#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_heightfield::NoProgress;
use relief_wavelet_lod::{Method, RefineSettings, Refiner, WaveletError};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(4096);
    let mode = args.get(2).map(String::as_str).unwrap_or("full");
    let strip: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(256);
    let alps = relief_testdata::load_dem("alps_dem").expect("shared DEM set (alps_dem)");
    let t = Instant::now();
    let input = alps.resample(size, size).expect("resample");
    drop(alps);
    println!(
        "input {size}^2 prepared in {:.2} s (not part of the timing)",
        t.elapsed().as_secs_f64()
    );
    let paper = args.get(4).map(String::as_str) == Some("paper");
    let base = if paper {
        RefineSettings::paper()
    } else {
        RefineSettings::default()
    };
    let settings = RefineSettings {
        method: Method::Lsa,
        window: 3,
        extra_levels: 2,
        seed: 42,
        ..base
    };
    let t0 = Instant::now();
    let refiner = Refiner::new(&input, &settings).expect("analysis");
    let t1 = Instant::now();
    let (ow, oh) = refiner.output_size();
    // Order-independent checksum: sum of the values in f64 per row, rows in order.
    let mut sum = 0.0f64;
    match mode {
        "full" => {
            let out = refiner.render(&NoProgress).expect("render");
            for row in out.as_slice().chunks(ow) {
                sum += row.iter().map(|&v| v as f64).sum::<f64>();
            }
        }
        "strips" => {
            refiner
                .render_strips::<WaveletError>(strip, &NoProgress, |_, rows: &[f32]| {
                    for row in rows.chunks(ow) {
                        sum += row.iter().map(|&v| v as f64).sum::<f64>();
                    }
                    Ok(())
                })
                .expect("render strips");
        }
        other => panic!("unknown mode {other} (full or strips)"),
    }
    let t2 = Instant::now();
    println!(
        "LOD {size}^2 -> {ow}x{oh} LSA 3x3 {} {}, mode {mode}{}, {} threads: analysis {:.3} s, \
         synthesis {:.3} s, total {:.3} s",
        settings.model.name(),
        settings.basis(),
        if mode == "strips" {
            format!(" ({strip} rows)")
        } else {
            String::new()
        },
        rayon::current_num_threads(),
        (t1 - t0).as_secs_f64(),
        (t2 - t1).as_secs_f64(),
        (t2 - t0).as_secs_f64()
    );
    println!("mean elevation {:.6} m", sum / (ow * oh) as f64);
    for (b, f) in ["h", "v", "d"].iter().zip(&refiner.analysis().fits) {
        println!(
            "band {b}: gamma {:.3}, a {:.3}, D {:.3}",
            f.gamma,
            f.a,
            f.fractal_dimension()
        );
    }
}
