//! Samples as little-endian `f32` bytes (4 a value, row by row for a grid): the raw `.f32`
//! layout, and the byte form of samples handed between processes (a pickled or planned tile),
//! which may come back at an address not aligned for `f32`.

/// `values` as little-endian bytes.
pub fn f32_to_le_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// The little-endian `f32` values of `bytes` (a trailing partial value is ignored: callers
/// check the length against what they expect).
pub fn f32_from_le_bytes(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_round_trip_bit_for_bit() {
        let v = [0.0, -0.0, 1.5, f32::NAN, f32::MIN_POSITIVE, -3.25e7];
        let b = f32_to_le_bytes(&v);
        assert_eq!(b.len(), 24);
        assert_eq!(&b[8..12], &1.5f32.to_le_bytes());
        let back = f32_from_le_bytes(&b);
        assert!(v.iter().zip(&back).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert_eq!(f32_from_le_bytes(&b[..7]).len(), 1);
    }
}
