#![no_main]
//! Fuzzes `Dictionary::from_bytes` (registry: `ridge`), twice per input: the bytes as given
//! (exercises the checksum and the unchecksummed version 1), and the bytes sealed with their
//! CRC-32 (so mutations reach the version-2 decoder behind the checksum). A dictionary that
//! decodes must encode and decode to the same bytes.

use libfuzzer_sys::fuzz_target;
use relief_sparse_core::Dictionary;
use relief_sparse_core::format::crc32;

fuzz_target!(|data: &[u8]| {
    let registry = relief_fuzz::sct_registry();
    let mut sealed = data.to_vec();
    sealed.extend_from_slice(&crc32(data).to_le_bytes());
    for bytes in [data, &sealed[..]] {
        if let Ok(d) = Dictionary::from_bytes(bytes, &registry) {
            let again = d.to_bytes().expect("a decoded dictionary encodes");
            let back = Dictionary::from_bytes(&again, &registry).expect("re-encoded decodes");
            assert_eq!(back.to_bytes().expect("encodes"), again);
            assert_eq!(back.len(), d.len());
        }
    }
});
