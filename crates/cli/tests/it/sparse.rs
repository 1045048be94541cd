//! `relief compress` / `relief decompress` end to end on crops of the bundled Grand Canyon
//! fixture (real SRTM-derived data): exact reconstruction with the complete dictionary, PSNR
//! rising with the sparsity, windows and scales, dictionary files, and bad input (truncated
//! or corrupt `.sct`, s > N, absurd sizes): non-zero exit, one line on stderr, no output file.

use std::path::Path;

use relief_heightfield::metrics;
use relief_sparse_core::{Dictionary, PatchGeometry, Sct, extract_patches};

use crate::common::*;

/// The number after `key` in the report (e.g. `"PSNR:"`).
fn figure(stdout: &str, key: &str) -> f64 {
    let line = stdout
        .lines()
        .find(|l| l.starts_with(key))
        .unwrap_or_else(|| panic!("no `{key}` in {stdout}"));
    line[key.len()..]
        .split_whitespace()
        .next()
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no number in {line}"))
}

fn rho(stdout: &str) -> f64 {
    let line = stdout.lines().find(|l| l.starts_with("storage:")).unwrap();
    let t = line.split("rho = ").nth(1).unwrap();
    t.split_whitespace().next().unwrap().parse().unwrap()
}

/// A failing run: exactly one `error:` line on stderr, no output file (nor temporaries).
fn fails(args: &[&std::ffi::OsStr], output: &Path, what: &str) -> String {
    let e = fails_with(&relief(args), &["error: "], &[output]);
    assert!(e.starts_with("error: "), "{what}: {e}");
    e
}

#[test]
fn complete_dictionary_s1_round_trip_is_exact() {
    let (tmp, input, hf) = tmp_with_crop("in.tif", (200, 150, 72, 64));
    let sct = tmp.path().join("c.sct");
    let stdout = ok(&relief_line(
        "compress {} {} --dict complete --sparsity 1",
        &[&input, &sct],
    ));
    // The complete dictionary stores every patch: rho > 1 (no compression), exact terrain.
    assert!(rho(&stdout) > 100.0, "{stdout}");
    assert!(figure(&stdout, "PSNR:") > 90.0, "{stdout}");
    let bytes = std::fs::read(&sct).unwrap();
    assert_eq!(figure(&stdout, "bytes:") as usize, bytes.len());
    let out = tmp.path().join("c.tif");
    let d = relief_ok!["decompress", sct, out, "--reference", input];
    assert_eq!(figure(&d, "bytes:") as usize, bytes.len());
    assert!(figure(&d, "PSNR:") > 90.0, "{d}");
    let rec = read(&out);
    assert_eq!((rec.width(), rec.height()), (72, 64));
    let err = metrics::max_abs_diff(&hf, &rec).unwrap();
    assert!(err < 1e-5 * hf.relief() as f64 + 1e-3, "max error {err} m");
}

#[test]
fn learned_dictionary_psnr_rises_with_sparsity_and_windows_match() {
    let (tmp, input, hf) = tmp_with_crop("in.tif", (100, 240, 96, 80));
    let mut psnr = Vec::new();
    let mut sizes = Vec::new();
    for s in ["1", "2", "8"] {
        let sct = tmp.path().join(format!("s{s}.sct"));
        let stdout = ok(&relief_line(
            "compress {} {} -s {} --atoms 48 --iterations 4",
            &[&input, &sct, &s],
        ));
        assert!(stdout.contains("K-SVD"), "{stdout}");
        // t(s, N) = KN + n(2s + 2) + 1 with K = 64, N = 48 and the printed n.
        let s: u64 = s.parse().unwrap();
        let n: u64 = stdout
            .lines()
            .find(|l| l.starts_with("primitives:"))
            .and_then(|l| l.split("n = ").nth(1))
            .and_then(|t| t.split(',').next())
            .and_then(|t| t.parse().ok())
            .unwrap();
        let t = 64 * 48 + n * (2 * s + 2) + 1;
        assert!(stdout.contains(&format!("= {t} values")), "{stdout}");
        psnr.push(figure(&stdout, "PSNR:"));
        sizes.push(std::fs::metadata(&sct).unwrap().len());
    }
    assert!(psnr[0] < psnr[1] && psnr[1] < psnr[2], "{psnr:?}");
    assert!(sizes[0] < sizes[1] && sizes[1] < sizes[2], "{sizes:?}");
    // The s = 8 model reconstructs the crop well (paper table 1: > 40 dB at s = 8).
    assert!(psnr[2] > 40.0, "{psnr:?}");

    // A window at scale 2.5 equals the same window of the full scale-2.5 raster, bit for bit.
    let sct = tmp.path().join("s8.sct");
    let full = tmp.path().join("full.tif");
    relief_ok!["decompress", sct, full, "--factor", "2.5"];
    let part = tmp.path().join("part.r32");
    ok(&relief_line(
        "decompress {} {} --scale 2.5 --window 31,17,60,45",
        &[&sct, &part],
    ));
    let full = read(&full);
    assert_eq!(
        (full.width(), full.height()),
        // Pixel-is-area: the same extent with cells 2.5 times smaller (96 x 80 input).
        (240, 200)
    );
    let part = relief_io::read(
        &part,
        &relief_io::ReadOptions {
            width: Some(60),
            height: Some(45),
            ..Default::default()
        },
    )
    .unwrap()
    .heightfield;
    for r in 0..45 {
        for c in 0..60 {
            assert_eq!(part.get(c, r).to_bits(), full.get(31 + c, 17 + r).to_bits());
        }
    }
    // Every 5th sample of the x2.5 raster (every 2nd terrain sample) is close to the input.
    let mut worst = 0f32;
    for r in (0..80).step_by(2) {
        for c in (0..96).step_by(2) {
            let v = full.get(c * 5 / 2, r * 5 / 2);
            worst = worst.max((v - hf.get(c, r)).abs());
        }
    }
    assert!(
        worst < 0.1 * hf.relief(),
        "worst {worst} of {}",
        hf.relief()
    );

    // The quantised file is smaller and still close.
    let q = tmp.path().join("q.sct");
    let stdout = ok(&relief_line(
        "compress {} {} -s 8 --atoms 48 --iterations 4 --quantize",
        &[&input, &q],
    ));
    assert!(std::fs::metadata(&q).unwrap().len() < sizes[2]);
    assert!((figure(&stdout, "PSNR:") - psnr[2]).abs() < 1.0, "{stdout}");
}

#[test]
fn dictionary_file_is_used() {
    let (tmp, input, hf) = tmp_with_crop("in.tif", (300, 300, 64, 64));
    // A dictionary of 6 x 6 patches from another part of the canyon.
    let (_, other) = fixture_crop(tmp.path(), "gc_20_20_64x64.tif", (20, 20, 64, 64));
    let p = extract_patches(&other, &PatchGeometry::with_patch_size(6)).unwrap();
    let sel: Vec<usize> = (0..32).map(|k| k * 7 + 3).collect();
    let (dict, _) = Dictionary::from_patches(&p, Some(&sel)).unwrap();
    let dict_path = tmp.path().join("canyon.dict");
    std::fs::write(&dict_path, dict.to_bytes().unwrap()).unwrap();
    let sct = tmp.path().join("d.sct");
    let stdout = relief_ok!["compress", input, sct, "--dictionary", dict_path, "-s", "4"];
    assert!(
        stdout.contains(&format!("N = {} atoms of 6 x 6", dict.len())),
        "{stdout}"
    );
    let model = Sct::from_bytes(&std::fs::read(&sct).unwrap(), &Default::default()).unwrap();
    assert_eq!(
        model.layers()[0].dictionary().discretize(),
        dict.discretize()
    );
    assert_eq!((model.width(), model.height()), (hf.width(), hf.height()));
    // Geometry options conflict with a dictionary file.
    let out = tmp.path().join("x.sct");
    fails(
        &[
            os("compress"),
            input.as_os_str(),
            out.as_os_str(),
            os("--dictionary"),
            dict_path.as_os_str(),
            os("--patch-size"),
            os("4"),
        ],
        &out,
        "dictionary + patch size",
    );
    // A corrupt dictionary file.
    let bad = tmp.path().join("bad.dict");
    let mut b = dict.to_bytes().unwrap();
    b.truncate(b.len() - 3);
    std::fs::write(&bad, b).unwrap();
    let e = fails(
        &[
            os("compress"),
            input.as_os_str(),
            out.as_os_str(),
            os("--dictionary"),
            bad.as_os_str(),
        ],
        &out,
        "truncated dictionary",
    );
    assert!(e.contains("bad.dict"), "{e}");
}

#[test]
fn bad_input_fails_cleanly() {
    let (tmp, input, _) = tmp_with_crop("in.tif", (0, 0, 48, 40));
    let good = tmp.path().join("good.sct");
    relief_ok!["compress", input, good, "--dict", "sample", "--atoms", "20"];
    let bytes = std::fs::read(&good).unwrap();
    let out = tmp.path().join("out.sct");
    let raster = tmp.path().join("out.tif");

    // s > N.
    let e = fails(
        &[
            os("compress"),
            input.as_os_str(),
            out.as_os_str(),
            os("--dict"),
            os("sample"),
            os("--atoms"),
            os("20"),
            os("-s"),
            os("21"),
        ],
        &out,
        "s > N",
    );
    assert!(e.contains("21") && e.contains("20"), "{e}");
    // s = 0 and s > 64.
    for s in ["0", "65"] {
        let e = fails(
            &[
                os("compress"),
                input.as_os_str(),
                out.as_os_str(),
                os("-s"),
                os(s),
            ],
            &out,
            "bad sparsity",
        );
        assert!(e.contains("sparsity"), "{e}");
    }
    // Absurd geometry and dictionary sizes.
    for args in [
        vec!["--patch-size", "0"],
        vec!["--patch-size", "100000"],
        vec!["--spacing=-1"],
        vec!["--tolerance=-1"],
        vec!["--step", "1e300"],
        vec!["--radius", "0.1"],
        vec!["--dict", "sample", "--atoms", "100000000"],
        vec!["--atoms", "0"],
    ] {
        let mut a = vec![os("compress"), input.as_os_str(), out.as_os_str()];
        a.extend(args.iter().map(os));
        fails(&a, &out, &format!("{args:?}"));
    }
    // Missing input and an input that is not a raster.
    fails(
        &[
            os("compress"),
            tmp.path().join("nope.tif").as_os_str(),
            out.as_os_str(),
        ],
        &out,
        "missing input",
    );
    fails(
        &[os("compress"), good.as_os_str(), out.as_os_str()],
        &out,
        ".sct as raster input",
    );
    // An input with voids needs --fill-voids.
    let holes = tmp.path().join("holes.tif");
    let mut h = read(&input);
    h.set(10, 10, f32::NAN);
    save(&holes, &h);
    let e = fails(
        &[os("compress"), holes.as_os_str(), out.as_os_str()],
        &out,
        "voids",
    );
    assert!(e.contains("--fill-voids"), "{e}");
    relief_ok!["compress", holes, out, "--fill-voids", "--dict", "sample"];
    std::fs::remove_file(&out).unwrap();

    // Truncated and corrupt .sct files.
    for (name, data) in [
        ("trunc.sct", bytes[..bytes.len() / 2].to_vec()),
        ("short.sct", bytes[..5].to_vec()),
        ("empty.sct", Vec::new()),
        ("magic.sct", {
            let mut b = bytes.clone();
            b[0] = b'X';
            b
        }),
        ("version.sct", {
            let mut b = bytes.clone();
            b[8] = 99;
            b
        }),
        ("huge.sct", {
            // The atom count N = 20 (u32 after the georeference block, the node tag, a,
            // delta and R) claims 4 billion atoms.
            let mut b = bytes.clone();
            let at = (36..b.len() - 4)
                .find(|&i| b[i..i + 4] == 20u32.to_le_bytes() && b[i - 19] == 0)
                .expect("atom count in the stream");
            b[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
            b
        }),
        ("trailing.sct", {
            let mut b = bytes.clone();
            b.extend_from_slice(b"junk");
            b
        }),
    ] {
        let p = tmp.path().join(name);
        std::fs::write(&p, data).unwrap();
        let e = fails(
            &[os("decompress"), p.as_os_str(), raster.as_os_str()],
            &raster,
            name,
        );
        assert!(e.contains(name), "{e}");
    }
    // Absurd output sizes, bad windows and scales.
    for args in [
        vec!["--factor", "1000"],
        vec!["--factor", "0"],
        vec!["--factor", "nan"],
        vec!["--scale=-2"],
        vec!["--window", "0,0,49,10"],
        vec!["--window", "40,0,10,10"],
        vec!["--window", "18446744073709551615,0,2,2"],
        vec!["--factor", "200", "--max-output-cells", "1000"],
        vec!["--scale", "200", "--max-cells", "1000"],
    ] {
        let mut a = vec![os("decompress"), good.as_os_str(), raster.as_os_str()];
        a.extend(args.iter().map(os));
        fails(&a, &raster, &format!("{args:?}"));
    }
    // A time budget the pilot estimate exceeds: refused before the raster is made (issue 18).
    let e = fails(
        &[
            os("decompress"),
            good.as_os_str(),
            raster.as_os_str(),
            os("--factor"),
            os("32"),
            os("--max-time"),
            os("0.001s"),
        ],
        &raster,
        "time budget",
    );
    assert!(
        e.contains("estimated at") && e.contains("--max-time") && e.contains("--factor"),
        "{e}"
    );
    for w in ["0,0,0,10", "1,2,3", "1,-2,3,4"] {
        let a = [
            os("decompress"),
            good.as_os_str(),
            raster.as_os_str(),
            os("--window"),
            os(w),
        ];
        usage_error(&a, "--window", &raster);
    }
    // A reference of the wrong size.
    let (other, _) = fixture_crop(tmp.path(), "gc_5_5_30x30.tif", (5, 5, 30, 30));
    fails(
        &[
            os("decompress"),
            good.as_os_str(),
            raster.as_os_str(),
            os("--reference"),
            other.as_os_str(),
        ],
        &raster,
        "reference size",
    );
    // Unknown output format.
    let weird = tmp.path().join("out.xyz");
    fails(
        &[os("decompress"), good.as_os_str(), weird.as_os_str()],
        &weird,
        "unknown output extension",
    );
}

/// `relief tree build`: a river valley (the paper's 3-level sub-tree) on a layer compressed
/// from a DEM, replaced by an exact `.sct` layer in a disk; the rasterised tree only lowers the
/// terrain, carves the channel below the original on every path vertex and keeps the DEM far
/// from the river; a missing layer and an output that is one of its inputs are refused.
#[test]
fn tree_build_authors_a_river_valley_on_layers() {
    let (tmp, input, hf) = tmp_with_crop("in.tif", (200, 150, 72, 64));
    let exact = tmp.path().join("exact.sct");
    ok(&relief_line(
        "compress {} {} --dict complete --sparsity 1",
        &[&input, &exact],
    ));
    let name = input.file_name().unwrap().to_str().unwrap();
    let spec = tmp.path().join("tree.json");
    let json = format!(
        r#"{{"root": {{"river_valley": {{
            "on": {{"replace": {{"base": {{"layer": "{name}"}}, "overlay": {{"layer": "exact.sct"}},
                                 "region": {{"disk": [36, 32, 100]}}, "falloff": 0}}}},
            "path": [[2, 5], [30, 30], [69, 60]],
            "valley_half_width": 6, "bank_height": 60, "channel_depth": 4}}}}}}"#
    );
    std::fs::write(&spec, json).unwrap();
    let sct = tmp.path().join("tree.sct");
    let stdout = relief_ok!["tree", "build", spec, sct];
    assert!(
        stdout.contains("2 layer(s) (1 compressed from DEMs)"),
        "{stdout}"
    );
    let out = tmp.path().join("tree.tif");
    relief_ok!["decompress", sct, out];
    let t = read(&out);
    assert_eq!((t.width(), t.height()), (72, 64));
    let (a, b) = (hf.as_slice(), t.as_slice());
    // The disk covers the grid: the exact layer, so only the river changes the terrain.
    assert!(a.iter().zip(b).all(|(x, y)| *y <= *x + 1e-3));
    for (x, y) in [(2, 5), (30, 30), (69, 60)] {
        assert!(t.get(x, y) <= hf.get(x, y) - 4.0 + 1e-3, "({x}, {y})");
    }
    let lowered = a.iter().zip(b).filter(|(x, y)| **y < **x - 0.5).count();
    assert!(lowered > 100 && lowered < a.len() / 2, "{lowered}");
    assert_eq!(t.get(70, 2), hf.get(70, 2));
    // A missing or corrupt tree file: exit 1, one line naming it, no output.
    let bad = tmp.path().join("bad.sct");
    let absent = tmp.path().join("absent.json");
    let corrupt = tmp.path().join("corrupt.json");
    std::fs::write(&corrupt, b"{\"root\": {\"layer\": ").unwrap();
    for f in [&absent, &corrupt] {
        let o = relief!["tree", "build", f, bad];
        assert_eq!(o.status.code(), Some(1));
        let e = stderr(&o);
        assert!(
            e.starts_with("error: ") && e.trim_end().lines().count() == 1,
            "{e}"
        );
        assert!(e.contains(f.file_name().unwrap().to_str().unwrap()), "{e}");
        assert!(!bad.exists());
    }
    // A missing layer: named, no output.
    std::fs::write(&spec, r#"{"root": {"layer": "missing.sct"}}"#).unwrap();
    fails_with(
        &relief!["tree", "build", spec, bad],
        &["missing.sct"],
        &[&bad],
    );
    // The output may not overwrite a layer.
    std::fs::write(&spec, r#"{"root": {"layer": "exact.sct"}}"#).unwrap();
    let before = std::fs::read(&exact).unwrap();
    let o = relief!["tree", "build", spec, exact];
    assert!(!o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(&exact).unwrap(), before);
}

/// `compress --analytic-atoms`: a mixed dictionary (figure 14) whose model decompresses; an
/// unknown family is a usage error naming it.
#[test]
fn compress_with_analytic_atoms_mixes_the_dictionary() {
    let (tmp, input, hf) = tmp_with_crop("in.tif", (120, 60, 64, 56));
    let sct = tmp.path().join("mixed.sct");
    let stdout = ok(&relief_line(
        "compress {} {} --atoms 32 --iterations 2 \
         --analytic-atoms ridged:16,perlin:8",
        &[&input, &sct],
    ));
    assert!(stdout.contains("N = 56 atoms"), "{stdout}");
    assert!(stdout.contains("16 analytic RidgedSum"), "{stdout}");
    let out = tmp.path().join("mixed.tif");
    relief_ok!["decompress", sct, out];
    let rec = read(&out);
    assert_eq!((rec.width(), rec.height()), (64, 56));
    let rmse = metrics::rmse(&hf, &rec).unwrap();
    assert!(rmse < 0.05 * hf.relief() as f64, "rmse {rmse}");
    let bad = tmp.path().join("bad.sct");
    let o = relief_line("compress {} {} --analytic-atoms voronoi:4", &[&input, &bad]);
    assert!(failed(&o).contains("voronoi"), "{}", stderr(&o));
    assert!(!bad.exists());
}

/// Issue 44 item 7: a tree of absurd values (a constant or a river depth of 1e308, a path at
/// +-1e300, a cell of 1e-320 m) is refused by `tree build` naming the field, and writes
/// nothing; a model that still overflows a 32-bit raster (two fields at the largest `f32`
/// added, as a crafted file can hold) is refused by `decompress` instead of writing
/// infinities.
#[test]
fn absurd_tree_values_are_refused_and_decompress_never_writes_infinities() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = tmp.path().join("tree.json");
    let out = tmp.path().join("tree.sct");
    let grid = r#""width": 32, "height": 32, "cell_size": [10, 10]"#;
    let river = |path: &str, depth: &str| {
        format!(
            r#"{{{grid}, "root": {{"add": [{{"constant": 100}}, {{"river": {{"path": {path},
                "half_width": 3, "depth": {depth}}}}}]}}}}"#
        )
    };
    for (json, field) in [
        (
            format!(r#"{{{grid}, "root": {{"constant": 1e308}}}}"#),
            "constant",
        ),
        (river("[[0, 16], [31, 16]]", "1e308"), "depth"),
        (river("[[-1e300, 16], [1e300, 16]]", "5"), "path"),
        (
            r#"{"width": 32, "height": 32, "cell_size": [1e-320, 1e-320],
                "root": {"constant": 1}}"#
                .to_string(),
            "cell_size",
        ),
    ] {
        std::fs::write(&spec, &json).unwrap();
        fails_with(&relief!["tree", "build", spec, out], &[field], &[&out]);
    }
    // A valid tree of bounded values still builds.
    std::fs::write(&spec, river("[[0, 16], [31, 16]]", "5")).unwrap();
    relief_ok!["tree", "build", spec, out];

    use relief_heightfield::Kernel;
    use relief_sparse_core::{Field, Node};
    let huge = Field::new(4, 4, vec![f32::MAX; 16], [0.0, 0.0], 8.0, Kernel::Keys).unwrap();
    let sct = Sct::new(
        Node::Add(vec![Node::Field(huge.clone()), Node::Field(huge)]),
        32,
        32,
        (10.0, 10.0),
    )
    .unwrap();
    let model = tmp.path().join("overflow.sct");
    std::fs::write(&model, sct.to_bytes().unwrap()).unwrap();
    let raster = tmp.path().join("overflow.tif");
    fails_with(
        &relief!["decompress", model, raster],
        &["evaluates to inf", "nothing written"],
        &[&raster],
    );
}
