//! The landform pass: drainage-aware finishing of detail added to a coarse terrain.
//!
//! Detail methods (sparse amplification, wavelet refinement, patch quilting) add texture that
//! has the right spectrum but not real terrain's drainage: every bump of the added detail
//! closes a small depression, and the valleys of neighbouring patches or primitives do not
//! connect downhill. [`finish`] turns such a surface into one that drains like real terrain while
//! keeping it consistent with the coarse input it was made from (its box reduction equals the
//! input):
//!
//! 1. **Breach**: every closed depression is drained by the cheapest channel cut through its
//!    rim (Lindsay 2016, [`crate::depression::breach`]): a narrow cut keeps the valley floors and
//!    the mean height of every coarse cell, where filling would drown them under flat lakes.
//! 2. **Incise**: channels are deepened by a few implicit stream-power steps without uplift
//!    (Braun and Willett 2013, [`crate::erode::stream_power`]) with hillslope diffusion, so the
//!    drainage network the detail lacks is carved along the routed flow: small valleys join
//!    bigger ones downhill across patch and primitive boundaries.
//! 3. **Back-project**: the box reduction of the result is brought back to the coarse input by
//!    adding the bicubic up-sampling of the difference (a smooth correction that moves every
//!    coarse cell's mean back without touching the fine relief).
//! 4. Repeat, and end with a breach and an epsilon fill so no closed depression is left
//!    (the back-projection can close a shallow one again). The end's breach cuts are one cell
//!    wide, the scheme's width rather than a landform's (a hillshade shows them as straight
//!    cracks): their sides are cut back to [`LandformSettings::cut_side_slope_deg`], so each
//!    is a small V-shaped valley whose floor is the cut ([`widen_cuts`]).
//!
//! Depressions the coarse input itself holds deeper than
//! [`LandformSettings::keep_depressions_deeper_than_m`] (a crater, a karst basin, a lake bed)
//! are kept: their fine cells are sinks.

use relief_heightfield::Heightfield;
use serde::{Deserialize, Serialize};

use crate::depression::breach::{BreachLimits, breach};
use crate::depression::fill::{FillMode, priority_flood};
use crate::erode::{StreamPowerParams, Uplift, base_level_mask, run as stream_power_run};
use crate::grid::Grid;
use crate::{LandscapeError, Result};

/// Peak working memory of [`finish`] per fine cell (bytes, measured: 262 MB over the output
/// raster for 2048^2 cells), for callers' memory estimates.
pub const WORKING_BYTES_PER_CELL: f64 = 64.0;

/// Settings of [`finish`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LandformSettings {
    /// Breach / back-projection rounds.
    pub rounds: usize,
    /// Closed depressions of the coarse input deeper than this (m) are real landforms and kept.
    pub keep_depressions_deeper_than_m: f64,
    /// Years of channel incision (stream power without uplift), spread over the rounds; 0 turns
    /// incision off.
    pub incision_years: f64,
    /// Stream-power steps per round.
    pub incision_steps: usize,
    /// Standard deviation (m) of the Gaussian that spreads each round's incision across the
    /// valley (0: the stream-power channels as cut, one cell wide).
    pub valley_width_m: f64,
    /// Channel-head drainage area (m^2) of the incision for a x4 step: cells draining less
    /// are left to the breach and the diffusion. Each further octave of added detail divides
    /// it by 4 (x16: 1/16 of it): the coarser the input, the fewer of the hollows and
    /// low-order valleys it holds, so the pass carves them from smaller areas. 1 km^2 is
    /// where Stock and Dietrich (2003) find the fluvial power law to start in steep terrain;
    /// 0 incises every cell. Overrides `stream_power.channel_area_m2`.
    pub channel_head_x4_m2: f64,
    /// Stream-power parameters of the incision (`dt` is set from the years and steps).
    pub stream_power: StreamPowerParams,
    /// Slope (degrees) the sides of the final breach cuts are cut back to: a one-cell gorge
    /// becomes a V-shaped notch, a swale where the cut is shallow. 10 degrees: at 30 and 45
    /// the notches still read as scratches in a hillshade of x16 and x32 refinements, at 10
    /// the box averages still hold within 0.6 % of the relief at x16 (docs/LANDSCAPE.md).
    /// 0 leaves the cuts one cell wide.
    pub cut_side_slope_deg: f64,
}

impl Default for LandformSettings {
    fn default() -> Self {
        Self {
            rounds: 3,
            keep_depressions_deeper_than_m: f64::INFINITY,
            incision_years: 60_000.0,
            incision_steps: 1,
            valley_width_m: 60.0,
            channel_head_x4_m2: 1e6,
            stream_power: StreamPowerParams {
                diffusion: 0.05,
                ..StreamPowerParams::default()
            },
            cut_side_slope_deg: 10.0,
        }
    }
}

/// What [`finish`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct LandformReport {
    /// Closed depressions of the detail before the pass.
    pub pits_before: usize,
    /// Cells lowered by breaching (all rounds).
    pub breached_cells: usize,
    /// Cells raised by the final fill.
    pub filled_cells: usize,
    /// RMS of box-down(output) - input after the pass (m).
    pub consistency_rms_m: f64,
}

fn box_residual(z: &[f64], w: usize, coarse: &Heightfield, f: usize) -> Vec<f64> {
    let (cw, ch) = (coarse.width(), coarse.height());
    let mut r = vec![0.0; cw * ch];
    let inv = 1.0 / (f * f) as f64;
    for cy in 0..ch {
        for cx in 0..cw {
            let mut s = 0.0;
            for y in cy * f..(cy + 1) * f {
                s += z[y * w + cx * f..y * w + (cx + 1) * f].iter().sum::<f64>();
            }
            r[cy * cw + cx] = f64::from(coarse.get(cx, cy)) - s * inv;
        }
    }
    r
}

/// Fixed-point iterations of [`back_project`] per round.
const BACK_PROJECTION_ITERATIONS: usize = 3;

/// Adds to `z` (`w x h`, `f` times `coarse`) the bicubic up-sampling of `coarse` minus the box
/// reduction of `z`.
fn back_project(z: &mut [f64], w: usize, h: usize, coarse: &Heightfield, f: usize) -> Result<()> {
    let r = box_residual(z, w, coarse, f);
    let (cx, cy) = coarse.cell_size();
    let rc = Heightfield::new(
        coarse.width(),
        coarse.height(),
        r.iter().map(|&v| v as f32).collect(),
        cx,
        cy,
    )?;
    let up = rc.resample(w, h)?;
    for (v, u) in z.iter_mut().zip(up.as_slice()) {
        *v += f64::from(*u);
    }
    Ok(())
}

/// Cuts back the sides of the cells `z` lowered below `before` (breach channels) to `slope`
/// (m/m): a channel cell cut `d` deep lowers the ground around it by `d - slope r` at distance
/// `r` (the deepest such notch over the channel cells, found by a two-pass chamfer sweep over
/// the eight neighbours), so a one-cell gorge becomes a V-shaped notch in the surface with the
/// gorge as its floor, as wide as its depth asks and no wider.
fn widen_cuts(z: &mut [f64], before: &[f64], grid: &Grid, slope: f64) {
    if !(slope.is_finite() && slope > 0.0) {
        return;
    }
    let mut notch: Vec<f64> = z
        .iter()
        .zip(before)
        .map(|(&a, &b)| (b - a).max(0.0))
        .collect();
    let cut: Vec<bool> = notch.iter().map(|&d| d > 0.0).collect();
    if !cut.contains(&true) {
        return;
    }
    let (w, h) = (grid.width, grid.height);
    let fall = grid.distances().map(|d| slope * d);
    // D8 directions that come before a cell in row-major order (the forward sweep's).
    let back: Vec<usize> = (0..8)
        .filter(|&k| {
            let (dy, dx) = crate::grid::D8[k];
            dy < 0 || (dy == 0 && dx < 0)
        })
        .collect();
    let fwd: Vec<usize> = (0..8).filter(|k| !back.contains(k)).collect();
    let mut relax = |i: usize, dirs: &[usize]| {
        for &k in dirs {
            if let Some(n) = grid.neighbour(i, k) {
                let v = notch[n] - fall[k];
                if v > notch[i] {
                    notch[i] = v;
                }
            }
        }
    };
    for i in 0..w * h {
        relax(i, &back);
    }
    for i in (0..w * h).rev() {
        relax(i, &fwd);
    }
    for ((v, d), c) in z.iter_mut().zip(&notch).zip(&cut) {
        if !c && *d > 0.0 {
            *v -= d;
        }
    }
}

/// Strict local minima off the edge.
fn pits(z: &[f64], grid: &Grid) -> usize {
    (0..z.len())
        .filter(|&i| !grid.is_edge(i))
        .filter(|&i| {
            let mut lowest = true;
            grid.for_neighbours(i, |_, m| lowest &= z[i] < z[m]);
            lowest
        })
        .count()
}

/// The fine cells (index in a grid `factor` times `coarse`) under the closed depressions of
/// `coarse` deeper than `depth` m.
fn kept_depressions(coarse: &Heightfield, factor: usize, depth: f64) -> Vec<usize> {
    let g = Grid::of(coarse);
    let z: Vec<f64> = coarse.as_slice().iter().map(|&v| f64::from(v)).collect();
    let mut filled = z.clone();
    priority_flood(&mut filled, &g, FillMode::Plain, None);
    let w = coarse.width() * factor;
    let mut keep = Vec::new();
    for (c, (a, b)) in z.iter().zip(&filled).enumerate() {
        if b - a > depth {
            let (cx, cy) = (c % g.width, c / g.width);
            for y in cy * factor..(cy + 1) * factor {
                keep.extend((cx * factor..(cx + 1) * factor).map(|x| y * w + x));
            }
        }
    }
    keep
}

/// Finishes `fine` (the detail method's output, `factor` times `coarse` per axis) as the module
/// docs say; returns the finished surface (same grid and georeference) and what was done.
///
/// Errors: a fine grid that is not an integer multiple of the coarse one, voids in either.
pub fn finish(
    fine: &Heightfield,
    coarse: &Heightfield,
    settings: &LandformSettings,
) -> Result<(Heightfield, LandformReport)> {
    finish_until(fine, coarse, settings, &|| false)
}

/// [`finish`], asking `stop` before every round and stream-power step; when it returns true
/// the pass ends with [`LandscapeError::Stopped`].
pub fn finish_until(
    fine: &Heightfield,
    coarse: &Heightfield,
    settings: &LandformSettings,
    stop: &dyn Fn() -> bool,
) -> Result<(Heightfield, LandformReport)> {
    let (w, h) = (fine.width(), fine.height());
    let f = w / coarse.width().max(1);
    if f == 0 || coarse.width() * f != w || coarse.height() * f != h {
        return Err(LandscapeError::InvalidInput(format!(
            "the detailed surface ({w}x{h}) is not an integer multiple of the coarse input ({}x{})",
            coarse.width(),
            coarse.height()
        )));
    }
    if fine
        .as_slice()
        .iter()
        .chain(coarse.as_slice())
        .any(|v| !v.is_finite())
    {
        return Err(LandscapeError::InvalidInput(
            "the landform pass needs surfaces without voids".into(),
        ));
    }
    let grid = Grid::of(fine);
    let mut z: Vec<f64> = fine.as_slice().iter().map(|&v| f64::from(v)).collect();
    let mut report = LandformReport {
        pits_before: pits(&z, &grid),
        ..Default::default()
    };
    let limits = BreachLimits {
        max_depth: f64::INFINITY,
        max_length: f64::INFINITY,
    };
    let keep = kept_depressions(coarse, f, settings.keep_depressions_deeper_than_m);
    let drain = |z: &mut Vec<f64>, breach_first: bool, fill: bool| {
        // Cells of kept depressions are voids meanwhile: flow into them leaves the map.
        let saved: Vec<(usize, f64)> = keep.iter().map(|&i| (i, z[i])).collect();
        for &i in &keep {
            z[i] = f64::NAN;
        }
        // Breach first (a depression of the coarse input is drained by a narrow gorge through
        // its rim, which keeps the rim's box averages; filling would raise a lake the
        // back-projection lowers again); the end also fills what is left.
        let mut n = if breach_first {
            breach(z, &grid, limits).lowered
        } else {
            0
        };
        if fill {
            n += priority_flood(z, &grid, FillMode::Epsilon, None);
        }
        for (i, v) in saved {
            z[i] = v;
        }
        n
    };
    let mut base = base_level_mask(&z, &grid);
    for &i in &keep {
        base[i] = true;
    }
    let rounds = settings.rounds.max(1);
    let steps = settings.incision_steps.max(1);
    let octaves_beyond_x4 = (f as f64 / 4.0).log2();
    let sp = StreamPowerParams {
        dt: settings.incision_years / (rounds * steps) as f64,
        channel_area_m2: settings.channel_head_x4_m2 / 4f64.powf(octaves_beyond_x4),
        ..settings.stream_power
    };
    for _ in 0..settings.rounds {
        if stop() {
            return Err(LandscapeError::Stopped("the landform pass".into()));
        }
        // The round's change (breach channels and incision) is spread across the valley: a
        // one-cell cut is the scheme's, not the landform's, width.
        let z0 = z.clone();
        report.breached_cells += drain(&mut z, true, false);
        if settings.incision_years > 0.0 {
            stream_power_run(
                &mut z,
                &grid,
                &base,
                &sp,
                Uplift::Constant(0.0),
                steps,
                &relief_heightfield::NoProgress,
                stop,
            )?;
        }
        if settings.valley_width_m > 0.0 {
            let sigma = settings.valley_width_m / grid.cell_x.min(grid.cell_y);
            let d = Heightfield::new(
                w,
                h,
                z.iter().zip(&z0).map(|(a, b)| (a - b) as f32).collect(),
                grid.cell_x,
                grid.cell_y,
            )?
            .gaussian_blur(sigma as f32)?;
            for ((v, b), dv) in z.iter_mut().zip(&z0).zip(d.as_slice()) {
                *v = b + f64::from(*dv);
            }
        }
        // Back to the input's box averages: fixed-point iterations of the bicubic
        // back-projection (bicubic up then box down is close to, not exactly, the identity).
        for _ in 0..BACK_PROJECTION_ITERATIONS {
            back_project(&mut z, w, h, coarse, f)?;
        }
    }
    let before = z.clone();
    report.filled_cells = drain(&mut z, true, true);
    // The end's cuts are one cell wide: their sides are cut back into V-shaped notches, and
    // what a notch closes (a cell it lowered under a neighbour's notch) is filled.
    widen_cuts(
        &mut z,
        &before,
        &grid,
        settings.cut_side_slope_deg.to_radians().tan(),
    );
    report.filled_cells += drain(&mut z, false, true);
    let r = box_residual(&z, w, coarse, f);
    report.consistency_rms_m = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
    let (cx, cy) = fine.cell_size();
    let out = Heightfield::new(w, h, z.iter().map(|&v| v as f32).collect(), cx, cy)?
        .with_georef(fine.georef().cloned());
    Ok((out, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Smooth hills on a 16 x 16 coarse grid (500 m cells), optionally with a bowl `depth` m
    /// deep in the middle, and its bicubic enlargement x4 with deterministic noise of +-4 m: the
    /// noise closes hundreds of small depressions, as detail methods do.
    fn case(depth: f64) -> (Heightfield, Heightfield) {
        let n = 16;
        let coarse: Vec<f32> = (0..n * n)
            .map(|i| {
                let (x, y) = ((i % n) as f64, (i / n) as f64);
                let r2 = (x - 7.5).powi(2) + (y - 7.5).powi(2);
                (300.0 + 80.0 * (x * 0.7).sin() * (y * 0.5).cos() + 10.0 * x
                    - depth * (-r2 / 3.0).exp()) as f32
            })
            .collect();
        let coarse = Heightfield::new(n, n, coarse, 500.0, 500.0).unwrap();
        let mut fine = coarse.resample(4 * n, 4 * n).unwrap();
        for (i, v) in fine.as_mut_slice().iter_mut().enumerate() {
            let hash = relief_heightfield::rng::splitmix64(i as u64);
            *v += ((hash % 1000) as f32 / 1000.0 - 0.5) * 8.0;
        }
        (coarse, fine)
    }

    fn strict_pits(hf: &Heightfield) -> usize {
        let z: Vec<f64> = hf.as_slice().iter().map(|&v| f64::from(v)).collect();
        pits(&z, &Grid::of(hf))
    }

    /// A cut 6 m deep along a row of a flat plain becomes a V-shaped notch: sides at the given
    /// slope (45 degrees on 1 m cells: 1 m lower per cell nearer the cut), out to 6 m from it;
    /// the cut's floor stays where it was.
    #[test]
    fn a_one_cell_cut_becomes_a_notch() {
        let (w, h) = (21, 21);
        let grid = Grid {
            width: w,
            height: h,
            cell_x: 1.0,
            cell_y: 1.0,
        };
        let before = vec![10.0; w * h];
        let mut z = before.clone();
        for x in 0..w {
            z[10 * w + x] = 4.0;
        }
        widen_cuts(&mut z, &before, &grid, 1.0);
        let at = |y: usize| z[y * w + 7];
        for (y, want) in [
            (10, 4.0),
            (11, 5.0),
            (9, 5.0),
            (12, 6.0),
            (15, 9.0),
            (16, 10.0),
        ] {
            assert!((at(y) - want).abs() < 1e-9, "row {y}: {} not {want}", at(y));
        }
        // Slope 0 leaves the cut one cell wide.
        let mut flat = before.clone();
        flat[10 * w + 3] = 4.0;
        widen_cuts(&mut flat, &before, &grid, 0.0);
        assert_eq!(flat[11 * w + 3], 10.0);
    }

    #[test]
    fn the_pass_drains_the_detail_and_keeps_the_box_averages() {
        let (coarse, fine) = case(0.0);
        assert!(strict_pits(&fine) > 15, "{}", strict_pits(&fine));
        let (out, report) = finish(&fine, &coarse, &LandformSettings::default()).unwrap();
        assert_eq!(report.pits_before, strict_pits(&fine));
        assert_eq!(strict_pits(&out), 0);
        assert!(crate::stats::drainage(&out).fill_depth_m < 1e-3);
        let relief = 277.7; // max - min of the coarse hills
        assert!(report.consistency_rms_m < 0.005 * relief, "{report:?}");
        let back = out.downsample_box(4).unwrap();
        let rms = (back
            .as_slice()
            .iter()
            .zip(coarse.as_slice())
            .map(|(a, b)| f64::from(a - b).powi(2))
            .sum::<f64>()
            / 256.0)
            .sqrt();
        assert!((rms - report.consistency_rms_m).abs() < 1e-3, "{rms}");
        // Channels were cut: some cells went down by more than the noise.
        let lowered = out
            .as_slice()
            .iter()
            .zip(fine.as_slice())
            .filter(|(a, b)| **b - **a > 4.0)
            .count();
        assert!(lowered > 20, "{lowered}");
        assert_eq!(out.cell_size(), fine.cell_size());
    }

    #[test]
    fn a_deep_coarse_depression_is_kept_when_asked() {
        let (coarse, fine) = case(300.0);
        let drained = finish(&fine, &coarse, &LandformSettings::default())
            .unwrap()
            .0;
        assert_eq!(strict_pits(&drained), 0);
        let keep = LandformSettings {
            keep_depressions_deeper_than_m: 50.0,
            ..Default::default()
        };
        let kept = finish(&fine, &coarse, &keep).unwrap().0;
        // The bowl still holds water: its fill depth is tens of metres at the centre.
        let g = Grid::of(&kept);
        let z: Vec<f64> = kept.as_slice().iter().map(|&v| f64::from(v)).collect();
        let mut f = z.clone();
        priority_flood(&mut f, &g, FillMode::Plain, None);
        let c = 32 * 64 + 32;
        assert!(f[c] - z[c] > 20.0, "{}", f[c] - z[c]);
    }

    #[test]
    fn mismatched_grids_and_voids_are_refused() {
        let (coarse, fine) = case(0.0);
        let odd = fine.crop(0, 0, 63, 64).unwrap();
        let e = finish(&odd, &coarse, &LandformSettings::default()).unwrap_err();
        assert!(e.to_string().contains("integer multiple"), "{e}");
        let mut holed = fine.clone();
        holed.as_mut_slice()[100] = f32::NAN;
        let e = finish(&holed, &coarse, &LandformSettings::default()).unwrap_err();
        assert!(e.to_string().contains("voids"), "{e}");
    }
}
