//! Differential terrain attributes that respect non-square cells: gradient, slope, normals and
//! hillshade. Derivatives are central differences (one-sided at the edges) with the east-west
//! spacing `cell_x` and north-south spacing `cell_y`. Row 0 is north, so `dz/dy` here is the
//! derivative towards the *south*; normals are returned in an east-north-up frame.

use ndarray::Array2;
use rayon::prelude::*;

use crate::grid::Heightfield;

/// Gradient `(dz/dx east, dz/dy north)` in metres per metre at cell `(x, y)`.
pub fn gradient_at(hf: &Heightfield, x: usize, y: usize) -> (f32, f32) {
    let (w, h) = (hf.width(), hf.height());
    let (cx, cy) = hf.cell_size();
    let (xl, xr) = (x.saturating_sub(1), (x + 1).min(w - 1));
    let (yu, yd) = (y.saturating_sub(1), (y + 1).min(h - 1));
    let gx = if xr > xl {
        (hf.get(xr, y) - hf.get(xl, y)) / ((xr - xl) as f64 * cx) as f32
    } else {
        0.0
    };
    // Rows grow southwards, so north-pointing derivative is (up - down).
    let gy = if yd > yu {
        (hf.get(x, yu) - hf.get(x, yd)) / ((yd - yu) as f64 * cy) as f32
    } else {
        0.0
    };
    (gx, gy)
}

/// Gradient field: two arrays `(dz/dx east, dz/dy north)`.
pub fn gradient(hf: &Heightfield) -> (Array2<f32>, Array2<f32>) {
    let (w, h) = (hf.width(), hf.height());
    let mut gx = Array2::zeros((h, w));
    let mut gy = Array2::zeros((h, w));
    gx.as_slice_mut()
        .expect("standard layout")
        .par_chunks_mut(w)
        .zip(
            gy.as_slice_mut()
                .expect("standard layout")
                .par_chunks_mut(w),
        )
        .enumerate()
        .for_each(|(y, (rx, ry))| {
            for x in 0..w {
                let (a, b) = gradient_at(hf, x, y);
                rx[x] = a;
                ry[x] = b;
            }
        });
    (gx, gy)
}

/// Slope angle in degrees at every cell.
pub fn slope_degrees(hf: &Heightfield) -> Array2<f32> {
    let (gx, gy) = gradient(hf);
    ndarray::Zip::from(&gx)
        .and(&gy)
        .map_collect(|a, b| a.hypot(*b).atan().to_degrees())
}

/// Unit surface normals `[east, north, up]` at every cell, row-major.
pub fn normals(hf: &Heightfield) -> Vec<[f32; 3]> {
    let (gx, gy) = gradient(hf);
    gx.iter()
        .zip(gy.iter())
        .map(|(a, b)| {
            let n = (a * a + b * b + 1.0).sqrt();
            [-a / n, -b / n, 1.0 / n]
        })
        .collect()
}

/// Lambertian hillshade in `[0, 1]` with the light from `azimuth_deg` (clockwise from north)
/// at `altitude_deg` above the horizon; `z_factor` exaggerates heights. Voids give 0.
pub fn hillshade(
    hf: &Heightfield,
    azimuth_deg: f32,
    altitude_deg: f32,
    z_factor: f32,
) -> Array2<f32> {
    let (gx, gy) = gradient(hf);
    let az = azimuth_deg.to_radians();
    let alt = altitude_deg.to_radians();
    // Light direction in east-north-up.
    let l = [az.sin() * alt.cos(), az.cos() * alt.cos(), alt.sin()];
    ndarray::Zip::from(&gx).and(&gy).map_collect(|a, b| {
        let (a, b) = (a * z_factor, b * z_factor);
        let n = (a * a + b * b + 1.0).sqrt();
        let d = (-a * l[0] - b * l[1] + l[2]) / n;
        if d.is_finite() { d.max(0.0) } else { 0.0 }
    })
}

/// 5-point Laplacian of the interior cells (m / m^2, true cell sizes).
pub fn laplacian(hf: &Heightfield) -> Vec<f64> {
    let (w, h) = (hf.width(), hf.height());
    let (cx, cy) = hf.cell_size();
    let z = hf.as_slice();
    let mut out = Vec::with_capacity(w.saturating_sub(2) * h.saturating_sub(2));
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            let c = z[y * w + x] as f64;
            let dx = z[y * w + x - 1] as f64 + z[y * w + x + 1] as f64 - 2.0 * c;
            let dy = z[(y - 1) * w + x] as f64 + z[(y + 1) * w + x] as f64 - 2.0 * c;
            out.push(dx / (cx * cx) + dy / (cy * cy));
        }
    }
    out
}
