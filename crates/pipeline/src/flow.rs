//! Stage `flow`: the drainage of the terrain the earlier stages produced (relief-landscape's
//! flow job, `relief flow`'s code; params = [`FlowSettings`]): the conditioned terrain (saved
//! whole, and a centre window of at most 128 x 128 cells as the golden), the terrain before and
//! after conditioning, the channel network in blue over the hillshade (wider by Strahler
//! order), the job's figures, and the drainage statistics of terrain_quality.py (pits per
//! km^2, mean closed-depression fill depth, drainage-area exponent beta) of the terrain and of
//! the input DEM side by side: synthetic relief should drain like the real one.

use anyhow::{Context, Result};
use relief_heightfield::Heightfield;
use relief_landscape::flow::job::FlowSettings;
use relief_landscape::stats::{DrainageStats, drainage};

use super::report::fmt_num;
use serde::{Deserialize, Serialize};

use super::spec::StageParams;
use super::{Stage, StageCx, Tolerance};

/// Tolerance of the conditioned window's golden: filling copies elevations of the terrain,
/// which the amplify stage hands on within its own tolerance (the dictionary stages').
const FLOW_TOLERANCE: Tolerance = Tolerance {
    max_abs_m: 0.5,
    rmse_m: 0.05,
};

/// Side of the golden window of the conditioned terrain.
const WINDOW: usize = 128;

/// Largest side of the channel map in the report (a larger terrain is drawn reduced).
const CHANNEL_MAP_SIDE: usize = 2048;

/// The `flow` stage: its parameters are the job's settings.
#[derive(Debug, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub(crate) struct FlowStage(pub(crate) FlowSettings);

impl StageParams for FlowStage {
    fn check_params(&self) -> Result<()> {
        self.0.check().context("invalid flow settings")
    }
}

impl Stage for FlowStage {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let terrain = cx.state.terrain()?.clone();
        // Pre-flight under `relief run --max-memory`: the library's bytes per cell of the
        // routing and the stage's copies of its rasters.
        cx.config.limits.check_memory(
            "flow",
            terrain.len() as f64
                * (relief_landscape::flow::job::FlowSettings::BYTES_PER_CELL + 16) as f64,
            "a smaller terrain (`crop`)",
        )?;
        let out = self
            .0
            .run(&terrain, &cx.progress())
            .context("cannot route the terrain")?;
        let (w, h) = (terrain.width(), terrain.height());
        cx.section.figure("size", [w, h]);
        if let serde_json::Value::Object(m) = serde_json::to_value(&out.figures)? {
            for (k, v) in m {
                cx.section.figure(&k, v);
            }
        }
        cx.section.headline("max_order", out.figures.max_order);
        cx.save_raster(
            "flow_filled",
            "the terrain with its closed depressions filled",
            &out.conditioned,
            None,
        )?;
        let (ww, wh) = (w.min(WINDOW), h.min(WINDOW));
        let window = out.conditioned.crop((w - ww) / 2, (h - wh) / 2, ww, wh)?;
        cx.save_raster(
            "flow_filled_window",
            &format!("centre {ww} x {wh} cells of the conditioned terrain (golden)"),
            &window,
            Some(FLOW_TOLERANCE),
        )?;
        cx.before_after(
            "flow_conditioning",
            "the terrain before (left) and after (right) its depressions are conditioned",
            &terrain,
            &out.conditioned,
        )?;
        if cx.config.previews {
            let (iw, ih, rgb) = crate::channels::channel_map_within(
                &terrain,
                &out.direction,
                &out.strahler,
                CHANNEL_MAP_SIDE,
            )?;
            cx.save_rgb(
                "flow_channels",
                &format!(
                    "channels from {} km2 of drainage area over the hillshade, wider by Strahler \
                     order (highest {})",
                    fmt_num(self.0.channel_area / 1e6),
                    out.figures.max_order
                ),
                iw,
                ih,
                &rgb,
            )?;
        }
        self.drainage_table(cx, &terrain)
    }
}

impl FlowStage {
    /// The drainage statistics of the terrain (figures) and of the input DEM beside them.
    fn drainage_table(&self, cx: &mut StageCx<'_>, terrain: &Heightfield) -> Result<()> {
        let mine = drainage(terrain);
        cx.section.headline("pits_per_km2", mine.pits_per_km2);
        cx.section.figure("fill_depth_m", mine.fill_depth_m);
        cx.section.headline("beta", mine.beta);
        let row = |name: &str, hf: &Heightfield, s: DrainageStats| {
            let (cx_m, cy_m) = hf.cell_size();
            vec![
                name.to_string(),
                format!("{} x {}", hf.width(), hf.height()),
                format!("{} x {}", fmt_num(cx_m), fmt_num(cy_m)),
                fmt_num(s.pits_per_km2),
                fmt_num(s.fill_depth_m),
                fmt_num(s.beta),
            ]
        };
        let mut rows = vec![row("terrain", terrain, mine)];
        if let Some(src) = cx.state.source.clone() {
            let s = drainage(&src);
            cx.section.figure("input_pits_per_km2", s.pits_per_km2);
            cx.section.figure("input_fill_depth_m", s.fill_depth_m);
            cx.section.figure("input_beta", s.beta);
            rows.push(row("input DEM", &src, s));
        }
        cx.section.table(
            "drainage statistics (terrain_quality.py): pits, mean closed-depression fill depth, \
             drainage-area exceedance exponent beta (about 0.4-0.5 on real fluvial terrain)",
            &[
                "surface",
                "cells",
                "cell (m)",
                "pits / km2",
                "fill depth (m)",
                "beta",
            ],
            rows,
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::State;
    use super::*;

    /// On a crop of the fixture: figures, the drainage statistics of the terrain and of the
    /// input, the conditioned terrain (never below the terrain) and its golden window, the
    /// channel map.
    #[test]
    fn stage_reports_drainage_of_the_terrain_and_the_input() {
        let (config, tmp) = crate::test_config(None);
        let src = crate::test_input_crop(&config, (100, 100, 160, 144));
        let mut state = State {
            source: Some(src.clone()),
            ..Default::default()
        };
        state.set_terrain(src.crop(0, 0, 150, 130).unwrap());
        let stage = FlowStage(FlowSettings {
            channel_area: 2e5,
            ..Default::default()
        });
        stage.check_params().unwrap();
        let section = crate::run_stage(&stage, "flow", &config, &mut state).unwrap();
        let fig = |k: &str| section.figures.get(k).cloned().unwrap_or_default();
        assert!(
            fig("reaches").as_u64().unwrap() > 0,
            "{:?}",
            section.figures
        );
        let pits = fig("pits_per_km2").as_f64().unwrap();
        assert!(pits > 0.0 && pits.is_finite(), "{pits}");
        assert!(fig("fill_depth_m").as_f64().unwrap() > 0.0);
        assert!(fig("beta").as_f64().unwrap() > 0.0);
        assert!(fig("input_beta").as_f64().is_some());
        let saved: Vec<&str> = state.outputs.iter().map(|o| o.name.as_str()).collect();
        assert_eq!(saved, ["flow_filled", "flow_filled_window"]);
        let filled = &state.outputs[0].raster;
        let terrain = state.terrain().unwrap();
        assert!(
            (filled.as_slice().iter().zip(terrain.as_slice())).all(|(f, t)| f >= t),
            "filling never lowers"
        );
        let win = &state.outputs[1].raster;
        assert_eq!((win.width(), win.height()), (128, 128));
        assert!(state.outputs[1].tolerance.is_some());
        for f in [
            "flow_channels.png",
            "flow_filled.tif",
            "flow_filled_window.tif",
        ] {
            assert!(tmp.path().join(f).is_file(), "{f} missing");
        }
        assert!(
            FlowStage(FlowSettings {
                channel_area: -1.0,
                ..Default::default()
            })
            .check_params()
            .is_err()
        );
    }
}
