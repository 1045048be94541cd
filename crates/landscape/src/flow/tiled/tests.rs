use super::*;
use crate::flow::{Depressions, RouteOptions, route};

/// The single run: `route` with plain filling and the flats drained, cells counted.
fn single(z: &[f32], w: usize, h: usize, cx: f64, cy: f64) -> Finished {
    let grid = Grid {
        width: w,
        height: h,
        cell_x: cx,
        cell_y: cy,
    };
    let r = route(
        z.to_vec(),
        grid,
        &RouteOptions {
            depressions: Depressions::Fill,
            ..Default::default()
        },
    );
    Finished {
        cells: r.cells_upstream(),
        filled: r.surface,
        dir: r.dir,
    }
}

/// The layout of a `w x h` raster of `cell` metres in tiles of side `tile`.
fn layout(w: usize, h: usize, tile: usize, cell: (f64, f64)) -> TileLayout {
    TileLayout {
        width: w,
        height: h,
        tile,
        cell_x: cell.0,
        cell_y: cell.1,
    }
}

fn shuffled(seed: u64) -> impl FnMut(usize, usize) -> Vec<usize> {
    move |phase, n| {
        let mut v: Vec<usize> = (0..n).collect();
        // A seeded Fisher-Yates shuffle: another order per phase and per seed.
        for i in (1..n).rev() {
            let r = relief_heightfield::rng::hash(seed, phase as u64, i as u64, 7);
            v.swap(i, (r % (i as u64 + 1)) as usize);
        }
        v
    }
}

fn assert_same(a: &Finished, b: &Finished, what: &str) {
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let n = a.filled.len();
    for i in 0..n {
        assert_eq!(
            a.filled[i].to_bits(),
            b.filled[i].to_bits(),
            "{what}: filled differs at cell {i}"
        );
        assert_eq!(a.dir[i], b.dir[i], "{what}: direction differs at cell {i}");
        assert_eq!(
            a.cells[i], b.cells[i],
            "{what}: upstream cells differ at cell {i}"
        );
    }
    assert_eq!(bits(&a.filled), bits(&b.filled));
}

fn check(z: &[f32], w: usize, h: usize, tiles: &[usize], what: &str) {
    let (cx, cy) = (30.0, 20.0);
    let want = single(z, w, h, cx, cy);
    for (k, &tile) in tiles.iter().enumerate() {
        let layout = layout(w, h, tile, (cx, cy));
        let got = run_in_memory(&layout, z, &mut shuffled(k as u64 + 1)).unwrap();
        assert_same(&got, &want, &format!("{what}, tile {tile}"));
    }
}

/// A basin spanning 3 x 3 tiles (a closed bowl filled to its rim), a river meandering across
/// every tile edge, a lake on it spanning tiles, integer elevations (flats everywhere) and
/// voids.
fn basin_and_river(w: usize, h: usize, voids: bool) -> Vec<f32> {
    relief_testdata::basin_and_river(w, h, 3, if voids { 0.01 } else { 0.0 })
}

#[test]
fn a_basin_over_nine_tiles_and_a_river_across_every_edge_equal_the_single_run() {
    let (w, h) = (96, 90);
    let z = basin_and_river(w, h, false);
    // 32 px tiles: the basin spans the 3 x 3 tiles; the others cut it anywhere.
    check(&z, w, h, &[32, 4, 7, 13, 16, 31, 45, 96, 200], "basin");
    // The filled bowl is a flat lake over nine tiles.
    let s = single(&z, w, h, 30.0, 20.0);
    let centre = (h / 2) * w + w / 2;
    assert!(s.filled[centre] > z[centre]);
    let layout = layout(w, h, 32, (30.0, 20.0));
    let lake: std::collections::BTreeSet<usize> = (0..w * h)
        .filter(|&i| s.filled[i] == s.filled[centre])
        .map(|i| layout.tile_at(i % w, i / w))
        .collect();
    assert_eq!(lake.len(), 9, "the lake spans the 3 x 3 tiles");
}

#[test]
fn voids_flats_and_odd_sizes_equal_the_single_run() {
    for (w, h, seed) in [
        (61, 47, 1u64),
        (40, 73, 2),
        (17, 5, 3),
        (1, 30, 4),
        (33, 1, 5),
    ] {
        let z: Vec<f32> = (0..w * h)
            .map(|i| {
                let u = relief_heightfield::rng::unit_f32(relief_heightfield::rng::hash(
                    seed, i as u64, 0, 0,
                ));
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                if u < 0.04 {
                    f32::NAN
                } else {
                    // Coarse steps: many flats, depressions and plateaus.
                    ((u * 6.0 + (x * 0.3).sin() * 4.0 + (y * 0.2).cos() * 4.0) / 2.0).floor()
                }
            })
            .collect();
        check(&z, w, h, &[4, 5, 8, 16], &format!("{w}x{h}"));
        let b = basin_and_river(w, h, true);
        check(&b, w, h, &[4, 9, 16], &format!("voids {w}x{h}"));
    }
}

/// Every DEM of the shared set (`../shared/data/dem`; skipped with a notice when absent, a
/// failure under CI): whole when small, else a crop; SRTM N47E011 whole with its 54,278 voids;
/// topobathy with its sea below zero. Tile sides cut them anywhere, tasks shuffled.
#[test]
fn the_shared_dems_equal_the_single_run() {
    type Crop = Option<(usize, usize, usize, usize)>;
    let cases: [(&str, Crop, &[usize]); 9] = [
        (
            "jacksboro_fault",
            Some((192, 64, 128, 128)),
            &[16, 23, 48, 64],
        ),
        ("jacksboro_fault", None, &[100]),
        ("N47E011", None, &[160, 512]),
        ("N57E011", Some((300, 500, 400, 300)), &[64, 144]),
        ("alps_dem", Some((600, 200, 500, 300)), &[96]),
        ("carrizo", Some((0, 300, 505, 300)), &[80]),
        ("grandcanyon", None, &[48, 128]),
        ("topobathy", None, &[16, 40]),
        ("maunga_whau", None, &[16, 20]),
    ];
    for (k, (id, crop, tiles)) in cases.into_iter().enumerate() {
        let hf = match crop {
            Some((x, y, w, h)) => relief_testdata::dem_crop(id, x, y, w, h),
            None => relief_testdata::load_dem(id),
        };
        let Some(hf) = hf else {
            return;
        };
        let (w, h) = (hf.width(), hf.height());
        let (cx, cy) = hf.cell_size();
        let z = hf.as_slice();
        let want = single(z, w, h, cx, cy);
        for &tile in tiles {
            let layout = layout(w, h, tile, (cx, cy));
            let got =
                run_in_memory(&layout, z, &mut shuffled(k as u64 * 31 + tile as u64)).unwrap();
            assert_same(&got, &want, &format!("{id}, tile {tile}"));
        }
    }
}

#[test]
fn products_round_trip_and_damage_is_refused() {
    let (w, h) = (40, 37);
    let z = basin_and_river(w, h, true);
    let layout = layout(w, h, 16, (1.0, 1.0));
    let t = 4;
    let (fill, graph) = phase1(&layout, t, &halo_window(&layout, t, &z).unwrap()).unwrap();
    let b = fill.to_bytes(t);
    assert_eq!(
        LocalFill::from_bytes(&b, &layout, t).unwrap().to_bytes(t),
        b
    );
    let gb = graph.to_bytes(&layout, t);
    let back = FillGraph::from_bytes(&gb, &layout, t).unwrap();
    assert_eq!(back.edges, graph.edges);
    // Another tile, a truncated file, a trailing byte, an absurd count: errors, no panic.
    assert!(LocalFill::from_bytes(&b, &layout, 3).is_err());
    assert!(LocalFill::from_bytes(&b[..b.len() - 1], &layout, t).is_err());
    let mut long = b.clone();
    long.push(0);
    assert!(LocalFill::from_bytes(&long, &layout, t).is_err());
    let mut huge = gb.clone();
    let at = 32 + back.band_z.len() * 8;
    huge[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    let e = FillGraph::from_bytes(&huge, &layout, t).unwrap_err();
    assert!(e.to_string().contains("count"), "{e}");
    for cut in 0..gb.len() {
        assert!(FillGraph::from_bytes(&gb[..cut], &layout, t).is_err());
    }
    let mut bad_label = b.clone();
    let off = 32 + w.min(16) * 16 * 4;
    bad_label[off..off + 4].copy_from_slice(&1_000_000u32.to_le_bytes());
    assert!(LocalFill::from_bytes(&bad_label, &layout, t).is_err());
}

/// The basin's lake crosses tile edges, so phase 4 drains flats, and the river's flow crosses
/// them, so inflows enter tiles: the test above exercises both.
#[test]
fn the_basin_sends_flats_and_inflows_through_phase_4() {
    let (w, h) = (96, 90);
    let z = basin_and_river(w, h, false);
    let layout = layout(w, h, 32, (30.0, 20.0));
    let p1: Vec<_> = (0..layout.tasks())
        .map(|t| phase1(&layout, t, &halo_window(&layout, t, &z).unwrap()).unwrap())
        .collect();
    let graphs: Vec<FillGraph> = p1.iter().map(|p| p.1.clone()).collect();
    let levels = phase2(&layout, &graphs).unwrap();
    let ports: Vec<PortGraph> = (0..layout.tasks())
        .map(|t| {
            let near: Vec<(usize, &Levels)> = layout
                .neighbourhood(t)
                .into_iter()
                .map(|u| (u, &levels[u]))
                .collect();
            phase3(&layout, t, &p1[t].0, &near).unwrap().1
        })
        .collect();
    let pending: usize = ports.iter().map(|p| p.pending.len()).sum();
    assert!(
        pending > 500,
        "{pending} cells of flats crossing tile edges"
    );
    let inflow = phase4(&layout, &ports).unwrap();
    let entering = inflow.iter().filter(|i| !i.entries.is_empty()).count();
    assert_eq!(entering, 9, "flow enters every tile");
}

/// Zeros of both signs at sea level (a coastal depression filled to 0 m, a -0.0 void-free
/// shore) and voids with an unusual NaN payload: the same bits as the single run.
#[test]
fn signed_zeros_and_nan_payloads_equal_the_single_run() {
    let (w, h) = (40, 36);
    let odd_nan = f32::from_bits(0x7fc0_1234);
    let z: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let u =
                relief_heightfield::rng::unit_f32(relief_heightfield::rng::hash(8, i as u64, 0, 0));
            if u < 0.03 {
                odd_nan
            } else if u < 0.5 {
                if ((x + y) as usize).is_multiple_of(2) {
                    -0.0
                } else {
                    0.0
                }
            } else {
                ((x - 20.0).abs() + (y - 18.0).abs() - 10.0)
                    .max(-3.0)
                    .floor()
            }
        })
        .collect();
    check(&z, w, h, &[4, 7, 16], "zeros");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
    /// Any small DEM of a few levels (flats, depressions and plateaus everywhere), with or
    /// without voids, any tile side from 4 cells, any task order: the single run's bits.
    #[test]
    fn any_dem_any_tile_any_order(
        w in 1usize..40,
        h in 1usize..40,
        tile in 4usize..19,
        levels in 2u32..6,
        voids in 0u32..3,
        seed in 0u64..1_000_000,
    ) {
        let z: Vec<f32> = (0..w * h)
            .map(|i| {
                let r = relief_heightfield::rng::hash(seed, i as u64, 1, 0);
                if (r % 100) < u64::from(voids) * 3 {
                    f32::NAN
                } else {
                    ((r >> 8) % u64::from(levels)) as f32
                }
            })
            .collect();
        let want = single(&z, w, h, 10.0, 7.5);
        let layout = layout(w, h, tile, (10.0, 7.5));
        let got = run_in_memory(&layout, &z, &mut shuffled(seed)).unwrap();
        assert_same(&got, &want, &format!("{w}x{h} tile {tile} seed {seed}"));
        // The network's products too (a channel from a few cells up), unless all are voids.
        if z.iter().any(|v| !v.is_nan()) {
            check_network(&z, w, h, (10.0, 7.5), &[tile], 10.0 * 7.5 * 3.0, 0);
        }
    }
}

/// Misuse of the public passes is an error naming the problem, never a panic.
#[test]
fn bad_tiles_sizes_and_orders_are_errors() {
    let layout = layout(20, 10, 8, (1.0, 1.0));
    let z = vec![1.0f32; 200];
    assert!(halo_window(&layout, 6, &z).is_err());
    assert!(halo_window(&layout, 0, &z[..199]).is_err());
    assert!(phase1(&layout, 9, &[0.0; 4]).is_err());
    assert!(phase1(&layout, 0, &[0.0; 4]).is_err());
    let e = run_in_memory(&layout, &z, &mut |_, n| (0..n - 1).collect()).unwrap_err();
    assert!(e.to_string().contains("leaves a tile out"), "{e}");
    let e = run_in_memory(&layout, &z, &mut |_, n| vec![0; n]).unwrap_err();
    assert!(e.to_string().contains("twice"), "{e}");
    for bad in [
        TileLayout { tile: 3, ..layout },
        TileLayout { width: 0, ..layout },
        TileLayout {
            cell_x: f64::NAN,
            ..layout
        },
    ] {
        assert!(run_in_memory(&bad, &z, &mut |_, n| (0..n).collect()).is_err());
    }
    assert!(phase2(&layout, &[]).is_err());
    assert!(phase4(&layout, &[]).is_err());
}

#[test]
fn halos_cut_from_row_bands_equal_those_of_the_whole_dem() {
    // What the plan cuts band by band: every tile's halo from just its rows (and from larger
    // bands), the same values as from the whole DEM; a band missing a row is an error.
    let (w, h) = (37, 29);
    let z = basin_and_river(w, h, true);
    let layout = layout(w, h, 8, (1.0, 1.0));
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for t in 0..layout.tasks() {
        let whole = halo_window(&layout, t, &z).unwrap();
        let (a, b) = halo_rows(&layout, t).unwrap();
        let [_, y0, _, th] = layout.window(t);
        assert_eq!((a, b), (y0.saturating_sub(1), (y0 + th + 1).min(h)));
        for (first, end) in [(a, b), (a.saturating_sub(2), (b + 3).min(h)), (0, h)] {
            let band = &z[first * w..end * w];
            let cut = halo_from_rows(&layout, t, band, first).unwrap();
            assert_eq!(bits(&cut), bits(&whole), "tile {t} rows {first}..{end}");
        }
        if b - a > 1 {
            assert!(halo_from_rows(&layout, t, &z[(a + 1) * w..b * w], a + 1).is_err());
            assert!(halo_from_rows(&layout, t, &z[a * w..(b - 1) * w], a).is_err());
        }
        assert!(halo_from_rows(&layout, t, &z[a * w..b * w - 1], a).is_err());
    }
}

/// Phases 6 and 7 after the tiled drainage of `z` (each tile's finished values cut from the
/// assembled run, which equals the single run), their products through their byte forms: the
/// Strahler order, watersheds, HAND, channel network and figures of `FlowSettings::run`.
fn check_network(
    z: &[f32],
    w: usize,
    h: usize,
    cell: (f64, f64),
    tiles: &[usize],
    area: f64,
    min_reaches: usize,
) {
    use crate::flow::job::FlowSettings;
    let hf = relief_heightfield::Heightfield::new(w, h, z.to_vec(), cell.0, cell.1).unwrap();
    let settings = FlowSettings {
        channel_area: area,
        ..Default::default()
    };
    let want = settings.run(&hf, &relief_heightfield::NoProgress).unwrap();
    assert!(
        want.figures.reaches >= min_reaches,
        "{} reaches",
        want.figures.reaches
    );
    for (k, &tile) in tiles.iter().enumerate() {
        let layout = layout(w, h, tile, cell);
        let all = run_in_memory(&layout, z, &mut shuffled(k as u64 + 40)).unwrap();
        let cut = |t: usize| all.tile(&layout, t);
        let sums: Vec<NetSummary> = (0..layout.tasks())
            .map(|t| {
                let s = summarize(&layout, t, &cut(t), area).unwrap();
                NetSummary::from_bytes(&s.to_bytes(&layout, t), &layout, t).unwrap()
            })
            .collect();
        let levels = phase6(&layout, &sums).unwrap();
        let mut strahler = vec![f32::NAN; w * h];
        let mut sheds = vec![f32::NAN; w * h];
        let mut hand = vec![0f32; w * h];
        let mut nets = Vec::new();
        for t in shuffled(k as u64 + 41)(7, layout.tasks()) {
            let lv = NetLevels::from_bytes(&levels[t].to_bytes(&layout, t), &layout, t).unwrap();
            let input = halo_window(&layout, t, z).unwrap();
            let (r, net) = phase7(&layout, t, &cut(t), &lv, &input, area).unwrap();
            let (o, l, hd) = (r.strahler, r.watersheds, r.hand);
            let net = TileNetwork::from_bytes(&net.to_bytes(&layout, t), &layout, t).unwrap();
            let [x0, y0, tw, _] = layout.window(t);
            for i in 0..o.len() {
                let g = (y0 + i / tw) * w + x0 + i % tw;
                if !z[g].is_nan() {
                    strahler[g] = o[i] as f32;
                    sheds[g] = l[i] as f32;
                }
                hand[g] = hd[i];
            }
            nets.push((t, net));
        }
        nets.sort_by_key(|n| n.0);
        let nets: Vec<TileNetwork> = nets.into_iter().map(|n| n.1).collect();
        let (geojson, figures) = assemble(&layout, None, &nets).unwrap();
        let what = format!("tile {tile}");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(&strahler),
            bits(want.strahler.as_slice()),
            "{what}: Strahler"
        );
        assert_eq!(
            bits(&sheds),
            bits(want.watersheds.as_slice()),
            "{what}: watersheds"
        );
        assert_eq!(bits(&hand), bits(want.hand.as_slice()), "{what}: HAND");
        assert_eq!(figures, want.figures, "{what}: figures");
        assert_eq!(
            serde_json::to_string(&geojson).unwrap(),
            serde_json::to_string(&want.channels).unwrap(),
            "{what}: network"
        );
    }
}

#[test]
fn network_products_of_a_basin_and_a_river_equal_the_single_run() {
    let (w, h) = (96, 90);
    for voids in [false, true] {
        let z = basin_and_river(w, h, voids);
        check_network(
            &z,
            w,
            h,
            (30.0, 20.0),
            &[32, 4, 7, 16, 31, 96],
            30.0 * 20.0 * 12.0,
            20,
        );
    }
}

#[test]
fn network_products_of_the_shared_dems_equal_the_single_run() {
    for (id, crop, tiles, area) in [
        (
            "jacksboro_fault",
            (192, 64, 128, 128),
            &[16, 23, 48][..],
            5e4,
        ),
        ("alps_dem", (600, 200, 300, 200), &[32, 96][..], 2e5),
        ("N47E011", (0, 0, 400, 300), &[64, 144][..], 3e5),
    ] {
        let Some(hf) = relief_testdata::dem_crop(id, crop.0, crop.1, crop.2, crop.3) else {
            return;
        };
        let (w, h) = (hf.width(), hf.height());
        check_network(hf.as_slice(), w, h, hf.cell_size(), tiles, area, 4);
    }
}
