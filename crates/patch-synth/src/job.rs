//! Job layer: the `quilt` and `validate` jobs as serde settings with one `check` and
//! one `run` on heightfields, shared by the CLI commands and the pipeline stage.
//!
//! A job takes the exemplars, the guide DEM as read (any cell size, any height units) and an
//! optional categorisation raster, and does every step between reading and writing: void
//! filling, exemplar categories (given or clustered), the guide on the output grid at its own
//! physical scale ([`guide::fit_to_grid`]), its low-pass, the categorisation map (given or from
//! the guide's height classes), the exemplar index, the guide's height mapping
//! ([`GuideRange`]) and the input validation (section 4), then the synthesis.

use std::time::Instant;

use relief_heightfield::fill::{FillSettings, fill_voids};
use relief_heightfield::{Heightfield, Progress};
use serde::{Deserialize, Serialize};

use crate::category::{ANY_CATEGORY, CategoryMap, categorize_exemplars, categorize_regions};
use crate::error::{PatchSynthError, Result};
use crate::guide::{self, GuideFit, GuideRange, RangeMapping};
use crate::index::{Exemplar, ExemplarIndex};
use crate::settings::Settings;
use crate::synth::{Control, Synthesis, synthesize};
use crate::validate::{ValidationReport, validate};

/// How the guide DEM given to a job becomes the guide of the synthesis.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GuideSetup {
    /// Cell size `(x, y)` in metres of the guide DEM, replacing the one it carries (a PNG or
    /// NPY stores none); it is resampled from it to the exemplars' cell size.
    pub cell_size: Option<(f64, f64)>,
    /// Standard deviation in cells of a Gaussian low-pass applied once the guide is on the
    /// output grid (a guide made from a detailed DEM); `None` = used as given.
    pub blur: Option<f32>,
    /// Linear height mapping once the exemplars are indexed: `auto` (onto the exemplar
    /// patches' range, checked by the validation, see [`guide::fit_range`]) or
    /// `{"metres": [lo, hi]}`; `None` = the guide's heights as they are.
    pub range: Option<GuideRange>,
}

/// The input check of section 4 on its own (`relief validate`): everything a synthesis reads,
/// without the synthesis.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ValidateJob {
    /// Synthesis settings (patch size, overlap, validation thresholds, ...).
    pub settings: Settings,
    /// Output size `(width, height)`; `None` = the guide's extent at the exemplars' cell size
    /// (required without a guide).
    pub size: Option<(usize, usize)>,
    /// How the guide is made.
    pub guide: GuideSetup,
    /// Category id of each exemplar, in input order (default: all 0, or clustered).
    pub exemplar_categories: Option<Vec<u16>>,
    /// Cluster the exemplars into K categories by their block averages (section 4) unless
    /// `exemplar_categories` is given, and, without a categorisation map, make one from the
    /// guide's heights clustered into K classes (lowest class = lowest exemplar category; a
    /// class no exemplar has accepts any).
    pub auto_categories: Option<usize>,
    /// Cluster the exemplars' patches into K categories by their block averages (section 4),
    /// so regions of one exemplar get different categories ([`categorize_regions`]), and,
    /// without a categorisation map, make one from the guide's heights clustered into K
    /// classes (class i accepts the patches of category i, the i-th lowest). Not with
    /// `auto_categories` or painted exemplar regions.
    pub region_categories: Option<usize>,
    /// Once the validation passes, keep only the small exemplar subset its greedy set cover
    /// picks (section 4: "a huge amount of redundant data increases significantly the
    /// processing cost"), re-index and re-validate it; a subset that fails keeps them all.
    pub auto_subset: bool,
}

/// Guided patch-based synthesis (`relief quilt`): the validation job's fields (the same JSON,
/// the same checks) run through to the synthesis. With `settings.enforce_validation` a failing
/// validation is an error ([`PatchSynthError::Validation`], with a suggested guide mapping
/// when one passes). Dereferences to its [`ValidateJob`], so `job.settings` reads and writes
/// the settings.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct QuiltJob(pub ValidateJob);

impl std::ops::Deref for QuiltJob {
    type Target = ValidateJob;
    fn deref(&self) -> &ValidateJob {
        &self.0
    }
}

impl std::ops::DerefMut for QuiltJob {
    fn deref_mut(&mut self) -> &mut ValidateJob {
        &mut self.0
    }
}

/// The rasters a job reads.
#[derive(Debug, Clone, Default)]
pub struct JobInputs {
    /// Exemplar DEMs (voids are filled; the first one's cell size is the output's).
    pub exemplars: Vec<Heightfield>,
    /// Guide DEM as read (any cell size; voids are filled).
    pub guide: Option<Heightfield>,
    /// Categorisation raster: category ids (65535 = any), nearest-resampled to the output.
    pub categories: Option<Heightfield>,
    /// Painted category regions of the exemplars: none, or one raster of category ids per
    /// exemplar, in order, at the exemplar's size ([`Exemplar::with_regions`]).
    pub exemplar_regions: Vec<Heightfield>,
}

/// Figures of the preparation (inputs, guide, index, validation).
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct PrepareFigures {
    /// Void cells filled per exemplar.
    pub exemplar_voids_filled: Vec<usize>,
    /// Void cells filled in the guide DEM.
    pub guide_voids_filled: usize,
    /// Category of each exemplar.
    pub exemplar_categories: Vec<u16>,
    /// True when the categories were clustered (`auto_categories` or `region_categories`).
    pub categories_clustered: bool,
    /// Candidate patches per category `(category, patches)`, ascending category.
    pub patches_per_category: Vec<(u16, usize)>,
    /// The exemplars kept by `auto_subset` (input order), when it dropped any.
    pub exemplar_subset: Option<Vec<usize>>,
    /// Where the guide went on the output grid.
    pub guide_fit: Option<GuideFit>,
    /// The guide's height mapping.
    pub guide_mapping: Option<RangeMapping>,
    /// Output size `(width, height)`.
    pub output_size: (usize, usize),
    /// Candidate patches in the index.
    pub candidate_patches: usize,
    /// Candidates the validation asked per block.
    pub required_candidates: usize,
    /// Validation passed (`None`: not run, an unguided synthesis).
    pub validation_ok: Option<bool>,
    /// Guide blocks failing the validation, of `validation_blocks`.
    pub failing_blocks: usize,
    /// Guide blocks checked.
    pub validation_blocks: usize,
    /// Seconds to build the index.
    pub index_seconds: f64,
    /// Seconds of the guide mapping and validation.
    pub validation_seconds: f64,
}

/// Everything a synthesis needs, built and checked by [`ValidateJob::prepare`].
#[derive(Debug)]
pub struct Prepared {
    /// The exemplar index.
    pub index: ExemplarIndex,
    /// Output size, guide as used and categorisation map.
    pub control: Control,
    /// The input validation (always with a guide; without, only for [`ValidateJob`]).
    pub report: Option<ValidationReport>,
    /// Figures so far.
    pub figures: PrepareFigures,
}

/// Result of [`ValidateJob::run`].
#[derive(Debug)]
pub struct ValidateOutput {
    /// The report (its `suggestion` names a guide mapping that would pass, if any).
    pub report: ValidationReport,
    /// The guide exactly as used (mapped, on the output grid).
    pub guide: Option<Heightfield>,
    /// Figures.
    pub figures: PrepareFigures,
}

/// Figures of a quilt job.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct QuiltFigures {
    /// The preparation's figures.
    pub prepare: PrepareFigures,
    /// Patches placed.
    pub patches: usize,
    /// Synthesis grid (columns, rows).
    pub grid: (usize, usize),
    /// Mean candidates scored per block.
    pub mean_candidates: f64,
    /// Vertical translations applied.
    pub translations_applied: usize,
    /// Translations rejected (`|h| > lambda`).
    pub translations_rejected: usize,
    /// Distinct source patches over patches placed (1 = no patch used twice).
    pub distinct_source_share: f64,
    /// Most placements of one source patch.
    pub max_source_repeats: usize,
    /// Seconds of the synthesis proper.
    pub synthesis_seconds: f64,
}

/// Result of [`QuiltJob::run`].
#[derive(Debug)]
pub struct QuiltOutput {
    /// The synthesis (terrain, seam map, placements, statistics).
    pub synthesis: Synthesis,
    /// The guide exactly as used.
    pub guide: Option<Heightfield>,
    /// The input validation (with a guide), reported even when not enforced.
    pub report: Option<ValidationReport>,
    /// Categorisation map as used.
    pub categories: Option<CategoryMap>,
    /// Figures.
    pub figures: QuiltFigures,
}

fn control_error(name: &'static str, reason: impl Into<String>) -> PatchSynthError {
    PatchSynthError::InvalidControl {
        name,
        reason: reason.into(),
    }
}

/// A painted region raster of `exemplar` as category ids: the same size, whole numbers in
/// 0..65535 (65535, "any", is for the categorisation map only).
fn region_ids(map: &Heightfield, exemplar: &Heightfield) -> Result<Vec<u16>> {
    if (map.width(), map.height()) != (exemplar.width(), exemplar.height()) {
        return Err(control_error(
            "exemplar_regions",
            format!(
                "a {} x {} region map for a {} x {} exemplar",
                map.width(),
                map.height(),
                exemplar.width(),
                exemplar.height()
            ),
        ));
    }
    map.as_slice()
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            if v.is_finite() && v >= 0.0 && v < ANY_CATEGORY as f32 {
                Ok(v.round() as u16)
            } else {
                Err(control_error(
                    "exemplar_regions",
                    format!(
                        "value {v} at ({}, {}) is not a category id 0..65534",
                        i % map.width(),
                        i / map.width()
                    ),
                ))
            }
        })
        .collect()
}

fn filled(mut hf: Heightfield) -> Result<(Heightfield, usize)> {
    let voids = hf.void_count();
    if voids > 0 {
        fill_voids(&mut hf, &FillSettings::default())?;
    }
    Ok((hf, voids))
}

/// Working bytes per exemplar cell that does not depend on the candidate count (summed-area
/// tables in f64, the exemplar itself, block descriptors).
const EXEMPLAR_BYTES_PER_CELL: f64 = 40.0;

/// Working bytes per candidate patch position, beyond its PCA coordinates (k-means cluster
/// ids, kd-tree nodes, hash-table entries).
const CANDIDATE_BYTES: f64 = 64.0;

/// Working bytes per output cell (the canvas, the guide, the seam map, the blending buffers).
const OUTPUT_BYTES_PER_CELL: f64 = 48.0;

/// Pre-flight estimate of a job's working memory ([`ValidateJob::memory`]), before any index
/// is built.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MemoryEstimate {
    /// Candidate patch positions of the exemplars.
    pub candidates: u64,
    /// Bytes of the exemplar index.
    pub index_bytes: f64,
    /// Output size `(width, height)`.
    pub output: (usize, usize),
    /// Bytes of the output canvases.
    pub output_bytes: f64,
}

impl ValidateJob {
    /// The working memory this job would need on `inputs` (cheap: no resampling, no index).
    pub fn memory(&self, inputs: &JobInputs) -> Result<MemoryEstimate> {
        let s = &self.settings;
        let stride = s.exemplar_stride.max(1) as f64;
        let p = s.patch_size as f64;
        let (mut cells, mut candidates) = (0.0, 0.0);
        for e in &inputs.exemplars {
            let (w, h) = (e.width() as f64, e.height() as f64);
            cells += w * h;
            candidates +=
                ((w - p + 1.0).max(0.0) / stride).ceil() * ((h - p + 1.0).max(0.0) / stride).ceil();
        }
        let output = match (self.size, &inputs.guide, inputs.exemplars.first()) {
            (Some(size), _, _) => size,
            (None, Some(g), Some(e)) => {
                let (gx, gy) = self.guide.cell_size.unwrap_or_else(|| g.cell_size());
                let (ex, ey) = e.cell_size();
                (
                    (g.width() as f64 * gx / ex).round() as usize,
                    (g.height() as f64 * gy / ey).round() as usize,
                )
            }
            _ => (0, 0),
        };
        // Two PCA spaces (left and top overlaps), f32 coordinates.
        let per_candidate = CANDIDATE_BYTES + 2.0 * 4.0 * s.pca_dims as f64;
        Ok(MemoryEstimate {
            candidates: candidates as u64,
            index_bytes: candidates * per_candidate + cells * EXEMPLAR_BYTES_PER_CELL,
            output,
            output_bytes: output.0 as f64 * output.1 as f64 * OUTPUT_BYTES_PER_CELL,
        })
    }

    /// Checks every field; the error names the field and the rule.
    pub fn check(&self) -> Result<()> {
        self.settings.check()?;
        if let Some((w, h)) = self.size
            && (w == 0
                || h == 0
                || w.checked_mul(h)
                    .is_none_or(|n| n > crate::grid::MAX_OUTPUT_CELLS))
        {
            return Err(PatchSynthError::setting(
                "size",
                format!("{w}x{h}"),
                format!(
                    "must be positive and at most {} cells",
                    crate::MAX_OUTPUT_CELLS
                ),
            ));
        }
        if let Some((x, y)) = self.guide.cell_size
            && !(x.is_finite() && y.is_finite() && x > 0.0 && y > 0.0)
        {
            return Err(PatchSynthError::setting(
                "guide.cell_size",
                format!("{x},{y}"),
                "must be finite and > 0",
            ));
        }
        if let Some(s) = self.guide.blur
            && !(s.is_finite() && s > 0.0 && s < 1e4)
        {
            return Err(PatchSynthError::setting(
                "guide.blur",
                s,
                "must be in (0, 1e4)",
            ));
        }
        if let Some(GuideRange::Metres(lo, hi)) = self.guide.range
            && !(lo.is_finite() && hi.is_finite() && lo < hi)
        {
            return Err(PatchSynthError::setting(
                "guide.range",
                format!("{lo},{hi}"),
                "must be two finite heights LO < HI",
            ));
        }
        for (name, k) in [
            ("auto_categories", self.auto_categories),
            ("region_categories", self.region_categories),
        ] {
            if let Some(k) = k
                && !(1..=1024).contains(&k)
            {
                return Err(PatchSynthError::setting(name, k, "must be in 1..=1024"));
            }
        }
        if let (Some(_), Some(k)) = (self.auto_categories, self.region_categories) {
            return Err(PatchSynthError::setting(
                "region_categories",
                k,
                "clusters the patches; auto_categories clusters whole exemplars: give one",
            ));
        }
        Ok(())
    }

    /// Reads nothing: checks the inputs against the job, fills voids, sets the categories,
    /// puts the guide on the output grid, indexes the exemplars, maps the guide's heights and
    /// runs the validation (with a guide, or always when `unguided_validation`).
    pub fn prepare(
        &self,
        inputs: JobInputs,
        unguided_validation: bool,
        progress: &dyn Progress,
    ) -> Result<Prepared> {
        self.check()?;
        let settings = &self.settings;
        let mut fig = PrepareFigures::default();
        let exemplars = self.exemplars(inputs.exemplars, inputs.exemplar_regions, &mut fig)?;
        let cell = exemplars[0].heightfield.cell_size();
        let guide = match inputs.guide {
            Some(g) => Some(self.guide_on_grid(g, cell, &mut fig)?),
            None => None,
        };
        if guide.is_none() && (self.guide.range.is_some() || self.guide.blur.is_some()) {
            return Err(control_error(
                "guide",
                "guide.range and guide.blur need a guide",
            ));
        }
        let mut control = match guide {
            Some(g) => Control::guided(g),
            None => {
                let (w, h) = self
                    .size
                    .ok_or_else(|| control_error("size", "without a guide, a size is required"))?;
                Control::unguided(w, h)
            }
        };
        fig.output_size = (control.width, control.height);
        control.categories = self.category_map(inputs.categories.as_ref(), &control, &exemplars)?;
        let t = Instant::now();
        let mut index = ExemplarIndex::build(exemplars, settings, progress)?;
        fig.index_seconds = t.elapsed().as_secs_f64();
        progress.begin("validating", 0);
        let t = Instant::now();
        let mut report =
            self.map_and_validate(&index, &mut control, unguided_validation, &mut fig)?;
        fig.validation_seconds = t.elapsed().as_secs_f64();
        if self.auto_subset
            && let Some(r) = &report
            && r.ok
            && !r.blocks.is_empty()
            && r.cover.len() < index.exemplars.len()
        {
            let mut keep = r.cover.clone();
            keep.sort_unstable();
            let subset: Vec<Exemplar> = keep.iter().map(|&e| index.exemplars[e].clone()).collect();
            let t = Instant::now();
            let sub = ExemplarIndex::build(subset, settings, progress)?;
            let sr = validate(&sub, &control, settings)?;
            if sr.ok {
                fig.index_seconds += t.elapsed().as_secs_f64();
                index = sub;
                report = Some(sr);
                fig.exemplar_subset = Some(keep);
            }
        }
        fig.candidate_patches = index.patches.len();
        fig.required_candidates = settings.required_candidates(index.patches.len());
        fig.patches_per_category = index
            .categories
            .iter()
            .map(|&c| {
                (
                    c,
                    index.patch_categories.iter().filter(|&&p| p == c).count(),
                )
            })
            .collect();
        if let Some(r) = &report {
            fig.validation_ok = Some(r.ok);
            fig.failing_blocks = r.failing.len();
            fig.validation_blocks = r.blocks.len();
        }
        Ok(Prepared {
            index,
            control,
            report,
            figures: fig,
        })
    }

    /// Runs the validation; a failing one is a report with `ok == false`, not an error.
    pub fn run(&self, inputs: JobInputs, progress: &dyn Progress) -> Result<ValidateOutput> {
        let p = self.prepare(inputs, true, progress)?;
        let report = p
            .report
            .ok_or_else(|| control_error("guide", "no report"))?;
        Ok(ValidateOutput {
            report,
            guide: p.control.guide,
            figures: p.figures,
        })
    }

    /// Exemplars filled, size-checked and categorised.
    fn exemplars(
        &self,
        hfs: Vec<Heightfield>,
        regions: Vec<Heightfield>,
        fig: &mut PrepareFigures,
    ) -> Result<Vec<Exemplar>> {
        if hfs.is_empty() {
            return Err(PatchSynthError::NoExemplars);
        }
        if !regions.is_empty() {
            if regions.len() != hfs.len() {
                return Err(control_error(
                    "exemplar_regions",
                    format!("{} region maps for {} exemplars", regions.len(), hfs.len()),
                ));
            }
            if self.auto_categories.is_some() || self.region_categories.is_some() {
                return Err(control_error(
                    "exemplar_regions",
                    "painted regions replace auto_categories and region_categories: give one",
                ));
            }
        }
        let p = self.settings.patch_size;
        let mut out = Vec::with_capacity(hfs.len());
        for (i, hf) in hfs.into_iter().enumerate() {
            if hf.width() < p || hf.height() < p {
                return Err(PatchSynthError::BadExemplar {
                    index: i,
                    width: hf.width(),
                    height: hf.height(),
                    reason: format!("smaller than patch_size {p}"),
                });
            }
            let (hf, voids) = filled(hf)?;
            fig.exemplar_voids_filled.push(voids);
            out.push(Exemplar::new(hf, 0));
        }
        let cats = match (&self.exemplar_categories, self.auto_categories) {
            (Some(c), _) => {
                if c.len() != out.len() {
                    return Err(PatchSynthError::setting(
                        "exemplar_categories",
                        format!("{c:?}"),
                        format!("names {} categories for {} exemplars", c.len(), out.len()),
                    ));
                }
                c.clone()
            }
            (None, Some(k)) => {
                let hfs: Vec<Heightfield> = out.iter().map(|e| e.heightfield.clone()).collect();
                fig.categories_clustered = true;
                categorize_exemplars(&hfs, k, &self.settings)?
            }
            (None, None) => vec![0; out.len()],
        };
        for (e, &c) in out.iter_mut().zip(&cats) {
            e.category = c;
        }
        fig.exemplar_categories = cats;
        let regions = match self.region_categories {
            Some(k) => {
                let hfs: Vec<Heightfield> = out.iter().map(|e| e.heightfield.clone()).collect();
                fig.categories_clustered = true;
                categorize_regions(&hfs, k, &self.settings)?
            }
            None => regions
                .iter()
                .zip(&out)
                .map(|(r, e)| region_ids(r, &e.heightfield))
                .collect::<Result<_>>()?,
        };
        for (e, r) in out.iter_mut().zip(regions) {
            e.regions = Some(r);
        }
        Ok(out)
    }

    /// The guide DEM filled, given its cell size, on the output grid and low-passed.
    fn guide_on_grid(
        &self,
        g: Heightfield,
        cell: (f64, f64),
        fig: &mut PrepareFigures,
    ) -> Result<Heightfield> {
        let (mut g, voids) = filled(g)?;
        fig.guide_voids_filled = voids;
        if let Some((cx, cy)) = self.guide.cell_size {
            g.set_cell_size(cx, cy)?;
        }
        let (g, fit) = guide::fit_to_grid(&g, cell, self.size)?;
        fig.guide_fit = Some(fit);
        match self.guide.blur {
            Some(s) => guide::gaussian_blur(&g, s),
            None => Ok(g),
        }
    }

    /// The categorisation map: the given raster, or the guide's height classes.
    fn category_map(
        &self,
        raster: Option<&Heightfield>,
        control: &Control,
        exemplars: &[Exemplar],
    ) -> Result<Option<CategoryMap>> {
        if let Some(m) = raster {
            return CategoryMap::from_heightfield(m, control.width, control.height).map(Some);
        }
        let k = self.auto_categories.or(self.region_categories);
        let (Some(k), Some(g)) = (k, &control.guide) else {
            return Ok(None);
        };
        let (mut map, _) = CategoryMap::from_guide_heights(g, k, self.settings.seed)?;
        for c in 0..k.min(u16::MAX as usize) as u16 {
            let present = exemplars.iter().any(|e| match &e.regions {
                Some(r) => r.contains(&c),
                None => e.category == c,
            });
            if !present {
                map.relabel(c, ANY_CATEGORY);
            }
        }
        Ok(Some(map))
    }

    /// Maps the guide's heights (`guide.range`) and validates; a failing validation of an
    /// unmapped guide suggests the `auto` mapping when that one passes.
    fn map_and_validate(
        &self,
        index: &ExemplarIndex,
        control: &mut Control,
        unguided_validation: bool,
        fig: &mut PrepareFigures,
    ) -> Result<Option<ValidationReport>> {
        let settings = &self.settings;
        let mut report = None;
        if let Some(g) = control.guide.take() {
            let g = match self.guide.range {
                Some(GuideRange::Auto) => {
                    let (g, m, r) = guide::fit_range(&g, index, control, settings)?;
                    fig.guide_mapping = Some(m);
                    report = Some(r);
                    g
                }
                Some(r) => {
                    let (g, m) = guide::map_range(&g, index, r)?;
                    fig.guide_mapping = Some(m);
                    g
                }
                None => g,
            };
            control.guide = Some(g);
        }
        if report.is_none() && (control.guide.is_some() || unguided_validation) {
            report = Some(validate(index, control, settings)?);
        }
        if let (Some(r), None, Some(g)) = (&mut report, self.guide.range, &control.guide)
            && !r.ok
        {
            let mut c = control.clone();
            c.guide = None;
            let (_, m, auto) = guide::fit_range(g, index, &c, settings)?;
            if auto.ok {
                r.suggestion = Some(format!(
                    "guide range auto would pass (it maps the guide's {:.0}..{:.0} m onto \
                     {:.0}..{:.0} m)",
                    m.from.0, m.from.1, m.to.0, m.to.1
                ));
            }
        }
        Ok(report)
    }
}

impl QuiltJob {
    /// The validation part of this job.
    pub fn validate_job(&self) -> ValidateJob {
        self.0.clone()
    }

    /// Checks every field; the error names the field and the rule.
    pub fn check(&self) -> Result<()> {
        self.validate_job().check()
    }

    /// Prepares (see [`ValidateJob::prepare`]), refuses a failing validation when
    /// `settings.enforce_validation` is set, and synthesizes.
    pub fn run(&self, inputs: JobInputs, progress: &dyn Progress) -> Result<QuiltOutput> {
        let Prepared {
            index,
            control,
            report,
            figures,
        } = self.validate_job().prepare(inputs, false, progress)?;
        if let Some(r) = &report
            && !r.ok
            && self.settings.enforce_validation
        {
            return Err(PatchSynthError::Validation(Box::new(r.clone())));
        }
        let settings = Settings {
            // Validated above (and reported when not enforced).
            enforce_validation: false,
            ..self.settings.clone()
        };
        let t = Instant::now();
        let synthesis = synthesize(&index, &control, &settings, progress)?;
        let synthesis_seconds = t.elapsed().as_secs_f64();
        let (distinct_source_share, max_source_repeats) = reuse(&synthesis);
        let s = &synthesis.stats;
        let figures = QuiltFigures {
            prepare: figures,
            patches: s.patches,
            grid: s.grid,
            mean_candidates: s.mean_candidates,
            translations_applied: s.translations_applied,
            translations_rejected: s.translations_rejected,
            distinct_source_share,
            max_source_repeats,
            synthesis_seconds,
        };
        Ok(QuiltOutput {
            synthesis,
            guide: control.guide,
            report,
            categories: control.categories,
            figures,
        })
    }
}

/// Share of distinct source patches among the placements, and the most placements of one.
pub fn reuse(out: &Synthesis) -> (f64, usize) {
    let mut ids: Vec<(u32, u32, u32)> = out
        .placements
        .iter()
        .map(|p| (p.patch.exemplar, p.patch.y, p.patch.x))
        .collect();
    if ids.is_empty() {
        return (1.0, 0);
    }
    ids.sort_unstable();
    let mut distinct = 0;
    let mut most = 0;
    let mut run = 0;
    for (i, &id) in ids.iter().enumerate() {
        if i == 0 || id != ids[i - 1] {
            distinct += 1;
            run = 0;
        }
        run += 1;
        most = most.max(run);
    }
    (distinct as f64 / ids.len() as f64, most)
}

#[cfg(test)]
mod tests;
