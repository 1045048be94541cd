//! Stage `load`: reads the input DEM through relief-io, crops it when asked, records its
//! statistics and writes it with a shaded preview.

use anyhow::{Context, Result};
use relief_heightfield::metrics;

use super::{Stage, StageCx, Tolerance};

/// Reads `config.input` (any format relief-io detects) and makes it the current terrain.
#[derive(Debug)]
pub(crate) struct Load;

impl Stage for Load {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let input = &cx.config.input;
        let raster = relief_io::read(input, &relief_io::ReadOptions::default())
            .with_context(|| format!("cannot read {}", input.display()))?;
        cx.section
            .figure("format", format!("{:?} ({})", raster.format, raster.dtype));
        // A PNG, Terrain-RGB, EXR, raw or NPY input stores no cell size: the 1 m stand-in is
        // flagged in the figures and the report.
        let assumed = !relief_io::heightmap16::cell_size_stored(input, &raster);
        cx.section.figure("cell_size_assumed", assumed);
        if assumed {
            cx.section.note(&format!(
                "{} stores no cell size: 1 x 1 m cells are assumed, so every figure in metres \
                 (slopes, areas, feature sizes) is only as right as that guess",
                input.display()
            ));
        }
        let mut hf = raster.heightfield;
        if let Some((x, y, w, h)) = cx.config.crop {
            hf = hf.crop(x, y, w, h)?;
            cx.section.figure("crop", [x, y, w, h]);
        }
        let s = metrics::stats(&hf)?;
        let (cx_m, cy_m) = hf.cell_size();
        cx.section.figure("width", hf.width());
        cx.section.figure("height", hf.height());
        cx.section.figure("cell_x_m", cx_m);
        cx.section.figure("cell_y_m", cy_m);
        cx.section.figure("min_m", s.min);
        cx.section.figure("max_m", s.max);
        cx.section.figure("mean_m", s.mean);
        cx.section.figure("std_m", s.std);
        cx.section.figure("voids", s.voids);
        cx.section.figure("georeferenced", hf.georef().is_some());
        cx.save_raster(
            "dem",
            "input DEM (hillshade over elevation ramp)",
            &hf,
            Some(Tolerance::EXACT),
        )?;
        cx.state.source = Some(hf.clone());
        cx.state.set_terrain(hf);
        Ok(())
    }
}
