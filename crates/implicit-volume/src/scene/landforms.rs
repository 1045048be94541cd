//! Landforms placed on the terrain: hoodoos and arches (paper section 4); floating islands are
//! in `islands.rs`.

use super::*;
use relief_heightfield::param::in_range;

/// Slope (degrees) above which ground counts as a rim or wall for hoodoo sites.
const RIM_SLOPE_DEG: f32 = 35.0;

/// The ring of rock an arch leaves (see [`SceneBuilder::arches`]): a half-ellipse standing on
/// the gap's floor at `centre`, in the vertical plane along `side`.
#[derive(Debug, Clone, Copy)]
struct ArchFit {
    /// Floor under the middle of the opening.
    centre: V3,
    /// Horizontal unit vector along the ridge (the ring's plane).
    side: V3,
    /// Horizontal unit vector across the ridge (through the opening).
    across: V3,
    /// Half-width of the ring's centre line at the floor: half the opening plus half a leg.
    half: f32,
    /// Height of the ring's centre line at the crown: the opening plus half the bridge.
    rise: f32,
    /// Width of a leg at the floor.
    leg: f32,
    /// Thickness of the bridge at the crown.
    bridge: f32,
}

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
            // between 0.6 and 1.4 of the nominal height (the first of equals), so each stands
            // as tall as its strata allow; sites without hard rock there are skipped.
            let rho = |z: f32| self.geology.resistance([p[0], p[1], z]);
            let mut cap = (f32::NEG_INFINITY, p[2] + s.height);
            for m in 0..=16 {
                let z = p[2] + s.height * (0.6 + 0.8 * m as f32 / 16.0);
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
            report.sizes_m.push(top + 0.45 * cr - p[2]);
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

    /// Natural arches eroded out of the rock ([`ArchSettings`]): the narrowest ridges of the
    /// DEM (at every node, eight horizontal directions; the ridge must drop by the opening
    /// plus the bridge on both sides within `max_length`) are cut through by a gap down to
    /// the higher mouth's ground, its walls flaring upwards and roughened by a warp, and in
    /// the gap a ring of the original rock is left standing in the ridge's plane: two legs
    /// and a bridge (a warped chain of cones along a half-ellipse, necked where the strata
    /// are soft, section 4.1's resistance), intersected with the DEM's rock so nothing is
    /// added. Seen along the gap, the arch stands free against the sky, like the fins and
    /// ridge-top arches of canyon country, instead of a tunnel mouth in a wall. Ridges
    /// whose ground cannot hold the ring are passed over; ridges are taken thinnest first,
    /// `max(2 max_length, 4 span)` apart.
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
        let mut cands = self.arch_candidates(s, region);
        cands.sort_by(|x, y| {
            x.0.total_cmp(&y.0)
                .then(hash(s.seed, x.1, 2, 0).cmp(&hash(s.seed, y.1, 2, 0)))
        });
        let total = cands.len();
        let fits: Vec<(ArchFit, V3, V3, V3, u64)> = cands
            .iter()
            .filter_map(|&(_, idx, d, m0, m1)| {
                self.arch_fits(s, d, m0, m1).map(|f| (f, d, m0, m1, idx))
            })
            .collect();
        let pts: Vec<V3> = fits
            .iter()
            .map(|x| [x.0.centre[0], x.0.centre[1], 0.0])
            .collect();
        let spacing = (2.0 * s.max_length).max(4.0 * s.span);
        let kept = poisson_filter(&pts, spacing, |_| true);
        let mut report = EffectReport {
            candidates: total,
            ..Default::default()
        };
        for k in kept {
            if report.features >= s.count {
                break;
            }
            let (arch, d, m0, m1, idx) = fits[k];
            let seed = (s.seed as u32).wrapping_add(idx as u32);
            report.primitives += self.carve_gap(&arch, d, m0, m1, seed)?;
            report.primitives += self.keep_ring(&arch, seed)?;
            report.features += 1;
            report.length_m += norm(sub(m1, m0));
            report.sizes_m.push(s.span);
            let c = arch.centre;
            report.sites.push([c[0], c[1], c[2] + 0.5 * s.height]);
            // Look through the opening from the lower side.
            let look = if m0[2] <= m1[2] { d } else { mul(d, -1.0) };
            report.axes.push(look);
        }
        Ok(report)
    }

    /// The ring an arch between the mouths `m0`, `m1` (across the ridge along `d`) would
    /// leave, when the original ground along the ridge holds all of it.
    fn arch_fits(&self, s: &ArchSettings, d: V3, m0: V3, m1: V3) -> Option<ArchFit> {
        let floor = m0[2].max(m1[2]);
        let mid = mul(add(m0, m1), 0.5);
        let fit = ArchFit {
            centre: [mid[0], mid[1], floor],
            side: [-d[1], d[0], 0.0],
            across: d,
            half: 0.5 * s.span + 0.6 * s.thickness,
            rise: s.height + 0.5 * s.thickness,
            leg: 1.2 * s.thickness,
            bridge: s.thickness,
        };
        let outer = fit.half + 0.5 * fit.leg;
        let top = fit.rise + 0.5 * fit.bridge;
        // The ring and its legs stand inside the DEM (not on the slab's side).
        let fr = self.frame;
        let (xm, ym) = (
            (fr.width - 1) as f32 * fr.cx,
            (fr.height - 1) as f32 * fr.cy,
        );
        let inside = |p: V3| p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= xm && p[1] <= ym;
        let reach = outer + fit.leg;
        if ![-1.0f32, 1.0]
            .iter()
            .all(|&u| inside(add(fit.centre, mul(fit.side, u * reach))))
        {
            return None;
        }
        // The ring's height is scaled down to the ground where the ridge sags (to 0.7 at most).
        let scale = (-8..=8)
            .map(|q| {
                let u = q as f32 / 8.0 * fit.half;
                let p = add(fit.centre, mul(fit.side, u));
                let need = top * (1.0 - (u / outer).powi(2)).max(0.0).sqrt();
                (self.ground(p[0], p[1]) - floor) / need
            })
            .fold(1.0f32, f32::min);
        (scale >= 0.7).then_some(ArchFit {
            rise: scale * top - 0.5 * fit.bridge,
            ..fit
        })
    }

    /// The gap through the ridge around an arch: negative capsules along `d` from beyond
    /// one mouth to beyond the other, three side by side at the floor (a flat bottom as wide
    /// as the ring plus half the opening on each side), then wider ones stacked up to the
    /// highest ground over the gap (walls flaring outwards), warped. Returns the primitives.
    fn carve_gap(&mut self, f: &ArchFit, d: V3, m0: V3, m1: V3, seed: u32) -> Result<usize> {
        // Saturated rock (field 2T) loses 0.76 of the support radius at this energy.
        let energy = 20.0 * THRESHOLD;
        let hole = |r: f32| r / 0.76;
        let w = f.half + 0.5 * f.leg + 0.5 * (f.half - 0.5 * f.leg);
        let (e0, e1) = (add(m0, mul(d, -0.5 * w)), add(m1, mul(d, 0.5 * w)));
        let crest = (0..=16)
            .flat_map(|q| [-1.0f32, 0.0, 1.0].map(move |u| (q, u)))
            .map(|(q, u)| {
                let p = add(
                    add(e0, mul(sub(e1, e0), q as f32 / 16.0)),
                    mul(f.side, u * w),
                );
                self.ground(p[0], p[1])
            })
            .fold(f.centre[2], f32::max);
        let floor = f.centre[2];
        let at = |p: V3, u: f32, z: f32| [p[0] + f.side[0] * u, p[1] + f.side[1] * u, z];
        let mut parts = Vec::new();
        let r0 = 0.55 * w;
        for u in [-0.5 * w, 0.0, 0.5 * w] {
            let (a, b) = (at(e0, u, floor + r0), at(e1, u, floor + r0));
            parts.push(self.tree.capsule(a, b, hole(r0), -energy)?);
            self.carved.push((mul(add(a, b), 0.5), hole(r0), false));
        }
        for k in 1..8 {
            let (z, r) = (floor + r0 + 0.7 * w * k as f32, w * (1.0 + 0.35 * k as f32));
            if z - r > crest {
                break;
            }
            let (a, b) = (at(e0, 0.0, z), at(e1, 0.0, z));
            parts.push(self.tree.capsule(a, b, hole(r), -energy)?);
            self.carved.push((mul(add(a, b), 0.5), hole(r), false));
        }
        let n = parts.len();
        let bl = self.tree.blend(&parts)?;
        let warped = self.tree.warp(bl, 0.12 * w, 1.0 / (0.8 * w), seed)?;
        self.negatives.push(warped);
        Ok(n)
    }

    /// The ring left standing in the gap: cones along the half-ellipse of `f` (legs
    /// `f.leg` wide at the floor, the bridge `f.bridge` thick at the crown, necked by soft
    /// strata), sunk into the floor at both feet, warped, and intersected with the DEM's rock.
    fn keep_ring(&mut self, f: &ArchFit, seed: u32) -> Result<usize> {
        use std::f32::consts::PI;
        // Support radius for a solid of half-thickness `r` at energy 2: (1 - q)^3 = 1/4.
        let support = |r: f32| r / 0.608;
        let n = 12;
        let (a, h) = (f.half - 0.5 * f.leg, f.rise - 0.5 * f.bridge);
        // The crown is as thick as the rock over the opening allows (up to two bridges): the
        // DEM's surface then trims it flat, so the bridge's top is the ridge's own.
        let over = self.ground(f.centre[0], f.centre[1]) - (f.centre[2] + h);
        let crown = (0.5 * over).clamp(0.5 * f.bridge, f.bridge);
        let foot = 0.6 * f.leg;
        // Inner edge of the opening (a half-ellipse) pushed out along its normal by the
        // tube's radius: the opening stays `2a` wide and `h` high.
        let ring = |t: f32, off: f32| {
            let th = PI * t;
            let (c, sn) = (th.cos(), th.sin());
            let nrm = {
                let (nu, nz) = (c / a, sn / h.max(1e-3));
                let l = (nu * nu + nz * nz).sqrt();
                (nu / l, nz / l)
            };
            let q = add(f.centre, mul(f.across, off));
            let q = add(q, mul(f.side, a * c));
            let q = [q[0], q[1], q[2] + h * sn];
            let r0 = crown + (foot - crown) * c * c;
            let r = r0 * (0.8 + 0.4 * self.geology.resistance(q));
            let p = add(add(q, mul(f.side, nrm.0 * r)), [0.0, 0.0, nrm.1 * r]);
            (p, r)
        };
        let mut parts = Vec::new();
        for off in [-0.3 * f.leg, 0.3 * f.leg] {
            for t in [0.0f32, 1.0] {
                let (p, r) = ring(t, off);
                let base = [p[0], p[1], p[2] - f.leg];
                parts.push(self.tree.cone(base, p, support(1.2 * r), support(r), 2.0)?);
            }
            for k in 0..n {
                let (p0, r0) = ring(k as f32 / n as f32, off);
                let (p1, r1) = ring((k + 1) as f32 / n as f32, off);
                parts.push(self.tree.cone(p0, p1, support(r0), support(r1), 2.0)?);
            }
        }
        let mut kept = parts[0];
        for &p in &parts[1..] {
            kept = self.tree.union(kept, p)?;
        }
        let warped = self.tree.warp(kept, 0.12 * f.leg, 1.0 / f.leg, seed)?;
        let kept = self.tree.intersection(self.hf, warped)?;
        self.positives.push(kept);
        Ok(parts.len())
    }

    /// Arch candidates, one per DEM node whose ridge is thin enough in some direction: (gap
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

    /// A north-south fin 50 m wide and 50 m high: the arch is a gap cut through it (air at
    /// the opening's middle, which was rock, and before and behind the bridge, where the fin
    /// stood) with a ring of rock left standing in it (the bridge and both legs still
    /// matter), seen along the gap's east-west axis.
    #[test]
    fn arches_leave_a_ring_of_rock_standing_in_a_gap_through_a_fin() {
        let hf = Heightfield::from_fn(40, 40, 5.0, 5.0, |x, _| {
            if (x as f32 - 20.0).abs() <= 5.0 {
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
        assert!(axis[0].abs() > 0.9, "the gap crosses the fin: {axis:?}");
        assert!((site[0] - 100.0).abs() < 10.0, "{site:?}");
        let scene = b.build(true).unwrap();
        assert!(before.inside(site), "the opening was rock");
        assert!(!scene.inside(site), "the opening is air");
        // The floor is the higher mouth's ground (the site is half the opening above it); the
        // bridge is 8-16 m thick over the 15 m opening, trimmed by the warp (1.2 m).
        let floor = site[2] - 7.5;
        let bridge = [site[0], site[1], floor + 15.0 + 4.0];
        assert!(scene.inside(bridge), "the bridge stands");
        for sign in [-1.0f32, 1.0] {
            let p = add(bridge, mul(axis, sign * 18.0));
            assert!(before.inside(p), "the fin stood at {p:?}");
            assert!(!scene.inside(p), "the fin is cut away at {p:?}");
        }
        // The legs, half a leg out from the opening's sides, on the floor.
        let side = [-axis[1], axis[0], 0.0];
        for sign in [-1.0f32, 1.0] {
            let foot = add(
                [site[0], site[1], floor + 2.0],
                mul(side, sign * (6.0 + 0.6 * 9.6)),
            );
            assert!(scene.inside(foot), "a leg at {foot:?}");
        }
        // Air all the way through the opening along the axis.
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
