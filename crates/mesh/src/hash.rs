//! A fast hasher for the meshing maps keyed by lattice points (vertex welding, cap and slice
//! vertex indices). The standard SipHash resists hash flooding, which these maps need not:
//! their keys are lattice coordinates the mesher made, and each map is bounded by its mesh.
//! SipHash was a sixth of a replay's time in these lookups.
//!
//! No map keyed this way is iterated to make output, so the hash values never reach a result.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// A `HashMap` with [`WordHasher`].
pub type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<WordHasher>>;

/// An empty [`FastMap`].
pub fn fast_map<K, V>() -> FastMap<K, V> {
    HashMap::with_hasher(BuildHasherDefault::default())
}

/// Multiply-rotate hashing of 64-bit words, with a final mix so that the low bits (the
/// bucket) depend on every input bit.
#[derive(Debug, Default, Clone, Copy)]
pub struct WordHasher {
    h: u64,
}

/// An odd constant with well-spread bits (from the golden ratio).
const K: u64 = 0x9E37_79B9_7F4A_7C15;

impl WordHasher {
    #[inline]
    fn word(&mut self, w: u64) {
        self.h = (self.h.rotate_left(23) ^ w).wrapping_mul(K);
    }
}

impl Hasher for WordHasher {
    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        let mut chunks = bytes.chunks_exact(8);
        for c in &mut chunks {
            self.word(u64::from_le_bytes([
                c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7],
            ]));
        }
        let rest = chunks.remainder();
        if !rest.is_empty() {
            let mut w = [0u8; 8];
            w[..rest.len()].copy_from_slice(rest);
            self.word(u64::from_le_bytes(w) ^ ((rest.len() as u64) << 56));
        }
    }
    #[inline]
    fn write_u8(&mut self, i: u8) {
        self.word(u64::from(i));
    }
    #[inline]
    fn write_u32(&mut self, i: u32) {
        self.word(u64::from(i));
    }
    #[inline]
    fn write_i32(&mut self, i: i32) {
        self.word(u64::from(i as u32));
    }
    #[inline]
    fn write_u64(&mut self, i: u64) {
        self.word(i);
    }
    #[inline]
    fn write_usize(&mut self, i: usize) {
        self.word(i as u64);
    }
    #[inline]
    fn finish(&self) -> u64 {
        let h = self.h ^ (self.h >> 32);
        let h = h.wrapping_mul(K);
        h ^ (h >> 29)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::hash::{BuildHasher, Hash};

    fn hash<T: Hash>(t: &T) -> u64 {
        BuildHasherDefault::<WordHasher>::default().hash_one(t)
    }

    #[test]
    fn neighbouring_lattice_points_spread_over_the_buckets() {
        // 32^3 neighbouring points into 4096 buckets by the low bits: no bucket holds many.
        let mut buckets = vec![0u32; 4096];
        for x in 0..32 {
            for y in 0..32 {
                for z in 0..32 {
                    let p: [i32; 4] = [2 * x, 2 * y, 2 * z, 128];
                    buckets[(hash(&p) & 4095) as usize] += 1;
                }
            }
        }
        let most = *buckets.iter().max().unwrap();
        assert!(
            most <= 32,
            "a bucket holds {most} of 32768 points (8 expected)"
        );
        assert_ne!(hash(&[1i32, 2, 3, 4]), hash(&[2i32, 1, 3, 4]));
    }
}
