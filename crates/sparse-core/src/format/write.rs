//! Writing: the stream encoder and the `to_bytes` of models and dictionaries.

use super::*;

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
            Node::Field(f) => {
                self.u8(8);
                self.u8(match f.kernel() {
                    Kernel::Keys => 0,
                    Kernel::Lanczos3 => 1,
                });
                self.len32(f.width(), "field width")?;
                self.len32(f.height(), "field height")?;
                self.f64(f.origin()[0]);
                self.f64(f.origin()[1]);
                self.f64(f.step());
                f.samples().iter().for_each(|&v| self.f32(v));
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
}
