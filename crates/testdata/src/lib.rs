//! Test support for the relief workspace (not published).
//!
//! Locates the real DEM set (`shared/data/dem` beside the checkout, or `$RELIEF_DEM_DIR`) and
//! loads its `.f32` rasters with their sidecars. When the folder is absent, [`dem_dir`] prints
//! a notice and returns `None` so a test can skip, unless the environment variable `CI` is
//! set: then it panics, because CI must run every real-data test.
//!
//! Only test code depends on this crate; library crates never read files themselves.
#![allow(clippy::print_stderr)]

use std::path::{Path, PathBuf};

use relief_heightfield::Heightfield;

/// Directory of the workspace root (two levels above this crate).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

/// A bundled fixture of the workspace (`fixtures/<name>`, e.g. `grandcanyon.tif`).
pub fn fixture(name: &str) -> PathBuf {
    workspace_root().join("fixtures").join(name)
}

/// The real DEM folder, or `None` (with a notice on stderr) when absent outside CI.
///
/// # Panics
/// Panics when the folder is absent and `CI` is set.
pub fn dem_dir() -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("RELIEF_DEM_DIR").map(PathBuf::from),
        Some(workspace_root().join("../shared/data/dem")),
    ];
    for c in candidates.into_iter().flatten() {
        if c.join("MANIFEST.md").is_file() {
            return Some(c);
        }
    }
    if std::env::var_os("CI").is_some() {
        panic!(
            "the real DEM set (../shared/data/dem) is absent but CI is set: CI must run real-data tests"
        );
    }
    eprintln!("notice: ../shared/data/dem not found; skipping a real-DEM test");
    None
}

/// Loads `<id>.f32` with its sidecar (`cell_size_x_m`, `cell_size_y_m`); voids (`nodata`) become
/// NaN. Returns `None` when the DEM folder is absent (see [`dem_dir`]).
///
/// # Panics
/// Panics on a malformed file: the shared set is trusted test data.
pub fn load_dem(id: &str) -> Option<Heightfield> {
    let dir = dem_dir()?;
    let side: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join(format!("{id}.json"))).expect("sidecar"))
            .expect("sidecar json");
    let w = side["width"].as_u64().expect("width") as usize;
    let h = side["height"].as_u64().expect("height") as usize;
    let cx = side["cell_size_x_m"]
        .as_f64()
        .or(side["cell_size_m"].as_f64())
        .expect("cell");
    let cy = side["cell_size_y_m"]
        .as_f64()
        .or(side["cell_size_m"].as_f64())
        .expect("cell");
    let nodata = side["nodata"].as_f64();
    let bytes = std::fs::read(dir.join(format!("{id}.f32"))).expect("f32 raster");
    let data: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .map(|v| {
            if nodata.is_some_and(|nd| v as f64 == nd) {
                f32::NAN
            } else {
                v
            }
        })
        .collect();
    Some(Heightfield::new(w, h, data, cx, cy).expect("valid DEM"))
}

/// A crop of a real DEM: `load_dem(id)` then `crop(x, y, w, h)`.
pub fn dem_crop(id: &str, x: usize, y: usize, w: usize, h: usize) -> Option<Heightfield> {
    load_dem(id).map(|d| d.crop(x, y, w, h).expect("crop inside the DEM"))
}

/// Writes the hillshade of `hf` (sun at 315 degrees azimuth, 45 degrees altitude) as an 8-bit
/// binary PGM image (the measurement examples' pictures).
///
/// # Panics
/// Panics when the file cannot be written.
pub fn write_shade(path: &Path, hf: &Heightfield) {
    let s = relief_heightfield::terrain::hillshade(hf, 315.0, 45.0, 1.0);
    let mut bytes = format!("P5\n{} {}\n255\n", hf.width(), hf.height()).into_bytes();
    bytes.extend(s.iter().map(|v| (v * 255.0).round() as u8));
    std::fs::write(path, bytes).expect("write the PGM image");
}

/// RMS (metres) of the detail finer than `k` cells: the grid minus its box x`k` reduction
/// up-sampled back.
///
/// # Panics
/// Panics when `hf` cannot be reduced by `k` (smaller than `k` cells) or has only voids.
pub fn detail_rms(hf: &Heightfield, k: usize) -> f64 {
    let low = hf
        .downsample_box(k)
        .expect("box reduction")
        .resample(hf.width(), hf.height())
        .expect("resampling back");
    relief_heightfield::metrics::rmse(hf, &low).expect("rmse")
}

/// Runs `f` on a rayon pool of `threads` workers (the determinism tests compare runs on
/// different thread counts).
///
/// # Panics
/// Panics when the pool cannot be built.
pub fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool")
        .install(f)
}

/// A window of a real DEM, `(id, x, y, w, h)` (see [`dem_crop`]): test files name the crops
/// they share as constants.
pub type Crop<'a> = (&'a str, usize, usize, usize, usize);

/// Several crops at once (see [`dem_crop`]), or `None` when the DEM folder is absent:
/// `let Some([a, b]) = dem_crops([..]) else { return };` skips a test.
pub fn dem_crops<const N: usize>(crops: [Crop<'_>; N]) -> Option<[Heightfield; N]> {
    let all: Option<Vec<Heightfield>> = crops
        .map(|(id, x, y, w, h)| dem_crop(id, x, y, w, h))
        .into_iter()
        .collect();
    all?.try_into().ok()
}

/// Several windows `(x, y, w, h)` of one real DEM, read once (see [`dem_crop`]), or `None` when
/// the DEM folder is absent.
pub fn dem_windows<const N: usize>(
    id: &str,
    windows: [(usize, usize, usize, usize); N],
) -> Option<[Heightfield; N]> {
    let dem = load_dem(id)?;
    Some(windows.map(|(x, y, w, h)| dem.crop(x, y, w, h).expect("crop inside the DEM")))
}

/// Checks the JSON contract of a job settings type: `value` round-trips through
/// JSON whose text contains every one of `fragments`, and `{}` reads as `T::default()`.
/// Returns the JSON text.
///
/// # Panics
/// Panics when one of these does not hold.
pub fn assert_json_round_trip<T>(value: &T, fragments: &[&str]) -> String
where
    T: serde::Serialize + serde::de::DeserializeOwned + PartialEq + Default + std::fmt::Debug,
{
    let json = serde_json::to_string(value).expect("serialise");
    for f in fragments {
        assert!(json.contains(f), "{f} not in {json}");
    }
    assert_eq!(&serde_json::from_str::<T>(&json).expect("read back"), value);
    assert_eq!(
        serde_json::from_str::<T>("{}").expect("read {}"),
        T::default()
    );
    json
}

/// CPU seconds of this process so far (user + system, all threads, from `/proc/self/stat`; 0
/// where it cannot be read), for the timing examples on a shared machine.
pub fn cpu_seconds() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let f: Vec<&str> = s
        .rsplit(')')
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect();
    let t = |k: usize| f.get(k).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (t(11) + t(12)) / 100.0
}

/// The value of `f` and the seconds it took (the measurement examples' timings).
pub fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = std::time::Instant::now();
    let v = f();
    (v, t.elapsed().as_secs_f64())
}

/// The damage contract of a checksummed stream (`.dict`, `.sct`): reading (`read`) the prefix
/// `bytes[..n]` for every `n` in `prefixes`, or a copy of `bytes` with any one byte changed
/// (`bytes[i] ^ flip`), is an error, never a panic nor a value.
///
/// # Panics
/// Panics when one of them reads.
pub fn assert_truncations_and_flips_refused<T, E>(
    bytes: &[u8],
    prefixes: impl IntoIterator<Item = usize>,
    flip: u8,
    read: impl Fn(&[u8]) -> Result<T, E>,
) {
    for n in prefixes {
        assert!(read(&bytes[..n]).is_err(), "prefix {n}");
    }
    let mut c = bytes.to_vec();
    for i in 0..bytes.len() {
        c[i] ^= flip;
        assert!(read(&c).is_err(), "byte {i} flipped");
        c[i] ^= flip;
    }
}

/// The ids of the real DEM set.
pub const DEM_IDS: [&str; 8] = [
    "alps_dem",
    "N47E011",
    "grandcanyon",
    "carrizo",
    "maunga_whau",
    "jacksboro_fault",
    "topobathy",
    "N57E011",
];

/// Issue 17's painted sketch guide in the JSON `relief quilt --guide-sketch` reads: 512 x 512
/// cells (at the exemplar's cell size), a ridge stroke across the top third rising to a
/// 2300 m summit, a valley stroke winding down to a 700 m basin in the bottom right, and a
/// 1700 m plateau seed on the left (heights in metres).
pub const PAINTED_SKETCH_JSON: &str = r#"{"width": 512, "height": 512, "smoothing": 4,
    "seeds": [{"x": 110, "y": 330, "height": 1700, "radius": 40},
              {"x": 430, "y": 440, "height": 700, "radius": 30}],
    "strokes": [{"points": [[20, 150, 1500], [200, 120, 1900], [330, 170, 2300],
                            [490, 110, 1800]]},
                {"points": [[250, 260, 1300], [300, 350, 1000], [380, 400, 850],
                            [430, 440, 700]]}]}"#;

/// Flood fill of a `width x height` grid from `start`, 4-connected, through the cells where
/// `free(i, k)` (column `i`, row `k`): how many cells it reaches and whether it reaches the
/// grid's border (where it stops). The volume tests' "is this air enclosed?" on a section.
pub fn flood_fill(
    width: usize,
    height: usize,
    start: (usize, usize),
    free: impl Fn(usize, usize) -> bool,
) -> (usize, bool) {
    let mut seen = vec![false; width * height];
    let mut stack = vec![start];
    let (mut n, mut open) = (0, false);
    while let Some((i, k)) = stack.pop() {
        if seen[k * width + i] || !free(i, k) {
            continue;
        }
        seen[k * width + i] = true;
        n += 1;
        if i == 0 || k == 0 || i == width - 1 || k == height - 1 {
            open = true;
            continue;
        }
        stack.extend([(i - 1, k), (i + 1, k), (i, k - 1), (i, k + 1)]);
    }
    (n, open)
}

/// The tiled drainage tests' terrain, `w x h` cells row-major: a closed bowl over the middle of
/// the map (filled to its rim, a lake spanning tiles), a river meandering from the west edge to
/// the east edge across every row of tiles and draining west, integer elevations (flats
/// everywhere) and, where the hash `seed` of a cell falls below `voids` (a fraction), a void.
pub fn basin_and_river(w: usize, h: usize, seed: u64, voids: f32) -> Vec<f32> {
    let (fw, fh) = (w as f32, h as f32);
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let u = relief_heightfield::rng::unit_f32(relief_heightfield::rng::hash(
                seed, i as u64, 0, 0,
            ));
            // The bowl: centre of the map, closed on every side.
            let (dx, dy) = ((x - fw * 0.5) / fw, (y - fh * 0.5) / fh);
            let r = (dx * dx + dy * dy).sqrt();
            let bowl = if r < 0.3 {
                10.0 + 60.0 * r
            } else {
                28.0 + (r - 0.3) * 120.0
            };
            // The river: a sine from the west edge to the east edge, crossing every row of
            // tiles on its way (it winds through the whole map) and draining west.
            let path = fh * (0.5 + 0.42 * (x / fw * 9.0).sin());
            let river = ((y - path).abs() - 2.0).max(0.0) * 3.0 + x * 0.05;
            // Inside the bowl, the bowl alone; outside, the terrain falls to the river.
            let z = if r < 0.3 {
                bowl
            } else if (y - path).abs() < 3.0 {
                river
            } else {
                bowl.min(river + 6.0)
            };
            if u < voids {
                f32::NAN
            } else {
                (z + u * 2.0).floor()
            }
        })
        .collect()
}
