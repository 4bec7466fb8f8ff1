//! Per-tet labels (seed 000 §3.2): INTERFERENCE where the two boundaries cross, and every
//! other tet INSIDE or OUTSIDE the other body. Tets not separated by INTERFERENCE tets form
//! regions; one inclusion test per region decides it, and the label spreads across face
//! adjacency. This is right with no INTERFERENCE tet at all: a body entirely inside the
//! other is one INSIDE region, disjoint bodies one OUTSIDE region each.

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

/// Labels every tet. `interference[t]` marks INTERFERENCE tets; `inside(t)` is the
/// inclusion test of an interior point of tet `t` (None if undecided).
pub fn label_regions(
    adjacency: &[[u32; 4]],
    interference: &[bool],
    mut inside: impl FnMut(u32) -> Option<bool>,
) -> Labeling {
    let n = adjacency.len();
    let mut labels = vec![Label::Outside; n];
    let mut seen = vec![false; n];
    let mut out = Labeling::default();
    let mut stack = Vec::new();
    let mut members = Vec::new();
    for start in 0..n {
        if seen[start] || interference[start] {
            if interference[start] {
                labels[start] = Label::Interference;
            }
            continue;
        }
        // Collect the region.
        members.clear();
        stack.push(start as u32);
        seen[start] = true;
        while let Some(t) = stack.pop() {
            members.push(t);
            for &nb in &adjacency[t as usize] {
                if nb != NO_NEIGHBOUR && !seen[nb as usize] && !interference[nb as usize] {
                    seen[nb as usize] = true;
                    stack.push(nb);
                }
            }
        }
        out.regions += 1;
        // Spread the tries over the region (its first tets may all touch the other body).
        let step = (members.len() / TRIES_PER_REGION).max(1);
        let verdict = members
            .iter()
            .step_by(step)
            .take(TRIES_PER_REGION)
            .find_map(|&t| inside(t));
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
