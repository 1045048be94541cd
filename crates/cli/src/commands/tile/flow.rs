//! `relief tile plan DIR -- flow DEM -o OUT_DIR`: drainage as a multi-phase plan
//! (relief-landscape's `flow::tiled`: Barnes 2016 filling and Barnes 2017 accumulation), five
//! phases, each a task array or one task, that a scheduler chains with dependencies
//! (`sbatch --dependency=afterok:<previous>`):
//!
//! | phase | tasks | reads | writes |
//! |---|---|---|---|
//! | 1 | one per tile | `input/tile-N.tif` (the tile and a one-cell margin) | `phase1/fill-N.bin`, `phase1/graph-N.bin` |
//! | 2 | one | every `phase1/graph-N.bin` | `phase2/levels-N.bin` |
//! | 3 | one per tile | `phase1/fill-N.bin`, the levels of the tile and its neighbours | `phase3/routed-N.bin`, `phase3/ports-N.bin` |
//! | 4 | one | every `phase3/ports-N.bin` | `phase4/inflow-N.bin` |
//! | 5 | one per tile | `phase3/routed-N.bin`, `phase4/inflow-N.bin` | `tiles/{filled,direction,area}-N.tif` |
//!
//! Every task writes its files atomically, then `phaseP/task-N.json` (the plan id and the
//! files' SHA-256); a task whose record and files agree is skipped, so a killed task is run
//! again. Plan files are untrusted input: a task reads only files whose names it derives from
//! the phase and the index, inside the plan folder's own folders (links in place of them are
//! refused, so no read or write goes through one), regular files (not links), no larger than
//! the tile allows, and checks each against the record of the task that wrote it (and the
//! inputs against `input/index.json`, whose checksum the manifest holds) before decoding it
//! with relief-landscape's checked byte forms.
//!
//! `relief tile mosaic` writes `OUT_DIR/filled.tif`, `direction.tif` and `area.tif` (together
//! or not at all), equal bit for bit to those of `relief flow` (the other products of
//! `relief flow` are not planned).

use relief_landscape::flow::ESRI_CODES;
use relief_landscape::flow::job::FlowSettings;
use relief_landscape::flow::tiled::{
    self, FillGraph, Inflow, Levels, LocalFill, PHASES, PortGraph, Routed, TileLayout,
};
use relief_landscape::flow::{Depressions, Directions};
use relief_landscape::grid::NO_FLOW;
use serde::{Deserialize, Serialize};

use super::mosaic::ranges;
use super::*;
use crate::outputs::OutKind;

/// The rasters a flow plan mosaics into its output folder.
pub(super) const PRODUCTS: [&str; 3] = ["filled", "direction", "area"];

/// The parser of the planned flow command.
#[derive(Debug, clap::Parser)]
#[command(name = "relief", no_binary_name = true)]
struct FlowInner {
    #[command(subcommand)]
    command: FlowCommand,
}

#[derive(Debug, clap::Subcommand)]
enum FlowCommand {
    Flow(crate::commands::flow::Args),
}

/// What the manifest's `job` holds for a flow plan.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct FlowJob {
    /// The job's settings (relief-landscape's `FlowSettings`).
    flow: FlowSettings,
}

fn out_files() -> Vec<(String, OutKind)> {
    PRODUCTS
        .iter()
        .map(|p| (format!("{p}.tif"), OutKind::Raster))
        .collect()
}

/// The settings a tiled plan reproduces exactly, or an error naming the flag.
fn tileable(s: &FlowSettings) -> Result<()> {
    if s.depressions != Depressions::Fill {
        bail!(
            "--depressions {} cannot be planned as tiles: only `fill` (the default: priority-flood \
             filling, then drainage across the flats) has a tiled form equal to the single run \
             (epsilon filling and breaching depend on the order of the whole flood)",
            serde_json::to_value(s.depressions)?.as_str().unwrap_or("?")
        );
    }
    if s.directions != Directions::D8 {
        bail!(
            "--directions mfd cannot be planned as tiles: the tiled accumulation is D8's \
             (Barnes 2017 routes one receiver per cell)"
        );
    }
    Ok(())
}

fn layout(m: &Manifest) -> Result<TileLayout> {
    let l = TileLayout {
        width: m.output.width,
        height: m.output.height,
        tile: m.tile,
        cell_x: m.output.cell_size[0],
        cell_y: m.output.cell_size[1],
    };
    l.check()
        .with_context(|| "the manifest's grid cannot be tiled".to_string())?;
    if l.tasks() != m.tasks || m.phases != PHASES {
        bail!("the manifest's tile grid or phases do not match a flow plan");
    }
    Ok(l)
}

/// `relief tile plan DIR --tile N -- flow ...`.
pub(super) fn plan(a: &PlanArgs, ctx: &Ctx) -> Result<()> {
    if a.tile < 16 || !a.tile.is_multiple_of(16) || a.tile > 1 << 15 {
        bail!(
            "invalid --tile {}: must be a multiple of 16 between 16 and 32768",
            a.tile
        );
    }
    let parsed = FlowInner::try_parse_from(&a.command)
        .map_err(|e| anyhow::anyhow!("invalid command after `--`: {}", e.to_string().trim()))?;
    let FlowCommand::Flow(f) = parsed.command;
    let settings = crate::commands::flow::settings(&f)?;
    tileable(&settings)?;
    if f.json {
        bail!("--json cannot be planned: a plan writes no report (relief tile status does)");
    }
    let input = absolute(&f.input)?;
    let out = absolute(&f.out)?;
    let dir = absolute(&a.dir)?;
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
    if dir.starts_with(&input) || out.starts_with(&dir) || dir.starts_with(&out) {
        bail!(
            "the plan folder {} must not contain the output folder, lie in it, or be the input",
            dir.display()
        );
    }
    // The output folder is checked as `relief flow` checks it (then the staging is dropped).
    let files = out_files();
    let names: Vec<(&str, OutKind)> = files.iter().map(|(n, k)| (n.as_str(), *k)).collect();
    drop(crate::folder::FolderOutputs::new(
        &out,
        &names,
        &[&input],
        ctx,
    )?);
    let mut dem = Dem::open(&input, &f.read, ctx)?;
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
    for sub in FOLDERS {
        std::fs::create_dir_all(dir.join(sub))
            .with_context(|| format!("cannot create {}", dir.join(sub).display()))?;
    }
    let index_bytes = match cut_inputs(&dir, &layout, &mut dem, ctx) {
        Ok(b) => b,
        Err(e) => {
            // Nothing of a plan that cannot run is left (the folder was new or empty).
            for sub in FOLDERS {
                let _ = std::fs::remove_dir_all(dir.join(sub));
            }
            return Err(e.context(format!("cannot plan {}", input.display())));
        }
    };
    let args = vec![
        "flow".to_string(),
        input.display().to_string(),
        "--out".into(),
        out.display().to_string(),
        "--depressions".into(),
        "fill".into(),
        "--directions".into(),
        "d8".into(),
    ];
    let mut m = Manifest {
        format: FORMAT.into(),
        version: VERSION,
        command: "flow".into(),
        args,
        job: serde_json::to_value(FlowJob { flow: settings })?,
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
        phases: PHASES,
        plan_id: String::new(),
    };
    m.plan_id = hex(Sha256::digest(serde_json::to_vec(&m)?));
    let json = crate::staging::json_text(&m)?;
    relief_io::write_bytes_atomic(&dir.join(MANIFEST), json.as_bytes())
        .with_context(|| format!("cannot write {}", dir.join(MANIFEST).display()))?;
    let (per_tile, single) = layout.memory_estimate();
    let mb = |b: u64| b as f64 / 1e6;
    ctx.note(format!(
        "planned the drainage of {} x {} cells ({}) as {} tiles of {} px ({} x {}) in five \
         phases in {}\n\
         memory: about {:.0} MB per tile task (phases 1, 3, 5) and {:.0} MB for the single tasks \
         (phases 2, 4) plus 60 bytes per cell of the flats that cross tile edges\n\
         run them in order, each after the previous one succeeded, e.g. on Slurm:\n  \
         j1=$(sbatch --parsable --array=0-{last} --wrap 'relief tile run {d} --phase 1')\n  \
         j2=$(sbatch --parsable --dependency=afterok:$j1 --wrap 'relief tile run {d} --phase 2')\n  \
         j3=$(sbatch --parsable --dependency=afterok:$j2 --array=0-{last} --wrap 'relief tile run {d} --phase 3')\n  \
         j4=$(sbatch --parsable --dependency=afterok:$j3 --wrap 'relief tile run {d} --phase 4')\n  \
         sbatch --dependency=afterok:$j4 --array=0-{last} --wrap 'relief tile run {d} --phase 5'\n\
         then: relief tile mosaic {d}",
        layout.width,
        layout.height,
        input.display(),
        tasks,
        a.tile,
        layout.tiles_x(),
        layout.tiles_y(),
        dir.display(),
        mb(per_tile),
        mb(single),
        last = tasks - 1,
        d = dir.display(),
    ));
    Ok(())
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
/// task reads its tile alone, and `input/index.json` (their checksums); returns the index.
/// A streamed DEM is read one row of tiles (and its margin rows) at a time.
fn cut_inputs(dir: &Path, layout: &TileLayout, dem: &mut Dem, ctx: &Ctx) -> Result<Vec<u8>> {
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
                let bytes = deflate_geotiff(&hf)?;
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
    Ok(index_bytes)
}

const INPUT_INDEX: &str = "input/index.json";

/// The plan's folders: every file a task reads or writes is in one of them.
const FOLDERS: [&str; 6] = ["input", "phase1", "phase2", "phase3", "phase4", "tiles"];

/// Every folder of the plan must be a real folder inside it.
fn check_folders(dir: &Path) -> Result<()> {
    FOLDERS.iter().try_for_each(|f| check_plan_folder(dir, f))
}

fn input_name(t: usize) -> String {
    format!("input/tile-{t:06}.tif")
}

/// The files task `index` of `phase` writes, by name (relative to the plan folder).
fn outputs_of(phase: usize, index: usize, tasks: usize) -> Vec<String> {
    match phase {
        1 => vec![
            format!("phase1/fill-{index:06}.bin"),
            format!("phase1/graph-{index:06}.bin"),
        ],
        2 => (0..tasks)
            .map(|t| format!("phase2/levels-{t:06}.bin"))
            .collect(),
        3 => vec![
            format!("phase3/routed-{index:06}.bin"),
            format!("phase3/ports-{index:06}.bin"),
        ],
        4 => (0..tasks)
            .map(|t| format!("phase4/inflow-{t:06}.bin"))
            .collect(),
        _ => PRODUCTS.iter().map(|p| product_name(p, index)).collect(),
    }
}

/// `tiles/<product>-N.tif`.
pub(super) fn product_name(product: &str, t: usize) -> String {
    format!("tiles/{product}-{t:06}.tif")
}

fn record_name(phase: usize, index: usize) -> String {
    let folder = if phase == PHASES {
        "tiles".to_string()
    } else {
        format!("phase{phase}")
    };
    format!("{folder}/task-{index:06}.json")
}

fn tasks_of(phase: usize, m: &Manifest) -> usize {
    if tiled::is_single(phase) { 1 } else { m.tasks }
}

/// The record of a finished task of a flow plan.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub(super) struct PhaseRecord {
    plan_id: String,
    phase: usize,
    index: usize,
    files: Vec<FileSum>,
}

/// Largest plan file a task reads: a tile's products take at most about 50 bytes per cell.
fn max_bytes(m: &Manifest, t: usize) -> u64 {
    let [_, _, w, h] = m.window(t);
    4096 + 64 * ((w + 4) * (h + 4)) as u64
}

/// The record of task `index` of `phase` when it is valid for this plan (not the files).
fn load_record(dir: &Path, m: &Manifest, phase: usize, index: usize) -> Option<PhaseRecord> {
    let max = 4096 + 256 * m.tasks as u64;
    let bytes = read_plan_file(dir, &record_name(phase, index), max).ok()?;
    parse_record(m, phase, index, &bytes)
}

/// The record of task `index` of `phase` in `bytes` when it is valid for this plan: its plan
/// id, phase and index, and the file names the task writes, in order.
pub(super) fn parse_record(
    m: &Manifest,
    phase: usize,
    index: usize,
    bytes: &[u8],
) -> Option<PhaseRecord> {
    let r: PhaseRecord = serde_json::from_slice(bytes).ok()?;
    let names = outputs_of(phase, index, m.tasks);
    let ok = r.plan_id == m.plan_id
        && r.phase == phase
        && r.index == index
        && r.files.len() == names.len()
        && r.files.iter().zip(&names).all(|(f, n)| &f.path == n);
    ok.then_some(r)
}

/// The files an accepted record of task `index` of `phase` lists (the fuzz target's view).
pub(crate) fn record_files(
    m: &Manifest,
    phase: usize,
    index: usize,
    bytes: &[u8],
) -> Option<Vec<String>> {
    parse_record(m, phase, index, bytes).map(|r| r.files.into_iter().map(|f| f.path).collect())
}

/// Done, missing or corrupt: a task is done when its record is valid and every file it lists
/// has the recorded checksum.
fn task_state(dir: &Path, m: &Manifest, phase: usize, index: usize) -> TileState {
    if std::fs::symlink_metadata(dir.join(record_name(phase, index))).is_err() {
        return TileState::Missing;
    }
    let Some(r) = load_record(dir, m, phase, index) else {
        return TileState::Corrupt;
    };
    for f in &r.files {
        let p = dir.join(&f.path);
        let regular = std::fs::symlink_metadata(&p)
            .is_ok_and(|md| md.file_type().is_file() && md.len() == f.bytes);
        if !regular || file_sum(&p, f.path.clone()).ok().as_ref() != Some(f) {
            return TileState::Corrupt;
        }
    }
    TileState::Done
}

/// Reads file `k` of the record of task `index` of `phase`, checked against the record.
fn read_product(
    dir: &Path,
    m: &Manifest,
    phase: usize,
    index: usize,
    k: usize,
    tile: usize,
) -> Result<Vec<u8>> {
    let r = load_record(dir, m, phase, index).with_context(|| {
        format!(
            "phase {phase} task {index} is not done (its record is missing or invalid): run it \
             first (relief tile status {})",
            dir.display()
        )
    })?;
    let f = &r.files[k];
    let bytes = read_plan_file(dir, &f.path, max_bytes(m, tile))?;
    if bytes_sum(&bytes, f.path.clone()) != *f {
        bail!(
            "{} does not match the checksum its task recorded (damaged or replaced): run phase \
             {phase} task {index} again",
            dir.join(&f.path).display()
        );
    }
    Ok(bytes)
}

/// Per phase, the tasks not done (missing, corrupt).
fn phase_states(dir: &Path, m: &Manifest) -> Vec<(Vec<usize>, Vec<usize>)> {
    (1..=PHASES)
        .map(|p| {
            let (mut missing, mut corrupt) = (Vec::new(), Vec::new());
            for i in 0..tasks_of(p, m) {
                match task_state(dir, m, p, i) {
                    TileState::Done => {}
                    TileState::Missing => missing.push(i),
                    TileState::Corrupt => corrupt.push(i),
                }
            }
            (missing, corrupt)
        })
        .collect()
}

/// `relief tile run` on a flow plan.
pub(super) fn run_task(dir: &Path, m: &Manifest, a: &RunArgs, ctx: &Ctx) -> Result<()> {
    let layout = layout(m)?;
    check_folders(dir)?;
    let phase = match a.phase {
        Some(p) if (1..=PHASES).contains(&p) => p,
        Some(p) => bail!("--phase {p} is out of range: a flow plan has phases 1 to {PHASES}"),
        // The first phase with a task unrecorded, or whose task of this index (0 for a
        // single phase) is not done (its own files are checked, not the whole plan's).
        None => {
            let own = super::task::task_index(a.index).unwrap_or(0);
            let next = (1..=PHASES).find(|&p| {
                let i = if tiled::is_single(p) { 0 } else { own };
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
    let index = if tiled::is_single(phase) {
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
    let outputs: Vec<(String, Vec<u8>)> = match phase {
        1 => phase1(dir, m, &layout, index)?,
        2 => phase2(dir, m, &layout)?,
        3 => phase3(dir, m, &layout, index)?,
        4 => phase4(dir, m, &layout)?,
        _ => phase5(dir, m, &layout, index)?,
    };
    let names = outputs_of(phase, index, m.tasks);
    let mut files = Vec::with_capacity(outputs.len());
    for ((name, bytes), want) in outputs.iter().zip(&names) {
        debug_assert_eq!(name, want);
        let path = dir.join(name);
        relief_io::write_bytes_atomic(&path, bytes)
            .with_context(|| format!("cannot write {}", path.display()))?;
        files.push(bytes_sum(bytes, name.clone()));
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

fn phase1(dir: &Path, m: &Manifest, l: &TileLayout, t: usize) -> Result<Vec<(String, Vec<u8>)>> {
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
    let (fill, graph) = tiled::phase1(l, t, hf.as_slice())?;
    let names = outputs_of(1, t, m.tasks);
    Ok(vec![
        (names[0].clone(), fill.to_bytes(t)),
        (names[1].clone(), graph.to_bytes(l, t)),
    ])
}

fn phase2(dir: &Path, m: &Manifest, l: &TileLayout) -> Result<Vec<(String, Vec<u8>)>> {
    let graphs = (0..m.tasks)
        .into_par_iter()
        .map(|t| {
            let b = read_product(dir, m, 1, t, 1, t)?;
            Ok(FillGraph::from_bytes(&b, l, t)?)
        })
        .collect::<Result<Vec<_>>>()?;
    let levels = tiled::phase2(l, &graphs)?;
    let names = outputs_of(2, 0, m.tasks);
    Ok(levels
        .iter()
        .enumerate()
        .map(|(t, lv)| (names[t].clone(), lv.to_bytes(l, t)))
        .collect())
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
    let names = outputs_of(3, t, m.tasks);
    Ok(vec![
        (names[0].clone(), routed.to_bytes(l, t)),
        (names[1].clone(), ports.to_bytes(l, t)),
    ])
}

fn phase4(dir: &Path, m: &Manifest, l: &TileLayout) -> Result<Vec<(String, Vec<u8>)>> {
    let graphs = (0..m.tasks)
        .into_par_iter()
        .map(|t| {
            let b = read_product(dir, m, 3, t, 1, t)?;
            Ok(PortGraph::from_bytes(&b, l, t)?)
        })
        .collect::<Result<Vec<_>>>()?;
    let inflow = tiled::phase4(l, &graphs)?;
    let names = outputs_of(4, 0, m.tasks);
    Ok(inflow
        .iter()
        .enumerate()
        .map(|(t, f)| (names[t].clone(), f.to_bytes(l, t)))
        .collect())
}

fn phase5(dir: &Path, m: &Manifest, l: &TileLayout, t: usize) -> Result<Vec<(String, Vec<u8>)>> {
    let routed = Routed::from_bytes(&read_product(dir, m, 3, t, 0, t)?, l, t)?;
    let inflow = Inflow::from_bytes(&read_product(dir, m, 4, 0, t, t)?, l, t)?;
    let f = tiled::phase5(l, t, &routed, &inflow)?;
    drop((routed, inflow));
    let [x, y, w, h] = l.window(t);
    let a0 = l.cell_x * l.cell_y;
    let georef = m
        .output
        .georef
        .as_ref()
        .map(|g| g.window(x as f64, y as f64, 1.0, 1.0));
    // The same values `relief flow` writes (relief-landscape's `FlowSettings::run`).
    let dir_codes: Vec<f32> = (0..w * h)
        .map(|i| {
            if f.filled[i].is_nan() {
                f32::NAN
            } else if f.dir[i] == NO_FLOW {
                0.0
            } else {
                ESRI_CODES[f.dir[i] as usize] as f32
            }
        })
        .collect();
    let area: Vec<f32> = (0..w * h)
        .map(|i| {
            if f.filled[i].is_nan() {
                f32::NAN
            } else {
                (f.cells[i] as f64 * a0) as f32
            }
        })
        .collect();
    let names = outputs_of(5, t, m.tasks);
    let mut out = Vec::with_capacity(3);
    for (name, data) in names.into_iter().zip([f.filled, dir_codes, area]) {
        let hf = Heightfield::new(w, h, data, l.cell_x, l.cell_y)?.with_georef(georef.clone());
        out.push((name, deflate_geotiff(&hf)?));
    }
    Ok(out)
}

/// `relief tile status` on a flow plan: each phase's progress and the phase to run next.
pub(super) fn status(dir: &Path, m: &Manifest, ctx: &Ctx) -> Result<()> {
    check_folders(dir)?;
    let states = phase_states(dir, m);
    let mut text = String::new();
    let mut next = None;
    for (p, (missing, corrupt)) in states.iter().enumerate() {
        let phase = p + 1;
        let n = tasks_of(phase, m);
        let done = n - missing.len() - corrupt.len();
        let kind = if tiled::is_single(phase) {
            "one task"
        } else {
            "one task per tile"
        };
        text.push_str(&format!(
            "phase {phase} ({kind}): {done}/{n} done, {} missing, {} corrupt\n",
            missing.len(),
            corrupt.len()
        ));
        if !missing.is_empty() {
            text.push_str(&format!("  missing: {}\n", ranges(missing)));
        }
        if !corrupt.is_empty() {
            text.push_str(&format!("  corrupt: {}\n", ranges(corrupt)));
        }
        if done < n && next.is_none() {
            let mut all = [missing.clone(), corrupt.clone()].concat();
            all.sort_unstable();
            next = Some((phase, all));
        }
    }
    match &next {
        Some((p, all)) => text.push_str(&format!(
            "next: phase {p}, tasks {} (relief tile run {} --phase {p}{})\n",
            ranges(all),
            dir.display(),
            if tiled::is_single(*p) {
                ""
            } else {
                " --index I"
            }
        )),
        None => text.push_str("next: relief tile mosaic (every phase is done)\n"),
    }
    crate::staging::print(&text)?;
    if let Some((p, all)) = next {
        bail!(
            "the plan is incomplete: phase {p} is next (tasks {})",
            ranges(&all)
        );
    }
    ctx.note("every phase is done: relief tile mosaic can assemble the tiles");
    Ok(())
}

/// `relief tile mosaic` on a flow plan: `OUT_DIR/{filled,direction,area}.tif` together.
pub(super) fn mosaic(dir: &Path, m: &Manifest, a: &MosaicArgs, ctx: &Ctx) -> Result<()> {
    layout(m)?;
    check_folders(dir)?;
    let bad: Vec<usize> = (0..m.tasks)
        .filter(|&i| task_state(dir, m, PHASES, i) != TileState::Done)
        .collect();
    if !bad.is_empty() {
        bail!(
            "{} of {} tiles of the last phase are missing or corrupt ({}): run them (relief tile \
             status {})",
            bad.len(),
            m.tasks,
            ranges(&bad),
            dir.display()
        );
    }
    for p in PRODUCTS {
        let vrt = dir.join(format!("mosaic-{p}.vrt"));
        write_vrt_named(&vrt, m, &|i| product_name(p, i))?;
    }
    if a.vrt_only {
        ctx.note(format!(
            "wrote {}/mosaic-{{{}}}.vrt",
            dir.display(),
            PRODUCTS.join(",")
        ));
        return Ok(());
    }
    let out = mosaic_output(dir, m, a.out.as_deref())?;
    let inputs: Vec<PathBuf> = m.inputs.iter().map(|s| PathBuf::from(&s.path)).collect();
    let in_refs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let files = out_files();
    let names: Vec<(&str, OutKind)> = files.iter().map(|(n, k)| (n.as_str(), *k)).collect();
    let staged = crate::folder::FolderOutputs::new(&out, &names, &in_refs, ctx)?;
    for p in PRODUCTS {
        let target = staged.path(&format!("{p}.tif"));
        super::mosaic::stream_tiles(dir, m, &|i| product_name(p, i), &target, a.bigtiff, ctx)?;
    }
    staged.commit()?;
    ctx.note(format!(
        "wrote {}/{{{}}}.tif ({} x {}{})",
        out.display(),
        PRODUCTS.join(","),
        m.output.width,
        m.output.height,
        if ctx.cog { ", cloud-optimized" } else { "" },
    ));
    Ok(())
}
