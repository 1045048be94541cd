//! Plans of windowed runs (`relief.dask`): everything a window of an amplified or refined
//! terrain needs, computed once, from which each window is computed alone and equal bit for
//! bit to the same window of the whole run (relief-dictionary-learning's [`LastStep`], relief-
//! wavelet-lod's [`Refiner::render_window`]). Plans pickle, so a Dask scheduler sends one to
//! its workers once.

use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::IntoPyObjectExt;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use relief_dictionary_learning::{LastStep, prepare_last_step};
use relief_heightfield::Heightfield;
use relief_wavelet_lod::{RefineSettings, Refiner};

use crate::convert::{self, Geo, NO_GEO, Transform};
use crate::detail::{
    amplify_settings, complete_array, refine_settings, refined_window, stop_or, window,
};
use crate::run::{Failure, run};

/// What `__reduce__` returns: the unpickling function and its arguments.
type Reduced<'py> = (Bound<'py, PyAny>, Bound<'py, PyAny>);

/// The `__reduce__` value that unpickles by calling `relief._relief.<function>(*args)`.
fn reduced<'py>(
    py: Python<'py>,
    function: &str,
    args: impl IntoPyObject<'py>,
) -> PyResult<Reduced<'py>> {
    let f = py.import("relief._relief")?.getattr(function)?;
    Ok((f, args.into_bound_py_any(py)?))
}

/// The analysis of `input` for windowed refinement (the GIL released), with `input` back.
fn analyse(
    py: Python<'_>,
    input: Heightfield,
    s: &RefineSettings,
) -> PyResult<(Refiner, Heightfield)> {
    let (refiner, input) = py.detach(move || {
        Refiner::new(&input, s)
            .map(|r| (r, input))
            .map_err(Failure::value)
    })?;
    Ok((refiner, input))
}

/// The last x4 step of an amplification: any window of its output.
#[pyclass(module = "relief._relief", frozen)]
#[derive(Debug)]
pub(crate) struct AmplifyPlan {
    last: LastStep,
    /// The keyword arguments the settings came from, and the paper switch (for pickling).
    settings_json: String,
    paper: bool,
    /// Geotransform of the whole amplified output.
    transform: Option<Transform>,
}

#[pymethods]
impl AmplifyPlan {
    /// `(width, height)` of the amplified output.
    fn output_size(&self) -> (usize, usize) {
        self.last.output_size()
    }

    /// The geotransform `[x0, dx, rx, y0, ry, dy]` of the whole output (GDAL order), if the
    /// input had one.
    #[getter]
    fn transform(&self) -> Option<Transform> {
        self.transform
    }

    /// The window `(x, y, width, height)` of the output, computed alone (the GIL released).
    fn window<'py>(
        &self,
        py: Python<'py>,
        x: usize,
        y: usize,
        width: usize,
        height: usize,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let win = window((x, y, width, height));
        let hf = py
            .detach(|| self.last.render_window(win))
            .map_err(Failure::value)?;
        Ok(convert::array(py, hf))
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Reduced<'py>> {
        let bytes = py.detach(|| self.last.to_bytes()).map_err(Failure::value)?;
        let args = (
            PyBytes::new(py, &bytes),
            self.settings_json.clone(),
            self.paper,
            self.transform,
        );
        reduced(py, "_amplify_plan", args)
    }
}

/// Unpickles an [`AmplifyPlan`].
#[pyfunction]
pub(crate) fn _amplify_plan(
    py: Python<'_>,
    bytes: &[u8],
    settings_json: String,
    paper: bool,
    transform: Option<Transform>,
) -> PyResult<AmplifyPlan> {
    let settings = amplify_settings(&settings_json, paper)?;
    let last = py
        .detach(|| LastStep::from_bytes(bytes, &settings))
        .map_err(Failure::value)?;
    Ok(AmplifyPlan {
        last,
        settings_json,
        paper,
        transform,
    })
}

/// Runs every amplification step but the last: see `relief.dask.amplify`.
#[pyfunction]
#[pyo3(signature = (coarse, cell_size, geo, exemplar, exemplar_cell_size, settings, paper, progress))]
pub(crate) fn amplify_plan(
    py: Python<'_>,
    coarse: PyReadonlyArray2<'_, f32>,
    cell_size: (f64, f64),
    geo: Geo,
    exemplar: PyReadonlyArray2<'_, f32>,
    exemplar_cell_size: (f64, f64),
    settings: String,
    paper: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<AmplifyPlan> {
    let s = amplify_settings(&settings, paper)?;
    let coarse = complete_array(&coarse, cell_size, &geo, "coarse input")?;
    let exemplar = complete_array(&exemplar, exemplar_cell_size, &NO_GEO, "exemplar")?;
    let steps = s.steps;
    let last = run(py, progress, move |p| {
        let (last, _) = prepare_last_step(&coarse, &exemplar, &s, p).map_err(|e| stop_or(e, p))?;
        Ok(last)
    })?;
    // The georeference of the amplified output, as `relief amplify` writes it.
    let f = 1.0 / 4f64.powi(steps as i32);
    let transform = convert::geo(&geo)?
        .map(|g| g.window(0.0, 0.0, f, f))
        .and_then(|g| g.geotransform);
    Ok(AmplifyPlan {
        last,
        settings_json: settings,
        paper,
        transform,
    })
}

/// The analysis of a refinement: any window of the refined terrain.
#[pyclass(module = "relief._relief", frozen)]
#[derive(Debug)]
pub(crate) struct RefinePlan {
    refiner: Refiner,
    input: Heightfield,
    settings_json: String,
    paper: bool,
}

#[pymethods]
impl RefinePlan {
    /// `(width, height)` of the refined terrain.
    fn output_size(&self) -> (usize, usize) {
        self.refiner.output_size()
    }

    /// The geotransform of the whole refined terrain (GDAL order), if the input had one.
    #[getter]
    fn transform(&self) -> PyResult<Option<Transform>> {
        let corner = self
            .refiner
            .render_window(0, 0, 1, 1)
            .map_err(Failure::value)?;
        Ok(corner.georef().and_then(|g| g.geotransform))
    }

    /// The window `(x, y, width, height)` of the refined terrain, computed alone.
    fn window<'py>(
        &self,
        py: Python<'py>,
        x: usize,
        y: usize,
        width: usize,
        height: usize,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let hf = py.detach(|| refined_window(&self.refiner, (x, y, width, height)))?;
        Ok(convert::array(py, hf))
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Reduced<'py>> {
        // The samples as bytes: a pickled numpy array may come back at an unaligned address.
        let bytes = relief_heightfield::bytes::f32_to_le_bytes(self.input.as_slice());
        let geo: Geo = (None, None, convert::georef_json(&self.input));
        let args = (
            PyBytes::new(py, &bytes),
            (self.input.width(), self.input.height()),
            self.input.cell_size(),
            geo,
            self.settings_json.clone(),
            self.paper,
        );
        reduced(py, "_refine_plan", args)
    }
}

/// Unpickles a [`RefinePlan`].
#[pyfunction]
pub(crate) fn _refine_plan(
    py: Python<'_>,
    bytes: &[u8],
    size: (usize, usize),
    cell_size: (f64, f64),
    geo: Geo,
    settings_json: String,
    paper: bool,
) -> PyResult<RefinePlan> {
    let s = refine_settings(&settings_json, paper)?;
    let data = relief_heightfield::bytes::f32_from_le_bytes(bytes);
    let input = Heightfield::new(size.0, size.1, data, cell_size.0, cell_size.1)
        .map_err(Failure::value)?
        .with_georef(convert::geo(&geo)?);
    let (refiner, input) = analyse(py, input, &s)?;
    Ok(RefinePlan {
        refiner,
        input,
        settings_json,
        paper,
    })
}

/// Analyses a terrain for windowed refinement: see `relief.dask.refine`.
#[pyfunction]
#[pyo3(signature = (input, cell_size, geo, settings, paper))]
pub(crate) fn refine_plan(
    py: Python<'_>,
    input: PyReadonlyArray2<'_, f32>,
    cell_size: (f64, f64),
    geo: Geo,
    settings: String,
    paper: bool,
) -> PyResult<RefinePlan> {
    let s: RefineSettings = refine_settings(&settings, paper)?;
    let input = complete_array(&input, cell_size, &geo, "input")?;
    let (refiner, input) = analyse(py, input, &s)?;
    Ok(RefinePlan {
        refiner,
        input,
        settings_json: settings,
        paper,
    })
}
