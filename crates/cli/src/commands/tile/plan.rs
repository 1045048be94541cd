//! `relief tile plan`: parse the command, make its paths absolute, prepare the shared input once,
//! write the checksummed manifest.

use super::*;

pub(super) fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("cannot resolve {}", p.display()))
}

/// The planned subcommand with every path argument made absolute (so tasks and the mosaic
/// can run from any directory), and its input and output paths.
pub(super) fn absolutise(cmd: &mut Windowable) -> Result<(Vec<PathBuf>, PathBuf)> {
    Ok(match cmd {
        Windowable::Amplify(a) => {
            a.input = absolute(&a.input)?;
            a.output = absolute(&a.output)?;
            a.exemplar.exemplar = absolute(&a.exemplar.exemplar)?;
            (
                vec![a.input.clone(), a.exemplar.exemplar.clone()],
                a.output.clone(),
            )
        }
        Windowable::Refine(a) => {
            a.input = absolute(&a.input)?;
            a.output = absolute(&a.output)?;
            (vec![a.input.clone()], a.output.clone())
        }
        Windowable::Decompress(a) => {
            a.input = absolute(&a.input)?;
            a.output = absolute(&a.output)?;
            (vec![a.input.clone()], a.output.clone())
        }
    })
}

/// Rewrites the argument list with absolute input/output paths (positional arguments and
/// `--exemplar`), leaving every other argument as typed.
pub(super) fn absolute_args(args: &[String], inputs: &[PathBuf], output: &Path) -> Vec<String> {
    let mut out = Vec::with_capacity(args.len());
    let mut positional = 0;
    let mut i = 0;
    while i < args.len() {
        let a = &args[i];
        if i == 0 {
            out.push(a.clone());
        } else if a == "--exemplar" && i + 1 < args.len() {
            out.push(a.clone());
            out.push(inputs[1].display().to_string());
            i += 1;
        } else if a.starts_with("--exemplar=") {
            out.push(format!("--exemplar={}", inputs[1].display()));
        } else if a.starts_with('-') {
            out.push(a.clone());
        } else if positional < 2 && !takes_value(&args[i - 1]) {
            out.push(if positional == 0 {
                inputs[0].display().to_string()
            } else {
                output.display().to_string()
            });
            positional += 1;
        } else {
            out.push(a.clone());
        }
        i += 1;
    }
    out
}

/// Whether a flag consumes the next argument (`--factor 4`), judged by the windowable
/// commands' definitions.
pub(super) fn takes_value(prev: &str) -> bool {
    use clap::CommandFactory;
    let Some(long) = prev.strip_prefix("--") else {
        return false;
    };
    if long.contains('=') {
        return false;
    }
    let cmd = Inner::command();
    cmd.get_subcommands().any(|s| {
        s.get_arguments()
            .any(|a| a.get_long() == Some(long) && a.get_action().takes_values())
    })
}

/// Commands that route flow over the whole DEM: a window of their output depends on every
/// cell upstream of it, so they are not windowable.
pub(super) const GLOBAL_DRAINAGE: [&str; 1] = ["erode"];

pub(super) fn plan(a: PlanArgs, ctx: &Ctx) -> Result<()> {
    if a.tile < 16 || !a.tile.is_multiple_of(16) || a.tile > 1 << 15 {
        bail!(
            "invalid --tile {}: must be a multiple of 16 between 16 and 32768",
            a.tile
        );
    }
    if a.command
        .first()
        .is_some_and(|c| c == "flow" || c == "masks")
    {
        return super::flow::plan(&a, ctx);
    }
    if let Some(global) = a
        .command
        .first()
        .filter(|c| GLOBAL_DRAINAGE.contains(&c.as_str()))
    {
        bail!(
            "`relief {global}` cannot be planned as tiles: drainage is global, a tile cannot \
             know the area that drains into it from upstream (only `flow` and `masks` have \
             exact multi-phase plans); run `relief {global}` on the whole DEM"
        );
    }
    if let Some(other) = a
        .command
        .first()
        .filter(|c| !["amplify", "refine", "decompress"].contains(&c.as_str()))
    {
        bail!(
            "`relief {other}` cannot be planned as tiles: a plan splits amplify, refine or \
             decompress (one task per output tile, each an exact window) or flow (seven phases)"
        );
    }
    let mut inner = Inner::try_parse_from(&a.command)
        .map_err(|e| anyhow::anyhow!("invalid command after `--`: {}", e.to_string().trim()))?;
    let (inputs, output) = absolutise(&mut inner.command)?;
    let name = a.command[0].clone();
    let args = absolute_args(&a.command, &inputs, &output);
    // The rewritten arguments must parse to the same command.
    Inner::try_parse_from(&args).context("cannot rewrite the command's paths")?;
    match &inner.command {
        Windowable::Amplify(x) if x.window.window.is_some() => bail!(
            "--window cannot be planned: a plan covers the whole output (the tiles are windows)"
        ),
        Windowable::Refine(x) if x.window_of.is_some() => bail!(
            "--window cannot be planned: a plan covers the whole output (the tiles are windows)"
        ),
        Windowable::Decompress(x) if x.window.is_some() => bail!(
            "--window cannot be planned: a plan covers the whole output (the tiles are windows)"
        ),
        _ => {}
    }
    if relief_io::Format::from_extension(&output) != Some(relief_io::Format::GeoTiff) {
        bail!(
            "the planned output {} must be a GeoTIFF (.tif): the mosaic is streamed into one",
            output.display()
        );
    }
    let dir = new_plan_dir(&a.dir)?;
    let in_refs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    ctx.check_outputs(&in_refs, &[(&output, crate::outputs::OutKind::Raster)])?;
    if inputs.iter().any(|i| dir.starts_with(i)) || output.starts_with(&dir) {
        bail!(
            "the plan folder {} must not contain the output nor be an input",
            dir.display()
        );
    }
    let sums = inputs
        .iter()
        .map(|p| file_sum(p, p.display().to_string()))
        .collect::<Result<Vec<_>>>()?;
    // Prepare what every task reads, and the output grid.
    let Prepared {
        name: prepared_name,
        bytes: prepared_bytes,
        job,
        width,
        height,
        cell,
        georef,
    } = prepare(&inner.command, ctx)?;
    let (tx, ty) = (width.div_ceil(a.tile), height.div_ceil(a.tile));
    if tx.saturating_mul(ty) > MAX_TASKS {
        bail!(
            "{tx} x {ty} tiles exceed {MAX_TASKS} tasks: use a larger --tile than {}",
            a.tile
        );
    }
    std::fs::create_dir_all(dir.join("tiles"))
        .with_context(|| format!("cannot create {}", dir.display()))?;
    relief_io::write_bytes_atomic(&dir.join(prepared_name), &prepared_bytes)
        .with_context(|| format!("cannot write {}", dir.join(prepared_name).display()))?;
    let mut m = Manifest {
        format: FORMAT.into(),
        version: VERSION,
        command: name,
        args,
        job,
        inputs: sums,
        prepared: bytes_sum(&prepared_bytes, prepared_name.into()),
        output: OutputGrid {
            path: output.display().to_string(),
            width,
            height,
            cell_size: [cell.0, cell.1],
            georef,
        },
        tile: a.tile,
        tiles_x: tx,
        tiles_y: ty,
        tasks: tx * ty,
        phases: 0,
        plan_id: String::new(),
    };
    m.plan_id = hex(Sha256::digest(serde_json::to_vec(&m)?));
    let json = crate::staging::json_text(&m)?;
    relief_io::write_bytes_atomic(&dir.join(MANIFEST), json.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join(MANIFEST).display()))?;
    ctx.note(format!(
        "planned {} x {} output {} as {} tasks of {} px tiles ({tx} x {ty}) in {}\n\
         run them with: sbatch --array=0-{} --wrap 'relief tile run {}'",
        width,
        height,
        output.display(),
        m.tasks,
        a.tile,
        dir.display(),
        m.tasks - 1,
        dir.display()
    ));
    Ok(())
}

/// The prepared file of an amplify plan: the last x4 step's input and dictionary
/// (`relief_dictionary_learning::LastStep`).
pub(super) const LAST_STEP: &str = "last-step.bin";

/// What a plan prepares once for every task: the file the tasks read, and the output grid.
pub(super) struct Prepared {
    name: &'static str,
    /// The job's settings (the manifest's `job`).
    job: serde_json::Value,
    bytes: Vec<u8>,
    width: usize,
    height: usize,
    cell: (f64, f64),
    georef: Option<GeoRef>,
}

/// Runs the expensive, shared part of the command once (amplify: the model; decompress: the
/// model as given; refine: the void-checked input) and sizes the output.
pub(super) fn prepare(cmd: &Windowable, ctx: &Ctx) -> Result<Prepared> {
    // Tiles are the raw method (the landform pass routes water over the whole raster): the
    // mosaic equals the single run with `--landform off`; asking for the pass is an error.
    let landform = match cmd {
        Windowable::Amplify(x) => x.landform.landform,
        Windowable::Refine(x) => x.landform.landform,
        _ => None,
    };
    if landform == Some(crate::landform::Switch::On) {
        bail!(
            "a tiled plan cannot run the landform pass (it routes water over the whole raster): \
             drop --landform on (tiles equal the single run with --landform off), and route \
             the mosaic with `relief flow` or `relief erode`"
        );
    }
    let (name, job, bytes, width, height, cell, georef) = match cmd {
        Windowable::Amplify(x) => {
            // The plan runs the steps before the last and keeps the last step's input and
            // dictionary; each task computes its window of the last step (the bulk of the
            // work: 15/16 of the coded cells).
            let out = crate::sparse_model::OutputPlan {
                last_step_tasked: true,
                sct: true,
                window: None,
                stream: true,
                steps_flag: "--factor",
                landform: false,
            };
            let settings = crate::commands::amplify::settings(x)?;
            let job = serde_json::to_value(settings)?;
            let (last, georef) = crate::commands::amplify::prepare_last(x, out, ctx)?;
            let (w, h) = last.output_size();
            let (cx, cy) = last.input.cell_size();
            let cell = (cx / 4.0, cy / 4.0);
            let bytes = last.to_bytes().context("cannot serialise the last step")?;
            (LAST_STEP, job, bytes, w, h, cell, georef)
        }
        Windowable::Decompress(x) => {
            let bytes = crate::sparse_model::read_model_bytes(&x.input, ctx)?;
            let sct = Sct::from_bytes(&bytes, &crate::sparse_model::registry())
                .with_context(|| format!("cannot read {}", x.input.display()))?;
            let (w, h) = sct
                .raster_size(x.scale)
                .context("invalid parameter `--factor`")?;
            let win = Window {
                x: 0,
                y: 0,
                width: w,
                height: h,
            };
            let g = sct.raster_georef(x.scale, win);
            let probe = sct.rasterize(&RasterSettings {
                scale: x.scale,
                window: Some(Window {
                    width: 1,
                    height: 1,
                    ..win
                }),
            })?;
            let job = serde_json::json!({ "scale": x.scale });
            ("model.sct", job, bytes, w, h, probe.cell_size(), g)
        }
        Windowable::Refine(x) => {
            let settings = x.settings()?;
            let hf = crate::commands::read_void_free(&x.input, &x.read, ctx)?;
            let refiner = relief_wavelet_lod::Refiner::new(&hf, &settings)
                .with_context(|| format!("cannot analyse {}", x.input.display()))?;
            let (w, h) = refiner.output_size();
            let corner = refiner.render_window(0, 0, 1, 1)?;
            let bytes = deflate_geotiff(&hf)?;
            (
                "input.tif",
                serde_json::to_value(&settings)?,
                bytes,
                w,
                h,
                corner.cell_size(),
                corner.georef().cloned(),
            )
        }
    };
    Ok(Prepared {
        name,
        job,
        bytes,
        width,
        height,
        cell,
        georef,
    })
}

/// The plan folder `dir`, absolute; it must be new or empty (a plan is written into a new
/// folder).
pub(super) fn new_plan_dir(dir: &Path) -> Result<PathBuf> {
    let dir = absolute(dir)?;
    if dir.exists()
        && std::fs::read_dir(&dir)
            .with_context(|| format!("cannot read {}", dir.display()))?
            .next()
            .is_some()
    {
        bail!(
            "the plan folder {} is not empty (a plan is written into a new folder)",
            dir.display()
        );
    }
    Ok(dir)
}
