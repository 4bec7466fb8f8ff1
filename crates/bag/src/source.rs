//! [`BagReader`]: the messages of whatever a bag path names, as rosbag2 writes it.
//!
//! - a single MCAP file, or a single rosbag2 SQLite file (`.db3`), or either compressed as a
//!   whole with zstd (`.mcap.zstd`, `.db3.zstd`);
//! - a rosbag2 directory (or its `metadata.yaml`): its split files in order, MCAP or SQLite,
//!   with rosbag2's `FILE` or `MESSAGE` zstd compression.
//!
//! The split files of a directory are read one after the other, each with bounded memory (one
//! MCAP chunk, or one page of SQLite rows); a file compressed as a whole is first
//! decompressed into a temporary file. A split file that is missing or cannot be read at all
//! is reported ([`BagError::SplitFile`]) and the others are read; one that ends early (a
//! truncated MCAP file, a damaged database) ends with a non-fatal
//! [`BagError::InSplitFile`] and reading goes on with the next. Channels of the split files
//! are merged by topic, type, encoding and schema text, and numbered by the reader (their ids
//! in a directory are not the files' ids); [`BagReader::recovery`] sums up the losses of every
//! file, each loss naming its file.

use std::collections::{HashMap, VecDeque};
use std::fs::File;
use std::io::{BufRead, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::error::{BagError, DecompressError};
use super::reader::{BagChannel, BagMessage, BagReadOptions, BagSchema, McapReader, MAX_CHANNELS};
use super::recovery::{BagLoss, LossKind, Recovery};
use super::rosbag2::{storage_of, Compression, Rosbag2Dir, METADATA_FILE};
use super::sqlite::{Db3Reader, SQLITE_MAGIC};
use super::summary::MAGIC;

/// The magic number of a zstd frame.
const ZSTD_MAGIC: [u8; 4] = [0x28, 0xB5, 0x2F, 0xFD];

/// What a bag path names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum BagLayout {
    /// One storage file.
    File {
        /// `mcap` or `sqlite3`.
        storage: &'static str,
        /// Compressed as a whole with zstd.
        compressed: bool,
    },
    /// A rosbag2 directory.
    Directory(Box<Rosbag2Dir>),
}

/// One storage file being read.
enum Part {
    Mcap(Box<McapReader>),
    Db3(Box<Db3Reader>),
}

impl Part {
    fn next(&mut self) -> Option<Result<BagMessage, BagError>> {
        match self {
            Part::Mcap(r) => r.next(),
            Part::Db3(r) => r.next(),
        }
    }
    fn recovery(&self) -> &Recovery {
        match self {
            Part::Mcap(r) => r.recovery(),
            Part::Db3(r) => r.recovery(),
        }
    }
    fn channels(&self) -> Vec<BagChannel> {
        match self {
            Part::Mcap(r) => r.channels(),
            Part::Db3(r) => r.channels(),
        }
    }
    fn schema_of(&self, id: u16) -> Option<Arc<BagSchema>> {
        match self {
            Part::Mcap(r) => r.schema_of(id),
            Part::Db3(r) => r.schema_of(id),
        }
    }
    fn profile(&self) -> &str {
        match self {
            Part::Mcap(r) => r.profile(),
            Part::Db3(_) => "ros2",
        }
    }
}

/// A storage file opened, with the temporary copy it was decompressed into (a file without a
/// name: its space is freed when it is dropped, after the part, or when the process dies).
struct OpenPart {
    part: Part,
    _temp: Option<File>,
}

/// What identifies a channel across split files.
#[derive(Clone, PartialEq, Eq, Hash)]
struct ChannelKey {
    topic: String,
    schema_name: String,
    schema_encoding: String,
    schema_data: Vec<u8>,
    message_encoding: String,
}

/// A channel of a directory, as merged over its split files.
struct Merged {
    channel: BagChannel,
    schema: Option<Arc<BagSchema>>,
}

/// Reads the messages of a bag, whatever form rosbag2 gave it (see the module
/// documentation), in file order, with bounded memory. An iterator of
/// `Result<BagMessage, BagError>`: damage is yielded as errors and reading goes on past it
/// as far as the bag allows; only an error that ends the whole bag is
/// [fatal](BagError::is_fatal).
///
/// ```no_run
/// use chronotope_bag::BagReader;
/// let mut reader = BagReader::open("in.mcap")?; // or a rosbag2 directory
/// for message in reader.by_ref() {
///     match message {
///         Ok(m) => println!("{} {} {} bytes", m.topic, m.log_time_ns, m.data.len()),
///         Err(e) => eprintln!("{e}"),
///     }
/// }
/// println!("{} messages lost", reader.recovery().messages_lost);
/// # Ok::<(), chronotope_bag::BagError>(())
/// ```
pub struct BagReader {
    path: PathBuf,
    options: BagReadOptions,
    layout: BagLayout,
    /// For a directory: split files not yet opened.
    files: VecDeque<PathBuf>,
    current: Option<OpenPart>,
    /// For a single file: its channels are the file's own (no merging).
    single: bool,
    /// rosbag2 per-message compression: every message's data is a zstd frame.
    message_compression: bool,
    // A directory's merged channels.
    merged: Vec<Merged>,
    keys: HashMap<ChannelKey, u16>,
    /// The current split file's channel ids -> merged ids (`None`: refused).
    part_ids: HashMap<u16, Option<u16>>,
    /// Channels refused by [`MAX_CHANNELS`] over the whole directory, by topic.
    refused_topics: HashMap<String, usize>,
    /// Losses of the split files already read (and of the directory itself).
    base: Recovery,
    /// `base` plus the current file's, made when [`Self::recovery`] is asked and dropped at
    /// every step (so that reading costs no copy of the losses per message or file).
    total: std::cell::OnceCell<Recovery>,
    /// Messages the current file counted as read that were not delivered (refused channel,
    /// not decompressing).
    undelivered: u64,
    pending: VecDeque<BagError>,
    profile: String,
    /// Messages delivered per topic, and the log times of the first and last (a directory's,
    /// to compare with its `metadata.yaml`).
    read_by_topic: HashMap<String, u64>,
    read_span: Option<(u64, u64)>,
    /// The directory's `metadata.yaml` has been compared with what was read.
    compared: bool,
    /// Topics whose messages were found compressed though nothing said so (said once each).
    compressed_topics: std::collections::HashSet<String>,
}

impl BagReader {
    /// Opens a bag with the default options (see [`BagReader::open_with`]).
    ///
    /// # Errors
    /// As [`BagReader::open_with`].
    pub fn open(path: impl AsRef<Path>) -> Result<Self, BagError> {
        Self::open_with(path, BagReadOptions::default())
    }

    /// Opens a bag: an MCAP or SQLite file (zstd-compressed or not), a rosbag2 directory, or
    /// a directory's `metadata.yaml`. A file's header and summary (or a directory's metadata
    /// and the summaries of its uncompressed split files) are read now.
    ///
    /// # Errors
    /// [`BagError::Io`] if the path cannot be opened; [`BagError::NotMcap`] if a file is none
    /// of the formats above; [`BagError::Metadata`] or [`BagError::NotABag`] for an unusable
    /// directory; the errors of the file's own reader ([`BagError::Truncated`],
    /// [`BagError::Sqlite`]) for a single file.
    pub fn open_with(path: impl AsRef<Path>, options: BagReadOptions) -> Result<Self, BagError> {
        let path = path.as_ref().to_path_buf();
        let meta = std::fs::metadata(&path).map_err(|source| BagError::Io {
            path: path.clone(),
            action: "cannot open the bag",
            source,
        })?;
        if meta.is_dir() {
            return Self::open_dir(path.clone(), &path, options);
        }
        if path.file_name().is_some_and(|n| n == METADATA_FILE) {
            let dir = path
                .parent()
                .filter(|d| !d.as_os_str().is_empty())
                .unwrap_or(Path::new("."))
                .to_path_buf();
            return Self::open_dir(path, &dir, options);
        }
        let (part, layout) = open_file(&path, &options)?;
        let mut reader = Self::single(path, options, layout, part);
        reader.message_compression = reader.lone_split_file_compressed();
        Ok(reader)
    }

    /// True if this single file is a split file of a rosbag2 directory whose `metadata.yaml`
    /// says its messages are compressed one by one: they are then decompressed as the
    /// directory would have them (and a warning says to pass the directory for all of it).
    fn lone_split_file_compressed(&self) -> bool {
        let dir = crate::fsio::parent_dir(&self.path);
        if std::fs::symlink_metadata(dir.join(METADATA_FILE)).is_err() {
            return false;
        }
        let Ok(info) = Rosbag2Dir::open(dir) else {
            return false;
        };
        let name = self.path.file_name();
        let listed = info.files.iter().any(|f| f.file_name() == name);
        if listed && info.compression == Compression::Message {
            tracing::warn!(
                "{}: a split file of the rosbag2 directory {}, whose {METADATA_FILE} says its \
                 messages are compressed one by one: decompressing them; pass the directory to \
                 read all {} split files",
                self.path.display(),
                dir.display(),
                info.files.len()
            );
            return true;
        }
        false
    }

    /// A reader of an MCAP file held in memory; errors name the file as `name`.
    ///
    /// # Errors
    /// As [`BagReader::open`] for an MCAP file.
    pub fn from_bytes(bytes: Vec<u8>, name: impl Into<PathBuf>) -> Result<Self, BagError> {
        let name = name.into();
        let reader = McapReader::from_bytes(bytes, name.clone())?;
        Ok(Self::single_mcap(name, reader))
    }

    /// A reader of any seekable source holding an MCAP file; errors name it as `name`.
    ///
    /// # Errors
    /// As [`BagReader::open`] for an MCAP file.
    pub fn from_reader(
        source: impl std::io::Read + std::io::Seek + Send + 'static,
        name: impl Into<PathBuf>,
        options: BagReadOptions,
    ) -> Result<Self, BagError> {
        let name = name.into();
        let reader = McapReader::from_reader(source, name.clone(), options)?;
        Ok(Self::single_mcap(name, reader))
    }

    fn single_mcap(path: PathBuf, reader: McapReader) -> Self {
        let layout = BagLayout::File {
            storage: "mcap",
            compressed: false,
        };
        let part = OpenPart {
            part: Part::Mcap(Box::new(reader)),
            _temp: None,
        };
        Self::single(path, BagReadOptions::default(), layout, part)
    }

    /// A reader of one storage file, already opened: its channels and losses are the file's.
    fn single(path: PathBuf, options: BagReadOptions, layout: BagLayout, part: OpenPart) -> Self {
        let profile = part.part.profile().to_owned();
        let total = part.part.recovery().clone();
        Self {
            path,
            options,
            layout,
            files: VecDeque::new(),
            current: Some(part),
            single: true,
            message_compression: false,
            merged: Vec::new(),
            keys: HashMap::new(),
            part_ids: HashMap::new(),
            refused_topics: HashMap::new(),
            base: Recovery::default(),
            total: std::cell::OnceCell::from(total),
            undelivered: 0,
            pending: VecDeque::new(),
            profile,
            read_by_topic: HashMap::new(),
            read_span: None,
            compared: true,
            compressed_topics: Default::default(),
        }
    }

    fn open_dir(path: PathBuf, dir: &Path, options: BagReadOptions) -> Result<Self, BagError> {
        let info = Rosbag2Dir::open(dir)?;
        for w in &info.warnings {
            tracing::warn!("{}: {w}", dir.display());
        }
        let mut reader = Self {
            path,
            options,
            files: info.files.iter().cloned().collect(),
            message_compression: info.compression == Compression::Message,
            layout: BagLayout::Directory(Box::new(info)),
            current: None,
            single: false,
            merged: Vec::new(),
            keys: HashMap::new(),
            part_ids: HashMap::new(),
            refused_topics: HashMap::new(),
            base: Recovery::default(),
            total: std::cell::OnceCell::new(),
            undelivered: 0,
            pending: VecDeque::new(),
            profile: "ros2".to_owned(),
            read_by_topic: HashMap::new(),
            read_span: None,
            compared: false,
            compressed_topics: Default::default(),
        };
        // The channels of every split file that opens cheaply (not compressed as a whole),
        // so that they are known before the first message, as an MCAP summary makes them.
        let mut all_summaries = true;
        let mut statistics = Some(0u64);
        for file in reader.files.clone() {
            let cheap = !file.extension().is_some_and(|e| e == "zstd")
                && reader.outside_link(&file).is_none();
            let opened = if cheap {
                open_file(&file, &options).ok().map(|(p, _)| p)
            } else {
                None
            };
            match opened {
                Some(p) => {
                    let r = p.part.recovery();
                    all_summaries &= r.summary_used;
                    statistics = statistics
                        .zip(r.statistics_message_count)
                        .map(|(a, b)| a + b);
                    for c in p.part.channels() {
                        let schema = p.part.schema_of(c.id);
                        reader.merge_channel(&c.topic, &c.message_encoding, schema.as_deref());
                    }
                }
                None => {
                    all_summaries = false;
                    statistics = None;
                }
            }
        }
        reader.base.summary_used = all_summaries && !reader.files.is_empty();
        reader.base.statistics_message_count = statistics;
        reader.sync_total();
        Ok(reader)
    }

    /// The bag's path, as given.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What the path names: a file (its storage, compressed or not) or a rosbag2 directory
    /// (with its metadata).
    pub fn layout(&self) -> &BagLayout {
        &self.layout
    }

    /// The profile of the MCAP header (`ros2` for rosbag2 files; `ros2` for SQLite files and
    /// directories).
    pub fn profile(&self) -> &str {
        &self.profile
    }

    /// What reading has cost so far, over every file (complete once the iterator has ended).
    pub fn recovery(&self) -> &Recovery {
        match (&self.current, self.single) {
            (Some(p), true) => p.part.recovery(),
            (None, _) => &self.base,
            (Some(p), false) => self.total.get_or_init(|| {
                let mut total = self.base.clone();
                add_recovery(&mut total, p.part.recovery(), &part_name(p));
                total.messages_read = total.messages_read.saturating_sub(self.undelivered);
                total
            }),
        }
    }

    /// The channels known so far, by id.
    pub fn channels(&self) -> Vec<BagChannel> {
        if self.single {
            return self
                .current
                .as_ref()
                .map(|p| p.part.channels())
                .unwrap_or_default();
        }
        self.merged.iter().map(|m| m.channel.clone()).collect()
    }

    /// The schema of channel `id`, if the channel and its schema are defined.
    pub fn schema_of(&self, id: u16) -> Option<Arc<BagSchema>> {
        if self.single {
            return self.current.as_ref()?.part.schema_of(id);
        }
        self.merged
            .get(usize::from(id).checked_sub(1)?)?
            .schema
            .clone()
    }

    /// The merged id of a channel (registering it); `None` if it is refused by
    /// [`MAX_CHANNELS`].
    fn merge_channel(
        &mut self,
        topic: &str,
        message_encoding: &str,
        schema: Option<&BagSchema>,
    ) -> Option<u16> {
        let key = ChannelKey {
            topic: topic.to_owned(),
            schema_name: schema.map(|s| s.name.clone()).unwrap_or_default(),
            schema_encoding: schema.map(|s| s.encoding.clone()).unwrap_or_default(),
            schema_data: schema.map(|s| s.data.clone()).unwrap_or_default(),
            message_encoding: message_encoding.to_owned(),
        };
        if let Some(id) = self.keys.get(&key) {
            return Some(*id);
        }
        if self.merged.len() >= MAX_CHANNELS {
            return None;
        }
        let id = self.merged.len() as u16 + 1;
        let schema = schema.map(|s| Arc::new(BagSchema { id, ..s.clone() }));
        self.merged.push(Merged {
            channel: BagChannel {
                id,
                topic: topic.to_owned(),
                schema_name: key.schema_name.clone(),
                message_encoding: message_encoding.to_owned(),
            },
            schema,
        });
        self.keys.insert(key, id);
        Some(id)
    }

    /// Opens the next split file of a directory; false when there is none.
    fn open_next(&mut self) -> bool {
        self.finish_part();
        while let Some(file) = self.files.pop_front() {
            let opened = match self.outside_link(&file) {
                Some(target) => Err(BagError::SplitFile {
                    path: file.clone(),
                    reason: format!(
                        "it is a link to {}, outside the bag directory: refused (a bag's split \
                         files are its own; copy the file into the bag, or pass it on its own)",
                        target.display()
                    ),
                }),
                None => open_file(&file, &self.options),
            };
            match opened {
                Ok(p) => {
                    self.current = Some(p.0);
                    self.part_ids.clear();
                    self.total = std::cell::OnceCell::new();
                    return true;
                }
                Err(e) => {
                    let reason = match &e {
                        BagError::Io { source, .. }
                            if source.kind() == std::io::ErrorKind::NotFound =>
                        {
                            format!("it is listed in {METADATA_FILE} but does not exist")
                        }
                        BagError::SplitFile { reason, .. } => reason.clone(),
                        _ => e.to_string(),
                    };
                    self.base.push(BagLoss {
                        offset: 0,
                        bytes: None,
                        kind: LossKind::SplitFile,
                        reason: format!("{}: {reason}", file.display()),
                        messages: None,
                        start_ns: None,
                        end_ns: None,
                        topics: Default::default(),
                    });
                    self.total = std::cell::OnceCell::new();
                    self.pending
                        .push_back(BagError::SplitFile { path: file, reason });
                }
            }
        }
        false
    }

    /// Moves the current split file's losses into `base` and closes it.
    fn finish_part(&mut self) {
        if let Some(p) = self.current.take() {
            let r = p.part.recovery();
            let name = part_name(&p);
            add_recovery(&mut self.base, r, &name);
            self.base.messages_read = self.base.messages_read.saturating_sub(self.undelivered);
            self.undelivered = 0;
            self.total = std::cell::OnceCell::new();
        }
    }

    /// Forgets the combined recovery: the current file's or the directory's changed.
    fn sync_total(&mut self) {
        self.total = std::cell::OnceCell::new();
    }

    /// A message of a directory's split file with its merged channel (and its data
    /// decompressed); `None` for a message of a refused channel.
    fn adopt(&mut self, mut m: BagMessage) -> Option<Result<BagMessage, BagError>> {
        let id = match self.part_ids.get(&m.channel_id) {
            Some(id) => *id,
            None => {
                let id = self.merge_channel(&m.topic, &m.message_encoding, m.schema.as_deref());
                self.part_ids.insert(m.channel_id, id);
                id
            }
        };
        let Some(id) = id else {
            let first = !self.refused_topics.contains_key(&m.topic);
            *self.refused_topics.entry(m.topic.clone()).or_default() += 1;
            self.undelivered += 1;
            self.sync_total();
            let t = m.log_time_ns;
            self.base.push(BagLoss {
                offset: 0,
                bytes: None,
                kind: LossKind::TooManyChannels,
                reason: format!(
                    "{}: a message of {}, a channel beyond MAX_CHANNELS = {MAX_CHANNELS} over the \
                     bag's split files",
                    self.current.as_ref().map(part_name).unwrap_or_default(),
                    m.topic
                ),
                messages: Some(1),
                start_ns: Some(t),
                end_ns: Some(t),
                topics: [(m.topic.clone(), 1)].into_iter().collect(),
            });
            return first.then(|| {
                Err(BagError::TooManyChannels {
                    path: self.path.clone(),
                    limit: MAX_CHANNELS,
                    topic: m.topic,
                })
            });
        };
        let merged = &self.merged[usize::from(id) - 1];
        m.channel_id = id;
        m.schema = merged.schema.clone();
        if !self.message_compression && self.compressed_unannounced(&m) {
            let path = self.current.as_ref().map(part_name).unwrap_or_default();
            self.pending.push_back(BagError::CompressedMessages {
                path: PathBuf::from(path),
                topic: m.topic.clone(),
            });
        }
        if self.message_compression || m.data.starts_with(&ZSTD_MAGIC) {
            match decompress_message(&m.data, self.options.max_record_bytes) {
                Ok(data) => m.data = data,
                Err(reason) => {
                    let path = self
                        .current
                        .as_ref()
                        .map(|p| PathBuf::from(part_name(p)))
                        .unwrap_or_default();
                    let t = m.log_time_ns;
                    self.undelivered += 1;
                    self.sync_total();
                    self.base.push(BagLoss {
                        offset: 0,
                        bytes: None,
                        kind: LossKind::Decompression,
                        reason: format!(
                            "{}: message on {} does not decompress: {reason}",
                            path.display(),
                            m.topic
                        ),
                        messages: Some(1),
                        start_ns: Some(t),
                        end_ns: Some(t),
                        topics: [(m.topic.clone(), 1)].into_iter().collect(),
                    });
                    return Some(Err(BagError::Decompression {
                        path,
                        topic: m.topic,
                        log_time_ns: t,
                        format: "zstd".to_owned(),
                        reason,
                    }));
                }
            }
        }
        self.count_read(&m);
        Some(Ok(m))
    }

    /// True the first time a message of a topic turns out to be a zstd frame while nothing
    /// says messages are compressed (no CDR payload starts with the zstd magic): it is read
    /// decompressed, and said once per topic.
    fn compressed_unannounced(&mut self, m: &BagMessage) -> bool {
        m.data.starts_with(&ZSTD_MAGIC) && self.compressed_topics.insert(m.topic.clone())
    }

    /// Counts a delivered message for the comparison with `metadata.yaml`.
    fn count_read(&mut self, m: &BagMessage) {
        match self.read_by_topic.get_mut(&m.topic) {
            Some(n) => *n += 1,
            None => {
                self.read_by_topic.insert(m.topic.clone(), 1);
            }
        }
        let t = m.log_time_ns;
        self.read_span = Some(self.read_span.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
    }

    /// Where a split file leads if it is a link out of the bag directory.
    fn outside_link(&self, file: &Path) -> Option<PathBuf> {
        match &self.layout {
            BagLayout::Directory(info) => info.outside_link(file),
            BagLayout::File { .. } => None,
        }
    }

    /// Once every split file is read: where `metadata.yaml` disagrees with what was read
    /// (messages it counts that were neither read nor already counted as lost, storage files
    /// it does not list, a time span the messages do not cover), as one loss in the
    /// recovery, so that `check` and `replay` say it and not only `info`.
    fn compare_with_metadata(&mut self) {
        if self.compared {
            return;
        }
        self.compared = true;
        let BagLayout::Directory(info) = &self.layout else {
            return;
        };
        if info.version.is_none() {
            return;
        }
        let mut said: Vec<String> = Vec::new();
        let mut missing_total = 0u64;
        let mut topics = std::collections::BTreeMap::new();
        // Messages each topic lost in losses already listed (with a known count).
        let mut lost: HashMap<&str, u64> = HashMap::new();
        for l in &self.base.losses {
            for (t, n) in &l.topics {
                *lost.entry(t.as_str()).or_default() += n;
            }
        }
        for t in &info.topics {
            let read = self.read_by_topic.get(&t.name).copied().unwrap_or(0);
            let known = read + lost.get(t.name.as_str()).copied().unwrap_or(0);
            if t.message_count > known {
                let n = t.message_count - known;
                missing_total += n;
                topics.insert(t.name.clone(), n);
            }
        }
        if missing_total > 0 {
            let per: Vec<String> = topics.iter().map(|(t, n)| format!("{t}: {n}")).collect();
            said.push(format!(
                "it counts {missing_total} more messages than were read or counted as lost \
                 ({}); a split file it does not list, or a file cut short, may hold them",
                per.join(", ")
            ));
        }
        let read_total: u64 = self.read_by_topic.values().sum();
        if let Some(listed) = info.message_count {
            let known = read_total + self.base.messages_lost;
            if listed > known && missing_total == 0 {
                missing_total = listed - known;
                said.push(format!(
                    "it counts {listed} messages in all; {read_total} were read and {} counted \
                     as lost",
                    self.base.messages_lost
                ));
            }
        }
        if !info.unlisted.is_empty() {
            let names: Vec<String> = info
                .unlisted
                .iter()
                .take(5)
                .map(|p| p.display().to_string())
                .collect();
            let more = info.unlisted.len().saturating_sub(5);
            said.push(format!(
                "the directory holds storage files it does not list, which were not read: {}{}",
                names.join(", "),
                if more > 0 {
                    format!(" and {more} more")
                } else {
                    String::new()
                }
            ));
        }
        if let (Some(start), Some(duration), Some((first, last))) =
            (info.starting_time_ns, info.duration_ns, self.read_span)
        {
            let end = start.saturating_add(duration);
            // Beyond a millisecond of rounding, a span the messages do not reach.
            if first > start.saturating_add(1_000_000) || last.saturating_add(1_000_000) < end {
                said.push(format!(
                    "it says the recording spans {:.3} s from its start; the messages read span \
                     {:.3}-{:.3} s",
                    duration as f64 * 1e-9,
                    first.saturating_sub(start) as f64 * 1e-9,
                    last.saturating_sub(start) as f64 * 1e-9
                ));
            }
        }
        if said.is_empty() {
            return;
        }
        let reason = format!(
            "{} disagrees with what was read: {}",
            info.dir.join(METADATA_FILE).display(),
            said.join("; ")
        );
        self.pending.push_back(BagError::MetadataDisagrees {
            path: info.dir.join(METADATA_FILE),
            reason: said.join("; "),
        });
        self.base.push(BagLoss {
            offset: 0,
            bytes: None,
            kind: LossKind::MetadataMismatch,
            reason,
            messages: Some(missing_total),
            start_ns: None,
            end_ns: None,
            topics,
        });
        self.sync_total();
    }
}

impl Iterator for BagReader {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.single {
            if let Some(e) = self.pending.pop_front() {
                return Some(Err(e));
            }
            let item = self.current.as_mut()?.part.next()?;
            if let Ok(m) = &item {
                if !self.message_compression && self.compressed_unannounced(m) {
                    self.pending.push_back(BagError::CompressedMessages {
                        path: self.path.clone(),
                        topic: m.topic.clone(),
                    });
                }
            }
            return Some(match item {
                Ok(mut m) if self.message_compression || m.data.starts_with(&ZSTD_MAGIC) => {
                    match decompress_message(&m.data, self.options.max_record_bytes) {
                        Ok(data) => {
                            m.data = data;
                            Ok(m)
                        }
                        Err(reason) => Err(BagError::Decompression {
                            path: self.path.clone(),
                            topic: m.topic,
                            log_time_ns: m.log_time_ns,
                            format: "zstd".to_owned(),
                            reason,
                        }),
                    }
                }
                other => other,
            });
        }
        loop {
            if let Some(e) = self.pending.pop_front() {
                return Some(Err(e));
            }
            let Some(p) = self.current.as_mut() else {
                if self.open_next() {
                    continue;
                }
                if let Some(e) = self.pending.pop_front() {
                    return Some(Err(e));
                }
                self.compare_with_metadata();
                return self.pending.pop_front().map(Err);
            };
            let item = p.part.next();
            self.sync_total();
            match item {
                Some(Ok(m)) => match self.adopt(m) {
                    Some(item) => {
                        self.sync_total();
                        return Some(item);
                    }
                    None => {
                        self.sync_total();
                        continue;
                    }
                },
                Some(Err(e)) if e.is_fatal() => {
                    self.finish_part();
                    if self.files.is_empty() {
                        return Some(Err(e));
                    }
                    return Some(Err(BagError::InSplitFile {
                        source: Box::new(e),
                    }));
                }
                Some(Err(e)) => return Some(Err(e)),
                None => {
                    if !self.open_next() && self.pending.is_empty() {
                        self.compare_with_metadata();
                        return self.pending.pop_front().map(Err);
                    }
                }
            }
        }
    }
}

/// A split file's name for loss reasons.
fn part_name(p: &OpenPart) -> String {
    match &p.part {
        Part::Mcap(r) => r.path().display().to_string(),
        Part::Db3(r) => r.path().display().to_string(),
    }
}

/// Adds the losses and counts of one file's `r` to `total`, each loss naming `file`.
fn add_recovery(total: &mut Recovery, r: &Recovery, file: &str) {
    total.indexed_chunks += r.indexed_chunks;
    total.messages_read += r.messages_read;
    total.add_unverified(r);
    for loss in &r.losses {
        let mut loss = loss.clone();
        loss.reason = format!("{file}: {}", loss.reason);
        total.push(loss);
    }
    total.losses_not_listed += r.losses_not_listed;
    // `push` counted the listed losses; the unlisted ones' counts come from the totals.
    let listed_lost: u64 = r.losses.iter().filter_map(|l| l.messages).sum();
    let listed_unknown = r.losses.iter().filter(|l| l.messages.is_none()).count() as u64;
    total.messages_lost += r.messages_lost.saturating_sub(listed_lost);
    total.regions_with_unknown_loss += r.regions_with_unknown_loss.saturating_sub(listed_unknown);
}

/// Opens one storage file by its content: MCAP, SQLite, or either compressed with zstd.
fn open_file(path: &Path, options: &BagReadOptions) -> Result<(OpenPart, BagLayout), BagError> {
    let io = |source| BagError::Io {
        path: path.to_path_buf(),
        action: "cannot open the bag",
        source,
    };
    let mut file = open_bag_file(path)?;
    let mut head = [0u8; 16];
    let n = read_up_to(&mut file, &mut head).map_err(io)?;
    let head = &head[..n];
    if head.starts_with(&ZSTD_MAGIC) {
        file.seek(SeekFrom::Start(0)).map_err(io)?;
        let mut temp = decompress_file(path, file, options.max_decompressed_file_bytes)?;
        let mut inner = [0u8; 16];
        temp.seek(SeekFrom::Start(0)).map_err(io)?;
        let n = read_up_to(&mut temp, &mut inner).map_err(io)?;
        let inner = &inner[..n];
        let (part, storage) = if inner.starts_with(SQLITE_MAGIC) {
            // SQLite opens by path: the copy without a name is reached through /proc.
            let by_fd = crate::fsio::proc_path(&temp).ok_or_else(|| BagError::NotABag {
                path: path.to_path_buf(),
                reason: "a compressed SQLite file is read through /proc/self/fd, which this \
                         system does not have; decompress it first (zstd -d)"
                    .to_owned(),
            })?;
            let r = Db3Reader::open(&by_fd, path, options.max_record_bytes)?;
            (Part::Db3(Box::new(r)), "sqlite3")
        } else {
            let mut f = temp.try_clone().map_err(io)?;
            f.seek(SeekFrom::Start(0)).map_err(io)?;
            let r = McapReader::from_reader(f, path.to_path_buf(), *options)?;
            (Part::Mcap(Box::new(r)), "mcap")
        };
        return Ok((
            OpenPart {
                part,
                _temp: Some(temp),
            },
            BagLayout::File {
                storage,
                compressed: true,
            },
        ));
    }
    if head.starts_with(SQLITE_MAGIC) {
        drop(file);
        let r = Db3Reader::open(path, path, options.max_record_bytes)?;
        return Ok((
            OpenPart {
                part: Part::Db3(Box::new(r)),
                _temp: None,
            },
            BagLayout::File {
                storage: "sqlite3",
                compressed: false,
            },
        ));
    }
    if !head.starts_with(&MAGIC) {
        let name = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        if storage_of(name).is_none() && n > 0 {
            return Err(BagError::NotMcap {
                path: path.to_path_buf(),
                reason: format!(
                    "it starts with {head:02x?}, which is neither the MCAP magic, an SQLite \
                     database, nor a zstd frame"
                ),
            });
        }
    }
    // MCAP, or something that claims to be one: its reader says what is wrong.
    file.seek(SeekFrom::Start(0)).map_err(io)?;
    let r = McapReader::from_reader(file, path.to_path_buf(), *options)?;
    Ok((
        OpenPart {
            part: Part::Mcap(Box::new(r)),
            _temp: None,
        },
        BagLayout::File {
            storage: "mcap",
            compressed: false,
        },
    ))
}

/// Opens a bag's storage file for reading if it is a regular file (a FIFO or a device is
/// refused before `open()` could block).
pub(crate) fn open_bag_file(path: &Path) -> Result<File, BagError> {
    crate::fsio::open_regular(path).map_err(|e| match e {
        crate::fsio::OpenError::Special(kind) => BagError::NotAFile {
            path: path.to_path_buf(),
            kind,
        },
        crate::fsio::OpenError::Io(source) => BagError::Io {
            path: path.to_path_buf(),
            action: "cannot open the bag",
            source,
        },
    })
}

/// Reads until `buf` is full or the end; the bytes read.
fn read_up_to(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match r.read(&mut buf[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

/// Decompresses a zstd-compressed storage file into a temporary copy that has no name (in
/// `TMPDIR`; its space is freed when it is dropped or the process dies), at most `limit`
/// bytes and at most half the space free there. A size declared in the first frame's header
/// above that is refused before anything is written.
fn decompress_file(path: &Path, input: File, limit: u64) -> Result<File, BagError> {
    let fail = |reason: String| BagError::NotABag {
        path: path.to_path_buf(),
        reason: format!("cannot decompress it: {reason}"),
    };
    // A file refused once is refused again at once: a command opens a bag up to three times,
    // and each refusal of a bomb costs filling the cap.
    let key = input.metadata().ok().map(|m| {
        use std::os::unix::fs::MetadataExt;
        (m.dev(), m.ino(), m.len(), m.mtime(), m.mtime_nsec(), limit)
    });
    type Key = (u64, u64, u64, i64, i64, u64);
    static REFUSED: std::sync::Mutex<Vec<(Key, String)>> = std::sync::Mutex::new(Vec::new());
    if let (Some(k), Ok(refused)) = (key, REFUSED.lock()) {
        if let Some((_, why)) = refused.iter().find(|(r, _)| *r == k) {
            return Err(fail(why.clone()));
        }
    }
    let remember = |why: String| {
        if let (Some(k), Ok(mut refused)) = (key, REFUSED.lock()) {
            if refused.len() < 64 {
                refused.push((k, why.clone()));
            }
        }
        fail(why)
    };
    let temp_dir = std::env::temp_dir();
    let free = crate::fsio::free_bytes(&temp_dir);
    let cap = free.map_or(limit, |f| limit.min(f / 2));
    let why_cap = || match free {
        Some(f) if f / 2 < limit => format!(
            "half of the {f} bytes free in {} (TMPDIR), where the copy is made",
            temp_dir.display()
        ),
        _ => format!(
            "max_decompressed_file_bytes = {limit}; {} (GiB) raises it for a trusted file",
            super::reader::MAX_DECOMPRESSED_ENV
        ),
    };
    let mut input = std::io::BufReader::with_capacity(1 << 20, input);
    let head = input.fill_buf().map_err(|e| fail(e.to_string()))?;
    if let Ok(Some(declared)) = zstd::zstd_safe::get_frame_content_size(&head[..head.len().min(18)])
    {
        if declared > cap {
            return Err(remember(format!(
                "its first frame declares {declared} bytes once decompressed, more than the \
                 {cap} bytes its temporary copy may take ({}); refused before writing",
                why_cap()
            )));
        }
    }
    let mut temp = tempfile::tempfile_in(&temp_dir).map_err(|e| {
        fail(format!(
            "cannot create a temporary file in {}: {e}",
            temp_dir.display()
        ))
    })?;
    let decoder =
        zstd::stream::read::Decoder::with_buffer(input).map_err(|e| fail(e.to_string()))?;
    let mut limited = decoder.take(cap.saturating_add(1));
    let copied = std::io::copy(&mut limited, &mut temp).map_err(|e| fail(e.to_string()))?;
    if copied > cap {
        return Err(remember(format!(
            "it decompresses to more than the {cap} bytes its temporary copy may take ({})",
            why_cap()
        )));
    }
    temp.flush().map_err(|e| fail(e.to_string()))?;
    Ok(temp)
}

/// Decompresses one message's data (a zstd frame), at most `limit` bytes.
fn decompress_message(data: &[u8], limit: usize) -> Result<Vec<u8>, DecompressError> {
    let declared =
        zstd::zstd_safe::get_frame_content_size(data).map_err(|_| DecompressError::NotZstd)?;
    if let Some(size) = declared {
        if size > limit as u64 {
            return Err(DecompressError::DeclaredTooLarge {
                declared: size,
                limit,
            });
        }
        let out = zstd::bulk::decompress(data, size as usize)?;
        if out.len() as u64 != size {
            return Err(DecompressError::SizeMismatch {
                held: out.len(),
                declared: size,
            });
        }
        return Ok(out);
    }
    let mut out = Vec::new();
    zstd::stream::read::Decoder::new(data)?
        .take(limit as u64 + 1)
        .read_to_end(&mut out)?;
    if out.len() > limit {
        return Err(DecompressError::TooLarge { limit });
    }
    Ok(out)
}
