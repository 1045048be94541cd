//! The conventions of each engine `relief export` writes for: the heightmap sizes it takes,
//! how a DEM is fitted to them, the file layout (format, byte order, row order, tile names) and
//! the import settings that turn the 16-bit counts back into metres.
//!
//! Sources (see the README's engine table):
//! - Unreal Engine, Landscape Technical Guide, "Recommended Landscape Sizes": 127, 253, 505,
//!   1009, 2017, 4033 and 8129 vertices per side (63 or 127 quads per section, 2x2 sections
//!   per component). The heightmap's counts are read as `(count - 32768) / 128 * ZScale`
//!   centimetres about the actor's location (Z scale 100: -256..256 m); X/Y scale are
//!   centimetres per quad. PNG rows are read north (image top) first; tiles are
//!   `NAME_x<X>_y<Y>` with `y0` the top row, each a landscape of a recommended size sharing
//!   its edge samples (placed by the sheet's Location X, Y). UE5's World Partition import of
//!   such a set (`FLandscapeImportHelper`) copies file (X, Y) to `X x width, Y x height`
//!   without overlap, so that import takes one heightmap, not shared-edge tiles.
//! - Unity, TerrainData and the terrain inspector's Import Raw: heightmap resolution
//!   `2^n + 1` (33..4097), 16-bit raw with byte order "Windows" (little-endian), raw row 0 is
//!   the terrain's z = 0 edge (south) unless "Flip Vertically" is ticked, height =
//!   count / 65536 x terrain height. Terrain Tools names tiles `NAME_<X>_<Z>`, Z northwards.
//! - Godot Terrain3D, `Terrain3DUtil::load_image`: R16/RAW little-endian, row 0 first,
//!   height = count / 65535 x (max - min) + min with the importer's `r16_height_range`;
//!   regions of 64..2048 vertices (the importer pads any size into regions).
//! - Gaea: any size; a 16-bit PNG is read as count / 65535 of the terrain's Height.

use anyhow::{Result, bail};
use serde::Serialize;

/// The engine (or tool) the export is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub(crate) enum Engine {
    /// Unreal Engine landscape: 16-bit PNG (or .r16), recommended landscape sizes, tiles
    /// NAME_x0_y0 (one landscape each), 8-bit weight maps per layer.
    Unreal,
    /// Unity terrain: 16-bit little-endian .raw of 2^n+1, tiles NAME_X_Z, RGBA splat
    /// (alphamap) per terrain.
    Unity,
    /// Godot Terrain3D: 16-bit little-endian .raw, long side a multiple of the region size,
    /// RGBA splat.
    Godot,
    /// Gaea: 16-bit PNG of any size, 8-bit masks per layer.
    Gaea,
}

/// How the heightmap size is chosen among the engine's sizes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub(crate) enum Fit {
    /// The size nearest to the DEM's (in ratio: 1500 samples go to 2017 rather than 1009).
    Nearest,
    /// The smallest size that keeps every DEM sample (never downsamples).
    Up,
    /// The largest size within the DEM's (never upsamples).
    Down,
}

/// The heightmap file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub(crate) enum HeightFormat {
    /// 16-bit greyscale PNG (big-endian as PNG defines).
    Png,
    /// Headerless 16-bit little-endian samples.
    R16,
}

/// Unreal's recommended landscape sizes (vertices per side) with their layout: quads per
/// section, sections per component per axis, components per axis.
pub(crate) const UNREAL_SIZES: [(usize, usize, usize, usize); 7] = [
    (127, 63, 2, 1),
    (253, 63, 2, 2),
    (505, 63, 2, 4),
    (1009, 63, 2, 8),
    (2017, 63, 2, 16),
    (4033, 63, 2, 32),
    (8129, 127, 2, 32),
];

/// Terrain3D's region sizes (vertices per side).
pub(crate) const GODOT_REGIONS: [usize; 6] = [64, 128, 256, 512, 1024, 2048];

/// Terrain3D's region map holds this many regions per axis.
const GODOT_MAX_REGIONS: usize = 32;

/// Gaea (any size): the largest side written.
const GAEA_MAX: usize = 65536;

impl Engine {
    /// The name shown in messages and sheets.
    pub(crate) fn title(self) -> &'static str {
        match self {
            Engine::Unreal => "Unreal Engine",
            Engine::Unity => "Unity",
            Engine::Godot => "Godot (Terrain3D)",
            Engine::Gaea => "Gaea",
        }
    }

    /// Whether the heightmap is square (Unreal and Unity: the long side sets both).
    pub(crate) fn square(self) -> bool {
        matches!(self, Engine::Unreal | Engine::Unity)
    }

    /// Whether the engine takes tiles of shared edges (separate landscapes or terrains).
    pub(crate) fn tiles(self) -> bool {
        matches!(self, Engine::Unreal | Engine::Unity)
    }

    /// The default heightmap format, and whether `format` is one the engine reads.
    pub(crate) fn format(self, format: Option<HeightFormat>) -> Result<HeightFormat> {
        let (default, ok): (HeightFormat, &[HeightFormat]) = match self {
            Engine::Unreal => (HeightFormat::Png, &[HeightFormat::Png, HeightFormat::R16]),
            Engine::Gaea => (HeightFormat::Png, &[HeightFormat::Png, HeightFormat::R16]),
            // Unity's Import Raw takes raw only; Godot reads PNG as 8 bits per channel.
            Engine::Unity | Engine::Godot => (HeightFormat::R16, &[HeightFormat::R16]),
        };
        match format {
            None => Ok(default),
            Some(f) if ok.contains(&f) => Ok(f),
            Some(_) => bail!(
                "--format png: {} reads 16-bit heightmaps as raw only (--format r16)",
                self.title()
            ),
        }
    }

    /// The sizes (vertices per side) the engine takes, in increasing order; `None`: any.
    pub(crate) fn sizes(self, region: usize) -> Option<Vec<usize>> {
        match self {
            Engine::Unreal => Some(UNREAL_SIZES.iter().map(|s| s.0).collect()),
            Engine::Unity => Some((5..=12).map(|n| (1 << n) + 1).collect()),
            Engine::Godot => Some((1..=GODOT_MAX_REGIONS).map(|k| k * region).collect()),
            Engine::Gaea => None,
        }
    }

    /// The sizes a tile may have (Unreal, Unity: those of a whole heightmap).
    pub(crate) fn tile_sizes(self) -> Vec<usize> {
        self.sizes(GODOT_REGIONS[2]).unwrap_or_default()
    }

    /// The file extension of the heightmap.
    pub(crate) fn extension(self, format: HeightFormat) -> &'static str {
        match (self, format) {
            (_, HeightFormat::Png) => "png",
            // Unity's and Terrain3D's file dialogs look for `.raw`.
            (Engine::Unity | Engine::Godot, HeightFormat::R16) => "raw",
            (_, HeightFormat::R16) => "r16",
        }
    }

    /// Whether raw row 0 is the south edge (Unity), not the north one.
    pub(crate) fn south_first(self) -> bool {
        self == Engine::Unity
    }

    /// The file name of tile `(x, y)` of `nx x ny`, `y` counted from the north (row 0).
    pub(crate) fn tile_name(self, stem: &str, (x, y): (usize, usize), ny: usize) -> String {
        match self {
            // Terrain Tools' batch import: NAME_X_Z, Z northwards.
            Engine::Unity => format!("{stem}_{x}_{}", ny - 1 - y),
            _ => format!("{stem}_x{x}_y{y}"),
        }
    }
}

/// Checks a `--region-size` (Godot only).
pub(crate) fn check_region(engine: Engine, region: usize, given: bool) -> Result<()> {
    if given && engine != Engine::Godot {
        bail!("--region-size is Terrain3D's (--engine godot)");
    }
    if !GODOT_REGIONS.contains(&region) {
        bail!("--region-size {region}: Terrain3D's region sizes are {GODOT_REGIONS:?}");
    }
    Ok(())
}

/// The engine's size nearest to `natural` samples under `fit` (`what` names the flag).
pub(crate) fn pick(natural: f64, sizes: &[usize], fit: Fit, what: &str) -> Result<usize> {
    let (Some(&lo), Some(&hi)) = (sizes.first(), sizes.last()) else {
        bail!("{what}: no size to choose from");
    };
    let chosen = match fit {
        Fit::Up => sizes.iter().copied().find(|&s| s as f64 >= natural - 1e-9),
        Fit::Down => sizes
            .iter()
            .copied()
            .rev()
            .find(|&s| s as f64 <= natural + 1e-9),
        Fit::Nearest => sizes.iter().copied().min_by(|&a, &b| {
            let d = |s: usize| (s as f64 / natural.max(1.0)).ln().abs();
            d(a).total_cmp(&d(b)).then(b.cmp(&a))
        }),
    };
    match chosen {
        Some(s) => Ok(s),
        None if fit == Fit::Up => bail!(
            "{what}: {natural:.0} samples are more than the largest size {hi}: use tiles \
             (--tiles or --tile-size), --fit nearest or --fit down"
        ),
        None => bail!(
            "{what}: {natural:.0} samples are fewer than the smallest size {lo}: use --fit \
             nearest or --fit up"
        ),
    }
}

/// A count of tiles along one axis for `quads` quads of the DEM in tiles of `tile_quads`.
fn tile_count(quads: f64, tile_quads: usize, fit: Fit) -> usize {
    let r = quads / tile_quads as f64;
    let n = match fit {
        Fit::Nearest => r.round(),
        Fit::Up => (r - 1e-9).ceil(),
        Fit::Down => (r + 1e-9).floor(),
    };
    (n as usize).max(1)
}

/// The layout of the export: the whole grid's samples, and its tiles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub(crate) struct Layout {
    /// Samples of the whole grid (x, y).
    pub(crate) samples: (usize, usize),
    /// Tiles (x, y) and their side in samples (one shared edge sample), when tiled.
    pub(crate) tiles: Option<((usize, usize), usize)>,
}

/// What the user asked for the size.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct SizeAsk {
    pub(crate) size: Option<usize>,
    pub(crate) tiles: Option<(usize, usize)>,
    pub(crate) tile_size: Option<usize>,
    pub(crate) region: usize,
}

/// Chooses the layout for a DEM of `cells` (w, h) under `fit` and the flags of `ask`.
pub(crate) fn layout(
    engine: Engine,
    cells: (usize, usize),
    fit: Fit,
    ask: SizeAsk,
) -> Result<Layout> {
    let (w, h) = (cells.0 as f64, cells.1 as f64);
    if ask.tiles.is_some() || ask.tile_size.is_some() {
        if !engine.tiles() {
            bail!(
                "--tiles/--tile-size: {} takes one heightmap (its importer splits it into \
                 regions itself); tiles are for --engine unreal or unity",
                engine.title()
            );
        }
        if ask.size.is_some() {
            bail!("--size is the side of one heightmap; with tiles give --tile-size");
        }
        let list = engine.tile_sizes();
        let t = match ask.tile_size {
            Some(t) if !list.contains(&t) => {
                bail!("--tile-size {t}: {} takes {list:?}", engine.title())
            }
            Some(t) => t,
            None => {
                let (nx, ny) = ask.tiles.unwrap_or((1, 1));
                pick(
                    (w / nx as f64).max(h / ny as f64) + 1.0,
                    &list,
                    fit,
                    "--tiles",
                )?
            }
        };
        let (nx, ny) = ask
            .tiles
            .unwrap_or_else(|| (tile_count(w, t - 1, fit), tile_count(h, t - 1, fit)));
        if nx == 0 || ny == 0 || nx > 256 || ny > 256 {
            bail!("--tiles {nx}x{ny}: 1 to 256 tiles per axis");
        }
        let samples = (nx * (t - 1) + 1, ny * (t - 1) + 1);
        return Ok(Layout {
            samples,
            tiles: Some(((nx, ny), t)),
        });
    }
    let long = w.max(h) + 1.0;
    let side = match (ask.size, engine.sizes(ask.region)) {
        (Some(s), Some(list)) if !list.contains(&s) => {
            let shown: Vec<usize> = list.iter().copied().take(12).collect();
            bail!(
                "--size {s}: {} takes {shown:?}{}",
                engine.title(),
                if list.len() > 12 { " ..." } else { "" }
            )
        }
        (Some(s), None) if !(2..=GAEA_MAX).contains(&s) => {
            bail!("--size {s}: 2 to {GAEA_MAX} samples")
        }
        (Some(s), _) => s,
        (None, Some(list)) => pick(long, &list, fit, "--fit")?,
        (None, None) if long > GAEA_MAX as f64 => {
            bail!("the DEM's {long} samples are more than {GAEA_MAX}: give --size")
        }
        (None, None) => long as usize,
    };
    let samples = if engine.square() {
        (side, side)
    } else {
        // The short side keeps the DEM's cell aspect (the importer pads regions itself).
        let short = ((w.min(h) * (side - 1) as f64 / (long - 1.0)).round() as usize + 1).max(2);
        if w >= h { (side, short) } else { (short, side) }
    };
    Ok(Layout {
        samples,
        tiles: None,
    })
}

/// The vertical mapping of the 16-bit counts: `metres = lo + count * step`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub(crate) struct Vertical {
    /// Height of count 0 (m).
    pub(crate) lo: f64,
    /// Height of count 65535 (m).
    pub(crate) hi: f64,
    /// Metres per count.
    pub(crate) step: f64,
}

impl Vertical {
    /// The mapping of `lo..hi` onto 0..=65535 (a flat range gets 1 m).
    pub(crate) fn new(lo: f64, hi: f64) -> Vertical {
        let hi = if hi > lo { hi } else { lo + 1.0 };
        Vertical {
            lo,
            hi,
            step: (hi - lo) / 65535.0,
        }
    }
}

/// One import setting: its name in the engine's UI and its value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct Setting {
    pub(crate) name: &'static str,
    pub(crate) value: String,
}

fn set(name: &'static str, value: impl std::fmt::Display) -> Setting {
    Setting {
        name,
        value: value.to_string(),
    }
}

/// The import settings of the export: `spacing` is the distance between samples (m, x and y),
/// `tile_samples` the side of one heightmap (a tile's, or the whole grid's).
pub(crate) fn settings(
    engine: Engine,
    v: Vertical,
    spacing: (f64, f64),
    samples: (usize, usize),
    tile_samples: (usize, usize),
) -> Vec<Setting> {
    let quads = |n: usize| (n - 1) as f64;
    match engine {
        Engine::Unreal => {
            let layout = UNREAL_SIZES.iter().find(|s| s.0 == tile_samples.0);
            let mut s = vec![
                set("Location Z (cm)", format!("{:.3}", unreal_location_z_cm(v))),
                set("Scale X (cm per quad)", format!("{:.4}", spacing.0 * 100.0)),
                set("Scale Y (cm per quad)", format!("{:.4}", spacing.1 * 100.0)),
                set("Scale Z", format!("{:.6}", unreal_z_scale(v))),
            ];
            if let Some(&(_, q, sec, _)) = layout {
                s.push(set("Section Size", format!("{q}x{q} Quads")));
                s.push(set(
                    "Sections Per Component",
                    format!("{sec}x{sec} Sections"),
                ));
            }
            let comp = layout.map_or(126, |l| l.1 * l.2);
            s.push(set(
                "Number of Components",
                format!("{} x {}", (samples.0 - 1) / comp, (samples.1 - 1) / comp),
            ));
            s.push(set(
                "Overall Resolution",
                format!("{} x {}", samples.0, samples.1),
            ));
            s
        }
        Engine::Unity => vec![
            set("Depth", "Bit 16"),
            set("Resolution", tile_samples.0),
            set("Byte Order", "Windows"),
            set("Flip Vertically", "off"),
            set(
                "Terrain Size (width, height, length) (m)",
                format!(
                    "{:.4}, {:.6}, {:.4}",
                    spacing.0 * quads(tile_samples.0),
                    unity_height(v),
                    spacing.1 * quads(tile_samples.1)
                ),
            ),
            set("Position Y (m)", format!("{:.4}", v.lo)),
        ],
        Engine::Godot => vec![
            set(
                "r16_height_range (min, max) (m)",
                format!("{:.4}, {:.4}", v.lo, v.hi),
            ),
            set("r16_size", format!("{}, {}", samples.0, samples.1)),
            set("vertex_spacing (m)", format!("{:.4}", spacing.0)),
            set("import_scale", 1),
            set("height_offset", 0),
        ],
        Engine::Gaea => vec![
            set("Resolution", format!("{} x {}", samples.0, samples.1)),
            set(
                "Terrain size (m)",
                format!(
                    "{:.3} x {:.3}",
                    spacing.0 * quads(samples.0),
                    spacing.1 * quads(samples.1)
                ),
            ),
            set("Height (m)", format!("{:.4}", v.hi - v.lo)),
            set("Base elevation (m)", format!("{:.4}", v.lo)),
        ],
    }
}

/// Unreal's Z scale: one count is `ZScale / 128` cm, so the 65535 steps of `v` need
/// `step x 100 x 128` (the usual `range_m x 100 / 512`, exact at both ends).
pub(crate) fn unreal_z_scale(v: Vertical) -> f64 {
    v.step * 100.0 * 128.0
}

/// Unreal's actor Location Z (cm) that puts count 32768 (the landscape's zero) where `v`
/// maps it, so count 0 lands on `v.lo`.
pub(crate) fn unreal_location_z_cm(v: Vertical) -> f64 {
    (v.lo + 32768.0 * v.step) * 100.0
}

/// Unity's terrain height: Import Raw reads `count / 65536` of it.
pub(crate) fn unity_height(v: Vertical) -> f64 {
    v.step * 65536.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unreal_sizes_are_whole_components() {
        for (n, q, sec, comp) in UNREAL_SIZES {
            assert_eq!(n - 1, q * sec * comp, "{n}");
        }
    }

    #[test]
    fn picks_follow_the_fit() {
        let list = Engine::Unreal.sizes(256).unwrap();
        assert_eq!(pick(1500.0, &list, Fit::Nearest, "x").unwrap(), 2017);
        assert_eq!(pick(1200.0, &list, Fit::Nearest, "x").unwrap(), 1009);
        assert_eq!(pick(1010.0, &list, Fit::Up, "x").unwrap(), 2017);
        assert_eq!(pick(1010.0, &list, Fit::Down, "x").unwrap(), 1009);
        assert_eq!(pick(1009.0, &list, Fit::Up, "x").unwrap(), 1009);
        assert!(pick(9000.0, &list, Fit::Up, "x").is_err());
        assert!(pick(100.0, &list, Fit::Down, "x").is_err());
        let unity = Engine::Unity.sizes(256).unwrap();
        assert_eq!(unity.first(), Some(&33));
        assert_eq!(unity.last(), Some(&4097));
    }

    #[test]
    fn layouts_of_each_engine() {
        let ask = SizeAsk {
            region: 256,
            ..Default::default()
        };
        let l = layout(Engine::Unreal, (300, 200), Fit::Nearest, ask).unwrap();
        assert_eq!(l.samples, (253, 253));
        let l = layout(Engine::Godot, (600, 300), Fit::Nearest, ask).unwrap();
        assert_eq!(l.samples, (512, 257)); // 511 quads x 255.5, rounded
        let l = layout(Engine::Gaea, (300, 200), Fit::Nearest, ask).unwrap();
        assert_eq!(l.samples, (301, 201));
        let tiles = SizeAsk {
            tiles: Some((2, 2)),
            ..ask
        };
        let l = layout(Engine::Unity, (256, 256), Fit::Nearest, tiles).unwrap();
        assert_eq!(l.samples, (257, 257));
        assert_eq!(l.tiles, Some(((2, 2), 129)));
        let by_size = SizeAsk {
            tile_size: Some(505),
            ..ask
        };
        let l = layout(Engine::Unreal, (2016, 1008), Fit::Nearest, by_size).unwrap();
        assert_eq!(l.tiles, Some(((4, 2), 505)));
        assert_eq!(l.samples, (2017, 1009));
        assert!(layout(Engine::Godot, (256, 256), Fit::Nearest, tiles).is_err());
        let bad = SizeAsk {
            size: Some(1000),
            ..ask
        };
        let e = layout(Engine::Unreal, (256, 256), Fit::Nearest, bad).unwrap_err();
        assert!(e.to_string().contains("1009"), "{e}");
    }

    #[test]
    fn vertical_scales_reconstruct_the_range() {
        let v = Vertical::new(100.0, 612.0);
        // Unreal: count c is LocZ + (c - 32768) * ZScale / 128 cm.
        let cm = |c: f64| unreal_location_z_cm(v) + (c - 32768.0) * unreal_z_scale(v) / 128.0;
        assert!((cm(0.0) - 10000.0).abs() < 1e-6);
        assert!((cm(65535.0) - 61200.0).abs() < 1e-6);
        // The usual rule of thumb: Z scale = range x 100 / 512.
        assert!((unreal_z_scale(v) - 512.0 * 100.0 / 512.0).abs() < 0.002);
        // Unity: count / 65536 of the terrain height above its position.
        assert!((65535.0 / 65536.0 * unity_height(v) + v.lo - 612.0).abs() < 1e-9);
    }

    #[test]
    fn tile_names_follow_each_engine() {
        assert_eq!(Engine::Unreal.tile_name("t", (1, 0), 2), "t_x1_y0");
        assert_eq!(Engine::Unity.tile_name("t", (1, 0), 2), "t_1_1");
        assert_eq!(Engine::Unity.tile_name("t", (0, 1), 2), "t_0_0");
    }
}
