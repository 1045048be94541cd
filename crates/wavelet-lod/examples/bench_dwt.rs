//! Release timing harness of the 2-D DWT against PyWavelets, measured in the same run.
//!
//! ```text
//! cargo run --release -p relief-wavelet-lod --example bench_dwt -- [SIZE] [LEVELS] [PYTHON]
//! ```
//! Defaults: 4096, 6, `target/peers-venv/bin/python`. The PyWavelets peer
//! (`xtask/peers/pywt_dwt.py`, 6 levels, median of 3) runs on the same surface, read from
//! `target/bench-data/dwt_surface_SIZE.npy` (written by `cargo xtask bench`); it is skipped when
//! the interpreter or that file is absent. Times forward + inverse after one untimed warm-up
//! run, `f32`, best of 3, on the rayon pool (set `RAYON_NUM_THREADS`); the peer reports its
//! median of 3 (single-threaded, as PyWavelets is).
#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_wavelet_lod::rng::{fill_normals, row_key};
use relief_wavelet_lod::{Boundary, Grid, Wavelet, wavedec2, waverec2_owned};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(4096);
    let levels: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(6);
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let python = args
        .get(3)
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| root.join("target/peers-venv/bin/python"));
    // A random-walk surface like the Python peer's.
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
    let g = Grid::new(size, size, data).expect("grid");
    let threads = rayon::current_num_threads();
    // Warm-up (untimed), like criterion's: the first large allocations of a process pay page
    // faults that a steady-state run (e.g. a server refining tiles) does not.
    let _ = waverec2_owned(wavedec2(&g, Wavelet::Cdf53, levels, Boundary::Symmetric).expect("dwt"));
    for wavelet in Wavelet::ALL {
        let (mut fwd, mut inv) = (f64::MAX, f64::MAX);
        let mut err = 0.0f32;
        for _ in 0..3 {
            let t0 = Instant::now();
            let dec = wavedec2(&g, wavelet, levels, Boundary::Symmetric).expect("dwt");
            let t1 = Instant::now();
            let back = waverec2_owned(dec);
            let t2 = Instant::now();
            fwd = fwd.min((t1 - t0).as_secs_f64());
            inv = inv.min((t2 - t1).as_secs_f64());
            err = back
                .data
                .iter()
                .zip(&g.data)
                .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
        }
        println!(
            "relief {wavelet}: {size}^2 f32, {levels} levels, {threads} threads: forward {fwd:.3} s, inverse {inv:.3} s, total {:.3} s (max error {err})",
            fwd + inv
        );
        let data = root.join("target/bench-data");
        let npy = data.join(format!("dwt_surface_{size}.npy"));
        if wavelet == Wavelet::Cdf53 && python.exists() && npy.exists() {
            let out = std::process::Command::new(&python)
                .arg(root.join("xtask/peers/pywt_dwt.py"))
                .arg(&data)
                .output()
                .expect("run the PyWavelets peer");
            let text = String::from_utf8_lossy(&out.stdout);
            println!("pywt: {}", text.trim());
            let key = format!("\"dwt_fwd_inv_bior22_{size}_s\": ");
            if let Some(total) = text
                .split(key.as_str())
                .nth(1)
                .and_then(|s| s.split([',', '}']).next())
                .and_then(|s| s.trim().parse::<f64>().ok())
            {
                println!(
                    "ratio pywt / relief (cdf53 forward + inverse): {:.2}x",
                    total / (fwd + inv)
                );
            }
        } else if wavelet == Wavelet::Cdf53 {
            println!(
                "pywt peer skipped: needs {} and {} (written by `cargo xtask bench`)",
                python.display(),
                npy.display()
            );
        }
    }
}
