//! Small vector helpers, axis-aligned boxes, counter-based hashing and value noise.
//!
//! Everything random in this crate is derived from [`hash`] of a seed and integer counters, so
//! results never depend on thread scheduling.

/// A point or vector in metres: `[x (east), y (north), z (up)]`.
pub type V3 = [f32; 3];

#[inline]
pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline]
pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
pub(crate) fn mul(a: V3, s: f32) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline]
pub(crate) fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline]
pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline]
pub(crate) fn norm(a: V3) -> f32 {
    dot(a, a).sqrt()
}
#[inline]
pub(crate) fn normalize(a: V3) -> V3 {
    let n = norm(a);
    if n > 0.0 {
        mul(a, 1.0 / n)
    } else {
        [0.0, 0.0, 1.0]
    }
}
#[inline]
pub(crate) fn finite3(a: V3) -> bool {
    a.iter().all(|v| v.is_finite())
}

/// An axis-aligned box `[min, max]` in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: V3,
    /// Upper corner.
    pub max: V3,
}

impl Aabb {
    /// Box from two corners (reordered per axis).
    pub fn new(a: V3, b: V3) -> Self {
        Self {
            min: [a[0].min(b[0]), a[1].min(b[1]), a[2].min(b[2])],
            max: [a[0].max(b[0]), a[1].max(b[1]), a[2].max(b[2])],
        }
    }
    /// The empty box (union identity).
    pub fn empty() -> Self {
        Self {
            min: [f32::INFINITY; 3],
            max: [f32::NEG_INFINITY; 3],
        }
    }
    /// Box of a sphere.
    pub fn sphere(c: V3, r: f32) -> Self {
        Self {
            min: [c[0] - r, c[1] - r, c[2] - r],
            max: [c[0] + r, c[1] + r, c[2] + r],
        }
    }
    /// Smallest box holding both.
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: zip3(self.min, o.min, f32::min),
            max: zip3(self.max, o.max, f32::max),
        }
    }
    /// Overlap of both (may be empty).
    pub fn intersection(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: zip3(self.min, o.min, f32::max),
            max: zip3(self.max, o.max, f32::min),
        }
    }
    /// Box grown by `d` on every side.
    pub fn inflate(&self, d: f32) -> Aabb {
        Aabb {
            min: [self.min[0] - d, self.min[1] - d, self.min[2] - d],
            max: [self.max[0] + d, self.max[1] + d, self.max[2] + d],
        }
    }
    /// Whether the box holds no point.
    pub fn is_empty(&self) -> bool {
        (0..3).any(|k| self.min[k] > self.max[k])
    }
    /// Whether `p` lies inside (boundary included).
    #[inline]
    pub fn contains(&self, p: V3) -> bool {
        p[0] >= self.min[0]
            && p[0] <= self.max[0]
            && p[1] >= self.min[1]
            && p[1] <= self.max[1]
            && p[2] >= self.min[2]
            && p[2] <= self.max[2]
    }
    /// Whether the two boxes overlap.
    #[inline]
    pub fn intersects(&self, o: &Aabb) -> bool {
        (0..3).all(|k| self.min[k] <= o.max[k] && o.min[k] <= self.max[k])
    }
    /// Centre point.
    pub fn center(&self) -> V3 {
        mul(add(self.min, self.max), 0.5)
    }
    /// Edge lengths.
    pub fn size(&self) -> V3 {
        sub(self.max, self.min)
    }
    /// Squared distance between two boxes (0 when they overlap).
    pub fn dist_sq_box(&self, o: &Aabb) -> f32 {
        let mut d = 0.0;
        for k in 0..3 {
            let v = (self.min[k] - o.max[k])
                .max(0.0)
                .max(o.min[k] - self.max[k]);
            d += v * v;
        }
        d
    }
    /// Largest squared distance from a point of the box to the segment `a`-`b` (reached at a
    /// corner: the distance to a segment is convex).
    pub fn max_dist_sq_to_segment(&self, a: V3, b: V3) -> f32 {
        self.max_dist_sq_to_segment_until(a, b, f32::INFINITY)
    }
    /// [`Self::max_dist_sq_to_segment`], or the first corner's squared distance `d` with
    /// `d / r2 >= 1` (a falloff of `d / r2` is then 0 whatever the larger corners give).
    pub fn max_dist_sq_to_segment_until(&self, a: V3, b: V3, r2: f32) -> f32 {
        let ab = sub(b, a);
        let len2 = dot(ab, ab);
        let mut m = 0.0f32;
        for c in 0..8 {
            let p = [
                if c & 1 == 0 { self.min[0] } else { self.max[0] },
                if c & 2 == 0 { self.min[1] } else { self.max[1] },
                if c & 4 == 0 { self.min[2] } else { self.max[2] },
            ];
            let ap = sub(p, a);
            let t = if len2 > 0.0 {
                (dot(ap, ab) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let d = sub(ap, mul(ab, t));
            m = m.max(dot(d, d));
            if m / r2 >= 1.0 {
                return m;
            }
        }
        m
    }
    /// Squared distance from `p` to the box (0 inside).
    #[inline]
    pub fn dist_sq(&self, p: V3) -> f32 {
        let mut d = 0.0;
        for k in 0..3 {
            let v = (self.min[k] - p[k]).max(0.0).max(p[k] - self.max[k]);
            d += v * v;
        }
        d
    }
    pub(crate) fn is_finite(&self) -> bool {
        finite3(self.min) && finite3(self.max)
    }
}

/// Counter-based random source of a work item (`seed` and three counters) and its uniform
/// `[0, 1)` value: the workspace's one implementation in [`relief_heightfield::rng`].
pub use relief_heightfield::rng::{hash, unit_f32 as unit};

/// `[f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2])]`.
#[inline]
fn zip3(a: V3, b: V3, f: impl Fn(f32, f32) -> f32) -> V3 {
    [f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2])]
}

#[inline]
fn lattice(seed: u64, x: i32, y: i32, z: i32) -> f32 {
    unit(hash(
        seed,
        x as u32 as u64,
        y as u32 as u64,
        z as u32 as u64,
    )) * 2.0
        - 1.0
}

#[inline]
fn fade(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// Trilinear value noise with smoothstep fade, values in `[-1, 1]`, lattice spacing 1.
pub fn value_noise(seed: u64, p: V3) -> f32 {
    let (fx, fy, fz) = (p[0].floor(), p[1].floor(), p[2].floor());
    let (x, y, z) = (fx as i32, fy as i32, fz as i32);
    let (tx, ty, tz) = (fade(p[0] - fx), fade(p[1] - fy), fade(p[2] - fz));
    let l = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let c00 = l(lattice(seed, x, y, z), lattice(seed, x + 1, y, z), tx);
    let c10 = l(
        lattice(seed, x, y + 1, z),
        lattice(seed, x + 1, y + 1, z),
        tx,
    );
    let c01 = l(
        lattice(seed, x, y, z + 1),
        lattice(seed, x + 1, y, z + 1),
        tx,
    );
    let c11 = l(
        lattice(seed, x, y + 1, z + 1),
        lattice(seed, x + 1, y + 1, z + 1),
        tx,
    );
    l(l(c00, c10, ty), l(c01, c11, ty), tz)
}

/// Lipschitz bound of [`value_noise`]: the smoothstep slope is at most 1.5 and lattice values
/// differ by at most 2, so each partial derivative is at most 3 and the gradient norm 3 sqrt(3).
pub const VALUE_NOISE_LIPSCHITZ: f32 = 5.2;

/// Fractal sum of `octaves` value-noise octaves (gain 1/2, lacunarity 2), roughly in `[-1, 1]`.
pub fn fbm(seed: u64, p: V3, octaves: u32) -> f32 {
    let mut s = 0.0;
    let mut a = 0.5;
    let mut f = 1.0;
    for o in 0..octaves.max(1) {
        s += a * value_noise(seed.wrapping_add(o as u64 * 7919), mul(p, f));
        a *= 0.5;
        f *= 2.0;
    }
    s
}

/// Lipschitz bound of [`fbm`] at unit frequency: sum of 0.5^o * 2^o = octaves times 0.5.
pub fn fbm_lipschitz(octaves: u32) -> f32 {
    0.5 * octaves.max(1) as f32 * VALUE_NOISE_LIPSCHITZ
}

/// A 3-vector of independent [`fbm`] values (for warps).
pub fn fbm3(seed: u64, p: V3, octaves: u32) -> V3 {
    // The three fbm of seeds `seed`, `seed ^ 0x5555_5555` and `seed ^ 0xAAAA_AAAA_0000`,
    // octave by octave with one lattice walk for the three (bit for bit the same sums).
    let base = [seed, seed ^ 0x5555_5555, seed ^ 0xAAAA_AAAA_0000];
    let mut s = [0.0f32; 3];
    let mut a = 0.5;
    let mut f = 1.0;
    for o in 0..octaves.max(1) {
        let seeds = base.map(|b| b.wrapping_add(o as u64 * 7919));
        let v = value_noise3(seeds, mul(p, f));
        for k in 0..3 {
            s[k] += a * v[k];
        }
        a *= 0.5;
        f *= 2.0;
    }
    s
}

/// [`value_noise`] of three seeds at one point: the floors, fades and lattice products are
/// shared, so it costs little more than one (bit for bit the same values).
pub fn value_noise3(seeds: [u64; 3], p: V3) -> V3 {
    use relief_heightfield::rng::mix64;
    let (fx, fy, fz) = (p[0].floor(), p[1].floor(), p[2].floor());
    let (x, y, z) = (fx as i32, fy as i32, fz as i32);
    let (tx, ty, tz) = (fade(p[0] - fx), fade(p[1] - fy), fade(p[2] - fz));
    // `hash(seed, x, y, z)` is `mix64(seed ^ x K1 ^ y K2 ^ z K3)`.
    let kx = |x: i32| (x as u32 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let ky = |y: i32| (y as u32 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    let kz = |z: i32| (z as u32 as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    let (x0, x1, y0, y1, z0, z1) = (kx(x), kx(x + 1), ky(y), ky(y + 1), kz(z), kz(z + 1));
    let l = |a: f32, b: f32, t: f32| a + (b - a) * t;
    seeds.map(|seed| {
        let lat = |m: u64| unit(mix64(seed ^ m)) * 2.0 - 1.0;
        let c00 = l(lat(x0 ^ y0 ^ z0), lat(x1 ^ y0 ^ z0), tx);
        let c10 = l(lat(x0 ^ y1 ^ z0), lat(x1 ^ y1 ^ z0), tx);
        let c01 = l(lat(x0 ^ y0 ^ z1), lat(x1 ^ y0 ^ z1), tx);
        let c11 = l(lat(x0 ^ y1 ^ z1), lat(x1 ^ y1 ^ z1), tx);
        l(l(c00, c10, ty), l(c01, c11, ty), tz)
    })
}

/// Visible radius of a primitive of support radius 1 at energy 1: where [`falloff`] meets
/// the threshold, `(1 - q)^3 = 0.5`, `sqrt(q) = sqrt(1 - 0.5^(1/3))` = 0.4542 (0.4544 is
/// the value the shapes were sized with; the hoodoo, arch, island and close-up code share it).
pub const VISIBLE: f32 = 0.454_4;

/// The compact-support cubic falloff of the paper's reference implementation:
/// `g(d^2) = (1 - d^2 / R^2)^3` for `d < R`, 0 beyond. Takes `q = d^2 / R^2`.
#[inline]
pub fn falloff(q: f32) -> f32 {
    if q >= 1.0 {
        0.0
    } else {
        let t = 1.0 - q;
        t * t * t
    }
}

/// Maximum slope of `d -> (1 - d^2/R^2)^3` is `1.7173 / R` (at `d = R / sqrt(5)`).
pub const FALLOFF_LIPSCHITZ: f32 = 1.7174;

/// Odd cubic step `s(x) = 1.5 x - 0.5 x^3` on `[-1, 1]`, clamped to -1 / 1 outside; slope <= 1.5.
#[inline]
pub fn cubic_step(x: f32) -> f32 {
    let x = x.clamp(-1.0, 1.0);
    1.5 * x - 0.5 * x * x * x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shared-lattice noise gives bit for bit what three separate fbm give.
    #[test]
    fn fbm3_equals_three_fbm_bit_for_bit() {
        for k in 0..2000u64 {
            let r = |s| (unit(hash(3, k, s, 0)) - 0.5) * 200.0;
            let p = [r(0), r(1), r(2)];
            let seed = hash(4, k, 0, 0);
            let octaves = 1 + (k % 3) as u32;
            let want = [
                fbm(seed, p, octaves),
                fbm(seed ^ 0x5555_5555, p, octaves),
                fbm(seed ^ 0xAAAA_AAAA_0000, p, octaves),
            ];
            let got = fbm3(seed, p, octaves);
            assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "{p:?}");
        }
    }
}
