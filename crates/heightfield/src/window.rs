//! A rectangular window of a raster, in pixels: what `--window X,Y,W,H` names in every command.

use std::str::FromStr;

/// A window of a raster: first column and row, width and height, in pixels (of the output
/// raster, for commands that write one).
///
/// ```
/// use relief_heightfield::Window;
/// let w: Window = "10, 20,300,200".parse().unwrap();
/// assert_eq!((w.x, w.y, w.width, w.height), (10, 20, 300, 200));
/// assert!("1,2,0,4".parse::<Window>().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Window {
    /// First column.
    pub x: usize,
    /// First row.
    pub y: usize,
    /// Number of columns.
    pub width: usize,
    /// Number of rows.
    pub height: usize,
}

impl Window {
    /// The window of `width x height` pixels whose first column is `x` and first row `y`.
    pub const fn new(x: usize, y: usize, width: usize, height: usize) -> Self {
        Self {
            x,
            y,
            width,
            height,
        }
    }

    /// `(x, y, width, height)`.
    pub fn as_tuple(&self) -> (usize, usize, usize, usize) {
        (self.x, self.y, self.width, self.height)
    }
}

impl FromStr for Window {
    type Err = String;

    /// Parses `X,Y,W,H` (whole pixels, W and H > 0; spaces allowed around the numbers).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let v: Vec<usize> = s
            .split(',')
            .map(|t| t.trim().parse::<usize>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("`{s}`: must be X,Y,W,H in whole pixels"))?;
        match v[..] {
            [x, y, width, height] if width > 0 && height > 0 => Ok(Window {
                x,
                y,
                width,
                height,
            }),
            _ => Err(format!("`{s}`: must be X,Y,W,H with W, H > 0")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Window;

    #[test]
    fn parses_x_y_w_h_and_names_what_is_wrong() {
        let w: Window = " 0, 1 ,8,9".parse().unwrap();
        assert_eq!(w.as_tuple(), (0, 1, 8, 9));
        for bad in [
            "1,2,3",
            "1,2,0,4",
            "1,2,4,0",
            "a,2,3,4",
            "-1,2,3,4",
            "1,2,3,4,5",
            "",
        ] {
            let e = bad.parse::<Window>().unwrap_err();
            assert!(e.contains("X,Y,W,H"), "{bad}: {e}");
        }
    }
}
