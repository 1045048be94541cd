//! Sketch synthesis (guerin2016 figure 12) on a real exemplar, release build:
//!
//! `cargo run --release -p relief-dictionary-learning --features examples --example sketch_synthesis [OUT_DIR]
//! [--grandcanyon] [--steps N] [--sketch-cell M]`
//!
//! A 64 x 128 painted sketch (ridge strokes, a peak, a valley, flat plateaus) is synthesised in
//! `N` x4 steps (default 3: 4096 x 8192) with an alps_dem crop (or the grandcanyon fixture) as
//! exemplar, four ways: the paper's method (`--paper`), the exemplar detail without the
//! structure step (`--structure-radius 0 --landform off`), with it (`--landform off`), and the
//! default (landscape evolution from the sketch, `relief_landscape::grow`). Prints, per way, the time, the
//! slope-histogram distance to the exemplar (EMD, degrees; the output has the exemplar's cell
//! size unless `--sketch-cell` sets the sketch's) and the correlation of the output reduced to
//! the sketch's size with the sketch; writes hillshades (PGM) of the default result (box-reduced
//! to 1024 rows) and of a 1024 x 1024 centre crop into OUT_DIR (default
//! `target/sketch_synthesis`).
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
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .map(|v| v.parse::<f64>().expect("a number"))
    };
    let out_dir = args
        .iter()
        .enumerate()
        .find(|(i, a)| !a.starts_with("--") && (*i == 0 || !args[i - 1].starts_with("--")))
        .map(|(_, a)| std::path::PathBuf::from(a))
        .unwrap_or_else(|| relief_testdata::workspace_root().join("target/sketch_synthesis"));
    std::fs::create_dir_all(&out_dir).unwrap();
    let exemplar = if args.iter().any(|a| a == "--grandcanyon") {
        relief_io::read(
            &relief_testdata::fixture("grandcanyon.tif"),
            &relief_io::ReadOptions::default(),
        )
        .expect("fixture")
        .heightfield
    } else {
        let Some(e) = dem_crop("alps_dem", 1300, 100, 1024, 640) else {
            println!("alps_dem absent");
            return;
        };
        e
    };
    let steps = value("--steps").map_or(3, |v| v as usize);
    let sketch_cell_size = value("--sketch-cell").map(|c| (c, c));
    let sk = sketch(64, 128);
    let lib = SynthesisSettings::default();
    let base = SynthesisSettings {
        amplify: AmplifySettings {
            steps,
            ..lib.amplify
        },
        sketch_cell_size,
        ..lib
    };
    let off = StructureSettings {
        radius: 0.0,
        ..Default::default()
    };
    let ways = [
        (
            "paper",
            SynthesisSettings {
                amplify: AmplifySettings {
                    exemplar_detail: false,
                    normalize_detail: false,
                    ..base.amplify
                },
                structure: off,
                grow: None,
                ..base
            },
        ),
        (
            "no structure",
            SynthesisSettings {
                structure: off,
                grow: None,
                ..base
            },
        ),
        (
            "structure (--landform off)",
            SynthesisSettings { grow: None, ..base },
        ),
        ("default (landscape evolution)", base),
    ];
    println!("| way | seconds | slope EMD (deg) | correlation with the sketch |");
    println!("|---|---|---|---|");
    for (name, settings) in ways {
        let ((sct, figures), secs) =
            timed(|| synthesize_with_figures(&sk, &exemplar, &settings, &NoProgress).unwrap());
        let out = sct.rasterize(&RasterSettings::default()).unwrap();
        let back = out.resample(sk.width(), sk.height()).unwrap();
        let r = relief_heightfield::metrics::pearson(back.as_slice(), sk.as_slice());
        let emd = relief_heightfield::metrics::slope_histogram_distance(&out, &exemplar);
        println!("| {name} | {secs:.2} | {emd:.2} | {r:.3} |");
        if name == "default" {
            if let Some(st) = &figures.structure {
                println!("{}", st.note);
            }
            let k = (out.height() / 1024).max(1);
            write_shade(&out_dir.join("whole.pgm"), &out.downsample_box(k).unwrap());
            let (cx, cy) = (out.width() / 2, out.height() / 2);
            let side = 1024.min(out.width()).min(out.height());
            write_shade(
                &out_dir.join("crop.pgm"),
                &out.crop(cx - side / 2, cy - side / 2, side, side).unwrap(),
            );
        }
    }
    write_shade(&out_dir.join("exemplar.pgm"), &exemplar);
    println!("hillshades in {}", out_dir.display());
}
