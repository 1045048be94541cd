//! The erosion presets on crops of the shared real DEMs, for looking at: for each DEM a panel
//! of hillshades (input, then each preset) and a line of figures per preset (time, volumes,
//! drainage statistics before and after):
//! `cargo run --release -p relief-landscape --features examples --example erode_look [-- DEM...]`
//! writes `target/look/erode/<dem>.png` (`PRESETS=mountain,desert` picks presets, `OVERRIDES`
//! a JSON object of `ErodeSettings` fields applied over each; `CROP=x,y,w,h` replaces the crop
//! of the DEMs named; `SQUARE=1` resamples each crop to square cells first).

#![allow(clippy::print_stdout)]

use std::time::Instant;

use relief_heightfield::{Heightfield, NoProgress};
use relief_landscape::erode::job::{ErodeSettings, Preset};
use relief_landscape::stats::drainage;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let crops: [(&str, usize, usize, usize, usize); 4] = [
        ("grandcanyon", 0, 0, 512, 512),
        ("alps_dem", 1200, 120, 640, 512),
        ("N47E011", 300, 300, 512, 512),
        ("carrizo", 0, 200, 505, 512),
    ];
    let out = relief_testdata::workspace_root().join("target/look/erode");
    std::fs::create_dir_all(&out).expect("output folder");
    let crop: Option<Vec<usize>> = std::env::var("CROP").ok().map(|c| {
        c.split(',')
            .map(|v| v.parse().expect("CROP x,y,w,h"))
            .collect()
    });
    for (id, mut x, mut y, mut w, mut h) in crops {
        if !args.is_empty() && !args.iter().any(|a| a == id) {
            continue;
        }
        if let Some(c) = crop.as_deref() {
            [x, y, w, h] = [c[0], c[1], c[2], c[3]];
        }
        let Some(dem) = relief_testdata::dem_crop(id, x, y, w, h) else {
            println!("{id}: shared DEMs not found");
            return;
        };
        let dem = if dem.has_voids() {
            let mut d = dem.clone();
            relief_heightfield::fill::fill_voids(&mut d, &Default::default()).expect("fill");
            d
        } else {
            dem
        };
        // SQUARE=1: resampled (bicubic) to square cells of the smaller side first, to tell the
        // processes' response to the terrain from their response to the cells' shape.
        let dem = if std::env::var_os("SQUARE").is_some() {
            let (cx, cy) = dem.cell_size();
            let c = cx.min(cy);
            let w2 = (dem.width() as f64 * cx / c).round() as usize;
            let h2 = (dem.height() as f64 * cy / c).round() as usize;
            dem.resample(w2, h2).expect("resample")
        } else {
            dem
        };
        let s0 = drainage(&dem);
        println!(
            "{id} {w}x{h} cells {:.1}x{:.1} m: input pits/km2 {:.2} fill {:.3} m beta {:.3}",
            dem.cell_size().0,
            dem.cell_size().1,
            s0.pits_per_km2,
            s0.fill_depth_m,
            s0.beta
        );
        let mut panels = vec![dem.clone()];
        let presets: Vec<Preset> = match std::env::var("PRESETS") {
            Ok(v) => Preset::ALL
                .into_iter()
                .filter(|p| v.split(',').any(|n| n == p.name()))
                .collect(),
            Err(_) => Preset::ALL.to_vec(),
        };
        for &preset in &presets {
            let t = Instant::now();
            // OVERRIDES: JSON fields of ErodeSettings applied over the preset (for tuning).
            let mut settings = ErodeSettings::preset(preset);
            if let Ok(json) = std::env::var("OVERRIDES") {
                let mut v = serde_json::to_value(&settings).expect("json");
                let o: serde_json::Value = serde_json::from_str(&json).expect("OVERRIDES json");
                for (k, x) in o.as_object().expect("object") {
                    v[k] = x.clone();
                }
                settings = serde_json::from_value(v).expect("settings");
            }
            let r = settings
                .run(&dem, None, &NoProgress, &|| false)
                .expect("erode");
            let s = drainage(&r.terrain);
            println!(
                "  {:9} {:5.1} s  eroded {:.3e} m3 deposited {:.3e} m3 max cut {:.1} m max fill {:.1} m  pits/km2 {:.2} fill {:.3} m beta {:.3}",
                preset.name(),
                t.elapsed().as_secs_f64(),
                r.figures.eroded_m3,
                r.figures.deposited_m3,
                r.figures.max_erosion_m,
                r.figures.max_deposition_m,
                s.pits_per_km2,
                s.fill_depth_m,
                s.beta
            );
            panels.push(r.terrain);
        }
        write_panel(&out.join(format!("{id}.png")), &panels);
    }
}

fn write_panel(path: &std::path::Path, panels: &[Heightfield]) {
    let (w, h) = (panels[0].width(), panels[0].height());
    let gap = 6;
    let total = panels.len() * w + (panels.len() - 1) * gap;
    let mut px = vec![255u8; total * h];
    for (k, p) in panels.iter().enumerate() {
        let s = relief_heightfield::terrain::hillshade(p, 315.0, 45.0, 1.0);
        for y in 0..h {
            for x in 0..w {
                px[y * total + k * (w + gap) + x] = (s[[y, x]] * 255.0).round() as u8;
            }
        }
    }
    let file = std::io::BufWriter::new(std::fs::File::create(path).expect("png"));
    let mut enc = png::Encoder::new(file, total as u32, h as u32);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()
        .expect("png")
        .write_image_data(&px)
        .expect("png");
}
