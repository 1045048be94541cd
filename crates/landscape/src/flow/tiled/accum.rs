//! Phases 4 and 5: the flats crossing tile edges drained whole and the ports' graph resolved
//! (Barnes 2017 section 3.2), then each tile's final directions and upstream cells (section
//! 3.3).

use std::collections::VecDeque;

use super::*;

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

impl TileLayout {
    /// The raster index of cell `c` of tile `t`.
    pub(super) fn global(&self, t: usize, c: u32) -> u64 {
        let [x0, y0, w, _] = self.window(t);
        let c = c as usize;
        ((y0 + c / w) * self.width + x0 + c % w) as u64
    }

    /// The tile of raster cell `g` and its index there.
    pub(super) fn locate(&self, g: u64) -> (usize, u32) {
        let (gx, gy) = (
            (g % self.width as u64) as usize,
            (g / self.width as u64) as usize,
        );
        let u = self.tile_at(gx, gy);
        let [x0, y0, w, _] = self.window(u);
        (u, ((gy - y0) * w + gx - x0) as u32)
    }

    /// Neighbour `k` of raster cell `g`, if on the map.
    pub(super) fn neighbour(&self, g: u64, k: usize) -> Option<u64> {
        let (gx, gy) = (
            (g % self.width as u64) as isize,
            (g / self.width as u64) as isize,
        );
        let (dy, dx) = D8[k];
        let (x, y) = (gx + dx, gy + dy);
        (x >= 0 && y >= 0 && x < self.width as isize && y < self.height as isize)
            .then(|| y as u64 * self.width as u64 + x as u64)
    }
}

/// The directions of the cells of flats crossing tile edges (by raster index): the same
/// labels, breadth-first rings and mask descent as `resolve_flats` (Barnes, Lehman and Mulla
/// 2014), on the cells the tiles sent.
fn drain_crossing_flats(layout: &TileLayout, graphs: &[PortGraph]) -> Result<IntMap<u64, u8>> {
    // The flats crossing tile edges, drained as `resolve_flats` drains them.
    let mut at: IntMap<u64, usize> = IntMap::default();
    let mut cz: Vec<f32> = Vec::new();
    let mut flat: Vec<bool> = Vec::new();
    let mut high: Vec<bool> = Vec::new();
    let mut gid: Vec<u64> = Vec::new();
    let mut lows: Vec<u64> = Vec::new();
    for (t, g) in graphs.iter().enumerate() {
        for p in &g.pending {
            let id = layout.global(t, p.cell);
            at.insert(id, cz.len());
            cz.push(p.z);
            flat.push(true);
            high.push(p.high);
            gid.push(id);
        }
    }
    for (t, g) in graphs.iter().enumerate() {
        for &(c, z) in &g.low {
            let id = layout.global(t, c);
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
            if let Some(j) = layout.neighbour(gid[i], k).and_then(|g| at.get(&g)) {
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
    Ok(resolved)
}

/// Phase 4: drains the flats that cross tile edges and resolves the ports' graph
/// (`graphs[t]` is tile `t`'s [`PortGraph`]).
pub fn phase4(layout: &TileLayout, graphs: &[PortGraph]) -> Result<Vec<Inflow>> {
    let tasks = layout.check_all(4, "port graphs", graphs)?;
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
    let resolved = drain_crossing_flats(layout, graphs)?;
    // The ports' graph in topological order (Barnes 2017 section 3.2).
    let mut port_at: IntMap<u64, usize> = IntMap::default();
    let mut pdir: Vec<u8> = Vec::new();
    let mut total: Vec<u64> = Vec::new();
    let mut pid: Vec<u64> = Vec::new();
    for (t, g) in graphs.iter().enumerate() {
        for &(c, d, count) in &g.ports {
            let id = layout.global(t, c);
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
            .then(|| layout.neighbour(pid[p], pdir[p] as usize))
            .flatten()
        else {
            down.push(None);
            continue;
        };
        let q = if let Some(&q) = port_at.get(&r) {
            Some(q)
        } else {
            let (u, c) = layout.locate(r);
            let to = *links[u].get(&c).ok_or_else(|| {
                bad(format!(
                    "tile {u}: its port graph does not say where cell {c} drains"
                ))
            })?;
            if to == NONE {
                None
            } else {
                Some(*port_at.get(&layout.global(u, to)).ok_or_else(|| {
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
    let ordered = super::drain_order(&mut indeg, |p| {
        let (_, q) = down[p]?;
        let q = q?;
        total[q] += total[p];
        Some(q)
    });
    if !ordered {
        return Err(bad(
            "the ports' graph has a cycle (the tiles' products do not belong together)",
        ));
    }
    let mut out: Vec<Inflow> = vec![Inflow::default(); tasks];
    let mut entries: Vec<IntMap<u32, u64>> = vec![IntMap::default(); tasks];
    for p in 0..np {
        if let Some((r, _)) = down[p] {
            let (u, c) = layout.locate(r);
            *entries[u].entry(c).or_insert(0) += total[p];
        }
    }
    for (id, d) in resolved {
        let (u, c) = layout.locate(id);
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

impl Finished {
    /// The values of tile `t` cut from those of the whole raster (as [`run_in_memory`] gives
    /// them): what [`phase5`] gives that tile.
    pub fn tile(&self, layout: &TileLayout, t: usize) -> Finished {
        let [x0, y0, tw, th] = layout.window(t);
        let pick = |i: usize| (y0 + i / tw) * layout.width + x0 + i % tw;
        Finished {
            filled: (0..tw * th).map(|i| self.filled[pick(i)]).collect(),
            dir: (0..tw * th).map(|i| self.dir[pick(i)]).collect(),
            cells: (0..tw * th).map(|i| self.cells[pick(i)]).collect(),
        }
    }
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
    let g = layout.grid_of(w, h);
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
    let order = crate::flow::flow_order(&g, &ldir, |i| !z[i].is_nan());
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
