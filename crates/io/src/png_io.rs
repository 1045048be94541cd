//! PNG rasters: 8/16-bit grey with the relief vertical mapping stored in a `tEXt` chunk
//! (`relief:vertical` = `offset=<m>;scale=<m per count>[;nodata=<count>]`), and Mapbox
//! Terrain-RGB (height = -10000 + (R * 65536 + G * 256 + B) * 0.1).

use std::io::Cursor;

use relief_heightfield::Heightfield;

use crate::raw::check_mapping;
use crate::util::{check_dims, finish, finite_range};
use crate::{Format, IoError, PngMode, Raster, ReadOptions, Result};

/// `tEXt` keyword of the grey vertical mapping.
pub(crate) const KEY_VERTICAL: &str = "relief:vertical";
/// `tEXt` keyword marking a Terrain-RGB file (`terrain-rgb[;nodata=0]`).
pub(crate) const KEY_ENCODING: &str = "relief:encoding";

fn perr(format: Format, e: png::DecodingError) -> IoError {
    IoError::malformed(format, crate::util::codec_reason(e.to_string()))
}

fn parse_kv(text: &str) -> impl Iterator<Item = (&str, &str)> {
    text.split(';')
        .filter_map(|kv| kv.split_once('='))
        .map(|(k, v)| (k.trim(), v.trim()))
}

fn parse_vertical(text: &str) -> Result<(f64, f64, Option<u32>)> {
    let (mut off, mut scale, mut nodata) = (None, None, None);
    for (k, v) in parse_kv(text) {
        let bad = || {
            IoError::malformed(
                Format::Png,
                format!("{KEY_VERTICAL} entry `{k}={v}` is not a number"),
            )
        };
        match k {
            "offset" => off = Some(v.parse::<f64>().map_err(|_| bad())?),
            "scale" => scale = Some(v.parse::<f64>().map_err(|_| bad())?),
            "nodata" => nodata = Some(v.parse::<u32>().map_err(|_| bad())?),
            _ => {}
        }
    }
    match (off, scale) {
        (Some(o), Some(s)) if o.is_finite() && s.is_finite() && s > 0.0 => Ok((o, s, nodata)),
        _ => Err(IoError::malformed(
            Format::Png,
            format!("{KEY_VERTICAL} = {text:?} lacks a finite offset and a positive scale"),
        )),
    }
}

pub(crate) fn read(bytes: &[u8], format: Format, opts: &ReadOptions) -> Result<Raster> {
    let f = Format::Png;
    // The IHDR is checked against our limit before the decoder allocates anything.
    if bytes.len() < 33 || &bytes[12..16] != b"IHDR" {
        return Err(IoError::truncated(
            f,
            "PNG signature and IHDR chunk",
            33,
            bytes.len() as u64,
        ));
    }
    let w = u32::from_be_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]);
    let h = u32::from_be_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]);
    let n = check_dims(f, w as u64, h as u64, opts)?;
    let limits = png::Limits {
        bytes: n.saturating_mul(8).saturating_add(1 << 20),
    };
    let mut dec = png::Decoder::new_with_limits(Cursor::new(bytes), limits);
    dec.set_transformations(png::Transformations::IDENTITY);
    let mut reader = dec.read_info().map_err(|e| perr(f, e))?;
    let info = reader.info();
    let text = |key: &str| -> Option<String> {
        info.uncompressed_latin1_text
            .iter()
            .find(|t| t.keyword == key)
            .map(|t| t.text.clone())
            .or_else(|| {
                info.utf8_text
                    .iter()
                    .find(|t| t.keyword == key)
                    .and_then(|t| t.get_text().ok())
            })
    };
    let vertical = text(KEY_VERTICAL);
    let encoding = text(KEY_ENCODING);
    let (color, depth) = (info.color_type, info.bit_depth);
    let terrain = match opts.png {
        PngMode::TerrainRgb => true,
        PngMode::Grey { .. } => false,
        PngMode::Auto => {
            format == Format::TerrainRgb
                || encoding
                    .as_deref()
                    .is_some_and(|e| e.starts_with("terrain-rgb"))
        }
    };
    let mut buf = vec![
        0u8;
        reader
            .output_buffer_size()
            .ok_or_else(|| IoError::malformed(f, "image too large"))?
    ];
    let frame = reader.next_frame(&mut buf).map_err(|e| perr(f, e))?;
    let buf = &buf[..frame.buffer_size()];
    let (w, h) = (w as usize, h as usize);
    let cell = opts.cell_size.unwrap_or((1.0, 1.0));
    if terrain {
        let ch = match (color, depth) {
            (png::ColorType::Rgb, png::BitDepth::Eight) => 3,
            (png::ColorType::Rgba, png::BitDepth::Eight) => 4,
            _ => {
                return Err(IoError::unsupported(
                    Format::TerrainRgb,
                    format!("Terrain-RGB needs 8-bit RGB(A), found {color:?} {depth:?}"),
                ));
            }
        };
        let void0 = encoding
            .as_deref()
            .is_some_and(|e| parse_kv(e).any(|(k, v)| k == "nodata" && v == "0"));
        let mut data = Vec::with_capacity(n);
        for p in buf.chunks_exact(ch).take(n) {
            let code = (p[0] as u32) << 16 | (p[1] as u32) << 8 | p[2] as u32;
            let transparent = ch == 4 && p[3] == 0;
            data.push(if (void0 && code == 0) || transparent {
                f32::NAN
            } else {
                (-10000.0 + code as f64 * 0.1) as f32
            });
        }
        return finish(Format::TerrainRgb, w, h, data, cell, None, "terrain-rgb");
    }
    let ch = match color {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        other => {
            return Err(IoError::unsupported(
                f,
                format!(
                    "{other:?} PNG: only grey PNGs are elevations (read a Mapbox Terrain-RGB PNG with --png-encoding terrain-rgb)"
                ),
            ));
        }
    };
    let (off, scale, nodata) = match opts.png {
        PngMode::Grey { offset, scale } => {
            let (o, s) = check_mapping((offset, scale))?;
            (o, s, None)
        }
        _ => match vertical.as_deref() {
            Some(t) => parse_vertical(t)?,
            None => (0.0, 1.0, None),
        },
    };
    let counts: Vec<u32> = match depth {
        png::BitDepth::Eight => buf.chunks_exact(ch).map(|p| p[0] as u32).collect(),
        png::BitDepth::Sixteen => buf
            .chunks_exact(2 * ch)
            .map(|p| u16::from_be_bytes([p[0], p[1]]) as u32)
            .collect(),
        d => {
            return Err(IoError::unsupported(
                f,
                format!("{d:?} grey PNG; only 8 and 16 bits are read"),
            ));
        }
    };
    if counts.len() < n {
        return Err(IoError::truncated(
            f,
            "decoded samples",
            n as u64,
            counts.len() as u64,
        ));
    }
    let data = counts
        .iter()
        .take(n)
        .map(|&c| {
            if Some(c) == nodata {
                f32::NAN
            } else {
                (off + scale * c as f64) as f32
            }
        })
        .collect();
    let dtype = if depth == png::BitDepth::Eight {
        "uint8"
    } else {
        "uint16"
    };
    finish(f, w, h, data, cell, None, dtype)
}

fn encode_png(
    w: usize,
    h: usize,
    color: png::ColorType,
    depth: png::BitDepth,
    texts: &[(&str, String)],
    data: &[u8],
) -> Result<Vec<u8>> {
    let f = Format::Png;
    let (w32, h32) = match (u32::try_from(w), u32::try_from(h)) {
        (Ok(a), Ok(b)) => (a, b),
        _ => {
            return Err(IoError::unsupported(
                f,
                format!("{w} x {h} is too large for PNG"),
            ));
        }
    };
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w32, h32);
        enc.set_color(color);
        enc.set_depth(depth);
        enc.set_compression(png::Compression::Fast);
        for (k, v) in texts {
            enc.add_text_chunk(k.to_string(), v.clone())
                .map_err(|e| IoError::malformed(f, e.to_string()))?;
        }
        let mut wr = enc
            .write_header()
            .map_err(|e| IoError::malformed(f, e.to_string()))?;
        wr.write_image_data(data)
            .map_err(|e| IoError::malformed(f, e.to_string()))?;
        wr.finish()
            .map_err(|e| IoError::malformed(f, e.to_string()))?;
    }
    Ok(out)
}

/// 16-bit grey PNG. Voids, if any, take count 0 and the finite range maps onto 1..=65535.
pub(crate) fn write_png16(hf: &Heightfield, mapping: Option<(f64, f64)>) -> Result<Vec<u8>> {
    let voids = hf.has_voids();
    let (off, scale) = match mapping {
        Some(m) => check_mapping(m)?,
        None => {
            let (lo, hi) = finite_range(hf, Format::Png)?;
            let span = hi as f64 - lo as f64;
            let levels = if voids { 65534.0 } else { 65535.0 };
            let s = if span > 0.0 { span / levels } else { 1.0 };
            (if voids { lo as f64 - s } else { lo as f64 }, s)
        }
    };
    let lo_count = u32::from(voids);
    let mut data = Vec::with_capacity(hf.len() * 2);
    for &v in hf.as_slice() {
        let c = if v.is_nan() {
            0u16
        } else {
            ((v as f64 - off) / scale)
                .round()
                .clamp(lo_count as f64, 65535.0) as u16
        };
        data.extend_from_slice(&c.to_be_bytes());
    }
    let mut text = format!("offset={off:e};scale={scale:e}");
    if voids {
        text.push_str(";nodata=0");
    }
    encode_png(
        hf.width(),
        hf.height(),
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &[(KEY_VERTICAL, text)],
        &data,
    )
}

/// Mapbox Terrain-RGB (0.1 m steps from -10000 m); voids are (0, 0, 0), marked in `tEXt`.
pub(crate) fn write_terrain_rgb(hf: &Heightfield) -> Result<Vec<u8>> {
    finite_range(hf, Format::TerrainRgb)?;
    let mut data = Vec::with_capacity(hf.len() * 3);
    for &v in hf.as_slice() {
        let code = if v.is_nan() {
            0u32
        } else {
            ((v as f64 + 10000.0) * 10.0)
                .round()
                .clamp(1.0, 16_777_215.0) as u32
        };
        data.extend_from_slice(&[(code >> 16) as u8, (code >> 8) as u8, code as u8]);
    }
    let enc = if hf.has_voids() {
        "terrain-rgb;nodata=0"
    } else {
        "terrain-rgb"
    };
    encode_png(
        hf.width(),
        hf.height(),
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &[(KEY_ENCODING, enc.to_string())],
        &data,
    )
}

/// 8-bit RGB or grey PNG bytes of a caller's image.
pub(crate) fn encode_8bit(w: usize, h: usize, channels: usize, data: &[u8]) -> Result<Vec<u8>> {
    let color = match channels {
        1 => png::ColorType::Grayscale,
        3 => png::ColorType::Rgb,
        4 => png::ColorType::Rgba,
        c => return Err(IoError::param("channels", c, "must be 1, 3 or 4")),
    };
    if w == 0
        || h == 0
        || w.checked_mul(h).and_then(|n| n.checked_mul(channels)) != Some(data.len())
    {
        return Err(IoError::param(
            "pixels",
            data.len(),
            format!(
                "a {w} x {h} image with {channels} channels needs {} bytes and a non-zero size",
                w.saturating_mul(h).saturating_mul(channels)
            ),
        ));
    }
    encode_png(w, h, color, png::BitDepth::Eight, &[], data)
}
