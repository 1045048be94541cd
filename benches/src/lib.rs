//! Shared inputs of the relief criterion benchmarks (`benches/*.rs`) and of the Python peers run
//! by `cargo xtask bench`, so ours and the peer's timings are taken on the same data.
//!
//! Add a bench: create `benches/benches/<crate>.rs` (criterion, data built outside the timed
//! closure, fixed seeds, parameters in `BenchmarkId`), add a `[[bench]] name = "<crate>"
//! harness = false` entry to `benches/Cargo.toml`, and a row to `xtask/src/bench/items.rs`
//! whose `criterion_id` is `<group>/<function>/<parameter>`.
#![warn(missing_docs)]

use std::path::{Path, PathBuf};

use relief_heightfield::Heightfield;

/// The bundled fixture DEM `fixtures/grandcanyon.tif` (512 x 512, ~62 m cells, no voids).
pub fn fixture_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/grandcanyon.tif")
}

/// Reads [`fixture_path`] through relief-io.
pub fn fixture_dem() -> Result<Heightfield, relief_io::IoError> {
    Ok(relief_io::read(&fixture_path(), &relief_io::ReadOptions::default())?.heightfield)
}

/// The fixture DEM, else `fallback` (the benches pass the real set's `grandcanyon` DEM from
/// relief-testdata, a dev-dependency).
///
/// # Panics
/// Panics when neither can be read.
pub fn fixture_or(fallback: impl FnOnce() -> Option<Heightfield>) -> Heightfield {
    fixture_dem()
        .ok()
        .or_else(fallback)
        .expect("fixtures/grandcanyon.tif or the grandcanyon DEM")
}

/// `target/bench-data/` of the workspace, where benches write the inputs their peers read
/// (created here).
pub fn bench_data_dir() -> std::io::Result<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/bench-data");
    std::fs::create_dir_all(&dir)?;
    Ok(dir)
}

/// Writes `data` as a C-order `f32` `.npy` file (format version 1.0) of the given `shape`
/// ([`relief_io::npy_f32`]).
pub fn write_npy(
    path: &Path,
    shape: &[usize],
    data: impl IntoIterator<Item = f32>,
) -> std::io::Result<()> {
    std::fs::write(path, relief_io::npy_f32(shape, data))
}

/// The random-walk surface of the DWT benches and of the PyWavelets peer's input: per row,
/// normals from the wavelet crate's counter-based generator (`row_key(1, 0, 0, y)`), summed
/// along x, then the rows summed along y; `size * size` values, row-major.
pub fn dwt_surface(size: usize) -> Vec<f32> {
    use relief_wavelet_lod::rng::{fill_normals, row_key};
    let mut data = vec![0.0f32; size * size];
    for y in 0..size {
        let row = &mut data[y * size..(y + 1) * size];
        fill_normals(row_key(1, 0, 0, y), 0, row);
        for x in 1..size {
            row[x] += row[x - 1];
        }
    }
    for y in 1..size {
        for x in 0..size {
            data[y * size + x] += data[(y - 1) * size + x];
        }
    }
    data
}

/// Holes punched into `hf` for void-fill benchmarks: four discs of radius `min(w, h) / 14`
/// centred at a quarter and three quarters of each side (about 7 % of the cells). Deterministic.
pub fn with_holes(hf: &Heightfield) -> Heightfield {
    let (w, h) = (hf.width(), hf.height());
    let r = (w.min(h) as f64 / 14.0).max(1.0);
    let centres = [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)];
    let mut out = hf.clone();
    for y in 0..h {
        for x in 0..w {
            let inside = centres
                .iter()
                .any(|&(fx, fy)| (x as f64 - fx * w as f64).hypot(y as f64 - fy * h as f64) <= r);
            if inside {
                out.set(x, y, f32::NAN);
            }
        }
    }
    out
}

/// The large-dictionary data of the `omp_large` bench and the `nearest_index` bench
/// (guerin2016 section 5.3, issue 15): `n_atoms` unit-norm mean-removed 8 x 8 patches of the top
/// half of the fixture DEM and `n_signals` patches of its bottom half (no signal is an atom),
/// both evenly strided over the patches with a norm above 1e-3.
pub fn large_dictionary_data(
    n_atoms: usize,
    n_signals: usize,
) -> (ndarray::Array2<f32>, ndarray::Array2<f32>) {
    use relief_sparse_core::{PatchGeometry, extract_patches};
    let dem = fixture_or(|| relief_testdata::load_dem("grandcanyon"));
    let (w, h) = (dem.width(), dem.height());
    let geom = PatchGeometry::with_patch_size(8);
    let top = extract_patches(&dem.crop(0, 0, w, h / 2).expect("crop"), &geom)
        .expect("patches")
        .matrix;
    let bottom = extract_patches(&dem.crop(0, h / 2, w, h - h / 2).expect("crop"), &geom)
        .expect("patches")
        .matrix;
    let every = |m: &ndarray::Array2<f32>, n: usize, unit: bool| {
        let mut out = ndarray::Array2::zeros((n, m.ncols()));
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
    (every(&top, n_atoms, true), every(&bottom, n_signals, false))
}

/// The 4096 x 4096 DEM of the drainage benches (`landscape/fill_d8/4096`) and of their peers
/// (`xtask/peers/drainage.py`, `flow_4096.npy`): the fixture DEM mirrored into an 8 x 8 mosaic
/// (continuous at every seam, so its depressions and flats are the real DEM's), 30 m cells.
pub fn flow_surface() -> Result<Heightfield, relief_io::IoError> {
    let dem = fixture_dem()?;
    let (w, h) = (dem.width(), dem.height());
    let n = 4096;
    let data: Vec<f32> = (0..n * n)
        .map(|i| {
            let (x, y) = (i % n, i / n);
            let (tx, ty) = (x / w, y / h);
            let sx = if tx % 2 == 0 { x % w } else { w - 1 - x % w };
            let sy = if ty % 2 == 0 { y % h } else { h - 1 - y % h };
            dem.get(sx, sy)
        })
        .collect();
    Ok(Heightfield::new(n, n, data, 30.0, 30.0).expect("a 4096^2 grid"))
}

/// The 1024 x 1024 initial surface of the stream-power benches and of their peer
/// (`xtask/peers/stream_power.py`, `spl_1024.npy`): a flat block with 1 m of uniform noise
/// (`relief_heightfield::rng::hash(7, cell, 0, 0)`), 100 m cells, uplifted at 1 mm/yr.
pub fn spl_surface() -> Heightfield {
    let n = 1024;
    let data: Vec<f32> = (0..n * n)
        .map(|i| {
            relief_heightfield::rng::unit_f32(relief_heightfield::rng::hash(7, i as u64, 0, 0))
        })
        .collect();
    Heightfield::new(n, n, data, 100.0, 100.0).expect("a 1024^2 grid")
}
