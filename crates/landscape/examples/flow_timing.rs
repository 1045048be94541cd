//! Times the steps of `relief flow`'s routing on a raw float32 raster:
//! `cargo run --release -p relief-landscape --features examples --example flow_timing -- FILE.f32 WIDTH HEIGHT CELL`.

#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_landscape::depression::{self, FillMode};
use relief_landscape::flow;
use relief_landscape::grid::Grid;

fn main() {
    let a: Vec<String> = std::env::args().collect();
    let bytes = std::fs::read(&a[1]).expect("raster");
    let z: Vec<f32> = relief_heightfield::bytes::f32_from_le_bytes(&bytes);
    let (w, h, cell): (usize, usize, f64) = (
        a[2].parse().unwrap(),
        a[3].parse().unwrap(),
        a[4].parse().unwrap(),
    );
    let grid = Grid::new(w, h, cell, cell);
    let t = Instant::now();
    let mut f = z.clone();
    depression::priority_flood(&mut f, &grid, FillMode::Plain, None);
    let fill = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let outlet: Vec<bool> = (0..grid.len())
        .map(|i| !f[i].is_nan() && depression::is_outlet(&f, &grid, i))
        .collect();
    let t_out = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut dir = flow::steepest_descent(&f, &grid, &outlet);
    let t_dir = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let flats = depression::resolve_flats(&f, &grid, &outlet, &mut dir);
    let t_flats = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let order = flow::flow_order(&grid, &dir, |i| !f[i].is_nan());
    let t_order = t.elapsed().as_secs_f64();
    let r = flow::Routing {
        grid,
        surface: f,
        dir,
        order,
        outlet,
    };
    let t = Instant::now();
    let acc = r.accumulation(None);
    let t_acc = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut e = z.clone();
    depression::priority_flood(&mut e, &grid, FillMode::Epsilon, None);
    let eps = t.elapsed().as_secs_f64();
    println!(
        "fill {fill:.2} s, outlets {t_out:.2}, dir {t_dir:.2}, flats {t_flats:.2} ({flats} cells), order {t_order:.2}, acc {t_acc:.2} (max {:.3e}); epsilon fill {eps:.2}",
        acc.iter().cloned().fold(0.0, f64::max)
    );
}
