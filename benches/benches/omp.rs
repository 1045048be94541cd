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
//! timed in the same run so the per-signal ratio holds on a loaded machine. The inverted-list
//! index of `relief_sparse_core::nearest::AtomIndex` (default settings: 256 lists, 8 probes) is
//! timed as `omp_large/atom_index_build_f32/k64_n65536_s1` (once per dictionary) and
//! `omp_large/atom_index_code_f32/k64_n65536_s1` (the same 16,384 signals); its recall against
//! the exact search is printed by `cargo bench -p relief-benches --bench nearest_index`.

use criterion::measurement::WallTime;
use criterion::{
    BenchmarkGroup, BenchmarkId, Criterion, Throughput, criterion_group, criterion_main,
};
use ndarray::{Array2, s};
use relief_sparse_core::nearest::{AtomIndex, AtomIndexSettings};
use relief_sparse_core::omp::{NEAREST_MIN_ATOMS, OmpFloat, OmpSettings, batch_omp};
use relief_sparse_core::{PatchGeometry, extract_patches};

/// Real mean-removed patches of side `a` of the fixture DEM (`n_signals` rows, evenly strided
/// over all patches at step `step`) and a dictionary of `n_atoms` other patches, unit-norm rows.
fn data(a: usize, step: f64, n_atoms: usize, n_signals: usize) -> (Array2<f32>, Array2<f32>) {
    let dem = relief_benches::fixture_or(|| relief_testdata::load_dem("grandcanyon"));
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
    let dir = relief_benches::bench_data_dir().expect("target/bench-data");
    let k = a * a;
    for (name, m) in [("dict", &dict), ("signals", &signals)] {
        let path = dir.join(format!("omp_k{k}_n{n_atoms}_{name}.npy"));
        relief_benches::write_npy(&path, &[m.nrows(), k], m.iter().copied()).expect("write npy");
    }
    (dict, signals)
}

/// `s = 1` with a 65,536-atom dictionary vs today's 4096-atom path, same signals.
fn omp_large(c: &mut Criterion) {
    let mut g = c.benchmark_group("omp_large");
    g.sample_size(10);
    for n_atoms in [4096usize, 65_536] {
        let (d, x) = relief_benches::large_dictionary_data(n_atoms, 16_384);
        g.throughput(Throughput::Elements(x.nrows() as u64));
        let param = format!("k64_n{n_atoms}_s1");
        bench_omp(&mut g, ("batch_omp_f32", &param), &d, &x, 1);
        if n_atoms > NEAREST_MIN_ATOMS {
            // The inverted-list index: built once per dictionary, then coding.
            let st = AtomIndexSettings::default();
            g.bench_function(BenchmarkId::new("atom_index_build_f32", &param), |b| {
                b.iter(|| AtomIndex::build(d.view(), &st).expect("index"))
            });
            let index = AtomIndex::build(d.view(), &st).expect("index");
            g.bench_function(BenchmarkId::new("atom_index_code_f32", &param), |b| {
                b.iter(|| index.code(x.view(), None).expect("code"))
            });
        }
    }
    g.finish();
}

/// Times `batch_omp` of the rows of `x` over the atoms `d` at sparsity `s`, as
/// `<group>/<function>/<param>`.
fn bench_omp<T: OmpFloat>(
    g: &mut BenchmarkGroup<'_, WallTime>,
    (function, param): (&str, &str),
    d: &Array2<T>,
    x: &Array2<T>,
    s: usize,
) {
    let st = OmpSettings {
        sparsity: s,
        tolerance: None,
    };
    g.bench_with_input(BenchmarkId::new(function, param), &st, |b, st| {
        b.iter(|| batch_omp(d.view(), x.view(), st).expect("omp"))
    });
}

fn omp(c: &mut Criterion) {
    let mut g = c.benchmark_group("omp");
    g.sample_size(10);
    let (d, x) = data(8, 1.0, 256, 65_536);
    g.throughput(Throughput::Elements(x.nrows() as u64));
    for s in [1usize, 4, 8] {
        let param = format!("k64_n256_s{s}");
        bench_omp(&mut g, ("batch_omp_f32", &param), &d, &x, s);
    }
    let (d, x) = data(16, 2.0, 1024, 16_384);
    g.throughput(Throughput::Elements(x.nrows() as u64));
    bench_omp(&mut g, ("batch_omp_f32", "k256_n1024_s8"), &d, &x, 8);
    // The f64 path on the same data (section 4.3 asks for both precisions).
    let (d64, x64) = (d.mapv(f64::from), x.mapv(f64::from));
    bench_omp(&mut g, ("batch_omp_f64", "k256_n1024_s8"), &d64, &x64, 8);
    let (d, x) = data(8, 1.0, 256, 65_536);
    let (d64, x64) = (d.mapv(f64::from), x.mapv(f64::from));
    g.throughput(Throughput::Elements(x.nrows() as u64));
    for s in [1usize, 4, 8] {
        let param = format!("k64_n256_s{s}");
        bench_omp(&mut g, ("batch_omp_f64", &param), &d64, &x64, s);
    }
    g.finish();
}

criterion_group!(benches, omp, omp_large);
criterion_main!(benches);
