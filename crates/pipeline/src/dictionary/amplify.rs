//! The `amplify` stage: the box protocol of issue 15, the x16 enlargement and the x256 window.

use super::*;

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
        dictionary: DictionaryChoice::learned_default(256),
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

impl StageParams for AmplifyParams {
    fn check_params(&self) -> Result<()> {
        self.job.check().context("invalid `job`")?;
        if !(1..=3).contains(&self.job.steps) {
            bail!(
                "invalid parameter `job.steps` = {}: the stage runs 1, 2 or 3 x4 steps",
                self.job.steps
            );
        }
        if self.x256_window != 0 && !(8..=64).contains(&self.x256_window) {
            bail!(
                "invalid parameter `x256_window` = {}: must be 0 (off) or 8..=64 input cells",
                self.x256_window
            );
        }
        if self.zoom < 16 {
            bail!("invalid parameter `zoom` = {}: must be >= 16", self.zoom);
        }
        Ok(())
    }
}

/// One table row of the box protocol, for the output `out`: its measures by name (the table
/// takes them in the order of [`QualityRow::cells`]).
#[derive(Debug, Clone, Copy)]
struct QualityRow {
    /// Consistency, % of relief.
    consistency_pct: f64,
    /// Signed spectral-slope error over the added octaves.
    slope_signed: f64,
    /// Slope EMD (degrees).
    slope_emd: f64,
    /// Laplacian EMD.
    curvature_emd: f64,
    /// Detail phase swing.
    swing: f64,
    /// High-pass phase swing of the output.
    hp_swing: f64,
    /// Drainage (`relief_landscape::stats`, as `terrain_quality.py`): pits per km^2, mean
    /// closed-depression depth (m), drainage-area exponent beta.
    pits_per_km2: f64,
    fill_depth_m: f64,
    beta: f64,
    seconds: f64,
}

impl QualityRow {
    fn of(r: &BoxProtocolRow, out: &Heightfield, seconds: f64) -> Result<Self> {
        let d = relief_landscape::stats::drainage(out);
        Ok(Self {
            consistency_pct: 100.0 * r.consistency,
            slope_signed: r.slope_signed,
            slope_emd: r.slope_emd,
            curvature_emd: r.curvature_emd,
            swing: r.swing,
            hp_swing: highpass_swing(out)?,
            pits_per_km2: d.pits_per_km2,
            fill_depth_m: d.fill_depth_m,
            beta: d.beta,
            seconds,
        })
    }

    /// The table's cells, in its column order.
    fn cells(&self) -> Vec<f64> {
        vec![
            self.consistency_pct,
            self.slope_signed,
            self.slope_emd,
            self.curvature_emd,
            self.swing,
            self.hp_swing,
            self.pits_per_km2,
            self.fill_depth_m,
            self.beta,
            self.seconds,
        ]
    }
}

/// The protocol row of `out` after the landform pass (`relief amplify`'s default), with its
/// drainage figures; `secs`: the amplification's time, to which the pass's is added.
fn landform_row(
    cx: &mut StageCx<'_>,
    (truth, coarse): (&Heightfield, &Heightfield),
    out: &Heightfield,
    fac: usize,
    secs: f64,
) -> Result<(String, QualityRow)> {
    let t = Instant::now();
    let (finished, _) = relief_landscape::landform::finish(
        out,
        coarse,
        &relief_landscape::landform::LandformSettings::default(),
    )?;
    let secs = secs + t.elapsed().as_secs_f64();
    let q = box_protocol(truth, coarse, &finished, fac)?;
    let d = relief_landscape::stats::drainage(&finished);
    cx.section
        .figure(&format!("landform_pits_per_km2_x{fac}"), d.pits_per_km2);
    cx.section
        .figure(&format!("landform_fill_depth_m_x{fac}"), d.fill_depth_m);
    cx.section.figure(&format!("landform_beta_x{fac}"), d.beta);
    Ok((
        format!("sparse + landform pass, the CLI default (x{fac})"),
        QualityRow::of(&q, &finished, secs)?,
    ))
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

impl Stage for AmplifyParams {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = self;
        let terrain = cx.state.complete_terrain("amplify")?;
        let (w, h) = (terrain.width(), terrain.height());
        let half = w / 2;
        let exemplar = terrain.crop(half, 0, w - half, h)?;
        let Some(plan) = self.plan(cx, (w, h), &exemplar) else {
            return Ok(());
        };
        let steps = plan.steps;
        let f = 4usize.pow(steps as u32);
        // Pre-flight under `relief run --max-memory`: the enlargement of the left half is the
        // stage's peak (its amplification, then the result and its bicubic comparison).
        let enlarged = (half * f) as f64 * (h * f) as f64;
        cx.config.limits.check_memory(
            "amplify",
            relief_dictionary_learning::memory::amplify_working_bytes(
                (half, h),
                (w - half, h),
                &plan.settings(p, steps, true),
            ) + enlarged * 8.0,
            "fewer `job.steps`, or a smaller terrain (`crop`)",
        )?;
        let (tw, th) = (half / f * f, h / f * f);
        let truth = terrain.crop(0, 0, tw, th)?;
        cx.section.figure("factor", f);
        cx.section.figure("radius", plan.radius);
        cx.section.figure("atoms", plan.atoms);
        cx.section.figure("truth_size", [tw, th]);
        cx.section
            .figure("exemplar_size", [exemplar.width(), exemplar.height()]);
        let mut factors = vec![steps];
        if p.also_x4 && steps > 1 {
            factors.insert(0, 1);
        }
        let mut output = None;
        let mut spectra: Vec<(String, Heightfield)> = Vec::new();
        for &st in &factors {
            self.protocol_block(
                cx,
                &plan,
                (&truth, &exemplar),
                st,
                &mut output,
                &mut spectra,
            )?;
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
        cx.side_by_side(
            "amplify_truth",
            "truth and the amplification",
            ("truth", &truth),
            ("amplified", &out),
        )?;
        let mut grids: Vec<(&str, &Heightfield)> = vec![("truth", &truth)];
        grids.extend(spectra.iter().map(|(n, g)| (n.as_str(), g)));
        cx.spectrum_plot("radial power spectra: truth vs amplifications", &grids);
        drop(spectra);

        let big = self.enlarge(cx, &plan, &terrain, &exemplar)?;
        if p.x256_window > 0 && cx.config.previews {
            self.x256_window(cx, &terrain, &exemplar, &plan.settings(p, 4, true))?;
        }
        if p.replace_terrain {
            cx.state.set_terrain(big);
        }
        Ok(())
    }
}

/// What the stage runs on this terrain: the job's steps and radius, lowered on small inputs.
struct Plan {
    steps: usize,
    radius: f64,
    dictionary: DictionaryChoice,
    /// Learned atoms (0 = complete).
    atoms: usize,
    seed: u64,
}

impl Plan {
    /// The job's settings at `steps` steps: `residual` false gives the paper's plain method,
    /// true the job as given (by default the residual correction, detail-energy normalisation
    /// and diverse atom choice).
    fn settings(&self, p: &AmplifyParams, steps: usize, residual: bool) -> AmplifySettings {
        AmplifySettings {
            radius: self.radius,
            steps,
            dictionary: self.dictionary,
            seed: self.seed,
            residual_correction: residual && p.job.residual_correction,
            normalize_detail: residual && p.job.normalize_detail,
            diverse_atoms: residual && p.job.diverse_atoms,
            ..p.job
        }
    }
}

impl AmplifyParams {
    /// Scales the work to the input: x16 needs a coarse input of >= 8 pixels per side and an
    /// exemplar of >= 6 fine patches; otherwise x4 and the smallest radius. `None` (with a
    /// note) when even that does not fit.
    fn plan(
        &self,
        cx: &mut StageCx<'_>,
        (w, h): (usize, usize),
        exemplar: &Heightfield,
    ) -> Option<Plan> {
        let p = self;
        let half = w / 2;
        let ex_side = exemplar.width().min(exemplar.height());
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
            return None;
        }
        let a = 2 * radius.ceil() as usize;
        let (dictionary, atoms) = capped_dictionary(
            p.job.dictionary,
            candidate_count((exemplar.width(), exemplar.height()), a) / 4,
        );
        Some(Plan {
            steps,
            radius,
            dictionary,
            atoms,
            seed: cx.config.seed ^ 0xa3f1 ^ p.job.seed,
        })
    }

    /// One block of the box protocol: the truth reduced `4^st` times and amplified back by the
    /// job (and the paper's plain method), bicubic and the noise baseline, as one table; the
    /// job's output of the last block and the spectra to plot are handed back.
    fn protocol_block(
        &self,
        cx: &mut StageCx<'_>,
        plan: &Plan,
        (truth, exemplar): (&Heightfield, &Heightfield),
        st: usize,
        output: &mut Option<(Heightfield, Heightfield)>,
        spectra: &mut Vec<(String, Heightfield)>,
    ) -> Result<()> {
        let p = self;
        let (steps, radius, atoms) = (plan.steps, plan.radius, plan.atoms);
        let (tw, th) = (truth.width(), truth.height());
        let progress = cx.progress();
        let fac = 4usize.pow(st as u32);
        let coarse = truth.downsample_box(fac)?;
        // The truth's own measures: its phase swing is what non-stationary relief gives
        // without any grid (the swing of a small crop is far from 1).
        let mut rows: Vec<(String, QualityRow)> = vec![(
            format!("truth (reference) (x{fac})"),
            QualityRow::of(&box_protocol(truth, &coarse, truth, fac)?, truth, 0.0)?,
        )];
        cx.section
            .figure(&format!("hp_swing_truth_x{fac}"), rows[0].1.hp_swing);
        let truth_swing = rows[0].1.swing;
        cx.section
            .figure(&format!("swing_truth_x{fac}"), truth_swing);
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
            let sct = amplify(
                &coarse,
                exemplar,
                &plan.settings(p, st, residual),
                &progress,
            )
            .with_context(|| format!("amplification x{fac}"))?;
            let out = sct.rasterize_with_progress(&RasterSettings::default(), &progress)?;
            let secs = t.elapsed().as_secs_f64();
            let q = box_protocol(truth, &coarse, &out, fac)?;
            let label = if residual {
                format!(
                    "sparse, {}, s = {}, default (x{fac})",
                    atoms_label(atoms),
                    p.job.sparsity
                )
            } else {
                format!("sparse --paper (plain method) (x{fac})")
            };
            rows.push((label, QualityRow::of(&q, &out, secs)?));
            if residual {
                rows.push(landform_row(cx, (truth, &coarse), &out, fac, secs)?); // + landform
                let tag = format!("x{fac}");
                cx.section
                    .figure(&format!("hp_swing_{tag}"), rows[rows.len() - 2].1.hp_swing);
                cx.section
                    .figure(&format!("consistency_{tag}"), q.consistency);
                cx.section
                    .figure(&format!("slope_error_{tag}"), q.slope_signed);
                cx.section
                    .figure(&format!("slope_emd_deg_{tag}"), q.slope_emd);
                cx.section
                    .figure(&format!("laplacian_emd_{tag}"), q.curvature_emd);
                cx.section.figure(&format!("swing_{tag}"), q.swing);
                // The bar: the method's swing within 1.15x of the truth's own.
                cx.section
                    .figure(&format!("swing_over_truth_{tag}"), q.swing / truth_swing);
                if st == steps {
                    cx.section.headline("amplify_consistency", q.consistency);
                    cx.section.headline("amplify_slope_error", q.slope_error);
                    cx.section.headline("amplify_swing", q.swing);
                    *output = Some((coarse.clone(), out.clone()));
                    spectra.push(("sparse".into(), out));
                }
            }
        }
        let t = Instant::now();
        let bicubic = coarse.resample(tw, th)?;
        let secs = t.elapsed().as_secs_f64();
        rows.push((
            format!("bicubic (x{fac})"),
            QualityRow::of(
                &box_protocol(truth, &coarse, &bicubic, fac)?,
                &bicubic,
                secs,
            )?,
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
            QualityRow::of(&box_protocol(truth, &coarse, &noise, fac)?, &noise, secs)?,
        ));
        if st == steps {
            spectra.push(("bicubic".into(), bicubic));
            spectra.push(("noise".into(), noise));
        }
        let rows_ref: Vec<(&str, Vec<f64>)> =
            rows.iter().map(|(n, v)| (n.as_str(), v.cells())).collect();
        cx.section.numbers(
            &format!("amplification x{fac} on real data (guerin2016 5.3, issue-15 box protocol)"),
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
                 4-32 pixels (1 = no grid; the truth row gives the crop's own value, 1.3-1.5 \
                 on real crops of 256^2-752^2: the bar is the method's swing <= 1.15 x the \
                 truth's); \
                 high-pass swing: the same of the output minus its 2-pixel Gaussian blur (no \
                 interpolated reference, whose own error depends on the phase); pits: strict \
                 local minima per km^2; fill: mean closed-depression depth (m); beta: \
                 drainage-area exponent (the bars: pits <= 2x the truth's, fill <= 2x + 0.05 \
                 m, |beta - truth's| <= 0.06)",
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
                "high-pass swing",
                "pits/km2",
                "fill (m)",
                "beta",
                "time (s)",
            ],
            &rows_ref,
        );
        Ok(())
    }
}

impl AmplifyParams {
    /// The enlargement: the left half at full resolution amplified x{f} (nothing finer exists,
    /// so the result cannot have seen its answer), details from the right half.
    fn enlarge(
        &self,
        cx: &mut StageCx<'_>,
        plan: &Plan,
        terrain: &Heightfield,
        exemplar: &Heightfield,
    ) -> Result<Heightfield> {
        let p = self;
        let (steps, f) = (plan.steps, 4usize.pow(plan.steps as u32));
        let (half, h) = (terrain.width() / 2, terrain.height());
        let progress = cx.progress();
        let region = terrain.crop(0, 0, half, h)?;
        progress.begin(&format!("enlarge the left half x{f}"), 0);
        let t = Instant::now();
        let big = amplify(&region, exemplar, &plan.settings(p, steps, true), &progress)
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
        Ok(big)
    }

    /// The x256 run of a centre window of the left half: detail phase swing of every step,
    /// hillshades of the whole result and of zoomed crops beside bicubic.
    fn x256_window(
        &self,
        cx: &mut StageCx<'_>,
        terrain: &Heightfield,
        exemplar: &Heightfield,
        settings: &AmplifySettings,
    ) -> Result<()> {
        let n = self.x256_window;
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
                    swing_floor(exemplar, side, 4)?,
                    phase_swing(&out, &bic, 8)?,
                    highpass_swing(&out)?,
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
        let worst = steps.iter().map(|r| r[2].max(r[4])).fold(1.0, f64::max);
        let worst_ratio = steps.iter().map(|r| r[2] / r[3]).fold(0.0, f64::max);
        let worst_hp = steps.iter().map(|r| r[5]).fold(1.0, f64::max);
        cx.section.figure("x256_worst_hp_swing", worst_hp);
        cx.section
            .figure("x256_worst_swing_over_floor", worst_ratio);
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
                 in the table above (periods 4-32) of the step's output minus the corner-aligned \
                 bicubic of its input in a window of at most 2048^2; real-terrain floor: the \
                 median swing of exemplar crops of the same size (no truth exists at the finer \
                 steps' cells; real relief scores 1.3-1.5, not 1); bar: swing <= 1.15 x floor; \
                 swing8: block-normalised swing at period 8 (robust to non-stationary relief); \
                 high-pass swing: of the output minus its 2-pixel Gaussian blur. \
                 exemplar reduction: the x4^k reduction of the exemplar the step used; \
                 self-similar = 1 when the exemplar was not fine enough for the step's cell size",
                out.width(),
                out.height()
            ),
            &[
                "step",
                "output side",
                "swing",
                "real-terrain floor",
                "swing8",
                "high-pass swing",
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
