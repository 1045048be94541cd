//! End-to-end tests of the `relief` binary on the real DEM set (skipped with a notice when
//! `../shared/data/dem` is absent, failing under `CI`).

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::*;

#[test]
fn info_reports_srtm_size_and_voids() {
    let Some(hgt) = dem("N47E011.hgt") else {
        return;
    };
    let stdout = relief_ok!["info", hgt];
    assert!(stdout.contains("1201 x 1201"), "{stdout}");
    assert!(
        stdout.contains("voids:       54,278 of 1,442,401 cells"),
        "{stdout}"
    );
    assert!(stdout.contains("format:"), "{stdout}");
    assert!(stdout.contains("elevation:"), "{stdout}");
    assert!(stdout.contains("georeference"), "{stdout}");
}

/// alps_dem.tiff (int16 metres) to every writable format and back; each format within its
/// stated precision: lossless f32 formats exactly, 16-bit ones within one quantisation step.
#[test]
fn convert_round_trips_alps() {
    let Some(tiff) = dem("alps_dem.tiff") else {
        return;
    };
    let original = read(&tiff);
    let (lo, hi) = original.min_max().expect("valid cells");
    let tmp = tempfile::tempdir().unwrap();
    // (extension, max-abs tolerance in metres)
    let quantum = (hi - lo) as f64 / 65535.0;
    let cases = [
        ("tif", 0.0),
        ("exr", 0.0),
        ("npy", 0.0),
        ("r32", 0.0),
        ("png", quantum * 0.5 + 1e-3),
    ];
    for (ext, tol) in cases {
        let out = tmp.path().join(format!("alps.{ext}"));
        relief_ok!["convert", tiff, out];
        // And back to GeoTIFF through the CLI, then compare.
        let back = tmp.path().join(format!("alps_from_{ext}.tif"));
        let width = original.width().to_string();
        let raw: &[&str] = if ext == "r32" {
            &["--width", &width]
        } else {
            &[]
        };
        ok(&relief(&[&["convert", s(&out), s(&back)], raw].concat()));
        let got = read(&back);
        assert_eq!(
            (got.width(), got.height()),
            (original.width(), original.height()),
            "{ext}"
        );
        let max_abs = relief_heightfield::metrics::max_abs_diff(&original, &got).unwrap();
        assert!(max_abs <= tol, "{ext}: max-abs {max_abs} > {tol}");
    }
}

#[test]
fn convert_fill_voids_leaves_no_voids() {
    let Some((hgt, tmp)) = dem_and_tmp("N47E011.hgt") else {
        return;
    };
    let out = tmp.path().join("filled.npy");
    relief_ok!["convert", hgt, out, "--fill-voids"];
    let filled = read(&out);
    assert_eq!(filled.void_count(), 0);
    let original = read(&hgt);
    // Valid cells are untouched.
    for (a, b) in original.as_slice().iter().zip(filled.as_slice()) {
        if a.is_finite() {
            assert_eq!(a, b);
        }
    }
}

#[test]
fn preview_writes_png() {
    let Some((tif, tmp)) = dem_and_tmp("grandcanyon.tif") else {
        return;
    };
    let out = tmp.path().join("gc.png");
    relief_ok!["preview", tif, out];
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    // N47E011: 1201 x 1201 samples of 62.8 m x 92.6 m: the preview is square on the ground.
    let Some(hgt) = dem("N47E011.hgt") else {
        return;
    };
    let out = tmp.path().join("n47.png");
    relief_ok!["preview", "--fill-voids", hgt, out];
    let b = std::fs::read(&out).unwrap();
    let (w, h) = (
        u32::from_be_bytes(b[16..20].try_into().unwrap()),
        u32::from_be_bytes(b[20..24].try_into().unwrap()),
    );
    assert_eq!(w, 1201);
    assert!((1760..=1785).contains(&h), "preview height {h}");
}

#[test]
fn corrupt_input_fails_cleanly_without_output() {
    let tmp = tempfile::tempdir().unwrap();
    let bad = tmp.path().join("bad.tif");
    // A TIFF header whose first IFD offset points past the end of the file.
    std::fs::write(&bad, b"II*\0\xff\xff\xff\x00garbage").unwrap();
    let out = tmp.path().join("out.exr");
    let e = fails_with(&relief!["convert", bad, out], &[], &[&out]);
    assert!(e.starts_with("error: cannot read"), "{e}");
    assert_eq!(files(tmp.path()), ["bad.tif"], "stray files left");
}

#[test]
fn unwritable_output_fails_cleanly_without_output() {
    let Some((tif, tmp)) = dem_and_tmp("grandcanyon.tif") else {
        return;
    };
    // The output folder does not exist: the temporary file cannot be created.
    let out = tmp.path().join("missing/dir/gc.tif");
    let e = failed(&relief!["convert", tif, out]);
    assert!(e.starts_with("error: cannot write"), "{e}");
    assert!(!out.exists());
    // An unknown extension is refused before anything is written.
    let out = tmp.path().join("gc.xyz");
    fails_with(&relief!["convert", tif, out], &[], &[&out]);
    assert!(files(tmp.path()).is_empty(), "stray files left");
}

#[test]
fn verbose_error_shows_cause_chain() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("nope.tif");
    let out = tmp.path().join("o.tif");
    let res = Command::new(BIN)
        .args([os("--verbose"), os("convert"), os(&missing), os(&out)])
        .output()
        .unwrap();
    let e = failed(&res);
    assert!(e.contains("caused by:"), "{e}");
}

/// Every malformed file of `fixtures/bad/` fails with one `error:` line, a non-zero exit code
/// and no output file.
#[test]
fn every_bad_fixture_fails_cleanly() {
    let bad = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/bad");
    let Ok(entries) = std::fs::read_dir(&bad) else {
        panic!("{} is missing", bad.display());
    };
    let tmp = tempfile::tempdir().unwrap();
    let mut n = 0;
    for e in entries {
        let input = e.unwrap().path();
        if input.extension().is_some_and(|x| x == "py" || x == "md") {
            continue; // the generator script and its notes
        }
        let out = tmp.path().join("out.tif");
        let e = fails_with(&relief!["convert", input, out], &[], &[&out]);
        assert!(
            e.starts_with("error: cannot read"),
            "{}: {e}",
            input.display()
        );
        n += 1;
    }
    assert!(n >= 10, "only {n} bad fixtures");
    assert!(files(tmp.path()).is_empty(), "stray files left");
}

/// `gdalinfo -json -checksum FILE`, or `None` (with a notice) when GDAL is not installed
/// (`.ci/run` installs Debian's gdal-bin, so CI always runs these checks).
pub(crate) fn gdalinfo(path: &Path) -> Option<serde_json::Value> {
    let out = match Command::new("gdalinfo")
        .args(["-json", "-checksum"])
        .arg(path)
        .output()
    {
        Ok(o) => o,
        Err(_) => {
            assert!(
                std::env::var_os("CI").is_none(),
                "gdalinfo is missing under CI (.ci/run installs gdal-bin)"
            );
            #[allow(clippy::print_stderr)]
            {
                eprintln!("skipping the GDAL check: gdalinfo not found");
            }
            return None;
        }
    };
    assert!(
        out.status.success(),
        "gdalinfo {}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    Some(serde_json::from_slice(&out.stdout).expect("gdalinfo -json"))
}

/// The bundled fixture and a scratch folder, or `None` (the test is skipped) without GDAL.
fn gdal_fixture() -> Option<(PathBuf, tempfile::TempDir)> {
    let src = relief_testdata::fixture("grandcanyon.tif");
    gdalinfo(&src)?;
    Some((src, tempfile::tempdir().unwrap()))
}

fn geo_transform(info: &serde_json::Value) -> Vec<f64> {
    geo_transform_of(&info["geoTransform"])
}

fn geo_transform_of(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .expect("geoTransform")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

/// Issue 14, checked with GDAL itself: a DEFLATE (predictor 3) GeoTIFF from `convert` has the
/// source's size, geotransform, CRS and band checksum; an amplified raster keeps the CRS and
/// extent with the pixel size divided by the factor.
#[test]
fn gdal_reads_relief_outputs_in_place() {
    let src = relief_testdata::fixture("grandcanyon.tif");
    let Some(orig) = gdalinfo(&src) else {
        return;
    };
    // `relief info --json` reports the grid exactly as GDAL does (grandcanyon.tif is
    // PixelIsPoint; SRTM tiles are pixel-centre registered).
    let mut files = vec![src.clone()];
    files.extend(dem("N47E011.hgt"));
    for f in &files {
        let mine = relief_json!["info", "--json", f];
        let gdal = gdalinfo(f).unwrap();
        assert_eq!(mine["size"], gdal["size"], "{}", f.display());
        let (a, b) = (
            geo_transform_of(&mine["geotransform"]),
            geo_transform(&gdal),
        );
        assert_close(&a, &b, 1e-9, &f.display().to_string());
        let epsg = mine["epsg"].as_u64().expect("an EPSG code");
        assert!(
            gdal["coordinateSystem"]["wkt"]
                .as_str()
                .unwrap()
                .contains(&format!("ID[\"EPSG\",{epsg}]")),
            "{}: EPSG {epsg}",
            f.display()
        );
    }
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("gc.tif");
    relief_ok!["convert", src, out];
    let info = gdalinfo(&out).unwrap();
    assert_eq!(info["size"], orig["size"]);
    assert_eq!(
        info["metadata"]["IMAGE_STRUCTURE"]["COMPRESSION"],
        "DEFLATE"
    );
    let (a, b) = (geo_transform(&info), geo_transform(&orig));
    assert_close(&a, &b, 1e-9, "convert");
    assert!(
        info["coordinateSystem"]["wkt"]
            .as_str()
            .unwrap()
            .contains("\"EPSG\",3857"),
        "CRS lost"
    );
    // f32 of the int16 source: GDAL's checksum of the values is the same.
    assert_eq!(info["bands"][0]["checksum"], orig["bands"][0]["checksum"]);

    // Amplify a georeferenced crop x4.
    let dem = read(&src);
    let coarse_p = tmp.path().join("coarse.tif");
    save(
        &coarse_p,
        &dem.crop(64, 96, 128, 128)
            .unwrap()
            .resample(32, 32)
            .unwrap(),
    );
    let ex = tmp.path().join("ex.tif");
    save(&ex, &dem.crop(256, 256, 256, 256).unwrap());
    let amp = tmp.path().join("amp.tif");
    ok(&relief_line(
        "amplify {} {} --exemplar {} --factor 4 --atoms 32",
        &[&coarse_p, &amp, &ex],
    ));
    let (ci, ai) = (gdalinfo(&coarse_p).unwrap(), gdalinfo(&amp).unwrap());
    assert_eq!(ai["size"], serde_json::json!([128, 128]));
    let (c, a) = (geo_transform(&ci), geo_transform(&ai));
    let want: Vec<f64> = (c.iter().enumerate())
        .map(|(k, y)| {
            if matches!(k, 1 | 2 | 4 | 5) {
                y / 4.0
            } else {
                *y
            }
        })
        .collect();
    assert_close(&a, &want, 1e-6, "amplify x4");
    assert_eq!(ai["coordinateSystem"], ci["coordinateSystem"]);
}

/// Issue 14: an ESRI ASCII grid keeps its CRS in a `.prj` (OGC WKT with the EPSG authority):
/// relief reads it back, `info --json` reports the WKT, GDAL identifies the EPSG code and
/// the extent; the `.prj` of an input is never overwritten.
#[test]
fn ascii_grids_carry_their_crs_in_a_prj() {
    let src = relief_testdata::fixture("grandcanyon.tif");
    let tmp = tempfile::tempdir().unwrap();
    let asc = tmp.path().join("gc.asc");
    relief_ok!["convert", src, asc];
    let prj = std::fs::read_to_string(tmp.path().join("gc.prj")).expect("a .prj beside the .asc");
    assert!(
        prj.starts_with("PROJCS[\"WGS 84 / Pseudo-Mercator\""),
        "{prj}"
    );
    assert!(prj.ends_with("AUTHORITY[\"EPSG\",\"3857\"]]"), "{prj}");
    let v = relief_json!["info", "--json", asc];
    assert_eq!(v["epsg"], 3857);
    assert_eq!(v["wkt"].as_str(), Some(prj.as_str()));
    // The GeoTIFF input's WKT is reported too.
    let t = relief_json!["info", "--json", src];
    assert_eq!(t["wkt"], v["wkt"]);
    let (a, b) = (
        geo_transform_of(&v["geotransform"]),
        geo_transform_of(&t["geotransform"]),
    );
    assert_close(&a, &b, 1e-9, "asc vs tif");
    // `gc.grd` would write `gc.prj`, which the input `gc.asc` reads: refused, even with --force.
    let grd = tmp.path().join("gc.grd");
    fails_with(
        &relief!["convert", asc, grd, "--force"],
        &["gc.prj"],
        &[&grd],
    );
    if let Some(info) = gdalinfo(&asc) {
        let wkt = info["coordinateSystem"]["wkt"].as_str().unwrap();
        assert!(wkt.contains("ID[\"EPSG\",3857]"), "{wkt}");
        let (a, b) = (geo_transform(&info), geo_transform_of(&t["geotransform"]));
        assert_close(&a, &b, 1e-6, "gdal");
    }
}

/// Issue 14: GeoTIFFs made by GDAL itself (ZSTD and LZW with predictors, tiled, COG, unit
/// scale/offset) read with the source's values and placement.
#[test]
fn gdal_made_geotiff_variants_read_correctly() {
    let Some((src, tmp)) = gdal_fixture() else {
        return;
    };
    let truth = read(&src);
    let t0 = truth.georef().unwrap().geotransform.unwrap();
    let variants: &[(&str, &[&str])] = &[
        (
            "zstd_fp.tif",
            &[
                "-ot",
                "Float32",
                "-co",
                "COMPRESS=ZSTD",
                "-co",
                "PREDICTOR=3",
            ],
        ),
        (
            "lzw_tiled.tif",
            &[
                "-co",
                "COMPRESS=LZW",
                "-co",
                "PREDICTOR=2",
                "-co",
                "TILED=YES",
            ],
        ),
        ("cog.tif", &["-of", "COG", "-co", "COMPRESS=DEFLATE"]),
        // Heights stored in decimetres with GDAL's unit scale: values x10, scale 0.1.
        (
            "decimetres.tif",
            &[
                "-ot", "Int32", "-scale", "0", "1", "0", "10", "-a_scale", "0.1",
            ],
        ),
    ];
    for (name, args) in variants {
        let out = tmp.path().join(name);
        let o = Command::new("gdal_translate")
            .arg("-q")
            .args(*args)
            .arg(&src)
            .arg(&out)
            .output()
            .expect("gdal_translate");
        ok(&o);
        let hf = read(&out);
        assert_eq!((hf.width(), hf.height()), (truth.width(), truth.height()));
        let worst = relief_heightfield::metrics::max_abs_diff(&hf, &truth).unwrap();
        assert!(worst < 1e-3, "{name}: values differ by up to {worst} m");
        let t = hf.georef().unwrap().geotransform.unwrap();
        assert_close(&t, &t0, 1e-9, name);
    }
}

/// Issue 14: 16-bit engine heightmaps state their vertical mapping in `OUT.json`, follow
/// `--height-range`, and refuse voids unless `--fill-voids`.
#[test]
fn heightmaps_state_their_height_range() {
    let tmp = tempfile::tempdir().unwrap();
    let src = relief_testdata::fixture("grandcanyon.tif");
    let truth = read(&src);
    let (lo, hi) = truth.min_max().unwrap();
    let r16 = tmp.path().join("h.r16");
    relief_ok!["convert", src, r16];
    let side: serde_json::Value = json(&tmp.path().join("h.r16.json"));
    assert_eq!(side["height_min_m"].as_f64().unwrap(), lo as f64);
    assert_eq!(side["height_max_m"].as_f64().unwrap(), hi as f64);
    assert_eq!(side["width"], 512);
    // The stored counts follow the stated mapping.
    let raw = std::fs::read(&r16).unwrap();
    let scale = side["metres_per_count"].as_f64().unwrap();
    let count = u16::from_le_bytes([raw[2 * 700], raw[2 * 700 + 1]]) as f64;
    assert!((lo as f64 + count * scale - truth.as_slice()[700] as f64).abs() <= scale);
    // A fixed range: PNG16 with 0..4000 m.
    let png = tmp.path().join("h.png");
    relief_ok!["--height-range", "0,4000", "convert", src, png];
    let side: serde_json::Value = json(&tmp.path().join("h.png.json"));
    assert_eq!(side["height_range_m"].as_f64().unwrap(), 4000.0);
    // Voids are refused for heightmaps, and nothing is left behind.
    let mut holed = truth.clone();
    holed.set(10, 10, f32::NAN);
    let holed_p = tmp.path().join("holed.tif");
    save(&holed_p, &holed);
    let out = tmp.path().join("v.r16");
    assert!(failed(&relief!["convert", holed_p, out]).contains("--fill-voids"));
    assert!(!out.exists() && !tmp.path().join("v.r16.json").exists());
    relief_ok!["convert", "--fill-voids", holed_p, out];
}

/// Issue 14: a Mapbox Terrain-RGB PNG (no relief marker) reads with `--png-encoding
/// terrain-rgb`; without it the error names that flag, not a Rust API.
#[test]
fn terrain_rgb_png_reads_from_the_command_line() {
    let tmp = tempfile::tempdir().unwrap();
    let (w, h) = (8usize, 4usize);
    let mut rgb = Vec::new();
    for i in 0..w * h {
        let code = ((100.0 + i as f64 + 10_000.0) * 10.0).round() as u32;
        rgb.extend_from_slice(&[(code >> 16) as u8, (code >> 8) as u8, code as u8]);
    }
    let p = tmp.path().join("tile.png");
    relief_io::write_rgb_png(&p, w, h, &rgb).unwrap();
    let res = relief!["info", p];
    let e = failed(&res);
    assert!(
        e.contains("--png-encoding terrain-rgb") && !e.contains("PngMode"),
        "{e}"
    );
    let v = relief_json!["info", "--json", "--png-encoding", "terrain-rgb", p];
    assert!((v["statistics"]["min"].as_f64().unwrap() - 100.0).abs() < 0.06);
    assert!((v["statistics"]["max"].as_f64().unwrap() - 131.0).abs() < 0.06);
}

/// `relief run SPEC.json` resolves the spec's paths against the spec's folder, writes
/// summary.json and report.html, and its figures equal the library pipeline's (what
/// `cargo xtask pipeline SPEC.json` runs) on the same spec; a failing spec leaves nothing.
#[test]
fn run_spec_matches_the_library_pipeline_and_is_all_or_nothing() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let tmp = tempfile::tempdir().unwrap();
    let job = tmp.path().join("job");
    std::fs::create_dir(&job).unwrap();
    std::fs::copy(
        root.join("fixtures/grandcanyon.tif"),
        job.join("canyon.tif"),
    )
    .unwrap();
    let spec = job.join("spec.json");
    std::fs::write(
        &spec,
        r#"{ "input": "canyon.tif", "crop": [40, 30, 96, 64], "seed": 3,
             "stages": [ { "stage": "load" }, { "stage": "fill_voids" }, { "stage": "convert" },
                         { "stage": "wavelet", "params": { "job": { "extra_levels": 1 }, "quality": false } } ] }"#,
    )
    .unwrap();
    let out = tmp.path().join("out");
    relief_ok!["run", spec, "--out", out];
    for f in ["summary.json", "report.html", "dem.tif", "dem.png"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let from_cli: serde_json::Value = json(&out.join("summary.json"));

    let lib_out = tmp.path().join("lib");
    let parsed = relief_cli::pipeline::spec::PipelineSpec::read(&spec).unwrap();
    let mut config = relief_cli::pipeline::PipelineConfig::new(PathBuf::new(), lib_out.clone());
    parsed.apply(&mut config);
    config.verbose = false;
    let stages = relief_cli::pipeline::spec::build_stages(&parsed.stages).unwrap();
    relief_cli::pipeline::run(&config, &stages).unwrap();
    let from_lib: serde_json::Value = json(&lib_out.join("summary.json"));
    let figures = |v: &serde_json::Value| -> Vec<(String, String, serde_json::Value)> {
        let mut all = Vec::new();
        for st in v["stages"].as_array().unwrap() {
            for (k, f) in st["figures"].as_object().unwrap() {
                if !(k.contains("second") || k.contains("per_s") || k.contains("memory")) {
                    all.push((st["stage"].to_string(), k.clone(), f.clone()));
                }
            }
        }
        all
    };
    let (a, b) = (figures(&from_cli), figures(&from_lib));
    assert!(a.len() > 10, "{a:?}");
    assert_eq!(a, b);
    assert_eq!(from_cli["stages"][0]["figures"]["width"], 96);

    // Re-running into the same (now non-empty) folder needs --force.
    assert!(failed(&relief!["run", spec, "--out", out]).contains("not empty"));
    // The input inside the output folder is refused.
    assert!(
        failed(&relief!["--force", "run", spec, "--out", job]).contains("write over its inputs")
    );
    // A stage that fails leaves no output folder and no staging folder.
    std::fs::write(
        &spec,
        r#"{ "input": "canyon.tif", "stages": [ { "stage": "fill_voids" } ] }"#,
    )
    .unwrap();
    let dead = tmp.path().join("failed");
    assert!(failed(&relief!["run", spec, "--out", dead]).contains("`load` stage must come first"));
    let left: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!dead.exists());
    assert!(
        left.iter().all(|n| !n.starts_with(".relief-stage")),
        "{left:?}"
    );
}

/// Issue 14, every raster-producing command checked with GDAL: from a georeferenced input,
/// `refine`, `decompress`, `fit-procedural`, `quilt` and `synthesize` write rasters with the
/// input's CRS and extent and the pixel size divided by their factor. `refine --model paper`
/// is the documented exception: the paper's dyadic lattice puts refined samples on the input
/// samples, so its georeference is the same size and pixel but shifted (1.5 refined pixels
/// after two levels, 0.5 per level in that level's pixels), and says so.
#[test]
fn gdal_places_every_command_output_on_the_input_extent() {
    let Some((src, tmp)) = gdal_fixture() else {
        return;
    };
    let dem = read(&src);
    let input = tmp.path().join("in.tif");
    save(&input, &dem.crop(64, 96, 128, 128).unwrap());
    let ex = tmp.path().join("ex.tif");
    save(&ex, &dem.crop(256, 256, 256, 256).unwrap());
    let sct = tmp.path().join("in.sct");
    relief_ok!["compress", input, sct];
    let base = gdalinfo(&input).unwrap();
    let t0 = geo_transform(&base);
    // Each command line with IN, EX, SCT and OUT standing for the files, and its factor.
    let cases = [
        ("refine IN OUT --levels 2", 4.0),
        ("refine IN OUT --levels 2 --model paper", 4.0),
        ("decompress SCT OUT --scale 2", 2.0),
        ("fit-procedural IN OUT", 1.0),
        ("quilt OUT --guide IN --exemplar EX --no-validate", 1.0),
        ("synthesize IN OUT --exemplar EX --steps 1", 4.0),
    ];
    for (i, (line, f)) in cases.into_iter().enumerate() {
        let o = tmp.path().join(format!("out{i}.tif"));
        let (input, ex, sct) = (s(&input), s(&ex), s(&sct));
        let args = line.split(' ');
        let args: Vec<&str> = (args.map(|a| match a {
            "IN" => input,
            "OUT" => s(&o),
            "SCT" => sct,
            "EX" => ex,
            a => a,
        }))
        .collect();
        ok(&relief(&args));
        let info = gdalinfo(&o).unwrap();
        let what = line;
        assert_eq!(
            info["size"],
            serde_json::json!([(128.0 * f) as u64, (128.0 * f) as u64]),
            "{what}"
        );
        assert_eq!(info["coordinateSystem"], base["coordinateSystem"], "{what}");
        let t = geo_transform(&info);
        // The paper's lattice: 0.5 pixel of each new level, in the output's pixels 1.5.
        let shift = if line.ends_with("paper") { 1.5 } else { 0.0 };
        let want = [
            t0[0] + shift * t0[1] / f,
            t0[1] / f,
            t0[2] / f,
            t0[3] + shift * t0[5] / f,
            t0[4] / f,
            t0[5] / f,
        ];
        assert_close(&t, &want, 1e-6, what);
    }
}

/// Issue 14: `preview` takes the light and the exaggeration, and refuses a bad one by its flag
/// without writing.
#[test]
fn preview_light_flags_are_used_and_checked() {
    let src = relief_testdata::fixture("grandcanyon.tif");
    let tmp = tempfile::tempdir().unwrap();
    let a = tmp.path().join("a.png");
    let b = tmp.path().join("b.png");
    relief_ok!["preview", src, a];
    ok(&relief_line(
        "preview {} {} --azimuth 90 --altitude 20 --exaggeration 3",
        &[&src, &b],
    ));
    assert_ne!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    for (flag, v) in [
        ("--altitude", "95"),
        ("--exaggeration", "0"),
        ("--azimuth", "nan"),
    ] {
        let c = tmp.path().join("c.png");
        fails_with(&relief!["preview", src, c, flag, v], &[flag], &[&c]);
    }
}

/// Issue 14: `--size-plus-one` writes the corner samples of a 16-bit heightmap (a 512^2 DEM
/// becomes the 513^2 heightmap engines expect, over the same extent), and is refused where no
/// output is a 16-bit heightmap.
#[test]
fn size_plus_one_writes_engine_heightmaps() {
    let src = relief_testdata::fixture("grandcanyon.tif");
    let tmp = tempfile::tempdir().unwrap();
    let r16 = tmp.path().join("h.r16");
    relief_ok!["convert", src, r16, "--size-plus-one"];
    assert_eq!(std::fs::metadata(&r16).unwrap().len(), 513 * 513 * 2);
    let side: serde_json::Value = json(&tmp.path().join("h.r16.json"));
    assert_eq!(side["width"], 513);
    assert_eq!(side["height"], 513);
    let cell = side["cell_size_m"][0].as_f64().unwrap();
    let extent = side["extent_m"][0].as_f64().unwrap();
    assert!((extent - 512.0 * cell).abs() < 1e-6, "{side}");
    // The corner between the first four cells is their mean (within a 16-bit count).
    let dem = read(&src);
    let raw = std::fs::read(&r16).unwrap();
    let count = u16::from_le_bytes([raw[(513 + 1) * 2], raw[(513 + 1) * 2 + 1]]) as f64;
    let h = side["offset_m"].as_f64().unwrap() + count * side["metres_per_count"].as_f64().unwrap();
    let mean = (dem.get(0, 0) + dem.get(1, 0) + dem.get(0, 1) + dem.get(1, 1)) as f64 / 4.0;
    assert!(
        (h - mean).abs() <= side["metres_per_count"].as_f64().unwrap(),
        "{h} vs {mean}"
    );
    let tif = tmp.path().join("h.tif");
    let res = relief!["convert", src, tif, "--size-plus-one"];
    fails_with(&res, &["--size-plus-one"], &[&tif]);
}

/// Issue 14: `--compress zstd|lzw` GeoTIFFs (with the floating-point predictor) read in GDAL
/// with the same values as the source, and back in relief exactly; a COG mosaic takes them too.
#[test]
fn zstd_and_lzw_geotiffs_read_in_gdal_and_relief() {
    let src = relief_testdata::fixture("grandcanyon.tif");
    let tmp = tempfile::tempdir().unwrap();
    let dem = read(&src);
    let orig = gdalinfo(&src);
    let mut sizes = Vec::new();
    for (codec, gdal_name) in [("deflate", "DEFLATE"), ("zstd", "ZSTD"), ("lzw", "LZW")] {
        let out = tmp.path().join(format!("{codec}.tif"));
        relief_ok!["--compress", codec, "convert", src, out];
        assert_eq!(read(&out).as_slice(), dem.as_slice(), "{codec}");
        sizes.push(std::fs::metadata(&out).unwrap().len());
        if let (Some(info), Some(orig)) = (gdalinfo(&out), &orig) {
            let st = &info["metadata"]["IMAGE_STRUCTURE"];
            assert_eq!(st["COMPRESSION"], gdal_name, "{codec}: {st}");
            assert_eq!(st["PREDICTOR"], "3", "{codec}: {st}");
            assert_eq!(
                info["bands"][0]["checksum"], orig["bands"][0]["checksum"],
                "{codec}"
            );
        }
    }
    let raw = (dem.len() * 4) as u64;
    assert!(
        sizes.iter().all(|&s| s < raw),
        "{sizes:?} vs {raw} uncompressed"
    );
}

/// Issue 14: the global `--cog` makes any command's GeoTIFF a Cloud-Optimized GeoTIFF (tiled,
/// overviews, GDAL's COG layout) with the same values and place; streamed outputs are tiled
/// and compressed too; `--cog` with no GeoTIFF output is refused.
#[test]
fn cog_flag_writes_cloud_optimized_geotiffs() {
    let src = relief_testdata::fixture("grandcanyon.tif");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("cog.tif");
    relief_ok!["--cog", "--compress", "zstd", "convert", src, out];
    assert_eq!(read(&out).as_slice(), read(&src).as_slice());
    if let (Some(info), Some(orig)) = (gdalinfo(&out), gdalinfo(&src)) {
        assert_eq!(
            info["metadata"]["IMAGE_STRUCTURE"]["LAYOUT"], "COG",
            "{info}"
        );
        assert_eq!(info["metadata"]["IMAGE_STRUCTURE"]["COMPRESSION"], "ZSTD");
        // 512^2 is one 512-pixel tile: no overview is needed (the tile test checks them).
        assert_eq!(
            info["bands"][0]["block"],
            serde_json::json!([512, 512]),
            "{info}"
        );
        assert_eq!(info["bands"][0]["checksum"], orig["bands"][0]["checksum"]);
        assert_eq!(geo_transform(&info), geo_transform(&orig));
    }
    let png = tmp.path().join("x.png");
    let res = relief!["--cog", "convert", src, png];
    assert!(!res.status.success() && stderr(&res).contains("--cog"));
    assert!(!png.exists());
}

/// Issue 44 item 9: `--force convert h.png h.png.f32` wrote the `.f32`'s sidecar over
/// `h.png.json`, the input heightmap's own (its cell size and height mapping); it is refused
/// and the sidecar is left as it was.
#[test]
fn force_never_replaces_an_input_heightmap_sidecar() {
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("h.png");
    relief_ok!["convert", relief_testdata::fixture("grandcanyon.tif"), png];
    let side = tmp.path().join("h.png.json");
    let before = std::fs::read(&side).unwrap();
    let out = tmp.path().join("h.png.f32");
    fails_with(
        &relief!["--force", "convert", png, out],
        &["would overwrite the input"],
        &[&out],
    );
    assert_eq!(std::fs::read(&side).unwrap(), before);
}

/// Issue 44 item 11, data read wrongly or silently assumed:
/// - relief's own `.r16` reads back in metres (its sidecar's `offset_m` and
///   `metres_per_count`), not as raw counts;
/// - a file without a cell size (a PNG without its sidecar) is flagged: `info` says the 1 m
///   is assumed (`cell_size_assumed` in `--json`), commands warn, `volume` refuses;
/// - `--cell-size` on a GeoTIFF input is what a GeoTIFF output states;
/// - `convert` of a `.sct` names it a model and points to `decompress`; `info` refuses a
///   dictionary without atoms.
#[test]
fn own_heightmaps_read_back_and_assumed_cells_are_flagged() {
    let tmp = tempfile::tempdir().unwrap();
    let src = relief_testdata::fixture("grandcanyon.tif");
    let truth = read(&src);
    let r16 = tmp.path().join("h.r16");
    relief_ok!["convert", src, r16];
    let back = tmp.path().join("back.tif");
    relief_ok!["convert", r16, back];
    let b = read(&back);
    let scale = json(&tmp.path().join("h.r16.json"))["metres_per_count"]
        .as_f64()
        .unwrap();
    let worst = relief_heightfield::metrics::max_abs_diff(&b, &truth).unwrap();
    assert!(
        worst <= scale,
        "r16 read back {worst} m off (a count is {scale} m)"
    );
    assert_eq!(b.cell_size(), truth.cell_size());

    // A PNG without its sidecar stores no cell size.
    let png = tmp.path().join("p.png");
    relief_ok!["convert", src, png];
    std::fs::remove_file(tmp.path().join("p.png.json")).unwrap();
    let text = relief_ok!["info", png];
    assert!(text.contains("ASSUMED"), "{text}");
    assert_eq!(
        relief_json!["info", png, "--json"]["cell_size_assumed"],
        true
    );
    assert_eq!(
        relief_json!["info", png, "--json", "--cell-size", "30"]["cell_size_assumed"],
        false
    );
    assert_eq!(
        relief_json!["info", src, "--json"]["cell_size_assumed"],
        false
    );
    let tif = tmp.path().join("p.tif");
    let o = relief_loud(&[os("convert"), os(&png), os(&tif)]);
    ok(&o);
    assert_stderr_has(&o, "warning: ");
    assert_stderr_has(&o, "stores no cell size");
    let glb = tmp.path().join("p.glb");
    fails_with(
        &relief!["volume", png, "--crop", "0,0,24,24", "--mesh", glb],
        &["stores no cell size", "--cell-size"],
        &[&glb],
    );

    // --cell-size on a GeoTIFF: the GeoTIFF written states it.
    let out = tmp.path().join("c30.tif");
    relief_ok!["convert", src, out, "--cell-size", "30"];
    let (cx, cy) = read(&out).cell_size();
    assert!(
        (cx - 30.0).abs() < 1e-6 && (cy - 30.0).abs() < 1e-6,
        "{cx} x {cy}"
    );

    // Models: convert rasterises a tree at its own grid (as decompress does); a dictionary
    // is refused, and one without atoms also by info.
    let sct = tmp.path().join("m.sct");
    let model =
        relief_sparse_core::Sct::new(relief_sparse_core::Node::Constant(1.0), 8, 8, (1.0, 1.0))
            .unwrap();
    std::fs::write(&sct, model.to_bytes().unwrap()).unwrap();
    let raster = tmp.path().join("m.tif");
    relief_ok!["convert", &sct, &raster];
    let r = read(&raster);
    assert_eq!((r.width(), r.height()), (8, 8));
    assert!(r.as_slice().iter().all(|&v| v == 1.0));
    let dict = tmp.path().join("empty.dict");
    let empty = relief_sparse_core::Dictionary::new(8, 1.0, 4.0).unwrap();
    std::fs::write(&dict, empty.to_bytes().unwrap()).unwrap();
    let raster2 = tmp.path().join("d.tif");
    fails_with(
        &relief!["convert", &dict, &raster2],
        &["is a relief model", "dictionary of patches"],
        &[&raster2],
    );
    fails_with(&relief!["info", dict], &["empty dictionary"], &[]);
}
