use super::*;

#[test]
fn feature_lists_parse_and_reject_unknown_names() {
    assert_eq!(
        Feature::parse_list("karst, sea,karst").unwrap(),
        vec![Feature::Sea, Feature::Karst]
    );
    assert_eq!(Feature::parse_list(" none ").unwrap(), vec![]);
    assert!(
        Feature::parse_list("none,sea").is_err(),
        "none stands alone"
    );
    let e = Feature::parse_list("sea,volcano").unwrap_err().to_string();
    assert!(e.contains("feature") && e.contains("volcano"), "{e}");
    for f in Feature::ALL {
        assert_eq!(f.name().parse::<Feature>().unwrap(), f);
    }
}

/// The scale check bounds the scale, not the DEM's size: a DEM of more than 1000 cells per side
/// is accepted at scale 1 (it was refused), absurd scales are refused.
#[test]
fn scale_check_accepts_large_dems() {
    let hf = Heightfield::from_fn(1500, 4, 10.0, 10.0, |x, y| ((x * 7 + y * 3) % 50) as f32);
    let recipe = |scale| Recipe {
        scale,
        features: vec![],
        ..Default::default()
    };
    build_recipe(&hf, &recipe(1.0)).unwrap();
    for scale in [1e-4, 2e3] {
        let e = build_recipe(&hf, &recipe(scale)).err().unwrap().to_string();
        assert!(e.contains("scale"), "{scale}: {e}");
    }
}

#[test]
fn recipe_rejects_bad_settings() {
    let hf = Heightfield::from_fn(8, 8, 10.0, 10.0, |x, y| (x + y) as f32);
    let bad = [
        (
            "scale",
            Recipe {
                scale: f32::NAN,
                ..Default::default()
            },
        ),
        (
            "mask",
            Recipe {
                mask: Some(vec![1.0; 3]),
                ..Default::default()
            },
        ),
    ];
    for (field, recipe) in bad {
        let e = build_recipe(&hf, &recipe).unwrap_err();
        assert!(e.to_string().contains(field), "{field}: {e}");
    }
}
