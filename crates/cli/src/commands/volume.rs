//! `relief volume IN --features sea,karst,... [--mesh OUT.glb] [--render OUT.png]
//! [--closeups OUT.png] [--section OUT.png] [--report OUT.json]`: 3D landforms on an implicit
//! construction tree (Paris et al. 2018, `relief-implicit-volume`): the DEM is implicitised, the
//! features are generated with sizes in metres derived from the DEM (or a `--geology` tree),
//! the scene is polygonised in chunks (optionally simplified to `--max-triangles`, GLB/PLY/OBJ
//! through relief-io), sphere-traced to an overview and close-ups on the features and cut by a
//! vertical section. Prints node counts, sizes, mesh size and timings on stdout; `--report`
//! writes them as JSON.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use relief_heightfield::{Heightfield, Progress};
use relief_implicit_volume::{
    Camera, Feature, GeologySpec, MeshSettings, Recipe, RenderSettings, SectionSettings,
    build_recipe, field_normals, polygonize, render, render_closeups, section, simplify, topology,
};
use serde_json::json;

use crate::ctx::Ctx;

/// Arguments of `relief volume`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input DEM (format detected from its content; must have no voids).
    pub(crate) input: PathBuf,
    /// Comma-separated features: cliffs, sea, caves, karst, hoodoos, arches, islands, overhangs
    /// (wind and rain), wind, rain.
    #[arg(long, default_value = "sea,karst,hoodoos,arches,islands")]
    pub(crate) features: String,
    /// Grey PNG (or any raster) of the DEM's size limiting every effect (0 = none, max = full).
    #[arg(long)]
    pub(crate) mask: Option<PathBuf>,
    /// Sea level in metres (default: the 25th percentile of the elevations).
    #[arg(long, allow_hyphen_values = true)]
    pub(crate) sea_level: Option<f32>,
    /// Write the polygonised scene (.glb, .ply or .obj).
    #[arg(long)]
    pub(crate) mesh: Option<PathBuf>,
    /// Write a sphere-traced shaded render (.png).
    #[arg(long)]
    pub(crate) render: Option<PathBuf>,
    /// Write a vertical cut-away section through the most carved row (.png).
    #[arg(long)]
    pub(crate) section: Option<PathBuf>,
    /// Seed of every effect.
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Write close-up renders on the placed features (.png: a row of tiles of half
    /// --image-size, one per kind of landform, at most four).
    #[arg(long)]
    pub(crate) closeups: Option<PathBuf>,
    /// Write the report (tree nodes by kind, sizes in metres, counts, karst length, timings) as
    /// JSON.
    #[arg(long)]
    pub(crate) report: Option<PathBuf>,
    /// Geology tree as JSON, nodes `{"type": "strata", "z0": M, "layers": [{"thickness": M,
    /// "hardness": 0..1}, ...]}`, `fold`, `fault`, `noise`, `warp`, `blend`, `max`, `min`,
    /// `uniform` (`GeologySpec` in relief-implicit-volume); default: layered strata scaled to
    /// the DEM's relief.
    #[arg(long)]
    pub(crate) geology: Option<PathBuf>,
    /// Crop `X,Y,W,H` (columns, rows) applied after reading.
    #[arg(long, value_parser = parse_crop)]
    pub(crate) crop: Option<(usize, usize, usize, usize)>,
    /// Meshing voxel edge in metres; feature sizes are checked against it (default: derived
    /// from the DEM's cell size, relief and extent).
    #[arg(long, conflicts_with = "resolution")]
    pub(crate) voxel: Option<f32>,
    /// Mesh cells per DEM cell horizontally (sets the voxel to the larger cell / N).
    #[arg(long)]
    pub(crate) resolution: Option<f32>,
    /// Simplify the mesh to at most this many triangles (quadric edge collapses that keep it
    /// watertight).
    #[arg(long)]
    pub(crate) max_triangles: Option<usize>,
    /// Multiplies every derived feature size (1 = physical defaults from the DEM).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) scale: f32,
    /// Karst budget in carving steps (default: from a passage density of 6 km per km^2).
    #[arg(long)]
    pub(crate) karst_budget: Option<usize>,
    /// Direction the wind blows towards, `X,Y` (x east, y north).
    #[arg(long, value_parser = parse_pair, allow_hyphen_values = true, default_value = "1,0.3")]
    pub(crate) wind: (f32, f32),
    /// Render and section size `WxH` in pixels.
    #[arg(long, default_value = "640x480", value_parser = parse_size)]
    pub(crate) image_size: (usize, usize),
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

fn parse_crop(s: &str) -> std::result::Result<(usize, usize, usize, usize), String> {
    let v: Vec<usize> = s
        .split(',')
        .map(|t| t.trim().parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("`{s}` is not X,Y,W,H (four non-negative integers)"))?;
    match v[..] {
        [x, y, w, h] if w >= 3 && h >= 3 => Ok((x, y, w, h)),
        _ => Err(format!("`{s}` is not X,Y,W,H with W, H >= 3")),
    }
}

fn parse_pair(s: &str) -> std::result::Result<(f32, f32), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("`{s}` is not X,Y"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{s}` is not X,Y (two finite numbers)"))
    };
    Ok((p(a)?, p(b)?))
}

fn parse_size(s: &str) -> std::result::Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}` is not WxH"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<usize>()
            .ok()
            .filter(|v| (1..=8192).contains(v))
            .ok_or_else(|| format!("`{s}`: each size must be in 1..=8192"))
    };
    Ok((p(w)?, p(h)?))
}

fn check_png(p: &Option<PathBuf>, what: &str) -> Result<()> {
    if let Some(p) = p {
        let ok = p
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
        if !ok {
            bail!("--{what} {}: the file must end in .png", p.display());
        }
    }
    Ok(())
}

/// Reads a mask raster and maps it to `[0, 1]`: values already in `[0, 1]` are kept, 8-bit
/// counts are divided by 255 and 16-bit counts by 65535.
fn read_mask(path: &Path, dem: &Heightfield, ctx: &Ctx) -> Result<Vec<f32>> {
    let raster = super::read_raster(path, &super::ReadArgs::default(), ctx)?;
    let m = raster.heightfield;
    if (m.width(), m.height()) != (dem.width(), dem.height()) {
        bail!(
            "mask {} is {}x{}, the DEM is {}x{}: they must match",
            path.display(),
            m.width(),
            m.height(),
            dem.width(),
            dem.height()
        );
    }
    let v = m.as_slice();
    if let Some(bad) = v.iter().find(|x| !x.is_finite() || **x < 0.0) {
        bail!(
            "mask {}: value {bad} is not a finite non-negative weight",
            path.display()
        );
    }
    let max = v.iter().cloned().fold(0.0f32, f32::max);
    let div = if max <= 1.0 {
        1.0
    } else if max <= 255.0 {
        255.0
    } else if max <= 65535.0 {
        65535.0
    } else {
        bail!(
            "mask {}: values up to {max}; expected [0, 1], 8-bit or 16-bit counts",
            path.display()
        );
    };
    Ok(v.iter().map(|x| x / div).collect())
}

/// Refuses a `--report` path that is not `.json`, is the input, or exists without `--force`.
fn check_report_path(report: &Path, input: &Path, ctx: &Ctx) -> Result<()> {
    let ok = report
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if !ok {
        bail!("--report {}: the file must end in .json", report.display());
    }
    if report.exists() {
        let same = std::fs::canonicalize(report).ok() == std::fs::canonicalize(input).ok();
        if same {
            bail!("--report {}: is the input", report.display());
        }
        if !ctx.force {
            bail!(
                "--report {}: exists (use --force to overwrite)",
                report.display()
            );
        }
    }
    Ok(())
}

fn read_geology(path: &Path) -> Result<GeologySpec> {
    let meta =
        std::fs::metadata(path).with_context(|| format!("cannot read {}", path.display()))?;
    if meta.len() > 16 << 20 {
        bail!(
            "--geology {}: {} bytes, at most 16 MiB",
            path.display(),
            meta.len()
        );
    }
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let spec: GeologySpec = serde_json::from_str(&text)
        .with_context(|| format!("--geology {}: not a geology tree", path.display()))?;
    spec.build()
        .with_context(|| format!("--geology {}: invalid geology", path.display()))?;
    Ok(spec)
}

/// Triangles per horizontal mesh cell assumed by the pre-flight estimate: a terrain surface
/// has 2; caves, arches, islands and overhangs add walls and ceilings. The default features on
/// a synthetic 128^2 DEM gave 22 (1.5 M triangles on a 262^2 grid; issue 18 measured 19 on its
/// case).
const TRIANGLES_PER_COLUMN: f64 = 24.0;

/// Peak bytes per triangle while meshing and writing: positions and normals of about half a
/// vertex (24 B), the triangle (12 B), the vertex map of the chunked polygoniser and the
/// encoded file built in memory before the atomic write (measured: 69-81 B at 1.5-6 M
/// triangles, release build).
const MESH_BYTES_PER_TRIANGLE: f64 = 90.0;

/// Bytes per file triangle (binary PLY/GLB: 12 B of indices plus half a vertex of 24 B).
const FILE_BYTES_PER_TRIANGLE: f64 = 26.0;

/// Bytes per pixel of the render and the section (RGB, depth, normals, per-ray state).
const IMAGE_BYTES_PER_PIXEL: f64 = 64.0;

/// Pre-flight estimate of the mesh (issue 18): triangles from the polygonisation grid, memory
/// against `--max-memory` and file size against `--max-output-size`, both naming
/// `--resolution`.
fn preflight_mesh(ctx: &Ctx, path: &Path, cells: [usize; 3], voxel_m: f64) -> Result<()> {
    let columns = cells[0] as f64 * cells[1] as f64;
    let triangles = columns * TRIANGLES_PER_COLUMN;
    let change = format!(
        "a larger --voxel or a smaller --resolution (the voxel is now {voxel_m:.3} m; the grid is \
         {}x{}x{}) or a --crop",
        cells[0], cells[1], cells[2]
    );
    ctx.check_output_size(
        &format!("the mesh {}", path.display()),
        triangles * FILE_BYTES_PER_TRIANGLE,
        &change,
    )?;
    ctx.check_memory(
        &format!("volume with {voxel_m:.3} m voxels"),
        &[&[crate::memory::part(
            format!("the mesh (about {:.0} M triangles)", triangles / 1e6),
            triangles * MESH_BYTES_PER_TRIANGLE,
            change,
        )]],
    )
}

/// The summary printed on stdout and the `--report` JSON of a built scene (before meshing and
/// rendering add their lines and fields).
fn describe(
    args: &Args,
    hf: &Heightfield,
    scene: &relief_implicit_volume::Scene,
    rep: &relief_implicit_volume::RecipeReport,
    t_build: f64,
) -> Result<(String, serde_json::Value)> {
    let st = scene.stats();
    let dims = &rep.dims;
    let (cx, cy) = hf.cell_size();
    let mut out = String::new();
    out.push_str(&format!(
        "dem:          {}x{} ({:.1} x {:.1} m cells, {:.2} km2, relief {:.0} m), sea level {:.1} m, voxel {:.2} m\n",
        hf.width(),
        hf.height(),
        cx,
        cy,
        dims.area_km2,
        dims.relief_m,
        rep.sea_level,
        dims.voxel_m
    ));
    out.push_str(&format!(
        "implicitise:  surface vs DEM max {:.4} m, mean {:.5} m ({} nodes), floor {:.0} m deep\n",
        rep.deviation.max, rep.deviation.mean, rep.deviation.samples, dims.floor_depth_m
    ));
    if let Some(t) = dims.soft_thickness_m {
        out.push_str(&format!(
            "geology:      soft strata {t:.1} m thick (median)\n"
        ));
    }
    for (f, e) in &rep.effects {
        let extra = match f {
            Feature::Karst => format!(
                ", {} steps, {:.2} km of passages of radius {:.1} m ({:?})",
                e.features,
                e.length_m / 1000.0,
                dims.karst_radius_m,
                e.stop.map_or("-".to_string(), |s| format!("{s:?}"))
            ),
            Feature::Hoodoos => format!(
                ", {} hoodoos {:.0} m tall, radius {:.0} m",
                e.features, dims.hoodoo_height_m, dims.hoodoo_radius_m
            ),
            Feature::Arches => format!(
                ", {} arches spanning {:.0} m, {:.0} m thick",
                e.features, dims.arch_span_m, dims.arch_thickness_m
            ),
            Feature::Islands => format!(
                ", {} islands of radius {:.0} m",
                e.features, dims.island_radius_m
            ),
            Feature::Cliffs => format!(
                ", {} columns, shore cut back {:.0} m",
                e.features, dims.cliff_retreat_m
            ),
            Feature::Sea | Feature::Caves => format!(
                ", {} caves, spheres of {:.1} m up to {:.0} m above the sea",
                e.features, dims.sea_radius_m, dims.sea_height_m
            ),
            _ => format!(", spheres of {:.1} m", dims.weathering_radius_m),
        };
        out.push_str(&format!(
            "{:<13} {} primitives from {} candidates{extra}\n",
            format!("{f}:"),
            e.primitives,
            e.candidates
        ));
    }
    for n in &dims.notes {
        out.push_str(&format!("note:         {n}\n"));
    }
    out.push_str(&format!(
        "tree:         {} nodes ({} primitives), {:.3} MB nodes + {:.3} MB DEM; built in {t_build:.3} s\n",
        st.nodes,
        st.primitives,
        st.node_bytes as f64 / 1e6,
        st.heightfield_bytes as f64 / 1e6
    ));
    let mut report = json!({
        "input": args.input.display().to_string(),
        "width": hf.width(),
        "height": hf.height(),
        "cell_size_m": [cx, cy],
        "seed": args.seed,
        "sea_level_m": rep.sea_level,
        "water_drawn": rep.has_sea,
        "tree_nodes": st.nodes,
        "tree_primitives": st.primitives,
        "tree_nodes_by_kind": scene
            .tree()
            .0
            .kind_counts()
            .into_iter()
            .map(|(k, n)| (k.to_string(), json!(n)))
            .collect::<serde_json::Map<_, _>>(),
        "tree_node_bytes": st.node_bytes,
        "build_s": t_build,
        "implicitisation_max_dev_m": rep.deviation.max,
        "dimensions": {
            "cell_m": dims.cell_m,
            "relief_m": dims.relief_m,
            "area_km2": dims.area_km2,
            "voxel_m": dims.voxel_m,
            "floor_depth_m": dims.floor_depth_m,
            "strata_period_m": dims.strata_period_m,
            "soft_thickness_m": dims.soft_thickness_m,
            "karst_radius_m": dims.karst_radius_m,
            "karst_step_m": dims.karst_step_m,
            "karst_budget": dims.karst_budget,
            "hoodoo_height_m": dims.hoodoo_height_m,
            "hoodoo_radius_m": dims.hoodoo_radius_m,
            "arch_span_m": dims.arch_span_m,
            "arch_height_m": dims.arch_height_m,
            "arch_thickness_m": dims.arch_thickness_m,
            "island_radius_m": dims.island_radius_m,
            "island_altitude_m": dims.island_altitude_m,
            "sea_radius_m": dims.sea_radius_m,
            "sea_height_m": dims.sea_height_m,
            "cave_length_m": dims.cave_length_m,
            "weathering_radius_m": dims.weathering_radius_m,
            "cliff_retreat_m": dims.cliff_retreat_m,
        },
        "notes": dims.notes,
        "geology": serde_json::to_value(&rep.geology).context("cannot encode the geology")?,
    });
    let effects: serde_json::Map<String, serde_json::Value> = rep
        .effects
        .iter()
        .map(|(f, e)| {
            (
                f.to_string(),
                json!({
                    "candidates": e.candidates,
                    "primitives": e.primitives,
                    "count": e.features,
                    "length_m": e.length_m,
                    "stop": e.stop.map(|s| format!("{s:?}").to_lowercase()),
                }),
            )
        })
        .collect();
    report["effects"] = effects.into();
    if let Some(karst) = rep.effects.iter().find(|(f, _)| *f == Feature::Karst) {
        report["karst_passage_length_m"] = json!(karst.1.length_m);
    }

    Ok((out, report))
}

/// Polygonises the scene on a `cells` grid (voxel `cell` metres), simplifies it under
/// `--max-triangles`, checks its topology and writes it to its staged path; adds its lines to
/// `out` and its fields to `report`.
fn write_mesh_output(
    args: &Args,
    path: &Path,
    scene: &relief_implicit_volume::Scene,
    cells: [usize; 3],
    cell: f32,
    staged: &crate::staging::Outputs,
    progress: &crate::ctx::CliProgress,
    out: &mut String,
    report: &mut serde_json::Value,
) -> Result<()> {
    progress.begin("polygonising", 0);
    let t = Instant::now();
    let (mut mesh, mr) = polygonize(
        scene,
        &MeshSettings {
            cells,
            normals: args.max_triangles.is_none(),
            ..Default::default()
        },
    )
    .context("cannot polygonise the scene")?;
    let t_mesh = t.elapsed().as_secs_f64();
    report["mesh_s"] = json!(t_mesh);
    report["mesh_grid"] = json!(cells);
    report["mesh_triangles_polygonised"] = json!(mesh.triangles.len());
    if let Some(max) = args.max_triangles {
        progress.begin("simplifying", 0);
        let t = Instant::now();
        let (m, sr) = simplify(&mesh, max).context("cannot simplify the mesh")?;
        mesh = m;
        field_normals(scene, &mut mesh, 0.25 * cell);
        let t_simp = t.elapsed().as_secs_f64();
        report["simplify_s"] = json!(t_simp);
        out.push_str(&format!(
            "simplify:     {} -> {} triangles ({} collapses refused) in {t_simp:.3} s\n",
            sr.triangles_in, sr.triangles_out, sr.refused
        ));
    }
    let topo = topology(&mesh);
    let watertight = topo.bad_edges == 0 && topo.misoriented_edges == 0;
    report["mesh_vertices"] = json!(mesh.positions.len());
    report["mesh_triangles"] = json!(mesh.triangles.len());
    report["mesh_watertight_manifold"] = json!(watertight);
    report["mesh_euler"] = json!(topo.euler);
    out.push_str(&format!(
        "mesh:         {} vertices, {} triangles, grid {}x{}x{} ({}/{} chunks sampled), {} in {t_mesh:.3} s\n",
        mesh.positions.len(),
        mesh.triangles.len(),
        cells[0],
        cells[1],
        cells[2],
        mr.chunks_sampled,
        mr.chunks,
        if watertight {
            "watertight, manifold".to_string()
        } else {
            format!(
                "{} open/non-manifold edges, {} misoriented",
                topo.bad_edges, topo.misoriented_edges
            )
        }
    ));
    let normals = (!mesh.normals.is_empty()).then_some(&mesh.normals[..]);
    let t = Instant::now();
    relief_io::write_mesh(
        &staged.path(path),
        &mesh.positions,
        &mesh.triangles,
        normals,
    )
    .with_context(|| format!("cannot write {}", path.display()))?;
    let bytes = std::fs::metadata(staged.path(path))
        .map(|m| m.len())
        .unwrap_or(0);
    report["mesh_bytes"] = json!(bytes);
    out.push_str(&format!(
        "wrote {} ({:.1} MB) in {:.3} s\n",
        path.display(),
        bytes as f64 / 1e6,
        t.elapsed().as_secs_f64()
    ));
    Ok(())
}

/// Writes the overview render, the close-ups and the vertical section that were asked for, at
/// `--image-size`; adds their lines to `out` and their fields to `report`.
fn write_images(
    args: &Args,
    scene: &relief_implicit_volume::Scene,
    rep: &relief_implicit_volume::RecipeReport,
    staged: &crate::staging::Outputs,
    progress: &crate::ctx::CliProgress,
    out: &mut String,
    report: &mut serde_json::Value,
) -> Result<()> {
    let (w, h) = args.image_size;
    let settings = RenderSettings {
        width: w,
        height: h,
        sea_level: rep.has_sea.then_some(rep.sea_level),
        ..Default::default()
    };
    if let Some(path) = &args.render {
        progress.begin("rendering", 0);
        let t = Instant::now();
        let img = render(scene, &Camera::overview(&scene.bbox()), &settings)
            .context("cannot render the scene")?;
        relief_io::write_rgb_png(&staged.path(path), img.width, img.height, &img.rgb)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let secs = t.elapsed().as_secs_f64();
        report["render_s"] = json!(secs);
        out.push_str(&format!(
            "render:       {}x{} in {secs:.3} s, wrote {}{}\n",
            w,
            h,
            path.display(),
            if rep.has_sea { " (with water)" } else { "" }
        ));
    }
    if let Some(path) = &args.closeups {
        progress.begin("rendering close-ups", 0);
        let t = Instant::now();
        // Tiles of half the image size, side by side.
        let tile = RenderSettings {
            width: (w / 2).max(1),
            height: (h / 2).max(1),
            ..settings
        };
        let (img, names) =
            render_closeups(scene, rep, &tile).context("cannot render the close-ups")?;
        relief_io::write_rgb_png(&staged.path(path), img.width, img.height, &img.rgb)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let secs = t.elapsed().as_secs_f64();
        report["closeups"] = json!(names);
        report["closeups_s"] = json!(secs);
        out.push_str(&format!(
            "close-ups:    {} ({}) in {secs:.3} s, wrote {}\n",
            names.len(),
            names.join(", "),
            path.display()
        ));
    }
    if let Some(path) = &args.section {
        progress.begin("cutting a section", 0);
        let t = Instant::now();
        let (start, end) = rep.section_line;
        let (img, ss) = section(
            scene,
            &SectionSettings {
                start,
                end,
                z_range: None,
                width: w,
                height: h,
            },
        )
        .context("cannot cut the section")?;
        relief_io::write_rgb_png(&staged.path(path), img.width, img.height, &img.rgb)
            .with_context(|| format!("cannot write {}", path.display()))?;
        report["section_carved_px"] = json!(ss.carved);
        report["section_enclosed_px"] = json!(ss.enclosed);
        out.push_str(&format!(
            "section:      y = {:.0} m, {} solid / {} carved ({} enclosed) / {} air pixels in {:.3} s, wrote {}\n",
            start[1],
            ss.solid,
            ss.carved,
            ss.enclosed,
            ss.air,
            t.elapsed().as_secs_f64(),
            path.display()
        ));
    }
    Ok(())
}

/// Builds the scene and writes the requested outputs.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    // Everything that can be checked without work is checked before any output is written.
    let features = Feature::parse_list(&args.features).context("bad --features")?;
    if let Some(m) = &args.mesh
        && relief_io::MeshFormat::from_extension(m).is_none()
    {
        bail!(
            "--mesh {}: the file must end in .glb, .ply or .obj",
            m.display()
        );
    }
    check_png(&args.render, "render")?;
    check_png(&args.closeups, "closeups")?;
    check_png(&args.section, "section")?;
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(args.mask.as_deref());
    inputs.extend(args.geology.as_deref());
    let mut outputs: Vec<(&Path, crate::outputs::OutKind)> = Vec::new();
    outputs.extend(
        args.mesh
            .as_deref()
            .map(|p| (p, crate::outputs::OutKind::Mesh)),
    );
    for p in [&args.render, &args.closeups, &args.section]
        .into_iter()
        .flatten()
    {
        outputs.push((p.as_path(), crate::outputs::OutKind::Png));
    }
    if outputs.is_empty() && args.report.is_none() {
        bail!(
            "nothing to write for {}: give at least one of --mesh, --render, --closeups, \
             --section or --report",
            args.input.display()
        );
    }
    ctx.check_outputs(&inputs, &outputs)?;
    if let Some(r) = &args.report {
        check_report_path(r, &args.input, ctx)?;
        if outputs.iter().any(|(p, _)| *p == r.as_path()) {
            bail!("--report {}: also named as another output", r.display());
        }
    }
    if let Some(r) = args.resolution
        && !(r.is_finite() && r > 0.0 && r <= 64.0)
    {
        bail!("--resolution {r}: must be in (0, 64]");
    }
    if let Some(v) = args.voxel
        && !(v.is_finite() && v > 0.0)
    {
        bail!("--voxel {v}: must be finite and > 0");
    }
    if args.max_triangles == Some(0) {
        bail!("--max-triangles 0: must be at least 1");
    }
    let geology = match &args.geology {
        Some(p) => Some(read_geology(p)?),
        None => None,
    };
    // The mesh, the images and the report appear together or not at all.
    let mut targets: Vec<&Path> = outputs.iter().map(|&(p, _)| p).collect();
    targets.extend(args.report.as_deref());
    let staged = crate::staging::Outputs::new(&targets)?;
    let raster = super::read_raster(&args.input, &args.read, ctx)?;
    let mut hf = raster.heightfield;
    if let Some((x, y, w, h)) = args.crop {
        hf = hf
            .crop(x, y, w, h)
            .with_context(|| format!("cannot crop {}", args.input.display()))?;
    }
    hf.require_complete()
        .with_context(|| format!("{} cannot be implicitised", args.input.display()))?;
    let mask = match &args.mask {
        Some(p) => Some(read_mask(p, &hf, ctx)?),
        None => None,
    };
    let (cx, cy) = hf.cell_size();
    let voxel = args
        .voxel
        .or(args.resolution.map(|r| cx.max(cy) as f32 / r));
    let recipe = Recipe {
        features,
        sea_level: args.sea_level,
        mask,
        scale: args.scale,
        voxel,
        geology,
        karst_budget: args.karst_budget,
        wind: [args.wind.0, args.wind.1],
        seed: args.seed,
        ..Default::default()
    };
    let progress = ctx.progress();
    progress.begin("building the implicit scene", 0);
    let t = Instant::now();
    let (scene, rep) = build_recipe(&hf, &recipe).context("cannot build the scene")?;
    let t_build = t.elapsed().as_secs_f64();
    let (mut out, mut report) = describe(&args, &hf, &scene, &rep, t_build)?;
    let dims = &rep.dims;
    let b = scene.bbox();
    let cell = dims.voxel_m;
    let sz = b.size();
    let cells = [0, 1, 2].map(|k| ((sz[k] / cell).ceil() as usize).clamp(2, 4096));
    if let Some(path) = &args.mesh {
        preflight_mesh(ctx, path, cells, dims.voxel_m as f64)?;
    }
    if args.render.is_some() || args.section.is_some() {
        let (w, h) = args.image_size;
        ctx.check_memory(
            "volume",
            &[&[crate::memory::part(
                "the render and section images",
                w as f64 * h as f64 * IMAGE_BYTES_PER_PIXEL,
                "a smaller --image-size",
            )]],
        )?;
    }
    if let Some(path) = &args.mesh {
        write_mesh_output(
            &args,
            path,
            &scene,
            cells,
            cell,
            &staged,
            &progress,
            &mut out,
            &mut report,
        )?;
    }
    write_images(
        &args,
        &scene,
        &rep,
        &staged,
        &progress,
        &mut out,
        &mut report,
    )?;
    if let Some(path) = &args.report {
        let mut text = serde_json::to_string_pretty(&report).context("cannot encode the report")?;
        text.push('\n');
        relief_io::write_bytes_atomic(&staged.path(path), text.as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        out.push_str(&format!("report:       wrote {}\n", path.display()));
    }
    staged.commit()?;
    drop(progress);
    let mut stdout = std::io::stdout().lock();
    std::io::Write::write_all(&mut stdout, out.as_bytes()).context("cannot write to stdout")?;
    Ok(())
}
