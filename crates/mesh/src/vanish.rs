//! Whether a part of a body vanishes between two frames: moves farther than its own
//! thickness in one frame period, so that in 4D its piece in one frame is not joined to its
//! piece in the next, and a contact it makes in between can be missed.
//!
//! The 4D marching hypercubes join two occupied voxels of consecutive frames when they lie
//! in one hypercube, i.e. within one voxel of each other on every axis. So a part of frame k
//! (a 26-connected set of occupied voxels) carries on into frame k+1 exactly when one of its
//! voxels has an occupied voxel of frame k+1 within one voxel; a part that has none ends
//! between the frames (and, read backwards, a part of frame k+1 that has none in frame k
//! begins there). A body at rest, or moving less than its thickness, has no such part;
//! a fast gripper beside a resting arm does, even though the body as a whole overlaps its
//! next frame.
//!
//! The test works on the frames' bit rows, a word of 64 voxels at a time: dilate the other
//! frame by one voxel, keep this frame's voxels inside it (the parts that carry on), grow
//! them through this frame's occupied voxels until nothing changes (a few steps: as many as
//! a carried-on part is thick beyond the dilation), and whatever is left ends. Growth that
//! is still changing after `WORD_STEPS` steps is finished voxel by voxel, so a long thin
//! part costs its length once, never its length times the grid.
//!
//! How many times the frame rate would join a vanishing part is estimated from the parts
//! that end in frame k and begin in frame k+1: their centres' distance over the smallest
//! extent of the ending parts (a part moving less than its extent per period stays joined).
//! It is an estimate, said as such; the verdict that a part vanishes is exact.

use super::OccupancyGrid;

/// Word-parallel growth steps before growth is finished voxel by voxel.
const WORD_STEPS: usize = 16;

/// A part of a body that vanishes between two frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vanishing {
    /// Voxels of the first frame whose part ends before the second.
    pub ending_voxels: u64,
    /// Voxels of the second frame whose part begins after the first.
    pub beginning_voxels: u64,
    /// Estimated factor on the frame rate that would join every part (at least 2; 0 when it
    /// cannot be estimated: nothing begins where something ends, or the reverse).
    pub rate_factor: f32,
}

/// Largest displacement measured between two frames (voxels); a larger one is reported as
/// this.
pub const MAX_DISPLACEMENT: u16 = 64;

/// How a body moved between two frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// How far it moved, in voxels on the grid's axes (Chebyshev): the least `d` such that
    /// every occupied voxel of each frame has one of the other within `d` voxels (the
    /// frames' Hausdorff distance). 1 when every voxel has a neighbour in the other frame
    /// (the 4D mesh then joins them, and no contact between frames is missed); at most
    /// [`MAX_DISPLACEMENT`].
    pub displacement: u16,
    /// A part that vanishes between the frames, if one does.
    pub vanishing: Option<Vanishing>,
}

/// How the body moved between frames `a` and `b` (same lattice): its displacement and any
/// part that vanishes.
pub fn motion(a: &OccupancyGrid, b: &OccupancyGrid) -> Motion {
    let at_most_one = Motion {
        displacement: 1,
        vanishing: None,
    };
    if a.padded != b.padded || a.words != b.words || a.occupied == 0 || b.occupied == 0 {
        return at_most_one;
    }
    if within_one(a, b) && within_one(b, a) {
        return at_most_one;
    }
    let Some(rows) = Rows::of(a, b) else {
        return at_most_one;
    };
    let mut scratch = vec![0u64; a.bits.len()];
    let mut grown = vec![0u64; a.bits.len()];
    let displacement = reach(&rows, &a.bits, &b.bits, &mut scratch, &mut grown).max(reach(
        &rows,
        &b.bits,
        &a.bits,
        &mut scratch,
        &mut grown,
    ));
    Motion {
        displacement,
        vanishing: vanishing_in(&rows, a, b, &mut scratch, &mut grown),
    }
}

/// The least `d` (at most [`MAX_DISPLACEMENT`]) such that every voxel of `this` lies within
/// `d` voxels of one of `other`: `other` dilated until it holds `this`.
fn reach(rows: &Rows, this: &[u64], other: &[u64], scratch: &mut [u64], grown: &mut [u64]) -> u16 {
    // Both frames are empty outside the box `rows` spans, and so is every dilation of
    // them within it: each pass below reads and writes the box only.
    let mut cur: Vec<u64> = other.to_vec();
    for d in 1..=MAX_DISPLACEMENT {
        dilate(rows, &cur, scratch, grown);
        if rows.spans().all(|s| {
            this[s.clone()]
                .iter()
                .zip(&grown[s])
                .all(|(t, g)| t & !g == 0)
        }) {
            return d;
        }
        for s in rows.spans() {
            cur[s.clone()].copy_from_slice(&grown[s]);
        }
    }
    MAX_DISPLACEMENT
}

/// Whether a part of the body vanishes between frames `a` and `b` (same lattice), and by how
/// much the frame rate would have to rise; `None` when every part carries on.
pub fn vanishing(a: &OccupancyGrid, b: &OccupancyGrid) -> Option<Vanishing> {
    if a.padded != b.padded || a.words != b.words || a.occupied == 0 || b.occupied == 0 {
        return None;
    }
    // The common case, a body moving less than a voxel or so per frame: every voxel of each
    // frame has one of the other within a voxel. Checked row by row without a buffer.
    if within_one(a, b) && within_one(b, a) {
        return None;
    }
    let rows = Rows::of(a, b)?;
    let mut scratch = vec![0u64; a.bits.len()];
    let mut grown = vec![0u64; a.bits.len()];
    vanishing_in(&rows, a, b, &mut scratch, &mut grown)
}

fn vanishing_in(
    rows: &Rows,
    a: &OccupancyGrid,
    b: &OccupancyGrid,
    scratch: &mut [u64],
    grown: &mut [u64],
) -> Option<Vanishing> {
    let (rows, scratch, grown) = (rows, scratch, grown);
    let ending = ends(rows, &a.bits, &b.bits, scratch, grown);
    let ending_voxels = count(&ending);
    let beginning = ends(rows, &b.bits, &a.bits, scratch, grown);
    let beginning_voxels = count(&beginning);
    if ending_voxels == 0 && beginning_voxels == 0 {
        return None;
    }
    let rate_factor = match (Extent::of(rows, &ending), Extent::of(rows, &beginning)) {
        (Some(e), Some(f)) => {
            let d: f64 = (0..3)
                .map(|k| (f.centre(k) - e.centre(k)).powi(2))
                .sum::<f64>()
                .sqrt();
            let thickness = e.smallest_side().min(f.smallest_side()).max(1.0);
            (d / thickness).ceil().clamp(2.0, 1e6) as f32
        }
        _ => 0.0,
    };
    Some(Vanishing {
        ending_voxels,
        beginning_voxels,
        rate_factor,
    })
}

/// Whether every occupied voxel of `this` has an occupied voxel of `other` within one voxel
/// on every axis (stops at the first that has none).
fn within_one(this: &OccupancyGrid, other: &OccupancyGrid) -> bool {
    let [_, py, pz] = this.padded;
    let w = this.words;
    // `other`'s row (y, z) dilated along x, word i.
    let xdil = |r: usize, i: usize| {
        let s = other.bits[r + i];
        let prev = if i > 0 {
            other.bits[r + i - 1] >> 63
        } else {
            0
        };
        let next = if i + 1 < w {
            other.bits[r + i + 1] << 63
        } else {
            0
        };
        s | (s << 1) | prev | (s >> 1) | next
    };
    for z in 1..pz.saturating_sub(1) {
        for y in 1..py.saturating_sub(1) {
            let r = (y + py * z) * w;
            for i in 0..w {
                let t = this.bits[r + i];
                if t == 0 {
                    continue;
                }
                let mut d = 0u64;
                for dz in [z - 1, z, z + 1] {
                    for dy in [y - 1, y, y + 1] {
                        d |= xdil((dy + py * dz) * w, i);
                    }
                }
                if t & !d != 0 {
                    return false;
                }
            }
        }
    }
    true
}

/// The rows and words the two frames' occupied voxels span, with the grid's shape.
struct Rows {
    py: usize,
    words: usize,
    /// Padded (y, z) ranges holding a voxel of either frame, widened by one (a dilation
    /// reaches there).
    y: (usize, usize),
    z: (usize, usize),
}

impl Rows {
    fn of(a: &OccupancyGrid, b: &OccupancyGrid) -> Option<Self> {
        let [_, py, pz] = a.padded;
        let w = a.words;
        let (mut y0, mut y1, mut z0, mut z1) = (usize::MAX, 0, usize::MAX, 0);
        for z in 0..pz {
            for y in 0..py {
                let r = (y + py * z) * w;
                let any = a.bits[r..r + w]
                    .iter()
                    .zip(&b.bits[r..r + w])
                    .any(|(x, y)| (x | y) != 0);
                if any {
                    y0 = y0.min(y);
                    y1 = y1.max(y);
                    z0 = z0.min(z);
                    z1 = z1.max(z);
                }
            }
        }
        (y0 <= y1).then(|| Self {
            py,
            words: w,
            // Occupied voxels lie inside the padding, so one row on each side exists.
            y: (y0.saturating_sub(1), (y1 + 1).min(py - 1)),
            z: (z0.saturating_sub(1), (z1 + 1).min(pz - 1)),
        })
    }

    fn row(&self, y: usize, z: usize) -> usize {
        (y + self.py * z) * self.words
    }

    /// The words of the box's rows: per z, its rows y0..=y1 lie side by side.
    fn spans(&self) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        (self.z.0..=self.z.1).map(|z| self.row(self.y.0, z)..self.row(self.y.1, z) + self.words)
    }
}

/// The voxels of `this` whose part has no voxel of `other` within one voxel.
fn ends(
    rows: &Rows,
    this: &[u64],
    other: &[u64],
    scratch: &mut [u64],
    grown: &mut [u64],
) -> Vec<u64> {
    // What carries on: this ∩ (other dilated).
    dilate(rows, other, scratch, grown);
    let mut reached: Vec<u64> = this.iter().zip(grown.iter()).map(|(t, g)| t & g).collect();
    if this.iter().zip(&reached).all(|(t, r)| t == r) {
        return vec![0; this.len()];
    }
    // Grown through this frame's voxels, a word at a time, then voxel by voxel (within the
    // box `rows` spans: nothing of either frame lies outside it).
    let mut settled = false;
    for _ in 0..WORD_STEPS {
        dilate(rows, &reached, scratch, grown);
        let mut changed = false;
        for s in rows.spans() {
            let (reached, grown, this) = (&mut reached[s.clone()], &grown[s.clone()], &this[s]);
            for ((r, g), t) in reached.iter_mut().zip(grown).zip(this) {
                let next = g & t;
                changed |= next != *r;
                *r = next;
            }
        }
        if !changed {
            settled = true;
            break;
        }
    }
    if !settled {
        flood(rows, this, &mut reached);
    }
    this.iter().zip(&reached).map(|(t, r)| t & !r).collect()
}

/// `out` = `src` dilated by one voxel on every axis (26-neighbourhood), over the rows
/// `rows` spans (outside them `out` is left as it is: zero, as `src` is there); `scratch`
/// holds the rows dilated along x.
fn dilate(rows: &Rows, src: &[u64], scratch: &mut [u64], out: &mut [u64]) {
    let w = rows.words;
    for s in rows.spans() {
        out[s].fill(0);
    }
    for z in rows.z.0..=rows.z.1 {
        for y in rows.y.0..=rows.y.1 {
            let r = rows.row(y, z);
            let mut carry_in = 0u64;
            for i in 0..w {
                let s = src[r + i];
                let next = if i + 1 < w { src[r + i + 1] } else { 0 };
                scratch[r + i] = s | (s << 1) | carry_in | (s >> 1) | (next << 63);
                carry_in = s >> 63;
            }
        }
    }
    for z in rows.z.0..=rows.z.1 {
        for y in rows.y.0..=rows.y.1 {
            let r = rows.row(y, z);
            for dz in [-1i64, 0, 1] {
                for dy in [-1i64, 0, 1] {
                    let (yy, zz) = (y as i64 + dy, z as i64 + dz);
                    if yy < rows.y.0 as i64
                        || yy > rows.y.1 as i64
                        || zz < rows.z.0 as i64
                        || zz > rows.z.1 as i64
                    {
                        continue;
                    }
                    let q = rows.row(yy as usize, zz as usize);
                    for i in 0..w {
                        out[r + i] |= scratch[q + i];
                    }
                }
            }
        }
    }
}

/// Grows `reached` through the voxels of `this` to everything 26-connected to it, voxel by
/// voxel (each voxel of `this` is taken once).
fn flood(rows: &Rows, this: &[u64], reached: &mut [u64]) {
    let w = rows.words;
    let mut stack: Vec<(usize, usize, usize)> = Vec::new();
    let at = |y: usize, z: usize, x: usize| rows.row(y, z) + x / 64;
    for z in rows.z.0..=rows.z.1 {
        for y in rows.y.0..=rows.y.1 {
            for i in 0..w {
                let mut word = reached[rows.row(y, z) + i];
                while word != 0 {
                    let b = word.trailing_zeros() as usize;
                    stack.push((64 * i + b, y, z));
                    word &= word - 1;
                }
            }
        }
    }
    while let Some((x, y, z)) = stack.pop() {
        for dz in [-1i64, 0, 1] {
            for dy in [-1i64, 0, 1] {
                for dx in [-1i64, 0, 1] {
                    let (xx, yy, zz) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                    if xx < 0
                        || xx >= (64 * w) as i64
                        || yy < rows.y.0 as i64
                        || yy > rows.y.1 as i64
                        || zz < rows.z.0 as i64
                        || zz > rows.z.1 as i64
                    {
                        continue;
                    }
                    let (xx, yy, zz) = (xx as usize, yy as usize, zz as usize);
                    let i = at(yy, zz, xx);
                    let bit = 1u64 << (xx % 64);
                    if this[i] & bit != 0 && reached[i] & bit == 0 {
                        reached[i] |= bit;
                        stack.push((xx, yy, zz));
                    }
                }
            }
        }
    }
}

fn count(bits: &[u64]) -> u64 {
    bits.iter().map(|w| u64::from(w.count_ones())).sum()
}

/// The box and centre of a set of voxels.
struct Extent {
    min: [usize; 3],
    max: [usize; 3],
    sum: [f64; 3],
    n: f64,
}

impl Extent {
    fn of(rows: &Rows, bits: &[u64]) -> Option<Self> {
        let mut e = Extent {
            min: [usize::MAX; 3],
            max: [0; 3],
            sum: [0.0; 3],
            n: 0.0,
        };
        for z in rows.z.0..=rows.z.1 {
            for y in rows.y.0..=rows.y.1 {
                let r = rows.row(y, z);
                for i in 0..rows.words {
                    let mut word = bits[r + i];
                    while word != 0 {
                        let x = 64 * i + word.trailing_zeros() as usize;
                        word &= word - 1;
                        for (k, c) in [x, y, z].into_iter().enumerate() {
                            e.min[k] = e.min[k].min(c);
                            e.max[k] = e.max[k].max(c);
                            e.sum[k] += c as f64;
                        }
                        e.n += 1.0;
                    }
                }
            }
        }
        (e.n > 0.0).then_some(e)
    }

    fn centre(&self, k: usize) -> f64 {
        self.sum[k] / self.n
    }

    /// The smallest side of the box, in voxels.
    fn smallest_side(&self) -> f64 {
        (0..3)
            .map(|k| (self.max[k] - self.min[k] + 1) as f64)
            .fold(f64::INFINITY, f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{DecodeOptions, FrameRef, OccupancyGrid};

    /// A bits frame of `n`³ voxels holding the listed boxes (inclusive voxel ranges).
    fn frame(n: u32, boxes: &[([u32; 3], [u32; 3])]) -> OccupancyGrid {
        let mut data = vec![0u8; ((n * n * n) as usize).div_ceil(8)];
        for (lo, hi) in boxes {
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let i = (x + n * (y + n * z)) as usize;
                        data[i / 8] |= 1 << (i % 8);
                    }
                }
            }
        }
        OccupancyGrid::decode(
            &FrameRef {
                stamp_ns: 0,
                origin: [0.0; 3],
                resolution: 0.1,
                size: [n, n, n],
                encoding: 0,
                data: &data,
            },
            &DecodeOptions::default(),
        )
        .unwrap()
    }

    #[test]
    fn a_body_moving_less_than_its_thickness_carries_on() {
        let a = frame(70, &[([2, 2, 2], [9, 9, 9])]);
        // Moved by 5 voxels of its 8: overlaps, but moves 5 voxels.
        let b = frame(70, &[([7, 2, 2], [14, 9, 9])]);
        assert_eq!(vanishing(&a, &b), None);
        assert_eq!(
            motion(&a, &b),
            Motion {
                displacement: 5,
                vanishing: None
            }
        );
        // By one voxel: joined everywhere.
        let one = frame(70, &[([3, 2, 2], [10, 9, 9])]);
        assert_eq!(motion(&a, &one).displacement, 1);
        // Moved by its thickness (8): the first column of one frame is next to the last of
        // the other, in one hypercube, so joined.
        let c = frame(70, &[([10, 2, 2], [17, 9, 9])]);
        assert_eq!(vanishing(&a, &c), None);
        // One voxel more and nothing joins them.
        let far = frame(70, &[([11, 2, 2], [18, 9, 9])]);
        assert_eq!(vanishing(&a, &far).map(|v| v.ending_voxels), Some(512));
        // A long body across word boundaries, moved by 3.
        let d = frame(200, &[([1, 3, 3], [150, 5, 5])]);
        let e = frame(200, &[([4, 3, 3], [153, 5, 5])]);
        assert_eq!(vanishing(&d, &e), None);
    }

    #[test]
    fn a_fast_part_beside_a_resting_one_vanishes() {
        // A resting base, and a thin gripper (2 voxels thick) moving 10 voxels along x.
        let a = frame(70, &[([2, 2, 2], [9, 9, 9]), ([20, 20, 20], [21, 25, 25])]);
        let b = frame(70, &[([2, 2, 2], [9, 9, 9]), ([30, 20, 20], [31, 25, 25])]);
        let v = vanishing(&a, &b).expect("the gripper vanishes");
        assert_eq!(v.ending_voxels, 2 * 6 * 6);
        assert_eq!(v.beginning_voxels, 2 * 6 * 6);
        // 10 voxels over 2 of thickness: five times the frame rate.
        assert_eq!(v.rate_factor, 5.0);
        let m = motion(&a, &b);
        assert_eq!(m.displacement, 10);
        assert_eq!(m.vanishing, Some(v));
        // Whole-body test of before (no voxel in common) would miss this: they share the base.
    }

    /// The frames' Hausdorff distance (Chebyshev), voxel by voxel.
    fn brute_displacement(a: &[[u32; 3]], b: &[[u32; 3]]) -> u16 {
        let one_way = |p: &[[u32; 3]], q: &[[u32; 3]]| {
            p.iter()
                .map(|u| {
                    q.iter()
                        .map(|v| (0..3).map(|k| u[k].abs_diff(v[k])).max().unwrap())
                        .min()
                        .unwrap()
                })
                .max()
                .unwrap()
        };
        (one_way(a, b).max(one_way(b, a)).max(1) as u16).min(MAX_DISPLACEMENT)
    }

    #[test]
    fn the_displacement_is_the_frames_hausdorff_distance() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |n: u32| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % u64::from(n)) as u32
        };
        for _ in 0..60 {
            let boxes = |next: &mut dyn FnMut(u32) -> u32| -> Vec<([u32; 3], [u32; 3])> {
                (0..1 + next(3))
                    .map(|_| {
                        let lo = [next(60), next(40), next(30)];
                        (lo, lo.map(|c| c + next(4)))
                    })
                    .collect()
            };
            let (ba, bb) = (boxes(&mut next), boxes(&mut next));
            let voxels = |bs: &[([u32; 3], [u32; 3])]| -> Vec<[u32; 3]> {
                let mut v = Vec::new();
                for (lo, hi) in bs {
                    for z in lo[2]..=hi[2] {
                        for y in lo[1]..=hi[1] {
                            for x in lo[0]..=hi[0] {
                                v.push([x, y, z]);
                            }
                        }
                    }
                }
                v
            };
            let (a, b) = (frame(70, &ba), frame(70, &bb));
            assert_eq!(
                motion(&a, &b).displacement,
                brute_displacement(&voxels(&ba), &voxels(&bb)),
                "{ba:?} {bb:?}"
            );
        }
    }

    #[test]
    fn a_long_thin_part_is_followed_to_its_end() {
        // A 1-voxel-thick snake of 60 voxels touching the next frame only at one end: it
        // carries on (grown voxel by voxel once past the word-parallel steps).
        let snake = ([2, 2, 2], [2, 2, 61]);
        let stub = ([2, 2, 1], [3, 3, 2]);
        assert_eq!(vanishing(&frame(70, &[snake]), &frame(70, &[stub])), None);
        // An extra part far away in the second frame begins from nothing: nothing ends, so
        // the rate cannot be estimated.
        let far = ([50, 50, 50], [52, 52, 52]);
        let v = vanishing(&frame(70, &[snake]), &frame(70, &[stub, far])).unwrap();
        assert_eq!((v.ending_voxels, v.beginning_voxels), (0, 27));
        assert_eq!(v.rate_factor, 0.0);
        let lone = ([40, 40, 40], [40, 40, 40]);
        let v = vanishing(&frame(70, &[snake, lone]), &frame(70, &[stub, far])).unwrap();
        assert_eq!(v.ending_voxels, 1);
    }
}
