//! Erosion effects of paper section 4: sea caves along the shore, sea cliffs, wind and rain.

use super::*;
use relief_heightfield::param::in_range;

impl SceneBuilder {
    /// Sea erosion (section 4.1, figure 5), plus sea caves dug inland from the most eroded
    /// samples near sea level.
    pub fn sea_erosion(&mut self, s: &SeaErosion, region: &Region) -> Result<EffectReport> {
        self.check_sea_erosion(s)?;
        let dist = self.distance_to_sea(s.sea_level, s.border_connected);
        let frame = self.frame;
        let stress = |me: &Self, p: V3| {
            // A flat floor under water is not attacked by waves: only ground reaching up to the
            // sea level around the sample (shores, cliffs, skerries) is.
            let (u, v) = frame.to_grid(p);
            let (j, i) = (u.floor().max(0.0) as usize, v.floor().max(0.0) as usize);
            let (j1, i1) = ((j + 1).min(frame.width - 1), (i + 1).min(frame.height - 1));
            let top = [
                me.dem_at(j, i),
                me.dem_at(j1, i),
                me.dem_at(j, i1),
                me.dem_at(j1, i1),
            ]
            .into_iter()
            .fold(f32::NEG_INFINITY, f32::max);
            if top <= s.sea_level {
                return 0.0;
            }
            let hgt = p[2] - s.sea_level;
            let t = if hgt >= s.peak {
                (hgt - s.peak) / (s.height - s.peak).max(1e-3)
            } else {
                (s.peak - hgt) / (s.peak + s.depth).max(1e-3)
            };
            let band = if t < 1.0 { (1.0 - t * t).powi(2) } else { 0.0 };
            let acc = frame.cell(p).map_or(0.0, |(j, i)| {
                (1.0 - dist[i * frame.width + j] / s.reach).max(0.0)
            });
            band * acc
        };
        let band = Some((s.sea_level - s.depth, s.sea_level + s.height));
        let (mut report, mut placed) = self.weather(&s.weathering, region, band, false, stress)?;
        let inland = |p: V3| inland(&frame, &dist, p);
        let r = s.weathering.radius;
        let w = &s.weathering;
        let mut all_placed = placed.clone();
        for pass in 1..s.iterations {
            // The current surface: the scene with every carving so far.
            let current = self.clone().build(true)?;
            let decay = 0.8f32.powi(pass as i32);
            let me = &*self;
            let next: Vec<Option<(V3, f32)>> = placed
                .par_iter()
                .enumerate()
                .map(|(k, &(p, _))| {
                    let dir = inland(p)?;
                    let h = |c: u64| unit(hash(w.seed, k as u64, pass as u64, 40 + c)) - 0.5;
                    let start = add(p, [0.0, 0.0, 0.4 * r * h(0)]);
                    // The nearest crossing of the current surface along inland, inland and
                    // down, down, and inland and up (the sample may sit in air left by the
                    // previous pass or still in rock).
                    let jit = [0.5 * h(1), 0.5 * h(2), 0.0];
                    let dirs = [
                        normalize(add(dir, jit)),
                        normalize(add(add(dir, jit), [0.0, 0.0, -0.7])),
                        normalize(add(jit, [0.0, 0.0, -1.0])),
                        normalize(add(add(dir, jit), [0.0, 0.0, 0.7])),
                    ];
                    let s_in = current.inside(start);
                    let mut hit = None;
                    'dirs: for d in dirs {
                        let mut a = 0.0f32;
                        for m in 1..=12 {
                            let t = m as f32 * 0.25 * r;
                            if current.inside(add(start, mul(d, t))) != s_in {
                                hit = Some((d, a, t));
                                break 'dirs;
                            }
                            a = t;
                        }
                    }
                    let (d, mut a, mut b) = hit?;
                    for _ in 0..12 {
                        let m = 0.5 * (a + b);
                        if current.inside(add(start, mul(d, m))) == s_in {
                            a = m;
                        } else {
                            b = m;
                        }
                    }
                    let q = add(start, mul(d, b));
                    let wgt = region.weight(&frame, q);
                    let sigma = (stress(me, q) * wgt * decay).clamp(0.0, 1.0);
                    let e = erosion_intensity(me.geology.resistance(q), sigma, w.beta);
                    (e >= w.threshold && e > 0.0).then_some((q, e))
                })
                .collect();
            let pts: Vec<(V3, f32)> = next.into_iter().flatten().collect();
            let keep = poisson_filter(
                &pts.iter().map(|x| x.0).collect::<Vec<_>>(),
                w.spacing,
                |_| true,
            );
            report.candidates += pts.len();
            placed = keep.into_iter().map(|k| pts[k]).collect();
            for &(q, e) in &placed {
                let id = self.tree.sphere(q, r, -w.energy * e)?;
                self.negatives.push(id);
                self.carved.push((q, r, false));
                report.primitives += 1;
            }
            all_placed.extend_from_slice(&placed);
            if placed.is_empty() {
                break;
            }
        }
        self.sea_caves(s, &all_placed, inland, &mut report)?;
        Ok(report)
    }

    /// Checks the settings of [`SceneBuilder::sea_erosion`].
    fn check_sea_erosion(&self, s: &SeaErosion) -> Result<()> {
        self.check_lens(&named_fields!(s; depth, height, reach, cave_length))?;
        if !s.sea_level.is_finite() {
            return Err(Error::param("sea_level", s.sea_level, "must be finite"));
        }
        if !(-s.depth..=s.height).contains(&s.peak) {
            return Err(Error::param("peak", s.peak, "must be in [-depth, height]"));
        }
        if s.cave_length / (0.5 * s.weathering.radius) > 4096.0 {
            return Err(Error::param(
                "cave_length",
                s.cave_length,
                "must be at most 2048 weathering radii",
            ));
        }
        Ok(in_range(
            "iterations",
            s.iterations,
            1..=8,
            "must be in 1..=8",
        )?)
    }

    /// Sea caves: chains of carving spheres going inland (up the distance-to-sea gradient,
    /// `inland`), from the most eroded samples just above sea level of `placed`, at the
    /// softest level of the lower sea band, only where the ground 1.5 radii inland rises 1.6
    /// radii over that level, under a roof, ending in resistant rock or under too thin a roof. Sites are the mouths, axes the directions out of them (to the sea).
    fn sea_caves(
        &mut self,
        s: &SeaErosion,
        placed: &[(V3, f32)],
        inland: impl Fn(V3) -> Option<V3>,
        report: &mut EffectReport,
    ) -> Result<()> {
        let r = s.weathering.radius;
        let w = &s.weathering;
        let mut best: Vec<(f32, usize)> = placed
            .iter()
            .enumerate()
            .filter(|(_, (p, _))| p[2] >= s.sea_level && p[2] <= s.sea_level + 0.5 * s.height)
            .map(|(k, (_, e))| (*e, k))
            .collect();
        best.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut mouths: Vec<V3> = Vec::new();
        for &(e, k) in &best {
            if mouths.len() >= s.caves {
                break;
            }
            let p = placed[k].0;
            if mouths.iter().any(|m| norm(sub(*m, p)) < s.cave_length) {
                continue;
            }
            let Some(inward) = inland(p) else {
                continue;
            };
            // Sea caves follow joints: the region's two orthogonal joint sets (direction
            // hashed from the seed), the one nearest the way inland (within 45 degrees).
            let mut dir = joint_towards(w.seed, inward);
            // The cave opens at the waterline in the softest rock of the lower sea band.
            let (lo, hi) = (s.sea_level, s.sea_level + 0.5 * s.height);
            let level = (0..=8)
                .map(|q| lo + (hi - lo) * q as f32 / 8.0)
                .min_by(|a, b| {
                    let rho = |z: f32| self.geology.resistance([p[0], p[1], z]);
                    rho(*a).total_cmp(&rho(*b))
                })
                .unwrap_or(p[2]);
            let mouth = [p[0], p[1], level];
            // Only into rock that rises over a roof: a shore lower than that gets notches,
            // no cave (a cave there would be a trench open to the sky).
            let behind = add(mouth, mul(dir, 1.5 * r));
            if self.ground(behind[0], behind[1]) - level < 1.6 * r {
                continue;
            }
            mouths.push(p);
            report.features += 1;
            report.sites.push(mouth);
            report.axes.push([-inward[0], -inward[1], 0.0]);
            // A cleft along the joint: the heading turns by up to +-5 degrees a step and the
            // floor drifts to the softest rock nearby, within the sea-erosion band; its
            // section is 2.2 times as tall as wide (waves quarry the joint upwards: an oval,
            // cleft-like mouth, not a round hole). Past its mouth it keeps a roof (its support
            // height at most 0.9 of the rock over its centre) and ends where the roof gets
            // thinner than 0.6 radius or the rock resistant: an enclosed void in soft rock,
            // not a trench.
            let n = (s.cave_length / (0.5 * r)).ceil() as usize;
            let mut widest = 0.0f32;
            let mut c = mouth;
            for m in 1..=n {
                let t = m as f32 / n as f32;
                let h = |q: u64| unit(hash(w.seed, k as u64, m as u64, 90 + q)) - 0.5;
                let turn = 0.17 * h(0);
                dir = [
                    dir[0] * turn.cos() - dir[1] * turn.sin(),
                    dir[0] * turn.sin() + dir[1] * turn.cos(),
                    0.0,
                ];
                c = add(c, mul(dir, 0.5 * r));
                c[2] = [-0.15f32, 0.0, 0.15]
                    .into_iter()
                    .map(|dz| (c[2] + dz * r).clamp(s.sea_level - s.depth, hi))
                    .min_by(|a, b| {
                        let rho = |z: f32| self.geology.resistance([c[0], c[1], z]);
                        rho(*a).total_cmp(&rho(*b))
                    })
                    .unwrap_or(c[2]);
                let room = self.ground(c[0], c[1]) - c[2];
                if m > 2 && (room < 0.6 * r || self.geology.resistance(c) >= 0.55) {
                    break;
                }
                let rr = r * (1.0 - 0.5 * t) * (0.85 + 0.3 * (h(2) + 0.5));
                let rr = if m > 1 { rr.min(0.9 * room) } else { rr };
                if rr <= 0.0 {
                    break;
                }
                widest = widest.max(rr);
                let tall = if m > 1 {
                    (2.2 * rr).min(0.9 * room)
                } else {
                    2.2 * rr
                };
                let id = self.tree.ellipsoid(
                    c,
                    [rr, rr, tall.max(rr)],
                    -s.weathering.energy * e.max(0.5),
                )?;
                self.negatives.push(id);
                self.carved.push((c, rr, false));
                report.primitives += 1;
            }
            report.sizes_m.push(widest);
        }
        Ok(())
    }

    /// Sea cliffs ([`SeaCliffs`]).
    pub fn sea_cliffs(&mut self, s: &SeaCliffs, region: &Region) -> Result<EffectReport> {
        self.check_lens(&named_fields!(s; depth, retreat, radius))?;
        if !s.sea_level.is_finite() {
            return Err(Error::param("sea_level", s.sea_level, "must be finite"));
        }
        in_range("beta", s.beta, 0.0..=1.0, "must be in [0, 1]")?;
        region.check(&self.frame)?;
        let f = self.frame;
        let spacing = 0.75 * s.radius;
        let per_cell = ((f.cx / spacing).ceil() * (f.cy / spacing).ceil()) as usize;
        if per_cell as f64 * (f.width * f.height) as f64 > (1u64 << 24) as f64 {
            return Err(Error::param(
                "radius",
                s.radius,
                "too small for this DEM: more than 2^24 cliff columns",
            ));
        }
        let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
        let mut best: Option<(f32, V3)> = None;
        let dist = self.distance_to_sea(s.sea_level, s.border_connected);
        // Bilinear distance to the sea (m).
        let dist_at = |x: f32, y: f32| {
            let (u, v) = f.to_grid([x, y, 0.0]);
            let u = u.clamp(0.0, (f.width - 1) as f32);
            let v = v.clamp(0.0, (f.height - 1) as f32);
            let (j0, i0) = (u.floor() as usize, v.floor() as usize);
            let (j1, i1) = ((j0 + 1).min(f.width - 1), (i0 + 1).min(f.height - 1));
            let (tx, ty) = (u - j0 as f32, v - i0 as f32);
            let g = |j: usize, i: usize| dist[i * f.width + j].min(1e9);
            (g(j0, i0) * (1.0 - tx) + g(j1, i0) * tx) * (1.0 - ty)
                + (g(j0, i1) * (1.0 - tx) + g(j1, i1) * tx) * ty
        };
        // Columns: a jittered grid `spacing` apart over the blocks of cells near the shore (a
        // block is one cell, or `stride` cells a side where cells are finer than the spacing,
        // so the columns stay `spacing` apart on a DEM interpolated finer).
        let cell = f.cx.max(f.cy);
        let stride = ((spacing / cell).floor() as usize).max(1);
        let reach_cells = (s.retreat / f.cx.min(f.cy)).ceil() + stride as f32;
        let mut pts: Vec<V3> = Vec::new();
        for i in (0..f.height - 1).step_by(stride) {
            for j in (0..f.width - 1).step_by(stride) {
                let (i1, j1) = (
                    (i + stride).min(f.height - 1),
                    (j + stride).min(f.width - 1),
                );
                let dmin = [(j, i), (j1, i), (j, i1), (j1, i1)]
                    .into_iter()
                    .map(|(jj, ii)| dist[ii * f.width + jj])
                    .fold(f32::INFINITY, f32::min);
                if dmin > reach_cells * cell {
                    continue;
                }
                let base = f.node(j, i1, 0.0);
                let (bw, bh) = ((j1 - j) as f32 * f.cx, (i1 - i) as f32 * f.cy);
                let (nx, ny) = (
                    (bw / spacing).ceil().max(1.0) as usize,
                    (bh / spacing).ceil().max(1.0) as usize,
                );
                for a in 0..nx {
                    for c in 0..ny {
                        let k = (a * ny + c) as u64;
                        let h = |q| unit(hash(s.seed, (i * f.width + j) as u64, k, q));
                        pts.push([
                            base[0] + (a as f32 + 0.25 + 0.5 * h(0)) / nx as f32 * bw,
                            base[1] + (c as f32 + 0.25 + 0.5 * h(1)) / ny as f32 * bh,
                            0.0,
                        ]);
                    }
                }
            }
        }
        let kept: Vec<usize> = (0..pts.len()).collect();
        let mut report = EffectReport {
            candidates: kept.len(),
            ..Default::default()
        };
        // Energy per sphere: several supports of the lattice overlap at each point; the energy
        // is set so that, in saturated rock, soft strata (e ~ 0.8) go and hard ones
        // (e ~ beta + 0.15) mostly stay. Within the heightfield transition under the surface
        // the rock is weaker and both go.
        let energy = 0.25;
        let dz = 0.5 * s.radius;
        for k in kept {
            let [x, y, _] = pts[k];
            let d = dist_at(x, y);
            let ground = self.ground(x, y);
            if d <= 0.0 || d > s.retreat || ground <= s.sea_level {
                continue;
            }
            let sigma = (1.0 - d / s.retreat).sqrt();
            // The lowest sphere is centred 0.8 radius above `sea_level - depth`: in the weak
            // rock of the heightfield transition under the surface, where a sphere cuts most
            // of its support, the cut stops within `depth` under the sea (a wave-cut platform
            // just under the water). Centred at `sea_level - depth` it cut most of a radius
            // deeper, and the DEM's low coastal fringe (SRTM runs of 1-2 m cells next to its
            // flat 0 m sea) became straight trenches under the water.
            let mut z = s.sea_level - s.depth + 0.8 * s.radius;
            let mut any = false;
            while z < ground + 0.5 * s.radius {
                let p = [x, y, z];
                let wgt = region.weight(&f, p);
                if wgt > 0.0 {
                    let e = erosion_intensity(self.geology.resistance(p), sigma * wgt, s.beta);
                    let id = self.tree.sphere(p, s.radius, -energy * e)?;
                    self.negatives.push(id);
                    self.carved.push((p, s.radius, false));
                    report.primitives += 1;
                    any = true;
                }
                z += dz;
            }
            if any {
                report.features += 1;
                // The site shown by close-ups: the cliff farthest from the DEM's border
                // (first found on ties).
                let inner = x.min(xm - x).min(y).min(ym - y);
                if best.is_none_or(|(b, _)| inner > b) {
                    best = Some((inner, [x, y, s.sea_level]));
                }
            }
        }
        report.sites.extend(best.map(|(_, p)| p));
        // Seen from the sea: the direction of the lowest ground around the site, one
        // retreat (at least 50 m) out.
        let reach = s.retreat.max(50.0);
        report.axes = report
            .sites
            .iter()
            .map(|&p| self.lowest_side(p, reach))
            .collect();
        Ok(report)
    }

    /// Wind erosion: stress = exposure of the surface to the wind times relative altitude.
    pub fn wind_erosion(&mut self, s: &WindErosion, region: &Region) -> Result<EffectReport> {
        let n = (s.direction[0].powi(2) + s.direction[1].powi(2)).sqrt();
        if !(n.is_finite() && n > 0.0) {
            return Err(Error::param(
                "direction",
                format!("{:?}", s.direction),
                "must be non-zero",
            ));
        }
        let wind = [s.direction[0] / n, s.direction[1] / n, 0.0];
        let (lo, hi) = self
            .dem
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |a, &z| {
                (a.0.min(z), a.1.max(z))
            });
        let stress = move |me: &Self, p: V3| {
            let Some((j, i)) = me.frame.cell(p) else {
                return 0.0;
            };
            let nrm = me.slope_normal(j, i);
            // `-n . w` is sin(slope) cos(aspect to the wind): ground gentler than 14.5 degrees
            // is not exposed (a groove there would be a closed pit, not an undercut), a face
            // turned to the wind at 30 degrees or more is fully exposed.
            let exposure = 4.0 * (-crate::math::dot(nrm, wind) - 0.25).max(0.0);
            exposure.min(1.0) * ((p[2] - lo) / (hi - lo).max(1e-3)).clamp(0.0, 1.0).sqrt()
        };
        Ok(self.weather(&s.weathering, region, None, true, stress)?.0)
    }

    /// Rain erosion: stress grows with the slope of the ground, from a third of
    /// `full_slope_deg` to `full_slope_deg`.
    pub fn rain_erosion(&mut self, s: &RainErosion, region: &Region) -> Result<EffectReport> {
        if !(s.full_slope_deg > 0.0 && s.full_slope_deg <= 90.0) {
            return Err(Error::param(
                "full_slope_deg",
                s.full_slope_deg,
                "must be in (0, 90]",
            ));
        }
        let full = s.full_slope_deg;
        let stress = move |me: &Self, p: V3| {
            let Some((j, i)) = me.frame.cell(p) else {
                return 0.0;
            };
            let slope = me.slope_normal(j, i)[2]
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees();
            // Zero on ground gentler than a third of `full` (no runoff to undercut a face;
            // a groove there would be a closed pit).
            ((slope - full / 3.0) / (full * 2.0 / 3.0)).clamp(0.0, 1.0)
        };
        Ok(self.weather(&s.weathering, region, None, true, stress)?.0)
    }
}

/// The horizontal direction inland (up the distance-to-sea gradient `dist`) at `p`.
fn inland(frame: &DemFrame, dist: &[f32], p: V3) -> Option<V3> {
    let (j, i) = frame.cell(p)?;
    let (j0, j1) = (j.saturating_sub(1), (j + 1).min(frame.width - 1));
    let (i0, i1) = (i.saturating_sub(1), (i + 1).min(frame.height - 1));
    let gx = dist[i * frame.width + j1] - dist[i * frame.width + j0];
    let gy = dist[i0 * frame.width + j] - dist[i1 * frame.width + j];
    let g = (gx * gx + gy * gy).sqrt();
    (g.is_finite() && g > 0.0).then(|| [gx / g, gy / g, 0.0])
}

/// The direction of the joint set nearest `inward` (horizontal, unit): the region's joints form
/// two orthogonal sets at an angle hashed from `seed`; of their four headings, the one closest
/// to `inward`.
fn joint_towards(seed: u64, inward: V3) -> V3 {
    let a0 = std::f32::consts::TAU * unit(hash(seed, 0x6a6f_696e, 0, 0x7365_6163));
    (0..4)
        .map(|k| {
            let a = a0 + k as f32 * std::f32::consts::FRAC_PI_2;
            [a.cos(), a.sin(), 0.0]
        })
        .max_by(|a, b| {
            let d = |v: &V3| v[0] * inward[0] + v[1] * inward[1];
            d(a).total_cmp(&d(b))
        })
        .unwrap_or(inward)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sea caves follow one of two orthogonal joint sets: whatever the way inland, the heading
    /// is within 45 degrees of it, and the headings for any two ways inland are parallel or
    /// perpendicular; another seed turns the sets.
    #[test]
    fn sea_caves_head_along_two_orthogonal_joint_sets() {
        let heading = |seed: u64, a: f32| joint_towards(seed, [a.cos(), a.sin(), 0.0]);
        let first = heading(7, 0.0);
        for k in 0..24 {
            let a = k as f32 * 0.26;
            let d = heading(7, a);
            assert!(d[0] * a.cos() + d[1] * a.sin() >= 0.707 - 1e-4, "{a} {d:?}");
            let c = (d[0] * first[0] + d[1] * first[1]).abs();
            assert!(c < 1e-4 || (c - 1.0).abs() < 1e-4, "{a} {d:?} {first:?}");
        }
        let other = heading(8, 0.0);
        assert!((other[0] * first[0] + other[1] * first[1]).abs() < 0.9999);
    }
}
