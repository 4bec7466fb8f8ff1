//! Streaming reader of the messages of an MCAP file, in file order, with bounded memory.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::McapError;

use super::error::{BagError, RecordLocation};
use super::records::{self, op};

/// The MCAP magic that starts (and ends) every file.
const MAGIC: [u8; 8] = [0x89, b'M', b'C', b'A', b'P', 0x30, b'\r', b'\n'];
/// Opcode and length prefix of every record.
const RECORD_PREFIX: usize = 1 + 8;
/// Most bytes handed to the MCAP reader per read; larger records arrive in several reads, so
/// the buffer only ever grows by data that is really in the file.
const READ_BLOCK: usize = 1 << 20;

/// Default of [`BagReadOptions::max_record_bytes`]: 256 MiB.
pub const DEFAULT_MAX_RECORD_BYTES: usize = 256 << 20;

/// Options of [`BagReader::open_with`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BagReadOptions {
    max_record_bytes: usize,
}

impl Default for BagReadOptions {
    fn default() -> Self {
        Self {
            max_record_bytes: DEFAULT_MAX_RECORD_BYTES,
        }
    }
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
}

/// One message of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagMessage {
    /// The channel's topic.
    pub topic: String,
    /// The channel's schema name (`pkg/msg/Type`), empty for a channel without schema.
    pub schema_name: String,
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
struct ChannelInfo {
    topic: String,
    schema_id: u16,
    message_encoding: String,
}

/// Reads the messages of an MCAP file in file order, streaming: memory stays at about one
/// chunk (or one unchunked message), however large the file.
///
/// The reader is an iterator of `Result<BagMessage, BagError>`. Errors that leave the file
/// structure readable (a chunk that fails to decompress or its CRC, a malformed record, a
/// message on an undefined channel) are yielded and reading goes on; others (truncation, broken
/// framing, I/O) are yielded once and end the iteration ([`BagError::is_fatal`]). No content
/// of the file can make it panic, and every length field is checked against the data present
/// or against [`BagReadOptions::max_record_bytes`] before anything is allocated.
///
/// ```no_run
/// use chronotope::bag::BagReader;
/// for message in BagReader::open("in.mcap")? {
///     let message = message?;
///     println!("{} {} {} bytes", message.topic, message.log_time_ns, message.data.len());
/// }
/// # Ok::<(), chronotope::bag::BagError>(())
/// ```
pub struct BagReader {
    source: BufReader<File>,
    /// Frames the top-level records; yields chunks whole (`emit_chunks`).
    outer: LinearReader,
    /// Bytes handed to `outer` so far.
    fed: u64,
    /// File offset of the next top-level record (exact: records follow one another).
    next_offset: u64,
    /// The chunk being read, if any.
    chunk: Option<ChunkCursor>,
    state: State,
    done: bool,
}

/// What records have told the reader so far.
struct State {
    path: PathBuf,
    limit: usize,
    profile: Option<String>,
    schemas: HashMap<u16, Arc<str>>,
    channels: HashMap<u16, ChannelInfo>,
}

/// The records of one chunk, decompressed (and CRC-checked) by a reader of its own, so that a
/// bad chunk costs only its own messages.
struct ChunkCursor {
    reader: LinearReader,
    offset: u64,
    index: usize,
}

impl BagReader {
    /// Opens an MCAP file with the default options and reads its header.
    ///
    /// # Errors
    ///
    /// [`BagError::Io`] if the file cannot be opened, [`BagError::NotMcap`] if it does not
    /// start with the MCAP magic and a Header record, [`BagError::Truncated`] if it ends first.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, BagError> {
        Self::open_with(path, BagReadOptions::default())
    }

    /// Opens an MCAP file with the given options and reads its header.
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
        let mut source = BufReader::with_capacity(256 << 10, file);
        let mut magic = [0u8; MAGIC.len()];
        let got = read_full(&mut source, &mut magic).map_err(|source| BagError::Io {
            path: path.clone(),
            action: "cannot read the bag",
            source,
        })?;
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
        let mut outer = LinearReader::new_with_options(
            LinearReaderOptions::default()
                .with_emit_chunks(true)
                .with_record_length_limit(options.max_record_bytes),
        );
        outer.insert(MAGIC.len()).copy_from_slice(&MAGIC);
        outer.notify_read(MAGIC.len());
        let mut reader = Self {
            source,
            outer,
            fed: MAGIC.len() as u64,
            next_offset: MAGIC.len() as u64,
            chunk: None,
            state: State {
                path,
                limit: options.max_record_bytes,
                profile: None,
                schemas: HashMap::new(),
                channels: HashMap::new(),
            },
            done: false,
        };
        reader.read_header()?;
        Ok(reader)
    }

    /// The file being read.
    pub fn path(&self) -> &Path {
        &self.state.path
    }

    /// The profile in the file's Header record (`ros2` for rosbag2 files).
    pub fn profile(&self) -> &str {
        self.state.profile.as_deref().unwrap_or_default()
    }

    /// Reads up to the Header record, which must come first.
    fn read_header(&mut self) -> Result<(), BagError> {
        loop {
            match self.outer.next_event() {
                Some(Ok(LinearReadEvent::ReadRequest(need))) => self.feed(need)?,
                Some(Ok(LinearReadEvent::Record { opcode, data })) => {
                    let offset = self.next_offset;
                    self.next_offset += (RECORD_PREFIX + data.len()) as u64;
                    if opcode != op::HEADER {
                        return Err(BagError::NotMcap {
                            path: self.state.path.clone(),
                            reason: format!(
                                "the first record (at byte {offset}) has opcode {opcode:#04x}, \
                                 not that of a Header"
                            ),
                        });
                    }
                    let header = records::header(data).map_err(|reason| BagError::NotMcap {
                        path: self.state.path.clone(),
                        reason: format!("malformed Header record: {reason}"),
                    })?;
                    self.state.profile = Some(header.profile);
                    return Ok(());
                }
                Some(Err(err)) => return Err(self.outer_error(err)),
                None => {
                    return Err(BagError::Truncated {
                        path: self.state.path.clone(),
                        offset: self.fed,
                    })
                }
            }
        }
    }

    /// Hands up to `need` more bytes of the file to the outer reader (0 at the end of the file).
    fn feed(&mut self, need: usize) -> Result<(), BagError> {
        let n = need.clamp(1, READ_BLOCK);
        let buf = self.outer.insert(n);
        let got = read_full(&mut self.source, buf).map_err(|source| BagError::Io {
            path: self.state.path.clone(),
            action: "cannot read the bag",
            source,
        })?;
        self.outer.notify_read(got);
        self.fed += got as u64;
        Ok(())
    }

    /// Turns an error of the outer (framing) reader into a fatal [`BagError`].
    fn outer_error(&self, err: McapError) -> BagError {
        let path = self.state.path.clone();
        let offset = self.next_offset;
        match err {
            McapError::UnexpectedEof => BagError::Truncated {
                path,
                offset: self.fed,
            },
            McapError::RecordTooLarge { opcode, len } => BagError::RecordTooLarge {
                path,
                offset,
                opcode,
                len,
                limit: self.state.limit,
            },
            McapError::BadMagic => BagError::Corrupt {
                path,
                offset,
                reason: "the MCAP magic is missing after the footer".to_owned(),
            },
            other => BagError::Corrupt {
                path,
                offset,
                reason: other.to_string(),
            },
        }
    }

    /// Sets up reading of the chunk record `body` found at `offset`.
    fn start_chunk(state: &State, offset: u64, body: &[u8]) -> Result<ChunkCursor, BagError> {
        let bad = |reason: String| BagError::CorruptChunk {
            path: state.path.clone(),
            offset,
            reason,
        };
        let chunk = records::chunk(body).map_err(bad)?;
        if chunk.uncompressed_size > state.limit as u64 {
            return Err(BagError::RecordTooLarge {
                path: state.path.clone(),
                offset,
                opcode: op::CHUNK,
                len: chunk.uncompressed_size,
                limit: state.limit,
            });
        }
        match chunk.compression.as_str() {
            // Checked here because the mcap reader trusts the record lengths of uncompressed
            // chunks once the data is there.
            "" => records::check_framing(chunk.records).map_err(bad)?,
            "zstd" | "lz4" => {}
            other => {
                return Err(bad(format!(
                    "unsupported compression {other:?} (zstd, lz4 and none are read)"
                )))
            }
        }
        let mut reader = LinearReader::new_with_options(
            LinearReaderOptions::default()
                .with_skip_start_magic(true)
                .with_skip_end_magic(true)
                .with_prevalidate_chunk_crcs(true)
                .with_record_length_limit(state.limit),
        );
        let buf = reader.insert(RECORD_PREFIX + body.len());
        buf[0] = op::CHUNK;
        buf[1..RECORD_PREFIX].copy_from_slice(&(body.len() as u64).to_le_bytes());
        buf[RECORD_PREFIX..].copy_from_slice(body);
        reader.notify_read(RECORD_PREFIX + body.len());
        Ok(ChunkCursor {
            reader,
            offset,
            index: 0,
        })
    }
}

impl State {
    /// Takes in one record; returns a message (or an error) if the record is a message.
    fn record(
        &mut self,
        opcode: u8,
        body: &[u8],
        location: RecordLocation,
    ) -> Option<Result<BagMessage, BagError>> {
        let bad = |kind: &'static str, reason: String| BagError::BadRecord {
            path: self.path.clone(),
            location,
            kind,
            reason,
        };
        match opcode {
            op::SCHEMA => match records::schema(body) {
                Ok(schema) => {
                    self.schemas.insert(schema.id, schema.name.into());
                    None
                }
                Err(reason) => Some(Err(bad("Schema", reason))),
            },
            op::CHANNEL => match records::channel(body) {
                Ok(channel) => {
                    self.channels.insert(
                        channel.id,
                        ChannelInfo {
                            topic: channel.topic,
                            schema_id: channel.schema_id,
                            message_encoding: channel.message_encoding,
                        },
                    );
                    None
                }
                Err(reason) => Some(Err(bad("Channel", reason))),
            },
            op::MESSAGE => Some(self.message(body, location)),
            _ => None,
        }
    }

    fn message(&self, body: &[u8], location: RecordLocation) -> Result<BagMessage, BagError> {
        let message = records::message(body).map_err(|reason| BagError::BadRecord {
            path: self.path.clone(),
            location,
            kind: "Message",
            reason,
        })?;
        let Some(channel) = self.channels.get(&message.channel_id) else {
            return Err(BagError::UnknownChannel {
                path: self.path.clone(),
                location,
                channel_id: message.channel_id,
            });
        };
        let schema_name = match channel.schema_id {
            0 => "",
            id => match self.schemas.get(&id) {
                Some(name) => name,
                None => {
                    return Err(BagError::UnknownSchema {
                        path: self.path.clone(),
                        location,
                        topic: channel.topic.clone(),
                        schema_id: id,
                    })
                }
            },
        };
        Ok(BagMessage {
            topic: channel.topic.clone(),
            schema_name: schema_name.to_owned(),
            message_encoding: channel.message_encoding.clone(),
            log_time_ns: message.log_time,
            publish_time_ns: message.publish_time,
            sequence: message.sequence,
            data: message.data.to_vec(),
        })
    }
}

impl Iterator for BagReader {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.done {
            if let Some(chunk) = &mut self.chunk {
                match chunk.reader.next_event() {
                    None => self.chunk = None,
                    // The whole chunk was handed over at the start: tell the reader that is all.
                    Some(Ok(LinearReadEvent::ReadRequest(_))) => chunk.reader.notify_read(0),
                    Some(Ok(LinearReadEvent::Record { opcode, data })) => {
                        let location = RecordLocation::Chunk {
                            chunk_offset: chunk.offset,
                            index: chunk.index,
                        };
                        chunk.index += 1;
                        if let Some(item) = self.state.record(opcode, data, location) {
                            return Some(item);
                        }
                    }
                    Some(Err(err)) => {
                        let offset = chunk.offset;
                        self.chunk = None;
                        return Some(Err(BagError::CorruptChunk {
                            path: self.state.path.clone(),
                            offset,
                            reason: err.to_string(),
                        }));
                    }
                }
                continue;
            }
            match self.outer.next_event() {
                None => self.done = true,
                Some(Ok(LinearReadEvent::ReadRequest(need))) => {
                    if let Err(err) = self.feed(need) {
                        self.done = true;
                        return Some(Err(err));
                    }
                }
                Some(Ok(LinearReadEvent::Record { opcode, data })) => {
                    let offset = self.next_offset;
                    self.next_offset += (RECORD_PREFIX + data.len()) as u64;
                    if opcode == op::CHUNK {
                        match Self::start_chunk(&self.state, offset, data) {
                            Ok(chunk) => self.chunk = Some(chunk),
                            Err(err) => return Some(Err(err)),
                        }
                    } else if let Some(item) =
                        self.state
                            .record(opcode, data, RecordLocation::File { offset })
                    {
                        return Some(item);
                    }
                }
                Some(Err(err)) => {
                    self.done = true;
                    return Some(Err(self.outer_error(err)));
                }
            }
        }
        None
    }
}

/// Reads until `buf` is full or the end of the file; returns the bytes read.
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
