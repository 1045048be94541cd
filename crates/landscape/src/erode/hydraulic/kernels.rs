//! The per-cell kernels of the hydraulic model: fluxes (Mei et al. eq. 2-5), depth, velocity,
//! erosion and deposition (eq. 6-12), the semi-Lagrangian transport (eq. 14), each as the
//! general per-cell code (edges and voids) and the branch-free runs of interior cells that
//! LLVM vectorises, with the arithmetic in the same order so both give the same bits.

#![allow(clippy::too_many_arguments)]

use super::*;

/// The new outflow fluxes of cell `i` at `(x, y)` from its fluxes `f` (Mei et al. eq. 2-5).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn flux_cell(
    c: &Consts,
    b: &[f32],
    d: &[f32],
    m: u8,
    x: usize,
    y: usize,
    i: usize,
    f: [f32; 4],
) -> [f32; 4] {
    if m & VALID == 0 {
        return [0.0; 4];
    }
    let nb = c.neighbours(x, y, i);
    let (di, hi) = (d[i], b[i] + d[i]);
    // Water surfaces of the neighbours (garbage where `m` says a side is open).
    let h = nb.map(|n| b[n] + d[n]);
    let mut new = [0.0f32; 4];
    let mut sum = 0.0f32;
    for k in 0..4 {
        // An open side drains into a dry virtual cell continuing the opposite side's slope.
        let dh = if ok(m, k) {
            hi - h[k]
        } else if ok(m, OPP[k]) {
            di + (h[OPP[k]] - hi).max(0.0)
        } else {
            di
        };
        new[k] = (f[k] + c.kflux[k] * dh).max(0.0);
        sum += new[k];
    }
    // Eq. 4: never drain more than the cell holds.
    let volume = di * c.area;
    if sum * c.dt > volume {
        let scale = volume / (sum * c.dt);
        new.map(|v| v * scale)
    } else {
        new
    }
}

/// [`flux_cell`] on the [`FULL`] cells `start..end` of the row beginning at cell `row`, without
/// the edge and void branches (the same arithmetic, in a loop LLVM vectorises); `f` is the row
/// of each direction's fluxes.
#[inline(always)]
pub(super) fn flux_run(
    c: &Consts,
    b: &[f32],
    d: &[f32],
    row: usize,
    start: usize,
    end: usize,
    f: &mut [&mut [f32]; 4],
) {
    let [fw, fe, fnn, fs] = f;
    let f = [
        &mut fw[start..end],
        &mut fe[start..end],
        &mut fnn[start..end],
        &mut fs[start..end],
    ];
    flux_cells(c, b, d, row + start, f);
}

/// The loop of [`flux_run`] from cell `i` on, the rows of fluxes as separate slices (so LLVM
/// knows they do not alias).
#[inline(never)]
pub(super) fn flux_cells(
    c: &Consts,
    b: &[f32],
    d: &[f32],
    i: usize,
    [fw, fe, fnn, fs]: [&mut [f32]; 4],
) {
    let (n, w) = (fw.len(), c.width);
    // The cells and their west, east, north and south neighbours.
    let at = |v, j| window(v, j, n);
    let cross = |v| {
        [
            at(v, i),
            at(v, i - 1),
            at(v, i + 1),
            at(v, i - w),
            at(v, i + w),
        ]
    };
    let [bc, bw, be, bn, bs] = cross(b);
    let [dc, dw, de, dn, ds] = cross(d);
    let (fe, fnn, fs) = (&mut fe[..n], &mut fnn[..n], &mut fs[..n]);
    let [kw, ke, kn, ks] = c.kflux;
    let (area, dt) = (c.area, c.dt);
    for x in 0..n {
        let (di, hi) = (dc[x], bc[x] + dc[x]);
        let nw = (fw[x] + kw * (hi - (bw[x] + dw[x]))).max(0.0);
        let ne = (fe[x] + ke * (hi - (be[x] + de[x]))).max(0.0);
        let nn = (fnn[x] + kn * (hi - (bn[x] + dn[x]))).max(0.0);
        let ns = (fs[x] + ks * (hi - (bs[x] + ds[x]))).max(0.0);
        let sum = 0.0 + nw + ne + nn + ns;
        // Eq. 4: never drain more than the cell holds (a factor of 1 changes nothing).
        let volume = di * area;
        let scale = if sum * dt > volume {
            volume / (sum * dt)
        } else {
            1.0
        };
        (fw[x], fe[x], fnn[x], fs[x]) = (nw * scale, ne * scale, nn * scale, ns * scale);
    }
}

/// The `n` values of `v` from `j`.
#[inline(always)]
pub(super) fn window(v: &[f32], j: usize, n: usize) -> &[f32] {
    &v[j..j + n]
}

/// The state of one cell after the erosion pass.
pub(super) struct CellOut {
    pub(super) b: f32,
    pub(super) d: f32,
    pub(super) s: f32,
    pub(super) uv: [f32; 2],
    pub(super) left: f32,
}

/// Water update, velocity, erosion and deposition of the valid cell `i` (mask `m`, neighbours
/// `nb`; Mei et al. eq. 6-12), from the fluxes of the cell and its neighbours, the ground
/// around it, its depth `d1` and load `s`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn erode_cell(
    c: &Consts,
    b: &[f32],
    f: &[Vec<f32>; 4],
    z0: f32,
    m: u8,
    i: usize,
    nb: [usize; 4],
    d1: f32,
    mut s: f32,
) -> CellOut {
    let bi = b[i];
    // Inflow from each side: the neighbour's flux towards this cell (0 from voids, whose
    // fluxes are 0, and from off the map, where `nb` points at the cell itself).
    let inflow = [W, E, N, S].map(|k| if nb[k] != i { f[OPP[k]][nb[k]] } else { 0.0 });
    let out = [W, E, N, S].map(|k| f[k][i]);
    let (mut sum_in, mut sum_out, mut open_out) = (0.0f32, 0.0f32, 0.0f32);
    for k in 0..4 {
        sum_in += inflow[k];
        sum_out += out[k];
        if !ok(m, k) {
            open_out += out[k];
        }
    }
    let d2 = (d1 + c.dt_area * (sum_in - sum_out)).max(0.0);
    // The water leaving through open sides takes its share of the load with it.
    let left = if open_out > 0.0 && d1 > 0.0 {
        s * (open_out * c.dt_area / d1).min(1.0)
    } else {
        0.0
    };
    s -= left;
    // Eq. 8-9: mean flux through the cell over its cross-section, at most a cell per step.
    let mean = 0.5 * (d1 + d2);
    let (mut u, mut v) = (0.0f32, 0.0f32);
    if mean > 1e-6 {
        let inv = 0.5 / mean;
        let wx = inflow[W] - out[W] + out[E] - inflow[E];
        let wy = inflow[N] - out[N] + out[S] - inflow[S];
        u = (wx * inv * c.inv_ly).clamp(-c.max_u, c.max_u);
        v = (wy * inv * c.inv_lx).clamp(-c.max_v, c.max_v);
    }
    // The ground's tilt from central differences (one-sided beside an edge or a void).
    let diff = |lo: usize, hi: usize, inv_l: f32| match (ok(m, lo), ok(m, hi)) {
        (true, true) => (b[nb[hi]] - b[nb[lo]]) * 0.5 * inv_l,
        (true, false) => (bi - b[nb[lo]]) * inv_l,
        (false, true) => (b[nb[hi]] - bi) * inv_l,
        (false, false) => 0.0,
    };
    let gx = diff(W, E, c.inv_lx);
    let gy = diff(N, S, c.inv_ly);
    let g2 = gx * gx + gy * gy;
    let sin = (g2 / (1.0 + g2)).sqrt().max(c.min_tilt);
    let speed = (u * u + v * v).sqrt();
    let capacity = c.kc_dt * sin * speed * (d2 * c.inv_full_depth).min(1.0);
    let hard = if c.inv_hardness > 0.0 {
        1.0 / (1.0 + (z0 - bi).max(0.0) * c.inv_hardness)
    } else {
        1.0
    };
    // Erosion (positive) or deposition (negative), without a branch on the sign. Erosion never
    // takes a cell below its lowest neighbour: the pipe model's water sloshing in a pit would
    // otherwise dig it ever deeper (a hole, not a landform).
    let gap = capacity - s;
    let rate = if gap > 0.0 { c.ks * hard } else { c.kd };
    let mut lowest = bi;
    for k in 0..4 {
        if ok(m, k) {
            lowest = lowest.min(b[nb[k]]);
        }
    }
    let change = (rate * gap).min(bi - lowest);
    CellOut {
        b: bi - change,
        d: d2,
        s: s + change,
        uv: [u, v],
        left,
    }
}

/// What [`erode_run`] reads: the constants, the ground, the fluxes, the initial ground, the
/// row's first cell, the run's columns `start..end`, the load's factor and the row's rain.
pub(super) type RunArgs<'a> = (
    &'a Consts,
    &'a [f32],
    &'a [Vec<f32>; 4],
    &'a [f32],
    usize,
    usize,
    usize,
    f32,
    &'a [f32],
);

/// [`erode_cell`] on the [`FULL`] cells `start..end` of a row (with hardening when `HARD`),
/// without the edge and void branches (the same arithmetic, in a loop LLVM vectorises): no
/// side is open, so no load leaves.
#[inline(always)]
pub(super) fn erode_run<const HARD: bool>(args: RunArgs<'_>, out: &mut RowOut<'_>) {
    let (c, b, f, z0, row, start, end, scale, wet) = args;
    let (n, w, i) = (end - start, c.width, row + start);
    let at = |v, j| window(v, j, n);
    let [fw, fe, fnn, fs] = f;
    let cells = RunIn {
        c,
        scale,
        b: [
            at(b, i),
            at(b, i - 1),
            at(b, i + 1),
            at(b, i - w),
            at(b, i + w),
        ],
        // The cell's outflows and the inflows: each neighbour's flux towards the cell.
        out: [at(fw, i), at(fe, i), at(fnn, i), at(fs, i)],
        inflow: [at(fe, i - 1), at(fw, i + 1), at(fs, i - w), at(fnn, i + w)],
        z0: at(z0, i),
        wet: &wet[start..end],
    };
    erode_cells::<HARD>(
        &cells,
        &mut out.b[start..end],
        &mut out.d[start..end],
        &mut out.s[start..end],
        &mut out.u[start..end],
        &mut out.v[start..end],
    );
}

/// The inputs of [`erode_cells`], each slice over the run's cells.
pub(super) struct RunIn<'a> {
    pub(super) c: &'a Consts,
    pub(super) scale: f32,
    /// The ground of the cells and of their west, east, north and south neighbours.
    pub(super) b: [&'a [f32]; 5],
    /// The cells' outflows to the west, east, north and south.
    pub(super) out: [&'a [f32]; 4],
    /// The inflows from the west, east, north and south.
    pub(super) inflow: [&'a [f32]; 4],
    pub(super) z0: &'a [f32],
    pub(super) wet: &'a [f32],
}

/// The loop of [`erode_run`], the outputs (ground, depth, load, velocity) as separate slices so
/// that LLVM knows they do not alias the inputs.
#[inline(never)]
pub(super) fn erode_cells<const HARD: bool>(
    k: &RunIn<'_>,
    bo: &mut [f32],
    d: &mut [f32],
    s: &mut [f32],
    u: &mut [f32],
    v: &mut [f32],
) {
    let n = bo.len();
    let at = |v| window(v, 0, n);
    let (d, s, u, v) = (&mut d[..n], &mut s[..n], &mut u[..n], &mut v[..n]);
    let [bc, bw, be, bn, bs] = k.b.map(at);
    let [ow, oe, on, os] = k.out.map(at);
    let [iw, ie, inn, is] = k.inflow.map(at);
    let (z0, wet, scale) = (at(k.z0), at(k.wet), k.scale);
    let c = k.c;
    let (dt_area, inv_lx, inv_ly, max_u, max_v) = (c.dt_area, c.inv_lx, c.inv_ly, c.max_u, c.max_v);
    let (min_tilt, kc_dt, inv_full_depth) = (c.min_tilt, c.kc_dt, c.inv_full_depth);
    let (ks, kd, keep, inv_hardness) = (c.ks, c.kd, c.keep, c.inv_hardness);
    let (half_inv_lx, half_inv_ly) = (0.5 * inv_lx, 0.5 * inv_ly);
    for x in 0..n {
        let (bi, d1, load) = (bc[x], d[x], s[x] * scale);
        let sum_in = 0.0 + iw[x] + ie[x] + inn[x] + is[x];
        let sum_out = 0.0 + ow[x] + oe[x] + on[x] + os[x];
        let d2 = (d1 + dt_area * (sum_in - sum_out)).max(0.0);
        let mean = 0.5 * (d1 + d2);
        let inv = 0.5 / mean;
        let wx = iw[x] - ow[x] + oe[x] - ie[x];
        let wy = inn[x] - on[x] + os[x] - is[x];
        let moving = mean > 1e-6;
        let ux = if moving {
            clamp(wx * inv * inv_ly, -max_u, max_u)
        } else {
            0.0
        };
        let vy = if moving {
            clamp(wy * inv * inv_lx, -max_v, max_v)
        } else {
            0.0
        };
        // `(hi - lo) * 0.5 * inv_l` with the exact factor `0.5 inv_l`.
        let gx = (be[x] - bw[x]) * half_inv_lx;
        let gy = (bs[x] - bn[x]) * half_inv_ly;
        let g2 = gx * gx + gy * gy;
        let sin = (g2 / (1.0 + g2)).sqrt().max(min_tilt);
        let speed = (ux * ux + vy * vy).sqrt();
        let capacity = kc_dt * sin * speed * (d2 * inv_full_depth).min(1.0);
        let gap = capacity - load;
        let erode = if HARD {
            ks * (1.0 / (1.0 + (z0[x] - bi).max(0.0) * inv_hardness))
        } else {
            ks
        };
        let rate = if gap > 0.0 { erode } else { kd };
        let lowest = bi.min(bw[x]).min(be[x]).min(bn[x]).min(bs[x]);
        let change = (rate * gap).min(bi - lowest);
        bo[x] = bi - change;
        d[x] = d2 * keep + wet[x];
        s[x] = load + change;
        (u[x], v[x]) = (ux, vy);
    }
}

/// Step 4 on row `y` (mask `m`, velocities `u` and `v`): the load `s` carried to each valid
/// cell, `s(x - v dt)` sampled bilinearly with the position clamped to the map, into `sn`.
/// `at` is scratch space: the sample positions are computed first (in a loop LLVM vectorises),
/// then the samples.
#[allow(clippy::too_many_arguments)]
#[inline(never)]
pub(super) fn advect_row(
    c: &Consts,
    s: &[f32],
    y: usize,
    m: &[u8],
    u: &[f32],
    v: &[f32],
    sn: &mut [f32],
    at: &mut Positions,
) {
    let (w, h) = (c.width, c.height);
    let (m, u, v, sn) = (&m[..w], &u[..w], &v[..w], &mut sn[..w]);
    let (xmax, ymax) = ((w - 1) as f32, (h - 1) as f32);
    let (kx, ky, yf) = (c.dt / c.lx, c.dt / c.ly, y as f32);
    if w > i32::MAX as usize || h > i32::MAX as usize {
        for x in 0..w {
            if m[x] & VALID != 0 {
                let sx = clamp(x as f32 - u[x] * kx, 0.0, xmax);
                let sy = clamp(yf - v[x] * ky, 0.0, ymax);
                sn[x] = bilinear(s, w, h, sx, sy);
            }
        }
        return;
    }
    at.resize(w);
    let Positions {
        x0,
        x1,
        y0,
        y1,
        tx,
        ty,
    } = at;
    let (x0, x1, y0, y1) = (&mut x0[..w], &mut x1[..w], &mut y0[..w], &mut y1[..w]);
    let (tx, ty) = (&mut tx[..w], &mut ty[..w]);
    let (wm, hm) = (w as i32 - 1, h as i32 - 1);
    for x in 0..w {
        let sx = clamp(x as i32 as f32 - u[x] * kx, 0.0, xmax);
        let sy = clamp(yf - v[x] * ky, 0.0, ymax);
        // Truncation is the floor here: the position is clamped to the map.
        let (ix, iy) = (sx as i32, sy as i32);
        (x0[x], y0[x]) = (ix, iy);
        (x1[x], y1[x]) = ((ix + 1).min(wm), (iy + 1).min(hm));
        (tx[x], ty[x]) = (sx - ix as f32, sy - iy as f32);
    }
    for x in 0..w {
        if m[x] & VALID == 0 {
            continue;
        }
        let (r0, r1) = (y0[x] as usize * w, y1[x] as usize * w);
        let (a, b) = (x0[x] as usize, x1[x] as usize);
        let (s00, s01, s10, s11) = (s[r0 + a], s[r0 + b], s[r1 + a], s[r1 + b]);
        let top = s00 + (s01 - s00) * tx[x];
        let bottom = s10 + (s11 - s10) * tx[x];
        sn[x] = top + (bottom - top) * ty[x];
    }
}

/// Per column of a row: the sample's columns and rows either side and its fractions.
#[derive(Default)]
pub(super) struct Positions {
    pub(super) x0: Vec<i32>,
    pub(super) x1: Vec<i32>,
    pub(super) y0: Vec<i32>,
    pub(super) y1: Vec<i32>,
    pub(super) tx: Vec<f32>,
    pub(super) ty: Vec<f32>,
}

impl Positions {
    fn resize(&mut self, n: usize) {
        for v in [&mut self.x0, &mut self.x1, &mut self.y0, &mut self.y1] {
            v.resize(n, 0);
        }
        self.tx.resize(n, 0.0);
        self.ty.resize(n, 0.0);
    }
}

/// Bilinear sample of `s` at `(x, y)` (cell units, inside the map).
#[inline]
pub(super) fn bilinear(s: &[f32], width: usize, height: usize, x: f32, y: f32) -> f32 {
    // Truncation is the floor here: the position is clamped to the map (no libm call).
    let (x0, y0) = (x as i32 as usize, y as i32 as usize);
    let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
    let (tx, ty) = (x - x0 as f32, y - y0 as f32);
    let row = |yy: usize| {
        let r = yy * width;
        s[r + x0] + (s[r + x1] - s[r + x0]) * tx
    };
    let (a, b) = (row(y0), row(y1));
    a + (b - a) * ty
}
