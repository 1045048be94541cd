//! Benchmarks of relief-wavelet-lod: the 2-D lifting DWT (forward + inverse, 6 levels, `f32`)
//! for every basis at 1024^2 and CDF 5/3 at 4096^2 (the speed goal, against PyWavelets
//! `wavedec2` + `waverec2` with `bior2.2`, timed by `xtask/peers/pywt_dwt.py`), and on-demand
//! LSA 3x3 refinement of a 512^2 window by two levels from a 1024^2 terrain.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use relief_heightfield::Heightfield;
use relief_wavelet_lod::rng::{fill_normals, row_key};
use relief_wavelet_lod::{
    Boundary, Grid, Method, RefineSettings, Refiner, Wavelet, wavedec2, waverec2,
};

/// A random-walk surface (the same construction as the PyWavelets peer's input).
fn surface(size: usize) -> Grid {
    let mut data = vec![0.0f32; size * size];
    for y in 0..size {
        let row = &mut data[y * size..(y + 1) * size];
        fill_normals(row_key(1, 0, 0, y), 0, row);
        for x in 1..size {
            row[x] += row[x - 1];
        }
    }
    for y in 1..size {
        for x in 0..size {
            data[y * size + x] += data[(y - 1) * size + x];
        }
    }
    Grid::new(size, size, data).expect("grid")
}

fn dwt(c: &mut Criterion) {
    let mut g = c.benchmark_group("wavelet_lod");
    g.sample_size(10);
    let small = surface(1024);
    for w in Wavelet::ALL {
        g.bench_with_input(
            BenchmarkId::new(format!("dwt_fwd_inv_{w}"), 1024),
            &small,
            |b, x| b.iter(|| waverec2(&wavedec2(x, w, 6, Boundary::Symmetric).expect("dwt"))),
        );
    }
    let big = surface(4096);
    g.bench_with_input(BenchmarkId::new("dwt_fwd_inv_cdf53", 4096), &big, |b, x| {
        b.iter(|| waverec2(&wavedec2(x, Wavelet::Cdf53, 6, Boundary::Symmetric).expect("dwt")))
    });
    g.finish();
}

fn lod(c: &mut Criterion) {
    let grid = surface(1024);
    let hf = Heightfield::new(1024, 1024, grid.data, 30.0, 30.0).expect("heightfield");
    let settings = RefineSettings {
        method: Method::Lsa,
        window: 3,
        extra_levels: 2,
        seed: 1,
        ..Default::default()
    };
    let refiner = Refiner::new(&hf, &settings).expect("analysis");
    let mut g = c.benchmark_group("wavelet_lod");
    g.sample_size(10);
    g.bench_function(BenchmarkId::new("lsa3_window_x4", 512), |b| {
        b.iter(|| refiner.render_window(1000, 2000, 512, 512).expect("window"))
    });
    g.bench_function(BenchmarkId::new("lsa3_analysis", 1024), |b| {
        b.iter(|| Refiner::new(&hf, &settings).expect("analysis"))
    });
    g.finish();
}

criterion_group!(benches, dwt, lod);
criterion_main!(benches);
