#![no_main]
//! Fuzzes the json_grid reader through `relief_io::read_bytes` with a `.json` name hint.

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    relief_fuzz::read_as(data, "fuzz.json");
});
