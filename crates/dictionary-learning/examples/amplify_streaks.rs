//! Streaks and grid artifacts of an amplification as a user sees them (issue 15), release build:
//!
//! `cargo run --release -p relief-dictionary-learning --features examples --example amplify_streaks -- DEM X Y SIDE EX_X EX_Y EX_W EX_H STEPS [MODE] [OUT_DIR]`
//!
//! e.g. `... -- grandcanyon 0 128 256 256 0 256 512 2` (the pipeline's x16 enlargement: the
//! fixture's left half, the right half as exemplar, every step self-similar) or
//! `... -- alps_dem 300 250 128 1300 100 1024 640 2`. A `SIDE`^2 crop of the DEM at full
//! resolution is amplified `4^STEPS` times with an exemplar crop at the same cell size. For
//! every x4 step it prints the repeat score of the added detail at the fine grid step
//! ([`repeat_score`]: one atom's detail repeated along a row of primitives), the detail swing
//! and the phase swing at 4-64 pixels; it writes hillshades (PGM) of the 512^2 centre crop of
//! the result and of bicubic, of the whole result and of the first step's centre crop into
//! `OUT_DIR` (default `target/amplify_streaks`). `MODE`: `default`, `paper`
//! (`AmplifySettings::paper()`), `best-atom` (the default without
//! `AmplifySettings::diverse_atoms`), `no-residual`, `no-norm`.
#![allow(clippy::print_stdout)]

use relief_dictionary_learning::*;
use relief_heightfield::{Heightfield, NoProgress};
use relief_sparse_core::RasterSettings;
use relief_testdata::{dem_crop, write_shade};

fn centre(hf: &Heightfield, side: usize) -> Heightfield {
    let (w, h) = (side.min(hf.width()), side.min(hf.height()));
    hf.crop((hf.width() - w) / 2, (hf.height() - h) / 2, w, h)
        .unwrap()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 9 {
        println!("usage: DEM X Y SIDE EX_X EX_Y EX_W EX_H STEPS [MODE] [OUT_DIR]");
        return;
    }
    let id = &args[0];
    let n: Vec<usize> = args[1..9].iter().map(|s| s.parse().unwrap()).collect();
    let mode = args.get(9).map_or("default", String::as_str);
    let out_dir = args.get(10).map_or_else(
        || relief_testdata::workspace_root().join("target/amplify_streaks"),
        std::path::PathBuf::from,
    );
    std::fs::create_dir_all(&out_dir).unwrap();
    let (Some(region), Some(ex)) = (
        dem_crop(id, n[0], n[1], n[2], n[2]),
        dem_crop(id, n[3], n[4], n[5], n[6]),
    ) else {
        println!("{id} absent");
        return;
    };
    let base = match mode {
        "paper" => AmplifySettings::paper(),
        "best-atom" => AmplifySettings {
            diverse_atoms: false,
            ..Default::default()
        },
        "no-residual" => AmplifySettings {
            residual_correction: false,
            ..Default::default()
        },
        "no-norm" => AmplifySettings {
            normalize_detail: false,
            ..Default::default()
        },
        _ => AmplifySettings::default(),
    };
    let st = AmplifySettings {
        steps: n[7],
        ..base
    };
    let lag = 4 * st.grid_step() as usize;
    let t = std::time::Instant::now();
    let mut per = Vec::new();
    let sct = amplify_observed(&region, &ex, &st, &NoProgress, &mut |r| {
        let out = r.output.rasterize(&RasterSettings::default()).unwrap();
        let bic = corner_bicubic(r.input, out.width(), out.height()).unwrap();
        if r.step == 0 {
            write_shade(
                &out_dir.join(format!("{id}_{mode}_step1.pgm")),
                &centre(&out, 256),
            );
        }
        let phases = [4, 8, 16, 32, 64].map(|p| phase_swing(&out, &bic, p).unwrap_or(f64::NAN));
        per.push((
            r.step,
            repeat_score(&out, &bic, lag).unwrap(),
            detail_swing(&out, &bic).unwrap(),
            phases,
        ));
    })
    .unwrap();
    let out = sct.rasterize(&RasterSettings::default()).unwrap();
    println!(
        "{id} {mode} x{}: {}^2 -> {}x{} in {:.1} s",
        4usize.pow(st.steps as u32),
        n[2],
        out.width(),
        out.height(),
        t.elapsed().as_secs_f64()
    );
    for (s, rep, sw, p) in per {
        println!(
            "  step {}: repeat score {rep:.3} (lag {lag}), swing {sw:.3}, phase swing at 4/8/16/32/64 px {p:.3?}",
            s + 1
        );
    }
    let bic = region.resample(out.width(), out.height()).unwrap();
    write_shade(
        &out_dir.join(format!("{id}_{mode}_zoom.pgm")),
        &centre(&out, 512),
    );
    write_shade(
        &out_dir.join(format!("{id}_bicubic_zoom.pgm")),
        &centre(&bic, 512),
    );
    let k = (out.width() / 1024).max(1);
    write_shade(
        &out_dir.join(format!("{id}_{mode}_whole.pgm")),
        &out.downsample_box(k).unwrap(),
    );
    println!("hillshades in {}", out_dir.display());
}
