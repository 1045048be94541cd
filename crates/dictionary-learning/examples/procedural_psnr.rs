//! Inverse procedural modelling (section 5.2, figure 8): PSNR of s = 1 reconstructions of a real
//! mountain DEM crop with analytic dictionaries of each noise family (release example):
//! `cargo run --release -p relief-dictionary-learning --features examples --example procedural_psnr`
#![allow(clippy::print_stdout)]

use relief_dictionary_learning::{NoiseFamily, ProceduralSettings, fit_procedural};
use relief_heightfield::NoProgress;

fn main() {
    let Some(hf) = relief_testdata::dem_crop("alps_dem", 900, 150, 256, 256) else {
        println!("alps_dem absent");
        return;
    };
    println!("alps_dem 256x256 crop, s = 1");
    for patch_size in [10usize, 16] {
        for family in [
            NoiseFamily::Perlin,
            NoiseFamily::RidgedMultifractal,
            NoiseFamily::RidgedSum,
            NoiseFamily::PerlinField,
            NoiseFamily::RidgedField,
        ] {
            for learned in [None, Some(64)] {
                let s = ProceduralSettings {
                    family,
                    n_candidates: 2048,
                    learned_atoms: learned,
                    patch_size,
                    ..Default::default()
                };
                let t = std::time::Instant::now();
                let fit = fit_procedural(&hf, &s, &NoProgress).unwrap();
                println!(
                    "a = {patch_size:2} {family:?}: N = {:4}, PSNR {:.2} dB ({:.1} s)",
                    fit.n_atoms,
                    fit.psnr,
                    t.elapsed().as_secs_f64()
                );
            }
        }
    }
}
