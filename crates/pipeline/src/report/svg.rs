//! Inline SVG line plots of the report (linear, log-y and log-log axes).

use std::fmt::Write as _;

use super::{Plot, esc, fmt_num};

/// Colours of plot series, in order.
const PALETTE: [&str; 10] = [
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf",
];

/// A plot as inline SVG (560 x 340): axes with ticks (decades on log axes), one polyline per
/// series, a legend.
pub(super) fn svg_plot(p: &Plot) -> String {
    const W: f64 = 560.0;
    const H: f64 = 340.0;
    let (l, r, t, b) = (64.0, 16.0, 28.0, 44.0);
    let tx = |v: f64| if p.log_x { v.log10() } else { v };
    let ty = |v: f64| if p.log_y { v.log10() } else { v };
    let ok = |x: f64, y: f64| {
        x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0)
    };
    let pts: Vec<Vec<(f64, f64)>> = p
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .filter(|(x, y)| ok(*x, *y))
                .map(|&(x, y)| (tx(x), ty(y)))
                .collect()
        })
        .collect();
    let all = pts.iter().flatten();
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let mut s = format!(
        "<svg class=\"plot\" xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\" \
         viewBox=\"0 0 {W} {H}\"><text x=\"{}\" y=\"16\" text-anchor=\"middle\" \
         font-weight=\"bold\">{}</text>",
        W / 2.0,
        esc(&p.title)
    );
    if !x0.is_finite() || !y0.is_finite() {
        s.push_str("<text x=\"20\" y=\"60\">no data</text></svg>\n");
        return s;
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    if y1 <= y0 {
        y1 = y0 + 1.0;
    }
    let pad = 0.04 * (y1 - y0);
    let (y0, y1) = (y0 - pad, y1 + pad);
    let sx = |x: f64| l + (x - x0) / (x1 - x0) * (W - l - r);
    let sy = |y: f64| H - b - (y - y0) / (y1 - y0) * (H - t - b);
    let _ = write!(
        s,
        "<rect x=\"{l}\" y=\"{t}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#888\"/>",
        W - l - r,
        H - t - b
    );
    for (v, log) in ticks(x0, x1, p.log_x) {
        let x = sx(v);
        let _ = write!(
            s,
            "<line x1=\"{x:.1}\" y1=\"{t}\" x2=\"{x:.1}\" y2=\"{}\" stroke=\"#eee\"/>\
             <text x=\"{x:.1}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            H - b,
            H - b + 14.0,
            tick_label(v, log)
        );
    }
    for (v, log) in ticks(y0, y1, p.log_y) {
        let y = sy(v);
        let _ = write!(
            s,
            "<line x1=\"{l}\" y1=\"{y:.1}\" x2=\"{}\" y2=\"{y:.1}\" stroke=\"#eee\"/>\
             <text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
            W - r,
            l - 4.0,
            y + 4.0,
            tick_label(v, log)
        );
    }
    let _ = write!(
        s,
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\
         <text x=\"14\" y=\"{}\" text-anchor=\"middle\" transform=\"rotate(-90 14 {})\">{}</text>",
        l + (W - l - r) / 2.0,
        H - 8.0,
        esc(&p.x_label),
        t + (H - t - b) / 2.0,
        t + (H - t - b) / 2.0,
        esc(&p.y_label)
    );
    let dash_of = |d: bool| if d { " stroke-dasharray=\"6 4\"" } else { "" };
    for (i, (series, pts)) in p.series.iter().zip(&pts).enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let dash = dash_of(series.dashed);
        if pts.len() == 1 {
            let _ = write!(
                s,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3\" fill=\"{colour}\"/>",
                sx(pts[0].0),
                sy(pts[0].1)
            );
        } else if pts.len() > 1 {
            let path: Vec<String> = pts
                .iter()
                .map(|&(x, y)| format!("{:.1},{:.1}", sx(x), sy(y)))
                .collect();
            let _ = write!(
                s,
                "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\"{dash} \
                 points=\"{}\"/>",
                path.join(" ")
            );
        }
    }
    // The legend last, on a translucent box over the lines.
    if !p.series.is_empty() {
        let _ = write!(
            s,
            "<rect x=\"{}\" y=\"{}\" width=\"152\" height=\"{}\" fill=\"#fff\" \
             fill-opacity=\"0.85\" stroke=\"#ddd\"/>",
            W - r - 156.0,
            t + 4.0,
            15.0 * p.series.len() as f64 + 4.0
        );
    }
    for (i, series) in p.series.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        let dash = dash_of(series.dashed);
        let ly = t + 14.0 + 15.0 * i as f64;
        let _ = write!(
            s,
            "<line x1=\"{}\" y1=\"{ly}\" x2=\"{}\" y2=\"{ly}\" stroke=\"{colour}\" \
             stroke-width=\"2\"{dash}/><text x=\"{}\" y=\"{}\">{}</text>",
            W - r - 150.0,
            W - r - 126.0,
            W - r - 120.0,
            ly + 4.0,
            esc(&series.label)
        );
    }
    s.push_str("</svg>\n");
    s
}

/// Tick positions in axis units (`log10` of the value on log axes): decades when a log axis
/// spans at least one, else about five round steps.
pub(super) fn ticks(lo: f64, hi: f64, log: bool) -> Vec<(f64, bool)> {
    if log && hi - lo >= 1.0 {
        let step = ((hi - lo) / 6.0).ceil().max(1.0);
        let mut v = (lo / step).ceil() * step;
        let mut out = Vec::new();
        while v <= hi + 1e-9 {
            out.push((v, true));
            v += step;
        }
        return out;
    }
    let raw = (hi - lo) / 5.0;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let mut v = (lo / step).ceil() * step;
    let mut out = Vec::new();
    while v <= hi + 1e-9 * step.abs() && out.len() < 20 {
        out.push((v, log));
        v += step;
    }
    out
}

fn tick_label(v: f64, log: bool) -> String {
    if log {
        let e = v.round();
        if (v - e).abs() < 1e-9 {
            return format!("1e{e}");
        }
        return fmt_num(10f64.powf(v));
    }
    fmt_num(v)
}
