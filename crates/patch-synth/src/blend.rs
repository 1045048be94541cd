//! Blending a placed block into the canvas: the crease-smoothing of a seam and the Poisson
//! blend (section 3.4), solved by conjugate gradients with an incomplete Cholesky
//! preconditioner.

/// Fraction of the way a crease-smoothing pass moves a cell towards its neighbours' mean.
const CREASE_WEIGHT: f32 = 0.35;

/// Crease smoothing along the new cuts of the patch at `(x0, y0)`: the cells within
/// one cell of a cut (`left[r]` = cut column of row `r`, `top[c]` = cut row of column `c`,
/// patch-local; empty when absent) move [`CREASE_WEIGHT`] of the way towards the mean of their four neighbours,
/// `passes` times (Jacobi, so the result does not depend on the visiting order). Neighbours
/// outside the canvas or not yet synthesized are skipped.
#[allow(clippy::too_many_arguments)]
pub(crate) fn smooth_crease(
    canvas: &mut [f32],
    filled: &[bool],
    cw: usize,
    ch: usize,
    (x0, y0): (usize, usize),
    left: &[usize],
    top: &[usize],
    passes: usize,
) {
    let mut cells: Vec<usize> = Vec::new();
    let mut mark = |x: isize, y: isize| {
        if x > 0 && y > 0 && (x as usize) + 1 < cw && (y as usize) + 1 < ch {
            cells.push(y as usize * cw + x as usize);
        }
    };
    for (r, &c) in left.iter().enumerate() {
        for d in -1isize..=1 {
            mark((x0 + c) as isize + d, (y0 + r) as isize);
        }
    }
    for (c, &r) in top.iter().enumerate() {
        for d in -1isize..=1 {
            mark((x0 + c) as isize, (y0 + r) as isize + d);
        }
    }
    cells.sort_unstable();
    cells.dedup();
    cells.retain(|&i| filled[i]);
    let mut next = vec![0.0f32; cells.len()];
    for _ in 0..passes {
        for (v, &i) in next.iter_mut().zip(&cells) {
            let (mut s, mut n) = (0.0f32, 0u32);
            for j in [i - 1, i + 1, i - cw, i + cw] {
                if filled[j] {
                    s += canvas[j];
                    n += 1;
                }
            }
            *v = if n > 0 {
                (1.0 - CREASE_WEIGHT) * canvas[i] + CREASE_WEIGHT * s / n as f32
            } else {
                canvas[i]
            };
        }
        for (&v, &i) in next.iter().zip(&cells) {
            canvas[i] = v;
        }
    }
}

pub(crate) struct PoissonInput<'a> {
    pub(crate) p: usize,
    /// Solve over the whole patch (else the overlap only, the interior as boundary).
    pub(crate) whole: bool,
    /// Screening weight towards the cut-and-paste values (0 = plain Poisson).
    pub(crate) screen: f64,
    pub(crate) ov_cols: &'a dyn Fn(usize) -> usize,
    pub(crate) is_new: &'a dyn Fn(usize, usize) -> bool,
    pub(crate) nv: &'a dyn Fn(usize, usize) -> f32,
    pub(crate) old: &'a dyn Fn(usize, usize) -> f32,
    /// Value of an already synthesized cell outside the patch (patch-local coordinates).
    pub(crate) outside: &'a dyn Fn(isize, isize) -> Option<f32>,
}

/// Poisson blending of the overlap region (Zhou et al. 2007, as cited in section 3.3): solves
/// the discrete Poisson equation on the overlap cells with the guidance gradient of the old
/// terrain on the old side, of the new patch on the new side and their average across the cut;
/// the patch interior and the surrounding synthesized terrain are Dirichlet boundaries, cells
/// not yet synthesized are Neumann. Conjugate gradients preconditioned by an incomplete Cholesky
/// factor ([`IncompleteCholesky`]), started from the cut-and-paste values.
/// Returns the iterations used.
pub(crate) fn poisson_blend(
    out: &mut [f32],
    inp: PoissonInput<'_>,
    max_iterations: usize,
) -> usize {
    let p = inp.p;
    let mut idx = vec![usize::MAX; p * p];
    let mut cells = Vec::new();
    for r in 0..p {
        let cols = if inp.whole { p } else { (inp.ov_cols)(r) };
        for c in 0..cols {
            idx[r * p + c] = cells.len();
            cells.push((r, c));
        }
    }
    let n = cells.len();
    if n == 0 {
        return 0;
    }
    // Neighbour lists: unknown neighbours and the right-hand side.
    let mut nbrs: Vec<[usize; 4]> = vec![[usize::MAX; 4]; n];
    let mut diag = vec![0.0f64; n];
    let mut rhs = vec![0.0f64; n];
    for (a, &(r, c)) in cells.iter().enumerate() {
        let new_a = (inp.is_new)(r, c);
        let (nva, olda) = ((inp.nv)(r, c) as f64, (inp.old)(r, c) as f64);
        for (k, (dr, dc)) in [(-1isize, 0isize), (1, 0), (0, -1), (0, 1)]
            .into_iter()
            .enumerate()
        {
            let (rr, cc) = (r as isize + dr, c as isize + dc);
            let inside = rr >= 0 && cc >= 0 && rr < p as isize && cc < p as isize;
            if inside {
                let (rr, cc) = (rr as usize, cc as usize);
                let b = idx[rr * p + cc];
                let nvb = (inp.nv)(rr, cc) as f64;
                if b != usize::MAX {
                    let oldb = (inp.old)(rr, cc) as f64;
                    let new_b = (inp.is_new)(rr, cc);
                    let g = match (new_a, new_b) {
                        (true, true) => nva - nvb,
                        (false, false) => olda - oldb,
                        _ => 0.5 * ((nva - nvb) + (olda - oldb)),
                    };
                    nbrs[a][k] = b;
                    diag[a] += 1.0;
                    rhs[a] += g;
                } else {
                    // Patch interior: Dirichlet with the new values.
                    diag[a] += 1.0;
                    rhs[a] += (nva - nvb) + nvb;
                }
            } else if let Some(v) = (inp.outside)(cc, rr) {
                let v = v as f64;
                diag[a] += 1.0;
                rhs[a] += (olda - v) + v;
            }
        }
    }
    if inp.screen > 0.0 {
        for (a, &(r, c)) in cells.iter().enumerate() {
            diag[a] += inp.screen;
            rhs[a] += inp.screen * out[r * p + c] as f64;
        }
    }
    let apply = |x: &[f64], y: &mut [f64]| {
        for a in 0..n {
            let mut s = diag[a] * x[a];
            for &b in &nbrs[a] {
                if b != usize::MAX {
                    s -= x[b];
                }
            }
            y[a] = s;
        }
    };
    let precond = IncompleteCholesky::new(&diag, &nbrs);
    let mut x: Vec<f64> = cells.iter().map(|&(r, c)| out[r * p + c] as f64).collect();
    let mut ax = vec![0.0f64; n];
    apply(&x, &mut ax);
    let mut res: Vec<f64> = rhs.iter().zip(&ax).map(|(b, a)| b - a).collect();
    let bnorm: f64 = rhs.iter().map(|v| v * v).sum::<f64>().max(1e-30);
    let it = relief_heightfield::cg::pcg(
        apply,
        |r: &[f64], z: &mut [f64]| precond.solve(r, z),
        &mut x,
        &mut res,
        |it, rr| it < max_iterations && rr > 1e-14 * bnorm,
    );
    for (a, &(r, c)) in cells.iter().enumerate() {
        out[r * p + c] = x[a] as f32;
    }
    it
}

/// Incomplete Cholesky factor IC(0) of the blending matrix `diag - adjacency` in the cells'
/// row-major order (up and left neighbours come first): `L` keeps the matrix's pattern, its
/// off-diagonal entries are `-1 / L_bb`. Preconditions the conjugate gradients (about a third
/// of the iterations of plain CG on a whole 64-cell patch).
struct IncompleteCholesky<'a> {
    /// `1 / L_aa`.
    inv: Vec<f64>,
    /// Neighbours `[up, down, left, right]` (`usize::MAX`: none).
    nbrs: &'a [[usize; 4]],
}

impl<'a> IncompleteCholesky<'a> {
    fn new(a_diag: &[f64], nbrs: &'a [[usize; 4]]) -> Self {
        let mut diag = vec![0.0f64; a_diag.len()];
        for a in 0..a_diag.len() {
            let mut d = a_diag[a];
            for k in [0, 2] {
                let b = nbrs[a][k];
                if b != usize::MAX && b < a {
                    d -= 1.0 / (diag[b] * diag[b]);
                }
            }
            // Diagonally dominant rows keep d > 0; a breakdown falls back to the row's diagonal.
            diag[a] = if d > 1e-12 {
                d.sqrt()
            } else {
                a_diag[a].sqrt()
            };
        }
        let inv = diag.iter().map(|d| 1.0 / d).collect();
        Self { inv, nbrs }
    }

    /// `z = (L L^T)^-1 r`.
    fn solve(&self, r: &[f64], z: &mut [f64]) {
        let n = r.len();
        for a in 0..n {
            let mut s = r[a];
            for k in [0, 2] {
                let b = self.nbrs[a][k];
                if b != usize::MAX && b < a {
                    s += z[b] * self.inv[b];
                }
            }
            z[a] = s * self.inv[a];
        }
        for a in (0..n).rev() {
            let mut s = z[a];
            for k in [1, 3] {
                let c = self.nbrs[a][k];
                if c != usize::MAX && c > a {
                    s += z[c] * self.inv[a];
                }
            }
            z[a] = s * self.inv[a];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat new patch 10 m below the terrain on its left: the plain Poisson blend squeezes
    /// the step into the overlap, the screened one spreads it over the patch (gentler largest
    /// slope) and lets it decay towards the patch's own height.
    #[test]
    fn screened_blend_spreads_a_boundary_offset_over_the_patch() {
        let (p, ov) = (32usize, 8usize);
        let run = |whole: bool, screen: f64| {
            let mut out = vec![0.0f32; p * p];
            let iters = poisson_blend(
                &mut out,
                PoissonInput {
                    p,
                    whole,
                    screen,
                    ov_cols: &|_| ov,
                    is_new: &|_, c| c >= ov / 2,
                    nv: &|_, _| 0.0,
                    old: &|_, _| 10.0,
                    outside: &|x, _| (x < 0).then_some(10.0),
                },
                2000,
            );
            assert!(iters > 0);
            out
        };
        let max_step = |v: &[f32]| {
            (0..p)
                .flat_map(|r| (1..p).map(move |c| (r, c)))
                .map(|(r, c)| (v[r * p + c] - v[r * p + c - 1]).abs())
                .fold(0.0f32, f32::max)
        };
        let plain = run(false, 0.0);
        let screened = run(true, 1.0 / 256.0);
        // Plain: the interior keeps the patch's height.
        assert!(plain[16 * p + ov + 2].abs() < 1e-6);
        // Screened: the offset reaches into the interior and decays along the row.
        let row = &screened[16 * p..17 * p];
        assert!(row[ov + 2] > 1.0, "{row:?}");
        assert!(row[ov + 2] > row[p - 1], "{row:?}");
        assert!(
            max_step(&screened) < 0.7 * max_step(&plain),
            "{} vs {}",
            max_step(&screened),
            max_step(&plain)
        );
    }

    /// IC(0) has no fill-in on a chain of cells (a tridiagonal matrix): it is the exact
    /// Cholesky factor, so one preconditioner solve inverts the matrix.
    #[test]
    fn incomplete_cholesky_is_exact_on_a_chain() {
        let n = 9;
        let nbrs: Vec<[usize; 4]> = (0..n)
            .map(|a| {
                let left = if a > 0 { a - 1 } else { usize::MAX };
                let right = if a + 1 < n { a + 1 } else { usize::MAX };
                [usize::MAX, usize::MAX, left, right]
            })
            .collect();
        let diag: Vec<f64> = (0..n).map(|a| 2.0 + 0.1 * a as f64).collect();
        let r: Vec<f64> = (0..n).map(|a| (a as f64 * 0.7).sin()).collect();
        let mut z = vec![0.0; n];
        IncompleteCholesky::new(&diag, &nbrs).solve(&r, &mut z);
        for a in 0..n {
            let mut az = diag[a] * z[a];
            for &b in &nbrs[a] {
                if b != usize::MAX {
                    az -= z[b];
                }
            }
            assert!((az - r[a]).abs() < 1e-12, "row {a}: {az} vs {}", r[a]);
        }
    }

    /// The preconditioned conjugate gradients converge on a whole screened 32 x 32 patch with
    /// a 10 m boundary step in under 40 iterations (33; plain CG took 107) to the same tolerance.
    #[test]
    fn preconditioned_blend_converges_fast() {
        let (p, ov) = (32usize, 8usize);
        let mut out = vec![0.0f32; p * p];
        let iters = poisson_blend(
            &mut out,
            PoissonInput {
                p,
                whole: true,
                screen: 1.0 / 256.0,
                ov_cols: &|_| ov,
                is_new: &|_, c| c >= ov / 2,
                nv: &|_, _| 0.0,
                old: &|_, _| 10.0,
                outside: &|x, y| (x < 0 || y < 0).then_some(10.0),
            },
            2000,
        );
        assert!(iters > 0 && iters < 40, "{iters} iterations");
    }
}
