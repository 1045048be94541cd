//! Release timing harness: a 1024 x 1024 guided synthesis from one 512 x 512 exemplar on 2
//! threads (goal <= 4 s; measured 2026-12-03 on a quiet machine after the box-mean images and
//! the preconditioned blend: 2.13-2.75 s, index 0.76-1.01 s and synthesis 1.35-1.74 s; 3.42 s
//! before them),
//! where texture-synthesis 0.8 takes 148 s for the same output size, `benches/benches/quilt.rs`).
//! The exemplar is the Grand Canyon DEM; the guide is the low-pass (factor 16) of a 512 x 512
//! alps crop enlarged to 1024 x 1024.
//!
//! Also prints the time of every progress phase (descriptors, k-means, pca, kd-trees,
//! synthesis): the profile of the run.
//!
//! `cargo run --release -p relief-patch-synth --features examples --example bench_quilt`
#![allow(clippy::print_stdout)]

use std::sync::Mutex;
use std::time::Instant;

use relief_heightfield::Progress;
use relief_patch_synth::{Control, Exemplar, ExemplarIndex, Settings, guide, synthesize};
use relief_testdata::{dem_crop, load_dem};

/// Prints the time spent in each progress phase.
struct Phases(Instant, Mutex<Option<(String, f64)>>);

impl Progress for Phases {
    fn begin(&self, phase: &str, _total: u64) {
        let now = self.0.elapsed().as_secs_f64();
        let mut last = self.1.lock().unwrap();
        if let Some((name, t)) = last.take() {
            println!("  {name:32} {:.2} s", now - t);
        }
        *last = Some((phase.to_string(), now));
    }
}

fn main() {
    let Some(ex) = load_dem("grandcanyon") else {
        return;
    };
    let src = dem_crop("alps_dem", 900, 200, 512, 512).expect("alps crop");
    // Bring the guide to the exemplar's height range, as a user's sketch would.
    let src = src.map(|v| 479.0 + (v - 640.0) * (2347.0 - 479.0) / (4115.0 - 640.0));
    let g = guide::lowpass_resample(&src.resample(1024, 1024).unwrap(), 16).unwrap();
    let settings = Settings {
        enforce_validation: false,
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    pool.install(|| {
        let t0 = Instant::now();
        let phases = Phases(t0, Mutex::new(None));
        let index =
            ExemplarIndex::build(vec![Exemplar::new(ex, 0)], &settings, &phases).expect("index");
        let t1 = Instant::now();
        let out = synthesize(&index, &Control::guided(g.clone()), &settings, &phases)
            .expect("synthesis");
        phases.begin("end", 0);
        let t2 = Instant::now();
        println!(
            "patch-synth 1024x1024 from 512x512, 2 threads: index {:.2} s + synthesis {:.2} s = {:.2} s total ({} patches, {:.0} candidates/block, PCA explained {:?})",
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            (t2 - t0).as_secs_f64(),
            out.stats.patches,
            out.stats.mean_candidates,
            index.pca_explained()
        );
        let fid = relief_patch_synth::quality::guide_fidelity(&out.heightfield, &g, 16).unwrap();
        let seam = relief_patch_synth::quality::seam_visibility(&out.heightfield, &out.seam_map)
            .unwrap();
        // FNV-1a of the output bytes: a speed change must leave it unchanged.
        let hash = out.heightfield.as_slice().iter().fold(0xcbf2_9ce4_8422_2325u64, |h, v| {
            v.to_le_bytes()
                .iter()
                .fold(h, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
        });
        println!("guide rmse {fid:.1} m, seam ratio {seam:.3}, output hash {hash:016x}");
    });
}
