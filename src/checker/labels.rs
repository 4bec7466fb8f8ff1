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
use serde::Serialize;

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

/// Labels every tet. `touch[t]` says how tet `t` meets the other boundary;
/// `inside(t, n)` tests up to `n` interior points of tet `t` (None if all undecided).
pub fn label_regions(
    adjacency: &[[u32; 4]],
    touch: &[Touch],
    mut inside: impl FnMut(u32, usize) -> Option<bool>,
) -> Labeling {
    let n = adjacency.len();
    let mut labels = vec![Label::Outside; n];
    let mut seen = vec![false; n];
    let mut out = Labeling::default();
    let mut stack = Vec::new();
    let mut members = Vec::new();
    for start in 0..n {
        match touch[start] {
            Touch::Interference => {
                labels[start] = Label::Interference;
                continue;
            }
            Touch::Contact | Touch::FaceToFace => {
                // On its own: every interior point tried.
                labels[start] = match inside(start as u32, usize::MAX) {
                    Some(true) => Label::Inside,
                    Some(false) => Label::Outside,
                    // Every point undecided: the tet lies in the other boundary. Face to
                    // face that is contact (outside); otherwise report it.
                    None => {
                        if touch[start] != Touch::FaceToFace {
                            out.undecided_regions += 1;
                        }
                        Label::Outside
                    }
                };
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
            .find_map(|&t| inside(t, 1));
        let label = match verdict {
            Some(true) => Label::Inside,
            Some(false) => Label::Outside,
            None => {
                out.undecided_regions += 1;
                Label::Outside
            }
        };
        for &t in &members {
            labels[t as usize] = label;
        }
    }
    out.labels = labels;
    out
}
