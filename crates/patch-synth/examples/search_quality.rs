//! Quality of the approximate patch search (section 3.5: box-mean features, PCA, kd-tree)
//! against the exhaustive search it replaces (mean-removed SSD over the full-resolution
//! L-shaped overlap of every patch). Exemplar: the 512 x 512 Grand Canyon DEM, default settings
//! (patch 64, overlap 16). Queries: 12 alps windows brought to the canyon's height range.
//! For each `pca_dims` and each `rerank` (1 = the kd-tree's own 24; 10, the default = 240
//! fetched per bucket and re-ranked by the exact overlap error): recall of the exhaustive best
//! 24 among the 24 returned, and the full-resolution SSD of the best returned patch over the
//! exhaustive best (1 = optimal).
//!
//! `cargo run --release -p relief-patch-synth --features examples --example search_quality [PCA_DIMS ...]`
#![allow(clippy::print_stdout)]

use relief_heightfield::NoProgress;
use relief_patch_synth::{Exemplar, ExemplarIndex, OverlapShape, Settings};
use relief_testdata::{dem_crop, load_dem};

fn main() {
    let Some(ex) = load_dem("grandcanyon") else {
        return;
    };
    let src = dem_crop("alps_dem", 900, 200, 512, 512).expect("alps crop");
    let src = src.map(|v| 479.0 + (v - 640.0) * (2347.0 - 479.0) / (4115.0 - 640.0));
    let dims: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let dims = if dims.is_empty() { vec![8, 16] } else { dims };
    for (pca_dims, rerank) in dims
        .iter()
        .flat_map(|&d| [(d, 1), (d, Settings::default().rerank)])
    {
        let s = Settings {
            pca_dims,
            ..Default::default()
        };
        let (p, o) = (s.patch_size, s.overlap);
        let index = ExemplarIndex::build(vec![Exemplar::new(ex.clone(), 0)], &s, &NoProgress)
            .expect("index");
        let cells: Vec<(usize, usize)> = (0..p)
            .flat_map(|r| (0..p).map(move |c| (r, c)))
            .filter(|&(r, c)| r < o || c < o)
            .collect();
        let n = cells.len() as f32;
        let (mut recall, mut ratio_sum, mut worst) = (0usize, 0.0f64, 0.0f64);
        let queries = 12;
        for qi in 0..queries {
            let (qx, qy) = (17 + 37 * qi, 400 - 29 * qi);
            let region: Vec<f32> = (0..p)
                .flat_map(|r| (0..p).map(move |c| (r, c)))
                .map(|(r, c)| src.get(qx + c, qy + r))
                .collect();
            let qm = cells.iter().map(|&(r, c)| region[r * p + c]).sum::<f32>() / n;
            let ssd = |id: usize| -> f64 {
                let pr = index.patches()[id];
                let hf = &index.exemplars()[pr.exemplar as usize].heightfield;
                let at = |r: usize, c: usize| hf.get(pr.x as usize + c, pr.y as usize + r);
                let pm = cells.iter().map(|&(r, c)| at(r, c)).sum::<f32>() / n;
                cells
                    .iter()
                    .map(|&(r, c)| {
                        let d = ((at(r, c) - pm) - (region[r * p + c] - qm)) as f64;
                        d * d
                    })
                    .sum()
            };
            let mut all: Vec<(f64, usize)> =
                (0..index.patches().len()).map(|id| (ssd(id), id)).collect();
            all.sort_by(|a, b| a.0.total_cmp(&b.0));
            let best: Vec<usize> = all[..24].iter().map(|v| v.1).collect();
            let got = index
                .nearest_overlaps(OverlapShape::Both, &region, 24, rerank)
                .expect("search");
            recall += got.iter().filter(|(_, id)| best.contains(id)).count();
            let got_best = got
                .iter()
                .map(|&(_, id)| ssd(id))
                .fold(f64::INFINITY, f64::min);
            let r = got_best / all[0].0;
            ratio_sum += r;
            worst = worst.max(r);
        }
        println!(
            "pca_dims {pca_dims:2} rerank {rerank:2} (explained {:?}): recall@24 {:.1} %, best-returned SSD / optimal SSD mean {:.2}, worst {:.2}",
            index.pca_explained(),
            100.0 * recall as f64 / (24 * queries) as f64,
            ratio_sum / queries as f64,
            worst
        );
    }
}
