//! rosbag2 directories: what `ros2 bag record` writes (a `metadata.yaml` and one or more split
//! storage files), read ([`Rosbag2Dir::open`]) and written ([`MetadataWriter`]).
//!
//! `metadata.yaml` versions 1 to 9 are read (a newer version is read as far as its fields
//! are known, with a warning). What is used from it: the storage plugin, the split files in
//! order (`relative_file_paths`), and the compression (`compression_format`, `compression_mode`:
//! `FILE` compresses each split file as a whole, `MESSAGE` each message's data). Topics and
//! counts are only reported (`chronotope info`); what the bag holds is decided from the storage
//! files. A directory without `metadata.yaml` (a recording cut before rosbag2 wrote it) is read
//! from its storage files in split order, with a warning.
//!
//! Written directories follow version 9 (Jazzy): one MCAP split file, `metadata.yaml` with the
//! topics, their counts and offered QoS profiles, so `ros2 bag info` and `ros2 bag play` open
//! them.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};

use serde::Serialize;
use serde_yaml_ng::Value;

use super::error::BagError;

/// The metadata file of a rosbag2 directory.
pub const METADATA_FILE: &str = "metadata.yaml";

/// Largest `metadata.yaml` read: 4 MiB (a bag of the maximum number of topics and split files
/// takes under 3 MiB).
pub const MAX_METADATA_BYTES: u64 = 4 << 20;

/// Most split files read from one directory (a day recorded in 10-second splits is 8 640).
pub const MAX_SPLIT_FILES: usize = 10_000;

/// The newest `metadata.yaml` version this program knows.
pub const METADATA_VERSION: u64 = 9;

/// How a rosbag2 directory's storage files are compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Compression {
    /// Not compressed (or compressed by the storage itself, as MCAP chunks are).
    None,
    /// Each split file compressed as a whole (`.mcap.zstd`, `.db3.zstd`).
    File,
    /// Each message's data compressed on its own.
    Message,
}

/// A topic as `metadata.yaml` lists it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct MetadataTopic {
    /// The topic.
    pub name: String,
    /// Its type (`pkg/msg/Type`).
    #[serde(rename = "type")]
    pub type_name: String,
    /// Its serialisation format (`cdr`).
    pub serialization_format: String,
    /// Its message count.
    pub message_count: u64,
}

/// What a rosbag2 directory's `metadata.yaml` says (or, without one, what its files say).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Rosbag2Dir {
    /// The directory.
    pub dir: PathBuf,
    /// The directory with every link resolved (a split file must lie inside it).
    #[serde(skip)]
    pub canonical_dir: PathBuf,
    /// The metadata version (`None` without `metadata.yaml`).
    pub version: Option<u64>,
    /// The storage plugin (`mcap`, `sqlite3`).
    pub storage: String,
    /// The split files, in order, as paths.
    pub files: Vec<PathBuf>,
    /// Storage files in the directory that `metadata.yaml` does not list (not read).
    pub unlisted: Vec<PathBuf>,
    /// The compression format (`zstd`), if any.
    pub compression_format: Option<String>,
    /// How the compression applies.
    pub compression: Compression,
    /// The topics listed.
    pub topics: Vec<MetadataTopic>,
    /// Messages listed.
    pub message_count: Option<u64>,
    /// First message's time, nanoseconds since the epoch.
    pub starting_time_ns: Option<u64>,
    /// Duration, nanoseconds.
    pub duration_ns: Option<u64>,
    /// The ROS distribution that wrote it, if said.
    pub ros_distro: Option<String>,
    /// The command of this program that derived the bag, if its `custom_data` says so (see
    /// [`BagWriteOptions::derived`](super::BagWriteOptions::derived)).
    pub derived_by: Option<String>,
    /// What was odd about the directory (a newer version, no metadata, a listed file that
    /// does not exist), one line each.
    pub warnings: Vec<String>,
}

impl Rosbag2Dir {
    /// Reads the directory `dir`: its `metadata.yaml`, or without one its storage files.
    ///
    /// # Errors
    /// [`BagError::Metadata`] if `metadata.yaml` is present but unusable (too large, too
    /// deep, not YAML, a field of the wrong type, no file list, an unknown storage or
    /// compression, a link leading out of the directory, not a regular file);
    /// [`BagError::NotABag`] if there is no `metadata.yaml` and no storage file.
    pub fn open(dir: &Path) -> Result<Self, BagError> {
        let canonical = dir.canonicalize().map_err(|source| BagError::Io {
            path: dir.to_path_buf(),
            action: "cannot open the rosbag2 directory",
            source,
        })?;
        let meta = dir.join(METADATA_FILE);
        if std::fs::symlink_metadata(&meta).is_ok() {
            let mut info = Self::from_metadata(dir, &meta, &canonical)?;
            info.unlisted = unlisted_files(dir, &info.files);
            return Ok(info);
        }
        let mut files: Vec<(u64, PathBuf)> = Vec::new();
        let entries = std::fs::read_dir(dir).map_err(|source| BagError::Io {
            path: dir.to_path_buf(),
            action: "cannot list the rosbag2 directory",
            source,
        })?;
        for e in entries.flatten() {
            let p = e.path();
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or_default();
            if storage_of(name).is_some() && !name.starts_with('.') {
                files.push((split_index(name), p));
                if files.len() > MAX_SPLIT_FILES {
                    return Err(BagError::NotABag {
                        path: dir.to_path_buf(),
                        reason: format!(
                            "the directory has no {METADATA_FILE} and more than MAX_SPLIT_FILES \
                             = {MAX_SPLIT_FILES} storage files"
                        ),
                    });
                }
            }
        }
        if files.is_empty() {
            return Err(BagError::NotABag {
                path: dir.to_path_buf(),
                reason: format!(
                    "the directory has no {METADATA_FILE} and no storage file (.mcap, .db3, \
                     or either compressed as .zstd)"
                ),
            });
        }
        files.sort();
        let storage = files
            .iter()
            .filter_map(|(_, p)| p.file_name()?.to_str().and_then(storage_of))
            .next()
            .unwrap_or("mcap")
            .to_owned();
        let compressed = files
            .iter()
            .any(|(_, p)| p.extension().is_some_and(|e| e == "zstd"));
        Ok(Self {
            dir: dir.to_path_buf(),
            canonical_dir: canonical,
            version: None,
            storage,
            files: files.into_iter().map(|(_, p)| p).collect(),
            unlisted: Vec::new(),
            compression_format: compressed.then(|| "zstd".to_owned()),
            compression: if compressed {
                Compression::File
            } else {
                Compression::None
            },
            topics: Vec::new(),
            message_count: None,
            starting_time_ns: None,
            duration_ns: None,
            ros_distro: None,
            derived_by: None,
            warnings: vec![format!(
                "no {METADATA_FILE} (was the recording stopped before rosbag2 wrote it?): \
                 reading the storage files in split order"
            )],
        })
    }

    /// Where a split file leads if it is a link out of the bag directory (it is then not
    /// read: a bag's files are its own); `None` for a file of the directory.
    pub fn outside_link(&self, file: &Path) -> Option<PathBuf> {
        let is_link = std::fs::symlink_metadata(file).is_ok_and(|m| m.file_type().is_symlink());
        if !is_link {
            return None;
        }
        match file.canonicalize() {
            Ok(target) if target.starts_with(&self.canonical_dir) => None,
            Ok(target) => Some(target),
            // A dangling link: opening it says so.
            Err(_) => None,
        }
    }

    fn from_metadata(dir: &Path, meta: &Path, canonical: &Path) -> Result<Self, BagError> {
        let bad = |reason: String| BagError::Metadata {
            path: meta.to_path_buf(),
            reason,
        };
        if let Ok(target) = meta.canonicalize() {
            if !target.starts_with(canonical) {
                return Err(bad(format!(
                    "it is a link to {}, outside the bag directory: refused (a bag's metadata \
                     is its own file)",
                    target.display()
                )));
            }
        }
        let mut file = crate::fsio::open_regular(meta).map_err(|e| match e {
            crate::fsio::OpenError::Special(kind) => bad(format!(
                "it is {kind}, not a regular file (it could block or never end)"
            )),
            crate::fsio::OpenError::Io(source) => BagError::Io {
                path: meta.to_path_buf(),
                action: "cannot open the metadata",
                source,
            },
        })?;
        let mut bytes = Vec::new();
        (&mut file)
            .take(MAX_METADATA_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| bad(format!("cannot read it: {e}")))?;
        if bytes.len() as u64 > MAX_METADATA_BYTES {
            return Err(bad(format!(
                "it is larger than MAX_METADATA_BYTES = {MAX_METADATA_BYTES} bytes"
            )));
        }
        let text = String::from_utf8(bytes).map_err(|e| {
            bad(format!(
                "it is not UTF-8 text (byte {})",
                e.utf8_error().valid_up_to()
            ))
        })?;
        // Bounded before it is parsed: nesting, entries and aliases are measured in one
        // linear pass, so no file can make the parser slow (chronotope_yaml).
        chronotope_yaml::prescan(&text, &METADATA_LIMITS).map_err(|e| bad(e.to_string()))?;
        let root: Value = serde_yaml_ng::from_str(&text).map_err(|e| bad(yaml_error(&e)))?;
        let info = root
            .get("rosbag2_bagfile_information")
            .ok_or_else(|| bad("it has no rosbag2_bagfile_information section".to_owned()))?;
        let field = |key: &str| info.get(key).filter(|v| !v.is_null());
        let mut warnings = Vec::new();
        let version = match field("version") {
            None => return Err(bad("it has no version".to_owned())),
            Some(v) => whole_number(v).map_err(|e| bad(format!("version {e}")))?,
        };
        if version > METADATA_VERSION {
            warnings.push(format!(
                "metadata version {version} is newer than the {METADATA_VERSION} this program \
                 knows; reading the fields it knows"
            ));
        }
        let storage = match field("storage_identifier") {
            None => String::new(),
            Some(v) => text_field(v).map_err(|e| bad(format!("storage_identifier {e}")))?,
        };
        if storage != "mcap" && storage != "sqlite3" {
            return Err(bad(format!(
                "storage_identifier is {}; this program reads \"mcap\" and \"sqlite3\"",
                chronotope_yaml::quote(&storage)
            )));
        }
        let format = match field("compression_format") {
            None => None,
            Some(v) => Some(text_field(v).map_err(|e| bad(format!("compression_format {e}")))?),
        }
        .filter(|s| !s.is_empty());
        let mode = match field("compression_mode") {
            None => String::new(),
            Some(v) => text_field(v).map_err(|e| bad(format!("compression_mode {e}")))?,
        }
        .to_ascii_lowercase();
        let compression = match (mode.as_str(), format.as_deref()) {
            ("" | "none", _) => Compression::None,
            ("file", Some("zstd")) => Compression::File,
            ("message", Some("zstd")) => Compression::Message,
            (m, f) => {
                return Err(bad(format!(
                    "compression_mode {} with compression_format {}: this program reads zstd \
                     compression of files or messages",
                    chronotope_yaml::quote(m),
                    chronotope_yaml::quote(f.unwrap_or(""))
                )))
            }
        };
        let paths = match field("relative_file_paths") {
            None => return Err(bad("it has no relative_file_paths list".to_owned())),
            Some(v) => v.as_sequence().ok_or_else(|| {
                bad(format!(
                    "relative_file_paths {}; expected a list of file names",
                    shape(v)
                ))
            })?,
        };
        if paths.len() > MAX_SPLIT_FILES {
            return Err(bad(format!(
                "it lists {} split files, more than MAX_SPLIT_FILES = {MAX_SPLIT_FILES}",
                paths.len()
            )));
        }
        let mut files = Vec::with_capacity(paths.len());
        for (i, p) in paths.iter().enumerate() {
            let p = text_field(p)
                .map_err(|e| bad(format!("relative_file_paths entry {} {e}", i + 1)))?;
            // Before version 4 the paths included the directory's own name; rosbag2 and
            // rosbags both take the file name alone.
            let name = Path::new(&p).file_name().ok_or_else(|| {
                bad(format!(
                    "relative file path {} names no file",
                    chronotope_yaml::quote(&p)
                ))
            })?;
            files.push(dir.join(name));
        }
        // Fields only reported (and compared with what is read): a wrong type is a warning.
        let mut number = |v: Option<&Value>, name: &str| -> Option<u64> {
            match v.filter(|v| !v.is_null()).map(whole_number) {
                None => None,
                Some(Ok(n)) => Some(n),
                Some(Err(e)) => {
                    warnings.push(format!("{METADATA_FILE}: {name} {e}; not used"));
                    None
                }
            }
        };
        let message_count = number(field("message_count"), "message_count");
        let starting_time_ns = number(
            field("starting_time").and_then(|v| v.get("nanoseconds_since_epoch")),
            "starting_time.nanoseconds_since_epoch",
        );
        let duration_ns = number(
            field("duration").and_then(|v| v.get("nanoseconds")),
            "duration.nanoseconds",
        );
        let mut topics = Vec::new();
        if let Some(seq) = field("topics_with_message_count") {
            match seq.as_sequence() {
                None => warnings.push(format!(
                    "{METADATA_FILE}: topics_with_message_count {}; expected a list; not used",
                    shape(seq)
                )),
                Some(seq) => {
                    for (i, t) in seq.iter().enumerate() {
                        match metadata_topic(t) {
                            Ok(t) => topics.push(t),
                            Err(e) => warnings.push(format!(
                                "{METADATA_FILE}: topics_with_message_count entry {}: {e}; not \
                                 used",
                                i + 1
                            )),
                        }
                    }
                }
            }
        }
        let derived_by = field("custom_data")
            .and_then(|c| c.get(DERIVED_KEY))
            .and_then(Value::as_str)
            .map(str::to_owned);
        Ok(Self {
            dir: dir.to_path_buf(),
            canonical_dir: canonical.to_path_buf(),
            version: Some(version),
            storage,
            files,
            unlisted: Vec::new(),
            compression_format: format,
            compression,
            topics,
            message_count,
            starting_time_ns,
            duration_ns,
            ros_distro: field("ros_distro")
                .and_then(Value::as_str)
                .map(str::to_owned),
            derived_by,
            warnings,
        })
    }
}

/// The bounds a `metadata.yaml` must keep before it is parsed (see [`chronotope_yaml`]): at most
/// [`MAX_METADATA_BYTES`], collections nested at most 32 deep, at most 400 000 entries. The
/// largest accepted file parses in well under a second.
pub const METADATA_LIMITS: chronotope_yaml::YamlLimits = chronotope_yaml::YamlLimits {
    max_bytes: MAX_METADATA_BYTES as usize,
    max_depth: 32,
    max_entries: 400_000,
};

/// serde_yaml_ng's complaint in the user's terms: an integer beyond 64 bits (which it cannot
/// hold as any value) named by its field, anything else as a YAML error.
fn yaml_error(e: &serde_yaml_ng::Error) -> String {
    let text = e.to_string();
    if let Some((field, rest)) = text.split_once(": invalid type: integer") {
        if rest.contains("as u128") || rest.contains("as i128") {
            let field = field
                .strip_prefix("rosbag2_bagfile_information.")
                .unwrap_or(field);
            let at = e
                .location()
                .map(|l| format!(" (line {}, column {})", l.line(), l.column()))
                .unwrap_or_default();
            return format!(
                "{} is a whole number beyond 64 bits{at}; expected a whole number from 0 to \
                 18446744073709551615",
                chronotope_yaml::cut(field)
            );
        }
    }
    format!("not valid YAML: {}", chronotope_yaml::shorten(&text))
}

/// What a YAML value is, for an error naming an unexpected type.
fn shape(v: &Value) -> String {
    match v {
        Value::Null => "is empty".to_owned(),
        Value::Bool(b) => format!("is {b}"),
        Value::Number(n) => format!("is the number {}", chronotope_yaml::cut(&n.to_string())),
        Value::String(s) => format!("is the string {}", chronotope_yaml::quote(s)),
        Value::Sequence(_) => "is a list".to_owned(),
        Value::Mapping(_) => "is a mapping".to_owned(),
        Value::Tagged(t) => format!("is tagged {}", chronotope_yaml::quote(&t.tag.to_string())),
    }
}

/// What a whole number of `metadata.yaml` must be, as its errors say.
const WHOLE_NUMBER: &str = "expected a whole number from 0 to 18446744073709551615";

/// Why a `metadata.yaml` value is not what its field takes: what the value is ([`shape`]),
/// then what was expected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
enum ValueError {
    /// A negative integer where a whole number goes.
    #[error("{found}: negative; {WHOLE_NUMBER}")]
    Negative {
        /// What the value is.
        found: String,
    },
    /// A number that is not a whole number from 0 to 2^64 - 1.
    #[error("{found}: not a whole number in range; {WHOLE_NUMBER}")]
    OutOfRange {
        /// What the value is.
        found: String,
    },
    /// Text (a quoted number, say) where a whole number goes.
    #[error("{found}; {WHOLE_NUMBER} (written without quotes)")]
    Quoted {
        /// What the value is.
        found: String,
    },
    /// Anything else where a whole number goes.
    #[error("{found}; {WHOLE_NUMBER}")]
    NotANumber {
        /// What the value is.
        found: String,
    },
    /// Anything but text where text goes.
    #[error("{found}; expected text")]
    NotText {
        /// What the value is.
        found: String,
    },
}

/// Why an entry of `topics_with_message_count` is not used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
enum TopicEntryError {
    /// The entry has no `topic_metadata`.
    #[error("it has no topic_metadata")]
    NoMetadata,
    /// A field of its `topic_metadata` is not text.
    #[error("topic_metadata.{key} {source}")]
    Field {
        /// The field.
        key: &'static str,
        /// What it is instead.
        source: ValueError,
    },
    /// Its `topic_metadata` names no topic.
    #[error("topic_metadata has no name")]
    NoName,
    /// Its `message_count` is not a whole number.
    #[error("message_count {0}")]
    MessageCount(ValueError),
}

/// A whole number from 0 to 2^64 - 1, or why the value is not one.
fn whole_number(v: &Value) -> Result<u64, ValueError> {
    if let Some(n) = v.as_u64() {
        return Ok(n);
    }
    let found = shape(v);
    Err(match v {
        Value::Number(n) if n.as_i64().is_some() => ValueError::Negative { found },
        Value::Number(_) => ValueError::OutOfRange { found },
        Value::String(_) => ValueError::Quoted { found },
        _ => ValueError::NotANumber { found },
    })
}

/// A text value, or why the value is not one.
fn text_field(v: &Value) -> Result<String, ValueError> {
    v.as_str()
        .map(str::to_owned)
        .ok_or_else(|| ValueError::NotText { found: shape(v) })
}

/// One entry of `topics_with_message_count`.
fn metadata_topic(t: &Value) -> Result<MetadataTopic, TopicEntryError> {
    let m = t.get("topic_metadata").ok_or(TopicEntryError::NoMetadata)?;
    let s = |key: &'static str| -> Result<String, TopicEntryError> {
        match m.get(key).filter(|v| !v.is_null()) {
            None => Ok(String::new()),
            Some(v) => text_field(v).map_err(|source| TopicEntryError::Field { key, source }),
        }
    };
    let name = s("name")?;
    if name.is_empty() {
        return Err(TopicEntryError::NoName);
    }
    let message_count = match t.get("message_count").filter(|v| !v.is_null()) {
        None => 0,
        Some(v) => whole_number(v).map_err(TopicEntryError::MessageCount)?,
    };
    Ok(MetadataTopic {
        name,
        type_name: s("type")?,
        serialization_format: s("serialization_format")?,
        message_count,
    })
}

/// Storage files in `dir` that `listed` does not name (hidden files aside): their messages
/// are not read, and a reader says so.
fn unlisted_files(dir: &Path, listed: &[PathBuf]) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let names: std::collections::HashSet<&std::ffi::OsStr> =
        listed.iter().filter_map(|p| p.file_name()).collect();
    let mut out: Vec<PathBuf> = entries
        .flatten()
        .filter(|e| {
            let name = e.file_name();
            let s = name.to_string_lossy();
            storage_of(&s).is_some() && !s.starts_with('.') && !names.contains(name.as_os_str())
        })
        .map(|e| e.path())
        .take(MAX_SPLIT_FILES)
        .collect();
    out.sort();
    out
}

/// True if a file name is a rosbag2 storage file's (`.mcap`, `.db3`, either with `.zstd`).
pub fn storage_file_name(name: &str) -> bool {
    storage_of(name).is_some()
}

/// The storage plugin a file name says (`mcap`, `sqlite3`), compressed or not.
pub(crate) fn storage_of(name: &str) -> Option<&'static str> {
    let name = name.strip_suffix(".zstd").unwrap_or(name);
    if name.ends_with(".mcap") {
        Some("mcap")
    } else if name.ends_with(".db3") {
        Some("sqlite3")
    } else {
        None
    }
}

/// The split index of a rosbag2 file name (`name_3.mcap` -> 3; 0 if it has none).
fn split_index(name: &str) -> u64 {
    let stem = name.split('.').next().unwrap_or(name);
    stem.rsplit('_')
        .next()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0)
}

/// Whether an output path names a rosbag2 directory: it ends with `/` or is an existing
/// directory.
pub fn is_directory_path(path: &Path) -> bool {
    path.as_os_str().to_string_lossy().ends_with('/') || path.is_dir()
}

/// The split file a rosbag2 directory written by this program holds: `<dir>/<dir name>_0.mcap`.
pub(crate) fn split_file_of(dir: &Path) -> PathBuf {
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .filter(|n| !n.is_empty() && n != "." && n != "..")
        .unwrap_or_else(|| "bag".to_owned());
    dir.join(format!("{name}_0.mcap"))
}

/// What [`MetadataWriter`] needs to know of one topic written.
#[derive(Debug, Clone, Default)]
pub(crate) struct WrittenTopic {
    pub type_name: String,
    pub count: u64,
}

/// Writes the `metadata.yaml` of a rosbag2 directory holding one MCAP split file.
pub(crate) struct MetadataWriter<'a> {
    pub dir: &'a Path,
    pub file: &'a Path,
    pub topics: &'a BTreeMap<String, WrittenTopic>,
    pub start_ns: Option<u64>,
    pub end_ns: Option<u64>,
    /// The command that derived the bag ([`BagWriteOptions::derived`](super::BagWriteOptions::derived)),
    /// kept in `custom_data` as `chronotope_derived_by`.
    pub derived: Option<&'a str>,
}

impl MetadataWriter<'_> {
    /// The YAML text (version 9).
    pub(crate) fn yaml(&self) -> String {
        let count: u64 = self.topics.values().map(|t| t.count).sum();
        let start = self.start_ns.unwrap_or(0);
        let duration = self.end_ns.unwrap_or(start).saturating_sub(start);
        let file = self
            .file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut y = String::new();
        y.push_str("rosbag2_bagfile_information:\n");
        y.push_str(&format!("  version: {METADATA_VERSION}\n"));
        y.push_str("  storage_identifier: mcap\n");
        y.push_str("  duration:\n");
        y.push_str(&format!("    nanoseconds: {duration}\n"));
        y.push_str("  starting_time:\n");
        y.push_str(&format!("    nanoseconds_since_epoch: {start}\n"));
        y.push_str(&format!("  message_count: {count}\n"));
        if self.topics.is_empty() {
            y.push_str("  topics_with_message_count: []\n");
        } else {
            y.push_str("  topics_with_message_count:\n");
        }
        for (name, t) in self.topics {
            y.push_str("    - topic_metadata:\n");
            y.push_str(&format!("        name: {}\n", yaml_str(name)));
            y.push_str(&format!("        type: {}\n", yaml_str(&t.type_name)));
            y.push_str("        serialization_format: cdr\n");
            y.push_str("        offered_qos_profiles:\n");
            for line in QOS_V9.lines() {
                y.push_str("          ");
                y.push_str(line);
                y.push('\n');
            }
            y.push_str("        type_description_hash: \"\"\n");
            y.push_str(&format!("      message_count: {}\n", t.count));
        }
        y.push_str("  compression_format: \"\"\n");
        y.push_str("  compression_mode: \"\"\n");
        y.push_str("  relative_file_paths:\n");
        y.push_str(&format!("    - {}\n", yaml_str(&file)));
        y.push_str("  files:\n");
        y.push_str(&format!("    - path: {}\n", yaml_str(&file)));
        y.push_str("      starting_time:\n");
        y.push_str(&format!("        nanoseconds_since_epoch: {start}\n"));
        y.push_str("      duration:\n");
        y.push_str(&format!("        nanoseconds: {duration}\n"));
        y.push_str(&format!("      message_count: {count}\n"));
        match self.derived {
            Some(by) => y.push_str(&format!(
                "  custom_data:\n    {DERIVED_KEY}: {}\n",
                yaml_str(by)
            )),
            None => y.push_str("  custom_data: {}\n"),
        }
        y.push_str("  ros_distro: chronotope\n");
        y
    }

    /// Writes `metadata.yaml` into the directory (complete or not at all, see
    /// [`crate::fsio::write_atomic`]).
    pub(crate) fn write(&self) -> Result<(), BagError> {
        let path = self.dir.join(METADATA_FILE);
        crate::fsio::write_atomic(&path, self.yaml().as_bytes()).map_err(|source| BagError::Io {
            path: path.clone(),
            action: "cannot write the metadata",
            source,
        })
    }
}

/// The `custom_data` key of `metadata.yaml` naming the command that derived a bag.
pub const DERIVED_KEY: &str = "chronotope_derived_by";

/// The offered QoS profile of every written topic, as version 9 writes it: the same profile as
/// the MCAP channels' [`OFFERED_QOS_PROFILES`](super::OFFERED_QOS_PROFILES) (reliable,
/// volatile, keep last 10, durations infinite), with enums by name.
const QOS_V9: &str = "\
- history: keep_last
  depth: 10
  reliability: reliable
  durability: volatile
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: automatic
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false";

/// A string as a YAML scalar: double-quoted with escapes (always valid, whatever it holds).
fn yaml_str(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| "\"\"".to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_indexes_sort_numerically() {
        assert_eq!(split_index("rec_10.mcap"), 10);
        assert_eq!(split_index("rec_2.db3.zstd"), 2);
        assert_eq!(split_index("rec.mcap"), 0);
    }

    #[test]
    fn written_metadata_parses_back() {
        let dir = tempfile::tempdir().unwrap();
        let mut topics = BTreeMap::new();
        topics.insert(
            "/a: b".to_owned(),
            WrittenTopic {
                type_name: "chronotope_msgs/msg/VoxelGrid".to_owned(),
                count: 3,
            },
        );
        let file = split_file_of(dir.path());
        let w = MetadataWriter {
            dir: dir.path(),
            file: &file,
            topics: &topics,
            start_ns: Some(5),
            end_ns: Some(25),
            derived: None,
        };
        w.write().unwrap();
        let back = Rosbag2Dir::open(dir.path()).unwrap();
        assert_eq!(back.version, Some(9));
        assert_eq!(back.files, vec![file]);
        assert_eq!(back.topics[0].name, "/a: b");
        assert_eq!(back.topics[0].message_count, 3);
        assert_eq!(back.duration_ns, Some(20));
        assert_eq!(back.message_count, Some(3));
        assert!(back.warnings.is_empty());
    }
}

#[cfg(test)]
mod hostile {
    use super::*;

    /// Mutated metadata files are refused or read, never a panic.
    #[test]
    fn mutated_metadata_never_panics() {
        let good = "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: sqlite3\n  \
                    relative_file_paths: [a_0.db3, a_1.db3]\n  compression_mode: FILE\n  \
                    compression_format: zstd\n  topics_with_message_count:\n    - topic_metadata: \
                    {name: /x, type: t, serialization_format: cdr}\n      message_count: 3\n";
        let dir = tempfile::tempdir().unwrap();
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..2000 {
            let mut bytes = good.as_bytes().to_vec();
            for _ in 0..(next() % 4 + 1) {
                let i = (next() % bytes.len() as u64) as usize;
                match next() % 3 {
                    0 => bytes[i] = (next() % 256) as u8,
                    1 => {
                        bytes.remove(i);
                    }
                    _ => bytes.insert(i, b"[]{}:-,\"'\n 9"[(next() % 12) as usize]),
                }
            }
            std::fs::write(dir.path().join(METADATA_FILE), &bytes).unwrap();
            if let Err(e) = Rosbag2Dir::open(dir.path()) {
                let s = e.to_string();
                assert!(!s.contains("{ ") && !s.is_empty(), "{s}");
            }
        }
    }
}
