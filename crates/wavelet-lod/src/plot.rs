//! The log-variance plot of section 5: measured `log2 Var` per level and band, the fitted lines
//! of equation (3) and the synthesised levels, as data and as an RGB8 raster (no file I/O).

use serde::{Deserialize, Serialize};

use crate::analysis::GlobalAnalysis;
use crate::dwt::Band;

/// One band's points and line.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlotSeries {
    /// The band.
    pub band: Band,
    /// Measured `(j, log2 Var)` of the input's levels.
    pub measured: Vec<(f64, f64)>,
    /// Whether each measured level took part in the fit.
    pub fitted: Vec<bool>,
    /// Synthesised levels `(j, log2 Var)`: measured on the refined terrain when it was given,
    /// otherwise the model value of equation (5).
    pub synthesized: Vec<(f64, f64)>,
    /// Fitted `gamma`.
    pub gamma: f64,
    /// Fitted `a`.
    pub a: f64,
}

/// Data of the log-variance plot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LogVariancePlot {
    /// One series per band, [`Band::ALL`] order.
    pub series: Vec<PlotSeries>,
    /// First synthesised level (`J`).
    pub first_new_level: i64,
    /// Number of synthesised levels.
    pub extra_levels: u32,
}

impl LogVariancePlot {
    /// Builds the plot from the input's analysis; `refined`, the analysis of the refined terrain
    /// (same wavelet), supplies measured variances of the synthesised levels.
    pub fn new(
        input: &GlobalAnalysis,
        extra_levels: u32,
        refined: Option<&GlobalAnalysis>,
    ) -> Self {
        let j0 = input.top_level;
        let floor = input.settings.variance_floor;
        let series = Band::ALL
            .iter()
            .map(|&b| {
                let f = input.fit(b);
                let measured: Vec<(f64, f64)> = input
                    .levels
                    .iter()
                    .filter(|l| l.count[b.index()] > 0)
                    .map(|l| (l.level as f64, l.variance[b.index()].max(floor).log2()))
                    .collect();
                let fitted = input
                    .levels
                    .iter()
                    .filter(|l| l.count[b.index()] > 0)
                    .map(|l| l.fitted)
                    .collect();
                let synthesized = (0..extra_levels as i64)
                    .map(|t| {
                        let j = j0 + t;
                        let measured = refined.and_then(|r| {
                            r.levels
                                .iter()
                                .find(|l| l.level == j)
                                .map(|l| l.variance[b.index()].max(floor).log2())
                        });
                        (j as f64, measured.unwrap_or(f.a - j as f64 * f.gamma))
                    })
                    .collect();
                PlotSeries {
                    band: b,
                    measured,
                    fitted,
                    synthesized,
                    gamma: f.gamma,
                    a: f.a,
                }
            })
            .collect();
        Self {
            series,
            first_new_level: j0,
            extra_levels,
        }
    }

    /// Renders the plot into an RGB8 buffer (`width * height * 3` bytes, row-major, top row
    /// first): axes with integer ticks and labels, the axis titles (level j, log2 Var) and a
    /// legend (H, V, D in their colours), filled squares for measured levels (grey
    /// outline when outside the fit), hollow squares for synthesised levels, the fitted lines
    /// (solid over the data, dashed over the new levels) and a dotted vertical line at the first
    /// synthesised level. Colours: H red, V green, D blue. Sizes are clamped into `64..=8192`.
    pub fn render_rgb(&self, width: usize, height: usize) -> Vec<u8> {
        let (w, h) = (width.clamp(64, 8192), height.clamp(64, 8192));
        let mut c = Canvas {
            w,
            h,
            px: vec![255u8; w * h * 3],
        };
        let pts = self
            .series
            .iter()
            .flat_map(|s| s.measured.iter().chain(&s.synthesized));
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in pts {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if x0 > x1 {
            (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
        }
        let (x0, x1) = (x0.floor() - 0.5, x1.ceil() + 0.5);
        let (y0, y1) = ((y0 - 1.0).floor(), (y1 + 1.0).ceil());
        let (l, r, t, b) = (34usize, w - 10, 10usize, h - 22);
        let sx = |x: f64| l as f64 + (x - x0) / (x1 - x0) * (r - l) as f64;
        let sy = |y: f64| b as f64 - (y - y0) / (y1 - y0) * (b - t) as f64;
        let black = [0, 0, 0];
        let grey = [150, 150, 150];
        c.line(l as f64, b as f64, r as f64, b as f64, black, 0);
        c.line(l as f64, t as f64, l as f64, b as f64, black, 0);
        // X ticks at every level.
        let mut j = x0.ceil() as i64;
        while (j as f64) <= x1 {
            let x = sx(j as f64);
            c.line(x, b as f64, x, b as f64 + 4.0, black, 0);
            c.text(&j.to_string(), x as i64 - 3, b as i64 + 7, black);
            j += 1;
        }
        // Y ticks every `step` units of log2 Var.
        let span = y1 - y0;
        let step = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0]
            .into_iter()
            .find(|s| span / s <= 10.0)
            .unwrap_or(100.0);
        let mut yv = (y0 / step).ceil() * step;
        while yv <= y1 {
            let y = sy(yv);
            c.line(l as f64 - 4.0, y, l as f64, y, black, 0);
            c.line(l as f64 + 1.0, y, r as f64, y, [225, 225, 225], 3);
            c.text(&format!("{}", yv as i64), 2, y as i64 - 2, black);
            yv += step;
        }
        // Axis titles and the legend (H red, V green, D blue), in the 3x5 font.
        let xlabel = "LEVEL J";
        let xl = (l + r) as i64 / 2 - (xlabel.len() as i64 * 4) / 2;
        c.text(xlabel, xl, b as i64 + 14, black);
        c.text("LOG2 VAR", l as i64 + 4, t as i64, black);
        let colours = [[200, 40, 40], [30, 140, 40], [40, 70, 210]];
        for (i, (name, col)) in ["H", "V", "D"].iter().zip(colours).enumerate() {
            c.text(name, r as i64 - 36 + 12 * i as i64, t as i64, col);
        }
        let xn = sx(self.first_new_level as f64 - 0.5);
        c.line(xn, t as f64, xn, b as f64, grey, 2);
        for (s, col) in self.series.iter().zip(colours) {
            let last_meas = s.measured.iter().map(|p| p.0).fold(x0 + 0.5, f64::max);
            let first_fit = s
                .measured
                .iter()
                .zip(&s.fitted)
                .filter(|(_, f)| **f)
                .map(|(p, _)| p.0)
                .fold(f64::MAX, f64::min)
                .min(last_meas);
            // The fitted line from `x0` to `x1` (dashed with `dash > 0`).
            let line = |x: f64| s.a - x * s.gamma;
            let mut segment = |x0: f64, x1: f64, dash| {
                c.line(sx(x0), sy(line(x0)), sx(x1), sy(line(x1)), col, dash);
            };
            segment(first_fit, last_meas, 0);
            let end = self.first_new_level as f64 + self.extra_levels as f64 - 1.0;
            if end > last_meas {
                segment(last_meas, end, 4);
            }
            for (p, f) in s.measured.iter().zip(&s.fitted) {
                let (x, y) = (sx(p.0) as i64, sy(p.1) as i64);
                c.rect(x - 3, y - 3, 7, if *f { col } else { grey }, true);
                if !*f {
                    c.rect(x - 2, y - 2, 5, col, true);
                }
            }
            for p in &s.synthesized {
                c.rect(sx(p.0) as i64 - 3, sy(p.1) as i64 - 3, 7, col, false);
            }
        }
        c.px
    }
}

struct Canvas {
    w: usize,
    h: usize,
    px: Vec<u8>,
}

impl Canvas {
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.w && (y as usize) < self.h {
            let i = (y as usize * self.w + x as usize) * 3;
            self.px[i..i + 3].copy_from_slice(&c);
        }
    }

    /// Line; `dash` > 0 draws `dash` pixels on, `dash` off.
    fn line(&mut self, x0: f64, y0: f64, x1: f64, y1: f64, c: [u8; 3], dash: usize) {
        if !(x0.is_finite() && y0.is_finite() && x1.is_finite() && y1.is_finite()) {
            return;
        }
        let n = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as usize).clamp(1, 20_000);
        for k in 0..=n {
            if dash > 0 && (k / dash) % 2 == 1 {
                continue;
            }
            let t = k as f64 / n as f64;
            self.put(
                (x0 + t * (x1 - x0)).round() as i64,
                (y0 + t * (y1 - y0)).round() as i64,
                c,
            );
        }
    }

    fn rect(&mut self, x: i64, y: i64, s: i64, c: [u8; 3], fill: bool) {
        for dy in 0..s {
            for dx in 0..s {
                if fill || dx == 0 || dy == 0 || dx == s - 1 || dy == s - 1 {
                    self.put(x + dx, y + dy, c);
                }
            }
        }
    }

    /// Text in a 3x5 pixel font (digits, '-', space and the capitals of the axis titles and
    /// legend).
    fn text(&mut self, s: &str, x: i64, y: i64, c: [u8; 3]) {
        for (i, ch) in s.chars().enumerate() {
            let glyph: [u8; 5] = match ch {
                '0' => [7, 5, 5, 5, 7],
                '1' => [2, 6, 2, 2, 7],
                '2' => [7, 1, 7, 4, 7],
                '3' => [7, 1, 7, 1, 7],
                '4' => [5, 5, 7, 1, 1],
                '5' => [7, 4, 7, 1, 7],
                '6' => [7, 4, 7, 5, 7],
                '7' => [7, 1, 1, 1, 1],
                '8' => [7, 5, 7, 5, 7],
                '9' => [7, 5, 7, 1, 7],
                '-' => [0, 0, 7, 0, 0],
                'A' => [2, 5, 7, 5, 5],
                'D' => [6, 5, 5, 5, 6],
                'E' => [7, 4, 7, 4, 7],
                'G' => [7, 4, 5, 5, 7],
                'H' => [5, 5, 7, 5, 5],
                'J' => [1, 1, 1, 5, 7],
                'L' => [4, 4, 4, 4, 7],
                'O' => [7, 5, 5, 5, 7],
                'R' => [6, 5, 6, 5, 5],
                'V' => [5, 5, 5, 5, 2],
                _ => [0; 5],
            };
            for (r, bits) in glyph.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        self.put(x + i as i64 * 4 + col, y + r as i64, c);
                    }
                }
            }
        }
    }
}

/// Renders the log-variance plot of `input` (and, when given, the measured synthesised levels
/// of `refined`) as an RGB8 buffer of `width * height * 3` bytes (sizes clamped into
/// `64..=8192`); see
/// [`LogVariancePlot::render_rgb`].
pub fn render_log_variance_plot(
    input: &GlobalAnalysis,
    extra_levels: u32,
    refined: Option<&GlobalAnalysis>,
    width: usize,
    height: usize,
) -> Vec<u8> {
    LogVariancePlot::new(input, extra_levels, refined).render_rgb(width, height)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(band: Band, a: f64) -> PlotSeries {
        PlotSeries {
            band,
            measured: (1..6).map(|j| (j as f64, a - 1.5 * j as f64)).collect(),
            fitted: vec![true; 5],
            synthesized: vec![],
            a,
            gamma: 1.5,
        }
    }

    /// The axis titles and the legend are drawn: black pixels in the row band under the x tick
    /// labels and at the top-left, the band colours at the top-right.
    #[test]
    fn the_plot_has_axis_titles_and_a_legend() {
        let plot = LogVariancePlot {
            series: vec![
                series(Band::ALL[0], 20.0),
                series(Band::ALL[1], 19.0),
                series(Band::ALL[2], 18.0),
            ],
            first_new_level: 6,
            extra_levels: 2,
        };
        let (w, h) = (320usize, 240usize);
        let rgb = plot.render_rgb(w, h);
        let px = |x: usize, y: usize| {
            [
                rgb[(y * w + x) * 3],
                rgb[(y * w + x) * 3 + 1],
                rgb[(y * w + x) * 3 + 2],
            ]
        };
        let count = |xs: std::ops::Range<usize>, ys: std::ops::Range<usize>, c: [u8; 3]| {
            ys.flat_map(|y| xs.clone().map(move |x| (x, y)))
                .filter(|&(x, y)| px(x, y) == c)
                .count()
        };
        let b = h - 22;
        assert!(count(100..220, b + 14..b + 19, [0, 0, 0]) > 20, "x title");
        assert!(count(38..80, 10..15, [0, 0, 0]) > 20, "y title");
        for (i, c) in [[200, 40, 40], [30, 140, 40], [40, 70, 210]]
            .into_iter()
            .enumerate()
        {
            let x0 = w - 10 - 36 + 12 * i;
            assert!(count(x0..x0 + 3, 10..15, c) >= 7, "legend {i}");
        }
    }
}
