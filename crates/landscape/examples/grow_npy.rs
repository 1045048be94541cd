//! Landscape evolution from a painted map in a `.npy` file (float32, C order):
//!
//! `cargo run --release -p relief-landscape --features examples --example grow_npy -- MAP.npy OUT.npy CELL_X CELL_Y [UPSAMPLE]`
//!
//! The map is enlarged `UPSAMPLE` times (bicubic, default 1) and grown with
//! [`relief_landscape::grow::grow`] (settings from the `GROW` environment variable, JSON).
#![allow(clippy::print_stdout)]

use relief_heightfield::Heightfield;
use relief_landscape::grow::{GrowSettings, grow};

#[path = "landform_npy.rs"]
#[allow(dead_code)]
mod npy;

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    assert!(a.len() >= 4, "MAP.npy OUT.npy CELL_X CELL_Y [UPSAMPLE]");
    let (cx, cy): (f64, f64) = (a[2].parse().unwrap(), a[3].parse().unwrap());
    let up: usize = a.get(4).map_or(1, |s| s.parse().unwrap());
    let (w, h, d) = npy::read_npy(&a[0]);
    let map = Heightfield::new(w, h, d, cx, cy)
        .unwrap()
        .resample(w * up, h * up)
        .unwrap();
    let settings: GrowSettings = std::env::var("GROW")
        .map(|s| serde_json::from_str(&s).expect("GROW json"))
        .unwrap_or_default();
    let t = std::time::Instant::now();
    let z = grow(&map, &settings, &|| false).unwrap();
    println!(
        "{}x{} in {:.2} s, relief {:?}, {:?}",
        z.width(),
        z.height(),
        t.elapsed().as_secs_f64(),
        z.min_max(),
        relief_landscape::stats::drainage(&z)
    );
    npy::write_npy(&a[1], &z);
}
