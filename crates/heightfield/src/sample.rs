use crate::grid::Heightfield;

/// The four Keys weights of a fractional position, in the float type of `t`.
macro_rules! keys_weights {
    ($t:expr) => {{
        let t = $t;
        let t2 = t * t;
        let t3 = t2 * t;
        [
            -0.5 * t3 + t2 - 0.5 * t,
            1.5 * t3 - 2.5 * t2 + 1.0,
            -1.5 * t3 + 2.0 * t2 + 0.5 * t,
            0.5 * t3 - 0.5 * t2,
        ]
    }};
}

/// Keys cubic convolution weights (a = -1/2, Catmull-Rom) for the four samples at offsets
/// -1, 0, 1, 2 from the integer part, given the fractional position `t` in [0, 1). The kernel
/// interpolates (weight 1 at t = 0) and reproduces quadratics.
#[inline]
pub fn cubic_weights(t: f32) -> [f32; 4] {
    keys_weights!(t)
}

/// [`cubic_weights`] in `f64` (the same expressions, evaluated in double precision).
#[inline]
pub fn cubic_weights_f64(t: f64) -> [f64; 4] {
    keys_weights!(t)
}

impl Heightfield {
    /// Bilinear sample at pixel coordinates `(x, y)` (column, row); coordinates outside the grid
    /// are clamped to its edge. Exact at grid nodes.
    pub fn sample_bilinear(&self, x: f32, y: f32) -> f32 {
        let (w, h) = (self.width(), self.height());
        let x = x.clamp(0.0, (w - 1) as f32);
        let y = y.clamp(0.0, (h - 1) as f32);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (tx, ty) = (x - x0 as f32, y - y0 as f32);
        let a = self.get(x0, y0) * (1.0 - tx) + self.get(x1, y0) * tx;
        let b = self.get(x0, y1) * (1.0 - tx) + self.get(x1, y1) * tx;
        a * (1.0 - ty) + b * ty
    }

    /// Bicubic (Keys, a = -1/2) sample at pixel coordinates `(x, y)`; edges are replicated.
    /// Exact at grid nodes and C1-continuous.
    pub fn sample_bicubic(&self, x: f32, y: f32) -> f32 {
        let (w, h) = (self.width() as f32, self.height() as f32);
        let x = x.clamp(0.0, w - 1.0);
        let y = y.clamp(0.0, h - 1.0);
        let (xf, yf) = (x.floor(), y.floor());
        let (wx, wy) = (cubic_weights(x - xf), cubic_weights(y - yf));
        let (xi, yi) = (xf as isize, yf as isize);
        let mut acc = 0.0;
        for (dy, wyv) in wy.iter().enumerate() {
            let yy = yi + dy as isize - 1;
            let mut row = 0.0;
            for (dx, wxv) in wx.iter().enumerate() {
                row += wxv * self.get_clamped(xi + dx as isize - 1, yy);
            }
            acc += wyv * row;
        }
        acc
    }
}
