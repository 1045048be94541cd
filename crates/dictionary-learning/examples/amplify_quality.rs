//! Quality of amplification on real DEMs, the protocol of issue 15 (the measures of
//! `shared/tools/terrain_quality.py`), release build:
//!
//! `cargo run --release -p relief-dictionary-learning --features examples --example amplify_quality`
//!
//! For alps_dem, N47E011 (voids filled) and carrizo: a truth crop, box down-sampled x4 and x16,
//! amplified back with an exemplar from a disjoint part of the same DEM, and compared with the
//! truth: consistency (RMS of box-down(output) - input over relief), spectral-slope error over
//! the added octaves, slope- and Laplacian-histogram distances, detail phase swing. Rows: the
//! default settings, the paper's plain method (`AmplifySettings::paper()`), bicubic and the
//! figure-15 noise baseline. `repeat`: [`repeat_score`] of the detail at the fine grid step
//! (8 px), one atom's detail repeated along rows of primitives (truth: about 0). Then the swing
//! of every step of a x256 run (32^2 -> 8192^2).
//! `--quick` skips the x256 run. With `AMPLIFY_QUALITY_NPY=DIR`, every table's truth and
//! default output are written to `DIR` as `.npy` (`alps_dem_x4_truth.npy`,
//! `alps_dem_x4_default.npy`, ...) for the reference tool:
//! `python ../shared/tools/terrain_quality.py DIR/alps_dem_x4_truth.npy
//! DIR/alps_dem_x4_default.npy 4 CELL`.
#![allow(clippy::print_stdout)]

use relief_dictionary_learning::*;
use relief_heightfield::fill::{FillSettings, fill_voids};
use relief_heightfield::{Heightfield, NoProgress};
use relief_sparse_core::RasterSettings;
use relief_testdata::{dem_crop, timed};

fn hp_swing(o: &Heightfield) -> f64 {
    highpass_swing(o).unwrap()
}

fn row(name: &str, r: &BoxProtocolRow, (p8, rep, hp): (f64, f64, f64), secs: Option<f64>) {
    println!(
        "| {name:24} | {:>7.3} | {:>+6.2} | {:>6.2} | {:>6.3} | {:>5.2} | {p8:>5.2} | {hp:>5.2} | {rep:>+6.3} | {} |",
        100.0 * r.consistency,
        r.slope_signed,
        r.slope_emd,
        r.curvature_emd,
        r.swing,
        secs.map_or("-".to_string(), |s| format!("{s:.1}"))
    );
}

/// The settings compared: the default, the paper's method, and the default without each of
/// its detail normalisation and diverse atom choice (the x256 run leaves the last out).
fn variants() -> [(&'static str, AmplifySettings); 4] {
    [
        ("default", AmplifySettings::default()),
        ("--paper", AmplifySettings::paper()),
        (
            "default w/o detail norm.",
            AmplifySettings {
                normalize_detail: false,
                ..AmplifySettings::default()
            },
        ),
        (
            "default, best atom only",
            AmplifySettings {
                diverse_atoms: false,
                ..AmplifySettings::default()
            },
        ),
    ]
}

fn table(label: &str, truth: &Heightfield, exemplar: &Heightfield, steps: usize) {
    let f = 4usize.pow(steps as u32);
    let input = truth.downsample_box(f).unwrap();
    let bicubic = input.resample(truth.width(), truth.height()).unwrap();
    let corner = corner_bicubic(&input, truth.width(), truth.height()).unwrap();
    println!(
        "\n{label} x{f}: truth {}x{}, input {}x{}, exemplar {}x{}; truth swing {:.2}, swing8 {:.2}, hp swing {:.2}, repeat {:+.3}",
        truth.width(),
        truth.height(),
        input.width(),
        input.height(),
        exemplar.width(),
        exemplar.height(),
        detail_swing(truth, &corner).unwrap(),
        phase_swing(truth, &corner, 8).unwrap(),
        hp_swing(truth),
        repeat_score(truth, &corner, 8).unwrap()
    );
    for step in exemplar_plan(
        input.cell_size(),
        (exemplar.width(), exemplar.height()),
        exemplar.cell_size(),
        &AmplifySettings {
            steps,
            ..AmplifySettings::default()
        },
    ) {
        println!("  {}", step.note);
    }
    // Phase swing at 8 px and repeat score at the default fine grid step (4 S = 8 px).
    let p8 = |o: &Heightfield| {
        (
            phase_swing(o, &corner, 8).unwrap(),
            repeat_score(o, &corner, 8).unwrap(),
            hp_swing(o),
        )
    };
    println!(
        "| method                   | consist % | dslope (signed) | slopeEMD | curvEMD | swing | swing8 | hp swing | repeat | s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (name, base) in variants() {
        let st = AmplifySettings { steps, ..base };
        let (out, secs) = timed(|| {
            amplify(&input, exemplar, &st, &NoProgress)
                .unwrap()
                .rasterize(&RasterSettings::default())
                .unwrap()
        });
        if name == "default" {
            dump(label, f, &[("truth", truth), ("default", &out)]);
        }
        row(
            name,
            &box_protocol(truth, &input, &out, f).unwrap(),
            p8(&out),
            Some(secs),
        );
    }
    row(
        "bicubic",
        &box_protocol(truth, &input, &bicubic, f).unwrap(),
        p8(&bicubic),
        None,
    );
    let noise = noise_amplify(
        &input,
        &NoiseBaselineSettings {
            factor: f,
            ..Default::default()
        },
    )
    .unwrap();
    row(
        "noise baseline (fig. 15)",
        &box_protocol(truth, &input, &noise, f).unwrap(),
        p8(&noise),
        None,
    );
}

/// Writes `rasters` as `DIR/{first word of label}_x{f}_{name}.npy` when
/// `AMPLIFY_QUALITY_NPY=DIR` is set.
fn dump(label: &str, f: usize, rasters: &[(&str, &Heightfield)]) {
    let Some(dir) = std::env::var_os("AMPLIFY_QUALITY_NPY") else {
        return;
    };
    let stem = label.split_whitespace().next().unwrap_or("dem");
    for (name, hf) in rasters {
        let bytes = relief_io::npy_f32(&[hf.height(), hf.width()], hf.as_slice().iter().copied());
        let path = std::path::Path::new(&dir).join(format!("{stem}_x{f}_{name}.npy"));
        std::fs::write(&path, bytes).unwrap();
    }
}

fn filled(id: &str, x: usize, y: usize, w: usize, h: usize) -> Option<Heightfield> {
    let mut t = dem_crop(id, x, y, w, h)?;
    fill_voids(&mut t, &FillSettings::default()).ok()?;
    Some(t)
}

/// Swing of the detail added by every step of a x256 run (each step's output minus the bicubic
/// up-sampling of its input), in a 2048^2 window of the step's output, beside the exemplar's
/// own swing at that size ([`swing_floor`]: no truth exists at the finer steps' cell sizes).
fn x256_steps(truth: &Heightfield, exemplar: &Heightfield, settings: &AmplifySettings) {
    let input = truth.downsample_box(truth.width() / 32).unwrap();
    let st = AmplifySettings {
        steps: 4,
        ..*settings
    };
    let mut swings = Vec::new();
    let (sct, model) = timed(|| {
        amplify_observed(&input, exemplar, &st, &NoProgress, &mut |r| {
            let (w, h) = (r.input.width(), r.input.height());
            let side = (4 * w).min(4 * h).min(2048);
            let win = relief_sparse_core::Window {
                x: 0,
                y: 0,
                width: side,
                height: side,
            };
            let out = r
                .output
                .rasterize(&RasterSettings {
                    scale: 1.0,
                    window: Some(win),
                })
                .unwrap();
            let bic = corner_bicubic(r.input, 4 * w, 4 * h)
                .unwrap()
                .crop(0, 0, side, side)
                .unwrap();
            swings.push((
                r.step,
                4 * w,
                detail_swing(&out, &bic).unwrap(),
                phase_swing(&out, &bic, 8).unwrap(),
                hp_swing(&out),
                swing_floor(exemplar, side, 4).unwrap(),
                r.exemplar.reduction,
                r.exemplar.self_similar,
            ));
        })
        .unwrap()
    });
    let (out, raster) = timed(|| sct.rasterize(&RasterSettings::default()).unwrap());
    println!(
        "x256 {}^2 -> {}^2: model {model:.1} s, rasterise {raster:.1} s",
        input.width(),
        out.width()
    );
    for (step, side, s, s8, hp, floor, red, ss) in swings {
        println!(
            "  step {} (-> {side}^2): swing {s:.3} (exemplar's own at that size {floor:.3}, ratio {:.2}), swing8 {s8:.3}, hp swing {hp:.3}, exemplar reduced x{red:.2}{}",
            step + 1,
            s / floor,
            if ss { " (self-similarity)" } else { "" }
        );
    }
}

fn main() {
    let quick = std::env::args().any(|a| a == "--quick");
    let x256_only = std::env::args().any(|a| a == "--x256");
    let (Some(alps), Some(alps_ex)) = (
        dem_crop("alps_dem", 100, 200, 512, 512),
        dem_crop("alps_dem", 1300, 100, 1024, 640),
    ) else {
        println!("alps_dem absent");
        return;
    };
    // Truth: Inn valley and the mountains south of it; exemplar: the mountains further east.
    let n47 = filled("N47E011", 0, 688, 512, 512).zip(filled("N47E011", 600, 688, 601, 512));
    let carrizo = dem_crop("carrizo", 0, 0, 448, 448).zip(dem_crop("carrizo", 0, 452, 505, 448));
    for steps in [1, 2].into_iter().filter(|_| !x256_only) {
        table("alps_dem", &alps, &alps_ex, steps);
        if let Some((t, e)) = &n47 {
            table("N47E011 (filled)", t, e, steps);
        }
        if let Some((t, e)) = &carrizo {
            table("carrizo", t, e, steps);
        }
    }
    if !quick {
        println!();
        for (name, s) in variants().into_iter().take(3) {
            println!("{name}:");
            x256_steps(&alps, &alps_ex, &s);
        }
    }
}
