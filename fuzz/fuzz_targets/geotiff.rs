#![no_main]
//! Fuzzes the GeoTIFF reader; a raster that reads must also write and read back with the same
//! size and samples (the georeference tags are carried verbatim).

use libfuzzer_sys::fuzz_target;
use relief_io::{Format, WriteOptions};

fuzz_target!(|data: &[u8]| {
    if let Some(r) = relief_fuzz::read_as(data, "fuzz.tif") {
        let hf = &r.heightfield;
        let bytes = relief_io::encode(hf, Format::GeoTiff, &WriteOptions::default())
            .expect("a raster that was read can be written");
        let back = relief_fuzz::read_as(&bytes, "back.tif").expect("written GeoTIFF reads back");
        let b = &back.heightfield;
        assert_eq!((b.width(), b.height()), (hf.width(), hf.height()));
        let same = hf
            .as_slice()
            .iter()
            .zip(b.as_slice())
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()));
        assert!(same, "samples changed in the GeoTIFF round trip");
    }
});
