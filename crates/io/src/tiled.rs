//! Streaming tiled GeoTIFF output, optionally Cloud-Optimized (COG): rows arrive in order, are
//! cut into square tiles (DEFLATE with the floating-point predictor, or uncompressed), and never
//! exist whole in memory. With overviews, every halving of the raster down to one tile is built
//! on the fly from the rows (2 x 2 mean, voids skipped), and the file is laid out the way GDAL's
//! COG driver lays it out: header, GDAL's structural-metadata ghost area, every image directory,
//! then the tile data from the smallest overview to the full resolution, so that a reader over
//! HTTP range requests gets all directories in the first bytes. Rasters whose file would pass
//! 4 GiB are written as BigTIFF (decided when the data size is known, at [`finish`]).
//!
//! Memory: one band of `tile` rows per level (for a 32768-wide raster with 512-px tiles, 64 MiB
//! at full resolution, half of that for all overviews together), whatever the height.
//!
//! [`finish`]: TiledGeoTiffWriter::finish

use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use relief_heightfield::GeoRef;

use crate::tiff_dir::{Value, encode_directories, georef_entries, header};
use crate::{Format, IoError, Result, TiffCompression};

mod blocks;
pub use blocks::EncodedBlocks;

const F: Format = Format::GeoTiff;

/// Options of [`TiledGeoTiffWriter`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TiledOptions {
    /// Tile side in pixels (a multiple of 16, at least 16; GDAL's COG default is 512).
    pub tile: usize,
    /// Compression of every tile.
    pub compression: TiffCompression,
    /// Build overviews (2x, 4x, ... down to one tile) and use the COG layout.
    pub cog: bool,
    /// Always write BigTIFF (GDAL's `BIGTIFF=YES`); otherwise only when the file would pass
    /// 4 GiB.
    pub bigtiff: bool,
}

impl Default for TiledOptions {
    fn default() -> Self {
        TiledOptions {
            tile: 512,
            compression: TiffCompression::Deflate,
            cog: false,
            bigtiff: false,
        }
    }
}

/// One resolution level being written.
#[derive(Debug)]
struct Level {
    width: usize,
    height: usize,
    /// Rows of the current band of tiles (`tile` rows at most), row-major.
    band: Vec<f32>,
    /// Rows received so far.
    rows: usize,
    /// Where this level's tile data goes, and bytes written there so far.
    sink: BufWriter<File>,
    written: u64,
    /// Offset of the level's first data byte in its sink.
    base: u64,
    /// Temporary file of the level (COG layout), removed at the end.
    tmp: Option<PathBuf>,
    /// Tile offsets (relative to `base`) and byte counts, row-major.
    offsets: Vec<u64>,
    counts: Vec<u64>,
    /// Odd row waiting for its pair before it is reduced into the next level.
    pending: Option<Vec<f32>>,
}

/// Streams a float32 raster into a tiled GeoTIFF (see the module documentation). Like every
/// relief-io write, the file is a hidden temporary sibling until [`finish`] renames it into
/// place; dropping the writer unfinished removes every temporary.
///
/// ```
/// use relief_io::{ReadOptions, TiledGeoTiffWriter, TiledOptions, read};
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("cog.tif");
/// let (w, h) = (100, 70);
/// let opts = TiledOptions { tile: 32, cog: true, ..Default::default() };
/// let mut out = TiledGeoTiffWriter::create(&path, w, h, (5.0, 5.0), None, opts).unwrap();
/// for y in 0..h {
///     let row: Vec<f32> = (0..w).map(|x| (x + 3 * y) as f32).collect();
///     out.write_rows(&row).unwrap();
/// }
/// out.finish().unwrap();
/// let back = read(&path, &ReadOptions::default()).unwrap().heightfield;
/// assert_eq!((back.width(), back.height()), (100, 70));
/// assert_eq!(back.get(99, 69), 99.0 + 3.0 * 69.0);
/// ```
///
/// [`finish`]: TiledGeoTiffWriter::finish
#[derive(Debug)]
pub struct TiledGeoTiffWriter {
    path: PathBuf,
    /// The output's temporary (the level-0 sink unless `cog`).
    tmp: PathBuf,
    opts: TiledOptions,
    levels: Vec<Level>,
    tags: GeoRef,
    has_nan: bool,
    finished: bool,
}

/// Bytes reserved at the start of a non-COG file for the header (a BigTIFF header is 16).
const HEADER: u64 = 16;

impl TiledGeoTiffWriter {
    /// Creates the temporaries of a `width x height` raster of cell size `cell_size` with an
    /// optional georeference (written verbatim, as [`crate::write`] does).
    pub fn create(
        path: &Path,
        width: usize,
        height: usize,
        cell_size: (f64, f64),
        georef: Option<&GeoRef>,
        opts: TiledOptions,
    ) -> Result<Self> {
        if width == 0 || height == 0 || u32::try_from(width.max(height)).is_err() {
            return Err(IoError::dimensions(
                F,
                width,
                height,
                "zero size or a side beyond 2^32",
            ));
        }
        if opts.tile < 16 || !opts.tile.is_multiple_of(16) || opts.tile > 1 << 14 {
            return Err(IoError::param(
                "tile",
                opts.tile,
                "must be a multiple of 16 between 16 and 16384",
            ));
        }
        crate::util::check_target(path, cell_size)?;
        crate::atomic::remove_stale_temps(path);
        let tmp = crate::atomic::temp_path(path);
        let mut sizes = vec![(width, height)];
        if opts.cog {
            while let Some(&(w, h)) = sizes.last() {
                if w <= opts.tile && h <= opts.tile {
                    break;
                }
                sizes.push((w.div_ceil(2), h.div_ceil(2)));
            }
        }
        let mut me = TiledGeoTiffWriter {
            path: path.to_path_buf(),
            tmp: tmp.clone(),
            opts,
            levels: Vec::with_capacity(sizes.len()),
            tags: crate::geotiff::georef_tags(cell_size, georef),
            has_nan: false,
            finished: false,
        };
        for (i, &(w, h)) in sizes.iter().enumerate() {
            // Level 0 of a plain file goes straight into the output temporary after the
            // reserved header; COG levels go to their own temporaries, assembled at the end.
            let (file_path, level_tmp, base) = if opts.cog {
                let t = crate::atomic::temp_path(path);
                (t.clone(), Some(t), 0)
            } else {
                (tmp.clone(), None, HEADER)
            };
            debug_assert!(opts.cog || i == 0);
            // Read back at `finish` (COG levels), hence read + write.
            let file = crate::atomic::create_temp(&file_path).map_err(|e| IoError::os(path, e))?;
            let mut sink = BufWriter::with_capacity(1 << 16, file);
            if base > 0 {
                sink.write_all(&[0u8; HEADER as usize])
                    .map_err(|e| IoError::os(path, e))?;
            }
            let mut band = Vec::new();
            band.try_reserve_exact(opts.tile * w).map_err(|_| {
                IoError::param("width", w, "one band of tiles does not fit in memory")
            })?;
            me.levels.push(Level {
                width: w,
                height: h,
                band,
                rows: 0,
                sink,
                written: 0,
                base,
                tmp: level_tmp,
                offsets: Vec::new(),
                counts: Vec::new(),
                pending: None,
            });
        }
        Ok(me)
    }

    /// Width in cells.
    pub fn width(&self) -> usize {
        self.levels[0].width
    }

    /// Height in cells.
    pub fn height(&self) -> usize {
        self.levels[0].height
    }

    /// Rows written so far.
    pub fn rows_written(&self) -> usize {
        self.levels[0].rows
    }

    /// Number of overview levels (0 unless COG).
    pub fn overview_count(&self) -> usize {
        self.levels.len() - 1
    }

    /// Appends whole rows (`rows.len()` a multiple of the width). Writing past the last row is
    /// an error.
    pub fn write_rows(&mut self, rows: &[f32]) -> Result<()> {
        let w = self.width();
        if !rows.len().is_multiple_of(w) {
            return Err(IoError::param(
                "rows",
                format!("{} samples", rows.len()),
                format!("not a whole number of rows of {w}"),
            ));
        }
        if self.finished {
            return Err(IoError::param(
                "writer",
                "finished",
                "no longer accepts rows",
            ));
        }
        let n = rows.len() / w;
        if self.rows_written() + n > self.height() {
            return Err(IoError::param(
                "rows",
                format!("{n} rows after {}", self.rows_written()),
                format!("the raster has only {} rows", self.height()),
            ));
        }
        for row in rows.chunks_exact(w) {
            self.has_nan |= row.iter().any(|v| v.is_nan());
            self.push_row(0, row)?;
        }
        Ok(())
    }

    /// Adds one row to level `k`, flushing its band when full and feeding the next level.
    fn push_row(&mut self, k: usize, row: &[f32]) -> Result<()> {
        let tile = self.opts.tile;
        let compression = self.opts.compression;
        let cog = self.opts.cog;
        let path = self.path.clone();
        {
            let level = &mut self.levels[k];
            level.band.extend_from_slice(row);
            level.rows += 1;
            if level.band.len() == tile * level.width || level.rows == level.height {
                flush_band(level, tile, compression, cog, &path)?;
            }
        }
        if k + 1 < self.levels.len() {
            let last = self.levels[k].rows == self.levels[k].height;
            match self.levels[k].pending.take() {
                Some(prev) => {
                    let r = reduce_rows(&prev, Some(row));
                    self.push_row(k + 1, &r)?;
                }
                None if last => {
                    let r = reduce_rows(row, None);
                    self.push_row(k + 1, &r)?;
                }
                None => self.levels[k].pending = Some(row.to_vec()),
            }
        }
        Ok(())
    }

    /// Checks that every row arrived, writes the directories, syncs and renames the file over
    /// the target path.
    pub fn finish(mut self) -> Result<()> {
        if self.rows_written() != self.height() {
            return Err(IoError::param(
                "rows",
                self.rows_written(),
                format!(
                    "{} rows were announced; the file is not written",
                    self.height()
                ),
            ));
        }
        self.finished = true;
        let res = if self.opts.cog {
            self.finish_cog()
        } else {
            self.finish_plain()
        };
        if res.is_err() {
            let _ = std::fs::remove_file(&self.tmp);
        }
        res?;
        crate::atomic::place(&self.tmp, &self.path).map_err(|e| {
            let _ = std::fs::remove_file(&self.tmp);
            IoError::os(&self.path, e)
        })
    }

    /// Plain layout: header, tile data, directory at the end.
    fn finish_plain(&mut self) -> Result<()> {
        let os = |e| IoError::os(&self.path, e);
        let level = &mut self.levels[0];
        level.sink.flush().map_err(os)?;
        let data_end = HEADER + level.written;
        let at = data_end.next_multiple_of(8);
        let specs = self.directories(&[HEADER]);
        let small = encode_directories(false, &specs, at);
        let big = self.opts.bigtiff || at + small.len() as u64 > u32::MAX as u64;
        let ifds = if big {
            encode_directories(true, &specs, at)
        } else {
            small
        };
        let level = &mut self.levels[0];
        let file = level.sink.get_mut();
        file.seek(SeekFrom::Start(data_end)).map_err(os)?;
        file.write_all(&vec![0u8; (at - data_end) as usize])
            .map_err(os)?;
        file.write_all(&ifds).map_err(os)?;
        file.seek(SeekFrom::Start(0)).map_err(os)?;
        file.write_all(&header(big, at)).map_err(os)?;
        file.sync_all().map_err(os)
    }

    /// COG layout: header, ghost area, all directories, then data from the smallest overview
    /// to the full resolution.
    fn finish_cog(&mut self) -> Result<()> {
        let path = self.path.clone();
        let os = |e| IoError::os(&path, e);
        for l in &mut self.levels {
            l.sink.flush().map_err(os)?;
        }
        let ghost = ghost_area();
        let try_layout = |big: bool| {
            let head = if big { 16 } else { 8 } + ghost.len() as u64;
            let at = head.next_multiple_of(8);
            // Directory bytes do not depend on the offsets' values: size them with zeros.
            let zeros = vec![0u64; self.levels.len()];
            let len = encode_directories(big, &self.directories(&zeros), at).len() as u64;
            let mut start = (at + len).next_multiple_of(8);
            let mut bases = vec![0u64; self.levels.len()];
            for (k, l) in self.levels.iter().enumerate().rev() {
                bases[k] = start;
                start += l.written;
            }
            (head, at, bases, start)
        };
        let (mut head, mut at, mut bases, end) = try_layout(false);
        let big = self.opts.bigtiff || end > u32::MAX as u64;
        if big {
            (head, at, bases, _) = try_layout(true);
        }
        let ifds = encode_directories(big, &self.directories(&bases), at);
        let file = crate::atomic::create_temp(&self.tmp).map_err(os)?;
        let mut out = BufWriter::with_capacity(1 << 20, file);
        let mut first = header(big, at);
        first.truncate(if big { 16 } else { 8 });
        out.write_all(&first).map_err(os)?;
        out.write_all(&ghost).map_err(os)?;
        out.write_all(&vec![0u8; (at - head) as usize])
            .map_err(os)?;
        out.write_all(&ifds).map_err(os)?;
        let mut pos = at + ifds.len() as u64;
        let mut buf = vec![0u8; 1 << 20];
        for (k, l) in self.levels.iter_mut().enumerate().rev() {
            out.write_all(&vec![0u8; (bases[k] - pos) as usize])
                .map_err(os)?;
            let file = l.sink.get_mut();
            file.seek(SeekFrom::Start(0)).map_err(os)?;
            let mut left = l.written;
            while left > 0 {
                let n = (left as usize).min(buf.len());
                file.read_exact(&mut buf[..n]).map_err(os)?;
                out.write_all(&buf[..n]).map_err(os)?;
                left -= n as u64;
            }
            pos = bases[k] + l.written;
        }
        let file = out.into_inner().map_err(|e| os(e.into_error()))?;
        file.sync_all().map_err(os)?;
        for l in &mut self.levels {
            if let Some(t) = l.tmp.take() {
                let _ = std::fs::remove_file(t);
            }
        }
        Ok(())
    }

    /// The image directories, level 0 first, with each level's data starting at `bases[k]`.
    fn directories(&self, bases: &[u64]) -> Vec<Vec<(u16, Value)>> {
        let t = self.opts.tile;
        let compressed = self.opts.compression != TiffCompression::None;
        self.levels
            .iter()
            .zip(bases)
            .enumerate()
            .map(|(k, (l, &base))| {
                let mut e: Vec<(u16, Value)> = Vec::new();
                if k > 0 {
                    e.push((254, Value::Long(vec![1])));
                }
                e.extend([
                    (256, Value::Long(vec![l.width as u32])),
                    (257, Value::Long(vec![l.height as u32])),
                    (258, Value::Short(vec![32])),
                    (259, Value::Short(vec![self.opts.compression.tag()])),
                    (262, Value::Short(vec![1])),
                    (277, Value::Short(vec![1])),
                    (284, Value::Short(vec![1])),
                    (322, Value::Long(vec![t as u32])),
                    (323, Value::Long(vec![t as u32])),
                    (
                        324,
                        Value::Offsets(l.offsets.iter().map(|o| o + base - l.base).collect()),
                    ),
                    (325, Value::Offsets(l.counts.clone())),
                    (339, Value::Short(vec![3])),
                ]);
                if compressed {
                    e.push((317, Value::Short(vec![3])));
                }
                if k == 0 {
                    georef_entries(&self.tags, &mut e);
                }
                if self.has_nan {
                    e.push((42113, Value::Ascii("nan".into())));
                }
                e.retain(|(_, v)| !v.is_empty());
                e.sort_by_key(|(tag, _)| *tag);
                e
            })
            .collect()
    }
}

impl Drop for TiledGeoTiffWriter {
    fn drop(&mut self) {
        if !self.finished {
            let _ = std::fs::remove_file(&self.tmp);
        }
        for l in &mut self.levels {
            if let Some(t) = l.tmp.take() {
                let _ = std::fs::remove_file(t);
            }
        }
    }
}

/// Cuts the band of `level` into tiles (padded to full tiles with zeros, as GDAL pads),
/// compresses them in parallel and appends them in row-major order.
fn flush_band(
    level: &mut Level,
    tile: usize,
    compression: TiffCompression,
    cog: bool,
    path: &Path,
) -> Result<()> {
    use rayon::prelude::*;
    let w = level.width;
    let rows = level.band.len() / w;
    let cols = w.div_ceil(tile);
    let os = |e| IoError::os(path, e);
    // A few tiles per worker at a time, so the compressed tiles waiting for their turn stay
    // a few MiB whatever the width.
    let batch = 8 * rayon::current_num_threads().max(1);
    let mut c0 = 0;
    while c0 < cols {
        let c1 = (c0 + batch).min(cols);
        let band = &level.band;
        let tiles: Vec<Vec<u8>> = (c0..c1)
            .into_par_iter()
            .map(|c| {
                let mut t = vec![0f32; tile * tile];
                let (x0, x1) = (c * tile, ((c + 1) * tile).min(w));
                for r in 0..rows {
                    t[r * tile..r * tile + (x1 - x0)]
                        .copy_from_slice(&band[r * w + x0..r * w + x1]);
                }
                compression.encode(&t, tile)
            })
            .collect::<Result<_>>()?;
        for t in tiles {
            // COG: GDAL's block leader (the size as u32) and trailer (the last 4 bytes
            // again), which let a reader check a block fetched by a range request.
            if cog {
                level
                    .sink
                    .write_all(&(t.len() as u32).to_le_bytes())
                    .map_err(os)?;
                level.written += 4;
            }
            level.offsets.push(level.base + level.written);
            level.counts.push(t.len() as u64);
            level.sink.write_all(&t).map_err(os)?;
            level.written += t.len() as u64;
            if cog {
                level.sink.write_all(&t[t.len() - 4..]).map_err(os)?;
                level.written += 4;
            }
        }
        c0 = c1;
    }
    level.band.clear();
    Ok(())
}

/// 2 x 2 mean of two rows (the second absent at an odd last row) into one row of half the
/// width (rounded up); voids (NaN) are skipped, a block of voids stays void.
fn reduce_rows(a: &[f32], b: Option<&[f32]>) -> Vec<f32> {
    let w = a.len();
    (0..w.div_ceil(2))
        .map(|i| {
            let mut s = 0f64;
            let mut n = 0u32;
            for row in [Some(a), b].into_iter().flatten() {
                for &v in &row[2 * i..(2 * i + 2).min(w)] {
                    if !v.is_nan() {
                        s += v as f64;
                        n += 1;
                    }
                }
            }
            if n == 0 {
                f32::NAN
            } else {
                (s / n as f64) as f32
            }
        })
        .collect()
}

/// GDAL's structural metadata block (read by GDAL to recognise the COG layout).
fn ghost_area() -> Vec<u8> {
    let body = "LAYOUT=IFDS_BEFORE_DATA\nBLOCK_ORDER=ROW_MAJOR\nBLOCK_LEADER=SIZE_AS_UINT4\n\
                BLOCK_TRAILER=LAST_4_BYTES_REPEATED\nKNOWN_INCOMPATIBLE_EDITION=NO\n ";
    format!(
        "GDAL_STRUCTURAL_METADATA_SIZE={:06} bytes\n{body}",
        body.len()
    )
    .into_bytes()
}

/// Reads a float32 GeoTIFF row by row (strip by strip or band of tiles by band of tiles), so
/// a raster far larger than memory can be copied or mosaicked with one strip or one band of
/// tiles in memory.
#[derive(Debug)]
pub struct GeoTiffRowReader {
    decoder: tiff::decoder::Decoder<std::io::BufReader<File>>,
    width: usize,
    height: usize,
    /// Rows per chunk row (strip height or tile height) and chunk width (tile width or the
    /// image width).
    chunk_rows: usize,
    chunk_cols: usize,
    /// The current band of decoded rows and the index of its first row.
    band: Vec<f32>,
    band_start: usize,
    next_row: usize,
    path: PathBuf,
    /// The map position (X, Y) of the north-west corner, from a single ModelTiepoint at
    /// raster (0, 0).
    origin: Option<(f64, f64)>,
}

impl GeoTiffRowReader {
    /// Opens `path` (a single-band float32 TIFF).
    pub fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).map_err(|e| IoError::os(path, e))?;
        let terr = |e: tiff::TiffError| IoError::malformed(F, format!("{}: {e}", path.display()));
        let mut decoder = tiff::decoder::Decoder::new(std::io::BufReader::new(file))
            .map_err(terr)?
            .with_limits(tiff::decoder::Limits::unlimited());
        let (w, h) = decoder.dimensions().map_err(terr)?;
        match decoder.colortype().map_err(terr)? {
            tiff::ColorType::Gray(32) => {}
            other => {
                return Err(IoError::unsupported(
                    F,
                    format!(
                        "{}: {other:?} (row reading needs float32 gray)",
                        path.display()
                    ),
                ));
            }
        }
        let (cw, ch) = decoder.chunk_dimensions();
        let origin = match decoder.find_tag(tiff::tags::Tag::ModelTiepointTag) {
            Ok(Some(v)) => v
                .into_f64_vec()
                .ok()
                .filter(|t| t.len() == 6 && t[0] == 0.0 && t[1] == 0.0)
                .map(|t| (t[3], t[4])),
            _ => None,
        };
        Ok(GeoTiffRowReader {
            decoder,
            width: w as usize,
            height: h as usize,
            chunk_rows: ch as usize,
            chunk_cols: cw as usize,
            band: Vec::new(),
            band_start: 0,
            next_row: 0,
            path: path.to_path_buf(),
            origin,
        })
    }

    /// The map position (X, Y) of the raster's north-west corner when the file has a single
    /// tiepoint at raster (0, 0) (as relief writes it).
    pub fn origin(&self) -> Option<(f64, f64)> {
        self.origin
    }

    /// Width in cells.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in cells.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Appends the next row to `out` (an error after the last row).
    pub fn read_row(&mut self, out: &mut Vec<f32>) -> Result<()> {
        if self.next_row >= self.height {
            return Err(IoError::param(
                "row",
                self.next_row,
                format!("{} has only {} rows", self.path.display(), self.height),
            ));
        }
        let in_band = self.band.len() / self.width;
        if self.next_row >= self.band_start + in_band || in_band == 0 {
            self.load_band(self.next_row / self.chunk_rows)?;
        }
        let r = self.next_row - self.band_start;
        out.extend_from_slice(&self.band[r * self.width..(r + 1) * self.width]);
        self.next_row += 1;
        Ok(())
    }

    /// Decodes chunk row `cr` (every chunk across the image) into `band`.
    fn load_band(&mut self, cr: usize) -> Result<()> {
        let terr =
            |e: tiff::TiffError| IoError::malformed(F, format!("{}: {e}", self.path.display()));
        crate::geotiff::read_chunk_row(
            &mut self.decoder,
            cr,
            (self.width, self.height),
            (self.chunk_cols, self.chunk_rows),
            &mut self.band,
            |decoded| match decoded {
                tiff::decoder::DecodingResult::F32(v) => Ok(v),
                _ => Err(IoError::unsupported(F, "samples are not float32")),
            },
            terr,
        )?;
        self.band_start = cr * self.chunk_rows;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ReadOptions, read};

    fn ramp(w: usize, h: usize) -> Vec<f32> {
        (0..w * h)
            .map(|i| ((i % w) as f32 * 0.7 + (i / w) as f32 * 1.3).sin() * 100.0 + i as f32 * 1e-3)
            .collect()
    }

    fn write(path: &Path, w: usize, h: usize, opts: TiledOptions, data: &[f32]) {
        let mut out = TiledGeoTiffWriter::create(path, w, h, (2.0, 2.0), None, opts).unwrap();
        // Uneven chunks of rows.
        let mut y = 0;
        let mut k = 1;
        while y < h {
            let n = k.min(h - y);
            out.write_rows(&data[y * w..(y + n) * w]).unwrap();
            y += n;
            k = k % 7 + 1;
        }
        out.finish().unwrap();
    }

    #[test]
    fn plain_and_cog_round_trip_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (123, 77);
        let data = ramp(w, h);
        for (cog, compression) in [
            (false, TiffCompression::Deflate),
            (false, TiffCompression::None),
            (true, TiffCompression::Deflate),
            (true, TiffCompression::None),
        ] {
            let p = dir.path().join(format!("t{cog}{compression:?}.tif"));
            let opts = TiledOptions {
                tile: 32,
                compression,
                cog,
                bigtiff: cog == (compression == TiffCompression::None),
            };
            write(&p, w, h, opts, &data);
            let magic = std::fs::read(&p).unwrap()[2];
            assert_eq!(magic, if opts.bigtiff { 43 } else { 42 });
            let back = read(&p, &ReadOptions::default()).unwrap().heightfield;
            assert_eq!((back.width(), back.height()), (w, h));
            assert_eq!(back.as_slice(), &data[..], "cog {cog} {compression:?}");
            assert_eq!(back.cell_size(), (2.0, 2.0));
            let mut rr = GeoTiffRowReader::open(&p).unwrap();
            let mut rows = Vec::new();
            for _ in 0..h {
                rr.read_row(&mut rows).unwrap();
            }
            assert_eq!(rows, data);
            assert!(rr.read_row(&mut rows).is_err());
            // Only the output is left in the folder: no temporaries.
            let n = std::fs::read_dir(dir.path()).unwrap().count();
            assert!(n >= 1);
            for e in std::fs::read_dir(dir.path()).unwrap() {
                let name = e.unwrap().file_name().into_string().unwrap();
                assert!(!name.starts_with('.'), "leftover {name}");
            }
        }
    }

    #[test]
    fn cog_has_overviews_down_to_one_tile_with_their_means() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (100, 70);
        let mut data = ramp(w, h);
        data[0] = f32::NAN;
        let p = dir.path().join("c.tif");
        let opts = TiledOptions {
            tile: 16,
            cog: true,
            ..Default::default()
        };
        let mut out = TiledGeoTiffWriter::create(&p, w, h, (1.0, 1.0), None, opts).unwrap();
        // 100 -> 50 -> 25 -> 13 (fits in one 16 tile).
        assert_eq!(out.overview_count(), 3);
        out.write_rows(&data).unwrap();
        out.finish().unwrap();
        let bytes = std::fs::read(&p).unwrap();
        // Ghost area right after the classic header, as GDAL writes it.
        assert!(bytes[8..].starts_with(b"GDAL_STRUCTURAL_METADATA_SIZE="));
        let mut dec = tiff::decoder::Decoder::new(std::io::Cursor::new(&bytes)).unwrap();
        let mut sizes = vec![dec.dimensions().unwrap()];
        let mut first_offsets = vec![dec.get_tag_u64_vec(tiff::tags::Tag::TileOffsets).unwrap()[0]];
        // GDAL's block leader (size) and trailer (last 4 bytes repeated) around every tile.
        let counts = dec
            .get_tag_u64_vec(tiff::tags::Tag::TileByteCounts)
            .unwrap();
        let offsets = dec.get_tag_u64_vec(tiff::tags::Tag::TileOffsets).unwrap();
        for (&o, &c) in offsets.iter().zip(&counts) {
            let (o, c) = (o as usize, c as usize);
            assert_eq!(
                u32::from_le_bytes(bytes[o - 4..o].try_into().unwrap()) as usize,
                c
            );
            assert_eq!(bytes[o + c..o + c + 4], bytes[o + c - 4..o + c]);
        }
        while dec.more_images() {
            dec.next_image().unwrap();
            sizes.push(dec.dimensions().unwrap());
            first_offsets.push(dec.get_tag_u64_vec(tiff::tags::Tag::TileOffsets).unwrap()[0]);
            if sizes.len() == 2 {
                let tiff::decoder::DecodingResult::F32(v) = dec.read_image().unwrap() else {
                    panic!("not f32");
                };
                // First overview cell: the mean of the 3 valid cells of the 2 x 2 block.
                let want = (data[1] as f64 + data[w] as f64 + data[w + 1] as f64) / 3.0;
                assert!((v[0] as f64 - want).abs() < 1e-4, "{} vs {want}", v[0]);
                let want =
                    (data[2] as f64 + data[3] as f64 + data[w + 2] as f64 + data[w + 3] as f64)
                        / 4.0;
                assert!((v[1] as f64 - want).abs() < 1e-4);
            }
        }
        assert_eq!(sizes, vec![(100, 70), (50, 35), (25, 18), (13, 9)]);
        // Every directory before any data; data from the smallest overview to full resolution.
        let last_ifd_end = first_offsets.iter().min().copied().unwrap();
        assert!(last_ifd_end < 4096);
        for pair in first_offsets.windows(2) {
            assert!(pair[0] > pair[1], "{first_offsets:?}");
        }
    }

    #[test]
    fn bad_rows_and_unfinished_writers_leave_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.tif");
        let opts = TiledOptions {
            tile: 16,
            cog: true,
            ..Default::default()
        };
        let mut out = TiledGeoTiffWriter::create(&p, 40, 40, (1.0, 1.0), None, opts).unwrap();
        assert!(out.write_rows(&[0.0; 39]).is_err());
        out.write_rows(&[0.0; 40 * 10]).unwrap();
        assert!(out.write_rows(&[0.0; 40 * 31]).is_err());
        drop(out);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        let out = TiledGeoTiffWriter::create(&p, 40, 40, (1.0, 1.0), None, opts).unwrap();
        assert!(out.finish().is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        for tile in [0, 8, 24, 1 << 15] {
            let o = TiledOptions { tile, ..opts };
            assert!(TiledGeoTiffWriter::create(&p, 40, 40, (1.0, 1.0), None, o).is_err());
        }
    }

    #[test]
    fn directories_encode_big_and_classic() {
        let dirs = vec![
            vec![
                (256u16, Value::Long(vec![5])),
                (324, Value::Offsets(vec![1 << 33, 7])),
            ],
            vec![(256u16, Value::Long(vec![3]))],
        ];
        let big = encode_directories(true, &dirs, 16);
        // First directory: 8-byte count, 2 entries of 20 bytes, 8-byte next.
        assert_eq!(u64::from_le_bytes(big[0..8].try_into().unwrap()), 2);
        let off = u64::from_le_bytes(big[8 + 20 + 12..8 + 20 + 20].try_into().unwrap());
        // The two offsets (16 bytes) did not fit inline: stored after the table.
        assert_eq!(off, 16 + 8 + 40 + 8);
        let stored = &big[(off - 16) as usize..(off - 16) as usize + 8];
        assert_eq!(u64::from_le_bytes(stored.try_into().unwrap()), 1 << 33);
        let classic = encode_directories(false, &dirs, 8);
        assert_eq!(u16::from_le_bytes(classic[0..2].try_into().unwrap()), 2);
    }
}
