//! Streaming reader of the messages of an MCAP file, in file order, with bounded memory, that
//! recovers everything the file's structure still allows (see `docs/bag-recovery.md`).
//!
//! How it reads:
//! - At open, the summary section (found through the footer) is read if present: its Schema
//!   and Channel records define channels before any data is read, so a damaged first chunk
//!   does not orphan the messages of later ones, and its Chunk Index records say where every
//!   chunk starts and how long it is.
//! - The data section is then read record by record. A chunk the index knows is read with the
//!   index's length (a damaged length field costs nothing). A record that cannot be framed (an
//!   opcode no MCAP file has, a length running past the data) is skipped to the next chunk the
//!   index knows, or, without an index, to the next offset where a plausible record starts (a
//!   chunk that decompresses and passes its CRC, or a record whose successor is also a record).
//! - A chunk identical to one already read is not delivered twice.
//! - Every loss is reported as an error item and kept in [`BagReader::recovery`], with the
//!   messages and time span lost when the chunk's Message Index records (or the Chunk Index)
//!   still say so.
//!
//! Statistics are never trusted over the data: they are only reported.

use std::collections::hash_map::DefaultHasher;
use std::collections::{HashMap, HashSet, VecDeque};
use std::fs::File;
use std::hash::{Hash, Hasher};
use std::io::{BufReader, Cursor, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::McapError;

use super::error::{BagError, RecordLocation};
use super::records::{self, op, ChunkIndexRecord};
use super::recovery::{BagLoss, LossKind, Recovery};
use super::summary::{read_summary, MAGIC};

/// Opcode and length prefix of every record.
const RECORD_PREFIX: u64 = 1 + 8;

/// Default of [`BagReadOptions::max_record_bytes`]: 256 MiB.
pub const DEFAULT_MAX_RECORD_BYTES: usize = 256 << 20;

/// Most channels (topics) read from one bag. Channels beyond it are refused by name
/// ([`BagError::TooManyChannels`]) and their messages counted as lost; every consumer (check,
/// mesh, replay, play) shares this limit.
pub const MAX_CHANNELS: usize = 256;

/// Most bytes of schema text kept for the whole bag (all schemas together): 16 MiB. A schema
/// beyond it is refused as malformed, and messages of its channels are counted as lost.
pub const MAX_SCHEMA_BYTES: usize = 16 << 20;

/// Recent chunks (and unchunked messages) remembered to recognise a duplicate.
const DEDUP_WINDOW: usize = 4096;

/// Bytes read at a time while scanning for the next record after damage.
const SCAN_BLOCK: usize = 1 << 16;

/// Options of [`BagReader::open_with`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BagReadOptions {
    pub(crate) max_record_bytes: usize,
    pub(crate) max_decompressed_file_bytes: u64,
}

/// Default of [`BagReadOptions::max_decompressed_file_bytes`]: 4 GiB.
pub const DEFAULT_MAX_DECOMPRESSED_FILE_BYTES: u64 = 4 << 30;

impl Default for BagReadOptions {
    /// The defaults; `CHRONOTOPE_MAX_DECOMPRESSED_GB` (a number of GiB), if set, replaces
    /// [`DEFAULT_MAX_DECOMPRESSED_FILE_BYTES`].
    fn default() -> Self {
        Self {
            max_record_bytes: DEFAULT_MAX_RECORD_BYTES,
            max_decompressed_file_bytes: max_decompressed_from_env(),
        }
    }
}

/// The environment variable that sets the temporary copy's cap, in GiB.
pub const MAX_DECOMPRESSED_ENV: &str = "CHRONOTOPE_MAX_DECOMPRESSED_GB";

/// [`DEFAULT_MAX_DECOMPRESSED_FILE_BYTES`], or what [`MAX_DECOMPRESSED_ENV`] says (a
/// non-negative number of GiB; anything else is ignored with a warning, once).
fn max_decompressed_from_env() -> u64 {
    static VALUE: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *VALUE.get_or_init(|| {
        let Some(v) = std::env::var_os(MAX_DECOMPRESSED_ENV) else {
            return DEFAULT_MAX_DECOMPRESSED_FILE_BYTES;
        };
        match v.to_str().and_then(|s| s.trim().parse::<f64>().ok()) {
            Some(gb) if gb.is_finite() && gb >= 0.0 && gb < 1e9 => {
                (gb * (1u64 << 30) as f64) as u64
            }
            _ => {
                tracing::warn!(
                    "{MAX_DECOMPRESSED_ENV}={}: not a number of GiB; using the default {} GiB",
                    chronotope_yaml::quote(&v.to_string_lossy()),
                    DEFAULT_MAX_DECOMPRESSED_FILE_BYTES >> 30
                );
                DEFAULT_MAX_DECOMPRESSED_FILE_BYTES
            }
        }
    })
}

impl BagReadOptions {
    /// The defaults: records up to [`DEFAULT_MAX_RECORD_BYTES`].
    pub fn new() -> Self {
        Self::default()
    }

    /// The largest record (a message, or a chunk compressed or decompressed) the reader will
    /// buffer. A length field above it is reported as [`BagError::RecordTooLarge`] instead of
    /// being allocated, so a corrupt file cannot make the reader allocate more than this.
    pub fn max_record_bytes(mut self, max_record_bytes: usize) -> Self {
        self.max_record_bytes = max_record_bytes;
        self
    }

    /// The largest size a whole-file-compressed split file (`.mcap.zstd`, `.db3.zstd`) may
    /// decompress to. It is decompressed into a temporary copy without a name (in `TMPDIR`),
    /// whose space is freed once the file has been read or the process ends, however it
    /// ends. The copy may also take at most half the space free in `TMPDIR`. A file whose
    /// zstd header declares more is refused before anything is written; one that turns out
    /// larger is refused when it passes the cap. Either way the split file is skipped and
    /// reported, so a hostile file cannot fill the disk.
    pub fn max_decompressed_file_bytes(mut self, bytes: u64) -> Self {
        self.max_decompressed_file_bytes = bytes;
        self
    }
}

/// A schema as a bag defines it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagSchema {
    /// Its id in the file.
    pub id: u16,
    /// Its name (`pkg/msg/Type`).
    pub name: String,
    /// Its encoding (`ros2msg` in rosbag2 files).
    pub encoding: String,
    /// Its text (for `ros2msg`: the rosbag2 concatenated `.msg` definitions).
    pub data: Vec<u8>,
}

/// One message of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagMessage {
    /// The channel's topic.
    pub topic: String,
    /// The channel's id in the file.
    pub channel_id: u16,
    /// The channel's schema name (`pkg/msg/Type`), empty for a channel without schema.
    pub schema_name: String,
    /// The channel's schema, `None` for a channel without schema.
    pub schema: Option<Arc<BagSchema>>,
    /// The channel's message encoding (`cdr` in rosbag2 files).
    pub message_encoding: String,
    /// Log (receive) time, nanoseconds since the epoch.
    pub log_time_ns: u64,
    /// Publish time, nanoseconds since the epoch.
    pub publish_time_ns: u64,
    /// The message's sequence number as the writer recorded it.
    pub sequence: u32,
    /// The serialised message (for `cdr`: encapsulation header and body).
    pub data: Vec<u8>,
}

/// A channel as the reader knows it.
#[derive(Debug, Clone, PartialEq, Eq)]
struct ChannelInfo {
    topic: String,
    schema_id: u16,
    message_encoding: String,
}

/// A channel of the bag, as [`BagReader::channels`] lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagChannel {
    /// Its id in the file.
    pub id: u16,
    /// Its topic.
    pub topic: String,
    /// Its schema's name, empty if it has none (or the schema is not defined).
    pub schema_name: String,
    /// Its message encoding.
    pub message_encoding: String,
}

/// Anything the reader can read from.
trait Source: Read + Seek + Send {}
impl<T: Read + Seek + Send> Source for T {}

/// Reads the messages of an MCAP file in file order, streaming: memory stays at about one
/// chunk compressed plus one decompressed (or one unchunked message), however large the file.
///
/// The reader is an iterator of `Result<BagMessage, BagError>`. Damage is yielded as errors
/// and reading goes on past it to everything the file's structure still allows (see the module
/// documentation); only truncation and I/O errors end the iteration ([`BagError::is_fatal`]).
/// What was lost is summed up by [`BagReader::recovery`]. No content of the file can make it
/// panic, and every length field is checked against the data present or against
/// [`BagReadOptions::max_record_bytes`] before anything is allocated.
///
/// ```no_run
/// use chronotope_bag::BagReader;
/// let mut reader = BagReader::open("in.mcap")?;
/// for message in reader.by_ref() {
///     match message {
///         Ok(m) => println!("{} {} {} bytes", m.topic, m.log_time_ns, m.data.len()),
///         Err(e) => eprintln!("{e}"),
///     }
/// }
/// println!("{} messages lost", reader.recovery().messages_lost);
/// # Ok::<(), chronotope_bag::BagError>(())
/// ```
pub struct McapReader {
    src: BufReader<Box<dyn Source>>,
    /// Where `src` is positioned.
    cursor: u64,
    /// File length.
    len: u64,
    path: PathBuf,
    limit: usize,
    profile: String,
    /// File offset of the next top-level record.
    pos: u64,
    /// Where the data section ends: the summary's start if it is used, else the file's end.
    data_end: u64,
    /// True if the file ends with a footer and the magic (so it is not truncated).
    tail_ok: bool,
    /// Chunk indexes of the summary, by chunk offset.
    chunk_index: std::collections::BTreeMap<u64, ChunkIndexRecord>,
    schemas: HashMap<u16, Arc<BagSchema>>,
    schema_bytes: usize,
    channels: HashMap<u16, ChannelInfo>,
    /// Loss entry (index into `recovery.losses`, if listed) of each channel whose messages are
    /// not delivered: undefined, refused (too many channels) or with an undefined schema.
    channel_losses: HashMap<u16, Option<usize>>,
    refused_channels: HashSet<u16>,
    chunk: Option<ChunkCursor>,
    seen_chunks: RecentSet,
    seen_messages: RecentSet,
    recovery: Recovery,
    /// After a lost chunk: its messages delivered so far per channel; the Message Index records
    /// that follow it complete the loss's counts.
    awaiting_index: Option<HashMap<u16, u64>>,
    /// Bytes the scan for the next record may still inspect closely (bounds the work on a
    /// hostile file to a few times its size).
    scan_budget: u64,
    pending: VecDeque<BagError>,
    done: bool,
    /// The chunk being read carries CRC 0: its messages are not verified.
    chunk_crc_zero: bool,
}

/// The records of one chunk, decompressed (and CRC-checked) by a reader of its own, so that a
/// bad chunk costs only its own messages.
struct ChunkCursor {
    reader: LinearReader,
    offset: u64,
    index: usize,
    start_ns: u64,
    end_ns: u64,
    delivered: HashMap<u16, u64>,
    /// The chunk index says the chunk holds no message.
    indexed_empty: bool,
}

/// A bounded set of recent hashes.
#[derive(Default)]
struct RecentSet {
    order: VecDeque<u64>,
    set: HashSet<u64>,
}

impl RecentSet {
    /// Adds `key`; false if it was already there.
    fn insert(&mut self, key: u64) -> bool {
        if !self.set.insert(key) {
            return false;
        }
        self.order.push_back(key);
        if self.order.len() > DEDUP_WINDOW {
            if let Some(old) = self.order.pop_front() {
                self.set.remove(&old);
            }
        }
        true
    }
}

impl McapReader {
    /// Opens an MCAP file with the default options and reads its header and summary.
    ///
    /// # Errors
    ///
    /// [`BagError::Io`] if the file cannot be opened, [`BagError::NotMcap`] if it does not
    /// start with the MCAP magic and a Header record, [`BagError::Truncated`] if it ends first.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, BagError> {
        Self::open_with(path, BagReadOptions::default())
    }

    /// Opens an MCAP file with the given options and reads its header and summary.
    ///
    /// # Errors
    ///
    /// As [`BagReader::open`].
    pub fn open_with(path: impl AsRef<Path>, options: BagReadOptions) -> Result<Self, BagError> {
        let path = path.as_ref().to_path_buf();
        let file = File::open(&path).map_err(|source| BagError::Io {
            path: path.clone(),
            action: "cannot open the bag",
            source,
        })?;
        let meta = file.metadata().map_err(|source| BagError::Io {
            path: path.clone(),
            action: "cannot read the bag",
            source,
        })?;
        if !meta.is_file() {
            return Err(BagError::NotMcap {
                path,
                reason: "it is not a regular file".to_owned(),
            });
        }
        Self::from_source(Box::new(file), path, options)
    }

    /// A reader of an MCAP file held in memory; errors name the file as `name`.
    ///
    /// # Errors
    ///
    /// As [`BagReader::open`].
    pub fn from_bytes(bytes: Vec<u8>, name: impl Into<PathBuf>) -> Result<Self, BagError> {
        Self::from_source(
            Box::new(Cursor::new(bytes)),
            name.into(),
            BagReadOptions::default(),
        )
    }

    /// A reader of any seekable source holding an MCAP file; errors name it as `name`.
    ///
    /// # Errors
    ///
    /// As [`BagReader::open`].
    pub fn from_reader(
        source: impl Read + Seek + Send + 'static,
        name: impl Into<PathBuf>,
        options: BagReadOptions,
    ) -> Result<Self, BagError> {
        Self::from_source(Box::new(source), name.into(), options)
    }

    fn from_source(
        mut source: Box<dyn Source>,
        path: PathBuf,
        options: BagReadOptions,
    ) -> Result<Self, BagError> {
        let io = |path: &PathBuf, source| BagError::Io {
            path: path.clone(),
            action: "cannot read the bag",
            source,
        };
        let len = source.seek(SeekFrom::End(0)).map_err(|e| io(&path, e))?;
        source.seek(SeekFrom::Start(0)).map_err(|e| io(&path, e))?;
        let mut src = BufReader::with_capacity(256 << 10, source);
        let mut magic = [0u8; MAGIC.len()];
        let got = read_full(&mut src, &mut magic).map_err(|e| io(&path, e))?;
        if got < MAGIC.len() {
            return Err(BagError::NotMcap {
                path,
                reason: format!("the file is {got} bytes long, shorter than the 8-byte MCAP magic"),
            });
        }
        if magic != MAGIC {
            return Err(BagError::NotMcap {
                path,
                reason: format!(
                    "it starts with {magic:02x?} instead of the MCAP magic {MAGIC:02x?}"
                ),
            });
        }
        let limit = options.max_record_bytes;
        let summary = read_summary(&mut src, len, limit).map_err(|e| io(&path, e))?;
        let mut reader = Self {
            src,
            cursor: u64::MAX,
            len,
            path,
            limit,
            profile: String::new(),
            pos: MAGIC.len() as u64,
            data_end: len,
            tail_ok: summary.tail_ok,
            chunk_index: Default::default(),
            schemas: HashMap::new(),
            schema_bytes: 0,
            channels: HashMap::new(),
            channel_losses: HashMap::new(),
            refused_channels: HashSet::new(),
            chunk: None,
            seen_chunks: RecentSet::default(),
            seen_messages: RecentSet::default(),
            recovery: Recovery::default(),
            awaiting_index: None,
            scan_budget: len.saturating_mul(4).saturating_add(64 << 20),
            pending: VecDeque::new(),
            done: false,
            chunk_crc_zero: false,
        };
        reader.read_header()?;
        // Schemas and channels from the summary, whether or not the rest of it is usable: they
        // are the same records the data section holds (MCAP requires it).
        for s in summary.schemas {
            reader.define_schema(s.id, s.name, s.encoding, &s.data);
        }
        for c in summary.channels {
            reader.define_channel(c.id, c.topic, c.schema_id, c.message_encoding, None);
        }
        reader.recovery.statistics_message_count = summary.message_count;
        if let (true, Some(start)) = (summary.complete, summary.summary_start) {
            reader.data_end = start;
            reader.recovery.summary_used = true;
            reader.recovery.indexed_chunks = summary.chunk_indexes.len() as u64;
            reader.chunk_index = summary
                .chunk_indexes
                .into_iter()
                .map(|c| (c.chunk_start_offset, c))
                .collect();
        }
        Ok(reader)
    }

    /// The file being read.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The profile in the file's Header record (`ros2` for rosbag2 files).
    pub fn profile(&self) -> &str {
        &self.profile
    }

    /// What reading has cost so far (complete once the iterator has ended).
    pub fn recovery(&self) -> &Recovery {
        &self.recovery
    }

    /// The channels known so far (from the summary at open, then from the data), by id.
    /// Channels refused by [`MAX_CHANNELS`] are not listed.
    pub fn channels(&self) -> Vec<BagChannel> {
        let mut out: Vec<BagChannel> = self
            .channels
            .iter()
            .map(|(id, c)| BagChannel {
                id: *id,
                topic: c.topic.clone(),
                schema_name: self
                    .schemas
                    .get(&c.schema_id)
                    .map(|s| s.name.clone())
                    .unwrap_or_default(),
                message_encoding: c.message_encoding.clone(),
            })
            .collect();
        out.sort_by_key(|c| c.id);
        out
    }

    /// The schema of channel `id`, if the channel and its schema are defined.
    pub fn schema_of(&self, id: u16) -> Option<Arc<BagSchema>> {
        let channel = self.channels.get(&id)?;
        self.schemas.get(&channel.schema_id).cloned()
    }

    /// Reads the Header record, which must come first.
    fn read_header(&mut self) -> Result<(), BagError> {
        let offset = MAGIC.len() as u64;
        let mut prefix = [0u8; RECORD_PREFIX as usize];
        let got = self.read_at(offset, &mut prefix)?;
        if got < prefix.len() {
            return Err(BagError::Truncated {
                path: self.path.clone(),
                offset: self.len,
            });
        }
        let (opcode, rlen) = split_prefix(&prefix);
        if opcode != op::HEADER {
            return Err(BagError::NotMcap {
                path: self.path.clone(),
                reason: format!(
                    "the first record (at byte {offset}) has opcode {opcode:#04x}, not that of \
                     a Header"
                ),
            });
        }
        let end = offset + RECORD_PREFIX;
        if rlen > self.len - end {
            return Err(BagError::Truncated {
                path: self.path.clone(),
                offset: self.len,
            });
        }
        if rlen > self.limit as u64 {
            return Err(BagError::NotMcap {
                path: self.path.clone(),
                reason: format!("its Header record claims {rlen} bytes"),
            });
        }
        let body = self.read_body(end, rlen)?;
        let header = records::header(&body).map_err(|reason| BagError::NotMcap {
            path: self.path.clone(),
            reason: format!("malformed Header record: {reason}"),
        })?;
        self.profile = header.profile;
        self.pos = end + rlen;
        Ok(())
    }

    fn io_error(&self, source: std::io::Error) -> BagError {
        BagError::Io {
            path: self.path.clone(),
            action: "cannot read the bag",
            source,
        }
    }

    /// Reads up to `buf.len()` bytes at `offset`; returns how many (fewer at the end).
    fn read_at(&mut self, offset: u64, buf: &mut [u8]) -> Result<usize, BagError> {
        if self.cursor != offset {
            if let Err(e) = self.src.seek(SeekFrom::Start(offset)) {
                self.cursor = u64::MAX;
                return Err(self.io_error(e));
            }
        }
        match read_full(&mut self.src, buf) {
            Ok(n) => {
                self.cursor = offset + n as u64;
                Ok(n)
            }
            Err(e) => {
                self.cursor = u64::MAX;
                Err(self.io_error(e))
            }
        }
    }

    /// Reads `len` bytes at `offset`; the caller has checked they are in the file and within
    /// the limit.
    fn read_body(&mut self, offset: u64, len: u64) -> Result<Vec<u8>, BagError> {
        let mut body = vec![0u8; usize::try_from(len).unwrap_or(0)];
        let got = self.read_at(offset, &mut body)?;
        if got < body.len() {
            return Err(BagError::Truncated {
                path: self.path.clone(),
                offset: offset + got as u64,
            });
        }
        Ok(body)
    }

    fn define_schema(&mut self, id: u16, name: String, encoding: String, data: &[u8]) -> bool {
        if let Some(existing) = self.schemas.get(&id) {
            return existing.name == name && existing.encoding == encoding && existing.data == data;
        }
        if self.schema_bytes + data.len() > MAX_SCHEMA_BYTES {
            return false;
        }
        self.schema_bytes += data.len();
        self.schemas.insert(
            id,
            Arc::new(BagSchema {
                id,
                name,
                encoding,
                data: data.to_vec(),
            }),
        );
        true
    }

    /// Defines a channel; false if it conflicts with an earlier definition of the same id.
    fn define_channel(
        &mut self,
        id: u16,
        topic: String,
        schema_id: u16,
        message_encoding: String,
        offset: Option<u64>,
    ) -> bool {
        let info = ChannelInfo {
            topic,
            schema_id,
            message_encoding,
        };
        if let Some(existing) = self.channels.get(&id) {
            return *existing == info;
        }
        if self.refused_channels.contains(&id) {
            return true;
        }
        if self.channels.len() >= MAX_CHANNELS {
            self.refused_channels.insert(id);
            let first = self.refused_channels.len() == 1;
            self.start_channel_loss(
                id,
                LossKind::TooManyChannels,
                offset.unwrap_or(0),
                format!(
                    "channel {id} ({}) is beyond the limit of MAX_CHANNELS = {MAX_CHANNELS} \
                     channels per bag; its messages are not read",
                    info.topic
                ),
                &info.topic,
            );
            if first {
                self.pending.push_back(BagError::TooManyChannels {
                    path: self.path.clone(),
                    limit: MAX_CHANNELS,
                    topic: info.topic,
                });
            }
            return true;
        }
        self.channels.insert(id, info);
        true
    }

    /// Opens the loss entry of a channel whose messages are not delivered.
    fn start_channel_loss(
        &mut self,
        id: u16,
        kind: LossKind,
        offset: u64,
        reason: String,
        topic: &str,
    ) {
        let listed = self.recovery.losses.len();
        self.recovery.push(BagLoss {
            offset,
            bytes: None,
            kind,
            reason,
            messages: Some(0),
            start_ns: None,
            end_ns: None,
            topics: std::iter::once((topic.to_owned(), 0)).collect(),
        });
        let index = (self.recovery.losses.len() > listed).then_some(listed);
        self.channel_losses.insert(id, index);
    }

    /// Counts one message of a channel whose messages are not delivered.
    fn count_channel_loss(&mut self, id: u16, log_time: u64) {
        self.recovery.messages_lost += 1;
        let Some(Some(index)) = self.channel_losses.get(&id) else {
            return;
        };
        if let Some(loss) = self.recovery.losses.get_mut(*index) {
            loss.messages = Some(loss.messages.unwrap_or(0) + 1);
            loss.start_ns = Some(loss.start_ns.map_or(log_time, |s| s.min(log_time)));
            loss.end_ns = Some(loss.end_ns.map_or(log_time, |e| e.max(log_time)));
            if let Some(n) = loss.topics.values_mut().next() {
                *n += 1;
            }
        }
    }

    /// Records a lost region or chunk; its counts are completed by the Message Index records
    /// that follow it, if any.
    #[allow(clippy::too_many_arguments)]
    fn lose(
        &mut self,
        offset: u64,
        bytes: Option<u64>,
        kind: LossKind,
        reason: String,
        span: Option<(u64, u64)>,
        delivered: HashMap<u16, u64>,
    ) {
        self.recovery.push(BagLoss {
            offset,
            bytes,
            kind,
            reason,
            messages: None,
            start_ns: span.map(|s| s.0),
            end_ns: span.map(|s| s.1),
            topics: Default::default(),
        });
        self.awaiting_index = Some(delivered);
    }

    /// Takes in one record (not a chunk) found at `location`; returns a message or an error to
    /// yield, if any.
    fn record(
        &mut self,
        opcode: u8,
        body: &[u8],
        location: RecordLocation,
    ) -> Option<Result<BagMessage, BagError>> {
        let bad = |path: &PathBuf, kind: &'static str, reason: String| BagError::BadRecord {
            path: path.clone(),
            location,
            kind,
            reason,
        };
        match opcode {
            op::SCHEMA => match records::schema(body) {
                Ok(s) => {
                    let id = s.id;
                    if self.define_schema(s.id, s.name, s.encoding, s.data) {
                        None
                    } else {
                        Some(Err(bad(
                            &self.path,
                            "Schema",
                            format!(
                                "schema {id} conflicts with an earlier definition, or the \
                                 schemas exceed MAX_SCHEMA_BYTES = {MAX_SCHEMA_BYTES} bytes; \
                                 the first definition is kept"
                            ),
                        )))
                    }
                }
                Err(reason) => Some(Err(bad(&self.path, "Schema", reason))),
            },
            op::CHANNEL => match records::channel(body) {
                Ok(c) => {
                    let id = c.id;
                    if self.define_channel(
                        c.id,
                        c.topic,
                        c.schema_id,
                        c.message_encoding,
                        Some(location.file_offset()),
                    ) {
                        None
                    } else {
                        Some(Err(bad(
                            &self.path,
                            "Channel",
                            format!(
                                "channel {id} conflicts with an earlier definition; the first \
                                 definition is kept"
                            ),
                        )))
                    }
                }
                Err(reason) => Some(Err(bad(&self.path, "Channel", reason))),
            },
            op::MESSAGE => self.message(body, location),
            _ => None,
        }
    }

    fn message(
        &mut self,
        body: &[u8],
        location: RecordLocation,
    ) -> Option<Result<BagMessage, BagError>> {
        let message = match records::message(body) {
            Ok(m) => m,
            Err(reason) => {
                return Some(Err(BagError::BadRecord {
                    path: self.path.clone(),
                    location,
                    kind: "Message",
                    reason,
                }))
            }
        };
        let id = message.channel_id;
        if self.channel_losses.contains_key(&id) {
            self.count_channel_loss(id, message.log_time);
            return None;
        }
        let Some(channel) = self.channels.get(&id) else {
            self.start_channel_loss(
                id,
                LossKind::UndefinedChannel,
                location.file_offset(),
                format!("messages on channel {id}, which no Channel record defines"),
                &format!("channel {id}"),
            );
            self.count_channel_loss(id, message.log_time);
            return Some(Err(BagError::UnknownChannel {
                path: self.path.clone(),
                location,
                channel_id: id,
            }));
        };
        let schema = match channel.schema_id {
            0 => None,
            sid => match self.schemas.get(&sid) {
                Some(s) => Some(s.clone()),
                None => {
                    let topic = channel.topic.clone();
                    self.start_channel_loss(
                        id,
                        LossKind::UndefinedSchema,
                        location.file_offset(),
                        format!("messages on {topic}, whose schema {sid} no Schema record defines"),
                        &topic,
                    );
                    self.count_channel_loss(id, message.log_time);
                    return Some(Err(BagError::UnknownSchema {
                        path: self.path.clone(),
                        location,
                        topic,
                        schema_id: sid,
                    }));
                }
            },
        };
        if let RecordLocation::File { .. } = location {
            // Outside chunks there is no CRC to tell a duplicated range: remember recent
            // messages instead.
            let mut h = DefaultHasher::new();
            (id, message.sequence, message.log_time, message.publish_time).hash(&mut h);
            message.data.len().hash(&mut h);
            message.data[..message.data.len().min(64)].hash(&mut h);
            message.data[message.data.len().saturating_sub(64)..].hash(&mut h);
            if !self.seen_messages.insert(h.finish()) {
                self.recovery.push(BagLoss {
                    offset: location.file_offset(),
                    bytes: Some(body.len() as u64 + RECORD_PREFIX),
                    kind: LossKind::DuplicateMessage,
                    reason: format!(
                        "a copy of a message of {} just read; not delivered twice",
                        channel.topic
                    ),
                    messages: Some(0),
                    start_ns: Some(message.log_time),
                    end_ns: Some(message.log_time),
                    topics: Default::default(),
                });
                return Some(Err(BagError::Duplicate {
                    path: self.path.clone(),
                    offset: location.file_offset(),
                    what: "message",
                }));
            }
        }
        self.recovery.messages_read += 1;
        match location {
            RecordLocation::File { .. } => self
                .recovery
                .note_unverified(&self.path, super::recovery::NO_CRC_UNCHUNKED),
            RecordLocation::Chunk { .. } if self.chunk_crc_zero => self
                .recovery
                .note_unverified(&self.path, super::recovery::NO_CRC_CHUNK),
            RecordLocation::Chunk { .. } => {}
        }
        Some(Ok(BagMessage {
            topic: channel.topic.clone(),
            channel_id: id,
            schema_name: schema.as_ref().map(|s| s.name.clone()).unwrap_or_default(),
            schema,
            message_encoding: channel.message_encoding.clone(),
            log_time_ns: message.log_time,
            publish_time_ns: message.publish_time,
            sequence: message.sequence,
            data: message.data.to_vec(),
        }))
    }

    /// Sets up reading of the chunk record `body` found at `offset`; on failure records the
    /// loss and returns the error to yield.
    fn start_chunk(
        &mut self,
        offset: u64,
        body: &[u8],
        index: Option<&ChunkIndexRecord>,
    ) -> Result<(), BagError> {
        let index_span = index.map(|c| (c.message_start_time, c.message_end_time));
        let indexed_empty = index.is_some_and(|c| c.message_index_channels == 0);
        let record_len = Some(body.len() as u64 + RECORD_PREFIX);
        let chunk = match records::chunk(body) {
            Ok(c) => c,
            Err(reason) => {
                let kind = if body.iter().all(|b| *b == 0) {
                    LossKind::ZeroFilled
                } else {
                    LossKind::ChunkMalformed
                };
                let reason = if kind == LossKind::ZeroFilled {
                    "the chunk is zero-filled".to_owned()
                } else {
                    format!("malformed chunk header: {reason}")
                };
                self.lose(
                    offset,
                    record_len,
                    kind,
                    reason.clone(),
                    index_span,
                    HashMap::new(),
                );
                if indexed_empty {
                    self.recovery.last_costs_nothing();
                }
                return Err(BagError::CorruptChunk {
                    path: self.path.clone(),
                    offset,
                    reason,
                });
            }
        };
        let span = Some((chunk.message_start_time, chunk.message_end_time));
        let mut h = DefaultHasher::new();
        (
            chunk.message_start_time,
            chunk.message_end_time,
            chunk.uncompressed_size,
            chunk.uncompressed_crc,
            &chunk.compression,
            chunk.records.len(),
        )
            .hash(&mut h);
        if chunk.uncompressed_crc == 0 {
            chunk.records.hash(&mut h);
        } else {
            chunk.records[..chunk.records.len().min(256)].hash(&mut h);
        }
        if !self.seen_chunks.insert(h.finish()) {
            self.lose(
                offset,
                record_len,
                LossKind::DuplicateChunk,
                "a copy of a chunk already read; its messages are not delivered twice".to_owned(),
                span,
                HashMap::new(),
            );
            // The copy's messages were delivered once: nothing is lost.
            self.recovery.last_costs_nothing();
            self.awaiting_index = None;
            return Err(BagError::Duplicate {
                path: self.path.clone(),
                offset,
                what: "chunk",
            });
        }
        let fail = |this: &mut Self, kind: LossKind, reason: String| {
            this.lose(
                offset,
                record_len,
                kind,
                reason.clone(),
                span,
                HashMap::new(),
            );
            if indexed_empty {
                this.recovery.last_costs_nothing();
            }
            BagError::CorruptChunk {
                path: this.path.clone(),
                offset,
                reason,
            }
        };
        if chunk.uncompressed_size > self.limit as u64 {
            let len = chunk.uncompressed_size;
            self.lose(
                offset,
                record_len,
                LossKind::RecordTooLarge,
                format!(
                    "the chunk decompresses to {len} bytes, more than the reader's limit of {} \
                     bytes",
                    self.limit
                ),
                span,
                HashMap::new(),
            );
            return Err(BagError::RecordTooLarge {
                path: self.path.clone(),
                offset,
                opcode: op::CHUNK,
                len,
                limit: self.limit,
            });
        }
        match chunk.compression.as_str() {
            // Checked here because the mcap reader trusts the record lengths of uncompressed
            // chunks once the data is there.
            "" => {
                if let Err(reason) = records::check_framing(chunk.records) {
                    return Err(fail(self, LossKind::ChunkMalformed, reason));
                }
            }
            "zstd" | "lz4" => {}
            other => {
                let reason =
                    format!("unsupported compression {other:?} (zstd, lz4 and none are read)");
                return Err(fail(self, LossKind::ChunkDecompression, reason));
            }
        }
        let reader = chunk_reader(body, self.limit);
        self.chunk_crc_zero = chunk.uncompressed_crc == 0;
        self.chunk = Some(ChunkCursor {
            reader,
            offset,
            index: 0,
            start_ns: chunk.message_start_time,
            end_ns: chunk.message_end_time,
            delivered: HashMap::new(),
            indexed_empty,
        });
        Ok(())
    }

    /// The next step in the chunk being read ([`Step::End`] if no chunk is open).
    fn next_in_chunk(&mut self) -> Step {
        // Taken out while its record is handled, so the record can borrow from its buffer.
        let Some(mut chunk) = self.chunk.take() else {
            return Step::End;
        };
        let out = match chunk.reader.next_event() {
            None => return Step::More,
            // The whole chunk was handed over at the start: tell the reader that is all.
            Some(Ok(LinearReadEvent::ReadRequest(_))) => {
                chunk.reader.notify_read(0);
                None
            }
            Some(Ok(LinearReadEvent::Record { opcode, data })) => {
                let location = RecordLocation::Chunk {
                    chunk_offset: chunk.offset,
                    index: chunk.index,
                };
                chunk.index += 1;
                let item = self.record(opcode, data, location);
                if let Some(Ok(m)) = &item {
                    *chunk.delivered.entry(m.channel_id).or_default() += 1;
                }
                item
            }
            Some(Err(err)) => {
                let kind = match &err {
                    McapError::BadChunkCrc { .. } => LossKind::ChunkCrc,
                    McapError::DecompressionError(_)
                    | McapError::UnsupportedCompression(_)
                    | McapError::Io(_) => LossKind::ChunkDecompression,
                    _ => LossKind::ChunkMalformed,
                };
                let reason = match &err {
                    McapError::BadChunkCrc { saved, calculated } => format!(
                        "the chunk fails its CRC (stored {saved:#010x}, computed {calculated:#010x})"
                    ),
                    other => other.to_string(),
                };
                self.lose(
                    chunk.offset,
                    None,
                    kind,
                    reason.clone(),
                    Some((chunk.start_ns, chunk.end_ns)),
                    chunk.delivered,
                );
                if chunk.indexed_empty {
                    self.recovery.last_costs_nothing();
                }
                return Step::Damage(BagError::CorruptChunk {
                    path: self.path.clone(),
                    offset: chunk.offset,
                    reason,
                });
            }
        };
        self.chunk = Some(chunk);
        out.into()
    }

    /// Reads the next top-level record; returns what to yield, if anything.
    fn step(&mut self) -> Result<Step, BagError> {
        let pos = self.pos;
        if pos >= self.data_end {
            self.done = true;
            if !self.recovery.summary_used {
                // Without a footer, the file was cut.
                return Err(self.truncated());
            }
            return Ok(Step::End);
        }
        let mut prefix = [0u8; RECORD_PREFIX as usize];
        let got = self.read_at(pos, &mut prefix)?;
        let index = self.chunk_index.get(&pos).cloned();
        if let Some(index) = index {
            // The index knows this chunk: read it with the index's length, whatever the
            // record's own length field says.
            if index.chunk_length - RECORD_PREFIX > self.limit as u64 {
                self.pos = pos + index.chunk_length;
                let len = index.chunk_length - RECORD_PREFIX;
                self.lose(
                    pos,
                    Some(index.chunk_length),
                    LossKind::RecordTooLarge,
                    format!(
                        "the chunk is {len} bytes, more than the reader's limit of {} bytes",
                        self.limit
                    ),
                    Some((index.message_start_time, index.message_end_time)),
                    HashMap::new(),
                );
                return Ok(Step::Damage(BagError::RecordTooLarge {
                    path: self.path.clone(),
                    offset: pos,
                    opcode: op::CHUNK,
                    len,
                    limit: self.limit,
                }));
            }
            let body = self.read_body(pos + RECORD_PREFIX, index.chunk_length - RECORD_PREFIX)?;
            self.pos = pos + index.chunk_length;
            self.end_awaiting();
            return Ok(self
                .start_chunk(pos, &body, Some(&index))
                .err()
                .map_or(Step::More, Step::Damage));
        }
        if got < prefix.len() {
            self.done = true;
            return Err(self.truncated());
        }
        let (opcode, rlen) = split_prefix(&prefix);
        let room = self.data_end - pos - RECORD_PREFIX.min(self.data_end - pos);
        if !records::known_opcode(opcode) || rlen > room || rlen > self.limit as u64 {
            return self.skip_damage(pos, opcode, rlen);
        }
        let body = self.read_body(pos + RECORD_PREFIX, rlen)?;
        self.pos = pos + RECORD_PREFIX + rlen;
        match opcode {
            op::CHUNK => {
                self.end_awaiting();
                Ok(self
                    .start_chunk(pos, &body, None)
                    .err()
                    .map_or(Step::More, Step::Damage))
            }
            op::MESSAGE_INDEX => {
                if self.awaiting_index.is_some() {
                    if let Ok(mi) = records::message_index(&body) {
                        let delivered = self
                            .awaiting_index
                            .as_ref()
                            .and_then(|d| d.get(&mi.channel_id))
                            .copied()
                            .unwrap_or(0);
                        let topic = self
                            .channels
                            .get(&mi.channel_id)
                            .map(|c| c.topic.clone())
                            .unwrap_or_else(|| format!("channel {}", mi.channel_id));
                        self.recovery.add_to_last(
                            &topic,
                            mi.count.saturating_sub(delivered),
                            mi.first_time,
                            mi.last_time,
                        );
                    }
                }
                Ok(Step::More)
            }
            op::FOOTER => {
                self.done = true;
                if self.tail_ok && self.pos + MAGIC.len() as u64 == self.len {
                    Ok(Step::End)
                } else if self.pos + MAGIC.len() as u64 > self.len {
                    Err(self.truncated())
                } else {
                    Err(BagError::Corrupt {
                        path: self.path.clone(),
                        offset: pos,
                        reason: "the footer is not followed by the MCAP magic that ends the file"
                            .to_owned(),
                    })
                }
            }
            _ => {
                self.end_awaiting();
                Ok(self
                    .record(opcode, &body, RecordLocation::File { offset: pos })
                    .into())
            }
        }
    }

    fn end_awaiting(&mut self) {
        self.awaiting_index = None;
    }

    fn truncated(&self) -> BagError {
        BagError::Truncated {
            path: self.path.clone(),
            offset: self.len,
        }
    }

    /// The record at `pos` cannot be framed: skip to the next readable record and say what
    /// was skipped.
    fn skip_damage(&mut self, pos: u64, opcode: u8, rlen: u64) -> Result<Step, BagError> {
        self.end_awaiting();
        let next = self.resync(pos + 1)?;
        let (kind, what) = if opcode == 0 && rlen == 0 {
            (LossKind::ZeroFilled, "zero bytes".to_owned())
        } else if !records::known_opcode(opcode) {
            (
                LossKind::Garbage,
                format!("opcode {opcode:#04x}, which no MCAP record has"),
            )
        } else if rlen > self.limit as u64 {
            (
                LossKind::RecordTooLarge,
                format!(
                    "a record (opcode {opcode:#04x}) claiming {rlen} bytes, more than the \
                     reader's limit of {} bytes",
                    self.limit
                ),
            )
        } else {
            (
                LossKind::BadLength,
                format!(
                    "a record (opcode {opcode:#04x}) claiming {rlen} bytes, more than the {} \
                     bytes left",
                    self.data_end.saturating_sub(pos + RECORD_PREFIX)
                ),
            )
        };
        let Some(next) = next else {
            if !self.tail_ok && !self.recovery.summary_used {
                // Nothing readable follows and the file has no footer: it was cut here (or
                // damaged up to its cut end).
                self.done = true;
                if kind == LossKind::RecordTooLarge {
                    self.pending.push_back(self.truncated());
                    return Err(BagError::RecordTooLarge {
                        path: self.path.clone(),
                        offset: pos,
                        opcode,
                        len: rlen,
                        limit: self.limit,
                    });
                }
                self.recovery.push(BagLoss {
                    offset: pos,
                    bytes: Some(self.len - pos),
                    kind: LossKind::Truncated,
                    reason: "the file ends in the middle of a record".to_owned(),
                    messages: None,
                    start_ns: None,
                    end_ns: None,
                    topics: Default::default(),
                });
                return Err(self.truncated());
            }
            let end = self.data_end;
            self.lose(
                pos,
                Some(end - pos),
                kind,
                format!("{what}; nothing readable follows"),
                None,
                HashMap::new(),
            );
            self.pos = end;
            self.done = true;
            return Ok(Step::Damage(BagError::Skipped {
                path: self.path.clone(),
                offset: pos,
                bytes: end - pos,
                reason: what,
                next: None,
            }));
        };
        self.lose(
            pos,
            Some(next - pos),
            kind,
            what.clone(),
            None,
            HashMap::new(),
        );
        self.pos = next;
        if kind == LossKind::RecordTooLarge {
            return Ok(Step::Damage(BagError::RecordTooLarge {
                path: self.path.clone(),
                offset: pos,
                opcode,
                len: rlen,
                limit: self.limit,
            }));
        }
        Ok(Step::Damage(BagError::Skipped {
            path: self.path.clone(),
            offset: pos,
            bytes: next - pos,
            reason: what,
            next: Some(next),
        }))
    }

    /// The offset of the next readable record at or after `from`: the next chunk the index
    /// knows, else the first offset where a plausible record starts; `None` if there is none
    /// before the end of the data.
    fn resync(&mut self, from: u64) -> Result<Option<u64>, BagError> {
        if let Some((&next, _)) = self.chunk_index.range(from..).next() {
            return Ok(Some(next));
        }
        let end = self.data_end;
        let mut block = vec![0u8; SCAN_BLOCK + RECORD_PREFIX as usize];
        let mut base = from;
        while base + RECORD_PREFIX <= end {
            let want = ((end - base) as usize).min(block.len());
            let got = self.read_at(base, &mut block[..want])?;
            if got < RECORD_PREFIX as usize {
                break;
            }
            let last = (got - RECORD_PREFIX as usize).min(SCAN_BLOCK - 1);
            for i in 0..=last {
                let q = base + i as u64;
                if self.plausible(q, &block[..got], i)? {
                    return Ok(Some(q));
                }
                if self.scan_budget == 0 {
                    return Ok(None);
                }
            }
            base += last as u64 + 1;
        }
        Ok(None)
    }

    /// True if a record starting at file offset `q` (= `block[i]`, `block` read from
    /// `q - i`) looks real: an MCAP opcode, a length that fits, a body that parses, and
    /// either a successor that is also a record, or (for a chunk) data that decompresses and
    /// passes its CRC.
    fn plausible(&mut self, q: u64, block: &[u8], i: usize) -> Result<bool, BagError> {
        let (opcode, rlen) = split_prefix(&block[i..i + RECORD_PREFIX as usize]);
        // Smallest body of each record type: rejects runs of zeros and most noise at once.
        let min = match opcode {
            op::SCHEMA => 14,
            op::CHANNEL => 16,
            op::MESSAGE => 22,
            op::CHUNK => 48,
            op::MESSAGE_INDEX => 6,
            op::CHUNK_INDEX => 56,
            op::STATISTICS => 46,
            op::DATA_END => 4,
            op::FOOTER => 20,
            0x09..=0x0E => 1,
            _ => return Ok(false),
        };
        let body_at = q + RECORD_PREFIX;
        if rlen < min || rlen > self.limit as u64 || rlen > self.data_end.saturating_sub(body_at) {
            return Ok(false);
        }
        let next = body_at + rlen;
        let rlen_usize = rlen as usize;
        let in_block = |at: u64, n: usize| -> Option<std::ops::Range<usize>> {
            let start = usize::try_from(at - (q - i as u64)).ok()?;
            (start.checked_add(n)? <= block.len()).then(|| start..start + n)
        };
        let body: std::borrow::Cow<'_, [u8]> = match in_block(body_at, rlen_usize) {
            Some(r) => std::borrow::Cow::Borrowed(&block[r]),
            None => {
                if opcode != op::CHUNK {
                    // Check the successor first: cheaper than reading a long body.
                    if !self.successor_ok(next, block, q, i)? {
                        return Ok(false);
                    }
                }
                self.scan_budget = self.scan_budget.saturating_sub(rlen.max(4096));
                std::borrow::Cow::Owned(self.read_body(body_at, rlen)?)
            }
        };
        let parses = match opcode {
            op::CHUNK => {
                let Ok(chunk) = records::chunk(&body) else {
                    return Ok(false);
                };
                if chunk.uncompressed_size > self.limit as u64
                    || !matches!(chunk.compression.as_str(), "" | "zstd" | "lz4")
                    || (chunk.compression.is_empty()
                        && records::check_framing(chunk.records).is_err())
                {
                    return Ok(false);
                }
                self.scan_budget = self.scan_budget.saturating_sub(chunk.uncompressed_size);
                let mut reader = chunk_reader(&body, self.limit);
                // Only a chunk that decompresses and passes its CRC.
                return Ok(loop {
                    match reader.next_event() {
                        Some(Ok(LinearReadEvent::ReadRequest(_))) => reader.notify_read(0),
                        Some(Ok(LinearReadEvent::Record { .. })) | None => break true,
                        Some(Err(_)) => break false,
                    }
                });
            }
            op::FOOTER => return Ok(next + MAGIC.len() as u64 == self.len),
            op::SCHEMA => records::schema(&body).is_ok(),
            op::CHANNEL => records::channel(&body).is_ok(),
            op::MESSAGE => {
                records::message(&body).is_ok_and(|m| self.channels.contains_key(&m.channel_id))
            }
            op::MESSAGE_INDEX => records::message_index(&body).is_ok(),
            op::CHUNK_INDEX => records::chunk_index(&body).is_ok(),
            op::STATISTICS => records::statistics(&body).is_ok(),
            _ => true,
        };
        Ok(parses && self.successor_ok(next, block, q, i)?)
    }

    /// True if a record starts at `next` (or `next` is the end of the data).
    fn successor_ok(
        &mut self,
        next: u64,
        block: &[u8],
        q: u64,
        i: usize,
    ) -> Result<bool, BagError> {
        if next == self.data_end {
            return Ok(true);
        }
        let mut prefix = [0u8; RECORD_PREFIX as usize];
        let start = (next - (q - i as u64)) as usize;
        if start + prefix.len() <= block.len() {
            prefix.copy_from_slice(&block[start..start + RECORD_PREFIX as usize]);
        } else {
            self.scan_budget = self.scan_budget.saturating_sub(4096);
            if self.read_at(next, &mut prefix)? < prefix.len() {
                return Ok(false);
            }
        }
        let (op, len) = split_prefix(&prefix);
        let room = self.data_end.saturating_sub(next + RECORD_PREFIX);
        Ok(matches!(op, 0x01..=0x0F) && len <= room)
    }
}

/// What one step of the reader gives: a message, damage it read past (the reader goes on),
/// nothing yet (more to read), or the end of what it was reading (the chunk, or the file).
#[derive(Debug)]
enum Step {
    /// A message to yield.
    Message(BagMessage),
    /// A loss to report; reading goes on after it.
    Damage(BagError),
    /// Nothing to yield yet: read on.
    More,
    /// Nothing more here: no chunk is open, or the file is read.
    End,
}

impl From<Option<Result<BagMessage, BagError>>> for Step {
    /// A record's outcome: a message, damage, or nothing to yield.
    fn from(item: Option<Result<BagMessage, BagError>>) -> Self {
        match item {
            Some(Ok(m)) => Step::Message(m),
            Some(Err(e)) => Step::Damage(e),
            None => Step::More,
        }
    }
}

impl Iterator for McapReader {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(err) = self.pending.pop_front() {
                return Some(Err(err));
            }
            match self.next_in_chunk() {
                Step::Message(m) => return Some(Ok(m)),
                Step::Damage(e) => return Some(Err(e)),
                Step::More => continue,
                Step::End => {}
            }
            if self.done {
                return None;
            }
            match self.step() {
                Ok(Step::Message(m)) => return Some(Ok(m)),
                Ok(Step::Damage(e)) => return Some(Err(e)),
                Ok(Step::More | Step::End) => {}
                Err(err) => {
                    self.done = true;
                    self.chunk = None;
                    return Some(Err(err));
                }
            }
        }
    }
}

/// A reader of the records of one chunk (`body` is the chunk record's body), checking its CRC
/// before yielding anything.
fn chunk_reader(body: &[u8], limit: usize) -> LinearReader {
    let mut reader = LinearReader::new_with_options(
        LinearReaderOptions::default()
            .with_skip_start_magic(true)
            .with_skip_end_magic(true)
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(limit),
    );
    let n = RECORD_PREFIX as usize + body.len();
    let buf = reader.insert(n);
    buf[0] = op::CHUNK;
    buf[1..RECORD_PREFIX as usize].copy_from_slice(&(body.len() as u64).to_le_bytes());
    buf[RECORD_PREFIX as usize..].copy_from_slice(body);
    reader.notify_read(n);
    reader
}

/// Opcode and body length of a record prefix (9 bytes).
fn split_prefix(prefix: &[u8]) -> (u8, u64) {
    let mut len = [0u8; 8];
    len.copy_from_slice(&prefix[1..9]);
    (prefix[0], u64::from_le_bytes(len))
}

/// Reads until `buf` is full or the end of the source; returns the bytes read.
fn read_full(source: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match source.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(err) if err.kind() == std::io::ErrorKind::Interrupted => {}
            Err(err) => return Err(err),
        }
    }
    Ok(filled)
}
