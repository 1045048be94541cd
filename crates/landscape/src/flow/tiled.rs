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

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap, VecDeque};

use crate::depression::flats::resolve_flats_labelled;
use crate::depression::is_outlet;
use crate::depression::radix::RadixHeap;
use crate::elev::Elev;
use crate::grid::{D8, Grid, NO_FLOW};
use crate::{LandscapeError, Result};

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

/// Number of passes of a tiled drainage run (three per tile, two single tasks).
pub const PHASES: usize = 5;

/// True for the passes that run as one task (the others run one task per tile).
pub fn is_single(phase: usize) -> bool {
    phase == 2 || phase == 4
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
        Grid {
            width: self.width,
            height: self.height,
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

// ---------------------------------------------------------------------------------------------
// Phase 1

/// Phase 1's tile: locally filled elevations and the label of every cell (`u32::MAX` on
/// voids, 0 for the cells that drain to an outlet inside the tile, `1 + k` for the region
/// flooded from the perimeter band's cell `k`).
#[derive(Debug, Clone, PartialEq)]
pub struct LocalFill {
    /// Tile columns.
    pub width: usize,
    /// Tile rows.
    pub height: usize,
    /// Locally filled elevations (`NaN` on voids).
    pub z: Vec<f32>,
    /// Labels.
    pub label: Vec<u32>,
}

/// Phase 1's perimeter data: the band's locally filled elevations and labels, and the lowest
/// spill between every two labels that touch inside the tile.
#[derive(Debug, Clone, PartialEq)]
pub struct FillGraph {
    /// Locally filled elevations of the band cells.
    pub band_z: Vec<f32>,
    /// Labels of the band cells.
    pub band_label: Vec<u32>,
    /// `(a, b, spill)` with `a < b`, sorted.
    pub edges: Vec<(u32, u32, f32)>,
}

/// Phase 1 of tile `t`: `halo` holds the tile's DEM with a one-cell margin (`(w + 2) x
/// (h + 2)`, `NaN` off the map and on voids).
pub fn phase1(layout: &TileLayout, t: usize, halo: &[f32]) -> Result<(LocalFill, FillGraph)> {
    layout.check_tile(t)?;
    let [_, _, w, h] = layout.window(t);
    if halo.len() != (w + 2) * (h + 2) {
        return Err(bad(format!(
            "tile {t}: the DEM window has {} cells, not ({w} + 2) x ({h} + 2)",
            halo.len()
        )));
    }
    let n = w * h;
    let hw = w + 2;
    let mut z: Vec<f32> = (0..n).map(|i| halo[(i / w + 1) * hw + i % w + 1]).collect();
    // As the single run does (`route`): a filled zero has one sign whatever reached it.
    super::positive_zeros(&mut z);
    let outlet = |i: usize| {
        let (x, y) = (i % w + 1, i / w + 1);
        D8.iter().any(|&(dy, dx)| {
            halo[(y as isize + dy) as usize * hw + (x as isize + dx) as usize].is_nan()
        })
    };
    let grid = Grid {
        width: w,
        height: h,
        cell_x: layout.cell_x,
        cell_y: layout.cell_y,
    };
    let mut label = vec![NONE; n];
    let mut closed = vec![false; n];
    let mut open: RadixHeap<u64> = RadixHeap::new();
    let mut pit: VecDeque<u32> = VecDeque::new();
    for i in 0..n {
        if z[i].is_nan() {
            closed[i] = true;
            continue;
        }
        let (x, y) = (i % w, i / w);
        let out = outlet(i);
        if out || is_perimeter(w, h, x, y) {
            closed[i] = true;
            label[i] = if out {
                0
            } else {
                1 + band_index(w, h, x, y).expect("a perimeter cell is in the band") as u32
            };
            open.push(z[i].entry(i as u32));
        }
    }
    let mut edges: IntMap<(u32, u32), f32> = IntMap::default();
    loop {
        let c = match pit.pop_front() {
            Some(c) => c,
            None => match open.pop() {
                Some(e) => f32::cell(e),
                None => break,
            },
        } as usize;
        let zc = z[c];
        let lc = label[c];
        grid.for_neighbours(c, |_, m| {
            if closed[m] {
                let lm = label[m];
                if lm != NONE && lm != lc {
                    let key = (lc.min(lm), lc.max(lm));
                    let s = raise(zc, z[m]);
                    edges
                        .entry(key)
                        .and_modify(|e| {
                            if s < *e {
                                *e = s
                            }
                        })
                        .or_insert(s);
                }
                return;
            }
            closed[m] = true;
            label[m] = lc;
            if z[m] <= zc {
                z[m] = zc;
                pit.push_back(m as u32);
            } else {
                open.push(z[m].entry(m as u32));
            }
        });
    }
    let mut edges: Vec<(u32, u32, f32)> = edges.into_iter().map(|((a, b), s)| (a, b, s)).collect();
    edges.sort_by_key(|e| (e.0, e.1));
    let (band_z, band_label) = band_cells(w, h)
        .map(|(x, y)| (z[y * w + x], label[y * w + x]))
        .unzip();
    Ok((
        LocalFill {
            width: w,
            height: h,
            z,
            label,
        },
        FillGraph {
            band_z,
            band_label,
            edges,
        },
    ))
}

// ---------------------------------------------------------------------------------------------
// Phase 2

/// Phase 2's product for one tile: the level of each of its labels (index = label; label 0,
/// the outlets, is `-inf`) and the filled elevations of its perimeter band.
#[derive(Debug, Clone, PartialEq)]
pub struct Levels {
    /// Level per label (`band length + 1` entries).
    pub level: Vec<f32>,
    /// Final filled elevations of the band cells.
    pub band: Vec<f32>,
}

/// Phase 2: joins the tiles' labels and spills (`graphs[t]` is tile `t`'s) and floods the
/// graph from the outlets.
pub fn phase2(layout: &TileLayout, graphs: &[FillGraph]) -> Result<Vec<Levels>> {
    layout.check()?;
    let tasks = layout.tasks();
    if graphs.len() != tasks {
        return Err(bad(format!(
            "phase 2 needs the graphs of all {tasks} tiles, got {}",
            graphs.len()
        )));
    }
    let mut base = Vec::with_capacity(tasks + 1);
    let mut next = 1usize;
    for (t, g) in graphs.iter().enumerate() {
        let [_, _, w, h] = layout.window(t);
        check_graph(g, w, h, t)?;
        base.push(next);
        next += band_len(w, h);
    }
    let nodes = next;
    let id = |t: usize, l: u32| if l == 0 { 0 } else { base[t] + l as usize - 1 };
    let mut adj: Vec<Vec<(u32, f32)>> = vec![Vec::new(); nodes];
    let mut link = |a: usize, b: usize, s: f32| {
        if a != b {
            adj[a].push((b as u32, s));
            adj[b].push((a as u32, s));
        }
    };
    for (t, g) in graphs.iter().enumerate() {
        for &(a, b, s) in &g.edges {
            link(id(t, a), id(t, b), s);
        }
    }
    // Spills across tile edges: every perimeter cell with its neighbours in the tiles after it.
    for (t, g) in graphs.iter().enumerate() {
        let [x0, y0, w, h] = layout.window(t);
        for (k, (x, y)) in band_cells(w, h).enumerate() {
            if !is_perimeter(w, h, x, y) || g.band_label[k] == NONE {
                continue;
            }
            let (gx, gy) = (x0 + x, y0 + y);
            for &(dy, dx) in &D8 {
                let (nx, ny) = (gx as isize + dx, gy as isize + dy);
                if nx < 0 || ny < 0 || nx >= layout.width as isize || ny >= layout.height as isize {
                    continue;
                }
                let (nx, ny) = (nx as usize, ny as usize);
                let u = layout.tile_at(nx, ny);
                if u <= t {
                    continue;
                }
                let [ux, uy, uw, uh] = layout.window(u);
                let ku = band_index(uw, uh, nx - ux, ny - uy)
                    .ok_or_else(|| bad("a tile edge cell is outside its band"))?;
                let gu = &graphs[u];
                if gu.band_label[ku] == NONE {
                    continue;
                }
                let s = raise(g.band_z[k], gu.band_z[ku]);
                link(id(t, g.band_label[k]), id(u, gu.band_label[ku]), s);
            }
        }
    }
    let mut level = vec![f32::INFINITY; nodes];
    level[0] = f32::NEG_INFINITY;
    let mut heap = BinaryHeap::new();
    heap.push(Reverse((f32::NEG_INFINITY.key(), 0u32)));
    while let Some(Reverse((k, u))) = heap.pop() {
        let u = u as usize;
        if k != level[u].key() {
            continue;
        }
        for &(v, s) in &adj[u] {
            let c = raise(s, level[u]);
            if c < level[v as usize] {
                level[v as usize] = c;
                heap.push(Reverse((c.key(), v)));
            }
        }
    }
    drop(adj);
    let mut out = Vec::with_capacity(tasks);
    for (t, g) in graphs.iter().enumerate() {
        let [_, _, w, h] = layout.window(t);
        let mut lv = Vec::with_capacity(band_len(w, h) + 1);
        lv.push(f32::NEG_INFINITY);
        lv.extend_from_slice(&level[base[t]..base[t] + band_len(w, h)]);
        for (k, &l) in g.band_label.iter().enumerate() {
            if l != NONE && l != 0 && lv[l as usize] == f32::INFINITY && !g.band_z[k].is_nan() {
                return Err(bad(format!(
                    "tile {t}: a region of the tile reaches no outlet (the graphs of the plan \
                     do not belong together)"
                )));
            }
        }
        let band = g
            .band_z
            .iter()
            .zip(&g.band_label)
            .map(|(&z, &l)| {
                if l == NONE {
                    z
                } else {
                    raise(z, lv[l as usize])
                }
            })
            .collect();
        out.push(Levels { level: lv, band });
    }
    Ok(out)
}

fn check_graph(g: &FillGraph, w: usize, h: usize, t: usize) -> Result<()> {
    let b = band_len(w, h);
    if g.band_z.len() != b || g.band_label.len() != b {
        return Err(bad(format!(
            "tile {t}: the perimeter band has the wrong size"
        )));
    }
    let max = b as u32;
    if g.band_label.iter().any(|&l| l != NONE && l > max)
        || g.edges.iter().any(|&(a, c, _)| a >= c || c > max)
    {
        return Err(bad(format!("tile {t}: a label is out of range")));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Phase 3

/// Phase 3's tile: final filled elevations and the D8 directions known so far ([`NO_FLOW`]
/// also on the cells of flats that cross tile edges, which phase 4 drains).
#[derive(Debug, Clone, PartialEq)]
pub struct Routed {
    /// Filled elevations.
    pub filled: Vec<f32>,
    /// Directions (index into [`D8`] or [`NO_FLOW`]).
    pub dir: Vec<u8>,
}

/// A cell of a flat that crosses tile edges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlatCell {
    /// Cell index in its tile.
    pub cell: u32,
    /// Its filled elevation.
    pub z: f32,
    /// Beside higher ground (a high edge).
    pub high: bool,
}

/// Phase 3's perimeter data for phase 4.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PortGraph {
    /// Cells of flats that cross tile edges.
    pub pending: Vec<FlatCell>,
    /// Low edges (draining cells beside a flat cell of the same elevation) next to such flats
    /// or to a flat cell across the tile edge: `(cell, z)`.
    pub low: Vec<(u32, f32)>,
    /// Ports: cells whose flow leaves the tile, and the pending cells: `(cell, direction, cells
    /// upstream inside the tile)`.
    pub ports: Vec<(u32, u8, u64)>,
    /// For the cells flow can enter from outside (perimeter cells and cells beside pending
    /// cells): the port their flow reaches in the tile (`u32::MAX`: none).
    pub links: Vec<(u32, u32)>,
}

/// Phase 3 of tile `t`: `fill` is its [`LocalFill`], `levels` the [`Levels`] of the tiles of
/// [`TileLayout::neighbourhood`] as `(tile, levels)`.
pub fn phase3(
    layout: &TileLayout,
    t: usize,
    fill: &LocalFill,
    levels: &[(usize, &Levels)],
) -> Result<(Routed, PortGraph)> {
    layout.check_tile(t)?;
    let [x0, y0, w, h] = layout.window(t);
    check_fill(fill, w, h, t)?;
    let find = |u: usize| -> Result<&Levels> {
        let l = levels
            .iter()
            .find(|(i, _)| *i == u)
            .map(|(_, l)| *l)
            .ok_or_else(|| bad(format!("tile {t}: the levels of tile {u} are missing")))?;
        let [_, _, uw, uh] = layout.window(u);
        if l.level.len() != band_len(uw, uh) + 1 || l.band.len() != band_len(uw, uh) {
            return Err(bad(format!("tile {u}: its levels have the wrong size")));
        }
        Ok(l)
    };
    let own = find(t)?;
    let (ww, wh) = (w + 2 * BAND, h + 2 * BAND);
    let mut wz = vec![f32::NAN; ww * wh];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let l = fill.label[i];
            // Voids keep their bits, as the single run's surface does.
            wz[(y + BAND) * ww + x + BAND] = if l == NONE {
                fill.z[i]
            } else {
                raise(fill.z[i], own.level[l as usize])
            };
        }
    }
    for wy in 0..wh {
        for wx in 0..ww {
            let inside = (BAND..BAND + w).contains(&wx) && (BAND..BAND + h).contains(&wy);
            let (gx, gy) = (
                (x0 + wx) as isize - BAND as isize,
                (y0 + wy) as isize - BAND as isize,
            );
            if inside
                || gx < 0
                || gy < 0
                || gx >= layout.width as isize
                || gy >= layout.height as isize
            {
                continue;
            }
            let (gx, gy) = (gx as usize, gy as usize);
            let u = layout.tile_at(gx, gy);
            let [ux, uy, uw, uh] = layout.window(u);
            let k = band_index(uw, uh, gx - ux, gy - uy)
                .ok_or_else(|| bad("a halo cell is outside its tile's band"))?;
            wz[wy * ww + wx] = find(u)?.band[k];
        }
    }
    let grid = Grid {
        width: ww,
        height: wh,
        cell_x: layout.cell_x,
        cell_y: layout.cell_y,
    };
    let outlet: Vec<bool> = (0..ww * wh)
        .map(|i| !wz[i].is_nan() && is_outlet(&wz, &grid, i))
        .collect();
    let mut wdir = super::steepest_descent(&wz, &grid, &outlet);
    let flat0: Vec<bool> = (0..ww * wh)
        .map(|i| !wz[i].is_nan() && !outlet[i] && wdir[i] == NO_FLOW)
        .collect();
    let fl = resolve_flats_labelled(&wz, &grid, &outlet, &mut wdir);
    let inside = |i: usize| {
        let (x, y) = (i % ww, i / ww);
        (BAND..BAND + w).contains(&x) && (BAND..BAND + h).contains(&y)
    };
    // A flat is drained here when all of it and its seed lie in the tile and the seed touches
    // no flat across the tile edge (which could share its label).
    let mut exact = vec![true; fl.seeds.len()];
    for i in 0..ww * wh {
        if flat0[i] && fl.label[i] != NONE && !inside(i) {
            exact[fl.label[i] as usize] = false;
        }
    }
    for (l, &s) in fl.seeds.iter().enumerate() {
        let s = s as usize;
        if !inside(s) {
            exact[l] = false;
            continue;
        }
        grid.for_neighbours(s, |_, m| {
            if !inside(m) && flat0[m] && wz[m] == wz[s] {
                exact[l] = false;
            }
        });
    }
    let to_tile = |i: usize| (i / ww - BAND) * w + i % ww - BAND;
    let to_win = |c: usize| (c / w + BAND) * ww + c % w + BAND;
    let n = w * h;
    let mut filled = vec![0f32; n];
    let mut dir = vec![NO_FLOW; n];
    let mut pending = vec![false; n];
    let mut graph = PortGraph::default();
    for c in 0..n {
        let i = to_win(c);
        filled[c] = wz[i];
        dir[c] = wdir[i];
        if flat0[i] && (fl.label[i] == NONE || !exact[fl.label[i] as usize]) {
            pending[c] = true;
            dir[c] = NO_FLOW;
            let mut high = false;
            grid.for_neighbours(i, |_, m| high |= !wz[m].is_nan() && wz[m] > wz[i]);
            graph.pending.push(FlatCell {
                cell: c as u32,
                z: wz[i],
                high,
            });
        }
    }
    for c in 0..n {
        let i = to_win(c);
        if wz[i].is_nan() || flat0[i] {
            continue;
        }
        let mut send = false;
        grid.for_neighbours(i, |_, m| {
            if flat0[m] && wz[m] == wz[i] && (!inside(m) || pending[to_tile(m)]) {
                send = true;
            }
        });
        if send {
            graph.low.push((c as u32, wz[i]));
        }
    }
    // Local accumulation with the ports as ends (Barnes 2017 section 3.1).
    let tgrid = Grid {
        width: w,
        height: h,
        cell_x: layout.cell_x,
        cell_y: layout.cell_y,
    };
    let (count, port) = local_counts(&tgrid, &filled, &dir, &pending);
    let order = super::flow_order(&tgrid, &local_dir(&tgrid, &dir, &port), |i| {
        !filled[i].is_nan()
    });
    let mut next_port = vec![NONE; n];
    for &c in order.iter().rev() {
        let c = c as usize;
        next_port[c] = if port[c] {
            c as u32
        } else {
            match in_tile_receiver(&tgrid, c, dir[c]) {
                Some(r) => next_port[r],
                None => NONE,
            }
        };
    }
    for c in 0..n {
        if port[c] {
            graph.ports.push((c as u32, dir[c], count[c]));
        }
    }
    for c in 0..n {
        if filled[c].is_nan() || pending[c] {
            continue;
        }
        let (x, y) = (c % w, c / w);
        let mut beside = false;
        tgrid.for_neighbours(c, |_, m| beside |= pending[m]);
        if beside || is_perimeter(w, h, x, y) {
            graph.links.push((c as u32, next_port[c]));
        }
    }
    Ok((Routed { filled, dir }, graph))
}

fn check_fill(f: &LocalFill, w: usize, h: usize, t: usize) -> Result<()> {
    if f.width != w || f.height != h || f.z.len() != w * h || f.label.len() != w * h {
        return Err(bad(format!(
            "tile {t}: the local fill is {} x {}, not {w} x {h}",
            f.width, f.height
        )));
    }
    let max = band_len(w, h) as u32;
    if f.label.iter().any(|&l| l != NONE && l > max) {
        return Err(bad(format!("tile {t}: a label is out of range")));
    }
    Ok(())
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

// ---------------------------------------------------------------------------------------------
// Phase 4

/// Phase 4's product for one tile: the directions of its cells on flats that cross tile
/// edges, and the cells flowing into it: `(cell, upstream cells)` where an inflow enters.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Inflow {
    /// `(cell, direction)` of the tile's pending cells.
    pub pending_dir: Vec<(u32, u8)>,
    /// `(cell, cells)`: upstream cells entering the tile at `cell`, sorted by cell.
    pub entries: Vec<(u32, u64)>,
}

/// Phase 4: drains the flats that cross tile edges and resolves the ports' graph
/// (`graphs[t]` is tile `t`'s [`PortGraph`]).
pub fn phase4(layout: &TileLayout, graphs: &[PortGraph]) -> Result<Vec<Inflow>> {
    layout.check()?;
    let tasks = layout.tasks();
    if graphs.len() != tasks {
        return Err(bad(format!(
            "phase 4 needs the port graphs of all {tasks} tiles, got {}",
            graphs.len()
        )));
    }
    for (t, g) in graphs.iter().enumerate() {
        let [_, _, w, h] = layout.window(t);
        let n = (w * h) as u32;
        if g.pending.iter().any(|p| p.cell >= n)
            || g.low.iter().any(|l| l.0 >= n)
            || g.ports
                .iter()
                .any(|p| p.0 >= n || (p.1 >= 8 && p.1 != NO_FLOW))
            || g.links
                .iter()
                .any(|l| l.0 >= n || (l.1 >= n && l.1 != NONE))
        {
            return Err(bad(format!(
                "tile {t}: a cell of its port graph is out of range"
            )));
        }
    }
    let global = |t: usize, c: u32| -> u64 {
        let [x0, y0, w, _] = layout.window(t);
        let c = c as usize;
        ((y0 + c / w) * layout.width + x0 + c % w) as u64
    };
    let locate = |g: u64| -> (usize, u32) {
        let (gx, gy) = (
            (g % layout.width as u64) as usize,
            (g / layout.width as u64) as usize,
        );
        let u = layout.tile_at(gx, gy);
        let [x0, y0, w, _] = layout.window(u);
        (u, ((gy - y0) * w + gx - x0) as u32)
    };
    let neighbour = |g: u64, k: usize| -> Option<u64> {
        let (gx, gy) = (
            (g % layout.width as u64) as isize,
            (g / layout.width as u64) as isize,
        );
        let (dy, dx) = D8[k];
        let (x, y) = (gx + dx, gy + dy);
        (x >= 0 && y >= 0 && x < layout.width as isize && y < layout.height as isize)
            .then(|| y as u64 * layout.width as u64 + x as u64)
    };
    // The flats crossing tile edges, drained as `resolve_flats` drains them.
    let mut at: IntMap<u64, usize> = IntMap::default();
    let mut cz: Vec<f32> = Vec::new();
    let mut flat: Vec<bool> = Vec::new();
    let mut high: Vec<bool> = Vec::new();
    let mut gid: Vec<u64> = Vec::new();
    let mut lows: Vec<u64> = Vec::new();
    for (t, g) in graphs.iter().enumerate() {
        for p in &g.pending {
            let id = global(t, p.cell);
            at.insert(id, cz.len());
            cz.push(p.z);
            flat.push(true);
            high.push(p.high);
            gid.push(id);
        }
    }
    for (t, g) in graphs.iter().enumerate() {
        for &(c, z) in &g.low {
            let id = global(t, c);
            if at.contains_key(&id) {
                return Err(bad(format!("tile {t}: a cell is both flat and a low edge")));
            }
            at.insert(id, cz.len());
            cz.push(z);
            flat.push(false);
            high.push(false);
            gid.push(id);
            lows.push(id);
        }
    }
    lows.sort_unstable();
    let m = cz.len();
    let nbrs = |i: usize, f: &mut dyn FnMut(usize, usize)| {
        for k in 0..8 {
            if let Some(j) = neighbour(gid[i], k).and_then(|g| at.get(&g)) {
                f(k, *j);
            }
        }
    };
    let mut label = vec![NONE; m];
    let mut next = 0u32;
    for &s in &lows {
        let s = at[&s];
        if label[s] != NONE {
            continue;
        }
        label[s] = next;
        let mut q = VecDeque::from([s]);
        while let Some(c) = q.pop_front() {
            nbrs(c, &mut |_, j| {
                if label[j] == NONE && cz[j] == cz[s] && flat[j] {
                    label[j] = next;
                    q.push_back(j);
                }
            });
        }
        next += 1;
    }
    let rings = |seeds: Vec<usize>, visit: &mut dyn FnMut(usize, u32)| {
        let mut seen = vec![false; m];
        for &s in &seeds {
            seen[s] = true;
        }
        let mut ring = 0u32;
        let mut frontier = seeds;
        while !frontier.is_empty() {
            ring += 1;
            let mut nxt = Vec::new();
            for &c in &frontier {
                nbrs(c, &mut |_, j| {
                    if !seen[j] && label[j] != NONE && label[j] == label[c] && flat[j] {
                        seen[j] = true;
                        visit(j, ring);
                        nxt.push(j);
                    }
                });
            }
            frontier = nxt;
        }
    };
    let mut away = vec![0u32; m];
    let mut flat_height = vec![0u32; next as usize];
    let highs: Vec<usize> = (0..m).filter(|&i| high[i] && label[i] != NONE).collect();
    for &hc in &highs {
        away[hc] = 1;
        let l = label[hc] as usize;
        flat_height[l] = flat_height[l].max(1);
    }
    rings(highs, &mut |i, ring| {
        away[i] = ring + 1;
        let l = label[i] as usize;
        flat_height[l] = flat_height[l].max(ring + 1);
    });
    let mut mask = vec![0u32; m];
    rings(lows.iter().map(|s| at[s]).collect(), &mut |i, ring| {
        let away_term = if away[i] > 0 {
            flat_height[label[i] as usize] - away[i]
        } else {
            0
        };
        mask[i] = 2 * ring + away_term;
    });
    let dist = layout.grid().distances();
    let mut resolved: IntMap<u64, u8> = IntMap::default();
    for i in 0..m {
        if !flat[i] {
            continue;
        }
        let mut best = (0.0f64, NO_FLOW);
        if label[i] != NONE {
            nbrs(i, &mut |k, j| {
                if label[j] == label[i] && mask[j] < mask[i] {
                    let s = (mask[i] - mask[j]) as f64 / dist[k];
                    if s > best.0 {
                        best = (s, k as u8);
                    }
                }
            });
        }
        resolved.insert(gid[i], best.1);
    }
    drop((at, cz, flat, high, label, mask, away));
    // The ports' graph in topological order (Barnes 2017 section 3.2).
    let mut port_at: IntMap<u64, usize> = IntMap::default();
    let mut pdir: Vec<u8> = Vec::new();
    let mut total: Vec<u64> = Vec::new();
    let mut pid: Vec<u64> = Vec::new();
    for (t, g) in graphs.iter().enumerate() {
        for &(c, d, count) in &g.ports {
            let id = global(t, c);
            let d = if d == NO_FLOW {
                *resolved.get(&id).ok_or_else(|| {
                    bad(format!(
                        "tile {t}: a port without direction is not on a flat"
                    ))
                })?
            } else {
                d
            };
            port_at.insert(id, pdir.len());
            pdir.push(d);
            total.push(count);
            pid.push(id);
        }
    }
    let links: Vec<IntMap<u32, u32>> = graphs
        .iter()
        .map(|g| g.links.iter().copied().collect())
        .collect();
    let np = pid.len();
    let mut down: Vec<Option<(u64, Option<usize>)>> = Vec::with_capacity(np);
    for p in 0..np {
        let Some(r) = (pdir[p] != NO_FLOW)
            .then(|| neighbour(pid[p], pdir[p] as usize))
            .flatten()
        else {
            down.push(None);
            continue;
        };
        let q = if let Some(&q) = port_at.get(&r) {
            Some(q)
        } else {
            let (u, c) = locate(r);
            let to = *links[u].get(&c).ok_or_else(|| {
                bad(format!(
                    "tile {u}: its port graph does not say where cell {c} drains"
                ))
            })?;
            if to == NONE {
                None
            } else {
                Some(*port_at.get(&global(u, to)).ok_or_else(|| {
                    bad(format!(
                        "tile {u}: a link points to a cell that is not a port"
                    ))
                })?)
            }
        };
        down.push(Some((r, q)));
    }
    let mut indeg = vec![0u32; np];
    for d in down.iter().flatten() {
        if let Some(q) = d.1 {
            indeg[q] += 1;
        }
    }
    let mut queue: Vec<usize> = (0..np).filter(|&p| indeg[p] == 0).collect();
    let mut head = 0;
    while head < queue.len() {
        let p = queue[head];
        head += 1;
        if let Some((_, Some(q))) = down[p] {
            total[q] += total[p];
            indeg[q] -= 1;
            if indeg[q] == 0 {
                queue.push(q);
            }
        }
    }
    if queue.len() != np {
        return Err(bad(
            "the ports' graph has a cycle (the tiles' products do not belong together)",
        ));
    }
    let mut out: Vec<Inflow> = vec![Inflow::default(); tasks];
    let mut entries: Vec<IntMap<u32, u64>> = vec![IntMap::default(); tasks];
    for p in 0..np {
        if let Some((r, _)) = down[p] {
            let (u, c) = locate(r);
            *entries[u].entry(c).or_insert(0) += total[p];
        }
    }
    for (id, d) in resolved {
        let (u, c) = locate(id);
        out[u].pending_dir.push((c, d));
    }
    for (t, o) in out.iter_mut().enumerate() {
        o.pending_dir.sort_unstable();
        o.entries = entries[t].iter().map(|(&c, &a)| (c, a)).collect();
        o.entries.sort_unstable();
    }
    Ok(out)
}

// ---------------------------------------------------------------------------------------------
// Phase 5

/// The final values of one tile.
#[derive(Debug, Clone, PartialEq)]
pub struct Finished {
    /// Filled elevations.
    pub filled: Vec<f32>,
    /// D8 directions (index into [`D8`] or [`NO_FLOW`]).
    pub dir: Vec<u8>,
    /// Cells upstream of each cell, itself included (0 on voids).
    pub cells: Vec<u64>,
}

/// Phase 5 of tile `t`: its [`Routed`] tile and its [`Inflow`].
pub fn phase5(layout: &TileLayout, t: usize, routed: &Routed, inflow: &Inflow) -> Result<Finished> {
    layout.check_tile(t)?;
    let [_, _, w, h] = layout.window(t);
    let n = w * h;
    if routed.filled.len() != n || routed.dir.len() != n {
        return Err(bad(format!("tile {t}: the routed tile is not {w} x {h}")));
    }
    let mut dir = routed.dir.clone();
    let mut pending = vec![false; n];
    for &(c, d) in &inflow.pending_dir {
        let c = c as usize;
        if c >= n || (d >= 8 && d != NO_FLOW) {
            return Err(bad(format!("tile {t}: an inflow cell is out of range")));
        }
        pending[c] = true;
        dir[c] = d;
    }
    let g = Grid {
        width: w,
        height: h,
        cell_x: layout.cell_x,
        cell_y: layout.cell_y,
    };
    let port: Vec<bool> = (0..n)
        .map(|c| pending[c] || (dir[c] != NO_FLOW && in_tile_receiver(&g, c, dir[c]).is_none()))
        .collect();
    let ldir = local_dir(&g, &dir, &port);
    let z = &routed.filled;
    let mut cells: Vec<u64> = (0..n).map(|i| u64::from(!z[i].is_nan())).collect();
    for &(c, a) in &inflow.entries {
        let c = c as usize;
        if c >= n || z[c].is_nan() {
            return Err(bad(format!(
                "tile {t}: an inflow enters a void or leaves the tile"
            )));
        }
        cells[c] += a;
    }
    let order = super::flow_order(&g, &ldir, |i| !z[i].is_nan());
    for &c in &order {
        let c = c as usize;
        if let Some(r) = in_tile_receiver(&g, c, ldir[c]) {
            cells[r] += cells[c];
        }
    }
    Ok(Finished {
        filled: routed.filled.clone(),
        dir,
        cells,
    })
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
    let [x0, y0, w, h] = layout.window(t);
    let mut out = vec![f32::NAN; (w + 2) * (h + 2)];
    for y in 0..h + 2 {
        let gy = (y0 + y) as isize - 1;
        if gy < 0 || gy >= layout.height as isize {
            continue;
        }
        for x in 0..w + 2 {
            let gx = (x0 + x) as isize - 1;
            if gx < 0 || gx >= layout.width as isize {
                continue;
            }
            out[y * (w + 2) + x] = dem[gy as usize * layout.width + gx as usize];
        }
    }
    Ok(out)
}

/// All five passes in one process, tasks in the order `order(phase, tasks)` gives (the tests
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
    let mut p1: Vec<Option<(LocalFill, FillGraph)>> = vec![None; tasks];
    for t in order(1, tasks) {
        if t >= tasks || p1[t].is_some() {
            return Err(bad(format!(
                "the task order names tile {t} twice or out of range"
            )));
        }
        p1[t] = Some(phase1(layout, t, &halo_window(layout, t, dem)?)?);
    }
    let missing = || bad("the task order leaves a tile out");
    let (fills, graphs): (Vec<LocalFill>, Vec<FillGraph>) = p1
        .into_iter()
        .map(|x| x.ok_or_else(missing))
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    let levels = phase2(layout, &graphs)?;
    let mut p3: Vec<Option<(Routed, PortGraph)>> = vec![None; tasks];
    for t in order(3, tasks) {
        if t >= tasks || p3[t].is_some() {
            return Err(bad(format!(
                "the task order names tile {t} twice or out of range"
            )));
        }
        let near: Vec<(usize, &Levels)> = layout
            .neighbourhood(t)
            .into_iter()
            .map(|u| (u, &levels[u]))
            .collect();
        p3[t] = Some(phase3(layout, t, &fills[t], &near)?);
    }
    let (routed, ports): (Vec<Routed>, Vec<PortGraph>) = p3
        .into_iter()
        .map(|x| x.ok_or_else(missing))
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    let inflow = phase4(layout, &ports)?;
    let n = layout.width * layout.height;
    let mut out = Finished {
        filled: vec![0.0; n],
        dir: vec![NO_FLOW; n],
        cells: vec![0; n],
    };
    let mut done = vec![false; tasks];
    for t in order(5, tasks) {
        if t >= tasks || done[t] {
            return Err(bad(format!(
                "the task order names tile {t} twice or out of range"
            )));
        }
        done[t] = true;
        let f = phase5(layout, t, &routed[t], &inflow[t])?;
        let [x0, y0, w, h] = layout.window(t);
        for y in 0..h {
            let (a, b) = ((y0 + y) * layout.width + x0, y * w);
            out.filled[a..a + w].copy_from_slice(&f.filled[b..b + w]);
            out.dir[a..a + w].copy_from_slice(&f.dir[b..b + w]);
            out.cells[a..a + w].copy_from_slice(&f.cells[b..b + w]);
        }
    }
    if done.contains(&false) {
        return Err(missing());
    }
    Ok(out)
}

mod codec;

#[cfg(test)]
mod tests;
