//! Batch-OMP throughput (relief-sparse-core, guerin2016 section 4.3) on real terrain patches of
//! the bundled fixture DEM: K = 64 (8 x 8 patches), N = 256 atoms, s = 1, 4, 8 on 65,536
//! signals, and K = 256 (16 x 16), N = 1024, s = 8 on 16,384 signals, `f32`, rayon threads as
//! configured (the dashboard runs with RAYON_NUM_THREADS=2).
//!
//! The inputs are also written to `target/bench-data/omp_k{K}_n{N}_{dict,signals}.npy` so the
//! SPAMS peer (`xtask/peers/spams_omp.py target/bench-data`) codes exactly the same data.
//! Criterion ids: `omp/batch_omp_f32/k64_n256_s{1,4,8}`, `omp/batch_omp_f32/k256_n1024_s8`, and
//! the same inputs in `f64`: `omp/batch_omp_f64/k64_n256_s{1,4,8}`,
//! `omp/batch_omp_f64/k256_n1024_s8`.
//!
//! Large dictionaries (guerin2016 section 5.3, issue 15): `s = 1` coding of 16,384 patches
//! (K = 64) with 65,536 atoms (the exact nearest-atom search, `omp_large/batch_omp_f32/k64_n65536_s1`)
//! against today's 4096-atom Gram path on the same signals (`omp_large/batch_omp_f32/k64_n4096_s1`),
//! timed in the same run so the per-signal ratio holds on a loaded machine.

use std::io::Write;
use std::path::PathBuf;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use ndarray::{Array2, s};
use relief_sparse_core::omp::{OmpSettings, batch_omp};
use relief_sparse_core::{PatchGeometry, extract_patches};

/// Writes a C-order `f32` `.npy` file (format version 1.0).
fn write_npy(path: &PathBuf, a: &Array2<f32>) -> std::io::Result<()> {
    let (r, c) = a.dim();
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({r}, {c}), }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut f = std::io::BufWriter::new(std::fs::File::create(path)?);
    f.write_all(b"\x93NUMPY\x01\x00")?;
    f.write_all(&(header.len() as u16).to_le_bytes())?;
    f.write_all(header.as_bytes())?;
    for v in a.iter() {
        f.write_all(&v.to_le_bytes())?;
    }
    f.flush()
}

/// Real mean-removed patches of side `a` of the fixture DEM (`n_signals` rows, evenly strided
/// over all patches at step `step`) and a dictionary of `n_atoms` other patches, unit-norm rows.
fn data(a: usize, step: f64, n_atoms: usize, n_signals: usize) -> (Array2<f32>, Array2<f32>) {
    let dem = relief_benches::fixture_dem()
        .ok()
        .or_else(|| relief_testdata::load_dem("grandcanyon"))
        .expect("fixtures/grandcanyon.tif or the grandcanyon DEM");
    let g = PatchGeometry {
        step,
        ..PatchGeometry::with_patch_size(a)
    };
    let p = extract_patches(&dem, &g).expect("patches").matrix;
    let n = p.nrows();
    let stride = (n / n_signals).max(1);
    let signals = p.slice(s![..stride * n_signals;stride, ..]).to_owned();
    let mut dict = Array2::zeros((n_atoms, a * a));
    let mut k = 0;
    let mut i = stride / 2;
    while k < n_atoms {
        let row = p.row(i % n);
        let norm = row.dot(&row).sqrt();
        if norm > 1e-3 {
            dict.row_mut(k).assign(&row.mapv(|v| v / norm));
            k += 1;
        }
        i += n / n_atoms + 1;
    }
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/bench-data");
    std::fs::create_dir_all(&dir).expect("target/bench-data");
    let k = a * a;
    write_npy(&dir.join(format!("omp_k{k}_n{n_atoms}_dict.npy")), &dict).expect("write npy");
    write_npy(
        &dir.join(format!("omp_k{k}_n{n_atoms}_signals.npy")),
        &signals,
    )
    .expect("write npy");
    (dict, signals)
}

/// `s = 1` with a 65,536-atom dictionary vs today's 4096-atom path, same signals.
fn omp_large(c: &mut Criterion) {
    let mut g = c.benchmark_group("omp_large");
    g.sample_size(10);
    let st = OmpSettings {
        sparsity: 1,
        tolerance: None,
    };
    let dem = relief_benches::fixture_dem()
        .ok()
        .or_else(|| relief_testdata::load_dem("grandcanyon"))
        .expect("fixtures/grandcanyon.tif or the grandcanyon DEM");
    let (w, h) = (dem.width(), dem.height());
    // Atoms from the top half, signals from the bottom half (no signal is an atom).
    let geom = PatchGeometry::with_patch_size(8);
    let top = extract_patches(&dem.crop(0, 0, w, h / 2).expect("crop"), &geom)
        .expect("patches")
        .matrix;
    let bottom = extract_patches(&dem.crop(0, h / 2, w, h - h / 2).expect("crop"), &geom)
        .expect("patches")
        .matrix;
    let every = |m: &Array2<f32>, n: usize, unit: bool| {
        let mut out = Array2::zeros((n, m.ncols()));
        let mut k = 0;
        let mut i = 0;
        while k < n {
            let row = m.row(i * m.nrows() / n % m.nrows());
            let norm = row.dot(&row).sqrt();
            if norm > 1e-3 {
                out.row_mut(k)
                    .assign(&row.mapv(|v| if unit { v / norm } else { v }));
                k += 1;
            }
            i += 1;
        }
        out
    };
    let x = every(&bottom, 16_384, false);
    for n_atoms in [4096usize, 65_536] {
        let d = every(&top, n_atoms, true);
        g.throughput(Throughput::Elements(x.nrows() as u64));
        g.bench_with_input(
            BenchmarkId::new("batch_omp_f32", format!("k64_n{n_atoms}_s1")),
            &st,
            |b, st| b.iter(|| batch_omp(d.view(), x.view(), st).expect("omp")),
        );
    }
    g.finish();
}

fn omp(c: &mut Criterion) {
    let mut g = c.benchmark_group("omp");
    g.sample_size(10);
    let (d, x) = data(8, 1.0, 256, 65_536);
    g.throughput(Throughput::Elements(x.nrows() as u64));
    for s in [1usize, 4, 8] {
        let st = OmpSettings {
            sparsity: s,
            tolerance: None,
        };
        g.bench_with_input(
            BenchmarkId::new("batch_omp_f32", format!("k64_n256_s{s}")),
            &st,
            |b, st| b.iter(|| batch_omp(d.view(), x.view(), st).expect("omp")),
        );
    }
    let (d, x) = data(16, 2.0, 1024, 16_384);
    g.throughput(Throughput::Elements(x.nrows() as u64));
    let st = OmpSettings {
        sparsity: 8,
        tolerance: None,
    };
    g.bench_with_input(
        BenchmarkId::new("batch_omp_f32", "k256_n1024_s8"),
        &st,
        |b, st| b.iter(|| batch_omp(d.view(), x.view(), st).expect("omp")),
    );
    // The f64 path on the same data (section 4.3 asks for both precisions).
    let (d64, x64) = (d.mapv(f64::from), x.mapv(f64::from));
    g.bench_with_input(
        BenchmarkId::new("batch_omp_f64", "k256_n1024_s8"),
        &st,
        |b, st| b.iter(|| batch_omp(d64.view(), x64.view(), st).expect("omp")),
    );
    let (d, x) = data(8, 1.0, 256, 65_536);
    let (d64, x64) = (d.mapv(f64::from), x.mapv(f64::from));
    g.throughput(Throughput::Elements(x.nrows() as u64));
    for s in [1usize, 4, 8] {
        let st = OmpSettings {
            sparsity: s,
            tolerance: None,
        };
        g.bench_with_input(
            BenchmarkId::new("batch_omp_f64", format!("k64_n256_s{s}")),
            &st,
            |b, st| b.iter(|| batch_omp(d64.view(), x64.view(), st).expect("omp")),
        );
    }
    g.finish();
}

criterion_group!(benches, omp, omp_large);
criterion_main!(benches);
