//! Reading: the checked stream decoder and the `from_bytes` of models and dictionaries.

use super::*;

struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
    quantized: bool,
    registry: &'a FunctionAtomRegistry,
}

impl<'a> Reader<'a> {
    fn new(b: &'a [u8], registry: &'a FunctionAtomRegistry) -> Self {
        Self {
            b,
            pos: 0,
            quantized: false,
            registry,
        }
    }
    /// Reads the magic and the version, which must be `magic` and one of `versions`; errors
    /// name the stream (`stream`: "a .sct stream") and the version (`version`: "version").
    fn header(
        &mut self,
        magic: &[u8; 8],
        versions: std::ops::RangeInclusive<u16>,
        stream: &str,
        version: &str,
    ) -> Result<u16> {
        if self.take(8)? != magic {
            return Err(SparseError::Format {
                offset: 0,
                reason: format!("bad magic (not {stream})"),
            });
        }
        let v = self.u16()?;
        if !versions.contains(&v) {
            let (lo, hi) = (versions.start(), versions.end());
            return Err(self.err(format!("unsupported {version} {v} (expected {lo} to {hi})")));
        }
        Ok(v)
    }
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
            8 => {
                let kernel = match self.u8()? {
                    0 => Kernel::Keys,
                    1 => Kernel::Lanczos3,
                    k => return Err(self.err(format!("unknown field kernel {k}"))),
                };
                let (w, h) = (self.u32()? as usize, self.u32()? as usize);
                let origin = [self.f64()?, self.f64()?];
                let step = self.f64()?;
                let n = w
                    .checked_mul(h)
                    .ok_or_else(|| self.err(format!("field size {w} x {h} overflows")))?;
                self.need(n, 4, "field sample")?;
                let mut v = Vec::with_capacity(n);
                for _ in 0..n {
                    v.push(self.f32()?);
                }
                let f = Field::new(w, h, v, origin, step, kernel);
                Ok(Node::Field(self.wrap(f)?))
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
    /// Reads `.sct` bytes; function atoms are rebuilt through `registry`.
    pub fn from_bytes(bytes: &[u8], registry: &FunctionAtomRegistry) -> Result<Sct> {
        // The checksum is verified before anything is decoded: a flipped byte is an error
        // naming the checksum, never a model with other values.
        let bytes = checked_body(bytes, MAGIC, FIRST_CHECKSUMMED, "the .sct")?;
        let mut r = Reader::new(bytes, registry);
        let version = r.header(MAGIC, OLDEST_VERSION..=VERSION, "a .sct stream", "version")?;
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
        let mut r = Reader::new(bytes, registry);
        r.header(
            DICTIONARY_MAGIC,
            OLDEST_DICTIONARY_VERSION..=DICTIONARY_VERSION,
            "a relief dictionary stream",
            "dictionary version",
        )?;
        let flags = r.u16()?;
        if flags != 0 {
            return Err(r.err(format!("unknown flags {flags:#x}")));
        }
        let dict = r.dictionary()?;
        if r.remaining() != 0 {
            return Err(r.err(format!("{} trailing bytes", r.remaining())));
        }
        // A dictionary file is read to code with: one without atoms codes nothing.
        if dict.is_empty() {
            return Err(SparseError::EmptyDictionary {
                n_atoms: 0,
                dim: dict.patch_size() * dict.patch_size(),
            });
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
