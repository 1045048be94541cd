//! Detail statistics and the power-law fit of section 5: equations (2)-(4).

use rayon::prelude::*;
use relief_heightfield::param::ensure;
use relief_heightfield::{Heightfield, check_field};
use serde::{Deserialize, Serialize};

use crate::dwt::{Band, Decomposition, Grid, max_levels, wavedec2};
use crate::error::{Result, WaveletError};
use crate::lift::Boundary;
use crate::wavelet::Wavelet;

/// Largest accepted [`FitSettings::variance_floor`] (m^2).
const MAX_VARIANCE_FLOOR: f64 = 1e12;
/// Smallest accepted [`FitSettings::gamma_min`].
const GAMMA_MIN_LOWEST: f64 = -2.0;
/// Largest accepted [`FitSettings::gamma_max`].
const GAMMA_MAX_HIGHEST: f64 = 16.0;
/// Largest accepted input elevation magnitude (m): squares of detail coefficients summed over
/// the largest LSA window stay far below the `f32` range.
pub(crate) const MAX_ELEVATION: f32 = 1e12;

/// Settings of the variance fit (equations (3) and (4)).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FitSettings {
    /// First level index `j` taking part in the fit (the paper rejects the coarse levels and
    /// fits "from level 3 and up"). Level `j` of an input whose larger side is `N` has about
    /// `2^j` coefficients along that side: `j = ceil(log2 N) - depth`.
    pub min_level: u32,
    /// Number of analysed (decomposed) levels; 0 means "down to `min_level`", i.e.
    /// `ceil(log2 N) - min_level`.
    pub levels: usize,
    /// Variances below this floor (m^2) are raised to it before the logarithm, so flat areas
    /// (zero variance, e.g. sea at 0 m) give finite fits: `gamma = 0` and variance = floor.
    /// Must be in `(0, 1e12]`.
    pub variance_floor: f64,
    /// Smallest `gamma` used for synthesis; a fit below it is clamped and `a` refitted with the
    /// slope fixed. 0 forbids variance growing towards finer levels. Must be in `[-2, 16]`.
    pub gamma_min: f64,
    /// Largest `gamma` used for synthesis (clamped likewise). Must be in `[gamma_min, 16]`.
    pub gamma_max: f64,
}

impl Default for FitSettings {
    fn default() -> Self {
        Self {
            min_level: 3,
            levels: 0,
            variance_floor: 1e-8,
            gamma_min: 0.0,
            gamma_max: 8.0,
        }
    }
}

impl FitSettings {
    /// Checks the settings.
    pub fn check(&self) -> Result<()> {
        let floor = self.variance_floor;
        let ok = floor > 0.0 && floor <= MAX_VARIANCE_FLOOR;
        ensure(ok, "variance_floor", floor, "must be in (0, 1e12] m^2")?;
        // Bounded so that the variances of equation (5) stay finite in f32 for every level the
        // refinement can add (12 levels of growth at gamma = -2 multiply a variance by 2^24).
        let gammas = GAMMA_MIN_LOWEST..=GAMMA_MAX_HIGHEST;
        check_field!(self, gamma_min, gammas, "must be in [-2, 16]")?;
        let gammas = self.gamma_min..=GAMMA_MAX_HIGHEST;
        check_field!(self, gamma_max, gammas, "must be in [gamma_min, 16]")?;
        check_field!(self, min_level, ..=40, "must be <= 40")?;
        Ok(())
    }

    /// `(J, analysed levels, levels used by the fit)` for an input size.
    pub(crate) fn plan(&self, width: usize, height: usize) -> Result<(i64, usize, usize)> {
        self.check()?;
        let top = max_levels(width, height);
        let auto = top.saturating_sub(self.min_level as usize);
        let levels = if self.levels == 0 {
            auto
        } else {
            self.levels.min(top)
        };
        let used = levels.min(auto);
        if used < 2 {
            return Err(WaveletError::TooFewLevels {
                min_level: self.min_level,
                available: used,
                levels,
                width,
                height,
            });
        }
        Ok((top as i64, levels, used))
    }
}

/// The fitted line `log2 Var = -j gamma + a` of one band (equation (3)).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BandFit {
    /// Decay exponent `gamma` used for synthesis (after clamping).
    pub gamma: f64,
    /// Intercept `a` (log2 of m^2).
    pub a: f64,
    /// Slope of the unconstrained least-squares fit, negated.
    pub gamma_fit: f64,
    /// Coefficient of determination of the unconstrained fit (1 = the variances lie on a line).
    pub r_squared: f64,
    /// Whether `gamma` was clamped into `[gamma_min, gamma_max]`.
    pub clamped: bool,
    /// Number of levels in the fit.
    pub levels_used: usize,
    /// Implied fractal dimension `3 - gamma / 2` (a copy of
    /// [`BandFit::fractal_dimension`] for serialised reports).
    pub fractal_dimension: f64,
}

impl BandFit {
    /// Hurst exponent `H = gamma / 2` implied by the fit. With the metric normalisation the
    /// detail coefficients at depth `k` are elevation increments over `2^k` cells, whose
    /// variance for a fractional Brownian surface grows as `(2^k)^(2H)` (section 4,
    /// `Var(V_H) ~ dr^(2H)`), hence `gamma = 2H`.
    pub fn hurst(&self) -> f64 {
        self.gamma / 2.0
    }

    /// Fractal dimension of the surface implied by the fit, `D = 3 - H = 3 - gamma / 2`.
    /// Meaningful for `0 < gamma < 2` (fBm-like terrain); outside, the terrain is not
    /// self-similar over the fitted levels and the value is only a roughness index.
    pub fn fractal_dimension(&self) -> f64 {
        3.0 - self.gamma / 2.0
    }

    /// Variance the fit predicts at level `j` (equation (5) for a new level `n = j`).
    pub fn variance_at(&self, j: f64) -> f64 {
        (self.a - j * self.gamma).exp2()
    }
}

/// Mean squares of the detail coefficients of one level (equation (2) with the zero-mean
/// assumption of the paper: `sigma^2 = E[d^2]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LevelVariance {
    /// Level index `j` (larger = finer).
    pub level: i64,
    /// Decomposition depth (1 = finest).
    pub depth: usize,
    /// Mean square per band, in [`Band::ALL`] order (m^2).
    pub variance: [f64; 3],
    /// Number of coefficients per band.
    pub count: [usize; 3],
    /// Whether this level takes part in the fit.
    pub fitted: bool,
}

/// The global statistics of a terrain (GSA, section 5.1): variances per band and level and the
/// fitted lines.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GlobalAnalysis {
    /// Basis of the analysis.
    pub wavelet: Wavelet,
    /// Input width.
    pub width: usize,
    /// Input height.
    pub height: usize,
    /// `J = ceil(log2(max(width, height)))`: the input itself is level `J`, its finest details
    /// are level `J - 1`, and the first synthesised level is `J`.
    pub top_level: i64,
    /// Per-level variances, coarsest first.
    pub levels: Vec<LevelVariance>,
    /// Fits per band in [`Band::ALL`] order.
    pub fits: [BandFit; 3],
    /// The fit settings used.
    pub settings: FitSettings,
}

impl GlobalAnalysis {
    /// The fit of a band.
    pub fn fit(&self, band: Band) -> &BandFit {
        &self.fits[band.index()]
    }

    /// Mean fractal dimension over the three bands.
    pub fn fractal_dimension(&self) -> f64 {
        self.fits.iter().map(|f| f.fractal_dimension()).sum::<f64>() / 3.0
    }
}

fn mean_square(g: &Grid) -> f64 {
    if g.is_empty() {
        return 0.0;
    }
    g.data
        .par_chunks(1 << 14)
        .map(|c| c.iter().map(|&v| (v as f64) * (v as f64)).sum::<f64>())
        .collect::<Vec<_>>()
        .iter()
        .sum::<f64>()
        / g.len() as f64
}

/// Least-squares line through `(j, y)`: returns `(gamma_fit, a_fit, r2)` of
/// `y = -gamma j + a`.
pub(crate) fn line_fit(js: &[f64], ys: &[f64]) -> (f64, f64, f64) {
    let n = js.len() as f64;
    let mj = js.iter().sum::<f64>() / n;
    let my = ys.iter().sum::<f64>() / n;
    let sxx: f64 = js.iter().map(|j| (j - mj) * (j - mj)).sum();
    let sxy: f64 = js.iter().zip(ys).map(|(j, y)| (j - mj) * (y - my)).sum();
    let syy: f64 = ys.iter().map(|y| (y - my) * (y - my)).sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let r2 = if syy > 0.0 && sxx > 0.0 {
        (sxy * sxy / (sxx * syy)).min(1.0)
    } else {
        1.0
    };
    (-slope, my - slope * mj, r2)
}

/// Applies the clamp of [`FitSettings`]: returns `(gamma, a, clamped)`.
#[inline]
pub(crate) fn clamp_fit(gamma: f64, a: f64, mj: f64, my: f64, s: &FitSettings) -> (f64, f64, bool) {
    if gamma < s.gamma_min || gamma > s.gamma_max {
        let g = gamma.clamp(s.gamma_min, s.gamma_max);
        (g, my + g * mj, true)
    } else {
        (gamma, a, false)
    }
}

pub(crate) fn decompose(
    hf: &Heightfield,
    wavelet: Wavelet,
    levels: usize,
) -> Result<Decomposition> {
    hf.require_complete()?;
    let max = hf.as_slice().iter().fold(0.0f32, |m, v| m.max(v.abs()));
    if max > MAX_ELEVATION {
        return Err(WaveletError::param(
            "input",
            format!("max |elevation| {max:e} m"),
            "elevations must be within +-1e12 m",
        ));
    }
    wavedec2(
        &Grid::from_heightfield(hf),
        wavelet,
        levels,
        Boundary::Symmetric,
    )
}

pub(crate) fn global_from(
    dec: &Decomposition,
    top: i64,
    settings: &FitSettings,
) -> Result<GlobalAnalysis> {
    let levels = dec.levels();
    let mut out = Vec::with_capacity(levels);
    for (i, lvl) in dec.details.iter().enumerate() {
        let depth = levels - i;
        let j = top - depth as i64;
        let mut variance = [0.0; 3];
        let mut count = [0; 3];
        for b in Band::ALL {
            let g = lvl.band(b);
            variance[b.index()] = mean_square(g);
            count[b.index()] = g.len();
        }
        out.push(LevelVariance {
            level: j,
            depth,
            variance,
            count,
            fitted: j >= settings.min_level as i64 && count.iter().all(|&c| c > 0),
        });
    }
    let used: Vec<&LevelVariance> = out.iter().filter(|l| l.fitted).collect();
    require_fit_levels(used.len(), dec, settings)?;
    let fits = fit_levels(&used, settings);
    Ok(GlobalAnalysis {
        wavelet: dec.wavelet,
        width: dec.width,
        height: dec.height,
        top_level: top,
        levels: out,
        fits,
        settings: settings.clone(),
    })
}

/// The fit of equation (3) needs at least 2 of the levels of `dec` (`available` take part).
fn require_fit_levels(available: usize, dec: &Decomposition, settings: &FitSettings) -> Result<()> {
    if available < 2 {
        return Err(WaveletError::TooFewLevels {
            min_level: settings.min_level,
            available,
            levels: dec.levels(),
            width: dec.width,
            height: dec.height,
        });
    }
    Ok(())
}

/// Equation (3) per band through the given levels (at least 2), clamped.
fn fit_levels(used: &[&LevelVariance], settings: &FitSettings) -> [BandFit; 3] {
    Band::ALL.map(|b| {
        let js: Vec<f64> = used.iter().map(|l| l.level as f64).collect();
        let ys: Vec<f64> = used
            .iter()
            .map(|l| l.variance[b.index()].max(settings.variance_floor).log2())
            .collect();
        let (g, a, r2) = line_fit(&js, &ys);
        let mj = js.iter().sum::<f64>() / js.len() as f64;
        let my = ys.iter().sum::<f64>() / ys.len() as f64;
        let (gamma, a, clamped) = clamp_fit(g, a, mj, my, settings);
        BandFit {
            gamma,
            a,
            gamma_fit: g,
            r_squared: r2,
            clamped,
            levels_used: js.len(),
            fractal_dimension: 3.0 - gamma / 2.0,
        }
    })
}

/// Decay assumed when an input has fewer than two detail levels: `gamma = 2` (a surface that
/// is smooth at the finest scale, the typical finest-level decay of DEMs), through the finest
/// level's variance when there is one.
const DEFAULT_GAMMA: f64 = 2.0;

fn default_fits(levels: &[LevelVariance], top: i64, settings: &FitSettings) -> [BandFit; 3] {
    let finest = levels.iter().rev().find(|l| l.count.iter().all(|&c| c > 0));
    let gamma = DEFAULT_GAMMA.clamp(settings.gamma_min, settings.gamma_max);
    Band::ALL.map(|b| {
        let (j, var) = finest.map_or((top as f64 - 1.0, 0.0), |l| {
            (l.level as f64, l.variance[b.index()])
        });
        BandFit {
            gamma,
            a: var.max(settings.variance_floor).log2() + j * gamma,
            gamma_fit: gamma,
            r_squared: 0.0,
            clamped: false,
            levels_used: usize::from(finest.is_some()),
            fractal_dimension: 3.0 - gamma / 2.0,
        }
    })
}

/// [`global_from`] that never fails for lack of levels: below two levels `>= min_level` it fits
/// every level of the input, below two levels at all it uses [`DEFAULT_GAMMA`]; each fallback
/// adds a note.
pub(crate) fn global_lenient(
    dec: &Decomposition,
    top: i64,
    settings: &FitSettings,
    notes: &mut Vec<String>,
) -> GlobalAnalysis {
    if let Ok(g) = global_from(dec, top, settings) {
        return g;
    }
    let all = FitSettings {
        min_level: 0,
        ..settings.clone()
    };
    if let Ok(mut g) = global_from(dec, top, &all) {
        notes.push(format!(
            "fewer than 2 detail levels >= {} in the {} x {} input: the fit uses all {} levels",
            settings.min_level,
            dec.width,
            dec.height,
            g.levels.len()
        ));
        g.settings = settings.clone();
        return g;
    }
    // Level variances without a fit: the same loop as global_from, nothing fitted.
    let nl = dec.levels();
    let levels: Vec<LevelVariance> = dec
        .details
        .iter()
        .enumerate()
        .map(|(i, lvl)| {
            let depth = nl - i;
            LevelVariance {
                level: top - depth as i64,
                depth,
                variance: Band::ALL.map(|b| mean_square(lvl.band(b))),
                count: Band::ALL.map(|b| lvl.band(b).len()),
                fitted: false,
            }
        })
        .collect();
    notes.push(format!(
        "the {} x {} input has fewer than 2 detail levels: default decay gamma = {DEFAULT_GAMMA} \
         through the finest level",
        dec.width, dec.height
    ));
    GlobalAnalysis {
        wavelet: dec.wavelet,
        width: dec.width,
        height: dec.height,
        top_level: top,
        fits: default_fits(&levels, top, settings),
        levels,
        settings: settings.clone(),
    }
}

/// The spectral model's fit: equation (3) through the finest `count` levels that have
/// coefficients in every band (fewer, with a note, when the input has fewer; the global fit when
/// fewer than 2).
pub(crate) fn fine_fit(
    global: &GlobalAnalysis,
    count: usize,
    settings: &FitSettings,
    notes: &mut Vec<String>,
) -> [BandFit; 3] {
    let usable: Vec<&LevelVariance> = global
        .levels
        .iter()
        .filter(|l| l.count.iter().all(|&c| c > 0))
        .collect();
    let used = &usable[usable.len().saturating_sub(count)..];
    if used.len() < 2 {
        notes.push(format!(
            "spectral fit: fewer than 2 detail levels in the {} x {} input; the global fit is used",
            global.width, global.height
        ));
        return global.fits;
    }
    if used.len() < count {
        notes.push(format!(
            "spectral fit: {} finest levels asked, the {} x {} input has {}",
            count,
            global.width,
            global.height,
            used.len()
        ));
    }
    fit_levels(used, settings)
}

/// Global analysis (GSA statistics) of a void-free terrain: equations (2) and (3).
pub fn analyze(
    hf: &Heightfield,
    wavelet: Wavelet,
    settings: &FitSettings,
) -> Result<GlobalAnalysis> {
    let (top, levels, _) = settings.plan(hf.width(), hf.height())?;
    let dec = decompose(hf, wavelet, levels)?;
    global_from(&dec, top, settings)
}

/// Checks an LSA window size.
pub(crate) fn check_window(window: usize) -> Result<()> {
    if window.is_multiple_of(2) || window == 0 || window > 31 {
        return Err(WaveletError::param(
            "window",
            window,
            "must be odd in 1..=31 (the paper uses 1, 3, 5, 7)",
        ));
    }
    Ok(())
}

/// Start of the `w`-wide window around `i` on an axis of length `n`, shifted inwards at the edges
/// so that it always holds `min(w, n)` samples.
#[inline]
fn window_start(i: usize, n: usize, w: usize) -> usize {
    i.saturating_sub(w / 2).min(n - w.min(n))
}

/// `log2` of the floored mean square over the `w x w` window around each coefficient
/// (equation (4)'s local variance), at the band's resolution.
pub(crate) fn windowed_log_variance(g: &Grid, w: usize, floor: f64) -> Grid {
    if g.is_empty() {
        return g.clone();
    }
    let (gw, gh) = (g.width, g.height);
    let (wx, wy) = (w.min(gw), w.min(gh));
    // Horizontal sums of squares.
    let mut rows = vec![0.0f32; gw * gh];
    rows.par_chunks_mut(gw)
        .zip(g.data.par_chunks(gw))
        .for_each(|(o, s)| {
            for (i, v) in o.iter_mut().enumerate() {
                let st = window_start(i, gw, w);
                *v = s[st..st + wx].iter().map(|x| x * x).sum();
            }
        });
    // Vertical sums, then the floored log2 mean.
    let inv = 1.0 / (wx * wy) as f32;
    // A floor under the smallest normal f32 (e.g. 1e-300) would round to 0 and give -inf.
    let floor = (floor as f32).max(f32::MIN_POSITIVE);
    let mut data = vec![0.0f32; gw * gh];
    data.par_chunks_mut(gw).enumerate().for_each(|(y, o)| {
        let st = window_start(y, gh, w);
        o.copy_from_slice(&rows[st * gw..(st + 1) * gw]);
        for r in st + 1..st + wy {
            o.iter_mut()
                .zip(&rows[r * gw..(r + 1) * gw])
                .for_each(|(a, b)| *a += b);
        }
        o.iter_mut().for_each(|v| *v = (*v * inv).max(floor).log2());
    });
    Grid {
        width: gw,
        height: gh,
        data,
    }
}

/// Per-level windowed log-variance grids for the local fit (LSA, section 5.2).
#[derive(Debug, Clone)]
pub(crate) struct LocalStats {
    pub(crate) window: usize,
    /// `(j, depth, [H, V, D] log2 variance grids)` for the fitted levels, coarsest first.
    pub(crate) levels: Vec<(i64, usize, [Grid; 3])>,
    /// Least-squares weights: `slope = sum_k c_k y_k`.
    pub(crate) weights: Vec<f64>,
    pub(crate) mean_j: f64,
    pub(crate) settings: FitSettings,
}

impl LocalStats {
    pub(crate) fn new(
        dec: &Decomposition,
        top: i64,
        window: usize,
        settings: &FitSettings,
    ) -> Result<Self> {
        check_window(window)?;
        let levels = dec.levels();
        let mut out = Vec::new();
        for (i, lvl) in dec.details.iter().enumerate() {
            let depth = levels - i;
            let j = top - depth as i64;
            if j < settings.min_level as i64 || lvl.d.is_empty() {
                continue;
            }
            let grids = [
                windowed_log_variance(&lvl.h, window, settings.variance_floor),
                windowed_log_variance(&lvl.v, window, settings.variance_floor),
                windowed_log_variance(&lvl.d, window, settings.variance_floor),
            ];
            out.push((j, depth, grids));
        }
        require_fit_levels(out.len(), dec, settings)?;
        let js: Vec<f64> = out.iter().map(|l| l.0 as f64).collect();
        let mean_j = js.iter().sum::<f64>() / js.len() as f64;
        let sxx: f64 = js.iter().map(|j| (j - mean_j).powi(2)).sum();
        let weights = js.iter().map(|j| (j - mean_j) / sxx).collect();
        Ok(Self {
            window,
            levels: out,
            weights,
            mean_j,
            settings: settings.clone(),
        })
    }

    /// `(gamma, a)` per band ([`Band::ALL`] order) for the input locations
    /// `[x0, x0 + w) x [y0, y0 + h)` (equation (4)), clamped like the global fit. The
    /// least-squares sums are accumulated down a pyramid (a coefficient at depth `k` serves
    /// `2^k x 2^k` locations), in the same order for every location whatever the region, so the
    /// values do not depend on how the terrain is tiled.
    pub(crate) fn fit_region(
        &self,
        x0: usize,
        y0: usize,
        w: usize,
        h: usize,
    ) -> [(Vec<f32>, Vec<f32>); 3] {
        let nl = self.levels.len() as f64;
        Band::ALL.map(|band| {
            let b = band.index();
            let (mut acc_s, mut acc_m) = (Vec::<f64>::new(), Vec::<f64>::new());
            let (mut prx0, mut pry0, mut pw) = (0usize, 0usize, 0usize);
            for (li, ((_, depth, grids), c)) in self.levels.iter().zip(&self.weights).enumerate() {
                let g = &grids[b];
                let (rx0, rx1) = (x0 >> depth, (x0 + w - 1) >> depth);
                let (ry0, ry1) = (y0 >> depth, (y0 + h - 1) >> depth);
                let (rw, rh) = (rx1 - rx0 + 1, ry1 - ry0 + 1);
                let mut ns = vec![0.0f64; rw * rh];
                let mut nm = vec![0.0f64; rw * rh];
                for yy in 0..rh {
                    let gy = (ry0 + yy).min(g.height - 1);
                    let grow = &g.data[gy * g.width..(gy + 1) * g.width];
                    for xx in 0..rw {
                        let v = grow[(rx0 + xx).min(g.width - 1)] as f64;
                        let (ps, pm) = if li == 0 {
                            (0.0, 0.0)
                        } else {
                            let k = (((ry0 + yy) >> 1) - pry0) * pw + ((rx0 + xx) >> 1) - prx0;
                            (acc_s[k], acc_m[k])
                        };
                        ns[yy * rw + xx] = ps + c * v;
                        nm[yy * rw + xx] = pm + v;
                    }
                }
                (acc_s, acc_m, prx0, pry0, pw) = (ns, nm, rx0, ry0, rw);
            }
            // The finest fitted level is depth 1: location (x, y) reads (x >> 1, y >> 1).
            let mut gam = vec![0.0f32; w * h];
            let mut aa = vec![0.0f32; w * h];
            for y in 0..h {
                for x in 0..w {
                    let k = (((y0 + y) >> 1) - pry0) * pw + ((x0 + x) >> 1) - prx0;
                    let slope = acc_s[k];
                    let my = acc_m[k] / nl;
                    let (g, a, _) = clamp_fit(
                        -slope,
                        my - slope * self.mean_j,
                        self.mean_j,
                        my,
                        &self.settings,
                    );
                    gam[y * w + x] = g as f32;
                    aa[y * w + x] = a as f32;
                }
            }
            (gam, aa)
        })
    }
}

/// Local statistics as maps at the input resolution (LSA, equation (4)): one `(gamma, a)` per
/// band and location, from the detail coefficients in a `window x window` neighbourhood at every
/// fitted level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocalMaps {
    /// Window size used.
    pub window: usize,
    /// `gamma` per band ([`Band::ALL`] order), at input resolution.
    pub gamma: [Grid; 3],
    /// `a` per band, at input resolution.
    pub a: [Grid; 3],
}

impl LocalMaps {
    /// Map of the implied fractal dimension `3 - gamma / 2` of a band.
    pub fn fractal_dimension(&self, band: Band) -> Grid {
        let g = &self.gamma[band.index()];
        Grid {
            width: g.width,
            height: g.height,
            data: g.data.iter().map(|v| 3.0 - v / 2.0).collect(),
        }
    }
}

pub(crate) fn maps_from(local: &LocalStats, width: usize, height: usize) -> LocalMaps {
    const STRIP: usize = 64;
    let strips: Vec<[(Vec<f32>, Vec<f32>); 3]> = (0..height.div_ceil(STRIP))
        .into_par_iter()
        .map(|s| {
            let y0 = s * STRIP;
            local.fit_region(0, y0, width, STRIP.min(height - y0))
        })
        .collect();
    let join = |b: usize, gamma: bool| Grid {
        width,
        height,
        data: strips
            .iter()
            .flat_map(|s| if gamma { s[b].0.iter() } else { s[b].1.iter() })
            .copied()
            .collect(),
    };
    LocalMaps {
        window: local.window,
        gamma: [join(0, true), join(1, true), join(2, true)],
        a: [join(0, false), join(1, false), join(2, false)],
    }
}

/// Local analysis (LSA statistics) of a void-free terrain as maps: equation (4).
pub fn analyze_local(
    hf: &Heightfield,
    wavelet: Wavelet,
    window: usize,
    settings: &FitSettings,
) -> Result<LocalMaps> {
    check_window(window)?;
    let (top, levels, _) = settings.plan(hf.width(), hf.height())?;
    let dec = decompose(hf, wavelet, levels)?;
    let local = LocalStats::new(&dec, top, window, settings)?;
    Ok(maps_from(&local, hf.width(), hf.height()))
}
