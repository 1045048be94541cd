//! Streaming GeoTIFF output: rows are written to the file as they are produced, so a raster far
//! larger than the working memory of the producer (e.g. a 16384^2 amplification computed window
//! by window) never exists as one buffer. The file is a temporary sibling until
//! [`GeoTiffStripWriter::finish`] renames it into place, like every relief-io write.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use relief_heightfield::GeoRef;

use crate::tiff_dir::{Value, encode_directories, georef_entries, header};
use crate::{Format, IoError, Result};

const F: Format = Format::GeoTiff;

/// Writes an uncompressed float32 GeoTIFF row by row (north row first), in strips of about
/// 64 KiB, with the same tags as [`crate::write`]: the georeference verbatim (or a pixel scale
/// from the cell size) and `GDAL_NODATA = nan` when a NaN was written.
///
/// Memory: a 64 KiB write buffer plus the strip tables (8 bytes per strip), whatever the raster
/// size. The file is written to a hidden temporary in the target directory; [`finish`] checks
/// that every row arrived, writes the directory, syncs and renames it over `path`. Dropping the
/// writer without `finish` (an error or a panic in the producer) removes the temporary, so no
/// partial output is ever visible under `path`.
///
/// Classic TIFF up to 4 GiB of samples, BigTIFF beyond (what GDAL's `BIGTIFF=IF_NEEDED`
/// gives).
///
/// [`finish`]: GeoTiffStripWriter::finish
///
/// ```
/// use relief_io::{GeoTiffStripWriter, ReadOptions, read};
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("big.tif");
/// let (w, h) = (300, 200);
/// let mut out = GeoTiffStripWriter::create(&path, w, h, (10.0, 10.0), None).unwrap();
/// let mut row = vec![0f32; w];
/// for y in 0..h {
///     for (x, v) in row.iter_mut().enumerate() {
///         *v = (x + 2 * y) as f32;
///     }
///     out.write_rows(&row).unwrap();
/// }
/// out.finish().unwrap();
/// let back = read(&path, &ReadOptions::default()).unwrap().heightfield;
/// assert_eq!(back.get(299, 199), 697.0); // x + 2 y
/// assert_eq!(back.cell_size(), (10.0, 10.0));
/// ```
#[derive(Debug)]
pub struct GeoTiffStripWriter {
    file: Option<BufWriter<File>>,
    tmp: PathBuf,
    path: PathBuf,
    width: usize,
    height: usize,
    rows_per_strip: usize,
    rows_written: usize,
    has_nan: bool,
    tags: GeoRef,
    row_bytes: Vec<u8>,
    /// BigTIFF (samples past 4 GiB).
    big: bool,
}

impl GeoTiffStripWriter {
    /// Creates the temporary file for a `width x height` raster with cell size `cell_size`
    /// (metres) and an optional georeference (written verbatim, see [`crate::write`]).
    pub fn create(
        path: &Path,
        width: usize,
        height: usize,
        cell_size: (f64, f64),
        georef: Option<&GeoRef>,
    ) -> Result<Self> {
        Self::create_as(path, (width, height), cell_size, georef, false)
    }

    /// [`create`](Self::create) of a `(width, height)` raster, writing BigTIFF even below
    /// 4 GiB when `bigtiff` is set.
    fn create_as(
        path: &Path,
        (width, height): (usize, usize),
        cell_size: (f64, f64),
        georef: Option<&GeoRef>,
        bigtiff: bool,
    ) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(IoError::dimensions(F, width, height, "zero size"));
        }
        let bytes = (width as u64)
            .checked_mul(height as u64)
            .and_then(|n| n.checked_mul(4))
            .unwrap_or(u64::MAX);
        if width > u32::MAX as usize || height > u32::MAX as usize || bytes == u64::MAX {
            return Err(IoError::dimensions(
                F,
                width,
                height,
                "larger than a TIFF can describe",
            ));
        }
        // BigTIFF (what GDAL writes with BIGTIFF=IF_NEEDED) once the samples pass 4 GiB.
        let big = bigtiff || bytes > u32::MAX as u64 - (1 << 20);
        crate::util::check_target(path, cell_size)?;
        crate::atomic::check_replaceable(path)?;
        crate::atomic::remove_stale_temps(path);
        let tmp = crate::atomic::temp_path(path);
        let file = crate::atomic::create_temp(&tmp).map_err(|e| IoError::os(path, e))?;
        let mut file = BufWriter::with_capacity(1 << 16, file);
        // Header; the directory offset is patched by `finish`.
        let first = header(big, 0);
        if let Err(e) = file.write_all(&first[..data_start(big) as usize]) {
            let _ = std::fs::remove_file(&tmp);
            return Err(IoError::os(path, e));
        }
        Ok(GeoTiffStripWriter {
            file: Some(file),
            tmp,
            path: path.to_path_buf(),
            width,
            height,
            rows_per_strip: (65536 / (width * 4)).clamp(1, height),
            rows_written: 0,
            has_nan: false,
            tags: crate::geotiff::georef_tags(cell_size, georef),
            row_bytes: Vec::new(),
            big,
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

    /// Rows written so far (the next row written is row `rows_written()`).
    pub fn rows_written(&self) -> usize {
        self.rows_written
    }

    /// Appends whole rows (`rows.len()` a multiple of the width), continuing from
    /// [`rows_written`](Self::rows_written). Writing past the last row is an error.
    pub fn write_rows(&mut self, rows: &[f32]) -> Result<()> {
        if !rows.len().is_multiple_of(self.width) {
            return Err(IoError::param(
                "rows",
                format!("{} samples", rows.len()),
                format!("not a whole number of rows of {}", self.width),
            ));
        }
        let n = rows.len() / self.width;
        if self.rows_written + n > self.height {
            return Err(IoError::param(
                "rows",
                format!("{n} rows after {}", self.rows_written),
                format!("the raster has only {} rows", self.height),
            ));
        }
        let file = self
            .file
            .as_mut()
            .ok_or_else(|| IoError::param("writer", "finished", "no longer accepts rows"))?;
        for row in rows.chunks_exact(self.width) {
            self.row_bytes.clear();
            for &v in row {
                self.has_nan |= v.is_nan();
                self.row_bytes.extend_from_slice(&v.to_le_bytes());
            }
            file.write_all(&self.row_bytes)
                .map_err(|e| IoError::os(&self.path, e))?;
        }
        self.rows_written += n;
        Ok(())
    }

    /// Checks that every row was written, appends the image directory, syncs the file and
    /// renames it over the target path.
    pub fn finish(mut self) -> Result<()> {
        if self.rows_written != self.height {
            return Err(IoError::param(
                "rows",
                self.rows_written,
                format!(
                    "{} rows were announced; the file is not written",
                    self.height
                ),
            ));
        }
        let mut file = self
            .file
            .take()
            .ok_or_else(|| IoError::param("writer", "finished", "already finished"))?;
        let res = (|| -> std::io::Result<()> {
            let data_end = data_start(self.big) + (self.width * self.height * 4) as u64;
            let at = data_end.next_multiple_of(8);
            file.write_all(&vec![0u8; (at - data_end) as usize])?;
            file.write_all(&self.directory(at))?;
            file.seek(SeekFrom::Start(0))?;
            file.write_all(&header(self.big, at)[..data_start(self.big) as usize])?;
            let file = file.into_inner().map_err(|e| e.into_error())?;
            file.sync_all()
        })();
        if let Err(e) = res {
            let _ = std::fs::remove_file(&self.tmp);
            return Err(IoError::os(&self.path, e));
        }
        crate::atomic::rename_into_place(&self.tmp, &self.path)
    }

    /// The image file directory placed at `at` (after the data, 8-byte aligned), followed by
    /// its out-of-line tag values.
    fn directory(&self, at: u64) -> Vec<u8> {
        let (w, h, rps) = (self.width, self.height, self.rows_per_strip);
        let start = data_start(self.big);
        let strips = h.div_ceil(rps);
        let strip_offsets = (0..strips)
            .map(|i| start + (i * rps * w * 4) as u64)
            .collect();
        let strip_counts = (0..strips)
            .map(|i| ((rps.min(h - i * rps)) * w * 4) as u64)
            .collect();
        let mut entries: Vec<(u16, Value)> = vec![
            (256, Value::Long(vec![w as u32])),
            (257, Value::Long(vec![h as u32])),
            (258, Value::Short(vec![32])),
            (259, Value::Short(vec![1])),
            (262, Value::Short(vec![1])),
            (273, Value::Offsets(strip_offsets)),
            (277, Value::Short(vec![1])),
            (278, Value::Long(vec![rps as u32])),
            (279, Value::Offsets(strip_counts)),
            (284, Value::Short(vec![1])),
            (339, Value::Short(vec![3])),
        ];
        georef_entries(&self.tags, &mut entries);
        if self.has_nan {
            entries.push((42113, Value::Ascii("nan".into())));
        }
        entries.retain(|(_, v)| !v.is_empty());
        entries.sort_by_key(|(t, _)| *t);
        encode_directories(self.big, &[entries], at)
    }
}

/// First data byte: right after the header (8 bytes in TIFF, 16 in BigTIFF).
fn data_start(big: bool) -> u64 {
    if big { 16 } else { 8 }
}

impl Drop for GeoTiffStripWriter {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Classic and BigTIFF layouts (the latter chosen past 4 GiB) read back to the same values,
    /// NaN and georeference included.
    #[test]
    fn classic_and_big_layouts_read_back_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (37, 1500); // several strips, the last one short
        let georef = crate::geotiff::georef_tags((2.0, 3.0), None);
        for big in [false, true] {
            let path = dir.path().join(format!("s{big}.tif"));
            let mut out =
                GeoTiffStripWriter::create_as(&path, (w, h), (2.0, 3.0), None, big).unwrap();
            assert_eq!(out.big, big);
            for y in 0..h {
                let row: Vec<f32> = (0..w)
                    .map(|x| {
                        if x == 5 && y == 7 {
                            f32::NAN
                        } else {
                            (x * 3 + y) as f32 * 0.5
                        }
                    })
                    .collect();
                out.write_rows(&row).unwrap();
            }
            out.finish().unwrap();
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(&bytes[2..4], if big { &[43u8, 0] } else { &[42u8, 0] });
            let back = crate::read(&path, &crate::ReadOptions::default())
                .unwrap()
                .heightfield;
            assert_eq!((back.width(), back.height()), (w, h));
            assert!(back.get(5, 7).is_nan());
            assert_eq!(back.get(36, 1499), (36 * 3 + 1499) as f32 * 0.5);
            assert_eq!(back.cell_size(), (2.0, 3.0));
            assert_eq!(georef.pixel_scale.as_ref().map(|p| p[0]), Some(2.0));
        }
    }
}
