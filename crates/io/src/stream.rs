//! Streaming GeoTIFF output: rows are written to the file as they are produced, so a raster far
//! larger than the working memory of the producer (e.g. a 16384^2 amplification computed window
//! by window) never exists as one buffer. The file is a temporary sibling until
//! [`GeoTiffStripWriter::finish`] renames it into place, like every relief-io write.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use relief_heightfield::GeoRef;

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
/// Classic TIFF only: at most 4 GiB of samples (32768 x 32768); larger rasters are refused by
/// [`create`](GeoTiffStripWriter::create).
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
}

/// First data byte: right after the 8-byte header.
const DATA_START: u64 = 8;

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
        if width == 0 || height == 0 {
            return Err(IoError::Dimensions {
                format: F,
                width: width as u64,
                height: height as u64,
                reason: "zero size".into(),
            });
        }
        let bytes = (width as u64)
            .checked_mul(height as u64)
            .and_then(|n| n.checked_mul(4))
            .unwrap_or(u64::MAX);
        if bytes > u32::MAX as u64 - (1 << 20) {
            return Err(IoError::Dimensions {
                format: F,
                width: width as u64,
                height: height as u64,
                reason: "more than 4 GiB of float32 (BigTIFF writing is not supported)".into(),
            });
        }
        let (cx, cy) = cell_size;
        if !(cx.is_finite() && cy.is_finite() && cx > 0.0 && cy > 0.0) {
            return Err(IoError::param(
                "cell_size",
                format!("({cx}, {cy})"),
                "must be finite and positive",
            ));
        }
        if path.file_name().is_none() {
            return Err(IoError::param("path", path.display(), "has no file name"));
        }
        crate::atomic::check_replaceable(path)?;
        crate::atomic::remove_stale_temps(path);
        let tmp = crate::atomic::temp_path(path);
        let file = File::create(&tmp).map_err(|e| IoError::os(path, e))?;
        let mut file = BufWriter::with_capacity(1 << 16, file);
        // Header; the directory offset is patched by `finish`.
        let header = [b'I', b'I', 42, 0, 0, 0, 0, 0];
        if let Err(e) = file.write_all(&header) {
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
            let data_end = DATA_START + (self.width * self.height * 4) as u64;
            let ifd = self.directory(data_end);
            file.write_all(&ifd)?;
            file.seek(SeekFrom::Start(4))?;
            file.write_all(&(data_end as u32).to_le_bytes())?;
            let file = file.into_inner().map_err(|e| e.into_error())?;
            file.sync_all()
        })();
        if let Err(e) = res {
            let _ = std::fs::remove_file(&self.tmp);
            return Err(IoError::os(&self.path, e));
        }
        crate::atomic::rename_into_place(&self.tmp, &self.path)
    }

    /// The image file directory placed at `at` (even: the data length is a multiple of 4),
    /// followed by the out-of-line tag values.
    fn directory(&self, at: u64) -> Vec<u8> {
        enum V {
            Short(Vec<u16>),
            Long(Vec<u32>),
            Double(Vec<f64>),
            Ascii(Vec<u8>),
        }
        let (w, h, rps) = (self.width, self.height, self.rows_per_strip);
        let strips = h.div_ceil(rps);
        let strip_offsets = (0..strips)
            .map(|i| (DATA_START + (i * rps * w * 4) as u64) as u32)
            .collect();
        let strip_counts = (0..strips)
            .map(|i| ((rps.min(h - i * rps)) * w * 4) as u32)
            .collect();
        let ascii = |s: &str| {
            let mut b = s.as_bytes().to_vec();
            b.push(0);
            V::Ascii(b)
        };
        let g = &self.tags;
        let mut entries: Vec<(u16, V)> = vec![
            (256, V::Long(vec![w as u32])),
            (257, V::Long(vec![h as u32])),
            (258, V::Short(vec![32])),
            (259, V::Short(vec![1])),
            (262, V::Short(vec![1])),
            (273, V::Long(strip_offsets)),
            (277, V::Short(vec![1])),
            (278, V::Long(vec![rps as u32])),
            (279, V::Long(strip_counts)),
            (284, V::Short(vec![1])),
            (339, V::Short(vec![3])),
        ];
        if let Some(v) = &g.pixel_scale {
            entries.push((33550, V::Double(v.clone())));
        }
        if let Some(v) = &g.tiepoints {
            entries.push((33922, V::Double(v.clone())));
        }
        if let Some(v) = &g.transformation {
            entries.push((34264, V::Double(v.clone())));
        }
        if let Some(v) = &g.geo_key_directory {
            entries.push((34735, V::Short(v.clone())));
        }
        if let Some(v) = &g.geo_double_params {
            entries.push((34736, V::Double(v.clone())));
        }
        if let Some(v) = &g.geo_ascii_params {
            entries.push((34737, ascii(v)));
        }
        if self.has_nan {
            entries.push((42113, ascii("nan")));
        }
        entries.retain(|(_, v)| match v {
            V::Short(x) => !x.is_empty(),
            V::Long(x) => !x.is_empty(),
            V::Double(x) => !x.is_empty(),
            V::Ascii(x) => !x.is_empty(),
        });
        entries.sort_by_key(|(t, _)| *t);
        let ifd_len = 2 + 12 * entries.len() + 4;
        let mut out = Vec::with_capacity(ifd_len);
        let mut extra: Vec<u8> = Vec::new();
        out.extend_from_slice(&(entries.len() as u16).to_le_bytes());
        for (tag, v) in &entries {
            let (typ, count, bytes): (u16, usize, Vec<u8>) = match v {
                V::Short(x) => (3, x.len(), x.iter().flat_map(|a| a.to_le_bytes()).collect()),
                V::Long(x) => (4, x.len(), x.iter().flat_map(|a| a.to_le_bytes()).collect()),
                V::Double(x) => (
                    12,
                    x.len(),
                    x.iter().flat_map(|a| a.to_le_bytes()).collect(),
                ),
                V::Ascii(x) => (2, x.len(), x.clone()),
            };
            out.extend_from_slice(&tag.to_le_bytes());
            out.extend_from_slice(&typ.to_le_bytes());
            out.extend_from_slice(&(count as u32).to_le_bytes());
            if bytes.len() <= 4 {
                let mut word = [0u8; 4];
                word[..bytes.len()].copy_from_slice(&bytes);
                out.extend_from_slice(&word);
            } else {
                if extra.len() % 2 == 1 {
                    extra.push(0);
                }
                let off = at + ifd_len as u64 + extra.len() as u64;
                out.extend_from_slice(&(off as u32).to_le_bytes());
                extra.extend_from_slice(&bytes);
            }
        }
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&extra);
        out
    }
}

impl Drop for GeoTiffStripWriter {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}
