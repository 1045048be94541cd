//! `relief learn EXEMPLAR... OUT.dict`: learns a dictionary from the patches of one or more
//! exemplar DEMs (guerin2016 section 4.4): K-SVD (problem (1), approximate or exact rank-1
//! update) or constrained learning (problem (2): every atom is one of the terrain patches).
//! The file is read by `relief compress --dictionary OUT.dict`.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use relief_dictionary_learning::{
    ConstrainedSettings, KsvdSettings, KsvdVariant, constrained_learning, ksvd, subsample_rows,
    training_patches,
};
use relief_heightfield::Heightfield;
use relief_sparse_core::{Dictionary, PatchGeometry};

use crate::ctx::Ctx;

/// Arguments of `relief learn`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// One or more exemplar rasters (no voids), then the output dictionary file (`.dict`).
    #[arg(required = true, num_args = 2.., value_name = "EXEMPLAR... OUT")]
    pub(crate) paths: Vec<PathBuf>,
    /// Number of atoms N.
    #[arg(short = 'n', long, default_value_t = KsvdSettings::default().n_atoms)]
    pub(crate) atoms: usize,
    /// Sparsity s of the coding step.
    #[arg(short, long, default_value_t = KsvdSettings::default().sparsity)]
    pub(crate) sparsity: usize,
    /// Patch side a in samples (K = a^2).
    #[arg(short = 'a', long, default_value_t = 8)]
    pub(crate) patch_size: usize,
    /// Step between patch centres in cells of the exemplars (default: half the patch side).
    #[arg(long)]
    pub(crate) step: Option<f64>,
    /// Learning iterations.
    #[arg(long, default_value_t = KsvdSettings::default().iterations)]
    pub(crate) iterations: usize,
    /// Atom update: `approximate` (one power iteration) or `exact` (rank-1 SVD).
    #[arg(long, default_value = "approximate")]
    pub(crate) variant: String,
    /// Constrained learning: every atom is one of the exemplar patches (problem (2)).
    #[arg(long)]
    pub(crate) constrained: bool,
    /// Largest number of training patches (evenly subsampled beyond it).
    #[arg(long, default_value_t = 30_000)]
    pub(crate) max_patches: usize,
    /// Seed of the initialisation.
    #[arg(long, default_value_t = KsvdSettings::default().seed)]
    pub(crate) seed: u64,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

/// Reads the exemplars, learns, writes the dictionary, prints a summary on stdout.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let Some((output, exemplars)) = args.paths.split_last() else {
        bail!("give at least one exemplar and the output file");
    };
    if exemplars.is_empty() {
        bail!("give at least one exemplar before the output file");
    }
    let inputs: Vec<&std::path::Path> = exemplars.iter().map(|p| p.as_path()).collect();
    ctx.check_outputs(&inputs, &[(output, crate::outputs::OutKind::Dict)])?;
    let variant = match args.variant.to_ascii_lowercase().as_str() {
        "approximate" | "approx" => KsvdVariant::Approximate,
        "exact" | "svd" => KsvdVariant::Exact,
        v => bail!("invalid --variant `{v}`: must be approximate or exact"),
    };
    let geometry = PatchGeometry {
        step: args.step.unwrap_or(args.patch_size as f64 / 2.0),
        ..PatchGeometry::with_patch_size(args.patch_size)
    };
    geometry
        .check()
        .with_context(|| format!("invalid patch geometry (--patch-size {})", args.patch_size))?;
    let mut terrains: Vec<Heightfield> = Vec::with_capacity(exemplars.len());
    for path in exemplars {
        let hf = super::read_raster(path, &args.read, ctx)?.heightfield;
        hf.require_complete()
            .with_context(|| format!("cannot learn from {}", path.display()))?;
        terrains.push(hf);
    }
    crate::commands::preflight::learn(&terrains, &geometry, &args, ctx)?;
    let refs: Vec<&Heightfield> = terrains.iter().collect();
    let all =
        training_patches(&refs, &geometry).context("cannot cut the exemplars into patches")?;
    let n_all = all.nrows();
    // Even subsampling (deterministic, spread over every exemplar).
    let patches = subsample_rows(all.view(), args.max_patches).context("invalid --max-patches")?;
    let progress = ctx.progress();
    let learned = if args.constrained {
        constrained_learning(
            patches.view(),
            patches.view(),
            &ConstrainedSettings {
                n_atoms: args.atoms,
                sparsity: args.sparsity,
                iterations: args.iterations,
                seed: args.seed,
            },
            &progress,
        )
    } else {
        ksvd(
            patches.view(),
            &KsvdSettings {
                n_atoms: args.atoms,
                sparsity: args.sparsity,
                iterations: args.iterations,
                variant,
                seed: args.seed,
                ..Default::default()
            },
            &progress,
        )
    }
    .context("cannot learn the dictionary")?;
    drop(progress);
    let dict = Dictionary::from_matrix(
        learned.atoms.view(),
        geometry.patch_size,
        geometry.spacing,
        geometry.support_radius,
    )
    .context("cannot build the dictionary")?;
    let bytes = dict.to_bytes().context("cannot serialise the dictionary")?;
    relief_io::write_bytes_atomic(output, &bytes)
        .with_context(|| format!("cannot write {}", output.display()))?;
    let first = learned.trace.first().map_or(f64::NAN, |t| t.rmse);
    let last = learned.trace.last().map_or(f64::NAN, |t| t.rmse);
    let replaced: usize = learned.trace.iter().map(|t| t.replaced).sum();
    let mut out = String::new();
    out.push_str(&format!(
        "dictionary:  N = {} atoms of {a} x {a} (K = {}), {} from {} patches ({} used) of {} \
         exemplar(s)\n",
        dict.len(),
        dict.dim(),
        if args.constrained {
            "constrained learning".to_string()
        } else {
            format!("K-SVD ({variant:?})")
        },
        n_all,
        patches.nrows(),
        exemplars.len(),
        a = geometry.patch_size,
    ));
    out.push_str(&format!(
        "fit:         rmse {first:.3} m -> {last:.3} m over {} iterations, s = {} ({replaced} \
         atoms replaced)\n",
        args.iterations, args.sparsity
    ));
    out.push_str(&format!(
        "wrote:       {} ({} bytes)\n",
        output.display(),
        bytes.len()
    ));
    crate::staging::print(&out)
}
