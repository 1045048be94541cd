//! Karst networks by invasion percolation from sinkholes (paper section 4.2).

use super::*;
use relief_heightfield::param::in_range;

impl SceneBuilder {
    /// Sinkholes of the DEM: strict local minima over the 8-neighbourhood (ties broken by index),
    /// lowest first.
    pub fn sinkholes(&self) -> Vec<(usize, usize)> {
        let f = self.frame;
        let mut out = Vec::new();
        for i in 1..f.height - 1 {
            for j in 1..f.width - 1 {
                let z = self.dem_at(j, i);
                let k = i * f.width + j;
                let mut min = true;
                for di in -1i32..=1 {
                    for dj in -1i32..=1 {
                        if di == 0 && dj == 0 {
                            continue;
                        }
                        let (jj, ii) = ((j as i32 + dj) as usize, (i as i32 + di) as usize);
                        let zz = self.dem_at(jj, ii);
                        let kk = ii * f.width + jj;
                        if zz < z || (zz == z && kk < k) {
                            min = false;
                        }
                    }
                }
                if min {
                    out.push((j, i));
                }
            }
        }
        out.sort_by(|a, b| {
            self.dem_at(a.0, a.1)
                .total_cmp(&self.dem_at(b.0, b.1))
                .then(a.1.cmp(&b.1))
                .then(a.0.cmp(&b.0))
        });
        out
    }

    /// Karst network by modified invasion percolation (section 4.2): seeds at the DEM's
    /// sinkholes and on steep faces, least (perturbed) resistance first, carving only where the
    /// passage sphere lies in rock softer than `rho0` and its support stays under the ground
    /// (the radius shrinks to fit under a thin roof; [`EffectReport::thin_cover`] counts the
    /// steps where even the smallest would reach the surface), new candidates on the flattened
    /// lower hemisphere, Poisson rejection; ends on the budget, the `rho_stop` threshold or an
    /// empty queue ([`EffectReport::stop`]).
    pub fn karst(&mut self, s: &KarstSettings, region: &Region) -> Result<EffectReport> {
        self.karst_with_progress(s, region, &relief_heightfield::NoProgress)
    }

    /// [`SceneBuilder::karst`], asking `progress` whether to stop before every candidate
    /// (up to 2^22 steps; then [`Error::Stopped`]).
    pub fn karst_with_progress(
        &mut self,
        s: &KarstSettings,
        region: &Region,
        progress: &dyn relief_heightfield::Progress,
    ) -> Result<EffectReport> {
        self.check_karst(s, region)?;
        let frame = self.frame;
        let floor = self.tree.bbox(self.hf).min[2];
        let (xm, ym) = (
            (frame.width - 1) as f32 * frame.cx,
            (frame.height - 1) as f32 * frame.cy,
        );
        let mut report = EffectReport::default();
        let seed = s.seed;
        let geo = self.geology.clone();
        let mut queue = Percolation::new(s, &geo);
        self.karst_sinkholes(s, region, floor, &mut queue);
        self.karst_resurgences(s, region, floor, &mut queue);
        report.sites = queue.cands.clone();
        let mut steps = 0usize;
        report.stop = Some(KarstStop::Exhausted);
        while let Some(Reverse((kbits, idx))) = queue.heap.pop() {
            if progress.stopped() {
                return Err(Error::Stopped("karst"));
            }
            if steps >= s.budget {
                report.stop = Some(KarstStop::Budget);
                break;
            }
            if f32::from_bits(kbits) > s.rho_stop {
                report.stop = Some(KarstStop::Threshold);
                break;
            }
            let p = queue.cands[idx as usize];
            report.candidates += 1;
            let wgt = region.weight(&frame, p);
            let rho = self.geology.resistance(p);
            let jitter = 1.0 + s.radius_jitter * (2.0 * unit(hash(seed, idx as u64, 3, 0)) - 1.0);
            if rho < s.rho0
                && wgt > 0.0
                && let Some(a) = soft_radius(&geo, s, p, (s.radius * jitter).max(s.min_radius))
            {
                let e = erosion_intensity(rho, s.sigma * wgt, s.beta);
                if e > 0.0 {
                    match self.covered_radius(s, p, a, e) {
                        Some(a) => {
                            steps += 1;
                            report.sizes_m.push(a);
                            report.primitives += self.karst_passage(s, p, a, e, wgt, idx)?;
                        }
                        None => report.thin_cover += 1,
                    }
                }
            }
            // New candidates on the lower hemisphere, flattened towards the horizontal.
            for d in 0..s.directions {
                let h = |c: u64| unit(hash(seed, idx as u64, d as u64, 10 + c));
                let phi = h(0) * std::f32::consts::TAU;
                let dir = normalize([phi.cos(), phi.sin(), -s.vertical * h(1)]);
                let q = add(p, mul(dir, s.step));
                if q[0] < 0.0
                    || q[1] < 0.0
                    || q[0] > xm
                    || q[1] > ym
                    || q[2] < floor + 3.0 * s.radius
                {
                    continue;
                }
                if q[2] > self.ground(q[0], q[1]) - 0.5 * s.radius {
                    continue;
                }
                if region.weight(&frame, q) <= 0.0 {
                    continue;
                }
                queue.push(q);
            }
        }
        report.features = steps;
        report.length_m = steps as f32 * s.step;
        Ok(report)
    }

    /// Checks the settings of [`SceneBuilder::karst`] and the region.
    fn check_karst(&self, s: &KarstSettings, region: &Region) -> Result<()> {
        let unit = named_fields!(s; rho0, rho_stop, epsilon, beta, sigma, vertical);
        Error::check_all_in(&unit, 0.0..=1.0, "must be in [0, 1]")?;
        if !(s.flatten > 0.0 && s.flatten <= 1.0) {
            return Err(Error::param("flatten", s.flatten, "must be in (0, 1]"));
        }
        in_range(
            "radius_jitter",
            s.radius_jitter,
            0.0..=0.9,
            "must be in [0, 0.9]",
        )?;
        let lens =
            named_fields!(s; radius, min_radius, energy, step, poisson_radius, cliff_spacing);
        self.check_lens(&lens)?;
        in_range("min_radius", s.min_radius, ..=s.radius, "must be <= radius")?;
        in_range("directions", s.directions, 1..=64, "must be in 1..=64")?;
        if s.sub_spheres > 16 {
            return Err(Error::param("sub_spheres", s.sub_spheres, "must be <= 16"));
        }
        if s.budget > 1 << 22 {
            return Err(Error::param("budget", s.budget, "must be <= 2^22"));
        }
        region.check(&self.frame)
    }

    /// Seeds at the sinkholes: each drains down to the first soft rock under it (its shaft
    /// through the hard strata is not carved).
    fn karst_sinkholes(
        &self,
        s: &KarstSettings,
        region: &Region,
        floor: f32,
        queue: &mut Percolation<'_>,
    ) {
        let (frame, geo) = (self.frame, queue.geo);
        let mut n_sinks = 0;
        for (j, i) in self.sinkholes() {
            if n_sinks >= s.max_sinkholes {
                break;
            }
            let mut p = frame.node(j, i, self.dem_at(j, i) - s.radius);
            while geo.resistance(p) >= s.rho0 && p[2] > floor + 4.0 * s.radius {
                p[2] -= 0.5 * s.radius;
            }
            if region.weight(&frame, p) <= 0.0 || geo.resistance(p) >= s.rho0 {
                continue;
            }
            if queue.push(p) {
                n_sinks += 1;
            }
        }
    }

    /// Resurgences on steep faces: Poisson-spaced steep cells, pushed into the rock.
    fn karst_resurgences(
        &self,
        s: &KarstSettings,
        region: &Region,
        floor: f32,
        queue: &mut Percolation<'_>,
    ) {
        if s.cliff_seeds == 0 {
            return;
        }
        let (frame, geo) = (self.frame, queue.geo);
        let mut steep = Vec::new();
        for i in 1..frame.height - 1 {
            for j in 1..frame.width - 1 {
                let n = self.slope_normal(j, i);
                if n[2] < 0.8 {
                    steep.push((hash(s.seed, (i * frame.width + j) as u64, 5, 0), j, i, n));
                }
            }
        }
        steep.sort_by_key(|x| x.0);
        let pts: Vec<V3> = steep
            .iter()
            .map(|&(_, j, i, _)| frame.node(j, i, self.dem_at(j, i)))
            .collect();
        let kept = poisson_filter(&pts, s.cliff_spacing, |_| true);
        let mut n_cliff = 0;
        for k in kept {
            if n_cliff >= s.cliff_seeds {
                break;
            }
            let n = steep[k].3;
            let mut p = sub(pts[k], mul(n, 1.5 * s.radius));
            while geo.resistance(p) >= s.rho0 && p[2] > floor + 4.0 * s.radius {
                p[2] -= 0.5 * s.radius;
            }
            if region.weight(&frame, p) <= 0.0 || p[2] < floor + 3.0 * s.radius {
                continue;
            }
            if queue.push(p) {
                n_cliff += 1;
            }
        }
    }

    /// Carves the passage at candidate `idx` (position `p`, visible radius `a`, intensity `e`):
    /// an ellipsoid flattened along the bedding and its sub-ellipsoids; returns the number of
    /// primitives added.
    fn karst_passage(
        &mut self,
        s: &KarstSettings,
        p: V3,
        a: f32,
        e: f32,
        wgt: f32,
        idx: u32,
    ) -> Result<usize> {
        let r = s.support_radius(a, e);
        let (wide, high) = s.axes();
        let id = self
            .tree
            .ellipsoid(p, [wide * r, wide * r, high * r], -s.energy * e)?;
        self.negatives.push(id);
        self.carved.push((p, wide * r, true));
        let mut primitives = 1;
        for m in 0..s.sub_spheres {
            let h = |c: u64| unit(hash(s.seed, idx as u64, 100 + m as u64, c)) * 2.0 - 1.0;
            // Mostly sideways: passages widen along the bedding.
            let q = add(p, mul([h(0), h(1), 0.3 * h(2)], 0.6 * a));
            let rq = self.geology.resistance(q);
            if rq < s.rho0 {
                let eq = erosion_intensity(rq, s.sigma * wgt, s.beta);
                let rr = 0.7 * s.support_radius(a, eq);
                if !self.under_cover(q, wide * rr, high * rr) {
                    continue;
                }
                let id =
                    self.tree
                        .ellipsoid(q, [wide * rr, wide * rr, high * rr], -s.energy * eq)?;
                self.negatives.push(id);
                self.carved.push((q, wide * rr, true));
                primitives += 1;
            }
        }
        Ok(primitives)
    }
}

impl SceneBuilder {
    /// The largest passage radius from `a` down to `s.min_radius` (steps of 3/4) whose whole
    /// support (the ellipsoid where the carving lowers the field, [`KarstSettings::support_radius`])
    /// stays under the ground: a passage in thin rock would otherwise dent the surface above it
    /// or break through it as a pit. `None` when even the smallest does not fit.
    fn covered_radius(&self, s: &KarstSettings, p: V3, mut a: f32, e: f32) -> Option<f32> {
        let (wide, high) = s.axes();
        loop {
            let r = s.support_radius(a, e);
            if self.under_cover(p, wide * r, high * r) {
                return Some(a);
            }
            if a <= s.min_radius {
                return None;
            }
            a = (a * 0.75).max(s.min_radius);
        }
    }

    /// Whether an ellipsoid at `p` with horizontal semi-axis `h` and vertical semi-axis `v`
    /// lies under the lowest ground within `h` of its centre.
    fn under_cover(&self, p: V3, h: f32, v: f32) -> bool {
        p[2] + v <= self.ground_min(p[0], p[1], h)
    }
}

/// The candidates of the invasion percolation: positions, a min-heap on the perturbed
/// resistance, and a grid for the Poisson rejection.
struct Percolation<'a> {
    s: &'a KarstSettings,
    geo: &'a Geology,
    cands: Vec<V3>,
    heap: BinaryHeap<Reverse<(u32, u32)>>,
    grid: FxHashMap<(i32, i32, i32), Vec<u32>>,
}

impl<'a> Percolation<'a> {
    fn new(s: &'a KarstSettings, geo: &'a Geology) -> Self {
        Self {
            s,
            geo,
            cands: Vec::new(),
            heap: BinaryHeap::new(),
            grid: FxHashMap::default(),
        }
    }

    fn key(&self, p: V3) -> (i32, i32, i32) {
        let pr = self.s.poisson_radius;
        (
            (p[0] / pr).floor() as i32,
            (p[1] / pr).floor() as i32,
            (p[2] / pr).floor() as i32,
        )
    }

    /// Adds a candidate unless one lies within the Poisson radius; true when added.
    fn push(&mut self, p: V3) -> bool {
        let pr = self.s.poisson_radius;
        let (a, b, c) = self.key(p);
        for da in -1..=1 {
            for db in -1..=1 {
                for dc in -1..=1 {
                    if let Some(v) = self.grid.get(&(a + da, b + db, c + dc))
                        && v.iter().any(|&q| norm(sub(self.cands[q as usize], p)) < pr)
                    {
                        return false;
                    }
                }
            }
        }
        let idx = self.cands.len() as u32;
        let k = self.geo.resistance(p) + self.s.epsilon * unit(hash(self.s.seed, idx as u64, 1, 0));
        self.cands.push(p);
        self.grid.entry((a, b, c)).or_default().push(idx);
        self.heap.push(Reverse((k.to_bits(), idx)));
        true
    }
}

/// Test points of a passage (unit sphere, scaled to the ellipsoid): six poles and eight
/// diagonal points.
const D: f32 = 0.577_350_26;
const DIRS: [V3; 14] = [
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, -1.0],
    [D, D, D],
    [D, D, -D],
    [D, -D, D],
    [D, -D, -D],
    [-D, D, D],
    [-D, D, -D],
    [-D, -D, D],
    [-D, -D, -D],
];

/// The largest passage radius from `start` down to `s.min_radius` (steps of 3/4) whose
/// passage ellipsoid ([`KarstSettings::flatten`]) lies in rock softer than `rho0`.
fn soft_radius(geo: &Geology, s: &KarstSettings, p: V3, start: f32) -> Option<f32> {
    let mut a = start;
    let (wide, high) = s.axes();
    loop {
        if DIRS.iter().all(|d| {
            let q = [d[0] * wide * a, d[1] * wide * a, d[2] * high * a];
            geo.resistance(add(p, q)) < s.rho0
        }) {
            return Some(a);
        }
        if a <= s.min_radius {
            return None;
        }
        a = (a * 0.75).max(s.min_radius);
    }
}
