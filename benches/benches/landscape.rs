//! Benchmarks of relief-landscape against the peers of `cargo xtask bench`
//! (`xtask/peers/drainage.py`: RichDEM and pysheds; `xtask/peers/stream_power.py`:
//! fastscapelib), on the same data (`relief_benches::flow_surface`, `spl_surface`).

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use relief_landscape::erode::hydraulic::{HydraulicParams, hydraulic};
use relief_landscape::erode::{StreamPowerParams, StreamPowerScratch, Uplift, base_level_mask};
use relief_landscape::flow::{Depressions, RouteOptions, route};
use relief_landscape::grid::Grid;

fn fill_d8(c: &mut Criterion) {
    let dem = relief_benches::flow_surface().expect("fixtures/grandcanyon.tif");
    let grid = Grid::of(&dem);
    let mut g = c.benchmark_group("landscape");
    g.sample_size(10);
    for (name, depressions) in [
        ("fill_d8", Depressions::Fill),
        ("fill_eps_d8", Depressions::Epsilon),
    ] {
        let opts = RouteOptions {
            depressions,
            ..Default::default()
        };
        g.bench_with_input(BenchmarkId::new(name, 4096), &dem, |b, hf| {
            b.iter(|| {
                let r = route(hf.as_slice().to_vec(), grid, &opts);
                r.accumulation(None)
            })
        });
    }
    // The tiled run of `relief tile plan -- flow` (issue 46) in one process: the five passes
    // of `flow::tiled` over 64 tiles of 512^2, tasks one after another (the plan's per-task
    // file reading and writing excluded), against the single run's same products (route,
    // then cells upstream: what `relief flow` writes as filled, direction and area).
    let layout = relief_landscape::flow::tiled::TileLayout {
        width: dem.width(),
        height: dem.height(),
        tile: 512,
        cell_x: grid.cell_x,
        cell_y: grid.cell_y,
    };
    g.bench_with_input(
        BenchmarkId::new("single_fill_d8_cells", 4096),
        &dem,
        |b, hf| {
            b.iter(|| {
                let r = route(hf.as_slice().to_vec(), grid, &RouteOptions::default());
                r.cells_upstream()
            })
        },
    );
    g.bench_with_input(
        BenchmarkId::new("tiled_fill_d8_cells", 4096),
        &dem,
        |b, hf| {
            b.iter(|| {
                relief_landscape::flow::tiled::run_in_memory(&layout, hf.as_slice(), &mut |_, n| {
                    (0..n).collect()
                })
                .expect("a valid layout")
            })
        },
    );
    // Every product of `relief flow` (issue 46): the seven passes (the five above, the
    // summaries, phase 6, phase 7 of every tile and the network's assembly) against
    // `FlowSettings::run` (filled, directions, area, Strahler, watersheds, HAND, network).
    let settings = relief_landscape::flow::job::FlowSettings::default();
    g.bench_with_input(BenchmarkId::new("single_flow_all", 4096), &dem, |b, hf| {
        b.iter(|| {
            settings
                .run(hf, &relief_heightfield::NoProgress)
                .expect("a DEM")
        })
    });
    g.bench_with_input(BenchmarkId::new("tiled_flow_all", 4096), &dem, |b, hf| {
        b.iter(|| tiled_all(&layout, hf, settings.channel_area))
    });
    g.finish();
}

/// The seven passes of the tiled drainage in one process, tiles one after another.
fn tiled_all(
    layout: &relief_landscape::flow::tiled::TileLayout,
    hf: &relief_heightfield::Heightfield,
    channel_area: f64,
) -> usize {
    use relief_landscape::flow::tiled;
    let all = tiled::run_in_memory(layout, hf.as_slice(), &mut |_, n| (0..n).collect())
        .expect("a valid layout");
    let cut = |t: usize| all.tile(layout, t);
    let n = layout.tasks();
    let sums: Vec<_> = (0..n)
        .map(|t| tiled::summarize(layout, t, &cut(t), channel_area).expect("a tile"))
        .collect();
    let levels = tiled::phase6(layout, &sums).expect("the summaries");
    let nets: Vec<_> = (0..n)
        .map(|t| {
            let input = tiled::halo_window(layout, t, hf.as_slice()).expect("a tile");
            let (r, net) = tiled::phase7(layout, t, &cut(t), &levels[t], &input, channel_area)
                .expect("a tile");
            std::hint::black_box(r);
            net
        })
        .collect();
    let (network, figures) = tiled::assemble(layout, hf.georef(), &nets).expect("the networks");
    std::hint::black_box(network);
    figures.reaches
}

fn stream_power(c: &mut Criterion) {
    let hf = relief_benches::spl_surface();
    let grid = Grid::of(&hf);
    let z0: Vec<f64> = hf.as_slice().iter().map(|&v| v as f64).collect();
    let base = base_level_mask(&z0, &grid);
    // The peer's parameters (fastscapelib's Mountain example, uplift 1 mm/yr).
    let params = StreamPowerParams::fastscape_mountain();
    let mut g = c.benchmark_group("landscape");
    g.sample_size(20);
    let mut z = z0.clone();
    let mut scratch = StreamPowerScratch::new();
    g.bench_function(BenchmarkId::new("stream_power_step", 1024), |b| {
        b.iter(|| {
            scratch
                .step(&mut z, &grid, &base, &params, Uplift::Constant(1e-3))
                .expect("step")
        })
    });
    g.finish();
}

fn hydraulic_default(c: &mut Criterion) {
    let dem = relief_benches::flow_surface().expect("fixtures/grandcanyon.tif");
    let dem = dem.crop(0, 0, 2048, 2048).expect("crop");
    let grid = Grid::of(&dem);
    let p = HydraulicParams::default();
    let mut g = c.benchmark_group("landscape");
    g.sample_size(10);
    g.bench_with_input(BenchmarkId::new("hydraulic", 2048), &dem, |b, hf| {
        b.iter(|| {
            let mut z = hf.as_slice().to_vec();
            hydraulic(&mut z, &grid, &p, &relief_heightfield::NoProgress, &|| {
                false
            })
            .expect("run")
        })
    });
    g.finish();
}

criterion_group!(benches, fill_d8, stream_power, hydraulic_default);
criterion_main!(benches);
