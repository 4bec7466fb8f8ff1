//! The check of one pair ([`check_pair`]): the tree-against-tree walk on all cores with the
//! exact predicate, then both bodies' labels, intervals and contact speeds; and the same walk
//! done piece by piece as the streams arrive ([`StreamWalk`]).

use super::normals::*;
use super::*;

/// The result of checking one pair.
#[derive(Debug, Clone, Default)]
pub struct PairResult {
    /// Labels of the first body's tets.
    pub labels_a: Labeling,
    /// Labels of the second body's tets.
    pub labels_b: Labeling,
    /// Candidate tet pairs whose boxes overlap.
    pub candidate_pairs: u64,
    /// Pairs whose boundaries cross (or overlap coplanar with the same orientation).
    pub interfering_pairs: u64,
    /// Checker-time ranges where the bodies overlap, merged and sorted.
    pub intervals: Vec<(f64, f64)>,
    /// For each interval, how fast the boundaries approach at its start and recede at its
    /// end (voxels per frame period; see `contact_speeds`).
    pub interval_speeds: Vec<(Option<f64>, Option<f64>)>,
    /// Where the time went.
    pub timing: PairTiming,
}

/// Wall-clock seconds of the phases of [`check_pair`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairTiming {
    /// Tree traversal and exact tet-pair classification.
    pub detect_s: f64,
    /// Labels of both bodies (inclusion tests and propagation) and the intervals.
    pub label_s: f64,
}

impl PairResult {
    /// True if the bodies' interiors overlap somewhere in space-time.
    pub fn interfering(&self) -> bool {
        let (a, b) = (self.labels_a.counts(), self.labels_b.counts());
        a.interference + a.inside + b.interference + b.inside > 0
    }
    /// The same result with the two bodies' roles exchanged.
    pub fn swapped(mut self) -> Self {
        std::mem::swap(&mut self.labels_a, &mut self.labels_b);
        self
    }
    /// Label counts of both bodies.
    pub fn counts(&self) -> (LabelCounts, LabelCounts) {
        (self.labels_a.counts(), self.labels_b.counts())
    }
    /// The earliest checker time of overlap.
    pub fn first_contact(&self) -> Option<f64> {
        self.intervals.first().map(|r| r.0)
    }
}

/// One worker's share of a pair check.
#[derive(Debug, Default)]
pub(super) struct Part {
    pub(super) hit_a: Vec<Touch>,
    pub(super) hit_b: Vec<Touch>,
    /// Time ranges of the interfering pairs, with the pair.
    pub(super) ranges: Vec<(f64, f64, u32, u32)>,
    pub(super) candidate_pairs: u64,
    pub(super) interfering_pairs: u64,
    /// Coplanar pairs facing each other, held back (see [`visit`]).
    pub(super) facing: Vec<(u32, u32)>,
}

/// How many node-pair levels the tree-against-tree walk is split at for the workers
/// (at most 4^6 independent sub-walks).
pub(super) const SPLIT_DEPTH: u32 = 6;

/// Checks two prepared bodies: the tree walk and exact predicate on all cores, then the
/// two bodies' labels side by side. The result does not depend on the number of threads.
pub fn check_pair(a: &Prepared, b: &Prepared) -> PairResult {
    let start = std::time::Instant::now();
    let all = walk(a, b, false);
    finish_pair(a, b, all, start)
}

/// One tet pair whose boundaries cross: the checker-time range of their section, and the
/// two tets (indices in the leaf order of the bodies' meshes).
pub type CrossingPair = (f64, f64, u32, u32);

/// [`check_pair`], with every crossing tet pair it found (in no particular order).
pub fn check_pair_detailed(a: &Prepared, b: &Prepared) -> (PairResult, Vec<CrossingPair>) {
    let start = std::time::Instant::now();
    let all = walk(a, b, false);
    let crossings = all.ranges.clone();
    (finish_pair(a, b, all, start), crossings)
}

/// [`check_pair`] with the walk done as the bodies' pieces arrived (`walked`, over `a`
/// and `b` prepared from those same pieces and placed as they are): only the labels are
/// left. If `walked` did not see every tet of both bodies, the walk is done here.
pub fn check_pair_walked(a: &Prepared, b: &Prepared, walked: StreamWalk) -> PairResult {
    if walked.tets() != (a.mesh.tets.len(), b.mesh.tets.len()) {
        return check_pair(a, b);
    }
    finish_pair(a, b, walked.part, std::time::Instant::now())
}

/// The labels and the rest of a [`PairResult`] after the walk (`all`, started at `start`).
pub(super) fn finish_pair(
    a: &Prepared,
    b: &Prepared,
    all: Part,
    start: std::time::Instant,
) -> PairResult {
    let mut r = PairResult {
        candidate_pairs: all.candidate_pairs,
        interfering_pairs: all.interfering_pairs,
        ..PairResult::default()
    };
    let mut ranges: Vec<(f64, f64)> = all.ranges.iter().map(|r| (r.0, r.1)).collect();
    r.timing.detect_s = start.elapsed().as_secs_f64();
    let start = std::time::Instant::now();
    let (la, lb) = rayon::join(
        || label_against(a, b, &all.hit_a),
        || label_against(b, a, &all.hit_b),
    );
    r.labels_a = la;
    r.labels_b = lb;
    for (p, labels) in [(a, &r.labels_a), (b, &r.labels_b)] {
        for (i, l) in labels.labels.iter().enumerate() {
            if *l == labels::Label::Inside {
                ranges.push(t_range(&tet_of(&p.mesh, i as u32)));
            }
        }
    }
    r.intervals = merge_ranges(ranges);
    r.interval_speeds = r
        .intervals
        .iter()
        .map(|&(s, e)| contact_speeds(a, b, &all.ranges, s, e))
        .collect();
    r.timing.label_s = start.elapsed().as_secs_f64();
    r
}

/// How fast the two boundaries approach at `start` and recede at `end` (voxels per frame
/// period), from the interfering pairs within one frame period of each end: each body's
/// boundary patch there moves along its spatial normal at −N_t/|N_s| (outward normals N
/// summed over the patch's tets, which smooths voxel staircases); the closing speed is
/// the sum for the two bodies, positive while they approach. `None` where no pair lies
/// near that end (an end made by a body starting or ending inside the other).
pub(super) fn contact_speeds(
    a: &Prepared,
    b: &Prepared,
    pairs: &[(f64, f64, u32, u32)],
    start: f64,
    end: f64,
) -> (Option<f64>, Option<f64>) {
    let frame = (a.factor as f64) * f64::from(a.geometry.scale);
    let speed = |near: &dyn Fn(&(f64, f64, u32, u32)) -> bool| -> Option<f64> {
        let (mut ta, mut tb): (Vec<u32>, Vec<u32>) =
            pairs.iter().filter(|p| near(p)).map(|p| (p.2, p.3)).unzip();
        if ta.is_empty() {
            return None;
        }
        let surface = |tets: &mut Vec<u32>, m: &TetMesh| {
            tets.sort_unstable();
            tets.dedup();
            let mut n = [0.0f64; 4];
            for &t in tets.iter() {
                let v = chronotope_kernel::float::tet_normal(&tet_of(m, t));
                (0..4).for_each(|k| n[k] += v[k]);
            }
            let ns = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            (ns > 0.0).then(|| -n[3] / ns)
        };
        Some(surface(&mut ta, &a.mesh)? + surface(&mut tb, &b.mesh)?)
    };
    (
        speed(&|p| p.0 >= start && p.0 <= start + frame),
        speed(&|p| p.1 <= end && p.1 >= end - frame).map(|v| -v),
    )
}

/// Whether two bodies interfere, exactly as [`check_pair`] decides it, but stopping at
/// the first interfering tet pair; the labels are computed only when no pair crosses
/// (then only containment can make them interfere).
pub fn interferes(a: &Prepared, b: &Prepared) -> bool {
    let all = walk(a, b, true);
    if all.interfering_pairs > 0 {
        return true;
    }
    let inside = |p: &Prepared, other: &Prepared, hit: &[Touch]| {
        labels::any_inside(
            &p.adjacency,
            hit,
            p.components(),
            &mut TetInside::of(p, other),
        )
    };
    let (a_inside, b_inside) =
        rayon::join(|| inside(a, b, &all.hit_a), || inside(b, a, &all.hit_b));
    a_inside || b_inside
}

/// The tree-against-tree walk with the exact predicate, split over all cores; with
/// `stop_at_interference` every worker stops once any finds an interfering pair.
pub(super) fn walk(a: &Prepared, b: &Prepared, stop_at_interference: bool) -> Part {
    let mut tops = Vec::new();
    top_pairs(&a.bvh, &b.bvh, SPLIT_DEPTH, &mut tops);
    let threads = rayon::current_num_threads()
        .clamp(1, 8)
        .min(tops.len().max(1));
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let work = || {
        let mut part = Part {
            hit_a: vec![Touch::Clear; a.mesh.tets.len()],
            hit_b: vec![Touch::Clear; b.mesh.tets.len()],
            ranges: Vec::new(),
            candidate_pairs: 0,
            interfering_pairs: 0,
            facing: Vec::new(),
        };
        let mut ws = TraverseWorkspace::new();
        while !stop.load(Ordering::Relaxed) {
            let k = next.fetch_add(1, Ordering::Relaxed);
            let Some(&top) = tops.get(k) else { break };
            let _ = overlapping_boxes_under(&a.bvh, &b.bvh, top, &mut ws, |i, j, bi, bj| {
                visit(Side::of(a), Side::of(b), (i, bi), (j, bj), &mut part);
                if stop_at_interference && part.interfering_pairs > 0 {
                    stop.store(true, Ordering::Relaxed);
                    return ControlFlow::Break(());
                }
                ControlFlow::Continue(())
            });
        }
        part
    };
    let parts: Vec<Part> = if threads == 1 {
        vec![work()]
    } else {
        // One part per worker (each holds a flag per tet of both bodies), the top pairs
        // taken in turn; the parts are merged with commutative operations.
        let done = std::sync::Mutex::new(Vec::with_capacity(threads));
        rayon::scope(|s| {
            for _ in 0..threads {
                s.spawn(|_| {
                    let part = work();
                    done.lock().unwrap_or_else(|e| e.into_inner()).push(part);
                });
            }
        });
        done.into_inner().unwrap_or_else(|e| e.into_inner())
    };
    let mut parts = parts.into_iter();
    let mut all = parts.next().expect("at least one worker");
    for p in parts {
        for (x, y) in all.hit_a.iter_mut().zip(&p.hit_a) {
            *x = (*x).max(*y);
        }
        for (x, y) in all.hit_b.iter_mut().zip(&p.hit_b) {
            *x = (*x).max(*y);
        }
        all.ranges.extend(p.ranges);
        all.candidate_pairs += p.candidate_pairs;
        all.interfering_pairs += p.interfering_pairs;
        all.facing.extend(p.facing);
    }
    settle_facing(Side::of(a), Side::of(b), &mut all);
    all
}

/// The instant k if the tets' time ranges meet only there, with at most one of the tets
/// lying in the time plane t = k (a cap tet). Then the pair can neither cross nor overlap
/// in a hyperplane, only touch, and A ∩ B = F_A ∩ F_B for the faces F of A and B spanned
/// by their vertices at t = k: A ∩ B lies in t = k, where each tet is that face (a linear
/// function is extreme on a convex set only on a face); the relative interior of a tet
/// that is not flat in time misses t = k, and a tet in t = k shares no hyperplane with one
/// that is not.
#[inline]
pub(super) fn one_instant(ta: &[LatticePoint; 4], tb: &[LatticePoint; 4]) -> Option<i32> {
    let range = |t: &[LatticePoint; 4]| {
        let lo = t[0][3].min(t[1][3]).min(t[2][3].min(t[3][3]));
        let hi = t[0][3].max(t[1][3]).max(t[2][3].max(t[3][3]));
        (lo, hi)
    };
    let ((alo, ahi), (blo, bhi)) = (range(ta), range(tb));
    if alo == ahi && blo == bhi {
        None
    } else if ahi == blo {
        Some(ahi)
    } else if bhi == alo {
        Some(alo)
    } else {
        None
    }
}

/// Whether the faces at t = `instant` of two tets (see [`one_instant`]) are apart, so that
/// the tets do not meet (exact; see [`faces_apart_on`]).
#[inline]
pub(super) fn faces_apart(ta: &[LatticePoint; 4], tb: &[LatticePoint; 4], instant: i32) -> bool {
    faces_apart_on(ta, tb, 3, instant)
}

/// Whether the faces in the plane x_`axis` = `c` of two tets (their vertices there) are
/// apart, so that tets that can only meet in that plane (see [`one_instant`]) do not meet
/// (exact): their boxes are disjoint, or one face is a triangle with the other on one side
/// of its plane. A tet with no vertex in the plane has an empty face there.
#[inline]
pub(super) fn faces_apart_on(
    ta: &[LatticePoint; 4],
    tb: &[LatticePoint; 4],
    axis: usize,
    c: i32,
) -> bool {
    let (fa, fb) = (InPlane::of(ta, axis, c), InPlane::of(tb, axis, c));
    // Where the boxes meet, the faces are still apart if one of them is a triangle whose
    // plane (within the hyperplane x_axis = c) has the other's points strictly on one side.
    fa.boxes_apart(&fb) || fa.strictly_beside(&fb) || fb.strictly_beside(&fa)
}

/// A tet's vertices in the hyperplane x_`axis` = c, with that coordinate dropped (see
/// [`faces_apart_on`]).
struct InPlane {
    points: [[i64; 3]; 4],
    len: usize,
}

impl InPlane {
    #[inline]
    fn of(t: &[LatticePoint; 4], axis: usize, c: i32) -> Self {
        let mut points = [[0; 3]; 4];
        let mut len = 0;
        for v in t.iter().filter(|v| v[axis] == c) {
            let mut k = 0;
            for (d, &x) in v.iter().enumerate() {
                if d != axis {
                    points[len][k] = i64::from(x);
                    k += 1;
                }
            }
            len += 1;
        }
        Self { points, len }
    }

    /// Whether the boxes of the two point sets are disjoint (an empty set is apart from
    /// everything).
    #[inline]
    fn boxes_apart(&self, other: &InPlane) -> bool {
        if self.len == 0 || other.len == 0 {
            return true;
        }
        let bounds = |f: &InPlane, k: usize| {
            let xs = f.points[..f.len].iter().map(|p| p[k]);
            (xs.clone().min().unwrap_or(0), xs.max().unwrap_or(0))
        };
        (0..3).any(|k| {
            let ((alo, ahi), (blo, bhi)) = (bounds(self, k), bounds(other, k));
            ahi < blo || bhi < alo
        })
    }

    /// Whether this is a triangle (three points not on one line) whose plane has every
    /// point of `other` strictly on one side of it, so that the two do not meet (exact:
    /// lattice coordinates, the determinants in i128).
    #[inline]
    fn strictly_beside(&self, other: &InPlane) -> bool {
        if self.len != 3 || other.len == 0 {
            return false;
        }
        let [p, q, r, _] = self.points;
        let d = |a: [i64; 3], b: [i64; 3]| [0, 1, 2].map(|k| i128::from(a[k] - b[k]));
        let (u, v) = (d(q, p), d(r, p));
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        if n == [0; 3] {
            return false;
        }
        let side = |x: &[i64; 3]| {
            let w = d(*x, p);
            (n[0] * w[0] + n[1] * w[1] + n[2] * w[2]).signum()
        };
        let first = side(&other.points[0]);
        first != 0 && other.points[1..other.len].iter().all(|x| side(x) == first)
    }
}

/// What the walk reads of a body: its tets and their normals.
#[derive(Clone, Copy)]
pub(super) struct Side<'a> {
    mesh: &'a TetMesh,
    normals: &'a [[i32; 4]],
}

impl<'a> Side<'a> {
    fn of(p: &'a Prepared) -> Self {
        Self {
            mesh: &p.mesh,
            normals: &p.normals,
        }
    }
}

/// The tree walk of one pair of bodies done as their pieces arrive (see [`prep`]): each
/// new piece of either body is walked against the pieces of the other that came before
/// it, so that every pair of pieces is walked once and, at the end of the stream, only
/// the labels are left ([`check_pair_walked`]).
///
/// Valid only if both bodies are already on the common lattice as prepared (same
/// lattice, same first frame: [`CommonLattice::places_as_is`]); otherwise the walk is
/// done again at the end.
#[derive(Debug, Default)]
pub struct StreamWalk {
    part: Part,
    /// Pieces of each body walked so far.
    seen: (usize, usize),
}

impl StreamWalk {
    /// Nothing walked yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Walks the pieces of `a` and `b` that came since the last call.
    pub fn advance(&mut self, a: &BodyPrep, b: &BodyPrep) {
        let (fa, fb) = (a.forest(), b.forest());
        let (na, nb) = (fa.pieces(), fb.pieces());
        let (sa, sb) = self.seen;
        if (na, nb) == (sa, sb) {
            return;
        }
        let part = &mut self.part;
        part.hit_a.resize(a.len(), Touch::Clear);
        part.hit_b.resize(b.len(), Touch::Clear);
        let (side_a, side_b) = (
            Side {
                mesh: a.mesh(),
                normals: a.normals(),
            },
            Side {
                mesh: b.mesh(),
                normals: b.normals(),
            },
        );
        let (ta, tb) = (fa.tree_so_far(), fb.tree_so_far());
        let mut ws = TraverseWorkspace::new();
        // New pieces of `a` against every piece of `b`, then old pieces of `a` against
        // the new ones of `b`.
        let pairs = (sa..na)
            .flat_map(|i| (0..nb).map(move |j| (i, j)))
            .chain((0..sa).flat_map(|i| (sb..nb).map(move |j| (i, j))));
        for (i, j) in pairs {
            let (Some((ra, ba)), Some((rb, bb))) = (fa.piece_root(i), fb.piece_root(j)) else {
                continue;
            };
            if !ba.overlaps(&bb) {
                continue;
            }
            let _ =
                overlapping_boxes_under(ta, tb, NodePair::new(ra, rb), &mut ws, |i, j, bi, bj| {
                    visit(side_a, side_b, (i, bi), (j, bj), part);
                    ControlFlow::<()>::Continue(())
                });
        }
        settle_facing(side_a, side_b, part);
        self.seen = (na, nb);
    }

    /// Tets of each body walked so far.
    pub fn tets(&self) -> (usize, usize) {
        (self.part.hit_a.len(), self.part.hit_b.len())
    }
}

/// One candidate pair (tets `i` of A and `j` of B, with boxes holding them): the exact
/// relation, recorded in the worker's share.
#[inline]
pub(super) fn visit(
    a: Side<'_>,
    b: Side<'_>,
    (i, box_a): (u32, &Aabb4),
    (j, box_b): (u32, &Aabb4),
    part: &mut Part,
) {
    part.candidate_pairs += 1;
    let (ha, hb) = (part.hit_a[i as usize], part.hit_b[j as usize]);
    // Whether the pair merely touches matters only to a tet not yet known to touch.
    let touching_matters = ha < Touch::Contact || hb < Touch::Contact;
    // On one lattice most candidates are tets of neighbouring cells (or of consecutive
    // slabs) whose boxes meet in one plane only: such a pair can at most touch (see
    // [`plane_of_meeting`]), which matters only to a tet not yet known to touch. Both tets
    // are then taken as touching, from the boxes and normals alone, without a vertex read:
    // a contact tet is labelled on its own by the exact tests that label its region, so one
    // that does not touch after all costs one test and changes no label (see
    // [`crate::labels`]). Two bodies resting face to face make millions of such pairs, and
    // nearly every tet in them touches anyway.
    if plane_of_meeting(
        (box_a, &a.normals[i as usize]),
        (box_b, &b.normals[j as usize]),
    )
    .is_some()
    {
        if touching_matters {
            part.hit_a[i as usize] = ha.max(Touch::Contact);
            part.hit_b[j as usize] = hb.max(Touch::Contact);
        }
        return;
    }
    let (ta, tb) = (tet_of(&a.mesh, i), tet_of(&b.mesh, j));
    // The same rule in time from the tets' own time ranges: for a tet without a known
    // normal, or boxes larger than their tets (a body placed by a shearing map).
    if let Some(instant) = one_instant(&ta, &tb) {
        if !touching_matters || faces_apart(&ta, &tb, instant) {
            return;
        }
    }
    visit_tets(a, b, (i, &ta), (j, &tb), part);
}

/// [`visit`] once the tets are read: the cheap exact tests on the tets' hyperplanes, the
/// facing pairs held back, then the exact relation.
#[inline]
fn visit_tets(
    a: Side<'_>,
    b: Side<'_>,
    (i, ta): (u32, &[LatticePoint; 4]),
    (j, tb): (u32, &[LatticePoint; 4]),
    part: &mut Part,
) {
    let (ha, hb) = (part.hit_a[i as usize], part.hit_b[j as usize]);
    let touching_matters = ha < Touch::Contact || hb < Touch::Contact;
    // Most other candidates lie strictly on one side of the other's hyperplane.
    let sides_of_b = sides(&a.normals[i as usize], ta, tb);
    if sides_of_b.is_some_and(|s| strictly_one_side(&s)) {
        return;
    }
    // Face to face (two bodies resting on each other, meshed on one lattice), most
    // candidates are coplanar pairs of tets facing each other. Such a pair never
    // interferes: it can only make its tets touch, or face each other. A tet's twin (the
    // same four points) settles that at once; any other facing pair waits for the end of
    // the walk, when most are moot (both tets face to face by then).
    if sides_of_b == Some([0; 4]) && facing(&a.normals[i as usize], &b.normals[j as usize]) {
        if same_points(ta, tb) {
            part.hit_a[i as usize] = ha.max(Touch::Twin);
            part.hit_b[j as usize] = hb.max(Touch::Twin);
        } else if ha < Touch::FaceToFace || hb < Touch::FaceToFace {
            part.facing.push((i, j));
            if part.facing.len() >= FACING_HELD {
                settle_facing(a, b, part);
            }
        }
        return;
    }
    let sides_of_a = sides(&b.normals[j as usize], tb, ta);
    if sides_of_a.is_some_and(|s| strictly_one_side(&s)) {
        return;
    }
    // Unless both straddle the other's hyperplane (they may cross) or B lies in A's
    // hyperplane (coplanar, or A flat), the pair can at most touch: what classify_if
    // would call Disjoint when touching does not matter.
    if let (false, Some(sb), Some(sa)) = (touching_matters, sides_of_b, sides_of_a) {
        if sb != [0; 4] && !(straddles(&sb) && straddles(&sa)) {
            return;
        }
    }
    relate(ta, tb, i, j, touching_matters, part);
}

/// The plane x_k = c (as `(k, c)`) where two tets, held by boxes `box_a` and `box_b` that
/// overlap, can only touch: the boxes meet in that plane only, and one of the tets does
/// not lie in it (its normal, known, has a component other than k). Then A ∩ B lies in
/// the plane, where that tet (on one side of it, not in it) has a proper face: the two
/// relative interiors do not meet (no crossing) and A ∩ B has no 3-volume (no coplanar
/// overlap); A ∩ B is the meet of their faces in the plane (see [`faces_apart_on`]). This
/// is [`one_instant`] on every axis. A tet whose normal is not known ([`NO_NORMAL`]) or
/// vanishes is taken as lying in the plane. Exact.
#[inline]
pub(super) fn plane_of_meeting(
    (box_a, na): (&Aabb4, &[i32; 4]),
    (box_b, nb): (&Aabb4, &[i32; 4]),
) -> Option<(usize, i32)> {
    let off_plane = |n: &[i32; 4], k: usize| *n != NO_NORMAL && (0..4).any(|m| m != k && n[m] != 0);
    (0..4).find_map(|k| {
        let c = if box_a.max[k] == box_b.min[k] {
            box_a.max[k]
        } else if box_b.max[k] == box_a.min[k] {
            box_b.max[k]
        } else {
            return None;
        };
        (off_plane(na, k) || off_plane(nb, k)).then_some((k, c))
    })
}

/// Facing pairs a worker holds before it settles them.
const FACING_HELD: usize = 1 << 16;

/// Settles the facing pairs `part` holds back (see [`visit`]): each one whose tets are not
/// both face to face already, as [`visit`] would have. The touches only grow, so the
/// order does not change what they end as.
pub(super) fn settle_facing(a: Side<'_>, b: Side<'_>, part: &mut Part) {
    let facing = std::mem::take(&mut part.facing);
    for &(i, j) in &facing {
        let (ha, hb) = (part.hit_a[i as usize], part.hit_b[j as usize]);
        if ha >= Touch::FaceToFace && hb >= Touch::FaceToFace {
            continue;
        }
        let touching_matters = ha < Touch::Contact || hb < Touch::Contact;
        relate(
            &tet_of(a.mesh, i),
            &tet_of(b.mesh, j),
            i,
            j,
            touching_matters,
            part,
        );
    }
    part.facing = facing;
    part.facing.clear();
}

/// The same four points (in any order).
#[inline]
fn same_points(ta: &[LatticePoint; 4], tb: &[LatticePoint; 4]) -> bool {
    ta.iter().all(|p| tb.contains(p))
}

/// The exact relation of tets `i` of A and `j` of B, recorded in `part`.
fn relate(
    ta: &[LatticePoint; 4],
    tb: &[LatticePoint; 4],
    i: u32,
    j: u32,
    touching_matters: bool,
    part: &mut Part,
) {
    let (ha, hb) = (part.hit_a[i as usize], part.hit_b[j as usize]);
    // Where the two tets meet in time: their section polygon for a crossing; for a
    // coplanar overlap, within both time ranges.
    let (range, touch) = match classify_if(ta, tb, touching_matters) {
        TetPairRelation::Crossing => (
            Some(contact::crossing_t_range(ta, tb).unwrap_or_else(|| overlap_t(ta, tb))),
            Touch::Interference,
        ),
        TetPairRelation::Coplanar {
            overlap_volume_positive: true,
            same_orientation: true,
        } => (Some(overlap_t(ta, tb)), Touch::Interference),
        TetPairRelation::Coplanar {
            overlap_volume_positive: true,
            same_orientation: false,
        } => (None, Touch::FaceToFace),
        TetPairRelation::Coplanar { .. } | TetPairRelation::Touching => (None, Touch::Contact),
        TetPairRelation::Disjoint => return,
    };
    if let Some(range) = range {
        part.interfering_pairs += 1;
        part.ranges.push((range.0, range.1, i, j));
    }
    part.hit_a[i as usize] = ha.max(touch);
    part.hit_b[j as usize] = hb.max(touch);
}

/// The common time range of two tets.
pub(super) fn overlap_t(ta: &[LatticePoint; 4], tb: &[LatticePoint; 4]) -> (f64, f64) {
    let (ra, rb) = (t_range(ta), t_range(tb));
    (ra.0.max(rb.0), ra.1.min(rb.1))
}

pub(super) fn label_against(p: &Prepared, other: &Prepared, hit: &[Touch]) -> Labeling {
    label_regions(&p.adjacency, hit, &mut TetInside::of(p, other))
}

/// Interior point (w·tet)/8 of a tet for weights `w` of [`INTERIOR_WEIGHTS`]: checker
/// coordinates are ×8 (and stay so under positive axis maps), so it is a lattice point.
pub(super) fn interior_point(tet: &[LatticePoint; 4], w: &[i64; 4]) -> LatticePoint {
    [0, 1, 2, 3].map(|k| ((0..4).map(|v| w[v] * i64::from(tet[v][k])).sum::<i64>() / 8) as i32)
}

/// Where inclusion tests read a body's tets: as its mesh holds them, or seen through a map
/// into another frame (the resolution's unplaced check).
pub(super) trait TetSource {
    /// Tet `t`'s vertices.
    fn tet(&self, t: u32) -> [LatticePoint; 4];
}

impl TetSource for &TetMesh {
    #[inline]
    fn tet(&self, t: u32) -> [LatticePoint; 4] {
        tet_of(self, t)
    }
}

/// Inclusion tests of one body's tets (read from `mesh`) against the other body.
pub(super) struct TetInside<'a, S = &'a TetMesh> {
    pub(super) mesh: S,
    pub(super) inc: Inclusion<'a>,
}

impl<'a> TetInside<'a> {
    /// Tests of `p`'s tets against the whole of `other`.
    fn of(p: &'a Prepared, other: &'a Prepared) -> Self {
        Self {
            mesh: &p.mesh,
            inc: Inclusion::with_normals(&other.mesh, &other.bvh, &other.normals),
        }
    }
}

impl<S: TetSource> labels::InsideTest for TetInside<'_, S> {
    fn far(&mut self, t: u32, tries: usize) -> Option<(bool, LatticePoint)> {
        // A tet lying in one tet of the other boundary has every point on it: each try
        // would be undecided.
        let tet = self.mesh.tet(t);
        if tries > 1
            && self
                .inc
                .lies_in_boundary(&interior_point(&tet, &INTERIOR_WEIGHTS[0]), &tet)
        {
            return None;
        }
        INTERIOR_WEIGHTS.iter().take(tries).find_map(|w| {
            let c = interior_point(&tet, w);
            self.inc.contains(&c).map(|inside| (inside, c))
        })
    }
    fn from_known(
        &mut self,
        t: u32,
        q: &LatticePoint,
        q_inside: bool,
    ) -> Option<(bool, LatticePoint)> {
        let c = self.point(t);
        self.inc
            .contains_from(&c, q, q_inside)
            .map(|inside| (inside, c))
    }
    fn point(&self, t: u32) -> LatticePoint {
        interior_point(&self.mesh.tet(t), &INTERIOR_WEIGHTS[0])
    }
    fn lies_in_boundary(&mut self, t: u32) -> bool {
        let tet = self.mesh.tet(t);
        self.inc
            .lies_in_boundary(&interior_point(&tet, &INTERIOR_WEIGHTS[0]), &tet)
    }
}

/// Sorts closed ranges and merges those that overlap or touch.
pub fn merge_ranges(mut v: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    v.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (s, e) in v {
        match out.last_mut() {
            Some(last) if s <= last.1 => last.1 = last.1.max(e),
            _ => out.push((s, e)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronotope_kernel::intersect::test_rng::Rng;
    use chronotope_kernel::tets_intersect;

    fn prepared(mesh: &TetMesh) -> Prepared {
        let local = prep::BodyPrep::of(mesh, &[0]).expect("a preparation");
        Prepared {
            id: "body".into(),
            mesh: local.mesh,
            bvh: local.bvh,
            adjacency: local.adjacency.into(),
            components: Default::default(),
            normals: local.normals,
            factor: CHECKER_FACTOR,
            geometry: GridGeometry {
                origin: [0.0; 3],
                resolution: 1.0,
                size: [1, 1, 1],
                encoding: 0,
                scale: 1,
            },
            original: local.original.into(),
        }
    }

    /// The walk's touches and interfering pairs against every pair classified on its own,
    /// for two bodies made to face each other: many tets of B are twins of A's (the same
    /// points, either orientation), others overlap them in part or touch them in the same
    /// hyperplanes, others cross them. Held-back facing pairs must change nothing.
    #[test]
    fn facing_pairs_held_back_give_what_each_pair_gives() {
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        let (mut faces, mut twins) = (0, 0);
        for round in 0..6 {
            let (mut a, mut b) = (TetMesh::default(), TetMesh::default());
            let push = |m: &mut TetMesh, t: [LatticePoint; 4]| {
                let base = m.vertices.len() as u32;
                m.vertices.extend(t);
                m.tets.push([base, base + 1, base + 2, base + 3]);
            };
            for _ in 0..160 {
                // A tet in a plane z = c (c in 0..3), coordinates ×8 on a small lattice.
                let z = (rng.next() % 3) as i32 * 8;
                let p = |rng: &mut Rng| {
                    [
                        (rng.next() % 4) as i32 * 8,
                        (rng.next() % 4) as i32 * 8,
                        z,
                        (rng.next() % 3) as i32 * 8,
                    ]
                };
                let t = [0; 4].map(|_| p(&mut rng));
                if tet_normal(t) == [0; 4] {
                    continue;
                }
                push(&mut a, t);
                match rng.next() % 5 {
                    // Its twin, facing it or not.
                    0 => push(&mut b, [t[1], t[0], t[2], t[3]]),
                    1 => push(&mut b, t),
                    // A tet in the same plane sharing a face or an edge, often overlapping.
                    2 => push(&mut b, [t[0], t[1], t[2], p(&mut rng)]),
                    3 => push(&mut b, [t[0], t[1], p(&mut rng), p(&mut rng)]),
                    // One across the plane.
                    _ => {
                        let mut q = t;
                        q[0][2] -= 8;
                        q[3][2] += 8;
                        push(&mut b, q);
                    }
                }
            }
            let (pa, pb) = (prepared(&a), prepared(&b));
            let all = walk(&pa, &pb, false);
            let exact = exact_touches(&pa, &pb);
            faces += exact.faces;
            twins += exact.twins;
            assert_same_touches(&pa, &pb, &all, &exact, round);
        }
        assert!(
            faces > 300 && twins > 200,
            "{faces} facing overlaps, {twins} twins"
        );
    }

    /// Every pair of two bodies classified on its own (the kernel's exact classifier),
    /// as the walk records it: each tet's strongest touch, and the interfering pairs.
    struct ExactTouches {
        hit_a: Vec<Touch>,
        hit_b: Vec<Touch>,
        interfering: Vec<(u32, u32)>,
        faces: usize,
        twins: usize,
    }

    fn exact_touches(pa: &Prepared, pb: &Prepared) -> ExactTouches {
        let mut e = ExactTouches {
            hit_a: vec![Touch::Clear; pa.mesh.tets.len()],
            hit_b: vec![Touch::Clear; pb.mesh.tets.len()],
            interfering: Vec::new(),
            faces: 0,
            twins: 0,
        };
        let (boxes_a, boxes_b) = (tet_boxes(pa), tet_boxes(pb));
        for i in 0..pa.mesh.tets.len() as u32 {
            for j in 0..pb.mesh.tets.len() as u32 {
                // Closed tets whose boxes are apart are disjoint.
                if !boxes_a[i as usize].overlaps(&boxes_b[j as usize]) {
                    continue;
                }
                let (ta, tb) = (tet_of(&pa.mesh, i), tet_of(&pb.mesh, j));
                let touch = match chronotope_kernel::classify(&ta, &tb) {
                    TetPairRelation::Crossing
                    | TetPairRelation::Coplanar {
                        overlap_volume_positive: true,
                        same_orientation: true,
                    } => Touch::Interference,
                    TetPairRelation::Coplanar {
                        overlap_volume_positive: true,
                        same_orientation: false,
                    } if same_points(&ta, &tb) => Touch::Twin,
                    TetPairRelation::Coplanar {
                        overlap_volume_positive: true,
                        same_orientation: false,
                    } => Touch::FaceToFace,
                    TetPairRelation::Coplanar { .. } | TetPairRelation::Touching => Touch::Contact,
                    TetPairRelation::Disjoint => Touch::Clear,
                };
                if touch == Touch::Interference {
                    e.interfering.push((i, j));
                }
                e.faces += usize::from(matches!(touch, Touch::FaceToFace | Touch::Twin));
                e.twins += usize::from(same_points(&ta, &tb));
                e.hit_a[i as usize] = e.hit_a[i as usize].max(touch);
                e.hit_b[j as usize] = e.hit_b[j as usize].max(touch);
            }
        }
        e.interfering.sort_unstable();
        e
    }

    /// The walk's touches are the exact ones, but for tets it took as touching untested
    /// through a pair whose boxes meet in one plane only (see [`visit`]): those may be
    /// `Contact` where the exact touch is `Clear`. Returns how many tets were so taken.
    fn assert_same_touches(
        pa: &Prepared,
        pb: &Prepared,
        all: &Part,
        exact: &ExactTouches,
        round: usize,
    ) -> usize {
        // The tets of a pair whose boxes (each tet's, as the tree's) meet in one plane.
        let (mut plane_a, mut plane_b) = (
            vec![false; pa.mesh.tets.len()],
            vec![false; pb.mesh.tets.len()],
        );
        let (boxes_a, boxes_b) = (tet_boxes(pa), tet_boxes(pb));
        for (i, ba) in boxes_a.iter().enumerate() {
            for (j, bb) in boxes_b.iter().enumerate() {
                if ba.overlaps(bb)
                    && plane_of_meeting((ba, &pa.normals[i]), (bb, &pb.normals[j])).is_some()
                {
                    plane_a[i] = true;
                    plane_b[j] = true;
                }
            }
        }
        let mut taken = 0;
        for (side, walked, exact, plane) in [
            ("A", &all.hit_a, &exact.hit_a, &plane_a),
            ("B", &all.hit_b, &exact.hit_b, &plane_b),
        ] {
            assert_eq!(walked.len(), exact.len());
            for (t, (&w, &e)) in walked.iter().zip(exact).enumerate() {
                if w != e {
                    assert!(
                        e == Touch::Clear && w == Touch::Contact && plane[t],
                        "round {round}: {side}'s tet {t}: the walk says {w:?}, exactly {e:?}"
                    );
                    taken += 1;
                }
            }
        }
        let mut walked: Vec<(u32, u32)> = all.ranges.iter().map(|r| (r.2, r.3)).collect();
        walked.sort_unstable();
        walked.dedup();
        assert_eq!(
            walked, exact.interfering,
            "round {round}: interfering pairs"
        );
        assert!(all.facing.is_empty());
        taken
    }

    fn tet_box(t: &[LatticePoint; 4]) -> Aabb4 {
        let mut b = Aabb4::from_point(t[0]);
        t[1..].iter().for_each(|v| b.grow(v));
        b
    }

    /// Each tet's box, as the tree holds it.
    fn tet_boxes(p: &Prepared) -> Vec<Aabb4> {
        (0..p.mesh.tets.len() as u32)
            .map(|i| tet_box(&tet_of(&p.mesh, i)))
            .collect()
    }

    /// A body of boxes (inclusive voxel ranges) on an 8³ lattice over 3 frames, moving by
    /// `step` voxels along x and y each frame.
    fn moving_boxes(boxes: Vec<([i64; 3], [i64; 3])>, step: [i64; 2]) -> BodyMesh {
        let stamps: Vec<i64> = (0..3).map(|k| k * 100_000_000).collect();
        chronotope_mesh::glue::test_body([8, 8, 8], [0.0; 3], &stamps, move |k, p| {
            let k = k as i64;
            let q = [
                p[0] as i64 - step[0] * k,
                p[1] as i64 - step[1] * k,
                p[2] as i64,
            ];
            boxes
                .iter()
                .any(|(lo, hi)| (0..3).all(|c| (lo[c]..=hi[c]).contains(&q[c])))
        })
    }

    /// A tet in a random cell of a small lattice (cells 8 apart, ×8 as the checker's
    /// coordinates are), its vertices on the cell's half lattice (corners, edge and face
    /// midpoints, centre), as marching cubes places them; two tets in three lie in a face
    /// of their cell.
    fn cell_tet(rng: &mut Rng) -> [LatticePoint; 4] {
        let cell = [0; 4].map(|_| rng.range(0, 2) as i32 * 8);
        let flat = rng.range(0, 5) as usize;
        let side = rng.range(0, 1) as i32 * 8;
        [0; 4].map(|_| {
            let mut p = [0; 4].map(|_| rng.range(0, 2) as i32 * 4);
            if flat < 4 {
                p[flat] = side;
            }
            [0, 1, 2, 3].map(|k| cell[k] + p[k])
        })
    }

    /// The plane rule against the exact classifier: a pair meeting in one plane never
    /// crosses or overlaps in a hyperplane (what lets the walk take it as touching
    /// untested), and faces apart in that plane mean the closed tets are disjoint (the test
    /// the rule in time makes). Tets in cells of one lattice make such pairs (neighbouring
    /// cells) common, and touching ones too.
    #[test]
    fn pairs_meeting_in_one_plane_only_touch_where_their_faces_meet() {
        let mut rng = Rng(0x6A09_E667_F3BC_C909);
        let (mut planes, mut touching, mut apart, mut beside) = ([0; 4], 0, 0, 0);
        for _ in 0..100_000 {
            let (ta, tb) = (cell_tet(&mut rng), cell_tet(&mut rng));
            let (ba, bb) = (tet_box(&ta), tet_box(&tb));
            if !ba.overlaps(&bb) {
                continue;
            }
            let (na, nb) = (tet_normal(ta), tet_normal(tb));
            let Some((k, c)) = plane_of_meeting((&ba, &na), (&bb, &nb)) else {
                continue;
            };
            planes[k] += 1;
            let relation = chronotope_kernel::classify(&ta, &tb);
            assert!(
                matches!(
                    relation,
                    TetPairRelation::Touching
                        | TetPairRelation::Disjoint
                        | TetPairRelation::Coplanar {
                            overlap_volume_positive: false,
                            ..
                        }
                ),
                "{ta:?} {tb:?} in x{k} = {c}: {relation:?}"
            );
            let meet = tets_intersect(&ta, &tb);
            touching += usize::from(meet);
            if faces_apart_on(&ta, &tb, k, c) {
                apart += 1;
                assert!(
                    !meet,
                    "{ta:?} {tb:?} meet though their faces in x{k} = {c} are apart"
                );
            }
            let (fa, fb) = (InPlane::of(&ta, k, c), InPlane::of(&tb, k, c));
            beside += usize::from(fa.strictly_beside(&fb) || fb.strictly_beside(&fa));
        }
        // Faces apart by a triangle's plane (their boxes may meet) come often too.
        assert!(
            planes.iter().all(|&n| n > 300) && touching > 1000 && apart > 4000 && beside > 300,
            "{planes:?} {touching} {apart} {beside}"
        );
    }

    /// The walk's touches and interfering pairs against every pair classified on its own,
    /// for two bodies of tets in the cells of one lattice: most candidates meet in one
    /// plane (neighbouring cells), their tets are taken as touching untested (some do not
    /// touch: taken, they are `Contact` where the exact touch is `Clear`), and some tets
    /// touch only through such a pair.
    #[test]
    fn pairs_meeting_in_a_plane_are_taken_as_touching() {
        let mut rng = Rng(0xBB67_AE85_84CA_A73B);
        let (mut plane_pairs, mut only_in_a_plane, mut taken) = (0, 0, 0);
        for round in 0..6 {
            let (mut a, mut b) = (TetMesh::default(), TetMesh::default());
            for m in [&mut a, &mut b] {
                while m.tets.len() < 150 {
                    let t = cell_tet(&mut rng);
                    if tet_normal(t) == [0; 4] {
                        continue;
                    }
                    let base = m.vertices.len() as u32;
                    m.vertices.extend(t);
                    m.tets.push([base, base + 1, base + 2, base + 3]);
                }
            }
            let (pa, pb) = (prepared(&a), prepared(&b));
            let all = walk(&pa, &pb, false);
            let exact = exact_touches(&pa, &pb);
            taken += assert_same_touches(&pa, &pb, &all, &exact, round);
            // Tets that touch the other body, and only in pairs meeting in a plane.
            let mut touched_off_plane = (vec![false; 150], vec![false; 150]);
            for i in 0..150u32 {
                for j in 0..150u32 {
                    let (ta, tb) = (tet_of(&pa.mesh, i), tet_of(&pb.mesh, j));
                    if !tets_intersect(&ta, &tb) {
                        continue;
                    }
                    // The tree's boxes: each tet's, exactly.
                    let (ba, bb) = (tet_box(&ta), tet_box(&tb));
                    let plane = plane_of_meeting(
                        (&ba, &pa.normals[i as usize]),
                        (&bb, &pb.normals[j as usize]),
                    );
                    plane_pairs += usize::from(plane.is_some());
                    if plane.is_none() {
                        touched_off_plane.0[i as usize] = true;
                        touched_off_plane.1[j as usize] = true;
                    }
                }
            }
            only_in_a_plane += (0..150)
                .filter(|&i| exact.hit_a[i] == Touch::Contact && !touched_off_plane.0[i])
                .count();
        }
        assert!(
            plane_pairs > 1000 && only_in_a_plane > 200 && taken > 100,
            "{plane_pairs} touching pairs in a plane, {only_in_a_plane} tets touching only so, \
             {taken} taken as touching that do not"
        );
    }

    /// Tets taken as touching untested (a pair whose boxes meet in one plane only) get the
    /// labels the exact touches give: closed bodies of two boxes each on a small lattice,
    /// moving by whole voxels (faces of one meet faces of the other in lattice planes,
    /// touching, facing or apart; some boxes overlap, some lie inside the other body).
    #[test]
    fn tets_taken_as_touching_get_the_labels_the_exact_touches_give() {
        let mut rng = Rng(0x3C6E_F372_FE94_F82B);
        let (mut taken, mut inside, mut contact) = (0, 0, 0);
        for round in 0..10 {
            let mut body = || {
                let boxes: Vec<([i64; 3], [i64; 3])> = (0..2)
                    .map(|_| {
                        let lo = [0; 3].map(|_| rng.range(1, 4));
                        let hi = lo.map(|c| c + rng.range(1, 3));
                        (lo, hi)
                    })
                    .collect();
                let dx = rng.range(0, 1);
                moving_boxes(boxes, [dx, 0])
            };
            let (a, b) = (body(), body());
            let lat = CommonLattice::of(&[("a", &a), ("b", &b)]).expect("one lattice");
            let (pa, pb) = (
                lat.prepare("a", &a).expect("a"),
                lat.prepare("b", &b).expect("b"),
            );
            let all = walk(&pa, &pb, false);
            let exact = exact_touches(&pa, &pb);
            taken += assert_same_touches(&pa, &pb, &all, &exact, round);
            for (p, o, walked, exact) in [
                (&pa, &pb, &all.hit_a, &exact.hit_a),
                (&pb, &pa, &all.hit_b, &exact.hit_b),
            ] {
                let labels = label_against(p, o, walked);
                assert_eq!(
                    labels.labels,
                    label_against(p, o, exact).labels,
                    "round {round}"
                );
                assert_eq!(labels.undecided_regions, 0, "round {round}");
                inside += labels.counts().inside;
                contact += walked.iter().filter(|&&t| t == Touch::Contact).count();
            }
        }
        assert!(
            taken > 1000 && inside > 1000 && contact > 3000,
            "{taken} taken as touching, {inside} inside, {contact} contact tets"
        );
    }

    /// The shortcut of the walk against the exact classifier: a pair whose time ranges
    /// meet in one instant never crosses or overlaps in a hyperplane, and faces apart at
    /// that instant mean the closed tets are disjoint. Vertices at t ∈ {0, 1, 2} (a third
    /// of the tets caps at one instant) on a small spatial lattice make such pairs common
    /// and touching ones too.
    #[test]
    fn pairs_meeting_in_one_instant_only_touch_where_their_faces_meet() {
        let mut rng = Rng(0x2545_F491_4F6C_DD1D);
        let (mut instants, mut touching, mut apart) = (0, 0, 0);
        let tet = |rng: &mut Rng, t: [i32; 4]| -> [LatticePoint; 4] {
            t.map(|t| {
                [0, 0, 0]
                    .map(|_| rng.range(0, 3) as i32)
                    .into_iter()
                    .chain([t])
                    .collect::<Vec<_>>()
                    .try_into()
                    .expect("4")
            })
        };
        let times = [
            [0, 0, 1, 1],
            [0, 1, 1, 1],
            [1, 1, 1, 2],
            [1, 2, 2, 2],
            [1, 1, 1, 1],
            [0, 0, 0, 1],
        ];
        for _ in 0..20_000 {
            let ka = rng.range(0, 5) as usize;
            let ta = tet(&mut rng, times[ka]);
            let kb = rng.range(0, 5) as usize;
            let tb = tet(&mut rng, times[kb]);
            let Some(k) = one_instant(&ta, &tb) else {
                continue;
            };
            instants += 1;
            let relation = chronotope_kernel::classify(&ta, &tb);
            assert!(
                matches!(
                    relation,
                    TetPairRelation::Touching | TetPairRelation::Disjoint
                ),
                "{ta:?} {tb:?} at {k}: {relation:?}"
            );
            let meet = tets_intersect(&ta, &tb);
            touching += usize::from(meet);
            if faces_apart(&ta, &tb, k) {
                apart += 1;
                assert!(
                    !meet,
                    "{ta:?} {tb:?} meet though their faces at {k} are apart"
                );
            }
        }
        assert!(
            instants > 5000 && touching > 500 && apart > 500,
            "{instants} {touching} {apart}"
        );
    }

    /// Contact tets on both sides of the other body (its boundary passing through them
    /// along a ridge, where pair by pair it only touches them) are labelled by the first of
    /// their points that decides. Over random bodies of one to three boxes moving by whole
    /// voxels (flat faces meeting in lattice planes make such ridges common), such a tet is
    /// never the only sign of an overlap, and its points inside the other body lie in the
    /// reported intervals: every contact tet of both bodies is tested at 35 interior points
    /// (every barycentric weight of eighths), and wherever one point is inside, the pair
    /// interferes and that point's time lies in an interval.
    #[test]
    fn contact_tets_on_both_sides_are_never_the_only_sign_of_an_overlap() {
        let mut rng = Rng(0x510E_527F_ADE6_82D1);
        let weights: Vec<[i64; 4]> = (1..8)
            .flat_map(|a| (1..8).flat_map(move |b| (1..8).map(move |c| [a, b, c, 8 - a - b - c])))
            .filter(|w| w[3] >= 1)
            .collect();
        let (mut both_sides, mut interfering) = (0, 0);
        for round in 0..150 {
            let body = |rng: &mut Rng| {
                let boxes: Vec<([i64; 3], [i64; 3])> = (0..rng.range(1, 3))
                    .map(|_| {
                        let lo = [0; 3].map(|_| rng.range(1, 4));
                        (lo, lo.map(|c| c + rng.range(0, 2)))
                    })
                    .collect();
                let step = [rng.range(-1, 1), rng.range(-1, 1)];
                moving_boxes(boxes, step)
            };
            let (a, b) = (body(&mut rng), body(&mut rng));
            let lat = CommonLattice::of(&[("a", &a), ("b", &b)]).expect("one lattice");
            let (pa, pb) = (
                lat.prepare("a", &a).expect("a"),
                lat.prepare("b", &b).expect("b"),
            );
            // One walk: its touches say which tets are contact tets, then the labels.
            let all = walk(&pa, &pb, false);
            let touches = [all.hit_a.clone(), all.hit_b.clone()];
            let r = finish_pair(&pa, &pb, all, std::time::Instant::now());
            interfering += usize::from(r.interfering());
            for (p, other, hit) in [(&pa, &pb, &touches[0]), (&pb, &pa, &touches[1])] {
                let mut inc = Inclusion::with_normals(&other.mesh, &other.bvh, &other.normals);
                for (t, _) in hit
                    .iter()
                    .enumerate()
                    .filter(|(_, &h)| matches!(h, Touch::Contact | Touch::FaceToFace | Touch::Twin))
                {
                    let tet = tet_of(&p.mesh, t as u32);
                    let points: Vec<(LatticePoint, bool)> = weights
                        .iter()
                        .filter_map(|w| {
                            let q = interior_point(&tet, w);
                            inc.contains(&q).map(|inside| (q, inside))
                        })
                        .collect();
                    let inside: Vec<&LatticePoint> =
                        points.iter().filter(|p| p.1).map(|p| &p.0).collect();
                    both_sides += usize::from(!inside.is_empty() && inside.len() < points.len());
                    for q in inside {
                        let t = f64::from(q[3]);
                        assert!(r.interfering(), "round {round}: a point of tet {t} inside");
                        assert!(
                            r.intervals.iter().any(|&(s, e)| s <= t && t <= e),
                            "round {round}: a point inside at {t}, intervals {:?}",
                            r.intervals
                        );
                    }
                }
            }
        }
        assert!(
            both_sides > 300 && interfering > 50,
            "{both_sides} contact tets on both sides, {interfering} pairs interfering"
        );
    }
}
