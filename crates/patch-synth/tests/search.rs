//! The public patch search (PCA + kd-tree, section 3.5) on a real DEM crop.

use relief_heightfield::NoProgress;
use relief_patch_synth::{Exemplar, ExemplarIndex, OverlapShape, PatchSynthError, Settings};
use relief_testdata::dem_crop;

#[test]
fn nearest_overlaps_finds_the_patch_itself_and_ranks_by_overlap() {
    let Some(ex) = dem_crop("grandcanyon", 100, 120, 160, 160) else {
        return;
    };
    let s = Settings {
        patch_size: 32,
        overlap: 8,
        kmeans_clusters: 8,
        pca_samples: 1500,
        ..Default::default()
    };
    let index = ExemplarIndex::build(vec![Exemplar::new(ex.clone(), 0)], &s, &NoProgress).unwrap();
    let p = s.patch_size;
    for (x, y) in [(0usize, 0usize), (57, 91), (128, 13)] {
        let region: Vec<f32> = (0..p)
            .flat_map(|r| (0..p).map(move |c| (r, c)))
            .map(|(r, c)| ex.get(x + c, y + r))
            .collect();
        let id = index
            .patches()
            .iter()
            .position(|q| (q.x as usize, q.y as usize) == (x, y))
            .unwrap();
        for shape in [OverlapShape::Left, OverlapShape::Top, OverlapShape::Both] {
            let near = index.nearest_overlaps(shape, &region, 24).unwrap();
            assert_eq!(near.len(), 24);
            assert!(near.windows(2).all(|w| w[0].0 <= w[1].0));
            // The patch itself is at PCA distance 0 (vertical offsets do not matter: the
            // features are mean-removed).
            assert!(near[0].0 < 1e-3, "{shape:?} {:?}", &near[..3]);
            assert!(
                near.iter().any(|&(_, i)| i == id),
                "{shape:?} at ({x}, {y})"
            );
            let shifted: Vec<f32> = region.iter().map(|v| v + 250.0).collect();
            let near2 = index.nearest_overlaps(shape, &shifted, 24).unwrap();
            assert!(near2.iter().any(|&(_, i)| i == id));
            // Far patches of the exemplar rank behind the true neighbours: the 24th distance
            // is small compared with the spread of the PCA coordinates of all patches.
            let all = index
                .nearest_overlaps(shape, &region, index.patches().len())
                .unwrap();
            assert_eq!(all.len(), index.patches().len());
            let median = all[all.len() / 2].0;
            assert!(near[23].0 < median, "{} vs median {median}", near[23].0);
        }
    }
    let e = index
        .nearest_overlaps(OverlapShape::Left, &[0.0; 10], 4)
        .unwrap_err();
    assert!(
        matches!(e, PatchSynthError::InvalidControl { name: "region", .. }),
        "{e}"
    );
    let e = index
        .nearest_overlaps(OverlapShape::Left, &vec![0.0; p * p], 0)
        .unwrap_err();
    assert!(e.to_string().contains("`knn` = 0"), "{e}");
    let mut bad = vec![1.0; p * p];
    bad[p + 1] = f32::NAN;
    assert!(index.nearest_overlaps(OverlapShape::Left, &bad, 4).is_err());
}
