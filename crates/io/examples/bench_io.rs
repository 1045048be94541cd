//! Release-mode timing harness for relief-io (criterion lives in the workspace `benches` crate;
//! this is a quick per-crate measurement). Run:
//! `cargo run --release -p relief-io --features examples --example bench_io`
#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_io::{ReadOptions, WriteOptions, read, write};

fn time<T>(label: &str, reps: u32, mut f: impl FnMut() -> T) {
    let _ = f();
    let t = Instant::now();
    for _ in 0..reps {
        std::hint::black_box(f());
    }
    println!(
        "{label:<40} {:>9.2} ms",
        t.elapsed().as_secs_f64() * 1e3 / reps as f64
    );
}

fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/dem");
    if !dir.join("MANIFEST.md").is_file() {
        println!("../shared/data/dem not found");
        return;
    }
    let o = ReadOptions::default();
    time("read N47E011.hgt (1201^2 int16 BE)", 10, || {
        read(&dir.join("N47E011.hgt"), &o).unwrap()
    });
    time("read alps_dem.tiff (2373x757 int16)", 10, || {
        read(&dir.join("alps_dem.tiff"), &o).unwrap()
    });
    time("read N47E011.f32 + sidecar", 10, || {
        read(&dir.join("N47E011.f32"), &o).unwrap()
    });
    time("read topobathy.npz", 10, || {
        read(&dir.join("topobathy.npz"), &o).unwrap()
    });
    let hf = read(&dir.join("alps_dem.tiff"), &o).unwrap().heightfield;
    let out = std::env::temp_dir().join(format!("relief-io-bench-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    for ext in ["tif", "png", "exr", "npy", "r32", "asc"] {
        let p = out.join(format!("alps.{ext}"));
        time(&format!("write alps .{ext}"), 3, || {
            write(&p, &hf, &WriteOptions::default()).unwrap()
        });
        let r = ReadOptions {
            width: Some(hf.width()),
            height: Some(hf.height()),
            ..Default::default()
        };
        time(&format!("read back alps .{ext}"), 3, || {
            read(&p, &r).unwrap()
        });
    }
    let p = out.join("alps_preview.png");
    time("write_preview_png alps", 3, || {
        relief_io::write_preview_png(&p, &hf).unwrap()
    });
    let _ = std::fs::remove_dir_all(&out);
}
