//! File input/output for relief: the only crate of the workspace that touches the filesystem.
//!
//! Rasters are read into a [`relief_heightfield::Heightfield`] (row 0 = north, voids = NaN,
//! separate x/y cell sizes in metres, the GeoTIFF georeference kept verbatim in
//! [`relief_heightfield::GeoRef`]) and written back from one. Meshes are written as OBJ, binary
//! PLY or GLB (glTF 2.0 binary).
//!
//! # Formats
//! | [`Format`] | read | write | precision of a round trip |
//! |---|---|---|---|
//! | GeoTIFF (int8/16/32, uint8/16/32, float32/64; strips, tiles, any compression the `tiff` crate reads) | yes | float32 + georeference + `GDAL_NODATA` | exact (f32) |
//! | SRTM `.hgt` (1201^2 or 3601^2 big-endian int16, -32768 = void) | yes | yes (same sizes, rounded) | 1 m |
//! | ESRI ASCII grid | yes | yes | exact (shortest round-trip decimal) |
//! | PNG 8/16-bit grey, vertical mapping in a `tEXt` chunk | yes | 16-bit | (max - min) / 65535 / 2 |
//! | Mapbox Terrain-RGB PNG | yes | yes | 0.05 m |
//! | OpenEXR single channel f32/f16 | yes | f32 | exact |
//! | raw `.r16` (u16 LE) / `.r32` (f32 LE), size given | yes | yes | r16: step/2, r32 exact |
//! | NumPy `.npy` / `.npz` | yes | `.npy` f32 | exact |
//! | `.f32` + `.json` sidecar (the `shared/data/dem` layout) and the `{width,height,values}` JSON grid | yes | `.f32` + `.json` | exact |
//!
//! # Guarantees
//! * Format detection looks at magic bytes first; the extension is only a hint (raw formats
//!   have no magic).
//! * Every declared size is checked against the file length and [`ReadOptions::max_cells`]
//!   before any allocation; malformed input gives an [`IoError`] naming the problem, never a
//!   panic.
//! * Writes are atomic: a temporary file in the destination directory is renamed over the
//!   target only once everything was written; on error nothing is left behind.
//! * Large outputs stream: [`GeoTiffStripWriter`] takes rows in order and keeps only a 64 KiB
//!   buffer, so a 16384^2 raster never has to exist in memory (same atomic rename at the end).
//!
//! Cell size and georeference: GeoTIFF stores both (cell sizes of geographic grids are
//! computed in metres at the centre latitude, Web Mercator pixels are scaled by cos(latitude));
//! ASCII grids and `.f32` sidecars store the cell size (ASCII also the corner); SRTM tiles take
//! it from the tile name (`N47E011.hgt`); NPZ from `latitude`/`longitude` or `dx`/`dy` arrays
//! in degrees. PNG, EXR, raw and NPY store neither: they read with a 1 m cell unless
//! [`ReadOptions::cell_size`] says otherwise. Rows stored south-up (GeoTIFF with a positive y
//! pixel size, NPZ with an ascending latitude array) are flipped to put north first
//! ([`Raster::rows_flipped`]) and the GeoTIFF tags are rewritten for the flipped grid.
//!
//! Not guaranteed: reprojection (cell sizes of geographic grids are computed at the centre
//! latitude on the WGS84 ellipsoid), multi-band rasters (only the first band of a single-sample
//! image is read), BigTIFF from the in-memory writer [`write()`] (the streaming writers,
//! [`GeoTiffStripWriter`] and [`TiledGeoTiffWriter`], write BigTIFF past 4 GiB).
//!
//! One grid convention: pixel-is-area. A PixelIsPoint GeoTIFF is read as the equivalent
//! PixelIsArea grid (origin half a pixel out, as `gdalinfo` reports it) and written back as
//! PixelIsArea; SRTM tiles get their EPSG:4326 pixel-centre grid from the tile name. GDAL's
//! `SCALE`/`OFFSET` metadata (tag 42112) is applied on read. GeoTIFF output is uncompressed or
//! DEFLATE with the floating-point predictor ([`WriteOptions::compression`]).
//!
//! # Example
//! ```
//! use relief_heightfield::Heightfield;
//! use relief_io::{read, write, ReadOptions, WriteOptions};
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("dem.tif");
//! let hf = Heightfield::from_fn(8, 5, 30.0, 30.0, |x, y| (x * 10 + y) as f32);
//! write(&path, &hf, &WriteOptions::default()).unwrap();
//! let back = read(&path, &ReadOptions::default()).unwrap();
//! assert_eq!(back.heightfield.as_slice(), hf.as_slice());
//! assert_eq!(back.heightfield.cell_size(), (30.0, 30.0));
//! ```
#![warn(missing_docs)]

mod ascii;
mod atomic;
pub mod crs;
mod error;
mod exr_io;
mod geotiff;
pub mod heightmap16;
mod hgt;
mod mesh;
mod npy;
mod png_io;
mod preview;
mod raw;
mod sidecar;
mod stream;
mod tiff_dir;
mod tiled;
mod util;
pub mod wkt_keys;

use std::path::Path;

use relief_heightfield::{GeoRef, Heightfield};

pub use atomic::{Staging, create_new_only, create_staging_dir, remove_own_temporaries};
pub use error::{IoError, Result};
pub use geotiff::bands::GeoTiffBands;
pub use geotiff::{DEFLATE_LEVEL, TiffCompression};
pub use mesh::{MeshFormat, encode_mesh, write_mesh, write_mesh_as, z_up_to_y_up};
pub use npy::npy_f32;
pub use preview::{
    PreviewStyle, RgbaPngWriter, preview_rgb, preview_rgb_with, write_gray_png, write_preview_png,
    write_preview_png_with, write_rgb_png, write_rgba_png,
};
pub use stream::GeoTiffStripWriter;
pub use tiled::{EncodedBlocks, GeoTiffRowReader, TiledGeoTiffWriter, TiledOptions};

/// A raster or mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Format {
    /// GeoTIFF / TIFF (`.tif`, `.tiff`).
    GeoTiff,
    /// SRTM height tile (`.hgt`): square big-endian int16.
    Hgt,
    /// ESRI ASCII grid (`.asc`).
    AsciiGrid,
    /// 8- or 16-bit greyscale PNG with an optional relief vertical mapping.
    Png,
    /// Mapbox Terrain-RGB PNG (height = -10000 + (R*65536 + G*256 + B) * 0.1).
    TerrainRgb,
    /// OpenEXR, one channel (f32 or f16).
    Exr,
    /// Raw little-endian u16 (`.r16`).
    R16,
    /// Raw little-endian f32 (`.r32`).
    R32,
    /// NumPy array (`.npy`).
    Npy,
    /// NumPy zip archive (`.npz`).
    Npz,
    /// Raw little-endian f32 with a `.json` sidecar (`.f32`), as in `shared/data/dem`.
    F32Sidecar,
    /// JSON grid `{"width", "height", "values"}` (e.g. `volcano.json`).
    JsonGrid,
}

impl Format {
    /// The format a file name's extension suggests (case-insensitive), if any.
    pub fn from_extension(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "tif" | "tiff" | "gtiff" => Format::GeoTiff,
            "hgt" => Format::Hgt,
            "asc" | "grd" => Format::AsciiGrid,
            "png" => Format::Png,
            "exr" => Format::Exr,
            "r16" | "raw" => Format::R16,
            "r32" => Format::R32,
            "npy" => Format::Npy,
            "npz" => Format::Npz,
            "f32" => Format::F32Sidecar,
            "json" => Format::JsonGrid,
            _ => return None,
        })
    }

    /// Detects the format of `bytes` from their magic numbers; `path_hint` (a file name) is
    /// used only for formats without magic (raw, hgt, `.f32`) or to pick between two that share
    /// one (PNG grey vs Terrain-RGB is decided when reading).
    pub fn detect(bytes: &[u8], path_hint: Option<&Path>) -> Result<Format> {
        let hint = path_hint.and_then(Format::from_extension);
        if bytes.starts_with(b"II*\0")
            || bytes.starts_with(b"MM\0*")
            || bytes.starts_with(b"II+\0")
            || bytes.starts_with(b"MM\0+")
        {
            return Ok(Format::GeoTiff);
        }
        if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
            return Ok(if hint == Some(Format::TerrainRgb) {
                Format::TerrainRgb
            } else {
                Format::Png
            });
        }
        if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
            return Ok(Format::Exr);
        }
        if bytes.starts_with(b"\x93NUMPY") {
            return Ok(Format::Npy);
        }
        if bytes.starts_with(b"PK\x03\x04") || bytes.starts_with(b"PK\x05\x06") {
            return Ok(Format::Npz);
        }
        // Raw formats have no magic: their samples may look like text, so a raw hint wins over
        // the text heuristics below.
        if let Some(f @ (Format::Hgt | Format::R16 | Format::R32 | Format::F32Sidecar)) = hint {
            return Ok(f);
        }
        let head = String::from_utf8_lossy(&bytes[..bytes.len().min(64)]).to_ascii_lowercase();
        let trimmed = head.trim_start();
        if trimmed.starts_with("ncols") || trimmed.starts_with("nrows") {
            return Ok(Format::AsciiGrid);
        }
        if trimmed.starts_with('{') {
            return Ok(Format::JsonGrid);
        }
        match hint {
            Some(f @ (Format::Hgt | Format::R16 | Format::R32 | Format::F32Sidecar)) => Ok(f),
            Some(f) => Err(IoError::malformed(
                f,
                format!(
                    "wrong magic bytes {:02x?} for a {f:?} file",
                    &bytes[..bytes.len().min(8)]
                ),
            )),
            None => Err(IoError::UnknownFormat(format!(
                "no known magic bytes ({:02x?}) and no recognised extension",
                &bytes[..bytes.len().min(8)]
            ))),
        }
    }
}

/// How a PNG's 8/16-bit samples become metres.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum PngMode {
    /// Use the relief `tEXt` mapping (or Terrain-RGB `tEXt` marker) when present; otherwise grey
    /// samples are taken as raw counts (0..255 or 0..65535) and colour PNGs are rejected.
    #[default]
    Auto,
    /// Grey samples mapped as `offset + scale * count`, ignoring any `tEXt` chunk.
    Grey {
        /// Height of count 0.
        offset: f64,
        /// Metres per count.
        scale: f64,
    },
    /// Mapbox Terrain-RGB decoding of an 8-bit RGB(A) PNG.
    TerrainRgb,
}

/// Options of [`read`] / [`read_bytes`]. Use `ReadOptions { width: Some(512), ..Default::default() }`.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadOptions {
    /// Width of a raw `.r16` / `.r32` / headerless `.f32` file (square assumed if both are `None`).
    pub width: Option<usize>,
    /// Height of a raw file (derived from the length and `width` if `None`).
    pub height: Option<usize>,
    /// Largest number of cells accepted before allocation (default 2^28 = 268 M cells, 1 GiB of
    /// f32). Raise it explicitly for larger rasters; at most `relief_heightfield::MAX_CELLS`.
    pub max_cells: usize,
    /// PNG interpretation.
    pub png: PngMode,
    /// Vertical mapping `offset + scale * count` of raw `.r16` files (default `(0, 1)`).
    pub r16_mapping: (f64, f64),
    /// Cell size `(x, y)` in metres for formats that do not store one (PNG, EXR, raw, NPY);
    /// also overrides the stored one when set.
    pub cell_size: Option<(f64, f64)>,
    /// Name of the array to read from an `.npz` (default: `elevation`, `topo`, `z`, `dem`,
    /// then the first 2-D numeric array).
    pub npz_array: Option<String>,
}

impl Default for ReadOptions {
    fn default() -> Self {
        ReadOptions {
            width: None,
            height: None,
            max_cells: 1 << 28,
            png: PngMode::Auto,
            r16_mapping: (0.0, 1.0),
            cell_size: None,
            npz_array: None,
        }
    }
}

/// Options of [`write()`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WriteOptions {
    /// Output format; `None` = from the extension.
    pub format: Option<Format>,
    /// Vertical mapping `(offset, scale)` for PNG16 / `.r16` output: metres = offset + scale *
    /// count. `None` maps the finite range onto `0..=65535` (a flat field gets scale 1).
    pub mapping: Option<(f64, f64)>,
    /// Strip compression of GeoTIFF output (other formats ignore it).
    pub compression: TiffCompression,
}

/// A raster read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct Raster {
    /// The elevations (row 0 north, voids NaN, georeference in `heightfield.georef()`).
    pub heightfield: Heightfield,
    /// The format the file was decoded as.
    pub format: Format,
    /// The nodata value the file declared (its cells are NaN in `heightfield`).
    pub nodata: Option<f64>,
    /// Data type of the stored samples, e.g. `"int16"`, `"float32"`.
    pub dtype: String,
    /// Whether rows were flipped to put north first (south-up storage).
    pub rows_flipped: bool,
}

/// Reads the raster at `path`, detecting its format from the magic bytes (extension as a hint).
///
/// `.f32` files take their size and cell size from the `.json` sidecar with the same stem.
pub fn read(path: &Path, opts: &ReadOptions) -> Result<Raster> {
    check_max_cells(opts)?;
    // No format needs more than 32 bytes per cell (ASCII text), so a larger file is refused
    // before it is read into memory.
    let len = std::fs::metadata(path)
        .map_err(|e| IoError::os(path, e))?
        .len();
    let cap = (opts.max_cells as u64)
        .saturating_mul(32)
        .saturating_add(1 << 20);
    if len > cap {
        return Err(IoError::param(
            "max_cells",
            opts.max_cells,
            format!(
                "the file has {len} bytes, more than any raster within the cell limit ({cap} bytes)"
            ),
        )
        .in_file(path));
    }
    // Devices and pipes report a length of 0: read them through the same cap, never to the
    // end of an endless stream (`/dev/zero`).
    let bytes = {
        let file = std::fs::File::open(path).map_err(|e| IoError::os(path, e))?;
        let buf = read_capped(file, cap + 1, len).map_err(|e| match e {
            ReadCapped::Io(e) => IoError::os(path, e),
            ReadCapped::Alloc(n) => IoError::param(
                "max_cells",
                opts.max_cells,
                format!("cannot allocate {n} bytes to read the file (lower the cell limit)"),
            )
            .in_file(path),
        })?;
        if buf.len() as u64 > cap {
            return Err(IoError::param(
                "max_cells",
                opts.max_cells,
                format!("the stream is longer than any raster within the cell limit ({cap} bytes)"),
            )
            .in_file(path));
        }
        buf
    };
    let format = Format::detect(&bytes, Some(path)).map_err(|e| e.in_file(path))?;
    let res = match format {
        Format::F32Sidecar => sidecar::read_f32_file(path, &bytes, opts),
        Format::JsonGrid => sidecar::read_json_any(path, &bytes, opts),
        Format::AsciiGrid => read_bytes(&bytes, Some(path), opts).map(|mut r| {
            ascii_prj_crs(&mut r.heightfield, path);
            r
        }),
        _ => return read_bytes(&bytes, Some(path), opts).map_err(|e| e.in_file(path)),
    };
    let mut raster = res.map_err(|e| e.in_file(path))?;
    if let Some((cx, cy)) = opts.cell_size {
        raster
            .heightfield
            .set_cell_size(cx, cy)
            .map_err(|e| IoError::from(e).in_file(path))?;
    }
    Ok(raster)
}

/// The `.prj` beside an ESRI ASCII grid names its CRS (GDAL's convention): recorded in the
/// grid's georeference when readable. A missing or unreadable `.prj` leaves it unset.
fn ascii_prj_crs(hf: &mut Heightfield, path: &Path) {
    let prj = path.with_extension("prj");
    let Ok(meta) = std::fs::metadata(&prj) else {
        return;
    };
    if !meta.is_file() || meta.len() > 1 << 16 {
        return;
    }
    let Ok(text) = std::fs::read_to_string(&prj) else {
        return;
    };
    if let (Some(crs), Some(g)) = (crs::crs_of_prj(&text), hf.georef().cloned()) {
        hf.set_georef(Some(GeoRef {
            crs: Some(crs),
            ..g
        }));
    }
}

/// The `.prj` file written beside an ESRI ASCII grid at `path`: its path and WKT, when the
/// grid's CRS is one [`crs::epsg_wkt`] knows.
pub fn ascii_prj(path: &Path, hf: &Heightfield) -> Option<(std::path::PathBuf, String)> {
    let wkt = crs::wkt(hf.georef()?)?;
    Some((path.with_extension("prj"), wkt))
}

/// Why [`read_capped`] failed.
#[derive(Debug)]
pub(crate) enum ReadCapped {
    /// The read itself.
    Io(std::io::Error),
    /// The buffer could not grow to this many bytes.
    Alloc(usize),
}

/// Reads at most `limit` bytes of `r` into memory (`hint`: the expected length, 0 when
/// unknown, as for devices and pipes). The buffer grows with `try_reserve`, so an allocation
/// the process cannot make is an error instead of an abort.
pub(crate) fn read_capped(
    r: impl std::io::Read,
    limit: u64,
    hint: u64,
) -> std::result::Result<Vec<u8>, ReadCapped> {
    use std::io::Read as _;
    let mut r = r.take(limit);
    let mut buf: Vec<u8> = Vec::new();
    let first = hint.min(limit).min(1 << 30) as usize;
    buf.try_reserve_exact(first.max(1 << 16))
        .map_err(|_| ReadCapped::Alloc(first))?;
    loop {
        if buf.len() == buf.capacity() {
            let more = buf.len().max(1 << 16);
            buf.try_reserve(more)
                .map_err(|_| ReadCapped::Alloc(buf.len() + more))?;
        }
        // At most 4 MiB per read, so zero-filling the spare part stays linear in the size.
        let spare = (buf.capacity() - buf.len()).min(4 << 20);
        let start = buf.len();
        buf.resize(start + spare, 0);
        match r.read(&mut buf[start..]) {
            Ok(0) => {
                buf.truncate(start);
                return Ok(buf);
            }
            Ok(n) => buf.truncate(start + n),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => buf.truncate(start),
            Err(e) => return Err(ReadCapped::Io(e)),
        }
    }
}

/// Reads a raster from memory; `hint` is a file name used for formats without magic bytes.
pub fn read_bytes(bytes: &[u8], hint: Option<&Path>, opts: &ReadOptions) -> Result<Raster> {
    check_max_cells(opts)?;
    let format = Format::detect(bytes, hint)?;
    let mut raster = match format {
        Format::GeoTiff => geotiff::read(bytes, opts),
        Format::Hgt => hgt::read(bytes, opts),
        Format::AsciiGrid => ascii::read(bytes, opts),
        Format::Png | Format::TerrainRgb => png_io::read(bytes, format, opts),
        Format::Exr => exr_io::read(bytes, opts),
        Format::R16 | Format::R32 => raw::read(bytes, format, opts),
        Format::Npy => npy::read_npy(bytes, opts),
        Format::Npz => npy::read_npz(bytes, opts),
        Format::F32Sidecar => sidecar::read_f32_bytes(bytes, None, opts),
        Format::JsonGrid => sidecar::read_json_grid(bytes, opts),
    }?;
    if format == Format::Hgt {
        let name = hint
            .and_then(|p| p.file_name())
            .map(|s| s.to_string_lossy().into_owned());
        if let Some(n) = name.as_deref() {
            hgt::check_tile_name(n)?;
        }
        let n = raster.heightfield.width();
        if let Some((cx, cy)) = name.as_deref().and_then(|s| hgt::tile_cell_from_name(s, n)) {
            raster.heightfield.set_cell_size(cx, cy)?;
        }
        if let Some(g) = name.as_deref().and_then(|s| hgt::tile_georef(s, n)) {
            raster.heightfield.set_georef(Some(g));
        }
    }
    if let Some((cx, cy)) = opts.cell_size {
        raster.heightfield.set_cell_size(cx, cy)?;
    }
    Ok(raster)
}

/// Reads `.f32` data from memory with the text of its `.json` sidecar (`None`: the size comes
/// from `opts.width/height`, or a square), as [`read`] does for a `.f32` file on disk.
pub fn read_f32_sidecar_bytes(
    data: &[u8],
    sidecar_json: Option<&[u8]>,
    opts: &ReadOptions,
) -> Result<Raster> {
    check_max_cells(opts)?;
    let side = sidecar_json
        .map(|t| sidecar::parse_sidecar_text(t, "json"))
        .transpose()?;
    let mut raster = sidecar::read_f32_bytes(data, side, opts)?;
    if let Some((cx, cy)) = opts.cell_size {
        raster.heightfield.set_cell_size(cx, cy)?;
    }
    Ok(raster)
}

fn check_max_cells(opts: &ReadOptions) -> Result<()> {
    if opts.max_cells == 0 || opts.max_cells > relief_heightfield::MAX_CELLS {
        return Err(IoError::param(
            "max_cells",
            opts.max_cells,
            format!("must be in 1..={}", relief_heightfield::MAX_CELLS),
        ));
    }
    if let Some((cx, cy)) = opts.cell_size {
        let (lo, hi) = util::CELL_RANGE_M;
        if !(cx.is_finite() && cy.is_finite() && (lo..=hi).contains(&cx) && (lo..=hi).contains(&cy))
        {
            return Err(IoError::param(
                "cell_size",
                format!("{cx} x {cy}"),
                format!("each must be a number of metres in {lo:e}..{hi:e}"),
            ));
        }
    }
    Ok(())
}

/// Writes `bytes` to `path` atomically: a temporary file in the same directory (hidden name
/// `.<name>.tmp-<pid>-<n>`) is written, synced and renamed over `path`. On error the temporary
/// file is removed and `path` is untouched (an existing file keeps its old content). For
/// non-raster outputs (`.sct`, dictionaries, reports).
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic::write_atomic(path, bytes)
}

/// Removes the temporaries that killed runs left in `dir` (hidden `.<name>.tmp-<pid>-<n>`
/// files and `.relief-stage-<pid>-<n>` folders of processes that no longer exist); every write
/// does this for its own folder. Errors are ignored (housekeeping).
pub fn remove_stale_temporaries(dir: &Path) {
    atomic::remove_stale_temps_in(dir);
}

/// Writes `hf` to `path` atomically; the format comes from `opts.format` or the extension
/// (`.tif/.tiff`, `.hgt`, `.asc` (+ `.prj` when the CRS is known, see [`crs`]), `.png`,
/// `.exr`, `.r16`, `.r32`, `.npy`, `.f32` (+ `.json`)). The files of one write appear together.
pub fn write(path: &Path, hf: &Heightfield, opts: &WriteOptions) -> Result<()> {
    let format = match opts.format.or_else(|| Format::from_extension(path)) {
        Some(f) => f,
        None => {
            return Err(IoError::UnknownFormat(format!(
                "{}: cannot choose an output format from the extension",
                path.display()
            )));
        }
    };
    let bytes = encode(hf, format, opts).map_err(|e| e.in_file(path))?;
    if format == Format::F32Sidecar {
        let json = sidecar::sidecar_json(hf);
        let json_path = path.with_extension("json");
        atomic::write_all_atomic(&[(path, &bytes), (&json_path, json.as_bytes())])
    } else if let Some((prj, wkt)) = (format == Format::AsciiGrid)
        .then(|| ascii_prj(path, hf))
        .flatten()
    {
        atomic::write_all_atomic(&[(path, &bytes), (&prj, wkt.as_bytes())])
    } else {
        atomic::write_atomic(path, &bytes)
    }
}

/// Encodes `hf` as the bytes of a `format` file (no file is touched).
pub fn encode(hf: &Heightfield, format: Format, opts: &WriteOptions) -> Result<Vec<u8>> {
    match format {
        Format::GeoTiff => geotiff::write_with(hf, opts.compression),
        Format::Hgt => hgt::write(hf),
        Format::AsciiGrid => ascii::write(hf),
        Format::Png => png_io::write_png16(hf, opts.mapping),
        Format::TerrainRgb => png_io::write_terrain_rgb(hf),
        Format::Exr => exr_io::write(hf),
        Format::R16 => raw::write_r16(hf, opts.mapping),
        Format::R32 => raw::write_r32(hf),
        Format::Npy => Ok(npy::write_npy(hf)),
        Format::F32Sidecar => Ok(raw::f32_sidecar_bytes(hf)),
        Format::Npz | Format::JsonGrid => Err(IoError::unsupported(
            format,
            "writing this format is not supported; use .npy or .f32",
        )),
    }
}
