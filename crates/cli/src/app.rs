//! The `relief` command line (the binary's `main` is [`main`]): the clap definition, one
//! `match` that dispatches to `src/commands/<name>.rs` (each with a `pub(crate) struct Args`
//! and `pub(crate) fn run(args: Args, ctx: &Ctx) -> anyhow::Result<()>`), and the error
//! report: one line on stderr and a non-zero exit code. Output files are written atomically
//! by `relief-io`, so a failing command never leaves a partial file behind. It lives in the
//! library, not in `main.rs`, so that the fuzz target `cli_args` can drive the
//! argument-to-settings path without running a job ([`settings_from_args`]).
//!
//! ```text
//! relief info N47E011.hgt
//! relief convert alps_dem.tiff alps.exr --fill-voids
//! relief preview grandcanyon.tif grandcanyon.png
//! ```

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::ctx::Ctx;
use crate::{budget, commands, ctx, memory};

/// Terrain rasters on the command line: inspect, convert between formats, preview.
#[derive(Debug, Parser)]
#[command(name = "relief", version, about, long_about = None)]
struct Cli {
    /// No progress bars and no informational messages.
    #[arg(short, long, global = true)]
    quiet: bool,
    /// On error, print the whole cause chain.
    #[arg(short, long, global = true)]
    verbose: bool,
    /// Replace output files that already exist (never an input: a command refuses to write
    /// over any file it reads, --force or not).
    #[arg(long, global = true)]
    force: bool,
    /// Worker threads for the parallel parts (default: one per core). Outputs are identical
    /// whatever the count.
    #[arg(long, global = true, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    /// Compression of GeoTIFF outputs, lossless, with the floating-point predictor: deflate
    /// (GDAL's COMPRESS=DEFLATE PREDICTOR=3), zstd (COMPRESS=ZSTD, about as small, faster to
    /// read), lzw (COMPRESS=LZW, read everywhere, larger) or none.
    #[arg(long, global = true, value_enum, default_value_t = ctx::CompressArg::Deflate)]
    compress: ctx::CompressArg,
    /// Heights LO,HI (metres) mapped to counts 0 and 65535 in 16-bit heightmaps (.png, .r16);
    /// default: the data range. The range used is printed and written to OUT.json beside them.
    #[arg(long, global = true, value_name = "LO,HI", value_parser = crate::args::parse_height_range, allow_hyphen_values = true)]
    height_range: Option<(f64, f64)>,
    /// Write 16-bit heightmaps (.png, .r16) with one more row and column: the heights at the
    /// cell corners (the mean of the cells around each), over the same extent, so a 2^n x 2^n
    /// result becomes the 2^n+1 heightmap Unreal and Unity expect.
    #[arg(long, global = true)]
    size_plus_one: bool,
    /// Write GeoTIFF outputs as Cloud-Optimized GeoTIFFs: 512-pixel tiles, overviews down to
    /// one tile, directories first (compressed as --compress says).
    #[arg(long, global = true)]
    cog: bool,
    /// Largest working memory of a run (e.g. 8G, 512M): a run whose pre-flight estimate needs
    /// more is refused before it starts, naming the setting to change. Default: half of the
    /// physical memory (less under a cgroup limit or `ulimit -v`).
    #[arg(long, global = true, value_name = "SIZE", value_parser = memory::parse_limit)]
    max_memory: Option<memory::Limit>,
    /// Largest output a run may write (default 32G): a larger estimate is refused up front.
    #[arg(long, global = true, value_name = "SIZE", value_parser = memory::parse_size)]
    max_output_size: Option<u64>,
    /// Longest run time (e.g. 90s, 15m, 2h; `none`: no limit; default 30m). `decompress`,
    /// `volume` renders, `flow`, `masks` and `erode` time a small pilot of their work, print
    /// the estimate and refuse a longer run before starting it; any run (`relief run` and
    /// `tile run` included) still going at the limit is stopped there, writing nothing.
    #[arg(long, global = true, value_name = "DURATION", value_parser = budget::parse_time)]
    max_time: Option<budget::TimeLimit>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print format, size, cell size, elevation range, void count and georeference of a raster.
    Info(commands::info::Args),
    /// Convert a raster to another format (chosen from OUT's extension).
    Convert(commands::convert::Args),
    /// Write a shaded-relief preview PNG (hillshade blended with an elevation colour ramp).
    Preview(commands::preview::Args),
    /// Compress a terrain into a sparse construction tree (.sct): dictionary + Batch-OMP.
    Compress(commands::compress::Args),
    /// Rasterise a .sct at any scale or window into any raster format.
    Decompress(commands::decompress::Args),
    /// 3D landforms (sea caves, karst, hoodoos, arches, floating islands) on an implicit tree
    /// built from the DEM (paris2018); writes a mesh, a render and a vertical section.
    Volume(commands::volume::Args),
    /// Amplify a coarse terrain x4^k with the details of a high-resolution exemplar (sparse
    /// multi-resolution dictionary, guerin2016 5.3); writes a raster or a .sct model.
    Amplify(commands::amplify::Args),
    /// Learn a dictionary (K-SVD or constrained) from exemplar DEMs; `compress --dictionary`
    /// reads it.
    Learn(commands::learn::Args),
    /// Synthesise a terrain from a painted sketch and an exemplar (x4 steps, figure 12). By
    /// default the sketch is read as rock uplift: ridges and valleys are grown on it by
    /// landscape evolution, mapped onto the exemplar's elevation range, and the x4 steps add
    /// the exemplar's detail (which can reach past that range by its own amplitude); the
    /// output has the exemplar's cell size (the sketch is 4^steps times coarser).
    Synthesize(commands::synthesize::Args),
    /// Fit an analytic (noise-atom) model to a terrain, write it as .sct and print its PSNR.
    FitProcedural(commands::fit_procedural::Args),
    /// Add levels of detail by wavelet synthesis (GSA/LSA, Perez et al.); any window on demand.
    Refine(commands::refine::Args),
    /// Print the wavelet detail statistics: gamma and a per band, fractal dimension, plot.
    Analyze(commands::analyze::Args),
    /// Quilt a terrain from exemplar patches under a guide and categorisation map (cruz2015).
    Quilt(commands::quilt::Args),
    /// Check that the exemplars can synthesize a guide (cruz2015 section 4); non-zero if not.
    Validate(commands::validate::Args),
    /// Split amplify, refine or decompress into output tiles for job arrays (Slurm,
    /// Kubernetes Indexed Jobs): plan, run one task, status, mosaic.
    Tile(commands::tile::Args),
    /// Author a construction tree from JSON (layers, blend/add/max/min/replace, rivers and the
    /// paper's river sub-tree) into a .sct that `decompress` rasterises.
    Tree(commands::tree::Args),
    /// Drainage of a DEM: depressions filled or breached, flow directions, drainage area,
    /// Strahler order, watersheds, HAND and the channel network, written into a folder.
    Flow(commands::flow::Args),
    /// Texturing masks of a DEM (slope, curvatures, drainage area, wetness, HAND, height bands,
    /// erosion/deposition) as GeoTIFFs or PNGs, and an RGBA splat map of four weights.
    Masks(commands::masks::Args),
    /// Erode a DEM (stream power with uplift and diffusion, hydraulic, thermal) from a preset
    /// whose values every flag overrides; writes the terrain and optionally the net erosion and
    /// deposition depths.
    Erode(commands::erode::Args),
    /// Export a DEM as a game engine's heightmap (Unreal, Unity, Godot Terrain3D, Gaea): the
    /// engine's sizes, 16-bit PNG or raw in its row order, tiles that share their edges, the
    /// drainage masks as its layers, and an import sheet with the vertical scale.
    Export(commands::export::Args),
    /// Run a pipeline spec (JSON: input, stages, parameters) and write its rasters, previews,
    /// summary.json and report.html, as `cargo xtask pipeline SPEC.json` does.
    Run(commands::run::Args),
}

/// The `relief` binary: parses the command line, runs the subcommand, reports an error as
/// one line on stderr and a non-zero exit code.
pub fn main() -> ExitCode {
    Ctx::start_clock();
    let cli = Cli::parse();
    let ctx = Ctx {
        quiet: cli.quiet,
        verbose: cli.verbose,
        force: cli.force,
        compress: cli.compress,
        height_range: cli.height_range,
        size_plus_one: cli.size_plus_one,
        cog: cli.cog,
        max_memory: cli.max_memory.unwrap_or_else(memory::default_limit),
        max_output: memory::OutputLimit(cli.max_output_size.unwrap_or(memory::DEFAULT_MAX_OUTPUT)),
        max_time: cli.max_time.unwrap_or_default(),
    };
    if let Some(n) = cli.threads
        && let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(usize::from(n))
            .build_global()
    {
        ctx.report_error(&anyhow::anyhow!("cannot start {n} worker threads: {e}"));
        return ExitCode::FAILURE;
    }
    crate::interrupt::install(&ctx);
    let result = match cli.command {
        Command::Info(args) => commands::info::run(args, &ctx),
        Command::Convert(args) => commands::convert::run(args, &ctx),
        Command::Preview(args) => commands::preview::run(args, &ctx),
        Command::Compress(args) => commands::compress::run(args, &ctx),
        Command::Decompress(args) => commands::decompress::run(args, &ctx),
        Command::Volume(args) => commands::volume::run(args, &ctx),
        Command::Amplify(args) => commands::amplify::run(args, &ctx),
        Command::Learn(args) => commands::learn::run(args, &ctx),
        Command::Synthesize(args) => commands::synthesize::run(args, &ctx),
        Command::FitProcedural(args) => commands::fit_procedural::run(args, &ctx),
        Command::Refine(args) => commands::refine::run(args, &ctx),
        Command::Analyze(args) => commands::analyze::run(args, &ctx),
        Command::Quilt(args) => commands::quilt::run(args, &ctx),
        Command::Validate(args) => commands::validate::run(args, &ctx),
        Command::Tile(args) => commands::tile::run(args, &ctx),
        Command::Tree(args) => commands::tree::run(args, &ctx),
        Command::Flow(args) => commands::flow::run(args, &ctx),
        Command::Masks(args) => commands::masks::run(args, &ctx),
        Command::Erode(args) => commands::erode::run(args, &ctx),
        Command::Export(args) => commands::export::run(args, &ctx),
        Command::Run(args) => commands::run::run(args, &ctx),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            let err = if crate::budget::is_stopped(&err) {
                err.context(format!(
                    "stopped: the run took longer than {} (it is stopped at the limit, \
                     whatever the estimate); nothing was written",
                    ctx.max_time
                ))
            } else {
                err
            };
            ctx.report_error(&err);
            ExitCode::FAILURE
        }
    }
}

/// What [`settings_from_args`] found wrong with the mapping itself (not with the arguments):
/// the fuzz target `cli_args` treats an error carrying this text as a bug.
pub const MAPPING_BUG: &str = "argument-to-settings bug";

/// Parses a `relief` command line (`args[0]` is the program name) and maps it onto the checked
/// library settings its subcommand would run, without reading a file or starting any work:
/// the argument-to-settings path of every job command (amplify, synthesize, compress,
/// fit-procedural, refine, analyze, quilt, validate, volume, flow, masks, erode). Returns the settings as JSON,
/// `Ok(None)` for a command without job settings (info, convert, tile, ...), and an error for
/// arguments a user can get wrong. Every settings value is also sent through its JSON form
/// (what a `relief run` spec holds) and checked again: a value the command line accepts but
/// a spec could not express, or that reads back different, is an error naming
/// [`MAPPING_BUG`]. For the fuzz target `cli_args` and tests; `relief` itself does not call it.
#[doc(hidden)]
pub fn settings_from_args<I, T>(args: I) -> anyhow::Result<Option<serde_json::Value>>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    use anyhow::Context as _;
    let cli = Cli::try_parse_from(args).context("invalid command line")?;
    let ctx = Ctx {
        quiet: true,
        height_range: cli.height_range,
        ..Default::default()
    };
    fn json<S>(s: S, check: impl Fn(&S) -> anyhow::Result<()>) -> anyhow::Result<serde_json::Value>
    where
        S: serde::Serialize + serde::de::DeserializeOwned + PartialEq + std::fmt::Debug,
    {
        let v = serde_json::to_value(&s)
            .map_err(|e| anyhow::anyhow!("{MAPPING_BUG}: {s:?} has no JSON form: {e}"))?;
        let back: S = serde_json::from_value(v.clone())
            .map_err(|e| anyhow::anyhow!("{MAPPING_BUG}: {v} does not read back: {e}"))?;
        if back != s {
            anyhow::bail!("{MAPPING_BUG}: {s:?} reads back as {back:?}");
        }
        check(&back).map_err(|e| anyhow::anyhow!("{MAPPING_BUG}: {v} fails its check: {e}"))?;
        Ok(v)
    }
    let v = match cli.command {
        Command::Amplify(a) => json(commands::amplify::settings(&a)?, |s| Ok(s.check()?))?,
        Command::Synthesize(a) => json(commands::synthesize::settings(&a, &ctx)?, |s| {
            Ok(s.amplify.check()?)
        })?,
        Command::Compress(a) => json(a.settings()?, |s| Ok(s.check()?))?,
        Command::FitProcedural(a) => {
            json(commands::fit_procedural::settings(&a)?, |s| Ok(s.check()?))?
        }
        Command::Refine(a) => json(a.settings()?, |s| Ok(s.check()?))?,
        Command::Analyze(a) => json(commands::analyze::settings(&a)?, |s| Ok(s.check()?))?,
        Command::Quilt(a) => json(commands::quilt::job(&a)?, |s| Ok(s.check()?))?,
        Command::Validate(a) => json(a.synth.job()?, |s| Ok(s.check()?))?,
        Command::Volume(a) => json(commands::volume::job(&a)?, |s| Ok(s.check()?))?,
        Command::Flow(a) => json(commands::flow::settings(&a)?, |s| Ok(s.check()?))?,
        Command::Masks(a) => json(commands::masks::settings(&a)?, |s| Ok(s.check()?))?,
        Command::Erode(a) => json(commands::erode::settings(&a)?, |s| Ok(s.check()?))?,
        Command::Info(_)
        | Command::Convert(_)
        | Command::Preview(_)
        | Command::Decompress(_)
        | Command::Learn(_)
        | Command::Tile(_)
        | Command::Tree(_)
        | Command::Export(_)
        | Command::Run(_) => return Ok(None),
    };
    Ok(Some(v))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    fn settings(args: &str) -> anyhow::Result<Option<serde_json::Value>> {
        settings_from_args(std::iter::once("relief").chain(args.split_whitespace()))
    }

    #[test]
    fn arguments_map_onto_checked_settings_without_touching_files() {
        // The files need not exist: nothing is read.
        let v = settings("amplify /no/a.tif /no/c.tif --exemplar /no/b.tif --factor 16 --seed 7")
            .unwrap()
            .unwrap();
        assert_eq!(v["steps"], 2, "{v}");
        assert_eq!(v["seed"], 7, "{v}");
        let v = settings("refine /no/a.tif /no/b.tif --levels 3")
            .unwrap()
            .unwrap();
        assert_eq!(v["extra_levels"], 3, "{v}");
        let v = settings("volume /no/a.tif --features karst,arches --render /no/r.png")
            .unwrap()
            .unwrap();
        assert_eq!(v["render"], true, "{v}");
        // Meshes are simplified to 2 M triangles unless asked otherwise; 0 keeps them all.
        assert_eq!(v["max_triangles"], 2_000_000, "{v}");
        let v = settings("volume /no/a.tif --mesh /no/m.glb --max-triangles 0")
            .unwrap()
            .unwrap();
        assert!(v["max_triangles"].is_null(), "{v}");
        assert!(settings("info /no/a.tif").unwrap().is_none());
        let v = settings("validate --guide /g --exemplar /e --min-candidates-share 0.05")
            .unwrap()
            .unwrap();
        assert!((v["settings"]["min_candidates_share"].as_f64().unwrap() - 0.05).abs() < 1e-6);
        let lowpass = |flag: &str| {
            settings(&format!("quilt /o.tif --guide /g --exemplar /e {flag}"))
                .unwrap()
                .unwrap()["settings"]["guide_lowpass"]
                .clone()
        };
        assert!(lowpass("").is_null());
        assert!(lowpass("--guide-lowpass auto").is_null());
        assert_eq!(lowpass("--guide-lowpass 0"), 0.0);
        assert_eq!(lowpass("--guide-lowpass 12.5"), 12.5);
        // The seed command lines of the fuzz target `cli_args` (fuzz/seeds/cli_args).
        for good in [
            "amplify /a.tif /o.sct --exemplar /b.tif --factor 4 --paper --atoms 64",
            "synthesize /s.tif /o.tif --exemplar /e.tif --x4-steps 3",
            "compress /a.tif /o.sct --sparsity 4",
            "fit-procedural /a.tif /o.sct --family perlin",
            "refine /a.tif /o.tif --levels 2 --method lsa",
            "analyze /a.tif --local 5 --plot-levels 6",
            "quilt /o.tif --guide /g.tif --exemplar /e.tif --patch-size 32 --reuse-penalty 0.5",
            "validate --guide /g.tif --exemplar /e.tif",
            "volume /a.tif --features karst,arches,sea --render /r.png --image-size 640x480",
            "flow /a.tif -o /out --depressions breach --directions mfd --channel-area 2e5",
            "masks /a.tif -o /out --format png16 --height-bands 1000,2000 --rock-slope 40",
            "erode /a.tif -o /o.tif --preset badlands --years 2e4 --uplift 1e-4 --weathering -1",
            "erode /a.tif -o /o.tif --talus-angle 30 --fill-pits false",
        ] {
            let v = settings(good)
                .map_err(|e| format!("{good}: {e:#}"))
                .unwrap();
            assert!(v.is_some_and(|v| v.is_object()), "{good}");
        }
        // Bad values are argument errors naming the flag, never mapping bugs.
        for bad in [
            "amplify /a /c --exemplar /b --factor 5",
            "refine /a /b --levels 0",
            "volume /a --features lava --render /r.png",
            "volume /a --render /r.png --resolution nan",
            "analyze /a --plot-levels 99",
            "quilt --guide /g --exemplar /e /o.tif --patch-size 0",
            "validate --guide /g --exemplar /e --min-candidates-share 1.5",
            "quilt --guide /g --exemplar /e /o.tif --guide-lowpass -3",
            "quilt --guide /g --exemplar /e /o.tif --guide-lowpass wide",
            "flow /a -o /out --channel-area -1",
            "flow /a -o /out --depressions lake",
            "masks /a -o /out --height-bands 2000,1000",
            "masks /a -o /out --rock-slope 95",
            "erode /a -o /o.tif --talus-angle 95",
            "erode /a -o /o.tif --rain -1",
            "erode /a -o /o.tif --preset glacier",
            "erode /a -o /o.tif --uplift 0.5",
        ] {
            let e = format!("{:#}", settings(bad).unwrap_err());
            assert!(!e.contains(MAPPING_BUG), "{bad}: {e}");
            assert!(
                e.contains("--") || e.contains('`'),
                "names no flag or field: {bad}: {e}"
            );
        }
    }

    /// The flag table of `docs/CLI.md`, generated from the clap definition.
    fn flag_table() -> String {
        let cmd = Cli::command();
        let mut s = String::from(
            "# `relief` flags\n\nGenerated from the clap definition by the test \
             `tests::cli_doc_is_current` (`RELIEF_BLESS_CLI_DOC=1 cargo test -p relief-cli \
             cli_doc` rewrites it). One name, one meaning, in every subcommand.\n\n\
             ## Global flags\n\n| flag | value | meaning |\n|---|---|---|\n",
        );
        let row = |a: &clap::Arg| -> Option<String> {
            let long = a.get_long()?;
            let value = a
                .get_value_names()
                .map(|v| v.iter().map(|n| n.as_str()).collect::<Vec<_>>().join(" "))
                .filter(|_| a.get_action().takes_values())
                .unwrap_or_default();
            let help = a
                .get_help()
                .map(|h| h.to_string())
                .unwrap_or_default()
                .replace('|', "\\|")
                .replace('\n', " ");
            Some(format!("| `--{long}` | {value} | {help} |\n"))
        };
        for a in cmd.get_arguments().filter(|a| a.is_global_set()) {
            s.extend(row(a));
        }
        // Subcommands, and their own subcommands (`relief tile plan`).
        let mut subs: Vec<(String, &clap::Command)> = Vec::new();
        for sub in cmd.get_subcommands() {
            subs.push((sub.get_name().to_string(), sub));
            for inner in sub.get_subcommands() {
                subs.push((format!("{} {}", sub.get_name(), inner.get_name()), inner));
            }
        }
        for (name, sub) in subs {
            s.push_str(&format!(
                "\n## `relief {name}`\n\n| flag | value | meaning |\n|---|---|---|\n"
            ));
            for a in sub.get_arguments().filter(|a| !a.is_global_set()) {
                s.extend(row(a));
            }
        }
        s
    }

    #[test]
    fn cli_doc_is_current() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/CLI.md");
        let want = flag_table();
        if std::env::var_os("RELIEF_BLESS_CLI_DOC").is_some() {
            std::fs::write(&path, &want).unwrap();
        }
        let have = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            have == want,
            "docs/CLI.md is out of date: RELIEF_BLESS_CLI_DOC=1 cargo test -p relief-cli cli_doc"
        );
    }
}
