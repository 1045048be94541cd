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
    let uplift: Vec<f64> = map
        .as_slice()
        .iter()
        .map(|&v| settings.peak_uplift_m_per_yr * f64::from(v - lo) / span)
        .collect();
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
