//! The sketch-structure step of synthesis ([`exemplar_structure`]): exemplar landforms between
//! the sketch's cell and its strokes, as coherent patches.

use relief_dictionary_learning::*;
use relief_heightfield::{Heightfield, NoProgress, metrics};
use relief_sparse_core::RasterSettings;
use relief_testdata::dem_crop;

/// A deterministic rough exemplar: octaves of Perlin noise (every patch distinct).
fn noise_exemplar(w: usize, h: usize) -> Heightfield {
    let p = noise::Perlin::new(7);
    Heightfield::from_fn(w, h, 30.0, 30.0, |x, y| {
        let (u, v) = (x as f64 / 23.0, y as f64 / 23.0);
        let mut s = 0.0;
        for o in 0..4 {
            let f = (1u32 << o) as f64;
            s += p.noise(u * f, v * f) / f;
        }
        (400.0 * s) as f32 + 1000.0
    })
}

/// A sketch cut from the exemplar (same cells, same range) gets the exemplar's own band at
/// the same place, away from its border: every patch matches its own position, continues its
/// neighbours, and the Hann blend of continuing bands is the exemplar's band.
#[test]
fn a_sketch_cut_from_the_exemplar_gets_its_own_band() {
    let ex = noise_exemplar(112, 96);
    let sketch = ex.crop(24, 24, 64, 48).unwrap();
    let range = ex.min_max().unwrap();
    let s = StructureSettings::default();
    let (out, report) = exemplar_structure(&sketch, &ex, ex.cell_size(), range, &s).unwrap();
    assert!(!report.self_similar && report.gain == 1.0, "{report:?}");
    assert_eq!(report.exemplar_size, (112, 96));
    // The band: the exemplar minus its Gaussian blur of R / 2 cells.
    let blur = ex.gaussian_blur(2.0).unwrap();
    let n = 16;
    let (mut worst, mut rms) = (0.0f32, 0.0f64);
    for y in n..48 - n {
        for x in n..64 - n {
            let band = ex.get(x + 24, y + 24) - blur.get(x + 24, y + 24);
            let added = out.get(x, y) - sketch.get(x, y);
            worst = worst.max((added - band).abs());
            rms += (band as f64).powi(2);
        }
    }
    let rms = (rms / ((64 - 2 * n) * (48 - 2 * n)) as f64).sqrt();
    assert!(rms > 10.0, "band RMS {rms}");
    assert!(
        worst < 0.05,
        "interior band differs by {worst} m (band RMS {rms:.1} m)"
    );
    assert!(report.continued > 0.9, "{report:?}");
}

/// Structure on a smooth painted sketch with a real exemplar: exemplar-sized relief between
/// the strokes (band RMS near the exemplar's own at that scale), the painted shape kept
/// (correlation of the output with the sketch), most patches continuing a neighbour, and a
/// synthesis whose slope histogram is closer to the exemplar's than without the step.
#[test]
fn structure_puts_exemplar_landforms_on_a_smooth_sketch() {
    let Some(ex) = dem_crop("alps_dem", 1300, 100, 1024, 640) else {
        return;
    };
    let sketch = Heightfield::from_fn(128, 64, 1.0, 1.0, |x, y| {
        let (u, v) = (x as f32 / 127.0, y as f32 / 63.0);
        let d = (v - 0.75 + 0.5 * u).abs();
        0.2 + 0.7 * (-(d / 0.15).powi(2)).exp()
    });
    let lib = SynthesisSettings::default();
    let run = |radius: f64| {
        let s = SynthesisSettings {
            amplify: AmplifySettings {
                steps: 2,
                dictionary: DictionaryChoice::learned(32, 1),
                ..lib.amplify
            },
            structure: StructureSettings {
                radius,
                ..Default::default()
            },
            // The structure step runs on the sketch's pixels (no landscape evolution).
            grow: None,
            ..lib
        };
        let (sct, fig) = synthesize_with_figures(&sketch, &ex, &s, &NoProgress).unwrap();
        (sct.rasterize(&RasterSettings::default()).unwrap(), fig)
    };
    let (with, fig) = run(4.0);
    let (without, fig0) = run(0.0);
    assert!(fig0.structure.is_none());
    let st = fig.structure.unwrap();
    assert!(st.continued > 0.5, "{st:?}");
    // The exemplar's own band at the grid the step used: RMS of the grid minus its blur.
    let e0 = relief_dictionary_learning::multires::box_resample(
        &ex,
        st.exemplar_size.0,
        st.exemplar_size.1,
    )
    .unwrap();
    let blur = e0.gaussian_blur(2.0).unwrap();
    let own = metrics::rmse(&e0, &blur).unwrap() * st.gain;
    assert!(
        st.band_rms > 0.5 * own && st.band_rms < 1.5 * own,
        "band RMS {:.1} m vs the exemplar's {own:.1} m",
        st.band_rms
    );
    let back = with.downsample_box(16).unwrap();
    let r = metrics::pearson(back.as_slice(), sketch.as_slice());
    assert!(r > 0.85, "correlation with the sketch {r}");
    let emd = |hf: &Heightfield| slope_emd(hf, &ex);
    let (a, b) = (emd(&with), emd(&without));
    assert!(
        a < 0.75 * b,
        "slope EMD to the exemplar {a:.2} deg with the structure, {b:.2} without"
    );
}

/// Earth mover's distance (degrees) between the slope histograms of two grids of the same
/// cell size.
fn slope_emd(a: &Heightfield, b: &Heightfield) -> f64 {
    let hist = |hf: &Heightfield| {
        let (cx, cy) = hf.cell_size();
        let mut h = vec![0.0f64; 90];
        let (w, ht) = (hf.width(), hf.height());
        for y in 1..ht - 1 {
            for x in 1..w - 1 {
                let gx = (hf.get(x + 1, y) - hf.get(x - 1, y)) as f64 / (2.0 * cx);
                let gy = (hf.get(x, y + 1) - hf.get(x, y - 1)) as f64 / (2.0 * cy);
                let d = gx.hypot(gy).atan().to_degrees();
                h[(d as usize).min(89)] += 1.0;
            }
        }
        let t: f64 = h.iter().sum();
        h.iter().map(|v| v / t).collect::<Vec<_>>()
    };
    let (ha, hb) = (hist(a), hist(b));
    let mut c = 0.0;
    ha.iter()
        .zip(&hb)
        .map(|(x, y)| {
            c += x - y;
            c.abs()
        })
        .sum()
}

/// Same bytes on 1 and 2 threads.
#[test]
fn structure_does_not_depend_on_thread_count() {
    let ex = noise_exemplar(120, 100);
    let sketch = Heightfield::from_fn(40, 24, 200.0, 200.0, |x, y| {
        1000.0 + 30.0 * x as f32 - 10.0 * y as f32
    });
    let run = |threads: usize, seed: u64| {
        relief_testdata::with_threads(threads, || {
            let s = StructureSettings { radius: 3.0, seed };
            exemplar_structure(&sketch, &ex, (30.0, 30.0), (900.0, 2400.0), &s)
                .unwrap()
                .0
        })
    };
    let a = run(1, 3);
    assert!(a.as_slice() == run(2, 3).as_slice());
    assert!(a.as_slice().iter().all(|v| v.is_finite()));
}

/// Bad settings and inputs are errors naming the problem.
#[test]
fn structure_rejects_bad_settings_and_inputs() {
    let ex = noise_exemplar(64, 64);
    let sketch = Heightfield::from_fn(16, 16, 100.0, 100.0, |x, _| x as f32);
    for r in [f64::NAN, -1.0, 0.5, 65.0, f64::INFINITY] {
        let s = StructureSettings {
            radius: r,
            ..Default::default()
        };
        let e = exemplar_structure(&sketch, &ex, (30.0, 30.0), (0.0, 1.0), &s).unwrap_err();
        assert!(e.to_string().contains("structure radius"), "{e}");
    }
    // 64 cells hold fewer than three 32-cell patches.
    let s = StructureSettings {
        radius: 8.0,
        ..Default::default()
    };
    let e = exemplar_structure(&sketch, &ex, (30.0, 30.0), (0.0, 1.0), &s).unwrap_err();
    assert!(e.to_string().contains("exemplar size"), "{e}");
    let mut holed = sketch.clone();
    holed.set(3, 3, f32::NAN);
    assert!(
        exemplar_structure(
            &holed,
            &ex,
            (30.0, 30.0),
            (0.0, 1.0),
            &StructureSettings::default()
        )
        .is_err()
    );
}

/// `sketch_cell_size` sets the sketch's extent: the output cell is it over `4^steps`, the
/// structure comes from the exemplar at that cell without self-similarity when the exemplar
/// covers it; a non-positive or non-finite one is an error naming it.
#[test]
fn sketch_cell_size_sets_the_extent() {
    let ex = noise_exemplar(160, 160);
    let sketch = Heightfield::from_fn(32, 16, 1.0, 1.0, |x, y| (x + y) as f32);
    let run = |cell: Option<(f64, f64)>| {
        let s = SynthesisSettings {
            amplify: AmplifySettings {
                steps: 1,
                radius: 2.0,
                dictionary: DictionaryChoice::learned(16, 1),
                ..SynthesisSettings::default().amplify
            },
            structure: StructureSettings {
                radius: 2.0,
                ..Default::default()
            },
            sketch_cell_size: cell,
            grow: None,
            ..Default::default()
        };
        synthesize_with_figures(&sketch, &ex, &s, &NoProgress)
    };
    let (sct, fig) = run(Some((60.0, 60.0))).unwrap();
    assert_eq!(sct.cell_size(), (15.0, 15.0));
    let st = fig.structure.unwrap();
    assert!(!st.self_similar, "{st:?}");
    assert!((st.exemplar_cell_size.0 - 60.0).abs() < 1.0, "{st:?}");
    // The default: the exemplar's 30 m cells times 4 per step, so the output has its cells.
    let (sct, _) = run(None).unwrap();
    assert_eq!(sct.cell_size(), (30.0, 30.0));
    for bad in [
        (0.0, 1.0),
        (f64::NAN, 5.0),
        (-3.0, -3.0),
        (f64::INFINITY, 1.0),
    ] {
        let e = run(Some(bad)).unwrap_err();
        assert!(e.to_string().contains("sketch_cell_size"), "{e}");
    }
}
