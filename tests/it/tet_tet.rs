//! Tet–tet intersection in R^4 against an independent exact LP oracle, hand cases and
//! invariance properties.
//!
//! The oracle solves, in exact rationals (two-phase simplex, Bland's rule),
//!
//! ```text
//! max t  s.t.  Σ λ_i a_i = Σ μ_j b_j,  Σ λ_i = Σ μ_j = 1,  λ_i ≥ t,  μ_j ≥ t
//! ```
//!
//! The closed tets meet iff the LP is feasible with t* ≥ 0; their relative interiors
//! meet iff t* > 0. With its own determinants for flatness, coplanarity and orientation
//! this gives an independent [`TetPairRelation`].

use chronotope::kernel::intersect::{
    classify, classify_if, relative_interiors_meet, segment_crosses_tet, tets_cross,
    tets_intersect, triangles_cross, LatticeTet, TetPairRelation,
};
use chronotope::kernel::LatticePoint;
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------
// Exact rationals over i128 (checked: an overflow fails the test loudly).
// ---------------------------------------------------------------------------------------

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Q {
    n: i128,
    d: i128,
}

fn gcd(mut a: i128, mut b: i128) -> i128 {
    a = a.abs();
    b = b.abs();
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

impl Q {
    fn int(n: i128) -> Q {
        Q { n, d: 1 }
    }
    fn new(n: i128, d: i128) -> Q {
        assert!(d != 0);
        let g = gcd(n, d).max(1);
        let s = if d < 0 { -1 } else { 1 };
        Q {
            n: s * n / g,
            d: s * d / g,
        }
    }
    fn zero() -> Q {
        Q::int(0)
    }
    fn is_zero(self) -> bool {
        self.n == 0
    }
    fn signum(self) -> i128 {
        self.n.signum()
    }
    fn add(self, o: Q) -> Q {
        let g = gcd(self.d, o.d);
        let (da, db) = (self.d / g, o.d / g);
        let n = self
            .n
            .checked_mul(db)
            .and_then(|x| o.n.checked_mul(da).and_then(|y| x.checked_add(y)))
            .expect("oracle overflow");
        Q::new(n, da.checked_mul(o.d).expect("oracle overflow"))
    }
    fn neg(self) -> Q {
        Q {
            n: -self.n,
            d: self.d,
        }
    }
    fn sub(self, o: Q) -> Q {
        self.add(o.neg())
    }
    fn mul(self, o: Q) -> Q {
        let g1 = gcd(self.n, o.d).max(1);
        let g2 = gcd(o.n, self.d).max(1);
        let n = (self.n / g1)
            .checked_mul(o.n / g2)
            .expect("oracle overflow");
        let d = (self.d / g2)
            .checked_mul(o.d / g1)
            .expect("oracle overflow");
        Q::new(n, d)
    }
    fn div(self, o: Q) -> Q {
        assert!(!o.is_zero());
        self.mul(Q::new(o.d, o.n))
    }
    fn lt(self, o: Q) -> bool {
        self.sub(o).n < 0
    }
}

// ---------------------------------------------------------------------------------------
// Two-phase simplex (maximisation, Bland's rule: no cycling).
// ---------------------------------------------------------------------------------------

struct Tableau {
    rows: Vec<Vec<Q>>,
    rhs: Vec<Q>,
    basis: Vec<usize>,
}

impl Tableau {
    fn pivot(&mut self, r: usize, c: usize) {
        let p = self.rows[r][c];
        for v in self.rows[r].iter_mut() {
            *v = v.div(p);
        }
        self.rhs[r] = self.rhs[r].div(p);
        for i in 0..self.rows.len() {
            if i != r && !self.rows[i][c].is_zero() {
                let f = self.rows[i][c];
                for j in 0..self.rows[i].len() {
                    let delta = f.mul(self.rows[r][j]);
                    self.rows[i][j] = self.rows[i][j].sub(delta);
                }
                self.rhs[i] = self.rhs[i].sub(f.mul(self.rhs[r]));
            }
        }
        self.basis[r] = c;
    }

    /// Maximises cost·x over columns `< allowed`; returns the optimum (bounded here).
    fn maximise(&mut self, cost: &[Q], allowed: usize) -> Q {
        loop {
            let mut entering = None;
            for j in 0..allowed {
                if self.basis.contains(&j) {
                    continue;
                }
                let mut rc = cost[j];
                for (i, &bi) in self.basis.iter().enumerate() {
                    rc = rc.sub(cost[bi].mul(self.rows[i][j]));
                }
                if rc.signum() > 0 {
                    entering = Some(j);
                    break;
                }
            }
            let Some(c) = entering else { break };
            let mut leave: Option<(usize, Q)> = None;
            for i in 0..self.rows.len() {
                if self.rows[i][c].signum() > 0 {
                    let ratio = self.rhs[i].div(self.rows[i][c]);
                    let better = match leave {
                        None => true,
                        Some((li, lr)) => {
                            ratio.lt(lr) || (ratio == lr && self.basis[i] < self.basis[li])
                        }
                    };
                    if better {
                        leave = Some((i, ratio));
                    }
                }
            }
            let (r, _) = leave.expect("the oracle LP is bounded");
            self.pivot(r, c);
        }
        let mut value = Q::zero();
        for (i, &bi) in self.basis.iter().enumerate() {
            value = value.add(cost[bi].mul(self.rhs[i]));
        }
        value
    }
}

/// max t (see the file notes), or None if the affine hulls do not even meet.
fn oracle_t(a: &LatticeTet, b: &LatticeTet) -> Option<Q> {
    // Columns: λ'_0..3, μ'_0..3, t+, t− (λ = λ' + t, μ = μ' + t), then 6 artificials.
    const N: usize = 10;
    let mut rows = vec![vec![Q::zero(); N + 6]; 6];
    let mut rhs = vec![Q::zero(); 6];
    for i in 0..4 {
        rows[0][i] = Q::int(1);
        rows[1][4 + i] = Q::int(1);
    }
    for r in 0..2 {
        rows[r][8] = Q::int(4);
        rows[r][9] = Q::int(-4);
        rhs[r] = Q::int(1);
    }
    for k in 0..4 {
        let mut tcoef = 0i128;
        for i in 0..4 {
            rows[2 + k][i] = Q::int(i128::from(a[i][k]));
            rows[2 + k][4 + i] = Q::int(-i128::from(b[i][k]));
            tcoef += i128::from(a[i][k]) - i128::from(b[i][k]);
        }
        rows[2 + k][8] = Q::int(tcoef);
        rows[2 + k][9] = Q::int(-tcoef);
    }
    for (r, row) in rows.iter_mut().enumerate() {
        row[N + r] = Q::int(1);
    }
    let mut tab = Tableau {
        rows,
        rhs,
        basis: (N..N + 6).collect(),
    };
    // Phase 1: maximise −Σ artificials.
    let mut cost1 = vec![Q::zero(); N + 6];
    for c in cost1.iter_mut().skip(N) {
        *c = Q::int(-1);
    }
    if tab.maximise(&cost1, N + 6).signum() < 0 {
        return None;
    }
    // Drive artificials out of the basis; drop redundant rows.
    let mut r = 0;
    while r < tab.rows.len() {
        if tab.basis[r] >= N {
            if let Some(c) = (0..N).find(|&c| !tab.rows[r][c].is_zero()) {
                tab.pivot(r, c);
            } else {
                tab.rows.remove(r);
                tab.rhs.remove(r);
                tab.basis.remove(r);
                continue;
            }
        }
        r += 1;
    }
    let mut cost2 = vec![Q::zero(); N + 6];
    cost2[8] = Q::int(1);
    cost2[9] = Q::int(-1);
    Some(tab.maximise(&cost2, N))
}

// ---------------------------------------------------------------------------------------
// The oracle's own determinants and classification.
// ---------------------------------------------------------------------------------------

fn det4(m: [[i128; 4]; 4]) -> i128 {
    // Leibniz formula: independent of the library's expansion.
    let mut total = 0;
    for p0 in 0..4 {
        for p1 in 0..4 {
            for p2 in 0..4 {
                for p3 in 0..4 {
                    let p = [p0, p1, p2, p3];
                    if (0..4).any(|i| (i + 1..4).any(|j| p[i] == p[j])) {
                        continue;
                    }
                    let inv = (0..4)
                        .map(|i| (i + 1..4).filter(|&j| p[i] > p[j]).count())
                        .sum::<usize>();
                    let s = if inv % 2 == 0 { 1 } else { -1 };
                    total += s * m[0][p0] * m[1][p1] * m[2][p2] * m[3][p3];
                }
            }
        }
    }
    total
}

/// det[t1−t0, t2−t0, t3−t0, x−t0].
fn side(t: &LatticeTet, x: &[i128; 4]) -> i128 {
    let d = |p: &[i128; 4]| [0, 1, 2, 3].map(|k| p[k] - i128::from(t[0][k]));
    let v = |p: &LatticePoint| d(&p.map(i128::from));
    det4([v(&t[1]), v(&t[2]), v(&t[3]), d(x)])
}

fn flat(t: &LatticeTet) -> bool {
    let o = t[0].map(i128::from);
    (0..4).all(|k| {
        let mut x = o;
        x[k] += 1;
        side(t, &x) == 0
    })
}

fn oracle(a: &LatticeTet, b: &LatticeTet) -> TetPairRelation {
    let t = oracle_t(a, b);
    let meet = matches!(t, Some(t) if t.signum() >= 0);
    let interiors = matches!(t, Some(t) if t.signum() > 0);
    if !meet {
        return TetPairRelation::Disjoint;
    }
    if flat(a) || flat(b) {
        return TetPairRelation::Touching;
    }
    if b.iter().all(|p| side(a, &p.map(i128::from)) == 0) {
        // Same hyperplane: compare the sides of a point off it.
        let off = |k: usize| {
            let mut x = a[0].map(i128::from);
            x[k] += 1;
            x
        };
        let x = (0..4)
            .map(off)
            .find(|x| side(a, x) != 0)
            .expect("a is not flat");
        return TetPairRelation::Coplanar {
            overlap_volume_positive: interiors,
            same_orientation: side(a, &x).signum() == side(b, &x).signum(),
        };
    }
    if interiors {
        TetPairRelation::Crossing
    } else {
        TetPairRelation::Touching
    }
}

/// The DESIGN §4 test taken literally (strict vertex tests only, no exact fallback).
fn design_literal(a: &LatticeTet, b: &LatticeTet) -> bool {
    const EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];
    const TRIS: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];
    let sides = |t: &LatticeTet, u: &LatticeTet| u.map(|p| side(t, &p.map(i128::from)).signum());
    let (sb, sa) = (sides(a, b), sides(b, a));
    let one_side = |s: [i128; 4]| s.iter().all(|&v| v >= 0) || s.iter().all(|&v| v <= 0);
    if one_side(sb) || one_side(sa) {
        return false;
    }
    EDGES
        .iter()
        .any(|&[i, j]| segment_crosses_tet(&a[i], &a[j], b))
        || EDGES
            .iter()
            .any(|&[i, j]| segment_crosses_tet(&b[i], &b[j], a))
        || TRIS.iter().any(|ta| {
            TRIS.iter()
                .any(|tb| triangles_cross(&ta.map(|i| a[i]), &tb.map(|i| b[i])))
        })
}

// ---------------------------------------------------------------------------------------
// Random pairs.
// ---------------------------------------------------------------------------------------

struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        // splitmix64
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn range(&mut self, lo: i32, hi: i32) -> i32 {
        lo + (self.next() % (hi - lo + 1) as u64) as i32
    }
    fn point(&mut self, lo: i32, hi: i32) -> LatticePoint {
        [0; 4].map(|_| self.range(lo, hi))
    }
    fn tet(&mut self, lo: i32, hi: i32) -> LatticeTet {
        [0; 4].map(|_| self.point(lo, hi))
    }
}

/// Facets of the Kuhn simplices of the unit 4-cube, scaled by 2 or 4 and moved by a small
/// offset: tets of lattice meshes (shared faces, coplanar neighbours, ridges).
fn kuhn_facet(rng: &mut Rng) -> LatticeTet {
    let mut perm = [0usize, 1, 2, 3];
    for i in (1..4).rev() {
        perm.swap(i, rng.range(0, i as i32) as usize);
    }
    let scale = 2 * rng.range(1, 2);
    let mut verts = [[0i32; 4]; 5];
    for s in 1..5 {
        verts[s] = verts[s - 1];
        verts[s][perm[s - 1]] += scale;
    }
    let offset = [0; 4].map(|_| rng.range(-2, 1));
    let skip = rng.range(0, 4) as usize;
    let mut out = [[0; 4]; 4];
    let mut m = 0;
    for (s, v) in verts.iter().enumerate() {
        if s != skip {
            out[m] = [0, 1, 2, 3].map(|k| v[k] + offset[k]);
            m += 1;
        }
    }
    out
}

/// A random point of the hyperplane n·x = c (n has a ±1 entry at `k`).
fn point_in_plane(rng: &mut Rng, n: [i32; 4], c: i32, k: usize, lo: i32, hi: i32) -> LatticePoint {
    let mut p = rng.point(lo, hi);
    p[k] = 0;
    let rest: i32 = (0..4).map(|i| n[i] * p[i]).sum();
    p[k] = (c - rest) * n[k];
    p
}

#[derive(Default, Debug)]
struct Tally {
    pairs: usize,
    disjoint: usize,
    touching: usize,
    crossing: usize,
    coplanar_overlap: usize,
    coplanar_contact: usize,
    flat: usize,
    literal_misses: usize,
}

fn check_pair(a: &LatticeTet, b: &LatticeTet, tally: &mut Tally) {
    let want = oracle(a, b);
    let got = classify(a, b);
    assert_eq!(got, want, "classify({a:?}, {b:?})");
    assert_eq!(classify(b, a), got, "symmetry for {a:?}, {b:?}");
    // When touching does not matter, a pair that only touches (a common boundary point,
    // or tets in one hyperplane meeting without a common interior point) may read
    // Disjoint; every other relation is decided in full.
    let lax = classify_if(a, b, false);
    match want {
        TetPairRelation::Touching
        | TetPairRelation::Coplanar {
            overlap_volume_positive: false,
            ..
        } => assert!(
            lax == want || lax == TetPairRelation::Disjoint,
            "classify_if({a:?}, {b:?}, false) = {lax:?}, want {want:?} or Disjoint"
        ),
        _ => assert_eq!(lax, want, "classify_if({a:?}, {b:?}, false)"),
    }
    let crossing = want == TetPairRelation::Crossing;
    assert_eq!(tets_cross(a, b), crossing, "tets_cross({a:?}, {b:?})");
    assert_eq!(tets_cross(b, a), crossing, "tets_cross({b:?}, {a:?})");
    let t = oracle_t(a, b);
    assert_eq!(
        tets_intersect(a, b),
        matches!(t, Some(t) if t.signum() >= 0),
        "SAT {a:?} {b:?}"
    );
    assert_eq!(
        relative_interiors_meet(a, b),
        matches!(t, Some(t) if t.signum() > 0),
        "strict SAT {a:?} {b:?}"
    );
    let literal = design_literal(a, b);
    assert!(
        !literal || crossing,
        "DESIGN vertex tests claim a crossing: {a:?} {b:?}"
    );
    tally.pairs += 1;
    if flat(a) || flat(b) {
        tally.flat += 1;
    }
    match want {
        TetPairRelation::Disjoint => tally.disjoint += 1,
        TetPairRelation::Touching => tally.touching += 1,
        TetPairRelation::Crossing => {
            tally.crossing += 1;
            if !literal {
                tally.literal_misses += 1;
            }
        }
        TetPairRelation::Coplanar {
            overlap_volume_positive: true,
            ..
        } => tally.coplanar_overlap += 1,
        TetPairRelation::Coplanar { .. } => tally.coplanar_contact += 1,
    }
}

#[test]
fn agrees_with_the_lp_oracle_on_random_pairs() {
    let mut rng = Rng(2024);
    let mut all = Vec::new();

    // 1. Tiny grid: degenerate positions everywhere.
    let mut t = Tally::default();
    for _ in 0..1500 {
        let (a, b) = (rng.tet(0, 2), rng.tet(0, 2));
        check_pair(&a, &b, &mut t);
    }
    all.push(("coords in [0,2]", t));

    // 2. Shared vertices (0..=3 of them, any order).
    let mut t = Tally::default();
    for _ in 0..1500 {
        let a = rng.tet(-3, 3);
        let mut b = rng.tet(-3, 3);
        let shared = rng.range(0, 3) as usize;
        for v in b.iter_mut().take(shared) {
            *v = a[rng.range(0, 3) as usize];
        }
        let r = rng.range(0, 3) as usize;
        b.swap(0, r);
        check_pair(&a, &b, &mut t);
    }
    all.push(("shared vertices, [-3,3]", t));

    // 3. Lattice mesh facets (Kuhn simplices of neighbouring cubes, midpoints).
    let mut t = Tally::default();
    for _ in 0..1500 {
        let a = kuhn_facet(&mut rng);
        let mut b = kuhn_facet(&mut rng);
        if rng.range(0, 2) == 0 {
            // Move one vertex to an edge midpoint-like lattice point nearby.
            let i = rng.range(0, 3) as usize;
            b[i] = rng.point(-2, 2);
        }
        check_pair(&a, &b, &mut t);
    }
    all.push(("Kuhn facets", t));

    // 4. Tets in one hyperplane (3D overlap), or one in it and one across.
    let mut t = Tally::default();
    let planes = [
        ([0, 0, 0, 1], 0, 3),
        ([1, 1, 0, 0], 1, 0),
        ([1, -1, 1, 1], 2, 2),
    ];
    for _ in 0..1500 {
        let (n, c, k) = planes[rng.range(0, 2) as usize];
        let a = [0; 4].map(|_| point_in_plane(&mut rng, n, c, k, -2, 2));
        let b = if rng.range(0, 3) == 0 {
            rng.tet(-2, 2)
        } else {
            [0; 4].map(|_| point_in_plane(&mut rng, n, c, k, -2, 2))
        };
        check_pair(&a, &b, &mut t);
    }
    all.push(("one hyperplane", t));

    // 5. Generic: larger coordinates, B near A.
    let mut t = Tally::default();
    for _ in 0..1000 {
        let a = rng.tet(-60, 60);
        let c = a[rng.range(0, 3) as usize];
        let b = [0; 4].map(|_| {
            let d = rng.point(-60, 60);
            [0, 1, 2, 3].map(|k| c[k] + d[k])
        });
        check_pair(&a, &b, &mut t);
    }
    all.push(("generic [-60,60]", t));

    let mut total = 0;
    for (name, t) in &all {
        println!("{name:>24}: {t:?}");
        total += t.pairs;
    }
    assert!(total >= 3000);
    // The sets must exercise what they are for.
    let sum = |f: fn(&Tally) -> usize| all.iter().map(|(_, t)| f(t)).sum::<usize>();
    assert!(sum(|t| t.crossing) > 300);
    assert!(sum(|t| t.touching) > 300);
    assert!(sum(|t| t.coplanar_overlap) > 100 && sum(|t| t.coplanar_contact) > 50);
    assert!(
        sum(|t| t.literal_misses) > 0,
        "degenerate crossings should occur"
    );
}

// ---------------------------------------------------------------------------------------
// Hand cases.
// ---------------------------------------------------------------------------------------

const O: LatticePoint = [0, 0, 0, 0];
const E1: LatticePoint = [1, 0, 0, 0];
const E2: LatticePoint = [0, 1, 0, 0];
const E3: LatticePoint = [0, 0, 1, 0];
const E4: LatticePoint = [0, 0, 0, 1];

fn neg(p: LatticePoint) -> LatticePoint {
    p.map(|c| -c)
}

fn both_ways(a: &LatticeTet, b: &LatticeTet) -> TetPairRelation {
    let r = classify(a, b);
    assert_eq!(classify(b, a), r);
    assert_eq!(oracle(a, b), r, "oracle disagrees on {a:?} {b:?}");
    r
}

#[test]
fn identical_tets_overlap_coplanar_with_the_same_orientation() {
    let a = [O, E1, E2, E3];
    let want = TetPairRelation::Coplanar {
        overlap_volume_positive: true,
        same_orientation: true,
    };
    assert_eq!(both_ways(&a, &a), want);
    // An even permutation keeps the orientation, an odd one flips it.
    assert_eq!(both_ways(&a, &[E1, E2, O, E3]), want);
    assert_eq!(
        both_ways(&a, &[E2, E1, O, E3]),
        TetPairRelation::Coplanar {
            overlap_volume_positive: true,
            same_orientation: false
        }
    );
    assert!(!tets_cross(&a, &a));
}

#[test]
fn shared_face_edge_or_vertex_only_is_touching() {
    // In the hyperplane t = 0.
    let a = [O, E1, E2, E3];
    // Shared face, other hyperplane (z = 0).
    assert_eq!(both_ways(&a, &[O, E1, E2, E4]), TetPairRelation::Touching);
    // Shared face, same hyperplane, other side: coplanar contact without volume.
    let far = [1, 1, 1, 0];
    assert!(matches!(
        both_ways(&a, &[E1, E2, E3, far]),
        TetPairRelation::Coplanar {
            overlap_volume_positive: false,
            ..
        }
    ));
    // Shared edge only, different hyperplanes (b ∩ {t = 0} is the edge O–E1).
    assert_eq!(
        both_ways(&a, &[O, E1, E4, [0, -1, 0, 1]]),
        TetPairRelation::Touching
    );
    // Shared vertex only.
    assert_eq!(
        both_ways(&a, &[O, neg(E1), neg(E2), E4]),
        TetPairRelation::Touching
    );
    assert_eq!(
        both_ways(&a, &[O, neg(E1), neg(E2), [0, 0, -1, 1]]),
        TetPairRelation::Touching
    );
    // Nothing shared: a parallel hyperplane, and a shifted copy in the same one.
    let up = a.map(|p| [p[0] + 2, p[1], p[2], p[3] + 1]);
    assert_eq!(both_ways(&a, &up), TetPairRelation::Disjoint);
    let aside = a.map(|p| [p[0] + 2, p[1], p[2], p[3]]);
    assert_eq!(both_ways(&a, &aside), TetPairRelation::Disjoint);
}

#[test]
fn a_clean_transversal_crossing() {
    let a = [O, [4, 0, 0, 0], [0, 4, 0, 0], [0, 0, 4, 0]]; // t = 0
    let b = [[1, 1, 1, -1], [2, 1, 1, -1], [1, 2, 1, -1], [1, 1, 1, 2]]; // z = 1
    assert_eq!(both_ways(&a, &b), TetPairRelation::Crossing);
    assert!(tets_cross(&a, &b) && tets_cross(&b, &a));
    assert!(design_literal(&a, &b));
}

#[test]
fn a_crossing_whose_polygon_has_only_degenerate_vertices() {
    // Both tets meet the 2-plane {z = 0, t = 0} in the same triangle (0,0),(2,0),(0,2),
    // each through two of its vertices and an edge midpoint: every vertex test hits a zero.
    let a = [O, [2, 0, 0, 0], [0, 2, 1, 0], [0, 2, -1, 0]]; // t = 0
    let b = [O, [2, 0, 0, 0], [0, 2, 0, 1], [0, 2, 0, -1]]; // z = 0
    assert_eq!(both_ways(&a, &b), TetPairRelation::Crossing);
    assert!(
        !design_literal(&a, &b),
        "the literal DESIGN test misses this one"
    );
}

#[test]
fn a_crossing_along_a_ridge_is_touching() {
    // Body A's surface: two tets meeting in the face F = (O, E1, E2) (plane z = t = 0)
    // and crossing the hyperplane z = 0 of B there; B's tet contains F in its interior
    // region of {z = 0, t = 0}.
    let a1 = [O, [4, 0, 0, 0], [0, 4, 0, 0], [0, 0, 1, 0]]; // t = 0, z ≥ 0
    let a2 = [O, [4, 0, 0, 0], [0, 4, 0, 0], [0, 0, -1, 1]]; // z ≤ 0
    let b = [
        [-1, -1, 0, -2],
        [9, -1, 0, -2],
        [-1, 9, 0, -2],
        [-1, -1, 0, 5],
    ]; // z = 0
    assert_eq!(both_ways(&a1, &b), TetPairRelation::Touching);
    assert_eq!(both_ways(&a2, &b), TetPairRelation::Touching);
}

/// Outward-oriented boundary tets of the 4-simplex `v` (the facet opposite v[i], ordered
/// so that the interior is on the negative side of its normal).
fn boundary(v: [LatticePoint; 5]) -> Vec<LatticeTet> {
    (0..5)
        .map(|skip| {
            let mut t: Vec<LatticePoint> = (0..5).filter(|&i| i != skip).map(|i| v[i]).collect();
            let tet: LatticeTet = [t[0], t[1], t[2], t[3]];
            if side(&tet, &v[skip].map(i128::from)) > 0 {
                t.swap(0, 1);
            }
            [t[0], t[1], t[2], t[3]]
        })
        .collect()
}

#[test]
fn face_to_face_bodies_in_adjacent_cells_never_cross() {
    // Two unit lattice 4-simplices on either side of the common hyperplane t = 0.
    let below = boundary([O, E1, E2, E3, neg(E4)]);
    let above = boundary([O, E1, E2, E3, E4]);
    let mut overlaps = 0;
    for a in &below {
        for b in &above {
            let r = both_ways(a, b);
            assert_ne!(r, TetPairRelation::Crossing, "{a:?} {b:?}");
            if let TetPairRelation::Coplanar {
                overlap_volume_positive: true,
                same_orientation,
            } = r
            {
                overlaps += 1;
                assert!(!same_orientation, "face to face: opposite outward normals");
            }
        }
    }
    // Only the common facet t = 0 (the facets x_i = 0 of both share just a triangle).
    assert_eq!(overlaps, 1);
    // The same bodies overlapping (one moved by half its size): the boundaries cross.
    let big = boundary([O, E1, E2, E3, E4].map(|p| p.map(|c| 2 * c)));
    let moved = boundary([O, E1, E2, E3, E4].map(|p| [2 * p[0] + 1, 2 * p[1], 2 * p[2], 2 * p[3]]));
    assert!(big.iter().any(|a| moved.iter().any(|b| tets_cross(a, b))));
    // A body against a copy of itself: every facet overlaps with the same orientation.
    for a in &above {
        assert_eq!(
            classify(a, a),
            TetPairRelation::Coplanar {
                overlap_volume_positive: true,
                same_orientation: true
            }
        );
    }
}

#[test]
fn huge_coordinates_take_the_wide_paths() {
    let a = [O, [4, 0, 0, 0], [0, 4, 0, 0], [0, 0, 4, 0]];
    let b = [[1, 1, 1, -1], [2, 1, 1, -1], [1, 2, 1, -1], [1, 1, 1, 2]];
    for k in [1, 1 << 12, 1 << 20, 1 << 27] {
        let s = |t: &LatticeTet| t.map(|p| p.map(|c| c * k));
        assert_eq!(
            classify(&s(&a), &s(&b)),
            TetPairRelation::Crossing,
            "scale {k}"
        );
    }
    // Spreads close to 2^32: only the 256-bit path is exact.
    let (lo, hi) = (i32::MIN, i32::MAX);
    let extreme = [
        [lo, lo, lo, 0],
        [hi, lo, lo, 0],
        [lo, hi, lo, 0],
        [lo, lo, hi, 0],
    ];
    let same = TetPairRelation::Coplanar {
        overlap_volume_positive: true,
        same_orientation: true,
    };
    assert_eq!(classify(&extreme, &extreme), same);
    let c = lo / 2;
    let across = [
        [c - 5, c - 5, c, lo],
        [c + 5, c - 5, c, lo],
        [c - 5, c + 5, c, lo],
        [c, c, c, hi],
    ];
    assert_eq!(classify(&extreme, &across), TetPairRelation::Crossing);
    assert!(tets_intersect(&extreme, &across) && relative_interiors_meet(&across, &extreme));
    let beside = across.map(|p| [p[0], p[1], hi, p[3]]);
    assert_eq!(classify(&extreme, &beside), TetPairRelation::Disjoint);
}

// ---------------------------------------------------------------------------------------
// Properties.
// ---------------------------------------------------------------------------------------

fn small_tet() -> impl Strategy<Value = LatticeTet> {
    prop::array::uniform4(prop::array::uniform4(-2i32..=2))
}

fn permute(t: &LatticeTet, p: [usize; 4]) -> LatticeTet {
    [t[p[0]], t[p[1]], t[p[2]], t[p[3]]]
}

fn parity(p: [usize; 4]) -> bool {
    (0..4)
        .map(|i| (i + 1..4).filter(|&j| p[i] > p[j]).count())
        .sum::<usize>()
        % 2
        == 1
}

fn flip(r: TetPairRelation) -> TetPairRelation {
    match r {
        TetPairRelation::Coplanar {
            overlap_volume_positive,
            same_orientation,
        } => TetPairRelation::Coplanar {
            overlap_volume_positive,
            same_orientation: !same_orientation,
        },
        other => other,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn classify_is_symmetric(a in small_tet(), b in small_tet()) {
        prop_assert_eq!(classify(&a, &b), classify(&b, &a));
        prop_assert_eq!(tets_cross(&a, &b), tets_cross(&b, &a));
        prop_assert_eq!(tets_intersect(&a, &b), tets_intersect(&b, &a));
    }

    #[test]
    fn classify_is_translation_invariant(
        a in small_tet(),
        b in small_tet(),
        v in prop::array::uniform4(-(1i32 << 29)..(1i32 << 29)),
    ) {
        let mv = |t: &LatticeTet| t.map(|p| [0, 1, 2, 3].map(|k| p[k] + v[k]));
        prop_assert_eq!(classify(&mv(&a), &mv(&b)), classify(&a, &b));
        prop_assert_eq!(tets_intersect(&mv(&a), &mv(&b)), tets_intersect(&a, &b));
    }

    #[test]
    fn classify_respects_vertex_permutations(
        a in small_tet(),
        b in small_tet(),
        pa in Just([0usize, 1, 2, 3]).prop_shuffle(),
        pb in Just([0usize, 1, 2, 3]).prop_shuffle(),
    ) {
        let r = classify(&a, &b);
        let mut want = r;
        if parity(pa) != parity(pb) {
            want = flip(want);
        }
        prop_assert_eq!(classify(&permute(&a, pa), &permute(&b, pb)), want);
    }

    #[test]
    fn classify_is_scale_invariant_across_widths(
        a in small_tet(),
        b in small_tet(),
        k in prop::sample::select(vec![3i32, 1 << 13, 1 << 20, (1 << 28) + 1]),
    ) {
        let s = |t: &LatticeTet| t.map(|p| p.map(|c| c * k));
        prop_assert_eq!(classify(&s(&a), &s(&b)), classify(&a, &b));
        prop_assert_eq!(relative_interiors_meet(&s(&a), &s(&b)), relative_interiors_meet(&a, &b));
    }
}

// ---------------------------------------------------------------------------------------
// Meshed voxel bodies (the real use): adjacent bodies touch, overlapping ones interfere.
// ---------------------------------------------------------------------------------------

use crate::common;

/// The closed 4D mesh of a box of voxels `lo..=hi` held for `frames` frames.
fn box_body(lo: [usize; 3], hi: [usize; 3], frames: usize) -> Vec<LatticeTet> {
    let size = [8, 6, 6];
    let inside = |x: usize, y: usize, z: usize| {
        (lo[0]..=hi[0]).contains(&x) && (lo[1]..=hi[1]).contains(&y) && (lo[2]..=hi[2]).contains(&z)
    };
    let frames: Vec<common::TestFrame> = (0..frames)
        .map(|k| common::TestFrame {
            stamp_ns: 1_000 * k as i64,
            encoding: 0,
            data: common::bits_data(size, inside),
        })
        .collect();
    let mesh = common::glued(&common::run(&frames, size, 0.1));
    mesh.tets
        .iter()
        .map(|t| t.map(|i| mesh.vertices[i as usize]))
        .collect()
}

fn relation_counts(a: &[LatticeTet], b: &[LatticeTet]) -> [usize; 6] {
    // Disjoint, Touching, Crossing, coplanar overlap same / opposite, coplanar contact.
    let mut n = [0; 6];
    for ta in a {
        for tb in b {
            let k = match classify(ta, tb) {
                TetPairRelation::Disjoint => 0,
                TetPairRelation::Touching => 1,
                TetPairRelation::Crossing => 2,
                TetPairRelation::Coplanar {
                    overlap_volume_positive: true,
                    same_orientation: true,
                } => 3,
                TetPairRelation::Coplanar {
                    overlap_volume_positive: true,
                    ..
                } => 4,
                TetPairRelation::Coplanar { .. } => 5,
            };
            n[k] += 1;
        }
    }
    n
}

#[test]
fn meshed_voxel_bodies() {
    // Closed 4D meshes (marching hypercubes, caps) of boxes of voxels over 3 frames.
    let a = box_body([1, 1, 1], [2, 2, 2], 3);
    let beside = box_body([3, 1, 1], [4, 2, 2], 3);
    let over = box_body([2, 1, 1], [3, 2, 2], 3);
    let shifted = box_body([2, 2, 2], [3, 3, 3], 3);
    let (n_beside, n_over, n_shifted) = (
        relation_counts(&a, &beside),
        relation_counts(&a, &over),
        relation_counts(&a, &shifted),
    );
    println!("[disjoint, touching, crossing, coplanar same, coplanar opposite, coplanar contact]");
    println!("beside:  {n_beside:?}\nover:    {n_over:?}\nshifted: {n_shifted:?}");
    // Face to face in adjacent voxels: contact only, never interference.
    assert_eq!(n_beside[2], 0);
    assert_eq!(n_beside[3], 0);
    assert!(n_beside[4] > 0);
    // Overlapping bodies show interference: crossings or coplanar same-side overlaps.
    // (Aligned boxes cross only along mesh ridges: there the signal is the coplanar one.)
    assert!(n_over[2] + n_over[3] > 0);
    assert!(n_shifted[2] > 0);
    // Symmetry on whole meshes.
    assert_eq!(relation_counts(&shifted, &a), n_shifted);
}
