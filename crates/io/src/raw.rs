//! Headerless rasters: `.r16` (u16 little-endian counts) and `.r32` (f32 little-endian).

use relief_heightfield::Heightfield;

use crate::util::{check_dims, finish, finite_range};
use crate::{Format, IoError, Raster, ReadOptions, Result};

/// Size of a headerless file of `len` bytes with `bps` bytes per sample: from
/// `opts.width`/`opts.height`, or a square when neither is given.
pub(crate) fn raw_dims(
    format: Format,
    len: usize,
    bps: usize,
    opts: &ReadOptions,
) -> Result<(usize, usize)> {
    if !len.is_multiple_of(bps) {
        return Err(IoError::malformed(
            format,
            format!("file length {len} is not a multiple of the {bps}-byte sample size"),
        ));
    }
    let n = (len / bps) as u64;
    let (w, h) = match (opts.width, opts.height) {
        (Some(w), Some(h)) => (w as u64, h as u64),
        (Some(w), None) => {
            if w == 0 || !n.is_multiple_of(w as u64) {
                return Err(IoError::param(
                    "width",
                    w,
                    format!("does not divide the {n} samples of the file"),
                ));
            }
            (w as u64, n / w as u64)
        }
        (None, Some(h)) => {
            if h == 0 || !n.is_multiple_of(h as u64) {
                return Err(IoError::param(
                    "height",
                    h,
                    format!("does not divide the {n} samples of the file"),
                ));
            }
            (n / h as u64, h as u64)
        }
        (None, None) => {
            let s = (n as f64).sqrt().round() as u64;
            if s * s != n {
                return Err(IoError::malformed(
                    format,
                    format!("{n} samples do not form a square; give the width and height"),
                ));
            }
            (s, s)
        }
    };
    let cells = check_dims(format, w, h, opts)?;
    if cells as u64 * bps as u64 != len as u64 {
        return Err(IoError::malformed(
            format,
            format!(
                "{w} x {h} samples need {} bytes but the file has {len}",
                cells as u64 * bps as u64
            ),
        ));
    }
    Ok((w as usize, h as usize))
}

pub(crate) fn read(bytes: &[u8], format: Format, opts: &ReadOptions) -> Result<Raster> {
    let cell = opts.cell_size.unwrap_or((1.0, 1.0));
    match format {
        Format::R16 => {
            let (w, h) = raw_dims(format, bytes.len(), 2, opts)?;
            let (off, scale) = opts.r16_mapping;
            if !(off.is_finite() && scale.is_finite() && scale != 0.0) {
                return Err(IoError::param(
                    "r16_mapping",
                    format!("({off}, {scale})"),
                    "offset and scale must be finite, scale non-zero",
                ));
            }
            let data = bytes
                .chunks_exact(2)
                .map(|b| (off + scale * u16::from_le_bytes([b[0], b[1]]) as f64) as f32)
                .collect();
            finish(format, w, h, data, cell, None, "uint16")
        }
        _ => {
            let (w, h) = raw_dims(format, bytes.len(), 4, opts)?;
            let data = relief_heightfield::bytes::f32_from_le_bytes(bytes);
            finish(format, w, h, data, cell, None, "float32")
        }
    }
}

/// `(offset, scale)` mapping the finite range of `hf` onto `0..=65535`.
pub(crate) fn auto_mapping(hf: &Heightfield, format: Format) -> Result<(f64, f64)> {
    let (lo, hi) = finite_range(hf, format)?;
    let span = hi as f64 - lo as f64;
    Ok((lo as f64, if span > 0.0 { span / 65535.0 } else { 1.0 }))
}

/// Quantises `v` to a u16 count with `(offset, scale)`; voids become 0.
pub(crate) fn quantise(v: f32, (off, scale): (f64, f64)) -> u16 {
    if v.is_nan() {
        0
    } else {
        ((v as f64 - off) / scale).round().clamp(0.0, 65535.0) as u16
    }
}

pub(crate) fn check_mapping(m: (f64, f64)) -> Result<(f64, f64)> {
    if m.0.is_finite() && m.1.is_finite() && m.1 > 0.0 {
        Ok(m)
    } else {
        Err(IoError::param(
            "mapping",
            format!("({}, {})", m.0, m.1),
            "offset must be finite and scale finite and > 0",
        ))
    }
}

pub(crate) fn write_r16(hf: &Heightfield, mapping: Option<(f64, f64)>) -> Result<Vec<u8>> {
    let m = match mapping {
        Some(m) => check_mapping(m)?,
        None => auto_mapping(hf, Format::R16)?,
    };
    let mut out = Vec::with_capacity(hf.len() * 2);
    for &v in hf.as_slice() {
        out.extend_from_slice(&quantise(v, m).to_le_bytes());
    }
    Ok(out)
}

pub(crate) fn write_r32(hf: &Heightfield) -> Result<Vec<u8>> {
    Ok(f32_le_bytes(hf))
}

/// Little-endian f32 samples, NaN kept.
pub(crate) fn f32_le_bytes(hf: &Heightfield) -> Vec<u8> {
    let mut out = Vec::with_capacity(hf.len() * 4);
    for &v in hf.as_slice() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Little-endian f32 samples with voids as -9999 (the sidecar's `nodata`).
pub(crate) fn f32_sidecar_bytes(hf: &Heightfield) -> Vec<u8> {
    let mut out = Vec::with_capacity(hf.len() * 4);
    for &v in hf.as_slice() {
        let v = if v.is_nan() { -9999.0f32 } else { v };
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}
