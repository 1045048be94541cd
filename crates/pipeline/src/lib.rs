//! The pipeline: an ordered list of [`Stage`]s run on one DEM, each writing its rasters,
//! previews, figures and tables into a shared [`Report`].
//!
//! # Adding a stage
//! 1. Create `crates/pipeline/src/<name>.rs` with a struct implementing [`Stage`]:
//!    `run(&self, cx: &mut StageCx)`. Read the current terrain with [`State::terrain`], replace
//!    it with [`State::set_terrain`] when the stage produces the next terrain (stages compose:
//!    the output of one is the input of the next), save every raster with
//!    [`StageCx::save_raster`] (GeoTIFF f32 + preview PNG, and a golden candidate with its
//!    tolerance), and put numbers into `cx.section` (`figure`, `table`, `image`).
//! 2. Add `mod <name>;` below and register it in `spec.rs` (one entry of its `REGISTRY`: the
//!    stage's name, at its place in the default run, and how it is built). A stage with
//!    parameters is its parameter struct: it derives `Serialize + Deserialize + Default`
//!    (`#[serde(default, deny_unknown_fields)]`, its method settings in a `job` field of the
//!    method crate's serde type) so a user's JSON spec can set them (merged onto its defaults),
//!    and implements `spec::StageParams` (the checks run when the spec is built).
//! 3. If the stage saves rasters with a tolerance, run `cargo xtask golden --bless` once and
//!    commit the new files in `fixtures/golden/` (keep them small: the golden run is a crop).

// Application code: stage progress goes to stderr when `PipelineConfig::verbose` is set.
#![allow(clippy::print_stderr)]

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use relief_heightfield::{Heightfield, Progress};

pub mod change;
pub mod channels;
mod convert;
mod dictionary;
mod erode;
mod fill;
mod flow;
mod load;
mod quilt;
pub mod report;
mod sparse;
pub mod spec;
mod volume;
pub mod volume_window;
mod wavelet;

pub use report::{Report, Section};
pub use spec::NamedStage;

/// What to run on and where to write.
#[derive(Debug, Clone)]
pub struct PipelineConfig {
    /// Input DEM (any format relief-io reads).
    pub input: PathBuf,
    /// Optional crop `(x, y, w, h)` applied right after loading.
    pub crop: Option<(usize, usize, usize, usize)>,
    /// Output directory (created if missing).
    pub out_dir: PathBuf,
    /// Seed handed to every stochastic stage (each stage derives its own stream from it).
    pub seed: u64,
    /// Write preview PNGs (the golden run skips them).
    pub previews: bool,
    /// Print per-stage progress on stderr.
    pub verbose: bool,
    /// Folder that relative paths in stage parameters (and the default fixtures a stage reads,
    /// such as `fixtures/volcano.json`) are resolved against: the spec file's folder.
    pub base_dir: PathBuf,
    /// The run's limits (`relief run --max-memory / --max-time`; none by default).
    pub limits: RunLimits,
}

/// Limits of a pipeline run: `relief run` passes its `--max-memory` and `--max-time`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunLimits {
    /// Largest working memory a stage's pre-flight estimate may reach, bytes.
    pub max_memory: Option<u64>,
    /// When the run must be over: stages stop (their long loops ask the progress sink) and
    /// the run ends with an error.
    pub deadline: Option<Instant>,
}

impl RunLimits {
    /// Refuses a stage whose estimated working memory `bytes` exceeds `max_memory`, naming
    /// the `parameters` that make it smaller.
    pub fn check_memory(&self, stage: &str, bytes: f64, parameters: &str) -> Result<()> {
        if let Some(max) = self.max_memory
            && (bytes.is_nan() || bytes > max as f64)
        {
            bail!(
                "stage `{stage}` needs about {} of working memory, more than --max-memory {}: \
                 use {parameters}, or raise --max-memory",
                human_bytes(bytes as u64),
                human_bytes(max)
            );
        }
        Ok(())
    }

    /// Whether the run is past its deadline.
    pub fn past_deadline(&self) -> bool {
        self.deadline.is_some_and(|d| Instant::now() >= d)
    }
}

impl PipelineConfig {
    /// A run on `input` writing into `out_dir`, with the default seed, previews and progress.
    pub fn new(input: PathBuf, out_dir: PathBuf) -> Self {
        let base_dir = input
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("."));
        Self {
            input,
            crop: None,
            out_dir,
            seed: 0x5eed_2024,
            previews: true,
            verbose: true,
            base_dir,
            limits: RunLimits::default(),
        }
    }

    /// The default run of the workspace at `root`: the whole bundled fixture into
    /// `target/pipeline/`.
    pub fn full(root: &Path) -> Self {
        Self {
            base_dir: root.to_path_buf(),
            ..Self::new(
                root.join("fixtures/grandcanyon.tif"),
                target_dir(root).join("pipeline"),
            )
        }
    }

    /// Where a relative path named by a spec or a stage lives: beside the spec
    /// ([`PipelineConfig::base_dir`]) when it exists there, else in the workspace this binary
    /// was built from (so `fixtures/...` works from a checkout), else beside the spec (the
    /// error then names that path). Absolute paths are returned as they are.
    pub fn resolve(&self, path: &Path) -> PathBuf {
        if path.is_absolute() {
            return path.to_path_buf();
        }
        let beside = self.base_dir.join(path);
        if beside.exists() {
            return beside;
        }
        match workspace_root().map(|r| r.join(path)) {
            Some(p) if p.exists() => p,
            _ => beside,
        }
    }

    /// The golden run: a 128 x 128 crop of the fixture (fast; goldens stay small).
    pub fn golden(root: &Path, out_dir: PathBuf) -> Self {
        Self {
            crop: Some((200, 160, 128, 128)),
            out_dir,
            previews: false,
            verbose: false,
            ..Self::full(root)
        }
    }
}

/// Tolerance of a golden comparison, in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Largest allowed absolute difference of any cell.
    pub max_abs_m: f64,
    /// Largest allowed root-mean-square difference.
    pub rmse_m: f64,
}

impl Tolerance {
    /// Bit-exact within f32 rounding noise of deterministic float code.
    pub const EXACT: Tolerance = Tolerance {
        max_abs_m: 1e-4,
        rmse_m: 1e-5,
    };
}

/// A raster a stage produced, kept for the golden comparison.
#[derive(Debug, Clone)]
pub struct RasterOutput {
    /// File stem (`<out>/<name>.tif`, `fixtures/golden/<name>.tif`).
    pub name: String,
    /// The raster.
    pub raster: Heightfield,
    /// Golden tolerance, or `None` for rasters that are not compared.
    pub tolerance: Option<Tolerance>,
}

/// Data flowing between stages.
#[derive(Debug, Default)]
pub struct State {
    terrain: Option<Heightfield>,
    /// The terrain as loaded (before any stage changed it), for before/after comparisons.
    pub source: Option<Heightfield>,
    /// Every raster saved so far, in order.
    pub outputs: Vec<RasterOutput>,
}

impl State {
    /// The current terrain (the previous stage's output).
    pub fn terrain(&self) -> Result<&Heightfield> {
        self.terrain
            .as_ref()
            .context("no terrain yet: the `load` stage must come first")
    }

    /// A copy of the current terrain, which the `stage` stage needs void-free.
    pub fn complete_terrain(&self, stage: &str) -> Result<Heightfield> {
        let terrain = self.terrain()?.clone();
        terrain.require_complete().with_context(|| {
            format!("the {stage} stage needs a void-free terrain (run fill_voids first)")
        })?;
        Ok(terrain)
    }

    /// The input DEM when it is void-free, else the current terrain (which the `stage` stage
    /// needs void-free, as its `what`), and which of the two it is.
    pub fn complete_source(&self, stage: &str, what: &str) -> Result<(Heightfield, &'static str)> {
        let (terrain, which) = match &self.source {
            Some(src) if src.require_complete().is_ok() => (src.clone(), "the input DEM"),
            _ => (self.terrain()?.clone(), "the current terrain"),
        };
        terrain
            .require_complete()
            .with_context(|| format!("the {stage} stage needs a void-free {what}"))?;
        Ok((terrain, which))
    }

    /// Replaces the current terrain; the next stage starts from it.
    pub fn set_terrain(&mut self, hf: Heightfield) {
        self.terrain = Some(hf);
    }
}

/// The terrain a stage works on (its `input` parameter).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub(crate) enum StageInput {
    /// The input DEM as loaded when it is void-free, else the current terrain (see
    /// [`State::complete_source`]).
    #[default]
    Source,
    /// The current terrain: the previous stage's output.
    Terrain,
}

/// Everything a stage may touch while it runs.
#[derive(Debug)]
pub struct StageCx<'a> {
    /// The run's configuration.
    pub config: &'a PipelineConfig,
    /// Terrain and outputs flowing between stages.
    pub state: &'a mut State,
    /// This stage's part of the report.
    pub section: &'a mut Section,
}

impl StageCx<'_> {
    /// Writes `hf` as `<out>/<name>.tif` (GeoTIFF f32) and, unless previews are off, a shaded
    /// preview `<out>/<name>.png` shown in the report; records it for the golden check when
    /// `tolerance` is given.
    pub fn save_raster(
        &mut self,
        name: &str,
        caption: &str,
        hf: &Heightfield,
        tolerance: Option<Tolerance>,
    ) -> Result<()> {
        let tif = self.config.out_dir.join(format!("{name}.tif"));
        relief_io::write(&tif, hf, &relief_io::WriteOptions::default())
            .with_context(|| format!("cannot write {}", tif.display()))?;
        self.section.file(&format!("{name}.tif"));
        if self.config.previews {
            self.save_preview(name, caption, hf)?;
        }
        self.state.outputs.push(RasterOutput {
            name: name.to_string(),
            raster: hf.clone(),
            tolerance,
        });
        Ok(())
    }

    /// Writes a preview PNG `<out>/<name>.png` and shows it in the report.
    pub fn save_preview(&mut self, name: &str, caption: &str, hf: &Heightfield) -> Result<()> {
        let png = self.config.out_dir.join(format!("{name}.png"));
        relief_io::write_preview_png(&png, hf)
            .with_context(|| format!("cannot write {}", png.display()))?;
        self.section.image(&format!("{name}.png"), caption);
        Ok(())
    }

    /// The terrain `input` names for the `stage` stage and which one it is (the figure
    /// `input`).
    pub(crate) fn input_terrain(
        &mut self,
        stage: &str,
        input: StageInput,
    ) -> Result<(Heightfield, &'static str)> {
        let (terrain, which) = match input {
            StageInput::Source => self.state.complete_source(stage, "terrain")?,
            StageInput::Terrain => (self.state.terrain()?.clone(), "the current terrain"),
        };
        self.section.figure("input", which);
        Ok((terrain, which))
    }

    /// The centre of `hf` cropped to at most `max_size` cells per side (0 = no crop); the
    /// figure `crop` gives the window `[x, y, w, h]` when it is cropped.
    pub(crate) fn centre_crop_to(
        &mut self,
        hf: Heightfield,
        max_size: usize,
    ) -> Result<Heightfield> {
        let (w, h) = (hf.width(), hf.height());
        if max_size == 0 || (w <= max_size && h <= max_size) {
            return Ok(hf);
        }
        let (cw, ch) = (w.min(max_size), h.min(max_size));
        let (x, y) = ((w - cw) / 2, (h - ch) / 2);
        self.section.figure("crop", [x, y, cw, ch]);
        Ok(hf.crop(x, y, cw, ch)?)
    }

    /// A progress sink for library calls that prints phase names under `verbose`.
    pub fn progress(&self) -> StageProgress {
        StageProgress {
            verbose: self.config.verbose,
            limits: self.config.limits,
        }
    }
}

/// Checks a stage's `max_size` parameter (the side [`StageCx::centre_crop_to`] crops to): 0 (no
/// crop) or at least `min` cells.
pub(crate) fn check_max_size(max_size: usize, min: usize) -> Result<()> {
    if max_size != 0 && max_size < min {
        bail!("`max_size` = {max_size} must be 0 or >= {min}");
    }
    Ok(())
}

/// Prints each phase a library call announces (`    <phase> (<total>)`) on stderr, and asks
/// the library to stop past the run's deadline.
#[derive(Debug, Clone, Copy)]
pub struct StageProgress {
    verbose: bool,
    limits: RunLimits,
}

impl Progress for StageProgress {
    fn begin(&self, phase: &str, total: u64) {
        if self.verbose {
            eprintln!("    {phase} ({total})");
        }
    }

    fn stopped(&self) -> bool {
        self.limits.past_deadline()
    }
}

/// One step of the pipeline.
pub trait Stage {
    /// Runs the stage: reads `cx.state`, writes files under `cx.config.out_dir`, fills
    /// `cx.section`.
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()>;
}

/// The stages of the default run, in order (see [`spec::default_spec`]).
pub fn default_stages() -> Vec<NamedStage> {
    spec::build_stages(&spec::default_spec())
        .expect("the default spec names registered stages with valid parameters (tested)")
}

/// What a finished run returns.
#[derive(Debug)]
pub struct PipelineRun {
    /// The final state (terrain and saved rasters).
    pub state: State,
    /// Number of stages run.
    pub stage_count: usize,
    /// Wall time of the whole run.
    pub seconds: f64,
}

/// Runs one stage on `state` into a new report section `name`, timed.
pub(crate) fn run_stage(
    stage: &dyn Stage,
    name: &str,
    config: &PipelineConfig,
    state: &mut State,
) -> Result<Section> {
    let t = Instant::now();
    let mut section = Section::new(name);
    stage.run(&mut StageCx {
        config,
        state,
        section: &mut section,
    })?;
    section.seconds = t.elapsed().as_secs_f64();
    Ok(section)
}

/// Runs `stages` in order, then writes `summary.json` and `report.html` into the output folder.
pub fn run(config: &PipelineConfig, stages: &[NamedStage]) -> Result<PipelineRun> {
    std::fs::create_dir_all(&config.out_dir)
        .with_context(|| format!("cannot create {}", config.out_dir.display()))?;
    let mut report = Report::new("relief pipeline", &config.input, config.seed);
    let mut state = State::default();
    let t_all = Instant::now();
    let n = stages.len();
    for (i, NamedStage { name, stage }) in stages.iter().enumerate() {
        if config.limits.past_deadline() {
            return Err(anyhow::Error::new(Stopped(format!(
                "the run reached its time limit before stage `{name}`"
            ))));
        }
        if config.verbose {
            eprintln!("[{}/{n}] {name} ...", i + 1);
        }
        let section = run_stage(stage.as_ref(), name, config, &mut state)
            .with_context(|| format!("pipeline stage `{name}` failed"))?;
        if config.verbose {
            eprintln!("[{}/{n}] {name} done in {:.2} s", i + 1, section.seconds);
        }
        report.push(section);
    }
    let seconds = t_all.elapsed().as_secs_f64();
    report.total_seconds = seconds;
    report.peak_memory_bytes = peak_memory_bytes();
    report.overview(config, &mut state)?;
    report.write(&config.out_dir)?;
    if state.terrain.is_none() {
        bail!("the pipeline ran no stage that produced a terrain");
    }
    Ok(PipelineRun {
        state,
        stage_count: n,
        seconds,
    })
}

/// Peak resident memory of this process (Linux `VmHWM`), when known.
fn peak_memory_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// For tests: the full run's settings, quiet, on `crop` of the bundled fixture (the whole of
/// it for `None`), writing into a new temporary folder (removed when the guard is dropped).
#[cfg(test)]
pub(crate) fn test_config(
    crop: Option<(usize, usize, usize, usize)>,
) -> (PipelineConfig, tempfile::TempDir) {
    let tmp = tempfile::tempdir().unwrap();
    let config = PipelineConfig {
        crop,
        out_dir: tmp.path().to_path_buf(),
        verbose: false,
        ..PipelineConfig::full(&crate::test_root())
    };
    (config, tmp)
}

/// For tests: the window `(x, y, w, h)` of the input DEM of `config`.
#[cfg(test)]
pub(crate) fn test_input_crop(
    config: &PipelineConfig,
    (x, y, w, h): (usize, usize, usize, usize),
) -> Heightfield {
    let raster = relief_io::read(&config.input, &relief_io::ReadOptions::default()).unwrap();
    raster.heightfield.crop(x, y, w, h).unwrap()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default stages on a crop write rasters, previews, summary.json and report.html, and
    /// the summary holds every stage's figures. The quilt stage enforces the paper's
    /// validation, which the quadrant exemplars of this small crop fail (6 of 48 volcano blocks
    /// lack candidates; the golden 128 x 128 crop passes): here it is reported, not enforced.
    #[test]
    fn pipeline_writes_report_on_crop() {
        let (config, tmp) = test_config(Some((64, 64, 96, 80)));
        let mut specs = spec::default_spec();
        for s in &mut specs {
            if s.stage == "quilt" {
                s.params = serde_json::json!({"job": {"settings": {"enforce_validation": false}}});
            }
            // The x256 window (an 8192^2 raster) is for the full run, not a unit test.
            if s.stage == "amplify" {
                s.params = serde_json::json!({"x256_window": 0});
            }
            // The volume stage on the DEM's own cells: on a refined window (its default, tested
            // by `volume::tests`) the scene's renders and close-ups took 22 of this test's 24 s.
            if s.stage == "volume" {
                s.params = serde_json::json!({"raw_dem": true});
            }
        }
        let run = run(&config, &spec::build_stages(&specs).unwrap()).unwrap();
        assert_eq!(run.stage_count, default_stages().len());
        // The amplify stage hands on its enlargement: the left half (48 x 80) x4 (the crop is
        // too small for x16).
        let terrain = run.state.terrain().unwrap();
        assert_eq!((terrain.width(), terrain.height()), (192, 320));
        for f in [
            "summary.json",
            "report.html",
            "dem.tif",
            "dem.png",
            "fill_check.png",
        ] {
            assert!(tmp.path().join(f).is_file(), "{f} missing");
        }
        let summary: serde_json::Value =
            serde_json::from_slice(&std::fs::read(tmp.path().join("summary.json")).unwrap())
                .unwrap();
        let stages = summary["stages"].as_array().unwrap();
        let names: Vec<&str> = stages
            .iter()
            .map(|s| s["stage"].as_str().unwrap())
            .collect();
        let expected: Vec<String> = spec::default_spec().into_iter().map(|s| s.stage).collect();
        assert_eq!(names, expected);
        assert_eq!(names[..3], ["load", "fill_voids", "convert"]);
        assert_eq!(stages[0]["figures"]["width"], 96);
        assert_eq!(stages[2]["figures"]["tif_max_abs_m"], 0.0);
        let rmse = stages[1]["figures"]["check_rmse_in_hole_m"]
            .as_f64()
            .unwrap();
        assert!(rmse > 0.0 && rmse < 500.0, "{rmse}");
        let html = std::fs::read_to_string(tmp.path().join("report.html")).unwrap();
        assert!(html.contains("<img src=\"dem.png\""));
        assert!(html.contains("write -&gt; read round trips"));
    }

    #[test]
    fn a_stage_before_load_is_an_error() {
        let (config, _tmp) = test_config(None);
        let stages = spec::build_stages(&[spec::StageSpec::named("fill_voids")]).unwrap();
        let err = run(&config, &stages).unwrap_err();
        assert!(
            format!("{err:#}").contains("`load` stage must come first"),
            "{err:#}"
        );
    }
}

/// The workspace this crate was built from (its `fixtures/` and `docs/`), when it still exists:
/// the last place a relative path in a pipeline spec is looked up, so the bundled fixtures work
/// from a checkout. An installed binary whose sources are gone gets `None`.
pub fn workspace_root() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent()?.parent()?;
    root.join("Cargo.toml")
        .is_file()
        .then(|| root.to_path_buf())
}

/// Cargo's target directory of the workspace at `root` (`$CARGO_TARGET_DIR` or `root/target`).
pub fn target_dir(root: &Path) -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"))
}

#[cfg(test)]
pub(crate) fn test_root() -> PathBuf {
    workspace_root().expect("tests run from the workspace")
}

/// `bytes` for people: `1.5 GiB`, `300 MiB`, `12 KiB`, `512 B`.
pub fn human_bytes(b: u64) -> String {
    const UNITS: [(&str, u64); 4] = [
        ("TiB", 1 << 40),
        ("GiB", 1 << 30),
        ("MiB", 1 << 20),
        ("KiB", 1 << 10),
    ];
    for (u, s) in UNITS {
        if b >= s {
            let v = b as f64 / s as f64;
            return if v < 10.0 {
                format!("{v:.1} {u}")
            } else {
                format!("{v:.0} {u}")
            };
        }
    }
    format!("{b} B")
}

/// A run stopped by its time budget (`relief run --max-time`): between stages, or inside one.
#[derive(Debug)]
pub struct Stopped(pub String);

impl std::fmt::Display for Stopped {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "stopped: {}", self.0)
    }
}

impl std::error::Error for Stopped {}

/// Writes the scene's mesh (format from the extension, with its normals and vertex colours)
/// and returns its size in bytes. `y_up`
/// rotates an OBJ or PLY to Y-up (`(x, y, z) -> (x, z, -y)`); a GLB is always Y-up.
pub fn write_mesh(path: &Path, mesh: &relief_implicit_volume::Mesh, y_up: bool) -> Result<u64> {
    let normals = (!mesh.normals.is_empty()).then_some(&mesh.normals[..]);
    let glb = relief_io::MeshFormat::from_extension(path) == Some(relief_io::MeshFormat::Glb);
    let rotated = (y_up && !glb).then(|| {
        let r =
            |v: &[[f32; 3]]| -> Vec<[f32; 3]> { v.iter().map(relief_io::z_up_to_y_up).collect() };
        (r(&mesh.positions), normals.map(r))
    });
    let (positions, normals) = match &rotated {
        Some((p, n)) => (&p[..], n.as_deref()),
        None => (&mesh.positions[..], normals),
    };
    let colours = (!mesh.colours.is_empty()).then_some(&mesh.colours[..]);
    relief_io::write_mesh(path, positions, &mesh.triangles, normals, colours)?;
    Ok(std::fs::metadata(path).map_or(0, |m| m.len()))
}
