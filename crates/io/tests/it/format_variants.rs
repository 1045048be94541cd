//! Reader coverage of the sample types and layouts each format allows: GeoTIFF (u8/u16/i32/f64,
//! deflate, tiles, big-endian, GDAL_NODATA), NPY (byte orders, Fortran order), EXR f16, PNG 8-bit.

use std::io::Cursor;
use std::path::Path;

use relief_io::{Format, PngMode, ReadOptions, read, read_bytes};
use tiff::encoder::{Compression, TiffEncoder, colortype, compression};
use tiff::tags::Tag;

fn expect(w: usize, h: usize) -> Vec<f32> {
    (0..w * h).map(|i| ((i * 37) % 200) as f32).collect()
}

fn read_tif(bytes: &[u8]) -> relief_io::Raster {
    read_bytes(bytes, None, &ReadOptions::default()).unwrap()
}

#[test]
fn geotiff_sample_types_and_compression() {
    let (w, h) = (13usize, 7usize);
    let e = expect(w, h);
    macro_rules! case {
        ($ct:ty, $conv:expr, $dtype:expr) => {{
            let data: Vec<_> = e.iter().map($conv).collect();
            for deflate in [false, true] {
                let mut buf = Cursor::new(Vec::new());
                let mut enc = TiffEncoder::new(&mut buf).unwrap();
                if deflate {
                    enc = enc.with_compression(Compression::Deflate(
                        compression::DeflateLevel::Balanced,
                    ));
                }
                enc.write_image::<$ct>(w as u32, h as u32, &data).unwrap();
                let r = read_tif(buf.get_ref());
                assert_eq!(r.dtype, $dtype);
                assert_eq!(
                    r.heightfield.as_slice(),
                    e.as_slice(),
                    "{} deflate={deflate}",
                    $dtype
                );
            }
        }};
    }
    case!(colortype::Gray8, |v: &f32| *v as u8, "uint8");
    case!(colortype::Gray16, |v: &f32| *v as u16, "uint16");
    case!(colortype::GrayI16, |v: &f32| *v as i16, "int16");
    case!(colortype::GrayI32, |v: &f32| *v as i32, "int32");
    case!(colortype::Gray32Float, |v: &f32| *v, "float32");
    case!(colortype::Gray64Float, |v: &f32| *v as f64, "float64");
}

#[test]
fn geotiff_gdal_nodata_becomes_nan() {
    let data: Vec<i16> = vec![5, -32768, 7, 8, -32768, 10];
    let mut buf = Cursor::new(Vec::new());
    let mut enc = TiffEncoder::new(&mut buf).unwrap();
    let mut img = enc.new_image::<colortype::GrayI16>(3, 2).unwrap();
    img.encoder().write_tag(Tag::GdalNodata, "-32768").unwrap();
    img.write_data(&data).unwrap();
    let r = read_tif(buf.get_ref());
    assert_eq!(r.nodata, Some(-32768.0));
    assert_eq!(r.heightfield.void_count(), 2);
    assert!(r.heightfield.get(1, 0).is_nan() && r.heightfield.get(1, 1).is_nan());
    assert_eq!(r.heightfield.get(2, 1), 10.0);
}

/// Hand-made tiled TIFF (16 x 16 int16 tiles over a 20 x 18 image) in either byte order.
fn tiled_tiff(big: bool, w: u32, h: u32) -> Vec<u8> {
    let (tw, th) = (16u32, 16u32);
    let (nx, ny) = (w.div_ceil(tw), h.div_ceil(th));
    let u16b = |v: u16| {
        if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let u32b = |v: u32| {
        if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let n_entries = 11u16;
    let ifd_len = 2 + n_entries as u32 * 12 + 4;
    let arrays_at = 8 + ifd_len;
    let n_tiles = nx * ny;
    let data_at = arrays_at + 8 * n_tiles;
    let tile_bytes = tw * th * 2;
    let mut out = Vec::new();
    out.extend_from_slice(if big { b"MM\0*" } else { b"II*\0" });
    out.extend_from_slice(&u32b(8));
    out.extend_from_slice(&u16b(n_entries));
    let mut entry = |tag: u16, typ: u16, count: u32, value: u32| {
        out.extend_from_slice(&u16b(tag));
        out.extend_from_slice(&u16b(typ));
        out.extend_from_slice(&u32b(count));
        if typ == 3 && count == 1 {
            out.extend_from_slice(&u16b(value as u16));
            out.extend_from_slice(&[0, 0]);
        } else {
            out.extend_from_slice(&u32b(value));
        }
    };
    entry(256, 4, 1, w);
    entry(257, 4, 1, h);
    entry(258, 3, 1, 16);
    entry(259, 3, 1, 1);
    entry(262, 3, 1, 1);
    entry(277, 3, 1, 1);
    entry(322, 4, 1, tw);
    entry(323, 4, 1, th);
    entry(324, 4, n_tiles, arrays_at);
    entry(325, 4, n_tiles, arrays_at + 4 * n_tiles);
    entry(339, 3, 1, 2);
    out.extend_from_slice(&u32b(0));
    for t in 0..n_tiles {
        out.extend_from_slice(&u32b(data_at + t * tile_bytes));
    }
    for _ in 0..n_tiles {
        out.extend_from_slice(&u32b(tile_bytes));
    }
    for ty in 0..ny {
        for tx in 0..nx {
            for y in 0..th {
                for x in 0..tw {
                    let (gx, gy) = (tx * tw + x, ty * th + y);
                    let v = if gx < w && gy < h {
                        (gy * 100 + gx) as i16 - 500
                    } else {
                        0
                    };
                    out.extend_from_slice(&if big {
                        v.to_be_bytes()
                    } else {
                        v.to_le_bytes()
                    });
                }
            }
        }
    }
    out
}

#[test]
fn geotiff_tiles_in_both_byte_orders() {
    for big in [false, true] {
        let r = read_tif(&tiled_tiff(big, 20, 18));
        assert_eq!((r.heightfield.width(), r.heightfield.height()), (20, 18));
        for (x, y) in [(0, 0), (19, 0), (0, 17), (17, 16), (15, 15), (16, 3)] {
            assert_eq!(
                r.heightfield.get(x, y),
                (y * 100 + x) as f32 - 500.0,
                "big={big} ({x},{y})"
            );
        }
    }
}

fn npy(descr: &str, shape: &str, fortran: bool, data: &[u8]) -> Vec<u8> {
    let mut header = format!(
        "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}",
        if fortran { "True" } else { "False" }
    );
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(data);
    out
}

#[test]
fn npy_byte_orders_types_and_fortran_order() {
    // Logical 2 x 3 grid [[1, 2, 3], [4, 5, 6]].
    let want = [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0];
    let c_order = [1i64, 2, 3, 4, 5, 6];
    let f_order = [1i64, 4, 2, 5, 3, 6];
    let cases: Vec<(&str, bool, Vec<u8>)> = vec![
        (
            ">i2",
            false,
            c_order
                .iter()
                .flat_map(|&v| (v as i16).to_be_bytes())
                .collect(),
        ),
        (
            "<i4",
            true,
            f_order
                .iter()
                .flat_map(|&v| (v as i32).to_le_bytes())
                .collect(),
        ),
        (
            ">f4",
            false,
            c_order
                .iter()
                .flat_map(|&v| (v as f32).to_be_bytes())
                .collect(),
        ),
        (
            "<f8",
            true,
            f_order
                .iter()
                .flat_map(|&v| (v as f64).to_le_bytes())
                .collect(),
        ),
        ("|u1", false, c_order.iter().map(|&v| v as u8).collect()),
        (
            "<u2",
            false,
            c_order
                .iter()
                .flat_map(|&v| (v as u16).to_le_bytes())
                .collect(),
        ),
        (
            "<f2",
            false,
            c_order
                .iter()
                .flat_map(|&v| half::f16::from_f32(v as f32).to_le_bytes())
                .collect(),
        ),
    ];
    for (descr, fortran, data) in cases {
        let bytes = npy(descr, "(2, 3)", fortran, &data);
        let r = read_bytes(&bytes, None, &ReadOptions::default())
            .unwrap_or_else(|e| panic!("{descr}: {e}"));
        assert_eq!(
            (r.heightfield.width(), r.heightfield.height()),
            (3, 2),
            "{descr}"
        );
        assert_eq!(r.heightfield.as_slice(), &want, "{descr} fortran={fortran}");
    }
}

#[test]
fn npz_selects_named_or_first_grid_and_flips_ascending_latitude() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.npz");
    {
        let f = std::fs::File::create(&p).unwrap();
        let mut z = zip::ZipWriter::new(f);
        let opt = zip::write::SimpleFileOptions::default();
        use std::io::Write;
        let le = |v: &[f64]| v.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<_>>();
        let le32 = |v: &[f32]| v.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<_>>();
        for (name, descr, shape, data) in [
            ("latitude.npy", "<f8", "(2,)", le(&[10.0, 10.1])),
            ("longitude.npy", "<f8", "(3,)", le(&[0.0, 0.1, 0.2])),
            (
                "grid.npy",
                "<f4",
                "(2, 3)",
                le32(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]),
            ),
            ("other.npy", "<f4", "(1, 2)", le32(&[7.0, 8.0])),
        ] {
            z.start_file(name, opt).unwrap();
            z.write_all(&npy(descr, shape, false, &data)).unwrap();
        }
        z.finish().unwrap();
    }
    let r = read(&p, &ReadOptions::default()).unwrap();
    assert!(r.rows_flipped);
    assert_eq!(r.heightfield.as_slice(), &[4.0, 5.0, 6.0, 1.0, 2.0, 3.0]);
    let (cx, cy) = r.heightfield.cell_size();
    assert!(
        (cx - 10_960.0).abs() < 30.0 && (cy - 11_060.0).abs() < 30.0,
        "{cx} {cy}"
    );
    let o = ReadOptions {
        npz_array: Some("other".into()),
        ..Default::default()
    };
    assert_eq!(read(&p, &o).unwrap().heightfield.as_slice(), &[7.0, 8.0]);
    let o = ReadOptions {
        npz_array: Some("nope".into()),
        ..Default::default()
    };
    let e = read(&p, &o).unwrap_err().to_string();
    assert!(e.contains("npz_array") && e.contains("grid"), "{e}");
}

#[test]
fn exr_f16_channel() {
    use exr::prelude::*;
    let vals: Vec<f16> = (0..12).map(|i| f16::from_f32(i as f32 * 0.5)).collect();
    let ch = AnyChannel::new("Z", FlatSamples::F16(vals));
    let layer = Layer::new(
        (4, 3),
        LayerAttributes::named("h"),
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(SmallVec::from_vec(vec![ch])),
    );
    let mut buf = Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut buf)
        .unwrap();
    let r = read_bytes(buf.get_ref(), None, &ReadOptions::default()).unwrap();
    assert_eq!(r.format, Format::Exr);
    assert_eq!(r.dtype, "float16");
    assert_eq!(r.heightfield.get(3, 2), 5.5);
}

#[test]
fn png8_grey_with_explicit_mapping() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("g.png");
    relief_io::write_gray_png(&p, 3, 1, &[0, 10, 255]).unwrap();
    let r = read(&p, &ReadOptions::default()).unwrap();
    assert_eq!(r.heightfield.as_slice(), &[0.0, 10.0, 255.0]);
    let o = ReadOptions {
        png: PngMode::Grey {
            offset: 100.0,
            scale: 2.0,
        },
        ..Default::default()
    };
    assert_eq!(
        read(&p, &o).unwrap().heightfield.as_slice(),
        &[100.0, 120.0, 610.0]
    );
    // A colour PNG is not silently taken as elevations.
    let c = dir.path().join("c.png");
    relief_io::write_rgb_png(&c, 1, 1, &[1, 2, 3]).unwrap();
    assert!(
        read(&c, &ReadOptions::default())
            .unwrap_err()
            .to_string()
            .contains("terrain-rgb")
    );
    let t = read(
        &c,
        &ReadOptions {
            png: PngMode::TerrainRgb,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(
        (t.heightfield.get(0, 0) as f64 - (-10000.0 + (65536.0 + 2.0 * 256.0 + 3.0) * 0.1)).abs()
            < 1e-3
    );
    let _ = Path::new("");
}
