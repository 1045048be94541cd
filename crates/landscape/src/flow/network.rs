//! The channel network: cells whose drainage area reaches a threshold, their Strahler order
//! (Strahler 1957), and the network as GeoJSON line strings in the DEM's coordinates.

use serde_json::{Value, json};

use super::{Routing, receiver};
use crate::grid::Grid;
use relief_heightfield::GeoRef;

/// Strahler order of every channel cell (`area >= threshold_m2`), 0 elsewhere: 1 at a
/// channel's head; where two channels of the same order meet, one more; else the larger.
pub fn strahler(r: &Routing, area: &[f64], threshold_m2: f64) -> Vec<u8> {
    let n = r.grid.len();
    let channel = |i: usize| area[i] >= threshold_m2;
    let mut order = vec![0u8; n];
    // Highest donor order and how many donors have it.
    let mut top = vec![(0u8, 0u8); n];
    for &c in &r.order {
        let c = c as usize;
        if !channel(c) {
            continue;
        }
        let (o, k) = top[c];
        order[c] = if o == 0 {
            1
        } else if k >= 2 {
            o.saturating_add(1)
        } else {
            o
        };
        if let Some(d) = receiver(&r.grid, c, r.dir[c]) {
            let t = &mut top[d];
            if order[c] > t.0 {
                *t = (order[c], 1);
            } else if order[c] == t.0 {
                t.1 = t.1.saturating_add(1);
            }
        }
    }
    order
}

/// One stretch of channel between a head or confluence and the next confluence or outlet.
#[derive(Debug, Clone, PartialEq)]
pub struct Reach {
    /// Cells from upstream to downstream (the downstream end included: the confluence cell or
    /// the outlet).
    pub cells: Vec<u32>,
    /// Strahler order of the reach.
    pub order: u8,
    /// Drainage area at the downstream end (m^2).
    pub area_m2: f64,
}

/// Splits the channel network into reaches (each from a head, or from just below a
/// confluence, down to the next confluence or the network's end), in the row-major order of
/// their first cells (an order the tiled run of [`super::tiled`] reproduces).
pub fn reaches(r: &Routing, area: &[f64], strahler: &[u8]) -> Vec<Reach> {
    let n = r.grid.len();
    let mut channel_donors = vec![0u8; n];
    for i in 0..n {
        if strahler[i] == 0 {
            continue;
        }
        if let Some(d) = receiver(&r.grid, i, r.dir[i]).filter(|&d| strahler[d] > 0) {
            channel_donors[d] = channel_donors[d].saturating_add(1);
        }
    }
    let mut out = Vec::new();
    // A reach starts at a head (no channel donor) or at a confluence (two or more).
    for c in 0..n {
        if strahler[c] == 0 || channel_donors[c] == 1 {
            continue;
        }
        let mut cells = vec![c as u32];
        let mut cur = c;
        while let Some(d) = receiver(&r.grid, cur, r.dir[cur]) {
            if strahler[d] == 0 {
                break;
            }
            cells.push(d as u32);
            if channel_donors[d] >= 2 {
                break;
            }
            cur = d;
        }
        let last = *cells.last().expect("a reach has a cell") as usize;
        if cells.len() >= 2 {
            out.push(Reach {
                order: strahler[c],
                area_m2: area[last],
                cells,
            });
        }
    }
    out
}

/// The EPSG code of a georeference's projected or geographic CRS, when its GeoKeys name one.
pub fn epsg(georef: &GeoRef) -> Option<u16> {
    let keys = georef.geo_key_directory.as_ref()?;
    keys.get(4..)?
        .chunks_exact(4)
        .find(|k| (k[0] == 3072 || k[0] == 2048) && k[1] == 0 && k[3] != 0 && k[3] != 32767)
        .map(|k| k[3])
}

/// Map coordinates of a cell centre: through the georeference's affine transform, else metres
/// from the north-west corner (x east, y north, so the first row has y = -cell_y / 2).
pub fn cell_centre(r: &Routing, georef: Option<&GeoRef>, i: usize) -> [f64; 2] {
    centre(&r.grid, georef, i as u64)
}

/// [`cell_centre`] of cell `i` of a grid.
pub fn centre(grid: &Grid, georef: Option<&GeoRef>, i: u64) -> [f64; 2] {
    let w = grid.width as u64;
    let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
    match georef.and_then(|g| g.geotransform) {
        Some(t) => [t[0] + x * t[1] + y * t[2], t[3] + x * t[4] + y * t[5]],
        None => [x * grid.cell_x, -y * grid.cell_y],
    }
}

/// One reach as a GeoJSON `Feature` (see [`geojson`]).
pub fn feature(coords: Vec<[f64; 2]>, order: u8, area_m2: f64, length_m: f64) -> Value {
    json!({
        "type": "Feature",
        "properties": {
            "order": order,
            "area_km2": area_m2 / 1e6,
            "length_m": length_m,
        },
        "geometry": { "type": "LineString", "coordinates": coords },
    })
}

/// The features as a GeoJSON `FeatureCollection` (see [`geojson`]).
pub fn collection(features: Vec<Value>, georef: Option<&GeoRef>) -> Value {
    let mut fc = json!({ "type": "FeatureCollection", "features": features });
    if let Some(code) = georef.and_then(epsg) {
        fc["crs"] = json!({
            "type": "name",
            "properties": { "name": format!("urn:ogc:def:crs:EPSG::{code}") },
        });
    }
    fc
}

/// The reaches as a GeoJSON `FeatureCollection` of `LineString`s (properties: `order`,
/// `area_km2`, `length_m`), in the DEM's CRS (named in a `crs` member when an EPSG code is
/// known, which GDAL/OGR and QGIS read).
pub fn geojson(r: &Routing, georef: Option<&GeoRef>, reaches: &[Reach]) -> Value {
    let dist = r.grid.distances();
    let features: Vec<Value> = reaches
        .iter()
        .map(|reach| {
            let coords: Vec<[f64; 2]> = reach
                .cells
                .iter()
                .map(|&c| cell_centre(r, georef, c as usize))
                .collect();
            let length: f64 = reach
                .cells
                .iter()
                .take(reach.cells.len() - 1)
                .map(|&c| dist[r.dir[c as usize] as usize])
                .sum();
            feature(coords, reach.order, reach.area_m2, length)
        })
        .collect();
    collection(features, georef)
}
