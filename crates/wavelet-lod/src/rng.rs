//! Counter-based Gaussian numbers: the value for `(seed, band, level, x, y)` is a pure function
//! of those five numbers (SplitMix64 finaliser chain, then Box-Muller), so any coefficient can be
//! produced alone, in any order, on any thread.

/// SplitMix64 finaliser (Steele, Lea and Flood 2014): a bijective 64-bit mix.
#[inline(always)]
pub fn splitmix64(z: u64) -> u64 {
    let mut z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash of everything but the column: computed once per row of coefficients.
#[inline]
pub fn row_key(seed: u64, band: usize, level: i64, y: usize) -> u64 {
    let k = splitmix64(seed ^ 0x5EED_0FDE_7A11);
    let k = splitmix64(k ^ ((band as u64) | ((level as u64) << 8)));
    splitmix64(k ^ y as u64)
}

/// The two standard normal numbers of the pair of columns `(2p, 2p + 1)` of a row.
#[inline(always)]
pub fn normal_pair(row_key: u64, pair: usize) -> (f32, f32) {
    let h = splitmix64(row_key ^ (pair as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93));
    // Two 24-bit uniforms: u1 in (0, 1], u2 in [0, 1).
    let u1 = ((h >> 40) + 1) as f32 * (1.0 / 16_777_216.0);
    let u2 = (h & 0xFF_FFFF) as f32 * (1.0 / 16_777_216.0);
    let r = (-2.0 * u1.ln()).sqrt();
    let (s, c) = (std::f32::consts::TAU * u2).sin_cos();
    (r * c, r * s)
}

/// The standard normal number for column `x` of a row.
#[inline]
pub fn normal_at(row_key: u64, x: usize) -> f32 {
    let (a, b) = normal_pair(row_key, x / 2);
    if x.is_multiple_of(2) { a } else { b }
}

/// Fills `out[k]` with the normal numbers of columns `x0 + k`.
pub fn fill_normals(row_key: u64, x0: usize, out: &mut [f32]) {
    let n = out.len();
    let mut k = 0;
    if x0 % 2 == 1 && n > 0 {
        out[0] = normal_pair(row_key, x0 / 2).1;
        k = 1;
    }
    while k + 1 < n {
        let (a, b) = normal_pair(row_key, (x0 + k) / 2);
        out[k] = a;
        out[k + 1] = b;
        k += 2;
    }
    if k < n {
        out[k] = normal_pair(row_key, (x0 + k) / 2).0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_have_unit_variance_and_fill_matches_pointwise() {
        let key = row_key(7, 1, 9, 3);
        let n = 200_000;
        let mut v = vec![0.0f32; n];
        fill_normals(key, 0, &mut v);
        let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
        let var = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "mean {mean}");
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
