//! Stepped slopes from the strata: where a resistant bed crops out on a slope, its edge
//! stands as a cliff and its top as a bench, and the soft rock between keeps the slope's
//! own angle (the structural benches of the Grand Canyon's walls, Bryce's amphitheatres and
//! every layered escarpment). Done on the DEM before it is implicitised, so every feature
//! (hoodoos, arches, undercuts, karst) is placed on the stepped ground.
//!
//! For a sample at height `u` inside a resistant run `[h0, h1]` of its column (the geology's
//! resistance at or above `rho0` from `h0` to `h1`), the new height is
//! `h0 + min((u - h0) / c, h1 - h0)`, `c` the cliff fraction: the lower `c` of the bed's
//! outcrop rises over the bed's whole thickness (a cliff `1 / c` times as steep as the slope
//! was) and the rest lies on the bed's top (the bench, which follows the bed's dip, folds and
//! faults). `c` is `1 - Recipe::benches` on steep ground and less where that would leave the
//! cliff under [`CLIFF_DEG`] (`tan(slope) / tan(70 deg)`, at least [`MIN_CLIFF`]): a
//! resistant bed stands as a cliff whatever the slope it crops out on, and its bench widens
//! on gentle ground. At each cliff's foot a talus apron leans against it: scree at 35 degrees
//! up to 0.4 of the bed's thickness, spreading down over the soft rock below (the map then
//! raises those soft samples too, never above the apron). Samples in soft rock keep their height, so the map is
//! continuous, never lowers the ground, and moves no sample by more than the thickness of the
//! bed it is in. The DEM is first interpolated (Keys bicubic, through the nodes) to cells of
//! the meshing voxel, so a bed a few metres thick has cells to step over.

use crate::geology::Geology;
use crate::{Error, Result};
use rayon::prelude::*;
use relief_heightfield::Heightfield;

/// Most nodes of the interpolated DEM the benches are cut on.
pub(super) const MAX_NODES: usize = 4096 * 4096;

/// Angle (degrees) a resistant bed's cliff stands at, at least: on a slope gentler than
/// `CLIFF_DEG` times the cliff fraction the cliff keeps this angle and the bench takes the
/// rest of the outcrop (the escarpments of gently dipping plateaus).
const CLIFF_DEG: f32 = 70.0;

/// Smallest cliff fraction (on flat ground): a cliff over 2 % of the outcrop.
const MIN_CLIFF: f32 = 0.02;

/// What [`benches`] did, for the report.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct BenchReport {
    /// Interpolation factor of the DEM's cells (1 = its own cells).
    pub factor: usize,
    /// Cell size cut on (m, the larger side).
    pub cell_m: f32,
    /// Median thickness of the resistant beds over nine columns (m).
    pub bed_m: f32,
    /// Samples raised (on a cliff or a bench).
    pub raised: usize,
    /// Largest rise (m).
    pub max_rise_m: f32,
}

/// The inputs of [`benches`].
pub(super) struct BenchInput<'a> {
    pub geology: &'a Geology,
    /// Resistance at and above which rock is resistant.
    pub rho0: f32,
    /// Fraction of a resistant bed's outcrop that becomes its bench, in `[0, 1)`.
    pub benches: f32,
    /// Cell size wanted (m): the meshing voxel.
    pub cell_m: f32,
    /// Samples at or below this height are left alone (the sea).
    pub sea_level: Option<f32>,
    /// Lowest and highest ground (m), the range the beds are measured over.
    pub lo: f32,
    pub hi: f32,
}

/// The DEM stepped by its resistant beds ([module docs](self)), or `Ok(None)` with the
/// reason when there is nothing to step: benches off, no resistant bed within the relief, or
/// beds too thin for the cells a run affords.
pub(super) fn benches(
    hf: &Heightfield,
    inp: &BenchInput<'_>,
) -> Result<std::result::Result<(Heightfield, BenchReport), String>> {
    if inp.benches == 0.0 {
        return Ok(Err("benches off".into()));
    }
    if !((0.0..1.0).contains(&inp.benches) && inp.cell_m.is_finite() && inp.cell_m > 0.0) {
        return Err(Error::param(
            "benches",
            inp.benches,
            "must be in [0, 1) with a finite, positive voxel",
        ));
    }
    let (ex, ey) = (
        (hf.width() - 1) as f64 * hf.cell_size().0,
        (hf.height() - 1) as f64 * hf.cell_size().1,
    );
    let Some(bed) = median_hard_run(inp, ex as f32, ey as f32) else {
        return Ok(Err(format!(
            "benches skipped: no resistant bed (resistance >= {}) crops out between {:.0} and \
             {:.0} m",
            inp.rho0, inp.lo, inp.hi
        )));
    };
    if inp.cell_m > bed {
        return Ok(Err(format!(
            "benches skipped: resistant beds {bed:.1} m thick (median) are thinner than the \
             {:.1} m voxel (a finer --voxel or a smaller window resolves them)",
            inp.cell_m
        )));
    }
    let cell = hf.cell_size().0.max(hf.cell_size().1) as f32;
    let nodes = |k: usize| ((hf.width() - 1) * k + 1) * ((hf.height() - 1) * k + 1);
    let cap = (MAX_NODES as f64 / ((hf.width() - 1) * (hf.height() - 1)) as f64).sqrt();
    let mut k = f64::from(cell / inp.cell_m).ceil().clamp(1.0, cap.max(1.0)) as usize;
    while k > 1 && nodes(k) > MAX_NODES {
        k -= 1;
    }
    let fine = cell / k as f32;
    // A cliff needs a cell or two across the bed's outcrop: on a 30-degree slope a bed `t`
    // thick crops out over 1.7 t.
    if fine > bed {
        return Ok(Err(format!(
            "benches skipped: resistant beds {bed:.1} m thick (median) need cells of at most \
             that; {fine:.1} m is the finest this DEM affords ({}x{} nodes)",
            (hf.width() - 1) * k + 1,
            (hf.height() - 1) * k + 1
        )));
    }
    let up = if k == 1 { hf.clone() } else { upsample(hf, k)? };
    let (w, h) = (up.width(), up.height());
    let (cx, cy) = up.cell_size();
    let step = 0.25 * bed;
    let max_run = (8.0 * bed).min((inp.hi - inp.lo).max(bed));
    let shape = Shape {
        step,
        max_run,
        cliff_max: 1.0 - inp.benches,
        steep: CLIFF_DEG.to_radians().tan(),
        bed,
    };
    let src = up.as_slice();
    // Ground gradient (m/m) by central differences, one-sided at the edges.
    let grad = |j: usize, i: usize| {
        let (j0, j1) = (j.saturating_sub(1), (j + 1).min(w - 1));
        let (i0, i1) = (i.saturating_sub(1), (i + 1).min(h - 1));
        let gx = (src[i * w + j1] - src[i * w + j0]) / ((j1 - j0).max(1) as f64 * cx) as f32;
        let gy = (src[i1 * w + j] - src[i0 * w + j]) / ((i1 - i0).max(1) as f64 * cy) as f32;
        gx.hypot(gy)
    };
    let mut out = vec![0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(i, row)| {
        let y = (h - 1 - i) as f32 * cy as f32;
        for (j, o) in row.iter_mut().enumerate() {
            let u = src[i * w + j];
            *o = match inp.sea_level {
                Some(s) if u <= s => u,
                _ => {
                    let xy = [j as f32 * cx as f32, y];
                    stepped_height(inp.geology, inp.rho0, xy, u, grad(j, i), &shape)
                }
            };
        }
    });
    let (raised, max_rise) = out
        .iter()
        .zip(src)
        .fold((0usize, 0f32), |(n, m), (&a, &b)| {
            if a > b { (n + 1, m.max(a - b)) } else { (n, m) }
        });
    let stepped = Heightfield::new(w, h, out, cx, cy)?;
    Ok(Ok((
        stepped,
        BenchReport {
            factor: k,
            cell_m: fine,
            bed_m: bed,
            raised,
            max_rise_m: max_rise,
        },
    )))
}

/// Slope (degrees) of the talus aprons at the cliffs' feet: scree at its angle of repose.
const TALUS_DEG: f32 = 35.0;

/// Height of a talus apron against its cliff, as a fraction of the bed's thickness.
const TALUS_FRACTION: f32 = 0.4;

/// How the steps are cut ([`stepped_height`]).
struct Shape {
    /// Search step and longest resistant run (m) of [`hard_run`].
    step: f32,
    max_run: f32,
    /// Largest cliff fraction (`1 - benches`) and the gradient of a [`CLIFF_DEG`] cliff.
    cliff_max: f32,
    steep: f32,
    /// Median bed thickness (m).
    bed: f32,
}

/// The stepped height of a sample at `u` on ground of gradient `g` ([module docs](self)),
/// with a talus apron at the foot of each cliff: scree at [`TALUS_DEG`] leaning against the
/// cliff up to [`TALUS_FRACTION`] of its height and spreading down over the soft rock below,
/// as the debris of the bed above collects there.
fn stepped_height(geo: &Geology, rho0: f32, xy: [f32; 2], u: f32, g: f32, s: &Shape) -> f32 {
    let g = g.max(1e-4);
    let cliff = (g / s.steep).clamp(MIN_CLIFF, s.cliff_max);
    // The cliff's gradient; the apron's surface at horizontal distance `d` from the cliff's
    // foot (upslope positive), up to where it meets the face (none on a cliff gentler than
    // the scree could lean on).
    let rise = g / cliff;
    let tan = TALUS_DEG.to_radians().tan();
    let apron = |h0: f32, h1: f32, d: f32| {
        if rise < 1.5 * tan {
            return f32::NEG_INFINITY;
        }
        let a = TALUS_FRACTION * (h1 - h0);
        (h0 + a + d * tan).min(h0 + a * rise / (rise - tan))
    };
    if let Some((h0, h1)) = hard_run(geo, rho0, xy, u, s.step, s.max_run) {
        let z = h0 + ((u - h0) / cliff).min(h1 - h0).max(u - h0);
        return z.max(apron(h0, h1, (u - h0) / g));
    }
    // Soft rock: under an apron when a cliff's foot is close above (an apron `a` high
    // reaches `a g / (g + tan)` below the foot; beds up to twice the median).
    let reach = TALUS_FRACTION * 2.0 * s.bed * g / (g + tan);
    let hard = |z: f32| geo.resistance([xy[0], xy[1], z]) >= rho0;
    let mut below = u;
    while below - u < reach {
        let next = (below + s.step).min(u + reach);
        if hard(next) {
            if let Some((h0, h1)) = hard_run(geo, rho0, xy, next, s.step, s.max_run) {
                return u.max(apron(h0, h1, -(h0 - u) / g));
            }
            break;
        }
        if next <= below {
            break;
        }
        below = next;
    }
    u
}

/// The DEM interpolated `k` times finer through its nodes (Keys bicubic, the same extent; no
/// georeference: the scene does not use it).
fn upsample(hf: &Heightfield, k: usize) -> Result<Heightfield> {
    let (w, h) = ((hf.width() - 1) * k + 1, (hf.height() - 1) * k + 1);
    let kf = k as f32;
    let mut out = vec![0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(i, row)| {
        for (j, o) in row.iter_mut().enumerate() {
            *o = hf.sample_bicubic(j as f32 / kf, i as f32 / kf);
        }
    });
    let (cx, cy) = hf.cell_size();
    Ok(Heightfield::new(w, h, out, cx / k as f64, cy / k as f64)?)
}

/// A DEM-sized mask (`w x h` nodes, row-major) interpolated (bilinear) onto the nodes of the
/// DEM interpolated `k` times finer; a mask of another size is returned as it is (the region's
/// check then names it).
pub(super) fn upsample_mask(mask: &[f32], w: usize, h: usize, k: usize) -> Vec<f32> {
    if k <= 1 || mask.len() != w * h {
        return mask.to_vec();
    }
    let (fw, fh) = ((w - 1) * k + 1, (h - 1) * k + 1);
    let kf = k as f32;
    (0..fw * fh)
        .map(|n| {
            let (u, v) = ((n % fw) as f32 / kf, (n / fw) as f32 / kf);
            let (j0, i0) = (u.floor() as usize, v.floor() as usize);
            let (j1, i1) = ((j0 + 1).min(w - 1), (i0 + 1).min(h - 1));
            let (tx, ty) = (u - j0 as f32, v - i0 as f32);
            let a = mask[i0 * w + j0] * (1.0 - tx) + mask[i0 * w + j1] * tx;
            let b = mask[i1 * w + j0] * (1.0 - tx) + mask[i1 * w + j1] * tx;
            a * (1.0 - ty) + b * ty
        })
        .collect()
}

/// The resistant run `[h0, h1]` (resistance `>= rho0`) of column `xy` that holds `u`, found
/// by stepping `step` down and up and bisecting the ends; `None` in soft rock or when the run
/// is longer than `max_run` either way (massive rock: no bed to step).
fn hard_run(
    g: &Geology,
    rho0: f32,
    xy: [f32; 2],
    u: f32,
    step: f32,
    max_run: f32,
) -> Option<(f32, f32)> {
    let hard = |z: f32| g.resistance([xy[0], xy[1], z]) >= rho0;
    if !hard(u) {
        return None;
    }
    let end = |dir: f32| {
        let mut inside = u;
        loop {
            let next = inside + dir * step;
            if (next - u).abs() > max_run {
                return None;
            }
            if !hard(next) {
                let (mut a, mut b) = (inside, next);
                for _ in 0..5 {
                    let m = 0.5 * (a + b);
                    if hard(m) { a = m } else { b = m }
                }
                return Some(a);
            }
            inside = next;
        }
    };
    Some((end(-1.0)?, end(1.0)?))
}

/// Median length of the resistant runs along nine columns between `lo` and `hi` (runs cut by
/// either end not counted); `None` without one.
fn median_hard_run(inp: &BenchInput<'_>, ex: f32, ey: f32) -> Option<f32> {
    let cols: Vec<[f32; 2]> = (0..9)
        .map(|c| {
            [
                ex * (0.2 + 0.3 * (c % 3) as f32),
                ey * (0.2 + 0.3 * (c / 3) as f32),
            ]
        })
        .collect();
    let step = ((inp.hi - inp.lo) / 4096.0).max(0.05);
    let rho0 = inp.rho0;
    let mut runs = inp
        .geology
        .runs(&cols, inp.lo, inp.hi, step, |rho| rho >= rho0);
    runs.sort_by(f32::total_cmp);
    runs.get(runs.len() / 2).copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plane sloping `deg` to the east over soft beds 6 m and resistant beds 4 m thick.
    fn slope_and_beds(benches: f32, deg: f32) -> (Heightfield, Heightfield, BenchReport) {
        let g = crate::geology::test_beds(0.0, (6.0, 0.2), (4.0, 0.8));
        let (w, h, cell) = (41, 5, 2.0);
        let t = deg.to_radians().tan();
        let data = (0..w * h)
            .map(|k| 5.0 + (k % w) as f32 * cell * t)
            .collect();
        let hf = Heightfield::new(w, h, data, cell as f64, cell as f64).unwrap();
        let (lo, hi) = hf.min_max().unwrap();
        let inp = BenchInput {
            geology: &g,
            rho0: 0.5,
            benches,
            cell_m: 0.5,
            sea_level: None,
            lo,
            hi,
        };
        let (out, rep) = super::benches(&hf, &inp).unwrap().unwrap();
        (hf, out, rep)
    }

    #[test]
    fn resistant_beds_become_cliffs_and_benches() {
        let (_, out, rep) = slope_and_beds(0.8, 30.0);
        assert_eq!(rep.factor, 4);
        assert!((rep.bed_m - 4.0).abs() < 0.2, "bed {}", rep.bed_m);
        let row: Vec<f32> = (0..out.width()).map(|j| out.get(j, 2)).collect();
        let dx = out.cell_size().0 as f32;
        let slopes: Vec<f32> = row
            .windows(2)
            .map(|p| ((p[1] - p[0]) / dx).atan().to_degrees())
            .collect();
        // Cliffs in the resistant beds (5x the 30-degree slope's gradient: 71 degrees),
        // benches on their tops, the soft beds at the slope's own 30 degrees.
        let steep = slopes.iter().filter(|&&s| s > 60.0).count();
        let flat = slopes.iter().filter(|&&s| s < 1.0).count();
        let soft = slopes.iter().filter(|&&s| (s - 30.0).abs() < 1.0).count();
        assert!(
            steep >= 3 && flat >= 15 && soft >= 30,
            "{steep} {flat} {soft}"
        );
        // Never lower, never more than a bed's thickness higher.
        let (hf, _, _) = slope_and_beds(0.8, 30.0);
        for j in 0..out.width() {
            let u = hf.sample_bicubic(j as f32 / 4.0, 2.0);
            let d = out.get(j, 2) - u;
            assert!((-1e-4..=4.01).contains(&d), "{j}: {d}");
        }
        // Talus aprons: soft samples just under a cliff's foot (beds from 10 k + 6) are
        // raised, by at most the apron's 1.6 m (0.4 of the 4 m bed), and the apron's
        // surface slopes at the scree's 35 degrees.
        let aprons = (0..out.width())
            .filter(|&j| {
                let u = hf.sample_bicubic(j as f32 / 4.0, 2.0);
                let under = (u - 5.0).rem_euclid(10.0);
                under > 0.0 && under < 1.0 && out.get(j, 2) - u > 0.05
            })
            .count();
        assert!(aprons >= 3, "{aprons} apron samples");
        let scree = slopes.iter().filter(|&&s| (s - 35.0).abs() < 1.5).count();
        assert!(scree >= 3, "{scree} samples at the scree's angle");
        // Every bench lies on a resistant bed's top: 10 m period, tops at 10 k.
        for (j, s) in slopes.iter().enumerate() {
            if *s < 1.0 {
                let z = row[j];
                assert!((z / 10.0 - (z / 10.0).round()).abs() < 0.01, "bench at {z}");
            }
        }
    }

    #[test]
    fn cliffs_stand_steep_on_gentle_slopes() {
        // On 5 degrees the outcrop is 46 m wide: a 70-degree cliff and a 44 m bench.
        let (_, out, _) = slope_and_beds(0.8, 5.0);
        let dx = out.cell_size().0 as f32;
        let steepest = (1..out.width())
            .map(|j| {
                ((out.get(j, 2) - out.get(j - 1, 2)) / dx)
                    .atan()
                    .to_degrees()
            })
            .fold(0f32, f32::max);
        assert!(steepest > 60.0, "steepest {steepest}");
    }

    #[test]
    fn benches_off_or_too_coarse_say_why() {
        let g = crate::geology::test_beds(0.0, (6.0, 0.2), (4.0, 0.8));
        let hf = Heightfield::new(
            3,
            3,
            vec![0.0, 10.0, 20.0, 0.0, 10.0, 20.0, 0.0, 10.0, 20.0],
            50.0,
            50.0,
        )
        .unwrap();
        let mut inp = BenchInput {
            geology: &g,
            rho0: 0.5,
            benches: 0.0,
            cell_m: 10.0,
            sea_level: None,
            lo: 0.0,
            hi: 20.0,
        };
        assert_eq!(benches(&hf, &inp).unwrap().unwrap_err(), "benches off");
        inp.benches = 0.8;
        let why = benches(&hf, &inp).unwrap().unwrap_err();
        assert!(why.contains("thinner than the 10.0 m voxel"), "{why}");
        // A voxel that resolves the beds on a DEM too large to interpolate to it (50 km
        // cells: at most 2047 times finer, 24 m).
        let wide = Heightfield::new(3, 3, hf.as_slice().to_vec(), 5e4, 5e4).unwrap();
        inp.cell_m = 1.0;
        let why = benches(&wide, &inp).unwrap().unwrap_err();
        assert!(why.contains("need cells of at most"), "{why}");
        inp.benches = 1.0;
        assert!(benches(&hf, &inp).is_err());
    }
}
