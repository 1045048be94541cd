//! Helpers shared by the test modules: run the binary, read and write rasters.

#![allow(dead_code)] // not every module uses every helper

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use relief_heightfield::Heightfield;

pub(crate) fn relief(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relief"))
        .arg("--quiet")
        .args(args)
        .output()
        .expect("run relief")
}

pub(crate) fn os<S: AsRef<std::ffi::OsStr> + ?Sized>(s: &S) -> &std::ffi::OsStr {
    s.as_ref()
}

pub(crate) fn read(path: &Path) -> Heightfield {
    relief_io::read(path, &relief_io::ReadOptions::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .heightfield
}

pub(crate) fn write(dir: &Path, name: &str, hf: &Heightfield) -> PathBuf {
    let p = dir.join(name);
    relief_io::write(&p, hf, &relief_io::WriteOptions::default()).unwrap();
    p
}

pub(crate) fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

pub(crate) fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

pub(crate) fn fixture() -> Heightfield {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/grandcanyon.tif");
    read(&p)
}

pub(crate) fn dem(name: &str) -> Option<PathBuf> {
    relief_testdata::dem_dir().map(|d| d.join(name))
}

/// A malformed flag value is a usage error: clap's message (naming the flag) on stderr, exit
/// code 2, and `output` is not written.
pub(crate) fn usage_error(args: &[&std::ffi::OsStr], flag: &str, output: &Path) {
    let out = relief(args);
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {e}");
    assert!(
        e.starts_with("error: ") && e.contains(flag),
        "{args:?}: {e}"
    );
    assert!(!output.exists(), "{args:?}: {} written", output.display());
}
