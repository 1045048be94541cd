//! The exact `s = 1` search for large dictionaries (`nearest_atom`) against the literal OMP of
//! the paper (`omp_reference`) and Batch-OMP's Gram path, on random data and on real DEM
//! patches; thread-count independence; `batch_omp`'s dispatch above 4096 atoms; the
//! inverted-list `AtomIndex` (exact when every list is probed, recall on real patches, errors).

use ndarray::{Array2, s};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64;
use relief_sparse_core::nearest::{AtomIndex, AtomIndexSettings, nearest_atom};
use relief_sparse_core::omp::{
    NEAREST_MIN_ATOMS, OmpSettings, SparseCodes, batch_omp, omp_reference,
};
use relief_sparse_core::{PatchGeometry, extract_patches};

const S1: OmpSettings = OmpSettings {
    sparsity: 1,
    tolerance: None,
};

fn gaussian(rows: usize, dim: usize, seed: u64, unit: bool) -> Array2<f32> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut d = Array2::from_shape_fn((rows, dim), |_| {
        let v: f64 = StandardNormal.sample(&mut rng);
        v as f32
    });
    if unit {
        normalise(&mut d);
    }
    d
}

fn normalise(d: &mut Array2<f32>) {
    for mut row in d.outer_iter_mut() {
        let n = row.dot(&row).sqrt();
        row.mapv_inplace(|v| v / n);
    }
}

/// Brute-force `argmax |<d, x>|` in `f64` and the gap to the runner-up, relative to `||x||`.
fn brute(d: &Array2<f32>, x: &[f32]) -> (u32, f64) {
    let xn = x.iter().map(|&v| (v as f64).powi(2)).sum::<f64>().sqrt();
    let (mut b1, mut b2, mut bi) = (-1.0f64, -1.0f64, 0u32);
    for (j, row) in d.outer_iter().enumerate() {
        let v = row
            .iter()
            .zip(x)
            .map(|(&a, &b)| a as f64 * b as f64)
            .sum::<f64>()
            .abs();
        if v > b1 {
            b2 = b1;
            b1 = v;
            bi = j as u32;
        } else if v > b2 {
            b2 = v;
        }
    }
    (bi, (b1 - b2) / xn)
}

/// Same atom as `other` for every signal whose best atom is not a near tie; values and
/// residuals within `f32` rounding. Returns the number of signals compared.
fn agree(
    a: &SparseCodes<f32>,
    other: &SparseCodes<f32>,
    d: &Array2<f32>,
    x: &Array2<f32>,
) -> usize {
    let mut compared = 0;
    for i in 0..x.nrows() {
        let row: Vec<f32> = x.row(i).to_vec();
        let (bi, gap) = brute(d, &row);
        let (ia, va) = a.signal(i);
        assert_eq!(ia.len(), 1, "signal {i}");
        if gap > 1e-5 {
            compared += 1;
            assert_eq!(ia[0], bi, "signal {i}: not the best atom");
            let (ib, vb) = other.signal(i);
            assert_eq!(ia, ib, "signal {i}");
            let scale = row.iter().map(|v| v.abs()).fold(0.0f32, f32::max).max(1e-6);
            assert!(
                (va[0] - vb[0]).abs() <= 1e-4 * scale * 8.0,
                "signal {i}: {} vs {}",
                va[0],
                vb[0]
            );
            let xx: f32 = row.iter().map(|v| v * v).sum();
            assert!(
                (a.residual_sq(i) - other.residual_sq(i)).abs() <= 1e-4 * xx,
                "signal {i}: residual {} vs {}",
                a.residual_sq(i),
                other.residual_sq(i)
            );
        }
    }
    compared
}

#[test]
fn random_data_matches_reference_and_gram_path() {
    let d = gaussian(1500, 24, 1, true);
    let x = gaussian(300, 24, 2, false);
    let fast = nearest_atom(d.view(), x.view(), &S1).unwrap();
    let refe = omp_reference(d.view(), x.view(), &S1).unwrap();
    let gram = batch_omp(d.view(), x.view(), &S1).unwrap();
    assert!(agree(&fast, &refe, &d, &x) >= 290);
    assert!(agree(&fast, &gram, &d, &x) >= 290);
}

#[test]
fn signals_equal_to_atoms_pick_themselves() {
    let d = gaussian(5000, 16, 3, true);
    let x = d.slice(s![..;97, ..]).mapv(|v| -3.0 * v);
    let fast = nearest_atom(d.view(), x.view(), &S1).unwrap();
    for i in 0..x.nrows() {
        let (idx, val) = fast.signal(i);
        assert_eq!(idx, [(i * 97) as u32]);
        assert!((val[0] + 3.0).abs() < 1e-4, "{}", val[0]);
        assert!(fast.residual_sq(i) < 1e-4);
    }
}

#[test]
fn ties_go_to_the_smallest_index() {
    // Atom 7 repeated (and negated) at 4000 and 4500: the signal along it picks 7.
    let mut d = gaussian(5000, 16, 4, true);
    let a = d.row(7).to_owned();
    d.row_mut(4000).assign(&a);
    d.row_mut(4500).assign(&a.mapv(|v| -v));
    let x = a.mapv(|v| 2.0 * v).insert_axis(ndarray::Axis(0));
    let fast = nearest_atom(d.view(), x.view(), &S1).unwrap();
    assert_eq!(fast.signal(0).0, [7]);
    let fast = batch_omp(d.view(), x.view(), &S1).unwrap();
    assert_eq!(fast.signal(0).0, [7]);
}

/// Unit-norm 8 x 8 patches (with relief) of the top half of the `w x h` Grand Canyon crop at
/// `(x, y)` as atoms, and the patches of its bottom half as signals.
fn atoms_and_signals(x: usize, y: usize, w: usize, h: usize) -> Option<(Array2<f32>, Array2<f32>)> {
    let dem = relief_testdata::dem_crop("grandcanyon", x, y, w, h)?;
    let geom = PatchGeometry::with_patch_size(8);
    let half = |y0| {
        extract_patches(&dem.crop(0, y0, w, h / 2).unwrap(), &geom)
            .unwrap()
            .matrix
    };
    let (top, bottom) = (half(0), half(h / 2));
    let mut d = top.select(
        ndarray::Axis(0),
        &(0..top.nrows())
            .filter(|&i| top.row(i).dot(&top.row(i)) > 1e-6)
            .collect::<Vec<_>>(),
    );
    normalise(&mut d);
    Some((d, bottom))
}

#[test]
fn real_dem_patches_match_gram_path() {
    let Some((d, bottom)) = atoms_and_signals(100, 100, 96, 128) else {
        return;
    };
    let x = bottom.slice(s![..;5, ..]).to_owned();
    let fast = nearest_atom(d.view(), x.view(), &S1).unwrap();
    let gram = batch_omp(d.view(), x.view(), &S1).unwrap();
    let refe = omp_reference(d.view(), x.slice(s![..;4, ..]), &S1).unwrap();
    let fast_sub = nearest_atom(d.view(), x.slice(s![..;4, ..]), &S1).unwrap();
    let n = x.nrows();
    assert!(
        agree(&fast, &gram, &d, &x) >= n * 9 / 10,
        "too many near ties"
    );
    let xs = x.slice(s![..;4, ..]).to_owned();
    assert!(agree(&fast_sub, &refe, &d, &xs) >= xs.nrows() * 9 / 10);
}

#[test]
fn thread_count_and_batch_do_not_change_the_codes() {
    let d = gaussian(6000, 32, 5, true);
    let x = gaussian(700, 32, 6, false);
    let run = |threads: usize| {
        relief_testdata::with_threads(threads, || batch_omp(d.view(), x.view(), &S1).unwrap())
    };
    let one = run(1);
    assert_eq!(one, run(3));
    let single = batch_omp(d.view(), x.slice(s![600..601, ..]), &S1).unwrap();
    assert_eq!(single.signal(0), one.signal(600));
    assert_eq!(single.residual_sq(0), one.residual_sq(600));
}

#[test]
fn large_dictionaries_pass_the_gram_limit_at_s1_only() {
    const { assert!(6000 > NEAREST_MIN_ATOMS) };
    let d = gaussian(40_000, 8, 7, true);
    let x = gaussian(50, 8, 8, false);
    let codes = batch_omp(d.view(), x.view(), &S1).unwrap();
    assert_eq!(codes.nnz(), 50);
    for i in 0..50 {
        assert_eq!(codes.signal(i).0[0], brute(&d, &x.row(i).to_vec()).0);
    }
    let s2 = OmpSettings {
        sparsity: 2,
        tolerance: None,
    };
    assert!(batch_omp(d.view(), x.view(), &s2).is_err());
    assert!(nearest_atom(d.view(), x.view(), &s2).is_err());
}

#[test]
fn tolerance_and_zero_signals_give_no_atom() {
    let d = gaussian(5000, 16, 9, true);
    let mut x = gaussian(3, 16, 10, false);
    x.row_mut(1).fill(0.0);
    x.row_mut(0).mapv_inplace(|v| 10.0 * v);
    x.row_mut(2).mapv_inplace(|v| 0.1 * v);
    let tol = OmpSettings {
        sparsity: 1,
        tolerance: Some(x.row(2).dot(&x.row(2)) as f64 * 1.01),
    };
    let c = nearest_atom(d.view(), x.view(), &tol).unwrap();
    assert_eq!(c.signal(0).0.len(), 1);
    assert_eq!(c.signal(1).0.len(), 0);
    assert_eq!(c.signal(2).0.len(), 0);
    let bad = d.mapv(|v| 2.0 * v);
    assert!(nearest_atom(bad.view(), x.view(), &S1).is_err());
}

fn index_settings(lists: usize, probes: usize) -> AtomIndexSettings {
    AtomIndexSettings {
        lists,
        probes,
        ..AtomIndexSettings::default()
    }
}

#[test]
fn index_probing_every_list_is_the_exact_search() {
    let d = gaussian(6000, 16, 11, true);
    let x = gaussian(400, 16, 12, false);
    let index = AtomIndex::build(d.view(), &index_settings(32, 32)).unwrap();
    assert_eq!((index.lists(), index.probes(), index.len()), (32, 32, 6000));
    let fast = index.code(x.view(), None).unwrap();
    let exact = nearest_atom(d.view(), x.view(), &S1).unwrap();
    assert!(agree(&fast, &exact, &d, &x) >= 380);
    let zero = Array2::<f32>::zeros((1, 16));
    assert_eq!(index.code(zero.view(), None).unwrap().signal(0).0.len(), 0);
    // Ties still go to the smallest index across lists.
    let mut d = d;
    let a = d.row(7).to_owned();
    d.row_mut(4000).assign(&a.mapv(|v| -v));
    let index = AtomIndex::build(d.view(), &index_settings(32, 32)).unwrap();
    let x = a.mapv(|v| 2.0 * v).insert_axis(ndarray::Axis(0));
    assert_eq!(index.code(x.view(), None).unwrap().signal(0).0, [7]);
}

#[test]
fn index_recall_on_real_dem_patches() {
    let Some((d, bottom)) = atoms_and_signals(0, 0, 256, 256) else {
        return;
    };
    let x = bottom.slice(s![..;3, ..]).to_owned();
    let probes = |p| {
        let index = AtomIndex::build(d.view(), &index_settings(0, p)).unwrap();
        index.recall(d.view(), x.view()).unwrap()
    };
    // About 7,400 atoms: 64 lists. Recall grows with the probes and the coefficient found is
    // within a fraction of a percent of the exact one.
    let (r2, q2) = probes(2);
    let (r8, q8) = probes(8);
    let (r64, q64) = probes(64);
    assert!(r2 < r8 && r8 >= 0.95 && q8 >= 0.999, "{r2} {r8} {q8}");
    assert!(q2 < q8 && q2 > 0.98, "{q2}");
    assert!(r64 > 0.99 && q64 > 0.99999, "{r64} {q64}");
}

#[test]
fn index_codes_do_not_depend_on_threads_or_batch() {
    let d = gaussian(9000, 16, 13, true);
    let x = gaussian(2500, 16, 14, false);
    let st = index_settings(0, 4);
    let run = |threads: usize| {
        relief_testdata::with_threads(threads, || {
            let index = AtomIndex::build(d.view(), &st).unwrap();
            index.code(x.view(), None).unwrap()
        })
    };
    let one = run(1);
    assert_eq!(one, run(2));
    let index = AtomIndex::build(d.view(), &st).unwrap();
    let single = index.code(x.slice(s![2100..2101, ..]), None).unwrap();
    assert_eq!(single.signal(0), one.signal(2100));
}

#[test]
fn index_refuses_bad_input() {
    let d = gaussian(500, 8, 15, true);
    let x = gaussian(5, 8, 16, false);
    let ok = AtomIndexSettings::default();
    for bad in [
        index_settings(0, 0),
        AtomIndexSettings {
            sample_per_list: 0,
            ..ok
        },
        AtomIndexSettings {
            iterations: 1000,
            ..ok
        },
    ] {
        assert!(AtomIndex::build(d.view(), &bad).is_err(), "{bad:?}");
    }
    assert!(AtomIndex::build(d.mapv(|v| 2.0 * v).view(), &ok).is_err());
    assert!(AtomIndex::build(Array2::<f32>::zeros((0, 8)).view(), &ok).is_err());
    let mut nan = d.clone();
    nan[[3, 3]] = f32::NAN;
    assert!(AtomIndex::build(nan.view(), &ok).is_err());
    let index = AtomIndex::build(d.view(), &ok).unwrap();
    assert_eq!(index.lists(), 16);
    assert!(index.code(gaussian(5, 9, 17, false).view(), None).is_err());
    let mut xn = x.clone();
    xn[[2, 0]] = f32::INFINITY;
    assert!(index.code(xn.view(), None).is_err());
    assert!(index.code(x.view(), Some(-1.0)).is_err());
    // Tolerance honoured: a signal within it gets no atom.
    let tol = Some(f64::from(x.row(0).dot(&x.row(0))) * 1.01);
    let c = index.code(x.slice(s![..1, ..]), tol).unwrap();
    assert_eq!(c.signal(0).0.len(), 0);
    assert_eq!(ok.lists_for(65_536), 256);
    assert_eq!(ok.lists_for(4096), 64);
    assert_eq!(ok.lists_for(1), 1);
}
