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

/// Lanczos-3 kernel `sinc(x) sinc(x / 3)` on `|x| < 3` (0 outside).
pub(crate) fn lanczos3(x: f64) -> f64 {
    let x = x.abs();
    if x < 1e-9 {
        1.0
    } else if x >= 3.0 {
        0.0
    } else {
        let px = std::f64::consts::PI * x;
        3.0 * px.sin() * (px / 3.0).sin() / (px * px)
    }
}

/// An interpolation kernel on a regular grid of samples (separable, applied along each axis).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Kernel {
    /// Keys cubic convolution (a = -1/2, Catmull-Rom): 4 taps, interpolating, reproduces
    /// quadratics ([`cubic_weights_f64`]).
    Keys,
    /// Lanczos-3 (`sinc(x) sinc(x / 3)`, 6 taps), weights normalised to sum 1: interpolating,
    /// closer to the ideal band-limited interpolation than Keys, so content near the grid's
    /// Nyquist frequency keeps about the same energy at every phase between the samples
    /// (Keys keeps it at the samples and smooths it between them).
    #[default]
    Lanczos3,
}

impl Kernel {
    /// Largest number of taps of any kernel.
    pub const MAX_TAPS: usize = 6;

    /// Number of taps `n`: the weights of [`Self::weights`] apply to the samples at offsets
    /// `1 - n / 2 ..= n / 2` from the integer part of the position.
    #[inline]
    pub const fn taps(self) -> usize {
        match self {
            Kernel::Keys => 4,
            Kernel::Lanczos3 => 6,
        }
    }

    /// For a position `u` in sample units: the index of the first tap (`floor(u) + 1 -
    /// taps / 2`) and the fractional position `t = u - floor(u)` that [`Self::weights`] takes.
    #[inline]
    pub fn position(self, u: f64) -> (i64, f64) {
        let f = u.floor();
        (f as i64 + 1 - (self.taps() / 2) as i64, u - f)
    }

    /// The weights of the [`Self::taps`] samples around a fractional position `t` in
    /// `[0, 1)` (unused entries are 0).
    #[inline]
    pub fn weights(self, t: f64) -> [f64; Self::MAX_TAPS] {
        let mut w = [0.0; Self::MAX_TAPS];
        match self {
            Kernel::Keys => w[..4].copy_from_slice(&cubic_weights_f64(t)),
            Kernel::Lanczos3 => {
                for (k, wk) in w.iter_mut().enumerate() {
                    *wk = lanczos3(t - (k as f64 - 2.0));
                }
                let s: f64 = w.iter().sum();
                w.iter_mut().for_each(|v| *v /= s);
            }
        }
        w
    }

    /// The name used in settings and on the command line (`"keys"`, `"lanczos3"`).
    pub const fn name(self) -> &'static str {
        match self {
            Kernel::Keys => "keys",
            Kernel::Lanczos3 => "lanczos3",
        }
    }
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
