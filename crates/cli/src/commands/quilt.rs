//! `relief quilt OUT --exemplar E [--exemplar E2 ...] (--guide G | --guide-from DEM --blur S)
//! [--categories MAP] --size WxH --patch P --overlap O --seed S`: guided patch-based terrain
//! synthesis (Cruz et al. 2015, relief-patch-synth). The inputs shared with `relief validate`
//! live in [`SynthArgs`].

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use relief_heightfield::fill::{FillSettings, fill_voids};
use relief_heightfield::{Heightfield, Progress};
use relief_patch_synth::{
    ANY_CATEGORY, Blend, CategoryMap, Control, CutMethod, Exemplar, Settings, Synthesis,
    categorize_exemplars, guide, quilt,
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
    /// Map the guide's heights before use: `auto` maps its 2-98 % range onto the exemplars'
    /// 2-98 % range (a guide from another DEM, or a PNG sketch read as 0-255); `LO,HI` maps it
    /// onto LO..HI metres. Default: the guide's heights as they are.
    #[arg(long, value_name = "auto|LO,HI", allow_hyphen_values = true)]
    pub(crate) guide_range: Option<String>,
    /// Also write the guide exactly as used (mapped, resampled to the output grid).
    #[arg(long, value_name = "FILE")]
    pub(crate) guide_out: Option<PathBuf>,
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

/// The guide on the output grid. With `--size` it is resampled to that size (its extent maps
/// onto the output); without, to the exemplars' cell size over its own extent, so the output
/// covers the guide's ground and keeps its georeference. Patches are copied cell for cell, so
/// the output has the exemplars' cells: when the guide's cells differ from them (a `--size`
/// that does not match the guide's extent), a note says how much the guide is scaled and the
/// output carries no georeference.
fn fit_guide(
    g: Heightfield,
    size: Option<(usize, usize)>,
    cell: (f64, f64),
    path: &Path,
    ctx: &Ctx,
) -> Result<Heightfield> {
    let (gx, gy) = g.cell_size();
    let (w, h) = match size {
        Some(s) => s,
        None => {
            let w = (g.width() as f64 * gx / cell.0).round().max(1.0) as usize;
            let h = (g.height() as f64 * gy / cell.1).round().max(1.0) as usize;
            if w.saturating_mul(h) > MAX_GUIDE_CELLS {
                bail!(
                    "guide {} covers {w} x {h} cells of the exemplars' {:.2} x {:.2} m: give \
                     --size WxH",
                    path.display(),
                    cell.0,
                    cell.1
                );
            }
            (w, h)
        }
    };
    let mut g = if (w, h) != (g.width(), g.height()) {
        g.resample(w, h)
            .with_context(|| format!("cannot resample guide {}", path.display()))?
    } else {
        g
    };
    let (ncx, ncy) = g.cell_size();
    let (sx, sy) = (cell.0 / ncx, cell.1 / ncy);
    if (sx - 1.0).abs() > 0.01 || (sy - 1.0).abs() > 0.01 {
        ctx.note(format!(
            "guide {}: {ncx:.2} x {ncy:.2} m cells on the output grid, synthesised with the \
             exemplars' {:.2} x {:.2} m cells: the guide's features are scaled x{sx:.2} x \
             {sy:.2} and the output is not georeferenced (omit --size to keep its extent)",
            path.display(),
            cell.0,
            cell.1
        ));
        g.set_georef(None);
    }
    g.set_cell_size(cell.0, cell.1)?;
    Ok(g)
}

/// The `p`-quantile (0..1) of the finite values of `v` (subsampled to at most ~1 M values).
fn quantile(v: &[f32], p: f64) -> Option<f64> {
    let step = (v.len() / (1 << 20)).max(1);
    let mut s: Vec<f32> = v
        .iter()
        .step_by(step)
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    if s.is_empty() {
        return None;
    }
    s.sort_by(f32::total_cmp);
    let i = ((s.len() - 1) as f64 * p).round() as usize;
    Some(s[i] as f64)
}

/// Applies `--guide-range` to the guide (see [`SynthArgs::guide_range`]).
fn map_guide(g: Heightfield, spec: &str, exemplars: &[Exemplar], ctx: &Ctx) -> Result<Heightfield> {
    let (glo, ghi) = match (quantile(g.as_slice(), 0.02), quantile(g.as_slice(), 0.98)) {
        (Some(a), Some(b)) => (a, b),
        _ => bail!("--guide-range: the guide has no values"),
    };
    let (lo, hi) = if spec.trim().eq_ignore_ascii_case("auto") {
        let all: Vec<f32> = exemplars
            .iter()
            .flat_map(|e| e.heightfield.as_slice().iter().copied())
            .collect();
        match (quantile(&all, 0.02), quantile(&all, 0.98)) {
            (Some(a), Some(b)) => (a, b),
            _ => bail!("--guide-range auto: the exemplars have no values"),
        }
    } else {
        crate::ctx::parse_height_range(spec)
            .map_err(|e| anyhow::anyhow!("invalid --guide-range {e} (or auto)"))?
    };
    let span = (ghi - glo).max(f64::MIN_POSITIVE);
    ctx.note(format!(
        "guide heights {glo:.1}..{ghi:.1} m (2-98 %) mapped onto {lo:.1}..{hi:.1} m"
    ));
    Ok(g.map(|v| (lo + (v as f64 - glo) / span * (hi - lo)) as f32))
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

        let guide = match (&self.guide, &self.guide_from) {
            (Some(path), None) => {
                let g = fill_if_needed(read_dem(path, "guide", self, ctx)?, "guide", path, ctx)?;
                Some(fit_guide(g, size, cell, path, ctx)?)
            }
            (None, Some(path)) => {
                let dem = fill_if_needed(
                    read_dem(path, "guide source", self, ctx)?,
                    "guide source",
                    path,
                    ctx,
                )?;
                let dem = fit_guide(dem, size, cell, path, ctx)?;
                let sigma = self.blur.unwrap_or_default();
                Some(guide::gaussian_blur(&dem, sigma).context("invalid --blur")?)
            }
            _ => None,
        };
        let guide = match (guide, &self.guide_range) {
            (Some(g), Some(spec)) => Some(map_guide(g, spec, &exemplars, ctx)?),
            (g, None) => g,
            (None, Some(_)) => bail!("--guide-range needs --guide or --guide-from"),
        };
        if let (Some(g), Some(p)) = (&guide, &self.guide_out) {
            ctx.write_raster(p, g)?;
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
        })
    }
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
    let Inputs {
        exemplars,
        control,
        mut settings,
    } = args.synth.inputs(ctx)?;
    preflight(&exemplars, &control, &settings, ctx)?;
    settings.enforce_validation = !args.no_validate;
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
    let progress = ctx.progress();
    let out = quilt(exemplars, &control, &settings, &progress).context("synthesis failed")?;
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
