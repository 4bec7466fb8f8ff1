//! The free fraction of every voxel, accumulated from free leaves, and the two
//! passes that turn it (with the occupied bits) into output: `Percent`, and
//! `Bits` with unknown counted occupied.
//!
//! Only rows (one x row per `(y, z)`) that a free leaf touched are read,
//! written and cleared: untouched rows are wholly unknown, or occupied where
//! an occupied leaf set a bit. Invariant between frames: every value is 0 and
//! no row is marked touched, so a frame costs what its leaves touch plus one
//! pass over the output, not a clear of the whole accumulator.

use crate::lattice::PERCENT_UNKNOWN;
use crate::rows::BitRows;

/// Free fractions in `VoxelGrid` order, with the rows touched.
#[derive(Debug, Default)]
pub(crate) struct FreeFractions {
    values: Vec<f32>,
    touched: Vec<u64>,
    size: [usize; 3],
}

impl FreeFractions {
    /// Zero fractions for a `size` lattice: reuses the clean buffer when the
    /// size is unchanged, else reallocates zeroed.
    pub(crate) fn prepare(&mut self, size: [u32; 3]) {
        let size = size.map(|n| n as usize);
        if size != self.size || self.values.len() != size[0] * size[1] * size[2] {
            self.size = size;
            self.values.clear();
            self.values.resize(size[0] * size[1] * size[2], 0.0);
            self.touched.clear();
            self.touched.resize((size[1] * size[2]).div_ceil(64), 0);
        }
    }

    /// Restores the invariant after an abandoned frame.
    pub(crate) fn clean(&mut self) {
        let nx = self.size[0];
        for (wi, &word) in self.touched.iter().enumerate() {
            let mut w = word;
            while w != 0 {
                let r = wi * 64 + w.trailing_zeros() as usize;
                w &= w - 1;
                self.values[r * nx..(r + 1) * nx].fill(0.0);
            }
        }
        self.touched.fill(0);
    }

    /// The values of row `(y, z)` from voxel `x0` to `x1`, marking the row touched.
    #[inline(always)]
    pub(crate) fn row_mut(&mut self, y: usize, z: usize, x0: usize, x1: usize) -> &mut [f32] {
        let r = y + self.size[1] * z;
        self.touched[r / 64] |= 1 << (r % 64);
        let base = r * self.size[0];
        &mut self.values[base + x0..=base + x1]
    }

    fn is_touched(&self, r: usize) -> bool {
        self.touched[r / 64] >> (r % 64) & 1 == 1
    }

    /// `Bits` with unknown occupied: sets the bit of every voxel whose free
    /// part is below `full_below` (no occupied leaf overlaps a voxel whose bit
    /// is clear, so the rest of it is unknown). Leaves the fractions clean.
    pub(crate) fn mark_partly_unknown(&mut self, rows: &mut BitRows, full_below: f32) {
        let nx = self.size[0];
        let wpr = rows.words_per_row();
        let last_mask = rows.last_word_mask();
        for (r, row) in rows.words_mut().chunks_exact_mut(wpr).enumerate() {
            if !self.is_touched(r) {
                row.fill(!0);
                row[wpr - 1] &= last_mask;
                continue;
            }
            let fr = &mut self.values[r * nx..(r + 1) * nx];
            for (word, chunk) in row.iter_mut().zip(fr.chunks(64)) {
                let mut mask = 0u64;
                for (b, &f) in chunk.iter().enumerate() {
                    mask |= u64::from(f < full_below) << b;
                }
                *word |= mask;
            }
            fr.fill(0.0);
        }
        self.touched.fill(0);
    }

    /// `Percent`: 255 where nothing covers a voxel, else the occupied-or-unknown
    /// part in whole percent rounded up (`slack` points of rounding forgiven),
    /// at least 1 where an occupied leaf overlaps. Returns (voxels at 50 % and
    /// above, voxels unknown). Leaves the fractions clean.
    pub(crate) fn write_percent(
        &mut self,
        rows: &BitRows,
        slack: f64,
        out: &mut Vec<u8>,
    ) -> (u64, u64) {
        let nx = self.size[0];
        let wpr = rows.words_per_row();
        out.clear();
        out.resize(self.values.len(), PERCENT_UNKNOWN);
        let (mut occupied, mut unknown) = (0u64, 0u64);
        for (r, (row, dst)) in rows
            .words()
            .chunks_exact(wpr)
            .zip(out.chunks_exact_mut(nx))
            .enumerate()
        {
            let set: u64 = row.iter().map(|w| u64::from(w.count_ones())).sum();
            if !self.is_touched(r) {
                // Wholly unknown but where occupied leaves are: those are 100.
                for_each_bit(row, |x| dst[x] = 100);
                occupied += set;
                unknown += nx as u64 - set;
                continue;
            }
            let fr = &mut self.values[r * nx..(r + 1) * nx];
            // Every voxel as if no occupied leaf overlapped it (a loop the
            // compiler vectorises), then the occupied ones.
            for (&f, d) in fr.iter().zip(dst.iter_mut()) {
                *d = percent_free_or_unknown(f, slack);
            }
            for_each_bit(row, |x| dst[x] = percent_occupied(fr[x], slack));
            for &v in dst.iter() {
                occupied += u64::from((50..=100).contains(&v));
                unknown += u64::from(v == PERCENT_UNKNOWN);
            }
            fr.fill(0.0);
        }
        self.touched.fill(0);
        (occupied, unknown)
    }
}

fn for_each_bit(row: &[u64], mut f: impl FnMut(usize)) {
    for (wi, &word) in row.iter().enumerate() {
        let mut w = word;
        while w != 0 {
            f(wi * 64 + w.trailing_zeros() as usize);
            w &= w - 1;
        }
    }
}

/// `ceil(100 · (1 - free) - slack)` within 0..=100, without a library call:
/// `100 - floor(100 · free + slack)`, the floor a truncation of a value
/// clamped non-negative.
#[inline(always)]
fn rounded_up(free: f32, slack: f64) -> u8 {
    let q = (100.0 * f64::from(free) + slack).clamp(0.0, 100.0);
    100 - q as u8
}

/// A voxel no occupied leaf overlaps.
#[inline(always)]
fn percent_free_or_unknown(free: f32, slack: f64) -> u8 {
    if free == 0.0 {
        PERCENT_UNKNOWN
    } else {
        rounded_up(free, slack)
    }
}

/// A voxel an occupied leaf overlaps: at least 1.
#[inline(always)]
fn percent_occupied(free: f32, slack: f64) -> u8 {
    rounded_up(free, slack).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounding_is_up_and_exact_for_dyadic_fractions() {
        assert_eq!(rounded_up(0.875, 0.0), 13); // 12.5 -> 13
        assert_eq!(rounded_up(0.75, 0.0), 25);
        assert_eq!(rounded_up(1.0, 0.0), 0);
        assert_eq!(rounded_up(1.0 / 512.0, 0.0), 100); // 99.8 -> 100
        assert_eq!(rounded_up(511.0 / 512.0, 0.0), 1); // 0.195 -> 1
        assert_eq!(rounded_up(0.75 + 1e-7, 1e-2), 25);
        assert_eq!(percent_free_or_unknown(0.0, 0.0), PERCENT_UNKNOWN);
        assert_eq!(percent_occupied(1.0 - 1e-9, 1e-2), 1);
    }
}
