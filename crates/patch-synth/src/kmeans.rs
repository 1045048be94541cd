//! Deterministic k-means (k-means++ seeding on a strided subsample, then Lloyd iterations with
//! fixed-chunk reductions so the result does not depend on the rayon thread count).

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

/// Result of a k-means run: `k` centroids of `dim` values (row-major) and one label per point.
/// Centroids are sorted by their mean value (ascending) so that cluster ids are ordered by
/// height when the data are heights.
#[derive(Debug, Clone)]
pub struct KMeans {
    /// Dimension of the points.
    pub dim: usize,
    /// Centroids, `k * dim` values.
    pub centroids: Vec<f32>,
    /// Cluster of every point.
    pub labels: Vec<u32>,
}

impl KMeans {
    /// Number of clusters.
    pub fn k(&self) -> usize {
        self.centroids.len() / self.dim.max(1)
    }
    /// Centroid `c`.
    pub fn centroid(&self, c: usize) -> &[f32] {
        &self.centroids[c * self.dim..(c + 1) * self.dim]
    }
}

const CHUNK: usize = 4096;

pub(crate) fn dist2(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

pub(crate) fn nearest(p: &[f32], centroids: &[f32], dim: usize) -> (u32, f32) {
    let mut best = (0u32, f32::INFINITY);
    for (c, cen) in centroids.chunks_exact(dim).enumerate() {
        let d = dist2(p, cen);
        if d < best.1 {
            best = (c as u32, d);
        }
    }
    best
}

/// Clusters `data` (`n * dim` values) into at most `k` clusters (fewer when there are fewer
/// distinct points). Deterministic for a given `seed` whatever the thread count.
pub fn kmeans(data: &[f32], dim: usize, k: usize, iterations: usize, seed: u64) -> KMeans {
    let n = data.len() / dim.max(1);
    if n == 0 || dim == 0 {
        return KMeans {
            dim,
            centroids: Vec::new(),
            labels: Vec::new(),
        };
    }
    let k = k.clamp(1, n);
    // k-means++ seeding on a strided subsample (bounded cost).
    let sub_stride = (n / 20_000).max(1);
    let sample: Vec<usize> = (0..n).step_by(sub_stride).collect();
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x6b6d_6561_6e73);
    let point = |i: usize| &data[i * dim..(i + 1) * dim];
    let mut centroids: Vec<f32> = point(sample[rng.random_range(0..sample.len())]).to_vec();
    let mut d2: Vec<f32> = sample
        .iter()
        .map(|&i| dist2(point(i), &centroids))
        .collect();
    while centroids.len() / dim < k {
        let total: f64 = d2.iter().map(|&v| v as f64).sum();
        if total <= 0.0 {
            break; // Fewer distinct points than k.
        }
        let mut t = rng.random::<f64>() * total;
        let mut pick = sample.len() - 1;
        for (j, &v) in d2.iter().enumerate() {
            t -= v as f64;
            if t <= 0.0 {
                pick = j;
                break;
            }
        }
        let c = point(sample[pick]).to_vec();
        for (j, &i) in sample.iter().enumerate() {
            d2[j] = d2[j].min(dist2(point(i), &c));
        }
        centroids.extend_from_slice(&c);
    }
    let k = centroids.len() / dim;
    let mut labels = vec![0u32; n];
    for _ in 0..iterations {
        labels
            .par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(ci, chunk)| {
                for (j, l) in chunk.iter_mut().enumerate() {
                    *l = nearest(point(ci * CHUNK + j), &centroids, dim).0;
                }
            });
        // Fixed-size chunks summed in order: the reduction is independent of the thread count.
        let partial: Vec<(Vec<f64>, Vec<usize>)> = labels
            .par_chunks(CHUNK)
            .enumerate()
            .map(|(ci, chunk)| {
                let mut s = vec![0.0f64; k * dim];
                let mut cnt = vec![0usize; k];
                for (j, &l) in chunk.iter().enumerate() {
                    let p = point(ci * CHUNK + j);
                    cnt[l as usize] += 1;
                    for (a, &b) in s[l as usize * dim..(l as usize + 1) * dim]
                        .iter_mut()
                        .zip(p)
                    {
                        *a += b as f64;
                    }
                }
                (s, cnt)
            })
            .collect();
        let mut s = vec![0.0f64; k * dim];
        let mut cnt = vec![0usize; k];
        for (ps, pc) in &partial {
            s.iter_mut().zip(ps).for_each(|(a, b)| *a += b);
            cnt.iter_mut().zip(pc).for_each(|(a, b)| *a += b);
        }
        let mut moved = false;
        for c in 0..k {
            if cnt[c] == 0 {
                continue; // Keep an empty cluster's centroid where it was.
            }
            for d in 0..dim {
                let v = (s[c * dim + d] / cnt[c] as f64) as f32;
                if v != centroids[c * dim + d] {
                    moved = true;
                }
                centroids[c * dim + d] = v;
            }
        }
        if !moved {
            break;
        }
    }
    // Final assignment and ordering of clusters by centroid mean.
    let mut order: Vec<usize> = (0..k).collect();
    let mean = |c: usize| centroids[c * dim..(c + 1) * dim].iter().sum::<f32>() / dim as f32;
    order.sort_by(|&a, &b| mean(a).total_cmp(&mean(b)).then(a.cmp(&b)));
    let sorted: Vec<f32> = order
        .iter()
        .flat_map(|&c| centroids[c * dim..(c + 1) * dim].iter().copied())
        .collect();
    labels
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(ci, chunk)| {
            for (j, l) in chunk.iter_mut().enumerate() {
                *l = nearest(point(ci * CHUNK + j), &sorted, dim).0;
            }
        });
    KMeans {
        dim,
        centroids: sorted,
        labels,
    }
}
