//! Issue 44 item 5: `--max-time` stops every long-running path during the work (not only by
//! a pilot's estimate before it), with a clear error and no output; `relief run` applies
//! `--max-memory` and `--max-time` to its stages.

use std::path::Path;
use std::process::Output;
use std::time::Instant;

use relief_heightfield::Heightfield;

use crate::common::*;

/// A clean one-line failure naming `--max-time` as the reason the run was stopped, leaving
/// none of `outputs`, within `limit_s` seconds of wall time (the limit is 1 s; the work
/// would take minutes).
fn stopped(out: &Output, seconds: f64, outputs: &[&Path]) {
    let e = fails_with(out, &["stopped", "--max-time 1.0 s"], outputs);
    assert!(seconds < 60.0, "stopped only after {seconds:.1} s: {e}");
}

fn timed(args: &[&std::ffi::OsStr]) -> (Output, f64) {
    let t = Instant::now();
    let o = relief(args);
    (o, t.elapsed().as_secs_f64())
}

/// `relief --max-time 1s LINE` (see [`words`]) is [`stopped`], leaving none of `outputs`.
fn stops_in_one_second(line: &str, files: &[&dyn AsRef<std::ffi::OsStr>], outputs: &[&Path]) {
    let line = format!("--max-time 1s {line}");
    let (o, s) = timed(&words(&line, files));
    stopped(&o, s, outputs);
}

/// A tree blending 2^20 constants on a small raster: no pilot (under 2^20 cells), seconds per
/// band; decompress stops between the children.
#[test]
fn decompress_of_a_wide_tree_stops_at_the_time_limit() {
    use relief_sparse_core::{Node, Sct};
    let tmp = tempfile::tempdir().unwrap();
    let children = (0..1 << 20).map(|i| Node::Constant(i as f64)).collect();
    let sct = Sct::new(Node::Blend(children), 256, 256, (10.0, 10.0)).unwrap();
    let model = tmp.path().join("wide.sct");
    std::fs::write(&model, sct.to_bytes().unwrap()).unwrap();
    let out = tmp.path().join("wide.tif");
    stops_in_one_second("decompress {} {}", &[&model, &out], &[&out]);
}

/// `refine --levels 8 --stream` of a 64^2 input: 256 strips of a 16384^2 GeoTIFF.
#[test]
fn a_streamed_refinement_stops_at_the_time_limit() {
    let (tmp, input, _) = tmp_with_crop("gc64.tif", (224, 224, 64, 64));
    let out = tmp.path().join("r.tif");
    stops_in_one_second("refine {} {} --levels 8 --stream", &[&input, &out], &[&out]);
}

/// Meshing a flat 64^2 DEM of 1 m cells: a fine voxel grid, no pilot for the mesh.
#[test]
fn meshing_stops_at_the_time_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let flat = Heightfield::from_fn(64, 64, 1.0, 1.0, |x, y| 100.0 + 0.01 * (x + y) as f32);
    let input = write(tmp.path(), "flat.tif", &flat);
    let mesh = tmp.path().join("flat.glb");
    stops_in_one_second(
        "volume {} --mesh {} --resolution 8",
        &[&input, &mesh],
        &[&mesh],
    );
}

/// Every long-running command, on inputs that take it several seconds, ends under
/// `--max-time 1s` with one line naming the limit (a pilot's refusal before the work, or a
/// stop during it) and writes nothing; two commands run at a time.
#[test]
fn every_long_command_stops_at_the_time_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let gc = relief_testdata::fixture("grandcanyon.tif");
    let big = write(t, "big.tif", &fixture().resample(2048, 2048).unwrap());
    let (small, _) = fixture_crop(t, "small.tif", (0, 0, 128, 128));
    let (mid, _) = fixture_crop(t, "mid.tif", (0, 0, 256, 256));
    let plan = t.join("plan");
    relief_ok![
        "tile",
        "plan",
        &plan,
        "--tile",
        "4096",
        "--",
        "amplify",
        &mid,
        t.join("a.tif"),
        "--exemplar",
        &gc,
        "--factor",
        "16",
        "--landform",
        "off"
    ];
    let o = |name: &str| t.join(name);
    let cases: Vec<(Vec<std::ffi::OsString>, Vec<std::path::PathBuf>)> = vec![
        (argv("flow {} -o {}", &[&big, &o("flow")]), vec![o("flow")]),
        (
            argv("masks {} --out {}", &[&big, &o("masks")]),
            vec![o("masks")],
        ),
        (
            argv("erode {} --output {}", &[&big, &o("e.tif")]),
            vec![o("e.tif")],
        ),
        (
            argv(
                "amplify {} {} --exemplar {} --factor 16",
                &[&small, &o("a16.tif"), &gc],
            ),
            vec![o("a16.tif")],
        ),
        (
            argv(
                "synthesize {} {} --exemplar {}",
                &[&small, &o("s.tif"), &gc],
            ),
            vec![o("s.tif")],
        ),
        (
            argv(
                "quilt {} --exemplar {} --guide {} --guide-range auto",
                &[&o("q.tif"), &gc, &gc],
            ),
            vec![o("q.tif")],
        ),
        (
            argv("compress {} {}", &[&big, &o("c.sct")]),
            vec![o("c.sct")],
        ),
        (
            argv("learn {} {}", &[&big, &o("l.dict")]),
            vec![o("l.dict")],
        ),
        (
            argv("fit-procedural {} {}", &[&big, &o("p.sct")]),
            vec![o("p.sct")],
        ),
        (
            argv("tile run {} --index 0", &[&plan]),
            vec![plan.join("tiles/tile-000000.tif")],
        ),
    ];
    let failures: Vec<String> = std::thread::scope(|sc| {
        cases
            .chunks(2)
            .flat_map(|pair| {
                let hs: Vec<_> = pair
                    .iter()
                    .map(|(args, outs)| {
                        sc.spawn(move || {
                            let mut a: Vec<&std::ffi::OsStr> = vec![os("--max-time"), os("1s")];
                            a.extend(args.iter().map(|x| x.as_os_str()));
                            let (out, secs) = timed(&a);
                            let e = stderr(&out);
                            let fine = !out.status.success()
                                && e.trim_end().lines().count() == 1
                                && e.contains("--max-time")
                                && secs < 30.0
                                && outs.iter().all(|p| !p.exists());
                            (!fine).then(|| format!("{args:?}: {secs:.1} s: {e}"))
                        })
                    })
                    .collect();
                hs.into_iter()
                    .filter_map(|h| h.join().unwrap())
                    .collect::<Vec<_>>()
            })
            .collect()
    });
    assert!(failures.is_empty(), "{failures:#?}");
}

/// `line` with each `{}` replaced by the next of `files`, as owned arguments.
fn argv(line: &str, files: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<std::ffi::OsString> {
    words(line, files)
        .into_iter()
        .map(|w| w.to_os_string())
        .collect()
}

/// `relief run`: a wavelet stage of 8 extra levels is refused by its pre-flight under
/// `--max-memory` (it aborted on a 4 GiB allocation), and a run past `--max-time` is stopped;
/// neither leaves an output folder.
#[test]
fn run_applies_the_memory_and_time_limits() {
    let tmp = tempfile::tempdir().unwrap();
    let input = write(
        tmp.path(),
        "canyon.tif",
        &fixture().crop(100, 100, 128, 128).unwrap(),
    );
    let spec = tmp.path().join("spec.json");
    std::fs::write(
        &spec,
        r#"{ "input": "canyon.tif",
             "stages": [ { "stage": "load" },
                         { "stage": "wavelet", "params": { "job": { "extra_levels": 8 },
                           "quality": false, "replace_terrain": true } } ] }"#,
    )
    .unwrap();
    let out = tmp.path().join("out");
    fails_with(
        &relief!["--max-memory", "1G", "run", spec, "--out", out],
        &["extra_levels", "--max-memory"],
        &[],
    );
    assert!(!out.exists());
    std::fs::write(
        &spec,
        r#"{ "input": "canyon.tif",
             "stages": [ { "stage": "load" },
                         { "stage": "wavelet", "params": { "job": { "extra_levels": 4 },
                           "quality": false, "replace_terrain": true } },
                         { "stage": "wavelet", "params": { "job": { "extra_levels": 2 },
                           "quality": false, "replace_terrain": true, "max_cells": 268435456 } } ] }"#,
    )
    .unwrap();
    let (o, s) = timed(&[
        os("--max-time"),
        os("1s"),
        os("run"),
        os(&spec),
        os("--out"),
        os(&out),
    ]);
    stopped(&o, s, &[]);
    assert!(!out.exists());
    let _ = input;
}

/// Every stage of `relief run` checks its working memory against `--max-memory` before its
/// work, naming the stage and the spec parameters that make it smaller.
#[test]
fn every_run_stage_applies_the_memory_limit() {
    let tmp = tempfile::tempdir().unwrap();
    // 900^2 cells: read within the smallest --max-memory (16M), too large for every stage's
    // working memory under it.
    write(
        tmp.path(),
        "canyon.tif",
        &fixture().resample(900, 900).unwrap(),
    );
    let spec = tmp.path().join("spec.json");
    let out = tmp.path().join("out");
    for (stage, params, limit, names) in [
        ("fill_voids", "{}", "16M", "`crop`"),
        ("flow", "{}", "16M", "`crop`"),
        ("erode", r#"{ "max_size": 0 }"#, "16M", "`max_size`"),
        ("sparse", "{}", "16M", "`job.step`"),
        ("quilt", "{}", "16M", "exemplar_stride"),
        ("procedural", r#"{ "max_side": 900 }"#, "16M", "`max_side`"),
        (
            "volume",
            r#"{ "job": { "recipe": { "voxel": 1.0 } }, "max_size": 0, "raw_dem": true }"#,
            "1G",
            "`job.recipe.voxel`",
        ),
    ] {
        std::fs::write(
            &spec,
            format!(
                r#"{{ "input": "canyon.tif", "stages": [ {{ "stage": "load" }},
                   {{ "stage": "{stage}", "params": {params} }} ] }}"#
            ),
        )
        .unwrap();
        fails_with(
            &relief!["--max-memory", limit, "run", spec, "--out", out],
            &[
                &format!("stage `{stage}"),
                "needs about",
                names,
                "--max-memory",
            ],
            &[],
        );
        assert!(!out.exists());
    }
}

/// Issue 44 item 8: `relief --force run` over an earlier run's folder is all or nothing: a
/// failing run leaves the earlier folder exactly as it was, a successful one leaves only its
/// own files (the earlier run's other files were kept beside the new ones).
#[test]
fn a_forced_run_replaces_an_earlier_run_all_or_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    write(
        tmp.path(),
        "canyon.tif",
        &fixture().crop(100, 100, 64, 64).unwrap(),
    );
    let spec = tmp.path().join("spec.json");
    let good = r#"{ "input": "canyon.tif", "stages": [ { "stage": "load" } ] }"#;
    std::fs::write(&spec, good).unwrap();
    let out = tmp.path().join("out");
    relief_ok!["run", spec, "--out", out];
    std::fs::write(out.join("earlier-only.txt"), b"from an earlier run").unwrap();
    let snapshot = |dir: &Path| -> Vec<(String, Vec<u8>)> {
        files(dir)
            .into_iter()
            .map(|f| {
                let bytes = std::fs::read(dir.join(&f)).unwrap();
                (f, bytes)
            })
            .collect()
    };
    let before = snapshot(&out);
    // Fails after its first stage wrote files (the wavelet pre-flight under --max-memory).
    std::fs::write(
        &spec,
        r#"{ "input": "canyon.tif",
             "stages": [ { "stage": "load" },
                         { "stage": "wavelet", "params": { "job": { "extra_levels": 8 },
                           "quality": false } } ] }"#,
    )
    .unwrap();
    failed(&relief![
        "--force",
        "--max-memory",
        "64M",
        "run",
        spec,
        "--out",
        out
    ]);
    assert_eq!(
        snapshot(&out),
        before,
        "a failed run changed the earlier one"
    );
    std::fs::write(&spec, good).unwrap();
    relief_ok!["--force", "run", spec, "--out", out];
    let after = files(&out);
    assert!(
        !after.contains(&"earlier-only.txt".to_string()),
        "{after:?}"
    );
    assert!(after.contains(&"summary.json".to_string()), "{after:?}");
    // Nothing hidden is left beside it.
    let hidden = hidden_files(tmp.path());
    assert!(hidden.is_empty(), "{hidden:?}");
}

/// A path whose loops do not ask whether to stop (K-SVD learning) is ended by the backstop a
/// few seconds after the `--max-time` deadline, with the same clear error and no output.
#[test]
fn the_backstop_ends_a_path_that_does_not_stop_by_itself() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("c.sct");
    stops_in_one_second(
        "compress {} {} -n 1024 --iterations 50 --sparsity 8 --patch-size 16",
        &[&relief_testdata::fixture("grandcanyon.tif"), &out],
        &[&out],
    );
    assert!(files(tmp.path()).is_empty(), "{:?}", files(tmp.path()));
}

/// SIGINT (and SIGTERM) in the middle of a streamed write: the run ends with `128 + signal`,
/// one clear line, and its temporary file is removed (it was left behind).
#[test]
fn an_interrupted_run_removes_its_temporaries() {
    let (tmp, input, _) = tmp_with_crop("gc64.tif", (224, 224, 64, 64));
    let out = tmp.path().join("r.tif");
    for (signal, code) in [("-INT", 130), ("-TERM", 143)] {
        let child = command()
            .args(words("refine {} {} --levels 8 --stream", &[&input, &out]))
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Wait until the streamed output's temporary exists (the write is under way).
        let t = Instant::now();
        while !files(tmp.path()).iter().any(|f| f.contains(".tmp-")) {
            assert!(t.elapsed().as_secs() < 60, "no temporary appeared");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let pid = child.id().to_string();
        assert!(
            std::process::Command::new("kill")
                .args([signal, &pid])
                .status()
                .unwrap()
                .success()
        );
        let o = child.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(code), "{}", stderr(&o));
        assert!(stderr(&o).contains("interrupted by SIG"), "{}", stderr(&o));
        assert_eq!(files(tmp.path()), ["gc64.tif"], "left behind");
    }
}
