//! The coder the encoder and the amplification steps call: Batch-OMP, or at `s = 1` with a large
//! dictionary the inverted-list search of [`crate::nearest`]. It sits above both solvers'
//! modules so neither has to call back into the other's dispatch.

use ndarray::ArrayView2;

use relief_heightfield::Progress;

use crate::codes::{NEAREST_MIN_ATOMS, OmpFloat, OmpSettings, SparseCodes};
use crate::error::Result;
use crate::nearest::{AtomIndex, AtomIndexSettings};
use crate::omp::batch_omp_with_progress;

/// `s = 1`-aware coding: with `settings.sparsity == 1`, more than
/// [`crate::omp::NEAREST_MIN_ATOMS`] atoms and `probes > 0`, the inverted-list [`AtomIndex`](crate::nearest::AtomIndex)
/// (default clustering, `probes` clusters searched per signal) built for `dict`; otherwise
/// [`crate::omp::batch_omp_with_progress`] (the Gram path, or the exact [`crate::nearest::nearest_atom`] above
/// 4096 atoms at `s = 1`). The index is a function of the dictionary alone, so the codes of a
/// signal do not depend on the batch it is coded in.
pub fn code_indexed<T: OmpFloat>(
    dict: ArrayView2<T>,
    signals: ArrayView2<T>,
    settings: &OmpSettings,
    probes: usize,
    progress: &dyn Progress,
) -> Result<SparseCodes<T>> {
    if settings.sparsity != 1 || dict.nrows() <= NEAREST_MIN_ATOMS || probes == 0 {
        return batch_omp_with_progress(dict, signals, settings, progress);
    }
    let index = AtomIndex::build(
        dict,
        &AtomIndexSettings {
            probes,
            ..AtomIndexSettings::default()
        },
    )?;
    index.code_with_progress(signals, settings.tolerance, progress)
}
