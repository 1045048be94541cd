//! End-to-end tests of `relief amplify`, `relief synthesize`, `relief fit-procedural` and
//! `relief learn` on crops of the bundled real DEM `fixtures/grandcanyon.tif` (512 x 512,
//! 76.4 m Web-Mercator pixels), plus bad input: non-zero exit, one line on stderr, no output.

#![allow(clippy::print_stderr)] // the tests report their measured figures

use std::path::Path;
use std::process::Output;

use relief_heightfield::{Heightfield, metrics};
use relief_sparse_core::{FunctionAtomRegistry, RasterSettings, Sct};

use crate::common::*;

/// Asserts a clean failure naming every `needle`, and no `output`.
fn fails(out: &Output, output: &Path, needles: &[&str]) {
    fails_with(out, needles, &[output]);
}

/// The `.sct` model at `path` (data atoms only).
fn read_model(path: &Path) -> Sct {
    Sct::from_bytes(&std::fs::read(path).unwrap(), &FunctionAtomRegistry::new()).unwrap()
}

/// x4: a 128^2 crop reduced to 32^2, amplified back with an exemplar from another part of the
/// DEM. The output has the right size and cell size, stays consistent with its input, is
/// closer to the truth than the input's relief, and the `.sct` and `--window` outputs agree
/// with the raster.
#[test]
fn amplify_x4_on_grand_canyon() {
    let dem = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let truth = dem.crop(64, 64, 128, 128).unwrap();
    let coarse = truth.resample(32, 32).unwrap();
    let exemplar = dem.crop(256, 256, 256, 256).unwrap();
    let cin = write(tmp.path(), "coarse.tif", &coarse);
    let ex = write(tmp.path(), "ex.tif", &exemplar);
    let out_tif = tmp.path().join("out.tif");
    let common = |out: &Path, extra: &[&str]| {
        // The raw method (the .sct model has no landform pass).
        let line = "amplify {} {} --exemplar {} --factor 4 --seed 3 --atoms 64 --landform off";
        relief_line_plus(line, &[&cin, &out, &ex], extra)
    };
    ok(&common(&out_tif, &[]));
    let out = read(&out_tif);
    assert_eq!((out.width(), out.height()), (128, 128));
    let (cx, _) = out.cell_size();
    let coarse_cx = read(&cin).cell_size().0;
    assert!(
        (cx / (coarse_cx / 4.0) - 1.0).abs() < 1e-6,
        "{cx} vs {coarse_cx} / 4"
    );
    let relief_m = truth.relief() as f64;
    let back = out.resample(32, 32).unwrap();
    let consistency = metrics::rmse(&back, &coarse).unwrap() / relief_m;
    let vs_truth = metrics::rmse(&out, &truth).unwrap() / relief_m;
    eprintln!("amplify x4: consistency {consistency:.4}, rmse vs truth {vs_truth:.4} of relief");
    assert!(consistency < 0.06, "{consistency}");
    assert!(vs_truth < 0.08, "{vs_truth}");
    // It added detail beyond the input's band: the part of the output a x4 low-pass removes
    // is several times that of the bicubic up-sampling and of the order of the truth's.
    let hf_energy = |h: &Heightfield| {
        let smooth = h.resample(32, 32).unwrap().resample(128, 128).unwrap();
        metrics::rmse(h, &smooth).unwrap()
    };
    let bicubic = coarse.resample(128, 128).unwrap();
    let (e_out, e_bic, e_truth) = (hf_energy(&out), hf_energy(&bicubic), hf_energy(&truth));
    eprintln!(
        "detail above the input band: out {e_out:.1} m, bicubic {e_bic:.1} m, truth {e_truth:.1} m"
    );
    assert!(e_out > 2.0 * e_bic, "{e_out} {e_bic}");
    assert!(
        e_out > 0.3 * e_truth && e_out < 3.0 * e_truth,
        "{e_out} {e_truth}"
    );

    // Same seed: the same bytes.
    let again = tmp.path().join("again.tif");
    ok(&common(&again, &[]));
    assert_eq!(
        std::fs::read(&again).unwrap(),
        std::fs::read(&out_tif).unwrap()
    );

    // The .sct model rasterises to the same terrain.
    let sct_path = tmp.path().join("out.sct");
    ok(&common(&sct_path, &[]));
    let sct = read_model(&sct_path);
    assert_eq!((sct.width(), sct.height()), (128, 128));
    let r = sct.rasterize(&RasterSettings::default()).unwrap();
    assert!(metrics::rmse(&r, &out).unwrap() < 1e-3);
    // Its residual is a Lanczos-3 field on the input's grid, and `info` says so;
    // `--residual-kernel keys` stores a Keys field and changes the terrain.
    assert_eq!(sct.fields().len(), 1);
    assert_eq!(
        sct.fields()[0].kernel(),
        relief_heightfield::Kernel::Lanczos3
    );
    let text = relief_ok!["info", sct_path];
    assert!(
        text.contains("field 0: 32 x 32 samples every 4.0 pixels, lanczos3"),
        "{text}"
    );
    let keys_path = tmp.path().join("keys.sct");
    ok(&common(&keys_path, &["--residual-kernel", "keys"]));
    let keys = read_model(&keys_path);
    assert_eq!(keys.fields()[0].kernel(), relief_heightfield::Kernel::Keys);
    let rk = keys.rasterize(&RasterSettings::default()).unwrap();
    let d = metrics::rmse(&rk, &r).unwrap();
    assert!(
        d > 0.01,
        "Keys and Lanczos-3 residuals give the same terrain ({d} m)"
    );

    // Streamed band by band (GeoTIFF strip writer): the same raster.
    let streamed = tmp.path().join("streamed.tif");
    ok(&common(&streamed, &["--stream"]));
    let st = read(&streamed);
    assert_eq!((st.width(), st.height()), (128, 128));
    assert!(metrics::rmse(&st, &out).unwrap() < 1e-4);
    let streamed_win = tmp.path().join("streamed_win.tif");
    ok(&common(
        &streamed_win,
        &["--stream", "--window", "40,8,50,60"],
    ));
    let sw = read(&streamed_win);
    assert!(metrics::rmse(&sw, &out.crop(40, 8, 50, 60).unwrap()).unwrap() < 1e-4);

    // A window is the matching crop of the whole raster.
    let win = tmp.path().join("win.tif");
    ok(&common(&win, &["--window", "40,8,50,60"]));
    let w = read(&win);
    assert_eq!((w.width(), w.height()), (50, 60));
    let crop = out.crop(40, 8, 50, 60).unwrap();
    let max = metrics::max_abs_diff(&w, &crop).unwrap();
    assert!(max < 1e-3, "{max}");
}

/// The correlation of `out` resampled to the size of `small` with `small`: how well a result
/// follows its coarse input or sketch at large scale.
fn correlation_at(out: &Heightfield, small: &Heightfield) -> f64 {
    let back = out.resample(small.width(), small.height()).unwrap();
    relief_heightfield::metrics::pearson(back.as_slice(), small.as_slice())
}

/// x16 in two steps from 16^2 to 256^2 with a small radius.
#[test]
fn amplify_x16_two_steps() {
    let dem = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let truth = dem.crop(0, 0, 256, 256).unwrap();
    let coarse = truth.resample(16, 16).unwrap();
    let cin = write(tmp.path(), "coarse.tif", &coarse);
    let ex = write(tmp.path(), "ex.tif", &dem.crop(256, 0, 256, 256).unwrap());
    let out_path = tmp.path().join("out.exr");
    let out = ok_read(
        "amplify {} {} --exemplar {} --factor 16 --radius 2 --atoms 0",
        &[&cin, &out_path, &ex],
    );
    assert_eq!((out.width(), out.height()), (256, 256));
    let c = correlation_at(&out, &coarse);
    assert!(c > 0.95, "correlation with the input {c}");
}

/// A 16 x 16 sketch painted by `f` of the coordinates from its centre.
fn centred_sketch(f: impl Fn(f32, f32) -> f32) -> Heightfield {
    Heightfield::from_fn(16, 16, 1.0, 1.0, |x, y| f(x as f32 - 7.5, y as f32 - 7.5))
}

/// Figure 12: a painted sketch (a ridge and a basin) becomes a terrain with the exemplar's
/// elevation range whose large-scale shape follows the sketch.
/// `--rivers` and `--ridges`: a river painted from the southern edge into a painted range
/// becomes a valley (lower than the same ground grown without it), a ridge line raises the
/// ground under it; strokes of the wrong size or without the grown relief are refused.
#[test]
fn synthesize_follows_ridge_and_river_strokes() {
    let dem = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let sketch = centred_sketch(|x, y| 255.0 * (-(x * x + y * y) / 40.0).exp());
    let river = Heightfield::from_fn(16, 16, 1.0, 1.0, |x, y| {
        if x == 11 && y >= 7 { 255.0 } else { 0.0 }
    });
    let ridge = Heightfield::from_fn(16, 16, 1.0, 1.0, |x, y| {
        if y == 4 && (3..13).contains(&x) {
            255.0
        } else {
            0.0
        }
    });
    let sk = write(tmp.path(), "sketch.npy", &sketch);
    let rv = write(tmp.path(), "river.npy", &river);
    let rg = write(tmp.path(), "ridge.npy", &ridge);
    let ex = write(tmp.path(), "ex.tif", &dem.crop(0, 0, 384, 384).unwrap());
    let line =
        "synthesize {} {} --exemplar {} --steps 2 --sketch-cell-size 1000 --height-range 0,2000";
    let plain = ok_read(line, &[&sk, &tmp.path().join("plain.tif"), &ex]);
    let strokes_out = tmp.path().join("strokes.tif");
    let with = ok_read(
        &format!("{line} --rivers {{}} --ridges {{}}"),
        &[&sk, &strokes_out, &ex, &rv, &rg],
    );
    // Mean height over sketch cells (x0..x1, y0..y1) (16 output cells each).
    let mean = |z: &Heightfield, x0: usize, x1: usize, y0: usize, y1: usize| {
        let mut s = 0.0f64;
        for y in 16 * y0..16 * y1 {
            for x in 16 * x0..16 * x1 {
                s += f64::from(z.get(x, y));
            }
        }
        s / (256 * (x1 - x0) * (y1 - y0)) as f64
    };
    let (r_with, r_plain) = (mean(&with, 11, 12, 8, 13), mean(&plain, 11, 12, 8, 13));
    assert!(r_with < r_plain - 100.0, "river {r_with} vs {r_plain} m");
    let (g_with, g_plain) = (mean(&with, 4, 12, 4, 5), mean(&plain, 4, 12, 4, 5));
    eprintln!(
        "strokes: river {r_with:.0} m (without {r_plain:.0}), ridge {g_with:.0} m (without {g_plain:.0})"
    );
    assert!(g_with > g_plain + 50.0, "ridge {g_with} vs {g_plain} m");
    // Refused: strokes of another size, and strokes without the grown relief.
    let small = write(
        tmp.path(),
        "small.npy",
        &Heightfield::from_fn(5, 5, 1.0, 1.0, |_, _| 0.0),
    );
    let bad_out = tmp.path().join("bad.tif");
    fails(
        &relief_line(
            &format!("{line} --rivers {{}}"),
            &[&sk, &bad_out, &ex, &small],
        ),
        &bad_out,
        &["river strokes (5x5)"],
    );
    fails(
        &relief_line(
            &format!("{line} --ridges {{}} --landform off"),
            &[&sk, &bad_out, &ex, &rg],
        ),
        &bad_out,
        &["--ridges and --rivers"],
    );
}

#[test]
fn synthesize_from_painted_sketch() {
    let dem = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let sketch = centred_sketch(|x, y| {
        let ridge = (-(x - 0.5 * y).powi(2) / 8.0).exp();
        let basin = (-((x - 5.0).powi(2) + (y + 5.0).powi(2)) / 6.0).exp();
        60_000.0 * (0.3 + 0.6 * ridge - 0.3 * basin)
    });
    let sk = write(tmp.path(), "sketch.png", &sketch);
    let ex = write(tmp.path(), "ex.tif", &dem.crop(0, 0, 384, 384).unwrap());
    let out_path = tmp.path().join("terrain.tif");
    let out = ok_read(
        "synthesize {} {} --exemplar {} --steps 2 --height-range 500,2300",
        &[&sk, &out_path, &ex],
    );
    assert_eq!((out.width(), out.height()), (256, 256));
    let (lo, hi) = out.min_max().unwrap();
    // The detail (the exemplar's, at the canyon's own amplitude of a few hundred metres)
    // reaches beyond the sketch's 500-2300 m, but not by more than that.
    assert!(lo > 0.0 && hi < 2800.0 && hi - lo > 1200.0, "{lo}..{hi}");
    // By default the sketch is an uplift map grown into a drained range (its lowest paint, the
    // basin, becomes a plain): it follows the painting less literally than the sketch's pixels
    // amplified directly (--landform off).
    let c = correlation_at(&out, &read(&sk));
    assert!(c > 0.8, "correlation with the sketch {c}");
    let literal_path = tmp.path().join("literal.tif");
    let literal = ok_read(
        "synthesize {} {} --exemplar {} --steps 2 --height-range 500,2300 --landform off",
        &[&sk, &literal_path, &ex],
    );
    let cl = correlation_at(&literal, &read(&sk));
    assert!(
        cl > 0.95,
        "correlation with the sketch {cl} (--landform off)"
    );
    let pits = |hf: &Heightfield| relief_landscape::stats::drainage(hf).pits_per_km2;
    assert!(
        pits(&out) < pits(&literal),
        "{} vs {}",
        pits(&out),
        pits(&literal)
    );
    // The output has the exemplar's cell size (as read back: EPSG:3857 metres at the crop's
    // latitude); --exemplar-cell-size overrides it.
    let ex_cell = read(&ex).cell_size();
    assert!(
        (out.cell_size().0 - ex_cell.0).abs() < 1e-6,
        "{:?} vs {ex_cell:?}",
        out.cell_size()
    );
    let scaled = tmp.path().join("scaled.tif");
    let s = ok_read(
        "synthesize {} {} --exemplar {} --steps 1 --exemplar-cell-size 30",
        &[&sk, &scaled, &ex],
    );
    assert_eq!((s.width(), s.height()), (64, 64));
    assert!((s.cell_size().0 - 30.0).abs() < 1e-6, "{:?}", s.cell_size());
    // --sketch-cell-size sets the sketch's extent: 16 cells of 400 m, one x4 step -> 100 m.
    let sized = tmp.path().join("sized.tif");
    let z = ok_read(
        "synthesize {} {} --exemplar {} --steps 1 --sketch-cell-size 400 --landform off",
        &[&sk, &sized, &ex],
    );
    assert!(
        (z.cell_size().0 - 100.0).abs() < 1e-6,
        "{:?}",
        z.cell_size()
    );
    // The structure step differs from --structure-radius 0 (the x4 steps alone), which keeps
    // the sketch's shape more closely.
    let off = tmp.path().join("off.tif");
    let o = ok_read(
        "synthesize {} {} --exemplar {} --steps 1 --sketch-cell-size 400 --structure-radius 0 --landform off",
        &[&sk, &off, &ex],
    );
    let (cz, co) = (
        correlation_at(&z, &read(&sk)),
        correlation_at(&o, &read(&sk)),
    );
    assert!(z.as_slice() != o.as_slice());
    assert!(
        co > cz && cz > 0.8,
        "correlation with the sketch {cz} (structure), {co} (off)"
    );
    // Bad values are refused before anything is written: a structure radius by the library
    // (one line naming it), a cell size already by the argument parser.
    let bad = tmp.path().join("bad.tif");
    for value in ["0.5", "nan", "65"] {
        let out = relief_line_plus(
            "synthesize {} {} --exemplar {} --steps 1",
            &[&sk, &bad, &ex],
            &["--structure-radius", value],
        );
        fails(&out, &bad, &["structure radius"]);
    }
    for value in ["0", "-5", "inf"] {
        let arg = format!("--sketch-cell-size={value}");
        let out = relief_line_plus(
            "synthesize {} {} --exemplar {} --steps 1",
            &[&sk, &bad, &ex],
            &[&arg],
        );
        assert!(
            !out.status.success() && !bad.exists(),
            "--sketch-cell-size {value}"
        );
        assert!(String::from_utf8_lossy(&out.stderr).contains("--sketch-cell-size"));
    }
}

fn psnr_of(stdout: &str) -> f64 {
    let rest = stdout
        .split("psnr: ")
        .nth(1)
        .unwrap_or_else(|| panic!("no psnr in {stdout}"));
    rest.split(" dB").next().unwrap().parse().unwrap()
}

/// Perlin vs ridged atoms on a canyon crop: both fits are written as function-atom `.sct`
/// models that rebuild to the printed PSNR.
#[test]
fn fit_procedural_prints_psnr_and_writes_function_atoms() {
    let dem = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let hf = dem.crop(300, 100, 80, 80).unwrap();
    let input = write(tmp.path(), "in.tif", &hf);
    let mut registry = FunctionAtomRegistry::new();
    relief_dictionary_learning::register_function_atoms(&mut registry);
    let mut psnrs = Vec::new();
    for family in ["perlin", "ridged"] {
        let out_path = tmp.path().join(format!("{family}.sct"));
        let stdout = ok(&relief_line(
            "fit-procedural {} {} --family {} --candidates 256",
            &[&input, &out_path, &family],
        ));
        let printed = psnr_of(&stdout);
        let sct = Sct::from_bytes(&std::fs::read(&out_path).unwrap(), &registry).unwrap();
        assert!(
            sct.layers()[0]
                .dictionary()
                .atoms()
                .iter()
                .all(|a| matches!(a, relief_sparse_core::dictionary::Atom::Function { .. }))
        );
        let rebuilt = sct.rasterize(&RasterSettings::default()).unwrap();
        let psnr = metrics::psnr(&hf, &rebuilt).unwrap();
        assert!((psnr - printed).abs() < 0.01, "{psnr} vs printed {printed}");
        assert!(psnr > 15.0, "{family}: {psnr}");
        psnrs.push(psnr);
        // Analytic atoms: the model rasterises at twice the resolution too.
        let big = sct
            .rasterize(&RasterSettings {
                scale: 2.0,
                window: None,
            })
            .unwrap();
        assert_eq!((big.width(), big.height()), sct.raster_size(2.0).unwrap());
        assert!(big.width() >= 159, "{}", big.width());
    }
    eprintln!(
        "fit-procedural PSNR: perlin {:.2} dB, ridged {:.2} dB",
        psnrs[0], psnrs[1]
    );
}

#[test]
fn bad_input_fails_cleanly() {
    let dem = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let coarse = write(tmp.path(), "coarse.tif", &dem.crop(0, 0, 32, 32).unwrap());
    let ex = write(tmp.path(), "ex.tif", &dem.crop(0, 0, 256, 256).unwrap());
    let out = tmp.path().join("out.tif");
    let amp_with = |input: &Path, ex: &Path, factor: &str, out: &Path, extra: &[&str]| {
        let line = "amplify {} {} --exemplar {} --factor {}";
        relief_line_plus(line, &[&input, &out, &ex, &factor], extra)
    };
    let amp =
        |input: &Path, ex: &Path, factor: &str, out: &Path| amp_with(input, ex, factor, out, &[]);
    // Factor not a power of 4.
    for f in ["8", "2", "1", "0"] {
        fails(&amp(&coarse, &ex, f, &out), &out, &["--factor", f]);
    }
    // Empty exemplar file.
    let empty = tmp.path().join("empty.tif");
    std::fs::write(&empty, b"").unwrap();
    fails(&amp(&coarse, &empty, "4", &out), &out, &["empty.tif"]);
    // An exemplar too small for the patches.
    let tiny = write(tmp.path(), "tiny.tif", &dem.crop(0, 0, 20, 20).unwrap());
    fails(&amp(&coarse, &tiny, "4", &out), &out, &["exemplar"]);
    // NaN (void) cells in the input.
    let mut holes = dem.crop(0, 0, 32, 32).unwrap();
    holes.set(5, 7, f32::NAN);
    let holes = write(tmp.path(), "holes.tif", &holes);
    fails(&amp(&holes, &ex, "4", &out), &out, &["holes.tif", "void"]);
    // Unknown output extension, and a window on a .sct output.
    let odd = tmp.path().join("out.xyz");
    fails(&amp(&coarse, &ex, "4", &odd), &odd, &["out.xyz"]);
    let sct = tmp.path().join("out.sct");
    let o = amp_with(&coarse, &ex, "4", &sct, &["--window", "0,0,4,4"]);
    fails(&o, &sct, &["--window"]);
    // Invalid radius names the field.
    let o = amp_with(&coarse, &ex, "4", &out, &["--radius", "NaN"]);
    fails(&o, &out, &["radius"]);
    // synthesize: zero steps; fit-procedural: unknown family and NaN input.
    let o = relief![
        "synthesize",
        coarse,
        out,
        "--exemplar",
        ex,
        "--x4-steps",
        "0"
    ];
    fails(&o, &out, &["steps"]);
    let sct = tmp.path().join("fit.sct");
    let o = relief!["fit-procedural", coarse, sct, "--family", "simplex"];
    fails(&o, &sct, &["--family", "simplex"]);
    let o = relief!["fit-procedural", holes, sct];
    fails(&o, &sct, &["holes.tif", "void"]);
}

/// `relief learn` from two canyon crops: a K-SVD dictionary file of the asked size whose
/// printed error trace decreases, a constrained variant, and `relief compress --dictionary`
/// using it on a third, unseen crop with a good PSNR.
#[test]
fn learn_writes_a_dictionary_compress_can_use() {
    let dem = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let a = write(tmp.path(), "a.tif", &dem.crop(0, 0, 128, 128).unwrap());
    let b = write(tmp.path(), "b.tif", &dem.crop(256, 0, 128, 128).unwrap());
    let dict_path = tmp.path().join("canyon.dict");
    let stdout = ok(&relief_line(
        "learn {} {} {} --atoms 48 --iterations 6",
        &[&a, &b, &dict_path],
    ));
    assert!(stdout.contains("N = 48 atoms of 8 x 8"), "{stdout}");
    let err = stdout.split("rmse ").nth(1).unwrap();
    let first: f64 = err.split(" m").next().unwrap().parse().unwrap();
    let last: f64 = err
        .split("-> ")
        .nth(1)
        .unwrap()
        .split(" m")
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(last < first, "{stdout}");
    let dict = relief_sparse_core::Dictionary::from_bytes(
        &std::fs::read(&dict_path).unwrap(),
        &FunctionAtomRegistry::new(),
    )
    .unwrap();
    assert_eq!((dict.len(), dict.patch_size()), (48, 8));

    // Constrained learning: every atom is an exemplar patch (unit norm, data atoms).
    let cdict = tmp.path().join("constrained.dict");
    ok(&relief_line(
        "learn {} {} --atoms 32 --sparsity 1 --iterations 2 --constrained",
        &[&a, &cdict],
    ));
    let d = relief_sparse_core::Dictionary::from_bytes(
        &std::fs::read(&cdict).unwrap(),
        &FunctionAtomRegistry::new(),
    )
    .unwrap();
    assert_eq!(d.len(), 32);

    // The dictionary compresses unseen ground (another part of the canyon) well.
    let c = write(tmp.path(), "c.tif", &dem.crop(128, 300, 128, 128).unwrap());
    let sct = tmp.path().join("c.sct");
    let stdout = ok(&relief_line(
        "compress {} {} --dictionary {} --sparsity 4",
        &[&c, &sct, &dict_path],
    ));
    let model = read_model(&sct);
    let psnr = metrics::psnr(
        &read(&c),
        &model.rasterize(&RasterSettings::default()).unwrap(),
    )
    .unwrap();
    assert!(psnr > 35.0, "{psnr} dB; compress said: {stdout}");

    // Bad input.
    let empty = tmp.path().join("empty.tif");
    std::fs::write(&empty, b"").unwrap();
    let out = tmp.path().join("bad.dict");
    fails(&relief!["learn", empty, out], &out, &["empty.tif"]);
    let mut holes = dem.crop(0, 0, 64, 64).unwrap();
    holes.set(1, 1, f32::NAN);
    let holes = write(tmp.path(), "holes.tif", &holes);
    fails(&relief!["learn", holes, out], &out, &["holes.tif", "void"]);
    fails(
        &relief!["learn", a, out, "--atoms", "0"],
        &out,
        &["n_atoms"],
    );
    fails(
        &relief!["learn", a, out, "--variant", "fast"],
        &out,
        &["--variant"],
    );
}

/// Asserts `out` covers the extent of `src` with cells `f` times smaller: same CRS, same
/// origin, pixel size divided by `f` (pixel-is-area), GDAL geotransform order.
fn assert_georef_scaled(out: &Heightfield, src: &Heightfield, f: f64, what: &str) {
    let gs = src.georef().expect("the source is georeferenced");
    let go = out
        .georef()
        .unwrap_or_else(|| panic!("{what}: georeference lost"));
    assert_eq!(go.crs, gs.crs, "{what}: CRS");
    assert_eq!(
        go.geo_key_directory, gs.geo_key_directory,
        "{what}: GeoKeys"
    );
    let (ts, to) = (
        gs.geotransform.expect("source transform"),
        go.geotransform
            .unwrap_or_else(|| panic!("{what}: no transform")),
    );
    let px = ts[1].abs();
    for (i, (a, b)) in to.iter().zip(ts.iter()).enumerate() {
        let want = if matches!(i, 1 | 2 | 4 | 5) {
            b / f
        } else {
            *b
        };
        assert!(
            (a - want).abs() <= 1e-9 * px.max(1.0) * 1e3,
            "{what}: transform[{i}] {a} vs {want} ({to:?} vs {ts:?})"
        );
    }
    assert_eq!(
        (out.width() as f64, out.height() as f64),
        (src.width() as f64 * f, src.height() as f64 * f),
        "{what}: size"
    );
}

/// Issue 14: amplify (raster, streamed raster and .sct), decompress, compress and
/// fit-procedural keep the CRS and extent of a georeferenced input (EPSG:3857 crop of
/// grandcanyon.tif), with the pixel size divided by the factor.
#[test]
fn method_outputs_keep_the_georeference() {
    let dem = fixture();
    assert!(dem.georef().and_then(|g| g.geotransform).is_some());
    let tmp = tempfile::tempdir().unwrap();
    let coarse = dem
        .crop(96, 128, 128, 128)
        .unwrap()
        .resample(32, 32)
        .unwrap();
    let cin = write(tmp.path(), "coarse.tif", &coarse);
    let coarse = read(&cin);
    let ex = write(tmp.path(), "ex.tif", &dem.crop(256, 256, 256, 256).unwrap());
    let amp = |out: &Path, extra: &[&str]| {
        let line = "amplify {} {} --exemplar {} --factor 4 --atoms 32 --landform off";
        ok(&relief_line_plus(line, &[&cin, &out, &ex], extra));
    };
    let out_tif = tmp.path().join("a.tif");
    amp(&out_tif, &[]);
    assert_georef_scaled(&read(&out_tif), &coarse, 4.0, "amplify .tif");
    let out_stream = tmp.path().join("s.tif");
    amp(&out_stream, &["--stream"]);
    assert_georef_scaled(&read(&out_stream), &coarse, 4.0, "amplify --stream");
    let out_sct = tmp.path().join("a.sct");
    amp(&out_sct, &[]);
    let dec = tmp.path().join("dec.tif");
    relief_ok!["decompress", out_sct, dec];
    assert_georef_scaled(&read(&dec), &coarse, 4.0, "amplify .sct -> decompress");
    assert_eq!(read(&dec).as_slice(), read(&out_tif).as_slice());
    // compress -> decompress at scale 1 keeps the grid exactly.
    let c_sct = tmp.path().join("c.sct");
    relief_ok!["compress", cin, c_sct, "--dict", "sample", "-n", "16"];
    let c_dec = tmp.path().join("c.tif");
    relief_ok!["decompress", c_sct, c_dec];
    assert_georef_scaled(&read(&c_dec), &coarse, 1.0, "compress -> decompress");
    // A window of a decompression starts at its own first cell.
    let w_dec = tmp.path().join("w.tif");
    relief_ok!["decompress", out_sct, w_dec, "--window", "8,4,16,16"];
    let gt = read(&dec).georef().unwrap().geotransform.unwrap();
    let gw = read(&w_dec).georef().unwrap().geotransform.unwrap();
    assert!((gw[0] - (gt[0] + 8.0 * gt[1])).abs() < 1e-6 * gt[1].abs());
    assert!((gw[3] - (gt[3] + 4.0 * gt[5])).abs() < 1e-6 * gt[5].abs());
    let fit = tmp.path().join("fit.tif");
    relief_ok!["fit-procedural", cin, fit, "--candidates", "64"];
    assert_georef_scaled(&read(&fit), &coarse, 1.0, "fit-procedural");
}

/// Issue 44 item 10: x256 of a 64 x 64 crop of the fixture ("gc64"). Since the default grid
/// step became R / 2, the last x4 step codes 2049^2 patches of 64 samples, 0.1 % more than
/// one patch matrix may hold, and the run failed with "invalid parameter `step` = 2: gives too
/// many primitives"; the step now codes its patches in bands. Written as a `.sct` (the
/// 16384^2 raster would only add time). A factor whose steps cannot place their primitives
/// at all (given the memory) is refused in the user's terms (`--factor`), never by an
/// internal parameter.
#[test]
fn amplify_x256_of_a_64_crop_and_too_large_a_factor() {
    let tmp = tempfile::tempdir().unwrap();
    let (gc64, _) = fixture_crop(tmp.path(), "gc64.tif", (224, 224, 64, 64));
    let ex = relief_testdata::fixture("grandcanyon.tif");
    let model = tmp.path().join("gc64x256.sct");
    ok(&relief_line(
        "amplify {} {} --exemplar {} --factor 256",
        &[&gc64, &model, &ex],
    ));
    let sct = read_model(&model);
    assert_eq!((sct.width(), sct.height()), (16384, 16384));
    let big = tmp.path().join("x1024.sct");
    let e = fails_with(
        &relief_line(
            "--max-memory 100000G amplify {} {} --exemplar {} --factor 1024",
            &[&gc64, &big, &ex],
        ),
        &["--factor", "too large for x1024"],
        &[&big],
    );
    assert!(!e.contains('`'), "an internal parameter named: {e}");
}

/// The landform pass (issue 41), on by default: `amplify` and `refine` outputs of a real crop
/// have no closed depression left, still reduce to the input, and differ from the raw method
/// (`--landform off`, also the default of `--paper` / `--model paper`); a tile plan refuses it.
#[test]
fn landform_pass_is_the_default_and_drains() {
    let dem = fixture();
    let tmp = tempfile::tempdir().unwrap();
    let truth = dem.crop(64, 64, 128, 128).unwrap();
    let coarse = truth.downsample_box(4).unwrap();
    let cin = write(tmp.path(), "coarse.tif", &coarse);
    let ex = write(tmp.path(), "ex.tif", &dem.crop(256, 256, 256, 256).unwrap());
    let pits = |hf: &Heightfield| relief_landscape::stats::drainage(hf).pits_per_km2;
    let consistency = |hf: &Heightfield| {
        metrics::rmse(&hf.downsample_box(4).unwrap(), &coarse).unwrap() / truth.relief() as f64
    };
    for (name, line) in [
        (
            "amplify",
            "amplify {} {} --exemplar {} --factor 4 --atoms 32",
        ),
        ("refine", "refine {} {} --levels 2 --seed 1"),
    ] {
        let on = tmp.path().join(format!("{name}-on.tif"));
        let off = tmp.path().join(format!("{name}-off.tif"));
        let paper = tmp.path().join(format!("{name}-paper.tif"));
        let run = |out: &Path, extra: &[&str], loud: bool| {
            let files: Vec<&dyn AsRef<std::ffi::OsStr>> = if name == "amplify" {
                vec![&cin, &out, &ex]
            } else {
                vec![&cin, &out]
            };
            let mut args = words(line, &files);
            args.extend(extra.iter().map(std::ffi::OsStr::new));
            let o = if loud {
                relief_loud(&args)
            } else {
                relief(&args)
            };
            ok(&o);
            o
        };
        let noted = run(&on, &[], true);
        assert!(
            String::from_utf8_lossy(&noted.stderr).contains("landform pass"),
            "{name}: the note says what the pass did"
        );
        run(&off, &["--landform", "off"], false);
        let paper_flag: &[&str] = if name == "amplify" {
            &["--paper"]
        } else {
            &["--model", "paper"]
        };
        run(&paper, paper_flag, false);
        let (on, off, paper) = (read(&on), read(&off), read(&paper));
        assert!(
            pits(&off) > 0.0 && pits(&paper) > 0.0,
            "{name}: raw detail has pits"
        );
        assert_eq!(pits(&on), 0.0, "{name}");
        assert!(consistency(&on) < 0.005, "{name}: {}", consistency(&on));
        assert_ne!(on.as_slice(), off.as_slice());
        assert_eq!(on.georef(), off.georef());
    }
    // A tile plan cannot route water across its tiles: its tiles are the raw method, and
    // asking for the pass is refused by name.
    let plan = tmp.path().join("plan");
    let out = tmp.path().join("tiled.tif");
    let refused = relief_line_plus(
        "tile plan {} -- amplify {} {} --exemplar {} --factor 4 --landform on",
        &[&plan, &cin, &out, &ex],
        &[],
    );
    fails(&refused, &out, &["--landform on", "--landform off"]);
}

/// `--max-time` holds through the landform pass: a x4 amplification of the whole fixture
/// (2048^2 cells, a pass of several seconds) under a 2 s limit stops with an error naming
/// the limit, and writes nothing.
#[test]
fn the_landform_pass_stops_at_the_time_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let gc = relief_testdata::fixture("grandcanyon.tif");
    let out = tmp.path().join("out.tif");
    let res = relief_line_plus(
        "amplify {} {} --exemplar {} --factor 4 --atoms 32 --max-time 2s",
        &[&gc, &out, &gc],
        &[],
    );
    fails(&res, &out, &["--max-time"]);
}
