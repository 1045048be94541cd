//! `relief tile plan -- flow`: the seven-phase drainage plan, run phase after phase as
//! shuffled tasks two at a time (what `sbatch --dependency=afterok` chains do), with a killed
//! task, a phase started too early and a damaged tile, mosaics into `relief flow`'s filled,
//! direction, area, Strahler, watershed and HAND rasters bit for bit, its `channels.geojson`
//! byte for byte and its figures, on a real DEM crop and on a synthetic basin spanning 3 x 3
//! tiles with a river across every tile edge.

use std::path::Path;
use std::process::{Child, Stdio};

use relief_heightfield::Heightfield;

use crate::common::*;

const PRODUCTS: [&str; 6] = [
    "filled",
    "direction",
    "area",
    "strahler",
    "watersheds",
    "hand",
];

fn spawn(dir: &Path, phase: usize, i: usize) -> Child {
    command()
        .args(["tile", "run", s(dir), "--phase", &phase.to_string()])
        .args(["--index", &i.to_string()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn task")
}

/// Every phase in turn; the per-tile phases as shuffled tasks two at a time.
fn run_phases(dir: &Path, n: usize, seed: u64) {
    run_phases_to(dir, n, seed, 7);
}

/// Phases 1 to `last` in turn (a masks plan has 8); the per-tile phases as shuffled tasks two
/// at a time.
pub(crate) fn run_phases_to(dir: &Path, n: usize, seed: u64, last: usize) {
    for phase in 1..=last {
        let mut order: Vec<usize> = if phase == 2 || phase == 4 || phase == 6 {
            vec![0]
        } else {
            (0..n).collect()
        };
        shuffle(&mut order, seed + phase as u64);
        two_at_a_time(&order, &format!("phase {phase} task"), |i| {
            spawn(dir, phase, i)
        });
    }
}

/// `relief tile plan PLAN --tile 32 -- CMD INPUT -o OUT EXTRA` fails naming `want` and writes
/// neither `PLAN` nor `OUT`, for every `(EXTRA, want)` of `cases`.
pub(crate) fn plan_refuses(
    cmd: &str,
    plan: &Path,
    input: &Path,
    out: &Path,
    cases: &[(Vec<&str>, &str)],
) {
    let line = format!("tile plan {{}} --tile 32 -- {cmd} {{}} -o {{}}");
    for (extra, want) in cases {
        let o = relief_line_plus(&line, &[&plan, &input, &out], extra);
        fails_with(&o, &[want], &[plan, out]);
    }
}

fn assert_same(single: &Path, tiled: &Path) {
    for p in PRODUCTS {
        let f = format!("{p}.tif");
        assert_same_raster(&single.join(&f), &tiled.join(&f));
    }
    let geojson = |d: &Path| std::fs::read(d.join("channels.geojson")).unwrap();
    let (a, b) = (geojson(single), geojson(tiled));
    assert!(a == b, "channels.geojson differs from the single run's");
    let (a, b) = (
        json(&single.join("flow.json")),
        json(&tiled.join("flow.json")),
    );
    for k in [
        "file",
        "width",
        "height",
        "cell_size",
        "crs",
        "settings",
        "figures",
    ] {
        assert_eq!(a[k], b[k], "flow.json: {k}");
    }
    assert!(!tiled.join("channels.png").exists());
}

pub(crate) fn tasks(dir: &Path) -> usize {
    json(&dir.join("manifest.json"))["tasks"].as_u64().unwrap() as usize
}

/// Single run, plan (which names the output it does not write), a killed phase-1 task, phase 3 refused before phase 2, every phase as
/// shuffled tasks, a damaged tile found by status and redone, mosaic equal to the single run.
fn cycle(dem: &Path, tile: usize, seed: u64) {
    let tmp = tempfile::tempdir().unwrap();
    let single = tmp.path().join("single");
    let tiled = tmp.path().join("tiled");
    let dir = tmp.path().join("plan");
    // A channel area of a few hundred cells: a network crossing every tile edge.
    relief_ok!["flow", dem, "-o", &single, "--channel-area", "2e5"];
    let tile_s = tile.to_string();
    let planned = relief_loud(&[
        std::ffi::OsStr::new("tile"),
        std::ffi::OsStr::new("plan"),
        dir.as_os_str(),
        std::ffi::OsStr::new("--tile"),
        std::ffi::OsStr::new(&tile_s),
        std::ffi::OsStr::new("--"),
        std::ffi::OsStr::new("flow"),
        dem.as_os_str(),
        std::ffi::OsStr::new("-o"),
        tiled.as_os_str(),
        std::ffi::OsStr::new("--channel-area"),
        std::ffi::OsStr::new("2e5"),
    ]);
    let note = String::from_utf8_lossy(&planned.stderr).to_string();
    assert!(planned.status.success(), "{note}");
    assert!(note.contains("not planned: channels.png"), "{note}");
    let n = tasks(&dir);
    assert!(n >= 4, "{n} tiles");
    let st = relief!["tile", "status", &dir];
    assert!(!st.status.success());
    let text = String::from_utf8_lossy(&st.stdout).to_string();
    assert!(text.contains("next: phase 1"), "{text}");
    // A phase whose predecessor is incomplete refuses to run, naming it.
    fails_with(
        &relief!["tile", "run", &dir, "--phase", "3", "--index", "0"],
        &["phase 1 is incomplete"],
        &[],
    );
    // A task killed mid-run leaves nothing that counts as done.
    kill_after(spawn(&dir, 1, 1), 40);
    run_phases(&dir, n, seed);
    relief_ok!["tile", "status", &dir];
    // A task already done is a no-op; a single phase is task 0 only.
    relief_ok!["tile", "run", &dir, "--phase", "3", "--index", "0"];
    fails_with(
        &relief!["tile", "run", &dir, "--phase", "2", "--index", "1"],
        &["one task"],
        &[],
    );
    // A damaged tile of the last phase is reported, refused by the mosaic, and redone.
    let t2 = dir.join("tiles/area-000002.tif");
    damage(&t2);
    let st = relief!["tile", "status", &dir];
    let text = String::from_utf8_lossy(&st.stdout).to_string();
    assert!(
        !st.status.success() && text.contains("corrupt: 2") && text.contains("next: phase 5"),
        "{text}"
    );
    assert!(!relief!["tile", "mosaic", &dir].status.success());
    assert!(!tiled.exists());
    // Without --phase, run picks the first incomplete phase.
    relief_ok!["tile", "run", &dir, "--index", "2"];
    // The single task of phase 4 lost and killed mid-run, then retried: the same bytes, so
    // the later phase's tiles stay valid.
    let inflow = dir.join("phase4/inflow-000001.bin");
    let before = std::fs::read(&inflow).unwrap();
    std::fs::remove_file(dir.join("phase4/task-000000.json")).unwrap();
    kill_after(spawn(&dir, 4, 0), 15);
    let text = String::from_utf8_lossy(&relief!["tile", "status", &dir].stdout).to_string();
    assert!(
        text.contains("next: phase 4") || text.contains("next: relief tile mosaic"),
        "{text}"
    );
    relief_ok!["tile", "run", &dir, "--phase", "4"];
    assert_eq!(std::fs::read(&inflow).unwrap(), before);
    relief_ok!["tile", "status", &dir];
    relief_ok!["tile", "mosaic", &dir];
    assert_same(&single, &tiled);
    let reaches = json(&single.join("flow.json"))["figures"]["reaches"].as_u64();
    assert!(reaches.unwrap() > 4, "{reaches:?} reaches");
    for p in PRODUCTS {
        assert!(dir.join(format!("mosaic-{p}.vrt")).exists());
    }
}

/// A 96 x 96 basin of 25 m cells: a bowl over the middle 3 x 3 tiles of 32 cells, a river
/// winding across every tile edge, integer elevations (flats everywhere) and a few voids.
pub(crate) fn basin() -> Heightfield {
    basin_of(96, 96)
}

/// [`basin`]'s shape over `w x h` cells.
fn basin_of(w: usize, h: usize) -> Heightfield {
    let data = relief_testdata::basin_and_river(w, h, 5, 0.005);
    Heightfield::new(w, h, data, 25.0, 25.0).unwrap()
}

/// `relief CMD DEM -o S EXTRA` (which must succeed) and `relief tile plan P --tile TILE --
/// CMD DEM -o T EXTRA` (its output returned, the note included), with a channel area of a few
/// hundred cells so that every small DEM has a network: the temporary folder and `[S, T, P]`.
pub(crate) fn single_and_plan(
    cmd: &str,
    dem: &Path,
    tile: usize,
    extra: &[&str],
) -> (
    tempfile::TempDir,
    [std::path::PathBuf; 3],
    std::process::Output,
) {
    let extra = [extra, &["--channel-area", "1e5"]].concat();
    let tmp = tempfile::tempdir().unwrap();
    let [single, tiled, dir] = ["s", "t", "p"].map(|n| tmp.path().join(n));
    let line = format!("{cmd} {{}} -o {{}}");
    let mut args = words(&line, &[&dem, &single]);
    args.extend(extra.iter().map(|a| std::ffi::OsStr::new(*a)));
    assert!(relief(&args).status.success(), "{args:?}");
    let line = format!("tile plan {{}} --tile {tile} -- {cmd} {{}} -o {{}}");
    let mut args = words(&line, &[&dir, &dem, &tiled]);
    args.extend(extra.iter().map(|a| std::ffi::OsStr::new(*a)));
    let planned = relief_loud(&args);
    (tmp, [single, tiled, dir], planned)
}

/// `relief flow DEM EXTRA` and its plan as tiles of `tile` cells, every phase run: the same
/// bytes.
fn plan_equals_single(dem: &Path, tile: usize, extra: &[&str]) {
    let (_tmp, [single, tiled, dir], planned) = single_and_plan("flow", dem, tile, extra);
    assert!(planned.status.success(), "{}", stderr(&planned));
    run_phases(&dir, tasks(&dir), 7);
    relief_ok!["tile", "mosaic", &dir];
    assert_same(&single, &tiled);
}

/// The plan reads a GeoTIFF file band by band (the plan step never holds the whole DEM) and
/// other inputs whole, with the read flags of `relief flow`: `--cell-size` scales the
/// georeference as the single run's, `--fill-voids` fills the whole DEM before cutting (the
/// whole read), a NumPy DEM is read whole; each mosaic equals the single run. A GeoTIFF of
/// voids only is refused by name and leaves no plan behind.
#[test]
fn flow_plan_reads_its_input_as_relief_flow_does() {
    let (tmp, gc, _) = tmp_with_crop("gc.tif", (10, 20, 100, 90));
    plan_equals_single(&gc, 32, &["--cell-size", "20,30"]);
    let hf = basin();
    let tif = write(tmp.path(), "basin.tif", &hf);
    plan_equals_single(&tif, 32, &["--fill-voids"]);
    let npy = write(tmp.path(), "basin.npy", &hf);
    plan_equals_single(&npy, 48, &[]);
    let void = Heightfield::new(40, 40, vec![f32::NAN; 1600], 5.0, 5.0).unwrap();
    let void = write(tmp.path(), "void.tif", &void);
    let (plan, out) = (tmp.path().join("vp"), tmp.path().join("vo"));
    fails_with(
        &relief![
            "tile", "plan", &plan, "--tile", "16", "--", "flow", &void, "-o", &out
        ],
        &["void.tif", "no valid cell"],
        &[],
    );
    assert!(
        !plan.exists() || files(&plan).is_empty(),
        "{:?}",
        files(&plan)
    );
}

/// A real DEM crop (alps_dem, 300 x 200 cells of 42.6 x 61.8 m): tiles of 64 and 48 cells.
#[test]
fn flow_plan_equals_the_single_run_on_a_real_dem() {
    let Some(hf) = relief_testdata::dem_crop("alps_dem", 120, 100, 300, 200) else {
        return;
    };
    let (_tmp, dem) = tmp_with("alps.tif", &hf);
    cycle(&dem, 64, 3);
    cycle(&dem, 48, 11);
}

/// A basin spanning 3 x 3 tiles of 32 cells (filled to a lake over nine tiles) and a river
/// winding across every tile edge, integer elevations (flats everywhere) and a few voids.
#[test]
fn flow_plan_equals_the_single_run_on_a_basin_over_nine_tiles() {
    let hf = basin();
    let (_tmp, dem) = tmp_with("basin.tif", &hf);
    cycle(&dem, 32, 5);
    cycle(&dem, 16, 17);
}

/// Tiles of 512 cells (the mosaic's GeoTIFF block) are written in the mosaic's blocks and
/// codec, so the mosaic copies their encoded blocks: the files are byte for byte those the
/// mosaic of tiles of 256 cells (off the block grid: decoded and encoded again) writes, and
/// the values the single run's; a COG mosaic (overviews made from the values) still works.
#[test]
fn flow_plan_mosaic_copies_aligned_tiles_blocks() {
    let hf = basin_of(700, 560);
    let (tmp, dem) = tmp_with("basin.tif", &hf);
    let single = tmp.path().join("single");
    // Relative paths, as flow.json's `file` names them.
    let in_tmp = |line: &str| {
        let out = command()
            .current_dir(tmp.path())
            .args(line.split(' '))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{line}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    assert!(dem.ends_with("basin.tif"));
    in_tmp("flow basin.tif -o single --channel-area 1e6");
    let mut outs = Vec::new();
    for tile in [512, 256] {
        let (dir, out) = (
            tmp.path().join(format!("p{tile}")),
            tmp.path().join(format!("t{tile}")),
        );
        in_tmp(&format!(
            "tile plan p{tile} --tile {tile} -- flow basin.tif -o t{tile} --channel-area 1e6"
        ));
        run_phases(&dir, tasks(&dir), 3);
        relief_ok!["tile", "mosaic", &dir];
        assert_same(&single, &out);
        let blocks = relief_io::EncodedBlocks::open(&dir.join("tiles/hand-000001.tif")).unwrap();
        assert_eq!(
            (blocks.tile(), blocks.width()),
            (512, if tile == 512 { 188 } else { 256 })
        );
        outs.push(out);
        if tile == 512 {
            let cog = tmp.path().join("cog");
            relief_ok!["--cog", "tile", "mosaic", &dir, "--out", &cog];
            assert_same(&single, &cog);
        }
    }
    for p in PRODUCTS {
        let f = format!("{p}.tif");
        let (a, b) = (
            std::fs::read(outs[0].join(&f)),
            std::fs::read(outs[1].join(&f)),
        );
        assert!(
            a.unwrap() == b.unwrap(),
            "{f}: the copied blocks differ from the encoded tiles"
        );
    }
}

/// What a flow plan cannot reproduce exactly is refused by name, and nothing is planned.
#[test]
fn flow_plans_refuse_what_they_cannot_tile_exactly() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 64, 64));
    let plan = tmp.path().join("plan");
    let out = tmp.path().join("out");
    plan_refuses(
        "flow",
        &plan,
        &input,
        &out,
        &[
            (vec!["--depressions", "epsilon"], "--depressions epsilon"),
            (vec!["--depressions", "breach"], "--depressions breach"),
            (vec!["--directions", "mfd"], "--directions mfd"),
            (vec!["--json"], "--json"),
        ],
    );
    fails_with(
        &relief![
            "tile", "plan", &plan, "--tile", "20", "--", "flow", &input, "-o", &out
        ],
        &["--tile"],
        &[&plan],
    );
    assert_eq!(files(tmp.path()), ["crop.tif"]);
}

/// Planted and damaged plan files are refused by name: a link in place of a product, an
/// oversized product, a record of another plan.
#[test]
fn flow_plan_files_are_untrusted() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 64, 48));
    let plan = tmp.path().join("plan");
    let out = tmp.path().join("out");
    relief_ok![
        "tile", "plan", &plan, "--tile", "32", "--", "flow", &input, "-o", &out
    ];
    for i in 0..4 {
        relief_ok![
            "tile",
            "run",
            &plan,
            "--phase",
            "1",
            "--index",
            i.to_string()
        ];
    }
    relief_ok!["tile", "run", &plan, "--phase", "2"];
    // A link planted in place of a phase-1 product: not a regular file, refused.
    let fill = plan.join("phase1/fill-000000.bin");
    let secret = tmp.path().join("secret.bin");
    std::fs::rename(&fill, &secret).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&secret, &fill).unwrap();
    #[cfg(unix)]
    fails_with(
        &relief!["tile", "run", &plan, "--phase", "3", "--index", "0"],
        &["fill-000000.bin", "not a regular file"],
        &[],
    );
    std::fs::remove_file(&fill).ok();
    // An oversized file in place of a product.
    std::fs::write(&fill, vec![0u8; 64 * 80 * 80]).unwrap();
    let st = relief!["tile", "status", &plan];
    assert!(String::from_utf8_lossy(&st.stdout).contains("corrupt: 0"));
    relief_ok!["tile", "run", &plan, "--phase", "1", "--index", "0"];
    // A link planted in place of one of the plan's folders: refused before anything is read
    // or written through it.
    #[cfg(unix)]
    {
        let elsewhere = tmp.path().join("elsewhere");
        std::fs::create_dir(&elsewhere).unwrap();
        let p3 = plan.join("phase3");
        std::fs::remove_dir(&p3).unwrap();
        std::os::unix::fs::symlink(&elsewhere, &p3).unwrap();
        fails_with(
            &relief!["tile", "run", &plan, "--phase", "3", "--index", "0"],
            &["phase3", "not a folder of the plan"],
            &[],
        );
        assert!(files(&elsewhere).is_empty());
        std::fs::remove_file(&p3).unwrap();
        std::fs::create_dir(&p3).unwrap();
    }
    // A record copied from another plan does not count.
    let rec = plan.join("phase1/task-000001.json");
    let text = std::fs::read_to_string(&rec).unwrap();
    let id = json(&plan.join("manifest.json"))["plan_id"]
        .as_str()
        .unwrap()
        .to_string();
    std::fs::write(&rec, text.replace(&id, &"0".repeat(64))).unwrap();
    fails_with(
        &relief!["tile", "run", &plan, "--phase", "3", "--index", "1"],
        &["phase 1 is incomplete", "1"],
        &[],
    );
}

/// A georeferenced input (the grandcanyon fixture, EPSG:3857): the mosaics carry the single
/// run's georeference (each tile placed on the map, the mosaic over the whole grid).
#[test]
fn flow_plan_keeps_the_georeference() {
    let (_tmp, dem, hf) = tmp_with_crop("gc.tif", (40, 30, 200, 150));
    assert!(hf.georef().and_then(|g| g.geotransform).is_some());
    cycle(&dem, 64, 23);
}
