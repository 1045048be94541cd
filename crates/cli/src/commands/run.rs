//! `relief run SPEC.json [--out DIR]`: runs a pipeline spec (the stages `cargo xtask pipeline`
//! runs, same JSON, same `summary.json` and `report.html`) with the installed binary.
//!
//! Relative paths in the spec are relative to the spec file. The run writes into a hidden
//! staging folder beside DIR, and only when every stage succeeded does that folder become DIR
//! (renames: an earlier run's DIR is set aside, then removed), so a failed run leaves DIR as it
//! was and a successful one leaves only its own files.

use std::path::{Path, PathBuf};

use crate::pipeline::{self, PipelineConfig, spec::PipelineSpec};
use anyhow::{Context, Result, bail};

use crate::ctx::Ctx;

/// Arguments of `relief run`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Pipeline spec (JSON; see docs/PIPELINE.md and docs/pipeline-chain.example.json).
    pub(crate) spec: PathBuf,
    /// Output folder for rasters, previews, summary.json and report.html (default: SPEC's
    /// name without `.json`, plus `.out`, beside SPEC). It must be empty or new (or --force:
    /// an earlier run's folder is then replaced as a whole, only if this run succeeds).
    #[arg(long, value_name = "DIR")]
    pub(crate) out: Option<PathBuf>,
    /// Input DEM, replacing the spec's `input`.
    #[arg(long, value_name = "FILE")]
    pub(crate) input: Option<PathBuf>,
    /// Seed of every stochastic stage, replacing the spec's `seed`.
    #[arg(long)]
    pub(crate) seed: Option<u64>,
}

/// Reads the spec, runs it in a staging folder, moves the results into place.
pub(crate) fn run(args: Args, ctx: &Ctx) -> Result<()> {
    let spec = PipelineSpec::read(&args.spec)?;
    let out = args.out.clone().unwrap_or_else(|| default_out(&args.spec));
    let mut config = PipelineConfig::new(PathBuf::new(), out.clone());
    spec.apply(&mut config);
    if let Some(input) = &args.input {
        config.input = input.clone();
    }
    if let Some(seed) = args.seed {
        config.seed = seed;
    }
    if config.input.as_os_str().is_empty() {
        bail!(
            "{} names no `input` DEM: add one to the spec or pass --input FILE",
            args.spec.display()
        );
    }
    if !config.input.is_file() {
        bail!("input DEM {} does not exist", config.input.display());
    }
    config.verbose = !ctx.quiet;
    // The global limits hold for the whole run: each stage's pre-flight against
    // --max-memory, and --max-time as a deadline its long loops and the stage loop ask.
    config.limits = pipeline::RunLimits {
        max_memory: Some(ctx.max_memory.bytes),
        deadline: ctx.deadline(),
    };
    check_out_dir(&out, &[&args.spec, &config.input], ctx.force)?;
    let stages = pipeline::spec::build_stages(&spec.stages)?;

    let parent = crate::outputs::parent_folder(&out);
    // A new folder of an unpredictable name, created exclusively: a planted or stale folder
    // (or a link to one) is never adopted, so only what this run writes is moved into --out.
    let staged = relief_io::create_staging_dir(parent)
        .with_context(|| format!("cannot create a staging folder in {}", parent.display()))?;
    let _cleanup = RemoveOnDrop(staged.clone());
    config.out_dir = staged.clone();
    let run = pipeline::run(&config, &stages)?;
    swap_in(&staged, &out, parent)?;
    ctx.note(format!(
        "ran {} stages in {:.1} s; report: {}",
        run.stage_count,
        run.seconds,
        out.join("report.html").display()
    ));
    Ok(())
}

/// Puts the finished staging folder `staged` in place as `out`, all or nothing: a new `out`
/// is one rename (which fails if another run created a non-empty `out` meanwhile: that run
/// keeps it); an existing `out` (an earlier run's, replaced under `--force`, or an empty
/// folder) is first renamed aside to a fresh hidden name in `parent`, then `staged` takes its
/// name and the earlier run is removed; if that second rename fails, the earlier run is
/// renamed back. No file of the earlier run is mixed with this run's.
fn swap_in(staged: &Path, out: &Path, parent: &Path) -> Result<()> {
    let moved = |e: std::io::Error| {
        anyhow::Error::new(e).context(format!("cannot move the result into {}", out.display()))
    };
    if std::fs::symlink_metadata(out).is_err() {
        return std::fs::rename(staged, out).map_err(moved);
    }
    // A fresh, exclusively made folder to park the earlier run in (the rename replaces it,
    // empty). Not a staging name: neither the stale-temporary cleaner nor the interrupt
    // handler may ever remove an earlier run that a crash left parked there.
    let aside = parent.join(format!(
        ".relief-earlier-run-{}-{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos())
    ));
    std::fs::create_dir(&aside).with_context(|| {
        format!(
            "cannot create {} to set the earlier run aside",
            aside.display()
        )
    })?;
    if let Err(e) = std::fs::rename(out, &aside) {
        let _ = std::fs::remove_dir(&aside);
        return Err(moved(e));
    }
    if let Err(e) = std::fs::rename(staged, out) {
        // Put the earlier run back; it was not touched.
        let _ = std::fs::rename(&aside, out);
        return Err(moved(e));
    }
    let _ = std::fs::remove_dir_all(&aside);
    Ok(())
}

/// `dir/name.out` for a spec `dir/name.json`.
fn default_out(spec: &Path) -> PathBuf {
    let stem = spec
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "pipeline".into());
    spec.with_file_name(format!("{stem}.out"))
}

/// The output folder must not hold an input (the run would write over it) and must be new or
/// empty unless `--force`.
fn check_out_dir(out: &Path, inputs: &[&Path], force: bool) -> Result<()> {
    if out.exists() && !out.is_dir() {
        bail!("--out {} exists and is not a folder", out.display());
    }
    if let Ok(out_abs) = out.canonicalize() {
        for input in inputs {
            if let Ok(abs) = input.canonicalize()
                && abs.starts_with(&out_abs)
            {
                bail!(
                    "--out {} holds the input {}: the run would write over its inputs; choose \
                     another output folder",
                    out.display(),
                    input.display()
                );
            }
        }
        let non_empty = std::fs::read_dir(out)
            .with_context(|| format!("cannot read {}", out.display()))?
            .next()
            .is_some();
        if non_empty && !force {
            bail!(
                "--out {} is not empty: pass --force to replace the files of an earlier run",
                out.display()
            );
        }
    }
    Ok(())
}

/// Removes the staging folder whatever happens.
#[derive(Debug)]
struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
