//! Floating islands (paper figure 4, right): a few large rock masses torn out of the relief,
//! in clusters, each with a flat-ish top that keeps a trace of the ground it came from and a
//! jagged underside tapering down like an inverted mountain, ledged by the strata.
//!
//! Placement ([`SceneBuilder::floating_islands`]):
//! * **cluster sites from the terrain**: candidate sites `2 radius` apart (Poisson, hashed
//!   order) are ranked by their local relief (highest minus lowest ground on rings of one and
//!   two radii): islands hang by cliffs, rims and peaks, not over the middle of a plain. The
//!   best-ranked sites at least `6 radius` apart become cluster seeds;
//! * **clustered growth**: each cluster's main island has a radius in `[0.8, 1.2] radius`;
//!   the others are budded off a random island already in the cluster, `(1 + 1.5 u^2)` times
//!   their radii sum away in a random direction (mostly close, sometimes far), with radii down to `main / spread`; a bud that
//!   overlaps an island or leaves the DEM is retried (12 tries). Nearest-neighbour spacing is
//!   therefore uneven (an even grid has a coefficient of variation of 0);
//! * **heights from the relief**: a cluster floats `altitude (0.8 + 0.4 u)` above its ground,
//!   each island a further `+-15 %`, and always clear of the highest ground under it by a
//!   quarter of `altitude` below its lowest tip.
//!
//! Shape of one island of radius `r` (visible, metres):
//! * top: 5 to 7 flattened lobes (ellipsoids 0.3 as thick as wide) scattered over the disc,
//!   their heights following the ground under them at 35 % (a flat-ish eroded top that still
//!   reads as the terrain it was torn from);
//! * underside: a main inverted cone to a tip `(1.1..1.8) r` down, off-centre, and three to six
//!   shorter secondary cones off the axis (a jagged, multi-tipped base), plus a stack of flat
//!   discs down the main axis whose radii follow the geology (hard strata stick out as
//!   ledges, soft strata are recessed, as on the hoodoos);
//! * three noise warps (wavelengths 1.3 r, 0.3 r and 0.12 r) make the outline irregular and
//!   the rock rough.

use super::*;
use relief_heightfield::param::in_range;

use crate::math::VISIBLE;

/// One island placed by [`SceneBuilder::floating_islands`]: centre of its top `(x, y, z)` and
/// visible radius.
#[derive(Debug, Clone, Copy)]
struct Island {
    top: V3,
    r: f32,
    /// Depth of its main tip below the top.
    depth: f32,
}

/// Horizontal distance (m) from each of `sites` to the nearest other one (infinite for a lone
/// site).
pub fn nearest_neighbour_distances(sites: &[V3]) -> Vec<f64> {
    sites
        .iter()
        .enumerate()
        .map(|(i, p)| {
            sites
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, q)| ((p[0] - q[0]) as f64).hypot((p[1] - q[1]) as f64))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// Coefficient of variation (standard deviation over mean) of the horizontal nearest-neighbour
/// distances of `sites`: 0 for an even grid, about 0.5 for a Poisson process, more for
/// clusters. `None` with fewer than two sites.
pub fn nearest_neighbour_cv(sites: &[V3]) -> Option<f32> {
    if sites.len() < 2 {
        return None;
    }
    let d = nearest_neighbour_distances(sites);
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    (mean > 0.0).then(|| (var.sqrt() / mean) as f32)
}

/// Clark-Evans ratio of `sites` spread over `area_m2`: their mean nearest-neighbour distance
/// over that of a Poisson process of the same density (1 random, < 1 clustered, > 1 regular).
/// `None` with fewer than two sites.
pub fn clark_evans(sites: &[V3], area_m2: f64) -> Option<f32> {
    if sites.len() < 2 {
        return None;
    }
    let d = nearest_neighbour_distances(sites);
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    Some((mean / (0.5 / (n / area_m2).sqrt())) as f32)
}

impl SceneBuilder {
    /// Floating islands ([module docs](self)): clusters grown from high-relief sites, each
    /// island a lobed flat-ish top over a jagged, strata-ledged inverted mountain, warped.
    /// [`EffectReport::sites`] are the tops' centres, [`EffectReport::sizes_m`] the radii and
    /// [`EffectReport::axes`] the directions of the lowest ground around them (where to look
    /// from to see the underside).
    pub fn floating_islands(
        &mut self,
        s: &IslandSettings,
        region: &Region,
    ) -> Result<EffectReport> {
        self.check_len("radius", s.radius)?;
        self.check_len("altitude", s.altitude)?;
        in_range("per_cluster", s.per_cluster, 1..=16, "must be in 1..=16")?;
        in_range("spread", s.spread, 1.0..=10.0, "must be in [1, 10]")?;
        region.check(&self.frame)?;
        let (islands, candidates) = self.island_sites(s, region);
        let mut report = EffectReport {
            candidates,
            ..Default::default()
        };
        for (k, isl) in islands.iter().enumerate() {
            report.primitives += self.island(isl, s.seed, k as u64)?;
            report.features += 1;
            report.sites.push(isl.top);
            report.sizes_m.push(isl.r);
            // Seen from the lowest ground around it: the underside against the sky.
            report.axes.push(self.lowest_side(isl.top, 3.0 * isl.r));
        }
        Ok(report)
    }

    /// Highest minus lowest ground over the centre and two rings (radii `r`, `2 r`).
    fn local_relief(&self, p: V3, r: f32) -> f32 {
        let (mut lo, mut hi) = (p[2], p[2]);
        for ring in [r, 2.0 * r] {
            for k in 0..12 {
                let a = k as f32 * std::f32::consts::TAU / 12.0;
                let g = self.ground_clamped(p[0] + ring * a.cos(), p[1] + ring * a.sin());
                (lo, hi) = (lo.min(g), hi.max(g));
            }
        }
        hi - lo
    }

    /// The horizontal direction (one of eight) in which the ground `reach` metres from `p`
    /// is lowest (the first on ties; east without a DEM): where a close-up looks from to see
    /// a feature against open space (an island's underside, a cliff from the sea).
    pub(super) fn lowest_side(&self, p: V3, reach: f32) -> V3 {
        (0..8)
            .map(|m| {
                let a = m as f32 * std::f32::consts::TAU / 8.0;
                let d = [a.cos(), a.sin(), 0.0];
                let q = add(p, mul(d, reach));
                (self.ground_clamped(q[0], q[1]), m, d)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
            .map_or([1.0, 0.0, 0.0], |x| x.2)
    }

    /// Ground height at `(x, y)` clamped into the DEM.
    fn ground_clamped(&self, x: f32, y: f32) -> f32 {
        let f = self.frame;
        let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
        self.ground(x.clamp(0.0, xm), y.clamp(0.0, ym))
    }

    /// Highest ground within `r` of `(x, y)` (centre and two rings).
    fn ground_max(&self, x: f32, y: f32, r: f32) -> f32 {
        self.ground_over(x, y, r, f32::max)
    }

    /// Lowest ground within `r` of `(x, y)` (centre and two rings).
    pub(super) fn ground_min(&self, x: f32, y: f32, r: f32) -> f32 {
        self.ground_over(x, y, r, f32::min)
    }

    /// `pick` folded over the ground at `(x, y)` and on two rings of 12 points, at `r / 2` and
    /// `r`.
    fn ground_over(&self, x: f32, y: f32, r: f32, pick: fn(f32, f32) -> f32) -> f32 {
        let mut v = self.ground_clamped(x, y);
        for ring in [0.5 * r, r] {
            for k in 0..12 {
                let a = k as f32 * std::f32::consts::TAU / 12.0;
                v = pick(
                    v,
                    self.ground_clamped(x + ring * a.cos(), y + ring * a.sin()),
                );
            }
        }
        v
    }

    /// The islands' positions, radii and heights, and the number of candidate sites.
    fn island_sites(&self, s: &IslandSettings, region: &Region) -> (Vec<Island>, usize) {
        let f = self.frame;
        let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
        let u = |a: u64, b: u64| unit(hash(s.seed, a, b, 0x1517));
        // Candidate cluster seeds, ranked by local relief (hash order breaks ties).
        let margin = 1.2 * s.radius;
        let mut cands = Vec::new();
        for i in 0..f.height {
            for j in 0..f.width {
                let p = f.node(j, i, self.dem_at(j, i));
                let inside =
                    p[0] >= margin && p[1] >= margin && p[0] <= xm - margin && p[1] <= ym - margin;
                if inside && region.weight(&f, p) > 0.0 {
                    cands.push((hash(s.seed, (i * f.width + j) as u64, 0, 0), p));
                }
            }
        }
        cands.sort_by_key(|x| x.0);
        let pts: Vec<V3> = cands.iter().map(|x| [x.1[0], x.1[1], 0.0]).collect();
        let kept = poisson_filter(&pts, 2.0 * s.radius, |_| true);
        let mut ranked: Vec<(f32, V3)> = kept
            .iter()
            .map(|&k| (self.local_relief(cands[k].1, s.radius), cands[k].1))
            .collect();
        ranked.sort_by(|a, b| b.0.total_cmp(&a.0));
        let seeds: Vec<V3> = ranked.iter().map(|x| [x.1[0], x.1[1], 0.0]).collect();
        let seeds: Vec<V3> = poisson_filter(&seeds, 6.0 * s.radius, |_| true)
            .into_iter()
            .map(|k| ranked[k].1)
            .collect();
        let candidates = ranked.len();
        let clusters = s.count.div_ceil(s.per_cluster);
        let mut out: Vec<Island> = Vec::new();
        for (c, &p) in seeds.iter().take(clusters).enumerate() {
            let c = c as u64;
            let lift = s.altitude * (0.8 + 0.4 * u(c, 0));
            let main = s.radius * (0.8 + 0.4 * u(c, 1));
            let first = out.len();
            out.push(self.island_at(p, main, lift, u(c, 2)));
            let want = s.per_cluster.min(s.count - first);
            let mut tries = 0u64;
            while out.len() - first < want && tries < 12 * want as u64 {
                tries += 1;
                let h = |k: u64| u(c, 16 + 8 * tries + k);
                let parent = out[first
                    + ((h(0) * (out.len() - first) as f32) as usize).min(out.len() - first - 1)];
                let r = main * s.spread.powf(-h(1));
                let a = h(2) * std::f32::consts::TAU;
                let d = (parent.r + r) * (1.0 + 1.5 * h(3) * h(3));
                let q = [parent.top[0] + d * a.cos(), parent.top[1] + d * a.sin()];
                let m = 1.2 * r;
                if q[0] < m || q[1] < m || q[0] > xm - m || q[1] > ym - m {
                    continue;
                }
                let g = [q[0], q[1], self.ground(q[0], q[1])];
                if region.weight(&f, g) <= 0.0
                    || out
                        .iter()
                        .any(|o| (o.top[0] - q[0]).hypot(o.top[1] - q[1]) < 0.95 * (o.r + r))
                {
                    continue;
                }
                let l = lift * (0.85 + 0.3 * h(4));
                out.push(self.island_at(g, r, l, h(5)));
            }
        }
        (out, candidates)
    }

    /// An island of radius `r` over ground point `g`, its top `lift` above the ground and
    /// clear of the highest ground under it; `u` in `[0, 1)` sets its depth.
    fn island_at(&self, g: V3, r: f32, lift: f32, u: f32) -> Island {
        let depth = r * (1.1 + 0.7 * u);
        let hi = self.ground_max(g[0], g[1], 1.2 * r);
        let z = (g[2] + lift).max(hi + depth + 0.25 * lift);
        Island {
            top: [g[0], g[1], z],
            r,
            depth,
        }
    }

    /// Adds one island's primitives (module docs); returns how many.
    fn island(&mut self, isl: &Island, seed: u64, k: u64) -> Result<usize> {
        let h = |a: u64, b: u64| unit(hash(seed, k, a, 0x1518 + b));
        let (c, r) = (isl.top, isl.r);
        // The ground under the centre: lobes follow the ground's shape at 35 %.
        let g0 = self.ground_clamped(c[0], c[1]);
        let mut parts = Vec::new();
        let lobes = 5 + (h(0, 0) * 3.0) as usize;
        for m in 0..lobes as u64 {
            let (dist, rl) = if m == 0 {
                (0.0, 0.8 * r)
            } else {
                (r * (0.3 + 0.35 * h(m, 1)), r * (0.45 + 0.2 * h(m, 2)))
            };
            let a = (m as f32 + 0.6 * h(m, 3)) * std::f32::consts::TAU / (lobes - 1).max(1) as f32;
            let (x, y) = (c[0] + dist * a.cos(), c[1] + dist * a.sin());
            let dz = (0.35 * (self.ground_clamped(x, y) - g0)).clamp(-0.3 * r, 0.3 * r);
            // Tall lobes (steep sides), cut flat by the cap below.
            let ax = [1.5 * rl * (0.85 + 0.3 * h(m, 4)), 1.5 * rl, 0.9 * rl];
            parts.push(
                self.tree
                    .ellipsoid([x, y, c[2] + dz - 0.35 * rl], ax, 1.0)?,
            );
        }
        // The main inverted cone, its tip off-centre.
        let tip = [
            c[0] + (h(20, 0) - 0.5) * 0.4 * r,
            c[1] + (h(20, 1) - 0.5) * 0.4 * r,
            c[2] - isl.depth,
        ];
        parts.push(
            self.tree
                .cone([c[0], c[1], c[2] - 0.15 * r], tip, 1.1 * r, 0.1 * r, 1.5)?,
        );
        // Secondary cones: shorter, off the axis, leaning outwards.
        let n2 = 3 + (h(21, 0) * 4.0) as u64;
        for m in 0..n2 {
            let a = (m as f32 + h(30 + m, 0)) * std::f32::consts::TAU / n2 as f32;
            let (ca, sa) = (a.cos(), a.sin());
            let o = r * (0.35 + 0.25 * h(30 + m, 1));
            let d = isl.depth * (0.3 + 0.5 * h(30 + m, 2));
            let top = [c[0] + o * ca, c[1] + o * sa, c[2] - 0.2 * r];
            let tip = [
                c[0] + 1.15 * o * ca,
                c[1] + 1.15 * o * sa,
                c[2] - 0.2 * r - d,
            ];
            parts.push(self.tree.cone(top, tip, 0.55 * r, 0.06 * r, 1.2)?);
        }
        // Strata ledges down the main axis: flat discs, wide in hard rock (a ledge sticking
        // out of the underside), narrow in soft rock (recessed), so the underside is terraced
        // by the geology rather than one smooth cone.
        let n = ((isl.depth / (0.2 * r)).ceil() as usize).clamp(4, 24);
        let gap = 0.8 * isl.depth / n as f32;
        for m in 0..n {
            let t = (m as f32 + 0.5) / n as f32 * 0.8;
            let p = add(add(c, [0.0, 0.0, -0.15 * r]), mul(sub(tip, c), t));
            let rho = self.geology.resistance(p);
            let rr = r * (1.0 - t) * (0.35 + 0.75 * rho) * (0.9 + 0.2 * h(40 + m as u64, 0));
            if rr > 0.05 * r {
                let ax = [
                    1.6 * rr,
                    1.6 * rr * (0.8 + 0.4 * h(40 + m as u64, 1)),
                    1.2 * gap,
                ];
                parts.push(self.tree.ellipsoid(p, ax, 1.0)?);
            }
        }
        let n_parts = parts.len() + 1;
        let body = self.tree.blend(&parts)?;
        // The flat-ish top: the body cut by a wide flat ellipsoid whose surface passes
        // through the top (visible semi-axes 0.454 of the support at energy 1), 10 radii wide
        // so that it drops under 0.1 r over the island.
        let hz = 3.0 * r;
        let cap = self.tree.ellipsoid(
            [c[0], c[1], c[2] + 0.05 * r - hz],
            [10.0 * r, 10.0 * r, hz / VISIBLE],
            1.0,
        )?;
        let b = self.tree.intersection(body, cap)?;
        let seed32 = (seed as u32).wrapping_add(k as u32 * 0x9e37);
        let w = self.tree.warp(b, 0.08 * r, 1.0 / (0.3 * r), seed32)?;
        let w = self
            .tree
            .warp(w, 0.2 * r, 1.0 / (1.3 * r), seed32 ^ 0x5bd1)?;
        // Ledges of the hard beds, added after the large warps (which move rock by up to a
        // fifth of the radius, in height too) so they stay at the beds' elevations.
        let w = match self.island_ledges(w, c, tip, r)? {
            Some(l) => self.tree.union(w, l)?,
            None => w,
        };
        // Rock roughness at a tenth of the radius.
        let w = self
            .tree
            .warp(w, 0.035 * r, 1.0 / (0.12 * r), seed32 ^ 0x2c4f)?;
        self.positives.push(w);
        Ok(n_parts)
    }

    /// The hard beds the underside of an island (top centre `c`, tip `tip`, radius `r`)
    /// crosses, as ledges: flat discs as thick as each run of resistant rock (`rho >= 0.5`)
    /// along the axis and wider than the body there, by more the harder the bed (at most 24,
    /// the thickest). A ledge stands out of the `body` by `(0.04 + 0.1 rho) r` beyond its
    /// mean radius at that height (measured on the body, along eight directions).
    fn island_ledges(&mut self, body: NodeId, c: V3, tip: V3, r: f32) -> Result<Option<NodeId>> {
        let top = add(c, [0.0, 0.0, -0.15 * r]);
        let axis = sub(tip, top);
        let steps = 160usize;
        let at = |k: usize| add(top, mul(axis, 0.8 * k as f32 / steps as f32));
        let rho: Vec<f32> = (0..=steps)
            .map(|k| self.geology.resistance(at(k)))
            .collect();
        // Runs of hard rock: (first, last) samples.
        let mut runs: Vec<(usize, usize)> = Vec::new();
        let mut start = None;
        for (k, &v) in rho.iter().enumerate() {
            match (v >= 0.5, start) {
                (true, None) => start = Some(k),
                (false, Some(s0)) => {
                    runs.push((s0, k - 1));
                    start = None;
                }
                _ => {}
            }
        }
        if let Some(s0) = start {
            runs.push((s0, steps));
        }
        runs.sort_by_key(|&(a, b)| std::cmp::Reverse(b - a));
        runs.truncate(24);
        let dz = 0.8 * axis[2].abs() / steps as f32;
        let mut discs = Vec::new();
        for (a, b) in runs {
            let (pa, pb) = (at(a), at(b));
            let mid = mul(add(pa, pb), 0.5);
            let hard = rho[a..=b].iter().fold(0.0f32, |m, &v| m.max(v));
            // Where the warps moved the body off the axis there is nothing to stand out of
            // (a disc there would float free).
            let body_r = self.body_radius(body, mid, 2.0 * r);
            let radius = body_r + (0.04 + 0.1 * hard) * r;
            let half = 0.5 * ((b - a + 1) as f32 * dz);
            if body_r > 0.05 * r {
                discs.push(self.tree.ellipsoid(
                    mid,
                    [radius / VISIBLE, radius / VISIBLE, half / VISIBLE],
                    1.0,
                )?);
            }
        }
        if discs.is_empty() {
            return Ok(None);
        }
        Ok(Some(self.tree.union_all(&discs)?))
    }

    /// Mean distance from `p` to the surface of `body` along eight horizontal directions
    /// (bisection within `max`; 0 where `p` is outside).
    fn body_radius(&self, body: NodeId, p: V3, max: f32) -> f32 {
        let inside = |q: V3| self.tree.eval(body, q) >= crate::tree::THRESHOLD;
        if !inside(p) {
            return 0.0;
        }
        let mut sum = 0.0;
        for k in 0..8 {
            let a = k as f32 * std::f32::consts::FRAC_PI_4;
            let d = [a.cos(), a.sin(), 0.0];
            let (mut lo, mut hi) = (0.0, max);
            for _ in 0..12 {
                let m = 0.5 * (lo + hi);
                if inside(add(p, mul(d, m))) {
                    lo = m;
                } else {
                    hi = m;
                }
            }
            sum += lo;
        }
        sum / 8.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plain at 100 m west of x = 600 m and a plateau at 400 m east of it (a cliff along
    /// x = 600 m), 1.2 km square, 20 m cells.
    fn cliff_scene() -> SceneBuilder {
        let hf = Heightfield::from_fn(61, 61, 20.0, 20.0, |x, _| {
            let t = ((x as f32 * 20.0 - 600.0) / 40.0).clamp(-1.0, 1.0);
            250.0 + 150.0 * t
        });
        // Alternating beds (a soft 12 m, a hard 8 m): the ledges the underside test looks for.
        let geo = crate::geology::test_beds(250.0, (12.0, 0.15), (8.0, 0.8));
        SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap()
    }

    /// The scene of one island (seed 2) over [`cliff_scene`], its top's centre and radius.
    fn one_island() -> (Scene, V3, f32) {
        let mut b = cliff_scene();
        let rep = b
            .floating_islands(&islands(1, 2), &Region::everywhere())
            .unwrap();
        let (c, r) = (rep.sites[0], rep.sizes_m[0]);
        (b.build(true).unwrap(), c, r)
    }

    /// `count` islands of 60 m radius 150 m over the ground of [`cliff_scene`], from `seed`.
    fn islands(count: usize, seed: u64) -> IslandSettings {
        IslandSettings {
            count,
            radius: 60.0,
            altitude: 150.0,
            seed,
            ..Default::default()
        }
    }

    #[test]
    fn islands_cluster_by_the_cliff_with_varied_sizes() {
        let mut b = cliff_scene();
        let s = IslandSettings {
            per_cluster: 3,
            spread: 3.0,
            ..islands(6, 4)
        };
        let rep = b.floating_islands(&s, &Region::everywhere()).unwrap();
        assert_eq!(rep.features, 6, "{rep:?}");
        assert_eq!(rep.sizes_m.len(), 6);
        let (lo, hi) = rep
            .sizes_m
            .iter()
            .fold((f32::INFINITY, 0.0f32), |(a, b), &x| (a.min(x), b.max(x)));
        assert!(
            hi / lo > 1.5 && lo >= 20.0 && hi <= 72.0,
            "{:?}",
            rep.sizes_m
        );
        // Clusters: every island has a neighbour within 2.5 times their radii sum, and the
        // main islands (first of each cluster) hang within three radii of the cliff.
        for (i, p) in rep.sites.iter().enumerate() {
            let near = rep.sites.iter().enumerate().any(|(j, q)| {
                j != i
                    && (p[0] - q[0]).hypot(p[1] - q[1]) <= 2.51 * (rep.sizes_m[i] + rep.sizes_m[j])
            });
            assert!(
                near,
                "island {i} is alone: {:?} {:?}",
                rep.sites, rep.sizes_m
            );
        }
        for k in [0, 3] {
            assert!((rep.sites[k][0] - 600.0).abs() < 180.0, "{:?}", rep.sites);
        }
        // Not an even spread: the nearest-neighbour spacing varies.
        assert!(nearest_neighbour_cv(&rep.sites).unwrap() > 0.05);
        // Determinism.
        let rep2 = cliff_scene()
            .floating_islands(&s, &Region::everywhere())
            .unwrap();
        assert_eq!(rep, rep2);
    }

    #[test]
    fn an_island_has_a_flat_top_and_a_tapering_underside_clear_of_the_ground() {
        let (scene, c, r) = one_island();
        // Share of rock on a horizontal disc of radius 1.5 r at height z.
        let solid = |z: f32| {
            let mut n = 0;
            for i in -12..=12 {
                for j in -12..=12 {
                    let (x, y) = (c[0] + 0.125 * r * j as f32, c[1] + 0.125 * r * i as f32);
                    n += usize::from(scene.inside([x, y, z]));
                }
            }
            n as f32 / 625.0
        };
        let (top, mid, low) = (
            solid(c[2] - 0.2 * r),
            solid(c[2] - 0.7 * r),
            solid(c[2] - r),
        );
        assert!(
            top > 0.2 && mid < 0.8 * top && low < 0.6 * top,
            "{top} {mid} {low}"
        );
        // Flat top: rock just under it over the middle of the disc, air just over it.
        for (dx, dy) in [(0.0, 0.0), (0.3, 0.0), (-0.3, 0.1), (0.0, -0.3), (0.1, 0.3)] {
            let (x, y) = (c[0] + dx * r, c[1] + dy * r);
            assert!(scene.inside([x, y, c[2] - 0.3 * r]), "{dx} {dy}");
            assert!(!scene.inside([x, y, c[2] + 0.3 * r]), "{dx} {dy}");
        }
        // Air between the island and the ground.
        let g = b_ground(&scene, c);
        assert!(c[2] - 2.0 * r > g, "{c:?} over {g}");
        for k in 1..10 {
            let z = g + 0.5 + k as f32 * 0.1 * (c[2] - 2.0 * r - g);
            assert!(!scene.inside([c[0], c[1], z]), "rock at {z}");
        }
    }

    /// The underside is terraced by the strata: after removing the taper (a linear trend),
    /// the rock share of horizontal discs through the underside follows the resistance of
    /// the rock at that height (hard strata stick out as ledges, soft ones are recessed).
    #[test]
    fn an_island_underside_is_ledged_by_the_strata() {
        let (scene, c, r) = one_island();
        let (mut share, mut rho, mut zs) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..48 {
            let z = c[2] - 0.2 * r - k as f32 * 0.02 * r;
            let mut n = 0;
            for i in -16..=16 {
                for j in -16..=16 {
                    let (x, y) = (c[0] + 0.1 * r * j as f32, c[1] + 0.1 * r * i as f32);
                    n += usize::from(scene.inside([x, y, z]));
                }
            }
            share.push(n as f64);
            rho.push(f64::from(scene.resistance([c[0], c[1], z])));
            zs.push(f64::from(z));
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        // The taper is not linear (the body's cone rounds off under the top): detrend by the
        // running mean over +-8 discs (+-0.16 r), so what is left is the ledging.
        let resid: Vec<f64> = (0..share.len())
            .map(|k| {
                let w = &share[k.saturating_sub(8)..(k + 9).min(share.len())];
                share[k] - mean(w)
            })
            .collect();
        let mr = mean(&rho);
        let cov: f64 = resid.iter().zip(&rho).map(|(a, b)| a * (b - mr)).sum();
        let corr = cov
            / (resid.iter().map(|a| a * a).sum::<f64>().sqrt()
                * rho.iter().map(|b| (b - mr).powi(2)).sum::<f64>().sqrt());
        // 0.55-0.65 on beds of 3 to 12 m; before the ledges were added after the warps,
        // -0.2 to 0.3 (the warps moved the discs off their beds).
        assert!(corr > 0.45, "{corr}");
    }

    fn b_ground(scene: &Scene, c: V3) -> f32 {
        scene.dem_height(c[0], c[1]).unwrap()
    }

    #[test]
    fn nn_cv_and_clark_evans_tell_a_grid_from_clusters() {
        let grid: Vec<V3> = (0..16)
            .map(|k| [(k % 4) as f32 * 10.0, (k / 4) as f32 * 10.0, 0.0])
            .collect();
        assert!(nearest_neighbour_cv(&grid).unwrap() < 1e-6);
        let clusters = [
            [0.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [100.0, 0.0, 0.0],
            [108.0, 0.0, 0.0],
            [100.0, 20.0, 0.0],
        ];
        assert!(nearest_neighbour_cv(&clusters).unwrap() > 0.3);
        // Clark-Evans: the 4 x 4 grid of spacing 10 on 40 x 40 m is twice as regular as a
        // Poisson process of its density; the clusters on 120 x 40 m are clustered (0.54).
        assert!((clark_evans(&grid, 1600.0).unwrap() - 2.0).abs() < 1e-6);
        assert!((clark_evans(&clusters, 4800.0).unwrap() - 0.542).abs() < 1e-3);
        assert_eq!(clark_evans(&grid[..1], 1e4), None);
        assert_eq!(nearest_neighbour_cv(&grid[..1]), None);
    }
}
