//! Stage `sparse`: the compact representation of guerin2016 section 5.1 (relief-sparse-core +
//! K-SVD of relief-dictionary-learning), the analogue of the paper's table 1.
//!
//! For each sparsity `s` (default 1, 2, 8) a dictionary of `N` atoms (`a x a` patches) is
//! learned by approximate K-SVD on the terrain's own patches with that `s`, the terrain is
//! encoded by Batch-OMP into a Sparse Construction Tree and decoded by stamping. The table gives
//! the paper's storage `t(s, N) = KN + n(2s + 2) + 1`, `rho = t / t0`, the real `.sct` size
//! (f32 and 16-bit quantised coefficients), PSNR and RMSE against the input, and the time of
//! learning, encoding and decoding. The reconstructions' hillshades are shown beside the
//! original's.
//!
//! Tree example (section 5.4, figures 12-13): a river is carved into the `s = 8` tree with
//! `Min(terrain, river bed)`: the polyline follows the valley floor (lowest smoothed cell in a
//! window around the previous vertex, column by column), the bed descends monotonically
//! downstream, and the cross-section is parabolic. The carved tree is rasterised at scale 1 and a
//! window of it at scale 4, showing that the representation is resolution-free.
//!
//! The terrain handed to the next stage is unchanged (later stages work on the original), unless
//! `replace_terrain` is set.

use std::time::Instant;

use anyhow::{Context, Result, bail};
use relief_dictionary_learning::CompressSettings;
use relief_heightfield::{Heightfield, Progress};
use relief_sparse_core::{
    FormatOptions, FunctionAtomRegistry, Node, RasterSettings, River, RiverMode, Sct, Window,
    compression_report, extract_patches,
};
use serde::{Deserialize, Serialize};

use super::spec::StageParams;
use super::{Stage, StageCx, Tolerance};

/// Tolerance of the sparse goldens: K-SVD and Batch-OMP are deterministic for a seed whatever
/// the thread count, so reruns agree to float rounding; one atom chosen differently (a real
/// change) moves the cells of a primitive by metres.
const SPARSE_TOLERANCE: Tolerance = Tolerance {
    max_abs_m: 0.5,
    rmse_m: 0.02,
};

/// Parameters of the `sparse` stage (JSON `params`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub(crate) struct SparseParams {
    /// The compress job, the same settings as `relief compress` ([`CompressSettings`]). The
    /// table runs it once per entry of `sparsities` (its `sparsity` is set per row), with the
    /// atoms capped at the number of patches and `seed` mixed with the spec's and the row.
    pub(crate) job: CompressSettings,
    /// The sparsities of the table.
    pub(crate) sparsities: Vec<usize>,
    /// Build the river tree example.
    pub(crate) river: bool,
    /// Hand the reconstruction at the largest sparsity to the next stages.
    pub(crate) replace_terrain: bool,
}

impl Default for SparseParams {
    fn default() -> Self {
        Self {
            job: CompressSettings::default(),
            sparsities: vec![1, 2, 8],
            river: true,
            replace_terrain: false,
        }
    }
}

impl StageParams for SparseParams {
    fn check_params(&self) -> Result<()> {
        self.job.check().context("invalid `job`")?;
        if self.sparsities.is_empty() {
            bail!("invalid parameter `sparsities` = []: give at least one sparsity");
        }
        for &s in &self.sparsities {
            CompressSettings {
                sparsity: s,
                ..self.job
            }
            .check()
            .context("invalid `sparsities`")?;
        }
        Ok(())
    }
}

impl Stage for SparseParams {
    fn run(&self, cx: &mut StageCx<'_>) -> Result<()> {
        let p = self;
        let terrain = cx.state.complete_terrain("sparse")?;
        // Pre-flight under `relief run --max-memory`: the patches and the dictionary.
        cx.config.limits.check_memory(
            "sparse",
            relief_dictionary_learning::memory::compress_job_bytes(
                (terrain.width(), terrain.height()),
                &p.job,
                p.sparsities.iter().copied().max().unwrap_or(1),
            ),
            "a larger `job.step` or `job.spacing`, fewer `job.atoms`, or a smaller terrain \
             (`crop`)",
        )?;
        let progress = cx.progress();
        let geometry = p.job.geometry();
        let patches = extract_patches(&terrain, &geometry)?;
        let n_patches = patches.matrix.nrows();
        let n_atoms = p.job.atoms.min(n_patches);
        let a = p.job.patch_size;
        cx.section.figure("patch_size", a);
        cx.section.figure("atoms", n_atoms);
        cx.section.figure("primitives", n_patches);
        let registry = FunctionAtomRegistry::new();
        let original = cx.save_hillshade("sparse_original", &terrain)?;
        let mut rows = Vec::new();
        let mut best: Option<(usize, f64, Sct, Heightfield)> = None;
        for (k, &s) in p.sparsities.iter().enumerate() {
            progress.begin(&format!("K-SVD, N = {n_atoms}, s = {s}"), 0);
            let out = CompressSettings {
                sparsity: s,
                atoms: n_atoms,
                seed: cx.config.seed ^ (0x5ca7_0000 + k as u64) ^ p.job.seed,
                ..p.job
            }
            .run(&terrain, None, &progress)
            .with_context(|| format!("compression at s = {s}"))?;
            let (t_learn, t_encode) = (out.figures.dictionary_seconds, out.figures.encode_seconds);
            let sct = out.sct;
            let t = Instant::now();
            let rec = sct.rasterize_with_progress(&RasterSettings::default(), &progress)?;
            let t_decode = t.elapsed().as_secs_f64();
            let f = compression_report(&terrain, &sct, &FormatOptions::default(), &registry)?;
            let q = compression_report(
                &terrain,
                &sct,
                &FormatOptions {
                    quantize_coefficients: true,
                },
                &registry,
            )?;
            let name = format!("sparse_s{s}");
            // The middle sparsity is the golden (one golden per stage keeps them small).
            let tolerance = (s == 2).then_some(SPARSE_TOLERANCE);
            cx.save_raster(&name, &format!("decoded, s = {s}"), &rec, tolerance)?;
            if let (Some(o), Some(r)) = (&original, cx.save_hillshade(&format!("{name}_hs"), &rec)?)
            {
                cx.section.pair(
                    (o, "original"),
                    (
                        &r,
                        &format!("s = {s}, N = {n_atoms}: PSNR {:.1} dB", f.psnr),
                    ),
                    &format!(
                        "hillshade of the decoded terrain, s = {s} (rho {:.1} %, {} bytes)",
                        100.0 * f.rho,
                        f.bytes
                    ),
                );
            }
            cx.section.figure(&format!("psnr_s{s}"), f.psnr);
            cx.section.figure(&format!("rmse_m_s{s}"), f.rmse);
            cx.section.figure(&format!("rho_s{s}"), f.rho);
            cx.section.figure(&format!("bytes_s{s}"), f.bytes);
            cx.section.figure(&format!("bytes_q16_s{s}"), q.bytes);
            rows.push((
                format!("s = {s}"),
                vec![
                    n_atoms as f64,
                    f.t as f64,
                    100.0 * f.rho,
                    f.bytes as f64,
                    q.bytes as f64,
                    100.0 * f.byte_ratio,
                    f.psnr,
                    q.psnr,
                    f.rmse,
                    t_learn,
                    t_encode,
                    t_decode,
                ],
            ));
            if best.as_ref().is_none_or(|b| s >= b.0) {
                best = Some((s, f.psnr, sct, rec));
            }
        }
        let rows_ref: Vec<(&str, Vec<f64>)> =
            rows.iter().map(|(n, v)| (n.as_str(), v.clone())).collect();
        cx.section.numbers(
            "compact representation (guerin2016 table 1 analogue)",
            &format!(
                "{} x {} terrain, t0 = {} samples, {n_patches} primitives of {a} x {a} (K = {}), \
                 step {h}, R = {r}; dictionary learned by approximate K-SVD ({} iterations) per \
                 row; t = KN + n(2s + 2) + 1; bytes = real .sct size (f32 / 16-bit \
                 coefficients); PSNR over the elevation range",
                terrain.width(),
                terrain.height(),
                terrain.width() * terrain.height(),
                a * a,
                p.job.iterations,
                h = geometry.step,
                r = geometry.support_radius,
            ),
            &[
                "sparsity",
                "N",
                "t (values)",
                "rho %",
                "bytes",
                "bytes q16",
                "bytes % of f32",
                "PSNR dB",
                "PSNR q16 dB",
                "RMSE m",
                "learn s",
                "encode s",
                "decode s",
            ],
            &rows_ref,
        );
        let Some((s_best, psnr_best, sct, rec)) = best else {
            bail!("no sparsity was run");
        };
        if let Some((_, v)) = rows.iter().find(|(n, _)| n == "s = 2") {
            cx.section.headline("rho_s2", v[2] / 100.0);
        }
        cx.section.headline(&format!("psnr_s{s_best}"), psnr_best);

        if p.river {
            river_example(cx, &terrain, sct, &rec)?;
        }
        if p.replace_terrain {
            cx.state.set_terrain(rec);
        }
        Ok(())
    }
}

/// A valley-following polyline: one vertex every `step` columns at the lowest cell of a
/// box-smoothed copy of the terrain within `reach` rows of the previous vertex, then smoothed
/// by Catmull-Rom subdivision.
fn valley_path(hf: &Heightfield) -> Vec<[f64; 2]> {
    let (w, h) = (hf.width(), hf.height());
    let k = (w.min(h) / 32).max(1);
    let smooth = hf.downsample_box(k).ok();
    let sample = |x: usize, y: usize| -> f32 {
        match &smooth {
            Some(s) => s.get((x / k).min(s.width() - 1), (y / k).min(s.height() - 1)),
            None => hf.get(x, y),
        }
    };
    let n = 12usize;
    let reach = (h / 10).max(2);
    // Start at the lowest smoothed cell of the first column.
    let mut y = (0..h)
        .min_by(|&a, &b| sample(0, a).total_cmp(&sample(0, b)))
        .unwrap_or(h / 2);
    let mut path = Vec::with_capacity(n + 1);
    for i in 0..=n {
        let x = (i * (w - 1)) / n;
        let lo = y.saturating_sub(reach);
        let hi = (y + reach).min(h - 1);
        y = (lo..=hi)
            .min_by(|&a, &b| sample(x, a).total_cmp(&sample(x, b)))
            .unwrap_or(y);
        path.push([x as f64, y as f64]);
    }
    // Catmull-Rom subdivision: small angles between segments, so the nearest-segment
    // interpolation of the bed has no visible step on the inside of bends.
    let sub = 6;
    let mut smooth = Vec::with_capacity(n * sub + 1);
    for i in 0..n {
        let p0 = path[i.saturating_sub(1)];
        let (p1, p2) = (path[i], path[i + 1]);
        let p3 = path[(i + 2).min(n)];
        for k in 0..sub {
            let t = k as f64 / sub as f64;
            let (t2, t3) = (t * t, t * t * t);
            let c = |a: f64, b: f64, c: f64, d: f64| {
                0.5 * (2.0 * b
                    + (c - a) * t
                    + (2.0 * a - 5.0 * b + 4.0 * c - d) * t2
                    + (3.0 * b - a - 3.0 * c + d) * t3)
            };
            smooth.push([
                c(p0[0], p1[0], p2[0], p3[0]),
                c(p0[1], p1[1], p2[1], p3[1]).clamp(0.0, (h - 1) as f64),
            ]);
        }
    }
    smooth.push(path[n]);
    smooth
}

/// Carves a river into the tree (section 5.4) and shows it at scale 1 and a window at scale 4.
fn river_example(
    cx: &mut StageCx<'_>,
    terrain: &Heightfield,
    sct: Sct,
    decoded: &Heightfield,
) -> Result<()> {
    let t = Instant::now();
    let path = valley_path(terrain);
    let n = path.len();
    let relief = terrain.relief() as f64;
    let (w, h) = (terrain.width(), terrain.height());
    // Width grows downstream (w / 100 .. w / 40 half widths); the banks rise 30 % of the
    // relief at one half width from the axis, so the carve stays a narrow gorge.
    let half_width: Vec<f64> = (0..n)
        .map(|i| (w as f64 / 100.0) * (1.0 + 1.5 * i as f64 / (n - 1) as f64))
        .map(|v| v.max(1.5))
        .collect();
    let banks: Vec<f64> = vec![(0.3 * relief).max(1.0); n];
    let channel = (0.03 * relief).max(1.0);
    // The bed follows the terrain along the path, a channel depth below it, never rising.
    let mut bed = Vec::with_capacity(n);
    let mut last = f64::INFINITY;
    for v in &path {
        let z = sct.eval(v[0], v[1]) - channel;
        last = last.min(z);
        bed.push(last);
    }
    let river = River::new(path.clone(), half_width, banks, RiverMode::Bed(bed))?;
    let mut tree = sct;
    let base = tree.take_root();
    tree.set_root(Node::Min(vec![base, Node::River(river)]))?;
    let carved = tree.rasterize(&RasterSettings::default())?;
    let bytes = tree.to_bytes()?.len();
    let lowered = carved
        .as_slice()
        .iter()
        .zip(decoded.as_slice())
        .filter(|(c, o)| **c < **o - 0.5)
        .count();
    cx.section.figure("river_vertices", n);
    cx.section.figure("river_tree_bytes", bytes);
    cx.section
        .figure("river_cells_lowered", lowered as f64 / (w * h) as f64);
    cx.save_raster(
        "sparse_river",
        "s = 8 tree with a river carved along the valley: Min(terrain, river bed)",
        &carved,
        Some(SPARSE_TOLERANCE),
    )?;
    // A window around the middle of the river at 4x resolution, from the same tree.
    let mid = path[n / 2];
    let side = (w.min(h) / 4).max(8);
    let scale = 4.0;
    let (fw, fh) = tree.raster_size(scale)?;
    let win_w = (side as f64 * scale) as usize;
    let x0 = ((mid[0] - side as f64 / 2.0).max(0.0) * scale) as usize;
    let y0 = ((mid[1] - side as f64 / 2.0).max(0.0) * scale) as usize;
    let win = Window {
        x: x0.min(fw - win_w.min(fw)),
        y: y0.min(fh - win_w.min(fh)),
        width: win_w.min(fw),
        height: win_w.min(fh),
    };
    let zoom = tree.rasterize(&RasterSettings {
        scale,
        window: Some(win),
    })?;
    if let Some(z) = cx.save_hillshade("sparse_river_x4", &zoom)?
        && let Some(c) = cx.save_hillshade("sparse_river_hs", &carved)?
    {
        cx.section.pair(
            (&c, "river carved into the tree (scale 1)"),
            (&z, "window decoded at scale 4 from the same tree"),
            &format!(
                "construction tree Min(sparse layer, river): {n}-vertex polyline, \
                 {bytes} bytes; x4 window {} x {} at ({}, {})",
                win.width, win.height, win.x, win.y
            ),
        );
    }
    cx.section
        .figure("river_seconds", t.elapsed().as_secs_f64());
    Ok(())
}
