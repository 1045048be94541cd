use relief_heightfield::NoProgress;
use relief_heightfield::rng::{hash, unit_f32};

use super::*;
use crate::erode::tests::assert_stopping_leaves_the_input_alone;

fn never() -> bool {
    false
}

/// Rough ground: a ramp with 40 m of white noise per cell (far steeper than any talus).
fn rough(grid: &Grid, seed: u64) -> Vec<f32> {
    (0..grid.len())
        .map(|i| (i % grid.width) as f32 * 3.0 + 40.0 * unit_f32(hash(seed, i as u64, 0, 0)))
        .collect()
}

fn total(z: &[f32]) -> f64 {
    z.iter().filter(|v| !v.is_nan()).map(|&v| v as f64).sum()
}

#[test]
fn mass_is_conserved_and_voids_untouched() {
    let grid = Grid::new(37, 23, 10.0, 14.0);
    let mut z = rough(&grid, 3);
    for i in [0, 50, 51, 52, 300, 400, grid.len() - 1] {
        z[i] = f32::NAN;
    }
    let before = z.clone();
    let p = ThermalParams {
        iterations: 200,
        ..Default::default()
    };
    let f = thermal(&mut z, &grid, &p, &NoProgress, &never).unwrap();
    for (a, b) in before.iter().zip(&z) {
        assert_eq!(a.is_nan(), b.is_nan());
    }
    let (t0, t1) = (total(&before), total(&z));
    // f32 heights of ~100 m: rounding of about 1e-5 m per cell and step at worst.
    assert!((t0 - t1).abs() < 1e-6 * t0, "{t0} -> {t1}");
    assert!(f.moved_m3 > 0.0 && f.max_lowering_m > 1.0 && f.max_raising_m > 1.0);
    assert!(f.steep_cells_after < f.steep_cells_before / 20, "{f:?}");
}

#[test]
fn a_cliff_relaxes_to_the_talus_angle_on_non_square_cells() {
    let grid = Grid::new(40, 5, 10.0, 15.0);
    let mut z: Vec<f32> = (0..grid.len())
        .map(|i| if i % grid.width < 20 { 100.0 } else { 0.0 })
        .collect();
    let p = ThermalParams {
        talus_angle_deg: 35.0,
        iterations: 3000,
        rate: 0.5,
        weathering_m: None,
    };
    let f = thermal(&mut z, &grid, &p, &NoProgress, &never).unwrap();
    assert_eq!(f.steep_cells_after, 0, "{f:?}");
    // Along the middle row, the scarp's face (where the slope is over 5 degrees) stands at the
    // talus angle, but for the two cells where it meets the flats above and below.
    let row = &z[2 * grid.width..3 * grid.width];
    let face: Vec<f64> = row
        .windows(2)
        .map(|w| ((w[0] - w[1]) as f64 / 10.0).atan().to_degrees())
        .filter(|a| *a > 5.0)
        .collect();
    assert!(face.len() >= 8, "{row:?}");
    let inner = &face[1..face.len() - 1];
    assert!(inner.iter().all(|a| (a - 35.0).abs() < 0.5), "{face:?}");
    // The edge rows (fewer neighbours to share with early on) end with nearly the same
    // profile.
    for y in 0..grid.height {
        for (a, b) in z[y * grid.width..(y + 1) * grid.width].iter().zip(row) {
            assert!((a - b).abs() < 0.5, "row {y}: {a} vs {b}");
        }
    }
}

#[test]
fn a_weathering_depth_keeps_the_cliff_and_builds_an_apron() {
    let grid = Grid::new(40, 5, 10.0, 10.0);
    let z0: Vec<f32> = (0..grid.len())
        .map(|i| if i % grid.width < 20 { 100.0 } else { 0.0 })
        .collect();
    let mut z = z0.clone();
    let p = ThermalParams {
        talus_angle_deg: 35.0,
        iterations: 500,
        rate: 0.5,
        weathering_m: Some(5.0),
    };
    thermal(&mut z, &grid, &p, &NoProgress, &never).unwrap();
    assert!((total(&z) - total(&z0)).abs() < 1e-2);
    let row = &z[2 * grid.width..3 * grid.width];
    // The top loses at most its 5 m (plus nothing: what it sheds moves on), the face still
    // drops most of the 100 m within a few cells, and the foot gained an apron.
    assert!(row.iter().all(|&v| (-1e-3..=100.0).contains(&v)));
    assert!(row[..20].iter().all(|&v| v >= 95.0 - 1e-3), "{row:?}");
    assert!(row[20] > 0.5 && row[20] < 40.0, "{row:?}");
    let mut loose = z0.clone();
    thermal(
        &mut loose,
        &grid,
        &ThermalParams {
            weathering_m: None,
            ..p
        },
        &NoProgress,
        &never,
    )
    .unwrap();
    // Without the limit the same run cuts the cliff top down much further.
    assert!(loose[2 * grid.width + 19] < row[19] - 10.0);
}

#[test]
fn one_and_two_threads_give_the_same_bytes() {
    let grid = Grid::new(70, 41, 30.0, 30.0);
    let run = |k: usize| {
        let mut z = rough(&grid, 9);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(k)
            .build()
            .unwrap();
        pool.install(|| {
            thermal(
                &mut z,
                &grid,
                &ThermalParams::default(),
                &NoProgress,
                &never,
            )
        })
        .unwrap();
        z.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn stopping_leaves_the_input_alone() {
    let grid = Grid::new(9, 9, 1.0, 1.0);
    let p = ThermalParams::default();
    assert_stopping_leaves_the_input_alone(rough(&grid, 1), |z, stop| {
        thermal(z, &grid, &p, &NoProgress, stop)
    });
}

#[test]
fn bad_settings_and_inputs_are_rejected_by_name() {
    let name = |p: ThermalParams| p.check().unwrap_err().name;
    let d = ThermalParams::default();
    assert!(d.check().is_ok());
    assert_eq!(
        name(ThermalParams {
            talus_angle_deg: f64::NAN,
            ..d
        }),
        "talus_angle_deg"
    );
    assert_eq!(
        name(ThermalParams {
            talus_angle_deg: -3.0,
            ..d
        }),
        "talus_angle_deg"
    );
    assert_eq!(name(ThermalParams { rate: -0.1, ..d }), "rate");
    assert_eq!(
        name(ThermalParams {
            rate: f64::NAN,
            ..d
        }),
        "rate"
    );
    assert_eq!(name(ThermalParams { rate: 0.6, ..d }), "rate");
    let grid = Grid::new(4, 4, 1.0, -1.0);
    let mut z = vec![0.0f32; 16];
    let e = thermal(&mut z, &grid, &d, &NoProgress, &never).unwrap_err();
    assert!(e.to_string().contains("cell_y"), "{e}");
    let grid = Grid {
        cell_y: 1.0,
        ..grid
    };
    let e = thermal(&mut z[..15], &grid, &d, &NoProgress, &never).unwrap_err();
    assert!(matches!(e, LandscapeError::InvalidInput(_)));
    let mut voids = vec![f32::NAN; 16];
    assert!(thermal(&mut voids, &grid, &d, &NoProgress, &never).is_err());
}
