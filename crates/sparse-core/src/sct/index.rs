//! Where a layer's primitives are, and the uniform-grid index of supports that point queries use.

use super::*;

/// Where the primitives of a layer are.
#[derive(Debug, Clone, PartialEq)]
pub enum Placement {
    /// A regular grid (the compact representation stores no centre).
    Grid(CentreGrid),
    /// Explicit centres (authoring).
    Explicit(Vec<[f64; 2]>),
}

impl Placement {
    /// Number of centres.
    pub fn len(&self) -> usize {
        match self {
            Placement::Grid(g) => g.len(),
            Placement::Explicit(c) => c.len(),
        }
    }

    /// True when there is no centre.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Centre of primitive `k`.
    pub fn centre(&self, k: usize) -> [f64; 2] {
        match self {
            Placement::Grid(g) => g.centre(k),
            Placement::Explicit(c) => c[k],
        }
    }
}

/// Uniform-grid spatial index: each cell lists (in increasing order) the primitives whose
/// support bounding box meets it, so a point query visits only nearby primitives.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SpatialIndex {
    pub(super) origin: [f64; 2],
    pub(super) cell: f64,
    pub(super) nx: usize,
    pub(super) ny: usize,
    pub(super) starts: Vec<u32>,
    pub(super) ids: Vec<u32>,
}

/// Largest number of cells per axis of a [`SpatialIndex`] (the cell grows beyond the preferred
/// size when the boxes are spread far apart, so the index never takes more than ~1M cells).
pub(super) const INDEX_MAX_CELLS_PER_AXIS: f64 = 1024.0;

impl SpatialIndex {
    /// Index of disks of radius `radius` around `centres`.
    pub(super) fn build(centres: &[[f64; 2]], radius: f64) -> Self {
        let boxes: Vec<[f64; 4]> = centres
            .par_iter()
            .map(|c| [c[0] - radius, c[1] - radius, c[0] + radius, c[1] + radius])
            .collect();
        Self::from_boxes(&boxes, 2.0 * radius)
    }

    /// Index of axis-aligned boxes `[x0, y0, x1, y1]` (finite) with preferred cell side `cell`.
    pub(super) fn from_boxes(boxes: &[[f64; 4]], cell: f64) -> Self {
        if boxes.is_empty() {
            return Self {
                origin: [0.0, 0.0],
                cell: 1.0,
                nx: 1,
                ny: 1,
                starts: vec![0, 0],
                ids: Vec::new(),
            };
        }
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for b in boxes {
            x0 = x0.min(b[0]);
            y0 = y0.min(b[1]);
            x1 = x1.max(b[2]);
            y1 = y1.max(b[3]);
        }
        let extent = (x1 - x0).max(y1 - y0);
        let cell = cell.max(extent / INDEX_MAX_CELLS_PER_AXIS);
        let cell = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            f64::MAX
        };
        let count = |span: f64| -> usize {
            let n = (span / cell).floor();
            if n.is_finite() && n >= 0.0 {
                (n as usize).min(INDEX_MAX_CELLS_PER_AXIS as usize) + 1
            } else {
                1
            }
        };
        let nx = count(x1 - x0);
        let ny = count(y1 - y0);
        let mut idx = Self {
            origin: [x0, y0],
            cell,
            nx,
            ny,
            starts: Vec::new(),
            ids: Vec::new(),
        };
        let mut counts = vec![0u32; nx * ny];
        let ranges: Vec<(usize, usize, usize, usize)> = boxes
            .par_iter()
            .map(|b| {
                let (ia, ib) = idx.span(b[0], b[2], 0);
                let (ja, jb) = idx.span(b[1], b[3], 1);
                (ia, ib, ja, jb)
            })
            .collect();
        for &(ia, ib, ja, jb) in &ranges {
            for j in ja..=jb {
                for i in ia..=ib {
                    counts[j * nx + i] += 1;
                }
            }
        }
        let mut starts = vec![0u32; nx * ny + 1];
        for k in 0..nx * ny {
            starts[k + 1] = starts[k] + counts[k];
        }
        let mut fill = starts.clone();
        let mut ids = vec![0u32; starts[nx * ny] as usize];
        for (p, &(ia, ib, ja, jb)) in ranges.iter().enumerate() {
            for j in ja..=jb {
                for i in ia..=ib {
                    let c = j * nx + i;
                    ids[fill[c] as usize] = p as u32;
                    fill[c] += 1;
                }
            }
        }
        idx.starts = starts;
        idx.ids = ids;
        idx
    }

    /// Cell range (inclusive, clamped) covering `[lo, hi]` along `axis`.
    pub(super) fn span(&self, lo: f64, hi: f64, axis: usize) -> (usize, usize) {
        let n = if axis == 0 { self.nx } else { self.ny };
        let f = |v: f64| -> usize {
            let c = ((v - self.origin[axis]) / self.cell).floor();
            c.clamp(0.0, (n - 1) as f64) as usize
        };
        (f(lo), f(hi))
    }

    pub(super) fn cell_ids(&self, x: f64, y: f64) -> &[u32] {
        let i = ((x - self.origin[0]) / self.cell).floor();
        let j = ((y - self.origin[1]) / self.cell).floor();
        if i < 0.0 || j < 0.0 || i >= self.nx as f64 || j >= self.ny as f64 {
            return &[];
        }
        let c = j as usize * self.nx + i as usize;
        &self.ids[self.starts[c] as usize..self.starts[c + 1] as usize]
    }

    /// Sorted, deduplicated primitives whose bounding box meets the rectangle.
    pub(super) fn query_rect(&self, x0: f64, y0: f64, x1: f64, y1: f64, out: &mut Vec<u32>) {
        out.clear();
        let gx1 = self.origin[0] + self.nx as f64 * self.cell;
        let gy1 = self.origin[1] + self.ny as f64 * self.cell;
        if x1 < self.origin[0] || y1 < self.origin[1] || x0 > gx1 || y0 > gy1 {
            return;
        }
        let (ia, ib) = self.span(x0, x1, 0);
        let (ja, jb) = self.span(y0, y1, 1);
        for j in ja..=jb {
            for i in ia..=ib {
                let c = j * self.nx + i;
                out.extend_from_slice(
                    &self.ids[self.starts[c] as usize..self.starts[c + 1] as usize],
                );
            }
        }
        out.sort_unstable();
        out.dedup();
    }
}
