//! Linear hillslope diffusion, dz/dt = D (d2z/dx2 + d2z/dy2), one implicit time step by the
//! alternating-direction implicit (ADI) scheme of fastscapelib's `DiffusionADIEroder`
//! (`include/fastscapelib/eroders/diffusion_adi.hpp`, Peaceman and Rachford 1955): a first
//! pass implicit along the rows (x) and explicit along the columns (y), then a second pass
//! implicit along y and explicit along x, each over the whole `dt` with the factors
//! `D / (2 dx^2)` and `D / (2 dy^2)`; each line is a tridiagonal system solved by the Thomas
//! algorithm. Unconditionally stable; second-order accurate in space.
//!
//! Boundaries: fixed cells (base levels) keep their elevation (Dirichlet: an identity row in
//! the tridiagonal system, as fastscapelib does for the whole outer edge, whatever the grid's
//! node status). Unlike fastscapelib, a free cell on the map's edge or beside a void has no
//! flux across that side (Neumann: the missing neighbour is dropped from the stencil), and
//! voids (`NaN`) stay voids. With the outer edge fixed and no voids this is fastscapelib's
//! scheme operation for operation.
//!
//! Parallel over rows (first pass) and over blocks of columns (second pass); every value is
//! computed by one thread in a fixed order, so the result does not depend on the thread count.

use rayon::prelude::*;
use relief_heightfield::param::{ensure, in_range};

use crate::grid::Grid;
use crate::{LandscapeError, Result};

/// A cell whose elevation evolves.
pub(crate) const FREE: u8 = 0;
/// A fixed-elevation cell (base level).
pub(crate) const FIXED: u8 = 1;
/// A void (`NaN`): no value, no flux.
pub(crate) const VOID: u8 = 2;

/// Columns per block of the second ADI pass: the block's tridiagonal systems are solved side
/// by side, row after row, so that every read and write is contiguous.
const BLOCK: usize = 64;

/// Buffers of [`diffuse`], reused between time steps (no allocation once sized).
#[derive(Debug, Default, Clone)]
pub struct DiffusionScratch {
    kind: Vec<u8>,
    tmp: Vec<f64>,
    gam: Vec<f64>,
    blocks: Vec<f64>,
}

impl DiffusionScratch {
    /// Empty buffers, sized on first use.
    pub fn new() -> Self {
        Self::default()
    }
}

/// Classifies every cell as [`FREE`], [`FIXED`] (`fixed[i]`) or [`VOID`] (`NaN`).
pub(crate) fn node_kinds(z: &[f64], fixed: &[bool], kind: &mut [u8]) {
    kind.par_iter_mut()
        .zip(z.par_iter().zip(fixed.par_iter()))
        .for_each(|(k, (&v, &f))| {
            *k = if v.is_nan() {
                VOID
            } else if f {
                FIXED
            } else {
                FREE
            }
        });
}

/// One implicit step (`dt` years) of linear diffusion with diffusivity `diffusivity` (m^2/yr)
/// on `z` in place; the cells marked in `fixed` and the voids keep their values.
///
/// Errors: a negative or non-finite diffusivity, a non-positive `dt`, or rasters whose length
/// is not the grid's.
pub fn diffuse(
    z: &mut [f64],
    grid: &Grid,
    fixed: &[bool],
    diffusivity: f64,
    dt: f64,
    scratch: &mut DiffusionScratch,
) -> Result<()> {
    in_range(
        "diffusivity",
        diffusivity,
        0.0..1e12,
        "must be >= 0 m2/yr and finite",
    )?;
    ensure(
        dt > 0.0 && dt.is_finite(),
        "dt",
        dt,
        "must be > 0 yr and finite",
    )?;
    if z.len() != grid.len() || fixed.len() != grid.len() {
        return Err(LandscapeError::InvalidInput(format!(
            "diffusion rasters of {} and {} cells on a {}x{} grid",
            z.len(),
            fixed.len(),
            grid.width,
            grid.height
        )));
    }
    let mut kind = std::mem::take(&mut scratch.kind);
    kind.resize(grid.len(), FREE);
    node_kinds(z, fixed, &mut kind);
    adi(z, grid, &kind, diffusivity, dt, scratch);
    scratch.kind = kind;
    Ok(())
}

/// The ADI step on `z` in place, with the cell kinds already classified.
pub(crate) fn adi(
    z: &mut [f64],
    grid: &Grid,
    kind: &[u8],
    diffusivity: f64,
    dt: f64,
    scratch: &mut DiffusionScratch,
) {
    let (w, h) = (grid.width, grid.height);
    if diffusivity == 0.0 || w == 0 || h == 0 {
        return;
    }
    let n = grid.len();
    // fastscapelib's factors: D / 2 / dy^2 along the columns, D / 2 / dx^2 along the rows.
    let fy = diffusivity * 0.5 / (grid.cell_y * grid.cell_y);
    let fx = diffusivity * 0.5 / (grid.cell_x * grid.cell_x);
    scratch.tmp.resize(n, 0.0);
    scratch.gam.resize(n, 0.0);
    scratch.blocks.resize(n, 0.0);
    let input: &[f64] = z;
    scratch
        .tmp
        .par_chunks_mut(w)
        .zip(scratch.gam.par_chunks_mut(w))
        .enumerate()
        .for_each(|(r, (out, gam))| row_pass(input, kind, w, h, r, fx, fy, dt, out, gam));
    let tmp = &scratch.tmp;
    scratch
        .blocks
        .par_chunks_mut(h * BLOCK)
        .zip(scratch.gam.par_chunks_mut(h * BLOCK))
        .enumerate()
        .for_each(|(b, (out, gam))| column_pass(tmp, kind, w, h, b * BLOCK, fx, fy, dt, out, gam));
    let blocks = &scratch.blocks;
    z.par_chunks_mut(w).enumerate().for_each(|(r, row)| {
        for (b, c0) in (0..w).step_by(BLOCK).enumerate() {
            let bw = BLOCK.min(w - c0);
            let src = &blocks[b * h * BLOCK + r * bw..][..bw];
            for j in 0..bw {
                if kind[r * w + c0 + j] == FREE {
                    row[c0 + j] = src[j];
                }
            }
        }
    });
}

/// The tridiagonal coefficients `(lower, diag, upper)` of a free cell along the implicit axis
/// (factor `f`) with neighbours `before` / `after` present or not.
#[inline]
fn implicit(f: f64, dt: f64, before: bool, after: bool) -> (f64, f64, f64) {
    let cnt = before as u8 + after as u8;
    let lower = if before { -f * dt } else { 0.0 };
    let upper = if after { -f * dt } else { 0.0 };
    (lower, 1.0 + f64::from(cnt) * f * dt, upper)
}

/// The explicit right-hand side of a free cell: `(1 - cnt f dt) z + f z_before dt + f z_after
/// dt`, in fastscapelib's order of operations.
#[inline]
fn explicit(f: f64, dt: f64, zc: f64, before: Option<f64>, after: Option<f64>) -> f64 {
    let cnt = before.is_some() as u8 + after.is_some() as u8;
    let mut v = (1.0 - f64::from(cnt) * f * dt) * zc;
    if let Some(zb) = before {
        v += f * zb * dt;
    }
    if let Some(za) = after {
        v += f * za * dt;
    }
    v
}

/// First pass on row `r`: implicit along x (factor `fx`), explicit along y (`fy`).
#[allow(clippy::too_many_arguments)]
fn row_pass(
    z: &[f64],
    kind: &[u8],
    w: usize,
    h: usize,
    r: usize,
    fx: f64,
    fy: f64,
    dt: f64,
    out: &mut [f64],
    gam: &mut [f64],
) {
    let base = r * w;
    let (mut bet, mut upper_prev) = (1.0, 0.0);
    for c in 0..w {
        let i = base + c;
        let (lower, diag, upper, vec) = match kind[i] {
            FREE => {
                let valid = |j: usize| kind[j] != VOID;
                let (lo, di, up) =
                    implicit(fx, dt, c > 0 && valid(i - 1), c + 1 < w && valid(i + 1));
                let north = (r > 0 && valid(i - w)).then(|| z[i - w]);
                let south = (r + 1 < h && valid(i + w)).then(|| z[i + w]);
                (lo, di, up, explicit(fy, dt, z[i], north, south))
            }
            FIXED => (0.0, 1.0, 0.0, z[i]),
            _ => (0.0, 1.0, 0.0, 0.0),
        };
        if c == 0 {
            bet = diag;
            out[c] = vec / bet;
        } else {
            gam[c] = upper_prev / bet;
            bet = diag - lower * gam[c];
            out[c] = (vec - lower * out[c - 1]) / bet;
        }
        upper_prev = upper;
    }
    for c in (0..w.saturating_sub(1)).rev() {
        out[c] -= gam[c + 1] * out[c + 1];
    }
}

/// Second pass on the columns `c0..c0 + bw` (`bw = out.len() / h`): implicit along y (factor
/// `fy`), explicit along x (`fx`) on the first pass's output `tmp`; the block's result is
/// stored row-major with `bw` columns in `out`.
#[allow(clippy::too_many_arguments)]
fn column_pass(
    tmp: &[f64],
    kind: &[u8],
    w: usize,
    h: usize,
    c0: usize,
    fx: f64,
    fy: f64,
    dt: f64,
    out: &mut [f64],
    gam: &mut [f64],
) {
    let bw = out.len() / h;
    let mut bet = [1.0f64; BLOCK];
    let mut upper_prev = [0.0f64; BLOCK];
    for r in 0..h {
        for j in 0..bw {
            let (c, i, o) = (c0 + j, r * w + c0 + j, r * bw + j);
            let (lower, diag, upper, vec) = match kind[i] {
                FREE => {
                    let valid = |k: usize| kind[k] != VOID;
                    let (lo, di, up) =
                        implicit(fy, dt, r > 0 && valid(i - w), r + 1 < h && valid(i + w));
                    let west = (c > 0 && valid(i - 1)).then(|| tmp[i - 1]);
                    let east = (c + 1 < w && valid(i + 1)).then(|| tmp[i + 1]);
                    (lo, di, up, explicit(fx, dt, tmp[i], west, east))
                }
                FIXED => (0.0, 1.0, 0.0, tmp[i]),
                _ => (0.0, 1.0, 0.0, 0.0),
            };
            if r == 0 {
                bet[j] = diag;
                out[o] = vec / bet[j];
            } else {
                gam[o] = upper_prev[j] / bet[j];
                bet[j] = diag - lower * gam[o];
                out[o] = (vec - lower * out[o - bw]) / bet[j];
            }
            upper_prev[j] = upper;
        }
    }
    for r in (0..h.saturating_sub(1)).rev() {
        for j in 0..bw {
            let o = r * bw + j;
            out[o] -= gam[o + bw] * out[o + bw];
        }
    }
}
