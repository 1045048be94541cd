//! `relief volume IN --features sea,karst,... [--mesh OUT.glb] [--render OUT.png]
//! [--closeups OUT.png] [--section OUT.png] [--report OUT.json]`: 3D landforms on an implicit
//! construction tree (Paris et al. 2018, `relief-implicit-volume`): the DEM is implicitised, the
//! features are generated with sizes in metres derived from the DEM (or a `--geology` tree),
//! the scene is polygonised in chunks (optionally simplified to `--max-triangles`, GLB/PLY/OBJ
//! through relief-io), sphere-traced to an overview and close-ups on the features and cut by a
//! vertical section. Prints node counts, sizes, mesh size and timings on stdout; `--report`
//! writes them as JSON.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use relief_heightfield::Heightfield;
use relief_implicit_volume::{Feature, GeologySpec, VolumeJob};

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
    /// Sea level in metres of the shore features (cliffs, sea, caves). Default: the DEM's own
    /// sea (border-connected ground at or below 0 m, or a large flat border-connected lowest
    /// area); on a DEM without sea (inland) they are skipped with a note and no water is
    /// drawn. Give a level to put a shore anywhere, e.g. a lake in a canyon.
    #[arg(long, allow_hyphen_values = true)]
    pub(crate) sea_level: Option<f32>,
    /// Write the polygonised scene (.glb, .ply or .obj).
    #[arg(long)]
    pub(crate) mesh: Option<PathBuf>,
    /// Up axis of an OBJ or PLY mesh: z (default; relief's frame: x east, y north, z up, as
    /// GIS tools and Houdini's Z-up setting read it) or y (rotated -90 degrees about x,
    /// `(x, y, z) -> (x, z, -y)`, as Blender's OBJ importer, Maya and game engines expect). A
    /// GLB is always Y-up (glTF 2.0 requires it).
    #[arg(long, value_enum)]
    pub(crate) up: Option<UpArg>,
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
    #[arg(long, value_parser = super::parse_crop)]
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
    #[arg(long, value_parser = super::parse_pair, allow_hyphen_values = true, default_value = "1,0.3")]
    pub(crate) wind: (f32, f32),
    /// Render and section size `WxH` in pixels.
    #[arg(long, default_value = "640x480", value_parser = super::parse_image_size)]
    pub(crate) image_size: (usize, usize),
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
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

/// Up axis of `relief volume --up`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum UpArg {
    /// Z up (relief's frame).
    Z,
    /// Y up (x, z, -y).
    Y,
}

/// The flags as a [`VolumeJob`] (checked; the geology file and the voxel from the input's
/// cell size are added by [`run`] once the files are read).
pub(crate) fn job(args: &Args) -> Result<VolumeJob> {
    let mut job = VolumeJob::default();
    let r = &mut job.recipe;
    r.features = Feature::parse_list(&args.features).context("bad --features")?;
    r.sea_level = args.sea_level;
    r.scale = args.scale;
    r.karst_budget = args.karst_budget;
    r.wind = [args.wind.0, args.wind.1];
    r.seed = args.seed;
    job.mesh = args.mesh.is_some();
    job.max_triangles = args.max_triangles;
    job.render = args.render.is_some();
    job.closeups = args.closeups.is_some();
    job.section = args.section.is_some();
    job.image_size = [args.image_size.0, args.image_size.1];
    if let Some(m) = &args.mesh
        && relief_io::MeshFormat::from_extension(m).is_none()
    {
        bail!(
            "--mesh {}: the file must end in .glb, .ply or .obj",
            m.display()
        );
    }
    match (&args.mesh, args.up) {
        (None, Some(_)) => bail!("--up applies to a --mesh; give one"),
        (Some(m), Some(UpArg::Z))
            if relief_io::MeshFormat::from_extension(m) == Some(relief_io::MeshFormat::Glb) =>
        {
            bail!(
                "--up z: {} is glTF, which is Y-up by specification; use .obj or .ply for a \
                 Z-up mesh",
                m.display()
            )
        }
        _ => {}
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
    job.check().context("invalid volume settings")?;
    Ok(job)
}

/// Maps the flags onto a [`VolumeJob`], runs it and writes the outputs.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    // Everything that can be checked without work is checked before any output is written.
    let mut job = job(&args)?;
    for (p, flag) in [
        (&args.render, "render"),
        (&args.closeups, "closeups"),
        (&args.section, "section"),
    ] {
        crate::outputs::check_png_flag(p.as_deref(), flag)?;
    }
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
        crate::outputs::check_report_path(r, &args.input, ctx.force)?;
        if outputs.iter().any(|(p, _)| *p == r.as_path()) {
            bail!("--report {}: also named as another output", r.display());
        }
    }
    if let Some(p) = &args.geology {
        job.recipe.geology = Some(read_geology(p)?);
        job.check().context("invalid volume settings")?;
    }
    // The mesh, the images and the report appear together or not at all.
    let staged = crate::staging::Outputs::of(&outputs, args.report.as_deref())?;
    let raster = super::read_raster(&args.input, &args.read, ctx)?;
    let mut hf = raster.heightfield;
    if let Some((x, y, w, h)) = args.crop {
        hf = hf
            .crop(x, y, w, h)
            .with_context(|| format!("cannot crop {}", args.input.display()))?;
    }
    hf.require_complete()
        .with_context(|| format!("{} cannot be implicitised", args.input.display()))?;
    if let Some(p) = &args.mask {
        job.recipe.mask = Some(read_mask(p, &hf, ctx)?);
    }
    let (cx, cy) = hf.cell_size();
    job.recipe.voxel = args
        .voxel
        .or(args.resolution.map(|r| cx.max(cy) as f32 / r));
    let progress = ctx.progress();
    let built = job
        .build(&hf, &progress)
        .context("cannot build the scene")?;
    if let Some(path) = &args.mesh {
        crate::memory::preflight_volume_mesh(
            ctx,
            path,
            built.mesh_grid(&job),
            built.report.dims.voxel_m as f64,
        )?;
    }
    if job.render || job.section || job.closeups {
        crate::memory::preflight_volume_images(ctx, args.image_size)?;
    }
    if let Some(est) = job
        .estimate_image_seconds(&built)
        .context("cannot time the pilot render")?
    {
        let (w, h) = args.image_size;
        ctx.check_time(
            &format!("rendering {w} x {h} images"),
            est,
            &format!(
                "from the same images at 1/{} of the size",
                relief_implicit_volume::job::PILOT_DIVISOR
            ),
            "a smaller --image-size",
        )?;
    }
    let out = job
        .finish(built, &progress)
        .context("cannot mesh or render the scene")?;
    let y_up = args.up == Some(UpArg::Y);
    let mut text = out.figures.summary();
    if let (Some(path), Some(mesh)) = (&args.mesh, &out.mesh) {
        let normals = (!mesh.normals.is_empty()).then_some(&mesh.normals[..]);
        let glb = relief_io::MeshFormat::from_extension(path) == Some(relief_io::MeshFormat::Glb);
        let rotated = (y_up && !glb).then(|| {
            let r = |v: &[[f32; 3]]| -> Vec<[f32; 3]> {
                v.iter().map(relief_io::z_up_to_y_up).collect()
            };
            (r(&mesh.positions), normals.map(r))
        });
        let (positions, normals) = match &rotated {
            Some((p, n)) => (&p[..], n.as_deref()),
            None => (&mesh.positions[..], normals),
        };
        relief_io::write_mesh(&staged.path(path), positions, &mesh.triangles, normals)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let bytes = std::fs::metadata(staged.path(path)).map_or(0, |m| m.len());
        text += &format!("wrote {} ({:.1} MB)\n", path.display(), bytes as f64 / 1e6);
    }
    for (path, image) in [
        (&args.render, &out.render),
        (&args.closeups, &out.closeups),
        (&args.section, &out.section),
    ] {
        if let (Some(path), Some(i)) = (path, image) {
            staged.write_png(path, i.width, i.height, &i.rgb)?;
        }
    }
    if let Some(path) = &args.report {
        let mut v = serde_json::to_value(&out.figures).context("cannot encode the report")?;
        v["input"] = args.input.display().to_string().into();
        staged.write_json(path, &v)?;
        text += &format!("report:       wrote {}\n", path.display());
    }
    staged.commit()?;
    drop(progress);
    crate::staging::print(&text)
}
