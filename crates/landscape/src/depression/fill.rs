//! Priority-flood depression filling (Barnes, Lehman and Mulla 2014, "Priority-Flood: An
//! optimal depression-filling and watershed-labeling algorithm for digital elevation models",
//! Computers & Geosciences 62): algorithm 2 (a plain queue for the cells of a depression, which
//! are raised to its spill level without touching the priority queue) and algorithm 3
//! (Priority-Flood+epsilon: each cell of a depression is raised to the next representable value
//! above the cell it was reached from, so that every cell has a strictly lower neighbour and
//! drains).

use std::collections::VecDeque;

use crate::radix::RadixHeap;

use crate::elev::Elev;
use crate::grid::Grid;

/// How closed depressions are removed by [`priority_flood`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FillMode {
    /// Raise every depression to its spill elevation (flat; unique result).
    Plain,
    /// Raise every depression cell one representable step above the cell it was reached from:
    /// no flats remain and every cell drains (the result depends on the order of equal cells,
    /// which here is the cell index).
    Epsilon,
}

/// No parent: a cell the flood started from (an outlet) or a void.
pub const NO_PARENT: u32 = u32::MAX;

/// True for a valid cell that drains off the map: on the outer edge or beside a void.
pub fn is_outlet<T: Elev>(z: &[T], grid: &Grid, i: usize) -> bool {
    if grid.is_edge(i) {
        return true;
    }
    let mut beside_void = false;
    grid.for_neighbours(i, |_, n| beside_void |= z[n].is_void());
    beside_void
}

/// Fills the closed depressions of `z` in place; returns how many cells were raised.
///
/// The flood starts from every valid cell on the map's edge or beside a void (voids are flow
/// off the map and are never changed). When `parent` is given (one entry per cell) it receives
/// for every valid cell the neighbour the flood reached it from ([`NO_PARENT`] for the start
/// cells and voids): inside a filled depression, following parents leads to its spill point,
/// which is how [`crate::flow`] routes water across lakes.
pub fn priority_flood<T: Elev>(
    z: &mut [T],
    grid: &Grid,
    mode: FillMode,
    mut parent: Option<&mut [u32]>,
) -> usize {
    let n = grid.len();
    debug_assert_eq!(z.len(), n);
    let mut closed = vec![false; n];
    let mut open: RadixHeap<T::Entry> = RadixHeap::new();
    let mut pit: VecDeque<u32> = VecDeque::new();
    if let Some(p) = parent.as_deref_mut() {
        p.fill(NO_PARENT);
    }
    for i in 0..n {
        if z[i].is_void() {
            closed[i] = true;
        } else if is_outlet(z, grid, i) {
            closed[i] = true;
            open.push(z[i].entry(i as u32));
        }
    }
    let mut raised = 0usize;
    loop {
        // The plain queue first (algorithms 2 and 3 of the paper): every cell it holds is
        // at or above the level last taken from the priority queue, so the priority queue
        // stays monotone (a radix heap).
        let c = match pit.pop_front() {
            Some(c) => Some(c),
            None => open.pop().map(T::cell),
        };
        let Some(c) = c else { break };
        let c = c as usize;
        let zc = z[c];
        let spill = match mode {
            FillMode::Plain => zc,
            FillMode::Epsilon => zc.up(),
        };
        grid.for_neighbours(c, |_, m| {
            if closed[m] {
                return;
            }
            closed[m] = true;
            if let Some(p) = parent.as_deref_mut() {
                p[m] = c as u32;
            }
            if z[m] <= spill {
                if z[m] < spill && (mode == FillMode::Epsilon || z[m] < zc) {
                    raised += 1;
                }
                z[m] = spill;
                pit.push_back(m as u32);
            } else {
                open.push(z[m].entry(m as u32));
            }
        });
    }
    raised
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(w: usize, h: usize) -> Grid {
        Grid::new(w, h, 1.0, 1.0)
    }

    /// Exhaustive reference: the filled elevation of a cell is the lowest, over all paths to
    /// an outlet, of the highest elevation on the path (minimax), computed by relaxation.
    fn minimax_reference(z: &[f32], g: &Grid) -> Vec<f32> {
        let mut f: Vec<f32> = (0..g.len())
            .map(|i| {
                if z[i].is_nan() || is_outlet(z, g, i) {
                    z[i]
                } else {
                    f32::INFINITY
                }
            })
            .collect();
        loop {
            let mut changed = false;
            for i in 0..g.len() {
                if z[i].is_nan() {
                    continue;
                }
                let mut best = f[i];
                g.for_neighbours(i, |_, n| {
                    if !z[n].is_nan() {
                        best = best.min(f[n].max(z[i]));
                    }
                });
                if best < f[i] {
                    f[i] = best;
                    changed = true;
                }
            }
            if !changed {
                return f;
            }
        }
    }

    fn hash_dem(w: usize, h: usize, seed: u64, voids: bool) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let u = relief_heightfield::rng::unit_f32(relief_heightfield::rng::hash(
                    seed, i as u64, 0, 0,
                ));
                if voids && u < 0.05 {
                    f32::NAN
                } else {
                    (u * 20.0).floor() + (i % w) as f32 * 0.3
                }
            })
            .collect()
    }

    #[test]
    fn plain_fill_is_the_minimax_surface() {
        for (seed, voids) in [(1, false), (2, true), (3, false)] {
            let g = grid(23, 17);
            let z = hash_dem(23, 17, seed, voids);
            let mut f = z.clone();
            priority_flood(&mut f, &g, FillMode::Plain, None);
            let r = minimax_reference(&z, &g);
            for i in 0..g.len() {
                assert!(f[i] == r[i] || (f[i].is_nan() && r[i].is_nan()), "cell {i}");
            }
        }
    }

    #[test]
    fn epsilon_fill_leaves_every_cell_a_strictly_lower_path_out() {
        let g = grid(31, 29);
        let z = hash_dem(31, 29, 7, true);
        let mut f = z.clone();
        let mut parent = vec![0u32; g.len()];
        priority_flood(&mut f, &g, FillMode::Epsilon, Some(&mut parent));
        let mut plain = z.clone();
        priority_flood(&mut plain, &g, FillMode::Plain, None);
        for i in 0..g.len() {
            if z[i].is_nan() {
                assert!(f[i].is_nan());
                continue;
            }
            assert!(f[i] >= plain[i] && f[i] - plain[i] < 0.01, "cell {i}");
            if !is_outlet(&z, &g, i) {
                let mut lower = false;
                g.for_neighbours(i, |_, n| lower |= f[n] < f[i]);
                assert!(lower, "cell {i} has no lower neighbour");
                assert_ne!(parent[i], NO_PARENT);
            }
        }
    }
}
