//! Stages of guerin2016 sections 5.2 and 5.3 (relief-dictionary-learning):
//!
//! * `amplify`: sparse amplification of real data. (1) The quality protocol of issue 15: the
//!   left half of the current terrain is the truth; it is box down-sampled x4 and x16 and
//!   amplified back with a multi-resolution dictionary learned (constrained learning, atoms are
//!   exemplar patches) from the RIGHT half, which the truth never overlaps. The table compares
//!   the sparse amplification (the library default, with residual correction and detail-energy
//!   normalisation, and the paper's plain method, `--paper`) with bicubic up-sampling and the
//!   noise-amplification baseline of figure 15: consistency (RMS of box-down(output) - input
//!   over relief), spectral-slope error over the added octaves, slope- and Laplacian-histogram
//!   distances, detail phase swing. The x16 amplification of the protocol is the stage's
//!   golden. (2) The enlargement: the left half at full resolution amplified x16 with the right
//!   half as exemplar (nothing finer exists, so it cannot have seen its answer), shown with
//!   zoomed hillshade crops beside bicubic and, unless `replace_terrain` is false, handed on to
//!   the next stages. (3) A centre window of the left half amplified x256 (`x256_window`,
//!   previews only): the phase swing of the detail every step added, and zoomed crops beside
//!   bicubic. On small inputs (the 128 x 128 golden crop) the factor drops to x4 and the radius
//!   to 1 so the exemplar still holds enough patches.
//! * `sketch`: synthesis from a painted sketch (a ridge stroke, a peak, a valley) with the
//!   input DEM as exemplar (the current terrain if the input has voids), in three incremental x4 steps (figure 12): the sketch of
//!   `n x n` cells becomes a `64 n x 64 n` terrain. The current terrain is unchanged.
//! * `procedural`: inverse procedural modelling (section 5.2, figures 7-8): a centre crop (at
//!   most `max_side`^2) of the input DEM as loaded (the current terrain if the input has
//!   voids; earlier stages may have made the current terrain synthetic) is fitted with
//!   Perlin, ridged multifractal and ridged-sum (figure 4) atoms and with a
//!   constrained-learning reduction of the ridged dictionary; PSNR per family (the paper:
//!   ridged 24.9 dB vs Perlin 20.0 dB on its data). The current terrain is unchanged.

use std::time::Instant;

use anyhow::{Context, Result, bail};
use relief_dictionary_learning::{
    AmplifySettings, BoxProtocolRow, DictionaryChoice, NoiseBaselineSettings, NoiseFamily,
    ProceduralSettings, SynthesisSettings, amplify, amplify_observed, box_protocol, corner_bicubic,
    detail_swing, fit_procedural, noise_amplify, phase_swing, synthesize,
};
use relief_heightfield::{Heightfield, Progress, metrics};
use relief_sparse_core::RasterSettings;
use serde::{Deserialize, Serialize};

use super::{Stage, StageCx, Tolerance};

/// Tolerance of the dictionary goldens: learning, coding and rasterising are deterministic for
/// a seed whatever the thread count, so reruns agree to float rounding; a different atom chosen
/// somewhere (a real change) moves the cells of a primitive by metres.
const DICT_TOLERANCE: Tolerance = Tolerance {
    max_abs_m: 0.5,
    rmse_m: 0.05,
};

/// Number of candidate positions of one exemplar at one step (coarse patch side `a`).
fn candidate_count(exemplar: (usize, usize), a: usize) -> usize {
    let (wl, hl) = (exemplar.0 / 4, exemplar.1 / 4);
    (wl + 1).saturating_sub(a) * (hl + 1).saturating_sub(a)
}

/// Smallest exemplar side the library accepts at radius `r` (6 fine patches).
fn min_exemplar_side(r: f64) -> usize {
    6 * 4 * 2 * r.ceil() as usize
}

/// Parameters of the `amplify` stage (JSON `params`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct AmplifyParams {
    /// The amplify job, the same settings as `relief amplify` ([`AmplifySettings`]); the spec's
    /// fields are merged onto the stage's defaults ([`stage_amplify_job`]: x16, `R` = 2, 256
    /// learned atoms). On small terrains the stage
    /// lowers `steps` and `radius` (recorded in the figures), caps the learned atoms at a
    /// quarter of the candidate patches and mixes `seed` with the spec's. `steps` must be 1..=3.
    pub(crate) job: AmplifySettings,
    /// Also amplify x4 from the truth reduced x4 (a second table block).
    pub(crate) also_x4: bool,
    /// Add the rows of the paper's plain method (`--paper`: no residual correction, no
    /// detail-energy normalisation) next to the job's.
    pub(crate) residual_rows: bool,
    /// Hand the enlargement (the left half of the terrain at full resolution amplified by the
    /// job's factor with the right half as exemplar) on to the next stages (default true).
    pub(crate) replace_terrain: bool,
    /// Side (input cells) of the centre window of the left half amplified x256 (4 steps) for the
    /// report: hillshade crops beside bicubic and the detail phase swing of every step; 0 = off.
    /// Skipped when previews are off (the golden run).
    pub(crate) x256_window: usize,
    /// Side (output cells) of the zoomed hillshade crops shown beside bicubic.
    pub(crate) zoom: usize,
}

/// The amplify job of the default run: x16 with `R` = 2 and 256 learned atoms (3 iterations),
/// sized for the 512 x 512 fixture.
pub(crate) fn stage_amplify_job() -> AmplifySettings {
    AmplifySettings {
        steps: 2,
        radius: 2.0,
        dictionary: DictionaryChoice::Learned {
            n_atoms: 256,
            iterations: 3,
        },
        ..AmplifySettings::default()
    }
}

impl Default for AmplifyParams {
    fn default() -> Self {
        Self {
            job: stage_amplify_job(),
            also_x4: true,
            residual_rows: true,
            replace_terrain: true,
            x256_window: 32,
            zoom: 512,
        }
    }
}

/// The `amplify` stage.
#[derive(Debug, Default)]
pub(crate) struct AmplifyStage(pub(crate) AmplifyParams);

impl AmplifyStage {
    /// Checks the job when the spec is built, so a bad spec fails before any stage runs.
    pub(crate) fn new(p: AmplifyParams) -> Result<Self> {
        p.job.check().context("invalid `job`")?;
        if !(1..=3).contains(&p.job.steps) {
            bail!(
                "invalid parameter `job.steps` = {}: the stage runs 1, 2 or 3 x4 steps",
                p.job.steps
            );
        }
        if p.x256_window != 0 && !(8..=64).contains(&p.x256_window) {
            bail!(
                "invalid parameter `x256_window` = {}: must be 0 (off) or 8..=64 input cells",
                p.x256_window
            );
        }
        if p.zoom < 16 {
            bail!("invalid parameter `zoom` = {}: must be >= 16", p.zoom);
        }
        Ok(Self(p))
    }
}

/// The job's dictionary with its atom count capped at `cap` (a learned dictionary cannot have
/// more atoms than a quarter of the candidate patches), and that count (0 = complete).
fn capped_dictionary(d: DictionaryChoice, cap: usize) -> (DictionaryChoice, usize) {
    match d {
        DictionaryChoice::Complete => (d, 0),
        DictionaryChoice::Learned {
            n_atoms,
            iterations,
        } => {
            let n = n_atoms.min(cap).max(1);
            (
                DictionaryChoice::Learned {
                    n_atoms: n,
                    iterations,
                },
                n,
            )
        }
    }
}

/// `N = n` for a learned dictionary, `complete` for 0.
fn atoms_label(atoms: usize) -> String {
    if atoms == 0 {
        "complete".into()
    } else {
        format!("N = {atoms}")
    }
}

/// One table row of the box protocol: consistency (% of relief), signed spectral-slope error
/// over the added octaves, slope EMD (degrees), Laplacian EMD, detail phase swing, seconds.
fn quality_cells(r: &BoxProtocolRow, seconds: f64) -> Vec<f64> {
    vec![
        100.0 * r.consistency,
        r.slope_signed,
        r.slope_emd,
        r.curvature_emd,
        r.swing,
        seconds,
    ]
}

/// The centre `side x side` crop (clamped to the grid) of a grid.
fn centre_crop(hf: &Heightfield, side: usize) -> Result<Heightfield> {
    let (w, h) = (side.min(hf.width()), side.min(hf.height()));
    Ok(hf.crop((hf.width() - w) / 2, (hf.height() - h) / 2, w, h)?)
}

impl StageCx<'_> {
    /// Hillshades of the same centre crop (`side` output cells) of an amplification and of the
    /// bicubic up-sampling of its input, side by side.
    fn zoom_pair(
        &mut self,
        name: &str,
        caption: &str,
        amplified: &Heightfield,
        bicubic: &Heightfield,
        side: usize,
    ) -> Result<()> {
        let (a, b) = (centre_crop(amplified, side)?, centre_crop(bicubic, side)?);
        let sa = self.save_hillshade(&format!("{name}_sparse"), &a)?;
        let sb = self.save_hillshade(&format!("{name}_bicubic"), &b)?;
        if let (Some(sa), Some(sb)) = (sa, sb) {
            let label = |what: &str| format!("{what} ({} x {} cells)", a.width(), a.height());
            self.section
                .pair((&sa, &label("sparse")), (&sb, &label("bicubic")), caption);
        }
        Ok(())
    }
}

impl Stage for AmplifyStage {
    fn name(&self) -> &'static str {
        "amplify"
    }

    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = &self.0;
        let terrain = cx.state.terrain()?.clone();
        terrain
            .require_complete()
            .context("the amplify stage needs a void-free terrain (run fill_voids first)")?;
        let (w, h) = (terrain.width(), terrain.height());
        let half = w / 2;
        let exemplar = terrain.crop(half, 0, w - half, h)?;
        let ex_side = exemplar.width().min(exemplar.height());
        // Scale the work to the input: x16 needs a coarse input of >= 8 pixels per side and an
        // exemplar of >= 6 fine patches; otherwise x4 and the smallest radius.
        let mut steps = p.job.steps;
        while steps > 1 && half.min(h) / 4usize.pow(steps as u32) < 8 {
            steps -= 1;
        }
        let mut radius = p.job.radius;
        if ex_side < min_exemplar_side(radius) {
            radius = 1.0;
        }
        if ex_side < min_exemplar_side(radius) || half.min(h) / 4usize.pow(steps as u32) < 4 {
            cx.section.note(&format!(
                "terrain {w} x {h} too small for the amplification protocol (the exemplar half \
                 needs >= {} pixels per side); stage skipped",
                min_exemplar_side(1.0)
            ));
            return Ok(());
        }
        let a = 2 * radius.ceil() as usize;
        let (dictionary, atoms) = capped_dictionary(
            p.job.dictionary,
            candidate_count((exemplar.width(), exemplar.height()), a) / 4,
        );
        let f = 4usize.pow(steps as u32);
        let (tw, th) = (half / f * f, h / f * f);
        let truth = terrain.crop(0, 0, tw, th)?;
        cx.section.figure("factor", f);
        cx.section.figure("radius", radius);
        cx.section.figure("atoms", atoms);
        cx.section.figure("truth_size", [tw, th]);
        cx.section
            .figure("exemplar_size", [exemplar.width(), exemplar.height()]);
        let progress = cx.progress();
        let settings = |steps: usize, residual: bool| AmplifySettings {
            radius,
            steps,
            dictionary,
            seed: cx.config.seed ^ 0xa3f1 ^ p.job.seed,
            // `false`: the paper's plain method; `true`: the job as given (by default the
            // residual correction, detail-energy normalisation and diverse atom choice).
            residual_correction: residual && p.job.residual_correction,
            normalize_detail: residual && p.job.normalize_detail,
            diverse_atoms: residual && p.job.diverse_atoms,
            ..p.job
        };
        let mut factors = vec![steps];
        if p.also_x4 && steps > 1 {
            factors.insert(0, 1);
        }
        let mut output = None;
        let mut spectra: Vec<(String, Heightfield)> = Vec::new();
        for &st in &factors {
            let fac = 4usize.pow(st as u32);
            let coarse = truth.downsample_box(fac)?;
            // The truth's own measures: its phase swing is what non-stationary relief gives
            // without any grid (the swing of a small crop is far from 1).
            let mut rows: Vec<(String, Vec<f64>)> = vec![(
                format!("truth (reference) (x{fac})"),
                quality_cells(&box_protocol(&truth, &coarse, &truth, fac)?, 0.0),
            )];
            // `true`: the library default; `false`: the paper's plain method (`--paper`).
            let residual_options: &[bool] = if p.residual_rows {
                &[true, false]
            } else {
                &[true]
            };
            for &residual in residual_options {
                progress.begin(
                    &format!("amplify x{fac}{}", if residual { "" } else { " (--paper)" }),
                    0,
                );
                let t = Instant::now();
                let sct = amplify(&coarse, &exemplar, &settings(st, residual), &progress)
                    .with_context(|| format!("amplification x{fac}"))?;
                let out = sct.rasterize_with_progress(&RasterSettings::default(), &progress)?;
                let secs = t.elapsed().as_secs_f64();
                let q = box_protocol(&truth, &coarse, &out, fac)?;
                let label = if residual {
                    format!(
                        "sparse, {}, s = {}, default (x{fac})",
                        atoms_label(atoms),
                        p.job.sparsity
                    )
                } else {
                    format!("sparse --paper (plain method) (x{fac})")
                };
                rows.push((label, quality_cells(&q, secs)));
                if residual {
                    let tag = format!("x{fac}");
                    cx.section
                        .figure(&format!("consistency_{tag}"), q.consistency);
                    cx.section
                        .figure(&format!("slope_error_{tag}"), q.slope_signed);
                    cx.section
                        .figure(&format!("slope_emd_deg_{tag}"), q.slope_emd);
                    cx.section
                        .figure(&format!("laplacian_emd_{tag}"), q.curvature_emd);
                    cx.section.figure(&format!("swing_{tag}"), q.swing);
                    if st == steps {
                        cx.section.headline("amplify_consistency", q.consistency);
                        cx.section.headline("amplify_slope_error", q.slope_error);
                        cx.section.headline("amplify_swing", q.swing);
                        output = Some((coarse.clone(), out.clone()));
                        spectra.push(("sparse".into(), out));
                    }
                }
            }
            let t = Instant::now();
            let bicubic = coarse.resample(tw, th)?;
            let secs = t.elapsed().as_secs_f64();
            rows.push((
                format!("bicubic (x{fac})"),
                quality_cells(&box_protocol(&truth, &coarse, &bicubic, fac)?, secs),
            ));
            let t = Instant::now();
            let noise = noise_amplify(
                &coarse,
                &NoiseBaselineSettings {
                    factor: fac,
                    seed: cx.config.seed ^ 0x4015e,
                    ..Default::default()
                },
            )?;
            let secs = t.elapsed().as_secs_f64();
            rows.push((
                format!("noise baseline, fig. 15 (x{fac})"),
                quality_cells(&box_protocol(&truth, &coarse, &noise, fac)?, secs),
            ));
            if st == steps {
                spectra.push(("bicubic".into(), bicubic));
                spectra.push(("noise".into(), noise));
            }
            let rows_ref: Vec<(&str, Vec<f64>)> =
                rows.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
            cx.section.numbers(
                &format!(
                    "amplification x{fac} on real data (guerin2016 5.3, issue-15 box protocol)"
                ),
                &format!(
                    "truth: left {tw} x {th} of the terrain; input: truth box down-sampled x{fac} \
                     to {} x {}; dictionary: constrained learning of {atoms} atoms (R = {radius}) \
                     from the right half ({} x {}), never overlapping the truth. consistency = \
                     RMS(box-down(output) - input) / relief, in %; slope error: spectral slope of \
                     the output minus the truth's over the added octaves (input Nyquist to \
                     output Nyquist; negative = too little fine detail); slope EMD: distance \
                     between slope-angle histograms (degrees); Laplacian EMD: distance between \
                     5-point Laplacian histograms (relative to the truth's 99th percentile); \
                     phase swing: max / min detail energy of output - bicubic per phase modulo \
                     4-32 pixels (1 = no grid; the truth row gives the crop's own value)",
                    coarse.width(),
                    coarse.height(),
                    exemplar.width(),
                    exemplar.height()
                ),
                &[
                    "method",
                    "consistency (%)",
                    "slope error",
                    "slope EMD (deg)",
                    "Laplacian EMD",
                    "phase swing",
                    "time (s)",
                ],
                &rows_ref,
            );
        }
        let (coarse, out) = output.context("no amplification output")?;
        cx.save_raster(
            "amplified",
            &format!("amplified x{f} (quality protocol)"),
            &out,
            Some(DICT_TOLERANCE),
        )?;
        cx.before_after(
            "amplify_io",
            &format!("input (truth box-reduced x{f}) and its x{f} amplification"),
            &coarse,
            &out,
        )?;
        cx.before_after("amplify_truth", "truth and the amplification", &truth, &out)?;
        let mut grids: Vec<(&str, &Heightfield)> = vec![("truth", &truth)];
        grids.extend(spectra.iter().map(|(n, g)| (n.as_str(), g)));
        cx.spectrum_plot("radial power spectra: truth vs amplifications", &grids);
        drop(spectra);

        // The enlargement: the left half at full resolution amplified x{f} (nothing finer
        // exists, so the result cannot have seen its answer), details from the right half.
        let region = terrain.crop(0, 0, half, h)?;
        progress.begin(&format!("enlarge the left half x{f}"), 0);
        let t = Instant::now();
        let big = amplify(&region, &exemplar, &settings(steps, true), &progress)
            .context("enlargement of the left half")?
            .rasterize_with_progress(&RasterSettings::default(), &progress)?;
        let secs = t.elapsed().as_secs_f64();
        let big_bicubic = region.resample(big.width(), big.height())?;
        let consistency =
            metrics::rmse(&big.downsample_box(f)?, &region)? / (region.relief() as f64).max(1e-9);
        cx.section
            .figure("enlarged_size", [big.width(), big.height()]);
        cx.section.figure("enlarged_seconds", secs);
        cx.section.figure("enlarged_consistency", consistency);
        cx.section.note(&format!(
            "enlargement: the left half ({half} x {h}) at full resolution amplified x{f} to {} x {} \
             in {secs:.1} s with the right half as exemplar (disjoint ground; the exemplar has \
             the input's cell size, so every step relies on the self-similarity of relief \
             across scales); consistency {:.3} % of relief{}",
            big.width(),
            big.height(),
            100.0 * consistency,
            if p.replace_terrain {
                "; handed on to the next stages"
            } else {
                ""
            }
        ));
        cx.save_raster(
            "enlarged",
            &format!("the left half enlarged x{f}"),
            &big,
            None,
        )?;
        cx.before_after(
            "enlarge",
            &format!("the left half of the terrain and its x{f} enlargement"),
            &region,
            &big,
        )?;
        cx.zoom_pair(
            "enlarge_zoom",
            &format!(
                "centre {0} x {0} cells of the x{f} enlargement (left) and of bicubic (right)",
                p.zoom
            ),
            &big,
            &big_bicubic,
            p.zoom,
        )?;
        drop(big_bicubic);
        if p.x256_window > 0 && cx.config.previews {
            self.x256_window(cx, &terrain, &exemplar, &settings(4, true))?;
        }
        if p.replace_terrain {
            cx.state.set_terrain(big);
        }
        Ok(())
    }
}

impl AmplifyStage {
    /// The x256 run of a centre window of the left half: detail phase swing of every step,
    /// hillshades of the whole result and of zoomed crops beside bicubic.
    fn x256_window(
        &self,
        cx: &mut StageCx<'_>,
        terrain: &Heightfield,
        exemplar: &Heightfield,
        settings: &AmplifySettings,
    ) -> Result<()> {
        let n = self.0.x256_window;
        let half = terrain.width() / 2;
        if half < n || terrain.height() < n {
            cx.section.note(&format!(
                "x256 window of {n} x {n} cells does not fit in the left half; skipped"
            ));
            return Ok(());
        }
        let window = terrain.crop((half - n) / 2, (terrain.height() - n) / 2, n, n)?;
        let progress = cx.progress();
        progress.begin(&format!("amplify a {n} x {n} window x256"), 0);
        let t = Instant::now();
        let mut steps: Vec<Vec<f64>> = Vec::new();
        let mut failure = None;
        let sct = amplify_observed(&window, exemplar, settings, &progress, &mut |r| {
            // The swing of the detail this step added, in a window of at most 2048^2 of its
            // output (the whole output up to x64).
            let (w, h) = (4 * r.input.width(), 4 * r.input.height());
            let side = w.min(h).min(2048);
            let run = || -> Result<Vec<f64>> {
                let out = r.output.rasterize(&RasterSettings {
                    scale: 1.0,
                    window: Some(relief_sparse_core::Window {
                        x: 0,
                        y: 0,
                        width: side,
                        height: side,
                    }),
                })?;
                let bic = corner_bicubic(r.input, w, h)?.crop(0, 0, side, side)?;
                Ok(vec![
                    (r.step + 1) as f64,
                    w as f64,
                    detail_swing(&out, &bic)?,
                    phase_swing(&out, &bic, 8)?,
                    r.exemplar.reduction,
                    f64::from(u8::from(r.exemplar.self_similar)),
                ])
            };
            match run() {
                Ok(row) => steps.push(row),
                Err(e) => failure = Some(e),
            }
        })
        .context("x256 amplification of the window")?;
        if let Some(e) = failure {
            return Err(e.context("phase swing of a x256 step"));
        }
        let model = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let out = sct.rasterize_with_progress(&RasterSettings::default(), &progress)?;
        let raster = t.elapsed().as_secs_f64();
        let worst = steps.iter().map(|r| r[2].max(r[3])).fold(1.0, f64::max);
        cx.section.figure("x256_size", [out.width(), out.height()]);
        cx.section.figure("x256_model_seconds", model);
        cx.section.figure("x256_raster_seconds", raster);
        cx.section.headline("x256_worst_swing", worst);
        let rows: Vec<(String, Vec<f64>)> = steps
            .iter()
            .map(|r| {
                (
                    format!("step {} (x{})", r[0], 4usize.pow(r[0] as u32)),
                    r[1..].to_vec(),
                )
            })
            .collect();
        let rows_ref: Vec<(&str, Vec<f64>)> =
            rows.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
        cx.section.numbers(
            &format!(
                "x256 run of a {n} x {n} window: phase swing of the detail added by every step"
            ),
            &format!(
                "centre {n} x {n} window of the left half amplified in 4 x4 steps to {} x {} \
                 (model {model:.1} s, raster {raster:.1} s), right half as exemplar. swing: as \
                 in the table above (periods 4-32); swing8: block-normalised swing at period 8 \
                 (robust to non-stationary relief), both of the step's output minus the \
                 corner-aligned bicubic of its input in a window of at most 2048^2; bar: <= 1.15. \
                 exemplar reduction: the x4^k reduction of the exemplar the step used; \
                 self-similar = 1 when the exemplar was not fine enough for the step's cell size",
                out.width(),
                out.height()
            ),
            &[
                "step",
                "output side",
                "swing",
                "swing8",
                "exemplar reduction",
                "self-similar",
            ],
            &rows_ref,
        );
        let bicubic = window.resample(out.width(), out.height())?;
        cx.before_after(
            "x256",
            &format!("the {n} x {n} window and its x256 amplification"),
            &window,
            &out,
        )?;
        for side in [2048, 512] {
            cx.zoom_pair(
                &format!("x256_zoom{side}"),
                &format!(
                    "centre {side} x {side} cells of the x256 amplification (left) and of \
                     bicubic (right)"
                ),
                &out,
                &bicubic,
                side,
            )?;
        }
        Ok(())
    }
}

/// Parameters of the `sketch` stage (JSON `params`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct SketchParams {
    /// Side of the painted sketch in cells (capped so the output is at most the exemplar's
    /// largest side times two); the output is `4^steps x` that.
    pub(crate) sketch_size: usize,
    /// The sketch-synthesis job, the same settings as `relief synthesize`
    /// ([`SynthesisSettings`]); the spec's fields are merged onto the library's defaults
    /// (figure 12: three x4 steps, 64 learned atoms) with `R` = 2. The stage lowers the radius
    /// to 1 on small exemplars, caps
    /// the atoms at a quarter of the candidate patches and mixes `amplify.seed` with the
    /// spec's. `amplify.steps` must be 1..=3.
    pub(crate) job: SynthesisSettings,
}

impl Default for SketchParams {
    fn default() -> Self {
        let lib = SynthesisSettings::default();
        Self {
            sketch_size: 8,
            job: SynthesisSettings {
                amplify: AmplifySettings {
                    radius: 2.0,
                    ..lib.amplify
                },
                ..lib
            },
        }
    }
}

/// The `sketch` stage.
#[derive(Debug, Default)]
pub(crate) struct SketchStage(pub(crate) SketchParams);

impl SketchStage {
    /// Checks the job when the spec is built.
    pub(crate) fn new(p: SketchParams) -> Result<Self> {
        p.job.amplify.check().context("invalid `job.amplify`")?;
        if !(1..=3).contains(&p.job.amplify.steps) {
            bail!(
                "invalid parameter `job.amplify.steps` = {}: must be 1, 2 or 3",
                p.job.amplify.steps
            );
        }
        if p.sketch_size == 0 {
            bail!("invalid parameter `sketch_size` = 0: must be >= 1");
        }
        Ok(Self(p))
    }
}

/// A "painted" sketch in `[0, 1]`: a diagonal ridge stroke, a round peak and a valley stroke,
/// the kind of coarse drawing figure 12 starts from.
pub(crate) fn painted_sketch(n: usize) -> Heightfield {
    let s = n as f32;
    Heightfield::from_fn(n, n, 1.0, 1.0, |x, y| {
        let (u, v) = ((x as f32 + 0.5) / s, (y as f32 + 0.5) / s);
        let stroke = |d: f32, w: f32| (-(d * d) / (w * w)).exp();
        let ridge = stroke((u - 0.2) - 0.9 * (v - 0.1), 0.18) * (1.0 - 0.6 * u);
        let peak = stroke(((u - 0.7).powi(2) + (v - 0.3).powi(2)).sqrt(), 0.15);
        let valley = stroke((v - 0.8) + 0.3 * (u - 0.5), 0.1);
        (0.25 + 0.5 * ridge + 0.6 * peak - 0.25 * valley).clamp(0.0, 1.0)
    })
}

impl Stage for SketchStage {
    fn name(&self) -> &'static str {
        "sketch"
    }

    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = &self.0;
        let steps = p.job.amplify.steps;
        // The real DEM as loaded when it is complete: earlier stages (amplify) may have made the
        // current terrain synthetic, and a sketch should get real relief; else the current
        // terrain.
        let (exemplar, which) = match &cx.state.source {
            Some(src) if src.require_complete().is_ok() => (src.clone(), "the input DEM"),
            _ => (cx.state.terrain()?.clone(), "the current terrain"),
        };
        exemplar
            .require_complete()
            .context("the sketch stage needs a void-free exemplar terrain")?;
        let side = exemplar.width().min(exemplar.height());
        let mut radius = p.job.amplify.radius;
        if side < min_exemplar_side(radius) {
            radius = 1.0;
        }
        if side < min_exemplar_side(radius) {
            cx.section.note(&format!(
                "exemplar {} x {} too small for sketch synthesis; stage skipped",
                exemplar.width(),
                exemplar.height()
            ));
            return Ok(());
        }
        let f = 4usize.pow(steps as u32);
        let a = 2 * radius.ceil() as usize;
        // Output at most twice the exemplar's largest side; the sketch holds >= one patch.
        let cap = 2 * exemplar.width().max(exemplar.height()) / f;
        let n = p.sketch_size.min(cap).max(a);
        let sketch = painted_sketch(n);
        let (dictionary, atoms) = capped_dictionary(
            p.job.amplify.dictionary,
            candidate_count((exemplar.width(), exemplar.height()), a) / 4,
        );
        let settings = SynthesisSettings {
            amplify: AmplifySettings {
                radius,
                dictionary,
                seed: cx.config.seed ^ 0x5e7c ^ p.job.amplify.seed,
                ..p.job.amplify
            },
            ..p.job
        };
        let progress = cx.progress();
        progress.begin(&format!("sketch synthesis {n} x {n} -> x{f}"), 0);
        let t = Instant::now();
        let sct = synthesize(&sketch, &exemplar, &settings, &progress)?;
        let out = sct.rasterize_with_progress(&RasterSettings::default(), &progress)?;
        let secs = t.elapsed().as_secs_f64();
        let back = out.resample(n, n)?;
        let fidelity = relief_heightfield::metrics::pearson(back.as_slice(), sketch.as_slice());
        let (lo, hi) = out.min_max().unwrap_or((0.0, 0.0));
        cx.section.figure("sketch_size", n);
        cx.section.figure("steps", steps);
        cx.section.figure("radius", radius);
        cx.section.figure("atoms", atoms);
        cx.section
            .figure("output_size", [out.width(), out.height()]);
        cx.section.figure("seconds", secs);
        cx.section.figure("elevation_range_m", [lo, hi]);
        cx.section.headline("sketch_correlation", fidelity);
        cx.section.note(&format!(
            "a {n} x {n} painted sketch (ridge stroke, peak, valley) mapped to the exemplar's \
             elevation range and amplified in {} x4 steps (figure 12) to {} x {} with \
             {which} ({} x {}) as exemplar, N = {atoms}, R = {radius}, in {secs:.2} s; \
             correlation of the output reduced to the sketch size with the sketch: {fidelity:.3}",
            steps,
            out.width(),
            out.height(),
            exemplar.width(),
            exemplar.height()
        ));
        cx.save_raster(
            "sketch_synthesis",
            "terrain synthesised from the sketch",
            &out,
            None,
        )?;
        // The golden is a centre window (at most 128 x 128) so the fixture stays small.
        let (gw, gh) = (out.width().min(128), out.height().min(128));
        let window = out.crop((out.width() - gw) / 2, (out.height() - gh) / 2, gw, gh)?;
        cx.save_raster(
            "sketch_synthesis_window",
            "centre window of the synthesis",
            &window,
            Some(DICT_TOLERANCE),
        )?;
        if cx.config.previews {
            let (elo, ehi) = exemplar.min_max().unwrap_or((0.0, 1.0));
            let shown = sketch
                .map(|v| elo + v * (ehi - elo))
                .resample(out.width(), out.height())?;
            cx.before_after(
                "sketch",
                "painted sketch (bicubic, for display) and the synthesis",
                &shown,
                &out,
            )?;
        }
        Ok(())
    }
}

/// Parameters of the `procedural` stage (JSON `params`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct ProceduralParams {
    /// Largest side of the centre crop that is fitted.
    pub(crate) max_side: usize,
    /// The fit-procedural job, the same settings as `relief fit-procedural`
    /// ([`ProceduralSettings`]). The stage runs it once per atom family (`family` is set per
    /// row), scales `n_candidates` down on crops under 128^2, and its "ridged, learned" row
    /// keeps `learned_atoms` atoms (64 when null); `seed` is mixed with the spec's.
    pub(crate) job: ProceduralSettings,
}

impl Default for ProceduralParams {
    fn default() -> Self {
        Self {
            max_side: 256,
            job: ProceduralSettings::default(),
        }
    }
}

impl ProceduralStage {
    /// Checks the job when the spec is built.
    pub(crate) fn new(p: ProceduralParams) -> Result<Self> {
        p.job.check().context("invalid `job`")?;
        if p.max_side < 16 {
            bail!(
                "invalid parameter `max_side` = {}: must be >= 16",
                p.max_side
            );
        }
        Ok(Self(p))
    }

    /// Atoms of the learned row.
    fn learned_atoms(&self, candidates: usize) -> usize {
        self.0
            .job
            .learned_atoms
            .unwrap_or(64)
            .min(candidates / 2)
            .max(1)
    }
}

/// The `procedural` stage.
#[derive(Debug, Default)]
pub(crate) struct ProceduralStage(pub(crate) ProceduralParams);

impl Stage for ProceduralStage {
    fn name(&self) -> &'static str {
        "procedural"
    }

    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = &self.0;
        // Fit the real DEM as loaded when it is complete (the comparison of atom families is
        // about real relief; earlier stages may have replaced the terrain by a synthetic one),
        // else the current terrain.
        let (terrain, which) = match &cx.state.source {
            Some(src) if src.require_complete().is_ok() => (src.clone(), "the input DEM"),
            _ => (cx.state.terrain()?.clone(), "the current terrain"),
        };
        terrain
            .require_complete()
            .context("the procedural stage needs a void-free terrain")?;
        let (w, h) = (
            terrain.width().min(p.max_side),
            terrain.height().min(p.max_side),
        );
        let crop = terrain.crop((terrain.width() - w) / 2, (terrain.height() - h) / 2, w, h)?;
        // Scale the dictionary down on small crops: full size from 128^2 up, fewer below.
        let n = p.job.n_candidates;
        let candidates = (n * w * h / (128 * 128)).clamp(64, n.max(64));
        let progress = cx.progress();
        let mut rows = Vec::new();
        let mut best: Option<(f64, Heightfield)> = None;
        let runs: [(&str, NoiseFamily, Option<usize>); 4] = [
            ("perlin", NoiseFamily::Perlin, None),
            ("ridged_multifractal", NoiseFamily::RidgedMultifractal, None),
            ("ridged", NoiseFamily::RidgedSum, None),
            (
                "ridged_learned",
                NoiseFamily::RidgedSum,
                Some(self.learned_atoms(candidates)),
            ),
        ];
        for (label, family, learned) in runs {
            progress.begin(&format!("procedural fit: {label}"), 0);
            let t = Instant::now();
            let fit = fit_procedural(
                &crop,
                &ProceduralSettings {
                    family,
                    n_candidates: candidates,
                    learned_atoms: learned,
                    seed: cx.config.seed ^ 0x9f0c ^ p.job.seed,
                    ..p.job
                },
                &progress,
            )
            .with_context(|| format!("procedural fit with {label} atoms"))?;
            let secs = t.elapsed().as_secs_f64();
            cx.section.figure(&format!("psnr_{label}_db"), fit.psnr);
            if label == "perlin" || label == "ridged" {
                cx.section
                    .headline(&format!("procedural_psnr_{label}_db"), fit.psnr);
            }
            let rec = fit.sct.rasterize(&RasterSettings::default())?;
            rows.push((
                label.to_string(),
                vec![
                    fit.n_atoms as f64,
                    fit.psnr,
                    metrics::rmse(&crop, &rec)?,
                    secs,
                ],
            ));
            if label == "ridged" {
                best = Some((fit.psnr, rec));
            }
        }
        let rows_ref: Vec<(&str, Vec<f64>)> =
            rows.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
        cx.section.numbers(
            "inverse procedural modelling (guerin2016 5.2): PSNR per atom family",
            &format!(
                "centre crop {w} x {h} of {which}; 10 x 10 patches, step 5, s = 1; \
                 analytic dictionary of {candidates} random atoms per family (figure 4 atoms = \
                 ridged), OMP on the discretised D, reconstruction with the analytic D~; \
                 ridged_learned keeps {} atoms by constrained learning (problem (2)). The paper \
                 reports ridged 24.9 dB vs Perlin 20.0 dB on its data",
                self.learned_atoms(candidates)
            ),
            &["atoms", "N", "PSNR (dB)", "RMSE (m)", "time (s)"],
            &rows_ref,
        );
        if let Some((psnr, rec)) = best {
            cx.save_raster(
                "procedural_ridged",
                &format!("ridged-atom fit, PSNR {psnr:.1} dB"),
                &rec,
                Some(DICT_TOLERANCE),
            )?;
            cx.before_after(
                "procedural",
                "fitted crop and its ridged-atom model",
                &crop,
                &rec,
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn painted_sketch_has_relief() {
        let s = painted_sketch(8);
        let (lo, hi) = s.min_max().unwrap();
        assert!(lo >= 0.0 && hi <= 1.0 && hi - lo > 0.4, "{lo} {hi}");
    }

    #[test]
    fn sizes() {
        assert_eq!(min_exemplar_side(2.0), 96);
        assert_eq!(candidate_count((64, 128), 2), 15 * 31);
    }
}
