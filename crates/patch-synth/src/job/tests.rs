//! Tests of the job layer.

use super::*;

#[test]
fn jobs_round_trip_through_json_and_refuse_unknown_fields() {
    let q = QuiltJob::default();
    let s = serde_json::to_string(&q).unwrap();
    assert_eq!(serde_json::from_str::<QuiltJob>(&s).unwrap(), q);
    let v = ValidateJob::default();
    let s = serde_json::to_string(&v).unwrap();
    assert_eq!(serde_json::from_str::<ValidateJob>(&s).unwrap(), v);
    assert!(serde_json::from_str::<QuiltJob>(r#"{"patch": 32}"#).is_err());
    assert!(serde_json::from_str::<QuiltJob>(r#"{"settings": {"patch": 32}}"#).is_err());
    assert!(serde_json::from_str::<QuiltJob>(r#"{"guide": {"sigma": 2}}"#).is_err());
    let j: QuiltJob = serde_json::from_str(
        r#"{"settings": {"patch_size": 32, "blend": {"feather": {"radius": 2.0}}},
            "guide": {"range": "auto", "blur": 3.0}, "size": [64, 48]}"#,
    )
    .unwrap();
    assert_eq!(j.settings.patch_size, 32);
    assert_eq!(j.settings.overlap, Settings::default().overlap);
    assert_eq!(j.guide.range, Some(GuideRange::Auto));
    assert_eq!(j.size, Some((64, 48)));
    let m: GuideSetup = serde_json::from_str(r#"{"range": {"metres": [10, 20]}}"#).unwrap();
    assert_eq!(m.range, Some(GuideRange::Metres(10.0, 20.0)));
}

#[test]
fn check_names_the_field() {
    let mut j = QuiltJob::default();
    j.guide.blur = Some(-1.0);
    assert!(j.check().unwrap_err().to_string().contains("guide.blur"));
    let mut j = QuiltJob::default();
    j.guide.range = Some(GuideRange::Metres(5.0, 5.0));
    assert!(j.check().unwrap_err().to_string().contains("guide.range"));
    let j = QuiltJob(ValidateJob {
        size: Some((0, 8)),
        ..Default::default()
    });
    assert!(j.check().unwrap_err().to_string().contains("`size`"));
    let mut j = QuiltJob::default();
    j.settings.overlap = 40;
    assert!(j.check().unwrap_err().to_string().contains("overlap"));
    let j = QuiltJob(ValidateJob {
        auto_categories: Some(0),
        ..Default::default()
    });
    assert!(
        j.check()
            .unwrap_err()
            .to_string()
            .contains("auto_categories")
    );
}

fn exemplar() -> Heightfield {
    Heightfield::from_fn(80, 80, 30.0, 30.0, |x, y| {
        ((x as f32 * 0.21).sin() * (y as f32 * 0.17).cos()) * 40.0 + x as f32 * 2.0
    })
}

fn small_settings() -> Settings {
    Settings {
        patch_size: 24,
        overlap: 6,
        min_candidates: 20,
        kmeans_clusters: 4,
        pca_samples: 400,
        ..Default::default()
    }
}

/// A guide at twice the exemplar's cell size in other units: kept at its ground extent,
/// mapped into the exemplar's heights, validated and synthesized; enforcement refuses a
/// guide far above the exemplar and suggests the auto mapping.
#[test]
fn quilt_job_maps_and_scales_the_guide() {
    let ex = exemplar();
    // The exemplar's centre at half the resolution, in other units (0.5 x, 5000 m up).
    let mut g = ex
        .crop(10, 15, 60, 50)
        .unwrap()
        .resample(30, 25)
        .unwrap()
        .map(|v| 5000.0 + 0.5 * v);
    g.set_cell_size(60.0, 60.0).unwrap();
    let mut job = QuiltJob(ValidateJob {
        settings: small_settings(),
        ..Default::default()
    });
    let inputs = JobInputs {
        exemplars: vec![ex.clone()],
        guide: Some(g.clone()),
        categories: None,
        exemplar_regions: Vec::new(),
    };
    let err = job
        .run(inputs.clone(), &relief_heightfield::NoProgress)
        .unwrap_err();
    let PatchSynthError::Validation(r) = err else {
        panic!("{err}")
    };
    assert!(!r.ok);
    assert!(r.suggestion.unwrap().contains("auto would pass"));
    job.guide.range = Some(GuideRange::Auto);
    let out = job.run(inputs, &relief_heightfield::NoProgress).unwrap();
    let used = out.guide.unwrap();
    assert_eq!((used.width(), used.height()), (60, 50));
    assert_eq!(used.cell_size(), (30.0, 30.0));
    // The guide's window-mean extremes went inside the exemplar's range (from 5000 m up).
    let m = out.figures.prepare.guide_mapping.unwrap();
    let (elo, ehi) = ex.min_max().unwrap();
    assert!(m.from.0 > 4900.0, "{m:?}");
    assert!(
        m.to.0 >= elo && m.to.1 <= ehi && m.to.0 < m.to.1,
        "{m:?} vs {elo}..{ehi}"
    );
    let (lo, hi) = used.min_max().unwrap();
    assert!(lo > elo - 100.0 && hi < ehi + 100.0, "{lo}..{hi}");
    assert_eq!(out.figures.prepare.validation_ok, Some(true));
    assert_eq!(out.figures.prepare.output_size, (60, 50));
    assert!(out.figures.prepare.guide_mapping.is_some());
    assert_eq!(
        (
            out.synthesis.heightfield.width(),
            out.synthesis.heightfield.height()
        ),
        (60, 50)
    );
    assert!(out.figures.distinct_source_share > 0.0 && out.figures.patches > 0);
}

#[test]
fn validate_job_reports_unguided_compatibility_and_refuses_bad_inputs() {
    let job = ValidateJob {
        settings: small_settings(),
        size: Some((64, 64)),
        ..Default::default()
    };
    let inputs = JobInputs {
        exemplars: vec![exemplar(), exemplar()],
        ..Default::default()
    };
    let out = job.run(inputs, &relief_heightfield::NoProgress).unwrap();
    assert_eq!(out.report.compatibility.len(), 2);
    let err = job
        .run(JobInputs::default(), &relief_heightfield::NoProgress)
        .unwrap_err();
    assert!(matches!(err, PatchSynthError::NoExemplars), "{err}");
    let small = JobInputs {
        exemplars: vec![exemplar().crop(0, 0, 20, 20).unwrap()],
        ..Default::default()
    };
    let err = job.run(small, &relief_heightfield::NoProgress).unwrap_err();
    assert!(err.to_string().contains("patch_size 24"), "{err}");
    let j = ValidateJob {
        size: None,
        ..job.clone()
    };
    let err = j
        .run(
            JobInputs {
                exemplars: vec![exemplar()],
                ..Default::default()
            },
            &relief_heightfield::NoProgress,
        )
        .unwrap_err();
    assert!(err.to_string().contains("size"), "{err}");
}
