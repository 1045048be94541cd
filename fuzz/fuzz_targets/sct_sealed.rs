#![no_main]
//! Fuzzes `Sct::from_bytes` behind the version-3 checksum: the input is sealed with its CRC-32
//! before decoding, so mutations reach the decoder instead of stopping at the checksum. A tree
//! that decodes must encode to the same bytes and, when small, rasterise without panicking.

use libfuzzer_sys::fuzz_target;
use relief_sparse_core::format::crc32;
use relief_sparse_core::{RasterSettings, Sct};

fuzz_target!(|data: &[u8]| {
    let registry = relief_fuzz::sct_registry();
    let mut sealed = data.to_vec();
    sealed.extend_from_slice(&crc32(data).to_le_bytes());
    if let Ok(sct) = Sct::from_bytes(&sealed, &registry) {
        let again = sct.to_bytes().expect("a decoded tree encodes");
        let back = Sct::from_bytes(&again, &registry).expect("re-encoded tree decodes");
        assert_eq!(back.to_bytes().expect("encodes"), again);
        if sct.width() * sct.height() <= 4096 {
            let _ = sct.rasterize(&RasterSettings::default());
        }
    }
});
