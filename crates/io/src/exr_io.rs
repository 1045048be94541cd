//! OpenEXR single-channel rasters (f32 or f16; u32 read as counts). The header is read and the
//! data window checked against the cell limit before the pixels are decoded.

use std::io::Cursor;

use exr::prelude::*;
use relief_heightfield::Heightfield;

use crate::util::{check_dims, finish};
use crate::{Format, IoError, Raster, ReadOptions, Result as IoResult};

const F: Format = Format::Exr;

fn eerr(e: exr::error::Error) -> IoError {
    IoError::malformed(F, crate::util::codec_reason(e.to_string()))
}

/// Channel names preferred as elevation, in order; otherwise the first channel.
const PREFERRED: [&str; 6] = ["Y", "Z", "height", "elevation", "R", "G"];

pub(crate) fn read(bytes: &[u8], opts: &ReadOptions) -> IoResult<Raster> {
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false).map_err(eerr)?;
    let header = meta
        .headers
        .first()
        .ok_or_else(|| IoError::malformed(F, "no layer"))?;
    if header.deep {
        return Err(IoError::unsupported(F, "deep data"));
    }
    check_tile_levels(bytes, &meta)?;
    // Every part's declared size counts: the decoder reads the offset tables of all of them.
    let mut total = 0u64;
    for h in &meta.headers {
        let (w, hh) = (h.layer_size.0 as u64, h.layer_size.1 as u64);
        let cells = check_dims(F, w, hh, opts)? as u64;
        total = total.saturating_add(cells.saturating_mul(h.channels.list.len().max(1) as u64));
        if total > opts.max_cells as u64 {
            return Err(IoError::Dimensions {
                format: F,
                width: w,
                height: hh,
                reason: format!(
                    "the {} parts declare more than {} samples in total (the cell limit)",
                    meta.headers.len(),
                    opts.max_cells
                ),
            });
        }
    }
    let size = header.layer_size;
    let n = check_dims(F, size.0 as u64, size.1 as u64, opts)?;
    let channels = header.channels.list.len() as u64;
    // Uncompressed samples are at least 2 bytes; compressed ones can shrink, so only the cell
    // limit applies to them (times the channel count).
    if channels == 0 || (n as u64).saturating_mul(channels) > opts.max_cells as u64 {
        return Err(IoError::Dimensions {
            format: F,
            width: size.0 as u64,
            height: size.1 as u64,
            reason: format!(
                "{channels} channels of {n} samples exceed the cell limit or are empty"
            ),
        });
    }
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(eerr)?;
    let layer = image.layer_data;
    let list = &layer.channel_data.list;
    let ch = PREFERRED
        .iter()
        .find_map(|p| list.iter().find(|c| c.name.eq(p)))
        .or_else(|| list.first())
        .ok_or_else(|| IoError::malformed(F, "no channel"))?;
    let (w, h) = (layer.size.0, layer.size.1);
    let (data, dtype): (Vec<f32>, &str) = match &ch.sample_data {
        FlatSamples::F32(v) => (v.clone(), "float32"),
        FlatSamples::F16(v) => (v.iter().map(|x| x.to_f32()).collect(), "float16"),
        FlatSamples::U32(v) => (v.iter().map(|&x| x as f32).collect(), "uint32"),
    };
    if data.len() != w * h {
        return Err(IoError::malformed(
            F,
            format!("channel holds {} samples, expected {w} x {h}", data.len()),
        ));
    }
    finish(
        F,
        w,
        h,
        data,
        opts.cell_size.unwrap_or((1.0, 1.0)),
        None,
        dtype,
    )
}

/// The exr crate picks the chunks of the wanted level from the offset table but trusts the
/// level written in each chunk, and a chunk claiming another level trips its internal
/// assertions (found by fuzzing: `fixtures/bad/exr_fuzz_tile_level_*.exr`). So multi-level
/// (mip/rip-mapped) files are refused and every tile of a single-level file must say level 0.
fn check_tile_levels(bytes: &[u8], meta: &exr::meta::MetaData) -> IoResult<()> {
    use exr::block::chunk::CompressedBlock;
    use exr::meta::BlockDescription;
    use exr::meta::attribute::LevelMode;
    let mut tiled = false;
    for h in &meta.headers {
        if let BlockDescription::Tiles(t) = h.blocks {
            tiled = true;
            if t.level_mode != LevelMode::Singular {
                return Err(IoError::unsupported(
                    F,
                    format!(
                        "{:?} tiled levels; only single-level EXR is read",
                        t.level_mode
                    ),
                ));
            }
        }
    }
    if !tiled {
        return Ok(());
    }
    let chunks = exr::block::read(Cursor::new(bytes), false)
        .and_then(|r| r.filter_chunks(false, |_, _, _| true))
        .map_err(eerr)?;
    for chunk in chunks {
        if let CompressedBlock::Tile(t) = chunk.map_err(eerr)?.compressed_block {
            let level = t.coordinates.level_index;
            if level != Vec2(0, 0) {
                return Err(IoError::malformed(
                    F,
                    format!(
                        "tile {:?} claims level {level:?} in a single-level file",
                        t.coordinates.tile_index
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// One f32 channel named `Y`, ZIP-compressed (lossless; voids stay NaN).
pub(crate) fn write(hf: &Heightfield) -> IoResult<Vec<u8>> {
    let (w, h) = (hf.width(), hf.height());
    let channel = AnyChannel::new("Y", FlatSamples::F32(hf.as_slice().to_vec()));
    let layer = Layer::new(
        (w, h),
        LayerAttributes::named("elevation"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![channel])),
    );
    let image = Image::from_layer(layer);
    let mut out = Cursor::new(Vec::new());
    image.write().to_buffered(&mut out).map_err(eerr)?;
    Ok(out.into_inner())
}
