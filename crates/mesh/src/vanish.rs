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
//! The test works on the frames' bit rows inside the box both frames' occupied voxels
//! span (copied side by side, a word of 64 voxels at a time): the other frame dilated by one
//! voxel marks the voxels of this frame that carry on; this frame's 26-connected parts are
//! found from its runs of occupied voxels along x (a run joins each run of the rows beside
//! it, in its plane and the next, that it overlaps once widened by one voxel), and a part
//! none of whose runs carries on ends.
//! Nothing outside the box matters: a dilation cut at the box's edge holds every voxel of
//! the box the whole dilation holds (the straight Chebyshev path between two voxels stays
//! in their box), and the parts are parts of one frame.
//!
//! How many times the frame rate would join a vanishing part is estimated from the parts
//! that end in frame k and begin in frame k+1: their centres' distance over the smallest
//! extent of the ending parts (a part moving less than its extent per period stays joined).
//! It is an estimate, said as such; the verdict that a part vanishes is exact.

use super::OccupancyGrid;

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
    let Some(mut pair) = Pair::of(a, b) else {
        return at_most_one;
    };
    let displacement = pair
        .region
        .reach(&pair.a, &pair.b_dilated, &mut pair.scratch)
        .max(
            pair.region
                .reach(&pair.b, &pair.a_dilated, &mut pair.scratch),
        );
    Motion {
        displacement,
        vanishing: pair.vanishing(),
    }
}

/// Whether a part of the body vanishes between frames `a` and `b` (same lattice), and by how
/// much the frame rate would have to rise; `None` when every part carries on.
pub fn vanishing(a: &OccupancyGrid, b: &OccupancyGrid) -> Option<Vanishing> {
    Pair::of(a, b)?.vanishing()
}

/// Two frames that do not join everywhere, in the box of their occupied voxels, each with
/// its dilation by one voxel, and the buffers of further dilations.
struct Pair {
    region: Region,
    a: Vec<u64>,
    b: Vec<u64>,
    a_dilated: Vec<u64>,
    b_dilated: Vec<u64>,
    scratch: Scratch,
}

impl Pair {
    /// `None` when the frames cannot be compared (different lattices, an empty frame) or
    /// every voxel of each has one of the other within one voxel.
    fn of(a: &OccupancyGrid, b: &OccupancyGrid) -> Option<Self> {
        if a.padded != b.padded || a.words != b.words || a.occupied == 0 || b.occupied == 0 {
            return None;
        }
        // The common case, a body moving less than a voxel or so per frame: checked row by
        // row without a buffer.
        if within_one(a, b) && within_one(b, a) {
            return None;
        }
        let region = Region::of(a, b)?;
        let (fa, fb) = (region.copy(&a.bits), region.copy(&b.bits));
        let mut scratch = Scratch::new(region.len());
        let mut a_dilated = vec![0u64; region.len()];
        let mut b_dilated = vec![0u64; region.len()];
        region.dilate(&fa, &mut scratch, &mut a_dilated);
        region.dilate(&fb, &mut scratch, &mut b_dilated);
        Some(Self {
            region,
            a: fa,
            b: fb,
            a_dilated,
            b_dilated,
            scratch,
        })
    }

    fn vanishing(&self) -> Option<Vanishing> {
        let ending = self.region.ends(&self.a, &self.b_dilated);
        let beginning = self.region.ends(&self.b, &self.a_dilated);
        let (ending_voxels, beginning_voxels) = (count(&ending), count(&beginning));
        if ending_voxels == 0 && beginning_voxels == 0 {
            return None;
        }
        let rate_factor = match (
            Extent::of(&self.region, &ending),
            Extent::of(&self.region, &beginning),
        ) {
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
}

/// Whether every occupied voxel of `this` has an occupied voxel of `other` within one voxel
/// on every axis (stops at the first that has none). `other` is dilated by one voxel a plane
/// at a time, along x (shifted words) and then along y, for the planes around each plane of
/// `this` that holds a voxel; three such planes are kept as z goes up, each made once.
fn within_one(this: &OccupancyGrid, other: &OccupancyGrid) -> bool {
    let [_, py, pz] = this.padded;
    let w = this.words;
    if py < 3 || pz < 3 {
        return true;
    }
    let plane = py * w;
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
    // `other`'s plane z dilated along x and y, word (y, i) at y·w + i for 0 < y < py − 1.
    let dilate = |z: usize, out: &mut [u64], rows: &mut [u64]| {
        for y in 0..py {
            for i in 0..w {
                rows[y * w + i] = xdil((y + py * z) * w, i);
            }
        }
        for k in w..plane - w {
            out[k] = rows[k - w] | rows[k] | rows[k + w];
        }
    };
    let mut ring = [vec![0u64; plane], vec![0u64; plane], vec![0u64; plane]];
    let mut made = [usize::MAX; 3];
    let mut rows = vec![0u64; plane];
    for z in 1..pz - 1 {
        let mine = &this.bits[z * plane..][..plane];
        if mine.iter().all(|&t| t == 0) {
            continue;
        }
        for dz in [z - 1, z, z + 1] {
            if made[dz % 3] != dz {
                dilate(dz, &mut ring[dz % 3], &mut rows);
                made[dz % 3] = dz;
            }
        }
        let [p0, p1, p2] = [&ring[(z - 1) % 3], &ring[z % 3], &ring[(z + 1) % 3]];
        for k in w..plane - w {
            let t = mine[k];
            if t != 0 && t & !(p0[k] | p1[k] | p2[k]) != 0 {
                return false;
            }
        }
    }
    true
}

/// The box two frames' occupied voxels span: rows `y`, planes `z` (inclusive, padded grid
/// coordinates) and the grid's words `w0..w0 + words` of each row. Its bit rows lie side by
/// side, row `(y, z)` at `((y - y.0) + ny·(z - z.0))·words`.
struct Region {
    w0: usize,
    words: usize,
    grid_words: usize,
    py: usize,
    y: (usize, usize),
    z: (usize, usize),
}

/// The buffers of a dilation: the rows dilated along x, then along y.
struct Scratch {
    x: Vec<u64>,
    y: Vec<u64>,
}

impl Scratch {
    fn new(len: usize) -> Self {
        Self {
            x: vec![0; len],
            y: vec![0; len],
        }
    }
}

impl Region {
    fn of(a: &OccupancyGrid, b: &OccupancyGrid) -> Option<Self> {
        let [_, py, pz] = a.padded;
        let w = a.words;
        let (mut y0, mut y1, mut z0, mut z1) = (usize::MAX, 0, usize::MAX, 0);
        let (mut w0, mut w1) = (usize::MAX, 0);
        for z in 0..pz {
            for y in 0..py {
                let r = (y + py * z) * w;
                let mut any = false;
                for (i, (wa, wb)) in a.bits[r..r + w].iter().zip(&b.bits[r..r + w]).enumerate() {
                    if (wa | wb) != 0 {
                        any = true;
                        w0 = w0.min(i);
                        w1 = w1.max(i);
                    }
                }
                if any {
                    y0 = y0.min(y);
                    y1 = y1.max(y);
                    z0 = z0.min(z);
                    z1 = z1.max(z);
                }
            }
        }
        (y0 <= y1).then_some(Self {
            w0,
            words: w1 - w0 + 1,
            grid_words: w,
            py,
            y: (y0, y1),
            z: (z0, z1),
        })
    }

    fn ny(&self) -> usize {
        self.y.1 - self.y.0 + 1
    }

    fn nz(&self) -> usize {
        self.z.1 - self.z.0 + 1
    }

    fn len(&self) -> usize {
        self.ny() * self.nz() * self.words
    }

    /// The box's rows of a frame's bits.
    fn copy(&self, bits: &[u64]) -> Vec<u64> {
        let mut out = Vec::with_capacity(self.len());
        for z in self.z.0..=self.z.1 {
            for y in self.y.0..=self.y.1 {
                let r = (y + self.py * z) * self.grid_words + self.w0;
                out.extend_from_slice(&bits[r..r + self.words]);
            }
        }
        out
    }

    /// `out` = `src` dilated by one voxel on every axis (26-neighbourhood) within the box:
    /// along x, then y, then z (the cube is the product of the three segments).
    fn dilate(&self, src: &[u64], scratch: &mut Scratch, out: &mut [u64]) {
        let w = self.words;
        for (o, s) in scratch.x.chunks_exact_mut(w).zip(src.chunks_exact(w)) {
            let mut carry_in = 0u64;
            for i in 0..w {
                let v = s[i];
                let next = if i + 1 < w { s[i + 1] << 63 } else { 0 };
                o[i] = v | (v << 1) | carry_in | (v >> 1) | next;
                carry_in = v >> 63;
            }
        }
        let plane = self.ny() * w;
        for (o, s) in scratch
            .y
            .chunks_exact_mut(plane)
            .zip(scratch.x.chunks_exact(plane))
        {
            or_neighbours(o, s, w);
        }
        or_neighbours(out, &scratch.y, plane);
    }

    /// The least `d` (at most [`MAX_DISPLACEMENT`]) such that every voxel of `this` lies
    /// within `d` voxels of the other frame, whose dilation by one is `first`.
    fn reach(&self, this: &[u64], first: &[u64], scratch: &mut Scratch) -> u16 {
        if covers(first, this) {
            return 1;
        }
        let mut cur = first.to_vec();
        let mut next = vec![0u64; cur.len()];
        for d in 2..=MAX_DISPLACEMENT {
            self.dilate(&cur, scratch, &mut next);
            if covers(&next, this) {
                return d;
            }
            std::mem::swap(&mut cur, &mut next);
        }
        MAX_DISPLACEMENT
    }

    /// The voxels of `this` whose part (26-connected) has no voxel in `reached` (the other
    /// frame dilated by one).
    fn ends(&self, this: &[u64], reached: &[u64]) -> Vec<u64> {
        let (ny, nz, w) = (self.ny(), self.nz(), self.words);
        // Runs of occupied voxels, row by row: (first x, last x), box-local x.
        let mut first = Vec::with_capacity(ny * nz + 1);
        let mut runs: Vec<(u32, u32)> = Vec::new();
        for row in this.chunks_exact(w) {
            first.push(runs.len());
            row_runs(row, &mut runs);
        }
        first.push(runs.len());
        let mut parent: Vec<u32> = (0..runs.len() as u32).collect();
        // Each row joins the rows before it that touch it: (y - 1, z), and (y - 1..=y + 1,
        // z - 1).
        for z in 0..nz {
            for y in 0..ny {
                let r = y + ny * z;
                let mut join = |q: usize| {
                    join_rows(
                        &runs,
                        (first[r], first[r + 1]),
                        (first[q], first[q + 1]),
                        &mut parent,
                    )
                };
                if y > 0 {
                    join(r - 1);
                }
                if z > 0 {
                    let q = r - ny;
                    join(q);
                    if y > 0 {
                        join(q - 1);
                    }
                    if y + 1 < ny {
                        join(q + 1);
                    }
                }
            }
        }
        // Each run with its row's bits.
        let by_row = || {
            first
                .windows(2)
                .enumerate()
                .flat_map(|(r, span)| (span[0]..span[1]).map(move |k| (k, r * w..(r + 1) * w)))
        };
        let mut carries_on = vec![false; runs.len()];
        for (k, row) in by_row() {
            if any_in(&reached[row], runs[k]) {
                let root = find(&mut parent, k as u32);
                carries_on[root as usize] = true;
            }
        }
        let mut out = vec![0u64; this.len()];
        for (k, row) in by_row() {
            if !carries_on[find(&mut parent, k as u32) as usize] {
                set_run(&mut out[row], runs[k]);
            }
        }
        out
    }
}

/// `out[k]` = `s[k - d] | s[k] | s[k + d]` (terms outside `s` left out).
fn or_neighbours(out: &mut [u64], s: &[u64], d: usize) {
    out.copy_from_slice(s);
    let n = s.len();
    if d >= n {
        return;
    }
    for (o, x) in out[d..].iter_mut().zip(&s[..n - d]) {
        *o |= x;
    }
    for (o, x) in out[..n - d].iter_mut().zip(&s[d..]) {
        *o |= x;
    }
}

/// Whether `grown` holds every voxel of `this`.
fn covers(grown: &[u64], this: &[u64]) -> bool {
    this.iter()
        .zip(grown)
        .fold(0u64, |left, (t, g)| left | (t & !g))
        == 0
}

/// Appends the runs of set bits of one row, in order of x.
fn row_runs(row: &[u64], runs: &mut Vec<(u32, u32)>) {
    let mut open: Option<u32> = None;
    for (i, &v) in row.iter().enumerate() {
        if v == 0 {
            continue;
        }
        let prev = if i > 0 { row[i - 1] >> 63 } else { 0 };
        let next = if i + 1 < row.len() {
            row[i + 1] << 63
        } else {
            0
        };
        // First and last voxels of runs in this word.
        let mut starts = v & !((v << 1) | prev);
        let mut ends = v & !((v >> 1) | next);
        let base = 64 * i as u32;
        loop {
            match open {
                None if starts != 0 => {
                    open = Some(base + starts.trailing_zeros());
                    starts &= starts - 1;
                }
                Some(x0) if ends != 0 => {
                    runs.push((x0, base + ends.trailing_zeros()));
                    ends &= ends - 1;
                    open = None;
                }
                _ => break,
            }
        }
    }
}

/// Joins every run of one row with each run of another that touches it (their x ranges,
/// one widened by one voxel, overlap).
fn join_rows(
    runs: &[(u32, u32)],
    (mut i, ie): (usize, usize),
    (mut j, je): (usize, usize),
    parent: &mut [u32],
) {
    while i < ie && j < je {
        let ((a0, a1), (b0, b1)) = (runs[i], runs[j]);
        if a0 <= b1 + 1 && b0 <= a1 + 1 {
            let (ra, rb) = (find(parent, i as u32), find(parent, j as u32));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
        // The run that ends first meets no later run of the other row.
        if a1 < b1 {
            i += 1;
        } else {
            j += 1;
        }
    }
}

fn find(parent: &mut [u32], mut k: u32) -> u32 {
    while parent[k as usize] != k {
        let up = parent[parent[k as usize] as usize];
        parent[k as usize] = up;
        k = up;
    }
    k
}

/// Whether `row` has a set bit in the run's x range.
fn any_in(row: &[u64], (x0, x1): (u32, u32)) -> bool {
    let (x0, x1) = (x0 as usize, x1 as usize);
    (x0 / 64..=x1 / 64).any(|i| row[i] & run_mask(i, x0, x1) != 0)
}

fn set_run(row: &mut [u64], (x0, x1): (u32, u32)) {
    let (x0, x1) = (x0 as usize, x1 as usize);
    for (i, word) in row.iter_mut().enumerate().take(x1 / 64 + 1).skip(x0 / 64) {
        *word |= run_mask(i, x0, x1);
    }
}

/// The bits of word `i` in x range `x0..=x1`.
fn run_mask(i: usize, x0: usize, x1: usize) -> u64 {
    let lo = x0.max(64 * i) - 64 * i;
    let hi = x1.min(64 * i + 63) - 64 * i;
    (u64::MAX >> (63 - hi)) & (u64::MAX << lo)
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
    fn of(region: &Region, bits: &[u64]) -> Option<Self> {
        let mut e = Extent {
            min: [usize::MAX; 3],
            max: [0; 3],
            sum: [0.0; 3],
            n: 0.0,
        };
        let mut rows = bits.chunks_exact(region.words);
        for z in region.z.0..=region.z.1 {
            for y in region.y.0..=region.y.1 {
                let row = rows.next()?;
                for (i, &w) in row.iter().enumerate() {
                    let mut word = w;
                    while word != 0 {
                        let x = 64 * (region.w0 + i) + word.trailing_zeros() as usize;
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
            let ba = boxes(&mut next);
            // Every other case the same boxes moved by at most a voxel on each axis, now and
            // then one of them by two: displacements of 1 and 2 both come.
            let bb = if next(2) == 0 {
                boxes(&mut next)
            } else {
                let far = next(3) == 0;
                ba.iter()
                    .enumerate()
                    .map(|(k, (lo, hi))| {
                        let by = if far && k == 0 { 2 } else { 1 };
                        let d = [0; 3].map(|_| next(2 * by + 1));
                        let m = |c: [u32; 3]| [0, 1, 2].map(|j| (c[j] + d[j]).saturating_sub(by));
                        (m(*lo), m(*hi))
                    })
                    .collect()
            };
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
            let brute = brute_displacement(&voxels(&ba), &voxels(&bb));
            assert_eq!(motion(&a, &b).displacement, brute, "{ba:?} {bb:?}");
            // The shortcut for the common case says so exactly when it is.
            assert_eq!(
                within_one(&a, &b) && within_one(&b, &a),
                brute <= 1,
                "{ba:?} {bb:?}"
            );
        }
    }

    /// What vanishes between two frames, voxel by voxel: the 26-connected parts of each
    /// frame with no voxel of the other within one voxel, their voxels counted, and the rate
    /// factor from their boxes and centres (coordinates summed in z, y, x order).
    fn brute_vanishing(a: &[[u32; 3]], b: &[[u32; 3]]) -> Option<Vanishing> {
        use std::collections::BTreeSet;
        let near = |u: &[u32; 3], v: &[u32; 3]| (0..3).all(|k| u[k].abs_diff(v[k]) <= 1);
        let ends = |this: &[[u32; 3]], other: &[[u32; 3]]| -> Vec<[u32; 3]> {
            let set: BTreeSet<[u32; 3]> = this.iter().copied().collect();
            let mut reached: BTreeSet<[u32; 3]> = set
                .iter()
                .filter(|u| other.iter().any(|v| near(u, v)))
                .copied()
                .collect();
            let mut stack: Vec<[u32; 3]> = reached.iter().copied().collect();
            while let Some(u) = stack.pop() {
                for v in &set {
                    if near(&u, v) && reached.insert(*v) {
                        stack.push(*v);
                    }
                }
            }
            // In scan order: z, then y, then x.
            let mut left: Vec<[u32; 3]> = set.difference(&reached).copied().collect();
            left.sort_by_key(|v| (v[2], v[1], v[0]));
            left
        };
        let (ending, beginning) = (ends(a, b), ends(b, a));
        if ending.is_empty() && beginning.is_empty() {
            return None;
        }
        let extent = |v: &[[u32; 3]]| -> Option<([f64; 3], f64)> {
            if v.is_empty() {
                return None;
            }
            let mut sum = [0.0f64; 3];
            for p in v {
                (0..3).for_each(|k| sum[k] += f64::from(p[k] + 1));
            }
            let side = (0..3)
                .map(|k| {
                    let lo = v.iter().map(|p| p[k]).min().unwrap();
                    let hi = v.iter().map(|p| p[k]).max().unwrap();
                    f64::from(hi - lo + 1)
                })
                .fold(f64::INFINITY, f64::min);
            Some((sum.map(|s| s / v.len() as f64), side))
        };
        let rate_factor = match (extent(&ending), extent(&beginning)) {
            (Some((ce, se)), Some((cf, sf))) => {
                let d = (0..3).map(|k| (cf[k] - ce[k]).powi(2)).sum::<f64>().sqrt();
                (d / se.min(sf).max(1.0)).ceil().clamp(2.0, 1e6) as f32
            }
            _ => 0.0,
        };
        Some(Vanishing {
            ending_voxels: ending.len() as u64,
            beginning_voxels: beginning.len() as u64,
            rate_factor,
        })
    }

    #[test]
    fn what_vanishes_is_what_a_voxel_by_voxel_search_finds() {
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x5eed_0f7a_1e00_d1ce);
        let mut vanished = 0;
        for round in 0..300 {
            // Parts of a few voxels to a few dozen, some across the 64-voxel words (the
            // frame is 70 voxels wide), some on the grid's edge.
            let frame_voxels = |rng: &mut chronotope_kernel::intersect::test_rng::Rng| {
                let mut boxes = Vec::new();
                for _ in 0..rng.range(1, 5) {
                    let lo =
                        [rng.range(0, 69), rng.range(0, 11), rng.range(0, 11)].map(|c| c as u32);
                    let side = [rng.range(1, 8), rng.range(1, 3), rng.range(1, 3)];
                    let hi = [0, 1, 2].map(|k| (lo[k] + side[k] as u32 - 1).min(69));
                    boxes.push((lo, hi));
                }
                // A diagonal chain of single voxels, joined only through edges or corners.
                if rng.range(0, 1) == 0 {
                    let d = [0; 3].map(|_| rng.range(-1, 1));
                    let mut p = [rng.range(0, 69), rng.range(0, 11), rng.range(0, 11)];
                    for _ in 0..rng.range(2, 6) {
                        let v = p.map(|c| c as u32);
                        boxes.push((v, v));
                        p = [0, 1, 2].map(|k| (p[k] + d[k]).clamp(0, [69, 11, 11][k]));
                    }
                }
                boxes
            };
            // The second frame: each part moved by up to 2 voxels, or by up to 10, or
            // gone; sometimes a new one.
            let ba = frame_voxels(&mut rng);
            let mut bb: Vec<([u32; 3], [u32; 3])> = Vec::new();
            for &(lo, hi) in &ba {
                let reach = [0, 2, 2, 2, 10][rng.range(0, 4) as usize];
                if rng.range(0, 9) == 0 {
                    continue;
                }
                let d = [0; 3].map(|_| rng.range(-reach, reach));
                let moved = |c: u32, k: usize| (i64::from(c) + d[k]).clamp(0, 69) as u32;
                bb.push((
                    [0, 1, 2].map(|k| moved(lo[k], k)),
                    [0, 1, 2].map(|k| moved(hi[k], k)),
                ));
            }
            if bb.is_empty() || rng.range(0, 4) == 0 {
                bb.extend(frame_voxels(&mut rng).into_iter().take(1));
            }
            let voxels = |bs: &[([u32; 3], [u32; 3])]| -> Vec<[u32; 3]> {
                let mut v = std::collections::BTreeSet::new();
                for (lo, hi) in bs {
                    for z in lo[2]..=hi[2] {
                        for y in lo[1]..=hi[1] {
                            for x in lo[0]..=hi[0] {
                                v.insert([x, y, z]);
                            }
                        }
                    }
                }
                v.into_iter().collect()
            };
            let (a, b) = (frame(70, &ba), frame(70, &bb));
            let want = brute_vanishing(&voxels(&ba), &voxels(&bb));
            vanished += usize::from(want.is_some());
            assert_eq!(vanishing(&a, &b), want, "round {round}: {ba:?} {bb:?}");
            assert_eq!(motion(&a, &b).vanishing, want, "round {round}");
        }
        // The scenes are not all trivial.
        assert!((30..=270).contains(&vanished), "{vanished} of 300 vanish");
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
