//! `relief export`: each engine's files read back as the engine reads them (sizes, byte order,
//! row order, the vertical scale of the import sheet giving the metres back within the 16-bit
//! step), tiles whose shared edges hold the same samples, the masks packed per engine, and
//! clean refusals.

use std::path::Path;

use relief_heightfield::Heightfield;
use relief_landscape::masks::{MasksSettings, splat_rgba8};

use crate::common::*;

/// A PNG's size, bit depth, colour type and raw sample bytes (16-bit samples big-endian, as
/// the PNG standard stores them and every engine's PNG reader takes them).
fn png(path: &Path) -> (usize, usize, png::BitDepth, png::ColorType, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    let (w, h) = (info.width as usize, info.height as usize);
    (w, h, info.bit_depth, info.color_type, buf)
}

/// The counts of a 16-bit greyscale PNG, row-major as stored.
fn png16(path: &Path) -> (usize, usize, Vec<u16>) {
    let (w, h, depth, colour, bytes) = png(path);
    assert_eq!(depth, png::BitDepth::Sixteen, "{}", path.display());
    assert_eq!(colour, png::ColorType::Grayscale, "{}", path.display());
    let counts = bytes
        .chunks(2)
        .map(|b| u16::from_be_bytes([b[0], b[1]]))
        .collect();
    (w, h, counts)
}

/// The counts of a headerless little-endian 16-bit raw file of `n` samples.
fn raw16(path: &Path, n: usize) -> Vec<u16> {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(bytes.len(), 2 * n, "{}: {n} samples", path.display());
    bytes
        .chunks(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect()
}

/// The value of the import setting `name` in the sheet.
fn setting(sheet: &serde_json::Value, name: &str) -> String {
    sheet["settings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == name)
        .unwrap_or_else(|| panic!("no setting `{name}` in {sheet}"))["value"]
        .as_str()
        .unwrap()
        .to_string()
}

/// The numbers of a setting's value ("a, b, c").
fn numbers(value: &str) -> Vec<f64> {
    value
        .split([',', 'x'])
        .map(|v| v.trim().parse().unwrap())
        .collect()
}

/// Asserts that `got(x, y)` (metres read back as the engine reads them) is `want` within half
/// a 16-bit step of the range plus the printed settings' rounding.
fn assert_metres(want: &Heightfield, tol: f64, got: impl Fn(usize, usize) -> f64) {
    let mut worst = 0.0f64;
    for y in 0..want.height() {
        for x in 0..want.width() {
            worst = worst.max((got(x, y) - f64::from(want.get(x, y))).abs());
        }
    }
    assert!(worst <= tol, "worst error {worst} m over {tol} m");
}

/// The fixture's tolerance: half a count of its range (about 1900 m / 65535), plus what the
/// sheet's printed digits lose.
fn tolerance(sheet: &serde_json::Value) -> f64 {
    sheet["vertical"]["step"].as_f64().unwrap() * 0.5 + 2e-3
}

/// `window` of the fixture as `crop.tif` in a new temporary folder, and its grid as the export
/// reads it (a Web-Mercator crop states its own ground cell size).
fn export_input(
    window: (usize, usize, usize, usize),
) -> (tempfile::TempDir, std::path::PathBuf, Heightfield) {
    let (tmp, input, _) = tmp_with_crop("crop.tif", window);
    let hf = read(&input);
    (tmp, input, hf)
}

/// Unreal: a 252^2-cell DEM fits the 253 landscape without resampling; the PNG is 16-bit,
/// north first, and Location Z + (count - 32768) / 128 x Z scale (cm) gives the corner
/// heights back; --format r16 writes the same counts little-endian.
#[test]
fn unreal_heightmap_reads_back_in_metres() {
    let (tmp, input, hf) = export_input((40, 60, 252, 252));
    let out = tmp.path().join("ue/");
    let sheet = relief_json!["export", "--engine", "unreal", &input, &out, "--json"];
    assert_eq!(json(&tmp.path().join("ue/crop.json")), sheet);
    assert_eq!(
        files(&tmp.path().join("ue")),
        ["crop.json", "crop.png", "crop.txt"]
    );
    let (w, h, counts) = png16(&tmp.path().join("ue/crop.png"));
    assert_eq!((w, h), (253, 253));
    let want = hf.corner_samples().unwrap();
    let z = numbers(&setting(&sheet, "Scale Z"))[0];
    let loc = numbers(&setting(&sheet, "Location Z (cm)"))[0];
    let cm = |c: u16| loc + (f64::from(c) - 32768.0) / 128.0 * z;
    assert_metres(&want, tolerance(&sheet), |x, y| {
        cm(counts[y * w + x]) / 100.0
    });
    // X/Y scale: the DEM's cells in centimetres (no resampling here).
    let (cx, _) = hf.cell_size();
    let sx = numbers(&setting(&sheet, "Scale X (cm per quad)"))[0];
    assert!((sx - cx * 100.0).abs() < 1e-3, "{sx} vs {cx}");
    assert_eq!(setting(&sheet, "Number of Components"), "2 x 2");
    // The text sheet says the same settings.
    let text = std::fs::read_to_string(tmp.path().join("ue/crop.txt")).unwrap();
    assert!(
        text.contains(&format!("Scale Z: {}", setting(&sheet, "Scale Z"))),
        "{text}"
    );
    // .r16: the same counts, little-endian.
    let prefix = tmp.path().join("r16/terrain");
    relief_ok![
        "export", "--engine", "unreal", &input, &prefix, "--format", "r16"
    ];
    assert_eq!(raw16(&tmp.path().join("r16/terrain.r16"), w * h), counts);
}

/// Unity: 2^8 + 1 samples of 16-bit little-endian raw whose row 0 is the terrain's z = 0
/// (south) edge, read as Import Raw does: count / 65536 x terrain height + position.
#[test]
fn unity_raw_is_south_first_and_scaled_by_the_terrain_height() {
    let (tmp, input, hf) = export_input((100, 30, 256, 256));
    let out = tmp.path().join("unity/");
    let sheet = relief_json![
        "export", "--engine", "unity", &input, &out, "--name", "t", "--json"
    ];
    let n = 257;
    assert_eq!(setting(&sheet, "Resolution"), "257");
    assert_eq!(setting(&sheet, "Byte Order"), "Windows");
    assert_eq!(setting(&sheet, "Flip Vertically"), "off");
    let counts = raw16(&out.join("t.raw"), n * n);
    let size = numbers(&setting(&sheet, "Terrain Size (width, height, length) (m)"));
    let base = numbers(&setting(&sheet, "Position Y (m)"))[0];
    let (cx, cy) = hf.cell_size();
    assert!((size[0] - 256.0 * cx).abs() < 1e-2 && (size[2] - 256.0 * cy).abs() < 1e-2);
    // Unity's heights[z, x]: z = 0 is raw row 0; the DEM's row 0 is north (z = n - 1).
    let unity = |x: usize, z: usize| base + f64::from(counts[z * n + x]) / 65536.0 * size[1];
    let want = hf.corner_samples().unwrap();
    assert_metres(&want, tolerance(&sheet), |x, y| unity(x, n - 1 - y));
}

/// Godot Terrain3D: the long side fitted to a multiple of the region size (300 cells: 256
/// samples) with the short side in proportion, resampled by the workspace's resamplers;
/// Terrain3D's R16 loader reads count / 65535 x (max - min) + min, row 0 first.
#[test]
fn godot_raw_is_resampled_to_the_region_size() {
    let (tmp, input, hf) = export_input((10, 200, 300, 200));
    let out = tmp.path().join("godot/");
    let sheet = relief_json!["export", "--engine", "godot", &input, &out, "--json"];
    assert_eq!(sheet["samples"], serde_json::json!([256, 171]));
    assert_eq!(setting(&sheet, "r16_size"), "256, 171");
    let counts = raw16(&out.join("crop.raw"), 256 * 171);
    let range = numbers(&setting(&sheet, "r16_height_range (min, max) (m)"));
    let want = hf.resample(255, 170).unwrap().corner_samples().unwrap();
    let t3d = |x: usize, y: usize| {
        f64::from(counts[y * 256 + x]) / 65535.0 * (range[1] - range[0]) + range[0]
    };
    assert_metres(&want, tolerance(&sheet), t3d);
    let spacing = numbers(&setting(&sheet, "vertex_spacing (m)"))[0];
    assert!(
        (spacing - 300.0 * hf.cell_size().0 / 255.0).abs() < 1e-3,
        "{spacing}"
    );
}

/// Gaea: any size (the DEM's corners), a 16-bit PNG read as count / 65535 of the Height above
/// the base elevation.
#[test]
fn gaea_png_keeps_the_dem_size() {
    let (tmp, input, hf) = export_input((0, 0, 100, 70));
    let sheet = relief_json![
        "export",
        "--engine",
        "gaea",
        &input,
        tmp.path().join("g/"),
        "--json"
    ];
    let (w, h, counts) = png16(&tmp.path().join("g/crop.png"));
    assert_eq!((w, h), (101, 71));
    let height = numbers(&setting(&sheet, "Height (m)"))[0];
    let base = numbers(&setting(&sheet, "Base elevation (m)"))[0];
    let gaea = |x: usize, y: usize| base + f64::from(counts[y * w + x]) / 65535.0 * height;
    assert_metres(&hf.corner_samples().unwrap(), tolerance(&sheet), gaea);
    // --height-range fixes the mapping (exports that must meet share it).
    let out = tmp.path().join("fixed/");
    let sheet = relief_json![
        "--height-range",
        "0,4000",
        "export",
        "--engine",
        "gaea",
        &input,
        &out,
        "--json"
    ];
    assert_eq!(setting(&sheet, "Height (m)"), "4000.0000");
    assert_eq!(setting(&sheet, "Base elevation (m)"), "0.0000");
    let counts = png16(&out.join("crop.png")).2;
    let fixed = |x: usize, y: usize| f64::from(counts[y * w + x]) / 65535.0 * 4000.0;
    assert_metres(
        &hf.corner_samples().unwrap(),
        4000.0 / 65535.0 * 0.5 + 1e-3,
        fixed,
    );
}

/// --max-time: a run still going at the limit stops there and writes nothing.
#[test]
fn export_stops_at_the_time_limit() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 256, 256));
    let out = tmp.path().join("late/");
    fails_with(
        &relief![
            "--max-time",
            "0.001",
            "export",
            "--engine",
            "unity",
            &input,
            &out,
            "--tiles",
            "2x2"
        ],
        &["stopped", "--max-time"],
        &[&tmp.path().join("late")],
    );
    assert_eq!(files(tmp.path()), ["crop.tif"]);
}

/// Unreal World Partition tiles NAME_x<X>_y<Y> (y0 north): 2x2 tiles of 127 for a 252^2
/// DEM; neighbours hold the same samples on their shared edge, and each tile is the whole
/// grid's window.
#[test]
fn unreal_tiles_share_their_edges() {
    let (tmp, input, hf) = export_input((40, 60, 252, 252));
    let out = tmp.path().join("tiles/");
    let sheet = relief_json![
        "export", "--engine", "unreal", &input, &out, "--tiles", "2x2", "--json"
    ];
    assert_eq!(sheet["tiles"], serde_json::json!([[2, 2], 127]));
    let tile = |x: usize, y: usize| png16(&out.join(format!("crop_x{x}_y{y}.png"))).2;
    let t = 127;
    let (a, b, c) = (tile(0, 0), tile(1, 0), tile(0, 1));
    for i in 0..t {
        assert_eq!(a[i * t + t - 1], b[i * t], "east edge, row {i}");
        assert_eq!(a[(t - 1) * t + i], c[i], "south edge, column {i}");
    }
    let want = hf.corner_samples().unwrap();
    let z = numbers(&setting(&sheet, "Scale Z"))[0];
    let loc = numbers(&setting(&sheet, "Location Z (cm)"))[0];
    let d = tile(1, 1);
    let m = |c: u16| (loc + (f64::from(c) - 32768.0) / 128.0 * z) / 100.0;
    let sw = want.crop(126, 126, t, t).unwrap();
    assert_metres(&sw, tolerance(&sheet), |x, y| m(d[y * t + x]));
    // Each tile is placed by hand at its Location X, Y (cm): x1_y1 is 126 quads in each way.
    let placed = sheet["heightmaps"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["file"] == "crop_x1_y1.png")
        .unwrap();
    let loc = numbers(
        placed["position"]
            .as_str()
            .unwrap()
            .split(':')
            .nth(1)
            .unwrap(),
    );
    let quad_cm = numbers(&setting(&sheet, "Scale X (cm per quad)"))[0];
    assert!((loc[0] - 126.0 * quad_cm).abs() < 0.01 && (loc[1] - loc[0]).abs() < 0.01);
    assert!(
        sheet["notes"][0]
            .as_str()
            .unwrap()
            .contains("without overlap")
    );
}

/// Unity tiles NAME_<X>_<Z> (Z northwards), each south first: the north-west tile is
/// `_0_1`; its raw row 0 (its south edge) is the south-west tile's last row (its north edge).
#[test]
fn unity_tiles_are_named_by_x_and_z_and_share_their_edges() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (100, 30, 256, 256));
    let out = tmp.path().join("u/");
    relief_ok![
        "export", "--engine", "unity", &input, &out, "--tiles", "2x2"
    ];
    let t = 129;
    let tile = |x: usize, z: usize| raw16(&out.join(format!("crop_{x}_{z}.raw")), t * t);
    let (sw, nw, se) = (tile(0, 0), tile(0, 1), tile(1, 0));
    assert_eq!(&nw[..t], &sw[(t - 1) * t..], "the shared east-west edge");
    for z in 0..t {
        assert_eq!(
            sw[z * t + t - 1],
            se[z * t],
            "the shared north-south edge, z {z}"
        );
    }
    // North-first rows would put the DEM's north edge in the SW tile's row 0: it is not.
    assert_ne!(&nw[..t], &nw[(t - 1) * t..]);
    // The sheet places each terrain by its south-west corner: the north-west one 128 cells up.
    let sheet = json(&out.join("crop.json"));
    let nw = sheet["heightmaps"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["file"] == "crop_0_1.raw")
        .unwrap();
    let z = numbers(nw["position"].as_str().unwrap().split(':').nth(1).unwrap())[1];
    let want = 128.0 * sheet["spacing_m"][1].as_f64().unwrap();
    assert!((z - want).abs() < 1e-3, "{z} vs {want}");
}

/// --masks: Unreal gets one 8-bit weight map per layer on the heightmap's samples, the
/// layers summing to 255; they are the `relief masks` splat of the exported grid.
#[test]
fn unreal_masks_are_weight_maps_per_layer() {
    let (tmp, input, hf) = export_input((40, 60, 252, 252));
    let out = tmp.path().join("m/");
    relief_ok!["export", "--engine", "unreal", &input, &out, "--masks"];
    let corners = hf.corner_samples().unwrap();
    let masks = MasksSettings::default()
        .run(&corners, None, None, &relief_heightfield::NoProgress)
        .unwrap();
    let rgba = splat_rgba8(&masks.splat);
    let mut sum = vec![0u32; 253 * 253];
    for (c, layer) in ["ground", "rock", "sediment", "wet"].iter().enumerate() {
        let (w, h, depth, colour, grey) = png(&out.join(format!("crop_{layer}.png")));
        assert_eq!(
            (w, h, depth, colour),
            (253, 253, png::BitDepth::Eight, png::ColorType::Grayscale)
        );
        let want: Vec<u8> = rgba.chunks(4).map(|p| p[c]).collect();
        assert_eq!(grey, want, "{layer}");
        for (s, g) in sum.iter_mut().zip(&grey) {
            *s += u32::from(*g);
        }
    }
    assert!(sum.iter().all(|&s| s == 255));
}

/// --masks with Unity tiles: one RGBA alphamap of 2^n cells per terrain, named as its
/// heightmap, cut from the splat of the whole grid's cells (not from overlapping tiles).
#[test]
fn unity_masks_are_alphamaps_per_terrain() {
    let (tmp, input, hf) = export_input((100, 30, 256, 256));
    let out = tmp.path().join("um/");
    relief_ok![
        "export", "--engine", "unity", &input, &out, "--tiles", "2x2", "--masks"
    ];
    let masks = MasksSettings::default()
        .run(&hf, None, None, &relief_heightfield::NoProgress)
        .unwrap();
    let rgba = splat_rgba8(&masks.splat);
    // The north-east terrain (x 1, z 1): cells 128.. of the first 128 rows.
    let (w, h, depth, colour, px) = png(&out.join("crop_splat_1_1.png"));
    assert_eq!(
        (w, h, depth, colour),
        (128, 128, png::BitDepth::Eight, png::ColorType::Rgba)
    );
    for y in 0..128 {
        let row = &rgba[(y * 256 + 128) * 4..(y * 256 + 256) * 4];
        assert_eq!(&px[y * 512..(y + 1) * 512], row, "row {y}");
    }
    assert!(
        px.chunks(4)
            .all(|p| p.iter().map(|&v| u32::from(v)).sum::<u32>() == 255)
    );
}

/// Refusals name the problem and write nothing: an output over the input, existing files
/// without --force, a size the engine does not take, tiles for Terrain3D, a heightmap over
/// --max-memory, voids.
#[test]
fn bad_exports_are_refused_naming_the_problem() {
    let (tmp, input, hf) = export_input((0, 0, 64, 64));
    let d = tmp.path();
    // A 16-bit PNG input whose name the export would take.
    let png_in = write(d, "h.png", &hf);
    let prefix = d.join("h");
    fails_with(
        &relief!["export", "--engine", "unreal", &png_in, &prefix],
        &["refusing to overwrite an input"],
        &[&d.join("h.json")],
    );
    let out = d.join("out/");
    fails_with(
        &relief![
            "export", "--engine", "unreal", &input, &out, "--size", "1000"
        ],
        &["--size 1000", "1009"],
        &[&d.join("out")],
    );
    fails_with(
        &relief![
            "export", "--engine", "godot", &input, &out, "--tiles", "2x2"
        ],
        &["--tiles", "unreal or unity"],
        &[&d.join("out")],
    );
    fails_with(
        &relief![
            "--max-memory",
            "16M",
            "export",
            "--engine",
            "unreal",
            &input,
            &out,
            "--size",
            "8129"
        ],
        &["export would need", "8129 x 8129", "--max-memory"],
        &[&d.join("out")],
    );
    fails_with(
        &relief!["export", "--engine", "unreal", &input, d.join("t.png")],
        &["drop the .png"],
        &[&d.join("t.png.png")],
    );
    fails_with(
        &relief![
            "export",
            "--engine",
            "unreal",
            &input,
            &out,
            "--region-size",
            "512"
        ],
        &["--region-size", "godot"],
        &[&d.join("out")],
    );
    fails_with(
        &relief![
            "export",
            "--engine",
            "godot",
            &input,
            &out,
            "--region-size",
            "300"
        ],
        &["--region-size 300", "2048"],
        &[&d.join("out")],
    );
    fails_with(
        &relief![
            "export", "--engine", "unity", &input, &out, "--format", "png"
        ],
        &["--format r16"],
        &[&d.join("out")],
    );
    let mut holes = hf.clone();
    holes.set(3, 3, f32::NAN);
    let holed = write(d, "holes.tif", &holes);
    fails_with(
        &relief!["export", "--engine", "gaea", &holed, &out],
        &["1 void cells", "--fill-voids"],
        &[&d.join("out")],
    );
    // An existing export is replaced only under --force.
    relief_ok!["export", "--engine", "gaea", &input, &out];
    let before = std::fs::read(d.join("out/crop.png")).unwrap();
    fails_with(
        &relief!["export", "--engine", "gaea", &input, &out, "--size", "33"],
        &["already exists", "--force"],
        &[],
    );
    assert_eq!(std::fs::read(d.join("out/crop.png")).unwrap(), before);
    relief_ok![
        "--force", "export", "--engine", "gaea", &input, &out, "--size", "33"
    ];
    assert_eq!(png16(&d.join("out/crop.png")).0, 33);
}
