//! Rendering a prepared refinement: windows, tiles and strips, the paper model's inverse DWT
//! of new levels and the spectral model's smooth part plus coloured detail.

use relief_heightfield::Window;

use super::*;

impl Refiner {
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
        Ok(self.render_region(Window::new(x, y, w, h)))
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
        // The spectral model is area-consistent: output block `[2^n i, 2^n (i + 1))` covers
        // input cell `i`, the extent is the input's.
        let shift = match self.settings.model {
            Model::Paper => 0.5 - 0.5 * s,
            Model::Spectral => 0.0,
        };
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
            .try_for_each(|(sy, strip)| {
                let y0 = sy * t;
                let th = strip.len() / ow;
                for tx in 0..tiles_x {
                    if progress.stopped() {
                        return Err(WaveletError::Stopped("the refinement"));
                    }
                    let x0 = tx * t;
                    let tw = t.min(ow - x0);
                    let tile = self.render_region(Window::new(x0, y0, tw, th));
                    for (r, row) in tile.chunks(tw).enumerate() {
                        strip[r * ow + x0..r * ow + x0 + tw].copy_from_slice(row);
                    }
                    progress.advance(1);
                }
                Ok(())
            })?;
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
                    if progress.stopped() {
                        return Err(WaveletError::Stopped("the refinement"));
                    }
                    let x0 = tx * t;
                    Ok(self.render_region(Window::new(x0, y0, t.min(ow - x0), sh)))
                })
                .collect::<Result<_>>()?;
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
    fn render_region(&self, win: Window) -> Vec<f32> {
        match &self.spectral {
            Some(plan) if self.settings.extra_levels > 0 => self.render_spectral(plan, win),
            _ => self.render_pass(win, true),
        }
    }

    /// The spectral model's window: the smooth part `cubic(q * (input - box-down(D)))` plus the
    /// synthetic detail `D` (the inverse DWT of the new levels over a zero approximation). `q`
    /// inverts `box-down(cubic(.))`, so the box down-sampling of the output is the input (up to
    /// rounding): the detail's own block means are taken out through the smooth part, as in a
    /// conditional simulation. Every value depends only on its position (fixed summation
    /// orders), so windows stay bit-identical to the full run.
    fn render_spectral(&self, plan: &SpectralPlan, win: Window) -> Vec<f32> {
        let (x, y, w, h) = win.as_tuple();
        let up = &plan.cubic;
        let f = up.factor;
        let (iw, ih) = (self.input.width, self.input.height);
        let correct = self.settings.consistency;
        // Coarse cells the cubic reads, then the cells the inverse filter reads around them.
        let (gx0, gx1) = up.coarse_range(x, x + w, iw);
        let (gy0, gy1) = up.coarse_range(y, y + h, ih);
        let ql = QL as isize;
        let span = |g0: usize, g1: usize, n: usize| {
            let (mut lo, mut hi) = (usize::MAX, 0usize);
            for i in g0 as isize - ql..g1 as isize + ql {
                let r = reflect(i, n);
                lo = lo.min(r);
                hi = hi.max(r + 1);
            }
            (lo, hi)
        };
        let (rx0, rx1) = span(gx0, gx1, iw);
        let (ry0, ry1) = span(gy0, gy1, ih);
        // The detail over the window, or over every block the correction reads (which holds
        // the window), unless those blocks' means are cached.
        let cached = correct && !self.block_means.is_empty();
        let (dx0, dx1, dy0, dy1) = if correct && !cached {
            (
                (rx0 * f).min(x),
                (rx1 * f).max(x + w),
                (ry0 * f).min(y),
                (ry1 * f).max(y + h),
            )
        } else {
            (x, x + w, y, y + h)
        };
        let dw = dx1 - dx0;
        let detail = self.render_pass(Window::new(dx0, dy0, dw, dy1 - dy0), false);
        // Coarse residual s = input - box-down(D) over [rx0, rx1) x [ry0, ry1).
        let sw = rx1 - rx0;
        let mut s = vec![0.0f32; sw * (ry1 - ry0)];
        let inv = 1.0 / (f * f) as f64;
        for (j, row) in s.chunks_mut(sw).enumerate() {
            let cy = ry0 + j;
            for (i, v) in row.iter_mut().enumerate() {
                let cx = rx0 + i;
                let mut mean = 0.0f64;
                if cached {
                    mean = self.block_mean(cx, cy, f);
                } else if correct {
                    for r in 0..f {
                        let o = (cy * f + r - dy0) * dw + cx * f - dx0;
                        mean += detail[o..o + f].iter().map(|&z| z as f64).sum::<f64>();
                    }
                    mean *= inv;
                }
                *v = (self.input.data[cy * iw + cx] as f64 - mean) as f32;
            }
        }
        // g = q * s (separable, symmetric reflection) over [gx0, gx1) x [gy0, gy1).
        let q = &up.inverse;
        let gw = gx1 - gx0;
        let mut tq = vec![0.0f32; gw * (ry1 - ry0)];
        let qidx: Vec<usize> = (gx0..gx1)
            .flat_map(|c| {
                (0..q.len()).map(move |k| reflect(c as isize + k as isize - ql, iw) - rx0)
            })
            .collect();
        for (row, srow) in tq.chunks_mut(gw).zip(s.chunks(sw)) {
            for (v, idx) in row.iter_mut().zip(qidx.chunks(q.len())) {
                let mut acc = 0.0f32;
                for (&qk, &i) in q.iter().zip(idx) {
                    acc += qk * srow[i];
                }
                *v = acc;
            }
        }
        let mut g = vec![0.0f32; gw * (gy1 - gy0)];
        for (j, row) in g.chunks_mut(gw).enumerate() {
            let c = (gy0 + j) as isize;
            for (k, &qk) in q.iter().enumerate() {
                let src = reflect(c + k as isize - ql, ih) - ry0;
                row.iter_mut()
                    .zip(&tq[src * gw..(src + 1) * gw])
                    .for_each(|(a, b)| *a += qk * b);
            }
        }
        // Cubic up-sampling of g to the window, rows then columns, plus the detail.
        // Taps of every window column, computed once for all rows.
        let taps: Vec<([usize; 4], [f32; 4])> = (x..x + w)
            .map(|o| {
                let (off, wt) = up.phases[o % f];
                let base = (o / f) as isize + off;
                (
                    [0, 1, 2, 3].map(|t| reflect(base + t as isize, iw) - gx0),
                    wt,
                )
            })
            .collect();
        let mut th = vec![0.0f32; w * (gy1 - gy0)];
        for (row, grow) in th.chunks_mut(w).zip(g.chunks(gw)) {
            for (v, (idx, wt)) in row.iter_mut().zip(&taps) {
                let mut acc = 0.0f32;
                for (&i, &wv) in idx.iter().zip(wt) {
                    acc += wv * grow[i];
                }
                *v = acc;
            }
        }
        let mut out = vec![0.0f32; w * h];
        for (r, row) in out.chunks_mut(w).enumerate() {
            let o = y + r;
            let (off, wt) = up.phases[o % f];
            let base = (o / f) as isize + off;
            for (t, &wv) in wt.iter().enumerate() {
                let src = reflect(base + t as isize, ih) - gy0;
                row.iter_mut()
                    .zip(&th[src * w..(src + 1) * w])
                    .for_each(|(a, b)| *a += wv * b);
            }
            let d = &detail[(o - dy0) * dw + x - dx0..(o - dy0) * dw + x - dx0 + w];
            row.iter_mut().zip(d).for_each(|(a, b)| *a += b);
        }
        out
    }

    /// The mean of the spectral model's detail over the `f x f` block of input cell
    /// `(cx, cy)`, summed in the order the uncached correction sums it (rows, then each row's
    /// cells, in `f64`), so that the result is the same bit for bit. Computed once, for the
    /// aligned group of blocks about a tile wide that holds it ([`block_group`]; one pass per
    /// block would repeat the per-window set-up thousands of times).
    fn block_mean(&self, cx: usize, cy: usize, f: usize) -> f64 {
        let (iw, ih) = (self.input.width, self.input.height);
        let g = block_group(self.settings.tile, f);
        let (gx0, gy0) = (cx - cx % g, cy - cy % g);
        let group = (cy / g) * iw.div_ceil(g) + cx / g;
        let (gw, gh) = (g.min(iw - gx0), g.min(ih - gy0));
        // One thread computes a group; the others needing it wait for its means.
        let means = self.block_means[group].get_or_init(|| {
            let dw = gw * f;
            let d = self.render_pass(Window::new(gx0 * f, gy0 * f, dw, gh * f), false);
            let inv = 1.0 / (f * f) as f64;
            let mut means = Vec::with_capacity(gw * gh);
            for j in 0..gh {
                for i in 0..gw {
                    let mut mean = 0.0f64;
                    for r in 0..f {
                        let o = (j * f + r) * dw + i * f;
                        mean += d[o..o + f].iter().map(|&z| z as f64).sum::<f64>();
                    }
                    means.push(mean * inv);
                }
            }
            means
        });
        means[(cy - gy0) * gw + cx - gx0]
    }

    /// The inverse DWT of the new levels over the approximation `input` (`with_input`) or over
    /// a zero approximation (the spectral model's detail alone).
    fn render_pass(&self, win: Window, with_input: bool) -> Vec<f32> {
        let (x, y, w, h) = win.as_tuple();
        #[cfg(test)]
        self.rendered_cells
            .fetch_add((w * h) as u64, std::sync::atomic::Ordering::Relaxed);
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
        let wavelet = self.settings.basis();
        let margin = wavelet.synthesis_margin();
        let (iw, ih) = (self.input.width, self.input.height);
        // Plans from the finest level down to the input.
        let mut plans = Vec::with_capacity(n as usize);
        let (mut xs, mut ys) = (x..x + w, y..y + h);
        for t in (1..=n).rev() {
            let px = AxisPlan::new(iw << t, xs, margin);
            let py = AxisPlan::new(ih << t, ys, margin);
            (xs, ys) = (px.even.clone(), py.even.clone());
            plans.push((px, py));
        }
        plans.reverse();
        // Level 0: the input itself is the approximation at level J (zero for the spectral
        // model's detail).
        let mut cur = Vec::with_capacity(xs.len() * ys.len());
        for r in ys.clone() {
            if with_input {
                cur.extend_from_slice(&self.input.data[r * iw + xs.start..r * iw + xs.end]);
            } else {
                cur.resize(cur.len() + xs.len(), 0.0);
            }
        }
        let (lx0, ly0, lw, lh) = (xs.start, ys.start, xs.len(), ys.len());
        let scheme = wavelet.scheme();
        let sigmas = self.sigma_maps(lx0, ly0, lw, lh);
        for (t, (px, py)) in plans.iter().enumerate() {
            let sig = &sigmas[t];
            let t = t as u32;
            let level = self.global.top_level + t as i64;
            let make_band = |band: Band, xs: &Range<usize>, ys: &Range<usize>| -> Vec<f32> {
                let (cw, ch) = (xs.len(), ys.len());
                let s = &sig[band.index()];
                if self.spectral.is_some() {
                    let region = BandRegion {
                        xs: xs.clone(),
                        ys: ys.start..ys.start + ch,
                        dims: (iw << t, ih << t),
                    };
                    let mut out = self.texture(t, band, &region);
                    let sigma = s.first().copied().unwrap_or(0.0);
                    match &self.amplitude {
                        None => out.iter_mut().for_each(|v| *v *= sigma),
                        Some(maps) => {
                            let map = &maps[(t as usize).min(maps.len() - 1)][band.index()];
                            // Coefficient k of new level t lies at input coordinate
                            // (k + 1/2) / 2^t - 1/2; the amplitude grid at half the input
                            // resolution. Bilinear, so the amplitude has no steps.
                            let inv = 1.0 / (1u64 << t) as f32;
                            let coord = |k: usize| ((k as f32 + 0.5) * inv - 0.5) * 0.5 - 0.25;
                            let xw: Vec<(usize, usize, f32)> = (0..cw)
                                .map(|k| lerp_index(coord(xs.start + k), map.width))
                                .collect();
                            // The two x-interpolated map rows `a` and `b` depend only on the
                            // map rows (y0, y1), shared by consecutive coefficient rows: kept
                            // until they change.
                            let (mut av, mut bv) = (vec![0.0f32; cw], vec![0.0f32; cw]);
                            let mut rows_of = None;
                            for (r, row) in out.chunks_mut(cw.max(1)).enumerate().take(ch) {
                                let (y0, y1, fy) = lerp_index(coord(ys.start + r), map.height);
                                if rows_of != Some((y0, y1)) {
                                    rows_of = Some((y0, y1));
                                    let (r0, r1) = (
                                        &map.data[y0 * map.width..(y0 + 1) * map.width],
                                        &map.data[y1 * map.width..(y1 + 1) * map.width],
                                    );
                                    for ((a, b), &(x0, x1, fx)) in
                                        av.iter_mut().zip(bv.iter_mut()).zip(&xw)
                                    {
                                        *a = r0[x0] + fx * (r0[x1] - r0[x0]);
                                        *b = r1[x0] + fx * (r1[x1] - r1[x0]);
                                    }
                                }
                                for ((v, &a), &b) in row.iter_mut().zip(&av).zip(&bv) {
                                    *v *= sigma * (a + fy * (b - a));
                                }
                            }
                        }
                    }
                    return out;
                }
                let mut out = vec![0.0f32; cw * ch];
                for (r, row) in out.chunks_mut(cw.max(1)).enumerate().take(ch) {
                    let gy = ys.start + r;
                    let key = row_key(self.settings.seed, band.index(), level, gy);
                    fill_normals(key, xs.start, row);
                    let sy = ((gy >> t) - ly0) * lw;
                    for (k, v) in row.iter_mut().enumerate() {
                        let sx = ((xs.start + k) >> t) - lx0;
                        *v *= s[sy + sx];
                    }
                }
                out
            };
            let hb = make_band(Band::H, &px.even, &py.odd);
            let vb = make_band(Band::V, &px.odd, &py.even);
            let db = make_band(Band::D, &px.odd, &py.odd);
            cur = inverse_level_window(scheme, Boundary::Symmetric, px, py, cur, hb, vb, db, false);
        }
        cur
    }
}

/// Blocks per side of a group whose detail means are computed together: about one tile wide.
pub(super) fn block_group(tile: usize, f: usize) -> usize {
    (tile / f.max(1)).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 44 item 5: the spectral model's consistency correction reads the detail's block
    /// means `QL` input cells around a window; rendering the detail over all of them for
    /// every tile made a x256 streamed refinement 81 times the work of its output (18 min
    /// for a 64^2 input). With the block means cached, streaming renders about twice the
    /// output (the output, and the detail once per block), and the values are unchanged.
    #[test]
    fn streaming_a_large_factor_renders_each_block_once() {
        let hf = Heightfield::from_fn(16, 16, 30.0, 30.0, |x, y| {
            ((x as f32 * 0.7).sin() + (y as f32 * 0.4).cos()) * 40.0 + x as f32
        });
        let settings = RefineSettings {
            extra_levels: 6,
            ..RefineSettings::default()
        };
        let r = Refiner::new(&hf, &settings).unwrap();
        let (ow, oh) = r.output_size();
        let mut out = vec![0.0f32; ow * oh];
        r.render_strips::<WaveletError>(64, &relief_heightfield::NoProgress, |y0, rows| {
            out[y0 * ow..y0 * ow + rows.len()].copy_from_slice(rows);
            Ok(())
        })
        .unwrap();
        let work = r.rendered_cells.load(std::sync::atomic::Ordering::Relaxed) as f64;
        let cells = (ow * oh) as f64;
        assert!(work <= 2.0 * cells, "{work} cells rendered for {cells}");
        // The same values as a window of a fresh refiner (no mean cached before).
        let fresh = Refiner::new(&hf, &settings).unwrap();
        let win = fresh.render_window_values(300, 500, 200, 100).unwrap();
        for (r, row) in win.chunks(200).enumerate() {
            assert_eq!(row, &out[(500 + r) * ow + 300..(500 + r) * ow + 500]);
        }
    }
}
