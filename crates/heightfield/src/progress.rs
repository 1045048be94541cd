/// Progress sink for long computations. Library code never prints; it reports here and the CLI
/// turns the reports into a progress bar. Implementations must be cheap and thread-safe: the
/// methods may be called from rayon worker threads.
pub trait Progress: Sync {
    /// Announces a new phase with `total` units of work (0 when unknown).
    fn begin(&self, _phase: &str, _total: u64) {}
    /// Reports `n` more units done in the current phase.
    fn advance(&self, _n: u64) {}
    /// Whether the caller asks the work to stop (its time budget ran out). Long loops ask
    /// between units of work and end with their crate's `Stopped` error, leaving no partial
    /// result; the default never stops.
    fn stopped(&self) -> bool {
        false
    }
}

/// A [`Progress`] that ignores every report.
#[derive(Debug, Default, Clone, Copy)]
pub struct NoProgress;

impl Progress for NoProgress {}
