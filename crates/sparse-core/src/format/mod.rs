//! The versioned binary `.sct` format (bytes only; files are written by `relief-io` / the CLI).
//!
//! Layout (all little-endian):
//! ```text
//! magic  "RLFSCT\r\n" (8 bytes)   version u16 (= 4)   flags u16 (bit 0: 16-bit coefficients)
//! width u32  height u32  cell_x f64  cell_y f64
//! georef (version 2 only; version 1 streams are still read, without it):
//!   present u8 (0 | 1), then when 1, each optional field as flag u8 + value:
//!   pixel_scale, tiepoints, transformation: n u32 + n f64 | geo_key_directory: n u32 + n u16
//!   geo_double_params: n u32 + n f64 | geo_ascii_params, crs: n u32 + n UTF-8 bytes
//!   geotransform: 6 f64
//! node (recursive):
//!   tag u8: 0 layer | 1 constant | 2 river | 3 blend | 4 add | 5 max | 6 min | 7 replace
//!           | 8 field (version 4)
//!   layer:    dictionary, placement, z (n f32), counts (n u8), indices (nnz u16 if N <= 65536
//!             else u32), coefficients (nnz f32, or lo f32 + hi f32 + nnz u16 when quantised)
//!   dictionary: a u16, delta f64, R f64, N u32, N atoms:
//!             0 = data: a*a f32 | 1 = function: mean f64, scale f64, kind (u16 len + UTF-8),
//!             params (u32 count + f64s)
//!   placement: 0 = grid: ox f64, oy f64, step f64, nx u32, ny u32 | 1 = explicit: n u32, 2n f64
//!   constant: f64
//!   river:    n u32, n x (x, y, half width, depth) f64, mode u8 (0 carve | 1 bed + n f64)
//!   blend/add/max/min: count u32, children
//!   replace:  region u8 (0 rect: 4 f64 | 1 disk: 3 f64), falloff f64, base, overlay
//!   field:    kernel u8 (0 keys | 1 lanczos3), width u32, height u32, origin 2 f64, step f64,
//!             width*height f32
//! checksum (version 3): CRC-32 (IEEE, as zlib's `crc32`) u32 of every byte before it
//! ```
//!
//! Versions 1 (no georeference), 2 (no checksum) and 3 (no field node) are still read.
//!
//! A dictionary alone (`.dict` files of `relief learn`, [`Dictionary::to_bytes`]) is
//! ```text
//! magic  "RLFDIC\r\n" (8 bytes)   version u16 (= 2)   flags u16 (= 0)   dictionary (as above)
//! checksum (version 2): CRC-32 u32 of every byte before it
//! ```
//! (version 1, without the checksum, is still read).
//! and its reader also checks that every data atom has unit L2 norm (OMP relies on it).
//!
//! The reader checks every declared count against the bytes that remain **before** allocating,
//! limits the tree depth, and validates the decoded objects through the same constructors as the
//! API, so corrupt, truncated or hostile input is an `Err`, never a panic or a huge allocation.

use std::sync::Arc;

use relief_heightfield::{GeoRef, Kernel};

use crate::dictionary::{Atom, AtomDescriptor, Dictionary, FunctionAtomRegistry};
use crate::error::{Result, SparseError};
use crate::patches::CentreGrid;
use crate::sct::{Field, Node, Placement, Region, River, RiverMode, Sct, SparseLayer};

/// File magic.
pub const MAGIC: &[u8; 8] = b"RLFSCT\r\n";
/// Current format version.
pub const VERSION: u16 = 4;
/// First `.sct` version that ends with a CRC-32 of the stream.
const FIRST_CHECKSUMMED: u16 = 3;
/// First dictionary version that ends with a CRC-32 of the stream.
const FIRST_CHECKSUMMED_DICTIONARY: u16 = 2;
/// Oldest version still read (no georeference block).
const OLDEST_VERSION: u16 = 1;
/// Largest element count of one georeference field.
const MAX_GEOREF_ITEMS: usize = 1 << 16;
/// Magic of a dictionary stream ([`Dictionary::to_bytes`]).
pub const DICTIONARY_MAGIC: &[u8; 8] = b"RLFDIC\r\n";
/// Current version of the dictionary stream.
pub const DICTIONARY_VERSION: u16 = 2;
/// Oldest dictionary version still read (no checksum).
const OLDEST_DICTIONARY_VERSION: u16 = 1;

mod read;
mod write;

/// CRC-32 (IEEE 802.3 polynomial, reflected; the checksum of zlib, PNG and gzip).
pub fn crc32(bytes: &[u8]) -> u32 {
    const TABLE: [u32; 256] = {
        let mut t = [0u32; 256];
        let mut i = 0;
        while i < 256 {
            let mut c = i as u32;
            let mut k = 0;
            while k < 8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
                k += 1;
            }
            t[i] = c;
            i += 1;
        }
        t
    };
    let mut c = !0u32;
    for &b in bytes {
        c = TABLE[((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
    }
    !c
}

/// Splits a checksummed stream into its body and checks the trailing CRC-32; `what` names the
/// stream in the error.
fn verify_checksum<'a>(bytes: &'a [u8], what: &str) -> Result<&'a [u8]> {
    let Some(split) = bytes.len().checked_sub(4).filter(|&n| n >= 12) else {
        return Err(SparseError::Format {
            offset: bytes.len(),
            reason: format!("truncated {what}: no room for the header and the checksum"),
        });
    };
    let (body, tail) = bytes.split_at(split);
    let stored = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
    let actual = crc32(body);
    if stored != actual {
        return Err(SparseError::Format {
            offset: split,
            reason: format!(
                "checksum mismatch ({what} stores CRC-32 {stored:08x}, its bytes give \
                 {actual:08x}): the file is corrupt or truncated"
            ),
        });
    }
    Ok(body)
}

/// The bytes to decode: for a stream with `magic` whose version is at least `first` (the first
/// checksummed version), the body before its verified CRC-32; otherwise the bytes as given
/// (older versions, or not this kind of stream: the decoder reports those).
fn checked_body<'a>(bytes: &'a [u8], magic: &[u8; 8], first: u16, what: &str) -> Result<&'a [u8]> {
    match bytes.get(8..10) {
        Some(v) if bytes.starts_with(magic) && u16::from_le_bytes([v[0], v[1]]) >= first => {
            verify_checksum(bytes, what)
        }
        _ => Ok(bytes),
    }
}

/// Appends the CRC-32 of `buf` to it (the last field of checksummed streams).
fn seal(mut buf: Vec<u8>) -> Vec<u8> {
    let crc = crc32(&buf);
    buf.extend_from_slice(&crc.to_le_bytes());
    buf
}

/// What the header of a `.sct` or dictionary stream says, without decoding the rest: for
/// `relief info`.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamHeader {
    /// True for a `.sct` model, false for a dictionary.
    pub is_sct: bool,
    /// Format version.
    pub version: u16,
    /// `Some(true)` when the checksum matches, `Some(false)` when it does not, `None` for
    /// versions without one.
    pub checksum_ok: Option<bool>,
}

/// Reads the header of a `.sct` or dictionary stream (magic, version, checksum).
pub fn stream_header(bytes: &[u8]) -> Option<StreamHeader> {
    let is_sct = bytes.starts_with(MAGIC);
    if !is_sct && !bytes.starts_with(DICTIONARY_MAGIC) {
        return None;
    }
    let version = u16::from_le_bytes([*bytes.get(8)?, *bytes.get(9)?]);
    let first = if is_sct {
        FIRST_CHECKSUMMED
    } else {
        FIRST_CHECKSUMMED_DICTIONARY
    };
    let checksum_ok = (version >= first).then(|| verify_checksum(bytes, "stream").is_ok());
    Some(StreamHeader {
        is_sct,
        version,
        checksum_ok,
    })
}
const FLAG_QUANTIZED: u16 = 1;
const MAX_DEPTH: usize = 64;

/// Options of [`Sct::to_bytes_with`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FormatOptions {
    /// Store coefficient values as 16-bit integers over the per-layer range instead of `f32`
    /// (lossy: relative error <= range / 131070).
    pub quantize_coefficients: bool,
}

#[cfg(test)]
mod tests;
