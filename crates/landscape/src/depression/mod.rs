//! Depression handling: priority-flood filling (plain or epsilon), least-cost breaching, and
//! drainage across the flats that filling leaves.

pub mod breach;
pub mod fill;
pub mod flats;
/// The radix heap of the floods (kept at this path for callers; it lives in `crate::radix`).
pub use crate::radix;

pub use breach::{BreachLimits, BreachReport, breach};
pub use fill::{FillMode, NO_PARENT, is_outlet, priority_flood};
pub use flats::resolve_flats;
