//! The inputs of a patch synthesis shared by `relief quilt` and `relief validate`
//! ([`SynthArgs`]): exemplars, guide (file, blurred DEM or sketch), categories and sizes, their
//! mapping onto a [`ValidateJob`], reading them, the pre-flight estimate and the figures noted.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use relief_heightfield::Heightfield;
use relief_patch_synth::{
    GuideRange, GuideSetup, JobInputs, PatchSynthError, PrepareFigures, Settings, ValidateJob,
};

use crate::ctx::Ctx;

/// Inputs of a synthesis, shared by `relief quilt` and `relief validate`.
#[derive(Debug, clap::Args)]
pub(crate) struct SynthArgs {
    /// Exemplar DEM (repeat the option for several exemplars).
    #[arg(long = "exemplar", value_name = "DEM")]
    pub(crate) exemplars: Vec<PathBuf>,
    /// Category id of each exemplar, comma-separated in `--exemplar` order (default: all 0).
    /// The categorisation map names which categories each region accepts.
    #[arg(long, value_name = "C1,C2,..")]
    pub(crate) exemplar_categories: Option<String>,
    /// Cluster the exemplars into K categories by their block averages (cruz2015 section 4)
    /// unless `--exemplar-categories` is given, and, without `--categories`, make the
    /// categorisation map by clustering the guide's heights into K classes (lowest class =
    /// lowest exemplar category; a class no exemplar has accepts any).
    #[arg(long, value_name = "K")]
    pub(crate) auto_categories: Option<usize>,
    /// Cluster the exemplars' patches (not whole exemplars) into K categories by their block
    /// averages (cruz2015 section 4), so regions of one exemplar (valley floors, slopes, rims)
    /// get their own categories, numbered from the lowest; without `--categories`, the map
    /// comes from the guide's heights clustered into K classes.
    #[arg(long, value_name = "K", conflicts_with_all = ["auto_categories", "exemplar_regions"])]
    pub(crate) region_categories: Option<usize>,
    /// Painted category regions of an exemplar (e.g. an 8-bit grey PNG at the exemplar's size,
    /// values are category ids); repeat once per `--exemplar`, in the same order. A patch takes
    /// the category under its centre.
    #[arg(
        long = "exemplar-regions",
        value_name = "MAP",
        conflicts_with = "auto_categories"
    )]
    pub(crate) exemplar_regions: Vec<PathBuf>,
    /// Once the input validation passes, keep only the small subset of exemplars its greedy
    /// set cover picks (cruz2015 section 4), re-index and re-validate it (all are kept when the
    /// subset fails).
    #[arg(long)]
    pub(crate) auto_subset: bool,
    /// Guide DEM at the target resolution (low-frequency control); resampled to `--size` when
    /// its size differs.
    #[arg(long, value_name = "DEM")]
    pub(crate) guide: Option<PathBuf>,
    /// Make the guide from this DEM: voids filled, resampled to `--size`, then Gaussian
    /// low-pass of `--blur` cells.
    #[arg(long, value_name = "DEM")]
    pub(crate) guide_from: Option<PathBuf>,
    /// Make the guide from a sketch file (JSON: `width`, `height`, optional `cell_size` [x, y]
    /// in metres (default: the exemplars'), `smoothing` in cells (default 2), `seeds`
    /// [{x, y, height, radius}] and `strokes` [{points: [[x, y, height], ...]}], coordinates
    /// in guide cells, heights in metres): the painted heights, harmonic interpolation between
    /// them, then the blur.
    #[arg(long, value_name = "FILE.json")]
    pub(crate) guide_sketch: Option<PathBuf>,
    /// Standard deviation in cells of the Gaussian low-pass applied to `--guide-from`.
    #[arg(long, value_name = "SIGMA")]
    pub(crate) blur: Option<f32>,
    /// Map the guide's heights linearly before use (a guide from another DEM, or a PNG sketch
    /// of grey levels). `auto`: the extremes of its patch-sized window means go onto the 2-98 %
    /// range of the exemplar patches' means, narrowed or shifted (a few fixed tries) until the
    /// input validation passes; `LO,HI`: onto LO..HI metres. Default: the guide's heights as
    /// they are (a failing validation says when `auto` would pass).
    #[arg(long, value_name = "auto|LO,HI", allow_hyphen_values = true, value_parser = parse_guide_range)]
    pub(crate) guide_range: Option<GuideRange>,
    /// Also write the guide exactly as used (at the exemplars' cell size, cropped or padded to
    /// the output size, low-passed and mapped).
    #[arg(long, value_name = "FILE")]
    pub(crate) guide_out: Option<PathBuf>,
    /// Cell size in metres of the guide, `X` or `X,Y`, for a guide that stores none (PNG, NPY)
    /// or a wrong one; the guide is resampled from it to the exemplars' cell size. Without it,
    /// a guide that stores none is taken at the exemplars' cell size (one guide cell per output
    /// cell), and a 16-bit PNG relief wrote reads its cell size from its `.png.json` sidecar.
    #[arg(long, value_name = "X[,Y]", value_parser = crate::args::parse_cell_size)]
    pub(crate) guide_cell_size: Option<(f64, f64)>,
    /// Categorisation map (e.g. an 8-bit grey PNG): each cell's value is the exemplar category
    /// allowed there (65535 = any). Resampled (nearest) to the output size.
    #[arg(long, value_name = "MAP")]
    pub(crate) categories: Option<PathBuf>,
    /// Output size `WxH` (or `N` for square); defaults to the guide's size.
    #[arg(long, value_name = "WxH", value_parser = crate::args::parse_size)]
    pub(crate) size: Option<(usize, usize)>,
    /// Patch side in cells.
    #[arg(long = "patch-size", alias = "patch", default_value_t = Settings::default().patch_size)]
    pub(crate) patch: usize,
    /// Overlap between neighbouring patches in cells (< patch / 2; default: a quarter of the
    /// patch side, 16 for the default 64).
    #[arg(long)]
    pub(crate) overlap: Option<usize>,
    /// Seed of every random choice (same seed, same output bytes).
    #[arg(long, default_value_t = Settings::default().seed)]
    pub(crate) seed: u64,
    /// Minimum candidate patches per guide block for the input validation (section 4).
    #[arg(long, default_value_t = Settings::default().min_candidates)]
    pub(crate) min_candidates: usize,
    /// Candidates a guide block needs as a share in (0, 1] of the exemplars' candidate
    /// patches, when that is fewer than --min-candidates (on small exemplars an absolute count
    /// fails blocks that have ample candidates for their size). Default 0.0025: 500 of the
    /// 201,601 patches of a 512 x 512 exemplar; 1 = the absolute --min-candidates.
    #[arg(long, value_name = "SHARE")]
    pub(crate) min_candidates_share: Option<f32>,
    /// RMS tolerance in metres of a block match counted by the validation (default: half the
    /// guide's standard deviation).
    #[arg(long, value_name = "METRES")]
    pub(crate) tolerance: Option<f32>,
    /// Largest vertical translation of a patch in metres (section 3.4).
    #[arg(long, default_value_t = Settings::default().lambda)]
    pub(crate) lambda: f32,
    /// Weight of the guide distance G in the patch energy M = alpha G + beta O + gamma P
    /// (equation 1).
    #[arg(long, default_value_t = Settings::default().alpha)]
    pub(crate) alpha: f32,
    /// Weight of the overlap distance O in equation 1.
    #[arg(long, default_value_t = Settings::default().beta)]
    pub(crate) beta: f32,
    /// Weight of the cut cost P in equation 1.
    #[arg(long, default_value_t = Settings::default().gamma)]
    pub(crate) gamma: f32,
    /// Patch-reuse penalty: a candidate whose source lies within half a patch of the source of
    /// a block placed within 3 blocks has its energy multiplied by 1 + PENALTY per such block,
    /// so one source region does not wallpaper an area (0 = off, as in the paper).
    #[arg(long, value_name = "PENALTY", default_value_t = Settings::default().reuse_penalty)]
    pub(crate) reuse_penalty: f32,
    /// Low-pass of the exemplar that the guide distance G compares with the guide: `auto`
    /// (a Gaussian of the guide's own smoothness scale, about 1.1x the blur of a blurred DEM;
    /// smooth guides then no longer pick the flattest patches), SIGMA cells, or 0 (the paper's
    /// raw cell means; better for band-limited guides and tiny enlarged DEMs).
    #[arg(long, value_name = "auto|SIGMA", value_parser = parse_guide_lowpass)]
    pub(crate) guide_lowpass: Option<GuideLowpass>,
    /// Exemplar patches are taken every STRIDE cells (1 = every position).
    #[arg(long, default_value_t = Settings::default().exemplar_stride)]
    pub(crate) stride: usize,
    #[command(flatten)]
    pub(crate) read: crate::args::ReadArgs,
}

/// A `--guide-lowpass` value: automatic or a sigma in cells.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum GuideLowpass {
    Auto,
    Sigma(f32),
}

/// `--guide-lowpass` value parser: `auto` or a sigma in cells (0 = the paper's distance).
fn parse_guide_lowpass(spec: &str) -> std::result::Result<GuideLowpass, String> {
    let spec = spec.trim();
    if spec.eq_ignore_ascii_case("auto") {
        return Ok(GuideLowpass::Auto);
    }
    spec.parse::<f32>()
        .map(GuideLowpass::Sigma)
        .map_err(|_| format!("`{spec}` is neither auto nor a sigma in cells"))
}

/// `--guide-range` value parser: `auto` or `LO,HI` metres.
fn parse_guide_range(spec: &str) -> std::result::Result<GuideRange, String> {
    if spec.trim().eq_ignore_ascii_case("auto") {
        return Ok(GuideRange::Auto);
    }
    let (lo, hi) = crate::args::parse_height_range(spec).map_err(|e| format!("{e} (or auto)"))?;
    Ok(GuideRange::Metres(lo as f32, hi as f32))
}

/// True for a PNG read as raw grey counts (no relief vertical mapping): whole numbers that fit
/// 16 bits, which are grey levels rather than metres.
fn png_counts(path: &Path, g: &Heightfield) -> bool {
    crate::outputs::has_extension(path, "png")
        && g.as_slice()
            .iter()
            .all(|&v| !v.is_finite() || (v.fract() == 0.0 && (0.0..=65535.0).contains(&v)))
}

impl SynthArgs {
    /// Every file these arguments read (exemplars, guide, categorisation map).
    pub(crate) fn input_paths(&self) -> Vec<&Path> {
        let mut v: Vec<&Path> = self.exemplars.iter().map(|p| p.as_path()).collect();
        v.extend(self.guide.as_deref());
        v.extend(self.guide_from.as_deref());
        v.extend(self.guide_sketch.as_deref());
        v.extend(self.categories.as_deref());
        v.extend(self.exemplar_regions.iter().map(|p| p.as_path()));
        v
    }

    /// The extra outputs these arguments ask for (`--guide-out`).
    pub(crate) fn output_paths(&self) -> Vec<(&Path, crate::outputs::OutKind)> {
        self.guide_out
            .as_deref()
            .map(|p| (p, crate::outputs::OutKind::Raster))
            .into_iter()
            .collect()
    }

    /// The validation job these flags describe (library defaults where a flag is absent).
    pub(crate) fn job(&self) -> Result<ValidateJob> {
        if self.exemplars.is_empty() {
            bail!("no exemplar: give at least one --exemplar DEM");
        }
        let guides = [
            self.guide.is_some(),
            self.guide_from.is_some(),
            self.guide_sketch.is_some(),
        ];
        if guides.iter().filter(|&&g| g).count() > 1 {
            bail!("give one of --guide, --guide-from and --guide-sketch, not several");
        }
        if self.guide_from.is_some() != self.blur.is_some() {
            bail!("--guide-from DEM and --blur SIGMA go together");
        }
        let exemplar_categories = self
            .exemplar_categories
            .as_deref()
            .map(|list| {
                list.split(',')
                    .map(|t| {
                        t.trim().parse::<u16>().with_context(|| {
                            format!("invalid --exemplar-categories `{list}`: `{t}` is not 0..65535")
                        })
                    })
                    .collect::<Result<Vec<u16>>>()
            })
            .transpose()?;
        let job = ValidateJob {
            settings: Settings {
                patch_size: self.patch,
                overlap: self.overlap.unwrap_or_else(|| {
                    let d = Settings::default();
                    (self.patch * d.overlap / d.patch_size).max(1)
                }),
                seed: self.seed,
                min_candidates: self.min_candidates,
                min_candidates_share: self
                    .min_candidates_share
                    .or(Settings::default().min_candidates_share),
                validation_tolerance: self.tolerance,
                lambda: self.lambda,
                alpha: self.alpha,
                beta: self.beta,
                gamma: self.gamma,
                reuse_penalty: self.reuse_penalty,
                guide_lowpass: match self.guide_lowpass {
                    None | Some(GuideLowpass::Auto) => None,
                    Some(GuideLowpass::Sigma(s)) => Some(s),
                },
                exemplar_stride: self.stride,
                ..Settings::default()
            },
            size: self.size,
            guide: GuideSetup {
                cell_size: self.guide_cell_size,
                blur: self.blur,
                range: self.guide_range,
            },
            exemplar_categories,
            auto_categories: self.auto_categories,
            region_categories: self.region_categories,
            auto_subset: self.auto_subset,
        };
        if !self.exemplar_regions.is_empty() && self.exemplar_regions.len() != self.exemplars.len()
        {
            bail!(
                "{} --exemplar-regions for {} --exemplar: give one region map per exemplar, in \
                 the same order",
                self.exemplar_regions.len(),
                self.exemplars.len()
            );
        }
        job.check().context("invalid synthesis settings")?;
        Ok(job)
    }

    /// Reads the exemplars, the guide (refusing a grey-level PNG without `--guide-range`) and
    /// the categorisation map (raw grey counts).
    pub(crate) fn inputs(&self, ctx: &Ctx) -> Result<JobInputs> {
        let read = |path: &Path, what: &str| -> Result<Heightfield> {
            Ok(crate::read::read_raster(path, &self.read, ctx)
                .with_context(|| format!("{what} {}", path.display()))?
                .heightfield)
        };
        let mut inputs = JobInputs::default();
        for p in &self.exemplars {
            inputs.exemplars.push(read(p, "exemplar")?);
        }
        if let Some(path) = self.guide.as_deref().or(self.guide_from.as_deref()) {
            // A painted guide's missing cell size is handled below, not warned about.
            let read = crate::args::ReadArgs {
                warn_assumed_cell: false,
                ..self.read.clone()
            };
            let raster = crate::read::read_raster(path, &read, ctx)
                .with_context(|| format!("guide {}", path.display()))?;
            let stored = crate::read::cell_size_stored(path, &raster);
            let mut g = raster.heightfield;
            // A painted guide (PNG, raw, EXR, NPY) stores no cell size: it is drawn on the
            // output grid, so it takes the exemplars' cell size rather than the reader's 1 m
            // (which would shrink it 60 times against a 60 m exemplar).
            if self.guide_cell_size.is_none()
                && self.read.cell_size.is_none()
                && !stored
                && let Some(e) = inputs.exemplars.first()
            {
                let (cx, cy) = e.cell_size();
                g.set_cell_size(cx, cy)?;
                ctx.note(format!(
                    "guide {}: the file stores no cell size; taken at the exemplars' ({cx:.3} x {cy:.3} m, one guide cell per output cell; \
                     --guide-cell-size sets another)",
                    path.display()
                ));
            }
            if self.guide_range.is_none() && png_counts(path, &g) {
                bail!(
                    "guide {}: a PNG of grey levels (no relief vertical mapping) holds no \
                     heights; give --guide-range auto (the exemplars' heights) or LO,HI (metres)",
                    path.display()
                );
            }
            inputs.guide = Some(g);
        }
        if let Some(path) = &self.guide_sketch {
            inputs.guide = Some(read_sketch(path, &inputs.exemplars)?);
        }
        // Category rasters are raw grey counts (ids), not heights.
        let ids = |path: &Path, what: &str| -> Result<Heightfield> {
            let opts = relief_io::ReadOptions {
                png: relief_io::PngMode::Grey {
                    offset: 0.0,
                    scale: 1.0,
                },
                ..Default::default()
            };
            Ok(relief_io::read(path, &opts)
                .with_context(|| format!("cannot read {what} {}", path.display()))?
                .heightfield)
        };
        if let Some(path) = &self.categories {
            inputs.categories = Some(ids(path, "categorisation map")?);
        }
        for p in &self.exemplar_regions {
            inputs.exemplar_regions.push(ids(p, "exemplar region map")?);
        }
        Ok(inputs)
    }

    /// Pre-flight memory check of the job on these inputs.
    pub(crate) fn preflight(&self, job: &ValidateJob, inputs: &JobInputs, ctx: &Ctx) -> Result<()> {
        use crate::memory::part;
        let m = job.memory(inputs)?;
        ctx.check_memory(
            "quilt",
            &[&[
                part(
                    format!("the index of {} exemplar patches", m.candidates),
                    m.index_bytes,
                    "smaller (or fewer) --exemplar files, or a larger --stride",
                ),
                part(
                    format!("the {} x {} output canvases", m.output.0, m.output.1),
                    m.output_bytes,
                    "a smaller --size (or guide)",
                ),
            ]],
        )
    }

    /// An error of the job with the exemplar's or guide's path named.
    pub(crate) fn job_error(&self, e: PatchSynthError) -> anyhow::Error {
        let what = match &e {
            PatchSynthError::BadExemplar { index, .. } => self
                .exemplars
                .get(*index)
                .map(|p| format!("exemplar {}", p.display())),
            PatchSynthError::InvalidControl { name: "guide", .. } => self
                .guide
                .as_deref()
                .or(self.guide_from.as_deref())
                .map(|p| format!("guide {}", p.display())),
            _ => None,
        };
        match what {
            Some(w) => anyhow::anyhow!("{w}: {e}"),
            None => anyhow::Error::new(e),
        }
    }

    /// Notes on stderr of what the preparation did to the inputs.
    pub(crate) fn note_figures(&self, f: &PrepareFigures, ctx: &Ctx) {
        for (p, &n) in self.exemplars.iter().zip(&f.exemplar_voids_filled) {
            if n > 0 {
                ctx.note(format!("exemplar {}: filled {n} void cells", p.display()));
            }
        }
        let guide = self.guide.as_deref().or(self.guide_from.as_deref());
        if let (Some(p), n @ 1..) = (guide, f.guide_voids_filled) {
            ctx.note(format!("guide {}: filled {n} void cells", p.display()));
        }
        if f.categories_clustered && self.region_categories.is_none() {
            let list: Vec<String> = f
                .exemplar_categories
                .iter()
                .map(|c| c.to_string())
                .collect();
            ctx.note(format!(
                "exemplar categories (clustered): {}",
                list.join(",")
            ));
        }
        if self.region_categories.is_some() || !self.exemplar_regions.is_empty() {
            let list: Vec<String> = f
                .patches_per_category
                .iter()
                .map(|(c, n)| format!("{c}: {n}"))
                .collect();
            ctx.note(format!(
                "candidate patches per region category: {}",
                list.join(", ")
            ));
        }
        if let Some(keep) = &f.exemplar_subset {
            let names: Vec<String> = keep
                .iter()
                .filter_map(|&i| self.exemplars.get(i))
                .map(|p| p.display().to_string())
                .collect();
            ctx.note(format!(
                "--auto-subset: kept {} of {} exemplars ({}); the subset passes the validation",
                keep.len(),
                self.exemplars.len(),
                names.join(", ")
            ));
        }
        if let (Some(p), Some(fit)) = (guide, &f.guide_fit)
            && (fit.cropped != (0, 0) || fit.padded != (0, 0))
        {
            ctx.note(format!(
                "guide {}: {} x {} cells at the exemplars' cell size (its scale kept), cropped \
                 (centred) by {} x {} and mirror-padded by {} x {} cells to {} x {}",
                p.display(),
                fit.extent.0,
                fit.extent.1,
                fit.cropped.0,
                fit.cropped.1,
                fit.padded.0,
                fit.padded.1,
                f.output_size.0,
                f.output_size.1
            ));
        }
        if let Some(m) = &f.guide_mapping {
            ctx.note(format!(
                "guide heights {:.1}..{:.1} m (patch-window means) mapped onto {:.1}..{:.1} m",
                m.from.0, m.from.1, m.to.0, m.to.1
            ));
        }
    }
}

/// Largest sketch file read by `--guide-sketch` (a sketch is a few seeds and strokes).
const MAX_SKETCH_BYTES: u64 = 16 << 20;

/// Reads and rasterises a `--guide-sketch` file (at the first exemplar's cell size unless the
/// sketch names one).
fn read_sketch(path: &Path, exemplars: &[Heightfield]) -> Result<Heightfield> {
    let len = std::fs::metadata(path)
        .with_context(|| format!("cannot read sketch {}", path.display()))?
        .len();
    if len > MAX_SKETCH_BYTES {
        bail!(
            "sketch {}: {len} bytes, more than the {MAX_SKETCH_BYTES} a sketch file may have",
            path.display()
        );
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read sketch {}", path.display()))?;
    let sketch: relief_patch_synth::guide::SketchGuide = serde_json::from_str(&text)
        .with_context(|| format!("sketch {}: not a sketch guide", path.display()))?;
    let cell = exemplars.first().map_or((1.0, 1.0), |e| e.cell_size());
    sketch
        .render(cell)
        .with_context(|| format!("sketch {}", path.display()))
}
