//! Looks at thermal + hydraulic erosion on a real DEM: reads a `.f32` + `.json` pair of the
//! shared DEM set, runs [`thermal`] and [`hydraulic`] and writes hillshades before and after,
//! and a map of erosion (red) and deposition (blue), to `target/look/`.
//!
//! ```text
//! cargo run --release -p relief-landscape --features examples --example hydraulic_look -- \
//!     /work/shared/data/dem/grandcanyon [crop=W,H,X,Y] [zf=2] [thermal.iterations=0] [capacity=0.1] ...
//! ```
//! `key=value` pairs override [`HydraulicParams`] fields (`thermal.` ones [`ThermalParams`]),
//! with JSON values.

#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_heightfield::NoProgress;
use relief_landscape::erode::hydraulic::{HydraulicParams, hydraulic};
use relief_landscape::erode::thermal::{ThermalParams, thermal};
use relief_landscape::grid::Grid;
use serde_json::Value;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let stem = args
        .first()
        .ok_or("usage: hydraulic_look DEM_STEM [key=value ...]")?;
    let meta: Value = serde_json::from_str(&std::fs::read_to_string(format!("{stem}.json"))?)?;
    let (w, h) = (
        meta["width"].as_u64().ok_or("width")? as usize,
        meta["height"].as_u64().ok_or("height")? as usize,
    );
    let (cx, cy) = (
        meta["cell_size_x_m"].as_f64().ok_or("cell_size_x_m")?,
        meta["cell_size_y_m"].as_f64().ok_or("cell_size_y_m")?,
    );
    let bytes = std::fs::read(format!("{stem}.f32"))?;
    let mut z: Vec<f32> = relief_heightfield::bytes::f32_from_le_bytes(&bytes);
    let mut grid = Grid::new(w, h, cx, cy);
    let mut hp = serde_json::to_value(HydraulicParams::default())?;
    let mut tp = serde_json::to_value(ThermalParams::default())?;
    let (mut zf, mut tag, mut up) = (1.0f64, String::new(), 1usize);
    for a in &args[1..] {
        let (k, v) = a.split_once('=').ok_or("arguments are key=value")?;
        match k {
            "crop" => {
                let c: Vec<usize> = v.split(',').map(str::parse).collect::<Result<_, _>>()?;
                let (cw, ch, x0, y0) = (c[0], c[1], c[2], c[3]);
                z = (0..ch)
                    .flat_map(|y| z[(y0 + y) * w + x0..(y0 + y) * w + x0 + cw].to_vec())
                    .collect();
                grid.width = cw;
                grid.height = ch;
            }
            "zf" => zf = v.parse()?,
            "up" => up = v.parse()?,
            "tag" => tag = v.to_string(),
            _ => match k.strip_prefix("thermal.") {
                Some(t) => tp[t] = serde_json::from_str(v)?,
                None => hp[k] = serde_json::from_str(v)?,
            },
        }
    }
    let hp: HydraulicParams = serde_json::from_value(hp)?;
    let tp: ThermalParams = serde_json::from_value(tp)?;
    let name = std::path::Path::new(stem)
        .file_name()
        .ok_or("stem")?
        .to_string_lossy()
        .to_string()
        + &tag;
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/look");
    std::fs::create_dir_all(&out)?;
    let before = z.clone();
    let write_shade = |when: &str, z: &[f32]| {
        write_gray(
            &out.join(format!("{name}_{when}.png")),
            &grid,
            up,
            &hillshade(z, &grid, zf),
        )
    };
    write_shade("before", &z)?;

    let t = Instant::now();
    let tf = thermal(&mut z, &grid, &tp, &NoProgress, &|| false)?;
    let t_thermal = t.elapsed();
    let t = Instant::now();
    let ho = hydraulic(&mut z, &grid, &hp, &NoProgress, &|| false)?;
    let t_hydraulic = t.elapsed();
    println!("{}x{} cells of {cx} x {cy} m", grid.width, grid.height);
    println!("thermal {tp:?}: {:.2?} {tf:?}", t_thermal);
    println!("hydraulic {hp:?}: {:.2?}\n{:#?}", t_hydraulic, ho.figures);
    write_shade("after", &z)?;
    // Erosion red, deposition blue, over the old hillshade; full colour at 1/4 of the cell size.
    let shade = hillshade(&before, &grid, zf);
    let full = 0.25 * cx.min(cy) as f32;
    let rgb: Vec<u8> = (0..grid.len())
        .flat_map(|i| {
            let g = shade[i] * 0.6 + 0.2;
            let e = (ho.erosion[i] / full).min(1.0);
            let d = (ho.deposition[i] / full).min(1.0);
            // Towards pure red with erosion, pure blue with deposition.
            let c = [
                g + (1.0 - g) * e - g * d,
                g * (1.0 - e) * (1.0 - d),
                g + (1.0 - g) * d - g * e,
            ];
            c.map(|v| (v.clamp(0.0, 1.0) * 255.0) as u8)
        })
        .collect();
    write_png(
        &out.join(format!("{name}_change.png")),
        &grid,
        up,
        png::ColorType::Rgb,
        &rgb,
    )?;
    println!("wrote {}/{name}_{{before,after,change}}.png", out.display());
    Ok(())
}

/// Lambertian hillshade (light from the north-west, 45 degrees up) in `[0, 1]`.
fn hillshade(z: &[f32], grid: &Grid, zf: f64) -> Vec<f32> {
    let (w, h) = (grid.width, grid.height);
    let at = |x: usize, y: usize| z[y * w + x] as f64;
    let l = [-(0.5f64.sqrt()) * 0.5f64.sqrt(), 0.5, 0.5f64.sqrt()];
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let (xa, xb) = (x.saturating_sub(1), (x + 1).min(w - 1));
            let (ya, yb) = (y.saturating_sub(1), (y + 1).min(h - 1));
            let gx = (at(xb, y) - at(xa, y)) / ((xb - xa) as f64 * grid.cell_x) * zf;
            // North up: rows grow southwards.
            let gy = (at(x, ya) - at(x, yb)) / ((yb - ya) as f64 * grid.cell_y) * zf;
            let n = (gx * gx + gy * gy + 1.0).sqrt();
            let d = (-gx * l[0] - gy * l[1] + l[2]) / n;
            if d.is_finite() {
                d.max(0.0) as f32
            } else {
                0.0
            }
        })
        .collect()
}

fn write_gray(path: &std::path::Path, grid: &Grid, up: usize, v: &[f32]) -> std::io::Result<()> {
    let bytes: Vec<u8> = v
        .iter()
        .map(|&s| (s.clamp(0.0, 1.0) * 255.0) as u8)
        .collect();
    write_png(path, grid, up, png::ColorType::Grayscale, &bytes)
}

fn write_png(
    path: &std::path::Path,
    grid: &Grid,
    up: usize,
    color: png::ColorType,
    data: &[u8],
) -> std::io::Result<()> {
    // Nearest-neighbour enlargement by `up` for close looks.
    let c = data.len() / grid.len();
    let (w, h) = (grid.width * up, grid.height * up);
    let data: Vec<u8> = (0..w * h)
        .flat_map(|i| {
            let j = (i / w / up) * grid.width + (i % w) / up;
            data[j * c..(j + 1) * c].to_vec()
        })
        .collect();
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut enc = png::Encoder::new(file, w as u32, h as u32);
    enc.set_color(color);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(std::io::Error::other)?;
    writer
        .write_image_data(&data)
        .map_err(std::io::Error::other)?;
    Ok(())
}
