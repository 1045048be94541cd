use ndarray::{Array2, ArrayView2, ArrayViewMut2};
use serde::{Deserialize, Serialize};

use crate::error::{HeightfieldError, Result};

/// Largest number of cells any heightfield may hold (2^31, e.g. 46341^2); readers check declared
/// sizes against this before they allocate.
pub const MAX_CELLS: usize = 1 << 31;

/// Georeference carried through unchanged. The raw GeoTIFF tags are kept verbatim so that a
/// GeoTIFF written back has the same georeference; other formats fill what they know.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GeoRef {
    /// GeoTIFF `ModelPixelScaleTag` (33550).
    pub pixel_scale: Option<Vec<f64>>,
    /// GeoTIFF `ModelTiepointTag` (33922).
    pub tiepoints: Option<Vec<f64>>,
    /// GeoTIFF `ModelTransformationTag` (34264).
    pub transformation: Option<Vec<f64>>,
    /// GeoTIFF `GeoKeyDirectoryTag` (34735).
    pub geo_key_directory: Option<Vec<u16>>,
    /// GeoTIFF `GeoDoubleParamsTag` (34736).
    pub geo_double_params: Option<Vec<f64>>,
    /// GeoTIFF `GeoAsciiParamsTag` (34737).
    pub geo_ascii_params: Option<String>,
    /// A human-readable CRS name when known (e.g. `EPSG:3857`, `WGS84 geographic`).
    pub crs: Option<String>,
    /// Affine transform `[x0, dx, rx, y0, ry, dy]` (GDAL order) of the grid's outer corner.
    pub geotransform: Option<[f64; 6]>,
}

impl GeoRef {
    /// The georeference of a window of the grid starting at column `x`, row `y`, with cells
    /// `sx`, `sy` times the original size. Only the affine part changes; tags that cannot be
    /// updated consistently (a tiepoint list with several points) are dropped.
    pub fn window(&self, x: f64, y: f64, sx: f64, sy: f64) -> GeoRef {
        let mut g = self.clone();
        if let Some(t) = g.geotransform.as_mut() {
            let (x0, y0) = (t[0] + x * t[1] + y * t[2], t[3] + x * t[4] + y * t[5]);
            *t = [x0, t[1] * sx, t[2] * sy, y0, t[4] * sx, t[5] * sy];
        }
        if let (Some(scale), Some(tp)) = (g.pixel_scale.as_mut(), g.tiepoints.as_mut()) {
            if tp.len() == 6 && scale.len() >= 2 {
                // Tiepoint (i, j, k) -> (X, Y, Z); move it to the window origin.
                let (px, py) = (tp[0], tp[1]);
                tp[3] += (x - px) * scale[0];
                tp[4] -= (y - py) * scale[1];
                tp[0] = 0.0;
                tp[1] = 0.0;
                scale[0] *= sx;
                scale[1] *= sy;
            }
        } else if g.tiepoints.as_ref().is_some_and(|t| t.len() > 6) {
            g.tiepoints = None;
        }
        if g.transformation.is_some() && (x != 0.0 || y != 0.0 || sx != 1.0 || sy != 1.0) {
            if let Some(m) = g.transformation.as_mut().filter(|m| m.len() == 16) {
                let (a, b, d, e) = (m[0], m[1], m[4], m[5]);
                m[3] += a * x + b * y;
                m[7] += d * x + e * y;
                m[0] *= sx;
                m[4] *= sx;
                m[1] *= sy;
                m[5] *= sy;
            } else {
                g.transformation = None;
            }
        }
        g
    }
}

/// A regular grid of `f32` elevations (metres). Row 0 is north, column 0 west; voids are `NaN`.
#[derive(Debug, Clone, PartialEq)]
pub struct Heightfield {
    data: Array2<f32>,
    cell_x: f64,
    cell_y: f64,
    georef: Option<GeoRef>,
}

pub(crate) fn check_dims(width: usize, height: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(HeightfieldError::InvalidDimensions {
            width,
            height,
            reason: "zero size",
        });
    }
    match width.checked_mul(height) {
        Some(n) if n <= MAX_CELLS => Ok(()),
        _ => Err(HeightfieldError::InvalidDimensions {
            width,
            height,
            reason: "more cells than the 2^31 limit",
        }),
    }
}

fn check_cell(cell_x: f64, cell_y: f64) -> Result<()> {
    if cell_x.is_finite() && cell_y.is_finite() && cell_x > 0.0 && cell_y > 0.0 {
        Ok(())
    } else {
        Err(HeightfieldError::InvalidCellSize { cell_x, cell_y })
    }
}

impl Heightfield {
    /// Builds a heightfield from row-major samples (`height` rows of `width` values).
    pub fn new(
        width: usize,
        height: usize,
        data: Vec<f32>,
        cell_x: f64,
        cell_y: f64,
    ) -> Result<Self> {
        check_dims(width, height)?;
        check_cell(cell_x, cell_y)?;
        if data.len() != width * height {
            return Err(HeightfieldError::LengthMismatch {
                width,
                height,
                expected: width * height,
                got: data.len(),
            });
        }
        let data = Array2::from_shape_vec((height, width), data).map_err(|_| {
            HeightfieldError::InvalidDimensions {
                width,
                height,
                reason: "shape",
            }
        })?;
        Ok(Self {
            data,
            cell_x,
            cell_y,
            georef: None,
        })
    }

    /// Builds a heightfield from an array of shape `(rows, cols)`.
    pub fn from_array(data: Array2<f32>, cell_x: f64, cell_y: f64) -> Result<Self> {
        let (h, w) = data.dim();
        check_dims(w, h)?;
        check_cell(cell_x, cell_y)?;
        let data = if data.is_standard_layout() {
            data
        } else {
            data.as_standard_layout().to_owned()
        };
        Ok(Self {
            data,
            cell_x,
            cell_y,
            georef: None,
        })
    }

    /// Builds a heightfield from `f(column, row)`.
    ///
    /// # Panics
    /// Panics if the size is zero or the cell size is not positive (use [`Heightfield::new`] for
    /// user input).
    pub fn from_fn(
        width: usize,
        height: usize,
        cell_x: f64,
        cell_y: f64,
        mut f: impl FnMut(usize, usize) -> f32,
    ) -> Self {
        check_dims(width, height).expect("from_fn: invalid dimensions");
        check_cell(cell_x, cell_y).expect("from_fn: invalid cell size");
        let data = Array2::from_shape_fn((height, width), |(y, x)| f(x, y));
        Self {
            data,
            cell_x,
            cell_y,
            georef: None,
        }
    }

    /// A grid of the same size, cell and georeference with new samples (row-major).
    pub fn with_data(&self, data: Vec<f32>) -> Result<Self> {
        let mut out = Self::new(self.width(), self.height(), data, self.cell_x, self.cell_y)?;
        out.georef = self.georef.clone();
        Ok(out)
    }

    /// Number of columns.
    pub fn width(&self) -> usize {
        self.data.ncols()
    }
    /// Number of rows.
    pub fn height(&self) -> usize {
        self.data.nrows()
    }
    /// Number of cells.
    pub fn len(&self) -> usize {
        self.data.len()
    }
    /// Always false: a heightfield has at least one cell.
    pub fn is_empty(&self) -> bool {
        false
    }
    /// Cell size `(east-west, north-south)` in metres.
    pub fn cell_size(&self) -> (f64, f64) {
        (self.cell_x, self.cell_y)
    }
    /// Sets the cell size (metres).
    pub fn set_cell_size(&mut self, cell_x: f64, cell_y: f64) -> Result<()> {
        check_cell(cell_x, cell_y)?;
        self.cell_x = cell_x;
        self.cell_y = cell_y;
        Ok(())
    }
    /// The georeference, if any.
    pub fn georef(&self) -> Option<&GeoRef> {
        self.georef.as_ref()
    }
    /// Sets or clears the georeference.
    pub fn set_georef(&mut self, georef: Option<GeoRef>) {
        self.georef = georef;
    }
    /// Builder form of [`Heightfield::set_georef`].
    pub fn with_georef(mut self, georef: Option<GeoRef>) -> Self {
        self.georef = georef;
        self
    }
    /// The samples as an array view of shape `(rows, cols)`.
    pub fn view(&self) -> ArrayView2<'_, f32> {
        self.data.view()
    }
    /// The samples as a mutable array view.
    pub fn view_mut(&mut self) -> ArrayViewMut2<'_, f32> {
        self.data.view_mut()
    }
    /// The sample array.
    pub fn array(&self) -> &Array2<f32> {
        &self.data
    }
    /// Consumes the heightfield and returns its sample array.
    pub fn into_array(self) -> Array2<f32> {
        self.data
    }
    /// Consumes the heightfield and returns its row-major samples, without copying them
    /// (the array is in standard layout, an invariant, and owns exactly its samples).
    pub fn into_vec(self) -> Vec<f32> {
        let n = self.data.len();
        match self.data.into_raw_vec_and_offset() {
            (v, Some(0)) if v.len() == n => v,
            (v, Some(o)) if o + n <= v.len() => v[o..o + n].to_vec(),
            (v, _) => v,
        }
    }
    /// Row-major samples.
    pub fn as_slice(&self) -> &[f32] {
        self.data
            .as_slice()
            .expect("standard layout is an invariant")
    }
    /// Mutable row-major samples.
    pub fn as_mut_slice(&mut self) -> &mut [f32] {
        self.data
            .as_slice_mut()
            .expect("standard layout is an invariant")
    }
    /// Sample at column `x`, row `y`.
    ///
    /// # Panics
    /// Panics when out of bounds.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> f32 {
        self.data[(y, x)]
    }
    /// Sets the sample at column `x`, row `y`.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: f32) {
        self.data[(y, x)] = v;
    }
    /// Sample with clamped (edge-replicating) coordinates.
    #[inline]
    pub fn get_clamped(&self, x: isize, y: isize) -> f32 {
        let xx = x.clamp(0, self.width() as isize - 1) as usize;
        let yy = y.clamp(0, self.height() as isize - 1) as usize;
        self.data[(yy, xx)]
    }

    /// Number of void (non-finite) cells.
    pub fn void_count(&self) -> usize {
        self.as_slice().iter().filter(|v| !v.is_finite()).count()
    }
    /// True if any cell is void.
    pub fn has_voids(&self) -> bool {
        self.as_slice().iter().any(|v| !v.is_finite())
    }
    /// Errors unless every cell is valid; method crates call this on their inputs.
    pub fn require_complete(&self) -> Result<()> {
        // Blocks of 64 cells tested at once (vectorised), the count only when one is void.
        if self
            .as_slice()
            .chunks(64)
            .all(|c| c.iter().fold(true, |all, v| all & v.is_finite()))
        {
            return Ok(());
        }
        match self.void_count() {
            0 => Ok(()),
            n if n == self.len() => Err(HeightfieldError::AllVoid { count: n }),
            count => Err(HeightfieldError::HasVoids { count }),
        }
    }
    /// Validity mask (true = valid sample), row-major.
    pub fn valid_mask(&self) -> Vec<bool> {
        self.as_slice().iter().map(|v| v.is_finite()).collect()
    }

    /// Copies the window at column `x`, row `y` of size `w` x `h`; the georeference follows.
    pub fn crop(&self, x: usize, y: usize, w: usize, h: usize) -> Result<Self> {
        let oob = || HeightfieldError::WindowOutOfBounds {
            x,
            y,
            w,
            h,
            width: self.width(),
            height: self.height(),
        };
        if w == 0 || h == 0 {
            return Err(oob());
        }
        let (xe, ye) = (
            x.checked_add(w).ok_or_else(oob)?,
            y.checked_add(h).ok_or_else(oob)?,
        );
        if xe > self.width() || ye > self.height() {
            return Err(oob());
        }
        let data = self.data.slice(ndarray::s![y..ye, x..xe]).to_owned();
        Ok(Self {
            data,
            cell_x: self.cell_x,
            cell_y: self.cell_y,
            georef: self
                .georef
                .as_ref()
                .map(|g| g.window(x as f64, y as f64, 1.0, 1.0)),
        })
    }

    /// Minimum and maximum over valid cells, `None` if all are void.
    pub fn min_max(&self) -> Option<(f32, f32)> {
        let mut it = self.as_slice().iter().copied().filter(|v| v.is_finite());
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), v| (lo.min(v), hi.max(v))))
    }

    /// Elevation range `max - min` over valid cells (0 when all are void).
    pub fn relief(&self) -> f32 {
        self.min_max().map_or(0.0, |(lo, hi)| hi - lo)
    }

    /// Applies `f` to every sample.
    pub fn map(&self, f: impl Fn(f32) -> f32) -> Self {
        Self {
            data: self.data.mapv(f),
            cell_x: self.cell_x,
            cell_y: self.cell_y,
            georef: self.georef.clone(),
        }
    }
}
