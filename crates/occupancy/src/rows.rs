//! Padded bit rows: the working occupancy of one frame, one x row per `(y, z)`,
//! each row a whole number of 64-bit words, and the packing into
//! `VoxelGrid.data`.
//!
//! Word-aligned rows make range sets, row dilation and column fills whole-word
//! operations; packing to the contiguous `VoxelGrid` bit order happens once per
//! frame at the end. Invariant: bits at `x >= nx` in a row's last word are 0.

/// Bit rows of a `nx × ny × nz` lattice.
#[derive(Clone, Debug, Default)]
pub(crate) struct BitRows {
    nx: usize,
    ny: usize,
    nz: usize,
    /// Words per row, `ceil(nx / 64)`.
    wpr: usize,
    words: Vec<u64>,
}

impl BitRows {
    /// Clears to an all-zero `size` lattice, keeping the allocation.
    pub(crate) fn reset(&mut self, size: [u32; 3]) {
        let [nx, ny, nz] = size.map(|n| n as usize);
        self.nx = nx;
        self.ny = ny;
        self.nz = nz;
        self.wpr = nx.div_ceil(64);
        self.words.clear();
        self.words.resize(self.wpr * ny * nz, 0);
    }

    /// Sets every bit set in `other`, a frame of the same size.
    pub(crate) fn or_from(&mut self, other: &BitRows) {
        for (w, o) in self.words.iter_mut().zip(&other.words) {
            *w |= o;
        }
    }

    pub(crate) fn size(&self) -> [usize; 3] {
        [self.nx, self.ny, self.nz]
    }

    pub(crate) fn words_per_row(&self) -> usize {
        self.wpr
    }

    /// Index of the first word of row `(y, z)`.
    #[inline(always)]
    pub(crate) fn row_start(&self, y: usize, z: usize) -> usize {
        (y + self.ny * z) * self.wpr
    }

    #[inline(always)]
    pub(crate) fn set(&mut self, x: usize, y: usize, z: usize) {
        let w = self.row_start(y, z) + x / 64;
        self.words[w] |= 1u64 << (x % 64);
    }

    #[cfg(test)]
    pub(crate) fn get(&self, x: usize, y: usize, z: usize) -> bool {
        let w = self.row_start(y, z) + x / 64;
        self.words[w] >> (x % 64) & 1 == 1
    }

    /// Sets bits `x0..=x1` of the row starting at word `start`.
    #[inline]
    pub(crate) fn set_range(&mut self, start: usize, x0: usize, x1: usize) {
        debug_assert!(x0 <= x1 && x1 < self.nx);
        let (w0, w1) = (x0 / 64, x1 / 64);
        let lo = !0u64 << (x0 % 64);
        let hi = !0u64 >> (63 - x1 % 64);
        let row = &mut self.words[start..start + self.wpr];
        if w0 == w1 {
            row[w0] |= lo & hi;
        } else {
            row[w0] |= lo;
            for w in &mut row[w0 + 1..w1] {
                *w = !0;
            }
            row[w1] |= hi;
        }
    }

    pub(crate) fn words(&self) -> &[u64] {
        &self.words
    }

    pub(crate) fn words_mut(&mut self) -> &mut [u64] {
        &mut self.words
    }

    /// Mask of the valid bits of a row's last word.
    pub(crate) fn last_word_mask(&self) -> u64 {
        match self.nx % 64 {
            0 => !0,
            r => (1u64 << r) - 1,
        }
    }

    /// Number of set bits.
    pub(crate) fn count_ones(&self) -> u64 {
        self.words.iter().map(|w| u64::from(w.count_ones())).sum()
    }

    /// Writes the rows as `VoxelGrid` bits: contiguous, LSB first, x fastest.
    pub(crate) fn pack_bits(&self, out: &mut Vec<u8>) {
        let total = (self.nx * self.ny * self.nz).div_ceil(8);
        out.clear();
        out.reserve(total + 8);
        let mask = self.last_word_mask();
        let tail_bits = match self.nx % 64 {
            0 => 64,
            r => r,
        };
        let mut acc = 0u64;
        let mut nacc = 0u32;
        for row in self.words.chunks_exact(self.wpr.max(1)) {
            let last = row.len() - 1;
            for (i, &word) in row.iter().enumerate() {
                let (w, bits) = if i == last {
                    (word & mask, tail_bits as u32)
                } else {
                    (word, 64)
                };
                acc |= w << nacc;
                if nacc + bits >= 64 {
                    out.extend_from_slice(&acc.to_le_bytes());
                    acc = if nacc == 0 { 0 } else { w >> (64 - nacc) };
                    nacc = nacc + bits - 64;
                } else {
                    nacc += bits;
                }
            }
        }
        if nacc > 0 {
            out.extend_from_slice(&acc.to_le_bytes()[..nacc.div_ceil(8) as usize]);
        }
        debug_assert_eq!(out.len(), total);
        out.truncate(total);
    }

    /// Writes the rows as `VoxelGrid` percent bytes: `on` where set, `off` elsewhere.
    pub(crate) fn pack_bytes(&self, on: u8, off: u8, out: &mut Vec<u8>) {
        out.clear();
        out.resize(self.nx * self.ny * self.nz, off);
        if self.nx == 0 {
            return;
        }
        for (row, dst) in self
            .words
            .chunks_exact(self.wpr)
            .zip(out.chunks_exact_mut(self.nx))
        {
            for (wi, &word) in row.iter().enumerate() {
                let mut w = word;
                while w != 0 {
                    let b = w.trailing_zeros() as usize;
                    w &= w - 1;
                    let x = wi * 64 + b;
                    if x < self.nx {
                        dst[x] = on;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive_pack(rows: &BitRows) -> Vec<u8> {
        let [nx, ny, nz] = rows.size();
        let mut out = vec![0u8; (nx * ny * nz).div_ceil(8)];
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    if rows.get(x, y, z) {
                        let n = x + nx * (y + ny * z);
                        out[n / 8] |= 1 << (n % 8);
                    }
                }
            }
        }
        out
    }

    #[test]
    fn packing_matches_the_bit_by_bit_order_for_odd_row_lengths() {
        for nx in [1usize, 3, 63, 64, 65, 100, 128, 130] {
            let mut rows = BitRows::default();
            rows.reset([nx as u32, 3, 2]);
            let mut seed = 0x9e37_79b9_u64;
            for z in 0..2 {
                for y in 0..3 {
                    for x in 0..nx {
                        seed = seed
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        if seed >> 61 & 1 == 1 {
                            rows.set(x, y, z);
                        }
                    }
                }
            }
            let mut out = Vec::new();
            rows.pack_bits(&mut out);
            assert_eq!(out, naive_pack(&rows), "nx = {nx}");
        }
    }

    #[test]
    fn range_sets_cover_exactly_the_range() {
        let mut rows = BitRows::default();
        rows.reset([200, 1, 1]);
        rows.set_range(0, 5, 140);
        for x in 0..200 {
            assert_eq!(rows.get(x, 0, 0), (5..=140).contains(&x), "x = {x}");
        }
        rows.set_range(0, 199, 199);
        assert!(rows.get(199, 0, 0));
        assert_eq!(rows.count_ones(), 137);
    }
}
