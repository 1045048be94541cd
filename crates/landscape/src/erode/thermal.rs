//! Thermal erosion: talus-angle relaxation (Musgrave, Kolb and Mace 1989, section 4; Olsen
//! 2004, section 3.1). Wherever the drop from a cell to one of its eight neighbours exceeds
//! what the talus angle allows over their centre distance (`tan(talus) * distance`, so
//! non-square cells are honoured), material slides down to the lower neighbours, shared in
//! proportion to each one's excess.
//!
//! Each iteration is a Jacobi step: every transfer is computed from the heights of the previous
//! iteration, one cell at a time in a fixed order, so the result is bit for bit the same on any
//! number of threads. A plain Jacobi version of Musgrave's rule (each cell sends `rate` times
//! its largest excess) overshoots where many cells pour into one (a one-cell pit fed by its
//! eight neighbours rises by eight times what each sent); here the transfer between a higher
//! cell `i` and a lower cell `k` is
//!
//! `t_ik = rate * e_ik * min(max_out_i / sum_out_i, max_in_k / sum_in_k)`
//!
//! with `e_ik` the pair's excess height and `sum_out`/`max_out` (`sum_in`/`max_in`) the sum and
//! largest of the excesses a cell has towards its lower (from its higher) neighbours: no cell
//! gives more than `rate` times its largest outgoing excess (Musgrave's rule) nor receives more
//! than `rate` times its largest incoming one. The same `t_ik` is computed from both cells' side
//! with the same operands, so the material a cell loses is exactly what its neighbours gain
//! (mass is conserved up to `f32` rounding of the heights).
//!
//! Voids (`NaN`) are left untouched and take no material; nothing leaves the map.

use rayon::prelude::*;
use relief_heightfield::param::{ensure, in_left_open, in_range};
use relief_heightfield::{ParamError, Progress};
use serde::{Deserialize, Serialize};

use crate::LandscapeError;
use crate::grid::{Grid, OPPOSITE};

/// Rows per parallel work item (a fixed decomposition: results do not depend on it).
const BAND_ROWS: usize = 16;

/// Settings of [`thermal`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ThermalParams {
    /// Angle of repose (degrees) of the loose material: about 30-40 for scree and talus,
    /// 25-30 for sand, under 20 for wet soil. Slopes steeper than this shed material.
    pub talus_angle_deg: f64,
    /// Number of relaxation steps. A cliff of height `H` on cells of size `l` spreads over about
    /// `H / (l tan(talus))` cells and needs a few times that squared to settle fully.
    pub iterations: u32,
    /// Fraction of the excess moved per iteration, in `(0, 0.5]`: 0.5 is the fastest stable
    /// value, smaller values relax more gently (and need more iterations).
    pub rate: f64,
    /// Depth of bedrock (m) each cell can weather into loose material over the run; `None`:
    /// the whole surface is loose (Musgrave's model, which levels cliffs to the talus angle).
    /// With a depth, a cliff gives at most that much and keeps its face, while what it sheds
    /// (loose from then on) slides on and builds talus aprons at the angle of repose.
    pub weathering_m: Option<f64>,
}

impl Default for ThermalParams {
    fn default() -> Self {
        Self {
            talus_angle_deg: 35.0,
            iterations: 50,
            rate: 0.5,
            weathering_m: None,
        }
    }
}

impl ThermalParams {
    /// Checks every field (names the first one out of range).
    pub fn check(&self) -> Result<(), ParamError> {
        in_range(
            "talus_angle_deg",
            self.talus_angle_deg,
            0.1..=89.0,
            "must be in [0.1, 89] degrees",
        )?;
        check_iterations(self.iterations)?;
        in_left_open("rate", self.rate, (0.0, 0.5), "must be in (0, 0.5]")?;
        if let Some(w) = self.weathering_m {
            in_range("weathering_m", w, 0.0..=1e4, "must be in [0, 10000] m")?;
        }
        Ok(())
    }
}

/// What a [`thermal`] run did.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ThermalFigures {
    /// Iterations run (fewer than asked when the slopes settled earlier).
    pub iterations: u32,
    /// Volume of material that ended lower than it started (m^3): the net volume moved.
    pub moved_m3: f64,
    /// Largest lowering of a cell (m).
    pub max_lowering_m: f64,
    /// Largest raising of a cell (m).
    pub max_raising_m: f64,
    /// Cells steeper than the talus angle (by more than 0.5 degree) towards a neighbour, before.
    pub steep_cells_before: usize,
    /// The same count after the run.
    pub steep_cells_after: usize,
}

/// Relaxes every slope of `z` (row-major on `grid`, voids `NaN`) steeper than the talus angle
/// for `p.iterations` Jacobi steps. `z` is changed only on success: when `stop()` returns true
/// (checked once per iteration) the run ends with [`LandscapeError::Stopped`] and `z` as given.
pub fn thermal(
    z: &mut [f32],
    grid: &Grid,
    p: &ThermalParams,
    progress: &dyn Progress,
    stop: &dyn Fn() -> bool,
) -> Result<ThermalFigures, LandscapeError> {
    p.check()?;
    check_input(z, grid)?;
    let tan = p.talus_angle_deg.to_radians().tan();
    let talus: [f32; 8] = grid.distances().map(|d| (tan * d) as f32);
    let rate = p.rate as f32;
    let steep_talus: [f32; 8] = {
        let t = (p.talus_angle_deg + 0.5).min(89.9).to_radians().tan();
        grid.distances().map(|d| (t * d) as f32)
    };
    let steep_cells_before = count_steep(z, grid, &steep_talus);

    let n = grid.len();
    let mut cur = z.to_vec();
    let mut next = vec![0.0f32; n];
    // Per cell: max_out / sum_out and max_in / sum_in of the current heights.
    let mut share_out = vec![0.0f32; n];
    let mut share_in = vec![0.0f32; n];
    let band = BAND_ROWS * grid.width;
    let mut loose: Option<Vec<f32>> = p.weathering_m.map(|w| vec![w as f32; n]);
    let mut scale = if loose.is_some() {
        vec![1.0f32; n]
    } else {
        Vec::new()
    };
    progress.begin("thermal erosion", p.iterations as u64);
    let mut done = 0;
    for it in 0..p.iterations {
        check_stop(stop, "thermal erosion", it, p.iterations)?;
        (
            share_out.par_chunks_mut(band),
            share_in.par_chunks_mut(band),
        )
            .into_par_iter()
            .enumerate()
            .for_each(|(b, (so, si))| {
                for_cells(grid, b, so.len(), |j, at| {
                    (so[j], si[j]) = shares(&cur, grid, at, &talus);
                });
            });
        if let Some(loose) = loose.as_mut() {
            // Each cell gives at most its loose material: the pair transfers out of a cell are
            // scaled by `min(1, loose / loss)` (the giver's factor, seen alike from both cells).
            scale.par_chunks_mut(band).enumerate().for_each(|(b, out)| {
                for_cells(grid, b, out.len(), |j, at| {
                    let i = at.2;
                    let loss =
                        relax::<false>(&cur, grid, at, &talus, rate, &share_out, &share_in, None).1;
                    out[j] = if loss > loose[i] {
                        loose[i] / loss
                    } else {
                        1.0
                    };
                });
            });
            let sc = &scale;
            (next.par_chunks_mut(band), loose.par_chunks_mut(band))
                .into_par_iter()
                .enumerate()
                .for_each(|(b, (out, lo))| {
                    for_cells(grid, b, out.len(), |j, at| {
                        let (zi, loss, gain) = relax::<true>(
                            &cur,
                            grid,
                            at,
                            &talus,
                            rate,
                            &share_out,
                            &share_in,
                            Some(sc),
                        );
                        out[j] = zi;
                        lo[j] = (lo[j] - loss + gain).max(0.0);
                    });
                });
        } else {
            next.par_chunks_mut(band).enumerate().for_each(|(b, out)| {
                for_cells(grid, b, out.len(), |j, at| {
                    out[j] =
                        relax::<true>(&cur, grid, at, &talus, rate, &share_out, &share_in, None).0;
                });
            });
        }
        // Settled (no cell changed): the remaining iterations would change nothing either.
        let settled = next
            .par_chunks(band)
            .zip(cur.par_chunks(band))
            .all(|(a, b)| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
        std::mem::swap(&mut cur, &mut next);
        progress.advance(1);
        done += 1;
        if settled {
            progress.advance((p.iterations - it - 1) as u64);
            break;
        }
    }

    let mut figures = ThermalFigures {
        iterations: done,
        steep_cells_before,
        steep_cells_after: count_steep(&cur, grid, &steep_talus),
        ..Default::default()
    };
    let area = grid.cell_area();
    for (a, b) in z.iter().zip(&cur) {
        if a.is_nan() {
            continue;
        }
        let dz = (*b - *a) as f64;
        if dz < 0.0 {
            figures.moved_m3 -= dz * area;
            figures.max_lowering_m = figures.max_lowering_m.max(-dz);
        } else {
            figures.max_raising_m = figures.max_raising_m.max(dz);
        }
    }
    z.copy_from_slice(&cur);
    Ok(figures)
}

/// Iterations of a hydraulic or thermal run: at most a million.
pub(crate) fn check_iterations(iterations: u32) -> Result<(), ParamError> {
    in_range(
        "iterations",
        iterations,
        ..=1_000_000,
        "must be at most 1000000",
    )
}

/// [`LandscapeError::Stopped`] naming `what` and the `it` of `of` iterations done when `stop()`
/// returns true (checked before every iteration of the hydraulic and thermal runs).
pub(crate) fn check_stop(
    stop: &dyn Fn() -> bool,
    what: &str,
    it: u32,
    of: u32,
) -> Result<(), LandscapeError> {
    if stop() {
        Err(LandscapeError::Stopped(format!(
            "{what} after {it} of {of} iterations"
        )))
    } else {
        Ok(())
    }
}

/// The size check every erosion routine shares: `z` holds one value per cell, cell sizes are
/// positive, and at least one cell is valid.
pub(crate) fn check_input(z: &[f32], grid: &Grid) -> Result<(), LandscapeError> {
    if z.len() != grid.len() {
        return Err(LandscapeError::InvalidInput(format!(
            "the raster has {} values for a {}x{} grid",
            z.len(),
            grid.width,
            grid.height
        )));
    }
    for (name, v) in [("cell_x", grid.cell_x), ("cell_y", grid.cell_y)] {
        ensure(
            v.is_finite() && v > 0.0,
            name,
            v,
            "must be a positive cell size",
        )?;
    }
    if z.iter().all(|v| v.is_nan()) {
        return Err(LandscapeError::InvalidInput(
            "the raster has no valid cell".into(),
        ));
    }
    Ok(())
}

/// Calls `f(j, (x, y, i))` for the `len` cells of band `b` (of [`BAND_ROWS`] rows) in order:
/// `j` the index in the band, `i` on the map (no division per cell).
#[inline]
fn for_cells(grid: &Grid, b: usize, len: usize, mut f: impl FnMut(usize, (usize, usize, usize))) {
    let w = grid.width;
    let first = b * BAND_ROWS;
    for r in 0..len / w {
        let y = first + r;
        for x in 0..w {
            f(r * w + x, (x, y, y * w + x));
        }
    }
}

/// `(max_out / sum_out, max_in / sum_in)` of cell `i`: the largest over the sum of its excesses
/// towards its lower neighbours and from its higher ones (0 without any).
#[inline]
fn shares(
    z: &[f32],
    grid: &Grid,
    (x, y, i): (usize, usize, usize),
    talus: &[f32; 8],
) -> (f32, f32) {
    let zi = z[i];
    if zi.is_nan() {
        return (0.0, 0.0);
    }
    let (mut max_out, mut sum_out, mut max_in, mut sum_in) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    grid.for_neighbours_at(x, y, i, |k, m| {
        let zm = z[m];
        // NaN neighbours fail both comparisons.
        let e_out = zi - zm - talus[k];
        if e_out > 0.0 {
            max_out = max_out.max(e_out);
            sum_out += e_out;
        }
        let e_in = zm - zi - talus[k];
        if e_in > 0.0 {
            max_in = max_in.max(e_in);
            sum_in += e_in;
        }
    });
    let ratio = |m: f32, s: f32| if s > 0.0 { m / s } else { 0.0 };
    (ratio(max_out, sum_out), ratio(max_in, sum_in))
}

/// The height of cell `i` after one relaxation step, with what it lost and gained. With
/// `scale` (the givers' loose-material factors) each transfer is scaled by its giver's.
/// Without `GAIN` only the loss is computed (the gain is 0), with the same operations in the
/// same order.
#[inline]
#[allow(clippy::too_many_arguments)]
fn relax<const GAIN: bool>(
    z: &[f32],
    grid: &Grid,
    (x, y, i): (usize, usize, usize),
    talus: &[f32; 8],
    rate: f32,
    share_out: &[f32],
    share_in: &[f32],
    scale: Option<&[f32]>,
) -> (f32, f32, f32) {
    let zi = z[i];
    // A cell with no excess towards or from any neighbour neither gives nor takes (most cells:
    // slopes under the angle of repose).
    if zi.is_nan() || (share_out[i] == 0.0 && (!GAIN || share_in[i] == 0.0)) {
        return (zi, 0.0, 0.0);
    }
    let factor = |c: usize| scale.map_or(1.0, |s| s[c]);
    let mut gain = 0.0f32;
    let mut loss = 0.0f32;
    grid.for_neighbours_at(x, y, i, |k, m| {
        let zm = z[m];
        // The transfer of a pair is computed with the same operands from both sides (the
        // higher cell's excess, the higher cell's outgoing share, the lower one's incoming
        // share, the higher cell's factor): `talus[k] == talus[OPPOSITE[k]]`.
        debug_assert_eq!(talus[k], talus[OPPOSITE[k] as usize]);
        let e_out = zi - zm - talus[k];
        if e_out > 0.0 {
            loss += rate * e_out * share_out[i].min(share_in[m]) * factor(i);
        }
        let e_in = zm - zi - talus[k];
        if GAIN && e_in > 0.0 {
            gain += rate * e_in * share_out[m].min(share_in[i]) * factor(m);
        }
    });
    (zi - loss + gain, loss, gain)
}

/// Cells with a neighbour lower by more than `limit[k]`.
fn count_steep(z: &[f32], grid: &Grid, limit: &[f32; 8]) -> usize {
    (0..grid.len())
        .into_par_iter()
        .filter(|&i| {
            let mut steep = false;
            grid.for_neighbours(i, |k, m| steep |= z[i] - z[m] > limit[k]);
            steep
        })
        .count()
}

#[cfg(test)]
mod tests;
