//! Noise atoms, registry round trip, parameter validation.

use ndarray::Array2;
use relief_dictionary_learning::noise::{Perlin, random_function_atoms};
use relief_dictionary_learning::*;
use relief_heightfield::{Heightfield, NoProgress};
use relief_sparse_core::{Dictionary, FunctionAtomRegistry};

#[test]
fn noise_is_deterministic_and_bounded() {
    let a = Perlin::new(5);
    let b = Perlin::new(5);
    let c = Perlin::new(6);
    let mut diff = 0.0;
    for i in 0..500 {
        let (x, y) = (i as f64 * 0.173, i as f64 * 0.311);
        assert_eq!(a.noise(x, y).to_bits(), b.noise(x, y).to_bits());
        assert!(a.noise(x, y).abs() <= 1.5);
        let r = a.ridged(x, y);
        assert!((0.0..=1.0).contains(&r));
        diff += (a.noise(x, y) - c.noise(x, y)).abs();
    }
    assert!(diff > 10.0, "different seeds must differ");
    assert_eq!(
        a.noise(3.0, 4.0),
        0.0,
        "gradient noise vanishes on the lattice"
    );
}

#[test]
fn function_atoms_round_trip_through_the_registry() {
    let mut reg = FunctionAtomRegistry::new();
    register_function_atoms(&mut reg);
    for fam in [
        NoiseFamily::Perlin,
        NoiseFamily::RidgedMultifractal,
        NoiseFamily::RidgedSum,
    ] {
        for atom in random_function_atoms(fam, 8, 3) {
            let back = reg.construct(&atom.descriptor()).unwrap();
            for i in 0..20 {
                let (u, v) = (-1.0 + 0.1 * i as f64, 0.9 - 0.07 * i as f64);
                assert_eq!(atom.eval(u, v).to_bits(), back.eval(u, v).to_bits());
            }
        }
    }
    let mut d = Dictionary::new(8, 1.0, 4.0).unwrap();
    for atom in random_function_atoms(NoiseFamily::RidgedSum, 4, 1) {
        d.push_function(atom).unwrap();
    }
    assert_eq!(d.discretize().nrows(), 4);
    // Bad parameters are errors.
    let bad = relief_sparse_core::AtomDescriptor {
        kind: "ridged_sum".into(),
        params: vec![1.0; 3],
    };
    assert!(reg.construct(&bad).is_err());
}

#[test]
fn invalid_parameters_are_errors() {
    let sig = Array2::<f32>::from_shape_fn((50, 16), |(i, j)| ((i * 3 + j * 7) % 13) as f32 - 6.0);
    let bad = KsvdSettings {
        n_atoms: 0,
        ..Default::default()
    };
    assert!(matches!(
        ksvd(sig.view(), &bad, &NoProgress),
        Err(LearnError::InvalidParameter {
            name: "n_atoms",
            ..
        })
    ));
    let bad = KsvdSettings {
        n_atoms: 8,
        sparsity: 9,
        ..Default::default()
    };
    assert!(ksvd(sig.view(), &bad, &NoProgress).is_err());
    let bad = KsvdSettings {
        n_atoms: 80,
        sparsity: 2,
        ..Default::default()
    };
    assert!(matches!(
        ksvd(sig.view(), &bad, &NoProgress),
        Err(LearnError::NotEnough { .. })
    ));
    let mut nan = sig.clone();
    nan[(3, 3)] = f32::NAN;
    let ok = KsvdSettings {
        n_atoms: 8,
        sparsity: 2,
        iterations: 2,
        ..Default::default()
    };
    assert!(matches!(
        ksvd(nan.view(), &ok, &NoProgress),
        Err(LearnError::NonFinite { row: 3, .. })
    ));
    assert!(ksvd(sig.view(), &ok, &NoProgress).is_ok());
    let hf = Heightfield::from_fn(64, 64, 1.0, 1.0, |x, y| (x * y) as f32 * 0.01);
    let bad = AmplifySettings {
        radius: 0.5,
        ..Default::default()
    };
    assert!(amplify(&hf, &hf, &bad, &NoProgress).is_err());
    let bad = AmplifySettings {
        step: Some(9.0),
        ..Default::default()
    };
    assert!(amplify(&hf, &hf, &bad, &NoProgress).is_err());
    // Exemplar too small for the patch size.
    assert!(matches!(
        amplify(&hf, &hf, &AmplifySettings::default(), &NoProgress),
        Err(LearnError::NotEnough { .. })
    ));
    assert!(
        noise_amplify(
            &hf,
            &NoiseBaselineSettings {
                factor: 1,
                ..Default::default()
            }
        )
        .is_err()
    );
    let mut void = hf.clone();
    void.set(3, 3, f32::NAN);
    assert!(noise_amplify(&void, &NoiseBaselineSettings::default()).is_err());
}

#[test]
fn mixed_data_and_analytic_atoms_keep_fixed_atoms() {
    // Dictionary mixing discretised function atoms (kept fixed) and learned data atoms.
    let mut d = Dictionary::new(6, 1.0, 3.0).unwrap();
    for atom in random_function_atoms(NoiseFamily::RidgedSum, 4, 9) {
        d.push_function(atom).unwrap();
    }
    let f = d.discretize();
    let sig = Array2::<f32>::from_shape_fn((300, 36), |(i, j)| {
        ((i as f32 * 0.37 + j as f32 * 0.91).sin() * 3.0) + f[(i % 4, j)] * 2.0
    });
    let mut init = Array2::<f32>::zeros((12, 36));
    for j in 0..4 {
        init.row_mut(j).assign(&f.row(j));
    }
    for j in 4..12 {
        init.row_mut(j).assign(&sig.row(j * 20));
    }
    let s = KsvdSettings {
        n_atoms: 12,
        sparsity: 2,
        iterations: 4,
        ..Default::default()
    };
    let r = ksvd_with_fixed(sig.view(), init, &[0, 1, 2, 3], &s, &NoProgress).unwrap();
    for j in 0..4 {
        for (a, b) in r.atoms.row(j).iter().zip(f.row(j)) {
            assert!((a - b).abs() < 1e-6);
        }
    }
    assert!(r.trace.last().unwrap().rmse < r.trace[0].rmse);
}

#[test]
fn field_windows_store_their_shared_field_once() {
    let count = |family: NoiseFamily| {
        let mut d = Dictionary::new(10, 1.0, 5.0).unwrap();
        for atom in random_function_atoms(family, 50, 3) {
            d.push_function(atom).unwrap();
        }
        (d.len() as u64, relief_sparse_core::dictionary_values(&d))
    };
    // Independent atoms: every parameter is their own.
    assert_eq!(count(NoiseFamily::Perlin), (50, 50 * 6));
    assert_eq!(count(NoiseFamily::RidgedMultifractal), (50, 50 * 8));
    // Windows of one field: the field (3 or 5 values) once, then offset and angle each.
    assert_eq!(count(NoiseFamily::PerlinField), (50, 3 + 50 * 3));
    assert_eq!(count(NoiseFamily::RidgedField), (50, 5 + 50 * 3));
}
