//! Conversions between Python values and the library's: numpy arrays and [`Heightfield`]s,
//! GDAL geotransforms and CRS text and [`GeoRef`]s, keyword arguments (as JSON) and the
//! library's serde settings types.

use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use relief_heightfield::{GeoRef, Heightfield};
use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

use crate::run::Failure;

/// A GDAL geotransform `[x0, dx, rx, y0, ry, dy]` (the Python side converts rasterio's
/// `Affine`).
pub(crate) type Transform = [f64; 6];

/// GeoTIFF keys: GTModelTypeGeoKey, GTRasterTypeGeoKey, GeographicTypeGeoKey,
/// ProjectedCSTypeGeoKey; model types and RasterPixelIsArea.
const GT_MODEL_TYPE: u16 = 1024;
const GT_RASTER_TYPE: u16 = 1025;
const GEOGRAPHIC_TYPE: u16 = 2048;
const PROJECTED_CS_TYPE: u16 = 3072;
const MODEL_PROJECTED: u16 = 1;
const MODEL_GEOGRAPHIC: u16 = 2;
const PIXEL_IS_AREA: u16 = 1;

/// A georeference from Python: the geotransform, the CRS text, and the library's own
/// georeference as JSON when the raster came from relief (its raw GeoTIFF tags, written back
/// verbatim as `relief` does; used while its transform is the one given).
pub(crate) type Geo = (Option<Transform>, Option<String>, Option<String>);

/// The georeference of a [`Geo`].
pub(crate) fn geo(g: &Geo) -> Result<Option<GeoRef>, Failure> {
    let (t, crs, json) = g;
    if let Some(j) = json {
        let r: GeoRef = serde_json::from_str(j).map_err(Failure::value)?;
        if t.is_none() || r.geotransform == *t {
            return Ok(Some(r));
        }
    }
    georef(*t, crs.as_deref()).map_err(Failure::value)
}

/// The library's georeference of a heightfield as JSON (see [`Geo`]).
pub(crate) fn georef_json(hf: &Heightfield) -> Option<String> {
    hf.georef().and_then(|g| serde_json::to_string(g).ok())
}

/// The heightfield of a 2-D float32 array (one copy: the library owns its grids) with cell size
/// `cell` and the georeference `geo`.
pub(crate) fn heightfield(
    array: &PyReadonlyArray2<'_, f32>,
    cell: (f64, f64),
    geo: &Geo,
) -> Result<Heightfield, Failure> {
    let g = self::geo(geo)?;
    let hf = Heightfield::from_array(array.as_array().to_owned(), cell.0, cell.1)
        .map_err(Failure::value)?;
    Ok(hf.with_georef(g))
}

/// No georeference.
pub(crate) const NO_GEO: Geo = (None, None, None);

/// The numpy array of a heightfield's grid (moved, not copied).
pub(crate) fn array(py: Python<'_>, hf: Heightfield) -> Bound<'_, PyArray2<f32>> {
    PyArray2::from_owned_array(py, hf.into_array())
}

/// The georeference of a geotransform and a CRS (`EPSG:<code>`, OGC/ESRI WKT 1, or a name):
/// the affine transform, the CRS name and the GeoTIFF keys a GeoTIFF written from it stores:
/// those naming the EPSG code, or for WKT 1 without one the user-defined keys of
/// [`relief_io::wkt_keys`]. A WKT those cannot express is an error naming why (the CRS would
/// otherwise be lost from the written file).
pub(crate) fn georef(
    transform: Option<Transform>,
    crs: Option<&str>,
) -> Result<Option<GeoRef>, String> {
    if transform.is_none() && crs.is_none() {
        return Ok(None);
    }
    let name = crs.map(|c| {
        let c = c.trim();
        relief_io::crs::crs_of_prj(c).unwrap_or_else(|| c.to_string())
    });
    let mut g = GeoRef {
        geotransform: transform,
        crs: name,
        ..GeoRef::default()
    };
    if let Some(code) = relief_io::crs::epsg_code(&g).and_then(|c| u16::try_from(c).ok()) {
        let geographic = relief_io::crs::epsg_wkt(code.into())
            .is_some_and(|w| w.trim_start().starts_with("GEOGCS["));
        let (model, key) = if geographic {
            (MODEL_GEOGRAPHIC, GEOGRAPHIC_TYPE)
        } else {
            (MODEL_PROJECTED, PROJECTED_CS_TYPE)
        };
        g.geo_key_directory = Some(vec![
            1,
            1,
            0,
            3,
            GT_MODEL_TYPE,
            0,
            1,
            model,
            GT_RASTER_TYPE,
            0,
            1,
            PIXEL_IS_AREA,
            key,
            0,
            1,
            code,
        ]);
    } else if let Some(text) = crs.map(str::trim).filter(|c| {
        ["PROJCS[", "GEOGCS[", "COMPD_CS["]
            .iter()
            .any(|k| c.starts_with(k))
    }) {
        let keys = relief_io::wkt_keys::geokeys_of_wkt(text)
            .map_err(|e| format!("the CRS cannot be written to a GeoTIFF: {e}"))?;
        g.geo_key_directory = Some(keys.directory);
        g.geo_double_params = (!keys.doubles.is_empty()).then_some(keys.doubles);
        g.geo_ascii_params = (!keys.ascii.is_empty()).then_some(keys.ascii);
    } else if let Some(text) = crs.map(str::trim).filter(|c| {
        [
            "PROJCRS[",
            "GEOGCRS[",
            "GEODCRS[",
            "BOUNDCRS[",
            "COMPOUNDCRS[",
            "PROJECTEDCRS[",
        ]
        .iter()
        .any(|k| c.starts_with(k))
    }) {
        let head: String = text.chars().take(40).collect();
        return Err(format!(
            "the CRS is WKT 2 ({head}...), which relief does not read: pass an EPSG code, \
             WKT 1 (e.g. crs.to_wkt(version=\"WKT1_GDAL\")) or a rasterio CRS"
        ));
    }
    Ok(Some(g))
}

/// The CRS of a georeference as text: its OGC WKT 1 when it has an EPSG code the table holds,
/// else its name (`EPSG:<code>`, a citation).
pub(crate) fn crs_text(g: &GeoRef) -> Option<String> {
    relief_io::crs::wkt(g).or_else(|| g.crs.clone())
}

/// Merges JSON object `over` into `base` (nested objects field by field).
fn merge(base: &mut Value, over: Value) {
    match (base, over) {
        (Value::Object(b), Value::Object(o)) => {
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot @ Value::Object(_)) if v.is_object() => merge(slot, v),
                    _ => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (b, o) => *b = o,
    }
}

/// The settings `base` with the fields of the JSON object `json` (the keyword arguments)
/// replacing its own: the library's serde names, its unknown-field and type errors.
pub(crate) fn settings<T: Serialize + DeserializeOwned>(
    base: &T,
    json: &str,
) -> Result<T, Failure> {
    let mut value = serde_json::to_value(base).map_err(Failure::value)?;
    let over: Value = serde_json::from_str(json).map_err(Failure::value)?;
    if !over.is_object() {
        return Err(Failure::Value(
            "the settings must be keyword arguments".into(),
        ));
    }
    merge(&mut value, over);
    serde_json::from_value(value).map_err(Failure::value)
}

/// The default settings of a job as JSON (what [`settings`] starts from).
pub(crate) fn defaults_json<T: Serialize>(t: &T) -> Result<String, Failure> {
    serde_json::to_string(t).map_err(Failure::value)
}
