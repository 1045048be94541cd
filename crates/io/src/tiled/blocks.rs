//! Encoded blocks copied from tiled GeoTIFF to tiled GeoTIFF without decoding them: a mosaic
//! of tiles that were written with the output's own block size and codec, whose block grids
//! line up with the output's, is the tiles' blocks in the output's order. The bytes are those
//! [`TiledGeoTiffWriter::write_rows`] would write for the same values (the same codec, the
//! same zero padding of the last column and row of blocks), without the second decoding and
//! encoding.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use super::{F, TiledGeoTiffWriter};
use crate::{IoError, Result, TiffCompression};

/// The stored blocks of a tiled single-band float32 GeoTIFF (see the module documentation).
#[derive(Debug)]
pub struct EncodedBlocks {
    file: File,
    path: PathBuf,
    width: usize,
    height: usize,
    tile: usize,
    compression: TiffCompression,
    has_nan: bool,
    offsets: Vec<u64>,
    counts: Vec<u64>,
    file_len: u64,
}

/// The codec of TIFF `Compression` tag value `tag` (with the floating-point predictor when
/// compressed, as relief writes them).
fn codec(tag: u16) -> Option<TiffCompression> {
    [
        TiffCompression::None,
        TiffCompression::Deflate,
        TiffCompression::Zstd,
        TiffCompression::Lzw,
    ]
    .into_iter()
    .find(|c| c.tag() == tag)
}

impl EncodedBlocks {
    /// Opens `path`: a tiled float32 single-band TIFF with square blocks, its codec one of
    /// [`TiffCompression`]'s with the floating-point predictor (none when uncompressed), every
    /// block inside the file. Anything else is an error naming what differs.
    pub fn open(path: &Path) -> Result<Self> {
        use tiff::tags::Tag;
        let bad = |why: String| IoError::unsupported(F, format!("{}: {why}", path.display()));
        let terr = |e: tiff::TiffError| IoError::malformed(F, format!("{}: {e}", path.display()));
        let file = File::open(path).map_err(|e| IoError::os(path, e))?;
        let file_len = file.metadata().map_err(|e| IoError::os(path, e))?.len();
        let mut d = tiff::decoder::Decoder::new(std::io::BufReader::new(
            file.try_clone().map_err(|e| IoError::os(path, e))?,
        ))
        .map_err(terr)?;
        let (w, h) = d.dimensions().map_err(terr)?;
        if d.get_chunk_type() != tiff::decoder::ChunkType::Tile {
            return Err(bad("not tiled".into()));
        }
        let (tw, th) = d.chunk_dimensions();
        let mut short = |tag: Tag, default: u16| -> Result<u16> {
            Ok(d.find_tag_unsigned::<u16>(tag)
                .map_err(terr)?
                .unwrap_or(default))
        };
        let layout = [
            short(Tag::BitsPerSample, 1)?,
            short(Tag::SamplesPerPixel, 1)?,
            short(Tag::SampleFormat, 1)?,
            short(Tag::PlanarConfiguration, 1)?,
        ];
        if layout != [32, 1, 3, 1] || tw != th || tw == 0 {
            return Err(bad(format!(
                "not single-band float32 with square blocks (bits, samples, format, planar \
                 {layout:?}, blocks {tw} x {th})"
            )));
        }
        let ctag = short(Tag::Compression, 1)?;
        let predictor = short(Tag::Predictor, 1)?;
        let compression = codec(ctag)
            .filter(|c| predictor == if *c == TiffCompression::None { 1 } else { 3 })
            .ok_or_else(|| bad(format!("compression {ctag} with predictor {predictor}")))?;
        let offsets: Vec<u64> = d
            .find_tag_unsigned_vec(Tag::TileOffsets)
            .map_err(terr)?
            .unwrap_or_default();
        let counts: Vec<u64> = d
            .find_tag_unsigned_vec(Tag::TileByteCounts)
            .map_err(terr)?
            .unwrap_or_default();
        let (width, height, tile) = (w as usize, h as usize, tw as usize);
        let n = width.div_ceil(tile) * height.div_ceil(tile);
        if offsets.len() != n || counts.len() != n {
            return Err(bad(format!(
                "{} block offsets and {} byte counts for {n} blocks",
                offsets.len(),
                counts.len()
            )));
        }
        if offsets
            .iter()
            .zip(&counts)
            .any(|(&o, &c)| c == 0 || o.checked_add(c).is_none_or(|e| e > file_len))
        {
            return Err(bad("a block lies outside the file".into()));
        }
        let has_nan = matches!(
            d.find_tag(Tag::GdalNodata).map_err(terr)?,
            Some(v) if v.clone().into_string().is_ok_and(|s| s.trim_end_matches('\0').trim() == "nan")
        );
        Ok(EncodedBlocks {
            file,
            path: path.to_path_buf(),
            width,
            height,
            tile,
            compression,
            has_nan,
            offsets,
            counts,
            file_len,
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

    /// Block side in cells.
    pub fn tile(&self) -> usize {
        self.tile
    }

    /// The blocks' codec.
    pub fn compression(&self) -> TiffCompression {
        self.compression
    }

    /// Whether the file declares voids (`GDAL_NODATA = nan`, as relief writes it when a value
    /// is NaN).
    pub fn has_nan(&self) -> bool {
        self.has_nan
    }

    /// Appends the stored bytes of the blocks of block row `row` to `out`, one vector per
    /// block, west to east.
    pub fn read_block_row(&mut self, row: usize, out: &mut Vec<Vec<u8>>) -> Result<()> {
        let cols = self.width.div_ceil(self.tile);
        if row >= self.height.div_ceil(self.tile) {
            return Err(IoError::param(
                "block row",
                row,
                format!("{} has fewer block rows", self.path.display()),
            ));
        }
        for k in row * cols..(row + 1) * cols {
            let (o, c) = (self.offsets[k], self.counts[k]);
            debug_assert!(o + c <= self.file_len);
            let mut b = vec![0u8; c as usize];
            self.file
                .seek(SeekFrom::Start(o))
                .and_then(|_| self.file.read_exact(&mut b))
                .map_err(|e| IoError::os(&self.path, e))?;
            out.push(b);
        }
        Ok(())
    }
}

impl TiledGeoTiffWriter {
    /// Appends the next band of blocks as encoded bytes (row-major across the raster, in this
    /// writer's codec and block size: the blocks of another file written with both, such as
    /// [`EncodedBlocks::read_block_row`] gives), covering `rows` rows (the block side, or the
    /// rows left for the last band); `has_nan` says whether any of their values is NaN. Only a
    /// plain (not COG) writer takes blocks, at a band boundary.
    pub fn write_encoded_band(
        &mut self,
        blocks: &[Vec<u8>],
        rows: usize,
        has_nan: bool,
    ) -> Result<()> {
        let tile = self.opts.tile;
        let left = self.height() - self.rows_written();
        let cols = self.width().div_ceil(tile);
        let level = &self.levels[0];
        let why = if self.opts.cog || self.levels.len() > 1 {
            Some("a COG's overviews are made from the values".to_string())
        } else if self.finished || !level.band.is_empty() {
            Some("the writer is not at a band boundary".to_string())
        } else if rows != tile.min(left) || rows == 0 {
            Some(format!("{rows} rows where the band has {}", tile.min(left)))
        } else if blocks.len() != cols {
            Some(format!("{} blocks for {cols} columns", blocks.len()))
        } else {
            None
        };
        if let Some(why) = why {
            return Err(IoError::param("encoded band", "refused", why));
        }
        let path = self.path.clone();
        let os = |e| IoError::os(&path, e);
        let level = &mut self.levels[0];
        for b in blocks {
            level.offsets.push(level.base + level.written);
            level.counts.push(b.len() as u64);
            level.sink.write_all(b).map_err(os)?;
            level.written += b.len() as u64;
        }
        level.rows += rows;
        self.has_nan |= has_nan;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TiledOptions;

    fn field(w: usize, h: usize, voids: bool) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                if voids && (x - 40.0).abs() < 3.0 && (y - 20.0).abs() < 2.0 {
                    f32::NAN
                } else {
                    (x * 0.31).sin() * 50.0 + y * 0.7 + (x * y * 1e-3).cos()
                }
            })
            .collect()
    }

    fn write(path: &Path, w: usize, h: usize, data: &[f32], opts: TiledOptions) {
        let mut out = TiledGeoTiffWriter::create(path, w, h, (2.0, 2.0), None, opts).unwrap();
        out.write_rows(data).unwrap();
        out.finish().unwrap();
    }

    /// A 2 x 2 mosaic of tiles (the east and south ones partial blocks) copied block by block
    /// is byte for byte the file written from the values, with or without voids, for every
    /// codec.
    #[test]
    fn copied_blocks_equal_the_file_written_from_the_values() {
        let dir = tempfile::tempdir().unwrap();
        let (w, h, t, side) = (100, 75, 16, 64);
        for compression in [
            TiffCompression::Deflate,
            TiffCompression::None,
            TiffCompression::Lzw,
        ] {
            for voids in [false, true] {
                let all = field(w, h, voids);
                let opts = TiledOptions {
                    tile: t,
                    compression,
                    ..Default::default()
                };
                let whole = dir.path().join("whole.tif");
                write(&whole, w, h, &all, opts);
                let mut parts = Vec::new();
                for (ty, tx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                    let (x0, y0) = (tx * side, ty * side);
                    let (pw, ph) = ((w - x0).min(side), (h - y0).min(side));
                    let data: Vec<f32> = (y0..y0 + ph)
                        .flat_map(|y| all[y * w + x0..y * w + x0 + pw].to_vec())
                        .collect();
                    let p = dir.path().join(format!("part-{ty}{tx}.tif"));
                    write(&p, pw, ph, &data, opts);
                    parts.push(EncodedBlocks::open(&p).unwrap());
                }
                assert_eq!(parts[0].compression(), compression);
                assert_eq!(parts[0].tile(), t);
                let joined = dir.path().join("joined.tif");
                let mut out =
                    TiledGeoTiffWriter::create(&joined, w, h, (2.0, 2.0), None, opts).unwrap();
                for ty in 0..2 {
                    let rows_of_tiles = parts[2 * ty].height().div_ceil(t);
                    for r in 0..rows_of_tiles {
                        let mut blocks = Vec::new();
                        let mut nan = false;
                        for p in &mut parts[2 * ty..2 * ty + 2] {
                            p.read_block_row(r, &mut blocks).unwrap();
                            nan |= p.has_nan();
                        }
                        let rows = t.min(h - out.rows_written());
                        out.write_encoded_band(&blocks, rows, nan).unwrap();
                    }
                }
                out.finish().unwrap();
                assert_eq!(
                    std::fs::read(&whole).unwrap(),
                    std::fs::read(&joined).unwrap(),
                    "{compression:?} voids {voids}"
                );
            }
        }
    }

    /// Bands that do not fit are refused, and strips or integer files are not blocks.
    #[test]
    fn mismatched_bands_and_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.tif");
        let opts = TiledOptions {
            tile: 16,
            ..Default::default()
        };
        let mut out = TiledGeoTiffWriter::create(&p, 40, 20, (1.0, 1.0), None, opts).unwrap();
        assert!(
            out.write_encoded_band(&vec![vec![1]; 2], 16, false)
                .is_err()
        );
        assert!(
            out.write_encoded_band(&vec![vec![1]; 3], 20, false)
                .is_err()
        );
        out.write_rows(&[0.0; 40]).unwrap();
        assert!(
            out.write_encoded_band(&vec![vec![1]; 3], 15, false)
                .is_err()
        );
        let cog = TiledOptions { cog: true, ..opts };
        let mut c = TiledGeoTiffWriter::create(&p, 40, 20, (1.0, 1.0), None, cog).unwrap();
        assert!(c.write_encoded_band(&vec![vec![1]; 3], 16, false).is_err());
        let strips = dir.path().join("s.tif");
        let hf = relief_heightfield::Heightfield::new(8, 8, vec![1.0; 64], 1.0, 1.0).unwrap();
        crate::write(&strips, &hf, &Default::default()).unwrap();
        assert!(EncodedBlocks::open(&strips).is_err());
    }
}
