//! Stage `fill_voids`: fills the DEM's own voids with the harmonic fill of relief-heightfield,
//! and measures the fill on a known hole: a disc of valid cells is blanked, filled and compared
//! with the truth (RMSE and max-abs in metres inside the hole).

use anyhow::Result;
use relief_heightfield::fill::{FillSettings, fill_voids};
use relief_heightfield::{Heightfield, Progress, metrics};

use super::{Stage, StageCx, Tolerance};

/// Tolerance of the fill check golden: the conjugate-gradient solve stops at a relative
/// residual of 1e-7, so reruns agree far below a millimetre.
const FILL_TOLERANCE: Tolerance = Tolerance {
    max_abs_m: 1e-2,
    rmse_m: 1e-3,
};

/// Fills voids (the next stages get a complete terrain) and reports fill quality.
#[derive(Debug)]
pub(crate) struct FillVoids;

/// Working bytes per cell of the stage: the terrain's copy (4), the fill's unknowns, residual,
/// direction, product and preconditioner (5 x 8) and its masks.
const FILL_BYTES_PER_CELL: f64 = 48.0;

impl Stage for FillVoids {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let settings = FillSettings::default();
        let mut hf = cx.state.terrain()?.clone();
        // Pre-flight under `relief run --max-memory`: the copy and the conjugate-gradient
        // vectors (f64) of the harmonic fill over the grid.
        cx.config.limits.check_memory(
            "fill_voids",
            hf.len() as f64 * FILL_BYTES_PER_CELL,
            "a smaller terrain (`crop`)",
        )?;
        let voids = hf.void_count();
        cx.section.figure("voids_before", voids);
        let progress = cx.progress();
        if voids > 0 {
            progress.begin("harmonic fill of the DEM's voids", voids as u64);
            let rep = fill_voids(&mut hf, &settings)?;
            cx.section.figure("filled", rep.filled);
            cx.section.figure("cg_iterations", rep.iterations);
            cx.section
                .figure("relative_residual", rep.relative_residual);
            cx.save_raster(
                "filled",
                "voids filled (harmonic)",
                &hf,
                Some(FILL_TOLERANCE),
            )?;
        }

        // Fill check on a known hole: blank a disc of radius min(w, h) / 8 centred in the grid.
        let (w, h) = (hf.width(), hf.height());
        let r = (w.min(h) / 8).max(2) as f64;
        let (x0, y0) = (w as f64 / 2.0, h as f64 / 2.0);
        let in_hole = |x: usize, y: usize| (x as f64 - x0).hypot(y as f64 - y0) <= r;
        let mut holed: Heightfield = hf.clone();
        for y in 0..h {
            for x in 0..w {
                if in_hole(x, y) {
                    holed.set(x, y, f32::NAN);
                }
            }
        }
        let blanked = holed.void_count();
        let mut refilled = holed.clone();
        progress.begin("fill check on a known hole", blanked as u64);
        let rep = fill_voids(&mut refilled, &settings)?;
        let (mut se, mut max_abs) = (0.0f64, 0.0f64);
        for y in 0..h {
            for x in 0..w {
                if in_hole(x, y) {
                    let d = (refilled.get(x, y) - hf.get(x, y)) as f64;
                    se += d * d;
                    max_abs = max_abs.max(d.abs());
                }
            }
        }
        let rmse = (se / blanked.max(1) as f64).sqrt();
        cx.section.figure("check_hole_cells", blanked);
        cx.section.figure("check_cg_iterations", rep.iterations);
        cx.section.figure("check_rmse_in_hole_m", rmse);
        cx.section.figure("check_max_abs_in_hole_m", max_abs);
        cx.section.figure(
            "check_psnr_db",
            metrics::psnr(&hf, &refilled).unwrap_or(f64::INFINITY),
        );
        if cx.config.previews {
            cx.save_preview("fill_check_hole", "known hole (void)", &holed)?;
        }
        cx.save_raster(
            "fill_check",
            "known hole, filled",
            &refilled,
            Some(FILL_TOLERANCE),
        )?;
        cx.state.set_terrain(hf);
        Ok(())
    }
}
