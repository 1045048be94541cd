//! Property tests of the heightfield core: sampling exact at nodes, resampling round trips,
//! void filling invariants, and the same on real DEM crops.

use proptest::prelude::*;
use relief_heightfield::fill::{FillSettings, fill_voids};
use relief_heightfield::metrics::{
    psnr, radial_power_spectrum, rmse, slope_histogram_distance, spectral_slope,
};
use relief_heightfield::terrain::{hillshade, slope_degrees};
use relief_heightfield::{Heightfield, HeightfieldError};

fn smooth_field() -> impl Strategy<Value = Heightfield> {
    (8usize..40, 8usize..40, 0.5f64..50.0, any::<u64>()).prop_map(|(w, h, cell, seed)| {
        let s = (seed % 1000) as f32 / 100.0;
        Heightfield::from_fn(w, h, cell, cell * 1.3, |x, y| {
            let (x, y) = (x as f32, y as f32);
            100.0 * (0.21 * x + s).sin() * (0.17 * y - s).cos() + 3.0 * x - 2.0 * y
        })
    })
}

proptest! {
    #[test]
    fn sampling_is_exact_at_nodes(hf in smooth_field()) {
        for y in 0..hf.height() {
            for x in 0..hf.width() {
                let v = hf.get(x, y);
                prop_assert!((hf.sample_bilinear(x as f32, y as f32) - v).abs() <= 1e-4 * v.abs().max(1.0));
                prop_assert!((hf.sample_bicubic(x as f32, y as f32) - v).abs() <= 1e-4 * v.abs().max(1.0));
            }
        }
    }

    #[test]
    fn upsample_then_downsample_recovers_smooth_input(hf in smooth_field(), k in 2usize..5) {
        let up = hf.resample(hf.width() * k, hf.height() * k).unwrap();
        let back = up.resample(hf.width(), hf.height()).unwrap();
        // Smooth band-limited input: the round trip loses little compared to the relief.
        let e = rmse(&hf, &back).unwrap();
        prop_assert!(e < 0.02 * hf.relief() as f64, "rmse {e} relief {}", hf.relief());
        let (cx, cy) = hf.cell_size();
        prop_assert!((up.cell_size().0 - cx / k as f64).abs() < 1e-9);
        prop_assert!((up.cell_size().1 - cy / k as f64).abs() < 1e-9);
    }

    #[test]
    fn into_vec_is_the_row_major_samples(hf in smooth_field()) {
        let rows: Vec<f32> = hf.array().iter().copied().collect();
        prop_assert_eq!(hf.as_slice(), rows.as_slice());
        prop_assert_eq!(hf.into_vec(), rows);
    }

    #[test]
    fn downsampling_preserves_the_mean(hf in smooth_field()) {
        let small = hf.resample(hf.width() / 2, hf.height() / 2).unwrap();
        let m = |h: &Heightfield| h.as_slice().iter().map(|&v| v as f64).sum::<f64>() / h.len() as f64;
        prop_assert!((m(&hf) - m(&small)).abs() < 0.05 * hf.relief() as f64);
    }

    #[test]
    fn fill_keeps_valid_cells_and_stays_within_bounds(hf in smooth_field(), holes in prop::collection::vec((0usize..40, 0usize..40, 1usize..8), 1..6)) {
        let mut holed = hf.clone();
        for (x, y, r) in holes {
            for yy in y.min(hf.height() - 1)..(y + r).min(hf.height()) {
                for xx in x.min(hf.width() - 1)..(x + r).min(hf.width()) {
                    holed.set(xx, yy, f32::NAN);
                }
            }
        }
        let before = holed.clone();
        let mut filled = holed;
        let report = fill_voids(&mut filled, &FillSettings::default()).unwrap();
        prop_assert_eq!(report.filled, before.void_count());
        prop_assert_eq!(filled.void_count(), 0);
        let (lo, hi) = before.min_max().unwrap();
        for (a, b) in before.as_slice().iter().zip(filled.as_slice()) {
            if a.is_finite() {
                prop_assert_eq!(a.to_bits(), b.to_bits());
            } else {
                // Maximum principle of harmonic functions.
                prop_assert!(*b >= lo - 1e-2 && *b <= hi + 1e-2);
            }
        }
    }
}

#[test]
fn constructors_reject_bad_sizes() {
    assert!(matches!(
        Heightfield::new(0, 5, vec![], 1.0, 1.0),
        Err(HeightfieldError::InvalidDimensions { .. })
    ));
    assert!(matches!(
        Heightfield::new(2, 2, vec![0.0; 3], 1.0, 1.0),
        Err(HeightfieldError::LengthMismatch { got: 3, .. })
    ));
    assert!(matches!(
        Heightfield::new(2, 2, vec![0.0; 4], -1.0, 1.0),
        Err(HeightfieldError::InvalidCellSize { .. })
    ));
    assert!(Heightfield::new(1 << 20, 1 << 20, vec![], 1.0, 1.0).is_err());
    let hf = Heightfield::new(2, 2, vec![0.0; 4], 1.0, 1.0).unwrap();
    assert!(hf.crop(1, 1, 2, 1).is_err());
    assert!(hf.crop(usize::MAX, 0, 2, 1).is_err());
    let mut all_void = Heightfield::new(2, 2, vec![f32::NAN; 4], 1.0, 1.0).unwrap();
    assert!(matches!(
        fill_voids(&mut all_void, &FillSettings::default()),
        Err(HeightfieldError::AllVoid { count: 4 })
    ));
}

#[test]
fn slopes_respect_non_square_cells() {
    // z = x metres east: a 45-degree slope whatever the cell size.
    let hf = Heightfield::from_fn(10, 10, 2.0, 7.0, |x, _| 2.0 * x as f32);
    let s = slope_degrees(&hf);
    assert!(s.iter().all(|v| (v - 45.0).abs() < 1e-3));
    // Light from the west on a west-facing slope is brighter than from the east.
    let west = hillshade(&hf, 270.0, 45.0, 1.0);
    let east = hillshade(&hf, 90.0, 45.0, 1.0);
    assert!(west[(5, 5)] > east[(5, 5)] + 0.5);
}

/// N47E011 (SRTM3, Inn valley) has 54,278 voids: the fill leaves no void, keeps every valid cell
/// and produces heights within the tile's valid range.
#[test]
fn fills_the_srtm_voids_of_n47e011() {
    let Some(dem) = relief_testdata::load_dem("N47E011") else {
        return;
    };
    assert_eq!(dem.void_count(), 54_278);
    let mut filled = dem.clone();
    let report = fill_voids(&mut filled, &FillSettings::default()).unwrap();
    assert_eq!(report.filled, 54_278);
    assert!(report.relative_residual <= 1e-7, "{report:?}");
    assert_eq!(filled.void_count(), 0);
    let (lo, hi) = dem.min_max().unwrap();
    for (a, b) in dem.as_slice().iter().zip(filled.as_slice()) {
        if a.is_finite() {
            assert_eq!(a, b);
        } else {
            assert!(*b >= lo && *b <= hi);
        }
    }
}

/// On a real mountain crop, down-sampling by 4 and enlarging back keeps the large forms (high
/// PSNR) but loses the fine octaves (steeper spectrum, narrower slope histogram): the
/// measures the amplification methods report are sensitive to exactly what they add.
#[test]
fn quality_measures_on_alps_crop() {
    let Some(crop) = relief_testdata::dem_crop("alps_dem", 600, 100, 256, 256) else {
        return;
    };
    let coarse = crop.resample(64, 64).unwrap();
    let back = coarse.resample(256, 256).unwrap();
    let p = psnr(&crop, &back).unwrap();
    assert!(p > 25.0 && p.is_finite(), "psnr {p}");
    let (cx, _) = crop.cell_size();
    let band = (1.0 / (16.0 * cx), 1.0 / (2.5 * cx));
    let s_truth = spectral_slope(&radial_power_spectrum(&crop).unwrap(), band.0, band.1).unwrap();
    let s_back = spectral_slope(&radial_power_spectrum(&back).unwrap(), band.0, band.1).unwrap();
    assert!(s_truth < -1.5 && s_truth > -6.5, "truth slope {s_truth}");
    assert!(
        s_back < s_truth - 0.5,
        "smooth up-sampling must fall off faster: {s_back} vs {s_truth}"
    );
    assert!(slope_histogram_distance(&crop, &back) > 1.0);
    assert!(slope_histogram_distance(&crop, &crop) == 0.0);
}
