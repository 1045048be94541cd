//! The Sparse Construction Tree (guerin2016 sections 4.1 and 5.4): sparse layers of primitives
//! blended by `f(p) = sum_i f_i(p) alpha_i(p) / sum_i alpha_i(p)`, operator nodes and procedural
//! primitives, evaluation at any point and rasterisation of any window at any scale.
//!
//! # Value and weight
//! Every node evaluates to a pair `(value, weight)`. A [`SparseLayer`] gives
//! `(sum f_i alpha_i / sum alpha_i, sum alpha_i)` (value NaN where no support covers the point);
//! [`Node::Blend`] normalises the weighted sum of its children the same way, so blending layers
//! generalises the equation above to sub-trees. The other operators keep the weight of their
//! first child (the base) and combine values: [`Node::Add`] sums, [`Node::Max`]/[`Node::Min`]
//! take the extremum (carving: `Min(terrain, river bed)`), [`Node::Replace`] blends an overlay
//! into the base inside a [`Region`] with a smooth fall-off.
//!
//! # Rasterisation
//! [`Sct::rasterize`] splits the requested window into bands of rows processed in parallel.
//! A layer is rasterised by *stamping*: each primitive whose support meets the band first sums
//! its data atoms into one `a x a` patch `P_i = sum_j x_i^j d_j`, then adds
//! `(z_i + bicubic(P_i) + function atoms) alpha_i` and `alpha_i` into numerator and denominator
//! buffers, using a separable bicubic (one horizontal pass per patch row, then four taps per
//! pixel). Primitives are always visited in increasing index order and every pixel's value is
//! computed by the same arithmetic as [`Sct::eval`], so a window rasterised alone equals the
//! same window of the full raster bit for bit, and both equal point evaluation, whatever the
//! thread count.
//!
//! The other nodes are stamped too: a [`River`] stamps each segment over the pixels of its box
//! grown by the largest half width (carve) or over the band (bed profile, defined everywhere),
//! keeping per pixel the nearest segment in increasing segment order; [`Node::Replace`] stamps
//! its overlay only on the part of the band where the region's weight is non-zero; operators
//! combine their children's band buffers pixel by pixel with the same function as
//! [`Node::eval`]. Every node kind therefore rasterises bit for bit like point evaluation
//! (tested for each kind and for random trees).
//!
//! Point queries visit only nearby primitives: each layer and each carving river keeps a
//! uniform-grid index of its supports (disks, segment boxes).
//!
//! One grid convention, pixel-is-area: the raster at scale factor `s` covers the encoded grid's
//! extent with cells `1 / s` as large, so it has `round(w s)` columns (at least 1) and pixel
//! `(X, Y)` samples the terrain at pixel coordinates `((X + 1/2) / s - 1/2, (Y + 1/2) / s - 1/2)`
//! ([`raster_coord`]; exactly `(X, Y)` at scale 1).
//!
//! Files: `index.rs` (placement and the uniform-grid spatial index), `layer.rs` (sparse layers
//! and their stamping), `river.rs` (regions and procedural rivers), `node.rs` (the operator tree),
//! `spec.rs` (trees authored from a JSON description),
//! this file (windows, raster settings and [`Sct`]).

mod field;
mod index;
mod layer;
mod node;
mod river;
mod spec;

pub use field::Field;
pub use index::Placement;
pub use layer::SparseLayer;
pub use node::Node;
pub use river::{Region, River, RiverMode};
pub use spec::{NodeSpec, Profile, RegionSpec, RiverSpec, RiverValleySpec, TreeSpec};

use index::SpatialIndex;
pub use layer::raster_coord;
use layer::{Band, StampScratch};

use std::sync::Arc;

use rayon::prelude::*;
use relief_heightfield::{GeoRef, Heightfield, NoProgress, Progress};

use crate::dictionary::{Atom, Dictionary};
use crate::error::{Result, SparseError};
use crate::omp::SparseCodes;
use crate::patches::{CentreGrid, cubic_weights};

/// A window of the output raster, in output pixels at the requested scale (the workspace's one
/// window type, from `relief-heightfield`).
pub use relief_heightfield::Window;

/// `None` when `win` is non-empty and inside a `width x height` raster (whatever its numbers,
/// without overflow), else the value an error names: `x,y,w,h (<of> width x height)`.
pub fn window_outside(win: &Window, (width, height): (usize, usize), of: &str) -> Option<String> {
    let fits = |start: usize, len: usize, end: usize| {
        len > 0 && start.checked_add(len).is_some_and(|e| e <= end)
    };
    if fits(win.x, win.width, width) && fits(win.y, win.height, height) {
        return None;
    }
    let (x, y, w, h) = win.as_tuple();
    Some(format!("{x},{y},{w},{h} ({of} {width} x {height})"))
}

/// Largest `|value|` in metres of an elevation a tree states (a constant, a river's depth,
/// bed or floor): a million kilometres, far beyond any terrain, so a larger value is a unit or
/// typing error, and sums of such values stay finite in an `f32` raster.
pub const MAX_ABS_ELEVATION: f64 = 1e9;
/// Largest `|coordinate|` in terrain cells of a river vertex, a region or a falloff: 2^30,
/// 64 times the widest grid.
pub const MAX_ABS_COORD: f64 = (1u64 << 30) as f64;
/// Smallest river half width in terrain cells: a thousandth of a cell (narrower ones only
/// overflow the bed profile `depth (d / w)^2` far from the axis).
pub const MIN_HALF_WIDTH: f64 = 1e-3;
/// Cell sizes of a tree's grid, metres: from a micrometre to a million kilometres.
pub const CELL_SIZE_RANGE: std::ops::RangeInclusive<f64> = 1e-6..=1e9;

/// `Err` naming `name` and `v` unless `v` is finite and `|v| <= limit`.
pub(crate) fn check_bounded(name: &'static str, v: f64, limit: f64) -> Result<()> {
    if v.is_finite() && v.abs() <= limit {
        Ok(())
    } else {
        Err(SparseError::param(
            name,
            v,
            if limit == MAX_ABS_ELEVATION {
                "must be finite and within +-1e9 metres"
            } else {
                "must be finite and within +-2^30 cells"
            },
        ))
    }
}

/// Settings of [`Sct::rasterize`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RasterSettings {
    /// Scale factor `s` (> 0): the raster covers the terrain's extent with `round(w s) x
    /// round(h s)` cells; pixel `(X, Y)` samples terrain pixel coordinates
    /// [`raster_coord`]`(X, s)`, [`raster_coord`]`(Y, s)`.
    pub scale: f64,
    /// Window of the output raster (`None` = the whole raster).
    pub window: Option<Window>,
}

impl Default for RasterSettings {
    fn default() -> Self {
        Self {
            scale: 1.0,
            window: None,
        }
    }
}

impl RasterSettings {
    /// Validates the settings on their own: `scale` finite and in `(0, 1024]`, a window (if
    /// any) non-empty and of at most `relief_heightfield::MAX_CELLS` cells. Whether the window
    /// lies inside the raster is checked by [`Sct::rasterize`].
    pub fn check(&self) -> Result<()> {
        if !(self.scale.is_finite() && self.scale > 0.0 && self.scale <= 1024.0) {
            return Err(SparseError::param(
                "scale",
                self.scale,
                "must be finite and in (0, 1024]",
            ));
        }
        if let Some(w) = self.window {
            let cells = (w.width as u128) * (w.height as u128);
            if cells == 0 || cells > relief_heightfield::MAX_CELLS as u128 {
                return Err(SparseError::param(
                    "window",
                    format!("{},{},{},{}", w.x, w.y, w.width, w.height),
                    "must be non-empty and hold at most MAX_CELLS cells",
                ));
            }
        }
        Ok(())
    }
}

/// Rows per parallel band.
const BAND_ROWS: usize = 64;
/// Columns per block of a band: a band is stamped block by block so that the stamping
/// buffers (four `f64` per cell) stay in the core's cache. A pixel's value does not depend on
/// the block (the primitives are visited in the index's order whatever the window).
const BLOCK_COLS: usize = 512;

/// A Sparse Construction Tree over a `width x height` terrain domain.
#[derive(Debug, Clone)]
pub struct Sct {
    root: Node,
    width: usize,
    height: usize,
    cell_size: (f64, f64),
    georef: Option<GeoRef>,
}

impl Sct {
    /// A tree over a `width x height` domain with the given cell size (metres).
    pub fn new(root: Node, width: usize, height: usize, cell_size: (f64, f64)) -> Result<Self> {
        if width == 0 || height == 0 || width > 1 << 24 || height > 1 << 24 {
            return Err(SparseError::param(
                "width x height",
                format!("{width} x {height}"),
                "must be in 1..=2^24",
            ));
        }
        let (cx, cy) = cell_size;
        if !(CELL_SIZE_RANGE.contains(&cx) && CELL_SIZE_RANGE.contains(&cy)) {
            return Err(SparseError::param(
                "cell_size",
                format!("{cx} x {cy}"),
                "must be in [1e-6, 1e9] metres",
            ));
        }
        root.check()?;
        Ok(Self {
            root,
            width,
            height,
            cell_size,
            georef: None,
        })
    }

    /// The georeference of the domain grid at scale 1 (pixel-is-area: domain pixel `(i, j)`
    /// covers `[i, i + 1) x [j, j + 1)` of the geotransform), carried into every raster.
    pub fn georef(&self) -> Option<&GeoRef> {
        self.georef.as_ref()
    }

    /// Sets the georeference of the domain grid (see [`Sct::georef`]).
    pub fn set_georef(&mut self, georef: Option<GeoRef>) {
        self.georef = georef;
    }

    /// Builder form of [`Sct::set_georef`].
    pub fn with_georef(mut self, georef: Option<GeoRef>) -> Self {
        self.georef = georef;
        self
    }

    /// The georeference of the raster window `win` at scale `s`: the raster's cells (size
    /// `1 / s`) tile the domain grid's extent from its corner, so raster cell `X` starts at
    /// `X / s` of the domain grid (pixel-is-area, see the module docs).
    pub fn raster_georef(&self, scale: f64, win: Window) -> Option<GeoRef> {
        self.georef.as_ref().map(|g| {
            g.window(
                win.x as f64 / scale,
                win.y as f64 / scale,
                1.0 / scale,
                1.0 / scale,
            )
        })
    }

    /// The root node.
    pub fn root(&self) -> &Node {
        &self.root
    }

    /// Replaces the root (authoring: wrap the current root in operators), checked.
    pub fn set_root(&mut self, root: Node) -> Result<()> {
        root.check()?;
        self.root = root;
        Ok(())
    }

    /// Takes the root out, leaving a constant 0 in its place.
    pub fn take_root(&mut self) -> Node {
        std::mem::replace(&mut self.root, Node::Constant(0.0))
    }

    /// Domain width in terrain pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Domain height in terrain pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Cell size `(east-west, north-south)` in metres at scale 1.
    pub fn cell_size(&self) -> (f64, f64) {
        self.cell_size
    }

    /// Every sparse layer of the tree (depth-first order).
    pub fn layers(&self) -> Vec<&SparseLayer> {
        let mut v = Vec::new();
        self.root.visit_leaves(&mut |n| {
            if let Node::Layer(l) = n {
                v.push(l);
            }
        });
        v
    }

    /// Every field node of the tree (depth-first order).
    pub fn fields(&self) -> Vec<&Field> {
        let mut v = Vec::new();
        self.root.visit_leaves(&mut |n| {
            if let Node::Field(f) = n {
                v.push(f);
            }
        });
        v
    }

    /// Elevation `f(p)` at terrain pixel coordinates `(x, y)` (NaN outside every support).
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        self.root.eval(x, y).0
    }

    /// Size `(columns, rows)` of the full raster at scale `scale`.
    pub fn raster_size(&self, scale: f64) -> Result<(usize, usize)> {
        if !(scale.is_finite() && scale > 0.0 && scale <= 1024.0) {
            return Err(SparseError::param(
                "scale",
                scale,
                "must be finite and in (0, 1024]",
            ));
        }
        let f = |n: usize| ((n as f64 * scale).round() as usize).max(1);
        let (w, h) = (f(self.width), f(self.height));
        if (w as u128) * (h as u128) > 1u128 << 34 {
            return Err(SparseError::param(
                "scale",
                scale,
                "the raster would exceed 2^34 cells",
            ));
        }
        Ok((w, h))
    }

    /// Rasterises a window at a scale factor, in parallel (see the module docs).
    pub fn rasterize(&self, settings: &RasterSettings) -> Result<Heightfield> {
        self.rasterize_with_progress(settings, &NoProgress)
    }

    /// [`Sct::rasterize`] reporting rows done to `progress` (phase `"rasterize"`).
    pub fn rasterize_with_progress(
        &self,
        settings: &RasterSettings,
        progress: &dyn Progress,
    ) -> Result<Heightfield> {
        settings.check()?;
        let (fw, fh) = self.raster_size(settings.scale)?;
        let win = settings.window.unwrap_or(Window {
            x: 0,
            y: 0,
            width: fw,
            height: fh,
        });
        if let Some(v) = window_outside(&win, (fw, fh), "raster") {
            return Err(SparseError::param(
                "window",
                v,
                "must be non-empty and inside the raster",
            ));
        }
        if (win.width as u128) * (win.height as u128) > relief_heightfield::MAX_CELLS as u128 {
            return Err(SparseError::param(
                "scale",
                settings.scale,
                "the raster would exceed MAX_CELLS cells (ask for a window)",
            ));
        }
        let mut out = vec![0f32; win.width * win.height];
        progress.begin("rasterize", win.height as u64);
        let stop = std::sync::atomic::AtomicBool::new(false);
        let scratch = || StampScratch {
            progress: Some(progress),
            ..StampScratch::default()
        };
        out.par_chunks_mut(win.width * BAND_ROWS)
            .enumerate()
            .for_each_init(scratch, |scratch, (b, chunk)| {
                use std::sync::atomic::Ordering::Relaxed;
                if stop.load(Relaxed) || scratch.should_stop() {
                    stop.store(true, Relaxed);
                    return;
                }
                let rows = chunk.len() / win.width;
                let y0 = win.y + b * BAND_ROWS;
                let cells = rows * BLOCK_COLS.min(win.width);
                let (mut val, mut wt) = (vec![0.0; cells], vec![0.0; cells]);
                for x0 in (0..win.width).step_by(BLOCK_COLS) {
                    let bw = BLOCK_COLS.min(win.width - x0);
                    let band = Band {
                        cols: win.x + x0..win.x + x0 + bw,
                        rows: y0..y0 + rows,
                        scale: settings.scale,
                    };
                    let (val, wt) = (&mut val[..rows * bw], &mut wt[..rows * bw]);
                    self.root.raster(&band, val, wt, scratch);
                    for (orow, vrow) in chunk.chunks_mut(win.width).zip(val.chunks(bw)) {
                        for (o, v) in orow[x0..x0 + bw].iter_mut().zip(vrow) {
                            *o = *v as f32;
                        }
                    }
                }
                if scratch.stopped {
                    stop.store(true, Relaxed);
                }
                progress.advance(rows as u64);
            });
        if stop.into_inner() {
            return Err(SparseError::Stopped("rasterising the model"));
        }
        let hf = Heightfield::new(
            win.width,
            win.height,
            out,
            self.cell_size.0 / settings.scale,
            self.cell_size.1 / settings.scale,
        )?
        .with_georef(self.raster_georef(settings.scale, win));
        Ok(hf)
    }
}
