//! Measures of how a carved surface looks, to catch artefacts a hillshade shows: the share of
//! downward-facing area (overhangs and undercuts) and the small closed pits of the top surface
//! ("bubble-wrap" of isolated round carvings), and the openings carvings make through the
//! DEM's surface with their elongation ([`surface_openings`]: round holes versus slots).

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use rayon::prelude::*;

use crate::math::{V3, mul, normalize, sub};
use crate::mesh::Mesh;
use crate::scene::Scene;

/// Look of a mesh's surface ([`surface_look`]).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct SurfaceLook {
    /// Share of the mesh area whose normal points down (`n_z < -0.2`): overhangs, undercuts,
    /// cave ceilings and the upper rims of dents in walls.
    pub downward_share: f32,
    /// Closed depressions of the top surface deeper than `min_depth` and at most `max_cells`
    /// raster cells in area: the round pits left by isolated carvings.
    pub small_pits: usize,
    /// All closed depressions deeper than `min_depth`.
    pub pits: usize,
    /// Raster of the top surface: columns along x and y.
    pub raster: [usize; 2],
}

/// Measures `mesh`: the downward-facing area share, and the closed depressions of its top
/// surface rasterised at `cell` metres (highest vertex per cell, empty cells filled from their
/// neighbours) deeper than `min_depth` metres; those of at most `max_cells` cells are `small_pits`.
/// Triangles within `cell` of the mesh's lowest point (a closing floor) are left out of the area.
/// Depressions touching the raster border drain out and are not counted.
pub fn surface_look(mesh: &Mesh, cell: f32, min_depth: f32, max_cells: usize) -> SurfaceLook {
    let mut out = SurfaceLook::default();
    let (mut total, mut down) = (0.0f64, 0.0f64);
    // The closing floor of an implicitised DEM (the lowest `cell` of the mesh) is not terrain.
    let zmin = mesh
        .positions
        .iter()
        .fold(f32::INFINITY, |m, p| m.min(p[2]));
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|k| mesh.positions[k as usize]);
        if a[2].max(b[2]).max(c[2]) < zmin + cell {
            continue;
        }
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let area = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt() as f64;
        if area.is_nan() || area <= 0.0 {
            continue;
        }
        total += area;
        if (n[2] as f64) < -0.2 * area {
            down += area;
        }
    }
    if total > 0.0 {
        out.downward_share = (down / total) as f32;
    }
    if mesh.positions.is_empty() || !(cell.is_finite() && cell > 0.0) {
        return out;
    }
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for p in &mesh.positions {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let nx = (((hi[0] - lo[0]) / cell).floor() as usize + 1).min(4096);
    let ny = (((hi[1] - lo[1]) / cell).floor() as usize + 1).min(4096);
    out.raster = [nx, ny];
    let mut z = vec![f32::NEG_INFINITY; nx * ny];
    for p in &mesh.positions {
        let j = (((p[0] - lo[0]) / cell) as usize).min(nx - 1);
        let i = (((p[1] - lo[1]) / cell) as usize).min(ny - 1);
        z[i * nx + j] = z[i * nx + j].max(p[2]);
    }
    // Empty cells (finer raster than the mesh): the highest of their filled neighbours, twice.
    for _ in 0..2 {
        let prev = z.clone();
        for i in 0..ny {
            for j in 0..nx {
                if prev[i * nx + j] > f32::NEG_INFINITY {
                    continue;
                }
                let mut m = f32::NEG_INFINITY;
                for (dj, di) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (jj, ii) = (j as i64 + dj, i as i64 + di);
                    if jj >= 0 && ii >= 0 && (jj as usize) < nx && (ii as usize) < ny {
                        m = m.max(prev[ii as usize * nx + jj as usize]);
                    }
                }
                z[i * nx + j] = m;
            }
        }
    }
    let floor = z
        .iter()
        .cloned()
        .filter(|v| v.is_finite())
        .fold(f32::INFINITY, f32::min);
    for v in &mut z {
        if !v.is_finite() {
            *v = floor;
        }
    }
    // Priority flood from the border: `w` is the water level that fills every depression.
    let mut w = vec![f32::NAN; nx * ny];
    let mut heap: BinaryHeap<Reverse<(OrdF32, usize)>> = BinaryHeap::new();
    for i in 0..ny {
        for j in 0..nx {
            if i == 0 || j == 0 || i == ny - 1 || j == nx - 1 {
                w[i * nx + j] = z[i * nx + j];
                heap.push(Reverse((OrdF32(z[i * nx + j]), i * nx + j)));
            }
        }
    }
    while let Some(Reverse((OrdF32(level), k))) = heap.pop() {
        for q in neighbours4(k, nx, ny) {
            if !w[q].is_nan() {
                continue;
            }
            w[q] = z[q].max(level);
            heap.push(Reverse((OrdF32(w[q]), q)));
        }
    }
    // Connected components of flooded cells; a pit counts when its deepest water exceeds
    // `min_depth`.
    let mut seen = vec![false; nx * ny];
    let mut stack = Vec::new();
    for s in 0..nx * ny {
        if seen[s] || w[s] - z[s] <= 0.0 {
            continue;
        }
        seen[s] = true;
        stack.push(s);
        let (mut n, mut deepest) = (0usize, 0.0f32);
        while let Some(k) = stack.pop() {
            n += 1;
            deepest = deepest.max(w[k] - z[k]);
            for q in neighbours4(k, nx, ny) {
                if !seen[q] && w[q] - z[q] > 0.0 {
                    seen[q] = true;
                    stack.push(q);
                }
            }
        }
        if deepest > min_depth {
            out.pits += 1;
            if n <= max_cells {
                out.small_pits += 1;
            }
        }
    }
    out
}

/// Total order on finite `f32` for the flood's heap.
#[derive(Debug, Clone, Copy, PartialEq)]
struct OrdF32(f32);
impl Eq for OrdF32 {}
impl PartialOrd for OrdF32 {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for OrdF32 {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&o.0)
    }
}

/// The 4-neighbours of cell `k` of a row-major `nx x ny` grid that lie inside it (west, east,
/// north, south).
/// Openings of a carved scene through its DEM's surface ([`surface_openings`]).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct Openings {
    /// Openings of at least the requested number of samples.
    pub count: usize,
    /// Per opening (in raster order of their first sample): its elongation, the square root of
    /// the ratio of the two largest eigenvalues of its samples' 3D covariance (1 = round, 2 =
    /// twice as long as wide).
    pub aspects: Vec<f32>,
    /// Per opening: its number of samples.
    pub samples: Vec<usize>,
}

impl Openings {
    /// Median of [`Openings::aspects`] (`None` without openings).
    pub fn median_aspect(&self) -> Option<f32> {
        let mut a = self.aspects.clone();
        a.sort_by(f32::total_cmp);
        a.get(a.len() / 2).copied()
    }
}

/// Where `scene` is air `depth` metres under its DEM's surface (along the surface normal, so
/// cliffs count), sampled every `step` metres in x and y: the openings a carving makes in the
/// surface, as 4-connected patches of at least `min_samples` samples, with their elongation.
/// `None` when the scene has no DEM. Deterministic (rows in parallel, collected in order).
pub fn surface_openings(
    scene: &Scene,
    step: f32,
    depth: f32,
    min_samples: usize,
) -> Option<Openings> {
    let f = scene.dem_frame()?;
    let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
    if !(step.is_finite() && step > 0.0) {
        return Some(Openings::default());
    }
    let nx = ((xm / step) as usize + 1).min(8192);
    let ny = ((ym / step) as usize + 1).min(8192);
    let g = |x: f32, y: f32| scene.dem_height(x.clamp(0.0, xm), y.clamp(0.0, ym));
    // The sample under the surface point above (x, y), or None on the DEM's border (its
    // walls are the slab's sides, not the surface).
    let point = |x: f32, y: f32| -> Option<V3> {
        if x < step || y < step || x > xm - step || y > ym - step {
            return None;
        }
        let z = g(x, y)?;
        let dzdx = (g(x + step, y)? - g(x - step, y)?) / (2.0 * step);
        let dzdy = (g(x, y + step)? - g(x, y - step)?) / (2.0 * step);
        let n = normalize([-dzdx, -dzdy, 1.0]);
        Some(sub([x, y, z], mul(n, depth)))
    };
    let pts: Vec<Option<V3>> = (0..ny)
        .into_par_iter()
        .flat_map_iter(|i| {
            (0..nx).map(move |j| {
                let p = point(j as f32 * step, i as f32 * step)?;
                (!scene.inside(p)).then_some(p)
            })
        })
        .collect();
    let mut seen = vec![false; nx * ny];
    let mut out = Openings::default();
    for k0 in 0..nx * ny {
        if seen[k0] || pts[k0].is_none() {
            continue;
        }
        seen[k0] = true;
        let (mut stack, mut patch) = (vec![k0], Vec::new());
        while let Some(k) = stack.pop() {
            patch.push(pts[k].unwrap_or_default());
            for q in neighbours4(k, nx, ny) {
                if !seen[q] && pts[q].is_some() {
                    seen[q] = true;
                    stack.push(q);
                }
            }
        }
        if patch.len() >= min_samples.max(3) {
            out.count += 1;
            out.aspects.push(elongation(&patch));
            out.samples.push(patch.len());
        }
    }
    Some(out)
}

/// Square root of the ratio of the two largest eigenvalues of the points' covariance.
fn elongation(pts: &[V3]) -> f32 {
    let n = pts.len() as f64;
    let mut m = [0.0f64; 3];
    for p in pts {
        for k in 0..3 {
            m[k] += p[k] as f64 / n;
        }
    }
    let mut c = [[0.0f64; 3]; 3];
    for p in pts {
        let d = [0, 1, 2].map(|k| p[k] as f64 - m[k]);
        for a in 0..3 {
            for b in 0..3 {
                c[a][b] += d[a] * d[b] / n;
            }
        }
    }
    let mut e = sym3_eigenvalues(c);
    e.sort_by(|a, b| b.total_cmp(a));
    if e[1] <= 1e-12 * e[0].max(1e-30) {
        return f32::INFINITY;
    }
    (e[0] / e[1]).sqrt() as f32
}

/// Eigenvalues of a symmetric 3 x 3 matrix by cyclic Jacobi rotations.
fn sym3_eigenvalues(mut a: [[f64; 3]; 3]) -> [f64; 3] {
    for _ in 0..32 {
        let off = a[0][1].powi(2) + a[0][2].powi(2) + a[1][2].powi(2);
        if off < 1e-24 * (a[0][0].powi(2) + a[1][1].powi(2) + a[2][2].powi(2)).max(1e-300) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() < 1e-300 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let (c, s) = (1.0 / (t * t + 1.0).sqrt(), t / (t * t + 1.0).sqrt());
            // a <- J^T a J with the rotation J in the (p, q) plane.
            for k in 0..3 {
                let (akp, akq) = (a[k][p], a[k][q]);
                a[k][p] = c * akp - s * akq;
                a[k][q] = s * akp + c * akq;
            }
            for k in 0..3 {
                let (apk, aqk) = (a[p][k], a[q][k]);
                a[p][k] = c * apk - s * aqk;
                a[q][k] = s * apk + c * aqk;
            }
        }
    }
    [a[0][0], a[1][1], a[2][2]]
}

fn neighbours4(k: usize, nx: usize, ny: usize) -> impl Iterator<Item = usize> {
    let (i, j) = (k / nx, k % nx);
    [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
        .into_iter()
        .filter_map(move |(dj, di)| {
            let (jj, ii) = (j as i64 + dj, i as i64 + di);
            let inside = jj >= 0 && ii >= 0 && (jj as usize) < nx && (ii as usize) < ny;
            inside.then(|| ii as usize * nx + jj as usize)
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grid mesh of `z(x, y)` (top only: enough for the raster and the normals).
    fn grid(n: usize, z: impl Fn(f32, f32) -> f32) -> Mesh {
        let mut m = Mesh::default();
        for i in 0..n {
            for j in 0..n {
                m.positions
                    .push([j as f32, i as f32, z(j as f32, i as f32)]);
            }
        }
        for i in 0..n - 1 {
            for j in 0..n - 1 {
                let k = (i * n + j) as u32;
                let n = n as u32;
                m.triangles.push([k, k + 1, k + n + 1]);
                m.triangles.push([k, k + n + 1, k + n]);
            }
        }
        m
    }

    #[test]
    fn openings_tell_a_round_hole_from_a_slot() {
        use crate::scene::{ImplicitizeSettings, SceneBuilder};
        let hf = relief_heightfield::Heightfield::from_fn(41, 41, 5.0, 5.0, |_, _| 50.0);
        let geo = crate::geology::Geology::layered_default([100.0, 100.0, 40.0], 10.0, 1).unwrap();
        let mut b = SceneBuilder::new(&hf, geo, &ImplicitizeSettings::default()).unwrap();
        let none = surface_openings(&b.clone().build(true).unwrap(), 1.0, 0.5, 4).unwrap();
        assert_eq!(none.count, 0);
        let t = b.tree_mut();
        let round = t.sphere([50.0, 50.0, 50.0], 12.0, -3.0).unwrap();
        let slot = t
            .ellipsoid([140.0, 140.0, 50.0], [24.0, 8.0, 8.0], -3.0)
            .unwrap();
        b.add_carving(round);
        b.add_carving(slot);
        let scene = b.build(true).unwrap();
        let o = surface_openings(&scene, 1.0, 0.5, 4).unwrap();
        assert_eq!(o.count, 2, "{o:?}");
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            assert_eq!(
                pool.install(|| surface_openings(&scene, 1.0, 0.5, 4)),
                Some(o.clone())
            );
        }
        assert!((o.aspects[0] - 1.0).abs() < 0.15, "{o:?}");
        assert!(o.aspects[1] > 2.5, "{o:?}");
        assert_eq!(o.median_aspect(), Some(o.aspects[1]));
    }

    #[test]
    fn counts_round_pits_and_not_a_groove_open_to_the_border() {
        let flat = grid(40, |_, _| 10.0);
        let l = surface_look(&flat, 1.0, 0.1, 20);
        assert_eq!((l.pits, l.small_pits, l.downward_share), (0, 0, 0.0));
        // Four round dents of radius 2 and depth 1.
        let pits = grid(40, |x, y| {
            let mut z = 10.0f32;
            for (cx, cy) in [(8.0, 8.0), (30.0, 8.0), (8.0, 30.0), (30.0, 30.0)] {
                let d = ((x - cx) * (x - cx) + (y - cy) * (y - cy)).sqrt();
                if d < 2.0 {
                    z -= 1.0 - d / 2.0;
                }
            }
            z
        });
        let l = surface_look(&pits, 1.0, 0.1, 20);
        assert_eq!((l.pits, l.small_pits), (4, 4), "{l:?}");
        // A long groove reaching the border drains: no pit.
        let groove = grid(40, |_, y| if (y - 20.0).abs() < 2.0 { 9.0 } else { 10.0 });
        let l = surface_look(&groove, 1.0, 0.1, 20);
        assert_eq!(l.pits, 0, "{l:?}");
        // Upside-down triangles count as downward-facing (a ramp: a flat mesh is all floor).
        let mut flipped = grid(40, |x, _| x);
        for t in &mut flipped.triangles {
            t.swap(1, 2);
        }
        assert!((surface_look(&flipped, 1.0, 0.1, 20).downward_share - 1.0).abs() < 1e-6);
    }
}
