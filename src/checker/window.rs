//! One frame period of a pair checked on its own: the rolling checker's unit of work.
//!
//! The full check labels every tet of a body against the other body's whole closed mesh.
//! A tet of slab [k, k+1] only needs a part of it:
//!
//! - **Interference.** A lateral tet's relative interior lies strictly between the two frame
//!   times, so it can only cross the other body's lateral tets of the same slab; tets of
//!   neighbouring slabs and caps meet it in one instant at most, and only touch.
//! - **Inside or outside.** Whether a point strictly inside the slab lies inside the other
//!   body is the same question for the other body's slab closed by two caps: the closed
//!   solid agrees with the body at every time strictly between its end caps.
//!
//! So each body's window is its slab closed by caps: its own first or last cap where its
//! stream starts or ends there, otherwise a cap built from its decoded frame there (an
//! *artificial* cap, not part of the body's boundary). Labels are taken only for the
//! *centre* slab and the real caps at its two frame times. A real cap of one body lies in
//! a time plane where the other body may go on: the other's window then reaches one slab
//! further, so that its artificial cap is not in that plane (see [`WindowBody`]). With that,
//! every taken tet gets exactly the label and the crossings the full check gives it
//! (tests/rolling.rs compares the two on whole scenes).

use std::ops::Range;

use super::labels::{Label, LabelCounts};
use super::prep::{BodyPrep, PrepError};
use super::{check_pair_detailed, t_range, tet_of, Prepared, CHECKER_FACTOR};
use crate::kernel::float::tet_normal;
use crate::mesh::march::{march_cap, Welder};
use crate::mesh::table::table;
use crate::mesh::{CapSide, GridGeometry, OccupancyGrid, SlabPlacement, TetMesh};

/// Where a window body's end cap comes from.
#[derive(Debug, Clone, Copy)]
pub enum CapSource<'a> {
    /// The body's own first or last cap (as the mesher sent it, in the body's lattice).
    Real(&'a TetMesh),
    /// The body goes on past this frame: an artificial cap built from the decoded frame.
    Frame(&'a OccupancyGrid),
}

/// One body's part of a window.
#[derive(Debug, Clone)]
pub struct WindowBody<'a> {
    /// The body's id.
    pub id: &'a str,
    /// The body's lattice.
    pub geometry: GridGeometry,
    /// Percent iso level of its frames (graded frames only).
    pub iso: u8,
    /// Body frame index of the first slab's earlier frame.
    pub lo: u32,
    /// Consecutive lateral pieces from `lo` (body lattice, as the mesher made them).
    pub slabs: Vec<&'a TetMesh>,
    /// Which of `slabs` is the checked one (the others are context for the other body's
    /// real caps).
    pub centre: usize,
    /// The cap at frame `lo`.
    pub low: CapSource<'a>,
    /// The cap at frame `lo + slabs.len()`.
    pub high: CapSource<'a>,
    /// Axis map onto the pair's lattice: checker coordinates (body lattice ×
    /// [`CHECKER_FACTOR`], with frame `lo` at time 0) times `mul`, plus `add`.
    pub mul: i64,
    /// See `mul`.
    pub add: [i64; 4],
    /// Most tets an artificial cap may have.
    pub max_cap_tets: usize,
}

/// Why a window cannot be checked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WindowError {
    /// The window has no slab, or its centre is not one of them.
    #[error("body {id}: a window needs its centre slab")]
    NoCentre {
        /// The body.
        id: String,
    },
    /// An artificial cap would exceed the tet limit.
    #[error("body {id}: the cap of frame {frame} exceeds {limit} tets")]
    CapTooLarge {
        /// The body.
        id: String,
        /// Body frame index.
        frame: u32,
        /// The limit.
        limit: usize,
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
    /// The closed window mesh on the pair's lattice.
    pub body: Prepared,
    /// Taken tets in the window mesh's own order: the real first cap (if the centre slab
    /// opens the stream), the centre slab, the real last cap (if it closes it).
    pub taken: [Range<usize>; 3],
}

impl PreparedWindow {
    /// Tets whose labels are taken.
    pub fn taken_len(&self) -> usize {
        self.taken.iter().map(|r| r.len()).sum()
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
    let scale = w.geometry.scale;
    let shift_t = i64::from(scale) * i64::from(w.lo);
    let shifted = |m: &TetMesh| -> Result<TetMesh, WindowError> {
        let mut out = m.clone();
        for p in &mut out.vertices {
            let t = i64::from(p[3]) - shift_t;
            p[3] = i32::try_from(t).map_err(|_| WindowError::Overflow { id: id() })?;
        }
        Ok(out)
    };
    let cap = |src: &CapSource<'_>, local: u32, side: CapSide| -> Result<TetMesh, WindowError> {
        match src {
            CapSource::Real(m) => shifted(m),
            CapSource::Frame(g) => {
                let mut out = TetMesh::default();
                let at = SlabPlacement {
                    scale,
                    frame: i64::from(local),
                    iso: w.iso,
                };
                if march_cap(table(), g, at, side, w.max_cap_tets, &mut out) {
                    Ok(out)
                } else {
                    Err(WindowError::CapTooLarge {
                        id: id(),
                        frame: w.lo + local,
                        limit: w.max_cap_tets,
                    })
                }
            }
        }
    };
    let n = w.slabs.len() as u32;
    let mut mesh = TetMesh::default();
    let mut welder = Welder::default();
    let mut pieces = Vec::with_capacity(w.slabs.len() + 2);
    let mut ranges = Vec::with_capacity(w.slabs.len() + 2);
    let mut push = |part: &TetMesh, mesh: &mut TetMesh| {
        let start = mesh.tets.len();
        pieces.push(start);
        welder.append(mesh, part);
        ranges.push(start..mesh.tets.len());
    };
    push(&cap(&w.low, 0, CapSide::Low)?, &mut mesh);
    for s in &w.slabs {
        push(&shifted(s)?, &mut mesh);
    }
    push(&cap(&w.high, n, CapSide::High)?, &mut mesh);
    let empty = 0..0;
    let centre = w.centre + 1;
    let taken = [
        if w.centre == 0 && matches!(w.low, CapSource::Real(_)) {
            ranges[0].clone()
        } else {
            empty.clone()
        },
        ranges[centre].clone(),
        if w.centre + 1 == w.slabs.len() && matches!(w.high, CapSource::Real(_)) {
            ranges[ranges.len() - 1].clone()
        } else {
            empty
        },
    ];
    let local =
        BodyPrep::of(&mesh, &pieces).map_err(|source| WindowError::Prep { id: id(), source })?;
    let mut body = Prepared {
        id: w.id.to_string(),
        mesh: local.mesh,
        bvh: local.bvh,
        adjacency: local.adjacency.into(),
        normals: local.normals,
        factor: CHECKER_FACTOR * w.mul as i32,
        geometry: w.geometry,
        stamps_ns: Vec::new(),
        original: local.original.into(),
    };
    let mul = [w.mul; 4];
    if (mul != [1; 4] || w.add != [0; 4]) && !body.map_in_place(mul, w.add) {
        return Err(WindowError::Overflow { id: id() });
    }
    Ok(PreparedWindow { body, taken })
}

/// One crossing tet pair of two taken tets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// Checker-time range of the section.
    pub t: (f64, f64),
    /// Positions of the two tets among their bodies' taken tets, in leaf order (see
    /// `w_position`).
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
    /// Candidate tet pairs of the window (artificial caps and context slabs included).
    pub candidate_pairs: u64,
    /// Regions or contact tets whose inclusion stayed undecided (labelled OUTSIDE).
    pub undecided: u32,
}

/// Checks two prepared window bodies and keeps what their taken tets get.
pub fn check_window(a: &PreparedWindow, b: &PreparedWindow) -> WindowResult {
    let (r, crossings) = check_pair_detailed(&a.body, &b.body);
    let mut out = WindowResult {
        candidate_pairs: r.candidate_pairs,
        undecided: r.labels_a.undecided_regions + r.labels_b.undecided_regions,
        ..WindowResult::default()
    };
    for (k, (w, l)) in [(a, &r.labels_a), (b, &r.labels_b)].into_iter().enumerate() {
        let mut labels = vec![Label::Outside as u8; w.taken_len()];
        for (leaf, (&orig, &label)) in w.body.original.iter().zip(&l.labels).enumerate() {
            if let Some(p) = w.position(orig) {
                labels[p as usize] = label as u8;
                if label == Label::Inside {
                    out.ranges.push(t_range(&tet_of(&w.body.mesh, leaf as u32)));
                }
            }
        }
        let mut counts = LabelCounts::default();
        for &l in &labels {
            match l {
                x if x == Label::Interference as u8 => counts.interference += 1,
                x if x == Label::Inside as u8 => counts.inside += 1,
                _ => counts.outside += 1,
            }
        }
        out.labels[k] = TakenLabels {
            labels,
            counts,
            pieces: w.taken.clone().map(|r| r.len()),
        };
    }
    for (t0, t1, i, j) in crossings {
        let (Some(pa), Some(pb)) = (w_position(a, i), w_position(b, j)) else {
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

/// Position of leaf `i` of a window body among the taken tets in leaf order: each piece
/// keeps its range of indices in both orders, and its tets in leaf order are the order the
/// full check's streamed preparation gives them, so this position plus the piece's first
/// tet is the tet's leaf index in the full check.
fn w_position(w: &PreparedWindow, i: u32) -> Option<u32> {
    w.position(i)
}
