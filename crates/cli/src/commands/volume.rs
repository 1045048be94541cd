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
    /// Keep the DEM's own sea flat when it is stored as a flat surface (SRTM's 0 m). Default:
    /// it gets a floor, the coast's slope continued under the water down to a tenth of the
    /// relief (at most 200 m), so the mesh has a seabed and the water shows its depth.
    #[arg(long)]
    pub(crate) flat_sea: bool,
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
    /// `uniform`; default: layered strata scaled to the DEM's relief.
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
    /// watertight).
    #[arg(long)]
    pub(crate) max_triangles: Option<usize>,
    /// Keep the DEM's own cells. By default, when they are coarser than a surface feature needs
    /// (hoodoos: their height, 12 m; arches: half their span, 15 m; shore: half the cliff
    /// retreat, 15 m; overhangs: 20 m), the scene is built on a window of the DEM, centred (on
    /// the shore nearest the centre for shore features) and as wide as the features' voxel
    /// affords (512 voxels), refined (wavelet, spectral model)
    /// to that cell. With --raw-dem such features are refused with a note naming the cell they
    /// need.
    #[arg(long)]
    pub(crate) raw_dem: bool,
    /// Multiplies every feature size (1 = the physical defaults in metres, docs/VOLUME_SIZES.md).
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
    let amplified = amplify_window(&mut hf, &mut job, &args, ctx)?;
    let (cx, cy) = hf.cell_size();
    job.recipe.voxel = args
        .voxel
        .or(args.resolution.map(|r| cx.max(cy) as f32 / r));
    let progress = ctx.progress();
    let mut built = job
        .build(&hf, &progress)
        .context("cannot build the scene")?;
    built.figures.notes.extend(amplified);
    crate::preflight::volume(ctx, &job, &built, args.mesh.as_deref(), args.image_size)?;
    let out = job
        .finish(built, &progress)
        .context("cannot mesh or render the scene")?;
    let text = files.write(&out, &args.input, args.up == Some(UpArg::Y), &staged)?;
    staged.commit()?;
    drop(progress);
    crate::staging::print(&text)
}

/// When the DEM's cells are coarser than a surface feature asked for needs
/// ([`relief_implicit_volume::recipe::FeatureSizes::needed_cell_for`]) and `--raw-dem` is not given, replaces `hf` by a window
/// of it refined to that cell (issue 42: features at their physical size on amplified terrain,
/// never kilometre-wide caves on coarse cells): the window is centred (on the shore nearest
/// the centre for shore features, [`window_centre`]), as wide as 512 of the
/// features' voxels ([`relief_implicit_volume::recipe::FeatureSizes::voxel_for`]) or the whole DEM when smaller, analysed
/// with a margin of [`MARGIN`] cells and refined by `L` wavelet levels (`2^L` finer, the
/// smallest `L` that reaches the cell). Returns the note saying what was done (printed and put
/// in the report), none when `hf` is kept.
fn amplify_window(
    hf: &mut relief_heightfield::Heightfield,
    job: &mut VolumeJob,
    args: &Args,
    ctx: &Ctx,
) -> Result<Option<String>> {
    let r = &job.recipe;
    let sizes = r.sizes.scaled(r.scale);
    let Some(need) = sizes.needed_cell_for(&r.features) else {
        return Ok(None);
    };
    let (cx, cy) = hf.cell_size();
    let cell = cx.max(cy);
    if args.raw_dem || cell <= f64::from(need) * 1.001 {
        return Ok(None);
    }
    if args.mask.is_some() {
        bail!(
            "--mask: the DEM's {cell:.1} m cells are coarser than the {need:.1} m the features \
             need, so the scene is built on a refined window of it, which a DEM-sized mask \
             does not fit; give --raw-dem (features that need finer cells are then refused) or \
             crop and refine the DEM and its mask first (relief refine)"
        );
    }
    let levels = (cell / f64::from(need)).log2().ceil().max(1.0) as u32;
    if levels > 8 {
        bail!(
            "{}: {cell:.1} m cells are over 256 times coarser than the {need:.1} m the features \
             ask for; use a finer DEM, fewer features (--features), a larger --scale, or \
             --raw-dem",
            args.input.display()
        );
    }
    let side = sizes
        .voxel_for(&r.features)
        .map_or(f64::INFINITY, |v| 512.0 * f64::from(v));
    let (w, h) = (hf.width(), hf.height());
    let k = 1usize << levels;
    // Fine nodes wanted along each axis (`side` metres, at most the whole DEM refined).
    let want = |n: usize, c: f64| {
        ((side * k as f64 / c).ceil() as usize + 1).clamp(17.min((n - 1) * k + 1), (n - 1) * k + 1)
    };
    let (nx, ny) = (want(w, cx), want(h, cy));
    let (jf, if_, sea) = window_centre(hf, r, args.sea_level);
    let (jc, ic) = (jf.round() as usize, if_.round() as usize);
    // The source nodes under the window, two more each side and a margin for the analysis.
    let span = |c: usize, n: usize, nf: usize| {
        let half = nf / (2 * k) + 2 + MARGIN;
        (c.saturating_sub(half), (c + half + 1).min(n))
    };
    let ((sx0, sx1), (sy0, sy1)) = (span(jc, w, nx), span(ic, h, ny));
    let src = hf
        .crop(sx0, sy0, sx1 - sx0, sy1 - sy0)
        .context("cannot take the window to amplify")?;
    let settings = relief_wavelet_lod::RefineSettings {
        extra_levels: levels,
        seed: r.seed,
        ..Default::default()
    };
    let refiner = relief_wavelet_lod::Refiner::new(&src, &settings)
        .context("cannot analyse the window to amplify")?;
    let (ow, oh) = refiner.output_size();
    // The window of the refined grid centred on the chosen node, inside the grid.
    let start = |c: f64, s0: usize, nf: usize, o: usize| {
        (((c - s0 as f64) * k as f64).round().max(0.0) as usize)
            .saturating_sub(nf / 2)
            .min(o.saturating_sub(nf))
    };
    let (nx, ny) = (nx.min(ow), ny.min(oh));
    let (fx0, fy0) = (start(jf, sx0, nx, ow), start(if_, sy0, ny, oh));
    let out = refiner
        .render_window(fx0, fy0, nx, ny)
        .context("cannot refine the window")?;
    let (fx, fy) = out.cell_size();
    let note = format!(
        "volume: built on a {:.0} x {:.0} m window around column {jf:.1}, row {if_:.1} of the DEM \
         refined {k}x (wavelet, {levels} levels) from {cell:.1} m to {:.1} m cells: the \
         features need cells of at most {need:.1} m and their voxel affords {:.0} m a side \
         (--crop picks another window, --raw-dem keeps the DEM)",
        (nx - 1) as f64 * fx,
        (ny - 1) as f64 * fy,
        fx.max(fy),
        side.min(f64::from(u32::MAX)),
    );
    ctx.note(format!("note: {note}"));
    // The refined sea is no longer flat (the synthesis adds detail everywhere), so the DEM's
    // own sea level is passed on rather than detected again in the window.
    if let (None, Some(level)) = (job.recipe.sea_level, sea) {
        job.recipe.sea_level = Some(level);
    }
    *hf = out;
    Ok(Some(note))
}

/// The node an amplified window is centred on: with shore features and a sea (`--sea-level`,
/// else the DEM's own, [`relief_implicit_volume::detect_sea`]), the shore node (above the
/// level, next to one at or below it) nearest the DEM's centre, moved along the edge to where
/// the coast crosses it; else the centre (fractional node coordinates). Also returns
/// the DEM's own sea level when it was detected.
fn window_centre(
    hf: &relief_heightfield::Heightfield,
    r: &relief_implicit_volume::Recipe,
    sea_level: Option<f32>,
) -> (f64, f64, Option<f32>) {
    let (w, h) = (hf.width(), hf.height());
    let centre = ((w / 2) as f64, (h / 2) as f64, None);
    let shore = [Feature::Sea, Feature::Caves, Feature::Cliffs];
    if !r.features.iter().any(|f| shore.contains(f)) {
        return centre;
    }
    let detected = match sea_level {
        Some(_) => None,
        None => relief_implicit_volume::detect_sea(hf).map(|s| s.level),
    };
    let Some(level) = sea_level.or(detected) else {
        return centre;
    };
    let z = |j: usize, i: usize| f64::from(hf.get(j, i));
    let level = f64::from(level);
    // Where the coast crosses each edge from a dry node to a wet one (linear interpolation).
    let mut best: Option<(f64, (f64, f64))> = None;
    for i in 0..h {
        for j in 0..w {
            let a = z(j, i);
            if a <= level {
                continue;
            }
            for (dj, di) in [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)] {
                let (jn, in_) = (j as i64 + dj, i as i64 + di);
                if jn < 0 || in_ < 0 || jn >= w as i64 || in_ >= h as i64 {
                    continue;
                }
                let b = z(jn as usize, in_ as usize);
                if b > level {
                    continue;
                }
                let t = (a - level) / (a - b);
                let p = (j as f64 + t * dj as f64, i as f64 + t * di as f64);
                let d = (p.0 - centre.0).powi(2) + (p.1 - centre.1).powi(2);
                if best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, p));
                }
            }
        }
    }
    best.map_or(centre, |(_, (j, i))| (j, i, detected))
}

/// Source cells around an amplified window that the wavelet analysis also sees.
const MARGIN: usize = 8;
