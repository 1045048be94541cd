//! Render timing on a recipe scene (grandcanyon 48 x 48 crop, every feature):
//! `cargo run --release -p relief-implicit-volume --example render_prof`
#![allow(clippy::print_stdout)]
use relief_implicit_volume::*;
use std::time::Instant;
fn main() {
    let hf = relief_testdata::dem_crop("grandcanyon", 200, 160, 48, 48).expect("DEM set");
    let recipe = Recipe {
        features: Feature::ALL.to_vec(),
        seed: 3,
        ..Default::default()
    };
    let (scene, _) = build_recipe(&hf, &recipe).unwrap();
    for shadows in [false, true] {
        let t = Instant::now();
        let _ = render(
            &scene,
            &Camera::overview(&scene.bbox()),
            &RenderSettings {
                width: 160,
                height: 120,
                shadows,
                ..Default::default()
            },
        )
        .unwrap();
        println!("shadows {shadows}: {:.3} s", t.elapsed().as_secs_f64());
    }
}
