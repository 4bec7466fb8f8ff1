//! `octomap_msgs/msg/Octomap`: an OctoMap octree as octomap_server publishes it (the binary
//! stream of `binaryMapToMsg` or the full stream of `fullMapToMsg` in `data`).
//!
//! Mirrored field by field from the ROS 2 text of `octomap_msgs` (2.0, the package Humble
//! and Jazzy release), kept in `msgs/deps/octomap_msgs/msg/Octomap.msg` with its comments and
//! the trailing space of one comment line, as rosbag2 stores it. `int8[] data` is held as
//! bytes: CDR writes `int8[]` and `uint8[]` alike (a `u32` count, then the bytes), and one
//! copy of the whole array is far cheaper than a serde element per byte. The tree is read by
//! `chronotope_occupancy` (the occupancy node), not here.

use serde::{Deserialize, Serialize};

use super::voxel_grid::Header;
use super::RosMessage;

use super::std_types::defs::{HEADER, TIME};

/// `octomap_msgs/msg/Octomap`: a 3D occupancy map as an octree.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Octomap {
    /// stamp: time of the map; frame_id: frame of its keys' metric coordinates.
    pub header: Header,
    /// True: `data` holds only free/occupied leaves (`.bt`, `writeBinaryData`); false: the
    /// full tree with each node's value (`.ot`, `writeData`).
    pub binary: bool,
    /// Class id of the tree (`OcTree`, `OcTreeStamped`, `ColorOcTree`, …).
    pub id: String,
    /// Edge of the smallest octree nodes (m).
    pub resolution: f64,
    /// The serialised tree (`int8[]` on the wire; the same bytes).
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

impl RosMessage for Octomap {
    const TYPE_NAME: &'static str = "octomap_msgs/msg/Octomap";
    const DEFINITION: &'static str =
        include_str!("../../../msgs/deps/octomap_msgs/msg/Octomap.msg");
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        vec![HEADER, TIME]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{decode_cdr, encode_cdr, Time};

    #[test]
    fn octomap_cdr_round_trip_keeps_signed_bytes() {
        let map = Octomap {
            header: Header {
                stamp: Time {
                    sec: 12,
                    nanosec: 5,
                },
                frame_id: "map".into(),
            },
            binary: true,
            id: "OcTree".into(),
            resolution: 0.05,
            data: vec![0x00, 0x80, 0xff, 0x7f, 0x03],
        };
        let bytes = encode_cdr(&map).unwrap();
        assert_eq!(decode_cdr::<Octomap>(&bytes).unwrap(), map);
        // The array is a count and the bytes: what `int8[]` is in CDR.
        assert_eq!(
            &bytes[bytes.len() - 9..],
            &[5, 0, 0, 0, 0x00, 0x80, 0xff, 0x7f, 0x03]
        );
    }
}
