//! Procedural noises and the function atoms built on them (guerin2016 section 5.2, figure 4;
//! ridged noise after Ebert, Musgrave et al. [EMP*98]).
//!
//! Everything here is portable: the gradient permutation comes from a seeded PCG shuffle, the
//! arithmetic is plain `f64`, so the same seed gives the same values on every platform.

use std::sync::Arc;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use relief_sparse_core::{AtomDescriptor, FunctionAtom, FunctionAtomRegistry, SparseError};

/// Counter-based 64-bit hash (SplitMix64) used to derive per-item seeds: the workspace's one
/// implementation, [`relief_heightfield::rng::splitmix64`].
pub use relief_heightfield::rng::splitmix64 as hash64;

/// Seed of work item `item` of stream `stream` under the user seed `seed`.
pub fn item_seed(seed: u64, stream: u64, item: u64) -> u64 {
    hash64(hash64(seed ^ hash64(stream)) ^ item)
}

/// 2-D gradient (Perlin) noise with a seeded permutation; values roughly in `[-1, 1]`.
#[derive(Debug, Clone)]
pub struct Perlin {
    perm: [u8; 512],
}

const GRADS: [[f64; 2]; 8] = [
    [1.0, 0.0],
    [-1.0, 0.0],
    [0.0, 1.0],
    [0.0, -1.0],
    [
        std::f64::consts::FRAC_1_SQRT_2,
        std::f64::consts::FRAC_1_SQRT_2,
    ],
    [
        -std::f64::consts::FRAC_1_SQRT_2,
        std::f64::consts::FRAC_1_SQRT_2,
    ],
    [
        std::f64::consts::FRAC_1_SQRT_2,
        -std::f64::consts::FRAC_1_SQRT_2,
    ],
    [
        -std::f64::consts::FRAC_1_SQRT_2,
        -std::f64::consts::FRAC_1_SQRT_2,
    ],
];

impl Perlin {
    /// Noise whose permutation table is shuffled by a PCG seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        let mut p: Vec<u8> = (0..=255u8).collect();
        let mut rng = Pcg64Mcg::seed_from_u64(hash64(seed));
        p.shuffle(&mut rng);
        let mut perm = [0u8; 512];
        for i in 0..512 {
            perm[i] = p[i & 255];
        }
        Self { perm }
    }

    #[inline]
    fn grad(&self, xi: i64, yi: i64, dx: f64, dy: f64) -> f64 {
        let h = self.perm[(self.perm[(xi & 255) as usize] as usize + (yi & 255) as usize) & 511];
        let g = GRADS[(h & 7) as usize];
        g[0] * dx + g[1] * dy
    }

    /// Noise value at `(x, y)`; zero at integer lattice points, C^2 (quintic fade).
    pub fn noise(&self, x: f64, y: f64) -> f64 {
        let (xf, yf) = (x.floor(), y.floor());
        let (xi, yi) = (xf as i64, yf as i64);
        let (dx, dy) = (x - xf, y - yf);
        let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
        let (u, v) = (fade(dx), fade(dy));
        let n00 = self.grad(xi, yi, dx, dy);
        let n10 = self.grad(xi.wrapping_add(1), yi, dx - 1.0, dy);
        let n01 = self.grad(xi, yi.wrapping_add(1), dx, dy - 1.0);
        let n11 = self.grad(xi.wrapping_add(1), yi.wrapping_add(1), dx - 1.0, dy - 1.0);
        let a = n00 + u * (n10 - n00);
        let b = n01 + u * (n11 - n01);
        (a + v * (b - a)) * std::f64::consts::SQRT_2
    }

    /// Ridged noise `(1 - |n|)^2` in `[0, 1]` ([EMP*98]): sharp crests where `n` crosses 0.
    pub fn ridged(&self, x: f64, y: f64) -> f64 {
        let r = 1.0 - self.noise(x, y).abs();
        r * r
    }

    /// Fractional Brownian motion: `octaves` octaves of gradient noise, lacunarity 2, gain 0.5.
    pub fn fbm(&self, x: f64, y: f64, octaves: u32) -> f64 {
        let (mut f, mut a, mut s) = (1.0, 1.0, 0.0);
        for o in 0..octaves {
            s += a * self.noise(x * f + 17.3 * o as f64, y * f + 5.9 * o as f64);
            f *= 2.0;
            a *= 0.5;
        }
        s
    }

    /// Musgrave's ridged multifractal ([EMP*98] ch. 16): each octave is weighted by the
    /// previous one, so crests get finer detail than valleys.
    pub fn ridged_multifractal(
        &self,
        x: f64,
        y: f64,
        octaves: u32,
        lacunarity: f64,
        gain: f64,
    ) -> f64 {
        let offset = 1.0;
        let mut signal = offset - self.noise(x, y).abs();
        signal *= signal;
        let mut result = signal;
        let mut freq = 1.0;
        let mut amp = 1.0;
        for o in 1..octaves {
            freq *= lacunarity;
            amp *= lacunarity.powf(-1.0);
            let weight = (signal * gain).clamp(0.0, 1.0);
            signal = offset
                - self
                    .noise(x * freq + 11.1 * o as f64, y * freq + 3.7 * o as f64)
                    .abs();
            signal = signal * signal * weight;
            result += signal * amp;
        }
        result
    }
}

fn rotate(u: f64, v: f64, angle: f64) -> (f64, f64) {
    let (s, c) = angle.sin_cos();
    (c * u - s * v, s * u + c * v)
}

fn check_params(kind: &'static str, params: &[f64], n: usize) -> relief_sparse_core::Result<()> {
    if params.len() != n {
        return Err(SparseError::param(
            kind,
            params.len(),
            "wrong number of parameters",
        ));
    }
    if params.iter().any(|p| !p.is_finite()) {
        return Err(SparseError::param(kind, "NaN", "parameters must be finite"));
    }
    Ok(())
}

/// [`check_params`] for a fixed count, returning the parameters as an array.
fn param_array<const N: usize>(
    kind: &'static str,
    params: &[f64],
) -> relief_sparse_core::Result<[f64; N]> {
    check_params(kind, params, N)?;
    let mut out = [0.0; N];
    out.copy_from_slice(params);
    Ok(out)
}

/// Kind name of [`PerlinAtom`].
pub const PERLIN_KIND: &str = "perlin";
/// Kind name of [`RidgedMultifractalAtom`].
pub const RIDGED_MULTIFRACTAL_KIND: &str = "ridged_multifractal";
/// Kind name of [`RidgedSumAtom`].
pub const RIDGED_SUM_KIND: &str = "ridged_sum";

/// A Perlin (fBm) atom: `fbm(R(angle) (u, v) frequency + offset)`.
/// Parameters: `[seed, frequency, octaves, offset_x, offset_y, angle]`.
#[derive(Debug, Clone)]
pub struct PerlinAtom {
    params: [f64; 6],
    noise: Perlin,
}

impl PerlinAtom {
    /// Builds the atom from its 6 parameters (see the type docs).
    pub fn from_params(p: &[f64]) -> relief_sparse_core::Result<Self> {
        let params: [f64; 6] = param_array(PERLIN_KIND, p)?;
        if p[1] <= 0.0 || !(1.0..=12.0).contains(&p[2]) {
            return Err(SparseError::param(
                "perlin frequency/octaves",
                p[1],
                "frequency > 0, octaves in 1..=12",
            ));
        }
        Ok(Self {
            noise: Perlin::new(p[0] as u64),
            params,
        })
    }
}

impl FunctionAtom for PerlinAtom {
    fn eval(&self, u: f64, v: f64) -> f64 {
        let p = &self.params;
        let (x, y) = rotate(u, v, p[5]);
        self.noise
            .fbm(x * p[1] + p[3], y * p[1] + p[4], p[2] as u32)
    }
    fn descriptor(&self) -> AtomDescriptor {
        AtomDescriptor {
            kind: PERLIN_KIND.into(),
            params: self.params.to_vec(),
        }
    }
    /// Seed, frequency and octaves describe the field; offset and angle the window.
    fn field_params(&self) -> usize {
        3
    }
}

/// A ridged multifractal atom.
/// Parameters: `[seed, frequency, octaves, lacunarity, gain, offset_x, offset_y, angle]`.
#[derive(Debug, Clone)]
pub struct RidgedMultifractalAtom {
    params: [f64; 8],
    noise: Perlin,
}

impl RidgedMultifractalAtom {
    /// Builds the atom from its 8 parameters (see the type docs).
    pub fn from_params(p: &[f64]) -> relief_sparse_core::Result<Self> {
        let params: [f64; 8] = param_array(RIDGED_MULTIFRACTAL_KIND, p)?;
        if p[1] <= 0.0 || !(1.0..=12.0).contains(&p[2]) || p[3] <= 1.0 || p[4] <= 0.0 {
            return Err(SparseError::param(
                "ridged_multifractal parameters",
                format!("{p:?}"),
                "frequency > 0, octaves in 1..=12, lacunarity > 1, gain > 0",
            ));
        }
        Ok(Self {
            noise: Perlin::new(p[0] as u64),
            params,
        })
    }
}

impl FunctionAtom for RidgedMultifractalAtom {
    fn eval(&self, u: f64, v: f64) -> f64 {
        let p = &self.params;
        let (x, y) = rotate(u, v, p[7]);
        self.noise
            .ridged_multifractal(x * p[1] + p[5], y * p[1] + p[6], p[2] as u32, p[3], p[4])
    }
    fn descriptor(&self) -> AtomDescriptor {
        AtomDescriptor {
            kind: RIDGED_MULTIFRACTAL_KIND.into(),
            params: self.params.to_vec(),
        }
    }
    /// Seed, frequency, octaves, lacunarity and gain describe the field; offset and angle
    /// the window.
    fn field_params(&self) -> usize {
        5
    }
}

/// Number of coefficients of a [`RidgedSumAtom`] (figure 4: `K = 2 x 8 = 16`).
pub const RIDGED_SUM_TERMS: usize = 16;
const RIDGED_SUM_LACUNARITY: f64 = 1.5;

/// The paper's analytic atom (figure 4): a parametrised sum of ridged noise functions,
/// `sum_{f<2, o<8} c_{f,o} ridged(R(angle) (u, v) base lambda^o + offset_f)`, i.e. two ridged
/// noise fields (different lattice offsets) at 8 frequencies `base * 1.5^o`; the 16
/// coefficients `c` are the atom's coordinates in that function space.
/// Parameters: `[seed, base_frequency, angle, c_0 .. c_15]` (19 values).
#[derive(Debug, Clone)]
pub struct RidgedSumAtom {
    params: Vec<f64>,
    noise: Perlin,
}

impl RidgedSumAtom {
    /// Builds the atom from its 19 parameters (see the type docs).
    pub fn from_params(p: &[f64]) -> relief_sparse_core::Result<Self> {
        check_params(RIDGED_SUM_KIND, p, 3 + RIDGED_SUM_TERMS)?;
        if p[1] <= 0.0 {
            return Err(SparseError::param(
                "ridged_sum base_frequency",
                p[1],
                "must be > 0",
            ));
        }
        Ok(Self {
            noise: Perlin::new(p[0] as u64),
            params: p.to_vec(),
        })
    }
}

impl FunctionAtom for RidgedSumAtom {
    fn eval(&self, u: f64, v: f64) -> f64 {
        let p = &self.params;
        let (x, y) = rotate(u, v, p[2]);
        let mut s = 0.0;
        let mut f = p[1];
        for o in 0..RIDGED_SUM_TERMS / 2 {
            for field in 0..2 {
                let c = p[3 + field * 8 + o];
                if c != 0.0 {
                    let off = 31.7 * field as f64 + 7.3 * o as f64;
                    s += c * self.noise.ridged(x * f + off, y * f - off);
                }
            }
            f *= RIDGED_SUM_LACUNARITY;
        }
        s
    }
    fn descriptor(&self) -> AtomDescriptor {
        AtomDescriptor {
            kind: RIDGED_SUM_KIND.into(),
            params: self.params.clone(),
        }
    }
}

/// Registers the three function-atom kinds of this module so `.sct` readers can rebuild them.
pub fn register_function_atoms(registry: &mut FunctionAtomRegistry) {
    registry.register(PERLIN_KIND, |p| {
        Ok(Arc::new(PerlinAtom::from_params(p)?) as Arc<dyn FunctionAtom>)
    });
    registry.register(RIDGED_MULTIFRACTAL_KIND, |p| {
        Ok(Arc::new(RidgedMultifractalAtom::from_params(p)?) as Arc<dyn FunctionAtom>)
    });
    registry.register(RIDGED_SUM_KIND, |p| {
        Ok(Arc::new(RidgedSumAtom::from_params(p)?) as Arc<dyn FunctionAtom>)
    });
}

/// Family of analytic atoms for [`random_function_atoms`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseFamily {
    /// [`PerlinAtom`] (fBm of gradient noise).
    Perlin,
    /// [`RidgedMultifractalAtom`].
    RidgedMultifractal,
    /// [`RidgedSumAtom`] (the paper's figure 4 atoms).
    RidgedSum,
    /// Windows of ONE fBm field at terrain scale ([`PerlinAtom`]s sharing seed, frequency and
    /// octaves; only the offset and the angle differ): see [`FIELD_FREQUENCY`].
    PerlinField,
    /// Windows of ONE ridged multifractal field at terrain scale
    /// ([`RidgedMultifractalAtom`]s sharing all but the offset and the angle).
    RidgedField,
}

/// Base frequency (cycles per patch half-width) of the field families
/// ([`NoiseFamily::PerlinField`], [`NoiseFamily::RidgedField`]): a wavelength of about 12
/// patch half-widths (60 pixels for the paper's 10-pixel patches), so a window sees the field
/// at the scale of the terrain's landforms (a slope, a crest, a valley head) with the finer
/// octaves as its detail. Independent random functions of frequency 0.5-3 (the other
/// families) put 1-6 noise cells in a patch, finer than the relief of real terrain patches.
pub const FIELD_FREQUENCY: f64 = 0.08;
/// Octaves of the field families (lacunarity 2: the finest wavelength is about 2 pixels at
/// the paper's patch size).
pub const FIELD_OCTAVES: f64 = 5.0;
/// Extent (noise lattice cells) over which the field windows' offsets are drawn.
const FIELD_EXTENT: f64 = 64.0;

/// `n` random atoms of `family` (the analytic dictionary `D~` of section 5.2), parameters drawn
/// from a PCG seeded per atom by a counter-based hash of `(seed, atom)`.
pub fn random_function_atoms(
    family: NoiseFamily,
    n: usize,
    seed: u64,
) -> Vec<Arc<dyn FunctionAtom>> {
    // The one field of the field families (its seed is shared by every window).
    let field_seed = (item_seed(seed, 0xf1e1d, family as u64) % 65_536) as f64;
    (0..n)
        .map(|i| {
            let mut rng = Pcg64Mcg::seed_from_u64(item_seed(seed, family as u64 + 1, i as u64));
            let nseed = (rng.random::<u32>() % 65_536) as f64;
            let freq = 0.5 + 2.5 * rng.random::<f64>();
            let angle = std::f64::consts::PI * rng.random::<f64>();
            let (ox, oy) = (100.0 * rng.random::<f64>(), 100.0 * rng.random::<f64>());
            let atom: Arc<dyn FunctionAtom> = match family {
                NoiseFamily::Perlin => Arc::new(
                    PerlinAtom::from_params(&[
                        nseed,
                        freq,
                        1.0 + (rng.random::<u32>() % 4) as f64,
                        ox,
                        oy,
                        angle,
                    ])
                    .expect("valid generated parameters"),
                ),
                NoiseFamily::RidgedMultifractal => Arc::new(
                    RidgedMultifractalAtom::from_params(&[
                        nseed,
                        freq,
                        1.0 + (rng.random::<u32>() % 4) as f64,
                        2.0,
                        1.0 + rng.random::<f64>(),
                        ox,
                        oy,
                        angle,
                    ])
                    .expect("valid generated parameters"),
                ),
                NoiseFamily::PerlinField => Arc::new(
                    PerlinAtom::from_params(&[
                        field_seed,
                        FIELD_FREQUENCY,
                        FIELD_OCTAVES,
                        FIELD_EXTENT * ox / 100.0,
                        FIELD_EXTENT * oy / 100.0,
                        angle * 2.0,
                    ])
                    .expect("valid generated parameters"),
                ),
                NoiseFamily::RidgedField => Arc::new(
                    RidgedMultifractalAtom::from_params(&[
                        field_seed,
                        FIELD_FREQUENCY,
                        FIELD_OCTAVES,
                        2.0,
                        1.0,
                        FIELD_EXTENT * ox / 100.0,
                        FIELD_EXTENT * oy / 100.0,
                        angle * 2.0,
                    ])
                    .expect("valid generated parameters"),
                ),
                NoiseFamily::RidgedSum => {
                    let mut p = vec![nseed, 0.5 + 1.5 * rng.random::<f64>(), angle];
                    for t in 0..RIDGED_SUM_TERMS {
                        // Sparse-ish coefficient vectors with a 1/f-like amplitude decay.
                        let o = t % 8;
                        let keep = rng.random::<f64>() < 0.5;
                        let c = if keep {
                            (2.0 * rng.random::<f64>() - 1.0) * 0.7f64.powi(o as i32)
                        } else {
                            0.0
                        };
                        p.push(c);
                    }
                    p[3] = 1.0;
                    Arc::new(RidgedSumAtom::from_params(&p).expect("valid generated parameters"))
                }
            };
            atom
        })
        .collect()
}
