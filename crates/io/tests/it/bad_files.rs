//! Every file in `fixtures/bad/` (made by `fixtures/bad/make_bad.py`) must give an `Err` whose
//! message names the problem, and no reader may panic on it.

use std::path::{Path, PathBuf};

use relief_io::{ReadOptions, read};

fn bad_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/bad")
}

/// Expected fragments of the error message (lowercase) for some files: the message must name
/// the actual problem, not just fail.
const EXPECT: &[(&str, &str)] = &[
    ("tif_truncated.tif", "tif"),
    ("tif_wrong_magic.tif", "magic"),
    ("tif_zero_width.tif", "0"),
    ("tif_huge_1e6x1e6.tif", "exceed the limit"),
    ("tif_overflow_dims.tif", "exceed the limit"),
    ("tif_strip_past_end.tif", "strip 0"),
    ("tif_strip_count_past_end.tif", "strip 0"),
    ("tif_short_strip.tif", "truncated"),
    ("tif_strip_and_tile.tif", "tileoffsets"),
    ("tif_tiles_and_stray_strip.tif", "tileoffsets"),
    ("tif_nan_only.tif", "only voids"),
    ("tif_rgb_unsupported.tif", "unsupported"),
    ("png_wrong_magic.png", "magic"),
    ("png_zero_height.png", "zero size"),
    ("png_overflow_dims.png", "exceed the limit"),
    ("hgt_truncated.hgt", "neither 1201"),
    (
        "asc_lying_header.asc",
        "header declares 10 x 10 = 100 values",
    ),
    ("asc_too_many_values.asc", "holds more"),
    ("asc_overflow_dims.asc", "invalid dimensions"),
    ("asc_zero_dims.asc", "zero size"),
    ("asc_not_a_number.asc", "abc"),
    ("asc_nan_only.asc", "only voids"),
    ("npy_absurd_shape.npy", "exceed the limit"),
    ("npy_overflow_shape.npy", "overflows"),
    ("npy_truncated.npy", "truncated"),
    ("npy_header_past_end.npy", "truncated"),
    ("npy_nan_only.npy", "only voids"),
    ("npy_3d.npy", "not a 2-d grid"),
    ("npy_object_dtype.npy", "dtype"),
    ("npy_zero_axis.npy", "zero"),
    ("npz_no_grid.npz", "no 2-d numeric array"),
    ("npz_absurd_member.npz", "exceed the limit"),
    ("r32_odd_length.r32", "multiple"),
    ("r16_not_square.r16", "square"),
    ("sidecar_size_mismatch.f32", "sidecar declares 100 x 100"),
    ("sidecar_size_mismatch.json", "sidecar declares 100 x 100"),
    ("sidecar_nan_only.f32", "only voids"),
    ("sidecar_nan_only.json", "only voids"),
    ("sidecar_zero_width.f32", "zero size"),
    ("grid_lying.json", "holds 3"),
    ("grid_overflow.json", "width"),
    ("grid_nan_only.json", "only voids"),
    ("grid_not_json.json", "invalid json"),
    ("unknown_format.bin", "unknown format"),
    // Minimised crashes found by fuzzing (fuzz/, see fixtures/bad/FUZZ.md).
    ("exr_fuzz_tile_level_1.exr", "level"),
    ("exr_fuzz_tile_level_2.exr", "level"),
];

#[test]
fn every_bad_file_fails_cleanly() {
    let dir = bad_dir();
    let mut entries: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("fixtures/bad exists")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e != "py" && e != "md"))
        .collect();
    entries.sort();
    assert!(
        entries.len() >= 40,
        "fixtures/bad holds only {} files; run make_bad.py",
        entries.len()
    );
    for (name, _) in EXPECT {
        assert!(
            dir.join(name).is_file(),
            "{name} missing from fixtures/bad; run make_bad.py"
        );
    }
    let mut failures = Vec::new();
    for path in &entries {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let p = path.clone();
        let outcome = std::panic::catch_unwind(move || read(&p, &ReadOptions::default()));
        match outcome {
            Err(_) => failures.push(format!("{name}: PANICKED")),
            Ok(Ok(r)) => failures.push(format!(
                "{name}: read succeeded ({:?} {}x{})",
                r.format,
                r.heightfield.width(),
                r.heightfield.height()
            )),
            Ok(Err(e)) => {
                let msg = e.to_string();
                let lower = msg.to_lowercase();
                if !msg.contains(&name) {
                    failures.push(format!("{name}: message does not name the file: {msg}"));
                }
                if let Some((_, frag)) = EXPECT.iter().find(|(n, _)| *n == name)
                    && !lower.contains(frag)
                {
                    failures.push(format!("{name}: message lacks {frag:?}: {msg}"));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "bad files not rejected cleanly:\n{}",
        failures.join("\n")
    );
}

#[test]
fn bad_bytes_fail_in_memory_too() {
    // Every truncation of a valid file is an error or a valid smaller read, never a panic.
    let hf = relief_heightfield::Heightfield::from_fn(6, 5, 10.0, 10.0, |x, y| (x * 7 + y) as f32);
    for ext in ["tif", "png", "exr", "npy", "asc"] {
        let fmt = relief_io::Format::from_extension(Path::new(&format!("a.{ext}"))).unwrap();
        let bytes = relief_io::encode(&hf, fmt, &relief_io::WriteOptions::default()).unwrap();
        for cut in (0..bytes.len()).step_by(7) {
            let part = bytes[..cut].to_vec();
            let hint = PathBuf::from(format!("x.{ext}"));
            let res = std::panic::catch_unwind(move || {
                relief_io::read_bytes(&part, Some(&hint), &ReadOptions::default()).map(|_| ())
            });
            assert!(
                res.is_ok(),
                "{ext}: reader panicked on the first {cut} bytes"
            );
        }
    }
}

#[test]
fn exr_with_a_huge_data_window_is_rejected_before_decoding() {
    let hf = relief_heightfield::Heightfield::from_fn(4, 4, 1.0, 1.0, |x, y| (x + y) as f32);
    let mut bytes = relief_io::encode(
        &hf,
        relief_io::Format::Exr,
        &relief_io::WriteOptions::default(),
    )
    .unwrap();
    for key in [&b"dataWindow\0box2i\0"[..], &b"displayWindow\0box2i\0"[..]] {
        let at = bytes
            .windows(key.len())
            .position(|w| w == key)
            .expect("window attribute")
            + key.len()
            + 4;
        // box2i = xMin, yMin, xMax, yMax (i32 LE).
        bytes[at + 8..at + 12].copy_from_slice(&999_999i32.to_le_bytes());
        bytes[at + 12..at + 16].copy_from_slice(&999_999i32.to_le_bytes());
    }
    let res = std::panic::catch_unwind(|| {
        relief_io::read_bytes(&bytes, None, &ReadOptions::default()).map(|_| ())
    });
    let err = res
        .expect("no panic")
        .expect_err("huge EXR must be rejected");
    assert!(err.to_string().to_lowercase().contains("exr"), "{err}");
}

mod mutations {
    use super::*;
    use proptest::prelude::*;

    fn valid(ext: &str) -> Vec<u8> {
        let hf = relief_heightfield::Heightfield::from_fn(9, 7, 10.0, 10.0, |x, y| {
            (x * 7 + y * 3) as f32
        });
        let fmt = relief_io::Format::from_extension(Path::new(&format!("a.{ext}"))).unwrap();
        relief_io::encode(&hf, fmt, &relief_io::WriteOptions::default()).unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        /// Random byte edits of valid files: every reader returns (Ok or Err) without panicking.
        #[test]
        fn corrupted_files_never_panic(
            which in 0usize..6,
            edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        ) {
            let ext = ["tif", "png", "exr", "npy", "asc", "hgt"][which];
            let mut bytes = if ext == "hgt" { vec![0u8; 1201 * 1201 * 2] } else { valid(ext) };
            for (i, b) in &edits {
                let k = i.index(bytes.len());
                bytes[k] = *b;
            }
            let hint = PathBuf::from(format!("x.{ext}"));
            let res = std::panic::catch_unwind(move || {
                relief_io::read_bytes(&bytes, Some(&hint), &ReadOptions::default()).map(|_| ())
            });
            prop_assert!(res.is_ok(), "{} reader panicked after edits {:?}", ext, edits);
        }
    }
}
