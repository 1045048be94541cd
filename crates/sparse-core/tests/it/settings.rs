//! Settings validation: every public settings struct (`PatchGeometry`, `OmpSettings`,
//! `EncodeSettings`, `RasterSettings`, river/region parameters, tree sizes) rejects invalid values
//! with an error naming the field and the value, and random settings fed to every public entry
//! point never panic (proptest). Also: `encode` gives identical bytes on 1 and 2 threads.

use std::sync::Arc;

use ndarray::Array2;
use proptest::prelude::*;
use relief_heightfield::Heightfield;
use relief_sparse_core::{
    Dictionary, EncodeSettings, FormatOptions, FunctionAtomRegistry, Node, OmpSettings,
    PatchGeometry, RasterSettings, Region, River, RiverMode, Sct, SparseError, Window, batch_omp,
    compression_report, encode, encode_shared, extract_patches, omp_reference,
};

/// Scale 1, a `width` x `height` window at the origin.
fn window_at_origin(width: usize, height: usize) -> RasterSettings {
    RasterSettings {
        scale: 1.0,
        window: Some(Window {
            x: 0,
            y: 0,
            width,
            height,
        }),
    }
}

/// Asserts that `r` is an error naming `field` (and, for parameter errors, its value).
fn names<T: std::fmt::Debug>(r: Result<T, SparseError>, field: &str, what: &str) {
    match r {
        Ok(v) => panic!("{what}: accepted ({v:?})"),
        Err(SparseError::InvalidParameter { name, value, .. }) => {
            assert_eq!(name, field, "{what}");
            let msg = SparseError::InvalidParameter {
                name,
                value: value.clone(),
                reason: "",
            }
            .to_string();
            assert!(msg.contains(field) && msg.contains(&value), "{what}: {msg}");
        }
        Err(SparseError::SparsityTooLarge { sparsity, n_atoms }) => {
            assert_eq!(field, "sparsity", "{what}: s = {sparsity} > N = {n_atoms}");
        }
        Err(SparseError::EmptyDictionary { .. }) => {
            assert_eq!(field, "dictionary", "{what}");
        }
        Err(e) => panic!("{what}: unexpected error {e}"),
    }
}

fn terrain() -> Option<Heightfield> {
    relief_testdata::dem_crop("carrizo", 200, 100, 48, 40)
}

fn small_dict(hf: &Heightfield, n: usize) -> Dictionary {
    let p = extract_patches(hf, &PatchGeometry::with_patch_size(6)).unwrap();
    let sel: Vec<usize> = (0..n).map(|k| k * p.matrix.nrows() / n).collect();
    Dictionary::from_patches(&p, Some(&sel)).unwrap().0
}

#[test]
fn invalid_settings_name_field_and_value() {
    let g = PatchGeometry::with_patch_size(8);
    names(
        PatchGeometry { patch_size: 0, ..g }.check(),
        "patch_size",
        "a = 0",
    );
    names(
        PatchGeometry {
            patch_size: 257,
            ..g
        }
        .check(),
        "patch_size",
        "a = 257",
    );
    for v in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        names(
            PatchGeometry { spacing: v, ..g }.check(),
            "spacing",
            "spacing",
        );
        names(PatchGeometry { step: v, ..g }.check(), "step", "step");
        names(
            PatchGeometry {
                support_radius: v,
                ..g
            }
            .check(),
            "support_radius",
            "radius",
        );
    }
    names(
        PatchGeometry { step: 6.0, ..g }.check(),
        "support_radius",
        "R <= S/sqrt2",
    );
    names(
        PatchGeometry {
            step: 1e-4,
            support_radius: 4.0,
            ..g
        }
        .grid(64, 64),
        "step",
        "too many primitives",
    );
    names(g.grid(0, 10), "width x height", "empty terrain");

    for s in [0usize, 65, 1000] {
        names(
            OmpSettings {
                sparsity: s,
                tolerance: None,
            }
            .check(100),
            "sparsity",
            "s",
        );
    }
    names(
        OmpSettings {
            sparsity: 11,
            tolerance: None,
        }
        .check(10),
        "sparsity",
        "s > N",
    );
    for t in [-1.0, f64::NAN, f64::INFINITY] {
        names(
            OmpSettings {
                sparsity: 2,
                tolerance: Some(t),
            }
            .check(10),
            "tolerance",
            "tolerance",
        );
    }
    for s in [0.0, -2.0, 1024.5, f64::NAN, f64::INFINITY] {
        names(
            RasterSettings {
                scale: s,
                window: None,
            }
            .check(),
            "scale",
            "scale",
        );
    }
    names(window_at_origin(0, 3).check(), "window", "empty window");
    names(
        window_at_origin(usize::MAX, usize::MAX).check(),
        "window",
        "huge window",
    );
    names(
        Sct::new(Node::Constant(0.0), 0, 5, (1.0, 1.0)),
        "width x height",
        "w = 0",
    );
    names(
        Sct::new(Node::Constant(0.0), 5, 5, (0.0, 1.0)),
        "cell_size",
        "cell",
    );
    names(
        Sct::new(Node::Constant(f64::NAN), 5, 5, (1.0, 1.0)),
        "constant",
        "NaN constant",
    );
    let region = Region::Rect {
        x0: 5.0,
        y0: 0.0,
        x1: 1.0,
        y1: 2.0,
    };
    let rep = |region: Region, falloff: f64| Node::Replace {
        base: Box::new(Node::Constant(0.0)),
        overlay: Box::new(Node::Constant(1.0)),
        region,
        falloff,
    };
    names(
        Sct::new(rep(region, 1.0), 5, 5, (1.0, 1.0)),
        "region",
        "x0 > x1",
    );
    let disk = Region::Disk {
        cx: 1.0,
        cy: 1.0,
        r: 2.0,
    };
    names(
        Sct::new(rep(disk, -1.0), 5, 5, (1.0, 1.0)),
        "falloff",
        "falloff",
    );
    let p2 = vec![[0.0, 0.0], [4.0, 4.0]];
    names(
        River::new(p2.clone(), vec![0.0, 1.0], vec![1.0; 2], RiverMode::Carve),
        "half_width",
        "zero width",
    );
    names(
        River::new(p2.clone(), vec![1.0; 2], vec![-1.0, 1.0], RiverMode::Carve),
        "depth",
        "negative depth",
    );
    names(
        River::new(
            vec![[0.0, 0.0], [1e308, 0.0]],
            vec![1e308; 2],
            vec![1.0; 2],
            RiverMode::Carve,
        ),
        "path",
        "overflowing extent",
    );

    let Some(hf) = terrain() else { return };
    let dict = small_dict(&hf, 12);
    let e = |s: EncodeSettings| encode(&hf, &dict, &s);
    let d = EncodeSettings::default();
    names(e(EncodeSettings { sparsity: 13, ..d }), "sparsity", "s > N");
    names(e(EncodeSettings { sparsity: 0, ..d }), "sparsity", "s = 0");
    names(
        e(EncodeSettings {
            tolerance: Some(-3.0),
            ..d
        }),
        "tolerance",
        "tolerance",
    );
    names(
        e(EncodeSettings {
            step: Some(f64::NAN),
            ..d
        }),
        "step",
        "NaN step",
    );
    names(
        e(EncodeSettings {
            step: Some(5.0),
            ..d
        }),
        "support_radius",
        "step too large for R",
    );
    let empty = Dictionary::new(6, 1.0, 3.0).unwrap();
    names(encode(&hf, &empty, &d), "dictionary", "empty dictionary");
    let sct = e(d).unwrap();
    let (fw, fh) = sct.raster_size(1.0).unwrap();
    names(
        sct.rasterize(&RasterSettings {
            scale: 1.0,
            window: Some(Window {
                x: fw - 2,
                y: 0,
                width: 3,
                height: 1,
            }),
        }),
        "window",
        "window past the edge",
    );
    let _ = fh;
}

#[test]
fn encode_is_identical_on_one_and_two_threads() {
    let Some(hf) = relief_testdata::dem_crop("alps_dem", 400, 600, 96, 72) else {
        return;
    };
    let p = extract_patches(&hf, &PatchGeometry::with_patch_size(8)).unwrap();
    let n = p.matrix.nrows();
    let sel: Vec<usize> = (0..64).map(|k| k * n / 64).collect();
    let dict = Arc::new(Dictionary::from_patches(&p, Some(&sel)).unwrap().0);
    let run = |threads: usize, s: usize| {
        relief_testdata::with_threads(threads, || {
            let sct = encode_shared(
                &hf,
                dict.clone(),
                &EncodeSettings {
                    sparsity: s,
                    tolerance: Some(1.0),
                    ..Default::default()
                },
            )
            .unwrap();
            let r = sct.rasterize(&RasterSettings::default()).unwrap();
            (sct.to_bytes().unwrap(), r)
        })
    };
    for s in [1, 4, 8] {
        let (a, ra) = run(1, s);
        let (b, rb) = run(2, s);
        assert_eq!(a, b, "s = {s}: .sct bytes differ between 1 and 2 threads");
        assert_eq!(
            ra.as_slice()
                .iter()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>(),
            rb.as_slice()
                .iter()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>()
        );
    }
}

/// Floats that break naive code: NaN, infinities, zero, negatives, tiny and huge values.
fn wild() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(0.0),
        Just(-1.0),
        Just(1e-300),
        Just(1e300),
        Just(f64::MAX),
        0.05f64..12.0,
        -12.0f64..12.0,
    ]
}

fn wild_usize() -> impl Strategy<Value = usize> {
    prop_oneof![
        Just(0usize),
        Just(usize::MAX),
        Just(1usize << 40),
        0usize..80,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    /// Random geometry and dictionary parameters: `check`, `grid`, `extract_patches`,
    /// `Dictionary::new`, `from_patches`, `encode` never panic, and an accepted geometry
    /// really is valid.
    #[test]
    fn random_geometry_never_panics(
        a in prop_oneof![Just(0usize), Just(300usize), 1usize..12],
        spacing in wild(),
        step in wild(),
        radius in wild(),
        sparsity in wild_usize(),
        tolerance in prop::option::of(wild()),
        w in 1usize..30,
        h in 1usize..30,
    ) {
        let hf = Heightfield::from_fn(w, h, 30.0, 30.0, |x, y| {
            ((x as f32) * 0.7).sin() * 40.0 + ((y as f32) * 0.45).cos() * 25.0 + (x * y) as f32
        });
        let g = PatchGeometry { patch_size: a, spacing, step, support_radius: radius };
        if g.check().is_ok() {
            prop_assert!(spacing.is_finite() && spacing > 0.0 && step.is_finite() && step > 0.0);
            prop_assert!(radius * radius > step * step / 2.0 && (1..=256).contains(&a));
        }
        let _ = g.grid(w, h);
        if let Ok(p) = extract_patches(&hf, &g) {
            prop_assert_eq!(p.matrix.ncols(), a * a);
            prop_assert!(p.matrix.iter().all(|v| v.is_finite()));
            if let Ok((dict, _)) = Dictionary::from_patches(&p, None) {
                let s = EncodeSettings { sparsity, tolerance, step: Some(step), ..EncodeSettings::default() };
                if let Ok(sct) = encode(&hf, &dict, &s) {
                    prop_assert!((1..=64).contains(&sparsity) && sparsity <= dict.len());
                    let r = sct.rasterize(&RasterSettings::default()).unwrap();
                    prop_assert_eq!((r.width(), r.height()), (w, h));
                }
            }
        }
        let _ = Dictionary::new(a, spacing, radius);
    }

    /// Random OMP settings and signals (NaN included) on both solvers and both precisions.
    #[test]
    fn random_omp_settings_never_panic(
        sparsity in wild_usize(),
        tolerance in prop::option::of(wild()),
        n_atoms in 0usize..12,
        dim in 0usize..10,
        n_signals in 0usize..6,
        poison in any::<bool>(),
        seed in any::<u64>(),
    ) {
        let mut state = seed | 1;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut d = Array2::<f64>::from_shape_fn((n_atoms, dim), |_| next());
        for mut row in d.outer_iter_mut() {
            let n = row.dot(&row).sqrt();
            if n > 0.0 {
                row.mapv_inplace(|v| v / n);
            }
        }
        let mut x = Array2::<f64>::from_shape_fn((n_signals, dim), |_| next());
        if poison && n_signals > 0 && dim > 0 {
            x[[0, 0]] = f64::NAN;
        }
        let s = OmpSettings { sparsity, tolerance };
        let r64 = batch_omp(d.view(), x.view(), &s);
        let _ = omp_reference(d.view(), x.view(), &s);
        let d32 = d.mapv(|v| v as f32);
        let x32 = x.mapv(|v| v as f32);
        let _ = batch_omp(d32.view(), x32.view(), &s);
        let _ = omp_reference(d32.view(), x32.view(), &s);
        if let Ok(codes) = r64 {
            prop_assert!(!poison || n_signals == 0 || dim == 0);
            prop_assert!((1..=64).contains(&sparsity) && sparsity <= n_atoms);
            for i in 0..codes.n_signals() {
                prop_assert!(codes.signal(i).0.len() <= sparsity);
            }
        }
    }

    /// Random raster settings, tree sizes, rivers and regions: `Sct::new`, `rasterize`,
    /// `eval`, `raster_size`, `River::new`, `compression_report` never panic.
    #[test]
    fn random_tree_and_raster_settings_never_panic(
        scale in wild(),
        win in prop::option::of((wild_usize(), wild_usize(), wild_usize(), wild_usize())),
        width in wild_usize(),
        height in wild_usize(),
        cell in wild(),
        river in prop::collection::vec((wild(), wild(), wild(), wild()), 0..4),
        region in (wild(), wild(), wild(), wild()),
        falloff in wild(),
        quantize in any::<bool>(),
    ) {
        let n = river.len();
        let path: Vec<[f64; 2]> = river.iter().map(|r| [r.0, r.1]).collect();
        let hw: Vec<f64> = river.iter().map(|r| r.2).collect();
        let dp: Vec<f64> = river.iter().map(|r| r.3).collect();
        let leaf = match River::new(path, hw, dp, RiverMode::Carve) {
            Ok(r) => {
                prop_assert!(n >= 2);
                Node::River(r)
            }
            Err(_) => Node::Constant(3.0),
        };
        let tree = Node::Replace {
            base: Box::new(Node::Add(vec![Node::Constant(100.0), leaf])),
            overlay: Box::new(Node::Constant(0.0)),
            region: Region::Rect { x0: region.0, y0: region.1, x1: region.2, y1: region.3 },
            falloff,
        };
        // Sizes are capped so that accepted rasters stay small in the test.
        let (w, h) = (width.min(1 << 25), height.min(1 << 25));
        if let Ok(t) = Sct::new(tree, w, h, (cell, cell)) {
            prop_assert!((1..=1 << 24).contains(&w) && (1..=1 << 24).contains(&h));
            let _ = t.eval(1.5, 2.5);
            let _ = t.raster_size(scale);
            let window = win.map(|(x, y, ww, wh)| Window {
                x,
                y,
                width: ww.min(64),
                height: wh.min(64),
            });
            let rs = RasterSettings { scale, window };
            // Only rasterise what is small (a full raster of a 2^24-wide tree is legal).
            let small = match (window, t.raster_size(scale)) {
                (Some(_), _) => true,
                (None, Ok((fw, fh))) => fw * fh <= 1 << 16,
                (None, Err(_)) => true,
            };
            if small && let Ok(r) = t.rasterize(&rs) {
                prop_assert!(scale.is_finite() && scale > 0.0 && scale <= 1024.0);
                prop_assert!(r.width() * r.height() <= 1 << 16);
            }
            if w * h <= 1 << 12 {
                let original = Heightfield::from_fn(w, h, 1.0, 1.0, |x, y| (x + 2 * y) as f32);
                let _ = compression_report(
                    &original,
                    &t,
                    &FormatOptions { quantize_coefficients: quantize },
                    &FunctionAtomRegistry::new(),
                );
            }
        }
    }
}
