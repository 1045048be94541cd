//! The versioned binary `.sct` format (bytes only; files are written by `relief-io` / the CLI).
//!
//! Layout (all little-endian):
//! ```text
//! magic  "RLFSCT\r\n" (8 bytes)   version u16 (= 3)   flags u16 (bit 0: 16-bit coefficients)
//! width u32  height u32  cell_x f64  cell_y f64
//! georef (version 2 only; version 1 streams are still read, without it):
//!   present u8 (0 | 1), then when 1, each optional field as flag u8 + value:
//!   pixel_scale, tiepoints, transformation: n u32 + n f64 | geo_key_directory: n u32 + n u16
//!   geo_double_params: n u32 + n f64 | geo_ascii_params, crs: n u32 + n UTF-8 bytes
//!   geotransform: 6 f64
//! node (recursive):
//!   tag u8: 0 layer | 1 constant | 2 river | 3 blend | 4 add | 5 max | 6 min | 7 replace
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
//! checksum (version 3): CRC-32 (IEEE, as zlib's `crc32`) u32 of every byte before it
//! ```
//!
//! Versions 1 (no georeference) and 2 (no checksum) are still read.
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

use relief_heightfield::GeoRef;

use crate::dictionary::{Atom, AtomDescriptor, Dictionary, FunctionAtomRegistry};
use crate::error::{Result, SparseError};
use crate::patches::CentreGrid;
use crate::sct::{Node, Placement, Region, River, RiverMode, Sct, SparseLayer};

/// File magic.
pub const MAGIC: &[u8; 8] = b"RLFSCT\r\n";
/// Current format version.
pub const VERSION: u16 = 3;
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

struct Writer {
    buf: Vec<u8>,
    quantize: bool,
}

impl Writer {
    fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    fn u16(&mut self, v: u16) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    fn len32(&mut self, n: usize, what: &'static str) -> Result<()> {
        let v = u32::try_from(n).map_err(|_| SparseError::param(what, n, "exceeds u32"))?;
        self.u32(v);
        Ok(())
    }

    fn opt_f64s(&mut self, v: Option<&[f64]>, what: &'static str) -> Result<()> {
        self.u8(u8::from(v.is_some()));
        if let Some(v) = v {
            self.len32(v.len(), what)?;
            v.iter().for_each(|&x| self.f64(x));
        }
        Ok(())
    }

    fn opt_str(&mut self, v: Option<&str>, what: &'static str) -> Result<()> {
        self.u8(u8::from(v.is_some()));
        if let Some(v) = v {
            self.len32(v.len(), what)?;
            self.buf.extend_from_slice(v.as_bytes());
        }
        Ok(())
    }

    fn georef(&mut self, g: Option<&GeoRef>) -> Result<()> {
        let Some(g) = g else {
            self.u8(0);
            return Ok(());
        };
        self.u8(1);
        self.opt_f64s(g.pixel_scale.as_deref(), "pixel scale")?;
        self.opt_f64s(g.tiepoints.as_deref(), "tiepoints")?;
        self.opt_f64s(g.transformation.as_deref(), "transformation")?;
        self.u8(u8::from(g.geo_key_directory.is_some()));
        if let Some(k) = &g.geo_key_directory {
            self.len32(k.len(), "geo keys")?;
            k.iter().for_each(|&x| self.u16(x));
        }
        self.opt_f64s(g.geo_double_params.as_deref(), "geo double params")?;
        self.opt_str(g.geo_ascii_params.as_deref(), "geo ascii params")?;
        self.opt_str(g.crs.as_deref(), "crs")?;
        self.opt_f64s(g.geotransform.as_ref().map(|t| &t[..]), "geotransform")?;
        Ok(())
    }

    fn node(&mut self, node: &Node) -> Result<()> {
        match node {
            Node::Layer(l) => {
                self.u8(0);
                self.layer(l)
            }
            Node::Constant(c) => {
                self.u8(1);
                self.f64(*c);
                Ok(())
            }
            Node::River(r) => {
                self.u8(2);
                self.len32(r.path().len(), "river vertices")?;
                for k in 0..r.path().len() {
                    self.f64(r.path()[k][0]);
                    self.f64(r.path()[k][1]);
                    self.f64(r.half_width()[k]);
                    self.f64(r.depth()[k]);
                }
                match r.mode() {
                    RiverMode::Carve => self.u8(0),
                    RiverMode::Bed(b) => {
                        self.u8(1);
                        b.iter().for_each(|&v| self.f64(v));
                    }
                }
                Ok(())
            }
            Node::Blend(c) | Node::Add(c) | Node::Max(c) | Node::Min(c) => {
                self.u8(match node {
                    Node::Blend(_) => 3,
                    Node::Add(_) => 4,
                    Node::Max(_) => 5,
                    _ => 6,
                });
                self.len32(c.len(), "children")?;
                c.iter().try_for_each(|n| self.node(n))
            }
            Node::Replace {
                base,
                overlay,
                region,
                falloff,
            } => {
                self.u8(7);
                match *region {
                    Region::Rect { x0, y0, x1, y1 } => {
                        self.u8(0);
                        [x0, y0, x1, y1].iter().for_each(|&v| self.f64(v));
                    }
                    Region::Disk { cx, cy, r } => {
                        self.u8(1);
                        [cx, cy, r].iter().for_each(|&v| self.f64(v));
                    }
                }
                self.f64(*falloff);
                self.node(base)?;
                self.node(overlay)
            }
        }
    }

    fn layer(&mut self, l: &SparseLayer) -> Result<()> {
        let d = l.dictionary();
        self.dictionary(d)?;
        self.placement_and_codes(l)
    }

    fn dictionary(&mut self, d: &Dictionary) -> Result<()> {
        self.u16(d.patch_size() as u16);
        self.f64(d.spacing());
        self.f64(d.support_radius());
        self.len32(d.len(), "atoms")?;
        for atom in d.atoms() {
            match atom {
                Atom::Data(v) => {
                    self.u8(0);
                    v.iter().for_each(|&x| self.f32(x));
                }
                Atom::Function { func, mean, scale } => {
                    self.u8(1);
                    self.f64(*mean);
                    self.f64(*scale);
                    let desc = func.descriptor();
                    let kind = desc.kind.as_bytes();
                    let n = u16::try_from(kind.len())
                        .map_err(|_| SparseError::param("kind", &desc.kind, "name too long"))?;
                    self.u16(n);
                    self.buf.extend_from_slice(kind);
                    self.len32(desc.params.len(), "params")?;
                    desc.params.iter().for_each(|&p| self.f64(p));
                }
            }
        }
        Ok(())
    }

    fn placement_and_codes(&mut self, l: &SparseLayer) -> Result<()> {
        let d = l.dictionary();
        match l.placement() {
            Placement::Grid(g) => {
                self.u8(0);
                self.f64(g.origin[0]);
                self.f64(g.origin[1]);
                self.f64(g.step);
                self.len32(g.nx, "nx")?;
                self.len32(g.ny, "ny")?;
            }
            Placement::Explicit(c) => {
                self.u8(1);
                self.len32(c.len(), "centres")?;
                for p in c {
                    self.f64(p[0]);
                    self.f64(p[1]);
                }
            }
        }
        l.z().iter().for_each(|&v| self.f32(v));
        for w in l.offsets().windows(2) {
            let c = w[1] - w[0];
            let c = u8::try_from(c).map_err(|_| {
                SparseError::param("coefficients per primitive", c, "must be <= 255")
            })?;
            self.u8(c);
        }
        let wide = d.len() > 65536;
        for &j in l.atom_indices() {
            if wide {
                self.u32(j);
            } else {
                self.u16(j as u16);
            }
        }
        let c = l.coefficients();
        if self.quantize {
            let lo = c.iter().fold(f32::INFINITY, |m, &v| m.min(v));
            let hi = c.iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v));
            let (lo, hi) = if c.is_empty() { (0.0, 0.0) } else { (lo, hi) };
            self.f32(lo);
            self.f32(hi);
            let range = hi as f64 - lo as f64;
            for &v in c {
                let q = if range > 0.0 {
                    ((v as f64 - lo as f64) / range * 65535.0).round()
                } else {
                    0.0
                };
                self.u16(q.clamp(0.0, 65535.0) as u16);
            }
        } else {
            c.iter().for_each(|&v| self.f32(v));
        }
        Ok(())
    }
}

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
    quantized: bool,
    registry: &'a FunctionAtomRegistry,
}

impl<'a> Reader<'a> {
    fn err(&self, reason: impl Into<String>) -> SparseError {
        SparseError::Format {
            offset: self.pos,
            reason: reason.into(),
        }
    }
    fn remaining(&self) -> usize {
        self.b.len() - self.pos
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        if n > self.remaining() {
            return Err(self.err(format!(
                "truncated: need {n} bytes, {} remain",
                self.remaining()
            )));
        }
        let s = &self.b[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    /// Checks that `count` items of `size` bytes can still be read.
    fn need(&self, count: usize, size: usize, what: &str) -> Result<()> {
        match count.checked_mul(size) {
            Some(t) if t <= self.remaining() => Ok(()),
            _ => Err(self.err(format!(
                "declared {what} count {count} needs more than the {} bytes left",
                self.remaining()
            ))),
        }
    }
    fn u8(&mut self) -> Result<u8> {
        Ok(self.take(1)?[0])
    }
    fn u16(&mut self) -> Result<u16> {
        let s = self.take(2)?;
        Ok(u16::from_le_bytes([s[0], s[1]]))
    }
    fn u32(&mut self) -> Result<u32> {
        let s = self.take(4)?;
        Ok(u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
    }
    fn f32(&mut self) -> Result<f32> {
        let s = self.take(4)?;
        Ok(f32::from_le_bytes([s[0], s[1], s[2], s[3]]))
    }
    fn f64(&mut self) -> Result<f64> {
        let s = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(s);
        Ok(f64::from_le_bytes(a))
    }
    fn flag(&mut self, what: &str) -> Result<bool> {
        match self.u8()? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(self.err(format!("invalid {what} flag {v}"))),
        }
    }
    fn count(&mut self, size: usize, what: &str) -> Result<usize> {
        let n = self.u32()? as usize;
        if n > MAX_GEOREF_ITEMS {
            return Err(self.err(format!("{what} count {n} exceeds {MAX_GEOREF_ITEMS}")));
        }
        self.need(n, size, what)?;
        Ok(n)
    }
    fn opt_f64s(&mut self, what: &str) -> Result<Option<Vec<f64>>> {
        if !self.flag(what)? {
            return Ok(None);
        }
        let n = self.count(8, what)?;
        (0..n).map(|_| self.f64()).collect::<Result<_>>().map(Some)
    }
    fn opt_str(&mut self, what: &str) -> Result<Option<String>> {
        if !self.flag(what)? {
            return Ok(None);
        }
        let n = self.count(1, what)?;
        let bytes = self.take(n)?;
        String::from_utf8(bytes.to_vec())
            .map(Some)
            .map_err(|_| self.err(format!("{what} is not UTF-8")))
    }
    fn georef(&mut self) -> Result<Option<GeoRef>> {
        if !self.flag("georeference")? {
            return Ok(None);
        }
        let pixel_scale = self.opt_f64s("pixel scale")?;
        let tiepoints = self.opt_f64s("tiepoints")?;
        let transformation = self.opt_f64s("transformation")?;
        let geo_key_directory = if self.flag("geo keys")? {
            let n = self.count(2, "geo keys")?;
            Some((0..n).map(|_| self.u16()).collect::<Result<Vec<u16>>>()?)
        } else {
            None
        };
        let geo_double_params = self.opt_f64s("geo double params")?;
        let geo_ascii_params = self.opt_str("geo ascii params")?;
        let crs = self.opt_str("crs")?;
        let geotransform = match self.opt_f64s("geotransform")? {
            None => None,
            Some(t) => match <[f64; 6]>::try_from(t.as_slice()) {
                Ok(a) if a.iter().all(|v| v.is_finite()) => Some(a),
                _ => return Err(self.err("geotransform must be 6 finite numbers")),
            },
        };
        Ok(Some(GeoRef {
            pixel_scale,
            tiepoints,
            transformation,
            geo_key_directory,
            geo_double_params,
            geo_ascii_params,
            crs,
            geotransform,
        }))
    }
    fn wrap<T>(&self, r: Result<T>) -> Result<T> {
        r.map_err(|e| match e {
            SparseError::Format { .. } => e,
            other => self.err(other.to_string()),
        })
    }

    fn node(&mut self, depth: usize) -> Result<Node> {
        if depth > MAX_DEPTH {
            return Err(self.err("tree deeper than 64 levels"));
        }
        let tag = self.u8()?;
        match tag {
            0 => Ok(Node::Layer(self.layer()?)),
            1 => Ok(Node::Constant(self.f64()?)),
            2 => {
                let n = self.u32()? as usize;
                self.need(n, 32, "river vertex")?;
                let (mut path, mut hw, mut dp) = (
                    Vec::with_capacity(n),
                    Vec::with_capacity(n),
                    Vec::with_capacity(n),
                );
                for _ in 0..n {
                    path.push([self.f64()?, self.f64()?]);
                    hw.push(self.f64()?);
                    dp.push(self.f64()?);
                }
                let mode = match self.u8()? {
                    0 => RiverMode::Carve,
                    1 => {
                        self.need(n, 8, "bed elevation")?;
                        let mut b = Vec::with_capacity(n);
                        for _ in 0..n {
                            b.push(self.f64()?);
                        }
                        RiverMode::Bed(b)
                    }
                    m => return Err(self.err(format!("unknown river mode {m}"))),
                };
                let r = River::new(path, hw, dp, mode);
                Ok(Node::River(self.wrap(r)?))
            }
            3..=6 => {
                let n = self.u32()? as usize;
                self.need(n, 1, "child")?;
                let mut c = Vec::with_capacity(n);
                for _ in 0..n {
                    c.push(self.node(depth + 1)?);
                }
                Ok(match tag {
                    3 => Node::Blend(c),
                    4 => Node::Add(c),
                    5 => Node::Max(c),
                    _ => Node::Min(c),
                })
            }
            7 => {
                let region = match self.u8()? {
                    0 => Region::Rect {
                        x0: self.f64()?,
                        y0: self.f64()?,
                        x1: self.f64()?,
                        y1: self.f64()?,
                    },
                    1 => Region::Disk {
                        cx: self.f64()?,
                        cy: self.f64()?,
                        r: self.f64()?,
                    },
                    k => return Err(self.err(format!("unknown region kind {k}"))),
                };
                let falloff = self.f64()?;
                let base = Box::new(self.node(depth + 1)?);
                let overlay = Box::new(self.node(depth + 1)?);
                Ok(Node::Replace {
                    base,
                    overlay,
                    region,
                    falloff,
                })
            }
            t => Err(self.err(format!("unknown node tag {t}"))),
        }
    }

    fn layer(&mut self) -> Result<SparseLayer> {
        let dict = self.dictionary()?;
        self.placement_and_codes(dict)
    }

    fn dictionary(&mut self) -> Result<Dictionary> {
        let a = self.u16()? as usize;
        let spacing = self.f64()?;
        let radius = self.f64()?;
        let d = Dictionary::new(a, spacing, radius);
        let mut dict = self.wrap(d)?;
        let n_atoms = self.u32()? as usize;
        let k = a * a;
        self.need(n_atoms, (1 + 4 * k).min(23), "atom")?;
        for _ in 0..n_atoms {
            match self.u8()? {
                0 => {
                    self.need(k, 4, "atom sample")?;
                    let mut v = Vec::with_capacity(k);
                    for _ in 0..k {
                        let x = self.f32()?;
                        if !x.is_finite() {
                            return Err(self.err("non-finite atom sample"));
                        }
                        v.push(x);
                    }
                    dict.push_raw(Atom::Data(v));
                }
                1 => {
                    let mean = self.f64()?;
                    let scale = self.f64()?;
                    if !(mean.is_finite() && scale.is_finite()) {
                        return Err(self.err("non-finite function atom normalisation"));
                    }
                    let len = self.u16()? as usize;
                    let kind = std::str::from_utf8(self.take(len)?)
                        .map_err(|_| self.err("function atom kind is not UTF-8"))?
                        .to_string();
                    let np = self.u32()? as usize;
                    self.need(np, 8, "parameter")?;
                    let mut params = Vec::with_capacity(np);
                    for _ in 0..np {
                        params.push(self.f64()?);
                    }
                    let func = self.registry.construct(&AtomDescriptor { kind, params });
                    let func = self.wrap(func)?;
                    dict.push_raw(Atom::Function { func, mean, scale });
                }
                t => return Err(self.err(format!("unknown atom kind {t}"))),
            }
        }
        Ok(dict)
    }

    fn placement_and_codes(&mut self, dict: Dictionary) -> Result<SparseLayer> {
        let placement = match self.u8()? {
            0 => {
                let origin = [self.f64()?, self.f64()?];
                let step = self.f64()?;
                let nx = self.u32()? as usize;
                let ny = self.u32()? as usize;
                if !(step.is_finite() && step > 0.0) {
                    return Err(self.err(format!("invalid grid step {step}")));
                }
                // Each primitive needs at least 5 bytes (z + count) further on.
                self.need(nx.saturating_mul(ny), 5, "primitive")?;
                Placement::Grid(CentreGrid {
                    origin,
                    step,
                    nx,
                    ny,
                })
            }
            1 => {
                let n = self.u32()? as usize;
                self.need(n, 16 + 5, "centre")?;
                let mut c = Vec::with_capacity(n);
                for _ in 0..n {
                    c.push([self.f64()?, self.f64()?]);
                }
                Placement::Explicit(c)
            }
            t => return Err(self.err(format!("unknown placement {t}"))),
        };
        let n = placement.len();
        self.need(n, 5, "primitive")?;
        let mut z = Vec::with_capacity(n);
        for _ in 0..n {
            z.push(self.f32()?);
        }
        let counts = self.take(n)?;
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0u32);
        let mut nnz = 0u32;
        for &c in counts {
            nnz = nnz
                .checked_add(c as u32)
                .ok_or_else(|| self.err("coefficient count overflows"))?;
            offsets.push(nnz);
        }
        let nnz = nnz as usize;
        let wide = dict.len() > 65536;
        self.need(nnz, if wide { 4 } else { 2 }, "atom index")?;
        let mut atoms = Vec::with_capacity(nnz);
        for _ in 0..nnz {
            atoms.push(if wide {
                self.u32()?
            } else {
                self.u16()? as u32
            });
        }
        let coeffs = if self.quantized {
            let lo = self.f32()? as f64;
            let hi = self.f32()? as f64;
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(self.err("invalid quantisation range"));
            }
            self.need(nnz, 2, "quantised coefficient")?;
            let mut c = Vec::with_capacity(nnz);
            for _ in 0..nnz {
                let q = self.u16()? as f64;
                c.push((lo + q * (hi - lo) / 65535.0) as f32);
            }
            c
        } else {
            self.need(nnz, 4, "coefficient")?;
            let mut c = Vec::with_capacity(nnz);
            for _ in 0..nnz {
                c.push(self.f32()?);
            }
            c
        };
        let l = SparseLayer::from_parts(Arc::new(dict), placement, z, offsets, atoms, coeffs);
        self.wrap(l)
    }
}

impl Sct {
    /// Serialises to `.sct` bytes with `f32` coefficients.
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        self.to_bytes_with(&FormatOptions::default())
    }

    /// Serialises to `.sct` bytes.
    pub fn to_bytes_with(&self, options: &FormatOptions) -> Result<Vec<u8>> {
        let mut w = Writer {
            buf: Vec::new(),
            quantize: options.quantize_coefficients,
        };
        w.buf.extend_from_slice(MAGIC);
        w.u16(VERSION);
        w.u16(if options.quantize_coefficients {
            FLAG_QUANTIZED
        } else {
            0
        });
        w.len32(self.width(), "width")?;
        w.len32(self.height(), "height")?;
        w.f64(self.cell_size().0);
        w.f64(self.cell_size().1);
        w.georef(self.georef())?;
        w.node(self.root())?;
        Ok(seal(w.buf))
    }

    /// Reads `.sct` bytes; function atoms are rebuilt through `registry`.
    pub fn from_bytes(bytes: &[u8], registry: &FunctionAtomRegistry) -> Result<Sct> {
        // The checksum is verified before anything is decoded: a flipped byte is an error
        // naming the checksum, never a model with other values.
        let bytes = checked_body(bytes, MAGIC, FIRST_CHECKSUMMED, "the .sct")?;
        let mut r = Reader {
            b: bytes,
            pos: 0,
            quantized: false,
            registry,
        };
        if r.take(8)? != MAGIC {
            return Err(SparseError::Format {
                offset: 0,
                reason: "bad magic (not a .sct stream)".into(),
            });
        }
        let version = r.u16()?;
        if !(OLDEST_VERSION..=VERSION).contains(&version) {
            return Err(r.err(format!(
                "unsupported version {version} (expected {OLDEST_VERSION} to {VERSION})"
            )));
        }
        let flags = r.u16()?;
        if flags & !FLAG_QUANTIZED != 0 {
            return Err(r.err(format!("unknown flags {flags:#x}")));
        }
        r.quantized = flags & FLAG_QUANTIZED != 0;
        let width = r.u32()? as usize;
        let height = r.u32()? as usize;
        let cell = (r.f64()?, r.f64()?);
        let georef = if version >= 2 { r.georef()? } else { None };
        let root = r.node(0)?;
        if r.remaining() != 0 {
            return Err(r.err(format!("{} trailing bytes", r.remaining())));
        }
        let s = Sct::new(root, width, height, cell).map(|s| s.with_georef(georef));
        r.wrap(s)
    }
}

impl Dictionary {
    /// Serialises the dictionary alone (atoms, patch size, spacing, support radius): the
    /// versioned little-endian stream described in the [module docs](self).
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        let mut w = Writer {
            buf: Vec::new(),
            quantize: false,
        };
        w.buf.extend_from_slice(DICTIONARY_MAGIC);
        w.u16(DICTIONARY_VERSION);
        w.u16(0);
        w.dictionary(self)?;
        Ok(seal(w.buf))
    }

    /// Reads a dictionary written by [`Dictionary::to_bytes`]; function atoms are rebuilt
    /// through `registry`. Truncated, corrupt or hostile bytes, unknown versions, trailing
    /// bytes and data atoms that are not unit-norm are errors.
    pub fn from_bytes(bytes: &[u8], registry: &FunctionAtomRegistry) -> Result<Dictionary> {
        let bytes = checked_body(
            bytes,
            DICTIONARY_MAGIC,
            FIRST_CHECKSUMMED_DICTIONARY,
            "the dictionary",
        )?;
        let mut r = Reader {
            b: bytes,
            pos: 0,
            quantized: false,
            registry,
        };
        if r.take(8)? != DICTIONARY_MAGIC {
            return Err(SparseError::Format {
                offset: 0,
                reason: "bad magic (not a relief dictionary stream)".into(),
            });
        }
        let version = r.u16()?;
        if !(OLDEST_DICTIONARY_VERSION..=DICTIONARY_VERSION).contains(&version) {
            return Err(r.err(format!(
                "unsupported dictionary version {version} (expected \
                 {OLDEST_DICTIONARY_VERSION} to {DICTIONARY_VERSION})"
            )));
        }
        let flags = r.u16()?;
        if flags != 0 {
            return Err(r.err(format!("unknown flags {flags:#x}")));
        }
        let dict = r.dictionary()?;
        if r.remaining() != 0 {
            return Err(r.err(format!("{} trailing bytes", r.remaining())));
        }
        for (i, atom) in dict.atoms().iter().enumerate() {
            let norm = match atom {
                Atom::Data(v) => v.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt(),
                Atom::Function { scale, .. } => {
                    if *scale > 0.0 {
                        1.0
                    } else {
                        0.0
                    }
                }
            };
            if (norm - 1.0).abs() > 1e-3 {
                return Err(r.err(SparseError::NotNormalised { atom: i, norm }.to_string()));
            }
        }
        Ok(dict)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc32_is_the_ieee_checksum() {
        // The standard check value of CRC-32/ISO-HDLC (zlib, PNG).
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn stream_header_reports_version_and_checksum() {
        let s = Sct::new(Node::Constant(2.0), 4, 4, (1.0, 1.0)).unwrap();
        let mut b = s.to_bytes().unwrap();
        let h = stream_header(&b).unwrap();
        assert!(h.is_sct);
        assert_eq!(h.version, VERSION);
        assert_eq!(h.checksum_ok, Some(true));
        let n = b.len();
        b[n - 5] ^= 1;
        assert_eq!(stream_header(&b).unwrap().checksum_ok, Some(false));
        let e = Sct::from_bytes(&b, &FunctionAtomRegistry::new()).unwrap_err();
        assert!(e.to_string().contains("checksum"), "{e}");
        assert!(stream_header(b"not a model").is_none());
    }
}
