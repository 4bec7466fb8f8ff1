//! Octree streams written by the test writer come back as the right voxels.

use crate::octree_writer::{self as w, Tree};
use chronotope_occupancy::{
    read_leaves, Encoding, Lattice, Limits, OctomapMsg, OctomapOptions, OctomapRasterizer,
    VoxelFrame, PARALLEL_BYTES, PERCENT_UNKNOWN,
};
use proptest::prelude::*;

const K0: u32 = 32768;

/// A lattice in key units of a tree of resolution `res`: min corner at key
/// `origin_key` (may be fractional for fine lattices), edge `edge` keys.
fn key_lattice(res: f64, origin_key: [f64; 3], edge: f64, size: [u32; 3]) -> Lattice {
    let origin = origin_key.map(|k| (k - f64::from(K0)) * res);
    Lattice::new(origin, edge * res, size).unwrap()
}

fn run(
    tree: &Option<Tree>,
    binary: bool,
    id: &str,
    res: f64,
    lattice: &Lattice,
    enc: Encoding,
    opts: OctomapOptions,
) -> Vec<u8> {
    let data = if binary {
        w::binary(tree, opts.threshold())
    } else {
        w::full(
            tree,
            if id == "ColorOcTree" {
                &[10, 20, 30]
            } else {
                &[]
            },
        )
    };
    let msg = OctomapMsg {
        binary,
        id,
        resolution: res,
        data: &data,
    };
    let mut raster = OctomapRasterizer::new(opts);
    let mut frame = VoxelFrame::new();
    raster.rasterize(&msg, lattice, enc, &mut frame).unwrap();
    assert_eq!(frame.encoding(), Some(enc));
    frame.take_data()
}

fn bit(data: &[u8], n: usize) -> bool {
    data[n / 8] >> (n % 8) & 1 == 1
}

/// Exact reference: volumes in integer "fine units" (`scale` per key).
struct Reference {
    bits: Vec<bool>,
    percent: Vec<u8>,
}

fn reference(
    leaves: &[([u32; 3], u32, f32)],
    threshold: f32,
    unknown_occupied: bool,
    origin_fine: [i64; 3],
    edge_fine: i64,
    scale: i64,
    size: [u32; 3],
) -> Reference {
    let [nx, ny, nz] = size.map(|n| n as i64);
    let vol = edge_fine.pow(3) as i128;
    let mut bits = Vec::new();
    let mut percent = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let lo = [
                    origin_fine[0] + i * edge_fine,
                    origin_fine[1] + j * edge_fine,
                    origin_fine[2] + k * edge_fine,
                ];
                let (mut occ, mut free) = (0i128, 0i128);
                for (key, depth, value) in leaves {
                    let len = (1i64 << (16 - depth)) * scale;
                    let mut v = 1i128;
                    for a in 0..3 {
                        let l = i64::from(key[a]) * scale;
                        let o = (l + len).min(lo[a] + edge_fine) - l.max(lo[a]);
                        v *= i128::from(o.max(0));
                    }
                    if *value >= threshold {
                        occ += v;
                    } else {
                        free += v;
                    }
                }
                bits.push(occ > 0 || (unknown_occupied && free < vol));
                percent.push(if occ + free == 0 {
                    PERCENT_UNKNOWN
                } else {
                    let p = ((100 * (vol - free) + vol - 1) / vol) as u8;
                    if occ > 0 {
                        p.max(1)
                    } else {
                        p
                    }
                });
            }
        }
    }
    Reference { bits, percent }
}

#[test]
fn a_single_finest_leaf_lands_on_its_voxel_in_both_streams() {
    let res = 0.05;
    let mut tree = None;
    // The cell from (0.10, 0.05, 0.00) to (0.15, 0.10, 0.05).
    w::insert(
        &mut tree,
        [
            w::key_of(0.125, res),
            w::key_of(0.075, res),
            w::key_of(0.025, res),
        ],
        16,
        2.0,
    );
    let lattice = Lattice::new([0.0; 3], res, [4, 4, 4]).unwrap();
    for binary in [true, false] {
        let data = run(
            &tree,
            binary,
            "OcTree",
            res,
            &lattice,
            Encoding::Bits,
            OctomapOptions::new(),
        );
        let set: Vec<usize> = (0..64).filter(|&n| bit(&data, n)).collect();
        assert_eq!(set, vec![2 + 4], "binary = {binary}");
        let data = run(
            &tree,
            binary,
            "OcTree",
            res,
            &lattice,
            Encoding::Percent,
            OctomapOptions::new(),
        );
        assert_eq!(data[6], 100);
        assert_eq!(data.iter().filter(|&&v| v == PERCENT_UNKNOWN).count(), 63);
    }
}

#[test]
fn a_pruned_coarse_leaf_fills_every_voxel_it_covers() {
    let res = 0.1;
    let mut tree = None;
    // A depth-13 leaf: 8 cells a side, keys K0..K0+8 (0 to 0.8 m).
    w::insert(&mut tree, [K0, K0, K0], 13, 3.5);
    let lattice = Lattice::new([-0.2, -0.2, -0.2], res, [12, 12, 12]).unwrap();
    let data = run(
        &tree,
        true,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new(),
    );
    for k in 0..12 {
        for j in 0..12 {
            for i in 0..12 {
                let inside = (2..10).contains(&i) && (2..10).contains(&j) && (2..10).contains(&k);
                assert_eq!(
                    bit(&data, i + 12 * (j + 12 * k)),
                    inside,
                    "voxel {i} {j} {k}"
                );
            }
        }
    }
}

#[test]
fn one_fine_occupied_leaf_makes_a_coarse_voxel_occupied_and_percent_counts_volume() {
    let res = 0.05;
    let mut tree = None;
    // Voxel (0,0,0) of a 0.1 m lattice holds 8 cells: 1 occupied, 4 free, 3 unknown.
    let cells = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1]];
    for (n, c) in cells.iter().enumerate() {
        let v = if n == 0 { 1.0 } else { -1.0 };
        w::insert(&mut tree, [K0 + c[0], K0 + c[1], K0 + c[2]], 16, v);
    }
    let lattice = Lattice::new([0.0; 3], 0.1, [1, 1, 1]).unwrap();
    let bits = run(
        &tree,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new(),
    );
    assert_eq!(bits, vec![1]);
    // Occupied 1/8 plus unknown 3/8: 50 %.
    let pct = run(
        &tree,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Percent,
        OctomapOptions::new(),
    );
    assert_eq!(pct, vec![50]);
    // Without the occupied cell: free 4/8, unknown 3/8 (the occupied cell now free: 5/8 free).
    let mut freed = tree.clone();
    w::insert(&mut freed, [K0, K0, K0], 16, -1.0);
    let pct = run(
        &freed,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Percent,
        OctomapOptions::new(),
    );
    assert_eq!(pct, vec![38]); // ceil(37.5)
    let bits = run(
        &freed,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new(),
    );
    assert_eq!(bits, vec![0]);
    let bits = run(
        &freed,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new().unknown_occupied(true),
    );
    assert_eq!(bits, vec![1]);
}

#[test]
fn unknown_space_is_free_in_bits_unless_asked_and_255_in_percent() {
    let res = 0.1;
    let tree = None; // empty message: nothing known
    let lattice = Lattice::new([0.0; 3], res, [3, 2, 1]).unwrap();
    let bits = run(
        &tree,
        true,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new(),
    );
    assert_eq!(bits, vec![0]);
    let bits = run(
        &tree,
        true,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new().unknown_occupied(true),
    );
    assert_eq!(bits, vec![0b11_1111]);
    let pct = run(
        &tree,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Percent,
        OctomapOptions::new(),
    );
    assert_eq!(pct, vec![255; 6]);
}

#[test]
fn the_threshold_decides_full_streams_and_defaults_to_log_odds_zero() {
    let res = 0.1;
    let mut tree = None;
    w::insert(&mut tree, [K0, K0, K0], 16, 0.4);
    w::insert(&mut tree, [K0 + 1, K0, K0], 16, -0.1);
    w::insert(&mut tree, [K0 + 2, K0, K0], 16, 0.0);
    let lattice = Lattice::new([0.0; 3], res, [3, 1, 1]).unwrap();
    let bits = run(
        &tree,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new(),
    );
    assert_eq!(
        bits,
        vec![0b101],
        "0 is occupied (>=), as OctoMap's isNodeOccupied"
    );
    let bits = run(
        &tree,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new().threshold_probability(0.7),
    );
    assert_eq!(bits, vec![0b000], "log-odds 0.4 < logodds(0.7) = 0.847");
    let bits = run(
        &tree,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new().threshold_log_odds(-0.2),
    );
    assert_eq!(bits, vec![0b111]);
}

#[test]
fn stamped_and_colour_trees_read_as_their_occupancy() {
    let res = 0.2;
    let mut tree = None;
    w::insert(&mut tree, [K0, K0, K0], 15, 1.0);
    w::insert(&mut tree, [K0 + 2, K0, K0], 16, -1.0);
    let lattice = Lattice::new([0.0; 3], res, [4, 2, 2]).unwrap();
    let plain = run(
        &tree,
        false,
        "OcTree",
        res,
        &lattice,
        Encoding::Percent,
        OctomapOptions::new(),
    );
    let stamped = run(
        &tree,
        false,
        "OcTreeStamped",
        res,
        &lattice,
        Encoding::Percent,
        OctomapOptions::new(),
    );
    let colour = run(
        &tree,
        false,
        "ColorOcTree",
        res,
        &lattice,
        Encoding::Percent,
        OctomapOptions::new(),
    );
    assert_eq!(plain, stamped);
    assert_eq!(plain, colour);
    assert_eq!(&plain[..4], &[100, 100, 0, 255]);
    let binary = run(
        &tree,
        true,
        "ColorOcTree",
        res,
        &lattice,
        Encoding::Percent,
        OctomapOptions::new(),
    );
    assert_eq!(plain, binary);
}

#[test]
fn a_leaf_touching_a_voxel_face_does_not_spill_into_it_on_an_unaligned_lattice() {
    // Tree 0.1 m, lattice 0.15 m from 0: the cell 0.3..0.4 m is inside voxel 2
    // (0.30..0.45) only; the cell 0.4..0.5 straddles voxels 2 and 3.
    let res = 0.1;
    let lattice = Lattice::new([0.0; 3], 0.15, [5, 1, 1]).unwrap();
    let mut tree = None;
    w::insert(&mut tree, [K0 + 3, K0, K0], 16, 1.0);
    let bits = run(
        &tree,
        true,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new(),
    );
    assert_eq!(bits, vec![0b00100]);
    let mut tree = None;
    w::insert(&mut tree, [K0 + 4, K0, K0], 16, 1.0);
    let bits = run(
        &tree,
        true,
        "OcTree",
        res,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new(),
    );
    assert_eq!(bits, vec![0b01100]);
}

#[test]
fn a_root_leaf_covers_the_whole_tree_in_a_full_stream() {
    let tree = Some(Tree::Leaf(2.0));
    let lattice = Lattice::new([-5.0, 3.0, 100.0], 1.0, [2, 2, 2]).unwrap();
    let bits = run(
        &tree,
        false,
        "OcTree",
        0.1,
        &lattice,
        Encoding::Bits,
        OctomapOptions::new(),
    );
    assert_eq!(bits, vec![0xff]);
    // Outside the tree's cube (±3276.8 m) nothing is known.
    let far = Lattice::new([4000.0, 0.0, 0.0], 1.0, [1, 1, 1]).unwrap();
    let pct = run(
        &tree,
        false,
        "OcTree",
        0.1,
        &far,
        Encoding::Percent,
        OctomapOptions::new(),
    );
    assert_eq!(pct, vec![PERCENT_UNKNOWN]);
}

#[test]
fn one_rasteriser_serves_frames_of_changing_lattices() {
    let res = 0.1;
    let mut tree = None;
    w::insert(&mut tree, [K0, K0, K0], 16, 1.0);
    let data = w::binary(&tree, 0.0);
    let msg = OctomapMsg {
        binary: true,
        id: "OcTree",
        resolution: res,
        data: &data,
    };
    let mut raster = OctomapRasterizer::new(OctomapOptions::new());
    let mut frame = VoxelFrame::new();
    for (n, enc) in [
        (70u32, Encoding::Percent),
        (3, Encoding::Bits),
        (130, Encoding::Percent),
        (2, Encoding::Bits),
    ] {
        let lattice = Lattice::new([0.0; 3], res, [n, 2, 2]).unwrap();
        raster.rasterize(&msg, &lattice, enc, &mut frame).unwrap();
        assert_eq!(frame.occupied(0, 0, 0), Some(true));
        assert_eq!(
            frame.value(1, 0, 0),
            Some(if enc == Encoding::Bits { 0 } else { 255 })
        );
        assert_eq!(
            frame.data().len() as u64,
            enc.data_len(lattice.voxel_count())
        );
    }
}

#[test]
fn read_leaves_reports_every_leaf_with_its_depth() {
    let mut tree = None;
    w::insert(&mut tree, [K0, K0, K0], 14, 1.0);
    w::insert(&mut tree, [K0 + 4, K0, K0], 16, -1.0);
    let data = w::full(&tree, &[]);
    let msg = OctomapMsg {
        binary: false,
        id: "OcTree",
        resolution: 0.1,
        data: &data,
    };
    let mut got = Vec::new();
    let summary = read_leaves(&msg, &OctomapOptions::new(), &Limits::default(), |l| {
        got.push(*l)
    })
    .unwrap();
    assert_eq!(got.len(), 2);
    assert_eq!(
        (
            got[0].key_min,
            got[0].depth,
            got[0].occupied,
            got[0].log_odds
        ),
        ([K0, K0, K0], 14, true, Some(1.0))
    );
    assert_eq!(got[0].size(), 4);
    assert_eq!(summary.max_depth, 16);
    assert_eq!((summary.occupied_leaves, summary.free_leaves), (1, 1));
    assert_eq!(summary.bytes_read, data.len() as u64);
}

/// A random subtree over a 32-cell cube at `base` (depth 11), leaves at any depth.
fn random_tree() -> impl Strategy<Value = Vec<([u32; 3], u32, f32)>> {
    // Each decision: 0 unknown, 1 free leaf, 2 occupied leaf, 3 split.
    proptest::collection::vec(0u8..=255, 600).prop_map(|choices| {
        let mut leaves = Vec::new();
        let mut it = choices.into_iter().cycle();
        fn rec(
            key: [u32; 3],
            depth: u32,
            it: &mut impl Iterator<Item = u8>,
            out: &mut Vec<([u32; 3], u32, f32)>,
        ) {
            let c = it.next().unwrap();
            let split_weight = if depth >= 16 {
                0
            } else if depth < 13 {
                200
            } else {
                110
            };
            let kind = if c < split_weight { 3 } else { c % 3 };
            match kind {
                0 => {}
                1 => out.push((key, depth, -0.4 - f32::from(c % 7) * 0.1)),
                2 => out.push((key, depth, f32::from(c % 5) * 0.5)),
                _ => {
                    let half = 1u32 << (16 - depth - 1);
                    for i in 0..8u32 {
                        let k = [
                            key[0] + (i & 1) * half,
                            key[1] + (i >> 1 & 1) * half,
                            key[2] + (i >> 2 & 1) * half,
                        ];
                        rec(k, depth + 1, it, out);
                    }
                }
            }
        }
        rec([K0 - 32, K0, K0 - 64], 11, &mut it, &mut leaves);
        leaves
    })
}

fn tree_of(leaves: &[([u32; 3], u32, f32)]) -> Option<Tree> {
    let mut tree = None;
    for (k, d, v) in leaves {
        w::insert(&mut tree, *k, *d, *v);
    }
    tree
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Aligned lattices (edge a power of two of the tree's, origin on its
    /// grid): both streams give exactly the integer reference, bits and percent.
    #[test]
    fn aligned_lattices_match_the_exact_reference(
        leaves in random_tree(),
        res_pick in 0usize..4,
        edge_log2 in -1i32..=2,
        off in proptest::array::uniform3(-6i64..=6),
        size in proptest::array::uniform3(1u32..=9),
        unknown_occupied in any::<bool>(),
        threshold_pick in 0usize..3,
    ) {
        let res = [0.05, 0.1, 0.25, 0.037][res_pick];
        let threshold = [0.0f32, 0.5, -0.45][threshold_pick];
        let scale = if edge_log2 < 0 { 2i64 } else { 1 };
        let edge_fine = if edge_log2 < 0 { 1 } else { 1i64 << edge_log2 };
        // Origin in fine units near the subtree at [K0-32, K0, K0-64].
        let base = [i64::from(K0) - 32, i64::from(K0), i64::from(K0) - 64].map(|k| k * scale);
        let origin_fine = [base[0] + off[0] * 3, base[1] + off[1] * 3, base[2] + off[2] * 5];
        let origin_key = origin_fine.map(|o| o as f64 / scale as f64);
        let edge_key = edge_fine as f64 / scale as f64;
        let lattice = key_lattice(res, origin_key, edge_key, size);
        let tree = tree_of(&leaves);
        let expect = reference(&w::leaves(&tree), threshold, unknown_occupied, origin_fine, edge_fine, scale, size);
        let opts = OctomapOptions::new().unknown_occupied(unknown_occupied).threshold_log_odds(threshold);
        for binary in [true, false] {
            let bits = run(&tree, binary, "OcTree", res, &lattice, Encoding::Bits, opts);
            let got: Vec<bool> = (0..expect.bits.len()).map(|n| bit(&bits, n)).collect();
            prop_assert_eq!(&got, &expect.bits, "bits, binary = {}", binary);
            let pct = run(&tree, binary, "OcTree", res, &lattice, Encoding::Percent, opts);
            prop_assert_eq!(&pct, &expect.percent, "percent, binary = {}", binary);
        }
    }

    /// Any lattice: bits agree with a float reference wherever the occupied
    /// overlap is not a sliver, percent within one point.
    #[test]
    fn unaligned_lattices_agree_with_a_float_reference(
        leaves in random_tree(),
        origin in proptest::array::uniform3(-1.2f64..0.2),
        edge in 0.031f64..0.4,
        size in proptest::array::uniform3(1u32..=7),
    ) {
        let res = 0.05;
        let tree = tree_of(&leaves);
        let lattice = Lattice::new(origin, edge, size).unwrap();
        let bits = run(&tree, false, "OcTree", res, &lattice, Encoding::Bits, OctomapOptions::new());
        let pct = run(&tree, false, "OcTree", res, &lattice, Encoding::Percent, OctomapOptions::new());
        let all = w::leaves(&tree);
        let [nx, ny, nz] = size.map(|n| n as usize);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let lo = [origin[0] + i as f64 * edge, origin[1] + j as f64 * edge, origin[2] + k as f64 * edge];
                    let (mut occ, mut free) = (0.0f64, 0.0f64);
                    for (key, depth, value) in &all {
                        let len = f64::from(1u32 << (16 - depth)) * res;
                        let mut v = 1.0;
                        for a in 0..3 {
                            let l = (f64::from(key[a]) - f64::from(K0)) * res;
                            v *= ((l + len).min(lo[a] + edge) - l.max(lo[a])).max(0.0) / edge;
                        }
                        if *value >= 0.0 { occ += v } else { free += v }
                    }
                    let n = i + nx * (j + ny * k);
                    if occ > 1e-6 || occ == 0.0 {
                        prop_assert_eq!(bit(&bits, n), occ > 0.0, "voxel {} {} {} occ {}", i, j, k, occ);
                    }
                    if occ + free < 1e-6 {
                        prop_assert!(pct[n] == 255 || pct[n] >= 99, "voxel {} {} {}: {} for nothing known", i, j, k, pct[n]);
                    } else if occ + free > 1e-6 {
                        let want = (100.0 * (1.0 - free)).ceil();
                        prop_assert!((f64::from(pct[n]) - want).abs() <= 1.0, "voxel {} {} {}: {} vs {}", i, j, k, pct[n], want);
                    }
                }
            }
        }
    }
}

#[test]
fn a_lattice_spanning_more_cells_than_the_span_table_still_finds_fine_leaves() {
    // Tree 1 mm, lattice 20 m wide: 20 000 cells a side, past the table's 16 384.
    let res = 0.001;
    let mut tree = None;
    w::insert(
        &mut tree,
        [
            w::key_of(12.3455, res),
            w::key_of(0.0005, res),
            w::key_of(0.0005, res),
        ],
        16,
        1.0,
    );
    w::insert(
        &mut tree,
        [
            w::key_of(0.0005, res),
            w::key_of(0.0005, res),
            w::key_of(0.0005, res),
        ],
        14,
        1.0,
    );
    let lattice = Lattice::new([0.0; 3], 1.0, [20, 1, 1]).unwrap();
    for binary in [true, false] {
        let bits = run(
            &tree,
            binary,
            "OcTree",
            res,
            &lattice,
            Encoding::Bits,
            OctomapOptions::new(),
        );
        assert_eq!(bits, vec![0b0000_0001, 0b0001_0000, 0], "binary = {binary}");
        let pct = run(
            &tree,
            binary,
            "OcTree",
            res,
            &lattice,
            Encoding::Percent,
            OctomapOptions::new(),
        );
        assert_eq!((pct[0], pct[12], pct[1]), (100, 100, 255));
    }
}

/// A stream long enough to be read on a second thread while the caller rasterises its
/// leaves gives the frame and figures that one thread gives, in both streams and on an
/// unaligned lattice (where the order of the sums would show).
#[test]
fn a_stream_read_beside_its_rasterisation_gives_the_same_frame() {
    let res = 0.05;
    let mut tree = None;
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    for _ in 0..40_000 {
        let r = next();
        let key = [0, 1, 2].map(|a| K0 - 64 + (r >> (a * 8) & 127) as u32);
        let value = ((r >> 32) % 9) as f32 * 0.25 - 1.0;
        w::insert(&mut tree, key, 16, value);
    }
    // Coarser free leaves around: the merged ones and the partial overlaps.
    for i in 0..64u32 {
        let key = [K0 + 64 + (i % 4) * 16, K0 + (i / 4 % 4) * 16, K0 - 64 + (i / 16) * 16];
        w::insert(&mut tree, key, 12, -2.0);
    }
    let lattice = Lattice::new([-3.3, -3.1, -3.2], 0.0781, [80, 80, 72]).unwrap();
    for binary in [false, true] {
        let data = if binary {
            w::binary(&tree, 0.0)
        } else {
            w::full(&tree, &[])
        };
        if !binary {
            assert!(data.len() >= PARALLEL_BYTES, "{} bytes", data.len());
        }
        let msg = OctomapMsg {
            binary,
            id: "OcTree",
            resolution: res,
            data: &data,
        };
        for (enc, unknown) in [(Encoding::Percent, false), (Encoding::Bits, true)] {
            let frame = |parallel: bool| {
                let opts = OctomapOptions::new()
                    .unknown_occupied(unknown)
                    .parallel(parallel);
                let mut raster = OctomapRasterizer::new(opts);
                let mut frame = VoxelFrame::new();
                let stats = raster.rasterize(&msg, &lattice, enc, &mut frame).unwrap();
                (stats, frame.take_data())
            };
            let (one, two) = (frame(false), frame(true));
            assert_eq!(one.0, two.0, "binary {binary} {enc:?}");
            assert!(one.1 == two.1, "binary {binary} {enc:?}: the frames differ");
            assert!(one.0.leaves_in_lattice > 1000, "{:?}", one.0);
        }
    }
}
