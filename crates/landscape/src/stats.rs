//! Drainage statistics, exactly as `shared/tools/terrain_quality.py` (`drainage`) defines them,
//! so that the project's quality protocol and the reference tool give the same numbers:
//!
//! * **pits**: strict 8-neighbour local minima per km^2, border excluded;
//! * **fill depth**: mean depth (m) of closed depressions, the priority-flood fill with an
//!   additive epsilon of 1e-4 m (ties broken by row, then column) minus the surface, averaged
//!   over every cell;
//! * **beta**: the exponent of the drainage-area exceedance `P(A >= a) ~ a^-beta` over 10..1000
//!   cells, D8 (steepest drop over centre distance, the first neighbour winning ties) on the
//!   filled surface, cells within 2 of the border left out; about 0.4-0.5 on real fluvial
//!   terrain.
//!
//! Voids are left out (the reference tool has none): cells beside a void start the fill like
//! the border, and means and counts are over valid cells.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use relief_heightfield::Heightfield;
use serde::{Deserialize, Serialize};

use crate::elev::Elev;
use crate::grid::Grid;

/// The drainage statistics of one surface.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DrainageStats {
    /// Strict local minima per km^2.
    pub pits_per_km2: f64,
    /// Mean closed-depression fill depth (m).
    pub fill_depth_m: f64,
    /// Drainage-area exceedance exponent (NaN when fewer than two areas fall in the range).
    pub beta: f64,
}

/// Additive epsilon of the reference fill (m).
pub const REFERENCE_EPSILON: f64 = 1e-4;

/// The statistics of `hf` (see the module docs).
pub fn drainage(hf: &Heightfield) -> DrainageStats {
    let g = Grid::of(hf);
    let z: Vec<f64> = hf.as_slice().iter().map(|&v| v as f64).collect();
    let (w, h) = (g.width, g.height);
    let valid = z.iter().filter(|v| !v.is_nan()).count();
    let km2 = valid as f64 * g.cell_area() / 1e6;
    let pits = (1..h.saturating_sub(1))
        .flat_map(|y| (1..w - 1).map(move |x| y * w + x))
        .filter(|&i| {
            let mut lowest = true;
            g.for_neighbours(i, |_, m| lowest &= z[i] < z[m]);
            lowest
        })
        .count();
    let f = reference_fill(&z, &g);
    let fill: f64 = z
        .iter()
        .zip(&f)
        .filter(|(a, _)| !a.is_nan())
        .map(|(a, b)| b - a)
        .sum::<f64>()
        / valid.max(1) as f64;
    DrainageStats {
        pits_per_km2: pits as f64 / km2,
        fill_depth_m: fill,
        beta: beta(&f, &g),
    }
}

/// The reference tool's priority flood: every cell through one heap keyed by (elevation,
/// index), a cell not above the one it is reached from raised to that plus 1e-4 m.
pub fn reference_fill(z: &[f64], g: &Grid) -> Vec<f64> {
    let mut f = z.to_vec();
    let mut seen: Vec<bool> = z.iter().map(|v| v.is_nan()).collect();
    let mut heap = BinaryHeap::new();
    for i in 0..g.len() {
        if !seen[i] && crate::depression::is_outlet(z, g, i) {
            seen[i] = true;
            heap.push(Reverse((f[i].key(), i as u32)));
        }
    }
    while let Some(Reverse((_, c))) = heap.pop() {
        let c = c as usize;
        let v = f[c];
        g.for_neighbours(c, |_, m| {
            if !seen[m] {
                seen[m] = true;
                if f[m] <= v {
                    f[m] = v + REFERENCE_EPSILON;
                }
                heap.push(Reverse((f[m].key(), m as u32)));
            }
        });
    }
    f
}

/// D8 drainage area in cells on a filled surface (receiver: the steepest strictly lower
/// neighbour, first of [`crate::grid::D8`] on ties).
pub fn d8_cells(f: &[f64], g: &Grid) -> Vec<f64> {
    let dist = g.distances();
    let mut rec = vec![u32::MAX; g.len()];
    for i in 0..g.len() {
        if f[i].is_nan() {
            continue;
        }
        let mut best = 0.0;
        g.for_neighbours(i, |k, m| {
            let d = (f[i] - f[m]) / dist[k];
            if d > best {
                best = d;
                rec[i] = m as u32;
            }
        });
    }
    let mut idx: Vec<u32> = (0..g.len() as u32)
        .filter(|&i| !f[i as usize].is_nan())
        .collect();
    idx.sort_by(|&a, &b| f[b as usize].total_cmp(&f[a as usize]).then(a.cmp(&b)));
    let mut acc = vec![1.0f64; g.len()];
    for &i in &idx {
        let r = rec[i as usize];
        if r != u32::MAX {
            acc[r as usize] += acc[i as usize];
        }
    }
    acc
}

fn beta(f: &[f64], g: &Grid) -> f64 {
    let (w, h) = (g.width, g.height);
    let acc = d8_cells(f, g);
    let mut a: Vec<f64> = (2..h.saturating_sub(2))
        .flat_map(|y| (2..w.saturating_sub(2)).map(move |x| y * w + x))
        .filter(|&i| !f[i].is_nan())
        .map(|i| acc[i])
        .collect();
    a.sort_by(f64::total_cmp);
    let n = a.len() as f64;
    let (mut sx, mut sy, mut sxx, mut sxy, mut k) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (j, &v) in a.iter().enumerate() {
        if (10.0..=1000.0).contains(&v) {
            let (x, y) = (v.ln(), (1.0 - j as f64 / n).ln());
            sx += x;
            sy += y;
            sxx += x * x;
            sxy += x * y;
            k += 1.0;
        }
    }
    let den = k * sxx - sx * sx;
    if k < 2.0 || den <= 0.0 {
        return f64::NAN;
    }
    -(k * sxy - sx * sy) / den
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_single_pit_is_counted_and_filled() {
        // A plane tilted east with one 2 m pit in a 10 x 10 grid of 10 m cells (0.01 km^2).
        let mut v: Vec<f32> = (0..100).map(|i| (i % 10) as f32).collect();
        v[55] -= 2.0;
        let hf = Heightfield::new(10, 10, v, 10.0, 10.0).unwrap();
        let s = drainage(&hf);
        assert!((s.pits_per_km2 - 100.0).abs() < 1e-9, "{s:?}");
        // The pit fills to its lowest neighbour (4 m, from 3 m) plus 1e-4: 1.0001 m over 100.
        assert!((s.fill_depth_m - 1.0001 / 100.0).abs() < 1e-9, "{s:?}");
    }

    #[test]
    fn beta_of_parallel_rills_is_flat_and_of_a_tree_is_positive() {
        // A V-shaped valley draining south: a convergent network gives a finite beta.
        let (w, h) = (64, 64);
        let v: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                (x - 31.5).abs() * 2.0
                    + (h as f32 - y) * 0.5
                    + relief_heightfield::rng::unit_f32(relief_heightfield::rng::hash(
                        3, i as u64, 0, 0,
                    ))
            })
            .collect();
        let hf = Heightfield::new(w, h, v, 30.0, 30.0).unwrap();
        let s = drainage(&hf);
        assert!(s.beta.is_finite() && s.beta > 0.0, "{s:?}");
    }
}
