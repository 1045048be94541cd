//! Quality protocol of issue 6: synthesize the low-pass guide of a real DEM (an alps crop) from
//! other exemplars (two other alps crops and the Grand Canyon) and report guide fidelity, seam
//! visibility and slope-histogram distance.
//!
//! `cargo run --release -p relief-patch-synth --features examples --example quality_protocol`
//! (optional environment overrides for experiments: `ALPHA`, `BETA`, `GAMMA`, `LAMBDA`, `KNN`,
//! `PCA_DIMS`).
#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_heightfield::{Heightfield, NoProgress};
use relief_patch_synth::{Control, Exemplar, ExemplarIndex, Settings, guide, quality, synthesize};
use relief_testdata::dem_crop;

fn env(name: &str, default: f32) -> f32 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let Some(a) = dem_crop("alps_dem", 450, 250, 384, 384) else {
        return;
    };
    let b = dem_crop("alps_dem", 1650, 0, 384, 384).unwrap();
    let c = dem_crop("grandcanyon", 0, 0, 512, 512).unwrap();
    let src = dem_crop("alps_dem", 2100, 250, 256, 256).unwrap();
    let factor = 8;
    let g = guide::lowpass_resample(&src, factor).unwrap();
    let d = Settings::default();
    let settings = Settings {
        patch_size: 32,
        overlap: 8,
        alpha: env("ALPHA", d.alpha),
        beta: env("BETA", d.beta),
        gamma: env("GAMMA", d.gamma),
        lambda: env("LAMBDA", d.lambda),
        knn: env("KNN", d.knn as f32) as usize,
        pca_dims: env("PCA_DIMS", d.pca_dims as f32) as usize,
        ..d
    };
    let ex = vec![
        Exemplar::new(a, 0),
        Exemplar::new(b, 0),
        Exemplar::new(c, 1),
    ];
    let refs: Vec<Heightfield> = ex.iter().map(|e| e.heightfield.clone()).collect();
    let t0 = Instant::now();
    let index = ExemplarIndex::build(ex, &settings, &NoProgress).unwrap();
    let report =
        relief_patch_synth::validate(&index, &Control::guided(g.clone()), &settings).unwrap();
    println!(
        "validation: ok = {}, cover = {:?}; {report}",
        report.ok, report.cover
    );
    let control = Control::guided(g.clone());
    let s = Settings {
        enforce_validation: false,
        ..settings.clone()
    };
    let out = synthesize(&index, &control, &s, &NoProgress).unwrap();
    let dt = t0.elapsed().as_secs_f64();
    let r: Vec<&Heightfield> = refs.iter().collect();
    let q = quality::assess(&out.heightfield, &out.seam_map, &g, factor, &r, Some(&src)).unwrap();
    println!(
        "256x256 from alps + grandcanyon exemplars ({dt:.2} s): guide rmse {:.1} m (guide std {:.1} m, ratio {:.3}), seam ratio {:.3}, slope EMD {:.2} deg (source DEM vs exemplars {:.2} deg)",
        q.guide_rmse,
        q.guide_std,
        q.guide_rmse / q.guide_std,
        q.seam_ratio,
        q.slope_distance,
        q.slope_distance_baseline
    );
    println!("stats: {:?}", out.stats);
}
