//! Beam pre-pass of the primary rays: one cone traced for a block of pixels proves the space
//! in front of all of them empty, so each pixel's own trace starts where its block's beam
//! stopped instead of at the eye (the empty-space and far-from-surface steps are shared by
//! the block's rays; the near-surface steps stay per pixel, so every hit is still found by
//! the pixel's own sphere tracing).

use rayon::prelude::*;

use crate::math::{Aabb, V3, add, cross, dot, mul, norm, normalize, sub};
use crate::scene::Scene;
use crate::tree::THRESHOLD;

/// The pinhole's ray directions: `fwd + u right + v up` for a pixel's centre, with `u` and `v`
/// the image-plane coordinates of [`Pinhole::uv`].
#[derive(Debug, Clone, Copy)]
pub(super) struct Pinhole {
    pub eye: V3,
    pub fwd: V3,
    pub right: V3,
    pub up: V3,
    /// `tan(fov / 2)`.
    pub th: f32,
    pub width: usize,
    pub height: usize,
}

impl Pinhole {
    /// The pinhole of `cam` for an image of `width` x `height` pixels.
    pub(super) fn new(cam: &super::Camera, width: usize, height: usize) -> Self {
        let fwd = normalize(sub(cam.target, cam.eye));
        let right = normalize(cross(fwd, cam.up));
        Self {
            eye: cam.eye,
            fwd,
            right,
            up: cross(right, fwd),
            th: (0.5 * cam.fov_deg.to_radians()).tan(),
            width,
            height,
        }
    }
    /// Image-plane coordinates of the point `(x, y)` in pixels (pixel centres at `+ 0.5`).
    fn uv(&self, x: f32, y: f32) -> (f32, f32) {
        let aspect = self.width as f32 / self.height as f32;
        (
            (x / self.width as f32 * 2.0 - 1.0) * self.th * aspect,
            (1.0 - y / self.height as f32 * 2.0) * self.th,
        )
    }
    /// Unit direction through the point `(x, y)` of the image (in pixels).
    pub(super) fn dir(&self, x: f32, y: f32) -> V3 {
        let (u, v) = self.uv(x, y);
        normalize(add(self.fwd, add(mul(self.right, u), mul(self.up, v))))
    }
    /// The unit axis of the pixels `x0..x1` x `y0..y1` (half-open) and the largest angle
    /// (radians) between it and any ray through them (their whole area, not only their
    /// centres: the anti-aliasing samples start where the beam stopped too).
    fn cone(&self, x0: usize, x1: usize, y0: usize, y1: usize) -> (V3, f32) {
        let (xa, xb) = (x0 as f32, x1 as f32);
        let (ya, yb) = (y0 as f32, y1 as f32);
        let axis = self.dir(0.5 * (xa + xb), 0.5 * (ya + yb));
        // The pixels fill a rectangle of the image plane, so the widest angle is at a corner;
        // 1 % and a micro-radian of slack for rounding.
        let widest = [(xa, ya), (xb, ya), (xa, yb), (xb, yb)]
            .into_iter()
            .map(|(x, y)| dot(axis, self.dir(x, y)).clamp(-1.0, 1.0).acos())
            .fold(0.0f32, f32::max);
        (axis, widest * 1.01 + 1e-6)
    }
}

/// Pixels per side of the coarse and the fine beam blocks.
pub(super) const COARSE: usize = 16;
pub(super) const FINE: usize = 4;

/// Where the primary ray of each `FINE` x `FINE` block of pixels may start: a distance from the
/// eye before which every ray of the block is proven in air (row-major over the blocks,
/// `ceil(width / FINE)` per row). Beams of `COARSE` blocks first, then their `FINE` blocks
/// from where the coarse beam stopped. The same values for any thread count.
pub(super) fn starts(scene: &Scene, cam: &Pinhole, max_steps: u32) -> Vec<f32> {
    let (bw, bh) = (cam.width.div_ceil(FINE), cam.height.div_ceil(FINE));
    let per = COARSE / FINE;
    let (cw, ch) = (cam.width.div_ceil(COARSE), cam.height.div_ceil(COARSE));
    let tiles: Vec<Vec<(usize, f32)>> = (0..cw * ch)
        .into_par_iter()
        .map(|k| {
            let (tx, ty) = (k % cw, k / cw);
            let (x0, y0) = (tx * COARSE, ty * COARSE);
            let (x1, y1) = ((x0 + COARSE).min(cam.width), (y0 + COARSE).min(cam.height));
            let (axis, a) = cam.cone(x0, x1, y0, y1);
            let tc = beam(scene, cam.eye, axis, a, 0.0, max_steps);
            let mut out = Vec::with_capacity(per * per);
            for by in ty * per..((ty + 1) * per).min(bh) {
                for bx in tx * per..((tx + 1) * per).min(bw) {
                    let (fx0, fy0) = (bx * FINE, by * FINE);
                    let (fx1, fy1) = ((fx0 + FINE).min(cam.width), (fy0 + FINE).min(cam.height));
                    let (axis, a) = cam.cone(fx0, fx1, fy0, fy1);
                    out.push((by * bw + bx, beam(scene, cam.eye, axis, a, tc, max_steps)));
                }
            }
            out
        })
        .collect();
    let mut t = vec![0.0f32; bw * bh];
    for (k, v) in tiles.into_iter().flatten() {
        t[k] = v;
    }
    t
}

/// Traces a cone from `o` around the unit `axis` with half-angle `a` (radians), from the
/// distance `t_start` (already proven empty), and returns a distance up to which every ray
/// inside the cone is proven in air. A ray at angle `<= a` from the axis is, at parameter
/// `t`, within `a t` of the axis point at `t`, so a step `s` is safe for all of them when the
/// ball of radius `s + a (t + s)` around the axis point holds no matter (interval bound) or
/// when the field's distance bound there exceeds it (Lipschitz bound). Stops where the cone
/// gets as wide as the distance to the surface.
fn beam(scene: &Scene, o: V3, axis: V3, a: f32, t_start: f32, max_steps: u32) -> f32 {
    let b = scene.bbox();
    let diag = norm(b.size());
    // Beyond the farthest corner of the scene box from `o`, every ray is outside the box.
    let far = b.max_dist_sq_to_segment(o, o).sqrt();
    let mut t = t_start;
    let mut r = 0.02 * diag;
    let min_step = 1e-5 * diag;
    for _ in 0..max_steps {
        if t >= far {
            return far;
        }
        let p = add(o, mul(axis, t));
        let widen = a * t;
        let ball = |s: f32| Aabb::sphere(p, s + a * (t + s));
        let reach = ball(r);
        if !reach.intersects(&b) || scene.max_over(&reach) <= THRESHOLD {
            t += r;
            r *= 2.0;
            continue;
        }
        // Distance from `p` to the nearest matter, bounded within the ball `reach`.
        let dist = match scene.upper_field(p) {
            Some(u) if u < THRESHOLD => {
                (THRESHOLD - u) / scene.upper_lipschitz(&reach).unwrap_or(1e-9).max(1e-9)
            }
            Some(_) if scene.root_max_over(&reach) <= THRESHOLD => f32::INFINITY,
            _ => {
                let f = scene.field(p);
                if f > THRESHOLD {
                    break;
                }
                (THRESHOLD - f) / scene.lipschitz(&reach).max(1e-9)
            }
        };
        // Every ray point of the next step lies within `s + a (t + s)` of `p`, and the
        // distance bound holds within `reach` (radius `r + a (t + r)`).
        let s = ((dist.min(r + a * (t + r)) - widen) / (1.0 + a)).min(r);
        // Advance while the steps are worth a cone's width; else shrink the ball (a smaller
        // one holds fewer primitives, so its bounds are tighter) down to the cone's width.
        let r_min = (2.0 * widen).max(min_step);
        if s >= 0.5 * r || s > widen.max(min_step) {
            t += s;
            r = if s >= r {
                2.0 * r
            } else {
                (2.0 * s).max(r_min)
            };
        } else if r > r_min {
            r = (0.25 * r).max(r_min);
        } else {
            break;
        }
    }
    t.min(far)
}
