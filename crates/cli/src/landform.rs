//! `--landform`: the drainage-aware finishing of the detail methods' outputs
//! ([`relief_landscape::landform`]), on by default, off in the paper modes.

use anyhow::{Context, Result};
use relief_heightfield::{Heightfield, Progress};
use relief_landscape::landform::{LandformSettings, finish_until};

use crate::ctx::Ctx;

/// `--landform` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Switch {
    /// The pass runs.
    On,
    /// The method's raw output.
    Off,
}

/// The `--landform` option of the detail commands.
#[derive(clap::Args, Debug, Clone, Copy)]
pub(crate) struct LandformArg {
    /// Landform pass over the result (relief-landscape): closed depressions the detail made are
    /// breached, channels are incised along the routed flow (stream power, no uplift) and the
    /// result is brought back to the input's box averages, so the terrain drains like real
    /// terrain instead of being grain. Default: on, off with the paper's method. Needs the
    /// whole raster in memory: skipped (with a note) for `.sct` models, `--window` and
    /// streamed outputs (route those with `relief flow` / `relief erode`).
    #[arg(long, value_enum, value_name = "on|off")]
    pub(crate) landform: Option<Switch>,
}

impl LandformArg {
    /// True when the pass runs (`paper`: the command's paper mode, whose default is off).
    pub(crate) fn on(&self, paper: bool) -> bool {
        self.landform.map_or(!paper, |s| s == Switch::On)
    }
}

/// Runs the pass over `fine` (the detail method's output over the whole grid of `coarse`
/// times an integer factor) and notes what it did.
pub(crate) fn apply(fine: Heightfield, coarse: &Heightfield, ctx: &Ctx) -> Result<Heightfield> {
    let progress = ctx.progress();
    progress.begin("landform pass", 0);
    // --max-time holds: the pass is asked to stop at the deadline.
    let (out, r) = finish_until(&fine, coarse, &LandformSettings::default(), &|| {
        progress.stopped()
    })
    .context("the landform pass failed")?;
    drop(progress);
    ctx.note(format!(
        "landform pass: {} depressions breached or filled ({} cells lowered, {} raised), \
         consistency with the input {:.3} m RMS",
        r.pits_before, r.breached_cells, r.filled_cells, r.consistency_rms_m
    ));
    Ok(out)
}

/// The note for a run whose pass is on but cannot run (`why`: the output kind).
pub(crate) fn skipped(ctx: &Ctx, why: &str) {
    ctx.note(format!(
        "note: no landform pass for {why} (it routes water over the whole raster); \
         route the result with `relief flow` or `relief erode`, or pass --landform off"
    ));
}
