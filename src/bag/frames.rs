//! The bodies of a bag: every channel with schema `chronotope_msgs/msg/VoxelGrid`, decoded.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use super::error::{BagError, FrameError};
use super::reader::{BagReadOptions, BagReader, DEFAULT_MAX_RECORD_BYTES};
use super::summary::read_summary;
use crate::msg::{decode_cdr, RosMessage, VoxelGrid};

/// Iterator over the VoxelGrid frames of a bag, in file order: `(topic, frame)` or an error.
///
/// A message that does not decode is an `Err` and iteration goes on; an error of the bag
/// itself is `Err(FrameError::Bag(..))`, after which iteration ends if the error is
/// [fatal](BagError::is_fatal). Made by [`voxel_frames`].
pub struct VoxelFrames {
    reader: BagReader,
}

impl VoxelFrames {
    /// Frames from an already opened reader (the caller has checked the bag's contents).
    pub fn from_reader(reader: BagReader) -> Self {
        Self { reader }
    }

    /// The file being read.
    pub fn path(&self) -> &Path {
        self.reader.path()
    }
}

impl Iterator for VoxelFrames {
    type Item = Result<(String, VoxelGrid), FrameError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            let message = match self.reader.next()? {
                Ok(message) => message,
                Err(err) => return Some(Err(FrameError::Bag(err))),
            };
            if message.schema_name != VoxelGrid::TYPE_NAME {
                continue;
            }
            return Some(match decode_cdr::<VoxelGrid>(&message.data) {
                Ok(grid) => Ok((message.topic, grid)),
                Err(reason) => Err(FrameError::Decode {
                    topic: message.topic,
                    log_time_ns: message.log_time_ns,
                    reason,
                }),
            });
        }
    }
}

/// Opens a bag for iterating its VoxelGrid frames, after checking that it has some.
///
/// The check reads the summary section when the file has one (cheap); otherwise it scans the
/// file up to the first VoxelGrid message.
///
/// # Errors
///
/// [`BagError::EmptyBag`] if the bag holds no messages, [`BagError::NoVoxelTopics`] if none of
/// them is a VoxelGrid (listing the topics it has), and the errors of [`BagReader::open`]; with
/// no summary, a fatal error met while scanning for the first frame.
pub fn voxel_frames(path: impl AsRef<Path>) -> Result<VoxelFrames, BagError> {
    let path = path.as_ref();
    let reader = BagReader::open(path)?;
    match read_summary(path, DEFAULT_MAX_RECORD_BYTES).map_err(|source| io_error(path, source))? {
        Some(summary) => {
            if summary.message_count == 0 {
                return Err(BagError::EmptyBag {
                    path: path.to_path_buf(),
                });
            }
            let has_frames = summary
                .channels
                .iter()
                .any(|c| c.schema_name == VoxelGrid::TYPE_NAME && c.message_count > 0);
            if !has_frames {
                let topics_seen = summary
                    .channels
                    .iter()
                    .map(|c| topic_label(&c.topic, &c.schema_name))
                    .collect::<BTreeSet<_>>();
                return Err(no_voxel_topics(path, topics_seen));
            }
        }
        None => scan_for_first_frame(path)?,
    }
    Ok(VoxelFrames::from_reader(reader))
}

/// The topics of the bag whose schema is `chronotope_msgs/msg/VoxelGrid`, sorted.
///
/// From the summary section if the file has one (every such channel, with or without
/// messages), otherwise from a scan of the whole file (the topics that have messages).
///
/// # Errors
///
/// The errors of [`BagReader::open`]; with no summary, a fatal error met while scanning.
pub fn voxel_topics(path: impl AsRef<Path>) -> Result<Vec<String>, BagError> {
    let path = path.as_ref();
    let reader = BagReader::open(path)?;
    let topics: BTreeSet<String> =
        match read_summary(path, DEFAULT_MAX_RECORD_BYTES).map_err(|e| io_error(path, e))? {
            Some(summary) => summary
                .channels
                .into_iter()
                .filter(|c| c.schema_name == VoxelGrid::TYPE_NAME)
                .map(|c| c.topic)
                .collect(),
            None => {
                let mut topics = BTreeSet::new();
                for item in reader {
                    match item {
                        Ok(m) if m.schema_name == VoxelGrid::TYPE_NAME => {
                            topics.insert(m.topic);
                        }
                        Err(err) if err.is_fatal() => return Err(err),
                        _ => {}
                    }
                }
                topics
            }
        };
    Ok(topics.into_iter().collect())
}

/// Without a summary: reads until the first VoxelGrid message, to tell an empty bag and a bag
/// without frames from one with frames.
fn scan_for_first_frame(path: &Path) -> Result<(), BagError> {
    let mut any_message = false;
    let mut topics_seen = BTreeSet::new();
    for item in BagReader::open_with(path, BagReadOptions::default())? {
        match item {
            Ok(m) if m.schema_name == VoxelGrid::TYPE_NAME => return Ok(()),
            Ok(m) => {
                any_message = true;
                topics_seen.insert(topic_label(&m.topic, &m.schema_name));
            }
            Err(err) if err.is_fatal() => return Err(err),
            Err(_) => {}
        }
    }
    if any_message {
        Err(no_voxel_topics(path, topics_seen))
    } else {
        Err(BagError::EmptyBag {
            path: path.to_path_buf(),
        })
    }
}

fn topic_label(topic: &str, schema_name: &str) -> String {
    if schema_name.is_empty() {
        format!("{topic} (no schema)")
    } else {
        format!("{topic} ({schema_name})")
    }
}

fn no_voxel_topics(path: &Path, topics_seen: BTreeSet<String>) -> BagError {
    BagError::NoVoxelTopics {
        path: path.to_path_buf(),
        topics_seen: topics_seen.into_iter().collect(),
    }
}

fn io_error(path: &Path, source: std::io::Error) -> BagError {
    BagError::Io {
        path: PathBuf::from(path),
        action: "cannot read the bag's summary",
        source,
    }
}
