//! The `sketch` stage: synthesis from a painted sketch in three x4 steps (figure 12).

use super::*;

/// Parameters of the `sketch` stage (JSON `params`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct SketchParams {
    /// Rows of the painted sketch (it is twice as wide), capped so the output is at most four
    /// times the exemplar's largest side; the output is `4^steps x` that.
    pub(crate) sketch_size: usize,
    /// The sketch-synthesis job, the same settings as `relief synthesize`
    /// ([`SynthesisSettings`]); the spec's fields are merged onto the library's defaults
    /// (figure 12: three x4 steps, 64 learned atoms) with `R` = 2. The stage lowers the radius
    /// to 1 on small exemplars, caps
    /// the atoms at a quarter of the candidate patches and mixes `amplify.seed` with the
    /// spec's (the library caps the structure radius at an eighth of the sketch's side).
    /// `amplify.steps` must be 1..=3.
    pub(crate) job: SynthesisSettings,
}

impl Default for SketchParams {
    fn default() -> Self {
        let lib = SynthesisSettings::default();
        Self {
            sketch_size: 64,
            job: SynthesisSettings {
                amplify: AmplifySettings {
                    radius: 2.0,
                    steps: 2,
                    ..lib.amplify
                },
                ..lib
            },
        }
    }
}

impl StageParams for SketchParams {
    fn check_params(&self) -> Result<()> {
        self.job.amplify.check().context("invalid `job.amplify`")?;
        if !(1..=3).contains(&self.job.amplify.steps) {
            bail!(
                "invalid parameter `job.amplify.steps` = {}: must be 1, 2 or 3",
                self.job.amplify.steps
            );
        }
        if self.sketch_size == 0 {
            bail!("invalid parameter `sketch_size` = 0: must be >= 1");
        }
        Ok(())
    }
}

/// A "painted" sketch in `[0, 1]` of `w x h` cells: a diagonal ridge stroke, a round peak and
/// a valley stroke, the kind of coarse drawing figure 12 starts from.
pub(crate) fn painted_sketch(w: usize, h: usize) -> Heightfield {
    let (sw, sh) = (w as f32, h as f32);
    Heightfield::from_fn(w, h, 1.0, 1.0, |x, y| {
        let (u, v) = ((x as f32 + 0.5) / sw, (y as f32 + 0.5) / sh);
        let stroke = |d: f32, w: f32| (-(d * d) / (w * w)).exp();
        let ridge = stroke((u - 0.2) - 0.9 * (v - 0.1), 0.18) * (1.0 - 0.6 * u);
        let peak = stroke(((u - 0.7).powi(2) + (v - 0.3).powi(2)).sqrt(), 0.15);
        let valley = stroke((v - 0.8) + 0.3 * (u - 0.5), 0.1);
        (0.25 + 0.5 * ridge + 0.6 * peak - 0.25 * valley).clamp(0.0, 1.0)
    })
}

impl Stage for SketchParams {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = self;
        let steps = p.job.amplify.steps;
        // The real DEM as loaded when it is complete: earlier stages (amplify) may have made the
        // current terrain synthetic, and a sketch should get real relief; else the current
        // terrain.
        let (exemplar, which) = cx.state.complete_source("sketch", "exemplar terrain")?;
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
        // Output at most four times the exemplar's largest side; the sketch (n x 2n) holds
        // at least one patch.
        let cap = 2 * exemplar.width().max(exemplar.height()) / f;
        let n = p.sketch_size.min(cap).max(a);
        let sketch = painted_sketch(2 * n, n);
        // The sketch spans the exemplar's width (its landforms at their own scale), unless the
        // spec sets the sketch's cell size.
        let (ecx, _) = exemplar.cell_size();
        let spanning = ecx * exemplar.width() as f64 / (2 * n) as f64;
        let sketch_cell = p.job.sketch_cell_size.unwrap_or((spanning, spanning));
        let cell = sketch_cell.0;
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
            sketch_cell_size: Some(sketch_cell),
            ..p.job
        };
        // Pre-flight under `relief run --max-memory`: the x4 steps from the sketch, the
        // exemplar's dictionaries, and the grown relief on the sketch grid x4.
        let grown = (8 * n) as f64 * (4 * n) as f64;
        cx.config.limits.check_memory(
            "sketch",
            relief_dictionary_learning::memory::amplify_working_bytes(
                (2 * n, n),
                (exemplar.width(), exemplar.height()),
                &settings.amplify,
            ) + grown * relief_landscape::landform::WORKING_BYTES_PER_CELL,
            "fewer `job.amplify.steps` or a smaller `sketch_size`",
        )?;
        let progress = cx.progress();
        progress.begin(&format!("sketch synthesis {} x {n} -> x{f}", 2 * n), 0);
        let t = Instant::now();
        let (sct, figures) = synthesize_with_figures(&sketch, &exemplar, &settings, &progress)?;
        let out = sct.rasterize_with_progress(&RasterSettings::default(), &progress)?;
        let secs = t.elapsed().as_secs_f64();
        let back = out.resample(2 * n, n)?;
        let fidelity = relief_heightfield::metrics::pearson(back.as_slice(), sketch.as_slice());
        let (lo, hi) = out.min_max().unwrap_or((0.0, 0.0));
        cx.section.figure("sketch_size", [2 * n, n]);
        cx.section.figure("sketch_cell_size_m", cell);
        cx.section.figure("steps", steps);
        cx.section.figure("radius", radius);
        cx.section.figure("atoms", atoms);
        if let Some(st) = &figures.structure {
            cx.section.figure("structure_radius", st.radius);
            cx.section.figure("structure_band_rms_m", st.band_rms);
            cx.section
                .figure("structure_continued_fraction", st.continued);
            cx.section.note(&st.note);
        }
        for step in &figures.steps {
            cx.section.note(&step.note);
        }
        cx.section
            .figure("output_size", [out.width(), out.height()]);
        cx.section.figure("seconds", secs);
        cx.section.figure("elevation_range_m", [lo, hi]);
        cx.section.headline("sketch_correlation", fidelity);
        cx.section.note(&format!(
            "a {} x {n} painted sketch (ridge stroke, peak, valley) of {cell:.1} m cells \
             (by default it spans the exemplar's width) mapped to the exemplar's elevation \
             range, given the exemplar's landforms between its cells and its strokes, and \
             amplified in {} x4 steps (figure 12) to {} x {} with {which} ({} x {}) as \
             exemplar, N = {atoms}, R = {radius}, in {secs:.2} s; correlation of the output \
             reduced to the sketch size with the sketch: {fidelity:.3}",
            2 * n,
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
        let window = centre_crop(&out, 128)?;
        cx.save_raster(
            "sketch_synthesis_window",
            "centre window of the synthesis",
            &window,
            Some(DICT_TOLERANCE),
        )?;
        if cx.config.previews {
            let (elo, ehi) = exemplar.min_max().unwrap_or((0.0, 1.0));
            // At the output's cell size, so both hillshades use the same slopes.
            let mut shown = sketch
                .map(|v| elo + v * (ehi - elo))
                .resample(out.width(), out.height())?;
            shown.set_cell_size(out.cell_size().0, out.cell_size().1)?;
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
