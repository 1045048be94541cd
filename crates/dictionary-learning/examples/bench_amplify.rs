//! Amplification and sketch-synthesis timing (release harness):
//! `RAYON_NUM_THREADS=2 cargo run --release -p relief-dictionary-learning --example bench_amplify`
//!
//! * x256 amplification 32^2 -> 8192^2 (4 x4 steps), learned N = 256, everything included
//!   (exemplar reductions, constrained learning at every step, coding, intermediate rasters and
//!   the final 8192^2 raster). Goal <= 10 s.
//! * Sketch synthesis 64x128 -> 4096x8192 (3 x4 steps, figure 12), learned N = 64. Goal <= 3 s.
#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_dictionary_learning::{
    AmplifySettings, DictionaryChoice, SynthesisSettings, amplify, synthesize,
};
use relief_heightfield::{Heightfield, NoProgress};
use relief_sparse_core::RasterSettings;

fn main() {
    let (Some(ex), Some(src)) = (
        relief_testdata::dem_crop("alps_dem", 1340, 0, 1024, 756),
        relief_testdata::dem_crop("alps_dem", 100, 150, 512, 512),
    ) else {
        println!("alps_dem absent");
        return;
    };
    println!("threads: {}", rayon::current_num_threads());
    let coarse = src.resample(32, 32).unwrap();
    let compare = std::env::args().any(|a| a == "--compare");
    let base = AmplifySettings {
        steps: 4,
        dictionary: DictionaryChoice::Learned {
            n_atoms: 256,
            iterations: 2,
        },
        ..Default::default()
    };
    let mut modes = vec![("default", base)];
    if compare {
        // The paper's plain method on the paper's grid, and the former default (grid step R).
        let paper = AmplifySettings {
            residual_correction: false,
            normalize_detail: false,
            ..base
        };
        modes.push(("--paper", paper));
        modes.push((
            "--paper --step 4 (former default)",
            AmplifySettings {
                step: Some(4.0),
                ..paper
            },
        ));
    }
    for (name, s) in modes {
        let t = Instant::now();
        let sct = amplify(&coarse, &ex, &s, &NoProgress).unwrap();
        let t_model = t.elapsed().as_secs_f64();
        let out = sct.rasterize(&RasterSettings::default()).unwrap();
        let total = t.elapsed().as_secs_f64();
        println!(
            "x256 amplification 32^2 -> {}x{} [{name}]: model {t_model:.2} s, total with raster \
             {total:.2} s",
            out.width(),
            out.height()
        );
    }
    let sketch = Heightfield::from_fn(128, 64, 1.0, 1.0, |x, y| {
        let (u, v) = (x as f32 / 127.0, y as f32 / 63.0);
        let ridge = 1.0 - ((u - 0.5) * 2.2 + 0.3 * (v * 6.0).sin()).abs();
        ridge.max(0.0) * (0.6 + 0.4 * v)
    });
    let ss = SynthesisSettings {
        amplify: AmplifySettings {
            steps: 3,
            dictionary: DictionaryChoice::Learned {
                n_atoms: 64,
                iterations: 2,
            },
            ..Default::default()
        },
        height_range: Some((800.0, 3800.0)),
    };
    let t = Instant::now();
    let sct = synthesize(&sketch, &ex, &ss, &NoProgress).unwrap();
    let t_model = t.elapsed().as_secs_f64();
    let out = sct.rasterize(&RasterSettings::default()).unwrap();
    let total = t.elapsed().as_secs_f64();
    println!(
        "sketch synthesis 128x64 -> {}x{}: model {t_model:.2} s, total with raster {total:.2} s",
        out.width(),
        out.height()
    );
}
