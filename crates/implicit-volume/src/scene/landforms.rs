//! Landforms placed on the terrain: hoodoos, arches and floating islands (paper section 4).

use super::*;

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

    /// Hoodoos (figure 3): a cone base blended with stacked perturbed spheres and a caprock,
    /// creased by a warp, unioned with the terrain on gentle ground.
    pub fn hoodoos(&mut self, s: &HoodooSettings, region: &Region) -> Result<EffectReport> {
        for (n, v) in [
            ("height", s.height),
            ("radius", s.radius),
            ("spacing", s.spacing),
        ] {
            self.check_len(n, v)?;
        }
        if !(0.0..=90.0).contains(&s.max_slope_deg) {
            return Err(Error::param(
                "max_slope_deg",
                s.max_slope_deg,
                "must be in [0, 90]",
            ));
        }
        if !(0.0..=1.0).contains(&s.cap_rho) {
            return Err(Error::param("cap_rho", s.cap_rho, "must be in [0, 1]"));
        }
        region.check(&self.frame)?;
        let sites = self.flat_sites(s.spacing, s.max_slope_deg, s.seed, region, 2.0 * s.radius);
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
            let b = self.tree.blend(&parts)?;
            let w = self.tree.warp(
                b,
                0.12 * s.radius,
                1.0 / (0.6 * s.radius),
                (s.seed as u32).wrapping_add(k as u32),
            )?;
            self.positives.push(w);
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

    /// Arches at sampled gentle sites of the region.
    pub fn arches(&mut self, s: &ArchSettings, region: &Region) -> Result<EffectReport> {
        for (n, v) in [
            ("span", s.span),
            ("height", s.height),
            ("thickness", s.thickness),
        ] {
            self.check_len(n, v)?;
        }
        region.check(&self.frame)?;
        let sites = self.flat_sites(2.0 * s.span, 30.0, s.seed, region, s.span);
        let f = self.frame;
        let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
        let mut report = EffectReport {
            candidates: sites.len(),
            primitives: 0,
            ..Default::default()
        };
        for (k, &p) in sites.iter().enumerate() {
            if report.features >= s.count {
                break;
            }
            let ang = unit(hash(s.seed, k as u64, 3, 3)) * std::f32::consts::TAU;
            let (dx, dy) = (0.5 * s.span * ang.cos(), 0.5 * s.span * ang.sin());
            let (a, b) = ([p[0] - dx, p[1] - dy], [p[0] + dx, p[1] + dy]);
            if [a, b]
                .iter()
                .any(|q| q[0] < 0.0 || q[1] < 0.0 || q[0] > xm || q[1] > ym)
            {
                continue;
            }
            self.arch(
                a,
                b,
                s.height,
                s.thickness,
                (s.seed as u32).wrapping_add(k as u32),
            )?;
            report.primitives += 12;
            report.features += 1;
            report.sites.push([p[0], p[1], p[2] + 0.5 * s.height]);
        }
        Ok(report)
    }

    /// Floating islands: an ellipsoidal top blended with an inverted cone, warped, hovering
    /// `altitude` metres above the ground.
    pub fn floating_islands(
        &mut self,
        s: &IslandSettings,
        region: &Region,
    ) -> Result<EffectReport> {
        self.check_len("radius", s.radius)?;
        self.check_len("altitude", s.altitude)?;
        region.check(&self.frame)?;
        let sites = self.flat_sites(3.0 * s.radius, 90.0, s.seed, region, s.radius);
        let mut report = EffectReport {
            candidates: sites.len(),
            primitives: 0,
            ..Default::default()
        };
        for (k, &p) in sites.iter().take(s.count).enumerate() {
            let c = add(p, [0.0, 0.0, s.altitude]);
            let top =
                self.tree
                    .ellipsoid(c, [s.radius * 1.6, s.radius * 1.4, s.radius * 0.5], 1.0)?;
            let cone = self.tree.cone(
                add(c, [0.0, 0.0, -0.1 * s.radius]),
                add(c, [0.0, 0.0, -1.6 * s.radius]),
                1.2 * s.radius,
                0.25 * s.radius,
                1.0,
            )?;
            let b = self.tree.blend(&[top, cone])?;
            let w = self.tree.warp(
                b,
                0.15 * s.radius,
                1.0 / (0.5 * s.radius),
                (s.seed as u32).wrapping_add(k as u32),
            )?;
            self.positives.push(w);
            report.primitives += 2;
            report.features += 1;
            report.sites.push(c);
        }
        Ok(report)
    }
}
