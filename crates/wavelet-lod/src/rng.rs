//! Counter-based Gaussian numbers: the value for `(seed, band, level, x, y)` is a pure function
//! of those five numbers (SplitMix64 finaliser chain, then Box-Muller), so any coefficient can be
//! produced alone, in any order, on any thread.

/// SplitMix64 (Steele, Lea and Flood 2014): the workspace's one implementation.
pub use relief_heightfield::rng::splitmix64;

/// Hash of everything but the column: computed once per row of coefficients.
#[inline]
pub fn row_key(seed: u64, band: usize, level: i64, y: usize) -> u64 {
    let k = splitmix64(seed ^ 0x5EED_0FDE_7A11);
    let k = splitmix64(k ^ ((band as u64) | ((level as u64) << 8)));
    splitmix64(k ^ y as u64)
}

/// Natural logarithm of `u` in `(0, 1]`: exponent split plus the `atanh` series of the
/// mantissa (`ln m = 2 atanh((m - 1)/(m + 1))`, five terms; absolute error below 1e-6). Pure
/// arithmetic, so it vectorises and gives the same bits on every platform.
#[inline(always)]
fn fast_ln(u: f32) -> f32 {
    let bits = u.to_bits();
    let e = ((bits >> 23) & 0xff) as i32 - 127;
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let p = s * (2.0 + s2 * (2.0 / 3.0 + s2 * (2.0 / 5.0 + s2 * (2.0 / 7.0 + s2 * (2.0 / 9.0)))));
    e as f32 * std::f32::consts::LN_2 + p
}

/// `(cos 2 pi u, sin 2 pi u)` for `u` in `[0, 1)`: with `phi = pi (u - 1/2)` in
/// `[-pi/2, pi/2)`, Taylor series of `sin phi` and `cos phi` (error < 4e-6) and the double-angle
/// formulas (`cos 2 pi u = -cos 2 phi`, `sin 2 pi u = -sin 2 phi`).
#[inline(always)]
fn fast_cos_sin_2pi(u: f32) -> (f32, f32) {
    let p = std::f32::consts::PI * (u - 0.5);
    let p2 = p * p;
    let s = p
        * (1.0
            + p2 * (-1.0 / 6.0
                + p2 * (1.0 / 120.0 + p2 * (-1.0 / 5040.0 + p2 * (1.0 / 362_880.0)))));
    let c = 1.0
        + p2 * (-0.5
            + p2 * (1.0 / 24.0
                + p2 * (-1.0 / 720.0 + p2 * (1.0 / 40_320.0 + p2 * (-1.0 / 3_628_800.0)))));
    (2.0 * s * s - 1.0, -2.0 * s * c)
}

/// The two uniforms of a pair: `u1` in `(0, 1]`, `u2` in `[0, 1)` (24 bits each).
#[inline(always)]
fn uniforms(row_key: u64, pair: usize) -> (f32, f32) {
    let h = splitmix64(row_key ^ (pair as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93));
    let u1 = ((h >> 40) + 1) as f32 * (1.0 / 16_777_216.0);
    let u2 = (h & 0xFF_FFFF) as f32 * (1.0 / 16_777_216.0);
    (u1, u2)
}

/// Box-Muller transform of two uniforms.
#[inline(always)]
fn box_muller(u1: f32, u2: f32) -> (f32, f32) {
    let r = (-2.0 * fast_ln(u1)).sqrt();
    let (c, s) = fast_cos_sin_2pi(u2);
    (r * c, r * s)
}

/// The two standard normal numbers of the pair of columns `(2p, 2p + 1)` of a row
/// (Box-Muller on two 24-bit uniforms from one hash; tails reach 5.8 sigma).
#[inline]
pub fn normal_pair(row_key: u64, pair: usize) -> (f32, f32) {
    let (u1, u2) = uniforms(row_key, pair);
    box_muller(u1, u2)
}

/// The standard normal number for column `x` of a row.
#[inline]
pub fn normal_at(row_key: u64, x: usize) -> f32 {
    let (a, b) = normal_pair(row_key, x / 2);
    if x.is_multiple_of(2) { a } else { b }
}

/// Fills `out[k]` with the normal numbers of columns `x0 + k` (wrapping at `usize::MAX`),
/// equal bit for bit to [`normal_at`].
pub fn fill_normals(row_key: u64, x0: usize, out: &mut [f32]) {
    const BLOCK: usize = 64;
    let n = out.len();
    if n == 0 {
        return;
    }
    if x0.checked_add(n).is_none() {
        // The window wraps around usize::MAX: positions are taken modulo 2^64, pointwise.
        for (k, v) in out.iter_mut().enumerate() {
            *v = normal_at(row_key, x0.wrapping_add(k));
        }
        return;
    }
    let p0 = x0 / 2;
    let p1 = (x0 + n - 1) / 2 + 1;
    let mut u1 = [0.0f32; BLOCK];
    let mut u2 = [0.0f32; BLOCK];
    let mut z = [0.0f32; 2 * BLOCK];
    let mut p = p0;
    while p < p1 {
        let m = (p1 - p).min(BLOCK);
        for k in 0..m {
            (u1[k], u2[k]) = uniforms(row_key, p + k);
        }
        for k in 0..m {
            let (a, b) = box_muller(u1[k], u2[k]);
            z[2 * k] = a;
            z[2 * k + 1] = b;
        }
        // Columns 2p .. 2(p + m) map to out[2p - x0 ..].
        let c0 = (2 * p).max(x0);
        let c1 = (2 * (p + m)).min(x0 + n);
        out[c0 - x0..c1 - x0].copy_from_slice(&z[c0 - 2 * p..c1 - 2 * p]);
        p += m;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_functions_match_libm() {
        for i in 1..=4096u32 {
            let u = i as f32 / 4096.0;
            assert!((fast_ln(u) - u.ln()).abs() < 2e-6, "ln {u}");
            let (c, s) = fast_cos_sin_2pi(u - 1.0 / 8192.0);
            let t = std::f32::consts::TAU * (u - 1.0 / 8192.0);
            assert!(
                (c - t.cos()).abs() < 2e-5 && (s - t.sin()).abs() < 2e-5,
                "trig {u}"
            );
        }
        assert!((fast_ln(1.0 / 16_777_216.0) - (1.0f32 / 16_777_216.0).ln()).abs() < 1e-5);
    }

    #[test]
    fn normals_have_unit_variance_and_fill_matches_pointwise() {
        let key = row_key(7, 1, 9, 3);
        let n = 200_000;
        let mut v = vec![0.0f32; n];
        fill_normals(key, 0, &mut v);
        let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
        let var = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "mean {mean}");
        let kurt =
            v.iter().map(|&x| (x as f64 - mean).powi(4)).sum::<f64>() / n as f64 / (var * var);
        assert!((kurt - 3.0).abs() < 0.05, "kurtosis {kurt}");
        let tail = v.iter().filter(|x| x.abs() > 2.0).count() as f64 / n as f64;
        assert!((tail - 0.0455).abs() < 0.003, "P(|z| > 2) = {tail}");
        assert!((var - 1.0).abs() < 0.01, "var {var}");
        let mut w = vec![0.0f32; 37];
        fill_normals(key, 11, &mut w);
        for (k, x) in w.iter().enumerate() {
            assert_eq!(x.to_bits(), normal_at(key, 11 + k).to_bits());
            assert_eq!(x.to_bits(), v[11 + k].to_bits());
        }
        assert_ne!(row_key(7, 1, 9, 3), row_key(7, 1, 9, 4));
        assert_ne!(row_key(7, 1, 9, 3), row_key(8, 1, 9, 3));
    }
}
