//! Hydraulic erosion on the shallow-water "virtual pipe" model of Mei, Decaudin and Hu 2007
//! ("Fast hydraulic erosion simulation and visualization on GPU", section 3), with the
//! depth-limited transport capacity of Št'ava et al. 2008 ("Interactive terrain modeling using
//! hydraulic erosion", section 4.2).
//!
//! Every cell holds a water depth `d`, suspended sediment `s` (metres of material over the
//! cell) and four outflow fluxes (m^3/s) to its west, east, north and south neighbours. One
//! iteration of `dt` seconds is, as in Mei et al. section 3.1:
//!
//! 1. **Rain**: `rain_m` of water on every cell, or on a seeded random `rain_fraction` of the
//!    cells (`relief_heightfield::rng::hash(seed, cell, iteration, 0)`) with `rain_m /
//!    rain_fraction` each, so the mean is the same.
//! 2. **Flow** (eq. 2-5): each pipe's flux grows by `dt A g dh / l` (`dh` the difference of
//!    water surfaces, `l` the centre distance along that axis, `A` the pipe cross-section), is
//!    kept `>= 0`, and the four are scaled down together when they would drain more than the
//!    cell holds (eq. 4). The depth changes by the net inflow (eq. 6-7) and the velocity is
//!    the mean flux through the cell over its cross-section (eq. 8-9).
//! 3. **Erosion and deposition** (eq. 10-12, Št'ava eq. 4): the capacity is
//!    `C = Kc max(sin a, min_tilt) |v| dt min(1, d / full_depth_m)`, `a` the ground's tilt.
//!    Where `s < C`, `erosion_rate (C - s)` is lifted into the water, scaled by
//!    `1 / (1 + removed / hardness_depth_m)` where the ground has already lost `removed` metres
//!    (older, harder layers under the surface); where `s > C`, `deposition_rate (s - C)` is laid
//!    down.
//! 4. **Evaporation** (eq. 15): `d <- d (1 - evaporation)`, then the next iteration's rain
//!    (transport does not read the water, so this can come before it).
//! 5. **Transport** (eq. 14): sediment is advected semi-Lagrangian, `s(x) <- s(x - v dt)`
//!    sampled bilinearly with the position clamped to the map, in the same sweep as the next
//!    iteration's fluxes. Semi-Lagrangian advection does not conserve mass, so the advected
//!    field is rescaled to the total before it (a global mass fixer, Priestley 1993); the
//!    largest correction is reported as `max_mass_fix`. The last iteration's load is not
//!    advected: it settles (or is reported) where the last erosion step left it.
//!
//! One safeguard departs from the paper: erosion never takes a cell below its lowest
//! neighbour, since the frictionless pipe model's water sloshing in a pit would otherwise dig a
//! hole there, ever deeper.
//!
//! **Units and scale.** Lengths are metres and `dt` seconds. Mei's `Kc` (seconds) is written
//! `capacity * dt` here, so `capacity` is dimensionless: a column can carry `capacity sin a`
//! times the distance its water travels in a step. Water moves at most one cell per step (the
//! outflow limit of eq. 4), so in flowing water `|v| dt` is about one cell: the capacity, and
//! with it every erosion and deposition depth, scales with the cell size, and the same settings
//! give the same landforms (in cells) on a 2 m lidar grid as on a 90 m SRTM one. The time step
//! defaults to half the stability limit of the pipe model's gravity waves on the grid,
//! `dt = 0.5 / sqrt(A g (1/(lx^2 ly) + 1/(ly^2 lx)))` (from the linearised pipe equations:
//! symplectic Euler is stable while `omega dt < 2`), which for square cells and `A = l^2` is
//! `0.5 sqrt(l / (2 g))`: 0.87 s on 60 m cells. Water depths do not depend on the cell size:
//! a channel holds the rain of the cells that drain into it within the distance water travels
//! in the run (one cell per iteration at most, and `1 / evaporation` iterations on average),
//! so `full_depth_m` is best read in units of `rain_m`: the default, 200 `rain_m`, keeps the
//! capacity growing with the water gathered over the whole run (sheet flow on the hillslopes
//! carries a few per cent of what a gully does), which is what carves gullies along the flow
//! lines instead of lowering every slope alike.
//!
//! **Boundaries.** Voids (`NaN`) are untouched and, like the outer edge, open: a pipe towards a
//! void or off the map drains into a virtual cell whose surface continues the slope of the
//! opposite side, and the water and sediment leaving through it are gone (`left_m3`).
//!
//! **Determinism.** Every pass is a Jacobi step: each cell's new values are a fixed-order
//! function of the previous buffers, computed in bands of rows in parallel, and the only sums
//! (the mass fixer, the figures) add per-band partial sums in band order, so the output bytes do
//! not depend on the thread count.
//!
//! **Speed.** The fluxes, the advection and the erosion are computed row by row on separate
//! rasters per quantity (the four fluxes, the two velocities): the runs of cells whose four
//! neighbours are valid (most of the map) take branch-free loops over row slices that LLVM
//! vectorises, with the same arithmetic as the per-cell code kept for the cells beside an edge
//! or a void, so both give the same bytes.

use rayon::prelude::*;
use relief_heightfield::param::{in_left_open, in_range};
use relief_heightfield::rng::{hash, unit_f32};
use relief_heightfield::{ParamError, Progress};
use serde::{Deserialize, Serialize};

use crate::LandscapeError;
use crate::grid::Grid;

use super::thermal::{check_input, check_iterations, check_stop};

/// Gravity (m/s^2).
const G: f64 = 9.81;

/// Settings of [`hydraulic`]. The defaults give visible gullies and fans on real DEMs at any
/// cell size (see the module docs for how each scales).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct HydraulicParams {
    /// Number of steps. Water travels at most one cell per step, so this bounds the length of
    /// the flow paths that gather water (in cells).
    pub iterations: u32,
    /// Time step (s); `None`: half the stability limit of the pipe model on the grid's cells.
    pub dt_s: Option<f64>,
    /// Rain per iteration (m of water), the mean over the cells.
    pub rain_m: f64,
    /// Fraction of the cells rained on per iteration, in `(0, 1]`: 1 is uniform rain; below 1
    /// the cells are drawn per iteration from `seed` (droplets of `rain_m / rain_fraction`).
    pub rain_fraction: f64,
    /// Fraction of the water depth that evaporates per iteration, in `[0, 1)` (Mei's `Ke dt`).
    pub evaporation: f64,
    /// Sediment capacity `Kc` (dimensionless: Mei's `Kc` in seconds is `capacity * dt`).
    pub capacity: f64,
    /// Fraction of the missing load `C - s` eroded per iteration, in `[0, 1]` (Mei's `Ks`).
    pub erosion_rate: f64,
    /// Fraction of the excess load `s - C` deposited per iteration, in `[0, 1]` (Mei's `Kd`).
    pub deposition_rate: f64,
    /// Lower bound of `sin(tilt)` in the capacity, in `[0, 1]`, so water on flat ground still
    /// carries some sediment (and flat valley floors are not all deposition).
    pub min_tilt: f64,
    /// Water depth (m) at which the capacity reaches its full value (Št'ava's `K_dmax`):
    /// shallower water carries proportionally less, so sheet flow on hillslopes erodes little
    /// and channels much.
    pub full_depth_m: f64,
    /// Cross-section of a pipe (m^2); `None`: the cell's area `lx ly`, which makes the flow
    /// independent of the cell size.
    pub pipe_area_m2: Option<f64>,
    /// Depth (m) of removed ground over which erodibility halves (`1 / (1 + removed / depth)`);
    /// 0 disables hardening.
    pub hardness_depth_m: f64,
    /// Lay the sediment still suspended at the end down where it is (true), or report it as
    /// `suspended_m3` and drop it (false).
    pub settle: bool,
    /// Seed of the random rain.
    pub seed: u64,
}

impl Default for HydraulicParams {
    fn default() -> Self {
        Self {
            iterations: 80,
            dt_s: None,
            rain_m: 0.01,
            rain_fraction: 1.0,
            evaporation: 0.02,
            capacity: 0.5,
            erosion_rate: 0.3,
            deposition_rate: 0.3,
            min_tilt: 0.02,
            full_depth_m: 2.0,
            pipe_area_m2: None,
            hardness_depth_m: 0.0,
            settle: true,
            seed: 0,
        }
    }
}

impl HydraulicParams {
    /// Checks every field (names the first one out of range).
    pub fn check(&self) -> Result<(), ParamError> {
        check_iterations(self.iterations)?;
        if let Some(dt) = self.dt_s {
            in_left_open("dt_s", dt, (0.0, 1e6), "must be in (0, 1e6] s")?;
        }
        in_range("rain_m", self.rain_m, 0.0..=10.0, "must be in [0, 10] m")?;
        in_left_open(
            "rain_fraction",
            self.rain_fraction,
            (0.0, 1.0),
            "must be in (0, 1]",
        )?;
        in_range(
            "evaporation",
            self.evaporation,
            0.0..1.0,
            "must be in [0, 1)",
        )?;
        in_range("capacity", self.capacity, 0.0..=1e3, "must be in [0, 1000]")?;
        in_range(
            "erosion_rate",
            self.erosion_rate,
            0.0..=1.0,
            "must be in [0, 1]",
        )?;
        in_range(
            "deposition_rate",
            self.deposition_rate,
            0.0..=1.0,
            "must be in [0, 1]",
        )?;
        in_range("min_tilt", self.min_tilt, 0.0..=1.0, "must be in [0, 1]")?;
        in_left_open(
            "full_depth_m",
            self.full_depth_m,
            (0.0, 1e4),
            "must be in (0, 1e4] m",
        )?;
        if let Some(a) = self.pipe_area_m2 {
            in_left_open("pipe_area_m2", a, (0.0, 1e12), "must be in (0, 1e12] m^2")?;
        }
        in_range(
            "hardness_depth_m",
            self.hardness_depth_m,
            0.0..=1e6,
            "must be in [0, 1e6] m (0: off)",
        )
    }

    /// The time step (s) on `grid`: `dt_s`, or half the pipe model's stability limit.
    pub fn time_step(&self, grid: &Grid) -> f64 {
        self.dt_s.unwrap_or_else(|| {
            let (lx, ly) = (grid.cell_x, grid.cell_y);
            let a = self.pipe_area(grid);
            0.5 / (a * G * (1.0 / (lx * lx * ly) + 1.0 / (ly * ly * lx))).sqrt()
        })
    }

    fn pipe_area(&self, grid: &Grid) -> f64 {
        self.pipe_area_m2.unwrap_or(grid.cell_x * grid.cell_y)
    }
}

/// What a [`hydraulic`] run did. Volumes are of ground material (m^3); the budget
/// `eroded_m3 - deposited_m3 = suspended_m3 + left_m3` holds up to rounding.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct HydraulicFigures {
    /// Iterations run.
    pub iterations: u32,
    /// The time step used (s).
    pub dt_s: f64,
    /// Volume of the ground lowered (sum of the erosion raster times the cell area).
    pub eroded_m3: f64,
    /// Volume of the ground raised (sum of the deposition raster times the cell area).
    pub deposited_m3: f64,
    /// Deepest erosion (m).
    pub max_erosion_m: f64,
    /// Thickest deposit (m).
    pub max_deposition_m: f64,
    /// Sediment still in the water at the end and dropped with it (0 with `settle`).
    pub suspended_m3: f64,
    /// Sediment laid down at the end where it was (part of `deposited_m3`; 0 without `settle`).
    pub settled_m3: f64,
    /// Sediment carried off the map or into voids by the water leaving.
    pub left_m3: f64,
    /// Water rained on the map (m^3).
    pub rain_m3: f64,
    /// Largest relative correction of the advection's mass fixer in one step.
    pub max_mass_fix: f64,
}

/// The result of [`hydraulic`] beside the new surface (written into the caller's raster).
#[derive(Debug, Clone, PartialEq)]
pub struct HydraulicOutput {
    /// Depth of ground removed per cell (m, `>= 0`; 0 on voids).
    pub erosion: Vec<f32>,
    /// Thickness of sediment laid down per cell (m, `>= 0`; 0 on voids).
    pub deposition: Vec<f32>,
    /// Figures of the run.
    pub figures: HydraulicFigures,
}

/// Erodes `z` (row-major on `grid`, voids `NaN`) with `p.iterations` steps of rain, flow,
/// erosion, transport and evaporation. `z` is changed only on success: when `stop()` returns
/// true (checked once per iteration) the run ends with [`LandscapeError::Stopped`] and `z` as
/// given.
pub fn hydraulic(
    z: &mut [f32],
    grid: &Grid,
    p: &HydraulicParams,
    progress: &dyn Progress,
    stop: &dyn Fn() -> bool,
) -> Result<HydraulicOutput, LandscapeError> {
    p.check()?;
    check_input(z, grid)?;
    let consts = Consts::new(grid, p);
    let mut sim = Sim::new(z, &consts);
    let mut figures = HydraulicFigures {
        iterations: p.iterations,
        dt_s: consts.dt as f64,
        ..Default::default()
    };
    if p.iterations > 0 {
        figures.rain_m3 += sim.rain(&consts, 0);
    }
    progress.begin("hydraulic erosion", p.iterations as u64);
    let mut suspended = 0.0f64;
    for it in 0..p.iterations {
        check_stop(stop, "hydraulic erosion", it, p.iterations)?;
        // Transport of the previous step's load (steps 4) and the new fluxes (step 2a) in one
        // sweep: both read what the erosion pass wrote and write different buffers.
        let advected = sim.flow_transport(&consts, it > 0);
        if it > 0 {
            // The global mass fixer: the advected field is scaled to the load before the
            // transport, lazily (the erosion pass multiplies the load it reads by the factor).
            if advected > 0.0 {
                sim.scale = (suspended / advected) as f32;
                figures.max_mass_fix = figures.max_mass_fix.max((suspended / advected - 1.0).abs());
            }
        }
        let next = (it + 1 < p.iterations).then_some(it + 1);
        let (load, left, rain) = sim.erode(z, &consts, next);
        suspended = load;
        figures.left_m3 += left;
        figures.rain_m3 += rain;
        progress.advance(1);
    }
    let area = grid.cell_area();
    let load = sim.load();
    if p.settle {
        figures.settled_m3 = sim.settle() * area;
    } else {
        figures.suspended_m3 = load * area;
    }
    figures.left_m3 *= area;
    figures.rain_m3 *= area;

    let mut erosion = vec![0.0f32; z.len()];
    let mut deposition = vec![0.0f32; z.len()];
    (z.par_iter_mut(), &sim.b, &mut erosion, &mut deposition)
        .into_par_iter()
        .for_each(|(z0, &b, e, dep)| {
            if z0.is_nan() {
                return;
            }
            *e = (*z0 - b).max(0.0);
            *dep = (b - *z0).max(0.0);
            *z0 = b;
        });
    // Fixed-order sums (the map's rows one after the other).
    for (e, dep) in erosion
        .chunks(grid.width)
        .zip(deposition.chunks(grid.width))
    {
        figures.eroded_m3 += e.iter().map(|&v| v as f64).sum::<f64>() * area;
        figures.deposited_m3 += dep.iter().map(|&v| v as f64).sum::<f64>() * area;
        let max = |v: &[f32]| v.iter().fold(0.0f32, |m, &x| m.max(x)) as f64;
        figures.max_erosion_m = figures.max_erosion_m.max(max(e));
        figures.max_deposition_m = figures.max_deposition_m.max(max(dep));
    }
    Ok(HydraulicOutput {
        erosion,
        deposition,
        figures,
    })
}

/// Rows per parallel work item (a fixed decomposition: results do not depend on it).
const BAND_ROWS: usize = 16;

/// Pipe directions: west, east, north, south.
const W: usize = 0;
const E: usize = 1;
const N: usize = 2;
const S: usize = 3;
/// The opposite of each direction.
const OPP: [usize; 4] = [E, W, S, N];

/// The settings resolved on the grid, as the `f32` the passes compute in.
struct Consts {
    width: usize,
    height: usize,
    dt: f32,
    /// Cell area (m^2).
    area: f32,
    /// `dt A g / l` per direction (m^2 s: flux gained per metre of head).
    kflux: [f32; 4],
    lx: f32,
    ly: f32,
    rain: f32,
    rain_fraction: f32,
    seed: u64,
    keep: f32,
    ks: f32,
    kd: f32,
    min_tilt: f32,
    inv_full_depth: f32,
    inv_hardness: f32,
    /// `dt / area`, `1 / lx`, `1 / ly`, `capacity dt`, the velocity limits (a cell per step).
    dt_area: f32,
    inv_lx: f32,
    inv_ly: f32,
    kc_dt: f32,
    max_u: f32,
    max_v: f32,
}

impl Consts {
    fn new(grid: &Grid, p: &HydraulicParams) -> Self {
        let dt = p.time_step(grid);
        let a = p.pipe_area(grid);
        let (lx, ly) = (grid.cell_x, grid.cell_y);
        let k = |l: f64| (dt * a * G / l) as f32;
        Self {
            width: grid.width,
            height: grid.height,
            dt: dt as f32,
            area: (lx * ly) as f32,
            kflux: [k(lx), k(lx), k(ly), k(ly)],
            lx: lx as f32,
            ly: ly as f32,
            rain: p.rain_m as f32,
            rain_fraction: p.rain_fraction as f32,
            seed: p.seed,
            keep: (1.0 - p.evaporation) as f32,
            ks: p.erosion_rate as f32,
            kd: p.deposition_rate as f32,
            min_tilt: p.min_tilt as f32,
            inv_full_depth: (1.0 / p.full_depth_m) as f32,
            inv_hardness: if p.hardness_depth_m > 0.0 {
                (1.0 / p.hardness_depth_m) as f32
            } else {
                0.0
            },
            dt_area: (dt / (lx * ly)) as f32,
            inv_lx: (1.0 / lx) as f32,
            inv_ly: (1.0 / ly) as f32,
            kc_dt: (p.capacity * dt) as f32,
            max_u: (lx / dt) as f32,
            max_v: (ly / dt) as f32,
        }
    }

    /// Rain on cell `i` at iteration `it` (m).
    #[inline]
    fn rain_at(&self, i: usize, it: u32) -> f32 {
        if self.rain_fraction >= 1.0 {
            self.rain
        } else if unit_f32(hash(self.seed, i as u64, it as u64, 0)) < self.rain_fraction {
            self.rain / self.rain_fraction
        } else {
            0.0
        }
    }

    /// The indices of the west, east, north and south neighbours of cell `i` at `(x, y)`,
    /// the cell itself for a side off the map.
    #[inline(always)]
    fn neighbours(&self, x: usize, y: usize, i: usize) -> [usize; 4] {
        let w = self.width;
        [
            i - (x > 0) as usize,
            i + (x + 1 < w) as usize,
            i - if y > 0 { w } else { 0 },
            i + if y + 1 < self.height { w } else { 0 },
        ]
    }
}

/// Bit of [`Sim::mask`] set for a valid cell; bits 0-3 are set for its valid neighbours (on the
/// map and not void) in the order west, east, north, south.
const VALID: u8 = 16;
/// The mask of a valid cell whose four neighbours are valid: the passes compute runs of these
/// (most of the map) without the edge and void branches.
const FULL: u8 = VALID | 15;

/// True when `mask` says neighbour `k` is valid.
#[inline(always)]
fn ok(mask: u8, k: usize) -> bool {
    mask >> k & 1 != 0
}

/// `x.clamp(lo, hi)` (the same comparisons) without the check of the bounds, so a loop using it
/// can be vectorised.
#[inline(always)]
fn clamp(x: f32, lo: f32, hi: f32) -> f32 {
    let x = if x < lo { lo } else { x };
    if x > hi { hi } else { x }
}

/// The simulation state: ground, water, load, fluxes and velocities (all `f32`).
struct Sim {
    /// Ground (m), voids `NaN`.
    b: Vec<f32>,
    /// The ground being written by the erosion pass.
    b_next: Vec<f32>,
    /// Water depth (m).
    d: Vec<f32>,
    /// Suspended load (m of material), to be multiplied by `scale`.
    s: Vec<f32>,
    /// The load being written by the transport pass.
    s_next: Vec<f32>,
    /// Outflow fluxes (m^3/s) to the west, east, north and south, a raster per direction.
    f: [Vec<f32>; 4],
    /// Velocity (m/s) east.
    u: Vec<f32>,
    /// Velocity (m/s) south.
    v: Vec<f32>,
    /// Per cell: [`VALID`] and the valid neighbours (voids never change).
    mask: Vec<u8>,
    /// Per row, the runs `[start, end)` of columns of [`FULL`] cells.
    runs: Vec<Vec<(usize, usize)>>,
    /// The mass fixer's factor, applied when `s` is next read.
    scale: f32,
}

/// The runs `[start, end)` of [`FULL`] cells in a row of the mask, then `(width, width)`, so
/// that the cells before each run's start (and after the last run) are the others.
fn full_runs(row: &[u8]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut x = 0;
    while x < row.len() {
        if row[x] == FULL {
            let start = x;
            while x < row.len() && row[x] == FULL {
                x += 1;
            }
            runs.push((start, x));
        } else {
            x += 1;
        }
    }
    runs.push((row.len(), row.len()));
    runs
}

/// One row of the erosion pass's outputs.
struct RowOut<'a> {
    b: &'a mut [f32],
    d: &'a mut [f32],
    s: &'a mut [f32],
    u: &'a mut [f32],
    v: &'a mut [f32],
}

impl Sim {
    fn new(z: &[f32], c: &Consts) -> Self {
        let n = z.len();
        let zero = || vec![0.0f32; n];
        let mask: Vec<u8> = (0..n)
            .map(|i| {
                if z[i].is_nan() {
                    return 0;
                }
                let (x, y) = (i % c.width, i / c.width);
                let nb = c.neighbours(x, y, i);
                (0..4).fold(VALID, |m, k| {
                    m | (((nb[k] != i) && !z[nb[k]].is_nan()) as u8) << k
                })
            })
            .collect();
        let runs = mask.chunks(c.width).map(full_runs).collect();
        Self {
            mask,
            runs,
            b: z.to_vec(),
            b_next: z.to_vec(),
            d: zero(),
            s: zero(),
            s_next: zero(),
            f: [zero(), zero(), zero(), zero()],
            u: zero(),
            v: zero(),
            scale: 1.0,
        }
    }

    /// Rains on every valid cell for iteration `it`; returns the depth summed over the cells.
    fn rain(&mut self, c: &Consts, it: u32) -> f64 {
        let band = BAND_ROWS * c.width;
        let b = &self.b;
        let sums: Vec<f64> = self
            .d
            .par_chunks_mut(band)
            .enumerate()
            .map(|(k, d)| {
                let mut sum = 0.0f64;
                for (j, d) in d.iter_mut().enumerate() {
                    let i = k * band + j;
                    if !b[i].is_nan() {
                        let r = c.rain_at(i, it);
                        *d += r;
                        sum += r as f64;
                    }
                }
                sum
            })
            .collect();
        sums.iter().sum()
    }

    /// Step 4 of the previous iteration when `advect` (semi-Lagrangian transport of the load,
    /// into `s_next`, then swapped) and step 2a (the outflow fluxes, Mei et al. eq. 2-5, in
    /// place: each cell's fluxes depend on its own fluxes and on the water surfaces, which this
    /// pass does not change); returns the advected load (m summed over the cells).
    fn flow_transport(&mut self, c: &Consts, advect: bool) -> f64 {
        let w = c.width;
        let band = BAND_ROWS * w;
        let (b, d, s, u, v) = (&self.b, &self.d, &self.s, &self.u, &self.v);
        let (mask, runs) = (&self.mask, &self.runs);
        let [fw, fe, fnn, fs] = &mut self.f;
        let sums: Vec<f64> = (
            fw.par_chunks_mut(band),
            fe.par_chunks_mut(band),
            fnn.par_chunks_mut(band),
            fs.par_chunks_mut(band),
            self.s_next.par_chunks_mut(band),
        )
            .into_par_iter()
            .enumerate()
            .map(|(k, (fw, fe, fnn, fs, sn))| {
                let mut load = 0.0f64;
                let mut at = Positions::default();
                for (r, y) in (k * BAND_ROWS..).take(sn.len() / w).enumerate() {
                    let (row, cols) = (y * w, r * w..(r + 1) * w);
                    let mut f = [
                        &mut fw[cols.clone()],
                        &mut fe[cols.clone()],
                        &mut fnn[cols.clone()],
                        &mut fs[cols.clone()],
                    ];
                    let m = &mask[row..row + w];
                    let mut x = 0;
                    for &(start, end) in &runs[y] {
                        for x in x..start {
                            if m[x] & VALID == 0 {
                                continue;
                            }
                            let old = [f[0][x], f[1][x], f[2][x], f[3][x]];
                            let new = flux_cell(c, b, d, m[x], x, y, row + x, old);
                            for (f, new) in f.iter_mut().zip(new) {
                                f[x] = new;
                            }
                        }
                        if start < end {
                            flux_run(c, b, d, row, start, end, &mut f);
                        }
                        x = end;
                    }
                    if advect {
                        let sn = &mut sn[cols];
                        let (u, v) = (&u[row..row + w], &v[row..row + w]);
                        advect_row(c, s, y, m, u, v, sn, &mut at);
                        // In the order of the cells (voids, never written, hold 0).
                        for &v in sn.iter() {
                            load += v as f64;
                        }
                    }
                }
                load
            })
            .collect();
        if advect {
            std::mem::swap(&mut self.s, &mut self.s_next);
        }
        sums.iter().sum()
    }

    /// Steps 2b, 3 and 5 (and the rain of iteration `next`): water depth, velocity, erosion and
    /// deposition, evaporation (which transport does not depend on, so it can come before it);
    /// returns the load after the step, the load carried off the map and the rain (m summed
    /// over the cells).
    fn erode(&mut self, z0: &[f32], c: &Consts, next: Option<u32>) -> (f64, f64, f64) {
        let w = c.width;
        let band = BAND_ROWS * w;
        let (b, f, scale, mask, runs) = (&self.b, &self.f, self.scale, &self.mask, &self.runs);
        let hardening = c.inv_hardness > 0.0;
        let sums: Vec<[f64; 3]> = (
            self.b_next.par_chunks_mut(band),
            self.d.par_chunks_mut(band),
            self.s.par_chunks_mut(band),
            self.u.par_chunks_mut(band),
            self.v.par_chunks_mut(band),
        )
            .into_par_iter()
            .enumerate()
            .map(|(k, (bn, d, s, u, v))| {
                let (mut load, mut left, mut rain) = (0.0f64, 0.0f64, 0.0f64);
                let mut wet = vec![0.0f32; w];
                for (r, y) in (k * BAND_ROWS..).take(bn.len() / w).enumerate() {
                    let (row, cols) = (y * w, r * w..(r + 1) * w);
                    let m = &mask[row..row + w];
                    for (x, wet) in wet.iter_mut().enumerate() {
                        *wet = match next {
                            Some(it) if m[x] & VALID != 0 => c.rain_at(row + x, it),
                            _ => 0.0,
                        };
                    }
                    let mut out = RowOut {
                        b: &mut bn[cols.clone()],
                        d: &mut d[cols.clone()],
                        s: &mut s[cols.clone()],
                        u: &mut u[cols.clone()],
                        v: &mut v[cols],
                    };
                    let mut x = 0;
                    for &(start, end) in &runs[y] {
                        for x in x..start {
                            if m[x] & VALID == 0 {
                                (out.d[x], out.s[x], out.u[x], out.v[x]) = (0.0, 0.0, 0.0, 0.0);
                                continue;
                            }
                            let i = row + x;
                            let nb = c.neighbours(x, y, i);
                            let z0 = if hardening { z0[i] } else { 0.0 };
                            let s0 = out.s[x] * scale;
                            let cell = erode_cell(c, b, f, z0, m[x], i, nb, out.d[x], s0);
                            out.b[x] = cell.b;
                            out.d[x] = cell.d * c.keep + wet[x];
                            out.s[x] = cell.s;
                            [out.u[x], out.v[x]] = cell.uv;
                            left += cell.left as f64;
                        }
                        if start < end {
                            let args = (c, &b[..], f, z0, row, start, end, scale, &wet[..]);
                            if hardening {
                                erode_run::<true>(args, &mut out);
                            } else {
                                erode_run::<false>(args, &mut out);
                            }
                        }
                        x = end;
                    }
                    // In the order of the cells (voids add 0).
                    for (&s, &r) in out.s.iter().zip(&wet) {
                        load += s as f64;
                        rain += r as f64;
                    }
                }
                [load, left, rain]
            })
            .collect();
        std::mem::swap(&mut self.b, &mut self.b_next);
        self.scale = 1.0;
        let t = sums
            .iter()
            .fold([0.0; 3], |a, s| [a[0] + s[0], a[1] + s[1], a[2] + s[2]]);
        (t[0], t[1], t[2])
    }

    /// The suspended load (m summed over the cells).
    fn load(&self) -> f64 {
        self.s.iter().map(|&v| v as f64).sum::<f64>() * self.scale as f64
    }

    /// Lays the suspended load down where it is; returns it (m summed over the cells).
    fn settle(&mut self) -> f64 {
        let load = self.load();
        let scale = self.scale;
        for (b, s) in self.b.iter_mut().zip(&mut self.s) {
            if !b.is_nan() {
                *b += *s * scale;
            }
            *s = 0.0;
        }
        load
    }
}

mod kernels;
use kernels::*;

#[cfg(test)]
mod tests;
