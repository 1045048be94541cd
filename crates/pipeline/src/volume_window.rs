//! The window a volume scene is built on when the DEM is too coarse for its features
//! (issue 42: features at their physical size on amplified terrain, never kilometre-wide caves
//! on coarse cells), shared by `relief volume` and the pipeline's `volume` stage.

use anyhow::{Context, Result, bail};
use relief_implicit_volume::{Feature, VolumeJob};

/// What the caller says about the run: the flags of `relief volume` (the pipeline gives the
/// same from its parameters).
#[derive(Debug, Clone, Copy)]
pub struct WindowOptions<'a> {
    /// Keep the DEM's own cells (`--raw-dem`): no window.
    pub raw_dem: bool,
    /// A DEM-sized mask is given (`--mask`): it would not fit a window.
    pub mask: bool,
    /// The sea level asked for (`--sea-level`), else detected.
    pub sea_level: Option<f32>,
    /// The DEM's name, for messages.
    pub input: &'a str,
}

/// When the DEM's cells are coarser than a surface feature asked for needs
/// ([`relief_implicit_volume::recipe::FeatureSizes::needed_cell_for`]) and `--raw-dem` is not given, replaces `hf` by a window
/// of it refined to that cell (issue 42: features at their physical size on amplified terrain,
/// never kilometre-wide caves on coarse cells): the window is centred (on the shore nearest
/// the highest shore for shore features, [`window_centre`]), as wide as 512 of the
/// features' voxels ([`relief_implicit_volume::recipe::FeatureSizes::voxel_for`]) or the whole DEM when smaller, analysed
/// with a margin of [`MARGIN`] cells and refined by `L` wavelet levels (`2^L` finer, the
/// smallest `L` that reaches the cell). Returns the note saying what was done (printed and put
/// in the report), none when `hf` is kept.
pub fn amplify_window(
    hf: &mut relief_heightfield::Heightfield,
    job: &mut VolumeJob,
    args: &WindowOptions<'_>,
) -> Result<Option<String>> {
    let r = &job.recipe;
    let sizes = r.sizes.scaled(r.scale);
    let Some(need) = sizes.needed_cell_for(&r.features) else {
        return Ok(None);
    };
    let (cx, cy) = hf.cell_size();
    let cell = cx.max(cy);
    if args.raw_dem || cell <= f64::from(need) * 1.001 {
        return Ok(None);
    }
    if args.mask {
        bail!(
            "--mask: the DEM's {cell:.1} m cells are coarser than the {need:.1} m the features \
             need, so the scene is built on a refined window of it, which a DEM-sized mask \
             does not fit; give --raw-dem (features that need finer cells are then refused) or \
             crop and refine the DEM and its mask first (relief refine)"
        );
    }
    let levels = (cell / f64::from(need)).log2().ceil().max(1.0) as u32;
    if levels > 8 {
        bail!(
            "{}: {cell:.1} m cells are over 256 times coarser than the {need:.1} m the features \
             ask for; use a finer DEM, fewer features (--features), a larger --feature-scale, or \
             --raw-dem",
            args.input
        );
    }
    let side = sizes
        .voxel_for(&r.features)
        .map_or(f64::INFINITY, |v| 512.0 * f64::from(v));
    let (w, h) = (hf.width(), hf.height());
    let k = 1usize << levels;
    // Fine nodes wanted along each axis (`side` metres, at most the whole DEM refined).
    let want = |n: usize, c: f64| {
        ((side * k as f64 / c).ceil() as usize + 1).clamp(17.min((n - 1) * k + 1), (n - 1) * k + 1)
    };
    let (nx, ny) = (want(w, cx), want(h, cy));
    // A window centred this many source nodes from the border is not clamped by it.
    let room = |n: usize, c: f64| (side / (2.0 * c)).ceil().min(n as f64) as usize;
    let (jf, if_, sea) = window_centre(hf, r, args.sea_level, (room(w, cx), room(h, cy)));
    let (jc, ic) = (jf.round() as usize, if_.round() as usize);
    // The source nodes under the window, two more each side and a margin for the analysis.
    let span = |c: usize, n: usize, nf: usize| {
        let half = nf / (2 * k) + 2 + MARGIN;
        (c.saturating_sub(half), (c + half + 1).min(n))
    };
    let ((sx0, sx1), (sy0, sy1)) = (span(jc, w, nx), span(ic, h, ny));
    let src = hf
        .crop(sx0, sy0, sx1 - sx0, sy1 - sy0)
        .context("cannot take the window to amplify")?;
    let settings = relief_wavelet_lod::RefineSettings {
        extra_levels: levels,
        seed: r.seed,
        ..Default::default()
    };
    let refiner = relief_wavelet_lod::Refiner::new(&src, &settings)
        .context("cannot analyse the window to amplify")?;
    let (ow, oh) = refiner.output_size();
    // The window of the refined grid centred on the chosen node, inside the grid.
    let start = |c: f64, s0: usize, nf: usize, o: usize| {
        (((c - s0 as f64) * k as f64).round().max(0.0) as usize)
            .saturating_sub(nf / 2)
            .min(o.saturating_sub(nf))
    };
    let (nx, ny) = (nx.min(ow), ny.min(oh));
    let (fx0, fy0) = (start(jf, sx0, nx, ow), start(if_, sy0, ny, oh));
    let out = refiner
        .render_window(fx0, fy0, nx, ny)
        .context("cannot refine the window")?;
    let (fx, fy) = out.cell_size();
    let note = format!(
        "volume: built on a {:.0} x {:.0} m window around column {jf:.1}, row {if_:.1} of the DEM \
         refined {k}x (wavelet, {levels} levels) from {cell:.1} m to {:.1} m cells: the \
         features need cells of at most {need:.1} m and their voxel affords {:.0} m a side \
         (--crop picks another window, --raw-dem keeps the DEM)",
        (nx - 1) as f64 * fx,
        (ny - 1) as f64 * fy,
        fx.max(fy),
        side.min(f64::from(u32::MAX)),
    );
    // The refined sea is no longer flat (the synthesis adds detail everywhere), so the DEM's
    // own sea level is passed on rather than detected again in the window.
    if let (None, Some(level)) = (job.recipe.sea_level, sea) {
        job.recipe.sea_level = Some(level);
    }
    *hf = out;
    Ok(Some(note))
}

/// The node an amplified window is centred on: with shore features and a sea (`--sea-level`,
/// else the DEM's own, [`relief_implicit_volume::detect_sea`]), the highest shore node (above
/// the level, next to one at or below it; its height the highest ground within
/// [`SHORE_REACH_M`], on cells no coarser than that), the nearest the DEM's centre among
/// equals, moved along the edge to where the coast crosses it; shore nodes at least `room`
/// nodes (half the window) from the border, where the window is not cut by it, come first;
/// else the centre (fractional node coordinates). Also returns
/// the DEM's own sea level when it was detected.
fn window_centre(
    hf: &relief_heightfield::Heightfield,
    r: &relief_implicit_volume::Recipe,
    sea_level: Option<f32>,
    room: (usize, usize),
) -> (f64, f64, Option<f32>) {
    let (w, h) = (hf.width(), hf.height());
    let centre = ((w / 2) as f64, (h / 2) as f64, None);
    let shore = [Feature::Sea, Feature::Caves, Feature::Cliffs];
    if !r.features.iter().any(|f| shore.contains(f)) {
        return centre;
    }
    let detected = match sea_level {
        Some(_) => None,
        None => relief_implicit_volume::detect_sea(hf).map(|s| s.level),
    };
    let Some(level) = sea_level.or(detected) else {
        return centre;
    };
    let z = |j: usize, i: usize| f64::from(hf.get(j, i));
    let level = f64::from(level);
    // The highest ground within `SHORE_REACH_M` of a node: a shore's height.
    let (cx, cy) = hf.cell_size();
    let (rj, ri) = (
        (SHORE_REACH_M / cx).round().max(1.0) as usize,
        (SHORE_REACH_M / cy).round().max(1.0) as usize,
    );
    // On cells coarser than the reach a node's neighbours say nothing of the shore's height
    // there (and the refined coast line may move by more than the window): nearest only.
    let ranked = cx.max(cy) <= SHORE_REACH_M;
    let height = |j: usize, i: usize| {
        if !ranked {
            return 0.0;
        }
        let mut m = f64::NEG_INFINITY;
        for ii in i.saturating_sub(ri)..(i + ri + 1).min(h) {
            for jj in j.saturating_sub(rj)..(j + rj + 1).min(w) {
                m = m.max(z(jj, ii));
            }
        }
        m
    };
    // Where the coast crosses each edge from a dry node to a wet one (linear interpolation),
    // the highest shore first, then the nearest the centre.
    let inside =
        |j: usize, i: usize| j >= room.0 && j + room.0 < w && i >= room.1 && i + room.1 < h;
    let mut best: Option<(bool, f64, f64, (f64, f64))> = None;
    for i in 0..h {
        for j in 0..w {
            let a = z(j, i);
            if a <= level {
                continue;
            }
            let mut shore: Option<f64> = None;
            for (dj, di) in [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)] {
                let (jn, in_) = (j as i64 + dj, i as i64 + di);
                if jn < 0 || in_ < 0 || jn >= w as i64 || in_ >= h as i64 {
                    continue;
                }
                let b = z(jn as usize, in_ as usize);
                if b > level {
                    continue;
                }
                let t = (a - level) / (a - b);
                let p = (j as f64 + t * dj as f64, i as f64 + t * di as f64);
                let d = (p.0 - centre.0).powi(2) + (p.1 - centre.1).powi(2);
                let hs = *shore.get_or_insert_with(|| height(j, i));
                let free = inside(j, i);
                let better = |(bf, bh, bd, _): (bool, f64, f64, (f64, f64))| {
                    (free && !bf) || (free == bf && (hs > bh || (hs == bh && d < bd)))
                };
                if best.is_none_or(better) {
                    best = Some((free, hs, d, p));
                }
            }
        }
    }
    best.map_or(centre, |(_, _, _, (j, i))| (j, i, detected))
}

/// How far inland (m) a shore's height is taken when the window is put on the coast: sea
/// cliffs, caves and notches need a shore that rises within a few hundred metres.
const SHORE_REACH_M: f64 = 250.0;

/// Source cells around an amplified window that the wavelet analysis also sees.
const MARGIN: usize = 8;

#[cfg(test)]
mod tests {
    use super::*;

    /// Sea west of column 20; the land is 5 m high except a 80 m headland in rows 0-7, far
    /// from the centre (row 20): the window goes to the headland's shore (a crossing within
    /// 250 m of it, the nearest the centre), not to the low shore next to the centre; on
    /// cells coarser than 250 m to the shore nearest the centre; shores where the window
    /// would be cut by the border come last; without shore features it stays at the centre.
    #[test]
    fn the_window_goes_to_the_highest_shore() {
        let hf = relief_heightfield::Heightfield::from_fn(60, 40, 90.0, 90.0, |x, y| {
            match (x < 20, y < 8) {
                (true, _) => -10.0,
                (false, true) => 80.0,
                (false, false) => 5.0,
            }
        });
        let mut r = relief_implicit_volume::Recipe {
            features: vec![Feature::Sea, Feature::Caves],
            ..Default::default()
        };
        let (j, i, _) = window_centre(&hf, &r, Some(0.0), (2, 2));
        assert!((19.0..20.0).contains(&j), "on the coast: column {j}");
        assert!(
            (7.0..=10.0).contains(&i),
            "at the headland, nearest the centre: row {i}"
        );
        // A window half 12 rows tall would be cut by the northern border there: the free
        // shores come first, all low, so the one nearest the centre.
        let (j, i, _) = window_centre(&hf, &r, Some(0.0), (2, 12));
        assert!((19.0..20.0).contains(&j) && i == 20.0, "({j}, {i})");
        // On 2 km cells the shore's height is unknown: the coast nearest the centre.
        let mut coarse = hf.clone();
        coarse.set_cell_size(2000.0, 2000.0).unwrap();
        let (j, i, _) = window_centre(&coarse, &r, Some(0.0), (2, 2));
        assert!((19.0..20.0).contains(&j) && i == 20.0, "({j}, {i})");
        r.features = vec![Feature::Karst];
        assert_eq!(
            window_centre(&hf, &r, Some(0.0), (2, 2)),
            (30.0, 20.0, None)
        );
    }
}
