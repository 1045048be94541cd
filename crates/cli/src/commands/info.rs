//! `relief info FILE`: format, size, cell size, elevation range, void count, georeference.

use std::path::PathBuf;

use anyhow::{Context, Result};
use relief_heightfield::metrics;

use crate::ctx::Ctx;

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
    let raster = super::read_raster(&args.file, &args.read, ctx)?;
    let hf = &raster.heightfield;
    let (cx, cy) = hf.cell_size();
    if args.json {
        let stats = metrics::stats(hf).ok();
        let g = hf.georef();
        let v = serde_json::json!({
            "file": args.file.display().to_string(),
            "format": format!("{:?}", raster.format),
            "dtype": raster.dtype,
            "size": [hf.width(), hf.height()],
            "nodata": raster.nodata,
            "stored_south_up": raster.rows_flipped,
            "cell_size_m": [cx, cy],
            "crs": g.and_then(|g| g.crs.clone()),
            "epsg": g
                .and_then(|g| g.crs.as_deref())
                .and_then(|c| c.strip_prefix("EPSG:"))
                .and_then(|c| c.parse::<u32>().ok()),
            "geotransform": g.and_then(|g| g.geotransform),
            "statistics": stats.map(|s| serde_json::json!({
                "min": s.min, "max": s.max, "mean": s.mean, "std": s.std
            })),
            "voids": hf.void_count(),
            "cells": hf.len(),
        });
        let mut stdout = std::io::stdout().lock();
        let text = serde_json::to_string_pretty(&v).context("cannot encode the JSON")?;
        std::io::Write::write_all(&mut stdout, format!("{text}\n").as_bytes())
            .context("cannot write to stdout")?;
        return Ok(());
    }
    let mut out = String::new();
    out.push_str(&format!("file:        {}\n", args.file.display()));
    let nodata = raster
        .nodata
        .map(|v| format!(", nodata {v}"))
        .unwrap_or_default();
    out.push_str(&format!(
        "format:      {:?} ({}{nodata}{})\n",
        raster.format,
        raster.dtype,
        if raster.rows_flipped {
            ", stored south-up"
        } else {
            ""
        }
    ));
    out.push_str(&format!(
        "size:        {} x {} (width x height)\n",
        hf.width(),
        hf.height()
    ));
    out.push_str(&format!(
        "cell size:   {cx:.3} x {cy:.3} m (east-west x north-south)\n"
    ));
    match metrics::stats(hf) {
        Ok(s) => out.push_str(&format!(
            "elevation:   {:.2} .. {:.2} m (mean {:.2}, std {:.2})\n",
            s.min, s.max, s.mean, s.std
        )),
        Err(_) => out.push_str("elevation:   none (every cell is void)\n"),
    }
    out.push_str(&format!(
        "voids:       {} of {} cells\n",
        group_thousands(hf.void_count()),
        group_thousands(hf.len())
    ));
    match hf.georef() {
        Some(g) => {
            out.push_str("georeference:\n");
            if let Some(crs) = &g.crs {
                out.push_str(&format!("  crs:           {crs}\n"));
            }
            if let Some(t) = &g.geotransform {
                // The two lines gdalinfo prints (same digits), pixel-is-area corner origin.
                out.push_str(&format!("  Origin = ({:.15},{:.15})\n", t[0], t[3]));
                out.push_str(&format!("  Pixel Size = ({:.15},{:.15})\n", t[1], t[5]));
                if t[2] != 0.0 || t[4] != 0.0 {
                    out.push_str(&format!("  rotation:      ({}, {})\n", t[2], t[4]));
                }
            }
            if let Some(s) = &g.pixel_scale {
                out.push_str(&format!("  pixel scale:   {s:?}\n"));
            }
            if let Some(t) = &g.tiepoints {
                out.push_str(&format!("  tiepoints:     {t:?}\n"));
            }
            if let Some(k) = &g.geo_key_directory {
                out.push_str(&format!(
                    "  geokeys:       {} keys\n",
                    k.get(3).copied().unwrap_or(0)
                ));
            }
        }
        None => out.push_str("georeference: none\n"),
    }
    let mut stdout = std::io::stdout().lock();
    std::io::Write::write_all(&mut stdout, out.as_bytes()).context("cannot write to stdout")?;
    Ok(())
}

/// `54278` -> `54,278`.
pub(crate) fn group_thousands(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::group_thousands;

    #[test]
    fn thousands() {
        assert_eq!(group_thousands(0), "0");
        assert_eq!(group_thousands(999), "999");
        assert_eq!(group_thousands(54278), "54,278");
        assert_eq!(group_thousands(1442401), "1,442,401");
    }
}
