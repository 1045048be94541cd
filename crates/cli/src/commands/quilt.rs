//! `relief quilt OUT --exemplar E [--exemplar E2 ...] (--guide G | --guide-from DEM --blur S)
//! [--categories MAP] --size WxH --patch P --overlap O --seed S`: guided patch-based terrain
//! synthesis (Cruz et al. 2015, relief-patch-synth). The inputs shared with `relief validate`
//! live in [`SynthArgs`].

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use relief_heightfield::fill::{FillSettings, fill_voids};
use relief_heightfield::{Heightfield, Progress};
use relief_patch_synth::{
    ANY_CATEGORY, Blend, CategoryMap, Control, CutMethod, Exemplar, ExemplarIndex, GuideRange,
    RangeMapping, Settings, Synthesis, ValidationReport, categorize_exemplars, guide, synthesize,
    validate,
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
    /// Guide DEM at the target resolution (low-frequency control); resampled to `--size` when
    /// its size differs.
    #[arg(long, value_name = "DEM")]
    pub(crate) guide: Option<PathBuf>,
    /// Make the guide from this DEM: voids filled, resampled to `--size`, then Gaussian
    /// low-pass of `--blur` cells.
    #[arg(long, value_name = "DEM")]
    pub(crate) guide_from: Option<PathBuf>,
    /// Standard deviation in cells of the Gaussian low-pass applied to `--guide-from`.
    #[arg(long, value_name = "SIGMA")]
    pub(crate) blur: Option<f32>,
    /// Map the guide's heights linearly before use (a guide from another DEM, or a PNG sketch
    /// of grey levels). `auto`: the extremes of its patch-sized window means go onto the 2-98 %
    /// range of the exemplar patches' means, narrowed or shifted (a few fixed tries) until the
    /// input validation passes; `LO,HI`: onto LO..HI metres. Default: the guide's heights as
    /// they are (a failing validation says when `auto` would pass).
    #[arg(long, value_name = "auto|LO,HI", allow_hyphen_values = true)]
    pub(crate) guide_range: Option<String>,
    /// Also write the guide exactly as used (at the exemplars' cell size, cropped or padded to
    /// the output size, low-passed and mapped).
    #[arg(long, value_name = "FILE")]
    pub(crate) guide_out: Option<PathBuf>,
    /// Cell size in metres of the guide, `X` or `X,Y`, for a guide that stores none (PNG, NPY)
    /// or a wrong one; the guide is resampled from it to the exemplars' cell size.
    #[arg(long, value_name = "X[,Y]", value_parser = super::parse_cell_size)]
    pub(crate) guide_cell_size: Option<(f64, f64)>,
    /// Categorisation map (e.g. an 8-bit grey PNG): each cell's value is the exemplar category
    /// allowed there (65535 = any). Resampled (nearest) to the output size.
    #[arg(long, value_name = "MAP")]
    pub(crate) categories: Option<PathBuf>,
    /// Output size `WxH` (or `N` for square); defaults to the guide's size.
    #[arg(long, value_name = "WxH")]
    pub(crate) size: Option<String>,
    /// Patch side in cells.
    #[arg(long = "patch-size", alias = "patch", default_value_t = 64)]
    pub(crate) patch: usize,
    /// Overlap between neighbouring patches in cells (< patch / 2).
    #[arg(long, default_value_t = 16)]
    pub(crate) overlap: usize,
    /// Seed of every random choice (same seed, same output bytes).
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Minimum candidate patches per guide block for the input validation (section 4).
    #[arg(long, default_value_t = 500)]
    pub(crate) min_candidates: usize,
    /// RMS tolerance in metres of a block match counted by the validation (default: half the
    /// guide's standard deviation).
    #[arg(long, value_name = "METRES")]
    pub(crate) tolerance: Option<f32>,
    /// Largest vertical translation of a patch in metres (section 3.4).
    #[arg(long, default_value_t = 50.0)]
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
    /// Exemplar patches are taken every STRIDE cells (1 = every position).
    #[arg(long, default_value_t = 1)]
    pub(crate) stride: usize,
    #[command(flatten)]
    pub(crate) read: super::ReadArgs,
}

impl SynthArgs {
    /// Every file these arguments read (exemplars, guide, categorisation map).
    pub(crate) fn input_paths(&self) -> Vec<&Path> {
        let mut v: Vec<&Path> = self.exemplars.iter().map(|p| p.as_path()).collect();
        v.extend(self.guide.as_deref());
        v.extend(self.guide_from.as_deref());
        v.extend(self.categories.as_deref());
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
}

/// Largest guide grid accepted without `--size` (cells at the exemplars' cell size).
const MAX_GUIDE_CELLS: usize = 1 << 26;

/// The guide on the output grid, at its own physical scale: resampled from its cell size (or
/// `--guide-cell-size`) to the exemplars' (patches are copied cell for cell), then, with
/// `--size`, cropped (centred, with a note) or mirror-padded to that size; without, the output
/// covers the guide's ground and keeps its georeference.
fn fit_guide(
    mut g: Heightfield,
    size: Option<(usize, usize)>,
    cell: (f64, f64),
    guide_cell: Option<(f64, f64)>,
    path: &Path,
    ctx: &Ctx,
) -> Result<Heightfield> {
    if let Some((cx, cy)) = guide_cell {
        g.set_cell_size(cx, cy)?;
    }
    let (gx, gy) = g.cell_size();
    let (kx, ky) = (gx / cell.0, gy / cell.1);
    // The guide's extent in the exemplars' cells.
    let (rw, rh) = (
        (g.width() as f64 * kx).round().max(1.0),
        (g.height() as f64 * ky).round().max(1.0),
    );
    if rw * rh > MAX_GUIDE_CELLS as f64 {
        match size {
            // Only the centre is used: crop it first (with a resampling margin) so that the
            // resampling stays within the output's size.
            Some((w, h)) => {
                let need = |n: usize, k: f64| ((n as f64 / k).ceil() as usize).saturating_add(4);
                let (nw, nh) = (need(w, kx).min(g.width()), need(h, ky).min(g.height()));
                g = g.crop((g.width() - nw) / 2, (g.height() - nh) / 2, nw, nh)?;
            }
            None => bail!(
                "guide {} covers {rw} x {rh} cells of the exemplars' {:.2} x {:.2} m: give \
                 --size WxH{}",
                path.display(),
                cell.0,
                cell.1,
                if guide_cell.is_none() {
                    " or the guide's --guide-cell-size"
                } else {
                    ""
                }
            ),
        }
    }
    let g = guide::to_cell_size(&g, cell)
        .with_context(|| format!("cannot resample guide {}", path.display()))?;
    let Some((w, h)) = size else {
        return Ok(g);
    };
    let (g2, fit) = guide::fit_to_size(&g, w, h)?;
    let mut changes = Vec::new();
    let cropped = (
        (rw as usize).saturating_sub(w),
        (rh as usize).saturating_sub(h),
    );
    if cropped != (0, 0) {
        changes.push(format!(
            "cropped (centred) by {} x {} cells",
            cropped.0, cropped.1
        ));
    }
    if fit.padded != (0, 0) {
        changes.push(format!(
            "mirror-padded by {} x {} cells",
            fit.padded.0, fit.padded.1
        ));
    }
    if !changes.is_empty() {
        ctx.note(format!(
            "guide {}: {rw} x {rh} cells at the exemplars' {:.2} x {:.2} m (its scale kept), {} to \
             --size {w}x{h}",
            path.display(),
            cell.0,
            cell.1,
            changes.join(" and ")
        ));
    }
    Ok(g2)
}

/// The parsed `--guide-range`.
fn parse_guide_range(spec: &str) -> Result<GuideRange> {
    if spec.trim().eq_ignore_ascii_case("auto") {
        return Ok(GuideRange::Auto);
    }
    let (lo, hi) = crate::ctx::parse_height_range(spec)
        .map_err(|e| anyhow::anyhow!("invalid --guide-range {e} (or auto)"))?;
    Ok(GuideRange::Metres(lo as f32, hi as f32))
}

/// True for a PNG read as raw grey counts (no relief vertical mapping): whole numbers that fit
/// 16 bits, which are grey levels rather than metres.
fn png_counts(path: &Path, g: &Heightfield) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        && g.as_slice()
            .iter()
            .all(|&v| !v.is_finite() || (v.fract() == 0.0 && (0.0..=65535.0).contains(&v)))
}

/// Seam blending of `relief quilt`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum BlendArg {
    /// Poisson blending over the overlap.
    Poisson,
    /// Smooth feathering across the seam.
    Feather,
    /// Plain cut and paste.
    None,
}

/// Seam search of `relief quilt`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum CutArg {
    /// Minimum-error boundary cut by dynamic programming.
    Dp,
    /// Greedy path (for comparison).
    Greedy,
}

/// Arguments of `relief quilt`.
#[derive(Debug, clap::Args)]
pub(crate) struct Args {
    /// Output raster (.tif, .exr, .npy, .png, .r16, .r32).
    pub(crate) output: PathBuf,
    #[command(flatten)]
    pub(crate) synth: SynthArgs,
    /// Also write a PNG of the seam map (one colour per patch, seams white).
    #[arg(long, value_name = "PNG")]
    pub(crate) seam_map: Option<PathBuf>,
    /// Seam blending.
    #[arg(long, value_enum, default_value_t = BlendArg::Poisson)]
    pub(crate) blend: BlendArg,
    /// Seam search.
    #[arg(long, value_enum, default_value_t = CutArg::Dp)]
    pub(crate) cut: CutArg,
    /// Synthesize even when the input validation fails (it still runs and is reported).
    #[arg(long)]
    pub(crate) no_validate: bool,
}

/// Everything a synthesis needs, read and checked.
pub(crate) struct Inputs {
    pub(crate) exemplars: Vec<Exemplar>,
    pub(crate) control: Control,
    pub(crate) settings: Settings,
    /// `--guide-range`, applied once the exemplars are indexed.
    pub(crate) guide_range: Option<GuideRange>,
}

/// Parses `WxH` or `N`.
pub(crate) fn parse_size(s: &str) -> Result<(usize, usize)> {
    let num = |t: &str| -> Result<usize> {
        t.trim()
            .parse::<usize>()
            .ok()
            .filter(|&v| v > 0)
            .with_context(|| format!("invalid --size `{s}`: expected WxH with positive integers"))
    };
    match s.split_once(['x', 'X']) {
        Some((w, h)) => Ok((num(w)?, num(h)?)),
        None => num(s).map(|v| (v, v)),
    }
}

fn read_dem(path: &Path, what: &str, args: &SynthArgs, ctx: &Ctx) -> Result<Heightfield> {
    let hf = super::read_raster(path, &args.read, ctx)
        .with_context(|| format!("{what} {}", path.display()))?
        .heightfield;
    Ok(hf)
}

fn fill_if_needed(mut hf: Heightfield, what: &str, path: &Path, ctx: &Ctx) -> Result<Heightfield> {
    if hf.has_voids() {
        let voids = hf.void_count();
        fill_voids(&mut hf, &FillSettings::default())
            .with_context(|| format!("cannot fill the voids of {what} {}", path.display()))?;
        ctx.note(format!(
            "{what} {}: filled {voids} void cells",
            path.display()
        ));
    }
    Ok(hf)
}

impl SynthArgs {
    /// The library settings these options describe (checked by the library).
    pub(crate) fn settings(&self) -> Settings {
        Settings {
            patch_size: self.patch,
            overlap: self.overlap,
            seed: self.seed,
            min_candidates: self.min_candidates,
            validation_tolerance: self.tolerance,
            lambda: self.lambda,
            alpha: self.alpha,
            beta: self.beta,
            gamma: self.gamma,
            exemplar_stride: self.stride,
            ..Settings::default()
        }
    }

    /// Reads exemplars, guide and categorisation map, and checks the settings.
    pub(crate) fn inputs(&self, ctx: &Ctx) -> Result<Inputs> {
        let settings = self.settings();
        settings.check().context("invalid synthesis settings")?;
        if self.exemplars.is_empty() {
            bail!("no exemplar: give at least one --exemplar DEM");
        }
        let cats: Vec<u16> = match &self.exemplar_categories {
            None => vec![0; self.exemplars.len()],
            Some(list) => {
                let cats = list
                    .split(',')
                    .map(|t| {
                        t.trim().parse::<u16>().with_context(|| {
                            format!("invalid --exemplar-categories `{list}`: `{t}` is not 0..65535")
                        })
                    })
                    .collect::<Result<Vec<u16>>>()?;
                if cats.len() != self.exemplars.len() {
                    bail!(
                        "--exemplar-categories names {} categories for {} exemplars",
                        cats.len(),
                        self.exemplars.len()
                    );
                }
                cats
            }
        };
        if self.guide.is_some() && self.guide_from.is_some() {
            bail!("give either --guide or --guide-from, not both");
        }
        if self.guide_from.is_some() != self.blur.is_some() {
            bail!("--guide-from DEM and --blur SIGMA go together");
        }
        let size = self.size.as_deref().map(parse_size).transpose()?;

        let mut exemplars = Vec::with_capacity(self.exemplars.len());
        for (path, &cat) in self.exemplars.iter().zip(&cats) {
            let hf = read_dem(path, "exemplar", self, ctx)?;
            let hf = fill_if_needed(hf, "exemplar", path, ctx)?;
            if hf.width() < settings.patch_size || hf.height() < settings.patch_size {
                bail!(
                    "exemplar {} is {} x {}, smaller than --patch {}",
                    path.display(),
                    hf.width(),
                    hf.height(),
                    settings.patch_size
                );
            }
            exemplars.push(Exemplar::new(hf, cat));
        }
        if let (Some(k), None) = (self.auto_categories, &self.exemplar_categories) {
            let hfs: Vec<Heightfield> = exemplars.iter().map(|e| e.heightfield.clone()).collect();
            let cats = categorize_exemplars(&hfs, k, &settings)
                .context("cannot cluster the exemplars (--auto-categories)")?;
            for (e, c) in exemplars.iter_mut().zip(&cats) {
                e.category = *c;
            }
            let list: Vec<String> = cats.iter().map(|c| c.to_string()).collect();
            ctx.note(format!(
                "exemplar categories (clustered): {}",
                list.join(",")
            ));
        }
        let cell = exemplars[0].heightfield.cell_size();

        let png_check = |path: &Path, g: &Heightfield| -> Result<()> {
            if self.guide_range.is_none() && png_counts(path, g) {
                bail!(
                    "guide {}: a PNG of grey levels (no relief vertical mapping) holds no \
                     heights; give --guide-range auto (the exemplars' heights) or LO,HI (metres)",
                    path.display()
                );
            }
            Ok(())
        };
        let guide = match (&self.guide, &self.guide_from) {
            (Some(path), None) => {
                let g = fill_if_needed(read_dem(path, "guide", self, ctx)?, "guide", path, ctx)?;
                png_check(path, &g)?;
                Some(fit_guide(g, size, cell, self.guide_cell_size, path, ctx)?)
            }
            (None, Some(path)) => {
                let dem = fill_if_needed(
                    read_dem(path, "guide source", self, ctx)?,
                    "guide source",
                    path,
                    ctx,
                )?;
                png_check(path, &dem)?;
                let dem = fit_guide(dem, size, cell, self.guide_cell_size, path, ctx)?;
                let sigma = self.blur.unwrap_or_default();
                Some(guide::gaussian_blur(&dem, sigma).context("invalid --blur")?)
            }
            _ => None,
        };
        let guide_range = self
            .guide_range
            .as_deref()
            .map(parse_guide_range)
            .transpose()?;
        if guide_range.is_some() && guide.is_none() {
            bail!("--guide-range needs --guide or --guide-from");
        }
        if self.guide_cell_size.is_some() && guide.is_none() {
            bail!("--guide-cell-size needs --guide or --guide-from");
        }
        let mut control = match guide {
            Some(g) => Control::guided(g),
            None => {
                let Some((w, h)) = size else {
                    bail!("without a guide, --size WxH is required");
                };
                Control::unguided(w, h)
            }
        };
        if let Some(path) = &self.categories {
            control.categories = Some(read_category_map(path, control.width, control.height)?);
        } else if let (Some(k), Some(g)) = (self.auto_categories, &control.guide) {
            let (mut map, _) = CategoryMap::from_guide_heights(g, k, self.seed)
                .context("cannot cluster the guide's heights (--auto-categories)")?;
            for c in 0..k.min(u16::MAX as usize) as u16 {
                if !exemplars.iter().any(|e| e.category == c) {
                    map.relabel(c, ANY_CATEGORY);
                }
            }
            control.categories = Some(map);
        }
        Ok(Inputs {
            exemplars,
            control,
            settings,
            guide_range,
        })
    }

    /// Reads the inputs, checks the memory, indexes the exemplars, maps the guide's heights
    /// (`--guide-range`), writes `--guide-out` and, with a guide, runs the input validation.
    pub(crate) fn prepare(&self, ctx: &Ctx, progress: &dyn Progress) -> Result<Prepared> {
        let Inputs {
            exemplars,
            mut control,
            settings,
            guide_range,
        } = self.inputs(ctx)?;
        preflight(&exemplars, &control, &settings, ctx)?;
        let index = ExemplarIndex::build(exemplars, &settings, progress)
            .context("cannot index the exemplars")?;
        progress.begin("validating", 0);
        let mut report = None;
        let note_mapping = |m: &RangeMapping| {
            ctx.note(format!(
                "guide heights {:.1}..{:.1} m (patch-window means) mapped onto {:.1}..{:.1} m",
                m.from.0, m.from.1, m.to.0, m.to.1
            ));
        };
        if let Some(g) = control.guide.take() {
            let g = match guide_range {
                Some(GuideRange::Auto) => {
                    let (g, m, r) = guide::fit_range(&g, &index, &control, &settings)
                        .context("--guide-range auto")?;
                    note_mapping(&m);
                    report = Some(r);
                    g
                }
                Some(r) => {
                    let (g, m) = guide::map_range(&g, &index, r).context("--guide-range")?;
                    note_mapping(&m);
                    g
                }
                None => g,
            };
            control.guide = Some(g);
        }
        if let (Some(g), Some(p)) = (&control.guide, &self.guide_out) {
            ctx.write_raster(p, g)?;
        }
        if report.is_none() && control.guide.is_some() {
            report = Some(validate(&index, &control, &settings).context("validation failed")?);
        }
        let mut hint = None;
        if let (Some(r), None, Some(g)) = (&report, guide_range, &control.guide)
            && !r.ok
        {
            let mut c = control.clone();
            c.guide = None;
            let (_, m, auto) = guide::fit_range(g, &index, &c, &settings)?;
            if auto.ok {
                hint = Some(format!(
                    "--guide-range auto would pass (it maps the guide's {:.0}..{:.0} m onto \
                     {:.0}..{:.0} m)",
                    m.from.0, m.from.1, m.to.0, m.to.1
                ));
            }
        }
        Ok(Prepared {
            index,
            control,
            settings,
            report,
            hint,
        })
    }
}

/// Inputs indexed, guide mapped and validated (see [`SynthArgs::prepare`]).
pub(crate) struct Prepared {
    pub(crate) index: ExemplarIndex,
    pub(crate) control: Control,
    pub(crate) settings: Settings,
    /// The input validation, with a guide.
    pub(crate) report: Option<ValidationReport>,
    /// What would make a failing validation pass.
    pub(crate) hint: Option<String>,
}

/// Reads a categorisation map: raw sample counts (grey PNG 0..255 or 0..65535, or any raster's
/// values) rounded to category ids, nearest-resampled to `w x h`.
fn read_category_map(path: &Path, w: usize, h: usize) -> Result<CategoryMap> {
    let opts = relief_io::ReadOptions {
        png: relief_io::PngMode::Grey {
            offset: 0.0,
            scale: 1.0,
        },
        ..Default::default()
    };
    let map = relief_io::read(path, &opts)
        .with_context(|| format!("cannot read categorisation map {}", path.display()))?
        .heightfield;
    let (mw, mh) = (map.width(), map.height());
    let mut ids = Vec::with_capacity(w * h);
    for y in 0..h {
        let sy = (y * mh / h).min(mh - 1);
        for x in 0..w {
            let sx = (x * mw / w).min(mw - 1);
            let v = map.get(sx, sy);
            if !(v.is_finite() && v >= 0.0 && v <= ANY_CATEGORY as f32) {
                bail!(
                    "categorisation map {}: value {v} at ({sx}, {sy}) is not a category id 0..65535",
                    path.display()
                );
            }
            ids.push(v.round() as u16);
        }
    }
    Ok(CategoryMap::from_raster(w, h, ids)?)
}

/// RGB image of a seam map: one muted colour per patch, seam cells white.
pub(crate) fn seam_map_rgb(out: &Synthesis) -> Vec<u8> {
    let m = &out.seam_map;
    let mut rgb = Vec::with_capacity(m.width * m.height * 3);
    for (&src, &seam) in m.source.iter().zip(&m.seam) {
        if seam {
            rgb.extend_from_slice(&[255, 255, 255]);
        } else if src == u32::MAX {
            rgb.extend_from_slice(&[0, 0, 0]);
        } else {
            // A fixed hash of the placement index: neighbours get distinct colours.
            let mut z = (src as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            z ^= z >> 29;
            rgb.extend_from_slice(&[
                60 + (z & 0x7f) as u8,
                60 + ((z >> 8) & 0x7f) as u8,
                60 + ((z >> 16) & 0x7f) as u8,
            ]);
        }
    }
    rgb
}

/// Working bytes per exemplar cell that does not depend on the candidate count (summed-area
/// tables in f64, the exemplar itself, block descriptors).
const EXEMPLAR_BYTES_PER_CELL: f64 = 40.0;

/// Working bytes per candidate patch position, beyond its PCA coordinates (k-means cluster
/// ids, kd-tree nodes, hash-table entries).
const CANDIDATE_BYTES: f64 = 64.0;

/// Working bytes per output cell (the canvas, the guide, the seam map, the blending buffers).
const OUTPUT_BYTES_PER_CELL: f64 = 48.0;

/// Pre-flight estimate of a synthesis (issue 18): the candidate index of the exemplars and
/// the output canvases, checked against `--max-memory` before any index is built.
pub(crate) fn preflight(
    exemplars: &[Exemplar],
    control: &Control,
    settings: &Settings,
    ctx: &Ctx,
) -> Result<()> {
    use crate::memory::part;
    let stride = settings.exemplar_stride.max(1) as f64;
    let mut ex_cells = 0.0;
    let mut candidates = 0.0;
    for e in exemplars {
        let (w, h) = (e.heightfield.width() as f64, e.heightfield.height() as f64);
        ex_cells += w * h;
        let p = settings.patch_size as f64;
        candidates +=
            ((w - p + 1.0).max(0.0) / stride).ceil() * ((h - p + 1.0).max(0.0) / stride).ceil();
    }
    // Two PCA spaces (left and top overlaps), f32 coordinates.
    let per_candidate = CANDIDATE_BYTES + 2.0 * 4.0 * settings.pca_dims as f64;
    let out_cells = control.width as f64 * control.height as f64;
    ctx.check_memory(
        "quilt",
        &[&[
            part(
                format!("the index of {} exemplar patches", candidates as u64),
                candidates * per_candidate + ex_cells * EXEMPLAR_BYTES_PER_CELL,
                "smaller (or fewer) --exemplar files, or a larger --stride",
            ),
            part(
                format!("the {} x {} output canvases", control.width, control.height),
                out_cells * OUTPUT_BYTES_PER_CELL,
                "a smaller --size (or guide)",
            ),
        ]],
    )
}

/// Reads the inputs, synthesizes and writes OUT (and the seam map) atomically.
pub(crate) fn run(mut args: Args, ctx: &Ctx) -> Result<()> {
    let mut outputs = vec![(args.output.as_path(), crate::outputs::OutKind::Raster)];
    outputs.extend(args.synth.output_paths());
    outputs.extend(
        args.seam_map
            .as_deref()
            .map(|p| (p, crate::outputs::OutKind::Png)),
    );
    ctx.check_outputs(&args.synth.input_paths(), &outputs)?;
    // The terrain, the guide as used and the seam map appear together or not at all.
    let targets: Vec<&Path> = outputs.iter().map(|&(p, _)| p).collect();
    let staged = crate::staging::Outputs::new(&targets)?;
    if let Some(g) = &args.synth.guide_out {
        args.synth.guide_out = Some(staged.path(g));
    }
    let progress = ctx.progress();
    let Prepared {
        index,
        control,
        mut settings,
        report,
        hint,
    } = args.synth.prepare(ctx, &progress)?;
    if let Some(r) = &report
        && !r.ok
    {
        if args.no_validate {
            ctx.note(format!(
                "input validation failed, synthesizing anyway (--no-validate): {} of {} guide \
                 blocks have fewer than {} candidates",
                r.failing.len(),
                r.blocks.len(),
                r.min_candidates
            ));
        } else {
            bail!(
                "synthesis failed: input validation failed: {r}{}",
                hint.map_or_else(String::new, |h| format!("; {h}"))
            );
        }
    }
    // Validated above.
    settings.enforce_validation = false;
    settings.cut = match args.cut {
        CutArg::Dp => CutMethod::DynamicProgramming,
        CutArg::Greedy => CutMethod::Greedy,
    };
    settings.blend = match args.blend {
        BlendArg::Poisson => Settings::default().blend,
        BlendArg::Feather => Blend::Feather {
            radius: (settings.overlap as f32 / 4.0).max(1.0),
        },
        BlendArg::None => Blend::None,
    };
    let out = synthesize(&index, &control, &settings, &progress).context("synthesis failed")?;
    progress.begin("writing", 0);
    ctx.write_raster(&staged.path(&args.output), &out.heightfield)?;
    if let Some(png) = &args.seam_map {
        relief_io::write_rgb_png(
            &staged.path(png),
            out.seam_map.width,
            out.seam_map.height,
            &seam_map_rgb(&out),
        )
        .with_context(|| format!("cannot write {}", png.display()))?;
    }
    staged.commit()?;
    drop(progress);
    let s = &out.stats;
    ctx.note(format!(
        "wrote {} ({} x {}): {} patches on a {} x {} grid, {:.0} candidates per block, {} translations applied, {} rejected (|h| > {} m)",
        args.output.display(),
        out.heightfield.width(),
        out.heightfield.height(),
        s.patches,
        s.grid.0,
        s.grid.1,
        s.mean_candidates,
        s.translations_applied,
        s.translations_rejected,
        settings.lambda
    ));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_size;

    #[test]
    fn size_argument() {
        assert_eq!(parse_size("128x96").unwrap(), (128, 96));
        assert_eq!(parse_size("64").unwrap(), (64, 64));
        assert!(parse_size("0x4").is_err());
        assert!(parse_size("axb").is_err());
    }
}
