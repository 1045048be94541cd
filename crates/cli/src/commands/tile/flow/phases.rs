//! `relief tile run` on a flow plan: the phase and task to run, and each phase's task.

use super::*;

/// `relief tile run` on a flow plan.
pub(in crate::commands::tile) fn run_task(
    dir: &Path,
    m: &Manifest,
    a: &RunArgs,
    ctx: &Ctx,
) -> Result<()> {
    let layout = layout(m)?;
    check_folders(dir, m)?;
    let phases = m.phases;
    let phase = match a.phase {
        Some(p) if (1..=phases).contains(&p) => p,
        Some(p) => bail!("--phase {p} is out of range: this plan has phases 1 to {phases}"),
        // The first phase with a task unrecorded, or whose task of this index (0 for a
        // single phase) is not done (its own files are checked, not the whole plan's).
        None => {
            let own = super::task::task_index(a.index).unwrap_or(0);
            let next = (1..=phases).find(|&p| {
                let i = if single(p) { 0 } else { own };
                (0..tasks_of(p, m)).any(|j| load_record(dir, m, p, j).is_none())
                    || (i < m.tasks && task_state(dir, m, p, i) != TileState::Done)
            });
            match next {
                Some(p) => p,
                None => {
                    ctx.note("every phase of the plan is done: relief tile mosaic can assemble it");
                    return Ok(());
                }
            }
        }
    };
    // Earlier phases must be complete (a dependency that did not hold): every task recorded.
    // The files this task reads are checked against their records when read; hashing every
    // earlier product here would make each task read the whole plan.
    for p in 1..phase {
        let bad: Vec<usize> = (0..tasks_of(p, m))
            .filter(|&i| load_record(dir, m, p, i).is_none())
            .collect();
        if !bad.is_empty() {
            bail!(
                "phase {phase} cannot run: phase {p} is incomplete (tasks {} are missing or \
                 corrupt); run them first",
                ranges(&bad)
            );
        }
    }
    let index = if single(phase) {
        match a.index {
            None | Some(0) => 0,
            Some(i) => bail!("phase {phase} is one task (index 0), not task {i}"),
        }
    } else {
        let i = match a.index {
            Some(i) => i,
            None if INDEX_VARS.iter().any(|v| std::env::var_os(v).is_some()) => {
                super::task::task_index(None)?
            }
            None => bail!(
                "no task index for phase {phase} (one task per tile): pass --index or run under \
                 a job array ({})",
                INDEX_VARS.join(", ")
            ),
        };
        if i >= m.tasks {
            bail!(
                "task index {i} is out of range: the plan has {} tiles (0..{})",
                m.tasks,
                m.tasks - 1
            );
        }
        i
    };
    if task_state(dir, m, phase, index) == TileState::Done {
        ctx.note(format!("phase {phase} task {index} is already done"));
        return Ok(());
    }
    let outputs: PhaseOutputs = match phase {
        1 => bytes(phase1(dir, m, &layout, index)?),
        2 => bytes(phase2(dir, m, &layout)?),
        3 => bytes(phase3(dir, m, &layout, index)?),
        4 => bytes(phase4(dir, m, &layout)?),
        5 => phase5(dir, m, &layout, index)?,
        6 => bytes(phase6(dir, m, &layout)?),
        PHASES => phase7(dir, m, &layout, index)?,
        _ => super::masks::phase8(dir, m, &layout, index)?,
    };
    let names = outputs_of(m, phase, index);
    let mut files = Vec::with_capacity(outputs.len());
    for ((name, bytes), want) in outputs.iter().zip(&names) {
        debug_assert_eq!(name, want);
        let path = dir.join(name);
        match bytes {
            Some(bytes) => {
                relief_io::write_bytes_atomic(&path, bytes)
                    .with_context(|| format!("cannot write {}", path.display()))?;
                files.push(bytes_sum(bytes, name.clone()));
            }
            // A raster the phase wrote in place (atomically).
            None => files.push(file_sum(&path, name.clone())?),
        }
    }
    let rec = PhaseRecord {
        plan_id: m.plan_id.clone(),
        phase,
        index,
        files,
    };
    let json = crate::staging::json_text(&rec)?;
    let rp = dir.join(record_name(phase, index));
    relief_io::write_bytes_atomic(&rp, json.as_bytes())
        .with_context(|| format!("cannot write {}", rp.display()))?;
    ctx.note(format!("phase {phase} task {index} done"));
    Ok(())
}

/// A phase task's outputs by file name: the bytes to write, or `None` for a raster the phase
/// wrote in place (atomically).
pub(super) type PhaseOutputs = Vec<(String, Option<Vec<u8>>)>;

/// Outputs to write (none written in place).
fn bytes(v: Vec<(String, Vec<u8>)>) -> PhaseOutputs {
    v.into_iter().map(|(n, b)| (n, Some(b))).collect()
}

/// Writes tile `t`'s rasters (`names`, values row-major) in place as tiled GeoTIFFs in a
/// mosaic's block side and codec (DEFLATE), so that `relief tile mosaic` copies their encoded
/// blocks instead of decoding and encoding them again (unless it writes another codec or a
/// COG).
pub(super) fn write_rasters(
    dir: &Path,
    m: &Manifest,
    l: &TileLayout,
    t: usize,
    rasters: Vec<(&String, Vec<f32>)>,
) -> Result<()> {
    let [x, y, w, h] = l.window(t);
    let georef = m
        .output
        .georef
        .as_ref()
        .map(|g| g.window(x as f64, y as f64, 1.0, 1.0));
    let opts = relief_io::TiledOptions {
        tile: super::super::mosaic::MOSAIC_BLOCK,
        compression: relief_io::TiffCompression::Deflate,
        cog: false,
        bigtiff: false,
    };
    for (name, data) in rasters {
        let path = dir.join(name);
        let cannot = || format!("cannot write {}", path.display());
        let mut out = relief_io::TiledGeoTiffWriter::create(
            &path,
            w,
            h,
            (l.cell_x, l.cell_y),
            georef.as_ref(),
            opts,
        )
        .with_context(cannot)?;
        out.write_rows(&data).with_context(cannot)?;
        out.finish().with_context(cannot)?;
    }
    Ok(())
}

fn phase1(dir: &Path, m: &Manifest, l: &TileLayout, t: usize) -> Result<Vec<(String, Vec<u8>)>> {
    let hf = read_input(dir, m, l, t)?;
    let (fill, graph) = tiled::phase1(l, t, hf.as_slice())?;
    let names = outputs_of(m, 1, t);
    Ok(vec![
        (names[0].clone(), fill.to_bytes(t)),
        (names[1].clone(), graph.to_bytes(l, t)),
    ])
}

/// Tile `t`'s input (the tile and its one-cell margin), checked against the input index.
pub(super) fn read_input(
    dir: &Path,
    m: &Manifest,
    l: &TileLayout,
    t: usize,
) -> Result<Heightfield> {
    // The input index is checked against the manifest, the tile's input against the index.
    let index_bytes = read_plan_file(dir, INPUT_INDEX, 4096 + 256 * m.tasks as u64)?;
    if bytes_sum(&index_bytes, m.prepared.path.clone()) != m.prepared {
        bail!(
            "{} does not match its checksum in the manifest (corrupt or replaced); plan again",
            dir.join(INPUT_INDEX).display()
        );
    }
    let index: Vec<FileSum> = serde_json::from_slice(&index_bytes)
        .with_context(|| format!("{} is not an input index", dir.join(INPUT_INDEX).display()))?;
    let name = input_name(t);
    let want = index
        .get(t)
        .filter(|s| s.path == name && index.len() == m.tasks)
        .with_context(|| format!("{} does not list tile {t}", INPUT_INDEX))?;
    let [_, _, w, h] = l.window(t);
    let bytes = read_plan_file(dir, &name, (1 << 20) + (16 * (w + 2) * (h + 2)) as u64)?;
    if bytes_sum(&bytes, name.clone()) != *want {
        bail!(
            "{} does not match its checksum in {INPUT_INDEX} (corrupt or replaced); plan again",
            dir.join(&name).display()
        );
    }
    let hf = relief_io::read_bytes(&bytes, Some(Path::new("tile.tif")), &Default::default())
        .with_context(|| format!("cannot read {}", dir.join(&name).display()))?
        .heightfield;
    if (hf.width(), hf.height()) != (w + 2, h + 2) {
        bail!(
            "{} is {} x {}, not the {} x {} of tile {t} and its margin",
            dir.join(&name).display(),
            hf.width(),
            hf.height(),
            w + 2,
            h + 2
        );
    }
    Ok(hf)
}

/// A single-task phase `phase`: decodes product `index` of every tile's task of phase `from`,
/// runs `run` over all of them and names every tile's encoded output.
#[allow(clippy::too_many_arguments)]
fn single_phase<I: Send, O>(
    dir: &Path,
    m: &Manifest,
    l: &TileLayout,
    (from, index): (usize, usize),
    phase: usize,
    decode: fn(&[u8], &TileLayout, usize) -> relief_landscape::Result<I>,
    run: fn(&TileLayout, &[I]) -> relief_landscape::Result<Vec<O>>,
    encode: fn(&O, &TileLayout, usize) -> Vec<u8>,
) -> Result<Vec<(String, Vec<u8>)>> {
    let inputs = (0..m.tasks)
        .into_par_iter()
        .map(|t| {
            let b = read_product(dir, m, from, t, index, t)?;
            Ok(decode(&b, l, t)?)
        })
        .collect::<Result<Vec<_>>>()?;
    let outputs = run(l, &inputs)?;
    let names = outputs_of(m, phase, 0);
    Ok(outputs
        .iter()
        .enumerate()
        .map(|(t, x)| (names[t].clone(), encode(x, l, t)))
        .collect())
}

fn phase2(dir: &Path, m: &Manifest, l: &TileLayout) -> Result<Vec<(String, Vec<u8>)>> {
    single_phase(
        dir,
        m,
        l,
        (1, 1),
        2,
        FillGraph::from_bytes,
        tiled::phase2,
        Levels::to_bytes,
    )
}

fn phase3(dir: &Path, m: &Manifest, l: &TileLayout, t: usize) -> Result<Vec<(String, Vec<u8>)>> {
    let fill = LocalFill::from_bytes(&read_product(dir, m, 1, t, 0, t)?, l, t)?;
    let near = l
        .neighbourhood(t)
        .into_iter()
        .map(|u| {
            let b = read_product(dir, m, 2, 0, u, u)?;
            Ok((u, Levels::from_bytes(&b, l, u)?))
        })
        .collect::<Result<Vec<_>>>()?;
    let refs: Vec<(usize, &Levels)> = near.iter().map(|(u, lv)| (*u, lv)).collect();
    let (routed, ports) = tiled::phase3(l, t, &fill, &refs)?;
    let names = outputs_of(m, 3, t);
    Ok(vec![
        (names[0].clone(), routed.to_bytes(l, t)),
        (names[1].clone(), ports.to_bytes(l, t)),
    ])
}

fn phase4(dir: &Path, m: &Manifest, l: &TileLayout) -> Result<Vec<(String, Vec<u8>)>> {
    single_phase(
        dir,
        m,
        l,
        (3, 1),
        4,
        PortGraph::from_bytes,
        tiled::phase4,
        Inflow::to_bytes,
    )
}

/// Tile `t`'s final filled elevations, directions and upstream cells (phase 5's values, which
/// phase 7 computes again rather than decoding three rasters).
pub(super) fn finished(
    dir: &Path,
    m: &Manifest,
    l: &TileLayout,
    t: usize,
) -> Result<tiled::Finished> {
    let routed = Routed::from_bytes(&read_product(dir, m, 3, t, 0, t)?, l, t)?;
    let inflow = Inflow::from_bytes(&read_product(dir, m, 4, 0, t, t)?, l, t)?;
    Ok(tiled::phase5(l, t, &routed, &inflow)?)
}

/// The channel area of the plan's settings.
fn channel_area(m: &Manifest) -> Result<f64> {
    let flow = if is_masks(m) {
        super::masks::job(m)?.masks.flow
    } else {
        let job: FlowJob = serde_json::from_value(m.job.clone())
            .context("the manifest's job is not a flow job's settings")?;
        job.flow
    };
    flow.check().map_err(crate::args::flag_error)?;
    Ok(flow.channel_area)
}

fn phase5(dir: &Path, m: &Manifest, l: &TileLayout, t: usize) -> Result<PhaseOutputs> {
    let f = finished(dir, m, l, t)?;
    let summary = tiled::summarize(l, t, &f, channel_area(m)?)?.to_bytes(l, t);
    let names = outputs_of(m, 5, t);
    if is_masks(m) {
        return Ok(vec![(names[0].clone(), Some(summary))]);
    }
    // The same values `relief flow` writes (relief-landscape's `FlowSettings::run`).
    let (dir_codes, area) = (f.direction_codes(), f.area(l));
    rasters_and_bytes(dir, m, l, t, &names, [f.filled, dir_codes, area], summary)
}

/// Writes the three rasters of tile `t` under the first three `names`: those three without
/// their bytes (written) and the fourth with `bytes`.
fn rasters_and_bytes(
    dir: &Path,
    m: &Manifest,
    l: &TileLayout,
    t: usize,
    names: &[String],
    rasters: [Vec<f32>; 3],
    bytes: Vec<u8>,
) -> Result<PhaseOutputs> {
    write_rasters(dir, m, l, t, names.iter().zip(rasters).collect())?;
    Ok(in_place_then_bytes(&names[..3], &names[3], bytes))
}

/// The outputs of a task that wrote the rasters `in_place` itself, then `name` with `bytes`.
pub(super) fn in_place_then_bytes(in_place: &[String], name: &str, bytes: Vec<u8>) -> PhaseOutputs {
    let mut out: PhaseOutputs = in_place.iter().map(|n| (n.clone(), None)).collect();
    out.push((name.to_string(), Some(bytes)));
    out
}

fn phase6(dir: &Path, m: &Manifest, l: &TileLayout) -> Result<Vec<(String, Vec<u8>)>> {
    single_phase(
        dir,
        m,
        l,
        // The summary: a masks plan's phase 5 writes nothing else.
        (5, if is_masks(m) { 0 } else { 3 }),
        6,
        tiled::NetSummary::from_bytes,
        tiled::phase6,
        tiled::NetLevels::to_bytes,
    )
}

fn phase7(dir: &Path, m: &Manifest, l: &TileLayout, t: usize) -> Result<PhaseOutputs> {
    let f = finished(dir, m, l, t)?;
    let levels = tiled::NetLevels::from_bytes(&read_product(dir, m, 6, 0, t, t)?, l, t)?;
    let input = read_input(dir, m, l, t)?;
    let (r, net) = tiled::phase7(l, t, &f, &levels, input.as_slice(), channel_area(m)?)?;
    let [_, _, w, _] = l.window(t);
    let names = outputs_of(m, 7, t);
    if is_masks(m) {
        let hand = relief_heightfield::bytes::f32_to_le_bytes(&r.hand);
        return Ok(vec![(names[0].clone(), Some(hand))]);
    }
    // The same values `relief flow` writes: voids NaN in the order and the watersheds.
    let (order, label) = r.to_f32(w, input.as_slice());
    let net = net.to_bytes(l, t);
    rasters_and_bytes(dir, m, l, t, &names, [order, label, r.hand], net)
}
