//! Conformance suite of the sparse solvers: every check runs against `omp_reference` and
//! `batch_omp`, in `f32` and `f64` (one macro instantiation per solver and type).

use ndarray::{Array2, ArrayView2};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64;
use relief_sparse_core::omp::{OmpFloat, OmpSettings, SparseCodes, batch_omp, omp_reference};
use relief_sparse_core::{PatchGeometry, SparseError, extract_patches};

/// Asserts that `res` is the error of a non-finite value in row `row` of input `what`.
fn assert_non_finite<C: std::fmt::Debug>(res: Result<C, SparseError>, what: &str, row: usize) {
    assert!(
        matches!(&res, Err(SparseError::NonFinite { what: w, row: r }) if *w == what && *r == row),
        "{res:?}"
    );
}

/// A `rows x cols` matrix of independent standard normal samples.
fn gaussian_matrix(rows: usize, cols: usize, seed: u64) -> Array2<f64> {
    let mut rng = Pcg64::seed_from_u64(seed);
    Array2::from_shape_fn((rows, cols), |_| StandardNormal.sample(&mut rng))
}

/// Random unit-norm Gaussian dictionary (well conditioned: low mutual coherence).
fn gaussian_dict(n_atoms: usize, dim: usize, seed: u64) -> Array2<f64> {
    let mut d = gaussian_matrix(n_atoms, dim, seed);
    for mut row in d.outer_iter_mut() {
        let n = row.dot(&row).sqrt();
        row.mapv_inplace(|v| v / n);
    }
    d
}

/// Signals that are exact `s`-sparse combinations with well separated coefficients; returns
/// the signals and the true supports.
fn sparse_signals(
    dict: &Array2<f64>,
    n: usize,
    s: usize,
    seed: u64,
) -> (Array2<f64>, Vec<Vec<u32>>) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (n_atoms, dim) = dict.dim();
    let mut x = Array2::zeros((n, dim));
    let mut supports = Vec::new();
    for i in 0..n {
        let mut sup: Vec<u32> = Vec::new();
        while sup.len() < s {
            let j = rng.random_range(0..n_atoms) as u32;
            if !sup.contains(&j) {
                sup.push(j);
            }
        }
        for (k, &j) in sup.iter().enumerate() {
            // Decreasing magnitudes 2^-k in [1, 2] * sign: a clear selection order.
            let mag = (1.0 + rng.random::<f64>()) * 0.6f64.powi(k as i32);
            let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
            x.row_mut(i).scaled_add(mag * sign, &dict.row(j as usize));
        }
        sup.sort_unstable();
        supports.push(sup);
    }
    (x, supports)
}

fn residual_sq<T: OmpFloat>(
    dict: ArrayView2<T>,
    x: ArrayView2<T>,
    codes: &SparseCodes<T>,
) -> Vec<f64> {
    let rec = codes.reconstruct(dict);
    (0..x.nrows())
        .map(|i| {
            x.row(i)
                .iter()
                .zip(rec.row(i))
                .map(|(a, b)| (a.to_f64() - b.to_f64()).powi(2))
                .sum()
        })
        .collect()
}

fn real_patches() -> Option<Array2<f32>> {
    let hf = relief_testdata::dem_crop("grandcanyon", 100, 140, 64, 64)?;
    let p = extract_patches(&hf, &PatchGeometry::with_patch_size(8)).ok()?;
    Some(p.matrix)
}

macro_rules! solver_suite {
    ($name:ident, $solver:ident, $t:ty) => {
        mod $name {
            use super::*;
            type T = $t;
            fn conv(a: &Array2<f64>) -> Array2<T> {
                a.mapv(|v| <T as OmpFloat>::from_f64(v))
            }

            #[test]
            fn errors_not_panics() {
                let d = conv(&gaussian_dict(16, 8, 1));
                let x = conv(&sparse_signals(&gaussian_dict(16, 8, 1), 3, 2, 2).0);
                let st = |s| OmpSettings {
                    sparsity: s,
                    tolerance: None,
                };
                assert!(matches!(
                    $solver(d.view(), x.view(), &st(17)),
                    Err(SparseError::SparsityTooLarge {
                        sparsity: 17,
                        n_atoms: 16
                    })
                ));
                assert!(matches!(
                    $solver(d.view(), x.view(), &st(0)),
                    Err(SparseError::InvalidParameter {
                        name: "sparsity",
                        ..
                    })
                ));
                let big = conv(&gaussian_dict(80, 8, 1));
                assert!(matches!(
                    $solver(big.view(), x.view(), &st(65)),
                    Err(SparseError::InvalidParameter {
                        name: "sparsity",
                        ..
                    })
                ));
                let empty = Array2::<T>::zeros((0, 8));
                assert!(matches!(
                    $solver(empty.view(), x.view(), &st(1)),
                    Err(SparseError::EmptyDictionary { .. })
                ));
                let mut nan = x.clone();
                nan[(1, 3)] = <T>::NAN;
                assert_non_finite($solver(d.view(), nan.view(), &st(2)), "signals", 1);
                let mut dnan = d.clone();
                dnan[(4, 0)] = <T>::INFINITY;
                assert_non_finite($solver(dnan.view(), x.view(), &st(2)), "dictionary", 4);
                let short = Array2::<T>::zeros((3, 7));
                assert!(matches!(
                    $solver(d.view(), short.view(), &st(2)),
                    Err(SparseError::DimensionMismatch {
                        expected: 8,
                        got: 7,
                        ..
                    })
                ));
                let unnorm = d.mapv(|v| v * 2.0);
                assert!(matches!(
                    $solver(unnorm.view(), x.view(), &st(2)),
                    Err(SparseError::NotNormalised { atom: 0, .. })
                ));
                let bad_tol = OmpSettings {
                    sparsity: 2,
                    tolerance: Some(-1.0),
                };
                assert!($solver(d.view(), x.view(), &bad_tol).is_err());
            }

            #[test]
            fn recovers_true_supports_on_well_conditioned_data() {
                let d64 = gaussian_dict(96, 64, 7);
                let (x64, supports) = sparse_signals(&d64, 200, 4, 8);
                let (d, x) = (conv(&d64), conv(&x64));
                let codes = $solver(
                    d.view(),
                    x.view(),
                    &OmpSettings {
                        sparsity: 4,
                        tolerance: None,
                    },
                )
                .unwrap();
                assert_eq!(codes.n_signals(), 200);
                let res = residual_sq(d.view(), x.view(), &codes);
                for i in 0..200 {
                    let mut got = codes.signal(i).0.to_vec();
                    got.sort_unstable();
                    assert_eq!(got, supports[i], "signal {i}");
                    let norm: f64 = x64.row(i).dot(&x64.row(i));
                    assert!(res[i] <= 1e-8 * norm, "signal {i}: residual {}", res[i]);
                }
            }

            #[test]
            fn residual_non_increasing_in_sparsity() {
                let d = conv(&gaussian_dict(64, 32, 11));
                let x = conv(&gaussian_matrix(40, 32, 12));
                let mut prev = vec![f64::INFINITY; 40];
                for s in 1..=12 {
                    let c = $solver(
                        d.view(),
                        x.view(),
                        &OmpSettings {
                            sparsity: s,
                            tolerance: None,
                        },
                    )
                    .unwrap();
                    let r = residual_sq(d.view(), x.view(), &c);
                    for i in 0..40 {
                        // The solver's own residual estimate agrees with the explicit one.
                        let est = c.residual_sq(i).to_f64();
                        assert!(
                            (est - r[i]).abs() <= 1e-3 * (1.0 + r[i]),
                            "{est} vs {}",
                            r[i]
                        );
                        assert!(r[i] <= prev[i] * (1.0 + 1e-4) + 1e-9, "s={s} signal {i}");
                        prev[i] = r[i];
                    }
                }
            }

            #[test]
            fn stops_on_tolerance() {
                let d = conv(&gaussian_dict(64, 32, 21));
                let x = conv(&gaussian_matrix(30, 32, 22));
                let tol = 8.0;
                let st = OmpSettings {
                    sparsity: 32,
                    tolerance: Some(tol),
                };
                let c = $solver(d.view(), x.view(), &st).unwrap();
                let r = residual_sq(d.view(), x.view(), &c);
                for i in 0..30 {
                    let k = c.signal(i).0.len();
                    assert!(
                        r[i] <= tol * 1.001 || k == 32,
                        "signal {i}: {} with {k} atoms",
                        r[i]
                    );
                    // Minimal: one atom fewer would not have reached the tolerance.
                    if k > 0 {
                        let fewer = $solver(
                            d.view(),
                            x.slice(ndarray::s![i..i + 1, ..]),
                            &OmpSettings {
                                sparsity: k.max(2) - 1,
                                tolerance: None,
                            },
                        )
                        .unwrap();
                        let rf = residual_sq(d.view(), x.slice(ndarray::s![i..i + 1, ..]), &fewer);
                        if k > 1 {
                            assert!(rf[0] > tol * 0.999, "signal {i} could stop at {}", k - 1);
                        }
                    }
                }
            }

            #[test]
            fn zero_signal_gives_empty_code() {
                let d = conv(&gaussian_dict(16, 8, 3));
                let x = Array2::<T>::zeros((2, 8));
                let c = $solver(
                    d.view(),
                    x.view(),
                    &OmpSettings {
                        sparsity: 3,
                        tolerance: None,
                    },
                )
                .unwrap();
                assert_eq!(c.signal(0).0.len(), 0);
                assert_eq!(c.nnz(), 0);
                assert_eq!(c.to_dense(16).sum(), 0.0);
            }

            #[test]
            fn real_dem_patches_first_atom_is_best_correlation() {
                let Some(m) = real_patches() else { return };
                // Dictionary: 64 normalised real patches (coherent, the realistic case).
                let mut d = Array2::<f64>::zeros((64, 64));
                for (k, i) in (0..m.nrows()).step_by(m.nrows() / 64).take(64).enumerate() {
                    let row = m.row(i).mapv(|v| v as f64);
                    let n = row.dot(&row).sqrt();
                    d.row_mut(k).assign(&(row / n));
                }
                let d = conv(&d);
                let x = m.mapv(|v| <T as OmpFloat>::from_f64(v as f64));
                let c1 = $solver(
                    d.view(),
                    x.view(),
                    &OmpSettings {
                        sparsity: 1,
                        tolerance: None,
                    },
                )
                .unwrap();
                for i in 0..x.nrows() {
                    let (idx, _) = c1.signal(i);
                    let corr: Vec<f64> = (0..64)
                        .map(|j| {
                            d.row(j)
                                .iter()
                                .zip(x.row(i))
                                .map(|(a, b)| a.to_f64() * b.to_f64())
                                .sum::<f64>()
                                .abs()
                        })
                        .collect();
                    let best = corr.iter().cloned().fold(0.0, f64::max);
                    if best > 0.0 {
                        assert!(corr[idx[0] as usize] >= best * (1.0 - 1e-4), "signal {i}");
                    }
                }
                // s = 8 beats s = 1 on every non-trivial patch.
                let c8 = $solver(
                    d.view(),
                    x.view(),
                    &OmpSettings {
                        sparsity: 8,
                        tolerance: None,
                    },
                )
                .unwrap();
                let (r1, r8) = (
                    residual_sq(d.view(), x.view(), &c1),
                    residual_sq(d.view(), x.view(), &c8),
                );
                let (s1, s8): (f64, f64) = (r1.iter().sum(), r8.iter().sum());
                assert!(s8 < 0.8 * s1, "{s8} vs {s1}");
            }
        }
    };
}

solver_suite!(reference_f32, omp_reference, f32);
solver_suite!(reference_f64, omp_reference, f64);
solver_suite!(batch_f32, batch_omp, f32);
solver_suite!(batch_f64, batch_omp, f64);

#[test]
fn batch_matches_reference_on_well_conditioned_data() {
    let d = gaussian_dict(128, 64, 31);
    let (x, _) = sparse_signals(&d, 300, 6, 32);
    let st = OmpSettings {
        sparsity: 6,
        tolerance: None,
    };
    let a = omp_reference(d.view(), x.view(), &st).unwrap();
    let b = batch_omp(d.view(), x.view(), &st).unwrap();
    let sorted = |c: &SparseCodes<f64>, i: usize| {
        let (idx, val) = c.signal(i);
        let mut p: Vec<(u32, f64)> = idx.iter().copied().zip(val.iter().copied()).collect();
        p.sort_by_key(|q| q.0);
        p
    };
    for i in 0..300 {
        // Same support (the literal argmin of section 4.3 may order it differently from the
        // max-correlation rule) and the same least-squares coefficients.
        let (pa, pb) = (sorted(&a, i), sorted(&b, i));
        assert_eq!(pa.len(), pb.len(), "signal {i}");
        for ((ja, u), (jb, v)) in pa.iter().zip(&pb) {
            assert_eq!(ja, jb, "signal {i}");
            assert!((u - v).abs() < 1e-9, "{u} vs {v}");
        }
    }
    // f32 Batch-OMP agrees with f64 on the same data.
    let c = batch_omp(
        d.mapv(|v| v as f32).view(),
        x.mapv(|v| v as f32).view(),
        &st,
    )
    .unwrap();
    for i in 0..300 {
        assert_eq!(b.signal(i).0, c.signal(i).0);
    }
}

#[test]
fn batch_is_independent_of_threads_and_batching() {
    let d = gaussian_dict(256, 64, 41).mapv(|v| v as f32);
    let mut rng = Pcg64::seed_from_u64(42);
    let x = Array2::from_shape_fn((1000, 64), |_| {
        let v: f32 = StandardNormal.sample(&mut rng);
        v
    });
    let st = OmpSettings {
        sparsity: 8,
        tolerance: None,
    };
    let run = |threads| {
        relief_testdata::with_threads(threads, || batch_omp(d.view(), x.view(), &st).unwrap())
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a, b);
    // A signal coded alone gets bit-identical codes.
    let single = batch_omp(d.view(), x.slice(ndarray::s![700..701, ..]), &st).unwrap();
    assert_eq!(single.signal(0), a.signal(700));
}
