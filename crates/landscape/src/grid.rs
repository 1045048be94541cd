//! The raster topology every routine of the crate shares: cell indices, the eight neighbours
//! in one fixed order, and the distances between cell centres on non-square cells.

use relief_heightfield::Heightfield;

/// The eight neighbours as `(dy, dx)`, row-major (north-west first, south-east last): the order
/// of `shared/tools/terrain_quality.py`, and the order in which ties are broken (the first
/// neighbour wins).
pub const D8: [(isize, isize); 8] = [
    (-1, -1),
    (-1, 0),
    (-1, 1),
    (0, -1),
    (0, 1),
    (1, -1),
    (1, 0),
    (1, 1),
];

/// No receiver: an outlet (a cell on the map's edge or beside a void that drains off the map),
/// a void, or a sink left in place.
pub const NO_FLOW: u8 = 255;

/// The opposite direction of each of [`D8`] (`D8[OPPOSITE[k]] = -D8[k]`).
pub const OPPOSITE: [u8; 8] = [7, 6, 5, 4, 3, 2, 1, 0];

/// A `width x height` raster of cells `cell_x` (east-west) by `cell_y` (north-south) metres;
/// cell `(x, y)` has index `y * width + x`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// East-west cell size (m).
    pub cell_x: f64,
    /// North-south cell size (m).
    pub cell_y: f64,
}

impl Grid {
    /// A `width x height` grid of `cell_x` by `cell_y` m cells.
    pub const fn new(width: usize, height: usize, cell_x: f64, cell_y: f64) -> Self {
        Self {
            width,
            height,
            cell_x,
            cell_y,
        }
    }

    /// The grid of a heightfield.
    pub fn of(hf: &Heightfield) -> Self {
        let (cell_x, cell_y) = hf.cell_size();
        Self::new(hf.width(), hf.height(), cell_x, cell_y)
    }

    /// Number of cells.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// True for a grid without cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Area of one cell (m^2).
    pub fn cell_area(&self) -> f64 {
        self.cell_x * self.cell_y
    }

    /// Distance (m) between the centres of a cell and its neighbour `k`, for each of [`D8`].
    pub fn distances(&self) -> [f64; 8] {
        D8.map(|(dy, dx)| (dy as f64 * self.cell_y).hypot(dx as f64 * self.cell_x))
    }

    /// Index offsets of the eight neighbours (valid only for cells away from the border).
    pub fn offsets(&self) -> [isize; 8] {
        let w = self.width as isize;
        D8.map(|(dy, dx)| dy * w + dx)
    }

    /// The index of neighbour `k` of cell `i`, or `None` off the map.
    #[inline]
    pub fn neighbour(&self, i: usize, k: usize) -> Option<usize> {
        let (x, y) = (i % self.width, i / self.width);
        let (dy, dx) = D8[k];
        let (nx, ny) = (x as isize + dx, y as isize + dy);
        if nx < 0 || ny < 0 || nx >= self.width as isize || ny >= self.height as isize {
            None
        } else {
            Some(ny as usize * self.width + nx as usize)
        }
    }

    /// True for a cell on the map's outer edge.
    #[inline]
    pub fn is_edge(&self, i: usize) -> bool {
        let (x, y) = (i % self.width, i / self.width);
        x == 0 || y == 0 || x + 1 == self.width || y + 1 == self.height
    }

    /// Calls `f(k, n)` for every neighbour `n` (direction `k`) of cell `i` on the map.
    #[inline]
    pub fn for_neighbours(&self, i: usize, f: impl FnMut(usize, usize)) {
        self.for_neighbours_at(i % self.width, i / self.width, i, f);
    }

    /// [`Grid::for_neighbours`] of cell `i` at column `x`, row `y`, for loops that know them
    /// (no division per cell).
    #[inline]
    pub fn for_neighbours_at(&self, x: usize, y: usize, i: usize, mut f: impl FnMut(usize, usize)) {
        debug_assert_eq!(i, y * self.width + x);
        if x > 0 && y > 0 && x + 1 < self.width && y + 1 < self.height {
            for (k, (dy, dx)) in D8.iter().enumerate() {
                f(k, (i as isize + dy * self.width as isize + dx) as usize);
            }
        } else {
            for k in 0..8 {
                if let Some(n) = self.neighbour(i, k) {
                    f(k, n);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opposite_reverses_each_direction() {
        for k in 0..8 {
            let (dy, dx) = D8[k];
            assert_eq!(D8[OPPOSITE[k] as usize], (-dy, -dx));
        }
    }

    #[test]
    fn distances_follow_non_square_cells() {
        let g = Grid::new(4, 3, 30.0, 40.0);
        let d = g.distances();
        assert_eq!(d[1], 40.0);
        assert_eq!(d[3], 30.0);
        assert_eq!(d[0], 50.0);
        let mut seen = Vec::new();
        g.for_neighbours(0, |k, n| seen.push((k, n)));
        assert_eq!(seen, vec![(4, 1), (6, 4), (7, 5)]);
    }
}
