//! The bodies of a bag: every channel with schema `chronotope_msgs/msg/VoxelGrid`, decoded.
//!
//! A channel is read as VoxelGrid frames only if everything about it says so: schema name
//! `chronotope_msgs/msg/VoxelGrid`, schema encoding `ros2msg`, a schema text that describes
//! this program's type by meaning (the same fields, types, order and nested types, whatever
//! the layout: [`chronotope_msg::Definition`]), and message encoding `cdr`. A VoxelGrid channel that fails one of these, and a channel without
//! a schema, is refused once by name ([`BagError::RefusedChannel`]) and its messages are counted
//! ([`VoxelFrames::refused`]), never silently dropped. Whether a bag is empty is decided from
//! its data, never from its Statistics record.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use serde::Serialize;

use super::error::{BagError, FrameError};
use super::reader::{BagMessage, BagSchema};
use super::recovery::Recovery;
use super::source::BagReader;
use chronotope_msg::{decode_cdr, ros2msg_schema, Definition, RosMessage, VoxelGrid};

/// A topic whose messages are not read as VoxelGrid frames, and what that cost.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RefusedTopic {
    /// The topic.
    pub topic: String,
    /// Why, in the user's terms.
    pub reason: String,
    /// Its messages met (and skipped).
    pub messages: u64,
    /// Log time of the first, nanoseconds.
    pub start_ns: u64,
    /// Log time of the last, nanoseconds.
    pub end_ns: u64,
}

impl RefusedTopic {
    /// Counts one more message of `topic`, refused for `reason`, logged at `log_time_ns`, in
    /// `refused` (by topic). True for the topic's first.
    pub fn count(
        refused: &mut BTreeMap<String, RefusedTopic>,
        topic: &str,
        reason: impl FnOnce() -> String,
        log_time_ns: u64,
    ) -> bool {
        let first = !refused.contains_key(topic);
        let t = log_time_ns;
        let e = refused
            .entry(topic.to_owned())
            .or_insert_with(|| RefusedTopic {
                topic: topic.to_owned(),
                reason: reason(),
                messages: 0,
                start_ns: t,
                end_ns: t,
            });
        e.messages += 1;
        e.start_ns = e.start_ns.min(t);
        e.end_ns = e.end_ns.max(t);
        first
    }
}

/// What to do with the messages of one channel.
#[derive(Debug, Clone)]
enum Verdict {
    Frames,
    Refused(String),
    NotVoxelGrid,
}

/// Iterator over the VoxelGrid frames of a bag, in file order: `(topic, frame)` or an error.
///
/// A message that does not decode is an `Err` and iteration goes on; an error of the bag
/// itself is `Err(FrameError::Bag(..))`, after which iteration ends if the error is
/// [fatal](BagError::is_fatal). A refused channel is one non-fatal
/// `Err(FrameError::Bag(BagError::RefusedChannel { .. }))` at its first message. Made by
/// [`voxel_frames`].
pub struct VoxelFrames {
    reader: BagReader,
    verdicts: HashMap<u16, Verdict>,
    refused: BTreeMap<String, RefusedTopic>,
}

impl VoxelFrames {
    /// Frames from an already opened reader (the caller has checked the bag's contents).
    pub fn from_reader(reader: BagReader) -> Self {
        Self {
            reader,
            verdicts: HashMap::new(),
            refused: BTreeMap::new(),
        }
    }

    /// The file being read.
    pub fn path(&self) -> &Path {
        self.reader.path()
    }

    /// What reading the bag has cost so far: damaged regions, messages lost, time spans
    /// (complete once the iterator has ended).
    pub fn recovery(&self) -> &Recovery {
        self.reader.recovery()
    }

    /// The topics refused so far and how many of their messages were skipped, by topic.
    pub fn refused(&self) -> Vec<RefusedTopic> {
        self.refused.values().cloned().collect()
    }

    /// Classifies a message's channel (once per channel); the error to yield if it is refused
    /// for the first time.
    fn classify(&mut self, m: &BagMessage) -> (Verdict, Option<BagError>) {
        if let Some(v) = self.verdicts.get(&m.channel_id) {
            return (v.clone(), None);
        }
        let v = verdict(m.schema.as_deref(), &m.message_encoding);
        self.verdicts.insert(m.channel_id, v.clone());
        let err = match &v {
            Verdict::Refused(reason) => Some(BagError::RefusedChannel {
                path: self.reader.path().to_path_buf(),
                topic: m.topic.clone(),
                reason: reason.clone(),
            }),
            _ => None,
        };
        (v, err)
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
            let (v, first_refusal) = self.classify(&message);
            match v {
                Verdict::NotVoxelGrid => continue,
                Verdict::Refused(reason) => {
                    RefusedTopic::count(
                        &mut self.refused,
                        &message.topic,
                        || reason,
                        message.log_time_ns,
                    );
                    match first_refusal {
                        Some(err) => return Some(Err(FrameError::Bag(err))),
                        None => continue,
                    }
                }
                Verdict::Frames => {}
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

/// Why a channel whose schema is named `chronotope_msgs/msg/VoxelGrid` cannot be read as
/// VoxelGrid frames (message encoding, schema encoding or schema text), if it cannot; `None`
/// for a readable one and for channels of other types.
pub fn voxel_channel_refusal(schema: Option<&BagSchema>, message_encoding: &str) -> Option<String> {
    match verdict(schema, message_encoding) {
        Verdict::Refused(reason) => Some(reason),
        _ => None,
    }
}

/// Whether a channel with this schema and message encoding carries VoxelGrid frames.
fn verdict(schema: Option<&BagSchema>, message_encoding: &str) -> Verdict {
    let Some(schema) = schema else {
        return Verdict::Refused(
            "the channel has no schema, so its messages cannot be told to be VoxelGrid frames \
             (record the topic with its schema)"
                .to_owned(),
        );
    };
    if schema.name != VoxelGrid::TYPE_NAME {
        return Verdict::NotVoxelGrid;
    }
    // A schema that names the type and holds no definition: what rosbag2's SQLite storage
    // records before Iron (no message_definitions table). The type name is all there is.
    let named_only = schema.encoding.is_empty() && schema.data.is_empty();
    if message_encoding != "cdr" {
        return Verdict::Refused(format!(
            "message encoding is {message_encoding:?}; VoxelGrid frames are read as \"cdr\" only"
        ));
    }
    if named_only {
        return Verdict::Frames;
    }
    if schema.encoding != "ros2msg" {
        return Verdict::Refused(format!(
            "schema encoding is {:?}; a VoxelGrid schema is read as \"ros2msg\" only",
            schema.encoding
        ));
    }
    if let Some(difference) = schema_difference(&schema.data) {
        return Verdict::Refused(format!(
            "its schema text does not describe the chronotope_msgs/msg/VoxelGrid this program \
             reads ({difference})"
        ));
    }
    Verdict::Frames
}

/// `None` if `data` describes our VoxelGrid by meaning (fields, types, order and nested types;
/// layout, comments, constants' placement and `pkg/msg/Type` spellings aside: see
/// [`chronotope_msg::Definition`]), else the first difference.
fn schema_difference(data: &[u8]) -> Option<String> {
    static EXPECTED: OnceLock<Definition> = OnceLock::new();
    let expected = EXPECTED.get_or_init(|| {
        Definition::parse(VoxelGrid::TYPE_NAME, &ros2msg_schema::<VoxelGrid>())
            .expect("our own definition parses")
    });
    let Ok(text) = std::str::from_utf8(data) else {
        return Some("the schema text is not UTF-8".to_owned());
    };
    match Definition::parse(VoxelGrid::TYPE_NAME, text) {
        Ok(got) => expected.difference(&got),
        Err(why) => Some(why.to_string()),
    }
}

/// Opens a bag for iterating its VoxelGrid frames, after checking from its data that it has
/// some (the Statistics record is never trusted for that).
///
/// The check reads the bag up to its first VoxelGrid frame.
///
/// # Errors
///
/// [`BagError::EmptyBag`] if the bag holds no messages and nothing in it is damaged;
/// [`BagError::NothingReadable`] if it has messages but every one was in a damaged region
/// (naming the regions); [`BagError::NoVoxelFrames`] if it has VoxelGrid topics but none of
/// their frames could be read (saying why); [`BagError::NoVoxelTopics`] if none of its
/// messages is a VoxelGrid (listing the topics it has); and the errors of [`BagReader::open`].
pub fn voxel_frames(path: impl AsRef<Path>) -> Result<VoxelFrames, BagError> {
    let path = path.as_ref();
    let reader = BagReader::open(path)?;
    probe(path)?;
    Ok(VoxelFrames::from_reader(reader))
}

/// Reads up to the first VoxelGrid frame; if there is none, the error that says why.
fn probe(path: &Path) -> Result<(), BagError> {
    let mut frames = VoxelFrames::from_reader(BagReader::open(path)?);
    let mut any_message = false;
    let mut topics_seen = BTreeSet::new();
    let mut fatal = None;
    let mut decode_errors = 0u64;
    while let Some(item) = frames.reader.next() {
        let m = match item {
            Ok(m) => m,
            Err(err) if err.is_fatal() => {
                fatal = Some(err);
                break;
            }
            Err(_) => continue,
        };
        any_message = true;
        topics_seen.insert(topic_label(&m.topic, &m.schema_name));
        let (v, _) = frames.classify(&m);
        match v {
            Verdict::Frames => {
                if decode_cdr::<VoxelGrid>(&m.data).is_ok() {
                    return Ok(());
                }
                decode_errors += 1;
            }
            Verdict::Refused(reason) => {
                frames
                    .refused
                    .entry(m.topic.clone())
                    .or_insert_with(|| RefusedTopic {
                        topic: m.topic.clone(),
                        reason,
                        messages: 0,
                        start_ns: m.log_time_ns,
                        end_ns: m.log_time_ns,
                    })
                    .messages += 1;
            }
            Verdict::NotVoxelGrid => {}
        }
    }
    let recovery = frames.reader.recovery().clone();
    let voxel_topics: BTreeSet<String> = frames
        .reader
        .channels()
        .into_iter()
        .filter(|c| c.schema_name == VoxelGrid::TYPE_NAME)
        .map(|c| c.topic)
        .chain(frames.refused.keys().cloned())
        .collect();
    let only_cut = recovery
        .losses
        .iter()
        .all(|l| l.kind == super::recovery::LossKind::Truncated);
    if !any_message && voxel_topics.is_empty() && frames.refused.is_empty() && only_cut {
        if let Some(err) = fatal {
            // Cut before anything: the truncation itself is the answer.
            return Err(err);
        }
    }
    let mut why: Vec<String> = frames
        .refused
        .values()
        .map(|r| format!("{}: {} ({} messages)", r.topic, r.reason, r.messages))
        .collect();
    if decode_errors > 0 {
        why.push(format!(
            "{decode_errors} messages do not decode as VoxelGrid"
        ));
    }
    if !recovery.is_clean() {
        why.push(recovery.describe());
    }
    if let Some(err) = &fatal {
        why.push(format!("reading stopped: {err}"));
    }
    if !any_message && why.is_empty() {
        return Err(BagError::EmptyBag {
            path: path.to_path_buf(),
        });
    }
    if !voxel_topics.is_empty() {
        if why.is_empty() {
            why.push("they have no messages".to_owned());
        }
        return Err(BagError::NoVoxelFrames {
            path: path.to_path_buf(),
            topics: voxel_topics.into_iter().collect(),
            detail: why.join("; "),
        });
    }
    if any_message {
        return Err(no_voxel_topics(path, topics_seen));
    }
    if !why.is_empty() {
        return Err(BagError::NothingReadable {
            path: path.to_path_buf(),
            detail: why.join("; "),
        });
    }
    Err(BagError::EmptyBag {
        path: path.to_path_buf(),
    })
}

/// The topics of the bag whose schema is `chronotope_msgs/msg/VoxelGrid` and that are read as
/// frames (not refused), sorted; at most [`MAX_CHANNELS`](super::MAX_CHANNELS).
///
/// From the summary section if the file has a usable one (every such channel, with or without
/// messages), otherwise from a scan of the whole file (the topics that have messages).
///
/// # Errors
///
/// The errors of [`BagReader::open`]; with no summary, a fatal error met while scanning.
pub fn voxel_topics(path: impl AsRef<Path>) -> Result<Vec<String>, BagError> {
    let path = path.as_ref();
    let mut reader = BagReader::open(path)?;
    let mut topics = BTreeSet::new();
    if reader.recovery().summary_used {
        for c in reader.channels() {
            let schema = reader.schema_of(c.id);
            if matches!(
                verdict(schema.as_deref(), &c.message_encoding),
                Verdict::Frames
            ) {
                topics.insert(c.topic);
            }
        }
    } else {
        let mut verdicts: HashMap<u16, bool> = HashMap::new();
        for item in reader.by_ref() {
            match item {
                Ok(m) => {
                    let ok = *verdicts.entry(m.channel_id).or_insert_with(|| {
                        matches!(
                            verdict(m.schema.as_deref(), &m.message_encoding),
                            Verdict::Frames
                        )
                    });
                    if ok {
                        topics.insert(m.topic);
                    }
                }
                Err(err) if err.is_fatal() => return Err(err),
                Err(_) => {}
            }
        }
    }
    Ok(topics.into_iter().collect())
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
        path: PathBuf::from(path),
        topics_seen: topics_seen.into_iter().collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn our_schema_matches_itself_with_comments_and_spacing_changed() {
        let ours = ros2msg_schema::<VoxelGrid>();
        assert_eq!(schema_difference(ours.as_bytes()), None);
        let respaced: String = ours
            .lines()
            .map(|l| format!("  {}   # a comment\n", l.replace(' ', "   ")))
            .collect();
        assert_eq!(schema_difference(respaced.as_bytes()), None);
        let changed = ours.replacen("float64 resolution", "float32 resolution", 1);
        let why = schema_difference(changed.as_bytes()).unwrap();
        assert!(why.contains("float32 resolution"), "{why}");
        // Constants first, as PyPI rosbags writes the definition: the same type.
        let constants_first = format!(
            "uint8 ENCODING_BITS=0\nuint8 ENCODING_PERCENT=1\n{}",
            ours.replacen("uint8 ENCODING_BITS=0", "", 1).replacen(
                "uint8 ENCODING_PERCENT=1",
                "",
                1
            )
        );
        assert_eq!(schema_difference(constants_first.as_bytes()), None);
    }
}
