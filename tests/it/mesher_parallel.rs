//! The mesher on several cores gives what it gives on one: a slab marched in chunks of
//! z-planes is the sequential sweep's mesh, vertex for vertex; the mesher node's batch of
//! several bodies' frames publishes what one-by-one handling publishes, in the same order.

use crate::common;

use std::sync::Arc;

use chronotope::mesh::march::{SlabMarcher, SlabPlacement, MIN_CHUNK_PLANES};
use chronotope::mesh::slice::{PlaneValue, Slicer, SLICE_CHUNK_TETS};
use chronotope::mesh::table::table;
use chronotope::mesh::{DecodeOptions, FrameRef, OccupancyGrid, TetMesh};
use chronotope::msg::{Header, Point, Time, VoxelGrid};
use chronotope::node::launch::LaunchConfig;
use chronotope::node::mesher::MesherNode;
use chronotope::node::{Message, Node, Payload};

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
}

/// A lumpy blob: a sphere of radius `r` voxels around `c`, with pseudo-random voxels of its
/// shell flipped (so that many hypercube cases occur), or percent values for graded frames.
fn blob(size: [u32; 3], c: [f64; 3], r: f64, seed: u64, percent: bool) -> Vec<u8> {
    let noise = |x: usize, y: usize, z: usize| {
        let mut h = seed ^ ((x as u64) << 40) ^ ((y as u64) << 20) ^ z as u64;
        h = h.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        h ^= h >> 29;
        h.wrapping_mul(0xBF58_476D_1CE4_E5B9) >> 58
    };
    let d = move |x: usize, y: usize, z: usize| {
        let v = [x as f64 - c[0], y as f64 - c[1], z as f64 - c[2]];
        (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - r
    };
    if percent {
        common::percent_data(size, |x, y, z| {
            let v = 50.0 - 30.0 * d(x, y, z);
            (v.clamp(0.0, 100.0) as u8).saturating_add(noise(x, y, z) as u8 % 7)
        })
    } else {
        common::bits_data(size, |x, y, z| {
            let dd = d(x, y, z);
            dd < 0.0 && !(dd > -1.5 && noise(x, y, z) == 0) || (dd < 1.0 && noise(x, y, z) == 1)
        })
    }
}

fn decode(size: [u32; 3], data: &[u8], percent: bool) -> OccupancyGrid {
    let f = FrameRef {
        stamp_ns: 0,
        origin: [0.0; 3],
        resolution: 0.01,
        size,
        encoding: u8::from(percent),
        data,
    };
    OccupancyGrid::decode(&f, &DecodeOptions::default()).unwrap()
}

fn march(
    threads: usize,
    f0: &OccupancyGrid,
    f1: &OccupancyGrid,
    scale: i32,
    max: usize,
) -> (bool, TetMesh) {
    pool(threads).install(|| {
        let mut m = SlabMarcher::default();
        let mut out = TetMesh::default();
        let at = SlabPlacement {
            scale,
            frame: 3,
            iso: 50,
        };
        // Twice with the same workspace: the second sweep must not see the first's cache.
        m.march(table(), f1, f0, at, max, &mut out);
        let ok = m.march(table(), f0, f1, at, max, &mut out);
        (ok, out)
    })
}

#[test]
fn a_slab_marched_in_chunks_is_the_sequential_mesh() {
    // Tall enough in z for four chunks of at least MIN_CHUNK_PLANES planes.
    let z = (4 * MIN_CHUNK_PLANES) as u32 + 3;
    for (percent, scale) in [(false, 2), (true, 64)] {
        let size = [40, 33, z];
        let c = [20.0, 16.0, f64::from(z) / 2.0];
        let a = decode(size, &blob(size, c, 14.0, 1, percent), percent);
        let b = decode(
            size,
            &blob(size, [21.0, 16.5, c[2] + 1.0], 14.0, 2, percent),
            percent,
        );
        let (ok1, one) = march(1, &a, &b, scale, usize::MAX);
        assert!(ok1 && !one.tets.is_empty());
        for threads in [2, 3, 4] {
            let (ok, many) = march(threads, &a, &b, scale, usize::MAX);
            assert!(ok);
            assert_eq!(
                many.vertices.len(),
                one.vertices.len(),
                "{threads} threads, percent {percent}"
            );
            assert!(
                many == one,
                "{threads} threads, percent {percent}: meshes differ"
            );
        }
    }
}

#[test]
fn the_tet_limit_holds_for_the_slab_as_a_whole_when_chunked() {
    let z = (4 * MIN_CHUNK_PLANES) as u32 + 3;
    let size = [40, 33, z];
    let c = [20.0, 16.0, f64::from(z) / 2.0];
    let a = decode(size, &blob(size, c, 14.0, 1, false), false);
    let b = decode(
        size,
        &blob(size, [21.0, 16.5, c[2] + 1.0], 14.0, 2, false),
        false,
    );
    let (_, one) = march(1, &a, &b, 2, usize::MAX);
    let n = one.tets.len();
    for threads in [1, 4] {
        // Exactly the slab's tets: accepted; one fewer: refused, and nothing kept.
        let (ok, m) = march(threads, &a, &b, 2, n);
        assert!(ok && m.tets.len() == n, "{threads} threads at the limit");
        let (ok, m) = march(threads, &a, &b, 2, n - 1);
        assert!(
            !ok && m.tets.is_empty() && m.vertices.is_empty(),
            "{threads} threads over it"
        );
        // Each chunk alone is under the limit; the slab is not.
        let (ok, _) = march(threads, &a, &b, 2, n / 2);
        assert!(!ok, "{threads} threads, half the slab's tets");
    }
}

#[test]
fn a_slice_cut_in_chunks_is_the_sequential_slice() {
    let size = [70, 70, 70];
    let a = decode(size, &blob(size, [35.0, 35.0, 35.0], 30.0, 3, false), false);
    let b = decode(size, &blob(size, [36.0, 34.0, 35.0], 30.0, 4, false), false);
    let (_, mesh) = march(1, &a, &b, 2, usize::MAX);
    assert!(
        mesh.tets.len() > 3 * SLICE_CHUNK_TETS,
        "{} tets",
        mesh.tets.len()
    );
    // Frame 3 at scale 2: the slab spans t = 6..8; a plane in the middle, and one through
    // the lattice vertices of the later frame's edges.
    for plane in [
        PlaneValue {
            num: 7 * 1024 + 1,
            den: 1024,
        },
        PlaneValue::lattice(7),
    ] {
        let slice = |threads: usize, par: bool| {
            pool(threads).install(|| {
                // A first part sliced alone, then the mesh: sources count over both.
                let mut s = Slicer::new(3, plane).with_sources();
                s.add(&mesh);
                if par {
                    s.add_par(&mesh);
                } else {
                    s.add(&mesh);
                }
                s.finish_with_sources()
            })
        };
        let one = slice(1, false);
        assert!(!one.0.triangles.is_empty());
        for threads in [1, 2, 3] {
            let many = slice(threads, true);
            assert!(many == one, "{threads} threads: slices differ");
        }
    }
}

/// A frame of body `i` (a blob moving +x one voxel per frame) at frame `k`.
fn frame(i: usize, k: u32) -> VoxelGrid {
    let size = [24, 24, 40];
    let c = [6.0 + f64::from(k) + 4.0 * i as f64, 12.0, 20.0];
    VoxelGrid {
        header: Header {
            stamp: Time::from_nanos(1_000_000_000 + i64::from(k) * 100_000_000),
            frame_id: "world".into(),
        },
        origin: Point::default(),
        resolution: 0.01,
        size_x: size[0],
        size_y: size[1],
        size_z: size[2],
        encoding: VoxelGrid::ENCODING_BITS,
        data: blob(size, c, 5.0 + i as f64, i as u64, false),
    }
}

fn node() -> MesherNode {
    let cfg = LaunchConfig::parse(
        "launch:\n\
         - node: {pkg: chronotope, exec: mesher, param: [{name: bodies, value: [/a/occupancy, /b/occupancy, /c/occupancy]}, {name: slice_markers, value: true}]}\n",
        "test",
    )
    .unwrap();
    MesherNode::from_spec(&cfg.nodes[0], &[]).unwrap()
}

/// Every published message as (topic, stamp, CDR bytes).
fn wire(out: &[Message]) -> Vec<(String, i64, Vec<u8>)> {
    out.iter()
        .map(|m| (m.topic.to_string(), m.stamp_ns, m.payload.encode().unwrap()))
        .collect()
}

#[test]
fn a_batch_of_several_bodies_publishes_what_one_by_one_handling_does() {
    let topics = ["/a/occupancy", "/b/occupancy", "/c/occupancy"];
    let mut batch = Vec::new();
    for k in 0..5u32 {
        for (i, t) in topics.iter().enumerate() {
            let mut f = frame(i, k);
            if i == 1 && k == 2 {
                // A refused frame in the middle: counted as a problem, in its place.
                f.resolution = -1.0;
            }
            batch.push(Message::new(
                t,
                f.header.stamp.as_nanos(),
                Payload::VoxelGrid(Arc::new(f)),
            ));
        }
        // A message of the wrong type on a body topic, and one on a topic no body uses.
        if k == 3 {
            let g = frame(0, k);
            batch.push(Message::new(
                "/d/occupancy",
                0,
                Payload::VoxelGrid(Arc::new(g)),
            ));
            batch.push(Message::new(
                "/c/occupancy",
                0,
                Payload::PoseStamped(Arc::new(Default::default())),
            ));
        }
    }
    let mut one = node();
    let mut out_one = Vec::new();
    for m in &batch {
        one.on_message(m, &mut out_one);
    }
    for threads in [1, 2, 3] {
        let mut many = node();
        let mut out_many = Vec::new();
        pool(threads).install(|| {
            // In two batches, as a live queue would hand them.
            let (x, y) = batch.split_at(7);
            many.on_messages(x, &mut out_many);
            many.on_messages(y, &mut out_many);
        });
        assert!(!out_one.is_empty());
        assert!(
            wire(&out_many) == wire(&out_one),
            "{threads} threads: outputs differ"
        );
        assert_eq!(many.status(), one.status(), "{threads} threads");
        for t in topics {
            assert_eq!(many.losses(t), one.losses(t));
        }
    }
    let s = one.status();
    assert_eq!(s.problems.get("frame_refused"), Some(&1));
    assert_eq!(s.problems.get("wrong_type"), Some(&1));
    assert_eq!(s.received, batch.len() as u64);
}
