//! Validation of tet meshes: closedness with consistent orientation, and hypervolume.
//!
//! A tet [a, b, c, d] induces on its faces the orientation of its boundary
//! `∂[a,b,c,d] = [b,c,d] − [a,c,d] + [a,b,d] − [a,b,c]`. A mesh is closed and consistently
//! oriented when every triangle is shared by exactly two tets that induce opposite
//! orientations on it.
//!
//! Hypervolume by the divergence theorem: with tets oriented so that
//! orient4(a, b, c, d, inside) < 0, V = −(1/24) Σ det[a, b, c, d] (exact in i128).

use rayon::prelude::*;

use super::march::TetMesh;
use chronotope_kernel::{det4_i128, LatticePoint};

/// The result of a closedness check.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClosedReport {
    /// Distinct triangles.
    pub triangles: u64,
    /// Triangles used by exactly one tet.
    pub unpaired: u64,
    /// Triangles used by more than two tets.
    pub overshared: u64,
    /// Triangles shared by two tets that induce the same orientation.
    pub misoriented: u64,
}

impl ClosedReport {
    /// True if closed and consistently oriented.
    pub fn is_closed(&self) -> bool {
        self.unpaired == 0 && self.overshared == 0 && self.misoriented == 0
    }
}

/// Sorts a triangle's vertex ids and returns the parity of the sort (+1 / −1).
#[inline]
pub fn canonical_triangle<T: Ord + Copy>(mut t: [T; 3]) -> ([T; 3], i8) {
    let mut sign = 1i8;
    if t[0] > t[1] {
        t.swap(0, 1);
        sign = -sign;
    }
    if t[1] > t[2] {
        t.swap(1, 2);
        sign = -sign;
    }
    if t[0] > t[1] {
        t.swap(0, 1);
        sign = -sign;
    }
    (t, sign)
}

/// The four boundary triangles of a tet with their induced orientation signs.
#[inline]
pub fn tet_faces<T: Copy>(t: [T; 4]) -> [([T; 3], i8); 4] {
    [
        ([t[1], t[2], t[3]], 1),
        ([t[0], t[2], t[3]], -1),
        ([t[0], t[1], t[3]], 1),
        ([t[0], t[1], t[2]], -1),
    ]
}

/// A tet's four ids sorted, each as `id << 2 | its position in the tet` (so equal ids keep
/// their order), by a sorting network of five compare-exchanges.
#[inline]
pub fn sorted_tet_ids(t: [u32; 4]) -> [u64; 4] {
    let mut k = [0, 1, 2, 3].map(|i| u64::from(t[i]) << 2 | i as u64);
    for (i, j) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
        let (lo, hi) = (k[i].min(k[j]), k[i].max(k[j]));
        (k[i], k[j]) = (lo, hi);
    }
    k
}

/// [`tet_faces`] of a tet of ids, each as [`canonical_triangle`] gives it, from one sort
/// of the four ids: the faces of the sorted tet are canonical already, and each carries the
/// sort's parity (an odd permutation reverses the tet, so every face). Face j omits the
/// j-th smallest id; `order[k]` is the position in `t` of the k-th smallest (equal ids
/// stay in their order).
#[inline]
pub fn canonical_tet_faces(t: [u32; 4]) -> ([([u32; 3], i8); 4], [usize; 4]) {
    let k = sorted_tet_ids(t);
    let order = k.map(|x| (x & 3) as usize);
    // The permutation's parity: its inversions.
    let mut inversions = 0;
    for i in 0..4 {
        for j in i + 1..4 {
            inversions += u32::from(order[i] > order[j]);
        }
    }
    let parity = if inversions % 2 == 0 { 1 } else { -1 };
    let s = k.map(|x| (x >> 2) as u32);
    (
        [
            ([s[1], s[2], s[3]], parity),
            ([s[0], s[2], s[3]], -parity),
            ([s[0], s[1], s[3]], parity),
            ([s[0], s[1], s[2]], -parity),
        ],
        order,
    )
}

/// Checks that every triangle is shared by exactly two tets with opposite induced
/// orientation. Works on vertex ids: weld first if vertices may be duplicated.
pub fn check_closed(mesh: &TetMesh) -> ClosedReport {
    let mut keys = Vec::new();
    let mut scratch = Vec::new();
    check_closed_with(mesh, |_| true, &mut keys, &mut scratch)
}

/// Largest vertex count for which a triangle packs into a u64 key (3 × 21 bits).
pub const PACKED_VERTEX_LIMIT: usize = 1 << 21;

/// Like [`check_closed`] over the faces `keep` accepts (given their three vertex ids),
/// reusing buffers. Faces are packed into u64 keys (three 21-bit ids, orientation in the
/// lowest bit) and radix sorted, so a pair is two adjacent keys differing in bit 0.
pub fn check_closed_with(
    mesh: &TetMesh,
    keep: impl Fn([u32; 3]) -> bool,
    keys: &mut Vec<u64>,
    scratch: &mut Vec<u64>,
) -> ClosedReport {
    if mesh.vertices.len() > PACKED_VERTEX_LIMIT {
        let mut faces: Vec<([u32; 3], i8)> = Vec::with_capacity(mesh.tets.len() * 4);
        for t in &mesh.tets {
            for (f, s) in tet_faces(*t) {
                if keep(f) {
                    let (k, p) = canonical_triangle(f);
                    faces.push((k, s * p));
                }
            }
        }
        return pair_faces(faces);
    }
    keys.clear();
    let bits = id_bits(mesh.vertices.len());
    for t in &mesh.tets {
        for (f, s) in tet_faces(*t) {
            if keep(f) {
                let (k, p) = canonical_triangle(f);
                keys.push(pack_face(k, s * p > 0, bits));
            }
        }
    }
    pair_packed(keys, scratch, bits)
}

/// Bits per vertex id needed for ids `0..n` (at most 21 when `n <=` [`PACKED_VERTEX_LIMIT`]).
pub fn id_bits(n: usize) -> u32 {
    (usize::BITS - n.saturating_sub(1).leading_zeros()).max(1)
}

/// Packs a canonical triangle of vertex ids (each below 2^`bits`) and its orientation into
/// the low 3·bits + 1 bits of a u64.
#[inline]
pub fn pack_face(k: [u32; 3], positive: bool, bits: u32) -> u64 {
    (u64::from(k[0]) << (2 * bits + 1))
        | (u64::from(k[1]) << (bits + 1))
        | (u64::from(k[2]) << 1)
        | u64::from(positive)
}

/// Counts how packed faces (ids of `bits` bits) pair up (see [`check_closed_with`]); `keys`
/// and `scratch` are left in no particular order.
///
/// The faces are bucketed by their smallest id (a counting sort over the ids they span,
/// one pass to count and one to place), and each bucket, the few dozen faces around one
/// vertex, is sorted alone, the buckets on rayon's pool. Faces spread over far more ids
/// than there are faces are radix sorted instead. Both give the report sorting everything
/// gives: a triangle's faces all share its bucket.
pub fn pair_packed(keys: &mut Vec<u64>, scratch: &mut Vec<u64>, bits: u32) -> ClosedReport {
    let shift = 2 * bits + 1;
    let (lo, hi) = keys.iter().fold((u64::MAX, 0), |(lo, hi), &k| {
        (lo.min(k >> shift), hi.max(k >> shift))
    });
    let n = keys.len();
    let span = if n == 0 { 0 } else { (hi - lo) as usize + 1 };
    if n < BUCKET_MIN_FACES || span > 4 * n + 64 || u32::try_from(n).is_err() {
        return pair_radix_sorted(keys, scratch, bits, false).0;
    }
    let faces = || keys.iter().map(|&k| (((k >> shift) - lo) as usize, k));
    pair_in_buckets(count_buckets(span, faces()), faces, n, scratch, false).0
}

/// Counts how packed faces pair up by a radix sort of all their keys; with `keep_single`,
/// the keys of triangles used once are returned rather than counted.
fn pair_radix_sorted(
    keys: &mut Vec<u64>,
    scratch: &mut Vec<u64>,
    bits: u32,
    keep_single: bool,
) -> (ClosedReport, Vec<u64>) {
    radix_sort_u64(keys, scratch, 3 * bits + 1);
    let mut r = ClosedReport::default();
    let mut single = Vec::new();
    for group in packed_groups(keys) {
        match group {
            [one] if keep_single => single.push(*one),
            _ => r.count(group),
        }
    }
    (r, single)
}

/// The bucket ends [`pair_in_buckets`] starts from: `ends[b + 1]` is the number of faces in
/// bucket b below `buckets`.
fn count_buckets(buckets: usize, faces: impl Iterator<Item = (usize, u64)>) -> Vec<u32> {
    let mut ends = vec![0u32; buckets + 1];
    for (b, _) in faces {
        ends[b + 1] += 1;
    }
    ends
}

/// Counts how `len` faces pair up, each given by `faces()` as its bucket below
/// `ends.len() - 1` and a key, with `ends[b + 1]` the number of faces in bucket b: a
/// triangle's faces share a bucket, and two faces of a bucket are of one triangle when
/// their keys agree above bit 0 (the orientation). The buckets are placed in `scratch` (a
/// counting sort's second pass), and each, the few dozen faces around one vertex, is sorted
/// alone; runs of whole buckets, about [`BUCKET_RUN`] faces each, are counted on rayon's
/// pool. With `keep_single`, the keys of triangles used once are returned rather than
/// counted.
fn pair_in_buckets<I: Iterator<Item = (usize, u64)>>(
    mut ends: Vec<u32>,
    faces: impl Fn() -> I,
    len: usize,
    scratch: &mut Vec<u64>,
    keep_single: bool,
) -> (ClosedReport, Vec<u64>) {
    // After the prefix sum ends[b] is bucket b's first slot, and after placing, its end.
    let buckets = ends.len() - 1;
    for b in 0..buckets {
        ends[b + 1] += ends[b];
    }
    // Every slot is written below: only its length matters (no zeroing when it had room).
    scratch.truncate(len);
    scratch.resize(len, 0);
    for (b, key) in faces() {
        let slot = &mut ends[b];
        scratch[*slot as usize] = key;
        *slot += 1;
    }
    ends.truncate(buckets);
    // Runs of whole buckets: each its faces and its buckets' ends (from the run's start).
    let mut runs: Vec<(&mut [u64], Vec<usize>)> = Vec::new();
    let (mut rest, mut cut, mut run_ends) = (scratch.as_mut_slice(), 0usize, Vec::new());
    for &end in &ends {
        let end = end as usize;
        run_ends.push(end - cut);
        if end - cut >= BUCKET_RUN {
            let (run, tail) = std::mem::take(&mut rest).split_at_mut(end - cut);
            runs.push((run, std::mem::take(&mut run_ends)));
            rest = tail;
            cut = end;
        }
    }
    runs.push((rest, run_ends));
    runs.into_par_iter()
        .map(|(run, ends)| {
            let mut r = ClosedReport::default();
            let mut single = Vec::new();
            let mut begin = 0;
            for end in ends {
                let bucket = &mut run[begin..end];
                bucket.sort_unstable();
                for group in packed_groups(bucket) {
                    match group {
                        [one] if keep_single => single.push(*one),
                        _ => r.count(group),
                    }
                }
                begin = end;
            }
            (r, single)
        })
        .reduce(Default::default, add_pairing)
}

/// Two pairings' reports and single faces together.
fn add_pairing(
    (mut a, mut sa): (ClosedReport, Vec<u64>),
    (b, sb): (ClosedReport, Vec<u64>),
) -> (ClosedReport, Vec<u64>) {
    a.triangles += b.triangles;
    a.unpaired += b.unpaired;
    a.overshared += b.overshared;
    a.misoriented += b.misoriented;
    sa.extend(sb);
    (a, sa)
}

/// Below this many faces, [`pair_packed`] radix sorts (its buckets' table would cost more
/// than the sort).
const BUCKET_MIN_FACES: usize = 4096;

/// Faces per run of buckets counted as one task of [`pair_packed`].
const BUCKET_RUN: usize = 1 << 16;

/// Faces a part of a [`FaceParts`] is sized for.
const PART_FACES: usize = 1 << 18;

/// Most ids in a part of a [`FaceParts`] (2^16: its counts, 256 KiB, stay in cache).
const PART_ID_BITS: u32 = 16;

/// How the packed faces of one mesh are split into the parts of a [`FaceParts`]: by their
/// smallest vertex id, 2^`shift` ids per part. Every [`FaceParts`] gathering the faces of
/// one mesh (one per chunk of its tets) has the same shape, so that they can be appended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FaceShape {
    bits: u32,
    shift: u32,
    parts: usize,
}

impl FaceShape {
    /// The shape for about `faces` faces over vertex ids below `vertices` (at most
    /// [`PACKED_VERTEX_LIMIT`]): parts of about `PART_FACES` faces, at most 2^16 ids each.
    pub fn new(vertices: usize, faces: usize) -> Self {
        Self::with_part_faces(vertices, faces, PART_FACES)
    }

    fn with_part_faces(vertices: usize, faces: usize, part_faces: usize) -> Self {
        let bits = id_bits(vertices);
        let want = faces.div_ceil(part_faces.max(1)).max(1);
        let shift = id_bits(vertices.div_ceil(want)).min(PART_ID_BITS);
        Self {
            bits,
            shift,
            parts: vertices.div_ceil(1 << shift).max(1),
        }
    }

    /// An empty gathering with room for about `faces` faces.
    pub fn gather(self, faces: usize) -> FaceParts {
        let ids = 1usize << self.shift;
        let each = faces / self.parts + faces / (8 * self.parts) + 64;
        FaceParts {
            shape: self,
            parts: (0..self.parts)
                .map(|_| FacePart {
                    keys: Vec::with_capacity(each),
                    counts: vec![0; ids + 1],
                })
                .collect(),
        }
    }
}

/// Packed faces (see [`check_closed_with`]) gathered by their smallest vertex id into the
/// parts of a [`FaceShape`], each part counting its faces per id as they come. Pairing them
/// ([`Self::pair`]) then needs neither a pass to find their range nor one to count them,
/// each part's buckets fit in cache, and the parts pair on rayon's pool: the same report as
/// [`pair_packed`] over all the faces (with the faces used once returned, if asked).
#[derive(Debug, Clone)]
pub struct FaceParts {
    shape: FaceShape,
    parts: Vec<FacePart>,
}

#[derive(Debug, Clone)]
struct FacePart {
    keys: Vec<u64>,
    /// `counts[i + 1]`: the faces whose smallest id is the part's i-th.
    counts: Vec<u32>,
}

impl FaceParts {
    /// Adds a canonical triangle of ids below the shape's vertex count, with its orientation.
    #[inline]
    pub fn push(&mut self, k: [u32; 3], positive: bool) {
        let shift = self.shape.shift;
        let part = &mut self.parts[(k[0] >> shift) as usize];
        part.counts[(k[0] & ((1 << shift) - 1)) as usize + 1] += 1;
        part.keys.push(pack_face(k, positive, self.shape.bits));
    }

    /// Counts how the faces `gathered` (of one shape, e.g. one per chunk of a mesh's tets)
    /// pair up; with `keep_single`, the keys of the triangles used once are returned (in no
    /// particular order) rather than counted. Each part's faces are taken together from
    /// every gathering and paired on rayon's pool; `scratch` serves the first part.
    pub fn pair(
        gathered: Vec<FaceParts>,
        scratch: &mut Vec<u64>,
        keep_single: bool,
    ) -> (ClosedReport, Vec<u64>) {
        let Some(shape) = gathered.first().map(|g| g.shape) else {
            return Default::default();
        };
        assert!(
            gathered.iter().all(|g| g.shape == shape),
            "faces gathered in different shapes"
        );
        let FaceShape { bits, shift, parts } = shape;
        // part j: its faces in each gathering.
        let mut by_part: Vec<Vec<FacePart>> = (0..parts).map(|_| Vec::new()).collect();
        for g in gathered {
            for (j, part) in g.parts.into_iter().enumerate() {
                by_part[j].push(part);
            }
        }
        let one = |pieces: Vec<FacePart>, scratch: &mut Vec<u64>| {
            let mut pieces = pieces.into_iter();
            let Some(FacePart {
                mut keys,
                mut counts,
            }) = pieces.next()
            else {
                return Default::default();
            };
            for more in pieces {
                keys.extend_from_slice(&more.keys);
                for (x, y) in counts.iter_mut().zip(&more.counts) {
                    *x += y;
                }
            }
            let n = keys.len();
            if n < BUCKET_MIN_FACES || u32::try_from(n).is_err() {
                return pair_radix_sorted(&mut keys, scratch, bits, keep_single);
            }
            let (at, mask) = (2 * bits + 1, (1u64 << shift) - 1);
            let faces = || keys.iter().map(|&k| (((k >> at) & mask) as usize, k));
            pair_in_buckets(counts, faces, n, scratch, keep_single)
        };
        if let [_] = by_part.as_slice() {
            // One part: paired here (no pool to wait for from a thread outside it).
            return by_part.pop().map(|p| one(p, scratch)).unwrap_or_default();
        }
        let rest = by_part.split_off(1);
        let (first, rest) = rayon::join(
            || by_part.pop().map(|p| one(p, scratch)).unwrap_or_default(),
            || {
                rest.into_par_iter()
                    .map(|p| one(p, &mut Vec::new()))
                    .reduce(Default::default, add_pairing)
            },
        );
        add_pairing(first, rest)
    }
}

/// Runs of sorted packed faces that share a triangle (they differ at most in bit 0, the
/// orientation).
pub fn packed_groups(keys: &[u64]) -> impl Iterator<Item = &[u64]> {
    keys.chunk_by(|a, b| a >> 1 == b >> 1)
}

impl ClosedReport {
    /// Counts one triangle given the packed keys of the tets using it.
    pub fn count(&mut self, group: &[u64]) {
        self.triangles += 1;
        match group {
            [_] => self.unpaired += 1,
            [a, b] => {
                if a == b {
                    self.misoriented += 1;
                }
            }
            _ => self.overshared += 1,
        }
    }
}

/// LSD radix sort of keys whose set bits are all below bit `bits`, 11 bits per pass (the
/// 2048 buckets stay in L1 while scattering).
pub fn radix_sort_u64(v: &mut Vec<u64>, scratch: &mut Vec<u64>, bits: u32) {
    const DIGIT: u32 = 11;
    const MASK: u64 = (1 << DIGIT) - 1;
    // Every slot is written by each pass: only its length matters.
    scratch.truncate(v.len());
    scratch.resize(v.len(), 0);
    let mut counts = vec![0usize; 1 << DIGIT];
    let mut shift = 0;
    while shift < bits {
        counts.iter_mut().for_each(|c| *c = 0);
        for &x in v.iter() {
            counts[((x >> shift) & MASK) as usize] += 1;
        }
        let mut sum = 0;
        for c in counts.iter_mut() {
            let n = *c;
            *c = sum;
            sum += n;
        }
        for &x in v.iter() {
            let d = ((x >> shift) & MASK) as usize;
            scratch[counts[d]] = x;
            counts[d] += 1;
        }
        std::mem::swap(v, scratch);
        shift += DIGIT;
    }
}

/// Groups oriented triangles and counts how they pair up.
pub fn pair_faces<K: Ord + Copy>(mut faces: Vec<(K, i8)>) -> ClosedReport {
    faces.sort_unstable_by_key(|f| f.0);
    pair_sorted(&faces)
}

/// Like [`pair_faces`] for canonical triangles of vertex ids below `n` (too many vertices
/// to pack a triangle into a u64): a counting sort by the smallest id, then each vertex's
/// few triangles sorted alone. O(faces + n) plus small sorts; the same report.
pub fn pair_by_first_vertex(faces: &[([u32; 3], i8)], n: usize) -> ClosedReport {
    let bits = id_bits(n);
    let fits = 2 * bits < 64
        && u32::try_from(faces.len()).is_ok()
        && faces
            .iter()
            .all(|(k, _)| k.iter().all(|&v| (v as usize) < n));
    if !fits {
        return pair_faces(faces.to_vec());
    }
    // Within a bucket (the smallest id) a face is its other two ids and its orientation.
    let rest = |k: &[u32; 3], s: i8| {
        (u64::from(k[1]) << (bits + 1)) | (u64::from(k[2]) << 1) | u64::from(s > 0)
    };
    let len = faces.len();
    let faces = || faces.iter().map(|(k, s)| (k[0] as usize, rest(k, *s)));
    pair_in_buckets(
        count_buckets(n, faces()),
        faces,
        len,
        &mut Vec::new(),
        false,
    )
    .0
}

/// Like [`pair_faces`] for triangles of points in one t plane: each point is packed into a
/// u64 (21 bits per coordinate) when the coordinates allow, which sorts much faster.
pub fn pair_plane_faces(faces: Vec<([[i32; 3]; 3], i8)>) -> ClosedReport {
    const LIM: i32 = 1 << 20;
    if faces.iter().any(|(t, _)| {
        t.iter()
            .any(|p| p.iter().any(|&c| !(-LIM..LIM).contains(&c)))
    }) {
        return pair_faces(faces);
    }
    let pack = |p: &[i32; 3]| {
        ((p[0] + LIM) as u64) << 42 | ((p[1] + LIM) as u64) << 21 | (p[2] + LIM) as u64
    };
    // Packing preserves the order of points, so canonical triangles stay canonical.
    let mut packed: Vec<([u64; 3], i8)> = faces
        .iter()
        .map(|(t, s)| (t.map(|p| pack(&p)), *s))
        .collect();
    packed.sort_unstable_by_key(|f| f.0);
    pair_sorted(&packed)
}

fn pair_sorted<K: Eq>(faces: &[(K, i8)]) -> ClosedReport {
    let mut r = ClosedReport::default();
    let mut i = 0;
    while i < faces.len() {
        let mut j = i + 1;
        while j < faces.len() && faces[j].0 == faces[i].0 {
            j += 1;
        }
        r.triangles += 1;
        match j - i {
            1 => r.unpaired += 1,
            2 => {
                if faces[i].1 == faces[i + 1].1 {
                    r.misoriented += 1;
                }
            }
            _ => r.overshared += 1,
        }
        i = j;
    }
    r
}

/// 24 × hypervolume in lattice units (exact): −Σ det[a, b, c, d]. Only meaningful for a
/// closed mesh (then it does not depend on the origin).
pub fn hypervolume24(mesh: &TetMesh) -> i128 {
    hypervolume24_about(mesh, [0, 0, 0, 0])
}

/// Like [`hypervolume24`] with coordinates taken relative to `origin` (keeps numbers small).
pub fn hypervolume24_about(mesh: &TetMesh, origin: LatticePoint) -> i128 {
    let rel = |p: &LatticePoint| {
        [
            p[0] - origin[0],
            p[1] - origin[1],
            p[2] - origin[2],
            p[3] - origin[3],
        ]
    };
    -mesh
        .tets
        .iter()
        .map(|t| {
            let [a, b, c, d] = t.map(|v| rel(&mesh.vertices[v as usize]));
            det4_i128(&a, &b, &c, &d)
        })
        .sum::<i128>()
}

/// 6 × the 3D volume (lattice units) enclosed by oriented triangles in a hyperplane of
/// constant t, each given with its induced sign; `sign_of_outward` is +1 if the induced
/// orientation is the outward one of the enclosed solid.
pub fn volume6_of_triangles(tris: &[([[i32; 3]; 3], i8)]) -> i128 {
    tris.iter()
        .map(|(t, s)| {
            let m = |p: &[i32; 3]| p.map(i128::from);
            let (a, b, c) = (m(&t[0]), m(&t[1]), m(&t[2]));
            let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]);
            i128::from(*s) * det
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    proptest! {
        /// Bucketing by the smallest id reports exactly what sorting everything does
        /// (faces drawn from few vertices, so triangles repeat and collide often).
        #[test]
        fn pairing_by_first_vertex_equals_sorting(
            raw in prop::collection::vec((0u32..9, 0u32..9, 0u32..9, any::<bool>()), 0..200),
            extra in 0usize..3,
        ) {
            let faces: Vec<([u32; 3], i8)> = raw
                .iter()
                .filter(|(a, b, c, _)| a != b && b != c && a != c)
                .map(|&(a, b, c, s)| {
                    let (k, p) = canonical_triangle([a, b, c]);
                    (k, if s { p } else { -p })
                })
                .collect();
            let n = 9 + extra;
            prop_assert_eq!(pair_by_first_vertex(&faces, n), pair_faces(faces.clone()));
        }
    }

    /// Packed faces counted by bucket (dense ids) and by radix sort (sparse ids, or few
    /// faces) report what sorting everything does. The faces repeat often (pairs, single
    /// ones, three or four of a triangle, both orientations), and there are enough of them
    /// for several runs of buckets on the pool.
    #[test]
    fn packed_pairing_equals_sorting_on_both_paths() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move |m: u32| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % u64::from(m)) as u32
        };
        for (ids, faces, stride) in [
            (3_000u32, 200_000usize, 1u32),
            (50, 5_000, 1),
            (40, 3_000, 1_000),
        ] {
            let bits = id_bits((ids * stride) as usize);
            let mut wide = Vec::new();
            while wide.len() < faces {
                let [a, b, c] = [next(ids), next(ids), next(ids)].map(|v| v * stride);
                if a == b || b == c || a == c {
                    continue;
                }
                let (k, p) = canonical_triangle([a, b, c]);
                // Most triangles twice with opposite orientations; some once, some with
                // the same orientation twice, some three or four times.
                let copies = match next(20) {
                    0 => 1,
                    1 => 3,
                    2 => 4,
                    _ => 2,
                };
                for i in 0..copies {
                    let s = if i % 2 == 0 || next(10) == 0 { p } else { -p };
                    wide.push((k, s));
                }
            }
            // Shuffled, so a bucket's faces arrive apart.
            for i in (1..wide.len()).rev() {
                wide.swap(i, next(i as u32 + 1) as usize);
            }
            let mut keys: Vec<u64> = wide
                .iter()
                .map(|&(k, s)| pack_face(k, s > 0, bits))
                .collect();
            let want = pair_faces(wide.clone());
            assert!(want.unpaired > 0 && want.misoriented > 0 && want.overshared > 0);
            assert_eq!(
                pair_packed(&mut keys, &mut Vec::new(), bits),
                want,
                "{ids} ids x {stride}"
            );
            // With a boundary (below): the triangles used once are given back, not counted.
            let mut once: Vec<u64> = Vec::new();
            let mut sorted: Vec<u64> = wide
                .iter()
                .map(|&(k, s)| pack_face(k, s > 0, bits))
                .collect();
            sorted.sort_unstable();
            for group in packed_groups(&sorted) {
                if let [one] = group {
                    once.push(*one);
                }
            }
            let bounded = ClosedReport {
                unpaired: 0,
                triangles: want.triangles - want.unpaired,
                ..want
            };
            // Gathered in parts (one to many, some with too few faces to bucket) from
            // one to several chunks of the faces: the same reports and single faces.
            for (part_faces, chunks) in [(usize::MAX, 1), (1 << 14, 1), (5_000, 3), (700, 4)] {
                let what = format!("{ids} ids x {stride}, {part_faces} per part, {chunks}");
                let shape = FaceShape::with_part_faces((ids * stride) as usize, faces, part_faces);
                let gather = || {
                    wide.chunks(wide.len().div_ceil(chunks))
                        .map(|c| {
                            let mut g = shape.gather(c.len());
                            c.iter().for_each(|&(k, s)| g.push(k, s > 0));
                            g
                        })
                        .collect::<Vec<_>>()
                };
                assert_eq!(
                    FaceParts::pair(gather(), &mut Vec::new(), false),
                    (want, Vec::new()),
                    "{what}"
                );
                let (report, mut single) = FaceParts::pair(gather(), &mut Vec::new(), true);
                single.sort_unstable();
                assert_eq!((report, single), (bounded, once.clone()), "{what}");
            }
        }
    }

    #[test]
    fn a_tets_faces_from_one_sort_are_each_face_sorted() {
        // Every tuple of four ids below 5 (repeated ids included).
        for n in 0..5u32.pow(4) {
            let t = [n % 5, n / 5 % 5, n / 25 % 5, n / 125];
            let want = tet_faces(t).map(|(f, s)| {
                let (k, p) = canonical_triangle(f);
                (k, s * p)
            });
            let (mut got, order) = canonical_tet_faces(t);
            let mut want = want.to_vec();
            want.sort_unstable();
            got.sort_unstable();
            assert_eq!(got.to_vec(), want, "{t:?}");
            let sorted = order.map(|i| t[i]);
            assert!(sorted.windows(2).all(|w| w[0] <= w[1]), "{t:?}");
            let mut positions = order;
            positions.sort_unstable();
            assert_eq!(positions, [0, 1, 2, 3], "{t:?}");
        }
    }

    #[test]
    fn face_shapes_split_ids_into_parts_that_cover_them() {
        for (vertices, faces, part_faces) in [
            (1, 0, 1),
            (3_000, 200_000, 1 << 18),
            (3_000, 200_000, 700),
            (98_176, 2_156_952, 1 << 18),
            (1 << 21, 1 << 24, 1 << 18),
        ] {
            let shape = FaceShape::with_part_faces(vertices, faces, part_faces);
            assert!(shape.shift <= PART_ID_BITS && shape.shift <= shape.bits);
            assert!(shape.parts << shape.shift >= vertices, "{shape:?}");
            assert!(
                (shape.parts - 1) << shape.shift < vertices.max(1),
                "{shape:?}"
            );
        }
    }

    #[test]
    fn an_id_out_of_range_falls_back_to_sorting() {
        let faces = vec![([0, 1, 7], 1i8), ([0, 1, 7], -1)];
        assert_eq!(pair_by_first_vertex(&faces, 3), pair_faces(faces.clone()));
        assert_eq!(pair_by_first_vertex(&faces, 3).triangles, 1);
    }
}
