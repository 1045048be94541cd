//! The `volume` job (issue 13's job layer): a [`Recipe`] plus what to make of the scene (a
//! mesh within a triangle budget, an overview render, close-ups, a vertical section), as one
//! serde settings type shared by `relief volume` and the pipeline's `volume` stage.
//! [`VolumeJob::run`] returns the products and the [`VolumeFigures`] a user wants (node
//! counts by kind, sizes in metres, counts, karst length, mesh size and topology, timings).

use relief_heightfield::param::in_range;
use std::collections::BTreeMap;
use std::time::Instant;

use relief_heightfield::{Heightfield, Progress};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::geology::GeologySpec;
use crate::mesh::{Mesh, MeshSettings, field_normals, polygonize_with_progress, topology};
use crate::recipe::{
    Dimensions, Recipe, RecipeReport, build_recipe_with_progress, render_closeups,
};
use crate::render::{
    Camera, Image, RenderSettings, SectionSettings, SectionStats, render_with_progress, section,
};
use crate::scene::Scene;
use crate::simplify::simplify_with_progress;

/// What `relief volume` and the pipeline's `volume` stage do with a DEM.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VolumeJob {
    /// Features, sizes, geology, seed ([`Recipe`]).
    pub recipe: Recipe,
    /// Polygonise the scene (one cell per recipe voxel).
    pub mesh: bool,
    /// Simplify the mesh to at most this many triangles (watertight edge collapses).
    pub max_triangles: Option<usize>,
    /// Largest mesh grid along an axis (cells); the voxel is the recipe's below it.
    pub max_mesh_cells: usize,
    /// Sphere-trace an overview.
    pub render: bool,
    /// Sphere-trace close-ups on the placed landforms (tiles of half `image_size`).
    pub closeups: bool,
    /// Cut a vertical section through the most carved row.
    pub section: bool,
    /// Render and section size `[width, height]` in pixels.
    pub image_size: [usize; 2],
}

impl Default for VolumeJob {
    fn default() -> Self {
        Self {
            recipe: Recipe::default(),
            mesh: true,
            max_triangles: None,
            max_mesh_cells: 4096,
            render: false,
            closeups: false,
            section: false,
            image_size: [640, 480],
        }
    }
}

/// What one effect did, for reports.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EffectFigures {
    /// Candidate samples considered.
    pub candidates: usize,
    /// Primitives added to the tree.
    pub primitives: usize,
    /// Landforms placed (karst: carved steps).
    pub count: usize,
    /// Karst passages / arch gaps: total length (m).
    pub length_m: f32,
    /// Karst: why the percolation ended (`budget`, `threshold`, `exhausted`).
    pub stop: Option<String>,
    /// Karst: soft-rock steps left uncarved because the rock above them is too thin.
    pub thin_cover: usize,
}

/// The figures of a [`VolumeJob`] run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VolumeFigures {
    /// DEM width (nodes).
    pub width: usize,
    /// DEM height (nodes).
    pub height: usize,
    /// DEM cell size (x, y) in metres.
    pub cell_size_m: [f64; 2],
    /// Seed.
    pub seed: u64,
    /// Sea level of the shore features (m): the recipe's, else the DEM's detected sea; `None`
    /// = no sea in the DEM and none set (shore features skipped, see `notes`).
    pub sea_level_m: Option<f32>,
    /// The sea detected in the DEM when the recipe sets no level
    /// ([`crate::recipe::detect_sea`]: level, rule, samples and their share).
    pub sea_detected: Option<crate::recipe::SeaDetection>,
    /// The floor given to the DEM's flat sea ([`crate::recipe::seabed`]: shore slope, depth,
    /// deepest sample, samples lowered); `None` = none (no flat sea, or `recipe.seabed` off).
    pub seabed: Option<crate::recipe::Seabed>,
    /// Whether the renders draw water (the scene has sea features).
    pub water_drawn: bool,
    /// Terrain tree nodes.
    pub tree_nodes: usize,
    /// Terrain tree primitives.
    pub tree_primitives: usize,
    /// Nodes by kind (`sphere_carving`, `capsule`, `heightfield`, `bvh`, ...).
    pub tree_nodes_by_kind: BTreeMap<String, usize>,
    /// Bytes of the node arena.
    pub tree_node_bytes: usize,
    /// Tree build time (s).
    pub build_s: f64,
    /// Largest vertical distance of the implicitised surface from the DEM (m).
    pub implicitisation_max_dev_m: f32,
    /// Mean vertical distance (m).
    pub implicitisation_mean_dev_m: f32,
    /// Sizes and counts derived from the DEM.
    pub dimensions: Dimensions,
    /// Features skipped or adjusted, and why.
    pub notes: Vec<String>,
    /// The geology used.
    pub geology: GeologySpec,
    /// Per applied feature.
    pub effects: BTreeMap<String, EffectFigures>,
    /// Length of the carved karst passages (m), when the karst ran.
    pub karst_passage_length_m: Option<f32>,
    /// Mesh grid (cells).
    pub mesh_grid: Option<[usize; 3]>,
    /// Meshing time (s).
    pub mesh_s: Option<f64>,
    /// Triangles out of the polygoniser.
    pub mesh_triangles_polygonised: Option<usize>,
    /// Simplification time (s).
    pub simplify_s: Option<f64>,
    /// Edge collapses the simplifier refused.
    pub simplify_refused: Option<usize>,
    /// Final mesh vertices.
    pub mesh_vertices: Option<usize>,
    /// Final mesh triangles.
    pub mesh_triangles: Option<usize>,
    /// Every edge shared by two consistently oriented triangles.
    pub mesh_watertight_manifold: Option<bool>,
    /// Euler characteristic of the final mesh.
    pub mesh_euler: Option<i64>,
    /// Look of the polygonised surface (before simplification, [`crate::surface_look`]):
    /// downward-facing area share and closed pits deeper than a quarter voxel, "small" when at
    /// most about two weathering spheres wide (the bubble-wrap of isolated carvings).
    pub mesh_look: Option<crate::SurfaceLook>,
    /// Chunks of the mesh grid / chunks sampled.
    pub mesh_chunks: Option<[usize; 2]>,
    /// Overview render time (s).
    pub render_s: Option<f64>,
    /// Close-up names, left to right.
    pub closeups: Option<Vec<String>>,
    /// Close-ups render time (s).
    pub closeups_s: Option<f64>,
    /// Section line y (m).
    pub section_y_m: Option<f32>,
    /// Section pixel counts.
    pub section: Option<SectionStats>,
}

/// The products of a [`VolumeJob`].
#[derive(Debug, Clone)]
pub struct VolumeOutput {
    /// The scene (to query, mesh or render again).
    pub scene: Scene,
    /// What the recipe did.
    pub report: RecipeReport,
    /// The mesh, if asked for.
    pub mesh: Option<Mesh>,
    /// The overview render.
    pub render: Option<Image>,
    /// The close-ups strip.
    pub closeups: Option<Image>,
    /// The vertical section.
    pub section: Option<Image>,
    /// The figures.
    pub figures: VolumeFigures,
}

/// [`VolumeJob::estimate_image_seconds`] times the images at 1/this of their width and height.
pub const PILOT_DIVISOR: usize = 4;
/// Smallest pilot image (width, height) in pixels.
const PILOT_MIN: [usize; 2] = [16, 12];

/// A built scene before its products ([`VolumeJob::build`]), so a caller can check the mesh
/// grid ([`Built::mesh_grid`]) against its memory before [`VolumeJob::finish`].
#[derive(Debug, Clone)]
pub struct Built {
    /// The scene.
    pub scene: Scene,
    /// What the recipe did.
    pub report: RecipeReport,
    /// The figures so far.
    pub figures: VolumeFigures,
}

impl Built {
    /// The mesh grid (cells along x, y, z) [`VolumeJob::finish`] will polygonise.
    pub fn mesh_grid(&self, job: &VolumeJob) -> [usize; 3] {
        let sz = self.scene.bbox().size();
        let v = self.report.dims.voxel_m;
        [0, 1, 2].map(|k| ((sz[k] / v).ceil() as usize).clamp(2, job.max_mesh_cells))
    }
}

impl VolumeFigures {
    /// A human-readable summary, one line per step (what `relief volume` prints).
    pub fn summary(&self) -> String {
        let d = &self.dimensions;
        let mut out = format!(
            "dem:          {}x{} ({:.1} x {:.1} m cells, {:.2} km2, relief {:.0} m), {}, voxel {:.2} m\n\
             implicitise:  surface vs DEM max {:.4} m, mean {:.5} m, floor {:.0} m deep\n",
            self.width,
            self.height,
            self.cell_size_m[0],
            self.cell_size_m[1],
            d.area_km2,
            d.relief_m,
            match (self.sea_level_m, self.sea_detected) {
                (Some(z), Some(s)) => format!(
                    "sea level {z:.1} m (detected: {:.1} % of the DEM)",
                    100.0 * s.share
                ),
                (Some(z), None) => format!("sea level {z:.1} m"),
                (None, _) => "no sea".to_string(),
            },
            d.voxel_m,
            self.implicitisation_max_dev_m,
            self.implicitisation_mean_dev_m,
            d.floor_depth_m
        );
        if let Some(t) = d.soft_thickness_m {
            out += &format!("geology:      soft strata {t:.1} m thick (median)\n");
        }
        for (f, e) in &self.effects {
            let extra = match f.as_str() {
                "karst" => format!(
                    ", {} steps, {:.2} km of passages of radius {:.1} m ({}; {} steps under \
                     too thin a roof left uncarved)",
                    e.count,
                    e.length_m / 1000.0,
                    d.karst_radius_m,
                    e.stop.as_deref().unwrap_or("-"),
                    e.thin_cover
                ),
                "hoodoos" => format!(
                    ", {} hoodoos under resistant cap beds near {:.0} m up, column radius {:.0} m \
                     at resistance 0.73 (narrower in soft rock)",
                    e.count, d.hoodoo_height_m, d.hoodoo_radius_m
                ),
                "arches" => format!(
                    ", {} arches (fins eroded through under a resistant bed), spans drawn \
                     around {:.0} m, fins {:.0} m thick, gaps {:.0} m long in all",
                    e.count, d.arch_span_m, d.arch_thickness_m, e.length_m
                ),
                "islands" => {
                    let r = &d.island_radii_m;
                    let (lo, hi) = r
                        .iter()
                        .fold((f32::INFINITY, 0.0f32), |(a, b), &x| (a.min(x), b.max(x)));
                    if r.is_empty() {
                        ", no room for an island".to_string()
                    } else {
                        format!(
                            ", {} islands in clusters, radii {lo:.0} to {hi:.0} m, {:.0} m up",
                            e.count, d.island_altitude_m
                        )
                    }
                }
                "cliffs" => format!(
                    ", {} columns, shore cut back {:.0} m",
                    e.count, d.cliff_retreat_m
                ),
                "sea" | "caves" => format!(
                    ", {} caves, spheres of {:.1} m up to {:.0} m above the sea",
                    e.count, d.sea_radius_m, d.sea_height_m
                ),
                _ => format!(", spheres of {:.1} m", d.weathering_radius_m),
            };
            out += &format!(
                "{:<13} {} primitives from {} candidates{extra}\n",
                format!("{f}:"),
                e.primitives,
                e.candidates
            );
        }
        for (f, z) in &d.sizes {
            out += &format!(
                "{:<13} {} {}: {:.1} / {:.1} / {:.1} m (min / median / max; p10-p90 {:.1}-{:.1} \
                 m)\n",
                format!("{f} size:"),
                z.count,
                z.measure,
                z.min,
                z.median,
                z.max,
                z.p10,
                z.p90
            );
        }
        for n in &self.notes {
            out += &format!("note:         {n}\n");
        }
        out += &format!(
            "tree:         {} nodes ({} primitives), {:.3} MB nodes; built in {:.3} s\n",
            self.tree_nodes,
            self.tree_primitives,
            self.tree_node_bytes as f64 / 1e6,
            self.build_s
        );
        if let (Some(p), Some(t)) = (self.mesh_triangles_polygonised, self.mesh_triangles)
            && let Some(s) = self.simplify_s
        {
            out += &format!("simplify:     {p} -> {t} triangles in {s:.3} s\n");
        }
        if let (Some(v), Some(t), Some(g), Some(w), Some(s)) = (
            self.mesh_vertices,
            self.mesh_triangles,
            self.mesh_grid,
            self.mesh_watertight_manifold,
            self.mesh_s,
        ) {
            out += &format!(
                "mesh:         {v} vertices, {t} triangles, grid {}x{}x{}, {} in {s:.3} s\n",
                g[0],
                g[1],
                g[2],
                if w {
                    "watertight, manifold"
                } else {
                    "NOT watertight"
                }
            );
        }
        if let Some(s) = self.render_s {
            out += &format!(
                "render:       in {s:.3} s{}\n",
                if self.water_drawn {
                    " (with water)"
                } else {
                    ""
                }
            );
        }
        if let (Some(n), Some(s)) = (&self.closeups, self.closeups_s) {
            out += &format!("close-ups:    {} ({}) in {s:.3} s\n", n.len(), n.join(", "));
        }
        if let (Some(y), Some(ss)) = (self.section_y_m, self.section) {
            out += &format!(
                "section:      y = {y:.0} m, {} solid / {} carved ({} enclosed) / {} air pixels\n",
                ss.solid, ss.carved, ss.enclosed, ss.air
            );
        }
        out
    }
}

impl VolumeJob {
    /// Checks every setting (each error names the field and the rule).
    pub fn check(&self) -> Result<()> {
        self.recipe.check()?;
        if self.max_triangles == Some(0) {
            return Err(Error::param("max_triangles", 0, "must be at least 1"));
        }
        in_range(
            "max_mesh_cells",
            self.max_mesh_cells,
            2..=8192,
            "must be in 2..=8192",
        )?;
        if self.image_size.iter().any(|&v| !(1..=8192).contains(&v)) {
            return Err(Error::param(
                "image_size",
                format!("{:?}", self.image_size),
                "each must be in 1..=8192",
            ));
        }
        Ok(())
    }

    /// Builds the scene of the recipe on `hf` (complete) and its figures.
    pub fn build(&self, hf: &Heightfield, progress: &dyn Progress) -> Result<Built> {
        self.check()?;
        progress.begin("building the implicit scene", 0);
        let t = Instant::now();
        let (scene, rep) = build_recipe_with_progress(hf, &self.recipe, progress)?;
        let build_s = t.elapsed().as_secs_f64();
        let st = scene.stats();
        let effects = rep
            .effects
            .iter()
            .map(|(f, e)| {
                (
                    f.to_string(),
                    EffectFigures {
                        candidates: e.candidates,
                        primitives: e.primitives,
                        count: e.features,
                        length_m: e.length_m,
                        stop: e.stop.map(|s| format!("{s:?}").to_lowercase()),
                        thin_cover: e.thin_cover,
                    },
                )
            })
            .collect();
        let figures = VolumeFigures {
            width: hf.width(),
            height: hf.height(),
            cell_size_m: [hf.cell_size().0, hf.cell_size().1],
            seed: self.recipe.seed,
            sea_level_m: rep.sea_level,
            sea_detected: rep.sea,
            seabed: rep.seabed,
            water_drawn: rep.has_sea,
            tree_nodes: st.nodes,
            tree_primitives: st.primitives,
            tree_nodes_by_kind: scene
                .tree()
                .0
                .kind_counts()
                .into_iter()
                .map(|(k, n)| (k.to_string(), n))
                .collect(),
            tree_node_bytes: st.node_bytes,
            build_s,
            implicitisation_max_dev_m: rep.deviation.max,
            implicitisation_mean_dev_m: rep.deviation.mean,
            dimensions: rep.dims.clone(),
            notes: rep.dims.notes.clone(),
            geology: rep.geology.clone(),
            effects,
            karst_passage_length_m: rep
                .effects
                .iter()
                .find(|(f, _)| *f == crate::recipe::Feature::Karst)
                .map(|(_, e)| e.length_m),
            mesh_grid: None,
            mesh_s: None,
            mesh_triangles_polygonised: None,
            simplify_s: None,
            simplify_refused: None,
            mesh_vertices: None,
            mesh_triangles: None,
            mesh_watertight_manifold: None,
            mesh_euler: None,
            mesh_look: None,
            mesh_chunks: None,
            render_s: None,
            closeups: None,
            closeups_s: None,
            section_y_m: None,
            section: None,
        };
        Ok(Built {
            scene,
            report: rep,
            figures,
        })
    }

    /// Makes the products asked for (mesh, render, close-ups, section) from a built scene.
    pub fn finish(&self, built: Built, progress: &dyn Progress) -> Result<VolumeOutput> {
        let cells = built.mesh_grid(self);
        let Built {
            scene,
            report: rep,
            mut figures,
        } = built;
        let f = &mut figures;
        let mut mesh = None;
        if self.mesh {
            progress.begin("polygonising", 0);
            let t = Instant::now();
            let (mut m, mr) = polygonize_with_progress(
                &scene,
                &MeshSettings {
                    cells,
                    normals: self.max_triangles.is_none(),
                    ..Default::default()
                },
                progress,
            )?;
            f.mesh_s = Some(t.elapsed().as_secs_f64());
            f.mesh_grid = Some(cells);
            f.mesh_chunks = Some([mr.chunks, mr.chunks_sampled]);
            f.mesh_triangles_polygonised = Some(m.triangles.len());
            let (v, r) = (rep.dims.voxel_m, rep.dims.weathering_radius_m);
            let max_cells = (std::f32::consts::PI * (2.0 * r / v).powi(2)).ceil() as usize;
            f.mesh_look = Some(crate::surface_look(&m, v, 0.25 * v, max_cells));
            if let Some(max) = self.max_triangles {
                progress.begin("simplifying", 0);
                let t = Instant::now();
                let (s, sr) = simplify_with_progress(&m, max, progress)?;
                m = s;
                field_normals(&scene, &mut m, 0.25 * rep.dims.voxel_m);
                f.simplify_s = Some(t.elapsed().as_secs_f64());
                f.simplify_refused = Some(sr.refused);
            }
            m.colours = crate::material::vertex_colours(&scene, &m);
            let topo = topology(&m);
            f.mesh_vertices = Some(m.positions.len());
            f.mesh_triangles = Some(m.triangles.len());
            f.mesh_watertight_manifold = Some(topo.bad_edges == 0 && topo.misoriented_edges == 0);
            f.mesh_euler = Some(topo.euler);
            mesh = Some(m);
        }
        let (overview, closeups, cut) =
            self.images(&scene, &rep, self.image_size, &mut figures, progress)?;
        Ok(VolumeOutput {
            scene,
            report: rep,
            mesh,
            render: overview,
            closeups,
            section: cut,
            figures,
        })
    }

    /// The images asked for (overview render, close-ups, section) at `size`, with their
    /// timings in `f`.
    fn images(
        &self,
        scene: &Scene,
        rep: &RecipeReport,
        size: [usize; 2],
        f: &mut VolumeFigures,
        progress: &dyn Progress,
    ) -> Result<(Option<Image>, Option<Image>, Option<Image>)> {
        let [w, h] = size;
        let settings = RenderSettings {
            width: w,
            height: h,
            sea_level: rep.sea_level.filter(|_| rep.has_sea),
            ..Default::default()
        };
        let mut overview = None;
        if self.render {
            progress.begin("rendering", h as u64);
            let t = Instant::now();
            overview = Some(render_with_progress(
                scene,
                &Camera::landscape(scene),
                &settings,
                progress,
            )?);
            f.render_s = Some(t.elapsed().as_secs_f64());
        }
        let mut closeups = None;
        if self.closeups {
            progress.begin("rendering close-ups", 0);
            let t = Instant::now();
            let tile = RenderSettings {
                width: (w / 2).max(1),
                height: (h / 2).max(1),
                ..settings
            };
            let (img, names) = render_closeups(scene, rep, &tile)?;
            f.closeups = Some(names);
            f.closeups_s = Some(t.elapsed().as_secs_f64());
            closeups = Some(img);
        }
        let mut cut = None;
        if self.section {
            progress.begin("cutting a section", 0);
            let (start, end) = rep.section_line;
            // From the closing floor to a little over the highest ground (floating islands
            // need the whole box).
            let d = &rep.dims;
            let z_range = scene
                .dem_floor()
                .filter(|_| {
                    !self
                        .recipe
                        .features
                        .contains(&crate::recipe::Feature::Islands)
                })
                .map(|f| (f, f + d.floor_depth_m + 1.15 * d.relief_m.max(d.voxel_m)));
            let (img, ss) = section(
                scene,
                &SectionSettings {
                    start,
                    end,
                    z_range,
                    width: w,
                    height: h,
                },
            )?;
            f.section_y_m = Some(start[1]);
            f.section = Some(ss);
            cut = Some(img);
        }
        Ok((overview, closeups, cut))
    }

    /// Estimated seconds of [`VolumeJob::finish`]'s images (render, close-ups, section) at
    /// this job's `image_size`, from timing the same images at 1/[`PILOT_DIVISOR`] of the width
    /// and height and scaling by the pixel count (the work is per pixel: one ray or one
    /// field sample each). `None` when no image is asked for. The pilot costs about
    /// 1/[`PILOT_DIVISOR`]^2 of the run it estimates; front ends use it to refuse a run over
    /// a time budget before starting it.
    pub fn estimate_image_seconds(&self, built: &Built) -> Result<Option<f64>> {
        if !(self.render || self.closeups || self.section) {
            return Ok(None);
        }
        let [w, h] = self.image_size;
        let pilot = [
            (w / PILOT_DIVISOR).max(PILOT_MIN[0]).min(w),
            (h / PILOT_DIVISOR).max(PILOT_MIN[1]).min(h),
        ];
        let t = Instant::now();
        self.images(
            &built.scene,
            &built.report,
            pilot,
            &mut built.figures.clone(),
            &relief_heightfield::NoProgress,
        )?;
        let ratio = (w as f64 * h as f64) / (pilot[0] as f64 * pilot[1] as f64);
        Ok(Some(t.elapsed().as_secs_f64() * ratio))
    }

    /// [`VolumeJob::build`] then [`VolumeJob::finish`].
    pub fn run(&self, hf: &Heightfield, progress: &dyn Progress) -> Result<VolumeOutput> {
        let built = self.build(hf, progress)?;
        self.finish(built, progress)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn job_round_trips_through_json_and_rejects_unknown_fields() {
        let job = VolumeJob::default();
        let text = serde_json::to_string(&job).unwrap();
        let back: VolumeJob = serde_json::from_str(&text).unwrap();
        assert_eq!(back, job);
        let e = serde_json::from_str::<VolumeJob>(r#"{"colour": 1}"#).unwrap_err();
        assert!(e.to_string().contains("colour"), "{e}");
        let e =
            serde_json::from_str::<VolumeJob>(r#"{"recipe": {"features": ["lava"]}}"#).unwrap_err();
        assert!(e.to_string().contains("lava"), "{e}");
        let j: VolumeJob =
            serde_json::from_str(r#"{"recipe": {"features": ["sea", "karst"]}}"#).unwrap();
        assert_eq!(
            j.recipe.features,
            vec![crate::recipe::Feature::Sea, crate::recipe::Feature::Karst]
        );
    }

    #[test]
    fn check_names_the_bad_field() {
        let bad = |j: VolumeJob, name: &str| {
            let e = j.check().unwrap_err().to_string();
            assert!(e.contains(name), "{name}: {e}");
        };
        bad(
            VolumeJob {
                max_triangles: Some(0),
                ..Default::default()
            },
            "max_triangles",
        );
        bad(
            VolumeJob {
                image_size: [0, 10],
                ..Default::default()
            },
            "image_size",
        );
        let mut j = VolumeJob::default();
        j.recipe.scale = -1.0;
        bad(j, "scale");
        let mut j = VolumeJob::default();
        j.recipe.wind = [0.0, 0.0];
        bad(j, "wind");
    }

    #[test]
    fn run_makes_the_products_asked_for() {
        let hf = Heightfield::from_fn(24, 24, 10.0, 10.0, |x, y| {
            20.0 + 2.0 * (x as f32 - 12.0).abs() + 0.5 * y as f32
        });
        let job = VolumeJob {
            recipe: Recipe {
                features: vec![crate::recipe::Feature::Karst, crate::recipe::Feature::Sea],
                ..Default::default()
            },
            max_triangles: Some(2000),
            section: true,
            image_size: [32, 24],
            ..Default::default()
        };
        let out = job.run(&hf, &relief_heightfield::NoProgress).unwrap();
        let m = out.mesh.as_ref().unwrap();
        assert!(m.triangles.len() <= 2000);
        assert_eq!(out.figures.mesh_watertight_manifold, Some(true));
        let look = out.figures.mesh_look.expect("a mesh has a look");
        assert!(look.raster[0] > 1 && look.raster[1] > 1, "{look:?}");
        assert!((0.0..0.5).contains(&look.downward_share), "{look:?}");
        assert!(look.small_pits <= look.pits, "{look:?}");
        assert!(out.render.is_none() && out.closeups.is_none());
        assert_eq!(out.section.as_ref().unwrap().width, 32);
        assert_eq!(
            out.figures.tree_nodes,
            out.figures.tree_nodes_by_kind.values().sum::<usize>()
        );
        let v = serde_json::to_value(&out.figures).unwrap();
        assert!(v["dimensions"]["voxel_m"].as_f64().unwrap() > 0.0, "{v}");
    }
}
