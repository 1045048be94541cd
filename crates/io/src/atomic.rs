//! Atomic file writes: a temporary file in the destination directory, then a rename. A run killed
//! mid-write leaves at most a hidden `.<name>.tmp-<pid>-<n>` file (or a `.relief-stage-<pid>-<n>`
//! folder of a [`Staging`]), never a partial `<name>`; the next write into the same folder
//! removes such leftovers of dead processes. An existing target that is not a regular file
//! (`/dev/null`, a pipe) is never replaced. Temporary names carry an unpredictable number and
//! are created exclusively (`O_CREAT | O_EXCL`, [`create_temp`]), staging folders with an
//! exclusive `mkdir`: a link planted in a shared folder is refused, never followed.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::{IoError, Result};

/// Longest file name most filesystems accept (bytes).
const NAME_MAX: usize = 255;

/// The hidden temporary sibling of `path`: `.<name>.tmp-<pid>-<n>`, with `<name>` shortened
/// (on a character boundary) so that the temporary name never exceeds [`NAME_MAX`] bytes
/// when the output name itself is legal.
pub(crate) fn temp_path(path: &Path) -> PathBuf {
    let n = unique_number();
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tail = format!(".tmp-{}-{n}-{}", std::process::id(), host_tag());
    let room = NAME_MAX - 1 - tail.len();
    let mut cut = name.len().min(room);
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    path.with_file_name(format!(".{}{tail}", &name[..cut]))
}

/// A number no other temporary name of this process uses and no other process can predict:
/// a per-process counter mixed with the clock, the process id and the address of a stack
/// value (the name is created exclusively anyway, [`create_temp`]; unpredictable names keep a
/// hostile folder from planting anything at them in advance).
pub(crate) fn unique_number() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let local = 0u8;
    let addr = &local as *const u8 as u64;
    let mut z = n ^ t.rotate_left(17) ^ (std::process::id() as u64).rotate_left(41) ^ addr;
    // splitmix64 finaliser.
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Creates the temporary file `tmp` exclusively (`O_CREAT | O_EXCL`): it fails when anything
/// already has that name, a symbolic link included (which is then not followed), so a planted
/// link can never redirect a write outside the folder.
pub(crate) fn create_temp(tmp: &Path) -> std::io::Result<std::fs::File> {
    let f = std::fs::OpenOptions::new()
        .write(true)
        .read(true)
        .create_new(true)
        .open(tmp)?;
    remember(tmp);
    Ok(f)
}

/// The temporaries and staging folders this process created (some long gone: renamed into
/// place or removed), for [`remove_own_temporaries`].
static OWN: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn remember(path: &Path) {
    OWN.lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(path.to_path_buf());
}

/// Removes every temporary file and staging folder this process created that is still there
/// (what a write in progress has not yet renamed into place): for a process about to exit
/// early, on SIGINT or SIGTERM, or when its time is up. Only names of this process's
/// temporaries are touched; outputs already in place stay. Errors are ignored.
pub fn remove_own_temporaries() {
    remove_own_under(None);
}

/// [`remove_own_temporaries`] of those under `dir` only (all with `None`).
fn remove_own_under(dir: Option<&Path>) {
    let own: Vec<PathBuf> = {
        let mut all = OWN.lock().unwrap_or_else(|e| e.into_inner());
        let (mine, keep) = std::mem::take(&mut *all)
            .into_iter()
            .partition(|p| dir.is_none_or(|d| p.starts_with(d)));
        *all = keep;
        mine
    };
    let pid = std::process::id();
    for path in own {
        let ours = path
            .file_name()
            .and_then(|n| n.to_str())
            .and_then(temp_owner)
            .is_some_and(|(p, host)| p == pid && host.is_none_or(|h| h == host_tag()));
        if !ours {
            continue;
        }
        match std::fs::symlink_metadata(&path) {
            Ok(m) if m.is_dir() => {
                let _ = std::fs::remove_dir_all(&path);
            }
            Ok(_) => {
                let _ = std::fs::remove_file(&path);
            }
            Err(_) => {}
        }
    }
}

/// A short tag of this machine (8 hex digits of a hash of the host name), part of every
/// temporary name: on a folder shared by several machines (a tile plan on NFS), a process id is
/// only meaningful on the machine that owns it, so only this machine's dead temporaries are
/// ever removed.
fn host_tag() -> &'static str {
    static TAG: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TAG.get_or_init(|| {
        let name = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .or_else(|_| std::fs::read_to_string("/etc/hostname"))
            .unwrap_or_default();
        let mut h: u32 = 0x811c_9dc5;
        for b in name.trim().bytes() {
            h = (h ^ b as u32).wrapping_mul(0x0100_0193);
        }
        format!("{h:08x}")
    })
}

/// The owner of a relief temporary name (`.<name>.tmp-<pid>-<n>-<host>` or
/// `.relief-stage-<pid>-<n>-<host>`; names of older versions have no host): the process id
/// and the host tag, if `file` is one.
fn temp_owner(file: &str) -> Option<(u32, Option<&str>)> {
    let rest = if let Some(r) = file.strip_prefix(STAGE_PREFIX) {
        r
    } else {
        let i = file.rfind(".tmp-")?;
        if !file.starts_with('.') || i == 0 {
            return None;
        }
        &file[i + ".tmp-".len()..]
    };
    let mut parts = rest.split('-');
    let pid = parts.next()?.parse::<u32>().ok()?;
    parts.next()?.parse::<u64>().ok()?;
    let host = parts.next();
    if parts.next().is_some() || host.is_some_and(|h| h.len() != 8) {
        return None;
    }
    Some((pid, host))
}

/// Removes the temporaries (files and staging folders) that runs killed mid-write left in the
/// folder of `path`: hidden `.<name>.tmp-<pid>-<n>` files and `.relief-stage-<pid>-<n>`
/// folders whose process no longer exists, whatever output they were for. Only where `/proc`
/// tells which processes are alive (Linux); elsewhere they stay (hidden, harmless). Errors are
/// ignored: this is housekeeping.
pub(crate) fn remove_stale_temps(path: &Path) {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    remove_stale_temps_in(dir);
}

/// [`remove_stale_temps`] for the folder `dir` itself.
pub(crate) fn remove_stale_temps_in(dir: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let me = std::process::id();
    for e in entries.flatten() {
        let file = e.file_name();
        let Some((pid, host)) = file.to_str().and_then(temp_owner) else {
            continue;
        };
        // Another machine's temporary (shared folder): its process may well be alive there.
        if host.is_some_and(|h| h != host_tag()) {
            continue;
        }
        if pid == me || Path::new("/proc").join(pid.to_string()).exists() {
            continue;
        }
        match e.file_type() {
            Ok(t) if t.is_dir() => {
                let _ = std::fs::remove_dir_all(e.path());
            }
            Ok(t) if t.is_file() => {
                let _ = std::fs::remove_file(e.path());
            }
            _ => {}
        }
    }
}

/// Refuses to replace an existing `path` that is not a regular file (a device such as
/// `/dev/null`, a pipe, a socket or a folder): renaming over it would replace the node itself.
pub(crate) fn check_replaceable(path: &Path) -> Result<()> {
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() => Err(IoError::param(
            "path",
            path.display(),
            "exists and is not a regular file (a device, pipe, socket or folder); relief only \
             replaces regular files",
        )),
        _ => Ok(()),
    }
}

/// Targets that must be created, never replaced ([`create_new_only`]), as absolute paths.
static NEW_ONLY: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

/// Marks `path` as a new output of this process: the write that puts it in place creates it
/// exclusively, and fails (leaving the other file alone) if something appeared at that name
/// meanwhile, instead of silently replacing it. For outputs a caller checked to be absent and
/// may not replace (two runs writing one new name at once: the second fails).
pub fn create_new_only(path: &Path) {
    let abs = absolute(path);
    let mut set = NEW_ONLY.lock().unwrap_or_else(|e| e.into_inner());
    if !set.contains(&abs) {
        set.push(abs);
    }
}

fn is_new_only(path: &Path) -> bool {
    let set = NEW_ONLY.lock().unwrap_or_else(|e| e.into_inner());
    !set.is_empty() && set.contains(&absolute(path))
}

/// Moves the finished `tmp` to `path`: a rename, or for a [`create_new_only`] target an
/// exclusive hard link (then `tmp` is removed), which fails when `path` exists. On a file
/// system without hard links the name is checked just before the rename.
pub(crate) fn place(tmp: &Path, path: &Path) -> std::io::Result<()> {
    if !is_new_only(path) {
        return std::fs::rename(tmp, path);
    }
    let taken = || {
        std::io::Error::new(
            std::io::ErrorKind::AlreadyExists,
            "another process created it while this one was writing it; it was not replaced",
        )
    };
    match std::fs::hard_link(tmp, path) {
        Ok(()) => {
            let _ = std::fs::remove_file(tmp);
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(taken()),
        Err(_) if std::fs::symlink_metadata(path).is_ok() => Err(taken()),
        Err(_) => std::fs::rename(tmp, path),
    }
}

/// Renames the finished temporary `tmp` over `path` (removing `tmp` on failure).
pub(crate) fn rename_into_place(tmp: &Path, path: &Path) -> Result<()> {
    let res =
        check_replaceable(path).and_then(|()| place(tmp, path).map_err(|e| IoError::os(path, e)));
    if res.is_err() {
        let _ = std::fs::remove_file(tmp);
    }
    res
}

/// Writes `bytes` to a temporary sibling, syncs it and renames it over `path`. On error the
/// temporary file is removed and `path` is untouched.
pub(crate) fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = write_temp(path, bytes)?;
    rename_into_place(&tmp, path)
}

const STAGE_PREFIX: &str = ".relief-stage-";

/// Outputs of one run that appear together or not at all.
///
/// [`Staging::path`] gives, for each target, a path with the same file name inside a hidden
/// staging folder `.relief-stage-<pid>-<n>` next to the target; the caller writes there with
/// any relief-io writer (sidecars such as `OUT.json` land beside it). [`Staging::commit`] moves
/// every file of every staging folder into place; dropping the `Staging` without a commit (an
/// error anywhere in the run) removes the staging folders, so no target is touched. A run
/// killed before the commit leaves only the hidden folder, removed by the next write into
/// that folder. The renames of the commit are not one atomic step, but each is a rename within
/// one folder (they do not fail for lack of space).
#[derive(Debug, Default)]
pub struct Staging {
    /// `(target folder, staging folder)`.
    dirs: Vec<(PathBuf, PathBuf)>,
}

impl Staging {
    /// An empty set of outputs.
    pub fn new() -> Staging {
        Staging::default()
    }

    /// Where to write `target` so that it appears at `target` on [`Staging::commit`]. Creates
    /// the staging folder of the target's folder on first use, which also checks that the
    /// folder exists and is writable. `target` must not be an existing non-regular file.
    pub fn path(&mut self, target: &Path) -> Result<PathBuf> {
        let name = target
            .file_name()
            .ok_or_else(|| IoError::param("path", target.display(), "has no file name"))?;
        check_replaceable(target)?;
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if let Some((_, stage)) = self.dirs.iter().find(|(d, _)| same_dir(d, &dir)) {
            return Ok(stage.join(name));
        }
        remove_stale_temps_in(&dir);
        let n = unique_number();
        let stage = dir.join(format!(
            "{STAGE_PREFIX}{}-{n}-{}",
            std::process::id(),
            host_tag()
        ));
        std::fs::create_dir(&stage).map_err(|e| IoError::os(target, e))?;
        remember(&stage);
        self.dirs.push((dir, stage.clone()));
        Ok(stage.join(name))
    }

    /// Moves every staged file into its target folder, then removes the staging folders.
    pub fn commit(mut self) -> Result<()> {
        let dirs = std::mem::take(&mut self.dirs);
        let res = staged_moves(&dirs).and_then(|moves| {
            moves
                .iter()
                .try_for_each(|(from, to)| place(from, to).map_err(|e| IoError::os(to, e)))
        });
        for (_, stage) in &dirs {
            let _ = std::fs::remove_dir_all(stage);
        }
        res
    }
}

/// The `(staged file, target)` moves of a [`Staging`]'s folders, checked before anything
/// moves: targets must be replaceable, and a new-only target ([`create_new_only`]) free.
fn staged_moves(dirs: &[(PathBuf, PathBuf)]) -> Result<Vec<(PathBuf, PathBuf)>> {
    let mut moves = Vec::new();
    for (dir, stage) in dirs {
        let entries = std::fs::read_dir(stage).map_err(|e| IoError::os(stage, e))?;
        for e in entries {
            let e = e.map_err(|e| IoError::os(stage, e))?;
            let name = e.file_name();
            // Leftover temporaries of the writers (none after a successful write).
            if name.to_str().is_some_and(|n| temp_owner(n).is_some()) {
                continue;
            }
            let target = dir.join(&name);
            check_replaceable(&target)?;
            if is_new_only(&target) && std::fs::symlink_metadata(&target).is_ok() {
                return Err(IoError::os(
                    &target,
                    std::io::Error::new(
                        std::io::ErrorKind::AlreadyExists,
                        "another process created it while this one was writing it; it was \
                         not replaced",
                    ),
                ));
            }
            moves.push((e.path(), target));
        }
    }
    Ok(moves)
}

impl Drop for Staging {
    fn drop(&mut self) {
        for (_, stage) in &self.dirs {
            let _ = std::fs::remove_dir_all(stage);
        }
    }
}

/// Creates a new, empty, hidden staging folder in `parent` (`.relief-stage-<pid>-<n>-<host>`,
/// `n` unpredictable) with an exclusive `mkdir`: an existing folder or a planted link of that
/// name is an error, never adopted. Dead runs' folders are removed by the next write into
/// `parent`, like the writers' temporaries.
pub fn create_staging_dir(parent: &Path) -> Result<PathBuf> {
    remove_stale_temps_in(parent);
    let stage = parent.join(format!(
        "{STAGE_PREFIX}{}-{}-{}",
        std::process::id(),
        unique_number(),
        host_tag()
    ));
    std::fs::create_dir(&stage).map_err(|e| IoError::os(&stage, e))?;
    remember(&stage);
    Ok(stage)
}

fn same_dir(a: &Path, b: &Path) -> bool {
    a == b
        || matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
}

fn write_temp(path: &Path, bytes: &[u8]) -> Result<PathBuf> {
    if path.file_name().is_none() {
        return Err(IoError::param("path", path.display(), "has no file name"));
    }
    check_replaceable(path)?;
    remove_stale_temps(path);
    let tmp = temp_path(path);
    let res = (|| {
        let mut f = create_temp(&tmp)?;
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
    for (path, _) in files {
        if let Err(e) = check_replaceable(path) {
            for t in &temps {
                let _ = std::fs::remove_file(t);
            }
            return Err(e);
        }
    }
    for (i, ((path, _), tmp)) in files.iter().zip(&temps).enumerate() {
        if let Err(e) = place(tmp, path) {
            for t in &temps[i..] {
                let _ = std::fs::remove_file(t);
            }
            return Err(IoError::os(path, e));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pid that is not running (the largest pid Linux hands out is below 2^22).
    const DEAD: u32 = 4_194_303;

    /// Issue 44 item 8: two runs writing one new output name at once both "succeeded" (the
    /// later rename silently won). A target marked new-only is created exclusively: the
    /// second write fails and leaves the first file alone; other targets are replaced as
    /// before.
    #[test]
    fn a_new_only_target_created_meanwhile_is_not_replaced() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("new.tif");
        create_new_only(&out);
        // Another process creates it between this one's check and its write.
        std::fs::write(&out, b"the other run").unwrap();
        let e = write_atomic(&out, b"this run").unwrap_err();
        assert!(e.to_string().contains("another process created it"), "{e}");
        assert_eq!(std::fs::read(&out).unwrap(), b"the other run");
        let left: Vec<_> = std::fs::read_dir(d.path()).unwrap().collect();
        assert_eq!(left.len(), 1, "a temporary was left");
        // The same through a staging folder and the multi-file writer.
        let side = d.path().join("new.json");
        create_new_only(&side);
        std::fs::write(&side, b"{}").unwrap();
        let mut st = Staging::new();
        std::fs::write(st.path(&side).unwrap(), b"[]").unwrap();
        assert!(st.commit().is_err());
        assert!(write_all_atomic(&[(&side, b"[1]".as_slice())]).is_err());
        assert_eq!(std::fs::read(&side).unwrap(), b"{}");
        // A new-only name still free is created; an ordinary target is replaced.
        let fresh = d.path().join("fresh.tif");
        create_new_only(&fresh);
        write_atomic(&fresh, b"x").unwrap();
        assert_eq!(std::fs::read(&fresh).unwrap(), b"x");
        let plain = d.path().join("plain.tif");
        std::fs::write(&plain, b"old").unwrap();
        write_atomic(&plain, b"new").unwrap();
        assert_eq!(std::fs::read(&plain).unwrap(), b"new");
    }

    /// The SIGINT/SIGTERM handler of `relief` removes what the run was still writing:
    /// its temporaries and staging folders, never an output already in place or another
    /// process's temporary.
    #[test]
    fn own_temporaries_are_removed_and_nothing_else() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("done.tif");
        write_atomic(&out, b"in place").unwrap();
        let pending = temp_path(&d.path().join("pending.tif"));
        drop(create_temp(&pending).unwrap());
        let stage = create_staging_dir(d.path()).unwrap();
        std::fs::write(stage.join("a.tif"), b"staged").unwrap();
        let other = d.path().join(format!(".x.tif.tmp-{DEAD}-7-{}", host_tag()));
        std::fs::write(&other, b"not ours").unwrap();
        // (Only this folder's: the other tests of this process write at the same time.)
        remove_own_under(Some(d.path()));
        assert!(!pending.exists() && !stage.exists());
        assert_eq!(std::fs::read(&out).unwrap(), b"in place");
        assert!(other.exists());
    }

    #[test]
    fn temporary_names_stay_within_the_name_limit() {
        let d = tempfile::tempdir().unwrap();
        for len in [1, 200, 239, 250, 255] {
            let name: String = "é".repeat(len / 2) + &"a".repeat(len % 2);
            assert_eq!(name.len(), len);
            let target = d.path().join(&name);
            let tmp = temp_path(&target);
            let tn = tmp.file_name().unwrap().to_str().unwrap();
            assert!(tn.len() <= NAME_MAX, "{len}: {}", tn.len());
            assert_eq!(temp_owner(tn), Some((std::process::id(), Some(host_tag()))));
            write_atomic(&target, b"abc").unwrap();
            assert_eq!(std::fs::read(&target).unwrap(), b"abc");
        }
    }

    #[test]
    fn leftovers_of_dead_runs_are_removed_by_any_write_in_the_folder() {
        if !Path::new("/proc/self").exists() {
            return;
        }
        let d = tempfile::tempdir().unwrap();
        let stale = d.path().join(format!(".big.tif.tmp-{DEAD}-3"));
        std::fs::write(&stale, b"half").unwrap();
        let stage = d.path().join(format!("{STAGE_PREFIX}{DEAD}-0"));
        std::fs::create_dir(&stage).unwrap();
        std::fs::write(stage.join("mesh.glb"), b"half").unwrap();
        let live = d
            .path()
            .join(format!(".x.tif.tmp-{}-9", std::process::id()));
        std::fs::write(&live, b"mine").unwrap();
        let unrelated = d.path().join(".notes.tmp-abc");
        std::fs::write(&unrelated, b"keep").unwrap();
        // A dead-looking temporary of this host goes; one of another host (a task writing
        // into a shared plan folder from another machine) stays.
        let mine_dead = d.path().join(format!(".t.tif.tmp-{DEAD}-1-{}", host_tag()));
        std::fs::write(&mine_dead, b"half").unwrap();
        let other = if host_tag() == "00000000" {
            "11111111"
        } else {
            "00000000"
        };
        let elsewhere = d.path().join(format!(".t.tif.tmp-{DEAD}-2-{other}"));
        std::fs::write(&elsewhere, b"busy").unwrap();
        write_atomic(&d.path().join("other.png"), b"png").unwrap();
        assert!(!stale.exists() && !stage.exists() && !mine_dead.exists());
        assert!(live.exists() && unrelated.exists() && elsewhere.exists());
    }

    #[test]
    fn staged_outputs_appear_together_or_not_at_all() {
        let d = tempfile::tempdir().unwrap();
        let (a, b) = (d.path().join("a.glb"), d.path().join("b.png"));
        {
            let mut s = Staging::new();
            write_atomic(&s.path(&a).unwrap(), b"mesh").unwrap();
            write_atomic(&s.path(&b).unwrap(), b"png").unwrap();
            // Dropped without commit: an error later in the run.
        }
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0);
        let mut s = Staging::new();
        write_atomic(&s.path(&a).unwrap(), b"mesh").unwrap();
        let side = s.path(&b).unwrap();
        write_atomic(&side, b"png").unwrap();
        write_atomic(&side.with_file_name("b.png.json"), b"{}").unwrap();
        assert!(!a.exists());
        s.commit().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"mesh");
        assert_eq!(std::fs::read(&b).unwrap(), b"png");
        assert!(d.path().join("b.png.json").exists());
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 3);
        // A folder that does not exist fails at `path`, before any work.
        let mut s = Staging::new();
        assert!(s.path(&d.path().join("no/such/dir/x.png")).is_err());
    }

    #[test]
    fn a_planted_link_at_a_temporary_name_is_never_followed() {
        let tmp = tempfile::tempdir().unwrap();
        let victim = tmp.path().join("victim.txt");
        std::fs::write(&victim, b"keep me").unwrap();
        let out = tmp.path().join("out.bin");
        // Names are unpredictable: two temporaries of the same target differ.
        assert_ne!(temp_path(&out), temp_path(&out));
        // And a link planted at whatever name is used is refused, not followed.
        let planted = temp_path(&out);
        std::os::unix::fs::symlink(&victim, &planted).unwrap();
        assert!(create_temp(&planted).is_err());
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep me");
        write_atomic(&out, b"data").unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"data");
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep me");
    }

    #[test]
    fn staging_folders_are_new_unpredictable_and_known_to_the_cleaner() {
        let tmp = tempfile::tempdir().unwrap();
        let a = create_staging_dir(tmp.path()).unwrap();
        let b = create_staging_dir(tmp.path()).unwrap();
        assert_ne!(a, b);
        for d in [&a, &b] {
            assert!(d.is_dir() && std::fs::read_dir(d).unwrap().next().is_none());
            let name = d.file_name().unwrap().to_str().unwrap();
            assert_eq!(temp_owner(name).map(|o| o.0), Some(std::process::id()));
        }
        // An existing folder of that name is an error, never adopted.
        assert!(std::fs::create_dir(&a).is_err());
    }

    #[test]
    fn non_regular_targets_are_never_replaced() {
        let d = tempfile::tempdir().unwrap();
        let sub = d.path().join("folder.tif");
        std::fs::create_dir(&sub).unwrap();
        assert!(write_atomic(&sub, b"x").is_err());
        assert!(sub.is_dir());
        if Path::new("/dev/null").exists() {
            let e = write_atomic(Path::new("/dev/null"), b"x").unwrap_err();
            assert!(e.to_string().contains("not a regular file"), "{e}");
            assert!(Staging::new().path(Path::new("/dev/null")).is_err());
        }
    }
}
