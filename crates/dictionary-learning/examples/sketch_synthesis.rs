//! Sketch synthesis (guerin2016 figure 12) on a real exemplar, release build:
//!
//! `cargo run --release -p relief-dictionary-learning --example sketch_synthesis [OUT_DIR] [--paper]`
//!
//! A 64 x 128 painted sketch (ridge strokes, a peak, a valley, flat plateaus) is synthesised in
//! three x4 steps to 4096 x 8192 with alps_dem as exemplar. Prints the time and measures of the
//! result (fine-scale relief on the sketch's plateaus relative to the exemplar's, slope-histogram
//! distance to the exemplar), and writes hillshades (PGM) of the whole result (box-reduced x4)
//! and of a 1024 x 1024 centre crop into OUT_DIR (default `target/sketch_synthesis`).
#![allow(clippy::print_stdout)]

use relief_dictionary_learning::*;
use relief_heightfield::{Heightfield, NoProgress};
use relief_sparse_core::RasterSettings;
use relief_testdata::{dem_crop, timed, write_shade};

/// A painted sketch in `[0, 1]` of `w x h` cells.
fn sketch(w: usize, h: usize) -> Heightfield {
    Heightfield::from_fn(w, h, 1.0, 1.0, |x, y| {
        let (u, v) = ((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
        let stroke = |d: f32, s: f32| (-(d * d) / (s * s)).exp();
        let ridge = stroke((u - 0.3) - 0.5 * (v - 0.2), 0.1) * (v < 0.75) as u8 as f32;
        let peak = stroke(((u - 0.7).powi(2) + (v - 0.25).powi(2)).sqrt(), 0.12);
        let valley = stroke((v - 0.85) + 0.3 * (u - 0.5), 0.05);
        (0.3 + 0.5 * ridge + 0.6 * peak - 0.25 * valley).clamp(0.0, 1.0)
    })
}

fn main() {
    let out_dir = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with("--"))
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| relief_testdata::workspace_root().join("target/sketch_synthesis"));
    std::fs::create_dir_all(&out_dir).unwrap();
    let Some(exemplar) = dem_crop("alps_dem", 1300, 100, 1024, 640) else {
        println!("alps_dem absent");
        return;
    };
    let sk = sketch(64, 128);
    // `--paper`: the paper's coded detail amplitude (the smooth blob this example documents).
    let paper = std::env::args().any(|a| a == "--paper");
    let lib = SynthesisSettings::default();
    let settings = SynthesisSettings {
        amplify: AmplifySettings {
            exemplar_detail: !paper,
            normalize_detail: !paper,
            ..lib.amplify
        },
        ..lib
    };
    let (sct, model) = timed(|| synthesize(&sk, &exemplar, &settings, &NoProgress).unwrap());
    let (out, raster) = timed(|| sct.rasterize(&RasterSettings::default()).unwrap());
    println!(
        "sketch {}x{} -> {}x{}: model {model:.2} s, rasterise {raster:.2} s",
        sk.width(),
        sk.height(),
        out.width(),
        out.height()
    );
    // The exemplar's detail at the same cell size, for scale.
    let ex_detail = relief_testdata::detail_rms(&exemplar, 16);
    // A plateau of the sketch (top-left corner, away from strokes), in output cells.
    let plateau = out.crop(0, 6000, 1024, 1024).unwrap();
    println!(
        "x16 detail RMS: plateau {:.1} m, whole {:.1} m, exemplar {:.1} m; slope EMD to the \
         exemplar {:.2} deg",
        relief_testdata::detail_rms(&plateau, 16),
        relief_testdata::detail_rms(&out, 16),
        ex_detail,
        relief_heightfield::metrics::slope_histogram_distance(&out, &exemplar)
    );
    for k in [4, 16, 64] {
        println!(
            "  detail finer than {k} cells: output {:.1} m, exemplar {:.1} m",
            relief_testdata::detail_rms(&out, k),
            relief_testdata::detail_rms(&exemplar, k)
        );
    }
    write_shade(&out_dir.join("whole.pgm"), &out.downsample_box(4).unwrap());
    write_shade(
        &out_dir.join("crop.pgm"),
        &out.crop(1536, 3584, 1024, 1024).unwrap(),
    );
    write_shade(&out_dir.join("exemplar.pgm"), &exemplar);
    println!("hillshades in {}", out_dir.display());
}
