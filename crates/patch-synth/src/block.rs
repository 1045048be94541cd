//! The steps of one synthesis block (sections 3.2 to 3.4), in the order
//! [`crate::synthesize`] runs them: cluster order, bucket probe, candidates, energy step 1
//! (`alpha G + beta O`), cuts of the survivors (step 2), choice, composite and blending,
//! pasting on the canvas.

use rand::Rng;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

use crate::blend::{PoissonInput, poisson_blend, smooth_crease};
use crate::cut::cut as seam_cut;
use crate::error::{PatchSynthError, Result};
use crate::grid::{smoothstep, translated_dist2, window_mean};
use crate::index::{ExemplarIndex, OverlapShape, PatchRef, Sat, features};
use crate::settings::{Blend, Settings};

/// What every block of one synthesis shares.
pub(crate) struct Shared<'a> {
    pub(crate) index: &'a ExemplarIndex,
    pub(crate) settings: &'a Settings,
    /// The guide padded to the canvas.
    pub(crate) guide: Option<&'a [f32]>,
    pub(crate) block_rects: &'a [[usize; 4]],
    pub(crate) guide_rects: &'a [[usize; 4]],
    /// Summed-area tables the guide distance reads (the exemplars low-passed by
    /// `guide_lowpass`, or their own tables when it is 0).
    pub(crate) guide_sats: &'a [Sat],
    /// Block descriptors of every patch read from `guide_sats` (patch-major, `blocks^2` each)
    /// and the clusters' means of them, when the guide distance uses a low-pass.
    pub(crate) guide_desc: Option<(Vec<f32>, Vec<f32>)>,
}

/// The working canvas (padded to whole patches).
pub(crate) struct Canvas {
    pub(crate) values: Vec<f32>,
    pub(crate) filled: Vec<bool>,
    pub(crate) seam: Vec<bool>,
    pub(crate) source: Vec<u32>,
    pub(crate) cw: usize,
    pub(crate) ch: usize,
}

/// One grid block: its corner and which neighbours it overlaps.
#[derive(Clone, Copy)]
pub(crate) struct Block {
    pub(crate) gx: usize,
    pub(crate) gy: usize,
    pub(crate) x0: usize,
    pub(crate) y0: usize,
    pub(crate) p: usize,
    pub(crate) o: usize,
    pub(crate) has_left: bool,
    pub(crate) has_top: bool,
}

impl Block {
    /// Overlap cells of row `r`: rows < o take the whole width when a top neighbour exists,
    /// the other rows the first o columns when a left neighbour exists.
    pub(crate) fn ov_cols(&self, r: usize) -> usize {
        if self.has_top && r < self.o {
            self.p
        } else if self.has_left {
            self.o
        } else {
            0
        }
    }

    pub(crate) fn n_overlap(&self) -> usize {
        (0..self.p).map(|r| self.ov_cols(r)).sum()
    }

    /// 0 = left strip, 1 = top strip, 2 = both, `None` = the first block.
    fn shape(&self) -> Option<usize> {
        match (self.has_left, self.has_top) {
            (true, false) => Some(0),
            (false, true) => Some(1),
            (true, true) => Some(2),
            (false, false) => None,
        }
    }
}

impl Canvas {
    fn target(&self, b: &Block, r: usize, c: usize) -> f32 {
        self.values[(b.y0 + r) * self.cw + b.x0 + c]
    }
}

/// A candidate after step 1.
pub(crate) struct Scored {
    pub(crate) id: u32,
    pub(crate) h: f32,
    pub(crate) rejected: bool,
    pub(crate) g: f32,
    pub(crate) o: f32,
    pub(crate) s1: f32,
}

/// A survivor's cuts: left-strip path, top-strip path, RMS error along them.
pub(crate) type Cuts = (Vec<usize>, Vec<usize>, f32);

/// The guide's `N x N` block descriptor over the block.
pub(crate) fn target_descriptor(sh: &Shared<'_>, cv: &Canvas, b: &Block) -> Option<Vec<f32>> {
    sh.guide.map(|g| {
        sh.block_rects
            .iter()
            .map(|r| window_mean(g, cv.cw, b.x0 + r[0], b.y0 + r[1], r[2], r[3]))
            .collect()
    })
}

/// Clusters in order of closeness to the target descriptor (section 3.2): after the
/// translation of equation (3) with a guide; unguided on the blocks holding synthesized cells;
/// seeded random for the first unguided block.
pub(crate) fn cluster_order(
    sh: &Shared<'_>,
    cv: &Canvas,
    b: &Block,
    target_desc: Option<&[f32]>,
    rng: &mut Pcg64Mcg,
) -> Vec<(f32, usize)> {
    let index = sh.index;
    let k = index.clusters.k();
    let mut order: Vec<(f32, usize)> = if let Some(d) = target_desc {
        (0..k)
            .map(|c| {
                let cen = match &sh.guide_desc {
                    Some((_, cens)) => &cens[c * d.len()..(c + 1) * d.len()],
                    None => index.clusters.centroid(c),
                };
                (translated_dist2(d, cen, sh.settings.lambda), c)
            })
            .collect()
    } else if b.n_overlap() > 0 {
        let mut d = Vec::with_capacity(sh.block_rects.len());
        for r in sh.block_rects {
            let (mut sum, mut n) = (0.0f64, 0usize);
            for y in r[1]..r[1] + r[3] {
                for x in r[0]..r[0] + r[2] {
                    let i = (b.y0 + y) * cv.cw + b.x0 + x;
                    if cv.filled[i] {
                        sum += cv.values[i] as f64;
                        n += 1;
                    }
                }
            }
            d.push((n > 0).then(|| (sum / n as f64) as f32));
        }
        (0..k)
            .map(|c| {
                let cen = index.clusters.centroid(c);
                let e: f32 = d
                    .iter()
                    .zip(cen)
                    .filter_map(|(a, b)| a.map(|a| (a - b) * (a - b)))
                    .sum();
                (e, c)
            })
            .collect()
    } else {
        (0..k).map(|c| (rng.random::<f32>(), c)).collect()
    };
    order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    order
}

/// The buckets probed: allowed categories of the clusters in `order` until
/// `probe_candidates` patches are gathered.
pub(crate) fn probe_buckets(
    sh: &Shared<'_>,
    b: &Block,
    order: &[(f32, usize)],
    allowed: &[bool],
) -> Result<Vec<usize>> {
    let index = sh.index;
    let ncat = index.categories.len();
    let mut probed = Vec::new();
    let mut gathered = 0usize;
    for &(_, c) in order {
        for (ci, &ok) in allowed.iter().enumerate() {
            let bi = c * ncat + ci;
            if ok && !index.buckets[bi].patches.is_empty() {
                gathered += index.buckets[bi].patches.len();
                probed.push(bi);
            }
        }
        if gathered >= sh.settings.probe_candidates {
            break;
        }
    }
    if probed.is_empty() {
        return Err(PatchSynthError::NoCandidates {
            gx: b.gx,
            gy: b.gy,
            reason: "no exemplar patch of an allowed category".into(),
        });
    }
    Ok(probed)
}

/// Candidates: kd-tree nearest neighbours of the PCA-reduced overlap (section 3.5), re-ranked
/// by the exact overlap error, plus (with a guide) the probed patches closest to the guide's
/// descriptor; every probed patch for the first block (one seeded random patch unguided).
pub(crate) fn candidates(
    sh: &Shared<'_>,
    cv: &Canvas,
    b: &Block,
    probed: &[usize],
    target_desc: Option<&[f32]>,
    rng: &mut Pcg64Mcg,
) -> Vec<u32> {
    let (index, settings) = (sh.index, sh.settings);
    let shape = b.shape();
    let mut cands: Vec<u32> = match shape {
        Some(s) => {
            let f = features(&index.layouts.rects[s], |x, y, ww, hh| {
                window_mean(&cv.values, cv.cw, b.x0 + x, b.y0 + y, ww, hh)
            });
            let mut q = vec![0.0f32; settings.pca_dims];
            index.pcas[s].project(&f, &mut q);
            let ov_shape = [OverlapShape::Left, OverlapShape::Top, OverlapShape::Both][s];
            let fetch = settings.knn.saturating_mul(settings.rerank);
            let target = |r: usize, c: usize| cv.target(b, r, c);
            probed
                .par_iter()
                .flat_map_iter(|&bi| {
                    let bucket = &index.buckets[bi];
                    let mut near: Vec<(f32, u32)> = bucket.trees[s]
                        .nearest(&q, fetch)
                        .into_iter()
                        .map(|(_, item)| {
                            let id = bucket.patches[item as usize];
                            (index.overlap_error(id as usize, ov_shape, target), id)
                        })
                        .collect();
                    if settings.rerank > 1 {
                        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                        near.truncate(settings.knn);
                    }
                    near.into_iter().map(|v| v.1)
                })
                .collect()
        }
        None => probed
            .iter()
            .flat_map(|&bi| index.buckets[bi].patches.iter().copied())
            .collect(),
    };
    // With a guide and an overlap, the patches of the probed buckets whose block descriptors
    // are closest to the guide's (after the translation of equation 3) join the overlap
    // neighbours, so that G and O both have good candidates.
    if let (Some(dg), Some(_)) = (target_desc, shape) {
        let lambda = settings.lambda;
        let mut by_guide: Vec<(f32, u32)> = probed
            .iter()
            .flat_map(|&bi| index.buckets[bi].patches.iter().copied())
            .map(|id| {
                let desc = match &sh.guide_desc {
                    Some((all, _)) => &all[id as usize * dg.len()..(id as usize + 1) * dg.len()],
                    None => index.descriptor(id as usize),
                };
                (translated_dist2(dg, desc, lambda), id)
            })
            .collect();
        let keep = (settings.knn * probed.len()).min(by_guide.len());
        if keep > 0 && keep < by_guide.len() {
            by_guide
                .select_nth_unstable_by(keep - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        }
        cands.extend(by_guide[..keep].iter().map(|v| v.1));
    }
    cands.sort_unstable();
    cands.dedup();
    if sh.guide.is_none() && shape.is_none() && !cands.is_empty() {
        // Unguided first block: nothing to compare with, so a seeded random patch.
        cands = vec![cands[rng.random_range(0..cands.len())]];
    }
    cands
}

/// Step 1: `alpha G + beta O` of every candidate with its translation (equation 3), in
/// parallel and order-preserving, sorted by it.
pub(crate) fn score(sh: &Shared<'_>, cv: &Canvas, b: &Block, cands: &[u32]) -> Vec<Scored> {
    let (index, settings) = (sh.index, sh.settings);
    let p = b.p;
    let n_overlap = b.n_overlap();
    let target = |r: usize, c: usize| cv.target(b, r, c);
    // Guide cell means of the block (for G) and its mean (for h without overlap).
    let gcells: Option<Vec<f32>> = sh.guide.map(|g| {
        sh.guide_rects
            .iter()
            .map(|r| window_mean(g, cv.cw, b.x0 + r[0], b.y0 + r[1], r[2], r[3]))
            .collect()
    });
    let gmean = sh.guide.map(|g| window_mean(g, cv.cw, b.x0, b.y0, p, p));
    let (alpha, beta) = (settings.alpha, settings.beta);
    let mut scored: Vec<Scored> = cands
        .par_iter()
        .map(|&id| {
            let idu = id as usize;
            let mut hsum = 0.0f64;
            if n_overlap > 0 {
                for r in 0..p {
                    let nc = b.ov_cols(r);
                    if nc == 0 {
                        continue;
                    }
                    let row = index.row(idu, r);
                    for c in 0..nc {
                        hsum += (target(r, c) - row[c]) as f64;
                    }
                }
            }
            // Equation (3): mean difference over the compared block.
            let mut hv = if n_overlap > 0 {
                (hsum / n_overlap as f64) as f32
            } else if let Some(gm) = gmean {
                gm - index.box_mean(idu, 0, 0, p, p)
            } else {
                0.0
            };
            let rejected = hv.abs() > settings.lambda;
            if rejected {
                hv = 0.0;
            }
            let ov = if n_overlap > 0 {
                let mut e = 0.0f64;
                for r in 0..p {
                    let nc = b.ov_cols(r);
                    let row = index.row(idu, r);
                    for c in 0..nc {
                        let d = (row[c] + hv - target(r, c)) as f64;
                        e += d * d;
                    }
                }
                (e / n_overlap as f64).sqrt() as f32
            } else {
                0.0
            };
            let g = gcells.as_ref().map_or(0.0, |gc| {
                let e: f64 = sh
                    .guide_rects
                    .iter()
                    .zip(gc)
                    .map(|(r, &gv)| {
                        let m = index.box_mean_in(sh.guide_sats, idu, r[0], r[1], r[2], r[3]);
                        let d = (m + hv - gv) as f64;
                        d * d
                    })
                    .sum();
                (e / sh.guide_rects.len() as f64).sqrt() as f32
            });
            Scored {
                id,
                h: hv,
                rejected,
                g,
                o: ov,
                s1: alpha * g + beta * ov,
            }
        })
        .collect();
    scored.sort_by(|a, b| a.s1.total_cmp(&b.s1).then(a.id.cmp(&b.id)));
    scored
}

/// Step 2: the minimum-error cuts of each survivor through its overlap strips and their RMS
/// error `P`.
pub(crate) fn cut_survivors(
    sh: &Shared<'_>,
    cv: &Canvas,
    b: &Block,
    survivors: &[Scored],
) -> Vec<Cuts> {
    let (index, settings) = (sh.index, sh.settings);
    let (p, o) = (b.p, b.o);
    let margin = o / 4;
    survivors
        .par_iter()
        .map(|sc| {
            let idu = sc.id as usize;
            let err = |r: usize, c: usize| {
                let d = index.row(idu, r)[c] + sc.h - cv.target(b, r, c);
                d * d
            };
            let (mut cost, mut len) = (0.0f64, 0usize);
            // One strip's cut: `transposed` walks the top strip with patch columns as rows, so
            // both strips share the same DP over a p x o error table.
            let mut strip_cut = |present: bool, transposed: bool| {
                if !present {
                    return Vec::new();
                }
                let e: Vec<f32> = (0..p)
                    .flat_map(|i| (0..o).map(move |j| if transposed { (j, i) } else { (i, j) }))
                    .map(|(r, c)| err(r, c))
                    .collect();
                let cut = seam_cut(&e, o, margin, o - 1 - margin, settings.cut);
                cost += cut.cost;
                len += p;
                cut.path
            };
            let left = strip_cut(b.has_left, false);
            let top = strip_cut(b.has_top, true);
            let pc = if len > 0 {
                (cost / len as f64).sqrt() as f32
            } else {
                0.0
            };
            (left, top, pc)
        })
        .collect()
}

/// The patch-reuse penalty (before the survivors are taken): the step-1 energy of every
/// candidate whose source lies less than half a patch from the source of a placed block within
/// `reuse_radius` (`nearby`, same exemplar) is multiplied by `1 + reuse_penalty * n` (`n` such
/// blocks), and the candidates re-sorted, so other sources take the survivors' places.
pub(crate) fn penalise_reuse(sh: &Shared<'_>, scored: &mut [Scored], nearby: &[PatchRef]) {
    let settings = sh.settings;
    if settings.reuse_penalty == 0.0 || nearby.is_empty() {
        return;
    }
    let half = (settings.patch_size / 2) as i64;
    for sc in scored.iter_mut() {
        let me = sh.index.patches[sc.id as usize];
        let n = nearby
            .iter()
            .filter(|q| {
                q.exemplar == me.exemplar
                    && (q.x as i64 - me.x as i64).abs() < half
                    && (q.y as i64 - me.y as i64).abs() < half
            })
            .count();
        sc.s1 *= 1.0 + settings.reuse_penalty * n as f32;
    }
    scored.sort_by(|a, b| a.s1.total_cmp(&b.s1).then(a.id.cmp(&b.id)));
}

/// The final choice: uniformly (seeded) among the survivors whose energy `M` is within
/// `choice_tolerance` of the best. Returns the pick and every energy.
pub(crate) fn choose(
    settings: &Settings,
    survivors: &[Scored],
    cuts: &[Cuts],
    rng: &mut Pcg64Mcg,
) -> (usize, Vec<f32>) {
    let energies: Vec<f32> = survivors
        .iter()
        .zip(cuts)
        .map(|(sc, cut)| sc.s1 + settings.gamma * cut.2)
        .collect();
    let best = energies.iter().copied().fold(f32::INFINITY, f32::min);
    let limit = best * (1.0 + settings.choice_tolerance) + 1e-6;
    let near: Vec<usize> = (0..energies.len())
        .filter(|&i| energies[i] <= limit)
        .collect();
    if near.is_empty() {
        // Non-finite energies (inputs are checked against this, so defensive only): the
        // smallest in total order, never a panic.
        let best = (0..energies.len())
            .min_by(|&a, &b| energies[a].total_cmp(&energies[b]))
            .unwrap_or(0);
        return (best, energies);
    }
    (near[rng.random_range(0..near.len())], energies)
}

/// Insertion: composite of old and new along the cuts, blending, then the block written on
/// the canvas (values, source, seams) and the crease smoothed. Returns the Poisson
/// iterations.
pub(crate) fn insert(
    sh: &Shared<'_>,
    cv: &mut Canvas,
    b: &Block,
    sc: &Scored,
    cut: &Cuts,
    placement: u32,
) -> usize {
    let (index, settings) = (sh.index, sh.settings);
    let (p, (left, top, _)) = (b.p, cut);
    let idu = sc.id as usize;
    let is_new = |r: usize, c: usize| (!b.has_left || c >= left[r]) && (!b.has_top || r >= top[c]);
    let nv = |r: usize, c: usize| index.row(idu, r)[c] + sc.h;
    let mut poisson_iters = 0;
    let mut out = vec![0.0f32; p * p];
    {
        let cvr: &Canvas = cv;
        let target = |r: usize, c: usize| cvr.target(b, r, c);
        let ov_cols = |r: usize| b.ov_cols(r);
        for r in 0..p {
            let nc = ov_cols(r);
            for c in 0..p {
                out[r * p + c] = if c < nc && !is_new(r, c) {
                    target(r, c)
                } else {
                    nv(r, c)
                };
            }
        }
        match settings.blend {
            Blend::None => {}
            Blend::Feather { radius } => {
                for r in 0..p {
                    for c in 0..ov_cols(r) {
                        let wl = if b.has_left {
                            smoothstep((c as f32 + 0.5 - left[r] as f32 + radius) / (2.0 * radius))
                        } else {
                            1.0
                        };
                        let wt = if b.has_top {
                            smoothstep((r as f32 + 0.5 - top[c] as f32 + radius) / (2.0 * radius))
                        } else {
                            1.0
                        };
                        let wgt = wl * wt;
                        out[r * p + c] = wgt * nv(r, c) + (1.0 - wgt) * target(r, c);
                    }
                }
            }
            Blend::Poisson { max_iterations } | Blend::Screened { max_iterations, .. } => {
                let (whole, screen) = match settings.blend {
                    Blend::Screened { decay, .. } => (true, 1.0 / (decay as f64 * decay as f64)),
                    _ => (false, 0.0),
                };
                if b.n_overlap() > 0 {
                    let (cw, ch) = (cvr.cw, cvr.ch);
                    poisson_iters += poisson_blend(
                        &mut out,
                        PoissonInput {
                            p,
                            whole,
                            screen,
                            ov_cols: &ov_cols,
                            is_new: &is_new,
                            nv: &nv,
                            old: &target,
                            outside: &|x: isize, y: isize| {
                                let (ax, ay) = (b.x0 as isize + x, b.y0 as isize + y);
                                if ax < 0 || ay < 0 || ax >= cw as isize || ay >= ch as isize {
                                    return None;
                                }
                                let i = ay as usize * cw + ax as usize;
                                cvr.filled[i].then_some(cvr.values[i])
                            },
                        },
                        max_iterations,
                    );
                }
            }
        }
    }
    let cw = cv.cw;
    for r in 0..p {
        let nc = b.ov_cols(r);
        for c in 0..p {
            let i = (b.y0 + r) * cw + b.x0 + c;
            cv.values[i] = out[r * p + c];
            cv.filled[i] = true;
            if c >= nc || is_new(r, c) {
                cv.source[i] = placement;
            }
        }
    }
    for (r, &c) in left.iter().enumerate() {
        cv.seam[(b.y0 + r) * cw + b.x0 + c] = true;
    }
    for (c, &r) in top.iter().enumerate() {
        cv.seam[(b.y0 + r) * cw + b.x0 + c] = true;
    }
    if settings.crease_passes > 0 && b.n_overlap() > 0 {
        smooth_crease(
            &mut cv.values,
            &cv.filled,
            cw,
            cv.ch,
            (b.x0, b.y0),
            left,
            top,
            settings.crease_passes,
        );
    }
    poisson_iters
}
