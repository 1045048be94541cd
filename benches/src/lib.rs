//! Shared inputs of the relief criterion benchmarks (`benches/*.rs`) and of the Python peers run
//! by `cargo xtask bench`, so ours and the peer's timings are taken on the same data.
//!
//! Add a bench: create `benches/benches/<crate>.rs` (criterion, data built outside the timed
//! closure, fixed seeds, parameters in `BenchmarkId`), add a `[[bench]] name = "<crate>"
//! harness = false` entry to `benches/Cargo.toml`, and a row to `xtask/src/bench/items.rs`
//! whose `criterion_id` is `<group>/<function>/<parameter>`.
#![warn(missing_docs)]

use std::path::PathBuf;

use relief_heightfield::Heightfield;

/// The bundled fixture DEM `fixtures/grandcanyon.tif` (512 x 512, ~62 m cells, no voids).
pub fn fixture_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../fixtures/grandcanyon.tif")
}

/// Reads [`fixture_path`] through relief-io.
pub fn fixture_dem() -> Result<Heightfield, relief_io::IoError> {
    Ok(relief_io::read(&fixture_path(), &relief_io::ReadOptions::default())?.heightfield)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holes_cover_about_seven_percent() {
        let hf = Heightfield::from_fn(512, 512, 1.0, 1.0, |x, y| (x + y) as f32);
        let holed = with_holes(&hf);
        let frac = holed.void_count() as f64 / holed.len() as f64;
        assert!((0.05..0.08).contains(&frac), "{frac}");
        assert_eq!(holed.get(0, 0), 0.0);
        assert!(holed.get(128, 128).is_nan());
    }
}
