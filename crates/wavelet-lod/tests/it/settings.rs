//! Settings validation: random (often absurd) settings and arguments handed to every public
//! entry point never panic; they either work (and then give finite values) or return an error
//! whose message names the offending field and its value.

use proptest::prelude::*;
use relief_heightfield::{Heightfield, NoProgress, ParamError};
use relief_wavelet_lod::rng::{fill_normals, normal_at};
use relief_wavelet_lod::{
    Boundary, Decomposition, FitSettings, Grid, Method, Model, RefineSettings, Refiner, Wavelet,
    WaveletError, analyze, analyze_local, dwt1, idwt1, max_levels, refine_window,
    render_log_variance_plot, size_at_depth, try_waverec2, wavedec2,
};

/// Floats from every class: ordinary, tiny, huge, zero, negative, infinite, NaN.
fn wild_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -20.0f64..20.0,
        1 => Just(0.0),
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(1e300),
        1 => Just(-1e300),
        1 => Just(1e-300),
        1 => Just(1e-8),
    ]
}

fn wild_usize() -> impl Strategy<Value = usize> {
    prop_oneof![
        6 => 0usize..40,
        1 => Just(usize::MAX),
        1 => Just(usize::MAX / 2),
        1 => 40usize..100_000,
    ]
}

fn wavelet() -> impl Strategy<Value = Wavelet> {
    prop::sample::select(Wavelet::ALL.to_vec())
}

fn fit_settings() -> impl Strategy<Value = FitSettings> {
    (
        prop_oneof![5 => 0u32..8, 1 => Just(u32::MAX), 1 => 8u32..100],
        wild_usize(),
        wild_f64(),
        wild_f64(),
        wild_f64(),
    )
        .prop_map(
            |(min_level, levels, variance_floor, gamma_min, gamma_max)| FitSettings {
                min_level,
                levels,
                variance_floor,
                gamma_min,
                gamma_max,
            },
        )
}

fn refine_settings() -> impl Strategy<Value = RefineSettings> {
    (
        wavelet(),
        prop::bool::ANY,
        prop_oneof![3 => prop::sample::select(vec![1usize, 3, 5, 7]), 2 => wild_usize()],
        prop_oneof![6 => 0u32..4, 1 => 4u32..80, 1 => Just(u32::MAX)],
        any::<u64>(),
        prop_oneof![
            3 => Just(FitSettings::default()),
            2 => fit_settings()
        ],
        prop_oneof![3 => Just(512usize), 2 => 16usize..200, 2 => wild_usize()],
        (
            prop::bool::ANY,
            prop_oneof![3 => Just(3usize), 1 => 0usize..12],
            prop_oneof![3 => Just(2.0f64), 1 => -1.0f64..9.0],
            prop::bool::ANY,
        ),
        (
            prop_oneof![3 => Just(1.0f64), 1 => -1.0f64..5.0],
            prop_oneof![3 => Just(0.6f64), 1 => -0.5f64..1.5],
            prop_oneof![3 => Just(0.0f64), 1 => -0.5f64..2.5],
        ),
    )
        .prop_map(
            |(
                wavelet,
                gsa,
                window,
                extra_levels,
                seed,
                fit,
                tile,
                (paper, fine_levels, min_gamma, consistency),
                (amplitude_power, amplitude_persistence, parent_conditioning),
            )| RefineSettings {
                model: if paper { Model::Paper } else { Model::Spectral },
                wavelet: Some(wavelet),
                method: if gsa { Method::Gsa } else { Method::Lsa },
                window,
                extra_levels,
                seed,
                fit,
                tile,
                fine_levels,
                min_gamma,
                consistency,
                amplitude_power,
                amplitude_persistence,
                parent_conditioning,
            },
        )
}

/// A small terrain, sometimes with voids or extreme elevations.
fn terrain() -> impl Strategy<Value = Heightfield> {
    (1usize..70, 1usize..70, any::<u64>(), 0u8..10).prop_map(|(w, h, seed, kind)| {
        let amp = match kind {
            0 => 0.0,   // flat
            1 => 1e30,  // absurd elevations
            _ => 300.0, // terrain-like
        };
        let mut hf = Heightfield::from_fn(w, h, 30.0, 30.0, |x, y| {
            let z = seed
                .wrapping_add((x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
                .wrapping_add((y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F));
            let z = (z ^ (z >> 31)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            let r = ((z >> 40) as f32 / 16_777_216.0) - 0.5;
            amp * r + (x as f32 * 0.3).sin() * amp * 0.5
        });
        if kind == 2 {
            hf.set(w / 2, h / 2, f32::NAN);
        }
        hf
    })
}

/// Field names the crate's `InvalidParameter` errors may carry.
const FIELDS: &[&str] = &[
    "window",
    "extra_levels",
    "tile",
    "variance_floor",
    "gamma_min",
    "gamma_max",
    "min_level",
    "levels",
    "signal",
    "high",
    "input",
    "decomposition",
    "strip",
    "fine_levels",
    "min_gamma",
    "amplitude_power",
    "amplitude_persistence",
    "parent_conditioning",
];

/// Every error names what is wrong: the field and its value for parameter errors.
fn check_error(e: &WaveletError) {
    let msg = e.to_string();
    assert!(!msg.is_empty());
    assert!(!msg.contains('\n'), "one line: {msg}");
    if let WaveletError::InvalidParameter(ParamError { name, value, .. }) = e {
        assert!(FIELDS.contains(name), "unexpected field name {name}");
        assert!(msg.contains(name) && msg.contains(value.as_str()), "{msg}");
    }
}

fn finite(v: &[f32]) -> bool {
    v.iter().all(|x| x.is_finite())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn refiner_never_panics(hf in terrain(), s in refine_settings(),
                            win in (wild_usize(), wild_usize(), wild_usize(), wild_usize())) {
        match Refiner::new(&hf, &s) {
            Err(e) => check_error(&e),
            Ok(r) => {
                let (ow, oh) = r.output_size();
                if ow * oh <= 1 << 18 {
                    let out = r.render(&NoProgress).unwrap();
                    prop_assert!(finite(out.as_slice()), "non-finite output for {s:?}");
                    let mut rows = 0;
                    match r.render_strips::<WaveletError>(win.2, &NoProgress, |_, v: &[f32]| {
                        rows += v.len() / ow;
                        Ok(())
                    }) {
                        Err(e) => check_error(&e),
                        Ok(()) => prop_assert_eq!(rows, oh),
                    }
                }
                match r.render_window(win.0, win.1, win.2, win.3) {
                    Err(e) => check_error(&e),
                    Ok(w) => prop_assert!(finite(w.as_slice())),
                }
                if let Some(maps) = r.local_maps() {
                    prop_assert!(maps.gamma.iter().all(|g| finite(&g.data)));
                    prop_assert!(maps.a.iter().all(|g| finite(&g.data)));
                }
            }
        }
        if let Err(e) = refine_window(&hf, &s, win.0, win.1, win.2.min(64), win.3.min(64)) {
            check_error(&e);
        }
    }

    #[test]
    fn analysis_never_panics(hf in terrain(), wl in wavelet(), fit in fit_settings(),
                             window in wild_usize(), plot in (wild_usize(), wild_usize(), 0u32..20)) {
        match analyze(&hf, wl, &fit) {
            Err(e) => check_error(&e),
            Ok(a) => {
                prop_assert!(a.fits.iter().all(|f| f.gamma.is_finite() && f.a.is_finite()));
                let rgb = render_log_variance_plot(&a, plot.2, Some(&a), plot.0, plot.1);
                prop_assert_eq!(rgb.len() % 3, 0);
                prop_assert!(rgb.len() >= 64 * 64 * 3);
            }
        }
        match analyze_local(&hf, wl, window, &fit) {
            Err(e) => check_error(&e),
            Ok(m) => prop_assert!(m.gamma.iter().chain(&m.a).all(|g| finite(&g.data))),
        }
    }

    #[test]
    fn transforms_never_panic(w in 0usize..40, h in 0usize..40, extra in 0usize..3,
                              wl in wavelet(), periodic in prop::bool::ANY, levels in wild_usize(),
                              n_low in 0usize..20, n_high in 0usize..20) {
        let boundary = if periodic { Boundary::Periodic } else { Boundary::Symmetric };
        let data: Vec<f32> = (0..w * h + extra).map(|i| (i as f32 * 0.37).sin() * 10.0).collect();
        let g = Grid { width: w, height: h, data: data.clone() };
        match wavedec2(&g, wl, levels, boundary) {
            Err(e) => check_error(&e),
            Ok(dec) => {
                let back = try_waverec2(&dec).unwrap();
                prop_assert_eq!((back.width, back.height), (w, h));
            }
        }
        if let Err(e) = Grid::new(w, h, data.clone()) {
            check_error(&e);
            prop_assert!(extra > 0);
        }
        match dwt1(&data[..n_low.min(data.len())], wl, boundary) {
            Err(e) => check_error(&e),
            Ok((lo, hi)) => prop_assert_eq!(lo.len() + hi.len(), n_low.min(data.len())),
        }
        let low = vec![1.0f32; n_low];
        let high = vec![0.5f32; n_high];
        match idwt1(&low, &high, wl, boundary) {
            Err(e) => check_error(&e),
            Ok(x) => prop_assert_eq!(x.len(), n_low + n_high),
        }
        prop_assert!(size_at_depth(w, levels.min(200)) <= w.max(1));
        prop_assert!(max_levels(w, h) <= 64);
    }

    /// A decomposition edited by hand (or deserialised from an untrusted file) with inconsistent
    /// shapes is an error of `try_waverec2`, not a panic.
    #[test]
    fn inconsistent_decompositions_are_errors(w in 1usize..30, h in 1usize..30, wl in wavelet(),
                                              edit in 0usize..6, by in 1usize..3) {
        let g = Grid { width: w, height: h, data: vec![1.0; w * h] };
        let levels = max_levels(w, h).min(3);
        let mut dec: Decomposition = wavedec2(&g, wl, levels, Boundary::Symmetric).unwrap();
        match edit {
            0 => dec.width += by,
            1 => dec.height += by,
            2 => { dec.approx.data.pop(); }
            3 => if let Some(l) = dec.details.first_mut() { l.h.width += by; },
            4 => if let Some(l) = dec.details.last_mut() { l.d.data.push(0.0); },
            _ => dec.boundary = Boundary::Periodic,
        }
        match try_waverec2(&dec) {
            Err(e) => check_error(&e),
            Ok(back) => prop_assert_eq!((back.width, back.height), (dec.width, dec.height)),
        }
    }

    #[test]
    fn names_and_hash_never_panic(name in ".{0,12}", key in any::<u64>(), x0 in any::<usize>(),
                                  n in 0usize..300) {
        if let Err(e) = Wavelet::from_name(&name) {
            check_error(&e);
            prop_assert!(e.to_string().contains(name.as_str()));
        }
        // Positions wrap around at usize::MAX, and the block fill equals the pointwise values.
        let mut out = vec![0.0f32; n];
        fill_normals(key, x0, &mut out);
        for (k, v) in out.iter().enumerate() {
            prop_assert_eq!(v.to_bits(), normal_at(key, x0.wrapping_add(k)).to_bits());
        }
    }
}

#[test]
fn absurd_elevations_are_rejected_naming_the_input() {
    let hf = Heightfield::from_fn(64, 64, 30.0, 30.0, |x, _| x as f32 * 1e30);
    let e = Refiner::new(&hf, &RefineSettings::default()).unwrap_err();
    check_error(&e);
    assert!(e.to_string().contains("input"), "{e}");
}
