//! `relief._relief`, the native part of the Python package `relief` (PyO3, the stable ABI of
//! CPython 3.9+). The jobs take numpy arrays and their settings as the JSON of the keyword
//! arguments (the library's serde settings types: the same names, defaults, checks and
//! messages), run on a thread of their own with the GIL released ([`run`]), and return numpy
//! arrays without a copy. The pure-Python part (`python/relief/`) holds the keyword-argument
//! signatures, rasterio's `Affine`, the xarray accessor and `relief.dask`.
//!
//! The crate is linked only as the extension module; its tests are the pytest suite under
//! `tests/`, run by `scripts/python-tests`.

mod convert;
mod detail;
mod jobs;
mod run;
mod tiled;
mod windows;

use numpy::PyReadonlyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::Transform;
use crate::run::Failure;

/// Reads any raster relief-io knows: a dict with `array` (float32, voids NaN), `cell_size`
/// (metres), `transform` (GDAL order, or None), `crs` (WKT or name, or None), `nodata`,
/// `format`, `dtype`.
#[pyfunction]
#[pyo3(signature = (path, max_cells=None))]
fn read<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
    max_cells: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut opts = relief_io::ReadOptions::default();
    if let Some(n) = max_cells {
        opts.max_cells = n;
    }
    let r = py
        .detach(|| relief_io::read(&path, &opts))
        .map_err(Failure::io)?;
    let d = PyDict::new(py);
    let g = r.heightfield.georef().cloned();
    d.set_item("cell_size", r.heightfield.cell_size())?;
    d.set_item("transform", g.as_ref().and_then(|g| g.geotransform))?;
    d.set_item("crs", g.as_ref().and_then(convert::crs_text))?;
    d.set_item("georef", convert::georef_json(&r.heightfield))?;
    d.set_item("nodata", r.nodata)?;
    d.set_item("format", format!("{:?}", r.format))?;
    d.set_item("dtype", r.dtype)?;
    d.set_item("array", convert::array(py, r.heightfield))?;
    Ok(d)
}

/// Writes a float32 array (format from the extension) with its cell size and georeference.
#[pyfunction]
#[pyo3(signature = (path, array, cell_size, geo))]
fn write(
    py: Python<'_>,
    path: std::path::PathBuf,
    array: PyReadonlyArray2<'_, f32>,
    cell_size: (f64, f64),
    geo: convert::Geo,
) -> PyResult<()> {
    let hf = convert::heightfield(&array, cell_size, &geo)?;
    py.detach(|| relief_io::write(&path, &hf, &relief_io::WriteOptions::default()))
        .map_err(Failure::io)?;
    Ok(())
}

/// Ground cell size `(x, y)` in metres of a grid `height` rows high with geotransform
/// `transform` (GDAL order) in `crs`, as relief-io derives it for a GeoTIFF (geographic grids
/// at the centre latitude, Web Mercator scaled by cos(latitude), other projections as metres).
#[pyfunction]
#[pyo3(signature = (transform, crs, height))]
fn ground_cell_size(
    transform: Transform,
    crs: Option<String>,
    height: usize,
) -> Option<(f64, f64)> {
    let g = convert::georef(Some(transform), crs.as_deref()).ok()??;
    relief_io::crs::ground_cell_size(&g, height)
}

/// The default settings of a job as JSON (`amplify`, `amplify_paper`, `synthesize`, `refine`,
/// `refine_paper`, `quilt`, `volume`, `flow`, `erode`, `masks`): the library's `Default`.
#[pyfunction]
fn defaults(job: &str) -> PyResult<String> {
    use convert::defaults_json as j;
    let s = match job {
        "amplify" => j(&relief_dictionary_learning::AmplifySettings::default()),
        "amplify_paper" => j(&relief_dictionary_learning::AmplifySettings::paper()),
        "synthesize" => j(&relief_dictionary_learning::SynthesisSettings::default()),
        "refine" => j(&relief_wavelet_lod::RefineSettings::default()),
        "refine_paper" => j(&relief_wavelet_lod::RefineSettings::paper()),
        "quilt" => j(&relief_patch_synth::QuiltJob::default()),
        "volume" => j(&relief_implicit_volume::VolumeJob::default()),
        "flow" => j(&relief_landscape::flow::job::FlowSettings::default()),
        "erode" => j(&relief_landscape::erode::job::ErodeSettings::default()),
        "masks" => j(&relief_landscape::masks::MasksSettings::default()),
        other => Err(Failure::Value(format!("no job named {other:?}"))),
    }?;
    Ok(s)
}

/// The module.
#[pymodule]
fn _relief(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(write, m)?)?;
    m.add_function(wrap_pyfunction!(defaults, m)?)?;
    m.add_function(wrap_pyfunction!(ground_cell_size, m)?)?;
    m.add_function(wrap_pyfunction!(run::last_run_seconds, m)?)?;
    m.add_function(wrap_pyfunction!(detail::amplify, m)?)?;
    m.add_function(wrap_pyfunction!(detail::synthesize, m)?)?;
    m.add_function(wrap_pyfunction!(detail::refine, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::quilt, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::volume, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::flow, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::erode, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::masks, m)?)?;
    m.add_function(wrap_pyfunction!(windows::amplify_plan, m)?)?;
    m.add_function(wrap_pyfunction!(windows::_amplify_plan, m)?)?;
    m.add_function(wrap_pyfunction!(windows::refine_plan, m)?)?;
    m.add_function(wrap_pyfunction!(windows::_refine_plan, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::flow_tiles, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::flow_phase1, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::flow_phase2, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::flow_phase3, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::flow_phase4, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::flow_phase5, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::flow_phase6, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::flow_phase7, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::flow_assemble, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::masks_check, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::masks_counts, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::masks_targets, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::masks_fine, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::masks_scales, m)?)?;
    m.add_function(wrap_pyfunction!(tiled::masks_tile, m)?)?;
    m.add_class::<windows::AmplifyPlan>()?;
    m.add_class::<windows::RefinePlan>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
