//! Flow routing on a conditioned surface: D8 receivers (steepest descent, distances of
//! non-square cells), the topological order of the flow graph, drainage area (D8 and the
//! multiple-flow-direction scheme of Quinn et al. 1991), and the products built on them
//! ([`network`]: Strahler order, channels as GeoJSON; [`basins`]: watersheds, HAND). [`tiled`]
//! computes the filled surface, D8 directions and drainage area of a DEM larger than one
//! machine in five passes over tiles (Barnes 2016, 2017), equal bit for bit to [`route`] and
//! [`Routing::area_d8`], and the Strahler order, watersheds, HAND and channel network of
//! [`job`] in two more.

pub mod basins;
pub mod job;
pub mod network;
pub mod tiled;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::depression::{self, BreachLimits, FillMode};
use crate::elev::Elev;
use crate::grid::{D8, Grid, NO_FLOW};

/// How closed depressions are handled before routing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Depressions {
    /// Priority-flood fill to the spill level, then drainage across the flats (Barnes et al.
    /// 2014, both papers): the GIS standard; filled elevations are unique.
    #[default]
    Fill,
    /// Priority-Flood+epsilon: every filled cell one representable step above the cell it was
    /// reached from, so every cell drains without a flats pass.
    Epsilon,
    /// Least-cost breaching (Lindsay 2016) within `breach_depth` and `breach_length`, the
    /// remaining depressions filled: keeps valley floors.
    Breach,
    /// No conditioning: pits are sinks where flow ends.
    None,
}

/// Flow directions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Directions {
    /// Single flow direction: the steepest of the eight neighbours.
    #[default]
    D8,
    /// Multiple flow directions (Quinn et al. 1991 FD8, Freeman 1991 exponent): water split
    /// among all lower neighbours in proportion to `(slope * contour length)^p`.
    Mfd,
}

/// ESRI / ArcGIS / pysheds direction codes of [`D8`] (east 1, south-east 2, ..., north-east
/// 128), the encoding of `relief flow`'s direction raster (0: outlet or sink).
pub const ESRI_CODES: [u8; 8] = [32, 64, 128, 16, 1, 8, 4, 2];

/// A routed surface: the conditioned elevations, each cell's D8 direction and the cells in
/// flow order (every cell before its receiver).
#[derive(Debug, Clone)]
pub struct Routing {
    /// The raster.
    pub grid: Grid,
    /// Conditioned elevations (filled or breached), voids `NaN`.
    pub surface: Vec<f32>,
    /// D8 direction (index into [`D8`]) or [`NO_FLOW`] (outlet, sink or void).
    pub dir: Vec<u8>,
    /// Valid cells in upstream-to-downstream order (donors before their receiver).
    pub order: Vec<u32>,
    /// True for the valid cells that drain off the map (edge or beside a void).
    pub outlet: Vec<bool>,
}

/// Settings of the routing step shared by `relief flow`, `relief erode` and the masks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RouteOptions {
    /// Depression handling.
    pub depressions: Depressions,
    /// Limits of breaching ([`Depressions::Breach`]).
    pub breach: BreachLimits,
}

impl Default for RouteOptions {
    fn default() -> Self {
        Self {
            depressions: Depressions::Fill,
            breach: BreachLimits {
                max_depth: 50.0,
                max_length: 2_000.0,
            },
        }
    }
}

/// Conditions `z` (a copy of the DEM, voids `NaN`) and routes it with D8. A `-0.0` cell is
/// taken as `+0.0` first: the flood raises a cell to a spill level equal to it, so otherwise
/// the sign of a filled zero would depend on which of two equal zeros reached it first (and
/// the tiled run of [`tiled`] could not reproduce it).
pub fn route(mut z: Vec<f32>, grid: Grid, opts: &RouteOptions) -> Routing {
    positive_zeros(&mut z);
    match opts.depressions {
        Depressions::Fill => {
            depression::priority_flood(&mut z, &grid, FillMode::Plain, None);
        }
        Depressions::Epsilon => {
            depression::priority_flood(&mut z, &grid, FillMode::Epsilon, None);
        }
        Depressions::Breach => {
            depression::breach(&mut z, &grid, opts.breach);
            depression::priority_flood(&mut z, &grid, FillMode::Plain, None);
        }
        Depressions::None => {}
    }
    let outlet: Vec<bool> = (0..grid.len())
        .into_par_iter()
        .map(|i| !z[i].is_nan() && depression::is_outlet(&z, &grid, i))
        .collect();
    let mut dir = steepest_descent(&z, &grid, &outlet);
    if opts.depressions != Depressions::Epsilon {
        depression::resolve_flats(&z, &grid, &outlet, &mut dir);
    }
    let order = flow_order(&grid, &dir, |i| !z[i].is_nan());
    Routing {
        grid,
        surface: z,
        dir,
        order,
        outlet,
    }
}

/// Turns every `-0.0` into `+0.0` (see [`route`]).
pub fn positive_zeros(z: &mut [f32]) {
    for v in z.iter_mut() {
        if *v == 0.0 {
            *v = 0.0;
        }
    }
}

/// The D8 direction of steepest descent of every valid cell (drop over centre distance; the
/// first of [`D8`] wins a tie); [`NO_FLOW`] where no neighbour is strictly lower and on the
/// outlets (cells on the edge or beside a void drain off the map, as in RichDEM and
/// fastscapelib, whose router this rule equals).
pub fn steepest_descent<T: Elev>(z: &[T], grid: &Grid, outlet: &[bool]) -> Vec<u8> {
    let dist = grid.distances();
    let inv: [f64; 8] = dist.map(|d| 1.0 / d);
    let mut dir = vec![NO_FLOW; grid.len()];
    dir.par_iter_mut().enumerate().for_each(|(i, d)| {
        if z[i].is_void() || outlet[i] {
            return;
        }
        let zi = z[i].to_f64();
        let mut best = 0.0;
        grid.for_neighbours(i, |k, m| {
            if z[m].is_void() {
                return;
            }
            let s = (zi - z[m].to_f64()) * inv[k];
            if s > best {
                best = s;
                *d = k as u8;
            }
        });
    });
    dir
}

/// The receiver of cell `i` under direction `d`, if any.
#[inline]
pub fn receiver(grid: &Grid, i: usize, d: u8) -> Option<usize> {
    if d == NO_FLOW {
        None
    } else {
        let (dy, dx) = D8[d as usize];
        Some((i as isize + dy * grid.width as isize + dx) as usize)
    }
}

/// The valid cells in flow order (Kahn's algorithm over the D8 graph, sources in index order):
/// every cell comes before its receiver.
pub fn flow_order(grid: &Grid, dir: &[u8], valid: impl Fn(usize) -> bool) -> Vec<u32> {
    let n = grid.len();
    let mut donors = vec![0u8; n];
    for i in 0..n {
        if let Some(r) = receiver(grid, i, dir[i]) {
            donors[r] += 1;
        }
    }
    let mut order = Vec::with_capacity(n);
    for i in 0..n {
        if donors[i] == 0 && valid(i) {
            order.push(i as u32);
        }
    }
    let mut head = 0;
    while head < order.len() {
        let c = order[head] as usize;
        head += 1;
        if let Some(r) = receiver(grid, c, dir[c]) {
            donors[r] -= 1;
            if donors[r] == 0 {
                order.push(r as u32);
            }
        }
    }
    order
}

impl Routing {
    /// D8 drainage area (m^2) of every cell: its own area times its weight (1 without
    /// weights, e.g. a rainfall raster) plus the area of every cell upstream; `NaN` on voids.
    pub fn accumulation(&self, weights: Option<&[f32]>) -> Vec<f64> {
        let a0 = self.grid.cell_area();
        let mut acc: Vec<f64> = (0..self.grid.len())
            .map(|i| {
                if self.surface[i].is_nan() {
                    f64::NAN
                } else {
                    a0 * weights.map_or(1.0, |w| w[i] as f64)
                }
            })
            .collect();
        for &c in &self.order {
            let c = c as usize;
            if let Some(r) = receiver(&self.grid, c, self.dir[c]) {
                acc[r] += acc[c];
            }
        }
        acc
    }

    /// Cells upstream of every cell along the D8 directions, itself included (0 on voids):
    /// integers, so the sums do not depend on the order they are made in (the tiled run of
    /// [`tiled`] adds them in another order and gets the same values).
    pub fn cells_upstream(&self) -> Vec<u64> {
        let mut n: Vec<u64> = self
            .surface
            .iter()
            .map(|v| u64::from(!v.is_nan()))
            .collect();
        for &c in &self.order {
            let c = c as usize;
            if let Some(r) = receiver(&self.grid, c, self.dir[c]) {
                n[r] += n[c];
            }
        }
        n
    }

    /// D8 drainage area (m^2) as `relief flow` writes it: [`Self::cells_upstream`] times the
    /// cell area (one product per cell, so equal bit for bit to the tiled run's), `NaN` on
    /// voids.
    pub fn area_d8(&self) -> Vec<f64> {
        let a0 = self.grid.cell_area();
        self.cells_upstream()
            .iter()
            .zip(&self.surface)
            .map(|(&n, z)| if z.is_nan() { f64::NAN } else { n as f64 * a0 })
            .collect()
    }

    /// Multiple-flow-direction drainage area (m^2): each cell splits its water among its
    /// strictly lower neighbours in proportion to `(tan slope)^p * L`, with the contour length
    /// `L` 0.5 of a cell side for the four sides and 0.354 for the diagonals (Quinn et al.
    /// 1991); cells without a lower neighbour (flats) pass all of it along their D8 direction,
    /// outlets keep it.
    pub fn accumulation_mfd(&self, exponent: f64) -> Vec<f64> {
        let g = &self.grid;
        let z = &self.surface;
        let n = g.len();
        let dist = g.distances();
        let contour: [f64; 8] = D8.map(|(dy, dx)| if dy != 0 && dx != 0 { 0.354 } else { 0.5 });
        // Order: every strictly-lower edge and every flat D8 edge goes down in (elevation,
        // flat rank), so a Kahn pass over the combined graph terminates.
        let lower = |i: usize, m: usize| !z[m].is_nan() && z[m] < z[i];
        let mut donors = vec![0u8; n];
        let mut splits = vec![false; n];
        for i in 0..n {
            if z[i].is_nan() || self.outlet[i] {
                continue;
            }
            let mut any = false;
            g.for_neighbours(i, |_, m| any |= lower(i, m));
            splits[i] = any;
            if any {
                g.for_neighbours(i, |_, m| {
                    if lower(i, m) {
                        donors[m] += 1;
                    }
                });
            } else if let Some(r) = receiver(g, i, self.dir[i]) {
                donors[r] += 1;
            }
        }
        let a0 = g.cell_area();
        let mut acc: Vec<f64> = z
            .iter()
            .map(|v| if v.is_nan() { f64::NAN } else { a0 })
            .collect();
        let mut queue: Vec<u32> = (0..n as u32)
            .filter(|&i| donors[i as usize] == 0 && !z[i as usize].is_nan())
            .collect();
        let mut head = 0;
        let push = |m: usize, donors: &mut [u8], queue: &mut Vec<u32>| {
            donors[m] -= 1;
            if donors[m] == 0 {
                queue.push(m as u32);
            }
        };
        while head < queue.len() {
            let c = queue[head] as usize;
            head += 1;
            if splits[c] {
                let mut w = [0.0f64; 8];
                let mut total = 0.0;
                g.for_neighbours(c, |k, m| {
                    if lower(c, m) {
                        let s = (z[c] - z[m]) as f64 / dist[k];
                        w[k] = s.powf(exponent) * contour[k];
                        total += w[k];
                    }
                });
                let a = acc[c];
                g.for_neighbours(c, |k, m| {
                    if lower(c, m) {
                        acc[m] += a * w[k] / total;
                        push(m, &mut donors, &mut queue);
                    }
                });
            } else if let Some(r) = receiver(g, c, self.dir[c]) {
                acc[r] += acc[c];
                push(r, &mut donors, &mut queue);
            }
        }
        acc
    }

    /// Number of valid cells that are neither outlets nor drained (sinks left in place).
    pub fn sinks(&self) -> usize {
        (0..self.grid.len())
            .filter(|&i| !self.surface[i].is_nan() && !self.outlet[i] && self.dir[i] == NO_FLOW)
            .count()
    }
}

#[cfg(test)]
mod tests;
