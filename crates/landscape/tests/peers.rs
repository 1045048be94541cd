//! Exactness against the peers a GIS user checks with (RichDEM, fastscapelib), on a crop of a
//! real DEM with non-square cells (jacksboro_fault rows 64..192, columns 192..320, read from
//! `../shared/data/dem`; the tests skip with a notice when it is absent, and fail under CI).
//! The peers' results were written once by `xtask/peers/landscape_reference.py` (its docstring
//! says how) and are committed under `tests/data/` (the fills as the cells they raise), so these
//! tests need no Python.

use std::path::Path;

use relief_landscape::depression::{FillMode, priority_flood};
use relief_landscape::flow::{self, Depressions, RouteOptions};
use relief_landscape::grid::Grid;

/// The crop and its grid, or `None` (with a notice) without the shared DEM set.
fn crop() -> Option<(Vec<f32>, Grid)> {
    let hf = relief_testdata::dem_crop("jacksboro_fault", 192, 64, 128, 128)?;
    let grid = Grid::of(&hf);
    Some((hf.as_slice().to_vec(), grid))
}

/// A peer's fill of the crop: the crop with the raised cells of `name` (rows of cell index,
/// filled elevation).
fn peer_fill(dem: &[f32], name: &str) -> Vec<f32> {
    let (rows, _, _) = npy(name);
    let mut f = dem.to_vec();
    for r in rows.chunks_exact(2) {
        f[r[0] as usize] = r[1] as f32;
    }
    f
}

/// A C-order little-endian `.npy` of `<f4` or `<f8` as f64 (the tests' own 20-line reader: the
/// crate does not depend on relief-io).
fn npy(name: &str) -> (Vec<f64>, usize, usize) {
    let bytes = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data")
            .join(name),
    )
    .expect("reference file");
    let hlen = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let header = std::str::from_utf8(&bytes[10..10 + hlen]).unwrap();
    let shape: Vec<usize> = header
        .split("'shape': (")
        .nth(1)
        .unwrap()
        .split(')')
        .next()
        .unwrap()
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let data = &bytes[10 + hlen..];
    let v: Vec<f64> = if header.contains("<f4") {
        data.chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()) as f64)
            .collect()
    } else {
        assert!(header.contains("<f8"));
        data.chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    };
    assert!(header.contains("'fortran_order': False"));
    (v, shape[1], shape[0])
}

#[test]
fn plain_fill_equals_richdem_cell_for_cell() {
    let Some((dem, g)) = crop() else { return };
    let reference = peer_fill(&dem, "rd_fill_raised.npy");
    let mut z = dem.clone();
    let raised = priority_flood(&mut z, &g, FillMode::Plain, None);
    assert_eq!(raised, 1332);
    assert_eq!(z, reference);
}

#[test]
fn epsilon_fill_differs_from_richdem_only_by_the_order_of_equal_cells() {
    // Both raise each cell one float32 step above the cell the flood reached it from; which
    // equal cell comes first is the heap's business (RichDEM: GCC's std::priority_queue; here:
    // the cell index), so the steps taken inside a filled flat may differ, never the level.
    let Some((dem, g)) = crop() else { return };
    let plain = peer_fill(&dem, "rd_fill_raised.npy");
    let reference = peer_fill(&dem, "rd_fill_eps_raised.npy");
    let mut z = dem.clone();
    priority_flood(&mut z, &g, FillMode::Epsilon, None);
    let mut differ = 0;
    for i in 0..g.len() {
        if z[i] != reference[i] {
            differ += 1;
            // Only on cells the epsilon raises (a filled depression or a flat, where the
            // level is the plain fill's), by a few float32 steps above that level.
            assert!(reference[i] > dem[i] || z[i] > dem[i], "cell {i}");
            assert!((z[i] - plain[i]).abs() < 0.01 && (reference[i] - plain[i]).abs() < 0.01);
        }
    }
    assert!(differ <= 40, "{differ} cells differ (17 when written)");
}

#[test]
fn d8_area_equals_fastscapelib_on_the_same_drained_surface() {
    // fastscapelib's SingleFlowRouter is the same rule (steepest drop over centre distance, the
    // first neighbour in row-major order winning ties, edges as outlets); routed on RichDEM's
    // epsilon-filled surface, where every interior cell has a lower neighbour.
    let Some((dem, g)) = crop() else { return };
    let eps = peer_fill(&dem, "rd_fill_eps_raised.npy");
    let (area, _, _) = npy("fs_area.npy");
    let r = flow::route(
        eps,
        g,
        &RouteOptions {
            depressions: Depressions::None,
            ..Default::default()
        },
    );
    assert_eq!(r.sinks(), 0);
    let ours = r.accumulation(None);
    let mut worst = 0f64;
    for i in 0..g.len() {
        worst = worst.max((ours[i] - area[i]).abs() / area[i]);
    }
    assert!(worst < 1e-12, "largest relative difference {worst}");
}

#[test]
fn drainage_stats_equal_the_reference_tool() {
    // `shared/tools/terrain_quality.py`'s drainage(z, 80.0) on the same crop (square 80 m
    // cells: the reference tool has one cell size): (2.02178955078125, 0.46583093872066983,
    // 0.5430709163880191).
    let Some((dem, g)) = crop() else { return };
    let hf = relief_heightfield::Heightfield::new(g.width, g.height, dem, 80.0, 80.0).unwrap();
    let s = relief_landscape::stats::drainage(&hf);
    assert!((s.pits_per_km2 - 2.02178955078125).abs() < 1e-9, "{s:?}");
    assert!((s.fill_depth_m - 0.46583093872066983).abs() < 1e-9, "{s:?}");
    assert!((s.beta - 0.5430709163880191).abs() < 1e-9, "{s:?}");
}

#[test]
fn d8_directions_and_area_equal_pysheds_but_for_the_order_of_exact_ties() {
    // pysheds' `flowdir(routing='d8')` is the same rule (steepest drop over centre distance) but
    // tries the neighbours clockwise from north, keeping the first of equal drops; relief (and
    // fastscapelib) keep the first in row-major order. So the directions may differ only where
    // two neighbours have the same drop, and pysheds' accumulation of its own directions must
    // equal ours of the same directions, cell for cell.
    let Some((dem, g)) = crop() else { return };
    let eps = peer_fill(&dem, "rd_fill_eps_raised.npy");
    let (receiver, _, _) = npy("ps_receiver.npy");
    let (area, _, _) = npy("ps_area.npy");
    let ours = flow::route(
        eps.clone(),
        g,
        &RouteOptions {
            depressions: Depressions::None,
            ..Default::default()
        },
    );
    let dist = g.distances();
    let (mut differ, mut theirs) = (0, ours.dir.clone());
    for i in 0..g.len() {
        let mine = flow::receiver(&g, i, ours.dir[i]).map_or(-1.0, |r| r as f64);
        if mine == receiver[i] {
            continue;
        }
        differ += 1;
        // Their receiver is a neighbour whose drop over distance equals ours exactly.
        let r = receiver[i] as usize;
        let k = (0..8)
            .find(|&k| flow::receiver(&g, i, k as u8) == Some(r))
            .expect("pysheds' receiver is a D8 neighbour");
        let j = flow::receiver(&g, i, ours.dir[i]).unwrap();
        let slope = |m: usize, d: f64| (eps[i] as f64 - eps[m] as f64) / d;
        assert_eq!(
            slope(r, dist[k]),
            slope(j, dist[ours.dir[i] as usize]),
            "cell {i}"
        );
        theirs[i] = k as u8;
    }
    assert!(
        differ > 0 && differ <= 80,
        "{differ} cells differ (66 when written)"
    );
    let order = flow::flow_order(&g, &theirs, |_| true);
    let same_dirs = flow::Routing {
        dir: theirs,
        order,
        ..ours
    };
    let acc = same_dirs.accumulation(None);
    let worst = (0..g.len())
        .map(|i| (acc[i] - area[i]).abs() / area[i])
        .fold(0.0, f64::max);
    assert!(worst < 1e-12, "largest relative difference {worst}");
}
