//! Stage `volume`: 3D landforms on an implicit construction tree (Paris et al. 2018,
//! relief-implicit-volume). The current terrain (its centre cropped to `max_size` cells per
//! side so the stage fits its budget) is implicitised, the chosen features are generated (sea
//! erosion and sea caves, a karst network, hoodoos, arches, floating islands, overhangs), the
//! scene is polygonised in chunks and written as GLB, rendered by sphere tracing and cut by a
//! vertical section through the most carved row. Reports node counts and memory, mesh size and
//! topology (watertight / manifold), the implicitisation deviation and timings.
//!
//! The stage does not change the terrain and saves no raster (so it has no golden file). In
//! runs without previews (the golden run) it meshes at one cell per DEM cell and skips the
//! render, to stay well under a second.

use std::time::Instant;

use anyhow::{Context, Result, bail};
use relief_implicit_volume::{
    Camera, Feature, MeshSettings, Recipe, RenderSettings, SectionSettings, build_recipe,
    field_normals, polygonize, render, section, simplify, topology,
};
use serde::Deserialize;

use super::{Stage, StageCx};

/// Parameters of the `volume` stage (JSON `params`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct VolumeParams {
    /// Features: any of `sea`, `caves`, `karst`, `hoodoos`, `arches`, `islands`,
    /// `overhangs` (e.g. `["caves"]` for implicit sea caves only).
    pub(crate) features: Vec<String>,
    /// The terrain's centre is cropped to at most this many cells per side (0 = no crop).
    pub(crate) max_size: usize,
    /// Sea level in metres (`null`: the 25th percentile of the elevations).
    pub(crate) sea_level: Option<f32>,
    /// Mesh cells per DEM cell (runs with previews; 1 without); `null` = the voxel derived
    /// by the recipe from the DEM.
    pub(crate) resolution: Option<f32>,
    /// Multiplies every feature size.
    pub(crate) scale: f32,
    /// Karst budget (carving steps); `null` = from the recipe's passage density.
    pub(crate) karst_budget: Option<usize>,
    /// Simplify the GLB to at most this many triangles (`null`: no simplification).
    pub(crate) max_triangles: Option<usize>,
    /// Render width and height in pixels.
    pub(crate) render_size: [usize; 2],
}

impl Default for VolumeParams {
    fn default() -> Self {
        Self {
            features: ["sea", "caves", "karst", "hoodoos", "arches", "islands"]
                .map(String::from)
                .to_vec(),
            max_size: 128,
            sea_level: None,
            resolution: None,
            scale: 1.0,
            karst_budget: None,
            max_triangles: Some(300_000),
            render_size: [480, 360],
        }
    }
}

impl VolumeParams {
    fn features(&self) -> Result<Vec<Feature>> {
        if self.features.is_empty() {
            bail!("`features` is empty");
        }
        Feature::parse_list(&self.features.join(",")).context("invalid `features`")
    }
}

/// The `volume` stage.
#[derive(Debug)]
pub(crate) struct VolumeStage(pub(crate) VolumeParams);

impl VolumeStage {
    /// Checks the parameters when the spec is read.
    pub(crate) fn new(p: VolumeParams) -> Result<Self> {
        p.features()?;
        if let Some(r) = p.resolution
            && !(r.is_finite() && r > 0.0 && r <= 8.0)
        {
            bail!("`resolution` = {r} must be in (0, 8]");
        }
        if p.max_triangles == Some(0) {
            bail!("`max_triangles` must be at least 1");
        }
        if p.render_size.iter().any(|&v| v == 0 || v > 4096) {
            bail!(
                "`render_size` = {:?}: each must be in 1..=4096",
                p.render_size
            );
        }
        if p.max_size != 0 && p.max_size < 3 {
            bail!("`max_size` = {} must be 0 or >= 3", p.max_size);
        }
        Ok(Self(p))
    }
}

impl Stage for VolumeStage {
    fn name(&self) -> &'static str {
        "volume"
    }

    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = &self.0;
        let terrain = cx.state.terrain()?;
        let (w, h) = (terrain.width(), terrain.height());
        let hf = if p.max_size > 0 && (w > p.max_size || h > p.max_size) {
            let (cw, ch) = (w.min(p.max_size), h.min(p.max_size));
            let (x, y) = ((w - cw) / 2, (h - ch) / 2);
            cx.section.figure("crop", [x, y, cw, ch]);
            terrain.crop(x, y, cw, ch)?
        } else {
            terrain.clone()
        };
        // Without previews (the golden run) the mesh is one cell per DEM cell.
        let (ccx, ccy) = hf.cell_size();
        let cell = ccx.max(ccy) as f32;
        let voxel = if cx.config.previews {
            p.resolution.map(|r| cell / r)
        } else {
            Some(cell)
        };
        let recipe = Recipe {
            features: p.features()?,
            sea_level: p.sea_level,
            scale: p.scale,
            voxel,
            karst_budget: p.karst_budget,
            seed: cx.config.seed,
            ..Default::default()
        };
        cx.section.figure(
            "features",
            recipe.features.iter().map(|f| f.name()).collect::<Vec<_>>(),
        );
        let progress = cx.progress();
        relief_heightfield::Progress::begin(&progress, "implicit scene", 0);
        let t = Instant::now();
        let (scene, rep) = build_recipe(&hf, &recipe).context("cannot build the scene")?;
        cx.section.figure("tree_build_s", t.elapsed().as_secs_f64());
        let st = scene.stats();
        cx.section.figure("tree_nodes", st.nodes);
        cx.section.figure("tree_primitives", st.primitives);
        cx.section.figure("tree_node_bytes", st.node_bytes);
        cx.section
            .figure("tree_heightfield_bytes", st.heightfield_bytes);
        cx.section
            .figure("geology_bytes", scene.geology().memory_bytes());
        cx.section.figure("sea_level_m", rep.sea_level);
        cx.section.figure("voxel_m", rep.dims.voxel_m);
        cx.section.figure("relief_m", rep.dims.relief_m);
        cx.section
            .figure("soft_thickness_m", rep.dims.soft_thickness_m);
        cx.section.figure("karst_radius_m", rep.dims.karst_radius_m);
        cx.section
            .figure("hoodoo_height_m", rep.dims.hoodoo_height_m);
        cx.section.figure("arch_span_m", rep.dims.arch_span_m);
        cx.section.figure("notes", &rep.dims.notes);
        for (k, n) in scene.tree().0.kind_counts() {
            cx.section.figure(&format!("tree_nodes_{k}"), n);
        }
        cx.section
            .figure("implicitisation_max_dev_m", rep.deviation.max);
        cx.section
            .figure("implicitisation_mean_dev_m", rep.deviation.mean);
        cx.section
            .figure("implicitisation_samples", rep.deviation.samples);
        let rows = rep
            .effects
            .iter()
            .map(|(f, e)| {
                cx.section.figure(&format!("{f}_primitives"), e.primitives);
                cx.section.figure(&format!("{f}_count"), e.features);
                if *f == Feature::Karst {
                    cx.section.figure("karst_passage_length_m", e.length_m);
                }
                vec![
                    f.to_string(),
                    e.candidates.to_string(),
                    e.primitives.to_string(),
                    e.features.to_string(),
                ]
            })
            .collect::<Vec<_>>();
        cx.section.table(
            "effects",
            &["feature", "candidates", "primitives", "count"],
            rows,
        );

        // Chunked polygonisation.
        let cell = rep.dims.voxel_m;
        let size = scene.bbox().size();
        let cells = [0, 1, 2].map(|k| ((size[k] / cell).ceil() as usize).clamp(2, 2048));
        relief_heightfield::Progress::begin(&progress, "polygonise", 0);
        let t = Instant::now();
        let (mut mesh, mr) = polygonize(
            &scene,
            &MeshSettings {
                cells,
                normals: p.max_triangles.is_none(),
                ..Default::default()
            },
        )?;
        cx.section.figure("mesh_s", t.elapsed().as_secs_f64());
        cx.section
            .figure("mesh_triangles_polygonised", mesh.triangles.len());
        if let Some(max) = p.max_triangles {
            let t = Instant::now();
            let (m, _) = simplify(&mesh, max)?;
            mesh = m;
            field_normals(&scene, &mut mesh, 0.25 * cell);
            cx.section.figure("simplify_s", t.elapsed().as_secs_f64());
        }
        let topo = topology(&mesh);
        cx.section.figure("mesh_grid", cells);
        cx.section.figure("mesh_chunks", mr.chunks);
        cx.section.figure("mesh_chunks_sampled", mr.chunks_sampled);
        cx.section.figure("mesh_vertices", mesh.positions.len());
        cx.section.figure("mesh_triangles", mesh.triangles.len());
        cx.section.figure("mesh_bad_edges", topo.bad_edges);
        cx.section
            .figure("mesh_misoriented_edges", topo.misoriented_edges);
        cx.section.figure("mesh_euler", topo.euler);
        cx.section.figure(
            "mesh_watertight_manifold",
            topo.bad_edges == 0 && topo.misoriented_edges == 0,
        );
        if !mesh.triangles.is_empty() {
            let glb = cx.config.out_dir.join("volume.glb");
            relief_io::write_mesh(&glb, &mesh.positions, &mesh.triangles, Some(&mesh.normals))
                .with_context(|| format!("cannot write {}", glb.display()))?;
            cx.section.file("volume.glb");
            cx.section.figure(
                "glb_bytes",
                std::fs::metadata(&glb).map(|m| m.len()).unwrap_or(0),
            );
        }

        // Vertical section through the most carved row (shows karst tunnels and sea caves).
        let (start, end) = rep.section_line;
        let (img, ss) = section(
            &scene,
            &SectionSettings {
                start,
                end,
                z_range: None,
                width: p.render_size[0],
                height: p.render_size[1] / 2,
            },
        )?;
        cx.section.figure("section_y_m", start[1]);
        cx.section.figure("section_solid_px", ss.solid);
        cx.section.figure("section_carved_px", ss.carved);
        cx.section.figure("section_enclosed_px", ss.enclosed);
        if cx.config.previews {
            let path = cx.config.out_dir.join("volume_section.png");
            relief_io::write_rgb_png(&path, img.width, img.height, &img.rgb)
                .with_context(|| format!("cannot write {}", path.display()))?;
            cx.section.image(
                "volume_section.png",
                &format!(
                    "vertical section west-east at y = {:.0} m: strata by resistance, carved voids red",
                    start[1]
                ),
            );
            relief_heightfield::Progress::begin(&progress, "render", 0);
            let t = Instant::now();
            let img = render(
                &scene,
                &Camera::overview(&scene.bbox()),
                &RenderSettings {
                    width: p.render_size[0],
                    height: p.render_size[1],
                    sea_level: rep.has_sea.then_some(rep.sea_level),
                    ..Default::default()
                },
            )?;
            cx.section.figure("render_s", t.elapsed().as_secs_f64());
            let path = cx.config.out_dir.join("volume_render.png");
            relief_io::write_rgb_png(&path, img.width, img.height, &img.rgb)
                .with_context(|| format!("cannot write {}", path.display()))?;
            cx.section.image(
                "volume_render.png",
                &format!(
                    "sphere-traced implicit scene ({} nodes), sea level {:.0} m",
                    st.nodes, rep.sea_level
                ),
            );
            // Close-ups on the first landforms of each kind (up to four).
            let t = Instant::now();
            let (img, names) = relief_implicit_volume::render_closeups(
                &scene,
                &rep,
                &RenderSettings {
                    width: p.render_size[0] / 2,
                    height: p.render_size[1] / 2,
                    sea_level: rep.has_sea.then_some(rep.sea_level),
                    ..Default::default()
                },
            )?;
            cx.section.figure("closeups_s", t.elapsed().as_secs_f64());
            let path = cx.config.out_dir.join("volume_closeups.png");
            relief_io::write_rgb_png(&path, img.width, img.height, &img.rgb)
                .with_context(|| format!("cannot write {}", path.display()))?;
            cx.section.image(
                "volume_closeups.png",
                &format!("close-ups, left to right: {}", names.join(", ")),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::{PipelineConfig, Section, State};
    use super::*;

    /// The default stage on the golden crop (previews off, as in the golden run): features
    /// present, mesh watertight, implicitisation exact to a centimetre, a GLB written.
    #[test]
    fn stage_on_the_golden_crop() {
        let root = crate::test_root();
        let tmp = tempfile::tempdir().unwrap();
        let config = PipelineConfig::golden(&root, tmp.path().to_path_buf());
        let raster = relief_io::read(&config.input, &relief_io::ReadOptions::default()).unwrap();
        let (x, y, w, h) = config.crop.unwrap();
        let mut state = State::default();
        state.set_terrain(raster.heightfield.crop(x, y, w, h).unwrap());
        let mut section = Section::new("volume");
        let mut cx = StageCx {
            config: &config,
            state: &mut state,
            section: &mut section,
        };
        let t = Instant::now();
        VolumeStage::new(VolumeParams::default())
            .unwrap()
            .run(&mut cx)
            .unwrap();
        let secs = t.elapsed().as_secs_f64();
        let f = &section.figures;
        eprintln!("volume stage on the golden crop: {secs:.2} s");
        assert_eq!(f["mesh_watertight_manifold"], true, "{f:?}");
        assert!(f["implicitisation_max_dev_m"].as_f64().unwrap() < 0.01);
        // Every feature carved or added something, or a note says why it could not be
        // resolved at one voxel per DEM cell (the golden run).
        let notes = f["notes"].to_string();
        for k in ["sea", "karst", "hoodoos", "arches", "islands"] {
            let n = f
                .get(&format!("{k}_primitives"))
                .and_then(|v| v.as_u64())
                .unwrap_or(0);
            assert!(
                n > 0 || notes.contains(&format!("{k} skipped")),
                "{k}: {f:?}"
            );
        }
        eprintln!(
            "build {} s, mesh {} s, nodes {}",
            f["tree_build_s"], f["mesh_s"], f["tree_nodes"]
        );
        assert!(f["tree_nodes"].as_u64().unwrap() > 500);
        assert!(f["section_carved_px"].as_u64().unwrap() > 0);
        assert!(tmp.path().join("volume.glb").is_file());
    }

    #[test]
    fn params_choose_features_and_reject_unknown_ones() {
        let p: VolumeParams =
            serde_json::from_value(serde_json::json!({ "features": ["caves"] })).unwrap();
        assert_eq!(
            VolumeStage::new(p).unwrap().0.features().unwrap(),
            vec![Feature::Caves]
        );
        let p: VolumeParams =
            serde_json::from_value(serde_json::json!({ "features": ["lava"] })).unwrap();
        let e = VolumeStage::new(p).unwrap_err();
        assert!(format!("{e:#}").contains("lava"), "{e:#}");
        assert!(
            serde_json::from_value::<VolumeParams>(serde_json::json!({ "colour": 1 })).is_err()
        );
    }
}
