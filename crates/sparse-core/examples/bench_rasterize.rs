//! Release timing of the rasterisation goal outside criterion: the grandcanyon DEM
//! (512 x 512) encoded with 128 of its own 8 x 8 patches at s = 4, then the 8192 x 8192 window
//! at scale 16.1 (same inputs as `rasterize/sct_window/8192_scale16.1`), best of 4 runs:
//! `RAYON_NUM_THREADS=2 cargo run --release -p relief-sparse-core --example bench_rasterize`
//! (needs ../shared/data/dem).
#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_sparse_core::{
    Dictionary, EncodeSettings, PatchGeometry, RasterSettings, Window, encode, extract_patches,
};

fn main() {
    let Some(dem) = relief_testdata::load_dem("grandcanyon") else {
        println!("DEM grandcanyon not found");
        return;
    };
    let patches = extract_patches(&dem, &PatchGeometry::with_patch_size(8)).expect("patches");
    let n = patches.matrix.nrows();
    let sel: Vec<usize> = (0..128).map(|k| k * n / 128 + 7).collect();
    let (dict, _) = Dictionary::from_patches(&patches, Some(&sel)).expect("dictionary");
    let settings = EncodeSettings {
        sparsity: 4,
        ..Default::default()
    };
    let sct = encode(&dem, &dict, &settings).expect("encode");
    let big = RasterSettings {
        scale: 16.1,
        window: Some(Window {
            x: 0,
            y: 0,
            width: 8192,
            height: 8192,
        }),
    };
    let mut best = f64::MAX;
    for _ in 0..4 {
        let t = Instant::now();
        let r = sct.rasterize(&big).expect("rasterize");
        best = best.min(t.elapsed().as_secs_f64());
        std::hint::black_box(r);
    }
    println!(
        "8192 x 8192 window at scale 16.1, {} threads: best of 4 {best:.3} s",
        rayon::current_num_threads()
    );
}
