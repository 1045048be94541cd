//! `relief tile status` and `relief tile mosaic` (streamed GeoTIFF or COG, plus a GDAL VRT).

use super::*;

pub(super) fn status(a: StatusArgs, ctx: &Ctx) -> Result<()> {
    let (dir, m) = open_plan(&a.dir)?;
    if m.phases > 0 {
        return super::flow::status(&dir, &m, ctx);
    }
    check_plan_folder(&dir, "tiles")?;
    let (mut missing, mut corrupt) = (Vec::new(), Vec::new());
    for i in 0..m.tasks {
        match tile_state(&dir, &m, i) {
            TileState::Done => {}
            TileState::Missing => missing.push(i),
            TileState::Corrupt => corrupt.push(i),
        }
    }
    let done = m.tasks - missing.len() - corrupt.len();
    let mut text = format!(
        "{done}/{} tiles done, {} missing, {} corrupt\n",
        m.tasks,
        missing.len(),
        corrupt.len()
    );
    if !missing.is_empty() {
        text.push_str(&format!("missing: {}\n", ranges(&missing)));
    }
    if !corrupt.is_empty() {
        text.push_str(&format!("corrupt: {}\n", ranges(&corrupt)));
    }
    crate::staging::print(&text)?;
    if done < m.tasks {
        bail!(
            "the plan is incomplete: run tasks {} again",
            ranges(&{
                let mut all = [missing, corrupt].concat();
                all.sort_unstable();
                all
            })
        );
    }
    ctx.note("every tile is done: relief tile mosaic can assemble them");
    Ok(())
}

/// `0-3,7,9-10`: the indices as Slurm `--array` ranges.
pub(super) fn ranges(v: &[usize]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1] == v[j] + 1 {
            j += 1;
        }
        out.push(if i == j {
            v[i].to_string()
        } else {
            format!("{}-{}", v[i], v[j])
        });
        i = j + 1;
    }
    out.join(",")
}

pub(super) fn mosaic(a: MosaicArgs, ctx: &Ctx) -> Result<()> {
    let (dir, m) = open_plan(&a.dir)?;
    if m.phases > 0 {
        return super::flow::mosaic(&dir, &m, &a, ctx);
    }
    check_plan_folder(&dir, "tiles")?;
    let bad: Vec<usize> = (0..m.tasks)
        .filter(|&i| tile_state(&dir, &m, i) != TileState::Done)
        .collect();
    if !bad.is_empty() {
        bail!(
            "{} of {} tiles are missing or corrupt ({}): run them (relief tile status {})",
            bad.len(),
            m.tasks,
            ranges(&bad),
            dir.display()
        );
    }
    let out = if a.vrt_only {
        PathBuf::new()
    } else {
        mosaic_output(&dir, &m, a.out.as_deref())?
    };
    let inputs: Vec<PathBuf> = m.inputs.iter().map(|s| PathBuf::from(&s.path)).collect();
    let in_refs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let vrt = dir.join("mosaic.vrt");
    if !a.vrt_only {
        ctx.check_outputs(&in_refs, &[(&out, crate::outputs::OutKind::Raster)])?;
    }
    write_vrt(&vrt, &m)?;
    if a.vrt_only {
        ctx.note(format!("wrote {}", vrt.display()));
        return Ok(());
    }
    stream_tiles(
        &dir,
        &m,
        &|i| format!("tiles/{}", tile_name(i)),
        &out,
        a.bigtiff,
        ctx,
    )?;
    ctx.note(format!(
        "wrote {} ({} x {}{}) and {}",
        out.display(),
        m.output.width,
        m.output.height,
        if ctx.cog { ", cloud-optimized" } else { "" },
        vrt.display()
    ));
    Ok(())
}

/// A tile of a georeferenced plan must sit where the plan puts tile `i` (to a thousandth of a
/// cell): a tile file copied over another's, with its record rewritten to match, is refused.
fn check_origin(m: &Manifest, i: usize, rd: &relief_io::GeoTiffRowReader, p: &Path) -> Result<()> {
    let Some(g) = m
        .output
        .georef
        .as_ref()
        .filter(|g| g.geotransform.is_some())
    else {
        return Ok(());
    };
    let [x, y, _, _] = m.window(i);
    let Some(t) = g.window(x as f64, y as f64, 1.0, 1.0).geotransform else {
        return Ok(());
    };
    let tol = 1e-3 * (m.output.cell_size[0].abs() + m.output.cell_size[1].abs());
    // A rotated grid is written as a ModelTransformation, without a tiepoint to compare.
    let placed = match rd.origin() {
        Some((ox, oy)) => (ox - t[0]).abs() <= tol && (oy - t[3]).abs() <= tol,
        None => g.transformation.is_some(),
    };
    if !placed {
        bail!(
            "{} is not placed where tile {i} belongs ({:?} instead of ({}, {})): it was copied \
             from another tile or plan; run tile {i} again",
            p.display(),
            rd.origin(),
            t[0],
            t[3]
        );
    }
    Ok(())
}

/// Block side of a mosaic's GeoTIFF (GDAL's COG default), which tiles written for a mosaic
/// share so that their encoded blocks are copied as they are.
pub(super) const MOSAIC_BLOCK: usize = 512;

/// Opens tile `i`'s file `name(i)` for reading rows, checked to be the size of tile `i` and
/// placed where it belongs.
fn open_tile(
    dir: &Path,
    m: &Manifest,
    name: &dyn Fn(usize) -> String,
    i: usize,
) -> Result<relief_io::GeoTiffRowReader> {
    let p = dir.join(name(i));
    let rd = relief_io::GeoTiffRowReader::open(&p)
        .with_context(|| format!("cannot read {}", p.display()))?;
    let [_, _, w, h] = m.window(i);
    if (rd.width(), rd.height()) != (w, h) {
        bail!(
            "{} is {} x {}, not the {w} x {h} of tile {i}: run the tile again",
            p.display(),
            rd.width(),
            rd.height()
        );
    }
    check_origin(m, i, &rd, &p)?;
    Ok(rd)
}

/// Whether the mosaic can be the copy of the tiles' encoded blocks: not a COG (whose
/// overviews are made from the values), every tile's corner on the output's block grid, and
/// every tile a tiled GeoTIFF in the output's block side and codec (as a flow plan's phases
/// write their products). Else the tiles are decoded and encoded again.
fn blocks_fit(
    dir: &Path,
    m: &Manifest,
    name: &dyn Fn(usize) -> String,
    opts: &relief_io::TiledOptions,
) -> Result<bool> {
    if opts.cog {
        return Ok(false);
    }
    for i in 0..m.tasks {
        let [x, y, _, _] = m.window(i);
        if !x.is_multiple_of(opts.tile) || !y.is_multiple_of(opts.tile) {
            return Ok(false);
        }
        if open_blocks(dir, m, name, opts, i).is_err() {
            return Ok(false);
        }
    }
    Ok(true)
}

/// Tile `i`'s encoded blocks, checked as [`open_tile`] checks the tile and to be in the
/// output's block side and codec.
fn open_blocks(
    dir: &Path,
    m: &Manifest,
    name: &dyn Fn(usize) -> String,
    opts: &relief_io::TiledOptions,
    i: usize,
) -> Result<relief_io::EncodedBlocks> {
    open_tile(dir, m, name, i)?;
    let p = dir.join(name(i));
    let b = relief_io::EncodedBlocks::open(&p)
        .with_context(|| format!("cannot read {}", p.display()))?;
    if b.tile() != opts.tile || b.compression() != opts.compression {
        bail!(
            "{} is not in the mosaic's blocks and codec: run tile {i} again",
            p.display()
        );
    }
    Ok(b)
}

/// Writes the mosaic as the tiles' encoded blocks, one band of blocks at a time (bytes equal
/// to encoding the decoded tiles: relief-io's `EncodedBlocks`), one row of tiles open at a
/// time.
fn copy_blocks(
    dir: &Path,
    m: &Manifest,
    name: &dyn Fn(usize) -> String,
    opts: &relief_io::TiledOptions,
    writer: &mut relief_io::TiledGeoTiffWriter,
    progress: &dyn Progress,
) -> Result<()> {
    let mut blocks = Vec::new();
    for r in 0..m.tiles_y {
        let mut row = (r * m.tiles_x..(r + 1) * m.tiles_x)
            .map(|i| open_blocks(dir, m, name, opts, i))
            .collect::<Result<Vec<_>>>()?;
        let has_nan = row.iter().any(|b| b.has_nan());
        let h = row[0].height();
        for k in 0..h.div_ceil(opts.tile) {
            blocks.clear();
            for b in &mut row {
                b.read_block_row(k, &mut blocks)?;
            }
            let rows = opts.tile.min(h - k * opts.tile);
            writer.write_encoded_band(&blocks, rows, has_nan)?;
            progress.advance(rows as u64);
        }
    }
    Ok(())
}

/// Streams the tiles `name(i)` (relative to the plan folder) into the GeoTIFF (or COG) `out`,
/// one band of tiles in memory.
pub(super) fn stream_tiles(
    dir: &Path,
    m: &Manifest,
    name: &dyn Fn(usize) -> String,
    out: &Path,
    bigtiff: bool,
    ctx: &Ctx,
) -> Result<()> {
    let opts = relief_io::TiledOptions {
        tile: MOSAIC_BLOCK,
        compression: ctx.write_options().compression,
        cog: ctx.cog,
        bigtiff,
    };
    let cell = (m.output.cell_size[0], m.output.cell_size[1]);
    let mut writer = relief_io::TiledGeoTiffWriter::create(
        out,
        m.output.width,
        m.output.height,
        cell,
        m.output.georef.as_ref(),
        opts,
    )
    .with_context(|| format!("cannot write {}", out.display()))?;
    let progress = ctx.progress();
    progress.begin("mosaicking", m.output.height as u64);
    if blocks_fit(dir, m, name, &opts)? {
        copy_blocks(dir, m, name, &opts, &mut writer, &progress)?;
        writer
            .finish()
            .with_context(|| format!("cannot write {}", out.display()))?;
        drop(progress);
        return Ok(());
    }
    // Blocks of rows: every tile of a row of tiles decodes its part in parallel, then the
    // block goes to the writer (which compresses its tiles in parallel too).
    let width = m.output.width;
    let mut block: Vec<f32> = Vec::new();
    for r in 0..m.tiles_y {
        let mut readers = (0..m.tiles_x)
            .map(|c| open_tile(dir, m, name, r * m.tiles_x + c))
            .collect::<Result<Vec<_>>>()?;
        let [_, _, _, h] = m.window(r * m.tiles_x);
        let mut y = 0;
        while y < h {
            let rows = MOSAIC_ROWS.min(h - y);
            let parts = readers
                .par_iter_mut()
                .map(|rd| {
                    let mut part = Vec::with_capacity(rows * rd.width());
                    for _ in 0..rows {
                        rd.read_row(&mut part)?;
                    }
                    Ok(part)
                })
                .collect::<Result<Vec<Vec<f32>>>>()?;
            block.clear();
            block.reserve(rows * width);
            for k in 0..rows {
                for (part, rd) in parts.iter().zip(&readers) {
                    let w = rd.width();
                    block.extend_from_slice(&part[k * w..(k + 1) * w]);
                }
            }
            writer.write_rows(&block)?;
            progress.advance(rows as u64);
            y += rows;
        }
    }
    writer
        .finish()
        .with_context(|| format!("cannot write {}", out.display()))?;
    drop(progress);
    Ok(())
}
