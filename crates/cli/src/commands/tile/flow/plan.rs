//! The plan step of a flow plan: the DEM read band by band (or whole) and cut into the tiles'
//! inputs with their one-cell margin, and the manifest.

use relief_landscape::masks::tiled::ScaleCounts;

use super::*;

/// `relief tile plan DIR --tile N -- flow ...`.
pub(in crate::commands::tile) fn plan(a: &PlanArgs, ctx: &Ctx) -> Result<()> {
    if a.tile < 16 || !a.tile.is_multiple_of(16) || a.tile > 1 << 15 {
        bail!(
            "invalid --tile {}: must be a multiple of 16 between 16 and 32768",
            a.tile
        );
    }
    let parsed = FlowInner::try_parse_from(&a.command)
        .map_err(|e| anyhow::anyhow!("invalid command after `--`: {}", e.to_string().trim()))?;
    // The drainage's settings, and the masks' for a masks plan.
    let (input_arg, out_arg, read, json, settings, masks) = match parsed.command {
        FlowCommand::Flow(f) => {
            let s = crate::commands::flow::settings(&f)?;
            (f.input, f.out, f.read, f.json, s, None)
        }
        FlowCommand::Masks(m) => {
            let s = super::masks::plannable(&m)?;
            (m.input, m.out, m.read, m.json, s.flow.clone(), Some(s))
        }
    };
    tileable(&settings)?;
    if json {
        bail!("--json cannot be planned: a plan writes no report (relief tile status does)");
    }
    let input = absolute(&input_arg)?;
    let out = absolute(&out_arg)?;
    let dir = super::super::plan::new_plan_dir(&a.dir)?;
    if dir.starts_with(&input) || out.starts_with(&dir) || dir.starts_with(&out) {
        bail!(
            "the plan folder {} must not contain the output folder, lie in it, or be the input",
            dir.display()
        );
    }
    // The output folder is checked as `relief flow` checks it (then the staging is dropped).
    let files = match &masks {
        None => out_files(),
        Some(s) => super::masks::out_files(s),
    };
    let names: Vec<(&str, OutKind)> = files.iter().map(|(n, k)| (n.as_str(), *k)).collect();
    drop(crate::folder::FolderOutputs::new(
        &out,
        &names,
        &[&input],
        ctx,
    )?);
    let mut dem = Dem::open(&input, &read, ctx)?;
    let (width, height) = dem.size();
    let (cx, cy) = dem.cell;
    let layout = TileLayout {
        width,
        height,
        tile: a.tile,
        cell_x: cx,
        cell_y: cy,
    };
    layout.check()?;
    let tasks = layout.tasks();
    if tasks > MAX_TASKS {
        bail!(
            "{} tiles exceed {MAX_TASKS} tasks: use a larger --tile than {}",
            tasks,
            a.tile
        );
    }
    let input_sum = file_sum(&input, input.display().to_string())?;
    let subs = folders(masks.is_some());
    for sub in &subs {
        std::fs::create_dir_all(dir.join(sub))
            .with_context(|| format!("cannot create {}", dir.join(sub).display()))?;
    }
    let cut =
        cut_inputs(&dir, &layout, &mut dem, masks.is_some(), ctx).and_then(|(index, counts)| {
            let job = match (&masks, counts) {
                (Some(s), Some(c)) => {
                    let job = super::masks::scales(&dir, &layout, s, &c, &input_arg, ctx)?;
                    serde_json::to_value(job)?
                }
                _ => serde_json::to_value(FlowJob::new(settings.clone(), &input_arg))?,
            };
            Ok((index, job))
        });
    let (index_bytes, job) = match cut {
        Ok(b) => b,
        Err(e) => {
            // Nothing of a plan that cannot run is left (the folder was new or empty).
            for sub in &subs {
                let _ = std::fs::remove_dir_all(dir.join(sub));
            }
            return Err(e.context(format!("cannot plan {}", input.display())));
        }
    };
    let command = if masks.is_some() { "masks" } else { "flow" };
    let mut args = vec![
        command.to_string(),
        input.display().to_string(),
        "--out".into(),
        out.display().to_string(),
        "--depressions".into(),
        "fill".into(),
        "--directions".into(),
        "d8".into(),
        "--channel-area".into(),
        settings.channel_area.to_string(),
    ];
    if let Some(s) = &masks {
        args.extend(super::masks::args(s));
    }
    let phases = if masks.is_some() { MASK_PHASES } else { PHASES };
    let mut m = Manifest {
        format: FORMAT.into(),
        version: VERSION,
        command: command.into(),
        args,
        job,
        inputs: vec![input_sum],
        prepared: bytes_sum(&index_bytes, INPUT_INDEX.into()),
        output: OutputGrid {
            path: out.display().to_string(),
            width: layout.width,
            height: layout.height,
            cell_size: [cx, cy],
            georef: dem.georef.clone(),
        },
        tile: a.tile,
        tiles_x: layout.tiles_x(),
        tiles_y: layout.tiles_y(),
        tasks,
        phases,
        plan_id: String::new(),
    };
    m.plan_id = hex(Sha256::digest(serde_json::to_vec(&m)?));
    let json = crate::staging::json_text(&m)?;
    relief_io::write_bytes_atomic(&dir.join(MANIFEST), json.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join(MANIFEST).display()))?;
    let bands = match &masks {
        Some(_) => Some(
            serde_json::from_value::<super::masks::MasksJob>(m.job.clone())?
                .scales
                .bands,
        ),
        None => None,
    };
    note(ctx, &layout, &input, &dir, a.tile, bands);
    Ok(())
}

/// The plan step's note: the plan, its memory, and the chain of phases on Slurm; `bands` are
/// a masks plan's height bands.
fn note(
    ctx: &Ctx,
    layout: &TileLayout,
    input: &Path,
    dir: &Path,
    tile: usize,
    bands: Option<Vec<f64>>,
) {
    let tasks = layout.tasks();
    let phases = if bands.is_some() { MASK_PHASES } else { PHASES };
    let (per_tile, single) = layout.memory_estimate();
    let mb = |b: u64| b as f64 / 1e6;
    let last = tasks - 1;
    let d = dir.display();
    let mut chain = String::new();
    for p in 1..=phases {
        let array = if super::single(p) {
            String::new()
        } else {
            format!(" --array=0-{last}")
        };
        let (var, dep) = (
            if p < phases {
                format!("j{p}=$(sbatch --parsable")
            } else {
                "sbatch".into()
            },
            if p > 1 {
                format!(" --dependency=afterok:$j{}", p - 1)
            } else {
                String::new()
            },
        );
        let close = if p < phases { ")" } else { "" };
        chain.push_str(&format!(
            "  {var}{dep}{array} --wrap 'relief tile run {d} --phase {p}'{close}\n"
        ));
    }
    let (what, extra) = match &bands {
        None => ("the drainage", String::new()),
        Some(b) => (
            "the masks",
            format!(
                "; phase 8 (per tile) writes the masks from the drainage and the map's height \
                 bands {b:?} m and profile-curvature scale, found exactly while planning"
            ),
        ),
    };
    ctx.note(format!(
        "planned {what} of {} x {} cells ({}) as {} tiles of {} px ({} x {}) in {phases} \
         phases in {}{extra}\n\
         memory: about {:.0} MB per tile task and {:.0} MB for the single tasks (phases 2, 4, \
         6) plus 60 bytes per cell of the flats that cross tile edges; the mosaic holds {}\n\
         not planned: {}\n\
         run them in order, each after the previous one succeeded, e.g. on Slurm:\n{chain}\
         then: relief tile mosaic {d}",
        layout.width,
        layout.height,
        input.display(),
        tasks,
        tile,
        layout.tiles_x(),
        layout.tiles_y(),
        dir.display(),
        mb(per_tile),
        mb(single),
        if bands.is_some() {
            "one row of tiles of the splat map (4 bytes per cell)"
        } else {
            "the channel network (about 200 bytes per channel cell)"
        },
        if bands.is_some() {
            super::masks::NOT_PLANNED
        } else {
            NOT_PLANNED
        },
    ));
}

/// The DEM the plan cuts: read band by band (a GeoTIFF file: the plan step holds a band of
/// tile rows, never the whole DEM), or whole (other formats, devices, `--fill-voids`, whose
/// filling is global), with the values, cell size and georeference `relief flow` reads.
struct Dem {
    source: Source,
    cell: (f64, f64),
    georef: Option<GeoRef>,
}

enum Source {
    Bands(Box<relief_io::GeoTiffBands>),
    Whole(Box<Heightfield>),
}

impl Dem {
    fn open(path: &Path, read: &crate::args::ReadArgs, ctx: &Ctx) -> Result<Self> {
        let streamable = !read.fill_voids
            && std::fs::metadata(path).is_ok_and(|m| m.is_file())
            && first_bytes(path).is_some_and(|b| {
                relief_io::Format::detect(&b, Some(path)).ok() == Some(relief_io::Format::GeoTiff)
            });
        if !streamable {
            let why = if read.fill_voids {
                "--fill-voids fills the whole DEM first"
            } else {
                "only a GeoTIFF file is read band by band"
            };
            ctx.note(format!(
                "{}: read whole to cut the tiles ({why}; about 6 bytes per cell)",
                path.display()
            ));
            let hf = crate::commands::read_raster_for(path, read, ctx, None)?.heightfield;
            if hf.as_slice().iter().all(|v| v.is_nan()) {
                bail!("{} has no valid cell to route", path.display());
            }
            return Ok(Dem {
                cell: hf.cell_size(),
                georef: hf.georef().cloned(),
                source: Source::Whole(Box::new(hf)),
            });
        }
        let mut opts = read.options();
        opts.cell_size = None;
        let bands = relief_io::GeoTiffBands::open(path, &opts)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let (mut cell, mut georef) = (bands.cell_size(), bands.georef().cloned());
        if let Some(new) = read.cell_size {
            // As `relief flow` reads it (`read_raster_for`).
            Heightfield::new(1, 1, vec![0.0], new.0, new.1)
                .with_context(|| format!("--cell-size {},{}", new.0, new.1))?;
            let size = (bands.width(), bands.height());
            georef = crate::commands::cell_size_georef(georef.as_ref(), size, cell, new);
            cell = new;
        }
        Ok(Dem {
            source: Source::Bands(Box::new(bands)),
            cell,
            georef,
        })
    }

    fn size(&self) -> (usize, usize) {
        match &self.source {
            Source::Bands(b) => (b.width(), b.height()),
            Source::Whole(hf) => (hf.width(), hf.height()),
        }
    }
}

/// The first bytes of a file (its format's magic).
fn first_bytes(path: &Path) -> Option<Vec<u8>> {
    use std::io::Read as _;
    let mut b = Vec::with_capacity(64);
    std::fs::File::open(path)
        .ok()?
        .take(64)
        .read_to_end(&mut b)
        .ok()?;
    Some(b)
}

/// Writes every tile's window with its one-cell margin (`input/tile-N.tif`), so a phase-1
/// task reads its tile alone, and `input/index.json` (their checksums); returns the index,
/// and for a masks plan (`masks`) the first pass of the map's mask scales.
/// A streamed DEM is read one row of tiles (and its margin rows) at a time.
fn cut_inputs(
    dir: &Path,
    layout: &TileLayout,
    dem: &mut Dem,
    masks: bool,
    ctx: &Ctx,
) -> Result<(Vec<u8>, Option<ScaleCounts>)> {
    // Merged as each tile is counted (integer counts: the order does not matter), so a row of
    // many small tiles never holds more than one count table per thread.
    let counts = std::sync::Mutex::new(masks.then(ScaleCounts::empty));
    let (cx, cy) = (layout.cell_x, layout.cell_y);
    let mut index = Vec::with_capacity(layout.tasks());
    let mut rows = Vec::new();
    let mut any_valid = false;
    let progress = ctx.progress();
    progress.begin("cutting the tiles' inputs", layout.tiles_y() as u64);
    for ty in 0..layout.tiles_y() {
        let row: Vec<usize> = (ty * layout.tiles_x()..(ty + 1) * layout.tiles_x()).collect();
        let (first, end) = tiled::halo_rows(layout, row[0])?;
        let (band, band_first): (&[f32], usize) = match &mut dem.source {
            Source::Whole(hf) => (hf.as_slice(), 0),
            Source::Bands(b) => {
                b.read_rows(first, end - first, &mut rows)?;
                let own = &rows[(ty * layout.tile - first) * layout.width..];
                let own = &own[..own.len().min(layout.tile * layout.width)];
                any_valid |= own.iter().any(|v| !v.is_nan());
                (&rows, first)
            }
        };
        let cut = row
            .into_par_iter()
            .map(|t| {
                let [_, _, w, h] = layout.window(t);
                let halo = tiled::halo_from_rows(layout, t, band, band_first)?;
                let hf = Heightfield::new(w + 2, h + 2, halo, cx, cy)?;
                if masks {
                    let c = ScaleCounts::of_tile(layout, t, hf.as_slice())?;
                    if let Some(all) = counts.lock().unwrap_or_else(|e| e.into_inner()).as_mut() {
                        all.merge(&c);
                    }
                }
                // Uncompressed: the plan, phase 1 and phase 7 spent about a third of their
                // time in DEFLATE and its predictor on these (4 bytes per cell on disk).
                let bytes =
                    relief_io::encode(&hf, relief_io::Format::GeoTiff, &Default::default())?;
                let name = input_name(t);
                let path = dir.join(&name);
                relief_io::write_bytes_atomic(&path, &bytes)
                    .with_context(|| format!("cannot write {}", path.display()))?;
                Ok(bytes_sum(&bytes, name))
            })
            .collect::<Result<Vec<FileSum>>>()?;
        index.extend(cut);
        progress.advance(1);
    }
    if matches!(dem.source, Source::Bands(_)) && !any_valid {
        bail!("the DEM has no valid cell to route (every cell is a void)");
    }
    let index_bytes = serde_json::to_vec(&index)?;
    relief_io::write_bytes_atomic(&dir.join(INPUT_INDEX), &index_bytes)
        .with_context(|| format!("cannot write {}", dir.join(INPUT_INDEX).display()))?;
    Ok((
        index_bytes,
        counts.into_inner().unwrap_or_else(|e| e.into_inner()),
    ))
}
