//! TIFF and BigTIFF image file directories, encoded by hand for the streaming writers
//! ([`crate::GeoTiffStripWriter`], [`crate::TiledGeoTiffWriter`]): they place the directory
//! after (strips) or before (COG) data written in bounded memory, which the `tiff` crate's
//! encoder, holding the whole image directory layout itself, does not allow.

use relief_heightfield::GeoRef;

/// A TIFF or BigTIFF header (16 bytes; a classic header uses the first 8) whose first
/// directory is at `ifd`.
pub(crate) fn header(big: bool, ifd: u64) -> Vec<u8> {
    let mut h = Vec::with_capacity(16);
    h.extend_from_slice(b"II");
    if big {
        h.extend_from_slice(&43u16.to_le_bytes());
        h.extend_from_slice(&8u16.to_le_bytes());
        h.extend_from_slice(&0u16.to_le_bytes());
        h.extend_from_slice(&ifd.to_le_bytes());
    } else {
        h.extend_from_slice(&42u16.to_le_bytes());
        h.extend_from_slice(&(ifd as u32).to_le_bytes());
        h.extend_from_slice(&[0u8; 8]);
    }
    h
}

/// A tag value.
#[derive(Debug, Clone)]
pub(crate) enum Value {
    Short(Vec<u16>),
    Long(Vec<u32>),
    /// Offsets and byte counts: LONG in TIFF, LONG8 in BigTIFF.
    Offsets(Vec<u64>),
    Double(Vec<f64>),
    Ascii(String),
}

impl Value {
    pub(crate) fn is_empty(&self) -> bool {
        match self {
            Value::Short(v) => v.is_empty(),
            Value::Long(v) => v.is_empty(),
            Value::Offsets(v) => v.is_empty(),
            Value::Double(v) => v.is_empty(),
            Value::Ascii(v) => v.is_empty(),
        }
    }

    /// TIFF type, count and little-endian bytes.
    fn encode(&self, big: bool) -> (u16, u64, Vec<u8>) {
        match self {
            Value::Short(v) => (
                3,
                v.len() as u64,
                v.iter().flat_map(|a| a.to_le_bytes()).collect(),
            ),
            Value::Long(v) => (
                4,
                v.len() as u64,
                v.iter().flat_map(|a| a.to_le_bytes()).collect(),
            ),
            Value::Offsets(v) if big => (
                16,
                v.len() as u64,
                v.iter().flat_map(|a| a.to_le_bytes()).collect(),
            ),
            Value::Offsets(v) => (
                4,
                v.len() as u64,
                v.iter().flat_map(|&a| (a as u32).to_le_bytes()).collect(),
            ),
            Value::Double(v) => (
                12,
                v.len() as u64,
                v.iter().flat_map(|a| a.to_le_bytes()).collect(),
            ),
            Value::Ascii(s) => {
                let mut b = s.as_bytes().to_vec();
                b.push(0);
                (2, b.len() as u64, b)
            }
        }
    }
}

/// Encodes the directories one after the other from file offset `at` (each followed by its
/// out-of-line values, chained by their next-directory offsets; the last points to 0).
pub(crate) fn encode_directories(big: bool, dirs: &[Vec<(u16, Value)>], at: u64) -> Vec<u8> {
    let (entry, inline, count_len, next_len) = if big { (20, 8, 8, 8) } else { (12, 4, 2, 4) };
    let mut out: Vec<u8> = Vec::new();
    for (d, entries) in dirs.iter().enumerate() {
        let start = at + out.len() as u64;
        let table = (count_len + entry * entries.len() + next_len) as u64;
        let mut extra: Vec<u8> = Vec::new();
        let mut table_bytes: Vec<u8> = Vec::with_capacity(table as usize);
        if big {
            table_bytes.extend_from_slice(&(entries.len() as u64).to_le_bytes());
        } else {
            table_bytes.extend_from_slice(&(entries.len() as u16).to_le_bytes());
        }
        for (tag, v) in entries {
            let (typ, count, bytes) = v.encode(big);
            table_bytes.extend_from_slice(&tag.to_le_bytes());
            table_bytes.extend_from_slice(&typ.to_le_bytes());
            if big {
                table_bytes.extend_from_slice(&count.to_le_bytes());
            } else {
                table_bytes.extend_from_slice(&(count as u32).to_le_bytes());
            }
            if bytes.len() <= inline {
                let mut word = vec![0u8; inline];
                word[..bytes.len()].copy_from_slice(&bytes);
                table_bytes.extend_from_slice(&word);
            } else {
                extra.resize(extra.len().next_multiple_of(8), 0);
                let off = start + table + extra.len() as u64;
                if big {
                    table_bytes.extend_from_slice(&off.to_le_bytes());
                } else {
                    table_bytes.extend_from_slice(&(off as u32).to_le_bytes());
                }
                extra.extend_from_slice(&bytes);
            }
        }
        extra.resize(extra.len().next_multiple_of(8), 0);
        let next = if d + 1 < dirs.len() {
            start + table + extra.len() as u64
        } else {
            0
        };
        if big {
            table_bytes.extend_from_slice(&next.to_le_bytes());
        } else {
            table_bytes.extend_from_slice(&(next as u32).to_le_bytes());
        }
        out.extend_from_slice(&table_bytes);
        out.extend_from_slice(&extra);
    }
    out
}

/// Appends the GeoTIFF tags of `g` (pixel scale, tie points, transformation, GeoKey
/// directory, double and ASCII parameters), skipping those it does not have.
pub(crate) fn georef_entries(g: &GeoRef, e: &mut Vec<(u16, Value)>) {
    let tags = [
        (33550, g.pixel_scale.clone().map(Value::Double)),
        (33922, g.tiepoints.clone().map(Value::Double)),
        (34264, g.transformation.clone().map(Value::Double)),
        (34735, g.geo_key_directory.clone().map(Value::Short)),
        (34736, g.geo_double_params.clone().map(Value::Double)),
        (34737, g.geo_ascii_params.clone().map(Value::Ascii)),
    ];
    e.extend(tags.into_iter().filter_map(|(tag, v)| Some((tag, v?))));
}

/// The largest decompression ratio of a TIFF compression scheme (name, ratio): DEFLATE
/// 1032:1, PackBits 64:1 (2 bytes for a run of 128), LZW 3641:1 (a 9-bit code for at most 4096
/// bytes), ZSTD 65536:1 (generous: RLE blocks); `None` for schemes without a known bound.
pub(crate) fn max_ratio(compression: u16) -> Option<(&'static str, u64)> {
    match compression {
        8 | 32946 => Some(("DEFLATE", 1032)),
        32773 => Some(("PackBits", 64)),
        5 => Some(("LZW", 3641)),
        50000 => Some(("ZSTD", 65536)),
        _ => None,
    }
}

/// The name of a TIFF compression scheme GDAL writes that relief's decoder does not read
/// (None for the ones it does: none, LZW, DEFLATE, PackBits, JPEG, ZSTD; and for unknown
/// codes, which the decoder names itself; CCITT files are 1-bit, refused by sample format).
pub(crate) fn unreadable_compression(compression: u16) -> Option<&'static str> {
    Some(match compression {
        34661 => "JBIG",
        34676 | 34677 => "SGILog",
        34712 => "JPEG 2000",
        34887 => "LERC",
        34925 => "LZMA",
        50001 => "WebP",
        50002 => "JPEG XL",
        _ => return None,
    })
}
