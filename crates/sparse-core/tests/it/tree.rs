//! Construction-tree nodes (guerin2016 section 5.4) on a real DEM crop: every node kind
//! (layer, constant, river carve and bed, field with each kernel, blend, add, max, min, replace
//! in a rectangle and in a disk) is rasterised by stamping, and the raster equals point evaluation `f(p)` at every pixel,
//! bit for bit, for any window, scale and thread count. Random trees (proptest) too.

use proptest::prelude::*;
use relief_heightfield::{Heightfield, Kernel};
use relief_sparse_core::{
    Dictionary, EncodeSettings, Field, Node, PatchGeometry, RasterSettings, Region, River,
    RiverMode, Sct, Window, encode, extract_patches, raster_coord,
};

/// The crop the tests build on and its s = 3 tree ([`layer`]), or `None` without the DEM set.
fn crop_and_layer() -> Option<(Heightfield, Node)> {
    let hf = relief_testdata::dem_crop("grandcanyon", 150, 220, 80, 64)?;
    let base = layer(&hf);
    Some((hf, base))
}

/// The model of `tree` over the grid of the crop `hf`.
fn on_crop(hf: &Heightfield, tree: Node) -> Sct {
    Sct::new(tree, hf.width(), hf.height(), hf.cell_size()).unwrap()
}

/// `base` carved by `carve`, replaced by the constant `overlay` inside `region`.
fn carved_and_replaced(
    base: &Node,
    carve: River,
    overlay: f64,
    region: Region,
    falloff: f64,
) -> Node {
    Node::Replace {
        base: Box::new(Node::Add(vec![base.clone(), Node::River(carve)])),
        overlay: Box::new(Node::Constant(overlay)),
        region,
        falloff,
    }
}

/// The river of [`river_path`] carving 3 m deep and 15 m wide all along.
fn plain_carve() -> River {
    let n = river_path().len();
    River::new(river_path(), vec![3.0; n], vec![15.0; n], RiverMode::Carve).unwrap()
}

/// The s = 3 tree of the crop over 48 sampled patches (8 x 8).
fn layer(hf: &Heightfield) -> Node {
    let p = extract_patches(hf, &PatchGeometry::with_patch_size(8)).unwrap();
    let n = p.matrix.nrows();
    let sel: Vec<usize> = (0..48).map(|k| k * n / 48).collect();
    let (dict, _) = Dictionary::from_patches(&p, Some(&sel)).unwrap();
    let sct = encode(
        hf,
        &dict,
        &EncodeSettings {
            sparsity: 3,
            ..Default::default()
        },
    )
    .unwrap();
    sct.root().clone()
}

/// The whole raster of `t` at `scale`.
fn raster(t: &Sct, scale: f64) -> Heightfield {
    t.rasterize(&RasterSettings {
        scale,
        window: None,
    })
    .unwrap()
}

/// Asserts raster == eval at every pixel of the full raster and of a window, at `scale`.
fn assert_raster_is_eval(t: &Sct, scale: f64, what: &str) {
    let full = raster(t, scale);
    for r in 0..full.height() {
        for c in 0..full.width() {
            let v = t.eval(raster_coord(c, scale), raster_coord(r, scale)) as f32;
            assert_eq!(
                v.to_bits(),
                full.get(c, r).to_bits(),
                "{what}: scale {scale} pixel ({c}, {r}): eval {v} raster {}",
                full.get(c, r)
            );
        }
    }
    let (w, h) = (full.width(), full.height());
    let win = Window {
        x: w / 5,
        y: h / 3,
        width: w / 2,
        height: h / 2,
    };
    let part = t
        .rasterize(&RasterSettings {
            scale,
            window: Some(win),
        })
        .unwrap();
    for r in 0..win.height {
        for c in 0..win.width {
            assert_eq!(
                part.get(c, r).to_bits(),
                full.get(win.x + c, win.y + r).to_bits(),
                "{what}: window pixel ({c}, {r})"
            );
        }
    }
}

fn river_path() -> Vec<[f64; 2]> {
    vec![
        [-3.0, 12.0],
        [20.0, 18.0],
        [34.0, 40.0],
        [36.0, 41.0],
        [60.0, 30.0],
        [60.0, 30.0],
        [85.0, 50.0],
    ]
}

#[test]
fn every_node_kind_rasterises_like_point_evaluation() {
    let Some((hf, base)) = crop_and_layer() else {
        return;
    };
    let path = river_path();
    let n = path.len();
    let carve = River::new(
        path.clone(),
        (0..n).map(|i| 2.0 + i as f64).collect(),
        (0..n).map(|i| 10.0 + 3.0 * i as f64).collect(),
        RiverMode::Carve,
    )
    .unwrap();
    let bed_z: Vec<f64> = path
        .iter()
        .map(|p| {
            hf.sample_bilinear(p[0].clamp(0.0, 79.0) as f32, p[1].clamp(0.0, 63.0) as f32) as f64
                - 20.0
        })
        .collect();
    let bed = River::new(
        path.clone(),
        vec![4.0; n],
        vec![200.0; n],
        RiverMode::Bed(bed_z),
    )
    .unwrap();
    // The crop reduced x4 as a field placed like an amplification step's residual.
    let coarse = hf.downsample_box(4).unwrap();
    let field = |kernel| {
        Node::Field(
            Field::new(
                coarse.width(),
                coarse.height(),
                coarse.as_slice().to_vec(),
                [1.5, 1.5],
                4.0,
                kernel,
            )
            .unwrap(),
        )
    };
    let trees: Vec<(&str, Node)> = vec![
        ("layer", base.clone()),
        ("field keys", field(Kernel::Keys)),
        ("field lanczos3", field(Kernel::Lanczos3)),
        (
            "add field",
            Node::Add(vec![base.clone(), field(Kernel::Lanczos3)]),
        ),
        ("constant", Node::Constant(1234.5)),
        ("river carve", Node::River(carve.clone())),
        ("river bed", Node::River(bed.clone())),
        (
            "add carve",
            Node::Add(vec![base.clone(), Node::River(carve.clone())]),
        ),
        (
            "min bed",
            Node::Min(vec![base.clone(), Node::River(bed.clone())]),
        ),
        (
            "max",
            Node::Max(vec![
                base.clone(),
                Node::Constant(hf.min_max().unwrap().0 as f64 + 300.0),
            ]),
        ),
        (
            "blend",
            Node::Blend(vec![base.clone(), Node::Constant(1000.0), base.clone()]),
        ),
        (
            "replace rect",
            Node::Replace {
                base: Box::new(base.clone()),
                overlay: Box::new(Node::Add(vec![base.clone(), Node::Constant(-50.0)])),
                region: Region::Rect {
                    x0: 20.5,
                    y0: 10.0,
                    x1: 45.0,
                    y1: 30.25,
                },
                falloff: 6.0,
            },
        ),
        (
            "replace disk, river overlay",
            Node::Replace {
                base: Box::new(base.clone()),
                overlay: Box::new(Node::Min(vec![base.clone(), Node::River(bed)])),
                region: Region::Disk {
                    cx: 40.0,
                    cy: 35.0,
                    r: 9.5,
                },
                falloff: 0.0,
            },
        ),
        (
            "nested",
            Node::Blend(vec![
                carved_and_replaced(
                    &base,
                    carve,
                    0.0,
                    Region::Disk {
                        cx: 70.0,
                        cy: 10.0,
                        r: 5.0,
                    },
                    3.0,
                ),
                base,
            ]),
        ),
    ];
    for (what, tree) in trees {
        let t = on_crop(&hf, tree);
        for scale in [1.0, 2.5, 0.37] {
            assert_raster_is_eval(&t, scale, what);
        }
    }
}

#[test]
fn river_carve_and_replace_change_only_their_support() {
    let Some((hf, base)) = crop_and_layer() else {
        return;
    };
    let (w, h) = (hf.width(), hf.height());
    let path = river_path();
    let carve = plain_carve();
    let plain = on_crop(&hf, base.clone());
    let carved = on_crop(&hf, Node::Add(vec![base, Node::River(carve.clone())]));
    let a = plain.rasterize(&RasterSettings::default()).unwrap();
    let b = carved.rasterize(&RasterSettings::default()).unwrap();
    let dist = |x: f64, y: f64| {
        path.windows(2)
            .map(|s| {
                let (ux, uy) = (s[1][0] - s[0][0], s[1][1] - s[0][1]);
                let l2 = ux * ux + uy * uy;
                let t = if l2 > 0.0 {
                    (((x - s[0][0]) * ux + (y - s[0][1]) * uy) / l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (s[0][0] + t * ux - x).hypot(s[0][1] + t * uy - y)
            })
            .fold(f64::MAX, f64::min)
    };
    let mut carved_cells = 0;
    for r in 0..h {
        for c in 0..w {
            let d = dist(c as f64, r as f64);
            let diff = b.get(c, r) as f64 - a.get(c, r) as f64;
            if d >= 3.0 {
                assert_eq!(diff, 0.0, "({c}, {r}) at distance {d}");
            } else {
                // -depth (1 - (d / w)^2)^2 (f32 rounding of both rasters).
                let q = 1.0 - (d / 3.0) * (d / 3.0);
                let want = -15.0 * q * q;
                assert!((diff - want).abs() < 1e-2, "({c}, {r}): {diff} vs {want}");
                carved_cells += 1;
            }
        }
    }
    assert!(carved_cells > 200, "{carved_cells}");
    // The index makes a carve query visit only nearby segments.
    assert_eq!(carve.candidates_at(5.0, 60.0), 0);
    assert!(carve.candidates_at(34.0, 40.0) <= 3);
}

#[test]
fn tree_raster_is_independent_of_threads() {
    let Some((hf, base)) = crop_and_layer() else {
        return;
    };
    let carve = plain_carve();
    let region = Region::Rect {
        x0: 10.0,
        y0: 10.0,
        x1: 30.0,
        y1: 20.0,
    };
    let t = on_crop(&hf, carved_and_replaced(&base, carve, 500.0, region, 4.0));
    let run = |threads| relief_testdata::with_threads(threads, || raster(&t, 3.3));
    let (a, b) = (run(1), run(2));
    assert_eq!(
        a.as_slice().iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        b.as_slice().iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
}

/// A random tree over a constant-free base: rivers (both modes), regions, operators.
fn arb_leaf() -> impl Strategy<Value = Node> {
    let coord = -10.0f64..50.0;
    prop_oneof![
        (-100.0f64..100.0).prop_map(Node::Constant),
        (
            1usize..7,
            1usize..6,
            prop::collection::vec(-50.0f32..50.0, 36),
            (-5.0f64..5.0, -5.0f64..5.0),
            0.5f64..9.0,
            any::<bool>(),
        )
            .prop_map(|(w, h, v, (ox, oy), step, keys)| {
                let kernel = if keys { Kernel::Keys } else { Kernel::Lanczos3 };
                let f = Field::new(w, h, v[..w * h].to_vec(), [ox, oy], step, kernel);
                Node::Field(f.unwrap())
            }),
        (
            prop::collection::vec((coord.clone(), coord.clone()), 2..6),
            0.5f64..6.0,
            0.0f64..20.0,
            any::<bool>(),
        )
            .prop_map(|(pts, w, d, bed)| {
                let n = pts.len();
                let path: Vec<[f64; 2]> = pts.iter().map(|&(x, y)| [x, y]).collect();
                let mode = if bed {
                    RiverMode::Bed((0..n).map(|i| 10.0 - i as f64).collect())
                } else {
                    RiverMode::Carve
                };
                Node::River(
                    River::new(
                        path,
                        (0..n).map(|i| w + 0.3 * i as f64).collect(),
                        vec![d; n],
                        mode,
                    )
                    .unwrap(),
                )
            }),
    ]
}

fn arb_tree() -> impl Strategy<Value = Node> {
    arb_leaf().prop_recursive(3, 12, 3, |inner| {
        let region = prop_oneof![
            (0.0f64..40.0, 0.0f64..40.0, 0.0f64..20.0, 0.0f64..20.0).prop_map(|(x, y, w, h)| {
                Region::Rect {
                    x0: x,
                    y0: y,
                    x1: x + w,
                    y1: y + h,
                }
            }),
            (0.0f64..40.0, 0.0f64..40.0, 0.0f64..15.0).prop_map(|(cx, cy, r)| Region::Disk {
                cx,
                cy,
                r
            }),
        ];
        prop_oneof![
            prop::collection::vec(inner.clone(), 1..4).prop_map(Node::Blend),
            prop::collection::vec(inner.clone(), 1..4).prop_map(Node::Add),
            prop::collection::vec(inner.clone(), 1..4).prop_map(Node::Max),
            prop::collection::vec(inner.clone(), 1..4).prop_map(Node::Min),
            (inner.clone(), inner, region, 0.0f64..8.0).prop_map(|(b, o, region, falloff)| {
                Node::Replace {
                    base: Box::new(b),
                    overlay: Box::new(o),
                    region,
                    falloff,
                }
            }),
        ]
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn random_trees_rasterise_like_point_evaluation(
        tree in arb_tree(),
        scale in prop_oneof![Just(1.0f64), 0.3f64..3.0],
        wx in 0usize..20,
        wy in 0usize..20,
    ) {
        let t = Sct::new(tree, 41, 37, (10.0, 10.0)).unwrap();
        let (fw, fh) = t.raster_size(scale).unwrap();
        let win = Window {
            x: wx.min(fw - 1),
            y: wy.min(fh - 1),
            width: (fw - wx.min(fw - 1)).min(23),
            height: (fh - wy.min(fh - 1)).min(19),
        };
        let r = t.rasterize(&RasterSettings { scale, window: Some(win) }).unwrap();
        for y in 0..win.height {
            for x in 0..win.width {
                let v = t.eval(raster_coord(win.x + x, scale), raster_coord(win.y + y, scale)) as f32;
                prop_assert_eq!(v.to_bits(), r.get(x, y).to_bits(), "pixel ({}, {})", x, y);
            }
        }
        // The .sct bytes round-trip the tree exactly.
        let bytes = t.to_bytes().unwrap();
        let back = Sct::from_bytes(&bytes, &Default::default()).unwrap();
        prop_assert_eq!(back.to_bytes().unwrap(), bytes);
    }
}
