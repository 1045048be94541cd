//! Report builder: collects per-stage images, tables and figures, then writes `summary.json`
//! (machine-readable, every figure) and `report.html` (one self-contained page that links the
//! images written beside it).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Serialize;
use serde_json::Value;

/// An image shown in the report (path relative to the output folder).
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Image {
    pub(crate) path: String,
    pub(crate) caption: String,
}

/// A table of strings with a header row.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Table {
    pub(crate) title: String,
    pub(crate) columns: Vec<String>,
    pub(crate) rows: Vec<Vec<String>>,
}

/// One stage's part of the report.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Section {
    /// Stage name.
    pub(crate) stage: String,
    /// Wall time of the stage.
    pub(crate) seconds: f64,
    /// Named figures (numbers, strings, small objects), in insertion order of their names.
    pub(crate) figures: BTreeMap<String, Value>,
    /// Tables.
    pub(crate) tables: Vec<Table>,
    /// Images shown side by side.
    pub(crate) images: Vec<Image>,
    /// Other files written (rasters, meshes), relative to the output folder.
    pub(crate) files: Vec<String>,
}

impl Section {
    /// An empty section for `stage`.
    pub(crate) fn new(stage: &str) -> Self {
        Self {
            stage: stage.to_string(),
            seconds: 0.0,
            figures: BTreeMap::new(),
            tables: Vec::new(),
            images: Vec::new(),
            files: Vec::new(),
        }
    }

    /// Records a figure (anything serialisable: a number, a string, a small struct).
    pub(crate) fn figure(&mut self, name: &str, value: impl Serialize) {
        let v = serde_json::to_value(value).unwrap_or(Value::Null);
        self.figures.insert(name.to_string(), v);
    }

    /// Adds a table; every row must have as many cells as `columns`.
    pub(crate) fn table(&mut self, title: &str, columns: &[&str], rows: Vec<Vec<String>>) {
        debug_assert!(rows.iter().all(|r| r.len() == columns.len()));
        self.tables.push(Table {
            title: title.to_string(),
            columns: columns.iter().map(|c| c.to_string()).collect(),
            rows,
        });
    }

    /// Adds an image (a file already written under the output folder).
    pub(crate) fn image(&mut self, path: &str, caption: &str) {
        self.images.push(Image {
            path: path.to_string(),
            caption: caption.to_string(),
        });
    }

    /// Lists a written file.
    pub(crate) fn file(&mut self, path: &str) {
        self.files.push(path.to_string());
    }
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Report {
    pub(crate) title: String,
    pub(crate) input: PathBuf,
    pub(crate) total_seconds: f64,
    pub(crate) peak_memory_bytes: Option<u64>,
    pub(crate) threads: usize,
    pub(crate) seed: u64,
    pub(crate) stages: Vec<Section>,
}

impl Report {
    /// An empty report about `input`.
    pub(crate) fn new(title: &str, input: &Path, seed: u64) -> Self {
        Self {
            title: title.to_string(),
            input: input.to_path_buf(),
            total_seconds: 0.0,
            peak_memory_bytes: None,
            threads: rayon::current_num_threads(),
            seed,
            stages: Vec::new(),
        }
    }

    /// Appends a finished stage.
    pub(crate) fn push(&mut self, section: Section) {
        self.stages.push(section);
    }

    /// Writes `summary.json` and `report.html` into `dir`.
    pub(crate) fn write(&self, dir: &Path) -> Result<()> {
        let json = serde_json::to_string_pretty(self)?;
        let p = dir.join("summary.json");
        std::fs::write(&p, json).with_context(|| format!("cannot write {}", p.display()))?;
        let p = dir.join("report.html");
        std::fs::write(&p, self.html()).with_context(|| format!("cannot write {}", p.display()))?;
        Ok(())
    }

    /// The HTML page.
    pub(crate) fn html(&self) -> String {
        let mut h = String::new();
        let _ = write!(
            h,
            "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>{t}</title>\n<style>\n\
             body{{font-family:sans-serif;margin:2em;max-width:1400px}}\n\
             table{{border-collapse:collapse;margin:0.5em 0 1em}}\n\
             td,th{{border:1px solid #bbb;padding:2px 8px;text-align:right}}\n\
             th{{background:#eee}} td:first-child{{text-align:left}}\n\
             .imgs{{display:flex;flex-wrap:wrap;gap:12px}} figure{{margin:0}}\n\
             figure img{{max-width:420px;image-rendering:pixelated}}\n\
             figcaption{{font-size:0.9em;color:#333}}\n</style></head><body>\n\
             <h1>{t}</h1>\n<p>input: <code>{i}</code>; {n} stages in {s:.2} s; {th} threads; seed {seed}{m}</p>\n",
            t = esc(&self.title),
            i = esc(&self.input.display().to_string()),
            n = self.stages.len(),
            s = self.total_seconds,
            th = self.threads,
            seed = self.seed,
            m = self
                .peak_memory_bytes
                .map(|b| format!("; peak memory {:.1} MiB", b as f64 / (1024.0 * 1024.0)))
                .unwrap_or_default(),
        );
        h.push_str("<h2>Stages</h2>\n<table><tr><th>stage</th><th>seconds</th></tr>\n");
        for s in &self.stages {
            let _ = writeln!(
                h,
                "<tr><td><a href=\"#{0}\">{0}</a></td><td>{1:.3}</td></tr>",
                esc(&s.stage),
                s.seconds
            );
        }
        h.push_str("</table>\n");
        for s in &self.stages {
            let _ = writeln!(h, "<h2 id=\"{0}\">{0}</h2>", esc(&s.stage));
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
            if !s.figures.is_empty() {
                h.push_str("<table><tr><th>figure</th><th>value</th></tr>\n");
                for (k, v) in &s.figures {
                    let _ = writeln!(
                        h,
                        "<tr><td>{}</td><td>{}</td></tr>",
                        esc(k),
                        esc(&fmt_value(v))
                    );
                }
                h.push_str("</table>\n");
            }
            for t in &s.tables {
                let _ = writeln!(h, "<h3>{}</h3>\n<table><tr>", esc(&t.title));
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
        h.push_str("</body></html>\n");
        h
    }
}

/// Formats a figure for the HTML table: numbers with 4 significant digits after the point.
fn fmt_value(v: &Value) -> String {
    match v {
        Value::Number(n) => match (n.as_i64(), n.as_f64()) {
            (Some(i), _) => i.to_string(),
            (None, Some(f)) => format!("{f:.4}"),
            _ => n.to_string(),
        },
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Minimal HTML escaping.
pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn html_contains_figures_tables_and_images() {
        let mut r = Report::new("t", Path::new("in.tif"), 7);
        let mut s = Section::new("load");
        s.figure("voids", 3);
        s.figure("rmse_m", 0.25);
        s.table(
            "round trips",
            &["format", "max-abs"],
            vec![vec!["exr".into(), "0".into()]],
        );
        s.image("dem.png", "a <b>");
        r.push(s);
        let h = r.html();
        assert!(h.contains("<td>voids</td><td>3</td>"));
        assert!(h.contains("<td>rmse_m</td><td>0.2500</td>"));
        assert!(h.contains("<td>exr</td><td>0</td>"));
        assert!(h.contains("src=\"dem.png\""));
        assert!(h.contains("a &lt;b&gt;"));
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["stages"][0]["figures"]["voids"], 3);
    }
}
