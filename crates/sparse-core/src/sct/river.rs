//! Regions (for `Replace`) and procedural rivers carved or profiled along a polyline
//! (section 5.4, figures 12-13).

use super::*;

/// A region of the plane for [`Node::Replace`] (terrain pixel coordinates).
#[derive(Debug, Clone, PartialEq)]
pub enum Region {
    /// Axis-aligned rectangle `[x0, x1] x [y0, y1]`.
    Rect {
        /// West edge.
        x0: f64,
        /// North edge.
        y0: f64,
        /// East edge.
        x1: f64,
        /// South edge.
        y1: f64,
    },
    /// Disk of centre `(cx, cy)` and radius `r`.
    Disk {
        /// Centre x.
        cx: f64,
        /// Centre y.
        cy: f64,
        /// Radius.
        r: f64,
    },
}

impl Region {
    /// Signed distance (negative inside).
    pub(super) fn signed_distance(&self, x: f64, y: f64) -> f64 {
        match *self {
            Region::Rect { x0, y0, x1, y1 } => {
                let dx = (x0 - x).max(x - x1);
                let dy = (y0 - y).max(y - y1);
                if dx <= 0.0 && dy <= 0.0 {
                    dx.max(dy)
                } else {
                    (dx.max(0.0).powi(2) + dy.max(0.0).powi(2)).sqrt()
                }
            }
            Region::Disk { cx, cy, r } => ((x - cx).powi(2) + (y - cy).powi(2)).sqrt() - r,
        }
    }

    /// Box `[x0, y0, x1, y1]` outside which the overlay weight with `falloff` is 0.
    pub(super) fn bounds(&self, falloff: f64) -> [f64; 4] {
        match *self {
            Region::Rect { x0, y0, x1, y1 } => {
                [x0 - falloff, y0 - falloff, x1 + falloff, y1 + falloff]
            }
            Region::Disk { cx, cy, r } => [
                cx - r - falloff,
                cy - r - falloff,
                cx + r + falloff,
                cy + r + falloff,
            ],
        }
    }

    /// Overlay weight: 1 inside, smooth (C1, `3t^2 - 2t^3`) decay to 0 at `falloff` outside.
    pub(super) fn weight(&self, x: f64, y: f64, falloff: f64) -> f64 {
        let d = self.signed_distance(x, y);
        if d <= 0.0 {
            1.0
        } else if d >= falloff {
            0.0
        } else {
            let t = 1.0 - d / falloff;
            t * t * (3.0 - 2.0 * t)
        }
    }

    pub(super) fn check(&self) -> Result<()> {
        let ok = match *self {
            Region::Rect { x0, y0, x1, y1 } => {
                [x0, y0, x1, y1].iter().all(|v| v.abs() <= MAX_ABS_COORD) && x0 <= x1 && y0 <= y1
            }
            Region::Disk { cx, cy, r } => {
                [cx, cy, r].iter().all(|v| v.abs() <= MAX_ABS_COORD) && r >= 0.0
            }
        };
        if ok {
            Ok(())
        } else {
            Err(SparseError::param(
                "region",
                format!("{self:?}"),
                "coordinates must be finite and within +-2^30 cells, x0 <= x1, y0 <= y1, r >= 0",
            ))
        }
    }
}

/// Cross-section of a [`River`].
#[derive(Debug, Clone, PartialEq)]
pub enum RiverMode {
    /// A relative carve, used under [`Node::Add`]: `-depth (1 - (d / w)^2)^2` for `d < w`,
    /// 0 outside (`d` distance to the polyline, `w` half width).
    Carve,
    /// An absolute bed, used under [`Node::Min`]: `bed + depth (d / w)^2` (a parabolic valley
    /// whose floor follows the per-vertex bed elevations), so `Min(terrain, river)` carves it.
    Bed(Vec<f64>),
}

/// A procedural river along a polyline (guerin2016 figures 12-13) with half width and depth
/// interpolated linearly along the path between vertices.
#[derive(Debug, Clone, PartialEq)]
pub struct River {
    pub(super) path: Vec<[f64; 2]>,
    pub(super) half_width: Vec<f64>,
    pub(super) depth: Vec<f64>,
    pub(super) mode: RiverMode,
    pub(super) bbox: [f64; 4],
    /// Largest half width.
    pub(super) wmax: f64,
    /// Segment boxes expanded by `wmax` (and a relative margin), for the carve's stamps.
    pub(super) seg_boxes: Vec<[f64; 4]>,
    /// Index of `seg_boxes`: a point query visits only the segments near it.
    pub(super) index: SpatialIndex,
}

impl River {
    /// A river through `path` (terrain pixel coordinates, >= 2 vertices) with per-vertex half
    /// widths (> 0) and depths (>= 0).
    pub fn new(
        path: Vec<[f64; 2]>,
        half_width: Vec<f64>,
        depth: Vec<f64>,
        mode: RiverMode,
    ) -> Result<Self> {
        if path.len() < 2 {
            return Err(SparseError::param(
                "path",
                path.len(),
                "a river needs at least 2 vertices",
            ));
        }
        let n = path.len();
        for (what, len) in [("half_width", half_width.len()), ("depth", depth.len())] {
            if len != n {
                return Err(SparseError::DimensionMismatch {
                    what,
                    expected: n,
                    got: len,
                });
            }
        }
        if let RiverMode::Bed(b) = &mode {
            if b.len() != n {
                return Err(SparseError::DimensionMismatch {
                    what: "bed elevations",
                    expected: n,
                    got: b.len(),
                });
            }
            if let Some(i) = b.iter().position(|v| !v.is_finite()) {
                return Err(SparseError::non_finite("bed elevations", i));
            }
            for &v in b {
                check_bounded("bed", v, MAX_ABS_ELEVATION)?;
            }
        }
        SparseError::check_points("river path", &path)?;
        for p in &path {
            check_bounded("path", p[0], MAX_ABS_COORD)?;
            check_bounded("path", p[1], MAX_ABS_COORD)?;
        }
        if let Some(&w) = half_width
            .iter()
            .find(|w| !(w.is_finite() && **w >= MIN_HALF_WIDTH && **w <= MAX_ABS_COORD))
        {
            return Err(SparseError::param(
                "half_width",
                w,
                "must be finite and in [1e-3, 2^30] cells",
            ));
        }
        if let Some(&d) = depth.iter().find(|d| !(d.is_finite() && **d >= 0.0)) {
            return Err(SparseError::param("depth", d, "must be finite and >= 0"));
        }
        for &d in &depth {
            check_bounded("depth", d, MAX_ABS_ELEVATION)?;
        }
        let wmax = half_width.iter().fold(0.0f64, |m, &w| m.max(w));
        let mut bbox = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        for p in &path {
            bbox[0] = bbox[0].min(p[0] - wmax);
            bbox[1] = bbox[1].min(p[1] - wmax);
            bbox[2] = bbox[2].max(p[0] + wmax);
            bbox[3] = bbox[3].max(p[1] + wmax);
        }
        if !bbox.iter().all(|v| v.is_finite()) {
            return Err(SparseError::param(
                "path",
                format!("{bbox:?}"),
                "the river's extent (path +- half width) must be finite",
            ));
        }
        // Every segment within `wmax` of a point has the point inside its expanded box (the
        // margin absorbs rounding), so the index and the stamps see every segment that can
        // carve the point (see `River::eval`).
        let m =
            wmax * (1.0 + 1e-9) + 1e-9 * (1.0 + bbox.iter().fold(0.0f64, |a, v| a.max(v.abs())));
        let seg_boxes: Vec<[f64; 4]> = path
            .windows(2)
            .map(|w| {
                [
                    w[0][0].min(w[1][0]) - m,
                    w[0][1].min(w[1][1]) - m,
                    w[0][0].max(w[1][0]) + m,
                    w[0][1].max(w[1][1]) + m,
                ]
            })
            .collect();
        // Cell of about two half widths, grown so that the boxes cover at most ~4M cells.
        let area: f64 = seg_boxes
            .iter()
            .map(|b| (b[2] - b[0]) * (b[3] - b[1]))
            .sum();
        let cell = (2.0 * m).max((area / f64::from(1u32 << 22)).sqrt());
        let index = SpatialIndex::from_boxes(&seg_boxes, cell);
        Ok(Self {
            path,
            half_width,
            depth,
            mode,
            bbox,
            wmax,
            seg_boxes,
            index,
        })
    }

    /// The polyline.
    pub fn path(&self) -> &[[f64; 2]] {
        &self.path
    }

    /// Per-vertex half widths.
    pub fn half_width(&self) -> &[f64] {
        &self.half_width
    }

    /// Per-vertex depths.
    pub fn depth(&self) -> &[f64] {
        &self.depth
    }

    /// The cross-section mode.
    pub fn mode(&self) -> &RiverMode {
        &self.mode
    }

    /// Squared distance from `(x, y)` to segment `s` and the position `t` of the nearest point.
    #[inline]
    pub(super) fn segment_d2(&self, s: usize, x: f64, y: f64) -> (f64, f64) {
        let [ax, ay] = self.path[s];
        let [bx, by] = self.path[s + 1];
        let (ux, uy) = (bx - ax, by - ay);
        let l2 = ux * ux + uy * uy;
        let t = if l2 > 0.0 {
            (((x - ax) * ux + (y - ay) * uy) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (px, py) = (ax + t * ux - x, ay + t * uy - y);
        (px * px + py * py, t)
    }

    /// Nearest of the segments `segs` (increasing order; the first of equal distances wins):
    /// `(squared distance, segment, t)`, or `None` when `segs` is empty.
    pub(super) fn nearest_of(
        &self,
        segs: impl Iterator<Item = usize>,
        x: f64,
        y: f64,
    ) -> Option<(f64, usize, f64)> {
        let mut best: Option<(f64, usize, f64)> = None;
        for s in segs {
            let (d2, t) = self.segment_d2(s, x, y);
            if best.is_none_or(|b| d2 < b.0) {
                best = Some((d2, s, t));
            }
        }
        best
    }

    /// Value of the river for the nearest point `(segment s, t)` at squared distance `d2`;
    /// `None` (no nearest point) is only possible in carve mode and gives 0.
    #[inline]
    pub(super) fn profile(&self, nearest: Option<(f64, usize, f64)>) -> f64 {
        let lerp = |v: &[f64], s: usize, t: f64| v[s] + (v[s + 1] - v[s]) * t;
        match (&self.mode, nearest) {
            (RiverMode::Carve, None) => 0.0,
            (RiverMode::Carve, Some((d2, s, t))) => {
                let d = d2.sqrt();
                let w = lerp(&self.half_width, s, t);
                if d >= w {
                    return 0.0;
                }
                let q = 1.0 - (d / w) * (d / w);
                -lerp(&self.depth, s, t) * q * q
            }
            (RiverMode::Bed(bed), Some((d2, s, t))) => {
                let d = d2.sqrt();
                let w = lerp(&self.half_width, s, t);
                lerp(bed, s, t) + lerp(&self.depth, s, t) * (d / w) * (d / w)
            }
            (RiverMode::Bed(_), None) => f64::NAN,
        }
    }

    pub(super) fn outside_bbox(&self, x: f64, y: f64) -> bool {
        x < self.bbox[0] || y < self.bbox[1] || x > self.bbox[2] || y > self.bbox[3]
    }

    /// Value of the river at `(x, y)`.
    ///
    /// The carve is 0 farther than the largest half width `wmax` from the path, so it only
    /// looks at the segments the spatial index lists for the point's cell: those include every
    /// segment within `wmax`, hence the nearest segment whenever the value is not 0, and the
    /// first-of-equals rule picks the same segment as a scan of all segments. The bed profile
    /// is defined everywhere and scans every segment.
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        match &self.mode {
            RiverMode::Carve => {
                if self.outside_bbox(x, y) {
                    return 0.0;
                }
                let segs = self.index.cell_ids(x, y).iter().map(|&s| s as usize);
                self.profile(self.nearest_of(segs, x, y))
            }
            RiverMode::Bed(_) => self.profile(self.nearest_of(0..self.path.len() - 1, x, y)),
        }
    }

    /// Number of segments a carve point query at `(x, y)` visits (all of them in bed mode).
    pub fn candidates_at(&self, x: f64, y: f64) -> usize {
        match self.mode {
            RiverMode::Carve if self.outside_bbox(x, y) => 0,
            RiverMode::Carve => self.index.cell_ids(x, y).len(),
            RiverMode::Bed(_) => self.path.len() - 1,
        }
    }

    /// Rasterises the river into `val` (band-sized) by stamping segments: each segment updates
    /// the running nearest `(d2, segment, t)` of the pixels of its expanded box (carve) or of
    /// the whole band (bed), in increasing segment order, then every pixel takes
    /// [`River::profile`]. Same arithmetic and tie rule as [`River::eval`], so equal bit for
    /// bit.
    pub(super) fn stamp(&self, band: &Band, val: &mut [f64]) {
        let ncols = band.cols.len();
        let sc = band.scale;
        let n = val.len();
        let mut best: Vec<Option<(f64, usize, f64)>> = vec![None; n];
        let carve = matches!(self.mode, RiverMode::Carve);
        // A bed takes every pixel of the band.
        let (c, r) = (&band.cols, &band.rows);
        let whole = Some([
            c.start as i64,
            c.end as i64 - 1,
            r.start as i64,
            r.end as i64 - 1,
        ]);
        for (s, b) in self.seg_boxes.iter().enumerate() {
            let pixels = if carve { band.pixels_over(*b) } else { whole };
            let Some([xa, xb, ya, yb]) = pixels else {
                continue;
            };
            for yi in ya..=yb {
                let y = raster_coord(yi as usize, sc);
                let row = (yi as usize - band.rows.start) * ncols;
                for xi in xa..=xb {
                    let x = raster_coord(xi as usize, sc);
                    let o = row + (xi as usize - band.cols.start);
                    let (d2, t) = self.segment_d2(s, x, y);
                    if best[o].is_none_or(|p| d2 < p.0) {
                        best[o] = Some((d2, s, t));
                    }
                }
            }
        }
        for (k, (v, b)) in val.iter_mut().zip(&best).enumerate() {
            if carve {
                let x = raster_coord(band.cols.start + k % ncols, sc);
                let y = raster_coord(band.rows.start + k / ncols, sc);
                if self.outside_bbox(x, y) {
                    *v = 0.0;
                    continue;
                }
            }
            *v = self.profile(*b);
        }
    }

    /// Largest half width.
    pub fn max_half_width(&self) -> f64 {
        self.wmax
    }
}
