//! Landforms placed on the terrain: hoodoos and arches (paper section 4); floating islands are
//! in `islands.rs`.

use super::*;
use relief_heightfield::param::in_range;

/// Slope (degrees) above which ground counts as a rim or wall for hoodoo sites.
const RIM_SLOPE_DEG: f32 = 35.0;

impl SceneBuilder {
    fn flat_sites(
        &self,
        spacing: f32,
        max_slope_deg: f32,
        seed: u64,
        region: &Region,
        margin: f32,
    ) -> Vec<V3> {
        let f = self.frame;
        let cos_max = max_slope_deg.to_radians().cos();
        let mut pts = Vec::new();
        for i in 0..f.height {
            for j in 0..f.width {
                let p = f.node(j, i, self.dem_at(j, i));
                let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
                if p[0] < margin || p[1] < margin || p[0] > xm - margin || p[1] > ym - margin {
                    continue;
                }
                if self.slope_normal(j, i)[2] >= cos_max && region.weight(&f, p) > 0.0 {
                    pts.push((hash(seed, (i * f.width + j) as u64, 0, 0), p));
                }
            }
        }
        pts.sort_by_key(|x| x.0);
        let pts: Vec<V3> = pts.into_iter().map(|x| x.1).collect();
        let kept = poisson_filter(&pts, spacing, |_| true);
        kept.into_iter().map(|k| pts[k]).collect()
    }

    /// Adds the blend of `parts`, warped by noise of amplitude `amp` and wavelength
    /// `wavelength` (seeded), to the positive landforms.
    fn add_warped(&mut self, parts: &[NodeId], amp: f32, wavelength: f32, seed: u32) -> Result<()> {
        let b = self.tree.blend(parts)?;
        let w = self.tree.warp(b, amp, 1.0 / wavelength, seed)?;
        self.positives.push(w);
        Ok(())
    }

    /// `sites` reordered so that those within `reach` of steep ground (slope above
    /// [`RIM_SLOPE_DEG`]) come first, in their given order, then the others: hoodoos stand
    /// in the breaks below and along plateau rims and canyon walls (where the caprock is being
    /// undercut), not spread evenly over flat ground.
    fn rims_first(&self, sites: Vec<V3>, reach: f32) -> Vec<V3> {
        let f = self.frame;
        let cos_rim = RIM_SLOPE_DEG.to_radians().cos();
        let steep: Vec<bool> = (0..f.height)
            .flat_map(|i| (0..f.width).map(move |j| (j, i)))
            .map(|(j, i)| self.slope_normal(j, i)[2] < cos_rim)
            .collect();
        let (rx, ry) = (
            (reach / f.cx).ceil().max(1.0) as isize,
            (reach / f.cy).ceil().max(1.0) as isize,
        );
        let near_rim = |p: &V3| {
            let (gj, gi) = f.to_grid(*p);
            let (j0, i0) = (gj.round() as isize, gi.round() as isize);
            (-ry..=ry).any(|di| {
                (-rx..=rx).any(|dj| {
                    let (j, i) = (j0 + dj, i0 + di);
                    let inside =
                        j >= 0 && i >= 0 && (j as usize) < f.width && (i as usize) < f.height;
                    let d2 = (dj as f32 * f.cx).powi(2) + (di as f32 * f.cy).powi(2);
                    inside && d2 <= reach * reach && steep[i as usize * f.width + j as usize]
                })
            })
        };
        let (mut first, rest): (Vec<V3>, Vec<V3>) = sites.into_iter().partition(near_rim);
        first.extend(rest);
        first
    }

    /// Hoodoos (figure 3): a cone base blended with stacked perturbed spheres and a caprock,
    /// creased by a warp, unioned with the terrain on gentle ground.
    pub fn hoodoos(&mut self, s: &HoodooSettings, region: &Region) -> Result<EffectReport> {
        self.check_lens(&named_fields!(s; height, radius, spacing))?;
        in_range(
            "max_slope_deg",
            s.max_slope_deg,
            0.0..=90.0,
            "must be in [0, 90]",
        )?;
        in_range("cap_rho", s.cap_rho, 0.0..=1.0, "must be in [0, 1]")?;
        region.check(&self.frame)?;
        let sites = self.flat_sites(s.spacing, s.max_slope_deg, s.seed, region, 2.0 * s.radius);
        let sites = self.rims_first(sites, 3.0 * s.spacing);
        let mut report = EffectReport {
            candidates: sites.len(),
            primitives: 0,
            ..Default::default()
        };
        for (k, &p) in sites.iter().enumerate() {
            if report.features >= s.count {
                break;
            }
            let h = |c| unit(hash(s.seed, k as u64, c, 7));
            // A hoodoo survives under a resistant caprock: the cap sits at the hardest level
            // of the top quarter; sites without hard rock there are skipped.
            let rho = |z: f32| self.geology.resistance([p[0], p[1], z]);
            let mut cap = (f32::NEG_INFINITY, p[2] + s.height);
            for m in 0..=8 {
                let z = p[2] + s.height * (0.75 + 0.3 * m as f32 / 8.0);
                let r = rho(z);
                if r > cap.0 {
                    cap = (r, z);
                }
            }
            if cap.0 < s.cap_rho {
                continue;
            }
            let top = cap.1;
            let mut parts = Vec::new();
            let base = [p[0], p[1], p[2] - 0.2 * s.height];
            parts.push(self.tree.cone(
                base,
                [p[0], p[1], p[2] + 0.3 * (top - p[2])],
                1.8 * s.radius,
                1.0 * s.radius,
                1.0,
            )?);
            // The column: soft strata are narrow necks, hard strata bulges.
            let n = (((top - p[2]) / (0.45 * s.radius)).ceil() as usize).clamp(3, 64);
            for m in 0..n {
                let t = (m as f32 + 0.5) / n as f32;
                let z = p[2] + t * (top - p[2]);
                let c = [
                    p[0] + (h(10 + m as u64) - 0.5) * 0.15 * s.radius,
                    p[1] + (h(20 + m as u64) - 0.5) * 0.15 * s.radius,
                    z,
                ];
                let r = s.radius * (0.55 + 0.6 * rho(z)) * (0.9 + 0.2 * h(30 + m as u64));
                parts.push(self.tree.sphere(c, r, 0.6)?);
            }
            let cr = s.radius * (0.8 + 0.8 * cap.0);
            parts.push(self.tree.ellipsoid(
                [p[0], p[1], top],
                [1.3 * cr, 1.2 * cr, 0.45 * cr],
                1.5,
            )?);
            report.primitives += parts.len();
            report.features += 1;
            report.sites.push(p);
            let seed = (s.seed as u32).wrapping_add(k as u32);
            self.add_warped(&parts, 0.12 * s.radius, 0.6 * s.radius, seed)?;
        }
        Ok(report)
    }

    /// One arch between two feet given in scene `(x, y)`: capsules along an arc rising `height`
    /// above the higher foot, warped.
    pub fn arch(
        &mut self,
        a: [f32; 2],
        b: [f32; 2],
        height: f32,
        thickness: f32,
        seed: u32,
    ) -> Result<NodeId> {
        self.check_len("height", height)?;
        self.check_len("thickness", thickness)?;
        if !a.iter().chain(&b).all(|v| v.is_finite()) {
            return Err(Error::param(
                "arch feet",
                format!("{a:?} -> {b:?}"),
                "must be finite",
            ));
        }
        let za = self.ground(a[0], a[1]);
        let zb = self.ground(b[0], b[1]);
        let (pa, pb) = ([a[0], a[1], za - thickness], [b[0], b[1], zb - thickness]);
        let top = za.max(zb) + height;
        let n = 12;
        let pt = |t: f32| {
            let q = add(pa, mul(sub(pb, pa), t));
            let lift = (top - q[2]) * (std::f32::consts::PI * t).sin();
            [q[0], q[1], q[2] + lift]
        };
        let mut parts = Vec::new();
        for k in 0..n {
            let (t0, t1) = (k as f32 / n as f32, (k + 1) as f32 / n as f32);
            let r =
                thickness * (1.0 + 0.6 * (1.0 - (std::f32::consts::PI * (t0 + t1) * 0.5).sin()));
            parts.push(self.tree.capsule(pt(t0), pt(t1), r, 1.0)?);
        }
        let bl = self.tree.blend(&parts)?;
        let w = self
            .tree
            .warp(bl, 0.12 * thickness, 1.0 / thickness, seed)?;
        self.positives.push(w);
        Ok(w)
    }

    /// Natural arches carved out of the rock ([`ArchSettings`]): the narrowest ridges of the
    /// DEM (at every node, eight horizontal directions; the ridge must drop by the opening
    /// plus the bridge on both sides within `max_length`) are bored through by a negative
    /// capsule whose support stays under the ridge's crest, so the crest survives as the
    /// bridge; the tunnel's walls are widened by smaller spheres where the rock is soft
    /// (`e(rho, sigma)` of section 4.1), so the opening follows the strata. Ridges are taken
    /// thinnest first, `max(2 max_length, 4 span)` apart.
    pub fn arches(&mut self, s: &ArchSettings, region: &Region) -> Result<EffectReport> {
        self.check_lens(&named_fields!(s; span, height, thickness, max_length))?;
        if s.max_length < s.span {
            return Err(Error::param(
                "max_length",
                s.max_length,
                "must be at least the span",
            ));
        }
        region.check(&self.frame)?;
        let a = 0.5 * s.span;
        // The tunnel's axis sits `height - a` above the floor (a round opening when the height
        // is the span, a low flat-floored one below that).
        let lift = s.height - a;
        let mut cands = self.arch_candidates(s, region);
        cands.sort_by(|x, y| {
            x.0.total_cmp(&y.0)
                .then(hash(s.seed, x.1, 2, 0).cmp(&hash(s.seed, y.1, 2, 0)))
        });
        let pts: Vec<V3> = cands
            .iter()
            .map(|x| {
                let c = mul(add(x.3, x.4), 0.5);
                [c[0], c[1], 0.0]
            })
            .collect();
        let spacing = (2.0 * s.max_length).max(4.0 * s.span);
        let kept = poisson_filter(&pts, spacing, |_| true);
        let mut report = EffectReport {
            candidates: cands.len(),
            ..Default::default()
        };
        // Saturated rock (field 2T) keeps 0.8 of the support radius at this energy; in the
        // weaker rock of the heightfield's transition under the surface the hole is wider.
        let energy = 20.0 * THRESHOLD;
        for k in kept {
            if report.features >= s.count {
                break;
            }
            let (_, idx, d, m0, m1) = cands[k];
            let floor = m0[2].max(m1[2]);
            let z = floor + lift;
            // The crest along the tunnel's middle third: the support must stay under it.
            let crest = (1..=5)
                .map(|q| {
                    let t = 1.0 / 3.0 + q as f32 / 18.0;
                    let p = add(m0, mul(sub(m1, m0), t));
                    self.ground(p[0], p[1])
                })
                .fold(f32::INFINITY, f32::min);
            let r = (a / 0.8).min(crest - s.thickness - z);
            if r < 0.5 * a {
                continue;
            }
            let e0 = add([m0[0], m0[1], z], mul(d, a));
            let e1 = add([m1[0], m1[1], z], mul(d, -a));
            let id = self.tree.capsule(e0, e1, r, -energy)?;
            self.negatives.push(id);
            self.carved.push((mul(add(e0, e1), 0.5), r, false));
            report.primitives += 1;
            // Soft strata along the walls and the floor widen the opening (notches).
            let len = norm(sub(e1, e0));
            let n = ((len / (0.5 * a)).ceil() as usize).clamp(2, 256);
            let side = [-d[1], d[0], 0.0];
            for q in 0..=n {
                let p = add(e0, mul(sub(e1, e0), q as f32 / n as f32));
                for (w, off) in [(0u64, 1.0f32), (1, -1.0)] {
                    let h = |c: u64| unit(hash(s.seed, idx, (q * 4) as u64 + w, c));
                    let dz = (h(0) - 0.7) * a;
                    let c = add(p, [side[0] * off * 0.8 * a, side[1] * off * 0.8 * a, dz]);
                    let rho = self.geology.resistance(c);
                    let e = erosion_intensity(rho, 1.0, 0.1);
                    // Under the crest's bridge and under the ground above the notch itself:
                    // near the mouths, where the ground falls below the crest, a notch would
                    // otherwise pit the hillside beside the opening.
                    let cover = crest.min(self.ground(c[0], c[1])) - s.thickness;
                    if rho < 0.5 && c[2] + 0.6 * a < cover {
                        let id = self.tree.sphere(c, 0.6 * a, -energy * e)?;
                        self.negatives.push(id);
                        self.carved.push((c, 0.6 * a, false));
                        report.primitives += 1;
                    }
                }
            }
            report.features += 1;
            report.length_m += len;
            let mid = mul(add(e0, e1), 0.5);
            report.sites.push([mid[0], mid[1], z]);
            // Look through the opening from the lower side.
            let look = if m0[2] <= m1[2] { d } else { mul(d, -1.0) };
            report.axes.push(look);
        }
        Ok(report)
    }

    /// Arch candidates, one per DEM node whose ridge is thin enough in some direction: (tunnel
    /// length, node index, direction, the two mouths).
    fn arch_candidates(&self, s: &ArchSettings, region: &Region) -> Vec<(f32, u64, V3, V3, V3)> {
        let f = self.frame;
        let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
        let a = 0.5 * s.span;
        let need = s.height + s.thickness;
        let step = (0.25 * f.cx.min(f.cy)).min(0.5 * a);
        let half = 0.5 * s.max_length;
        let margin = a;
        // Candidates: (fin width, node index, direction index, mouths, floor).
        let nodes: Vec<(usize, usize)> = (0..f.height)
            .flat_map(|i| (0..f.width).map(move |j| (j, i)))
            .collect();
        let me = self;
        nodes
            .par_iter()
            .filter_map(|&(j, i)| {
                let top = me.dem_at(j, i);
                let c = f.node(j, i, top);
                if c[0] < margin || c[1] < margin || c[0] > xm - margin || c[1] > ym - margin {
                    return None;
                }
                if region.weight(&f, c) <= 0.0 {
                    return None;
                }
                let mut best: Option<(f32, V3, V3, V3)> = None;
                for k in 0..8 {
                    let ang = (k as f32 + 0.5 * unit(hash(s.seed, (i * f.width + j) as u64, 1, 0)))
                        * std::f32::consts::PI
                        / 8.0;
                    let d = [ang.cos(), ang.sin(), 0.0];
                    // Walk out on both sides to the first ground `need` under the crest.
                    let mut mouths = [[0.0f32; 3]; 2];
                    let mut ok = true;
                    for (m, sign) in [1.0f32, -1.0].into_iter().enumerate() {
                        let mut t = step;
                        let mut found = None;
                        while t <= half {
                            let q = add(c, mul(d, sign * t));
                            if q[0] < 0.0 || q[1] < 0.0 || q[0] > xm || q[1] > ym {
                                break;
                            }
                            let g = me.ground(q[0], q[1]);
                            if g <= top - need {
                                found = Some([q[0], q[1], g]);
                                break;
                            }
                            t += step;
                        }
                        match found {
                            Some(q) => mouths[m] = q,
                            None => {
                                ok = false;
                                break;
                            }
                        }
                    }
                    if !ok {
                        continue;
                    }
                    let len = norm(sub(mouths[0], mouths[1]));
                    if len < s.span.min(f.cx.min(f.cy)) {
                        continue;
                    }
                    if best.as_ref().is_none_or(|b| len < b.0) {
                        best = Some((len, d, mouths[0], mouths[1]));
                    }
                }
                let (len, d, m0, m1) = best?;
                Some((len, (i * f.width + j) as u64, d, m0, m1))
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geology::Geology;

    /// A north-south fin 30 m wide and 50 m high: the arch is a tunnel through it (air at the
    /// opening's middle, which was rock) under a bridge of rock (still matter), seen along the
    /// tunnel's east-west axis.
    #[test]
    fn arches_bore_through_a_fin_under_a_bridge() {
        let hf = Heightfield::from_fn(40, 40, 5.0, 5.0, |x, _| {
            if (x as f32 - 20.0).abs() <= 3.0 {
                60.0
            } else {
                10.0
            }
        });
        let geo = Geology::layered_default([100.0, 100.0, 35.0], 12.0, 1).unwrap();
        let mut b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
        let before = b.clone().build(true).unwrap();
        let s = ArchSettings {
            count: 1,
            span: 12.0,
            height: 15.0,
            thickness: 8.0,
            max_length: 80.0,
            seed: 3,
        };
        let rep = b.arches(&s, &Region::everywhere()).unwrap();
        assert_eq!(rep.features, 1, "{rep:?}");
        let site = rep.sites[0];
        let axis = rep.axes[0];
        assert!(axis[0].abs() > 0.9, "the tunnel crosses the fin: {axis:?}");
        assert!((site[0] - 100.0).abs() < 10.0, "{site:?}");
        let scene = b.build(true).unwrap();
        assert!(before.inside(site), "the opening was rock");
        assert!(!scene.inside(site), "the opening is air");
        let bridge = [site[0], site[1], 56.0];
        assert!(scene.inside(bridge), "the bridge stands");
        // Air all the way through the fin along the axis.
        for k in -4..=4 {
            let p = add(site, mul(axis, 4.0 * k as f32));
            assert!(!scene.inside(p), "rock at {p:?}");
        }
        // No ridge narrow enough: no arch, no error.
        let flat = Heightfield::from_fn(20, 20, 5.0, 5.0, |_, _| 10.0);
        let geo = Geology::layered_default([50.0, 50.0, 10.0], 12.0, 1).unwrap();
        let mut b = SceneBuilder::new(&flat, geo, &ImplicitizeSettings::default()).unwrap();
        assert_eq!(b.arches(&s, &Region::everywhere()).unwrap().features, 0);
    }
}
