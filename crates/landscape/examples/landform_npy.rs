//! The landform pass on `.npy` files (float32, C order), to try it on a detail method's output:
//!
//! `cargo run --release -p relief-landscape --features examples --example landform_npy -- COARSE.npy FINE.npy OUT.npy CELL_X CELL_Y`
//!
//! `CELL_X`, `CELL_Y`: the fine grid's cell size (m). Prints the report and the drainage
//! statistics before and after.
#![allow(clippy::print_stdout)]

use relief_heightfield::Heightfield;
use relief_landscape::landform::{LandformSettings, finish};
use relief_landscape::stats::drainage;

pub(crate) fn read_npy(path: &str) -> (usize, usize, Vec<f32>) {
    let b = std::fs::read(path).expect("read");
    let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
    let header = std::str::from_utf8(&b[10..10 + hl]).expect("header");
    assert!(
        header.contains("'<f4'") && header.contains("False"),
        "float32 C order"
    );
    let shape = &header[header.find("'shape': (").expect("shape") + 10..];
    let dims: Vec<usize> = shape[..shape.find(')').expect(")")]
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let data = relief_heightfield::bytes::f32_from_le_bytes(&b[10 + hl..]);
    (dims[1], dims[0], data)
}

pub(crate) fn write_npy(path: &str, hf: &Heightfield) {
    let mut header = format!(
        "{{'descr': '<f4', 'fortran_order': False, 'shape': ({}, {}), }}",
        hf.height(),
        hf.width()
    );
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend((header.len() as u16).to_le_bytes());
    b.extend(header.as_bytes());
    for v in hf.as_slice() {
        b.extend(v.to_le_bytes());
    }
    std::fs::write(path, b).expect("write");
}

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    assert!(a.len() >= 5, "COARSE.npy FINE.npy OUT.npy CELL_X CELL_Y");
    let (cx, cy): (f64, f64) = (a[3].parse().unwrap(), a[4].parse().unwrap());
    let (fw, fh, fd) = read_npy(&a[1]);
    let (cw, ch, cd) = read_npy(&a[0]);
    let f = (fw / cw) as f64;
    let fine = Heightfield::new(fw, fh, fd, cx, cy).unwrap();
    let coarse = Heightfield::new(cw, ch, cd, cx * f, cy * f).unwrap();
    let mut settings = LandformSettings::default();
    if let Ok(s) = std::env::var("LANDFORM") {
        settings = serde_json::from_str(&s).expect("LANDFORM json");
    }
    let t = std::time::Instant::now();
    let (out, report) = finish(&fine, &coarse, &settings).unwrap();
    println!(
        "{report:?} in {:.2} s\nbefore {:?}\nafter  {:?}",
        t.elapsed().as_secs_f64(),
        drainage(&fine),
        drainage(&out)
    );
    write_npy(&a[2], &out);
}
