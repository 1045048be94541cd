//! The files of `relief export`: the heightmaps (whole or tiles, in the engine's row order),
//! the masks packed as the engine's layers, and the import sheet.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use relief_heightfield::{Heightfield, Progress};
use relief_landscape::masks::{MasksSettings, splat_rgba8};
use serde::Serialize;

use super::Grids;
use super::engine::{self, Engine, HeightFormat, Layout, Setting, Vertical};
use crate::ctx::Ctx;
use crate::folder::FolderOutputs;
use crate::outputs::OutKind;

/// The splat map's layers, in channel order (R, G, B, A), as `relief masks` packs them.
pub(crate) const LAYERS: [&str; 4] = ["ground", "rock", "sediment", "wet"];

/// What one export writes.
#[derive(Debug)]
pub(crate) struct Plan {
    pub(crate) engine: Engine,
    pub(crate) format: HeightFormat,
    pub(crate) stem: String,
    pub(crate) layout: Layout,
    pub(crate) masks: bool,
}

/// One heightmap (or mask) file and where it sits.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Placed {
    pub(crate) file: String,
    /// Tile index (x, y), y counted from the north edge; (0, 0) for a whole heightmap.
    pub(crate) tile: (usize, usize),
    /// First sample (x, y) in the whole grid, from the north-west corner.
    pub(crate) first_sample: (usize, usize),
    /// Its north-west corner from the grid's north-west corner (m, x east, y south).
    pub(crate) origin_m: (f64, f64),
    /// Where the engine puts a tile placed by hand: Unreal's actor Location X, Y (cm, its
    /// north-west corner), Unity's terrain Position X, Z (m, its south-west corner, Z north).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) position: Option<String>,
}

/// The masks written.
#[derive(Debug, Serialize)]
pub(crate) struct MaskFiles {
    /// How they are packed.
    pub(crate) packing: &'static str,
    /// The layers, in channel order for an RGBA splat map.
    pub(crate) layers: [&'static str; 4],
    /// Samples of one mask file (x, y).
    pub(crate) size: (usize, usize),
    pub(crate) files: Vec<Placed>,
}

/// The import sheet (`NAME.json`; `NAME.txt` says the same for people).
#[derive(Debug, Serialize)]
pub(crate) struct Sheet {
    pub(crate) engine: Engine,
    pub(crate) input: String,
    pub(crate) input_cells: (usize, usize),
    pub(crate) input_cell_size_m: (f64, f64),
    /// Samples of the whole grid.
    pub(crate) samples: (usize, usize),
    /// Tiles (x, y) and their side, when tiled.
    pub(crate) tiles: Option<((usize, usize), usize)>,
    /// Distance between samples (m, x and y).
    pub(crate) spacing_m: (f64, f64),
    /// The grid's extent (m): the DEM's.
    pub(crate) extent_m: (f64, f64),
    pub(crate) format: &'static str,
    pub(crate) rows: &'static str,
    pub(crate) vertical: Vertical,
    pub(crate) decode: String,
    pub(crate) settings: Vec<Setting>,
    pub(crate) heightmaps: Vec<Placed>,
    pub(crate) masks: Option<MaskFiles>,
    /// How to bring the files in, when it needs saying.
    pub(crate) notes: Vec<&'static str>,
}

impl Plan {
    /// The tiles (x, y) in file order and the side of one heightmap (the whole grid's when
    /// not tiled).
    fn tiles(&self) -> (Vec<(usize, usize)>, (usize, usize)) {
        match self.layout.tiles {
            Some(((nx, ny), t)) => (
                (0..ny).flat_map(|y| (0..nx).map(move |x| (x, y))).collect(),
                (t, t),
            ),
            None => (vec![(0, 0)], self.layout.samples),
        }
    }

    /// The stem of tile `t` of the files named `base`.
    fn tile_stem(&self, base: &str, t: (usize, usize)) -> String {
        match self.layout.tiles {
            Some(((_, ny), _)) => self.engine.tile_name(base, t, ny),
            None => base.to_string(),
        }
    }

    /// The mask files' stems and how they are packed: per layer (unreal, gaea) or one RGBA
    /// splat map (unity, godot).
    fn mask_bases(&self) -> Vec<String> {
        if !self.masks {
            return Vec::new();
        }
        match self.engine {
            Engine::Unreal | Engine::Gaea => LAYERS
                .iter()
                .map(|l| format!("{}_{l}", self.stem))
                .collect(),
            Engine::Unity | Engine::Godot => vec![format!("{}_splat", self.stem)],
        }
    }

    /// Every file written, with what it is (for the output checks).
    pub(crate) fn files(&self) -> Vec<(String, OutKind)> {
        let (tiles, _) = self.tiles();
        let ext = self.engine.extension(self.format);
        let kind = match self.format {
            HeightFormat::Png => OutKind::Png,
            HeightFormat::R16 => OutKind::Raw16,
        };
        let mut v: Vec<(String, OutKind)> = tiles
            .iter()
            .map(|&t| (format!("{}.{ext}", self.tile_stem(&self.stem, t)), kind))
            .collect();
        for base in self.mask_bases() {
            for &t in &tiles {
                v.push((format!("{}.png", self.tile_stem(&base, t)), OutKind::Png));
            }
        }
        v.push((format!("{}.json", self.stem), OutKind::Json));
        v.push((format!("{}.txt", self.stem), OutKind::Text));
        v
    }

    /// Writes the heightmaps and masks into `staged`; returns the sheet.
    pub(crate) fn write(
        &self,
        staged: &FolderOutputs,
        grids: &Grids,
        v: Vertical,
        input: &Heightfield,
        input_path: &Path,
        ctx: &Ctx,
        progress: &dyn Progress,
    ) -> Result<Sheet> {
        let (tiles, side) = self.tiles();
        let c = &grids.corners;
        let (cx, cy) = input.cell_size();
        let extent = (input.width() as f64 * cx, input.height() as f64 * cy);
        let (sx, sy) = self.layout.samples;
        let spacing = (extent.0 / (sx - 1) as f64, extent.1 / (sy - 1) as f64);
        let ext = self.engine.extension(self.format);
        progress.begin("writing", tiles.len() as u64);
        let mut heightmaps = Vec::new();
        for &t in &tiles {
            stop_at_deadline(ctx)?;
            let first = ((side.0 - 1) * t.0, (side.1 - 1) * t.1);
            let tile = c.crop(first.0, first.1, side.0, side.1)?;
            let name = format!("{}.{ext}", self.tile_stem(&self.stem, t));
            let bytes = encode(&tile, self.engine, self.format, v)?;
            relief_io::write_bytes_atomic(&staged.path(&name), &bytes)
                .with_context(|| format!("cannot write {}", staged.target(&name).display()))?;
            let mut p = placed(name, t, first, spacing);
            if self.layout.tiles.is_some() {
                p.position = self.position(&p, side, spacing);
            }
            heightmaps.push(p);
            progress.advance(1);
        }
        let masks = if self.masks {
            Some(self.write_masks(staged, grids, &tiles, side, spacing, ctx, progress)?)
        } else {
            None
        };
        Ok(Sheet {
            engine: self.engine,
            input: input_path.display().to_string(),
            input_cells: (input.width(), input.height()),
            input_cell_size_m: (cx, cy),
            samples: self.layout.samples,
            tiles: self.layout.tiles,
            spacing_m: spacing,
            extent_m: extent,
            format: match self.format {
                HeightFormat::Png => "16-bit greyscale PNG",
                HeightFormat::R16 => "16-bit little-endian raw, no header",
            },
            rows: if self.engine.south_first() {
                "south edge first (raw row 0 is the terrain's z = 0 edge)"
            } else {
                "north edge first"
            },
            vertical: v,
            decode: format!(
                "metres = {:.6} + count x {:.9} (count 0..65535)",
                v.lo, v.step
            ),
            settings: engine::settings(self.engine, v, spacing, self.layout.samples, side),
            heightmaps,
            masks,
            notes: self.notes(),
        })
    }

    /// What the sheet adds for tiles.
    fn notes(&self) -> Vec<&'static str> {
        if self.layout.tiles.is_none() {
            return Vec::new();
        }
        match self.engine {
            Engine::Unreal => vec![
                "Each tile is a landscape of its own, sharing its edge samples with its \
                 neighbours: create one Landscape per tile with the settings above at the \
                 tile's Location X, Y. UE5's World Partition import of an _x_y file set \
                 places the files side by side without overlap (LandscapeImportHelper: start \
                 = tile index x file width), which would repeat the shared samples: for that \
                 import, export one heightmap (--size, up to 8129) instead.",
            ],
            Engine::Unity => vec![
                "One Terrain per tile (Terrain Tools' Toolbox batch import reads the _X_Z \
                 names, or Import Raw per terrain at the tile's Position X, Z); neighbours \
                 share their edge samples, as Unity's neighbouring terrains do.",
            ],
            Engine::Godot | Engine::Gaea => Vec::new(),
        }
    }

    /// The engine position of tile `p` of `side` samples (see [`Placed::position`]).
    fn position(&self, p: &Placed, side: (usize, usize), spacing: (f64, f64)) -> Option<String> {
        let (ox, oy) = p.origin_m;
        match self.engine {
            Engine::Unreal => Some(format!(
                "Location X, Y (cm): {:.3}, {:.3}",
                ox * 100.0,
                oy * 100.0
            )),
            Engine::Unity => {
                let south = (self.layout.samples.1 - 1) as f64 * spacing.1;
                let z = south - oy - (side.1 - 1) as f64 * spacing.1;
                Some(format!("Position X, Z (m): {ox:.4}, {:.4}", z.max(0.0)))
            }
            Engine::Godot | Engine::Gaea => None,
        }
    }

    /// Computes the masks on the export's grid and writes them packed for the engine.
    fn write_masks(
        &self,
        staged: &FolderOutputs,
        grids: &Grids,
        tiles: &[(usize, usize)],
        side: (usize, usize),
        spacing: (f64, f64),
        ctx: &Ctx,
        progress: &dyn Progress,
    ) -> Result<MaskFiles> {
        // Unity's alphamaps cover the terrain's cells (2^n per side); the other engines take
        // maps on the heightmap's samples.
        let (grid, tile) = if self.engine == Engine::Unity {
            (&grids.cells, (side.0 - 1, side.1 - 1))
        } else {
            (&grids.corners, side)
        };
        let settings = MasksSettings::default();
        if let Some((est, how)) =
            crate::budget::crop_pilot_seconds((grid.width(), grid.height()), |x, y, w, h| {
                settings
                    .run(
                        &grid.crop(x, y, w, h)?,
                        None,
                        None,
                        &relief_heightfield::NoProgress,
                    )
                    .map(drop)
                    .map_err(Into::into)
            })?
        {
            ctx.check_time("the masks", est, &how, "a smaller --size, or no --masks")?;
        }
        let masks = settings
            .run(grid, None, None, progress)
            .context("cannot compute the masks")?;
        let rgba = splat_rgba8(&masks.splat);
        let gw = grid.width();
        let mut files = Vec::new();
        for &t in tiles {
            stop_at_deadline(ctx)?;
            // Tiles of samples share their edge; Unity's cell tiles do not overlap.
            let step = (side.0 - 1, side.1 - 1);
            let first = (step.0 * t.0, step.1 * t.1);
            let block = crop_bytes(&rgba, gw, 4, first, tile);
            for (base, channel) in self.mask_bases().iter().zip(0..) {
                let name = format!("{}.png", self.tile_stem(base, t));
                let path = staged.path(&name);
                let written = if self.engine == Engine::Unity || self.engine == Engine::Godot {
                    relief_io::write_rgba_png(&path, tile.0, tile.1, &block)
                } else {
                    let grey: Vec<u8> = block.chunks(4).map(|p| p[channel]).collect();
                    relief_io::write_gray_png(&path, tile.0, tile.1, &grey)
                };
                written
                    .with_context(|| format!("cannot write {}", staged.target(&name).display()))?;
                files.push(placed(name, t, first, spacing));
            }
        }
        Ok(MaskFiles {
            packing: match self.engine {
                Engine::Unreal | Engine::Gaea => "one 8-bit greyscale weight map per layer",
                Engine::Unity => "RGBA 8-bit alphamap (splat) per terrain, 2^n cells",
                Engine::Godot => "RGBA 8-bit splat map on the heightmap's samples",
            },
            layers: LAYERS,
            size: tile,
            files,
        })
    }
}

fn placed(
    file: String,
    tile: (usize, usize),
    first: (usize, usize),
    spacing: (f64, f64),
) -> Placed {
    Placed {
        file,
        tile,
        first_sample: first,
        origin_m: (first.0 as f64 * spacing.0, first.1 as f64 * spacing.1),
        position: None,
    }
}

/// Ends the run with the CLI's stop once `--max-time` has passed.
fn stop_at_deadline(ctx: &Ctx) -> Result<()> {
    if ctx
        .deadline()
        .is_some_and(|d| std::time::Instant::now() >= d)
    {
        return Err(crate::budget::Stopped("relief export".into()).into());
    }
    Ok(())
}

/// The `w x h` block at `(x, y)` of a row-major image `src` of width `width` and `ch` bytes
/// per pixel.
fn crop_bytes(
    src: &[u8],
    width: usize,
    ch: usize,
    (x, y): (usize, usize),
    (w, h): (usize, usize),
) -> Vec<u8> {
    let mut out = Vec::with_capacity(w * h * ch);
    for row in y..y + h {
        let start = (row * width + x) * ch;
        out.extend_from_slice(&src[start..start + w * ch]);
    }
    out
}

/// The heightmap bytes of `hf` for `engine` (rows flipped for Unity's raw).
fn encode(hf: &Heightfield, engine: Engine, format: HeightFormat, v: Vertical) -> Result<Vec<u8>> {
    let flipped;
    let hf = if engine.south_first() {
        let (w, h) = (hf.width(), hf.height());
        let s = hf.as_slice();
        let data: Vec<f32> = (0..h)
            .rev()
            .flat_map(|y| s[y * w..(y + 1) * w].iter().copied())
            .collect();
        flipped = hf.with_data(data)?;
        &flipped
    } else {
        hf
    };
    let opts = relief_io::WriteOptions {
        mapping: Some((v.lo, v.step)),
        ..Default::default()
    };
    let f = match format {
        HeightFormat::Png => relief_io::Format::Png,
        HeightFormat::R16 => relief_io::Format::R16,
    };
    relief_io::encode(hf, f, &opts).context("cannot encode the heightmap")
}

/// The sheet as text: what to import and with which settings.
pub(crate) fn sheet_text(s: &Sheet) -> String {
    let mut t = String::new();
    let _ = writeln!(t, "engine:     {}", s.engine.title());
    let _ = writeln!(
        t,
        "input:      {} ({} x {} cells of {:.3} x {:.3} m)",
        s.input, s.input_cells.0, s.input_cells.1, s.input_cell_size_m.0, s.input_cell_size_m.1
    );
    let _ = writeln!(
        t,
        "heightmap:  {} x {} samples, {:.4} x {:.4} m apart, extent {:.2} x {:.2} m",
        s.samples.0, s.samples.1, s.spacing_m.0, s.spacing_m.1, s.extent_m.0, s.extent_m.1
    );
    if let Some(((nx, ny), side)) = s.tiles {
        let _ = writeln!(
            t,
            "tiles:      {nx} x {ny} of {side} x {side}, sharing edge samples"
        );
    }
    let _ = writeln!(t, "format:     {}, rows {}", s.format, s.rows);
    let _ = writeln!(
        t,
        "heights:    {:.3} .. {:.3} m ({})",
        s.vertical.lo, s.vertical.hi, s.decode
    );
    let files: Vec<&str> = s.heightmaps.iter().map(|p| p.file.as_str()).collect();
    let _ = writeln!(t, "import:     {}", list(&files));
    let _ = writeln!(t, "settings:");
    for set in &s.settings {
        let _ = writeln!(t, "  {}: {}", set.name, set.value);
    }
    for n in &s.notes {
        let _ = writeln!(t, "note:       {n}");
    }
    if let Some(m) = &s.masks {
        let files: Vec<&str> = m.files.iter().map(|p| p.file.as_str()).collect();
        let _ = writeln!(
            t,
            "masks:      {} ({}), {} x {}: {}",
            m.packing,
            m.layers.join(", "),
            m.size.0,
            m.size.1,
            list(&files)
        );
    }
    t
}

/// A file list, shortened past 8 names.
fn list(files: &[&str]) -> String {
    if files.len() <= 8 {
        files.join(", ")
    } else {
        format!(
            "{}, ... {} ({} files)",
            files[..4].join(", "),
            files[files.len() - 1],
            files.len()
        )
    }
}
