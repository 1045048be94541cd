//! Ending a run early without leaving its temporaries behind: SIGINT and SIGTERM, and the
//! `--max-time` backstop.
//!
//! A thread receives SIGINT or SIGTERM (`signal-hook`: the signal only wakes it, the work
//! happens outside the handler), removes every temporary file and staging folder the run
//! still had (`relief_io::remove_own_temporaries`: writes not yet renamed into place) and
//! exits with `128 + signal`. Outputs already in place stay: every write is atomic, so none is
//! partial. Long loops stop themselves at the `--max-time` deadline
//! (`relief_heightfield::Progress::stopped`); a path that does not ask (a tile task, a reader)
//! is ended the same way [`BACKSTOP_GRACE`] after the deadline.

use std::time::{Duration, Instant};

use crate::ctx::Ctx;

/// How long after the `--max-time` deadline a run that has not stopped by itself is ended.
pub(crate) const BACKSTOP_GRACE: Duration = Duration::from_secs(5);

/// Installs the signal thread and, with a time limit, the backstop.
pub(crate) fn install(ctx: &Ctx) {
    use signal_hook::consts::{SIGINT, SIGTERM};
    // Without a handler (the registration failed) a signal keeps its default action; the
    // temporaries then stay, hidden, until a later run in the folder removes them.
    if let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) {
        std::thread::spawn(move || {
            if let Some(sig) = signals.forever().next() {
                let name = if sig == SIGINT { "SIGINT" } else { "SIGTERM" };
                end(
                    &format!("interrupted by {name}: the files it was still writing were removed"),
                    128 + sig,
                );
            }
        });
    }
    if let Some(deadline) = ctx.deadline() {
        let limit = ctx.max_time;
        std::thread::spawn(move || {
            let at = deadline + BACKSTOP_GRACE;
            loop {
                let now = Instant::now();
                if now >= at {
                    end(
                        &format!(
                            "stopped: the run took longer than {limit} (it is stopped at the \
                             limit, whatever the estimate); the files it was still writing \
                             were removed"
                        ),
                        1,
                    );
                }
                std::thread::sleep((at - now).min(Duration::from_secs(1)));
            }
        });
    }
}

/// Removes the run's temporaries, reports `why` and exits with `code`.
fn end(why: &str, code: i32) -> ! {
    relief_io::remove_own_temporaries();
    #[allow(clippy::print_stderr)]
    {
        eprintln!("error: {why}");
    }
    std::process::exit(code)
}
