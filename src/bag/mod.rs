//! rosbag2-compatible MCAP files: writing ([`BagWriter`]), streaming reading ([`BagReader`]),
//! and the VoxelGrid bodies of a bag ([`voxel_frames`], [`voxel_topics`]).
//!
//! The files follow what `ros2 bag record -s mcap` writes (DESIGN.md section 10): header
//! profile `ros2`; one schema per message type, encoding `ros2msg`, named `pkg/msg/Type`,
//! holding the rosbag2 concatenated `.msg` text ([`ros2msg_schema`](crate::msg::ros2msg_schema));
//! one channel per topic with message encoding `cdr` and the `offered_qos_profiles` metadata;
//! messages as CDR with the encapsulation header; chunks, indexes and statistics as the `mcap`
//! crate writes them. The Python readers `rosbags` and `mcap-ros2-support` read them
//! (`tests/py/read_bags.py`).
//!
//! Reading relies on the `mcap` crate's sans-I/O linear reader for framing and decompression
//! only, and parses the records it needs itself with every length checked, so that no file
//! content can cause a panic or an allocation larger than the data present (or than
//! [`BagReadOptions::max_record_bytes`] for decompressed chunks). Memory stays at about one
//! chunk whatever the size of the file.

mod error;
mod frames;
mod reader;
mod records;
mod summary;
mod writer;

pub use error::{BagError, FrameError, RecordLocation};
pub use frames::{voxel_frames, voxel_topics, VoxelFrames};
pub use reader::{BagMessage, BagReadOptions, BagReader, DEFAULT_MAX_RECORD_BYTES};
pub use writer::{BagCompression, BagWriteOptions, BagWriter, OFFERED_QOS_PROFILES};
