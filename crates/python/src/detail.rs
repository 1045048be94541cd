//! The detail jobs: `amplify` and `synthesize` (relief-dictionary-learning, rasterised by
//! relief-sparse-core) and `refine` (relief-wavelet-lod), called as `relief amplify`,
//! `relief synthesize` and `relief refine` call them, with the same landform pass after them
//! (relief-landscape; on by default, off in the paper modes, skipped for a window).

use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use relief_dictionary_learning::{
    AmplifySettings, SynthesisSettings, amplify_with_figures, synthesize_with_strokes,
};
use relief_heightfield::{Heightfield, Progress, Window};
use relief_landscape::grow::Strokes;
use relief_landscape::landform::{LandformSettings, finish_until};
use relief_sparse_core::RasterSettings;
use relief_wavelet_lod::{RefineSettings, Refiner};

use crate::convert::{self, Geo, NO_GEO};
use crate::run::{Failure, Reporter, run};

/// A window `(x, y, width, height)` in output cells.
pub(crate) type WindowTuple = (usize, usize, usize, usize);

/// What a detail job returns: the raster, its georeference (JSON, see [`Geo`]) and the
/// library's notes.
type Out<'py> = (Bound<'py, PyArray2<f32>>, Option<String>, Vec<String>);

/// The library window of a tuple (width and height checked by the library).
pub(crate) fn window(w: WindowTuple) -> Window {
    Window::new(w.0, w.1, w.2, w.3)
}

/// The landform pass of the CLI's `--landform` over `fine`, the detail of `coarse`; its note
/// goes to `notes`.
fn landform(
    fine: Heightfield,
    coarse: &Heightfield,
    p: &Reporter,
    notes: &mut Vec<String>,
) -> Result<Heightfield, Failure> {
    p.begin("landform pass", 0);
    let (out, r) = finish_until(&fine, coarse, &LandformSettings::default(), &|| {
        p.stop_flag()
    })
    .map_err(|e| stop_or(e, p))?;
    let note = format!(
        "landform pass: {} depressions breached or filled ({} cells lowered, {} raised), \
         consistency with the input {:.3} m RMS",
        r.pits_before, r.breached_cells, r.filled_cells, r.consistency_rms_m
    );
    notes.push(note);
    Ok(out)
}

/// A library error as a failure, or [`Failure::Stopped`] when the run was asked to stop.
pub(crate) fn stop_or(e: impl std::fmt::Display, p: &Reporter) -> Failure {
    if p.stop_flag() {
        Failure::Stopped
    } else {
        Failure::value(e)
    }
}

fn output(py: Python<'_>, hf: Heightfield, notes: Vec<String>) -> Out<'_> {
    let t = convert::georef_json(&hf);
    (convert::array(py, hf), t, notes)
}

/// The checked amplify settings of keyword arguments over the default (or paper) settings.
pub(crate) fn amplify_settings(json: &str, paper: bool) -> Result<AmplifySettings, Failure> {
    let base = if paper {
        AmplifySettings::paper()
    } else {
        AmplifySettings::default()
    };
    let s = convert::settings(&base, json)?;
    s.check().map_err(Failure::value)?;
    Ok(s)
}

/// A void-free heightfield or the library's message naming `what`.
pub(crate) fn complete(hf: Heightfield, what: &str) -> Result<Heightfield, Failure> {
    hf.require_complete()
        .map_err(|e| Failure::Value(format!("cannot use the {what}: {e}")))?;
    Ok(hf)
}

/// The heightfield of an input array, void-free, or the library's message naming `what`.
pub(crate) fn complete_array(
    array: &PyReadonlyArray2<'_, f32>,
    cell: (f64, f64),
    geo: &Geo,
    what: &str,
) -> Result<Heightfield, Failure> {
    complete(convert::heightfield(array, cell, geo)?, what)
}

/// The rasterisation of a whole model, or of `window` of it.
fn raster_settings(window: Option<WindowTuple>) -> RasterSettings {
    RasterSettings {
        scale: 1.0,
        window: window.map(self::window),
    }
}

/// The window `(x, y, w, h)` of a refinement, or an error naming the refined grid's size.
pub(crate) fn refined_window(
    refiner: &Refiner,
    (x, y, w, h): WindowTuple,
) -> Result<Heightfield, Failure> {
    let (ow, oh) = refiner.output_size();
    refiner.render_window(x, y, w, h).map_err(|e| {
        Failure::Value(format!(
            "invalid window (the refined grid is {ow} x {oh}): {e}"
        ))
    })
}

/// `relief amplify`: see `relief.amplify`.
#[pyfunction]
#[pyo3(signature = (coarse, cell_size, geo, exemplar, exemplar_cell_size, settings, paper, landform, window, progress))]
#[allow(clippy::type_complexity)]
pub(crate) fn amplify<'py>(
    py: Python<'py>,
    coarse: PyReadonlyArray2<'py, f32>,
    cell_size: (f64, f64),
    geo: Geo,
    exemplar: PyReadonlyArray2<'py, f32>,
    exemplar_cell_size: (f64, f64),
    settings: &str,
    paper: bool,
    landform: Option<bool>,
    window: Option<WindowTuple>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Out<'py>> {
    let settings = amplify_settings(settings, paper)?;
    let coarse = complete_array(&coarse, cell_size, &geo, "coarse input")?;
    let exemplar = complete_array(&exemplar, exemplar_cell_size, &NO_GEO, "exemplar")?;
    let finish = landform.unwrap_or(!paper) && window.is_none();
    let raster = raster_settings(window);
    let (hf, notes) = run(py, progress, move |p| {
        let (sct, figures) =
            amplify_with_figures(&coarse, &exemplar, &settings, p).map_err(|e| stop_or(e, p))?;
        let mut notes: Vec<String> = figures.steps.iter().map(|s| s.note.clone()).collect();
        let hf = sct
            .rasterize_with_progress(&raster, p)
            .map_err(|e| stop_or(e, p))?;
        let hf = if finish {
            self::landform(hf, &coarse, p, &mut notes)?
        } else {
            hf
        };
        Ok((hf, notes))
    })?;
    Ok(output(py, hf, notes))
}

/// `relief synthesize`: see `relief.synthesize`.
#[pyfunction]
#[pyo3(signature = (sketch, cell_size, exemplar, exemplar_cell_size, settings, paper, window, progress, ridges=None, rivers=None))]
pub(crate) fn synthesize<'py>(
    py: Python<'py>,
    sketch: PyReadonlyArray2<'py, f32>,
    cell_size: (f64, f64),
    exemplar: PyReadonlyArray2<'py, f32>,
    exemplar_cell_size: (f64, f64),
    settings: &str,
    paper: bool,
    window: Option<WindowTuple>,
    progress: Option<Py<PyAny>>,
    ridges: Option<PyReadonlyArray2<'py, f32>>,
    rivers: Option<PyReadonlyArray2<'py, f32>>,
) -> PyResult<Out<'py>> {
    let mut base = SynthesisSettings::default();
    if paper {
        // `relief synthesize --paper`: the whole atom scaled by the code, no structure step,
        // no landscape evolution.
        base.amplify.normalize_detail = false;
        base.amplify.exemplar_detail = false;
        base.structure.radius = 0.0;
        base.grow = None;
    }
    let settings: SynthesisSettings = convert::settings(&base, settings)?;
    settings.amplify.check().map_err(Failure::value)?;
    settings.structure.check().map_err(Failure::value)?;
    let sketch = complete_array(&sketch, cell_size, &NO_GEO, "sketch")?;
    let exemplar = complete_array(&exemplar, exemplar_cell_size, &NO_GEO, "exemplar")?;
    let layer = |a: &Option<PyReadonlyArray2<'py, f32>>, name: &str| {
        a.as_ref()
            .map(|a| complete_array(a, (1.0, 1.0), &NO_GEO, name))
            .transpose()
    };
    let strokes = Strokes {
        ridges: layer(&ridges, "ridges")?,
        rivers: layer(&rivers, "rivers")?,
    };
    strokes
        .check(sketch.width(), sketch.height())
        .map_err(Failure::value)?;
    let raster = raster_settings(window);
    let (hf, notes) = run(py, progress, move |p| {
        let (sct, figures) = synthesize_with_strokes(&sketch, &strokes, &exemplar, &settings, p)
            .map_err(|e| stop_or(e, p))?;
        let mut notes: Vec<String> = figures.structure.iter().map(|s| s.note.clone()).collect();
        notes.extend(figures.steps.iter().map(|s| s.note.clone()));
        let hf = sct
            .rasterize_with_progress(&raster, p)
            .map_err(|e| stop_or(e, p))?;
        // The landform pass keeps the result on the grown network (its box averages).
        let hf = match (&figures.grown, raster.window) {
            (Some(grown), None) => self::landform(hf, grown, p, &mut notes)?,
            _ => hf,
        };
        Ok((hf, notes))
    })?;
    Ok(output(py, hf, notes))
}

/// The checked refine settings of keyword arguments over the default (or paper) settings.
pub(crate) fn refine_settings(json: &str, paper: bool) -> Result<RefineSettings, Failure> {
    let base = if paper {
        RefineSettings::paper()
    } else {
        RefineSettings::default()
    };
    let s: RefineSettings = convert::settings(&base, json)?;
    s.check().map_err(Failure::value)?;
    Ok(s)
}

/// `relief refine`: see `relief.refine`.
#[pyfunction]
#[pyo3(signature = (input, cell_size, geo, settings, paper, landform, window, progress))]
pub(crate) fn refine<'py>(
    py: Python<'py>,
    input: PyReadonlyArray2<'py, f32>,
    cell_size: (f64, f64),
    geo: Geo,
    settings: &str,
    paper: bool,
    landform: Option<bool>,
    window: Option<WindowTuple>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Out<'py>> {
    let settings = refine_settings(settings, paper)?;
    let hf = complete_array(&input, cell_size, &geo, "input")?;
    let finish = landform.unwrap_or(!paper) && window.is_none();
    let (out, notes) = run(py, progress, move |p| {
        p.begin("wavelet analysis", 0);
        let refiner = Refiner::new(&hf, &settings).map_err(|e| stop_or(e, p))?;
        let mut notes: Vec<String> = refiner
            .notes()
            .iter()
            .map(|n| format!("note: {n}"))
            .collect();
        let out = match window {
            Some(w) => {
                p.begin("synthesising the window", 0);
                refined_window(&refiner, w)?
            }
            None => refiner.render(p).map_err(|e| stop_or(e, p))?,
        };
        let out = if finish {
            self::landform(out, &hf, p, &mut notes)?
        } else {
            out
        };
        Ok((out, notes))
    })?;
    Ok(output(py, out, notes))
}
