//! Stream-power incision with uplift and hillslope diffusion,
//! `dz/dt = U - K A^m S^n + D lap z`, one time step as fastscapelib 0.3 computes it
//! (<https://github.com/fastscape-lem/fastscapelib>, the loop of its "Mountain" example):
//!
//! 1. uplift: `z += U dt` on every free cell (not on base levels);
//! 2. routing on the uplifted surface: D8 steepest descent (fastscapelib's `SingleFlowRouter`);
//!    when the surface has pits, closed depressions are routed across to their spill points by
//!    a priority flood (see below);
//! 3. drainage area `A` (m^2): the cells draining through each cell times
//!    [`Grid::cell_area`] (`FlowGraph::accumulate(1.0)`);
//! 4. channel incision by the implicit scheme of Braun and Willett (2013, "A very efficient
//!    O(n), implicit and parallel method to solve the stream power equation governing fluvial
//!    incision and landscape evolution", Geomorphology 180-181, eq. 21-22), receivers before
//!    donors: for `n = 1`, `z_i' = (z_i + F z_r') / (1 + F)` with `F = K dt A^m / d`; for
//!    `n != 1`, Newton iterations on the drop `delta` to the receiver,
//!    `delta + F delta^n = z_i - z_r'` with `F = K dt A^m / d^n` (fastscapelib's `SPLEroder`);
//! 5. hillslope diffusion by the implicit ADI scheme of [`crate::erode::diffusion`].
//!
//! **Lakes** (as fastscapelib's `SPLEroder` does): a cell not above its receiver's new
//! elevation is not eroded; a cell whose receiver is higher (a cell at the bottom of a lake,
//! draining across it to the spill point) is not eroded; erosion never takes a cell below its
//! receiver's new elevation (it is stopped one `f64::MIN_POSITIVE` above, counted as
//! [`StepFigures::limited`]), so incision creates no new depression.
//!
//! **Difference with fastscapelib on surfaces with pits.** fastscapelib's default
//! `MSTSinkResolver` (Cordonnier et al. 2019, Kruskal, "carve") keeps every cell's D8 receiver
//! and reverses the path from each pit to its pass; here every cell below its lake's spill
//! level drains to the neighbour the priority flood reached it from, which leads across the
//! lake to the spill point. On a pit-free surface both are plain D8 and the step matches
//! fastscapelib to rounding (tested against its output on a non-square raster); where there
//! are lakes, the water crosses each lake along a different path (the drainage area of the
//! spill point and everything downstream are the same; lake floors erode differently).
//!
//! **Difference for `n < 1`.** fastscapelib 0.3 takes the linear path whenever
//! `|n| - 1 <= epsilon`, i.e. for every `n < 1` too; here `n < 1` is solved (bracketed
//! Newton iterations), so results differ from fastscapelib for `n < 1` only.
//!
//! **Boundaries.** Base levels (`base_level[i]`, by default the outer edge: [`base_level_mask`])
//! keep their elevation (fastscapelib's fixed-value nodes). Voids (`NaN`) are never changed,
//! receive no flow and no diffusive flux; cells beside voids are base levels in the default
//! mask (a cell beside a void drains off the map, the crate's convention).
//!
//! **Determinism and speed.** Routing of each cell, the ADI lines and the uplift are computed
//! in parallel with rayon, each value by one thread; the stack, the drainage area and the
//! incision run sequentially in stack order, so the bytes do not depend on the thread count.
//! [`StreamPowerScratch`] keeps every buffer between steps.
//!
//! ```
//! use relief_heightfield::NoProgress;
//! use relief_landscape::erode::{self, StreamPowerParams, Uplift};
//! use relief_landscape::grid::Grid;
//! // A 32 x 24 block rising at 1 mm/yr for 20 kyr: valleys cut down to the fixed edge.
//! let grid = Grid { width: 32, height: 24, cell_x: 100.0, cell_y: 100.0 };
//! let mut z: Vec<f64> = (0..grid.len()).map(|i| ((i * 7919) % 13) as f64 * 0.01).collect();
//! let base = erode::base_level_mask(&z, &grid);
//! let params = StreamPowerParams { dt: 1e3, ..Default::default() };
//! let figures = erode::run(&mut z, &grid, &base, &params, Uplift::Constant(1e-3), 20,
//!     &NoProgress, &|| false).unwrap();
//! assert_eq!(figures.steps, 20);
//! // Incision keeps every cell below the 20 m of uplift; the fixed edge does not move.
//! assert!(z.iter().all(|v| *v < 20.2) && figures.last.mean_elevation < 20.0);
//! assert_eq!(z[0], 0.0);
//! ```

mod routing;

use rayon::prelude::*;
use relief_heightfield::Progress;
use relief_heightfield::param::{ParamError, ensure, in_range};
use serde::{Deserialize, Serialize};

use crate::erode::diffusion::{self, DiffusionScratch, FREE};
use crate::grid::{Grid, NO_FLOW};
use crate::{LandscapeError, Result};

/// Parameters of [`step`] and [`run`].
///
/// The defaults are those of a rapidly uplifting mountain range with 100 m cells: `m = 0.45`,
/// `n = 1` (the reference concavity `m/n = 0.45` of Wobus et al. 2006 and Kirby and Whipple
/// 2012, inside the 0.35-0.6 of most steady-state channels), `K = 2e-5 m^0.1/yr` (Stock and
/// Montgomery 1999 report 1e-6..1e-4 for `m = 0.5`; with `U = 1 mm/yr` it gives steady-state
/// slopes of 0.1 at 1 km^2 and 0.013 at 100 km^2), `D = 0.01 m^2/yr` (soil-mantled hillslopes:
/// Fernandes and Dietrich 1997, Roering et al. 1999 and Hurst et al. 2012 find 0.002-0.02),
/// `dt = 1000 yr`, and fastscapelib's Newton tolerance `1e-5 m`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct StreamPowerParams {
    /// Erodibility `K` (m^(1-2m)/yr, with the drainage area in m^2).
    pub k: f64,
    /// Drainage-area exponent `m`.
    pub m: f64,
    /// Slope exponent `n` (1: the linear, direct solve; otherwise Newton iterations).
    pub n: f64,
    /// Hillslope diffusivity `D` (m^2/yr; 0 turns diffusion off).
    pub diffusion: f64,
    /// Time step (yr). Both solvers are implicit and stable for any step.
    pub dt: f64,
    /// Convergence of the Newton iterations for `n != 1` (m): the residual of the drop to the
    /// receiver.
    pub tolerance: f64,
    /// Channel-head drainage area (m^2): cells draining less do not incise (0: every cell
    /// does). The stream-power law describes bedrock and alluvial channels; above the channel
    /// heads, hillslopes and colluvial hollows are shaped by diffusion and debris flows
    /// (Montgomery and Dietrich 1988; Stock and Dietrich 2003 find the fluvial power law from
    /// about 1 km^2 in steep terrain).
    pub channel_area_m2: f64,
}

impl Default for StreamPowerParams {
    fn default() -> Self {
        Self {
            k: 2e-5,
            m: 0.45,
            n: 1.0,
            diffusion: 0.01,
            dt: 1e3,
            tolerance: 1e-5,
            channel_area_m2: 0.0,
        }
    }
}

impl StreamPowerParams {
    /// The parameters of fastscapelib's Mountain example (K 2e-4, m 0.4, n 1, D 0.01, dt
    /// 1 kyr; its uplift is 1 mm/yr): the setup the speed comparisons with fastscapelib run.
    pub fn fastscape_mountain() -> Self {
        Self {
            k: 2e-4,
            m: 0.4,
            n: 1.0,
            diffusion: 0.01,
            dt: 1e3,
            ..Self::default()
        }
    }

    /// Checks every field, naming the first one out of range.
    pub fn check(&self) -> std::result::Result<(), ParamError> {
        in_range(
            "k",
            self.k,
            0.0..1e3,
            "must be >= 0 and finite (m^(1-2m)/yr)",
        )?;
        in_range("m", self.m, 0.0..=3.0, "must be in [0, 3]")?;
        in_range("n", self.n, 0.1..=4.0, "must be in [0.1, 4]")?;
        in_range(
            "diffusion",
            self.diffusion,
            0.0..1e9,
            "must be >= 0 and finite (m2/yr)",
        )?;
        ensure(
            self.dt > 0.0 && self.dt < 1e9,
            "dt",
            self.dt,
            "must be in (0, 1e9) yr",
        )?;
        ensure(
            self.tolerance > 0.0 && self.tolerance < 1e3,
            "tolerance",
            self.tolerance,
            "must be in (0, 1e3) m",
        )?;
        in_range(
            "channel_area_m2",
            self.channel_area_m2,
            0.0..1e15,
            "must be >= 0 and finite (m2)",
        )
    }

    /// True when the slope exponent takes fastscapelib's linear path (`|n - 1| <= epsilon`).
    fn linear(&self) -> bool {
        (self.n - 1.0).abs() <= f64::EPSILON
    }
}

/// Rock uplift rate (m/yr), applied to every cell except base levels and voids.
#[derive(Debug, Clone, Copy)]
pub enum Uplift<'a> {
    /// The same rate everywhere.
    Constant(f64),
    /// One rate per cell (the grid's length; ignored on base levels).
    Raster(&'a [f64]),
}

/// Figures of one [`step`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StepFigures {
    /// Free cells without a lower neighbour on the uplifted surface (closed depressions).
    pub pits: usize,
    /// Free cells below their depression's spill level, routed across their lake.
    pub lake_cells: usize,
    /// Cells whose incision was stopped just above their receiver (fastscapelib's `n_corr`).
    pub limited: usize,
    /// Largest channel incision of the step (m).
    pub max_incision: f64,
    /// Mean elevation of the valid cells after the step (m).
    pub mean_elevation: f64,
}

/// Figures of a [`run`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct RunFigures {
    /// Steps done (fewer than asked when stopped).
    pub steps: usize,
    /// True when `stop` ended the run early (the surface is the one after `steps` steps).
    pub stopped: bool,
    /// Sum over the steps of [`StepFigures::pits`].
    pub pits: usize,
    /// Sum over the steps of [`StepFigures::limited`].
    pub limited: usize,
    /// Figures of the last step.
    pub last: StepFigures,
}

/// The default base levels: the outer edge, the voids and the cells beside a void.
pub fn base_level_mask(z: &[f64], grid: &Grid) -> Vec<bool> {
    (0..grid.len())
        .map(|i| z[i].is_nan() || crate::depression::is_outlet(z, grid, i))
        .collect()
}

/// Buffers of a stream-power step, kept between steps (no allocation after the first step).
#[derive(Debug, Default, Clone)]
pub struct StreamPowerScratch {
    kind: Vec<u8>,
    dir: Vec<u8>,
    donors: Vec<u8>,
    stack: Vec<u32>,
    count: Vec<u32>,
    erosion: Vec<f64>,
    /// `(k dt) A^m` for small drainage areas, and the `(cell area, m, k dt)` it was built for.
    area_pow: Vec<f64>,
    area_pow_key: (f64, f64, f64),
    lakes: routing::LakeScratch,
    diffusion: DiffusionScratch,
}

/// Contributing-cell counts below which `(k dt) A^m` comes from a table.
const POW_TABLE: usize = 4096;

impl StreamPowerScratch {
    /// Empty buffers, sized on first use.
    pub fn new() -> Self {
        Self::default()
    }

    /// One time step on `z` in place (see [`step`]).
    pub fn step(
        &mut self,
        z: &mut [f64],
        grid: &Grid,
        base_level: &[bool],
        params: &StreamPowerParams,
        uplift: Uplift<'_>,
    ) -> Result<StepFigures> {
        params.check()?;
        check_inputs(z, grid, base_level, uplift)?;
        Ok(self.step_checked(z, grid, base_level, params, uplift))
    }

    fn step_checked(
        &mut self,
        z: &mut [f64],
        grid: &Grid,
        base_level: &[bool],
        p: &StreamPowerParams,
        uplift: Uplift<'_>,
    ) -> StepFigures {
        let n = grid.len();
        self.kind.resize(n, FREE);
        diffusion::node_kinds(z, base_level, &mut self.kind);
        let kind = &self.kind;
        let dt = p.dt;
        match uplift {
            Uplift::Constant(u) => z.par_iter_mut().zip(kind.par_iter()).for_each(|(v, &k)| {
                if k == FREE {
                    *v += dt * u;
                }
            }),
            Uplift::Raster(u) => z
                .par_iter_mut()
                .zip(kind.par_iter().zip(u.par_iter()))
                .for_each(|(v, (&k, &u))| {
                    if k == FREE {
                        *v += dt * u;
                    }
                }),
        }
        let mut figures = StepFigures::default();
        self.dir.resize(n, NO_FLOW);
        figures.pits = routing::receivers(z, grid, kind, &mut self.dir);
        if figures.pits > 0 {
            figures.lake_cells = routing::route_lakes(
                z,
                grid,
                kind,
                &mut self.dir,
                &mut self.stack,
                &mut self.donors,
                &mut self.lakes,
            );
        }
        routing::stack_order(grid, kind, &self.dir, &mut self.donors, &mut self.stack);
        self.count.resize(n, 0);
        routing::contributing_cells(grid, &self.dir, &self.stack, &mut self.count);
        self.fill_pow_table(grid, p);
        self.erosion.resize(n, 0.0);
        let (limited, max_incision) = self.incise(z, grid, p);
        figures.limited = limited;
        figures.max_incision = max_incision;
        z.par_iter_mut()
            .zip(self.erosion.par_iter())
            .for_each(|(v, e)| *v -= e);
        diffusion::adi(z, grid, &self.kind, p.diffusion, dt, &mut self.diffusion);
        let (sum, valid) = z
            .iter()
            .filter(|v| !v.is_nan())
            .fold((0.0, 0usize), |(s, c), v| (s + v, c + 1));
        figures.mean_elevation = sum / valid.max(1) as f64;
        figures
    }

    /// The table of `(k dt) (count * cell area)^m` for counts below [`POW_TABLE`]: the same
    /// operations as the direct computation, so the table changes speed, not values.
    fn fill_pow_table(&mut self, grid: &Grid, p: &StreamPowerParams) {
        let key = (grid.cell_area(), p.m, p.k * p.dt);
        if self.area_pow.len() == POW_TABLE && self.area_pow_key == key {
            return;
        }
        self.area_pow_key = key;
        self.area_pow.clear();
        self.area_pow
            .extend((0..POW_TABLE).map(|c| key.2 * (c as f64 * key.0).powf(key.1)));
    }

    /// Channel incision in stack order (receivers first) into `self.erosion`; returns the
    /// number of limited cells and the largest incision.
    fn incise(&mut self, z: &[f64], grid: &Grid, p: &StreamPowerParams) -> (usize, f64) {
        let w = grid.width;
        let dist = grid.distances();
        let dist_n = dist.map(|d| d.powf(p.n));
        let linear = p.linear();
        let (area0, kdt) = (grid.cell_area(), p.k * p.dt);
        let (e, dir, count, table) = (&mut self.erosion, &self.dir, &self.count, &self.area_pow);
        e.fill(0.0);
        let (mut limited, mut max_incision) = (0usize, 0.0f64);
        for &i in &self.stack {
            let i = i as usize;
            let d = dir[i];
            if d == NO_FLOW {
                continue;
            }
            let r = routing::target(w, i, d);
            let zi = z[i];
            let zr = z[r];
            let flooded = zr - e[r];
            if zi <= flooded {
                continue;
            }
            let mut new = zi;
            let c = count[i] as usize;
            if (c as f64) * area0 < p.channel_area_m2 {
                // Above the channel head: no incision (the cell still drains to its receiver).
                continue;
            }
            if zr <= zi {
                let kda = match table.get(c) {
                    Some(&v) => v,
                    None => kdt * (c as f64 * area0).powf(p.m),
                };
                if linear {
                    let f = kda / dist[d as usize];
                    new = (zi + f * flooded) / (1.0 + f);
                } else {
                    let f = kda / dist_n[d as usize];
                    new = zi - (zi - flooded - newton_drop(f, p.n, zi - flooded, p.tolerance));
                }
            }
            if new < flooded {
                limited += 1;
                new = flooded + f64::MIN_POSITIVE;
            }
            e[i] = zi - new;
            max_incision = max_incision.max(e[i]);
        }
        (limited, max_incision)
    }
}

/// The drop `delta` to the receiver after the step, solving `delta + f delta^n = delta0`
/// (fastscapelib's Newton iterations from `delta0`, stopping at a residual `<= tol`; for
/// `n > 1` the iterates decrease monotonically to the root). For `n < 1` (where plain Newton
/// can overshoot below 0) a step leaving the bracket `(lo, hi)` around the root is replaced by
/// bisection, and the iterations stop at `|residual| <= tol`.
pub(crate) fn newton_drop(f: f64, n: f64, delta0: f64, tol: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, delta0);
    let mut delta = delta0;
    for _ in 0..200 {
        let fde = f * delta.powf(n);
        let func = delta + fde - delta0;
        if func <= tol && (n >= 1.0 || func >= -tol) {
            break;
        }
        if func > 0.0 {
            hi = delta;
        } else {
            lo = delta;
        }
        let next = delta - func / (1.0 + n * fde / delta);
        if n >= 1.0 {
            if next <= 0.0 {
                return next;
            }
            delta = next;
        } else if next > lo && next < hi {
            delta = next;
        } else {
            delta = 0.5 * (lo + hi);
        }
    }
    delta
}

fn check_inputs(z: &[f64], grid: &Grid, base_level: &[bool], uplift: Uplift<'_>) -> Result<()> {
    let n = grid.len();
    let bad = |what: &str, len: usize| {
        Err(LandscapeError::InvalidInput(format!(
            "{what} has {len} cells, the {}x{} grid {n}",
            grid.width, grid.height
        )))
    };
    if z.len() != n {
        return bad("the elevation raster", z.len());
    }
    if base_level.len() != n {
        return bad("the base-level mask", base_level.len());
    }
    match uplift {
        Uplift::Constant(u) => in_range("uplift", u, -1e3..1e3, "must be finite (m/yr)")?,
        Uplift::Raster(r) if r.len() != n => return bad("the uplift raster", r.len()),
        Uplift::Raster(r) => {
            if let Some(i) = r.iter().position(|u| !u.is_finite()) {
                return Err(ParamError::new("uplift", r[i], "must be finite (m/yr)").into());
            }
        }
    }
    if !z.iter().zip(base_level).any(|(v, &b)| b && !v.is_nan()) {
        return Err(LandscapeError::InvalidInput(
            "no base level: the mask marks no valid cell".into(),
        ));
    }
    Ok(())
}

/// One time step of stream-power incision with uplift and diffusion on `z` (m, voids `NaN`) in
/// place: uplift, routing, drainage area, the implicit incision in stack order, then diffusion
/// (see the module docs). `base_level[i]` marks the cells of fixed elevation
/// ([`base_level_mask`] by default). Allocates its buffers: a loop of steps should keep one
/// [`StreamPowerScratch`] and call [`StreamPowerScratch::step`], as [`run`] does.
///
/// Errors: invalid parameters, rasters whose length is not the grid's, a non-finite uplift, or a
/// mask with no valid base level.
pub fn step(
    z: &mut [f64],
    grid: &Grid,
    base_level: &[bool],
    params: &StreamPowerParams,
    uplift: Uplift<'_>,
) -> Result<StepFigures> {
    StreamPowerScratch::new().step(z, grid, base_level, params, uplift)
}

/// `steps` time steps of [`step`] on `z` in place, reporting `begin("stream power", steps)`
/// and `advance(1)` per step. `stop` is asked before every step; when it returns true the run
/// ends with [`RunFigures::stopped`] set and `z` the surface after the steps done.
#[allow(clippy::too_many_arguments)]
pub fn run(
    z: &mut [f64],
    grid: &Grid,
    base_level: &[bool],
    params: &StreamPowerParams,
    uplift: Uplift<'_>,
    steps: usize,
    progress: &dyn Progress,
    stop: &dyn Fn() -> bool,
) -> Result<RunFigures> {
    params.check()?;
    check_inputs(z, grid, base_level, uplift)?;
    let mut scratch = StreamPowerScratch::new();
    let mut figures = RunFigures::default();
    progress.begin("stream power", steps as u64);
    for _ in 0..steps {
        if stop() {
            figures.stopped = true;
            break;
        }
        let f = scratch.step_checked(z, grid, base_level, params, uplift);
        figures.steps += 1;
        figures.pits += f.pits;
        figures.limited += f.limited;
        figures.last = f;
        progress.advance(1);
    }
    Ok(figures)
}
