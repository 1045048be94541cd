//! Hoodoos (paper figure 3) out of the strata: columns of soft rock left standing under a
//! resistant cap bed, in clusters on steep, dissected slopes below that bed.
//!
//! Placement ([`SceneBuilder::hoodoos`]):
//! * **sites from the geology**: a DEM node qualifies when its ground slopes between
//!   `min_slope_deg` and `max_slope_deg` (badland slopes, not the plateau) and the rock column
//!   over it holds a resistant bed (`rho >= cap_rho`) between 0.6 and 1.4 times the nominal
//!   height, the nearest to it, with mostly soft rock (`rho < 0.5`) under that bed: the bed
//!   becomes the cap, the soft rock the column;
//! * **clusters**: qualifying DEM nodes in hashed order, the steeper (at least 25 degrees)
//!   first and, among those, the ones whose cap stands within 20 % of the nominal height
//!   first, seed clusters `6 spacing` apart. A cluster is a field of rows along a joint:
//!   the region's joints form two orthogonal sets (their direction hashed from the seed), a
//!   cluster follows one of them (hashed, turned by up to +-10 degrees). Members stand on a
//!   staggered lattice `spacing` apart along a row and `1.15 spacing` between rows (jittered
//!   by 15 %, anywhere between DEM nodes), within an ellipse of 3.2 by 2.2 steps, nearest the
//!   seed first, each one a qualifying site no closer than `0.8 spacing` to another; up to
//!   `per_cluster` of them.
//! * **fins**: a third of the neighbours of a row stay joined at their feet by the fin they were cut
//!   from, a wall up to 10-35 % of the lower one's height, thick where the strata are hard
//!   and tapering upwards.
//! * **hollows**: the slope has wasted back around a cluster: each member stands on the flat
//!   floor of a hollow cut [`BOWL`] of the nominal height under the ground (its cap bed is then
//!   sought above that floor), [`HOLLOW_FLOOR`] `spacing` in radius, under fluted walls at
//!   [`HOLLOW_WALL_DEG`] with a crisp rim (a CSG cut), merging into the cluster's amphitheatre;
//! * **gullies**: between two neighbouring rows of a cluster the ground is cut down along the
//!   joint over the rows' length (a capsule carving about `0.45 R` deep and `2.1 R` wide),
//!   so the rows stand on ribs between gullies.
//!
//! Shape of one hoodoo (visible radius `R` = `radius`):
//! * the column, from under the lowest ground around it up to the cap bed, is a stack of
//!   cones (a union: the profile is exactly the sampled one) whose radius at each height
//!   follows the rock there, `R (0.45 + 0.75 rho(z))`: soft strata are narrow necks, harder
//!   beds bulges, so the same hoodoo has another profile on another geology; within a
//!   stratum, thin horizontal beds of 0.5-1.5 m (`+-0.3` in hardness, hashed per bed) make
//!   ledges and necks at the same heights on every column of a cluster (the totem-pole
//!   profile), the column never wider than 90 % of its cap; a foot flares
//!   (by up to 30 %) over the lowest 15 % (talus), each sample is jittered by +-8 % and the axis leans a
//!   little;
//! * the cap is the resistant bed itself: two offset slabs (each a tall elliptic column
//!   intersected with a wide flat ellipsoid: flat top and bottom, steep sides) as thick as
//!   the bed (within `[0.15, 0.6] R`, [`CAP_THICKNESS`]: a thicker bed is worn down to a
//!   slab) and `R (0.75 + 0.5 rho)` in radius, wider than the column above its foot, each
//!   warped by noise ([`CAP_BREAK`] of its radius) into a broken block rather than a disc;
//! * the column's top is cut flat at the cap's mid-plane (it never pokes through a thin cap),
//!   and the last `0.8 R` under the cap, sheltered by it, widens towards the cap;
//! * a third of the hoodoos have lost their cap: the column stops at 50-90 % of the capped
//!   height and rounds to a blunt spire over its top `1.5 R`;
//! * a noise warp stretched vertically (`0.22 R` deep, `1.1 R` across, `5 R` long) makes the
//!   column's sections irregular and runs shallow flutes down it.

use super::*;
use relief_heightfield::param::in_range;

use crate::math::VISIBLE;

/// Slope (degrees) from which a qualifying site counts as steep badland (placed first).
const BADLAND_SLOPE_DEG: f32 = 25.0;

/// Depth of the hollow a cluster stands in, as a share of the nominal height: the slope has
/// wasted back around the columns, which rise from its floor (an amphitheatre, as at Bryce
/// Canyon), not from the untouched slope.
const BOWL: f32 = 0.35;

/// Radius of a hoodoo hollow's floor, in cluster spacings: neighbours' floors (a spacing
/// along a row, 1.15 between rows) overlap into one.
const HOLLOW_FLOOR: f32 = 0.8;

/// Energy of the hollows' primitives: only where their field passes the threshold does a cut
/// matter, so a high energy puts that surface near the support's edge ([`CUT_VISIBLE`]) and
/// keeps the support, where the warp is evaluated, tight around it (1.26 times the visible
/// radius, not 2.2 as at energy 1).
const CUT_ENERGY: f32 = 20.0 * crate::tree::THRESHOLD;

/// Visible radius of a primitive of support radius 1 at [`CUT_ENERGY`]: `20 (1 - q)^3 = 1`,
/// `sqrt(q) = sqrt(1 - 0.05^(1/3))`.
const CUT_VISIBLE: f32 = 0.794_7;

/// Angle (degrees) of a hoodoo hollow's walls: the steep, fluted walls of an amphitheatre cut
/// back into soft rock under its rim.
const HOLLOW_WALL_DEG: f32 = 68.0;

/// The thickest cap, in column radii: a cap is the resistant bed, but where that bed is a
/// thick cliff-former a cap as thick as it is wide read as a pale ball (1.2 before the
/// default geology's column had beds of 8-80 m); the caps of Bryce Canyon are slabs a
/// fraction as thick as they are wide.
const CAP_THICKNESS: f32 = 0.6;

/// Depth of the noise that breaks a cap slab's outline and faces, as a share of its radius.
const CAP_BREAK: f32 = 0.22;

/// Share of the hoodoos that have lost their cap (spires of 50-90 % of the capped height).
const CAPLESS: f32 = 0.35;

/// Hardness contrast of the thin beds within the strata ([`bed_offset`]).
const BED_CONTRAST: f32 = 0.3;

/// The thin beds within a formation that columns weather out into ledges and necks (the
/// bedding of a hoodoo-forming rock such as the Claron Formation: limestone and mudstone beds
/// of about half a metre to a metre and a half): a hardness offset of up to `+-BED_CONTRAST`
/// for the bed at height `z` (m). Beds are horizontal, bounded every metre give or take half a
/// metre (hashed from `seed`), so every column of a cluster has its ledges at the same heights.
fn bed_offset(seed: u64, z: f32) -> f32 {
    let k = z.floor();
    let key = |k: f32| k as i64 as u64;
    let base = |k: f32| k + 0.5 * unit(hash(seed, key(k), 0, 0x6265_6473));
    let bed = if z >= base(k) { k } else { k - 1.0 };
    BED_CONTRAST * (2.0 * unit(hash(seed, key(bed), 1, 0x6265_6473)) - 1.0)
}

/// A qualifying hoodoo site: the ground node, its cap bed and its slope.
#[derive(Debug, Clone, Copy)]
struct Site {
    /// Ground at the node.
    p: V3,
    /// Base and top of the cap bed.
    bed: (f32, f32),
    /// Resistance of the cap bed (its hardest sample).
    rho_cap: f32,
    /// Ground slope (degrees).
    slope: f32,
    /// Node index (hash key).
    idx: u64,
}

impl SceneBuilder {
    /// The cap bed over the ground at `p` for a hoodoo of nominal height `h`: the resistant
    /// bed (`rho >= cap_rho`) whose base is nearest `h` above the ground within `[0.6, 1.4] h`,
    /// with at least 40 % soft rock (`rho < 0.5`) under it; its base, top and hardness.
    fn cap_bed(&self, p: V3, h: f32, cap_rho: f32, radius: f32) -> Option<((f32, f32), f32)> {
        let n = 96usize;
        let dz = 1.5 * h / n as f32;
        let rho: Vec<f32> = (0..=n)
            .map(|k| self.geology.resistance([p[0], p[1], p[2] + k as f32 * dz]))
            .collect();
        let mut best: Option<(f32, usize)> = None;
        for k in 1..=n {
            let z = k as f32 * dz;
            if rho[k] >= cap_rho && rho[k - 1] < cap_rho && (0.6 * h..=1.4 * h).contains(&z) {
                let soft = rho[..k].iter().filter(|&&r| r < 0.5).count() as f32 / k as f32;
                let d = (z - h).abs();
                if soft >= 0.4 && best.is_none_or(|b| d < b.0) {
                    best = Some((d, k));
                }
            }
        }
        let (_, k0) = best?;
        let mut k1 = k0;
        let mut hard = rho[k0];
        while k1 < n && rho[k1 + 1] >= cap_rho && (k1 - k0) as f32 * dz < CAP_THICKNESS * radius {
            k1 += 1;
            hard = hard.max(rho[k1]);
        }
        let base = p[2] + k0 as f32 * dz;
        let top = base + ((k1 + 1 - k0) as f32 * dz).clamp(0.15 * radius, CAP_THICKNESS * radius);
        Some(((base, top), hard))
    }

    /// A hoodoo site at scene `(x, y)` if it qualifies ([module docs](self)): inside the
    /// margin and the region, on a slope in range at its nearest DEM node, with a cap bed.
    fn site_at(
        &self,
        s: &HoodooSettings,
        region: &Region,
        x: f32,
        y: f32,
        idx: u64,
    ) -> Option<Site> {
        let f = self.frame;
        let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
        let margin = 2.0 * s.radius;
        if x < margin || y < margin || x > xm - margin || y > ym - margin {
            return None;
        }
        let (j, i) = f.cell([x, y, 0.0])?;
        let nz = self.slope_normal(j, i)[2];
        let (cos_min, cos_max) = (
            s.min_slope_deg.to_radians().cos(),
            s.max_slope_deg.to_radians().cos(),
        );
        // The floor of the hollow the hoodoo stands in ([`BOWL`]).
        let p = [x, y, self.ground(x, y) - BOWL * s.height];
        if nz > cos_min + 1e-6 || nz < cos_max || region.weight(&f, p) <= 0.0 {
            return None;
        }
        let (bed, rho_cap) = self.cap_bed(p, s.height, s.cap_rho, s.radius)?;
        Some(Site {
            p,
            bed,
            rho_cap,
            slope: nz.clamp(-1.0, 1.0).acos().to_degrees(),
            idx,
        })
    }

    /// The horizontal downslope direction at `p` (from its nearest DEM node; east on flat
    /// ground): a camera there sees a cluster against its slope.
    fn downslope(&self, p: V3) -> V3 {
        let n = match self.frame.cell(p) {
            Some((j, i)) => self.slope_normal(j, i),
            None => [0.0, 0.0, 1.0],
        };
        let l = n[0].hypot(n[1]);
        if l > 1e-6 {
            [n[0] / l, n[1] / l, 0.0]
        } else {
            [1.0, 0.0, 0.0]
        }
    }

    /// Every DEM node where a hoodoo could stand ([module docs](self)).
    fn hoodoo_sites(&self, s: &HoodooSettings, region: &Region) -> Vec<Site> {
        let f = self.frame;
        let k = self.site_stride;
        let nodes: Vec<(usize, usize)> = (0..f.height)
            .step_by(k)
            .flat_map(|i| (0..f.width).step_by(k).map(move |j| (j, i)))
            .collect();
        nodes
            .par_iter()
            .filter_map(|&(j, i)| {
                let p = f.node(j, i, 0.0);
                self.site_at(s, region, p[0], p[1], (i * f.width + j) as u64)
            })
            .collect()
    }

    /// The joint direction of the cluster around `centre` (along its rows) and the one across:
    /// the joints of a region form two orthogonal sets (one direction hashed from the seed),
    /// a cluster's rows follow one of the two, turned by up to +-10 degrees.
    fn joints(&self, s: &HoodooSettings, centre: &Site) -> ([f32; 2], [f32; 2]) {
        use std::f32::consts::{FRAC_PI_2, PI};
        let regional = PI * unit(hash(s.seed, 0, 0x6a6f_696e, 1));
        let h = |k| unit(hash(s.seed, centre.idx, 0x6a6f_696e, k));
        let set = if h(0) < 0.5 { 0.0 } else { FRAC_PI_2 };
        let theta = regional + set + (h(2) - 0.5) * 20f32.to_radians();
        ([theta.cos(), theta.sin()], [-theta.sin(), theta.cos()])
    }

    /// The gullies of a cluster ([module docs](self)): between two neighbouring rows that
    /// both hold members, the ground is cut down along the joint over the rows' length: a
    /// capsule of visible radius `1.6 R` whose axis lies `1.15 R` under the ground, so about
    /// `0.45 R` deep and `2.1 R` wide with rims sloping about 40 degrees. Returns the
    /// primitive count.
    fn hoodoo_gullies(
        &mut self,
        s: &HoodooSettings,
        centre: &Site,
        members: &[(Site, (i32, i32))],
    ) -> Result<usize> {
        let (u, v) = self.joints(s, centre);
        let (a, b, r) = (s.spacing, 1.15 * s.spacing, s.radius);
        let mut n = 0;
        for j in -2i32..2 {
            let cols = || {
                members
                    .iter()
                    .filter(|(_, (jj, _))| *jj == j || *jj == j + 1)
                    .map(|(_, (_, i))| *i as f32)
            };
            let rows = (
                members.iter().any(|(_, l)| l.0 == j),
                members.iter().any(|(_, l)| l.0 == j + 1),
            );
            if rows != (true, true) {
                continue;
            }
            let lo = cols().fold(f32::INFINITY, f32::min) - 0.5;
            let hi = cols().fold(f32::NEG_INFINITY, f32::max) + 1.0;
            let across = (j as f32 + 0.5) * b;
            let end = |t: f32| {
                let (x, y) = (
                    centre.p[0] + t * a * u[0] + across * v[0],
                    centre.p[1] + t * a * u[1] + across * v[1],
                );
                [x, y, self.ground(x, y) - BOWL * s.height - 1.15 * r]
            };
            let (e0, e1) = (end(lo), end(hi));
            let g = self.tree.capsule(e0, e1, 1.6 * r / VISIBLE, -1.0)?;
            self.negatives.push(g);
            n += 1;
        }
        Ok(n)
    }

    /// The members of the cluster around `centre` ([module docs](self)): sites on a
    /// staggered lattice of rows along the cluster's joint direction ([`Self::joints`]), `spacing`
    /// apart along a row and `1.15 spacing` between rows, jittered by 15 %, within an ellipse
    /// of `3.2` by `2.2` steps, nearest the centre first; none closer than `0.8 spacing` to
    /// a hoodoo already placed. Each member comes with its lattice `(row, column)`.
    fn hoodoo_cluster(
        &self,
        s: &HoodooSettings,
        region: &Region,
        centre: &Site,
        placed: &[V3],
        room: usize,
    ) -> Vec<(Site, (i32, i32))> {
        let (u, v) = self.joints(s, centre);
        let h = |a: u64, b: u64| unit(hash(s.seed, centre.idx, a, b));
        let (a, b) = (s.spacing, 1.15 * s.spacing);
        let mut cands: Vec<(f32, i32, i32, u64)> = Vec::new();
        for j in -2i32..=2 {
            for i in -3i32..=3 {
                let (x, y) = (i as f32 / 3.2, j as f32 / 2.2);
                if x * x + y * y <= 1.0 {
                    let key = ((i + 8) * 16 + j + 8) as u64;
                    let order = i.abs() as f32 + 1.5 * j.abs() as f32 + h(key, 1);
                    cands.push((order, j, i, key));
                }
            }
        }
        cands.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut out: Vec<(Site, (i32, i32))> = Vec::new();
        for &(_, j, i, key) in &cands {
            if out.len() >= room.min(s.per_cluster) {
                break;
            }
            let site = if (i, j) == (0, 0) {
                Some(*centre)
            } else {
                let along = (i as f32 + 0.5 * (j & 1) as f32 + 0.3 * (h(key, 2) - 0.5)) * a;
                let across = (j as f32 + 0.3 * (h(key, 3) - 0.5)) * b;
                let x = centre.p[0] + along * u[0] + across * v[0];
                let y = centre.p[1] + along * u[1] + across * v[1];
                self.site_at(s, region, x, y, hash(centre.idx, key, 0x6c61_7474, 0))
            };
            let Some(site) = site else { continue };
            let q = [site.p[0], site.p[1], 0.0];
            let near = |o: &V3| norm(sub(*o, q)) < 0.8 * s.spacing;
            if placed.iter().any(near) || out.iter().any(|(o, _)| near(&[o.p[0], o.p[1], 0.0])) {
                continue;
            }
            out.push((site, (j, i)));
        }
        out
    }

    /// Hoodoos ([module docs](self)): columns of soft rock under a resistant cap bed, their
    /// profile from the geology, clustered on steep slopes under that bed.
    /// [`EffectReport::sites`] are the ground under each axis, [`EffectReport::sizes_m`] the
    /// heights from that ground to the cap's top.
    pub fn hoodoos(&mut self, s: &HoodooSettings, region: &Region) -> Result<EffectReport> {
        self.check_lens(&named_fields!(s; height, radius, spacing))?;
        for (n, v) in named_fields!(s; min_slope_deg, max_slope_deg) {
            in_range(n, v, 0.0..=90.0, "must be in [0, 90]")?;
        }
        let max = s.max_slope_deg;
        in_range(
            "min_slope_deg",
            s.min_slope_deg,
            ..=max,
            "must be at most max_slope_deg",
        )?;
        in_range("cap_rho", s.cap_rho, 0.0..=1.0, "must be in [0, 1]")?;
        in_range("per_cluster", s.per_cluster, 1..=64, "must be in 1..=64")?;
        region.check(&self.frame)?;
        let mut sites = self.hoodoo_sites(s, region);
        sites.sort_by_key(|c| {
            (
                c.slope < BADLAND_SLOPE_DEG,
                (c.bed.1 - c.p[2] - s.height).abs() > 0.2 * s.height,
                hash(s.seed, c.idx, 0x686f_6f64, 0),
            )
        });
        let mut report = EffectReport {
            candidates: sites.len(),
            ..Default::default()
        };
        let pts: Vec<V3> = sites.iter().map(|c| [c.p[0], c.p[1], 0.0]).collect();
        let seeds = poisson_filter(&pts, 6.0 * s.spacing, |_| true);
        let mut placed: Vec<V3> = Vec::new();
        for &c in &seeds {
            let room = s.count - report.features;
            if room == 0 {
                break;
            }
            let members = self.hoodoo_cluster(s, region, &sites[c], &placed, room);
            let first = self.positives.len();
            for (site, _) in &members {
                placed.push([site.p[0], site.p[1], 0.0]);
                report.primitives += self.hoodoo_hollow(s, site)?;
                let (n, top) = self.hoodoo(s, site)?;
                report.primitives += n;
                report.features += 1;
                report.sites.push(site.p);
                report.sizes_m.push(top - site.p[2]);
                report.axes.push(self.downslope(site.p));
            }
            // The fins the row's hoodoos broke out of, between neighbours of a row.
            for (m, (site, (j, i))) in members.iter().enumerate() {
                let next = members.iter().find(|(_, l)| *l == (*j, i + 1));
                if let Some((other, _)) = next
                    && unit(hash(s.seed, site.idx, 0x6669_6e73, m as u64)) < 0.35
                {
                    report.primitives += self.hoodoo_fin(s, site, other)?;
                }
            }
            self.join_positives_since(first)?;
            report.primitives += self.hoodoo_gullies(s, &sites[c], &members)?;
        }
        Ok(report)
    }

    /// The hollow around the hoodoo on `site` ([`BOWL`]): the slope has wasted back around
    /// the column, leaving a floor at the site's level, [`HOLLOW_FLOOR`] `spacing` in radius,
    /// under walls standing at [`HOLLOW_WALL_DEG`] with a crisp rim (a CSG cut, not a blended
    /// dish), fluted down their height: the members' hollows merge into the steep-walled
    /// amphitheatre the cluster stands in, and the walls show the strata. Returns the
    /// primitive count.
    fn hoodoo_hollow(&mut self, s: &HoodooSettings, site: &Site) -> Result<usize> {
        let rf = HOLLOW_FLOOR * s.spacing;
        let floor = site.p[2];
        // Up to above the ground the walls meet on slopes up to about 50 degrees.
        let rise = BOWL * s.height + 1.5 * rf;
        let cot = 1.0 / HOLLOW_WALL_DEG.to_radians().tan();
        // Visible radius `rf + (z - floor) cot`, from `rf` under the floor (cut off by it)
        // up to `rise` over it.
        let (a, b) = (
            [site.p[0], site.p[1], floor - rf],
            [site.p[0], site.p[1], floor + rise],
        );
        let walls = self.tree.cone(
            a,
            b,
            rf * (1.0 - cot) / CUT_VISIBLE,
            (rf + rise * cot) / CUT_VISIBLE,
            CUT_ENERGY,
        )?;
        // The floor: the underside of a wide ellipsoid, flat to within 1 % over the hollow.
        let (wide, tall) = (10.0 * (rf + rise * cot), rise + rf);
        let above = self.tree.ellipsoid(
            [site.p[0], site.p[1], floor + tall],
            [wide / CUT_VISIBLE, wide / CUT_VISIBLE, tall / CUT_VISIBLE],
            CUT_ENERGY,
        )?;
        let hollow = self.tree.intersection(walls, above)?;
        let seed = (s.seed as u32) ^ (site.idx as u32).wrapping_mul(0x9e37);
        let fluted =
            self.tree
                .streaked_warp(hollow, 0.12 * rf, 1.0 / (0.6 * rf), 1.0 / (4.0 * rf), seed)?;
        self.cuts.push(fluted);
        Ok(2)
    }

    /// One hoodoo on `site` ([module docs](self)), from the floor of its hollow; returns its
    /// primitive count.
    fn hoodoo(&mut self, s: &HoodooSettings, site: &Site) -> Result<(usize, f32)> {
        let (p, r) = (site.p, s.radius);
        let h = |c: u64| unit(hash(s.seed, site.idx, c, 0x6361_7073));
        // A third have lost their cap: their soft column wastes down to a spire.
        let capless = h(60) < CAPLESS;
        // The foot: under the lowest floor within a radius (the downslope side).
        let low = (0..8)
            .map(|k| {
                let a = k as f32 * std::f32::consts::FRAC_PI_4;
                self.ground(p[0] + r * a.cos(), p[1] + r * a.sin()) - BOWL * s.height
            })
            .fold(p[2], f32::min);
        let tall = site.bed.0 - p[2];
        let z1 = if capless {
            p[2] + tall * (0.5 + 0.4 * h(61))
        } else {
            site.bed.0
        };
        let z0 = low - 0.3 * r;
        let lean_a = std::f32::consts::TAU * h(1);
        let lean = [lean_a.cos(), lean_a.sin(), 0.0];
        let axis = |z: f32| {
            let t = ((z - p[2]) / tall).max(0.0);
            add([p[0], p[1], z], mul(lean, 0.05 * tall * t * (0.5 + h(2))))
        };
        let rc = r * (0.75 + 0.5 * site.rho_cap);
        let n = (((z1 - z0) / (0.3f32).max(0.15 * r)).ceil() as usize).clamp(4, 64);
        let profile: Vec<(V3, f32)> = (0..=n)
            .map(|m| {
                let z = z0 + (z1 - z0) * m as f32 / n as f32;
                let rho =
                    (self.geology.resistance(axis(z)) + bed_offset(s.seed, z)).clamp(0.0, 1.0);
                let foot = (1.0 - (z - low) / (0.15 * tall)).clamp(0.0, 1.0);
                let jitter = 0.92 + 0.16 * h(10 + m as u64);
                let rv = r * (0.45 + 0.75 * rho) * (1.0 + 0.3 * foot * foot) * jitter;
                // The rock right under the cap is sheltered by it: the column widens
                // towards the cap over the last `0.8 R`.
                let rv = if capless {
                    // Rounded to a blunt point over the top `1.5 R`.
                    let t = ((z1 - z) / (1.5 * r)).clamp(0.0, 1.0);
                    rv * (0.3 + 0.7 * t.sqrt())
                } else {
                    // Never as wide as the cap that shelters it (a hard thin bed may bulge
                    // out to 90 % of it).
                    let guard = (1.0 - (z1 - z) / (0.8 * r)).clamp(0.0, 1.0);
                    let rv = rv.min(0.9 * rc);
                    rv + (0.85 * rc - rv).max(0.0) * guard
                };
                (axis(z), rv / VISIBLE)
            })
            .collect();
        let mut parts = Vec::with_capacity(n + 3);
        for w in profile.windows(2) {
            parts.push(self.tree.cone(w[0].0, w[1].0, w[0].1, w[1].1, 1.0)?);
        }
        let seed = (s.seed as u32).wrapping_add(site.idx as u32);
        if capless {
            let column = self.tree.union_all(&parts)?;
            self.push_fluted(column, r, seed)?;
            return Ok((parts.len(), z1));
        }
        // The cap: the resistant bed, wider than the column.
        let (b0, b1) = site.bed;
        let top = axis(b1);
        // Two offset slabs, each a tall elliptic column cut by a wide flat ellipsoid (their
        // intersection: a disc with flat top and bottom, the bed's, and steep sides).
        let th = 0.5 * (b1 - b0) / VISIBLE;
        for k in 0..2u64 {
            let a = std::f32::consts::TAU * h(20 + k);
            let off = if k == 0 { 0.0 } else { 0.25 * rc * h(30 + k) };
            let c = [
                top[0] + off * a.cos(),
                top[1] + off * a.sin(),
                0.5 * (b0 + b1),
            ];
            let (ax, ay) = (rc * (0.8 + 0.3 * h(40 + k)), rc * (0.8 + 0.3 * h(50 + k)));
            let column = self
                .tree
                .ellipsoid(c, [ax / VISIBLE, ay / VISIBLE, 6.0 * th], 1.0)?;
            let slab = self
                .tree
                .ellipsoid(c, [3.0 * ax / VISIBLE, 3.0 * ay / VISIBLE, th], 1.0)?;
            // A block of the bed broken along its joints, not a lathe-turned disc: its outline
            // and faces are warped by [`CAP_BREAK`] of its radius over about its radius.
            let disc = self.tree.intersection(column, slab)?;
            let seed = hash(s.seed, site.idx, 0x6361_7062, k) as u32;
            parts.push(
                self.tree
                    .warp(disc, CAP_BREAK * rc, 1.0 / (0.8 * rc), seed)?,
            );
        }
        // The column's rounded top is cut at the cap's mid-plane (a very flat ellipsoid's top
        // there), so it never pokes through a thin cap.
        let n_column = parts.len() - 2;
        let column = self.tree.union_all(&parts[..n_column])?;
        let mid = 0.5 * (b0 + b1);
        let (wide, deep) = (20.0 * rc / VISIBLE, 4.0 * (mid - z0) / VISIBLE);
        let below = self.tree.ellipsoid(
            [top[0], top[1], mid - deep * VISIBLE],
            [wide, wide, deep],
            1.0,
        )?;
        let cut = self.tree.intersection(column, below)?;
        let all = self
            .tree
            .union_all(&[&[cut], &parts[n_column..]].concat())?;
        self.push_fluted(all, r, seed)?;
        Ok((parts.len(), b1))
    }

    /// The positive shapes pushed since `first` (a cluster's columns, caps and fins) joined by
    /// a CSG union into one: the scene sums its positive shapes, and summed fields bridge the
    /// gap between neighbours (two caps a few metres apart fused into one pale blob).
    fn join_positives_since(&mut self, first: usize) -> Result<()> {
        if self.positives.len() > first + 1 {
            let parts = self.positives.split_off(first);
            let joined = self.tree.union_all(&parts)?;
            self.positives.push(joined);
        }
        Ok(())
    }

    /// `node` warped by noise stretched vertically (`0.22 R` deep, `1.1 R` across, `5 R`
    /// long: irregular sections, shallow flutes) and added to the scene.
    fn push_fluted(&mut self, node: NodeId, r: f32, seed: u32) -> Result<()> {
        let w = self
            .tree
            .streaked_warp(node, 0.22 * r, 1.0 / (1.1 * r), 1.0 / (5.0 * r), seed)?;
        self.positives.push(w);
        Ok(())
    }

    /// The fin between hoodoos `a` and `b` of a row ([module docs](self)): the rock they
    /// stood out of, up to a hashed 10-35 % of the lower one's height above the ground, its
    /// thickness following the strata (`R (0.35 + 0.5 rho)`) and tapering upwards; stacked
    /// cones parallel to the ground between the two axes, fluted as the columns. Returns
    /// its primitive count.
    fn hoodoo_fin(&mut self, s: &HoodooSettings, a: &Site, b: &Site) -> Result<usize> {
        let r = s.radius;
        let frac = 0.1 + 0.25 * unit(hash(s.seed, a.idx, b.idx, 0x6669_6e32));
        let wall = frac * (a.bed.0 - a.p[2]).min(b.bed.0 - b.p[2]);
        let n = ((wall / (0.4 * r)).ceil() as usize).clamp(2, 32);
        let mut rows = Vec::with_capacity(n + 1);
        for k in 0..=n {
            let t = k as f32 / n as f32;
            let dz = -0.3 * r + (wall + 0.3 * r) * t;
            let (pa, pb) = ([a.p[0], a.p[1], a.p[2] + dz], [b.p[0], b.p[1], b.p[2] + dz]);
            let mid = mul(add(pa, pb), 0.5);
            let rho = (self.geology.resistance(mid) + bed_offset(s.seed, mid[2])).clamp(0.0, 1.0);
            let rv = r * (0.35 + 0.5 * rho) * (1.0 - 0.55 * t) / VISIBLE;
            rows.push(self.tree.cone(pa, pb, rv, rv, 1.0)?);
        }
        let fin = self.tree.union_all(&rows)?;
        let seed = (s.seed as u32) ^ (a.idx as u32).wrapping_mul(31) ^ (b.idx as u32);
        self.push_fluted(fin, r, seed)?;
        Ok(rows.len())
    }
}

#[cfg(test)]
mod tests;
