//! Streaming reader of one rosbag2 SQLite storage file (`.db3`, what `ros2 bag record` writes
//! by default on Humble and Iron).
//!
//! The file's tables, as rosbag2 writes them: `topics(id, name, type, serialization_format,
//! offered_qos_profiles[, type_description_hash])`, `messages(id, topic_id, timestamp, data)`,
//! and, from Iron on, `message_definitions(topic_type, encoding, encoded_message_definition,
//! ...)`. Messages are read in row order (the order they were recorded, like an MCAP file's
//! order), a page at a time by row id, so memory stays at one page (at most
//! [`PAGE_BYTES`] of message data, or one message) however large the file; a message larger
//! than the reader's limit is skipped by its length alone, never loaded.
//!
//! A topic whose type has no stored definition (every Humble bag) gets a schema that names the
//! type and carries no text (encoding `""`); readers then trust the type name. A database that
//! fails part-way is reported ([`BagError::Sqlite`]) after the messages read before the failure.

use std::collections::{HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rusqlite::{Connection, OpenFlags, OptionalExtension};

use super::error::BagError;
use super::reader::{BagChannel, BagMessage, BagSchema, MAX_CHANNELS, MAX_SCHEMA_BYTES};
use super::recovery::{BagLoss, LossKind, Recovery};

/// Message data read from the database at a time (one page of rows): 16 MiB.
pub const PAGE_BYTES: usize = 16 << 20;

/// Rows read per page at most.
const PAGE_ROWS: i64 = 512;

/// The magic at the start of every SQLite 3 database file.
pub(crate) const SQLITE_MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// One topic of the file.
struct Topic {
    channel_id: u16,
    topic: String,
    schema: Arc<BagSchema>,
    message_encoding: String,
}

/// `path` as an SQLite URI that opens it read-only and immutable (every byte outside
/// `[A-Za-z0-9/._~-]` percent-encoded, so `?`, `#` and `%` in a path stay part of it).
fn sqlite_uri(path: &Path) -> String {
    use std::os::unix::ffi::OsStrExt;
    let mut uri = String::from("file:");
    for &b in path.as_os_str().as_bytes() {
        if b.is_ascii_alphanumeric() || b"/._~-".contains(&b) {
            uri.push(b as char);
        } else {
            uri.push_str(&format!("%{b:02X}"));
        }
    }
    uri.push_str("?mode=ro&immutable=1");
    uri
}

/// Reads the messages of one `.db3` file, in row order.
pub(crate) struct Db3Reader {
    conn: Connection,
    path: PathBuf,
    limit: usize,
    topics: HashMap<i64, Topic>,
    /// Topics beyond [`MAX_CHANNELS`] (by topic id, with their name): not read, counted.
    refused: HashMap<i64, String>,
    last_row: i64,
    page: VecDeque<Result<BagMessage, BagError>>,
    recovery: Recovery,
    done: bool,
}

impl Db3Reader {
    /// Opens `path` read-only and reads its topics and message definitions; errors and losses
    /// name the file as `name` (the compressed file a temporary copy came from).
    ///
    /// # Errors
    /// [`BagError::Sqlite`] if the file is not a readable SQLite database,
    /// [`BagError::NotABag`] if it lacks rosbag2's `topics` and `messages` tables.
    pub(crate) fn open(path: &Path, name: &Path, limit: usize) -> Result<Self, BagError> {
        let sql = |e: rusqlite::Error| BagError::Sqlite {
            path: name.to_path_buf(),
            reason: e.to_string(),
        };
        // Read-only and immutable: SQLite then takes no lock and creates nothing beside the
        // file (no -wal or -shm, as a database in WAL mode otherwise gets), so a bag in a
        // directory the user cannot write reads as PyPI rosbags reads it. A write-ahead log
        // left beside by a writer that did not close is therefore not read: said below.
        let conn = Connection::open_with_flags(
            sqlite_uri(path),
            OpenFlags::SQLITE_OPEN_READ_ONLY
                | OpenFlags::SQLITE_OPEN_URI
                | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(sql)?;
        let wal = {
            let mut w = path.as_os_str().to_owned();
            w.push("-wal");
            PathBuf::from(w)
        };
        let wal_bytes = std::fs::metadata(&wal).map(|m| m.len()).unwrap_or(0);
        let has_table = |name: &str| -> Result<bool, BagError> {
            conn.query_row(
                "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = ?1",
                [name],
                |r| r.get::<_, i64>(0),
            )
            .map(|n| n > 0)
            .map_err(sql)
        };
        for table in ["topics", "messages"] {
            if !has_table(table)? {
                return Err(BagError::NotABag {
                    path: name.to_path_buf(),
                    reason: format!(
                        "the SQLite database has no `{table}` table, so it is not a rosbag2 bag"
                    ),
                });
            }
        }
        // Message definitions (Iron and later): type -> (encoding, text).
        let mut definitions: HashMap<String, (String, String)> = HashMap::new();
        if has_table("message_definitions")? {
            let mut st = conn
                .prepare(
                    "SELECT topic_type, encoding, encoded_message_definition \
                     FROM message_definitions",
                )
                .map_err(sql)?;
            let rows = st
                .query_map([], |r| {
                    Ok((
                        r.get::<_, String>(0)?,
                        r.get::<_, String>(1)?,
                        r.get::<_, String>(2)?,
                    ))
                })
                .map_err(sql)?;
            let mut bytes = 0usize;
            for row in rows {
                let (ty, encoding, text) = row.map_err(sql)?;
                bytes += text.len();
                if bytes > MAX_SCHEMA_BYTES {
                    break;
                }
                definitions.insert(ty, (encoding, text));
            }
        }
        let mut reader = Self {
            conn,
            path: name.to_path_buf(),
            limit,
            topics: HashMap::new(),
            refused: HashMap::new(),
            last_row: i64::MIN,
            page: VecDeque::new(),
            recovery: Recovery {
                // The topics table is this format's summary: every topic is known up front.
                summary_used: true,
                ..Recovery::default()
            },
            done: false,
        };
        if wal_bytes > 0 {
            let reason = format!(
                "{} ({wal_bytes} bytes) lies beside the database: its writer did not close it, \
                 and what that log holds is not read (the database is read as it is, changing \
                 nothing and creating nothing beside it; to include the log, open a copy of the \
                 bag once with sqlite3)",
                wal.display()
            );
            reader.recovery.push(BagLoss {
                offset: 0,
                bytes: Some(wal_bytes),
                kind: LossKind::Database,
                reason: reason.clone(),
                messages: None,
                start_ns: None,
                end_ns: None,
                topics: Default::default(),
            });
            reader.page.push_back(Err(BagError::LogNotRead {
                path: name.to_path_buf(),
                reason,
            }));
        }
        let topics: Vec<(i64, String, String, String)> = {
            let mut st = reader
                .conn
                .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
                .map_err(sql)?;
            let rows = st
                .query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)))
                .map_err(sql)?;
            rows.collect::<Result<_, _>>().map_err(sql)?
        };
        for (id, name, ty, format) in topics {
            if reader.topics.len() >= MAX_CHANNELS {
                reader.refused.insert(id, name);
                continue;
            }
            let channel_id = reader.topics.len() as u16 + 1;
            let (encoding, text) = match definitions.get(&ty) {
                // rosbag2 stores "unknown" with an empty text when it had no definition.
                Some((e, t)) if !t.is_empty() && e != "unknown" => (e.clone(), t.clone()),
                _ => (String::new(), String::new()),
            };
            let schema = Arc::new(BagSchema {
                id: channel_id,
                name: ty,
                encoding,
                data: text.into_bytes(),
            });
            reader.topics.insert(
                id,
                Topic {
                    channel_id,
                    topic: name,
                    schema,
                    message_encoding: format,
                },
            );
        }
        let count: Option<i64> = reader
            .conn
            .query_row("SELECT count(*) FROM messages", [], |r| r.get(0))
            .optional()
            .ok()
            .flatten();
        reader.recovery.statistics_message_count = count.map(|n| n.max(0) as u64);
        Ok(reader)
    }

    /// The file being read.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// What reading has cost so far.
    pub(crate) fn recovery(&self) -> &Recovery {
        &self.recovery
    }

    /// The file's topics as channels (ids from 1, in topic id order).
    pub(crate) fn channels(&self) -> Vec<BagChannel> {
        let mut out: Vec<BagChannel> = self
            .topics
            .values()
            .map(|t| BagChannel {
                id: t.channel_id,
                topic: t.topic.clone(),
                schema_name: t.schema.name.clone(),
                message_encoding: t.message_encoding.clone(),
            })
            .collect();
        out.sort_by_key(|c| c.id);
        out
    }

    /// The schema of channel `id`.
    pub(crate) fn schema_of(&self, id: u16) -> Option<Arc<BagSchema>> {
        self.topics
            .values()
            .find(|t| t.channel_id == id)
            .map(|t| t.schema.clone())
    }

    /// Reads the next page of rows into `self.page`; false at the end of the table.
    fn read_page(&mut self) -> Result<bool, rusqlite::Error> {
        let Self {
            conn,
            path,
            limit,
            topics,
            refused,
            last_row,
            page,
            recovery,
            ..
        } = self;
        let mut st = conn.prepare_cached(
            "SELECT id, topic_id, timestamp, length(data), \
             CASE WHEN length(data) <= ?2 THEN data END \
             FROM messages WHERE id > ?1 ORDER BY id LIMIT ?3",
        )?;
        let max = i64::try_from(*limit).unwrap_or(i64::MAX);
        let mut rows = st.query(rusqlite::params![*last_row, max, PAGE_ROWS])?;
        let mut bytes = 0usize;
        let mut any = false;
        while let Some(row) = rows.next()? {
            any = true;
            let id: i64 = row.get(0)?;
            *last_row = id;
            let topic_id: i64 = row.get(1)?;
            let timestamp: i64 = row.get(2)?;
            let len: i64 = row.get::<_, Option<i64>>(3)?.unwrap_or(0);
            let mut lose =
                |kind: LossKind, reason: String, topic: Option<&str>, at: Option<u64>| {
                    recovery.push(BagLoss {
                        offset: id.max(0) as u64,
                        bytes: None,
                        kind,
                        reason: format!("message row {id}: {reason}"),
                        messages: Some(1),
                        start_ns: at,
                        end_ns: at,
                        topics: topic.into_iter().map(|t| (t.to_owned(), 1)).collect(),
                    });
                    BagError::BadRow {
                        path: path.clone(),
                        row: id,
                        reason,
                    }
                };
            let item = if let Some(name) = refused.get(&topic_id) {
                let reason = format!(
                    "topic {name} is beyond the limit of MAX_CHANNELS = {MAX_CHANNELS} topics \
                     per bag; its messages are not read"
                );
                Err(lose(LossKind::TooManyChannels, reason, Some(name), None))
            } else if let Some(t) = topics.get(&topic_id) {
                if timestamp < 0 {
                    let reason = format!("its timestamp {timestamp} ns is before 1970");
                    Err(lose(
                        LossKind::MalformedRecord,
                        reason,
                        Some(&t.topic),
                        None,
                    ))
                } else if len as u64 > *limit as u64 {
                    let reason = format!(
                        "its data is {len} bytes, more than the reader's limit of {limit} bytes"
                    );
                    let at = Some(timestamp as u64);
                    Err(lose(LossKind::RecordTooLarge, reason, Some(&t.topic), at))
                } else {
                    let data: Option<Vec<u8>> = row.get(4)?;
                    let data = data.unwrap_or_default();
                    bytes += data.len();
                    recovery.messages_read += 1;
                    recovery.note_unverified(path, super::recovery::NO_CRC_SQLITE);
                    Ok(BagMessage {
                        topic: t.topic.clone(),
                        channel_id: t.channel_id,
                        schema_name: t.schema.name.clone(),
                        schema: Some(t.schema.clone()),
                        message_encoding: t.message_encoding.clone(),
                        log_time_ns: timestamp as u64,
                        publish_time_ns: timestamp as u64,
                        sequence: 0,
                        data,
                    })
                }
            } else {
                let reason = format!("its topic_id {topic_id} is not in the topics table");
                Err(lose(LossKind::UndefinedChannel, reason, None, None))
            };
            page.push_back(item);
            if bytes >= PAGE_BYTES {
                break;
            }
        }
        Ok(any)
    }
}

impl Iterator for Db3Reader {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(item) = self.page.pop_front() {
                return Some(item);
            }
            if self.done {
                return None;
            }
            match self.read_page() {
                Ok(true) => {}
                Ok(false) => self.done = true,
                Err(e) => {
                    self.done = true;
                    let reason = format!(
                        "{e} (after message row {}; the rows before it were read)",
                        self.last_row
                    );
                    self.recovery.push(BagLoss {
                        offset: self.last_row.max(0) as u64,
                        bytes: None,
                        kind: LossKind::Database,
                        reason: reason.clone(),
                        messages: None,
                        start_ns: None,
                        end_ns: None,
                        topics: Default::default(),
                    });
                    // Rows already paged are delivered before the error.
                    self.page.push_back(Err(BagError::Sqlite {
                        path: self.path.clone(),
                        reason,
                    }));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rosbag2-shaped database with one good row and one of each fault.
    fn faulty_db(path: &Path) {
        let c = Connection::open(path).unwrap();
        c.execute_batch(
            "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
               serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
               timestamp INTEGER NOT NULL, data BLOB NOT NULL);
             INSERT INTO topics VALUES (1, '/a', 'std_msgs/msg/String', 'cdr', '');
             INSERT INTO messages VALUES (1, 1, 5, x'0001000003000000686900');
             INSERT INTO messages VALUES (2, 7, 6, x'00');
             INSERT INTO messages VALUES (3, 1, -1, x'00');
             INSERT INTO messages VALUES (4, 1, 8, zeroblob(100));
             INSERT INTO messages VALUES (5, 1, 9, x'00010000');",
        )
        .unwrap();
    }

    #[test]
    fn bad_rows_are_named_and_skipped() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("f.db3");
        faulty_db(&p);
        let r = Db3Reader::open(&p, &p, 64).unwrap();
        let items: Vec<_> = r.collect();
        let ok: Vec<u64> = items
            .iter()
            .filter_map(|i| i.as_ref().ok().map(|m| m.log_time_ns))
            .collect();
        assert_eq!(ok, vec![5, 9]);
        let errs: Vec<String> = items
            .iter()
            .filter_map(|i| i.as_ref().err().map(|e| e.to_string()))
            .collect();
        assert_eq!(errs.len(), 3, "{errs:?}");
        assert!(
            errs[0].contains("row 2") && errs[0].contains("topic_id 7"),
            "{errs:?}"
        );
        assert!(
            errs[1].contains("row 3") && errs[1].contains("before 1970"),
            "{errs:?}"
        );
        assert!(
            errs[2].contains("row 4") && errs[2].contains("limit of 64"),
            "{errs:?}"
        );
        assert!(items
            .iter()
            .all(|i| i.as_ref().err().is_none_or(|e| !e.is_fatal())));
    }

    #[test]
    fn a_type_without_a_definition_gets_a_named_empty_schema() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("f.db3");
        faulty_db(&p);
        let r = Db3Reader::open(&p, &p, 1 << 20).unwrap();
        let s = r.schema_of(1).unwrap();
        assert_eq!(s.name, "std_msgs/msg/String");
        assert!(s.encoding.is_empty() && s.data.is_empty());
        assert_eq!(r.recovery().statistics_message_count, Some(5));
    }

    #[test]
    fn a_database_without_the_tables_is_not_a_bag() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("f.db3");
        Connection::open(&p)
            .unwrap()
            .execute_batch("CREATE TABLE other(x);")
            .unwrap();
        let e = Db3Reader::open(&p, &p, 64).err().unwrap();
        assert!(e.to_string().contains("no `topics` table"), "{e}");
    }
}
