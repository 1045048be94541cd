//! The flow graph of one stream-power step: D8 receivers on the current surface, closed
//! depressions routed to their spill points, the stack (receivers before donors) and the
//! drainage area.

use std::collections::VecDeque;

use rayon::prelude::*;

use crate::elev::Elev;
use crate::erode::diffusion::{FREE, VOID};
use crate::grid::{D8, Grid, NO_FLOW, OPPOSITE};

/// Buffers of the lake routing (used only on steps whose surface has pits).
#[derive(Debug, Default, Clone)]
pub(super) struct LakeScratch {
    filled: Vec<f64>,
    parent: Vec<u8>,
    state: Vec<u8>,
    open: RadixHeap,
    pit: VecDeque<u32>,
}

/// A monotone priority queue of `(key, cell)` (a radix heap, Ahuja et al. 1990): every key
/// pushed is at least the last key popped, which holds in a priority flood (cells enter the
/// queue above the level being flooded). Amortised O(1) push and O(log key range) pop, against
/// a binary heap's O(log size) sift of 16-byte entries. Cells of equal key leave in a fixed
/// order (the order of the pushes and redistributions), so the flood is deterministic.
#[derive(Debug, Default, Clone)]
struct RadixHeap {
    buckets: Vec<Vec<(u64, u32)>>,
    last: u64,
    len: usize,
}

impl RadixHeap {
    fn clear(&mut self) {
        self.buckets.resize_with(65, Vec::new);
        self.buckets.iter_mut().for_each(Vec::clear);
        self.last = 0;
        self.len = 0;
    }

    #[inline]
    fn bucket(&self, key: u64) -> usize {
        64 - (key ^ self.last).leading_zeros() as usize
    }

    #[inline]
    fn push(&mut self, key: u64, cell: u32) {
        debug_assert!(key >= self.last, "radix heap keys must not decrease");
        let b = self.bucket(key);
        self.buckets[b].push((key, cell));
        self.len += 1;
    }

    fn pop(&mut self) -> Option<(u64, u32)> {
        if self.len == 0 {
            return None;
        }
        if self.buckets[0].is_empty() {
            let b = (1..65).find(|&b| !self.buckets[b].is_empty())?;
            let items = std::mem::take(&mut self.buckets[b]);
            self.last = items.iter().map(|e| e.0).min().unwrap_or(self.last);
            for &(key, cell) in &items {
                let nb = self.bucket(key);
                self.buckets[nb].push((key, cell));
            }
            // Hand the (now empty) allocation back to the bucket for reuse.
            let mut items = items;
            items.clear();
            if self.buckets[b].is_empty() {
                self.buckets[b] = items;
            }
        }
        self.len -= 1;
        self.buckets[0].pop()
    }
}

/// Flood states of [`route_lakes`]: a cell of a pit's basin not reached yet, a cell reached
/// (or outside every pit basin), a cell outside the pit basins queued as a seed of the flood.
const OPEN: u8 = 0;
const CLOSED: u8 = 1;
const SEED: u8 = 2;

/// The D8 receiver of every free cell: the neighbour of steepest descent, drop over the
/// distance between centres, the first of [`D8`] winning a tie, only slopes above
/// `f64::MIN_POSITIVE` (fastscapelib's `SingleFlowRouter`, operation for operation); fixed
/// cells and voids get [`NO_FLOW`]. Returns the number of pits (free cells without a lower
/// neighbour).
pub(super) fn receivers(z: &[f64], grid: &Grid, kind: &[u8], dir: &mut [u8]) -> usize {
    let w = grid.width;
    let dist = grid.distances();
    dir.par_chunks_mut(w)
        .enumerate()
        .map(|(y, row)| {
            let mut pits = 0;
            for (x, d) in row.iter_mut().enumerate() {
                let i = y * w + x;
                *d = NO_FLOW;
                if kind[i] != FREE {
                    continue;
                }
                let zi = z[i];
                let mut best = f64::MIN_POSITIVE;
                grid.for_neighbours(i, |k, m| {
                    if kind[m] != VOID {
                        let s = (zi - z[m]) / dist[k];
                        if s > best {
                            best = s;
                            *d = k as u8;
                        }
                    }
                });
                pits += usize::from(*d == NO_FLOW);
            }
            pits
        })
        .sum()
}

/// The neighbour of cell `i` in direction `d` (which must not be [`NO_FLOW`]).
#[inline]
pub(super) fn target(w: usize, i: usize, d: u8) -> usize {
    let (dy, dx) = D8[d as usize];
    (i as isize + dy * w as isize + dx) as usize
}

/// Routes the closed depressions of `z` to their spill points, changing the receivers in
/// `dir` (D8 on entry) of the cells that drain to a pit; returns the number of lake cells
/// (cells below their depression's spill level). `stack` and `donors` are scratch.
///
/// A priority flood (Barnes et al. 2014, algorithm 2) gives every cell its spill level (the
/// filled surface) and the neighbour it was reached from. Only the basins of the pits are
/// flooded, from the cells around them that drain to a base level (whose filled level is their
/// elevation, their D8 path descending all the way): the cost follows the size of the pits'
/// basins, not of the grid. A lake cell (below its spill level) and a cell whose steepest
/// descent leads into a lake at its own level (a cell on the rim at the spill level) drain to
/// the neighbour the flood reached them from, which leads across the lake to the spill point
/// and over it; every other cell keeps its D8 receiver. The graph stays acyclic: each receiver
/// is lower on the filled surface, or level with it and flooded earlier.
pub(super) fn route_lakes(
    z: &[f64],
    grid: &Grid,
    kind: &[u8],
    dir: &mut [u8],
    stack: &mut Vec<u32>,
    donors: &mut Vec<u8>,
    s: &mut LakeScratch,
) -> usize {
    let (n, w) = (grid.len(), grid.width);
    // Which cells drain to a base level along D8: receivers first, so a receiver is known
    // before its donors.
    stack_order(grid, kind, dir, donors, stack);
    s.state.clear();
    s.state.resize(n, OPEN);
    for &c in stack.iter() {
        let c = c as usize;
        let drains = match kind[c] {
            FREE => dir[c] != NO_FLOW && s.state[target(w, c, dir[c])] == CLOSED,
            _ => true,
        };
        if drains {
            s.state[c] = CLOSED;
        }
    }
    s.filled.clear();
    s.filled.extend_from_slice(z);
    s.parent.clear();
    s.parent.resize(n, NO_FLOW);
    s.open.clear();
    s.pit.clear();
    for y in 0..grid.height {
        for x in 0..w {
            let i = y * w + x;
            if s.state[i] == OPEN {
                grid.for_neighbours_at(x, y, i, |_, m| {
                    if s.state[m] == CLOSED && kind[m] != VOID {
                        s.state[m] = SEED;
                        s.open.push(z[m].key(), m as u32);
                    }
                });
            }
        }
    }
    // From here on a set `parent` marks the cells of the pits' basins reached by the flood.
    let filled = &mut s.filled;
    // The level being flooded: a cell popped from `open` sets it (its key is its filled
    // height); the cells it sends to `pit` are raised to it and flood at it, before the next pop.
    let mut level = 0.0;
    loop {
        let c = match s.pit.pop_front() {
            Some(c) => c,
            None => match s.open.pop() {
                Some((key, c)) => {
                    level = f64::from_key(key);
                    c
                }
                None => break,
            },
        } as usize;
        debug_assert_eq!(level.to_bits(), filled[c].to_bits());
        grid.for_neighbours(c, |k, m| {
            if s.state[m] != OPEN {
                return;
            }
            s.state[m] = CLOSED;
            s.parent[m] = OPPOSITE[k];
            if filled[m] <= level {
                filled[m] = level;
                s.pit.push_back(m as u32);
            } else {
                s.open.push(filled[m].key(), m as u32);
            }
        });
    }
    let mut lake = 0;
    for i in 0..n {
        if kind[i] != FREE || s.parent[i] == NO_FLOW {
            continue;
        }
        let raised = filled[i] > z[i];
        lake += usize::from(raised);
        let keep = !raised && dir[i] != NO_FLOW && filled[target(w, i, dir[i])] < filled[i];
        if !keep {
            dir[i] = s.parent[i];
        }
    }
    lake
}

/// The free cells in stack order (every receiver before its donors: the reverse of Kahn's
/// order over the flow graph, sources taken in index order) into `stack`; `donors` is scratch.
pub(super) fn stack_order(
    grid: &Grid,
    kind: &[u8],
    dir: &[u8],
    donors: &mut Vec<u8>,
    stack: &mut Vec<u32>,
) {
    let (n, w) = (grid.len(), grid.width);
    donors.clear();
    donors.resize(n, 0);
    for i in 0..n {
        if dir[i] != NO_FLOW {
            donors[target(w, i, dir[i])] += 1;
        }
    }
    stack.clear();
    stack.extend((0..n as u32).filter(|&i| donors[i as usize] == 0 && kind[i as usize] != VOID));
    let mut head = 0;
    while head < stack.len() {
        let c = stack[head] as usize;
        head += 1;
        if dir[c] != NO_FLOW {
            let r = target(w, c, dir[c]);
            donors[r] -= 1;
            if donors[r] == 0 {
                stack.push(r as u32);
            }
        }
    }
    stack.reverse();
}

/// The number of cells draining through each cell, itself included (0 on voids): the drainage
/// area is this count times the cell area, exact whatever the order of the sums.
pub(super) fn contributing_cells(grid: &Grid, dir: &[u8], stack: &[u32], count: &mut [u32]) {
    let w = grid.width;
    count.fill(0);
    for &c in stack {
        count[c as usize] = 1;
    }
    for &c in stack.iter().rev() {
        let c = c as usize;
        if dir[c] != NO_FLOW {
            count[target(w, c, dir[c])] += count[c];
        }
    }
}
