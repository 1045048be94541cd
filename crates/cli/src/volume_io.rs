//! File inputs and outputs of a volume scene shared by `relief volume` and the pipeline's
//! `volume` stage: the `--mask` raster, the `--geology` tree and the mesh.

use std::path::Path;

use anyhow::{Context, Result, bail};
use relief_heightfield::Heightfield;
use relief_implicit_volume::{GeologySpec, VolumeOutput};

use crate::ctx::Ctx;
use crate::outputs::{OutKind, check_png_flag, check_report_path};
use crate::staging::Outputs;

/// Reads a mask raster and maps it to `[0, 1]`: values already in `[0, 1]` are kept, 8-bit
/// counts are divided by 255 and 16-bit counts by 65535.
pub(crate) fn read_mask(path: &Path, dem: &Heightfield, ctx: &Ctx) -> Result<Vec<f32>> {
    let raster = crate::read::read_raster(path, &crate::args::ReadArgs::default(), ctx)?;
    let m = raster.heightfield;
    if (m.width(), m.height()) != (dem.width(), dem.height()) {
        bail!(
            "mask {} is {}x{}, the DEM is {}x{}: they must match",
            path.display(),
            m.width(),
            m.height(),
            dem.width(),
            dem.height()
        );
    }
    let v = m.as_slice();
    if let Some(bad) = v.iter().find(|x| !x.is_finite() || **x < 0.0) {
        bail!(
            "mask {}: value {bad} is not a finite non-negative weight",
            path.display()
        );
    }
    let max = v.iter().cloned().fold(0.0f32, f32::max);
    let div = if max <= 1.0 {
        1.0
    } else if max <= 255.0 {
        255.0
    } else if max <= 65535.0 {
        65535.0
    } else {
        bail!(
            "mask {}: values up to {max}; expected [0, 1], 8-bit or 16-bit counts",
            path.display()
        );
    };
    Ok(v.iter().map(|x| x / div).collect())
}

/// Reads and checks a `--geology` tree (JSON, at most 16 MiB).
pub(crate) fn read_geology(path: &Path) -> Result<GeologySpec> {
    let meta =
        std::fs::metadata(path).with_context(|| format!("cannot read {}", path.display()))?;
    if meta.len() > 16 << 20 {
        bail!(
            "--geology {}: {} bytes, at most 16 MiB",
            path.display(),
            meta.len()
        );
    }
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let spec: GeologySpec = serde_json::from_str(&text)
        .with_context(|| format!("--geology {}: not a geology tree", path.display()))?;
    spec.build()
        .with_context(|| format!("--geology {}: invalid geology", path.display()))?;
    Ok(spec)
}

pub(crate) use relief_pipeline::write_mesh;

/// The files of one `relief volume` run (each optional).
pub(crate) struct Files<'a> {
    /// `--mesh`: GLB, PLY or OBJ.
    pub(crate) mesh: Option<&'a Path>,
    /// `--render` (PNG).
    pub(crate) render: Option<&'a Path>,
    /// `--closeups` (PNG).
    pub(crate) closeups: Option<&'a Path>,
    /// `--section` (PNG).
    pub(crate) section: Option<&'a Path>,
    /// `--report` (JSON).
    pub(crate) report: Option<&'a Path>,
}

impl Files<'_> {
    /// The files but the report, with their kinds.
    fn outputs(&self) -> Vec<(&Path, OutKind)> {
        let mut outputs: Vec<(&Path, OutKind)> = Vec::new();
        outputs.extend(self.mesh.map(|p| (p, OutKind::Mesh)));
        for p in [self.render, self.closeups, self.section]
            .into_iter()
            .flatten()
        {
            outputs.push((p, OutKind::Png));
        }
        outputs
    }

    /// Checks the outputs against `inputs` (the DEM first) before any work.
    pub(crate) fn check(&self, inputs: &[&Path], ctx: &Ctx) -> Result<()> {
        let input = inputs[0];
        for (p, flag) in [
            (self.render, "render"),
            (self.closeups, "closeups"),
            (self.section, "section"),
        ] {
            check_png_flag(p, flag)?;
        }
        let outputs = self.outputs();
        if outputs.is_empty() && self.report.is_none() {
            bail!(
                "nothing to write for {}: give at least one of --mesh, --render, --closeups, \
                 --section or --report",
                input.display()
            );
        }
        ctx.check_outputs(inputs, &outputs)?;
        if let Some(r) = self.report {
            check_report_path(r, input, ctx.force)?;
            if outputs.iter().any(|(p, _)| *p == r) {
                bail!("--report {}: also named as another output", r.display());
            }
        }
        Ok(())
    }

    /// Stages the outputs: they appear together or not at all.
    pub(crate) fn stage(&self) -> Result<Outputs> {
        Outputs::of(&self.outputs(), self.report)
    }

    /// Writes the scene's outputs into `staged` (the mesh Y-up when `y_up`, the report with
    /// the `input` named) and returns the text printed: the figures and what was written.
    pub(crate) fn write(
        &self,
        out: &VolumeOutput,
        input: &Path,
        y_up: bool,
        staged: &Outputs,
    ) -> Result<String> {
        let mut text = out.figures.summary();
        if let (Some(path), Some(mesh)) = (self.mesh, &out.mesh) {
            let bytes = write_mesh(&staged.path(path), mesh, y_up)
                .with_context(|| format!("cannot write {}", path.display()))?;
            text += &format!("wrote {} ({:.1} MB)\n", path.display(), bytes as f64 / 1e6);
        }
        for (path, image) in [
            (self.render, &out.render),
            (self.closeups, &out.closeups),
            (self.section, &out.section),
        ] {
            if let (Some(path), Some(i)) = (path, image) {
                staged.write_png(path, i.width, i.height, &i.rgb)?;
            }
        }
        if let Some(path) = self.report {
            let mut v = serde_json::to_value(&out.figures).context("cannot encode the report")?;
            v["input"] = input.display().to_string().into();
            staged.write_json(path, &v)?;
            text += &format!("report:       wrote {}\n", path.display());
        }
        Ok(text)
    }
}
