//! Stage `convert`: writes the current terrain in every raster format relief-io writes, reads
//! each file back and checks the difference against the format's stated precision (exact for
//! f32 formats, half a quantisation step for 16-bit ones).

use anyhow::{Context, Result, bail};
use relief_heightfield::{Heightfield, metrics};
use relief_io::{ReadOptions, WriteOptions};

use super::{Stage, StageCx};

/// Round trips through every writable raster format.
#[derive(Debug)]
pub(crate) struct ConvertRoundTrips;

/// How precise a format's round trip must be.
#[derive(Debug, Clone, Copy)]
enum Precision {
    /// Bit-exact f32.
    Exact,
    /// Within half of the 16-bit step `(max - min) / 65535`.
    HalfStep16,
}

const FORMATS: &[(&str, Precision)] = &[
    ("tif", Precision::Exact),
    ("exr", Precision::Exact),
    ("npy", Precision::Exact),
    ("r32", Precision::Exact),
    ("f32", Precision::Exact),
    ("asc", Precision::Exact),
    ("png", Precision::HalfStep16),
    ("r16", Precision::HalfStep16),
];

impl Stage for ConvertRoundTrips {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let hf = cx.state.terrain()?.clone();
        let (lo, hi) = hf.min_max().context("terrain has no valid cell")?;
        let step = (hi as f64 - lo as f64) / 65535.0;
        let dir = cx.config.out_dir.join("roundtrip");
        std::fs::create_dir_all(&dir)?;
        let mut rows = Vec::new();
        let mut failures = Vec::new();
        for &(ext, precision) in FORMATS {
            let path = dir.join(format!("dem.{ext}"));
            // r16 has no header: state the mapping when writing and when reading.
            let mapping = (lo as f64, if step > 0.0 { step } else { 1.0 });
            let wopts = WriteOptions {
                mapping: (ext == "r16").then_some(mapping),
                ..Default::default()
            };
            relief_io::write(&path, &hf, &wopts)
                .with_context(|| format!("cannot write {}", path.display()))?;
            let ropts = ReadOptions {
                width: Some(hf.width()),
                height: Some(hf.height()),
                r16_mapping: mapping,
                ..Default::default()
            };
            let back: Heightfield = relief_io::read(&path, &ropts)
                .with_context(|| format!("cannot read back {}", path.display()))?
                .heightfield;
            let bytes = std::fs::metadata(&path)?.len();
            let max_abs = metrics::max_abs_diff(&hf, &back)?;
            let rmse = metrics::rmse(&hf, &back)?;
            let bound = match precision {
                Precision::Exact => 0.0,
                // Plus a few f32 ulps of the heights for the arithmetic of the mapping itself.
                Precision::HalfStep16 => {
                    step * 0.5 + 4.0 * f32::EPSILON as f64 * hi.abs().max(lo.abs()) as f64
                }
            };
            let ok = back.width() == hf.width() && back.height() == hf.height() && max_abs <= bound;
            if !ok {
                failures.push(format!("{ext}: max-abs {max_abs} m > {bound} m"));
            }
            cx.section.figure(&format!("{ext}_max_abs_m"), max_abs);
            rows.push(vec![
                ext.to_string(),
                bytes.to_string(),
                format!("{max_abs:.3e}"),
                format!("{rmse:.3e}"),
                format!("{bound:.3e}"),
                if ok { "ok" } else { "FAIL" }.to_string(),
            ]);
        }
        cx.section.table(
            "write -> read round trips",
            &[
                "format",
                "bytes",
                "max-abs (m)",
                "rmse (m)",
                "bound (m)",
                "result",
            ],
            rows,
        );
        if !failures.is_empty() {
            bail!(
                "round trips beyond the stated precision: {}",
                failures.join("; ")
            );
        }
        Ok(())
    }
}
