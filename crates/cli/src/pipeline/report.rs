//! Report builder: collects per-stage images, tables and figures, then writes `summary.json`
//! (machine-readable, every figure) and `report.html` (one self-contained page that links the
//! images written beside it).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use relief_heightfield::terrain::hillshade;
use relief_heightfield::{Heightfield, metrics};
use serde::Serialize;
use serde_json::Value;

use super::{PipelineConfig, StageCx, State};

/// An image shown in the report (path relative to the output folder).
#[derive(Debug, Clone, Serialize)]
pub struct Image {
    pub path: String,
    pub caption: String,
}

/// Two images shown side by side at the same display width (before/after, input/output):
/// grids of different sizes (an x4 amplification) cover the same extent on the page.
#[derive(Debug, Clone, Serialize)]
pub struct Pair {
    pub left: Image,
    pub right: Image,
    pub caption: String,
}

/// A table of strings with a header row.
#[derive(Debug, Clone, Serialize)]
pub struct Table {
    pub title: String,
    /// One sentence under the table saying what it shows (may be empty).
    pub caption: String,
    pub columns: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

/// One line of a [`Plot`].
#[derive(Debug, Clone, Serialize)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// Drawn dashed (fits, reference lines).
    pub dashed: bool,
}

/// A line plot drawn as inline SVG in `report.html`; its points are in `summary.json`.
///
/// ```ignore
/// cx.section.plot(
///     Plot::new("log-variance per level", "level", "log2 variance")
///         .line("input", levels_in)
///         .dashed("fit", fit_points),
/// );
/// ```
#[derive(Debug, Clone, Serialize)]
pub struct Plot {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
    pub series: Vec<Series>,
}

impl Plot {
    /// An empty plot with linear axes.
    pub fn new(title: &str, x_label: &str, y_label: &str) -> Self {
        Self {
            title: title.to_string(),
            x_label: x_label.to_string(),
            y_label: y_label.to_string(),
            log_x: false,
            log_y: false,
            series: Vec::new(),
        }
    }

    /// Both axes logarithmic (base 10; non-positive values are skipped).
    pub fn log_log(mut self) -> Self {
        self.log_x = true;
        self.log_y = true;
        self
    }

    /// Logarithmic y axis only.
    #[allow(dead_code)] // for the method stages
    pub fn log_y(mut self) -> Self {
        self.log_y = true;
        self
    }

    /// Adds a solid line.
    pub fn line(mut self, label: &str, points: impl IntoIterator<Item = (f64, f64)>) -> Self {
        self.series.push(Series {
            label: label.to_string(),
            points: points.into_iter().collect(),
            dashed: false,
        });
        self
    }

    /// Adds a dashed line (a fit, a target, a reference slope).
    #[allow(dead_code)] // for the method stages
    pub fn dashed(mut self, label: &str, points: impl IntoIterator<Item = (f64, f64)>) -> Self {
        self.series.push(Series {
            label: label.to_string(),
            points: points.into_iter().collect(),
            dashed: true,
        });
        self
    }
}

/// One stage's part of the report.
#[derive(Debug, Clone, Serialize)]
pub struct Section {
    /// Stage name.
    pub stage: String,
    /// Wall time of the stage.
    pub seconds: f64,
    /// Peak resident memory while the stage ran (Linux `VmHWM`, reset between stages), bytes.
    pub peak_memory_bytes: Option<u64>,
    /// How far the peak rose above the resident memory when the stage started (memory the
    /// stage itself needed at its peak), bytes.
    pub peak_rise_bytes: Option<u64>,
    /// Named figures (numbers, strings, small objects), in insertion order of their names.
    pub figures: BTreeMap<String, Value>,
    /// Names of the figures also shown in the summary table at the top of the report.
    pub headlines: Vec<String>,
    /// Paragraphs of text (what the stage did, with which parameters).
    pub notes: Vec<String>,
    /// Side-by-side image pairs.
    pub pairs: Vec<Pair>,
    /// Tables.
    pub tables: Vec<Table>,
    /// Line plots.
    pub plots: Vec<Plot>,
    /// Images shown side by side.
    pub images: Vec<Image>,
    /// Other files written (rasters, meshes), relative to the output folder.
    pub files: Vec<String>,
}

impl Section {
    /// An empty section for `stage`.
    pub fn new(stage: &str) -> Self {
        Self {
            stage: stage.to_string(),
            seconds: 0.0,
            peak_memory_bytes: None,
            peak_rise_bytes: None,
            figures: BTreeMap::new(),
            headlines: Vec::new(),
            notes: Vec::new(),
            pairs: Vec::new(),
            tables: Vec::new(),
            plots: Vec::new(),
            images: Vec::new(),
            files: Vec::new(),
        }
    }

    /// Records a figure (anything serialisable: a number, a string, a small struct).
    pub fn figure(&mut self, name: &str, value: impl Serialize) {
        let v = serde_json::to_value(value).unwrap_or(Value::Null);
        self.figures.insert(name.to_string(), v);
    }

    /// Records a figure and also shows it in the summary table at the top of the report (use
    /// it for the two or three numbers that say whether the stage worked: PSNR, rho, ...).
    #[allow(dead_code)] // for the method stages
    pub fn headline(&mut self, name: &str, value: impl Serialize) {
        self.figure(name, value);
        if !self.headlines.iter().any(|h| h == name) {
            self.headlines.push(name.to_string());
        }
    }

    /// Adds a paragraph of text.
    #[allow(dead_code)] // for the method stages
    pub fn note(&mut self, text: &str) {
        self.notes.push(text.to_string());
    }

    /// Adds a table; every row must have as many cells as `columns`.
    pub fn table(&mut self, title: &str, columns: &[&str], rows: Vec<Vec<String>>) {
        self.table_captioned(title, "", columns, rows);
    }

    /// Adds a table with a caption under it. Rows should have as many cells as `columns`;
    /// a mismatch never panics: short rows and the header are padded with empty cells.
    pub fn table_captioned(
        &mut self,
        title: &str,
        caption: &str,
        columns: &[&str],
        mut rows: Vec<Vec<String>>,
    ) {
        let width = rows.iter().map(Vec::len).fold(columns.len(), usize::max);
        let mut columns: Vec<String> = columns.iter().map(|c| c.to_string()).collect();
        columns.resize(width, String::new());
        for r in &mut rows {
            r.resize(width, String::new());
        }
        self.tables.push(Table {
            title: title.to_string(),
            caption: caption.to_string(),
            columns,
            rows,
        });
    }

    /// Adds a table of numbers: one row per `(name, values)`, values formatted with 4
    /// significant digits (NaN shows as `-`). `columns[0]` heads the row names.
    pub fn numbers(
        &mut self,
        title: &str,
        caption: &str,
        columns: &[&str],
        rows: &[(&str, Vec<f64>)],
    ) {
        let rows = rows
            .iter()
            .map(|(name, vals)| {
                std::iter::once(name.to_string())
                    .chain(vals.iter().map(|v| fmt_num(*v)))
                    .collect()
            })
            .collect();
        self.table_captioned(title, caption, columns, rows);
    }

    /// Adds an image (a file already written under the output folder).
    pub fn image(&mut self, path: &str, caption: &str) {
        self.images.push(Image {
            path: path.to_string(),
            caption: caption.to_string(),
        });
    }

    /// Shows two images (files already written under the output folder) side by side at the
    /// same display width, each with its caption, and `caption` under both.
    pub fn pair(&mut self, left: (&str, &str), right: (&str, &str), caption: &str) {
        let im = |(path, caption): (&str, &str)| Image {
            path: path.to_string(),
            caption: caption.to_string(),
        };
        self.pairs.push(Pair {
            left: im(left),
            right: im(right),
            caption: caption.to_string(),
        });
    }

    /// Adds a line plot (see [`Plot`]).
    pub fn plot(&mut self, plot: Plot) {
        self.plots.push(plot);
    }

    /// Lists a written file.
    pub fn file(&mut self, path: &str) {
        self.files.push(path.to_string());
    }
}

/// Largest side of a hillshade image written by [`StageCx::save_hillshade`].
const MAX_HILLSHADE_SIDE: usize = 4096;

/// Report helpers that write image files (hillshades, spectra, renders) from a stage.
impl StageCx<'_> {
    /// Writes a grey hillshade PNG `<out>/<name>.png` (light from the north-west, 45 degrees,
    /// slopes in metres so grids of any cell size shade alike; voids black) and returns its
    /// path relative to the output folder, or `None` when previews are off (golden run). Grids
    /// larger than 4096 cells on a side are box-averaged down to at most that first.
    pub fn save_hillshade(&mut self, name: &str, hf: &Heightfield) -> Result<Option<String>> {
        if !self.config.previews {
            return Ok(None);
        }
        let rel = format!("{name}.png");
        let path = self.config.out_dir.join(&rel);
        // Very large grids (a 16384^2 refinement) are box-averaged to at most
        // MAX_HILLSHADE_SIDE per side first: the page shows them at 480 px anyway.
        let k = hf.width().max(hf.height()).div_ceil(MAX_HILLSHADE_SIDE);
        let small;
        let hf = if k > 1 {
            small = hf.downsample_box(k)?;
            &small
        } else {
            hf
        };
        let shade = hillshade(hf, 315.0, 45.0, 1.0);
        let grey: Vec<u8> = shade
            .iter()
            .map(|s| (s * 255.0).round().clamp(0.0, 255.0) as u8)
            .collect();
        relief_io::write_gray_png(&path, hf.width(), hf.height(), &grey)
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(Some(rel))
    }

    /// Writes hillshades `<name>_before.png` and `<name>_after.png` and shows them side by
    /// side (same display width, so an upsampled output covers the same extent as its
    /// input). Does nothing when previews are off.
    pub fn before_after(
        &mut self,
        name: &str,
        caption: &str,
        before: &Heightfield,
        after: &Heightfield,
    ) -> Result<()> {
        let b = self.save_hillshade(&format!("{name}_before"), before)?;
        let a = self.save_hillshade(&format!("{name}_after"), after)?;
        if let (Some(b), Some(a)) = (b, a) {
            let lb = format!("before ({} x {})", before.width(), before.height());
            let la = format!("after ({} x {})", after.width(), after.height());
            self.section.pair((&b, &lb), (&a, &la), caption);
        }
        Ok(())
    }

    /// Adds a log-log plot of the radially averaged power spectra (cycles per metre) of the
    /// given grids, and records each one's spectral slope over the band from 4 cycles per
    /// grid to a quarter of its Nyquist frequency as the figure `spectral_slope_<label>`.
    /// Grids with voids or smaller than 8 x 8 are skipped.
    pub fn spectrum_plot(&mut self, title: &str, grids: &[(&str, &Heightfield)]) {
        let mut plot = Plot::new(title, "frequency (cycles / m)", "power").log_log();
        for (label, hf) in grids {
            let Ok(spec) = metrics::radial_power_spectrum(hf) else {
                continue;
            };
            let (cx, cy) = hf.cell_size();
            let extent = (hf.width() as f64 * cx).max(hf.height() as f64 * cy);
            let f_hi = 0.25 * 0.5 / cx.max(cy);
            if let Ok(slope) = metrics::spectral_slope(&spec, 4.0 / extent, f_hi) {
                self.section
                    .figure(&format!("spectral_slope_{label}"), slope);
            }
            plot = plot.line(label, spec);
        }
        if !plot.series.is_empty() {
            self.section.plot(plot);
        }
    }

    /// Writes an 8-bit RGB image (a render, a colour map) `<out>/<name>.png` from row-major
    /// `rgb` and shows it with `caption`. Does nothing when previews are off.
    #[allow(dead_code)] // for the method stages
    pub fn save_rgb(
        &mut self,
        name: &str,
        caption: &str,
        width: usize,
        height: usize,
        rgb: &[u8],
    ) -> Result<()> {
        if !self.config.previews {
            return Ok(());
        }
        let rel = format!("{name}.png");
        let path = self.config.out_dir.join(&rel);
        relief_io::write_rgb_png(&path, width, height, rgb)
            .with_context(|| format!("cannot write {}", path.display()))?;
        self.section.image(&rel, caption);
        Ok(())
    }
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    pub title: String,
    pub input: PathBuf,
    pub total_seconds: f64,
    /// Peak resident memory of the whole run (the largest of the stages' peaks), bytes.
    pub peak_memory_bytes: Option<u64>,
    pub threads: usize,
    pub seed: u64,
    /// Input versus final terrain (hillshades, spectra, statistics), shown first.
    pub overview: Option<Section>,
    pub stages: Vec<Section>,
    /// Resident memory when the current stage started (after the high-water mark was reset).
    #[serde(skip)]
    stage_start_rss: Option<u64>,
}

impl Report {
    /// An empty report about `input`.
    pub fn new(title: &str, input: &Path, seed: u64) -> Self {
        reset_peak_memory();
        Self {
            stage_start_rss: resident_memory_bytes(),
            title: title.to_string(),
            input: input.to_path_buf(),
            total_seconds: 0.0,
            peak_memory_bytes: None,
            threads: rayon::current_num_threads(),
            seed,
            overview: None,
            stages: Vec::new(),
        }
    }

    /// Appends a finished stage, recording its peak memory (the process's high-water mark
    /// since the previous stage finished; the mark is then reset for the next stage).
    pub fn push(&mut self, mut section: Section) {
        if section.peak_memory_bytes.is_none() {
            section.peak_memory_bytes = peak_memory_bytes();
            section.peak_rise_bytes = section
                .peak_memory_bytes
                .zip(self.stage_start_rss)
                .map(|(p, s)| p.saturating_sub(s));
        }
        reset_peak_memory();
        self.stage_start_rss = resident_memory_bytes();
        self.stages.push(section);
    }

    /// Builds the overview section: the loaded terrain (`state.source`) against the final one
    /// (hillshades side by side, spectra, a statistics table). Call after the last stage.
    pub fn overview(&mut self, config: &PipelineConfig, state: &mut State) -> Result<()> {
        let (Some(src), Ok(fin)) = (state.source.clone(), state.terrain().cloned()) else {
            return Ok(());
        };
        let mut section = Section::new("overview");
        {
            let mut cx = StageCx {
                config,
                state,
                section: &mut section,
            };
            cx.before_after(
                "overview",
                "input DEM (left) and the pipeline's final terrain (right), hillshaded",
                &src,
                &fin,
            )?;
            cx.spectrum_plot(
                "radially averaged power spectrum: input and final terrain",
                &[("input", &src), ("final", &fin)],
            );
        }
        let col = |hf: &Heightfield| -> Vec<f64> {
            let (cx, cy) = hf.cell_size();
            let st = metrics::stats(hf).ok();
            vec![
                hf.width() as f64,
                hf.height() as f64,
                cx,
                cy,
                st.as_ref().map_or(f64::NAN, |s| s.min),
                st.as_ref().map_or(f64::NAN, |s| s.max),
                st.as_ref().map_or(f64::NAN, |s| s.mean),
                st.as_ref().map_or(f64::NAN, |s| s.std),
                hf.void_count() as f64,
            ]
        };
        let (a, b) = (col(&src), col(&fin));
        let names = [
            "width", "height", "cell_x_m", "cell_y_m", "min_m", "max_m", "mean_m", "std_m", "voids",
        ];
        let rows: Vec<(&str, Vec<f64>)> = names
            .iter()
            .enumerate()
            .map(|(i, n)| (*n, vec![a[i], b[i]]))
            .collect();
        section.numbers(
            "input and final terrain",
            "statistics of the loaded DEM and of the terrain the last stage produced",
            &["", "input", "final"],
            &rows,
        );
        section.figure(
            "slope_histogram_distance_deg",
            metrics::slope_histogram_distance(&src, &fin),
        );
        self.overview = Some(section);
        Ok(())
    }

    /// Writes `summary.json` and `report.html` into `dir`.
    pub fn write(&mut self, dir: &Path) -> Result<()> {
        let stage_peak = self.stages.iter().filter_map(|s| s.peak_memory_bytes).max();
        self.peak_memory_bytes = match (self.peak_memory_bytes, stage_peak) {
            (Some(a), Some(b)) => Some(a.max(b)),
            (a, b) => a.or(b),
        };
        let json = serde_json::to_string_pretty(&*self)?;
        let p = dir.join("summary.json");
        std::fs::write(&p, json).with_context(|| format!("cannot write {}", p.display()))?;
        let p = dir.join("report.html");
        std::fs::write(&p, self.html()).with_context(|| format!("cannot write {}", p.display()))?;
        Ok(())
    }

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

/// Colours of plot series, in order.
const PALETTE: [&str; 10] = [
    "#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf",
];

/// A plot as inline SVG (560 x 340): axes with ticks (decades on log axes), one polyline per
/// series, a legend.
fn svg_plot(p: &Plot) -> String {
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
fn ticks(lo: f64, hi: f64, log: bool) -> Vec<(f64, bool)> {
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

/// A number with 4 significant digits (integers as they are; NaN as `-`).
pub fn fmt_num(v: f64) -> String {
    if v.is_nan() {
        return "-".to_string();
    }
    if v.is_infinite() {
        return if v > 0.0 { "inf" } else { "-inf" }.to_string();
    }
    if v == v.trunc() && v.abs() < 1e9 {
        return format!("{}", v as i64);
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        return format!("{v:.3e}");
    }
    let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
    format!("{v:.decimals$}")
}

fn fmt_mib(b: u64) -> String {
    format!("{:.1} MiB", b as f64 / (1024.0 * 1024.0))
}

/// Peak resident memory of this process since the last reset (Linux `VmHWM`), when known.
pub fn peak_memory_bytes() -> Option<u64> {
    proc_status_bytes("VmHWM:")
}

/// Resident memory of this process now (Linux `VmRSS`), when known.
fn resident_memory_bytes() -> Option<u64> {
    proc_status_bytes("VmRSS:")
}

fn proc_status_bytes(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Resets the `VmHWM` high-water mark to the current resident size (Linux >= 4.0: writing 5
/// to `/proc/self/clear_refs`); silently does nothing where that is not possible.
fn reset_peak_memory() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn html_contains_figures_tables_and_images() {
        let mut r = Report::new("t", Path::new("in.tif"), 7);
        let mut s = Section::new("load");
        s.figure("voids", 3);
        s.figure("rmse_m", 0.25);
        s.figure("residual", 1.5e-7);
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
        assert!(h.contains("<td>residual</td><td>1.5000e-7</td>"), "{h}");
        assert!(h.contains("<td>exr</td><td>0</td>"));
        assert!(h.contains("src=\"dem.png\""));
        assert!(h.contains("a &lt;b&gt;"));
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["stages"][0]["figures"]["voids"], 3);
    }

    #[test]
    fn helpers_render_toc_summary_pairs_plots_and_captions() {
        let mut r = Report::new("t", Path::new("in.tif"), 7);
        r.total_seconds = 4.0;
        let mut s = Section::new("sparse_amplify");
        s.seconds = 3.0;
        s.peak_memory_bytes = Some(3 * 1024 * 1024);
        s.peak_rise_bytes = Some(1024 * 1024);
        s.headline("psnr_db", 41.25);
        s.headline("psnr_db", 41.25);
        s.figure("not_headline", 1);
        s.note("x4 amplification & more");
        s.pair(("a.png", "before"), ("b.png", "after"), "hillshades");
        s.numbers(
            "quality",
            "lower is better",
            &["metric", "ours", "peer"],
            &[
                ("rmse_m", vec![0.123456, f64::NAN]),
                ("n", vec![12.0, 3e-5]),
            ],
        );
        s.plot(
            Plot::new("spectrum", "f", "power")
                .log_log()
                .line("in", [(0.01, 1e4), (0.1, 10.0), (0.0, 5.0)])
                .dashed("fit", [(0.01, 2e4), (0.1, 20.0)]),
        );
        r.push(s);
        let h = r.html();
        assert_eq!(r.stages[0].headlines, ["psnr_db"]);
        // Contents and summary link to the section; the summary shows headlines only.
        assert!(h.contains("<li><a href=\"#stage-sparse_amplify\">sparse_amplify</a></li>"));
        assert!(h.contains("<h2 id=\"stage-sparse_amplify\">"));
        assert!(
            h.contains("<td>3.00</td><td>75 %</td><td>3.0 MiB (+1.0 MiB)</td>"),
            "{h}"
        );
        assert!(
            h.contains("<td class=\"keys\">psnr_db = 41.2500</td>"),
            "{h}"
        );
        assert!(!h.contains("keys\">not_headline"));
        assert!(h.contains("<p>x4 amplification &amp; more</p>"));
        assert!(h.contains("<div class=\"pair\"><figure><img src=\"a.png\""));
        assert!(h.contains("<caption>lower is better</caption>"));
        assert!(
            h.contains("<td>rmse_m</td><td>0.1235</td><td>-</td>"),
            "{h}"
        );
        assert!(h.contains("<td>12</td><td>3.000e-5</td>"), "{h}");
        // The plot: two polylines (the zero-frequency point is dropped on the log axis),
        // one dashed, decade ticks.
        assert_eq!(h.matches("<polyline").count(), 2);
        assert_eq!(h.matches("stroke-dasharray").count(), 2); // line + legend swatch
        assert!(h.contains(">1e-2<") && h.contains(">1e4<"), "{h}");
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(
            json["stages"][0]["plots"][0]["series"][0]["points"][1][1],
            10.0
        );
        assert_eq!(json["stages"][0]["tables"][0]["caption"], "lower is better");
    }

    #[test]
    fn mismatched_tables_are_padded_not_fatal() {
        let mut s = Section::new("x");
        s.numbers("t", "", &["m", "a"], &[("r", vec![1.0, 2.0, 3.0])]);
        s.table("u", &["a", "b", "c"], vec![vec!["1".into()]]);
        assert_eq!(s.tables[0].columns, ["m", "a", "", ""]);
        assert_eq!(s.tables[0].rows[0], ["r", "1", "2", "3"]);
        assert_eq!(s.tables[1].rows[0], ["1", "", ""]);
    }

    #[test]
    fn huge_hillshades_are_reduced_and_pairs_recorded() {
        let tmp = tempfile::tempdir().unwrap();
        let config = PipelineConfig {
            out_dir: tmp.path().to_path_buf(),
            verbose: false,
            ..PipelineConfig::full(&crate::test_root())
        };
        let mut state = State::default();
        let mut section = Section::new("x");
        let mut cx = StageCx {
            config: &config,
            state: &mut state,
            section: &mut section,
        };
        let big = Heightfield::from_fn(4100, 6, 1.0, 1.0, |x, y| (x * y) as f32 * 0.01);
        let small = big.crop(0, 0, 64, 6).unwrap();
        cx.before_after("t", "c", &small, &big).unwrap();
        let png = std::fs::read(tmp.path().join("t_after.png")).unwrap();
        // PNG IHDR: width and height as big-endian u32 at bytes 16..24.
        let w = u32::from_be_bytes(png[16..20].try_into().unwrap());
        assert_eq!(w, 2050, "4100 wide, box-averaged by 2");
        assert_eq!(section.pairs.len(), 1);
        assert_eq!(section.pairs[0].right.caption, "after (4100 x 6)");
    }

    #[test]
    fn number_formatting_and_ticks() {
        assert_eq!(fmt_num(1234.5678), "1235");
        assert_eq!(fmt_num(0.012345), "0.01235");
        assert_eq!(fmt_num(-2.0), "-2");
        assert_eq!(fmt_num(f64::INFINITY), "inf");
        assert_eq!(fmt_num(2.5e7 + 0.5), "2.500e7");
        let t: Vec<f64> = ticks(0.0, 10.0, false).iter().map(|t| t.0).collect();
        assert_eq!(t, [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        let t: Vec<f64> = ticks(-3.2, 1.5, true).iter().map(|t| t.0).collect();
        assert_eq!(t, [-3.0, -2.0, -1.0, 0.0, 1.0]);
    }

    /// The run on a real crop: hillshade pair, spectra and statistics of the overview, per
    /// stage peak memory, and the figures in summary.json.
    #[test]
    fn overview_and_stage_memory_on_a_real_crop() {
        let root = crate::test_root();
        let tmp = tempfile::tempdir().unwrap();
        let config = PipelineConfig {
            crop: Some((100, 120, 96, 64)),
            out_dir: tmp.path().to_path_buf(),
            verbose: false,
            ..PipelineConfig::full(&root)
        };
        let stages = super::super::spec::build_stages(&[
            super::super::spec::StageSpec::named("load"),
            super::super::spec::StageSpec::named("fill_voids"),
        ])
        .unwrap();
        super::super::run(&config, &stages).unwrap();
        for f in ["overview_before.png", "overview_after.png"] {
            assert!(tmp.path().join(f).is_file(), "{f}");
        }
        let summary: serde_json::Value =
            serde_json::from_slice(&std::fs::read(tmp.path().join("summary.json")).unwrap())
                .unwrap();
        let o = &summary["overview"];
        let slope = o["figures"]["spectral_slope_input"].as_f64().unwrap();
        assert!(
            (-4.5..-1.0).contains(&slope),
            "terrain spectral slope {slope}"
        );
        assert_eq!(o["figures"]["slope_histogram_distance_deg"], 0.0);
        assert_eq!(
            o["tables"][0]["rows"][0],
            serde_json::json!(["width", "96", "96"])
        );
        assert_eq!(o["plots"][0]["series"].as_array().unwrap().len(), 2);
        for s in summary["stages"].as_array().unwrap() {
            let peak = s["peak_memory_bytes"].as_u64().unwrap();
            assert!(peak > 1 << 20, "{s}");
            assert!(s["peak_rise_bytes"].as_u64().unwrap() <= peak, "{s}");
        }
        let html = std::fs::read_to_string(tmp.path().join("report.html")).unwrap();
        assert!(html.contains("<a href=\"#overview\">"));
        assert!(html.contains("src=\"overview_after.png\""));
        assert!(html.contains("<svg class=\"plot\""));
    }
}

/// The pipeline documentation stays in step with the code: every registered stage has a
/// section in `docs/PIPELINE.md`, and every spec shown there or kept in `docs/*.json` parses and
/// builds (unknown stages, fields and invalid parameter values are errors).
#[cfg(test)]
mod docs_tests {
    use super::super::spec::{PipelineSpec, STAGE_NAMES, build_stages};

    fn doc() -> String {
        std::fs::read_to_string(crate::test_root().join("docs/PIPELINE.md")).unwrap()
    }

    #[test]
    fn every_stage_is_documented() {
        let doc = doc();
        for name in STAGE_NAMES {
            assert!(
                doc.contains(&format!("### `{name}`")),
                "docs/PIPELINE.md has no section for stage `{name}`: add one (what it does, its \
                 parameter table)"
            );
        }
    }

    #[test]
    fn specs_in_the_docs_are_valid() {
        let root = crate::test_root();
        let doc = doc();
        let mut n = 0;
        for block in doc.split("```json\n").skip(1) {
            let json = block.split("```").next().unwrap();
            let spec: PipelineSpec = serde_json::from_str(json)
                .unwrap_or_else(|e| panic!("spec in docs/PIPELINE.md: {e}\n{json}"));
            build_stages(&spec.stages).unwrap_or_else(|e| panic!("{e:#}\n{json}"));
            n += 1;
        }
        assert!(n >= 1);
        let mut files = 0;
        for entry in std::fs::read_dir(root.join("docs")).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "json") {
                let spec = PipelineSpec::read(&path)
                    .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
                let mut config = crate::pipeline::PipelineConfig::full(&root);
                spec.apply(&mut config);
                assert!(config.input.is_file(), "{}", path.display());
                assert_eq!(spec.stages[0].stage, "load", "{}", path.display());
                files += 1;
            }
        }
        assert!(files >= 1);
    }
}
