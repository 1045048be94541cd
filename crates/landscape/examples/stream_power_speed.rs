//! Time per stream-power step on the benchmark surface of `relief_benches::spl_surface` (1024^2
//! uniform noise in [0, 1) m, 100 m cells) with the parameters of `xtask/peers/stream_power.py`
//! (fastscapelib's Mountain example: K 2e-4, m 0.4, n 1, D 0.01 m2/yr, dt 1 kyr, U 1 mm/yr).
//!
//! `cargo run --release -p relief-landscape --features examples --example stream_power_speed -- [STEPS] [NPY_OUT]`
//! prints the median and total step time; with `NPY_OUT` it first writes the input surface as
//! a float64 `.npy` (for `stream_power.py DATA_DIR` as `DATA_DIR/spl_1024.npy`).

// An example reports on stdout.
#![allow(clippy::print_stdout)]

use std::io::Write;
use std::time::Instant;

use relief_heightfield::rng::{hash, unit_f32};
use relief_landscape::erode::{StreamPowerParams, StreamPowerScratch, Uplift, base_level_mask};
use relief_landscape::grid::Grid;

fn write_npy(path: &str, z: &[f64], rows: usize, cols: usize) -> std::io::Result<()> {
    let mut header =
        format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({rows}, {cols}), }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    f.write_all(b"\x93NUMPY\x01\x00")?;
    f.write_all(&(header.len() as u16).to_le_bytes())?;
    f.write_all(header.as_bytes())?;
    for v in z {
        f.write_all(&v.to_le_bytes())?;
    }
    f.flush()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let steps: usize = args.get(1).map_or(100, |s| s.parse().expect("STEPS"));
    let n = 1024;
    let grid = Grid::new(n, n, 100.0, 100.0);
    let mut z: Vec<f64> = (0..n * n)
        .map(|i| unit_f32(hash(7, i as u64, 0, 0)) as f64)
        .collect();
    if let Some(out) = args.get(2) {
        write_npy(out, &z, n, n).expect("write the .npy");
    }
    let base = base_level_mask(&z, &grid);
    let params = StreamPowerParams::fastscape_mountain();
    let mut scratch = StreamPowerScratch::new();
    let mut times = Vec::with_capacity(steps);
    for s in 0..steps {
        let t = Instant::now();
        let f = scratch
            .step(&mut z, &grid, &base, &params, Uplift::Constant(1e-3))
            .expect("step");
        times.push(t.elapsed().as_secs_f64());
        if s < 3 || s + 1 == steps {
            println!("step {s}: {:.4} s {f:?}", times[s]);
        }
    }
    let total: f64 = times.iter().sum();
    times.sort_by(f64::total_cmp);
    let max = z.iter().copied().fold(f64::MIN, f64::max);
    println!(
        "{{\"threads\": {}, \"steps\": {steps}, \"median_step_s\": {:.5}, \"total_s\": {total:.3}, \"final_mean_elev_m\": {}, \"final_max_elev_m\": {max}}}",
        rayon::current_num_threads(),
        times[steps / 2],
        z.iter().sum::<f64>() / z.len() as f64,
    );
}
