//! Natural arches (paper section 4) out of the strata: a ridge narrowed to a fin, eroded
//! through along a soft stratum under a resistant bridge bed.
//!
//! Placement ([`SceneBuilder::arches`]): the narrowest ridges of the DEM (at every node, eight
//! horizontal directions; the ridge must drop on both sides within `max_length`) are taken
//! thinnest first, `max(2 max_length, 4 span)` apart. Each arch draws its span from a
//! log-normal distribution around `span` ([`arch_span`]: 10 % of them under 0.56 and 10 %
//! over 1.8 times it, within `[0.35, 3]` times it and at most 120 m) and shrinks it (by a
//! quarter at a time, down to 0.35 `span`) until the ridge and the geology hold it:
//! * **the bridge bed**: over the opening's middle, the lowest place where the rock turns
//!   from soft (`rho < 0.5`) to resistant (`rho >= 0.55`) at least 0.35 span above the
//!   ground at the ridge's feet (the higher of the two), where the ridge keeps at least
//!   `max(0.4 thickness, 1 m)` of rock over it along the opening and stands up to it beside
//!   the opening (the legs). The opening's roof is that bed's base and its floor 0.6 span
//!   under it (less down to the feet's ground): the same ridge gets another arch on another
//!   geology.
//!
//! Shape ([`SceneBuilder::arches`]): a gap is cut across the ridge down to the floor (walls
//! flaring upwards, warped); in it the arch stands free, the ridge's rock left where the
//! resistant bed protected it: a rib swept along a half-superellipse (exponent 2.5: rounded
//! shoulders) from one foot over the opening to the other, its underside at the roof (the
//! bridge bed's base) and the opening `span` wide at the floor. The crown is as thick as the
//! resistant rock over the roof (within `[0.15, 0.35] span`), the rib thickens to legs of
//! `0.6 thickness + 0.15 span` radius, narrower in soft strata (`0.85 + 0.3 rho`) and jittered
//! by +-10 %; it is cut to the fin (rows of capsules along the ridge `thickness` thick,
//! recessed in soft strata and standing out at hard beds, `0.6 + 0.6 rho`), so its faces are
//! flat and ledged, and warped by noise (`0.12` of the leg radius); all hashed from the seed,
//! the same for the same seed. Beyond each leg the fin goes on along the ridge for 1.5 spans,
//! its top falling from the bridge's to the ground (`fin_wings`): the arch is a window in a
//! fin, not a rib alone on the ridge.

use super::*;

use crate::math::VISIBLE;

/// Span of arch `k` (m): log-normal around `median` (`sigma` 0.45), within
/// `[0.35, 3] median` and at most 120 m (the longest natural spans), hashed from `seed`.
pub(crate) fn arch_span(median: f32, seed: u64, k: u64) -> f32 {
    let u1 = unit(hash(seed, k, 0x7370_616e, 1)).max(1e-6);
    let u2 = unit(hash(seed, k, 0x7370_616e, 2));
    let g = (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos();
    (median * (0.45 * g).exp()).clamp(0.35 * median, (3.0 * median).min(120.0_f32.max(median)))
}

/// An arch that fits a ridge (see [`SceneBuilder::arches`]).
#[derive(Debug, Clone, Copy)]
struct ArchFit {
    /// Floor under the middle of the opening (the higher mouth's ground).
    centre: V3,
    /// Horizontal unit vector along the ridge (the fin's plane).
    side: V3,
    /// Horizontal unit vector across the ridge (through the opening).
    across: V3,
    /// Width of the opening (m).
    span: f32,
    /// Height of the opening: the bridge bed's base above the floor (m).
    rise: f32,
    /// Thickness of the fin (m).
    fin: f32,
    /// Half-width of the gap cut across the ridge, along it (m).
    half_gap: f32,
}

impl SceneBuilder {
    /// Natural arches ([module docs](self)). [`EffectReport::sites`] are the openings'
    /// middles, [`EffectReport::sizes_m`] their spans, [`EffectReport::axes`] the direction
    /// to look through them from the lower side.
    pub fn arches(&mut self, s: &ArchSettings, region: &Region) -> Result<EffectReport> {
        self.check_lens(&named_fields!(s; span, thickness, max_length))?;
        if s.max_length < s.span {
            return Err(Error::param(
                "max_length",
                s.max_length,
                "must be at least the span",
            ));
        }
        region.check(&self.frame)?;
        // Ridges that could hold the smallest arch.
        let s_min = 0.35 * s.span;
        let bridge_min = (0.4 * s.thickness).max(1.0);
        let probe = ArchSettings { span: s_min, ..*s };
        let mut cands = self.arch_candidates(&probe, 0.35 * s_min + bridge_min, region);
        cands.sort_by(|x, y| {
            x.0.total_cmp(&y.0)
                .then(hash(s.seed, x.1, 2, 0).cmp(&hash(s.seed, y.1, 2, 0)))
        });
        let total = cands.len();
        let fits: Vec<(ArchFit, V3, V3, V3, u64)> = cands
            .par_iter()
            .filter_map(|&(_, idx, d, m0, m1)| {
                let mut span = arch_span(s.span, s.seed, idx);
                while span >= s_min {
                    if let Some(f) = self.arch_fits(s, span, idx, d, m0, m1) {
                        return Some((f, d, m0, m1, idx));
                    }
                    span *= 0.75;
                }
                None
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
            report.primitives += self.keep_fin(&arch, s.seed, idx)?;
            report.features += 1;
            report.length_m += norm(sub(m1, m0));
            report.sizes_m.push(arch.span);
            let c = arch.centre;
            report.sites.push([c[0], c[1], c[2] + 0.5 * arch.rise]);
            // Look through the opening from the lower side.
            let look = if m0[2] <= m1[2] { d } else { mul(d, -1.0) };
            report.axes.push(look);
        }
        Ok(report)
    }

    /// The arch of `span` a ridge between the mouths `m0`, `m1` (across it along `d`) holds
    /// ([module docs](self)), if any.
    fn arch_fits(
        &self,
        s: &ArchSettings,
        span: f32,
        idx: u64,
        d: V3,
        m0: V3,
        m1: V3,
    ) -> Option<ArchFit> {
        let lowest = m0[2].max(m1[2]);
        let mid = mul(add(m0, m1), 0.5);
        let side = [-d[1], d[0], 0.0];
        let fin = s.thickness * (0.8 + 0.4 * unit(hash(s.seed, idx, 0x0066_696e, 0)));
        let half_gap = 0.75 * span + 1.2 * s.thickness;
        let fr = self.frame;
        let (xm, ym) = (
            (fr.width - 1) as f32 * fr.cx,
            (fr.height - 1) as f32 * fr.cy,
        );
        let inside = |p: V3| p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= xm && p[1] <= ym;
        let reach = 1.3 * half_gap + fin;
        if ![-1.0f32, 1.0]
            .iter()
            .all(|&u| inside(add(mid, mul(side, u * reach))))
        {
            return None;
        }
        let ground = |u: f32| {
            let p = add(mid, mul(side, u));
            self.ground(p[0], p[1])
        };
        // The ridge's crest over the opening, which must keep the bridge over the bed.
        let bridge = (0.4 * s.thickness).max(1.0);
        let crest = (-8..=8)
            .map(|q| ground(q as f32 / 8.0 * 0.5 * span))
            .fold(f32::INFINITY, f32::min);
        // The bridge bed: the lowest soft-to-resistant transition at least 0.35 span over the
        // mouths' ground, with the crest a bridge over it and the legs standing up to it.
        let rho = |z: f32| self.geology.resistance([mid[0], mid[1], z]);
        let dz = span / 64.0;
        let (z_lo, z_hi) = (lowest + 0.35 * span, crest - bridge);
        let n = (((z_hi - z_lo) / dz).ceil().max(0.0) as usize).min(1024);
        let bed = (0..n).map(|k| z_lo + k as f32 * dz).find(|&z| {
            rho(z - 0.5 * dz) < 0.5
                && rho(z + 0.5 * dz) >= 0.55
                && (0..=4).all(|q| {
                    let u = 0.5 * span + q as f32 / 4.0 * (half_gap - 0.5 * span);
                    ground(u) >= z && ground(-u) >= z
                })
        })?;
        let rise = (bed - lowest).min(0.6 * span);
        Some(ArchFit {
            centre: [mid[0], mid[1], bed - rise],
            side,
            across: d,
            span,
            rise,
            fin,
            half_gap,
        })
    }

    /// The arch left standing in the gap ([module docs](self)): a rib swept along a
    /// half-superellipse from one foot over the opening to the other, its underside at the
    /// roof, its crown as thick as the resistant bed over the roof (within `[0.15, 0.35]
    /// span`), thickening to the legs, narrower in soft strata, as deep across as the fin,
    /// warped by noise. Returns the primitives.
    fn keep_fin(&mut self, f: &ArchFit, seed: u64, idx: u64) -> Result<usize> {
        let h = |c: u64, m: u64| unit(hash(seed, idx, m, 0x6f70_656e + c));
        let at = |u: f32, v: f32, z: f32| {
            let p = add(add(f.centre, mul(f.side, u)), mul(f.across, v));
            [p[0], p[1], z]
        };
        let floor = f.centre[2];
        let roof = floor + f.rise;
        let rho = |u: f32, z: f32| self.geology.resistance(at(u, 0.0, z));
        // The bridge: the resistant rock over the roof.
        let dz = f.span / 64.0;
        let bed = (0..64)
            .map(|k| k as f32 * dz)
            .take_while(|&z| rho(0.0, roof + z + 0.5 * dz) >= 0.55)
            .count() as f32
            * dz;
        let bridge = bed.clamp(0.15 * f.span, 0.35 * f.span).max(1.0);
        let (r_crown, r_leg) = (0.5 * bridge, 0.6 * f.fin + 0.15 * f.span);
        // Centre line: a half-superellipse (exponent 2.5) of half-width `a`, crown `hc` over
        // the floor; its feet `0.3 r_leg` under the floor.
        let (a, hc) = (0.5 * f.span + r_leg, f.rise + r_crown);
        let n = 24usize;
        let e = 2.5f32;
        let line: Vec<(f32, f32, f32)> = (0..=n)
            .map(|k| {
                let phi = std::f32::consts::PI * k as f32 / n as f32;
                let (c, sn) = (phi.cos(), phi.sin());
                let u = -a * c.signum() * c.abs().powf(2.0 / e);
                let z = floor - 0.3 * r_leg + (hc + 0.3 * r_leg) * sn.abs().powf(2.0 / e);
                let w = c * c;
                let r = (r_crown + (r_leg - r_crown) * w)
                    * (0.85 + 0.3 * rho(u, z))
                    * (0.9 + 0.2 * h(0, k as u64));
                (u, z, r)
            })
            .collect();
        let mut parts = Vec::with_capacity(n);
        for w in line.windows(2) {
            let ((u0, z0, r0), (u1, z1, r1)) = (w[0], w[1]);
            let (p, q) = (at(u0, 0.0, z0), at(u1, 0.0, z1));
            parts.push(self.tree.cone(p, q, r0 / VISIBLE, r1 / VISIBLE, 1.0)?);
        }
        let rib = self.tree.union_all(&parts)?;
        // Cut to the fin: rows of capsules along the ridge, `fin` thick, recessed in soft
        // strata and standing out at hard beds (`0.6 + 0.6 rho`): flat, ledged faces.
        let (len, top) = (a + r_leg, floor + hc + r_crown + r_leg);
        let step = 0.3 * f.fin;
        let rows = (((top - floor + f.fin) / step).ceil() as usize).clamp(2, 256);
        let mut wall_rows = Vec::with_capacity(rows + 1);
        for k in 0..=rows {
            let z = floor - f.fin + k as f32 * step;
            let r = 0.5 * f.fin * (0.6 + 0.6 * rho(0.0, z));
            wall_rows.push(self.tree.capsule(
                at(-len, 0.0, z),
                at(len, 0.0, z),
                r / VISIBLE,
                1.0,
            )?);
        }
        let wall = self.tree.union_all(&wall_rows)?;
        let rib = self.tree.intersection(rib, wall)?;
        let (rib, wings) = match self.fin_wings(f, a, r_crown)? {
            Some((w, n)) => (self.tree.union(rib, w)?, n),
            None => (rib, 0),
        };
        let s32 = (seed as u32).wrapping_add(idx as u32);
        let rib = self
            .tree
            .warp(rib, 0.12 * r_leg, 1.0 / (1.5 * r_leg), s32 ^ 0x5eed)?;
        self.positives.push(rib);
        self.carved
            .push((at(0.0, 0.0, floor + 0.5 * f.rise), 0.5 * f.rise, false));
        Ok(parts.len() + wall_rows.len() + wings)
    }

    /// The fin the arch was cut from, left standing on the ridge beyond each leg: a wall
    /// `fin` thick (recessed in soft strata, `0.6 + 0.6 rho`) along the ridge for 1.5 spans
    /// past the leg (at `a` from the centre), its top falling from the bridge's top at the
    /// leg to half a bridge over the ridge's ground at the far end (slowly at first), in
    /// steps (each row of rock stops where the top falls below it), so the arch is a window
    /// in a rock fin, not a loaf alone on a hill. Returns the wings and their primitive count
    /// (`None` where no row stands).
    fn fin_wings(&mut self, f: &ArchFit, a: f32, r_crown: f32) -> Result<Option<(NodeId, usize)>> {
        let floor = f.centre[2];
        let crown = floor + f.rise + 2.0 * r_crown;
        let at = |u: f32, z: f32| {
            let p = add(f.centre, mul(f.side, u));
            [p[0], p[1], z]
        };
        let len = 1.5 * f.span;
        let n = 24usize;
        let step = 0.3 * f.fin;
        // Rows as (from, to, radius), laid out before the tree is touched.
        let mut lines: Vec<(V3, V3, f32)> = Vec::new();
        for sign in [-1.0f32, 1.0] {
            let u_at = |k: usize| sign * (a + len * k as f32 / n as f32);
            let ground: Vec<f32> = (0..=n)
                .map(|k| {
                    let p = at(u_at(k), 0.0);
                    self.ground(p[0], p[1])
                })
                .collect();
            // The wing's top: from the bridge's top at the leg down to half a bridge over
            // the ground at the far end.
            let tops: Vec<f32> = ground
                .iter()
                .enumerate()
                .map(|(k, &g)| {
                    let t = (k as f32 / n as f32).powi(2);
                    (crown + (g + r_crown - crown) * t).max(g + r_crown * (1.0 - t))
                })
                .collect();
            let lowest = ground.iter().fold(floor, |m, &g| m.min(g));
            let mut z = lowest - f.fin;
            while z <= crown && lines.len() < 512 {
                let rho = self.geology.resistance(at(u_at(0), z));
                let r = 0.5 * f.fin * (0.6 + 0.6 * rho);
                // The row reaches out to the last sample whose top stands over its rock
                // (flush tops).
                let reach = tops.iter().take_while(|&&t| t >= z + r).count();
                if reach >= 2 {
                    lines.push((at(u_at(0), z), at(u_at(reach - 1), z), r));
                }
                z += step;
            }
        }
        if lines.is_empty() {
            return Ok(None);
        }
        let mut rows = Vec::with_capacity(lines.len());
        for (p, q, r) in lines {
            rows.push(self.tree.capsule(p, q, r / VISIBLE, 1.0)?);
        }
        let count = rows.len();
        Ok(Some((self.tree.union_all(&rows)?, count)))
    }

    /// The gap through the ridge around an arch: negative capsules along `d` from beyond
    /// one mouth to beyond the other, three side by side at the floor (a flat bottom about
    /// `2 half_gap` wide along the ridge), then wider ones stacked up to the highest ground
    /// over the gap (walls flaring outwards), warped. Returns the primitives.
    fn carve_gap(&mut self, f: &ArchFit, d: V3, m0: V3, m1: V3, seed: u32) -> Result<usize> {
        // Saturated rock (field 2T) loses 0.76 of the support radius at this energy.
        let energy = 20.0 * THRESHOLD;
        let hole = |r: f32| r / 0.76;
        let w = f.half_gap;
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

    /// Arch candidates, one per DEM node whose ridge is thin enough in some direction: (gap
    /// length, node index, direction, the two mouths).
    /// The ridge must drop `need` metres on both sides.
    fn arch_candidates(
        &self,
        s: &ArchSettings,
        need: f32,
        region: &Region,
    ) -> Vec<(f32, u64, V3, V3, V3)> {
        let f = self.frame;
        let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
        let a = 0.5 * s.span;
        let stride = self.site_stride;
        let step = (0.25 * stride as f32 * f.cx.min(f.cy)).min(0.5 * a);
        let half = 0.5 * s.max_length;
        let margin = a;
        // Candidates: (fin width, node index, direction index, mouths, floor).
        let nodes: Vec<(usize, usize)> = (0..f.height)
            .step_by(stride)
            .flat_map(|i| (0..f.width).step_by(stride).map(move |j| (j, i)))
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
                                // On down to the foot of the slope.
                                let mut foot = [q[0], q[1], g];
                                while t + step <= half {
                                    let q = add(c, mul(d, sign * (t + step)));
                                    let inside = q[0] >= 0.0 && q[1] >= 0.0;
                                    if !(inside && q[0] <= xm && q[1] <= ym) {
                                        break;
                                    }
                                    let g = me.ground(q[0], q[1]);
                                    if g >= foot[2] - 1e-3 {
                                        break;
                                    }
                                    foot = [q[0], q[1], g];
                                    t += step;
                                }
                                found = Some(foot);
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
                    if len < s.span.min(stride as f32 * f.cx.min(f.cy)) {
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
    use crate::geology::{Geology, test_beds};

    /// Strata from `z0`: 8 m soft (0.15) under 4 m resistant (0.85) beds.
    fn beds(z0: f32) -> Geology {
        test_beds(z0, (8.0, 0.15), (4.0, 0.85))
    }

    /// A north-south ridge 20 m wide and 30 m high on ground at 10 m, `geo`, one arch.
    fn ridge_arch(geo: Geology, seed: u64) -> (Scene, Scene, EffectReport) {
        let hf = Heightfield::from_fn(48, 48, 2.0, 2.0, |x, _| {
            if (x as f32 * 2.0 - 48.0).abs() <= 10.0 {
                40.0
            } else {
                10.0
            }
        });
        let mut b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
        let before = b.clone().build(true).unwrap();
        let s = ArchSettings {
            count: 1,
            span: 14.0,
            thickness: 6.0,
            max_length: 70.0,
            seed,
        };
        let rep = b.arches(&s, &Region::everywhere()).unwrap();
        assert_eq!(rep.features, 1, "{rep:?}");
        (before, b.build(true).unwrap(), rep)
    }

    /// Air cells of the vertical section through `site` along `side` (0.5 m cells, `u` in
    /// +-30 m, `z` from 4 m to 46 m) connected to the site's cell, and whether that air
    /// reaches the section's border (is open).
    fn opening(scene: &Scene, site: V3, side: V3) -> (usize, bool) {
        let (nu, nz) = (121usize, 85usize);
        let p = |i: usize, k: usize| {
            let u = (i as f32 - 60.0) * 0.5;
            [
                site[0] + side[0] * u,
                site[1] + side[1] * u,
                4.0 + k as f32 * 0.5,
            ]
        };
        let start = (60, ((site[2] - 4.0) / 0.5).round() as usize);
        relief_testdata::flood_fill(nu, nz, start, |i, k| !scene.inside(p(i, k)))
    }

    /// The arch is a fin left in a gap cut across the ridge, eroded through under the
    /// resistant bed: the opening's middle was rock and is air, the section along the fin
    /// shows that air enclosed (bridge above, legs beside, floor below), the roof is the
    /// bed's base (18 m; 21 m on strata 3 m higher), the rock before and behind the fin is
    /// cut away, and the opening is not symmetric (noise), the same for the same seed.
    #[test]
    fn arches_are_fins_eroded_through_under_a_resistant_bed() {
        let (before, scene, rep) = ridge_arch(beds(10.0), 3);
        let (site, axis) = (rep.sites[0], rep.axes[0]);
        assert!(
            axis[0].abs() > 0.9,
            "the opening crosses the ridge: {axis:?}"
        );
        assert!(before.inside(site) && !scene.inside(site), "{site:?}");
        let side = [-axis[1], axis[0], 0.0];
        let (air, open) = opening(&scene, site, side);
        assert!(air > 40 && !open, "enclosed air: {air} cells, open {open}");
        let roof = |scene: &Scene, site: V3| {
            (0..200)
                .map(|k| site[2] + k as f32 * 0.1)
                .find(|&z| scene.inside([site[0], site[1], z]))
                .unwrap()
        };
        let r = roof(&scene, site);
        assert!((r - 18.0).abs() < 1.5, "roof at {r} m, bed base at 18 m");
        for sign in [-1.0f32, 1.0] {
            let p = add([site[0], site[1], r + 1.0], mul(axis, sign * 9.0));
            assert!(
                before.inside(p) && !scene.inside(p),
                "the ridge is cut at {p:?}"
            );
        }
        let mirrored = (1..40)
            .flat_map(|i| (0..30).map(move |k| (i as f32 * 0.25, site[2] - 6.0 + k as f32 * 0.5)))
            .filter(|&(u, z)| {
                let at = |u: f32| [site[0] + side[0] * u, site[1] + side[1] * u, z];
                scene.inside(at(u)) != scene.inside(at(-u))
            })
            .count();
        assert!(mirrored > 10, "an irregular opening: {mirrored}");
        let (_, again, rep2) = ridge_arch(beds(10.0), 3);
        assert_eq!(rep, rep2);
        assert_eq!(opening(&again, site, side), (air, open));
        // The same ridge on strata 3 m higher: the roof follows the bed.
        let (_, shifted, rep3) = ridge_arch(beds(13.0), 3);
        let r3 = roof(&shifted, rep3.sites[0]);
        assert!((r3 - 21.0).abs() < 1.5, "roof at {r3} m, bed base at 21 m");
        // No ridge: no arch, no error.
        let flat = Heightfield::from_fn(20, 20, 5.0, 5.0, |_, _| 10.0);
        let mut b = SceneBuilder::new(&flat, beds(0.0), &ImplicitizeSettings::default()).unwrap();
        let s = ArchSettings {
            span: 14.0,
            thickness: 6.0,
            max_length: 70.0,
            ..Default::default()
        };
        assert_eq!(b.arches(&s, &Region::everywhere()).unwrap().features, 0);
    }

    /// The fin beyond the legs, on flat ground at 10 m (an arch whose ridge has worn down
    /// beside it): a wall on the fin's plane, a fin thick (air 6 m before and behind it),
    /// standing to the bridge's top next to the leg and falling towards the far end, never
    /// above the bridge.
    #[test]
    fn the_fin_continues_beyond_the_legs() {
        let hf = Heightfield::from_fn(80, 80, 2.0, 2.0, |_, _| 10.0);
        let mut b = SceneBuilder::new(&hf, beds(0.0), &ImplicitizeSettings::default()).unwrap();
        let f = ArchFit {
            centre: [80.0, 80.0, 10.0],
            side: [0.0, 1.0, 0.0],
            across: [1.0, 0.0, 0.0],
            span: 14.0,
            rise: 8.0,
            fin: 6.0,
            half_gap: 18.0,
        };
        let (a, r_crown) = (12.0, 1.5);
        let (wings, n) = b.fin_wings(&f, a, r_crown).unwrap().unwrap();
        assert!(n > 4, "{n} rows");
        let crown = 10.0 + 8.0 + 2.0 * r_crown;
        let rock = |x: f32, y: f32, z: f32| b.tree.eval(wings, [x, y, z]) >= crate::tree::THRESHOLD;
        // The highest rock on the fin's plane at `u` along it (`None`: none above ground).
        let top = |u: f32| {
            (0..300)
                .map(|k| crown + 3.0 - k as f32 * 0.05)
                .find(|&z| rock(80.0, 80.0 + u, z))
                .filter(|&z| z > 10.0)
        };
        for sign in [-1.0f32, 1.0] {
            let near = top(sign * (a + 1.0)).expect("rock next to the leg");
            let far = top(sign * (a + 1.2 * f.span)).unwrap_or(10.0);
            assert!(
                near > crown - 2.0 && near <= crown + 0.5,
                "{near} vs crown {crown}"
            );
            assert!(far < near - 4.0, "the top falls: {near} -> {far}");
            // A wall: rock on the plane, air a fin's thickness before and behind it.
            let u = 80.0 + sign * (a + 0.5 * f.span);
            assert!(rock(80.0, u, 12.0) && !rock(86.0, u, 12.0) && !rock(74.0, u, 12.0));
        }
        // Nothing on the opening's side of the legs.
        assert!(top(0.0).is_none() && top(0.5 * f.span - 1.0).is_none());
    }

    /// The arch stands free of the old crest: over the opening's middle the rock ends a
    /// bridge's thickness over the roof (at most 0.35 span and the warp; the ridge stood to
    /// 40 m), and the rock over the opening is thicker towards the legs than at the crown.
    #[test]
    fn the_bridge_is_thin_and_thickens_to_the_legs() {
        let (before, scene, rep) = ridge_arch(beds(10.0), 3);
        let (site, axis, span) = (rep.sites[0], rep.axes[0], rep.sizes_m[0]);
        let side = [-axis[1], axis[0], 0.0];
        let at = |u: f32, z: f32| [site[0] + side[0] * u, site[1] + side[1] * u, z];
        let top = |u: f32| {
            (0..450)
                .map(|k| 45.0 - k as f32 * 0.1)
                .find(|&z| scene.inside(at(u, z)))
                .unwrap_or(0.0)
        };
        let mid = top(0.0);
        assert!(before.inside(at(0.0, 39.0)), "the ridge stood to 40 m");
        assert!(
            mid > 19.0 && mid < 18.0 + 0.35 * span + 1.5,
            "bridge top {mid} m over a roof at 18 m (span {span} m)"
        );
        // Vertical thickness of the rock over the opening's mid-height at `u`.
        let thick = |u: f32| {
            let under = (0..300)
                .map(|k| site[2] + k as f32 * 0.1)
                .find(|&z| scene.inside(at(u, z)))
                .unwrap_or(45.0);
            top(u) - under
        };
        let crown = thick(0.0);
        for u in [-0.45 * span, 0.45 * span] {
            assert!(
                thick(u) > crown + 1.0,
                "the rib thickens: {} at {u}, {crown}",
                thick(u)
            );
        }
    }

    /// Spans are log-normal around the median: spread both ways, within the bounds.
    #[test]
    fn arch_spans_are_drawn_from_a_distribution() {
        let mut v: Vec<f32> = (0..2000).map(|k| arch_span(30.0, 9, k)).collect();
        v.sort_by(f32::total_cmp);
        let q = |t: f32| v[(t * (v.len() - 1) as f32) as usize];
        assert!((q(0.5) - 30.0).abs() < 2.0, "median {}", q(0.5));
        assert!(q(0.1) < 20.0 && q(0.9) > 45.0, "{} {}", q(0.1), q(0.9));
        assert!(v[0] >= 0.35 * 30.0 - 1e-4 && v[v.len() - 1] <= 90.0 + 1e-4);
        assert!(arch_span(100.0, 9, 1) <= 300.0 && arch_span(60.0, 1, 2) <= 120.0);
    }
}
