//! The job settings are the one definition of each job's parameters (issue 13): they
//! round-trip through JSON, missing fields take the defaults and unknown fields are errors.

use relief_dictionary_learning::{
    AmplifySettings, DictionaryChoice, KsvdSettings, NoiseFamily, ProceduralSettings,
    SynthesisSettings,
};

#[test]
fn amplify_settings_round_trip_and_refuse_unknown_fields() {
    let s = AmplifySettings {
        steps: 3,
        radius: 2.0,
        step: Some(1.0),
        dictionary: DictionaryChoice::Complete,
        ..AmplifySettings::paper()
    };
    relief_testdata::assert_json_round_trip(&s, &["\"dictionary\":\"complete\""]);
    let learned: AmplifySettings =
        serde_json::from_str(r#"{"dictionary": {"learned": {"n_atoms": 32, "iterations": 2}}}"#)
            .unwrap();
    assert_eq!(
        learned.dictionary,
        DictionaryChoice::Learned {
            n_atoms: 32,
            iterations: 2
        }
    );
    for bad in [
        r#"{"atoms": 3}"#,
        r#"{"dictionary": {"learned": {"n_atoms": 3, "iters": 2}}}"#,
        r#"{"dictionary": "all"}"#,
    ] {
        assert!(
            serde_json::from_str::<AmplifySettings>(bad).is_err(),
            "{bad}"
        );
    }
}

#[test]
fn synthesis_procedural_and_ksvd_settings_round_trip() {
    let syn = SynthesisSettings {
        height_range: Some((10.0, 900.0)),
        ..SynthesisSettings::default()
    };
    relief_testdata::assert_json_round_trip(&syn, &[]);
    let proc_: ProceduralSettings =
        serde_json::from_str(r#"{"family": "ridged_multifractal", "learned_atoms": 16}"#).unwrap();
    assert_eq!(proc_.family, NoiseFamily::RidgedMultifractal);
    assert_eq!(proc_.learned_atoms, Some(16));
    assert_eq!(
        proc_.n_candidates,
        ProceduralSettings::default().n_candidates
    );
    assert!(serde_json::from_str::<ProceduralSettings>(r#"{"family": "simplex"}"#).is_err());
    let k = KsvdSettings::default();
    let json = serde_json::to_string(&k).unwrap();
    assert_eq!(serde_json::from_str::<KsvdSettings>(&json).unwrap(), k);
    assert!(serde_json::from_str::<KsvdSettings>(r#"{"atoms": 3}"#).is_err());
}
