//! `relief volume` end to end on crops of the bundled fixture `fixtures/grandcanyon.tif`
//! (western Grand Canyon, 61.7 m cells): outputs, printed counts, masks and bad input.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::*;

/// Width and height from a PNG's IHDR chunk.
fn png_size(p: &Path) -> (u32, u32) {
    let b = std::fs::read(p).unwrap();
    assert_eq!(&b[1..4], b"PNG", "{} is not a PNG", p.display());
    let be = |o: usize| u32::from_be_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    (be(16), be(20))
}

/// The bundled fixture DEM.
fn gc() -> PathBuf {
    relief_testdata::fixture("grandcanyon.tif")
}

#[test]
fn volume_writes_mesh_render_and_section_of_a_canyon_crop() {
    let dir = tempfile::tempdir().unwrap();
    let (glb, png, sec, close, report) = (
        dir.path().join("scene.glb"),
        dir.path().join("render.png"),
        dir.path().join("section.png"),
        dir.path().join("close.png"),
        dir.path().join("report.json"),
    );
    let input = gc();
    let out = relief_line(
        "volume {} --crop 200,160,32,32 \
         --features sea,caves,karst,hoodoos,arches,islands,overhangs --mesh {} \
         --render {} --section {} --closeups {} --report {} --max-triangles 20000 \
         --image-size 64x48 --resolution 1 --seed 3 --raw-dem",
        &[&input, &glb, &png, &sec, &close, &report],
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    ok(&out);
    for key in [
        "tree:",
        "nodes",
        "karst:",
        "watertight, manifold",
        "implicitise:",
    ] {
        assert!(stdout.contains(key), "`{key}` missing:\n{stdout}");
    }
    // The canyon has no sea (issue 19): the shore features are skipped with a note, no water.
    assert!(
        stdout.lines().any(|l| l.starts_with("note:")
            && l.contains("shore features skipped (sea, caves): no sea in this DEM")),
        "no sea note:\n{stdout}"
    );
    assert!(stdout.contains("no sea, voxel"), "{stdout}");
    assert!(!stdout.lines().any(|l| l.starts_with("sea:")), "{stdout}");
    // Every other requested feature added primitives to the tree, or a note says why it could
    // not be built (--raw-dem: on 61.7 m cells hoodoos, arches and overhangs are refused,
    // naming the cell they need).
    for f in ["karst", "overhangs", "hoodoos", "arches", "islands"] {
        match stdout.lines().find(|l| l.starts_with(&format!("{f}:"))) {
            Some(line) => {
                let n: usize = line.split_whitespace().nth(1).unwrap().parse().unwrap();
                assert!(n > 0, "{line}");
            }
            None => assert!(
                stdout.lines().any(|l| l.starts_with("note:")
                    && (l.contains(&format!("{f} skipped"))
                        || (l.contains(&format!("{f} refused: they need DEM cells of at most"))
                            && l.contains("61.7 m")))),
                "no `{f}` line nor note:\n{stdout}"
            ),
        }
    }
    // The report: nodes in total and by kind, sizes in metres, the mesh within its budget.
    let r: serde_json::Value = json(&report);
    let nodes = r["tree_nodes"].as_u64().unwrap();
    let by_kind: u64 = r["tree_nodes_by_kind"]
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(nodes, by_kind, "{r}");
    // Carvings: karst steps are ellipsoids flattened along the bedding, the others spheres.
    let kind = |k: &str| r["tree_nodes_by_kind"][k].as_u64().unwrap_or(0);
    assert!(kind("sphere_carving") + kind("ellipsoid") > 0, "{r}");
    assert!(r["karst_passage_length_m"].as_f64().unwrap() > 0.0, "{r}");
    assert!((r["dimensions"]["voxel_m"].as_f64().unwrap() - 61.703).abs() < 0.01);
    assert!(r["mesh_triangles"].as_u64().unwrap() <= 20_000);
    assert_eq!(r["mesh_watertight_manifold"], true);
    assert!(r["build_s"].as_f64().is_some() && r["render_s"].as_f64().is_some());
    assert_eq!(r["water_drawn"], false, "no sea, no water");
    assert!(
        r["sea_level_m"].is_null() && r["sea_detected"].is_null(),
        "{r}"
    );
    assert!(r["effects"]["sea"].is_null(), "{r}");
    let (cw, ch) = png_size(&close);
    assert!(ch == 24 && cw % 32 == 0 && cw >= 32, "{cw}x{ch}");
    let g = std::fs::read(&glb).unwrap();
    assert_eq!(&g[..4], b"glTF");
    assert!(g.len() > 10_000 && g.len() < 2_000_000, "{} bytes", g.len());
    assert_eq!(png_size(&png), (64, 48));
    assert_eq!(png_size(&sec), (64, 48));
}

#[test]
fn volume_mesh_formats_and_mask_limit_the_effects() {
    let dir = tempfile::tempdir().unwrap();
    let input = gc();
    // A mask of zeros switches the karst off; PLY and OBJ are written too.
    let mask = dir.path().join("mask.png");
    relief_io::write_gray_png(&mask, 24, 24, &[0u8; 24 * 24]).unwrap();
    for ext in ["ply", "obj"] {
        let mesh = dir.path().join(format!("m.{ext}"));
        let out = relief_line(
            "volume {} --crop 100,100,24,24 --features karst --mask {} --mesh {} \
             --resolution 1",
            &[&input, &mask, &mesh],
        );
        let stdout = String::from_utf8_lossy(&out.stdout);
        ok(&out);
        assert!(stdout.contains("karst:        0 primitives"), "{stdout}");
        let head = std::fs::read(&mesh).unwrap();
        match ext {
            "ply" => assert!(head.starts_with(b"ply\n")),
            _ => assert!(head.starts_with(b"v ") || head.starts_with(b"#")),
        }
    }
    // A full mask lets it carve.
    let full = dir.path().join("full.png");
    relief_io::write_gray_png(&full, 24, 24, &[255u8; 24 * 24]).unwrap();
    let out = relief_line(
        "volume {} --crop 100,100,24,24 --features karst --mask {} --section {}",
        &[&input, &full, &s(&dir.path().join("full_section.png"))],
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    ok(&out);
    assert!(!stdout.contains("karst:        0 primitives"), "{stdout}");
}

/// Issue 14: `--up y` writes OBJ/PLY meshes rotated into a Y-up frame, `(x, y, z) -> (x, z,
/// -y)`, vertex for vertex; `--up z` with a GLB (Y-up by specification) is refused.
#[test]
fn volume_up_axis_rotates_obj_and_ply() {
    let dir = tempfile::tempdir().unwrap();
    let input = gc();
    let obj_vertices = |p: &Path| -> Vec<[f32; 3]> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .filter_map(|l| l.strip_prefix("v "))
            .map(|l| {
                let v: Vec<f32> = l.split_whitespace().map(|t| t.parse().unwrap()).collect();
                [v[0], v[1], v[2]]
            })
            .collect()
    };
    let run = |up: &str, mesh: &Path| {
        ok(&relief_line(
            // The plain DEM mesh: the axis swap is the same for every scene, and an arch on
            // this crop is a 6 M-triangle scene on a refined window (15 s of the suite).
            "volume {} --crop 100,100,24,24 --features none --mesh {} --up {}",
            &[&input, &mesh, &up],
        ));
        obj_vertices(mesh)
    };
    let z = run("z", &dir.path().join("z.obj"));
    let y = run("y", &dir.path().join("y.obj"));
    assert_eq!(z.len(), y.len());
    assert!(!z.is_empty());
    for (a, b) in z.iter().zip(&y) {
        assert_eq!([a[0], a[2], -a[1]], *b);
    }
    // The terrain's height range lies along z in one and along y in the other.
    let span = |v: &[[f32; 3]], k: usize| {
        let (lo, hi) = v.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
            (lo.min(p[k]), hi.max(p[k]))
        });
        hi - lo
    };
    assert_eq!(span(&z, 2), span(&y, 1));
    let glb = dir.path().join("m.glb");
    let out = relief_line(
        "volume {} --crop 100,100,24,24 --mesh {} --up z",
        &[&input, &glb],
    );
    fails_with(&out, &["Y-up"], &[&glb]);
}

#[test]
fn volume_rejects_bad_input_without_writing() {
    let dir = tempfile::tempdir().unwrap();
    let input = gc();
    let glb = dir.path().join("o.glb");
    let png = dir.path().join("o.png");
    let base = |extra: &[&str]| {
        let mut v = vec![
            "volume",
            s(&input),
            "--crop",
            "0,0,16,16",
            "--mesh",
            s(&glb),
            "--render",
            s(&png),
        ];
        v.extend_from_slice(extra);
        relief(&v)
    };
    let out = base(&["--features", "sea,volcano"]);
    fails_with(&out, &["volcano"], &[&glb, &png]);

    let small = dir.path().join("small.png");
    relief_io::write_gray_png(&small, 8, 8, &[255u8; 64]).unwrap();
    let out = base(&["--mask", s(&small)]);
    fails_with(&out, &["8x8"], &[&glb, &png]);

    let out = base(&["--sea-level", "NaN"]);
    fails_with(&out, &["sea_level"], &[&glb, &png]);

    // A DEM with a void (NaN) cannot be implicitised.
    let raster = relief_io::read(&input, &relief_io::ReadOptions::default()).unwrap();
    let mut hf = raster.heightfield.crop(0, 0, 16, 16).unwrap();
    hf.set(5, 5, f32::NAN);
    let holed = dir.path().join("holed.tif");
    save(&holed, &hf);
    let out = relief!["volume", &holed, "--mesh", &glb, "--render", &png];
    fails_with(&out, &["void"], &[&glb, &png]);

    let bad_ext = dir.path().join("o.stl");
    let out = relief!["volume", &input, "--mesh", &bad_ext];
    fails_with(&out, &[".glb"], &[&bad_ext]);
}

/// Issue 14: the GLB of `relief volume` passes the Khronos glTF validator with no error and
/// no warning (`.ci/run` installs it from npm into target/gltf-validator; skipped with a notice
/// elsewhere when missing, a failure under CI).
#[test]
fn glb_passes_the_khronos_validator() {
    let modules =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/gltf-validator/node_modules");
    if !modules.join("gltf-validator").is_dir() {
        assert!(
            std::env::var_os("CI").is_none(),
            "gltf-validator is missing under CI (.ci/run installs it)"
        );
        #[allow(clippy::print_stderr)]
        {
            eprintln!("skipping: gltf-validator not installed in target/gltf-validator");
        }
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("v.glb");
    // A small mesh: two mesh cells per DEM cell (the default voxel makes 6.4 million
    // triangles here and simplifies them to 2 million, seconds of work the check needs not).
    relief_ok![
        "volume",
        &gc(),
        "--crop",
        "100,100,24,24",
        "--resolution",
        "2",
        "--mesh",
        &glb
    ];
    let script = "const v=require('gltf-validator');const b=new Uint8Array(require('fs')\
                  .readFileSync(process.argv[1]));v.validateBytes(b).then(r=>{console.log(\
                  JSON.stringify(r.issues))}).catch(e=>{console.error(String(e));process.exit(2)})";
    let res = Command::new("node")
        .env("NODE_PATH", &modules)
        .arg("-e")
        .arg(script)
        .arg(&glb)
        .output()
        .expect("run node");
    ok(&res);
    let issues: serde_json::Value = serde_json::from_slice(&res.stdout).unwrap();
    assert_eq!(issues["numErrors"], 0, "{issues}");
    assert_eq!(issues["numWarnings"], 0, "{issues}");
    // The mesh carries its strata's colours (COLOR_0) under a material they multiply.
    let b = std::fs::read(&glb).unwrap();
    let jl = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
    let json: serde_json::Value = serde_json::from_slice(&b[20..20 + jl]).unwrap();
    let prim = &json["meshes"][0]["primitives"][0];
    assert!(prim["attributes"].get("COLOR_0").is_some(), "{prim}");
    assert_eq!(prim["material"], 0);
}

/// `--sea-level` puts a shore in the canyon on purpose (the behaviour before issue 19's sea
/// detection): sea erosion and caves carved, water drawn at that level.
#[test]
fn volume_sea_level_puts_a_lake_shore_in_the_canyon() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("r.json");
    let stdout = ok(&relief_line(
        "volume {} --crop 218,160,12,12 --features sea,caves --sea-level 685 \
         --render {} --image-size 32x24 --report {}",
        &[&gc(), &s(&dir.path().join("r.png")), &report],
    ));
    assert!(stdout.contains("sea level 685.0 m,"), "{stdout}");
    let r: serde_json::Value = json(&report);
    assert_eq!(r["sea_level_m"], 685.0, "{r}");
    assert!(r["sea_detected"].is_null(), "{r}");
    assert_eq!(r["water_drawn"], true, "{r}");
    assert!(
        r["effects"]["sea"]["primitives"].as_u64().unwrap() > 0,
        "{r}"
    );
    assert!(!r["notes"].to_string().contains("no sea"), "{r}");
}

/// `--geology FILE.json` drives the strata (echoed in the report), a karst-only scene draws no
/// water, and a bad geology fails before any output is written.
#[test]
fn volume_reads_a_geology_and_draws_water_only_with_sea() {
    let dir = tempfile::tempdir().unwrap();
    let input = gc();
    let geo = dir.path().join("geo.json");
    std::fs::write(
        &geo,
        r#"{"type": "strata", "z0": 0, "layers": [
            {"thickness": 60, "hardness": 0.1}, {"thickness": 40, "hardness": 0.9}]}"#,
    )
    .unwrap();
    let report = dir.path().join("r.json");
    let png = dir.path().join("r.png");
    ok(&relief_line(
        "volume {} --crop 100,100,24,24 --features karst --geology {} --render {} \
         --image-size 32x24 --report {}",
        &[&input, &geo, &png, &report],
    ));
    let r: serde_json::Value = json(&report);
    assert_eq!(r["geology"]["type"], "strata", "{r}");
    assert!((r["geology"]["layers"][1]["hardness"].as_f64().unwrap() - 0.9).abs() < 1e-6);
    assert_eq!(r["water_drawn"], false);
    let soft = r["dimensions"]["soft_thickness_m"].as_f64().unwrap();
    assert!((soft - 60.0).abs() < 10.0, "{soft}");

    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, r#"{"type": "strata", "z0": 0, "layers": []}"#).unwrap();
    let out2 = dir.path().join("o.png");
    let rep2 = dir.path().join("o.json");
    let out = relief_line(
        "volume {} --crop 100,100,24,24 --geology {} --render {} --report {}",
        &[&input, &bad, &out2, &rep2],
    );
    fails_with(&out, &["layers"], &[&out2, &rep2]);
    let out = relief!["volume", &input, "--report", s(&dir.path().join("x.txt"))];
    fails_with(&out, &[".json"], &[]);
}

/// The limit leaves time to build the scene and time the pilot (about 2 s here), not the
/// render it estimates (7 s in a release build; the adaptive render made 2048 x 1536 fit):
/// refused before it starts. (A limit shorter than the
/// scene's build stops the build itself: `limits::meshing_stops_at_the_time_limit`.)
#[test]
fn volume_renders_over_the_time_budget_are_refused_before_starting() {
    let dir = tempfile::tempdir().unwrap();
    let render = dir.path().join("r.png");
    let mesh = dir.path().join("m.obj");
    let out = relief_line(
        "volume {} --crop 100,100,24,24 --features arches --mesh {} --render {} \
         --image-size 4096x3072 --max-time 5s",
        &[&gc(), &mesh, &render],
    );
    fails_with(&out, &["--max-time"], &[&render, &mesh]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("rendering 4096 x 3072 images") && err.contains("estimated at"),
        "{err}"
    );
    assert!(err.contains("--image-size"), "{err}");
}

/// Issue 42: on the fixture's 61.7 m cells, hoodoos (which need 12 m cells) are built on a
/// centred window refined 8x (three wavelet levels, 7.7 m cells) as wide as their voxel affords,
/// a note says so, and the report lists each feature's sizes in metres; `--raw-dem` refuses
/// them instead, naming the cell they need. The sizes do not follow the crop: the same heights
/// on a 24 and a 48 cell crop.
#[test]
fn volume_amplifies_a_window_for_features_finer_than_the_cells() {
    let dir = tempfile::tempdir().unwrap();
    let run = |crop: &str, raw: bool| {
        let report = dir.path().join(format!("r{crop}{raw}.json"));
        let out = relief_line(
            &format!(
                "volume {{}} --crop {crop} --features hoodoos,karst --report {{}}{}",
                if raw { " --raw-dem" } else { "" }
            ),
            &[&gc(), &report],
        );
        let stdout = ok(&out);
        (stdout, json(&report))
    };
    let (stdout, r) = run("200,160,24,24", false);
    assert!(
        stdout.contains("refined 8x (wavelet, 3 levels) from 61.7 m to 7.7 m cells"),
        "{stdout}"
    );
    assert!(
        (r["dimensions"]["cell_m"].as_f64().unwrap() - 7.713).abs() < 0.01,
        "{r}"
    );
    let sizes = &r["dimensions"]["sizes"];
    let h = &sizes["hoodoos"];
    assert!(h["count"].as_u64().unwrap() > 0, "{r}");
    assert!(
        h["min"].as_f64().unwrap() >= 1.5 && h["max"].as_f64().unwrap() <= 45.0,
        "{h}"
    );
    let k = &sizes["karst"];
    assert!(
        k["measure"] == "passage radius" && k["max"].as_f64().unwrap() <= 15.0,
        "{k}"
    );
    assert!(r["notes"].to_string().contains("refined 8x"), "{r}");
    // A larger crop: a window of the same size, the same sizes.
    let (_, r2) = run("188,148,48,48", false);
    let h2 = &r2["dimensions"]["sizes"]["hoodoos"];
    let med = |h: &serde_json::Value| h["median"].as_f64().unwrap();
    assert!((med(h) - med(h2)).abs() <= 0.3 * med(h), "{h} vs {h2}");
    assert_eq!(r["width"], r2["width"]);
    // --raw-dem: refused with the cell they need, karst still carved at its radius.
    let (stdout, r) = run("200,160,24,24", true);
    assert!(
        stdout.contains(
            "hoodoos refused: they need DEM cells of at most 12.0 m, this DEM's are 61.7 m"
        ),
        "{stdout}"
    );
    assert!(r["dimensions"]["sizes"]["hoodoos"].is_null(), "{r}");
    assert!(
        r["dimensions"]["sizes"]["karst"]["count"].as_u64().unwrap() > 0,
        "{r}"
    );
}

/// Issue 42: a coast of 567 m cells (topobathy's scale) gets its shore features at physical
/// size on a window around the coast refined 64x (8.9 m cells), the DEM's sea level passed on;
/// with --raw-dem they are refused naming the cell they need. Never kilometre-wide caves.
#[test]
fn volume_builds_the_shore_of_a_coarse_coast_on_an_amplified_window() {
    let dir = tempfile::tempdir().unwrap();
    let hf = relief_heightfield::Heightfield::from_fn(40, 40, 567.0, 567.0, |x, y| {
        if x < 17 {
            -1.0
        } else {
            (x as f32 - 16.5) * 40.0 + 25.0 * ((y as f32) * 0.7).sin()
        }
    });
    let input = write(dir.path(), "coast.tif", &hf);
    let run = |raw: bool| {
        let report = dir.path().join(format!("c{raw}.json"));
        let stdout = ok(&relief_line(
            &format!(
                "volume {{}} --cell-size 567 --features sea,caves,cliffs --report {{}}{}",
                if raw { " --raw-dem" } else { "" }
            ),
            &[&s(&input), &report],
        ));
        (stdout, json(&report))
    };
    let (stdout, r) = run(false);
    assert!(
        stdout.contains("refined 64x (wavelet, 6 levels) from 567.0 m to 8.9 m cells"),
        "{stdout}"
    );
    assert_eq!(r["sea_level_m"], 0.0, "{r}");
    let sizes = &r["dimensions"]["sizes"];
    assert!(sizes["sea"]["count"].as_u64().unwrap() > 0, "{r}");
    assert!(sizes["sea"]["max"].as_f64().unwrap() <= 15.0, "{r}");
    if let Some(m) = sizes["caves"]["max"].as_f64() {
        assert!(m <= 15.0, "{r}");
    }
    let (stdout, r) = run(true);
    assert!(
        stdout
            .contains("sea refused: they need DEM cells of at most 15.0 m, this DEM's are 567.0 m"),
        "{stdout}"
    );
    assert!(r["dimensions"]["sizes"]["sea"].is_null(), "{r}");
}
