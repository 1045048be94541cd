//! Quality table of amplification on real data (release example):
//! `cargo run --release -p relief-dictionary-learning --features examples --example quality_table`
#![allow(clippy::print_stdout)]

use relief_dictionary_learning::*;
use relief_heightfield::fill::{FillSettings, fill_voids};
use relief_heightfield::{Heightfield, NoProgress};
use relief_sparse_core::RasterSettings;
use relief_testdata::dem_crop;

fn table(label: &str, truth: &Heightfield, exemplar: &Heightfield, steps: usize) {
    let f = 4usize.pow(steps as u32);
    let coarse = truth
        .resample(truth.width() / f, truth.height() / f)
        .unwrap();
    println!(
        "\n{label}: truth {}x{}, input {}x{} (x{f})",
        truth.width(),
        truth.height(),
        coarse.width(),
        coarse.height()
    );
    println!(
        "{:28} {:>12} {:>12} {:>12} {:>10} {:>10}",
        "method", "consistency", "added slope", "truth slope", "slope EMD", "rmse/rel"
    );
    let print = |name: &str, out: &Heightfield| {
        let r = evaluate(truth, &coarse, out).unwrap();
        println!(
            "{name:28} {:>12.5} {:>12.2} {:>12.2} {:>10.2} {:>10.4}",
            r.consistency, r.added_slope, r.truth_slope, r.slope_hist_distance, r.truth_rmse
        );
    };
    let learned = DictionaryChoice::learned(256, 3);
    for (name, dict, s, rc) in [
        ("sparse learned N=256 s=1", learned, 1, false),
        ("sparse learned N=256 s=4", learned, 4, false),
        ("sparse complete s=1", DictionaryChoice::Complete, 1, false),
        ("sparse N=256 s=1 + residual", learned, 1, true),
    ] {
        let st = AmplifySettings {
            residual_correction: rc,
            steps,
            dictionary: dict,
            sparsity: s,
            max_candidates: 8192,
            max_learning_pool: 8192,
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let sct = amplify(&coarse, exemplar, &st, &NoProgress).unwrap();
        let out = sct.rasterize(&RasterSettings::default()).unwrap();
        let name = format!("{name} ({:.1}s)", t.elapsed().as_secs_f64());
        print(&name, &out);
    }
    print(
        "bicubic",
        &coarse.resample(truth.width(), truth.height()).unwrap(),
    );
    print(
        "noise baseline (fig. 15)",
        &noise_amplify(
            &coarse,
            &NoiseBaselineSettings {
                factor: f,
                ..Default::default()
            },
        )
        .unwrap(),
    );
}

fn main() {
    let Some(truth) = dem_crop("alps_dem", 100, 200, 512, 512) else {
        println!("alps_dem absent");
        return;
    };
    let ex = dem_crop("alps_dem", 1300, 100, 1024, 640).unwrap();
    table("alps_dem x4", &truth, &ex, 1);
    table("alps_dem x16", &truth, &ex, 2);
    if let (Some(mut t), Some(mut e)) = (
        dem_crop("N47E011", 300, 500, 512, 512),
        dem_crop("N47E011", 650, 80, 512, 512),
    ) {
        fill_voids(&mut t, &FillSettings::default()).unwrap();
        fill_voids(&mut e, &FillSettings::default()).unwrap();
        table("N47E011 x4", &t, &e, 1);
        table("N47E011 x16", &t, &e, 2);
    }
}
