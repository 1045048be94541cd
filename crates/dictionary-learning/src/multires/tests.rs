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
