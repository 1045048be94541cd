//! End-to-end tests of `relief quilt` and `relief validate` (guided patch-based synthesis,
//! cruz2015) on crops of the bundled Grand Canyon fixture (`fixtures/grandcanyon.tif`, 512 x 512,
//! ~62 m cells, 479..2347 m): one crop is the exemplar, another (low-passed) the guide.

use std::path::{Path, PathBuf};

use relief_heightfield::Heightfield;
use relief_heightfield::metrics::{rmse, stats};

use crate::common::*;

fn mean(hf: &Heightfield, x0: usize, x1: usize) -> f64 {
    let mut s = 0.0;
    for y in 0..hf.height() {
        for x in x0..x1 {
            s += hf.get(x, y) as f64;
        }
    }
    s / ((x1 - x0) * hf.height()) as f64
}

/// Exemplar: the north-west 256 x 256 quarter; guide: the Gaussian low-pass (sigma 4 cells) of
/// the south-east 128 x 128 crop. The output follows the guide (its low-pass is closer to the
/// guide than the exemplar's own mean level), keeps the exemplar's relief, the seam map has the
/// output's size, validation passes, and the same seed reproduces the same bytes.
#[test]
fn quilt_follows_a_guide_made_from_another_crop() {
    let gc = fixture();
    let (tmp, ex, _) = tmp_with_crop("ex.tif", (0, 0, 256, 256));
    let target = gc.crop(300, 300, 128, 128).unwrap();
    let src = write(tmp.path(), "src.tif", &target);
    let out = tmp.path().join("out.tif");
    let seams = tmp.path().join("seams.png");
    let opts = [
        "--exemplar",
        s(&ex),
        "--guide-from",
        s(&src),
        "--blur",
        "4",
        "--size",
        "128x128",
        "--patch",
        "32",
        "--overlap",
        "8",
        "--seed",
        "11",
        "--min-candidates",
        "100",
    ];
    let quilt = |out: &Path, extra: &[&str]| relief_parts(&[&["quilt", s(out)], &opts, extra]);
    ok(&quilt(&out, &["--seam-map", s(&seams)]));
    let hf = read(&out);
    assert_eq!((hf.width(), hf.height()), (128, 128));
    assert!(!hf.has_voids());
    assert!(
        // Web-Mercator ground cells vary slightly with the crop's latitude.
        (hf.cell_size().0 / gc.cell_size().0 - 1.0).abs() < 0.01,
        "{:?} vs {:?}",
        hf.cell_size(),
        gc.cell_size()
    );
    // Guide fidelity: the same low-pass of the output against the guide.
    let guide = relief_patch_synth::guide::gaussian_blur(&target, 4.0).unwrap();
    let low = relief_patch_synth::guide::gaussian_blur(&hf, 4.0).unwrap();
    let g_std = stats(&guide).unwrap().std as f64;
    let fid = rmse(&low, &guide).unwrap();
    let g_mean = stats(&guide).unwrap().mean as f32;
    let flat = rmse(&guide.map(|_| g_mean), &guide).unwrap();
    assert!(
        fid < 0.6 * flat,
        "guide rmse {fid:.1} m vs flat {flat:.1} m (guide std {g_std:.1})"
    );
    // Real relief, not a blurred copy of the guide: the detail left after the low-pass is
    // comparable to the target's own.
    let detail = rmse(&hf, &low).unwrap();
    let target_detail = rmse(&target, &guide).unwrap();
    assert!(
        detail > 0.4 * target_detail,
        "detail {detail:.1} vs {target_detail:.1}"
    );
    // Seam map PNG at the output size.
    let png = relief_io::read(
        &seams,
        &relief_io::ReadOptions {
            png: relief_io::PngMode::TerrainRgb,
            ..Default::default()
        },
    )
    .expect("seam map png")
    .heightfield;
    assert_eq!((png.width(), png.height()), (128, 128));
    // Same seed, same bytes.
    let out2 = tmp.path().join("out2.tif");
    ok(&quilt(&out2, &[]));
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&out2).unwrap());
    // The landform pass (default) drains the quilt: no closed depression, where the patches
    // as blended (--landform off) hold some; its box averages over quarter patches stay.
    let raw = tmp.path().join("raw.tif");
    ok(&quilt(&raw, &["--landform", "off"]));
    let raw = read(&raw);
    let drainage = relief_landscape::stats::drainage;
    assert!(drainage(&raw).pits_per_km2 > 0.0);
    assert_eq!(drainage(&hf).pits_per_km2, 0.0);
    let (a, b) = (
        hf.downsample_box(8).unwrap(),
        raw.downsample_box(8).unwrap(),
    );
    assert!(rmse(&a, &b).unwrap() < 0.005 * f64::from(raw.relief()));
    // The input check alone passes and says so.
    let stdout = ok(&relief_parts(&[&["validate"], &opts]));
    assert!(stdout.contains("result:          ok"), "{stdout}");
    assert!(stdout.contains("0 of 25 fail"), "{stdout}");
}

/// A guide 3000 m above every exemplar height: `validate` lists failing blocks and the missing
/// height range and exits non-zero with one stderr line; `quilt` refuses and writes nothing.
#[test]
fn validation_names_missing_heights_and_quilt_refuses() {
    let gc = fixture();
    let (tmp, ex, _) = tmp_with_crop("ex.tif", (0, 0, 192, 192));
    let mut guide = gc.crop(256, 256, 96, 96).unwrap().map(|v| v + 3000.0);
    // Left third at the exemplar's heights: only the other blocks fail.
    for y in 0..96 {
        for x in 0..32 {
            guide.set(x, y, gc.get(x, y));
        }
    }
    let g = write(tmp.path(), "guide.tif", &guide);
    let base = [
        "--exemplar",
        s(&ex),
        "--guide",
        s(&g),
        "--patch",
        "32",
        "--overlap",
        "8",
    ];
    let res = relief_parts(&[&["validate"], &base]);
    let stdout = String::from_utf8_lossy(&res.stdout);
    let err = fails_with(&res, &[], &[]);
    assert!(err.starts_with("error: validation failed"), "{err}");
    assert!(stdout.contains("failing block:   (3, 0)"), "{stdout}");
    assert!(stdout.contains("result:          FAILED"), "{stdout}");
    let missing: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("missing heights:"))
        .collect();
    assert!(!missing.is_empty(), "{stdout}");
    // The missing range lies above the exemplar's maximum.
    let ex_max = gc.crop(0, 0, 192, 192).unwrap().min_max().unwrap().1;
    let hi: f32 = missing[0]
        .split_whitespace()
        .rev()
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    assert!(hi > ex_max + 1000.0, "{} vs {ex_max}", missing[0]);

    let out = tmp.path().join("out.tif");
    let res = relief_parts(&[&["quilt", s(&out)], &base]);
    fails_with(&res, &["validation failed"], &[&out]);
}

/// The lowest and the highest 96 x 96 crops of `gc` (by mean height, on a 32-cell grid).
fn lowest_and_highest_crops(gc: &Heightfield) -> (Heightfield, Heightfield) {
    let mut crops: Vec<(f64, usize, usize)> = Vec::new();
    for y in (0..=416).step_by(32) {
        for x in (0..=416).step_by(32) {
            let c = gc.crop(x, y, 96, 96).unwrap();
            crops.push((stats(&c).unwrap().mean, x, y));
        }
    }
    crops.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (lo, hi) = (crops[0], crops[crops.len() - 1]);
    (
        gc.crop(lo.1, lo.2, 96, 96).unwrap(),
        gc.crop(hi.1, hi.2, 96, 96).unwrap(),
    )
}

/// Asserts that columns well inside each half of `hf` (away from the patches straddling the
/// border) have the mean height of their own exemplar: `low` on the left, `high` on the right.
fn assert_halves_follow(hf: &Heightfield, low: &Heightfield, high: &Heightfield, what: &str) {
    let (ml, mr) = (mean(hf, 0, 30), mean(hf, 82, 112));
    let (el, er) = (stats(low).unwrap().mean, stats(high).unwrap().mean);
    assert!(
        (ml - el).abs() < 0.25 * (er - el) && (mr - er).abs() < 0.25 * (er - el),
        "left {ml:.0} (low exemplar {el:.0}), right {mr:.0} (high exemplar {er:.0}); {what}"
    );
}

/// Categorisation map: left half category 0 (exemplar from the low canyon floor), right half
/// category 1 (exemplar from the high plateau); unguided, no vertical translations. Each half
/// of the output takes its heights from its own exemplar.
#[test]
fn categorisation_map_picks_the_exemplar_per_region() {
    let gc = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let (low, high) = lowest_and_highest_crops(&gc);
    let (lo_max, hi_min) = (low.min_max().unwrap().1, high.min_max().unwrap().0);
    let a = write(tmp.path(), "low.tif", &low);
    let b = write(tmp.path(), "high.tif", &high);
    let (w, h) = (112usize, 64usize);
    let map: Vec<u8> = (0..w * h)
        .map(|i| if i % w < w / 2 { 0 } else { 1 })
        .collect();
    let map_png = tmp.path().join("map.png");
    relief_io::write_gray_png(&map_png, w, h, &map).unwrap();
    let out = tmp.path().join("out.tif");
    ok(&relief_line(
        "quilt {} --exemplar {} --exemplar {} --exemplar-categories 0,1 \
         --categories {} --size 112x64 --patch 24 --overlap 6 --lambda 0 \
         --min-candidates 10",
        &[&out, &a, &b, &map_png],
    ));
    let hf = read(&out);
    assert_eq!((hf.width(), hf.height()), (112, 64));
    assert_halves_follow(&hf, &low, &high, &format!("ranges ..{lo_max}, {hi_min}.."));
}

/// `--auto-categories 2`: the low and the high exemplar fall into categories 0 and 1 (ordered
/// by height), the guide (low crop's low-pass on the left, high crop's on the right) is split
/// into two height classes, and each half of the output comes from its own exemplar.
#[test]
fn auto_categories_cluster_exemplars_and_guide() {
    let gc = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let (low, high) = lowest_and_highest_crops(&gc);
    let a = write(tmp.path(), "low.tif", &low);
    let b = write(tmp.path(), "high.tif", &high);
    let guide = Heightfield::from_fn(112, 64, 61.7, 61.7, |x, y| {
        if x < 56 {
            low.get(x + 20, y + 16)
        } else {
            high.get(x - 56 + 20, y + 16)
        }
    });
    let g = write(tmp.path(), "guide.tif", &guide);
    let out = tmp.path().join("out.tif");
    let res = relief_loud(&[
        "quilt",
        s(&out),
        "--exemplar",
        s(&a),
        "--exemplar",
        s(&b),
        "--guide-from",
        s(&g),
        "--blur",
        "3",
        "--auto-categories",
        "2",
        "--patch",
        "24",
        "--overlap",
        "6",
        "--lambda",
        "0",
        "--no-validate",
    ]);
    ok(&res);
    let err = stderr(&res);
    assert!(
        err.contains("exemplar categories (clustered): 0,1"),
        "{err}"
    );
    assert_halves_follow(&read(&out), &low, &high, "");
}

/// Without a guide, `validate` checks the exemplars' mutual compatibility: a crop raised by
/// 5000 m (translations disabled with `--lambda 0`) matches nothing of the other exemplar.
#[test]
fn unguided_validation_flags_an_incompatible_exemplar() {
    let gc = fixture();
    let (tmp, a, _) = tmp_with_crop("a.tif", (0, 0, 96, 96));
    let b = write(tmp.path(), "b.tif", &gc.crop(200, 200, 96, 96).unwrap());
    let raised = write(
        tmp.path(),
        "raised.tif",
        &gc.crop(300, 100, 96, 96).unwrap().map(|v| v + 5000.0),
    );
    let run = |third: &Path| {
        relief_line(
            "validate --exemplar {} --exemplar {} --exemplar {} --size 128x128 \
             --patch 24 --overlap 6 --lambda 0 --min-candidates 50",
            &[&a, &b, &third],
        )
    };
    let same = write(tmp.path(), "c.tif", &gc.crop(100, 300, 96, 96).unwrap());
    let stdout = ok(&run(&same));
    assert_eq!(stdout.matches("compatibility:").count(), 3, "{stdout}");
    let bad = run(&raised);
    let stdout = String::from_utf8_lossy(&bad.stdout);
    fails_with(&bad, &["incompatible"], &[]);
    let line = stdout
        .lines()
        .find(|l| l.starts_with("compatibility:") && l.contains("raised.tif"))
        .unwrap_or_default()
        .to_string();
    assert!(
        line.contains("TOO FEW") && line.contains(": 0 of"),
        "{stdout}"
    );
}

/// Bad inputs fail with one stderr line naming the problem, and leave no output file.
#[test]
fn bad_inputs_exit_non_zero_with_one_line() {
    let (tmp, ex, _) = tmp_with_crop("ex.tif", (0, 0, 48, 48));
    let out = tmp.path().join("out.tif");
    let ex = s(&ex);
    let cases: [(&[&str], &str); 5] = [
        // patch larger than the exemplar
        (
            &[
                "--exemplar",
                ex,
                "--size",
                "64x64",
                "--patch",
                "64",
                "--overlap",
                "8",
            ],
            "smaller than patch_size 64",
        ),
        // overlap >= patch
        (
            &[
                "--exemplar",
                ex,
                "--size",
                "64x64",
                "--patch",
                "16",
                "--overlap",
                "16",
            ],
            "`overlap` = 16",
        ),
        // empty exemplar list
        (
            &["--size", "64x64", "--patch", "16", "--overlap", "4"],
            "no exemplar",
        ),
        // unreadable exemplar
        (
            &["--exemplar", "/nonexistent/dem.tif", "--size", "64x64"],
            "/nonexistent/dem.tif",
        ),
        // guide-from without blur
        (
            &[
                "--exemplar",
                ex,
                "--guide-from",
                ex,
                "--patch",
                "16",
                "--overlap",
                "4",
            ],
            "--blur",
        ),
    ];
    for (args, expect) in cases {
        for cmd in [&["quilt", s(&out)][..], &["validate"]] {
            fails_with(&relief_parts(&[cmd, args]), &[expect], &[&out]);
        }
    }
    // A malformed size is a usage error of the flag's value parser (clap adds its `--help`
    // hint line).
    for cmd in [&["quilt", s(&out)][..], &["validate"]] {
        let e = failed(&relief_parts(&[cmd, &["--exemplar", ex, "--size", "64y"]]));
        assert!(e.contains("'--size <WxH>'") && e.contains("`64y`"), "{e}");
        assert!(!out.exists());
    }
}

fn quantile(v: &[f32], p: f64) -> f64 {
    let mut s: Vec<f32> = v.iter().copied().filter(|x| x.is_finite()).collect();
    s.sort_by(f32::total_cmp);
    s[((s.len() - 1) as f64 * p).round() as usize] as f64
}

/// The fixture's north-west 160 x 160 crop written as `ex.tif` in `dir`: the crop, its path and
/// its cell size as read back (its georeference gives the ground size at the crop).
fn exemplar_160(dir: &Path) -> (Heightfield, PathBuf, (f64, f64)) {
    let ex = fixture().crop(0, 0, 160, 160).unwrap();
    let ex_p = write(dir, "ex.tif", &ex);
    let cell = read(&ex_p).cell_size();
    (ex, ex_p, cell)
}

/// Issue 17: a guide in other units (a 0-255 sketch at twice the exemplar's cell size) is
/// mapped onto the exemplar's heights by `--guide-range auto` and resampled to the exemplar's
/// cells over its own extent (no squashing); `--guide-out` writes it exactly as used.
/// With `--size` the guide keeps its scale and is cropped (centred); a PNG of grey levels
/// without `--guide-range` is refused.
#[test]
fn guide_range_auto_and_guide_out() {
    let tmp = tempfile::tempdir().unwrap();
    let (ex, ex_p, (cx, cy)) = exemplar_160(tmp.path());
    let sketch = Heightfield::from_fn(48, 40, 2.0 * cx, 2.0 * cy, |x, y| {
        (127.0 + 120.0 * ((x as f32) * 0.15).sin() * ((y as f32) * 0.11).cos()).round()
    });
    let g_p = write(tmp.path(), "sketch.tif", &sketch);
    let out = tmp.path().join("q.tif");
    let used = tmp.path().join("guide_used.tif");
    ok(&relief_line(
        "quilt {} --exemplar {} --guide {} --guide-range auto --guide-out {} \
         --patch-size 32 --overlap 8 --no-validate",
        &[&out, &ex_p, &g_p, &used],
    ));
    let g = read(&used);
    // Twice the exemplar's cell: twice the cells, same ground.
    assert_eq!((g.width(), g.height()), (96, 80));
    let (gx, gy) = g.cell_size();
    assert!(
        (gx / cx - 1.0).abs() < 1e-6 && (gy / cy - 1.0).abs() < 1e-6,
        "{gx} x {gy} vs {cx} x {cy}"
    );
    // Mapped into the exemplar's heights (the extremes of the guide's patch-window means go
    // onto quantiles of the exemplar patches' means), spanning most of them.
    let (elo, ehi) = (quantile(ex.as_slice(), 0.02), quantile(ex.as_slice(), 0.98));
    let (glo, ghi) = (quantile(g.as_slice(), 0.02), quantile(g.as_slice(), 0.98));
    let tol = 0.15 * (ehi - elo);
    assert!(
        glo > elo - tol && ghi < ehi + tol && ghi - glo > 0.3 * (ehi - elo),
        "{glo}..{ghi} vs {elo}..{ehi}"
    );
    let q = read(&out);
    assert_eq!((q.width(), q.height()), (96, 80));
}

/// Issue 17: `--size` crops the guide (centred) at the exemplar's cell size instead of
/// rescaling it; `--guide-cell-size` gives a guide its cells; a grey-level PNG
/// guide needs `--guide-range`.
#[test]
fn guide_is_cropped_not_rescaled_and_png_needs_a_range() {
    let tmp = tempfile::tempdir().unwrap();
    let dem = fixture();
    let (_, ex_p, (cx, cy)) = exemplar_160(tmp.path());
    // A guide in metres at twice the exemplar's cells: 96 x 80 cells on the exemplar's grid.
    let g = dem
        .crop(200, 200, 48, 40)
        .unwrap()
        .resample(48, 40)
        .unwrap();
    let mut g = g;
    g.set_georef(None);
    g.set_cell_size(2.0 * cx, 2.0 * cy).unwrap();
    let g_p = write(tmp.path(), "g.tif", &g);
    let run = |extra: &[&str], out: &Path, used: &Path| {
        let (ex, out, used) = (s(&ex_p), s(out), s(used));
        let base = [
            "quilt",
            out,
            "--exemplar",
            ex,
            "--guide-out",
            used,
            "--patch-size",
            "32",
        ];
        relief_parts(&[&base, &["--overlap", "8", "--no-validate"], extra])
    };
    let (full, full_g) = (tmp.path().join("full.tif"), tmp.path().join("full_g.tif"));
    ok(&run(&["--guide", s(&g_p)], &full, &full_g));
    let (crop, crop_g) = (tmp.path().join("crop.tif"), tmp.path().join("crop_g.tif"));
    ok(&run(
        &["--guide", s(&g_p), "--size", "64x48"],
        &crop,
        &crop_g,
    ));
    let (a, b) = (read(&full_g), read(&crop_g));
    assert_eq!((a.width(), a.height()), (96, 80));
    assert_eq!((b.width(), b.height()), (64, 48));
    let (bx, by) = b.cell_size();
    assert!((bx / cx - 1.0).abs() < 1e-6 && (by / cy - 1.0).abs() < 1e-6);
    for (x, y) in [(0, 0), (63, 47), (30, 20)] {
        assert_eq!(b.get(x, y), a.get(16 + x, 16 + y), "({x}, {y})");
    }
    assert_eq!((read(&crop).width(), read(&crop).height()), (64, 48));

    // The same guide as a grey-level PNG without a cell size: refused without --guide-range,
    // and --guide-cell-size restores its ground extent.
    let (lo, hi) = g.min_max().unwrap();
    let grey: Vec<u8> = g
        .as_slice()
        .iter()
        .map(|&v| (255.0 * (v - lo) / (hi - lo)).round() as u8)
        .collect();
    let png = tmp.path().join("sketch.png");
    relief_io::write_gray_png(&png, 48, 40, &grey).unwrap();
    let (out, used) = (tmp.path().join("png.tif"), tmp.path().join("png_g.tif"));
    let o = run(&["--guide", s(&png)], &out, &used);
    fails_with(&o, &["--guide-range"], &[&out, &used]);
    let cell = format!("{},{}", 2.0 * cx, 2.0 * cy);
    let extra = [
        "--guide",
        s(&png),
        "--guide-range",
        "auto",
        "--guide-cell-size",
        &cell,
    ];
    ok(&run(&extra, &out, &used));
    let u = read(&used);
    assert_eq!((u.width(), u.height()), (96, 80));
    // Without --guide-cell-size the painted PNG is taken at the exemplar's cells (one guide
    // cell per output cell, with a note), not at the reader's 1 m, which shrank it to a
    // cell or two and mirror-padded that over the output.
    let (out, used) = (tmp.path().join("png1.tif"), tmp.path().join("png1_g.tif"));
    ok(&run(
        &["--guide", s(&png), "--guide-range", "auto"],
        &out,
        &used,
    ));
    let u = read(&used);
    assert_eq!((u.width(), u.height()), (48, 40));
    let corr = relief_heightfield::metrics::pearson(
        u.as_slice(),
        &grey.iter().map(|&v| v as f32).collect::<Vec<_>>(),
    );
    assert!(corr > 0.95, "guide as used vs the painted PNG: {corr}");
    // A 16-bit PNG relief wrote keeps its cell size through its `.png.json` sidecar.
    let (first, used_png) = (tmp.path().join("first.tif"), tmp.path().join("used.png"));
    ok(&run(&["--guide", s(&g_p)], &first, &used_png));
    let (again, used) = (tmp.path().join("again.tif"), tmp.path().join("again_g.tif"));
    ok(&run(&["--guide", s(&used_png)], &again, &used));
    let u = read(&used);
    assert_eq!((u.width(), u.height()), (96, 80));
    let (ux, uy) = u.cell_size();
    assert!((ux / cx - 1.0).abs() < 1e-6 && (uy / cy - 1.0).abs() < 1e-6);
}

/// `--guide-sketch FILE.json`: a ridge stroke (high) across a low seed field gives an output
/// that is high along the stroke and low at the seeds; a malformed sketch or a second guide is
/// refused with the file or the flags named, and nothing is written.
#[test]
fn quilt_follows_a_sketch_guide_file() {
    let gc = fixture();
    let (tmp, ex, _) = tmp_with_crop("ex.tif", (0, 0, 256, 256));
    let sketch = tmp.path().join("sketch.json");
    // A high ridge along the middle row, low corners.
    std::fs::write(
        &sketch,
        r#"{"width": 96, "height": 96, "smoothing": 3,
            "seeds": [{"x": 4, "y": 4, "height": 1500, "radius": 4},
                      {"x": 92, "y": 92, "height": 1500, "radius": 4},
                      {"x": 4, "y": 92, "height": 1500, "radius": 4},
                      {"x": 92, "y": 4, "height": 1500, "radius": 4}],
            "strokes": [{"points": [[8, 48, 2050], [88, 48, 2050]]}]}"#,
    )
    .unwrap();
    let out = tmp.path().join("out.tif");
    let run = |extra: &[&str], out: &Path| {
        let opts = ["--exemplar", s(&ex), "--patch", "32", "--overlap", "8"];
        relief_parts(&[
            &["quilt"],
            &opts,
            &["--min-candidates", "40", "--seed", "5"],
            extra,
            &[s(out)],
        ])
    };
    ok(&run(&["--guide-sketch", s(&sketch)], &out));
    let hf = read(&out);
    assert_eq!((hf.width(), hf.height()), (96, 96));
    // The guide as the library rasterises it (the exemplar's cell size).
    let sk: relief_patch_synth::guide::SketchGuide =
        serde_json::from_str(&std::fs::read_to_string(&sketch).unwrap()).unwrap();
    let guide = sk.render(gc.cell_size()).unwrap();
    let band = |g: &Heightfield, y0: usize, y1: usize| {
        let mut s = 0.0;
        for y in y0..y1 {
            for x in 24..72 {
                s += g.get(x, y) as f64;
            }
        }
        s / ((y1 - y0) * 48) as f64
    };
    let rise = |g: &Heightfield| band(g, 40, 56) - (band(g, 0, 12) + band(g, 84, 96)) / 2.0;
    let (out_rise, guide_rise) = (rise(&hf), rise(&guide));
    assert!(guide_rise > 150.0, "guide rise {guide_rise:.0} m");
    assert!(
        out_rise > 0.6 * guide_rise,
        "ridge rise {out_rise:.0} m against the guide's {guide_rise:.0} m"
    );
    // A malformed sketch names the file; two guides are refused; nothing is written.
    let bad = tmp.path().join("bad.json");
    std::fs::write(&bad, r#"{"width": 96, "height": 96, "seedz": []}"#).unwrap();
    let out2 = tmp.path().join("out2.tif");
    let res = run(&["--guide-sketch", s(&bad)], &out2);
    fails_with(&res, &["bad.json"], &[&out2]);
    let res = run(&["--guide-sketch", s(&sketch), "--guide", s(&ex)], &out2);
    fails_with(&res, &["--guide-sketch"], &[&out2]);
}
