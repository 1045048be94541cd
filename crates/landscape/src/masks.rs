//! Masks and splat maps for texturing: slope, profile and plan curvature, drainage area (log),
//! the topographic wetness index, height above the nearest drainage, height bands, and the
//! erosion and deposition depths of an erosion run; and a splat map that packs four weights
//! per cell (RGBA, summing to 1), the convention of World Creator, Terrain3D and Unity terrain
//! layers.
//!
//! Every mask is computed in physical units (degrees, 1/m, m^2, metres) and has a documented
//! normalisation to `[0, 1]` ([`Mask::normalised`]) for 8/16-bit images.

use relief_heightfield::param::in_range;
use relief_heightfield::{Heightfield, ParamError, Progress};
use serde::{Deserialize, Serialize};

use crate::flow::job::FlowSettings;
use crate::flow::{self, basins};
use crate::grid::Grid;
use crate::{LandscapeError, Result};

pub mod tiled;

/// Settings of `relief masks`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MasksSettings {
    /// Routing of the drainage masks (area, wetness, HAND).
    pub flow: FlowSettings,
    /// Upper limits (m) of the height bands; empty: the quartiles of the DEM.
    pub height_bands: Vec<f64>,
    /// Slope (degrees) from which the splat map's rock layer takes over.
    pub rock_slope: f64,
    /// Wetness index from which the splat map's wet layer takes over.
    pub wet_index: f64,
}

impl Default for MasksSettings {
    fn default() -> Self {
        Self {
            flow: FlowSettings::default(),
            height_bands: Vec::new(),
            rock_slope: 35.0,
            wet_index: 10.0,
        }
    }
}

impl MasksSettings {
    /// Checks every field.
    pub fn check(&self) -> std::result::Result<(), ParamError> {
        self.flow.check()?;
        in_range(
            "rock_slope",
            self.rock_slope,
            1.0..=89.0,
            "must be in [1, 89] degrees",
        )?;
        in_range(
            "wet_index",
            self.wet_index,
            0.0..=50.0,
            "must be in [0, 50]",
        )?;
        for w in self.height_bands.windows(2) {
            relief_heightfield::param::ensure(
                w[0] < w[1],
                "height_bands",
                format!("{:?}", self.height_bands),
                "must increase",
            )?;
        }
        for &b in &self.height_bands {
            in_range(
                "height_bands",
                b,
                -1e5..=1e5,
                "must be finite heights in metres",
            )?;
        }
        Ok(())
    }

    /// Computes every mask of `dem`; `erosion` and `deposition` (metres, from an erosion run on
    /// the same grid) add their masks and feed the splat map's deposition layer.
    pub fn run(
        &self,
        dem: &Heightfield,
        erosion: Option<&Heightfield>,
        deposition: Option<&Heightfield>,
        progress: &dyn Progress,
    ) -> Result<Masks> {
        self.check()?;
        for (name, r) in [("erosion", erosion), ("deposition", deposition)] {
            if let Some(r) = r.filter(|r| (r.width(), r.height()) != (dem.width(), dem.height())) {
                return Err(LandscapeError::InvalidInput(format!(
                    "the {name} raster is {}x{}, the DEM {}x{}",
                    r.width(),
                    r.height(),
                    dem.width(),
                    dem.height()
                )));
            }
        }
        let g = Grid::of(dem);
        let z = dem.as_slice();
        if z.iter().all(|v| v.is_nan()) {
            return Err(LandscapeError::InvalidInput(
                "the DEM has no valid cell".into(),
            ));
        }
        progress.begin("masks", 3);
        let (slope, profile, plan) = derivatives(z, &g);
        progress.advance(1);
        let r = flow::route(z.to_vec(), g, &self.flow.route_options());
        // D8 area is counted in cells and multiplied by the cell area once, as `relief flow`
        // does: the same bits whatever order the sums are made in (the tiled plan makes them
        // tile by tile).
        let d8 = r.area_d8();
        let area = match self.flow.directions {
            flow::Directions::D8 => d8.clone(),
            flow::Directions::Mfd => r.accumulation_mfd(self.flow.mfd_exponent),
        };
        let hand = basins::hand(&r, &d8, self.flow.channel_area);
        progress.advance(1);
        let scales = MaskScales {
            bands: self.bands(dem),
            profile_scale: percentile_abs(&profile, PROFILE_QUANTILE),
        };
        let (masks, splat) = self.assemble(
            Derivatives {
                slope,
                profile,
                plan,
            },
            &area,
            hand,
            dem.cell_size(),
            z,
            &scales,
            (
                erosion.map(|e| e.as_slice()),
                deposition.map(|d| d.as_slice()),
            ),
        );
        progress.advance(1);
        let georef = dem.georef().cloned();
        let rasters = masks
            .into_iter()
            .map(|m| Ok((m.kind, dem.with_data(m.values)?.with_georef(georef.clone()))))
            .collect::<Result<Vec<_>>>()?;
        Ok(Masks {
            rasters,
            splat,
            bands: scales.bands,
        })
    }

    /// The masks and splat weights of some cells from their derivatives, drainage area (m^2),
    /// HAND (m), heights `z`, the map's global [`MaskScales`] and the erosion and deposition
    /// depths: every value depends on its own cell only, so a tile's masks are the map's
    /// (`masks::tiled`). `cell` is the cell size (m).
    #[allow(clippy::too_many_arguments)]
    pub fn assemble(
        &self,
        d: Derivatives,
        area: &[f64],
        hand: Vec<f32>,
        cell: (f64, f64),
        z: &[f32],
        scales: &MaskScales,
        (erosion, deposition): (Option<&[f32]>, Option<&[f32]>),
    ) -> (Vec<Mask>, Vec<[f32; 4]>) {
        let width = (cell.0 * cell.1).sqrt();
        let slope = &d.slope;
        let wetness: Vec<f32> = (0..z.len())
            .map(|i| {
                let tan = (slope[i] as f64).to_radians().tan().max(1e-3);
                ((area[i] / width) / tan).ln() as f32
            })
            .collect();
        let log_area: Vec<f32> = area.iter().map(|&a| a.log10() as f32).collect();
        let band: Vec<f32> = z
            .iter()
            .map(|&v| {
                if v.is_nan() {
                    f32::NAN
                } else {
                    scales.bands.iter().filter(|&&b| (v as f64) > b).count() as f32
                }
            })
            .collect();
        let mut masks = vec![
            Mask::new(MaskKind::Slope, d.slope),
            Mask::new(MaskKind::ProfileCurvature, d.profile),
            Mask::new(MaskKind::PlanCurvature, d.plan),
            Mask::new(MaskKind::Area, log_area),
            Mask::new(MaskKind::Wetness, wetness),
            Mask::new(MaskKind::Hand, hand),
            Mask::new(MaskKind::HeightBand, band),
        ];
        if let Some(e) = erosion {
            masks.push(Mask::new(MaskKind::Erosion, e.to_vec()));
        }
        if let Some(d) = deposition {
            masks.push(Mask::new(MaskKind::Deposition, d.to_vec()));
        }
        let splat = self.splat(&masks, deposition, scales.profile_scale);
        (masks, splat)
    }

    fn bands(&self, dem: &Heightfield) -> Vec<f64> {
        if !self.height_bands.is_empty() {
            return self.height_bands.clone();
        }
        let mut v: Vec<f32> = dem
            .as_slice()
            .iter()
            .copied()
            .filter(|v| !v.is_nan())
            .collect();
        v.sort_by(f32::total_cmp);
        BAND_QUANTILES
            .iter()
            .map(|&q| v[band_rank(v.len() as u64, q) as usize] as f64)
            .collect()
    }

    /// Four weights per cell, summing to 1: R ground (gentle, dry), G rock (slopes above
    /// `rock_slope`, blended over 10 degrees), B sediment (deposition, or gentle concave
    /// ground at the foot of slopes without an erosion run), A wet (wetness index above
    /// `wet_index`, blended over 2 units, and channels).
    fn splat(
        &self,
        masks: &[Mask],
        deposition: Option<&[f32]>,
        profile_scale: f64,
    ) -> Vec<[f32; 4]> {
        let get = |k: MaskKind| &masks.iter().find(|m| m.kind == k).expect("mask").values;
        let (slope, profile, wet) = (
            get(MaskKind::Slope),
            get(MaskKind::ProfileCurvature),
            get(MaskKind::Wetness),
        );
        let prof_scale = profile_scale.max(1e-9);
        (0..slope.len())
            .map(|i| {
                if slope[i].is_nan() {
                    return [0.0; 4];
                }
                let rock = smoothstep(
                    self.rock_slope - 5.0,
                    self.rock_slope + 5.0,
                    slope[i] as f64,
                );
                let wet_w = smoothstep(self.wet_index - 1.0, self.wet_index + 1.0, wet[i] as f64);
                let sed = match deposition {
                    Some(d) => smoothstep(0.05, 1.0, d[i] as f64),
                    None => {
                        smoothstep(0.0, 1.0, profile[i] as f64 / prof_scale)
                            * (1.0 - smoothstep(10.0, 25.0, slope[i] as f64))
                    }
                };
                // Layers claim what the ones above them left: wet over sediment over rock.
                let a = wet_w * (1.0 - rock);
                let b = sed * (1.0 - a) * (1.0 - rock);
                let g = rock;
                let r = (1.0 - a - b - g).max(0.0);
                let s = r + g + b + a;
                [
                    (r / s) as f32,
                    (g / s) as f32,
                    (b / s) as f32,
                    (a / s) as f32,
                ]
            })
            .collect()
    }
}

fn smoothstep(lo: f64, hi: f64, v: f64) -> f64 {
    let t = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

pub(crate) fn percentile_abs(v: &[f32], q: f64) -> f64 {
    let mut a: Vec<f32> = v
        .iter()
        .filter(|x| x.is_finite())
        .map(|x| x.abs())
        .collect();
    if a.is_empty() {
        return 0.0;
    }
    let k = profile_rank(a.len() as u64, q) as usize;
    *a.select_nth_unstable_by(k, f32::total_cmp).1 as f64
}

/// Quantiles of the valid heights that bound the default height bands (the quartiles).
pub const BAND_QUANTILES: [f64; 3] = [0.25, 0.5, 0.75];

/// Quantile of `|profile curvature|` (finite cells) that scales the splat map's sediment layer.
pub const PROFILE_QUANTILE: f64 = 0.95;

/// Rank (0-based, in `f32::total_cmp` order) of the height-band limit at quantile `q` of `n`
/// valid heights: `round((n - 1) q)`.
pub fn band_rank(n: u64, q: f64) -> u64 {
    ((n - 1) as f64 * q).round() as u64
}

/// Rank (0-based) of the profile-curvature scale at quantile `q` of `n` finite values:
/// `floor((n - 1) q)`.
pub fn profile_rank(n: u64, q: f64) -> u64 {
    ((n - 1) as f64 * q) as u64
}

/// The statistics of the whole map the masks of a cell depend on: the height-band limits and
/// the profile-curvature scale of the splat map's sediment layer. A tiled run computes them
/// exactly beforehand (`masks::tiled`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaskScales {
    /// Upper limits of the height bands (m).
    pub bands: Vec<f64>,
    /// The [`PROFILE_QUANTILE`] quantile of `|profile curvature|` (1/m).
    pub profile_scale: f64,
}

/// Slope (degrees), profile and plan curvature (1/m) of some cells ([`derivatives`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Derivatives {
    /// Slope angle (degrees).
    pub slope: Vec<f32>,
    /// Profile curvature (1/m).
    pub profile: Vec<f32>,
    /// Plan curvature (1/m).
    pub plan: Vec<f32>,
}

/// Slope (degrees), profile and plan curvature (1/m) by central differences (Zevenbergen and
/// Thorne 1987's second-order polynomial, non-square cells, edges mirrored): profile
/// curvature is the second derivative along the steepest descent (positive where the slope
/// flattens downhill, concave), plan curvature across it (positive in hollows where flow
/// converges, negative on noses and ridges); both 0 on flat ground.
pub fn derivatives(z: &[f32], g: &Grid) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let (w, h) = (g.width, g.height);
    let (dx, dy) = (g.cell_x, g.cell_y);
    let at = |x: isize, y: isize, c: f32| -> f64 {
        let v = z[(y.clamp(0, h as isize - 1) as usize) * w + x.clamp(0, w as isize - 1) as usize];
        if v.is_nan() { c as f64 } else { v as f64 }
    };
    let mut slope = vec![f32::NAN; g.len()];
    let mut profile = vec![f32::NAN; g.len()];
    let mut plan = vec![f32::NAN; g.len()];
    for i in 0..g.len() {
        let c = z[i];
        if c.is_nan() {
            continue;
        }
        let (x, y) = ((i % w) as isize, (i / w) as isize);
        let z0 = c as f64;
        let (e, wv) = (at(x + 1, y, c), at(x - 1, y, c));
        let (n, s) = (at(x, y - 1, c), at(x, y + 1, c));
        // x east, y north.
        let zx = (e - wv) / (2.0 * dx);
        let zy = (n - s) / (2.0 * dy);
        let zxx = (e - 2.0 * z0 + wv) / (dx * dx);
        let zyy = (n - 2.0 * z0 + s) / (dy * dy);
        let zxy = (at(x + 1, y - 1, c) - at(x - 1, y - 1, c) - at(x + 1, y + 1, c)
            + at(x - 1, y + 1, c))
            / (4.0 * dx * dy);
        let p = zx * zx + zy * zy;
        slope[i] = p.sqrt().atan().to_degrees() as f32;
        if p > 1e-12 {
            profile[i] = ((zxx * zx * zx + 2.0 * zxy * zx * zy + zyy * zy * zy) / p) as f32;
            plan[i] = ((zxx * zy * zy - 2.0 * zxy * zx * zy + zyy * zx * zx) / p) as f32;
        } else {
            profile[i] = 0.0;
            plan[i] = 0.0;
        }
    }
    (slope, profile, plan)
}

/// Which mask a raster is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MaskKind {
    /// Slope angle (degrees).
    Slope,
    /// Profile curvature (1/m).
    ProfileCurvature,
    /// Plan curvature (1/m).
    PlanCurvature,
    /// log10 of the drainage area (m^2).
    Area,
    /// Topographic wetness index `ln(a / tan b)` (Beven and Kirkby 1979), `a` the specific
    /// catchment area (m^2 per metre of contour, the cell's side), `tan b` at least 0.001.
    Wetness,
    /// Height above the nearest drainage (m).
    Hand,
    /// Height band index (0 = below the first limit).
    HeightBand,
    /// Erosion depth (m) of an erosion run.
    Erosion,
    /// Deposition depth (m) of an erosion run.
    Deposition,
}

impl MaskKind {
    /// File stem of the mask (`slope`, `profile_curvature`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::Slope => "slope",
            Self::ProfileCurvature => "profile_curvature",
            Self::PlanCurvature => "plan_curvature",
            Self::Area => "area",
            Self::Wetness => "wetness",
            Self::Hand => "hand",
            Self::HeightBand => "height_band",
            Self::Erosion => "erosion",
            Self::Deposition => "deposition",
        }
    }
}

/// One mask in physical units.
#[derive(Debug, Clone, PartialEq)]
pub struct Mask {
    /// Which mask.
    pub kind: MaskKind,
    /// Values per cell (`NaN` on voids).
    pub values: Vec<f32>,
}

impl Mask {
    fn new(kind: MaskKind, values: Vec<f32>) -> Self {
        Self { kind, values }
    }

    /// The mask in `[0, 1]` for images: slope / 90; curvatures `0.5 + v / (2 c)` with `c` the
    /// 99th percentile of `|v|`; area, wetness, HAND and depths linearly between their 1st and
    /// 99th percentiles; bands / (number of bands). Voids are 0.
    pub fn normalised(kind: MaskKind, values: &[f32], bands: usize) -> Vec<f32> {
        let finite: Vec<f32> = values.iter().copied().filter(|v| v.is_finite()).collect();
        let pct = |q: f64| -> f64 {
            if finite.is_empty() {
                return 0.0;
            }
            let mut a = finite.clone();
            let k = ((a.len() - 1) as f64 * q) as usize;
            *a.select_nth_unstable_by(k, f32::total_cmp).1 as f64
        };
        let f: Box<dyn Fn(f64) -> f64> = match kind {
            MaskKind::Slope => Box::new(|v| v / 90.0),
            MaskKind::ProfileCurvature | MaskKind::PlanCurvature => {
                let c = percentile_abs(values, 0.99).max(1e-12);
                Box::new(move |v| 0.5 + v / (2.0 * c))
            }
            MaskKind::HeightBand => {
                let n = bands.max(1) as f64;
                Box::new(move |v| v / n)
            }
            _ => {
                let (lo, hi) = (pct(0.01), pct(0.99));
                let span = (hi - lo).max(1e-12);
                Box::new(move |v| (v - lo) / span)
            }
        };
        values
            .iter()
            .map(|&v| {
                if v.is_finite() {
                    f(v as f64).clamp(0.0, 1.0) as f32
                } else {
                    0.0
                }
            })
            .collect()
    }
}

/// The masks of a DEM.
#[derive(Debug, Clone)]
pub struct Masks {
    /// Each mask as a raster on the DEM's grid and georeference (physical units).
    pub rasters: Vec<(MaskKind, Heightfield)>,
    /// The splat weights (ground, rock, sediment, wet), summing to 1 (0 on voids).
    pub splat: Vec<[f32; 4]>,
    /// Upper limits of the height bands (m).
    pub bands: Vec<f64>,
}

/// Quantises splat weights to 8-bit RGBA whose four channels sum to exactly 255 (largest
/// remainder), row-major.
pub fn splat_rgba8(splat: &[[f32; 4]]) -> Vec<u8> {
    let mut out = Vec::with_capacity(splat.len() * 4);
    for w in splat {
        let s: f32 = w.iter().sum();
        if s <= 0.0 {
            out.extend_from_slice(&[0, 0, 0, 0]);
            continue;
        }
        let scaled = w.map(|v| v / s * 255.0);
        let mut q = scaled.map(|v| v.floor() as u8);
        let mut left = 255 - q.iter().map(|&v| v as u32).sum::<u32>();
        let mut order = [0usize, 1, 2, 3];
        order.sort_by(|&a, &b| {
            (scaled[b] - q[b] as f32)
                .total_cmp(&(scaled[a] - q[a] as f32))
                .then(a.cmp(&b))
        });
        for &k in &order {
            if left == 0 {
                break;
            }
            q[k] += 1;
            left -= 1;
        }
        out.extend_from_slice(&q);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cone(w: usize, cell: f64) -> Heightfield {
        Heightfield::from_fn(w, w, cell, cell, |x, y| {
            let (dx, dy) = (x as f32 - w as f32 / 2.0, y as f32 - w as f32 / 2.0);
            500.0 - (dx * dx + dy * dy).sqrt() * 8.0
        })
    }

    #[test]
    fn slope_and_curvature_of_a_cone_and_a_bowl() {
        let hf = cone(41, 10.0);
        let (s, prof, plan) = derivatives(hf.as_slice(), &Grid::of(&hf));
        // 8 m per 10 m cell: atan(0.8) = 38.66 degrees, away from the apex.
        let i = 20 * 41 + 30;
        assert!((s[i] - 38.66).abs() < 0.3, "{}", s[i]);
        // A cone's flanks are straight downhill and divergent (a nose) across.
        assert!(
            prof[i].abs() < 1e-4 && plan[i] < 0.0,
            "{} {}",
            prof[i],
            plan[i]
        );
        let bowl = hf.map(|v| 1000.0 - v);
        let (_, _, plan) = derivatives(bowl.as_slice(), &Grid::of(&bowl));
        assert!(plan[i] > 0.0);
    }

    #[test]
    fn splat_weights_sum_to_one_and_rock_is_on_steep_ground() {
        let hf = Heightfield::from_fn(48, 48, 10.0, 10.0, |x, _| {
            if x < 24 {
                x as f32 * 0.5
            } else {
                12.0 + (x as f32 - 24.0) * 12.0
            }
        });
        let m = MasksSettings::default()
            .run(&hf, None, None, &relief_heightfield::NoProgress)
            .unwrap();
        for w in &m.splat {
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        }
        assert!(m.splat[24 * 48 + 10][1] < 0.01);
        assert!(m.splat[24 * 48 + 40][1] > 0.99);
        let rgba = splat_rgba8(&m.splat);
        for px in rgba.chunks(4) {
            assert_eq!(px.iter().map(|&v| v as u32).sum::<u32>(), 255);
        }
    }

    #[test]
    fn mismatched_deposition_and_bad_settings_are_refused() {
        let hf = cone(16, 10.0);
        let small = cone(8, 10.0);
        let e = MasksSettings::default()
            .run(&hf, None, Some(&small), &relief_heightfield::NoProgress)
            .unwrap_err();
        assert!(e.to_string().contains("deposition raster is 8x8"), "{e}");
        let s = MasksSettings {
            height_bands: vec![10.0, 5.0],
            ..Default::default()
        };
        assert_eq!(s.check().unwrap_err().name, "height_bands");
    }
}
