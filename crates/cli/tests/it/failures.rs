//! Failure behaviour of the `relief` binary (issue 9): every failing run exits non-zero with one
//! `error:` line on stderr (the cause chain under `--verbose`), and no failed, interrupted or
//! killed run leaves a partial output file: outputs are written to a hidden temporary in the
//! target directory and renamed into place (relief-io), so a reader sees either no file or a
//! complete one.
//!
//! Covered: a missing or corrupt input for every subcommand (discovered from `relief help`, so
//! new subcommands are checked too), outputs into a read-only directory (chmod 555, or
//! `chattr +i` when running as root, who ignores permissions), a file-size limit that stops the
//! write half-way (RLIMIT_FSIZE via `ulimit -f`: the process is killed by SIGXFSZ, or gets
//! EFBIG when the signal is ignored), and SIGKILL at many instants of a large `convert`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Instant;

use relief_heightfield::Heightfield;

use crate::common::*;

/// Asserts a clean failure: exit code 1, exactly one non-empty line starting with `error:`.
fn assert_one_line_failure(o: &Output, what: &str) {
    let e = stderr(o);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{what}: status {:?}, stderr {e}",
        o.status
    );
    assert!(e.starts_with("error: "), "{what}: {e}");
    assert_eq!(
        e.trim_end().lines().count(),
        1,
        "{what}: more than one line: {e}"
    );
    assert!(
        e.trim_end().len() > "error: ".len() + 10,
        "{what}: uninformative: {e}"
    );
}

/// A smooth synthetic terrain (no voids) written as a float32 GeoTIFF.
fn synthetic_tif(path: &Path, w: usize, h: usize) -> Heightfield {
    let hf = Heightfield::from_fn(w, h, 10.0, 10.0, |x, y| {
        let (x, y) = (x as f32, y as f32);
        500.0 + 80.0 * (x * 0.05).sin() * (y * 0.037).cos() + 0.3 * x + 0.01 * x * y
    });
    relief_io::write(path, &hf, &relief_io::WriteOptions::default()).unwrap();
    hf
}

/// A new temporary folder holding `name`, a [`synthetic_tif`] of `side x side` cells.
fn synthetic_input(name: &str, side: usize) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    synthetic_tif(&path, side, side);
    (dir, path)
}

/// The subcommands and the argument placeholders of their usage line, from `relief help`.
fn subcommands() -> Vec<(String, Vec<String>)> {
    let help = Command::new(BIN).arg("help").output().unwrap();
    let text = String::from_utf8_lossy(&help.stdout).into_owned();
    let names: Vec<String> = text
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_owned))
        // `tile` has subcommands of its own (plan, run, status, mosaic) whose inputs are a plan
        // folder; the `tile` module covers their failures. `tree build` (a JSON tree and its
        // layers) is covered by `sparse::tree_build_authors_a_river_valley_on_layers`.
        .filter(|n| n != "help" && n != "tile" && n != "tree")
        .collect();
    assert!(names.len() >= 3, "no subcommands parsed from {text}");
    names
        .into_iter()
        .map(|n| {
            let h = Command::new(BIN).args([&n, "--help"]).output().unwrap();
            let h = String::from_utf8_lossy(&h.stdout).into_owned();
            let usage = h
                .lines()
                .find(|l| l.starts_with("Usage:"))
                .unwrap_or_default()
                .to_owned();
            let toks = usage
                .split_whitespace()
                .skip(3)
                .map(str::to_owned)
                .collect();
            (n, toks)
        })
        .collect()
}

/// Arguments for `cmd` from its usage tokens: every input-like value is `input`, outputs go to
/// `out_dir`, numbers get `4`.
fn fill_args(cmd: &str, usage: &[String], input: &Path, out_dir: &Path) -> Vec<String> {
    let mut args = vec![cmd.to_owned()];
    if cmd == "volume" {
        // `volume` refuses to run with no output at all.
        args.push("--render".into());
        args.push(out_dir.join("render.png").display().to_string());
    }
    let mut k = 0;
    let mut it = usage.iter().peekable();
    while let Some(t) = it.next() {
        if t == "[OPTIONS]" || t.starts_with('[') {
            continue;
        }
        if t.starts_with("--") {
            args.push(t.clone());
            let v = it.next().map(String::as_str).unwrap_or_default();
            let v = v.to_ascii_uppercase();
            if v.contains("ENGINE") {
                // `export --engine <ENGINE>`: one of the engines.
                args.push("unreal".into());
            } else if ["FACTOR", "SIZE", "STEPS", "LEVELS", "N"]
                .iter()
                .any(|n| v.contains(n))
            {
                args.push("4".into());
            } else if v.contains("OUT") {
                // A required output flag (`flow -o OUT_DIR`, `erode -o OUT`).
                k += 1;
                let name = if v.contains("DIR") {
                    format!("out{k}")
                } else {
                    format!("out{k}.tif")
                };
                args.push(out_dir.join(name).display().to_string());
            } else {
                args.push(input.display().to_string());
            }
            continue;
        }
        let upper = t.to_ascii_uppercase();
        if upper.contains("OUT") {
            k += 1;
            // Each command checks its output's extension before reading anything.
            let ext = match cmd {
                "preview" => "png",
                "compress" => "sct",
                "learn" => "dict",
                _ => "tif",
            };
            args.push(out_dir.join(format!("out{k}.{ext}")).display().to_string());
        } else {
            args.push(input.display().to_string());
        }
    }
    args
}

#[test]
fn every_subcommand_fails_cleanly_on_missing_and_corrupt_input() {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let missing = tmp.path().join("missing.tif");
    let corrupt = tmp.path().join("corrupt.tif");
    // A TIFF header whose first IFD lies past the end.
    std::fs::write(&corrupt, b"II*\0\xff\xff\xff\x00garbage").unwrap();
    let cmds = subcommands();
    let mut checked = 0;
    for (cmd, usage) in &cmds {
        for (input, expect) in [(&missing, "missing.tif"), (&corrupt, "corrupt.tif")] {
            let args = fill_args(cmd, usage, input, &out_dir);
            let o = relief(&args);
            let e = stderr(&o);
            if !args.iter().any(|a| a.ends_with(expect)) {
                // A subcommand without any input in its usage (e.g. all inputs optional): it
                // must still fail with one line.
                assert_one_line_failure(&o, &format!("{args:?}"));
                continue;
            }
            assert_one_line_failure(&o, &format!("{args:?}"));
            assert!(
                e.contains(expect) || e.contains("exemplar") || e.contains("guide"),
                "{args:?}: the error does not name the input: {e}"
            );
            // --verbose: the same first line, then the cause chain.
            let v = Command::new(BIN)
                .arg("--verbose")
                .args(&args)
                .output()
                .unwrap();
            let ve = stderr(&v);
            assert_eq!(v.status.code(), Some(1), "{args:?} --verbose: {ve}");
            assert!(ve.starts_with("error: "), "{args:?} --verbose: {ve}");
            if e.contains(expect) {
                assert!(
                    ve.contains("caused by:"),
                    "{args:?}: --verbose shows no cause chain: {ve}"
                );
            }
            assert!(
                files(&out_dir).is_empty(),
                "{args:?} left {:?}",
                files(&out_dir)
            );
            checked += 1;
        }
    }
    assert!(checked >= 10, "only {checked} subcommand runs checked");
}

#[test]
fn usage_errors_exit_2_and_start_with_error() {
    for args in [
        vec!["convert"],
        vec!["no-such-command"],
        vec!["info", "x.tif", "--no-such-flag"],
        vec!["convert", "a.tif", "b.tif", "--cell-size", "-3"],
    ] {
        let o = Command::new(BIN).args(&args).output().unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.starts_with("error: "), "{args:?}: {e}");
    }
}

/// A read-only directory; as root (permissions ignored) it is made immutable with `chattr +i`.
/// Restored on drop so the temporary directory can be removed.
struct ReadOnlyDir {
    path: PathBuf,
    immutable: bool,
}

impl ReadOnlyDir {
    fn new(path: PathBuf) -> Option<Self> {
        use std::os::unix::fs::PermissionsExt;
        std::fs::create_dir_all(&path).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o555)).unwrap();
        let mut d = ReadOnlyDir {
            path,
            immutable: false,
        };
        if d.writable() {
            d.immutable = Command::new("chattr")
                .arg("+i")
                .arg(&d.path)
                .stderr(Stdio::null())
                .status()
                .is_ok_and(|s| s.success());
            if !d.immutable || d.writable() {
                return None;
            }
        }
        Some(d)
    }

    fn writable(&self) -> bool {
        let probe = self.path.join("probe");
        let ok = std::fs::write(&probe, b"x").is_ok();
        let _ = std::fs::remove_file(&probe);
        ok
    }
}

impl Drop for ReadOnlyDir {
    fn drop(&mut self) {
        use std::os::unix::fs::PermissionsExt;
        if self.immutable {
            let _ = Command::new("chattr").arg("-i").arg(&self.path).status();
        }
        let _ = std::fs::set_permissions(&self.path, std::fs::Permissions::from_mode(0o755));
    }
}

#[test]
fn read_only_output_directory_fails_without_partial_file() {
    let (tmp, input) = synthetic_input("in.tif", 64);
    let Some(ro) = ReadOnlyDir::new(tmp.path().join("ro")) else {
        // Neither permissions nor chattr can make a directory read-only here.
        return;
    };
    let out = |name: &str| ro.path.join(name).display().to_string();
    let inp = input.display().to_string();
    let runs: Vec<Vec<String>> = vec![
        vec!["convert".into(), inp.clone(), out("o.tif")],
        vec!["convert".into(), inp.clone(), out("o.f32")],
        vec!["convert".into(), inp.clone(), out("o.exr")],
        vec!["preview".into(), inp.clone(), out("o.png")],
        vec![
            "compress".into(),
            inp.clone(),
            out("o.sct"),
            "--atoms".into(),
            "16".into(),
            "--dict".into(),
            "sample".into(),
        ],
        vec!["refine".into(), inp.clone(), out("o.tif")],
    ];
    for args in &runs {
        let o = relief(args);
        assert_one_line_failure(&o, &format!("{args:?}"));
        let e = stderr(&o);
        assert!(
            e.contains("cannot write") || e.contains("ro/o."),
            "{args:?}: {e}"
        );
        assert!(
            files(&ro.path).is_empty(),
            "{args:?} left {:?}",
            files(&ro.path)
        );
    }
    // An existing output in a read-only directory keeps its content.
    drop(ro);
    let dir = tmp.path().join("ro2");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(dir.join("o.tif"), b"previous").unwrap();
    let Some(ro) = ReadOnlyDir::new(dir) else {
        return;
    };
    let o = relief!["convert", inp, ro.path.join("o.tif")];
    assert_one_line_failure(&o, "convert over an existing file in a read-only directory");
    assert_eq!(std::fs::read(ro.path.join("o.tif")).unwrap(), b"previous");
    assert_eq!(files(&ro.path), ["o.tif"]);
}

#[test]
fn output_path_through_a_file_fails_without_output() {
    let (tmp, input) = synthetic_input("in.tif", 32);
    std::fs::write(tmp.path().join("file"), b"").unwrap();
    let out = tmp.path().join("file/o.tif");
    let o = relief!["convert", input, out];
    assert_one_line_failure(&o, "output below a regular file");
    assert_stderr_has(&o, "file/o.tif");
    assert_eq!(files(tmp.path()), ["file", "in.tif"]);
}

/// Runs `relief convert` under `ulimit -f` (512-byte blocks) so the write of the output stops
/// half-way; `ignore_signal` makes the write fail with EFBIG instead of SIGXFSZ killing it.
fn convert_with_file_limit(input: &Path, out: &Path, blocks: u32, ignore_signal: bool) -> Output {
    let trap = if ignore_signal { "trap '' XFSZ; " } else { "" };
    Command::new("sh")
        .arg("-c")
        .arg(format!("{trap}ulimit -f {blocks} && exec \"$0\" \"$@\""))
        .arg(BIN)
        .args([
            "--quiet".as_ref(),
            "convert".as_ref(),
            input.as_os_str(),
            out.as_os_str(),
        ])
        .output()
        .unwrap()
}

#[cfg(target_os = "linux")]
#[test]
fn a_write_stopped_by_the_file_size_limit_leaves_no_partial_output() {
    use std::os::unix::process::ExitStatusExt;
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.tif");
    let hf = synthetic_tif(&input, 512, 512); // 1 MiB of f32 per output
    let out_dir = tmp.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let out = out_dir.join("o.tif");

    // EFBIG: an error, the temporary removed, one line naming the output.
    let o = convert_with_file_limit(&input, &out, 512, true);
    assert_one_line_failure(&o, "EFBIG");
    assert_stderr_has(&o, "o.tif");
    assert!(files(&out_dir).is_empty(), "left {:?}", files(&out_dir));

    // SIGXFSZ kills the process in the middle of the write: no `o.tif`; at most a hidden
    // temporary, which the next write of the same output removes.
    let o = convert_with_file_limit(&input, &out, 512, false);
    assert_eq!(
        o.status.signal(),
        Some(25),
        "not killed by SIGXFSZ: {:?}",
        o.status
    );
    assert!(!out.exists(), "partial output after SIGXFSZ");
    let left = files(&out_dir);
    assert!(
        left.iter().all(|f| f.starts_with(".o.tif.tmp-")),
        "visible leftovers {left:?}"
    );
    relief_ok!["convert", input, out];
    assert_eq!(files(&out_dir), ["o.tif"], "stale temporary not cleaned");
    let back = relief_io::read(&out, &relief_io::ReadOptions::default()).unwrap();
    assert_eq!(back.heightfield.as_slice(), hf.as_slice());
}

#[cfg(target_os = "linux")]
#[test]
fn sigkill_at_any_instant_leaves_no_partial_output() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.tif");
    let hf = synthetic_tif(&input, 2048, 2048); // 16 MiB
    let out_dir = tmp.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    // Time of a complete run, then kills spread over it.
    let t0 = Instant::now();
    let out = out_dir.join("full.exr");
    relief_ok!["convert", input, out];
    let full = t0.elapsed();
    std::fs::remove_file(&out).unwrap();
    let mut killed = 0;
    for i in 0..12u32 {
        let out = out_dir.join(format!("o{i}.exr"));
        let at = full.mul_f64(0.15 + 0.08 * i as f64);
        let mut child = Command::new(BIN)
            .args([
                "--quiet".as_ref(),
                "convert".as_ref(),
                input.as_os_str(),
                out.as_os_str(),
            ])
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(at);
        let finished = child.try_wait().unwrap().is_some();
        let _ = child.kill(); // SIGKILL
        let status = child.wait().unwrap();
        if !finished && !status.success() {
            killed += 1;
        }
        // Either no output or a complete one.
        if out.exists() {
            let back = relief_io::read(&out, &relief_io::ReadOptions::default())
                .unwrap_or_else(|e| panic!("kill at {at:?} left a broken {}: {e}", out.display()));
            assert_eq!(back.heightfield.as_slice(), hf.as_slice());
        }
        for f in files(&out_dir) {
            assert!(
                f.starts_with('.') || f.starts_with('o') && f.ends_with(".exr"),
                "visible leftover {f}"
            );
        }
    }
    assert!(
        killed >= 3,
        "only {killed} runs were killed before finishing"
    );
    // A later write of an output removes the hidden temporaries its killed runs left.
    for i in 0..12u32 {
        let out = out_dir.join(format!("o{i}.exr"));
        relief_ok!["--force", "convert", input, out];
    }
    let left = hidden_files(&out_dir);
    assert!(left.is_empty(), "stale temporaries kept: {left:?}");
}

#[test]
fn max_input_cells_flag_limits_and_raises_the_input_size() {
    let (tmp, input) = synthetic_input("in.tif", 64);
    let out = tmp.path().join("o.exr");
    let o = relief!["convert", input, out, "--max-input-cells", "4095"];
    assert_one_line_failure(&o, "--max-input-cells 4095");
    let e = stderr(&o);
    // The declared size, and no library option name (`ReadOptions::max_cells`).
    assert!(e.contains("64 x 64 = 4096 cells"), "{e}");
    assert!(
        !e.contains("max_cells") && !e.contains("ReadOptions"),
        "{e}"
    );
    assert!(!out.exists());
    relief_ok!["convert", input, out, "--max-input-cells", "4096"];
    assert!(out.exists());
}

/// Bytes of `path`, to check a refused command left it untouched.
fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Issue 14 (data loss): an output that is an input, or whose implied `.json` sidecar is an
/// input, is refused whatever `--force` says, and the input keeps its bytes.
#[test]
fn no_command_overwrites_its_input() {
    let dir = tempfile::tempdir().unwrap();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
    let volcano = dir.path().join("volcano.json");
    std::fs::copy(fixtures.join("volcano.json"), &volcano).unwrap();
    let before = bytes(&volcano);
    let f32_out = dir.path().join("volcano.f32");
    for force in [false, true] {
        let mut args = vec!["convert".to_string()];
        if force {
            args.push("--force".into());
        }
        args.push(volcano.display().to_string());
        args.push(f32_out.display().to_string());
        let o = relief(&args);
        assert_one_line_failure(&o, "convert volcano.json volcano.f32");
        assert_stderr_has(&o, "overwrite the input");
        assert_eq!(bytes(&volcano), before, "volcano.json changed");
        assert!(!f32_out.exists());
    }
    // The same file as input and output, for every command that takes one of each.
    let tif = dir.path().join("dem.tif");
    synthetic_tif(&tif, 64, 64);
    let before = bytes(&tif);
    let t = tif.display().to_string();
    let cases: Vec<Vec<&str>> = vec![
        vec!["convert", &t, &t],
        vec!["refine", &t, &t],
        vec!["amplify", &t, &t, "--exemplar", &t, "--factor", "4"],
        vec!["synthesize", &t, &t, "--exemplar", &t],
        vec!["fit-procedural", &t, &t],
        vec!["quilt", &t, "--exemplar", &t, "--size", "64"],
    ];
    for args in cases {
        let mut a = vec!["--force"];
        a.extend(args.iter().copied());
        let o = relief(&a);
        assert_one_line_failure(&o, &args.join(" "));
        assert!(stderr(&o).contains("input"), "{args:?}: {}", stderr(&o));
        assert_eq!(bytes(&tif), before, "{args:?} changed the input");
    }
}

/// Issue 14: outputs whose extension does not match what a command writes are refused before
/// any work, and an existing file is replaced only under `--force`.
#[test]
fn output_extension_and_existing_files() {
    let (dir, tif) = synthetic_input("dem.tif", 64);
    let mine = dir.path().join("mine.tif");
    synthetic_tif(&mine, 8, 8);
    let mine_before = bytes(&mine);
    let t = tif.display().to_string();
    let m = mine.display().to_string();
    let p_tif = dir.path().join("p.tif").display().to_string();
    let c_tif = dir.path().join("c.tif").display().to_string();
    for (args, needle) in [
        (vec!["learn", &t, &m], ".dict"),
        (vec!["compress", &t, &c_tif], ".sct"),
        (vec!["preview", &t, &p_tif], ".png"),
    ] {
        let o = relief(&args);
        assert_one_line_failure(&o, &args.join(" "));
        assert!(stderr(&o).contains(needle), "{args:?}: {}", stderr(&o));
    }
    assert_eq!(bytes(&mine), mine_before, "learn overwrote a DEM");
    assert!(!dir.path().join("p.tif").exists() && !dir.path().join("c.tif").exists());
    // An existing output needs --force.
    let out = dir.path().join("out.tif");
    std::fs::write(&out, b"keep me").unwrap();
    let o = relief!["convert", &t, &out.display().to_string()];
    assert_one_line_failure(&o, "convert onto an existing file");
    assert_stderr_has(&o, "--force");
    assert_eq!(bytes(&out), b"keep me");
    relief_ok!["--force", "convert", &t, &out.display().to_string()];
    assert_ne!(bytes(&out), b"keep me");
}

/// Issue 18: absurd iteration counts are refused with the parameter named, not a capacity
/// overflow panic, an abort or an endless loop; hostile magnitudes read as voids.
#[test]
fn absurd_counts_and_magnitudes_fail_cleanly() {
    let (dir, tif) = synthetic_input("dem.tif", 48);
    let t = tif.display().to_string();
    for it in ["18446744073709551615", "18446744073709551614", "1000000000"] {
        let dict = dir.path().join("d.dict").display().to_string();
        let o = relief!["learn", &t, &dict, "--iterations", it, "-n", "8"];
        assert_one_line_failure(&o, &format!("learn --iterations {it}"));
        assert_stderr_has(&o, "iterations");
        let sct = dir.path().join("c.sct").display().to_string();
        let o = relief!["compress", &t, &sct, "--iterations", it, "-n", "8"];
        assert_one_line_failure(&o, &format!("compress --iterations {it}"));
        assert_stderr_has(&o, "iterations");
    }
    // A float DEM whose -3.4e38 nodata lost its tag: those cells are voids, and quilt runs.
    let mut hf = Heightfield::from_fn(96, 96, 10.0, 10.0, |x, y| {
        300.0 + 20.0 * ((x as f32) * 0.1).sin() + 15.0 * ((y as f32) * 0.13).cos()
    });
    for i in 0..40 {
        hf.set(i, 3, -3.402_823_5e38);
    }
    let ex = dir.path().join("max.tif");
    save(&ex, &hf);
    let back = relief_io::read(&ex, &relief_io::ReadOptions::default()).unwrap();
    assert_eq!(back.heightfield.void_count(), 40);
    let out = dir.path().join("q.tif").display().to_string();
    let o = relief_line(
        "quilt {} --exemplar {} --size 64 --patch 16 --overlap 4 --no-validate",
        &[&out, &ex.display().to_string()],
    );
    assert!(
        o.status.success() || stderr(&o).starts_with("error: "),
        "{}",
        stderr(&o)
    );
    // An endless device is refused at the cell limit, not read until memory runs out.
    if Path::new("/dev/zero").exists() {
        let o = relief!["info", "/dev/zero", "--max-input-cells", "1024"];
        assert_one_line_failure(&o, "info /dev/zero");
    }
}

/// Runs `relief --quiet ARGS` under an address-space limit of `kib` KiB (`ulimit -v`): a run
/// that started an impossible allocation would abort (SIGABRT) instead of failing cleanly.
fn relief_capped(kib: u64, args: &[String]) -> Output {
    let mut script = format!("ulimit -v {kib} && exec \"$0\" --quiet");
    for i in 1..=args.len() {
        script.push_str(&format!(" \"${i}\""));
    }
    Command::new("sh")
        .arg("-c")
        .arg(script)
        .arg(BIN)
        .args(args)
        .output()
        .expect("run relief under ulimit")
}

fn strs(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// Issue 18: absurd requests are refused by the pre-flight estimate before any work, with a
/// message naming the flag to change, even under a 2 GiB address-space cap (which an
/// attempted run would hit with an abort).
#[test]
fn absurd_requests_are_refused_up_front_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    synthetic_tif(&dir.path().join("c64.tif"), 64, 64);
    synthetic_tif(&dir.path().join("ex.tif"), 256, 256);
    synthetic_tif(&dir.path().join("d128.tif"), 128, 128);
    let cap = 2 << 20; // KiB
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            strs(&[
                "amplify",
                &p("c64.tif"),
                &p("a.tif"),
                "--exemplar",
                &p("ex.tif"),
                "--factor",
                "1024",
            ]),
            "--factor",
        ),
        (
            strs(&[
                "volume",
                &p("d128.tif"),
                "--resolution",
                "16",
                "--mesh",
                &p("m.ply"),
                "--features",
                "sea",
            ]),
            "--resolution",
        ),
        (
            strs(&["refine", &p("d128.tif"), &p("r.png"), "--levels", "8"]),
            "--levels",
        ),
        // A streamed GeoTIFF needs little memory, but 2^12 x 128 cells per side is 1 TiB of
        // output: refused by --max-output-size.
        (
            strs(&["refine", &p("d128.tif"), &p("r.tif"), "--levels", "12"]),
            "--max-output-size",
        ),
        (
            strs(&[
                "--max-memory",
                "64M",
                "quilt",
                &p("q.tif"),
                "--exemplar",
                &p("ex.tif"),
                "--size",
                "4096",
                "--no-validate",
            ]),
            "--max-memory",
        ),
        (
            strs(&[
                "compress",
                &p("d128.tif"),
                &p("c.sct"),
                "--dict",
                "complete",
                "--patch-size",
                "8",
                "--step",
                "0.25",
            ]),
            "--dict",
        ),
    ];
    for (args, flag) in &cases {
        let o = relief_capped(cap, args);
        assert_one_line_failure(&o, &format!("{args:?}"));
        let e = stderr(&o);
        assert!(
            e.contains(flag),
            "{args:?}: the error does not name {flag}: {e}"
        );
        assert!(
            e.contains("--max-memory") || e.contains("--max-output-size"),
            "{args:?}: {e}"
        );
    }
    assert_eq!(
        files(dir.path()),
        ["c64.tif", "d128.tif", "ex.tif"],
        "a refused run left a file"
    );
    // The same refine fits once the output is a window.
    ok(&relief_line(
        "refine {} {} --levels 8 --window 0,0,64,64",
        &[&p("d128.tif"), &p("w.tif")],
    ));
    // --max-memory takes sizes with units; nonsense is a usage error.
    for bad in ["lots", "0", "1k", "-5G"] {
        let o = relief!["--max-memory", bad, "info", &p("d128.tif")];
        assert_eq!(
            o.status.code(),
            Some(2),
            "--max-memory {bad}: {}",
            stderr(&o)
        );
    }
}

/// Issue 18: a compressed raster that would inflate beyond what --max-memory leaves is refused
/// from its header, before decoding (a PNG whose IHDR declares 4096 x 4096 zeros).
#[test]
fn decompression_bombs_are_refused_from_the_header() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("bomb.png");
    relief_io::write_gray_png(&png, 4096, 4096, &vec![0u8; 4096 * 4096]).unwrap();
    assert!(std::fs::metadata(&png).unwrap().len() < 1 << 20);
    let path = png.display().to_string();
    let o = relief!["--max-memory", "64M", "info", &path];
    assert_one_line_failure(&o, "info bomb.png");
    assert_stderr_has(&o, "--max-memory");
    relief_ok!["--max-memory", "1G", "info", &path];
    // A model read from an endless device stops at the model size limit.
    if Path::new("/dev/zero").exists() {
        let out = dir.path().join("z.tif").display().to_string();
        let o = relief_capped(2 << 20, &strs(&["decompress", "/dev/zero", &out]));
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    }
}

/// Issue 18: an NPZ whose member inflates far beyond the file (2 MiB of deflated zeros
/// declaring a 4096 x 4096 `f64` grid, 128 MiB) is refused from the member's declared size
/// under a small --max-memory, naming the flag, and read when the memory allows it.
#[test]
fn npz_bombs_are_refused_before_inflating() {
    use std::io::Write as _;
    let dir = tempfile::tempdir().unwrap();
    let npz = dir.path().join("bomb.npz");
    let (w, h) = (4096usize, 4096usize);
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({h}, {w}), }}");
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut z = zip::ZipWriter::new(std::fs::File::create(&npz).unwrap());
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .large_file(false);
    z.start_file("elevation.npy", opts).unwrap();
    z.write_all(b"\x93NUMPY\x01\x00").unwrap();
    z.write_all(&(header.len() as u16).to_le_bytes()).unwrap();
    z.write_all(header.as_bytes()).unwrap();
    let zeros = vec![0u8; 1 << 20];
    for _ in 0..(w * h * 8) >> 20 {
        z.write_all(&zeros).unwrap();
    }
    z.finish().unwrap();
    let len = std::fs::metadata(&npz).unwrap().len();
    assert!(len < 2 << 20, "the bomb is {len} bytes");
    let path = npz.display().to_string();
    let o = relief!["--max-memory", "64M", "info", &path];
    assert_one_line_failure(&o, "info bomb.npz");
    assert_stderr_has(&o, "--max-memory");
    // The same file converts when the memory allows it; a refused conversion leaves nothing.
    let out = dir.path().join("out.tif");
    let o = relief_line(
        "--max-memory 64M convert {} {}",
        &[&path, &out.display().to_string()],
    );
    assert_one_line_failure(&o, "convert bomb.npz");
    assert!(!out.exists());
    relief_ok!["--max-memory", "2G", "info", &path];
}

/// Issue 18: commands with several outputs check every path before working and write all of
/// them or none; killed runs' temporaries are removed by the next write into the folder;
/// temporary names of long output names stay legal; devices are never replaced.
#[test]
fn multi_output_commands_write_all_or_nothing() {
    let (dir, input) = synthetic_input("in.tif", 48);
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let s = |p: &Path| p.display().to_string();
    let i = s(&input);
    // A render path that is a folder: no mesh either.
    std::fs::create_dir(out.join("r.png")).unwrap();
    let o = relief_line(
        "volume {} --features sea --mesh {} --render {}",
        &[&i, &s(&out.join("m.ply")), &s(&out.join("r.png"))],
    );
    assert_one_line_failure(&o, "volume with a folder as render");
    assert_eq!(files(&out), ["r.png"]);
    std::fs::remove_dir(out.join("r.png")).unwrap();
    // A plot into a missing folder: no local maps either.
    let o = relief_line(
        "analyze {} --local 3 --maps {} --plot {}",
        &[
            &i,
            &s(&out.join("m")),
            &s(&dir.path().join("missing/plot.png")),
        ],
    );
    assert_one_line_failure(&o, "analyze with an unwritable plot");
    assert!(files(&out).is_empty(), "{:?}", files(&out));
    // A seam map in a read-only folder: no terrain either.
    if let Some(ro) = ReadOnlyDir::new(dir.path().join("ro")) {
        let o = relief_line(
            "quilt {} --exemplar {} --size 32 --patch-size 16 --overlap 4 \
             --no-validate --seam-map {}",
            &[&s(&out.join("q.tif")), &i, &s(&ro.path.join("seams.png"))],
        );
        assert_one_line_failure(&o, "quilt with an unwritable seam map");
        assert!(files(&out).is_empty(), "{:?}", files(&out));
        assert!(files(&ro.path).is_empty());
    }
    // Both outputs when everything is writable.
    ok(&relief_line(
        "analyze {} --local 3 --maps {} --plot {}",
        &[&i, &s(&out.join("m")), &s(&out.join("plot.png"))],
    ));
    assert_eq!(files(&out).len(), 8, "{:?}", files(&out));
    // Leftovers of killed runs (a temporary file and a staging folder of a dead process) go
    // with the next write of any output into the folder.
    let dead = 4_194_303; // above Linux's pid_max
    std::fs::write(out.join(format!(".big.tif.tmp-{dead}-0")), b"half").unwrap();
    std::fs::create_dir(out.join(format!(".relief-stage-{dead}-1"))).unwrap();
    std::fs::write(out.join(format!(".relief-stage-{dead}-1/m.glb")), b"half").unwrap();
    relief_ok!["convert", &i, &s(&out.join("other.tif"))];
    assert!(hidden_files(&out).is_empty(), "{:?}", files(&out));
    // A 250-byte output name: its temporary name must stay within the 255-byte limit.
    let long = format!("{}.tif", "n".repeat(246));
    relief_ok!["convert", &i, &s(&out.join(&long))];
    assert!(out.join(&long).exists());
    // A symlink to a device is refused, --force or not, and the device stays a device.
    if Path::new("/dev/null").exists() {
        use std::os::unix::fs::FileTypeExt;
        let link = out.join("null.tif");
        std::os::unix::fs::symlink("/dev/null", &link).unwrap();
        let o = relief!["--force", "convert", &i, &s(&link)];
        assert_one_line_failure(&o, "convert onto /dev/null");
        assert_stderr_has(&o, "not a regular file");
        let m = std::fs::metadata("/dev/null").unwrap();
        assert!(m.file_type().is_char_device());
    }
}

/// Issue 18: `.sct` and `.dict` files carry a checksum (a flipped byte is an error naming it)
/// and `relief info` describes them.
#[test]
fn models_are_checksummed_and_described_by_info() {
    let (dir, input) = synthetic_input("in.tif", 64);
    let s = |p: &Path| p.display().to_string();
    let sct = dir.path().join("m.sct");
    let dict = dir.path().join("d.dict");
    ok(&relief_line(
        "compress {} {} --atoms 16 --dict sample",
        &[&s(&input), &s(&sct)],
    ));
    ok(&relief_line(
        "learn {} {} --atoms 8 --iterations 2",
        &[&s(&input), &s(&dict)],
    ));
    let text = relief_ok!["info", sct];
    for want in [
        "version 4",
        "CRC-32 ok",
        "64 x 64",
        "primitives",
        "atoms:       16",
    ] {
        assert!(text.contains(want), "info .sct lacks {want:?}: {text}");
    }
    let v = relief_json!["info", "--json", dict];
    assert_eq!(v["atoms"], 8);
    assert_eq!(v["patch_size"], 8);
    assert_eq!(v["format"], "dict");
    // One flipped byte in the middle of each: refused, naming the checksum.
    for (file, run) in [
        (
            &sct,
            vec![
                "decompress".to_string(),
                s(&sct),
                s(&dir.path().join("x.tif")),
            ],
        ),
        (
            &dict,
            vec![
                "compress".to_string(),
                s(&input),
                s(&dir.path().join("y.sct")),
                "--dictionary".into(),
                s(&dict),
            ],
        ),
    ] {
        let mut b = std::fs::read(file).unwrap();
        let k = b.len() / 2;
        b[k] ^= 0x10;
        std::fs::write(file, &b).unwrap();
        let o = relief(&run);
        assert_one_line_failure(&o, &format!("{run:?}"));
        assert_stderr_has(&o, "checksum");
    }
    assert!(!dir.path().join("x.tif").exists() && !dir.path().join("y.sct").exists());
}

/// Issue 18: header values that make no sense are refused with the field named; negative
/// `--height-range` values parse.
#[test]
fn absurd_header_values_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let check = |path: &Path, field: &str| {
        let o = relief!["info", path];
        assert_one_line_failure(&o, s(path));
        assert_stderr_has(&o, field);
    };
    // (file written, its text, file read, the field named): two ESRI grids and the sidecar
    // of an `.f32` raster.
    std::fs::write(dir.path().join("s.f32"), [0u8; 16]).unwrap();
    let grid = |corner: &str, cell: &str| {
        format!("ncols 2\nnrows 2\nxllcorner {corner}\nyllcorner 0\ncellsize {cell}\n1 2\n3 4\n")
    };
    let sidecar = r#"{"width": 2, "height": 2, "cell_size_m": "30 m"}"#.to_string();
    for (written, text, read, field) in [
        ("inf.asc", grid("inf", "30"), "inf.asc", "xllcorner"),
        ("neg.asc", grid("0", "-30"), "neg.asc", "cellsize"),
        ("s.json", sidecar, "s.f32", "cell_size_m"),
    ] {
        std::fs::write(dir.path().join(written), text).unwrap();
        check(&dir.path().join(read), field);
    }
    // GeoTIFF with a NaN pixel scale.
    let hf = Heightfield::from_fn(4, 4, 30.0, 30.0, |x, y| (x + y) as f32).with_georef(Some(
        relief_heightfield::GeoRef {
            pixel_scale: Some(vec![f64::NAN, 30.0, 0.0]),
            tiepoints: Some(vec![0.0, 0.0, 0.0, 500_000.0, 4_000_000.0, 0.0]),
            ..Default::default()
        },
    ));
    let tif = dir.path().join("nan.tif");
    save(&tif, &hf);
    check(&tif, "ModelPixelScale");
    // An SRTM tile named beyond the pole.
    let hgt = dir.path().join("N95E011.hgt");
    std::fs::write(&hgt, vec![0u8; 1201 * 1201 * 2]).unwrap();
    check(&hgt, "latitude");
    // Absurd --cell-size values are usage errors.
    let tif = dir.path().join("ok.tif");
    synthetic_tif(&tif, 8, 8);
    for bad in ["1e-320", "1e308", "nan", "inf"] {
        let o = relief!["info", tif, "--cell-size", bad];
        assert_eq!(
            o.status.code(),
            Some(2),
            "--cell-size {bad}: {}",
            stderr(&o)
        );
    }
    // Negative heights parse in --height-range.
    let png = dir.path().join("h.png");
    relief_ok!["convert", tif, png, "--height-range", "-200,500"];
    let png = dir.path().join("h2.png");
    relief_ok!["--height-range", "-200,500", "convert", tif, png];
}
