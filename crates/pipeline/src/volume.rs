//! Stage `volume`: 3D landforms on an implicit construction tree (Paris et al. 2018,
//! relief-implicit-volume). The input DEM as loaded (`input: "source"`, the default: the
//! landforms at the real terrain's own scale, with room for arches, islands and a karst
//! network) or the current terrain (`input: "terrain"`, e.g. the amplified DEM), its centre
//! cropped to `max_size` cells per side so the stage fits its budget, runs the [`VolumeJob`]
//! of `params.job`, the same settings
//! type `relief volume` fills from its flags: the features are generated, the scene is
//! polygonised (and simplified) and written as GLB, cut by a vertical section through the most
//! carved row and, in runs with previews, rendered (overview and close-ups). Reports the job's
//! figures: node counts by kind, sizes in metres, mesh size and topology, timings.
//!
//! The stage does not change the terrain and saves no raster (so it has no golden file). In
//! runs without previews (the golden run) it meshes at one voxel per DEM cell unless the job
//! sets a voxel, and skips the renders, to stay well under a second.

use anyhow::{Context, Result};
use relief_implicit_volume::{Feature, Recipe, VolumeJob};
use serde::{Deserialize, Serialize};

use super::spec::StageParams;
use super::{Stage, StageCx, StageInput};

/// Parameters of the `volume` stage (JSON `params`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct VolumeParams {
    /// The job, exactly as `relief volume` builds it ([`VolumeJob`]: `recipe` with
    /// `features`, `sea_level`, `scale`, `voxel`, `karst_budget`, `geology`, ...;
    /// `max_triangles`, `image_size`, ...). Its `recipe.seed` is mixed with the spec's.
    pub(crate) job: VolumeJob,
    /// The terrain's centre is cropped to at most this many cells per side (0 = no crop).
    pub(crate) max_size: usize,
    /// Which terrain the scene is built on.
    pub(crate) input: StageInput,
    /// Keep the terrain's own cells (`relief volume --raw-dem`): features that need finer
    /// cells are refused with a note instead of built on a refined window.
    pub(crate) raw_dem: bool,
}

impl Default for VolumeParams {
    fn default() -> Self {
        Self {
            job: VolumeJob {
                recipe: Recipe {
                    features: vec![
                        Feature::Sea,
                        Feature::Caves,
                        Feature::Karst,
                        Feature::Hoodoos,
                        Feature::Arches,
                        Feature::Islands,
                    ],
                    ..Default::default()
                },
                max_triangles: Some(300_000),
                max_mesh_cells: 2048,
                section: true,
                image_size: [480, 360],
                ..Default::default()
            },
            max_size: 128,
            input: StageInput::Source,
            raw_dem: false,
        }
    }
}

impl StageParams for VolumeParams {
    fn check_params(&self) -> Result<()> {
        self.job.check().context("invalid `job`")?;
        crate::check_max_size(self.max_size, 3)
    }
}

impl Stage for VolumeParams {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = self;
        let (terrain, which) = cx.input_terrain("volume", p.input)?;
        let mut hf = cx.centre_crop_to(terrain, p.max_size)?;
        let mut job = p.job.clone();
        job.recipe.seed ^= cx.config.seed;
        if !cx.config.previews {
            // The golden run: one voxel per DEM cell, no renders.
            let (ccx, ccy) = hf.cell_size();
            job.recipe.voxel = job.recipe.voxel.or(Some(ccx.max(ccy) as f32));
            job.render = false;
            job.closeups = false;
        } else {
            job.render = true;
            job.closeups = true;
            // As `relief volume`: a DEM coarser than the features need is replaced by a window
            // of it refined to their cell (the golden run keeps one voxel per DEM cell).
            if !p.raw_dem {
                let options = crate::volume_window::WindowOptions {
                    raw_dem: false,
                    mask: job.recipe.mask.is_some(),
                    sea_level: job.recipe.sea_level,
                    input: which,
                };
                if let Some(note) =
                    crate::volume_window::amplify_window(&mut hf, &mut job, &options)?
                {
                    cx.section.note(&note);
                    cx.section
                        .figure("amplified_window", [hf.width(), hf.height()]);
                }
            }
        }
        // Pre-flight under `relief run --max-memory`: the mesh and the images.
        cx.config.limits.check_memory(
            "volume",
            relief_implicit_volume::memory::volume_job_bytes(
                (hf.width(), hf.height()),
                hf.cell_size(),
                &job,
            ),
            "a larger `job.recipe.voxel`, a smaller `job.max_mesh_cells`, `max_size` or \
             `job.image_size`",
        )?;
        let progress = cx.progress();
        let out = job.run(&hf, &progress).context("cannot build the scene")?;
        let figures = serde_json::to_value(&out.figures).context("cannot encode the figures")?;
        if let Some(map) = figures.as_object() {
            for (k, v) in map {
                cx.section.figure(k, v);
            }
        }
        let rows = out
            .figures
            .effects
            .iter()
            .map(|(f, e)| {
                vec![
                    f.clone(),
                    e.candidates.to_string(),
                    e.primitives.to_string(),
                    e.count.to_string(),
                ]
            })
            .collect::<Vec<_>>();
        cx.section.table(
            "effects",
            &["feature", "candidates", "primitives", "count"],
            rows,
        );
        if let Some(mesh) = out.mesh.as_ref().filter(|m| !m.triangles.is_empty()) {
            let glb = cx.config.out_dir.join("volume.glb");
            let bytes = crate::write_mesh(&glb, mesh, false)
                .with_context(|| format!("cannot write {}", glb.display()))?;
            cx.section.file("volume.glb");
            cx.section.figure("glb_bytes", bytes);
        }
        if cx.config.previews {
            let y = out.figures.section_y_m.unwrap_or(0.0);
            let names = out.figures.closeups.clone().unwrap_or_default();
            for (img, file, caption) in [
                (
                    out.section.as_ref(),
                    "volume_section.png",
                    format!(
                        "vertical section west-east at y = {y:.0} m: strata by resistance, carved voids red"
                    ),
                ),
                (
                    out.render.as_ref(),
                    "volume_render.png",
                    format!(
                        "sphere-traced implicit scene ({} nodes), {}",
                        out.figures.tree_nodes,
                        match out.figures.sea_level_m {
                            Some(z) if out.figures.water_drawn => format!("sea level {z:.0} m"),
                            _ => "no sea".to_string(),
                        }
                    ),
                ),
                (
                    out.closeups.as_ref(),
                    "volume_closeups.png",
                    format!(
                        "close-ups, {}: {}",
                        if names.len() > 4 {
                            "rows of four, left to right"
                        } else {
                            "left to right"
                        },
                        names.join(", ")
                    ),
                ),
            ] {
                if let Some(img) = img {
                    let path = cx.config.out_dir.join(file);
                    relief_io::write_rgb_png(&path, img.width, img.height, &img.rgb)
                        .with_context(|| format!("cannot write {}", path.display()))?;
                    cx.section.image(file, &caption);
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::{PipelineConfig, State};
    use super::*;
    use std::time::Instant;

    /// The default stage on the golden crop (previews off, as in the golden run): features
    /// present, mesh watertight, implicitisation exact to a centimetre, a GLB written.
    #[test]
    fn stage_on_the_golden_crop() {
        let root = crate::test_root();
        let tmp = tempfile::tempdir().unwrap();
        let config = PipelineConfig::golden(&root, tmp.path().to_path_buf());
        let mut state = State::default();
        state.set_terrain(crate::test_input_crop(&config, config.crop.unwrap()));
        let t = Instant::now();
        let stage = VolumeParams::default();
        stage.check_params().unwrap();
        let section = crate::run_stage(&stage, "volume", &config, &mut state).unwrap();
        let secs = t.elapsed().as_secs_f64();
        let f = &section.figures;
        eprintln!("volume stage on the golden crop: {secs:.2} s");
        assert_eq!(f["mesh_watertight_manifold"], true, "{f:?}");
        assert!(f["implicitisation_max_dev_m"].as_f64().unwrap() < 0.01);
        // The canyon has no sea: sea and caves skipped with a note, no water.
        let notes = f["notes"].to_string();
        assert!(
            notes.contains("shore features skipped (sea, caves): no sea in this DEM"),
            "{notes}"
        );
        assert!(
            f["effects"]["sea"].is_null() && f["sea_level_m"].is_null(),
            "{f:?}"
        );
        assert_eq!(f["water_drawn"], false);
        // Every other feature carved or added something, or a note says why not: skipped, or
        // refused because its physical size needs finer DEM cells than the golden crop's.
        for k in ["karst", "hoodoos", "arches", "islands"] {
            let n = f["effects"][k]["primitives"].as_u64().unwrap_or(0);
            assert!(
                n > 0
                    || notes.contains(&format!("{k} skipped"))
                    || notes.contains(&format!("{k} refused: they need DEM cells of at most")),
                "{k}: {f:?}"
            );
        }
        eprintln!(
            "build {} s, mesh {} s, nodes {}",
            f["build_s"], f["mesh_s"], f["tree_nodes"]
        );
        assert!(f["tree_nodes"].as_u64().unwrap() > 500);
        assert!(f["section"]["carved"].as_u64().unwrap() > 0);
        assert!(tmp.path().join("volume.glb").is_file());
    }

    /// `input` chooses the DEM as loaded (the default) or the current terrain: a 24-cell
    /// source and a 16-cell "amplified" terrain of half the cell size give scenes of their own
    /// cell size.
    #[test]
    fn input_chooses_the_loaded_dem_or_the_current_terrain() {
        let root = crate::test_root();
        let tmp = tempfile::tempdir().unwrap();
        let config = PipelineConfig::golden(&root, tmp.path().to_path_buf());
        let source = crate::test_input_crop(&config, (200, 160, 24, 24));
        let (cx0, _) = source.cell_size();
        let current =
            relief_heightfield::Heightfield::from_fn(16, 16, cx0 / 2.0, cx0 / 2.0, |x, y| {
                1000.0 + (x * y) as f32
            });
        for (input, cell, which) in [
            (StageInput::Source, cx0, "the input DEM"),
            (StageInput::Terrain, cx0 / 2.0, "the current terrain"),
        ] {
            let mut state = State {
                source: Some(source.clone()),
                ..Default::default()
            };
            state.set_terrain(current.clone());
            let mut p = VolumeParams {
                input,
                ..Default::default()
            };
            p.job.recipe.features = vec![Feature::Karst];
            p.check_params().unwrap();
            let section = crate::run_stage(&p, "volume", &config, &mut state).unwrap();
            let f = &section.figures;
            assert_eq!(f["input"], which);
            let got = f["cell_size_m"][0].as_f64().unwrap();
            assert!((got - cell).abs() < 1e-6, "{input:?}: {got} vs {cell}");
        }
    }

    #[test]
    fn params_choose_features_and_reject_unknown_ones() {
        let p: VolumeParams = serde_json::from_value(
            serde_json::json!({ "job": { "recipe": { "features": ["caves"] } } }),
        )
        .unwrap();
        p.check_params().unwrap();
        assert_eq!(p.job.recipe.features, vec![Feature::Caves]);
        let e = serde_json::from_value::<VolumeParams>(
            serde_json::json!({ "job": { "recipe": { "features": ["lava"] } } }),
        )
        .unwrap_err();
        assert!(e.to_string().contains("lava"), "{e}");
        let p: VolumeParams =
            serde_json::from_value(serde_json::json!({ "job": { "max_triangles": 0 } })).unwrap();
        let e = p.check_params().unwrap_err();
        assert!(format!("{e:#}").contains("max_triangles"), "{e:#}");
        assert!(
            serde_json::from_value::<VolumeParams>(serde_json::json!({ "colour": 1 })).is_err()
        );
    }
}
