use super::*;
use relief_heightfield::Heightfield;

#[test]
fn node_is_compact() {
    assert!(
        TerrainTree::node_size() <= 40,
        "{}",
        TerrainTree::node_size()
    );
}

#[test]
fn bvh_equals_flat_blend_and_lipschitz_bounds_hold() {
    let mut t = TerrainTree::new();
    let mut ids = Vec::new();
    for k in 0..200u64 {
        let h = |s| crate::math::unit(crate::math::hash(3, k, s, 0)) * 100.0;
        let c = [h(0), h(1), h(2)];
        ids.push(match k % 4 {
            0 => t.sphere(c, 5.0 + h(3) * 0.1, 1.0).unwrap(),
            1 => t.capsule(c, add(c, [3.0, 1.0, 2.0]), 4.0, -0.7).unwrap(),
            2 => t.cone(c, add(c, [0.0, 0.0, 8.0]), 6.0, 2.0, 0.9).unwrap(),
            _ => t.ellipsoid(c, [6.0, 4.0, 3.0], 1.2).unwrap(),
        });
    }
    let flat = t.blend(&ids).unwrap();
    let bvh = t.bvh_blend(&ids).unwrap();
    let region = Aabb::new([0.0; 3], [100.0; 3]);
    let l = t.lipschitz(flat, &region);
    assert!((l - t.lipschitz(bvh, &region)).abs() < 1e-3 * l);
    for k in 0..2000u64 {
        let h = |s| crate::math::unit(crate::math::hash(9, k, s, 0)) * 100.0;
        let p = [h(0), h(1), h(2)];
        let (a, b) = (t.eval(flat, p), t.eval(bvh, p));
        assert!((a - b).abs() < 1e-5, "{a} {b}");
        let q = add(p, [0.3, -0.2, 0.1]);
        let small = Aabb::new(p, q);
        let lb = t.lipschitz(bvh, &small);
        let d = crate::math::norm(sub(q, p));
        assert!((t.eval(bvh, q) - b).abs() <= lb * d + 1e-5);
    }
}

/// The tree of a wavy 300 x 200 m ground with a sphere and an ellipsoid above it, and their
/// nodes `(ground, sphere, ellipsoid)`.
fn ground_sphere_ellipsoid() -> (TerrainTree, [NodeId; 3]) {
    let hf = Heightfield::from_fn(30, 20, 10.0, 10.0, |x, y| {
        50.0 + 20.0 * ((x as f32) * 0.3).sin() + y as f32
    });
    let mut t = TerrainTree::new();
    let (h, _) = t.heightfield(&hf, 15.0, 30.0).unwrap();
    let s1 = t.sphere([100.0, 100.0, 60.0], 30.0, -2.0).unwrap();
    let e1 = t
        .ellipsoid([150.0, 80.0, 90.0], [20.0, 10.0, 15.0], 1.0)
        .unwrap();
    (t, [h, s1, e1])
}

#[test]
fn intervals_contain_the_field() {
    let (mut t, [h, s1, e1]) = ground_sphere_ellipsoid();
    let bv = t.bvh_blend(&[s1, e1]).unwrap();
    let bl = t.blend(&[h, bv]).unwrap();
    let w = t.warp(e1, 3.0, 0.1, 1).unwrap();
    // A slanted carving capsule and a cone of matter kept inside the ground.
    let cap = t
        .capsule([40.0, 30.0, 40.0], [200.0, 150.0, 70.0], 25.0, -10.0)
        .unwrap();
    let cone = t
        .cone([220.0, 40.0, 20.0], [250.0, 160.0, 90.0], 30.0, 10.0, 2.0)
        .unwrap();
    let kept = t.intersection(h, cone).unwrap();
    let carved = t.blend(&[bl, cap]).unwrap();
    let root = t.union(carved, w).unwrap();
    let root = t.union(root, kept).unwrap();
    for k in 0..600u64 {
        let r = |s| crate::math::unit(crate::math::hash(5, k, s, 0));
        let c = [r(0) * 290.0, r(1) * 190.0, r(2) * 150.0];
        // Boxes from a few metres to most of the DEM (the pyramid's coarse levels).
        let size = if k % 3 == 0 { 250.0 } else { 40.0 };
        let b = Aabb::new(c, add(c, [r(3) * size, r(4) * size, r(5) * size]));
        let (lo, hi) = t.interval(root, &b);
        for m in 0..20u64 {
            let q = |s| crate::math::unit(crate::math::hash(6, k, m, s));
            let p = [
                b.min[0] + q(0) * (b.max[0] - b.min[0]),
                b.min[1] + q(1) * (b.max[1] - b.min[1]),
                b.min[2] + q(2) * (b.max[2] - b.min[2]),
            ];
            let v = t.eval(root, p);
            assert!(v >= lo - 1e-5 && v <= hi + 1e-5, "{v} not in [{lo}, {hi}]");
        }
    }
    // A box around the carving's axis is proven below zero (a box-to-bbox test could not).
    let core = Aabb::sphere([120.0, 90.0, 55.0], 5.0);
    let (lo, hi) = t.interval(cap, &core);
    assert!(hi < -5.0 && lo >= -10.0, "[{lo}, {hi}]");
    // Beside the cone, inside its bounding box: proven air (a box-to-bbox test gives `e`).
    let beside = Aabb::sphere([271.0, 100.0, 95.0], 1.0);
    assert!(t.bbox(cone).intersects(&beside));
    let (lo, hi) = t.interval(cone, &beside);
    assert!(lo >= 0.0 && hi < THRESHOLD, "[{lo}, {hi}]");
}

/// The min/max pyramid's ranges hold every DEM node under the box and come from at most a
/// few blocks: exact for boxes of a couple of cells, never narrower for any.
#[test]
fn height_ranges_from_the_pyramid_hold_the_nodes_under_the_box() {
    let hf = Heightfield::from_fn(37, 23, 10.0, 10.0, |x, y| {
        ((x * 7 + y * 13) % 17) as f32 + 0.1 * (x as f32)
    });
    let mut t = TerrainTree::new();
    t.heightfield(&hf, 5.0, 10.0).unwrap();
    let p = &t.hfs[0];
    for k in 0..400u64 {
        let r = |s| crate::math::unit(crate::math::hash(9, k, s, 0));
        let c = [r(0) * 360.0, r(1) * 220.0, 0.0];
        let size = [10.0, 30.0, 400.0][k as usize % 3] * r(2);
        let b = Aabb::new(c, add(c, [size, size * r(3), 1.0]));
        let (lo, hi) = p.height_range(&b);
        let u0 = ((b.min[0] / 10.0).floor().max(0.0) as usize).min(36);
        let u1 = ((b.max[0] / 10.0).ceil().max(0.0) as usize).min(36);
        let v0 = ((22.0 - b.max[1] / 10.0).floor().max(0.0) as usize).min(22);
        let v1 = ((22.0 - b.min[1] / 10.0).ceil().max(0.0) as usize).min(22);
        let (mut el, mut eh) = (f32::INFINITY, f32::NEG_INFINITY);
        for i in v0..=v1 {
            for j in u0..=u1 {
                el = el.min(hf.get(j, i));
                eh = eh.max(hf.get(j, i));
            }
        }
        assert!(lo <= el && hi >= eh, "[{lo}, {hi}] misses [{el}, {eh}]");
        if u1 - u0 <= 3 && v1 - v0 <= 3 {
            assert_eq!((lo, hi), (el, eh), "a small box reads the nodes");
        }
    }
}

#[test]
fn warp_skips_the_noise_outside_its_box_without_changing_the_field() {
    let mut t = TerrainTree::new();
    let e1 = t
        .ellipsoid([150.0, 80.0, 90.0], [20.0, 10.0, 15.0], 1.0)
        .unwrap();
    let (amp, freq) = (6.0, 0.1);
    let w = t.warp(e1, amp, freq, 3).unwrap();
    let b = t.bbox(w);
    assert_eq!(b, t.bbox(e1).inflate(0.75 * amp));
    let mut inside = 0;
    for k in 0..4000u64 {
        let r = |s| crate::math::unit(crate::math::hash(9, k, s, 0));
        let p = [110.0 + r(0) * 80.0, 60.0 + r(1) * 40.0, 65.0 + r(2) * 50.0];
        // The definition: the child at the displaced point.
        let d = fbm3(3, mul(p, freq), 2);
        let want = t.eval(e1, add(p, mul(d, amp)));
        assert_eq!(t.eval(w, p), want, "at {p:?}");
        if !b.contains(p) {
            assert_eq!(want, 0.0, "warp box too small at {p:?}");
        } else if want > 0.0 {
            inside += 1;
        }
    }
    assert!(inside > 100, "{inside}");
}

#[test]
fn analytic_gradient_matches_central_differences() {
    let (mut t, [h, s1, e1]) = ground_sphere_ellipsoid();
    let c1 = t
        .capsule([50.0, 50.0, 60.0], [120.0, 80.0, 70.0], 12.0, -1.5)
        .unwrap();
    let k1 = t
        .cone([200.0, 60.0, 60.0], [200.0, 60.0, 100.0], 15.0, 5.0, 1.0)
        .unwrap();
    let bv = t.bvh_blend(&[s1, c1]).unwrap();
    let bl = t.blend(&[h, bv]).unwrap();
    let sm = t.smooth_blend(e1, k1, 3.0).unwrap();
    let w = t.warp(e1, 3.0, 0.1, 1).unwrap();
    let u = t.union(bl, sm).unwrap();
    let d = t.difference(u, w).unwrap();
    let root = t.intersection(d, h).unwrap();
    let (mut n, mut worst) = (0, 0.0f32);
    for k in 0..4000u64 {
        let r = |s| crate::math::unit(crate::math::hash(8, k, s, 0));
        let p = [r(0) * 290.0, r(1) * 190.0, 20.0 + r(2) * 100.0];
        let (v, g) = t.eval_grad(root, p, 1e-3);
        assert!((v - t.eval(root, p)).abs() < 1e-5);
        let mut fd = [0.0; 3];
        let hh = 1e-2;
        for a in 0..3 {
            let (mut p1, mut p2) = (p, p);
            p1[a] += hh;
            p2[a] -= hh;
            fd[a] = (t.eval(root, p1) - t.eval(root, p2)) / (2.0 * hh);
        }
        let err = crate::math::norm(sub(g, fd));
        let scale = crate::math::norm(fd).max(1e-3);
        // Kinks (CSG switches, grid lines, clamps) can sit between the FD samples.
        if err > 0.05 * scale + 1e-4 {
            worst = worst.max(err / scale);
            n += 1;
        }
    }
    assert!(n < 40, "{n} points disagree (worst relative {worst})");
}

#[test]
fn errors_name_the_parameter() {
    let mut t = TerrainTree::new();
    let e = t.sphere([0.0; 3], -1.0, 1.0).unwrap_err();
    assert!(e.to_string().contains("sphere.radius"));
    assert!(t.union(NodeId(5), NodeId(6)).is_err());
    assert!(t.smooth_blend(NodeId(0), NodeId(0), 0.5).is_err());
}

/// The shading gradient of the DEM surface is continuous across cell edges (the bilinear
/// patches' own gradient jumps there, which shades each cell as a facet), equals the node
/// slopes' central differences at the nodes, and leaves the field value unchanged.
#[test]
fn shading_gradient_is_continuous_across_dem_cells() {
    // z = 0.002 x^2 on 10 m cells: the bilinear slope is constant per cell and jumps by
    // 0.04 at every cell edge; the smooth slope is 0.004 x up to the edges' rounding.
    let hf = Heightfield::from_fn(16, 8, 10.0, 10.0, |x, _| 0.002 * (10.0 * x as f32).powi(2));
    let mut t = TerrainTree::new();
    let (id, _) = t.heightfield(&hf, 5.0, 50.0).unwrap();
    let slope = |g: V3| -g[0] / g[2];
    for x in [30.0f32, 50.0, 70.0, 90.0] {
        let z = t.dem_height(id, x, 35.0).unwrap();
        let (l, r) = ([x - 1e-2, 35.0, z], [x + 1e-2, 35.0, z]);
        let (exact_l, exact_r) = (t.eval_grad(id, l, 1e-3), t.eval_grad(id, r, 1e-3));
        let (smooth_l, smooth_r) = (
            t.eval_shading_grad(id, l, 1e-3),
            t.eval_shading_grad(id, r, 1e-3),
        );
        assert_eq!(exact_l.0, smooth_l.0);
        assert!((slope(exact_r.1) - slope(exact_l.1) - 0.04).abs() < 1e-3);
        assert!((slope(smooth_r.1) - slope(smooth_l.1)).abs() < 1e-3);
        assert!((slope(smooth_l.1) - 0.004 * x).abs() < 1e-3, "{x}");
    }
}

/// The heightfield's Lipschitz bound over a region follows the steepest cell under it: it holds
/// for pairs of points in the region (a DEM with a 60 m cliff and gentle ground), and on the
/// gentle side it is far below the DEM-wide bound set by the cliff.
#[test]
fn heightfield_lipschitz_follows_the_local_slope() {
    let hf = Heightfield::from_fn(48, 32, 10.0, 10.0, |x, y| {
        let gentle = 0.3 * x as f32 + 0.2 * y as f32;
        if x >= 30 { gentle + 60.0 } else { gentle }
    });
    let mut t = TerrainTree::new();
    let (h, _) = t.heightfield(&hf, 8.0, 20.0).unwrap();
    let whole = t.lipschitz(h, &t.bbox(h));
    // West of the cliff (x < 290 m; row 0 is the north edge, y up).
    let gentle = Aabb::new([20.0, 20.0, -10.0], [200.0, 290.0, 40.0]);
    let local = t.lipschitz(h, &gentle);
    assert!(local < 0.2 * whole, "{local} vs {whole}");
    for (k, region) in [gentle, t.bbox(h)].iter().enumerate() {
        let l = t.lipschitz(h, region);
        for m in 0..2000u64 {
            let r = |s| crate::math::unit(crate::math::hash(11, k as u64, m, s));
            let pt = |o: u64| {
                [
                    region.min[0] + r(o) * (region.max[0] - region.min[0]),
                    region.min[1] + r(o + 1) * (region.max[1] - region.min[1]),
                    region.min[2] + r(o + 2) * (region.max[2] - region.min[2]),
                ]
            };
            let (p, q) = (pt(0), pt(3));
            let q = add(p, mul(sub(q, p), 0.05));
            let d = crate::math::norm(sub(q, p));
            let df = (t.eval(h, q) - t.eval(h, p)).abs();
            assert!(df <= l * d + 1e-5, "{df} > {l} * {d}");
        }
    }
}
