//! Stage `quilt`: guided patch-based synthesis (Cruz et al. 2015, relief-patch-synth) from
//! exemplars cut out of the current terrain.
//!
//! Two runs, each with the input validation of section 4 reported before the synthesis:
//! * **volcano**: the guide comes from another real DEM, `fixtures/volcano.json` (Maunga Whau,
//!   87 x 61 cells), enlarged to the terrain's width, its heights mapped linearly onto the
//!   terrain's 10..90 % height range and low-passed; the four quadrants of the terrain are the
//!   exemplars, clustered into two categories by their block averages (section 4), and the
//!   categorisation map is the guide's heights clustered into two classes (low class = the low
//!   exemplars). Shows guide, categories, result and seam map.
//! * **holdout** (the quality protocol with a known answer): the left half of the terrain is the
//!   exemplar and the low-pass of the right half the guide; the result is compared with the
//!   right half it should resemble.
//!
//! Quality table: guide fidelity (RMSE of the low-pass of the output against the guide), seam
//! visibility (mean gradient on seams / elsewhere), spectral slope and slope-histogram distance
//! against the exemplars (with the held-out truth as a baseline). The terrain handed to the next
//! stage is unchanged unless `replace_terrain` is set.

use anyhow::{Context, Result};
use relief_heightfield::fill::{FillSettings, fill_voids};
use relief_heightfield::metrics::{radial_power_spectrum, rmse, spectral_slope};
use relief_heightfield::{Heightfield, Progress};
use relief_patch_synth::{
    ANY_CATEGORY, CategoryMap, Control, Exemplar, ExemplarIndex, Settings, Synthesis,
    categorize_exemplars, guide, quality, synthesize, validate,
};
use serde::Deserialize;

use super::{Stage, StageCx, Tolerance};

/// Tolerance of the quilt goldens: synthesis is deterministic for a seed, so reruns agree to
/// float rounding; a flipped patch choice (a real change) moves cells by tens of metres.
const QUILT_TOLERANCE: Tolerance = Tolerance {
    max_abs_m: 0.5,
    rmse_m: 0.05,
};

/// Parameters of the `quilt` stage (JSON `params`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct QuiltParams {
    /// Patch side in cells; 0 = an eighth of the exemplar quadrant's side, rounded down to a
    /// multiple of 4, in 16..=64 (32 on the 512 x 512 fixture, 16 on the 128 x 128 golden crop).
    pub(crate) patch: usize,
    /// Overlap in cells; 0 = patch / 4.
    pub(crate) overlap: usize,
    /// Low-pass factor of the guides (`guide::lowpass_resample`); 0 = patch / 4.
    pub(crate) lowpass: usize,
    /// Number of exemplar categories and guide height classes of the volcano run.
    pub(crate) categories: usize,
    /// Minimum candidates per guide block reported by the validation.
    pub(crate) min_candidates: usize,
    /// Hand the volcano-guided result to the next stages instead of the input terrain.
    pub(crate) replace_terrain: bool,
}

impl Default for QuiltParams {
    fn default() -> Self {
        Self {
            patch: 0,
            overlap: 0,
            lowpass: 0,
            categories: 2,
            min_candidates: 500,
            replace_terrain: false,
        }
    }
}

/// The `quilt` stage.
#[derive(Debug, Default)]
pub(crate) struct Quilt(pub(crate) QuiltParams);

/// Numbers of one synthesis for the quality table.
struct Row {
    name: &'static str,
    output: String,
    guide_rmse: f64,
    guide_std: f64,
    truth_rmse: Option<f64>,
    seam_ratio: f64,
    slope_out: f64,
    slope_ex: f64,
    slope_truth: Option<f64>,
    hist_out: f64,
    hist_truth: Option<f64>,
    failing_blocks: usize,
    blocks: usize,
    patches: usize,
    seconds: f64,
}

/// Spectral slope over the report's band: 4 cycles per grid to a quarter of Nyquist.
fn spectral(hf: &Heightfield) -> f64 {
    let (cx, cy) = hf.cell_size();
    let extent = (hf.width() as f64 * cx).max(hf.height() as f64 * cy);
    radial_power_spectrum(hf)
        .and_then(|s| spectral_slope(&s, 4.0 / extent, 0.125 / cx.max(cy)))
        .unwrap_or(f64::NAN)
}

/// Pooled spectral slope of several exemplars: the mean of their slopes.
fn spectral_pooled(ex: &[&Heightfield]) -> f64 {
    ex.iter().map(|h| spectral(h)).sum::<f64>() / ex.len() as f64
}

/// RGB image of a categorisation map (one colour per category, grey = any).
fn category_rgb(map: &CategoryMap) -> Vec<u8> {
    const COLOURS: [[u8; 3]; 6] = [
        [52, 101, 164],
        [204, 120, 40],
        [78, 154, 6],
        [117, 80, 123],
        [193, 45, 45],
        [196, 160, 0],
    ];
    map.ids
        .iter()
        .flat_map(|&id| {
            if id == ANY_CATEGORY {
                [160, 160, 160]
            } else {
                COLOURS[id as usize % COLOURS.len()]
            }
        })
        .collect()
}

/// RGB image of a seam map: one muted colour per patch, seams white.
fn seam_rgb(out: &Synthesis) -> Vec<u8> {
    let m = &out.seam_map;
    m.source
        .iter()
        .zip(&m.seam)
        .flat_map(|(&src, &seam)| {
            if seam {
                [255, 255, 255]
            } else if src == u32::MAX {
                [0, 0, 0]
            } else {
                let mut z = (src as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                z ^= z >> 29;
                [
                    60 + (z & 0x7f) as u8,
                    60 + ((z >> 8) & 0x7f) as u8,
                    60 + ((z >> 16) & 0x7f) as u8,
                ]
            }
        })
        .collect()
}

/// Height below which a fraction `q` of the cells lie.
fn quantile(hf: &Heightfield, q: f64) -> f32 {
    let mut v: Vec<f32> = hf.as_slice().to_vec();
    v.sort_by(f32::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

impl Quilt {
    fn settings(&self, quadrant: usize, seed: u64) -> Settings {
        let p = &self.0;
        let patch = if p.patch > 0 {
            p.patch
        } else {
            (quadrant / 8 / 4 * 4).clamp(16, 64)
        };
        let overlap = if p.overlap > 0 { p.overlap } else { patch / 4 };
        Settings {
            patch_size: patch,
            overlap,
            min_candidates: p.min_candidates,
            // The validation runs separately and is reported; the synthesis goes on.
            enforce_validation: false,
            seed,
            ..Settings::default()
        }
    }

    fn lowpass(&self, s: &Settings) -> usize {
        if self.0.lowpass > 0 {
            self.0.lowpass
        } else {
            (s.patch_size / 4).max(2)
        }
    }
}

impl Stage for Quilt {
    fn name(&self) -> &'static str {
        "quilt"
    }

    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let mut terrain = cx.state.terrain()?.clone();
        if terrain.has_voids() {
            fill_voids(&mut terrain, &FillSettings::default())?;
        }
        let (w, h) = (terrain.width(), terrain.height());
        let settings = self.settings(w.min(h) / 2, cx.config.seed ^ 0x0c12_2015);
        settings.check().context("quilt settings")?;
        let factor = self.lowpass(&settings);
        let progress = cx.progress();
        cx.section.figure("patch_size", settings.patch_size);
        cx.section.figure("overlap", settings.overlap);
        cx.section.figure("guide_lowpass_factor", factor);
        let mut rows = Vec::new();

        // --- volcano: guide from another real DEM, categories from clustering ---------------
        let t = std::time::Instant::now();
        let (qw, qh) = (w / 2, h / 2);
        let quads: Vec<Heightfield> = [(0, 0), (qw, 0), (0, qh), (qw, qh)]
            .iter()
            .map(|&(x, y)| terrain.crop(x, y, qw, qh))
            .collect::<Result<_, _>>()?;
        let k = self.0.categories.max(1);
        let cats = categorize_exemplars(&quads, k, &settings)?;
        let volcano_path = cx
            .config
            .resolve(std::path::Path::new("fixtures/volcano.json"));
        let volcano = relief_io::read(&volcano_path, &relief_io::ReadOptions::default())
            .with_context(|| format!("cannot read {}", volcano_path.display()))?
            .heightfield;
        let gh = ((w as f64 * volcano.height() as f64 / volcano.width() as f64).round() as usize)
            .max(settings.patch_size);
        let (vlo, vhi) = volcano
            .min_max()
            .context("volcano.json has no valid cell")?;
        let (tlo, thi) = (quantile(&terrain, 0.1), quantile(&terrain, 0.9));
        let mapped = volcano
            .resample(w, gh)?
            .map(|v| tlo + (v - vlo) / (vhi - vlo) * (thi - tlo));
        let mut g = guide::lowpass_resample(&mapped, factor)?;
        g.set_cell_size(terrain.cell_size().0, terrain.cell_size().1)?;
        g.set_georef(None);
        let (mut cmap, centres) = CategoryMap::from_guide_heights(&g, k, cx.config.seed)?;
        // Height class c takes the exemplar category c (both ordered by height); a class no
        // exemplar has accepts every category.
        for c in 0..centres.len() as u16 {
            if !cats.contains(&c) {
                cmap.relabel(c, ANY_CATEGORY);
            }
        }
        cx.section.figure(
            "volcano_exemplar_categories",
            cats.iter()
                .map(|c| c.to_string())
                .collect::<Vec<_>>()
                .join(","),
        );
        cx.section.figure(
            "volcano_guide_class_centres_m",
            centres
                .iter()
                .map(|c| format!("{c:.0}"))
                .collect::<Vec<_>>()
                .join(","),
        );
        let exemplars: Vec<Exemplar> = quads
            .iter()
            .zip(&cats)
            .map(|(q, &c)| Exemplar::new(q.clone(), c))
            .collect();
        progress.begin("quilt: indexing the quadrant exemplars", 0);
        let index = ExemplarIndex::build(exemplars, &settings, &progress)?;
        let control = Control::guided(g.clone()).with_categories(cmap.clone());
        let report = validate(&index, &control, &settings)?;
        cx.section.figure("volcano_validation_ok", report.ok);
        cx.section.figure("volcano_validation", report.to_string());
        let out = synthesize(&index, &control, &settings, &progress)?;
        let secs = t.elapsed().as_secs_f64();
        let refs: Vec<&Heightfield> = quads.iter().collect();
        let q = quality::assess(&out.heightfield, &out.seam_map, &g, factor, &refs, None)?;
        rows.push(Row {
            name: "volcano",
            output: format!("{} x {}", out.heightfield.width(), out.heightfield.height()),
            guide_rmse: q.guide_rmse,
            guide_std: q.guide_std,
            truth_rmse: None,
            seam_ratio: q.seam_ratio,
            slope_out: spectral(&out.heightfield),
            slope_ex: spectral_pooled(&refs),
            slope_truth: None,
            hist_out: q.slope_distance,
            hist_truth: None,
            failing_blocks: report.failing.len(),
            blocks: report.blocks.len(),
            patches: out.stats.patches,
            seconds: secs,
        });
        cx.save_raster("quilt_volcano_guide", "volcano guide (low-pass)", &g, None)?;
        cx.save_rgb(
            "quilt_volcano_categories",
            "categorisation map (guide height classes; colour = exemplar category)",
            cmap.width,
            cmap.height,
            &category_rgb(&cmap),
        )?;
        cx.save_raster(
            "quilt_volcano",
            "quilted from the terrain's quadrants under the volcano guide",
            &out.heightfield,
            Some(QUILT_TOLERANCE),
        )?;
        cx.save_rgb(
            "quilt_volcano_seams",
            "seam map (one colour per patch, seams white)",
            out.seam_map.width,
            out.seam_map.height,
            &seam_rgb(&out),
        )?;
        cx.section.figure(
            "volcano_translations_applied",
            out.stats.translations_applied,
        );
        cx.section.figure(
            "volcano_translations_rejected",
            out.stats.translations_rejected,
        );
        let volcano_result = out.heightfield;

        // --- holdout: left half as exemplar, low-pass of the right half as guide -------------
        let t = std::time::Instant::now();
        let half = w / 2;
        let ex = terrain.crop(0, 0, half, h)?;
        let truth = terrain.crop(half, 0, w - half, h)?;
        let g = guide::lowpass_resample(&truth, factor)?;
        progress.begin("quilt: indexing the left half", 0);
        let index = ExemplarIndex::build(vec![Exemplar::new(ex.clone(), 0)], &settings, &progress)?;
        let control = Control::guided(g.clone());
        let report = validate(&index, &control, &settings)?;
        cx.section.figure("holdout_validation_ok", report.ok);
        let out = synthesize(&index, &control, &settings, &progress)?;
        let secs = t.elapsed().as_secs_f64();
        let q = quality::assess(
            &out.heightfield,
            &out.seam_map,
            &g,
            factor,
            &[&ex],
            Some(&truth),
        )?;
        rows.push(Row {
            name: "holdout",
            output: format!("{} x {}", out.heightfield.width(), out.heightfield.height()),
            guide_rmse: q.guide_rmse,
            guide_std: q.guide_std,
            truth_rmse: Some(rmse(&out.heightfield, &truth)?),
            seam_ratio: q.seam_ratio,
            slope_out: spectral(&out.heightfield),
            slope_ex: spectral(&ex),
            slope_truth: Some(spectral(&truth)),
            hist_out: q.slope_distance,
            hist_truth: Some(q.slope_distance_baseline),
            failing_blocks: report.failing.len(),
            blocks: report.blocks.len(),
            patches: out.stats.patches,
            seconds: secs,
        });
        cx.save_raster(
            "quilt_holdout_guide",
            "holdout guide: low-pass of the right half",
            &g,
            None,
        )?;
        cx.save_raster(
            "quilt_holdout",
            "right half re-synthesized from the left half under its low-pass",
            &out.heightfield,
            Some(QUILT_TOLERANCE),
        )?;
        if cx.config.previews {
            cx.save_preview("quilt_holdout_truth", "held-out truth (right half)", &truth)?;
        }
        cx.save_rgb(
            "quilt_holdout_seams",
            "holdout seam map (seams white)",
            out.seam_map.width,
            out.seam_map.height,
            &seam_rgb(&out),
        )?;
        cx.spectrum_plot(
            "quilt holdout: power spectra",
            &[
                ("holdout_exemplar", &ex),
                ("holdout_truth", &truth),
                ("holdout_output", &out.heightfield),
            ],
        );
        let f = |v: f64| format!("{v:.2}");
        let opt = |v: Option<f64>| v.map_or("-".to_string(), f);
        cx.section.table(
            "quilt quality (guide fidelity, seams, spectrum, slopes)",
            &[
                "run",
                "output",
                "guide RMSE (m)",
                "guide std (m)",
                "RMSE vs truth (m)",
                "seam ratio",
                "spectral slope out",
                "spectral slope exemplars",
                "spectral slope truth",
                "slope-hist EMD out vs exemplars (deg)",
                "slope-hist EMD truth vs exemplars (deg)",
                "failing blocks",
                "patches",
                "seconds",
            ],
            rows.iter()
                .map(|r| {
                    vec![
                        r.name.to_string(),
                        r.output.clone(),
                        f(r.guide_rmse),
                        f(r.guide_std),
                        opt(r.truth_rmse),
                        format!("{:.3}", r.seam_ratio),
                        f(r.slope_out),
                        f(r.slope_ex),
                        opt(r.slope_truth),
                        f(r.hist_out),
                        opt(r.hist_truth),
                        format!("{} of {}", r.failing_blocks, r.blocks),
                        r.patches.to_string(),
                        f(r.seconds),
                    ]
                })
                .collect(),
        );
        for r in &rows {
            cx.section
                .headline(&format!("{}_guide_rmse_m", r.name), r.guide_rmse);
            cx.section
                .headline(&format!("{}_seam_ratio", r.name), r.seam_ratio);
            cx.section
                .figure(&format!("{}_slope_hist_emd_deg", r.name), r.hist_out);
        }
        if self.0.replace_terrain {
            cx.state.set_terrain(volcano_result);
        }
        Ok(())
    }
}
