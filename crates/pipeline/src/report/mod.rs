//! Report builder: collects per-stage images, tables and figures, then writes `summary.json`
//! (machine-readable, every figure) and `report.html` (one self-contained page that links the
//! images written beside it).
//!
//! The model (sections, figures, tables, plots) is here; `html.rs` renders the page and
//! `svg.rs` the plots.

mod html;
mod svg;
#[cfg(test)]
mod tests;

pub use html::esc;

use std::collections::BTreeMap;
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
    pub fn line(self, label: &str, points: impl IntoIterator<Item = (f64, f64)>) -> Self {
        self.series(label, points.into_iter().collect(), false)
    }

    /// Adds a dashed line (a fit, a target, a reference slope).
    #[allow(dead_code)] // for the method stages
    pub fn dashed(self, label: &str, points: impl IntoIterator<Item = (f64, f64)>) -> Self {
        self.series(label, points.into_iter().collect(), true)
    }

    fn series(mut self, label: &str, points: Vec<(f64, f64)>, dashed: bool) -> Self {
        self.series.push(Series {
            label: label.to_string(),
            points,
            dashed,
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
        self.side_by_side(name, caption, ("before", before), ("after", after))
    }

    /// [`Self::before_after`] with other labels (e.g. "truth" beside "amplified"): the files
    /// are still `<name>_before.png` and `<name>_after.png`.
    pub fn side_by_side(
        &mut self,
        name: &str,
        caption: &str,
        (left_label, left): (&str, &Heightfield),
        (right_label, right): (&str, &Heightfield),
    ) -> Result<()> {
        let b = self.save_hillshade(&format!("{name}_before"), left)?;
        let a = self.save_hillshade(&format!("{name}_after"), right)?;
        if let (Some(b), Some(a)) = (b, a) {
            let lb = format!("{left_label} ({} x {})", left.width(), left.height());
            let la = format!("{right_label} ({} x {})", right.width(), right.height());
            self.section.pair((&b, &lb), (&a, &la), caption);
        }
        Ok(())
    }

    /// Adds a log-log plot of the radially averaged power spectra (cycles per metre) of the
    /// given grids, and records each one's spectral slope over the band from 4 cycles per
    /// grid to a quarter of its Nyquist frequency as the figure `spectral_slope_<label>`.
    /// Grids with voids or smaller than 8 x 8 are skipped. The curves are power spectral
    /// densities (m^2 per (cycle/m)^2: the FFT power times the cell area over the cells and
    /// the Hann window's mean square), so grids of other sizes and cell sizes that hold the
    /// same terrain lie on one curve.
    pub fn spectrum_plot(&mut self, title: &str, grids: &[(&str, &Heightfield)]) {
        let mut plot = Plot::new(
            title,
            "frequency (cycles / m)",
            "power spectral density (m^4)",
        )
        .log_log();
        for (label, hf) in grids {
            let Ok(spec) = metrics::radial_power_spectrum(hf) else {
                continue;
            };
            let (cx, cy) = hf.cell_size();
            let hann_ms = |n: usize| {
                (0..n)
                    .map(|i| {
                        let v = 0.5
                            - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / (n - 1) as f64).cos();
                        v * v
                    })
                    .sum::<f64>()
                    / n as f64
            };
            let norm = cx * cy / (hf.len() as f64 * hann_ms(hf.width()) * hann_ms(hf.height()));
            let spec: Vec<(f64, f64)> = spec.into_iter().map(|(f, p)| (f, p * norm)).collect();
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

pub(super) fn fmt_mib(b: u64) -> String {
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
