#![no_main]
//! Fuzzes the Terrain-RGB PNG decoding (`PngMode::TerrainRgb`).

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use relief_io::{PngMode, ReadOptions};

fuzz_target!(|data: &[u8]| {
    let o = ReadOptions {
        png: PngMode::TerrainRgb,
        ..relief_fuzz::opts()
    };
    relief_fuzz::check(relief_io::read_bytes(data, Some(Path::new("fuzz.png")), &o), &o);
});
