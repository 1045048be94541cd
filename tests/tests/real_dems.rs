//! Every DEM of the shared set read through relief-io, and a fill -> resample -> write pipeline
//! across relief-heightfield and relief-io on a void-rich crop of the N47E011 SRTM tile.

use relief_heightfield::fill::{FillSettings, fill_voids};
use relief_heightfield::{Heightfield, metrics};

fn read(path: &std::path::Path) -> Heightfield {
    relief_io::read(path, &relief_io::ReadOptions::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .heightfield
}

/// NaN-aware exact equality.
fn same_samples(a: &Heightfield, b: &Heightfield) -> bool {
    a.as_slice().len() == b.as_slice().len()
        && a.as_slice()
            .iter()
            .zip(b.as_slice())
            .all(|(x, y)| x == y || (x.is_nan() && y.is_nan()))
}

#[test]
fn every_dem_reads_with_its_size_and_void_count() {
    let Some(dir) = relief_testdata::dem_dir() else {
        return;
    };
    for id in relief_testdata::DEM_IDS {
        let side: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join(format!("{id}.json"))).unwrap())
                .unwrap();
        let (w, h) = (
            side["width"].as_u64().unwrap() as usize,
            side["height"].as_u64().unwrap() as usize,
        );
        let voids = side["nodata_count"].as_u64().unwrap() as usize;

        // The .f32 + .json sidecar format, through relief-io.
        let f32_dem = read(&dir.join(format!("{id}.f32")));
        assert_eq!((f32_dem.width(), f32_dem.height()), (w, h), "{id}.f32");
        assert_eq!(f32_dem.void_count(), voids, "{id}.f32 voids");

        // The original file, byte for byte as published (R's volcano JSON is not a DEM format).
        let original = side["original_file"].as_str().unwrap();
        if original.ends_with(".json") {
            continue;
        }
        let orig = read(&dir.join(original));
        assert_eq!((orig.width(), orig.height()), (w, h), "{original}");
        assert_eq!(orig.void_count(), voids, "{original} voids");
        assert!(
            same_samples(&orig, &f32_dem),
            "{original} differs from {id}.f32"
        );
        let (cx, cy) = orig.cell_size();
        assert!(cx > 0.0 && cy > 0.0, "{original}: cell size {cx} x {cy}");
    }
}

#[test]
fn fill_resample_write_pipeline_on_srtm_crop() {
    let Some(dir) = relief_testdata::dem_dir() else {
        return;
    };
    let tile = read(&dir.join("N47E011.hgt"));
    assert_eq!(tile.void_count(), 54_278);

    // The 256 x 256 window (on a 64-cell lattice) with the most voids, but not mostly void.
    let n = 256;
    let mut best = (0, 0, 0);
    for y in (0..=tile.height() - n).step_by(64) {
        for x in (0..=tile.width() - n).step_by(64) {
            let v = tile.crop(x, y, n, n).unwrap().void_count();
            if v > best.2 && v < n * n / 4 {
                best = (x, y, v);
            }
        }
    }
    let (x0, y0, voids) = best;
    assert!(
        voids > 1000,
        "expected a void-rich window, best has {voids}"
    );
    let crop = tile.crop(x0, y0, n, n).unwrap();
    let (lo, hi) = crop.min_max().unwrap();

    let mut filled = crop.clone();
    let rep = fill_voids(&mut filled, &FillSettings::default()).unwrap();
    assert_eq!(rep.filled, voids);
    assert_eq!(filled.void_count(), 0);
    for (a, b) in crop.as_slice().iter().zip(filled.as_slice()) {
        if a.is_finite() {
            assert_eq!(a, b, "a valid cell changed");
        } else {
            // Maximum principle of the harmonic fill: no new extremes.
            assert!(
                (lo - 1e-2..=hi + 1e-2).contains(b),
                "filled {b} outside {lo}..{hi}"
            );
        }
    }

    // Down by 4 with the low-pass, back up with bicubic: a smooth approximation of the terrain.
    let down = filled.resample(n / 4, n / 4).unwrap();
    assert_eq!(down.cell_size().0, filled.cell_size().0 * 4.0);
    let s_full = metrics::stats(&filled).unwrap();
    let s_down = metrics::stats(&down).unwrap();
    assert!(
        (s_full.mean - s_down.mean).abs() < 0.01 * s_full.std,
        "mean drifted"
    );
    let up = down.resample(n, n).unwrap();
    let err = metrics::rmse(&filled, &up).unwrap();
    assert!(
        err > 0.0 && err < 0.25 * s_full.std,
        "rmse {err} vs std {}",
        s_full.std
    );

    // Through relief-io and back: GeoTIFF f32 is lossless.
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("filled.tif");
    relief_io::write(&p, &filled, &relief_io::WriteOptions::default()).unwrap();
    let back = read(&p);
    assert!(same_samples(&filled, &back));
    // The crop now carries its EPSG:4326 georeference, so the GeoTIFF reader derives the ground
    // cell size at the crop's own centre latitude rather than the whole tile's.
    let (a, b) = (back.cell_size(), filled.cell_size());
    assert!(
        (a.0 / b.0 - 1.0).abs() < 5e-3 && (a.1 / b.1 - 1.0).abs() < 5e-3,
        "{a:?} vs {b:?}"
    );
    assert_eq!(back.georef().unwrap().crs.as_deref(), Some("EPSG:4326"));
}
