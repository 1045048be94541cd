//! The `.f32` + `.json` sidecar layout of `shared/data/dem` and the `{width, height, values}`
//! JSON grid (`volcano.json`).

use std::path::Path;

use relief_heightfield::Heightfield;
use serde_json::Value;

use crate::util::{check_dims, finish};
use crate::{Format, IoError, Raster, ReadOptions, Result};

/// Size, cell and nodata taken from a sidecar.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sidecar {
    width: u64,
    height: u64,
    cell: (f64, f64),
    nodata: Option<f64>,
}

fn parse_sidecar(v: &Value) -> Result<Sidecar> {
    let f = Format::F32Sidecar;
    let dim = |key: &str| -> Result<u64> {
        v.get(key).and_then(Value::as_u64).ok_or_else(|| {
            IoError::malformed(
                f,
                format!("sidecar field `{key}` missing or not a non-negative integer"),
            )
        })
    };
    let width = dim("width")?;
    let height = dim("height")?;
    // A field that is present must be a number: `"cell_size_m": "30 m"` is an error, not a
    // silent 1 m cell.
    let num = |key: &str| -> Result<Option<f64>> {
        match v.get(key) {
            None | Some(Value::Null) => Ok(None),
            Some(x) => x.as_f64().map(Some).ok_or_else(|| {
                IoError::malformed(
                    f,
                    format!("sidecar field `{key}` = {x} is not a number of metres"),
                )
            }),
        }
    };
    let both = num("cell_size_m")?;
    let cx = num("cell_size_x_m")?.or(both).unwrap_or(1.0);
    let cy = num("cell_size_y_m")?.or(both).unwrap_or(1.0);
    crate::util::check_cell(f, "sidecar field `cell_size_m`", cx, cy)?;
    let nodata = match v.get("nodata") {
        None | Some(Value::Null) => None,
        Some(x) => Some(x.as_f64().ok_or_else(|| {
            IoError::malformed(f, format!("sidecar `nodata` = {x} is not a number"))
        })?),
    };
    Ok(Sidecar {
        width,
        height,
        cell: (cx, cy),
        nodata,
    })
}

/// Decodes `.f32` bytes with an optional sidecar; without one `opts.width/height` (or a square)
/// give the size.
pub(crate) fn read_f32_bytes(
    bytes: &[u8],
    side: Option<Sidecar>,
    opts: &ReadOptions,
) -> Result<Raster> {
    let f = Format::F32Sidecar;
    let side = match side {
        Some(s) => s,
        None => {
            let (w, h) = crate::raw::raw_dims(f, bytes.len(), 4, opts)?;
            Sidecar {
                width: w as u64,
                height: h as u64,
                cell: (1.0, 1.0),
                nodata: None,
            }
        }
    };
    let n = check_dims(f, side.width, side.height, opts)?;
    let needed = n as u64 * 4;
    if needed != bytes.len() as u64 {
        return Err(IoError::malformed(
            f,
            format!(
                "sidecar declares {} x {} = {needed} bytes of f32 but the data file has {} bytes",
                side.width,
                side.height,
                bytes.len()
            ),
        ));
    }
    let data = relief_heightfield::bytes::f32_from_le_bytes(bytes);
    finish(
        f,
        side.width as usize,
        side.height as usize,
        data,
        side.cell,
        side.nodata,
        "float32",
    )
}

/// Largest sidecar JSON accepted (bytes).
const SIDECAR_LIMIT: usize = 1 << 20;

/// Parses sidecar JSON text; `name` names it in errors.
pub(crate) fn parse_sidecar_text(text: &[u8], name: &str) -> Result<Sidecar> {
    if text.len() > SIDECAR_LIMIT {
        return Err(IoError::malformed(
            Format::F32Sidecar,
            format!(
                "sidecar {name} is {} bytes, more than the {SIDECAR_LIMIT} allowed",
                text.len()
            ),
        ));
    }
    let v: Value = serde_json::from_slice(text)
        .map_err(|e| IoError::malformed(Format::F32Sidecar, format!("sidecar {name}: {e}")))?;
    parse_sidecar(&v)
}

/// Reads `path` (`.f32`) with the sidecar `<stem>.json` next to it when present.
pub(crate) fn read_f32_file(path: &Path, bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let json_path = path.with_extension("json");
    let side = if json_path.is_file() {
        let text = read_limited(&json_path, SIDECAR_LIMIT as u64)?;
        Some(parse_sidecar_text(&text, &json_path.display().to_string())?)
    } else {
        None
    };
    read_f32_bytes(bytes, side, opts)
}

fn read_limited(path: &Path, limit: u64) -> Result<Vec<u8>> {
    let len = std::fs::metadata(path)
        .map_err(|e| IoError::os(path, e))?
        .len();
    if len > limit {
        return Err(IoError::malformed(
            Format::F32Sidecar,
            format!(
                "sidecar {} is {len} bytes, more than the {limit} allowed",
                path.display()
            ),
        ));
    }
    std::fs::read(path).map_err(|e| IoError::os(path, e))
}

/// A `.json` file: a `{width, height, values}` grid, or a sidecar whose `.f32` is read.
pub(crate) fn read_json_any(path: &Path, bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let shape: GridShape = parse_json(bytes)?;
    if shape.values.is_some() {
        return read_json_grid(bytes, opts);
    }
    let v: Value = parse_json(bytes)?;
    let side = parse_sidecar(&v)?;
    let data_name = v
        .get("data_file")
        .and_then(Value::as_str)
        .map(str::to_owned)
        .unwrap_or_else(|| {
            path.with_extension("f32")
                .file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        });
    // Only a plain file name next to the sidecar is followed.
    if data_name.contains('/') || data_name.contains('\\') || data_name.is_empty() {
        return Err(IoError::malformed(
            Format::F32Sidecar,
            format!("sidecar `data_file` = {data_name:?} is not a plain file name"),
        ));
    }
    let data_path = path.with_file_name(&data_name);
    let len = std::fs::metadata(&data_path)
        .map_err(|e| IoError::os(&data_path, e))?
        .len();
    let n = check_dims(Format::F32Sidecar, side.width, side.height, opts)?;
    if len != n as u64 * 4 {
        return Err(IoError::malformed(
            Format::F32Sidecar,
            format!(
                "sidecar declares {} x {} = {} bytes but {} has {len} bytes",
                side.width,
                side.height,
                n as u64 * 4,
                data_path.display()
            ),
        ));
    }
    let data = std::fs::read(&data_path).map_err(|e| IoError::os(&data_path, e))?;
    read_f32_bytes(&data, Some(side), opts)
}

/// Decodes a JSON document (a [`Value`], or the [`GridShape`] first pass of a JSON grid).
fn parse_json<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T> {
    serde_json::from_slice(bytes)
        .map_err(|e| IoError::malformed(Format::JsonGrid, format!("invalid JSON: {e}")))
}

/// First pass over a JSON grid: the declared size and the number of `values`, counted without
/// storing them, so the size is checked against the cell limit before anything is allocated.
#[derive(serde::Deserialize)]
struct GridShape {
    width: Option<Value>,
    height: Option<Value>,
    values: Option<ValueCount>,
}

/// The length of a JSON array (`None` when `values` is not an array), elements skipped.
struct ValueCount(Option<u64>);

impl<'de> serde::Deserialize<'de> for ValueCount {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = ValueCount;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("any JSON value")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> std::result::Result<ValueCount, A::Error> {
                let mut n = 0u64;
                while seq.next_element::<serde::de::IgnoredAny>()?.is_some() {
                    n += 1;
                }
                Ok(ValueCount(Some(n)))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> std::result::Result<ValueCount, A::Error> {
                while map
                    .next_entry::<serde::de::IgnoredAny, serde::de::IgnoredAny>()?
                    .is_some()
                {}
                Ok(ValueCount(None))
            }
            fn visit_bool<E>(self, _: bool) -> std::result::Result<ValueCount, E> {
                Ok(ValueCount(None))
            }
            fn visit_i64<E>(self, _: i64) -> std::result::Result<ValueCount, E> {
                Ok(ValueCount(None))
            }
            fn visit_u64<E>(self, _: u64) -> std::result::Result<ValueCount, E> {
                Ok(ValueCount(None))
            }
            fn visit_f64<E>(self, _: f64) -> std::result::Result<ValueCount, E> {
                Ok(ValueCount(None))
            }
            fn visit_str<E>(self, _: &str) -> std::result::Result<ValueCount, E> {
                Ok(ValueCount(None))
            }
            fn visit_unit<E>(self) -> std::result::Result<ValueCount, E> {
                Ok(ValueCount(None))
            }
        }
        d.deserialize_any(V)
    }
}

/// Second pass: the grid with its values decoded straight to f32 (`null` = NaN).
#[derive(serde::Deserialize)]
struct GridBody {
    values: GridValues,
    cell_size_x_m: Option<Value>,
    cell_size_y_m: Option<Value>,
    cell_size: Option<Value>,
    nodata: Option<Value>,
}

struct GridValues(Vec<f32>);

impl<'de> serde::Deserialize<'de> for GridValues {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = GridValues;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("an array of numbers or nulls")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> std::result::Result<GridValues, A::Error> {
                // The first pass counted the elements and checked them against the limit.
                let mut out = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(1 << 20));
                while let Some(x) = seq.next_element::<Value>()? {
                    match x {
                        Value::Null => out.push(f32::NAN),
                        x => out.push(x.as_f64().ok_or_else(|| {
                            serde::de::Error::custom(format!(
                                "values[{}] = {x:.40} is not a number",
                                out.len()
                            ))
                        })? as f32),
                    }
                }
                Ok(GridValues(out))
            }
        }
        d.deserialize_seq(V)
    }
}

/// Decodes a `{width, height, values}` JSON grid (row-major, row 0 first; `null` = void). The
/// declared size is checked against `opts.max_cells` and the number of values before the
/// values are stored.
pub(crate) fn read_json_grid(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let f = Format::JsonGrid;
    let shape: GridShape = parse_json(bytes)?;
    let dim = |v: &Option<Value>, key: &str| -> Result<u64> {
        v.as_ref().and_then(Value::as_u64).ok_or_else(|| {
            IoError::malformed(
                f,
                format!("field `{key}` missing or not a non-negative integer"),
            )
        })
    };
    let (w, h) = (dim(&shape.width, "width")?, dim(&shape.height, "height")?);
    let n = check_dims(f, w, h, opts)?;
    let count = shape
        .values
        .and_then(|c| c.0)
        .ok_or_else(|| IoError::malformed(f, "field `values` is not an array"))?;
    if count != n as u64 {
        return Err(IoError::malformed(
            f,
            format!("header says {w} x {h} = {n} values but `values` holds {count}"),
        ));
    }
    let body: GridBody = serde_json::from_slice(bytes)
        .map_err(|e| IoError::malformed(f, format!("invalid JSON grid: {e}")))?;
    let data = body.values.0;
    if data.len() != n {
        return Err(IoError::malformed(
            f,
            format!("`values` holds {} values, expected {n}", data.len()),
        ));
    }
    let num = |key: &str, v: &Option<Value>| -> Result<Option<f64>> {
        match v {
            None | Some(Value::Null) => Ok(None),
            Some(x) => x.as_f64().map(Some).ok_or_else(|| {
                IoError::malformed(f, format!("field `{key}` = {x} is not a number"))
            }),
        }
    };
    let both = num("cell_size", &body.cell_size)?;
    let cell = (
        num("cell_size_x_m", &body.cell_size_x_m)?
            .or(both)
            .unwrap_or(1.0),
        num("cell_size_y_m", &body.cell_size_y_m)?
            .or(both)
            .unwrap_or(1.0),
    );
    crate::util::check_cell(f, "field `cell_size`", cell.0, cell.1)?;
    let nodata = num("nodata", &body.nodata)?;
    finish(f, w as usize, h as usize, data, cell, nodata, "number")
}

/// The sidecar written next to a `.f32` file.
pub(crate) fn sidecar_json(hf: &Heightfield) -> String {
    let (cx, cy) = hf.cell_size();
    let voids = hf.void_count();
    let (min, max) = hf
        .min_max()
        .map_or((None, None), |(a, b)| (Some(a), Some(b)));
    let v = serde_json::json!({
        "width": hf.width(),
        "height": hf.height(),
        "cell_size_m": (cx * cy).sqrt(),
        "cell_size_x_m": cx,
        "cell_size_y_m": cy,
        "nodata": if voids > 0 { Some(-9999.0) } else { None },
        "nodata_count": voids,
        "min": min,
        "max": max,
        "layout": "float32 little-endian, row-major, height rows of width values; row 0 = northern edge, column 0 = western edge",
        "units": "metres",
        "source": "written by relief-io",
    });
    let mut s = serde_json::to_string_pretty(&v).unwrap_or_default();
    s.push('\n');
    s
}
