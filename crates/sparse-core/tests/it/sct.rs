//! Sparse Construction Tree on real DEM crops: exact reconstruction, compression at
//! s = 1, 2, 8, tiling / scale determinism, operators and rivers, the `.sct` format.

use std::sync::Arc;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use relief_heightfield::{Heightfield, metrics};
use relief_sparse_core::dictionary::{AtomDescriptor, FunctionAtom};
use relief_sparse_core::{
    CompressionReport, Dictionary, EncodeSettings, FormatOptions, FunctionAtomRegistry, Node,
    PatchGeometry, Placement, RasterSettings, Region, River, RiverMode, Sct, SparseError,
    SparseLayer, Window, compression_report, encode, extract_patches, raster_coord, storage_values,
};

fn crop(id: &str, x: usize, y: usize, w: usize, h: usize) -> Option<Heightfield> {
    relief_testdata::dem_crop(id, x, y, w, h)
}

/// Encoding settings of sparsity `s`, the rest default.
/// The whole raster of `sct` at `scale`.
fn raster(sct: &Sct, scale: f64) -> Heightfield {
    sct.rasterize(&RasterSettings {
        scale,
        window: None,
    })
    .unwrap()
}

fn sparsity(s: usize) -> EncodeSettings {
    EncodeSettings {
        sparsity: s,
        ..Default::default()
    }
}

/// The compression report of `sct` against `hf` (no function atoms).
fn report(hf: &Heightfield, sct: &Sct, quantize_coefficients: bool) -> CompressionReport {
    let options = FormatOptions {
        quantize_coefficients,
    };
    compression_report(hf, sct, &options, &FunctionAtomRegistry::new()).unwrap()
}

/// A dictionary of `n` patches of `hf` picked at random (seeded), as the paper's K-SVD starts.
fn random_patch_dictionary(hf: &Heightfield, a: usize, n: usize, seed: u64) -> Dictionary {
    let p = extract_patches(hf, &PatchGeometry::with_patch_size(a)).unwrap();
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut sel = Vec::new();
    while sel.len() < n {
        let i = rng.random_range(0..p.matrix.nrows());
        if !sel.contains(&i) {
            sel.push(i);
        }
    }
    Dictionary::from_patches(&p, Some(&sel)).unwrap().0
}

#[test]
fn complete_dictionary_s1_reconstructs_exactly() {
    for (id, x, y) in [
        ("grandcanyon", 200, 180),
        ("alps_dem", 1200, 300),
        ("carrizo", 100, 400),
    ] {
        let Some(hf) = crop(id, x, y, 72, 60) else {
            return;
        };
        let p = extract_patches(&hf, &PatchGeometry::with_patch_size(8)).unwrap();
        let (dict, _) = Dictionary::from_patches(&p, None).unwrap();
        let sct = encode(&hf, &dict, &sparsity(1)).unwrap();
        let rec = sct.rasterize(&RasterSettings::default()).unwrap();
        let err = metrics::max_abs_diff(&hf, &rec).unwrap();
        let relief = hf.relief() as f64;
        assert!(
            err <= 2e-5 * relief.max(100.0) + 1e-3,
            "{id}: max error {err} m"
        );
    }
}

#[test]
fn compression_psnr_increases_with_sparsity() {
    let Some(hf) = crop("grandcanyon", 128, 128, 128, 128) else {
        return;
    };
    let dict = random_patch_dictionary(&hf, 8, 128, 5);
    assert_eq!(dict.len(), 128);
    let mut last = f64::NEG_INFINITY;
    let mut last_rho = 0.0;
    for s in [1usize, 2, 8] {
        let sct = encode(&hf, &dict, &sparsity(s)).unwrap();
        let r = report(&hf, &sct, false);
        let layer = sct.layers()[0];
        assert_eq!(r.t, storage_values(64, 128, layer.len(), s));
        assert_eq!(r.t0, 128 * 128);
        assert!((r.rho - r.t as f64 / r.t0 as f64).abs() < 1e-12);
        assert_eq!(r.bytes, sct.to_bytes().unwrap().len());
        assert!(r.psnr > last + 0.5, "s = {s}: PSNR {} after {last}", r.psnr);
        assert!(r.rho > last_rho);
        assert!(r.psnr > 20.0, "s = {s}: PSNR {}", r.psnr);
        last = r.psnr;
        last_rho = r.rho;
    }
    // Quantised coefficients: smaller and almost as good.
    let sct = encode(&hf, &dict, &sparsity(2)).unwrap();
    let f = report(&hf, &sct, false);
    let q = report(&hf, &sct, true);
    assert!(q.bytes < f.bytes);
    assert!(q.psnr > f.psnr - 1.0, "{} vs {}", q.psnr, f.psnr);
}

fn alps_sct(s: usize) -> Option<(Heightfield, Sct)> {
    let hf = crop("alps_dem", 600, 200, 90, 70)?;
    let dict = random_patch_dictionary(&hf, 8, 64, 9);
    let sct = encode(&hf, &dict, &sparsity(s)).unwrap();
    Some((hf, sct))
}

#[test]
fn window_alone_equals_full_raster_bit_for_bit() {
    let Some((_, sct)) = alps_sct(4) else { return };
    for scale in [1.0, 2.5, 0.5, 3.0] {
        let full = raster(&sct, scale);
        let (w, h) = sct.raster_size(scale).unwrap();
        assert_eq!((full.width(), full.height()), (w, h));
        assert!(!full.has_voids(), "the weights cover the whole domain");
        for (x, y, ww, wh) in [
            (0, 0, 7, 5),
            (w / 3, h / 4, w / 2, h / 3),
            (w - 9, h - 17, 9, 17),
        ] {
            let win = Window {
                x,
                y,
                width: ww,
                height: wh,
            };
            let part = sct
                .rasterize(&RasterSettings {
                    scale,
                    window: Some(win),
                })
                .unwrap();
            for r in 0..wh {
                for c in 0..ww {
                    assert_eq!(
                        part.get(c, r).to_bits(),
                        full.get(x + c, y + r).to_bits(),
                        "scale {scale} window {win:?} pixel ({c}, {r})"
                    );
                }
            }
        }
        // Point evaluation is the same function.
        for (c, r) in [(0, 0), (w - 1, h - 1), (w / 2, h / 3), (3, h - 2)] {
            let v = sct.eval(raster_coord(c, scale), raster_coord(r, scale)) as f32;
            assert_eq!(v.to_bits(), full.get(c, r).to_bits(), "eval at ({c}, {r})");
        }
    }
    // Independent of the number of threads.
    let run = |t| relief_testdata::with_threads(t, || raster(&sct, 1.7));
    assert_eq!(run(1).as_slice(), run(2).as_slice());
}

/// At a large scale a primitive's support spans more pixels than the rasteriser caches whole
/// (its offsets are then cached per band): the pixels are still the point evaluations, bit for
/// bit, and a window inside a window gives the same pixels.
#[test]
fn large_scale_windows_are_point_evaluations() {
    let Some((_, sct)) = alps_sct(4) else { return };
    let scale = 40.0;
    let (w, h) = sct.raster_size(scale).unwrap();
    let win = Window {
        x: w / 3,
        y: h / 2 - 37,
        width: 96,
        height: 150,
    };
    let at = |win: Window| {
        sct.rasterize(&RasterSettings {
            scale,
            window: Some(win),
        })
        .unwrap()
    };
    let part = at(win);
    for r in 0..win.height {
        for c in 0..win.width {
            let (x, y) = (
                raster_coord(win.x + c, scale),
                raster_coord(win.y + r, scale),
            );
            let v = sct.eval(x, y) as f32;
            assert_eq!(v.to_bits(), part.get(c, r).to_bits(), "pixel ({c}, {r})");
        }
    }
    let inner = at(Window {
        x: win.x + 5,
        y: win.y + 70,
        width: 40,
        height: 3,
    });
    for r in 0..3 {
        for c in 0..40 {
            assert_eq!(inner.get(c, r).to_bits(), part.get(c + 5, r + 70).to_bits());
        }
    }
}

#[test]
fn upscaled_raster_is_continuous_and_consistent() {
    let Some((hf, sct)) = alps_sct(8) else { return };
    let big = raster(&sct, 4.0);
    // Pixel-is-area: the x4 raster covers the same extent with 4 x 4 cells per input cell.
    let one = sct.rasterize(&RasterSettings::default()).unwrap();
    assert_eq!(
        (big.width(), big.height()),
        (4 * one.width(), 4 * one.height())
    );
    let (mut max_in, mut max_out) = (0f32, 0f32);
    for r in 0..hf.height() {
        for c in 1..hf.width() {
            max_in = max_in.max((hf.get(c, r) - hf.get(c - 1, r)).abs());
        }
    }
    // The four central x4 samples of a cell straddle its centre (+-1/8 cell): their mean is
    // the scale-1 value up to second-order terms.
    for r in 0..one.height() {
        for c in 0..one.width() {
            let m = (big.get(4 * c + 1, 4 * r + 1)
                + big.get(4 * c + 2, 4 * r + 1)
                + big.get(4 * c + 1, 4 * r + 2)
                + big.get(4 * c + 2, 4 * r + 2))
                / 4.0;
            let d = (m - one.get(c, r)).abs();
            assert!(
                d < 0.02 * max_in,
                "({c}, {r}): {d} (steepest step {max_in})"
            );
        }
    }
    // No jumps: neighbouring x4 samples differ by less than the steepest input step.
    for r in 0..big.height() {
        for c in 1..big.width() {
            max_out = max_out.max((big.get(c, r) - big.get(c - 1, r)).abs());
        }
    }
    assert!(max_out < max_in, "x4 step {max_out} vs input step {max_in}");
}

#[test]
fn spatial_index_visits_only_nearby_primitives() {
    let Some((_, sct)) = alps_sct(2) else { return };
    let layer = sct.layers()[0];
    let r2 = layer.dictionary().support_radius().powi(2);
    let mut rng = Pcg64::seed_from_u64(3);
    for _ in 0..500 {
        let (x, y) = (rng.random::<f64>() * 89.0, rng.random::<f64>() * 69.0);
        let brute: Vec<usize> = (0..layer.len())
            .filter(|&i| {
                let c = layer.centre(i);
                (x - c[0]).powi(2) + (y - c[1]).powi(2) < r2
            })
            .collect();
        assert_eq!(layer.primitives_at(x, y), brute);
        assert!(!brute.is_empty());
        // The index visits a small constant number of candidates, not all primitives.
        assert!(
            layer.candidates_at(x, y) <= 16,
            "{}",
            layer.candidates_at(x, y)
        );
    }
    assert!(layer.len() > 300);
}

#[test]
fn operators_and_river() {
    let Some((hf, sct)) = alps_sct(4) else { return };
    let base = sct.root().clone();
    let (w, h) = (hf.width(), hf.height());
    let path = vec![[5.0, 10.0], [40.0, 35.0], [85.0, 30.0]];
    let carve = River::new(
        path.clone(),
        vec![4.0, 6.0, 8.0],
        vec![20.0, 25.0, 30.0],
        RiverMode::Carve,
    )
    .unwrap();
    let tree = Node::Add(vec![base.clone(), Node::River(carve)]);
    let t = Sct::new(tree, w, h, hf.cell_size()).unwrap();
    // On the path the carve is the full (interpolated) depth; far away nothing changes.
    let on = t.eval(40.0, 35.0) - sct.eval(40.0, 35.0);
    assert!((on + 25.0).abs() < 1e-9, "{on}");
    let mid = t.eval(22.5, 22.5) - sct.eval(22.5, 22.5);
    assert!((mid + 22.5).abs() < 1e-9, "{mid}");
    assert_eq!(t.eval(80.0, 60.0), sct.eval(80.0, 60.0));
    let ras = t.rasterize(&RasterSettings::default()).unwrap();
    assert_eq!(
        ras.get(40, 35).to_bits(),
        (t.eval(40.0, 35.0) as f32).to_bits()
    );

    // Bed mode under Min: the terrain never rises above the bed surface.
    let bed = River::new(
        path,
        vec![5.0; 3],
        vec![50.0; 3],
        RiverMode::Bed(vec![
            hf.get(5, 10) as f64 - 30.0,
            hf.get(40, 35) as f64 - 30.0,
            hf.get(85, 30) as f64 - 30.0,
        ]),
    )
    .unwrap();
    let bed_node = Node::River(bed.clone());
    let t = Sct::new(
        Node::Min(vec![base.clone(), bed_node]),
        w,
        h,
        hf.cell_size(),
    )
    .unwrap();
    let v = t.eval(40.0, 35.0);
    assert!((v - (hf.get(40, 35) as f64 - 30.0)).abs() < 1e-9);
    for (x, y) in [(3.0, 60.0), (60.0, 5.0), (20.0, 20.0)] {
        assert!(t.eval(x, y) <= bed.eval(x, y) + 1e-12 && t.eval(x, y) <= sct.eval(x, y) + 1e-12);
    }
    let t = Sct::new(
        Node::Max(vec![base.clone(), Node::Constant(1e6)]),
        w,
        h,
        hf.cell_size(),
    )
    .unwrap();
    assert_eq!(t.eval(10.0, 10.0), 1e6);

    // Replace in a disk: overlay inside, base outside, in between inside the fall-off.
    let rep = Node::Replace {
        base: Box::new(base.clone()),
        overlay: Box::new(Node::Constant(0.0)),
        region: Region::Disk {
            cx: 45.0,
            cy: 35.0,
            r: 10.0,
        },
        falloff: 5.0,
    };
    let t = Sct::new(rep, w, h, hf.cell_size()).unwrap();
    assert_eq!(t.eval(45.0, 38.0), 0.0);
    assert_eq!(t.eval(45.0, 51.0), sct.eval(45.0, 51.0));
    let mid = t.eval(45.0, 47.5);
    assert!(mid > 0.0 && mid < sct.eval(45.0, 47.5));
    // A rasterised window of the composite tree equals its point evaluation.
    let win = t
        .rasterize(&RasterSettings {
            scale: 2.0,
            window: Some(Window {
                x: 60,
                y: 50,
                width: 50,
                height: 40,
            }),
        })
        .unwrap();
    for (c, r) in [(0usize, 0usize), (30, 20), (49, 39)] {
        let v = t.eval(raster_coord(60 + c, 2.0), raster_coord(50 + r, 2.0)) as f32;
        assert_eq!(v.to_bits(), win.get(c, r).to_bits());
    }

    // Blend of two identical layers is the layer.
    let t = Sct::new(Node::Blend(vec![base.clone(), base]), w, h, hf.cell_size()).unwrap();
    assert!((t.eval(33.3, 44.4) - sct.eval(33.3, 44.4)).abs() < 1e-9);
    assert!(Node::Add(vec![]).check().is_err());
    assert!(River::new(vec![[0.0, 0.0]], vec![1.0], vec![1.0], RiverMode::Carve).is_err());
    assert!(
        River::new(
            vec![[0.0, 0.0], [1.0, 1.0]],
            vec![0.0, 1.0],
            vec![1.0, 1.0],
            RiverMode::Carve
        )
        .is_err()
    );
}

#[derive(Debug)]
struct Ridge {
    freq: f64,
    angle: f64,
}

impl FunctionAtom for Ridge {
    fn eval(&self, u: f64, v: f64) -> f64 {
        let t = u * self.angle.cos() + v * self.angle.sin();
        1.0 - (self.freq * t).sin().abs()
    }
    fn descriptor(&self) -> AtomDescriptor {
        AtomDescriptor {
            kind: "ridge".into(),
            params: vec![self.freq, self.angle],
        }
    }
}

/// The fuzz target's registry: one `ridge` kind with two finite parameters.
fn registry() -> FunctionAtomRegistry {
    let mut r = FunctionAtomRegistry::new();
    r.register("ridge", |p: &[f64]| {
        if p.len() != 2 || !p.iter().all(|x| x.is_finite()) {
            return Err(SparseError::param("ridge params", p.len(), "need 2 finite"));
        }
        Ok(Arc::new(Ridge {
            freq: p[0],
            angle: p[1],
        }) as Arc<dyn FunctionAtom>)
    });
    r
}

#[test]
fn mixed_dictionary_and_format_round_trip() {
    let Some(hf) = crop("grandcanyon", 300, 300, 64, 48) else {
        return;
    };
    let mut dict = random_patch_dictionary(&hf, 8, 4, 1);
    for k in 0..16 {
        dict.push_function(Arc::new(Ridge {
            freq: 1.0 + k as f64 * 0.5,
            angle: k as f64 * 0.4,
        }))
        .unwrap();
    }
    let d = dict.discretize();
    for row in d.outer_iter() {
        assert!((row.dot(&row) - 1.0).abs() < 1e-4);
    }
    let sct = encode(&hf, &dict, &sparsity(4)).unwrap();
    let layer = sct.layers()[0];
    assert!(
        layer.atom_indices().iter().any(|&j| j >= 4),
        "function atoms are used"
    );
    // Wrap in a tree to cover every node kind in the format.
    let river = River::new(
        vec![[2.0, 3.0], [60.0, 40.0]],
        vec![3.0, 4.0],
        vec![5.0, 6.0],
        RiverMode::Carve,
    )
    .unwrap();
    let tree = Node::Replace {
        base: Box::new(Node::Add(vec![sct.root().clone(), Node::River(river)])),
        overlay: Box::new(Node::Max(vec![
            Node::Constant(1.0),
            Node::Min(vec![Node::Blend(vec![sct.root().clone()])]),
        ])),
        region: Region::Rect {
            x0: 10.0,
            y0: 10.0,
            x1: 20.0,
            y1: 15.0,
        },
        falloff: 3.0,
    };
    let t = Sct::new(tree, hf.width(), hf.height(), hf.cell_size()).unwrap();
    let bytes = t.to_bytes().unwrap();
    let back = Sct::from_bytes(&bytes, &registry()).unwrap();
    assert_eq!(back.to_bytes().unwrap(), bytes);
    let a = raster(&t, 1.5);
    let b = raster(&back, 1.5);
    assert_eq!(a.as_slice(), b.as_slice());
    // Without the registry the function atoms cannot be rebuilt.
    assert!(matches!(
        Sct::from_bytes(&bytes, &FunctionAtomRegistry::new()),
        Err(SparseError::Format { .. })
    ));
    // Every truncation is an error, never a panic, and every single-byte change is caught by
    // the checksum (format version 3), never decoded into a model with other values.
    let prefixes = (0..bytes.len()).step_by(7).chain([bytes.len() - 1]);
    relief_testdata::assert_truncations_and_flips_refused(&bytes, prefixes, 0x5a, |b| {
        Sct::from_bytes(b, &registry())
    });
    // Trailing garbage, bad magic, bad version.
    let mut long = bytes.clone();
    long.push(0);
    assert!(Sct::from_bytes(&long, &registry()).is_err());
    let mut bad = bytes.clone();
    bad[0] = b'X';
    assert!(Sct::from_bytes(&bad, &registry()).is_err());
    let mut bad = bytes.clone();
    bad[8] = 9;
    assert!(Sct::from_bytes(&bad, &registry()).is_err());
    // Random byte flips never panic.
    let mut rng = Pcg64::seed_from_u64(77);
    for _ in 0..300 {
        let mut c = bytes.clone();
        for _ in 0..3 {
            let i = rng.random_range(0..c.len());
            c[i] = rng.random();
        }
        let _ = Sct::from_bytes(&c, &registry());
    }
}

#[test]
fn hostile_declared_sizes_are_rejected_before_allocation() {
    let Some((_, sct)) = alps_sct(1) else { return };
    let bytes = sct.to_bytes().unwrap();
    // Header: 8 magic + 2 version + 2 flags + 4 w + 4 h + 16 cell = 36; node tag at 36; then
    // a u16, delta f64, R f64, N u32 at 37 + 2 + 16 = 55.
    // The edited streams are re-sealed with a valid checksum, so the reader's own checks are
    // what refuses them.
    let mut c = bytes.clone();
    c[55..59].copy_from_slice(&u32::MAX.to_le_bytes());
    reseal(&mut c);
    let e = Sct::from_bytes(&c, &registry()).unwrap_err();
    assert!(matches!(e, SparseError::Format { .. }), "{e}");
    assert!(!e.to_string().contains("checksum"), "{e}");
    let mut c = bytes.clone();
    c[37..39].copy_from_slice(&0u16.to_le_bytes());
    reseal(&mut c);
    assert!(Sct::from_bytes(&c, &registry()).is_err());
}

/// Rewrites the trailing CRC-32 of an edited stream.
fn reseal(bytes: &mut [u8]) {
    let n = bytes.len() - 4;
    let crc = relief_sparse_core::format::crc32(&bytes[..n]);
    bytes[n..].copy_from_slice(&crc.to_le_bytes());
}

#[test]
fn invalid_inputs_are_errors() {
    let Some(hf) = crop("maunga_whau", 0, 0, 60, 40) else {
        return;
    };
    let dict = random_patch_dictionary(&hf, 8, 16, 2);
    let s = |sparsity| EncodeSettings {
        sparsity,
        ..Default::default()
    };
    assert!(matches!(
        encode(&hf, &dict, &s(17)),
        Err(SparseError::SparsityTooLarge { .. })
    ));
    assert!(encode(&hf, &dict, &s(0)).is_err());
    let mut holes = hf.clone();
    holes.set(3, 3, f32::NAN);
    assert!(encode(&holes, &dict, &s(1)).is_err());
    let empty = Dictionary::new(8, 1.0, 4.0).unwrap();
    assert!(matches!(
        encode(&hf, &empty, &s(1)),
        Err(SparseError::EmptyDictionary { .. })
    ));
    let g = PatchGeometry {
        step: 7.0,
        ..PatchGeometry::with_patch_size(8)
    };
    assert!(matches!(
        g.check(),
        Err(SparseError::InvalidParameter {
            name: "support_radius",
            ..
        })
    ));
    assert!(Dictionary::new(0, 1.0, 4.0).is_err());
    assert!(Dictionary::new(8, -1.0, 4.0).is_err());
    let mut d = Dictionary::new(4, 1.0, 2.0).unwrap();
    assert!(matches!(
        d.push_data(&[1.0; 16]),
        Err(SparseError::DegenerateAtom { .. })
    ));
    assert!(d.push_data(&[1.0; 15]).is_err());
    let sct = encode(&hf, &dict, &s(2)).unwrap();
    let bad_win = Window {
        x: 50,
        y: 0,
        width: 20,
        height: 5,
    };
    assert!(
        sct.rasterize(&RasterSettings {
            scale: 1.0,
            window: Some(bad_win)
        })
        .is_err()
    );
    assert!(
        sct.rasterize(&RasterSettings {
            scale: 0.0,
            window: None
        })
        .is_err()
    );
    assert!(
        sct.rasterize(&RasterSettings {
            scale: f64::NAN,
            window: None
        })
        .is_err()
    );
    let layer = sct.layers()[0].clone();
    assert!(
        SparseLayer::from_parts(
            layer.dictionary().clone(),
            Placement::Explicit(vec![[0.0, 0.0]]),
            vec![1.0],
            vec![0, 1],
            vec![99],
            vec![1.0],
        )
        .is_err()
    );
}

#[test]
fn non_unit_spacing_and_tolerance() {
    let Some(hf) = crop("jacksboro_fault", 40, 40, 96, 80) else {
        return;
    };
    // Atoms of 8 x 8 samples every 1.5 cells: the patch samples fall between terrain samples
    // (bicubic extraction) and the reconstruction interpolates the atoms.
    let g = PatchGeometry {
        patch_size: 8,
        spacing: 1.5,
        step: 6.0,
        support_radius: 6.0,
    };
    let p = extract_patches(&hf, &g).unwrap();
    let (dict, _) = Dictionary::from_patches(&p, None).unwrap();
    let settings = EncodeSettings {
        sparsity: 1,
        step: Some(6.0),
        ..Default::default()
    };
    let sct = encode(&hf, &dict, &settings).unwrap();
    let rec = sct.rasterize(&RasterSettings::default()).unwrap();
    let psnr = metrics::psnr(&hf, &rec).unwrap();
    assert!(psnr > 35.0, "PSNR {psnr}");
    // A residual tolerance uses fewer coefficients than the sparsity cap, at a bounded error.
    let dict = random_patch_dictionary(&hf, 8, 96, 4);
    let capped = encode(&hf, &dict, &sparsity(12)).unwrap();
    let tol = 8.0 * 64.0; // mean squared error of 8 m^2 per sample over a patch
    let tolerant = encode(
        &hf,
        &dict,
        &EncodeSettings {
            sparsity: 12,
            tolerance: Some(tol),
            ..Default::default()
        },
    )
    .unwrap();
    let (a, b) = (capped.layers()[0], tolerant.layers()[0]);
    assert!(b.atom_indices().len() < a.atom_indices().len());
    let rb = tolerant.rasterize(&RasterSettings::default()).unwrap();
    let rmse = metrics::rmse(&hf, &rb).unwrap();
    assert!(rmse < 8f64.sqrt() * 1.5, "rmse {rmse}");
}

#[derive(Default)]
struct Counter(
    std::sync::atomic::AtomicU64,
    std::sync::Mutex<Vec<(String, u64)>>,
);

impl relief_heightfield::Progress for Counter {
    fn begin(&self, phase: &str, total: u64) {
        self.1.lock().unwrap().push((phase.to_string(), total));
        self.0.store(0, std::sync::atomic::Ordering::SeqCst);
    }
    fn advance(&self, n: u64) {
        self.0.fetch_add(n, std::sync::atomic::Ordering::SeqCst);
    }
}

#[test]
fn progress_is_reported() {
    let Some(hf) = crop("carrizo", 50, 50, 64, 64) else {
        return;
    };
    let dict = Arc::new(random_patch_dictionary(&hf, 8, 32, 6));
    let c = Counter::default();
    let sct = relief_sparse_core::encode_with_progress(&hf, dict, &EncodeSettings::default(), &c)
        .unwrap();
    let n = sct.layers()[0].len() as u64;
    assert_eq!(c.0.load(std::sync::atomic::Ordering::SeqCst), n);
    assert_eq!(
        c.1.lock().unwrap().last().unwrap(),
        &("batch-omp".to_string(), n)
    );
    let c = Counter::default();
    let r = sct
        .rasterize_with_progress(
            &RasterSettings {
                scale: 2.0,
                window: None,
            },
            &c,
        )
        .unwrap();
    assert_eq!(
        c.0.load(std::sync::atomic::Ordering::SeqCst),
        r.height() as u64
    );
}

/// Format version 2 stores the georeference; rasters inherit it (scaled and shifted to their
/// window); version-1 streams (no georeference block) still read.
#[test]
fn georeference_round_trips_and_reaches_rasters() {
    use relief_heightfield::GeoRef;
    use relief_sparse_core::{FunctionAtomRegistry, Node, RasterSettings, Sct, Window};
    let g = GeoRef {
        pixel_scale: Some(vec![30.0, 30.0, 0.0]),
        tiepoints: Some(vec![0.0, 0.0, 0.0, 500_000.0, 4_000_000.0, 0.0]),
        geo_key_directory: Some(vec![1, 1, 0, 1, 3072, 0, 1, 32611]),
        crs: Some("EPSG:32611".into()),
        geotransform: Some([500_000.0, 30.0, 0.0, 4_000_000.0, 0.0, -30.0]),
        ..Default::default()
    };
    let sct = Sct::new(Node::Constant(5.0), 16, 8, (30.0, 30.0))
        .unwrap()
        .with_georef(Some(g.clone()));
    let reg = FunctionAtomRegistry::new();
    let bytes = sct.to_bytes().unwrap();
    let back = Sct::from_bytes(&bytes, &reg).unwrap();
    assert_eq!(back.georef(), Some(&g));
    // A truncated georeference block is an error, not a panic.
    assert!(Sct::from_bytes(&bytes[..50], &reg).is_err());
    let r = back
        .rasterize(&RasterSettings {
            scale: 1.0,
            window: Some(Window {
                x: 2,
                y: 3,
                width: 4,
                height: 4,
            }),
        })
        .unwrap();
    let t = r.georef().unwrap().geotransform.unwrap();
    assert_eq!(t, [500_060.0, 30.0, 0.0, 3_999_910.0, 0.0, -30.0]);
    // Scale 2 (pixel-is-area): cells of 15 m tiling the same extent from the same corner.
    let r2 = raster(&back, 2.0);
    let t2 = r2.georef().unwrap().geotransform.unwrap();
    assert_eq!(t2, [500_000.0, 15.0, 0.0, 4_000_000.0, 0.0, -15.0]);
    assert_eq!(
        (r2.width(), r2.height()),
        (2 * back.width(), 2 * back.height())
    );
    // A version-1 stream: same header without the georeference block.
    let plain = Sct::new(Node::Constant(5.0), 16, 8, (30.0, 30.0)).unwrap();
    let mut v1 = plain.to_bytes().unwrap();
    assert_eq!(v1[36], 0, "no-georeference flag");
    v1.truncate(v1.len() - 4);
    v1.remove(36);
    v1[8..10].copy_from_slice(&1u16.to_le_bytes());
    let old = Sct::from_bytes(&v1, &reg).unwrap();
    assert!(old.georef().is_none());
    assert_eq!(old.eval(3.0, 3.0), 5.0);
    // A version-2 stream: the georeference block, no checksum.
    let mut v2 = sct_geo_bytes_v2(&plain);
    let two = Sct::from_bytes(&v2, &reg).unwrap();
    assert_eq!(two.eval(3.0, 3.0), 5.0);
    v2.push(0);
    assert!(Sct::from_bytes(&v2, &reg).is_err(), "trailing byte");
}

/// The version-2 bytes of `sct` (version 3 without its checksum).
fn sct_geo_bytes_v2(sct: &Sct) -> Vec<u8> {
    let mut b = sct.to_bytes().unwrap();
    b.truncate(b.len() - 4);
    b[8..10].copy_from_slice(&2u16.to_le_bytes());
    b
}

/// Regression inputs found by fuzzing `Sct::from_bytes` (+ re-encode + rasterise), the
/// `fuzz/fuzz_targets/sct.rs` target: each file in `tests/fuzz_regressions/` once made the
/// decoder or the rasteriser overflow (huge centres, tiny spacings). They must now decode to an
/// error, or to a tree that re-encodes identically and rasterises without panicking.
#[test]
fn fuzz_crash_inputs_are_handled() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_regressions");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(files.len() >= 16, "{} files", files.len());
    let reg = registry();
    for f in files {
        let data = std::fs::read(&f).unwrap();
        if let Ok(sct) = Sct::from_bytes(&data, &reg) {
            let again = sct.to_bytes().unwrap();
            let back = Sct::from_bytes(&again, &reg).unwrap();
            assert_eq!(back.to_bytes().unwrap(), again, "{}", f.display());
            if sct.width() * sct.height() <= 4096 {
                let _ = sct.rasterize(&RasterSettings::default());
                let _ = sct.rasterize(&RasterSettings {
                    scale: 2.5,
                    window: None,
                });
            }
            let _ = sct.eval(0.5, 0.5);
        }
    }
}
