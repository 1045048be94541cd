//! What [`super::read`] and [`super::bands::GeoTiffBands`] take from a GeoTIFF's directory
//! before any sample (decoder limits, sample type, chunk table, nodata, georeference tags,
//! GDAL's scaling), and the conversion of decoded samples to `f32`: one reading for both, so
//! a file reads the same whole or band by band.

use std::io::{Read, Seek};

use relief_heightfield::GeoRef;
use tiff::ColorType;
use tiff::decoder::{ChunkType, Decoder, DecodingResult, Limits};
use tiff::tags::Tag;

use super::{
    F, GDAL_METADATA_TAG, cell_size, check_georef_values, complete_georef, gdal_scale_offset, terr,
};
use crate::{IoError, ReadOptions, Result};

/// A decoder of `reader` whose buffers are capped by `opts.max_cells`.
pub(super) fn decoder<R: Read + Seek>(reader: R, opts: &ReadOptions) -> Result<Decoder<R>> {
    let dec = Decoder::new(reader).map_err(terr)?;
    let mut limits = Limits::default();
    limits.decoding_buffer_size = opts.max_cells.saturating_mul(8);
    limits.ifd_value_size = 16 << 20;
    Ok(dec.with_limits(limits))
}

/// Bits per sample and the data type name of a single-band raster `read` accepts.
pub(super) fn sample_type<R: Read + Seek>(dec: &mut Decoder<R>) -> Result<(u8, &'static str)> {
    let bits = match dec.colortype().map_err(terr)? {
        ColorType::Gray(b) => b,
        other => {
            return Err(IoError::unsupported(
                F,
                format!("colour type {other:?}; only single-band rasters are read"),
            ));
        }
    };
    let sample_format = dec
        .find_tag_unsigned_vec::<u16>(Tag::SampleFormat)
        .map_err(terr)?
        .and_then(|v| v.first().copied())
        .unwrap_or(1);
    let dtype = match (sample_format, bits) {
        (1, 8) => "uint8",
        (1, 16) => "uint16",
        (1, 32) => "uint32",
        (2, 8) => "int8",
        (2, 16) => "int16",
        (2, 32) => "int32",
        (3, 32) => "float32",
        (3, 64) => "float64",
        (sf, b) => {
            return Err(IoError::unsupported(
                F,
                format!("sample format {sf} with {b} bits per sample"),
            ));
        }
    };
    Ok((bits, dtype))
}

/// Every strip or tile listed lies inside the file (`file_len` bytes), before any is read.
/// Returns the kind of chunk (`"strip"` or `"tile"`) and their byte counts.
pub(super) fn check_chunks_in_file<R: Read + Seek>(
    dec: &mut Decoder<R>,
    file_len: u64,
) -> Result<(&'static str, Vec<u64>)> {
    let (off_tag, cnt_tag, kind) = match dec.get_chunk_type() {
        ChunkType::Strip => (Tag::StripOffsets, Tag::StripByteCounts, "strip"),
        ChunkType::Tile => (Tag::TileOffsets, Tag::TileByteCounts, "tile"),
    };
    let offsets = dec
        .find_tag_unsigned_vec::<u64>(off_tag)
        .map_err(terr)?
        .ok_or_else(|| IoError::malformed(F, format!("missing {kind} offsets")))?;
    let counts = dec
        .find_tag_unsigned_vec::<u64>(cnt_tag)
        .map_err(terr)?
        .ok_or_else(|| IoError::malformed(F, format!("missing {kind} byte counts")))?;
    if offsets.len() != counts.len() {
        return Err(IoError::malformed(
            F,
            format!(
                "{} {kind} offsets but {} byte counts",
                offsets.len(),
                counts.len()
            ),
        ));
    }
    for (i, (&o, &c)) in offsets.iter().zip(&counts).enumerate() {
        let end = o.saturating_add(c);
        if end > file_len {
            return Err(IoError::truncated(
                F,
                format!("{kind} {i} (offset {o}, {c} bytes)"),
                end,
                file_len,
            ));
        }
    }
    Ok((kind, counts))
}

fn find_f64s<R: Read + Seek>(dec: &mut Decoder<R>, tag: Tag) -> Result<Option<Vec<f64>>> {
    match dec.find_tag(tag).map_err(terr)? {
        Some(v) => Ok(Some(v.into_f64_vec().map_err(terr)?)),
        None => Ok(None),
    }
}

/// The tags read beside the samples: GDAL's nodata, the raw georeference tags (not yet
/// completed) and GDAL's metadata XML.
pub(super) struct Tags {
    pub nodata: Option<f64>,
    pub geo: GeoRef,
    pub gdal_metadata: Option<String>,
}

impl Tags {
    pub(super) fn read<R: Read + Seek>(dec: &mut Decoder<R>) -> Result<Self> {
        let nodata = match dec.find_tag(Tag::GdalNodata).map_err(terr)? {
            Some(v) => {
                let s = v.into_string().map_err(terr)?;
                let s = s.trim_matches(|c: char| c == '\0' || c.is_whitespace());
                Some(s.parse::<f64>().map_err(|_| {
                    IoError::malformed(F, format!("GDAL_NODATA tag {s:?} is not a number"))
                })?)
            }
            None => None,
        };
        let geo = GeoRef {
            pixel_scale: find_f64s(dec, Tag::ModelPixelScaleTag)?,
            tiepoints: find_f64s(dec, Tag::ModelTiepointTag)?,
            transformation: find_f64s(dec, Tag::ModelTransformationTag)?,
            geo_key_directory: match dec.find_tag(Tag::GeoKeyDirectoryTag).map_err(terr)? {
                Some(v) => Some(v.into_u16_vec().map_err(terr)?),
                None => None,
            },
            geo_double_params: find_f64s(dec, Tag::GeoDoubleParamsTag)?,
            geo_ascii_params: match dec.find_tag(Tag::GeoAsciiParamsTag).map_err(terr)? {
                Some(v) => Some(v.into_string().map_err(terr)?),
                None => None,
            },
            crs: None,
            geotransform: None,
        };
        let gdal_metadata = match dec
            .find_tag(Tag::Unknown(GDAL_METADATA_TAG))
            .map_err(terr)?
        {
            Some(v) => Some(v.into_string().map_err(terr)?),
            None => None,
        };
        Ok(Tags {
            nodata,
            geo,
            gdal_metadata,
        })
    }

    /// Completes the georeference of a `w x h` grid (see [`complete_georef`]), checks it and
    /// returns whether the rows are stored south first, and the cell size (1 x 1 without one).
    pub(super) fn complete_georef(&mut self, w: usize, h: usize) -> Result<(bool, (f64, f64))> {
        let flipped = complete_georef(&mut self.geo, w, h);
        check_georef_values(&self.geo)?;
        let cell = cell_size(&self.geo, h).unwrap_or((1.0, 1.0));
        crate::util::check_cell(
            F,
            "georeference (ModelPixelScale / ModelTransformation)",
            cell.0,
            cell.1,
        )?;
        Ok((flipped, cell))
    }

    /// GDAL's `(scale, offset)` when the metadata states either (the other defaulting to 1
    /// or 0); a scale of 0 is refused.
    pub(super) fn scale(&self) -> Result<Option<(f64, f64)>> {
        let (scale, offset) = self
            .gdal_metadata
            .as_deref()
            .map(gdal_scale_offset)
            .unwrap_or_default();
        if scale.is_none() && offset.is_none() {
            return Ok(None);
        }
        let (s, o) = (scale.unwrap_or(1.0), offset.unwrap_or(0.0));
        if s == 0.0 {
            return Err(IoError::malformed(F, "GDAL metadata SCALE is 0"));
        }
        Ok(Some((s, o)))
    }
}

/// The decoded samples as `f32` (`None` for a sample type `read` does not accept).
pub(super) fn samples_f32(decoded: DecodingResult) -> Option<Vec<f32>> {
    Some(match decoded {
        DecodingResult::U8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::I8(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        _ => return None,
    })
}

/// Decodes chunk row `cr` of a `width x height` raster stored in chunks (strips or tiles) of
/// `chunk_cols x chunk_rows` into `band` (full rows), each chunk's samples converted by
/// `samples`; `terr` says a codec error.
pub(crate) fn read_chunk_row<R: Read + Seek>(
    dec: &mut Decoder<R>,
    cr: usize,
    (width, height): (usize, usize),
    (chunk_cols, chunk_rows): (usize, usize),
    band: &mut Vec<f32>,
    samples: impl Fn(DecodingResult) -> Result<Vec<f32>>,
    terr: impl Fn(tiff::TiffError) -> IoError,
) -> Result<()> {
    let y0 = cr * chunk_rows;
    let rows = chunk_rows.min(height - y0);
    let across = width.div_ceil(chunk_cols);
    band.clear();
    band.resize(rows * width, 0.0);
    for c in 0..across {
        let index = u32::try_from(cr * across + c)
            .map_err(|_| IoError::malformed(F, "more chunks than a TIFF holds"))?;
        let v = samples(dec.read_chunk(index).map_err(&terr)?)?;
        let (dw, _) = dec.chunk_data_dimensions(index);
        let dw = dw as usize;
        let x0 = c * chunk_cols;
        let cols = dw.min(width - x0);
        if rows.saturating_mul(dw) > v.len() || cols == 0 {
            return Err(IoError::malformed(F, "a chunk is shorter than its size"));
        }
        for r in 0..rows {
            band[r * width + x0..r * width + x0 + cols].copy_from_slice(&v[r * dw..r * dw + cols]);
        }
    }
    Ok(())
}
