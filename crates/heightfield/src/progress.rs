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

impl dyn Progress + '_ {
    /// `Err(stopped())` when the caller asks the work to stop ([`Progress::stopped`]), else
    /// `Ok(())`: the check a long computation makes between units of work, `stopped` making
    /// its crate's `Stopped` error.
    pub fn check_stop<E>(&self, stopped: impl FnOnce() -> E) -> Result<(), E> {
        if self.stopped() {
            Err(stopped())
        } else {
            Ok(())
        }
    }
}

/// A [`Progress`] that ignores every report.
#[derive(Debug, Default, Clone, Copy)]
pub struct NoProgress;

impl Progress for NoProgress {}

/// A [`Progress`] that forwards only [`Progress::stopped`] to another: for inner work that
/// must stop when asked but whose phases are not the caller's to show (the coding inside one
/// step of a longer job).
#[derive(Clone, Copy)]
pub struct StopOnly<'a>(pub &'a dyn Progress);

impl std::fmt::Debug for StopOnly<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("StopOnly")
    }
}

impl Progress for StopOnly<'_> {
    fn stopped(&self) -> bool {
        self.0.stopped()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

    struct Counting(AtomicU64, AtomicBool);
    impl Progress for Counting {
        fn begin(&self, _: &str, _: u64) {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
        fn advance(&self, _: u64) {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
        fn stopped(&self) -> bool {
            self.1.load(Ordering::Relaxed)
        }
    }

    #[test]
    fn stop_only_forwards_the_stop_and_nothing_else() {
        let inner = Counting(AtomicU64::new(0), AtomicBool::new(false));
        let p = StopOnly(&inner);
        p.begin("phase", 10);
        p.advance(3);
        assert!(!p.stopped());
        inner.1.store(true, Ordering::Relaxed);
        assert!(p.stopped());
        assert_eq!(inner.0.load(Ordering::Relaxed), 0);
    }
}
