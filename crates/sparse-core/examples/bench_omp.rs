//! Release timing harness of Batch-OMP (the criterion bench in `benches/benches/omp.rs` is the
//! reference measurement on real patches):
//! `cargo run --release -p relief-sparse-core --features examples --example bench_omp -- [K] [N] [S] [SIGNALS]` on
//! synthetic data, or `... --example bench_omp -- --npy target/bench-data` on the four cases the
//! criterion bench wrote (the same inputs as `xtask/peers/spams_omp.py`). Prints wall time,
//! process CPU time, signals/s and signals per CPU-second (comparable on a shared machine).
#![allow(clippy::print_stdout)]

use std::time::Instant;

use ndarray::Array2;
use relief_sparse_core::omp::{OmpSettings, batch_omp};

/// Process CPU time (user + system) in seconds, from /proc/self/stat (Linux; 0 elsewhere).
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let fields: Vec<&str> = stat
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect();
    let ticks: f64 = fields.get(11).and_then(|v| v.parse().ok()).unwrap_or(0.0)
        + fields
            .get(12)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(0.0);
    ticks / 100.0
}

/// Deterministic pseudo-random values in [-1, 1) (splitmix64).
fn values(n: usize, seed: u64) -> Vec<f32> {
    let mut z = seed;
    (0..n)
        .map(|_| {
            z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut x = z;
            x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            x ^= x >> 31;
            ((x >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        })
        .collect()
}

/// Reads a C-order little-endian `f32` 2-D `.npy` file (as written by the criterion bench).
fn read_npy(path: &str) -> Array2<f32> {
    let b = std::fs::read(path).expect("read .npy");
    assert!(
        b.len() > 10 && &b[..6] == b"\x93NUMPY",
        "{path}: not a .npy file"
    );
    let hlen = u16::from_le_bytes([b[8], b[9]]) as usize;
    let header = std::str::from_utf8(&b[10..10 + hlen]).expect("header");
    assert!(
        header.contains("'<f4'") && header.contains("False"),
        "{path}: need C-order <f4"
    );
    let shape = header
        .split('(')
        .nth(1)
        .and_then(|t| t.split(')').next())
        .expect("shape");
    let dims: Vec<usize> = shape
        .split(',')
        .filter_map(|v| v.trim().parse().ok())
        .collect();
    let data: Vec<f32> = b[10 + hlen..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Array2::from_shape_vec((dims[0], dims[1]), data).expect("shape")
}

fn time(d: &Array2<f32>, x: &Array2<f32>, s: usize) {
    let st = OmpSettings {
        sparsity: s,
        tolerance: None,
    };
    batch_omp(d.view(), x.view(), &st).expect("omp");
    let (t0, c0) = (Instant::now(), cpu_seconds());
    let reps = 3;
    for _ in 0..reps {
        batch_omp(d.view(), x.view(), &st).expect("omp");
    }
    let wall = t0.elapsed().as_secs_f64() / reps as f64;
    let cpu = (cpu_seconds() - c0) / reps as f64;
    let (m, k, n) = (x.nrows(), d.ncols(), d.nrows());
    println!(
        "K={k} N={n} s={s} signals={m} threads={}: wall {:.1} ms, cpu {:.1} ms, {:.0} signals/s (wall), {:.0} signals/s per CPU-second",
        rayon::current_num_threads(),
        wall * 1e3,
        cpu * 1e3,
        m as f64 / wall,
        m as f64 / cpu
    );
}

fn main() {
    let raw: Vec<String> = std::env::args().skip(1).collect();
    if raw.first().map(String::as_str) == Some("--npy") {
        let dir = raw
            .get(1)
            .map(String::as_str)
            .unwrap_or("target/bench-data");
        for (k, n, s) in [(64, 256, 1), (64, 256, 4), (64, 256, 8), (256, 1024, 8)] {
            let d = read_npy(&format!("{dir}/omp_k{k}_n{n}_dict.npy"));
            let x = read_npy(&format!("{dir}/omp_k{k}_n{n}_signals.npy"));
            time(&d, &x, s);
        }
        return;
    }
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let k = *args.first().unwrap_or(&64);
    let n = *args.get(1).unwrap_or(&256);
    let s = *args.get(2).unwrap_or(&8);
    let m = *args.get(3).unwrap_or(&65_536);
    let mut d = Array2::from_shape_vec((n, k), values(n * k, 1)).expect("shape");
    for mut row in d.outer_iter_mut() {
        let norm = row.dot(&row).sqrt();
        row.mapv_inplace(|v| v / norm);
    }
    let x = Array2::from_shape_vec((m, k), values(m * k, 2)).expect("shape");
    time(&d, &x, s);
}
