//! Phase 3: the filled tile, its D8 directions on a two-cell halo, the flats it holds
//! drained, and the local accumulation with its ports (Barnes 2016 section 3.3, Barnes 2017
//! section 3.1).

use crate::depression::flats::resolve_flats_labelled;
use crate::depression::is_outlet;

use super::*;

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

/// The final filled surface of tile `t` with a margin of [`BAND`] cells: its own cells from
/// its local fill and levels, the margin from its neighbours' bands (`NaN` off the map).
fn surface_window(
    layout: &TileLayout,
    t: usize,
    fill: &LocalFill,
    levels: &[(usize, &Levels)],
) -> Result<Vec<f32>> {
    let [x0, y0, w, h] = layout.window(t);
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
    Ok(wz)
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
    let [_, _, w, h] = layout.window(t);
    check_fill(fill, w, h, t)?;
    let wz = surface_window(layout, t, fill, levels)?;
    let (ww, wh) = (w + 2 * BAND, h + 2 * BAND);
    let grid = layout.grid_of(ww, wh);
    let outlet: Vec<bool> = (0..ww * wh)
        .map(|i| !wz[i].is_nan() && is_outlet(&wz, &grid, i))
        .collect();
    let mut wdir = crate::flow::steepest_descent(&wz, &grid, &outlet);
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
    let tgrid = layout.grid_of(w, h);
    let (count, port) = local_counts(&tgrid, &filled, &dir, &pending);
    let order = crate::flow::flow_order(&tgrid, &local_dir(&tgrid, &dir, &port), |i| {
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
