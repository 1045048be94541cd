//! `relief tile plan DIR -- masks DEM -o OUT_DIR`: the masks of `relief masks` as a plan of
//! eight phases, the drainage's seven ([`super`]) and an eighth, one task per tile, that
//! writes the tile's masks (`masks/<mask>-N.tif`) and splat weights (`masks/splat-N.bin`,
//! RGBA bytes) from its input, its drainage (phases 3 and 4: the cells upstream; phase 7:
//! HAND, `tiles/hand-N.bin`) and the map's height bands and profile-curvature scale. Phases 5
//! and 7 of a masks plan write only what phases 6 and 8 read (not the drainage's rasters). Those two statistics of the
//! whole map are found exactly while planning, in two passes over the tiles' inputs
//! (relief-landscape's `masks::tiled`), and kept in the manifest's job.
//!
//! `relief tile mosaic` writes `OUT_DIR/{slope,profile_curvature,plan_curvature,area,wetness,
//! hand,height_band}.tif`, `splat.png` (assembled row by row) and `masks.json`: the masks equal
//! to those of `relief masks --format tif` value for value (bit for bit; the mosaic's GeoTIFFs
//! are tiled), `splat.png` and `masks.json` byte for byte.

use relief_landscape::masks::tiled::{self as mask_tiles, ScaleCounts, ScaleFine};
use relief_landscape::masks::{MaskScales, MasksSettings, splat_rgba8};

use super::*;
use crate::commands::masks::{BASE_KINDS, MaskFormat, file_name};

/// The options of `relief masks` a plan does not take, and why.
pub(super) const NOT_PLANNED: &str = "--format png8/png16 (their normalisation takes \
     percentiles of each whole mask: convert the mosaic's GeoTIFFs), --erosion-depth and \
     --deposition-depth (erode the whole DEM first)";

/// What the manifest's `job` holds for a masks plan.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MasksJob {
    /// The job's settings (relief-landscape's `MasksSettings`).
    pub(super) masks: MasksSettings,
    /// The map's height bands and profile-curvature scale, found while planning.
    pub(super) scales: MaskScales,
    /// The input as the plan's command line named it (`masks.json`'s `file`).
    file: String,
}

/// The job of a masks plan's manifest.
pub(super) fn job(m: &Manifest) -> Result<MasksJob> {
    let job: MasksJob = serde_json::from_value(m.job.clone())
        .context("the manifest's job is not a masks job's settings")?;
    job.masks.check().map_err(crate::args::flag_error)?;
    Ok(job)
}

/// The checked settings of a planned `relief masks`, or an error naming what cannot be
/// planned.
pub(super) fn plannable(a: &crate::commands::masks::Args) -> Result<MasksSettings> {
    if a.format != MaskFormat::Tif {
        bail!(
            "--format png8/png16 cannot be planned as tiles: their normalisation takes the 1st \
             and 99th percentiles of each whole mask; plan --format tif (the default) and \
             convert the mosaic's GeoTIFFs"
        );
    }
    if a.erosion_depth.is_some() || a.deposition_depth.is_some() {
        bail!(
            "--erosion-depth and --deposition-depth cannot be planned as tiles: erosion is \
             global; run relief erode and relief masks on the whole DEM"
        );
    }
    crate::commands::masks::settings(a)
}

/// The files of the mosaic's output folder.
pub(super) fn out_files(_s: &MasksSettings) -> Vec<(String, OutKind)> {
    let mut v: Vec<(String, OutKind)> = BASE_KINDS
        .iter()
        .map(|&k| (file_name(k, MaskFormat::Tif), OutKind::Raster))
        .collect();
    v.push(("splat.png".into(), OutKind::Png));
    v.push(("masks.json".into(), OutKind::Json));
    v
}

/// The masks' own flags in the manifest's `args` (after the drainage's).
pub(super) fn args(s: &MasksSettings) -> Vec<String> {
    let mut v = vec![
        "--format".to_string(),
        "tif".into(),
        "--rock-slope".into(),
        s.rock_slope.to_string(),
        "--wet-index".into(),
        s.wet_index.to_string(),
    ];
    if !s.height_bands.is_empty() {
        let b: Vec<String> = s.height_bands.iter().map(|b| b.to_string()).collect();
        v.extend(["--height-bands".into(), b.join(",")]);
    }
    v
}

/// The files task `index` of phase 8 writes.
pub(super) fn outputs(index: usize) -> Vec<String> {
    let mut v: Vec<String> = BASE_KINDS
        .iter()
        .map(|k| format!("masks/{}-{index:06}.tif", k.name()))
        .collect();
    v.push(format!("masks/splat-{index:06}.bin"));
    v
}

/// The second pass of the map's mask scales over the tiles' inputs just cut (the first,
/// `counts`, was made while cutting), and the plan's job.
pub(super) fn scales(
    dir: &Path,
    layout: &TileLayout,
    settings: &MasksSettings,
    counts: &ScaleCounts,
    file: &Path,
    ctx: &Ctx,
) -> Result<MasksJob> {
    let targets = counts
        .targets(settings)
        .context("cannot take the map's height bands")?;
    let progress = ctx.progress();
    progress.begin("the map's height bands and curvature scale", 0);
    let fine = std::sync::Mutex::new(ScaleFine::empty(&targets));
    (0..layout.tasks()).into_par_iter().try_for_each(|t| {
        let path = dir.join(input_name(t));
        let [_, _, w, h] = layout.window(t);
        let bytes = read_plan_file(
            dir,
            &input_name(t),
            (1 << 20) + (16 * (w + 2) * (h + 2)) as u64,
        )?;
        let hf = relief_io::read_bytes(&bytes, Some(Path::new("tile.tif")), &Default::default())
            .with_context(|| format!("cannot read {}", path.display()))?
            .heightfield;
        let f = ScaleFine::of_tile(layout, t, hf.as_slice(), &targets)?;
        fine.lock().unwrap_or_else(|e| e.into_inner()).merge(&f);
        Ok::<(), anyhow::Error>(())
    })?;
    let scales = fine
        .into_inner()
        .unwrap_or_else(|e| e.into_inner())
        .scales(&targets);
    Ok(MasksJob {
        masks: settings.clone(),
        scales,
        file: file.display().to_string(),
    })
}

/// Phase 8 of tile `t`: its masks and splat weights.
pub(super) fn phase8(
    dir: &Path,
    m: &Manifest,
    l: &TileLayout,
    t: usize,
) -> Result<phases::PhaseOutputs> {
    let job = job(m)?;
    let input = phases::read_input(dir, m, l, t)?;
    let f = phases::finished(dir, m, l, t)?;
    // Phase 7's HAND: the tile's, as `relief flow` (and `relief masks`) compute it.
    let hand_file = &outputs_of(m, PHASES, t)[0];
    let bytes = read_product(dir, m, PHASES, t, 0, t)?;
    let [_, _, w, h] = l.window(t);
    if bytes.len() != w * h * 4 {
        bail!(
            "{} holds {} bytes, not the {w} x {h} f32 cells of tile {t}",
            dir.join(hand_file).display(),
            bytes.len()
        );
    }
    let hand = relief_heightfield::bytes::f32_from_le_bytes(&bytes);
    let (masks, splat) = mask_tiles::tile_masks(
        &job.masks,
        l,
        t,
        input.as_slice(),
        &f.cells,
        hand,
        &job.scales,
    )?;
    let names = outputs(t);
    phases::write_rasters(
        dir,
        m,
        l,
        t,
        names
            .iter()
            .zip(masks.into_iter().map(|k| k.values))
            .collect(),
    )?;
    let n = BASE_KINDS.len();
    Ok(phases::in_place_then_bytes(
        &names[..n],
        &names[n],
        splat_rgba8(&splat),
    ))
}

/// `relief tile mosaic` on a masks plan: `OUT_DIR/{<mask>.tif, splat.png, masks.json}`
/// together.
pub(super) fn mosaic(
    dir: &Path,
    m: &Manifest,
    l: &TileLayout,
    a: &MosaicArgs,
    ctx: &Ctx,
) -> Result<()> {
    let bad: Vec<usize> = (0..m.tasks)
        .filter(|&i| task_state(dir, m, MASK_PHASES, i) != TileState::Done)
        .collect();
    if !bad.is_empty() {
        bail!(
            "{} of {} tiles of phase {MASK_PHASES} are missing or corrupt ({}): run them \
             (relief tile status {})",
            bad.len(),
            m.tasks,
            ranges(&bad),
            dir.display()
        );
    }
    let job = job(m)?;
    let tile_name = |k: usize| move |i: usize| outputs(i)[k].clone();
    for (k, kind) in BASE_KINDS.iter().enumerate() {
        let vrt = dir.join(format!("mosaic-{}.vrt", kind.name()));
        write_vrt_named(&vrt, m, &tile_name(k))?;
    }
    if a.vrt_only {
        ctx.note(format!(
            "wrote {}/mosaic-{{{}}}.vrt",
            dir.display(),
            BASE_KINDS.map(|k| k.name()).join(",")
        ));
        return Ok(());
    }
    let out = mosaic_output(dir, m, a.out.as_deref())?;
    let inputs: Vec<PathBuf> = m.inputs.iter().map(|s| PathBuf::from(&s.path)).collect();
    let in_refs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let files = out_files(&job.masks);
    let names: Vec<(&str, OutKind)> = files.iter().map(|(n, k)| (n.as_str(), *k)).collect();
    let staged = crate::folder::FolderOutputs::new(&out, &names, &in_refs, ctx)?;
    let mut written = Vec::new();
    for (k, kind) in BASE_KINDS.iter().enumerate() {
        let file = file_name(*kind, MaskFormat::Tif);
        let target = staged.path(&file);
        super::super::mosaic::stream_tiles(dir, m, &tile_name(k), &target, a.bigtiff, ctx)?;
        written.push((*kind, file));
    }
    write_splat(dir, m, l, &staged.path("splat.png"))?;
    let report = crate::commands::masks::Report {
        input: crate::commands::InputGrid {
            file: job.file.clone(),
            width: m.output.width,
            height: m.output.height,
        },
        settings: job.masks.clone(),
        bands: job.scales.bands.clone(),
        format: "tif",
        masks: written,
        splat: "splat.png",
        splat_channels: crate::commands::masks::SPLAT_CHANNELS,
    };
    staged.write_json("masks.json", &report, true)?;
    staged.commit()?;
    ctx.note(format!(
        "wrote {}/{{{},splat.png,masks.json}} ({} x {}); not planned: {NOT_PLANNED}",
        out.display(),
        files[..BASE_KINDS.len()]
            .iter()
            .map(|(f, _)| f.as_str())
            .collect::<Vec<_>>()
            .join(","),
        m.output.width,
        m.output.height,
    ));
    Ok(())
}

/// `splat.png` from every tile's splat weights, one row of tiles in memory at a time.
fn write_splat(dir: &Path, m: &Manifest, l: &TileLayout, path: &Path) -> Result<()> {
    let (width, k) = (m.output.width, BASE_KINDS.len());
    let mut png = relief_io::RgbaPngWriter::create(path, width, m.output.height)
        .with_context(|| format!("cannot write {}", path.display()))?;
    for ty in 0..l.tiles_y() {
        let row: Vec<usize> = (ty * l.tiles_x()..(ty + 1) * l.tiles_x()).collect();
        let tiles = row
            .par_iter()
            .map(|&t| {
                let b = read_product(dir, m, MASK_PHASES, t, k, t)?;
                let [_, _, w, h] = l.window(t);
                if b.len() != w * h * 4 {
                    bail!("{} is not {w} x {h} RGBA pixels", outputs(t)[k]);
                }
                Ok(b)
            })
            .collect::<Result<Vec<_>>>()?;
        let h = l.window(row[0])[3];
        let mut band = Vec::with_capacity(width * 4 * h);
        for r in 0..h {
            for (&t, b) in row.iter().zip(&tiles) {
                let w = l.window(t)[2];
                band.extend_from_slice(&b[r * w * 4..(r + 1) * w * 4]);
            }
        }
        png.write_rows(&band)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    png.finish()
        .with_context(|| format!("cannot write {}", path.display()))
}
