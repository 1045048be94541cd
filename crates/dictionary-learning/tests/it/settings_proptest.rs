//! Random settings (valid, boundary and absurd values, NaN and infinities) handed to every
//! public entry point: nothing panics, an out-of-range field is an `Err` that names that field
//! (in the variant and in the message), and valid settings never give `InvalidParameter`.
//! Terrains are small real crops (alps_dem) so each case stays fast.

use proptest::prelude::*;
use relief_dictionary_learning::*;
use relief_heightfield::{Heightfield, Kernel, NoProgress};
use relief_sparse_core::{PatchGeometry, extract_patches};
use relief_testdata::dem_crop;

fn alps(x: usize, y: usize, w: usize, h: usize) -> Heightfield {
    // Synthetic stand-in only when the data set is absent outside CI (dem_crop panics in CI).
    dem_crop("alps_dem", x, y, w, h).unwrap_or_else(|| {
        Heightfield::from_fn(w, h, 30.0, 30.0, |i, j| {
            let (u, v) = ((i + x) as f32 * 0.21, (j + y) as f32 * 0.17);
            900.0 + 120.0 * u.sin() * v.cos() + 40.0 * (2.3 * u + v).sin()
        })
    })
}

/// Checks one result: `invalid` lists the fields that are out of range (with whether each
/// is); an error naming a field must name an out-of-range one, and if any field is out of
/// range the call must fail.
fn check<T>(r: &Result<T>, invalid: &[(&str, bool)]) -> std::result::Result<(), TestCaseError> {
    let bad: Vec<&str> = invalid.iter().filter(|f| f.1).map(|f| f.0).collect();
    match r {
        Ok(_) => prop_assert!(bad.is_empty(), "accepted invalid {bad:?}"),
        Err(e @ LearnError::InvalidParameter { name, .. }) => {
            prop_assert!(
                bad.contains(name),
                "error names `{name}` but the invalid fields are {bad:?}: {e}"
            );
            prop_assert!(e.to_string().contains(name), "{e}");
        }
        Err(_) => {}
    }
    Ok(())
}

fn usize_edge(lo: usize, hi: usize) -> impl Strategy<Value = usize> {
    prop_oneof![1 => Just(0usize), 5 => lo..hi, 1 => Just(hi + 50), 1 => Just(usize::MAX)]
}

fn f64_edge(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => lo..hi,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(-1.0),
        1 => Just(0.0),
        1 => Just(hi * 10.0),
    ]
}

fn signals() -> ndarray::Array2<f32> {
    let hf = alps(400, 300, 48, 48);
    extract_patches(
        &hf,
        &PatchGeometry {
            step: 2.0,
            ..PatchGeometry::with_patch_size(6)
        },
    )
    .unwrap()
    .matrix
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn ksvd_settings(
        n_atoms in usize_edge(1, 40),
        sparsity in usize_edge(1, 6),
        iterations in 0usize..3,
        dup in f64_edge(0.5, 1.0),
        exact in any::<bool>(),
        seed in any::<u64>(),
    ) {
        let sig = signals();
        let s = KsvdSettings {
            n_atoms,
            sparsity,
            iterations,
            duplicate_threshold: dup,
            variant: if exact { KsvdVariant::Exact } else { KsvdVariant::Approximate },
            seed,
        };
        let r = ksvd(sig.view(), &s, &NoProgress);
        check(&r, &[
            ("n_atoms", n_atoms == 0),
            ("sparsity", sparsity == 0 || sparsity > n_atoms || sparsity > 64),
            ("duplicate_threshold", !(dup > 0.0 && dup <= 1.0)),
        ])?;
        if n_atoms > 0 && n_atoms <= sig.nrows() && (1..=n_atoms.min(64)).contains(&sparsity)
            && dup > 0.0 && dup <= 1.0
        {
            prop_assert!(r.is_ok(), "{:?}", r.err());
        }
    }

    #[test]
    fn constrained_settings(
        n_atoms in usize_edge(1, 40),
        sparsity in usize_edge(1, 4),
        iterations in 0usize..3,
        seed in any::<u64>(),
    ) {
        let sig = signals();
        let s = ConstrainedSettings { n_atoms, sparsity, iterations, seed };
        let r = constrained_learning(sig.view(), sig.view(), &s, &NoProgress);
        check(&r, &[
            ("n_atoms", n_atoms == 0),
            ("sparsity", sparsity == 0 || sparsity > n_atoms || sparsity > 64),
        ])?;
    }

    #[test]
    fn noise_baseline_settings(factor in usize_edge(2, 9), gain in f64_edge(0.0, 2.0), seed in any::<u64>()) {
        let coarse = alps(600, 200, 12, 10);
        let r = noise_amplify(&coarse, &NoiseBaselineSettings { factor, gain, seed });
        check(&r, &[
            ("factor", !(2..=256).contains(&factor)),
            ("gain", !(gain.is_finite() && gain >= 0.0)),
        ])?;
        if (2..=8).contains(&factor) && gain.is_finite() && gain >= 0.0 {
            let out = r.unwrap();
            prop_assert_eq!((out.width(), out.height()), (12 * factor, 10 * factor));
            prop_assert!(out.as_slice().iter().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn procedural_settings(
        family in prop_oneof![Just(NoiseFamily::Perlin), Just(NoiseFamily::RidgedSum), Just(NoiseFamily::RidgedMultifractal)],
        n_candidates in prop_oneof![1 => Just(0usize), 5 => 1usize..48, 1 => Just(70_000)],
        learned in prop_oneof![2 => Just(None), 1 => Just(Some(0usize)), 3 => (1usize..12).prop_map(Some), 1 => Just(Some(usize::MAX))],
        iterations in 0usize..2,
        patch_size in prop_oneof![1 => Just(0usize), 1 => Just(1), 5 => 2usize..9, 1 => Just(65)],
        sparsity in prop_oneof![1 => Just(0usize), 5 => 1usize..3, 1 => Just(65)],
        seed in any::<u64>(),
    ) {
        let hf = alps(900, 500, 24, 24);
        let s = ProceduralSettings {
            family, n_candidates, learned_atoms: learned, iterations, patch_size, sparsity, seed,
        };
        let r = fit_procedural(&hf, &s, &NoProgress);
        let n_dict = learned.unwrap_or(n_candidates);
        check(&r, &[
            ("n_candidates", n_candidates == 0 || n_candidates > 1 << 16),
            ("patch_size", !(2..=64).contains(&patch_size)),
            ("learned_atoms", learned.is_some_and(|n| n == 0 || n > n_candidates)),
            ("sparsity", sparsity == 0 || sparsity > 64 || sparsity > n_dict),
        ])?;
    }

    #[test]
    fn amplify_settings(
        radius in f64_edge(1.0, 4.0),
        step in prop_oneof![4 => Just(None), 1 => Just(Some(f64::NAN)), 1 => Just(Some(0.5)), 1 => Just(Some(1.5)), 3 => (1u32..7).prop_map(|v| Some(v as f64))],
        steps in prop_oneof![1 => Just(0usize), 6 => 1usize..3, 1 => Just(7)],
        sparsity in prop_oneof![1 => Just(0usize), 6 => 1usize..4, 1 => Just(65)],
        learned in prop_oneof![Just(None), (0usize..48, 0usize..2).prop_map(Some)],
        candidate_step in prop_oneof![1 => Just(0usize), 6 => 1usize..4],
        max_candidates in prop_oneof![1 => Just(0usize), 6 => 1usize..3000],
        max_training in prop_oneof![1 => Just(0usize), 6 => 1usize..3000],
        residual in any::<bool>(),
        poison in 0u8..6,
        seed in any::<u64>(),
        structure_radius in prop_oneof![2 => Just(0.0), 3 => Just(4.0), 1 => Just(f64::NAN), 1 => Just(0.5), 1 => Just(100.0), 2 => 1f64..6.0],
    ) {
        let mut coarse = alps(300, 300, 12, 12);
        let mut exemplar = alps(1200, 200, 112, 112);
        match poison {
            0 => coarse.set(3, 4, f32::NAN),
            1 => exemplar.set(50, 60, f32::NAN),
            _ => {}
        }
        let dictionary = match learned {
            None => DictionaryChoice::Complete,
            Some((n_atoms, iterations)) => DictionaryChoice::Learned { n_atoms, iterations },
        };
        let s = AmplifySettings {
            radius, step, steps, sparsity, dictionary, candidate_step, max_candidates,
            max_learning_pool: 4096, max_training, seed, residual_correction: residual, normalize_detail: residual,
            exemplar_detail: false, diverse_atoms: residual, exemplar_cell_size: None, index_probes: 8,
            residual_kernel: if seed % 2 == 0 { Kernel::Lanczos3 } else { Kernel::Keys },
        };
        let st = step.unwrap_or((radius / 2.0).floor().max(1.0));
        let radius_bad = !(radius.is_finite() && (1.0..=32.0).contains(&radius));
        let step_bad = !radius_bad
            && (!(st.is_finite() && st >= 1.0 && st.fract() == 0.0) || radius * radius <= st * st / 2.0);
        let invalid = [
            ("radius", radius_bad),
            ("step", step_bad),
            ("steps", steps == 0 || steps > 6),
            ("sparsity", sparsity == 0 || sparsity > 64),
            ("candidate_step", candidate_step == 0),
            ("max_candidates / max_training / max_learning_pool", max_candidates == 0 || max_training == 0),
            ("n_atoms", learned.is_some_and(|(n, _)| n < sparsity)),
        ];
        let r = amplify(&coarse, &exemplar, &s, &NoProgress);
        check(&r, &invalid)?;
        if poison < 2 {
            prop_assert!(r.is_err());
        }
        if let Ok(sct) = &r {
            let f = 4usize.pow(steps as u32);
            prop_assert_eq!((sct.width(), sct.height()), (12 * f, 12 * f));
        }
        let structure = StructureSettings { radius: structure_radius, seed };
        let syn = SynthesisSettings { amplify: s, height_range: None, structure, sketch_cell_size: None, grow: None };
        let r = synthesize(&coarse, &exemplar, &syn, &NoProgress);
        let structure_bad =
            !(structure_radius == 0.0 || (1.0..=64.0).contains(&structure_radius));
        let mut invalid = invalid.to_vec();
        invalid.push(("structure radius", structure_bad));
        check(&r, &invalid)?;
    }

    #[test]
    fn synthesis_height_range(
        lo in prop_oneof![Just(f32::NAN), Just(f32::NEG_INFINITY), -100f32..3000.0],
        span in prop_oneof![Just(-5f32), Just(0f32), 1f32..2000.0],
    ) {
        let sketch = alps(700, 700, 8, 8);
        let exemplar = alps(100, 600, 96, 96);
        let s = SynthesisSettings {
            amplify: AmplifySettings {
                radius: 1.0,
                steps: 1,
                dictionary: DictionaryChoice::learned(16, 1),
                ..Default::default()
            },
            height_range: Some((lo, lo + span)),
            ..Default::default()
        };
        let r = synthesize(&sketch, &exemplar, &s, &NoProgress);
        check(&r, &[("height_range", !(lo.is_finite() && span >= 0.0))])?;
    }
}

#[test]
fn small_entry_points_name_their_fields() {
    let sig = signals();
    assert!(matches!(
        subsample_rows(sig.view(), 0),
        Err(LearnError::InvalidParameter { name: "max", .. })
    ));
    assert_eq!(subsample_rows(sig.view(), 7).unwrap().nrows(), 7);
    let truth = alps(0, 0, 32, 32);
    let input = truth.resample(8, 8).unwrap();
    let wrong = truth.crop(0, 0, 16, 16).unwrap();
    assert!(matches!(
        evaluate(&truth, &input, &wrong),
        Err(LearnError::InvalidParameter { name: "output", .. })
    ));
    assert!(matches!(
        training_patches(&[], &PatchGeometry::with_patch_size(4)),
        Err(LearnError::NotEnough { .. })
    ));
    let ex = alps(0, 0, 96, 96);
    assert!(
        MultiResDictionary::from_exemplars(&[], None, &AmplifySettings::default(), &NoProgress)
            .is_err()
    );
    // A training matrix of the wrong width names `training`.
    let s = AmplifySettings {
        radius: 1.0,
        dictionary: DictionaryChoice::learned(8, 1),
        ..Default::default()
    };
    assert!(matches!(
        MultiResDictionary::from_exemplar(&ex, Some(sig.view()), &s, &NoProgress),
        Err(LearnError::InvalidParameter {
            name: "training",
            ..
        })
    ));
}

#[test]
fn procedural_learned_atoms_is_named() {
    let hf = alps(900, 500, 24, 24);
    for learned in [0, 100] {
        let r = fit_procedural(
            &hf,
            &ProceduralSettings {
                n_candidates: 32,
                learned_atoms: Some(learned),
                patch_size: 6,
                ..Default::default()
            },
            &NoProgress,
        );
        let e = r.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("learned_atoms"), "learned {learned}: {e}");
    }
}
