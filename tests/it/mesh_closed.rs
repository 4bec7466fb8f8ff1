//! Closedness and orientation of 4D meshes on random grids, in both encodings; streaming
//! validation agrees with explicit validation; slices are closed.

use crate::common;

use chronotope::mesh::slice::{slice_mesh, PlaneValue, Slicer};
use chronotope::mesh::validate::{check_closed, hypervolume24, pair_faces};
use chronotope::mesh::{DecodeOptions, FrameRef, OccupancyGrid};
use common::*;
use proptest::prelude::*;

fn random_frames(size: [u32; 3], frames: usize, encoding: u8, seed_bits: &[u8]) -> Vec<TestFrame> {
    let n = (size[0] * size[1] * size[2]) as usize;
    (0..frames)
        .map(|k| {
            let v = |x: usize, y: usize, z: usize| {
                let i = x + size[0] as usize * (y + size[1] as usize * z);
                seed_bits[(k * n + i) % seed_bits.len()]
            };
            let data = if encoding == 0 {
                bits_data(size, |x, y, z| v(x, y, z) % 2 == 1)
            } else {
                // Mix of exact iso hits, extremes, unknown and anything between.
                percent_data(size, |x, y, z| match v(x, y, z) % 7 {
                    0 => 50,
                    1 => 0,
                    2 => 100,
                    3 => 255,
                    _ => v(x, y, z) % 101,
                })
            };
            TestFrame {
                stamp_ns: 1_000 + 37 * k as i64 * (k as i64 + 3),
                encoding,
                data,
            }
        })
        .collect()
}

fn grids(frames: &[TestFrame], size: [u32; 3]) -> Vec<OccupancyGrid> {
    frames
        .iter()
        .map(|f| {
            let r: FrameRef<'_> = frame_ref(f, size, 0.1);
            OccupancyGrid::decode(&r, &DecodeOptions::default()).unwrap()
        })
        .collect()
}

fn check_run(frames: &[TestFrame], size: [u32; 3]) {
    let r = run(frames, size, 0.1);
    let g = glued(&r);
    let report = check_closed(&g);
    assert!(report.is_closed(), "glued mesh not closed: {report:?}");
    // Streaming validation saw the same mesh.
    assert!(
        r.stats.closed.is_closed(),
        "stream validation: {:?}",
        r.stats.closed
    );
    assert_eq!(r.stats.tets, g.tets.len() as u64);
    assert_eq!(r.stats.vertices, g.vertices.len() as u64);
    // Every slab is closed on its own with its two caps, and hypervolumes add up.
    let gr = grids(frames, size);
    let mut sum24 = 0i128;
    for k in 0..r.slabs.len() {
        let m = closed_slab(&r, k, &gr);
        let rep = check_closed(&m);
        assert!(rep.is_closed(), "slab {k} not closed: {rep:?}");
        let v = hypervolume24(&m);
        assert!(v >= 0, "slab {k} negative hypervolume {v}");
        sum24 += v;
    }
    // Lattice hypervolume of the glued mesh equals the per-slab sum and the streamed sum.
    assert_eq!(hypervolume24(&g), sum24);
    assert!(
        (r.stats.hypervolume_lattice - sum24 as f64 / 24.0).abs() <= 1e-6 * (1.0 + sum24 as f64)
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, .. ProptestConfig::default() })]

    #[test]
    fn random_binary_grids_mesh_closed(
        sx in 1u32..6, sy in 1u32..6, sz in 1u32..5, frames in 2usize..5,
        bits in proptest::collection::vec(any::<u8>(), 64..512),
    ) {
        let size = [sx, sy, sz];
        check_run(&random_frames(size, frames, 0, &bits), size);
    }

    #[test]
    fn random_percent_grids_mesh_closed(
        sx in 1u32..6, sy in 1u32..5, sz in 1u32..5, frames in 2usize..4,
        bits in proptest::collection::vec(any::<u8>(), 64..512),
    ) {
        let size = [sx, sy, sz];
        check_run(&random_frames(size, frames, 1, &bits), size);
    }

    #[test]
    fn slices_of_random_meshes_are_closed(
        sx in 2u32..6, sy in 2u32..6, sz in 2u32..5,
        bits in proptest::collection::vec(any::<u8>(), 64..512),
        axis in 0usize..4, num in 0i64..24, den in 1i64..5,
        encoding in 0u8..2,
    ) {
        let size = [sx, sy, sz];
        let frames = random_frames(size, 3, encoding, &bits);
        let r = run(&frames, size, 0.1);
        let g = glued(&r);
        let num = num * if encoding == 0 { 1 } else { 16 };
        let s = slice_mesh(&[&g], axis, PlaneValue { num, den });
        let generic = num % den != 0;
        if generic {
            // No vertex on the plane: a closed 2-manifold.
            let rep = check_closed_tri(&s.triangles);
            prop_assert!(rep.is_closed(), "slice axis {} at {}/{} not closed: {:?}", axis, num, den, rep);
        }
        // Always a closed oriented surface: every edge as often one way as the other.
        prop_assert!(edges_balanced(&s.triangles), "slice axis {} at {}/{} has boundary", axis, num, den);
    }
}

/// Every edge used as often in one direction as in the other.
fn edges_balanced(tris: &[[u32; 3]]) -> bool {
    let mut sum: std::collections::HashMap<(u32, u32), i32> = std::collections::HashMap::new();
    for t in tris {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *sum.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
        }
    }
    sum.values().all(|&v| v == 0)
}

/// Closedness of a triangle mesh: every edge used by exactly two triangles in opposite
/// directions.
pub fn check_closed_tri(tris: &[[u32; 3]]) -> chronotope::mesh::validate::ClosedReport {
    let mut edges = Vec::new();
    for t in tris {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            edges.push(if a < b { ((a, b), 1i8) } else { ((b, a), -1i8) });
        }
    }
    pair_faces(edges)
}

#[test]
fn slice_at_a_frame_time_reproduces_that_frame() {
    let size = [6, 5, 4];
    let bits: Vec<u8> = (0..997u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    for encoding in [0u8, 1] {
        // Frames 2 and 3 repeat frame 1: the body rests for two periods, and the mesher
        // marches the first (slab 1) and moves it in time for the second (slab 2).
        let mut frames = random_frames(size, 5, encoding, &bits);
        for _ in 0..2 {
            let again = TestFrame {
                stamp_ns: 0,
                encoding,
                data: frames[1].data.clone(),
            };
            frames.insert(2, again);
        }
        for (j, f) in frames.iter_mut().enumerate() {
            f.stamp_ns = 1_000 + 37 * j as i64 * (j as i64 + 3);
        }
        let r = run(&frames, size, 0.1);
        let g = glued(&r);
        let gr = grids(&frames, size);
        let scale = r.slabs[0].geometry.scale;
        let moved: Vec<[i32; 4]> = r.slabs[1]
            .mesh
            .vertices
            .iter()
            .map(|p| [p[0], p[1], p[2], p[3] + scale])
            .collect();
        assert!(!moved.is_empty() && r.slabs[2].mesh.vertices == moved);
        assert_eq!(
            r.slabs[2].mesh.tets, r.slabs[1].mesh.tets,
            "slab 2 is slab 1 a period later"
        );
        for (k, grid) in gr.iter().enumerate() {
            let plane = PlaneValue::lattice(i64::from(scale) * k as i64);
            let s = slice_mesh(&[&g], 3, plane);
            // The frame's surface: boundary faces of its cap.
            let mut cap = chronotope::mesh::TetMesh::default();
            let at = chronotope::mesh::SlabPlacement {
                scale,
                frame: k as i64,
                iso: 50,
            };
            chronotope::mesh::march::march_cap(
                chronotope::mesh::table::table(),
                grid,
                at,
                chronotope::mesh::CapSide::High,
                usize::MAX,
                &mut cap,
            );
            let mut want = boundary_triangles(&cap);
            want.sort();
            assert_eq!(sorted_triangles(&s), want, "encoding {encoding}, frame {k}");
            // What the markers draw of a slab: the slab alone, sliced at its later frame,
            // gives that frame too (marched or moved in time).
            if k > 0 {
                let slab = &r.slabs[k - 1];
                assert_eq!(slab.index as usize, k - 1);
                let mut slicer = Slicer::new(3, plane);
                slicer.add(&slab.mesh);
                let alone = sorted_triangles(&slicer.finish());
                assert_eq!(alone, want, "encoding {encoding}, slab {} alone", k - 1);
            }
        }
    }
}

/// A slice's triangles by their corners, each rotated by [`canonical_rot`], sorted.
fn sorted_triangles(s: &chronotope::mesh::slice::TriMesh) -> Vec<[[i64; 3]; 3]> {
    let mut t: Vec<[[i64; 3]; 3]> = s
        .triangles
        .iter()
        .map(|t| canonical_rot(t.map(|v| s.vertices[v as usize].map(|c| c as i64))))
        .collect();
    t.sort();
    t
}

/// Rotates a triangle so its smallest point is first (keeps orientation).
fn canonical_rot(t: [[i64; 3]; 3]) -> [[i64; 3]; 3] {
    let k = (0..3).min_by_key(|&i| t[i]).unwrap();
    [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
}

/// Boundary triangles of a cap (unpaired faces), oriented outward of the 3D solid.
fn boundary_triangles(cap: &chronotope::mesh::TetMesh) -> Vec<[[i64; 3]; 3]> {
    use chronotope::mesh::validate::{canonical_triangle, tet_faces};
    use std::collections::HashMap;
    let mut count: HashMap<[u32; 3], (i32, [u32; 3])> = HashMap::new();
    for t in &cap.tets {
        for (f, s) in tet_faces(*t) {
            let (k, _) = canonical_triangle(f);
            let e = count.entry(k).or_insert((0, f));
            e.0 += 1;
            // High caps are oriented with positive 3D volume: their induced boundary
            // orientation is the outward one of the 3D solid for s = +1 faces.
            if s < 0 {
                e.1 = [f[0], f[2], f[1]];
            } else {
                e.1 = f;
            }
        }
    }
    count
        .values()
        .filter(|(n, _)| *n == 1)
        .map(|(_, f)| {
            canonical_rot(f.map(|v| {
                let p = cap.vertices[v as usize];
                [i64::from(p[0]), i64::from(p[1]), i64::from(p[2])]
            }))
        })
        .collect()
}

#[test]
fn streaming_validation_catches_damaged_meshes() {
    use chronotope::mesh::stats::StatsAccumulator;
    let size = [6, 5, 4];
    let bits: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 11) as u8)
        .collect();
    let frames = random_frames(size, 4, 0, &bits);
    let r = run(&frames, size, 0.1);
    assert!(r.stats.closed.is_closed());
    type Damage = fn(&mut chronotope::mesh::TetMesh);
    let damages: [(&str, Damage); 3] = [
        ("dropped tet", |m| {
            m.tets.pop();
        }),
        ("flipped tet", |m| {
            let t = &mut m.tets[0];
            t.swap(2, 3);
        }),
        ("duplicated tet", |m| {
            let t = m.tets[0];
            m.tets.push(t);
        }),
    ];
    for (what, damage) in damages {
        for k in 0..r.slabs.len() {
            let mut acc = StatsAccumulator::new();
            for (i, s) in r.slabs.iter().enumerate() {
                let mut s = s.clone();
                if i == k {
                    damage(&mut s.mesh);
                }
                acc.add_slab(&s, r.first_cap.as_ref());
            }
            let st = acc.finish(
                4,
                r.first_cap.as_ref().map(|c| (c.tets.len() as u64, 0)),
                r.last_cap.as_ref().map(|c| (c, 0)),
            );
            assert!(
                !st.closed.is_closed(),
                "{what} in slab {k} not detected: {:?}",
                st.closed
            );
        }
    }
}

#[test]
fn damage_only_the_time_planes_can_see_is_caught() {
    use chronotope::mesh::stats::StatsAccumulator;
    let size = [6, 5, 4];
    let bits: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 9) as u8)
        .collect();
    let frames = random_frames(size, 4, 1, &bits);
    let r = run(&frames, size, 0.1);
    assert!(r.stats.closed.is_closed());
    // Without the last cap the upper plane of the last slab stays open.
    let mut acc = StatsAccumulator::new();
    for s in &r.slabs {
        acc.add_slab(s, r.first_cap.as_ref());
    }
    assert!(!acc
        .finish(
            4,
            r.first_cap.as_ref().map(|c| (c.tets.len() as u64, 0)),
            None
        )
        .closed
        .is_closed());
    // A vertex of the upper plane moved within the plane: pairing inside the slab still
    // holds, only the plane matching can tell.
    let k = r.slabs.len() - 2;
    let mut moved = r.slabs.clone();
    let t_hi = moved[k].t_hi();
    let v = moved[k]
        .mesh
        .vertices
        .iter()
        .position(|p| p[3] == t_hi)
        .expect("a vertex on the upper plane");
    moved[k].mesh.vertices[v][0] += 1;
    let mut acc = StatsAccumulator::new();
    for s in &moved {
        acc.add_slab(s, r.first_cap.as_ref());
    }
    let st = acc.finish(
        4,
        r.first_cap.as_ref().map(|c| (c.tets.len() as u64, 0)),
        r.last_cap.as_ref().map(|c| (c, 0)),
    );
    assert!(!st.closed.is_closed(), "{:?}", st.closed);
}

#[test]
fn closedness_at_the_packed_id_limit() {
    use chronotope::mesh::validate::{check_closed, PACKED_VERTEX_LIMIT};
    use chronotope::mesh::TetMesh;
    // The boundary of a 4-simplex on the highest vertex ids: closed, at n = 2^21 (packed
    // keys, 21-bit ids) and at n = 2^21 + 1 (the wide path).
    for n in [
        PACKED_VERTEX_LIMIT - 1,
        PACKED_VERTEX_LIMIT,
        PACKED_VERTEX_LIMIT + 1,
    ] {
        let mut m = TetMesh {
            vertices: vec![[0, 0, 0, 0]; n],
            tets: Vec::new(),
        };
        let ids: Vec<u32> = (n - 5..n).map(|i| i as u32).collect();
        let pts = [
            [0, 0, 0, 0],
            [1, 0, 0, 0],
            [0, 1, 0, 0],
            [0, 0, 1, 0],
            [0, 0, 0, 1],
        ];
        for (i, p) in ids.iter().zip(pts) {
            m.vertices[*i as usize] = p;
        }
        // ∂[0..5] = Σ (−1)^i [.. without i ..]
        for skip in 0..5 {
            let mut t: Vec<u32> = (0..5).filter(|&j| j != skip).map(|j| ids[j]).collect();
            if skip % 2 == 1 {
                t.swap(0, 1);
            }
            m.tets.push([t[0], t[1], t[2], t[3]]);
        }
        assert!(
            check_closed(&m).is_closed(),
            "n = {n}: {:?}",
            check_closed(&m)
        );
        m.tets.pop();
        assert!(!check_closed(&m).is_closed(), "n = {n}");
    }
}
