//! Stage `erode`: relief-landscape's erode job (`relief erode`'s code; params `job` =
//! [`ErodeSettings`]) on the input DEM as loaded (`input: "source"`, the default: erosion at
//! the real terrain's own cell size, shown beside it; the pipeline's terrain is left as it is)
//! or on the current terrain (`input: "terrain"`: the eroded terrain is handed on). The report
//! shows the terrain before and after, the channel network of the result over its hillshade,
//! the drainage statistics of terrain_quality.py before and after, and (`presets`, default on)
//! every preset's result beside the input, with its time and statistics.

use std::time::Instant;

use anyhow::{Context, Result};
use relief_heightfield::NoProgress;
use relief_landscape::erode::job::{ErodeOutput, ErodeSettings, Preset};
use relief_landscape::flow::job::FlowSettings;
use relief_landscape::stats::{DrainageStats, drainage};
use serde::{Deserialize, Serialize};

use super::report::fmt_num;
use super::spec::StageParams;
use super::{Stage, StageCx, StageInput};

/// Parameters of the `erode` stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct ErodeParams {
    /// The job, exactly as `relief erode` builds it (`preset` and its overrides).
    pub(crate) job: ErodeSettings,
    /// Which terrain is eroded: the input DEM as loaded (the terrain is not changed) or the
    /// current terrain (replaced by the eroded one).
    pub(crate) input: StageInput,
    /// The terrain's centre is cropped to at most this many cells per side (0 = no crop).
    pub(crate) max_size: usize,
    /// Also run every preset and show each beside the input.
    pub(crate) presets: bool,
}

impl Default for ErodeParams {
    fn default() -> Self {
        Self {
            job: ErodeSettings::default(),
            input: StageInput::Source,
            max_size: 1024,
            presets: true,
        }
    }
}

impl StageParams for ErodeParams {
    fn check_params(&self) -> Result<()> {
        self.job.check().context("invalid `job`")?;
        crate::check_max_size(self.max_size, 16)
    }
}

impl Stage for ErodeParams {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = self;
        let (terrain, _) = cx.input_terrain("erode", p.input)?;
        let (w, h) = (terrain.width(), terrain.height());
        let dem = cx.centre_crop_to(terrain, p.max_size)?;
        // Pre-flight under `relief run --max-memory`: the library's bytes per cell of the
        // erosion and the stage's copies of its rasters.
        cx.config.limits.check_memory(
            "erode",
            dem.len() as f64
                * (relief_landscape::erode::job::ErodeSettings::BYTES_PER_CELL + 12) as f64,
            "a smaller `max_size`",
        )?;
        let mut job = p.job.clone();
        job.seed ^= cx.config.seed;
        let t0 = Instant::now();
        let out = job
            .run(&dem, None, &cx.progress(), &|| {
                cx.config.limits.past_deadline()
            })
            .context("cannot erode the terrain")?;
        let seconds = t0.elapsed().as_secs_f64();
        cx.section.figure("seconds", seconds);
        cx.section.figure("preset", job.preset.name());
        for (k, v) in [
            ("eroded_m3", out.figures.eroded_m3),
            ("deposited_m3", out.figures.deposited_m3),
            ("max_erosion_m", out.figures.max_erosion_m),
            ("max_deposition_m", out.figures.max_deposition_m),
        ] {
            cx.section.figure(k, v);
        }
        cx.section
            .figure("plan", serde_json::to_value(out.figures.plan)?);
        cx.save_raster(
            "erode_terrain",
            &format!("the terrain after the `{}` preset", job.preset.name()),
            &out.terrain,
            None,
        )?;
        cx.before_after(
            "erode",
            &format!(
                "the terrain before (left) and after (right) the `{}` preset: stream power, \
                 hydraulic erosion, talus",
                job.preset.name()
            ),
            &dem,
            &out.terrain,
        )?;
        self.channels(cx, &out)?;
        if cx.config.previews {
            let (w, h, rgb) = crate::change::change_map(&out)?;
            cx.save_rgb(
                "erode_change",
                &format!(
                    "where the `{}` preset lowered (blue) and raised (orange: fans, talus,                      filled hollows) the terrain, over its hillshade; the tint is full at {} m",
                    job.preset.name(),
                    crate::change::CHANGE_FULL_M
                ),
                w,
                h,
                &rgb,
            )?;
        }
        let before = drainage(&dem);
        let after = drainage(&out.terrain);
        cx.section.headline("pits_per_km2", after.pits_per_km2);
        cx.section.headline("beta", after.beta);
        cx.section.figure("input_beta", before.beta);
        let mut rows = vec![
            row("input", None, before),
            row(job.preset.name(), Some(seconds), after),
        ];
        if p.presets && cx.config.previews {
            for preset in Preset::ALL.into_iter().filter(|&q| q != job.preset) {
                let s = ErodeSettings {
                    preset,
                    seed: job.seed,
                    ..ErodeSettings::default()
                };
                let t = Instant::now();
                let o = s
                    .run(&dem, None, &NoProgress, &|| false)
                    .with_context(|| format!("cannot erode with the `{}` preset", preset.name()))?;
                let secs = t.elapsed().as_secs_f64();
                cx.before_after(
                    &format!("erode_{}", preset.name()),
                    &format!(
                        "the `{}` preset (right) beside the input (left)",
                        preset.name()
                    ),
                    &dem,
                    &o.terrain,
                )?;
                rows.push(row(preset.name(), Some(secs), drainage(&o.terrain)));
            }
        }
        cx.section.table(
            "drainage statistics (terrain_quality.py) of the input and of each preset's result: \
             pits, mean closed-depression fill depth, drainage-area exponent beta",
            &["surface", "seconds", "pits / km2", "fill depth (m)", "beta"],
            rows,
        );
        if p.input == StageInput::Terrain && (w, h) == (dem.width(), dem.height()) {
            cx.state.set_terrain(out.terrain);
        }
        Ok(())
    }
}

fn row(name: &str, seconds: Option<f64>, s: DrainageStats) -> Vec<String> {
    vec![
        name.to_string(),
        seconds.map_or("-".into(), fmt_num),
        fmt_num(s.pits_per_km2),
        fmt_num(s.fill_depth_m),
        fmt_num(s.beta),
    ]
}

impl ErodeParams {
    /// The channel network of the eroded terrain over its hillshade.
    fn channels(&self, cx: &mut StageCx<'_>, out: &ErodeOutput) -> Result<()> {
        if !cx.config.previews {
            return Ok(());
        }
        let flow = FlowSettings::default()
            .run(&out.terrain, &NoProgress)
            .context("cannot route the eroded terrain")?;
        let (iw, ih, rgb) = crate::channels::channel_map_within(
            &out.terrain,
            &flow.direction,
            &flow.strahler,
            2048,
        )?;
        cx.save_rgb(
            "erode_channels",
            &format!(
                "channels of the eroded terrain (from 1 km2 of drainage area), wider by Strahler \
                 order (highest {})",
                flow.figures.max_order
            ),
            iw,
            ih,
            &rgb,
        )
    }
}

/// The eroded terrain of `hf` under the default job (for tests).
#[cfg(test)]
fn eroded(hf: &relief_heightfield::Heightfield) -> relief_heightfield::Heightfield {
    ErodeSettings::default()
        .run(hf, None, &NoProgress, &|| false)
        .unwrap()
        .terrain
}

#[cfg(test)]
mod tests {
    use super::super::State;
    use super::*;

    /// On a crop of the fixture: the eroded terrain is saved, the figures and the drainage
    /// table are there, the terrain is left alone with `input: source` and replaced with
    /// `input: terrain`.
    #[test]
    fn stage_erodes_the_source_or_the_terrain() {
        let (mut config, _tmp) = crate::test_config(None);
        config.previews = false;
        let src = crate::test_input_crop(&config, (100, 100, 96, 80));
        for input in [StageInput::Source, StageInput::Terrain] {
            let mut state = State {
                source: Some(src.clone()),
                ..Default::default()
            };
            state.set_terrain(src.clone());
            let stage = ErodeParams {
                input,
                ..Default::default()
            };
            stage.check_params().unwrap();
            let section = crate::run_stage(&stage, "erode", &config, &mut state).unwrap();
            assert!(section.figures.get("eroded_m3").unwrap().as_f64().unwrap() > 0.0);
            assert!(section.figures.contains_key("beta"));
            let expected = eroded(&src);
            assert_eq!(state.outputs[0].raster.as_slice(), expected.as_slice());
            let t = state.terrain().unwrap();
            match input {
                StageInput::Source => assert_eq!(t.as_slice(), src.as_slice()),
                StageInput::Terrain => assert_eq!(t.as_slice(), expected.as_slice()),
            }
        }
        // The change map: blue over lowered cells, orange over raised ones, grey elsewhere.
        let hf = src.clone();
        let n = hf.len();
        let mut out = ErodeSettings::default()
            .run(&hf, None, &NoProgress, &|| false)
            .unwrap();
        let mut lowered = vec![0f32; n];
        let mut raised = vec![0f32; n];
        lowered[0] = 40.0;
        raised[1] = 40.0;
        out.erosion = hf.with_data(lowered).unwrap();
        out.deposition = hf.with_data(raised).unwrap();
        let (w, h, rgb) = crate::change::change_map(&out).unwrap();
        assert_eq!((w, h, rgb.len()), (hf.width(), hf.height(), 3 * n));
        assert!(rgb[2] > rgb[0], "lowered {:?}", &rgb[..3]);
        assert!(rgb[3] > rgb[5], "raised {:?}", &rgb[3..6]);
        let grey = &rgb[3 * 10..3 * 11];
        assert!(grey[0] == grey[1] && grey[1] == grey[2], "{grey:?}");
        assert!(
            ErodeParams {
                max_size: 3,
                ..Default::default()
            }
            .check_params()
            .is_err()
        );
    }
}
