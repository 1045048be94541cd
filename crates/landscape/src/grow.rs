//! Relief grown from a painted map by landscape evolution, the approach of Cordonnier et al.
//! (2016, "Large scale terrain generation from tectonic uplift and fluvial erosion", Computer
//! Graphics Forum 35(2)) and Schott et al. (2023, "Large-scale terrain authoring through
//! interactive erosion simulation", ACM TOG 42(5)): the map is the rock uplift rate, and a
//! stream-power incision and hillslope diffusion run ([`crate::erode::stream_power`]) from a
//! nearly flat surface grows, where the map is high, mountains whose ridges and dendritic
//! valleys follow the painted strokes, and leaves the unpainted ground low and flat. The map's
//! edge is the base level (the sea or a river leaving the map).
//!
//! The run lasts long enough to approach the steady state of the stream-power law (uplift
//! balanced by incision), so the result depends on the painting, not on the run length: by
//! default 2 Myr of 1 mm/yr peak uplift with the mountain-range parameters of
//! [`StreamPowerParams`] (the response time of a 10 km catchment is a few hundred kyr) and a
//! hillslope diffusivity of 0.05 m^2/yr, in 100 steps of 20 kyr (with much longer steps the
//! network keeps the flow directions of the initial slope: parallel gullies down every flank
//! instead of valleys that capture one another and merge).
//!
//! Ridge and river strokes painted beside the map ([`Strokes`], [`grow_with_strokes`]) raise
//! the uplift under ridge lines and cancel it under rivers, each faded over
//! [`GrowSettings::stroke_width_m`] metres, so the divides and the main valleys follow them.

use relief_heightfield::Heightfield;
use relief_heightfield::param::{ParamError, ensure, in_range};
use serde::{Deserialize, Serialize};

use crate::erode::{StreamPowerParams, Uplift, base_level_mask, run as stream_power_run};
use crate::grid::Grid;
use crate::{LandscapeError, Result};

/// Settings of [`grow`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GrowSettings {
    /// Uplift rate (m/yr) where the map is at its maximum; the map's minimum gets none.
    pub peak_uplift_m_per_yr: f64,
    /// Length of the run (yr).
    pub years: f64,
    /// Implicit time steps over the run.
    pub steps: usize,
    /// Stream-power and diffusion parameters (`dt` is set from the years and steps).
    pub stream_power: StreamPowerParams,
    /// Extra uplift rate (m/yr) under a full-strength ridge stroke ([`Strokes::ridges`]).
    pub ridge_uplift_m_per_yr: f64,
    /// Distance (m, a Gaussian's sigma) over which a stroke's effect fades on either side:
    /// a river's valley sides, a ridge's flanks (a painted line is a few pixels wide; a
    /// valley is not a trench).
    pub stroke_width_m: f64,
    /// Amplitude (m) of the initial random roughness that seeds the drainage network.
    pub roughness_m: f64,
    /// Seed of the initial roughness.
    pub seed: u64,
}

impl Default for GrowSettings {
    fn default() -> Self {
        Self {
            peak_uplift_m_per_yr: 1e-3,
            years: 2e6,
            steps: 100,
            stream_power: StreamPowerParams {
                diffusion: 0.05,
                ..StreamPowerParams::default()
            },
            ridge_uplift_m_per_yr: 5e-4,
            stroke_width_m: 1500.0,
            roughness_m: 1.0,
            seed: 0,
        }
    }
}

impl GrowSettings {
    /// Checks every field, naming the first one out of range.
    pub fn check(&self) -> std::result::Result<(), ParamError> {
        in_range(
            "peak_uplift_m_per_yr",
            self.peak_uplift_m_per_yr,
            1e-6..=1.0,
            "must be in [1e-6, 1] m/yr",
        )?;
        in_range("years", self.years, 1.0..=1e9, "must be in [1, 1e9] yr")?;
        ensure(
            (1..=10_000).contains(&self.steps),
            "steps",
            self.steps,
            "must be in 1..=10000",
        )?;
        in_range(
            "ridge_uplift_m_per_yr",
            self.ridge_uplift_m_per_yr,
            0.0..=1.0,
            "must be in [0, 1] m/yr",
        )?;
        in_range(
            "stroke_width_m",
            self.stroke_width_m,
            0.0..=1e6,
            "must be in [0, 1e6] m",
        )?;
        in_range(
            "roughness_m",
            self.roughness_m,
            0.0..=1e4,
            "must be in [0, 1e4] m",
        )?;
        StreamPowerParams {
            dt: self.years / self.steps as f64,
            ..self.stream_power
        }
        .check()
    }
}

/// Explicit strokes painted beside the uplift map, as guerin2016's figure 12 draws ridge lines
/// and rivers over its sketch: each a mask (bright = stroke; scaled so its brightest cell is a
/// full-strength stroke, negative values count as none) of the map's size or an integer
/// fraction of it (then resampled like the map).
#[derive(Debug, Clone, Default)]
pub struct Strokes {
    /// Ridge lines: rock uplift raised by up to [`GrowSettings::ridge_uplift_m_per_yr`], so
    /// the divides follow them.
    pub ridges: Option<Heightfield>,
    /// Rivers: no rock uplift under the stroke, so it stays a valley floor at the base level
    /// while the land around it rises (a river drawn to the map's edge drains there; one
    /// that ends inside the map is a basin the landform pass later drains).
    pub rivers: Option<Heightfield>,
}

impl Strokes {
    /// Whether neither layer is given.
    pub fn is_empty(&self) -> bool {
        self.ridges.is_none() && self.rivers.is_none()
    }

    /// Checks that each layer has the size `w` x `h` of the map it paints over, or an integer
    /// fraction of it, and no voids.
    pub fn check(&self, w: usize, h: usize) -> Result<()> {
        for (name, m) in [("ridge", &self.ridges), ("river", &self.rivers)] {
            let Some(m) = m else { continue };
            let (mw, mh) = (m.width(), m.height());
            if mw == 0
                || mh == 0
                || !w.is_multiple_of(mw)
                || !h.is_multiple_of(mh)
                || w / mw != h / mh
            {
                return Err(LandscapeError::InvalidInput(format!(
                    "the {name} strokes ({mw}x{mh}) must have the size of the map they paint \
                     over ({w}x{h}) or an integer fraction of it"
                )));
            }
            if m.as_slice().iter().any(|v| !v.is_finite()) {
                return Err(LandscapeError::InvalidInput(format!(
                    "the {name} strokes have voids: paint 0 where there is no stroke"
                )));
            }
        }
        Ok(())
    }

    /// The layer `m` as weights in `[0, 1]` on a `w` x `h` grid of `cell` metres (checked by
    /// [`Self::check`]), faded over `width_m` on either side.
    fn weights(m: &Heightfield, w: usize, h: usize, cell: f64, width_m: f64) -> Result<Vec<f64>> {
        let m = if m.width() == w {
            m.clone()
        } else {
            m.resample(w, h)?
        };
        let sigma = (width_m / cell) as f32;
        let m = if sigma >= 0.5 {
            m.gaussian_blur(sigma)?
        } else {
            m
        };
        let top = m.as_slice().iter().fold(0.0f32, |a, &v| a.max(v));
        Ok(m.as_slice()
            .iter()
            .map(|&v| {
                if top > 0.0 {
                    f64::from((v / top).clamp(0.0, 1.0))
                } else {
                    0.0
                }
            })
            .collect())
    }
}

/// Grows relief from `map` (any values; its minimum means no uplift, its maximum
/// [`GrowSettings::peak_uplift_m_per_yr`]) on `map`'s grid and cell size; returns the surface
/// in metres above the base level (the map's edge, at 0). `stop` is asked before every step
/// (the run then ends with an error naming it).
///
/// Errors: invalid settings, voids in the map, a map smaller than 3 x 3.
pub fn grow(
    map: &Heightfield,
    settings: &GrowSettings,
    stop: &dyn Fn() -> bool,
) -> Result<Heightfield> {
    grow_with_strokes(map, &Strokes::default(), settings, stop)
}

/// [`grow`] with ridge and river strokes ([`Strokes`]) over the uplift map.
///
/// Errors: those of [`grow`], and strokes of another size than the map (or an integer
/// fraction of it) or with voids.
pub fn grow_with_strokes(
    map: &Heightfield,
    strokes: &Strokes,
    settings: &GrowSettings,
    stop: &dyn Fn() -> bool,
) -> Result<Heightfield> {
    settings.check()?;
    let (w, h) = (map.width(), map.height());
    if w < 3 || h < 3 {
        return Err(LandscapeError::InvalidInput(format!(
            "a map of {w}x{h} cells is too small to grow relief on (3x3 at least)"
        )));
    }
    let (lo, hi) = map
        .min_max()
        .ok_or_else(|| LandscapeError::InvalidInput("the map has no valid cell".into()))?;
    if map.as_slice().iter().any(|v| !v.is_finite()) {
        return Err(LandscapeError::InvalidInput(
            "the map has voids: fill them first".into(),
        ));
    }
    let span = f64::from(hi - lo).max(f64::MIN_POSITIVE);
    let mut uplift: Vec<f64> = map
        .as_slice()
        .iter()
        .map(|&v| settings.peak_uplift_m_per_yr * f64::from(v - lo) / span)
        .collect();
    strokes.check(w, h)?;
    let (cx, cy) = map.cell_size();
    let weights = |m| Strokes::weights(m, w, h, cx.min(cy), settings.stroke_width_m);
    if let Some(r) = &strokes.ridges {
        for (u, r) in uplift.iter_mut().zip(weights(r)?) {
            *u += settings.ridge_uplift_m_per_yr * r;
        }
    }
    if let Some(r) = &strokes.rivers {
        for (u, r) in uplift.iter_mut().zip(weights(r)?) {
            *u *= 1.0 - r;
        }
    }
    let grid = Grid::of(map);
    let mut z: Vec<f64> = (0..w * h)
        .map(|i| {
            let r = relief_heightfield::rng::splitmix64(
                settings.seed ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15),
            );
            settings.roughness_m * ((r >> 11) as f64 / (1u64 << 53) as f64)
        })
        .collect();
    for i in 0..w * h {
        if grid.is_edge(i) {
            z[i] = 0.0;
        }
    }
    let base = base_level_mask(&z, &grid);
    let params = StreamPowerParams {
        dt: settings.years / settings.steps as f64,
        ..settings.stream_power
    };
    let figures = stream_power_run(
        &mut z,
        &grid,
        &base,
        &params,
        Uplift::Raster(&uplift),
        settings.steps,
        &relief_heightfield::NoProgress,
        stop,
    )?;
    if figures.stopped {
        return Err(LandscapeError::Stopped(format!(
            "growing relief stopped after {} of {} steps",
            figures.steps, settings.steps
        )));
    }
    let (cx, cy) = map.cell_size();
    Ok(
        Heightfield::new(w, h, z.iter().map(|&v| v as f32).collect(), cx, cy)?
            .with_georef(map.georef().cloned()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ridge_strokes_raise_the_divide_and_river_strokes_cut_a_valley() {
        // Uniform uplift over a 64 x 64 map of 200 m cells; a ridge stroke along row 20 and a
        // river stroke along column 44 from the southern edge to the middle, given at half
        // the map's size (resampled like the map).
        let map = Heightfield::from_fn(64, 64, 200.0, 200.0, |x, y| {
            if (4..60).contains(&x) && (4..60).contains(&y) {
                1.0
            } else {
                0.0
            }
        });
        let ridges = Heightfield::from_fn(
            32,
            32,
            400.0,
            400.0,
            |_, y| {
                if y == 10 { 255.0 } else { 0.0 }
            },
        );
        let rivers = Heightfield::from_fn(32, 32, 400.0, 400.0, |x, y| {
            if x == 22 && y >= 16 { 255.0 } else { 0.0 }
        });
        let settings = GrowSettings {
            steps: 40,
            ..GrowSettings::default()
        };
        let plain = grow(&map, &settings, &|| false).unwrap();
        let strokes = Strokes {
            ridges: Some(ridges),
            rivers: Some(rivers),
        };
        let z = grow_with_strokes(&map, &strokes, &settings, &|| false).unwrap();
        let mean = |z: &Heightfield, xs: std::ops::Range<usize>, ys: std::ops::Range<usize>| {
            let n = (xs.len() * ys.len()) as f32;
            ys.flat_map(|y| xs.clone().map(move |x| (x, y)))
                .map(|(x, y)| z.get(x, y))
                .sum::<f32>()
                / n
        };
        // The ridge row stands higher than without the stroke, and higher than rows 8 cells
        // away.
        let (ridge, ridge_plain) = (mean(&z, 8..36, 20..22), mean(&plain, 8..36, 20..22));
        assert!(ridge > 1.2 * ridge_plain, "{ridge} vs {ridge_plain}");
        assert!(ridge > mean(&z, 8..36, 28..30), "{ridge}");
        // The river's cells (columns 44-45, rows 36-56) are a valley: well below the land 8
        // cells either side and below the same cells without the stroke.
        let river = mean(&z, 44..46, 36..56);
        let banks = 0.5 * (mean(&z, 36..38, 36..56) + mean(&z, 52..54, 36..56));
        assert!(river < 0.5 * banks, "{river} vs {banks}");
        assert!(river < 0.5 * mean(&plain, 44..46, 36..56), "{river}");
        // Wrong sizes are named.
        let bad = Strokes {
            rivers: Some(Heightfield::from_fn(30, 30, 1.0, 1.0, |_, _| 0.0)),
            ..Strokes::default()
        };
        let e = grow_with_strokes(&map, &bad, &settings, &|| false).unwrap_err();
        assert!(e.to_string().contains("river strokes (30x30)"), "{e}");
    }

    /// A painted ridge (a band of high values) across a 96 x 64 map of 200 m cells.
    fn ridge_map() -> Heightfield {
        Heightfield::from_fn(96, 64, 200.0, 200.0, |x, y| {
            let d = (y as f32 - 32.0 - 0.2 * (x as f32 - 48.0)).abs();
            (-(d * d) / 60.0).exp()
        })
    }

    #[test]
    fn a_painted_ridge_grows_a_drained_mountain_range_and_flat_lowlands() {
        let map = ridge_map();
        let z = grow(&map, &GrowSettings::default(), &|| false).unwrap();
        let at = |x: usize, y: usize| z.get(x, y);
        // High under the stroke, low far from it.
        assert!(at(48, 32) > 200.0, "{}", at(48, 32));
        assert!(at(48, 4) < 5.0, "{}", at(48, 4));
        // Steady state drains everything: no closed depression deeper than the roughness.
        let stats = crate::stats::drainage(&z);
        assert!(stats.fill_depth_m < 0.5, "{stats:?}");
        // Valleys: along the ridge crest line the heights vary by tens of metres (a network
        // of valleys and spurs, not a smooth swell).
        let crest: Vec<f32> = (10..86)
            .map(|x| {
                let y = (32.0 + 0.2 * (x as f32 - 48.0)).round() as usize;
                (y - 6..=y + 6)
                    .map(|yy| z.get(x, yy))
                    .fold(f32::MIN, f32::max)
            })
            .collect();
        let lo = crest.iter().copied().fold(f32::MAX, f32::min);
        let hi = crest.iter().copied().fold(f32::MIN, f32::max);
        assert!(hi - lo > 20.0, "{lo}..{hi}");
        // Same seed, same bytes; another seed, another network.
        let again = grow(&map, &GrowSettings::default(), &|| false).unwrap();
        assert_eq!(z.as_slice(), again.as_slice());
        let other = grow(
            &map,
            &GrowSettings {
                seed: 9,
                ..Default::default()
            },
            &|| false,
        )
        .unwrap();
        assert_ne!(z.as_slice(), other.as_slice());
    }

    #[test]
    fn bad_settings_and_maps_are_refused_by_name() {
        let map = ridge_map();
        let e = grow(
            &map,
            &GrowSettings {
                steps: 0,
                ..Default::default()
            },
            &|| false,
        )
        .unwrap_err();
        assert!(e.to_string().contains("steps"), "{e}");
        let tiny = Heightfield::from_fn(2, 2, 1.0, 1.0, |_, _| 0.0);
        let e = grow(&tiny, &GrowSettings::default(), &|| false).unwrap_err();
        assert!(e.to_string().contains("too small"), "{e}");
        let e = grow(&map, &GrowSettings::default(), &|| true).unwrap_err();
        assert!(e.to_string().contains("stopped"), "{e}");
    }
}
