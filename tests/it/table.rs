//! The marching-hypercubes table: orientation of every case's tets, and identical
//! triangulation of every shared 3-face of the hypercube from both sides, over all cases.

use chronotope::mesh::table::table;
use chronotope::mesh::table_gen::{corner4, edge4, orient4, P4};
use chronotope::mesh::validate::{canonical_triangle, tet_faces};
use std::collections::HashMap;

fn edge_point(e: u8) -> P4 {
    let (a, b, _) = edge4(usize::from(e));
    let (pa, pb) = (corner4(a), corner4(b));
    [0, 1, 2, 3].map(|k| (pa[k] + pb[k]) / 2)
}

#[test]
fn every_case_tets_face_outward() {
    let t = table();
    for case in 0..=u16::MAX {
        for tet in t.lateral(case) {
            let p = tet.map(edge_point);
            let mut outside = 0;
            for c in 0..16 {
                let s = orient4([&p[0], &p[1], &p[2], &p[3], &corner4(c)]);
                let positive = (case >> c) & 1 == 1;
                // Occupied corners never lie beyond a lateral facet; some free corner does.
                if positive {
                    assert!(
                        s <= 0,
                        "case {case:#06x}: occupied corner {c} outside tet {tet:?}"
                    );
                } else if s > 0 {
                    outside += 1;
                }
            }
            assert!(
                outside > 0,
                "case {case:#06x}: tet {tet:?} has no free corner outside"
            );
        }
    }
}

#[test]
fn uniform_cases_are_empty_and_mixed_cases_are_not() {
    let t = table();
    assert!(t.lateral(0).is_empty());
    assert!(t.lateral(u16::MAX).is_empty());
    for case in 1..u16::MAX {
        assert!(
            !t.lateral(case).is_empty(),
            "case {case:#06x} has no surface"
        );
    }
}

#[test]
fn table_size_is_what_bhaniramka_gives() {
    let t = table();
    let avg = t.lateral_total() as f64 / 65536.0;
    // docs/methods/marching.md#the-case-table: at most 24 tets per case, 12.94 on average
    // for a pulling triangulation.
    assert!(
        t.lateral_max() <= 24,
        "max {} tets per case",
        t.lateral_max()
    );
    assert!((12.0..14.0).contains(&avg), "average {avg}");
}

/// A triangle in a hypercube facet (three points, three coordinates) with its orientation.
type FacetTriangle = ([[i64; 3]; 3], i8);

/// Triangles of a case's lateral tets that lie in the cube facet `x_axis = side`, as
/// coordinate triples within that facet with their induced orientation.
fn facet_triangles(case: u16, axis: usize, side: i64) -> Vec<FacetTriangle> {
    let mut out = Vec::new();
    for tet in table().lateral(case) {
        let p = tet.map(edge_point);
        for (f, s) in tet_faces([0usize, 1, 2, 3]) {
            let pts = f.map(|i| p[i]);
            if pts.iter().all(|q| q[axis] == side) {
                let drop = |q: &P4| {
                    let mut r = [0i64; 3];
                    let mut j = 0;
                    for (k, v) in q.iter().enumerate() {
                        if k != axis {
                            r[j] = *v;
                            j += 1;
                        }
                    }
                    r
                };
                let (key, parity) = canonical_triangle(pts.map(|q| drop(&q)));
                out.push((key, s * parity));
            }
        }
    }
    out.sort();
    out
}

/// The 8 corner bits of a case on the facet `axis = side/2`, in facet-local order.
fn facet_config(case: u16, axis: usize, side: i64) -> u8 {
    let mut cfg = 0u8;
    let mut j = 0;
    for c in 0..16usize {
        if ((c >> axis) & 1) as i64 * 2 == side {
            cfg |= (((case >> c) & 1) as u8) << j;
            j += 1;
        }
    }
    cfg
}

#[test]
fn shared_three_faces_are_triangulated_identically_from_both_sides() {
    // For every facet configuration, the triangulation seen from the cube below (facet at
    // side 2) must equal the one seen from the cube above (side 0) with opposite induced
    // orientation, whatever the other 8 corners are.
    let mut seen: HashMap<(usize, u8), Vec<FacetTriangle>> = HashMap::new();
    for case in 0..=u16::MAX {
        for axis in 0..4 {
            for side in [0i64, 2] {
                let cfg = facet_config(case, axis, side);
                let mut tris = facet_triangles(case, axis, side);
                if side == 2 {
                    // Seen from the other cube, orientation flips.
                    for t in &mut tris {
                        t.1 = -t.1;
                    }
                }
                match seen.get(&(axis, cfg)) {
                    Some(prev) => assert_eq!(
                        prev, &tris,
                        "case {case:#06x}, axis {axis}, side {side}: facet config {cfg:#04x} triangulated differently"
                    ),
                    None => {
                        seen.insert((axis, cfg), tris);
                    }
                }
            }
        }
    }
    // Every one of the 4 x 256 facet configurations occurred.
    assert_eq!(seen.len(), 4 * 256);
}
