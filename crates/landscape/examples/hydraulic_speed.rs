//! Times [`hydraulic`] with the default settings on a 2048 x 2048 grid (the grandcanyon DEM of
//! the shared set, found by `relief_testdata::load_dem`, mirrored 4 x 4, 61.7 m cells) on 1 and
//! 2 threads, and checks that both give the same bytes. Without the DEM set it prints a notice
//! and exits.
//!
//! ```text
//! cargo run --release -p relief-landscape --features examples --example hydraulic_speed -- [SIZE] [ITERATIONS] [THREADS]
//! ```
//! With `THREADS`, only that thread count is timed.

#![allow(clippy::print_stdout, clippy::print_stderr)]

use std::time::Instant;

use relief_heightfield::NoProgress;
use relief_landscape::erode::hydraulic::{HydraulicParams, hydraulic};
use relief_landscape::grid::Grid;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let size: usize = args.first().map_or(Ok(2048), |s| s.parse())?;
    let mut p = HydraulicParams::default();
    if let Some(it) = args.get(1) {
        p.iterations = it.parse()?;
    }
    let Some(hf) = relief_testdata::load_dem("grandcanyon") else {
        eprintln!("notice: the grandcanyon DEM is absent; nothing to time");
        return Ok(());
    };
    let (dw, dh) = (hf.width(), hf.height());
    let (cell_x, cell_y) = hf.cell_size();
    let dem = hf.as_slice();
    // Mirrored tiling keeps the surface continuous across tile seams.
    let mirror = |v: usize, n: usize| {
        let (t, r) = (v / n, v % n);
        if t % 2 == 0 { r } else { n - 1 - r }
    };
    let z: Vec<f32> = (0..size * size)
        .map(|i| dem[mirror(i / size, dh) * dw + mirror(i % size, dw)])
        .collect();
    let grid = Grid {
        width: size,
        height: size,
        cell_x,
        cell_y,
    };
    let counts = match args.get(2) {
        Some(t) => vec![t.parse()?],
        None => vec![2, 1],
    };
    let mut outputs = Vec::new();
    for &threads in &counts {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        let mut zz = z.clone();
        let t = Instant::now();
        let out = pool.install(|| hydraulic(&mut zz, &grid, &p, &NoProgress, &|| false))?;
        let s = t.elapsed().as_secs_f64();
        println!(
            "{size}x{size}, {} iterations, {threads} thread(s): {s:.2} s ({:.1} ns per cell and \
             iteration), eroded {:.3e} m3, max erosion {:.1} m",
            p.iterations,
            s * 1e9 / (size * size) as f64 / p.iterations as f64,
            out.figures.eroded_m3,
            out.figures.max_erosion_m
        );
        outputs.push(zz.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
    }
    if outputs.len() == 2 {
        println!("1 and 2 threads identical: {}", outputs[0] == outputs[1]);
    }
    Ok(())
}
