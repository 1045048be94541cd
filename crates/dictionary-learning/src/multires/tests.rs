use super::*;

#[test]
fn box_resample_is_area_consistent() {
    let hf = Heightfield::from_fn(30, 21, 2.0, 3.0, |x, y| {
        (x as f32 * 0.7).sin() * 10.0 + y as f32 * 1.5 + ((x * y) % 7) as f32
    });
    // Integer factor: the exact box average.
    let a = box_resample(&hf, 10, 7).unwrap();
    let b = hf.downsample_box(3).unwrap();
    assert_eq!(a.cell_size(), (6.0, 9.0));
    for (p, q) in a.as_slice().iter().zip(b.as_slice()) {
        assert!((p - q).abs() < 1e-4, "{p} {q}");
    }
    // Fractional factor: the mean (over the whole extent) and the extent are kept.
    let c = box_resample(&hf, 13, 8).unwrap();
    let mean = |h: &Heightfield| {
        h.as_slice().iter().map(|&v| v as f64).sum::<f64>() / h.as_slice().len() as f64
    };
    assert!((mean(&c) - mean(&hf)).abs() < 1e-4);
    assert!((c.cell_size().0 * 13.0 - 60.0).abs() < 1e-9);
    assert!((c.cell_size().1 * 8.0 - 63.0).abs() < 1e-9);
    assert!(box_resample(&hf, 31, 21).is_err());
    assert!(box_resample(&hf, 0, 5).is_err());
}

#[test]
fn exemplar_plan_relates_cell_sizes() {
    let s = AmplifySettings {
        steps: 3,
        radius: 2.0,
        ..AmplifySettings::default()
    };
    // Coarse 120 m, exemplar 10 m (1000 x 800): targets 30, 7.5, 1.875 m.
    let plan = exemplar_plan((120.0, 120.0), (1000, 800), (10.0, 10.0), &s);
    assert_eq!(plan.len(), 3);
    assert!((plan[0].reduction - 3.0).abs() < 1e-9 && !plan[0].self_similar);
    assert_eq!(plan[0].exemplar_size, (333, 267));
    assert!((plan[0].target_cell_size.0 - 30.0).abs() < 1e-9);
    for p in &plan[1..] {
        assert!(p.self_similar && p.reduction == 1.0, "{p:?}");
        assert_eq!(p.exemplar_size, (1000, 800));
        assert!(p.note.contains("finer than the exemplar"), "{}", p.note);
    }
    // Too small to be reduced to 30 m (min side 6 * 16 = 96 cells): reduced as far as
    // it can be, and said so.
    let small = exemplar_plan((120.0, 120.0), (200, 200), (10.0, 10.0), &s);
    assert!(small[0].self_similar && small[0].exemplar_size.0 >= 96);
    assert!((small[0].reduction - 200.0 / 96.0).abs() < 1e-9);
    assert!(small[0].note.contains("too small"), "{}", small[0].note);
    // Anisotropic cells.
    let an = exemplar_plan((160.0, 80.0), (800, 800), (10.0, 5.0), &s);
    assert_eq!(an[0].exemplar_size, (200, 200));
    assert!((an[0].exemplar_cell_size.0 - 40.0).abs() < 1e-9);
    assert!((an[0].exemplar_cell_size.1 - 20.0).abs() < 1e-9);
}

/// A rough synthetic terrain (ridges plus hashed bumps).
fn rough(w: usize, h: usize, cell: f64, salt: u64) -> Heightfield {
    Heightfield::from_fn(w, h, cell, cell, |x, y| {
        let n = crate::noise::item_seed(salt, x as u64, y as u64) % 1000;
        (x as f32 * 0.31).sin() * 40.0
            + (y as f32 * 0.17 + x as f32 * 0.05).cos() * 60.0
            + ((x as f32 * 0.9).sin() * (y as f32 * 0.7).cos()).abs() * 25.0
            + n as f32 * 0.01
    })
}

#[test]
fn last_step_windows_equal_the_full_run_bit_for_bit() {
    let coarse = rough(45, 38, 64.0, 1);
    let exemplar = rough(160, 160, 4.0, 2);
    for (radius, steps, paper) in [(2.0, 2, false), (3.0, 1, false), (2.5, 1, true)] {
        let base = if paper {
            AmplifySettings::paper()
        } else {
            AmplifySettings::default()
        };
        let settings = AmplifySettings {
            radius,
            steps,
            dictionary: DictionaryChoice::learned(32, 1),
            seed: 7,
            ..base
        };
        let full = amplify(
            &coarse,
            &exemplar,
            &settings,
            &relief_heightfield::NoProgress,
        )
        .unwrap()
        .rasterize(&RasterSettings::default())
        .unwrap();
        let (last, figures) = prepare_last_step(
            &coarse,
            &exemplar,
            &settings,
            &relief_heightfield::NoProgress,
        )
        .unwrap();
        assert_eq!(figures.steps.len(), steps);
        assert_eq!(last.output_size(), (full.width(), full.height()));
        // Through the byte stream, as a tiled task reads it.
        let last = LastStep::from_bytes(&last.to_bytes().unwrap(), &settings).unwrap();
        let (w, h) = last.output_size();
        for win in [
            relief_sparse_core::Window {
                x: 0,
                y: 0,
                width: w,
                height: h,
            },
            relief_sparse_core::Window {
                x: 0,
                y: 0,
                width: 37,
                height: 50,
            },
            relief_sparse_core::Window {
                x: 61,
                y: 45,
                width: 70,
                height: 33,
            },
            relief_sparse_core::Window {
                x: w - 29,
                y: h - 17,
                width: 29,
                height: 17,
            },
            relief_sparse_core::Window {
                x: w / 2 + 3,
                y: 1,
                width: 5,
                height: h - 1,
            },
            // Away from every border (for x16, the crop is inside the input on all sides).
            relief_sparse_core::Window {
                x: w / 2 - 61,
                y: h / 2 - 53,
                width: 41,
                height: 37,
            },
        ] {
            let got = last.render_window(win).unwrap();
            let want = full.crop(win.x, win.y, win.width, win.height).unwrap();
            let same = got
                .as_slice()
                .iter()
                .zip(want.as_slice())
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(
                same,
                "R {radius} steps {steps} paper {paper}: window {win:?} differs"
            );
        }
    }
}

#[test]
fn last_step_bytes_reject_corruption() {
    let coarse = rough(24, 24, 64.0, 3);
    let exemplar = rough(100, 100, 16.0, 4);
    let settings = AmplifySettings {
        radius: 2.0,
        dictionary: DictionaryChoice::learned(16, 1),
        ..AmplifySettings::default()
    };
    let (last, _) = prepare_last_step(
        &coarse,
        &exemplar,
        &settings,
        &relief_heightfield::NoProgress,
    )
    .unwrap();
    let bytes = last.to_bytes().unwrap();
    assert!(LastStep::from_bytes(&bytes, &settings).is_ok());
    // Another radius: the dictionary does not fit.
    let other = AmplifySettings {
        radius: 3.0,
        ..settings
    };
    assert!(LastStep::from_bytes(&bytes, &other).is_err());
    for cut in [0, 7, 20, bytes.len() / 2, bytes.len() - 1] {
        assert!(
            LastStep::from_bytes(&bytes[..cut], &settings).is_err(),
            "cut {cut}"
        );
    }
    let mut flipped = bytes.clone();
    flipped[bytes.len() / 3] ^= 0x10;
    let e = LastStep::from_bytes(&flipped, &settings)
        .unwrap_err()
        .to_string();
    assert!(e.contains("checksum"), "{e}");
    let win = relief_sparse_core::Window {
        x: 90,
        y: 0,
        width: 10,
        height: 4,
    };
    assert!(last.render_window(win).is_err());
}

#[test]
fn the_last_step_stops_when_asked_and_runs_otherwise() {
    struct Stop;
    impl Progress for Stop {
        fn stopped(&self) -> bool {
            true
        }
    }
    let settings = AmplifySettings {
        steps: 1,
        dictionary: DictionaryChoice::learned(16, 1),
        seed: 3,
        ..AmplifySettings::default()
    };
    let (last, _) = prepare_last_step(
        &rough(40, 36, 64.0, 5),
        &rough(200, 200, 16.0, 6),
        &settings,
        &relief_heightfield::NoProgress,
    )
    .unwrap();
    match last.sct_with(&Stop) {
        Err(LearnError::Stopped(m)) => assert!(m.contains("coding"), "{m}"),
        other => panic!("{other:?}"),
    }
    assert!(last.sct().is_ok());
}
