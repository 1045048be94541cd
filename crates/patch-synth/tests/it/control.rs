//! Control structures and unguided synthesis on real DEM crops: guides from a DEM and from a
//! sketch, exemplar categories by clustering (per exemplar and per region of one exemplar), the
//! categorisation map from guide heights, the compatibility check and greedy exemplar
//! selection (reported, and applied by `auto_subset`), and the public patch search (PCA +
//! kd-tree, section 3.5).

use relief_heightfield::metrics::{rmse, stats};
use relief_heightfield::{Heightfield, NoProgress};
use relief_patch_synth::guide::{
    GuideRange, Seed, Stroke, fit_range, fit_to_size, gaussian_blur, guide_from_sketch,
    lowpass_resample, map_range, to_cell_size,
};
use relief_patch_synth::quality::seam_visibility;
use relief_patch_synth::{
    CategoryMap, Control, Exemplar, ExemplarIndex, GuideSetup, JobInputs, OverlapShape,
    PatchSynthError, QuiltJob, Settings, ValidateJob, categorize_exemplars, categorize_regions,
    synthesize, validate,
};
use relief_testdata::{Crop, dem_crop, dem_crops, dem_windows};

/// The low, flat coast of N57E011 (it matches no alpine guide).
const COAST: Crop<'static> = ("N57E011", 900, 100, 160, 160);
/// An alpine exemplar, and the source of an alpine guide from another part of the alps.
const ALPS: Crop<'static> = ("alps_dem", 450, 250, 256, 256);
const ALPS_GUIDE: Crop<'static> = ("alps_dem", 2150, 300, 128, 128);
/// Jacksboro fault's 74.57 x 92.48 m cells (a guide for 61.70 m Grand Canyon exemplars).
const JACKSBORO: Crop<'static> = ("jacksboro_fault", 100, 80, 100, 80);

/// 32-cell patches, 8-cell overlaps, 8 clusters, PCA on 1500 samples (the patch search).
fn search_settings() -> Settings {
    Settings {
        patch_size: 32,
        overlap: 8,
        kmeans_clusters: 8,
        pca_samples: 1500,
        ..Default::default()
    }
}

/// The search settings at every second patch position, with 150 candidates (synthesis).
fn small() -> Settings {
    Settings {
        exemplar_stride: 2,
        min_candidates: 150,
        ..search_settings()
    }
}

/// The index of `exemplars`, all in category 0.
fn index_of(exemplars: impl IntoIterator<Item = Heightfield>, s: &Settings) -> ExemplarIndex {
    let exemplars = exemplars.into_iter().map(|e| Exemplar::new(e, 0)).collect();
    ExemplarIndex::build(exemplars, s, &NoProgress).unwrap()
}

#[test]
fn lowpass_guides_keep_the_coarse_shape_and_drop_detail() {
    let Some(dem) = dem_crop("jacksboro_fault", 100, 100, 128, 128) else {
        return;
    };
    let a = lowpass_resample(&dem, 8).unwrap();
    let b = gaussian_blur(&dem, 4.0).unwrap();
    let s = stats(&dem).unwrap().std;
    for g in [&a, &b] {
        assert_eq!((g.width(), g.height()), (128, 128));
        let e = rmse(g, &dem).unwrap();
        // The low-pass stays close to the DEM but removes its detail (smaller slopes).
        assert!(e < 0.5 * s && e > 1.0, "rmse {e} std {s}");
        let (gs, ds) = (
            relief_heightfield::terrain::slope_degrees(g)
                .mean()
                .unwrap(),
            relief_heightfield::terrain::slope_degrees(&dem)
                .mean()
                .unwrap(),
        );
        assert!(gs < 0.7 * ds, "guide slope {gs} vs dem {ds}");
    }
    assert!(
        lowpass_resample(&dem, 0)
            .unwrap_err()
            .to_string()
            .contains("`factor` = 0")
    );
    assert!(
        gaussian_blur(&dem, -1.0)
            .unwrap_err()
            .to_string()
            .contains("`sigma` = -1")
    );
}

#[test]
fn smoothness_scale_follows_the_blur_of_a_guide() {
    let Some(dem) = dem_crop("jacksboro_fault", 0, 0, 256, 256) else {
        return;
    };
    let scales: Vec<f32> = [4.0, 8.0, 16.0]
        .iter()
        .map(|&sigma| {
            relief_patch_synth::guide::smoothness_scale(&gaussian_blur(&dem, sigma).unwrap())
        })
        .collect();
    // About 1.1 sigma for a blurred DEM (the automatic `guide_lowpass`).
    for (sigma, l) in [4.0f32, 8.0, 16.0].iter().zip(&scales) {
        assert!(
            (0.8 * sigma..1.6 * sigma).contains(l),
            "sigma {sigma}: scale {l} ({scales:?})"
        );
    }
    assert!(scales[0] < scales[1] && scales[1] < scales[2], "{scales:?}");
    // A plane has no curvature: no detail at any scale.
    let plane = dem
        .with_data((0..256 * 256).map(|i| (i % 256) as f32).collect())
        .unwrap();
    assert_eq!(
        relief_patch_synth::guide::smoothness_scale(&plane),
        f32::INFINITY
    );
}

#[test]
fn sketch_guide_interpolates_seeds_and_strokes() {
    let seeds = [
        Seed {
            x: 10.0,
            y: 10.0,
            height: 500.0,
            radius: 2.0,
        },
        Seed {
            x: 100.0,
            y: 90.0,
            height: 1500.0,
            radius: 3.0,
        },
    ];
    let ridge = Stroke {
        points: vec![(20.0, 100.0, 800.0), (110.0, 20.0, 1200.0)],
    };
    let g = guide_from_sketch(128, 128, (30.0, 30.0), &seeds, &[ridge], 0.0).unwrap();
    assert_eq!(g.get(10, 10), 500.0);
    assert_eq!(g.get(100, 90), 1500.0);
    // Midpoint of the stroke carries the interpolated stroke height.
    assert!((g.get(65, 60) - 1000.0).abs() < 15.0, "{}", g.get(65, 60));
    let (lo, hi) = g.min_max().unwrap();
    assert!(
        lo >= 499.0 && hi <= 1501.0,
        "harmonic interpolation stays within the seeds"
    );
    assert!(guide_from_sketch(8, 8, (1.0, 1.0), &[], &[], 0.0).is_err());
}

#[test]
fn exemplar_categories_by_clustering_separate_low_and_high_terrain() {
    let Some([coast, canyon, alps]) = dem_crops([
        COAST,
        ("grandcanyon", 0, 0, 160, 160),
        ("alps_dem", 1200, 250, 160, 160),
    ]) else {
        return;
    };
    let cats = categorize_exemplars(&[coast, canyon, alps], 3, &small()).unwrap();
    // Classes are ordered by height: the low coast first, the alps last.
    assert!(cats[0] < cats[1] && cats[1] <= cats[2], "{cats:?}");
    assert!(cats[0] != cats[2]);
}

#[test]
fn category_map_from_guide_heights_is_ordered() {
    let Some(dem) = dem_crop("alps_dem", 2100, 250, 128, 128) else {
        return;
    };
    let g = lowpass_resample(&dem, 8).unwrap();
    let (map, centres) = CategoryMap::from_guide_heights(&g, 3, 1).unwrap();
    assert_eq!(centres.len(), 3);
    assert!(centres[0] < centres[1] && centres[1] < centres[2]);
    for (i, &id) in map.ids.iter().enumerate() {
        let v = g.as_slice()[i];
        let nearest = (0..3)
            .min_by(|&a, &b| (v - centres[a]).abs().total_cmp(&(v - centres[b]).abs()))
            .unwrap();
        assert_eq!(id as usize, nearest);
    }
}

#[test]
fn unguided_synthesis_with_compatibility_check_and_exemplar_cover() {
    let Some([a, b]) = dem_windows("jacksboro_fault", [(0, 0, 192, 192), (200, 140, 192, 192)])
    else {
        return;
    };
    let s = small();
    let index = index_of([a, b], &s);
    let control = Control::unguided(128, 96);
    let report = validate(&index, &control, &s).unwrap();
    assert_eq!(report.compatibility.len(), 2);
    assert!(report.ok, "two parts of one DEM are compatible: {report}");
    let out = synthesize(&index, &control, &s, &NoProgress).unwrap();
    assert_eq!(
        (out.heightfield.width(), out.heightfield.height()),
        (128, 96)
    );
    let r = seam_visibility(&out.heightfield, &out.seam_map).unwrap();
    assert!((0.75..1.3).contains(&r), "seam ratio {r}");
    // Both exemplars are used somewhere.
    let used: std::collections::BTreeSet<u32> =
        out.placements.iter().map(|p| p.patch.exemplar).collect();
    assert!(!used.is_empty());
}

#[test]
fn greedy_cover_picks_the_exemplar_that_matches_the_guide() {
    let Some([coast, alps, src]) = dem_crops([COAST, ALPS, ALPS_GUIDE]) else {
        return;
    };
    let g = lowpass_resample(&src, 8).unwrap();
    let s = Settings {
        lambda: 60.0,
        ..small()
    };
    let index = index_of([coast, alps], &s);
    let report = validate(&index, &Control::guided(g), &s).unwrap();
    assert_eq!(
        report.cover.first(),
        Some(&1),
        "the alps exemplar covers the alpine guide"
    );
    assert!(
        !report.cover.contains(&0),
        "the flat coast adds nothing: {:?}",
        report.cover
    );
}

#[derive(Default)]
struct Counting {
    phases: std::sync::Mutex<Vec<(String, u64)>>,
    done: std::sync::atomic::AtomicU64,
}

impl relief_heightfield::Progress for Counting {
    fn begin(&self, phase: &str, total: u64) {
        self.phases.lock().unwrap().push((phase.to_string(), total));
    }
    fn advance(&self, n: u64) {
        self.done.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    }
}

#[test]
fn quilt_reports_progress_for_every_phase() {
    let Some([a, src]) = dem_windows("grandcanyon", [(100, 100, 160, 160), (300, 300, 80, 80)])
    else {
        return;
    };
    let g = gaussian_blur(&src, 4.0).unwrap();
    let s = Settings {
        enforce_validation: false,
        ..small()
    };
    let p = Counting::default();
    let out =
        relief_patch_synth::quilt(vec![Exemplar::new(a, 0)], &Control::guided(g), &s, &p).unwrap();
    let phases = p.phases.lock().unwrap().clone();
    let names: Vec<&str> = phases.iter().map(|(n, _)| n.as_str()).collect();
    assert!(
        names.iter().any(|n| n.contains("k-means")) && names.iter().any(|n| n.contains("kd-trees"))
    );
    let (_, total) = phases
        .iter()
        .find(|(n, _)| n.contains("synthesis"))
        .unwrap();
    assert_eq!(*total as usize, out.placements.len());
    let expected: u64 = phases.iter().map(|(_, t)| t).sum();
    assert_eq!(p.done.load(std::sync::atomic::Ordering::Relaxed), expected);
}

/// Issue 17: a guide keeps its physical scale (resampled to the exemplars' cells over its own
/// extent, then cropped or mirror-padded without resampling) and its heights are mapped onto
/// the exemplars' (`LO,HI` exactly; `auto` checked by the validation).
#[test]
fn guide_keeps_its_scale_and_is_mapped_onto_the_exemplar_heights() {
    let Some([src, ex]) = dem_crops([JACKSBORO, ("grandcanyon", 150, 150, 160, 160)]) else {
        return;
    };
    // 74.57 x 92.48 m cells onto 61.70 m: the same ground in more cells.
    let cell = ex.cell_size();
    let g = to_cell_size(&src, cell).unwrap();
    assert_eq!(g.cell_size(), cell);
    let (sx, sy) = src.cell_size();
    assert_eq!(
        (g.width(), g.height()),
        (
            (100.0 * sx / cell.0).round() as usize,
            (80.0 * sy / cell.1).round() as usize
        )
    );
    assert!(to_cell_size(&src, (0.0, 1.0)).is_err());

    // Crop: the centred window, values unchanged.
    let (c, fit) = fit_to_size(&g, 64, 50).unwrap();
    assert_eq!(fit.cropped, (g.width() - 64, g.height() - 50));
    assert_eq!(fit.padded, (0, 0));
    let (ox, oy) = (g.width() / 2 - 32, g.height() / 2 - 25);
    for (x, y) in [(0, 0), (63, 49), (20, 31)] {
        assert_eq!(c.get(x, y), g.get(ox + x, oy + y));
    }
    // Pad: the guide in the middle, mirrored (not clamped) beyond its edges.
    let (w, h) = (g.width() + 20, g.height() + 10);
    let (pd, fit) = fit_to_size(&g, w, h).unwrap();
    assert_eq!(fit.padded, (20, 10));
    assert_eq!(pd.get(10, 5), g.get(0, 0));
    assert_eq!(pd.get(9, 5), g.get(1, 0));
    assert_eq!(pd.get(8, 5), g.get(2, 0));
    assert!(fit_to_size(&g, 0, 4).is_err());

    let s = small();
    let index = index_of([ex.clone()], &s);
    let (guide, _) = fit_to_size(&gaussian_blur(&g, 4.0).unwrap(), 96, 96).unwrap();
    // LO,HI: the extremes of the patch-window means land on LO and HI.
    let (m, map) = map_range(&guide, &index, GuideRange::Metres(1000.0, 1500.0)).unwrap();
    assert_eq!(map.to, (1000.0, 1500.0));
    let k = 500.0 / (map.from.1 - map.from.0);
    for (x, y) in [(0, 0), (50, 70)] {
        let want = 1000.0 + (guide.get(x, y) - map.from.0) * k;
        assert!(
            (m.get(x, y) - want).abs() < 0.01,
            "{} vs {want}",
            m.get(x, y)
        );
    }
    assert!(map_range(&guide, &index, GuideRange::Metres(5.0, 1.0)).is_err());
    // auto: inside the exemplar's heights, and the validation passes where the raw guide
    // (jacksboro's 300-700 m against the canyon's 1000-2000 m) fails.
    let control = Control::guided(guide.clone());
    let raw = validate(&index, &control, &s).unwrap();
    let (a, amap, report) = fit_range(&guide, &index, &control, &s).unwrap();
    let (elo, ehi) = ex.min_max().unwrap();
    assert!(amap.to.0 >= elo && amap.to.1 <= ehi, "{amap:?}");
    let (d, _) = map_range(&guide, &index, GuideRange::Auto).unwrap();
    let default = validate(&index, &Control::guided(d), &s).unwrap();
    assert!(
        report.failing.len() < raw.failing.len() && report.failing.len() <= default.failing.len(),
        "{} failing blocks (raw guide {}, 2-98 % mapping {})",
        report.failing.len(),
        raw.failing.len(),
        default.failing.len()
    );
    assert_eq!(validate(&index, &Control::guided(a), &s).unwrap(), report);
}

/// Section 4 clusters the patches, not the exemplars: one Grand Canyon crop gets two region
/// categories (the lower class lower on average), and a categorisation map that asks for
/// category 0 on the left and 1 on the right is obeyed by every block wholly inside a half.
#[test]
fn region_categories_split_one_exemplar_and_the_map_is_obeyed() {
    let Some(ex) = dem_crop("grandcanyon", 0, 0, 192, 192) else {
        return;
    };
    let s = small();
    let regions = categorize_regions(std::slice::from_ref(&ex), 2, &s).unwrap();
    let r = &regions[0];
    assert_eq!(r.len(), ex.len());
    let mean_of = |c: u16| {
        let v: Vec<f64> = (0..r.len())
            .filter(|&i| r[i] == c)
            .map(|i| ex.as_slice()[i] as f64)
            .collect();
        (v.len(), v.iter().sum::<f64>() / v.len().max(1) as f64)
    };
    let ((n0, m0), (n1, m1)) = (mean_of(0), mean_of(1));
    assert!(n0 > r.len() / 10 && n1 > r.len() / 10, "{n0} / {n1} cells");
    assert!(m0 < m1, "class 0 {m0:.0} m, class 1 {m1:.0} m");
    let p = s.patch_size;
    let index = ExemplarIndex::build(
        vec![Exemplar::new(ex.clone(), 0).with_regions(r.clone())],
        &s,
        &NoProgress,
    )
    .unwrap();
    assert_eq!(index.categories(), &[0, 1]);
    let (w, h) = (160, 96);
    let ids: Vec<u16> = (0..w * h).map(|i| u16::from(i % w >= w / 2)).collect();
    let control =
        Control::unguided(w, h).with_categories(CategoryMap::from_raster(w, h, ids).unwrap());
    let out = synthesize(&index, &control, &s, &NoProgress).unwrap();
    let cat = |pl: &relief_patch_synth::Placement| {
        let (x, y) = (pl.patch.x as usize + p / 2, pl.patch.y as usize + p / 2);
        r[y * ex.width() + x]
    };
    let (mut left, mut right) = (0, 0);
    for pl in &out.placements {
        if pl.x + p <= w / 2 {
            assert_eq!(cat(pl), 0, "block ({}, {}) on the left", pl.gx, pl.gy);
            left += 1;
        } else if pl.x >= w / 2 {
            assert_eq!(cat(pl), 1, "block ({}, {}) on the right", pl.gx, pl.gy);
            right += 1;
        }
    }
    assert!(
        left > 0 && right > 0,
        "{left} / {right} blocks inside a half"
    );
    // The output follows: its right half stands higher than its left.
    let o = &out.heightfield;
    let half = |x0: usize| {
        (0..h)
            .flat_map(|y| (x0..x0 + w / 2).map(move |x| (x, y)))
            .map(|(x, y)| o.get(x, y) as f64)
            .sum::<f64>()
            / (w / 2 * h) as f64
    };
    assert!(half(0) < half(w / 2), "{} vs {}", half(0), half(w / 2));
}

/// The job layer: `region_categories` clusters the patches of one exemplar and makes the map
/// from the guide's height classes; painted regions must fit their exemplar; `auto_subset`
/// drops a redundant exemplar once the validation passes, and the subset still validates.
#[test]
fn jobs_take_region_categories_painted_regions_and_apply_the_exemplar_subset() {
    let Some([a, b]) = dem_windows("grandcanyon", [(0, 0, 160, 160), (300, 300, 160, 160)]) else {
        return;
    };
    let s = Settings {
        enforce_validation: false,
        min_candidates: 40,
        ..small()
    };
    let guide = Heightfield::from_fn(128, 96, 61.7, 61.7, |x, y| {
        if x < 64 {
            a.get(x + 10, y + 20)
        } else {
            b.get(x - 64 + 10, y + 20)
        }
    });
    let mut job = QuiltJob(ValidateJob {
        settings: s.clone(),
        guide: GuideSetup {
            blur: Some(4.0),
            ..Default::default()
        },
        region_categories: Some(3),
        ..Default::default()
    });
    let inputs = JobInputs {
        exemplars: vec![a.clone()],
        guide: Some(guide.clone()),
        ..Default::default()
    };
    let out = job.run(inputs, &NoProgress).unwrap();
    let f = &out.figures.prepare;
    assert!(f.categories_clustered);
    assert_eq!(
        f.patches_per_category.len(),
        3,
        "{:?}",
        f.patches_per_category
    );
    assert!(
        out.categories.is_some(),
        "a map from the guide's height classes"
    );
    // Painted regions: a wrong size is refused by name, a good one gives its categories.
    job.region_categories = None;
    let bad = JobInputs {
        exemplars: vec![a.clone()],
        guide: Some(guide.clone()),
        exemplar_regions: vec![Heightfield::from_fn(10, 10, 1.0, 1.0, |_, _| 0.0)],
        ..Default::default()
    };
    let err = job.run(bad, &NoProgress).unwrap_err().to_string();
    assert!(
        err.contains("exemplar_regions") && err.contains("10 x 10"),
        "{err}"
    );
    let painted = Heightfield::from_fn(160, 160, 1.0, 1.0, |x, _| if x < 80 { 4.0 } else { 7.0 });
    let good = JobInputs {
        exemplars: vec![a.clone()],
        guide: Some(guide.clone()),
        exemplar_regions: vec![painted],
        ..Default::default()
    };
    let out = job.run(good, &NoProgress).unwrap();
    let cats: Vec<u16> = out
        .figures
        .prepare
        .patches_per_category
        .iter()
        .map(|c| c.0)
        .collect();
    assert_eq!(cats, vec![4, 7]);
    // Three exemplars: a lower region of the canyon the guide never reaches, then the guide's
    // region twice. The cover keeps one copy of the guide's region.
    let v = ValidateJob {
        settings: s,
        guide: GuideSetup {
            blur: Some(4.0),
            ..Default::default()
        },
        auto_subset: true,
        ..Default::default()
    };
    let three = JobInputs {
        exemplars: vec![b, a.clone(), a.clone()],
        guide: Some(a.crop(16, 24, 128, 96).unwrap()),
        ..Default::default()
    };
    let out = v.run(three, &NoProgress).unwrap();
    assert!(out.report.ok, "{}", out.report);
    assert_eq!(out.figures.exemplar_subset, Some(vec![1]));
    let one = index_of([a], &small());
    assert_eq!(out.figures.candidate_patches, one.patches().len());
}

// The public patch search (PCA + kd-tree, section 3.5).

#[test]
fn nearest_overlaps_finds_the_patch_itself_and_ranks_by_overlap() {
    let Some(ex) = dem_crop("grandcanyon", 100, 120, 160, 160) else {
        return;
    };
    let s = search_settings();
    let index = index_of([ex.clone()], &s);
    let p = s.patch_size;
    for (x, y) in [(0usize, 0usize), (57, 91), (128, 13)] {
        let region: Vec<f32> = (0..p)
            .flat_map(|r| (0..p).map(move |c| (r, c)))
            .map(|(r, c)| ex.get(x + c, y + r))
            .collect();
        let id = index
            .patches()
            .iter()
            .position(|q| (q.x as usize, q.y as usize) == (x, y))
            .unwrap();
        for shape in [OverlapShape::Left, OverlapShape::Top, OverlapShape::Both] {
            let near = index.nearest_overlaps(shape, &region, 24, 10).unwrap();
            assert_eq!(near.len(), 24);
            assert!(near.windows(2).all(|w| w[0].0 <= w[1].0));
            // The patch itself has overlap error 0 (vertical offsets do not matter: the
            // error is mean-removed).
            assert!(near[0].0 < 1e-3, "{shape:?} {:?}", &near[..3]);
            assert!(
                near.iter().any(|&(_, i)| i == id),
                "{shape:?} at ({x}, {y})"
            );
            let shifted: Vec<f32> = region.iter().map(|v| v + 250.0).collect();
            let near2 = index.nearest_overlaps(shape, &shifted, 24, 10).unwrap();
            assert!(near2.iter().any(|&(_, i)| i == id));
            // Far patches of the exemplar rank behind the true neighbours: the 24th error is
            // small compared with the errors of all patches (every patch fetched: exact).
            let all = index
                .nearest_overlaps(shape, &region, index.patches().len(), 1)
                .unwrap();
            assert_eq!(all.len(), index.patches().len());
            let median = all[all.len() / 2].0;
            assert!(near[23].0 < median, "{} vs median {median}", near[23].0);
        }
    }
    let e = index
        .nearest_overlaps(OverlapShape::Left, &[0.0; 10], 4, 10)
        .unwrap_err();
    assert!(
        matches!(e, PatchSynthError::InvalidControl { name: "region", .. }),
        "{e}"
    );
    let e = index
        .nearest_overlaps(OverlapShape::Left, &vec![0.0; p * p], 0, 10)
        .unwrap_err();
    assert!(e.to_string().contains("`knn` = 0"), "{e}");
    let mut bad = vec![1.0; p * p];
    bad[p + 1] = f32::NAN;
    assert!(
        index
            .nearest_overlaps(OverlapShape::Left, &bad, 4, 10)
            .is_err()
    );
}

/// Re-ranking the kd-tree's neighbours by the exact overlap error (issue 17): the 24 returned
/// hold most of the exhaustive best 24 for an overlap from another DEM, and more of them than
/// the kd-tree's own 24 (`rerank = 1`).
#[test]
fn reranked_search_recovers_the_exhaustive_best() {
    let Some([ex, other]) = dem_crops([
        ("grandcanyon", 100, 120, 200, 200),
        ("alps_dem", 900, 200, 200, 200),
    ]) else {
        return;
    };
    let s = search_settings();
    let index = index_of([ex], &s);
    let p = s.patch_size;
    let n = index.patches().len();
    let (mut hit1, mut hit10) = (0usize, 0usize);
    for (x, y) in [(10usize, 20usize), (70, 130), (150, 40), (120, 150)] {
        let region: Vec<f32> = (0..p)
            .flat_map(|r| (0..p).map(move |c| (r, c)))
            .map(|(r, c)| 0.5 * other.get(x + c, y + r))
            .collect();
        let exact: Vec<usize> = index
            .nearest_overlaps(OverlapShape::Both, &region, n, 1)
            .unwrap()
            .into_iter()
            .take(24)
            .map(|v| v.1)
            .collect();
        for (rerank, hits) in [(1, &mut hit1), (10, &mut hit10)] {
            let got = index
                .nearest_overlaps(OverlapShape::Both, &region, 24, rerank)
                .unwrap();
            *hits += got.iter().filter(|v| exact.contains(&v.1)).count();
        }
    }
    assert!(hit10 * 10 >= 9 * 4 * 24, "recall {hit10} of 96");
    assert!(hit10 > hit1, "rerank 10: {hit10}, rerank 1: {hit1}");
}

/// Issue 44 item 11: a guide whose cell size differs from the exemplars' (the usual
/// cross-DEM case) keeps its georeference when resampled to their cells: the same origin,
/// the pixel size scaled by the resampling, so the output lies on the guide's ground.
#[test]
fn a_resampled_guide_keeps_its_georeference() {
    let guide = Heightfield::from_fn(40, 30, 90.0, 90.0, |x, y| (x * 3 + y) as f32).with_georef(
        Some(relief_heightfield::GeoRef {
            crs: Some("EPSG:32611".into()),
            geotransform: Some([500_000.0, 90.0, 0.0, 4_000_000.0, 0.0, -90.0]),
            ..Default::default()
        }),
    );
    let g = to_cell_size(&guide, (30.0, 30.0)).unwrap();
    assert_eq!((g.width(), g.height()), (120, 90));
    let r = g.georef().expect("the georeference is kept");
    assert_eq!(r.crs.as_deref(), Some("EPSG:32611"));
    assert_eq!(
        r.geotransform.unwrap(),
        [500_000.0, 30.0, 0.0, 4_000_000.0, 0.0, -30.0]
    );
}
