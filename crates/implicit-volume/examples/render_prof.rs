//! Render timing on a recipe scene (grandcanyon 48 x 48 crop, every feature):
//! `cargo run --release -p relief-implicit-volume --features examples --example render_prof`
#![allow(clippy::print_stdout)]
use relief_implicit_volume::*;
fn main() {
    let hf = relief_testdata::dem_crop("grandcanyon", 200, 160, 48, 48).expect("DEM set");
    let recipe = Recipe {
        features: Feature::ALL.to_vec(),
        seed: 3,
        ..Default::default()
    };
    let (scene, _) = build_recipe(&hf, &recipe).unwrap();
    let camera = Camera::overview(&scene.bbox());
    for shadows in [false, true] {
        let settings = RenderSettings {
            width: 160,
            height: 120,
            shadows,
            ..Default::default()
        };
        let (_, secs) = relief_testdata::timed(|| render(&scene, &camera, &settings).unwrap());
        println!("shadows {shadows}: {secs:.3} s");
    }
}
