//! NumPy `.npy` (versions 1-3; int8..int64, uint8..uint64, float16/32/64, both byte orders,
//! C and Fortran order) and `.npz` archives (the array named by
//! [`ReadOptions::npz_array`](crate::ReadOptions::npz_array) or the first 2-D numeric one).
//! In an `.npz`, a 1-D `latitude`/`lat` array that ascends means the grid is stored south-up:
//! its rows are flipped so that row 0 is north. Degree coordinates (`latitude`/`longitude`
//! arrays, or `dx`/`dy` with `ymin`/`ymax`) give the cell size in metres at the centre latitude.

use std::io::{Cursor, Read};

use relief_heightfield::Heightfield;

use crate::geotiff::metres_per_degree;
use crate::util::{check_dims, finish, flip_rows};
use crate::{Format, IoError, Raster, ReadOptions, Result};

/// A parsed `.npy`: element type, shape and where the data start.
#[derive(Debug)]
struct Npy<'a> {
    kind: char,
    size: usize,
    big_endian: bool,
    fortran: bool,
    shape: Vec<u64>,
    data: &'a [u8],
    descr: String,
}

fn field<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pos = header
        .find(&format!("'{key}'"))
        .or_else(|| header.find(&format!("\"{key}\"")))?;
    let rest = &header[pos + key.len() + 2..];
    let colon = rest.find(':')?;
    Some(rest[colon + 1..].trim_start())
}

fn parse(bytes: &[u8], f: Format) -> Result<Npy<'_>> {
    if bytes.len() < 10 || !bytes.starts_with(b"\x93NUMPY") {
        return Err(IoError::malformed(
            f,
            "missing the \\x93NUMPY magic or truncated preamble",
        ));
    }
    let major = bytes[6];
    let (hlen, start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err(IoError::truncated(
                    f,
                    "npy v2 preamble",
                    12,
                    bytes.len() as u64,
                ));
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => return Err(IoError::unsupported(f, format!("npy format version {v}"))),
    };
    let end = start as u64 + hlen as u64;
    if end > bytes.len() as u64 {
        return Err(IoError::truncated(f, "npy header", end, bytes.len() as u64));
    }
    let end = end as usize;
    let header = std::str::from_utf8(&bytes[start..end])
        .map_err(|_| IoError::malformed(f, "npy header is not text"))?;
    let descr_raw =
        field(header, "descr").ok_or_else(|| IoError::malformed(f, "npy header has no 'descr'"))?;
    let q = descr_raw.chars().next().unwrap_or(' ');
    if q != '\'' && q != '"' {
        return Err(IoError::unsupported(
            f,
            format!("structured dtype {descr_raw:.40}"),
        ));
    }
    let descr: String = descr_raw[1..].chars().take_while(|&c| c != q).collect();
    let mut chars = descr.chars();
    let order = chars.next().unwrap_or(' ');
    let kind = chars.next().unwrap_or(' ');
    let size: usize = chars
        .as_str()
        .parse()
        .map_err(|_| IoError::unsupported(f, format!("dtype {descr:?}")))?;
    let big_endian = match order {
        '<' | '|' | '=' => false,
        '>' => true,
        _ => return Err(IoError::unsupported(f, format!("dtype {descr:?}"))),
    };
    let ok = matches!(
        (kind, size),
        ('i' | 'u', 1 | 2 | 4 | 8) | ('f', 2 | 4 | 8) | ('b', 1)
    );
    if !ok {
        return Err(IoError::unsupported(
            f,
            format!("dtype {descr:?} (numeric ints and floats only)"),
        ));
    }
    let fortran = field(header, "fortran_order")
        .ok_or_else(|| IoError::malformed(f, "npy header has no 'fortran_order'"))?
        .starts_with("True");
    let shape_s =
        field(header, "shape").ok_or_else(|| IoError::malformed(f, "npy header has no 'shape'"))?;
    let inner = shape_s
        .strip_prefix('(')
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| IoError::malformed(f, format!("npy shape {shape_s:.40} is not a tuple")))?;
    let mut shape = Vec::new();
    for part in inner.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let p = part.trim_end_matches('L');
        shape.push(p.parse::<u64>().map_err(|_| {
            IoError::malformed(
                f,
                format!("npy shape entry {part:?} is not a non-negative integer"),
            )
        })?);
    }
    Ok(Npy {
        kind,
        size,
        big_endian,
        fortran,
        shape,
        data: &bytes[end..],
        descr,
    })
}

fn decode(a: &Npy<'_>, n: usize) -> Vec<f64> {
    let s = a.size;
    a.data[..n * s]
        .chunks_exact(s)
        .map(|c| {
            let mut b = [0u8; 8];
            b[..s].copy_from_slice(c);
            if a.big_endian {
                b[..s].reverse();
            }
            match (a.kind, s) {
                ('f', 2) => half::f16::from_le_bytes([b[0], b[1]]).to_f64(),
                ('f', 4) => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                ('f', _) => f64::from_le_bytes(b),
                ('i', 1) => b[0] as i8 as f64,
                ('i', 2) => i16::from_le_bytes([b[0], b[1]]) as f64,
                ('i', 4) => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
                ('i', _) => i64::from_le_bytes(b) as f64,
                _ => u64::from_le_bytes(b) as f64,
            }
        })
        .collect()
}

/// The 2-D grid of an array: `(width, height, row-major values)`; a trailing or leading axis of
/// length 1 is ignored.
fn grid(a: &Npy<'_>, f: Format, opts: &ReadOptions) -> Result<(usize, usize, Vec<f32>)> {
    let (h, w) = match a.shape.as_slice() {
        [h, w] => (*h, *w),
        shape if shape.len() > 2 => {
            // Extra axes of length 1 (e.g. (1, h, w) or (h, w, 1)) are squeezed.
            let dims: Vec<u64> = shape.iter().copied().filter(|&d| d != 1).collect();
            match dims.as_slice() {
                [h, w] => (*h, *w),
                [w] => (1, *w),
                [] => (1, 1),
                _ => {
                    return Err(IoError::unsupported(
                        f,
                        format!("array of shape {shape:?} is not a 2-D grid"),
                    ));
                }
            }
        }
        shape => {
            return Err(IoError::unsupported(
                f,
                format!("array of shape {shape:?} is not a 2-D grid"),
            ));
        }
    };
    if a.shape.contains(&0) {
        return Err(IoError::Dimensions {
            format: f,
            width: w,
            height: h,
            reason: format!("shape {:?} has a zero axis", a.shape),
        });
    }
    let n = check_dims(f, w, h, opts)?;
    let needed = n as u64 * a.size as u64;
    if needed > a.data.len() as u64 {
        return Err(IoError::truncated(
            f,
            format!("{h} x {w} array of {}", a.descr),
            needed,
            a.data.len() as u64,
        ));
    }
    let vals = decode(a, n);
    let (w, h) = (w as usize, h as usize);
    let data = if a.fortran {
        let mut out = vec![0f32; n];
        for x in 0..w {
            for y in 0..h {
                out[y * w + x] = vals[x * h + y] as f32;
            }
        }
        out
    } else {
        vals.into_iter().map(|v| v as f32).collect()
    };
    Ok((w, h, data))
}

fn dtype_name(a: &Npy<'_>) -> String {
    let k = match a.kind {
        'f' => "float",
        'i' => "int",
        'b' => "bool",
        _ => "uint",
    };
    format!(
        "{k}{}{}",
        a.size * 8,
        if a.big_endian && a.size > 1 {
            " big-endian"
        } else {
            ""
        }
    )
}

pub(crate) fn read_npy(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let f = Format::Npy;
    let a = parse(bytes, f)?;
    let (w, h, data) = grid(&a, f, opts)?;
    finish(
        f,
        w,
        h,
        data,
        opts.cell_size.unwrap_or((1.0, 1.0)),
        None,
        &dtype_name(&a),
    )
}

/// Reads every member of the archive within a total byte budget.
fn members(bytes: &[u8], opts: &ReadOptions) -> Result<Vec<(String, Vec<u8>)>> {
    let f = Format::Npz;
    let mut zip = zip::ZipArchive::new(Cursor::new(bytes)).map_err(|e| {
        IoError::malformed(
            f,
            format!("zip: {}", crate::util::codec_reason(e.to_string())),
        )
    })?;
    let mut budget = (opts.max_cells as u64)
        .saturating_mul(8)
        .saturating_add(1 << 20);
    let mut out = Vec::new();
    for i in 0..zip.len() {
        let mut entry = zip.by_index(i).map_err(|e| {
            IoError::malformed(
                f,
                format!(
                    "zip member {i}: {}",
                    crate::util::codec_reason(e.to_string())
                ),
            )
        })?;
        let name = entry.name().trim_end_matches(".npy").to_string();
        let declared = entry.size();
        if declared > budget {
            return Err(IoError::Dimensions {
                format: f,
                width: declared,
                height: 1,
                reason: format!(
                    "member {name:?} declares {declared} bytes, more than the remaining budget of {budget} bytes (from the cell limit)"
                ),
            });
        }
        let mut buf = Vec::with_capacity(declared.min(1 << 24) as usize);
        (&mut entry)
            .take(declared + 1)
            .read_to_end(&mut buf)
            .map_err(|e| {
                IoError::malformed(
                    f,
                    format!(
                        "zip member {name:?}: {}",
                        crate::util::codec_reason(e.to_string())
                    ),
                )
            })?;
        if buf.len() as u64 != declared {
            return Err(IoError::malformed(
                f,
                format!(
                    "zip member {name:?} holds {} bytes but declares {declared}",
                    buf.len()
                ),
            ));
        }
        budget -= declared;
        out.push((name, buf));
    }
    Ok(out)
}

fn vector(members: &[(String, Vec<u8>)], names: &[&str]) -> Option<Vec<f64>> {
    let (_, b) = members.iter().find(|(n, _)| names.contains(&n.as_str()))?;
    let a = parse(b, Format::Npz).ok()?;
    let n: u64 = a.shape.iter().product();
    if n == 0 || n > 1 << 24 || n * a.size as u64 > a.data.len() as u64 {
        return None;
    }
    Some(decode(&a, n as usize))
}

pub(crate) fn read_npz(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let f = Format::Npz;
    let members = members(bytes, opts)?;
    let names: Vec<&str> = members.iter().map(|(n, _)| n.as_str()).collect();
    let chosen = if let Some(want) = &opts.npz_array {
        members.iter().find(|(n, _)| n == want).ok_or_else(|| {
            IoError::param(
                "npz_array",
                want,
                format!("no such array; the archive holds {names:?}"),
            )
        })?
    } else {
        let preferred = ["elevation", "topo", "z", "dem", "height", "heights"];
        let is_grid = |b: &[u8]| {
            parse(b, f)
                .is_ok_and(|a| a.shape.iter().filter(|&&d| d != 1).count() == 2 && a.kind != 'b')
        };
        preferred
            .iter()
            .find_map(|p| members.iter().find(|(n, b)| n == p && is_grid(b)))
            .or_else(|| members.iter().find(|(_, b)| is_grid(b)))
            .ok_or_else(|| IoError::malformed(f, format!("no 2-D numeric array among {names:?}")))?
    };
    let a = parse(&chosen.1, f)
        .map_err(|e| IoError::malformed(f, format!("array {:?}: {e}", chosen.0)))?;
    let (w, h, mut data) = grid(&a, f, opts)?;
    let lat = vector(&members, &["latitude", "lat"]).filter(|v| v.len() == h);
    let lon = vector(&members, &["longitude", "lon"]).filter(|v| v.len() == w);
    let mut flipped = false;
    if let Some(l) = &lat
        && h > 1
        && l[h - 1] > l[0]
    {
        flip_rows(&mut data, w);
        flipped = true;
    }
    let scalar = |name: &str| {
        vector(&members, &[name])
            .filter(|v| v.len() == 1)
            .map(|v| v[0])
    };
    let mut cell = (1.0, 1.0);
    if let (Some(la), Some(lo)) = (&lat, &lon)
        && h > 1
        && w > 1
    {
        let lat_c = (la[0] + la[h - 1]) / 2.0;
        if lat_c.abs() <= 90.0 {
            let (mx, my) = metres_per_degree(lat_c);
            let dlon = (lo[w - 1] - lo[0]).abs() / (w - 1) as f64;
            let dlat = (la[h - 1] - la[0]).abs() / (h - 1) as f64;
            cell = (dlon * mx, dlat * my);
        }
    } else if let (Some(dx), Some(dy), Some(y0), Some(y1)) =
        (scalar("dx"), scalar("dy"), scalar("ymin"), scalar("ymax"))
    {
        let lat_c = (y0 + y1) / 2.0;
        if lat_c.abs() <= 90.0 && dx.abs() < 10.0 && dy.abs() < 10.0 {
            let (mx, my) = metres_per_degree(lat_c);
            cell = (dx.abs() * mx, dy.abs() * my);
        }
    }
    if !(cell.0 > 0.0 && cell.1 > 0.0 && cell.0.is_finite() && cell.1.is_finite()) {
        cell = (1.0, 1.0);
    }
    let mut r = finish(
        f,
        w,
        h,
        data,
        opts.cell_size.unwrap_or(cell),
        None,
        &dtype_name(&a),
    )?;
    r.rows_flipped = flipped;
    Ok(r)
}

/// `.npy` v1.0, `<f4`, C order, shape `(height, width)`; voids stay NaN.
pub(crate) fn write_npy(hf: &Heightfield) -> Vec<u8> {
    let mut out = npy_header(&[hf.height(), hf.width()]);
    out.extend_from_slice(&crate::raw::f32_le_bytes(hf));
    out
}

/// A C-order little-endian `float32` array of any `shape` (`.npy` v1.0), for arrays that are
/// not heightfields (patch matrices, voxel grids): the values, row-major, must number the
/// product of the shape (not checked: the bytes are what `values` yields).
pub fn npy_f32(shape: &[usize], values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    let mut out = npy_header(shape);
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Magic, version 1.0, header length and the header dictionary of a C-order `<f4` array,
/// padded so that the data starts at a multiple of 64 bytes.
fn npy_header(shape: &[usize]) -> Vec<u8> {
    // `(r, c)`, `(d0, d1, d2)`, or `(n,)` for one dimension.
    let dims = match shape {
        [n] => format!("{n},"),
        _ => shape
            .iter()
            .map(|d| d.to_string())
            .collect::<Vec<_>>()
            .join(", "),
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({dims}), }}");
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut out = Vec::with_capacity(10 + header.len());
    out.extend_from_slice(b"\x93NUMPY\x01\x00");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The header of every shape is the dictionary NumPy writes, padded so that the data
    /// starts at a multiple of 64; a 2-D array reads back as the same heightfield.
    #[test]
    fn npy_f32_headers_and_round_trip() {
        for (shape, text) in [
            (&[5usize][..], "(5,)"),
            (&[2, 3][..], "(2, 3)"),
            (&[2, 2, 2][..], "(2, 2, 2)"),
        ] {
            let n: usize = shape.iter().product();
            let bytes = npy_f32(shape, (0..n).map(|v| v as f32));
            let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
            assert_eq!((10 + hlen) % 64, 0, "{shape:?}");
            let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
            assert!(header.contains(&format!("'shape': {text}")), "{header}");
            assert_eq!(bytes.len(), 10 + hlen + 4 * n);
        }
        let bytes = npy_f32(&[2, 3], [1.0, 2.0, 3.0, 4.0, 5.0, f32::NAN]);
        let r = read_npy(&bytes, &crate::ReadOptions::default()).unwrap();
        let hf = r.heightfield;
        assert_eq!((hf.width(), hf.height()), (3, 2));
        assert_eq!(hf.get(2, 0), 3.0);
        assert!(hf.get(2, 1).is_nan());
        assert_eq!(write_npy(&hf), bytes);
    }
}
