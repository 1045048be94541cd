//! `cargo xtask <command>`: workspace automation (matklad's cargo-xtask pattern).
//!
//! * `cargo xtask pipeline [SPEC.json] [--out DIR]`: runs every pipeline stage (or a spec's) on the bundled fixture DEM and
//!   writes rasters, previews, `summary.json` and `report.html` (default `target/pipeline/`).
//! * `cargo xtask golden [--bless]`: runs the pipeline on a small crop with a fixed thread count
//!   and compares its raster outputs with `fixtures/golden/` (max-abs and RMSE in metres).
//!   The same check is a `#[test]` (`golden::tests`), so `cargo test --workspace` runs it.
//! * `cargo xtask bench`: criterion benches of `relief-benches` plus the Python peers, written
//!   to `target/bench/dashboard.{json,html}`.
#![allow(clippy::print_stdout, clippy::print_stderr)]

use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand};
use relief_pipeline as pipeline;

mod bench;
mod claims;
mod cycles;
mod golden;
mod tidy;

/// Workspace automation for relief.
#[derive(Debug, Parser)]
#[command(name = "xtask", about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run every stage on the bundled fixture DEM (or the stages of SPEC) and write the report.
    Pipeline {
        /// A JSON pipeline spec (see docs/pipeline-spec.example.json); default: every stage.
        spec: Option<PathBuf>,
        /// Output directory (default: target/pipeline).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Input DEM (default: fixtures/grandcanyon.tif).
        #[arg(long)]
        input: Option<PathBuf>,
    },
    /// Compare the pipeline's raster outputs with fixtures/golden/.
    Golden {
        /// Overwrite the goldens with the current outputs (read fixtures/golden/README.md first).
        #[arg(long)]
        bless: bool,
    },
    /// Run the criterion benches and the Python peers; write target/bench/dashboard.{json,html}.
    Bench {
        /// Skip `cargo bench` and use the criterion results already under target/criterion.
        #[arg(long)]
        no_cargo: bool,
        /// Skip the Python peers.
        #[arg(long)]
        no_peers: bool,
        /// Passed to criterion as a filter (only matching benchmarks run).
        #[arg(long)]
        filter: Option<String>,
    },
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Pipeline { spec, out, input } => {
            let root = project_root();
            let mut config = pipeline::PipelineConfig::full(&root);
            let stages = match spec {
                Some(path) => {
                    let spec = pipeline::spec::PipelineSpec::read(&path)?;
                    spec.apply(&mut config);
                    pipeline::spec::build_stages(&spec.stages)?
                }
                None => pipeline::default_stages(),
            };
            if let Some(out) = out {
                config.out_dir = out;
            }
            if let Some(input) = input {
                config.input = input;
            }
            let run = pipeline::run(&config, &stages)?;
            eprintln!(
                "pipeline: {} stages in {:.1} s; report: {}",
                run.stage_count,
                run.seconds,
                config.out_dir.join("report.html").display()
            );
        }
        Command::Golden { bless } => {
            let outcome = golden::check(&project_root(), bless)?;
            eprintln!("{outcome}");
        }
        Command::Bench {
            no_cargo,
            no_peers,
            filter,
        } => {
            let opts = bench::BenchOptions {
                run_cargo: !no_cargo,
                run_peers: !no_peers,
                filter,
            };
            let dash = bench::run(&project_root(), &opts)?;
            eprintln!("bench: dashboard at {}", dash.display());
        }
    }
    Ok(())
}

/// The workspace root (the parent of this crate's folder).
pub(crate) fn project_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives one level below the workspace root")
        .to_path_buf()
}

/// Cargo's target directory (`$CARGO_TARGET_DIR` or `<root>/target`).
pub(crate) fn target_dir(root: &Path) -> PathBuf {
    relief_pipeline::target_dir(root)
}
