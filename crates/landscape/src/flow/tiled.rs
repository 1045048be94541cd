//! Exact drainage of a DEM larger than one machine: depression filling, D8 directions and D8
//! drainage area computed tile by tile in five passes, equal bit for bit to [`super::route`]
//! with [`super::Depressions::Fill`] and [`super::Routing::cells_upstream`] (the single run of
//! `relief flow`), whatever the tile size and the order of the tasks.
//!
//! The passes follow Barnes (2016), "Parallel priority-flood depression filling for trillion
//! cell digital elevation models" (Computers & Geosciences 96), and Barnes (2017), "Parallel
//! non-divergent flow accumulation for trillion cell digital elevation models" (Computers &
//! Geosciences 104): a per-tile pass, one small global pass over what the tiles' perimeters
//! need, a per-tile pass. The filling's third pass is the accumulation's first, so the whole
//! drainage takes five passes, three of them one task per tile:
//!
//! 1. [`phase1`] (per tile, reads the tile and a one-cell halo of the DEM): a priority flood
//!    from the tile's perimeter and its outlets, each perimeter cell its own label (Barnes 2016
//!    section 3.1); writes the locally filled tile and labels ([`LocalFill`]) and the tile's
//!    perimeter band and the lowest spill between every two touching labels ([`FillGraph`]).
//! 2. [`phase2`] (one task, reads every [`FillGraph`]): the labels of all tiles joined by the
//!    spills inside tiles and across tile edges; a priority flood over this graph from the
//!    outlets gives every label the level it must be raised to (section 3.2) ([`Levels`]).
//! 3. [`phase3`] (per tile, reads its [`LocalFill`] and the [`Levels`] of its tile and its
//!    eight neighbours): the filled tile (`max(local, level of its label)`, section 3.3), the D8
//!    directions on a two-cell halo, the drainage of the flats that lie in this tile alone
//!    (Barnes, Lehman and Mulla 2014, as [`crate::depression::resolve_flats`]), and the local
//!    accumulation with the cells where flow leaves the tile or whose flat spans several tiles
//!    as ports (Barnes 2017 section 3.1) ([`Routed`], [`PortGraph`]).
//! 4. [`phase4`] (one task, reads every [`PortGraph`]): the flats that span tiles, drained
//!    exactly as the single run drains them, then the ports' graph in topological order: the
//!    cells that flow into each port (Barnes 2017 section 3.2) ([`Inflow`]).
//! 5. [`phase5`] (per tile): the final directions and the upstream cells of every cell, the
//!    inflows of phase 4 added downstream of where they enter the tile (section 3.3).
//!
//! Two more passes give what `relief flow` derives from the D8 tree and the area
//! ([`network`]): [`summarize`] (run with phase 5: where each perimeter cell's path goes in
//! the tile, the tile's ends of the flow, its channel cells whose Strahler order depends on
//! other tiles), 6. [`phase6`] (one task: watershed numbers by area, the paths chained tile to
//! tile, those channel cells' orders), 7. [`phase7`] (per tile: Strahler order, watersheds,
//! HAND, the channel cells and figures), and [`assemble`] (the channel network's GeoJSON and
//! the figures from every tile's channel cells).
//!
//! Why it is exact: the filled elevation of a cell is the lowest, over its paths to an outlet,
//! of the highest cell on the path (a minimax), whose value is one of the DEM's own values and
//! does not depend on any order; phases 1-3 compute it as Barnes (2016) proves. Directions
//! depend on a 3 x 3 neighbourhood of filled values, present in the two-cell halo. The drainage
//! of a flat depends on the whole flat: a flat held by one tile (and the halo) is drained in
//! that tile; one that crosses a tile edge (or whose first low edge lies across one) is sent
//! whole to phase 4, which runs the same breadth-first rings on it. Drainage area is counted
//! in cells (integers, so the sums do not depend on their order) and multiplied by the cell
//! area once, as the single run does.
//!
//! Memory: a per-tile pass holds a tile and its halo (about 40 bytes per cell); the global
//! passes hold the tiles' perimeter bands (about 20 bytes per perimeter cell) and, in phase 4,
//! the cells of the flats that cross tile edges (about 60 bytes each): a large lake crossing
//! many tiles is held whole there, the one part of the plan not bounded by the tile size.
//!
//! Every pass's product has a byte form (`to_bytes`, `from_bytes`) that checks its magic, its
//! tile, its sizes and its counts against the [`TileLayout`], for plan folders are read as
//! untrusted input.

use std::collections::HashMap;

use crate::elev::Elev;
use crate::grid::{D8, Grid, NO_FLOW};
use crate::radix::RadixHeap;
use crate::{LandscapeError, Result};

mod accum;
mod fill;
mod network;
mod route;

pub use accum::{Finished, Inflow, phase4, phase5};
pub use fill::{FillGraph, Levels, LocalFill, phase1, phase2};
use fill::{check_fill, check_graph};
pub use network::{
    Entry, Key, NetLevels, NetRasters, NetSummary, TileFigures, TileNetwork, assemble, phase6,
    phase7, summarize,
};
pub use route::{FlatCell, PortGraph, Routed, phase3};

/// A multiply-xorshift hasher for the integer keys of the passes' maps (cells, label pairs):
/// the standard SipHash spends more time than the flood itself on the label pairs of phase 1.
#[derive(Default, Clone, Copy)]
struct IntHasher(u64);

impl std::hash::Hasher for IntHasher {
    fn finish(&self) -> u64 {
        let h = self.0.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        h ^ (h >> 29)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
        }
    }
    fn write_u32(&mut self, v: u32) {
        self.0 = (self.0.rotate_left(32) ^ u64::from(v)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0 ^ v).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

type IntMap<K, V> = HashMap<K, V, std::hash::BuildHasherDefault<IntHasher>>;

/// Number of passes of a tiled drainage run (four per tile, three single tasks).
pub const PHASES: usize = 7;

/// True for the passes that run as one task (the others run one task per tile).
pub fn is_single(phase: usize) -> bool {
    phase == 2 || phase == 4 || phase == 6
}

/// Depth of the perimeter band a tile shares with its neighbours (the halo of phase 3).
const BAND: usize = 2;
/// No label (a void) or no port.
const NONE: u32 = u32::MAX;

fn bad(msg: impl Into<String>) -> LandscapeError {
    LandscapeError::InvalidInput(msg.into())
}

/// The tiles of a raster: `tile x tile` cells each, row-major from the north-west tile; the
/// last column and row of tiles are narrower when the size is not a multiple.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TileLayout {
    /// Columns of the raster.
    pub width: usize,
    /// Rows of the raster.
    pub height: usize,
    /// Tile side (cells).
    pub tile: usize,
    /// East-west cell size (m).
    pub cell_x: f64,
    /// North-south cell size (m).
    pub cell_y: f64,
}

impl TileLayout {
    /// Checks the sizes: a tile of 4 to 32768 cells, at most 2^40 cells in all.
    pub fn check(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(bad("the raster to tile has no cell"));
        }
        if !(4..=1 << 15).contains(&self.tile) {
            return Err(bad(format!(
                "tile side {} is outside 4..=32768 cells",
                self.tile
            )));
        }
        if (self.width as u64).saturating_mul(self.height as u64) > 1 << 40 {
            return Err(bad(format!(
                "{} x {} cells exceed the 2^40 cells a tiled drainage run handles",
                self.width, self.height
            )));
        }
        if !(self.cell_x > 0.0
            && self.cell_y > 0.0
            && self.cell_x.is_finite()
            && self.cell_y.is_finite())
        {
            return Err(bad("the cell size must be positive and finite"));
        }
        Ok(())
    }

    /// [`Self::check`], and `t` a tile of the layout.
    pub fn check_tile(&self, t: usize) -> Result<()> {
        self.check()?;
        if t >= self.tasks() {
            return Err(bad(format!(
                "tile {t} is not in the layout ({} tiles)",
                self.tasks()
            )));
        }
        Ok(())
    }

    /// [`Self::check`], and one of `items` (`what`) per tile for `phase`: the number of tiles.
    pub(crate) fn check_all<T>(&self, phase: u8, what: &str, items: &[T]) -> Result<usize> {
        self.check()?;
        let tasks = self.tasks();
        if items.len() != tasks {
            return Err(bad(format!(
                "phase {phase} needs the {what} of all {tasks} tiles, got {}",
                items.len()
            )));
        }
        Ok(tasks)
    }

    /// Tiles per row.
    pub fn tiles_x(&self) -> usize {
        self.width.div_ceil(self.tile)
    }

    /// Rows of tiles.
    pub fn tiles_y(&self) -> usize {
        self.height.div_ceil(self.tile)
    }

    /// Number of tiles.
    pub fn tasks(&self) -> usize {
        self.tiles_x() * self.tiles_y()
    }

    /// `[x, y, w, h]` of tile `t`.
    pub fn window(&self, t: usize) -> [usize; 4] {
        let (c, r) = (t % self.tiles_x(), t / self.tiles_x());
        let (x, y) = (c * self.tile, r * self.tile);
        [
            x,
            y,
            self.tile.min(self.width - x),
            self.tile.min(self.height - y),
        ]
    }

    fn tile_at(&self, gx: usize, gy: usize) -> usize {
        (gy / self.tile) * self.tiles_x() + gx / self.tile
    }

    /// The grid of the whole raster.
    pub fn grid(&self) -> Grid {
        self.grid_of(self.width, self.height)
    }

    /// A `width x height` grid at the raster's cell size (a tile, or a tile with a margin).
    pub(crate) fn grid_of(&self, width: usize, height: usize) -> Grid {
        Grid {
            width,
            height,
            cell_x: self.cell_x,
            cell_y: self.cell_y,
        }
    }

    /// The tiles whose products phase 3 of tile `t` reads ([`Levels`]): `t` and its (up to
    /// eight) neighbours.
    pub fn neighbourhood(&self, t: usize) -> Vec<usize> {
        let (c, r) = ((t % self.tiles_x()) as isize, (t / self.tiles_x()) as isize);
        let mut out = Vec::with_capacity(9);
        for dr in -1..=1 {
            for dc in -1..=1 {
                let (cc, rr) = (c + dc, r + dr);
                if cc >= 0
                    && rr >= 0
                    && cc < self.tiles_x() as isize
                    && rr < self.tiles_y() as isize
                {
                    out.push(rr as usize * self.tiles_x() + cc as usize);
                }
            }
        }
        out
    }

    /// Peak bytes of a per-tile pass and of the two single passes (without the cells of flats
    /// crossing tile edges, which phase 4 adds at about 60 bytes each).
    pub fn memory_estimate(&self) -> (u64, u64) {
        let side = self.tile.min(self.width.max(self.height)) as u64;
        let halo = (side + 4) * (side + 4);
        // Phase 3: window of f32, outlet, directions, flat labels and masks (~28 B), tile
        // arrays (counts, next port, local fill: ~20 B).
        let per_tile = halo * 28 + side * side * 20;
        let band: u64 = (0..self.tasks())
            .map(|t| {
                let [_, _, w, h] = self.window(t);
                band_len(w, h) as u64
            })
            .sum();
        // Phase 4: per perimeter-band cell, its share of the ports, links and their maps
        // (measured: 300 MB for 64 tiles of 2048^2, 1.05 M band cells).
        (per_tile, band * 288)
    }
}

/// Cells of the perimeter band of a `w x h` tile.
fn band_len(w: usize, h: usize) -> usize {
    if w <= 2 * BAND || h <= 2 * BAND {
        w * h
    } else {
        2 * BAND * w + (h - 2 * BAND) * 2 * BAND
    }
}

/// Index of `(x, y)` in the band of a `w x h` tile (row-major order of the band's cells).
fn band_index(w: usize, h: usize, x: usize, y: usize) -> Option<usize> {
    if w <= 2 * BAND || h <= 2 * BAND {
        return Some(y * w + x);
    }
    if y < BAND {
        Some(y * w + x)
    } else if y >= h - BAND {
        Some(BAND * w + (h - 2 * BAND) * 2 * BAND + (y - (h - BAND)) * w + x)
    } else {
        let base = BAND * w + (y - BAND) * 2 * BAND;
        if x < BAND {
            Some(base + x)
        } else if x >= w - BAND {
            Some(base + BAND + x - (w - BAND))
        } else {
            None
        }
    }
}

fn band_cells(w: usize, h: usize) -> impl Iterator<Item = (usize, usize)> {
    (0..h).flat_map(move |y| (0..w).filter_map(move |x| band_index(w, h, x, y).map(|_| (x, y))))
}

fn is_perimeter(w: usize, h: usize, x: usize, y: usize) -> bool {
    x == 0 || y == 0 || x + 1 == w || y + 1 == h
}

/// The larger of two elevations, keeping the bits of the one taken (as the single flood
/// assigns the spill level).
#[inline]
fn raise(z: f32, level: f32) -> f32 {
    if level > z { level } else { z }
}

/// The receiver of `c` when it lies in the tile.
#[inline]
fn in_tile_receiver(g: &Grid, c: usize, d: u8) -> Option<usize> {
    if d == NO_FLOW {
        return None;
    }
    let (dy, dx) = D8[d as usize];
    let (x, y) = ((c % g.width) as isize + dx, (c / g.width) as isize + dy);
    (x >= 0 && y >= 0 && x < g.width as isize && y < g.height as isize)
        .then(|| y as usize * g.width + x as usize)
}

/// Directions of the local graph: ports end it.
fn local_dir(g: &Grid, dir: &[u8], port: &[bool]) -> Vec<u8> {
    (0..g.len())
        .map(|c| {
            if port[c] || in_tile_receiver(g, c, dir[c]).is_none() {
                NO_FLOW
            } else {
                dir[c]
            }
        })
        .collect()
}

/// Cells upstream of every cell inside the tile (itself included), the ports (pending cells
/// and cells draining out of the tile) ending the paths.
fn local_counts(g: &Grid, z: &[f32], dir: &[u8], pending: &[bool]) -> (Vec<u64>, Vec<bool>) {
    let n = g.len();
    let port: Vec<bool> = (0..n)
        .map(|c| pending[c] || (dir[c] != NO_FLOW && in_tile_receiver(g, c, dir[c]).is_none()))
        .collect();
    let ldir = local_dir(g, dir, &port);
    let order = super::flow_order(g, &ldir, |i| !z[i].is_nan());
    let mut count: Vec<u64> = (0..n).map(|i| u64::from(!z[i].is_nan())).collect();
    for &c in &order {
        let c = c as usize;
        if let Some(r) = in_tile_receiver(g, c, ldir[c]) {
            count[r] += count[c];
        }
    }
    (count, port)
}

/// The one-cell-margin window phase 1 of tile `t` reads, cut from a whole DEM (`NaN` off the
/// map).
pub fn halo_window(layout: &TileLayout, t: usize, dem: &[f32]) -> Result<Vec<f32>> {
    layout.check_tile(t)?;
    if dem.len() != layout.width * layout.height {
        return Err(bad(format!(
            "the DEM has {} cells, not the layout's {} x {}",
            dem.len(),
            layout.width,
            layout.height
        )));
    }
    halo_from_rows(layout, t, dem, 0)
}

/// The rows of the DEM [`halo_window`] of tile `t` reads: `first .. end` (its tile's rows and
/// the margin rows inside the map).
pub fn halo_rows(layout: &TileLayout, t: usize) -> Result<(usize, usize)> {
    layout.check_tile(t)?;
    let [_, y0, _, h] = layout.window(t);
    Ok((y0.saturating_sub(1), (y0 + h + 1).min(layout.height)))
}

/// [`halo_window`] cut from a band of whole rows of the DEM, `rows` starting at row `first`,
/// which must hold the rows [`halo_rows`] names (so the plan can cut its tiles' inputs from
/// the DEM read band by band): the same values.
pub fn halo_from_rows(
    layout: &TileLayout,
    t: usize,
    rows: &[f32],
    first: usize,
) -> Result<Vec<f32>> {
    let (need0, need1) = halo_rows(layout, t)?;
    let n = rows.len() / layout.width.max(1);
    if !rows.len().is_multiple_of(layout.width.max(1)) || first > need0 || first + n < need1 {
        return Err(bad(format!(
            "rows {first}..{} ({} values) do not hold rows {need0}..{need1} of tile {t} across \
             {} columns",
            first + n,
            rows.len(),
            layout.width
        )));
    }
    let [x0, y0, w, h] = layout.window(t);
    let mut out = vec![f32::NAN; (w + 2) * (h + 2)];
    for y in 0..h + 2 {
        let gy = (y0 + y) as isize - 1;
        if gy < 0 || gy >= layout.height as isize {
            continue;
        }
        let r = gy as usize - first;
        for x in 0..w + 2 {
            let gx = (x0 + x) as isize - 1;
            if gx < 0 || gx >= layout.width as isize {
                continue;
            }
            out[y * (w + 2) + x] = rows[r * layout.width + gx as usize];
        }
    }
    Ok(out)
}

/// Kahn's order over a graph whose nodes each drain into at most one other (`indeg[p]` nodes
/// drain into node `p`): `visit(p)` handles node `p` once every node draining into it is
/// handled, sources first, first in first out, and gives the node `p` drains into. False when
/// a cycle leaves nodes unhandled.
fn drain_order(indeg: &mut [u32], mut visit: impl FnMut(usize) -> Option<usize>) -> bool {
    let mut queue: Vec<usize> = (0..indeg.len()).filter(|&p| indeg[p] == 0).collect();
    let mut head = 0;
    while head < queue.len() {
        let p = queue[head];
        head += 1;
        if let Some(q) = visit(p) {
            indeg[q] -= 1;
            if indeg[q] == 0 {
                queue.push(q);
            }
        }
    }
    queue.len() == indeg.len()
}

/// A per-tile pass run on the `tasks` tiles in the task order `order` (an error unless it names
/// every tile once), and every tile's product.
fn per_tile<T>(
    tasks: usize,
    order: Vec<usize>,
    mut run: impl FnMut(usize) -> Result<T>,
) -> Result<Vec<T>> {
    let mut done: Vec<Option<T>> = (0..tasks).map(|_| None).collect();
    for t in order {
        if !matches!(done.get(t), Some(None)) {
            return Err(bad(format!(
                "the task order names tile {t} twice or out of range"
            )));
        }
        done[t] = Some(run(t)?);
    }
    done.into_iter()
        .map(|x| x.ok_or_else(|| bad("the task order leaves a tile out")))
        .collect()
}

/// The first five passes in one process, tasks in the order `order(phase, tasks)` gives (the tests
/// shuffle it): the tiled run of [`TileLayout`] over `dem`, assembled.
pub fn run_in_memory(
    layout: &TileLayout,
    dem: &[f32],
    order: &mut dyn FnMut(usize, usize) -> Vec<usize>,
) -> Result<Finished> {
    layout.check()?;
    if dem.len() != layout.width * layout.height {
        return Err(bad("the DEM does not match the layout"));
    }
    let tasks = layout.tasks();
    let (fills, graphs): (Vec<LocalFill>, Vec<FillGraph>) =
        per_tile(tasks, order(1, tasks), |t| {
            phase1(layout, t, &halo_window(layout, t, dem)?)
        })?
        .into_iter()
        .unzip();
    let levels = phase2(layout, &graphs)?;
    let (routed, ports): (Vec<Routed>, Vec<PortGraph>) = per_tile(tasks, order(3, tasks), |t| {
        let near: Vec<(usize, &Levels)> = layout
            .neighbourhood(t)
            .into_iter()
            .map(|u| (u, &levels[u]))
            .collect();
        phase3(layout, t, &fills[t], &near)
    })?
    .into_iter()
    .unzip();
    let inflow = phase4(layout, &ports)?;
    let n = layout.width * layout.height;
    let mut out = Finished {
        filled: vec![0.0; n],
        dir: vec![NO_FLOW; n],
        cells: vec![0; n],
    };
    per_tile(tasks, order(5, tasks), |t| {
        let f = phase5(layout, t, &routed[t], &inflow[t])?;
        let [x0, y0, w, h] = layout.window(t);
        for y in 0..h {
            let (a, b) = ((y0 + y) * layout.width + x0, y * w);
            out.filled[a..a + w].copy_from_slice(&f.filled[b..b + w]);
            out.dir[a..a + w].copy_from_slice(&f.dir[b..b + w]);
            out.cells[a..a + w].copy_from_slice(&f.cells[b..b + w]);
        }
        Ok(())
    })?;
    Ok(out)
}

mod codec;

#[cfg(test)]
mod tests;
