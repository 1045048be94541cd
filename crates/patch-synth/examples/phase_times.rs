//! Phase timing of the 1024 x 1024 benchmark synthesis (see `bench_quilt`): prints the
//! elapsed time at every progress phase.
//!
//! `cargo run --release -p relief-patch-synth --example phase_times`
#![allow(clippy::print_stdout)]

use std::sync::Mutex;
use std::time::Instant;

use relief_heightfield::Progress;
use relief_patch_synth::{Control, Exemplar, ExemplarIndex, Settings, guide, synthesize};
use relief_testdata::{dem_crop, load_dem};

struct Phases(Instant, Mutex<Option<(String, f64)>>);

impl Progress for Phases {
    fn begin(&self, phase: &str, _total: u64) {
        let now = self.0.elapsed().as_secs_f64();
        let mut last = self.1.lock().unwrap();
        if let Some((name, t)) = last.take() {
            println!("{name:40} {:.2} s", now - t);
        }
        *last = Some((phase.to_string(), now));
    }
}

fn main() {
    let Some(ex) = load_dem("grandcanyon") else {
        return;
    };
    let src = dem_crop("alps_dem", 900, 200, 512, 512).expect("alps crop");
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
        let p = Phases(Instant::now(), Mutex::new(None));
        let index = ExemplarIndex::build(vec![Exemplar::new(ex, 0)], &settings, &p).unwrap();
        let _ = synthesize(&index, &Control::guided(g), &settings, &p).unwrap();
        p.begin("end", 0);
    });
}
