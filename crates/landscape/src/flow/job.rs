//! The `relief flow` job: one serde settings type, checked once, and the run that turns a DEM
//! into the conditioned surface, directions, drainage area, Strahler order, watersheds, HAND and
//! the channel network.

use relief_heightfield::param::in_range;
use relief_heightfield::{Heightfield, ParamError, Progress};
use serde::{Deserialize, Serialize};

use super::basins::{hand, watersheds};
use super::network::{geojson, reaches, strahler};
use super::{Depressions, Directions, ESRI_CODES, RouteOptions, route};
use crate::depression::BreachLimits;
use crate::grid::{Grid, NO_FLOW};
use crate::{LandscapeError, Result};

/// Settings of `relief flow` (and of the pipeline's `flow` stage).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FlowSettings {
    /// Depression handling ([`Depressions`]): `fill` (default), `epsilon`, `breach`, `none`.
    pub depressions: Depressions,
    /// Deepest breach cut (m) with `breach`.
    pub breach_depth: f64,
    /// Longest breach channel (m) with `breach`.
    pub breach_length: f64,
    /// Flow directions of the accumulation: `d8` (default) or `mfd`.
    pub directions: Directions,
    /// Exponent `p` of the multiple-flow-direction split (Quinn et al. 1991 use 1; 1.1 is
    /// Freeman's, the default).
    pub mfd_exponent: f64,
    /// Drainage area (m^2) from which a cell is a channel: Strahler order, the GeoJSON network
    /// and HAND start there. Default 1 km^2, a typical channel-head area of humid and alpine
    /// catchments (Montgomery and Dietrich 1988 report 0.01-1 km^2; at 30-90 m cells a smaller
    /// threshold traces every hollow).
    pub channel_area: f64,
}

impl Default for FlowSettings {
    fn default() -> Self {
        Self {
            depressions: Depressions::Fill,
            breach_depth: 50.0,
            breach_length: 2_000.0,
            directions: Directions::D8,
            mfd_exponent: 1.1,
            channel_area: 1e6,
        }
    }
}

impl FlowSettings {
    /// Checks every field.
    pub fn check(&self) -> std::result::Result<(), ParamError> {
        in_range(
            "breach_depth",
            self.breach_depth,
            0.0..=1e4,
            "must be in [0, 10000] m",
        )?;
        in_range(
            "breach_length",
            self.breach_length,
            0.0..=1e6,
            "must be in [0, 1e6] m",
        )?;
        in_range(
            "mfd_exponent",
            self.mfd_exponent,
            0.1..=100.0,
            "must be in [0.1, 100]",
        )?;
        in_range(
            "channel_area",
            self.channel_area,
            1e-6..=1e13,
            "must be a positive area in m^2 (at most 1e13)",
        )
    }

    /// The routing options of these settings.
    pub fn route_options(&self) -> RouteOptions {
        RouteOptions {
            depressions: self.depressions,
            breach: BreachLimits {
                max_depth: self.breach_depth,
                max_length: self.breach_length,
            },
        }
    }

    /// Bytes of working memory per cell of a run (the pre-flight estimate of callers): the
    /// input and conditioned surface, directions, order, areas (f64) and six output rasters.
    pub const BYTES_PER_CELL: u64 = 4 + 4 + 1 + 4 + 1 + 8 + 8 + 1 + 6 * 4 + 4;

    /// Runs the job on a DEM (voids are flow off the map).
    pub fn run(&self, dem: &Heightfield, progress: &dyn Progress) -> Result<FlowOutput> {
        self.check()?;
        let grid = Grid::of(dem);
        let valid = dem.as_slice().iter().filter(|v| !v.is_nan()).count();
        if valid == 0 {
            return Err(LandscapeError::InvalidInput(
                "the DEM has no valid cell to route".into(),
            ));
        }
        progress.begin("flow routing", 4);
        // Asked between the passes (each a fraction of a second per million cells): a run
        // past its time budget ends with `Stopped`.
        let stop = |after: &str| {
            progress.check_stop(|| LandscapeError::Stopped(format!("flow routing, after {after}")))
        };
        let r = route(dem.as_slice().to_vec(), grid, &self.route_options());
        progress.advance(1);
        stop("the depressions and directions")?;
        // D8 area is counted in cells and multiplied by the cell area once: the same bits
        // whatever order the sums are made in (the tiled plan of `relief tile` makes them
        // tile by tile; `flow::tiled`).
        let area = match self.directions {
            Directions::D8 => r.area_d8(),
            Directions::Mfd => r.accumulation_mfd(self.mfd_exponent),
        };
        // The network, basins and HAND follow the D8 tree (a tree is what they need).
        let d8_area = if self.directions == Directions::D8 {
            area.clone()
        } else {
            r.area_d8()
        };
        progress.advance(1);
        stop("the drainage area")?;
        let order = strahler(&r, &d8_area, self.channel_area);
        let reach = reaches(&r, &d8_area, &order);
        stop("the Strahler order")?;
        let basins = watersheds(&r, &d8_area);
        stop("the watersheds")?;
        let hand = hand(&r, &d8_area, self.channel_area);
        progress.advance(1);
        stop("HAND")?;
        let input = dem.as_slice();
        let mut raised = 0usize;
        let mut lowered = 0usize;
        let mut max_fill = 0f32;
        let mut max_cut = 0f32;
        for (a, b) in input.iter().zip(&r.surface) {
            if b > a {
                raised += 1;
                max_fill = max_fill.max(b - a);
            } else if b < a {
                lowered += 1;
                max_cut = max_cut.max(a - b);
            }
        }
        let outlets = (0..grid.len())
            .filter(|&i| r.outlet[i] && r.dir[i] == NO_FLOW)
            .count();
        // Counted by direction, then multiplied: the same bits whatever order the cells are
        // visited in (the tiled plan counts them tile by tile).
        let mut steps = [0u64; 8];
        for i in 0..grid.len() {
            if order[i] > 0 && r.dir[i] != NO_FLOW {
                steps[r.dir[i] as usize] += 1;
            }
        }
        let channel_m = channel_length(&grid, &steps);
        let basin_area = |l: u32| basins.iter().filter(|&&b| b == l).count() as f64;
        let figures = FlowFigures {
            cells: grid.len(),
            voids: grid.len() - valid,
            raised_cells: raised,
            lowered_cells: lowered,
            max_fill_m: max_fill as f64,
            max_cut_m: max_cut as f64,
            sinks: r.sinks(),
            outlets,
            channel_km: channel_m / 1e3,
            reaches: reach.len(),
            max_order: order.iter().copied().max().unwrap_or(0),
            largest_basin_km2: basin_area(1) * grid.cell_area() / 1e6,
        };
        let georef = dem.georef();
        let channels = geojson(&r, georef, &reach);
        let raster = |v: Vec<f32>| -> Result<Heightfield> {
            Ok(dem.with_data(v)?.with_georef(georef.cloned()))
        };
        let dir: Vec<f32> = (0..grid.len())
            .map(|i| {
                if input[i].is_nan() {
                    f32::NAN
                } else if r.dir[i] == NO_FLOW {
                    0.0
                } else {
                    ESRI_CODES[r.dir[i] as usize] as f32
                }
            })
            .collect();
        let nan_or = |i: usize, v: f32| if input[i].is_nan() { f32::NAN } else { v };
        let out = FlowOutput {
            conditioned: raster(r.surface.clone())?,
            direction: raster(dir)?,
            area: raster(area.iter().map(|&a| a as f32).collect())?,
            strahler: raster(
                (0..grid.len())
                    .map(|i| nan_or(i, order[i] as f32))
                    .collect(),
            )?,
            watersheds: raster(
                (0..grid.len())
                    .map(|i| nan_or(i, basins[i] as f32))
                    .collect(),
            )?,
            hand: raster(hand)?,
            channels,
            figures,
        };
        progress.advance(1);
        Ok(out)
    }
}

/// Length (m) of the channel steps counted by direction (index into `D8`).
pub fn channel_length(grid: &Grid, steps: &[u64; 8]) -> f64 {
    let dist = grid.distances();
    let mut m = 0.0;
    for k in 0..8 {
        m += steps[k] as f64 * dist[k];
    }
    m
}

/// The rasters and network of a flow run (all on the DEM's grid and georeference).
#[derive(Debug, Clone)]
pub struct FlowOutput {
    /// The filled or breached DEM.
    pub conditioned: Heightfield,
    /// D8 directions as ESRI codes ([`ESRI_CODES`]; 0 for outlets and sinks).
    pub direction: Heightfield,
    /// Drainage area (m^2), D8 or MFD as set.
    pub area: Heightfield,
    /// Strahler order of channel cells (0 elsewhere).
    pub strahler: Heightfield,
    /// Watershed labels (1 = the largest basin).
    pub watersheds: Heightfield,
    /// Height above the nearest drainage (m).
    pub hand: Heightfield,
    /// Channel reaches as a GeoJSON `FeatureCollection`.
    pub channels: serde_json::Value,
    /// Figures of the run.
    pub figures: FlowFigures,
}

/// Figures of a flow run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlowFigures {
    /// Cells of the DEM.
    pub cells: usize,
    /// Void cells.
    pub voids: usize,
    /// Cells raised by filling.
    pub raised_cells: usize,
    /// Cells lowered by breaching.
    pub lowered_cells: usize,
    /// Deepest fill (m).
    pub max_fill_m: f64,
    /// Deepest breach cut (m).
    pub max_cut_m: f64,
    /// Cells where flow ends inside the map (0 unless `depressions` is `none`).
    pub sinks: usize,
    /// Cells where flow leaves the map.
    pub outlets: usize,
    /// Total channel length (km).
    pub channel_km: f64,
    /// Channel reaches in the GeoJSON.
    pub reaches: usize,
    /// Highest Strahler order.
    pub max_order: u8,
    /// Area of the largest watershed (km^2).
    pub largest_basin_km2: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_reject_bad_values_by_name() {
        for (s, name) in [
            (
                FlowSettings {
                    channel_area: f64::NAN,
                    ..Default::default()
                },
                "channel_area",
            ),
            (
                FlowSettings {
                    breach_depth: -1.0,
                    ..Default::default()
                },
                "breach_depth",
            ),
            (
                FlowSettings {
                    mfd_exponent: 0.0,
                    ..Default::default()
                },
                "mfd_exponent",
            ),
        ] {
            assert_eq!(s.check().unwrap_err().name, name);
        }
        relief_testdata::assert_json_round_trip(&FlowSettings::default(), &[]);
        assert!(serde_json::from_str::<FlowSettings>(r#"{"depressions": "lake"}"#).is_err());
    }

    #[test]
    fn a_dem_of_voids_is_refused() {
        let hf = Heightfield::new(4, 4, vec![f32::NAN; 16], 1.0, 1.0).unwrap();
        let e = FlowSettings::default()
            .run(&hf, &relief_heightfield::NoProgress)
            .unwrap_err();
        assert!(e.to_string().contains("no valid cell"), "{e}");
    }
}
