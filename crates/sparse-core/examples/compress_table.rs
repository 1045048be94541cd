//! The analogue of guerin2016 table 1 on a real DEM: rho, bytes and PSNR at s = 1, 2, 8 with a
//! dictionary of N = 128 patches (8 x 8) picked evenly from the same DEM (until learned
//! dictionaries are used): `cargo run --release -p relief-sparse-core --features examples --example compress_table
//! -- [DEM id]` (default `grandcanyon`, 512 x 512; needs ../shared/data/dem).
#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_sparse_core::{
    Dictionary, EncodeSettings, FormatOptions, FunctionAtomRegistry, PatchGeometry,
    compression_report, encode, extract_patches,
};

fn main() {
    let id = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "grandcanyon".into());
    let Some(hf) = relief_testdata::load_dem(&id) else {
        println!("DEM {id} not found");
        return;
    };
    let hf = if hf.has_voids() {
        let mut h = hf;
        relief_heightfield::fill::fill_voids(&mut h, &Default::default()).expect("fill");
        h
    } else {
        hf
    };
    let patches = extract_patches(&hf, &PatchGeometry::with_patch_size(8)).expect("patches");
    let n = patches.matrix.nrows();
    let sel: Vec<usize> = (0..128).map(|k| k * n / 128 + 7).collect();
    let (dict, _) = Dictionary::from_patches(&patches, Some(&sel)).expect("dictionary");
    println!(
        "{id}: {} x {}, n = {n} patches, K = 64, N = {}",
        hf.width(),
        hf.height(),
        dict.len()
    );
    println!("s  rho      bytes    bytes(q16)  PSNR     PSNR(q16)  encode");
    for s in [1, 2, 8] {
        let t = Instant::now();
        let sct = encode(
            &hf,
            &dict,
            &EncodeSettings {
                sparsity: s,
                ..Default::default()
            },
        )
        .expect("encode");
        let dt = t.elapsed().as_secs_f64();
        let reg = FunctionAtomRegistry::new();
        let f = compression_report(&hf, &sct, &FormatOptions::default(), &reg).expect("report");
        let q = compression_report(
            &hf,
            &sct,
            &FormatOptions {
                quantize_coefficients: true,
            },
            &reg,
        )
        .expect("report");
        println!(
            "{s}  {:5.1} %  {:8}  {:8}   {:6.2}   {:6.2}     {:.2} s",
            100.0 * f.rho,
            f.bytes,
            q.bytes,
            f.psnr,
            q.psnr,
            dt
        );
    }
}
