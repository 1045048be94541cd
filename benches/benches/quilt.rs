//! Side-by-side timing of guided patch synthesis (relief-patch-synth, cruz2015) and Embark's
//! `texture-synthesis` 0.8 on the same exemplar, both on 2 threads.
//!
//! * relief-patch-synth: 1024 x 1024 output from the 512 x 512 Grand Canyon DEM (f32 heights),
//!   guided by a low-passed alps crop; index build + synthesis.
//! * texture-synthesis: 512 x 512 output from the same exemplar **converted to 8-bit grey**
//!   (256 levels over the 479..2347 m range, about 7.3 m per level): the peer only takes
//!   images, so its input has lost the precision of the DEM. Its output is not a terrain of
//!   comparable fidelity; the comparison is of running time only.
//!
//! `cargo bench -p relief-benches --bench quilt`
#![allow(clippy::print_stderr)]

use std::time::Instant;

use criterion::{Criterion, criterion_group, criterion_main};
use relief_heightfield::{Heightfield, NoProgress};
use relief_patch_synth::{Control, Exemplar, ExemplarIndex, Settings, guide, synthesize};
use relief_testdata::{dem_crop, load_dem};
use texture_synthesis as ts;

fn inputs() -> Option<(Heightfield, Heightfield)> {
    let ex = load_dem("grandcanyon")?;
    let src = dem_crop("alps_dem", 900, 200, 512, 512)?;
    let src = src.map(|v| 479.0 + (v - 640.0) * (2347.0 - 479.0) / (4115.0 - 640.0));
    let g = guide::lowpass_resample(&src.resample(1024, 1024).ok()?, 16).ok()?;
    Some((ex, g))
}

fn patch_synth(ex: &Heightfield, g: &Heightfield) -> Heightfield {
    let settings = Settings {
        enforce_validation: false,
        ..Default::default()
    };
    let index = ExemplarIndex::build(vec![Exemplar::new(ex.clone(), 0)], &settings, &NoProgress)
        .expect("index");
    synthesize(&index, &Control::guided(g.clone()), &settings, &NoProgress)
        .expect("synthesis")
        .heightfield
}

fn to_gray8(ex: &Heightfield) -> ts::image::DynamicImage {
    let (lo, hi) = ex.min_max().expect("complete exemplar");
    let bytes: Vec<u8> = ex
        .as_slice()
        .iter()
        .map(|&v| ((v - lo) / (hi - lo) * 255.0).round().clamp(0.0, 255.0) as u8)
        .collect();
    let img = ts::image::GrayImage::from_raw(ex.width() as u32, ex.height() as u32, bytes)
        .expect("gray image");
    ts::image::DynamicImage::ImageLuma8(img)
}

fn texture_synthesis(img: &ts::image::DynamicImage) -> ts::image::DynamicImage {
    ts::Session::builder()
        .add_example(img.clone())
        .output_size(ts::Dims::square(512))
        .max_thread_count(2)
        .seed(0)
        .build()
        .expect("session")
        .run(None)
        .into_image()
}

fn bench(c: &mut Criterion) {
    let Some((ex, g)) = inputs() else { return };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    let img = to_gray8(&ex);
    // One timed run of each first, so a single `cargo bench` prints both side by side.
    let t = Instant::now();
    pool.install(|| patch_synth(&ex, &g));
    let a = t.elapsed().as_secs_f64();
    let t = Instant::now();
    texture_synthesis(&img);
    let b = t.elapsed().as_secs_f64();
    eprintln!(
        "single run, 2 threads: relief-patch-synth 1024x1024 (f32 DEM) {a:.2} s; texture-synthesis 512x512 (8-bit copy) {b:.2} s"
    );
    let mut group = c.benchmark_group("quilt");
    group.sample_size(10);
    group.bench_function("relief_patch_synth_1024_from_512_2threads", |bch| {
        bch.iter(|| pool.install(|| patch_synth(&ex, &g)))
    });
    group.bench_function("texture_synthesis_512_from_512_8bit_2threads", |bch| {
        bch.iter(|| texture_synthesis(&img))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
