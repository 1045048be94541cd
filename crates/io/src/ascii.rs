//! ESRI ASCII grid (`.asc`): a `key value` header (`ncols`, `nrows`, `xllcorner`/`xllcenter`,
//! `yllcorner`/`yllcenter`, `cellsize` or `dx`/`dy`, optional `NODATA_value`) followed by
//! `nrows` rows of `ncols` values, north row first.

use std::fmt::Write as _;

use relief_heightfield::{GeoRef, Heightfield};

use crate::util::{check_dims, finish};
use crate::{Format, IoError, Raster, ReadOptions, Result};

const F: Format = Format::AsciiGrid;

pub(crate) fn read(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| IoError::malformed(F, format!("not UTF-8 text: {e}")))?;
    let mut tokens = text.split_ascii_whitespace().peekable();
    let (mut ncols, mut nrows) = (None, None);
    let (mut x0, mut y0, mut center) = (0.0f64, 0.0f64, false);
    let (mut dx, mut dy) = (None, None);
    let mut nodata = None;
    while let Some(&tok) = tokens.peek() {
        if !tok.starts_with(|c: char| c.is_ascii_alphabetic()) || tok.eq_ignore_ascii_case("nan") {
            break;
        }
        let key = tok.to_ascii_lowercase();
        tokens.next();
        let val = tokens
            .next()
            .ok_or_else(|| IoError::malformed(F, format!("header key `{key}` has no value")))?;
        let num = || -> Result<f64> {
            val.parse::<f64>().map_err(|_| {
                IoError::malformed(F, format!("header `{key}` = {val:?} is not a number"))
            })
        };
        let int = || -> Result<u64> {
            val.parse::<u64>().map_err(|_| {
                IoError::malformed(
                    F,
                    format!("header `{key}` = {val:?} is not a non-negative integer"),
                )
            })
        };
        match key.as_str() {
            "ncols" => ncols = Some(int()?),
            "nrows" => nrows = Some(int()?),
            "xllcorner" => x0 = num()?,
            "yllcorner" => y0 = num()?,
            "xllcenter" => {
                x0 = num()?;
                center = true;
            }
            "yllcenter" => {
                y0 = num()?;
                center = true;
            }
            "cellsize" => {
                let c = num()?;
                dx = Some(c);
                dy = Some(c);
            }
            "dx" | "xdim" => dx = Some(num()?),
            "dy" | "ydim" => dy = Some(num()?),
            "nodata_value" => nodata = Some(num()?),
            _ => return Err(IoError::malformed(F, format!("unknown header key `{key}`"))),
        }
    }
    let w = ncols.ok_or_else(|| IoError::malformed(F, "header has no `ncols`"))?;
    let h = nrows.ok_or_else(|| IoError::malformed(F, "header has no `nrows`"))?;
    let n = check_dims(F, w, h, opts)?;
    // Every value takes at least two bytes (digit + separator): a header promising more values
    // than the file can hold is rejected before allocating.
    if n as u64 > bytes.len() as u64 / 2 + 1 {
        return Err(IoError::malformed(
            F,
            format!(
                "header declares {w} x {h} = {n} values but the file has only {} bytes",
                bytes.len()
            ),
        ));
    }
    let (dx, dy) = (dx.unwrap_or(1.0), dy.unwrap_or(dx.unwrap_or(1.0)));
    crate::util::check_cell(F, "header `cellsize` (or `dx`/`dy`)", dx, dy)?;
    let (xk, yk) = if center {
        ("xllcenter", "yllcenter")
    } else {
        ("xllcorner", "yllcorner")
    };
    crate::util::check_origin(F, &format!("header `{xk}`"), x0)?;
    crate::util::check_origin(F, &format!("header `{yk}`"), y0)?;
    let mut data = Vec::with_capacity(n);
    for tok in tokens {
        if data.len() == n {
            return Err(IoError::malformed(
                F,
                format!("header declares {w} x {h} = {n} values but the file holds more"),
            ));
        }
        let v: f64 = tok.parse().map_err(|_| {
            IoError::malformed(
                F,
                format!("value #{} {tok:?} is not a number", data.len() + 1),
            )
        })?;
        data.push(v as f32);
    }
    if data.len() != n {
        return Err(IoError::malformed(
            F,
            format!(
                "header declares {w} x {h} = {n} values but the file holds only {}",
                data.len()
            ),
        ));
    }
    let (left, bottom) = if center {
        (x0 - dx / 2.0, y0 - dy / 2.0)
    } else {
        (x0, y0)
    };
    let geo = GeoRef {
        geotransform: Some([left, dx, 0.0, bottom + dy * h as f64, 0.0, -dy]),
        ..GeoRef::default()
    };
    let mut r = finish(F, w as usize, h as usize, data, (dx, dy), nodata, "ascii")?;
    r.heightfield.set_georef(Some(geo));
    Ok(r)
}

pub(crate) fn write(hf: &Heightfield) -> Result<Vec<u8>> {
    let (cx, cy) = hf.cell_size();
    let (w, h) = (hf.width(), hf.height());
    // A north-up georeference is written in its own units (what GDAL reads back as the same
    // extent); without one the header holds the cell size in metres and a corner at the origin.
    let (x0, y_top, sx, sy) = match hf
        .georef()
        .and_then(|g| g.geotransform)
        .filter(|t| t[2] == 0.0 && t[4] == 0.0 && t[1] > 0.0 && t[5] < 0.0)
    {
        Some(t) => (t[0], t[3], t[1], -t[5]),
        None => (0.0, cy * h as f64, cx, cy),
    };
    let mut s = String::with_capacity(hf.len() * 8 + 200);
    let _ = writeln!(
        s,
        "ncols {w}\nnrows {h}\nxllcorner {x0}\nyllcorner {}",
        y_top - sy * h as f64
    );
    if (sx - sy).abs() <= 1e-12 * sx {
        let _ = writeln!(s, "cellsize {sx}");
    } else {
        // Non-square cells: GDAL's AAIGrid driver reads DX/DY.
        let _ = writeln!(s, "dx {sx}\ndy {sy}");
    }
    let _ = writeln!(s, "NODATA_value -9999");
    for row in hf.as_slice().chunks(w) {
        for (i, v) in row.iter().enumerate() {
            if i > 0 {
                s.push(' ');
            }
            if v.is_nan() {
                s.push_str("-9999");
            } else {
                let _ = write!(s, "{v}");
            }
        }
        s.push('\n');
    }
    Ok(s.into_bytes())
}
