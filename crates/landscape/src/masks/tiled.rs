//! The masks of a DEM cut into tiles (`relief tile plan -- masks`), equal bit for bit to
//! [`MasksSettings::run`] on the whole DEM with D8 routing:
//!
//! * every mask of a cell depends on the cell, its eight neighbours (the derivatives: a tile's
//!   one-cell margin holds them, [`tile_derivatives`]), its drainage area and HAND (the tiled
//!   drainage of [`crate::flow::tiled`]), and two statistics of the whole map ([`MaskScales`]):
//!   the height-band limits (quartiles of the valid heights, unless given) and the splat map's
//!   profile-curvature scale (95th percentile of `|profile curvature|`);
//! * those statistics are order statistics, found exactly in two passes over the tiles
//!   without holding the map: [`ScaleCounts`] counts each tile's values by the high 16 bits of
//!   their order key (`f32::total_cmp` order), which locates the bin that holds each wanted
//!   rank ([`ScaleCounts::targets`]); [`ScaleFine`] then counts the values of those bins by the
//!   low 16 bits, which gives the value itself ([`ScaleFine::scales`]). A pass holds 65536
//!   counts per statistic, whatever the map's size.

use crate::flow::tiled::TileLayout;
use crate::grid::Grid;
use crate::masks::{
    BAND_QUANTILES, Derivatives, MaskScales, MasksSettings, PROFILE_QUANTILE, band_rank,
    derivatives, profile_rank,
};
use crate::{LandscapeError, Result};

const BINS: usize = 1 << 16;

/// The order key of `v`: `a.total_cmp(&b) == key(a).cmp(&key(b))`.
pub fn order_key(v: f32) -> u32 {
    let b = v.to_bits();
    if b >> 31 == 1 { !b } else { b | 0x8000_0000 }
}

/// The value of an order key ([`order_key`]'s inverse).
pub fn from_order_key(k: u32) -> f32 {
    f32::from_bits(if k >> 31 == 1 { k & 0x7fff_ffff } else { !k })
}

fn bad(msg: impl Into<String>) -> LandscapeError {
    LandscapeError::InvalidInput(msg.into())
}

/// A count table's non-zero bins, `(bin, count)` in increasing bin order (the byte forms).
type Sparse = Vec<(u32, u64)>;

fn sparse(v: &[u64]) -> Sparse {
    v.iter()
        .enumerate()
        .filter(|(_, c)| **c > 0)
        .map(|(b, &c)| (b as u32, c))
        .collect()
}

/// The table of `s` (bins increasing, each below 65536).
fn dense(s: &[(u32, u64)], what: &str) -> Result<Vec<u64>> {
    let mut v = vec![0; BINS];
    let mut last = None;
    for &(b, c) in s {
        if b as usize >= BINS || last.is_some_and(|l| l >= b) {
            return Err(bad(format!("{what}: bins out of order or range")));
        }
        last = Some(b);
        v[b as usize] = c;
    }
    Ok(v)
}

fn decode<T: serde::de::DeserializeOwned>(b: &[u8], what: &str) -> Result<T> {
    serde_json::from_slice(b).map_err(|e| bad(format!("{what}: {e}")))
}

/// Slope, profile and plan curvature of tile `t` from its input (the tile and its one-cell
/// margin, `(w + 2) x (h + 2)` row-major, margin cells outside the map `NaN` or anything):
/// the values [`derivatives`] gives those cells on the whole map, bit for bit. Outside the
/// map the margin takes the nearest cell of the map, as the whole-map run's edge clamp does.
pub fn tile_derivatives(layout: &TileLayout, t: usize, input: &[f32]) -> Result<Derivatives> {
    layout.check_tile(t)?;
    let [x, y, w, h] = layout.window(t);
    let (pw, ph) = (w + 2, h + 2);
    if input.len() != pw * ph {
        return Err(bad(format!(
            "tile {t}: the input holds {} cells, not the {pw} x {ph} of the tile and its margin",
            input.len()
        )));
    }
    let mut p = input.to_vec();
    // Columns first, then rows: a corner takes the map's corner cell, as a clamp of both
    // coordinates does.
    for r in 0..ph {
        if x == 0 {
            p[r * pw] = p[r * pw + 1];
        }
        if x + w == layout.width {
            p[r * pw + pw - 1] = p[r * pw + pw - 2];
        }
    }
    if y == 0 {
        p.copy_within(pw..2 * pw, 0);
    }
    if y + h == layout.height {
        p.copy_within((ph - 2) * pw..(ph - 1) * pw, (ph - 1) * pw);
    }
    let g = Grid::new(pw, ph, layout.cell_x, layout.cell_y);
    let (s, pr, pl) = derivatives(&p, &g);
    let inner = |v: Vec<f32>| -> Vec<f32> {
        (0..h)
            .flat_map(|r| v[(r + 1) * pw + 1..(r + 1) * pw + 1 + w].to_vec())
            .collect()
    };
    Ok(Derivatives {
        slope: inner(s),
        profile: inner(pr),
        plan: inner(pl),
    })
}

/// The tile's own heights (its input without the margin).
pub fn tile_heights(layout: &TileLayout, t: usize, input: &[f32]) -> Result<Vec<f32>> {
    layout.check_tile(t)?;
    let [_, _, w, h] = layout.window(t);
    let pw = w + 2;
    if input.len() != pw * (h + 2) {
        return Err(bad(format!(
            "tile {t}: the input is not the tile and its margin"
        )));
    }
    Ok((0..h)
        .flat_map(|r| input[(r + 1) * pw + 1..(r + 1) * pw + 1 + w].to_vec())
        .collect())
}

/// Which values a statistic is taken over.
fn heights(z: &[f32]) -> impl Iterator<Item = f32> + '_ {
    z.iter().copied().filter(|v| !v.is_nan())
}

fn abs_profile(p: &[f32]) -> impl Iterator<Item = f32> + '_ {
    p.iter().filter(|v| v.is_finite()).map(|v| v.abs())
}

/// First pass of the map's [`MaskScales`]: counts of a tile's (or several tiles') valid
/// heights and finite `|profile curvature|` by the high 16 bits of their order key.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleCounts {
    heights: Vec<u64>,
    profile: Vec<u64>,
}

impl ScaleCounts {
    /// No value counted.
    pub fn empty() -> Self {
        Self {
            heights: vec![0; BINS],
            profile: vec![0; BINS],
        }
    }

    /// The counts of tile `t` (its input with the one-cell margin).
    pub fn of_tile(layout: &TileLayout, t: usize, input: &[f32]) -> Result<Self> {
        let d = tile_derivatives(layout, t, input)?;
        let z = tile_heights(layout, t, input)?;
        let mut c = Self::empty();
        for v in heights(&z) {
            c.heights[(order_key(v) >> 16) as usize] += 1;
        }
        for v in abs_profile(&d.profile) {
            c.profile[(order_key(v) >> 16) as usize] += 1;
        }
        Ok(c)
    }

    /// The counts as bytes (JSON of the non-zero bins), for a task graph to move.
    pub fn to_bytes(&self) -> Vec<u8> {
        serde_json::to_vec(&(sparse(&self.heights), sparse(&self.profile))).unwrap_or_default()
    }

    /// The counts of [`ScaleCounts::to_bytes`], checked.
    pub fn from_bytes(b: &[u8]) -> Result<Self> {
        let (h, p): (Sparse, Sparse) = decode(b, "scale counts")?;
        Ok(Self {
            heights: dense(&h, "scale counts")?,
            profile: dense(&p, "scale counts")?,
        })
    }

    /// Adds `other`'s counts.
    pub fn merge(&mut self, other: &Self) {
        for (a, b) in self.heights.iter_mut().zip(&other.heights) {
            *a += b;
        }
        for (a, b) in self.profile.iter_mut().zip(&other.profile) {
            *a += b;
        }
    }

    /// The bins and ranks within them of the statistics `settings` needs (the height
    /// quartiles unless it gives the bands, and the profile scale); an error when the map has
    /// no valid height.
    pub fn targets(&self, settings: &MasksSettings) -> Result<ScaleTargets> {
        let n: u64 = self.heights.iter().sum();
        if n == 0 {
            return Err(bad("the DEM has no valid cell"));
        }
        let heights = if settings.height_bands.is_empty() {
            BAND_QUANTILES
                .iter()
                .map(|&q| locate(&self.heights, band_rank(n, q)))
                .collect()
        } else {
            Vec::new()
        };
        let np: u64 = self.profile.iter().sum();
        let profile = (np > 0).then(|| locate(&self.profile, profile_rank(np, PROFILE_QUANTILE)));
        Ok(ScaleTargets {
            bands: settings.height_bands.clone(),
            heights,
            profile,
        })
    }
}

/// The bin holding rank `k` and the rank within it.
fn locate(counts: &[u64], mut k: u64) -> (u32, u64) {
    for (b, &c) in counts.iter().enumerate() {
        if k < c {
            return (b as u32, k);
        }
        k -= c;
    }
    // Unreachable for k below the total; the last bin otherwise.
    (BINS as u32 - 1, 0)
}

/// The bins (high 16 bits of the order key) and ranks within them of the wanted statistics.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScaleTargets {
    bands: Vec<f64>,
    heights: Vec<(u32, u64)>,
    profile: Option<(u32, u64)>,
}

/// Second pass of the map's [`MaskScales`]: counts of the values in the target bins by the low
/// 16 bits of their order key.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleFine {
    heights: Vec<Vec<u64>>,
    profile: Vec<u64>,
}

impl ScaleTargets {
    /// The targets as bytes (JSON).
    pub fn to_bytes(&self) -> Vec<u8> {
        serde_json::to_vec(self).unwrap_or_default()
    }

    /// The targets of [`ScaleTargets::to_bytes`], checked.
    pub fn from_bytes(b: &[u8]) -> Result<Self> {
        let t: Self = decode(b, "scale targets")?;
        let bins_ok = t
            .heights
            .iter()
            .chain(&t.profile)
            .all(|&(b, _)| (b as usize) < BINS);
        if !bins_ok || t.heights.len() > BAND_QUANTILES.len() {
            return Err(bad("scale targets: bins out of range"));
        }
        Ok(t)
    }
}

impl ScaleFine {
    /// The counts as bytes (JSON of the non-zero bins).
    pub fn to_bytes(&self) -> Vec<u8> {
        let h: Vec<Sparse> = self.heights.iter().map(|v| sparse(v)).collect();
        serde_json::to_vec(&(h, sparse(&self.profile))).unwrap_or_default()
    }

    /// The counts of [`ScaleFine::to_bytes`] for `targets`, checked.
    pub fn from_bytes(b: &[u8], targets: &ScaleTargets) -> Result<Self> {
        let (h, p): (Vec<Sparse>, Sparse) = decode(b, "scale counts")?;
        if h.len() != targets.heights.len() || (targets.profile.is_none() && !p.is_empty()) {
            return Err(bad("scale counts: not those of these targets"));
        }
        Ok(Self {
            heights: h
                .iter()
                .map(|v| dense(v, "scale counts"))
                .collect::<Result<_>>()?,
            profile: if targets.profile.is_some() {
                dense(&p, "scale counts")?
            } else {
                Vec::new()
            },
        })
    }

    /// No value counted, for `targets`.
    pub fn empty(targets: &ScaleTargets) -> Self {
        Self {
            heights: vec![vec![0; BINS]; targets.heights.len()],
            profile: vec![0; if targets.profile.is_some() { BINS } else { 0 }],
        }
    }

    /// The counts of tile `t` (its input with the one-cell margin).
    pub fn of_tile(
        layout: &TileLayout,
        t: usize,
        input: &[f32],
        targets: &ScaleTargets,
    ) -> Result<Self> {
        let mut f = Self::empty(targets);
        let z = tile_heights(layout, t, input)?;
        for v in heights(&z) {
            let k = order_key(v);
            for (i, &(bin, _)) in targets.heights.iter().enumerate() {
                if k >> 16 == bin {
                    f.heights[i][(k & 0xffff) as usize] += 1;
                }
            }
        }
        if let Some((bin, _)) = targets.profile {
            let d = tile_derivatives(layout, t, input)?;
            for v in abs_profile(&d.profile) {
                let k = order_key(v);
                if k >> 16 == bin {
                    f.profile[(k & 0xffff) as usize] += 1;
                }
            }
        }
        Ok(f)
    }

    /// Adds `other`'s counts.
    pub fn merge(&mut self, other: &Self) {
        for (a, b) in self.heights.iter_mut().zip(&other.heights) {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        }
        self.profile
            .iter_mut()
            .zip(&other.profile)
            .for_each(|(x, y)| *x += y);
    }

    /// The map's statistics: the values at the targets' ranks.
    pub fn scales(&self, targets: &ScaleTargets) -> MaskScales {
        let value = |bin: u32, fine: &[u64], rank: u64| -> f32 {
            let (low, _) = locate(fine, rank);
            from_order_key(bin << 16 | low)
        };
        let bands = if targets.heights.is_empty() {
            targets.bands.clone()
        } else {
            targets
                .heights
                .iter()
                .zip(&self.heights)
                .map(|(&(bin, rank), fine)| value(bin, fine, rank) as f64)
                .collect()
        };
        let profile_scale = targets
            .profile
            .map_or(0.0, |(bin, rank)| value(bin, &self.profile, rank) as f64);
        MaskScales {
            bands,
            profile_scale,
        }
    }
}

/// The masks and splat weights of tile `t` ([`MasksSettings::assemble`]) from its input (the
/// tile and its one-cell margin), the cells upstream of each of its cells along the D8
/// directions (the tiled drainage's `Finished::cells`), its HAND (m) and the map's
/// [`MaskScales`]: the whole run's values of these cells, bit for bit. D8 routing only (the
/// tiled drainage is D8's).
#[allow(clippy::type_complexity)]
pub fn tile_masks(
    settings: &MasksSettings,
    layout: &TileLayout,
    t: usize,
    input: &[f32],
    cells: &[u64],
    hand: Vec<f32>,
    scales: &MaskScales,
) -> Result<(Vec<crate::masks::Mask>, Vec<[f32; 4]>)> {
    if settings.flow.directions != crate::flow::Directions::D8 {
        return Err(bad(
            "tiled masks route D8 only (the tiled drainage area is D8's)",
        ));
    }
    let d = tile_derivatives(layout, t, input)?;
    let z = tile_heights(layout, t, input)?;
    if cells.len() != z.len() || hand.len() != z.len() {
        return Err(bad(format!(
            "tile {t}: the drainage rasters do not hold the tile's {} cells",
            z.len()
        )));
    }
    let a0 = layout.cell_x * layout.cell_y;
    let area: Vec<f64> = z
        .iter()
        .zip(cells)
        .map(|(v, &n)| if v.is_nan() { f64::NAN } else { n as f64 * a0 })
        .collect();
    Ok(settings.assemble(
        d,
        &area,
        hand,
        (layout.cell_x, layout.cell_y),
        &z,
        scales,
        (None, None),
    ))
}

#[cfg(test)]
mod tests {
    use relief_heightfield::{Heightfield, NoProgress};

    use super::*;
    use crate::masks::MaskKind;

    #[test]
    fn order_keys_follow_total_cmp() {
        let v = [
            f32::NEG_INFINITY,
            -3.5,
            -1e-30,
            -0.0,
            0.0,
            1e-30,
            2.0,
            7e5,
            f32::INFINITY,
        ];
        for a in v {
            assert_eq!(from_order_key(order_key(a)).to_bits(), a.to_bits());
            for b in v {
                assert_eq!(a.total_cmp(&b), order_key(a).cmp(&order_key(b)), "{a} {b}");
            }
        }
    }

    /// A rough DEM with voids, ties and a non-square cell, cut into tiles of 8 with their
    /// margins as `relief tile plan` cuts them (`NaN` outside the map).
    fn dem() -> Heightfield {
        Heightfield::from_fn(21, 18, 30.0, 42.5, |x, y| {
            if (x + 2 * y) % 17 == 3 {
                f32::NAN
            } else {
                ((x * 7919 + y * 104729) % 23) as f32 * 3.5 + (x as f32) * 1.25
                    - (y as f32).powi(2) * 0.5
            }
        })
    }

    /// [`dem`]'s grid in tiles of 8.
    fn layout() -> TileLayout {
        TileLayout {
            width: 21,
            height: 18,
            tile: 8,
            cell_x: 30.0,
            cell_y: 42.5,
        }
    }

    fn input(hf: &Heightfield, l: &TileLayout, t: usize) -> Vec<f32> {
        let [x, y, w, h] = l.window(t);
        let mut v = Vec::with_capacity((w + 2) * (h + 2));
        for yy in y as isize - 1..=(y + h) as isize {
            for xx in x as isize - 1..=(x + w) as isize {
                let inside = (0..hf.width() as isize).contains(&xx)
                    && (0..hf.height() as isize).contains(&yy);
                v.push(if inside {
                    hf.get(xx as usize, yy as usize)
                } else {
                    f32::NAN
                });
            }
        }
        v
    }

    #[test]
    fn tiled_derivatives_and_scales_equal_the_whole_run() {
        let hf = dem();
        let l = layout();
        let whole = derivatives(hf.as_slice(), &Grid::of(&hf));
        let settings = MasksSettings::default();
        let mut counts = ScaleCounts::empty();
        for t in 0..l.tasks() {
            let i = input(&hf, &l, t);
            let d = tile_derivatives(&l, t, &i).unwrap();
            let [x, y, w, h] = l.window(t);
            for r in 0..h {
                for c in 0..w {
                    let g = (y + r) * 21 + x + c;
                    let k = r * w + c;
                    assert_eq!(d.slope[k].to_bits(), whole.0[g].to_bits(), "slope {g}");
                    assert_eq!(d.profile[k].to_bits(), whole.1[g].to_bits(), "profile {g}");
                    assert_eq!(d.plan[k].to_bits(), whole.2[g].to_bits(), "plan {g}");
                }
            }
            // Through the byte forms a task graph moves.
            let c = ScaleCounts::of_tile(&l, t, &i).unwrap();
            counts.merge(&ScaleCounts::from_bytes(&c.to_bytes()).unwrap());
        }
        let targets = counts.targets(&settings).unwrap();
        let targets = ScaleTargets::from_bytes(&targets.to_bytes()).unwrap();
        let mut fine = ScaleFine::empty(&targets);
        for t in 0..l.tasks() {
            let f = ScaleFine::of_tile(&l, t, &input(&hf, &l, t), &targets).unwrap();
            fine.merge(&ScaleFine::from_bytes(&f.to_bytes(), &targets).unwrap());
        }
        assert!(ScaleCounts::from_bytes(b"[[[70000,1]],[]]").is_err());
        assert!(ScaleCounts::from_bytes(b"[[[5,1],[5,2]],[]]").is_err());
        assert!(ScaleFine::from_bytes(b"[[],[]]", &targets).is_err());
        let scales = fine.scales(&targets);
        let m = settings.run(&hf, None, None, &NoProgress).unwrap();
        assert_eq!(scales.bands, m.bands);
        assert_eq!(
            scales.profile_scale,
            crate::masks::percentile_abs(&whole.1, PROFILE_QUANTILE)
        );
        assert!(scales.profile_scale > 0.0);
        // The band mask of the whole run follows these limits.
        let band = &m
            .rasters
            .iter()
            .find(|r| r.0 == MaskKind::HeightBand)
            .unwrap()
            .1;
        let top = band.as_slice().iter().filter(|&&b| b == 3.0).count();
        let valid = hf.as_slice().iter().filter(|v| !v.is_nan()).count();
        assert!(top > 0 && top <= valid / 4 + 1, "{top} of {valid}");
    }

    #[test]
    fn tile_masks_equal_the_whole_run() {
        let hf = dem();
        let l = layout();
        let settings = MasksSettings::default();
        let m = settings.run(&hf, None, None, &NoProgress).unwrap();
        let r = crate::flow::route(
            hf.as_slice().to_vec(),
            Grid::of(&hf),
            &settings.flow.route_options(),
        );
        let cells = r.cells_upstream();
        let hand = crate::flow::basins::hand(&r, &r.area_d8(), settings.flow.channel_area);
        let whole_prof = &m.rasters[1].1;
        let scales = MaskScales {
            bands: m.bands.clone(),
            profile_scale: crate::masks::percentile_abs(whole_prof.as_slice(), PROFILE_QUANTILE),
        };
        let splat = crate::masks::splat_rgba8(&m.splat);
        for t in 0..l.tasks() {
            let [x, y, w, h] = l.window(t);
            let crop = |v: &[u64]| -> Vec<u64> {
                (0..h)
                    .flat_map(|r| v[(y + r) * 21 + x..(y + r) * 21 + x + w].to_vec())
                    .collect()
            };
            let hand_t: Vec<f32> = (0..h)
                .flat_map(|r| hand[(y + r) * 21 + x..(y + r) * 21 + x + w].to_vec())
                .collect();
            let (masks, sp) = tile_masks(
                &settings,
                &l,
                t,
                &input(&hf, &l, t),
                &crop(&cells),
                hand_t,
                &scales,
            )
            .unwrap();
            assert_eq!(masks.len(), m.rasters.len());
            for (tm, (kind, whole)) in masks.iter().zip(&m.rasters) {
                assert_eq!(tm.kind, *kind);
                for r in 0..h {
                    for c in 0..w {
                        let (a, b) = (tm.values[r * w + c], whole.get(x + c, y + r));
                        assert_eq!(a.to_bits(), b.to_bits(), "{kind:?} tile {t} ({c}, {r})");
                    }
                }
            }
            let tile_rgba = crate::masks::splat_rgba8(&sp);
            for r in 0..h {
                let g = ((y + r) * 21 + x) * 4;
                assert_eq!(&tile_rgba[r * w * 4..(r + 1) * w * 4], &splat[g..g + w * 4]);
            }
        }
    }

    #[test]
    fn given_bands_are_kept_and_an_empty_map_is_refused() {
        let s = MasksSettings {
            height_bands: vec![1.0, 2.0],
            ..Default::default()
        };
        let l = TileLayout {
            width: 4,
            height: 4,
            tile: 4,
            cell_x: 1.0,
            cell_y: 1.0,
        };
        let i = vec![5.0; 36];
        let c = ScaleCounts::of_tile(&l, 0, &i).unwrap();
        let t = c.targets(&s).unwrap();
        let f = ScaleFine::of_tile(&l, 0, &i, &t).unwrap();
        assert_eq!(f.scales(&t).bands, vec![1.0, 2.0]);
        let voids = ScaleCounts::of_tile(&l, 0, &[f32::NAN; 36]).unwrap();
        assert!(voids.targets(&s).is_err());
        assert!(tile_derivatives(&l, 0, &[0.0; 10]).is_err());
    }
}
