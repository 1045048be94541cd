//! The public patch search (PCA + kd-tree, section 3.5) on a real DEM crop.

use relief_heightfield::NoProgress;
use relief_patch_synth::{Exemplar, ExemplarIndex, OverlapShape, PatchSynthError, Settings};
use relief_testdata::dem_crop;

/// 32-cell patches, 8-cell overlaps, 8 clusters, PCA on 1500 samples.
fn search_settings() -> Settings {
    Settings {
        patch_size: 32,
        overlap: 8,
        kmeans_clusters: 8,
        pca_samples: 1500,
        ..Default::default()
    }
}

#[test]
fn nearest_overlaps_finds_the_patch_itself_and_ranks_by_overlap() {
    let Some(ex) = dem_crop("grandcanyon", 100, 120, 160, 160) else {
        return;
    };
    let s = search_settings();
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
            let near = index.nearest_overlaps(shape, &region, 24, 10).unwrap();
            assert_eq!(near.len(), 24);
            assert!(near.windows(2).all(|w| w[0].0 <= w[1].0));
            // The patch itself has overlap error 0 (vertical offsets do not matter: the
            // error is mean-removed).
            assert!(near[0].0 < 1e-3, "{shape:?} {:?}", &near[..3]);
            assert!(
                near.iter().any(|&(_, i)| i == id),
                "{shape:?} at ({x}, {y})"
            );
            let shifted: Vec<f32> = region.iter().map(|v| v + 250.0).collect();
            let near2 = index.nearest_overlaps(shape, &shifted, 24, 10).unwrap();
            assert!(near2.iter().any(|&(_, i)| i == id));
            // Far patches of the exemplar rank behind the true neighbours: the 24th error is
            // small compared with the errors of all patches (every patch fetched: exact).
            let all = index
                .nearest_overlaps(shape, &region, index.patches().len(), 1)
                .unwrap();
            assert_eq!(all.len(), index.patches().len());
            let median = all[all.len() / 2].0;
            assert!(near[23].0 < median, "{} vs median {median}", near[23].0);
        }
    }
    let e = index
        .nearest_overlaps(OverlapShape::Left, &[0.0; 10], 4, 10)
        .unwrap_err();
    assert!(
        matches!(e, PatchSynthError::InvalidControl { name: "region", .. }),
        "{e}"
    );
    let e = index
        .nearest_overlaps(OverlapShape::Left, &vec![0.0; p * p], 0, 10)
        .unwrap_err();
    assert!(e.to_string().contains("`knn` = 0"), "{e}");
    let mut bad = vec![1.0; p * p];
    bad[p + 1] = f32::NAN;
    assert!(
        index
            .nearest_overlaps(OverlapShape::Left, &bad, 4, 10)
            .is_err()
    );
}

/// Re-ranking the kd-tree's neighbours by the exact overlap error (issue 17): the 24 returned
/// hold most of the exhaustive best 24 for an overlap from another DEM, and more of them than
/// the kd-tree's own 24 (`rerank = 1`).
#[test]
fn reranked_search_recovers_the_exhaustive_best() {
    let Some([ex, other]) = relief_testdata::dem_crops([
        ("grandcanyon", 100, 120, 200, 200),
        ("alps_dem", 900, 200, 200, 200),
    ]) else {
        return;
    };
    let s = search_settings();
    let index = ExemplarIndex::build(vec![Exemplar::new(ex, 0)], &s, &NoProgress).unwrap();
    let p = s.patch_size;
    let n = index.patches().len();
    let (mut hit1, mut hit10) = (0usize, 0usize);
    for (x, y) in [(10usize, 20usize), (70, 130), (150, 40), (120, 150)] {
        let region: Vec<f32> = (0..p)
            .flat_map(|r| (0..p).map(move |c| (r, c)))
            .map(|(r, c)| 0.5 * other.get(x + c, y + r))
            .collect();
        let exact: Vec<usize> = index
            .nearest_overlaps(OverlapShape::Both, &region, n, 1)
            .unwrap()
            .into_iter()
            .take(24)
            .map(|v| v.1)
            .collect();
        for (rerank, hits) in [(1, &mut hit1), (10, &mut hit10)] {
            let got = index
                .nearest_overlaps(OverlapShape::Both, &region, 24, rerank)
                .unwrap();
            *hits += got.iter().filter(|v| exact.contains(&v.1)).count();
        }
    }
    assert!(hit10 * 10 >= 9 * 4 * 24, "recall {hit10} of 96");
    assert!(hit10 > hit1, "rerank 10: {hit10}, rerank 1: {hit1}");
}
