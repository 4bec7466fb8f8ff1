//! The 4D AABB tree against brute force: tree-against-tree pairs, segment and ray
//! candidates, rebuilds, empty and single-item trees, degenerate and huge boxes.
//!
//! `cargo test --release --test it bvh:: -- --ignored --nocapture` prints build and traversal
//! times for two meshes of about 1.5 M tets each.

use chronotope::kernel::{
    overlapping_pairs, overlapping_pairs_under, top_pairs, try_overlapping_pairs, Aabb4, Bvh,
    BvhError, LatticePoint, NodePair, TraverseWorkspace,
};
use proptest::prelude::*;
use std::ops::ControlFlow;

// ---------------------------------------------------------------------------------------
// Oracles

fn brute_pairs(a: &[Aabb4], b: &[Aabb4]) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            // Written out, not via `Aabb4::overlaps`.
            let empty = x.is_empty() || y.is_empty();
            if !empty && (0..4).all(|k| x.min[k] <= y.max[k] && y.min[k] <= x.max[k]) {
                out.push((i as u32, j as u32));
            }
        }
    }
    out
}

fn tree_pairs(a: &Bvh, b: &Bvh, ws: &mut TraverseWorkspace) -> Vec<(u32, u32)> {
    let mut out = Vec::new();
    overlapping_pairs(a, b, ws, |i, j| out.push((i, j)));
    sorted_unique(out)
}

/// Sorts, and fails on duplicates.
fn sorted_unique<T: Ord + Copy + std::fmt::Debug>(mut v: Vec<T>) -> Vec<T> {
    v.sort();
    for w in v.windows(2) {
        assert_ne!(w[0], w[1], "reported twice");
    }
    v
}

/// Whether `p + s (q - p)` lies in `b` for some `s` in `[0, 1]` (or `s >= 0` for a ray
/// with `q = p + d`): the feasible set is a closed interval, so if it is not empty its
/// lower end is 0 or one of the slab boundaries; try them all. Exact in i128 for
/// coordinates up to 2^60.
fn oracle_line(b: &Aabb4, p: [i64; 4], d: [i64; 4], ray: bool) -> bool {
    let p = p.map(i128::from);
    let d = d.map(i128::from);
    let mut candidates = vec![(0i128, 1i128)];
    for k in 0..4 {
        if d[k] != 0 {
            for bound in [b.min[k], b.max[k]] {
                let n = i128::from(bound) - p[k];
                candidates.push(if d[k] > 0 { (n, d[k]) } else { (-n, -d[k]) });
            }
        }
    }
    candidates.iter().any(|&(n, m)| {
        n >= 0
            && (ray || n <= m)
            && (0..4).all(|k| {
                let x = p[k] * m + n * d[k];
                i128::from(b.min[k]) * m <= x && x <= i128::from(b.max[k]) * m
            })
    })
}

fn oracle_segment(b: &Aabb4, p: [i64; 4], q: [i64; 4]) -> bool {
    oracle_line(b, p, [0, 1, 2, 3].map(|k| q[k] - p[k]), false)
}

fn tree_segment(t: &Bvh, p: [i64; 4], q: [i64; 4], ws: &mut TraverseWorkspace) -> Vec<u32> {
    let mut out = Vec::new();
    t.segment_candidates(p, q, ws, |i| out.push(i));
    sorted_unique(out)
}

fn brute_segment(boxes: &[Aabb4], p: [i64; 4], q: [i64; 4]) -> Vec<u32> {
    (0..boxes.len() as u32)
        .filter(|&i| oracle_segment(&boxes[i as usize], p, q))
        .collect()
}

// ---------------------------------------------------------------------------------------
// Strategies

/// Boxes on a small lattice (so that touching and coincident boxes are common) with zero
/// extent on some axes about half the time.
fn small_box() -> impl Strategy<Value = Aabb4> {
    let extent = prop_oneof![2 => Just(0i32), 3 => 0i32..5];
    (
        prop::array::uniform4(-8i32..12),
        prop::array::uniform4(extent),
    )
        .prop_map(|(min, e)| Aabb4::new(min, [0, 1, 2, 3].map(|k| min[k] + e[k])))
}

/// Small boxes scaled by 1 or 2^26 (coordinates near ±2^30; scaling by a positive factor
/// keeps the overlap structure) and shifted.
fn boxes(max: usize) -> impl Strategy<Value = Vec<Aabb4>> {
    (
        prop::collection::vec(small_box(), 0..max),
        prop_oneof![Just(1i32), Just(1 << 26)],
        -3i32..3,
    )
        .prop_map(|(v, scale, shift)| {
            v.into_iter()
                .map(|b| {
                    Aabb4::new(
                        b.min.map(|c| (c + shift) * scale),
                        b.max.map(|c| (c + shift) * scale),
                    )
                })
                .collect()
        })
}

/// A segment end point: near the boxes, far (2^40), or very far (up to 2^60).
fn end_point() -> impl Strategy<Value = [i64; 4]> {
    let coord = prop_oneof![
        6 => -14i64..22,
        1 => (-3i64..4).prop_map(|k| k << 40),
        1 => -(1i64 << 60)..(1i64 << 60),
    ];
    prop::array::uniform4(coord)
}

// ---------------------------------------------------------------------------------------
// Properties

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn pairs_match_brute_force(a in boxes(80), b in boxes(80)) {
        let (ta, tb) = (Bvh::from_boxes(&a).unwrap(), Bvh::from_boxes(&b).unwrap());
        let mut ws = TraverseWorkspace::new();
        prop_assert_eq!(tree_pairs(&ta, &tb, &mut ws), brute_pairs(&a, &b));
        // Swapping the trees swaps the pairs.
        let mut swapped: Vec<_> = tree_pairs(&tb, &ta, &mut ws).into_iter().map(|(i, j)| (j, i)).collect();
        swapped.sort();
        prop_assert_eq!(swapped, brute_pairs(&a, &b));
    }

    #[test]
    fn segment_candidates_match_exact_brute_force(
        v in boxes(60),
        segs in prop::collection::vec((end_point(), end_point()), 1..12),
    ) {
        let t = Bvh::from_boxes(&v).unwrap();
        let mut ws = TraverseWorkspace::new();
        for (p, q) in segs {
            let expect = brute_segment(&v, p, q);
            prop_assert_eq!(tree_segment(&t, p, q, &mut ws), expect.clone(), "p {:?} q {:?}", p, q);
            // The segment is symmetric in its end points.
            prop_assert_eq!(tree_segment(&t, q, p, &mut ws), expect);
            for b in &v {
                prop_assert_eq!(b.intersects_segment(p, q), oracle_segment(b, p, q));
            }
        }
    }

    #[test]
    fn ray_candidates_match_exact_brute_force(
        v in boxes(60),
        rays in prop::collection::vec((end_point(), prop::array::uniform4(-3i64..4)), 1..12),
    ) {
        let t = Bvh::from_boxes(&v).unwrap();
        let mut ws = TraverseWorkspace::new();
        for (p, d) in rays {
            let mut got = Vec::new();
            t.ray_candidates(p, d, &mut ws, |i| got.push(i));
            let expect: Vec<u32> = (0..v.len() as u32)
                .filter(|&i| oracle_line(&v[i as usize], p, d, true))
                .collect();
            prop_assert_eq!(sorted_unique(got), expect);
        }
    }

    #[test]
    fn rebuild_with_fewer_and_more_items_stays_correct(
        sets in prop::collection::vec(boxes(120), 1..6),
        other in boxes(40),
        (p, q) in (end_point(), end_point()),
    ) {
        let mut t = Bvh::new();
        let to = Bvh::from_boxes(&other).unwrap();
        let mut ws = TraverseWorkspace::new();
        for v in &sets {
            t.build(v).unwrap();
            prop_assert_eq!(t.len(), v.len());
            prop_assert_eq!(t.aabb(), v.iter().fold(Aabb4::EMPTY, |a, b| a.union(b)));
            prop_assert_eq!(tree_pairs(&t, &to, &mut ws), brute_pairs(v, &other));
            prop_assert_eq!(tree_segment(&t, p, q, &mut ws), brute_segment(v, p, q));
        }
    }

    #[test]
    fn an_affine_image_of_a_tree_answers_for_its_boxes_images(
        v in boxes(100),
        matrix in prop::array::uniform4(prop::array::uniform4(-6i64..7)),
        shift in prop::array::uniform4(-50i64..50),
        other in boxes(40),
        (p, q) in (end_point(), end_point()),
    ) {
        // Each box replaced by the box of its image: pairs and segments are those of the
        // items' images (where every image fits i32).
        let t = Bvh::from_boxes(&v).unwrap();
        let images: Option<Vec<Aabb4>> = v.iter().map(|b| b.affine_image(&matrix, &shift)).collect();
        let mut m = Bvh::new();
        let mapped = m.map_affine_from(&t, matrix, shift);
        if let (Some(images), true) = (images, mapped) {
            let to = Bvh::from_boxes(&other).unwrap();
            let mut ws = TraverseWorkspace::new();
            prop_assert_eq!(m.len(), t.len());
            prop_assert!(m.aabb().contains(&images.iter().fold(Aabb4::EMPTY, |a, b| a.union(b))));
            prop_assert_eq!(tree_pairs(&m, &to, &mut ws), brute_pairs(&images, &other));
            prop_assert_eq!(tree_segment(&m, p, q, &mut ws), brute_segment(&images, p, q));
        }
    }

    #[test]
    fn mapped_segment_candidates_are_those_of_the_mapped_boxes(
        v in boxes(60),
        n in 1i64..40,
        shift in prop::array::uniform4(-50i64..50),
        segs in prop::collection::vec((end_point(), end_point()), 1..8),
    ) {
        // The boxes mapped by x -> n x + shift as the walk reaches them, against the mapped
        // boxes themselves (those that do not fit i32 are taken as met).
        let t = Bvh::from_boxes(&v).unwrap();
        let map = |c: i32, k: usize| i64::from(c) * n + shift[k];
        let mapped: Vec<Option<Aabb4>> = v
            .iter()
            .map(|b| {
                if b.is_empty() {
                    return Some(Aabb4::EMPTY);
                }
                let lo = [0, 1, 2, 3].map(|k| i32::try_from(map(b.min[k], k)).ok());
                let hi = [0, 1, 2, 3].map(|k| i32::try_from(map(b.max[k], k)).ok());
                if lo.iter().chain(&hi).any(Option::is_none) {
                    return None;
                }
                Some(Aabb4::new(lo.map(Option::unwrap), hi.map(Option::unwrap)))
            })
            .collect();
        let mut ws = TraverseWorkspace::new();
        for (p, q) in segs {
            let expect: Vec<u32> = (0..v.len() as u32)
                .filter(|&i| match &mapped[i as usize] {
                    Some(b) => !b.is_empty() && oracle_segment(b, p, q),
                    None => true,
                })
                .collect();
            let mut got = Vec::new();
            t.segment_candidates_mapped(p, q, [n; 4], shift, &mut ws, |i| got.push(i));
            prop_assert_eq!(sorted_unique(got), expect);
        }
    }

    #[test]
    fn top_pairs_split_the_walk_exactly(a in boxes(100), b in boxes(100), depth in 0u32..8) {
        let (ta, tb) = (Bvh::from_boxes(&a).unwrap(), Bvh::from_boxes(&b).unwrap());
        let mut ws = TraverseWorkspace::new();
        let mut tops = Vec::new();
        top_pairs(&ta, &tb, depth, &mut tops);
        prop_assert!(tops.len() <= 1 << (2 * depth));
        let mut all = Vec::new();
        for &np in &tops {
            let _ = overlapping_pairs_under(&ta, &tb, np, &mut ws, |i, j| {
                all.push((i, j));
                ControlFlow::<()>::Continue(())
            });
        }
        prop_assert_eq!(sorted_unique(all), brute_pairs(&a, &b));
    }

    #[test]
    fn tet_meshes_match_brute_force(
        base in prop::array::uniform4(-(1i32 << 30)..(1i32 << 30)),
        verts_a in prop::collection::vec(prop::array::uniform4(0i32..10), 4..40),
        verts_b in prop::collection::vec(prop::array::uniform4(0i32..10), 4..40),
        tets_a in prop::collection::vec(prop::array::uniform4(0u32..1000), 0..60),
        tets_b in prop::collection::vec(prop::array::uniform4(0u32..1000), 0..60),
    ) {
        let shift = |v: Vec<LatticePoint>| -> Vec<LatticePoint> {
            v.into_iter().map(|p| [0, 1, 2, 3].map(|k| base[k] + p[k])).collect()
        };
        let (va, vb) = (shift(verts_a), shift(verts_b));
        let fix = |t: Vec<[u32; 4]>, n: usize| -> Vec<[u32; 4]> {
            t.into_iter().map(|t| t.map(|i| i % n as u32)).collect()
        };
        let (ta, tb) = (fix(tets_a, va.len()), fix(tets_b, vb.len()));
        let tet_box = |v: &[LatticePoint], t: &[u32; 4]| {
            Aabb4::from_points(&t.map(|i| v[i as usize]))
        };
        let ba: Vec<Aabb4> = ta.iter().map(|t| tet_box(&va, t)).collect();
        let bb: Vec<Aabb4> = tb.iter().map(|t| tet_box(&vb, t)).collect();
        let (xa, xb) = (Bvh::from_tets(&va, &ta).unwrap(), Bvh::from_tets(&vb, &tb).unwrap());
        let mut ws = TraverseWorkspace::new();
        prop_assert_eq!(tree_pairs(&xa, &xb, &mut ws), brute_pairs(&ba, &bb));
        // A segment from inside to a far point outside the mesh's box, as the inside
        // test does.
        let p = va[0].map(i64::from);
        let q = [0, 1, 2, 3].map(|k| p[k] + [1 << 33, 7, -3, 1][k]);
        prop_assert_eq!(tree_segment(&xa, p, q, &mut ws), brute_segment(&ba, p, q));
    }
}

// ---------------------------------------------------------------------------------------
// Cases

#[test]
fn empty_tree() {
    let t = Bvh::from_boxes(&[]).unwrap();
    assert!(t.is_empty());
    assert_eq!(t.len(), 0);
    assert_eq!(t.node_count(), 0);
    assert_eq!(t.depth(), 0);
    assert_eq!(t.aabb(), Aabb4::EMPTY);
    assert!(t.aabb().is_empty());
    let one = Bvh::from_boxes(&[Aabb4::new([i32::MIN; 4], [i32::MAX; 4])]).unwrap();
    let mut ws = TraverseWorkspace::new();
    assert!(tree_pairs(&t, &one, &mut ws).is_empty());
    assert!(tree_pairs(&one, &t, &mut ws).is_empty());
    assert!(tree_pairs(&t, &t, &mut ws).is_empty());
    assert!(tree_segment(&t, [i64::MIN; 4], [i64::MAX; 4], &mut ws).is_empty());
    let mut tops = vec![];
    top_pairs(&t, &one, 5, &mut tops);
    assert!(tops.is_empty());
    // An empty tree from tets, and rebuilding to empty.
    assert!(Bvh::from_tets(&[], &[]).unwrap().is_empty());
    let mut r = Bvh::from_boxes(&[Aabb4::new([0; 4], [1; 4])]).unwrap();
    r.build(&[]).unwrap();
    assert!(r.is_empty() && r.aabb().is_empty());
    assert!(tree_pairs(&r, &one, &mut ws).is_empty());
}

#[test]
fn single_item_tree() {
    let b = Aabb4::new([0, 0, 0, 5], [3, 3, 3, 5]); // a cap box: zero extent in t
    let t = Bvh::from_boxes(&[b]).unwrap();
    assert_eq!((t.len(), t.node_count(), t.depth()), (1, 1, 1));
    assert_eq!(t.aabb(), b);
    let mut ws = TraverseWorkspace::new();
    assert_eq!(tree_pairs(&t, &t, &mut ws), [(0, 0)]);
    // Touching only at t = 5.
    let u = Bvh::from_boxes(&[Aabb4::new([3, 3, 3, 5], [9, 9, 9, 9])]).unwrap();
    assert_eq!(tree_pairs(&t, &u, &mut ws), [(0, 0)]);
    let v = Bvh::from_boxes(&[Aabb4::new([0, 0, 0, 6], [3, 3, 3, 9])]).unwrap();
    assert!(tree_pairs(&t, &v, &mut ws).is_empty());
    // Segments through the t = 5 hyperplane, grazing, and missing.
    assert_eq!(
        tree_segment(&t, [1, 1, 1, 0], [1, 1, 1, 1 << 50], &mut ws),
        [0]
    );
    assert_eq!(tree_segment(&t, [3, 0, 0, 5], [3, 3, 0, 5], &mut ws), [0]);
    assert!(tree_segment(&t, [1, 1, 1, 6], [1, 1, 1, 1 << 50], &mut ws).is_empty());
}

#[test]
fn degenerate_boxes_many_coincident() {
    // Many identical points (all centres coincide: the build halves), identical cap boxes,
    // and a flat layer t = 0.
    let mut v = vec![Aabb4::from_point([4, 4, 4, 0]); 50];
    v.extend(std::iter::repeat_n(
        Aabb4::new([0, 0, 0, 0], [2, 2, 2, 0]),
        30,
    ));
    for i in 0..40 {
        v.push(Aabb4::new([i, 2 * i, 0, 0], [i + 1, 2 * i, 1, 0]));
    }
    let t = Bvh::from_boxes(&v).unwrap();
    let mut ws = TraverseWorkspace::new();
    assert_eq!(tree_pairs(&t, &t, &mut ws), brute_pairs(&v, &v));
    let (p, q) = ([4, 4, 4, -10], [4, 4, 4, 10]);
    assert_eq!(tree_segment(&t, p, q, &mut ws), brute_segment(&v, p, q));
    assert!(t.depth() <= 12, "depth {}", t.depth());
}

#[test]
fn clusters_far_apart_get_a_good_tree() {
    // Two dense clusters at opposite ends of the i32 range: their Morton codes tie at the
    // top level and must be re-quantised, otherwise the tree degenerates.
    let mut v = Vec::new();
    for c in [-(1i32 << 30), 1 << 30] {
        for i in 0..2000i32 {
            let p = [c + i % 13, c + (i / 13) % 11, c + i % 7, c + i / 143];
            v.push(Aabb4::new(p, p.map(|x| x + 1)));
        }
    }
    v.push(Aabb4::new([i32::MIN; 4], [i32::MIN + 1; 4]));
    v.push(Aabb4::new([i32::MAX - 1; 4], [i32::MAX; 4]));
    // Shuffle, so that item order says nothing about position.
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    for i in (1..v.len()).rev() {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1);
        v.swap(i, (state >> 33) as usize % (i + 1));
    }
    let t = Bvh::from_boxes(&v).unwrap();
    assert!(t.depth() <= 24, "depth {}", t.depth());
    // Tree quality: a point in a cluster meets few leaves (expanding the walk against a
    // one-leaf tree to the bottom gives exactly the leaves whose box holds the point).
    let c = 1 << 30;
    let point = Bvh::from_boxes(&[Aabb4::from_point([c + 6, c + 5, c + 3, c + 7])]).unwrap();
    let mut leaves = Vec::new();
    top_pairs(&t, &point, 64, &mut leaves);
    assert!(leaves.len() <= 12, "{} leaves hold the point", leaves.len());
    let mut ws = TraverseWorkspace::new();
    let probe: Vec<Aabb4> = (0..50)
        .map(|i| {
            let c = if i % 2 == 0 { -(1i32 << 30) } else { 1 << 30 };
            Aabb4::new(
                [c + i % 9, c + 3, c, c + i % 12],
                [c + i % 9 + 2, c + 4, c + 6, c + i % 12],
            )
        })
        .chain([
            Aabb4::new([i32::MAX; 4], [i32::MAX; 4]),
            Aabb4::new([i32::MIN; 4], [i32::MAX; 4]),
        ])
        .collect();
    let tp = Bvh::from_boxes(&probe).unwrap();
    assert_eq!(tree_pairs(&t, &tp, &mut ws), brute_pairs(&v, &probe));
}

#[test]
fn extreme_coordinates() {
    let full = Aabb4::new([i32::MIN; 4], [i32::MAX; 4]);
    let corner_hi = Aabb4::from_point([i32::MAX; 4]);
    let corner_lo = Aabb4::from_point([i32::MIN; 4]);
    let v = [
        full,
        corner_hi,
        corner_lo,
        Aabb4::new([0; 4], [0, 0, 0, i32::MAX]),
    ];
    let t = Bvh::from_boxes(&v).unwrap();
    assert_eq!(t.aabb(), full);
    let mut ws = TraverseWorkspace::new();
    assert_eq!(tree_pairs(&t, &t, &mut ws), brute_pairs(&v, &v));
    // End points at the ends of i64: numerators and denominators near 2^64.
    let (lo, hi) = (i64::MIN, i64::MAX);
    assert_eq!(tree_segment(&t, [lo; 4], [hi; 4], &mut ws), [0, 1, 2, 3]);
    assert_eq!(
        tree_segment(&t, [lo, 0, 0, 0], [hi, 0, 0, 0], &mut ws),
        [0, 3]
    );
    // x = y = MIN + s (2^64 - 1) is exactly 0 at s = 2^63 / (2^64 - 1).
    assert_eq!(
        tree_segment(&t, [lo, lo, 0, 0], [hi, hi, 0, 0], &mut ws),
        [0, 3]
    );
    // y reaches i32::MIN only for s > 1 - 2^-32, when x is far above i32::MAX.
    assert_eq!(
        tree_segment(&t, [lo, lo, 0, 0], [hi, 0, 0, 0], &mut ws),
        Vec::<u32>::new()
    );
    assert_eq!(
        tree_segment(&t, [hi, lo, hi, lo], [hi, hi, hi, hi], &mut ws),
        Vec::<u32>::new()
    );
    // Through the far corner and beyond: passes (MAX, MAX, MAX, MAX) at s = 1/2 exactly.
    let m = i64::from(i32::MAX);
    assert_eq!(tree_segment(&t, [m - 5; 4], [m + 5; 4], &mut ws), [0, 1]);
    // A near miss on the far corner: off by one in y at the crossing.
    assert!(
        !corner_hi.intersects_segment([m - 5, m - 6, m - 5, m - 5], [m + 5, m + 4, m + 5, m + 5])
    );
    assert!(corner_hi.intersects_segment([m - hi / 4, m, m, m], [m + hi / 2, m, m, m]));
    assert!(!corner_hi.intersects_segment([m - hi / 4, m, m, m], [m + hi / 2, m + 1, m, m]));
    // Rays with the largest directions.
    assert!(corner_lo.intersects_ray([0; 4], [lo; 4]));
    assert!(!corner_lo.intersects_ray([0; 4], [hi; 4]));
    assert!(corner_hi.intersects_ray([0; 4], [hi; 4]));
    assert!(corner_hi.intersects_ray([m; 4], [0; 4])); // point query
    assert!(!corner_hi.intersects_ray([m - 1, m, m, m], [0; 4]));
}

#[test]
fn empty_boxes_are_items_that_overlap_nothing() {
    let v = [
        Aabb4::new([0; 4], [5; 4]),
        Aabb4::EMPTY,
        Aabb4::new([0, 0, 0, 5], [5, 5, 5, 3]), // inverted in t only
        Aabb4::new([1; 4], [2; 4]),
    ];
    let t = Bvh::from_boxes(&v).unwrap();
    assert_eq!(t.len(), 4);
    assert_eq!(t.aabb(), Aabb4::new([0; 4], [5; 4]));
    let mut ws = TraverseWorkspace::new();
    assert_eq!(
        tree_pairs(&t, &t, &mut ws),
        [(0, 0), (0, 3), (3, 0), (3, 3)]
    );
    assert_eq!(tree_segment(&t, [-9; 4], [9; 4], &mut ws), [0, 3]);
    let all_empty = Bvh::from_boxes(&[Aabb4::EMPTY; 9]).unwrap();
    assert!(all_empty.aabb().is_empty());
    assert!(tree_pairs(&all_empty, &t, &mut ws).is_empty());
    assert!(tree_segment(&all_empty, [i64::MIN; 4], [i64::MAX; 4], &mut ws).is_empty());
    assert!(!Aabb4::EMPTY.overlaps(&Aabb4::new([i32::MIN; 4], [i32::MAX; 4])));
}

#[test]
fn bad_vertex_index_is_an_error() {
    let v: Vec<LatticePoint> = vec![[0; 4], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]];
    let mut t = Bvh::from_tets(&v, &[[0, 1, 2, 3]]).unwrap();
    assert_eq!(t.len(), 1);
    let err = t.build_tets(&v, &[[0, 1, 2, 3], [0, 1, 2, 4]]).unwrap_err();
    assert_eq!(
        err,
        BvhError::VertexOutOfRange {
            tet: 1,
            vertex: 4,
            vertices: 4
        }
    );
    assert!(err.to_string().contains("vertex 4"));
    assert!(t.is_empty(), "a failed build leaves an empty tree");
    assert!(Bvh::from_tets(&v, &[[u32::MAX, 0, 0, 0]]).is_err());
    assert_eq!(Bvh::MAX_ITEMS, 1 << 31);
}

#[test]
fn early_exit_and_node_pairs() {
    let v: Vec<Aabb4> = (0..100).map(|i| Aabb4::new([i; 4], [i + 1; 4])).collect();
    let t = Bvh::from_boxes(&v).unwrap();
    let mut ws = TraverseWorkspace::new();
    let mut calls = 0;
    let r = try_overlapping_pairs(&t, &t, &mut ws, |i, j| {
        calls += 1;
        if calls == 3 {
            ControlFlow::Break((i, j))
        } else {
            ControlFlow::Continue(())
        }
    });
    assert!(matches!(r, ControlFlow::Break(_)));
    assert_eq!(calls, 3);
    let r = t.try_segment_candidates([0; 4], [200; 4], &mut ws, |i| {
        if i == 50 {
            ControlFlow::Break(i)
        } else {
            ControlFlow::Continue(())
        }
    });
    assert_eq!(r, ControlFlow::Break(50));
    // Node pairs from another, larger tree pair are ignored or clipped, never panic.
    let big = Bvh::from_boxes(&vec![Aabb4::new([0; 4], [1; 4]); 5000]).unwrap();
    let mut tops: Vec<NodePair> = Vec::new();
    top_pairs(&big, &big, 10, &mut tops);
    assert!(tops.iter().any(|p| p.a() as usize >= t.node_count()));
    for &np in &tops {
        let _ =
            overlapping_pairs_under(&t, &t, np, &mut ws, |_, _| ControlFlow::<()>::Continue(()));
    }
}

// ---------------------------------------------------------------------------------------
// Timing (not a behaviour test: run by hand in release)

/// Two bodies of the four-spheres scene meshed in full (all slabs concatenated).
fn scene_meshes(grid: u32, frames: u32) -> Vec<(Vec<LatticePoint>, Vec<[u32; 4]>)> {
        use chronotope::mesh::{Mesher, MesherOptions};
    use chronotope::msg::VoxelGrid;
    use chronotope::scene::{build_scene, Rasterizer, SceneName, SceneOptions};
    let opts = SceneOptions::for_scene(SceneName::FourSpheres)
        .grid(grid)
        .frames(frames);
    let scene = build_scene(SceneName::FourSpheres, &opts).unwrap();
    let mut raster = Rasterizer::new();
    (0..2)
        .map(|body| {
            let mut m = Mesher::new(MesherOptions::default()).unwrap();
            let (mut verts, mut tets) = (Vec::new(), Vec::new());
            for k in 0..scene.frame_count() {
                let mut g = VoxelGrid::default();
                scene.write_frame(body, k, &mut raster, &mut g).unwrap();
                if let Some(slab) = m.push(&g.frame_ref()).unwrap() {
                    let off = verts.len() as u32;
                    verts.extend_from_slice(&slab.mesh.vertices);
                    tets.extend(slab.mesh.tets.iter().map(|t| t.map(|i| i + off)));
                }
            }
            (verts, tets)
        })
        .collect()
}

/// Small random simplices (edges up to 3) around a 3-sphere of radius 100 in a 256^4 box,
/// like a surface mesh.
fn synthetic_mesh(n: usize, seed: u64, centre: [f64; 4]) -> (Vec<LatticePoint>, Vec<[u32; 4]>) {
    let mut s = seed;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    let mut verts = Vec::with_capacity(4 * n);
    let mut tets = Vec::with_capacity(n);
    for t in 0..n {
        let g: [f64; 4] = std::array::from_fn(|_| (next() % 20001) as f64 / 10000.0 - 1.0);
        let r = g.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-9);
        let base: LatticePoint = std::array::from_fn(|k| (centre[k] + 100.0 * g[k] / r) as i32);
        for _ in 0..4 {
            verts.push(std::array::from_fn(|k| base[k] + (next() % 4) as i32));
        }
        let i = 4 * t as u32;
        tets.push([i, i + 1, i + 2, i + 3]);
    }
    (verts, tets)
}

fn time_pair(
    label: &str,
    a: &(Vec<LatticePoint>, Vec<[u32; 4]>),
    b: &(Vec<LatticePoint>, Vec<[u32; 4]>),
) {
    use std::time::Instant;
    let (mut ta, mut tb) = (Bvh::new(), Bvh::new());
    let mut ws = TraverseWorkspace::new();
    let mut best = [f64::MAX; 4];
    let mut pairs = 0u64;
    for _ in 0..5 {
        let t0 = Instant::now();
        ta.build_tets(&a.0, &a.1).unwrap();
        let t1 = Instant::now();
        tb.build_tets(&b.0, &b.1).unwrap();
        let t2 = Instant::now();
        pairs = 0;
        overlapping_pairs(&ta, &tb, &mut ws, |_, _| pairs += 1);
        let t3 = Instant::now();
        // 1000 segments from inside points to a far point (the inside test).
        let far = [1i64 << 40, 3 << 38, 5 << 37, 7];
        let mut hits = 0u64;
        for i in (0..a.1.len()).step_by(a.1.len().div_ceil(1000).max(1)) {
            let p = a.0[a.1[i][0] as usize].map(i64::from);
            tb.segment_candidates(p, far, &mut ws, |_| hits += 1);
        }
        let t4 = Instant::now();
        let d = [t1 - t0, t2 - t1, t3 - t2, t4 - t3].map(|d| d.as_secs_f64() * 1e3);
        for k in 0..4 {
            best[k] = best[k].min(d[k]);
        }
        std::hint::black_box(hits);
    }
    println!(
        "{label}: {} + {} tets, nodes {} / {}, depth {} / {}; best of 5: build A {:.1} ms, build B {:.1} ms, \
         overlapping_pairs {:.1} ms ({pairs} pairs), 1000 segments {:.2} ms",
        a.1.len(),
        b.1.len(),
        ta.node_count(),
        tb.node_count(),
        ta.depth(),
        tb.depth(),
        best[0],
        best[1],
        best[2],
        best[3],
    );
}

#[test]
#[ignore = "timing: run with --release --ignored --nocapture"]
fn timing_build_and_traverse() {
    let n = 1_500_000;
    let a = synthetic_mesh(n, 0x1234_5678_9ABC_DEF1, [128.0; 4]);
    let b = synthetic_mesh(n, 0x0FED_CBA9_8765_4321, [160.0, 128.0, 128.0, 128.0]);
    time_pair("synthetic 3-spheres in 256^4", &a, &b);
    let m = scene_meshes(96, 65);
    time_pair("four-spheres 96^3 x 65, bodies a and b", &m[0], &m[1]);
}
