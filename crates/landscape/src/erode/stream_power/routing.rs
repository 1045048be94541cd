//! The flow graph of one stream-power step: D8 receivers on the current surface, closed
//! depressions routed to their spill points, the stack (receivers before donors) and the
//! drainage area.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

use rayon::prelude::*;

use crate::elev::Elev;
use crate::erode::diffusion::{FREE, VOID};
use crate::grid::{D8, Grid, NO_FLOW, OPPOSITE};

/// Buffers of the lake routing (used only on steps whose surface has pits).
#[derive(Debug, Default, Clone)]
pub(super) struct LakeScratch {
    filled: Vec<f64>,
    parent: Vec<u8>,
    closed: Vec<bool>,
    open: BinaryHeap<Reverse<(u64, u32)>>,
    pit: VecDeque<u32>,
}

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

/// Routes the closed depressions of `z` to their spill points; returns the number of lake
/// cells (cells below their depression's spill level).
///
/// A priority flood (Barnes et al. 2014, algorithm 2) from the fixed cells gives every cell its
/// spill level (the filled surface) and the neighbour it was reached from. A lake cell (below
/// its spill level) and a cell whose steepest descent leads into a lake at its own level (a
/// cell on the lake's rim at the spill level) drain to that neighbour, which leads across the
/// lake to the spill point and over it; every other cell keeps its D8 receiver. The graph is
/// acyclic: each receiver is lower on the filled surface, or level with it and flooded earlier.
pub(super) fn route_lakes(
    z: &[f64],
    grid: &Grid,
    kind: &[u8],
    dir: &mut [u8],
    s: &mut LakeScratch,
) -> usize {
    let n = grid.len();
    s.filled.clear();
    s.filled.extend_from_slice(z);
    s.parent.clear();
    s.parent.resize(n, NO_FLOW);
    s.closed.clear();
    s.closed.extend(kind.iter().map(|&k| k != FREE));
    s.open.clear();
    s.pit.clear();
    for i in 0..n {
        if kind[i] != FREE && kind[i] != VOID {
            s.open.push(Reverse((z[i].key(), i as u32)));
        }
    }
    let filled = &mut s.filled;
    loop {
        let c = match s.pit.pop_front() {
            Some(c) => c,
            None => match s.open.pop() {
                Some(Reverse((_, c))) => c,
                None => break,
            },
        } as usize;
        let level = filled[c];
        grid.for_neighbours(c, |k, m| {
            if s.closed[m] {
                return;
            }
            s.closed[m] = true;
            s.parent[m] = OPPOSITE[k];
            if filled[m] <= level {
                filled[m] = level;
                s.pit.push_back(m as u32);
            } else {
                s.open.push(Reverse((filled[m].key(), m as u32)));
            }
        });
    }
    let w = grid.width;
    let mut lake = 0;
    for i in 0..n {
        if kind[i] != FREE {
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
