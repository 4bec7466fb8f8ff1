//! A voxel bitset in VoxelGrid's bit order: voxel `v` is bit `v % 64` of word `v / 64`, so
//! the words written little-endian are the `bits` data.

/// Sets bits `[from, to)`.
pub(crate) fn set_range(words: &mut [u64], from: usize, to: usize) {
    if from >= to {
        return;
    }
    let (w0, b0) = (from / 64, from % 64);
    let (w1, b1) = ((to - 1) / 64, (to - 1) % 64);
    let lo = u64::MAX << b0;
    let hi = u64::MAX >> (63 - b1);
    if w0 == w1 {
        words[w0] |= lo & hi;
        return;
    }
    words[w0] |= lo;
    for w in &mut words[w0 + 1..w1] {
        *w = u64::MAX;
    }
    words[w1] |= hi;
}

/// Writes the first `len` bytes of the words, little-endian, into `out`.
pub(crate) fn to_bytes(words: &[u64], len: usize, out: &mut Vec<u8>) {
    out.clear();
    out.reserve(len);
    for w in words {
        out.extend_from_slice(&w.to_le_bytes());
    }
    out.truncate(len);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_set_exactly_their_bits_across_words() {
        for (from, to) in [(0, 1), (3, 64), (63, 65), (5, 200), (64, 128), (10, 10)] {
            let mut w = vec![0u64; 4];
            set_range(&mut w, from, to);
            for b in 0..256 {
                assert_eq!(
                    w[b / 64] >> (b % 64) & 1 == 1,
                    (from..to).contains(&b),
                    "{from}..{to} bit {b}"
                );
            }
        }
        let mut out = Vec::new();
        to_bytes(&[0x0102_0304_0506_0708, 0xff], 9, &mut out);
        assert_eq!(out, [8, 7, 6, 5, 4, 3, 2, 1, 0xff]);
    }
}
