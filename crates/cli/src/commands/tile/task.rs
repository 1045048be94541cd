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
    let dir = absolute(&a.dir)?;
    let m = load_manifest(&dir)?;
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
    if tile_state(&dir, &m, i) == TileState::Done {
        ctx.note(format!("tile {i} is already done"));
        return Ok(());
    }
    // Inputs still reachable must be those planned (a task on another machine may not see
    // them: it reads only the prepared file, which is always checked).
    for s in &m.inputs {
        let p = Path::new(&s.path);
        if p.exists() {
            let now = file_sum(p, s.path.clone())?;
            if now != *s {
                bail!(
                    "input {} changed since the plan (checksum {} instead of {}); plan again",
                    s.path,
                    &now.sha256[..12],
                    &s.sha256[..12]
                );
            }
        }
    }
    let prepared_path = dir.join(&m.prepared.path);
    let prepared = crate::sparse_model::read_model_bytes(&prepared_path, ctx)?;
    if bytes_sum(&prepared, m.prepared.path.clone()) != m.prepared {
        bail!(
            "{} does not match its checksum in the manifest (corrupt or replaced); plan again",
            prepared_path.display()
        );
    }
    let [x, y, w, h] = m.window(i);
    let hf = render(
        &m,
        prepared,
        Window {
            x,
            y,
            width: w,
            height: h,
        },
    )?;
    let bytes = deflate_geotiff(&hf)?;
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

/// One window of the planned output, from the prepared file and the manifest's job settings.
/// The prepared bytes are dropped as soon as they are decoded (a large last step's input is
/// held once, not twice, while the window is computed).
pub(super) fn render(m: &Manifest, prepared: Vec<u8>, win: Window) -> Result<Heightfield> {
    let sct_window = |prepared: &[u8], scale: f64| -> Result<Heightfield> {
        let sct = Sct::from_bytes(prepared, &crate::sparse_model::registry())
            .context("cannot read the prepared model")?;
        Ok(sct.rasterize(&RasterSettings {
            scale,
            window: Some(win),
        })?)
    };
    let bad_job = || format!("the manifest's `job` is not valid {} settings", m.command);
    match m.command.as_str() {
        "amplify" if m.prepared.path == super::plan::LAST_STEP => {
            let settings: relief_dictionary_learning::AmplifySettings =
                serde_json::from_value(m.job.clone()).with_context(bad_job)?;
            let last = relief_dictionary_learning::LastStep::from_bytes(&prepared, &settings)
                .context("cannot read the prepared last step")?;
            drop(prepared);
            let hf = last.render_window(win)?;
            let georef = m
                .output
                .georef
                .as_ref()
                .map(|g| g.window(win.x as f64, win.y as f64, 1.0, 1.0));
            Ok(hf.with_georef(georef))
        }
        "amplify" => sct_window(&prepared, 1.0),
        "decompress" => {
            let scale = m.job["scale"].as_f64().with_context(bad_job)?;
            sct_window(&prepared, scale)
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
            let refiner = relief_wavelet_lod::Refiner::new(&hf, &settings)
                .context("cannot analyse the prepared input")?;
            Ok(refiner.render_window(win.x, win.y, win.width, win.height)?)
        }
        other => bail!("the manifest's command `{other}` cannot be tiled"),
    }
}
