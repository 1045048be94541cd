//! Every DEM of `shared/data/dem`, read from its original file, equals its `.f32` exactly
//! (voids included), and the `.f32` + sidecar reader agrees with `relief-testdata`.

use std::path::Path;

use relief_heightfield::Heightfield;
use relief_io::{Format, ReadOptions, read};

/// Bitwise equality with NaN == NaN (voids).
fn assert_same(id: &str, got: &Heightfield, want: &Heightfield) {
    assert_eq!(
        (got.width(), got.height()),
        (want.width(), want.height()),
        "{id}: size"
    );
    let mut diff = 0usize;
    let mut first = None;
    for (i, (a, b)) in got.as_slice().iter().zip(want.as_slice()).enumerate() {
        let same = (a.is_nan() && b.is_nan()) || a.to_bits() == b.to_bits();
        if !same {
            diff += 1;
            first.get_or_insert((i, *a, *b));
        }
    }
    assert_eq!(
        diff, 0,
        "{id}: {diff} cells differ, first (index, got, want) = {first:?}"
    );
}

fn check_cell(id: &str, got: &Heightfield, want: &Heightfield, rel: f64) {
    let (gx, gy) = got.cell_size();
    let (wx, wy) = want.cell_size();
    assert!(
        ((gx - wx) / wx).abs() < rel && ((gy - wy) / wy).abs() < rel,
        "{id}: cell size {gx} x {gy}, sidecar says {wx} x {wy}"
    );
}

fn original(dir: &Path, id: &str, file: &str, opts: &ReadOptions) -> Heightfield {
    let r = read(&dir.join(file), opts).unwrap_or_else(|e| panic!("{id}: {e}"));
    r.heightfield
}

#[test]
fn sidecar_reader_matches_testdata() {
    let Some(dir) = relief_testdata::dem_dir() else {
        return;
    };
    for id in ["maunga_whau", "topobathy", "N47E011"] {
        let want = relief_testdata::load_dem(id).expect("dem");
        let r = read(&dir.join(format!("{id}.f32")), &ReadOptions::default()).unwrap();
        assert_eq!(r.format, Format::F32Sidecar);
        assert_same(id, &r.heightfield, &want);
        assert_eq!(r.heightfield.cell_size(), want.cell_size(), "{id}");
        // The sidecar itself can be opened too.
        let r2 = read(&dir.join(format!("{id}.json")), &ReadOptions::default()).unwrap();
        assert_same(id, &r2.heightfield, &want);
    }
}

#[test]
fn geotiffs_equal_their_f32() {
    let Some(dir) = relief_testdata::dem_dir() else {
        return;
    };
    let o = ReadOptions::default();
    for (id, file, dtype) in [
        ("alps_dem", "alps_dem.tiff", "int16"),
        ("grandcanyon", "grandcanyon.tif", "int16"),
        ("carrizo", "carrizo.tif", "float32"),
    ] {
        let want = relief_testdata::load_dem(id).expect("dem");
        let r = read(&dir.join(file), &o).unwrap();
        assert_eq!(r.format, Format::GeoTiff);
        assert_eq!(r.dtype, dtype, "{id}");
        assert!(r.heightfield.georef().is_some(), "{id}: georeference kept");
        assert_same(id, &r.heightfield, &want);
        check_cell(id, &r.heightfield, &want, 0.01);
    }
    let carrizo = read(&dir.join("carrizo.tif"), &o).unwrap();
    assert!(carrizo.rows_flipped, "carrizo is stored south-up");
    let gc = read(&dir.join("grandcanyon.tif"), &o).unwrap();
    assert_eq!(
        gc.heightfield
            .georef()
            .and_then(|g| g.crs.clone())
            .as_deref(),
        Some("EPSG:3857")
    );
}

#[test]
fn hgt_json_and_npz_equal_their_f32() {
    let Some(dir) = relief_testdata::dem_dir() else {
        return;
    };
    let o = ReadOptions::default();
    for (id, file, format, cell_tol) in [
        ("N47E011", "N47E011.hgt", Format::Hgt, 0.005),
        ("N57E011", "N57E011.hgt", Format::Hgt, 0.005),
        (
            "jacksboro_fault",
            "jacksboro_fault_dem.npz",
            Format::Npz,
            0.005,
        ),
        ("topobathy", "topobathy.npz", Format::Npz, 0.02),
        (
            "maunga_whau",
            "volcano.json",
            Format::JsonGrid,
            f64::INFINITY,
        ),
    ] {
        let want = relief_testdata::load_dem(id).expect("dem");
        let r = read(&dir.join(file), &o).unwrap_or_else(|e| panic!("{id}: {e}"));
        assert_eq!(r.format, format, "{id}");
        assert_same(id, &r.heightfield, &want);
        if cell_tol.is_finite() {
            check_cell(id, &r.heightfield, &want, cell_tol);
        }
    }
    let n47 = original(&dir, "N47E011", "N47E011.hgt", &o);
    assert_eq!(n47.void_count(), 54_278);
    assert_eq!((n47.width(), n47.height()), (1201, 1201));
    let topo = read(&dir.join("topobathy.npz"), &o).unwrap();
    assert!(topo.rows_flipped, "topobathy latitude ascends");
    let jb = read(&dir.join("jacksboro_fault_dem.npz"), &o).unwrap();
    assert!(!jb.rows_flipped);
    assert_eq!(jb.dtype, "int16");
}
