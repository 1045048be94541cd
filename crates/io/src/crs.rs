//! Coordinate reference systems as text: the EPSG code of a [`GeoRef`], its OGC WKT 1 (so an
//! ESRI ASCII grid gets its `.prj` and `relief info --json` reports the WKT, as GDAL does), and
//! the EPSG code named by a `.prj` file. The WKT comes from the `crs-definitions` table (pure
//! Rust, no PROJ); a code outside it keeps its `EPSG:<code>` without a WKT.

use relief_heightfield::GeoRef;

/// The EPSG code of a georeference whose CRS is `EPSG:<code>` (as relief-io's GeoTIFF and SRTM
/// readers record it).
pub fn epsg_code(g: &GeoRef) -> Option<u32> {
    g.crs
        .as_deref()?
        .trim()
        .strip_prefix("EPSG:")?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// The georeference's CRS as OGC WKT 1 (with `AUTHORITY` nodes, the form GDAL writes to a
/// `.prj`), when it has an EPSG code the table holds.
pub fn wkt(g: &GeoRef) -> Option<String> {
    epsg_wkt(epsg_code(g)?)
}

/// OGC WKT 1 of an EPSG code (from the `crs-definitions` table, GDAL's own WKT of every EPSG
/// code; see docs/ARCHITECTURE.md), or `None` for a code it does not hold.
pub fn epsg_wkt(code: u32) -> Option<String> {
    let code = u16::try_from(code).ok()?;
    crs_definitions::from_code(code).map(|d| d.wkt.to_string())
}

/// Ground cell size `(x, y)` in metres of a grid `height` rows high with georeference `g`, as
/// the GeoTIFF reader derives it from the affine transform and the GeoTIFF keys: geographic
/// grids at the centre latitude (WGS84), Web Mercator scaled by cos(latitude), other
/// projections taken as metres. `None` without a usable transform.
pub fn ground_cell_size(g: &GeoRef, height: usize) -> Option<(f64, f64)> {
    crate::geotiff::cell_size(g, height)
}

/// The CRS a `.prj` (WKT 1, OGC or ESRI flavour) names: `EPSG:<code>` from its outermost
/// `AUTHORITY["EPSG", ...]` (the last one in the text), else the name of its outermost
/// `PROJCS` / `GEOGCS`. `None` for text that is not WKT.
pub fn crs_of_prj(text: &str) -> Option<String> {
    let t = text.trim();
    if !(t.starts_with("PROJCS[") || t.starts_with("GEOGCS[") || t.starts_with("COMPD_CS[")) {
        return None;
    }
    // The outermost node's AUTHORITY closes the text: `...,AUTHORITY["EPSG","3857"]]`.
    let tail = t.trim_end_matches(']');
    if let Some(i) = tail.rfind("AUTHORITY[")
        && tail[i..].matches('[').count() == 1
    {
        let inner = &tail[i + "AUTHORITY[".len()..];
        let parts: Vec<&str> = inner
            .split(',')
            .map(|s| s.trim().trim_matches('"'))
            .collect();
        if parts.len() == 2
            && parts[0].eq_ignore_ascii_case("EPSG")
            && let Ok(code) = parts[1].parse::<u32>()
        {
            return Some(format!("EPSG:{code}"));
        }
    }
    let start = t.find('"')? + 1;
    let len = t[start..].find('"')?;
    Some(t[start..start + len].to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn georef(crs: &str) -> GeoRef {
        GeoRef {
            crs: Some(crs.into()),
            ..GeoRef::default()
        }
    }

    #[test]
    fn codes_and_their_wkt() {
        assert_eq!(epsg_code(&georef("EPSG:3857")), Some(3857));
        assert_eq!(epsg_code(&georef("WGS84 geographic")), None);
        let w = wkt(&georef("EPSG:32612")).unwrap();
        assert!(w.starts_with("PROJCS[\"WGS 84 / UTM zone 12N\""), "{w}");
        assert!(w.contains("PARAMETER[\"central_meridian\",-111]"), "{w}");
        assert!(w.ends_with("AUTHORITY[\"EPSG\",\"32612\"]]"), "{w}");
        let s = epsg_wkt(32733).unwrap();
        assert!(s.contains("UTM zone 33S") && s.contains("\"false_northing\",10000000"));
        assert!(epsg_wkt(25832).unwrap().contains("ETRS89 / UTM zone 32N"));
        assert!(epsg_wkt(4326).unwrap().starts_with("GEOGCS[\"WGS 84\""));
        assert!(epsg_wkt(3857).unwrap().contains("Mercator_1SP"));
        assert!(epsg_wkt(2154).unwrap().contains("Lambert-93"));
        assert!(epsg_wkt(1).is_none());
        assert!(epsg_wkt(100_000).is_none());
        // Brackets balance in every string.
        for code in [4326, 4258, 4269, 3857, 32601, 32760, 25838, 26923] {
            let w = epsg_wkt(code).unwrap();
            assert_eq!(w.matches('[').count(), w.matches(']').count(), "{code}");
        }
    }

    #[test]
    fn prj_files_name_their_crs() {
        for code in [4326, 3857, 32611, 25832] {
            assert_eq!(
                crs_of_prj(&epsg_wkt(code).unwrap()),
                Some(format!("EPSG:{code}"))
            );
        }
        // An ESRI-flavoured .prj without AUTHORITY: its name.
        let esri = "PROJCS[\"NAD_1983_UTM_Zone_12N\",GEOGCS[\"GCS_North_American_1983\",\
                    DATUM[\"D_North_American_1983\",SPHEROID[\"GRS_1980\",6378137.0,\
                    298.257222101]],PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\",\
                    0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],UNIT[\"Meter\",1.0]]";
        assert_eq!(crs_of_prj(esri).as_deref(), Some("NAD_1983_UTM_Zone_12N"));
        assert_eq!(crs_of_prj("hello"), None);
        assert_eq!(crs_of_prj(""), None);
    }
}
