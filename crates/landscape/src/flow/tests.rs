use super::*;
use crate::flow::basins::{hand, watersheds};
use crate::flow::network::{geojson, reaches, strahler};

fn hash_dem(w: usize, h: usize, seed: u64) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let u = relief_heightfield::rng::unit_f32(relief_heightfield::rng::hash(
                seed, i as u64, 0, 0,
            ));
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            u * 8.0 + ((x - w as f32 / 2.0).abs() + (y - h as f32 / 2.0).abs()) * 0.5
        })
        .collect()
}

fn grid(w: usize, h: usize, cx: f64, cy: f64) -> Grid {
    Grid::new(w, h, cx, cy)
}

#[test]
fn every_cell_drains_and_area_is_conserved() {
    for depressions in [Depressions::Fill, Depressions::Epsilon, Depressions::Breach] {
        let g = grid(40, 33, 30.0, 20.0);
        let mut z = hash_dem(40, 33, 11);
        z[500] = f32::NAN;
        z[501] = f32::NAN;
        let r = route(
            z,
            g,
            &RouteOptions {
                depressions,
                ..Default::default()
            },
        );
        assert_eq!(r.sinks(), 0, "{depressions:?}");
        assert_eq!(r.order.len(), g.len() - 2);
        let acc = r.accumulation(None);
        let total: f64 = (0..g.len())
            .filter(|&i| r.dir[i] == NO_FLOW && !r.surface[i].is_nan())
            .map(|i| acc[i])
            .sum();
        assert!(
            (total - 600.0 * (g.len() - 2) as f64).abs() < 1e-6,
            "{depressions:?}"
        );
        let mfd = r.accumulation_mfd(1.1);
        let total: f64 = (0..g.len())
            .filter(|&i| r.dir[i] == NO_FLOW && !r.surface[i].is_nan())
            .map(|i| mfd[i])
            .sum();
        assert!((total / (600.0 * (g.len() - 2) as f64) - 1.0).abs() < 1e-9);
        // Every valid cell reaches an outlet along its receivers.
        for i in 0..g.len() {
            if r.surface[i].is_nan() {
                continue;
            }
            let mut c = i;
            let mut steps = 0;
            while let Some(d) = receiver(&g, c, r.dir[c]) {
                c = d;
                steps += 1;
                assert!(steps < g.len());
            }
            assert!(r.outlet[c], "{depressions:?}: cell {i} ends in {c}");
        }
    }
}

#[test]
fn steepest_descent_weighs_non_square_cells() {
    // Cells 10 m east-west, 100 m north-south: a 1 m drop east beats a 5 m drop south.
    let g = grid(3, 3, 10.0, 100.0);
    let z = vec![9.0f32, 9.0, 9.0, 9.0, 6.0, 5.0, 9.0, 1.0, 9.0];
    let dir = steepest_descent(&z, &g, &[false; 9]);
    assert_eq!(D8[dir[4] as usize], (0, 1));
}

#[test]
fn flats_drain_towards_lower_ground_and_away_from_higher() {
    // A flat plateau at 10 m, higher ground to the north, one exit at the south edge.
    let (w, h) = (9, 9);
    let mut z = vec![20.0f32; w * h];
    for y in 1..8 {
        for x in 1..8 {
            z[y * w + x] = 10.0;
        }
    }
    z[8 * w + 4] = 5.0;
    let g = grid(w, h, 1.0, 1.0);
    let r = route(z, g, &RouteOptions::default());
    assert_eq!(r.sinks(), 0);
    let acc = r.accumulation(None);
    // The rim is made of outlets: the flat's 49 cells leave through the exit.
    assert_eq!(acc[8 * w + 4], 50.0);
    // Paths across the flat are direct: from the far corner to the exit in at most 9 steps
    // (7 rows down plus a detour away from the rim).
    let mut c = w + 1;
    let mut steps = 0;
    while let Some(d) = receiver(&g, c, r.dir[c]) {
        c = d;
        steps += 1;
    }
    assert_eq!(c, 8 * w + 4);
    assert!(steps <= 9, "{steps} steps");
}

#[test]
fn strahler_of_a_two_headed_network() {
    // Two tributaries of order 1 meet and go on as order 2; a third order-1 joins lower down.
    let (w, h) = (7, 12);
    let mut z = vec![100.0f32; w * h];
    for y in 0..h {
        z[y * w + 3] = 50.0 - y as f32 * 2.0;
    }
    for y in 0..4 {
        z[y * w + 1] = 60.0 - y as f32;
        z[y * w + 5] = 60.0 - y as f32;
    }
    z[4 * w + 2] = 55.0;
    z[4 * w + 4] = 55.0;
    let g = grid(w, h, 10.0, 10.0);
    let r = route(z, g, &RouteOptions::default());
    let acc = r.accumulation(None);
    let s = strahler(&r, &acc, 250.0);
    let trunk_bottom = s[(h - 1) * w + 3];
    assert!(trunk_bottom >= 2, "{s:?}");
    let rs = reaches(&r, &acc, &s);
    assert!(!rs.is_empty());
    let gj = geojson(&r, None, &rs);
    assert_eq!(gj["type"], "FeatureCollection");
    assert_eq!(gj["features"].as_array().unwrap().len(), rs.len());
}

#[test]
fn watersheds_partition_and_hand_is_zero_on_channels() {
    let g = grid(30, 30, 10.0, 10.0);
    let z = hash_dem(30, 30, 5);
    let r = route(z, g, &RouteOptions::default());
    let acc = r.accumulation(None);
    let ws = watersheds(&r, &acc);
    assert!(ws.iter().all(|&l| l >= 1));
    // Label 1 is the largest basin.
    let count = |l: u32| ws.iter().filter(|&&v| v == l).count();
    assert!(count(1) >= count(2));
    let hd = hand(&r, &acc, 2_000.0);
    for i in 0..g.len() {
        assert!(hd[i] >= 0.0);
        if acc[i] >= 2_000.0 {
            assert_eq!(hd[i], 0.0);
        }
    }
}
