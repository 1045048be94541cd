//! Flag groups and value parsers shared by the subcommands: [`ReadArgs`] (flattened into
//! every command that reads a raster) and the parsers of structured flag values (cell sizes,
//! crops, pairs, image sizes, noise families, analytic atoms), so one flag parses the same
//! everywhere.

use anyhow::{Result, bail};
use relief_dictionary_learning::{AnalyticAtoms, NoiseFamily};

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
    /// NPY); overrides a stored one.
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

pub(crate) fn parse_cell_size(s: &str) -> std::result::Result<(f64, f64), String> {
    // 1 micrometre to 10 000 km, as relief-io accepts from files: `1e-320` or `1e308` are
    // typos, and would overflow extents.
    let parse = |t: &str| {
        t.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && (1e-6..=1e7).contains(v))
            .ok_or_else(|| format!("`{t}` is not a cell size in metres between 1e-6 and 1e7"))
    };
    match s.split_once(',') {
        Some((x, y)) => Ok((parse(x)?, parse(y)?)),
        None => parse(s).map(|v| (v, v)),
    }
}

/// `X,Y,W,H` crop of `relief volume --crop` (W, H >= 3).
pub(crate) fn parse_crop(s: &str) -> std::result::Result<(usize, usize, usize, usize), String> {
    let v: Vec<usize> = s
        .split(',')
        .map(|t| t.trim().parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("`{s}` is not X,Y,W,H (four non-negative integers)"))?;
    match v[..] {
        [x, y, w, h] if w >= 3 && h >= 3 => Ok((x, y, w, h)),
        _ => Err(format!("`{s}` is not X,Y,W,H with W, H >= 3")),
    }
}

/// `X,Y`: two finite numbers.
pub(crate) fn parse_pair(s: &str) -> std::result::Result<(f32, f32), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("`{s}` is not X,Y"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{s}` is not X,Y (two finite numbers)"))
    };
    Ok((p(a)?, p(b)?))
}

/// `WxH` image size, each side in 1..=8192.
pub(crate) fn parse_image_size(s: &str) -> std::result::Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("`{s}` is not WxH"))?;
    let p = |t: &str| {
        t.trim()
            .parse::<usize>()
            .ok()
            .filter(|v| (1..=8192).contains(v))
            .ok_or_else(|| format!("`{s}`: each size must be in 1..=8192"))
    };
    Ok((p(w)?, p(h)?))
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
    fn families() {
        assert_eq!(family("perlin").unwrap(), NoiseFamily::Perlin);
        assert_eq!(family("Ridged").unwrap(), NoiseFamily::RidgedSum);
        let e = family("simplex").unwrap_err().to_string();
        assert!(e.contains("--family") && e.contains("simplex"), "{e}");
    }
}
