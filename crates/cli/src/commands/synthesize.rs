//! `relief synthesize SKETCH OUT --exemplar EX`: a terrain from a painted coarse sketch (any
//! raster, typically a grey PNG) and an exemplar DEM, by incremental x4 amplification steps
//! (guerin2016 section 5.3, figure 12: three steps, x64).

use std::path::PathBuf;

use anyhow::{Context, Result};
use relief_dictionary_learning::{
    AmplifySettings, StructureSettings, SynthesisSettings, synthesize_with_strokes,
};

use crate::ctx::Ctx;
use crate::sparse_model::{OutputPlan, check_output_path, dictionary_choice, write_model};

/// Arguments of `relief synthesize`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Painted sketch (bright = high): read as rock uplift and grown into relief (default), or
    /// mapped linearly to the elevation range (`--landform off`, `--paper`).
    pub(crate) sketch: PathBuf,
    /// Output: a raster (.tif, .png, .exr, .npy, .r16, .r32) or a `.sct` model.
    pub(crate) output: PathBuf,
    #[command(flatten)]
    pub(crate) exemplar: crate::sparse_model::ExemplarArg,
    /// Number of x4 amplification steps (the output is 4^N times the sketch; figure 12 uses 3;
    /// not the grid --step; --steps is an alias).
    #[arg(long = "x4-steps", visible_alias = "steps", value_name = "N", default_value_t = SynthesisSettings::default().amplify.steps)]
    pub(crate) steps: usize,
    #[command(flatten)]
    pub(crate) seed: crate::sparse_model::SeedArg,
    /// Support radius R in cells of each step's input (its coarse pixels).
    #[arg(long, default_value_t = SynthesisSettings::default().amplify.radius)]
    pub(crate) radius: f64,
    /// Grid step S between primitive centres, in cells of each step's input (default: half the
    /// radius).
    #[arg(long)]
    pub(crate) step: Option<f64>,
    /// The paper's plain method: the whole high-resolution atom scaled by the code (no detail at
    /// the exemplar's amplitude, no detail-energy normalisation). Synthesis never applies the
    /// residual correction (a sketch's pixels are not to be reproduced).
    #[arg(long)]
    pub(crate) paper: bool,
    /// Radius (sketch cells) of the exemplar patches that give the sketch its landforms before
    /// the x4 steps: patches 4R cells wide whose smooth part matches the sketch's, continued
    /// coherently from patch to patch. 0 turns the step off (the paper's method; `--paper`
    /// does too).
    #[arg(long, default_value_t = SynthesisSettings::default().structure.radius)]
    pub(crate) structure_radius: f64,
    /// Ground size of a sketch pixel in metres, `X` or `X,Y` (the sketch's extent over its
    /// size). Default: the exemplar's cell size times 4^steps, so the output has the
    /// exemplar's cell size. Set it so the strokes are landform-sized and the sketch covers
    /// about what the exemplar does: the landforms then come at their own scale rather than by
    /// self-similarity (the notes say which).
    #[arg(long, value_parser = crate::args::parse_cell_size, value_name = "X[,Y]")]
    pub(crate) sketch_cell_size: Option<(f64, f64)>,
    /// Number of learned atoms N; 0 = the complete dictionary.
    #[arg(long, default_value_t = SynthesisSettings::default().amplify.dictionary.n_atoms())]
    pub(crate) atoms: usize,
    #[command(flatten)]
    pub(crate) window: crate::sparse_model::WindowArg,
    /// Landscape evolution and landform pass (default on, off with --paper): the sketch is
    /// read as an uplift map and a stream-power run grows ridges and valleys that follow the
    /// strokes on the sketch's grid x4, the exemplar's detail is added by the remaining steps,
    /// and the result is drained and kept on the grown network. Off: the sketch's pixels
    /// amplified directly (with the structure step).
    #[command(flatten)]
    pub(crate) landform: crate::landform::LandformArg,
    /// Ridge lines painted beside the sketch (a raster of the sketch's size or an integer
    /// fraction of it; bright = ridge): the grown relief gets extra uplift there, so its
    /// divides follow them (figure 12's ridge strokes). Needs the grown relief (not with
    /// `--paper` or `--landform off`).
    #[arg(long, value_name = "RASTER")]
    pub(crate) ridges: Option<PathBuf>,
    /// Rivers painted beside the sketch (as `--ridges`; bright = river): no uplift under the
    /// stroke, so it stays a valley floor while the land around it rises; draw a river to the
    /// map's edge for it to drain there.
    #[arg(long, value_name = "RASTER")]
    pub(crate) rivers: Option<PathBuf>,
}

/// Reads the sketch and exemplar, synthesises, writes.
/// The library settings of the arguments (checked).
pub(crate) fn settings(args: &Args, ctx: &Ctx) -> Result<SynthesisSettings> {
    let settings = SynthesisSettings {
        amplify: AmplifySettings {
            radius: args.radius,
            steps: args.steps,
            dictionary: dictionary_choice(args.atoms),
            seed: args.seed.seed,
            step: args.step,
            normalize_detail: !args.paper,
            exemplar_detail: !args.paper,
            exemplar_cell_size: args.exemplar.exemplar_cell_size,
            ..SynthesisSettings::default().amplify
        },
        // The global --height-range: the sketch is mapped onto it (default: the exemplar's
        // range), and a 16-bit heightmap output uses the same mapping.
        height_range: ctx.height_range.map(|(lo, hi)| (lo as f32, hi as f32)),
        structure: StructureSettings {
            radius: if args.paper {
                0.0
            } else {
                args.structure_radius
            },
            ..Default::default()
        },
        sketch_cell_size: args.sketch_cell_size,
        grow: args
            .landform
            .on(args.paper)
            .then(relief_landscape::grow::GrowSettings::default),
    };
    settings
        .amplify
        .check()
        .context("invalid synthesis settings")?;
    settings
        .structure
        .check()
        .context("invalid synthesis settings")?;
    Ok(settings)
}

pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let settings = settings(&args, ctx)?;
    let window = args.window.window;
    check_output_path(&args.output, window)?;
    let stroke_paths: Vec<&std::path::Path> = args
        .ridges
        .iter()
        .chain(&args.rivers)
        .map(PathBuf::as_path)
        .collect();
    if !stroke_paths.is_empty() && settings.grow.is_none() {
        anyhow::bail!(
            "--ridges and --rivers shape the grown relief: drop --paper / --landform off to use \
             them"
        );
    }
    let mut inputs = vec![args.sketch.as_path(), args.exemplar.exemplar.as_path()];
    inputs.extend(stroke_paths);
    ctx.check_outputs(
        &inputs,
        &[(&args.output, crate::outputs::OutKind::RasterOrSct)],
    )?;
    let sketch = super::read_raster(&args.sketch, &super::ReadArgs::default(), ctx)?.heightfield;
    let read_strokes = |p: &Option<PathBuf>| -> Result<Option<relief_heightfield::Heightfield>> {
        p.as_ref()
            .map(|p| Ok(super::read_raster(p, &super::ReadArgs::default(), ctx)?.heightfield))
            .transpose()
    };
    let strokes = relief_landscape::grow::Strokes {
        ridges: read_strokes(&args.ridges)?,
        rivers: read_strokes(&args.rivers)?,
    };
    strokes
        .check(sketch.width(), sketch.height())
        .context("cannot use the strokes")?;
    let exemplar = args.exemplar.read(ctx)?;
    crate::sparse_model::preflight(
        ctx,
        &format!("synthesize ({} steps)", settings.amplify.steps),
        (sketch.width(), sketch.height()),
        (exemplar.width(), exemplar.height()),
        &settings.amplify,
        OutputPlan::of(&args.output, window, "--x4-steps").with_landform(settings.grow.is_some()),
    )?;
    let (sct, figures) = {
        let progress = ctx.progress();
        synthesize_with_strokes(&sketch, &strokes, &exemplar, &settings, &progress).with_context(
            || {
                format!(
                    "cannot synthesise from {} with {}",
                    args.sketch.display(),
                    args.exemplar.exemplar.display()
                )
            },
        )?
    };
    if let Some(st) = &figures.structure {
        ctx.note(st.note.clone());
    }
    if let Some(g) = &figures.grown {
        ctx.note(format!(
            "grew relief from the sketch by landscape evolution on {} x {} cells of {:.1} x \
             {:.1} m (stream power and diffusion, the sketch as uplift)",
            g.width(),
            g.height(),
            g.cell_size().0,
            g.cell_size().1
        ));
    }
    for step in &figures.steps {
        ctx.note(step.note.clone());
    }
    // The landform pass keeps the result on the grown network (its box averages).
    let finish = figures.grown.as_ref().map(crate::sparse_model::Landform);
    write_model(&sct, &args.output, window, false, finish.as_ref(), ctx)
}
