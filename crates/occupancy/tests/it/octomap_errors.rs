//! Every refusal of an Octomap message: its variant, and a message naming the culprit.

use crate::octree_writer::{self as w};
use chronotope_occupancy::{
    Encoding, Lattice, LatticeError, Limits, OctomapError, OctomapMsg, OctomapOptions,
    OctomapRasterizer, VoxelFrame,
};

const K0: u32 = 32768;

fn try_msg(binary: bool, id: &str, resolution: f64, data: &[u8]) -> Result<(), OctomapError> {
    try_with(
        binary,
        id,
        resolution,
        data,
        OctomapOptions::new(),
        Limits::default(),
    )
}

fn try_with(
    binary: bool,
    id: &str,
    resolution: f64,
    data: &[u8],
    opts: OctomapOptions,
    limits: Limits,
) -> Result<(), OctomapError> {
    let lattice = Lattice::new([0.0; 3], 0.1, [4, 4, 4]).unwrap();
    let msg = OctomapMsg {
        binary,
        id,
        resolution,
        data,
    };
    let mut frame = VoxelFrame::new();
    OctomapRasterizer::with_limits(opts, limits)
        .rasterize(&msg, &lattice, Encoding::Percent, &mut frame)
        .map(|_| ())
}

fn small_tree() -> Option<w::Tree> {
    let mut tree = None;
    w::insert(&mut tree, [K0, K0, K0], 16, 1.0);
    w::insert(&mut tree, [K0 + 2, K0, K0], 15, -1.0);
    tree
}

#[test]
fn bad_resolutions_are_refused_with_their_value() {
    let data = w::binary(&small_tree(), 0.0);
    for r in [0.0, -0.05, f64::NAN, f64::INFINITY, 1e-9] {
        let err = try_msg(true, "OcTree", r, &data).unwrap_err();
        assert!(matches!(err, OctomapError::Resolution { .. }), "{err:?}");
        assert!(
            err.to_string().contains("resolution") && err.to_string().contains(&format!("{r}")),
            "{err}"
        );
    }
}

#[test]
fn unknown_ids_are_refused_by_name() {
    let data = w::full(&small_tree(), &[]);
    for id in ["CountingOcTree", "SemanticOcTree", ""] {
        let err = try_msg(false, id, 0.1, &data).unwrap_err();
        assert_eq!(err, OctomapError::UnknownTreeId { id: id.to_owned() });
        assert!(err.to_string().contains(&format!("\"{id}\"")), "{err}");
    }
}

#[test]
fn truncated_binary_streams_name_the_offset() {
    let data = w::binary(&small_tree(), 0.0);
    for cut in 1..data.len() {
        let err = try_msg(true, "OcTree", 0.1, &data[..cut]).unwrap_err();
        let OctomapError::Truncated { offset, len, .. } = err.clone() else {
            panic!("{err:?}")
        };
        assert_eq!(len, cut as u64);
        assert!(offset <= cut as u64);
        assert!(
            err.to_string().contains(&format!("offset {offset}")),
            "{err}"
        );
    }
}

#[test]
fn truncated_full_streams_name_the_offset_and_what_was_read() {
    let data = w::full(&small_tree(), &[]);
    for cut in 1..data.len() {
        let err = try_msg(false, "OcTree", 0.1, &data[..cut]).unwrap_err();
        assert!(
            matches!(err, OctomapError::Truncated { .. }),
            "cut {cut}: {err:?}"
        );
    }
    // A ColorOcTree stream read without its colours runs out of data... and an
    // OcTree stream read as ColorOcTree does too.
    assert!(try_msg(false, "ColorOcTree", 0.1, &data).is_err());
    let coloured = w::full(&small_tree(), &[1, 2, 3]);
    let err = try_msg(false, "ColorOcTree", 0.1, &coloured[..coloured.len() - 2]).unwrap_err();
    let OctomapError::Truncated { what, .. } = err.clone() else {
        panic!("{err:?}")
    };
    assert!(what.contains("mask") || what.contains("colour"), "{what}");
    assert!(err.to_string().contains("truncated"), "{err}");
}

#[test]
fn a_child_mask_announcing_children_past_the_end_is_truncation() {
    // Root: value, mask with all 8 children, and nothing after.
    let mut data = 1.0f32.to_le_bytes().to_vec();
    data.push(0xff);
    let err = try_msg(false, "OcTree", 0.1, &data).unwrap_err();
    assert_eq!(
        err,
        OctomapError::Truncated {
            offset: 5,
            needed: 4,
            len: 5,
            what: "a node's log-odds"
        }
    );
}

#[test]
fn a_tree_deeper_than_16_is_refused_at_the_offending_codes() {
    // Binary: 16 levels of "child 0 has children", then a depth-16 child with children.
    let mut data = Vec::new();
    for _ in 0..16 {
        data.extend_from_slice(&[0b11, 0]);
    }
    data.extend_from_slice(&[0b10, 0]);
    let err = try_msg(true, "OcTree", 0.1, &data).unwrap_err();
    assert_eq!(err, OctomapError::TooDeep { offset: 30 });
    assert!(
        err.to_string().contains("offset 30") && err.to_string().contains("deeper than 16"),
        "{err}"
    );
    // Full: 17 nodes each with child 0, the last (depth 16) still with a child.
    let mut data = Vec::new();
    for _ in 0..17 {
        data.extend_from_slice(&0.5f32.to_le_bytes());
        data.push(1);
    }
    data.extend_from_slice(&0.5f32.to_le_bytes());
    data.push(0);
    let err = try_msg(false, "OcTree", 0.1, &data).unwrap_err();
    assert_eq!(err, OctomapError::TooDeep { offset: 16 * 5 + 4 });
}

#[test]
fn node_counts_past_the_limit_are_refused() {
    let data = w::full(&small_tree(), &[]);
    let limits = Limits {
        max_octree_nodes: 10,
        ..Limits::default()
    };
    let err = try_with(false, "OcTree", 0.1, &data, OctomapOptions::new(), limits).unwrap_err();
    assert!(
        matches!(err, OctomapError::TooManyNodes { limit: 10, .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("max_octree_nodes = 10"), "{err}");
    let err = try_with(
        true,
        "OcTree",
        0.1,
        &w::binary(&small_tree(), 0.0),
        OctomapOptions::new(),
        limits,
    )
    .unwrap_err();
    assert!(
        matches!(err, OctomapError::TooManyNodes { limit: 10, .. }),
        "{err:?}"
    );
}

#[test]
fn messages_past_the_byte_limit_are_refused_before_reading() {
    let data = vec![0u8; 100];
    let limits = Limits {
        max_octree_bytes: 64,
        ..Limits::default()
    };
    let err = try_with(true, "OcTree", 0.1, &data, OctomapOptions::new(), limits).unwrap_err();
    assert_eq!(
        err,
        OctomapError::TooLarge {
            len: 100,
            limit: 64
        }
    );
    assert!(err.to_string().contains("max_octree_bytes = 64"));
}

#[test]
fn trailing_bytes_are_refused_unless_allowed_and_then_counted() {
    let mut data = w::binary(&small_tree(), 0.0);
    let end = data.len() as u64;
    data.extend_from_slice(b"junk");
    let err = try_msg(true, "OcTree", 0.1, &data).unwrap_err();
    assert_eq!(
        err,
        OctomapError::TrailingBytes {
            offset: end,
            count: 4
        }
    );
    assert!(
        err.to_string()
            .contains("4 bytes after the tree ends at offset"),
        "{err}"
    );

    let lattice = Lattice::new([0.0; 3], 0.1, [4, 4, 4]).unwrap();
    let msg = OctomapMsg {
        binary: true,
        id: "OcTree",
        resolution: 0.1,
        data: &data,
    };
    let mut raster = OctomapRasterizer::new(OctomapOptions::new().allow_trailing_bytes(true));
    let stats = raster
        .rasterize(&msg, &lattice, Encoding::Bits, &mut VoxelFrame::new())
        .unwrap();
    assert_eq!(stats.stream.trailing_bytes, 4);
    assert_eq!(stats.stream.bytes_read, end);
}

#[test]
fn nan_log_odds_are_refused_at_their_offset() {
    let mut data = w::full(&small_tree(), &[]);
    data[5..9].copy_from_slice(&f32::NAN.to_le_bytes());
    let err = try_msg(false, "OcTree", 0.1, &data).unwrap_err();
    assert_eq!(err, OctomapError::NanLogOdds { offset: 5 });
    assert!(err.to_string().contains("offset 5"));
}

#[test]
fn a_nan_threshold_is_refused() {
    let data = w::full(&small_tree(), &[]);
    let err = try_with(
        false,
        "OcTree",
        0.1,
        &data,
        OctomapOptions::new().threshold_log_odds(f32::NAN),
        Limits::default(),
    )
    .unwrap_err();
    assert_eq!(err, OctomapError::Threshold);
}

#[test]
fn lattices_past_the_limits_are_refused_before_allocating() {
    let data = w::binary(&small_tree(), 0.0);
    let msg = OctomapMsg {
        binary: true,
        id: "OcTree",
        resolution: 0.1,
        data: &data,
    };
    let mut raster = OctomapRasterizer::new(OctomapOptions::new());
    let mut frame = VoxelFrame::new();
    let huge = Lattice::new([0.0; 3], 0.1, [2048, 2048, 512]).unwrap();
    let err = raster
        .rasterize(&msg, &huge, Encoding::Bits, &mut frame)
        .unwrap_err();
    assert!(
        matches!(
            err,
            OctomapError::Lattice(LatticeError::TooManyVoxels { .. })
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("max_voxels"), "{err}");
    let big = Lattice::new([0.0; 3], 0.1, [512, 512, 512]).unwrap();
    let err = raster
        .rasterize(&msg, &big, Encoding::Percent, &mut frame)
        .unwrap_err();
    assert!(
        matches!(
            err,
            OctomapError::Lattice(LatticeError::TooManyBytes { .. })
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("max_decoded_bytes"), "{err}");
    assert!(frame.data().is_empty(), "the frame is left as it was");
}

#[test]
fn bad_lattices_are_refused_by_name() {
    assert!(matches!(
        Lattice::new([f64::NAN, 0.0, 0.0], 0.1, [1, 1, 1]),
        Err(LatticeError::Origin { axis: 'x', .. })
    ));
    assert!(matches!(
        Lattice::new([0.0; 3], -0.1, [1, 1, 1]),
        Err(LatticeError::Resolution { .. })
    ));
    let err = Lattice::new([0.0; 3], 0.1, [1, 0, 1]).unwrap_err();
    assert_eq!(err, LatticeError::EmptySize { axis: 'y' });
    assert!(err.to_string().contains("size_y"));
}
