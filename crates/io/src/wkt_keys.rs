//! GeoTIFF keys of a CRS given as OGC WKT 1 without an EPSG code (a custom Lambert conformal
//! conic, a national grid on its own datum, a geographic CRS on another ellipsoid), so that a
//! GeoTIFF written from it carries the CRS: GDAL, rasterio and QGIS read it back as the same
//! projection. The mapping of each projection method's parameters onto the keys is GDAL's
//! (`GTIFSetFromOGISDefnEx` in `gt_wkt_srs.cpp`): user-defined (32767) projected CRS,
//! projection and, unless they carry an EPSG authority, geographic CRS, datum and ellipsoid,
//! with the parameters as GeoDoubleParams. A method this module does not map is an error that
//! names it, never a CRS dropped in silence.

/// The three GeoTIFF tags that carry a CRS.
#[derive(Debug, Clone, PartialEq)]
pub struct GeoKeys {
    /// `GeoKeyDirectoryTag` (34735).
    pub directory: Vec<u16>,
    /// `GeoDoubleParamsTag` (34736).
    pub doubles: Vec<f64>,
    /// `GeoAsciiParamsTag` (34737).
    pub ascii: String,
}

/// A WKT node: `KEYWORD[item, ...]`, an item a quoted string, a number or a node.
#[derive(Debug, Clone, PartialEq)]
enum Item {
    Text(String),
    Number(f64),
    Node(Node),
}

#[derive(Debug, Clone, PartialEq)]
struct Node {
    keyword: String,
    items: Vec<Item>,
}

impl Node {
    fn child(&self, keyword: &str) -> Option<&Node> {
        self.items.iter().find_map(|i| match i {
            Item::Node(n) if n.keyword.eq_ignore_ascii_case(keyword) => Some(n),
            _ => None,
        })
    }

    fn children<'a>(&'a self, keyword: &'a str) -> impl Iterator<Item = &'a Node> + 'a {
        self.items.iter().filter_map(move |i| match i {
            Item::Node(n) if n.keyword.eq_ignore_ascii_case(keyword) => Some(n),
            _ => None,
        })
    }

    fn text(&self, k: usize) -> Option<&str> {
        match self.items.get(k) {
            Some(Item::Text(t)) => Some(t),
            _ => None,
        }
    }

    fn number(&self, k: usize) -> Option<f64> {
        match self.items.get(k) {
            Some(Item::Number(v)) => Some(*v),
            Some(Item::Text(t)) => t.trim().parse().ok(),
            _ => None,
        }
    }

    /// The EPSG code of its `AUTHORITY["EPSG", "code"]` (WKT 1) or `ID["EPSG", code]`.
    fn epsg(&self) -> Option<u16> {
        let a = self.child("AUTHORITY").or_else(|| self.child("ID"))?;
        if !a.text(0)?.eq_ignore_ascii_case("EPSG") {
            return None;
        }
        let code = a.number(1)?;
        (code.fract() == 0.0 && (1.0..32767.0).contains(&code)).then_some(code as u16)
    }
}

/// Parses WKT 1 text (square or round brackets).
fn parse(text: &str) -> Result<Node, String> {
    let mut p = Parser {
        s: text.as_bytes(),
        i: 0,
        depth: 0,
    };
    let n = p.node()?;
    p.skip_space();
    if p.i != p.s.len() {
        return Err(format!("unexpected text after the WKT at byte {}", p.i));
    }
    Ok(n)
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
    depth: usize,
}

impl Parser<'_> {
    fn skip_space(&mut self) {
        while self.i < self.s.len() && self.s[self.i].is_ascii_whitespace() {
            self.i += 1;
        }
    }

    fn node(&mut self) -> Result<Node, String> {
        self.depth += 1;
        if self.depth > 32 {
            return Err("WKT nested more than 32 deep".into());
        }
        self.skip_space();
        let start = self.i;
        while self.i < self.s.len()
            && (self.s[self.i].is_ascii_alphanumeric() || self.s[self.i] == b'_')
        {
            self.i += 1;
        }
        let keyword = String::from_utf8_lossy(&self.s[start..self.i]).into_owned();
        if keyword.is_empty() {
            return Err(format!("a WKT keyword expected at byte {start}"));
        }
        self.skip_space();
        let close = match self.s.get(self.i) {
            Some(b'[') => b']',
            Some(b'(') => b')',
            _ => return Err(format!("'[' expected after {keyword}")),
        };
        self.i += 1;
        let mut items = Vec::new();
        loop {
            self.skip_space();
            match self.s.get(self.i) {
                None => return Err(format!("{keyword}[ is not closed")),
                Some(&c) if c == close && !items.is_empty() => {
                    self.i += 1;
                    break;
                }
                Some(b',') if !items.is_empty() => {
                    self.i += 1;
                    self.skip_space();
                }
                Some(_) if items.is_empty() => {}
                Some(_) => return Err(format!("',' expected in {keyword} at byte {}", self.i)),
            }
            items.push(self.item()?);
        }
        self.depth -= 1;
        Ok(Node { keyword, items })
    }

    fn item(&mut self) -> Result<Item, String> {
        match self.s.get(self.i) {
            Some(b'"') => {
                // A doubled quote inside a string is one quote.
                let mut t = Vec::new();
                self.i += 1;
                loop {
                    match self.s.get(self.i) {
                        None => return Err("a WKT string is not closed".into()),
                        Some(b'"') if self.s.get(self.i + 1) == Some(&b'"') => {
                            t.push(b'"');
                            self.i += 2;
                        }
                        Some(b'"') => {
                            self.i += 1;
                            break;
                        }
                        Some(&c) => {
                            t.push(c);
                            self.i += 1;
                        }
                    }
                }
                Ok(Item::Text(String::from_utf8_lossy(&t).into_owned()))
            }
            Some(c) if c.is_ascii_digit() || *c == b'-' || *c == b'+' || *c == b'.' => {
                let start = self.i;
                while self.i < self.s.len()
                    && matches!(
                        self.s[self.i],
                        b'0'..=b'9' | b'-' | b'+' | b'.' | b'e' | b'E'
                    )
                {
                    self.i += 1;
                }
                let t = std::str::from_utf8(&self.s[start..self.i]).unwrap_or("");
                t.parse()
                    .map(Item::Number)
                    .map_err(|_| format!("bad number {t:?} in the WKT"))
            }
            Some(_) => {
                // A bare enumeration (AXIS["Easting",EAST]) is text; a keyword with a bracket
                // is a node.
                let save = self.i;
                while self.i < self.s.len()
                    && (self.s[self.i].is_ascii_alphanumeric() || self.s[self.i] == b'_')
                {
                    self.i += 1;
                }
                let word = String::from_utf8_lossy(&self.s[save..self.i]).into_owned();
                self.skip_space();
                if matches!(self.s.get(self.i), Some(b'[' | b'(')) {
                    self.i = save;
                    Ok(Item::Node(self.node()?))
                } else if word.is_empty() {
                    Err(format!("unexpected character at byte {}", self.i))
                } else {
                    Ok(Item::Text(word))
                }
            }
            None => Err("the WKT ends early".into()),
        }
    }
}

// GeoKey ids and values (GeoTIFF 1.1).
const GT_MODEL_TYPE: u16 = 1024;
const GT_RASTER_TYPE: u16 = 1025;
const GT_CITATION: u16 = 1026;
const GEOGRAPHIC_TYPE: u16 = 2048;
const GEOG_CITATION: u16 = 2049;
const GEOG_DATUM: u16 = 2050;
const GEOG_PRIME_MERIDIAN: u16 = 2051;
const GEOG_ANGULAR_UNITS: u16 = 2054;
const GEOG_ELLIPSOID: u16 = 2056;
const GEOG_SEMI_MAJOR: u16 = 2057;
const GEOG_INV_FLATTENING: u16 = 2059;
const GEOG_PRIME_MERIDIAN_LONG: u16 = 2061;
const PROJECTED_TYPE: u16 = 3072;
const PCS_CITATION: u16 = 3073;
const PROJECTION: u16 = 3074;
const PROJ_COORD_TRANS: u16 = 3075;
const PROJ_LINEAR_UNITS: u16 = 3076;
const PROJ_LINEAR_UNIT_SIZE: u16 = 3077;
const STD_PARALLEL_1: u16 = 3078;
const STD_PARALLEL_2: u16 = 3079;
const NAT_ORIGIN_LONG: u16 = 3080;
const NAT_ORIGIN_LAT: u16 = 3081;
const FALSE_EASTING: u16 = 3082;
const FALSE_NORTHING: u16 = 3083;
const FALSE_ORIGIN_LONG: u16 = 3084;
const FALSE_ORIGIN_LAT: u16 = 3085;
const FALSE_ORIGIN_EASTING: u16 = 3086;
const FALSE_ORIGIN_NORTHING: u16 = 3087;
const CENTER_LONG: u16 = 3088;
const CENTER_LAT: u16 = 3089;
const SCALE_AT_NAT_ORIGIN: u16 = 3092;
const STRAIGHT_VERT_POLE_LONG: u16 = 3095;
const USER_DEFINED: u16 = 32767;
const DOUBLES_TAG: u16 = 34736;
const ASCII_TAG: u16 = 34737;

/// A key's value while the directory is built.
enum Value {
    Short(u16),
    Double(f64),
    Ascii(String),
}

/// The GeoTIFF keys of `wkt` (OGC or ESRI WKT 1) for a raster whose pixels are areas. An
/// outermost EPSG authority gives the plain `EPSG:<code>` keys; otherwise the CRS is written
/// user-defined. Errors name what cannot be written (not WKT 1, a projection method outside
/// the map below, a compound CRS).
pub fn geokeys_of_wkt(wkt: &str) -> Result<GeoKeys, String> {
    let root = parse(wkt.trim())?;
    let mut keys: Vec<(u16, Value)> = vec![(GT_RASTER_TYPE, Value::Short(1))];
    match root.keyword.to_ascii_uppercase().as_str() {
        "GEOGCS" => {
            keys.push((GT_MODEL_TYPE, Value::Short(2)));
            geographic(&root, &mut keys)?;
        }
        "PROJCS" => {
            keys.push((GT_MODEL_TYPE, Value::Short(1)));
            let name = root.text(0).unwrap_or("unnamed").to_string();
            keys.push((GT_CITATION, Value::Ascii(name.clone())));
            if let Some(code) = root.epsg() {
                keys.push((PROJECTED_TYPE, Value::Short(code)));
            } else {
                let geog = root
                    .child("GEOGCS")
                    .ok_or("the PROJCS has no GEOGCS (its datum and ellipsoid)")?;
                geographic(geog, &mut keys)?;
                keys.push((PROJECTED_TYPE, Value::Short(USER_DEFINED)));
                keys.push((PCS_CITATION, Value::Ascii(name)));
                keys.push((PROJECTION, Value::Short(USER_DEFINED)));
                projection(&root, &mut keys)?;
                linear_unit(&root, &mut keys)?;
            }
        }
        other => {
            return Err(format!(
                "a {other} CRS cannot be written as GeoTIFF keys (a PROJCS or GEOGCS can)"
            ));
        }
    }
    Ok(directory(keys))
}

fn geographic(g: &Node, keys: &mut Vec<(u16, Value)>) -> Result<(), String> {
    let name = g.text(0).unwrap_or("unnamed").to_string();
    if let Some(code) = g.epsg() {
        keys.push((GEOGRAPHIC_TYPE, Value::Short(code)));
        return Ok(());
    }
    keys.push((GEOGRAPHIC_TYPE, Value::Short(USER_DEFINED)));
    keys.push((GEOG_CITATION, Value::Ascii(name)));
    let datum = g.child("DATUM").ok_or("the GEOGCS has no DATUM")?;
    keys.push((
        GEOG_DATUM,
        Value::Short(datum.epsg().unwrap_or(USER_DEFINED)),
    ));
    let sph = datum
        .child("SPHEROID")
        .or_else(|| datum.child("ELLIPSOID"))
        .ok_or("the DATUM has no SPHEROID")?;
    match sph.epsg() {
        Some(code) => keys.push((GEOG_ELLIPSOID, Value::Short(code))),
        None => {
            let (a, inv_f) = (sph.number(1), sph.number(2));
            let (Some(a), Some(inv_f)) = (a, inv_f) else {
                return Err("the SPHEROID lacks its semi-major axis or inverse flattening".into());
            };
            if !(a.is_finite() && a > 0.0 && inv_f.is_finite() && inv_f >= 0.0) {
                return Err(format!(
                    "the SPHEROID's axis {a} or inverse flattening {inv_f}"
                ));
            }
            keys.push((GEOG_ELLIPSOID, Value::Short(USER_DEFINED)));
            keys.push((GEOG_SEMI_MAJOR, Value::Double(a)));
            keys.push((GEOG_INV_FLATTENING, Value::Double(inv_f)));
        }
    }
    let pm = g.child("PRIMEM").and_then(|p| p.number(1)).unwrap_or(0.0);
    if pm == 0.0 {
        keys.push((GEOG_PRIME_MERIDIAN, Value::Short(8901)));
    } else {
        keys.push((GEOG_PRIME_MERIDIAN, Value::Short(USER_DEFINED)));
        keys.push((GEOG_PRIME_MERIDIAN_LONG, Value::Double(pm)));
    }
    let unit = g.child("UNIT").and_then(|u| u.number(1));
    if unit.is_some_and(|u| (u - std::f64::consts::PI / 180.0).abs() > 1e-12) {
        return Err("a geographic CRS in angular units other than degrees".into());
    }
    keys.push((GEOG_ANGULAR_UNITS, Value::Short(9102)));
    Ok(())
}

/// GeoTIFF coordinate transformation and the key of each WKT parameter, per method (GDAL's).
fn method(name: &str) -> Option<(u16, &'static [(&'static str, u16)])> {
    const TM: &[(&str, u16)] = &[
        ("latitude_of_origin", NAT_ORIGIN_LAT),
        ("central_meridian", NAT_ORIGIN_LONG),
        ("scale_factor", SCALE_AT_NAT_ORIGIN),
        ("false_easting", FALSE_EASTING),
        ("false_northing", FALSE_NORTHING),
    ];
    const LCC2: &[(&str, u16)] = &[
        ("standard_parallel_1", STD_PARALLEL_1),
        ("standard_parallel_2", STD_PARALLEL_2),
        ("latitude_of_origin", FALSE_ORIGIN_LAT),
        ("central_meridian", FALSE_ORIGIN_LONG),
        ("false_easting", FALSE_ORIGIN_EASTING),
        ("false_northing", FALSE_ORIGIN_NORTHING),
    ];
    const ALBERS: &[(&str, u16)] = &[
        ("standard_parallel_1", STD_PARALLEL_1),
        ("standard_parallel_2", STD_PARALLEL_2),
        ("latitude_of_center", NAT_ORIGIN_LAT),
        ("longitude_of_center", NAT_ORIGIN_LONG),
        ("false_easting", FALSE_EASTING),
        ("false_northing", FALSE_NORTHING),
    ];
    const POLAR: &[(&str, u16)] = &[
        ("latitude_of_origin", NAT_ORIGIN_LAT),
        ("central_meridian", STRAIGHT_VERT_POLE_LONG),
        ("scale_factor", SCALE_AT_NAT_ORIGIN),
        ("false_easting", FALSE_EASTING),
        ("false_northing", FALSE_NORTHING),
    ];
    const MERC2: &[(&str, u16)] = &[
        ("standard_parallel_1", STD_PARALLEL_1),
        ("central_meridian", NAT_ORIGIN_LONG),
        ("false_easting", FALSE_EASTING),
        ("false_northing", FALSE_NORTHING),
    ];
    const LAEA: &[(&str, u16)] = &[
        ("latitude_of_center", CENTER_LAT),
        ("longitude_of_center", CENTER_LONG),
        ("false_easting", FALSE_EASTING),
        ("false_northing", FALSE_NORTHING),
    ];
    Some(match name.to_ascii_lowercase().as_str() {
        "transverse_mercator" => (1, TM),
        "lambert_conformal_conic_1sp" => (9, TM),
        "lambert_conformal_conic_2sp" | "lambert_conformal_conic" => (8, LCC2),
        "albers_conic_equal_area" | "albers" => (11, ALBERS),
        "polar_stereographic" => (15, POLAR),
        "mercator_1sp" => (7, TM),
        "mercator_2sp" => (7, MERC2),
        "lambert_azimuthal_equal_area" => (10, LAEA),
        "oblique_stereographic" => (16, TM),
        _ => return None,
    })
}

fn projection(p: &Node, keys: &mut Vec<(u16, Value)>) -> Result<(), String> {
    let name = p
        .child("PROJECTION")
        .and_then(|n| n.text(0))
        .ok_or("the PROJCS has no PROJECTION")?;
    let (ct, params) = method(name).ok_or_else(|| {
        format!(
            "the projection method {name} has no GeoTIFF mapping here (Transverse Mercator, \
             Lambert conformal conic 1SP/2SP, Albers, polar and oblique stereographic, \
             Mercator 1SP/2SP and Lambert azimuthal equal-area have); give an EPSG code or \
             write with rasterio/GDAL"
        )
    })?;
    keys.push((PROJ_COORD_TRANS, Value::Short(ct)));
    let mut known = std::collections::BTreeMap::new();
    for par in p.children("PARAMETER") {
        if let (Some(n), Some(v)) = (par.text(0), par.number(1)) {
            if !v.is_finite() {
                return Err(format!("the parameter {n} is {v}"));
            }
            known.insert(n.to_ascii_lowercase(), v);
        }
    }
    for &(wkt_name, key) in params {
        // GDAL's defaults for a parameter left out: scale 1, every other 0.
        let default = if key == SCALE_AT_NAT_ORIGIN { 1.0 } else { 0.0 };
        let v = known.remove(wkt_name).unwrap_or(default);
        keys.push((key, Value::Double(v)));
    }
    // A parameter the method does not take would change the projection if dropped.
    if let Some((n, v)) = known.into_iter().find(|(_, v)| *v != 0.0) {
        return Err(format!(
            "the parameter {n} = {v} of {name} has no GeoTIFF key in this mapping"
        ));
    }
    Ok(())
}

fn linear_unit(p: &Node, keys: &mut Vec<(u16, Value)>) -> Result<(), String> {
    let size = p.child("UNIT").and_then(|u| u.number(1)).unwrap_or(1.0);
    if !(size.is_finite() && size > 0.0) {
        return Err(format!("the linear unit's size {size} m"));
    }
    let code = [(1.0, 9001), (0.3048, 9002), (1200.0 / 3937.0, 9003)]
        .iter()
        .find(|(s, _)| (size - s).abs() < 1e-12)
        .map(|&(_, c)| c);
    match code {
        Some(c) => keys.push((PROJ_LINEAR_UNITS, Value::Short(c))),
        None => {
            keys.push((PROJ_LINEAR_UNITS, Value::Short(USER_DEFINED)));
            keys.push((PROJ_LINEAR_UNIT_SIZE, Value::Double(size)));
        }
    }
    Ok(())
}

/// The directory of `keys` (sorted by id, as GeoTIFF requires), doubles and ASCII params.
fn directory(mut keys: Vec<(u16, Value)>) -> GeoKeys {
    keys.sort_by_key(|(k, _)| *k);
    let mut dir = vec![1, 1, 0, keys.len() as u16];
    let (mut doubles, mut ascii) = (Vec::new(), String::new());
    for (k, v) in keys {
        match v {
            Value::Short(s) => dir.extend([k, 0, 1, s]),
            Value::Double(d) => {
                dir.extend([k, DOUBLES_TAG, 1, doubles.len() as u16]);
                doubles.push(d);
            }
            Value::Ascii(t) => {
                // Printable ASCII without GeoTIFF's '|' terminator, at most 255 characters (a
                // citation, not a payload: the offsets are 16-bit).
                let t: String = t
                    .chars()
                    .filter(|c| *c != '|' && (c.is_ascii_graphic() || *c == ' '))
                    .take(255)
                    .collect();
                dir.extend([k, ASCII_TAG, t.len() as u16 + 1, ascii.len() as u16]);
                ascii.push_str(&t);
                ascii.push('|');
            }
        }
    }
    GeoKeys {
        directory: dir,
        doubles,
        ascii,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LCC: &str = r#"PROJCS["unknown",GEOGCS["unknown",DATUM["Unknown based on GRS80 ellipsoid",SPHEROID["GRS 1980",6378137,298.257222101,AUTHORITY["EPSG","7019"]]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]]],PROJECTION["Lambert_Conformal_Conic_2SP"],PARAMETER["latitude_of_origin",47],PARAMETER["central_meridian",10],PARAMETER["standard_parallel_1",45],PARAMETER["standard_parallel_2",50],PARAMETER["false_easting",0],PARAMETER["false_northing",0],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH]]"#;

    fn short(k: &GeoKeys, key: u16) -> Option<u16> {
        k.directory[4..]
            .chunks(4)
            .find(|e| e[0] == key && e[1] == 0)
            .map(|e| e[3])
    }

    fn double(k: &GeoKeys, key: u16) -> Option<f64> {
        k.directory[4..]
            .chunks(4)
            .find(|e| e[0] == key && e[1] == DOUBLES_TAG)
            .map(|e| k.doubles[e[3] as usize])
    }

    #[test]
    fn a_custom_lambert_conic_becomes_user_defined_keys() {
        let k = geokeys_of_wkt(LCC).unwrap();
        assert_eq!(short(&k, GT_MODEL_TYPE), Some(1));
        assert_eq!(short(&k, PROJECTED_TYPE), Some(USER_DEFINED));
        assert_eq!(short(&k, PROJ_COORD_TRANS), Some(8));
        assert_eq!(short(&k, GEOG_ELLIPSOID), Some(7019));
        assert_eq!(short(&k, PROJ_LINEAR_UNITS), Some(9001));
        assert_eq!(double(&k, STD_PARALLEL_1), Some(45.0));
        assert_eq!(double(&k, STD_PARALLEL_2), Some(50.0));
        assert_eq!(double(&k, FALSE_ORIGIN_LAT), Some(47.0));
        assert_eq!(double(&k, FALSE_ORIGIN_LONG), Some(10.0));
        // Keys sorted, the count in the header, ASCII offsets inside the params.
        let ids: Vec<u16> = k.directory[4..].chunks(4).map(|e| e[0]).collect();
        assert!(ids.windows(2).all(|w| w[0] < w[1]), "{ids:?}");
        assert_eq!(k.directory[3] as usize, ids.len());
        assert!(k.ascii.starts_with("unknown|"));
    }

    #[test]
    fn an_epsg_authority_gives_the_code_and_a_custom_ellipsoid_its_axes() {
        let utm = crate::crs::epsg_wkt(32612).unwrap();
        let k = geokeys_of_wkt(&utm).unwrap();
        assert_eq!(short(&k, PROJECTED_TYPE), Some(32612));
        let geog = r#"GEOGCS["Mars 2000",DATUM["D_Mars_2000",SPHEROID["Mars_2000_IAU_IAG",3396190.0,169.894447223612]],PRIMEM["Reference_Meridian",0.0],UNIT["Degree",0.0174532925199433]]"#;
        let k = geokeys_of_wkt(geog).unwrap();
        assert_eq!(short(&k, GT_MODEL_TYPE), Some(2));
        assert_eq!(short(&k, GEOGRAPHIC_TYPE), Some(USER_DEFINED));
        assert_eq!(double(&k, GEOG_SEMI_MAJOR), Some(3396190.0));
        assert_eq!(double(&k, GEOG_INV_FLATTENING), Some(169.894447223612));
    }

    #[test]
    fn what_cannot_be_written_is_named() {
        let bad = LCC.replace("Lambert_Conformal_Conic_2SP", "Hotine_Oblique_Mercator");
        let e = geokeys_of_wkt(&bad).unwrap_err();
        assert!(e.contains("Hotine_Oblique_Mercator"), "{e}");
        let extra = LCC.replace(
            "PARAMETER[\"false_easting\",0]",
            "PARAMETER[\"false_easting\",0],PARAMETER[\"azimuth\",12]",
        );
        assert!(geokeys_of_wkt(&extra).unwrap_err().contains("azimuth"));
        for junk in [
            "",
            "hello",
            "PROJCS[",
            "PROJCS[\"x\"",
            "PROJCS[\"x\"]]",
            "VERT_CS[\"h\"]",
        ] {
            assert!(geokeys_of_wkt(junk).is_err(), "{junk}");
        }
        let deep = "A[".repeat(100);
        assert!(geokeys_of_wkt(&deep).is_err());
        // A 100 kB name is cut to a citation, not a 16-bit overflow.
        let long = LCC.replacen("\"unknown\"", &format!("\"{}\"", "n".repeat(100_000)), 1);
        let k = geokeys_of_wkt(&long).unwrap();
        assert!(k.ascii.len() < 1000);
    }
}

#[cfg(test)]
mod fuzz {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn any_text_gives_keys_or_an_error(s in "[A-Z_\\[\\]\\(\\),\" 0-9.eE+-]{0,200}") {
            let _ = geokeys_of_wkt(&s);
        }

        #[test]
        fn mangled_wkt_gives_keys_or_an_error(cut in 0usize..600, junk in "[\\[\\]\",]{0,3}") {
            let w = tests_lcc();
            let cut = cut.min(w.len());
            let _ = geokeys_of_wkt(&format!("{}{}{}", &w[..cut], junk, &w[cut..]));
        }
    }

    fn tests_lcc() -> String {
        crate::crs::epsg_wkt(2154)
            .unwrap()
            .replace("AUTHORITY[\"EPSG\",\"2154\"]", "")
    }
}
