//! The passes of the tiled drainage (`relief.dask.flow`): relief-landscape's `flow::tiled`,
//! one function per pass, each taking and giving the passes' checked byte forms (Python
//! `bytes`, which Dask moves between workers), so a graph of per-tile and single tasks
//! computes `relief.flow` of a DEM larger than one worker, equal bit for bit; and the passes
//! of the tiled masks (`relief.dask.masks`, relief-landscape's `masks::tiled`).

use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use relief_landscape::flow::tiled::{
    self, FillGraph, Finished, Inflow, Levels, LocalFill, NetLevels, NetSummary, PortGraph, Routed,
    TileLayout, TileNetwork,
};

use relief_landscape::masks::tiled::{self as mask_tiles, ScaleCounts, ScaleFine, ScaleTargets};
use relief_landscape::masks::{MaskScales, MasksSettings};

use crate::convert::Geo;
use crate::run::Failure;

/// `(width, height, tile, cell_x, cell_y)` of a tiled run.
type Layout = (usize, usize, usize, f64, f64);

fn layout(l: Layout) -> PyResult<TileLayout> {
    let t = TileLayout {
        width: l.0,
        height: l.1,
        tile: l.2,
        cell_x: l.3,
        cell_y: l.4,
    };
    t.check().map_err(Failure::value)?;
    Ok(t)
}

fn tile(l: &TileLayout, t: usize) -> PyResult<[usize; 4]> {
    l.check_tile(t).map_err(Failure::value)?;
    Ok(l.window(t))
}

fn array<'py>(
    py: Python<'py>,
    w: usize,
    h: usize,
    v: Vec<f32>,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let a = ndarray::Array2::from_shape_vec((h, w), v).map_err(Failure::value)?;
    Ok(PyArray2::from_owned_array(py, a))
}

/// A tile's input from its bytes (little-endian f32, the tile and its one-cell margin, row
/// by row: bytes rather than an array, which a Dask worker may hand over unaligned).
fn halo(l: &TileLayout, t: usize, b: &[u8]) -> PyResult<Vec<f32>> {
    let [_, _, w, h] = tile(l, t)?;
    if b.len() != (w + 2) * (h + 2) * 4 {
        return Err(Failure::Value(format!(
            "the input of tile {t} has {} bytes, not the {} of its {} x {} f32 cells with the margin",
            b.len(),
            (w + 2) * (h + 2) * 4,
            w + 2,
            h + 2
        ))
        .into());
    }
    Ok(relief_heightfield::bytes::f32_from_le_bytes(b))
}

/// Each tile's `(x, y, width, height)`.
#[pyfunction]
pub(crate) fn flow_tiles(l: Layout) -> PyResult<Vec<[usize; 4]>> {
    let l = layout(l)?;
    Ok((0..l.tasks()).map(|t| l.window(t)).collect())
}

/// Phase 1 of tile `t` from its input (the tile and a one-cell margin, `NaN` off the map, as
/// little-endian f32 bytes):
/// `(local fill, fill graph)`.
#[pyfunction]
pub(crate) fn flow_phase1<'py>(
    py: Python<'py>,
    l: Layout,
    t: usize,
    input: Vec<u8>,
) -> PyResult<(Bound<'py, PyBytes>, Bound<'py, PyBytes>)> {
    let l = layout(l)?;
    let z = halo(&l, t, &input)?;
    let (f, g) = py
        .detach(|| tiled::phase1(&l, t, &z))
        .map_err(Failure::value)?;
    Ok((
        PyBytes::new(py, &f.to_bytes(t)),
        PyBytes::new(py, &g.to_bytes(&l, t)),
    ))
}

/// A single-task phase: decodes every tile's input, runs `phase` over all of them off the GIL
/// and encodes every tile's output.
fn single_phase<'py, I, O>(
    py: Python<'py>,
    l: Layout,
    inputs: Vec<Vec<u8>>,
    decode: fn(&[u8], &TileLayout, usize) -> relief_landscape::Result<I>,
    phase: fn(&TileLayout, &[I]) -> relief_landscape::Result<Vec<O>>,
    encode: fn(&O, &TileLayout, usize) -> Vec<u8>,
) -> PyResult<Vec<Bound<'py, PyBytes>>> {
    let l = layout(l)?;
    let out = py
        .detach(|| {
            let decoded = inputs
                .iter()
                .enumerate()
                .map(|(t, b)| decode(b, &l, t))
                .collect::<relief_landscape::Result<Vec<_>>>()?;
            let outputs = phase(&l, &decoded)?;
            Ok::<_, relief_landscape::LandscapeError>(
                outputs
                    .iter()
                    .enumerate()
                    .map(|(t, x)| encode(x, &l, t))
                    .collect::<Vec<_>>(),
            )
        })
        .map_err(Failure::value)?;
    Ok(out.iter().map(|b| PyBytes::new(py, b)).collect())
}

/// Phase 2 (one task): every tile's levels from every tile's fill graph.
#[pyfunction]
pub(crate) fn flow_phase2<'py>(
    py: Python<'py>,
    l: Layout,
    graphs: Vec<Vec<u8>>,
) -> PyResult<Vec<Bound<'py, PyBytes>>> {
    single_phase(
        py,
        l,
        graphs,
        FillGraph::from_bytes,
        tiled::phase2,
        Levels::to_bytes,
    )
}

/// Phase 3 of tile `t`: `(routed, port graph)` from its local fill and every tile's levels.
#[pyfunction]
pub(crate) fn flow_phase3<'py>(
    py: Python<'py>,
    l: Layout,
    t: usize,
    fill: Vec<u8>,
    levels: Vec<Vec<u8>>,
) -> PyResult<(Bound<'py, PyBytes>, Bound<'py, PyBytes>)> {
    let l = layout(l)?;
    tile(&l, t)?;
    let (r, p) = py
        .detach(|| {
            let f = LocalFill::from_bytes(&fill, &l, t)?;
            let near = l
                .neighbourhood(t)
                .into_iter()
                .map(|u| {
                    let b = levels.get(u).map(Vec::as_slice).unwrap_or_default();
                    Ok((u, Levels::from_bytes(b, &l, u)?))
                })
                .collect::<relief_landscape::Result<Vec<_>>>()?;
            let refs: Vec<(usize, &Levels)> = near.iter().map(|(u, x)| (*u, x)).collect();
            let (r, p) = tiled::phase3(&l, t, &f, &refs)?;
            Ok::<_, relief_landscape::LandscapeError>((r.to_bytes(&l, t), p.to_bytes(&l, t)))
        })
        .map_err(Failure::value)?;
    Ok((PyBytes::new(py, &r), PyBytes::new(py, &p)))
}

/// Phase 4 (one task): every tile's inflows from every tile's port graph.
#[pyfunction]
pub(crate) fn flow_phase4<'py>(
    py: Python<'py>,
    l: Layout,
    ports: Vec<Vec<u8>>,
) -> PyResult<Vec<Bound<'py, PyBytes>>> {
    single_phase(
        py,
        l,
        ports,
        PortGraph::from_bytes,
        tiled::phase4,
        Inflow::to_bytes,
    )
}

fn finished(
    l: &TileLayout,
    t: usize,
    routed: &[u8],
    inflow: &[u8],
) -> relief_landscape::Result<Finished> {
    let r = Routed::from_bytes(routed, l, t)?;
    let i = Inflow::from_bytes(inflow, l, t)?;
    tiled::phase5(l, t, &r, &i)
}

/// Three rasters of a tile and a byte form (its summary or its network).
type TileRasters<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyBytes>,
);

/// Phase 5 of tile `t`: `(filled, direction, area, network summary)`, the rasters as
/// `relief.flow` gives them.
#[pyfunction]
pub(crate) fn flow_phase5<'py>(
    py: Python<'py>,
    l: Layout,
    t: usize,
    routed: Vec<u8>,
    inflow: Vec<u8>,
    channel_area: f64,
) -> PyResult<TileRasters<'py>> {
    let l = layout(l)?;
    let [_, _, w, h] = tile(&l, t)?;
    let (f, s) = py
        .detach(|| {
            let f = finished(&l, t, &routed, &inflow)?;
            let s = tiled::summarize(&l, t, &f, channel_area)?.to_bytes(&l, t);
            Ok::<_, relief_landscape::LandscapeError>((f, s))
        })
        .map_err(Failure::value)?;
    let (d, a) = (f.direction_codes(), f.area(&l));
    Ok((
        array(py, w, h, f.filled)?,
        array(py, w, h, d)?,
        array(py, w, h, a)?,
        PyBytes::new(py, &s),
    ))
}

/// Phase 6 (one task): every tile's network levels from every tile's summary.
#[pyfunction]
pub(crate) fn flow_phase6<'py>(
    py: Python<'py>,
    l: Layout,
    summaries: Vec<Vec<u8>>,
) -> PyResult<Vec<Bound<'py, PyBytes>>> {
    single_phase(
        py,
        l,
        summaries,
        NetSummary::from_bytes,
        tiled::phase6,
        NetLevels::to_bytes,
    )
}

/// Phase 7 of tile `t`: `(strahler, watersheds, hand, network)`.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub(crate) fn flow_phase7<'py>(
    py: Python<'py>,
    l: Layout,
    t: usize,
    routed: Vec<u8>,
    inflow: Vec<u8>,
    net: Vec<u8>,
    input: Vec<u8>,
    channel_area: f64,
) -> PyResult<TileRasters<'py>> {
    let l = layout(l)?;
    let [_, _, w, h] = tile(&l, t)?;
    let z = halo(&l, t, &input)?;
    let (r, n) = py
        .detach(|| {
            let f = finished(&l, t, &routed, &inflow)?;
            let lv = NetLevels::from_bytes(&net, &l, t)?;
            let (r, n) = tiled::phase7(&l, t, &f, &lv, &z, channel_area)?;
            Ok::<_, relief_landscape::LandscapeError>((r, n.to_bytes(&l, t)))
        })
        .map_err(Failure::value)?;
    let (o, s) = r.to_f32(w, &z);
    Ok((
        array(py, w, h, o)?,
        array(py, w, h, s)?,
        array(py, w, h, r.hand)?,
        PyBytes::new(py, &n),
    ))
}

/// The channel network (GeoJSON text) and the figures (JSON text) from every tile's network.
#[pyfunction]
pub(crate) fn flow_assemble(
    py: Python<'_>,
    l: Layout,
    geo: Geo,
    networks: Vec<Vec<u8>>,
) -> PyResult<(String, String)> {
    let l = layout(l)?;
    let g = crate::convert::geo(&geo)?;
    py.detach(|| {
        let nets = networks
            .iter()
            .enumerate()
            .map(|(t, b)| TileNetwork::from_bytes(b, &l, t))
            .collect::<relief_landscape::Result<Vec<_>>>()?;
        let (gj, fig) = tiled::assemble(&l, g.as_ref(), &nets)?;
        Ok::<_, relief_landscape::LandscapeError>((
            gj.to_string(),
            serde_json::to_string(&fig).unwrap_or_default(),
        ))
    })
    .map_err(|e| Failure::value(e).into())
}

/// The masks settings of `relief.dask.masks` (JSON keyword arguments over the defaults).
fn mask_settings(json: &str) -> PyResult<MasksSettings> {
    let s: MasksSettings = crate::convert::settings(&MasksSettings::default(), json)?;
    s.check().map_err(Failure::value)?;
    Ok(s)
}

/// Checks the settings of `relief.dask.masks` (an error names the field), before any task.
#[pyfunction]
pub(crate) fn masks_check(settings: &str) -> PyResult<()> {
    mask_settings(settings).map(|_| ())
}

/// First pass of the map's mask scales over tile `t` (its input with the margin, f32 bytes).
#[pyfunction]
pub(crate) fn masks_counts<'py>(
    py: Python<'py>,
    l: Layout,
    t: usize,
    input: Vec<u8>,
) -> PyResult<Bound<'py, PyBytes>> {
    let l = layout(l)?;
    let z = halo(&l, t, &input)?;
    let c = py
        .detach(|| ScaleCounts::of_tile(&l, t, &z))
        .map_err(Failure::value)?;
    Ok(PyBytes::new(py, &c.to_bytes()))
}

/// One task: the bins and ranks of the map's statistics from every tile's counts.
#[pyfunction]
pub(crate) fn masks_targets<'py>(
    py: Python<'py>,
    settings: &str,
    counts: Vec<Vec<u8>>,
) -> PyResult<Bound<'py, PyBytes>> {
    let s = mask_settings(settings)?;
    let t = py
        .detach(|| {
            let mut all = ScaleCounts::empty();
            for b in &counts {
                all.merge(&ScaleCounts::from_bytes(b)?);
            }
            all.targets(&s)
        })
        .map_err(Failure::value)?;
    Ok(PyBytes::new(py, &t.to_bytes()))
}

/// Second pass of the map's mask scales over tile `t`.
#[pyfunction]
pub(crate) fn masks_fine<'py>(
    py: Python<'py>,
    l: Layout,
    t: usize,
    input: Vec<u8>,
    targets: Vec<u8>,
) -> PyResult<Bound<'py, PyBytes>> {
    let l = layout(l)?;
    let z = halo(&l, t, &input)?;
    let f = py
        .detach(|| {
            let targets = ScaleTargets::from_bytes(&targets)?;
            ScaleFine::of_tile(&l, t, &z, &targets)
        })
        .map_err(Failure::value)?;
    Ok(PyBytes::new(py, &f.to_bytes()))
}

/// One task: the map's height bands and curvature scale (`MaskScales` as JSON) from every
/// tile's second-pass counts.
#[pyfunction]
pub(crate) fn masks_scales(
    py: Python<'_>,
    targets: Vec<u8>,
    fine: Vec<Vec<u8>>,
) -> PyResult<String> {
    let scales = py
        .detach(|| {
            let targets = ScaleTargets::from_bytes(&targets)?;
            let mut all = ScaleFine::empty(&targets);
            for b in &fine {
                all.merge(&ScaleFine::from_bytes(b, &targets)?);
            }
            Ok::<_, relief_landscape::LandscapeError>(all.scales(&targets))
        })
        .map_err(Failure::value)?;
    serde_json::to_string(&scales).map_err(|e| Failure::value(e).into())
}

/// The masks of tile `t` from its input, its routed tile and inflow (phases 3 and 4), its
/// HAND (phase 7) and the map's scales: `(masks by name, splat weights (h, w * 4))`.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub(crate) fn masks_tile<'py>(
    py: Python<'py>,
    l: Layout,
    t: usize,
    input: Vec<u8>,
    routed: Vec<u8>,
    inflow: Vec<u8>,
    hand: numpy::PyReadonlyArray2<'py, f32>,
    settings: &str,
    scales: &str,
) -> PyResult<(Bound<'py, pyo3::types::PyDict>, Bound<'py, PyArray2<f32>>)> {
    let l = layout(l)?;
    let [_, _, w, h] = tile(&l, t)?;
    let z = halo(&l, t, &input)?;
    let s = mask_settings(settings)?;
    let scales: MaskScales = serde_json::from_str(scales).map_err(Failure::value)?;
    let hand: Vec<f32> = hand.as_array().iter().copied().collect();
    let (masks, splat) = py
        .detach(|| {
            let f = finished(&l, t, &routed, &inflow)?;
            mask_tiles::tile_masks(&s, &l, t, &z, &f.cells, hand, &scales)
        })
        .map_err(Failure::value)?;
    let d = pyo3::types::PyDict::new(py);
    for m in masks {
        d.set_item(m.kind.name(), array(py, w, h, m.values)?)?;
    }
    let splat = ndarray::Array2::from_shape_vec((h, w * 4), splat.into_flattened())
        .map_err(Failure::value)?;
    Ok((d, PyArray2::from_owned_array(py, splat)))
}
