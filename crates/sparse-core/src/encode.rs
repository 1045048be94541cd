//! Compact terrain representation (guerin2016 section 5.1): encode a heightfield as a Sparse
//! Construction Tree over a dictionary, and measure it.
//!
//! Storage in values follows the paper: `t(s, N) = K N + n (2 s + 2) + 1` against
//! `t0 = w h` input samples, `rho = t / t0`. The real size of the `.sct` bytes is reported too
//! (it also stores a header and 1-2 bytes per index instead of a full value).

use std::sync::Arc;

use relief_heightfield::{Heightfield, NoProgress, Progress, metrics};

use crate::coding::code_indexed;
use crate::dictionary::{Dictionary, FunctionAtomRegistry};
use crate::error::{Result, SparseError};
use crate::format::FormatOptions;
use crate::omp::OmpSettings;
use crate::patches::{PatchGeometry, extract_patches};
use crate::sct::{Node, Placement, RasterSettings, Sct, SparseLayer};

/// Settings of [`encode`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EncodeSettings {
    /// Sparsity `s` of every primitive (1..=64, <= N).
    pub sparsity: usize,
    /// Optional squared-residual target per patch (OMP stops earlier when reached).
    pub tolerance: Option<f64>,
    /// Grid step between primitive centres in terrain cells; `None` = half the patch width
    /// (`a delta / 2`).
    pub step: Option<f64>,
    /// With `s = 1` and more than 4096 atoms: clusters of the inverted-list index searched per
    /// patch ([`crate::code_indexed`]; 0 = the exact search). Default
    /// [`DEFAULT_INDEX_PROBES`].
    pub index_probes: usize,
}

/// Default probes of the `s = 1` atom index for dictionaries of more than 4096 atoms: on
/// 65,536 Grand Canyon atoms, 96.8 % of the patches get the exact search's atom and the
/// squared residual grows by 0.27 %, at 15 us per patch against 230 us for the exact search
/// and 23 us for a 4096-atom dictionary (`cargo bench -p relief-benches --bench
/// nearest_index`).
pub const DEFAULT_INDEX_PROBES: usize = 8;

impl Default for EncodeSettings {
    fn default() -> Self {
        Self {
            sparsity: 2,
            tolerance: None,
            step: None,
            index_probes: DEFAULT_INDEX_PROBES,
        }
    }
}

impl EncodeSettings {
    /// The patch geometry these settings give with `dict`.
    pub fn geometry(&self, dict: &Dictionary) -> PatchGeometry {
        PatchGeometry {
            patch_size: dict.patch_size(),
            spacing: dict.spacing(),
            step: self
                .step
                .unwrap_or(dict.patch_size() as f64 * dict.spacing() / 2.0),
            support_radius: dict.support_radius(),
        }
    }
}

impl EncodeSettings {
    /// Validates the settings against `dict`: a non-empty dictionary, the sparsity and
    /// tolerance of [`OmpSettings::check`], and the patch geometry (step finite and > 0, the
    /// support radius larger than `step / sqrt(2)`, a bounded number of primitives per cell).
    pub fn check(&self, dict: &Dictionary) -> Result<()> {
        if dict.is_empty() {
            return Err(SparseError::EmptyDictionary {
                n_atoms: 0,
                dim: dict.dim(),
            });
        }
        OmpSettings {
            sparsity: self.sparsity,
            tolerance: self.tolerance,
        }
        .check(dict.len())?;
        if let Some(step) = self.step
            && !(step.is_finite() && step > 0.0)
        {
            return Err(SparseError::param("step", step, "must be finite and > 0"));
        }
        self.geometry(dict).check()
    }
}

/// Encodes a void-free heightfield: extract the patches `T_i` and `z_i` on the regular centre
/// grid (section 4.2), code them with Batch-OMP over `dict` (section 4.3) and build a one-layer
/// tree whose terrain is `f(p) = sum f_i alpha_i / sum alpha_i` (section 4.1).
pub fn encode(hf: &Heightfield, dict: &Dictionary, settings: &EncodeSettings) -> Result<Sct> {
    encode_shared(hf, Arc::new(dict.clone()), settings)
}

/// [`encode`] with a shared dictionary (no copy).
pub fn encode_shared(
    hf: &Heightfield,
    dict: Arc<Dictionary>,
    settings: &EncodeSettings,
) -> Result<Sct> {
    encode_with_progress(hf, dict, settings, &NoProgress)
}

/// [`encode_shared`] reporting progress (phases `"extract patches"`, `"batch-omp"`).
pub fn encode_with_progress(
    hf: &Heightfield,
    dict: Arc<Dictionary>,
    settings: &EncodeSettings,
    progress: &dyn Progress,
) -> Result<Sct> {
    settings.check(&dict)?;
    let geometry = settings.geometry(&dict);
    progress.begin("extract patches", 1);
    let patches = extract_patches(hf, &geometry)?;
    progress.advance(1);
    let d = dict.discretize();
    let codes = code_indexed(
        d.view(),
        patches.matrix.view(),
        &OmpSettings {
            sparsity: settings.sparsity,
            tolerance: settings.tolerance,
        },
        settings.index_probes,
        progress,
    )?;
    let layer = SparseLayer::from_codes(
        dict,
        Placement::Grid(patches.grid),
        patches.means.clone(),
        &codes,
    )?;
    Ok(
        Sct::new(Node::Layer(layer), hf.width(), hf.height(), hf.cell_size())?
            .with_georef(hf.georef().cloned()),
    )
}

/// Paper storage `t(s, N) = K N + n (2 s + 2) + 1` (number of stored values).
pub fn storage_values(k: usize, n_atoms: usize, n_patches: usize, sparsity: usize) -> u64 {
    (k as u64) * (n_atoms as u64) + (n_patches as u64) * (2 * sparsity as u64 + 2) + 1
}

/// Values a dictionary stores: `K` samples per data atom, and only the parameters of a
/// function atom (its samples are computed, section 5.2); the field parameters that function
/// atoms of one kind share ([`crate::dictionary::FunctionAtom::field_params`]: windows of one
/// noise field) are counted once. For a data-only dictionary this is the `K N` of
/// [`storage_values`].
pub fn dictionary_values(d: &crate::Dictionary) -> u64 {
    let mut fields: std::collections::HashSet<(String, Vec<u64>)> = Default::default();
    d.atoms()
        .iter()
        .map(|a| match a {
            crate::dictionary::Atom::Data(_) => d.dim() as u64,
            crate::dictionary::Atom::Function { func, .. } => {
                let desc = func.descriptor();
                let k = func.field_params().min(desc.params.len());
                let key = desc.params[..k].iter().map(|p| p.to_bits()).collect();
                let shared = if k > 0 && !fields.insert((desc.kind, key)) {
                    k
                } else {
                    0
                };
                (desc.params.len() - shared) as u64
            }
        })
        .sum()
}

/// Stored values of a layer: [`dictionary_values`] + `n (2 s + 2) + 1` (the paper's
/// `t(s, N)` for data atoms, with analytic atoms counted by their parameters).
pub fn layer_storage_values(d: &crate::Dictionary, n_patches: usize, sparsity: usize) -> u64 {
    dictionary_values(d) + (n_patches as u64) * (2 * sparsity as u64 + 2) + 1
}

/// Measures of a compact representation (the columns of the paper's table 1 and more).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CompressionReport {
    /// Input samples `t0 = w h`.
    pub t0: u64,
    /// Paper storage `t(s, N)` summed over the layers (s = largest per-primitive count); an
    /// analytic atom counts its parameters, not `K` samples ([`layer_storage_values`]).
    pub t: u64,
    /// `rho = t / t0`.
    pub rho: f64,
    /// Real size of the `.sct` bytes.
    pub bytes: usize,
    /// `bytes / (4 t0)`: size relative to the input as `f32`.
    pub byte_ratio: f64,
    /// PSNR in dB of the scale-1 rasterisation against the input (peak = elevation range).
    pub psnr: f64,
    /// RMSE in metres.
    pub rmse: f64,
    /// Number of primitives `n`.
    pub n_patches: usize,
    /// Number of atoms `N`.
    pub n_atoms: usize,
    /// Atom dimension `K`.
    pub k: usize,
    /// Largest per-primitive sparsity `s`.
    pub sparsity: usize,
}

/// Rasterises `sct` at scale 1 and compares it with `original`; serialises with `options`
/// (with quantisation, the reconstruction measured is that of the bytes read back with
/// `registry`, so the quantisation error is included).
pub fn compression_report(
    original: &Heightfield,
    sct: &Sct,
    options: &FormatOptions,
    registry: &FunctionAtomRegistry,
) -> Result<CompressionReport> {
    let bytes = sct.to_bytes_with(options)?;
    let rec = if options.quantize_coefficients {
        Sct::from_bytes(&bytes, registry)?.rasterize(&RasterSettings::default())?
    } else {
        sct.rasterize(&RasterSettings::default())?
    };
    let (mut t, mut n_patches, mut n_atoms, mut k, mut s) = (0u64, 0, 0, 0, 0);
    for l in sct.layers() {
        let d = l.dictionary();
        t += layer_storage_values(d, l.len(), l.max_sparsity());
        n_patches += l.len();
        n_atoms += d.len();
        k = k.max(d.dim());
        s = s.max(l.max_sparsity());
    }
    let t0 = (original.width() * original.height()) as u64;
    Ok(CompressionReport {
        t0,
        t,
        rho: t as f64 / t0 as f64,
        bytes: bytes.len(),
        byte_ratio: bytes.len() as f64 / (4.0 * t0 as f64),
        psnr: metrics::psnr(original, &rec)?,
        rmse: metrics::rmse(original, &rec)?,
        n_patches,
        n_atoms,
        k,
        sparsity: s,
    })
}
