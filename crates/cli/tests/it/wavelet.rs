//! End-to-end tests of `relief refine` and `relief analyze` (wavelet detail synthesis) on crops
//! of the bundled real DEM `fixtures/grandcanyon.tif`.

use std::path::Path;
use std::process::{Command, Output};

use relief_heightfield::Heightfield;

use crate::common::*;

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn a_refined_window_equals_the_same_window_of_the_full_output() {
    let (tmp, input, _) = tmp_with_crop("in.tif", (200, 160, 64, 48));
    let src = read(&input);
    for (method, wavelet) in [("lsa", "cdf53"), ("gsa", "cdf97"), ("lsa", "db4")] {
        let full = tmp.path().join(format!("full-{method}-{wavelet}.tif"));
        let win = tmp.path().join(format!("win-{method}-{wavelet}.tif"));
        let common = [
            "--levels",
            "2",
            "--method",
            method,
            "--stats-window",
            "3",
            "--wavelet",
            wavelet,
            "--seed",
            "11",
            "--model",
            "paper",
        ];
        let mut a = vec![os("refine"), input.as_os_str(), full.as_os_str()];
        a.extend(common.iter().map(os));
        ok(&relief(&a));
        let mut b = vec![os("refine"), input.as_os_str(), win.as_os_str()];
        b.extend(common.iter().map(os));
        b.extend([os("--window"), os("37,101,50,60")]);
        ok(&relief(&b));
        let full = read(&full);
        let win = read(&win);
        assert_eq!((full.width(), full.height()), (256, 192));
        assert_eq!((win.width(), win.height()), (50, 60));
        let (cx, cy) = src.cell_size();
        let (fx, fy) = full.cell_size();
        // Geographic grids get their metric cell size at the grid's centre latitude, hence the
        // relative tolerance.
        assert!(
            (fx * 4.0 / cx - 1.0).abs() < 1e-3 && (fy * 4.0 / cy - 1.0).abs() < 1e-3,
            "{:?} {:?}",
            src.cell_size(),
            full.cell_size()
        );
        assert_eq!(
            bits(win.as_slice()),
            bits(full.crop(37, 101, 50, 60).unwrap().as_slice()),
            "{method} {wavelet}"
        );
        // The refinement keeps the input's relief: mean and range within a few metres, and
        // new detail was added (it is not an interpolation).
        let (lo, hi) = src.min_max().unwrap();
        let (flo, fhi) = full.min_max().unwrap();
        assert!(flo > lo - 0.2 * (hi - lo) && fhi < hi + 0.2 * (hi - lo));
        let mean =
            |h: &Heightfield| h.as_slice().iter().map(|&v| v as f64).sum::<f64>() / h.len() as f64;
        assert!(
            (mean(&src) - mean(&full)).abs() < 0.01 * (hi - lo) as f64,
            "{} {}",
            mean(&src),
            mean(&full)
        );
        // Refined sample (4i, 4j) lies on input sample (i, j) (vertex-aligned lattice): the
        // coarse shape is kept up to the synthesised detail.
        let mut se = 0.0f64;
        for y in 0..src.height() {
            for x in 0..src.width() {
                se += ((full.get(4 * x, 4 * y) - src.get(x, y)) as f64).powi(2);
            }
        }
        let rmse = (se / src.len() as f64).sqrt();
        assert!(
            rmse < 0.05 * (hi - lo) as f64,
            "{method}: rmse on the input lattice {rmse} m"
        );
        let bicubic = src.resample(256, 192).unwrap();
        let diff = relief_heightfield::metrics::max_abs_diff(&full, &bicubic).unwrap();
        assert!(diff > 0.5, "{method}: no detail added ({diff} m)");
    }
    // Another seed gives other detail.
    let other = tmp.path().join("other.tif");
    relief_ok!["refine", input, other, "--seed", "12", "--levels", "2"];
    let full = read(&tmp.path().join("full-lsa-cdf53.tif"));
    assert_ne!(bits(read(&other).as_slice()), bits(full.as_slice()));
}

#[test]
fn analyze_prints_fits_json_and_plot() {
    let (tmp, input, _) = tmp_with_crop("in.tif", (0, 0, 256, 256));
    let text = relief_ok!["analyze", input, "--local", "3"];
    for needle in ["gamma", "fractal dimension", "local fit", "level"] {
        assert!(text.contains(needle), "{needle}: {text}");
    }
    let plot = tmp.path().join("plot.png");
    let json = relief_ok!["analyze", input, "--json", "--plot", plot];
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let fits = v["analysis"]["fits"].as_array().unwrap();
    assert_eq!(fits.len(), 3);
    for f in fits {
        let g = f["gamma"].as_f64().unwrap();
        // Real terrain: variance decays towards finer levels (gamma > 0), and the fit is good.
        assert!(g > 0.5 && g < 4.0, "gamma {g}");
        assert!(f["r_squared"].as_f64().unwrap() > 0.8, "{f}");
        let d = f["fractal_dimension"].as_f64().unwrap();
        assert!((d - (3.0 - g / 2.0)).abs() < 1e-12);
    }
    // 256 -> J = 8, fitted levels 3..=7.
    assert_eq!(v["analysis"]["top_level"], 8);
    let levels = v["analysis"]["levels"].as_array().unwrap();
    assert_eq!(levels.iter().filter(|l| l["fitted"] == true).count(), 5);
    let bytes = std::fs::read(&plot).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    assert_eq!((w, h), (720, 440));
    // The text and JSON agree on gamma.
    let g_h = fits[0]["gamma"].as_f64().unwrap();
    assert!(text.contains(&format!("{g_h:.4}")), "{text}");
}

#[test]
fn voids_need_fill_voids() {
    let tmp = tempfile::tempdir().unwrap();
    let mut hf = fixture().crop(100, 100, 64, 64).unwrap();
    for y in 20..26 {
        for x in 30..37 {
            hf.set(x, y, f32::NAN);
        }
    }
    let input = tmp.path().join("holes.tif");
    save(&input, &hf);
    assert!(read(&input).has_voids());
    let out = tmp.path().join("out.tif");
    relief_ok!["refine", input, out, "--levels", "1", "--fill-voids"];
    let r = read(&out);
    assert_eq!((r.width(), r.height()), (128, 128));
    assert!(!r.has_voids());
    relief_ok!["analyze", input, "--fill-voids"];
}

/// Each bad invocation exits non-zero with exactly one line on stderr naming the problem and
/// leaves no output file.
#[test]
fn bad_input_fails_cleanly() {
    let (tmp, input, _) = tmp_with_crop("in.tif", (300, 300, 64, 64));
    let mut holes = read(&input);
    holes.set(5, 5, f32::NAN);
    let holed = tmp.path().join("holes.tif");
    save(&holed, &holes);
    let tiny = fixture_crop(tmp.path(), "tiny.tif", (0, 0, 8, 8)).0;
    let out = tmp.path().join("out.tif");
    let cases: Vec<(Vec<&std::ffi::OsStr>, &str)> = vec![
        (vec![os("--stats-window"), os("4")], "window"),
        (vec![os("--stats-window"), os("0")], "window"),
        (vec![os("--levels"), os("0")], "levels"),
        (vec![os("--levels"), os("13")], "extra_levels"),
        (vec![os("--wavelet"), os("sym9")], "sym9"),
        (vec![os("--window"), os("0,0,300,10")], "window"),
    ];
    let check = |args: Vec<&std::ffi::OsStr>, needle: &str, out: &Path| {
        let res = relief(&args);
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert!(!res.status.success(), "{args:?} succeeded");
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.starts_with("error: "), "{stderr}");
        assert!(
            stderr.contains(needle),
            "{args:?}: `{needle}` not in {stderr}"
        );
        assert!(!out.exists(), "{args:?} left {}", out.display());
    };
    for (extra, needle) in cases {
        let mut args = vec![os("refine"), input.as_os_str(), out.as_os_str()];
        args.extend(extra);
        check(args, needle, &out);
    }
    check(
        vec![os("refine"), holed.as_os_str(), out.as_os_str()],
        "void",
        &out,
    );
    let a = [
        os("refine"),
        input.as_os_str(),
        out.as_os_str(),
        os("--window"),
        os("1,2,3"),
    ];
    usage_error(&a, "--window", &out);
    // A tiny input is refined from the levels it has, with a note (not an error).
    let res = Command::new(env!("CARGO_BIN_EXE_relief"))
        .args([os("refine"), tiny.as_os_str(), out.as_os_str()])
        .output()
        .expect("run relief");
    ok(&res);
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert!(stderr.contains("note:"), "{stderr}");
    assert_eq!(
        (read(&out).width(), read(&out).height()),
        (32, 32),
        "{stderr}"
    );
    std::fs::remove_file(&out).unwrap();
    let missing = tmp.path().join("missing.tif");
    check(
        vec![os("refine"), missing.as_os_str(), out.as_os_str()],
        "missing.tif",
        &out,
    );
    let plot = tmp.path().join("plot.png");
    check(
        vec![
            os("analyze"),
            holed.as_os_str(),
            os("--plot"),
            plot.as_os_str(),
        ],
        "void",
        &plot,
    );
    check(
        vec![
            os("analyze"),
            input.as_os_str(),
            os("--wavelet"),
            os("coif3"),
            os("--plot"),
            plot.as_os_str(),
        ],
        "coif3",
        &plot,
    );
    check(
        vec![
            os("analyze"),
            input.as_os_str(),
            os("--local"),
            os("2"),
            os("--plot"),
            plot.as_os_str(),
        ],
        "--local = 2",
        &plot,
    );
}

#[test]
fn analyze_writes_the_local_maps() {
    let (tmp, input, _) = tmp_with_crop("in.tif", (100, 200, 96, 80));
    let prefix = tmp.path().join("lsa");
    let json = relief_ok!["analyze", input, "--local", "3", "--maps", prefix, "--json"];
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let local = v["local"].as_array().unwrap();
    assert_eq!(local.len(), 3);
    let mean =
        |h: &Heightfield| h.as_slice().iter().map(|&x| x as f64).sum::<f64>() / h.len() as f64;
    let mut gammas = Vec::new();
    for (i, b) in ["h", "v", "d"].iter().enumerate() {
        let g = read(&tmp.path().join(format!("lsa_gamma_{b}.tif")));
        let a = read(&tmp.path().join(format!("lsa_a_{b}.tif")));
        assert_eq!((g.width(), g.height()), (96, 80));
        assert!(!g.has_voids() && !a.has_voids());
        // The map is what the summary describes.
        let want = local[i]["gamma"]["mean"].as_f64().unwrap();
        assert!(
            (mean(&g) - want).abs() < 1e-3,
            "{b}: {} vs {want}",
            mean(&g)
        );
        // Local statistics vary over a real terrain.
        let (lo, hi) = g.min_max().unwrap();
        assert!(hi - lo > 0.2, "{b}: gamma map range {lo}..{hi}");
        gammas.push(g);
    }
    let d = read(&tmp.path().join("lsa_dimension.tif"));
    for k in [0, 1234, 96 * 80 - 1] {
        let g = (gammas[0].as_slice()[k] + gammas[1].as_slice()[k] + gammas[2].as_slice()[k]) / 3.0;
        assert!((d.as_slice()[k] - (3.0 - g / 2.0)).abs() < 1e-5);
    }
    // --maps needs --local.
    let res = relief!["analyze", input, "--maps", prefix];
    assert!(!res.status.success());
}

/// `relief refine ... --stream` (forced on small outputs; automatic above 16 M cells) writes the
/// GeoTIFF band by band: the same bits, size, cell size and georeference as the in-memory path,
/// for the whole grid (render_strips) and for a window (band by band), over several band seams.
#[test]
fn streamed_output_equals_the_in_memory_output() {
    let (tmp, input, _) = tmp_with_crop("in.tif", (220, 180, 64, 48));
    let src = read(&input);
    assert!(src.georef().is_some(), "the fixture is georeferenced");
    for (method, wavelet, window) in [
        ("lsa", "cdf53", None),
        ("gsa", "db4", None),
        ("lsa", "cdf97", Some("37,101,50,60")),
        ("lsa", "haar", Some("0,3,256,7")),
    ] {
        let mut common = vec![
            os("refine"),
            input.as_os_str(),
            os("--levels"),
            os("2"),
            os("--method"),
            os(method),
            os("--wavelet"),
            os(wavelet),
            os("--seed"),
            os("5"),
            os("--landform"),
            os("off"),
        ];
        if let Some(w) = window {
            common.extend([os("--window"), os(w)]);
        }
        let tag = format!("{method}-{wavelet}-{}", window.is_some());
        let mem = tmp.path().join(format!("mem-{tag}.tif"));
        let streamed = tmp.path().join(format!("streamed-{tag}.tif"));
        let mut a = common.clone();
        a.insert(2, mem.as_os_str());
        ok(&relief(&a));
        let mut b = common.clone();
        b.insert(2, streamed.as_os_str());
        b.push(os("--stream"));
        // Without --quiet: the note says the streamed path was taken.
        let res = Command::new(env!("CARGO_BIN_EXE_relief"))
            .args(&b)
            .output()
            .unwrap();
        ok(&res);
        let note = String::from_utf8_lossy(&res.stderr);
        assert!(note.contains("streamed in bands of"), "{tag}: {note}");
        let (m, s) = (read(&mem), read(&streamed));
        let size = window.map_or((256, 192), |w| {
            let v: Vec<usize> = w.split(',').map(|p| p.parse().unwrap()).collect();
            (v[2], v[3])
        });
        assert_eq!((m.width(), m.height()), size, "{tag}");
        assert_eq!((s.width(), s.height()), size, "{tag}");
        assert_eq!(bits(s.as_slice()), bits(m.as_slice()), "{tag}");
        assert_eq!(s.cell_size(), m.cell_size(), "{tag}");
        assert!(s.georef().is_some(), "{tag}: georeference lost");
        assert_eq!(s.georef(), m.georef(), "{tag}");
        assert!(!s.has_voids());
    }
    // Non-GeoTIFF outputs keep the in-memory path (same values).
    let npy = tmp.path().join("out.npy");
    let res = Command::new(env!("CARGO_BIN_EXE_relief"))
        .args([
            os("refine"),
            input.as_os_str(),
            npy.as_os_str(),
            os("--levels"),
            os("2"),
            os("--method"),
            os("gsa"),
            os("--wavelet"),
            os("db4"),
            os("--seed"),
            os("5"),
            os("--landform"),
            os("off"),
            os("--stream"),
        ])
        .output()
        .unwrap();
    ok(&res);
    assert!(!String::from_utf8_lossy(&res.stderr).contains("streamed"));
    let gsa = read(&tmp.path().join("mem-gsa-db4-false.tif"));
    assert_eq!(bits(read(&npy).as_slice()), bits(gsa.as_slice()));
}

/// Files in `dir` whose name starts with `.{name}.tmp-` (the writer's hidden temporaries).
fn temps(dir: &Path, name: &str) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|f| f.starts_with(&format!(".{name}.tmp-")))
        .collect()
}

/// A streamed write that fails leaves no output file: the output cannot be created (its
/// directory is a regular file), or the file system refuses the data mid-stream (a file-size
/// limit, `ulimit -f`: EFBIG with SIGXFSZ ignored -> the error path removes the temporary; with
/// SIGXFSZ delivered the process dies mid-write, and the next run removes its stale temporary).
#[cfg(target_os = "linux")]
#[test]
fn a_failing_streamed_write_leaves_no_file() {
    let (tmp, input, _) = tmp_with_crop("in.tif", (300, 100, 64, 64));
    let args = |out: &Path| {
        vec![
            os("refine").to_owned(),
            input.as_os_str().to_owned(),
            out.as_os_str().to_owned(),
            os("--levels").to_owned(),
            os("2").to_owned(),
            os("--stream").to_owned(),
        ]
    };
    let one_error_line = |res: &Output, what: &str| {
        assert!(!res.status.success(), "{what}: succeeded");
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{what}: {stderr}");
        assert!(
            stderr.starts_with("error: cannot write"),
            "{what}: {stderr}"
        );
    };

    // 1. The output directory is a regular file.
    let not_dir = tmp.path().join("not-a-dir");
    std::fs::write(&not_dir, b"x").unwrap();
    let out = not_dir.join("out.tif");
    let res = Command::new(env!("CARGO_BIN_EXE_relief"))
        .arg("--quiet")
        .args(args(&out))
        .output()
        .unwrap();
    one_error_line(&res, "directory is a file");
    assert!(!out.exists());

    // 2. The file system refuses the data after 32 KiB (the output is 256 KiB): write error
    //    mid-stream, reported on one line, temporary removed.
    let dir = tmp.path().join("limited");
    std::fs::create_dir(&dir).unwrap();
    let out = dir.join("out.tif");
    let limited = |trap: &str| {
        Command::new("sh")
            .arg("-c")
            .arg(format!("{trap} ulimit -f 64 && exec \"$0\" --quiet \"$@\""))
            .arg(env!("CARGO_BIN_EXE_relief"))
            .args(args(&out))
            .output()
            .unwrap()
    };
    let res = limited("trap '' XFSZ;");
    one_error_line(&res, "file size limit");
    assert!(
        String::from_utf8_lossy(&res.stderr).contains("large"),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    assert!(!out.exists());
    assert_eq!(temps(&dir, "out.tif"), Vec::<String>::new());

    // 3. Killed mid-write (SIGXFSZ): no output; the hidden temporary it left is removed by
    //    the next run, which succeeds.
    let res = limited("");
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(
        res.status.signal(),
        Some(25),
        "SIGXFSZ expected: {:?}",
        res.status
    );
    assert!(!out.exists());
    assert_eq!(
        temps(&dir, "out.tif").len(),
        1,
        "the killed run's temporary"
    );
    ok(&Command::new(env!("CARGO_BIN_EXE_relief"))
        .arg("--quiet")
        .args(args(&out))
        .output()
        .unwrap());
    assert_eq!(read(&out).width(), 256);
    assert_eq!(temps(&dir, "out.tif"), Vec::<String>::new());
}

/// The default (spectral) model is area-consistent: the 4 x 4 block means of the refined
/// terrain are the input cells, within a small fraction of the relief; `--model paper` is not.
#[test]
fn default_refinement_is_area_consistent() {
    let (tmp, input, _) = tmp_with_crop("in.tif", (200, 160, 64, 48));
    let src = read(&input);
    let (lo, hi) = src.min_max().unwrap();
    let err = |model: &str| {
        let out = tmp.path().join(format!("out-{model}.tif"));
        relief_ok!["refine", input, out, "--model", model, "--seed", "3"];
        let down = read(&out).downsample_box(4).unwrap();
        relief_heightfield::metrics::rmse(&down, &src).unwrap() / (hi - lo) as f64
    };
    let spectral = err("spectral");
    let paper = err("paper");
    assert!(spectral < 0.005, "spectral: {spectral}");
    assert!(spectral < paper, "spectral {spectral} vs paper {paper}");
}
