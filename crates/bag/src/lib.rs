//! rosbag2-compatible MCAP files: writing ([`BagWriter`]), streaming reading ([`BagReader`]),
//! and the VoxelGrid bodies of a bag ([`voxel_frames`], [`voxel_topics`]).
//!
//! The files follow what `ros2 bag record -s mcap` writes (docs/formats.md#bag-files):
//! header profile `ros2`; one schema per message type, encoding `ros2msg`, named
//! `pkg/msg/Type`, holding the rosbag2 concatenated `.msg` text
//! ([`ros2msg_schema`](chronotope_msg::ros2msg_schema)); one channel per topic with message
//! encoding `cdr` and the `offered_qos_profiles` metadata; messages as CDR with the
//! encapsulation header; chunks, indexes and statistics as the `mcap` crate writes them.
//! The Python readers `rosbags` and `mcap-ros2-support` read them
//! (`tests/py/read_bags.py`).
//!
//! Reading frames the records itself with every length checked, and relies on the `mcap`
//! crate's sans-I/O reader only to decompress and CRC-check one chunk at a time, so that no
//! file content can cause a panic or an allocation larger than the data present (or than
//! [`BagReadOptions::max_record_bytes`] for decompressed chunks). Memory stays at about one
//! chunk (compressed plus decompressed) whatever the size of the file. Damaged bags are read
//! as far as their structure allows, through the summary and chunk indexes when they are
//! intact, by scanning for the next record when they are not; [`BagReader::recovery`] says
//! what was lost (`docs/bag-recovery.md`).
#![warn(missing_docs)]

mod error;
mod frames;
pub mod fsio;
mod reader;
mod records;
mod recovery;
mod rosbag2;
mod source;
mod sqlite;
mod summary;
mod writer;

pub use error::{BagError, DecompressError, FrameError, RecordLocation};
pub use frames::{voxel_channel_refusal, voxel_frames, voxel_topics, RefusedTopic, VoxelFrames};
pub use reader::{
    BagChannel, BagMessage, BagReadOptions, BagSchema, McapReader,
    DEFAULT_MAX_DECOMPRESSED_FILE_BYTES, DEFAULT_MAX_RECORD_BYTES, MAX_CHANNELS,
    MAX_DECOMPRESSED_ENV, MAX_SCHEMA_BYTES,
};
pub use recovery::{BagLoss, Integrity, LossKind, Recovery, Unverified, MAX_LISTED_LOSSES};
pub use rosbag2::{
    is_directory_path, storage_file_name, Compression, MetadataTopic, Rosbag2Dir,
    MAX_METADATA_BYTES, MAX_SPLIT_FILES, METADATA_FILE, METADATA_LIMITS,
};
pub use source::{BagLayout, BagReader};
pub use sqlite::PAGE_BYTES;
pub use writer::{derived_by, BagCompression, BagWriteOptions, BagWriter, OFFERED_QOS_PROFILES};
