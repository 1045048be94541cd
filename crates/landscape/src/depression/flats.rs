//! Drainage across flats (Barnes, Lehman and Mulla 2014, "An efficient assignment of drainage
//! direction over flat surfaces in raster digital elevation models", Computers & Geosciences
//! 62): on a flat (a connected set of equal cells, e.g. a filled depression), water flows
//! towards the flat's lower edges and away from its higher edges. Two breadth-first distances
//! are combined into an increment mask, `2 * (steps to a low edge) + (steps from the farthest
//! high edge)`, whose only minima are the low edges, and the flat's cells take the D8
//! direction of steepest descent of the mask within their flat.

use std::collections::VecDeque;

use rayon::prelude::*;

use crate::elev::Elev;
use crate::grid::{Grid, NO_FLOW};

/// Gives every cell of `dir` that has no receiver yet (and is not an outlet or a void) a
/// direction across its flat, towards lower ground and away from higher ground. Cells of a flat
/// without any way out (a closed flat, possible only in an unfilled surface) keep [`NO_FLOW`].
/// Returns the number of cells given a direction.
pub fn resolve_flats<T: Elev>(z: &[T], grid: &Grid, outlet: &[bool], dir: &mut [u8]) -> usize {
    resolve_flats_labelled(z, grid, outlet, dir).given
}

/// What [`resolve_flats_labelled`] found: the flats' labels (`u32::MAX` outside them) and the
/// low-edge cell each label was flooded from.
pub(crate) struct FlatLabels {
    /// Cells given a direction.
    pub(crate) given: usize,
    /// The label of every flat cell and of each label's seed.
    pub(crate) label: Vec<u32>,
    /// `seeds[l]`: the low-edge cell label `l` was flooded from (the first of the flat's low
    /// edges in index order).
    pub(crate) seeds: Vec<u32>,
}

/// [`resolve_flats`], also returning the labels (the tiled plan tells from them which flats
/// a tile holds entirely).
pub(crate) fn resolve_flats_labelled<T: Elev>(
    z: &[T],
    grid: &Grid,
    outlet: &[bool],
    dir: &mut [u8],
) -> FlatLabels {
    let n = grid.len();
    let flat: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| !z[i].is_void() && !outlet[i] && dir[i] == NO_FLOW)
        .collect();
    let is_flat = |i: usize| flat[i];
    // Low edges: draining cells beside a flat cell of the same elevation; high edges: flat
    // cells beside higher ground.
    let edges: Vec<(u32, bool, bool)> = (0..n)
        .into_par_iter()
        .filter_map(|i| {
            if z[i].is_void() {
                return None;
            }
            let flat_i = flat[i];
            let (mut low_edge, mut high_edge) = (false, false);
            grid.for_neighbours(i, |_, m| {
                if z[m].is_void() {
                    return;
                }
                if !flat_i && flat[m] && z[m] == z[i] {
                    low_edge = true;
                }
                if flat_i && z[m] > z[i] {
                    high_edge = true;
                }
            });
            (low_edge || high_edge).then_some((i as u32, low_edge, high_edge))
        })
        .collect();
    let mut low: VecDeque<u32> = edges.iter().filter(|e| e.1).map(|e| e.0).collect();
    let mut high: VecDeque<u32> = edges.iter().filter(|e| e.2).map(|e| e.0).collect();
    if low.is_empty() {
        return FlatLabels {
            given: 0,
            label: vec![u32::MAX; n],
            seeds: Vec::new(),
        };
    }
    // Label each flat from its low edges.
    const NONE: u32 = u32::MAX;
    let mut label = vec![NONE; n];
    let mut next = 0u32;
    let mut seeds = Vec::new();
    for &s in &low {
        let s = s as usize;
        if label[s] != NONE {
            continue;
        }
        label[s] = next;
        seeds.push(s as u32);
        let mut q = VecDeque::from([s]);
        while let Some(c) = q.pop_front() {
            grid.for_neighbours(c, |_, m| {
                if label[m] == NONE && z[m] == z[s] && is_flat(m) {
                    label[m] = next;
                    q.push_back(m);
                }
            });
        }
        next += 1;
    }
    // Gradient away from higher terrain (rings from the high edges; the ring count per flat).
    let mut away = vec![0u32; n];
    let mut flat_height = vec![0u32; next as usize];
    high.retain(|&h| label[h as usize] != NONE);
    for &h in &high {
        away[h as usize] = 1;
        let l = label[h as usize] as usize;
        flat_height[l] = flat_height[l].max(1);
    }
    bfs_rings(grid, &mut high, &label, is_flat, |i, ring| {
        away[i] = ring + 1;
        let l = label[i] as usize;
        flat_height[l] = flat_height[l].max(ring + 1);
    });
    // Gradient towards lower terrain, combined: 2 * towards + (height - away).
    let mut mask = vec![0u32; n];
    bfs_rings(grid, &mut low, &label, is_flat, |i, ring| {
        let away_term = if away[i] > 0 {
            flat_height[label[i] as usize] - away[i]
        } else {
            0
        };
        mask[i] = 2 * ring + away_term;
    });
    // Steepest descent of the mask within the flat; low edges keep their own direction.
    let dist = grid.distances();
    let mut given = 0;
    for i in 0..n {
        if !is_flat(i) || label[i] == NONE {
            continue;
        }
        let mut best = (0.0f64, NO_FLOW);
        grid.for_neighbours(i, |k, m| {
            if label[m] == label[i] && mask[m] < mask[i] {
                let s = (mask[i] - mask[m]) as f64 / dist[k];
                if s > best.0 {
                    best = (s, k as u8);
                }
            }
        });
        if best.1 != NO_FLOW {
            dir[i] = best.1;
            given += 1;
        }
    }
    FlatLabels {
        given,
        label,
        seeds,
    }
}

/// Breadth-first rings over the flat cells of the labelled flats, from `seeds` (ring 0, not
/// visited by `visit`); `visit(cell, ring)` is called once per reached flat cell, ring >= 1.
fn bfs_rings(
    grid: &Grid,
    seeds: &mut VecDeque<u32>,
    label: &[u32],
    is_flat: impl Fn(usize) -> bool + Copy,
    mut visit: impl FnMut(usize, u32),
) {
    let mut seen = vec![false; grid.len()];
    for &s in seeds.iter() {
        seen[s as usize] = true;
    }
    let mut ring = 0u32;
    let mut frontier: Vec<u32> = seeds.drain(..).collect();
    while !frontier.is_empty() {
        ring += 1;
        let mut next = Vec::new();
        for &c in &frontier {
            let c = c as usize;
            grid.for_neighbours(c, |_, m| {
                if !seen[m] && label[m] != u32::MAX && label[m] == label[c] && is_flat(m) {
                    seen[m] = true;
                    visit(m, ring);
                    next.push(m as u32);
                }
            });
        }
        frontier = next;
    }
}
