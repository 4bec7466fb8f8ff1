//! Random input never panics and finishes quickly: octree streams of random
//! bytes under every id and flag, mutated real streams, and clouds with random
//! headers over random bytes.

use crate::octree_writer as w;
use chronotope_occupancy::{
    CloudOptions, CloudRasterizer, Encoding, Fill, Lattice, Limits, OctomapMsg, OctomapOptions,
    OctomapRasterizer, PointCloud2Ref, PointField, VoxelFrame,
};
use proptest::prelude::*;
use std::time::{Duration, Instant};

const IDS: [&str; 4] = ["OcTree", "OcTreeStamped", "ColorOcTree", "CountingOcTree"];

fn octomap_once(data: &[u8], binary: bool, id: &str, unknown_occupied: bool, enc: Encoding) {
    let lattice = Lattice::new([-0.4, -0.4, -0.4], 0.1, [8, 8, 8]).unwrap();
    let msg = OctomapMsg {
        binary,
        id,
        resolution: 0.1,
        data,
    };
    let limits = Limits {
        max_octree_nodes: 1 << 16,
        ..Limits::default()
    };
    let mut raster = OctomapRasterizer::with_limits(
        OctomapOptions::new().unknown_occupied(unknown_occupied),
        limits,
    );
    let mut frame = VoxelFrame::new();
    let start = Instant::now();
    if raster.rasterize(&msg, &lattice, enc, &mut frame).is_ok() {
        assert_eq!(frame.data().len() as u64, enc.data_len(512));
    }
    assert!(start.elapsed() < Duration::from_secs(2));
}

/// 400 cases by default; `PROPTEST_CASES=100000` for a longer run.
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(400)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    #[test]
    fn random_octree_bytes_never_panic(
        data in proptest::collection::vec(any::<u8>(), 0..600),
        binary in any::<bool>(),
        id in 0usize..4,
        unknown_occupied in any::<bool>(),
        percent in any::<bool>(),
    ) {
        let enc = if percent { Encoding::Percent } else { Encoding::Bits };
        octomap_once(&data, binary, IDS[id], unknown_occupied, enc);
    }

    #[test]
    fn mutated_real_streams_never_panic(
        flips in proptest::collection::vec((any::<u16>(), any::<u8>()), 1..6),
        cut in any::<u16>(),
        binary in any::<bool>(),
    ) {
        let mut tree = None;
        for (i, k) in [[0u32, 0, 0], [1, 0, 0], [2, 3, 1], [4, 4, 4]].iter().enumerate() {
            w::insert(&mut tree, [32768 + k[0] * 2, 32768 + k[1] * 2, 32768 + k[2] * 2], 15 + (i as u32 % 2), if i % 2 == 0 { 1.0 } else { -1.0 });
        }
        let mut data = if binary { w::binary(&tree, 0.0) } else { w::full(&tree, &[]) };
        for (at, v) in flips {
            let n = data.len();
            data[at as usize % n] ^= v;
        }
        let keep = data.len() - (cut as usize % 4);
        data.truncate(keep);
        octomap_once(&data, binary, "OcTree", true, Encoding::Percent);
    }

    #[test]
    fn random_clouds_never_panic(
        data in proptest::collection::vec(any::<u8>(), 0..512),
        height in 0u32..5,
        width in 0u32..40,
        point_step in 0u32..40,
        row_pad in 0u32..8,
        row_step_shrink in 0u32..3,
        offsets in proptest::array::uniform3(0u32..40),
        types in proptest::array::uniform3(0u8..10),
        big in any::<bool>(),
        dilate in 0.0f64..0.3,
        fill in any::<bool>(),
        min_points in 0u8..3,
    ) {
        let names = ["x", "y", "z"];
        let fields: Vec<PointField<'_>> = (0..3).map(|a| PointField { name: names[a], offset: offsets[a], datatype: types[a], count: 1 }).collect();
        let row_step = (width * point_step + row_pad).saturating_sub(row_step_shrink);
        let cloud = PointCloud2Ref { height, width, fields: &fields, is_bigendian: big, point_step, row_step, data: &data, is_dense: false };
        let lattice = Lattice::new([-1.0, -1.0, -1.0], 0.1, [20, 20, 20]).unwrap();
        let opts = CloudOptions::new().dilate_m(dilate).min_points(min_points).fill(if fill { Fill::down_to_floor() } else { Fill::None });
        let mut frame = VoxelFrame::new();
        if let Ok(stats) = CloudRasterizer::new(opts).rasterize(&cloud, &lattice, Encoding::Bits, &mut frame) {
            prop_assert_eq!(stats.points, u64::from(width * height));
            prop_assert!(stats.nonfinite + stats.outside + stats.margin_points <= stats.points);
            prop_assert_eq!(frame.data().len(), 1000);
        }
    }
}

#[test]
fn a_stream_of_all_inner_nodes_stops_at_the_node_limit_quickly() {
    // 0xff bytes: every child has children, forever: bounded by depth 16 and the node limit.
    let data = vec![0xffu8; 1 << 20];
    let start = Instant::now();
    for binary in [true, false] {
        let msg = OctomapMsg {
            binary,
            id: "OcTree",
            resolution: 0.1,
            data: &data,
        };
        let lattice = Lattice::new([0.0; 3], 0.1, [4, 4, 4]).unwrap();
        let err = OctomapRasterizer::new(OctomapOptions::new()).rasterize(
            &msg,
            &lattice,
            Encoding::Bits,
            &mut VoxelFrame::new(),
        );
        assert!(err.is_err());
    }
    assert!(start.elapsed() < Duration::from_secs(2));
}
