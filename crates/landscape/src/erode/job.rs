//! The `relief erode` job: a preset (a landscape type a user starts from) and the fields that
//! override it, resolved into up to three processes run in order: stream-power incision with
//! uplift and hillslope diffusion over geological time (the drainage network), hydraulic erosion
//! (gullies and fans at the grid's scale), thermal relaxation (talus below cliffs).

use std::time::Instant;

use relief_heightfield::param::{ensure, in_range};
use relief_heightfield::{Heightfield, ParamError, Progress};
use serde::{Deserialize, Serialize};

use super::fans::{FanFigures, FanParams, build_fans};
use super::hydraulic::{HydraulicFigures, HydraulicParams, hydraulic};
use super::stream_power::{self, RunFigures, StreamPowerParams, Uplift, base_level_mask};
use super::thermal::{ThermalFigures, ThermalParams, thermal};
use crate::depression::{FillMode, priority_flood};
use crate::grid::Grid;
use crate::{LandscapeError, Result};

/// Cell size (m) up to which the hydraulic model runs a preset's full iterations: about a
/// gully's width ([`ErodeSettings::plan_for`]).
pub const RILL_CELL_M: f64 = 10.0;

/// A landscape type to start from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Soil-mantled rolling hills: weak incision, strong hillslope diffusion, light rain wash.
    Gentle,
    /// Alpine relief: channel incision over 50 kyr from channel heads of 1 km^2, moderate
    /// diffusion, gullies, 38 degree scree below cliffs and channel walls.
    #[default]
    Mountain,
    /// Soft rock under heavy storms: dense gullies, fast incision, little diffusion.
    Badlands,
    /// Arid ranges: rare flash floods that build fans, long talus aprons at 33 degrees.
    Desert,
}

impl Preset {
    /// Every preset, in the order of the documentation.
    pub const ALL: [Preset; 4] = [Self::Gentle, Self::Mountain, Self::Badlands, Self::Desert];

    /// The preset's name (`gentle`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Self::Gentle => "gentle",
            Self::Mountain => "mountain",
            Self::Badlands => "badlands",
            Self::Desert => "desert",
        }
    }

    /// The processes of the preset.
    pub fn plan(self) -> Plan {
        // Stream power takes 10 kyr steps (both solvers are implicit, stable at any step),
        // so a preset's geological time costs a handful of routings; the hydraulic model's
        // capacity is the hydraulic defaults' (0.5, full capacity at 2 m of water) scaled
        // per preset.
        // Channel heads: cells draining less than `head` m^2 are hillslopes (diffusion
        // only), the rest channels (Montgomery and Dietrich 1988; about 1 km^2 in steep
        // alpine terrain, Stock and Dietrich 2003; tens to hundreds of m^2 in badlands).
        let sp = |k: f64, diffusion: f64, years: f64, head: f64| StreamPowerStage {
            params: StreamPowerParams {
                k,
                diffusion,
                dt: 10_000.0,
                channel_area_m2: head,
                ..StreamPowerParams::default()
            },
            years,
            uplift: 0.0,
        };
        let hy = |iterations: u32, rain_m: f64, capacity: f64, evaporation: f64| HydraulicParams {
            iterations,
            rain_m,
            capacity,
            evaporation,
            ..HydraulicParams::default()
        };
        // Bedrock weathers into at most `weathering_m` of loose material over the run, so
        // cliffs keep their faces and shed talus aprons instead of being levelled.
        let th = |talus_angle_deg: f64, iterations: u32, weathering_m: f64| ThermalParams {
            talus_angle_deg,
            iterations,
            weathering_m: Some(weathering_m),
            ..ThermalParams::default()
        };
        let fan = |gradient_deg: f64, trapped: f64| FanParams {
            gradient_deg,
            trapped,
            ..FanParams::default()
        };
        match self {
            Self::Gentle => Plan {
                stream_power: Some(sp(1e-5, 0.02, 50_000.0, 1e6)),
                hydraulic: Some(hy(50, 0.01, 0.3, 0.03)),
                fans: Some(fan(2.0, 0.3)),
                thermal: Some(th(30.0, 30, 5.0)),
                fill_pits: true,
            },
            Self::Mountain => Plan {
                stream_power: Some(sp(2e-5, 0.01, 50_000.0, 1e6)),
                hydraulic: Some(hy(80, 0.01, 0.5, 0.02)),
                fans: Some(fan(4.0, 0.3)),
                thermal: Some(th(38.0, 20, 40.0)),
                fill_pits: true,
            },
            Self::Badlands => Plan {
                stream_power: Some(sp(1e-4, 0.002, 20_000.0, 1e3)),
                hydraulic: Some(hy(120, 0.015, 0.8, 0.015)),
                fans: Some(fan(5.0, 0.5)),
                thermal: Some(th(40.0, 20, 5.0)),
                fill_pits: true,
            },
            Self::Desert => Plan {
                stream_power: Some(sp(5e-6, 0.005, 20_000.0, 1e5)),
                hydraulic: Some(hy(100, 0.02, 0.6, 0.04)),
                fans: Some(fan(3.0, 0.6)),
                thermal: Some(th(33.0, 60, 20.0)),
                fill_pits: true,
            },
        }
    }
}

/// Stream power over geological time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StreamPowerStage {
    /// Parameters (K, m, n, D, dt).
    pub params: StreamPowerParams,
    /// Duration (yr); the number of steps is `ceil(years / dt)`.
    pub years: f64,
    /// Rock uplift (m/yr) away from the base levels (the edges and voids), unless an uplift
    /// raster is given to the run.
    pub uplift: f64,
}

/// The resolved processes of a run, in the order they run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// Stream power with diffusion, first.
    pub stream_power: Option<StreamPowerStage>,
    /// Hydraulic erosion, second.
    pub hydraulic: Option<HydraulicParams>,
    /// Alluvial fans below the valleys' mouths from the sediment eroded upstream, third.
    pub fans: Option<FanParams>,
    /// Thermal relaxation, last.
    pub thermal: Option<ThermalParams>,
    /// Fill the closed depressions the processes dug or dammed (sediment settling in the
    /// ponds): the result keeps the input's own closed depressions, no deeper than they were,
    /// and no others, so it drains like the input.
    pub fill_pits: bool,
}

/// Settings of `relief erode` (and the pipeline's `erode` stage): the preset and the fields
/// that override it (`None`: the preset's value).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ErodeSettings {
    /// The landscape type to start from.
    pub preset: Preset,
    /// Stream-power duration (yr); 0 skips stream power.
    pub years: Option<f64>,
    /// Stream-power time step (yr).
    pub dt: Option<f64>,
    /// Uplift rate (m/yr).
    pub uplift: Option<f64>,
    /// Erodibility `K` (m^(1-2m)/yr).
    pub k: Option<f64>,
    /// Drainage-area exponent `m`.
    pub m: Option<f64>,
    /// Slope exponent `n`.
    pub n: Option<f64>,
    /// Hillslope diffusivity (m^2/yr).
    pub diffusion: Option<f64>,
    /// Channel-head drainage area (m^2): cells draining less are hillslopes, not incised by
    /// stream power (0 incises every cell).
    pub channel_area: Option<f64>,
    /// Gradient of the alluvial fans (degrees); 0 builds none.
    pub fan_gradient: Option<f64>,
    /// Hydraulic iterations; 0 skips hydraulic erosion.
    pub hydraulic_iterations: Option<u32>,
    /// Rain per hydraulic iteration (m of water).
    pub rain: Option<f64>,
    /// Sediment capacity of the hydraulic model (dimensionless).
    pub capacity: Option<f64>,
    /// Angle of repose of the thermal relaxation (degrees).
    pub talus_angle: Option<f64>,
    /// Thermal iterations; 0 skips thermal relaxation.
    pub thermal_iterations: Option<u32>,
    /// Bedrock depth (m) each cell can weather into loose material for the thermal
    /// relaxation; a negative value makes the whole surface loose (cliffs levelled).
    pub weathering: Option<f64>,
    /// Fill the closed depressions the erosion made (see [`Plan::fill_pits`]).
    pub fill_pits: Option<bool>,
    /// Seed of the random rain (used when the rain is not uniform).
    pub seed: u64,
}

impl ErodeSettings {
    /// The settings of a preset without overrides.
    pub fn preset(preset: Preset) -> Self {
        Self {
            preset,
            ..Self::default()
        }
    }

    /// The preset with the overrides applied.
    pub fn plan(&self) -> Plan {
        let mut plan = self.preset.plan();
        if let Some(sp) = plan.stream_power.as_mut() {
            let p = &mut sp.params;
            p.k = self.k.unwrap_or(p.k);
            p.m = self.m.unwrap_or(p.m);
            p.n = self.n.unwrap_or(p.n);
            p.diffusion = self.diffusion.unwrap_or(p.diffusion);
            p.channel_area_m2 = self.channel_area.unwrap_or(p.channel_area_m2);
            p.dt = self.dt.unwrap_or(p.dt);
            sp.years = self.years.unwrap_or(sp.years);
            sp.uplift = self.uplift.unwrap_or(sp.uplift);
            // A run shorter than one step is one step of its own length, not a whole step.
            if sp.years > 0.0 {
                p.dt = p.dt.min(sp.years);
            }
        }
        if plan.stream_power.is_some_and(|s| s.years == 0.0) {
            plan.stream_power = None;
        }
        if let Some(h) = plan.hydraulic.as_mut() {
            h.iterations = self.hydraulic_iterations.unwrap_or(h.iterations);
            h.rain_m = self.rain.unwrap_or(h.rain_m);
            h.capacity = self.capacity.unwrap_or(h.capacity);
            h.seed = self.seed;
        }
        if plan.hydraulic.is_some_and(|h| h.iterations == 0) {
            plan.hydraulic = None;
        }
        if let Some(t) = plan.thermal.as_mut() {
            t.talus_angle_deg = self.talus_angle.unwrap_or(t.talus_angle_deg);
            t.iterations = self.thermal_iterations.unwrap_or(t.iterations);
            if let Some(w) = self.weathering {
                t.weathering_m = (w >= 0.0).then_some(w);
            }
        }
        plan.fill_pits = self.fill_pits.unwrap_or(plan.fill_pits);
        match self.fan_gradient {
            Some(0.0) => plan.fans = None,
            Some(g) => {
                plan.fans
                    .get_or_insert_with(FanParams::default)
                    .gradient_deg = g
            }
            None => {}
        }
        if plan.thermal.is_some_and(|t| t.iterations == 0) {
            plan.thermal = None;
        }
        plan
    }

    /// The plan on a grid of `cell_x` by `cell_y` metres. Unless `hydraulic_iterations` is
    /// set, the hydraulic model's iterations are the preset's on cells up to [`RILL_CELL_M`]
    /// and fewer in proportion on coarser ones: its rills are a cell wide, so on a 50 m grid
    /// each is a 50 m gully, and the preset's full run would cut one down every slope (on
    /// alpine DEMs that turned smooth glacial slopes into parallel gullies: beta 0.637 ->
    /// 0.527, docs/LANDSCAPE.md). Unless `years` is set, a preset's
    /// stream-power time is capped so that hillslope diffusion spreads no further than half a
    /// cell, `sqrt(D t) <= min(cell_x, cell_y) / 2`: what the grid can show. An SRTM grid
    /// (30-90 m) gets the preset's tens of millennia, a 2 m lidar grid a century (over 50 kyr
    /// the diffusion alone would smooth a 2 m grid's scarps over 10 cells and the incision would
    /// cut rills every cell wide, finer than channel heads are). Half a cell, not a cell: on
    /// carrizo's lidar (2 m) a diffusion length of one cell (400 yr at D = 0.01) already smooths
    /// away the micro-relief that steers the flow, and the hillslopes drain in parallel sheets
    /// (beta 0.595 -> 0.737); at half a cell the network keeps its character (0.635).
    pub fn plan_for(&self, cell_x: f64, cell_y: f64) -> Plan {
        let mut plan = self.plan();
        let cell = cell_x.min(cell_y);
        if let Some(sp) = plan.stream_power.as_mut().filter(|_| self.years.is_none()) {
            let d = sp.params.diffusion;
            let cap = 0.25 * cell * cell / d;
            if d > 0.0 && cap < sp.years {
                sp.years = cap;
                sp.params.dt = sp.params.dt.min(sp.years);
            }
        }
        if let Some(h) = plan
            .hydraulic
            .as_mut()
            .filter(|_| self.hydraulic_iterations.is_none())
            .filter(|_| cell > RILL_CELL_M)
        {
            h.iterations = ((f64::from(h.iterations) * RILL_CELL_M / cell).round() as u32).max(1);
        }
        plan
    }

    /// Checks every field (through the resolved plan, so an override is checked by the
    /// process that takes it, under its own name).
    pub fn check(&self) -> std::result::Result<(), ParamError> {
        if let Some(y) = self.years {
            in_range("years", y, 0.0..=1e8, "must be in [0, 1e8] years")?;
        }
        if let Some(u) = self.uplift {
            in_range("uplift", u, -0.1..=0.1, "must be in [-0.1, 0.1] m/yr")?;
        }
        let plan = self.plan();
        if let Some(sp) = plan.stream_power {
            sp.params.check()?;
            ensure(
                sp.years / sp.params.dt <= 1e6,
                "years",
                sp.years,
                "needs at most 1e6 steps of dt",
            )?;
        }
        if let Some(h) = plan.hydraulic {
            h.check()?;
            in_range(
                "hydraulic_iterations",
                h.iterations,
                0..=1_000_000,
                "must be at most 1e6",
            )?;
        }
        if let Some(t) = plan.thermal {
            t.check()?;
        }
        if let Some(f) = plan.fans {
            f.check()?;
        }
        Ok(())
    }

    /// Bytes of working memory per cell of a run: the f64 surface, its copy and the stream-power
    /// buffers (about 60 B), the hydraulic model's eight f32 fields and two buffers (40 B), the
    /// input and outputs (12 B).
    pub const BYTES_PER_CELL: u64 = 120;

    /// Seconds the run will take on `dem`, timed on a pilot: each process on a centre crop of
    /// at most 256 x 256 cells for a few steps, scaled by cells and steps.
    pub fn estimate_seconds(&self, dem: &Heightfield) -> Result<f64> {
        self.check()?;
        let (w, h) = (dem.width().min(256), dem.height().min(256));
        let crop = dem.crop((dem.width() - w) / 2, (dem.height() - h) / 2, w, h)?;
        let scale = dem.len() as f64 / crop.len() as f64;
        let (cx, cy) = dem.cell_size();
        let plan = self.plan_for(cx, cy);
        let pilot = Plan {
            stream_power: plan.stream_power.map(|s| StreamPowerStage {
                years: s.params.dt * 3.0,
                ..s
            }),
            hydraulic: plan.hydraulic.map(|p| HydraulicParams {
                iterations: p.iterations.min(6),
                ..p
            }),
            thermal: plan.thermal.map(|p| ThermalParams {
                iterations: p.iterations.min(6),
                ..p
            }),
            fans: plan.fans,
            fill_pits: plan.fill_pits,
        };
        let t0 = Instant::now();
        run_plan(
            &pilot,
            &crop,
            None,
            &relief_heightfield::NoProgress,
            &|| false,
        )?;
        let per_unit = t0.elapsed().as_secs_f64() * scale;
        let units = |full: f64, done: f64| if done > 0.0 { full / done } else { 0.0 };
        let steps = |p: &Plan| {
            (
                p.stream_power
                    .map_or(0.0, |s| (s.years / s.params.dt).ceil()),
                p.hydraulic.map_or(0.0, |h| h.iterations as f64),
                p.thermal.map_or(0.0, |t| t.iterations as f64),
            )
        };
        let (a, b, c) = steps(&plan);
        let (pa, pb, pc) = steps(&pilot);
        // The pilot's time split evenly over its processes is pessimistic enough for a
        // budget check; each process scales with its own step count.
        let parts = [(a, pa), (b, pb), (c, pc)]
            .iter()
            .filter(|(_, p)| *p > 0.0)
            .count()
            .max(1) as f64;
        Ok(per_unit / parts * (units(a, pa) + units(b, pb) + units(c, pc)))
    }

    /// Runs the job. `uplift` (m/yr per cell, the DEM's grid) replaces the constant uplift.
    /// `stop` is asked between steps; when it returns true the run ends with
    /// [`LandscapeError::Stopped`].
    pub fn run(
        &self,
        dem: &Heightfield,
        uplift: Option<&Heightfield>,
        progress: &dyn Progress,
        stop: &dyn Fn() -> bool,
    ) -> Result<ErodeOutput> {
        self.check()?;
        if let Some(u) = uplift {
            if (u.width(), u.height()) != (dem.width(), dem.height()) {
                return Err(LandscapeError::InvalidInput(format!(
                    "the uplift raster is {}x{}, the DEM {}x{}",
                    u.width(),
                    u.height(),
                    dem.width(),
                    dem.height()
                )));
            }
            if u.as_slice().iter().any(|v| !v.is_nan() && v.abs() > 0.1) {
                return Err(LandscapeError::InvalidInput(
                    "the uplift raster has rates beyond 0.1 m/yr".into(),
                ));
            }
        }
        if dem.as_slice().iter().all(|v| v.is_nan()) {
            return Err(LandscapeError::InvalidInput(
                "the DEM has no valid cell".into(),
            ));
        }
        let (cx, cy) = dem.cell_size();
        run_plan(&self.plan_for(cx, cy), dem, uplift, progress, stop)
    }
}

fn run_plan(
    plan: &Plan,
    dem: &Heightfield,
    uplift: Option<&Heightfield>,
    progress: &dyn Progress,
    stop: &dyn Fn() -> bool,
) -> Result<ErodeOutput> {
    let grid = Grid::of(dem);
    let mut figures = ErodeFigures {
        plan: *plan,
        ..ErodeFigures::default()
    };
    let mut z: Vec<f32> = dem.as_slice().to_vec();
    // The uplift each cell received, so that erosion and deposition are net of it.
    let mut uplifted = vec![0f64; grid.len()];
    // The input's own depressions, filled on a worker of the pool while this thread runs the
    // processes (stream power's routing is serial): the result is the same whenever it is made.
    let mut input_filled = None;
    rayon::in_place_scope(|scope| -> Result<()> {
        if plan.fill_pits {
            let filled = &mut input_filled;
            scope.spawn(move |_| {
                let mut f = dem.as_slice().to_vec();
                priority_flood(&mut f, &grid, FillMode::Plain, None);
                *filled = Some(f);
            });
        }
        erode_steps(
            &mut z,
            plan,
            dem,
            uplift,
            progress,
            stop,
            &grid,
            &mut uplifted,
            &mut figures,
        )
    })?;
    let input = dem.as_slice();
    if let Some(before) = input_filled {
        fill_new_pits(input, &before, &mut z, &grid);
    }
    let mut erosion = vec![f32::NAN; grid.len()];
    let mut deposition = vec![f32::NAN; grid.len()];
    let a0 = grid.cell_area();
    for i in 0..grid.len() {
        if input[i].is_nan() {
            continue;
        }
        let change = z[i] as f64 - input[i] as f64 - uplifted[i];
        erosion[i] = (-change).max(0.0) as f32;
        deposition[i] = change.max(0.0) as f32;
        figures.eroded_m3 += (-change).max(0.0) * a0;
        figures.deposited_m3 += change.max(0.0) * a0;
        figures.max_erosion_m = figures.max_erosion_m.max(-change);
        figures.max_deposition_m = figures.max_deposition_m.max(change);
    }
    let georef = dem.georef().cloned();
    Ok(ErodeOutput {
        terrain: dem.with_data(z)?.with_georef(georef.clone()),
        erosion: dem.with_data(erosion)?.with_georef(georef.clone()),
        deposition: dem.with_data(deposition)?.with_georef(georef),
        figures,
    })
}

/// The processes of `plan` in order on `z`, the DEM's cells (stream power, hydraulic, fans,
/// thermal), with the uplift each cell received into `uplifted` and the figures of each.
fn erode_steps(
    z: &mut [f32],
    plan: &Plan,
    dem: &Heightfield,
    uplift: Option<&Heightfield>,
    progress: &dyn Progress,
    stop: &dyn Fn() -> bool,
    grid: &Grid,
    uplifted: &mut [f64],
    figures: &mut ErodeFigures,
) -> Result<()> {
    if let Some(sp) = plan.stream_power {
        let mut zz: Vec<f64> = z.iter().map(|&v| v as f64).collect();
        let base = base_level_mask(&zz, grid);
        let rates: Option<Vec<f64>> = uplift.map(|u| {
            u.as_slice()
                .iter()
                .map(|&v| if v.is_nan() { 0.0 } else { v as f64 })
                .collect()
        });
        let up = match rates.as_deref() {
            Some(r) => Uplift::Raster(r),
            None => Uplift::Constant(sp.uplift),
        };
        // Equal steps that add up to the run's years (45.5 kyr in steps of at most 10 kyr is
        // five steps of 9.1 kyr, not five of 10).
        let steps = (sp.years / sp.params.dt).ceil().max(1.0);
        let params = StreamPowerParams {
            dt: sp.years / steps,
            ..sp.params
        };
        let steps = steps as usize;
        if let Some(s) = figures.plan.stream_power.as_mut() {
            s.params.dt = params.dt;
        }
        let f = stream_power::run(&mut zz, grid, &base, &params, up, steps, progress, stop)?;
        if f.stopped {
            return Err(LandscapeError::Stopped("stream power".into()));
        }
        let years = f.steps as f64 * params.dt;
        for i in 0..grid.len() {
            if !base[i] {
                uplifted[i] = years * rates.as_ref().map_or(sp.uplift, |r| r[i]);
            }
        }
        for (a, b) in z.iter_mut().zip(&zz) {
            *a = *b as f32;
        }
        figures.stream_power = Some(f);
    }
    if let Some(p) = plan.hydraulic {
        let out = hydraulic(z, grid, &p, progress, stop)?;
        figures.hydraulic = Some(out.figures);
    }
    let input = dem.as_slice();
    if let Some(p) = plan.fans {
        if stop() {
            return Err(LandscapeError::Stopped("alluvial fans".into()));
        }
        progress.begin("alluvial fans", 0);
        let eroded: Vec<f32> = (0..grid.len())
            .map(|i| (f64::from(input[i]) + uplifted[i] - f64::from(z[i])) as f32)
            .collect();
        figures.fans = Some(
            build_fans(z, &eroded, grid, &p, stop)
                .ok_or_else(|| LandscapeError::Stopped("alluvial fans".into()))?,
        );
    }
    if let Some(p) = plan.thermal {
        figures.thermal = Some(thermal(z, grid, &p, progress, stop)?);
    }
    Ok(())
}

/// Raises the cells of `z` that lie in a closed depression to the depression's spill level,
/// less the depth the input had there: the input's own depressions stay (no deeper), those the
/// erosion made are filled.
fn fill_new_pits(input: &[f32], before: &[f32], z: &mut [f32], grid: &Grid) {
    let mut after = z.to_vec();
    priority_flood(&mut after, grid, FillMode::Plain, None);
    for i in 0..grid.len() {
        if after[i] > z[i] {
            let kept = before[i] - input[i];
            z[i] = z[i].max(after[i] - kept);
        }
    }
}

/// The result of an erosion run, on the DEM's grid and georeference.
#[derive(Debug, Clone)]
pub struct ErodeOutput {
    /// The eroded terrain.
    pub terrain: Heightfield,
    /// Net lowering (m, >= 0), uplift left out.
    pub erosion: Heightfield,
    /// Net raising (m, >= 0), uplift left out.
    pub deposition: Heightfield,
    /// Figures of the run.
    pub figures: ErodeFigures,
}

/// Figures of an erosion run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ErodeFigures {
    /// The processes that ran, with their parameters.
    pub plan: Plan,
    /// Stream power's figures.
    pub stream_power: Option<RunFigures>,
    /// Hydraulic erosion's figures.
    pub hydraulic: Option<HydraulicFigures>,
    /// Thermal relaxation's figures.
    pub thermal: Option<ThermalFigures>,
    /// The alluvial fans' figures.
    pub fans: Option<FanFigures>,
    /// Volume lowered (m^3), uplift left out.
    pub eroded_m3: f64,
    /// Volume raised (m^3).
    pub deposited_m3: f64,
    /// Deepest net lowering (m).
    pub max_erosion_m: f64,
    /// Highest net raising (m).
    pub max_deposition_m: f64,
}

impl Default for Plan {
    fn default() -> Self {
        Preset::default().plan()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_replace_the_preset_and_zero_skips_a_process() {
        let s = ErodeSettings {
            preset: Preset::Badlands,
            k: Some(3e-5),
            hydraulic_iterations: Some(0),
            talus_angle: Some(31.0),
            ..Default::default()
        };
        let p = s.plan();
        assert_eq!(p.stream_power.unwrap().params.k, 3e-5);
        assert_eq!(p.stream_power.unwrap().params.diffusion, 0.002);
        assert!(p.hydraulic.is_none());
        assert_eq!(p.thermal.unwrap().talus_angle_deg, 31.0);
        assert_eq!(p.fans.unwrap().gradient_deg, 5.0);
        let fans = |g: f64| {
            ErodeSettings {
                fan_gradient: Some(g),
                ..s.clone()
            }
            .plan()
            .fans
        };
        assert_eq!(fans(0.0), None);
        assert_eq!(fans(7.0).unwrap().gradient_deg, 7.0);
        for preset in Preset::ALL {
            ErodeSettings::preset(preset).check().unwrap();
        }
        relief_testdata::assert_json_round_trip(&s, &[]);
    }

    #[test]
    fn bad_overrides_are_refused_by_name() {
        for (s, name) in [
            (
                ErodeSettings {
                    k: Some(f64::NAN),
                    ..Default::default()
                },
                "k",
            ),
            (
                ErodeSettings {
                    years: Some(-5.0),
                    ..Default::default()
                },
                "years",
            ),
            (
                ErodeSettings {
                    talus_angle: Some(95.0),
                    ..Default::default()
                },
                "talus_angle_deg",
            ),
            (
                ErodeSettings {
                    fan_gradient: Some(-3.0),
                    ..Default::default()
                },
                "gradient_deg",
            ),
        ] {
            assert_eq!(s.check().unwrap_err().name, name, "{s:?}");
        }
    }

    #[test]
    fn the_stream_power_steps_add_up_to_the_years_asked() {
        let dem = Heightfield::from_fn(40, 32, 50.0, 50.0, |x, y| {
            300.0 - (x as f32 - 20.0).abs() * 6.0 - y as f32 * 2.0
        });
        let only_sp = |years: f64, dt: Option<f64>| {
            ErodeSettings {
                years: Some(years),
                dt,
                hydraulic_iterations: Some(0),
                thermal_iterations: Some(0),
                fill_pits: Some(false),
                ..Default::default()
            }
            .run(&dem, None, &relief_heightfield::NoProgress, &|| false)
            .unwrap()
        };
        // 300 yr with the preset's 10 kyr step is one step of 300 yr, not of 10 kyr.
        let short = only_sp(300.0, None);
        let sp = short.figures.plan.stream_power.unwrap();
        assert_eq!(
            (sp.params.dt, short.figures.stream_power.unwrap().steps),
            (300.0, 1)
        );
        assert_eq!(short.terrain, only_sp(300.0, Some(300.0)).terrain);
        assert!(short.figures.eroded_m3 < only_sp(10_000.0, None).figures.eroded_m3 / 5.0);
        // 25 kyr in steps of at most 10 kyr: three equal steps of 8333 yr.
        let odd = only_sp(25_000.0, None);
        assert_eq!(odd.figures.stream_power.unwrap().steps, 3);
        assert_eq!(odd.terrain, only_sp(25_000.0, Some(25_000.0 / 3.0)).terrain);
    }

    #[test]
    fn erosion_and_deposition_balance_the_change_net_of_uplift() {
        let dem = Heightfield::from_fn(48, 40, 50.0, 60.0, |x, y| {
            let (dx, dy) = (x as f32 - 24.0, y as f32 - 20.0);
            400.0 - (dx * dx + dy * dy).sqrt() * 9.0
                + relief_heightfield::rng::unit_f32(relief_heightfield::rng::hash(
                    1,
                    (y * 48 + x) as u64,
                    0,
                    0,
                ))
        });
        let s = ErodeSettings {
            years: Some(5_000.0),
            dt: Some(1_000.0),
            uplift: Some(1e-3),
            hydraulic_iterations: Some(20),
            thermal_iterations: Some(5),
            ..Default::default()
        };
        let out = s
            .run(&dem, None, &relief_heightfield::NoProgress, &|| false)
            .unwrap();
        let f = &out.figures;
        assert!(f.eroded_m3 > 0.0 && f.stream_power.unwrap().steps == 5);
        for i in 0..dem.len() {
            let (a, b, e, d) = (
                dem.as_slice()[i] as f64,
                out.terrain.as_slice()[i] as f64,
                out.erosion.as_slice()[i] as f64,
                out.deposition.as_slice()[i] as f64,
            );
            assert!(e >= 0.0 && d >= 0.0 && e * d == 0.0);
            let (x, y) = (i % 48, i / 48);
            let edge = x == 0 || y == 0 || x == 47 || y == 39;
            let up = if edge { 0.0 } else { 5.0 };
            assert!((b - a - up - (d - e)).abs() < 1e-3, "cell {i}");
        }
        // The erosion leaves no closed depression the input did not have.
        let pits = crate::stats::drainage(&out.terrain).pits_per_km2;
        assert!(pits <= crate::stats::drainage(&dem).pits_per_km2, "{pits}");
        let stopped = s.run(&dem, None, &relief_heightfield::NoProgress, &|| true);
        // On a 2 m grid the preset's 50 kyr are capped at cell^2 / 4D (100 yr at D = 0.01);
        // an explicit `years` is kept.
        let fine = ErodeSettings::default().plan_for(2.0, 2.0);
        assert_eq!(fine.stream_power.unwrap().years, 100.0);
        assert_eq!(
            ErodeSettings::default()
                .plan_for(60.0, 90.0)
                .stream_power
                .unwrap()
                .years,
            50_000.0
        );
        assert_eq!(s.plan_for(2.0, 2.0).stream_power.unwrap().years, 5_000.0);
        assert!(matches!(stopped, Err(LandscapeError::Stopped(_))));
    }
}
