//! The descriptions the commands print: what `relief info` says of a raster (format, size,
//! cell size, elevation range, voids, georeference) and of a `.sct` model or `.dict`
//! dictionary, as text or JSON, and the figures of `relief compress`.

use std::path::Path;

use anyhow::{Context, Result};
use relief_heightfield::metrics;

use crate::ctx::Ctx;

/// The description of a raster as JSON (`relief info --json`).
/// `cell_assumed`: the file stores no cell size and none was given (the 1 m stand-in).
pub(crate) fn raster_json(
    file: &Path,
    raster: &relief_io::Raster,
    cell_assumed: bool,
) -> serde_json::Value {
    let hf = &raster.heightfield;
    let (cx, cy) = hf.cell_size();
    let stats = metrics::stats(hf).ok();
    let g = hf.georef();
    serde_json::json!({
        "file": file.display().to_string(),
        "format": format!("{:?}", raster.format),
        "dtype": raster.dtype,
        "size": [hf.width(), hf.height()],
        "nodata": raster.nodata,
        "stored_south_up": raster.rows_flipped,
        "cell_size_m": [cx, cy],
        "cell_size_assumed": cell_assumed,
        "crs": g.and_then(|g| g.crs.clone()),
        "epsg": g
            .and_then(|g| g.crs.as_deref())
            .and_then(|c| c.strip_prefix("EPSG:"))
            .and_then(|c| c.parse::<u32>().ok()),
        "wkt": g.and_then(relief_io::crs::wkt),
        "geotransform": g.and_then(|g| g.geotransform),
        "statistics": stats.map(|s| serde_json::json!({
            "min": s.min, "max": s.max, "mean": s.mean, "std": s.std
        })),
        "voids": hf.void_count(),
        "cells": hf.len(),
    })
}

/// The description of a raster as text (`relief info`).
/// (`cell_assumed` as in [`raster_json`].)
pub(crate) fn raster_text(file: &Path, raster: &relief_io::Raster, cell_assumed: bool) -> String {
    let hf = &raster.heightfield;
    let (cx, cy) = hf.cell_size();
    let mut out = String::new();
    out.push_str(&format!("file:        {}\n", file.display()));
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
        "cell size:   {cx:.3} x {cy:.3} m (east-west x north-south){}\n",
        if cell_assumed {
            "; ASSUMED: the file stores none (pass --cell-size)"
        } else {
            ""
        }
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
    out
}

/// Whether `path` starts with the magic of a `.sct` model or a `.dict` dictionary.
pub(crate) fn is_model(path: &Path) -> bool {
    head(path).is_some_and(|h| {
        &h == relief_sparse_core::format::MAGIC
            || &h == relief_sparse_core::format::DICTIONARY_MAGIC
    })
}

/// Whether `path` starts with the magic of a construction tree (`.sct`).
pub(crate) fn is_tree(path: &Path) -> bool {
    head(path).is_some_and(|h| &h == relief_sparse_core::format::MAGIC)
}

/// The first 8 bytes of `path`.
fn head(path: &Path) -> Option<[u8; 8]> {
    use std::io::Read as _;
    let mut head = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .ok()
        .map(|_| head)
}

/// One dictionary, for `info`: atoms, patch size, spacing, support radius, function atoms.
fn dictionary_json(d: &relief_sparse_core::Dictionary) -> serde_json::Value {
    let functions = d
        .atoms()
        .iter()
        .filter(|a| !matches!(a, relief_sparse_core::dictionary::Atom::Data(_)))
        .count();
    serde_json::json!({
        "atoms": d.len(),
        "patch_size": d.patch_size(),
        "spacing": d.spacing(),
        "support_radius": d.support_radius(),
        "function_atoms": functions,
    })
}

/// Describes a `.sct` model or a `.dict` dictionary: version, checksum, size,
/// cell size, georeference, and per layer the atoms, patch size and primitives.
pub(crate) fn model(path: &Path, json: bool, ctx: &Ctx) -> Result<String> {
    let bytes = crate::sparse_model::read_model_bytes(path, ctx)?;
    let header = relief_sparse_core::format::stream_header(&bytes)
        .with_context(|| format!("cannot read {}: not a model", path.display()))?;
    let reg = crate::sparse_model::registry();
    let checksum = match header.checksum_ok {
        Some(true) => "CRC-32 ok",
        Some(false) => "CRC-32 MISMATCH",
        None => "none (older version)",
    };
    let v = if header.is_sct {
        let sct = relief_sparse_core::Sct::from_bytes(&bytes, &reg)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let layers: Vec<serde_json::Value> = sct
            .layers()
            .iter()
            .map(|l| {
                let mut d = dictionary_json(l.dictionary());
                d["primitives"] = l.len().into();
                d["coefficients"] = l.coefficients().len().into();
                d["max_sparsity"] = l.max_sparsity().into();
                d
            })
            .collect();
        let fields: Vec<serde_json::Value> = sct
            .fields()
            .iter()
            .map(|f| {
                serde_json::json!({
                    "size": [f.width(), f.height()],
                    "origin": f.origin(),
                    "step": f.step(),
                    "kernel": f.kernel().name(),
                })
            })
            .collect();
        let g = sct.georef();
        serde_json::json!({
            "file": path.display().to_string(),
            "format": "sct",
            "version": header.version,
            "checksum": checksum,
            "bytes": bytes.len(),
            "size": [sct.width(), sct.height()],
            "cell_size_m": [sct.cell_size().0, sct.cell_size().1],
            "crs": g.and_then(|g| g.crs.clone()),
            "geotransform": g.and_then(|g| g.geotransform),
            "layers": layers,
            "fields": fields,
        })
    } else {
        let d = relief_sparse_core::Dictionary::from_bytes(&bytes, &reg)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let mut v = dictionary_json(&d);
        v["file"] = path.display().to_string().into();
        v["format"] = "dict".into();
        v["version"] = header.version.into();
        v["checksum"] = checksum.into();
        v["bytes"] = bytes.len().into();
        v
    };
    if json {
        crate::staging::json_text(&v)
    } else {
        Ok(model_text(&v))
    }
}

/// The text form of [`model`]'s JSON.
fn model_text(v: &serde_json::Value) -> String {
    let mut out = String::new();
    let f = |k: &str| v[k].to_string().trim_matches('"').to_string();
    out.push_str(&format!("file:        {}\n", f("file")));
    let kind = if v["format"] == "sct" {
        "Sparse Construction Tree model (.sct)"
    } else {
        "dictionary (.dict)"
    };
    out.push_str(&format!(
        "format:      {kind}, version {}, {} bytes\n",
        f("version"),
        f("bytes")
    ));
    out.push_str(&format!("checksum:    {}\n", f("checksum")));
    let dict_lines = |out: &mut String, d: &serde_json::Value, indent: &str| {
        out.push_str(&format!(
            "{indent}atoms:       {} ({} function atoms), patch {} x {} samples, spacing {}, \
             support radius {}\n",
            d["atoms"],
            d["function_atoms"],
            d["patch_size"],
            d["patch_size"],
            d["spacing"],
            d["support_radius"]
        ));
    };
    if v["format"] == "sct" {
        out.push_str(&format!(
            "size:        {} x {} (width x height)\n",
            v["size"][0], v["size"][1]
        ));
        out.push_str(&format!(
            "cell size:   {} x {} m\n",
            v["cell_size_m"][0], v["cell_size_m"][1]
        ));
        let layers = v["layers"].as_array().cloned().unwrap_or_default();
        out.push_str(&format!("layers:      {}\n", layers.len()));
        for (i, l) in layers.iter().enumerate() {
            out.push_str(&format!(
                "  layer {i}: {} primitives, {} coefficients (sparsity <= {})\n",
                l["primitives"], l["coefficients"], l["max_sparsity"]
            ));
            dict_lines(&mut out, l, "    ");
        }
        for (i, f) in v["fields"].as_array().into_iter().flatten().enumerate() {
            out.push_str(&format!(
                "  field {i}: {} x {} samples every {} pixels, {} interpolation\n",
                f["size"][0],
                f["size"][1],
                f["step"],
                f["kernel"].as_str().unwrap_or("?")
            ));
        }
        match (&v["crs"], &v["geotransform"]) {
            (serde_json::Value::Null, serde_json::Value::Null) => {
                out.push_str("georeference: none\n")
            }
            (crs, t) => {
                out.push_str("georeference:\n");
                if !crs.is_null() {
                    out.push_str(&format!(
                        "  crs:           {}\n",
                        crs.to_string().trim_matches('"')
                    ));
                }
                if let Some(t) = t.as_array() {
                    out.push_str(&format!("  Origin = ({},{})\n", t[0], t[3]));
                    out.push_str(&format!("  Pixel Size = ({},{})\n", t[1], t[5]));
                }
            }
        }
    } else {
        dict_lines(&mut out, v, "");
    }
    out
}

/// What `relief compress` prints: the input, the dictionary, the primitives, the storage
/// figures (see [`report_lines`]) and the timings.
pub(crate) fn compression(
    input: &Path,
    hf: &relief_heightfield::Heightfield,
    job: &relief_dictionary_learning::CompressSettings,
    f: &relief_dictionary_learning::CompressFigures,
) -> String {
    let mut text = format!(
        "input:       {} ({} x {})\n",
        input.display(),
        hf.width(),
        hf.height()
    );
    text.push_str(&format!(
        "dictionary:  N = {} atoms of {a} x {a} (K = {}), delta {}, R {}: {}\n",
        f.report.n_atoms,
        f.report.k,
        f.spacing,
        f.radius,
        f.dictionary,
        a = f.patch_size
    ));
    text.push_str(&format!(
        "primitives:  n = {}, s = {}{}\n",
        f.report.n_patches,
        job.sparsity,
        if job.quantize {
            ", 16-bit coefficients"
        } else {
            ""
        }
    ));
    text.push_str(&report_lines(&f.report));
    text.push_str(&format!(
        "time:        dictionary {:.2} s, encode {:.2} s\n",
        f.dictionary_seconds, f.encode_seconds
    ));
    text
}

/// The report lines: storage, bytes, PSNR.
fn report_lines(f: &relief_sparse_core::CompressionReport) -> String {
    format!(
        "storage:     t(s, N) = KN + n(2s + 2) + 1 = {} values for t0 = {} samples: rho = {:.2} %\n\
         bytes:       {} ({:.2} % of the input as f32)\n\
         PSNR:        {:.2} dB (RMSE {:.3} m)\n",
        f.t,
        f.t0,
        100.0 * f.rho,
        f.bytes,
        100.0 * f.byte_ratio,
        f.psnr,
        f.rmse
    )
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
