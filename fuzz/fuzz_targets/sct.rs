#![no_main]
//! Fuzzes `Sct::from_bytes` (with a registry knowing one function atom, `ridge`); a tree that
//! decodes must encode to the same bytes and, when small, rasterise without panicking.

use libfuzzer_sys::fuzz_target;
use relief_sparse_core::{RasterSettings, Sct};

fuzz_target!(|data: &[u8]| {
    let registry = relief_fuzz::sct_registry();
    if let Ok(sct) = Sct::from_bytes(data, &registry) {
        let again = sct.to_bytes().expect("a decoded tree encodes");
        let back = Sct::from_bytes(&again, &registry).expect("re-encoded tree decodes");
        assert_eq!(back.to_bytes().expect("encodes"), again);
        if sct.width() * sct.height() <= 4096 {
            let _ = sct.rasterize(&RasterSettings::default());
        }
    }
});
