#![no_main]
//! Fuzzes the exr reader through `relief_io::read_bytes` with a `.exr` name hint.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    relief_fuzz::read_as(data, "fuzz.exr");
});
