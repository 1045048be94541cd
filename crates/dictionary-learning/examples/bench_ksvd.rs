//! K-SVD speed and error vs SPAMS `trainDL` on the same real patches (release timing harness):
//! `cargo run --release -p relief-dictionary-learning --features examples --example bench_ksvd`
//!
//! ~28k mean-removed 16x16 patches of alps_dem (step 8), N = 256, s = 4, 10 iterations, on the
//! rayon pool (set `RAYON_NUM_THREADS=2` for the 2-thread figure). The patches are written to
//! `target/bench-data/ksvd_patches.npy` and `xtask/peers/spams_traindl.py` is run on them with
//! `target/peers-venv/bin/python` when that venv exists.
#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_dictionary_learning::{KsvdSettings, KsvdVariant, ksvd};
use relief_heightfield::NoProgress;
use relief_sparse_core::{PatchGeometry, extract_patches};

fn main() {
    let Some(hf) = relief_testdata::load_dem("alps_dem") else {
        println!("alps_dem absent");
        return;
    };
    let geom = PatchGeometry {
        step: 8.0,
        ..PatchGeometry::with_patch_size(16)
    };
    let p = extract_patches(&hf, &geom).unwrap();
    let (n, k) = p.matrix.dim();
    println!(
        "patches: {n} x {k}, threads: {}",
        rayon::current_num_threads()
    );
    for (variant, iters) in [(KsvdVariant::Approximate, 10), (KsvdVariant::Exact, 2)] {
        let s = KsvdSettings {
            n_atoms: 256,
            sparsity: 4,
            iterations: iters,
            variant,
            seed: 1,
            ..Default::default()
        };
        let t = Instant::now();
        let r = ksvd(p.matrix.view(), &s, &NoProgress).unwrap();
        let secs = t.elapsed().as_secs_f64();
        let trace: Vec<String> = r.trace.iter().map(|t| format!("{:.3}", t.rmse)).collect();
        println!(
            "relief K-SVD {variant:?} x{iters}: {secs:.2} s, rmse trace [{}]",
            trace.join(", ")
        );
    }
    let root = relief_testdata::workspace_root();
    let dir = root.join("target/bench-data");
    std::fs::create_dir_all(&dir).unwrap();
    let npy = dir.join("ksvd_patches.npy");
    let flat: Vec<f32> = p.matrix.iter().copied().collect();
    std::fs::write(&npy, relief_io::npy_f32(&[n, k], flat.iter().copied())).unwrap();
    let py = root.join("target/peers-venv/bin/python");
    if py.exists() {
        let out = std::process::Command::new(py)
            .arg(root.join("xtask/peers/spams_traindl.py"))
            .arg(&npy)
            .arg(rayon::current_num_threads().to_string())
            .output()
            .unwrap();
        println!(
            "SPAMS trainDL: {}",
            String::from_utf8_lossy(&out.stdout).trim()
        );
        if !out.status.success() {
            println!("SPAMS failed: {}", String::from_utf8_lossy(&out.stderr));
        }
    } else {
        println!("peers venv absent: SPAMS not measured");
    }
}
