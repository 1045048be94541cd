//! GeoTIFF reading (via the `tiff` crate, guarded by our own size checks) and float32 writing
//! with the georeference kept verbatim.

use std::io::Cursor;

use relief_heightfield::{GeoRef, Heightfield};
use tiff::decoder::Decoder;
use tiff::encoder::{TiffEncoder, colortype};
use tiff::tags::Tag;

use crate::util::{check_dims, finish, flip_rows};
use crate::{Format, IoError, Raster, ReadOptions, Result};

pub(crate) mod bands;
mod directory;

use directory::Tags;
pub(crate) use directory::read_chunk_row;

const F: Format = Format::GeoTiff;

fn terr(e: tiff::TiffError) -> IoError {
    use tiff::{TiffError, TiffFormatError};
    // The codec's generic messages, said in terms of the parts of the file.
    let reason = match &e {
        TiffError::FormatError(TiffFormatError::InconsistentSizesEncountered) => {
            "the strip/tile tables disagree with the image (StripOffsets / StripByteCounts / \
             TileOffsets / TileByteCounts counts vs RowsPerStrip and the image size, or \
             BitsPerSample / ExtraSamples vs SamplesPerPixel)"
                .to_string()
        }
        TiffError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "truncated file: a tag value, strip or tile lies past the end of the file".to_string()
        }
        _ => e.to_string(),
    };
    IoError::malformed(F, reason)
}

// GeoKey ids (GeoTIFF 1.1, section 7).
const GT_MODEL_TYPE: u16 = 1024;
const GT_RASTER_TYPE: u16 = 1025;
/// `GTRasterTypeGeoKey` values.
const PIXEL_IS_AREA: u16 = 1;
const PIXEL_IS_POINT: u16 = 2;
/// GDAL's metadata tag (XML items such as SCALE and OFFSET).
const GDAL_METADATA_TAG: u16 = 42112;
const GEOGRAPHIC_TYPE: u16 = 2048;
const GEOG_ANGULAR_UNITS: u16 = 2054;
const PROJECTED_CS_TYPE: u16 = 3072;

fn geo_key(dir: &[u16], key: u16) -> Option<u16> {
    // Header: version, revision, minor, count; then (key, location, count, value) quadruples.
    if dir.len() < 4 {
        return None;
    }
    let n = dir[3] as usize;
    dir[4..]
        .chunks_exact(4)
        .take(n)
        .find(|k| k[0] == key && k[1] == 0)
        .map(|k| k[3])
}

/// WGS84 ground lengths (east-west, north-south) of one degree at latitude `lat_deg`.
pub(crate) fn metres_per_degree(lat_deg: f64) -> (f64, f64) {
    let a = 6_378_137.0f64;
    let e2 = 6.694_379_990_14e-3f64;
    let phi = lat_deg.to_radians();
    let s = 1.0 - e2 * phi.sin().powi(2);
    let n = a / s.sqrt();
    let m = a * (1.0 - e2) / s.powf(1.5);
    let d = std::f64::consts::PI / 180.0;
    (n * phi.cos() * d, m * d)
}

/// Checks, before the decoder touches them, that every chunk lies inside the file and that
/// the chunks hold enough bytes for the `w x h = n` declared samples.
fn check_chunks(
    dec: &mut Decoder<Cursor<&[u8]>>,
    bytes: &[u8],
    (w, h, n): (u32, u32, usize),
    bits: u8,
    dtype: &str,
) -> Result<()> {
    let (kind, counts) = directory::check_chunks_in_file(dec, bytes.len() as u64)?;
    let compression = dec
        .find_tag_unsigned::<u16>(Tag::Compression)
        .map_err(terr)?
        .unwrap_or(1);
    if let Some(name) = crate::tiff_dir::unreadable_compression(compression) {
        return Err(IoError::unsupported(
            F,
            format!(
                "{name} compression (TIFF compression {compression}) is not read by relief; \
                 convert the file to a lossless one first, e.g. `gdal_translate -co \
                 COMPRESS=DEFLATE -co PREDICTOR=3 IN.tif OUT.tif`"
            ),
        ));
    }
    let total: u64 = counts.iter().fold(0u64, |a, &c| a.saturating_add(c));
    let needed = n as u64 * (bits as u64 / 8);
    if compression == 1 {
        if total < needed {
            return Err(IoError::truncated(
                F,
                format!("{w} x {h} uncompressed {dtype} samples"),
                needed,
                total,
            ));
        }
    } else if let Some((name, ratio)) = crate::tiff_dir::max_ratio(compression)
        && total.saturating_mul(ratio) < needed
    {
        // A compressed chunk cannot inflate beyond the codec's largest ratio: a file whose
        // chunks hold too few bytes for its declared samples is refused before the decoder
        // allocates for them.
        return Err(IoError::malformed(
            F,
            format!(
                "{w} x {h} {dtype} samples need {needed} bytes, but the {kind} byte counts \
                 (StripByteCounts / TileByteCounts) total {total} bytes, which {name} cannot \
                 inflate beyond {ratio}:1"
            ),
        ));
    }
    Ok(())
}

pub(crate) fn read(bytes: &[u8], opts: &ReadOptions) -> Result<Raster> {
    let mut dec = directory::decoder(Cursor::new(bytes), opts)?;
    let (w, h) = dec.dimensions().map_err(terr)?;
    let n = check_dims(F, w as u64, h as u64, opts)?;
    let (bits, dtype) = directory::sample_type(&mut dec)?;
    check_chunks(&mut dec, bytes, (w, h, n), bits, dtype)?;
    let mut tags = Tags::read(&mut dec)?;

    let decoded = dec.read_image().map_err(terr)?;
    let mut data = directory::samples_f32(decoded)
        .ok_or_else(|| IoError::unsupported(F, format!("decoded sample type of {dtype}")))?;
    if data.len() != n {
        return Err(IoError::malformed(
            F,
            format!("decoded {} samples, expected {w} x {h} = {n}", data.len()),
        ));
    }
    let (w, h) = (w as usize, h as usize);
    let (flipped, cell) = tags.complete_georef(w, h)?;
    if flipped {
        flip_rows(&mut data, w);
    }
    let Tags { nodata, geo, .. } = &tags;
    let georef = (*geo != GeoRef::default()).then(|| geo.clone());
    let mut r = finish(F, w, h, data, cell, *nodata, dtype)?;
    if let Some((s, o)) = tags.scale()? {
        // GDAL's unit scaling (e.g. an int16 DEM stored in decimetres): nodata was matched
        // on the stored values above, the heights are scaled values.
        r.heightfield = r.heightfield.map(|v| (v as f64 * s + o) as f32);
    }
    r.heightfield.set_georef(georef);
    r.rows_flipped = flipped;
    Ok(r)
}

/// Fills `geotransform` and `crs` from the raw tags. If the grid is stored south-up (positive
/// y pixel size), rewrites the tags for the row-flipped grid and returns `true`.
fn complete_georef(g: &mut GeoRef, _w: usize, h: usize) -> bool {
    to_pixel_is_area(g);
    let mut flipped = false;
    if let Some(m) = g.transformation.as_mut().filter(|m| m.len() == 16) {
        // y = m4 * i + m5 * j + m7.
        if m[5] > 0.0 && m[1] == 0.0 && m[4] == 0.0 {
            m[7] += m[5] * h as f64;
            m[5] = -m[5];
            flipped = true;
        }
        g.geotransform = Some([m[3], m[0], m[1], m[7], m[4], m[5]]);
    } else if let (Some(s), Some(t)) = (g.pixel_scale.as_mut(), g.tiepoints.as_mut())
        && s.len() >= 2
        && t.len() >= 6
    {
        // Raster point (i, j) maps to (X, Y): X = Xt + (i - it) * sx, Y = Yt - (j - jt) * sy.
        if s[1] < 0.0 {
            // South-up: Y grows with j. After flipping, row j' = h - j; put the tiepoint
            // at the new top-left corner.
            let (x0, y_top) = (t[3] - t[0] * s[0], t[4] + (h as f64 - t[1]) * (-s[1]));
            s[1] = -s[1];
            t.truncate(6);
            t[0] = 0.0;
            t[1] = 0.0;
            t[3] = x0;
            t[4] = y_top;
            flipped = true;
        }
        g.geotransform = Some([
            t[3] - t[0] * s[0],
            s[0],
            0.0,
            t[4] + t[1] * s[1],
            0.0,
            -s[1],
        ]);
    }
    if let Some(dir) = g.geo_key_directory.as_deref() {
        if let Some(code) = geo_key(dir, PROJECTED_CS_TYPE).filter(|&c| c != 0 && c != 32767) {
            g.crs = Some(format!("EPSG:{code}"));
        } else if let Some(code) = geo_key(dir, GEOGRAPHIC_TYPE).filter(|&c| c != 0 && c != 32767) {
            g.crs = Some(format!("EPSG:{code}"));
        } else if let Some(a) = g.geo_ascii_params.as_deref() {
            let a = a.trim_end_matches(['|', '\0']);
            if !a.is_empty() {
                g.crs = Some(a.to_string());
            }
        }
    }
    flipped
}

/// Refuses a georeference whose pixel size or origin is not a finite number, or whose pixel
/// size is zero (NaN in ModelPixelScale, inf in ModelTiepoint), naming the tag.
fn check_georef_values(g: &GeoRef) -> Result<()> {
    let Some(t) = g.geotransform else {
        return Ok(());
    };
    let tag = if g.transformation.is_some() {
        "ModelTransformationTag"
    } else {
        "ModelPixelScaleTag"
    };
    let (sx, sy) = (
        (t[1].powi(2) + t[4].powi(2)).sqrt(),
        (t[2].powi(2) + t[5].powi(2)).sqrt(),
    );
    if !(sx.is_finite() && sy.is_finite() && sx > 0.0 && sy > 0.0) {
        return Err(IoError::malformed(
            F,
            format!("{tag}: pixel size {sx} x {sy} is not a finite positive number"),
        ));
    }
    let origin_tag = if g.transformation.is_some() {
        "ModelTransformationTag"
    } else {
        "ModelTiepointTag"
    };
    crate::util::check_origin(F, &format!("{origin_tag} origin x"), t[0])?;
    crate::util::check_origin(F, &format!("{origin_tag} origin y"), t[3])
}

/// Rewrites a PixelIsPoint georeference as the equivalent PixelIsArea one, the single grid
/// convention of the workspace (and what GDAL reports): a PixelIsPoint tiepoint at raster
/// `(i, j)` names the centre of that pixel, i.e. area coordinate `(i + 1/2, j + 1/2)`; a
/// transformation matrix moves by half a pixel. The raster-type key becomes PixelIsArea, so
/// files written from it say what they mean.
fn to_pixel_is_area(g: &mut GeoRef) {
    let Some(dir) = g.geo_key_directory.as_mut() else {
        return;
    };
    if geo_key(dir, GT_RASTER_TYPE) != Some(PIXEL_IS_POINT) {
        return;
    }
    let n = dir.get(3).copied().unwrap_or(0) as usize;
    if let Some(k) = dir
        .get_mut(4..)
        .into_iter()
        .flat_map(|d| d.chunks_exact_mut(4))
        .take(n)
        .find(|k| k[0] == GT_RASTER_TYPE && k[1] == 0)
    {
        k[3] = PIXEL_IS_AREA;
    }
    if let Some(m) = g.transformation.as_mut().filter(|m| m.len() == 16) {
        m[3] -= 0.5 * (m[0] + m[1]);
        m[7] -= 0.5 * (m[4] + m[5]);
    } else if let Some(t) = g.tiepoints.as_mut() {
        for tp in t.chunks_exact_mut(6) {
            tp[0] += 0.5;
            tp[1] += 0.5;
        }
    }
}

/// The `SCALE` and `OFFSET` items of band 0 in GDAL's metadata XML (tag 42112), if any:
/// stored values `v` mean `v * scale + offset`.
fn gdal_scale_offset(xml: &str) -> (Option<f64>, Option<f64>) {
    let mut scale = None;
    let mut offset = None;
    for item in xml.split("<Item").skip(1) {
        let Some((attrs, rest)) = item.split_once('>') else {
            continue;
        };
        let value = rest.split('<').next().unwrap_or("").trim();
        let attr = |name: &str| {
            attrs
                .split_once(&format!("{name}=\""))
                .and_then(|(_, r)| r.split('"').next())
        };
        if attr("sample").is_some_and(|s| s != "0") {
            continue;
        }
        let v = value.parse::<f64>().ok().filter(|v| v.is_finite());
        match (attr("name"), attr("role")) {
            (Some("SCALE"), _) | (_, Some("scale")) => scale = v,
            (Some("OFFSET"), _) | (_, Some("offset")) => offset = v,
            _ => {}
        }
    }
    (scale, offset)
}

/// Ground cell size in metres: geographic grids at the centre latitude (WGS84), Web Mercator
/// scaled by cos(latitude), other projections taken as metres.
pub(crate) fn cell_size(g: &GeoRef, h: usize) -> Option<(f64, f64)> {
    let t = g.geotransform?;
    let (sx, sy) = (
        (t[1].powi(2) + t[4].powi(2)).sqrt(),
        (t[2].powi(2) + t[5].powi(2)).sqrt(),
    );
    if !(sx > 0.0 && sy > 0.0 && sx.is_finite() && sy.is_finite()) {
        return None;
    }
    let dir = g.geo_key_directory.as_deref().unwrap_or(&[]);
    let model = geo_key(dir, GT_MODEL_TYPE);
    let cy_coord = t[3] + t[5] * h as f64 / 2.0;
    if model == Some(2) {
        // GeogAngularUnitSizeGeoKey (2055): radians per unit, in GeoDoubleParams.
        let unit_size = dir
            .get(4..)
            .unwrap_or(&[])
            .chunks_exact(4)
            .find(|k| k[0] == 2055 && k[1] == 34736)
            .and_then(|k| g.geo_double_params.as_ref()?.get(k[3] as usize).copied())
            .filter(|r| r.is_finite() && *r > 0.0);
        let unit_deg = match geo_key(dir, GEOG_ANGULAR_UNITS) {
            _ if unit_size.is_some() => unit_size.unwrap_or(1.0).to_degrees(),
            Some(9101) => 180.0 / std::f64::consts::PI,
            Some(9103) => 1.0 / 60.0,
            Some(9104) => 1.0 / 3600.0,
            Some(9105) => 0.9,
            _ => 1.0,
        };
        let lat = cy_coord * unit_deg;
        if !(-90.0..=90.0).contains(&lat) {
            return None;
        }
        let (mx, my) = metres_per_degree(lat);
        return Some((sx * unit_deg * mx, sy * unit_deg * my));
    }
    if matches!(geo_key(dir, PROJECTED_CS_TYPE), Some(3857 | 3785)) {
        let lat = (cy_coord / 6_378_137.0).sinh().atan();
        return Some((sx * lat.cos(), sy * lat.cos()));
    }
    Some((sx, sy))
}

/// The georeference tags to write: verbatim when `georef` has raw tags; a georeference without
/// them (e.g. from an ASCII grid) is written from its affine transform, and none at all from
/// the cell size.
pub(crate) fn georef_tags(cell: (f64, f64), georef: Option<&GeoRef>) -> GeoRef {
    match georef {
        Some(g)
            if g.pixel_scale.is_some() || g.tiepoints.is_some() || g.transformation.is_some() =>
        {
            g.clone()
        }
        other => {
            let (cx, cy) = cell;
            let mut d = other.cloned().unwrap_or_default();
            match d.geotransform {
                Some(t) if t[2] == 0.0 && t[4] == 0.0 && t[5] < 0.0 => {
                    d.pixel_scale = Some(vec![t[1], -t[5], 0.0]);
                    d.tiepoints = Some(vec![0.0, 0.0, 0.0, t[0], t[3], 0.0]);
                }
                Some(t) => {
                    d.transformation = Some(vec![
                        t[1], t[2], 0.0, t[0], t[4], t[5], 0.0, t[3], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                        0.0, 1.0,
                    ]);
                }
                None => {
                    d.pixel_scale = Some(vec![cx, cy, 0.0]);
                    d.tiepoints = Some(vec![0.0; 6]);
                }
            }
            d
        }
    }
}

/// libdeflate level of [`TiffCompression::Deflate`]: 1, libdeflate's fastest parser (one hash
/// table, no match chains). GDAL's default is 6 (lazy matching); on predicted float DEMs
/// the match search is mostly wasted on the random low mantissa bytes, so the sizes barely
/// differ while level 6 spent a quarter of an x256 amplification's CPU. Measured with
/// libdeflate 1.26 (2026-12-05): an amplified 8192^2 DEM 140.1 MB at level 1, 139.7 MB at
/// level 4, 138.5 MB at level 6, and the x256 CLI run 3.86-3.90 s against 4.00-4.09 s at
/// level 4; carrizo.tif 851 kB and grandcanyon.tif 273 kB as Float32, smaller than
/// `gdal_translate -co COMPRESS=DEFLATE -co PREDICTOR=3` (859 kB, 273 kB); the smooth field of
/// the test below 1.91x (level 4: 1.99x; the test's bound catches a level that would store it
/// uncompressed).
pub const DEFLATE_LEVEL: i32 = 1;

/// Compression of GeoTIFF output strips.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum TiffCompression {
    /// Uncompressed strips (fastest to write, 4 bytes per cell).
    #[default]
    None,
    /// DEFLATE (zlib stream, libdeflate level [`DEFLATE_LEVEL`]) with the TIFF floating-point
    /// predictor (3), as
    /// `gdal_translate -co COMPRESS=DEFLATE -co PREDICTOR=3` writes: the usual lossless choice
    /// for float DEMs (typically 2-4x smaller than uncompressed).
    Deflate,
    /// Zstandard (level 9) with the floating-point predictor, GDAL's `COMPRESS=ZSTD
    /// PREDICTOR=3` (TIFF compression 50000): about DEFLATE's size, faster to decode.
    Zstd,
    /// LZW with the floating-point predictor, `COMPRESS=LZW PREDICTOR=3`: the codec every
    /// TIFF reader has, larger than the other two.
    Lzw,
}

impl TiffCompression {
    /// The TIFF `Compression` tag value.
    pub(crate) fn tag(self) -> u16 {
        match self {
            TiffCompression::None => 1,
            TiffCompression::Deflate => 8,
            TiffCompression::Zstd => 50000,
            TiffCompression::Lzw => 5,
        }
    }

    /// The bytes of a strip or tile of `width`-sample rows: raw little-endian samples when
    /// uncompressed, else the floating-point-predicted rows through the codec.
    pub(crate) fn encode(self, samples: &[f32], width: usize) -> Result<Vec<u8>> {
        if self == TiffCompression::None {
            return Ok(samples.iter().flat_map(|v| v.to_le_bytes()).collect());
        }
        CODEC_SCRATCH.with_borrow_mut(|sc| {
            let raw = &mut sc.raw;
            raw.clear();
            raw.reserve(samples.len() * 4);
            for row in samples.chunks(width.max(1)) {
                fp_predict_row(row, raw);
            }
            self.compress(raw, &mut sc.deflate)
        })
    }

    /// The codec's stream of the predicted bytes `raw` (not [`TiffCompression::None`]).
    fn compress(self, raw: &[u8], deflate: &mut Option<DeflateScratch>) -> Result<Vec<u8>> {
        let failed = |e: std::io::Error| IoError::unsupported(F, format!("{self:?} failed: {e}"));
        match self {
            TiffCompression::Deflate => {
                // libdeflate, the DEFLATE codec GDAL links: the same stream format as zlib.
                let d = match deflate {
                    Some(d) => d,
                    None => {
                        let level =
                            libdeflater::CompressionLvl::new(DEFLATE_LEVEL).map_err(|e| {
                                IoError::unsupported(F, format!("DEFLATE level: {e:?}"))
                            })?;
                        deflate.insert(DeflateScratch {
                            compressor: libdeflater::Compressor::new(level),
                            out: Vec::new(),
                        })
                    }
                };
                let bound = d.compressor.zlib_compress_bound(raw.len());
                if d.out.len() < bound {
                    d.out.resize(bound, 0);
                }
                let n = d
                    .compressor
                    .zlib_compress(raw, &mut d.out[..bound])
                    .map_err(|e| IoError::unsupported(F, format!("DEFLATE failed: {e:?}")))?;
                Ok(d.out[..n].to_vec())
            }
            TiffCompression::Zstd => zstd::bulk::compress(raw, 9).map_err(failed),
            TiffCompression::Lzw => {
                weezl::encode::Encoder::with_tiff_size_switch(weezl::BitOrder::Msb, 8)
                    .encode(raw)
                    .map_err(|e| IoError::unsupported(F, format!("LZW failed: {e}")))
            }
            TiffCompression::None => Ok(raw.to_vec()),
        }
    }
}

/// A thread's DEFLATE compressor and output buffer, kept from one strip or tile to the next.
struct DeflateScratch {
    compressor: libdeflater::Compressor,
    out: Vec<u8>,
}

/// A thread's codec buffers: the predicted bytes and the DEFLATE state. Reused from strip to
/// strip (a fresh compressor and two zeroed tile-sized buffers per tile cost about a tenth of
/// writing an 8192^2 DEFLATE GeoTIFF); the bytes written are the same.
#[derive(Default)]
struct CodecScratch {
    raw: Vec<u8>,
    deflate: Option<DeflateScratch>,
}

std::thread_local! {
    static CODEC_SCRATCH: std::cell::RefCell<CodecScratch> =
        std::cell::RefCell::new(CodecScratch::default());
}

/// TIFF Technical Note 3 floating-point predictor on one row of `f32` samples, appended to
/// `out` (4 bytes per sample): bytes regrouped most significant first, then byte-wise
/// horizontal differencing (libtiff's `fpDiff`).
pub(crate) fn fp_predict_row(row: &[f32], out: &mut Vec<u8>) {
    let start = out.len();
    for shift in [24u32, 16, 8, 0] {
        out.extend(row.iter().map(|v| (v.to_bits() >> shift) as u8));
    }
    // Each byte minus the byte before it (the original one): through a copy of a block, so
    // the loop reads one buffer and writes another and vectorises.
    let mut prev = 0u8;
    for block in out[start..].chunks_mut(64) {
        let mut orig = [0u8; 64];
        let orig = &mut orig[..block.len()];
        orig.copy_from_slice(block);
        block[0] = orig[0].wrapping_sub(prev);
        for (b, pair) in block[1..].iter_mut().zip(orig.windows(2)) {
            *b = pair[1].wrapping_sub(pair[0]);
        }
        prev = orig[orig.len() - 1];
    }
}

/// Rows per strip: about 64 KiB of samples, at least one row.
fn rows_per_strip(w: usize) -> usize {
    (65_536 / (4 * w.max(1))).max(1)
}

/// Writes the georeference tags (and `GDAL_NODATA` when there are voids) into a directory.
fn write_geo_tags<W: std::io::Write + std::io::Seek, K: tiff::encoder::TiffKind>(
    d: &mut tiff::encoder::DirectoryEncoder<'_, W, K>,
    hf: &Heightfield,
) -> Result<()> {
    let g = georef_tags(hf.cell_size(), hf.georef());
    write_opt_tag(d, Tag::ModelPixelScaleTag, g.pixel_scale.as_deref())?;
    write_opt_tag(d, Tag::ModelTiepointTag, g.tiepoints.as_deref())?;
    write_opt_tag(d, Tag::ModelTransformationTag, g.transformation.as_deref())?;
    write_opt_tag(d, Tag::GeoKeyDirectoryTag, g.geo_key_directory.as_deref())?;
    write_opt_tag(d, Tag::GeoDoubleParamsTag, g.geo_double_params.as_deref())?;
    write_opt_tag(d, Tag::GeoAsciiParamsTag, g.geo_ascii_params.as_deref())?;
    if hf.has_voids() {
        d.write_tag(Tag::GdalNodata, "nan").map_err(terr)?;
    }
    Ok(())
}

/// Writes `tag` into a directory when `value` is set.
fn write_opt_tag<W, K, T>(
    d: &mut tiff::encoder::DirectoryEncoder<'_, W, K>,
    tag: Tag,
    value: Option<&T>,
) -> Result<()>
where
    W: std::io::Write + std::io::Seek,
    K: tiff::encoder::TiffKind,
    T: tiff::encoder::TiffValue + ?Sized,
{
    match value {
        Some(v) => d.write_tag(tag, v).map_err(terr),
        None => Ok(()),
    }
}

/// Encodes `hf` as a float32 GeoTIFF with DEFLATE + floating-point predictor strips
/// (compressed in parallel; the bytes do not depend on the thread count).
fn write_compressed(hf: &Heightfield, compression: TiffCompression) -> Result<Vec<u8>> {
    use rayon::prelude::*;
    let (w, h) = (hf.width(), hf.height());
    let rps = rows_per_strip(w);
    let strips: Vec<Vec<u8>> = hf
        .as_slice()
        .par_chunks(rps * w)
        .map(|chunk| compression.encode(chunk, w))
        .collect::<Result<_>>()?;
    let total: u64 = strips.iter().map(|s| s.len() as u64).sum();
    if total > (u32::MAX as u64) - (1 << 20) {
        return Err(IoError::unsupported(
            F,
            "compressed raster larger than 4 GiB (BigTIFF writing is not supported)",
        ));
    }
    let mut buf = Cursor::new(Vec::with_capacity(total as usize + 4096));
    {
        let mut enc = TiffEncoder::new(&mut buf).map_err(terr)?;
        let mut d = enc.image_directory().map_err(terr)?;
        let mut offsets: Vec<u32> = Vec::with_capacity(strips.len());
        let mut counts: Vec<u32> = Vec::with_capacity(strips.len());
        for s in &strips {
            let off = d.write_data(s.as_slice()).map_err(terr)?;
            offsets.push(off as u32);
            counts.push(s.len() as u32);
        }
        d.write_tag(Tag::ImageWidth, w as u32).map_err(terr)?;
        d.write_tag(Tag::ImageLength, h as u32).map_err(terr)?;
        d.write_tag(Tag::BitsPerSample, 32u16).map_err(terr)?;
        d.write_tag(Tag::Compression, compression.tag())
            .map_err(terr)?;
        d.write_tag(Tag::PhotometricInterpretation, 1u16)
            .map_err(terr)?;
        d.write_tag(Tag::StripOffsets, offsets.as_slice())
            .map_err(terr)?;
        d.write_tag(Tag::SamplesPerPixel, 1u16).map_err(terr)?;
        d.write_tag(Tag::RowsPerStrip, rps as u32).map_err(terr)?;
        d.write_tag(Tag::StripByteCounts, counts.as_slice())
            .map_err(terr)?;
        d.write_tag(Tag::PlanarConfiguration, 1u16).map_err(terr)?;
        d.write_tag(Tag::Predictor, 3u16).map_err(terr)?;
        d.write_tag(Tag::SampleFormat, 3u16).map_err(terr)?;
        write_geo_tags(&mut d, hf)?;
        d.finish().map_err(terr)?;
    }
    Ok(buf.into_inner())
}

/// Encodes `hf` as a float32 GeoTIFF with the given strip compression.
pub(crate) fn write_with(hf: &Heightfield, compression: TiffCompression) -> Result<Vec<u8>> {
    check_classic_size(hf)?;
    match compression {
        TiffCompression::None => write(hf),
        c => write_compressed(hf, c),
    }
}

fn check_classic_size(hf: &Heightfield) -> Result<()> {
    let (w, h) = (hf.width(), hf.height());
    if u32::try_from(w).is_err() || u32::try_from(h).is_err() {
        return Err(IoError::unsupported(
            F,
            format!("{w} x {h} exceeds the classic TIFF size"),
        ));
    }
    Ok(())
}

/// Encodes `hf` as an uncompressed float32 GeoTIFF: the georeference tags verbatim (or a pixel
/// scale from the cell size when there is none) and `GDAL_NODATA = nan` when it has voids.
pub(crate) fn write(hf: &Heightfield) -> Result<Vec<u8>> {
    let mut buf = Cursor::new(Vec::new());
    let (w, h) = (hf.width(), hf.height());
    let (w32, h32) = match (u32::try_from(w), u32::try_from(h)) {
        (Ok(a), Ok(b)) => (a, b),
        _ => {
            return Err(IoError::unsupported(
                F,
                format!("{w} x {h} exceeds the classic TIFF size"),
            ));
        }
    };
    if (hf.len() as u64) * 4 > (u32::MAX as u64) - (1 << 20) {
        return Err(IoError::unsupported(
            F,
            "raster larger than 4 GiB (BigTIFF writing is not supported)",
        ));
    }
    {
        let mut enc = TiffEncoder::new(&mut buf).map_err(terr)?;
        let mut img = enc
            .new_image::<colortype::Gray32Float>(w32, h32)
            .map_err(terr)?;
        write_geo_tags(img.encoder(), hf)?;
        img.write_data(hf.as_slice()).map_err(terr)?;
    }
    Ok(buf.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The predictor (planes, then blocked differencing) equals libtiff's `fpDiff` written
    /// plainly, for rows shorter and longer than a block and rows appended one after another.
    #[test]
    fn fp_predictor_matches_the_plain_definition() {
        for w in [1usize, 15, 16, 17, 100, 333] {
            let row: Vec<f32> = (0..w)
                .map(|i| (i as f32 * 0.37).sin() * 1e3 - 7.5)
                .collect();
            let mut want = vec![0u8; 4 * w];
            for (i, v) in row.iter().enumerate() {
                for (k, b) in v.to_be_bytes().into_iter().enumerate() {
                    want[k * w + i] = b;
                }
            }
            for i in (1..want.len()).rev() {
                want[i] = want[i].wrapping_sub(want[i - 1]);
            }
            let mut got = vec![9u8; 3];
            fp_predict_row(&row, &mut got);
            assert_eq!(&got[..3], &[9, 9, 9], "bytes before the row are kept");
            assert_eq!(&got[3..], &want[..], "width {w}");
        }
    }

    fn geo(raster_type: u16) -> GeoRef {
        GeoRef {
            pixel_scale: Some(vec![30.0, 30.0, 0.0]),
            tiepoints: Some(vec![0.0, 0.0, 0.0, 500_000.0, 4_000_000.0, 0.0]),
            // version 1.1.0, 3 keys: model projected, raster type, EPSG:32611.
            geo_key_directory: Some(vec![
                1,
                1,
                0,
                3,
                1024,
                0,
                1,
                1,
                1025,
                0,
                1,
                raster_type,
                3072,
                0,
                1,
                32611,
            ]),
            ..Default::default()
        }
    }

    fn round_trip(g: GeoRef) -> Raster {
        let hf =
            Heightfield::from_fn(4, 3, 30.0, 30.0, |x, y| (x + 10 * y) as f32).with_georef(Some(g));
        read(&write(&hf).unwrap(), &crate::ReadOptions::default()).unwrap()
    }

    #[test]
    fn pixel_is_point_reads_as_the_area_grid_gdal_reports() {
        let area = round_trip(geo(PIXEL_IS_AREA));
        let t = area.heightfield.georef().unwrap().geotransform.unwrap();
        assert_eq!(t, [500_000.0, 30.0, 0.0, 4_000_000.0, 0.0, -30.0]);
        // The same tiepoint as a pixel centre: the corner is half a pixel north-west.
        let point = round_trip(geo(PIXEL_IS_POINT));
        let g = point.heightfield.georef().unwrap();
        let t = g.geotransform.unwrap();
        assert_eq!(t, [499_985.0, 30.0, 0.0, 4_000_015.0, 0.0, -30.0]);
        let dir = g.geo_key_directory.as_deref().unwrap();
        assert_eq!(geo_key(dir, GT_RASTER_TYPE), Some(PIXEL_IS_AREA));
        // Written again and re-read: the same place (no second shift).
        let again = round_trip(g.clone());
        assert_eq!(again.heightfield.georef().unwrap().geotransform, Some(t));
    }

    #[test]
    fn gdal_scale_and_offset_are_applied() {
        let xml = "<GDALMetadata>\n  <Item name=\"OFFSET\" sample=\"0\" role=\"offset\">100\
                   </Item>\n  <Item name=\"SCALE\" sample=\"0\" role=\"scale\">0.1</Item>\n\
                   </GDALMetadata>";
        assert_eq!(gdal_scale_offset(xml), (Some(0.1), Some(100.0)));
        let mut buf = Cursor::new(Vec::new());
        {
            let mut enc = TiffEncoder::new(&mut buf).unwrap();
            let mut img = enc.new_image::<colortype::GrayI16>(3, 2).unwrap();
            img.encoder()
                .write_tag(Tag::Unknown(GDAL_METADATA_TAG), xml)
                .unwrap();
            img.encoder().write_tag(Tag::GdalNodata, "-32768").unwrap();
            img.write_data(&[10i16, 20, 30, -32768, 50, 12345]).unwrap();
        }
        let r = read(&buf.into_inner(), &crate::ReadOptions::default()).unwrap();
        let v = r.heightfield.as_slice();
        assert_eq!(v[0], 101.0);
        assert!((v[5] - 1334.5).abs() < 1e-3, "{}", v[5]);
        assert!(v[3].is_nan(), "nodata matched on the stored value");
    }
}

#[cfg(test)]
mod compression_tests {
    use super::*;

    #[test]
    fn deflate_with_float_predictor_round_trips_exactly_and_is_smaller() {
        let g = GeoRef {
            geotransform: Some([500_000.0, 30.0, 0.0, 4_000_000.0, 0.0, -30.0]),
            ..Default::default()
        };
        let mut hf = Heightfield::from_fn(300, 70, 30.0, 30.0, |x, y| {
            1000.0 + 50.0 * ((x as f32) * 0.05).sin() * ((y as f32) * 0.07).cos() + 0.01 * x as f32
        })
        .with_georef(Some(g));
        hf.set(7, 5, f32::NAN);
        let plain = write_with(&hf, TiffCompression::None).unwrap();
        let packed = write_with(&hf, TiffCompression::Deflate).unwrap();
        // DEFLATE_LEVEL 1 packs this smooth field 1.91x (level 4: 1.99x, level 6: 2.0x); the bound
        // catches a level or strip layout that would store it uncompressed (1.0x).
        assert!(
            packed.len() * 18 < plain.len() * 10,
            "{} vs {}",
            packed.len(),
            plain.len()
        );
        let r = read(&packed, &crate::ReadOptions::default()).unwrap();
        let (a, b) = (r.heightfield.as_slice(), hf.as_slice());
        assert!(
            a.iter()
                .zip(b)
                .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
        );
        assert_eq!(
            r.heightfield.georef().unwrap().geotransform,
            hf.georef().unwrap().geotransform
        );
        // Same bytes whatever the thread count.
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| write_with(&hf, TiffCompression::Deflate).unwrap());
        assert_eq!(one, packed);
    }
}
