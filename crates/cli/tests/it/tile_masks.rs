//! `relief tile plan -- masks`: the eight-phase masks plan (the drainage's seven, then the
//! masks per tile) mosaics into `relief masks`'s GeoTIFF masks value for value (bit for
//! bit), its splat map and `masks.json` byte for byte, on a real DEM crop with non-square
//! cells and on a synthetic basin with voids and flats over 3 x 3 tiles; what it cannot
//! reproduce is refused by name.

use std::path::Path;

use crate::common::*;
use crate::tile_flow::{basin, plan_refuses, run_phases_to, single_and_plan, tasks};

const MASKS: [&str; 7] = [
    "slope",
    "profile_curvature",
    "plan_curvature",
    "area",
    "wetness",
    "hand",
    "height_band",
];

/// `relief masks DEM EXTRA` and its plan as tiles of `tile` cells, every phase run in
/// shuffled order: the same files.
fn masks_plan_equals_single(dem: &Path, tile: usize, extra: &[&str], seed: u64) {
    let (_tmp, [single, tiled, dir], planned) = single_and_plan("masks", dem, tile, extra);
    let note = stderr(&planned);
    assert!(planned.status.success(), "{note}");
    assert!(
        note.contains("in 8 phases") && note.contains("--phase 8"),
        "{note}"
    );
    let n = tasks(&dir);
    assert!(n >= 4, "{n} tiles");
    run_phases_to(&dir, n, seed, 7);
    let st = relief!["tile", "status", &dir];
    let text = String::from_utf8_lossy(&st.stdout).to_string();
    assert!(
        !st.status.success() && text.contains("next: phase 8"),
        "{text}"
    );
    fails_with(
        &relief!["tile", "mosaic", &dir],
        &["phase 8 are missing"],
        &[&tiled],
    );
    run_phases_to(&dir, n, seed, 8);
    relief_ok!["tile", "status", &dir];
    relief_ok!["tile", "mosaic", &dir];
    for m in MASKS {
        let f = format!("{m}.tif");
        assert_same_raster(&single.join(&f), &tiled.join(&f));
    }
    for f in ["splat.png", "masks.json"] {
        assert!(
            std::fs::read(single.join(f)).unwrap() == std::fs::read(tiled.join(f)).unwrap(),
            "{f} differs from the single run's"
        );
    }
    // The masks are not trivially equal: the bands split the map, the splat map has rock.
    let bands = &json(&tiled.join("masks.json"))["bands"];
    assert_eq!(bands.as_array().map(Vec::len), Some(3), "{bands}");
    assert!(dir.join("mosaic-wetness.vrt").exists());
}

/// A real DEM crop (alps_dem, 200 x 150 cells of 42.6 x 61.8 m), tiles of 64 cells.
#[test]
fn masks_plan_equals_the_single_run_on_a_real_dem() {
    let Some(hf) = relief_testdata::dem_crop("alps_dem", 120, 100, 200, 150) else {
        return;
    };
    let (_tmp, dem) = tmp_with("alps.tif", &hf);
    masks_plan_equals_single(&dem, 64, &[], 3);
}

/// The 96 x 96 basin (voids, flats, a lake over nine tiles) as tiles of 32 cells, with
/// given height bands and a rock slope.
#[test]
fn masks_plan_equals_the_single_run_on_a_basin_over_nine_tiles() {
    let (_tmp, dem) = tmp_with("basin.tif", &basin());
    masks_plan_equals_single(&dem, 32, &[], 5);
    masks_plan_equals_single(
        &dem,
        32,
        &["--height-bands", "20,40,60", "--rock-slope", "20"],
        9,
    );
}

/// What a masks plan cannot reproduce exactly is refused by name, and nothing is planned.
#[test]
fn masks_plans_refuse_what_they_cannot_tile_exactly() {
    let (tmp, input, _) = tmp_with_crop("crop.tif", (0, 0, 64, 64));
    let plan = tmp.path().join("plan");
    let out = tmp.path().join("out");
    let dep = tmp.path().join("crop.tif");
    plan_refuses(
        "masks",
        &plan,
        &input,
        &out,
        &[
            (vec!["--format", "png8"], "--format png8/png16"),
            (vec!["--deposition-depth", s(&dep)], "--deposition-depth"),
            (vec!["--directions", "mfd"], "--directions mfd"),
            (vec!["--json"], "--json"),
        ],
    );
    fails_with(
        &relief!["tile", "plan", &plan, "--", "erode", &input, "-o", &out],
        &["relief erode", "cannot be planned"],
        &[&plan],
    );
    assert_eq!(files(tmp.path()), ["crop.tif"]);
}
