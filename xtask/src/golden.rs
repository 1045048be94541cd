//! Golden regression: the pipeline's raster outputs on a fixed crop, compared with
//! `fixtures/golden/<name>.tif` using explicit tolerances in metres (max-abs and RMSE).
//!
//! The run uses a fixed seed and a fixed rayon thread count ([`GOLDEN_THREADS`]). On failure a
//! diff image (`target/golden/diff/<name>.png`: grey = |difference| scaled to the largest one,
//! red = cells beyond the max-abs tolerance or whose void status changed) is written and the
//! error names the command that re-blesses. When blessing is legitimate is explained in
//! `fixtures/golden/README.md`.

use std::fmt;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use relief_heightfield::Heightfield;

use relief_pipeline::{self as pipeline, PipelineConfig, RasterOutput};

/// Rayon threads of the golden run (outputs must not depend on it, but the goldens are made
/// with a stated count).
pub(crate) const GOLDEN_THREADS: usize = 2;

/// Result of one golden check.
#[derive(Debug)]
pub(crate) struct Outcome {
    /// `(name, max_abs_m, rmse_m)` per compared output.
    pub(crate) compared: Vec<(String, f64, f64)>,
    /// Files written by `--bless`.
    pub(crate) blessed: Vec<PathBuf>,
}

impl fmt::Display for Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if !self.blessed.is_empty() {
            writeln!(f, "golden: blessed {} files:", self.blessed.len())?;
            for p in &self.blessed {
                writeln!(f, "  {}", p.display())?;
            }
        }
        for (name, m, r) in &self.compared {
            writeln!(f, "golden: {name} ok (max-abs {m:.3e} m, rmse {r:.3e} m)")?;
        }
        Ok(())
    }
}

/// Folder of the golden files.
pub(crate) fn golden_dir(root: &Path) -> PathBuf {
    root.join("fixtures/golden")
}

/// Runs the golden pipeline and compares (or, with `bless`, overwrites) the goldens.
pub(crate) fn check(root: &Path, bless: bool) -> Result<Outcome> {
    let work = crate::target_dir(root).join("golden");
    let out_dir = work.join("run");
    let config = PipelineConfig::golden(root, out_dir);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(GOLDEN_THREADS)
        .build()?;
    let run = pool.install(|| pipeline::run(&config, &pipeline::default_stages()))?;
    let outputs: Vec<&RasterOutput> = run
        .state
        .outputs
        .iter()
        .filter(|o| o.tolerance.is_some())
        .collect();
    let dir = golden_dir(root);
    if bless {
        return bless_all(&dir, &outputs);
    }
    compare_all(&dir, &work.join("diff"), &outputs)
}

fn bless_all(dir: &Path, outputs: &[&RasterOutput]) -> Result<Outcome> {
    std::fs::create_dir_all(dir)?;
    let mut blessed = Vec::new();
    for o in outputs {
        let p = dir.join(format!("{}.tif", o.name));
        relief_io::write(&p, &o.raster, &relief_io::WriteOptions::default())
            .with_context(|| format!("cannot write {}", p.display()))?;
        blessed.push(p);
    }
    // Goldens whose output no longer exists are stale.
    for e in std::fs::read_dir(dir)? {
        let p = e?.path();
        let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or_default();
        if p.extension().is_some_and(|x| x == "tif") && !outputs.iter().any(|o| o.name == stem) {
            std::fs::remove_file(&p)?;
        }
    }
    Ok(Outcome {
        compared: Vec::new(),
        blessed,
    })
}

fn compare_all(dir: &Path, diff_dir: &Path, outputs: &[&RasterOutput]) -> Result<Outcome> {
    let mut failures = Vec::new();
    let mut compared = Vec::new();
    for o in outputs {
        let tol = o.tolerance.expect("filtered above");
        let p = dir.join(format!("{}.tif", o.name));
        if !p.is_file() {
            failures.push(format!("{}: no golden file {}", o.name, p.display()));
            continue;
        }
        let golden = relief_io::read(&p, &relief_io::ReadOptions::default())
            .with_context(|| format!("cannot read golden {}", p.display()))?
            .heightfield;
        match compare(&golden, &o.raster) {
            Err(msg) => failures.push(format!("{}: {msg}", o.name)),
            Ok(d) if d.max_abs > tol.max_abs_m || d.rmse > tol.rmse_m || d.void_mismatch > 0 => {
                let img = diff_dir.join(format!("{}.png", o.name));
                write_diff_image(&img, &golden, &o.raster, tol.max_abs_m)?;
                failures.push(format!(
                    "{}: max-abs {:.4e} m (tolerance {:.1e}), rmse {:.4e} m (tolerance {:.1e}), \
                     {} cells changed void status; diff image {}",
                    o.name,
                    d.max_abs,
                    tol.max_abs_m,
                    d.rmse,
                    tol.rmse_m,
                    d.void_mismatch,
                    img.display()
                ));
            }
            Ok(d) => compared.push((o.name.clone(), d.max_abs, d.rmse)),
        }
    }
    // A golden without an output means a stage stopped producing it.
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries {
            let p = e?.path();
            let stem = p.file_stem().and_then(|s| s.to_str()).unwrap_or_default();
            if p.extension().is_some_and(|x| x == "tif") && !outputs.iter().any(|o| o.name == stem)
            {
                failures.push(format!(
                    "{stem}: golden {} has no pipeline output",
                    p.display()
                ));
            }
        }
    }
    if !failures.is_empty() {
        bail!(
            "golden check failed:\n  {}\nIf (and only if) the change is intended, see \
             fixtures/golden/README.md and run `cargo xtask golden --bless`.",
            failures.join("\n  ")
        );
    }
    Ok(Outcome {
        compared,
        blessed: Vec::new(),
    })
}

/// Differences between a golden and an output of the same size.
#[derive(Debug, Clone, Copy)]
struct Diff {
    max_abs: f64,
    rmse: f64,
    void_mismatch: usize,
}

fn compare(golden: &Heightfield, out: &Heightfield) -> std::result::Result<Diff, String> {
    if (golden.width(), golden.height()) != (out.width(), out.height()) {
        return Err(format!(
            "size {} x {} differs from the golden's {} x {}",
            out.width(),
            out.height(),
            golden.width(),
            golden.height()
        ));
    }
    let (mut se, mut n, mut max_abs, mut void_mismatch) = (0.0f64, 0usize, 0.0f64, 0usize);
    for (&a, &b) in golden.as_slice().iter().zip(out.as_slice()) {
        match (a.is_nan(), b.is_nan()) {
            (true, true) => {}
            (false, false) => {
                let d = (a as f64 - b as f64).abs();
                se += d * d;
                n += 1;
                max_abs = max_abs.max(d);
            }
            _ => void_mismatch += 1,
        }
    }
    Ok(Diff {
        max_abs,
        rmse: if n > 0 { (se / n as f64).sqrt() } else { 0.0 },
        void_mismatch,
    })
}

fn write_diff_image(path: &Path, golden: &Heightfield, out: &Heightfield, tol: f64) -> Result<()> {
    let (w, h) = (golden.width(), golden.height());
    let diffs: Vec<f64> = golden
        .as_slice()
        .iter()
        .zip(out.as_slice())
        .map(|(&a, &b)| (a as f64 - b as f64).abs())
        .collect();
    let max = diffs
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(0.0, f64::max);
    let mut rgb = Vec::with_capacity(w * h * 3);
    for d in &diffs {
        if !d.is_finite() || *d > tol {
            rgb.extend_from_slice(&[255, 0, 0]);
        } else {
            let g = if max > 0.0 {
                (d / max * 255.0) as u8
            } else {
                0
            };
            rgb.extend_from_slice(&[g, g, g]);
        }
    }
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)?;
    }
    relief_io::write_rgb_png(path, w, h, &rgb)
        .with_context(|| format!("cannot write diff image {}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The golden check as a test: `cargo test -p xtask` fails when a pipeline output drifts.
    #[test]
    fn golden_outputs_match() {
        let root = crate::project_root();
        if let Err(e) = check(&root, false) {
            panic!("{e:#}");
        }
    }

    /// Outputs must not depend on the rayon thread count (the design's determinism invariant).
    #[test]
    fn outputs_independent_of_thread_count() {
        let root = crate::project_root();
        let tmp = tempfile::tempdir().unwrap();
        let run_with = |threads: usize| {
            let config = PipelineConfig::golden(&root, tmp.path().join(threads.to_string()));
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| pipeline::run(&config, &pipeline::default_stages()))
                .unwrap()
                .state
                .outputs
        };
        let (one, two) = (run_with(1), run_with(GOLDEN_THREADS));
        assert_eq!(one.len(), two.len());
        for (a, b) in one.iter().zip(&two) {
            let bits = |o: &RasterOutput| -> Vec<u32> {
                o.raster.as_slice().iter().map(|v| v.to_bits()).collect()
            };
            assert_eq!(
                bits(a),
                bits(b),
                "{} differs between 1 and 2 threads",
                a.name
            );
        }
    }

    #[test]
    fn compare_detects_changes() {
        let a = Heightfield::from_fn(8, 8, 1.0, 1.0, |x, y| (x + y) as f32);
        let mut b = a.clone();
        assert_eq!(compare(&a, &b).unwrap().max_abs, 0.0);
        b.set(3, 3, 7.5);
        let d = compare(&a, &b).unwrap();
        assert!((d.max_abs - 1.5).abs() < 1e-9);
        assert!((d.rmse - 1.5 / 8.0).abs() < 1e-9);
        b.set(0, 0, f32::NAN);
        assert_eq!(compare(&a, &b).unwrap().void_mismatch, 1);
        let c = a.crop(0, 0, 4, 4).unwrap();
        assert!(compare(&a, &c).is_err());
    }
}
