//! `relief info FILE`: format, size, cell size, elevation range, void count, georeference.

use std::path::PathBuf;

use anyhow::Result;

use crate::ctx::Ctx;
use crate::describe;

/// Arguments of `relief info`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Raster to describe (format detected from its content).
    pub(crate) file: PathBuf,
    /// Print one JSON object (size, dtype, nodata, CRS, GDAL-order geotransform, cell size,
    /// statistics, voids) instead of text.
    #[arg(long)]
    pub(crate) json: bool,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Prints the description on stdout.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    if describe::is_model(&args.file) {
        return crate::staging::print(&describe::model(&args.file, args.json, ctx)?);
    }
    // The description says when the cell size is assumed; no separate warning.
    let read = super::ReadArgs {
        warn_assumed_cell: false,
        ..args.read.clone()
    };
    let raster = super::read_raster(&args.file, &read, ctx)?;
    let assumed = super::cell_size_assumed(&args.file, &raster, &read);
    crate::staging::print(&if args.json {
        crate::staging::json_text(&describe::raster_json(&args.file, &raster, assumed))?
    } else {
        describe::raster_text(&args.file, &raster, assumed)
    })
}
