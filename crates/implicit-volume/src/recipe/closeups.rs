//! Cameras on what a recipe built: the densest karst, the section line and the close-up
//! renders of its highlights.

use super::*;

/// Where to cut the karst away for its close-up: the centre of the karst passage sphere
/// whose vertical cut plane (normal `cut`, horizontal) shows the most separate holes under
/// the ground within the close-up's frame (9 of the spheres' radii each way along the plane,
/// 5 up and down: 25 radii away at 40 degrees), ties broken by the most spheres crossed. A
/// hole is a group of crossed spheres whose sections on the plane overlap; counting spheres
/// alone chose the densest knot of the maze, which the cut showed as one chamber.
pub(super) fn densest_karst(b: &SceneBuilder, cut: [f32; 3]) -> Option<[f32; 3]> {
    let n = crate::math::normalize([cut[0], cut[1], 0.0]);
    // Passage spheres wholly under the ground (a mouth at the surface is not a cut hole).
    let karst: Vec<([f32; 3], f32)> = b
        .carvings()
        .iter()
        .filter(|c| c.2 && c.0[2] + crate::math::VISIBLE * c.1 < b.ground(c.0[0], c.0[1]))
        .map(|c| (c.0, crate::math::VISIBLE * c.1))
        .collect();
    // At most 4096 candidates (a stride over the list) against every sphere.
    let stride = karst.len().div_ceil(4096).max(1);
    let side = [-n[1], n[0], 0.0];
    let mut best: Option<((usize, usize), [f32; 3])> = None;
    for (c, r) in karst.iter().step_by(stride) {
        // The sections on the plane: (along, up, radius).
        let discs: Vec<(f32, f32, f32)> = karst
            .iter()
            .filter_map(|(q, rq)| {
                let d = crate::math::sub(*q, *c);
                let off = crate::math::dot(d, n);
                let along = crate::math::dot(d, side);
                (off.abs() < *rq && along.abs() < 9.0 * r && d[2].abs() < 5.0 * r)
                    .then(|| (along, d[2], (rq * rq - off * off).sqrt()))
            })
            .collect();
        let score = (holes(&discs), discs.len());
        if best.is_none_or(|b| score > b.0) {
            best = Some((score, *c));
        }
    }
    best.map(|b| b.1)
}

/// Groups of overlapping discs `(x, y, radius)` (connected components).
fn holes(discs: &[(f32, f32, f32)]) -> usize {
    let mut parent: Vec<usize> = (0..discs.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..discs.len() {
        for j in i + 1..discs.len() {
            let (a, b) = (discs[i], discs[j]);
            if (a.0 - b.0).hypot(a.1 - b.1) < a.2 + b.2 {
                let (ra, rb) = (root(&mut parent, i), root(&mut parent, j));
                parent[ra] = rb;
            }
        }
    }
    (0..discs.len())
        .filter(|&i| root(&mut parent, i) == i)
        .count()
}

/// The west-east line through the DEM row holding the most karst spheres; without karst,
/// through the first sea cave two radii `cave_radius` inside its mouth (the section then cuts
/// the cave under its roof); else through the row of the most carving spheres.
pub(super) fn best_section_line(
    b: &SceneBuilder,
    effects: &[(Feature, EffectReport)],
    cave_radius: f32,
) -> ([f32; 2], [f32; 2]) {
    let f = b.frame();
    let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
    let cave = effects
        .iter()
        .filter(|(k, _)| matches!(k, Feature::Sea | Feature::Caves))
        .find_map(|(_, e)| Some((*e.sites.first()?, *e.axes.first()?)));
    if let Some((mouth, out)) = cave
        && !b.carvings().iter().any(|c| c.2)
    {
        let y = (mouth[1] - 2.0 * cave_radius * out[1]).clamp(0.0, ym);
        return ([0.0, y], [xm, y]);
    }
    let mut counts = vec![0usize; f.height];
    // Karst passages when there are any (weathering pits would win the count otherwise).
    let any_karst = b.carvings().iter().any(|c| c.2);
    for (c, _, karst) in b.carvings() {
        if any_karst && !karst {
            continue;
        }
        let i = ((c[1] / f.cy).round().max(0.0) as usize).min(f.height - 1);
        counts[i] += 1;
    }
    let best = counts
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0)))
        .filter(|x| *x.1 > 0)
        .map_or(0.5 * ym, |(i, _)| i as f32 * f.cy);
    ([0.0, best], [xm, best])
}

/// Close-up renders of the landforms a recipe placed (one per highlight: one per placed kind,
/// each framed by the size of its kind), on a grid four wide in one image (row-major in the
/// order of the names returned), with their feature names; a second row with room to spare
/// ends with an `overview` of the whole scene; a
/// closer oblique view of the middle of the scene when nothing was placed. `tile` is the size
/// and shading of one close-up.
pub fn render_closeups(
    scene: &Scene,
    rep: &RecipeReport,
    tile: &RenderSettings,
) -> Result<(Image, Vec<String>)> {
    let mut tiles = Vec::new();
    let mut names = Vec::new();
    for (cam, s, name) in closeup_views(scene, rep, tile) {
        tiles.push(render(scene, &cam, &s)?);
        names.push(name);
    }
    // A last row with room to spare ends with the whole scene, where the close-ups are taken,
    // rather than an empty black cell.
    if tiles.len() > PER_ROW && tiles.len() % PER_ROW != 0 {
        tiles.push(render(scene, &Camera::landscape(scene), tile)?);
        names.push("overview".into());
    }
    Ok((strip(&tiles), names))
}

/// The views of [`render_closeups`]: for each close-up, its camera, its render settings
/// (`tile` with the cut-away plane of an underground view) and its feature name.
pub fn closeup_views(
    scene: &Scene,
    rep: &RecipeReport,
    tile: &RenderSettings,
) -> Vec<(Camera, RenderSettings, String)> {
    let d = &rep.dims;
    let mut views = Vec::new();
    for h in &rep.highlights {
        let own = |nominal: f32| h.size_m.unwrap_or(nominal);
        // The sea's highlight is a cave mouth when it reports the cave's radius.
        let cave = h
            .size_m
            .filter(|_| matches!(h.feature, Feature::Sea | Feature::Caves));
        let size = match h.feature {
            // A cluster, seen whole (the highlighted member may be a short spire).
            Feature::Hoodoos => own(d.hoodoo_height_m).max(d.hoodoo_height_m) * 4.0,
            Feature::Arches => own(d.arch_span_m) * 3.0,
            Feature::Islands => own(d.island_radius_m) * 7.0,
            Feature::Karst => d.karst_radius_m * 25.0,
            Feature::Overhangs => d.weathering_radius_m * 10.0,
            // A sea cave's mouth (its radius reported) at its own scale, a few mouths across
            // the frame; else the notched cliff.
            _ if let Some(r) = cave => r * 12.0,
            _ => d.sea_height_m * 6.0,
        };
        let dist = size.max(4.0 * d.voxel_m);
        if h.cutaway {
            // Eye in the removed rock, looking at the cut face through `at`.
            let v = h.from.unwrap_or([-0.55, -0.7, 0.35]);
            let dir = crate::math::normalize(v);
            let cam = Camera {
                eye: crate::math::add(h.at, crate::math::mul(dir, dist)),
                target: h.at,
                up: [0.0, 0.0, 1.0],
                fov_deg: 40.0,
            };
            let s = RenderSettings {
                cutaway: Some((h.at, crate::math::normalize([v[0], v[1], 0.0]))),
                sea_level: None,
                ..*tile
            };
            views.push((cam, s, format!("{} (cut-away)", h.feature)));
            continue;
        }
        // Hoodoos are placed by their foot: aim at 0.6 of the height (the eye looks down).
        let at = match h.feature {
            Feature::Hoodoos => [h.at[0], h.at[1], h.at[2] + 0.6 * own(d.hoodoo_height_m)],
            // Islands are placed by their top: aim below it, at the underside.
            Feature::Islands => [h.at[0], h.at[1], h.at[2] - 0.6 * d.island_radius_m],
            // A sea cave's mouth is at the waterline: aim over it, at the cliff it opens in,
            // so the sea takes the lower third of the frame, not half.
            _ if let Some(r) = cave => [h.at[0], h.at[1], h.at[2] + 1.5 * r],
            _ => h.at,
        };
        // An arch is seen through its gap from either side: the sunlit one. An undercut face
        // is seen obliquely (50 degrees off its normal), so its ledges stand out against
        // the hollows under them.
        let from = match (h.feature, h.from) {
            // A hoodoo cluster from down its slope and to the sunlit side (45 degrees off the
            // fall line), so the ground falls away from the eye and the columns are lit.
            (Feature::Hoodoos, Some(v)) => {
                let mut c = [-v[1], v[0]];
                if c[0] * tile.light[0] + c[1] * tile.light[1] < 0.0 {
                    c = [v[1], -v[0]];
                }
                Some([v[0] + c[0], v[1] + c[1], 0.0])
            }
            (Feature::Arches, Some(v)) if v[0] * tile.light[0] + v[1] * tile.light[1] < 0.0 => {
                Some([-v[0], -v[1], v[2]])
            }
            (Feature::Overhangs, Some(v)) => {
                let (c, s) = (50f32.to_radians().cos(), 50f32.to_radians().sin());
                Some([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])
            }
            (_, v) => v,
        };
        let cam = match from {
            // A hoodoo cluster from about 31 degrees above the line of sight to it, so the
            // eye sees down into the hollow the columns stand in.
            Some(v) if h.feature == Feature::Hoodoos => {
                Camera::closeup_from(scene, at, dist, [v[0], v[1], 0.85])
            }
            Some(v) => Camera::closeup_from(scene, at, dist, [v[0], v[1], 0.08]),
            None => Camera::closeup(scene, at, dist),
        };
        let name = match cave {
            Some(_) => "sea cave".to_string(),
            None => h.feature.to_string(),
        };
        views.push((cam, *tile, name));
    }
    if views.is_empty() {
        let b = scene.bbox();
        let c = b.center();
        let z = scene.dem_height(c[0], c[1]).unwrap_or(c[2]);
        let dist = 0.3 * b.size()[0].max(b.size()[1]);
        views.push((
            Camera::closeup(scene, [c[0], c[1], z], dist),
            *tile,
            "centre".into(),
        ));
    }
    views
}

/// Close-ups per row of the image [`render_closeups`] returns.
const PER_ROW: usize = 4;

/// Images on a grid of [`PER_ROW`] columns (rows of tiles top-aligned in cells of the largest
/// tile's size, black around smaller ones).
fn strip(tiles: &[Image]) -> Image {
    let th = tiles.iter().map(|t| t.height).max().unwrap_or(1);
    let tw = tiles.iter().map(|t| t.width).max().unwrap_or(1);
    let cols = tiles.len().clamp(1, PER_ROW);
    let rows = tiles.len().div_ceil(PER_ROW).max(1);
    let (w, h) = (cols * tw, rows * th);
    let mut rgb = vec![0u8; w * h * 3];
    for (k, t) in tiles.iter().enumerate() {
        let (x0, y0) = ((k % PER_ROW) * tw, (k / PER_ROW) * th);
        for y in 0..t.height {
            let src = &t.rgb[y * t.width * 3..(y + 1) * t.width * 3];
            let at = ((y0 + y) * w + x0) * 3;
            rgb[at..at + t.width * 3].copy_from_slice(src);
        }
    }
    Image {
        width: w,
        height: h,
        rgb,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every close-up is kept (the fifth starts a second row of four); each tile sits in
    /// its grid cell, black fills the rest.
    #[test]
    fn close_ups_go_on_a_grid_four_wide() {
        let tile = |v: u8| Image {
            width: 3,
            height: 2,
            rgb: vec![v; 3 * 2 * 3],
        };
        let tiles: Vec<Image> = (1..=5).map(|k| tile(10 * k)).collect();
        let img = strip(&tiles);
        assert_eq!((img.width, img.height), (12, 4));
        let at = |x: usize, y: usize| img.rgb[(y * img.width + x) * 3];
        assert_eq!([at(0, 0), at(3, 1), at(9, 0), at(2, 3)], [10, 20, 40, 50]);
        assert_eq!(at(4, 3), 0, "no sixth tile");
        let one = strip(&tiles[..1]);
        assert_eq!((one.width, one.height), (3, 2));
    }

    #[test]
    fn holes_count_groups_of_overlapping_sections() {
        // Two overlapping discs, one apart, and a chain of three touching end to end.
        let discs = [0.0, 1.5, 10.0, 20.0, 21.9, 23.8].map(|x| (x, 0.0, 1.0));
        assert_eq!(holes(&discs), 3);
        assert_eq!(holes(&discs[..3]), 2);
        assert_eq!(holes(&[]), 0);
    }
}
