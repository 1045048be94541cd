//! Benchmarks of relief-wavelet-lod: the 2-D lifting DWT (forward + inverse, 6 levels, `f32`)
//! for every basis at 1024^2 and CDF 5/3 at 4096^2 (the speed goal, against PyWavelets
//! `wavedec2` + `waverec2` with `bior2.2`, timed by `xtask/peers/pywt_dwt.py`), and on-demand
//! LSA 3x3 refinement of a 512^2 window by two levels from a 1024^2 terrain (and GSA), whole
//! refinements 1024^2 -> 4096^2 (GSA, LSA 3x3), and the level-of-detail goal 4096^2 -> 16384^2
//! with LSA 3x3 streamed in strips.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use relief_heightfield::{Heightfield, NoProgress};
use relief_wavelet_lod::{
    Boundary, Grid, Method, RefineSettings, Refiner, Wavelet, WaveletError, wavedec2,
    waverec2_owned,
};

/// The random-walk surface of the PyWavelets peer's input.
fn surface(size: usize) -> Grid {
    Grid::new(size, size, relief_benches::dwt_surface(size)).expect("grid")
}

fn dwt(c: &mut Criterion) {
    let mut g = c.benchmark_group("wavelet_lod");
    g.sample_size(10);
    let small = surface(1024);
    for w in Wavelet::ALL {
        g.bench_with_input(
            BenchmarkId::new(format!("dwt_fwd_inv_{w}"), 1024),
            &small,
            |b, x| b.iter(|| waverec2_owned(wavedec2(x, w, 6, Boundary::Symmetric).expect("dwt"))),
        );
    }
    let big = surface(4096);
    g.bench_with_input(BenchmarkId::new("dwt_fwd_inv_cdf53", 4096), &big, |b, x| {
        b.iter(|| waverec2_owned(wavedec2(x, Wavelet::Cdf53, 6, Boundary::Symmetric).expect("dwt")))
    });
    g.finish();
}

/// The `size^2` surface as a 30 m heightfield, and LSA 3x3 refinement by two levels (seed 1).
fn lsa3_x4(size: usize) -> (Heightfield, RefineSettings) {
    let grid = surface(size);
    let hf = Heightfield::new(size, size, grid.data, 30.0, 30.0).expect("heightfield");
    let settings = RefineSettings {
        method: Method::Lsa,
        window: 3,
        extra_levels: 2,
        seed: 1,
        ..Default::default()
    };
    (hf, settings)
}

fn lod(c: &mut Criterion) {
    let (hf, settings) = lsa3_x4(1024);
    let refiner = Refiner::new(&hf, &settings).expect("analysis");
    let mut g = c.benchmark_group("wavelet_lod");
    g.sample_size(10);
    g.bench_function(BenchmarkId::new("lsa3_window_x4", 512), |b| {
        b.iter(|| refiner.render_window(1000, 2000, 512, 512).expect("window"))
    });
    g.bench_function(BenchmarkId::new("lsa3_analysis", 1024), |b| {
        b.iter(|| Refiner::new(&hf, &settings).expect("analysis"))
    });
    let gsa_settings = RefineSettings {
        method: Method::Gsa,
        ..settings.clone()
    };
    let gsa = Refiner::new(&hf, &gsa_settings).expect("analysis");
    g.bench_function(BenchmarkId::new("gsa_window_x4", 512), |b| {
        b.iter(|| gsa.render_window(1000, 2000, 512, 512).expect("window"))
    });
    // Whole refinements (analysis + synthesis of every tile), 1024^2 -> 4096^2.
    for (name, s) in [
        ("refine_lsa3_x4", &settings),
        ("refine_gsa_x4", &gsa_settings),
    ] {
        g.bench_function(BenchmarkId::new(name, 1024), |b| {
            b.iter(|| {
                Refiner::new(&hf, s)
                    .expect("analysis")
                    .render(&NoProgress)
                    .expect("render")
            })
        });
    }
    g.finish();
}

/// The level-of-detail goal: 4096^2 -> 16384^2 with LSA 3x3 (analysis + synthesis),
/// streamed in strips of 256 rows to a sink that folds a checksum (what a streaming writer
/// receives), so the 1 GiB output is never held at once. Run with `RAYON_NUM_THREADS=2` for the
/// goal's 2 threads.
fn lod_big(c: &mut Criterion) {
    let (hf, settings) = lsa3_x4(4096);
    let mut g = c.benchmark_group("wavelet_lod");
    g.sample_size(10);
    g.bench_function(BenchmarkId::new("lod_lsa3_x4_strips", 4096), |b| {
        b.iter(|| {
            let r = Refiner::new(&hf, &settings).expect("analysis");
            let mut sum = 0.0f64;
            r.render_strips::<WaveletError>(256, &NoProgress, |_, rows: &[f32]| {
                sum += rows.iter().map(|&v| v as f64).sum::<f64>();
                Ok(())
            })
            .expect("render");
            sum
        })
    });
    g.finish();
}

criterion_group!(benches, dwt, lod, lod_big);
criterion_main!(benches);
