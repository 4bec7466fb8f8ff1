//! Per-tet labels (seed 000 §3.2): INTERFERENCE where the two boundaries cross, and every
//! other tet INSIDE or OUTSIDE the other body.
//!
//! A tet that meets the other boundary without crossing it (shared vertices or edges, face
//! to face) is a *contact* tet and is tested on its own: the boundary may pass exactly
//! through its vertices, so such tets do not separate inside from outside. Every remaining
//! tet is disjoint from the other boundary, and two such tets sharing a face lie on the same
//! side; they form regions, one inclusion test per region decides it, and the label spreads
//! across face adjacency. This is right with no INTERFERENCE tet at all: a body entirely
//! inside the other is one INSIDE region, disjoint bodies one OUTSIDE region each.

use super::adjacency::NO_NEIGHBOUR;
use crate::kernel::LatticePoint;
use serde::Serialize;
use std::collections::{HashMap, VecDeque};

/// A tet's relation to the other body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[repr(u8)]
pub enum Label {
    /// Outside the other body.
    Outside = 0,
    /// Inside the other body.
    Inside = 1,
    /// Crosses the other body's boundary (or overlaps it with the same orientation).
    Interference = 2,
}

/// How a tet meets the other body's boundary (ordered: the strongest relation wins).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Touch {
    /// Disjoint from every tet of the other boundary.
    Clear,
    /// Touches it (vertex, edge, contact inside a face) without crossing.
    Contact,
    /// Lies in one of its tets' hyperplane, overlapping with opposite orientation: the two
    /// bodies face each other there (contact, not interference).
    FaceToFace,
    /// Crosses it, or overlaps it with the same orientation.
    Interference,
}

/// Label counts.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LabelCounts {
    /// INTERFERENCE tets.
    pub interference: u64,
    /// INSIDE tets.
    pub inside: u64,
    /// OUTSIDE tets.
    pub outside: u64,
}

/// The labels of one body against another.
#[derive(Debug, Clone, Default)]
pub struct Labeling {
    /// One label per tet.
    pub labels: Vec<Label>,
    /// Regions (connected sets of non-INTERFERENCE tets).
    pub regions: u32,
    /// Regions whose inclusion test stayed undecided on every point tried (labelled
    /// OUTSIDE; a non-zero count is reported as a warning).
    pub undecided_regions: u32,
}

impl Labeling {
    /// Counts per label.
    pub fn counts(&self) -> LabelCounts {
        let mut c = LabelCounts::default();
        for l in &self.labels {
            match l {
                Label::Outside => c.outside += 1,
                Label::Inside => c.inside += 1,
                Label::Interference => c.interference += 1,
            }
        }
        c
    }
}

/// How many tets of a region are tried as inclusion-test points before giving up.
const TRIES_PER_REGION: usize = 16;

/// The inclusion tests [`label_regions`] needs, against the other body.
pub trait InsideTest {
    /// Whether tet `t` lies inside, from up to `tries` of its interior points, each tested
    /// along rays to far points; with the point that decided (`None`: all undecided).
    fn far(&mut self, t: u32, tries: usize) -> Option<(bool, LatticePoint)>;
    /// Whether tet `t` lies inside, from its first interior point and a point `q` off the
    /// other boundary whose answer `q_inside` is known (crossings along the short segment
    /// between them); with the point used. `None` if a crossing is degenerate.
    fn from_known(
        &mut self,
        t: u32,
        q: &LatticePoint,
        q_inside: bool,
    ) -> Option<(bool, LatticePoint)>;
    /// An interior point of tet `t`.
    fn point(&self, t: u32) -> LatticePoint;
}

/// Labels every tet. `touch[t]` says how tet `t` meets the other boundary.
///
/// Regions of clear tets are labelled first (one far-ray test per region). Contact tets
/// are then decided one by one, each from a decided neighbour along the short segment
/// between their interior points (far rays only where that is degenerate or no neighbour
/// is decided): the neighbour's point is off the other boundary, so the signed crossing
/// count along the segment is the difference of the two answers.
pub fn label_regions(
    adjacency: &[[u32; 4]],
    touch: &[Touch],
    test: &mut impl InsideTest,
) -> Labeling {
    let n = adjacency.len();
    let mut labels = vec![Label::Outside; n];
    // Tets whose label is decided and whose reference point is off the other boundary.
    let mut decided = vec![false; n];
    let mut out = Labeling::default();
    let mut stack = Vec::new();
    let mut members = Vec::new();
    let mut contact = Vec::new();
    let mut seen = vec![false; n];
    for start in 0..n {
        match touch[start] {
            Touch::Interference => {
                labels[start] = Label::Interference;
                continue;
            }
            Touch::Contact | Touch::FaceToFace => {
                contact.push(start as u32);
                continue;
            }
            Touch::Clear if seen[start] => continue,
            Touch::Clear => {}
        }
        // Collect the region of clear tets.
        members.clear();
        stack.push(start as u32);
        seen[start] = true;
        while let Some(t) = stack.pop() {
            members.push(t);
            for &nb in &adjacency[t as usize] {
                if nb != NO_NEIGHBOUR && !seen[nb as usize] && touch[nb as usize] == Touch::Clear {
                    seen[nb as usize] = true;
                    stack.push(nb);
                }
            }
        }
        out.regions += 1;
        // Spread the tries over the region; one interior point per tet suffices here.
        let step = (members.len() / TRIES_PER_REGION).max(1);
        let verdict = members
            .iter()
            .step_by(step)
            .take(TRIES_PER_REGION)
            .find_map(|&t| test.far(t, 1));
        let label = match verdict {
            Some((true, _)) => Label::Inside,
            Some((false, _)) => Label::Outside,
            None => {
                out.undecided_regions += 1;
                Label::Outside
            }
        };
        for &t in &members {
            labels[t as usize] = label;
            // An undecided region is no reference for its neighbours.
            decided[t as usize] = verdict.is_some();
        }
    }
    // Contact tets, breadth first from decided neighbours.
    let mut queue: VecDeque<u32> = contact
        .iter()
        .copied()
        .filter(|&t| {
            adjacency[t as usize]
                .iter()
                .any(|&u| u != NO_NEIGHBOUR && decided[u as usize])
        })
        .collect();
    // Records a contact tet's verdict.
    let decide = |t: u32, verdict: Option<(bool, LatticePoint)>, st: &mut State| {
        st.done[t as usize] = true;
        st.labels[t as usize] = match verdict {
            Some((inside, p)) => {
                st.decided[t as usize] = true;
                st.points.insert(t, p);
                if inside {
                    Label::Inside
                } else {
                    Label::Outside
                }
            }
            // Every point undecided: the tet lies in the other boundary. Face to face that
            // is contact (outside); otherwise report it.
            None => {
                if touch[t as usize] != Touch::FaceToFace {
                    st.out.undecided_regions += 1;
                }
                Label::Outside
            }
        };
    };
    let mut st = State {
        labels,
        decided,
        points: HashMap::new(),
        out,
        done: vec![false; n],
    };
    while let Some(t) = queue.pop_front() {
        if st.done[t as usize] {
            continue;
        }
        let reference = adjacency[t as usize].iter().find_map(|&u| {
            if u == NO_NEIGHBOUR || !st.decided[u as usize] {
                return None;
            }
            let q = st.points.get(&u).copied().unwrap_or_else(|| test.point(u));
            Some((q, st.labels[u as usize] == Label::Inside))
        });
        let verdict = reference
            .and_then(|(q, q_inside)| test.from_known(t, &q, q_inside))
            .or_else(|| test.far(t, usize::MAX));
        decide(t, verdict, &mut st);
        for &u in &adjacency[t as usize] {
            if u != NO_NEIGHBOUR
                && !st.done[u as usize]
                && matches!(touch[u as usize], Touch::Contact | Touch::FaceToFace)
            {
                queue.push_back(u);
            }
        }
    }
    for &t in &contact {
        if !st.done[t as usize] {
            let verdict = test.far(t, usize::MAX);
            decide(t, verdict, &mut st);
        }
    }
    let State {
        labels, mut out, ..
    } = st;
    out.labels = labels;
    out
}

/// The labelling state of the contact pass.
struct State {
    labels: Vec<Label>,
    decided: Vec<bool>,
    points: HashMap<u32, LatticePoint>,
    out: Labeling,
    done: Vec<bool>,
}
