//! Reading a GeoTIFF band of rows by band of rows: the values, voids, scaling and georeference
//! [`crate::read`] gives, without the whole raster (or the whole file) in memory.

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use relief_heightfield::GeoRef;
use tiff::decoder::Decoder;

use super::directory::{self, Tags};
use super::{F, terr};
use crate::util::{check_dims, voids_to_nan};
use crate::{IoError, ReadOptions, Result};

/// A GeoTIFF opened for reading in bands of rows (see [`GeoTiffBands::read_rows`]). Its size,
/// cell size, georeference, nodata and data type are those [`crate::read`] reports for the
/// file, and every row holds the values `read` gives (north row first, voids NaN, GDAL's SCALE
/// and OFFSET applied), whatever the storage: strips or tiles, any sample type `read` accepts,
/// south-up grids.
///
/// Memory: one row of chunks (a strip, or a band of tiles across the raster) beside the rows
/// asked for.
///
/// ```
/// use relief_heightfield::Heightfield;
/// use relief_io::{GeoTiffBands, ReadOptions, WriteOptions, read, write};
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("dem.tif");
/// let hf = Heightfield::from_fn(40, 30, 5.0, 5.0, |x, y| (x * 7 + y) as f32);
/// write(&path, &hf, &WriteOptions::default()).unwrap();
/// let mut bands = GeoTiffBands::open(&path, &ReadOptions::default()).unwrap();
/// let mut rows = Vec::new();
/// bands.read_rows(10, 5, &mut rows).unwrap();
/// let whole = read(&path, &ReadOptions::default()).unwrap().heightfield;
/// assert_eq!(rows, whole.as_slice()[10 * 40..15 * 40]);
/// ```
#[derive(Debug)]
pub struct GeoTiffBands {
    decoder: Decoder<BufReader<File>>,
    path: PathBuf,
    width: usize,
    height: usize,
    cell: (f64, f64),
    georef: Option<GeoRef>,
    nodata: Option<f64>,
    dtype: &'static str,
    flipped: bool,
    /// GDAL's `(scale, offset)`, when the file states either.
    scale: Option<(f64, f64)>,
    /// Stored rows per chunk row (strip or tile height) and chunk width.
    chunk_rows: usize,
    chunk_cols: usize,
    /// The decoded chunk row `band_index` (stored order, values final), full rows.
    band: Vec<f32>,
    band_index: Option<usize>,
}

impl GeoTiffBands {
    /// Opens `path` and reads its directory (no samples yet): the size (checked against
    /// `opts.max_cells`), sample type, nodata, georeference and scaling, with the checks and
    /// errors of [`crate::read`]. Every chunk must lie inside the file.
    pub fn open(path: &Path, opts: &ReadOptions) -> Result<Self> {
        Self::open_file(path, opts).map_err(|e| e.in_file(path))
    }

    fn open_file(path: &Path, opts: &ReadOptions) -> Result<Self> {
        let file = File::open(path).map_err(|e| IoError::os(path, e))?;
        let file_len = file.metadata().map_err(|e| IoError::os(path, e))?.len();
        let mut dec = directory::decoder(BufReader::new(file), opts)?;
        let (w, h) = dec.dimensions().map_err(terr)?;
        check_dims(F, w as u64, h as u64, opts)?;
        let (_, dtype) = directory::sample_type(&mut dec)?;
        directory::check_chunks_in_file(&mut dec, file_len)?;
        let mut tags = Tags::read(&mut dec)?;
        let (w, h) = (w as usize, h as usize);
        let (flipped, cell) = tags.complete_georef(w, h)?;
        crate::util::check_cell(F, "cell size", cell.0, cell.1)?;
        let scale = tags.scale()?;
        let Tags { nodata, geo, .. } = tags;
        let (cw, ch) = dec.chunk_dimensions();
        if cw == 0 || ch == 0 {
            return Err(IoError::malformed(
                F,
                "a strip or tile of no rows or columns",
            ));
        }
        Ok(GeoTiffBands {
            decoder: dec,
            path: path.to_path_buf(),
            width: w,
            height: h,
            cell,
            georef: (geo != GeoRef::default()).then_some(geo),
            nodata,
            dtype,
            flipped,
            scale,
            chunk_rows: (ch as usize).min(h),
            chunk_cols: (cw as usize).min(w),
            band: Vec::new(),
            band_index: None,
        })
    }

    /// Width in cells.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in cells.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Cell size `(x, y)` in metres, as [`crate::read`] derives it.
    pub fn cell_size(&self) -> (f64, f64) {
        self.cell
    }

    /// The georeference (`None` when the file has none), as [`crate::read`] gives it.
    pub fn georef(&self) -> Option<&GeoRef> {
        self.georef.as_ref()
    }

    /// The nodata value the file declares.
    pub fn nodata(&self) -> Option<f64> {
        self.nodata
    }

    /// Data type of the stored samples, e.g. `"int16"`.
    pub fn dtype(&self) -> &'static str {
        self.dtype
    }

    /// Whether the file stores its rows south first (rows are still given north first).
    pub fn rows_flipped(&self) -> bool {
        self.flipped
    }

    /// Rows of one stored chunk row (strip or tile height): the rows decoded at once.
    pub fn chunk_rows(&self) -> usize {
        self.chunk_rows
    }

    /// Replaces `out` with rows `y0 .. y0 + rows` (north first), `rows * width` values.
    pub fn read_rows(&mut self, y0: usize, rows: usize, out: &mut Vec<f32>) -> Result<()> {
        if y0.checked_add(rows).is_none_or(|end| end > self.height) {
            return Err(IoError::param(
                "rows",
                rows,
                format!(
                    "rows {y0}..{} of {} are past its {} rows",
                    y0.saturating_add(rows),
                    self.path.display(),
                    self.height
                ),
            ));
        }
        out.clear();
        out.try_reserve_exact(rows * self.width)
            .map_err(|_| IoError::param("rows", rows, "cannot allocate the rows".to_string()))?;
        for y in y0..y0 + rows {
            let stored = if self.flipped { self.height - 1 - y } else { y };
            let cr = stored / self.chunk_rows;
            if self.band_index != Some(cr) {
                self.load_band(cr).map_err(|e| e.in_file(&self.path))?;
            }
            let r = stored - cr * self.chunk_rows;
            out.extend_from_slice(&self.band[r * self.width..(r + 1) * self.width]);
        }
        Ok(())
    }

    /// Decodes chunk row `cr` (every chunk across the raster) into `band`, values final.
    fn load_band(&mut self, cr: usize) -> Result<()> {
        self.band_index = None;
        let dtype = self.dtype;
        directory::read_chunk_row(
            &mut self.decoder,
            cr,
            (self.width, self.height),
            (self.chunk_cols, self.chunk_rows),
            &mut self.band,
            |decoded| {
                directory::samples_f32(decoded)
                    .ok_or_else(|| IoError::unsupported(F, format!("samples of {dtype}")))
            },
            terr,
        )?;
        voids_to_nan(&mut self.band, self.nodata);
        if let Some((s, o)) = self.scale {
            // As `read` applies GDAL's unit scaling: nodata matched on the stored values.
            for v in &mut self.band {
                *v = (*v as f64 * s + o) as f32;
            }
        }
        self.band_index = Some(cr);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;

    use tiff::encoder::{TiffEncoder, colortype};
    use tiff::tags::Tag;

    use super::*;
    use crate::geotiff::GDAL_METADATA_TAG;
    use crate::{TiledGeoTiffWriter, TiledOptions, read};

    /// Every band split gives the rows of `read`, with its size, cell, georeference and nodata.
    fn same_as_read(path: &Path) {
        let whole = read(path, &ReadOptions::default()).unwrap();
        let hf = &whole.heightfield;
        let mut b = GeoTiffBands::open(path, &ReadOptions::default()).unwrap();
        assert_eq!((b.width(), b.height()), (hf.width(), hf.height()));
        assert_eq!(b.cell_size(), hf.cell_size());
        assert_eq!(b.georef(), hf.georef());
        assert_eq!(b.nodata().map(f64::to_bits), whole.nodata.map(f64::to_bits));
        assert_eq!(b.dtype(), whole.dtype);
        assert_eq!(b.rows_flipped(), whole.rows_flipped);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let w = hf.width();
        let mut rows = Vec::new();
        // Bands of every height, in an order that goes back and forth over chunk rows.
        for n in [1, 2, 5, hf.height()] {
            let starts: Vec<usize> = (0..hf.height()).step_by(n).rev().collect();
            for y in starts {
                let k = n.min(hf.height() - y);
                b.read_rows(y, k, &mut rows).unwrap();
                assert_eq!(
                    bits(&rows),
                    bits(&hf.as_slice()[y * w..(y + k) * w]),
                    "{y}+{k}"
                );
            }
        }
        assert!(b.read_rows(hf.height() - 1, 2, &mut rows).is_err());
        assert!(b.read_rows(usize::MAX, 2, &mut rows).is_err());
    }

    #[test]
    fn int16_strips_with_nodata_scale_and_south_up_read_as_whole() {
        let (w, h) = (23u32, 17u32);
        let data: Vec<i16> = (0..w * h)
            .map(|i| {
                if i % 11 == 3 {
                    -32768
                } else {
                    (i as i16) * 7 - 900
                }
            })
            .collect();
        let mut buf = Cursor::new(Vec::new());
        let mut enc = TiffEncoder::new(&mut buf).unwrap();
        let mut img = enc.new_image::<colortype::GrayI16>(w, h).unwrap();
        img.rows_per_strip(3).unwrap();
        let e = img.encoder();
        e.write_tag(Tag::GdalNodata, "-32768").unwrap();
        let xml = "<GDALMetadata><Item name=\"SCALE\" sample=\"0\" role=\"scale\">0.1</Item>\
                   <Item name=\"OFFSET\" sample=\"0\" role=\"offset\">100.5</Item></GDALMetadata>";
        e.write_tag(Tag::Unknown(GDAL_METADATA_TAG), xml).unwrap();
        // South-up: a positive y pixel size.
        e.write_tag(Tag::ModelPixelScaleTag, &[30.0f64, -30.0, 0.0][..])
            .unwrap();
        e.write_tag(
            Tag::ModelTiepointTag,
            &[0.0f64, 0.0, 0.0, 500000.0, 4000000.0, 0.0][..],
        )
        .unwrap();
        img.write_data(&data).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("i16.tif");
        std::fs::write(&p, buf.get_ref()).unwrap();
        let r = read(&p, &ReadOptions::default()).unwrap();
        assert!(r.rows_flipped && r.nodata.is_some() && r.heightfield.has_voids());
        assert_eq!(
            r.heightfield.get(1, h as usize - 1),
            (-893.0f64 * 0.1 + 100.5) as f32
        );
        same_as_read(&p);
    }

    #[test]
    fn float_tiles_with_void_markers_read_as_whole() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f32.tif");
        let (w, h) = (70, 45);
        let opts = TiledOptions {
            tile: 16,
            ..Default::default()
        };
        let mut out = TiledGeoTiffWriter::create(&p, w, h, (2.5, 2.5), None, opts).unwrap();
        let data: Vec<f32> = (0..w * h)
            .map(|i| match i % 13 {
                0 => f32::NAN,
                1 => -3.4028235e38,
                2 => f32::INFINITY,
                3 => -0.0,
                _ => (i as f32 * 0.37).sin() * 1e3,
            })
            .collect();
        out.write_rows(&data).unwrap();
        out.finish().unwrap();
        same_as_read(&p);
        // Relief's own strips, with a georeference.
        let hf = relief_heightfield::Heightfield::new(w, h, data, 2.5, 2.5).unwrap();
        let p2 = dir.path().join("strips.tif");
        let g = GeoRef {
            crs: Some("EPSG:32612".into()),
            geotransform: Some([4e5, 2.5, 0.0, 4e6, 0.0, -2.5]),
            ..Default::default()
        };
        crate::write(&p2, &hf.with_georef(Some(g)), &Default::default()).unwrap();
        same_as_read(&p2);
    }

    #[test]
    fn bad_files_are_errors_naming_them() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.tif");
        let hf = relief_heightfield::Heightfield::new(40, 40, vec![1.0; 1600], 1.0, 1.0).unwrap();
        crate::write(&p, &hf, &Default::default()).unwrap();
        let small = ReadOptions {
            max_cells: 1000,
            ..Default::default()
        };
        let e = GeoTiffBands::open(&p, &small).unwrap_err().to_string();
        assert!(e.contains("x.tif") && e.contains("1600"), "{e}");
        let bytes = std::fs::read(&p).unwrap();
        std::fs::write(&p, &bytes[..bytes.len() - 100]).unwrap();
        let e = GeoTiffBands::open(&p, &ReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.tif") && e.contains("strip"), "{e}");
        assert!(GeoTiffBands::open(&dir.path().join("none.tif"), &Default::default()).is_err());
    }
}
