//! Reliability of relief-io: atomic byte writes, the in-memory `.f32` + sidecar reader, the
//! cell limit of every reader and the regression inputs found by fuzzing (`fuzz/`).

use std::path::Path;

use relief_io::{ReadOptions, read_f32_sidecar_bytes, write_bytes_atomic};

fn temp_files(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp-"))
        .collect()
}

#[test]
fn write_bytes_atomic_replaces_and_leaves_no_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("model.sct");
    write_bytes_atomic(&p, b"first").unwrap();
    write_bytes_atomic(&p, b"second version").unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), b"second version");
    assert!(temp_files(dir.path()).is_empty());
    // A missing directory is an error naming the path; nothing is created.
    let q = dir.path().join("missing/out.sct");
    let e = write_bytes_atomic(&q, b"x").unwrap_err().to_string();
    assert!(e.contains("missing/out.sct"), "{e}");
    // A path without a file name is refused.
    assert!(write_bytes_atomic(Path::new("/"), b"x").is_err());
}

#[cfg(unix)]
#[test]
fn write_bytes_atomic_into_read_only_directory_keeps_old_file() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("keep.bin");
    std::fs::write(&p, b"old").unwrap();
    std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o555)).unwrap();
    // root ignores directory permissions: then the write succeeds, which is fine too.
    let res = write_bytes_atomic(&p, b"new");
    std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    match res {
        Err(e) => {
            assert!(e.to_string().contains("keep.bin"), "{e}");
            assert_eq!(std::fs::read(&p).unwrap(), b"old");
        }
        Ok(()) => assert_eq!(std::fs::read(&p).unwrap(), b"new"),
    }
    assert!(temp_files(dir.path()).is_empty());
}

#[test]
fn f32_sidecar_from_memory() {
    let data: Vec<u8> = (0..6)
        .flat_map(|i| (i as f32 * 1.5).to_le_bytes())
        .collect();
    let json = br#"{"width": 3, "height": 2, "cell_size_x_m": 10, "cell_size_y_m": 20}"#;
    let r = read_f32_sidecar_bytes(&data, Some(json), &ReadOptions::default()).unwrap();
    assert_eq!((r.heightfield.width(), r.heightfield.height()), (3, 2));
    assert_eq!(r.heightfield.cell_size(), (10.0, 20.0));
    assert_eq!(r.heightfield.as_slice()[5], 7.5);
    let e = read_f32_sidecar_bytes(
        &data,
        Some(b"{\"width\": 4, \"height\": 2}"),
        &ReadOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("sidecar declares 4 x 2"), "{e}");
    let e = read_f32_sidecar_bytes(&data, Some(b"not json"), &ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("sidecar"), "{e}");
    // Without a sidecar the width option gives the size.
    let o = ReadOptions {
        width: Some(2),
        ..Default::default()
    };
    let r = read_f32_sidecar_bytes(&data, None, &o).unwrap();
    assert_eq!((r.heightfield.width(), r.heightfield.height()), (2, 3));
}

#[cfg(target_os = "linux")]
#[test]
fn stale_temporaries_of_dead_runs_are_removed_by_the_next_write() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("model.sct");
    // pid_max is at most 2^22 on Linux: this process cannot exist.
    let dead = dir.path().join(".model.sct.tmp-999999999-0");
    let alive = dir
        .path()
        .join(format!(".model.sct.tmp-{}-77", std::process::id()));
    let other = dir.path().join(".other.tif.tmp-999999999-0");
    for f in [&dead, &alive, &other] {
        std::fs::write(f, b"partial").unwrap();
    }
    write_bytes_atomic(&p, b"done").unwrap();
    assert!(!dead.exists(), "stale temporary of a dead process kept");
    assert!(alive.exists(), "temporary of a live process removed");
    assert!(other.exists(), "temporary of another target removed");
}
