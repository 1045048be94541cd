#![no_main]
//! Fuzzes the construction-tree description of `relief tree build` (`TreeSpec`, JSON): every
//! layer resolves to a small constant tree; a description may be refused, never panic; a built
//! tree encodes, decodes to the same bytes and, when small, rasterises to finite values.

use libfuzzer_sys::fuzz_target;
use relief_sparse_core::{RasterSettings, Sct, TreeSpec};

fuzz_target!(|data: &[u8]| {
    let Ok(spec) = serde_json::from_slice::<TreeSpec>(data) else {
        return;
    };
    let registry = relief_fuzz::sct_registry();
    let mut resolve = |_: &str| relief_fuzz::constant_tree(16, 12, 5.0);
    let Ok(sct) = spec.build(&mut resolve) else {
        return;
    };
    let bytes = sct.to_bytes().expect("a built tree encodes");
    let back = Sct::from_bytes(&bytes, &registry).expect("an encoded tree decodes");
    assert_eq!(back.to_bytes().expect("encodes"), bytes);
    if sct.width() * sct.height() <= 4096 {
        if let Ok(hf) = sct.rasterize(&RasterSettings::default()) {
            assert!(
                hf.as_slice().iter().all(|v| v.is_finite()),
                "non-finite cell"
            );
        }
    }
});
