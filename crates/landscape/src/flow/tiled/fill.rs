//! Phases 1 and 2: the local priority flood of a tile with its labels and spills, and the
//! global flood over the labels of all tiles (Barnes 2016 sections 3.1-3.2).

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

use super::*;
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
    crate::flow::positive_zeros(&mut z);
    let outlet = |i: usize| {
        let (x, y) = (i % w + 1, i / w + 1);
        D8.iter().any(|&(dy, dx)| {
            halo[(y as isize + dy) as usize * hw + (x as isize + dx) as usize].is_nan()
        })
    };
    let grid = layout.grid_of(w, h);
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
    let tasks = layout.check_all(2, "graphs", graphs)?;
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

pub(super) fn check_graph(g: &FillGraph, w: usize, h: usize, t: usize) -> Result<()> {
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

pub(super) fn check_fill(f: &LocalFill, w: usize, h: usize, t: usize) -> Result<()> {
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
