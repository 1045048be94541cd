//! Preprocessing (section 3.5): every exemplar patch gets its `N x N` block-average descriptor
//! (section 3.2), the descriptors are clustered by k-means into the keys of a hash table whose
//! buckets are further split by exemplar category, and the overlap regions (left strip, top
//! strip and the L-shaped corner) are reduced by PCA and stored per bucket in kd-trees.

use std::num::NonZero;

use kiddo::SquaredEuclidean;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use relief_heightfield::{Heightfield, Progress};

use crate::error::{PatchSynthError, Result};
use crate::grid::{Layouts, bounds};
use crate::kmeans::{KMeans, kmeans};
use crate::pca::Pca;
use crate::settings::Settings;

/// An exemplar DEM with its category (section 3.1), or with categories by region.
#[derive(Debug, Clone)]
pub struct Exemplar {
    /// The exemplar terrain (void-free).
    pub heightfield: Heightfield,
    /// Category id; the categorisation map names which categories each target region accepts.
    pub category: u16,
    /// Category of every cell (row-major, the exemplar's size), when regions of one exemplar
    /// belong to different categories (section 4 clusters the patches, not the exemplars; see
    /// [`crate::categorize_regions`]). A patch takes the category of its centre cell;
    /// `None` = `category` for every patch.
    pub regions: Option<Vec<u16>>,
}

impl Exemplar {
    /// An exemplar with a category.
    pub fn new(heightfield: Heightfield, category: u16) -> Self {
        Self {
            heightfield,
            category,
            regions: None,
        }
    }

    /// The same exemplar with a category per cell (`regions`, row-major, the exemplar's size;
    /// checked when the index is built).
    pub fn with_regions(mut self, regions: Vec<u16>) -> Self {
        self.regions = Some(regions);
        self
    }

    /// Category of the patch of side `p` whose top-left cell is `(x, y)`.
    pub(crate) fn patch_category(&self, x: usize, y: usize, p: usize) -> u16 {
        match &self.regions {
            Some(r) => r[(y + p / 2) * self.heightfield.width() + x + p / 2],
            None => self.category,
        }
    }
}

/// Summed-area table for O(1) box sums.
#[derive(Debug, Clone)]
pub(crate) struct Sat {
    w: usize,
    data: Vec<f64>,
}

impl Sat {
    pub(crate) fn new(hf: &Heightfield) -> Self {
        let (w, h) = (hf.width(), hf.height());
        let s = hf.as_slice();
        let mut data = vec![0.0f64; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0.0f64;
            for x in 0..w {
                row += s[y * w + x] as f64;
                data[(y + 1) * (w + 1) + x + 1] = data[y * (w + 1) + x + 1] + row;
            }
        }
        Self { w, data }
    }
    #[inline]
    pub(crate) fn mean(&self, x: usize, y: usize, w: usize, h: usize) -> f32 {
        let s = self.w + 1;
        let (x1, y1) = (x + w, y + h);
        let v = self.data[y1 * s + x1] - self.data[y * s + x1] - self.data[y1 * s + x]
            + self.data[y * s + x];
        (v / (w * h) as f64) as f32
    }
}

/// Box means of one exemplar at every top-left position, one image per box size a layout uses:
/// the index build reads each feature with one load instead of four summed-area reads. The
/// values are [`Sat::mean`]'s, so the index does not change. Lives only during the build
/// (`4 W H` bytes per box size).
struct BoxMeans {
    /// Exemplar width (row stride of every image).
    w: usize,
    /// `(box width, box height, image)`; image cell `y * w + x` is the mean of the box at
    /// `(x, y)` (0 where the box would leave the exemplar).
    images: Vec<(usize, usize, Vec<f32>)>,
}

impl BoxMeans {
    fn new(sat: &Sat, w: usize, h: usize, sizes: &[(usize, usize)]) -> Self {
        let images = sizes
            .iter()
            .map(|&(bw, bh)| {
                let mut img = vec![0.0f32; w * h];
                if bw <= w && bh <= h {
                    img.par_chunks_mut(w)
                        .take(h - bh + 1)
                        .enumerate()
                        .for_each(|(y, row)| {
                            for (x, v) in row[..=w - bw].iter_mut().enumerate() {
                                *v = sat.mean(x, y, bw, bh);
                            }
                        });
                }
                (bw, bh, img)
            })
            .collect();
        Self { w, images }
    }

    /// `(image, offset)` of every rectangle (patch coordinates): a patch at `(px, py)` reads
    /// rectangle `i` at `images[plan[i].0][py * w + px + plan[i].1]`. `None` when a size has no
    /// image (never for the sizes the build asked for).
    fn plan(&self, rects: &[[usize; 4]]) -> Option<Vec<(usize, usize)>> {
        rects
            .iter()
            .map(|r| {
                let i = self
                    .images
                    .iter()
                    .position(|i| i.0 == r[2] && i.1 == r[3])?;
                Some((i, r[1] * self.w + r[0]))
            })
            .collect()
    }

    /// The box means of `plan`'s rectangles for the patch at `(px, py)`.
    #[inline]
    fn gather(&self, plan: &[(usize, usize)], px: usize, py: usize) -> Vec<f32> {
        let base = py * self.w + px;
        plan.iter()
            .map(|&(i, off)| self.images[i].2[base + off])
            .collect()
    }
}

/// The distinct box sizes of a set of rectangles.
fn box_sizes<'a>(rects: impl IntoIterator<Item = &'a [usize; 4]>) -> Vec<(usize, usize)> {
    let mut sizes: Vec<(usize, usize)> = rects.into_iter().map(|r| (r[2], r[3])).collect();
    sizes.sort_unstable();
    sizes.dedup();
    sizes
}

/// Rectangles `(x, y, w, h)` (patch coordinates) of an `n x n` grid of cells.
pub(crate) fn grid_rects(size: usize, n: usize) -> Vec<[usize; 4]> {
    let b = bounds(size, n);
    let mut r = Vec::with_capacity(n * n);
    for &(y, h) in &b {
        for &(x, w) in &b {
            r.push([x, y, w, h]);
        }
    }
    r
}

/// Which already-synthesized neighbours a grid block overlaps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OverlapShape {
    /// Only the left strip (first row of the grid).
    Left = 0,
    /// Only the top strip (first column).
    Top = 1,
    /// Both strips (the L-shaped region).
    Both = 2,
}

/// Mean-removed box-mean features of one shape, from a box-mean function in patch coordinates.
pub(crate) fn features(
    rects: &[[usize; 4]],
    mean: impl Fn(usize, usize, usize, usize) -> f32,
) -> Vec<f32> {
    remove_mean(rects.iter().map(|r| mean(r[0], r[1], r[2], r[3])).collect())
}

/// `f` minus its mean.
fn remove_mean(mut f: Vec<f32>) -> Vec<f32> {
    let m = f.iter().sum::<f32>() / f.len() as f32;
    f.iter_mut().for_each(|v| *v -= m);
    f
}

macro_rules! trees {
    ($($v:ident = $k:literal),*) => {
        /// A kd-tree over PCA coordinates, monomorphised for the supported dimensions.
        pub(crate) enum Tree { $($v(ImmutableKdTree<f32, u32, $k, 32>)),* }
        impl Tree {
            fn build(points: &[f32], k: usize) -> Tree {
                match k {
                    $($k => {
                        let pts: Vec<[f32; $k]> = points
                            .chunks_exact($k)
                            .map(|c| c.try_into().expect("chunk of k values"))
                            .collect();
                        Tree::$v(ImmutableKdTree::new_from_slice(&pts))
                    })*
                    _ => unreachable!("pca_dims is checked by Settings::check"),
                }
            }
            /// The `n` nearest items `(squared distance, item)`.
            pub(crate) fn nearest(&self, q: &[f32], n: usize) -> Vec<(f32, u32)> {
                let n = NonZero::new(n.max(1)).expect("n >= 1");
                match self {
                    $(Tree::$v(t) => {
                        let q: [f32; $k] = q.try_into().expect("query of k values");
                        t.nearest_n::<SquaredEuclidean>(&q, n)
                            .into_iter()
                            .map(|nn| (nn.distance, nn.item))
                            .collect()
                    })*
                }
            }
        }
    };
}
trees!(D4 = 4, D6 = 6, D8 = 8, D12 = 12, D16 = 16);

/// One hash-table bucket: the patches of one k-means cluster and one category, with a kd-tree
/// of their PCA-reduced overlap features for every overlap shape.
pub(crate) struct Bucket {
    pub(crate) patches: Vec<u32>,
    pub(crate) trees: Vec<Tree>,
}

/// A patch of an exemplar: exemplar index and top-left corner.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PatchRef {
    /// Index of the exemplar.
    pub exemplar: u32,
    /// Column of the top-left cell.
    pub x: u32,
    /// Row of the top-left cell.
    pub y: u32,
}

/// The preprocessed exemplar set: descriptors, hash table, PCA bases and kd-trees (built once,
/// reusable for many syntheses with the same patch geometry).
pub struct ExemplarIndex {
    /// The settings the index was built with (its patch geometry is checked against the
    /// synthesis settings, [`ExemplarIndex::check_settings`]).
    pub(crate) built_with: Settings,
    pub(crate) exemplars: Vec<Exemplar>,
    pub(crate) sats: Vec<Sat>,
    pub(crate) patches: Vec<PatchRef>,
    /// `N * N` block means per patch.
    pub(crate) descriptors: Vec<f32>,
    pub(crate) clusters: KMeans,
    /// Distinct categories, sorted.
    pub(crate) categories: Vec<u16>,
    /// Category of every patch.
    pub(crate) patch_categories: Vec<u16>,
    /// `cluster * categories.len() + category index`.
    pub(crate) buckets: Vec<Bucket>,
    pub(crate) layouts: Layouts,
    pub(crate) pcas: Vec<Pca>,
    /// Patch ids sorted by the mean of their descriptor, and those means.
    pub(crate) by_mean: Vec<(f32, u32)>,
}

impl std::fmt::Debug for ExemplarIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ExemplarIndex")
            .field("exemplars", &self.exemplars.len())
            .field("patches", &self.patches.len())
            .field("clusters", &self.clusters.k())
            .field("categories", &self.categories)
            .field(
                "buckets",
                &self
                    .buckets
                    .iter()
                    .filter(|b| !b.patches.is_empty())
                    .count(),
            )
            .finish()
    }
}

/// Largest exemplar height magnitude (1e9: metres, millimetres and any plausible unit; the
/// squared differences of 64 x 64 patches of such heights stay far below `f32::MAX`).
pub(crate) const MAX_HEIGHT: f32 = 1e9;

pub(crate) fn check_exemplars(exemplars: &[Exemplar], patch: usize) -> Result<()> {
    if exemplars.is_empty() {
        return Err(PatchSynthError::NoExemplars);
    }
    for (i, e) in exemplars.iter().enumerate() {
        let hf = &e.heightfield;
        let bad = |reason: String| PatchSynthError::BadExemplar {
            index: i,
            width: hf.width(),
            height: hf.height(),
            reason,
        };
        if hf.width() < patch || hf.height() < patch {
            return Err(bad(format!("smaller than patch_size = {patch}")));
        }
        if hf.has_voids() {
            return Err(bad(format!(
                "{} void cells; fill them first",
                hf.void_count()
            )));
        }
        if hf.as_slice().iter().any(|v| !v.is_finite()) {
            return Err(bad("non-finite heights".into()));
        }
        // Squared height differences summed over a patch must stay finite in f32.
        if let Some(v) = hf.as_slice().iter().find(|v| v.abs() > MAX_HEIGHT) {
            return Err(bad(format!(
                "a height of {v:e} is beyond +-{MAX_HEIGHT:e} (patch distances would overflow); \
                 scale the heights to metres"
            )));
        }
        if let Some(r) = &e.regions {
            if r.len() != hf.len() {
                return Err(bad(format!(
                    "{} region categories for {} cells",
                    r.len(),
                    hf.len()
                )));
            }
            if r.contains(&crate::ANY_CATEGORY) {
                return Err(bad(format!(
                    "region category {} (any) is for the categorisation map only",
                    crate::ANY_CATEGORY
                )));
            }
        }
    }
    Ok(())
}

impl ExemplarIndex {
    /// Preprocesses `exemplars` for `settings` (checked here).
    pub fn build(
        exemplars: Vec<Exemplar>,
        settings: &Settings,
        progress: &dyn Progress,
    ) -> Result<Self> {
        settings.check()?;
        let p = settings.patch_size;
        check_exemplars(&exemplars, p)?;
        let stride = settings.exemplar_stride;
        let sats: Vec<Sat> = exemplars
            .par_iter()
            .map(|e| Sat::new(&e.heightfield))
            .collect();
        let patches = patch_positions(&exemplars, p, stride)?;
        progress.begin("patch-synth: descriptors", patches.len() as u64);
        let n = settings.blocks;
        let block_rects = grid_rects(p, n);
        let layouts = Layouts::new(p, settings.overlap);
        let sizes = box_sizes(block_rects.iter().chain(layouts.rects.iter().flatten()));
        let boxes: Vec<BoxMeans> = exemplars
            .iter()
            .zip(&sats)
            .map(|(e, sat)| {
                let hf = &e.heightfield;
                BoxMeans::new(sat, hf.width(), hf.height(), &sizes)
            })
            .collect();
        // Per exemplar: the plans of the descriptor cells and of the three overlap shapes.
        let plans: Vec<[Vec<(usize, usize)>; 4]> = boxes
            .iter()
            .map(|b| {
                let plan = |rects: &[[usize; 4]]| b.plan(rects).unwrap_or_default();
                [
                    plan(&block_rects),
                    plan(&layouts.rects[0]),
                    plan(&layouts.rects[1]),
                    plan(&layouts.rects[2]),
                ]
            })
            .collect();
        let gather = |pr: PatchRef, set: usize| {
            let e = pr.exemplar as usize;
            boxes[e].gather(&plans[e][set], pr.x as usize, pr.y as usize)
        };
        let descriptors: Vec<f32> = patches
            .par_iter()
            .flat_map_iter(|&pr| gather(pr, 0))
            .collect();
        progress.advance(patches.len() as u64);
        progress.begin("patch-synth: k-means", settings.kmeans_iterations as u64);
        let clusters = kmeans(
            &descriptors,
            n * n,
            settings.kmeans_clusters,
            settings.kmeans_iterations,
            settings.seed,
        );
        progress.advance(settings.kmeans_iterations as u64);

        let patch_categories: Vec<u16> = patches
            .iter()
            .map(|pr| {
                exemplars[pr.exemplar as usize].patch_category(pr.x as usize, pr.y as usize, p)
            })
            .collect();
        let mut categories = patch_categories.clone();
        categories.sort_unstable();
        categories.dedup();
        let ncat = categories.len();

        let feat = |pid: usize, shape: usize| remove_mean(gather(patches[pid], shape + 1));
        progress.begin("patch-synth: pca", 3);
        let pcas = fit_pcas(&layouts, patches.len(), settings, &feat, progress)?;

        // Buckets: cluster x category.
        let k = clusters.k();
        let mut members: Vec<Vec<u32>> = vec![Vec::new(); k * ncat];
        for (pid, cat) in patch_categories.iter().enumerate() {
            let c = clusters.labels[pid] as usize;
            let ci = categories.binary_search(cat).unwrap_or(0);
            members[c * ncat + ci].push(pid as u32);
        }
        progress.begin("patch-synth: kd-trees", members.len() as u64);
        let buckets = build_buckets(members, settings.pca_dims, &pcas, &feat, progress);
        let nn = n * n;
        let mut by_mean: Vec<(f32, u32)> = (0..patches.len())
            .map(|i| {
                let d = &descriptors[i * nn..(i + 1) * nn];
                (d.iter().sum::<f32>() / nn as f32, i as u32)
            })
            .collect();
        by_mean.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        Ok(Self {
            built_with: settings.clone(),
            exemplars,
            sats,
            patches,
            descriptors,
            clusters,
            categories,
            patch_categories,
            buckets,
            layouts,
            pcas,
            by_mean,
        })
    }
}

/// Every patch position of every exemplar, `stride` cells apart.
fn patch_positions(exemplars: &[Exemplar], p: usize, stride: usize) -> Result<Vec<PatchRef>> {
    let mut patches = Vec::new();
    for (i, e) in exemplars.iter().enumerate() {
        let (w, h) = (e.heightfield.width(), e.heightfield.height());
        for y in (0..=h - p).step_by(stride) {
            for x in (0..=w - p).step_by(stride) {
                patches.push(PatchRef {
                    exemplar: i as u32,
                    x: x as u32,
                    y: y as u32,
                });
            }
        }
    }
    if patches.len() > u32::MAX as usize {
        return Err(PatchSynthError::setting(
            "exemplar_stride",
            stride,
            "too many patches; increase the stride",
        ));
    }
    Ok(patches)
}

/// PCA bases of the three overlap shapes, fitted on seeded random patches (`feat(patch,
/// shape)` gives a patch's overlap features).
fn fit_pcas(
    layouts: &Layouts,
    npatches: usize,
    settings: &Settings,
    feat: &(dyn Fn(usize, usize) -> Vec<f32> + Sync),
    progress: &dyn Progress,
) -> Result<Vec<Pca>> {
    let mut rng = Pcg64Mcg::seed_from_u64(settings.seed ^ 0x7063_6121);
    let ns = settings.pca_samples.min(npatches).max(2);
    let sample: Vec<usize> = (0..ns).map(|_| rng.random_range(0..npatches)).collect();
    let mut pcas = Vec::with_capacity(3);
    for shape in 0..3 {
        let dim = layouts.rects[shape].len();
        let k = settings.pca_dims;
        if k > dim {
            return Err(PatchSynthError::setting(
                "pca_dims",
                k,
                format!("exceeds the {dim} overlap features of this patch geometry"),
            ));
        }
        let data: Vec<f32> = sample.iter().flat_map(|&s| feat(s, shape)).collect();
        pcas.push(Pca::fit(&data, dim, k)?);
        progress.advance(1);
    }
    Ok(pcas)
}

/// One bucket per (cluster, category) with a kd-tree per overlap shape over the PCA projections
/// (`kd` components) of its patches.
fn build_buckets(
    members: Vec<Vec<u32>>,
    kd: usize,
    pcas: &[Pca],
    feat: &(dyn Fn(usize, usize) -> Vec<f32> + Sync),
    progress: &dyn Progress,
) -> Vec<Bucket> {
    // One task per (bucket, shape), largest first: the k-means buckets differ in size by
    // an order of magnitude, and one task per bucket left a thread idle most of the phase.
    let mut tasks: Vec<(usize, usize)> = (0..members.len())
        .filter(|&b| !members[b].is_empty())
        .flat_map(|b| (0..3).map(move |shape| (b, shape)))
        .collect();
    tasks.sort_by_key(|&(b, shape)| (std::cmp::Reverse(members[b].len()), b, shape));
    let mut trees: Vec<(usize, usize, Tree)> = tasks
        .into_par_iter()
        .map(|(b, shape)| {
            let ids = &members[b];
            let mut pts = vec![0.0f32; ids.len() * kd];
            for (j, &pid) in ids.iter().enumerate() {
                let f = feat(pid as usize, shape);
                pcas[shape].project(&f, &mut pts[j * kd..(j + 1) * kd]);
            }
            if shape == 2 {
                progress.advance(1);
            }
            (b, shape, Tree::build(&pts, kd))
        })
        .collect();
    trees.sort_by_key(|t| (t.0, t.1));
    let mut trees = trees.into_iter().peekable();
    members
        .into_iter()
        .enumerate()
        .map(|(b, ids)| {
            let mut t = Vec::new();
            while let Some((_, _, tree)) = trees.next_if(|x| x.0 == b) {
                t.push(tree);
            }
            Bucket {
                patches: ids,
                trees: t,
            }
        })
        .collect()
}

impl ExemplarIndex {
    /// Checks that `settings` use the patch geometry this index was built with.
    pub(crate) fn check_settings(&self, s: &Settings) -> Result<()> {
        let b = &self.built_with;
        let pairs = [
            ("patch_size", s.patch_size, b.patch_size),
            ("overlap", s.overlap, b.overlap),
            ("blocks", s.blocks, b.blocks),
            ("exemplar_stride", s.exemplar_stride, b.exemplar_stride),
            ("kmeans_clusters", s.kmeans_clusters, b.kmeans_clusters),
            ("pca_dims", s.pca_dims, b.pca_dims),
        ];
        for (name, v, iv) in pairs {
            if v != iv {
                return Err(PatchSynthError::IndexMismatch {
                    name,
                    value: v.to_string(),
                    index_value: iv.to_string(),
                });
            }
        }
        Ok(())
    }

    /// The exemplars.
    pub fn exemplars(&self) -> &[Exemplar] {
        &self.exemplars
    }
    /// Every indexed patch.
    pub fn patches(&self) -> &[PatchRef] {
        &self.patches
    }
    /// Block-average descriptor (`N * N` values) of patch `id`.
    pub fn descriptor(&self, id: usize) -> &[f32] {
        let nn = self.built_with.blocks * self.built_with.blocks;
        &self.descriptors[id * nn..(id + 1) * nn]
    }
    /// The k-means clustering of the descriptors (the hash-table keys).
    pub fn clusters(&self) -> &KMeans {
        &self.clusters
    }
    /// Distinct exemplar categories.
    pub fn categories(&self) -> &[u16] {
        &self.categories
    }
    /// Fraction of the overlap-feature variance kept by each PCA (left, top, L-shape).
    pub fn pca_explained(&self) -> [f32; 3] {
        [
            self.pcas[0].explained,
            self.pcas[1].explained,
            self.pcas[2].explained,
        ]
    }
    /// The patch search of section 3.5 for one overlap region, as the synthesis runs it: the
    /// overlap cells of `region` (a `patch_size x patch_size` row-major raster in patch-local
    /// coordinates; only the cells of `shape`'s overlap are read) are reduced to box-mean
    /// features, projected on the shape's PCA basis, and the `knn` nearest patches of every
    /// non-empty bucket's kd-tree are merged, `knn * rerank` per bucket, then re-ranked by the
    /// exact overlap error (mean squared difference over the full-resolution overlap cells,
    /// both means removed). Returns `(exact error in m^2, patch id)` for the `knn` best,
    /// ascending (ties by id). `rerank = 1` keeps the kd-tree's own choice.
    pub fn nearest_overlaps(
        &self,
        shape: OverlapShape,
        region: &[f32],
        knn: usize,
        rerank: usize,
    ) -> Result<Vec<(f32, usize)>> {
        let p = self.built_with.patch_size;
        if region.len() != p * p {
            return Err(PatchSynthError::InvalidControl {
                name: "region",
                reason: format!("{} values for a {p} x {p} patch", region.len()),
            });
        }
        if knn == 0 {
            return Err(PatchSynthError::setting("knn", knn, "must be >= 1"));
        }
        let sh = shape as usize;
        let rects = &self.layouts.rects[sh];
        if rects.iter().any(|r| {
            (r[1]..r[1] + r[3]).any(|y| {
                region[y * p + r[0]..y * p + r[0] + r[2]]
                    .iter()
                    .any(|v| !v.is_finite())
            })
        }) {
            return Err(PatchSynthError::InvalidControl {
                name: "region",
                reason: "non-finite heights in the overlap".into(),
            });
        }
        let f = features(rects, |x, y, w, h| {
            crate::grid::window_mean(region, p, x, y, w, h)
        });
        let mut q = vec![0.0f32; self.built_with.pca_dims];
        self.pcas[sh].project(&f, &mut q);
        let fetch = knn.saturating_mul(rerank.max(1));
        let mut out: Vec<(f32, usize)> = self
            .buckets
            .par_iter()
            .filter(|b| !b.patches.is_empty())
            .flat_map_iter(|b| {
                b.trees[sh]
                    .nearest(&q, fetch)
                    .into_iter()
                    .map(|(_, item)| b.patches[item as usize] as usize)
            })
            .map(|id| {
                let e = self.overlap_error(id, shape, |r, c| region[r * p + c]);
                (e, id)
            })
            .collect();
        out.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        out.truncate(knn);
        Ok(out)
    }

    /// Exact overlap error of patch `id` against a target (`target(row, col)`, patch-local):
    /// the mean squared difference over the overlap cells of `shape` after removing both means
    /// (the vertical translation of equation 3), in square metres.
    pub(crate) fn overlap_error(
        &self,
        id: usize,
        shape: OverlapShape,
        target: impl Fn(usize, usize) -> f32,
    ) -> f32 {
        let (p, o) = (self.built_with.patch_size, self.built_with.overlap);
        let (mut sd, mut sd2, mut n) = (0.0f64, 0.0f64, 0usize);
        for r in 0..p {
            let nc = match shape {
                OverlapShape::Left => o,
                OverlapShape::Top if r < o => p,
                OverlapShape::Top => 0,
                OverlapShape::Both if r < o => p,
                OverlapShape::Both => o,
            };
            let row = self.row(id, r);
            for (c, &v) in row.iter().enumerate().take(nc) {
                let d = (v - target(r, c)) as f64;
                sd += d;
                sd2 += d * d;
            }
            n += nc;
        }
        if n == 0 {
            return 0.0;
        }
        let m = sd / n as f64;
        (sd2 / n as f64 - m * m).max(0.0) as f32
    }

    /// Category of patch `id`.
    pub(crate) fn patch_category(&self, id: usize) -> u16 {
        self.patch_categories[id]
    }
    /// Row `y` of patch `id` (patch-local, `patch_size` values).
    #[inline]
    pub(crate) fn row(&self, id: usize, y: usize) -> &[f32] {
        let pr = self.patches[id];
        let hf = &self.exemplars[pr.exemplar as usize].heightfield;
        let w = hf.width();
        let start = (pr.y as usize + y) * w + pr.x as usize;
        &hf.as_slice()[start..start + self.built_with.patch_size]
    }
    /// Summed-area tables of the exemplars blurred by a Gaussian of `sigma` cells (what the
    /// guide distance compares with [`Settings::guide_lowpass`]).
    pub(crate) fn lowpassed_sats(&self, sigma: f32) -> Result<Vec<Sat>> {
        self.exemplars
            .par_iter()
            .map(|e| crate::grid::gaussian_blur(&e.heightfield, sigma).map(|low| Sat::new(&low)))
            .collect()
    }
    /// With a guide low-pass `sigma > 0`: the low-passed exemplars' tables
    /// ([`Self::lowpassed_sats`]) and the block descriptors read from them
    /// ([`Self::lowpassed_descriptors`]); `None` for the paper's distance (`sigma == 0`).
    #[allow(clippy::type_complexity)]
    pub(crate) fn lowpassed_guide_tables(
        &self,
        sigma: f32,
        rects: &[[usize; 4]],
    ) -> Result<Option<(Vec<Sat>, (Vec<f32>, Vec<f32>))>> {
        if sigma <= 0.0 {
            return Ok(None);
        }
        let sats = self.lowpassed_sats(sigma)?;
        let desc = self.lowpassed_descriptors(&sats, rects);
        Ok(Some((sats, desc)))
    }
    /// Block descriptors of every patch read from `sats` (patch-major, one value per
    /// rectangle of `rects`) and their means over the patches of every cluster (cluster-major).
    pub(crate) fn lowpassed_descriptors(
        &self,
        sats: &[Sat],
        rects: &[[usize; 4]],
    ) -> (Vec<f32>, Vec<f32>) {
        let n = rects.len();
        let all: Vec<f32> = (0..self.patches.len())
            .into_par_iter()
            .flat_map_iter(|id| {
                rects
                    .iter()
                    .map(move |r| self.box_mean_in(sats, id, r[0], r[1], r[2], r[3]))
            })
            .collect();
        let k = self.clusters.k();
        let ncat = self.categories.len();
        let mut cens = vec![0.0f32; k * n];
        for c in 0..k {
            let mut sum = vec![0.0f64; n];
            let mut count = 0usize;
            for ci in 0..ncat {
                for &id in &self.buckets[c * ncat + ci].patches {
                    for (s, v) in sum
                        .iter_mut()
                        .zip(&all[id as usize * n..(id as usize + 1) * n])
                    {
                        *s += *v as f64;
                    }
                    count += 1;
                }
            }
            if count == 0 {
                cens[c * n..(c + 1) * n].copy_from_slice(self.clusters.centroid(c));
            } else {
                for (o, s) in cens[c * n..(c + 1) * n].iter_mut().zip(&sum) {
                    *o = (s / count as f64) as f32;
                }
            }
        }
        (all, cens)
    }
    /// Box mean over a rectangle of patch `id` of the tables `sats` (one per exemplar).
    #[inline]
    pub(crate) fn box_mean_in(
        &self,
        sats: &[Sat],
        id: usize,
        x: usize,
        y: usize,
        w: usize,
        h: usize,
    ) -> f32 {
        let pr = self.patches[id];
        sats[pr.exemplar as usize].mean(pr.x as usize + x, pr.y as usize + y, w, h)
    }
    /// Box mean over a rectangle of patch `id` (patch-local).
    #[inline]
    pub(crate) fn box_mean(&self, id: usize, x: usize, y: usize, w: usize, h: usize) -> f32 {
        self.box_mean_in(&self.sats, id, x, y, w, h)
    }
}
