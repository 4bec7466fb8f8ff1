//! Errors of bag reading and writing ([`BagError`]) and of VoxelGrid frame iteration
//! ([`FrameError`]).

use std::fmt;
use std::path::PathBuf;

use chronotope_msg::{CdrError, SchemaError};

/// Where in an MCAP file a record is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RecordLocation {
    /// A record at the top level of the file, at this byte offset.
    File {
        /// Byte offset of the record's opcode.
        offset: u64,
    },
    /// A record inside a chunk.
    Chunk {
        /// Byte offset of the chunk record in the file.
        chunk_offset: u64,
        /// Position of the record among the chunk's records, from 0.
        index: usize,
    },
}

impl RecordLocation {
    /// The file offset of the record, or of the chunk holding it.
    pub fn file_offset(&self) -> u64 {
        match *self {
            RecordLocation::File { offset } => offset,
            RecordLocation::Chunk { chunk_offset, .. } => chunk_offset,
        }
    }
}

impl fmt::Display for RecordLocation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RecordLocation::File { offset } => write!(f, "byte {offset}"),
            RecordLocation::Chunk {
                chunk_offset,
                index,
            } => write!(f, "record {index} of the chunk at byte {chunk_offset}"),
        }
    }
}

/// What went wrong reading or writing a rosbag2 MCAP file. Every variant names the file.
///
/// Reading yields some of these as items of [`BagReader`](super::BagReader) and goes on
/// (a corrupt chunk, a malformed record, a message on an undefined channel); the others end
/// the iteration ([`BagError::is_fatal`]).
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The file could not be opened, read, created or written.
    #[error("{}: {action}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("cannot open", "cannot read", ...).
        action: &'static str,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The path names something other than a regular file or a directory (a FIFO, a socket,
    /// a device): refused before it is opened, as it could block or never end.
    #[error(
        "{}: it is {kind}, not a regular file (it could block or never end); give a bag file or \
         a rosbag2 directory",
        path.display()
    )]
    NotAFile {
        /// The path.
        path: PathBuf,
        /// What it is.
        kind: crate::fsio::SpecialKind,
    },
    /// The file is not MCAP at all.
    #[error("{}: not an MCAP file: {reason}", path.display())]
    NotMcap {
        /// The file.
        path: PathBuf,
        /// What was found instead.
        reason: String,
    },
    /// The file ends in the middle of a record (or before the footer).
    #[error(
        "{}: the file ends at byte {offset} in the middle of a record: the bag is truncated \
         (was the recorder stopped before it could finish the file?); the messages before that \
         point were read",
        path.display()
    )]
    Truncated {
        /// The file.
        path: PathBuf,
        /// The file size, where reading stopped.
        offset: u64,
    },
    /// The record structure of the file is broken, so nothing after this point can be read.
    #[error("{}: corrupt MCAP structure at byte {offset}: {reason}", path.display())]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// Offset of the record that could not be framed.
        offset: u64,
        /// What was wrong.
        reason: String,
    },
    /// A record is larger than the reader is configured to accept; it is skipped and
    /// reading goes on with the next readable record.
    #[error(
        "{}: record at byte {offset} (opcode {opcode:#04x}) is {len} bytes, more than the \
         reader's limit of {limit} bytes; it is skipped (if the file is trusted, raise the \
         limit with BagReadOptions::max_record_bytes)",
        path.display()
    )]
    RecordTooLarge {
        /// The file.
        path: PathBuf,
        /// Offset of the record (or of the chunk holding it).
        offset: u64,
        /// MCAP opcode of the record.
        opcode: u8,
        /// Its declared length.
        len: u64,
        /// The limit in force.
        limit: usize,
    },
    /// A chunk could not be decompressed or failed its CRC; its messages are skipped and
    /// reading goes on with the next record.
    #[error(
        "{}: chunk at byte {offset} is unreadable, its messages are skipped: {reason}",
        path.display()
    )]
    CorruptChunk {
        /// The file.
        path: PathBuf,
        /// Offset of the chunk record.
        offset: u64,
        /// What was wrong.
        reason: String,
    },
    /// A record could be framed but its content is malformed; it is skipped.
    #[error("{}: malformed {kind} record at {location}: {reason}", path.display())]
    BadRecord {
        /// The file.
        path: PathBuf,
        /// Where the record is.
        location: RecordLocation,
        /// Record type ("Schema", "Channel", "Message", ...).
        kind: &'static str,
        /// What was wrong.
        reason: String,
    },
    /// A message refers to a channel that no Channel record (in the data before it, or in
    /// the summary) defines; it is skipped, and so are further messages of that channel
    /// (counted in the reader's recovery, reported once).
    #[error(
        "{}: message at {location} is on channel {channel_id}, which no Channel record defines \
         (neither before it nor in the summary); this channel's messages are skipped",
        path.display()
    )]
    UnknownChannel {
        /// The file.
        path: PathBuf,
        /// Where the message is.
        location: RecordLocation,
        /// The channel id it names.
        channel_id: u16,
    },
    /// A channel refers to a schema that no earlier Schema record defined; its messages are
    /// skipped.
    #[error(
        "{}: message at {location} is on channel {topic:?}, whose schema {schema_id} no Schema \
         record defines; this channel's messages are skipped",
        path.display()
    )]
    UnknownSchema {
        /// The file.
        path: PathBuf,
        /// Where the message is.
        location: RecordLocation,
        /// The channel's topic.
        topic: String,
        /// The schema id it names.
        schema_id: u16,
    },
    /// Bytes where no record can be framed (zeroes, an unknown opcode, a length running past
    /// the data) were skipped up to the next readable record; reading goes on.
    #[error(
        "{}: bytes {offset}-{} hold no readable record ({reason}); {}",
        path.display(),
        offset + bytes,
        match next {
            Some(n) => format!("skipped to the next readable record at byte {n}"),
            None => "nothing readable follows".to_owned(),
        }
    )]
    Skipped {
        /// The file.
        path: PathBuf,
        /// Where the damage starts.
        offset: u64,
        /// Bytes skipped.
        bytes: u64,
        /// What was found there.
        reason: String,
        /// Where reading goes on, if anywhere.
        next: Option<u64>,
    },
    /// A copy of a chunk (or unchunked message) already read; its messages are not delivered
    /// twice, and reading goes on.
    #[error(
        "{}: the {what} at byte {offset} is a copy of one already read; its messages are not \
         delivered twice",
        path.display()
    )]
    Duplicate {
        /// The file.
        path: PathBuf,
        /// Where the copy is.
        offset: u64,
        /// "chunk" or "message".
        what: &'static str,
    },
    /// The bag defines more channels than [`MAX_CHANNELS`](super::MAX_CHANNELS); the first
    /// ones are read, the others' messages are counted as lost. Reported once.
    #[error(
        "{}: the bag has more than MAX_CHANNELS = {limit} channels; {topic} and every further \
         channel are not read (their messages are counted as lost)",
        path.display()
    )]
    TooManyChannels {
        /// The file.
        path: PathBuf,
        /// The limit.
        limit: usize,
        /// The first channel refused.
        topic: String,
    },
    /// A VoxelGrid channel that cannot be read as one (its encoding, its schema); its messages
    /// are counted as skipped and reading goes on. Reported once per channel.
    #[error("{}: topic {topic}: {reason}; its messages are skipped", path.display())]
    RefusedChannel {
        /// The file.
        path: PathBuf,
        /// The channel's topic.
        topic: String,
        /// Why, in the user's terms.
        reason: String,
    },
    /// The bag holds no messages at all, and nothing in it is damaged.
    #[error("{}: the bag holds no messages", path.display())]
    EmptyBag {
        /// The file.
        path: PathBuf,
    },
    /// The bag has messages, but none could be read: every one was in a damaged region.
    #[error("{}: no message could be read: {detail}", path.display())]
    NothingReadable {
        /// The file.
        path: PathBuf,
        /// The damaged regions and what they cost.
        detail: String,
    },
    /// The bag has VoxelGrid topics, but no frame of them could be read.
    #[error(
        "{}: the bag has VoxelGrid topics ({}), but no frame of them could be read: {detail}",
        path.display(),
        topics.join(", ")
    )]
    NoVoxelFrames {
        /// The file.
        path: PathBuf,
        /// The VoxelGrid topics.
        topics: Vec<String>,
        /// Why: refused channels, damaged regions, or no messages.
        detail: String,
    },
    /// The bag holds messages, but none on a `chronotope_msgs/msg/VoxelGrid` channel.
    #[error(
        "{}: no messages of type chronotope_msgs/msg/VoxelGrid; topics in the bag: {}",
        path.display(),
        list_or_none(topics_seen)
    )]
    NoVoxelTopics {
        /// The file.
        path: PathBuf,
        /// Every topic in the bag, with its schema name: `"/topic (pkg/msg/Type)"`.
        topics_seen: Vec<String>,
    },
    /// Writing: the topic was not added with [`BagWriter::add_topic`](super::BagWriter::add_topic).
    #[error("{}: topic {topic:?} was not added; call add_topic first", path.display())]
    UnknownTopic {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
    },
    /// Writing: the topic exists with another message type.
    #[error(
        "{}: topic {topic:?} carries {existing}, not {requested}",
        path.display()
    )]
    TopicTypeConflict {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// Its message type.
        existing: String,
        /// The type asked for.
        requested: String,
    },
    /// Writing: the message type's definitions are incomplete.
    #[error("{}: cannot write the schema of {type_name}: {source}", path.display())]
    Schema {
        /// The file.
        path: PathBuf,
        /// The message type.
        type_name: &'static str,
        /// What is missing.
        #[source]
        source: SchemaError,
    },
    /// Writing: the message could not be serialised, or raw bytes are not CDR.
    #[error("{}: message for topic {topic:?} is not valid CDR: {source}", path.display())]
    Cdr {
        /// The file.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// What was wrong.
        #[source]
        source: CdrError,
    },
    /// A path that is neither an MCAP file, a rosbag2 SQLite file, a zstd-compressed one, nor
    /// a rosbag2 directory (fatal).
    #[error("{}: not a bag: {reason}", path.display())]
    NotABag {
        /// The path.
        path: PathBuf,
        /// Why, in words.
        reason: String,
    },
    /// A rosbag2 directory's `metadata.yaml` cannot be used (fatal when nothing else says
    /// which files the bag holds).
    #[error("{}: {reason}", path.display())]
    Metadata {
        /// The `metadata.yaml` file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A split file of a rosbag2 directory that cannot be read at all (missing, unreadable,
    /// not a bag, too large once decompressed); the other files are read.
    #[error("{}: split file skipped: {reason}", path.display())]
    SplitFile {
        /// The split file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// A rosbag2 SQLite file whose database cannot be read further (fatal for that file).
    #[error("{}: cannot read the SQLite database: {reason}", path.display())]
    Sqlite {
        /// The `.db3` file.
        path: PathBuf,
        /// SQLite's own words.
        reason: String,
    },
    /// Messages found compressed (zstd frames: no CDR payload starts so) though nothing said
    /// so (no `metadata.yaml`, or one whose `compression_mode` says otherwise): they are read
    /// decompressed. Said once per topic.
    #[error(
        "{}: messages on {topic} are zstd-compressed though nothing says so (rosbag2 per-message \
         compression; metadata.yaml's compression_mode says otherwise, or there is none): read \
         decompressed",
        path.display()
    )]
    CompressedMessages {
        /// The storage file.
        path: PathBuf,
        /// The topic.
        topic: String,
    },
    /// A rosbag2 SQLite file with a write-ahead log left beside it, which is not read (the
    /// database is read as it is, immutable); the rows in the database are read.
    #[error("{}: {reason}", path.display())]
    LogNotRead {
        /// The `.db3` file.
        path: PathBuf,
        /// What lies beside it and what it means.
        reason: String,
    },
    /// One message row of a rosbag2 SQLite file that cannot be used; it is skipped.
    #[error("{}: message row {row}: {reason}; it is skipped", path.display())]
    BadRow {
        /// The `.db3` file.
        path: PathBuf,
        /// The row's `id`.
        row: i64,
        /// What is wrong with it.
        reason: String,
    },
    /// A message of a bag written with rosbag2's per-message compression that does not
    /// decompress; it is skipped.
    #[error("{}: message on {topic} logged at {log_time_ns} ns does not decompress ({format}): {reason}; it is skipped", path.display())]
    Decompression {
        /// The storage file.
        path: PathBuf,
        /// The message's topic.
        topic: String,
        /// Its log time.
        log_time_ns: u64,
        /// The compression format (`zstd`).
        format: String,
        /// Why.
        #[source]
        reason: DecompressError,
    },
    /// A rosbag2 directory's `metadata.yaml` disagrees with what its split files hold
    /// (messages it counts that were not read, files it does not list, a time span not
    /// covered); reported once all files are read.
    #[error("{}: disagrees with what was read: {reason}", path.display())]
    MetadataDisagrees {
        /// The `metadata.yaml` file.
        path: PathBuf,
        /// Where and by how much.
        reason: String,
    },
    /// An error of one split file of a rosbag2 directory that ends that file's reading; the
    /// next split files are read.
    #[error("{source}; reading the next split file")]
    InSplitFile {
        /// What ended the file.
        #[source]
        source: Box<BagError>,
    },
    /// Writing: the MCAP writer failed (usually an I/O error underneath).
    #[error("{}: MCAP writer failed: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The writer's error.
        #[source]
        source: mcap::McapError,
    },
}

impl BagError {
    /// True if reading cannot go on after this error (the iterator ends after yielding it).
    pub fn is_fatal(&self) -> bool {
        !matches!(
            self,
            BagError::CorruptChunk { .. }
                | BagError::SplitFile { .. }
                | BagError::BadRow { .. }
                | BagError::LogNotRead { .. }
                | BagError::CompressedMessages { .. }
                | BagError::Decompression { .. }
                | BagError::InSplitFile { .. }
                | BagError::MetadataDisagrees { .. }
                | BagError::RecordTooLarge { .. }
                | BagError::Skipped { .. }
                | BagError::Duplicate { .. }
                | BagError::TooManyChannels { .. }
                | BagError::RefusedChannel { .. }
                | BagError::BadRecord { .. }
                | BagError::UnknownChannel { .. }
                | BagError::UnknownSchema { .. }
        )
    }
}

fn list_or_none(topics: &[String]) -> String {
    if topics.is_empty() {
        "none".to_owned()
    } else {
        topics.join(", ")
    }
}

/// Why one message of a bag compressed per message does not decompress
/// ([`BagError::Decompression`]).
#[derive(Debug, thiserror::Error)]
pub enum DecompressError {
    /// The data does not start as a zstd frame.
    #[error("it is not a zstd frame")]
    NotZstd,
    /// The frame's header declares more than the reader takes.
    #[error("it declares {declared} bytes, more than the reader's limit of {limit} bytes")]
    DeclaredTooLarge {
        /// What the header declares.
        declared: u64,
        /// The reader's limit (`BagReadOptions::max_record_bytes`).
        limit: usize,
    },
    /// The frame holds less or more than its header declares.
    #[error("it holds {held} bytes where its header declares {declared}")]
    SizeMismatch {
        /// What it decompressed to.
        held: usize,
        /// What the header declares.
        declared: u64,
    },
    /// Without a declared size, it decompresses to more than the reader takes.
    #[error("it decompresses to more than the reader's limit of {limit} bytes")]
    TooLarge {
        /// The reader's limit (`BagReadOptions::max_record_bytes`).
        limit: usize,
    },
    /// The zstd decoder's error (a damaged frame).
    #[error(transparent)]
    Zstd(#[from] std::io::Error),
}

/// What went wrong iterating the VoxelGrid frames of a bag.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// One message on a VoxelGrid channel does not decode as a VoxelGrid; it is skipped and
    /// iteration goes on. (A channel whose message encoding is not `cdr` ends up here too,
    /// as its bytes do not start with a CDR encapsulation header.)
    #[error("VoxelGrid message on {topic:?} logged at {log_time_ns} ns does not decode: {reason}")]
    Decode {
        /// The message's topic.
        topic: String,
        /// The message's log time.
        log_time_ns: u64,
        /// What was wrong with its CDR.
        #[source]
        reason: CdrError,
    },
    /// An error of the bag itself (it names the file); if [fatal](BagError::is_fatal),
    /// iteration ends after it, otherwise it goes on with the next readable record.
    #[error(transparent)]
    Bag(#[from] BagError),
}
