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
    /// The feature sizes times the recipe's scale (m).
    sz: FeatureSizes,
}

impl Basis<'_> {
    /// The seed of step `k`.
    fn sub(&self, k: u64) -> u64 {
        crate::math::hash(self.recipe.seed, k, 0x7265_6369, 0)
    }

    fn has(&self, f: Feature) -> bool {
        self.recipe.features.contains(&f)
    }

    /// Whether weathering `f` at `spacing` over the whole DEM is beyond a run's budget
    /// ([`WEATHERING_MAX_SAMPLES`]; a note then names the window that fits).
    fn too_large(
        &self,
        f: Feature,
        spacing: f32,
        zband: Option<(f32, f32)>,
        o: &mut Out<'_>,
    ) -> bool {
        let n = o.b.candidate_count(spacing, zband);
        if n <= WEATHERING_MAX_SAMPLES as f64 {
            return false;
        }
        let side = self.ex.max(self.ey) * (WEATHERING_MAX_SAMPLES as f64 / n).sqrt() as f32;
        o.dims.notes.push(format!(
            "{f} refused: {n:.0} surface samples at their {spacing:.1} m spacing over this \
             {:.1} km2 DEM, over the {WEATHERING_MAX_SAMPLES} a run affords; a window of about \
             {side:.0} m (--crop) fits",
            self.area_km2
        ));
        true
    }

    /// Whether the DEM's cells are too coarse for `f` (a note then says what cell it needs).
    fn too_coarse(&self, f: Feature, dims: &mut Dimensions) -> bool {
        match self.sz.needed_cell_m(f) {
            Some(need) if self.l > need * 1.001 => {
                dims.notes.push(format!(
                    "{f} refused: they need DEM cells of at most {need:.1} m, this DEM's are \
                     {:.1} m (relief volume amplifies a window of the DEM to that cell unless \
                     --raw-dem)",
                    self.l
                ));
                true
            }
            _ => false,
        }
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
    let level = recipe.sea_level.or(sea.map(|s| s.level));
    let (dem_w, dem_h) = (hf.width(), hf.height());
    let stepped = stepped(&basis, &geo, hf, level, &mut dims)?;
    let hf = stepped.as_ref().map_or(hf, |s| &s.0);
    let b = SceneBuilder::new(
        hf,
        geo,
        &ImplicitizeSettings {
            // Twice the DEM's own cell (the default on it): a shorter transition saturates the
            // rock closer to the surface but raises the field's Lipschitz bound, which slows
            // sphere tracing.
            transition: 2.0 * basis.l,
            depth: dims.floor_depth_m,
        },
    )?;
    let region = Region {
        mask: match (&recipe.mask, &stepped) {
            (Some(m), Some((_, k))) => Some(benches::upsample_mask(m, dem_w, dem_h, *k)),
            (m, _) => m.clone(),
        },
        bbox: None,
    };
    let mut b = b;
    if let Some((_, k)) = &stepped {
        b.set_site_stride(*k);
    }
    region.check(&b.frame())?;
    let deviation = b.implicitization_deviation(4096);
    basis.sea_level = recipe.sea_level.or(sea.map(|s| s.level));
    basis.sea_detected = sea.is_some();
    basis.wr = basis.sz.overhang_depth_m;
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
        b,
        mut dims,
        effects,
        ..
    } = out;
    dims.sizes = size_stats(&basis, &dims, &effects);
    let section_line = best_section_line(&b, &effects, dims.sea_radius_m);
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
    let sz = recipe.sizes.scaled(k);
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
        None => sz
            .voxel_for(&recipe.features)
            .unwrap_or((0.5 * l).min((hi - lo) / 32.0))
            .max(ex.max(ey) / 512.0),
    };
    let relief = (hi - lo).max(4.0 * voxel);
    let dims = Dimensions {
        cell_m: l,
        relief_m: hi - lo,
        area_km2,
        voxel_m: voxel,
        floor_depth_m: (0.3 * relief).max(8.0 * voxel),
        needed_cell_m: sz.needed_cell_for(&recipe.features),
        affordable_extent_m: sz.voxel_for(&recipe.features).map(|v| 512.0 * v),
        ..Default::default()
    };
    let mut dims = dims;
    if let (Some(want), None) = (sz.voxel_for(&recipe.features), recipe.voxel)
        && voxel > 1.5 * want
    {
        dims.notes.push(format!(
            "mesh voxel {voxel:.1} m (512 cells over {:.0} m): the features are built at their \
             size (renders, close-ups and sections show them) but a mesh resolves them at a \
             {want:.1} m voxel, on a window of at most {:.0} m (--crop)",
            ex.max(ey),
            512.0 * want
        ));
    }
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
        sz,
    };
    Ok((basis, dims))
}

/// The DEM stepped by its resistant beds ([`benches::benches`]) when any feature is asked
/// for, with a note saying what was done or why not.
fn stepped(
    basis: &Basis<'_>,
    geology: &Geology,
    hf: &Heightfield,
    sea_level: Option<f32>,
    dims: &mut Dimensions,
) -> Result<Option<(Heightfield, usize)>> {
    let r = basis.recipe;
    if r.features.is_empty() || r.benches == 0.0 {
        return Ok(None);
    }
    let inp = benches::BenchInput {
        geology,
        rho0: basis.rho0,
        benches: r.benches,
        cell_m: basis.voxel,
        sea_level,
        lo: basis.lo,
        hi: basis.hi,
    };
    Ok(match benches::benches(hf, &inp)? {
        Ok((out, rep)) => {
            dims.notes.push(format!(
                "benches: resistant beds ({:.1} m thick, median) stepped into cliffs and \
                 benches ({:.0} % of each outcrop a bench) on the DEM interpolated {}x to \
                 {:.1} m cells: {} samples raised, at most {:.1} m (benches = 0 keeps the \
                 smooth slopes)",
                rep.bed_m,
                100.0 * r.benches,
                rep.factor,
                rep.cell_m,
                rep.raised,
                rep.max_rise_m
            ));
            Some((out, rep.factor))
        }
        Err(why) => {
            dims.notes.push(why);
            None
        }
    })
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
        ..
    } = *basis;
    // The strata at fixed elevations (from 0 m), whatever the crop.
    let center = [0.5 * ex, 0.5 * ey, 0.0];
    let period = basis.sz.strata_period_m;
    let geology = match &basis.recipe.geology {
        Some(g) => g.clone(),
        None => {
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
    let step = (period / 40.0).min(0.25 * voxel);
    let rho0 = basis.rho0;
    let mut runs = geo.runs(&cols, lo - dims.floor_depth_m, hi, step, |rho| rho < rho0);
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
        let sz = self.sz;
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
        // Spheres finer than the soft strata, so hard ones survive as ledges, but at least a
        // sixth of the retreat (the cut's primitive count grows with the inverse cube).
        // The height band the waves reach (what the shore effects sample).
        let band = (
            sea_level - 0.3 * sz.sea_radius_m,
            sea_level + sz.sea_height_m,
        );
        let soft = o.dims.soft_thickness_m.unwrap_or(sz.sea_radius_m);
        let cr = (0.4 * soft).max(sz.cliff_retreat_m / 6.0);
        if self.has(Feature::Cliffs)
            && !self.too_coarse(Feature::Cliffs, &mut o.dims)
            && !self.too_large(Feature::Cliffs, 0.75 * cr, Some(band), o)
        {
            let c = SeaCliffs {
                sea_level,
                depth: 0.3 * cr,
                retreat: sz.cliff_retreat_m,
                radius: cr,
                beta: 0.2,
                seed: self.sub(8),
                border_connected: self.sea_detected,
            };
            o.dims.cliff_retreat_m = c.retreat;
            o.effects
                .push((Feature::Cliffs, o.b.sea_cliffs(&c, &o.region)?));
        }
        let shore = [Feature::Sea, Feature::Caves]
            .into_iter()
            .find(|&f| self.has(f));
        if let Some(f) = shore
            && !self.too_coarse(f, &mut o.dims)
            && !self.too_large(f, 0.4 * sz.sea_radius_m, Some(band), o)
        {
            let r = sz.sea_radius_m;
            let dims = &mut o.dims;
            dims.sea_radius_m = r;
            dims.sea_height_m = sz.sea_height_m;
            dims.cave_count = if self.has(Feature::Caves) {
                count(self.recipe.densities.caves_per_km2, self.area_km2, 64)
            } else {
                0
            };
            dims.cave_length_m = sz.cave_length_m.min(0.25 * self.ex.min(self.ey));
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
                reach: sz.cliff_retreat_m.max(2.0 * self.l),
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

    /// Karst passages in the soft strata, at most half their thickness in radius.
    fn karst(&self, o: &mut Out<'_>) -> Result<()> {
        if !self.has(Feature::Karst) {
            return Ok(());
        }
        let area_km2 = self.area_km2;
        let d = &self.recipe.densities;
        let dims = &mut o.dims;
        match dims.soft_thickness_m {
            Some(t) => {
                let a = self.sz.karst_radius_m.min(0.5 * t);
                if a < self.sz.karst_radius_m {
                    dims.notes.push(format!(
                        "karst passages {a:.1} m in radius, not {:.1} m: the soft strata are \
                         {t:.1} m thick",
                        self.sz.karst_radius_m
                    ));
                }
                let step = a;
                dims.karst_radius_m = a;
                dims.karst_step_m = step;
                let wanted = (d.karst_km_per_km2 * area_km2 * 1000.0 / step).round() as usize;
                dims.karst_budget = self.recipe.karst_budget.unwrap_or_else(|| {
                    if wanted > KARST_MAX_STEPS {
                        dims.notes.push(format!(
                            "karst budget {KARST_MAX_STEPS} steps ({:.1} km of passages), not \
                             the {:.1} km the density asks for over {area_km2:.1} km2 \
                             (--karst-budget)",
                            KARST_MAX_STEPS as f32 * step * 1e-3,
                            wanted as f32 * step * 1e-3
                        ));
                    }
                    wanted.min(KARST_MAX_STEPS)
                });
                let ks = KarstSettings {
                    radius: a,
                    // Passages narrow to half their radius under thin roofs.
                    min_radius: 0.5 * a,
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
            None => dims
                .notes
                .push("karst skipped: the geology has no soft strata (rho < 0.5)".into()),
        }
        Ok(())
    }

    /// Wind and rain erosion; together they are the overhangs feature (one report).
    fn weathering(&self, o: &mut Out<'_>) -> Result<()> {
        let recipe = self.recipe;
        let mut wind = self.has(Feature::Wind) || self.has(Feature::Overhangs);
        let mut rain = self.has(Feature::Rain) || self.has(Feature::Overhangs);
        if (wind || rain)
            && (self.too_coarse(Feature::Overhangs, &mut o.dims)
                || self.too_large(Feature::Overhangs, 0.5 * self.wr, None, o))
        {
            (wind, rain) = (false, false);
        }
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
        if let Some(mut h) = overhangs {
            // Soft rock retreating under resistant beds: the overhangs proper.
            let u = o.b.undercuts(
                &UndercutSettings {
                    depth: self.wr,
                    spacing: 0.5 * self.wr,
                    seed: self.sub(9),
                    ..Default::default()
                },
                &o.region,
            )?;
            h.candidates += u.candidates;
            h.primitives += u.primitives;
            h.features += u.features;
            h.sites = u.sites;
            h.axes = u.axes;
            h.sizes_m = u.sizes_m;
            o.effects.push((Feature::Overhangs, h));
        }
        Ok(())
    }

    /// Hoodoos, refused (with a note) on DEM cells coarser than their height.
    fn hoodoos(&self, o: &mut Out<'_>) -> Result<()> {
        let (height, radius) = (self.sz.hoodoo_height_m, self.sz.hoodoo_radius_m);
        let dims = &mut o.dims;
        (dims.hoodoo_height_m, dims.hoodoo_radius_m) = (height, radius);
        if self.too_coarse(Feature::Hoodoos, dims) {
            return Ok(());
        }
        dims.hoodoo_count = count(self.recipe.densities.hoodoos_per_km2, self.area_km2, 256);
        let h = HoodooSettings {
            count: dims.hoodoo_count,
            height,
            radius,
            spacing: 3.2 * radius,
            min_slope_deg: 15.0,
            max_slope_deg: 55.0,
            cap_rho: 0.55,
            per_cluster: 12,
            seed: self.sub(5),
        };
        let rep = o.b.hoodoos(&h, &o.region)?;
        if rep.features == 0 {
            o.dims.notes.push(format!(
                "hoodoos skipped: no ground sloping {:.0}-{:.0} degrees has a resistant bed \
                 (rho >= {}) {:.0}-{:.0} m over it with mostly soft rock under it",
                h.min_slope_deg,
                h.max_slope_deg,
                h.cap_rho,
                0.6 * height,
                1.4 * height
            ));
        }
        o.effects.push((Feature::Hoodoos, rep));
        Ok(())
    }

    /// Floating islands: clusters of three, main radius [`FeatureSizes::island_radius_m`], down
    /// to a third of that, floating four radii above the ground.
    fn islands(&self, o: &mut Out<'_>) -> Result<()> {
        let dims = &mut o.dims;
        dims.island_radius_m = self.sz.island_radius_m;
        dims.island_altitude_m = 4.0 * dims.island_radius_m;
        dims.island_count = count(self.recipe.densities.islands_per_km2, self.area_km2, 16);
        let i = IslandSettings {
            count: dims.island_count,
            radius: dims.island_radius_m,
            altitude: dims.island_altitude_m,
            per_cluster: 3,
            // The smallest island a third of the main one.
            spread: 3.0,
            seed: self.sub(7),
        };
        let rep = o.b.floating_islands(&i, &o.region)?;
        dims.island_radii_m = rep.sizes_m.clone();
        o.effects.push((Feature::Islands, rep));
        Ok(())
    }

    /// Arches, refused (with a note) on DEM cells coarser than half their span, or skipped when
    /// no ridge can carry one.
    fn arches(&self, o: &mut Out<'_>) -> Result<()> {
        let dims = &mut o.dims;
        let (span, thickness) = (self.sz.arch_span_m, self.sz.arch_thickness_m);
        dims.arch_span_m = span;
        dims.arch_height_m = 0.6 * span;
        dims.arch_thickness_m = thickness;
        if self.too_coarse(Feature::Arches, dims) {
            return Ok(());
        }
        dims.arch_count = count(self.recipe.densities.arches_per_km2, self.area_km2, 64);
        let a = ArchSettings {
            count: dims.arch_count,
            span,
            thickness,
            max_length: (5.0 * span).max(3.0 * self.l),
            seed: self.sub(6),
        };
        let rep = o.b.arches(&a, &o.region)?;
        // The smallest arch tried: 0.35 of the span, its opening 0.35 of that high.
        let small = 0.35 * span;
        if rep.features == 0 && rep.candidates == 0 {
            o.dims.notes.push(format!(
                "arches skipped: no ridge rises {:.0} m on both sides within {:.0} m",
                0.35 * small + (0.4 * thickness).max(1.0),
                a.max_length
            ));
        } else if rep.features == 0 {
            o.dims.notes.push(format!(
                "arches skipped: {} ridges are narrow enough, but on none does soft rock lie \
                 under a resistant bed 0.35 to 1 span above the floor with the ridge holding \
                 the bridge over it (spans {small:.0} to {:.0} m tried)",
                rep.candidates,
                3.0 * span
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
            let from = [-0.55, -0.7, 0.35];
            if let Some(c) = densest_karst(b, from) {
                highlights.push(Highlight {
                    feature: *f,
                    at: c,
                    from: Some(from),
                    cutaway: true,
                    size_m: None,
                });
            }
        } else if matches!(
            f,
            Feature::Hoodoos
                | Feature::Arches
                | Feature::Overhangs
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
                size_m: e.sizes_m.get(k).copied(),
            });
        }
    }
    highlights
}

/// Per placed feature, the distribution of its instances' sizes (m): measured per instance where
/// the generator reports it ([`EffectReport::sizes_m`]: karst radii per step, hoodoo heights,
/// arch spans, cave radii, island radii), else the nominal size once per primitive (notch and
/// weathering spheres) or once (cliff retreat).
fn size_stats(
    basis: &Basis<'_>,
    dims: &Dimensions,
    effects: &[(Feature, EffectReport)],
) -> std::collections::BTreeMap<String, SizeStats> {
    let mut out = std::collections::BTreeMap::new();
    for (f, e) in effects {
        let nominal = |v: f32, n: usize| vec![v; n];
        let (key, measure, sizes) = match f {
            Feature::Karst => ("karst", "passage radius", e.sizes_m.clone()),
            Feature::Hoodoos => ("hoodoos", "height", e.sizes_m.clone()),
            Feature::Arches => ("arches", "span", e.sizes_m.clone()),
            Feature::Islands => ("islands", "radius", e.sizes_m.clone()),
            Feature::Cliffs => ("cliffs", "retreat", nominal(dims.cliff_retreat_m, 1)),
            Feature::Sea | Feature::Caves => {
                let caves = e.sizes_m.len();
                if basis.has(Feature::Caves) {
                    out.insert(
                        "caves".to_string(),
                        SizeStats::of("cave radius", &e.sizes_m),
                    );
                }
                if *f == Feature::Caves {
                    continue;
                }
                let notches = e.primitives.saturating_sub(caves);
                ("sea", "notch radius", nominal(dims.sea_radius_m, notches))
            }
            Feature::Overhangs | Feature::Wind | Feature::Rain => {
                // Overhangs: the undercuts' depths apart from the weathering hollows.
                if !e.sizes_m.is_empty() {
                    out.insert(
                        "undercuts".to_string(),
                        SizeStats::of("undercut depth", &e.sizes_m),
                    );
                }
                let hollows = e.primitives.saturating_sub(e.sizes_m.len());
                (f.name(), "hollow radius", nominal(basis.wr, hollows))
            }
        };
        out.insert(key.to_string(), SizeStats::of(measure, &sizes));
    }
    out
}
