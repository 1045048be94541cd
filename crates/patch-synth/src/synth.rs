//! Raster-order synthesis over an overlapping grid (sections 3.2 to 3.4).

use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use relief_heightfield::{Heightfield, Progress};

use crate::block::{self, Block, Canvas, Shared};
use crate::error::{PatchSynthError, Result};
use crate::index::{Exemplar, ExemplarIndex, PatchRef, grid_rects};
use crate::settings::Settings;
use crate::validate::validate;

pub use crate::control::Control;
pub(crate) use crate::control::allowed_categories;
pub use crate::grid::MAX_OUTPUT_CELLS;
use crate::grid::{Grid, block_seed, grid_for, pad};

/// Where each output cell came from and where the seams run (for visualisation).
#[derive(Debug, Clone, PartialEq)]
pub struct SeamMap {
    /// Width in cells (the output's).
    pub width: usize,
    /// Height in cells.
    pub height: usize,
    /// True on the cells of a cut path.
    pub seam: Vec<bool>,
    /// Index into [`Synthesis::placements`] of the patch that supplied each cell (new side of
    /// the cut).
    pub source: Vec<u32>,
}

impl SeamMap {
    /// RGB image (row-major, 3 bytes a cell): one muted colour per patch (a fixed hash of its
    /// placement index, so neighbours differ), seam cells white, unfilled cells black.
    pub fn rgb(&self) -> Vec<u8> {
        let mut rgb = Vec::with_capacity(self.width * self.height * 3);
        for (&src, &seam) in self.source.iter().zip(&self.seam) {
            if seam {
                rgb.extend_from_slice(&[255, 255, 255]);
            } else if src == u32::MAX {
                rgb.extend_from_slice(&[0, 0, 0]);
            } else {
                let mut z = (src as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                z ^= z >> 29;
                rgb.extend_from_slice(&[
                    60 + (z & 0x7f) as u8,
                    60 + ((z >> 8) & 0x7f) as u8,
                    60 + ((z >> 16) & 0x7f) as u8,
                ]);
            }
        }
        rgb
    }
}

/// One inserted patch.
#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    /// Grid column.
    pub gx: usize,
    /// Grid row.
    pub gy: usize,
    /// Output column of the patch's top-left cell.
    pub x: usize,
    /// Output row of the patch's top-left cell.
    pub y: usize,
    /// The exemplar patch.
    pub patch: PatchRef,
    /// Vertical translation applied (equation 3), 0 when rejected.
    pub translation: f32,
    /// True when equation (3) gave `|h| > lambda` and the translation was not applied.
    pub translation_rejected: bool,
    /// Guide distance `G` (RMS, metres).
    pub guide_distance: f32,
    /// Overlap distance `O` (RMS, metres).
    pub overlap_distance: f32,
    /// Cut cost `P` (RMS error along the seam, metres).
    pub cut_cost: f32,
    /// Energy `M` of equation (1).
    pub energy: f32,
    /// Number of candidates scored exactly.
    pub candidates: usize,
}

/// Summary of a synthesis run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SynthesisStats {
    /// Grid size (columns, rows).
    pub grid: (usize, usize),
    /// Patches inserted.
    pub patches: usize,
    /// Mean number of candidates scored per block.
    pub mean_candidates: f64,
    /// Mean number of hash-table buckets probed per block.
    pub mean_buckets_probed: f64,
    /// Translations applied (|h| <= lambda and h != 0).
    pub translations_applied: usize,
    /// Translations rejected (|h| > lambda).
    pub translations_rejected: usize,
    /// Largest applied |h|.
    pub max_translation: f32,
    /// Mean `G`, `O`, `P` of the chosen patches.
    pub mean_guide_distance: f64,
    /// Mean overlap distance of the chosen patches.
    pub mean_overlap_distance: f64,
    /// Mean cut cost of the chosen patches.
    pub mean_cut_cost: f64,
    /// Mean conjugate-gradient iterations of the Poisson blending (0 if unused).
    pub mean_poisson_iterations: f64,
    /// Sigma in cells of the low-pass the guide distance applied to the patches (0: none).
    pub guide_lowpass: f32,
}

/// Result of [`synthesize`].
#[derive(Debug, Clone)]
pub struct Synthesis {
    /// The synthesized terrain (`width x height`, cell size of the guide or first exemplar).
    pub heightfield: Heightfield,
    /// Seam and source maps.
    pub seam_map: SeamMap,
    /// Every inserted patch, in insertion order.
    pub placements: Vec<Placement>,
    /// Summary figures.
    pub stats: SynthesisStats,
}

/// Synthesizes a terrain from the preprocessed exemplars under `control` (sections 3.2-3.4).
///
/// Blocks are visited in raster order; at each block the candidates are scored in parallel and
/// the choice uses a random generator seeded from `(settings.seed, block)`, so the output bytes
/// are the same for a seed whatever the rayon thread count. When a guide is given and
/// `settings.enforce_validation` is set, the input validation of section 4 runs first and a
/// failure is returned as [`PatchSynthError::Validation`].
pub fn synthesize(
    index: &ExemplarIndex,
    control: &Control,
    settings: &Settings,
    progress: &dyn Progress,
) -> Result<Synthesis> {
    settings.check()?;
    index.check_settings(settings)?;
    control.check()?;
    if settings.enforce_validation && control.guide.is_some() {
        let report = validate(index, control, settings)?;
        if !report.ok {
            return Err(PatchSynthError::Validation(Box::new(report)));
        }
    }
    let (p, o) = (settings.patch_size, settings.overlap);
    let s = p - o;
    let (w, h) = (control.width, control.height);
    let Grid { nx, ny, cw, ch } = grid_for(w, h, p, o);
    let guide: Option<Vec<f32>> = control
        .guide
        .as_ref()
        .map(|g| pad(g.as_slice(), w, h, cw, ch));
    let cmap: Option<Vec<u16>> = control
        .categories
        .as_ref()
        .map(|m| pad(&m.ids, w, h, cw, ch));
    let block_rects = grid_rects(p, settings.blocks);
    let guide_rects = grid_rects(p, settings.guide_cells);
    let guide_lowpass = control.guide.as_ref().map_or(0.0, |g| {
        settings
            .guide_lowpass
            .unwrap_or_else(|| crate::guide::smoothness_scale(g).min(p as f32))
    });
    let lowpassed = index.lowpassed_guide_tables(guide_lowpass, &block_rects)?;
    let (lowpassed, guide_desc) = lowpassed.map_or((None, None), |(s, d)| (Some(s), Some(d)));
    let sh = Shared {
        index,
        settings,
        guide: guide.as_deref(),
        block_rects: &block_rects,
        guide_rects: &guide_rects,
        guide_sats: lowpassed.as_deref().unwrap_or(&index.sats),
        guide_desc,
    };
    let mut cv = Canvas {
        values: vec![0.0f32; cw * ch],
        filled: vec![false; cw * ch],
        seam: vec![false; cw * ch],
        source: vec![u32::MAX; cw * ch],
        cw,
        ch,
    };
    let mut placements: Vec<Placement> = Vec::with_capacity(nx * ny);
    let mut stats = SynthesisStats {
        grid: (nx, ny),
        guide_lowpass,
        ..Default::default()
    };
    let mut poisson_iters = 0usize;
    let mut buckets_probed = 0usize;
    progress.begin("patch-synth: synthesis", (nx * ny) as u64);

    for gy in 0..ny {
        for gx in 0..nx {
            let b = Block {
                gx,
                gy,
                x0: gx * s,
                y0: gy * s,
                p,
                o,
                has_left: gx > 0,
                has_top: gy > 0,
            };
            let (pl, probed, iters) =
                place_block(&sh, &mut cv, &b, cmap.as_deref(), &placements, nx)?;
            buckets_probed += probed;
            poisson_iters += iters;
            if pl.translation_rejected {
                stats.translations_rejected += 1;
            } else if pl.translation != 0.0 {
                stats.translations_applied += 1;
                stats.max_translation = stats.max_translation.max(pl.translation.abs());
            }
            stats.mean_candidates += pl.candidates as f64;
            stats.mean_guide_distance += pl.guide_distance as f64;
            stats.mean_overlap_distance += pl.overlap_distance as f64;
            stats.mean_cut_cost += pl.cut_cost as f64;
            placements.push(pl);
            progress.advance(1);
        }
    }
    let np = placements.len().max(1) as f64;
    stats.patches = placements.len();
    stats.mean_candidates /= np;
    stats.mean_guide_distance /= np;
    stats.mean_overlap_distance /= np;
    stats.mean_cut_cost /= np;
    stats.mean_buckets_probed = buckets_probed as f64 / np;
    stats.mean_poisson_iterations = poisson_iters as f64 / np;

    let (hf, seam_map) = assemble(&cv, control, index, w, h)?;
    Ok(Synthesis {
        heightfield: hf,
        seam_map,
        placements,
        stats,
    })
}

/// Chooses and inserts the patch of block `b` (section 3: candidates from the probed
/// clusters, energy, cut, choice): its placement, the buckets probed and the Poisson
/// iterations of the insert.
fn place_block(
    sh: &Shared<'_>,
    cv: &mut Canvas,
    b: &Block,
    cmap: Option<&[u16]>,
    placements: &[Placement],
    nx: usize,
) -> Result<(Placement, usize, usize)> {
    let (gx, gy) = (b.gx, b.gy);
    let mut rng = Pcg64Mcg::seed_from_u64(block_seed(sh.settings.seed, gx as u64, gy as u64));
    let allowed = allowed_categories(sh.index, cmap, cv.cw, b.x0, b.y0, b.p);
    if !allowed.iter().any(|&a| a) {
        return Err(PatchSynthError::NoCandidates {
            gx,
            gy,
            reason: "the categorisation map names no category of the exemplar set".into(),
        });
    }
    let target_desc = block::target_descriptor(sh, cv, b);
    let order = block::cluster_order(sh, cv, b, target_desc.as_deref(), &mut rng);
    let probed = block::probe_buckets(sh, b, &order, &allowed)?;
    let cands = block::candidates(sh, cv, b, &probed, target_desc.as_deref(), &mut rng);
    let mut scored = block::score(sh, cv, b, &cands);
    let ncand = scored.len();
    // Sources of the placed blocks within reuse_radius (placements are in raster order:
    // block (x, y) is placement y * nx + x).
    let r = sh.settings.reuse_radius;
    let nearby: Vec<PatchRef> = (gy.saturating_sub(r)..=gy)
        .flat_map(|y| (gx.saturating_sub(r)..=(gx + r).min(nx - 1)).map(move |x| (x, y)))
        .filter(|&(x, y)| y < gy || x < gx)
        .map(|(x, y)| placements[y * nx + x].patch)
        .collect();
    block::penalise_reuse(sh, &mut scored, &nearby);
    scored.truncate(sh.settings.survivors);
    let cuts = block::cut_survivors(sh, cv, b, &scored);
    let (pick, energies) = block::choose(sh.settings, &scored, &cuts, &mut rng);
    let sc = &scored[pick];
    let pi = placements.len() as u32;
    let iters = block::insert(sh, cv, b, sc, &cuts[pick], pi);
    let pcost = cuts[pick].2;
    let placement = Placement {
        gx,
        gy,
        x: b.x0,
        y: b.y0,
        patch: sh.index.patches[sc.id as usize],
        translation: sc.h,
        translation_rejected: sc.rejected,
        guide_distance: sc.g,
        overlap_distance: sc.o,
        cut_cost: pcost,
        energy: energies[pick],
        candidates: ncand,
    };
    Ok((placement, probed.len(), iters))
}

/// The output heightfield (cell size and georeference of the guide, else of the first
/// exemplar) and seam map cropped from the canvas.
fn assemble(
    cv: &Canvas,
    control: &Control,
    index: &ExemplarIndex,
    w: usize,
    h: usize,
) -> Result<(Heightfield, SeamMap)> {
    let cw = cv.cw;
    let crop = |v: &[f32]| -> Vec<f32> {
        (0..h)
            .flat_map(|y| v[y * cw..y * cw + w].iter().copied())
            .collect()
    };
    let (cx, cy) = control.guide.as_ref().map_or_else(
        || index.exemplars[0].heightfield.cell_size(),
        |g| g.cell_size(),
    );
    let mut hf = Heightfield::new(w, h, crop(&cv.values), cx, cy)?;
    if let Some(g) = &control.guide {
        hf.set_georef(g.georef().cloned());
    }
    let seam_map = SeamMap {
        width: w,
        height: h,
        seam: (0..h)
            .flat_map(|y| cv.seam[y * cw..y * cw + w].iter().copied())
            .collect(),
        source: (0..h)
            .flat_map(|y| cv.source[y * cw..y * cw + w].iter().copied())
            .collect(),
    };
    Ok((hf, seam_map))
}

/// Builds the index, then synthesizes: the one-call entry point.
pub fn quilt(
    exemplars: Vec<Exemplar>,
    control: &Control,
    settings: &Settings,
    progress: &dyn Progress,
) -> Result<Synthesis> {
    control.check()?;
    let index = ExemplarIndex::build(exemplars, settings, progress)?;
    synthesize(&index, control, settings, progress)
}
