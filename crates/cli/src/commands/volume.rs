//! `relief volume IN --features sea,karst,... [--mesh OUT.glb] [--render OUT.png]
//! [--closeups OUT.png] [--section OUT.png] [--report OUT.json]`: 3D landforms on an implicit
//! construction tree (Paris et al. 2018, `relief-implicit-volume`): the DEM is implicitised, the
//! features are generated with sizes in metres derived from the DEM (or a `--geology` tree),
//! the scene is polygonised in chunks (optionally simplified to `--max-triangles`, GLB/PLY/OBJ
//! through relief-io), sphere-traced to an overview and close-ups on the features and cut by a
//! vertical section. Prints node counts, sizes, mesh size and timings on stdout; `--report`
//! writes them as JSON.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use relief_implicit_volume::{Feature, VolumeJob};

use crate::ctx::Ctx;

/// Arguments of `relief volume`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input DEM (format detected from its content; must have no voids).
    pub(crate) input: PathBuf,
    /// Comma-separated features: cliffs, sea, caves, karst, hoodoos, arches, islands, overhangs
    /// (soft rock retreating under resistant beds, wind and rain hollows), wind, rain; `none`
    /// meshes and renders the DEM alone (a plain DEM -> mesh).
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
    /// Keep the DEM's own sea flat when it is stored as a flat surface (SRTM's 0 m). Default:
    /// it gets a floor, the coast's slope continued under the water down to a tenth of the
    /// relief (at most 200 m), so the mesh has a seabed and the water shows its depth.
    #[arg(long)]
    pub(crate) flat_sea: bool,
    /// Write the polygonised scene (.glb, .ply or .obj) with vertex normals and colours (rock
    /// by stratum, soil on gentle slopes: what the renders show).
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
    /// Write close-up renders on the placed features (.png: tiles of half --image-size in
    /// rows of four, one per kind of landform).
    #[arg(long)]
    pub(crate) closeups: Option<PathBuf>,
    /// Write the report (tree nodes by kind, sizes in metres, counts, karst length, timings) as
    /// JSON.
    #[arg(long)]
    pub(crate) report: Option<PathBuf>,
    /// Geology tree as JSON, nodes `{"type": "strata", "z0": M, "layers": [{"thickness": M,
    /// "hardness": 0..1}, ...]}`, `fold`, `fault`, `noise`, `warp`, `blend`, `max`, `min`,
    /// `uniform`; default: a stratigraphic column of cliff beds and ledgy slopes (formations
    /// of about 20 m times `--feature-scale`) at fixed elevations.
    #[arg(long)]
    pub(crate) geology: Option<PathBuf>,
    /// Crop `X,Y,W,H` (columns, rows) applied after reading.
    #[arg(long, value_parser = super::parse_crop)]
    pub(crate) crop: Option<relief_heightfield::Window>,
    /// Meshing voxel edge in metres (default: a third of the smallest feature asked for, at
    /// most 512 cells across the DEM).
    #[arg(long, conflicts_with = "resolution")]
    pub(crate) voxel: Option<f32>,
    /// Mesh cells per DEM cell horizontally (sets the voxel to the larger cell / N).
    #[arg(long)]
    pub(crate) resolution: Option<f32>,
    /// Simplify the mesh to at most this many triangles (quadric edge collapses that keep it
    /// watertight); 0 keeps every triangle of the voxel mesh. The default, 2 million (a GLB of
    /// about 50 MB), is a mesh Blender, Unity and Unreal open interactively.
    #[arg(long, default_value_t = 2_000_000)]
    pub(crate) max_triangles: usize,
    /// Keep the DEM's own cells. By default, when they are coarser than a surface feature needs
    /// (hoodoos: their height, 12 m; arches: half their span, 15 m; shore: half the cliff
    /// retreat, 15 m; overhangs: 20 m), the scene is built on a window of the DEM, centred (on
    /// the shore nearest the centre for shore features) and as wide as the features' voxel
    /// affords (512 voxels), refined (wavelet, spectral model)
    /// to that cell. With --raw-dem such features are refused with a note naming the cell they
    /// need.
    #[arg(long)]
    pub(crate) raw_dem: bool,
    /// Multiplies every feature size (1 = the physical defaults in metres, docs/VOLUME_SIZES.md;
    /// --scale is an alias).
    #[arg(long = "feature-scale", visible_alias = "scale", default_value_t = 1.0)]
    pub(crate) scale: f32,
    /// Karst budget in carving steps (default: from a passage density of 6 km per km^2).
    #[arg(long)]
    pub(crate) karst_budget: Option<usize>,
    /// Stepped slopes: the fraction of a resistant bed's outcrop that becomes a bench on its
    /// top, the rest a cliff (0 keeps the DEM's smooth slopes; default 0.8). Cut on the DEM
    /// interpolated to the meshing voxel when that resolves the beds, with any feature.
    #[arg(long)]
    pub(crate) benches: Option<f32>,
    /// Direction the wind blows towards, `X,Y` (x east, y north).
    #[arg(long, value_parser = super::parse_pair, allow_hyphen_values = true, default_value = "1,0.3")]
    pub(crate) wind: (f32, f32),
    /// Render and section size `WxH` in pixels.
    #[arg(long, default_value = "640x480", value_parser = super::parse_image_size)]
    pub(crate) image_size: (usize, usize),
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
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
    r.seabed = !args.flat_sea;
    r.scale = args.scale;
    r.karst_budget = args.karst_budget;
    if let Some(b) = args.benches {
        r.benches = b;
    }
    r.wind = [args.wind.0, args.wind.1];
    r.seed = args.seed;
    job.mesh = args.mesh.is_some();
    job.max_triangles = (args.max_triangles > 0).then_some(args.max_triangles);
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
    job.check().context("invalid volume settings")?;
    Ok(job)
}

/// Maps the flags onto a [`VolumeJob`], runs it and writes the outputs.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    // Everything that can be checked without work is checked before any output is written.
    let mut job = job(&args)?;
    let files = crate::volume_io::Files {
        mesh: args.mesh.as_deref(),
        render: args.render.as_deref(),
        closeups: args.closeups.as_deref(),
        section: args.section.as_deref(),
        report: args.report.as_deref(),
    };
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(args.mask.as_deref());
    inputs.extend(args.geology.as_deref());
    files.check(&inputs, ctx)?;
    if let Some(p) = &args.geology {
        job.recipe.geology = Some(crate::volume_io::read_geology(p)?);
        job.check().context("invalid volume settings")?;
    }
    let staged = files.stage()?;
    let read = super::ReadArgs {
        warn_assumed_cell: false,
        ..args.read.clone()
    };
    let raster = super::read_raster(&args.input, &read, ctx)?;
    // Landforms are sized in metres (caves, arches, voxels): on a guessed 1 m cell a 512-cell
    // DEM of a 30 km range becomes a 512 m base under a kilometres-high spike, so a file
    // without a cell size is refused rather than warned about.
    if super::cell_size_assumed(&args.input, &raster, &read) {
        bail!(
            "{} stores no cell size, and volume sizes its landforms in metres: pass \
             --cell-size X[,Y] (metres per cell)",
            args.input.display()
        );
    }
    let mut hf = raster.heightfield;
    if let Some((x, y, w, h)) = args.crop.map(|w| w.as_tuple()) {
        hf = hf
            .crop(x, y, w, h)
            .with_context(|| format!("cannot crop {}", args.input.display()))?;
    }
    hf.require_complete()
        .with_context(|| format!("{} cannot be implicitised", args.input.display()))?;
    if let Some(p) = &args.mask {
        job.recipe.mask = Some(crate::volume_io::read_mask(p, &hf, ctx)?);
    }
    let amplified = relief_pipeline::volume_window::amplify_window(
        &mut hf,
        &mut job,
        &relief_pipeline::volume_window::WindowOptions {
            raw_dem: args.raw_dem,
            mask: args.mask.is_some(),
            sea_level: args.sea_level,
            input: &args.input.display().to_string(),
        },
    )?;
    if let Some(n) = &amplified {
        ctx.note(format!("note: {n}"));
    }
    let (cx, cy) = hf.cell_size();
    job.recipe.voxel = args
        .voxel
        .or(args.resolution.map(|r| cx.max(cy) as f32 / r));
    let progress = ctx.progress();
    let mut built = job
        .build(&hf, &progress)
        .context("cannot build the scene")?;
    built.figures.notes.extend(amplified);
    crate::commands::preflight::volume(ctx, &job, &built, args.mesh.as_deref(), args.image_size)?;
    let out = job
        .finish(built, &progress)
        .context("cannot mesh or render the scene")?;
    let text = files.write(&out, &args.input, args.up == Some(UpArg::Y), &staged)?;
    // Simplifying and encoding a large mesh ask no deadline: a run past --max-time is not
    // committed (the staged files are removed), whatever phase it was in.
    if relief_heightfield::Progress::stopped(&progress) {
        return Err(crate::budget::Stopped(
            "volume, after meshing and encoding the outputs".into(),
        )
        .into());
    }
    staged.commit()?;
    drop(progress);
    crate::staging::print(&text)
}
