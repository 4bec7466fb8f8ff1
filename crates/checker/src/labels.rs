//! Per-tet labels (the interference paper's §3.2:
//! docs/methods/interference.md#labelling-by-propagation): INTERFERENCE where the two
//! boundaries cross, and every other tet INSIDE or OUTSIDE the other body.
//!
//! A tet that meets the other boundary without crossing it (shared vertices or edges, face
//! to face) is a *contact* tet and is tested on its own: the boundary may pass exactly
//! through its vertices, so such tets do not separate inside from outside. A tet the walk
//! only took as touching (it can at most touch, and was not tested further) is a contact
//! tet too: if it is disjoint from the other boundary after all, every point of it lies on
//! one side, and its own test gives the answer its region would have. Every remaining tet
//! is disjoint from the other boundary, and two such tets sharing a face lie on the same
//! side; they form regions, one inclusion test per region decides it, and the label spreads
//! across face adjacency. This is right with no INTERFERENCE tet at all: a body entirely
//! inside the other is one INSIDE region, disjoint bodies one OUTSIDE region each.

use chronotope_kernel::LatticePoint;
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
    /// Touches it (vertex, edge, contact inside a face) without crossing, or can at most
    /// touch it and was not tested further (a pair whose boxes meet in one plane only; see
    /// the walk's `visit`): labelled on its own either way.
    Contact,
    /// Lies in one of its tets' hyperplane, overlapping with opposite orientation: the two
    /// bodies face each other there (contact, not interference).
    FaceToFace,
    /// [`Touch::FaceToFace`] with one of its tets on the same four points (its twin): the
    /// tet lies in the other boundary, every point of it on that boundary.
    Twin,
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
    /// Whether tet `t` lies in one tet of the other boundary (then every point of it is on
    /// that boundary: [`Self::far`] and [`Self::from_known`] answer `None`). `false` when
    /// not known.
    fn lies_in_boundary(&mut self, _t: u32) -> bool {
        false
    }
}

/// Labels every tet. `touch[t]` says how tet `t` meets the other boundary.
///
/// Regions of clear tets are labelled first (one far-ray test per region). Contact tets
/// are then decided one by one, each from a decided neighbour along the short segment
/// between their interior points (far rays only where that is degenerate or no neighbour
/// is decided): the neighbour's point is off the other boundary, so the signed crossing
/// count along the segment is the difference of the two answers. A contact tet no decided
/// tet reaches (cut off by tets lying in the other boundary, where two bodies stand face
/// to face) takes far rays and is then the reference of its contact neighbours in turn.
pub fn label_regions(
    adjacency: &[[u32; 4]],
    touch: &[Touch],
    test: &mut impl InsideTest,
) -> Labeling {
    let n = adjacency.len().min(touch.len());
    let mut labels = vec![Label::Outside; n];
    let mut out = Labeling::default();
    let clear = |t: usize| touch[t] == Touch::Clear;
    let mut contact = Vec::new();
    for t in 0..n {
        match touch[t] {
            Touch::Interference => labels[t] = Label::Interference,
            Touch::Contact | Touch::FaceToFace | Touch::Twin => contact.push(t as u32),
            Touch::Clear => {}
        }
    }
    let Regions { of: region, tries } = Regions::of(&adjacency[..n], clear);
    out.regions = tries.len() as u32;
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
            let verdict = verdicts[region[t] as usize];
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
    // Queues the contact neighbours of `t` not yet decided.
    let push_contact_neighbours = |t: u32, done: &[bool], queue: &mut VecDeque<u32>| {
        for &u in &adjacency[t as usize] {
            if (u as usize) < n
                && !done[u as usize]
                && matches!(
                    touch[u as usize],
                    Touch::Contact | Touch::FaceToFace | Touch::Twin
                )
            {
                queue.push_back(u);
            }
        }
    };
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
                if !matches!(touch[t as usize], Touch::FaceToFace | Touch::Twin) {
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
    // Contact tets no decided tet reaches (their neighbours lie in the other boundary, as
    // face to face ones do) seed the search again one at a time, tested on their own: each
    // is then the reference for its contact neighbours, which take the short segment.
    let mut seeds = contact.iter();
    loop {
        while let Some(t) = queue.pop_front() {
            if st.done[t as usize] {
                continue;
            }
            // A tet face to face with the other body mostly lies in one of its tets (its twin,
            // as a rule): every test would be undecided, so none is made.
            let lies_in = match touch[t as usize] {
                Touch::Twin => true,
                Touch::FaceToFace => test.lies_in_boundary(t),
                _ => false,
            };
            if lies_in {
                decide(t, None, &mut st);
                push_contact_neighbours(t, &st.done, &mut queue);
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
            push_contact_neighbours(t, &st.done, &mut queue);
        }
        match seeds.find(|&&t| !st.done[t as usize]) {
            Some(&t) => queue.push_back(t),
            None => break,
        }
    }
    let State {
        labels, mut out, ..
    } = st;
    out.labels = labels;
    out
}

/// Connected sets of tets under face adjacency (those `member` takes), with the tets an
/// inclusion test tries in each.
#[derive(Debug)]
struct Regions {
    /// Region of each tet ([`NO_REGION`] for a tet not taken).
    of: Vec<u32>,
    /// Per region, every step-th of its tets in index order, up to [`TRIES_PER_REGION`].
    tries: Vec<Vec<u32>>,
}

const NO_REGION: u32 = u32::MAX;

impl Regions {
    fn of(adjacency: &[[u32; 4]], member: impl Fn(usize) -> bool) -> Self {
        let n = adjacency.len();
        // Union-find in one pass over the tets in index order (the tree's leaf order: a
        // linear read of the adjacency, where a flood fill jumps around and waits on
        // memory). Each region's root is its smallest tet.
        let mut parent: Vec<u32> = (0..n as u32).collect();
        for t in (0..n).filter(|&t| member(t)) {
            let mut root = find(&mut parent, t as u32);
            for &nb in &adjacency[t] {
                if (nb as usize) < n && member(nb as usize) {
                    let other = find(&mut parent, nb);
                    // The smaller root becomes the root of both.
                    if other != root {
                        parent[root.max(other) as usize] = root.min(other);
                        root = root.min(other);
                    }
                }
            }
        }
        // Regions numbered by root, in order.
        let mut of = vec![NO_REGION; n];
        let mut sizes: Vec<usize> = Vec::new();
        for t in (0..n).filter(|&t| member(t)) {
            let r = find(&mut parent, t as u32) as usize;
            if of[r] == NO_REGION {
                of[r] = sizes.len() as u32;
                sizes.push(0);
            }
            of[t] = of[r];
            sizes[of[t] as usize] += 1;
        }
        // Tries spread over each region; one interior point per tet suffices.
        let steps: Vec<usize> = sizes
            .iter()
            .map(|&s| (s / TRIES_PER_REGION).max(1))
            .collect();
        let mut tries: Vec<Vec<u32>> = vec![Vec::new(); sizes.len()];
        let mut seen = vec![0usize; sizes.len()];
        for t in (0..n).filter(|&t| member(t)) {
            let k = of[t] as usize;
            if seen[k] % steps[k] == 0 && tries[k].len() < TRIES_PER_REGION {
                tries[k].push(t as u32);
            }
            seen[k] += 1;
        }
        Self { of, tries }
    }
}

/// A body's connected components under face adjacency: they do not change when the body
/// moves, so a search that checks one placement after another computes them once
/// ([`any_inside`]).
#[derive(Debug)]
pub struct Components(Regions);

impl Components {
    /// The components of a mesh with this face adjacency.
    pub fn of(adjacency: &[[u32; 4]]) -> Self {
        Self(Regions::of(adjacency, |_| true))
    }
}

/// Whether [`label_regions`] labels some tet INSIDE, for `touch` without an INTERFERENCE
/// tet (the check of a candidate move, once no tet pair crosses), in time linear in the
/// contact tets rather than in the body:
///
/// - a component no tet of which touches the other boundary is one region: its tries are
///   tested as labelling tests them;
/// - in a component with contact tets, every region of clear tets borders a contact tet
///   (a path to it leaves the region through one), and lies on that tet's side of the other
///   boundary if the tet is decided. So each contact tet is decided, from a decided
///   neighbour along the short segment between their interior points (far rays where there
///   is none, or the segment is degenerate), and the clear neighbours of the undecided
///   ones (lying in the other boundary) are decided too.
///
/// Wherever labelling decides, this gives its answer: every point of a region, or of a
/// contact tet, is on the same side. A region whose every try is undecided (it lies in the
/// other boundary) is OUTSIDE for labelling; here another of its tets may decide it.
/// `touch` with an INTERFERENCE tet, or components of another mesh, are labelled in full.
pub fn any_inside(
    adjacency: &[[u32; 4]],
    touch: &[Touch],
    components: &Components,
    test: &mut impl InsideTest,
) -> bool {
    let Components(comps) = components;
    let n = adjacency.len();
    if touch.len() != n || comps.of.len() != n || touch.contains(&Touch::Interference) {
        return label_regions(adjacency, touch, test)
            .labels
            .contains(&Label::Inside);
    }
    let mut touched = vec![false; comps.tries.len()];
    let mut contact = Vec::new();
    for t in 0..n {
        if touch[t] != Touch::Clear {
            touched[comps.of[t] as usize] = true;
            contact.push(t as u32);
        }
    }
    let untouched_inside = comps.tries.iter().zip(&touched).any(|(tries, &touched)| {
        !touched
            && tries
                .iter()
                .find_map(|&t| test.far(t, 1))
                .is_some_and(|(inside, _)| inside)
    });
    if untouched_inside {
        return true;
    }
    // Decided tets, with the point that decided and the answer.
    let mut known: HashMap<u32, Option<(LatticePoint, bool)>> = HashMap::new();
    let mut decide = |t: u32, from: Option<(LatticePoint, bool)>| {
        from.and_then(|(q, q_inside)| test.from_known(t, &q, q_inside))
            .or_else(|| test.far(t, usize::MAX))
            .map(|(inside, p)| (p, inside))
    };
    for &c in &contact {
        let nbs = adjacency[c as usize]
            .iter()
            .copied()
            .filter(|&u| (u as usize) < n);
        if !known.contains_key(&c) {
            // A reference: a decided neighbour, else a clear one decided now.
            let mut from = nbs.clone().find_map(|u| known.get(&u).copied().flatten());
            if from.is_none() {
                if let Some(u) = nbs.clone().find(|&u| touch[u as usize] == Touch::Clear) {
                    let v = decide(u, None);
                    if v.is_some_and(|(_, inside)| inside) {
                        return true;
                    }
                    known.insert(u, v);
                    from = v;
                }
            }
            let v = decide(c, from);
            if v.is_some_and(|(_, inside)| inside) {
                return true;
            }
            known.insert(c, v);
        }
        // A decided contact tet is on the side of its clear neighbours (the face they share
        // is off the other boundary, and so is the contact tet's interior); an undecided one
        // (lying in the other boundary) says nothing of them.
        if known.get(&c).copied().flatten().is_some() {
            continue;
        }
        for u in nbs {
            if touch[u as usize] == Touch::Clear && !known.contains_key(&u) {
                let v = decide(u, None);
                if v.is_some_and(|(_, inside)| inside) {
                    return true;
                }
                known.insert(u, v);
            }
        }
    }
    false
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Answers by a truth table, counting the tests made: what an exact test of a body
    /// gives, off its boundary.
    struct Truth {
        inside: Vec<bool>,
        far: usize,
        from_known: usize,
    }

    impl InsideTest for Truth {
        fn far(&mut self, t: u32, _tries: usize) -> Option<(bool, LatticePoint)> {
            self.far += 1;
            Some((self.inside[t as usize], self.point(t)))
        }
        fn from_known(
            &mut self,
            t: u32,
            _q: &LatticePoint,
            _q_inside: bool,
        ) -> Option<(bool, LatticePoint)> {
            self.from_known += 1;
            Some((self.inside[t as usize], self.point(t)))
        }
        fn point(&self, t: u32) -> LatticePoint {
            [t as i32, 0, 0, 0]
        }
    }

    /// Tets in a row, each a face neighbour of the next.
    fn row(n: usize) -> Vec<[u32; 4]> {
        (0..n)
            .map(|t| {
                let before = if t > 0 { t as u32 - 1 } else { u32::MAX };
                let after = if t + 1 < n { t as u32 + 1 } else { u32::MAX };
                [before, after, u32::MAX, u32::MAX]
            })
            .collect()
    }

    /// Contact tets whose only neighbours lie in the other boundary (twins), as where two
    /// bodies stand face to face, with no clear tet to start from: one far test per run of
    /// them, the rest each from its neighbour's known answer; labels as the truth says.
    #[test]
    fn contact_runs_cut_off_by_twins_are_tested_once_each() {
        // Runs of 5, 7 and 3 contact tets between twins; the middle run inside.
        let mut touch = Vec::new();
        let mut inside = Vec::new();
        for (len, is_in) in [(5, false), (7, true), (3, false)] {
            touch.push(Touch::Twin);
            inside.push(false);
            touch.extend(std::iter::repeat_n(Touch::Contact, len));
            inside.extend(std::iter::repeat_n(is_in, len));
        }
        let adjacency = row(touch.len());
        let mut test = Truth {
            inside: inside.clone(),
            far: 0,
            from_known: 0,
        };
        let got = label_regions(&adjacency, &touch, &mut test);
        assert_eq!(test.far, 3, "one far test per run");
        assert_eq!(test.from_known, 5 + 7 + 3 - 3);
        for (t, l) in got.labels.iter().enumerate() {
            let want = if touch[t] == Touch::Twin || !inside[t] {
                Label::Outside
            } else {
                Label::Inside
            };
            assert_eq!(*l, want, "tet {t}");
        }
        assert_eq!(got.undecided_regions, 0);
    }
}
