//! The last x4 step of an amplification as a job of its own: its input raster and its
//! dictionary, from which any window of the amplified output is computed alone (tiled runs:
//! the steps before it are cheap, a sixteenth of the last one's cells, and run once; the
//! last one runs tile by tile).
//!
//! # Why a window equals the full run
//! Every part of a step is local: a primitive's code depends on its coarse patch (radius
//! `R`), the residual's back-projection is a 4-iteration stencil of radius 3 (Lanczos-3; 2 with
//! Keys) and its interpolation reaches 3 samples, and the primitives' grids start at the same
//! origin whatever the raster size. A window is computed on a crop of the input whose corner is
//! a multiple of both grid steps, with a halo of `4 ceil(R) + 16` coarse pixels (at least the
//! `2R + 2 ceil(R) + 14` the dependencies reach) so that no
//! sample of the window sees the crop's clamped border; the seeded atom choice hashes each
//! primitive's position in the whole grid ([`GridFrame`]). The same floating-point operations
//! then run in the same order, so the window is bit-identical (tested).
//!
//! # Byte stream ([`LastStep::to_bytes`])
//! Little-endian: magic `RLFLAST1`, `u16` version (1), the input (`u32` width and height,
//! `f64` cell sizes, the samples as `f32`), the dictionary (`u32` atom count `N` and coarse
//! patch side `a`; `L` as `N a^2` `f32`; `transfer`, `footprint_scale`, `footprint_mean`,
//! `low_norm` as `N` `f32` each; `origins` as `2N` `f64`; `detail_rms` as a presence byte and
//! an `f64`; then the `H` and footprint dictionaries as `u64`-length-prefixed
//! [`Dictionary::to_bytes`] streams) and a trailing CRC-32 of everything before it. The
//! settings are not stored: they travel with the job ([`LastStep::from_bytes`] takes them).

use super::step::GridFrame;
use super::*;
use relief_sparse_core::sct::window_outside;
use relief_sparse_core::{FunctionAtomRegistry, Window};

const MAGIC: &[u8; 8] = b"RLFLAST1";
const VERSION: u16 = 1;

/// The last x4 step of an amplification ([`prepare_last_step`]).
#[derive(Debug, Clone)]
pub struct LastStep {
    /// The step's coarse input (the amplified output over 4 along each axis).
    pub input: Heightfield,
    /// The step's dictionary.
    pub dictionary: MultiResDictionary,
    /// The settings of the whole amplification (the step derives its seed from them).
    pub settings: AmplifySettings,
}

impl LastStep {
    /// The settings the step runs with.
    fn step_settings(&self) -> AmplifySettings {
        plan::step_settings(&self.settings, self.settings.steps - 1)
    }

    /// Size `(width, height)` of the amplified output.
    pub fn output_size(&self) -> (usize, usize) {
        (
            self.input.width() * STEP_FACTOR,
            self.input.height() * STEP_FACTOR,
        )
    }

    /// The whole step as a model (what [`amplify`] returns, without the georeference).
    pub fn sct(&self) -> Result<Sct> {
        self.sct_with(&relief_heightfield::NoProgress)
    }

    /// [`Self::sct`], asking `progress` whether to stop between bands of coded primitives.
    pub fn sct_with(&self, progress: &dyn Progress) -> Result<Sct> {
        self.dictionary
            .amplify_once_with(&self.input, &self.step_settings(), progress)
    }

    /// The window `win` (output pixels) of the amplified output, computed on a crop of the
    /// input only: equal bit for bit to the same window of [`Self::sct`] rasterised (module
    /// docs). Not available with [`AmplifySettings::exemplar_detail`] (its gain is a mean over
    /// the whole step). The result carries no georeference.
    pub fn render_window(&self, win: Window) -> Result<Heightfield> {
        let st = self.step_settings();
        st.check()?;
        if let Some(v) = window_outside(&win, self.output_size(), "output") {
            return Err(LearnError::param(
                "window",
                v,
                "must be non-empty and inside the output",
            ));
        }
        let (w, h) = (self.input.width(), self.input.height());
        let s = st.grid_step() as usize;
        let r = st.radius.floor().max(1.0) as usize;
        let align = s / gcd(s, r) * r;
        let halo = 4 * st.radius.ceil() as usize + 16;
        let f = STEP_FACTOR;
        let x0 = (win.x / f).saturating_sub(halo) / align * align;
        let y0 = (win.y / f).saturating_sub(halo) / align * align;
        let x1 = ((win.x + win.width).div_ceil(f) + halo).min(w);
        let y1 = ((win.y + win.height).div_ceil(f) + halo).min(h);
        let crop = self.input.crop(x0, y0, x1 - x0, y1 - y0)?;
        // Columns of the whole input's grid (one row of it: the whole grid may exceed the
        // primitive cap of one raster, which the crops do not).
        let nx = st.coarse_geometry().grid(w, 1)?.nx;
        let frame = GridFrame {
            col0: x0 / s,
            row0: y0 / s,
            nx,
        };
        let sct = self.dictionary.amplify_once_in(
            &crop,
            &st,
            Some(frame),
            &relief_heightfield::NoProgress,
        )?;
        let out = sct.rasterize(&RasterSettings {
            scale: 1.0,
            window: Some(Window {
                x: win.x - f * x0,
                y: win.y - f * y0,
                ..win
            }),
        })?;
        Ok(out.with_georef(None))
    }

    /// Serialises the step (module docs).
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        let d = &self.dictionary;
        let mut b = Vec::new();
        b.extend_from_slice(MAGIC);
        b.extend_from_slice(&VERSION.to_le_bytes());
        put_u32(&mut b, self.input.width())?;
        put_u32(&mut b, self.input.height())?;
        let (cx, cy) = self.input.cell_size();
        b.extend_from_slice(&cx.to_le_bytes());
        b.extend_from_slice(&cy.to_le_bytes());
        self.input
            .as_slice()
            .iter()
            .for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
        let n = d.len();
        let a = (d.low.ncols() as f64).sqrt().round() as usize;
        put_u32(&mut b, n)?;
        put_u32(&mut b, a)?;
        d.low
            .iter()
            .chain(&d.transfer)
            .chain(&d.footprint_scale)
            .chain(&d.footprint_mean)
            .chain(&d.low_norm)
            .for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
        d.origins
            .iter()
            .flatten()
            .for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
        b.push(u8::from(d.detail_rms.is_some()));
        b.extend_from_slice(&d.detail_rms.unwrap_or(0.0).to_le_bytes());
        for dict in [&d.high, &d.footprint] {
            let bytes = dict.to_bytes()?;
            b.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
            b.extend_from_slice(&bytes);
        }
        let crc = relief_sparse_core::format::crc32(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        Ok(b)
    }

    /// Reads a step written by [`Self::to_bytes`], with the settings of its amplification.
    /// Truncated, corrupt or inconsistent bytes are errors (sizes are checked against the
    /// bytes present before anything is allocated).
    pub fn from_bytes(bytes: &[u8], settings: &AmplifySettings) -> Result<Self> {
        settings.check()?;
        let bad = |reason: &'static str| LearnError::param("last step bytes", bytes.len(), reason);
        if bytes.len() < MAGIC.len() + 6 || &bytes[..MAGIC.len()] != MAGIC {
            return Err(bad("not a relief last-step stream (bad magic)"));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 4);
        let crc = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
        if relief_sparse_core::format::crc32(body) != crc {
            return Err(bad("checksum mismatch (corrupt or truncated)"));
        }
        let mut r = Cursor {
            b: body,
            pos: MAGIC.len(),
        };
        if r.u16()? != VERSION {
            return Err(bad("unknown version"));
        }
        let (w, h) = (r.u32()?, r.u32()?);
        let (cx, cy) = (r.f64()?, r.f64()?);
        let data = r.f32s(w.checked_mul(h).ok_or(bad("input size overflows"))?)?;
        let input = Heightfield::new(w, h, data, cx, cy)?;
        let (n, a) = (r.u32()?, r.u32()?);
        if a != settings.patch_size() || n == 0 {
            return Err(bad(
                "the dictionary does not match the settings' patch size",
            ));
        }
        let low = r.f32s(
            n.checked_mul(a * a)
                .ok_or(bad("dictionary size overflows"))?,
        )?;
        let low = Array2::from_shape_vec((n, a * a), low).map_err(|_| bad("dictionary shape"))?;
        let transfer = r.f32s(n)?;
        let footprint_scale = r.f32s(n)?;
        let footprint_mean = r.f32s(n)?;
        let low_norm = r.f32s(n)?;
        let origins = r
            .f64s(2 * n)?
            .chunks_exact(2)
            .map(|p| [p[0], p[1]])
            .collect();
        let has_rms = r.take(1)?[0] != 0;
        let rms = r.f64()?;
        let registry = FunctionAtomRegistry::new();
        let mut dicts = Vec::with_capacity(2);
        for _ in 0..2 {
            let len = usize::try_from(r.u64()?).map_err(|_| bad("dictionary length"))?;
            dicts.push(Arc::new(Dictionary::from_bytes(r.take(len)?, &registry)?));
        }
        if r.pos != body.len() {
            return Err(bad("trailing bytes"));
        }
        let footprint = dicts.pop().ok_or(bad("missing footprint dictionary"))?;
        let high = dicts.pop().ok_or(bad("missing H dictionary"))?;
        if high.len() != n
            || footprint.len() != n
            || high.patch_size() != STEP_FACTOR * a
            || footprint.patch_size() != a
        {
            return Err(bad("the H or footprint dictionary does not match L"));
        }
        Ok(Self {
            input,
            dictionary: MultiResDictionary {
                low,
                high,
                transfer,
                origins,
                footprint,
                footprint_scale,
                footprint_mean,
                low_norm,
                detail_rms: has_rms.then_some(rms),
            },
            settings: *settings,
        })
    }
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a.max(1) } else { gcd(b, a % b) }
}

fn put_u32(b: &mut Vec<u8>, v: usize) -> Result<()> {
    let v = u32::try_from(v).map_err(|_| LearnError::param("last step size", v, "exceeds u32"))?;
    b.extend_from_slice(&v.to_le_bytes());
    Ok(())
}

/// A bounds-checked reader.
struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.b.len())
            .ok_or(LearnError::param(
                "last step bytes",
                self.pos,
                "truncated (a declared size exceeds the bytes present)",
            ))?;
        let s = &self.b[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn u16(&mut self) -> Result<u16> {
        let s = self.take(2)?;
        Ok(u16::from_le_bytes([s[0], s[1]]))
    }

    fn u32(&mut self) -> Result<usize> {
        let s = self.take(4)?;
        Ok(u32::from_le_bytes([s[0], s[1], s[2], s[3]]) as usize)
    }

    fn u64(&mut self) -> Result<u64> {
        let mut a = [0u8; 8];
        a.copy_from_slice(self.take(8)?);
        Ok(u64::from_le_bytes(a))
    }

    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_bits(self.u64()?))
    }

    /// The bytes of `n` values of `width` bytes each.
    fn take_values(&mut self, n: usize, width: usize) -> Result<&'a [u8]> {
        let len = n.checked_mul(width).ok_or(LearnError::param(
            "last step bytes",
            n,
            "size overflows",
        ))?;
        self.take(len)
    }

    fn f32s(&mut self, n: usize) -> Result<Vec<f32>> {
        let s = self.take_values(n, 4)?;
        Ok(s.chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect())
    }

    fn f64s(&mut self, n: usize) -> Result<Vec<f64>> {
        let s = self.take_values(n, 8)?;
        Ok(s.chunks_exact(8)
            .map(|c| {
                let mut a = [0u8; 8];
                a.copy_from_slice(c);
                f64::from_le_bytes(a)
            })
            .collect())
    }
}
