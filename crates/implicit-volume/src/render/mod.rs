//! Sphere-traced shaded rendering and vertical cut-away sections to RGB8 buffers (no file I/O).
//!
//! The tracer steps along each ray by `(T - f(p)) / L`, where `L` is a Lipschitz bound of the
//! field over a ball around `p` ([`Scene::lipschitz`]), so it never steps over a surface thinner
//! than the bound allows; the ball radius adapts (doubling after free steps). Two shortcuts
//! keep that exact but cheaper: a beam pre-pass ([`beam`]) traces one cone per block of 16 x 16
//! and then 4 x 4 pixels, so each primary ray starts where its block's cone proved the space
//! in front of it empty; and a primary ray creeping along a surface at the smallest step (the
//! pixel footprint) skips the interval test of its ball, which fails there, and reuses the
//! Lipschitz bound while it stays inside the ball the bound was computed over. On top of
//! that, the image loop (module `frame`) traces every fourth pixel and fills the others from them
//! where they lie on one smooth surface ([`RenderSettings::adaptive`]).

use rayon::prelude::*;

mod beam;
mod frame;

use crate::error::{Error, Result};
use crate::material;
use crate::math::{Aabb, V3, add, cross, dot, mul, norm, normalize, sub};
use crate::scene::Scene;
use crate::tree::THRESHOLD;

/// An RGB8 image, row-major from the top-left.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height * 3` bytes.
    pub rgb: Vec<u8>,
}

/// A pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub eye: V3,
    /// Point looked at.
    pub target: V3,
    /// Up vector.
    pub up: V3,
    /// Vertical field of view (degrees).
    pub fov_deg: f32,
}

impl Camera {
    /// A camera looking at the centre of `bbox` from the south-west, above.
    pub fn overview(bbox: &Aabb) -> Self {
        let c = bbox.center();
        let s = bbox.size();
        let d = s[0].max(s[1]);
        Camera {
            eye: add(c, [-0.55 * d, -0.75 * d, 0.6 * d + 0.5 * s[2]]),
            target: c,
            up: [0.0, 0.0, 1.0],
            fov_deg: 45.0,
        }
    }
}

impl Camera {
    /// A landscape view of a scene: the eye just inside its south-west corner, a little above
    /// the highest matter, looking across the scene at the ground 60 % of the way to the
    /// north-east corner, so the terrain fills the frame up to its far edge and the horizon
    /// (instead of a small block seen from far above, [`Camera::overview`]).
    pub fn landscape(scene: &Scene) -> Self {
        let b = scene.bbox();
        let (x0, y0, x1, y1) = match scene.dem_frame() {
            Some(f) => (
                0.0,
                0.0,
                (f.width - 1) as f32 * f.cx,
                (f.height - 1) as f32 * f.cy,
            ),
            None => (b.min[0], b.min[1], b.max[0], b.max[1]),
        };
        let (sx, sy) = (x1 - x0, y1 - y0);
        let d = sx.max(sy);
        // Mean ground height over a 16 x 16 lattice (the box centre without a DEM).
        let mut sum = 0.0f64;
        let mut n = 0usize;
        for j in 0..16 {
            for i in 0..16 {
                let (x, y) = (
                    x0 + (i as f32 + 0.5) / 16.0 * sx,
                    y0 + (j as f32 + 0.5) / 16.0 * sy,
                );
                if let Some(z) = scene.dem_height(x, y).filter(|z| z.is_finite()) {
                    sum += z as f64;
                    n += 1;
                }
            }
        }
        let ground = if n > 0 {
            (sum / n as f64) as f32
        } else {
            b.center()[2]
        };
        let top = b.max[2];
        let eye = [x0 + 0.03 * sx, y0 + 0.03 * sy, top + 0.12 * d];
        let target = [x0 + 0.6 * sx, y0 + 0.6 * sy, ground.min(top)];
        if !(crate::math::finite3(eye) && crate::math::finite3(target)) || d <= 0.0 {
            return Self::overview(&b);
        }
        Camera {
            eye,
            target,
            up: [0.0, 0.0, 1.0],
            fov_deg: 50.0,
        }
    }

    /// A close-up on `target` from the south-west and above, `distance` metres away, the eye
    /// raised out of the rock if it starts inside (e.g. behind a cliff).
    pub fn closeup(scene: &Scene, target: V3, distance: f32) -> Self {
        Self::closeup_from(scene, target, distance, [-0.55, -0.7, 0.6])
    }

    /// A close-up on `target` from the direction `from` (towards the eye, need not be
    /// normalised; a zero vector falls back to the south-west view), `distance` metres away,
    /// the eye raised out of the rock if it starts inside.
    pub fn closeup_from(scene: &Scene, target: V3, distance: f32, from: V3) -> Self {
        let dir = if norm(from) > 0.0 && crate::math::finite3(from) {
            normalize(from)
        } else {
            normalize([-0.55, -0.7, 0.6])
        };
        // From the target, out along the horizontal of `from` to where the ground is under
        // it (the mouth of a tunnel the target is in), then `distance` further along `from`;
        // raised out of the rock if still inside.
        let h = normalize([dir[0], dir[1], 0.0]);
        let mut start = target;
        if crate::math::finite3(h) {
            for m in 0..=64 {
                let q = add(target, mul(h, m as f32 * distance / 16.0));
                start = q;
                if scene.dem_height(q[0], q[1]).is_none_or(|g| g <= target[2]) {
                    break;
                }
            }
        }
        // Not beyond the first ground rising over the line of sight (a neighbouring ridge):
        // the view is raised (steeper, up to about 60 degrees) until the ground stays under
        // it, and only then shortened.
        let ground_hit = |dir: V3| {
            (1..=32).find_map(|m| {
                let t = m as f32 * distance / 32.0;
                let q = add(start, mul(dir, t));
                scene
                    .dem_height(q[0], q[1])
                    .is_some_and(|g| g > q[2])
                    .then_some(t)
            })
        };
        let mut dir = dir;
        let mut reach = distance;
        if crate::math::finite3(h) {
            let mut hit = ground_hit(dir);
            for lift in [0.35f32, 0.7, 1.2, 1.8] {
                if hit.is_none() {
                    break;
                }
                let steeper = normalize([
                    h[0],
                    h[1],
                    dir[2].max(0.0) / norm([dir[0], dir[1], 0.0]).max(1e-6) + lift,
                ]);
                if let Some(t) = ground_hit(steeper) {
                    if hit.is_some_and(|t0| t > t0) {
                        hit = Some(t);
                        dir = steeper;
                    }
                } else {
                    hit = None;
                    dir = steeper;
                }
            }
            if let Some(t) = hit {
                reach = (t - distance / 32.0).max(0.25 * distance);
            }
        }
        let mut eye = add(start, mul(dir, reach));
        let over = |q: V3| over_dem(scene, q);
        let occluder = |eye: V3| first_occluder(scene, start, eye);
        let turned = |eye: V3| other_side(scene, start, eye);
        // Over the scene, not beyond its border (from outside, the side of the slab hides
        // the feature): another side at full distance when there is one, else pulled back
        // along the line of sight into the DEM's footprint.
        if !over(eye)
            && let Some(q) = turned(eye)
        {
            eye = q;
        }
        if let Some(f) = scene.dem_frame() {
            let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
            let sight = sub(eye, start);
            let mut keep = 1.0f32;
            for (k, hi) in [(0, xm), (1, ym)] {
                if sight[k] != 0.0 {
                    let lim = if sight[k] > 0.0 { hi } else { 0.0 };
                    let t = (lim - start[k]) / sight[k];
                    if t >= 0.0 {
                        keep = keep.min(t);
                    }
                }
            }
            if keep < 1.0 && keep.is_finite() {
                eye = add(start, mul(sight, keep.max(0.02)));
            }
        }
        // An occluder in the nearer half of the sight is looked over first: the eye is
        // raised about the target (steeper, keeping its distance) while that clears it;
        // then other sides are tried; last, the eye stops just before the occluder.
        let sight = sub(eye, start);
        let len = norm(sight);
        if len > 0.0 && crate::math::finite3(sight) {
            if occluder(eye).is_some_and(|m| m < 24) {
                let h = norm([sight[0], sight[1], 0.0]);
                for lift in [0.3f32, 0.6, 1.0] {
                    let up = normalize([sight[0], sight[1], sight[2] + lift * h.max(1e-3)]);
                    let raised = add(start, mul(up, len));
                    if occluder(raised).is_none() && !scene.inside(raised) {
                        eye = raised;
                        break;
                    }
                }
            }
            if occluder(eye).is_some()
                && let Some(q) = turned(eye)
            {
                eye = q;
            }
            if let Some(m) = occluder(eye) {
                // Just before the occluder, however close (behind it, the eye would only be
                // raised out of it and look down from far above).
                eye = add(start, mul(sub(eye, start), (m - 1).max(1) as f32 / 48.0));
            }
        }
        for _ in 0..64 {
            if !scene.inside(eye) {
                break;
            }
            eye[2] += 0.25 * distance;
        }
        Camera {
            eye,
            target,
            up: [0.0, 0.0, 1.0],
            fov_deg: 40.0,
        }
    }
}

/// Whether `q` lies over the scene's DEM footprint (always, without a DEM).
fn over_dem(scene: &Scene, q: V3) -> bool {
    scene.dem_frame().is_none_or(|f| {
        let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
        (0.0..=xm).contains(&q[0]) && (0.0..=ym).contains(&q[1])
    })
}

/// Other matter on the line of sight from `start` to `eye` (a hoodoo or a stack in front of
/// the one aimed at): once out of the target's own rock, the first of 48 steps towards the
/// eye that is inside matter.
fn first_occluder(scene: &Scene, start: V3, eye: V3) -> Option<usize> {
    let sight = sub(eye, start);
    let mut out_of_target = false;
    (1..=48).find(|&m| {
        let solid = scene.inside(add(start, mul(sight, m as f32 / 48.0)));
        out_of_target |= !solid;
        solid && out_of_target
    })
}

/// The eye at the same distance from `start` as `eye` on another side: turned about the
/// vertical through it by up to 180 degrees, nearest first, each also raised; the first over
/// the DEM, in air, with a clear sight ([`first_occluder`]).
fn other_side(scene: &Scene, start: V3, eye: V3) -> Option<V3> {
    let sight = sub(eye, start);
    let len = norm(sight);
    let h = norm([sight[0], sight[1], 0.0]).max(1e-3);
    [30f32, -30.0, 60.0, -60.0, 90.0, -90.0, 135.0, -135.0, 180.0]
        .into_iter()
        .flat_map(|deg| [0.0f32, 0.3, 0.6].map(move |lift| (deg, lift)))
        .map(|(deg, lift)| {
            let (c, s) = (deg.to_radians().cos(), deg.to_radians().sin());
            let v = [
                c * sight[0] - s * sight[1],
                s * sight[0] + c * sight[1],
                sight[2] + lift * h,
            ];
            add(start, mul(normalize(v), len))
        })
        .find(|&q| {
            over_dem(scene, q) && !scene.inside(q) && first_occluder(scene, start, q).is_none()
        })
}

/// Render settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderSettings {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Direction towards the sun.
    pub light: V3,
    /// Maximum sphere-tracing steps per ray.
    pub max_steps: u32,
    /// Trace shadow rays.
    pub shadows: bool,
    /// Darken the sky and bounce light in hollows ([`crate::material::ambient_occlusion`]:
    /// fifteen field evaluations per pixel).
    pub ambient_occlusion: bool,
    /// Sea level drawn as a translucent water plane (`None`: no water).
    pub sea_level: Option<f32>,
    /// Cut-away: a plane (a point on it, its normal pointing to the side removed, towards
    /// the eye) in front of which matter is ignored; the cut face is drawn in the rock colours
    /// of its strata ([`crate::material::rock_albedo`]), so tunnels behind it show as holes
    /// (`None`: no cut).
    pub cutaway: Option<(V3, V3)>,
    /// Trace only every fourth pixel in full and fill the pixels between from them where
    /// they lie on one smooth surface and agree on the light (six times faster on the
    /// benchmark close-ups, 0.03 % of pixels differ by more than 8 grey levels; see the
    /// `frame` module); `false` traces every pixel.
    pub adaptive: bool,
}
impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 320,
            height: 240,
            light: [-0.5, 0.4, 0.75],
            max_steps: 600,
            shadows: true,
            ambient_occlusion: true,
            sea_level: None,
            cutaway: None,
            adaptive: true,
        }
    }
}

/// Sphere-traces a ray; returns the hit distance.
/// `cone`: smallest step per unit distance (a pixel's angle; 0 = exact sphere tracing), the
/// distance counted from `bias` before the ray's origin (a shadow ray starts at the hit).
fn trace(
    scene: &Scene,
    o: V3,
    d: V3,
    tmax_user: f32,
    max_steps: u32,
    cone: f32,
    bias: f32,
    creep: bool,
) -> Option<f32> {
    let b = scene.bbox();
    // Slab test.
    let (mut t0, mut t1) = (0.0f32, tmax_user);
    for k in 0..3 {
        let inv = 1.0 / d[k];
        let (mut a, mut c) = ((b.min[k] - o[k]) * inv, (b.max[k] - o[k]) * inv);
        if a > c {
            std::mem::swap(&mut a, &mut c);
        }
        t0 = t0.max(a);
        t1 = t1.min(c);
    }
    if t0.is_nan() || t1.is_nan() || t0 > t1 {
        return None;
    }
    let diag = norm(b.size());
    let eps = 1e-4 * diag;
    let mut t = t0;
    let mut t_prev = t0;
    let mut r = 0.02 * diag;
    // Hit found between `a` (air) and `b` (matter): refine by bisection.
    let refine = |mut a: f32, mut b: f32| {
        for _ in 0..10 {
            let m = 0.5 * (a + b);
            if scene.field(add(o, mul(d, m))) > THRESHOLD {
                b = m;
            } else {
                a = m;
            }
        }
        b
    };
    // Creeping along a surface at the smallest step: the interval test of the ball is skipped
    // (near the surface it fails) and the carving-free tree's Lipschitz bound is reused while
    // the ray stays in the ball it was computed over (centre, radius, bound).
    let mut creeping = false;
    let mut cached: Option<(V3, f32, f32)> = None;
    // A ray still creeping after its steps grazes a surface (the far ground seen from a low
    // camera, warped hoodoo tops against the sky): it goes on with a step floor four and then
    // sixteen times the pixel's (half the steps each), so it either meets the surface or
    // leaves it for the sky instead of stopping in mid-air.
    let rounds = [
        (1.0f32, max_steps),
        (4.0, max_steps / 2),
        (16.0, max_steps / 2),
    ];
    for k in rounds
        .iter()
        .flat_map(|&(k, n)| std::iter::repeat_n(k, n as usize))
    {
        if t > t1 {
            // A step of the (enlarged) floor may leap past the scene's far side: the ray
            // may have entered the ground short of it.
            let end = t_prev + 0.999 * (t1 - t_prev).max(0.0);
            return (t_prev < t1 && scene.field(add(o, mul(d, end))) > THRESHOLD)
                .then(|| refine(t_prev, end));
        }
        let p = add(o, mul(d, t));
        let floor = eps.max(k * cone * (t + bias));
        // A ball proven empty by interval arithmetic: jump across it and try a larger one.
        if !creeping && scene.max_over(&Aabb::sphere(p, r)) <= THRESHOLD {
            t_prev = t;
            t += r;
            r *= 2.0;
            continue;
        }
        // In air of the carving-free tree (upper >= f), its cheaper bound gives a safe step.
        let step = match scene.upper_field(p) {
            Some(u) if u < THRESHOLD => {
                let reuse = cached
                    .filter(|&(c, rc, _)| norm(sub(p, c)) <= rc)
                    .map(|(_, _, l)| (THRESHOLD - u) / l)
                    .filter(|&s| s < floor);
                match reuse {
                    Some(s) => s,
                    None => {
                        let l = scene
                            .upper_lipschitz(&Aabb::sphere(p, r))
                            .unwrap_or(1e-9)
                            .max(1e-9);
                        cached = Some((p, r, l));
                        (THRESHOLD - u) / l
                    }
                }
            }
            Some(_) if scene.root_max_over(&Aabb::sphere(p, r)) <= THRESHOLD => r,
            _ => {
                let f = scene.field(p);
                if f > THRESHOLD {
                    return Some(if t > t_prev { refine(t_prev, t) } else { t });
                }
                let l = scene.lipschitz(&Aabb::sphere(p, r)).max(1e-9);
                (THRESHOLD - f) / l
            }
        };
        t_prev = t;
        creeping = creep && step < floor && step < r;
        if step >= r {
            t += r;
            r *= 2.0;
        } else {
            // Cone marching: never step less than the pixel footprint (features thinner than
            // a pixel may be skipped, a hit is then refined by bisection).
            let s = step.max(floor);
            t += s;
            r = (2.0 * s).max(4.0 * eps);
        }
    }
    // Out of steps inside the scene: the ray has been creeping along a surface it grazes
    // (the far ground from a low camera, a gap's walls); drawing it as a hit there beats a
    // hole of sky in the ground.
    (t <= t1).then_some(t)
}

/// Checks the image size, the camera and the settings; returns the cut-away plane with a unit
/// normal.
fn check_view(cam: &Camera, s: &RenderSettings) -> Result<Option<(V3, V3)>> {
    if s.width == 0 || s.height == 0 || s.width * s.height > 1 << 26 {
        return Err(Error::param(
            "image size",
            format!("{}x{}", s.width, s.height),
            "must be non-zero and at most 2^26 pixels",
        ));
    }
    if !(crate::math::finite3(cam.eye) && crate::math::finite3(cam.target))
        || norm(sub(cam.target, cam.eye)) <= 0.0
    {
        return Err(Error::param(
            "camera eye/target",
            format!("{:?} -> {:?}", cam.eye, cam.target),
            "must be finite and distinct",
        ));
    }
    let side = cross(sub(cam.target, cam.eye), cam.up);
    if !crate::math::finite3(cam.up) || norm(side) <= 0.0 {
        return Err(Error::param(
            "camera up",
            format!("{:?}", cam.up),
            "must be finite and not parallel to the view direction",
        ));
    }
    if !crate::math::finite3(s.light) || norm(s.light) <= 0.0 {
        return Err(Error::param(
            "light",
            format!("{:?}", s.light),
            "must be finite and non-zero",
        ));
    }
    if let Some(z) = s.sea_level
        && !z.is_finite()
    {
        return Err(Error::param("sea_level", z, "must be finite"));
    }
    let cut = match s.cutaway {
        Some((p, n)) if crate::math::finite3(p) && crate::math::finite3(n) && norm(n) > 0.0 => {
            Some((p, normalize(n)))
        }
        Some((p, n)) => {
            return Err(Error::param(
                "cutaway",
                format!("{p:?}, {n:?}"),
                "must be a finite point and a finite non-zero normal",
            ));
        }
        None => None,
    };
    if !(cam.fov_deg > 0.0 && cam.fov_deg < 179.0) {
        return Err(Error::param("fov_deg", cam.fov_deg, "must be in (0, 179)"));
    }
    Ok(cut)
}

/// Renders the scene (see module docs).
pub fn render(scene: &Scene, cam: &Camera, s: &RenderSettings) -> Result<Image> {
    render_with_progress(scene, cam, s, &relief_heightfield::NoProgress)
}

/// Where a ray from `eye` along `d` starts: with a cut-away plane `(point, normal)`, where it
/// enters the kept side (`None`: it never does), and whether it starts on the cut face: in
/// matter, or under the DEM's closing floor within its footprint (the bedrock goes on below
/// the modelled slab; a cut-away must not show sky under it).
fn ray_start(
    scene: &Scene,
    eye: [f32; 3],
    d: [f32; 3],
    cut: Option<([f32; 3], [f32; 3])>,
) -> (Option<f32>, bool) {
    let Some((cp, cn)) = cut else {
        return (Some(0.0), false);
    };
    let side = dot(sub(eye, cp), cn);
    let dn = dot(d, cn);
    if side <= 0.0 {
        (Some(0.0), false)
    } else if dn < 0.0 {
        let t = side / -dn;
        let q = add(eye, mul(d, t));
        // Under the DEM's closing floor, inside its footprint.
        let under = match (scene.dem_floor(), scene.dem_frame()) {
            (Some(z), Some(f)) => {
                let (xm, ym) = ((f.width - 1) as f32 * f.cx, (f.height - 1) as f32 * f.cy);
                q[2] < z && (0.0..=xm).contains(&q[0]) && (0.0..=ym).contains(&q[1])
            }
            _ => false,
        };
        (Some(t), under || scene.inside(q))
    } else {
        (None, false)
    }
}

/// [`render`] reporting image rows done to `progress` (within the caller's phase: the total
/// is the image height).
pub fn render_with_progress(
    scene: &Scene,
    cam: &Camera,
    s: &RenderSettings,
    progress: &dyn relief_heightfield::Progress,
) -> Result<Image> {
    let cut = check_view(cam, s)?;
    frame::render_frame(scene, cam, s, cut, progress)
}

/// A pixel's ray, for [`water_over`]: the eye, the unit direction, the sky's colour along it,
/// the scene box's diagonal (haze distance) and height range (water clarity).
struct View {
    eye: V3,
    d: V3,
    sky: V3,
    diag: f32,
    relief: f32,
}

/// The colour `col` of a pixel whose ray hits the ground at `hit` (`None`: nothing), seen
/// through a sea at level `sea` when the ray crosses it before the ground.
fn water_over(col: V3, sea: f32, hit: Option<f32>, v: &View) -> V3 {
    let (eye, d) = (v.eye, v.d);
    if d[2] >= 0.0 {
        return col;
    }
    let ts = (sea - eye[2]) / d[2];
    // Ground within SEA_TOLERANCE of the level is under water: a DEM whose sea is stored as a
    // flat surface at the level (SRTM) would otherwise fight with the water plane (speckles)
    // and show its coast as cell-edge steps.
    let te = (sea + SEA_TOLERANCE - eye[2]) / d[2];
    if ts <= 0.0 || hit.is_some_and(|t| t <= te) {
        return col;
    }
    // The ground shows through the water by its depth (a shelf reads as bathymetry, whatever
    // the view's angle).
    let depth = hit.map_or(f32::INFINITY, |t| (sea - (eye[2] + d[2] * t)).max(0.0));
    let clear = (-depth / (WATER_CLARITY * v.relief.max(1e-3))).exp();
    let mut col = add(
        mul(col, 0.2 + 0.35 * clear),
        mul([0.05, 0.2, 0.4], 1.0 - 0.3 * clear),
    );
    // The surface reflects the sky by Fresnel's law (Schlick, water's 2 % at normal incidence,
    // all of it at grazing angles) and fades into the haze with distance where no ground is
    // under it (the ground's colour has its own), so open water reads as sea to the horizon
    // rather than as a flat blue wall.
    let refl = [0.55 + 0.3 * (-d[2]), 0.7 + 0.2 * (-d[2]), 0.95];
    let fresnel = 0.02 + 0.98 * (1.0 + d[2]).clamp(0.0, 1.0).powi(5);
    col = add(mul(col, 1.0 - fresnel), mul(refl, fresnel));
    if hit.is_none() {
        let haze = (ts / (3.0 * v.diag)).min(0.6);
        col = add(mul(col, 1.0 - haze), mul(v.sky, haze));
    }
    col
}

/// Depth of water, as a share of the scene's height range, under which the ground's light
/// falls to `1/e` in [`render`]'s water tint.
pub const WATER_CLARITY: f32 = 0.03;

/// Height above the sea level (scene units, metres) up to which ground is drawn under water:
/// half the 1 m step of integer DEMs, so the coast of a DEM that stores its sea as a flat
/// surface at the level is drawn along the half-metre contour between sea and land samples.
pub const SEA_TOLERANCE: f32 = 0.5;

/// A vertical cut-away section along a horizontal segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SectionSettings {
    /// Start of the segment (scene x, y).
    pub start: [f32; 2],
    /// End of the segment.
    pub end: [f32; 2],
    /// Vertical range; `None` = the scene's box.
    pub z_range: Option<(f32, f32)>,
    /// Width in pixels (along the segment).
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

/// Pixel counts of a section.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct SectionStats {
    /// Matter (coloured by resistance: light = soft, dark = hard).
    pub solid: usize,
    /// Carved voids below the DEM surface (red): caves, karst tunnels, notches.
    pub carved: usize,
    /// Air above the DEM surface.
    pub air: usize,
    /// Carved pixels fully enclosed below the surface (matter above them in their column).
    pub enclosed: usize,
}

/// Vertical section image: solid coloured by resistance, carved voids below the DEM surface in
/// red, air in blue. Shows karst tunnels.
pub fn section(scene: &Scene, s: &SectionSettings) -> Result<(Image, SectionStats)> {
    if s.width == 0 || s.height == 0 || s.width * s.height > 1 << 26 {
        return Err(Error::param(
            "image size",
            format!("{}x{}", s.width, s.height),
            "must be non-zero and at most 2^26 pixels",
        ));
    }
    let b = scene.bbox();
    if !s.start.iter().chain(&s.end).all(|v| v.is_finite()) {
        return Err(Error::param(
            "start/end",
            format!("{:?} -> {:?}", s.start, s.end),
            "must be finite",
        ));
    }
    let (z0, z1) = s.z_range.unwrap_or((b.min[2], b.max[2]));
    if !(z0.is_finite() && z1.is_finite()) || z0 >= z1 {
        return Err(Error::param(
            "z_range",
            format!("{z0}..{z1}"),
            "must be finite and increasing",
        ));
    }
    let cols: Vec<(Vec<u8>, SectionStats)> = (0..s.width)
        .into_par_iter()
        .map(|x| {
            let t = (x as f32 + 0.5) / s.width as f32;
            let px = s.start[0] + t * (s.end[0] - s.start[0]);
            let py = s.start[1] + t * (s.end[1] - s.start[1]);
            let ground = scene.dem_height(px, py);
            let floor = scene.dem_floor().unwrap_or(f32::NEG_INFINITY);
            let mut col = vec![0u8; s.height * 3];
            let mut st = SectionStats::default();
            let mut matter_above = false;
            for y in 0..s.height {
                let z = z1 - (y as f32 + 0.5) / s.height as f32 * (z1 - z0);
                let p = [px, py, z];
                let c: V3 = if scene.inside(p) {
                    matter_above = true;
                    st.solid += 1;
                    let r = scene.resistance(p);
                    [0.85 - 0.5 * r, 0.75 - 0.45 * r, 0.55 - 0.35 * r]
                } else if z > floor && ground.is_some_and(|g| z < g) {
                    st.carved += 1;
                    if matter_above {
                        st.enclosed += 1;
                    }
                    [0.85, 0.1, 0.1]
                } else {
                    st.air += 1;
                    [0.6, 0.75, 0.95]
                };
                for k in 0..3 {
                    col[y * 3 + k] = material::to_byte(c[k]);
                }
            }
            (col, st)
        })
        .collect();
    let mut rgb = vec![0u8; s.width * s.height * 3];
    let mut st = SectionStats::default();
    for (x, (col, cs)) in cols.iter().enumerate() {
        for y in 0..s.height {
            rgb[(y * s.width + x) * 3..(y * s.width + x) * 3 + 3]
                .copy_from_slice(&col[y * 3..y * 3 + 3]);
        }
        st.solid += cs.solid;
        st.carved += cs.carved;
        st.air += cs.air;
        st.enclosed += cs.enclosed;
    }
    Ok((
        Image {
            width: s.width,
            height: s.height,
            rgb,
        },
        st,
    ))
}

#[cfg(test)]
mod sea_cave_sections {
    //! Sections through the sea caves of `scene::SceneBuilder::sea_erosion` (here, not in the
    //! scene's tests: the scene does not depend on the renderer).
    use super::{SectionSettings, section};
    use crate::geology::test_beds;
    use crate::scene::{ImplicitizeSettings, Region, SceneBuilder, SeaErosion, Weathering};
    use relief_heightfield::Heightfield;

    /// A 20 m cliff rising out of the sea (x > 30 m) in strata of 6 m soft (0.15) under 4 m
    /// resistant (0.85) rock, the waterline in soft rock: sea caves open at the waterline in
    /// soft rock and run inland under a roof, so vertical sections along and across them show
    /// carved air with rock over it (enclosed), not trenches open to the sky.
    #[test]
    fn sea_caves_are_enclosed_voids_in_soft_rock_at_the_waterline() {
        let hf = Heightfield::from_fn(48, 32, 2.0, 2.0, |x, _| {
            if x < 15 {
                -4.0
            } else {
                20.0f32.min(-4.0 + 12.0 * (x - 14) as f32)
            }
        });
        let g = test_beds(-3.0, (6.0, 0.15), (4.0, 0.85));
        let mut b = SceneBuilder::new(&hf, g.clone(), &ImplicitizeSettings::default()).unwrap();
        let s = SeaErosion {
            weathering: Weathering {
                spacing: 1.5,
                radius: 3.0,
                energy: 3.0,
                ..Default::default()
            },
            height: 8.0,
            peak: 2.0,
            reach: 20.0,
            caves: 2,
            cave_length: 24.0,
            ..Default::default()
        };
        let rep = b.sea_erosion(&s, &Region::everywhere()).unwrap();
        assert!(rep.features >= 1, "{rep:?}");
        let scene = b.build(true).unwrap();
        for (mouth, out) in rep.sites.iter().zip(&rep.axes) {
            assert!(g.resistance(*mouth) < 0.5, "mouth in soft rock: {mouth:?}");
            assert!(
                (0.0..=4.0).contains(&mouth[2]),
                "at the waterline: {mouth:?}"
            );
            assert!(out[0] < -0.5, "the mouth faces the sea: {out:?}");
            let cut = |start: [f32; 2], end: [f32; 2]| {
                let st = SectionSettings {
                    start,
                    end,
                    z_range: Some((-8.0, 24.0)),
                    width: 160,
                    height: 128,
                };
                section(&scene, &st).unwrap().1
            };
            // Along the cave (west-east through the mouth) and across it 8 m inland.
            let along = cut([0.0, mouth[1]], [94.0, mouth[1]]);
            let across = cut([mouth[0] + 8.0, 0.0], [mouth[0] + 8.0, 62.0]);
            assert!(
                along.enclosed > 0 && across.enclosed > 0,
                "{along:?} {across:?}"
            );
        }
    }
}

#[cfg(test)]
mod grazing {
    use super::trace;
    use crate::geology::test_beds;
    use crate::scene::{ImplicitizeSettings, SceneBuilder};
    use relief_heightfield::Heightfield;

    /// A ray leaving flat ground at 0.3 degrees creeps along it at the pixel-footprint step
    /// and runs out of steps long before the scene's edge; it must come out as sky, not as a
    /// hit in mid-air (with the steps given up as a hit, it stopped 13 m on, 0.4 m over
    /// the ground: speckles above a render's skyline). A ray aimed into the ground still hits.
    #[test]
    fn a_ray_grazing_the_ground_reaches_the_sky() {
        let hf = Heightfield::from_fn(64, 16, 4.0, 4.0, |_, _| 0.0);
        let g = test_beds(-50.0, (6.0, 0.2), (4.0, 0.8));
        let scene = SceneBuilder::new(&hf, g, &ImplicitizeSettings::default())
            .unwrap()
            .build(true)
            .unwrap();
        let z0 = scene.dem_height(8.0, 32.0).unwrap();
        let a = 0.3f32.to_radians();
        let o = [8.0, 32.0, z0 + 0.3];
        let up = [a.cos(), 0.0, a.sin()];
        assert_eq!(trace(&scene, o, up, 1e30, 40, 0.01, 0.0, true), None);
        let down = [a.cos(), 0.0, -(2.0 * a).sin()];
        let t = trace(&scene, o, down, 1e30, 40, 0.01, 0.0, true).expect("hits the ground");
        assert!((t * (2.0 * a).sin() - 0.3).abs() < 0.15, "hit at {t} m");
    }
}
