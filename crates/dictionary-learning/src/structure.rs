//! Exemplar structure for sketch synthesis: the landforms between the sketch's pixel and its
//! strokes, taken from the exemplar as whole coherent patches (a departure from the paper, see
//! [`exemplar_structure`]).
//!
//! A painted sketch says where the high and low ground is, at the scale of its strokes. Each
//! x4 step of [`crate::amplify`] adds only the octave below its input's cell, so the valleys and
//! spurs a few sketch pixels apart, the ones that make a painted blob read as a mountain range,
//! would never be added: the result is the blob with fine texture. This step adds them at the
//! sketch's own resolution, before the x4 steps:
//!
//! * the exemplar is brought to the sketch's cell size (box down-sampling; when it is too small
//!   or too coarse for that, a reduced copy stands in by self-similarity, and the figures say
//!   so);
//! * both the sketch and the exemplar are split by a Gaussian low-pass of `R / 2` cells into a
//!   smooth part and a band (the band holds the landforms up to about a patch wide);
//! * the sketch is covered by square patches of side `4R` on a half-patch grid; each takes the
//!   exemplar patch whose smooth part best matches the sketch's there (shape, and level with a
//!   lower weight: high ground takes the exemplar's high ground), with the paper's `s = 1` and a
//!   complete dictionary (every exemplar patch is a candidate);
//! * patches are chosen in scan order and a candidate that continues an already chosen
//!   neighbour's exemplar region (its position offset by the grid offset) is also tried, with
//!   the mismatch of its band over the overlap added to its cost: where neighbours continue
//!   each other, the blend reproduces the exemplar's band exactly (whole valleys, not a blend
//!   of unrelated ones);
//! * the output is the sketch plus the chosen bands blended with separable Hann windows (a
//!   partition of unity at a half-patch step). The sketch is kept whole rather than replaced
//!   by its smooth part, so narrow painted strokes survive (measured on alps_dem and
//!   grandcanyon: correlation with the sketch 0.958 / 0.921 against 0.951 / 0.910, and a
//!   slightly closer slope histogram).

use rayon::prelude::*;
use relief_heightfield::Heightfield;
use serde::{Deserialize, Serialize};

use crate::error::{LearnError, Result};
use crate::multires::octave_ratio;
use crate::multires::{STEP_FACTOR, box_resample, grid_at};
use crate::noise::item_seed;

/// Smallest side (cells) of the exemplar grid the structure is taken from, in patch sides
/// (3: the exemplar is reduced closer to the sketch's cell, so less relies on self-similarity;
/// measured on alps_dem, slope-histogram distance 4.1 deg against 7.1 with 6).
const MIN_EXEMPLAR_PATCHES: usize = 3;

/// Largest number of exemplar positions scored per patch (beyond it the positions are
/// strided; continuing candidates are still tried at every position).
const MAX_CANDIDATES: usize = 16_384;

/// Fewest exemplar positions scored per patch, whatever the sketch's size.
const MIN_CANDIDATES: usize = 1024;

/// Budget of multiply-adds for scoring every patch against the candidates (about a second on
/// two cores); larger sketches stride the candidates more.
const SCORE_BUDGET: f64 = 2.0e9;

/// Number of best-matching positions kept per patch for the coherent pass.
const SHORTLIST: usize = 24;

/// Weight of the level mismatch (mean difference) against the shape mismatch in the cost.
const LEVEL_WEIGHT: f64 = 0.25;

/// Weight of the band mismatch over the overlap with chosen neighbours. Continuing a
/// neighbour's exemplar region (no mismatch) is strongly preferred: a blend of unrelated bands
/// loses half their amplitude and their shapes. Measured on alps_dem: 81 % of the patches
/// continue a neighbour with 16, 5 % with 1.
const OVERLAP_WEIGHT: f64 = 16.0;

/// Relative seeded jitter of the cost (different seeds pick among near-equal matches).
const JITTER: f64 = 0.05;

/// Relative cell-size mismatch under which the exemplar grid counts as at the sketch's scale.
const SCALE_TOLERANCE: f64 = 0.05;

/// Largest band RMS of a self-similar stand-in, as a fraction of the sketch's range. The
/// exemplar's relief growth alone (about 2.2-2.7x on alps_dem and grandcanyon at the default
/// three steps) took the correlation of the output with the sketch to 0.75-0.82.
const MAX_BAND_FRACTION: f64 = 0.1;

/// Largest height gain of a self-similar stand-in.
const MAX_SELF_SIMILAR_GAIN: f64 = 8.0;

/// Settings of [`exemplar_structure`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StructureSettings {
    /// Patch radius `R` in sketch cells: patches are `4R` cells wide, on a `2R` grid, and the
    /// band is what a Gaussian of `R / 2` cells removes. 0 disables the step.
    pub radius: f64,
    /// Seed (choice among near-equal matches).
    pub seed: u64,
}

impl Default for StructureSettings {
    fn default() -> Self {
        Self {
            radius: 4.0,
            seed: 0,
        }
    }
}

impl StructureSettings {
    /// Errs unless the radius is 0 (off) or in `[1, 64]`.
    pub fn check(&self) -> Result<()> {
        let r = self.radius;
        if !(r.is_finite() && (r == 0.0 || (1.0..=64.0).contains(&r))) {
            return Err(LearnError::param(
                "structure radius",
                r,
                "must be 0 (off) or in [1, 64] sketch cells",
            ));
        }
        Ok(())
    }

    /// Patch side (cells).
    fn side(&self) -> usize {
        (4.0 * self.radius).round() as usize
    }
}

/// What [`exemplar_structure`] did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StructureReport {
    /// Patch radius `R` used (sketch cells).
    pub radius: f64,
    /// Size `(width, height)` of the exemplar grid the band was taken from.
    pub exemplar_size: (usize, usize),
    /// Its cell size `(x, y)` in metres.
    pub exemplar_cell_size: (f64, f64),
    /// True when that grid is not at the sketch's cell size (the exemplar is coarser than the
    /// sketch, or too small to be reduced that far): its landforms stand in for the sketch's
    /// scale by self-similarity, with heights scaled to the sketch's range.
    pub self_similar: bool,
    /// Height gain applied to the exemplar's band.
    pub gain: f64,
    /// Number of patches.
    pub patches: usize,
    /// Fraction of patches that continue a neighbour's exemplar region.
    pub continued: f64,
    /// RMS (metres) of the added band.
    pub band_rms: f64,
    /// One line saying what the step did (printed by the CLI).
    pub note: String,
}

/// The exemplar grid at the sketch's cell size, or a self-similar stand-in, with the gain of
/// its heights: `(grid, self_similar)`.
fn exemplar_grid(
    sketch_cell: (f64, f64),
    exemplar: &Heightfield,
    exemplar_cell: (f64, f64),
    side: usize,
) -> Result<(Heightfield, bool)> {
    let min_side = MIN_EXEMPLAR_PATCHES * side;
    let (w, h) = (exemplar.width(), exemplar.height());
    if w.min(h) < min_side {
        return Err(LearnError::param(
            "exemplar size",
            format!("{w}x{h}"),
            "too small for the sketch structure (needs 3 patch sides; lower the structure radius)",
        ));
    }
    let g = grid_at(
        sketch_cell,
        (w, h),
        exemplar_cell,
        min_side as f64,
        SCALE_TOLERANCE,
    );
    let grid = if g.reduced {
        box_resample(exemplar, g.size.0, g.size.1)?
    } else {
        exemplar.clone()
    };
    Ok((grid, g.self_similar))
}

/// Hann window of side `n`: `sin^2(pi (u + 1/2) / n)`; copies shifted by `n / 2` sum to 1.
fn hann(n: usize) -> Vec<f64> {
    (0..n)
        .map(|u| {
            let s = (std::f64::consts::PI * (u as f64 + 0.5) / n as f64).sin();
            s * s
        })
        .collect()
}

/// A grid with its values as `f64` rows, read with clamped coordinates.
struct Grid {
    w: usize,
    h: usize,
    v: Vec<f64>,
}

impl Grid {
    fn of(hf: &Heightfield) -> Self {
        Self {
            w: hf.width(),
            h: hf.height(),
            v: hf.as_slice().iter().map(|&x| x as f64).collect(),
        }
    }

    fn at(&self, x: isize, y: isize) -> f64 {
        let x = x.clamp(0, self.w as isize - 1) as usize;
        let y = y.clamp(0, self.h as isize - 1) as usize;
        self.v[y * self.w + x]
    }

    /// The `n x n` patch at `(x0, y0)` (clamped).
    fn patch(&self, x0: isize, y0: isize, n: usize) -> Vec<f64> {
        let mut out = Vec::with_capacity(n * n);
        for y in 0..n as isize {
            for x in 0..n as isize {
                out.push(self.at(x0 + x, y0 + y));
            }
        }
        out
    }
}

/// Weighted shape + level mismatch of two patches (`w` sums to 1).
fn match_cost(a: &[f64], b: &[f64], w: &[f64]) -> f64 {
    let (mut m, mut q) = (0.0, 0.0);
    for ((x, y), wi) in a.iter().zip(b).zip(w) {
        let d = x - y;
        m += wi * d;
        q += wi * d * d;
    }
    q - (1.0 - LEVEL_WEIGHT) * m * m
}

/// The patch grid over the sketch: `n x n` patches at origins `k * hop - hop` (every cell is
/// under two windows per axis), their Hann windows.
struct Layout {
    n: usize,
    hop: usize,
    gx: usize,
    gy: usize,
    sw: usize,
    sh: usize,
    win1: Vec<f64>,
    win: Vec<f64>,
}

/// A patch's position in the exemplar grid (top-left corner).
type Pos = (usize, usize);

impl Layout {
    fn new(n: usize, sw: usize, sh: usize) -> Self {
        let hop = n / 2;
        let win1 = hann(n);
        let win = win1
            .iter()
            .flat_map(|a| win1.iter().map(move |b| a * b))
            .collect();
        Self {
            n,
            hop,
            gx: sw.div_ceil(hop) + 1,
            gy: sh.div_ceil(hop) + 1,
            sw,
            sh,
            win1,
            win,
        }
    }

    fn count(&self) -> usize {
        self.gx * self.gy
    }

    fn origin(&self, p: usize) -> (isize, isize) {
        let (i, j) = (p % self.gx, p / self.gx);
        let hop = self.hop as isize;
        (i as isize * hop - hop, j as isize * hop - hop)
    }

    /// Match weights of patch `p`: the window over the cells inside the sketch (it has no data
    /// beyond its border), summing to 1.
    fn weights(&self, p: usize) -> Vec<f64> {
        let (ox, oy) = self.origin(p);
        let n = self.n;
        let mut w: Vec<f64> = (0..n * n)
            .map(|k| {
                let (x, y) = (ox + (k % n) as isize, oy + (k / n) as isize);
                let inside =
                    (0..self.sw as isize).contains(&x) && (0..self.sh as isize).contains(&y);
                if inside { self.win[k] } else { 0.0 }
            })
            .collect();
        let t: f64 = w.iter().sum();
        w.iter_mut().for_each(|v| *v /= t.max(f64::MIN_POSITIVE));
        w
    }

    /// The patches chosen before `p` in scan order that overlap it: left, up-left, up,
    /// up-right.
    fn earlier_neighbours(&self, p: usize) -> Vec<usize> {
        let (i, j) = ((p % self.gx) as isize, (p / self.gx) as isize);
        [(-1isize, 0isize), (-1, -1), (0, -1), (1, -1)]
            .iter()
            .filter_map(|&(di, dj)| {
                let (ni, nj) = (i + di, j + dj);
                let inside = ni >= 0 && nj >= 0 && (ni as usize) < self.gx;
                // Not `then_some`: the index of an outside neighbour would overflow.
                if inside {
                    Some(nj as usize * self.gx + ni as usize)
                } else {
                    None
                }
            })
            .collect()
    }
}

/// The exemplar grid split for matching: its smooth part and its band, heights in the
/// sketch's frame.
struct ExemplarBands {
    low: Grid,
    band: Grid,
}

/// Candidate positions of the exemplar grid (strided to the scoring budget) and, per patch,
/// the best [`SHORTLIST`] of them by match cost (ties by index).
fn shortlists(lay: &Layout, s_low: &Grid, e_low: &Grid) -> Vec<Vec<Pos>> {
    let n = lay.n;
    let (cw, ch) = (e_low.w - n + 1, e_low.h - n + 1);
    let most = (SCORE_BUDGET / (lay.count() as f64 * (n * n) as f64))
        .clamp(MIN_CANDIDATES as f64, MAX_CANDIDATES as f64);
    let stride = ((cw * ch) as f64 / most).sqrt().ceil().max(1.0) as usize;
    let cands: Vec<Pos> = (0..ch)
        .step_by(stride)
        .flat_map(|y| (0..cw).step_by(stride).map(move |x| (x, y)))
        .collect();
    let cand_low: Vec<Vec<f64>> = cands
        .par_iter()
        .map(|&(x, y)| e_low.patch(x as isize, y as isize, n))
        .collect();
    (0..lay.count())
        .into_par_iter()
        .map(|p| {
            let (ox, oy) = lay.origin(p);
            let sp = s_low.patch(ox, oy, n);
            let wn = lay.weights(p);
            let mut scored: Vec<(f64, usize)> = cand_low
                .iter()
                .enumerate()
                .map(|(c, cl)| (match_cost(&sp, cl, &wn), c))
                .collect();
            let k = SHORTLIST.min(scored.len());
            scored.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            scored.truncate(k);
            scored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            scored.into_iter().map(|(_, c)| cands[c]).collect()
        })
        .collect()
}

/// Chooses every patch's exemplar position in scan order among its shortlist and the
/// positions continuing its earlier neighbours, by match cost plus the overlap term (seeded
/// jitter); returns the positions and how many continue a neighbour.
fn choose(
    lay: &Layout,
    s_low: &Grid,
    ex: &ExemplarBands,
    shortlists: &[Vec<Pos>],
    seed: u64,
) -> Result<(Vec<Pos>, usize)> {
    let n = lay.n;
    let (cw, ch) = (ex.low.w - n + 1, ex.low.h - n + 1);
    let mut chosen: Vec<Pos> = Vec::with_capacity(lay.count());
    let mut continued = 0usize;
    for (p, shortlist) in shortlists.iter().enumerate() {
        let o = lay.origin(p);
        let sp = s_low.patch(o.0, o.1, n);
        let wn = lay.weights(p);
        let neighbours = lay.earlier_neighbours(p);
        let mut options: Vec<(Pos, bool)> = shortlist.iter().map(|&c| (c, false)).collect();
        for &q in &neighbours {
            let (qo, (cx, cy)) = (lay.origin(q), chosen[q]);
            let (x, y) = (cx as isize + o.0 - qo.0, cy as isize + o.1 - qo.1);
            if x >= 0 && y >= 0 && (x as usize) < cw && (y as usize) < ch {
                let c = (x as usize, y as usize);
                match options.iter_mut().find(|opt| opt.0 == c) {
                    Some(opt) => opt.1 = true,
                    None => options.push((c, true)),
                }
            }
        }
        let mut best: Option<(f64, Pos, bool)> = None;
        for (k, &(c, cont)) in options.iter().enumerate() {
            let cl = ex.low.patch(c.0 as isize, c.1 as isize, n);
            let ov: f64 = neighbours
                .iter()
                .map(|&q| {
                    let nb = (chosen[q], lay.origin(q));
                    overlap_mismatch(&ex.band, (c, o), nb, (n, lay.sw, lay.sh), &lay.win1)
                })
                .sum();
            let u = item_seed(seed, 0x57c0 ^ p as u64, k as u64) as f64 / u64::MAX as f64;
            let cost = (match_cost(&sp, &cl, &wn) + OVERLAP_WEIGHT * ov) * (1.0 + JITTER * u);
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, c, cont));
            }
        }
        let (_, c, cont) = best.ok_or(LearnError::param(
            "exemplar",
            "no patch",
            "no candidate position",
        ))?;
        continued += usize::from(cont);
        chosen.push(c);
    }
    Ok((chosen, continued))
}

/// The sketch plus the Hann-weighted bands of the chosen positions, and the bands' RMS.
fn blend(lay: &Layout, sketch: &Heightfield, band: &Grid, chosen: &[Pos]) -> (Vec<f32>, f64) {
    let (n, sw, sh) = (lay.n, lay.sw, lay.sh);
    let mut acc = vec![0.0f64; sw * sh];
    let mut wacc = vec![0.0f64; sw * sh];
    for (p, &(cx, cy)) in chosen.iter().enumerate() {
        let (ox, oy) = lay.origin(p);
        for v in 0..n {
            let y = oy + v as isize;
            if y < 0 || y >= sh as isize {
                continue;
            }
            for u in 0..n {
                let x = ox + u as isize;
                if x < 0 || x >= sw as isize {
                    continue;
                }
                let wv = lay.win[v * n + u];
                let idx = y as usize * sw + x as usize;
                acc[idx] += wv * band.v[(cy + v) * band.w + cx + u];
                wacc[idx] += wv;
            }
        }
    }
    let mut e2 = 0.0;
    let out: Vec<f32> = sketch
        .as_slice()
        .iter()
        .zip(acc.iter().zip(&wacc))
        .map(|(&s, (a, w))| {
            let b = if *w > 1e-12 { a / w } else { 0.0 };
            e2 += b * b;
            (s as f64 + b) as f32
        })
        .collect();
    (out, (e2 / (sw * sh) as f64).sqrt())
}

/// Height gain of the exemplar grid `e0` (cells `e0_cell`, band RMS `band_rms` metres)
/// standing in for the sketch's cells: 1 at the sketch's scale. For a self-similar stand-in
/// finer than the sketch by `r`: the exemplar's own relief growth over `log4 r` octaves
/// ([`octave_ratio`] per x4) times the sketch's range over the grid's, at most what brings the
/// band's RMS to [`MAX_BAND_FRACTION`] of the sketch's range (the painted shape stays the
/// larger part).
fn band_gain(
    e0: &Heightfield,
    (e0_cell, band_rms): ((f64, f64), f64),
    sketch_cell: (f64, f64),
    range: (f32, f32),
    self_similar: bool,
) -> f64 {
    if !self_similar {
        return 1.0;
    }
    let (emin, emax) = e0.min_max().unwrap_or((0.0, 0.0));
    let span = (emax - emin).max(f32::MIN_POSITIVE) as f64;
    let r = ((sketch_cell.0 / e0_cell.0) * (sketch_cell.1 / e0_cell.1)).sqrt();
    let octaves = r.ln() / (STEP_FACTOR as f64).ln();
    let growth = octave_ratio(e0).powf(octaves);
    let sketch_relief = (range.1 - range.0) as f64;
    let cap = MAX_BAND_FRACTION * sketch_relief / band_rms.max(f64::MIN_POSITIVE);
    (growth * sketch_relief / span)
        .min(cap)
        .min(MAX_SELF_SIMILAR_GAIN)
}

/// Adds to a sketch (heights in metres, its cell size set) the exemplar's landforms between
/// its cell and its strokes (see the module documentation). `range` is the elevation range the
/// sketch was mapped to; a self-similar exemplar's band is scaled by that range over its own.
/// `exemplar_cell` is the exemplar's cell size in metres (its grid's, or a user's). The bands
/// can take valleys below the range and peaks above it, as the x4 steps' detail does.
pub fn exemplar_structure(
    sketch: &Heightfield,
    exemplar: &Heightfield,
    exemplar_cell: (f64, f64),
    range: (f32, f32),
    settings: &StructureSettings,
) -> Result<(Heightfield, StructureReport)> {
    settings.check()?;
    sketch.require_complete()?;
    exemplar.require_complete()?;
    let n = settings.side();
    let sigma = (settings.radius / 2.0) as f32;
    let (e0, self_similar) = exemplar_grid(sketch.cell_size(), exemplar, exemplar_cell, n)?;
    let e0_cell = (
        exemplar_cell.0 * exemplar.width() as f64 / e0.width() as f64,
        exemplar_cell.1 * exemplar.height() as f64 / e0.height() as f64,
    );
    // The band (what a Gaussian of R / 2 cells removes), then the gain; the mapping to the
    // sketch's frame is affine, so it commutes with the blur.
    let raw = Grid::of(&e0);
    let raw_low = Grid::of(&e0.gaussian_blur(sigma)?);
    let raw_band: Vec<f64> = raw.v.iter().zip(&raw_low.v).map(|(a, b)| a - b).collect();
    let raw_rms = (raw_band.iter().map(|v| v * v).sum::<f64>() / raw_band.len() as f64).sqrt();
    let gain = band_gain(
        &e0,
        (e0_cell, raw_rms),
        sketch.cell_size(),
        range,
        self_similar,
    );
    // Exemplar heights in the sketch's frame: lo + (e - emin) * gain.
    let emin = e0.min_max().map_or(0.0, |m| m.0) as f64;
    let low = Grid {
        w: raw.w,
        h: raw.h,
        v: raw_low
            .v
            .iter()
            .map(|v| range.0 as f64 + (v - emin) * gain)
            .collect(),
    };
    let band = Grid {
        w: raw.w,
        h: raw.h,
        v: raw_band.iter().map(|v| v * gain).collect(),
    };
    let ex = ExemplarBands { low, band };
    let s_low = Grid::of(&sketch.gaussian_blur(sigma)?);
    let lay = Layout::new(n, sketch.width(), sketch.height());
    let lists = shortlists(&lay, &s_low, &ex.low);
    let (chosen, continued) = choose(&lay, &s_low, &ex, &lists, settings.seed)?;
    let (out, band_rms) = blend(&lay, sketch, &ex.band, &chosen);
    let patches = chosen.len();
    let continued = continued as f64 / patches.max(1) as f64;
    let (ecx, ecy) = e0_cell;
    let note = format!(
        "sketch structure (R = {}): {patches} patches of {n} x {n} cells from the exemplar at {ecx:.1} \
         x {ecy:.1} m ({} x {}){}; {:.0} % continue a neighbour; band RMS {band_rms:.1} m",
        settings.radius,
        e0.width(),
        e0.height(),
        if self_similar {
            format!(
                ", standing in for the sketch's {:.1} x {:.1} m cells by self-similarity \
                 (heights x{gain:.3})",
                sketch.cell_size().0,
                sketch.cell_size().1
            )
        } else {
            String::new()
        },
        100.0 * continued
    );
    Ok((
        sketch.with_data(out)?,
        StructureReport {
            radius: settings.radius,
            exemplar_size: (e0.width(), e0.height()),
            exemplar_cell_size: e0_cell,
            self_similar,
            gain,
            patches,
            continued,
            band_rms,
            note,
        },
    ))
}

/// Mean squared difference, weighted by the smaller of the two Hann weights, of the band a
/// patch at sketch origin `o` would take from exemplar position `c` and the band a chosen
/// neighbour (exemplar position `nc`, sketch origin `no`) takes, over their overlap inside
/// the `sw x sh` sketch (patch side `n`).
fn overlap_mismatch(
    band: &Grid,
    (c, o): (Pos, (isize, isize)),
    (nc, no): (Pos, (isize, isize)),
    (n, sw, sh): (usize, usize, usize),
    win1: &[f64],
) -> f64 {
    let (x0, x1) = (
        o.0.max(no.0).max(0),
        (o.0 + n as isize).min(no.0 + n as isize).min(sw as isize),
    );
    let (y0, y1) = (
        o.1.max(no.1).max(0),
        (o.1 + n as isize).min(no.1 + n as isize).min(sh as isize),
    );
    let (mut s, mut ws) = (0.0, 0.0);
    for y in y0..y1 {
        let (v, nv) = ((y - o.1) as usize, (y - no.1) as usize);
        for x in x0..x1 {
            let (u, nu) = ((x - o.0) as usize, (x - no.0) as usize);
            let w = (win1[u] * win1[v]).min(win1[nu] * win1[nv]);
            let a = band.v[(c.1 + v) * band.w + c.0 + u];
            let b = band.v[(nc.1 + nv) * band.w + nc.0 + nu];
            s += w * (a - b) * (a - b);
            ws += w;
        }
    }
    if ws > 0.0 { s / ws } else { 0.0 }
}
