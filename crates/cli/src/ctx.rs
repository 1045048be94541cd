//! Run-wide context handed to every subcommand: verbosity flags, progress bars and error
//! reporting.

use std::io::IsTerminal;
use std::time::Duration;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use relief_heightfield::Progress;

/// Global options shared by every subcommand.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Ctx {
    /// `--quiet`: no progress bars and no informational messages on stderr.
    pub(crate) quiet: bool,
    /// `--verbose`: the full error cause chain and extra detail.
    pub(crate) verbose: bool,
    /// `--force`: replace existing output files (never inputs).
    pub(crate) force: bool,
    /// `--compress`: strip compression of GeoTIFF outputs.
    pub(crate) compress: CompressArg,
    /// `--height-range LO,HI`: vertical mapping of 16-bit engine heightmaps (PNG16, `.r16`).
    pub(crate) height_range: Option<(f64, f64)>,
    /// `--size-plus-one`: 16-bit heightmaps get the corner samples (`(w + 1) x (h + 1)`).
    pub(crate) size_plus_one: bool,
    /// `--cog`: GeoTIFF outputs as Cloud-Optimized GeoTIFFs (tiled, with overviews).
    pub(crate) cog: bool,
    /// `--max-memory`: pre-flight limit of a run's working memory (see `memory.rs`).
    pub(crate) max_memory: crate::memory::Limit,
    /// `--max-output-size`: pre-flight limit of a run's output bytes.
    pub(crate) max_output: crate::memory::OutputLimit,
    /// `--max-time`: the longest estimated run a command starts (see `budget.rs`).
    pub(crate) max_time: crate::budget::TimeLimit,
}

/// GeoTIFF outputs larger than this many cells are streamed band by band (`refine` and the
/// sparse models), unless `--stream` asks for it at any size.
pub(crate) const STREAM_CELLS: usize = 1 << 24;

/// Cells per band of a raster streamed into a GeoTIFF (16 MiB of f32: 256 rows of a
/// 16384-wide output).
pub(crate) const STREAM_BAND_CELLS: usize = 1 << 22;

/// A GeoTIFF written band by band (`refine`, `amplify --stream`): memory is a band or two, never
/// the whole raster. Dropped unfinished (on any error), it leaves no file.
pub(crate) struct RowStream<'a> {
    writer: relief_io::TiledGeoTiffWriter,
    path: &'a std::path::Path,
    /// Rows per band.
    pub(crate) band: usize,
    height: usize,
}

impl RowStream<'_> {
    /// The bands `(first row, rows)`, north first.
    pub(crate) fn bands(&self) -> impl Iterator<Item = (usize, usize)> + use<> {
        let (band, height) = (self.band, self.height);
        (0..height)
            .step_by(band)
            .map(move |y| (y, band.min(height - y)))
    }

    /// Appends rows (row-major, north first).
    pub(crate) fn write(&mut self, rows: &[f32]) -> anyhow::Result<()> {
        self.writer
            .write_rows(rows)
            .with_context(|| format!("cannot write {}", self.path.display()))
    }

    /// Completes the file.
    pub(crate) fn finish(self) -> anyhow::Result<()> {
        self.writer
            .finish()
            .with_context(|| format!("cannot write {}", self.path.display()))
    }
}

pub(crate) use relief_io::heightmap16::{heightmap_sidecar, is_heightmap16};

/// `--compress` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub(crate) enum CompressArg {
    /// DEFLATE with the floating-point predictor.
    #[default]
    Deflate,
    /// Zstandard with the floating-point predictor (GDAL's COMPRESS=ZSTD PREDICTOR=3).
    Zstd,
    /// LZW with the floating-point predictor (COMPRESS=LZW PREDICTOR=3).
    Lzw,
    /// Uncompressed strips.
    None,
}

impl Ctx {
    /// A progress sink for library calls. It draws an indicatif bar on stderr when stderr is a
    /// terminal; in a log (pipe, file, batch job) a run that lasts longer than
    /// [`LOG_AFTER`] prints one plain line per phase and at most one every [`LOG_EVERY`];
    /// nothing under `--quiet`.
    pub(crate) fn progress(&self) -> CliProgress {
        let terminal = std::io::stderr().is_terminal();
        let visible = !self.quiet && terminal;
        let log = (!self.quiet && !terminal).then(|| {
            std::sync::Mutex::new(LogState {
                start: *RUN_START.get_or_init(std::time::Instant::now),
                last: None,
                phase: String::new(),
                phase_start: std::time::Instant::now(),
                total: 0,
                done: 0,
            })
        });
        let bar = if visible {
            let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
            bar.enable_steady_tick(Duration::from_millis(120));
            bar
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(spinner_style());
        CliProgress {
            bar,
            log,
            deadline: self.deadline(),
        }
    }

    /// When the run must be over: its start plus `--max-time` (`None`: no limit). Long loops
    /// ask [`relief_heightfield::Progress::stopped`] of the progress sinks of [`Ctx::progress`],
    /// which turns true then, and the run ends with an error naming `--max-time`.
    pub(crate) fn deadline(&self) -> Option<std::time::Instant> {
        let start = *RUN_START.get_or_init(std::time::Instant::now);
        self.max_time
            .0
            .and_then(|s| start.checked_add(Duration::from_secs_f64(s)))
    }

    /// Starts the run's clock (the reference of `--max-time`); the first call wins.
    pub(crate) fn start_clock() {
        RUN_START.get_or_init(std::time::Instant::now);
    }

    /// A GeoTIFF writer fed row by row (north first) in bounded memory: tiled, compressed as
    /// `--compress` says, a Cloud-Optimized GeoTIFF with overviews under `--cog`; written to a
    /// temporary and renamed by `finish` (dropped unfinished, it leaves nothing).
    pub(crate) fn geotiff_rows(
        &self,
        path: &std::path::Path,
        (width, height): (usize, usize),
        cell_size: (f64, f64),
        georef: Option<&relief_heightfield::GeoRef>,
    ) -> relief_io::Result<relief_io::TiledGeoTiffWriter> {
        relief_io::TiledGeoTiffWriter::create(
            path,
            width,
            height,
            cell_size,
            georef,
            relief_io::TiledOptions {
                compression: self.write_options().compression,
                cog: self.cog,
                ..Default::default()
            },
        )
    }

    /// [`Ctx::geotiff_rows`] for a raster written in bands of [`RowStream::band`] rows.
    pub(crate) fn row_stream<'a>(
        &self,
        path: &'a std::path::Path,
        (width, height): (usize, usize),
        cell_size: (f64, f64),
        georef: Option<&relief_heightfield::GeoRef>,
    ) -> anyhow::Result<RowStream<'a>> {
        let writer = self
            .geotiff_rows(path, (width, height), cell_size, georef)
            .with_context(|| format!("cannot write {}", path.display()))?;
        let band = (STREAM_BAND_CELLS / width).clamp(1, height);
        // Several bands even for small rasters, so `--stream` exercises the band seams.
        let band = band.min(height.div_ceil(4)).max(1);
        Ok(RowStream {
            writer,
            path,
            band,
            height,
        })
    }

    /// Streams a `width x height` raster into a GeoTIFF at `path` band by band (see
    /// [`Ctx::row_stream`]): `rows_of(y, n)` computes rows `y..y + n` (row-major, north first)
    /// while a progress bar says `what`. Memory is two bands (one computed while the other is
    /// written), never the whole raster; on any error the file is not written. Returns the
    /// band height.
    pub(crate) fn stream_bands(
        &self,
        path: &std::path::Path,
        size: (usize, usize),
        cell_size: (f64, f64),
        georef: Option<&relief_heightfield::GeoRef>,
        what: &str,
        mut rows_of: impl FnMut(usize, usize) -> anyhow::Result<Vec<f32>> + Send,
    ) -> anyhow::Result<usize> {
        use relief_heightfield::Progress as _;
        let mut out = self.row_stream(path, size, cell_size, georef)?;
        let progress = self.progress();
        progress.begin(what, size.1 as u64);
        // Band k is compressed and written while band k + 1 is computed: both are parallel,
        // and running them together lets the workers of one take up the other's idle time
        // (rows still arrive in order, so the file is the same).
        let mut pending: Option<(Vec<f32>, usize)> = None;
        for (y, rows) in out.bands().collect::<Vec<_>>() {
            let (written, next) = rayon::join(
                || match pending.take() {
                    Some((p, n)) => out.write(&p).map(|()| n),
                    None => Ok(0),
                },
                || rows_of(y, rows),
            );
            progress.advance(written? as u64);
            pending = Some((next?, rows));
        }
        if let Some((p, n)) = pending {
            out.write(&p)?;
            progress.advance(n as u64);
        }
        let band = out.band;
        out.finish()?;
        Ok(band)
    }

    /// Write options of raster outputs (GeoTIFF compression from `--compress`).
    pub(crate) fn write_options(&self) -> relief_io::WriteOptions {
        relief_io::WriteOptions {
            compression: match self.compress {
                CompressArg::Deflate => relief_io::TiffCompression::Deflate,
                CompressArg::Zstd => relief_io::TiffCompression::Zstd,
                CompressArg::Lzw => relief_io::TiffCompression::Lzw,
                CompressArg::None => relief_io::TiffCompression::None,
            },
            ..Default::default()
        }
    }

    /// Writes a raster output atomically. 16-bit heightmaps (PNG16, `.r16`) for engines are
    /// mapped onto `--height-range` (default: the data range), refuse voids (they would read as
    /// the lowest height), and get a JSON sidecar `OUT.json` stating the mapping, which is
    /// also printed: Unity/Unreal/Gaea users set their terrain height from it.
    pub(crate) fn write_raster(
        &self,
        path: &std::path::Path,
        hf: &relief_heightfield::Heightfield,
    ) -> anyhow::Result<()> {
        let mut opts = self.write_options();
        if !is_heightmap16(path) {
            // These flags shape 16-bit engine heightmaps only: say so instead of ignoring them.
            for (set, flag) in [
                (self.height_range.is_some(), "--height-range"),
                (self.size_plus_one, "--size-plus-one"),
            ] {
                if set {
                    self.note(format!(
                        "{flag} applies to 16-bit heightmaps (.png, .r16) only: {} is written \
                         in metres as it is",
                        crate::staging::shown(path).display()
                    ));
                }
            }
        }
        let corners;
        let hf = if self.size_plus_one && is_heightmap16(path) {
            corners = hf
                .corner_samples()
                .context("cannot make the corner samples (--size-plus-one)")?;
            &corners
        } else {
            hf
        };
        let map16 = if is_heightmap16(path) {
            if hf.has_voids() {
                anyhow::bail!(
                    "cannot write {}: {} void cells cannot be stored in a 16-bit heightmap \
                     (they would read as the lowest height); pass --fill-voids",
                    crate::staging::shown(path).display(),
                    hf.void_count()
                );
            }
            let (dlo, dhi) = hf
                .min_max()
                .map(|(a, b)| (a as f64, b as f64))
                .unwrap_or((0.0, 0.0));
            let (lo, hi) = match self.height_range {
                Some((lo, hi)) => {
                    let outside = hf
                        .as_slice()
                        .iter()
                        .filter(|&&v| (v as f64) < lo || (v as f64) > hi)
                        .count();
                    if outside > 0 {
                        self.note(format!(
                            "{}: {outside} cells ({dlo:.2}..{dhi:.2} m) outside --height-range \
                             {lo},{hi} are clamped to it",
                            crate::staging::shown(path).display()
                        ));
                    }
                    (lo, hi)
                }
                None => (dlo, dhi),
            };
            let scale = if hi > lo { (hi - lo) / 65535.0 } else { 1.0 };
            opts.mapping = Some((lo, scale));
            Some((lo, hi, scale))
        } else {
            None
        };
        let cannot = || format!("cannot write {}", crate::staging::shown(path).display());
        if self.cog && relief_io::Format::from_extension(path) == Some(relief_io::Format::GeoTiff) {
            let mut w = self
                .geotiff_rows(path, (hf.width(), hf.height()), hf.cell_size(), hf.georef())
                .with_context(cannot)?;
            w.write_rows(hf.as_slice()).with_context(cannot)?;
            w.finish().with_context(cannot)?;
        } else {
            relief_io::write(path, hf, &opts).with_context(cannot)?;
        }
        if let Some((lo, hi, scale)) = map16 {
            let side = heightmap_sidecar(path);
            let (cx, cy) = hf.cell_size();
            let json = serde_json::json!({
                "width": hf.width(),
                "height": hf.height(),
                "encoding": if relief_io::Format::from_extension(path)
                    == Some(relief_io::Format::R16) {
                    "u16 little-endian, row 0 north"
                } else {
                    "16-bit grey PNG, row 0 north"
                },
                "height_min_m": lo,
                "height_max_m": hi,
                "height_range_m": hi - lo,
                "metres_per_count": scale,
                "offset_m": lo,
                "cell_size_m": [cx, cy],
                "samples": if self.size_plus_one {
                    "cell corners (--size-plus-one): width x height vertices, the extent is \
                     (width - 1) x (height - 1) cells"
                } else {
                    "cell centres"
                },
                "extent_m": if self.size_plus_one {
                    [cx * (hf.width() - 1) as f64, cy * (hf.height() - 1) as f64]
                } else {
                    [cx * hf.width() as f64, cy * hf.height() as f64]
                },
                "note": "height = offset_m + count * metres_per_count. Unity: set the terrain \
                         height to height_range_m and flip rows (Unity's row 0 is south).",
            });
            let text = serde_json::to_string_pretty(&json).unwrap_or_default();
            if let Err(e) = relief_io::write_bytes_atomic(&side, text.as_bytes()) {
                let _ = std::fs::remove_file(path);
                return Err(
                    anyhow::Error::new(e).context(format!("cannot write {}", side.display()))
                );
            }
            self.note(format!(
                "{}: heights {lo:.2}..{hi:.2} m ({:.4} m per count), mapping in {}",
                crate::staging::shown(path).display(),
                scale,
                crate::staging::shown(&side).display()
            ));
        }
        Ok(())
    }

    /// Refuses, before any work, outputs that are inputs, have the wrong extension, or exist
    /// without `--force` (see [`crate::outputs`]).
    pub(crate) fn check_outputs(
        &self,
        inputs: &[&std::path::Path],
        outputs: &[(&std::path::Path, crate::outputs::OutKind)],
    ) -> anyhow::Result<()> {
        let heightmap = |(p, k): &(&std::path::Path, crate::outputs::OutKind)| {
            is_heightmap16(p)
                && matches!(
                    k,
                    crate::outputs::OutKind::Raster | crate::outputs::OutKind::RasterOrSct
                )
        };
        let geotiff = |(p, k): &(&std::path::Path, crate::outputs::OutKind)| {
            relief_io::Format::from_extension(p) == Some(relief_io::Format::GeoTiff)
                && matches!(
                    k,
                    crate::outputs::OutKind::Raster | crate::outputs::OutKind::RasterOrSct
                )
        };
        if self.cog && !outputs.iter().any(geotiff) {
            anyhow::bail!(
                "--cog applies to GeoTIFF outputs (.tif); no output of this command is one"
            );
        }
        if self.size_plus_one && !outputs.iter().any(heightmap) {
            anyhow::bail!(
                "--size-plus-one applies to 16-bit heightmaps (.png, .r16); no output of this \
                 command is one"
            );
        }
        crate::outputs::check_outputs(inputs, outputs, self.force)
    }

    /// Prints an informational line on stderr unless `--quiet`.
    pub(crate) fn note(&self, msg: impl std::fmt::Display) {
        if !self.quiet {
            #[allow(clippy::print_stderr)]
            {
                eprintln!("{msg}");
            }
        }
    }

    /// Prints `err` on stderr: one line `error: <what failed>: <root cause>`, or, under
    /// `--verbose`, the outermost message followed by the whole cause chain, one per line.
    pub(crate) fn report_error(&self, err: &anyhow::Error) {
        #[allow(clippy::print_stderr)]
        {
            eprintln!("{}", format_error(err, self.verbose));
        }
    }
}

/// Formats an error for stderr (see [`Ctx::report_error`]).
pub(crate) fn format_error(err: &anyhow::Error, verbose: bool) -> String {
    let mut chain = err.chain();
    let top = chain.next().map(|e| e.to_string()).unwrap_or_default();
    let rest: Vec<String> = chain.map(|e| e.to_string()).collect();
    if verbose {
        let mut s = format!("error: {top}");
        for cause in &rest {
            s.push_str("\n  caused by: ");
            s.push_str(cause);
        }
        s
    } else {
        match rest.last() {
            // The root cause is usually the concrete reason (e.g. "permission denied"); the
            // intermediate layers stay hidden unless asked for.
            Some(root) if !top.contains(root.as_str()) => format!("error: {top}: {root}"),
            _ => format!("error: {top}"),
        }
    }
}

fn spinner_style() -> ProgressStyle {
    ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("valid progress template")
}

fn bar_style() -> ProgressStyle {
    ProgressStyle::with_template("{msg:>14} [{bar:40}] {percent:>3}% {elapsed}/{eta}")
        .expect("valid progress template")
        .progress_chars("=> ")
}

/// When the run started (`main`, else the first progress sink): the run's age decides whether
/// progress lines print, and `--max-time` counts from it.
static RUN_START: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();

/// Runs shorter than this print no progress line in a log.
pub(crate) const LOG_AFTER: Duration = Duration::from_secs(5);
/// Smallest interval between two progress lines of one phase in a log.
pub(crate) const LOG_EVERY: Duration = Duration::from_secs(10);

/// Progress state of a run whose stderr is not a terminal.
#[derive(Debug)]
struct LogState {
    start: std::time::Instant,
    last: Option<std::time::Instant>,
    phase: String,
    /// When the current phase began (its ETA is extrapolated from its own pace).
    phase_start: std::time::Instant,
    total: u64,
    done: u64,
}

impl LogState {
    /// The line to print now, if any.
    fn line(&mut self, new_phase: bool) -> Option<String> {
        let now = std::time::Instant::now();
        let elapsed = now.duration_since(self.start);
        if elapsed < LOG_AFTER {
            return None;
        }
        if !new_phase && self.last.is_some_and(|t| now.duration_since(t) < LOG_EVERY) {
            return None;
        }
        self.last = Some(now);
        let pct = if self.total > 0 {
            format!(
                " {:.0}%",
                100.0 * self.done.min(self.total) as f64 / self.total as f64
            )
        } else {
            String::new()
        };
        // The phase's remaining time at its pace so far (as the terminal bar's {eta}).
        let eta = if self.total > 0 && self.done > 0 && self.done < self.total {
            let spent = now.duration_since(self.phase_start).as_secs_f64();
            let left = spent * (self.total - self.done) as f64 / self.done as f64;
            format!(", about {} left", crate::budget::human_secs(left))
        } else {
            String::new()
        };
        Some(format!(
            "progress: {}{pct} ({:.0} s{eta})",
            self.phase,
            elapsed.as_secs_f64()
        ))
    }
}

/// indicatif-backed [`Progress`]: each `begin` starts a new phase on the same line (a bar when
/// the total is known, a spinner otherwise). The bar is cleared when dropped. Without a
/// terminal, long runs print plain `progress:` lines instead.
#[derive(Debug)]
pub(crate) struct CliProgress {
    bar: ProgressBar,
    log: Option<std::sync::Mutex<LogState>>,
    /// [`Ctx::deadline`]: [`Progress::stopped`] turns true from then on.
    deadline: Option<std::time::Instant>,
}

impl CliProgress {
    fn log_line(&self, update: impl FnOnce(&mut LogState), new_phase: bool) {
        let Some(log) = &self.log else {
            return;
        };
        let line = {
            let mut s = log.lock().unwrap_or_else(|e| e.into_inner());
            update(&mut s);
            s.line(new_phase)
        };
        if let Some(line) = line {
            #[allow(clippy::print_stderr)]
            {
                eprintln!("{line}");
            }
        }
    }
}

impl CliProgress {
    /// Whether anything is drawn (false under `--quiet` or when stderr is not a terminal).
    #[allow(dead_code)]
    pub(crate) fn is_visible(&self) -> bool {
        !self.bar.is_hidden()
    }
}

impl Progress for CliProgress {
    fn begin(&self, phase: &str, total: u64) {
        self.log_line(
            |s| {
                s.phase = phase.to_string();
                s.phase_start = std::time::Instant::now();
                s.total = total;
                s.done = 0;
            },
            true,
        );
        self.bar.set_message(phase.to_string());
        self.bar.reset();
        if total > 0 {
            self.bar.set_style(bar_style());
            self.bar.set_length(total);
        } else {
            self.bar.set_style(spinner_style());
            self.bar.unset_length();
        }
    }

    fn advance(&self, n: u64) {
        self.log_line(|s| s.done = s.done.saturating_add(n), false);
        self.bar.inc(n);
    }

    fn stopped(&self) -> bool {
        self.deadline
            .is_some_and(|d| std::time::Instant::now() >= d)
    }
}

impl Drop for CliProgress {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

impl Ctx {
    /// [`crate::budget::check_time`] against `--max-time`; prints the estimate when it is not short.
    pub(crate) fn check_time(
        &self,
        what: &str,
        est_s: f64,
        how: &str,
        change: &str,
    ) -> anyhow::Result<()> {
        crate::budget::check_time(what, est_s, how, self.max_time, change)?;
        if est_s >= crate::budget::NOTE_AFTER_S {
            self.note(format!(
                "{what}: estimated {} ({how})",
                crate::budget::human_secs(est_s)
            ));
        }
        Ok(())
    }
}

impl Ctx {
    /// [`crate::memory::check_memory`] against `--max-memory`.
    pub(crate) fn check_memory(
        &self,
        command: &str,
        peaks: &[&[crate::memory::Part]],
    ) -> anyhow::Result<()> {
        crate::memory::check_memory(command, self.max_memory, peaks)
    }

    /// [`crate::memory::check_output`] against `--max-output-size`.
    pub(crate) fn check_output_size(
        &self,
        what: &str,
        bytes: f64,
        change: &str,
    ) -> anyhow::Result<()> {
        crate::memory::check_output(what, bytes, self.max_output.0, change)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_line_error_names_root_cause() {
        let err = anyhow::anyhow!("permission denied").context("cannot write out.tif");
        assert_eq!(
            format_error(&err, false),
            "error: cannot write out.tif: permission denied"
        );
        let verbose = format_error(&err, true);
        assert_eq!(verbose.lines().count(), 2);
        assert!(verbose.contains("caused by: permission denied"));
    }

    #[test]
    fn root_cause_not_repeated() {
        let err = anyhow::anyhow!("bad magic").context("cannot read x: bad magic");
        assert_eq!(format_error(&err, false), "error: cannot read x: bad magic");
    }

    #[test]
    fn quiet_progress_is_hidden() {
        let ctx = Ctx {
            quiet: true,
            verbose: false,
            force: false,
            compress: CompressArg::None,
            height_range: None,
            ..Default::default()
        };
        let p = ctx.progress();
        assert!(!p.is_visible());
        p.begin("phase", 10);
        p.advance(3);
        assert_eq!(p.bar.position(), 3);
        assert!(p.log.is_none(), "--quiet prints no log lines either");
    }

    #[test]
    fn log_lines_only_for_long_runs_and_rate_limited() {
        let t0 = std::time::Instant::now();
        let mut s = LogState {
            start: t0,
            last: None,
            phase: "k-svd".into(),
            phase_start: t0,
            total: 4,
            done: 1,
        };
        assert_eq!(s.line(true), None, "short runs stay silent");
        s.start = t0 - LOG_AFTER - Duration::from_secs(1);
        s.phase_start = t0 - Duration::from_secs(20);
        let l = s.line(false).expect("a line once the run is long");
        assert!(l.starts_with("progress: k-svd 25%"), "{l}");
        assert!(
            l.contains("about 60 s left"),
            "the ETA at the phase's pace: {l}"
        );
        assert_eq!(s.line(false), None, "rate-limited");
        assert!(s.line(true).is_some(), "a new phase is always shown");
    }
}
