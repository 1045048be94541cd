//! Benchmarks of relief-heightfield kernels on the bundled fixture DEM and the N47E011 SRTM tile:
//! resampling (low-pass down, bicubic up) and harmonic void filling. Rows of the dashboard in
//! `xtask/src/bench/items.rs` refer to these ids (`heightfield/<function>/<parameter>`).

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use relief_heightfield::fill::{FillSettings, fill_voids};

fn resample(c: &mut Criterion) {
    let dem = relief_benches::fixture_dem().expect("fixtures/grandcanyon.tif");
    let small = dem.resample(128, 128).expect("resample");
    let mut g = c.benchmark_group("heightfield");
    g.sample_size(20);
    g.bench_with_input(BenchmarkId::new("resample_down", 512), &dem, |b, hf| {
        b.iter(|| hf.resample(128, 128).expect("resample"))
    });
    g.bench_with_input(BenchmarkId::new("resample_up", 128), &small, |b, hf| {
        b.iter(|| hf.resample(512, 512).expect("resample"))
    });
    g.finish();
}

fn fill(c: &mut Criterion) {
    let dem = relief_benches::fixture_dem().expect("fixtures/grandcanyon.tif");
    let holed = relief_benches::with_holes(&dem);
    let settings = FillSettings::default();
    let mut g = c.benchmark_group("heightfield");
    g.sample_size(10);
    g.bench_with_input(BenchmarkId::new("fill_voids", 512), &holed, |b, hf| {
        b.iter(|| {
            let mut x = hf.clone();
            fill_voids(&mut x, &settings).expect("fill")
        })
    });
    if let Some(srtm) = relief_testdata::load_dem("N47E011") {
        g.bench_with_input(BenchmarkId::new("fill_voids_srtm", 1201), &srtm, |b, hf| {
            b.iter(|| {
                let mut x = hf.clone();
                fill_voids(&mut x, &settings).expect("fill")
            })
        });
    }
    g.finish();
}

criterion_group!(benches, resample, fill);
criterion_main!(benches);
