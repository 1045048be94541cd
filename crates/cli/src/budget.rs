//! Time budgets. Memory and output size follow from the input and the settings
//! (`memory.rs`), but the run time of some jobs does not: `decompress` of a model with wide
//! blends at a large `--factor`, or `volume` renders at a large `--image-size`, can take from
//! seconds to hours for the same output size. Those commands time a small pilot of the very
//! same work before they start (a few evenly spaced row strips of the raster, the images at
//! 1/4 of their width and height), extrapolate by the amount of work, print the estimate when
//! it is not short, and refuse a run whose estimate exceeds the global `--max-time` (default
//! [`DEFAULT_MAX_TIME_S`]) with a message naming the setting to change. `--max-time none`
//! lifts the limit. The estimate never changes an output: only whether the run starts.

use anyhow::{Result, bail};
use rayon::prelude::*;
use relief_sparse_core::{RasterSettings, Sct, Window};

/// Default `--max-time`: 30 minutes.
pub(crate) const DEFAULT_MAX_TIME_S: f64 = 1800.0;

/// Estimates shorter than this are not printed.
pub(crate) const NOTE_AFTER_S: f64 = 10.0;

/// `--max-time`: the longest estimated run time a command starts (`None`: no limit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TimeLimit(pub(crate) Option<f64>);

impl Default for TimeLimit {
    fn default() -> Self {
        TimeLimit(Some(DEFAULT_MAX_TIME_S))
    }
}

/// Parses `--max-time`: `none`, or a duration in seconds with an optional unit `s`, `m`
/// (`min`) or `h`, e.g. `90`, `90s`, `15m`, `2h`, `1.5h`.
pub(crate) fn parse_time(s: &str) -> std::result::Result<TimeLimit, String> {
    let t = s.trim().to_ascii_lowercase();
    if t == "none" {
        return Ok(TimeLimit(None));
    }
    let (num, mul) = if let Some(n) = t.strip_suffix("min") {
        (n, 60.0)
    } else if let Some(n) = t.strip_suffix('h') {
        (n, 3600.0)
    } else if let Some(n) = t.strip_suffix('m') {
        (n, 60.0)
    } else if let Some(n) = t.strip_suffix('s') {
        (n, 1.0)
    } else {
        (t.as_str(), 1.0)
    };
    let v: f64 = num.trim().parse().map_err(|_| {
        format!("`{s}` is not a duration (seconds, or a number with s, m or h, e.g. 15m; or none)")
    })?;
    let secs = v * mul;
    if !(secs.is_finite() && secs > 0.0 && secs <= 1e9) {
        return Err(format!(
            "`{s}`: the duration must be over 0 s and at most 10^9 s (or none)"
        ));
    }
    Ok(TimeLimit(Some(secs)))
}

/// A duration for people: `0.5 s`, `45 s`, `12 min`, `2.5 h`.
pub(crate) fn human_secs(s: f64) -> String {
    if s < 10.0 {
        format!("{s:.1} s")
    } else if s < 90.0 {
        format!("{s:.0} s")
    } else if s < 5400.0 {
        format!("{:.0} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}

impl std::fmt::Display for TimeLimit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.0 {
            None => write!(f, "--max-time none"),
            Some(s) if s == DEFAULT_MAX_TIME_S => {
                write!(f, "--max-time {} (the default)", human_secs(s))
            }
            Some(s) => write!(f, "--max-time {}", human_secs(s)),
        }
    }
}

/// Refuses a run estimated at `est_s` seconds over `limit`. `what` names the work, `how` the
/// pilot the estimate comes from, `change` the setting that makes the work smaller.
pub(crate) fn check_time(
    what: &str,
    est_s: f64,
    how: &str,
    limit: TimeLimit,
    change: &str,
) -> Result<()> {
    if let Some(max) = limit.0
        && (est_s.is_nan() || est_s > max)
    {
        bail!(
            "{what} is estimated at {} ({how}), more than {limit}: use {change}, or raise \
             --max-time (`--max-time none` lifts the limit)",
            human_secs(est_s)
        );
    }
    Ok(())
}

/// Whether `err` comes from work stopped by its time budget (a library's `Stopped` error,
/// raised when [`crate::ctx::Ctx::deadline`] passed during the work).
pub(crate) fn is_stopped(err: &anyhow::Error) -> bool {
    err.chain().any(|e| {
        matches!(
            e.downcast_ref::<relief_sparse_core::SparseError>(),
            Some(relief_sparse_core::SparseError::Stopped(_))
        ) || matches!(
            e.downcast_ref::<relief_wavelet_lod::WaveletError>(),
            Some(relief_wavelet_lod::WaveletError::Stopped(_))
        ) || matches!(
            e.downcast_ref::<relief_implicit_volume::Error>(),
            Some(relief_implicit_volume::Error::Stopped(_))
        ) || matches!(
            e.downcast_ref::<relief_landscape::LandscapeError>(),
            Some(relief_landscape::LandscapeError::Stopped(_))
        ) || e
            .downcast_ref::<relief_dictionary_learning::LearnError>()
            .is_some_and(|e| e.is_stopped())
            || e.downcast_ref::<Stopped>().is_some()
            || e.downcast_ref::<relief_pipeline::Stopped>().is_some()
    })
}

/// The CLI's own stop (between pipeline stages, in streamed writers): see [`is_stopped`].
#[derive(Debug)]
pub(crate) struct Stopped(pub(crate) String);

impl std::fmt::Display for Stopped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "stopped: {}", self.0)
    }
}

impl std::error::Error for Stopped {}

/// Ends a command's writing: `commit` makes its staged outputs final, unless the run went past
/// `--max-time` meanwhile (writing asks no deadline: a late run is not committed, its staged
/// files are removed). `progress` ends here.
pub(crate) fn commit_in_time(
    command: &str,
    progress: impl relief_heightfield::Progress,
    commit: impl FnOnce() -> Result<()>,
) -> Result<()> {
    if progress.stopped() {
        return Err(Stopped(format!("{command}, after writing the outputs")).into());
    }
    commit()
}

/// Rasters of at least this many cells get a time estimate (smaller ones take seconds).
const PILOT_FROM_CELLS: usize = 1 << 20;
/// The pilot rasterises this many evenly spaced row strips ...
const PILOT_STRIPS: usize = 16;
/// ... covering about 1/this of the window's rows.
const PILOT_SHARE: usize = 64;

/// Estimated seconds to rasterise `settings`' window: times [`PILOT_STRIPS`] evenly spaced
/// full-width row strips covering about 1/[`PILOT_SHARE`] of it, in parallel as the run is,
/// and scales by the cell count (the cost of a cell is the atoms over it, which the strips
/// sample across the whole model). `None` for small windows. Returns the pilot's description.
pub(crate) fn sct_raster_seconds(
    sct: &Sct,
    settings: &RasterSettings,
) -> Result<Option<(f64, String)>> {
    let Some(win) = settings.window else {
        return Ok(None);
    };
    let cells = win.width * win.height;
    if cells < PILOT_FROM_CELLS {
        return Ok(None);
    }
    let rows = win.height.div_ceil(PILOT_SHARE * PILOT_STRIPS).max(1);
    let strips: Vec<Window> = (0..PILOT_STRIPS)
        .map(|i| Window {
            x: win.x,
            y: win.y + (i * (win.height - rows)) / (PILOT_STRIPS - 1),
            width: win.width,
            height: rows,
        })
        .collect();
    let t = std::time::Instant::now();
    strips.par_iter().try_for_each(|&w| {
        sct.rasterize(&RasterSettings {
            scale: settings.scale,
            window: Some(w),
        })
        .map(drop)
    })?;
    let pilot_cells = (PILOT_STRIPS * rows * win.width) as f64;
    let est = t.elapsed().as_secs_f64() * cells as f64 / pilot_cells;
    Ok(Some((
        est,
        format!(
            "from {PILOT_STRIPS} strips of {rows} rows, {:.1} % of the cells",
            100.0 * pilot_cells / cells as f64
        ),
    )))
}

/// Estimated seconds of a job on a whole grid of `width x height` cells whose cost grows as
/// `n log n` (priority floods, sorts): times `run` on a centred crop of about
/// 1/[`PILOT_SHARE`] of the cells (`crop(x, y, w, h)` makes it) and scales. `None` for grids
/// under [`PILOT_FROM_CELLS`]. Returns the pilot's description too.
pub(crate) fn crop_pilot_seconds(
    (width, height): (usize, usize),
    run: impl FnOnce(usize, usize, usize, usize) -> Result<()>,
) -> Result<Option<(f64, String)>> {
    let cells = width * height;
    if cells < PILOT_FROM_CELLS {
        return Ok(None);
    }
    let side = (PILOT_SHARE as f64).sqrt();
    let (w, h) = (
        ((width as f64 / side).ceil() as usize).clamp(1, width),
        ((height as f64 / side).ceil() as usize).clamp(1, height),
    );
    let (x, y) = ((width - w) / 2, (height - h) / 2);
    let t = std::time::Instant::now();
    run(x, y, w, h)?;
    let pilot = (w * h) as f64;
    let n = cells as f64;
    let est = t.elapsed().as_secs_f64() * (n / pilot) * (n.ln() / pilot.ln().max(1.0));
    Ok(Some((
        est,
        format!(
            "from a {w} x {h} crop, {:.1} % of the cells",
            100.0 * pilot / n
        ),
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_parse_with_units_and_none() {
        assert_eq!(parse_time("90").unwrap(), TimeLimit(Some(90.0)));
        assert_eq!(parse_time("90s").unwrap(), TimeLimit(Some(90.0)));
        assert_eq!(parse_time("15m").unwrap(), TimeLimit(Some(900.0)));
        assert_eq!(parse_time("15min").unwrap(), TimeLimit(Some(900.0)));
        assert_eq!(parse_time("1.5h").unwrap(), TimeLimit(Some(5400.0)));
        assert_eq!(parse_time("None").unwrap(), TimeLimit(None));
        for bad in ["", "fast", "-5m", "0", "nan", "inf", "1e12h"] {
            assert!(parse_time(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn estimates_over_the_limit_are_refused_naming_the_flags() {
        let limit = TimeLimit(Some(600.0));
        assert!(
            check_time(
                "the render",
                599.0,
                "pilot",
                limit,
                "a smaller --image-size"
            )
            .is_ok()
        );
        let e = check_time(
            "the render",
            1500.0,
            "pilot",
            limit,
            "a smaller --image-size",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("25 min") && e.contains("--max-time 10 min"),
            "{e}"
        );
        assert!(
            e.contains("a smaller --image-size") && e.contains("--max-time none"),
            "{e}"
        );
        // A NaN estimate (a broken clock) is refused, not waved through.
        assert!(check_time("x", f64::NAN, "pilot", limit, "y").is_err());
        assert!(check_time("x", 1e12, "pilot", TimeLimit(None), "y").is_ok());
    }
}
