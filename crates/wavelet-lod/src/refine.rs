//! New levels of detail: GSA (section 5.1) and LSA (section 5.2), generated on demand.

use rayon::prelude::*;
use relief_heightfield::{Heightfield, MAX_CELLS, NoProgress, Progress};
use serde::{Deserialize, Serialize};

use crate::analysis::{
    FitSettings, GlobalAnalysis, LocalMaps, LocalStats, check_window, decompose, global_from,
    maps_from,
};
use crate::dwt::{AxisPlan, Band, Grid, inverse_level_window};
use crate::error::{Result, WaveletError};
use crate::lift::Boundary;
use crate::rng::{fill_normals, row_key};
use crate::wavelet::Wavelet;

/// Which statistics drive the synthesis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Global scope approach (section 5.1): one `(gamma, a)` per band.
    Gsa,
    /// Local scope approach (section 5.2): one `(gamma, a)` per band and input location, from a
    /// `window x window` neighbourhood ([`RefineSettings::window`]).
    #[default]
    Lsa,
}

/// Settings of [`Refiner`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RefineSettings {
    /// Basis (the paper recommends the linear spline, [`Wavelet::Cdf53`]).
    pub wavelet: Wavelet,
    /// GSA or LSA.
    pub method: Method,
    /// LSA window side (odd; the paper tests 1, 3, 5, 7 and recommends 3).
    pub window: usize,
    /// Number of synthesised levels: the output is `2^extra_levels` times larger per side.
    pub extra_levels: u32,
    /// Seed of the coefficient hash.
    pub seed: u64,
    /// Fit settings.
    pub fit: FitSettings,
    /// Tile side (output cells, 16..=65536) of [`Refiner::render`]; only affects speed and
    /// memory, never the values.
    pub tile: usize,
}

impl Default for RefineSettings {
    fn default() -> Self {
        Self {
            wavelet: Wavelet::Cdf53,
            method: Method::Lsa,
            window: 3,
            extra_levels: 2,
            seed: 0,
            fit: FitSettings::default(),
            tile: 512,
        }
    }
}

impl RefineSettings {
    /// Checks the settings.
    pub fn validate(&self) -> Result<()> {
        self.fit.validate()?;
        if self.method == Method::Lsa {
            check_window(self.window)?;
        }
        if self.extra_levels > 12 {
            return Err(WaveletError::param(
                "extra_levels",
                self.extra_levels,
                "must be <= 12",
            ));
        }
        if !(16..=65_536).contains(&self.tile) {
            return Err(WaveletError::param(
                "tile",
                self.tile,
                "must be in 16..=65536",
            ));
        }
        Ok(())
    }
}

/// A prepared refinement: the input, its analysis and the settings. Rendering any window costs
/// memory proportional to the window (plus the analysis, proportional to the input), never to
/// the whole refined terrain.
#[derive(Debug)]
pub struct Refiner {
    input: Grid,
    cell: (f64, f64),
    georef: Option<relief_heightfield::GeoRef>,
    settings: RefineSettings,
    global: GlobalAnalysis,
    local: Option<LocalStats>,
}

impl Refiner {
    /// Analyses a void-free terrain (forward DWT, equations (2)-(4)) and prepares the synthesis.
    pub fn new(hf: &Heightfield, settings: &RefineSettings) -> Result<Self> {
        settings.validate()?;
        let n = settings.extra_levels;
        let (ow, oh) = (
            hf.width().checked_shl(n).unwrap_or(usize::MAX),
            hf.height().checked_shl(n).unwrap_or(usize::MAX),
        );
        if ow.checked_mul(oh).is_none_or(|c| c > MAX_CELLS) || ow >> n != hf.width() {
            return Err(WaveletError::param(
                "extra_levels",
                n,
                "the refined grid would exceed the 2^31-cell limit",
            ));
        }
        let (top, levels, _) = settings.fit.plan(hf.width(), hf.height())?;
        let dec = decompose(hf, settings.wavelet, levels)?;
        let global = global_from(&dec, top, &settings.fit)?;
        let local = match settings.method {
            Method::Gsa => None,
            Method::Lsa => Some(LocalStats::new(&dec, top, settings.window, &settings.fit)?),
        };
        Ok(Self {
            input: Grid::from_heightfield(hf),
            cell: hf.cell_size(),
            georef: hf.georef().cloned(),
            settings: settings.clone(),
            global,
            local,
        })
    }

    /// The global statistics (always computed, also for LSA).
    pub fn analysis(&self) -> &GlobalAnalysis {
        &self.global
    }

    /// The settings.
    pub fn settings(&self) -> &RefineSettings {
        &self.settings
    }

    /// The local statistics as maps at input resolution (`None` for GSA).
    pub fn local_maps(&self) -> Option<LocalMaps> {
        self.local
            .as_ref()
            .map(|l| maps_from(l, self.input.width, self.input.height))
    }

    /// Size `(width, height)` of the refined terrain.
    pub fn output_size(&self) -> (usize, usize) {
        let n = self.settings.extra_levels;
        (self.input.width << n, self.input.height << n)
    }

    /// Standard deviations of the new coefficients (equation (5)) for every new level `t`
    /// (0 = first) at the input locations `[x0, x0 + w) x [y0, y0 + h)`: per level, three grids
    /// (H, V, D).
    fn sigma_maps(&self, x0: usize, y0: usize, w: usize, h: usize) -> Vec<[Vec<f32>; 3]> {
        let n = self.settings.extra_levels;
        let js: Vec<f64> = (0..n)
            .map(|t| (self.global.top_level + t as i64) as f64)
            .collect();
        match &self.local {
            None => js
                .iter()
                .map(|&j| {
                    Band::ALL.map(|b| {
                        let f = self.global.fit(b);
                        vec![(0.5 * (f.a - j * f.gamma)).exp2() as f32; w * h]
                    })
                })
                .collect(),
            Some(local) => {
                let fits = local.fit_region(x0, y0, w, h);
                js.iter()
                    .map(|&j| {
                        let j = j as f32;
                        [0, 1, 2].map(|b| {
                            let (g, a) = &fits[b];
                            g.iter()
                                .zip(a)
                                .map(|(g, a)| (0.5 * (a - j * g)).exp2())
                                .collect()
                        })
                    })
                    .collect()
            }
        }
    }

    /// Renders the window `[x, x + w) x [y, y + h)` of the refined terrain (output cells) into a
    /// row-major buffer. The values are bit-identical to the same window of [`Refiner::render`].
    pub fn render_window_values(&self, x: usize, y: usize, w: usize, h: usize) -> Result<Vec<f32>> {
        let (ow, oh) = self.output_size();
        if w == 0
            || h == 0
            || x.checked_add(w).is_none_or(|e| e > ow)
            || y.checked_add(h).is_none_or(|e| e > oh)
        {
            return Err(WaveletError::param(
                "window",
                format!("x={x} y={y} w={w} h={h}"),
                "must be non-empty and inside the refined grid",
            ));
        }
        Ok(self.render_region(x, y, w, h))
    }

    /// [`Refiner::render_window_values`] as a heightfield (cell size divided by
    /// `2^extra_levels`; the georeference follows, see the crate docs on alignment).
    pub fn render_window(&self, x: usize, y: usize, w: usize, h: usize) -> Result<Heightfield> {
        let data = self.render_window_values(x, y, w, h)?;
        self.wrap(x, y, w, h, data)
    }

    fn wrap(&self, x: usize, y: usize, w: usize, h: usize, data: Vec<f32>) -> Result<Heightfield> {
        let s = 1.0 / (1u64 << self.settings.extra_levels) as f64;
        let hf = Heightfield::new(w, h, data, self.cell.0 * s, self.cell.1 * s)?;
        // Refined sample k is centred on input pixel coordinate k * s (vertex-aligned lattice:
        // sample 2^n i lies on input sample i), so its corner is at k * s + (1 - s) / 2.
        let shift = 0.5 - 0.5 * s;
        Ok(hf.with_georef(
            self.georef
                .as_ref()
                .map(|g| g.window(x as f64 * s + shift, y as f64 * s + shift, s, s)),
        ))
    }

    /// Renders the whole refined terrain, tile by tile in parallel.
    pub fn render(&self, progress: &dyn Progress) -> Result<Heightfield> {
        let (ow, oh) = self.output_size();
        let t = self.settings.tile;
        let strips = oh.div_ceil(t);
        let tiles_x = ow.div_ceil(t);
        progress.begin("wavelet-lod: synthesise tiles", (strips * tiles_x) as u64);
        let mut data = vec![0.0f32; ow * oh];
        data.par_chunks_mut(ow * t)
            .enumerate()
            .for_each(|(sy, strip)| {
                let y0 = sy * t;
                let th = strip.len() / ow;
                for tx in 0..tiles_x {
                    let x0 = tx * t;
                    let tw = t.min(ow - x0);
                    let tile = self.render_region(x0, y0, tw, th);
                    for (r, row) in tile.chunks(tw).enumerate() {
                        strip[r * ow + x0..r * ow + x0 + tw].copy_from_slice(row);
                    }
                    progress.advance(1);
                }
            });
        self.wrap(0, 0, ow, oh, data)
    }

    /// Renders the whole refined terrain as horizontal strips of `strip` rows (the last one may
    /// be shorter), top to bottom, and hands each to `sink` as `(first row, row-major values of
    /// full width)`, in order. The tiles of a strip ([`RefineSettings::tile`] wide) are rendered
    /// in parallel. Memory is proportional to `strip * width` (plus the analysis), never to the
    /// whole refined terrain, so a terrain larger than memory can be streamed to a writer; the
    /// values are bit-identical to [`Refiner::render`]. The first error of `sink` stops the
    /// rendering and is returned.
    pub fn render_strips<E: From<WaveletError>>(
        &self,
        strip: usize,
        progress: &dyn Progress,
        mut sink: impl FnMut(usize, &[f32]) -> std::result::Result<(), E>,
    ) -> std::result::Result<(), E> {
        let (ow, oh) = self.output_size();
        if strip == 0 || strip.checked_mul(ow).is_none_or(|c| c > MAX_CELLS) {
            return Err(WaveletError::param(
                "strip",
                strip,
                "must be >= 1 and strip * width must stay within the cell limit",
            )
            .into());
        }
        let t = self.settings.tile;
        let tiles_x = ow.div_ceil(t);
        let strips = oh.div_ceil(strip);
        progress.begin("wavelet-lod: synthesise strips", strips as u64);
        let mut buf = vec![0.0f32; strip.min(oh) * ow];
        for s in 0..strips {
            let y0 = s * strip;
            let sh = strip.min(oh - y0);
            let tiles: Vec<Vec<f32>> = (0..tiles_x)
                .into_par_iter()
                .map(|tx| {
                    let x0 = tx * t;
                    self.render_region(x0, y0, t.min(ow - x0), sh)
                })
                .collect();
            // Row by row in parallel (a serial copy would leave the other threads idle).
            buf[..sh * ow]
                .par_chunks_mut(ow)
                .enumerate()
                .for_each(|(r, row)| {
                    for (tx, tile) in tiles.iter().enumerate() {
                        let x0 = tx * t;
                        let tw = t.min(ow - x0);
                        row[x0..x0 + tw].copy_from_slice(&tile[r * tw..(r + 1) * tw]);
                    }
                });
            sink(y0, &buf[..sh * ow])?;
            progress.advance(1);
        }
        Ok(())
    }

    /// The window at the finest level, computed from the input through every new level with
    /// only the lanes each inverse step needs (section 5, "generated when needed").
    fn render_region(&self, x: usize, y: usize, w: usize, h: usize) -> Vec<f32> {
        let n = self.settings.extra_levels;
        if n == 0 {
            let mut out = Vec::with_capacity(w * h);
            for r in y..y + h {
                out.extend_from_slice(
                    &self.input.data[r * self.input.width + x..r * self.input.width + x + w],
                );
            }
            return out;
        }
        let wavelet = self.settings.wavelet;
        let margin = wavelet.synthesis_margin();
        let (iw, ih) = (self.input.width, self.input.height);
        // Plans from the finest level down to the input.
        let mut plans = Vec::with_capacity(n as usize);
        let (mut ax, mut bx, mut ay, mut by) = (x, x + w, y, y + h);
        for t in (1..=n).rev() {
            let px = AxisPlan::new(iw << t, ax, bx, margin);
            let py = AxisPlan::new(ih << t, ay, by, margin);
            (ax, bx, ay, by) = (px.e0, px.e1, py.e0, py.e1);
            plans.push((px, py));
        }
        plans.reverse();
        // Level 0: the input itself is the approximation at level J.
        let mut cur = Vec::with_capacity((bx - ax) * (by - ay));
        for r in ay..by {
            cur.extend_from_slice(&self.input.data[r * iw + ax..r * iw + bx]);
        }
        let (lx0, ly0, lw, lh) = (ax, ay, bx - ax, by - ay);
        let scheme = wavelet.scheme();
        let sigmas = self.sigma_maps(lx0, ly0, lw, lh);
        for (t, (px, py)) in plans.iter().enumerate() {
            let sig = &sigmas[t];
            let t = t as u32;
            let level = self.global.top_level + t as i64;
            let make_band = |band: Band, xs: (usize, usize), ys: (usize, usize)| -> Vec<f32> {
                let (cw, ch) = (xs.1 - xs.0, ys.1.max(ys.0) - ys.0);
                let mut out = vec![0.0f32; cw * ch];
                let s = &sig[band.index()];
                for (r, row) in out.chunks_mut(cw.max(1)).enumerate().take(ch) {
                    let gy = ys.0 + r;
                    let key = row_key(self.settings.seed, band.index(), level, gy);
                    fill_normals(key, xs.0, row);
                    let sy = ((gy >> t) - ly0) * lw;
                    for (k, v) in row.iter_mut().enumerate() {
                        let sx = ((xs.0 + k) >> t) - lx0;
                        *v *= s[sy + sx];
                    }
                }
                out
            };
            let hb = make_band(Band::H, (px.e0, px.e1), (py.o0, py.o1));
            let vb = make_band(Band::V, (px.o0, px.o1), (py.e0, py.e1));
            let db = make_band(Band::D, (px.o0, px.o1), (py.o0, py.o1));
            cur = inverse_level_window(scheme, Boundary::Symmetric, px, py, cur, hb, vb, db, false);
        }
        cur
    }
}

/// Refines a void-free terrain by `settings.extra_levels` levels (whole grid).
pub fn refine(hf: &Heightfield, settings: &RefineSettings) -> Result<Heightfield> {
    Refiner::new(hf, settings)?.render(&NoProgress)
}

/// Refines only the window `[x, x + w) x [y, y + h)` of the refined grid (output cells); equal
/// bit for bit to the same window of [`refine`].
pub fn refine_window(
    hf: &Heightfield,
    settings: &RefineSettings,
    x: usize,
    y: usize,
    w: usize,
    h: usize,
) -> Result<Heightfield> {
    Refiner::new(hf, settings)?.render_window(x, y, w, h)
}
