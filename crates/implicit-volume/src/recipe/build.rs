//! [`build_recipe`] in steps: the sizes derived from the DEM, the geology and the implicitised
//! DEM, then the coast (cliffs, sea, caves), karst, weathering (wind, rain, overhangs) and the
//! landforms (hoodoos, arches, islands), and the highlights worth a close-up.

use super::*;
use crate::geology::Geology;

/// What every step of [`build_recipe`] derives its sizes from.
struct Basis<'a> {
    recipe: &'a Recipe,
    /// The larger cell size `l` (m).
    l: f32,
    /// Extent east and north (m).
    ex: f32,
    ey: f32,
    /// Lowest and highest sample (m).
    lo: f32,
    hi: f32,
    area_km2: f32,
    voxel: f32,
    /// The relief, at least four voxels.
    relief: f32,
    /// Resistance under which rock is soft.
    rho0: f32,
    /// Sea level of the shore features; `None` = no sea (they are skipped).
    sea_level: Option<f32>,
    /// The level is the detected sea's: the shore is that of the border-connected sea only.
    sea_detected: bool,
    /// Radius of the weathering spheres.
    wr: f32,
}

impl Basis<'_> {
    /// The seed of step `k`.
    fn sub(&self, k: u64) -> u64 {
        crate::math::hash(self.recipe.seed, k, 0x7265_6369, 0)
    }

    fn has(&self, f: Feature) -> bool {
        self.recipe.features.contains(&f)
    }
}

/// Builds the scene of `recipe` on `hf` (complete, at least 3 x 3 nodes). Deterministic in
/// `recipe.seed` whatever the thread count.
pub fn build_recipe(hf: &Heightfield, recipe: &Recipe) -> Result<(Scene, RecipeReport)> {
    build_recipe_with_progress(hf, recipe, &relief_heightfield::NoProgress)
}

/// [`build_recipe`], asking `progress` whether to stop between its steps (coast, karst,
/// weathering, each landform; [`relief_heightfield::Progress::stopped`], then
/// [`crate::Error::Stopped`]).
pub fn build_recipe_with_progress(
    hf: &Heightfield,
    recipe: &Recipe,
    progress: &dyn relief_heightfield::Progress,
) -> Result<(Scene, RecipeReport)> {
    let check = || {
        if progress.stopped() {
            Err(crate::Error::Stopped("building the scene"))
        } else {
            Ok(())
        }
    };
    let (mut basis, mut dims) = sizes(hf, recipe)?;
    let (geology, geo) = geology(&basis, &mut dims)?;
    let sea = if recipe.sea_level.is_none() {
        detect_sea(hf)
    } else {
        None
    };
    let floor = match sea {
        Some(s) if recipe.seabed => seabed(hf, &s, basis.relief),
        _ => None,
    };
    if let Some((_, f)) = &floor {
        dims.notes.push(format!(
            "flat sea given a floor: {} samples lowered, sloping {:.1} % from the coast to \
             {:.0} m deep (seabed = false keeps the DEM's flat sea)",
            f.cells,
            100.0 * f.shore_slope,
            f.deepest_m
        ));
    }
    let hf = floor.as_ref().map_or(hf, |f| &f.0);
    let b = SceneBuilder::new(
        hf,
        geo,
        &ImplicitizeSettings {
            // Twice the cell (the default): a shorter transition saturates the rock closer to
            // the surface but raises the field's Lipschitz bound, which slows sphere tracing.
            transition: 0.0,
            depth: dims.floor_depth_m,
        },
    )?;
    let region = Region {
        mask: recipe.mask.clone(),
        bbox: None,
    };
    region.check(&b.frame())?;
    let deviation = b.implicitization_deviation(4096);
    basis.sea_level = recipe.sea_level.or(sea.map(|s| s.level));
    basis.sea_detected = sea.is_some();
    basis.wr = (2.5 * basis.voxel).max(0.05 * basis.relief * recipe.scale);
    dims.weathering_radius_m = basis.wr;
    let mut out = Out {
        b,
        region,
        dims,
        effects: Vec::new(),
        progress,
    };
    check()?;
    basis.coast(&mut out)?;
    check()?;
    basis.karst(&mut out)?;
    check()?;
    basis.weathering(&mut out)?;
    // The landforms, each when asked for.
    let landforms: [(Feature, Step<'_>); 3] = [
        (Feature::Hoodoos, Basis::hoodoos),
        (Feature::Arches, Basis::arches),
        (Feature::Islands, Basis::islands),
    ];
    for (feature, step) in landforms {
        if basis.has(feature) {
            check()?;
            step(&basis, &mut out)?;
        }
    }
    check()?;
    let Out {
        b, dims, effects, ..
    } = out;
    let section_line = best_section_line(&b);
    let highlights = highlights(&b, &effects);
    // Water wherever the scene has a sea level: the DEM's own sea (even when no shore feature
    // is asked for: a karst-only coast still shows its sea) or the recipe's explicit level.
    let has_sea = basis.sea_level.is_some();
    let scene = b.build(true)?;
    Ok((
        scene,
        RecipeReport {
            effects,
            sea_level: basis.sea_level,
            sea,
            seabed: floor.map(|f| f.1),
            has_sea,
            dims,
            geology,
            deviation,
            section_line,
            highlights,
        },
    ))
}

/// Checks the DEM and the recipe and derives the voxel, the relief and the closing floor.
fn sizes<'a>(hf: &Heightfield, recipe: &'a Recipe) -> Result<(Basis<'a>, Dimensions)> {
    hf.require_complete()?;
    if hf.width() < 3 || hf.height() < 3 {
        return Err(Error::param(
            "heightfield size",
            format!("{}x{}", hf.width(), hf.height()),
            "needs at least 3x3 nodes",
        ));
    }
    recipe.check()?;
    let (cx, cy) = hf.cell_size();
    let (cx, cy) = (cx as f32, cy as f32);
    let l = cx.max(cy);
    let k = recipe.scale;
    let (lo, hi) = hf
        .min_max()
        .ok_or(Error::param("heightfield", "all void", "needs samples"))?;
    let (ex, ey) = ((hf.width() - 1) as f32 * cx, (hf.height() - 1) as f32 * cy);
    let area_km2 = ex * ey * 1e-6;
    let mag = [ex, ey, lo.abs(), hi.abs(), 1.0]
        .into_iter()
        .fold(0.0f32, f32::max);
    // The derived sizes are multiples of `l k`: `k` far from 1 or sizes beyond the DEM's
    // extent are typos. (A bound relative to the extent from below would refuse every DEM of
    // more than 1000 cells per side at `scale` 1.)
    if !(1e-3..=1e3).contains(&k) || l * k > 5.0 * mag {
        return Err(Error::param(
            "scale",
            recipe.scale,
            "must be in [0.001, 1000] and keep the feature sizes (scale x cell size) under 5 \
             times the DEM's extent",
        ));
    }
    let voxel = match recipe.voxel {
        Some(v) if v.is_finite() && v > 0.0 && v >= ex.max(ey) / 8192.0 => v,
        Some(v) => {
            return Err(Error::param(
                "voxel",
                v,
                "must be finite, > 0 and at least 1/8192 of the DEM's extent",
            ));
        }
        None => (0.5 * l).min((hi - lo) / 32.0).max(ex.max(ey) / 512.0),
    };
    let relief = (hi - lo).max(4.0 * voxel);
    let dims = Dimensions {
        cell_m: l,
        relief_m: hi - lo,
        area_km2,
        voxel_m: voxel,
        floor_depth_m: (0.3 * relief).max(8.0 * voxel),
        ..Default::default()
    };
    let basis = Basis {
        recipe,
        l,
        ex,
        ey,
        lo,
        hi,
        area_km2,
        voxel,
        relief,
        rho0: 0.5,
        sea_level: None,
        sea_detected: false,
        wr: 0.0,
    };
    Ok((basis, dims))
}

/// The recipe's geology (the layered default when it has none), and the median thickness of
/// its soft strata over nine columns, from the floor to the top.
fn geology(basis: &Basis<'_>, dims: &mut Dimensions) -> Result<(GeologySpec, Geology)> {
    let Basis {
        ex,
        ey,
        lo,
        hi,
        voxel,
        relief,
        ..
    } = *basis;
    let center = [0.5 * ex, 0.5 * ey, 0.5 * (lo + hi)];
    let geology = match &basis.recipe.geology {
        Some(g) => g.clone(),
        None => {
            let period = (relief / 6.0).max(9.0 * voxel);
            dims.strata_period_m = Some(period);
            GeologySpec::layered_default(center, period, basis.recipe.seed)?
        }
    };
    let geo = geology.build()?;
    let cols: Vec<[f32; 2]> = (0..9)
        .map(|i| {
            [
                ex * (0.2 + 0.3 * (i % 3) as f32),
                ey * (0.2 + 0.3 * (i / 3) as f32),
            ]
        })
        .collect();
    let mut runs = geo.soft_runs(&cols, lo - dims.floor_depth_m, hi, basis.rho0, 0.25 * voxel);
    runs.sort_by(f32::total_cmp);
    dims.soft_thickness_m = runs.get(runs.len() / 2).copied();
    Ok((geology, geo))
}

/// What the steps after the implicitised DEM add to: each step (a method of [`Basis`]) adds
/// its effects to the scene builder, its sizes to the dimensions and its report to the effects.
struct Out<'p> {
    b: SceneBuilder,
    region: Region,
    dims: Dimensions,
    effects: Vec<(Feature, EffectReport)>,
    /// Asked whether to stop inside the long steps (karst).
    progress: &'p dyn relief_heightfield::Progress,
}

/// A step: adds what it builds to the output.
type Step<'a> = fn(&Basis<'a>, &mut Out<'_>) -> Result<()>;

impl Basis<'_> {
    /// Sea cliffs, and sea erosion with or without caves.
    fn coast(&self, o: &mut Out<'_>) -> Result<()> {
        let (voxel, relief, wr) = (self.voxel, self.relief, self.wr);
        let shore: Vec<&str> = [Feature::Cliffs, Feature::Sea, Feature::Caves]
            .into_iter()
            .filter(|&f| self.has(f))
            .map(Feature::name)
            .collect();
        let Some(sea_level) = self.sea_level else {
            if !shore.is_empty() {
                o.dims.notes.push(format!(
                    "shore features skipped ({}): no sea in this DEM (no border-connected area \
                     at or below 0 m, nor a flat border-connected lowest area, covering {:.0} % \
                     of it); set sea_level (--sea-level) to place a shore",
                    shore.join(", "),
                    100.0 * SEA_MIN_SHARE
                ));
            }
            return Ok(());
        };
        if self.has(Feature::Cliffs) {
            // Spheres finer than the soft strata, so hard ones survive as ledges.
            let cr = (1.5 * voxel).max(wr.min(0.4 * o.dims.soft_thickness_m.unwrap_or(wr)));
            let c = SeaCliffs {
                sea_level,
                depth: 0.3 * cr,
                retreat: 6.0 * cr,
                radius: cr,
                beta: 0.2,
                seed: self.sub(8),
                border_connected: self.sea_detected,
            };
            o.dims.cliff_retreat_m = c.retreat;
            o.effects
                .push((Feature::Cliffs, o.b.sea_cliffs(&c, &o.region)?));
        }
        if self.has(Feature::Sea) || self.has(Feature::Caves) {
            let r = wr;
            let dims = &mut o.dims;
            dims.sea_radius_m = r;
            dims.sea_height_m = (0.15 * relief).max(2.0 * r);
            dims.cave_count = if self.has(Feature::Caves) {
                count(self.recipe.densities.caves_per_km2, self.area_km2, 64)
            } else {
                0
            };
            dims.cave_length_m = (12.0 * r).min(0.25 * self.ex.min(self.ey));
            let s = SeaErosion {
                weathering: Weathering {
                    spacing: 0.4 * r,
                    radius: r,
                    energy: 3.0,
                    seed: self.sub(1),
                    ..Default::default()
                },
                sea_level,
                depth: 0.3 * r,
                height: dims.sea_height_m,
                peak: 0.2 * dims.sea_height_m,
                reach: (6.0 * r).max(2.0 * self.l),
                caves: dims.cave_count,
                cave_length: dims.cave_length_m,
                iterations: 3,
                border_connected: self.sea_detected,
            };
            let rep = o.b.sea_erosion(&s, &o.region)?;
            let f = if self.has(Feature::Sea) {
                Feature::Sea
            } else {
                Feature::Caves
            };
            o.effects.push((f, rep));
        }
        Ok(())
    }

    /// Karst passages in the soft strata, when they are at least two voxels thick.
    fn karst(&self, o: &mut Out<'_>) -> Result<()> {
        if !self.has(Feature::Karst) {
            return Ok(());
        }
        let (voxel, k, area_km2) = (self.voxel, self.recipe.scale, self.area_km2);
        let d = &self.recipe.densities;
        let dims = &mut o.dims;
        match dims.soft_thickness_m {
            Some(t) if 0.5 * t >= voxel => {
                let a = (0.4 * t * k).clamp(voxel, 0.5 * t);
                let step = a;
                dims.karst_radius_m = a;
                dims.karst_step_m = step;
                dims.karst_budget = self.recipe.karst_budget.unwrap_or(
                    ((d.karst_km_per_km2 * area_km2 * 1000.0 / step).round() as usize).min(1 << 22),
                );
                let ks = KarstSettings {
                    radius: a,
                    // The flattened passage is at least a voxel high where it narrows.
                    min_radius: (voxel / KarstSettings::default().axes().1).min(a),
                    step,
                    poisson_radius: 0.8 * step,
                    sub_spheres: 4,
                    budget: dims.karst_budget,
                    max_sinkholes: 256,
                    cliff_seeds: (d.karst_cliff_seeds_per_km2 * area_km2).round() as usize,
                    cliff_spacing: 10.0 * a,
                    rho0: self.rho0,
                    rho_stop: 0.7,
                    seed: self.sub(2),
                    ..Default::default()
                };
                o.effects.push((
                    Feature::Karst,
                    o.b.karst_with_progress(&ks, &o.region, o.progress)?,
                ));
            }
            Some(t) => dims.notes.push(format!(
                "karst skipped: soft strata {t:.1} m thick, under two voxels of {voxel:.1} m \
                 (a finer --voxel or a thicker geology resolves them)"
            )),
            None => dims
                .notes
                .push("karst skipped: the geology has no soft strata (rho < 0.5)".into()),
        }
        Ok(())
    }

    /// Wind and rain erosion; together they are the overhangs feature (one report).
    fn weathering(&self, o: &mut Out<'_>) -> Result<()> {
        let recipe = self.recipe;
        let wind = self.has(Feature::Wind) || self.has(Feature::Overhangs);
        let rain = self.has(Feature::Rain) || self.has(Feature::Overhangs);
        let w = Weathering {
            spacing: 0.5 * self.wr,
            radius: self.wr,
            energy: recipe.wind_strength,
            threshold: 0.45,
            seed: self.sub(3),
            ..Default::default()
        };
        let mut overhangs: Option<EffectReport> = None;
        if wind {
            let rep = o.b.wind_erosion(
                &WindErosion {
                    weathering: w,
                    direction: recipe.wind,
                },
                &o.region,
            )?;
            if self.has(Feature::Overhangs) {
                overhangs = Some(rep);
            } else {
                o.effects.push((Feature::Wind, rep));
            }
        }
        if rain {
            let rep = o.b.rain_erosion(
                &RainErosion {
                    weathering: Weathering {
                        seed: self.sub(4),
                        energy: recipe.rain_strength,
                        ..w
                    },
                    full_slope_deg: 40.0,
                },
                &o.region,
            )?;
            match overhangs.as_mut() {
                Some(h) => {
                    h.candidates += rep.candidates;
                    h.primitives += rep.primitives;
                }
                None => o.effects.push((Feature::Rain, rep)),
            }
        }
        if let Some(h) = overhangs {
            o.effects.push((Feature::Overhangs, h));
        }
        Ok(())
    }

    /// Hoodoos, skipped (with a note) when the voxel or the relief cannot hold them.
    fn hoodoos(&self, o: &mut Out<'_>) -> Result<()> {
        let height = (0.12 * self.relief).clamp(15.0, 250.0) * self.recipe.scale;
        let radius = (height / 6.0).max(self.voxel);
        let dims = &mut o.dims;
        (dims.hoodoo_height_m, dims.hoodoo_radius_m) = (height, radius);
        if height > 0.45 * self.relief || height < 4.0 * self.voxel {
            dims.notes.push(format!(
                "hoodoos skipped: {height:.0} m tall is not between four voxels ({:.0} m) and \
                 0.45 of the relief ({:.0} m)",
                4.0 * self.voxel,
                0.45 * self.relief
            ));
            return Ok(());
        }
        dims.hoodoo_count = count(self.recipe.densities.hoodoos_per_km2, self.area_km2, 256);
        let h = HoodooSettings {
            count: dims.hoodoo_count,
            height,
            radius,
            spacing: 4.0 * radius,
            max_slope_deg: 25.0,
            cap_rho: 0.55,
            seed: self.sub(5),
        };
        o.effects
            .push((Feature::Hoodoos, o.b.hoodoos(&h, &o.region)?));
        Ok(())
    }

    /// Floating islands: clusters of three, main radii `clamp(0.1 R, 20, 300) s`, down to a
    /// third of that, floating `max(0.3 R, 4 radius)` above the ground.
    fn islands(&self, o: &mut Out<'_>) -> Result<()> {
        let dims = &mut o.dims;
        let radius = (0.1 * self.relief).clamp(20.0, 300.0) * self.recipe.scale;
        dims.island_radius_m = radius.max(2.0 * self.voxel);
        dims.island_altitude_m = (0.3 * self.relief).max(4.0 * dims.island_radius_m);
        dims.island_count = count(self.recipe.densities.islands_per_km2, self.area_km2, 16);
        let i = IslandSettings {
            count: dims.island_count,
            radius: dims.island_radius_m,
            altitude: dims.island_altitude_m,
            per_cluster: 3,
            // The smallest island at least two voxels wide.
            spread: (dims.island_radius_m / (2.0 * self.voxel)).clamp(1.0, 3.0),
            seed: self.sub(7),
        };
        let rep = o.b.floating_islands(&i, &o.region)?;
        dims.island_radii_m = rep.sizes_m.clone();
        o.effects.push((Feature::Islands, rep));
        Ok(())
    }

    /// Arches, skipped (with a note) when the voxel or the relief cannot hold them, or when
    /// no ridge can carry one.
    fn arches(&self, o: &mut Out<'_>) -> Result<()> {
        let (voxel, relief, dims) = (self.voxel, self.relief, &mut o.dims);
        let span = (0.2 * relief).clamp(30.0, 300.0) * self.recipe.scale;
        let thickness = (span / 4.0).max(voxel);
        dims.arch_span_m = span;
        dims.arch_height_m = 0.6 * span;
        dims.arch_thickness_m = thickness;
        if span > 0.5 * relief || span < 3.0 * voxel {
            dims.notes.push(format!(
                "arches skipped: a {span:.0} m opening is over half the relief ({:.0} m) or \
                 under three {voxel:.1} m voxels",
                0.5 * relief
            ));
            return Ok(());
        }
        dims.arch_count = count(self.recipe.densities.arches_per_km2, self.area_km2, 64);
        let a = ArchSettings {
            count: dims.arch_count,
            span,
            height: dims.arch_height_m,
            thickness,
            max_length: (5.0 * span).max(3.0 * self.l),
            seed: self.sub(6),
        };
        let rep = o.b.arches(&a, &o.region)?;
        if rep.features == 0 && rep.candidates == 0 {
            o.dims.notes.push(format!(
                "arches skipped: no ridge rises {:.0} m on both sides within {:.0} m",
                a.height + a.thickness,
                a.max_length
            ));
        } else if rep.features == 0 {
            o.dims.notes.push(format!(
                "arches skipped: {} ridges are narrow enough, but none keeps {:.0} m of rock \
                 (at least 0.7 of it) along {:.0} m of its crest for the ring",
                rep.candidates,
                a.height + a.thickness,
                a.span + 2.4 * a.thickness
            ));
        } else {
            o.effects.push((Feature::Arches, rep));
        }
        Ok(())
    }
}

/// The landforms worth a close-up: the densest karst (cut away) and, of the other placed
/// features, the first site away from the DEM's border.
fn highlights(b: &SceneBuilder, effects: &[(Feature, EffectReport)]) -> Vec<Highlight> {
    let mut highlights = Vec::new();
    for (f, e) in effects {
        if *f == Feature::Karst {
            if let Some(c) = densest_karst(b) {
                highlights.push(Highlight {
                    feature: *f,
                    at: c,
                    from: Some([-0.55, -0.7, 0.35]),
                    cutaway: true,
                });
            }
        } else if matches!(
            f,
            Feature::Hoodoos
                | Feature::Arches
                | Feature::Islands
                | Feature::Caves
                | Feature::Sea
                | Feature::Cliffs
        ) && let Some(k) = {
            // The first site away from the DEM's border (a close-up of a feature on the edge
            // looks at the side of the slab), else the first.
            let fr = b.frame();
            let (xm, ym) = (
                (fr.width - 1) as f32 * fr.cx,
                (fr.height - 1) as f32 * fr.cy,
            );
            let m = 0.12 * xm.min(ym);
            e.sites
                .iter()
                .position(|p| p[0] > m && p[0] < xm - m && p[1] > m && p[1] < ym - m)
                .or((!e.sites.is_empty()).then_some(0))
        } {
            highlights.push(Highlight {
                feature: *f,
                at: e.sites[k],
                from: e.axes.get(k).or(e.axes.first()).copied(),
                cutaway: false,
            });
        }
    }
    highlights
}
