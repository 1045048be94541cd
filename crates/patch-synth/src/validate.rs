//! Input validation and exemplar selection (section 4).

use rayon::prelude::*;

use crate::control::{Control, allowed_categories};
use crate::error::Result;
use crate::grid::{Grid, grid_for, pad, window_mean};
use crate::index::{ExemplarIndex, grid_rects};
pub use crate::report::{BlockReport, ExemplarCompatibility, ValidationReport};
use crate::settings::Settings;

/// Does descriptor `dp` match `dg` within `tol` (RMS) after the vertical translation of
/// equation (3), dropped when larger than `lambda`?
fn matches(dp: &[f32], dg: &[f32], lambda: f32, tol: f32) -> bool {
    let n = dp.len() as f32;
    let mut h = dg.iter().zip(dp).map(|(g, p)| g - p).sum::<f32>() / n;
    if h.abs() > lambda {
        h = 0.0;
    }
    let e: f32 = dg
        .iter()
        .zip(dp)
        .map(|(g, p)| (p + h - g) * (p + h - g))
        .sum();
    (e / n).sqrt() <= tol
}

/// Patch ids whose descriptor mean lies in `[lo, hi]`.
fn mean_range(index: &ExemplarIndex, lo: f32, hi: f32) -> &[(f32, u32)] {
    let a = index.by_mean.partition_point(|v| v.0 < lo);
    let b = index.by_mean.partition_point(|v| v.0 <= hi);
    &index.by_mean[a..b.max(a)]
}

fn std_of(values: impl Iterator<Item = f32>) -> f32 {
    let (mut n, mut s, mut s2) = (0usize, 0.0f64, 0.0f64);
    for v in values {
        n += 1;
        s += v as f64;
        s2 += (v as f64).powi(2);
    }
    if n == 0 {
        return 0.0;
    }
    let m = s / n as f64;
    ((s2 / n as f64 - m * m).max(0.0)).sqrt() as f32
}

/// Validates the input before synthesis (section 4).
///
/// With a guide: every grid block of the guide must be matched by at least
/// `settings.min_candidates` exemplar patches of an allowed category (block descriptors within
/// the RMS tolerance after the vertical translation); the report names the failing blocks and
/// the height ranges they need, and a greedy set cover picks a small subset of exemplars that
/// covers the guide. Without a guide: every exemplar must have enough patches that match
/// patches of other exemplars.
pub fn validate(
    index: &ExemplarIndex,
    control: &Control,
    settings: &Settings,
) -> Result<ValidationReport> {
    settings.check()?;
    index.check_settings(settings)?;
    control.check()?;
    let (p, o) = (settings.patch_size, settings.overlap);
    let grid = grid_for(control.width, control.height, p, o);
    let ne = index.exemplars.len();
    let exemplar_ranges = exemplar_ranges(index, settings.blocks * settings.blocks);
    let Some(guide) = &control.guide else {
        return Ok(validate_unguided(index, settings, &grid, exemplar_ranges));
    };
    let tol = settings
        .validation_tolerance
        .unwrap_or_else(|| (0.5 * std_of(guide.as_slice().iter().copied())).max(1e-3));
    let (w, h) = (control.width, control.height);
    let g = pad(guide.as_slice(), w, h, grid.cw, grid.ch);
    let cmap = control
        .categories
        .as_ref()
        .map(|m| pad(&m.ids, w, h, grid.cw, grid.ch));
    let rects = grid_rects(p, settings.blocks);
    let blocks: Vec<BlockReport> = (0..grid.nx * grid.ny)
        .into_par_iter()
        .map(|bi| {
            let (gx, gy) = (bi % grid.nx, bi / grid.nx);
            let (x0, y0) = (gx * (p - o), gy * (p - o));
            let dg: Vec<f32> = rects
                .iter()
                .map(|r| window_mean(&g, grid.cw, x0 + r[0], y0 + r[1], r[2], r[3]))
                .collect();
            let allowed = allowed_categories(index, cmap.as_deref(), grid.cw, x0, y0, p);
            let per = block_candidates(index, &dg, &allowed, settings.lambda, tol);
            let lo = dg.iter().copied().fold(f32::INFINITY, f32::min);
            let hi = dg.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            BlockReport {
                gx,
                gy,
                x: x0,
                y: y0,
                candidates: per.iter().sum(),
                per_exemplar: per,
                guide_range: (lo, hi),
            }
        })
        .collect();
    let min = settings.required_candidates(index.patches.len());
    let failing: Vec<usize> = (0..blocks.len())
        .filter(|&i| blocks[i].candidates < min)
        .collect();
    let missing_ranges = merged_ranges(failing.iter().map(|&i| blocks[i].guide_range).collect());
    let cover = greedy_cover(&blocks, min, ne);
    let uncovered = failing
        .iter()
        .map(|&i| (blocks[i].gx, blocks[i].gy))
        .collect();
    Ok(ValidationReport {
        ok: failing.is_empty(),
        min_candidates: min,
        tolerance: tol,
        grid: (grid.nx, grid.ny),
        blocks,
        failing,
        missing_ranges,
        exemplar_ranges,
        cover,
        uncovered,
        compatibility: Vec::new(),
        suggestion: None,
    })
}

/// Per exemplar, the range of its patches' block-descriptor means (`nn` blocks per patch).
fn exemplar_ranges(index: &ExemplarIndex, nn: usize) -> Vec<(f32, f32)> {
    (0..index.exemplars.len())
        .map(|e| {
            let mut r = (f32::INFINITY, f32::NEG_INFINITY);
            for (i, pr) in index.patches.iter().enumerate() {
                if pr.exemplar as usize == e {
                    let m = index.descriptor(i).iter().sum::<f32>() / nn as f32;
                    r = (r.0.min(m), r.1.max(m));
                }
            }
            r
        })
        .collect()
}

/// Per exemplar, the patches of an allowed category matching the guide block descriptor `dg`
/// (RMS within `tol` after a vertical translation of at most `lambda`).
fn block_candidates(
    index: &ExemplarIndex,
    dg: &[f32],
    allowed: &[bool],
    lambda: f32,
    tol: f32,
) -> Vec<usize> {
    let m = dg.iter().sum::<f32>() / dg.len() as f32;
    let mut per = vec![0usize; index.exemplars.len()];
    for &(_, j) in mean_range(index, m - lambda - tol, m + lambda + tol) {
        let j = j as usize;
        let cat = index.patch_category(j);
        let ci = index.categories.binary_search(&cat).unwrap_or(0);
        if allowed[ci] && matches(index.descriptor(j), dg, lambda, tol) {
            per[index.patches[j].exemplar as usize] += 1;
        }
    }
    per
}

/// The height ranges sorted and merged where they overlap.
fn merged_ranges(mut ranges: Vec<(f32, f32)>) -> Vec<(f32, f32)> {
    ranges.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut merged: Vec<(f32, f32)> = Vec::new();
    for r in ranges {
        match merged.last_mut() {
            Some(last) if r.0 <= last.1 => last.1 = last.1.max(r.1),
            _ => merged.push(r),
        }
    }
    merged
}

/// Greedy multi-cover: repeatedly takes the exemplar that removes the most missing candidates
/// from the blocks' deficits (each block needs `min`); returns the exemplars in pick order.
fn greedy_cover(blocks: &[BlockReport], min: usize, ne: usize) -> Vec<usize> {
    let mut deficit: Vec<usize> = blocks.iter().map(|b| min.min(b.candidates)).collect();
    let mut cover = Vec::new();
    let mut used = vec![false; ne];
    loop {
        let best = (0..ne)
            .filter(|&e| !used[e])
            .map(|e| {
                let gain: usize = blocks
                    .iter()
                    .zip(&deficit)
                    .map(|(b, &d)| d.min(b.per_exemplar[e]))
                    .sum();
                (gain, e)
            })
            .max_by(|a, b| a.0.cmp(&b.0).then(b.1.cmp(&a.1)));
        match best {
            Some((gain, e)) if gain > 0 => {
                used[e] = true;
                cover.push(e);
                for (b, d) in blocks.iter().zip(deficit.iter_mut()) {
                    *d -= (*d).min(b.per_exemplar[e]);
                }
            }
            _ => return cover,
        }
    }
}

/// Without a guide: every exemplar must have enough patches that match patches of other
/// exemplars (sampled every `overlap` cells, scaled to all its patches).
fn validate_unguided(
    index: &ExemplarIndex,
    settings: &Settings,
    grid: &Grid,
    exemplar_ranges: Vec<(f32, f32)>,
) -> ValidationReport {
    let ne = index.exemplars.len();
    let nn = settings.blocks * settings.blocks;
    let lambda = settings.lambda;
    let tol = settings.validation_tolerance.unwrap_or_else(|| {
        0.5 * std_of(
            index
                .exemplars
                .iter()
                .flat_map(|e| e.heightfield.as_slice().iter().copied()),
        )
    });
    let step = settings.overlap.max(1);
    let min_needed = settings.required_candidates(index.patches.len());
    let compatibility: Vec<ExemplarCompatibility> = (0..ne)
        .into_par_iter()
        .map(|e| {
            let own: Vec<usize> = index
                .patches
                .iter()
                .enumerate()
                .filter(|(_, pr)| {
                    pr.exemplar as usize == e
                        && (pr.x as usize).is_multiple_of(step)
                        && (pr.y as usize).is_multiple_of(step)
                })
                .map(|(i, _)| i)
                .collect();
            let total = index
                .patches
                .iter()
                .filter(|pr| pr.exemplar as usize == e)
                .count();
            let compatible = if ne < 2 {
                own.len()
            } else {
                own.iter()
                    .filter(|&&i| {
                        let d = index.descriptor(i);
                        let m = d.iter().sum::<f32>() / nn as f32;
                        mean_range(index, m - lambda - tol, m + lambda + tol)
                            .iter()
                            .any(|&(_, j)| {
                                index.patches[j as usize].exemplar as usize != e
                                    && matches(index.descriptor(j as usize), d, lambda, tol)
                            })
                    })
                    .count()
            };
            let est = if own.is_empty() {
                0
            } else {
                (compatible as f64 / own.len() as f64 * total as f64).round() as usize
            };
            ExemplarCompatibility {
                exemplar: e,
                checked: own.len(),
                compatible,
                estimated_compatible: est,
                ok: est >= min_needed,
            }
        })
        .collect();
    ValidationReport {
        ok: compatibility.iter().all(|c| c.ok),
        min_candidates: min_needed,
        tolerance: tol,
        grid: (grid.nx, grid.ny),
        blocks: Vec::new(),
        failing: Vec::new(),
        missing_ranges: Vec::new(),
        exemplar_ranges,
        cover: (0..ne).collect(),
        uncovered: Vec::new(),
        compatibility,
        suggestion: None,
    }
}
