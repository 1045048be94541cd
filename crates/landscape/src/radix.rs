//! A radix heap (Ahuja, Mehlhorn, Orlin and Tarjan 1990): a monotone priority queue, for
//! priority floods, whose pops never decrease (a cell is pushed only above the level being
//! flooded). Push is O(1) and pop amortised O(log C) in the key range instead of a binary
//! heap's O(log n) comparisons and cache misses: the fill of a 4096^2 DEM spends most of its
//! time in its queue.

/// An unsigned integer key of a [`RadixHeap`].
pub trait RadixKey: Copy + Ord + std::fmt::Debug {
    /// Bits of the key type.
    const BITS: u32;
    /// Leading zeros of `self ^ other`.
    fn xor_lz(self, other: Self) -> u32;
    /// The smallest key.
    const ZERO: Self;
}

/// [`RadixKey`] for unsigned integer types.
macro_rules! radix_key {
    ($($t:ty),+) => {$(
        impl RadixKey for $t {
            const BITS: u32 = <$t>::BITS;
            const ZERO: $t = 0;
            #[inline]
            fn xor_lz(self, other: $t) -> u32 {
                (self ^ other).leading_zeros()
            }
        }
    )+};
}

radix_key!(u64, u128);

/// A monotone min-queue of keys: every pushed key must be at least the last popped one.
#[derive(Debug)]
pub struct RadixHeap<K: RadixKey> {
    last: K,
    buckets: Vec<Vec<K>>,
    len: usize,
}

impl<K: RadixKey> RadixHeap<K> {
    /// An empty queue.
    pub fn new() -> Self {
        Self {
            last: K::ZERO,
            buckets: (0..=K::BITS).map(|_| Vec::new()).collect(),
            len: 0,
        }
    }

    #[inline]
    fn bucket(&self, k: K) -> usize {
        (K::BITS - k.xor_lz(self.last)) as usize
    }

    /// Adds `k` (at least the last popped key).
    #[inline]
    pub fn push(&mut self, k: K) {
        debug_assert!(k >= self.last, "a radix heap is monotone");
        let b = self.bucket(k);
        self.buckets[b].push(k);
        self.len += 1;
    }

    /// Number of keys held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Moves the smallest key into bucket 0 (the keys equal to `last`).
    fn settle(&mut self) {
        if !self.buckets[0].is_empty() || self.len == 0 {
            return;
        }
        let i = (1..self.buckets.len())
            .find(|&i| !self.buckets[i].is_empty())
            .expect("a non-empty heap has a non-empty bucket");
        let keys = std::mem::take(&mut self.buckets[i]);
        self.last = *keys.iter().min().expect("non-empty bucket");
        for &k in &keys {
            let b = self.bucket(k);
            self.buckets[b].push(k);
        }
        // Give the (now empty) bucket its allocation back for later keys.
        let mut keys = keys;
        keys.clear();
        if self.buckets[i].is_empty() {
            self.buckets[i] = keys;
        }
    }

    /// The smallest key, without removing it.
    pub fn peek(&mut self) -> Option<K> {
        self.settle();
        self.buckets[0].last().copied()
    }

    /// Removes and returns the smallest key.
    pub fn pop(&mut self) -> Option<K> {
        self.settle();
        let k = self.buckets[0].pop()?;
        self.len -= 1;
        Some(k)
    }
}

impl<K: RadixKey> Default for RadixHeap<K> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn pops_in_order_like_a_binary_heap(
            keys in proptest::collection::vec(0u64..1_000_000, 1..300),
            extra in proptest::collection::vec(0u64..1_000, 0..300),
        ) {
            let mut r = RadixHeap::new();
            let mut b = std::collections::BinaryHeap::new();
            for &k in &keys {
                r.push(k);
                b.push(std::cmp::Reverse(k));
            }
            let mut extra = extra.into_iter();
            while let Some(std::cmp::Reverse(k)) = b.pop() {
                prop_assert_eq!(r.pop(), Some(k));
                // Monotone pushes above the popped key.
                if let Some(e) = extra.next() {
                    r.push(k + e);
                    b.push(std::cmp::Reverse(k + e));
                }
            }
            prop_assert!(r.is_empty());
        }
    }
}
