//! Reliability of relief-io: atomic byte writes, the in-memory `.f32` + sidecar reader, the
//! cell limit of every reader and the regression inputs found by fuzzing (`fuzz/`).

use std::path::Path;

use relief_io::{ReadOptions, read_f32_sidecar_bytes, write_bytes_atomic};

fn temp_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp-"))
        .collect()
}

#[test]
fn write_bytes_atomic_replaces_and_leaves_no_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("model.sct");
    write_bytes_atomic(&p, b"first").unwrap();
    write_bytes_atomic(&p, b"second version").unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), b"second version");
    assert!(temp_files(dir.path()).is_empty());
    // A missing directory is an error naming the path; nothing is created.
    let q = dir.path().join("missing/out.sct");
    let e = write_bytes_atomic(&q, b"x").unwrap_err().to_string();
    assert!(e.contains("missing/out.sct"), "{e}");
    // A path without a file name is refused.
    assert!(write_bytes_atomic(Path::new("/"), b"x").is_err());
}

#[cfg(unix)]
#[test]
fn write_bytes_atomic_into_read_only_directory_keeps_old_file() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("keep.bin");
    std::fs::write(&p, b"old").unwrap();
    std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o555)).unwrap();
    // root ignores directory permissions: then the write succeeds, which is fine too.
    let res = write_bytes_atomic(&p, b"new");
    std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    match res {
        Err(e) => {
            assert!(e.to_string().contains("keep.bin"), "{e}");
            assert_eq!(std::fs::read(&p).unwrap(), b"old");
        }
        Ok(()) => assert_eq!(std::fs::read(&p).unwrap(), b"new"),
    }
    assert!(temp_files(dir.path()).is_empty());
}

#[test]
fn f32_sidecar_from_memory() {
    let data: Vec<u8> = (0..6)
        .flat_map(|i| (i as f32 * 1.5).to_le_bytes())
        .collect();
    let json = br#"{"width": 3, "height": 2, "cell_size_x_m": 10, "cell_size_y_m": 20}"#;
    let r = read_f32_sidecar_bytes(&data, Some(json), &ReadOptions::default()).unwrap();
    assert_eq!((r.heightfield.width(), r.heightfield.height()), (3, 2));
    assert_eq!(r.heightfield.cell_size(), (10.0, 20.0));
    assert_eq!(r.heightfield.as_slice()[5], 7.5);
    let e = read_f32_sidecar_bytes(
        &data,
        Some(b"{\"width\": 4, \"height\": 2}"),
        &ReadOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("sidecar declares 4 x 2"), "{e}");
    let e = read_f32_sidecar_bytes(&data, Some(b"not json"), &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("sidecar"), "{e}");
    // Without a sidecar the width option gives the size.
    let o = ReadOptions {
        width: Some(2),
        ..Default::default()
    };
    let r = read_f32_sidecar_bytes(&data, None, &o).unwrap();
    assert_eq!((r.heightfield.width(), r.heightfield.height()), (2, 3));
}

#[cfg(target_os = "linux")]
#[test]
fn stale_temporaries_of_dead_runs_are_removed_by_the_next_write() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("model.sct");
    // pid_max is at most 2^22 on Linux: this process cannot exist.
    let dead = dir.path().join(".model.sct.tmp-999999999-0");
    let alive = dir
        .path()
        .join(format!(".model.sct.tmp-{}-77", std::process::id()));
    let other = dir.path().join(".other.tif.tmp-999999999-0");
    for f in [&dead, &alive, &other] {
        std::fs::write(f, b"partial").unwrap();
    }
    write_bytes_atomic(&p, b"done").unwrap();
    assert!(!dead.exists(), "stale temporary of a dead process kept");
    assert!(alive.exists(), "temporary of a live process removed");
    // Issue 18: leftovers of killed runs go with the next write into the folder, whatever
    // output they were for.
    assert!(!other.exists(), "stale temporary of another target kept");
}

mod limits {
    //! The cell limit protects every reader: a file declaring an absurd size is refused before
    //! allocation, and a real file of `n` cells needs `max_cells >= n` (raising it is explicit).

    use std::io::Write;
    use std::path::Path;

    use relief_heightfield::Heightfield;
    use relief_io::{
        Format, IoError, PngMode, ReadOptions, WriteOptions, encode, read_bytes,
        read_f32_sidecar_bytes,
    };

    fn root(e: &IoError) -> &IoError {
        match e {
            IoError::InFile { source, .. } => root(source),
            e => e,
        }
    }

    /// Asserts that `res` failed because of the declared size (a dimensions error).
    fn assert_size_refused(res: relief_io::Result<relief_io::Raster>, what: &str) {
        let e = res.err().unwrap_or_else(|| panic!("{what}: accepted"));
        assert!(
            matches!(root(&e), IoError::Dimensions { .. }),
            "{what}: not a size error: {e}"
        );
    }

    /// A size error, or a malformed-file error where the decoder notices first.
    fn assert_size_or_malformed(res: relief_io::Result<relief_io::Raster>, what: &str) {
        let e = res.err().unwrap_or_else(|| panic!("{what}: accepted"));
        assert!(
            matches!(
                root(&e),
                IoError::Dimensions { .. } | IoError::Malformed { .. }
            ),
            "{what}: {e}"
        );
    }

    fn terrain(w: usize, h: usize) -> Heightfield {
        Heightfield::from_fn(w, h, 30.0, 30.0, |x, y| {
            (100.0 + 3.0 * x as f64 + 2.0 * (y as f64 * 0.3).sin()) as f32
        })
    }

    fn opts(max_cells: usize) -> ReadOptions {
        ReadOptions {
            max_cells,
            ..Default::default()
        }
    }

    /// Reads `bytes` (named `name`) with the limit one below and at its cell count `n`.
    fn check_limit(bytes: &[u8], name: &str, n: usize, base: ReadOptions) {
        let hint = Some(Path::new(name));
        let below = ReadOptions {
            max_cells: n - 1,
            ..base.clone()
        };
        let e = read_bytes(bytes, hint, &below).unwrap_err();
        assert!(
            matches!(root(&e), IoError::Dimensions { .. }),
            "{name}: {e}"
        );
        assert!(e.to_string().contains("max_cells"), "{name}: {e}");
        let at = ReadOptions {
            max_cells: n,
            ..base
        };
        let r = read_bytes(bytes, hint, &at).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(r.heightfield.len(), n, "{name}");
    }

    #[test]
    fn every_writable_format_obeys_the_limit_and_raising_it_reads() {
        let hf = terrain(37, 23);
        let n = hf.len();
        for (format, name) in [
            (Format::GeoTiff, "a.tif"),
            (Format::AsciiGrid, "a.asc"),
            (Format::Png, "a.png"),
            (Format::Exr, "a.exr"),
            (Format::R32, "a.r32"),
            (Format::R16, "a.r16"),
            (Format::Npy, "a.npy"),
        ] {
            let bytes = encode(&hf, format, &WriteOptions::default()).unwrap();
            let base = ReadOptions {
                width: Some(37),
                ..Default::default()
            };
            check_limit(&bytes, name, n, base);
        }
        let bytes = encode(&hf, Format::TerrainRgb, &WriteOptions::default()).unwrap();
        let base = ReadOptions {
            png: PngMode::TerrainRgb,
            ..Default::default()
        };
        check_limit(&bytes, "a.png", n, base);
        // SRTM tiles have a fixed size: 1201^2 cells.
        let tile = terrain(1201, 1201);
        let bytes = encode(&tile, Format::Hgt, &WriteOptions::default()).unwrap();
        check_limit(&bytes, "N47E011.hgt", 1201 * 1201, ReadOptions::default());
        // .f32 + sidecar.
        let data = encode(&hf, Format::F32Sidecar, &WriteOptions::default()).unwrap();
        let side = br#"{"width": 37, "height": 23, "cell_size_m": 30}"#;
        let e = read_f32_sidecar_bytes(&data, Some(side), &opts(n - 1)).unwrap_err();
        assert!(matches!(root(&e), IoError::Dimensions { .. }), "{e}");
        assert!(read_f32_sidecar_bytes(&data, Some(side), &opts(n)).is_ok());
        // JSON grid.
        let values: Vec<String> = hf.as_slice().iter().map(|v| v.to_string()).collect();
        let json = format!(
            r#"{{"width": 37, "height": 23, "values": [{}]}}"#,
            values.join(",")
        );
        check_limit(json.as_bytes(), "a.json", n, ReadOptions::default());
        // NPZ.
        let npy = encode(&hf, Format::Npy, &WriteOptions::default()).unwrap();
        let mut z = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
        z.start_file("elevation.npy", zip::write::SimpleFileOptions::default())
            .unwrap();
        z.write_all(&npy).unwrap();
        let npz = z.finish().unwrap().into_inner();
        check_limit(&npz, "a.npz", n, ReadOptions::default());
    }

    #[test]
    fn absurd_declared_sizes_are_refused_for_every_format() {
        let o = ReadOptions::default();
        let huge = 1u64 << 31;
        // GeoTIFF: fixtures/bad holds 1e6 x 1e6 and u32::MAX^2 headers (bad_files.rs); here a
        // real file with its width patched.
        let hf = terrain(8, 8);
        let mut tif = encode(&hf, Format::GeoTiff, &WriteOptions::default()).unwrap();
        let ifd = u32::from_le_bytes(tif[4..8].try_into().unwrap()) as usize;
        let count = u16::from_le_bytes([tif[ifd], tif[ifd + 1]]) as usize;
        for k in 0..count {
            let e = ifd + 2 + 12 * k;
            let tag = u16::from_le_bytes([tif[e], tif[e + 1]]);
            if tag == 256 || tag == 257 {
                // Force LONG type so the value holds 4e9.
                tif[e + 2..e + 4].copy_from_slice(&4u16.to_le_bytes());
                tif[e + 8..e + 12].copy_from_slice(&4_000_000_000u32.to_le_bytes());
            }
        }
        // The tiff crate itself notices that the strips cannot hold 4e9^2 samples.
        assert_size_or_malformed(read_bytes(&tif, Some(Path::new("a.tif")), &o), "tif");
        // PNG: IHDR width/height (checked before decoding, the CRC is not even looked at).
        let mut png = encode(&hf, Format::Png, &WriteOptions::default()).unwrap();
        png[16..20].copy_from_slice(&0x7fff_ffffu32.to_be_bytes());
        png[20..24].copy_from_slice(&0x7fff_ffffu32.to_be_bytes());
        assert_size_refused(read_bytes(&png, Some(Path::new("a.png")), &o), "png");
        let tro = ReadOptions {
            png: PngMode::TerrainRgb,
            ..Default::default()
        };
        assert_size_refused(
            read_bytes(&png, Some(Path::new("a.png")), &tro),
            "terrain-rgb",
        );
        // EXR: the dataWindow attribute.
        let mut exr = encode(&hf, Format::Exr, &WriteOptions::default()).unwrap();
        let at = exr
            .windows(10)
            .position(|w| w == b"dataWindow")
            .expect("dataWindow attribute")
            + b"dataWindow\0box2i\0".len()
            + 4;
        exr[at + 8..at + 12].copy_from_slice(&(1i32 << 30).to_le_bytes());
        exr[at + 12..at + 16].copy_from_slice(&(1i32 << 30).to_le_bytes());
        assert_size_or_malformed(read_bytes(&exr, Some(Path::new("a.exr")), &o), "exr");
        // ASCII grid.
        let asc = format!("ncols {huge}\nnrows {huge}\ncellsize 1\n1 2 3\n");
        assert_size_refused(read_bytes(asc.as_bytes(), None, &o), "asc");
        // NPY (and the same array inside an NPZ).
        let hdr =
            format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({huge}, {huge}), }}");
        let mut npy = b"\x93NUMPY\x01\x00".to_vec();
        npy.extend_from_slice(&(hdr.len() as u16 + 1).to_le_bytes());
        npy.extend_from_slice(hdr.as_bytes());
        npy.push(b'\n');
        npy.extend_from_slice(&[0u8; 64]);
        assert_size_refused(read_bytes(&npy, None, &o), "npy");
        let mut z = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
        z.start_file("z.npy", zip::write::SimpleFileOptions::default())
            .unwrap();
        z.write_all(&npy).unwrap();
        let npz = z.finish().unwrap().into_inner();
        assert_size_refused(read_bytes(&npz, None, &o), "npz");
        // Raw: the size comes from the options; absurd options are refused.
        let raw = vec![0u8; 64];
        for name in ["a.r16", "a.r32", "a.f32"] {
            let ro = ReadOptions {
                width: Some(huge as usize),
                height: Some(huge as usize),
                ..Default::default()
            };
            assert!(
                read_bytes(&raw, Some(Path::new(name)), &ro).is_err(),
                "{name}"
            );
        }
        // .f32 sidecar and JSON grid declaring 2^62 cells.
        let side = format!(r#"{{"width": {huge}, "height": {huge}}}"#);
        assert_size_refused(
            read_f32_sidecar_bytes(&raw, Some(side.as_bytes()), &o),
            "sidecar",
        );
        let grid = format!(r#"{{"width": {huge}, "height": {huge}, "values": [1, 2]}}"#);
        assert_size_refused(read_bytes(grid.as_bytes(), None, &o), "json grid");
        // The limit itself must be sane.
        for bad in [0, usize::MAX] {
            let e = read_bytes(&npy, None, &opts(bad)).unwrap_err().to_string();
            assert!(e.contains("max_cells"), "{e}");
        }
    }

    #[test]
    fn json_grid_counts_values_before_storing_them() {
        // Declares 2 x 2 but holds 5 values, values that are not numbers, not an array.
        let o = ReadOptions::default();
        let err = |json: &[u8]| read_bytes(json, None, &o).unwrap_err().to_string();
        let e = err(br#"{"width":2,"height":2,"values":[1,2,3,4,5]}"#);
        assert!(e.contains("holds 5"), "{e}");
        let e = err(br#"{"values":[1,"x",3,null],"width":2,"height":2}"#);
        assert!(e.contains("values[1]"), "{e}");
        let json = br#"{"values":[1,2.5,null,4],"width":2,"height":2,"cell_size":5}"#;
        let r = read_bytes(json, None, &o).unwrap();
        assert_eq!(r.heightfield.cell_size(), (5.0, 5.0));
        assert!(r.heightfield.as_slice()[2].is_nan());
        assert_eq!(r.heightfield.as_slice()[1], 2.5);
        let e = err(br#"{"width":2,"height":2,"values":{"a":1}}"#);
        assert!(e.contains("not an array"), "{e}");
    }
}

mod streaming {
    //! `GeoTiffStripWriter`: same file content as `write` for any row batching, atomic, and no
    //! leftovers when the producer stops early.

    use std::path::Path;

    use relief_heightfield::Heightfield;
    use relief_io::{GeoTiffStripWriter, ReadOptions, WriteOptions, read, write};

    fn leftovers(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect()
    }

    fn fixture() -> Heightfield {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/grandcanyon.tif");
        read(&p, &ReadOptions::default()).unwrap().heightfield
    }

    fn stream(path: &Path, hf: &Heightfield, batch: usize) {
        let mut out =
            GeoTiffStripWriter::create(path, hf.width(), hf.height(), hf.cell_size(), hf.georef())
                .unwrap();
        for rows in hf.as_slice().chunks(hf.width() * batch) {
            out.write_rows(rows).unwrap();
        }
        assert_eq!(out.rows_written(), hf.height());
        out.finish().unwrap();
    }

    #[test]
    fn streamed_file_reads_back_like_a_whole_write() {
        let mut hf = fixture();
        // A void so the nodata tag is exercised.
        hf.set(5, 7, f32::NAN);
        let dir = tempfile::tempdir().unwrap();
        let whole = dir.path().join("whole.tif");
        write(&whole, &hf, &WriteOptions::default()).unwrap();
        let a = read(&whole, &ReadOptions::default()).unwrap();
        for batch in [1, 3, 64, hf.height()] {
            let p = dir.path().join(format!("s{batch}.tif"));
            stream(&p, &hf, batch);
            let b = read(&p, &ReadOptions::default()).unwrap();
            assert_eq!(b.heightfield.width(), hf.width());
            let same = a
                .heightfield
                .as_slice()
                .iter()
                .zip(b.heightfield.as_slice())
                .all(|(x, y)| x.to_bits() == y.to_bits());
            assert!(same, "batch {batch}: samples differ");
            assert_eq!(b.heightfield.cell_size(), a.heightfield.cell_size());
            assert_eq!(
                b.heightfield.georef(),
                a.heightfield.georef(),
                "batch {batch}"
            );
            assert_eq!(b.nodata.map(f64::is_nan), Some(true));
            assert!(b.heightfield.get(5, 7).is_nan());
        }
        // The georeference of the fixture survived (EPSG code and geotransform).
        let g = a.heightfield.georef().expect("fixture is georeferenced");
        assert!(g.geotransform.is_some());
    }

    #[test]
    fn strip_layout_for_wide_and_narrow_rasters() {
        let dir = tempfile::tempdir().unwrap();
        for (w, h) in [(1, 1), (1, 70000), (20000, 3), (257, 129)] {
            let hf = Heightfield::from_fn(w, h, 2.0, 3.0, |x, y| (x as f32) - 0.5 * y as f32);
            let p = dir.path().join(format!("{w}x{h}.tif"));
            stream(&p, &hf, 7);
            let b = read(&p, &ReadOptions::default()).unwrap().heightfield;
            assert_eq!(b.as_slice(), hf.as_slice(), "{w} x {h}");
            assert_eq!(b.cell_size(), (2.0, 3.0));
        }
    }

    #[test]
    fn misuse_and_early_stop_leave_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("o.tif");
        let mut out = GeoTiffStripWriter::create(&p, 4, 3, (1.0, 1.0), None).unwrap();
        assert!(out.write_rows(&[0.0; 5]).is_err(), "partial row accepted");
        out.write_rows(&[1.0; 8]).unwrap();
        assert!(
            out.write_rows(&[1.0; 8]).is_err(),
            "rows past the end accepted"
        );
        let e = out.finish().unwrap_err().to_string();
        assert!(e.contains("3 rows were announced"), "{e}");
        assert!(
            leftovers(dir.path()).is_empty(),
            "{:?}",
            leftovers(dir.path())
        );
        // Dropped mid-way (e.g. the producer failed): the temporary is removed.
        let mut out = GeoTiffStripWriter::create(&p, 4, 3, (1.0, 1.0), None).unwrap();
        out.write_rows(&[1.0; 4]).unwrap();
        drop(out);
        assert!(
            leftovers(dir.path()).is_empty(),
            "{:?}",
            leftovers(dir.path())
        );
        // An existing file is replaced only by a complete one.
        std::fs::write(&p, b"old").unwrap();
        let mut out = GeoTiffStripWriter::create(&p, 4, 3, (1.0, 1.0), None).unwrap();
        out.write_rows(&[2.0; 8]).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        out.write_rows(&[2.0; 4]).unwrap();
        out.finish().unwrap();
        let b = read(&p, &ReadOptions::default()).unwrap().heightfield;
        assert_eq!(b.as_slice(), &[2.0; 12]);
        // Bad arguments.
        assert!(GeoTiffStripWriter::create(&p, 0, 3, (1.0, 1.0), None).is_err());
        // Past 4 GiB of samples the file becomes a BigTIFF (nothing is allocated up front);
        // a side beyond what a TIFF can describe is refused.
        drop(GeoTiffStripWriter::create(&p, 40000, 40000, (1.0, 1.0), None).unwrap());
        assert!(GeoTiffStripWriter::create(&p, 1 << 33, 1, (1.0, 1.0), None).is_err());
        assert!(GeoTiffStripWriter::create(&p, 4, 3, (-1.0, 1.0), None).is_err());
        assert!(
            GeoTiffStripWriter::create(&dir.path().join("no/o.tif"), 4, 3, (1.0, 1.0), None)
                .is_err()
        );
        assert_eq!(leftovers(dir.path()), ["o.tif"]);
    }
}

/// Issue 18: a compressed GeoTIFF whose strips hold fewer bytes than its declared samples could
/// inflate from (DEFLATE: at most 1032:1) is refused from its tags, before the decoder
/// allocates the image.
#[test]
fn geotiff_strips_too_small_for_their_samples_are_refused() {
    use relief_heightfield::Heightfield;
    let hf = Heightfield::from_fn(256, 256, 10.0, 10.0, |x, y| (x * 3 + y) as f32);
    let opts = relief_io::WriteOptions {
        compression: relief_io::TiffCompression::Deflate,
        ..Default::default()
    };
    let mut b = relief_io::encode(&hf, relief_io::Format::GeoTiff, &opts).unwrap();
    assert!(relief_io::read_bytes(&b, None, &ReadOptions::default()).is_ok());
    // Little-endian IFD: count u16, then 12-byte entries (tag, type, count, value/offset).
    let u16_at = |b: &[u8], i: usize| u16::from_le_bytes([b[i], b[i + 1]]) as usize;
    let u32_at =
        |b: &[u8], i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]) as usize;
    let ifd = u32_at(&b, 4);
    let entries = u16_at(&b, ifd);
    let e = (0..entries)
        .map(|k| ifd + 2 + 12 * k)
        .find(|&e| u16_at(&b, e) == 279)
        .expect("StripByteCounts");
    let (ty, count) = (u16_at(&b, e + 2), u32_at(&b, e + 4));
    let size = if ty == 3 { 2 } else { 4 };
    let at = if count * size <= 4 {
        e + 8
    } else {
        u32_at(&b, e + 8)
    };
    for k in 0..count {
        let p = at + k * size;
        b[p] = 1;
        for q in 1..size {
            b[p + q] = 0;
        }
    }
    let e = relief_io::read_bytes(&b, None, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("1032:1"), "{e}");
}

#[test]
fn geotiff_compressions_relief_cannot_decode_are_named_with_the_way_out() {
    // GDAL writes LERC, JPEG 2000, LZMA, WebP...: the message names the scheme and the
    // gdal_translate line that converts the file, not "malformed ... unsupported error".
    use relief_heightfield::Heightfield;
    let hf = Heightfield::from_fn(16, 16, 10.0, 10.0, |x, y| (x * 3 + y) as f32);
    let opts = relief_io::WriteOptions::default();
    let mut b = relief_io::encode(&hf, relief_io::Format::GeoTiff, &opts).unwrap();
    let u16_at = |b: &[u8], i: usize| u16::from_le_bytes([b[i], b[i + 1]]) as usize;
    let ifd = u32::from_le_bytes([b[4], b[5], b[6], b[7]]) as usize;
    let e = (0..u16_at(&b, ifd))
        .map(|k| ifd + 2 + 12 * k)
        .find(|&e| u16_at(&b, e) == 259)
        .expect("Compression");
    for (code, name) in [(34887u16, "LERC"), (34712, "JPEG 2000"), (50001, "WebP")] {
        b[e + 8..e + 10].copy_from_slice(&code.to_le_bytes());
        let err = relief_io::read_bytes(&b, None, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(name) && err.contains("gdal_translate") && !err.contains("malformed"),
            "{err}"
        );
    }
}

/// Issue 18: cell sizes and origins that are not finite positive numbers are refused with the
/// field named; a present but non-numeric sidecar cell size is not silently 1 m.
#[test]
fn absurd_cell_sizes_and_origins_name_the_field() {
    let asc = b"ncols 2\nnrows 2\nxllcorner nan\nyllcorner 0\ncellsize 30\n1 2\n3 4\n";
    let e = relief_io::read_bytes(asc, None, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("xllcorner"), "{e}");
    let asc = b"ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1e308\n1 2\n3 4\n";
    let e = relief_io::read_bytes(asc, None, &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("cellsize"), "{e}");
    let data = [0u8; 16];
    for side in [
        r#"{"width": 2, "height": 2, "cell_size_m": "30 m"}"#,
        r#"{"width": 2, "height": 2, "cell_size_m": 0}"#,
        r#"{"width": 2, "height": 2, "cell_size_x_m": -5, "cell_size_y_m": 5}"#,
    ] {
        let e = read_f32_sidecar_bytes(&data, Some(side.as_bytes()), &ReadOptions::default())
            .unwrap_err();
        assert!(e.to_string().contains("cell_size"), "{side}: {e}");
    }
    let ok = read_f32_sidecar_bytes(
        &data,
        Some(br#"{"width": 2, "height": 2, "cell_size_m": 30}"#),
        &ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(ok.heightfield.cell_size(), (30.0, 30.0));
    let opts = ReadOptions {
        cell_size: Some((1e-320, 1e-320)),
        ..Default::default()
    };
    assert!(read_f32_sidecar_bytes(&data, None, &opts).is_err());
}
