#![no_main]
//! Fuzzes the raw `.r16` reader: the first two bytes are the width option (0 = square).

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    relief_fuzz::read_raw(data, "fuzz.r16");
});
