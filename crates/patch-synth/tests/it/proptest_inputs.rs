//! Property tests: random (often invalid) settings and parameters handed to every public entry
//! point never panic; setting errors name the field and its value; `quilt` gives the same bytes
//! on 1 and 2 threads. Exemplars are small crops of the Grand Canyon DEM (real data).

use std::sync::OnceLock;

use proptest::prelude::*;
use relief_heightfield::{Heightfield, NoProgress};
use relief_patch_synth::guide::{Seed, Stroke, gaussian_blur, guide_from_sketch, lowpass_resample};
use relief_patch_synth::kmeans::kmeans;
use relief_patch_synth::pca::Pca;
use relief_patch_synth::quality::{assess, guide_fidelity, seam_visibility, slope_distance};
use relief_patch_synth::{
    Blend, CategoryMap, Control, CutMethod, Exemplar, ExemplarIndex, OverlapShape, PatchSynthError,
    SeamMap, Settings, categorize_exemplars, min_error_cut, quilt, synthesize, validate,
};
use relief_testdata::dem_crop;

/// Every field name a setting error may report.
const FIELDS: &[&str] = &[
    "patch_size",
    "overlap",
    "alpha",
    "beta",
    "gamma",
    "lambda",
    "blocks",
    "guide_cells",
    "guide_lowpass",
    "kmeans_clusters",
    "kmeans_iterations",
    "pca_dims",
    "pca_samples",
    "knn",
    "rerank",
    "reuse_penalty",
    "reuse_radius",
    "probe_candidates",
    "survivors",
    "choice_tolerance",
    "min_candidates",
    "min_candidates_share",
    "validation_tolerance",
    "exemplar_stride",
    "blend.radius",
    "blend.max_iterations",
    "blend.decay",
    "crease_passes",
    "seed",
];

/// Two real exemplars (48 x 48 and 40 x 56 Grand Canyon crops) and a 64 x 64 crop for guides.
fn data() -> Option<&'static (Heightfield, Heightfield, Heightfield)> {
    static DATA: OnceLock<Option<(Heightfield, Heightfield, Heightfield)>> = OnceLock::new();
    DATA.get_or_init(|| {
        Some((
            dem_crop("grandcanyon", 40, 60, 48, 48)?,
            dem_crop("grandcanyon", 300, 200, 40, 56)?,
            dem_crop("grandcanyon", 180, 330, 64, 64)?,
        ))
    })
    .as_ref()
}

fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => 0.0f32..8.0,
        1 => Just(0.0f32),
        1 => -4.0f32..0.0,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
    ]
}

fn small(max: usize) -> impl Strategy<Value = usize> {
    prop_oneof![8 => 0..=max, 1 => Just(0usize), 1 => Just(100_000usize)]
}

/// Every kind of blend, with radii, iteration counts and decays drawn from the given strategies.
fn blends(
    radius: impl Strategy<Value = f32> + 'static,
    iterations: std::ops::RangeInclusive<usize>,
    decay: impl Strategy<Value = f32> + 'static,
) -> impl Strategy<Value = Blend> {
    prop_oneof![
        Just(Blend::None),
        radius.prop_map(|radius| Blend::Feather { radius }),
        iterations
            .clone()
            .prop_map(|max_iterations| Blend::Poisson { max_iterations }),
        (iterations, decay).prop_map(|(max_iterations, decay)| Blend::Screened {
            max_iterations,
            decay
        }),
    ]
}

fn settings() -> impl Strategy<Value = Settings> {
    let a = (
        prop_oneof![8 => 0usize..=40, 1 => Just(2000usize)],
        0usize..=24,
        any_f32(),
        any_f32(),
        any_f32(),
        prop_oneof![3 => 0.0f32..200.0, 1 => any_f32()],
        0usize..=8,
        0usize..=40,
    );
    let b = (
        prop_oneof![8 => 0usize..=24, 1 => Just(5000usize)],
        0usize..=6,
        prop_oneof![
            Just(4usize),
            Just(5),
            Just(6),
            Just(8),
            Just(12),
            Just(16),
            Just(0)
        ],
        0usize..=600,
        small(40),
        small(600),
        0usize..=12,
        any_f32(),
    );
    let c = (
        0usize..=800,
        prop_oneof![3 => Just(None), 1 => any_f32().prop_map(Some)],
        any::<bool>(),
        0usize..=4,
        any::<bool>(),
        blends(any_f32(), 0..=40, any_f32()),
        any::<u64>(),
    );
    (a, b, c).prop_map(|d| {
        let seed = d.2.6;
        Settings {
            // Sometimes set, sometimes out of (0, 1] (checked).
            min_candidates_share: (seed % 3 == 0).then(|| (seed % 100) as f32 / 50.0 - 0.5),
            // Drawn from the seed: the strategy tuples are full.
            rerank: (seed % 12) as usize,
            crease_passes: ((seed >> 8) % 4) as usize,
            // Sometimes out of range (checked).
            reuse_penalty: ((seed >> 12) % 7) as f32 * 40.0 - 40.0,
            reuse_radius: ((seed >> 16) % 80) as usize,
            // Sometimes NaN, negative or too large (checked).
            guide_lowpass: [
                None,
                Some(f32::NAN),
                Some(-1.0),
                Some(0.0),
                Some(24.0),
                Some(2000.0),
            ][(seed >> 24) as usize % 6],
            ..drawn(d)
        }
    })
}

/// The settings fields both strategies draw, in the order they draw them.
type Drawn = (
    (usize, usize, f32, f32, f32, f32, usize, usize),
    (usize, usize, usize, usize, usize, usize, usize, f32),
    (usize, Option<f32>, bool, usize, bool, Blend, u64),
);

/// Settings of the drawn fields; the fields derived from the seed are the caller's (zero here).
fn drawn((a, b, c): Drawn) -> Settings {
    Settings {
        patch_size: a.0,
        overlap: a.1,
        alpha: a.2,
        beta: a.3,
        gamma: a.4,
        lambda: a.5,
        blocks: a.6,
        guide_cells: a.7,
        kmeans_clusters: b.0,
        kmeans_iterations: b.1,
        pca_dims: b.2,
        pca_samples: b.3,
        knn: b.4,
        probe_candidates: b.5,
        survivors: b.6,
        choice_tolerance: b.7,
        min_candidates: c.0,
        min_candidates_share: None,
        guide_lowpass: None,
        validation_tolerance: c.1,
        enforce_validation: c.2,
        exemplar_stride: c.3,
        cut: if c.4 {
            CutMethod::Greedy
        } else {
            CutMethod::DynamicProgramming
        },
        blend: c.5,
        rerank: 0,
        crease_passes: 0,
        reuse_penalty: 0.0,
        reuse_radius: 0,
        seed: c.6,
    }
}

/// Settings drawn from the valid ranges (the synthesis path runs on most of them).
fn valid_settings() -> impl Strategy<Value = Settings> {
    // The same draws as `settings`, regrouped into its layout (regrouping draws nothing).
    let a = (
        (8usize..=40).prop_flat_map(|p| (Just(p), 1..p.div_ceil(2))),
        (0.0f32..8.0, 0.0f32..8.0, 0.01f32..8.0),
        0.0f32..200.0,
        1usize..=4,
        1usize..=8,
    )
        .prop_map(|((p, o), (al, be, ga), la, bl, gc)| (p, o, al, be, ga, la, bl, gc));
    let b = (
        1usize..=24,
        1usize..=6,
        prop_oneof![Just(4usize), Just(6), Just(8), Just(12), Just(16)],
        32usize..=600,
        1usize..=40,
        1usize..=600,
        1usize..=12,
        0.0f32..1.0,
    );
    let c = (
        1usize..=800,
        prop_oneof![Just(None), (1.0f32..300.0).prop_map(Some)],
        any::<bool>(),
        1usize..=4,
        any::<bool>(),
        blends(0.5f32..6.0, 1..=40, 1.0f32..40.0),
        any::<u64>(),
    );
    (a, b, c).prop_map(|d| {
        let seed = d.2.6;
        Settings {
            rerank: 1 + (seed % 12) as usize,
            crease_passes: ((seed >> 8) % 3) as usize,
            reuse_penalty: ((seed >> 12) % 4) as f32 * 0.5,
            reuse_radius: ((seed >> 16) % 5) as usize,
            guide_lowpass: [None, Some(0.0), Some(4.0), Some(24.0)][(seed >> 24) as usize % 4],
            ..drawn(d)
        }
    })
}

/// Half valid settings, half anything (mostly invalid).
fn mixed_settings() -> impl Strategy<Value = Settings> {
    prop_oneof![valid_settings(), settings()]
}

/// A setting error names a known field and shows the offending value.
fn check_names_field(err: &PatchSynthError) -> Result<(), TestCaseError> {
    check_names(err, &[])
}

/// [`check_names_field`] that also accepts the function parameters `extra`.
fn check_names(err: &PatchSynthError, extra: &[&str]) -> Result<(), TestCaseError> {
    if let PatchSynthError::InvalidParameter { name, value, .. } = err {
        prop_assert!(
            FIELDS.contains(name) || extra.contains(name),
            "unknown field {name}"
        );
        let msg = err.to_string();
        prop_assert!(
            msg.contains(&format!("`{name}` = {value}")),
            "message does not show field and value: {msg}"
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    /// Random settings through check, build, validate and synthesize (guided or not, with or
    /// without a categorisation map, random output size): no panic; errors name field and value;
    /// the index refuses exactly the settings `check` refuses.
    #[test]
    fn random_settings_never_panic(
        s in mixed_settings(),
        (w, h) in prop_oneof![8 => (1usize..=72, 1usize..=72), 1 => Just((100_000usize, 100_000usize))],
        guided in any::<bool>(),
        void_guide in prop::bool::weighted(0.1),
        map_cat in prop_oneof![Just(None), (0u16..=2).prop_map(Some), Just(Some(u16::MAX))],
    ) {
        let Some((a, b, g)) = data() else { return Ok(()) };
        let checked = s.check();
        if let Err(e) = &checked {
            check_names_field(e)?;
            prop_assert!(matches!(e, PatchSynthError::InvalidParameter { .. }), "{e}");
        }
        let ex = vec![Exemplar::new(a.clone(), 0), Exemplar::new(b.clone(), 1)];
        let built = ExemplarIndex::build(ex.clone(), &s, &NoProgress);
        match (&checked, &built) {
            (Err(e1), Err(e2)) => prop_assert_eq!(e1.to_string(), e2.to_string()),
            (Err(e1), Ok(_)) => prop_assert!(false, "build accepted settings check refused: {}", e1),
            (Ok(()), Err(e)) => {
                // Only the exemplars can be at fault now (too small for the patch).
                prop_assert!(matches!(e, PatchSynthError::BadExemplar { .. }), "{e}");
                prop_assert!(s.patch_size > 40, "{e}");
            }
            (Ok(()), Ok(_)) => {}
        }
        // Control: guide from the real crop resized to w x h (when small enough).
        let mut control = if guided && w <= 72 {
            let mut gg = g.resample(w, h).map_err(|e| TestCaseError::fail(e.to_string()))?;
            if void_guide {
                gg.set(0, 0, f32::NAN);
            }
            Control::guided(gg)
        } else {
            Control::unguided(w, h)
        };
        if let Some(c) = map_cat {
            control = control.with_categories(CategoryMap::uniform(w.min(72), h.min(72), c));
        }
        if let Ok(index) = &built {
            // Patch search with a region that may not fit the patch.
            let p = s.patch_size;
            let region: Vec<f32> = g.as_slice().iter().copied().cycle().take(p * p + (w % 3) / 2).collect();
            for shape in [OverlapShape::Left, OverlapShape::Top, OverlapShape::Both] {
                match index.nearest_overlaps(shape, &region, s.knn, s.rerank) {
                    Ok(near) => {
                        prop_assert_eq!(region.len(), p * p);
                        prop_assert!(!near.is_empty() && near.len() <= s.knn);
                    }
                    Err(e) => check_names_field(&e)?,
                }
            }
            match validate(index, &control, &s) {
                Ok(rep) => {
                    prop_assert_eq!(rep.failing.len(), rep.blocks.iter().filter(|b| b.candidates < s.min_candidates).count());
                }
                Err(e) => check_names_field(&e)?,
            }
            match synthesize(index, &control, &s, &NoProgress) {
                Ok(out) => {
                    prop_assert_eq!((out.heightfield.width(), out.heightfield.height()), (w, h));
                    prop_assert!(out.heightfield.as_slice().iter().all(|v| v.is_finite()));
                    prop_assert_eq!(out.seam_map.seam.len(), w * h);
                }
                Err(e) => {
                    check_names_field(&e)?;
                    // A valid setup only fails for a named reason.
                    prop_assert!(
                        matches!(
                            e,
                            PatchSynthError::InvalidControl { .. }
                                | PatchSynthError::Validation(_)
                                | PatchSynthError::NoCandidates { .. }
                        ),
                        "{e}"
                    );
                }
            }
        }
        // The one-call entry point agrees with check on the settings.
        if checked.is_err() {
            prop_assert!(quilt(ex, &control, &s, &NoProgress).is_err());
        }
    }

    /// Random parameters to the guide, category, clustering, PCA, cut and quality entry points:
    /// errors instead of panics, parameter errors naming the parameter.
    #[test]
    fn other_entry_points_never_panic(
        factor in small(80),
        sigma in prop_oneof![4 => any_f32(), 1 => Just(1e5f32), 1 => 0.1f32..20.0],
        k in small(50),
        s in mixed_settings(),
        rows in 0usize..=12,
        cols in 0usize..=12,
        extra in 0usize..=2,
        lo in 0usize..=14,
        hi in 0usize..=14,
        errs in prop::collection::vec(any_f32(), 0..=160),
        dim in 0usize..=6,
        data_len in 0usize..=60,
        sw in 0usize..=40,
        sh in 0usize..=40,
        seeds in prop::collection::vec((any_f32(), any_f32(), any_f32(), any_f32()), 0..=3),
        stroke in prop::collection::vec((any_f32(), any_f32(), any_f32()), 0..=3),
        far in prop::bool::weighted(0.1),
    ) {
        let Some((a, b, g)) = data() else { return Ok(()) };
        let named = |r: Result<(), PatchSynthError>| -> Result<(), TestCaseError> {
            if let Err(e) = r {
                check_names(&e, &["factor", "sigma", "k"])?;
            }
            Ok(())
        };
        named(lowpass_resample(g, factor).map(|_| ()))?;
        named(gaussian_blur(g, sigma).map(|_| ()))?;
        named(CategoryMap::from_guide_heights(g, k, 3).map(|_| ()))?;
        named(CategoryMap::from_raster(sw, sh, vec![0; (sw * sh + extra) % 2000]).map(|_| ()))?;
        named(categorize_exemplars(&[a.clone(), b.clone()], k, &s).map(|_| ()))?;
        // Cut: a grid that may not match rows x cols.
        let n = (rows * cols + extra).min(errs.len());
        let grid: Vec<f32> = errs[..n].to_vec();
        for m in [CutMethod::DynamicProgramming, CutMethod::Greedy] {
            match min_error_cut(&grid, rows, cols, lo, hi, m) {
                Ok(c) => {
                    prop_assert_eq!(grid.len(), rows * cols);
                    prop_assert_eq!(c.path.len(), if cols == 0 { 0 } else { rows });
                    for w2 in c.path.windows(2) {
                        prop_assert!(w2[0].abs_diff(w2[1]) <= 1);
                    }
                    prop_assert!(c.path.iter().all(|&p| p < cols.max(1)));
                }
                Err(e) => prop_assert!(grid.len() != rows * cols, "{e}"),
            }
        }
        // k-means and PCA on data built from the real crop.
        let vals: Vec<f32> = g.as_slice()[..data_len].to_vec();
        let km = kmeans(&vals, dim, k.min(64), 3, 1);
        if dim > 0 && vals.len() >= dim {
            prop_assert!(km.k() >= 1 && km.k() <= (vals.len() / dim).max(1));
            prop_assert_eq!(km.labels.len(), vals.len() / dim);
        }
        let _ = Pca::fit(&vals, dim, k.min(8));
        // Sketch guide with random seeds and strokes (maybe non-finite or far away).
        let seeds: Vec<Seed> = seeds
            .into_iter()
            .map(|(x, y, hgt, r)| Seed { x: x * 5.0, y: y * 5.0, height: hgt * 100.0, radius: r })
            .collect();
        let mut pts: Vec<(f32, f32, f32)> = stroke.iter().map(|&(x, y, v)| (x * 5.0, y * 5.0, v)).collect();
        if far && !pts.is_empty() {
            pts[0].0 = 3e38;
        }
        named(guide_from_sketch(sw, sh, (30.0, 30.0), &seeds, &[Stroke { points: pts }], sigma.min(50.0)).map(|_| ()))?;
        // Quality measures with mismatched or degenerate inputs.
        let seams = SeamMap { width: sw, height: sh, seam: vec![true; sw * sh], source: vec![0; sw * sh] };
        named(seam_visibility(g, &seams).map(|_| ()))?;
        named(guide_fidelity(g, a, factor).map(|_| ()))?;
        let _ = slope_distance(g, &[]);
        named(assess(g, &seams, g, factor, &[a, b], None).map(|_| ()))?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]

    /// `quilt` (index + synthesis) gives identical bytes, seam maps and placements on 1 and 2
    /// rayon threads, for random seeds, patch sizes and blends.
    #[test]
    fn quilt_is_thread_count_independent(
        seed in any::<u64>(),
        patch in prop_oneof![Just(12usize), Just(16), Just(20)],
        poisson in any::<bool>(),
    ) {
        let Some((a, b, g)) = data() else { return Ok(()) };
        let s = Settings {
            patch_size: patch,
            overlap: patch / 4,
            kmeans_clusters: 6,
            pca_samples: 400,
            min_candidates: 20,
            enforce_validation: false,
            blend: if poisson { Blend::Poisson { max_iterations: 60 } } else { Blend::Feather { radius: 1.5 } },
            seed,
            ..Settings::default()
        };
        let control = Control::guided(lowpass_resample(g, 4).unwrap());
        let run = |threads: usize| {
            relief_testdata::with_threads(threads, || {
                quilt(
                    vec![Exemplar::new(a.clone(), 0), Exemplar::new(b.clone(), 0)],
                    &control,
                    &s,
                    &NoProgress,
                )
                .unwrap()
            })
        };
        let (one, two) = (run(1), run(2));
        let bytes = |h: &Heightfield| relief_heightfield::bytes::f32_to_le_bytes(h.as_slice());
        prop_assert_eq!(bytes(&one.heightfield), bytes(&two.heightfield));
        prop_assert_eq!(&one.seam_map, &two.seam_map);
        prop_assert_eq!(&one.placements, &two.placements);
    }
}

/// Exemplar heights far beyond any unit (1e25, whose squared differences overflow f32 and used
/// to end in a panic choosing among non-finite energies) are refused by name.
#[test]
fn absurd_exemplar_heights_are_refused_not_a_panic() {
    let hf = Heightfield::from_fn(64, 64, 10.0, 10.0, |x, y| 1e25 + (x * y) as f32 * 1e22);
    let e = ExemplarIndex::build(
        vec![Exemplar::new(hf, 0)],
        &Settings::default(),
        &NoProgress,
    )
    .unwrap_err();
    assert!(
        matches!(e, PatchSynthError::BadExemplar { .. }) && e.to_string().contains("beyond"),
        "{e}"
    );
}
