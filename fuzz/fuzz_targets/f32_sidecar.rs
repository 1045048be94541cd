#![no_main]
//! Fuzzes the `.f32` + `.json` sidecar reader: the first two bytes (LE) give the length of the
//! sidecar JSON, which follows; the rest is the `.f32` data (no sidecar when the length is 0).

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if data.len() < 2 {
        return;
    }
    let n = u16::from_le_bytes([data[0], data[1]]) as usize;
    let rest = &data[2..];
    let (json, f32s) = rest.split_at(n.min(rest.len()));
    let o = relief_fuzz::opts();
    let side = (n > 0).then_some(json);
    relief_fuzz::check(relief_io::read_f32_sidecar_bytes(f32s, side, &o), &o);
});
