//! `relief tile`: a plan run as shuffled tasks two at a time, with a killed task and a corrupted
//! tile, mosaics bit for bit into the single-machine output (values and georeference); the
//! VRT and COG read in GDAL as the same raster.

#![allow(clippy::print_stderr)] // skip notices for missing tools

use std::path::Path;
use std::process::{Child, Command};

use crate::common::*;

fn tasks(dir: &Path) -> usize {
    let m: serde_json::Value = json(&dir.join("manifest.json"));
    m["tasks"].as_u64().unwrap() as usize
}

fn spawn_task(dir: &Path, i: usize) -> Child {
    command()
        .args(["tile", "run", s(dir), "--index", &i.to_string()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn task")
}

/// Runs every task of the plan in a shuffled order, two processes at a time.
fn run_all_two_at_a_time(dir: &Path, n: usize, seed: u64) {
    let mut order: Vec<usize> = (0..n).collect();
    shuffle(&mut order, seed);
    two_at_a_time(&order, "task", |i| spawn_task(dir, i));
}

/// The whole cycle for one command: single run, plan, a killed task, shuffled tasks two at a
/// time, a corrupted tile found and redone, mosaic equal to the single run. `line` is the
/// command without its output, `{}` standing for the fixture DEM.
fn cycle(line: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let tmp = tmp.path();
    let gc = relief_testdata::fixture("grandcanyon.tif");
    let command: Vec<&str> = (line.split(' '))
        .map(|w| if w == "{}" { s(&gc) } else { w })
        .collect();
    let name = command[0];
    let single = tmp.join(format!("{name}-single.tif"));
    let planned = tmp.join(format!("{name}-tiled.tif"));
    let dir = tmp.join(format!("{name}-plan"));
    let mut args: Vec<&str> = command.to_vec();
    args.insert(2, s(&single));
    ok(&relief(&args));
    let mut plan: Vec<&str> = vec!["tile", "plan", s(&dir), "--tile", "512", "--"];
    plan.extend_from_slice(&command);
    plan.insert(8, s(&planned));
    ok(&relief(&plan));
    let n = tasks(&dir);
    assert!(n >= 4, "{n} tasks");
    // Mosaic and status refuse an incomplete plan.
    let st = relief!["tile", "status", &dir];
    assert!(!st.status.success());
    assert!(String::from_utf8_lossy(&st.stdout).contains(&format!("0/{n} tiles done")));
    let mo = relief!["tile", "mosaic", &dir];
    assert!(!mo.status.success());
    assert!(!planned.exists());
    // A task killed at some point of its run leaves no tile that counts as done.
    kill_after(spawn_task(&dir, 1), 60);
    run_all_two_at_a_time(&dir, n, 7);
    relief_ok!["tile", "status", &dir];
    // A re-run of a done task is a no-op.
    let again = relief!["tile", "run", &dir, "--index", "0"];
    ok(&again);
    // A damaged tile is reported, refused by the mosaic, and redone by its task.
    let t2 = dir.join("tiles/tile-000002.tif");
    damage(&t2);
    let st = relief!["tile", "status", &dir];
    assert!(!st.status.success());
    assert!(
        String::from_utf8_lossy(&st.stdout).contains("corrupt: 2"),
        "{}",
        String::from_utf8_lossy(&st.stdout)
    );
    assert!(!relief!["tile", "mosaic", &dir].status.success());
    relief_ok!["tile", "run", &dir, "--index", "2"];
    relief_ok!["tile", "mosaic", &dir];
    assert_same_raster(&single, &planned);
    // The COG holds the same full-resolution values.
    relief_ok!["--force", "tile", "mosaic", &dir, "--cog"];
    assert_same_raster(&single, &planned);
    // Out-of-range and absent indices are errors naming the problem.
    let bad = relief!["tile", "run", &dir, "--index", &n.to_string()];
    assert!(String::from_utf8_lossy(&bad.stderr).contains("out of range"));
    let none = relief!["tile", "run", &dir];
    assert!(String::from_utf8_lossy(&none.stderr).contains("SLURM_ARRAY_TASK_ID"));
    let env = crate::common::command()
        .args(["tile", "run", s(&dir)])
        .env("JOB_COMPLETION_INDEX", "3")
        .output()
        .unwrap();
    ok(&env);
}

#[test]
fn amplify_plan_mosaics_into_the_single_run() {
    // Tiles never run the landform pass (it routes water over the whole raster).
    cycle("amplify {} --exemplar {} --factor 4 --landform off");
}

/// x16: the plan runs the first x4 step and keeps the last step's input and dictionary; the
/// tasks code the last step window by window, and the mosaic is still the single run.
#[test]
fn amplify_x16_plan_codes_the_last_step_in_the_tasks() {
    let tmp = tempfile::tempdir().unwrap();
    let gc = relief_testdata::fixture("grandcanyon.tif");
    let full = relief_io::read(&gc, &relief_io::ReadOptions::default())
        .unwrap()
        .heightfield;
    let crop = full.crop(200, 150, 72, 56).unwrap();
    let input = tmp.path().join("crop.tif");
    save(&input, &crop);
    let single = tmp.path().join("single.tif");
    let planned = tmp.path().join("tiled.tif");
    let dir = tmp.path().join("plan");
    let cmd = |out: &Path| {
        vec![
            "amplify".to_string(),
            s(&input).to_string(),
            s(out).to_string(),
            "--exemplar".to_string(),
            s(&gc).to_string(),
            "--factor".to_string(),
            "16".to_string(),
            "--seed".to_string(),
            "3".to_string(),
            "--landform".to_string(),
            "off".to_string(),
        ]
    };
    let single_args = cmd(&single);
    let refs: Vec<&str> = single_args.iter().map(String::as_str).collect();
    ok(&relief(&refs));
    let plan_cmd = cmd(&planned);
    let mut plan: Vec<&str> = vec!["tile", "plan", s(&dir), "--tile", "288", "--"];
    plan.extend(plan_cmd.iter().map(String::as_str));
    ok(&relief(&plan));
    assert!(dir.join("last-step.bin").exists());
    assert!(!dir.join("model.sct").exists());
    let n = tasks(&dir);
    assert_eq!(n, 4 * 4, "1152 x 896 in tiles of 288");
    run_all_two_at_a_time(&dir, n, 11);
    relief_ok!["tile", "mosaic", &dir];
    assert_same_raster(&single, &planned);
}

#[test]
fn refine_plan_mosaics_into_the_single_run() {
    cycle("refine {} --levels 2 --seed 5 --landform off");
}

#[test]
fn a_changed_input_or_prepared_file_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.tif");
    std::fs::copy(relief_testdata::fixture("grandcanyon.tif"), &input).unwrap();
    let dir = tmp.path().join("plan");
    let out = tmp.path().join("out.tif");
    relief_ok![
        "tile", "plan", &dir, "--tile", "256", "--", "refine", &input, &out
    ];
    // A second plan into the same folder is refused.
    let again = relief!["tile", "plan", &dir, "--", "refine", &input, &out];
    assert!(String::from_utf8_lossy(&again.stderr).contains("not empty"));
    let mut bytes = std::fs::read(&input).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&input, &bytes).unwrap();
    let r = relief!["tile", "run", &dir, "--index", "0"];
    assert!(!r.status.success());
    assert!(
        String::from_utf8_lossy(&r.stderr).contains("changed since the plan"),
        "{}",
        String::from_utf8_lossy(&r.stderr)
    );
    // With the input gone (a task on a node that does not see it), the prepared copy is used;
    // a damaged prepared copy is refused.
    std::fs::remove_file(&input).unwrap();
    relief_ok!["tile", "run", &dir, "--index", "0"];
    let prepared = dir.join("input.tif");
    let mut p = std::fs::read(&prepared).unwrap();
    p[100] ^= 1;
    std::fs::write(&prepared, &p).unwrap();
    let r = relief!["tile", "run", &dir, "--index", "1"];
    assert!(String::from_utf8_lossy(&r.stderr).contains("checksum"));
    // A hand-edited manifest is refused.
    let m = dir.join("manifest.json");
    let text = std::fs::read_to_string(&m)
        .unwrap()
        .replace("\"tile\": 256", "\"tile\": 128");
    std::fs::write(&m, text).unwrap();
    let r = relief!["tile", "status", &dir];
    assert!(String::from_utf8_lossy(&r.stderr).contains("modified after planning"));
}

#[test]
fn plans_refuse_what_they_cannot_tile() {
    let tmp = tempfile::tempdir().unwrap();
    let gc = relief_testdata::fixture("grandcanyon.tif");
    let d = tmp.path().join("p");
    let png = tmp.path().join("o.png");
    let tif = tmp.path().join("o.tif");
    for (args, want) in [
        (vec!["refine", s(&gc), s(&png)], "GeoTIFF"),
        (
            vec!["refine", s(&gc), s(&tif), "--window", "0,0,8,8"],
            "--window",
        ),
        (
            vec!["preview", s(&gc), s(&png)],
            "cannot be planned as tiles",
        ),
    ] {
        let mut a = vec!["tile", "plan", s(&d), "--"];
        a.extend(args);
        let r = relief(&a);
        let e = failed(&r);
        assert!(e.contains(want), "{e}");
    }
    let r = relief![
        "tile", "plan", &d, "--tile", "100", "--", "refine", &gc, &tif
    ];
    assert!(String::from_utf8_lossy(&r.stderr).contains("--tile"));
    assert!(!d.join("manifest.json").exists());
}

/// GDAL reads the VRT over the tiles and the COG as the same raster (same checksum), and sees
/// the COG's overviews and layout.
#[test]
fn gdal_reads_the_vrt_and_the_cog() {
    if Command::new("gdalinfo").arg("--version").output().is_err() {
        assert!(
            std::env::var_os("CI").is_none(),
            "gdalinfo is missing under CI (.ci/run installs gdal-bin)"
        );
        eprintln!("skipping: gdalinfo not found (apt-get install gdal-bin)");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let gc = relief_testdata::fixture("grandcanyon.tif");
    let dir = tmp.path().join("plan");
    let out = tmp.path().join("out.tif");
    relief_ok![
        "tile", "plan", &dir, "--tile", "256", "--", "refine", &gc, &out
    ];
    for i in 0..tasks(&dir) {
        relief_ok!["tile", "run", &dir, "--index", &i.to_string()];
    }
    relief_ok!["tile", "mosaic", &dir, "--cog"];
    let info = |p: &Path| {
        let o = Command::new("gdalinfo")
            .args(["-checksum", s(p)])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let (a, b) = (info(&dir.join("mosaic.vrt")), info(&out));
    let checksum = |t: &str| {
        t.lines()
            .find(|l| l.trim_start().starts_with("Checksum="))
            .map(str::to_owned)
            .unwrap_or_default()
    };
    assert!(!checksum(&a).is_empty(), "{a}");
    assert_eq!(checksum(&a), checksum(&b));
    let line = |t: &str, key: &str| {
        t.lines()
            .find(|l| l.starts_with(key))
            .map(str::to_owned)
            .unwrap_or_default()
    };
    for key in ["Size is", "Origin =", "Pixel Size ="] {
        assert_eq!(line(&a, key), line(&b, key), "{key}");
    }
    assert!(b.contains("LAYOUT=COG"), "{b}");
    assert!(b.contains("Overviews:"), "{b}");
    assert!(b.contains("COMPRESSION=DEFLATE"), "{b}");
    // A BigTIFF COG reads the same in GDAL.
    relief_ok!["--force", "tile", "mosaic", &dir, "--cog", "--bigtiff"];
    assert_eq!(std::fs::read(&out).unwrap()[2], 43, "BigTIFF magic");
    let big = info(&out);
    assert_eq!(checksum(&a), checksum(&big));
    assert!(big.contains("LAYOUT=COG"), "{big}");
    // GDAL's own COG validator (Debian's python3-gdal, a dependency of gdal-bin).
    let validator =
        Path::new("/usr/share/doc/python3-gdal/examples/validate_cloud_optimized_geotiff.py");
    match Command::new("/usr/bin/python3")
        .args([validator.to_str().unwrap(), "--full-check=yes", s(&out)])
        .output()
    {
        Ok(o) if validator.exists() => {
            let text = String::from_utf8_lossy(&o.stdout);
            assert!(
                o.status.success() && text.contains("is a valid cloud optimized GeoTIFF"),
                "{text}{}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        _ => eprintln!(
            "skipping the COG validator: {} not found",
            validator.display()
        ),
    }
}

/// Missing or corrupt plan folders fail with one line naming the problem, exit code 1.
#[test]
fn tile_commands_fail_cleanly_on_missing_and_corrupt_plans() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("nowhere");
    let corrupt = tmp.path().join("corrupt");
    std::fs::create_dir(&corrupt).unwrap();
    std::fs::write(corrupt.join("manifest.json"), b"{\"format\": 3").unwrap();
    for (dir, want) in [
        (&missing, "is this a plan folder"),
        (&corrupt, "not a tile plan"),
    ] {
        for sub in [
            vec!["tile", "run", s(dir), "--index", "0"],
            vec!["tile", "status", s(dir)],
            vec!["tile", "mosaic", s(dir)],
        ] {
            let o = relief(&sub);
            let e = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{sub:?}: {e}");
            assert!(e.starts_with("error: ") && e.contains(want), "{sub:?}: {e}");
            assert_eq!(e.trim_end().lines().count(), 1, "{sub:?}: {e}");
        }
    }
}

/// Under `--max-time` a task renders its tile in bands of rows, asking the deadline between
/// them: the tile is the same bytes as rendered at once (refine and amplify plans, tiles of
/// 1024 rows).
#[test]
fn a_tile_rendered_in_bands_is_the_same_tile() {
    let tmp = tempfile::tempdir().unwrap();
    let gc = relief_testdata::fixture("grandcanyon.tif");
    let out = tmp.path().join("o.tif");
    for (k, line) in [
        "refine {} {} --landform off",
        "amplify {} {} --exemplar {} --factor 4 --landform off",
    ]
    .iter()
    .enumerate()
    {
        let dir = tmp.path().join(format!("plan-{k}"));
        let files: Vec<&dyn AsRef<std::ffi::OsStr>> = if k == 0 {
            vec![&gc, &out]
        } else {
            vec![&gc, &out, &gc]
        };
        let mut args = words("tile plan {} --tile 1024 --", &[&dir]);
        args.extend(words(line, &files));
        ok(&relief(&args));
        relief_ok!["--max-time", "1h", "tile", "run", &dir, "--index", "0"];
        let tile = dir.join("tiles/tile-000000.tif");
        let banded = std::fs::read(&tile).unwrap();
        std::fs::remove_file(&tile).unwrap();
        std::fs::remove_file(dir.join("tiles/tile-000000.json")).unwrap();
        relief_ok!["tile", "run", &dir, "--index", "0"];
        assert!(
            banded == std::fs::read(&tile).unwrap(),
            "{line}: the banded tile differs"
        );
    }
}
