//! Surface colours shared by the renderer and the meshes: rock coloured by its stratum's
//! resistance (soft shale red-brown, sandstone orange to buff, hard limestone pale grey, as in
//! the Grand Canyon's column), with a grain texture in metres, and a soil and vegetation cover
//! on gentle slopes tinted by the rock beneath. A render ([`crate::render`]) and a mesh's vertex
//! colours ([`vertex_colours`]) use the same [`surface_albedo`], so Blender and game engines
//! show the strata a render shows. Renders also tilt the shading normal by a relief texture
//! in metres ([`bumped_normal`]) that fades out where a pixel is too coarse. Ambient occlusion
//! ([`ambient_occlusion`]) darkens hollows, cave mouths and the feet of cliffs in renders.

use rayon::prelude::*;

use crate::math::{V3, add, cross, fbm, mul, norm, normalize};
use crate::mesh::Mesh;
use crate::scene::Scene;

/// Rock colours along resistance: `(resistance, [r, g, b])`, display values in `[0, 1]`.
const ROCK: [(f32, V3); 5] = [
    (0.0, [0.50, 0.27, 0.19]),  // soft shale, red-brown
    (0.3, [0.70, 0.42, 0.26]),  // weak sandstone, orange
    (0.55, [0.80, 0.64, 0.45]), // sandstone, buff
    (0.75, [0.76, 0.72, 0.62]), // hard sandstone / dolomite, pale
    (1.0, [0.70, 0.70, 0.68]),  // limestone, grey
];

/// Wavelengths (m) of the rock's grain texture: a coarse mottling and a fine grain.
const GRAIN_COARSE_M: f32 = 24.0;
const GRAIN_FINE_M: f32 = 3.0;

/// Colour of rock of resistance `rho` (clamped to `[0, 1]`) at `p` (metres): the stratum's
/// colour with a grain texture of +-12 % whose wavelengths are in metres, so the same rock
/// looks the same at every scale of mesh or render.
pub fn rock_albedo(rho: f32, p: V3) -> V3 {
    let r = if rho.is_finite() {
        rho.clamp(0.0, 1.0)
    } else {
        0.5
    };
    let mut c = ROCK[ROCK.len() - 1].1;
    for w in ROCK.windows(2) {
        let ((r0, c0), (r1, c1)) = (w[0], w[1]);
        if r <= r1 {
            let t = (r - r0) / (r1 - r0);
            c = add(mul(c0, 1.0 - t), mul(c1, t));
            break;
        }
    }
    let g = 0.08 * fbm(0x6a11, mul(p, 1.0 / GRAIN_COARSE_M), 2)
        + 0.05 * fbm(0x6a12, mul(p, 1.0 / GRAIN_FINE_M), 2);
    mul(c, 1.0 + g)
}

/// Wavelengths (m) of the rock's relief in renders ([`bumped_normal`]): joints and ledges a
/// couple of metres apart, and the roughness of weathered rock.
const BUMP_M: [f32; 2] = [2.0, 0.5];

/// Relief amplitude of [`bumped_normal`] as a share of each wavelength.
const BUMP_AMPLITUDE: f32 = 0.15;

/// The shading normal of rock at `p` (outward normal `n`) tilted by a relief texture
/// whose wavelengths are in metres ([`BUMP_M`], amplitude 8 % of each), `strength` in
/// `[0, 1]` scaling it: small-scale roughness that a mesh at the render's resolution does
/// not carry. A wavelength shorter than four `footprint`s (a pixel's size on the surface, m)
/// fades out (none below two), so a distant surface does not alias into noise.
pub fn bumped_normal(n: V3, p: V3, footprint: f32, strength: f32) -> V3 {
    let mut g = [0.0f32; 3];
    for (k, lam) in BUMP_M.into_iter().enumerate() {
        let fade = ((lam / footprint.max(1e-6) - 2.0) * 0.5).clamp(0.0, 1.0);
        if fade <= 0.0 {
            continue;
        }
        let seed = 0x6a20 + k as u64;
        let q = mul(p, 1.0 / lam);
        let e = 0.05;
        let f0 = fbm(seed, q, 2);
        for (a, ga) in g.iter_mut().enumerate() {
            let mut qa = q;
            qa[a] += e;
            *ga += fade * strength * BUMP_AMPLITUDE * (fbm(seed, qa, 2) - f0) / e;
        }
    }
    let gn = g[0] * n[0] + g[1] * n[1] + g[2] * n[2];
    let tilted = normalize(add(n, mul(add(g, mul(n, -gn)), -1.0)));
    if crate::math::finite3(tilted) {
        tilted
    } else {
        n
    }
}

/// Slope (degrees) around which the regolith gives way to bare rock ([`surface_albedo`]),
/// and the half-width of the transition.
const OUTCROP_SLOPE_DEG: f32 = 36.0;
const OUTCROP_SPREAD_DEG: f32 = 7.0;

/// How far (degrees) the outcrop threshold wanders from place to place: soil thickness varies,
/// so a bed's riser is bare in one spot and grassed over a few tens of metres on.
const OUTCROP_JITTER_DEG: f32 = 10.0;

/// Wavelength (m) of that wandering.
const OUTCROP_PATCH_M: f32 = 45.0;

/// Height (m) above the DEM's ground from which a surface is a landform's added rock, bare
/// (fully from twice it): more than the implicit surface's own departure from the DEM.
const BARE_ABOVE_M: f32 = 1.0;

/// Weathered rock mixed over the beds (the mean of [`ROCK`], a little darker) and sparse
/// vegetation, the two parts of the cover on gentle ground.
const REGOLITH: V3 = [0.62, 0.52, 0.40];
const VEGETATION: V3 = [0.34, 0.40, 0.22];

/// Colour of the surface at `p` with outward normal `n`: bare rock where the slope is steeper
/// than about [`OUTCROP_SLOPE_DEG`] (a threshold that wanders by [`OUTCROP_JITTER_DEG`] over
/// [`OUTCROP_PATCH_M`], so a bed's riser crops out in patches, not as a contour stripe),
/// elsewhere regolith ([`REGOLITH`]) with patches of vegetation, sparser high in the scene's
/// height range, only faintly tinted by the rock beneath: regolith mixes the beds it creeps
/// over, and a strong tint would draw every bed's outcrop as a stripe across gentle ground.
/// Surfaces more than [`BARE_ABOVE_M`] above the DEM's ground (the landforms' added rock) are
/// bare rock at any slope.
pub fn surface_albedo(scene: &Scene, p: V3, n: V3) -> V3 {
    let b = scene.bbox();
    let (zlo, zhi) = (b.min[2], b.max[2]);
    let hgt = ((p[2] - zlo) / (zhi - zlo).max(1e-3)).clamp(0.0, 1.0);
    let rock = rock_albedo(scene.resistance(p), p);
    let slope = n[2].clamp(-1.0, 1.0).acos().to_degrees();
    let jitter = OUTCROP_JITTER_DEG * fbm(0x6a14, mul(p, 1.0 / OUTCROP_PATCH_M), 2);
    let t =
        ((slope + jitter - OUTCROP_SLOPE_DEG) / (2.0 * OUTCROP_SPREAD_DEG) + 0.5).clamp(0.0, 1.0);
    // Matter a landform added above the DEM's ground (a hoodoo's cap, an arch's bridge, a
    // floating island) is bare rock: regolith creeps over hillslopes, it does not collect on
    // a column's top a few metres across.
    let above = scene.dem_height(p[0], p[1]).map_or(0.0, |g| {
        ((p[2] - g - BARE_ABOVE_M) / BARE_ABOVE_M).clamp(0.0, 1.0)
    });
    let t = t.max(above);
    let k = t * t * (3.0 - 2.0 * t);
    // Regolith: the beds' weathered, mixed rock (one colour whatever the bed, faintly
    // tinted), under vegetation in 40 m patches, sparser high in the scene's height range.
    let patch = fbm(0x6a13, mul(p, 1.0 / 40.0), 3);
    let regolith = add(mul(REGOLITH, 0.85), mul(rock, 0.15));
    let veg = ((0.4 + 0.9 * patch) * (1.0 - 0.5 * hgt)).clamp(0.0, 0.85);
    let soil = add(mul(regolith, 1.0 - veg), mul(VEGETATION, veg));
    add(mul(soil, 1.0 - k), mul(rock, k))
}

/// Share of sky light reaching `p` (outward normal `n`), in `[0, 1]`: points at distances
/// `radius / 4`, `radius / 2` and `radius` along the normal and along four directions tilted
/// 45 degrees from it are tested for matter; each solid point removes its weight (the nearer
/// points weigh more). One field evaluation per point, fifteen in all.
pub fn ambient_occlusion(scene: &Scene, p: V3, n: V3, radius: f32) -> f32 {
    // A tangent frame around n.
    let a = if n[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let t = normalize(cross(n, a));
    let s = cross(n, t);
    let dirs = [
        n,
        add(mul(n, 0.707), mul(t, 0.707)),
        add(mul(n, 0.707), mul(t, -0.707)),
        add(mul(n, 0.707), mul(s, 0.707)),
        add(mul(n, 0.707), mul(s, -0.707)),
    ];
    let mut occluded = 0.0;
    let mut total = 0.0;
    for (k, scale) in [0.25f32, 0.5, 1.0].into_iter().enumerate() {
        let w = [1.0, 0.6, 0.35][k];
        for d in dirs {
            total += w;
            if scene.inside(add(p, mul(d, radius * scale))) {
                occluded += w;
            }
        }
    }
    1.0 - occluded / total
}

/// Display value in `[0, 1]` to an 8-bit sRGB byte.
pub(crate) fn to_byte(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// sRGB colours (alpha 255) of `mesh`'s vertices from [`surface_albedo`], with the mesh's
/// normals (a vertex without a finite normal takes the scene's). The same bytes for any
/// thread count.
pub fn vertex_colours(scene: &Scene, mesh: &Mesh) -> Vec<[u8; 4]> {
    let h = 1e-3 * norm(scene.bbox().size()).max(1e-3);
    mesh.positions
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            let n = match mesh.normals.get(i) {
                Some(n) if n.iter().all(|c| c.is_finite()) => *n,
                _ => scene.shading_normal(p, h),
            };
            let c = surface_albedo(scene, p, n);
            [to_byte(c[0]), to_byte(c[1]), to_byte(c[2]), 255]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geology::test_beds;
    use crate::scene::{ImplicitizeSettings, SceneBuilder};
    use relief_heightfield::Heightfield;

    /// `hf` over beds of 6 m soft (0.2) under 4 m hard (0.8) rock from 0 m.
    fn bedded(hf: &Heightfield) -> Scene {
        let g = test_beds(0.0, (6.0, 0.2), (4.0, 0.8));
        SceneBuilder::new(hf, g, &ImplicitizeSettings::default())
            .unwrap()
            .build(true)
            .unwrap()
    }

    /// The floor of a V valley with 60 degree walls 40 m deep is occluded; the flat plains on
    /// either side are not.
    #[test]
    fn ambient_occlusion_darkens_a_valley_floor_not_the_plains_beside_it() {
        let hf = Heightfield::from_fn(64, 16, 2.0, 2.0, |x, _| {
            let d = (x as f32 - 32.0).abs() * 2.0;
            if x < 8 {
                40.0
            } else {
                (d * 3f32.sqrt()).min(40.0)
            }
        });
        let scene = bedded(&hf);
        let ao = |x: f32| {
            let z = scene.dem_height(x, 16.0).unwrap();
            let p = [x, 16.0, z + 0.05];
            ambient_occlusion(&scene, p, scene.shading_normal(p, 0.05), 8.0)
        };
        let (floor, west, east) = (ao(64.0), ao(8.0), ao(116.0));
        assert!(floor < 0.75, "valley floor {floor}");
        assert!(west > 0.95 && east > 0.95, "plains {west}, {east}");
    }

    /// Close up (a 5 cm pixel), rock's shading normal is tilted by metre-scale relief (by
    /// 5-40 degrees at most over a 4 m patch, more at full strength than at the soil's 0.3);
    /// seen from afar (a 2 m pixel) it is the plain normal (no aliasing noise); always unit.
    #[test]
    fn rock_relief_tilts_close_normals_and_fades_with_distance() {
        let n = normalize([0.3, -0.2, 0.9]);
        let tilt = |foot: f32, strength: f32| {
            let mut worst = 0.0f32;
            for i in 0..40 {
                for j in 0..40 {
                    let p = [i as f32 * 0.1, j as f32 * 0.1, 7.0];
                    let b = bumped_normal(n, p, foot, strength);
                    assert!((norm(b) - 1.0).abs() < 1e-4);
                    let d = (b[0] * n[0] + b[1] * n[1] + b[2] * n[2]).clamp(-1.0, 1.0);
                    worst = worst.max(d.acos().to_degrees());
                }
            }
            worst
        };
        let (rock, soil, far) = (tilt(0.05, 1.0), tilt(0.05, 0.3), tilt(2.0, 1.0));
        assert!(
            rock > 5.0 && rock < 40.0 && soil < 0.6 * rock,
            "{rock} {soil}"
        );
        assert!(far < 1e-3, "{far}");
    }

    /// On gentle ground the beds hardly show through the regolith (their mean colours differ
    /// by less than a sixth of what they differ by as bare rock on a 70 degree face), so
    /// a hillside is not drawn as contour stripes; with the old cover (a quarter of the rock's
    /// colour, rock from 25 degrees) the share was 0.30. Steep faces are bare rock.
    #[test]
    fn gentle_ground_is_regolith_and_steep_faces_are_bare_rock() {
        let hf = Heightfield::from_fn(32, 32, 4.0, 4.0, |x, _| x as f32);
        let scene = bedded(&hf);
        let at = |deg: f32| {
            let n = [deg.to_radians().sin(), 0.0, deg.to_radians().cos()];
            let (mut soft, mut hard, mut ns, mut nh) = ([0.0f32; 3], [0.0f32; 3], 0, 0);
            for i in 0..60 {
                for k in 0..30 {
                    // On the DEM's ground (its height is x / 4 m), through every bed.
                    let z = k as f32 + (i as f32 * 0.37) % 1.0;
                    let p = [4.0 * z, 40.0 + i as f32 * 0.7, z];
                    let c = surface_albedo(&scene, p, n);
                    if scene.resistance(p) < 0.5 {
                        soft = add(soft, c);
                        ns += 1;
                    } else {
                        hard = add(hard, c);
                        nh += 1;
                    }
                }
            }
            let d = add(mul(soft, 1.0 / ns as f32), mul(hard, -1.0 / nh as f32));
            norm(d)
        };
        let (gentle, steep) = (at(10.0), at(70.0));
        assert!(steep > 0.1, "bare beds differ by {steep}");
        assert!(gentle < steep / 6.0, "gentle {gentle}, steep {steep}");
    }

    /// A flat top standing 12 m over flat ground (a hoodoo's cap) is bare rock; the ground
    /// at its foot, as flat, is regolith.
    #[test]
    fn landforms_above_the_ground_are_bare_rock() {
        let hf = Heightfield::from_fn(32, 32, 4.0, 4.0, |_, _| 3.0);
        let scene = bedded(&hf);
        let up = [0.0, 0.0, 1.0];
        let (mut top, mut ground) = (0.0f32, 0.0f32);
        for i in 0..100 {
            let (x, y) = (20.0 + i as f32 * 0.6, 30.0 + i as f32 * 0.4);
            let rock = rock_albedo(scene.resistance([x, y, 15.0]), [x, y, 15.0]);
            top += norm(add(
                surface_albedo(&scene, [x, y, 15.0], up),
                mul(rock, -1.0),
            ));
            let rock = rock_albedo(scene.resistance([x, y, 3.0]), [x, y, 3.0]);
            ground += norm(add(
                surface_albedo(&scene, [x, y, 3.0], up),
                mul(rock, -1.0),
            ));
        }
        assert!(top < 1e-4, "the cap's top differs from its rock by {top}");
        assert!(ground > 5.0, "the ground is rock-coloured: {ground}");
    }

    #[test]
    fn soft_rock_is_redder_and_darker_than_hard_rock() {
        // Away from the grain's extremes: the mean over many points.
        let mean = |rho: f32| {
            let mut s = [0.0f32; 3];
            for i in 0..200 {
                let c = rock_albedo(rho, [i as f32 * 7.3, i as f32 * 3.1, 0.0]);
                s = add(s, mul(c, 1.0 / 200.0));
            }
            s
        };
        let (soft, hard) = (mean(0.05), mean(0.95));
        assert!(
            soft[0] / soft[2] > 2.0 * hard[0] / hard[2],
            "{soft:?} {hard:?}"
        );
        assert!(soft.iter().sum::<f32>() < hard.iter().sum::<f32>());
        // The grain varies the colour by a few per cent: 3-35 % from the lowest to the highest.
        let c = (0..200).map(|i| rock_albedo(0.5, [i as f32 * 1.7, 0.0, 0.0])[0]);
        let (lo, hi) = c.fold((f32::MAX, f32::MIN), |(a, b), v| (a.min(v), b.max(v)));
        assert!(hi / lo > 1.03 && hi / lo < 1.35, "{lo} {hi}");
        // Out-of-range and non-finite resistance give a colour, not a panic or NaN.
        for r in [-1.0, 2.0, f32::NAN] {
            assert!(rock_albedo(r, [0.0; 3]).iter().all(|v| v.is_finite()));
        }
    }
}
