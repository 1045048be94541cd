//! Tests of the erosion models: one step against fastscapelib, steady state, network
//! statistics, determinism over thread counts, the Newton solver, lakes and diffusion.

use relief_heightfield::NoProgress;
use relief_heightfield::rng::{hash, unit_f64};

use super::stream_power::newton_drop;
use super::*;
use crate::LandscapeError;
use crate::depression::{FillMode, priority_flood};
use crate::flow::{flow_order, receiver, steepest_descent};
use crate::grid::Grid;

/// Reads a little-endian `f64` C-order `.npy` file: `(rows, cols, values)`.
fn read_npy(path: &str) -> (usize, usize, Vec<f64>) {
    let b = std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    assert_eq!(&b[..6], b"\x93NUMPY", "{path}: not a .npy file");
    let (len, start) = match b[6] {
        1 => (u16::from_le_bytes([b[8], b[9]]) as usize, 10),
        _ => (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12),
    };
    let header = std::str::from_utf8(&b[start..start + len]).unwrap();
    assert!(header.contains("'descr': '<f8'") && header.contains("'fortran_order': False"));
    let shape = &header[header.find("'shape': (").unwrap() + 10..];
    let dims: Vec<usize> = shape[..shape.find(')').unwrap()]
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let data: Vec<f64> = b[start + len..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(data.len(), dims[0] * dims[1], "{path}: truncated");
    (dims[0], dims[1], data)
}

fn data(name: &str) -> String {
    format!("{}/tests/data/{name}.npy", env!("CARGO_MANIFEST_DIR"))
}

/// A flat plateau at `base` with uniform noise in `[0, amplitude)` m (counter-based, seeded).
fn noisy_plateau(grid: &Grid, base: f64, amplitude: f64, seed: u64) -> Vec<f64> {
    (0..grid.len())
        .map(|i| base + amplitude * unit_f64(hash(seed, i as u64, 0, 0)))
        .collect()
}

fn square(w: usize, h: usize, cell: f64) -> Grid {
    Grid::new(w, h, cell, cell)
}

fn max_rel_diff(got: &[f64], want: &[f64]) -> f64 {
    got.iter()
        .zip(want)
        .map(|(g, w)| (g - w).abs() / w.abs().max(f64::MIN_POSITIVE))
        .fold(0.0, f64::max)
}

/// The references were made once by `tests/data/make_stream_power.py` with fastscapelib 0.3.0
/// (pit-free input, so its MST sink resolver is plain D8 as here).
#[test]
fn one_step_matches_fastscapelib_on_non_square_cells() {
    let (rows, cols, input) = read_npy(&data("spl_in"));
    let grid = Grid::new(cols, rows, 100.0, 80.0);
    let base = base_level_mask(&input, &grid);
    for (name, n, diffusion) in [
        ("spl_n1", 1.0, 0.0),
        ("spl_n1_kd001", 1.0, 0.01),
        ("spl_n1_kd2", 1.0, 2.0),
        ("spl_n15_kd001", 1.5, 0.01),
    ] {
        let (_, _, want) = read_npy(&data(name));
        let params = StreamPowerParams {
            k: 2e-4,
            m: 0.4,
            n,
            diffusion,
            dt: 1e3,
            tolerance: 1e-5,
            channel_area_m2: 0.0,
        };
        let mut z = input.clone();
        let f = step(&mut z, &grid, &base, &params, Uplift::Constant(1e-3)).unwrap();
        assert_eq!((f.pits, f.limited), (0, 0), "{name}");
        assert!(f.max_incision > 0.2, "{name}: incision {}", f.max_incision);
        let rel = max_rel_diff(&z, &want);
        assert!(rel < 1e-6, "{name}: max relative difference {rel:e}");
    }
}

/// The receiver slope of every free cell with a receiver on `z`, and its drainage area (m^2),
/// on the D8 graph of `z` uplifted by `uplift` (pit-free): the graph of the last step.
fn slope_area(z: &[f64], grid: &Grid, uplift: f64) -> Vec<(f64, f64)> {
    let outlet = base_level_mask(z, grid);
    let lifted: Vec<f64> = (0..grid.len())
        .map(|i| if outlet[i] { z[i] } else { z[i] + uplift })
        .collect();
    let dir = steepest_descent(&lifted, grid, &outlet);
    let order = flow_order(grid, &dir, |_| true);
    let mut area = vec![grid.cell_area(); grid.len()];
    for &c in &order {
        if let Some(r) = receiver(grid, c as usize, dir[c as usize]) {
            area[r] += area[c as usize];
        }
    }
    let dist = grid.distances();
    (0..grid.len())
        .filter(|&i| !outlet[i])
        .filter_map(|i| {
            receiver(grid, i, dir[i]).map(|r| ((z[i] - z[r]) / dist[dir[i] as usize], area[i]))
        })
        .collect()
}

/// Least-squares slope of `y` on `x`.
fn fit_slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    sxy / sxx
}

#[test]
fn steady_state_follows_the_slope_area_relation() {
    let grid = square(64, 64, 100.0);
    let mut z = noisy_plateau(&grid, 0.0, 1.0, 11);
    let base = base_level_mask(&z, &grid);
    let params = StreamPowerParams {
        k: 1e-4,
        m: 0.45,
        n: 1.0,
        diffusion: 0.0,
        dt: 2e4,
        tolerance: 1e-5,
        channel_area_m2: 0.0,
    };
    let u = 1e-3;
    let f = run(
        &mut z,
        &grid,
        &base,
        &params,
        Uplift::Constant(u),
        300,
        &NoProgress,
        &|| false,
    )
    .unwrap();
    assert_eq!(f.last.pits, 0);
    let channels: Vec<(f64, f64)> = slope_area(&z, &grid, u * params.dt)
        .into_iter()
        .filter(|&(_, a)| a >= 10.0 * grid.cell_area())
        .map(|(s, a)| (a.ln(), s.ln()))
        .collect();
    assert!(channels.len() > 100, "{} channel cells", channels.len());
    let concavity = -fit_slope(&channels);
    assert!((concavity - params.m).abs() < 0.05, "concavity {concavity}");
    // The steepness k_s = S A^(m/n) is (U/K)^(1/n) on every channel cell.
    for &(ln_a, ln_s) in &channels {
        let ks = (ln_s + params.m * ln_a).exp();
        assert!((ks / (u / params.k) - 1.0).abs() < 1e-6, "steepness {ks}");
    }
}

/// The drainage-area exceedance exponent of `shared/tools/terrain_quality.py` `drainage()`:
/// priority-flood+epsilon, D8 areas, the cells two away from the edge, a least-squares fit of
/// log P(A >= a) on log a over 10..1000 cells.
fn exceedance_beta(z: &[f64], grid: &Grid) -> f64 {
    let mut f = z.to_vec();
    priority_flood(&mut f, grid, FillMode::Epsilon, None);
    let dir = steepest_descent(&f, grid, &base_level_mask(&f, grid));
    let order = flow_order(grid, &dir, |_| true);
    let mut area = vec![grid.cell_area(); grid.len()];
    for &c in &order {
        if let Some(r) = receiver(grid, c as usize, dir[c as usize]) {
            area[r] += area[c as usize];
        }
    }
    let (w, h) = (grid.width, grid.height);
    let mut a: Vec<f64> = (2..h - 2)
        .flat_map(|y| (2..w - 2).map(move |x| y * w + x))
        .map(|i| area[i])
        .collect();
    a.sort_by(f64::total_cmp);
    let n = a.len() as f64;
    let cell = grid.cell_area();
    let points: Vec<(f64, f64)> = a
        .iter()
        .enumerate()
        .filter(|&(_, &v)| (10.0 * cell..=1000.0 * cell).contains(&v))
        .map(|(k, &v)| (v.ln(), (1.0 - k as f64 / n).ln()))
        .collect();
    -fit_slope(&points)
}

/// The block drains to its south edge (a range front; the other edges are closed): with all
/// four edges at base level the basins are at most ~64 cells long and the finite-size cut-off
/// of the exceedance steepens the fit over 10..1000 cells to beta ~0.60.
#[test]
fn an_uplifted_block_grows_a_dendritic_network() {
    let grid = square(128, 128, 100.0);
    let mut z = noisy_plateau(&grid, 0.0, 1.0, 3);
    let base: Vec<bool> = (0..grid.len()).map(|i| i / 128 == 127).collect();
    let params = StreamPowerParams {
        k: 1e-4,
        dt: 1e4,
        ..Default::default()
    };
    run(
        &mut z,
        &grid,
        &base,
        &params,
        Uplift::Constant(1e-3),
        100,
        &NoProgress,
        &|| false,
    )
    .unwrap();
    let beta = exceedance_beta(&z, &grid);
    assert!((0.4..=0.5).contains(&beta), "beta {beta}");
}

fn run_on_threads(threads: usize) -> Vec<u64> {
    let grid = square(96, 80, 30.0);
    let mut z = noisy_plateau(&grid, 100.0, 5.0, 5);
    z[40 * 96 + 40] = f64::NAN;
    let base = base_level_mask(&z, &grid);
    let params = StreamPowerParams {
        k: 1e-4,
        n: 1.3,
        diffusion: 0.5,
        ..Default::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        run(
            &mut z,
            &grid,
            &base,
            &params,
            Uplift::Constant(2e-3),
            12,
            &NoProgress,
            &|| false,
        )
        .unwrap()
    });
    z.iter().map(|v| v.to_bits()).collect()
}

#[test]
fn identical_bytes_on_one_and_two_threads() {
    assert_eq!(run_on_threads(1), run_on_threads(2));
}

#[test]
fn newton_converges_and_erodes_less_on_gentle_slopes() {
    for n in [1.5, 0.6, 2.5] {
        for f in [1e-4, 0.03, 1.0, 40.0] {
            for d0 in [1e-3, 0.2, 3.0, 150.0] {
                let tol = 1e-5;
                let d = newton_drop(f, n, d0, tol);
                let residual = d + f * d.powf(n) - d0;
                assert!(d > 0.0 && d <= d0, "n {n} f {f} d0 {d0}: {d}");
                assert!(
                    residual.abs() <= tol,
                    "n {n} f {f} d0 {d0}: residual {residual}"
                );
            }
        }
    }
    // A gentle slope (at most 0.02): S^1.5 < S, so every cell erodes less with n = 1.5.
    let grid = square(40, 30, 100.0);
    let mut z0: Vec<f64> = (0..grid.len())
        .map(|i| {
            let (x, y) = ((i % 40) as f64, (i / 40) as f64);
            0.5 * x.min(39.0 - x).min(y).min(29.0 - y) + 0.4 * unit_f64(hash(9, i as u64, 0, 0))
        })
        .collect();
    let base = base_level_mask(&z0, &grid);
    let erosion = |n: f64, z0: &mut Vec<f64>| {
        let params = StreamPowerParams {
            k: 5e-4,
            n,
            diffusion: 0.0,
            ..Default::default()
        };
        let mut z = z0.clone();
        let f = step(&mut z, &grid, &base, &params, Uplift::Constant(0.0)).unwrap();
        (
            z0.iter().zip(&z).map(|(a, b)| a - b).collect::<Vec<f64>>(),
            f,
        )
    };
    let (e1, _) = erosion(1.0, &mut z0);
    let (e15, f15) = erosion(1.5, &mut z0);
    assert_eq!(f15.pits, 0);
    for i in 0..grid.len() {
        assert!(
            e15[i] <= e1[i] + 1e-12 && e15[i] >= 0.0,
            "cell {i}: {} vs {}",
            e15[i],
            e1[i]
        );
    }
    let (s1, s15): (f64, f64) = (e1.iter().sum(), e15.iter().sum());
    assert!(s15 > 0.0 && s15 < 0.5 * s1, "total erosion {s15} vs {s1}");
}

#[test]
fn a_lake_drains_over_its_spill_point_without_eroding_its_floor() {
    // A plane tilted to the west edge with a closed bowl of 3 x 3 cells 2 m deep.
    let grid = square(12, 9, 100.0);
    let mut z: Vec<f64> = (0..grid.len())
        .map(|i| 0.1 * (i % 12) as f64 + 1.0)
        .collect();
    for y in 3..6 {
        for x in 6..9 {
            z[y * 12 + x] -= 2.0;
        }
    }
    let before = z.clone();
    let base = base_level_mask(&z, &grid);
    let params = StreamPowerParams {
        k: 1e-3,
        diffusion: 0.0,
        ..Default::default()
    };
    let f = step(&mut z, &grid, &base, &params, Uplift::Constant(0.0)).unwrap();
    assert_eq!((f.pits, f.lake_cells), (3, 9));
    // The lowest cells of the bowl drain to the (higher) spill point and are not eroded; the
    // others erode at most down to their receiver: nothing goes below the bowl's floor.
    for y in 3..6 {
        assert_eq!(z[y * 12 + 6], before[y * 12 + 6], "lake bottom (6, {y})");
        for x in 7..9 {
            assert!(z[y * 12 + x] >= before[3 * 12 + 6], "lake floor ({x}, {y})");
        }
    }
    // Downstream of the spill point (west of the bowl) the channel carries the bowl's area:
    // it erodes more than any cell of the plane without the bowl.
    let mut plane: Vec<f64> = (0..grid.len())
        .map(|i| 0.1 * (i % 12) as f64 + 1.0)
        .collect();
    step(&mut plane, &grid, &base, &params, Uplift::Constant(0.0)).unwrap();
    let column = |z: &[f64], x: usize| {
        (1..8)
            .map(|y| 0.1 * x as f64 + 1.0 - z[y * 12 + x])
            .fold(0.0, f64::max)
    };
    assert!(column(&z, 3) > 1.2 * column(&plane, 3));
    assert!(z.iter().all(|v| v.is_finite()));
}

#[test]
fn diffusion_conserves_volume_with_closed_edges_and_keeps_fixed_cells_and_voids() {
    let grid = Grid::new(37, 23, 10.0, 7.0);
    let mut z = noisy_plateau(&grid, 50.0, 10.0, 1);
    let none = vec![false; grid.len()];
    let before: f64 = z.iter().sum();
    let mut scratch = DiffusionScratch::new();
    diffuse(&mut z, &grid, &none, 5.0, 10.0, &mut scratch).unwrap();
    let after: f64 = z.iter().sum();
    assert!(
        (after - before).abs() < 1e-9 * before,
        "{before} -> {after}"
    );
    // Voids stay voids and leak nowhere; fixed cells keep their value.
    z[5 * 37 + 5] = f64::NAN;
    let mut fixed = none.clone();
    fixed[10 * 37 + 20] = true;
    let kept = z[10 * 37 + 20];
    diffuse(&mut z, &grid, &fixed, 5.0, 10.0, &mut scratch).unwrap();
    assert!(z[5 * 37 + 5].is_nan());
    assert_eq!(z[10 * 37 + 20], kept);
    assert_eq!(z.iter().filter(|v| v.is_nan()).count(), 1);
    assert!(diffuse(&mut z, &grid, &fixed, -1.0, 10.0, &mut scratch).is_err());
}

#[test]
fn diffusion_decays_a_sine_mode_at_the_analytic_rate() {
    // z = sin(pi x / L) sin(pi y / H) with fixed edges decays as exp(-D pi^2 (1/L^2 + 1/H^2) t).
    let (w, h) = (65, 49);
    let grid = Grid::new(w, h, 10.0, 8.0);
    let (lx, ly) = ((w - 1) as f64 * 10.0, (h - 1) as f64 * 8.0);
    let pi = std::f64::consts::PI;
    let mut z: Vec<f64> = (0..grid.len())
        .map(|i| {
            let (x, y) = ((i % w) as f64 * 10.0, (i / w) as f64 * 8.0);
            (pi * x / lx).sin() * (pi * y / ly).sin()
        })
        .collect();
    let z0 = z.clone();
    let fixed: Vec<bool> = (0..grid.len()).map(|i| grid.is_edge(i)).collect();
    let (d, dt, steps) = (1.0, 50.0, 40);
    let mut scratch = DiffusionScratch::new();
    for _ in 0..steps {
        diffuse(&mut z, &grid, &fixed, d, dt, &mut scratch).unwrap();
    }
    let want = (-d * pi * pi * (1.0 / (lx * lx) + 1.0 / (ly * ly)) * dt * steps as f64).exp();
    let centre = (h / 2) * w + w / 2;
    let got = z[centre] / z0[centre];
    assert!((got / want - 1.0).abs() < 0.01, "decay {got} vs {want}");
}

#[test]
fn params_are_checked() {
    assert!(StreamPowerParams::default().check().is_ok());
    let bad = StreamPowerParams {
        m: f64::NAN,
        ..Default::default()
    };
    assert_eq!(bad.check().unwrap_err().name, "m");
    let grid = square(8, 8, 10.0);
    let mut z = vec![1.0; 64];
    let base = vec![false; 64];
    let p = StreamPowerParams::default();
    assert!(step(&mut z, &grid, &base, &p, Uplift::Constant(1e-3)).is_err());
    let base = base_level_mask(&z, &grid);
    assert!(step(&mut z, &grid, &base, &p, Uplift::Raster(&[0.0; 3])).is_err());
    let stopped = run(
        &mut z,
        &grid,
        &base,
        &p,
        Uplift::Constant(1e-3),
        5,
        &NoProgress,
        &|| true,
    )
    .unwrap();
    assert!(stopped.stopped && stopped.steps == 0);
}

/// An erosion `run` (given the raster and its stop flag) asked to stop from the start ends
/// with [`LandscapeError::Stopped`] and leaves `z` as given.
pub(super) fn assert_stopping_leaves_the_input_alone<T: std::fmt::Debug>(
    mut z: Vec<f32>,
    run: impl FnOnce(&mut [f32], &dyn Fn() -> bool) -> Result<T, LandscapeError>,
) {
    let before = z.clone();
    let e = run(&mut z, &|| true);
    assert!(matches!(e, Err(LandscapeError::Stopped(_))), "{e:?}");
    assert_eq!(z, before);
}

#[test]
fn cells_above_the_channel_head_do_not_incise() {
    // No uplift, no diffusion: a cell changes only by incision. A 64 x 64 grid of 100 m
    // cells drains 4.1e7 m^2 in all; each cell 1e4 m^2.
    let grid = square(64, 64, 100.0);
    let z0 = noisy_plateau(&grid, 0.0, 1.0, 11);
    let base = base_level_mask(&z0, &grid);
    let changed = |channel_area_m2: f64| {
        let params = StreamPowerParams {
            k: 1e-4,
            diffusion: 0.0,
            dt: 1e3,
            channel_area_m2,
            ..StreamPowerParams::default()
        };
        let mut z = z0.clone();
        step(&mut z, &grid, &base, &params, Uplift::Constant(0.0)).unwrap();
        z.iter().zip(&z0).filter(|(a, b)| a != b).count()
    };
    let (all, some, none) = (changed(0.0), changed(2e5), changed(1e9));
    assert_eq!(none, 0);
    assert!(some > 0 && 2 * some < all, "{all} {some}");
}

/// Issue 40's bar on the shared DEMs: the default preset (mountain) leaves no pit the input
/// did not have and keeps the drainage-area exponent beta within 0.05 of the input's (the
/// crops of `examples/erode_look`; before channel heads and grid-sized rills alps_dem went
/// 0.637 -> 0.527).
#[test]
#[allow(clippy::print_stderr)]
fn the_default_preset_keeps_the_drainage_of_the_shared_dems() {
    use crate::erode::job::ErodeSettings;
    let crops: [relief_testdata::Crop<'_>; 4] = [
        ("grandcanyon", 0, 0, 512, 512),
        ("alps_dem", 1200, 120, 640, 512),
        ("N47E011", 300, 300, 512, 512),
        ("carrizo", 0, 200, 505, 512),
    ];
    let Some(dems) = relief_testdata::dem_crops(crops) else {
        return;
    };
    for ((id, ..), mut dem) in crops.into_iter().zip(dems) {
        if dem.has_voids() {
            relief_heightfield::fill::fill_voids(&mut dem, &Default::default()).unwrap();
        }
        let before = crate::stats::drainage(&dem);
        let r = ErodeSettings::default()
            .run(&dem, None, &relief_heightfield::NoProgress, &|| false)
            .unwrap();
        let after = crate::stats::drainage(&r.terrain);
        eprintln!(
            "{id}: beta {:.3} -> {:.3}, pits/km2 {:.2} -> {:.2}",
            before.beta, after.beta, before.pits_per_km2, after.pits_per_km2
        );
        assert!(
            (after.beta - before.beta).abs() <= 0.05,
            "{id}: beta {} -> {}",
            before.beta,
            after.beta
        );
        assert!(
            after.pits_per_km2 <= before.pits_per_km2 + 1e-9,
            "{id}: pits {} -> {}",
            before.pits_per_km2,
            after.pits_per_km2
        );
        // Visibly eroded: the channels are cut metres deep somewhere.
        assert!(r.figures.max_erosion_m > 1.0, "{id}: {:?}", r.figures);
    }
}
