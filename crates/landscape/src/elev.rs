//! Elevation types the routing works on: `f32` rasters as read, `f64` for the erosion models
//! (whose implicit solvers compare with fastscapelib's double precision).

/// An elevation type: ordered keys for the priority queues (and back), the next
/// representable value upward (the epsilon of Priority-Flood+epsilon), voids.
pub trait Elev: Copy + PartialOrd + Send + Sync + std::fmt::Debug + 'static {
    /// An integer key whose order is the numeric order of non-NaN values.
    type Key: Ord + Copy + std::fmt::Debug;
    /// The order-preserving key of `self`.
    fn key(self) -> Self::Key;
    /// The value whose key is `key` (the inverse of [`Elev::key`], bit for bit).
    fn from_key(key: Self::Key) -> Self;
    /// A priority-queue entry: the key of `self` and a cell index, ordered by key, then index.
    type Entry: crate::radix::RadixKey;
    /// The entry of `self` at cell `i`.
    fn entry(self, i: u32) -> Self::Entry;
    /// The cell of an entry.
    fn cell(e: Self::Entry) -> u32;
    /// The smallest representable value above `self`.
    fn up(self) -> Self;
    /// True for a void (NaN).
    fn is_void(self) -> bool;
    /// As `f64`.
    fn to_f64(self) -> f64;
    /// From `f64` (rounded).
    fn from_f64(v: f64) -> Self;
}

/// One implementation for both float widths: `$key` the unsigned integer of the float's bits,
/// `$entry` one wide enough for a key and a 32-bit cell index.
macro_rules! impl_elev {
    ($t:ty, $key:ty, $entry:ty) => {
        impl Elev for $t {
            type Key = $key;
            type Entry = $entry;
            #[inline]
            fn entry(self, i: u32) -> $entry {
                ((self.key() as $entry) << 32) | i as $entry
            }
            #[inline]
            fn cell(e: $entry) -> u32 {
                e as u32
            }
            #[inline]
            fn key(self) -> $key {
                // Negative floats reversed, positive ones above them: integer order = numeric.
                let b = self.to_bits();
                let sign = 1 << (<$key>::BITS - 1);
                if b & sign != 0 { !b } else { b | sign }
            }
            #[inline]
            fn from_key(key: $key) -> $t {
                let sign = 1 << (<$key>::BITS - 1);
                <$t>::from_bits(if key & sign != 0 { key & !sign } else { !key })
            }
            #[inline]
            fn up(self) -> $t {
                self.next_up()
            }
            #[inline]
            fn is_void(self) -> bool {
                self.is_nan()
            }
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn from_f64(v: f64) -> $t {
                v as $t
            }
        }
    };
}

impl_elev!(f32, u32, u64);
impl_elev!(f64, u64, u128);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_sort_like_the_values() {
        let v = [-1e30f32, -2.5, -0.0, 0.0, 1e-40, 1.0, 3000.5, f32::INFINITY];
        for w in v.windows(2) {
            assert!(w[0].key() <= w[1].key(), "{w:?}");
            assert!((w[0] as f64).key() <= (w[1] as f64).key());
        }
        for v in v {
            assert_eq!(f32::from_key(v.key()).to_bits(), v.to_bits());
            let d = v as f64;
            assert_eq!(f64::from_key(d.key()).to_bits(), d.to_bits());
        }
        assert!(1.0f32.up() > 1.0 && 1.0f64.up() > 1.0);
    }
}
