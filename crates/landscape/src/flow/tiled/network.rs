//! Phases 6 and 7: what `relief flow` derives from the D8 tree and the drainage area beyond
//! the three rasters of phase 5: Strahler order, watersheds, HAND, the channel cells of the
//! GeoJSON network and the run's figures, equal to [`crate::flow::job::FlowSettings::run`].
//!
//! Each of them follows the D8 tree, one way or the other, so it is carried across tile edges
//! as phase 4 carries the drainage area, through the cells of the tiles' perimeters:
//!
//! - downstream (watershed label, HAND base): a cell takes its receiver's value unless it
//!   defines one (an end of the flow for the label, a channel cell or an end for the base).
//!   Phase 5 follows the path of every perimeter cell inside its tile to where the value is
//!   defined or to the cell where the path leaves the tile ([`Entry`]); phase 6 chains these
//!   paths tile to tile.
//! - upstream (Strahler order): the order of a channel cell is a function of its channel
//!   donors' orders. The channel cells downstream of a perimeter channel cell are "tainted"
//!   (their order may depend on other tiles); phase 5 keeps of them only the perimeter cells
//!   and the confluences ([`Key`]), each with the summary of its donors inside the tile whose
//!   order is known locally and the next key cell downstream (between two key cells the order
//!   passes unchanged). Phase 6 evaluates the keys of all tiles in topological order.
//! - watershed numbers rank every end of the flow by drainage area (ties by cell index): phase
//!   5 lists its tile's ends, phase 6 ranks them all.
//!
//! Phase 6's memory is a few tens of bytes per perimeter cell and per end of the flow (the
//! map's edge and the cells beside voids); phase 7 holds a tile.

use super::*;

/// True when `cells` upstream cells make a channel (drainage area `cells x a0`, as the single
/// run's `area_d8`, at least the threshold).
#[inline]
fn is_channel(cells: u64, a0: f64, threshold_m2: f64) -> bool {
    cells as f64 * a0 >= threshold_m2
}

/// Where the path of a perimeter cell of a tile goes, as far as the tile sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry {
    /// The perimeter cell (tile index).
    pub cell: u32,
    /// The cell the path ends at in the tile: an end of the flow, or the cell where the path
    /// leaves the tile (`out` is its direction).
    pub target: u32,
    /// The direction out of the tile from `target`, or [`NO_FLOW`] when `target` is an end.
    pub out: u8,
    /// The filled elevation of the first channel cell on the path (from `cell`, both ends
    /// included), else the end's when `target` is an end; `NaN` when the path leaves the tile
    /// before a channel (the base is then the next tile's).
    pub base: f32,
}

/// A key cell of the Strahler order: a channel cell on the tile's perimeter or a confluence
/// downstream of one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Key {
    /// The cell (tile index).
    pub cell: u32,
    /// Highest order of its channel donors known inside the tile, and how many have it (the
    /// count capped at 2): `(0, 0)` for none.
    pub top: (u8, u8),
    /// The next key cell downstream in the tile, or [`NONE`].
    pub down: u32,
    /// The direction out of the tile when the cell drains into another tile, else
    /// [`NO_FLOW`].
    pub out: u8,
}

/// Phase 5's summary of a tile for phase 6.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NetSummary {
    /// `(cell, upstream cells, filled elevation)` of the ends of the flow in the tile (valid
    /// cells without direction), sorted by cell.
    pub ends: Vec<(u32, u64, f32)>,
    /// Every valid perimeter cell's path, sorted by cell.
    pub entries: Vec<Entry>,
    /// The key cells of the Strahler order, sorted by cell.
    pub keys: Vec<Key>,
}

/// Phase 6's product for one tile.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NetLevels {
    /// `(end cell, watershed number)`, sorted by cell.
    pub labels: Vec<(u32, u32)>,
    /// `(cell leaving the tile, watershed number, HAND base)` beyond it, sorted by cell.
    pub exits: Vec<(u32, u32, f32)>,
    /// `(key cell, Strahler order)`, sorted by cell.
    pub orders: Vec<(u32, u8)>,
}

/// Phase 7's rasters of one tile.
#[derive(Debug, Clone, PartialEq)]
pub struct NetRasters {
    /// Strahler order of the channel cells (0 elsewhere and on voids).
    pub strahler: Vec<u8>,
    /// Watershed number (1 = the largest basin; 0 on voids).
    pub watersheds: Vec<u32>,
    /// Height above the nearest drainage (m), `NaN` on voids.
    pub hand: Vec<f32>,
}

/// The channel cells and figures of one tile (phase 7), for the network and the report.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TileNetwork {
    /// `(cell, direction, upstream cells, Strahler order)` of the channel cells, by cell.
    pub channels: Vec<(u32, u8, u64, u8)>,
    /// The tile's share of the figures.
    pub figures: TileFigures,
}

/// A tile's share of `relief flow`'s figures: counts and extremes, so their sums and maxima
/// over the tiles are the single run's whatever the order.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileFigures {
    /// Void cells.
    pub voids: u64,
    /// Cells raised by the filling.
    pub raised: u64,
    /// Cells lowered (none with filling).
    pub lowered: u64,
    /// Deepest fill (m).
    pub max_fill: f32,
    /// Deepest cut (m).
    pub max_cut: f32,
    /// Valid cells neither outlets nor drained.
    pub sinks: u64,
    /// Outlets without direction (flow leaves the map there).
    pub outlets: u64,
    /// Channel cells with a direction, by direction (index into [`D8`]).
    pub channel_steps: [u64; 8],
    /// Cells of watershed 1.
    pub largest_basin_cells: u64,
    /// Highest Strahler order.
    pub max_order: u8,
}

/// What phases 5 and 7 derive alike from a finished tile.
struct Local {
    g: Grid,
    /// Directions with the cells draining out of the tile as ends.
    ldir: Vec<u8>,
    order: Vec<u32>,
    channel: Vec<bool>,
    tainted: Vec<bool>,
    key: Vec<bool>,
}

impl Local {
    fn new(layout: &TileLayout, t: usize, f: &Finished, threshold_m2: f64) -> Result<Self> {
        layout.check_tile(t)?;
        let [_, _, w, h] = layout.window(t);
        let n = w * h;
        if f.filled.len() != n || f.dir.len() != n || f.cells.len() != n {
            return Err(bad(format!("tile {t}: the finished tile is not {w} x {h}")));
        }
        if f.dir.iter().any(|&d| d >= 8 && d != NO_FLOW) {
            return Err(bad(format!("tile {t}: a direction is out of range")));
        }
        let g = layout.grid_of(w, h);
        let ldir: Vec<u8> = (0..n)
            .map(|c| {
                if in_tile_receiver(&g, c, f.dir[c]).is_some() {
                    f.dir[c]
                } else {
                    NO_FLOW
                }
            })
            .collect();
        let order = crate::flow::flow_order(&g, &ldir, |i| !f.filled[i].is_nan());
        let a0 = layout.cell_x * layout.cell_y;
        let channel: Vec<bool> = (0..n)
            .map(|c| !f.filled[c].is_nan() && is_channel(f.cells[c], a0, threshold_m2))
            .collect();
        // Tainted: downstream of a perimeter channel cell; key: tainted and on the perimeter
        // or with two channel donors or more.
        let mut tainted = vec![false; n];
        let mut donors = vec![0u8; n];
        for &c in &order {
            let c = c as usize;
            if !channel[c] {
                continue;
            }
            tainted[c] |= is_perimeter(w, h, c % w, c / w);
            if let Some(r) = in_tile_receiver(&g, c, ldir[c]) {
                donors[r] = donors[r].saturating_add(1);
                tainted[r] |= tainted[c];
            }
        }
        let key = (0..n)
            .map(|c| tainted[c] && (is_perimeter(w, h, c % w, c / w) || donors[c] >= 2))
            .collect();
        Ok(Local {
            g,
            ldir,
            order,
            channel,
            tainted,
            key,
        })
    }

    fn receiver(&self, c: usize) -> Option<usize> {
        in_tile_receiver(&self.g, c, self.ldir[c])
    }
}

/// Strahler's rule: the order of a channel cell from the highest order of its channel donors
/// and how many have it (as [`crate::flow::network::strahler`]).
#[inline]
fn strahler_of(top: (u8, u8)) -> u8 {
    match top {
        (0, _) => 1,
        (o, k) if k >= 2 => o.saturating_add(1),
        (o, _) => o,
    }
}

/// Adds a donor of order `o` to a cell's summary of donors.
#[inline]
fn merge_top(t: &mut (u8, u8), o: u8) {
    if o > t.0 {
        *t = (o, 1);
    } else if o == t.0 {
        t.1 = t.1.saturating_add(1).min(2);
    }
}

/// Phase 5's summary of tile `t` (its finished values, `threshold_m2` the channel area).
pub fn summarize(
    layout: &TileLayout,
    t: usize,
    f: &Finished,
    threshold_m2: f64,
) -> Result<NetSummary> {
    let l = Local::new(layout, t, f, threshold_m2)?;
    let (w, h) = (l.g.width, l.g.height);
    let n = w * h;
    let z = &f.filled;
    // Downstream: each cell's target and base, receivers first.
    let mut target = vec![NONE; n];
    let mut base = vec![f32::NAN; n];
    let mut next_key = vec![NONE; n];
    for &c in l.order.iter().rev() {
        let c = c as usize;
        match l.receiver(c) {
            Some(r) => {
                target[c] = target[r];
                base[c] = if l.channel[c] { z[c] } else { base[r] };
                next_key[c] = if l.key[r] { r as u32 } else { next_key[r] };
            }
            None => {
                target[c] = c as u32;
                // An end's base is its own elevation; a cell leaving the tile has one when it
                // is a channel.
                base[c] = if l.channel[c] || f.dir[c] == NO_FLOW {
                    z[c]
                } else {
                    f32::NAN
                };
            }
        }
    }
    // Upstream: the orders known inside the tile (channel cells not tainted), summarised
    // at their receivers.
    let mut top = vec![(0u8, 0u8); n];
    for &c in &l.order {
        let c = c as usize;
        if !l.channel[c] || l.tainted[c] {
            continue;
        }
        if let Some(r) = l.receiver(c) {
            let o = strahler_of(top[c]);
            merge_top(&mut top[r], o);
        }
    }
    let out = |c: usize| {
        if l.receiver(c).is_none() {
            f.dir[c]
        } else {
            NO_FLOW
        }
    };
    let mut s = NetSummary::default();
    for c in 0..n {
        if z[c].is_nan() {
            continue;
        }
        if f.dir[c] == NO_FLOW {
            s.ends.push((c as u32, f.cells[c], z[c]));
        }
        if is_perimeter(w, h, c % w, c / w) {
            let tg = target[c] as usize;
            s.entries.push(Entry {
                cell: c as u32,
                target: tg as u32,
                out: out(tg),
                base: base[c],
            });
        }
        if l.key[c] {
            s.keys.push(Key {
                cell: c as u32,
                top: top[c],
                down: next_key[c],
                out: out(c),
            });
        }
    }
    Ok(s)
}

/// Phase 6: watershed numbers, HAND bases across tile edges and the Strahler order of every
/// key cell (`sums[t]` is tile `t`'s [`NetSummary`]).
pub fn phase6(layout: &TileLayout, sums: &[NetSummary]) -> Result<Vec<NetLevels>> {
    let tasks = layout.check_all(6, "summaries", sums)?;
    // Ends ranked by drainage area (as `basins::watersheds`: area descending, then index).
    let a0 = layout.cell_x * layout.cell_y;
    let mut ends: Vec<(f64, u64)> = Vec::new();
    for (t, s) in sums.iter().enumerate() {
        ends.extend(
            s.ends
                .iter()
                .map(|&(c, n, _)| (n as f64 * a0, layout.global(t, c))),
        );
    }
    ends.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let number: IntMap<u64, u32> = ends
        .iter()
        .enumerate()
        .map(|(k, &(_, g))| (g, k as u32 + 1))
        .collect();
    let entry_at = |t: usize, c: u32| -> Result<&Entry> {
        let e = &sums[t].entries;
        e.binary_search_by_key(&c, |x| x.cell)
            .map(|k| &e[k])
            .map_err(|_| bad(format!("tile {t}: no path is given for perimeter cell {c}")))
    };
    // Where the flow goes after a cell leaving tile `t` at `c` in direction `d`.
    let beyond = |t: usize, c: u32, d: u8| -> Result<(usize, &Entry)> {
        let r = (d < 8)
            .then(|| layout.neighbour(layout.global(t, c), d as usize))
            .flatten()
            .ok_or_else(|| bad(format!("tile {t}: cell {c} drains off the map")))?;
        let (u, rc) = layout.locate(r);
        Ok((u, entry_at(u, rc)?))
    };
    // The watershed number and base past every cell leaving a tile, chains followed to their
    // end (each path visits a tile edge at most once per perimeter cell: longer is a cycle).
    let limit: usize = sums.iter().map(|s| s.entries.len()).sum::<usize>() + 1;
    let mut memo: IntMap<u64, (u32, f32)> = IntMap::default();
    let mut out: Vec<NetLevels> = vec![NetLevels::default(); tasks];
    for (t, s) in sums.iter().enumerate() {
        for e in s
            .entries
            .iter()
            .filter(|e| e.cell == e.target && e.out != NO_FLOW)
        {
            let mut chain: Vec<(u64, f32)> = Vec::new();
            let (mut u, mut x) = (t, *e);
            let (num, mut base) = loop {
                let id = layout.global(u, x.cell);
                if let Some(&v) = memo.get(&id) {
                    break v;
                }
                if chain.len() > limit {
                    return Err(bad("the tiles' paths form a cycle (their products do not \
                                    belong together)"));
                }
                let (v, next) = beyond(u, x.cell, x.out)?;
                chain.push((id, next.base));
                if next.out == NO_FLOW {
                    let g = layout.global(v, next.target);
                    let num = *number.get(&g).ok_or_else(|| {
                        bad(format!(
                            "tile {v}: a path ends at a cell that is not an end"
                        ))
                    })?;
                    break (num, f32::NAN);
                }
                u = v;
                x = *entry_at(v, next.target)?;
                if x.cell != x.target || x.out == NO_FLOW {
                    return Err(bad(format!(
                        "tile {v}: a path leaves at a cell that does not"
                    )));
                }
            };
            for &(id, b) in chain.iter().rev() {
                if !b.is_nan() {
                    base = b;
                }
                memo.insert(id, (num, base));
            }
            let (num, base) = memo[&layout.global(t, e.cell)];
            if base.is_nan() {
                return Err(bad(format!("tile {t}: a path has no end")));
            }
            out[t].exits.push((e.cell, num, base));
        }
    }
    for (k, &(_, g)) in ends.iter().enumerate() {
        let (u, c) = layout.locate(g);
        out[u].labels.push((c, k as u32 + 1));
    }
    strahler_keys(layout, sums, &mut out)?;
    for o in &mut out {
        o.labels.sort_unstable();
        o.exits.sort_unstable_by_key(|e| e.0);
        o.orders.sort_unstable();
    }
    Ok(out)
}

/// The Strahler order of every key cell: the keys of all tiles in topological order.
fn strahler_keys(layout: &TileLayout, sums: &[NetSummary], out: &mut [NetLevels]) -> Result<()> {
    let mut at: IntMap<u64, usize> = IntMap::default();
    let mut node: Vec<(usize, Key)> = Vec::new();
    for (t, s) in sums.iter().enumerate() {
        for k in &s.keys {
            at.insert(layout.global(t, k.cell), node.len());
            node.push((t, *k));
        }
    }
    let m = node.len();
    let mut down = vec![usize::MAX; m];
    let mut indeg = vec![0u32; m];
    for (i, &(t, k)) in node.iter().enumerate() {
        let to = if k.down != NONE {
            Some(layout.global(t, k.down))
        } else if k.out != NO_FLOW {
            layout.neighbour(layout.global(t, k.cell), k.out as usize)
        } else {
            None
        };
        if let Some(g) = to {
            let j = *at.get(&g).ok_or_else(|| {
                bad(format!(
                    "tile {t}: a channel drains into a cell that is not a key of the network"
                ))
            })?;
            down[i] = j;
            indeg[j] += 1;
        }
    }
    let mut top: Vec<(u8, u8)> = node.iter().map(|(_, k)| k.top).collect();
    let ordered = super::drain_order(&mut indeg, |i| {
        let o = strahler_of(top[i]);
        let (t, k) = node[i];
        out[t].orders.push((k.cell, o));
        let j = down[i];
        (j != usize::MAX).then(|| {
            merge_top(&mut top[j], o);
            j
        })
    });
    if !ordered {
        return Err(bad(
            "the channel keys form a cycle (the tiles' products do not belong together)",
        ));
    }
    Ok(())
}

/// Phase 7 of tile `t`: its Strahler order, watershed numbers and HAND, its channel cells and
/// its figures, from its finished values, its [`NetLevels`] and its input (the tile and a
/// one-cell margin, as phase 1 read it).
pub fn phase7(
    layout: &TileLayout,
    t: usize,
    f: &Finished,
    levels: &NetLevels,
    input: &[f32],
    threshold_m2: f64,
) -> Result<(NetRasters, TileNetwork)> {
    let l = Local::new(layout, t, f, threshold_m2)?;
    let (w, h) = (l.g.width, l.g.height);
    let n = w * h;
    if input.len() != (w + 2) * (h + 2) {
        return Err(bad(format!(
            "tile {t}: the input is not the tile and its margin"
        )));
    }
    let z = &f.filled;
    let order_of: IntMap<u32, u8> = levels.orders.iter().copied().collect();
    let label_of: IntMap<u32, u32> = levels.labels.iter().copied().collect();
    let exit_of: IntMap<u32, (u32, f32)> =
        levels.exits.iter().map(|&(c, a, b)| (c, (a, b))).collect();
    let missing = |what: &str, c: usize| bad(format!("tile {t}: no {what} is given for cell {c}"));
    let mut strahler = vec![0u8; n];
    let mut top = vec![(0u8, 0u8); n];
    for &c in &l.order {
        let c = c as usize;
        if !l.channel[c] {
            continue;
        }
        strahler[c] = if l.key[c] {
            *order_of
                .get(&(c as u32))
                .ok_or_else(|| missing("order", c))?
        } else {
            strahler_of(top[c])
        };
        if let Some(r) = l.receiver(c) {
            merge_top(&mut top[r], strahler[c]);
        }
    }
    let mut label = vec![0u32; n];
    let mut base = vec![f32::NAN; n];
    for &c in l.order.iter().rev() {
        let c = c as usize;
        let (lab, b) = match l.receiver(c) {
            Some(r) => (label[r], base[r]),
            None if f.dir[c] == NO_FLOW => (
                *label_of
                    .get(&(c as u32))
                    .ok_or_else(|| missing("watershed", c))?,
                z[c],
            ),
            None => *exit_of
                .get(&(c as u32))
                .ok_or_else(|| missing("watershed", c))?,
        };
        label[c] = lab;
        base[c] = if l.channel[c] { z[c] } else { b };
    }
    let hand: Vec<f32> = (0..n).map(|i| z[i] - base[i]).collect();
    let mut net = TileNetwork::default();
    let fig = &mut net.figures;
    let ww = w + 2;
    for c in 0..n {
        let (x, y) = (c % w, c / w);
        let a = input[(y + 1) * ww + x + 1];
        let b = z[c];
        if a.is_nan() {
            fig.voids += 1;
            continue;
        }
        if b > a {
            fig.raised += 1;
            fig.max_fill = fig.max_fill.max(b - a);
        } else if b < a {
            fig.lowered += 1;
            fig.max_cut = fig.max_cut.max(a - b);
        }
        let mut outlet = false;
        for (dy, dx) in D8 {
            let v = input[((y + 1) as isize + dy) as usize * ww + ((x + 1) as isize + dx) as usize];
            outlet |= v.is_nan();
        }
        if f.dir[c] == NO_FLOW {
            if outlet {
                fig.outlets += 1;
            } else {
                fig.sinks += 1;
            }
        }
        if strahler[c] > 0 {
            if f.dir[c] != NO_FLOW {
                fig.channel_steps[f.dir[c] as usize] += 1;
            }
            net.channels
                .push((c as u32, f.dir[c], f.cells[c], strahler[c]));
        }
        fig.largest_basin_cells += u64::from(label[c] == 1);
        fig.max_order = fig.max_order.max(strahler[c]);
    }
    let rasters = NetRasters {
        strahler,
        watersheds: label,
        hand,
    };
    Ok((rasters, net))
}

/// The channel network and the figures of the whole run from every tile's [`TileNetwork`]
/// (`nets[t]` is tile `t`'s): the GeoJSON `FeatureCollection` and the figures of
/// [`crate::flow::job::FlowSettings::run`], equal to the single run's. Holds the channel
/// cells of the whole map (about 40 bytes each).
pub fn assemble(
    layout: &TileLayout,
    georef: Option<&relief_heightfield::GeoRef>,
    nets: &[TileNetwork],
) -> Result<(serde_json::Value, crate::flow::job::FlowFigures)> {
    use crate::flow::network::{centre, collection, feature};
    layout.check()?;
    if nets.len() != layout.tasks() {
        return Err(bad(format!(
            "the network needs all {} tiles, got {}",
            layout.tasks(),
            nets.len()
        )));
    }
    let mut cells: Vec<(u64, u8, u64, u8)> = Vec::new();
    let mut fig = TileFigures::default();
    for (t, net) in nets.iter().enumerate() {
        let [_, _, w, h] = layout.window(t);
        for &(c, d, n, o) in &net.channels {
            if c as usize >= w * h || (d >= 8 && d != NO_FLOW) || o == 0 {
                return Err(bad(format!("tile {t}: a channel cell is out of range")));
            }
            cells.push((layout.global(t, c), d, n, o));
        }
        let f = &net.figures;
        fig.voids += f.voids;
        fig.raised += f.raised;
        fig.lowered += f.lowered;
        fig.max_fill = fig.max_fill.max(f.max_fill);
        fig.max_cut = fig.max_cut.max(f.max_cut);
        fig.sinks += f.sinks;
        fig.outlets += f.outlets;
        for k in 0..8 {
            fig.channel_steps[k] += f.channel_steps[k];
        }
        fig.largest_basin_cells += f.largest_basin_cells;
        fig.max_order = fig.max_order.max(f.max_order);
    }
    cells.sort_unstable_by_key(|c| c.0);
    let find = |g: u64| cells.binary_search_by_key(&g, |c| c.0).ok();
    let down = |k: usize| -> Option<usize> {
        let (g, d, _, _) = cells[k];
        (d != NO_FLOW)
            .then(|| layout.neighbour(g, d as usize))
            .flatten()
            .and_then(find)
    };
    let mut donors = vec![0u8; cells.len()];
    for k in 0..cells.len() {
        if let Some(j) = down(k) {
            donors[j] = donors[j].saturating_add(1);
        }
    }
    let grid = layout.grid();
    let dist = grid.distances();
    let a0 = layout.cell_x * layout.cell_y;
    let mut features = Vec::new();
    for k in 0..cells.len() {
        if donors[k] == 1 {
            continue;
        }
        let mut reach = vec![k];
        let mut cur = k;
        while let Some(j) = down(cur) {
            if reach.len() > cells.len() {
                return Err(bad("the channel cells form a cycle"));
            }
            reach.push(j);
            if donors[j] >= 2 {
                break;
            }
            cur = j;
        }
        if reach.len() < 2 {
            continue;
        }
        let coords = reach
            .iter()
            .map(|&j| centre(&grid, georef, cells[j].0))
            .collect();
        let length: f64 = reach[..reach.len() - 1]
            .iter()
            .map(|&j| dist[cells[j].1 as usize])
            .sum();
        let last = cells[*reach.last().expect("a reach has cells")];
        features.push(feature(coords, cells[k].3, last.2 as f64 * a0, length));
    }
    let figures = crate::flow::job::FlowFigures {
        cells: layout.width * layout.height,
        voids: fig.voids as usize,
        raised_cells: fig.raised as usize,
        lowered_cells: fig.lowered as usize,
        max_fill_m: fig.max_fill as f64,
        max_cut_m: fig.max_cut as f64,
        sinks: fig.sinks as usize,
        outlets: fig.outlets as usize,
        channel_km: crate::flow::job::channel_length(&grid, &fig.channel_steps) / 1e3,
        reaches: features.len(),
        max_order: fig.max_order,
        largest_basin_km2: fig.largest_basin_cells as f64 * a0 / 1e6,
    };
    Ok((collection(features, georef), figures))
}

impl Finished {
    /// The direction raster `relief flow` writes for these cells: ESRI codes, 0 where the
    /// flow ends, `NaN` on voids.
    pub fn direction_codes(&self) -> Vec<f32> {
        (0..self.filled.len())
            .map(|i| {
                if self.filled[i].is_nan() {
                    f32::NAN
                } else if self.dir[i] == NO_FLOW {
                    0.0
                } else {
                    crate::flow::ESRI_CODES[self.dir[i] as usize] as f32
                }
            })
            .collect()
    }

    /// The drainage area raster (m^2) `relief flow` writes for these cells (`cells x a0`,
    /// rounded to f32 once), `NaN` on voids.
    pub fn area(&self, layout: &TileLayout) -> Vec<f32> {
        let a0 = layout.cell_x * layout.cell_y;
        (0..self.filled.len())
            .map(|i| {
                if self.filled[i].is_nan() {
                    f32::NAN
                } else {
                    (self.cells[i] as f64 * a0) as f32
                }
            })
            .collect()
    }
}

impl NetRasters {
    /// The Strahler order and watershed rasters `relief flow` writes, `NaN` on the voids of
    /// `input` (the tile and its one-cell margin, as phase 7 read it).
    pub fn to_f32(&self, width: usize, input: &[f32]) -> (Vec<f32>, Vec<f32>) {
        let void = |i: usize| input[(i / width + 1) * (width + 2) + i % width + 1].is_nan();
        let nan_or = |i: usize, v: f32| if void(i) { f32::NAN } else { v };
        (
            (0..self.strahler.len())
                .map(|i| nan_or(i, self.strahler[i] as f32))
                .collect(),
            (0..self.watersheds.len())
                .map(|i| nan_or(i, self.watersheds[i] as f32))
                .collect(),
        )
    }
}
