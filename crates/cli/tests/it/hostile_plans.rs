//! Tile plans are untrusted input: a plan folder lives on a volume many jobs write, and its
//! plan id is an unkeyed SHA-256 anyone can recompute. For every plan type (amplify, refine,
//! decompress, flow): forged manifests (paths outside the folder, devices, huge counts),
//! records naming other tiles' files, tiles copied over others, links and devices planted at
//! plan names. Each ends with a clear error (or a tile counted as corrupt), never a read or
//! a write outside the named places, never a hang.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

use sha2::{Digest, Sha256};

use crate::common::*;

/// Runs `relief args`, failing the test if it has not ended within `secs` (a hang).
fn within<S: AsRef<OsStr>>(args: &[S], secs: u64) -> Output {
    let mut child = command()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            return child.wait_with_output().unwrap();
        }
        if t0.elapsed() > Duration::from_secs(secs) {
            let _ = child.kill();
            panic!(
                "relief {:?} hung",
                args.iter().map(|a| a.as_ref()).collect::<Vec<_>>()
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// `text` without the whitespace outside strings: the compact JSON serde writes.
fn minify(text: &str) -> String {
    let (mut out, mut in_str, mut esc) = (String::new(), false, false);
    for c in text.chars() {
        if in_str {
            out.push(c);
            match (esc, c) {
                (true, _) => esc = false,
                (false, '\\') => esc = true,
                (false, '"') => in_str = false,
                _ => {}
            }
        } else if c == '"' {
            in_str = true;
            out.push(c);
        } else if !c.is_whitespace() {
            out.push(c);
        }
    }
    out
}

/// Rewrites the manifest as an attacker with write access to the folder would: `edit` on its
/// text, then the plan id recomputed (SHA-256 of the compact manifest with an empty id).
fn forge(dir: &Path, edit: impl Fn(String) -> String) {
    let path = dir.join("manifest.json");
    let id = json(&path)["plan_id"].as_str().unwrap().to_string();
    let text = edit(std::fs::read_to_string(&path).unwrap().replace(&id, ""));
    let sum: String = Sha256::digest(minify(&text).as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let text = text.replace("\"plan_id\": \"\"", &format!("\"plan_id\": \"{sum}\""));
    put_manifest(dir, &text);
}

/// Writes the manifest `text` and moves the records of the done tiles from the current plan
/// id to its id (as an attacker would; also how the tests put a plan back).
fn put_manifest(dir: &Path, text: &str) {
    let path = dir.join("manifest.json");
    let id = |p: &Path| {
        let v: serde_json::Value = serde_json::from_slice(&std::fs::read(p).ok()?).ok()?;
        Some(v["plan_id"].as_str()?.to_string())
    };
    let old = id(&path);
    std::fs::write(&path, text).unwrap();
    let (Some(old), Some(new)) = (old, id(&path)) else {
        return;
    };
    let tiles = dir.join("tiles");
    for name in files(&tiles).iter().filter(|n| n.ends_with(".json")) {
        let p = tiles.join(name);
        let r = std::fs::read_to_string(&p).unwrap().replace(&old, &new);
        std::fs::write(&p, r).unwrap();
    }
}

/// Replaces the JSON value of the first `"key": ` in `text` (a string or a number).
fn set(text: &str, key: &str, value: &str) -> String {
    let k = format!("\"{key}\": ");
    let a = text
        .find(&k)
        .unwrap_or_else(|| panic!("{key} not in {text}"))
        + k.len();
    let rest = &text[a..];
    let end = if let Some(inner) = rest.strip_prefix('"') {
        1 + inner.find('"').unwrap() + 1
    } else {
        rest.find([',', '\n', '}']).unwrap()
    };
    format!("{}{value}{}", &text[..a], &text[a + end..])
}

#[cfg(unix)]
fn chmod(p: &Path, mode: u32) {
    use std::os::unix::fs::PermissionsExt as _;
    std::fs::set_permissions(p, std::fs::Permissions::from_mode(mode)).unwrap();
}

/// A small plan of each type in `tmp`: its folder and planned output.
fn plan(tmp: &Path, kind: &str) -> (PathBuf, PathBuf) {
    let (input, _) = fixture_crop(tmp, &format!("{kind}-in.tif"), (0, 0, 64, 64));
    let dir = tmp.join(format!("{kind}-plan"));
    let mut out = tmp.join(format!("{kind}-out.tif"));
    let exemplar = relief_testdata::fixture("grandcanyon.tif");
    let model = tmp.join("m.sct");
    let (tile, command) = match kind {
        "amplify" => (
            "128",
            words(
                "amplify {} {} --exemplar {} --factor 4 --landform off",
                &[&input, &out, &exemplar],
            ),
        ),
        "refine" => ("128", words("refine {} {} --landform off", &[&input, &out])),
        "decompress" => {
            relief_ok!["compress", &input, &model];
            ("32", words("decompress {} {}", &[&model, &out]))
        }
        _ => {
            out = tmp.join("flow-out");
            ("32", words("flow {} -o {}", &[&input, &out]))
        }
    };
    let mut args = words("tile plan {} --tile", &[&dir]);
    args.extend([OsStr::new(tile), OsStr::new("--")]);
    args.extend(command);
    ok(&relief(&args));
    (dir, out)
}

/// Forged manifests of every plan type: a recomputed plan id is accepted as such (the forge is
/// real), but a prepared file outside the folder, a device as an input, and 2^54 tasks are
/// refused by name, quickly.
#[test]
fn forged_manifests_are_refused_for_every_plan_type() {
    let tmp = tempfile::tempdir().unwrap();
    let secret = tmp.path().join("secret.tif");
    std::fs::write(&secret, b"not for the plan").unwrap();
    for kind in ["amplify", "refine", "decompress", "flow"] {
        let (dir, _) = plan(tmp.path(), kind);
        let manifest = std::fs::read_to_string(dir.join("manifest.json")).unwrap();
        let reset = || put_manifest(&dir, &manifest);
        // The identity forge loads: the tests below test the checks, not a bad plan id.
        forge(&dir, |t| t);
        let st = within(&["tile", "status", s(&dir)], 60);
        assert!(
            !stderr(&st).contains("modified after planning"),
            "{kind}: {}",
            stderr(&st)
        );
        for (prepared, why) in [
            ("../secret.tif", "outside the plan folder"),
            (s(&secret), "outside the plan folder"),
        ] {
            forge(&dir, |t| {
                let a = t.find("\"prepared\"").unwrap();
                format!(
                    "{}{}",
                    &t[..a],
                    set(&t[a..], "path", &format!("\"{prepared}\""))
                )
            });
            for args in [
                vec!["tile", "run", s(&dir), "--index", "0", "--phase", "1"],
                vec!["tile", "status", s(&dir)],
            ] {
                fails_with(&within(&args, 60), &[why], &[]);
            }
            reset();
        }
        forge(&dir, |t| {
            let t = set(&t, "tiles_x", &(1u64 << 27).to_string());
            let t = set(&t, "tiles_y", &(1u64 << 27).to_string());
            set(&t, "tasks", &(1u64 << 54).to_string())
        });
        for sub in ["status", "mosaic"] {
            fails_with(
                &within(&["tile", sub, s(&dir)], 30),
                &["more than a plan may hold"],
                &[],
            );
        }
        reset();
        // A manifest that is a link, or too large to be one, is refused before it is parsed.
        #[cfg(unix)]
        {
            let m = dir.join("manifest.json");
            let elsewhere = tmp.path().join(format!("{kind}-manifest.json"));
            std::fs::rename(&m, &elsewhere).unwrap();
            std::os::unix::fs::symlink(&elsewhere, &m).unwrap();
            fails_with(
                &within(&["tile", "status", s(&dir)], 30),
                &["not a regular file"],
                &[],
            );
            std::fs::remove_file(&m).unwrap();
            std::fs::write(&m, vec![b' '; 17 << 20]).unwrap();
            fails_with(
                &within(&["tile", "status", s(&dir)], 30),
                &["more than the"],
                &[],
            );
            reset();
        }
    }
    assert_eq!(std::fs::read(&secret).unwrap(), b"not for the plan");
}

/// A refine plan run to the end, then attacked: the mosaic follows the planned output only
/// when the folder is the user's own; records naming other tiles, tiles copied over others,
/// devices and links at plan names count as corrupt or are refused; no write outside.
#[cfg(unix)]
#[test]
fn tampered_records_tiles_and_outputs_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let (dir, out) = plan(tmp.path(), "refine");
    let n = json(&dir.join("manifest.json"))["tasks"].as_u64().unwrap() as usize;
    assert_eq!(n, 4);
    for i in 0..n {
        relief_ok!["tile", "run", &dir, "--index", i.to_string()];
    }
    // An input named as a device: never read (it would hash forever).
    let manifest = std::fs::read_to_string(dir.join("manifest.json")).unwrap();
    forge(&dir, |t| {
        let a = t.find("\"inputs\"").unwrap();
        format!("{}{}", &t[..a], set(&t[a..], "path", "\"/dev/zero\""))
    });
    std::fs::remove_file(dir.join("tiles/tile-000000.json")).unwrap();
    fails_with(
        &within(&["tile", "run", s(&dir), "--index", "0"], 60),
        &["/dev/zero", "changed since the plan"],
        &[],
    );
    put_manifest(&dir, &manifest);
    relief_ok!["tile", "run", &dir, "--index", "0"];
    // A plan folder other users can write: its manifest may have been forged, so its output
    // path is not followed; --out names the place.
    let victim = tmp.path().join("victim.tif");
    forge(&dir, |t| {
        let a = t.find("\"output\"").unwrap();
        format!(
            "{}{}",
            &t[..a],
            set(&t[a..], "path", &format!("\"{}\"", s(&victim)))
        )
    });
    chmod(&dir, 0o777);
    fails_with(
        &within(&["tile", "mosaic", s(&dir)], 60),
        &["--out"],
        &[&victim, &out],
    );
    let mine = tmp.path().join("mine.tif");
    ok(&within(&["tile", "mosaic", s(&dir), "--out", s(&mine)], 60));
    assert!(mine.exists() && !victim.exists());
    chmod(&dir, 0o755);
    put_manifest(&dir, &manifest);
    // A record naming another tile's file (with that file's checksum) is corrupt.
    let rec1 = dir.join("tiles/tile-000001.json");
    let good1 = std::fs::read_to_string(&rec1).unwrap();
    let rec0 = json(&dir.join("tiles/tile-000000.json"));
    let forged = set(&good1, "path", "\"tile-000000.tif\"");
    let forged = set(
        &forged,
        "sha256",
        &format!("\"{}\"", rec0["file"]["sha256"].as_str().unwrap()),
    );
    let forged = set(&forged, "bytes", &rec0["file"]["bytes"].to_string());
    std::fs::write(&rec1, forged).unwrap();
    let st = within(&["tile", "status", s(&dir)], 60);
    assert!(
        String::from_utf8_lossy(&st.stdout).contains("corrupt: 1"),
        "{}",
        stderr(&st)
    );
    std::fs::write(&rec1, &good1).unwrap();
    // Tile 2's file copied over tile 1's with the record rewritten to match: the checksums
    // agree, but the tile is not where tile 1 belongs on the map.
    let t1 = dir.join("tiles/tile-000001.tif");
    let good_tile = std::fs::read(&t1).unwrap();
    let bytes2 = std::fs::read(dir.join("tiles/tile-000002.tif")).unwrap();
    std::fs::write(&t1, &bytes2).unwrap();
    let sum: String = Sha256::digest(&bytes2)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let forged = set(
        &set(&good1, "sha256", &format!("\"{sum}\"")),
        "bytes",
        &bytes2.len().to_string(),
    );
    std::fs::write(&rec1, forged).unwrap();
    let other = tmp.path().join("other.tif");
    fails_with(
        &within(&["tile", "mosaic", s(&dir), "--out", s(&other)], 60),
        &["tile-000001.tif", "not placed where tile 1 belongs"],
        &[&other],
    );
    std::fs::write(&t1, &good_tile).unwrap();
    std::fs::write(&rec1, &good1).unwrap();
    // A device or a link at a record's or a tile's name: corrupt, never read.
    std::fs::remove_file(&rec1).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &rec1).unwrap();
    std::fs::remove_file(&t1).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &t1).unwrap();
    let st = within(&["tile", "status", s(&dir)], 60);
    assert!(
        String::from_utf8_lossy(&st.stdout).contains("corrupt: 1"),
        "{}",
        stderr(&st)
    );
    std::fs::remove_file(&rec1).unwrap();
    std::fs::remove_file(&t1).unwrap();
    // The tiles folder replaced by a link elsewhere: nothing is read or written through it.
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let tiles = dir.join("tiles");
    std::fs::rename(&tiles, tmp.path().join("tiles-moved")).unwrap();
    std::os::unix::fs::symlink(&elsewhere, &tiles).unwrap();
    for args in [
        vec!["tile", "run", s(&dir), "--index", "1"],
        vec!["tile", "status", s(&dir)],
        vec!["tile", "mosaic", s(&dir), "--out", s(&other)],
    ] {
        fails_with(&within(&args, 60), &["not a folder of the plan"], &[&other]);
    }
    assert!(files(&elsewhere).is_empty());
    std::fs::remove_file(&tiles).unwrap();
    std::fs::rename(tmp.path().join("tiles-moved"), &tiles).unwrap();
    relief_ok!["tile", "run", &dir, "--index", "1"];
    relief_ok!["tile", "mosaic", &dir];
    assert!(out.exists());
}

/// `tile run` applies `--max-memory` (at least 16M) before it reads the prepared file: plans
/// whose one tile is 2048^2 cells.
#[test]
fn tile_run_applies_the_memory_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let gc = relief_testdata::fixture("grandcanyon.tif");
    let (small, _) = fixture_crop(t, "small.tif", (0, 0, 128, 128));
    let model = t.join("m.sct");
    relief_ok!["compress", &small, &model];
    let plans: [Vec<&OsStr>; 3] = [
        words("refine {} r.tif --landform off", &[&gc]),
        words("decompress {} d.tif --scale 16", &[&model]),
        words(
            "amplify {} a.tif --exemplar {} --factor 16 --landform off",
            &[&small, &gc],
        ),
    ];
    for (k, line) in plans.iter().enumerate() {
        let dir = t.join(format!("plan-{k}"));
        let mut args: Vec<&OsStr> = vec![
            os("tile"),
            os("plan"),
            os(&dir),
            os("--tile"),
            os("2048"),
            os("--"),
        ];
        args.extend(line.iter().map(|a| os(*a)));
        let o = relief(&args);
        ok(&o);
        fails_with(
            &within(
                &[
                    os("--max-memory"),
                    os("16M"),
                    os("tile"),
                    os("run"),
                    os(&dir),
                    os("--index"),
                    os("0"),
                ],
                60,
            ),
            &["--max-memory"],
            &[&dir.join("tiles/tile-000000.tif")],
        );
    }
}
