//! `relief flow` (and the drainage commands' refusal by `tile plan`): outputs, georeference,
//! the GeoJSON network, clean failures.

use std::path::Path;

use crate::cli::gdalinfo;
use crate::common::*;

/// The files `relief flow` writes.
const FLOW_FILES: [&str; 9] = [
    "area.tif",
    "channels.geojson",
    "channels.png",
    "direction.tif",
    "filled.tif",
    "flow.json",
    "hand.tif",
    "strahler.tif",
    "watersheds.tif",
];

const FLOW_RASTERS: [&str; 6] = [
    "filled.tif",
    "direction.tif",
    "area.tif",
    "strahler.tif",
    "watersheds.tif",
    "hand.tif",
];

/// Width and height of a PNG from its IHDR chunk.
fn png_size(path: &Path) -> (u32, u32) {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[1..4], b"PNG", "{}", path.display());
    let be = |i: usize| u32::from_be_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    (be(16), be(20))
}

/// Every coordinate pair of a GeoJSON geometry.
fn coordinates(v: &serde_json::Value, out: &mut Vec<[f64; 2]>) {
    match v.as_array() {
        Some(a) if a.len() == 2 && a.iter().all(serde_json::Value::is_number) => {
            out.push([a[0].as_f64().unwrap(), a[1].as_f64().unwrap()]);
        }
        Some(a) => a.iter().for_each(|x| coordinates(x, out)),
        None => {}
    }
}

/// `relief flow` on a crop of the fixture writes every output into a new folder, each raster
/// on the input's grid with its georeference (checked with GDAL when present), a GeoJSON
/// network whose coordinates fall inside the raster's extent, the preview at the input's size,
/// and `flow.json`, which `--json` prints.
#[test]
fn flow_writes_every_output_with_the_georeference() {
    let (tmp, input, hf) = tmp_with_crop("crop.tif", (96, 64, 192, 160));
    let out = tmp.path().join("flow");
    let printed = relief_json![
        "flow",
        &input,
        "-o",
        &out,
        "--channel-area",
        "5e5",
        "--json"
    ];
    assert_eq!(files(&out), FLOW_FILES);
    let report = json(&out.join("flow.json"));
    assert_eq!(printed, report);
    assert_eq!(report["settings"]["channel_area"], 5e5);
    assert_eq!(report["settings"]["depressions"], "fill");
    assert_eq!(report["figures"]["cells"], 192 * 160);
    assert!(
        report["figures"]["reaches"].as_u64().unwrap() > 0,
        "{report}"
    );
    let g_in = hf.georef().expect("the fixture is georeferenced");
    let t = g_in.geotransform.expect("a geotransform");
    for name in FLOW_RASTERS {
        let r = read(&out.join(name));
        assert_eq!((r.width(), r.height()), (192, 160), "{name}");
        assert_eq!(r.georef().and_then(|g| g.geotransform), Some(t), "{name}");
        assert_eq!(r.georef().and_then(|g| g.crs.clone()), g_in.crs, "{name}");
    }
    let dir = read(&out.join("direction.tif"));
    assert!(
        dir.as_slice()
            .iter()
            .all(|&d| [0.0, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0, 128.0].contains(&d)),
        "ESRI codes"
    );
    let strahler = read(&out.join("strahler.tif"));
    let max_order = strahler.as_slice().iter().fold(0f32, |a, &b| a.max(b));
    assert_eq!(f64::from(max_order), report["figures"]["max_order"]);
    let filled = read(&out.join("filled.tif"));
    assert!(
        filled
            .as_slice()
            .iter()
            .zip(hf.as_slice())
            .all(|(f, i)| f >= i)
    );
    assert_eq!(png_size(&out.join("channels.png")), (192, 160));

    // The network: line strings whose every point lies inside the raster's extent.
    let gj = json(&out.join("channels.geojson"));
    assert_eq!(gj["type"], "FeatureCollection");
    let features = gj["features"].as_array().unwrap();
    assert_eq!(features.len() as u64, report["figures"]["reaches"]);
    let (xa, xb) = (t[0], t[0] + 192.0 * t[1]);
    let (ya, yb) = (t[3] + 160.0 * t[5], t[3]);
    let mut points = Vec::new();
    for f in features {
        assert_eq!(f["geometry"]["type"], "LineString");
        assert!(f["properties"]["order"].as_u64().unwrap() >= 1);
        coordinates(&f["geometry"]["coordinates"], &mut points);
    }
    assert!(!points.is_empty());
    for [x, y] in points {
        assert!(x > xa.min(xb) && x < xa.max(xb), "x {x} outside {xa}..{xb}");
        assert!(y > ya.min(yb) && y < ya.max(yb), "y {y} outside {ya}..{yb}");
    }

    // GDAL reads the rasters with the input's CRS and geotransform.
    let Some(src) = gdalinfo(&input) else {
        return;
    };
    for name in ["filled.tif", "direction.tif", "hand.tif"] {
        let info = gdalinfo(&out.join(name)).unwrap();
        assert_eq!(info["size"], src["size"], "{name}");
        assert_eq!(info["geoTransform"], src["geoTransform"], "{name}");
        assert_eq!(
            info["coordinateSystem"]["wkt"], src["coordinateSystem"]["wkt"],
            "{name}"
        );
    }
}

/// Into an existing folder: the outputs join what is there, and a second run needs --force.
#[test]
fn flow_into_an_existing_folder_needs_force_to_replace() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 96, 80));
    let out = tmp.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    relief_ok!["flow", &input, "-o", &out, "--depressions", "breach"];
    let mut want: Vec<&str> = FLOW_FILES.to_vec();
    want.push("notes.txt");
    want.sort_unstable();
    assert_eq!(files(&out), want);
    fails_with(
        &relief!["flow", &input, "-o", &out],
        &["filled.tif already exists", "--force"],
        &[],
    );
    relief_ok!["flow", &input, "-o", &out, "--force"];
    assert_eq!(files(&out), want, "no staging folder left");
}

/// Each `(flag, value)` makes `relief COMMAND INPUT -o OUT FLAG VALUE` fail with one line
/// naming the flag, before anything is written.
fn bad_values_fail_naming_the_flag(
    command: &str,
    input: &Path,
    out: &Path,
    cases: &[(&str, &str)],
) {
    for (flag, value) in cases {
        fails_with(
            &relief![command, input, "-o", out, flag, value],
            &[&format!("invalid {flag}")],
            &[out],
        );
    }
}

/// Bad parameters fail cleanly, naming the flag, before anything is written.
#[test]
fn flow_bad_parameters_fail_naming_the_flag() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 64, 64));
    let out = tmp.path().join("out");
    bad_values_fail_naming_the_flag(
        "flow",
        &input,
        &out,
        &[
            ("--channel-area", "-5"),
            ("--channel-area", "nan"),
            ("--breach-depth", "-1"),
            ("--breach-length", "1e9"),
            ("--mfd-exponent", "0"),
        ],
    );
    usage_error(
        &words("flow {} -o {} --depressions lake", &[&input, &out]),
        "--depressions",
        &out,
    );
    usage_error(
        &words("flow {} -o {} --directions d16", &[&input, &out]),
        "--directions",
        &out,
    );
    // A folder whose parent is missing, and a file named as the folder.
    fails_with(
        &relief!["flow", &input, "-o", tmp.path().join("no/such")],
        &["cannot create the output folder"],
        &[],
    );
    fails_with(
        &relief!["flow", &input, "-o", &input],
        &["exists and is not a folder"],
        &[],
    );
    assert_eq!(files(tmp.path()), ["crop.tif"]);
}

/// The pre-flight estimate refuses a DEM whose flow rasters do not fit in --max-memory.
#[test]
fn flow_over_max_memory_is_refused_before_the_run() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let input = relief_testdata::fixture("grandcanyon.tif");
    fails_with(
        &relief!["--max-memory", "16M", "flow", &input, "-o", &out],
        &["flow would need", "512 x 512", "--max-memory"],
        &[&out],
    );
    assert!(!out.exists());
}

/// `tile plan` refuses the drainage commands without an exact multi-phase plan (erode, masks),
/// saying why, and writes no plan (`flow` has one: `tile_flow.rs`).
#[test]
fn tile_plan_refuses_drainage_commands() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 64, 64));
    let plan = tmp.path().join("plan");
    // masks has its own exact plan (tile_masks); erode has none.
    let eroded = tmp.path().join("e.tif");
    let mut args = words("tile plan {} --", &[&plan]);
    args.extend(words("erode {} -o {}", &[&input, &eroded]));
    fails_with(
        &relief(&args),
        &["drainage is global", "upstream", "multi-phase"],
        &[&plan],
    );
    assert_eq!(files(tmp.path()), ["crop.tif"]);
}

/// The masks of `relief masks` (no erosion run).
const MASKS: [&str; 7] = [
    "area",
    "hand",
    "height_band",
    "plan_curvature",
    "profile_curvature",
    "slope",
    "wetness",
];

/// A PNG's bit depth, colour type and pixels.
fn png_pixels(path: &Path) -> (png::BitDepth, png::ColorType, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.bit_depth, info.color_type, buf)
}

/// `relief masks` writes every mask as a GeoTIFF on the input's grid and georeference (PNGs
/// of the normalised masks with `--format png8|png16`), and an RGBA splat map whose four
/// weights sum to 255 in every pixel.
#[test]
fn masks_write_each_mask_and_a_splat_map() {
    let (tmp, input, hf) = tmp_with_crop("crop.tif", (160, 96, 120, 100));
    let out = tmp.path().join("m");
    let report = relief_json!["masks", &input, "-o", &out, "--json"];
    let mut want: Vec<String> = MASKS.iter().map(|m| format!("{m}.tif")).collect();
    want.extend(["masks.json".into(), "splat.png".into()]);
    want.sort();
    assert_eq!(files(&out), want);
    assert_eq!(json(&out.join("masks.json")), report);
    assert_eq!(
        report["bands"].as_array().unwrap().len(),
        3,
        "quartiles: {report}"
    );
    let t = hf.georef().and_then(|g| g.geotransform);
    for m in MASKS {
        let r = read(&out.join(format!("{m}.tif")));
        assert_eq!((r.width(), r.height()), (120, 100), "{m}");
        assert_eq!(r.georef().and_then(|g| g.geotransform), t, "{m}");
    }
    let slope = read(&out.join("slope.tif"));
    assert!(slope.as_slice().iter().all(|&s| (0.0..=90.0).contains(&s)));
    let (depth, colour, px) = png_pixels(&out.join("splat.png"));
    assert_eq!(
        (depth, colour),
        (png::BitDepth::Eight, png::ColorType::Rgba)
    );
    assert_eq!(px.len(), 120 * 100 * 4);
    assert!(
        px.chunks(4)
            .all(|p| p.iter().map(|&v| u32::from(v)).sum::<u32>() == 255)
    );
    assert!(
        px.chunks(4).any(|p| p[1] > 128),
        "some rock on the canyon walls"
    );

    for (format, bits) in [
        ("png8", png::BitDepth::Eight),
        ("png16", png::BitDepth::Sixteen),
    ] {
        let out = tmp.path().join(format);
        relief_ok![
            "masks",
            &input,
            "-o",
            &out,
            "--format",
            format,
            "--height-bands",
            "1200,1600"
        ];
        let (depth, colour, _) = png_pixels(&out.join("slope.png"));
        assert_eq!(
            (depth, colour),
            (bits, png::ColorType::Grayscale),
            "{format}"
        );
        assert_eq!(
            json(&out.join("masks.json"))["bands"],
            serde_json::json!([1200.0, 1600.0])
        );
    }
}

/// Bad mask parameters fail naming the flag and write nothing.
#[test]
fn masks_bad_parameters_fail_naming_the_flag() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 64, 64));
    let out = tmp.path().join("m");
    bad_values_fail_naming_the_flag(
        "masks",
        &input,
        &out,
        &[
            ("--rock-slope", "95"),
            ("--wet-index", "-1"),
            ("--height-bands", "1500,1000"),
            ("--channel-area", "0"),
        ],
    );
    usage_error(
        &words("masks {} -o {} --format jpg", &[&input, &out]),
        "--format",
        &out,
    );
    let small = write(
        tmp.path(),
        "small.tif",
        &read(&input).crop(0, 0, 16, 16).unwrap(),
    );
    fails_with(
        &relief(&words(
            "masks {} -o {} --deposition-depth {}",
            &[&input, &out, &small],
        )),
        &["--deposition-depth", "16 x 16", "must match"],
        &[&out],
    );
    std::fs::remove_file(&small).unwrap();
    assert_eq!(files(tmp.path()), ["crop.tif"]);
}

/// A short run of every process: few steps on a small crop.
const SHORT_ERODE: [&str; 8] = [
    "--years",
    "2e4",
    "--dt",
    "1e4",
    "--hydraulic-iterations",
    "8",
    "--thermal-iterations",
    "4",
];

/// `relief erode` writes the eroded terrain and the net erosion and deposition depths, all on
/// the input's grid and georeference; `--uplift` takes a rate or a raster of rates; `--json`
/// prints the settings (the preset with the flags over it) and the figures.
#[test]
fn erode_writes_the_terrain_and_the_depths_with_the_georeference() {
    let (tmp, input, hf) = tmp_with_crop("crop.tif", (200, 160, 96, 80));
    let (out, e, d, png) = (
        tmp.path().join("eroded.tif"),
        tmp.path().join("erosion.tif"),
        tmp.path().join("deposition.tif"),
        tmp.path().join("change.png"),
    );
    let mut args = words(
        "erode {} -o {} --erosion {} --deposition {} --change-map {} --preset badlands --json \
         --fill-pits false --weathering 2",
        &[&input, &out, &e, &d, &png],
    );
    args.extend(SHORT_ERODE.iter().map(std::ffi::OsStr::new));
    let report: serde_json::Value = serde_json::from_str(&ok(&relief(&args))).unwrap();
    assert_eq!(report["settings"]["preset"], "badlands");
    assert_eq!(report["settings"]["years"], 2e4);
    assert_eq!(report["settings"]["hydraulic_iterations"], 8);
    assert_eq!(report["settings"]["fill_pits"], false);
    assert_eq!(report["settings"]["weathering"], 2.0);
    assert!(
        report["figures"]["eroded_m3"].as_f64().unwrap() > 0.0,
        "{report}"
    );
    let t = hf.georef().and_then(|g| g.geotransform);
    let [eroded, erosion, deposition] = [&out, &e, &d].map(|p| read(p));
    for r in [&eroded, &erosion, &deposition] {
        assert_eq!((r.width(), r.height()), (96, 80));
        assert_eq!(r.georef().and_then(|g| g.geotransform), t);
    }
    // The change map: an RGB PNG of the grid's size.
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let info = decoder.read_info().unwrap().info().clone();
    assert_eq!((info.width, info.height), (96, 80));
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert!(erosion.as_slice().iter().all(|&v| v >= 0.0));
    assert!(deposition.as_slice().iter().all(|&v| v >= 0.0));
    let changed = (eroded.as_slice().iter().zip(hf.as_slice()))
        .filter(|(a, b)| a != b)
        .count();
    assert!(changed > 96 * 80 / 2, "{changed} cells changed");
    let max_e = erosion.as_slice().iter().fold(0f32, |a, &b| a.max(b));
    let want = report["figures"]["max_erosion_m"].as_f64().unwrap();
    assert!(
        (f64::from(max_e) - want).abs() < 1e-3 * want.max(1.0),
        "{max_e} vs {want}"
    );

    // A raster of uplift rates on the DEM's grid, and one on another grid.
    let rates = write(
        tmp.path(),
        "uplift.tif",
        &hf.with_data(vec![1e-4; 96 * 80]).unwrap(),
    );
    let out2 = tmp.path().join("uplifted.tif");
    let mut args = words("erode {} -o {} --uplift {}", &[&input, &out2, &rates]);
    args.extend(SHORT_ERODE.iter().map(std::ffi::OsStr::new));
    ok(&relief(&args));
    assert_eq!(read(&out2).width(), 96);
    let small = write(tmp.path(), "small.tif", &hf.crop(0, 0, 32, 32).unwrap());
    let out3 = tmp.path().join("never.tif");
    fails_with(
        &relief(&words(
            "erode {} -o {} --uplift {}",
            &[&input, &out3, &small],
        )),
        &["--uplift", "32 x 32", "must match"],
        &[&out3],
    );
}

/// Bad erosion parameters fail naming the flag (the preset's processes check the overrides
/// under their own names) and write nothing; an estimate over `--max-time` is refused before
/// the run.
#[test]
fn erode_refuses_bad_parameters_and_runs_over_max_time() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 64, 64));
    let (out, e) = (tmp.path().join("o.tif"), tmp.path().join("e.tif"));
    for (flag, value) in [
        ("--talus-angle", "95"),
        ("--rain", "-1"),
        ("--uplift", "0.5"),
        ("--years", "-3"),
        ("--k", "-1"),
        ("--hydraulic-iterations", "2000000"),
        ("--thermal-iterations", "2000000"),
        ("--weathering", "1e9"),
    ] {
        fails_with(
            &relief!["erode", &input, "-o", &out, "--erosion", &e, flag, value],
            &[&format!("invalid {flag} ")],
            &[&out, &e],
        );
    }
    usage_error(
        &words("erode {} -o {} --preset glacier", &[&input, &out]),
        "--preset",
        &out,
    );
    fails_with(
        &relief![
            "--max-time",
            "0.000001s",
            "erode",
            &input,
            "-o",
            &out,
            "--erosion",
            &e
        ],
        &["the erosion is estimated at", "--max-time"],
        &[&out, &e],
    );
    assert_eq!(files(tmp.path()), ["crop.tif"]);
}

/// A painted uplift map in any units (here the DEM itself, metres) is refused as rates, taken
/// with `--uplift-max` (its highest value becomes that rate), and `--uplift-max` without a
/// raster is an error.
#[test]
fn erode_takes_a_painted_uplift_map_scaled_by_uplift_max() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 48, 48));
    let out = tmp.path().join("o.tif");
    let p = tmp.path().join("p.tif");
    let (h, t) = ("--hydraulic-iterations", "--thermal-iterations");
    fails_with(
        &relief![
            "erode", &input, "-o", &out, "--uplift", &input, "--years", "2e4", h, "0", t, "0"
        ],
        &["0.1 m/yr"],
        &[&out],
    );
    relief_ok![
        "erode",
        &input,
        "-o",
        &out,
        "--uplift",
        &input,
        "--uplift-max",
        "0.001",
        "--years",
        "2e4",
        h,
        "0",
        t,
        "0"
    ];
    assert!(out.is_file());
    fails_with(
        &relief![
            "erode",
            &input,
            "-o",
            &p,
            "--uplift-max",
            "0.001",
            h,
            "0",
            t,
            "0"
        ],
        &["--uplift-max"],
        &[&p],
    );
}
