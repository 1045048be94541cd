use relief_heightfield::NoProgress;
use relief_heightfield::rng::{hash, unit_f32};

use super::*;
use crate::erode::tests::assert_stopping_leaves_the_input_alone;
use crate::flow::{RouteOptions, route};

fn never() -> bool {
    false
}

fn run(z: &mut [f32], grid: &Grid, p: &HydraulicParams) -> HydraulicOutput {
    hydraulic(z, grid, p, &NoProgress, &never).unwrap()
}

/// A cone of `height` m over the grid with `noise` m of white noise per cell.
fn cone(grid: &Grid, height: f32, noise: f32, seed: u64) -> Vec<f32> {
    let (cx, cy) = (grid.width as f32 / 2.0, grid.height as f32 / 2.0);
    let r = cx.min(cy);
    (0..grid.len())
        .map(|i| {
            let (x, y) = ((i % grid.width) as f32 - cx, (i / grid.width) as f32 - cy);
            let n = unit_f32(hash(seed, i as u64, 0, 0)) - 0.5;
            height * (1.0 - (x * x + y * y).sqrt() / r).max(0.0) + noise * n
        })
        .collect()
}

fn volume(z: &[f32], grid: &Grid) -> f64 {
    z.iter()
        .filter(|v| !v.is_nan())
        .map(|&v| v as f64)
        .sum::<f64>()
        * grid.cell_area()
}

fn grid(width: usize, height: usize, cell: f64) -> Grid {
    Grid {
        width,
        height,
        cell_x: cell,
        cell_y: cell,
    }
}

#[test]
fn the_sediment_budget_closes() {
    // A bowl: a cone turned upside down, so most water and sediment stay on the map.
    let g = Grid::new(48, 40, 30.0, 40.0);
    let bowl: Vec<f32> = cone(&g, 300.0, 5.0, 1).iter().map(|v| 300.0 - v).collect();
    for settle in [false, true] {
        let mut z = bowl.clone();
        let p = HydraulicParams {
            settle,
            ..Default::default()
        };
        let out = run(&mut z, &g, &p);
        let f = out.figures;
        assert!(f.eroded_m3 > 1e4, "{f:?}");
        // Erosion minus deposition is what the water still holds plus what it took away.
        let budget = f.eroded_m3 - f.deposited_m3 - f.suspended_m3 - f.left_m3;
        assert!(budget.abs() < 1e-3 * f.eroded_m3, "{budget} {f:?}");
        // The rasters are the surface's change.
        let change = volume(&bowl, &g) - volume(&z, &g);
        assert!((change - (f.eroded_m3 - f.deposited_m3)).abs() < 1e-3 * f.eroded_m3);
        // A closed bowl keeps nearly all of it.
        assert!(f.left_m3 < 0.05 * f.eroded_m3, "{f:?}");
        assert_eq!(settle, f.suspended_m3 == 0.0, "{f:?}");
        assert!(out.erosion.iter().chain(&out.deposition).all(|&v| v >= 0.0));
        assert!(f.max_mass_fix < 0.5, "{f:?}");
    }
}

#[test]
fn one_and_two_threads_give_the_same_bytes() {
    let g = grid(70, 45, 30.0);
    let mut z0 = cone(&g, 400.0, 10.0, 2);
    z0[300] = f32::NAN;
    let p = HydraulicParams {
        iterations: 40,
        rain_fraction: 0.3,
        seed: 7,
        hardness_depth_m: 5.0,
        ..Default::default()
    };
    let go = |k: usize| {
        let mut z = z0.clone();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(k)
            .build()
            .unwrap();
        let out = pool.install(|| run(&mut z, &g, &p));
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        (
            bits(&z),
            bits(&out.erosion),
            bits(&out.deposition),
            out.figures,
        )
    };
    let (a, b) = (go(1), go(2));
    assert!(a.3.eroded_m3 > 0.0);
    assert_eq!(a, b);
}

#[test]
fn gullies_follow_the_flow_lines() {
    // A cone with noise: water gathers in the noise's hollows on the way down.
    let g = grid(96, 96, 30.0);
    let z0 = cone(&g, 600.0, 20.0, 3);
    let mut z = z0.clone();
    let out = run(&mut z, &g, &HydraulicParams::default());
    let area = route(z0.clone(), g, &RouteOptions::default()).accumulation(None);
    let cells = |a: f64| a / g.cell_area();
    // Mean erosion on the cells that drain 20 or more cells, against the ridges (cells nothing
    // drains into), away from the edge and the cone's flat rim.
    let (mut wet, mut dry) = ((0.0, 0), (0.0, 0));
    for i in 0..g.len() {
        if g.is_edge(i) || z0[i] < 50.0 {
            continue;
        }
        let e = out.erosion[i] as f64;
        if cells(area[i]) >= 20.0 {
            wet = (wet.0 + e, wet.1 + 1);
        } else if cells(area[i]) <= 1.0 {
            dry = (dry.0 + e, dry.1 + 1);
        }
    }
    let (wet, dry) = (wet.0 / wet.1 as f64, dry.0 / dry.1 as f64);
    assert!(wet > 2.0 * dry, "channels {wet} m, ridges {dry} m");
    assert!(out.figures.max_erosion_m > 1.0, "{:?}", out.figures);
}

#[test]
fn deposits_gather_at_the_foot_of_a_slope() {
    // A plane falling east at 30 % onto a flat plain at x = 40 (with a little noise).
    let g = grid(96, 48, 30.0);
    let foot = 40usize;
    let z0: Vec<f32> = (0..g.len())
        .map(|i| {
            let x = i % g.width;
            let n = unit_f32(hash(5, i as u64, 0, 0)) - 0.5;
            0.3 * 30.0 * foot.saturating_sub(x) as f32 + 0.2 * n
        })
        .collect();
    let mut z = z0.clone();
    let out = run(&mut z, &g, &HydraulicParams::default());
    let column = |x0: usize, x1: usize| -> f64 {
        (0..g.len())
            .filter(|i| (x0..x1).contains(&(i % g.width)))
            .map(|i| out.deposition[i] as f64)
            .sum()
    };
    let total = column(0, g.width);
    let band = column(foot - 4, foot + 12);
    assert!(total > 0.0);
    assert!(band > 0.6 * total, "{band} of {total} m at the slope break");
    // The slope itself loses ground.
    let eroded: f64 = (0..g.len())
        .filter(|i| (5..foot - 5).contains(&(i % g.width)))
        .map(|i| out.erosion[i] as f64)
        .sum();
    assert!(
        eroded > band,
        "{eroded} eroded on the slope, {band} deposited"
    );
}

#[test]
fn voids_are_untouched_and_open() {
    let g = grid(40, 30, 10.0);
    let mut z = cone(&g, 100.0, 2.0, 4);
    let voids: Vec<usize> = (0..g.len()).filter(|i| (i % g.width) < 5).collect();
    for &i in &voids {
        z[i] = f32::NAN;
    }
    let out = run(&mut z, &g, &HydraulicParams::default());
    for &i in &voids {
        assert!(z[i].is_nan());
        assert_eq!((out.erosion[i], out.deposition[i]), (0.0, 0.0));
    }
    assert!(z.iter().filter(|v| !v.is_nan()).all(|v| v.is_finite()));
    assert!(out.figures.left_m3 > 0.0, "{:?}", out.figures);
}

#[test]
fn stopping_leaves_the_input_alone() {
    let g = grid(9, 9, 10.0);
    let p = HydraulicParams::default();
    assert_stopping_leaves_the_input_alone(cone(&g, 50.0, 1.0, 1), |z, stop| {
        hydraulic(z, &g, &p, &NoProgress, stop)
    });
}

#[test]
fn the_time_step_follows_the_cell_size() {
    let p = HydraulicParams::default();
    // Half the pipe model's limit sqrt(l / (2 g)) on square cells with A = l^2.
    let dt = p.time_step(&grid(4, 4, 60.0));
    assert!((dt - 0.5 * (60.0 / (2.0 * G)).sqrt()).abs() < 1e-9, "{dt}");
    assert!(p.time_step(&grid(4, 4, 2.0)) < dt);
    let fixed = HydraulicParams {
        dt_s: Some(0.1),
        ..p
    };
    assert_eq!(fixed.time_step(&grid(4, 4, 60.0)), 0.1);
}

#[test]
fn bad_settings_are_rejected_by_name() {
    let d = HydraulicParams::default();
    assert!(d.check().is_ok());
    let name = |p: HydraulicParams| p.check().unwrap_err().name;
    let nan = f64::NAN;
    assert_eq!(
        name(HydraulicParams {
            dt_s: Some(nan),
            ..d
        }),
        "dt_s"
    );
    assert_eq!(
        name(HydraulicParams {
            dt_s: Some(-1.0),
            ..d
        }),
        "dt_s"
    );
    assert_eq!(name(HydraulicParams { rain_m: nan, ..d }), "rain_m");
    assert_eq!(name(HydraulicParams { rain_m: -0.1, ..d }), "rain_m");
    assert_eq!(
        name(HydraulicParams {
            rain_fraction: 0.0,
            ..d
        }),
        "rain_fraction"
    );
    assert_eq!(
        name(HydraulicParams {
            evaporation: nan,
            ..d
        }),
        "evaporation"
    );
    assert_eq!(
        name(HydraulicParams {
            evaporation: 1.0,
            ..d
        }),
        "evaporation"
    );
    assert_eq!(
        name(HydraulicParams {
            capacity: -1.0,
            ..d
        }),
        "capacity"
    );
    assert_eq!(
        name(HydraulicParams {
            erosion_rate: nan,
            ..d
        }),
        "erosion_rate"
    );
    assert_eq!(
        name(HydraulicParams {
            deposition_rate: -0.5,
            ..d
        }),
        "deposition_rate"
    );
    assert_eq!(name(HydraulicParams { min_tilt: nan, ..d }), "min_tilt");
    assert_eq!(
        name(HydraulicParams {
            full_depth_m: 0.0,
            ..d
        }),
        "full_depth_m"
    );
    assert_eq!(
        name(HydraulicParams {
            pipe_area_m2: Some(nan),
            ..d
        }),
        "pipe_area_m2"
    );
    assert_eq!(
        name(HydraulicParams {
            hardness_depth_m: -2.0,
            ..d
        }),
        "hardness_depth_m"
    );
    let g = grid(4, 4, 10.0);
    let mut short = vec![0.0f32; 15];
    let e = hydraulic(&mut short, &g, &d, &NoProgress, &never).unwrap_err();
    assert!(matches!(e, LandscapeError::InvalidInput(_)));
}
