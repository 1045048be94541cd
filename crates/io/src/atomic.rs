//! Atomic file writes: a temporary file in the destination directory, then a rename. A run killed
//! mid-write leaves at most a hidden `.<name>.tmp-<pid>-<n>` file, never a partial `<name>`; the
//! next write of the same target removes such leftovers of dead processes.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::{IoError, Result};

pub(crate) fn temp_path(path: &Path) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}-{n}", std::process::id()))
}

/// Writes `bytes` to a temporary sibling, syncs it and renames it over `path`. On error the
/// temporary file is removed and `path` is untouched.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = write_temp(path, bytes)?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        IoError::os(path, e)
    })
}

/// Removes temporaries of `path` left by runs that were killed mid-write (`.<name>.tmp-<pid>-<n>`
/// whose process no longer exists). Only where `/proc` tells which processes are alive (Linux);
/// elsewhere they stay (hidden, harmless). Errors are ignored: this is housekeeping.
pub(crate) fn remove_stale_temps(path: &Path) {
    let proc_fs = Path::new("/proc/self");
    let Some(name) = path.file_name().map(|s| s.to_string_lossy().into_owned()) else {
        return;
    };
    if !proc_fs.exists() {
        return;
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let prefix = format!(".{name}.tmp-");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let me = std::process::id();
    for e in entries.flatten() {
        let file = e.file_name();
        let Some(rest) = file.to_str().and_then(|f| f.strip_prefix(&prefix)) else {
            continue;
        };
        let Some(pid) = rest
            .split_once('-')
            .and_then(|(p, n)| n.parse::<u64>().ok().and(p.parse::<u32>().ok()))
        else {
            continue;
        };
        if pid != me && !Path::new("/proc").join(pid.to_string()).exists() {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

fn write_temp(path: &Path, bytes: &[u8]) -> Result<PathBuf> {
    if path.file_name().is_none() {
        return Err(IoError::param("path", path.display(), "has no file name"));
    }
    remove_stale_temps(path);
    let tmp = temp_path(path);
    let res = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    })();
    match res {
        Ok(()) => Ok(tmp),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(IoError::os(path, e))
        }
    }
}

/// Writes several files: all temporaries first, then the renames. If a temporary cannot be
/// written, none of the targets is touched.
pub(crate) fn write_all_atomic(files: &[(&Path, &[u8])]) -> Result<()> {
    let mut temps: Vec<PathBuf> = Vec::new();
    for (path, bytes) in files {
        match write_temp(path, bytes) {
            Ok(t) => temps.push(t),
            Err(e) => {
                for t in &temps {
                    let _ = std::fs::remove_file(t);
                }
                return Err(e);
            }
        }
    }
    for (i, ((path, _), tmp)) in files.iter().zip(&temps).enumerate() {
        if let Err(e) = std::fs::rename(tmp, path) {
            for t in &temps[i..] {
                let _ = std::fs::remove_file(t);
            }
            return Err(IoError::os(path, e));
        }
    }
    Ok(())
}
