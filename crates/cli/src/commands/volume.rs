//! `relief volume IN --features sea,karst,... [--mesh OUT.glb] [--render OUT.png]
//! [--section OUT.png]`: 3D landforms on an implicit construction tree (Paris et al. 2018,
//! `relief-implicit-volume`): the DEM is implicitised, the features are generated, the scene is
//! polygonised in chunks (GLB/PLY/OBJ through relief-io), sphere-traced to a PNG and cut by a
//! vertical section. Prints node counts, mesh size and timings on stdout.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use relief_heightfield::{Heightfield, Progress};
use relief_implicit_volume::{
    Camera, Feature, MeshSettings, Recipe, RenderSettings, SectionSettings, build_recipe,
    polygonize, render, section, topology,
};

use crate::ctx::Ctx;

/// Arguments of `relief volume`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input DEM (format detected from its content; must have no voids).
    pub(crate) input: PathBuf,
    /// Comma-separated features: sea, caves, karst, hoodoos, arches, islands, overhangs.
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
    /// Crop `X,Y,W,H` (columns, rows) applied after reading.
    #[arg(long, value_parser = parse_crop)]
    pub(crate) crop: Option<(usize, usize, usize, usize)>,
    /// Mesh cells per DEM cell horizontally (the vertical cell is the same size in metres).
    #[arg(long, default_value_t = 2.0)]
    pub(crate) resolution: f32,
    /// Multiplies every feature size (1 = scaled to the DEM cell).
    #[arg(long, default_value_t = 1.0)]
    pub(crate) scale: f32,
    /// Karst budget (carving steps).
    #[arg(long, default_value_t = 600)]
    pub(crate) karst_budget: usize,
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
fn preflight_mesh(ctx: &Ctx, path: &Path, cells: [usize; 3], resolution: f32) -> Result<()> {
    let columns = cells[0] as f64 * cells[1] as f64;
    let triangles = columns * TRIANGLES_PER_COLUMN;
    let change = format!(
        "a smaller --resolution (now {resolution}; the grid is {}x{}x{}) or a --crop",
        cells[0], cells[1], cells[2]
    );
    ctx.check_output_size(
        &format!("the mesh {}", path.display()),
        triangles * FILE_BYTES_PER_TRIANGLE,
        &change,
    )?;
    ctx.check_memory(
        &format!("volume --resolution {resolution}"),
        &[&[crate::memory::part(
            format!("the mesh (about {:.0} M triangles)", triangles / 1e6),
            triangles * MESH_BYTES_PER_TRIANGLE,
            change,
        )]],
    )
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
    check_png(&args.section, "section")?;
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(args.mask.as_deref());
    let mut outputs: Vec<(&Path, crate::outputs::OutKind)> = Vec::new();
    outputs.extend(
        args.mesh
            .as_deref()
            .map(|p| (p, crate::outputs::OutKind::Mesh)),
    );
    outputs.extend(
        args.render
            .as_deref()
            .map(|p| (p, crate::outputs::OutKind::Png)),
    );
    outputs.extend(
        args.section
            .as_deref()
            .map(|p| (p, crate::outputs::OutKind::Png)),
    );
    if outputs.is_empty() {
        bail!(
            "nothing to write for {}: give at least one of --mesh, --render or --section",
            args.input.display()
        );
    }
    ctx.check_outputs(&inputs, &outputs)?;
    if !(args.resolution.is_finite() && args.resolution > 0.0 && args.resolution <= 16.0) {
        bail!("--resolution {}: must be in (0, 16]", args.resolution);
    }
    // The mesh, the render and the section appear together or not at all.
    let targets: Vec<&Path> = outputs.iter().map(|&(p, _)| p).collect();
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
    let recipe = Recipe {
        features,
        sea_level: args.sea_level,
        mask,
        scale: args.scale,
        karst_budget: args.karst_budget,
        seed: args.seed,
    };
    let progress = ctx.progress();
    progress.begin("building the implicit scene", 0);
    let t = Instant::now();
    let (scene, rep) = build_recipe(&hf, &recipe).context("cannot build the scene")?;
    let t_build = t.elapsed().as_secs_f64();
    let st = scene.stats();
    let mut out = String::new();
    out.push_str(&format!(
        "dem:          {}x{} ({:.1} m cells), sea level {:.1} m, unit L = {:.1} m\n",
        hf.width(),
        hf.height(),
        hf.cell_size().0,
        rep.sea_level,
        rep.unit
    ));
    out.push_str(&format!(
        "implicitise:  surface vs DEM max {:.4} m, mean {:.5} m ({} nodes)\n",
        rep.deviation.max, rep.deviation.mean, rep.deviation.samples
    ));
    for (f, e) in &rep.effects {
        out.push_str(&format!(
            "{:<13} {} primitives from {} candidates\n",
            format!("{f}:"),
            e.primitives,
            e.candidates
        ));
    }
    out.push_str(&format!(
        "tree:         {} nodes ({} primitives), {:.3} MB nodes + {:.3} MB DEM; built in {t_build:.3} s\n",
        st.nodes,
        st.primitives,
        st.node_bytes as f64 / 1e6,
        st.heightfield_bytes as f64 / 1e6
    ));

    let b = scene.bbox();
    let cell = rep.unit / recipe.scale / args.resolution;
    let sz = b.size();
    let cells = [0, 1, 2].map(|k| ((sz[k] / cell).ceil() as usize).clamp(2, 4096));
    if let Some(path) = &args.mesh {
        preflight_mesh(ctx, path, cells, args.resolution)?;
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
        progress.begin("polygonising", 0);
        let t = Instant::now();
        let (mesh, mr) = polygonize(
            &scene,
            &MeshSettings {
                cells,
                ..Default::default()
            },
        )
        .context("cannot polygonise the scene")?;
        let t_mesh = t.elapsed().as_secs_f64();
        let topo = topology(&mesh);
        out.push_str(&format!(
            "mesh:         {} vertices, {} triangles, grid {}x{}x{} ({}/{} chunks sampled), {} in {t_mesh:.3} s\n",
            mesh.positions.len(),
            mesh.triangles.len(),
            cells[0],
            cells[1],
            cells[2],
            mr.chunks_sampled,
            mr.chunks,
            if topo.bad_edges == 0 && topo.misoriented_edges == 0 {
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
        out.push_str(&format!(
            "wrote {} in {:.3} s\n",
            path.display(),
            t.elapsed().as_secs_f64()
        ));
    }
    let (w, h) = args.image_size;
    if let Some(path) = &args.render {
        progress.begin("rendering", 0);
        let t = Instant::now();
        let img = render(
            &scene,
            &Camera::overview(&scene.bbox()),
            &RenderSettings {
                width: w,
                height: h,
                sea_level: Some(rep.sea_level),
                ..Default::default()
            },
        )
        .context("cannot render the scene")?;
        relief_io::write_rgb_png(&staged.path(path), img.width, img.height, &img.rgb)
            .with_context(|| format!("cannot write {}", path.display()))?;
        out.push_str(&format!(
            "render:       {}x{} in {:.3} s, wrote {}\n",
            w,
            h,
            t.elapsed().as_secs_f64(),
            path.display()
        ));
    }
    if let Some(path) = &args.section {
        progress.begin("cutting a section", 0);
        let t = Instant::now();
        let (start, end) = rep.section_line;
        let (img, ss) = section(
            &scene,
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
    staged.commit()?;
    drop(progress);
    let mut stdout = std::io::stdout().lock();
    std::io::Write::write_all(&mut stdout, out.as_bytes()).context("cannot write to stdout")?;
    Ok(())
}
