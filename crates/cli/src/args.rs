//! Flag groups and value parsers shared by the subcommands: [`ReadArgs`] (flattened into
//! every command that reads a raster) and the parsers of structured flag values (cell sizes,
//! crops, pairs, image and output sizes, height ranges, noise families, analytic atoms), so one
//! flag parses the same everywhere.

use anyhow::{Result, bail};
use relief_dictionary_learning::{AnalyticAtoms, NoiseFamily};
use relief_heightfield::Window;

/// Input options shared by every subcommand that reads a raster (`#[command(flatten)]`).
#[derive(Debug, Clone, Default, clap::Args)]
pub(crate) struct ReadArgs {
    /// Width of a raw .r16/.r32 input (square assumed when neither size is given).
    #[arg(long)]
    pub(crate) width: Option<usize>,
    /// Height of a raw .r16/.r32 input (derived from the file length when omitted).
    #[arg(long)]
    pub(crate) height: Option<usize>,
    /// Cell size in metres, `X` or `X,Y`, for inputs that do not store one (PNG, EXR, raw,
    /// NPY; without it they get 1 m cells and a warning, and `volume` refuses them); overrides
    /// a stored one, and a georeference follows (its pixel size scaled about the centre).
    #[arg(long, value_parser = parse_cell_size)]
    pub(crate) cell_size: Option<(f64, f64)>,
    /// Largest input raster accepted, in cells (default 268435456 = 2^28, 1 GiB of f32): a
    /// file declaring more is refused before anything is allocated. Raise it for larger inputs.
    #[arg(long)]
    pub(crate) max_input_cells: Option<usize>,
    /// Fill voids (nodata cells) by harmonic interpolation right after reading; without it a
    /// command that needs complete data refuses an input with voids.
    #[arg(long)]
    pub(crate) fill_voids: bool,
    /// How a PNG input encodes heights: `auto` (relief's grey mapping or raw grey counts) or
    /// `terrain-rgb` (Mapbox Terrain-RGB colour PNG).
    #[arg(long, value_enum, default_value_t = PngEncoding::Auto)]
    pub(crate) png_encoding: PngEncoding,
    /// Whether reading warns that the cell size is assumed (a PNG, Terrain-RGB, EXR, raw or
    /// NPY file without `--cell-size`): set for a command's own input flags, off in
    /// `ReadArgs::default()`, which auxiliary rasters (painted maps, sketches) are read with.
    #[arg(skip = true)]
    pub(crate) warn_assumed_cell: bool,
}

/// `--png-encoding` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub(crate) enum PngEncoding {
    /// Grey PNG (relief's recorded mapping, else raw counts).
    #[default]
    Auto,
    /// Mapbox Terrain-RGB.
    TerrainRgb,
}

impl ReadArgs {
    /// The library's read options of the flags.
    pub(crate) fn options(&self) -> relief_io::ReadOptions {
        relief_io::ReadOptions {
            width: self.width,
            height: self.height,
            cell_size: self.cell_size,
            max_cells: self
                .max_input_cells
                .unwrap_or(relief_io::ReadOptions::default().max_cells),
            png: match self.png_encoding {
                PngEncoding::Auto => relief_io::PngMode::Auto,
                PngEncoding::TerrainRgb => relief_io::PngMode::TerrainRgb,
            },
            ..Default::default()
        }
    }
}

/// The numbers of a structured flag value: `s` split at any of `seps`, each part trimmed and
/// parsed as `T`; `None` when a part does not parse. The count is the caller's to check.
fn numbers<T: std::str::FromStr>(s: &str, seps: &[char]) -> Option<Vec<T>> {
    s.split(seps).map(|t| t.trim().parse::<T>().ok()).collect()
}

/// `X` or `X,Y`: a cell size in metres, each in `1e-6..=1e7` (as relief-io accepts from files:
/// `1e-320` or `1e308` are typos, and would overflow extents).
pub(crate) fn parse_cell_size(s: &str) -> std::result::Result<(f64, f64), String> {
    let v = numbers::<f64>(s, &[','])
        .filter(|v| v.iter().all(|x| x.is_finite() && (1e-6..=1e7).contains(x)));
    match v.as_deref() {
        Some(&[x]) => Ok((x, x)),
        Some(&[x, y]) => Ok((x, y)),
        _ => Err(format!(
            "`{s}` is not a cell size in metres (X or X,Y, each between 1e-6 and 1e7)"
        )),
    }
}

/// `X,Y,W,H` crop of `relief volume --crop` (the shared [`Window`] syntax, with W, H >= 3).
pub(crate) fn parse_crop(s: &str) -> std::result::Result<Window, String> {
    let w: Window = s.parse()?;
    if w.width < 3 || w.height < 3 {
        return Err(format!("`{s}` is not X,Y,W,H with W, H >= 3"));
    }
    Ok(w)
}

/// `X,Y`: two finite numbers.
pub(crate) fn parse_pair(s: &str) -> std::result::Result<(f32, f32), String> {
    match numbers::<f32>(s, &[',']).as_deref() {
        Some(&[x, y]) if x.is_finite() && y.is_finite() => Ok((x, y)),
        _ => Err(format!("`{s}` is not X,Y (two finite numbers)")),
    }
}

/// `WxH` image size, each side in 1..=8192.
pub(crate) fn parse_image_size(s: &str) -> std::result::Result<(usize, usize), String> {
    match numbers::<usize>(s, &['x', 'X']).as_deref() {
        Some(&[w, h]) if (1..=8192).contains(&w) && (1..=8192).contains(&h) => Ok((w, h)),
        _ => Err(format!("`{s}` is not WxH with each size in 1..=8192")),
    }
}

/// `WxH` or `N` (square): an output size in cells, both positive.
pub(crate) fn parse_size(s: &str) -> std::result::Result<(usize, usize), String> {
    match numbers::<usize>(s, &['x', 'X']).as_deref() {
        Some(&[n]) if n > 0 => Ok((n, n)),
        Some(&[w, h]) if w > 0 && h > 0 => Ok((w, h)),
        _ => Err(format!("`{s}`: expected WxH (or N) with positive integers")),
    }
}

/// `LO,HI`: a height range in metres, finite, LO < HI.
pub(crate) fn parse_height_range(s: &str) -> std::result::Result<(f64, f64), String> {
    match numbers::<f64>(s, &[',']).as_deref() {
        Some(&[lo, hi]) if lo.is_finite() && hi.is_finite() && lo < hi => Ok((lo, hi)),
        _ => Err(format!(
            "`{s}`: expected two finite heights LO,HI in metres with LO < HI"
        )),
    }
}

/// The atom family a name denotes.
pub(crate) fn family(name: &str) -> Result<NoiseFamily> {
    Ok(match name.to_ascii_lowercase().as_str() {
        "ridged" | "ridged-sum" => NoiseFamily::RidgedSum,
        "perlin" => NoiseFamily::Perlin,
        "ridged-multifractal" | "multifractal" => NoiseFamily::RidgedMultifractal,
        "ridged-field" => NoiseFamily::RidgedField,
        "perlin-field" => NoiseFamily::PerlinField,
        _ => bail!(
            "invalid --family `{name}`: must be ridged-field, perlin-field, ridged, perlin or \
             ridged-multifractal"
        ),
    })
}

/// `--analytic-atoms` value parser.
pub(crate) fn parse_analytic_atoms(spec: &str) -> std::result::Result<AnalyticAtoms, String> {
    let mut a = AnalyticAtoms::default();
    for item in spec.split(',') {
        let (name, n) = item
            .split_once(':')
            .ok_or_else(|| format!("`{item}`: expected FAMILY:N"))?;
        let n: usize = n
            .trim()
            .parse()
            .map_err(|_| format!("`{item}`: N must be a count"))?;
        match family(name.trim()).map_err(|e| e.to_string())? {
            NoiseFamily::RidgedSum => a.ridged_sum += n,
            NoiseFamily::Perlin => a.perlin += n,
            NoiseFamily::RidgedMultifractal => a.ridged_multifractal += n,
            NoiseFamily::PerlinField => a.perlin_field += n,
            NoiseFamily::RidgedField => a.ridged_field += n,
        }
    }
    Ok(a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_size_argument() {
        assert_eq!(parse_cell_size("30"), Ok((30.0, 30.0)));
        assert_eq!(parse_cell_size("62.8,92.6"), Ok((62.8, 92.6)));
        assert!(parse_cell_size("0").is_err());
        assert!(parse_cell_size("x,1").is_err());
        for bad in ["1e-320", "1e308", "inf", "NaN", "-30", "30 m"] {
            assert!(parse_cell_size(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn number_lists() {
        assert_eq!(parse_size("128x96"), Ok((128, 96)));
        assert_eq!(parse_size("64"), Ok((64, 64)));
        for bad in ["0x4", "axb", "1x2x3", ""] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_height_range("-10,2500"), Ok((-10.0, 2500.0)));
        for bad in ["5,5", "x,5", "5", "1,nan", "1,2,3"] {
            assert!(parse_height_range(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_pair("1, -0.5"), Ok((1.0, -0.5)));
        for bad in ["1", "1,inf", "a,b", "1,2,3"] {
            assert!(parse_pair(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_image_size("640x480"), Ok((640, 480)));
        for bad in ["0x10", "9000x10", "640", "640x480x2"] {
            assert!(parse_image_size(bad).is_err(), "{bad}");
        }
        assert_eq!(
            parse_crop("1,2,30,40").map(|w| w.as_tuple()),
            Ok((1, 2, 30, 40))
        );
        for bad in ["1,2,2,40", "1,2,30", "-1,2,30,40"] {
            assert!(parse_crop(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn families() {
        assert_eq!(family("perlin").unwrap(), NoiseFamily::Perlin);
        assert_eq!(family("Ridged").unwrap(), NoiseFamily::RidgedSum);
        let e = family("simplex").unwrap_err().to_string();
        assert!(e.contains("--family") && e.contains("simplex"), "{e}");
    }
}

/// A flag value that is one of a library's serde enums (`--depressions breach`): parsed and
/// shown by the library's own names (its serde spelling), so the command line, a pipeline spec
/// and a tile manifest name a value the same way, and a flag's default comes from the
/// library's `Default` (`default_value_t = LibEnum(Settings::default().field)`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct LibEnum<T>(pub(crate) T);

impl<T: serde::de::DeserializeOwned> std::str::FromStr for LibEnum<T> {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        serde_json::from_value(serde_json::Value::String(s.trim().to_string()))
            .map(LibEnum)
            .map_err(|e| {
                // serde: "unknown variant `x`, expected one of `a`, `b`": keep its list.
                let e = e.to_string();
                e.split(" at line").next().unwrap_or(&e).to_string()
            })
    }
}

impl<T: serde::Serialize> std::fmt::Display for LibEnum<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match serde_json::to_value(&self.0) {
            Ok(serde_json::Value::String(s)) => f.write_str(&s),
            Ok(v) => write!(f, "{v}"),
            Err(_) => f.write_str("?"),
        }
    }
}

/// A library `check()` error as the flag it comes from: the field `channel_area` is the flag
/// `--channel-area` (flags map one-to-one onto the job's fields).
pub(crate) fn flag_error(e: relief_heightfield::ParamError) -> anyhow::Error {
    anyhow::anyhow!(
        "invalid --{} {}: {}",
        e.name.replace('_', "-"),
        e.value,
        e.reason
    )
}
