//! Exemplar categories and the categorisation map (sections 3.1 and 4).

use rayon::prelude::*;
use relief_heightfield::Heightfield;

use crate::error::{PatchSynthError, Result};
use crate::index::{Sat, check_exemplars, grid_rects};
use crate::kmeans::{KMeans, kmeans, nearest};
use crate::settings::Settings;

/// Map value that allows every category.
pub const ANY_CATEGORY: u16 = u16::MAX;

/// Per-cell category ids at the target resolution: a synthesis block accepts the exemplar
/// categories that occur inside its window ([`ANY_CATEGORY`] accepts all).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CategoryMap {
    /// Width in cells.
    pub width: usize,
    /// Height in cells.
    pub height: usize,
    /// Row-major category ids.
    pub ids: Vec<u16>,
}

impl CategoryMap {
    /// A map from a user raster (e.g. a painted image decoded to ids).
    pub fn from_raster(width: usize, height: usize, ids: Vec<u16>) -> Result<Self> {
        if width == 0 || height == 0 || ids.len() != width * height {
            return Err(PatchSynthError::InvalidControl {
                name: "categories",
                reason: format!("{} ids for a {width} x {height} map", ids.len()),
            });
        }
        Ok(Self { width, height, ids })
    }

    /// A map from a raster of category ids (e.g. a grey PNG read as raw counts), rounded and
    /// nearest-resampled to `width x height`; a value outside 0..=65535 is an error naming it.
    pub fn from_heightfield(map: &Heightfield, width: usize, height: usize) -> Result<Self> {
        if width == 0
            || height == 0
            || width
                .checked_mul(height)
                .is_none_or(|n| n > crate::MAX_OUTPUT_CELLS)
        {
            return Err(PatchSynthError::InvalidControl {
                name: "categories",
                reason: format!("a {width} x {height} map is empty or too large"),
            });
        }
        let (mw, mh) = (map.width(), map.height());
        let mut ids = Vec::with_capacity(width * height);
        for y in 0..height {
            let sy = (y * mh / height).min(mh - 1);
            for x in 0..width {
                let sx = (x * mw / width).min(mw - 1);
                let v = map.get(sx, sy);
                if !(v.is_finite() && v >= 0.0 && v <= ANY_CATEGORY as f32) {
                    return Err(PatchSynthError::InvalidControl {
                        name: "categories",
                        reason: format!("value {v} at ({sx}, {sy}) is not a category id 0..65535"),
                    });
                }
                ids.push(v.round() as u16);
            }
        }
        Self::from_raster(width, height, ids)
    }

    /// A map with one category everywhere.
    pub fn uniform(width: usize, height: usize, id: u16) -> Self {
        Self {
            width,
            height,
            ids: vec![id; width * height],
        }
    }

    /// Clusters the guide's heights into `k` classes by k-means (section 3.1); class 0 is the
    /// lowest. Returns the map and the class centres (metres, ascending).
    pub fn from_guide_heights(
        guide: &Heightfield,
        k: usize,
        seed: u64,
    ) -> Result<(Self, Vec<f32>)> {
        guide.require_complete()?;
        if k == 0 || k > 1024 {
            return Err(PatchSynthError::setting("k", k, "must be in 1..=1024"));
        }
        let km = kmeans(guide.as_slice(), 1, k, 50, seed);
        let ids = km.labels.iter().map(|&l| l as u16).collect();
        Ok((
            Self {
                width: guide.width(),
                height: guide.height(),
                ids,
            },
            km.centroids,
        ))
    }

    /// Replaces every occurrence of `from` by `to` (e.g. to associate a height class with an
    /// exemplar category).
    pub fn relabel(&mut self, from: u16, to: u16) {
        self.ids
            .iter_mut()
            .filter(|v| **v == from)
            .for_each(|v| *v = to);
    }
}

/// Block-average descriptors (`N x N` means, section 3.2) of the patches of every exemplar on
/// a grid of step `max(overlap, exemplar_stride)` (bounded cost on large exemplars), one flat
/// vector per exemplar (`dim` values a patch), and their k-means clustering into `k` classes
/// (at least ten iterations, seeded); `settings` and `k` are checked here.
fn cluster_grid(
    exemplars: &[Heightfield],
    k: usize,
    settings: &Settings,
) -> Result<(Vec<Vec<f32>>, usize, KMeans)> {
    settings.check()?;
    if k == 0 || k > 1024 {
        return Err(PatchSynthError::setting("k", k, "must be in 1..=1024"));
    }
    let ex: Vec<crate::index::Exemplar> = exemplars
        .iter()
        .map(|h| crate::index::Exemplar::new(h.clone(), 0))
        .collect();
    check_exemplars(&ex, settings.patch_size)?;
    let p = settings.patch_size;
    let rects = grid_rects(p, settings.blocks);
    let step = settings.overlap.max(settings.exemplar_stride);
    let per: Vec<Vec<f32>> = exemplars
        .par_iter()
        .map(|hf| {
            let sat = Sat::new(hf);
            let mut d = Vec::new();
            for y in (0..=hf.height() - p).step_by(step) {
                for x in (0..=hf.width() - p).step_by(step) {
                    d.extend(
                        rects
                            .iter()
                            .map(|r| sat.mean(x + r[0], y + r[1], r[2], r[3])),
                    );
                }
            }
            d
        })
        .collect();
    let dim = rects.len();
    let all: Vec<f32> = per.iter().flatten().copied().collect();
    let iterations = settings.kmeans_iterations.max(10);
    let km = kmeans(&all, dim, k, iterations, settings.seed);
    Ok((per, dim, km))
}

/// Automatic exemplar categories (section 4): the patches of all exemplars are clustered into
/// `k` classes by their `N x N` block averages (k-means), classes ordered by mean height; each
/// exemplar takes the class most of its patches fall in. Returns one category per exemplar.
/// With a single exemplar (or exemplars that each hold several kinds of ground), use
/// [`categorize_regions`].
pub fn categorize_exemplars(
    exemplars: &[Heightfield],
    k: usize,
    settings: &Settings,
) -> Result<Vec<u16>> {
    let (per, dim, km) = cluster_grid(exemplars, k, settings)?;
    let mut out = Vec::with_capacity(exemplars.len());
    let mut start = 0;
    for d in &per {
        let n = d.len() / dim;
        let mut votes = vec![0usize; km.k()];
        for &l in &km.labels[start..start + n] {
            votes[l as usize] += 1;
        }
        start += n;
        let best = (0..votes.len()).max_by(|&a, &b| votes[a].cmp(&votes[b]).then(b.cmp(&a)));
        out.push(best.unwrap_or(0) as u16);
    }
    Ok(out)
}

/// Categories by region (section 4: "we cluster the patches from exemplars according to the
/// blocks of average of pieces, and create the categorization according to this
/// clustering"): the patches of all exemplars are clustered into `k` classes by their
/// `N x N` block averages (k-means on a grid of patches), classes numbered by ascending mean
/// height, and every cell of every exemplar takes the class nearest to the descriptor of the
/// patch centred on it (clamped inside the exemplar). One exemplar thus holds several
/// categories (valley floor, slopes, rims), and a categorisation map can send each region
/// of the output to its own kind of ground. Returns a row-major category raster per exemplar
/// (for [`crate::Exemplar::with_regions`]).
pub fn categorize_regions(
    exemplars: &[Heightfield],
    k: usize,
    settings: &Settings,
) -> Result<Vec<Vec<u16>>> {
    let (_, dim, km) = cluster_grid(exemplars, k, settings)?;
    let p = settings.patch_size;
    let rects = grid_rects(p, settings.blocks);
    Ok(exemplars
        .iter()
        .map(|hf| {
            let sat = Sat::new(hf);
            let (w, h) = (hf.width(), hf.height());
            let mut out = vec![0u16; w * h];
            out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
                let py = y.saturating_sub(p / 2).min(h - p);
                let mut d = vec![0.0f32; dim];
                for (x, c) in row.iter_mut().enumerate() {
                    let px = x.saturating_sub(p / 2).min(w - p);
                    for (v, r) in d.iter_mut().zip(&rects) {
                        *v = sat.mean(px + r[0], py + r[1], r[2], r[3]);
                    }
                    *c = nearest(&d, &km.centroids, dim).0 as u16;
                }
            });
            out
        })
        .collect())
}
