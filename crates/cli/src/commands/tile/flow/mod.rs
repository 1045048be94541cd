//! `relief tile plan DIR -- flow DEM -o OUT_DIR`: drainage as a multi-phase plan
//! (relief-landscape's `flow::tiled`: Barnes 2016 filling and Barnes 2017 accumulation, then
//! the products that follow the D8 tree carried across tile edges the same way), seven phases,
//! each a task array or one task, that a scheduler chains with dependencies
//! (`sbatch --dependency=afterok:<previous>`):
//!
//! | phase | tasks | reads | writes |
//! |---|---|---|---|
//! | 1 | one per tile | `input/tile-N.tif` (the tile and a one-cell margin) | `phase1/fill-N.bin`, `phase1/graph-N.bin` |
//! | 2 | one | every `phase1/graph-N.bin` | `phase2/levels-N.bin` |
//! | 3 | one per tile | `phase1/fill-N.bin`, the levels of the tile and its neighbours | `phase3/routed-N.bin`, `phase3/ports-N.bin` |
//! | 4 | one | every `phase3/ports-N.bin` | `phase4/inflow-N.bin` |
//! | 5 | one per tile | `phase3/routed-N.bin`, `phase4/inflow-N.bin` | `tiles/{filled,direction,area}-N.tif`, `phase5/summary-N.bin` |
//! | 6 | one | every `phase5/summary-N.bin` | `phase6/net-N.bin` |
//! | 7 | one per tile | `input/tile-N.tif`, `phase3/routed-N.bin`, `phase4/inflow-N.bin`, `phase6/net-N.bin` | `tiles/{strahler,watersheds,hand}-N.tif`, `tiles/network-N.bin` |
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
//! `relief tile mosaic` writes `OUT_DIR/{filled,direction,area,strahler,watersheds,hand}.tif`,
//! `channels.geojson` (joined from every tile's channel cells) and `flow.json` (the figures
//! summed over the tiles), together or not at all, equal byte for byte to those of
//! `relief flow` (`flow.json` names the input as the plan's command line named it, as
//! `relief flow` does). `channels.png`, a preview drawn over the whole map's hillshade, is not
//! planned (the plan says so). The rasters of phases 5 and 7 are tiled GeoTIFFs in the
//! mosaic's block side and codec, so that the mosaic of a plan whose tile is a multiple of
//! that block copies their encoded blocks instead of decoding and encoding them again.

use relief_landscape::flow::job::FlowSettings;
use relief_landscape::flow::tiled::{
    self, FillGraph, Inflow, Levels, LocalFill, PHASES, PortGraph, Routed, TileLayout,
};
use relief_landscape::flow::{Depressions, Directions};
use serde::{Deserialize, Serialize};

use super::mosaic::ranges;
use super::*;
use crate::outputs::OutKind;

/// The rasters a flow plan mosaics into its output folder (phase 5's, then phase 7's).
pub(super) const PRODUCTS: [&str; 6] = [
    "filled",
    "direction",
    "area",
    "strahler",
    "watersheds",
    "hand",
];

/// The files of `relief flow` a plan does not write, and why (the plan's note says so).
pub(super) const NOT_PLANNED: &str = "channels.png (a preview drawn over the whole map's \
     hillshade; draw it from the mosaic with relief flow on a reduced DEM or relief preview)";

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
    Masks(crate::commands::masks::Args),
}

/// What the manifest's `job` holds for a flow plan.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct FlowJob {
    /// The job's settings (relief-landscape's `FlowSettings`).
    flow: FlowSettings,
    /// The input as the plan's command line named it (`flow.json`'s `file`, as `relief flow`
    /// writes it); plans made before it was kept give the absolute path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    file: Option<String>,
}

impl FlowJob {
    /// The job of settings `flow` on the input `file` as the command line named it.
    fn new(flow: FlowSettings, file: &Path) -> Self {
        FlowJob {
            flow,
            file: Some(file.display().to_string()),
        }
    }
}

fn out_files() -> Vec<(String, OutKind)> {
    let mut v: Vec<(String, OutKind)> = PRODUCTS
        .iter()
        .map(|p| (format!("{p}.tif"), OutKind::Raster))
        .collect();
    v.push(("channels.geojson".into(), OutKind::Json));
    v.push(("flow.json".into(), OutKind::Json));
    v
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

/// Phases of a masks plan: the drainage's seven, then the masks per tile.
pub(super) const MASK_PHASES: usize = PHASES + 1;

/// Whether `m` plans masks (its last phase writes them).
fn is_masks(m: &Manifest) -> bool {
    m.command == "masks"
}

/// Whether phase `p` of a plan is one task (the others are one task per tile).
fn single(p: usize) -> bool {
    p <= PHASES && tiled::is_single(p)
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
    let phases = if is_masks(m) { MASK_PHASES } else { PHASES };
    if l.tasks() != m.tasks || m.phases != phases {
        bail!("the manifest's tile grid or phases do not match a flow plan");
    }
    Ok(l)
}

mod masks;
mod phases;
mod plan;

pub(super) use phases::run_task;
pub(super) use plan::plan;

const INPUT_INDEX: &str = "input/index.json";

/// The plan's folders: every file a task reads or writes is in one of them (and `masks` for
/// a masks plan).
const FOLDERS: [&str; 8] = [
    "input", "phase1", "phase2", "phase3", "phase4", "phase5", "phase6", "tiles",
];

/// The folders of plan `m`.
fn folders(masks: bool) -> Vec<&'static str> {
    let mut v = FOLDERS.to_vec();
    if masks {
        v.push("masks");
    }
    v
}

/// Every folder of the plan must be a real folder inside it.
fn check_folders(dir: &Path, m: &Manifest) -> Result<()> {
    folders(is_masks(m))
        .iter()
        .try_for_each(|f| check_plan_folder(dir, f))
}

fn input_name(t: usize) -> String {
    format!("input/tile-{t:06}.tif")
}

/// The files task `index` of `phase` of plan `m` writes, by name (relative to the plan
/// folder). A masks plan's phases 5 and 7 write only what phases 6 and 8 read (the summary;
/// HAND as raw little-endian f32), not the drainage's rasters and network.
fn outputs_of(m: &Manifest, phase: usize, index: usize) -> Vec<String> {
    let tasks = m.tasks;
    if is_masks(m) && phase == 5 {
        return vec![format!("phase5/summary-{index:06}.bin")];
    }
    if is_masks(m) && phase == PHASES {
        return vec![format!("tiles/hand-{index:06}.bin")];
    }
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
        5 => {
            let mut v: Vec<String> = PRODUCTS[..3]
                .iter()
                .map(|p| product_name(p, index))
                .collect();
            v.push(format!("phase5/summary-{index:06}.bin"));
            v
        }
        6 => (0..tasks)
            .map(|t| format!("phase6/net-{t:06}.bin"))
            .collect(),
        MASK_PHASES => masks::outputs(index),
        _ => {
            let mut v: Vec<String> = PRODUCTS[3..]
                .iter()
                .map(|p| product_name(p, index))
                .collect();
            v.push(format!("tiles/network-{index:06}.bin"));
            v
        }
    }
}

/// `tiles/<product>-N.tif`.
pub(super) fn product_name(product: &str, t: usize) -> String {
    format!("tiles/{product}-{t:06}.tif")
}

fn record_name(phase: usize, index: usize) -> String {
    let folder = if phase == PHASES {
        "tiles".to_string()
    } else if phase == MASK_PHASES {
        "masks".to_string()
    } else {
        format!("phase{phase}")
    };
    format!("{folder}/task-{index:06}.json")
}

fn tasks_of(phase: usize, m: &Manifest) -> usize {
    if single(phase) { 1 } else { m.tasks }
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
    let names = outputs_of(m, phase, index);
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
    let Some(f) = r.files.get(k) else {
        bail!("phase {phase} task {index} recorded no file {k}");
    };
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
    (1..=m.phases)
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

/// `relief tile status` on a flow plan: each phase's progress and the phase to run next.
pub(super) fn status(dir: &Path, m: &Manifest, ctx: &Ctx) -> Result<()> {
    check_folders(dir, m)?;
    let states = phase_states(dir, m);
    let mut text = String::new();
    let mut next = None;
    for (p, (missing, corrupt)) in states.iter().enumerate() {
        let phase = p + 1;
        let n = tasks_of(phase, m);
        let done = n - missing.len() - corrupt.len();
        let kind = if single(phase) {
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
            if single(*p) { "" } else { " --index I" }
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

/// `relief tile mosaic` on a flow plan: `OUT_DIR/{filled,direction,area,strahler,watersheds,
/// hand}.tif`, `channels.geojson` and `flow.json` together.
pub(super) fn mosaic(dir: &Path, m: &Manifest, a: &MosaicArgs, ctx: &Ctx) -> Result<()> {
    let layout = layout(m)?;
    check_folders(dir, m)?;
    if is_masks(m) {
        return masks::mosaic(dir, m, &layout, a, ctx);
    }
    for phase in [5, PHASES] {
        let bad: Vec<usize> = (0..m.tasks)
            .filter(|&i| task_state(dir, m, phase, i) != TileState::Done)
            .collect();
        if !bad.is_empty() {
            bail!(
                "{} of {} tiles of phase {phase} are missing or corrupt ({}): run them (relief \
                 tile status {})",
                bad.len(),
                m.tasks,
                ranges(&bad),
                dir.display()
            );
        }
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
    // The network: every tile's channel cells, joined into reaches as the single run's.
    let nets = (0..m.tasks)
        .into_par_iter()
        .map(|t| {
            let b = read_product(dir, m, PHASES, t, 3, t)?;
            Ok(tiled::TileNetwork::from_bytes(&b, &layout, t)?)
        })
        .collect::<Result<Vec<_>>>()?;
    let georef = m.output.georef.as_ref();
    let (channels, figures) = tiled::assemble(&layout, georef, &nets)?;
    drop(nets);
    staged.write_json("channels.geojson", &channels, false)?;
    let job: FlowJob = serde_json::from_value(m.job.clone())
        .context("the manifest's job is not a flow job's settings")?;
    let report = crate::commands::flow::Report {
        input: crate::commands::InputGrid {
            file: job
                .file
                .clone()
                .or_else(|| m.inputs.first().map(|s| s.path.clone()))
                .unwrap_or_default(),
            width: m.output.width,
            height: m.output.height,
        },
        cell_size: (m.output.cell_size[0], m.output.cell_size[1]),
        crs: georef.and_then(|g| g.crs.clone()),
        settings: job.flow,
        figures,
        outputs: crate::commands::flow::FILES
            .iter()
            .map(|(n, _)| *n)
            .filter(|n| files.iter().any(|(f, _)| f == n))
            .collect(),
    };
    staged.write_json("flow.json", &report, true)?;
    staged.commit()?;
    ctx.note(format!(
        "wrote {}/{{{},channels.geojson,flow.json}} ({} x {}{}); not planned: {NOT_PLANNED}",
        out.display(),
        PRODUCTS
            .iter()
            .map(|p| format!("{p}.tif"))
            .collect::<Vec<_>>()
            .join(","),
        m.output.width,
        m.output.height,
        if ctx.cog { ", cloud-optimized" } else { "" },
    ));
    Ok(())
}
