//! The `procedural` stage: inverse procedural modelling of a centre crop (figures 7-8).

use super::*;

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

impl StageParams for ProceduralParams {
    fn check_params(&self) -> Result<()> {
        self.job.check().context("invalid `job`")?;
        if self.max_side < 16 {
            bail!(
                "invalid parameter `max_side` = {}: must be >= 16",
                self.max_side
            );
        }
        Ok(())
    }
}

impl ProceduralParams {
    /// Atoms of the learned row.
    fn learned_atoms(&self, candidates: usize) -> usize {
        self.job
            .learned_atoms
            .unwrap_or(64)
            .min(candidates / 2)
            .max(1)
    }
}

impl Stage for ProceduralParams {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = self;
        // Fit the real DEM as loaded when it is complete (the comparison of atom families is
        // about real relief; earlier stages may have replaced the terrain by a synthetic one),
        // else the current terrain.
        let (terrain, which) = cx.state.complete_source("procedural", "terrain")?;
        let crop = centre_crop(&terrain, p.max_side)?;
        let (w, h) = (crop.width(), crop.height());
        // Scale the dictionary down on small crops: full size from 128^2 up, fewer below.
        let n = p.job.n_candidates;
        let candidates = (n * w * h / (128 * 128)).clamp(64, n.max(64));
        // Pre-flight under `relief run --max-memory`, as `relief fit-procedural`'s: the
        // patches of the crop, the discretised candidate atoms and their Gram matrix.
        let a = p.job.patch_size as f64;
        let step = (a / 2.0).max(1.0);
        let patches = (w as f64 / step).ceil() * (h as f64 / step).ceil();
        let k = candidates as f64;
        cx.config.limits.check_memory(
            "procedural",
            patches * a * a * 16.0 + (w * h) as f64 * 16.0 + k * a * a * 8.0 + k * k * 8.0,
            "a smaller `max_side` or fewer `job.n_candidates`",
        )?;
        let progress = cx.progress();
        let mut rows = Vec::new();
        // The paper's ridged-sum fit (the golden) and the default field fit.
        let mut best: Option<(f64, Heightfield)> = None;
        let mut field: Option<(f64, Heightfield)> = None;
        let runs: [(&str, NoiseFamily, Option<usize>); 6] = [
            ("ridged_field", NoiseFamily::RidgedField, None),
            ("perlin_field", NoiseFamily::PerlinField, None),
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
            if matches!(label, "perlin" | "ridged" | "ridged_field") {
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
            match label {
                "ridged" => best = Some((fit.psnr, rec)),
                "ridged_field" => field = Some((fit.psnr, rec)),
                _ => {}
            }
        }
        let rows_ref: Vec<(&str, Vec<f64>)> =
            rows.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
        cx.section.numbers(
            "inverse procedural modelling (guerin2016 5.2): PSNR per atom family",
            &format!(
                "centre crop {w} x {h} of {which}; 10 x 10 patches, step 5, s = 1; \
                 analytic dictionary of {candidates} random atoms per family (figure 4 atoms = \
                 ridged; ridged_field and perlin_field, the default, are windows of one noise \
                 field at terrain scale), OMP on the discretised D, reconstruction with the analytic D~; \
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
        if let Some((psnr, rec)) = field {
            cx.before_after(
                "procedural_field",
                &format!("fitted crop and its ridged-field model (the default), PSNR {psnr:.1} dB"),
                &crop,
                &rec,
            )?;
        }
        Ok(())
    }
}
