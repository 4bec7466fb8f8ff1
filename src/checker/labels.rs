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
    let n = adjacency.len().min(touch.len());
    let mut labels = vec![Label::Outside; n];
    let mut out = Labeling::default();
    let clear = |t: usize| touch[t] == Touch::Clear;
    // Regions of clear tets by union-find in one pass over the tets in index order (the
    // tree's leaf order: a linear read of the adjacency, where a flood fill jumps around
    // and waits on memory). Each region's root is its smallest tet.
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut contact = Vec::new();
    for t in 0..n {
        match touch[t] {
            Touch::Interference => labels[t] = Label::Interference,
            Touch::Contact | Touch::FaceToFace => contact.push(t as u32),
            Touch::Clear => {
                let mut root = find(&mut parent, t as u32);
                for &nb in &adjacency[t] {
                    if (nb as usize) < n && clear(nb as usize) {
                        let other = find(&mut parent, nb);
                        // The smaller root becomes the root of both.
                        if other != root {
                            parent[root.max(other) as usize] = root.min(other);
                            root = root.min(other);
                        }
                    }
                }
            }
        }
    }
    // Every clear tet points at its root; regions numbered by root, in order.
    const NO_REGION: u32 = u32::MAX;
    let mut region_of_root = vec![NO_REGION; n];
    let mut sizes: Vec<usize> = Vec::new();
    for t in 0..n {
        if clear(t) {
            let r = find(&mut parent, t as u32);
            parent[t] = r;
            let k = &mut region_of_root[r as usize];
            if *k == NO_REGION {
                *k = sizes.len() as u32;
                sizes.push(0);
            }
            sizes[*k as usize] += 1;
        }
    }
    out.regions = sizes.len() as u32;
    // Tries spread over each region (every step-th tet, up to TRIES_PER_REGION of them);
    // one interior point per tet suffices here.
    let steps: Vec<usize> = sizes
        .iter()
        .map(|&s| (s / TRIES_PER_REGION).max(1))
        .collect();
    let mut tries: Vec<Vec<u32>> = vec![Vec::new(); sizes.len()];
    let mut seen = vec![0usize; sizes.len()];
    for t in 0..n {
        if clear(t) {
            let k = region_of_root[parent[t] as usize] as usize;
            if seen[k] % steps[k] == 0 && tries[k].len() < TRIES_PER_REGION {
                tries[k].push(t as u32);
            }
            seen[k] += 1;
        }
    }
    let verdicts: Vec<Option<bool>> = tries
        .iter()
        .map(|ts| {
            ts.iter()
                .find_map(|&t| test.far(t, 1))
                .map(|(inside, _)| inside)
        })
        .collect();
    out.undecided_regions = verdicts.iter().filter(|v| v.is_none()).count() as u32;
    // Tets whose label is decided and whose reference point is off the other boundary (an
    // undecided region is no reference for its neighbours).
    let mut decided = vec![false; n];
    for t in 0..n {
        if clear(t) {
            let verdict = verdicts[region_of_root[parent[t] as usize] as usize];
            labels[t] = if verdict == Some(true) {
                Label::Inside
            } else {
                Label::Outside
            };
            decided[t] = verdict.is_some();
        }
    }
    // Contact tets, breadth first from decided neighbours.
    let mut queue: VecDeque<u32> = contact
        .iter()
        .copied()
        .filter(|&t| {
            adjacency[t as usize]
                .iter()
                .any(|&u| (u as usize) < n && decided[u as usize])
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
            if u as usize >= n || !st.decided[u as usize] {
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
            if (u as usize) < n
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

/// The root of `x`'s set, halving the path on the way.
fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}

/// The labelling state of the contact pass.
struct State {
    labels: Vec<Label>,
    decided: Vec<bool>,
    points: HashMap<u32, LatticePoint>,
    out: Labeling,
    done: Vec<bool>,
}
