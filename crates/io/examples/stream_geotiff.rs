//! Peak-memory harness of the streaming GeoTIFF writer (issue 9, large outputs).
//!
//! `cargo build --release -p relief-io --features examples --example stream_geotiff` then
//! `/usr/bin/time -v target/release/examples/stream_geotiff OUT.tif 16384 stream` (rows produced
//! and written one at a time) or `... whole` (the same raster built in memory and written with
//! `relief_io::write`), and compare "Maximum resident set size".

use std::path::Path;
use std::time::Instant;

use relief_heightfield::Heightfield;
use relief_io::{GeoTiffStripWriter, WriteOptions};

fn sample(x: usize, y: usize) -> f32 {
    let (fx, fy) = (x as f32 * 0.001, y as f32 * 0.0013);
    1000.0 + 300.0 * fx.sin() * fy.cos() + 0.01 * (x ^ y) as f32
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let out = args.get(1).map_or("stream.tif", String::as_str);
    let n: usize = args.get(2).map_or(Ok(16384), |s| s.parse())?;
    let mode = args.get(3).map_or("stream", String::as_str);
    let t = Instant::now();
    match mode {
        "stream" => {
            let mut w = GeoTiffStripWriter::create(Path::new(out), n, n, (2.0, 2.0), None)?;
            let mut row = vec![0f32; n];
            for y in 0..n {
                for (x, v) in row.iter_mut().enumerate() {
                    *v = sample(x, y);
                }
                w.write_rows(&row)?;
            }
            w.finish()?;
        }
        _ => {
            let hf = Heightfield::from_fn(n, n, 2.0, 2.0, sample);
            relief_io::write(Path::new(out), &hf, &WriteOptions::default())?;
        }
    }
    let bytes = std::fs::metadata(out)?.len();
    #[allow(clippy::print_stdout)]
    {
        println!(
            "{mode}: {n} x {n} -> {out} ({:.0} MiB) in {:.2} s",
            bytes as f64 / (1 << 20) as f64,
            t.elapsed().as_secs_f64()
        );
    }
    Ok(())
}
