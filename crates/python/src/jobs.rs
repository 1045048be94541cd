//! The other jobs: `quilt` (relief-patch-synth), `volume` (relief-implicit-volume) and the
//! drainage jobs `flow`, `erode`, `masks` (relief-landscape), each with its serde job type
//! from keyword arguments and the run the CLI command makes.

use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use relief_heightfield::{Heightfield, Progress};
use relief_implicit_volume::VolumeJob;
use relief_landscape::erode::job::ErodeSettings;
use relief_landscape::flow::job::FlowSettings;
use relief_landscape::landform::{LandformSettings, finish_until};
use relief_landscape::masks::MasksSettings;
use relief_patch_synth::{JobInputs, QuiltJob};

use crate::convert::{self, Geo, NO_GEO};
use crate::detail::stop_or;
use crate::run::{Failure, run};

/// A raster argument: the array and its cell size.
type Grid<'py> = (PyReadonlyArray2<'py, f32>, (f64, f64));

fn grid(g: &Grid<'_>, geo: &Geo) -> Result<Heightfield, Failure> {
    convert::heightfield(&g.0, g.1, geo)
}

/// `relief quilt`: see `relief.quilt`.
#[pyfunction]
#[pyo3(signature = (exemplars, guide, categories, exemplar_regions, settings, landform, progress))]
pub(crate) fn quilt<'py>(
    py: Python<'py>,
    exemplars: Vec<Grid<'py>>,
    guide: Option<Grid<'py>>,
    categories: Option<Grid<'py>>,
    exemplar_regions: Vec<Grid<'py>>,
    settings: &str,
    landform: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let job: QuiltJob = convert::settings(&QuiltJob::default(), settings)?;
    job.check().map_err(Failure::value)?;
    let all = |v: &[Grid<'py>]| {
        v.iter()
            .map(|g| grid(g, &NO_GEO))
            .collect::<Result<Vec<_>, _>>()
    };
    let inputs = JobInputs {
        exemplars: all(&exemplars)?,
        guide: guide.as_ref().map(|g| grid(g, &NO_GEO)).transpose()?,
        categories: categories.as_ref().map(|g| grid(g, &NO_GEO)).transpose()?,
        exemplar_regions: all(&exemplar_regions)?,
    };
    let hf = run(py, progress, move |p| {
        let out = job.run(inputs, p).map_err(|e| stop_or(e, p))?;
        let hf = out.synthesis.heightfield;
        if !landform {
            return Ok(hf);
        }
        // `relief quilt`'s pass: the quilt's own box averages over blocks of `k` cells, the
        // largest divisor of both sides up to a quarter patch (none when only 1 divides them).
        let (w, h) = (hf.width(), hf.height());
        let Some(k) = (2..=(job.settings.patch_size / 4).max(2))
            .rev()
            .find(|k| w.is_multiple_of(*k) && h.is_multiple_of(*k))
        else {
            return Ok(hf);
        };
        let coarse = hf.downsample_box(k).map_err(Failure::value)?;
        p.begin("landform pass", 0);
        let (hf, _) = finish_until(&hf, &coarse, &LandformSettings::default(), &|| {
            p.stop_flag()
        })
        .map_err(|e| stop_or(e, p))?;
        Ok(hf)
    })?;
    Ok(convert::array(py, hf))
}

/// A mesh as numpy arrays: vertices `(n, 3)` float32 in metres (Z up), faces `(m, 3)` uint32.
type MeshArrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<u32>>,
    Bound<'py, PyArray2<u8>>,
);

/// `relief volume --mesh`: see `relief.volume`.
#[pyfunction]
#[pyo3(signature = (dem, settings, progress))]
pub(crate) fn volume<'py>(
    py: Python<'py>,
    dem: Grid<'py>,
    settings: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<MeshArrays<'py>> {
    let mut job: VolumeJob = convert::settings(&VolumeJob::default(), settings)?;
    // The mesh is what this call returns; images are `relief volume`'s files.
    job.mesh = true;
    job.render = false;
    job.closeups = false;
    job.section = false;
    job.check().map_err(Failure::value)?;
    let hf = crate::detail::complete(grid(&dem, &NO_GEO)?, "DEM")?;
    let mesh = run(py, progress, move |p| {
        let built = job.build(&hf, p).map_err(|e| stop_or(e, p))?;
        let out = job.finish(built, p).map_err(|e| stop_or(e, p))?;
        out.mesh
            .ok_or_else(|| Failure::Value("the volume job made no mesh".into()))
    })?;
    let n = mesh.positions.len();
    let m = mesh.triangles.len();
    let v = ndarray::Array2::from_shape_vec((n, 3), mesh.positions.into_flattened())
        .map_err(Failure::value)?;
    let f = ndarray::Array2::from_shape_vec((m, 3), mesh.triangles.into_flattened())
        .map_err(Failure::value)?;
    let c = ndarray::Array2::from_shape_vec((mesh.colours.len(), 4), mesh.colours.into_flattened())
        .map_err(Failure::value)?;
    Ok((
        PyArray2::from_owned_array(py, v),
        PyArray2::from_owned_array(py, f),
        PyArray2::from_owned_array(py, c),
    ))
}

/// A dict of named rasters.
fn rasters<'py>(py: Python<'py>, items: Vec<(&str, Heightfield)>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, hf) in items {
        d.set_item(k, convert::array(py, hf))?;
    }
    Ok(d)
}

/// `relief flow`: see `relief.flow`.
#[pyfunction]
#[pyo3(signature = (dem, geo, settings, progress))]
pub(crate) fn flow<'py>(
    py: Python<'py>,
    dem: Grid<'py>,
    geo: Geo,
    settings: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<(Bound<'py, PyDict>, String)> {
    let s: FlowSettings = convert::settings(&FlowSettings::default(), settings)?;
    s.check().map_err(Failure::value)?;
    let hf = grid(&dem, &geo)?;
    let out = run(py, progress, move |p| {
        s.run(&hf, p).map_err(|e| stop_or(e, p))
    })?;
    let channels = out.channels.to_string();
    let d = rasters(
        py,
        vec![
            ("conditioned", out.conditioned),
            ("direction", out.direction),
            ("area", out.area),
            ("strahler", out.strahler),
            ("watersheds", out.watersheds),
            ("hand", out.hand),
        ],
    )?;
    Ok((d, channels))
}

/// `relief erode`: see `relief.erode`.
#[pyfunction]
#[pyo3(signature = (dem, uplift, settings, progress))]
pub(crate) fn erode<'py>(
    py: Python<'py>,
    dem: Grid<'py>,
    uplift: Option<Grid<'py>>,
    settings: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let s: ErodeSettings = convert::settings(&ErodeSettings::default(), settings)?;
    s.check().map_err(Failure::value)?;
    let hf = grid(&dem, &NO_GEO)?;
    let uplift = uplift.as_ref().map(|u| grid(u, &NO_GEO)).transpose()?;
    let out = run(py, progress, move |p| {
        s.run(&hf, uplift.as_ref(), p, &|| p.stop_flag())
            .map_err(|e| stop_or(e, p))
    })?;
    rasters(
        py,
        vec![
            ("terrain", out.terrain),
            ("erosion", out.erosion),
            ("deposition", out.deposition),
        ],
    )
}

/// `relief masks`: see `relief.masks`.
#[pyfunction]
#[pyo3(signature = (dem, erosion, deposition, settings, progress))]
pub(crate) fn masks<'py>(
    py: Python<'py>,
    dem: Grid<'py>,
    erosion: Option<Grid<'py>>,
    deposition: Option<Grid<'py>>,
    settings: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyArray2<f32>>)> {
    let s: MasksSettings = convert::settings(&MasksSettings::default(), settings)?;
    s.check().map_err(Failure::value)?;
    let hf = grid(&dem, &NO_GEO)?;
    let (w, h) = (hf.width(), hf.height());
    let erosion = erosion.as_ref().map(|g| grid(g, &NO_GEO)).transpose()?;
    let deposition = deposition.as_ref().map(|g| grid(g, &NO_GEO)).transpose()?;
    let out = run(py, progress, move |p| {
        s.run(&hf, erosion.as_ref(), deposition.as_ref(), p)
            .map_err(|e| stop_or(e, p))
    })?;
    let d = PyDict::new(py);
    for (kind, r) in out.rasters {
        d.set_item(kind.name(), convert::array(py, r))?;
    }
    // The splat map: `(height, width * 4)` weights reshaped to `(height, width, 4)` in Python.
    let splat = ndarray::Array2::from_shape_vec((h, w * 4), out.splat.into_flattened())
        .map_err(Failure::value)?;
    Ok((d, PyArray2::from_owned_array(py, splat)))
}
