//! Watersheds and height above the nearest drainage (HAND, Renno et al. 2008).

use super::{Routing, receiver};

/// The watershed of every valid cell: the outlet (or sink) its flow ends in, numbered from 1
/// by decreasing drainage area (ties by the outlet's index), 0 on voids.
pub fn watersheds(r: &Routing, area: &[f64]) -> Vec<u32> {
    let n = r.grid.len();
    let mut ends: Vec<u32> = (0..n as u32)
        .filter(|&i| !r.surface[i as usize].is_nan() && r.dir[i as usize] == crate::grid::NO_FLOW)
        .collect();
    ends.sort_by(|&a, &b| {
        area[b as usize]
            .total_cmp(&area[a as usize])
            .then(a.cmp(&b))
    });
    let mut label = vec![0u32; n];
    for (k, &e) in ends.iter().enumerate() {
        label[e as usize] = k as u32 + 1;
    }
    for &c in r.order.iter().rev() {
        let c = c as usize;
        if let Some(d) = receiver(&r.grid, c, r.dir[c]) {
            label[c] = label[d];
        }
    }
    label
}

/// Height above the nearest drainage: each cell's conditioned elevation minus that of the
/// first channel cell (`area >= threshold_m2`) its flow path reaches (the outlet's when it
/// reaches none); `NaN` on voids.
pub fn hand(r: &Routing, area: &[f64], threshold_m2: f64) -> Vec<f32> {
    let n = r.grid.len();
    let z = &r.surface;
    let mut base = vec![f32::NAN; n];
    for &c in r.order.iter().rev() {
        let c = c as usize;
        base[c] = if area[c] >= threshold_m2 {
            z[c]
        } else {
            match receiver(&r.grid, c, r.dir[c]) {
                Some(d) => base[d],
                None => z[c],
            }
        };
    }
    (0..n).map(|i| z[i] - base[i]).collect()
}
