//! `relief tile run`: one task renders its tile atomically and idempotently.

use super::*;

/// The task index from `--index` or the scheduler's environment.
pub(super) fn task_index(given: Option<usize>) -> Result<usize> {
    if let Some(i) = given {
        return Ok(i);
    }
    for var in INDEX_VARS {
        if let Ok(v) = std::env::var(var) {
            return v
                .trim()
                .parse()
                .with_context(|| format!("{var} = `{v}` is not a task index"));
        }
    }
    bail!(
        "no task index: pass --index or run under a job array ({})",
        INDEX_VARS.join(", ")
    )
}

pub(super) fn run_task(a: RunArgs, ctx: &Ctx) -> Result<()> {
    let (dir, m) = open_plan(&a.dir)?;
    if m.phases > 0 {
        return super::flow::run_task(&dir, &m, &a, ctx);
    }
    if a.phase.is_some_and(|p| p != 1) {
        bail!("this plan has one phase (a task per tile): --phase must be 1 or absent");
    }
    let i = task_index(a.index)?;
    if i >= m.tasks {
        bail!(
            "task index {i} is out of range: the plan has {} tasks (0..{})",
            m.tasks,
            m.tasks - 1
        );
    }
    check_plan_folder(&dir, "tiles")?;
    if tile_state(&dir, &m, i) == TileState::Done {
        ctx.note(format!("tile {i} is already done"));
        return Ok(());
    }
    check_inputs(&dir, &m)?;
    let [x, y, w, h] = m.window(i);
    let win = Window {
        x,
        y,
        width: w,
        height: h,
    };
    preflight(&m, win, ctx)?;
    let prepared = read_prepared(&dir, &m, ctx)?;
    let hf = render(&m, prepared, win, ctx)?;
    let bytes = deflate_geotiff(&hf)?;
    // Encoding asks no deadline: a task past --max-time writes nothing (the tile stays to do).
    if ctx
        .deadline()
        .is_some_and(|d| std::time::Instant::now() >= d)
    {
        return Err(
            crate::budget::Stopped(format!("tile task {i}, after encoding the tile")).into(),
        );
    }
    let name = tile_name(i);
    let tile_path = dir.join("tiles").join(&name);
    relief_io::write_bytes_atomic(&tile_path, &bytes)
        .with_context(|| format!("cannot write {}", tile_path.display()))?;
    let rec = TileRecord {
        plan_id: m.plan_id.clone(),
        index: i,
        window: [x, y, w, h],
        file: bytes_sum(&bytes, name),
    };
    let json = crate::staging::json_text(&rec)?;
    relief_io::write_bytes_atomic(&record_path(&dir, i), json.as_bytes())
        .with_context(|| format!("cannot write the record of tile {i}"))?;
    ctx.note(format!("tile {i} done ({w} x {h} at {x},{y})"));
    Ok(())
}

/// Inputs still reachable must be those planned. A task on another machine may not see them
/// (it reads only the prepared file, which is always checked), and they lie outside the plan
/// folder, so they are read only when the manifest is the user's own
/// ([`manifest_is_trusted`]), only when they are regular files of the planned length (a
/// device named in their place is never read).
fn check_inputs(dir: &Path, m: &Manifest) -> Result<()> {
    if !manifest_is_trusted(dir) {
        return Ok(());
    }
    for s in &m.inputs {
        let Ok(meta) = std::fs::metadata(&s.path) else {
            continue;
        };
        let now = if !meta.is_file() || meta.len() != s.bytes {
            None
        } else {
            Some(file_sum(Path::new(&s.path), s.path.clone())?)
        };
        if now.as_ref() != Some(s) {
            bail!(
                "input {} changed since the plan (its length or checksum differs); plan again",
                s.path
            );
        }
    }
    Ok(())
}

/// The prepared file: a regular file inside the plan folder, of the length and checksum the
/// manifest records, and at most a third of `--max-memory` (its decoded form takes about
/// twice the file).
fn read_prepared(dir: &Path, m: &Manifest, ctx: &Ctx) -> Result<Vec<u8>> {
    let cap = crate::sparse_model::MAX_MODEL_BYTES.min(ctx.max_memory.bytes / 3);
    if m.prepared.bytes > cap {
        bail!(
            "the plan's prepared file {} holds {} bytes, above the {} a task may read (a third \
             of --max-memory {})",
            m.prepared.path,
            m.prepared.bytes,
            crate::memory::human(cap),
            ctx.max_memory
        );
    }
    let prepared = read_plan_file(dir, &m.prepared.path, m.prepared.bytes)?;
    if bytes_sum(&prepared, m.prepared.path.clone()) != m.prepared {
        bail!(
            "{} does not match its checksum in the manifest (corrupt or replaced); plan again",
            dir.join(&m.prepared.path).display()
        );
    }
    Ok(prepared)
}

/// Pre-flight of one task against `--max-memory`, before the prepared file is read: the
/// decoded prepared file and the window, with the single commands' own estimates.
fn preflight(m: &Manifest, win: Window, ctx: &Ctx) -> Result<()> {
    let change = "a smaller --tile (plan again)";
    let prepared = m.prepared.bytes as f64;
    match m.command.as_str() {
        "refine" => crate::commands::preflight::refine_window(prepared, m, win, change, ctx),
        "decompress" | "amplify" if m.prepared.path != super::plan::LAST_STEP => {
            let scale = m.job["scale"].as_f64().unwrap_or(1.0);
            crate::commands::preflight::decompress(
                win,
                scale,
                m.prepared.bytes as usize,
                change,
                ctx,
            )
        }
        _ => crate::commands::preflight::last_step_window(prepared, win, change, ctx),
    }
}

/// Rows of a tile rendered at once when the run has a deadline (`--max-time`): the deadline
/// is asked between bands. A band is a window like any other, so the tile is the same bytes.
const BAND_ROWS: usize = 512;

/// The window `win` of the planned output, in bands of [`BAND_ROWS`] rows when the run has a
/// deadline (asked before each band), else at once.
pub(super) fn render(
    m: &Manifest,
    prepared: Vec<u8>,
    win: Window,
    ctx: &Ctx,
) -> Result<Heightfield> {
    let window = renderer(m, prepared)?;
    if ctx.deadline().is_none() || win.height <= BAND_ROWS {
        return window(win);
    }
    let progress = ctx.progress();
    let mut data: Vec<f32> = Vec::with_capacity(win.width * win.height);
    let mut first: Option<Heightfield> = None;
    for y in (0..win.height).step_by(BAND_ROWS) {
        if progress.stopped() {
            return Err(crate::budget::Stopped(format!(
                "tile task, after {y} of {} rows",
                win.height
            ))
            .into());
        }
        let band = window(Window {
            y: win.y + y,
            height: BAND_ROWS.min(win.height - y),
            ..win
        })?;
        data.extend_from_slice(band.as_slice());
        first.get_or_insert(band);
    }
    let first = first.context("an empty tile")?;
    let (cx, cy) = first.cell_size();
    Ok(Heightfield::new(win.width, win.height, data, cx, cy)?.with_georef(first.georef().cloned()))
}

/// Decodes the prepared file once; the result renders any window of the planned output from
/// the manifest's job settings.
#[allow(clippy::type_complexity)]
fn renderer(
    m: &Manifest,
    prepared: Vec<u8>,
) -> Result<Box<dyn Fn(Window) -> Result<Heightfield> + '_>> {
    let sct = |prepared: &[u8], scale: f64| -> Result<Box<dyn Fn(Window) -> Result<Heightfield>>> {
        let sct = Sct::from_bytes(prepared, &crate::sparse_model::registry())
            .context("cannot read the prepared model")?;
        Ok(Box::new(move |win| {
            Ok(sct.rasterize(&RasterSettings {
                scale,
                window: Some(win),
            })?)
        }))
    };
    let bad_job = || format!("the manifest's `job` is not valid {} settings", m.command);
    match m.command.as_str() {
        "amplify" if m.prepared.path == super::plan::LAST_STEP => {
            let settings: relief_dictionary_learning::AmplifySettings =
                serde_json::from_value(m.job.clone()).with_context(bad_job)?;
            // The prepared bytes are dropped once decoded (a large last step's input is held
            // once, not twice, while windows are computed).
            let last = relief_dictionary_learning::LastStep::from_bytes(&prepared, &settings)
                .context("cannot read the prepared last step")?;
            drop(prepared);
            Ok(Box::new(move |win: Window| {
                let hf = last.render_window(win)?;
                let georef = m
                    .output
                    .georef
                    .as_ref()
                    .map(|g| g.window(win.x as f64, win.y as f64, 1.0, 1.0));
                Ok(hf.with_georef(georef))
            }))
        }
        "amplify" => sct(&prepared, 1.0),
        "decompress" => {
            let scale = m.job["scale"].as_f64().with_context(bad_job)?;
            sct(&prepared, scale)
        }
        "refine" => {
            let settings: relief_wavelet_lod::RefineSettings =
                serde_json::from_value(m.job.clone()).with_context(bad_job)?;
            let hf = relief_io::read_bytes(
                &prepared,
                Some(Path::new("input.tif")),
                &relief_io::ReadOptions::default(),
            )
            .context("cannot read the prepared input")?
            .heightfield;
            drop(prepared);
            let refiner = relief_wavelet_lod::Refiner::new(&hf, &settings)
                .context("cannot analyse the prepared input")?;
            Ok(Box::new(move |win: Window| {
                Ok(refiner.render_window(win.x, win.y, win.width, win.height)?)
            }))
        }
        other => bail!("the manifest's command `{other}` cannot be tiled"),
    }
}
