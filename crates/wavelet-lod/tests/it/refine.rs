//! Refinement on synthetic inputs: windows equal the full run bit for bit, results do not depend
//! on the thread count, the synthesised levels follow equation (5), and bad settings are errors.

use relief_heightfield::{Heightfield, NoProgress, metrics};
use relief_wavelet_lod::{
    Boundary, FitSettings, Grid, Method, RefineSettings, Refiner, Wavelet, WaveletError, analyze,
    analyze_local, max_levels, refine, wavedec2,
};

/// A deterministic rough surface (sum of octaves of hashed values, bilinearly interpolated).
fn rough(w: usize, h: usize, seed: u64) -> Heightfield {
    let hash = |x: i64, y: i64, o: u64| -> f32 {
        let mut z = (x as u64).wrapping_mul(0x9E3779B97F4A7C15)
            ^ (y as u64).wrapping_mul(0xC2B2AE3D27D4EB4F)
            ^ (o.wrapping_add(seed)).wrapping_mul(0x165667B19E3779F9);
        z ^= z >> 29;
        z = z.wrapping_mul(0xBF58476D1CE4E5B9);
        z ^= z >> 32;
        (z % 10_000) as f32 / 5_000.0 - 1.0
    };
    Heightfield::from_fn(w, h, 30.0, 30.0, |x, y| {
        let mut v = 0.0;
        for o in 0..6u64 {
            let s = (1 << (6 - o)) as f32;
            let (fx, fy) = (x as f32 / s, y as f32 / s);
            let (x0, y0) = (fx.floor(), fy.floor());
            let (tx, ty) = (fx - x0, fy - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let a = hash(x0, y0, o) * (1.0 - tx) + hash(x0 + 1, y0, o) * tx;
            let b = hash(x0, y0 + 1, o) * (1.0 - tx) + hash(x0 + 1, y0 + 1, o) * tx;
            v += (a * (1.0 - ty) + b * ty) * s * 8.0;
        }
        v + 500.0
    })
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// The refiner of `hf` with `s` and its whole output.
fn refiner_and_output(hf: &Heightfield, s: &RefineSettings) -> (Refiner, Heightfield) {
    let r = Refiner::new(hf, s).unwrap();
    let full = r.render(&NoProgress).unwrap();
    (r, full)
}

/// Asserts that every window `(x, y, w, h)` rendered alone equals that part of `full`, bit
/// for bit.
fn assert_windows_match(r: &Refiner, full: &Heightfield, windows: &[[usize; 4]], what: &str) {
    for &[x, y, w, h] in windows {
        let win = r.render_window(x, y, w, h).unwrap();
        let want = full.crop(x, y, w, h).unwrap();
        assert_eq!(
            bits(win.as_slice()),
            bits(want.as_slice()),
            "{what} window {x},{y},{w},{h}"
        );
    }
}

/// The largest difference (m) between a cell of `hf` and the mean of its `f x f` block of
/// `out` (area consistency).
fn worst_block_mean_error(out: &Heightfield, hf: &Heightfield, f: usize) -> f32 {
    out.downsample_box(f)
        .unwrap()
        .as_slice()
        .iter()
        .zip(hf.as_slice())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max)
}

#[test]
fn windows_equal_the_full_run_bit_for_bit() {
    let hf = rough(45, 37, 1);
    for wavelet in Wavelet::ALL {
        for (method, window) in [(Method::Gsa, 3), (Method::Lsa, 3), (Method::Lsa, 1)] {
            for extra in [1u32, 2, 3] {
                let s = RefineSettings {
                    wavelet: Some(wavelet),
                    method,
                    window,
                    extra_levels: extra,
                    seed: 99,
                    tile: 64,
                    ..Default::default()
                };
                let (r, full) = refiner_and_output(&hf, &s);
                let (ow, oh) = r.output_size();
                assert_eq!((full.width(), full.height()), (45 << extra, 37 << extra));
                let windows = [
                    [0, 0, 1, 1],
                    [0, 0, ow, oh],
                    [ow - 3, oh - 5, 3, 5],
                    [7, 11, 33, 17],
                    [ow / 2 + 1, 3, ow / 2 - 1, oh / 3],
                    [13, oh - 1, 1, 1],
                ];
                let what = format!("{wavelet} {method:?} w{window} +{extra}");
                assert_windows_match(&r, &full, &windows, &what);
            }
        }
    }
}

#[test]
fn tile_size_and_thread_count_do_not_change_the_result() {
    let hf = rough(70, 50, 2);
    let base = RefineSettings {
        seed: 5,
        ..Default::default()
    };
    let run = |threads: usize, tile: usize| {
        relief_testdata::with_threads(threads, || {
            refine(
                &hf,
                &RefineSettings {
                    tile,
                    ..base.clone()
                },
            )
            .unwrap()
        })
    };
    let a = run(1, 512);
    let b = run(2, 16);
    let c = run(2, 100);
    assert_eq!(bits(a.as_slice()), bits(b.as_slice()));
    assert_eq!(bits(a.as_slice()), bits(c.as_slice()));
    // A different seed changes the detail.
    let d = refine(&hf, &RefineSettings { seed: 6, ..base }).unwrap();
    assert_ne!(bits(a.as_slice()), bits(d.as_slice()));
}

#[test]
fn refined_terrain_keeps_the_input_as_its_coarse_levels_and_follows_equation_5() {
    let hf = rough(128, 96, 3);
    let s = RefineSettings {
        method: Method::Gsa,
        extra_levels: 2,
        seed: 11,
        ..RefineSettings::paper()
    };
    let (r, out) = refiner_and_output(&hf, &s);
    // Cell size divided by 4.
    assert_eq!(out.cell_size(), (7.5, 7.5));
    // Two forward levels of the refined terrain give back the input (the refinement only adds
    // detail levels) ...
    let g = Grid::from_heightfield(&out);
    let dec = wavedec2(&g, s.basis(), 2, Boundary::Symmetric).unwrap();
    let err = dec
        .approx
        .data
        .iter()
        .zip(hf.as_slice())
        .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
    assert!(err < 2e-3, "coarse levels changed by {err} m");
    // ... and the new detail levels have the variances of equation (5).
    let an = r.analysis();
    for (t, lvl) in dec.details.iter().enumerate() {
        let j = an.top_level as f64 + t as f64;
        for (b, band) in [&lvl.h, &lvl.v, &lvl.d].into_iter().enumerate() {
            let ms =
                band.data.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / band.data.len() as f64;
            let want = an.fits[b].variance_at(j);
            let ratio = ms / want;
            assert!(
                (0.9..1.1).contains(&ratio),
                "level {j} band {b}: {ms} vs {want}"
            );
        }
    }
    // The analysis of the refined terrain continues the same lines.
    let fit2 = analyze(&out, s.basis(), &FitSettings::default()).unwrap();
    assert_eq!(fit2.top_level, an.top_level + 2);
}

#[test]
fn zero_detail_lsa_on_flat_input_is_finite_and_flat() {
    // Flat "sea" on the left half, a rough coast on the right.
    let rough_hf = rough(96, 64, 4);
    let hf = Heightfield::from_fn(96, 64, 50.0, 90.0, |x, y| {
        if x < 48 {
            0.0
        } else {
            rough_hf.get(x, y) - 400.0
        }
    });
    for window in [1, 3, 5, 7] {
        let s = RefineSettings {
            method: Method::Lsa,
            window,
            seed: 1,
            ..Default::default()
        };
        let out = refine(&hf, &s).unwrap();
        assert!(
            out.as_slice().iter().all(|v| v.is_finite()),
            "window {window}"
        );
        // Far from the coast the sea stays flat (variance floor 1e-8 m^2).
        for y in 0..out.height() {
            for x in 0..120 {
                assert!(
                    out.get(x, y).abs() < 1e-2,
                    "sea at {x},{y}: {}",
                    out.get(x, y)
                );
            }
        }
        let maps = analyze_local(&hf, Wavelet::Cdf53, window, &FitSettings::default()).unwrap();
        for g in maps.gamma.iter().chain(maps.a.iter()) {
            assert!(g.data.iter().all(|v| v.is_finite()));
        }
        // Sea: the predicted variance of the first new level (J = 7) is negligible.
        let (g, a) = (maps.gamma[0].get(5, 30) as f64, maps.a[0].get(5, 30) as f64);
        assert!(
            (a - 7.0 * g).exp2() < 1e-6,
            "window {window}: gamma {g}, a {a}"
        );
        if window == 1 {
            // Every window at every level is pure sea: gamma 0 and the floor as variance.
            assert_eq!(g, 0.0);
            assert!((a - (1e-8f64).log2()).abs() < 1e-3);
        }
    }
    // A completely flat input works too.
    let flat = Heightfield::from_fn(64, 64, 10.0, 10.0, |_, _| 12.0);
    let out = refine(&flat, &RefineSettings::default()).unwrap();
    assert!(out.as_slice().iter().all(|v| (v - 12.0).abs() < 1e-2));
}

#[test]
fn bad_settings_and_inputs_are_errors() {
    let hf = rough(64, 64, 5);
    // One field out of range per case, the others at their defaults.
    let bad: [fn(&mut RefineSettings); 8] = [
        |s| s.window = 4,
        |s| s.window = 0,
        |s| s.extra_levels = 13,
        |s| s.tile = 2,
        |s| s.fit.variance_floor = 0.0,
        |s| (s.fit.gamma_min, s.fit.gamma_max) = (3.0, 1.0),
        |s| s.fine_levels = 1,
        |s| s.min_gamma = f64::NAN,
    ];
    for set in bad {
        let mut s = RefineSettings::default();
        set(&mut s);
        let e = Refiner::new(&hf, &s).unwrap_err();
        assert!(!e.to_string().is_empty());
    }
    // Too few levels for the fit asked for: a result from the levels available, with a note.
    let r = Refiner::new(
        &hf,
        &RefineSettings {
            fit: FitSettings {
                min_level: 5,
                ..Default::default()
            },
            ..RefineSettings::paper()
        },
    )
    .unwrap();
    assert!(
        r.notes().iter().any(|n| n.contains(">= 5")),
        "{:?}",
        r.notes()
    );
    assert!(r.render(&NoProgress).is_ok());
    // Voids.
    let mut holes = hf.clone();
    holes.set(3, 3, f32::NAN);
    assert!(matches!(
        Refiner::new(&holes, &RefineSettings::default()),
        Err(WaveletError::Heightfield(_))
    ));
    // Windows outside the output.
    let r = Refiner::new(&hf, &RefineSettings::default()).unwrap();
    assert!(r.render_window(250, 0, 10, 10).is_err());
    assert!(r.render_window(0, 0, 0, 10).is_err());
    assert!(
        wavedec2(
            &Grid::from_heightfield(&hf),
            Wavelet::Haar,
            max_levels(64, 64) + 1,
            Boundary::Symmetric
        )
        .is_err()
    );
}

#[test]
fn fits_serialise() {
    let hf = rough(64, 64, 6);
    let a = analyze(&hf, Wavelet::Cdf97, &FitSettings::default()).unwrap();
    let json = serde_json::to_string(&a).unwrap();
    let back: relief_wavelet_lod::GlobalAnalysis = serde_json::from_str(&json).unwrap();
    assert_eq!(back.fits.len(), 3);
    assert_eq!(back.top_level, 6);
    assert_eq!(back.levels.len(), 3);
    assert!(json.contains("\"gamma\""));
    assert!(json.contains("\"fractal_dimension\""));
    assert_eq!(
        back.fits[0].fractal_dimension,
        a.fits[0].fractal_dimension()
    );
}

#[test]
fn georeference_follows_the_vertex_aligned_lattice() {
    let mut hf = rough(64, 64, 7);
    hf.set_georef(Some(relief_heightfield::GeoRef {
        geotransform: Some([1000.0, 30.0, 0.0, 5000.0, 0.0, -30.0]),
        ..Default::default()
    }));
    // The spectral model is area-consistent: same extent, pixel-is-area.
    let r = Refiner::new(&hf, &RefineSettings::default()).unwrap();
    let out = r.render_window(8, 12, 16, 16).unwrap();
    let t = out.georef().unwrap().geotransform.unwrap();
    assert_eq!((t[0], t[3], t[1], t[5]), (1060.0, 4910.0, 7.5, -7.5));
    let r = Refiner::new(&hf, &RefineSettings::paper()).unwrap();
    let out = r.render_window(8, 12, 16, 16).unwrap();
    let t = out.georef().unwrap().geotransform.unwrap();
    assert_eq!((t[1], t[5]), (7.5, -7.5));
    // Refined sample (8, 12) is input sample (2, 3): same cell centre.
    let (cx, cy) = (t[0] + 0.5 * t[1], t[3] + 0.5 * t[5]);
    assert!((cx - (1000.0 + 2.5 * 30.0)).abs() < 1e-9, "{cx}");
    assert!((cy - (5000.0 - 3.5 * 30.0)).abs() < 1e-9, "{cy}");
    // And it keeps the input value there.
    assert!((out.get(0, 0) - hf.get(2, 3)).abs() < 50.0);
}

#[test]
fn strips_equal_the_full_run_and_sink_errors_stop_it() {
    let hf = rough(45, 38, 8);
    for method in [Method::Gsa, Method::Lsa] {
        let s = RefineSettings {
            method,
            tile: 40,
            seed: 3,
            ..Default::default()
        };
        let (r, full) = refiner_and_output(&hf, &s);
        let (ow, oh) = r.output_size();
        for strip in [1, 7, 64, 1000] {
            let mut got = Vec::with_capacity(ow * oh);
            let mut next = 0;
            r.render_strips::<WaveletError>(strip, &NoProgress, |y0, rows: &[f32]| {
                assert_eq!(y0, next);
                assert_eq!(rows.len() % ow, 0);
                next += rows.len() / ow;
                got.extend_from_slice(rows);
                Ok(())
            })
            .unwrap();
            assert_eq!(next, oh);
            assert_eq!(
                bits(&got),
                bits(full.as_slice()),
                "{method:?} strip {strip}"
            );
        }
        assert!(
            r.render_strips::<WaveletError>(0, &NoProgress, |_, _: &[f32]| Ok(()))
                .is_err()
        );
        let mut calls = 0;
        let err = r
            .render_strips::<SinkError>(16, &NoProgress, |_, _: &[f32]| {
                calls += 1;
                Err(SinkError::DiskFull)
            })
            .unwrap_err();
        assert!(matches!(err, SinkError::DiskFull) && calls == 1);
    }
}

#[derive(Debug)]
enum SinkError {
    #[allow(dead_code)]
    Wavelet(WaveletError),
    DiskFull,
}

impl From<WaveletError> for SinkError {
    fn from(e: WaveletError) -> Self {
        Self::Wavelet(e)
    }
}

#[test]
fn small_inputs_give_a_result_with_a_note() {
    for (w, h) in [(16, 16), (8, 8), (5, 3), (2, 2), (1, 1)] {
        let hf = rough(w, h, 9);
        for s in [RefineSettings::default(), RefineSettings::paper()] {
            let r = Refiner::new(&hf, &s).unwrap_or_else(|e| panic!("{w}x{h} {:?}: {e}", s.model));
            let out = r.render(&NoProgress).unwrap();
            assert_eq!((out.width(), out.height()), (4 * w, 4 * h));
            assert!(out.as_slice().iter().all(|v| v.is_finite()));
            assert!(!r.notes().is_empty(), "{w}x{h} {:?}: no note", s.model);
            // Windows still equal the full run.
            let win = r.render_window(1, 1, 2, 2).unwrap();
            assert_eq!(
                bits(win.as_slice()),
                bits(out.crop(1, 1, 2, 2).unwrap().as_slice())
            );
        }
    }
    // 16 x 16 has 4 levels: the spectral fit uses them (fewer than the 4 finest asked for only
    // when a level is empty), so the note is about the paper's `min_level`.
    let r = Refiner::new(&rough(16, 16, 9), &RefineSettings::default()).unwrap();
    assert!(r.synthesis_fits().iter().all(|f| f.levels_used >= 2));
}

#[test]
fn spectral_model_is_area_consistent() {
    let hf = rough(96, 80, 12);
    for levels in [1u32, 2, 3] {
        let s = RefineSettings {
            extra_levels: levels,
            seed: 4,
            ..Default::default()
        };
        let out = refine(&hf, &s).unwrap();
        let f = 1usize << levels;
        let down = out.downsample_box(f).unwrap();
        let rel = metrics::rmse(&down, &hf).unwrap() / hf.relief() as f64;
        // Without the correction step the same run is noticeably less consistent.
        let raw = refine(
            &hf,
            &RefineSettings {
                consistency: false,
                ..s.clone()
            },
        )
        .unwrap()
        .downsample_box(f)
        .unwrap();
        let rel_raw = metrics::rmse(&raw, &hf).unwrap() / hf.relief() as f64;
        // The smooth part inverts box-down(cubic(.)) exactly (up to f32 rounding), borders
        // included: every block mean is its input cell.
        assert!(
            rel < 1e-6,
            "x{f}: box-down differs from the input by {rel} of the relief"
        );
        let worst = worst_block_mean_error(&out, &hf, f);
        assert!(worst < 1e-4 * hf.relief(), "x{f}: worst cell {worst} m");
        assert!(
            rel < rel_raw,
            "x{f}: correction does not help ({rel} vs {rel_raw})"
        );
    }
}

#[test]
fn local_amplitude_keeps_flat_ground_smooth_and_its_knobs_act() {
    // Left half rough, right half a tilted plane (no detail at any level).
    let r = rough(128, 64, 3);
    let hf = Heightfield::from_fn(128, 64, 30.0, 30.0, |x, y| {
        if x < 64 {
            r.get(x, y)
        } else {
            500.0 + 2.0 * x as f32 + y as f32
        }
    });
    let run = |s: RefineSettings| {
        let s = RefineSettings {
            extra_levels: 3,
            seed: 11,
            ..s
        };
        let out = refine(&hf, &s).unwrap();
        // Away from the seam and the borders (the mirrored plane has a kink there): the
        // middle of each half, input cells [16, 48) x [16, 48) and [80, 112) x [16, 48).
        let left = out.crop(16 * 8, 16 * 8, 32 * 8, 32 * 8).unwrap();
        let right = out.crop(80 * 8, 16 * 8, 32 * 8, 32 * 8).unwrap();
        let e = |h: &Heightfield| {
            let b = h.width().min(h.height()) - 2;
            relief_wavelet_lod::quality::block_curvature(h, b)[0]
        };
        e(&right) / e(&left)
    };
    let default = run(RefineSettings::default());
    let follow = run(RefineSettings {
        amplitude_power: 1.0,
        amplitude_persistence: 1.0,
        ..Default::default()
    });
    let uniform = run(RefineSettings {
        amplitude_power: 0.0,
        ..Default::default()
    });
    let gsa = run(RefineSettings {
        method: Method::Gsa,
        ..Default::default()
    });
    // The plane gets almost none of the rough half's fine relief with the local amplitude,
    // a comparable share without it.
    assert!(follow < 0.02, "plane/rough curvature energy {follow}");
    assert!(default < 0.2, "plane/rough curvature energy {default}");
    assert!(uniform > 0.2 && gsa > 0.2, "uniform {uniform}, gsa {gsa}");
    // Persistence below 1 spreads the finest levels towards a uniform texture.
    assert!(default > follow, "default {default} vs follow {follow}");
}

#[test]
fn parent_conditioning_keeps_windows_threads_and_consistency() {
    let hf = rough(45, 37, 21);
    for extra in [2u32, 3] {
        let s = RefineSettings {
            extra_levels: extra,
            seed: 8,
            tile: 48,
            parent_conditioning: 1.0,
            ..Default::default()
        };
        let (r, full) = refiner_and_output(&hf, &s);
        let (ow, oh) = r.output_size();
        let windows = [
            [0, 0, 1, 1],
            [ow - 3, oh - 5, 3, 5],
            [7, 11, 33, 17],
            [ow / 2 + 1, 3, 20, 9],
        ];
        assert_windows_match(&r, &full, &windows, &format!("+{extra}"));
        let one = relief_testdata::with_threads(1, || {
            refine(
                &hf,
                &RefineSettings {
                    tile: 512,
                    ..s.clone()
                },
            )
            .unwrap()
        });
        assert_eq!(bits(one.as_slice()), bits(full.as_slice()));
        // Area consistency is untouched, and the setting acts.
        let f = 1usize << extra;
        let worst = worst_block_mean_error(&full, &hf, f);
        assert!(worst < 1e-4 * hf.relief(), "+{extra}: worst cell {worst} m");
        let free = refine(
            &hf,
            &RefineSettings {
                parent_conditioning: 0.0,
                ..s.clone()
            },
        )
        .unwrap();
        assert_ne!(bits(free.as_slice()), bits(full.as_slice()));
    }
}
