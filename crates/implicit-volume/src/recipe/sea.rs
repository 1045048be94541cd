//! Sea detection: where a DEM has sea, and at which level ([`detect_sea`]).
//!
//! A recipe without an explicit [`Recipe::sea_level`] places its shore features (sea erosion,
//! caves, cliffs) only where the DEM itself has sea. The sea is what DEMs record as sea:
//!
//! * **connected to the DEM's border**: a flood fill (4-connected, through finite samples)
//!   from the border samples at or below the level. A closed depression (a canyon floor, a
//!   crater, a polder) is not sea, however low;
//! * **flat or below zero**: the convention of SRTM-like products and ocean masks is sea at
//!   exactly 0 m, and bathymetric DEMs (topobathy) go below 0 m. So the level is 0 m when
//!   enough border-connected samples are at or below 0 m ([`SeaKind::Zero`]); otherwise, in a
//!   DEM whose datum puts the water elsewhere, a large border-connected area within a flatness
//!   tolerance of the DEM's lowest value (but [`SEA_PITS`] samples, so a few pits under the
//!   water do not set it), and flat rather than a gentle slope (doubling the tolerance adds
//!   less than half the area again): a lake or sea surface ([`SeaKind::FlatMinimum`]);
//! * **flat within the DEM's noise**: water in a real DEM is flat only up to its vertical
//!   noise and quantisation (SRTM-like products leave a few decimetres of speckle on
//!   unflattened water). The tolerance is [`sea_flat_tolerance`]: `max(SEA_FLAT_NOISE_M,
//!   1.5 q)` with `q` the DEM's vertical quantum (the smallest step between distinct
//!   sample values: 1 m for integer DEMs, so a water surface stored as two adjacent integers is
//!   still flat). The sea is the border-connected area at or below `lowest + tolerance` and
//!   its level is that area's median height;
//! * **large enough to be a sea**: at least [`SEA_MIN_SHARE`] of the samples and at least
//!   [`SEA_MIN_CELLS`] samples. A few border samples at 0 m (a river mouth on the edge of a
//!   crop, a void filled with 0) or the last contour of a valley floor cut by the border
//!   would otherwise draw a sea; 2 % keeps a coastal strip of one sample in 50 along a
//!   border, and 16 samples (a 4 x 4 block) keeps tiny rasters from calling a single low
//!   corner a sea.
//!
//! Anything else is no sea: the recipe skips its shore features and says so. Measured on the
//! shared DEM set: N57E011 (Kattegat coast) 85.5 % border-connected at or below 0 m, topobathy
//! 44 %; grandcanyon, alps_dem, carrizo, jacksboro_fault have no sample at or below 0 m and no
//! flat minimum; maunga_whau's lowest contour (94 m, 1.0 % of the samples) is below the share.

use relief_heightfield::Heightfield;

use crate::scene::border_connected_at_or_below;

/// Smallest share of the DEM's samples a sea covers ([`detect_sea`]).
pub const SEA_MIN_SHARE: f32 = 0.02;
/// Smallest number of samples a sea covers ([`detect_sea`]).
pub const SEA_MIN_CELLS: usize = 16;
/// Samples allowed below a flat water surface's lowest value ([`detect_sea`]): pits of
/// speckle or voids filled low.
pub const SEA_PITS: usize = 4;
/// Peak-to-peak vertical noise (m) a water surface may have and still be flat
/// ([`sea_flat_tolerance`]): a few decimetres either side of its level.
pub const SEA_FLAT_NOISE_M: f32 = 1.0;

/// The flatness tolerance of a water surface in `hf` ([`detect_sea`], module docs):
/// `max(SEA_FLAT_NOISE_M, 1.5 q)` with `q` the smallest positive difference between two
/// distinct finite sample values (the DEM's vertical quantum), `q` capped at 10 m.
pub fn sea_flat_tolerance(hf: &Heightfield) -> f32 {
    let mut v = finite_samples(hf);
    v.sort_by(f32::total_cmp);
    v.dedup();
    let q = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f32::INFINITY, f32::min)
        .min(10.0);
    if q.is_finite() {
        SEA_FLAT_NOISE_M.max(1.5 * q)
    } else {
        SEA_FLAT_NOISE_M
    }
}

/// The finite samples of `hf`, in row-major order.
fn finite_samples(hf: &Heightfield) -> Vec<f32> {
    hf.as_slice()
        .iter()
        .copied()
        .filter(|z| z.is_finite())
        .collect()
}

/// Which rule found the sea.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SeaKind {
    /// Border-connected samples at or below 0 m (SRTM sea at 0 m, bathymetry below).
    Zero,
    /// A border-connected area within [`sea_flat_tolerance`] of the DEM's lowest value (a
    /// water surface, flat within the DEM's noise, in a DEM without 0 m).
    FlatMinimum,
}

/// The sea [`detect_sea`] found.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SeaDetection {
    /// Sea level (m): 0 for [`SeaKind::Zero`], the median height of the flat area otherwise.
    pub level: f32,
    /// Which rule found it.
    pub kind: SeaKind,
    /// Samples of the sea (border-connected, at or below `level`; for
    /// [`SeaKind::FlatMinimum`] at or below the lowest value plus the tolerance).
    pub cells: usize,
    /// `cells` over the DEM's sample count.
    pub share: f32,
}

/// Detects the sea of a DEM (module docs): border-connected samples at or below 0 m, else a
/// border-connected area within [`sea_flat_tolerance`] of the lowest value, each kept only
/// when it covers at least [`SEA_MIN_SHARE`] of the samples and [`SEA_MIN_CELLS`] samples;
/// `None` = no sea (an inland DEM). Pure and deterministic; non-finite samples are ignored.
pub fn detect_sea(hf: &Heightfield) -> Option<SeaDetection> {
    let n = hf.width() * hf.height();
    let large =
        |cells: usize| cells >= SEA_MIN_CELLS && cells as f64 >= SEA_MIN_SHARE as f64 * n as f64;
    let zero = border_connected_at_or_below(hf, 0.0);
    let cells = zero.iter().filter(|&&s| s).count();
    if large(cells) {
        return Some(SeaDetection {
            level: 0.0,
            kind: SeaKind::Zero,
            cells,
            share: cells as f32 / n.max(1) as f32,
        });
    }
    // The water's lowest value: the lowest sample but `SEA_PITS`, so that a few pits below
    // the water (speckle, voids filled low) do not set it.
    let mut low = finite_samples(hf);
    let k = (SEA_PITS + 1).min(low.len()).checked_sub(1)?;
    let (_, &mut lo, _) = low.select_nth_unstable_by(k, f32::total_cmp);
    if lo <= 0.0 {
        return None;
    }
    let tol = sea_flat_tolerance(hf);
    let count = |level: f32| {
        border_connected_at_or_below(hf, level)
            .iter()
            .filter(|&&s| s)
            .count()
    };
    // Flat, not a gentle slope: doubling the tolerance must not add half as much area again
    // (on a uniform slope the area doubles; water ends at a shore that rises).
    if 2 * count(lo + 2.0 * tol) > 3 * count(lo + tol) {
        return None;
    }
    let mask = border_connected_at_or_below(hf, lo + tol);
    let mut z: Vec<f32> = hf
        .as_slice()
        .iter()
        .zip(&mask)
        .filter(|x| *x.1)
        .map(|x| *x.0)
        .collect();
    if !large(z.len()) {
        return None;
    }
    z.sort_by(f32::total_cmp);
    Some(SeaDetection {
        level: z[z.len() / 2],
        kind: SeaKind::FlatMinimum,
        cells: z.len(),
        share: z.len() as f32 / n.max(1) as f32,
    })
}

/// Share of a sea's samples that must sit at its level (within 1 cm) for it to be a flat sea
/// surface with no bathymetry (SRTM's 0 m), which [`seabed`] replaces.
pub const FLAT_SEA_SHARE: f32 = 0.9;

/// The seabed [`seabed`] gave a flat sea.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Seabed {
    /// Slope of the sea floor at the coast (m/m): the median slope of the coast's land.
    pub shore_slope: f32,
    /// Depth the floor tends to offshore (m).
    pub depth_m: f32,
    /// Deepest sample of the new floor below the level (m).
    pub deepest_m: f32,
    /// Samples lowered.
    pub cells: usize,
}

/// A seabed under a sea stored as a flat surface (at least [`FLAT_SEA_SHARE`] of the detected
/// sea's samples at its level, as SRTM stores the sea at 0 m): without one, the implicit
/// terrain is a flat plate at the water line, shore erosion has nothing to undercut below it
/// and a mesh has no sea floor. Each sea sample is lowered to `level - D (1 - exp(-s d / D))`
/// (never raised), `d` its distance (m, chamfer over the 8 neighbours) to the nearest land
/// sample, `s` the median slope of the land samples next to the sea (clamped to
/// `[0.005, 0.2]`: the coast's own slope continues under the water) and `D = clamp(0.1
/// relief, 5, 200)` m the depth the floor levels out at. `None` when the sea already has a
/// floor (bathymetry) or there is no land. Deterministic.
pub fn seabed(hf: &Heightfield, sea: &SeaDetection, relief: f32) -> Option<(Heightfield, Seabed)> {
    let (w, h) = (hf.width(), hf.height());
    let tol = match sea.kind {
        SeaKind::Zero => 0.0,
        SeaKind::FlatMinimum => sea_flat_tolerance(hf),
    };
    let mask = border_connected_at_or_below(hf, sea.level + tol);
    let z = hf.as_slice();
    let n = mask.iter().filter(|&&m| m).count();
    let flat = mask
        .iter()
        .zip(z)
        .filter(|(m, v)| **m && (**v - sea.level).abs() <= 0.01)
        .count();
    if n == 0 || n == w * h || (flat as f32) < FLAT_SEA_SHARE * n as f32 {
        return None;
    }
    let (cx, cy) = hf.cell_size();
    let (cx, cy) = (cx as f32, cy as f32);
    // The coast's slope: land samples with a sea neighbour, central differences.
    let at = |i: usize, j: usize| z[i * w + j];
    let mut slopes = Vec::new();
    for i in 0..h {
        for j in 0..w {
            let k = i * w + j;
            let near_sea = (j > 0 && mask[k - 1])
                || (j + 1 < w && mask[k + 1])
                || (i > 0 && mask[k - w])
                || (i + 1 < h && mask[k + w]);
            if mask[k] || !near_sea || !z[k].is_finite() {
                continue;
            }
            let (j0, j1) = (j.saturating_sub(1), (j + 1).min(w - 1));
            let (i0, i1) = (i.saturating_sub(1), (i + 1).min(h - 1));
            let sx = (at(i, j1) - at(i, j0)) / ((j1 - j0).max(1) as f32 * cx);
            let sy = (at(i1, j) - at(i0, j)) / ((i1 - i0).max(1) as f32 * cy);
            let g = (sx * sx + sy * sy).sqrt();
            if g.is_finite() {
                slopes.push(g);
            }
        }
    }
    if slopes.is_empty() {
        return None;
    }
    let mid = slopes.len() / 2;
    let (_, &mut s, _) = slopes.select_nth_unstable_by(mid, f32::total_cmp);
    let s = s.clamp(0.005, 0.2);
    let depth = (0.1 * relief).clamp(5.0, 200.0);
    let dist = distance_to_land(&mask, w, h, cx, cy);
    let mut out = z.to_vec();
    let mut deepest = 0.0f32;
    for k in 0..w * h {
        if mask[k] {
            let dz = depth * (1.0 - (-s * dist[k] / depth).exp());
            out[k] = out[k].min(sea.level - dz);
            deepest = deepest.max(sea.level - out[k]);
        }
    }
    let (ccx, ccy) = hf.cell_size();
    let floor = Heightfield::new(w, h, out, ccx, ccy)
        .ok()?
        .with_georef(hf.georef().cloned());
    Some((
        floor,
        Seabed {
            shore_slope: s,
            depth_m: depth,
            deepest_m: deepest,
            cells: n,
        },
    ))
}

/// Distance (m) from each `mask` sample to the nearest sample outside it: two chamfer passes
/// over the 8 neighbours with the cell's edge and diagonal lengths (within 8 % of Euclidean).
fn distance_to_land(mask: &[bool], w: usize, h: usize, cx: f32, cy: f32) -> Vec<f32> {
    let diag = (cx * cx + cy * cy).sqrt();
    let mut d: Vec<f32> = mask
        .iter()
        .map(|&m| if m { f32::INFINITY } else { 0.0 })
        .collect();
    let fwd: [(isize, isize, f32); 4] = [(-1, -1, diag), (-1, 0, cy), (-1, 1, diag), (0, -1, cx)];
    for pass in 0..2 {
        for step in 0..w * h {
            let k = if pass == 0 { step } else { w * h - 1 - step };
            let (i, j) = ((k / w) as isize, (k % w) as isize);
            for &(di, dj, c) in &fwd {
                let (di, dj) = if pass == 0 { (di, dj) } else { (-di, -dj) };
                let (ii, jj) = (i + di, j + dj);
                if ii >= 0 && jj >= 0 && (ii as usize) < h && (jj as usize) < w {
                    let v = d[ii as usize * w + jj as usize] + c;
                    if v < d[k] {
                        d[k] = v;
                    }
                }
            }
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hf(w: usize, h: usize, f: impl Fn(usize, usize) -> f32) -> Heightfield {
        Heightfield::from_fn(w, h, 30.0, 30.0, f)
    }

    /// SRTM's coast: a flat 0 m sea west of land rising 2 m per 30 m cell (6.7 %). The floor
    /// continues the coast's slope under the water and levels out at a tenth of the relief;
    /// land is untouched. A sea with bathymetry keeps its floor.
    #[test]
    fn a_flat_sea_gets_a_floor_continuing_the_coast() {
        let d = hf(
            60,
            20,
            |x, _| {
                if x < 40 { 0.0 } else { (x - 39) as f32 * 2.0 }
            },
        );
        let sea = detect_sea(&d).unwrap();
        let (floor, bed) = seabed(&d, &sea, 400.0).unwrap();
        assert_eq!(bed.cells, 40 * 20);
        assert!((bed.shore_slope - 2.0 / 30.0).abs() < 0.02, "{bed:?}");
        assert_eq!(bed.depth_m, 40.0);
        for y in 0..20 {
            // Deeper with every cell offshore, under the level, above the limit.
            let mut last = 0.0;
            for x in (0..40).rev() {
                let z = floor.get(x, y);
                assert!(z < last && z > -40.0, "({x}, {y}): {z} after {last}");
                last = z;
            }
            // The first cell off the coast: the coast's slope over one cell.
            let first = -floor.get(39, y);
            assert!((first - 30.0 * bed.shore_slope).abs() < 0.2, "{first}");
            for x in 40..60 {
                assert_eq!(floor.get(x, y), d.get(x, y));
            }
        }
        assert!((bed.deepest_m - -floor.get(0, 10)).abs() < 1e-3);
        // A sea whose floor is already surveyed (below 0 m, varied): no floor is made.
        let bathy = hf(40, 30, |x, y| x as f32 * 10.0 - 100.0 + y as f32);
        let s = detect_sea(&bathy).unwrap();
        assert!(seabed(&bathy, &s, 400.0).is_none());
    }

    #[test]
    fn a_coast_at_zero_is_sea() {
        // Sea (0 m) on the western 10 columns, land rising to the east.
        let d = hf(
            40,
            30,
            |x, _| if x < 10 { 0.0 } else { (x - 9) as f32 * 5.0 },
        );
        let s = detect_sea(&d).unwrap();
        assert_eq!((s.level, s.kind, s.cells), (0.0, SeaKind::Zero, 300));
        assert!((s.share - 0.25).abs() < 1e-6);
    }

    #[test]
    fn bathymetry_below_zero_is_sea_at_zero() {
        let d = hf(32, 32, |x, y| x as f32 * 10.0 - 100.0 + y as f32);
        let s = detect_sea(&d).unwrap();
        assert_eq!((s.level, s.kind), (0.0, SeaKind::Zero));
        assert!(s.share > 0.2, "{s:?}");
    }

    #[test]
    fn an_enclosed_depression_is_not_sea() {
        // A bowl below 0 m in the middle, ringed by land that touches every border.
        let d = hf(32, 32, |x, y| {
            let r = ((x as f32 - 15.5).powi(2) + (y as f32 - 15.5).powi(2)).sqrt();
            if r < 8.0 { -20.0 } else { 50.0 + r }
        });
        assert_eq!(detect_sea(&d), None);
        assert!(!border_connected_at_or_below(&d, 0.0).contains(&true));
    }

    #[test]
    fn an_inland_dem_has_no_sea() {
        // A canyon (valley floor reaching the border) in a plateau, all above 0 m.
        let d = hf(48, 48, |x, y| {
            500.0 + (x as f32 - 24.0).abs() * 20.0 + (y as f32 * 0.7).sin() * 3.0
        });
        assert_eq!(detect_sea(&d), None);
    }

    #[test]
    fn a_small_patch_at_zero_is_not_sea() {
        // 12 samples at 0 m on the border of a 40 x 40 DEM: 0.75 %, under 2 %.
        let d = hf(40, 40, |x, y| {
            if x < 3 && y < 4 {
                0.0
            } else {
                10.0 + x as f32 + y as f32
            }
        });
        assert_eq!(detect_sea(&d), None);
        // The same on an 8 x 8 DEM is over 2 % but under 16 samples.
        let d = hf(8, 8, |x, y| if x < 3 && y < 4 { 0.0 } else { 10.0 });
        assert_eq!(detect_sea(&d), None);
    }

    #[test]
    fn a_flat_lake_surface_without_zero_is_sea_at_its_level() {
        // A lake at exactly 372 m on the southern third, hills above; no sample at 0 m.
        let d = hf(30, 30, |x, y| {
            if y >= 20 {
                372.0
            } else {
                380.0 + (20 - y) as f32 * 4.0 + (x % 5) as f32
            }
        });
        let s = detect_sea(&d).unwrap();
        assert_eq!(
            (s.level, s.kind, s.cells),
            (372.0, SeaKind::FlatMinimum, 300)
        );
        // A valley whose lowest value is a single sample is no lake.
        let d = hf(30, 30, |x, y| {
            372.0 + (x as f32 - 15.0).abs() + y as f32 * 0.5
        });
        assert_eq!(detect_sea(&d), None);
    }

    /// A lake surface with +-0.3 m of hashed speckle (no two samples equal, as on unflattened
    /// SRTM water): flat within the noise, so sea at its median level; a valley whose floor
    /// rises 2 m per sample stays no sea.
    #[test]
    fn a_noisy_lake_surface_is_sea_at_its_median_level() {
        let noise = |x: usize, y: usize| {
            let h = crate::math::hash(5, x as u64, y as u64, 0);
            crate::math::unit(h) * 0.6 - 0.3
        };
        let d = hf(40, 40, |x, y| {
            if y >= 26 {
                372.0 + noise(x, y)
            } else {
                380.0 + (26 - y) as f32 * 4.0 + (x % 5) as f32 + noise(x, y)
            }
        });
        assert!((sea_flat_tolerance(&d) - SEA_FLAT_NOISE_M).abs() < 1e-6);
        let s = detect_sea(&d).unwrap();
        assert_eq!((s.kind, s.cells), (SeaKind::FlatMinimum, 14 * 40));
        assert!((s.level - 372.0).abs() < 0.1, "{s:?}");
        // Integer metres: the lake stored as 372 and 373 is still flat (quantum 1 m).
        let d = hf(40, 40, |x, y| {
            if y >= 26 {
                372.0 + ((x + y) % 2) as f32
            } else {
                380.0 + (26 - y) as f32 * 4.0 + (x % 5) as f32
            }
        });
        assert_eq!(sea_flat_tolerance(&d), 1.5);
        assert_eq!(detect_sea(&d).unwrap().cells, 14 * 40);
        let d = hf(40, 40, |x, y| {
            372.0 + (x as f32 - 20.0).abs() * 2.0 + y as f32 * 0.5 + noise(x, y)
        });
        assert_eq!(detect_sea(&d), None);
    }

    #[test]
    fn voids_block_the_fill_and_are_never_sea() {
        let mut v: Vec<f32> = (0..20 * 20)
            .map(|k| if k % 20 < 10 { 0.0 } else { 30.0 })
            .collect();
        // A column of voids between the border column and the rest of the sea.
        for i in 0..20 {
            v[i * 20 + 1] = f32::NAN;
        }
        let d = Heightfield::new(20, 20, v, 30.0, 30.0).unwrap();
        let m = border_connected_at_or_below(&d, 0.0);
        // The western border column, and the rest through the top and bottom rows.
        assert!(m[0] && !m[1] && m[5 * 20 + 5]);
        assert_eq!(detect_sea(&d).unwrap().cells, 20 * 10 - 20);
    }
}
