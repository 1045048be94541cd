//! Alluvial fans where channels leave their valleys: the sediment a catchment lost is laid
//! down as a cone below the mouth of its valley, at the gradient of real fans.
//!
//! Stream power incises and the hydraulic model moves sediment only a few cells on coarse
//! grids (its iterations are scaled to the cell, [`super::job::RILL_CELL_M`]), so on 30-90 m
//! DEMs nothing carries a valley's load to the plain below it. Fans are built here from the
//! routed network in one pass instead:
//!
//! 1. **Routing**: D8 on the epsilon-filled surface; each cell's drainage area and the volume
//!    eroded upstream of it (the run's net lowering so far, uplift left out).
//! 2. **Mouths**: channel cells (catchment at least [`FanParams::min_catchment_m2`]) where the
//!    channel steeper than three times the fan gradient above them reaches ground no steeper
//!    than the fan gradient below them, over a reach of `0.1 sqrt(A)` (100 m for 1 km^2, 1 km
//!    for 100 km^2; at least two cells), measured along the trunk stream where the valley
//!    opens onto a larger one's floor (the fans of the Alpine valleys and of the Grand
//!    Canyon's tributaries). Taken upstream first; a mouth already buried by a fan is skipped.
//!    The fan's apex is the first cell below the mouth where the channel is no steeper than
//!    the fan.
//! 3. **Cones**: from each mouth, the surface `apex - S d`, with `S` the fan gradient
//!    ([`FanParams::gradient_deg`]; fluvial fans 1-5 degrees, debris-flow fans to 10 or more)
//!    and `d` the distance from the apex over the ground the cone covers (so a fan spreads
//!    around hills, not through them), within a radius of `sqrt(A)` (Bull's fan areas are
//!    0.1-2 times `A^0.9`; at most 20 km). The apex height is found by bisection so that the
//!    cone's volume above the ground is [`FanParams::trapped`] times the volume eroded
//!    upstream; it rises at most `S` times the reach (and 150 m) above the mouth (a fan heads
//!    at the mouth and backfills the valley a little; it does not bury it), and a cone that
//!    reaches that height or its radius first is kept at that size. It is nowhere thicker
//!    than at its apex: where the ground falls away faster than the fan (a gorge or a cliff
//!    below the toe) the fan ends there rather than filling it. A fan pushes the larger
//!    stream it meets aside rather than damming it: cells draining more than twice its
//!    catchment are neither raised nor crossed.
//!
//! The cone raises the ground, never lowers it; its volume is bounded by the sediment eroded
//! upstream, so the run conserves mass. Flow on a cone runs radially off it, the divergent
//! drainage of real fans.

use relief_heightfield::param::{ParamError, in_range};
use serde::{Deserialize, Serialize};

use crate::elev::Elev;
use crate::flow::{Depressions, RouteOptions, receiver, route};
use crate::grid::Grid;
use crate::radix::RadixHeap;

/// The largest fan radius (m) whatever the catchment: the largest alluvial fans outside the
/// megafans of the Himalayan foreland are some tens of kilometres long (Blair and McPherson
/// 1994); it also bounds the work of one cone.
const MAX_RADIUS_M: f64 = 20_000.0;

/// The highest a fan's apex rises above its mouth (m).
const MAX_RISE_M: f64 = 150.0;

/// Parameters of [`build_fans`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FanParams {
    /// Surface gradient of the fans (degrees).
    pub gradient_deg: f64,
    /// Fraction of the volume eroded upstream of a mouth laid down on its fan (the rest is
    /// carried on by the stream).
    pub trapped: f64,
    /// Smallest catchment (m^2) whose mouth builds a fan.
    pub min_catchment_m2: f64,
}

impl Default for FanParams {
    fn default() -> Self {
        Self {
            gradient_deg: 3.0,
            trapped: 0.5,
            min_catchment_m2: 1e5,
        }
    }
}

impl FanParams {
    /// Checks every field, naming the first one out of range.
    pub fn check(&self) -> Result<(), ParamError> {
        in_range(
            "gradient_deg",
            self.gradient_deg,
            0.1..=30.0,
            "must be in [0.1, 30] degrees",
        )?;
        in_range("trapped", self.trapped, 0.0..=1.0, "must be in [0, 1]")?;
        in_range(
            "min_catchment_m2",
            self.min_catchment_m2,
            0.0..1e15,
            "must be >= 0 and finite (m2)",
        )
    }
}

/// What [`build_fans`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FanFigures {
    /// Fans built.
    pub fans: usize,
    /// Volume laid down (m^3).
    pub volume_m3: f64,
    /// Thickest deposit (m).
    pub max_thickness_m: f64,
}

/// Builds the fans of the module docs on `z` (m, voids `NaN`) in place; `eroded[i]` is the
/// depth (m) the run has lowered cell `i` by so far (negative or `NaN`: nothing). `stop` is
/// asked before each fan; when it returns true the step ends with `None` (the fans built so
/// far stay in `z`).
pub fn build_fans(
    z: &mut [f32],
    eroded: &[f32],
    grid: &Grid,
    p: &FanParams,
    stop: &dyn Fn() -> bool,
) -> Option<FanFigures> {
    let n = grid.len();
    let r = route(
        z.to_vec(),
        *grid,
        &RouteOptions {
            depressions: Depressions::Epsilon,
            ..RouteOptions::default()
        },
    );
    let a0 = grid.cell_area();
    let mut area = vec![0f64; n];
    let mut volume = vec![0f64; n];
    // The upstream neighbour with the largest catchment (the main stem), `u32::MAX` for none.
    let mut main = vec![u32::MAX; n];
    for &c in &r.order {
        let c = c as usize;
        area[c] += a0;
        let e = eroded[c];
        if e > 0.0 {
            volume[c] += f64::from(e) * a0;
        }
        if let Some(q) = receiver(grid, c, r.dir[c]) {
            area[q] += area[c];
            volume[q] += volume[c];
            if main[q] == u32::MAX || area[c] > area[main[q] as usize] {
                main[q] = c as u32;
            }
        }
    }
    let s_fan = p.gradient_deg.to_radians().tan();
    let dist = grid.distances();
    let two_cells = 2.0 * grid.cell_x.max(grid.cell_y);
    let zs = &r.surface;
    let mut figures = FanFigures::default();
    let mut builder = ConeBuilder::new(grid);
    for &m in &r.order {
        let m = m as usize;
        // The cheap tests first: a cell under a fan already built, or draining too little,
        // needs no walk along its channel.
        if builder.buried[m]
            || area[m] < p.min_catchment_m2.max(a0)
            || p.trapped * volume[m] <= a0 * 1e-3
        {
            continue;
        }
        let reach = (0.1 * area[m].sqrt()).max(two_cells);
        // Downstream: the drop over the reach (along the trunk stream where the valley opens
        // onto a larger one's floor).
        let (mut c, mut d) = (m, 0.0);
        while d < reach {
            match receiver(grid, c, r.dir[c]) {
                Some(q) => {
                    d += dist[r.dir[c] as usize];
                    c = q;
                }
                None => break,
            }
        }
        if d < reach {
            continue;
        }
        let s_down = f64::from(zs[m] - zs[c]) / d;
        // Upstream along the main stem.
        let (mut c, mut u) = (m, 0.0);
        while u < reach && main[c] != u32::MAX {
            let q = main[c] as usize;
            u += dist[r.dir[q] as usize];
            c = q;
        }
        if u < reach {
            continue;
        }
        let s_up = f64::from(zs[c] - zs[m]) / u;
        if s_down > s_fan || s_up < 3.0 * s_fan {
            continue;
        }
        // The apex: the first cell downstream where the channel is no steeper than the fan
        // (the reach's mean slopes place `m` up to half a reach inside the valley).
        let mut apex = m;
        let mut walked = 0.0;
        while walked < reach {
            match receiver(grid, apex, r.dir[apex]) {
                Some(q) if f64::from(z[apex] - z[q]) / dist[r.dir[apex] as usize] > s_fan => {
                    walked += dist[r.dir[apex] as usize];
                    apex = q;
                }
                _ => break,
            }
        }
        // The apex rises at most the fan's own fall over the reach: a fan heads at its
        // valley's mouth and backfills the valley a little, it does not bury it.
        let limits = (
            area[apex].sqrt().min(MAX_RADIUS_M),
            (s_fan * reach).min(MAX_RISE_M),
        );
        if stop() {
            return None;
        }
        let added = builder.build(z, &area, apex, s_fan, limits, p.trapped * volume[m]);
        if added.0 > 0.0 {
            figures.fans += 1;
            figures.volume_m3 += added.0;
            figures.max_thickness_m = figures.max_thickness_m.max(added.1);
        }
    }
    Some(figures)
}

/// The cones of [`build_fans`], with their scratch.
struct ConeBuilder<'a> {
    grid: &'a Grid,
    /// Cells under a fan already built.
    buried: Vec<bool>,
    /// Distance from the current apex (m), `INFINITY` where not reached.
    d: Vec<f64>,
    /// Cells whose distance was set by the current flood (to reset them).
    touched: Vec<usize>,
}

impl<'a> ConeBuilder<'a> {
    fn new(grid: &'a Grid) -> Self {
        Self {
            grid,
            buried: vec![false; grid.len()],
            d: vec![f64::INFINITY; grid.len()],
            touched: Vec::new(),
        }
    }

    /// The cells of the cone `z[apex] + rise - s d` over `z` from `apex` within `radius` m and
    /// no thicker than `rise`, with their distances (left in `self.d` until the next flood),
    /// and the cone's volume (m^3).
    fn flood(&mut self, z: &[f32], trunk: &Trunk<'_>, rise: f64, s: f64, radius: f64) -> f64 {
        let apex = trunk.apex;
        let top = f64::from(z[apex]) + rise;
        for &i in &self.touched {
            self.d[i] = f64::INFINITY;
        }
        self.touched.clear();
        let dist = self.grid.distances();
        let a0 = self.grid.cell_area();
        // Dijkstra's order with a radix heap (the distances popped never decrease).
        let mut heap: RadixHeap<<f64 as Elev>::Entry> = RadixHeap::new();
        self.d[apex] = 0.0;
        self.touched.push(apex);
        heap.push(0f64.entry(apex as u32));
        let mut volume = 0.0;
        while let Some(e) = heap.pop() {
            let i = f64::cell(e) as usize;
            let di = self.d[i];
            if e != di.entry(i as u32) {
                // A stale entry: the cell was reached by a shorter path since.
                continue;
            }
            let above = top - s * di - f64::from(z[i]);
            // Nowhere thicker than at the apex: where the ground falls away faster than the
            // fan (a gorge, a cliff below the toe) the fan ends rather than filling it.
            // (A micrometre of slack: at the apex `above` is `rise` up to rounding.)
            if above <= 0.0 || above > rise + 1e-6 {
                continue;
            }
            volume += above * a0;
            self.grid.for_neighbours(i, |k, j| {
                let dj = di + dist[k];
                if z[j].is_nan() || dj > radius || dj >= self.d[j] || trunk.is_trunk(j) {
                    return;
                }
                if self.d[j].is_infinite() {
                    self.touched.push(j);
                }
                self.d[j] = dj;
                heap.push(dj.entry(j as u32));
            });
        }
        volume
    }

    /// Lays the cone from `apex` holding `volume` m^3 onto `z`, or as much as fits within
    /// `radius` with its top at most `max_rise` above the apex; returns the volume laid down
    /// and the thickest deposit.
    fn build(
        &mut self,
        z: &mut [f32],
        area: &[f64],
        apex: usize,
        s: f64,
        (radius, max_rise): (f64, f64),
        volume: f64,
    ) -> (f64, f64) {
        let trunk = Trunk { area, apex };
        let base = f64::from(z[apex]);
        let (mut lo, mut hi) = (0.0, max_rise);
        if self.flood(z, &trunk, hi, s, radius) > volume {
            // To a millionth of the rise.
            for _ in 0..20 {
                let mid = 0.5 * (lo + hi);
                if self.flood(z, &trunk, mid, s, radius) > volume {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
        } else {
            lo = hi;
        }
        self.flood(z, &trunk, lo, s, radius);
        let (mut laid, mut thickest) = (0.0, 0.0f64);
        let a0 = self.grid.cell_area();
        for &i in &self.touched {
            let cone = base + lo - s * self.d[i];
            let above = cone - f64::from(z[i]);
            if above > 0.0 && above <= lo + 1e-6 {
                // Rounded to f32 the raise may be a little less than `above`: count what lands.
                let before = z[i];
                z[i] = (cone as f32).max(before);
                let t = f64::from(z[i] - before);
                laid += t * a0;
                thickest = thickest.max(t);
                self.buried[i] = true;
            }
        }
        (laid, thickest)
    }
}

/// The streams a fan does not bury: a fan pushes the larger stream its valley joins aside,
/// it does not dam it (cells draining more than twice the apex's catchment are left as they
/// are, and the cone does not spread across them).
struct Trunk<'a> {
    area: &'a [f64],
    apex: usize,
}

impl Trunk<'_> {
    fn is_trunk(&self, i: usize) -> bool {
        self.area[i] > 2.0 * self.area[self.apex]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A valley (a V trough falling east at 20 %) that opens at mid-grid onto a plain falling
    /// east at 0.5 %: 100 m cells.
    fn valley_and_plain() -> (Grid, Vec<f32>) {
        let grid = Grid::new(120, 61, 100.0, 100.0);
        let z = (0..grid.len())
            .map(|i| {
                let (x, y) = ((i % 120) as f64, (i / 120) as f64);
                let across = (y - 30.0).abs() * 100.0;
                let v = if x < 60.0 {
                    // The valley: its floor falls 20 m per cell, its sides rise at 30 %.
                    300.0 + (60.0 - x) * 20.0 + 0.3 * across
                } else {
                    300.0 - (x - 60.0) * 0.5 + 0.001 * across
                };
                v as f32
            })
            .collect();
        (grid, z)
    }

    #[test]
    fn a_valley_opening_onto_a_plain_builds_a_fan_of_its_eroded_volume() {
        let (grid, mut z) = valley_and_plain();
        let before = z.clone();
        // 2 m eroded over the whole valley.
        let eroded: Vec<f32> = (0..grid.len())
            .map(|i| if i % 120 < 60 { 2.0 } else { 0.0 })
            .collect();
        let eroded_m3: f64 = eroded.iter().map(|&e| f64::from(e)).sum::<f64>() * 1e4;
        let p = FanParams {
            gradient_deg: 3.0,
            trapped: 0.5,
            min_catchment_m2: 1e5,
        };
        let f = build_fans(&mut z, &eroded, &grid, &p, &|| false).unwrap();
        assert!(f.fans >= 1, "{f:?}");
        // No more than the trapped share of what was eroded; nothing lowered.
        assert!(
            f.volume_m3 <= 0.5 * eroded_m3 * 1.0001,
            "{f:?} of {eroded_m3}"
        );
        assert!(f.volume_m3 > 0.05 * eroded_m3, "{f:?} of {eroded_m3}");
        assert!(z.iter().zip(&before).all(|(a, b)| a >= b));
        // The deposit lies below the valley's mouth, on the plain, spread across it (a cone,
        // not a ridge along the channel), and thins away from the apex.
        let at = |x: usize, y: usize| f64::from(z[y * 120 + x] - before[y * 120 + x]);
        let plain: f64 = (0..grid.len())
            .filter(|i| i % 120 >= 60)
            .map(|i| f64::from(z[i] - before[i]))
            .sum::<f64>()
            * 1e4;
        assert!(plain > 0.5 * f.volume_m3, "{plain} of {f:?}");
        assert!(at(64, 30) > at(75, 30), "{} {}", at(64, 30), at(75, 30));
        assert!(
            at(62, 27) > 0.0 && at(62, 33) > 0.0,
            "{} {}",
            at(62, 27),
            at(62, 33)
        );
        // Nowhere thicker than at the apex.
        assert!(
            f.max_thickness_m <= at(60, 30) + 1e-3,
            "{f:?} {}",
            at(60, 30)
        );
        // The fan's surface falls away from the apex at about the fan gradient.
        let s = f64::from(z[30 * 120 + 62] - z[30 * 120 + 66]) / 400.0;
        assert!((s - 3f64.to_radians().tan()).abs() < 0.01, "gradient {s}");
    }

    #[test]
    fn no_fan_without_erosion_or_when_stopped_and_the_gradient_is_checked() {
        let (grid, mut z) = valley_and_plain();
        let before = z.clone();
        let none = vec![0f32; grid.len()];
        let f = build_fans(&mut z, &none, &grid, &FanParams::default(), &|| false).unwrap();
        assert_eq!((f.fans, z == before), (0, true));
        let bad = FanParams {
            gradient_deg: 0.0,
            ..FanParams::default()
        };
        assert_eq!(bad.check().unwrap_err().name, "gradient_deg");
        // Asked to stop, the step ends before its first fan and changes nothing.
        let (grid, mut z) = valley_and_plain();
        let eroded = vec![2f32; grid.len()];
        assert!(build_fans(&mut z, &eroded, &grid, &FanParams::default(), &|| true).is_none());
        assert!(z == valley_and_plain().1);
    }
}
