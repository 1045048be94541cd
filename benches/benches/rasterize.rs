//! Rasterisation of a Sparse Construction Tree (relief-sparse-core, guerin2016 sections 4.1 and
//! 5.1) by stamping: the fixture DEM (512 x 512) encoded with a 128-atom dictionary of its own
//! 8 x 8 patches at s = 4, then an 8192 x 8192 window rasterised at scale 16.1 (the goal is
//! <= 2 s on 2 threads), plus the scale-1 full raster.
//! A construction tree over the same layer (a carved river along a 64-segment polyline under
//! `Add`, a `Replace` in a disk) is rasterised over the same window.
//! Criterion ids: `rasterize/sct_window/8192_scale16.1`, `rasterize/tree_window/8192_scale16.1`,
//! `rasterize/sct_full/512_scale1`.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use relief_sparse_core::{
    Dictionary, EncodeSettings, Node, PatchGeometry, RasterSettings, Region, River, RiverMode, Sct,
    Window, encode, extract_patches,
};

fn rasterize(c: &mut Criterion) {
    let dem = relief_benches::fixture_or(|| relief_testdata::load_dem("grandcanyon"));
    let patches = extract_patches(&dem, &PatchGeometry::with_patch_size(8)).expect("patches");
    let n = patches.matrix.nrows();
    let sel: Vec<usize> = (0..128).map(|k| k * n / 128 + 7).collect();
    let (dict, _) = Dictionary::from_patches(&patches, Some(&sel)).expect("dictionary");
    let sct = encode(
        &dem,
        &dict,
        &EncodeSettings {
            sparsity: 4,
            ..Default::default()
        },
    )
    .expect("encode");
    let mut g = c.benchmark_group("rasterize");
    g.sample_size(10);
    let big = RasterSettings {
        scale: 16.1,
        window: Some(Window {
            x: 0,
            y: 0,
            width: 8192,
            height: 8192,
        }),
    };
    g.throughput(Throughput::Elements(8192 * 8192));
    g.bench_with_input(
        BenchmarkId::new("sct_window", "8192_scale16.1"),
        &big,
        |b, st| b.iter(|| sct.rasterize(st).expect("rasterize")),
    );
    // The same window of a construction tree (section 5.4): the layer with a river carved
    // along a 64-segment polyline and a replaced disk, every node stamped.
    let path: Vec<[f64; 2]> = (0..=64)
        .map(|i| {
            let t = i as f64 / 64.0;
            [t * 511.0, 256.0 + 90.0 * (6.0 * t).sin()]
        })
        .collect();
    let river = River::new(path, vec![6.0; 65], vec![40.0; 65], RiverMode::Carve).expect("river");
    let tree = Node::Replace {
        base: Box::new(Node::Add(vec![sct.root().clone(), Node::River(river)])),
        overlay: Box::new(Node::Constant(f64::from(dem.min_max().expect("range").0))),
        region: Region::Disk {
            cx: 380.0,
            cy: 120.0,
            r: 40.0,
        },
        falloff: 12.0,
    };
    let tree = Sct::new(tree, sct.width(), sct.height(), sct.cell_size()).expect("tree");
    g.bench_with_input(
        BenchmarkId::new("tree_window", "8192_scale16.1"),
        &big,
        |b, st| b.iter(|| tree.rasterize(st).expect("rasterize")),
    );
    g.throughput(Throughput::Elements(512 * 512));
    let one = RasterSettings::default();
    g.bench_with_input(BenchmarkId::new("sct_full", "512_scale1"), &one, |b, st| {
        b.iter(|| sct.rasterize(st).expect("rasterize"))
    });
    g.finish();
}

criterion_group!(benches, rasterize);
criterion_main!(benches);
