//! One frame period of a pair checked on its own: the rolling checker's unit of work.
//!
//! The full check labels every tet of a body against the other body's whole closed mesh.
//! A tet of slab [k, k+1] only needs a part of it:
//!
//! - **Interference.** A lateral tet's relative interior lies strictly between the two frame
//!   times, so it can only cross the other body's lateral tets of the same slab; tets of
//!   neighbouring slabs and caps meet it in one instant at most, and only touch.
//! - **Inside or outside.** Whether a point of the slab lies inside the other body is
//!   decided along segments that stay in the slab's time band: to far points whose time
//!   lies strictly between the two frame times (see [`Inclusion::within_time`]), and
//!   between interior points of neighbouring tets of the slab. Such a segment meets only
//!   the other body's lateral tets of the same slab, and that slab, closed by any two caps,
//!   agrees with the other body at every time strictly between them: the crossing count
//!   is the one the closed body gives, and no cap is needed.
//!
//! So each body's window is its slab, with its own first or last cap where its stream
//! starts or ends there. Labels are taken only for the *centre* slab and the real caps at
//! its two frame times. A real cap of one body lies in a time plane where the other body
//! may go on, and there meets the other's slabs on both sides of it: the other's window
//! then reaches one slab further (see [`WindowBody`]). With that, every taken tet gets
//! exactly the label and the crossings the full check gives it (tests/it/rolling.rs compares
//! the two on whole scenes).
//!
//! [`Inclusion::within_time`]: super::inclusion::Inclusion::within_time

use std::ops::Range;

use super::inclusion::Inclusion;
use super::labels::{label_regions, InsideTest, Label, LabelCounts, Labeling, Touch};
use super::prep::{BodyPrep, PrepError};
use super::{t_range, tet_of, walk, Prepared, TetInside, CHECKER_FACTOR};
use chronotope_kernel::float::tet_normal;
use chronotope_kernel::LatticePoint;
use chronotope_mesh::march::{union_bounds, SpatialBounds, Welder};
use chronotope_mesh::{GridGeometry, TetMesh};

/// One body's part of a window.
#[derive(Debug, Clone)]
pub struct WindowBody<'a> {
    /// The body's id.
    pub id: &'a str,
    /// The body's lattice.
    pub geometry: GridGeometry,
    /// Body frame index of the first slab's earlier frame.
    pub lo: u32,
    /// Consecutive lateral pieces from `lo` (body lattice, as the mesher made them).
    pub slabs: Vec<&'a TetMesh>,
    /// Which of `slabs` is the checked one (the others are context for the other body's
    /// real caps).
    pub centre: usize,
    /// The body's first cap, if its stream starts at frame `lo`.
    pub low: Option<&'a TetMesh>,
    /// The body's last cap, if its stream ends at frame `lo + slabs.len()`.
    pub high: Option<&'a TetMesh>,
    /// Axis map onto the pair's lattice: checker coordinates (body lattice ×
    /// [`CHECKER_FACTOR`], with frame `lo` at time 0) times `mul`, plus `add`.
    pub mul: i64,
    /// See `mul`.
    pub add: [i64; 4],
    /// If set, its partners' windows (checker coordinates on the pair's lattice): only the
    /// tets a partner's check can need are prepared (see [`Clip`]).
    pub clip: Option<Partner>,
}

impl WindowBody<'_> {
    /// Its parts: the first cap, the slabs, the last cap (those it has).
    fn parts(&self) -> impl Iterator<Item = &TetMesh> + '_ {
        self.low
            .iter()
            .chain(&self.slabs)
            .chain(self.high.iter())
            .copied()
    }

    /// The box of every vertex of the window on the pair's lattice, spatial axes only
    /// (`None` for a window without vertices).
    pub fn spatial_box(&self) -> Option<SpatialBox> {
        let bounds = self
            .parts()
            .fold(None, |b, m| union_bounds(b, m.spatial_bounds()))?;
        Some(on_pair_lattice(bounds, self.mul, &self.add))
    }

    /// How its tets are clipped for its partners ([`Self::clip`]), if they are.
    fn clipping(&self) -> Option<Clip> {
        self.clip
            .zip(self.spatial_box())
            .map(|(p, full)| Clip::for_partner(&p, full))
    }

    /// How many tets [`prepare_window`] would keep: those that reach its partners' box or
    /// the far points' side of it (every tet, if it is not clipped). A window that keeps
    /// none is apart from its partners: a partner's tet meets none of its tets, and a
    /// segment from a partner's point to its far point meets none, so every tet of both is
    /// OUTSIDE the other body, as though their boxes were apart.
    pub fn kept_tets(&self) -> usize {
        let Some(c) = self.clipping() else {
            return self.parts().map(|p| p.tets.len()).sum();
        };
        let f = i64::from(CHECKER_FACTOR) * self.mul;
        let mut reach: Vec<u8> = Vec::new();
        self.parts()
            .map(|part| {
                reach.clear();
                reach.extend(
                    part.vertices
                        .iter()
                        .map(|p| c.reaches([0, 1, 2].map(|k| i64::from(p[k]) * f + self.add[k]))),
                );
                // A vertex past its table (never accepted) reaches everywhere: the window
                // is then prepared, which says what is wrong.
                part.tets
                    .iter()
                    .filter(|t| {
                        t.iter().fold(0u8, |bits, &v| {
                            bits | reach.get(v as usize).copied().unwrap_or(0b111)
                        }) == 0b111
                    })
                    .count()
            })
            .sum()
    }
}

/// Spatial bounds on a body's lattice as a box on the pair's lattice, by the axis map of a
/// [`WindowBody`] (`mul`, `add`).
pub fn on_pair_lattice((lo, hi): SpatialBounds, mul: i64, add: &[i64; 4]) -> SpatialBox {
    let f = i64::from(CHECKER_FACTOR) * mul;
    let map = |x: [i32; 3]| [0, 1, 2].map(|k| i64::from(x[k]) * f + add[k]);
    (map(lo), map(hi))
}

/// A window's partners, as its [`Clip`] needs them: the box their whole windows lie in,
/// and, where the partner's window was prepared first, the box of the tets it kept and the
/// side of its far points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Partner {
    /// Every vertex of the partners' windows.
    pub whole: SpatialBox,
    /// The partner's window prepared first: the box of its kept tets and, per axis, whether
    /// its far points lie below it ([`Clip::far_low`]).
    pub kept: Option<(SpatialBox, [bool; 3])>,
}

impl Partner {
    /// Partners known by the box of their whole windows.
    pub fn whole(whole: SpatialBox) -> Self {
        Partner { whole, kept: None }
    }

    /// Both partners: their whole boxes together, and their kept tets' where both were
    /// prepared first with their far points on the same sides (else known by their whole
    /// boxes alone).
    pub fn union(&self, o: &Partner) -> Partner {
        let union = |x: &SpatialBox, y: &SpatialBox| {
            (
                [0, 1, 2].map(|k| x.0[k].min(y.0[k])),
                [0, 1, 2].map(|k| x.1[k].max(y.1[k])),
            )
        };
        let kept = match (self.kept, o.kept) {
            (Some((x, f)), Some((y, g))) if f == g => Some((union(&x, &y), f)),
            _ => None,
        };
        Partner {
            whole: union(&self.whole, &o.whole),
            kept,
        }
    }

    /// The partner whose whole window lies in `whole`, prepared (clipped) as `p`; known by
    /// its box alone if `p` is not clipped or keeps no tet.
    pub fn prepared(whole: SpatialBox, p: &PreparedWindow) -> Self {
        let kept = p
            .clip
            .filter(|_| !p.body.mesh.tets.is_empty())
            .map(|c| (p.kept_box(), c.far_low));
        Partner { whole, kept }
    }
}

/// Which tets of a window are prepared for its partners, and how inclusion tests against
/// it are made so that they need no other.
///
/// On each spatial axis the far points of the inclusion tests against this window lie
/// beyond the whole window on one side (`far_low`: below its minimum, else above its
/// maximum), and the tets kept are those that reach the near box or that side of it. The
/// near box is, per axis, one of two (whichever keeps the shorter stretch of the window):
///
/// - **The partners' whole box**, far points on the side where less of the window lies
///   beyond it. A segment from a partner's point to a far point then only meets kept tets;
///   a partner's tets meet only kept tets; and a tet left out is apart from the partners'
///   box, so it is OUTSIDE.
/// - **The box of the tets the partner's window kept**, prepared first (clipped for this
///   window's whole box), far points on the side opposite to the partner's. A tet of this
///   window inside the partner's body has its points' segments to the partner's far points
///   cross the partner's boundary, and only kept partner tets lie on them, so on this axis
///   the tet reaches the kept tets' box from the side away from the partner's far points:
///   the side kept here. A partner's kept tet, and the segment from its points to this
///   window's far points, lie on that side too; a partner's tet left out is OUTSIDE and
///   meets none of this window's tets.
///
/// Either way a tet left out meets no partner tet the check keeps and is OUTSIDE.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clip {
    /// The near box, per axis the partners' whole box or their kept tets' (see above).
    pub near: SpatialBox,
    /// Per axis, whether the far points lie below the window (tets above the partners'
    /// box are left out) or above it (those below are).
    pub far_low: [bool; 3],
    /// The whole window's box.
    pub full: SpatialBox,
}

impl Clip {
    /// The clip of a window whose vertices lie in `full` for partners `p` (see [`Clip`]).
    fn for_partner(p: &Partner, (lo, hi): SpatialBox) -> Clip {
        let mut near = p.whole;
        let mut far_low = [false; 3];
        for k in 0..3 {
            // The stretch of the window kept with far points below it (`true`) or above it,
            // for a near range `n`.
            let kept = |below: bool, n: ([i64; 3], [i64; 3])| {
                if below {
                    n.1[k] - lo[k]
                } else {
                    hi[k] - n.0[k]
                }
            };
            let w = p.whole;
            far_low[k] = hi[k] - w.1[k] > w.0[k] - lo[k];
            if let Some((b, far)) = p.kept {
                if kept(!far[k], b) < kept(far_low[k], w) {
                    far_low[k] = !far[k];
                    (near.0[k], near.1[k]) = (b.0[k], b.1[k]);
                }
            }
        }
        Clip {
            near,
            far_low,
            full: (lo, hi),
        }
    }

    /// Per spatial axis (bit k), whether a point with coordinates `c` lies on the partners'
    /// box or on the far points' side of it: a tet is kept when its vertices' bits,
    /// or-ed, are all set.
    fn reaches(&self, c: [i64; 3]) -> u8 {
        (0..3)
            .filter(|&k| {
                if self.far_low[k] {
                    c[k] <= self.near.1[k]
                } else {
                    c[k] >= self.near.0[k]
                }
            })
            .fold(0, |bits, k| bits | 1 << k)
    }

    /// Whether every tet partner `p` can need is kept: on each axis its whole box lies on
    /// the kept side, or it was prepared first with its far points on the other side than
    /// this clip's and its kept tets' box lies on the kept side (see [`Clip`]).
    fn serves(&self, p: &Partner) -> bool {
        let within = |b: &SpatialBox, k: usize| {
            if self.far_low[k] {
                b.1[k] <= self.near.1[k]
            } else {
                self.near.0[k] <= b.0[k]
            }
        };
        (0..3).all(|k| {
            within(&p.whole, k)
                || p.kept
                    .is_some_and(|(b, far)| far[k] != self.far_low[k] && within(&b, k))
        })
    }

    fn moved(&self, d: [i64; 3]) -> Self {
        let m = |b: &SpatialBox| (add3(b.0, d), add3(b.1, d));
        Clip {
            near: m(&self.near),
            far_low: self.far_low,
            full: m(&self.full),
        }
    }
}

/// `a + d` on each spatial axis.
fn add3(a: [i64; 3], d: [i64; 3]) -> [i64; 3] {
    [a[0] + d[0], a[1] + d[1], a[2] + d[2]]
}

/// A closed box in space, `(min, max)` on x, y, z (checker coordinates on a pair's
/// lattice).
pub type SpatialBox = ([i64; 3], [i64; 3]);

/// Why a window cannot be checked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WindowError {
    /// The window has no slab, or its centre is not one of them.
    #[error("body {id}: a window needs its centre slab")]
    NoCentre {
        /// The body.
        id: String,
    },
    /// The window's mesh cannot be prepared.
    #[error("body {id}: {source}")]
    Prep {
        /// The body.
        id: String,
        /// Why.
        source: PrepError,
    },
    /// Coordinates leave the checker lattice on the pair's lattice.
    #[error("body {id}: checker lattice coordinates would overflow on the pair's lattice")]
    Overflow {
        /// The body.
        id: String,
    },
}

/// One body of a window, prepared, with the tets whose labels are taken.
#[derive(Debug)]
pub struct PreparedWindow {
    /// The window mesh on the pair's lattice.
    pub body: Prepared,
    /// Taken tets in the window mesh's own order: the real first cap (if the centre slab
    /// opens the stream), the centre slab, the real last cap (if it closes it).
    pub taken: [Range<usize>; 3],
    /// Checker times of the centre slab's two frames on the pair's lattice.
    pub band: (i32, i32),
    /// How its tets were clipped (see [`WindowBody::clip`]); `None`: every tet is kept.
    pub clip: Option<Clip>,
}

impl PreparedWindow {
    /// Tets whose labels are taken.
    pub fn taken_len(&self) -> usize {
        self.taken.iter().map(|r| r.len()).sum()
    }

    /// Whether this window can be checked against `partner` (see [`Clip`]).
    pub fn serves(&self, partner: &Partner) -> bool {
        self.clip.is_none_or(|c| c.serves(partner))
    }

    /// The box of its (kept) tets' vertices, spatial axes (a window without tets: an
    /// empty box).
    pub fn kept_box(&self) -> SpatialBox {
        let b = self.body.bvh.aabb();
        (
            [0, 1, 2].map(|k| i64::from(b.min[k])),
            [0, 1, 2].map(|k| i64::from(b.max[k])),
        )
    }

    /// Whether this window moved by `d` ([`Self::moved_by`]) would serve `partner`.
    pub fn serves_moved(&self, d: [i64; 4], partner: &Partner) -> bool {
        self.clip
            .is_none_or(|c| c.moved([d[0], d[1], d[2]]).serves(partner))
    }

    /// Inclusion tests against this window (far points as its [`Clip`] needs them).
    fn inclusion(&self) -> Inclusion<'_> {
        let inc = Inclusion::with_normals(&self.body.mesh, &self.body.bvh, &self.body.normals);
        match &self.clip {
            Some(c) => inc.far_beyond(c.full, c.far_low),
            None => inc,
        }
    }

    /// The box the whole window (every tet, kept or not) lies in.
    fn reach(&self) -> SpatialBox {
        match &self.clip {
            Some(c) => c.full,
            None => {
                let b = self.body.bvh.aabb();
                (
                    [0, 1, 2].map(|k| i64::from(b.min[k])),
                    [0, 1, 2].map(|k| i64::from(b.max[k])),
                )
            }
        }
    }

    /// Position of window tet `original` among the taken tets (piece order), if taken.
    fn position(&self, original: u32) -> Option<u32> {
        let o = original as usize;
        let mut before = 0;
        for r in &self.taken {
            if r.contains(&o) {
                return Some((before + o - r.start) as u32);
            }
            before += r.len();
        }
        None
    }
}

/// Builds and prepares one body's window.
///
/// # Errors
/// See [`WindowError`].
pub fn prepare_window(w: &WindowBody<'_>) -> Result<PreparedWindow, WindowError> {
    let id = || w.id.to_string();
    if w.centre >= w.slabs.len() {
        return Err(WindowError::NoCentre { id: id() });
    }
    let scale = i64::from(w.geometry.scale);
    let shift_t = scale * i64::from(w.lo);
    let overflow = || WindowError::Overflow { id: id() };
    // Only the tets the partners can need, if clipped (see [`Clip`]): the whole window's
    // box from its parts' vertices, then each part's tets kept, before any is welded.
    let f = i64::from(CHECKER_FACTOR) * w.mul;
    let parts: Vec<&TetMesh> = w.parts().collect();
    let clip = w.clipping();
    let mut mesh = TetMesh::default();
    let mut welder = Welder::default();
    let mut pieces = Vec::with_capacity(parts.len());
    let mut ranges = Vec::with_capacity(parts.len());
    // Window tet (all parts' tets in order) of each kept tet, when clipped.
    let mut kept: Vec<u32> = Vec::new();
    let mut all = 0usize;
    let mut keep: Vec<u32> = Vec::new();
    let mut reach: Vec<u8> = Vec::new();
    for part in &parts {
        let first_vertex = mesh.vertices.len();
        pieces.push(mesh.tets.len());
        ranges.push(all..all + part.tets.len());
        match &clip {
            Some(c) => {
                reach.clear();
                reach.extend(
                    part.vertices
                        .iter()
                        .map(|p| c.reaches([0, 1, 2].map(|k| i64::from(p[k]) * f + w.add[k]))),
                );
                keep.clear();
                keep.extend((0..part.tets.len() as u32).filter(|&t| {
                    let bits = part.tets[t as usize]
                        .iter()
                        .fold(0, |b, &v| b | reach[v as usize]);
                    bits == 0b111
                }));
                welder.append_tets(&mut mesh, part, &keep);
                kept.extend(keep.iter().map(|&t| (all + t as usize) as u32));
            }
            None => welder.append(&mut mesh, part),
        }
        all += part.tets.len();
        // New vertices only: welded ones are already shifted.
        for p in &mut mesh.vertices[first_vertex..] {
            let t = i64::from(p[3]) - shift_t;
            p[3] = i32::try_from(t).map_err(|_| overflow())?;
        }
    }
    let kept = (clip.is_some() && kept.len() < all).then_some(kept);
    let centre = w.centre + usize::from(w.low.is_some());
    let empty = 0..0;
    let taken = [
        if w.centre == 0 && w.low.is_some() {
            ranges[0].clone()
        } else {
            empty.clone()
        },
        ranges[centre].clone(),
        if w.centre + 1 == w.slabs.len() && w.high.is_some() {
            ranges[ranges.len() - 1].clone()
        } else {
            empty
        },
    ];
    let mut local =
        BodyPrep::of(&mesh, &pieces).map_err(|source| WindowError::Prep { id: id(), source })?;
    drop(mesh);
    if let Some(keep) = &kept {
        for o in &mut local.original {
            *o = keep[*o as usize];
        }
    }
    let mut body = Prepared {
        id: w.id.to_string(),
        mesh: local.mesh,
        bvh: local.bvh,
        adjacency: local.adjacency.into(),
        components: Default::default(),
        normals: local.normals,
        factor: CHECKER_FACTOR * w.mul as i32,
        geometry: w.geometry,
        original: local.original.into(),
    };
    let mul = [w.mul; 4];
    if (mul != [1; 4] || w.add != [0; 4]) && !body.map_in_place(mul, w.add) {
        return Err(overflow());
    }
    let period = scale * i64::from(CHECKER_FACTOR);
    let time = |frame: i64| -> Result<i32, WindowError> {
        i32::try_from(frame * period * w.mul + w.add[3]).map_err(|_| overflow())
    };
    let band = (time(w.centre as i64)?, time(w.centre as i64 + 1)?);
    Ok(PreparedWindow {
        body,
        taken,
        band,
        clip,
    })
}

impl PreparedWindow {
    /// This window moved by `d` in checker coordinates (the tree's boxes and the vertices
    /// are moved; the normals, adjacency and leaf order are kept): a window of the same
    /// tets moved by `d`, as exact as [`prepare_window`]'s of them. `None` if a coordinate
    /// would leave the checker's range.
    pub fn moved_by(&self, d: [i64; 4]) -> Option<PreparedWindow> {
        let body = self.body.mapped([1; 4], d)?;
        let moved = |t: i32| i32::try_from(i64::from(t) + d[3]).ok();
        let clip = self.clip.map(|c| c.moved([d[0], d[1], d[2]]));
        Some(PreparedWindow {
            body,
            taken: self.taken.clone(),
            band: (moved(self.band.0)?, moved(self.band.1)?),
            clip,
        })
    }
}

/// One crossing tet pair of two taken tets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// Checker-time range of the section.
    pub t: (f64, f64),
    /// Positions of the two tets among their bodies' taken tets, in piece order (see
    /// `PreparedWindow::position`).
    pub tets: (u32, u32),
    /// Their hyperplane normals (exact integers in `f64`, so sums are exact).
    pub normals: ([f64; 4], [f64; 4]),
}

/// One body's labels from a window.
#[derive(Debug, Clone, Default)]
pub struct TakenLabels {
    /// One label per taken tet, in piece order (first cap, slab, last cap).
    pub labels: Vec<u8>,
    /// Counts of `labels`.
    pub counts: LabelCounts,
    /// Tets of the taken first cap, slab and last cap.
    pub pieces: [usize; 3],
}

/// What a window gives.
#[derive(Debug, Clone, Default)]
pub struct WindowResult {
    /// Labels of the two bodies' taken tets.
    pub labels: [TakenLabels; 2],
    /// Checker-time ranges of overlap: the crossings', and those of taken INSIDE tets.
    pub ranges: Vec<(f64, f64)>,
    /// The crossings of taken tets.
    pub crossings: Vec<Crossing>,
    /// Candidate tet pairs of the window (context slabs included).
    pub candidate_pairs: u64,
    /// Regions or contact tets whose inclusion stayed undecided (labelled OUTSIDE).
    pub undecided: u32,
}

impl WindowResult {
    /// The same result for the two windows moved `dt` in checker time (and by one vector
    /// in space): the same labels, every range moved. Exact for the ranges of INSIDE tets
    /// (integers); a crossing's range is rounded, so a result with crossings is moved
    /// only up to that rounding.
    pub fn moved_in_time(&self, dt: i64) -> Self {
        let dt = dt as f64;
        let mut r = self.clone();
        for x in &mut r.ranges {
            *x = (x.0 + dt, x.1 + dt);
        }
        for c in &mut r.crossings {
            c.t = (c.t.0 + dt, c.t.1 + dt);
        }
        r
    }
}

/// Checks two prepared window bodies and keeps what their taken tets get.
pub fn check_window(a: &PreparedWindow, b: &PreparedWindow) -> WindowResult {
    let all = walk(&a.body, &b.body, false);
    let (la, lb) = rayon::join(
        || label_taken(a, b, &all.hit_a),
        || label_taken(b, a, &all.hit_b),
    );
    let mut out = WindowResult {
        candidate_pairs: all.candidate_pairs,
        undecided: la.1 + lb.1,
        ..WindowResult::default()
    };
    for (k, (w, (labels, _))) in [(a, la), (b, lb)].into_iter().enumerate() {
        let mut counts = LabelCounts::default();
        for &l in &labels {
            match l {
                x if x == Label::Interference as u8 => counts.interference += 1,
                x if x == Label::Inside as u8 => counts.inside += 1,
                _ => counts.outside += 1,
            }
        }
        // A tet left out by a clip is OUTSIDE: the INSIDE ones are all prepared.
        for (leaf, &orig) in w.body.original.iter().enumerate() {
            let Some(p) = w.position(orig) else { continue };
            if labels[p as usize] == Label::Inside as u8 {
                out.ranges.push(t_range(&tet_of(&w.body.mesh, leaf as u32)));
            }
        }
        out.labels[k] = TakenLabels {
            labels,
            counts,
            pieces: w.taken.clone().map(|r| r.len()),
        };
    }
    for &(t0, t1, i, j) in &all.ranges {
        let (Some(pa), Some(pb)) = (
            a.position(a.body.original[i as usize]),
            b.position(b.body.original[j as usize]),
        ) else {
            continue;
        };
        out.ranges.push((t0, t1));
        out.crossings.push(Crossing {
            t: (t0, t1),
            tets: (pa, pb),
            normals: (
                tet_normal(&tet_of(&a.body.mesh, i)),
                tet_normal(&tet_of(&b.body.mesh, j)),
            ),
        });
    }
    out.crossings
        .sort_unstable_by(|x, y| x.tets.cmp(&y.tets).then(x.t.0.total_cmp(&y.t.0)));
    out
}

/// Labels of `p`'s taken tets against `other` (one per taken tet, in piece order), with the
/// regions and contact tets left undecided. Only the taken tets are labelled, as one
/// mesh whose face adjacency stops at their edge; far points lie in the centre slab's time
/// band, so every segment tested stays in it.
fn label_taken(p: &PreparedWindow, other: &PreparedWindow, hit: &[Touch]) -> (Vec<u8>, u32) {
    let n = p.body.mesh.tets.len();
    let mut leaves: Vec<u32> = Vec::with_capacity(p.taken_len());
    let mut compact = vec![u32::MAX; n];
    // The other window lies in its box: a tet whose box is apart from it in space meets
    // none of its tets and lies outside the other body at every time of the band, so it
    // is OUTSIDE without a test (and the regions to test are only those near the other).
    let (lo, hi) = other.reach();
    let near = |leaf: usize| {
        let tet = tet_of(&p.body.mesh, leaf as u32);
        (0..3).all(|k| {
            tet.iter().any(|v| i64::from(v[k]) <= hi[k])
                && tet.iter().any(|v| i64::from(v[k]) >= lo[k])
        })
    };
    for (leaf, &orig) in p.body.original.iter().enumerate() {
        if p.position(orig).is_some() && near(leaf) {
            compact[leaf] = leaves.len() as u32;
            leaves.push(leaf as u32);
        }
    }
    let adjacency: Vec<[u32; 4]> = leaves
        .iter()
        .map(|&leaf| {
            p.body.adjacency[leaf as usize]
                .map(|nb| compact.get(nb as usize).copied().unwrap_or(u32::MAX))
        })
        .collect();
    let touch: Vec<Touch> = leaves
        .iter()
        .map(|&leaf| hit.get(leaf as usize).copied().unwrap_or(Touch::Clear))
        .collect();
    let mut test = Taken {
        inner: TetInside {
            mesh: &p.body.mesh,
            inc: other.inclusion().within_time(p.band.0, p.band.1),
        },
        leaves: &leaves,
    };
    let Labeling {
        labels,
        undecided_regions,
        ..
    } = label_regions(&adjacency, &touch, &mut test);
    let mut out = vec![Label::Outside as u8; p.taken_len()];
    for (c, &leaf) in leaves.iter().enumerate() {
        if let Some(pos) = p.position(p.body.original[leaf as usize]) {
            out[pos as usize] = labels[c] as u8;
        }
    }
    (out, undecided_regions)
}

/// Inclusion tests of the taken tets, numbered in the order of `leaves`.
struct Taken<'a> {
    inner: TetInside<'a>,
    leaves: &'a [u32],
}

impl InsideTest for Taken<'_> {
    fn far(&mut self, t: u32, tries: usize) -> Option<(bool, LatticePoint)> {
        self.inner.far(self.leaves[t as usize], tries)
    }
    fn from_known(
        &mut self,
        t: u32,
        q: &LatticePoint,
        q_inside: bool,
    ) -> Option<(bool, LatticePoint)> {
        self.inner.from_known(self.leaves[t as usize], q, q_inside)
    }
    fn lies_in_boundary(&mut self, t: u32) -> bool {
        self.inner.lies_in_boundary(self.leaves[t as usize])
    }
    fn point(&self, t: u32) -> LatticePoint {
        self.inner.point(self.leaves[t as usize])
    }
}
