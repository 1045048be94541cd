//! Preconditioned conjugate gradients for the sparse symmetric positive definite systems of
//! the workspace: the harmonic void fill ([`crate::fill`]) and patch-synth's Poisson blending
//! of a patch's overlap, each with its own operator, preconditioner and stopping rule.

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// Solves `A x = b` by conjugate gradients preconditioned by `M`, from the start `x` and its
/// residual `r = b - A x`, both updated in place: `apply(v, out)` writes `A v`,
/// `precondition(r, z)` writes `M^-1 r`. Iterates while `go_on(iterations, |r|^2)` holds; a
/// breakdown (a curvature `p . A p` that is not a positive finite number, or `r . M^-1 r <= 0`)
/// ends the run at the last iterate. Returns the iterations run.
pub fn pcg(
    apply: impl Fn(&[f64], &mut [f64]),
    precondition: impl Fn(&[f64], &mut [f64]),
    x: &mut [f64],
    r: &mut [f64],
    mut go_on: impl FnMut(usize, f64) -> bool,
) -> usize {
    let n = x.len();
    let mut z = vec![0.0f64; n];
    precondition(r, &mut z);
    let mut p = z.clone();
    let mut rz = dot(r, &z);
    let mut rr = dot(r, r);
    let mut ap = vec![0.0f64; n];
    let mut iterations = 0;
    while go_on(iterations, rr) {
        apply(&p, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() || rz <= 0.0 {
            break;
        }
        let alpha = rz / pap;
        for k in 0..n {
            x[k] += alpha * p[k];
            r[k] -= alpha * ap[k];
        }
        rr = dot(r, r);
        precondition(r, &mut z);
        let rz_new = dot(r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        for k in 0..n {
            p[k] = z[k] + beta * p[k];
        }
        iterations += 1;
    }
    iterations
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1-D Laplacian system with Jacobi preconditioning converges to the known solution.
    #[test]
    fn solves_a_small_laplacian() {
        // A = tridiag(-1, 2, -1), x* = [1, 2, 3, 4] => b = A x*.
        let apply = |v: &[f64], out: &mut [f64]| {
            for k in 0..v.len() {
                let l = if k > 0 { v[k - 1] } else { 0.0 };
                let r = if k + 1 < v.len() { v[k + 1] } else { 0.0 };
                out[k] = 2.0 * v[k] - l - r;
            }
        };
        let want = [1.0, 2.0, 3.0, 4.0];
        let mut b = [0.0; 4];
        apply(&want, &mut b);
        let mut x = [0.0; 4];
        let mut r = b;
        let it = pcg(
            apply,
            |r: &[f64], z: &mut [f64]| z.iter_mut().zip(r).for_each(|(z, r)| *z = r / 2.0),
            &mut x,
            &mut r,
            |it, rr| it < 10 && rr > 1e-24,
        );
        assert!(it <= 4, "{it}");
        for (a, b) in x.iter().zip(want) {
            assert!((a - b).abs() < 1e-9, "{x:?}");
        }
    }
}
