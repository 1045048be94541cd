//! Undercuts: overhangs where a resistant bed overlies soft rock on a steep face. The soft
//! rock retreats under the bed (sapping, spalling, wind and rain on the weaker layer) and the
//! bed is left standing out as a ledge over the hollow: the alcoves and overhanging ledges of
//! layered canyon walls, and what makes the caprock of hoodoos and mesas overhang.
//!
//! [`SceneBuilder::undercuts`]: surface samples `spacing` apart on faces steeper than
//! `min_slope_deg` (spread up steep cells, as for the weathering effects); at each, the
//! geology is read down the face's line: where, within `depth` of the sample, the rock turns
//! from soft (`rho < rho_soft`) below to resistant (`rho >= rho_hard`) above, a horizontal
//! hollow is carved in the soft rock just under the bed's base, along the contour line
//! (neighbouring hollows under one bed merge into a continuous recess), reaching
//! `depth (rho_bed - rho_below) / 0.5` (at most `depth`, at least `0.2 depth`) into the face:
//! a stronger contrast retreats further; along the bed, noise over [`ALCOVE_LENGTH`] depths
//! scales it by 0.35-1, so a recess runs from deep alcoves to shallow notches. Its radius is half the soft run under the bed (at
//! most the depth), so thin soft partings give slots and thick soft members deep alcoves;
//! the bed itself is not touched, so it overhangs.

use super::*;

/// Visible radius of a carving of support radius 1 in saturated rock (field `2T`) at energy
/// `20 T`: `2T - 20 T (1 - q)^3 = T` at `q = 0.76^2`... (see `carve_gap` in `arches.rs`).
const HOLE: f32 = 0.76;

/// Length (in depths) over which an undercut's retreat varies along its bed, from an alcove
/// to a shallow notch and back.
const ALCOVE_LENGTH: f32 = 4.0;

/// One hollow: centre, contour direction, visible radius, depth into the face and the
/// horizontal direction out of the face.
#[derive(Debug, Clone, Copy)]
struct Hollow {
    c: V3,
    along: V3,
    rv: f32,
    depth: f32,
    out: V3,
}

impl SceneBuilder {
    /// Undercuts ([module docs](self)). [`EffectReport::sites`] are the hollows' centres,
    /// [`EffectReport::sizes_m`] their depths into the face, [`EffectReport::axes`] the
    /// horizontal directions out of the face (where to look from).
    pub fn undercuts(&mut self, s: &UndercutSettings, region: &Region) -> Result<EffectReport> {
        self.check_lens(&named_fields!(s; depth, spacing))?;
        relief_heightfield::param::in_range(
            "min_slope_deg",
            s.min_slope_deg,
            0.0..=90.0,
            "must be in [0, 90]",
        )?;
        for (n, v) in named_fields!(s; rho_soft, rho_hard) {
            relief_heightfield::param::in_range(n, v, 0.0..=1.0, "must be in [0, 1]")?;
        }
        region.check(&self.frame)?;
        self.check_candidates(s.spacing, None)?;
        let f = self.frame;
        let cos_min = s.min_slope_deg.to_radians().cos();
        let cand = self.surface_candidates(s.spacing, s.seed, None);
        let kept = poisson_filter(&cand, s.spacing, |_| true);
        let me = &*self;
        let hollows: Vec<Option<Hollow>> = kept
            .par_iter()
            .map(|&k| {
                let p = cand[k];
                let (j, i) = f.cell(p)?;
                let n = me.slope_normal(j, i);
                if n[2] > cos_min || region.weight(&f, p) <= 0.0 {
                    return None;
                }
                me.undercut_at(s, p, n)
            })
            .collect();
        let mut report = EffectReport {
            candidates: kept.len(),
            ..Default::default()
        };
        for Hollow {
            c,
            along: t,
            rv,
            depth,
            out,
        } in hollows.into_iter().flatten()
        {
            let half = 0.5 * GROOVE_LENGTH * rv;
            let (a, b) = (add(c, mul(t, -half)), add(c, mul(t, half)));
            let id = self.tree.capsule(a, b, rv / HOLE, -20.0 * THRESHOLD)?;
            self.negatives.push(id);
            self.carved.push((c, rv / HOLE, false));
            report.primitives += 1;
            report.features += 1;
            report.sites.push(c);
            report.sizes_m.push(depth);
            report.axes.push(out);
        }
        Ok(report)
    }

    /// The hollow under the bed nearest the face sample `p` (ground normal `n`).
    fn undercut_at(&self, s: &UndercutSettings, p: V3, n: V3) -> Option<Hollow> {
        let h = (n[0] * n[0] + n[1] * n[1]).sqrt();
        if h < 1e-4 {
            return None;
        }
        let inward = [-n[0] / h, -n[1] / h, 0.0];
        let along = [-n[1] / h, n[0] / h, 0.0];
        // The face's line: going up by dz moves the surface inward by dz / tan(slope).
        let run = n[2] / h;
        let on_face = |dz: f32| add(p, add(mul(inward, dz * run), [0.0, 0.0, dz]));
        // Read the rock a little inside the face (the surface itself is weathered).
        let rho = |dz: f32| {
            let q = add(on_face(dz), mul(inward, 0.25 * s.depth));
            self.geology.resistance(q)
        };
        let m = 24;
        let dz = s.depth / m as f32;
        let base = (-m..m)
            .map(|k| k as f32 * dz)
            .filter(|&z| rho(z - 0.5 * dz) < s.rho_soft && rho(z + 0.5 * dz) >= s.rho_hard)
            .min_by(|a, b| a.abs().total_cmp(&b.abs()))?;
        // The soft run under the bed (up to two depths) and the contrast across its base.
        let soft = (1..=2 * m)
            .map(|k| k as f32 * dz)
            .take_while(|&d| rho(base - d) < s.rho_soft)
            .last()
            .unwrap_or(dz);
        let contrast = rho(base + 0.5 * dz) - rho(base - 0.5 * soft);
        // Along the bed the retreat is uneven: alcoves where seeps and spalling work deepest,
        // shallow notches between ([`ALCOVE_LENGTH`] depths long).
        let at = on_face(base);
        let v = crate::math::fbm3(
            s.seed ^ 0x616c_636f,
            mul(at, 1.0 / (ALCOVE_LENGTH * s.depth)),
            2,
        )[0];
        let alcove = 0.35 + 0.65 * (0.5 + 0.8 * v).clamp(0.0, 1.0);
        let depth = (s.depth * contrast / 0.5 * alcove).clamp(0.2 * s.depth, s.depth);
        let rv = (0.5 * soft).clamp(0.1 * s.depth, depth);
        // Centre one radius under the bed's base, `depth - rv` behind the face at the base:
        // the hollow reaches `depth` under the bed's edge, which overhangs it.
        let c = add(add(on_face(base), mul(inward, depth - rv)), [0.0, 0.0, -rv]);
        Some(Hollow {
            c,
            along,
            rv,
            depth,
            out: [-inward[0], -inward[1], 0.0],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geology::test_beds;

    /// A west-facing cliff (60 degrees, 0 to 40 m) in strata of 5 m soft (0.1) under 3 m
    /// resistant (0.9) beds: under each bed's base the face is cut back into a hollow (air
    /// where there was rock) while the bed over it still stands at the same place (rock over
    /// air: an overhang); on flat ground nothing is carved; the same with any thread count.
    #[test]
    fn soft_rock_retreats_under_resistant_beds() {
        let hf = Heightfield::from_fn(40, 24, 1.0, 1.0, |x, _| {
            ((x as f32 - 12.0) * 3f32.sqrt()).clamp(0.0, 40.0)
        });
        let g = test_beds(0.0, (5.0, 0.1), (3.0, 0.9));
        let s = UndercutSettings {
            depth: 2.0,
            spacing: 1.0,
            ..Default::default()
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let mut b =
                    SceneBuilder::new(&hf, g.clone(), &ImplicitizeSettings::default()).unwrap();
                let before = b.clone().build(true).unwrap();
                let rep = b.undercuts(&s, &Region::everywhere()).unwrap();
                (before, b.build(true).unwrap(), rep)
            })
        };
        let (before, scene, rep) = run(1);
        assert_eq!(run(2).2, rep);
        assert!(rep.features > 10, "{rep:?}");
        assert!(rep.sizes_m.iter().all(|&d| (0.4..=2.0).contains(&d)));
        // Uneven along the beds (one contrast everywhere here, so every hollow was 2 m deep):
        // alcoves and shallow notches.
        let lo = rep.sizes_m.iter().copied().fold(f32::INFINITY, f32::min);
        assert!(lo < 0.8 * 2.0, "no shallow notch: depths from {lo} m");
        // Bed bases at 13, 21 and 29 m; the face at height z is at x = 12 + z / sqrt(3). An
        // overhang: behind the face, rock in the bed over air under it, where there was rock.
        let y = 11.5;
        let mut overhangs = 0;
        for zb in [13.0f32, 21.0, 29.0] {
            let x_face = 12.0 + zb / 3f32.sqrt();
            let found = (3..=15).any(|k| {
                let x = x_face + 0.1 * k as f32;
                let (hollow, ledge) = ([x, y, zb - 0.5], [x, y, zb + 0.3]);
                before.inside(hollow) && !scene.inside(hollow) && scene.inside(ledge)
            });
            overhangs += usize::from(found);
        }
        assert!(overhangs >= 2, "{overhangs} overhanging beds");
        // Nothing on flat ground (west of the cliff).
        assert!(rep.sites.iter().all(|c| c[0] > 10.0), "{:?}", rep.sites);
    }
}
