//! Helpers shared by the test modules: run the binary (`relief![...]`), check how a run ended,
//! read and write rasters, fixtures and temporary files.

#![allow(dead_code)] // not every module uses every helper

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};

use relief_heightfield::Heightfield;

/// The `relief` binary under test.
pub(crate) const BIN: &str = env!("CARGO_BIN_EXE_relief");

/// `relief --quiet`, with the scheduler variables of an enclosing job removed (they must not
/// leak into `relief tile run`).
pub(crate) fn command() -> Command {
    let mut c = Command::new(BIN);
    c.arg("--quiet");
    for v in [
        "SLURM_ARRAY_TASK_ID",
        "JOB_COMPLETION_INDEX",
        "AWS_BATCH_JOB_ARRAY_INDEX",
    ] {
        c.env_remove(v);
    }
    c
}

/// Runs `relief --quiet ARGS`.
pub(crate) fn relief<S: AsRef<OsStr>>(args: &[S]) -> Output {
    command().args(args).output().expect("run relief")
}

/// [`relief`] on the concatenation of `parts` (shared options plus per-run ones).
pub(crate) fn relief_parts(parts: &[&[&str]]) -> Output {
    relief(&parts.concat())
}

/// `line` split at whitespace, each `{}` replaced by the next of `files`.
pub(crate) fn words<'a>(line: &'a str, files: &[&'a dyn AsRef<OsStr>]) -> Vec<&'a OsStr> {
    let mut files = files.iter().copied();
    let args = (line.split_whitespace())
        .map(|w| match w {
            "{}" => files.next().expect("a file for every {}").as_ref(),
            w => OsStr::new(w),
        })
        .collect();
    assert!(files.next().is_none(), "more files than {{}} in `{line}`");
    args
}

/// [`relief`] on [`words`]: `relief_line("refine {} {} --levels 2", &[&input, &out])`.
pub(crate) fn relief_line(line: &str, files: &[&dyn AsRef<OsStr>]) -> Output {
    relief(&words(line, files))
}

/// [`relief_line`] of a command that must succeed and writes a raster as its second file
/// (`files[1]`), read back.
pub(crate) fn ok_read(line: &str, files: &[&dyn AsRef<OsStr>]) -> Heightfield {
    ok(&relief_line(line, files));
    read(Path::new(files[1]))
}

/// [`relief_line`] plus `extra` words.
pub(crate) fn relief_line_plus(line: &str, files: &[&dyn AsRef<OsStr>], extra: &[&str]) -> Output {
    let mut args = words(line, files);
    args.extend(extra.iter().map(OsStr::new));
    relief(&args)
}

/// `relief ARGS` without `--quiet` (for the notes it prints on stderr).
pub(crate) fn relief_loud<S: AsRef<OsStr>>(args: &[S]) -> Output {
    Command::new(BIN).args(args).output().expect("run relief")
}

/// `relief!["convert", input, &out, "--force"]`: [`relief`] on words of mixed types (strings,
/// paths, anything `AsRef<OsStr>`).
macro_rules! relief_words {
    ($($a:expr),* $(,)?) => {
        $crate::common::relief(&[$($crate::common::os(&$a)),*])
    };
}
// Renamed so that the import brings only the macro (the function has the same name).
pub(crate) use relief_words as relief;

/// `relief_ok![...]`: [`relief!`] that must succeed; its stdout.
macro_rules! relief_ok {
    ($($a:expr),* $(,)?) => {
        $crate::common::ok(&$crate::common::relief![$($a),*])
    };
}
pub(crate) use relief_ok;

/// `relief_json![...]`: [`relief_ok!`] whose stdout is one JSON value, parsed.
macro_rules! relief_json {
    ($($a:expr),* $(,)?) => {
        serde_json::from_str::<serde_json::Value>(&$crate::common::relief_ok![$($a),*])
            .expect("JSON on stdout")
    };
}
pub(crate) use relief_json;

pub(crate) fn os<S: AsRef<OsStr> + ?Sized>(s: &S) -> &OsStr {
    s.as_ref()
}

/// A path as UTF-8 (every test path is).
pub(crate) fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

pub(crate) fn read(path: &Path) -> Heightfield {
    relief_io::read(path, &relief_io::ReadOptions::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .heightfield
}

/// Two rasters with the same grid, bits (voids included), cell size and georeference.
pub(crate) fn assert_same_raster(a: &Path, b: &Path) {
    let (x, y) = (read(a), read(b));
    assert_eq!((x.width(), x.height()), (y.width(), y.height()));
    let differ = x
        .as_slice()
        .iter()
        .zip(y.as_slice())
        .filter(|(p, q)| p.to_bits() != q.to_bits())
        .count();
    assert_eq!(
        differ,
        0,
        "{differ} cells differ between {} and {}",
        a.display(),
        b.display()
    );
    assert_eq!(x.cell_size(), y.cell_size());
    let geo = |h: &Heightfield| {
        h.georef()
            .map(|g| (g.geotransform, g.crs.clone(), g.geo_key_directory.clone()))
    };
    assert_eq!(geo(&x), geo(&y), "georeference of {}", a.display());
}

/// Writes `hf` into `path` with the default options.
pub(crate) fn save(path: &Path, hf: &Heightfield) {
    relief_io::write(path, hf, &relief_io::WriteOptions::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

pub(crate) fn write(dir: &Path, name: &str, hf: &Heightfield) -> PathBuf {
    let p = dir.join(name);
    save(&p, hf);
    p
}

/// A JSON file, parsed.
pub(crate) fn json(path: &Path) -> serde_json::Value {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_slice(&bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Asserts success; the stdout.
pub(crate) fn ok(out: &Output) -> String {
    assert!(out.status.success(), "stderr: {}", stderr(out));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Asserts failure; the stderr.
pub(crate) fn failed(out: &Output) -> String {
    assert!(!out.status.success(), "unexpected success: {}", stderr(out));
    stderr(out)
}

/// Asserts a clean failure: exactly one stderr line containing every `needle`, and none of
/// `outputs` written.
pub(crate) fn fails_with(out: &Output, needles: &[&str], outputs: &[&Path]) -> String {
    let e = failed(out);
    assert_eq!(e.trim_end().lines().count(), 1, "one stderr line: {e}");
    for n in needles {
        assert!(e.contains(n), "`{n}` not in: {e}");
    }
    for f in outputs {
        assert!(!f.exists(), "{} was written", f.display());
        let dir = f.parent().filter(|d| d.is_dir());
        let temps: Vec<String> = dir.map(files).unwrap_or_default();
        let temps: Vec<&String> = temps.iter().filter(|n| n.contains(".tmp")).collect();
        assert!(temps.is_empty(), "temporary files left: {temps:?}");
    }
    e
}

/// Asserts that stderr contains `needle`.
pub(crate) fn assert_stderr_has(o: &Output, needle: &str) {
    let e = stderr(o);
    assert!(e.contains(needle), "`{needle}` not in: {e}");
}

pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Names of the files in `dir` (sorted).
pub(crate) fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// The hidden names (`.` first: temporaries, staging folders) in `dir`, sorted.
pub(crate) fn hidden_files(dir: &Path) -> Vec<String> {
    files(dir)
        .into_iter()
        .filter(|f| f.starts_with('.'))
        .collect()
}

/// Asserts `a` and `b` agree element by element within `rel` of each value (absolute below 1).
pub(crate) fn assert_close(a: &[f64], b: &[f64], rel: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: {a:?} vs {b:?}");
    for (x, y) in a.iter().zip(b) {
        assert!(
            (x - y).abs() <= rel * y.abs().max(1.0),
            "{what}: {a:?} vs {b:?}"
        );
    }
}

pub(crate) fn fixture() -> Heightfield {
    read(&relief_testdata::fixture("grandcanyon.tif"))
}

/// A crop of the fixture written as `name` into `dir`; its path and the crop.
pub(crate) fn fixture_crop(
    dir: &Path,
    name: &str,
    (x, y, w, h): (usize, usize, usize, usize),
) -> (PathBuf, Heightfield) {
    let hf = fixture().crop(x, y, w, h).unwrap();
    (write(dir, name, &hf), hf)
}

/// A fresh temporary folder with the crop `window` of the fixture written into it as `name`:
/// the folder, that file and the crop.
pub(crate) fn tmp_with_crop(
    name: &str,
    window: (usize, usize, usize, usize),
) -> (tempfile::TempDir, PathBuf, Heightfield) {
    let tmp = tempfile::tempdir().unwrap();
    let (path, hf) = fixture_crop(tmp.path(), name, window);
    (tmp, path, hf)
}

/// A temporary folder holding `hf` written as `name`, and the file's path.
pub(crate) fn tmp_with(name: &str, hf: &Heightfield) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let path = write(tmp.path(), name, hf);
    (tmp, path)
}

pub(crate) fn dem(name: &str) -> Option<PathBuf> {
    relief_testdata::dem_dir().map(|d| d.join(name))
}

/// A file of the real DEM set and a fresh temporary folder, or `None` when the set is absent
/// (the test then returns early, see `relief_testdata::dem_dir`).
pub(crate) fn dem_and_tmp(name: &str) -> Option<(PathBuf, tempfile::TempDir)> {
    Some((dem(name)?, tempfile::tempdir().unwrap()))
}

/// A malformed flag value is a usage error: clap's message (naming the flag) on stderr, exit
/// code 2, and `output` is not written.
pub(crate) fn usage_error(args: &[&OsStr], flag: &str, output: &Path) {
    let out = relief(args);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {e}");
    assert!(
        e.starts_with("error: ") && e.contains(flag),
        "{args:?}: {e}"
    );
    assert!(!output.exists(), "{args:?}: {} written", output.display());
}

/// A fixed Fisher-Yates shuffle of `order` (splitmix64 from `seed`): tasks in another order
/// than the plan's.
pub(crate) fn shuffle(order: &mut [usize], seed: u64) {
    let mut x = seed;
    for i in (1..order.len()).rev() {
        let z = relief_heightfield::rng::splitmix64(x);
        x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
        order.swap(i, (z % (i as u64 + 1)) as usize);
    }
}

/// Runs the tasks of `order` two processes at a time (`spawn` starts task `i`); every one must
/// succeed (`what` names them when one fails).
pub(crate) fn two_at_a_time(order: &[usize], what: &str, spawn: impl Fn(usize) -> Child) {
    for pair in order.chunks(2) {
        let children: Vec<Child> = pair.iter().map(|&i| spawn(i)).collect();
        for c in children {
            let out = c.wait_with_output().unwrap();
            assert!(
                out.status.success(),
                "{what} failed: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }
}

/// Kills `child` (SIGKILL) `ms` milliseconds after it started and reaps it: a task killed
/// mid-run.
pub(crate) fn kill_after(mut child: Child, ms: u64) {
    std::thread::sleep(std::time::Duration::from_millis(ms));
    let _ = child.kill();
    let _ = child.wait();
}

/// Damages a file in place: one byte in its middle flipped.
pub(crate) fn damage(path: &Path) {
    let mut bytes = std::fs::read(path).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x55;
    std::fs::write(path, &bytes).unwrap();
}
