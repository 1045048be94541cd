//! Minimum-error boundary cut through an overlap region (section 3.3): the globally optimal
//! path by dynamic programming, and the greedy path of local decisions for comparison.

use crate::error::{PatchSynthError, Result};
use crate::settings::CutMethod;

/// A vertical seam: for every row, the first column that takes the new patch.
#[derive(Debug, Clone, PartialEq)]
pub struct Cut {
    /// Seam column of every row.
    pub path: Vec<usize>,
    /// Sum of the error along the path.
    pub cost: f64,
}

/// Finds a top-to-bottom seam through `errors` (`rows * cols`, row-major) that moves at most one
/// column per row and stays within columns `lo..=hi` (clamped to the grid).
///
/// Dynamic programming returns the path of least total error; the greedy variant starts at the
/// cheapest cell of the first row and then takes the cheapest of the three cells below.
/// Errors when `errors.len() != rows * cols`. NaN errors do not panic (the path stays a valid
/// seam; its cost is then NaN).
pub fn min_error_cut(
    errors: &[f32],
    rows: usize,
    cols: usize,
    lo: usize,
    hi: usize,
    method: CutMethod,
) -> Result<Cut> {
    if rows.checked_mul(cols) != Some(errors.len()) {
        return Err(PatchSynthError::InvalidControl {
            name: "errors",
            reason: format!("{} error values for a {rows} x {cols} grid", errors.len()),
        });
    }
    Ok(cut(errors, cols, lo, hi, method))
}

/// [`min_error_cut`] of a grid known to be whole rows of `cols` errors.
pub(crate) fn cut(errors: &[f32], cols: usize, lo: usize, hi: usize, method: CutMethod) -> Cut {
    let rows = errors.len().checked_div(cols).unwrap_or(0);
    debug_assert_eq!(errors.len(), rows * cols);
    if rows == 0 {
        return Cut {
            path: Vec::new(),
            cost: 0.0,
        };
    }
    let hi = hi.min(cols - 1);
    let lo = lo.min(hi);
    let e = |r: usize, c: usize| errors[r * cols + c] as f64;
    match method {
        CutMethod::Greedy => {
            let mut c = (lo..=hi)
                .min_by(|&a, &b| e(0, a).total_cmp(&e(0, b)).then(a.cmp(&b)))
                .unwrap_or(lo);
            let mut path = vec![c];
            let mut cost = e(0, c);
            for r in 1..rows {
                let (a, b) = (c.saturating_sub(1).max(lo), (c + 1).min(hi));
                c = (a..=b)
                    .min_by(|&x, &y| e(r, x).total_cmp(&e(r, y)).then(x.cmp(&y)))
                    .unwrap_or(c);
                cost += e(r, c);
                path.push(c);
            }
            Cut { path, cost }
        }
        CutMethod::DynamicProgramming => {
            let mut acc = vec![f64::INFINITY; rows * cols];
            for c in lo..=hi {
                acc[c] = e(0, c);
            }
            for r in 1..rows {
                for c in lo..=hi {
                    let (a, b) = (c.saturating_sub(1).max(lo), (c + 1).min(hi));
                    let m = (a..=b)
                        .map(|x| acc[(r - 1) * cols + x])
                        .fold(f64::INFINITY, f64::min);
                    acc[r * cols + c] = e(r, c) + m;
                }
            }
            let last = (rows - 1) * cols;
            let mut c = (lo..=hi)
                .min_by(|&a, &b| acc[last + a].total_cmp(&acc[last + b]).then(a.cmp(&b)))
                .unwrap_or(lo);
            let cost = acc[last + c];
            let mut path = vec![0usize; rows];
            path[rows - 1] = c;
            for r in (0..rows - 1).rev() {
                let (a, b) = (c.saturating_sub(1).max(lo), (c + 1).min(hi));
                c = (a..=b)
                    .min_by(|&x, &y| {
                        acc[r * cols + x]
                            .total_cmp(&acc[r * cols + y])
                            .then(x.cmp(&y))
                    })
                    .unwrap_or(c);
                path[r] = c;
            }
            Cut { path, cost }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dp_finds_the_zero_valley_greedy_misses() {
        // A zero-error path that bends away from the cheapest first-row cell.
        let (rows, cols) = (6, 5);
        let mut e = vec![10.0f32; rows * cols];
        e[0] = 0.5; // greedy start (cheapest in row 0), then only expensive cells below it
        let valley = [3, 3, 4, 4, 3, 2];
        for (r, &c) in valley.iter().enumerate() {
            e[r * cols + c] = 1.0;
        }
        let dp = min_error_cut(&e, rows, cols, 0, cols - 1, CutMethod::DynamicProgramming).unwrap();
        let gr = min_error_cut(&e, rows, cols, 0, cols - 1, CutMethod::Greedy).unwrap();
        assert_eq!(dp.path, valley);
        assert!((dp.cost - 6.0).abs() < 1e-9);
        assert!(gr.cost > dp.cost);
        for w in dp.path.windows(2) {
            assert!(w[0].abs_diff(w[1]) <= 1);
        }
    }
}
