//! Least-cost breaching (Lindsay 2016, "Efficient hybrid breaching-filling sink removal methods
//! for flow path enforcement in digital elevation models", Hydrological Processes 30): each
//! pit, lowest first, is drained by cutting the cheapest channel from it to lower ground or to
//! the map's edge, found by a Dijkstra search whose cost is the depth of cut times the length,
//! within a largest depth and length. Cutting keeps the valley floors that filling would drown
//! under flat lakes; the pits that no channel within the limits can drain are left for a
//! filling pass (the hybrid of the paper).

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::depression::fill::is_outlet;
use crate::elev::Elev;
use crate::grid::{Grid, OPPOSITE};

/// Limits of one breach channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BreachLimits {
    /// Deepest cut below the original surface (m).
    pub max_depth: f64,
    /// Longest channel (m).
    pub max_length: f64,
}

/// What [`breach`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BreachReport {
    /// Pits drained by a cut channel.
    pub breached: usize,
    /// Pits no channel within the limits could drain.
    pub unresolved: usize,
    /// Cells lowered.
    pub lowered: usize,
}

fn is_pit<T: Elev>(z: &[T], grid: &Grid, outlet: &[bool], i: usize) -> bool {
    if z[i].is_void() || outlet[i] {
        return false;
    }
    let mut lower = false;
    grid.for_neighbours(i, |_, m| lower |= !z[m].is_void() && z[m] < z[i]);
    !lower
}

/// Breaches the pits of `z` in place (see the module docs).
pub fn breach<T: Elev>(z: &mut [T], grid: &Grid, limits: BreachLimits) -> BreachReport {
    let n = grid.len();
    let outlet: Vec<bool> = (0..n)
        .map(|i| !z[i].is_void() && is_outlet(z, grid, i))
        .collect();
    let mut pits: Vec<u32> = (0..n as u32)
        .filter(|&i| is_pit(z, grid, &outlet, i as usize))
        .collect();
    pits.sort_by_key(|&i| (z[i as usize].key(), i));
    let dist = grid.distances();
    let mut cost = vec![f64::INFINITY; n];
    let mut length = vec![0f64; n];
    let mut back = vec![0u8; n];
    let mut touched: Vec<u32> = Vec::new();
    let mut report = BreachReport::default();
    for p in pits {
        let p = p as usize;
        if !is_pit(z, grid, &outlet, p) {
            continue;
        }
        let zp = z[p].to_f64();
        for &t in &touched {
            cost[t as usize] = f64::INFINITY;
        }
        touched.clear();
        cost[p] = 0.0;
        length[p] = 0.0;
        touched.push(p as u32);
        let mut heap = BinaryHeap::new();
        heap.push(Reverse((0u64, p as u32)));
        let mut found = None;
        while let Some(Reverse((ck, c))) = heap.pop() {
            let c = c as usize;
            if f64::from_bits(ck) > cost[c] {
                continue;
            }
            if c != p && (z[c].to_f64() < zp || outlet[c]) {
                found = Some(c);
                break;
            }
            grid.for_neighbours(c, |k, m| {
                if z[m].is_void() {
                    return;
                }
                let len = length[c] + dist[k];
                let cut = z[m].to_f64() - zp;
                if len > limits.max_length || cut > limits.max_depth {
                    return;
                }
                let nc = cost[c] + cut.max(0.0) * dist[k];
                if nc < cost[m] {
                    if cost[m].is_infinite() {
                        touched.push(m as u32);
                    }
                    cost[m] = nc;
                    length[m] = len;
                    back[m] = OPPOSITE[k];
                    heap.push(Reverse((nc.to_bits(), m as u32)));
                }
            });
        }
        let Some(end) = found else {
            report.unresolved += 1;
            continue;
        };
        // The path from the pit to `end`, then lowered to descend strictly from the pit.
        let mut path = vec![end];
        let mut c = end;
        while c != p {
            c = grid
                .neighbour(c, back[c] as usize)
                .expect("a back link points to a cell on the map");
            path.push(c);
        }
        path.reverse();
        let mut level = z[p];
        for &c in &path[1..] {
            level = down(level);
            if z[c] > level {
                z[c] = level;
                report.lowered += 1;
            } else {
                break;
            }
        }
        report.breached += 1;
    }
    report
}

/// The next representable value below `v`.
fn down<T: Elev>(v: T) -> T {
    let f = v.to_f64();
    let mut d = T::from_f64(f - f.abs().max(1.0) * 1e-7);
    while d >= v {
        d = T::from_f64(d.to_f64() - f.abs().max(1.0) * 1e-7);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dam_across_a_valley_is_cut_not_filled() {
        // A valley sloping east with a 3 m dam at column 10: breaching cuts through the dam.
        let g = Grid::new(20, 9, 10.0, 10.0);
        let mut z: Vec<f32> = (0..g.len())
            .map(|i| {
                let (x, y) = (i % 20, i / 20);
                let valley = 100.0 - x as f32 + (y as f32 - 4.0).abs() * 5.0;
                if x == 10 { valley + 3.0 } else { valley }
            })
            .collect();
        let before = z.clone();
        let r = breach(
            &mut z,
            &g,
            BreachLimits {
                max_depth: 10.0,
                max_length: 500.0,
            },
        );
        assert!(r.breached >= 1 && r.unresolved == 0, "{r:?}");
        // The dam is lowered in the valley's axis; the floor upstream of it is untouched.
        assert!(z[4 * 20 + 10] < before[4 * 20 + 9]);
        assert_eq!(z[4 * 20 + 5], before[4 * 20 + 5]);
        let outlet: Vec<bool> = (0..g.len()).map(|i| is_outlet(&z, &g, i)).collect();
        assert!((0..g.len()).all(|i| !is_pit(&z, &g, &outlet, i)));
    }

    #[test]
    fn a_deep_closed_basin_stays_unresolved_within_the_limits() {
        let g = Grid::new(15, 15, 1.0, 1.0);
        let mut z: Vec<f32> = (0..g.len())
            .map(|i| {
                let (x, y) = ((i % 15) as f32 - 7.0, (i / 15) as f32 - 7.0);
                50.0 - 40.0 * (-(x * x + y * y) / 8.0).exp()
            })
            .collect();
        let r = breach(
            &mut z,
            &g,
            BreachLimits {
                max_depth: 5.0,
                max_length: 100.0,
            },
        );
        assert_eq!((r.breached, r.unresolved), (0, 1));
    }
}
