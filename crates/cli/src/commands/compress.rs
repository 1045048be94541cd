//! `relief compress IN OUT.sct`: the compact representation of guerin2016 section 5.1. The
//! terrain is cut into disk-supported patches on a regular grid, each patch is coded with
//! Batch-OMP on a dictionary (`s` atoms), and the Sparse Construction Tree is written as a
//! versioned `.sct` file. Prints the paper's storage `t(s, N) = KN + n(2s + 2) + 1`, `rho`,
//! the real file size and the PSNR of the reconstruction.
//!
//! ```text
//! relief compress grandcanyon.tif gc.sct --sparsity 2 --atoms 128
//! relief compress alps.tif alps.sct --dictionary alps.dict --quantize
//! relief compress dem.tif dem.sct --dict complete --sparsity 1   # every patch an atom
//! ```

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use relief_dictionary_learning::{AnalyticAtoms, CompressSettings, DictionarySource};
use relief_sparse_core::Dictionary;

use crate::ctx::Ctx;
use crate::describe;
use crate::sparse_model::{read_model_bytes, registry};

/// Where the dictionary comes from when no `--dictionary FILE` is given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum DictSource {
    /// K-SVD (approximate) learned on the input's own patches (section 4.4).
    Ksvd,
    /// `--atoms` patches of the input picked evenly (no learning).
    Sample,
    /// Every patch is its own atom (section 4.3): exact with `s = 1`, but `N = n` atoms.
    Complete,
}

/// Arguments of `relief compress`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Input raster (any format relief reads).
    pub(crate) input: PathBuf,
    /// Output `.sct` file (written atomically).
    pub(crate) output: PathBuf,
    /// Sparsity `s`: atoms per primitive (1..=64, at most the number of atoms).
    #[arg(short, long, default_value_t = CompressSettings::default().sparsity)]
    pub(crate) sparsity: usize,
    /// Number of atoms `N` of a learned or sampled dictionary.
    #[arg(short = 'n', long, default_value_t = CompressSettings::default().atoms)]
    pub(crate) atoms: usize,
    /// Dictionary source when no `--dictionary FILE` is given [default: ksvd].
    #[arg(long = "dict", value_enum)]
    pub(crate) dict: Option<DictSource>,
    /// Dictionary file saved by `relief learn` (its patch size, spacing and radius are used;
    /// not with --dict, --patch-size, --spacing or --radius).
    #[arg(long)]
    pub(crate) dictionary: Option<PathBuf>,
    /// Patch side `a` in samples (`K = a^2`) [default: 8].
    #[arg(short = 'a', long)]
    pub(crate) patch_size: Option<usize>,
    /// Sample spacing `delta` of the patches, in cells [default: 1].
    #[arg(long)]
    pub(crate) spacing: Option<f64>,
    /// Support radius `R` in cells of the input (default: half the patch width, `a delta / 2`).
    #[arg(long)]
    pub(crate) radius: Option<f64>,
    /// Step between primitive centres in cells of the input (default: half the patch width).
    #[arg(long)]
    pub(crate) step: Option<f64>,
    /// Stop a patch's OMP early once its squared residual is at most this, in m^2 (a sum over
    /// the patch's samples; not quilt's RMS --tolerance in metres; --tolerance is an alias).
    #[arg(
        long = "residual-tolerance",
        visible_alias = "tolerance",
        value_name = "M2"
    )]
    pub(crate) tolerance: Option<f64>,
    /// Store coefficients as 16-bit integers (smaller file, slightly lower PSNR).
    #[arg(long)]
    pub(crate) quantize: bool,
    /// K-SVD iterations (with `--dict ksvd`).
    #[arg(long, default_value_t = CompressSettings::default().iterations)]
    pub(crate) iterations: usize,
    /// Seed of the K-SVD initialisation (with `--dict ksvd`).
    #[arg(long, default_value_t = CompressSettings::default().seed)]
    pub(crate) seed: u64,
    /// Append random analytic atoms to the data dictionary, `FAMILY:N,...` with FAMILY one of
    /// `ridged` (sums of ridged noise, figure 4), `perlin`, `ridged-multifractal`,
    /// `ridged-field`, `perlin-field` (windows of one noise field at terrain scale): a mixed
    /// dictionary whose OMP picks data or analytic atoms per primitive (figure 14).
    #[arg(long, value_name = "FAMILY:N,..", value_parser = crate::args::parse_analytic_atoms)]
    pub(crate) analytic_atoms: Option<AnalyticAtoms>,
    /// With `--sparsity 1` and more than 4096 atoms (`--dict complete` on a large DEM): clusters
    /// of the atom index searched per patch; 0 = the exact search (about 15x slower at 65,536
    /// atoms).
    #[arg(long, default_value_t = CompressSettings::default().index_probes)]
    pub(crate) index_probes: usize,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

impl Args {
    /// The job settings of the flags (checked).
    pub(crate) fn settings(&self) -> Result<CompressSettings> {
        let d = CompressSettings::default();
        let s = CompressSettings {
            sparsity: self.sparsity,
            atoms: self.atoms,
            source: match self.dict.unwrap_or(DictSource::Ksvd) {
                DictSource::Ksvd => DictionarySource::Ksvd,
                DictSource::Sample => DictionarySource::Sample,
                DictSource::Complete => DictionarySource::Complete,
            },
            patch_size: self.patch_size.unwrap_or(d.patch_size),
            spacing: self.spacing.unwrap_or(d.spacing),
            radius: self.radius,
            step: self.step,
            tolerance: self.tolerance,
            quantize: self.quantize,
            iterations: self.iterations,
            seed: self.seed,
            analytic_atoms: self.analytic_atoms.unwrap_or_default(),
            index_probes: self.index_probes,
        };
        if self.dictionary.is_some() && self.analytic_atoms.is_some() {
            anyhow::bail!(
                "--analytic-atoms adds to a dictionary this command makes, not to --dictionary"
            );
        }
        s.check().context("invalid compress settings")?;
        Ok(s)
    }
}

/// The dictionary of `--dictionary FILE`, if given (it fixes the atoms: `--dict`,
/// `--patch-size`, `--spacing` and `--radius` are refused with it).
fn given_dictionary(args: &Args, ctx: &Ctx) -> Result<Option<(Dictionary, String)>> {
    let Some(path) = &args.dictionary else {
        return Ok(None);
    };
    for (given, name) in [
        (args.dict.is_some(), "--dict"),
        (args.patch_size.is_some(), "--patch-size"),
        (args.spacing.is_some(), "--spacing"),
        (args.radius.is_some(), "--radius"),
    ] {
        if given {
            bail!("{name} cannot be used with --dictionary (the file fixes the atoms)");
        }
    }
    let bytes = read_model_bytes(path, ctx)?;
    let d = Dictionary::from_bytes(&bytes, &registry())
        .with_context(|| format!("cannot read the dictionary {}", path.display()))?;
    if d.is_empty() {
        bail!("the dictionary {} holds no atom", path.display());
    }
    Ok(Some((d, format!("file {}", path.display()))))
}

/// Reads, (fills,) learns or loads a dictionary, encodes, writes the `.sct`, prints the figures.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let job = args.settings()?;
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(args.dictionary.as_deref());
    ctx.check_outputs(&inputs, &[(&args.output, crate::outputs::OutKind::Sct)])?;
    let raster = super::read_raster(&args.input, &args.read, ctx)?;
    let hf = raster.heightfield;
    // `--fill-voids` (ReadArgs) filled them on reading; without it voids are an error.
    if hf.has_voids() {
        bail!(
            "{} has {} void cells: pass --fill-voids to fill them first",
            args.input.display(),
            hf.void_count()
        );
    }
    crate::commands::preflight::compress(&args, &hf, ctx)?;
    let given = given_dictionary(&args, ctx)?;
    let progress = ctx.progress();
    let out = job
        .run(&hf, given, &progress)
        .context("cannot compress the terrain")?;
    drop(progress);
    relief_io::write_bytes_atomic(&args.output, &out.bytes)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    let mut text = describe::compression(&args.input, &hf, &job, &out.figures);
    text.push_str(&format!("wrote:       {}\n", args.output.display()));
    #[allow(clippy::print_stdout)]
    {
        print!("{text}");
    }
    Ok(())
}
