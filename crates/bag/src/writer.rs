//! Writer of rosbag2-compatible MCAP files.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::MessageHeader;

use super::error::BagError;
use chronotope_msg::{encapsulation, encode_cdr, try_ros2msg_schema, RosMessage};

/// The QoS profile recorded for every topic: reliable, volatile, keep last 10, durations
/// infinite, in the YAML rosbag2 stores under the channel metadata key `offered_qos_profiles`.
///
/// Policies are written as rmw enum numbers (rosbag2 metadata up to version 8, as Humble
/// records them), which every rosbag2 release and the Python readers understand; durations
/// are `RMW_DURATION_INFINITE` as `sec`/`nsec`.
pub const OFFERED_QOS_PROFILES: &str = "\
- history: 1
  depth: 10
  reliability: 1
  durability: 2
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: 1
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false";

/// Chunk compression of a bag being written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BagCompression {
    /// Zstandard (the default; what `ros2 bag record --storage-preset-profile zstd_fast` uses).
    Zstd,
    /// LZ4 frames.
    Lz4,
}

/// Options of [`BagWriter::create_with`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BagWriteOptions {
    compression: Option<BagCompression>,
    chunk_size: u64,
    derived: Option<&'static str>,
    visible: bool,
}

impl Default for BagWriteOptions {
    fn default() -> Self {
        Self {
            compression: Some(BagCompression::Zstd),
            chunk_size: mcap::WriteOptions::DEFAULT_CHUNK_SIZE,
            derived: None,
            visible: false,
        }
    }
}

impl BagWriteOptions {
    /// The defaults: zstd chunks of about 1 MiB, with CRCs, message and chunk indexes and
    /// statistics.
    pub fn new() -> Self {
        Self::default()
    }

    /// Chunk compression, or `None` for uncompressed chunks.
    pub fn compression(mut self, compression: Option<BagCompression>) -> Self {
        self.compression = compression;
        self
    }

    /// Target uncompressed size of a chunk in bytes; a chunk is closed once it is larger.
    pub fn chunk_size(mut self, chunk_size: u64) -> Self {
        self.chunk_size = chunk_size;
        self
    }

    /// Marks the bag as derived by the command `by` (`replay`, `scene`, `sample`): a result
    /// that the same command can make again from its inputs, which the next run may replace
    /// without `--overwrite` ([`derived_by`]). A recording is never marked.
    pub fn derived(mut self, by: &'static str) -> Self {
        self.derived = Some(by);
        self
    }

    /// Writes the bag where it will stay while it grows (a recording: what was recorded
    /// survives a crash), instead of giving it its name only once complete. A path that
    /// exists is written beside under a hidden name and replaces it at the end.
    pub fn visible(mut self, visible: bool) -> Self {
        self.visible = visible;
        self
    }
}

/// What the MCAP header's `library` says after the version for a bag [derived](BagWriteOptions::derived)
/// by a command: `chronotope 0.1.0 (mcap-rs); derived by replay`.
const DERIVED_MARK: &str = "; derived by ";

/// The command that derived the MCAP file `path` ([`BagWriteOptions::derived`]), if it is one
/// this program wrote so marked; `None` for any other file, a recording, or one that cannot be
/// read. Only the file's first bytes (magic and header record) are read.
pub fn derived_by(path: &Path) -> Option<String> {
    use std::io::Read;
    let mut head = Vec::with_capacity(1024);
    crate::fsio::open_regular(path)
        .ok()?
        .take(1024)
        .read_to_end(&mut head)
        .ok()?;
    let rest = head.strip_prefix(&super::summary::MAGIC[..])?;
    // The header record: opcode 0x01, u64 length, then profile and library as u32-prefixed
    // strings.
    let (&op, rest) = rest.split_first()?;
    if op != 0x01 {
        return None;
    }
    let rest = rest.get(8..)?;
    let string = |b: &[u8]| -> Option<(String, usize)> {
        let n = u32::from_le_bytes(b.get(..4)?.try_into().ok()?) as usize;
        let s = std::str::from_utf8(b.get(4..4 + n)?).ok()?;
        Some((s.to_owned(), 4 + n))
    };
    let (_, used) = string(rest)?;
    let (library, _) = string(rest.get(used..)?)?;
    let by = library
        .strip_prefix("chronotope ")?
        .split_once(DERIVED_MARK)?
        .1;
    Some(by.to_owned())
}

/// A topic being written.
struct Topic {
    channel_id: u16,
    type_name: &'static str,
    next_sequence: u32,
    /// Messages written.
    count: u64,
}

/// Writes a rosbag2 MCAP file: profile `ros2`, one `ros2msg` schema per message type (the
/// rosbag2 schema text, see [`ros2msg_schema`](chronotope_msg::ros2msg_schema)), one `cdr` channel
/// per topic with the `offered_qos_profiles` metadata rosbag2 expects, zstd chunks, indexes and
/// statistics.
///
/// ```no_run
/// use chronotope_bag::BagWriter;
/// use chronotope_msg::VoxelGrid;
/// let mut bag = BagWriter::create("out.mcap")?;
/// bag.add_topic::<VoxelGrid>("/a/occupancy")?;
/// bag.write("/a/occupancy", 1_000_000_000, &VoxelGrid::default())?;
/// bag.finish()?;
/// # Ok::<(), chronotope_bag::BagError>(())
/// ```
///
/// The bag takes its name only in [`finish`](Self::finish) (see [`crate::fsio`]): until then
/// nothing is at the path (or what was there stays), and dropping the writer without
/// `finish` leaves no file. A [visible](BagWriteOptions::visible) bag (a recording) is
/// written in place instead, so that what was recorded survives a crash.
pub struct BagWriter {
    /// The storage file as the user will know it (messages in errors).
    path: PathBuf,
    inner: mcap::Writer<BufWriter<File>>,
    topics: HashMap<String, Topic>,
    /// How the file and its directory get their names at the end.
    placement: Placement,
    /// Log times of the first and last message written.
    span: Option<(u64, u64)>,
    /// The command that derived it, if it is marked so.
    derived: Option<&'static str>,
}

/// How a bag being written takes its place in [`BagWriter::finish`].
enum Placement {
    /// A storage file with no name yet: linked at its path (or into a directory's staging).
    Unnamed {
        file: crate::fsio::NewFile,
        dir: Option<PathBuf>,
    },
    /// A storage file written under its own name (a visible bag whose path was free).
    InPlace { dir: Option<PathBuf> },
    /// A visible file written under a hidden name beside an existing one, renamed over it at
    /// the end.
    Beside { written: PathBuf },
    /// A visible directory bag assembled in a hidden staging directory beside an existing
    /// one, which it replaces at the end.
    StagedDir { staging: PathBuf, target: PathBuf },
}

impl BagWriter {
    /// Creates (or truncates) `path` and writes the MCAP header, with the default options.
    ///
    /// # Errors
    ///
    /// [`BagError::Io`] if the file cannot be created, [`BagError::Write`] if the header
    /// cannot be written.
    pub fn create(path: impl AsRef<Path>) -> Result<Self, BagError> {
        Self::create_with(path, BagWriteOptions::default())
    }

    /// Creates (or truncates) `path` and writes the MCAP header.
    ///
    /// If `path` ends with `/` or is an existing directory, the bag is a rosbag2 directory:
    /// the directory is created if needed, the messages go to its split file
    /// `<dir>/<dir name>_0.mcap`, and [`finish`](Self::finish) writes its `metadata.yaml`
    /// (version 9), so that `ros2 bag info` and `ros2 bag play` open it.
    ///
    /// # Errors
    ///
    /// As [`BagWriter::create`].
    pub fn create_with(path: impl AsRef<Path>, options: BagWriteOptions) -> Result<Self, BagError> {
        let given = path.as_ref();
        let dir = super::rosbag2::is_directory_path(given).then(|| given.to_path_buf());
        let io = |path: &Path, action: &'static str| {
            let path = path.to_path_buf();
            move |source| BagError::Io {
                path,
                action,
                source,
            }
        };
        // The directory the output goes in is made (making missing parents destroys nothing).
        let home = crate::fsio::parent_dir(dir.as_deref().unwrap_or(given)).to_path_buf();
        std::fs::create_dir_all(&home)
            .map_err(io(&home, "cannot create the output's directory"))?;
        let path = match &dir {
            Some(d) => super::rosbag2::split_file_of(d),
            None => given.to_path_buf(),
        };
        let exists = std::fs::symlink_metadata(dir.as_deref().unwrap_or(given)).is_ok();
        let (file, placement) = if !options.visible {
            let mut staged = crate::fsio::NewFile::create_staged_in(&path, &home)
                .map_err(io(&path, "cannot create the bag"))?;
            let file = staged
                .file()
                .try_clone()
                .map_err(io(&path, "cannot create the bag"))?;
            (file, Placement::Unnamed { file: staged, dir })
        } else {
            let create_new = |p: &Path| {
                std::fs::OpenOptions::new()
                    .write(true)
                    .create_new(true)
                    .open(p)
                    .map_err(io(p, "cannot create the bag"))
            };
            match (&dir, exists) {
                (None, false) => (create_new(&path)?, Placement::InPlace { dir: None }),
                (None, true) => {
                    let (f, written) = crate::fsio::create_hidden_beside(&path)
                        .map_err(io(&path, "cannot create the bag"))?;
                    (f, Placement::Beside { written })
                }
                (Some(d), _) if !exists || dir_is_empty(d) => {
                    std::fs::create_dir_all(d)
                        .map_err(io(d, "cannot create the rosbag2 directory"))?;
                    (create_new(&path)?, Placement::InPlace { dir: dir.clone() })
                }
                (Some(d), _) => {
                    let staging = crate::fsio::stage_dir(d)
                        .map_err(io(d, "cannot create the rosbag2 directory"))?;
                    let file = create_new(&staging.join(path.file_name().unwrap_or_default()))?;
                    (
                        file,
                        Placement::StagedDir {
                            staging,
                            target: d.clone(),
                        },
                    )
                }
            }
        };
        let compression = options.compression.map(|c| match c {
            BagCompression::Zstd => mcap::Compression::Zstd,
            BagCompression::Lz4 => mcap::Compression::Lz4,
        });
        let library = match options.derived {
            Some(by) => format!(
                "chronotope {} (mcap-rs){DERIVED_MARK}{by}",
                env!("CARGO_PKG_VERSION")
            ),
            None => format!("chronotope {} (mcap-rs)", env!("CARGO_PKG_VERSION")),
        };
        let inner = mcap::WriteOptions::new()
            .profile("ros2")
            .library(library)
            .compression(compression)
            .chunk_size(Some(options.chunk_size))
            .create(BufWriter::new(file))
            .map_err(|source| BagError::Write {
                path: path.clone(),
                source,
            })?;
        Ok(Self {
            path,
            inner,
            topics: HashMap::new(),
            placement,
            span: None,
            derived: options.derived,
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Adds a topic carrying messages of type `M`. Adding the same topic with the same type
    /// again does nothing.
    ///
    /// # Errors
    ///
    /// [`BagError::TopicTypeConflict`] if the topic exists with another type,
    /// [`BagError::Schema`] if `M`'s dependencies are incomplete, [`BagError::Write`] if the
    /// records cannot be written.
    pub fn add_topic<M: RosMessage>(&mut self, topic: &str) -> Result<(), BagError> {
        if let Some(existing) = self.topics.get(topic) {
            return if existing.type_name == M::TYPE_NAME {
                Ok(())
            } else {
                Err(self.conflict(topic, existing.type_name, M::TYPE_NAME))
            };
        }
        let schema = try_ros2msg_schema::<M>().map_err(|source| BagError::Schema {
            path: self.path.clone(),
            type_name: M::TYPE_NAME,
            source,
        })?;
        self.add_topic_with_schema(topic, M::TYPE_NAME, &schema)
    }

    /// Adds a topic of type `type_name` (`pkg/msg/Type`) whose complete `ros2msg` schema text
    /// is `schema` (for writers that know the type only at run time). Adding the same topic
    /// with the same type again does nothing.
    ///
    /// # Errors
    ///
    /// [`BagError::TopicTypeConflict`] if the topic exists with another type,
    /// [`BagError::Write`] if the records cannot be written.
    pub fn add_topic_with_schema(
        &mut self,
        topic: &str,
        type_name: &'static str,
        schema: &str,
    ) -> Result<(), BagError> {
        if let Some(existing) = self.topics.get(topic) {
            return if existing.type_name == type_name {
                Ok(())
            } else {
                Err(self.conflict(topic, existing.type_name, type_name))
            };
        }
        // The mcap writer reuses the id of an identical schema already written.
        let schema_id = self
            .inner
            .add_schema(type_name, "ros2msg", schema.as_bytes())
            .map_err(|source| self.write_error(source))?;
        let metadata = BTreeMap::from([(
            "offered_qos_profiles".to_owned(),
            OFFERED_QOS_PROFILES.to_owned(),
        )]);
        let channel_id = self
            .inner
            .add_channel(schema_id, topic, "cdr", &metadata)
            .map_err(|source| self.write_error(source))?;
        self.topics.insert(
            topic.to_owned(),
            Topic {
                channel_id,
                type_name,
                next_sequence: 1,
                count: 0,
            },
        );
        Ok(())
    }

    /// Writes `msg` on `topic` (added for type `M`), logged and published at `log_time_ns`.
    ///
    /// # Errors
    ///
    /// [`BagError::UnknownTopic`] or [`BagError::TopicTypeConflict`] if the topic was not
    /// added for `M`, [`BagError::Cdr`] if the message cannot be serialised,
    /// [`BagError::Write`] if it cannot be written.
    pub fn write<M: RosMessage>(
        &mut self,
        topic: &str,
        log_time_ns: u64,
        msg: &M,
    ) -> Result<(), BagError> {
        let existing = self.topic(topic)?.type_name;
        if existing != M::TYPE_NAME {
            return Err(self.conflict(topic, existing, M::TYPE_NAME));
        }
        let bytes = encode_cdr(msg).map_err(|source| BagError::Cdr {
            path: self.path.clone(),
            topic: topic.to_owned(),
            source,
        })?;
        self.write_cdr(topic, log_time_ns, &bytes)
    }

    /// Writes an already serialised message (encapsulation header and CDR body) on `topic`,
    /// logged and published at `log_time_ns`. The bytes are not checked beyond the header.
    ///
    /// # Errors
    ///
    /// [`BagError::UnknownTopic`] if the topic was not added, [`BagError::Cdr`] if the bytes
    /// do not start with a CDR encapsulation header, [`BagError::Write`] if writing fails.
    pub fn write_cdr(
        &mut self,
        topic: &str,
        log_time_ns: u64,
        bytes: &[u8],
    ) -> Result<(), BagError> {
        self.write_cdr_published(topic, log_time_ns, log_time_ns, bytes)
    }

    /// As [`BagWriter::write_cdr`], with the time the message was published (its DDS source
    /// timestamp, as rosbag2 records it) apart from the time it was received and logged.
    ///
    /// # Errors
    ///
    /// As [`BagWriter::write_cdr`].
    pub fn write_cdr_published(
        &mut self,
        topic: &str,
        log_time_ns: u64,
        publish_time_ns: u64,
        bytes: &[u8],
    ) -> Result<(), BagError> {
        if let Err(source) = encapsulation(bytes) {
            return Err(BagError::Cdr {
                path: self.path.clone(),
                topic: topic.to_owned(),
                source,
            });
        }
        let path = &self.path;
        let entry = self
            .topics
            .get_mut(topic)
            .ok_or_else(|| BagError::UnknownTopic {
                path: path.clone(),
                topic: topic.to_owned(),
            })?;
        let header = MessageHeader {
            channel_id: entry.channel_id,
            sequence: entry.next_sequence,
            log_time: log_time_ns,
            publish_time: publish_time_ns,
        };
        entry.next_sequence = entry.next_sequence.wrapping_add(1);
        entry.count += 1;
        self.span = Some(match self.span {
            Some((a, b)) => (a.min(log_time_ns), b.max(log_time_ns)),
            None => (log_time_ns, log_time_ns),
        });
        self.inner
            .write_to_known_channel(&header, bytes)
            .map_err(|source| BagError::Write {
                path: path.clone(),
                source,
            })
    }

    /// Writes the summary (schemas, channels, statistics, indexes) and the footer, and flushes
    /// the file.
    ///
    /// # Errors
    ///
    /// [`BagError::Write`] or [`BagError::Io`] if the end of the file cannot be written.
    pub fn finish(mut self) -> Result<(), BagError> {
        self.inner
            .finish()
            .map_err(|source| self.write_error(source))?;
        let path = self.path.clone();
        let io = |action: &'static str| {
            let path = path.clone();
            move |source| BagError::Io {
                path,
                action,
                source,
            }
        };
        self.inner
            .into_inner()
            .into_inner()
            .map_err(|err| BagError::Io {
                path: self.path.clone(),
                action: "cannot flush the bag",
                source: err.into_error(),
            })?;
        let topics: BTreeMap<String, super::rosbag2::WrittenTopic> = self
            .topics
            .iter()
            .map(|(name, t)| {
                (
                    name.clone(),
                    super::rosbag2::WrittenTopic {
                        type_name: t.type_name.to_owned(),
                        count: t.count,
                    },
                )
            })
            .collect();
        let metadata = |dir: &Path| {
            super::rosbag2::MetadataWriter {
                dir,
                file: &self.path,
                topics: &topics,
                start_ns: self.span.map(|s| s.0),
                end_ns: self.span.map(|s| s.1),
                derived: self.derived,
            }
            .write()
        };
        match &mut self.placement {
            Placement::Unnamed { file, dir: None } => file
                .commit_as(&self.path)
                .map_err(io("cannot name the bag")),
            Placement::Unnamed {
                file,
                dir: Some(dir),
            } => {
                let staging = crate::fsio::stage_dir(dir)
                    .map_err(io("cannot create the rosbag2 directory"))?;
                let done = (|| {
                    file.commit_as(&staging.join(self.path.file_name().unwrap_or_default()))
                        .map_err(io("cannot name the bag"))?;
                    metadata(&staging)?;
                    crate::fsio::replace_dir(&staging, dir)
                        .map_err(io("cannot put the rosbag2 directory in place"))
                })();
                if done.is_err() {
                    let _ = std::fs::remove_dir_all(&staging);
                }
                done
            }
            Placement::InPlace { dir: None } => Ok(()),
            Placement::InPlace { dir: Some(dir) } => metadata(dir),
            Placement::Beside { written } => {
                std::fs::rename(&*written, &self.path).map_err(io("cannot name the bag"))
            }
            Placement::StagedDir { staging, target } => {
                metadata(staging)?;
                crate::fsio::replace_dir(staging, target)
                    .map_err(io("cannot put the rosbag2 directory in place"))
            }
        }
    }

    fn topic(&self, topic: &str) -> Result<&Topic, BagError> {
        self.topics
            .get(topic)
            .ok_or_else(|| BagError::UnknownTopic {
                path: self.path.clone(),
                topic: topic.to_owned(),
            })
    }

    fn conflict(&self, topic: &str, existing: &str, requested: &str) -> BagError {
        BagError::TopicTypeConflict {
            path: self.path.clone(),
            topic: topic.to_owned(),
            existing: existing.to_owned(),
            requested: requested.to_owned(),
        }
    }

    fn write_error(&self, source: mcap::McapError) -> BagError {
        BagError::Write {
            path: self.path.clone(),
            source,
        }
    }
}

/// True if `dir` is a directory with nothing in it.
fn dir_is_empty(dir: &Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|mut d| d.next().is_none())
}
