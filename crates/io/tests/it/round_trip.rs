//! Round trip of every writer/reader pair (proptest over sizes and values), each within the
//! format's stated precision, plus atomic-write and real-DEM conversions.

use std::path::Path;

use proptest::prelude::*;
use relief_heightfield::Heightfield;
use relief_io::{Format, PngMode, ReadOptions, WriteOptions, encode, read, read_bytes, write};

/// Heightfields of 1..24 x 1..24 cells with values in -500..4500 m and, when `voids`, some NaN
/// cells (never all).
fn fields(voids: bool) -> impl Strategy<Value = Heightfield> {
    (1usize..24, 1usize..24).prop_flat_map(move |(w, h)| {
        let cell = prop_oneof![Just(f32::NAN), -500.0f32..4500.0];
        let cells = if voids {
            cell.boxed()
        } else {
            (-500.0f32..4500.0).boxed()
        };
        (
            prop::collection::vec(cells, w * h),
            0.5f64..100.0,
            0.5f64..100.0,
        )
            .prop_map(move |(mut d, cx, cy)| {
                if d.iter().all(|v| v.is_nan()) {
                    d[0] = 1.0;
                }
                Heightfield::new(w, h, d, cx, cy).unwrap()
            })
    })
}

/// Max |a - b| over cells, requiring the void masks to agree.
fn max_err(a: &Heightfield, b: &Heightfield) -> f64 {
    assert_eq!((a.width(), a.height()), (b.width(), b.height()));
    let mut m = 0.0f64;
    for (x, y) in a.as_slice().iter().zip(b.as_slice()) {
        assert_eq!(x.is_nan(), y.is_nan(), "void mask differs: {x} vs {y}");
        if !x.is_nan() {
            m = m.max((*x as f64 - *y as f64).abs());
        }
    }
    m
}

fn round_trip(
    hf: &Heightfield,
    fmt: Format,
    wopts: &WriteOptions,
    ropts: &ReadOptions,
) -> Heightfield {
    let bytes = encode(hf, fmt, wopts).unwrap();
    let ext = match fmt {
        Format::R16 => "r16",
        Format::R32 => "r32",
        _ => "bin",
    };
    let hint = format!("x.{ext}");
    let r = read_bytes(&bytes, Some(Path::new(&hint)), ropts).unwrap();
    assert_eq!(r.format, fmt);
    r.heightfield
}

/// One proptest per exact format: values, voids and (where stored) cell size come back bit for bit.
macro_rules! exact_round_trip {
    ($($name:ident: $fmt:expr, voids = $voids:expr, keeps_cell = $cell:expr;)*) => {$(
        proptest! {
            #![proptest_config(ProptestConfig::with_cases(48))]
            #[test]
            fn $name(hf in fields($voids)) {
                let ropts = ReadOptions { width: Some(hf.width()), height: Some(hf.height()), ..Default::default() };
                let back = round_trip(&hf, $fmt, &WriteOptions::default(), &ropts);
                prop_assert_eq!(max_err(&hf, &back), 0.0);
                if $cell {
                    let (a, b) = (hf.cell_size(), back.cell_size());
                    prop_assert!((a.0 - b.0).abs() < 1e-9 * a.0 && (a.1 - b.1).abs() < 1e-9 * a.1, "{:?} vs {:?}", a, b);
                }
            }
        }
    )*};
}

exact_round_trip! {
    geotiff_exact: Format::GeoTiff, voids = true, keeps_cell = true;
    exr_exact: Format::Exr, voids = true, keeps_cell = false;
    npy_exact: Format::Npy, voids = true, keeps_cell = false;
    r32_exact: Format::R32, voids = true, keeps_cell = false;
    ascii_exact: Format::AsciiGrid, voids = true, keeps_cell = true;
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// PNG16 with the automatic mapping: error <= half a quantisation step.
    #[test]
    fn png16_within_half_step(hf in fields(true)) {
        let back = round_trip(&hf, Format::Png, &WriteOptions::default(), &ReadOptions::default());
        let (lo, hi) = hf.min_max().unwrap();
        let step = ((hi - lo) as f64 / 65534.0).max(1e-9);
        let tol = step / 2.0 + 1e-6 * (hi.abs().max(lo.abs()) as f64 + 1.0);
        prop_assert!(max_err(&hf, &back) <= tol, "err {} > {}", max_err(&hf, &back), tol);
    }

    /// PNG16 with an explicit mapping and Terrain-RGB (0.1 m steps).
    #[test]
    fn png16_mapping_and_terrain_rgb(hf in fields(false)) {
        let w = WriteOptions { mapping: Some((-1000.0, 0.1)), ..Default::default() };
        let back = round_trip(&hf, Format::Png, &w, &ReadOptions::default());
        prop_assert!(max_err(&hf, &back) <= 0.05 + 1e-3);
        let back = round_trip(&hf, Format::TerrainRgb, &WriteOptions::default(), &ReadOptions { png: PngMode::TerrainRgb, ..Default::default() });
        prop_assert!(max_err(&hf, &back) <= 0.05 + 1e-3);
    }

    /// `.r16` with a mapping given on both sides: error <= half a step.
    #[test]
    fn r16_within_half_step(hf in fields(false)) {
        let m = (-600.0, 0.08);
        let w = WriteOptions { mapping: Some(m), ..Default::default() };
        let r = ReadOptions { width: Some(hf.width()), height: Some(hf.height()), r16_mapping: m, ..Default::default() };
        let back = round_trip(&hf, Format::R16, &w, &r);
        prop_assert!(max_err(&hf, &back) <= 0.04 + 1e-3);
    }
}

#[test]
fn terrain_rgb_is_detected_from_its_text_chunk() {
    let hf = Heightfield::from_fn(5, 4, 1.0, 1.0, |x, y| 100.0 + (x * 3 + y) as f32 * 0.5);
    let bytes = encode(&hf, Format::TerrainRgb, &WriteOptions::default()).unwrap();
    let r = read_bytes(&bytes, None, &ReadOptions::default()).unwrap();
    assert_eq!(r.format, Format::TerrainRgb);
    assert!(max_err(&hf, &r.heightfield) <= 0.051);
}

#[test]
fn hgt_and_f32_sidecar_round_trip_through_files() {
    let dir = tempfile::tempdir().unwrap();
    let hf = Heightfield::from_fn(1201, 1201, 60.0, 90.0, |x, y| {
        ((x * 7 + y * 3) % 4000) as f32 - 100.0
    });
    let mut hf_void = hf.clone();
    hf_void.set(5, 7, f32::NAN);
    let p = dir.path().join("N47E011.hgt");
    write(&p, &hf_void, &WriteOptions::default()).unwrap();
    let back = read(&p, &ReadOptions::default()).unwrap().heightfield;
    assert_eq!(max_err(&hf_void, &back), 0.0);
    let p = dir.path().join("dem.f32");
    write(&p, &hf_void, &WriteOptions::default()).unwrap();
    assert!(dir.path().join("dem.json").is_file());
    let back = read(&p, &ReadOptions::default()).unwrap().heightfield;
    assert_eq!(max_err(&hf_void, &back), 0.0);
    assert_eq!(back.cell_size(), (60.0, 90.0));
    // The testdata loader understands the sidecar written by relief-io.
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("dem.json")).unwrap()).unwrap();
    assert_eq!(side["nodata"].as_f64(), Some(-9999.0));
    assert_eq!(side["nodata_count"].as_u64(), Some(1));
}

#[test]
fn failed_writes_leave_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let void = Heightfield::new(3, 2, vec![f32::NAN; 6], 1.0, 1.0).unwrap();
    for ext in ["png", "r16", "tif", "hgt", "npz", "xyz"] {
        let p = dir.path().join(format!("out.{ext}"));
        let e = write(&p, &void, &WriteOptions::default());
        if ext == "tif" {
            // A NaN-only GeoTIFF is representable; remove it and go on.
            e.unwrap();
            std::fs::remove_file(&p).unwrap();
            continue;
        }
        assert!(
            e.is_err(),
            "{ext}: writing an all-void / unsupported raster must fail"
        );
    }
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "files left behind: {left:?}");
    // A missing directory is an error naming the path, and creates nothing.
    let hf = Heightfield::from_fn(3, 3, 1.0, 1.0, |x, _| x as f32);
    let e = write(
        &dir.path().join("missing/out.tif"),
        &hf,
        &WriteOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("missing"), "{e}");
    // An existing file is replaced only after a complete write.
    let p = dir.path().join("keep.tif");
    write(&p, &hf, &WriteOptions::default()).unwrap();
    let e = write(
        &p,
        &void,
        &WriteOptions {
            format: Some(Format::Png),
            ..Default::default()
        },
    );
    assert!(e.is_err());
    assert_eq!(
        read(&p, &ReadOptions::default())
            .unwrap()
            .heightfield
            .as_slice(),
        hf.as_slice()
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn geotiff_written_back_keeps_the_georeference() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/grandcanyon.tif");
    let r = read(&src, &ReadOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("gc.tif");
    write(&p, &r.heightfield, &WriteOptions::default()).unwrap();
    let back = read(&p, &ReadOptions::default()).unwrap();
    assert_eq!(back.dtype, "float32");
    assert_eq!(back.heightfield.georef(), r.heightfield.georef());
    assert_eq!(back.heightfield.cell_size(), r.heightfield.cell_size());
    assert_eq!(max_err(&r.heightfield, &back.heightfield), 0.0);
}

#[test]
fn alps_converts_to_every_format_and_back() {
    let Some(dir) = relief_testdata::dem_dir() else {
        return;
    };
    let src = read(&dir.join("alps_dem.tiff"), &ReadOptions::default())
        .unwrap()
        .heightfield;
    let (lo, hi) = src.min_max().unwrap();
    let out = tempfile::tempdir().unwrap();
    let r = ReadOptions {
        width: Some(src.width()),
        height: Some(src.height()),
        ..Default::default()
    };
    for (ext, tol) in [
        ("tif", 0.0),
        ("exr", 0.0),
        ("npy", 0.0),
        ("r32", 0.0),
        ("asc", 0.0),
        ("f32", 0.0),
        ("png", (hi - lo) as f64 / 65535.0 / 2.0 + 1e-3),
    ] {
        let p = out.path().join(format!("alps.{ext}"));
        write(&p, &src, &WriteOptions::default()).unwrap();
        let back = read(&p, &r).unwrap().heightfield;
        let e = max_err(&src, &back);
        assert!(e <= tol, "{ext}: max error {e} > {tol}");
    }
}

#[test]
fn ascii_georeference_survives_a_geotiff_round_trip() {
    let hf = Heightfield::from_fn(5, 4, 25.0, 25.0, |x, y| (x * 3 + y) as f32);
    let asc = encode(&hf, Format::AsciiGrid, &WriteOptions::default()).unwrap();
    let a = read_bytes(&asc, Some(Path::new("x.asc")), &ReadOptions::default()).unwrap();
    let mut g = a.heightfield.georef().cloned().unwrap();
    g.geotransform = Some([1000.0, 25.0, 0.0, 5100.0, 0.0, -25.0]);
    let hf2 = a.heightfield.clone().with_georef(Some(g));
    let tif = encode(&hf2, Format::GeoTiff, &WriteOptions::default()).unwrap();
    let t = read_bytes(&tif, None, &ReadOptions::default()).unwrap();
    assert_eq!(t.heightfield.cell_size(), (25.0, 25.0));
    assert_eq!(
        t.heightfield.georef().unwrap().geotransform,
        Some([1000.0, 25.0, 0.0, 5100.0, 0.0, -25.0])
    );
    // And back to ASCII: the corner is kept.
    let asc2 = String::from_utf8(
        encode(&t.heightfield, Format::AsciiGrid, &WriteOptions::default()).unwrap(),
    )
    .unwrap();
    assert!(
        asc2.contains("xllcorner 1000\n") && asc2.contains("yllcorner 5000\n"),
        "{asc2}"
    );
}

/// Issue 14: a projected grid whose CRS units differ from ground metres (Web Mercator: 76.4 m
/// pixels that are 61 m on the ground) keeps its corner and CRS pixel size in an ASCII grid.
#[test]
fn ascii_output_keeps_the_position_in_crs_units() {
    let g = relief_heightfield::GeoRef {
        geotransform: Some([-12_601_714.25, 76.5, 0.0, 4_344_069.5, 0.0, -76.5]),
        ..Default::default()
    };
    let hf = Heightfield::from_fn(6, 4, 61.2, 61.2, |x, y| (x + y) as f32).with_georef(Some(g));
    let asc = String::from_utf8(encode(&hf, Format::AsciiGrid, &WriteOptions::default()).unwrap())
        .unwrap();
    assert!(asc.contains("xllcorner -12601714.25\n"), "{asc}");
    assert!(
        asc.contains(&format!("yllcorner {}\n", 4_344_069.5 - 4.0 * 76.5)),
        "{asc}"
    );
    assert!(asc.contains("cellsize 76.5\n"), "{asc}");
    let back = read_bytes(
        asc.as_bytes(),
        Some(Path::new("x.asc")),
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(
        back.heightfield.georef().unwrap().geotransform,
        Some([-12_601_714.25, 76.5, 0.0, 4_344_069.5, 0.0, -76.5])
    );
}

#[test]
fn raw_samples_that_look_like_text_keep_their_hinted_format() {
    // 0x7b = '{', 0x20 = ' ': a raw file may begin like JSON or ASCII text.
    let v = f32::from_le_bytes([0x7b, 0x20, 0x22, 0x41]);
    let hf = Heightfield::new(2, 1, vec![v, 1.0], 1.0, 1.0).unwrap();
    let bytes = encode(&hf, Format::R32, &WriteOptions::default()).unwrap();
    let r = read_bytes(
        &bytes,
        Some(Path::new("a.r32")),
        &ReadOptions {
            width: Some(2),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(r.format, Format::R32);
    assert_eq!(r.heightfield.as_slice(), hf.as_slice());
}

#[test]
fn files_larger_than_the_cell_limit_allows_are_refused_unread() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("big.r32");
    std::fs::write(&p, vec![0u8; 4 * 64 * 64]).unwrap();
    let small = ReadOptions {
        max_cells: 16,
        ..Default::default()
    };
    let e = read(&p, &small).unwrap_err().to_string();
    assert!(e.contains("max_cells") && e.contains("big.r32"), "{e}");
    // Within the byte cap but over the cell limit: the dimension check names the limit.
    let mid = ReadOptions {
        max_cells: 2048,
        ..Default::default()
    };
    let e = read(&p, &mid).unwrap_err().to_string();
    assert!(e.contains("exceed the limit"), "{e}");
    assert_eq!(
        read(&p, &ReadOptions::default())
            .unwrap()
            .heightfield
            .width(),
        64
    );
}
