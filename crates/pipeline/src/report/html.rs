//! `report.html`: one self-contained page (inline CSS and SVG plots, images linked beside it).

use std::fmt::Write as _;

use serde_json::Value;

use super::svg::svg_plot;
use super::{Report, Section, fmt_mib};

impl Report {
    /// The HTML page: header, table of contents, summary table (per-stage seconds, peak
    /// memory and headline figures), the overview, then one section per stage.
    pub fn html(&self) -> String {
        let mut h = String::new();
        let _ = write!(
            h,
            "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>{t}</title>\n<style>\n{css}</style></head><body>\n\
             <h1>{t}</h1>\n<p>input: <code>{i}</code>; {n} stages in {s:.2} s; {th} threads; seed {seed}{m}</p>\n",
            t = esc(&self.title),
            css = CSS,
            i = esc(&self.input.display().to_string()),
            n = self.stages.len(),
            s = self.total_seconds,
            th = self.threads,
            seed = self.seed,
            m = self
                .peak_memory_bytes
                .map(|b| format!("; peak memory {}", fmt_mib(b)))
                .unwrap_or_default(),
        );
        // Table of contents.
        h.push_str("<nav><h2>Contents</h2><ol>\n<li><a href=\"#summary\">Summary</a></li>\n");
        if self.overview.is_some() {
            h.push_str("<li><a href=\"#overview\">Input and final terrain</a></li>\n");
        }
        for s in &self.stages {
            let _ = writeln!(h, "<li><a href=\"#stage-{0}\">{0}</a></li>", esc(&s.stage));
        }
        h.push_str("</ol></nav>\n");
        // Summary table.
        h.push_str(
            "<h2 id=\"summary\">Summary</h2>\n<table class=\"summary\"><tr><th>stage</th>\
             <th>seconds</th><th>share</th><th>peak memory (rise)</th><th>key figures</th></tr>\n",
        );
        for s in &self.stages {
            let share = if self.total_seconds > 0.0 {
                100.0 * s.seconds / self.total_seconds
            } else {
                0.0
            };
            let keys: Vec<String> = s
                .headlines
                .iter()
                .filter_map(|k| {
                    s.figures
                        .get(k)
                        .map(|v| format!("{} = {}", esc(k), esc(&fmt_value(v))))
                })
                .collect();
            let _ = writeln!(
                h,
                "<tr><td><a href=\"#stage-{0}\">{0}</a></td><td>{1:.2}</td><td>{2:.0} %</td>\
                 <td>{3}</td><td class=\"keys\">{4}</td></tr>",
                esc(&s.stage),
                s.seconds,
                share,
                match (s.peak_memory_bytes, s.peak_rise_bytes) {
                    (Some(p), Some(r)) => format!("{} (+{})", fmt_mib(p), fmt_mib(r)),
                    (Some(p), None) => fmt_mib(p),
                    _ => "-".into(),
                },
                keys.join("<br>")
            );
        }
        let _ = writeln!(
            h,
            "<tr><th>total</th><th>{:.2}</th><th></th><th>{}</th><th></th></tr>\n</table>",
            self.total_seconds,
            self.peak_memory_bytes
                .map(fmt_mib)
                .unwrap_or_else(|| "-".into())
        );
        if let Some(o) = &self.overview {
            h.push_str("<h2 id=\"overview\">Input and final terrain</h2>\n");
            section_body(&mut h, o);
        }
        for s in &self.stages {
            let _ = writeln!(
                h,
                "<h2 id=\"stage-{0}\">{0} <small>({1:.2} s{2})</small></h2>",
                esc(&s.stage),
                s.seconds,
                s.peak_memory_bytes
                    .map(|b| format!(", peak {}", fmt_mib(b)))
                    .unwrap_or_default()
            );
            section_body(&mut h, s);
        }
        h.push_str("</body></html>\n");
        h
    }
}

const CSS: &str = "body{font-family:sans-serif;margin:2em;max-width:1400px;color:#222}\n\
table{border-collapse:collapse;margin:0.5em 0 0.3em}\n\
td,th{border:1px solid #bbb;padding:2px 8px;text-align:right;vertical-align:top}\n\
th{background:#eee} td:first-child{text-align:left}\n\
td.keys{text-align:left;font-size:0.9em}\n\
caption,.cap{caption-side:bottom;font-size:0.9em;color:#555;text-align:left;padding:2px 0 1em}\n\
.imgs{display:flex;flex-wrap:wrap;gap:12px;margin:0.5em 0} figure{margin:0}\n\
figure img{max-width:420px;image-rendering:pixelated}\n\
.pair{display:grid;grid-template-columns:repeat(2,480px);gap:12px;margin:0.5em 0}\n\
.pair img{width:480px;image-rendering:auto}\n\
figcaption{font-size:0.9em;color:#333}\n\
svg.plot{background:#fff;border:1px solid #ddd;margin:0.5em 12px 0.5em 0}\n\
svg.plot text{font:11px sans-serif}\n\
nav ol{columns:3}\n";

/// The body of one section (notes, pairs, images, plots, figures, tables, files).
fn section_body(h: &mut String, s: &Section) {
    for n in &s.notes {
        let _ = writeln!(h, "<p>{}</p>", esc(n));
    }
    for p in &s.pairs {
        h.push_str("<div class=\"pair\">");
        for im in [&p.left, &p.right] {
            let _ = write!(
                h,
                "<figure><img src=\"{}\" alt=\"{c}\"><figcaption>{c}</figcaption></figure>",
                esc(&im.path),
                c = esc(&im.caption)
            );
        }
        let _ = writeln!(h, "</div>\n<p class=\"cap\">{}</p>", esc(&p.caption));
    }
    if !s.images.is_empty() {
        h.push_str("<div class=\"imgs\">\n");
        for im in &s.images {
            let _ = writeln!(
                h,
                "<figure><img src=\"{}\" alt=\"{c}\"><figcaption>{c}</figcaption></figure>",
                esc(&im.path),
                c = esc(&im.caption)
            );
        }
        h.push_str("</div>\n");
    }
    if !s.plots.is_empty() {
        h.push_str("<div class=\"imgs\">\n");
        for p in &s.plots {
            h.push_str(&svg_plot(p));
        }
        h.push_str("</div>\n");
    }
    if !s.figures.is_empty() {
        h.push_str("<table><tr><th>figure</th><th>value</th></tr>\n");
        let mut rows = Vec::new();
        for (k, v) in &s.figures {
            flatten(k, v, &mut rows);
        }
        for (k, v) in rows {
            let _ = writeln!(h, "<tr><td>{}</td><td>{}</td></tr>", esc(&k), esc(&v));
        }
        h.push_str("</table>\n");
    }
    for t in &s.tables {
        let _ = writeln!(h, "<h3>{}</h3>\n<table>", esc(&t.title));
        if !t.caption.is_empty() {
            let _ = writeln!(h, "<caption>{}</caption>", esc(&t.caption));
        }
        h.push_str("<tr>");
        for c in &t.columns {
            let _ = write!(h, "<th>{}</th>", esc(c));
        }
        h.push_str("</tr>\n");
        for r in &t.rows {
            h.push_str("<tr>");
            for c in r {
                let _ = write!(h, "<td>{}</td>", esc(c));
            }
            h.push_str("</tr>\n");
        }
        h.push_str("</table>\n");
    }
    if !s.files.is_empty() {
        h.push_str("<p>files: ");
        let links: Vec<String> = s
            .files
            .iter()
            .map(|f| format!("<a href=\"{0}\">{0}</a>", esc(f)))
            .collect();
        h.push_str(&links.join(", "));
        h.push_str("</p>\n");
    }
}

/// The rows of a figure: an object becomes one row per field (`sizes.arches.count`), nested
/// to any depth, so a stage's structured figures read as a table and not as one cell of JSON;
/// a list of numbers or strings is one row (at most 12 items shown, then the count).
fn flatten(key: &str, v: &Value, rows: &mut Vec<(String, String)>) {
    match v {
        Value::Object(m) if !m.is_empty() => {
            for (k, x) in m {
                flatten(&format!("{key}.{k}"), x, rows);
            }
        }
        Value::Array(a) if a.iter().all(|x| !x.is_object() && !x.is_array()) => {
            let shown: Vec<String> = a.iter().take(12).map(fmt_value).collect();
            let more = if a.len() > 12 {
                format!(", ... ({} items)", a.len())
            } else {
                String::new()
            };
            rows.push((key.to_string(), format!("[{}{more}]", shown.join(", "))));
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate().take(12) {
                flatten(&format!("{key}[{i}]"), x, rows);
            }
            if a.len() > 12 {
                rows.push((key.to_string(), format!("... ({} items)", a.len())));
            }
        }
        _ => rows.push((key.to_string(), fmt_value(v))),
    }
}

/// Formats a figure for the HTML table: numbers with 4 significant digits after the point.
fn fmt_value(v: &Value) -> String {
    match v {
        Value::Number(n) => match (n.as_i64(), n.as_f64()) {
            (Some(i), _) => i.to_string(),
            (None, Some(f)) if f == 0.0 || (1e-3..1e7).contains(&f.abs()) => format!("{f:.4}"),
            (None, Some(f)) => format!("{f:.4e}"),
            _ => n.to_string(),
        },
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Minimal HTML escaping.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
