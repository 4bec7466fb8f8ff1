//! Parsers for the few MCAP record bodies the bag reader needs, written so that every length
//! field is checked against the bytes actually present before anything is allocated.
//!
//! (The `mcap` crate's own `parse_record` reserves string buffers of the declared length first,
//! up to 4 GiB for a corrupt `u32`; here a bad length is an error string instead.) Layouts are
//! those of the MCAP specification, little endian throughout.

/// MCAP opcodes used here.
pub(crate) mod op {
    pub const HEADER: u8 = 0x01;
    pub const FOOTER: u8 = 0x02;
    pub const SCHEMA: u8 = 0x03;
    pub const CHANNEL: u8 = 0x04;
    pub const MESSAGE: u8 = 0x05;
    pub const CHUNK: u8 = 0x06;
    pub const MESSAGE_INDEX: u8 = 0x07;
    pub const CHUNK_INDEX: u8 = 0x08;
    pub const STATISTICS: u8 = 0x0B;
    pub const DATA_END: u8 = 0x0F;
}

/// True for the opcodes the MCAP specification defines (0x01-0x0F) and for private records
/// (0x80 and above); 0x00 and 0x10-0x7F never occur in a sound file, so meeting one means the
/// reader is not at a record boundary.
pub(crate) fn known_opcode(opcode: u8) -> bool {
    matches!(opcode, 0x01..=0x0F | 0x80..=0xFF)
}

/// Why a record body could not be parsed.
pub(crate) type ParseError = String;

/// A bounded little-endian cursor over a record body.
struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], ParseError> {
        let data = self.data;
        match self
            .pos
            .checked_add(n)
            .and_then(|end| data.get(self.pos..end))
        {
            Some(bytes) => {
                self.pos += n;
                Ok(bytes)
            }
            None => Err(format!(
                "{what} needs {n} bytes at record byte {}, but the record has {} bytes",
                self.pos,
                data.len()
            )),
        }
    }

    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], ParseError> {
        let mut out = [0; N];
        out.copy_from_slice(self.take(N, what)?);
        Ok(out)
    }

    fn u16(&mut self, what: &str) -> Result<u16, ParseError> {
        Ok(u16::from_le_bytes(self.array(what)?))
    }

    fn u32(&mut self, what: &str) -> Result<u32, ParseError> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    fn u64(&mut self, what: &str) -> Result<u64, ParseError> {
        Ok(u64::from_le_bytes(self.array(what)?))
    }

    /// A `u32`-length-prefixed byte string.
    fn bytes(&mut self, what: &str) -> Result<&'a [u8], ParseError> {
        let len = self.u32(what)?;
        let len = usize::try_from(len).map_err(|_| format!("{what} length {len} is too large"))?;
        self.take(len, what)
    }

    /// A `u32`-length-prefixed UTF-8 string.
    fn string(&mut self, what: &str) -> Result<String, ParseError> {
        let bytes = self.bytes(what)?;
        std::str::from_utf8(bytes)
            .map(str::to_owned)
            .map_err(|_| format!("{what} is not valid UTF-8"))
    }

    fn rest(&mut self) -> &'a [u8] {
        let rest = &self.data[self.pos..];
        self.pos = self.data.len();
        rest
    }
}

/// Header record: the file's profile and writing library.
pub(crate) struct HeaderRecord {
    pub profile: String,
}

pub(crate) fn header(body: &[u8]) -> Result<HeaderRecord, ParseError> {
    let mut c = Cursor::new(body);
    Ok(HeaderRecord {
        profile: c.string("profile")?,
    })
}

/// Footer record: where the summary section starts (0 if there is none).
pub(crate) struct FooterRecord {
    pub summary_start: u64,
}

pub(crate) fn footer(body: &[u8]) -> Result<FooterRecord, ParseError> {
    let mut c = Cursor::new(body);
    Ok(FooterRecord {
        summary_start: c.u64("summary start")?,
    })
}

/// Schema record.
pub(crate) struct SchemaRecord<'a> {
    pub id: u16,
    pub name: String,
    pub encoding: String,
    pub data: &'a [u8],
}

pub(crate) fn schema(body: &[u8]) -> Result<SchemaRecord<'_>, ParseError> {
    let mut c = Cursor::new(body);
    let id = c.u16("schema id")?;
    let name = c.string("schema name")?;
    let encoding = c.string("schema encoding")?;
    let data = c.bytes("schema data")?;
    if id == 0 {
        return Err("schema id 0 is reserved for \"no schema\"".to_owned());
    }
    Ok(SchemaRecord {
        id,
        name,
        encoding,
        data,
    })
}

/// Channel record.
pub(crate) struct ChannelRecord {
    pub id: u16,
    pub schema_id: u16,
    pub topic: String,
    pub message_encoding: String,
}

pub(crate) fn channel(body: &[u8]) -> Result<ChannelRecord, ParseError> {
    let mut c = Cursor::new(body);
    let id = c.u16("channel id")?;
    let schema_id = c.u16("schema id")?;
    let topic = c.string("topic")?;
    let message_encoding = c.string("message encoding")?;
    let map = c.bytes("metadata")?;
    // The metadata (QoS profiles) is not needed, but must be well-formed.
    let mut m = Cursor::new(map);
    while m.pos < map.len() {
        m.bytes("metadata key")?;
        m.bytes("metadata value")?;
    }
    Ok(ChannelRecord {
        id,
        schema_id,
        topic,
        message_encoding,
    })
}

/// Message record; `data` borrows from the body.
pub(crate) struct MessageRecord<'a> {
    pub channel_id: u16,
    pub sequence: u32,
    pub log_time: u64,
    pub publish_time: u64,
    pub data: &'a [u8],
}

pub(crate) fn message(body: &[u8]) -> Result<MessageRecord<'_>, ParseError> {
    let mut c = Cursor::new(body);
    Ok(MessageRecord {
        channel_id: c.u16("channel id")?,
        sequence: c.u32("sequence")?,
        log_time: c.u64("log time")?,
        publish_time: c.u64("publish time")?,
        data: c.rest(),
    })
}

/// Chunk record header; `records` are the (possibly compressed) records it holds.
pub(crate) struct ChunkRecord<'a> {
    pub message_start_time: u64,
    pub message_end_time: u64,
    pub uncompressed_size: u64,
    pub uncompressed_crc: u32,
    pub compression: String,
    pub records: &'a [u8],
}

pub(crate) fn chunk(body: &[u8]) -> Result<ChunkRecord<'_>, ParseError> {
    let mut c = Cursor::new(body);
    let message_start_time = c.u64("message start time")?;
    let message_end_time = c.u64("message end time")?;
    let uncompressed_size = c.u64("uncompressed size")?;
    let uncompressed_crc = c.u32("uncompressed CRC")?;
    let compression = c.string("compression")?;
    let compressed_size = c.u64("compressed size")?;
    let compressed_size = usize::try_from(compressed_size)
        .map_err(|_| format!("compressed size {compressed_size} is too large"))?;
    let records = c.take(compressed_size, "chunk records")?;
    if c.pos != body.len() {
        return Err(format!(
            "the chunk record is {} bytes, but its header and records take {}",
            body.len(),
            c.pos
        ));
    }
    Ok(ChunkRecord {
        message_start_time,
        message_end_time,
        uncompressed_size,
        uncompressed_crc,
        compression,
        records,
    })
}

/// Message Index record: how many messages of one channel a chunk holds, and their log times.
pub(crate) struct MessageIndexRecord {
    pub channel_id: u16,
    pub count: u64,
    pub first_time: Option<u64>,
    pub last_time: Option<u64>,
}

pub(crate) fn message_index(body: &[u8]) -> Result<MessageIndexRecord, ParseError> {
    let mut c = Cursor::new(body);
    let channel_id = c.u16("channel id")?;
    let entries = c.bytes("message index entries")?;
    if entries.len() % 16 != 0 {
        return Err(format!(
            "message index entries take {} bytes, not a multiple of 16",
            entries.len()
        ));
    }
    let mut first_time: Option<u64> = None;
    let mut last_time: Option<u64> = None;
    for entry in entries.chunks_exact(16) {
        let mut t = [0u8; 8];
        t.copy_from_slice(&entry[..8]);
        let t = u64::from_le_bytes(t);
        first_time = Some(first_time.map_or(t, |f| f.min(t)));
        last_time = Some(last_time.map_or(t, |l| l.max(t)));
    }
    Ok(MessageIndexRecord {
        channel_id,
        count: (entries.len() / 16) as u64,
        first_time,
        last_time,
    })
}

/// Chunk Index record (summary section): where a chunk is and what it covers.
#[derive(Debug, Clone)]
pub(crate) struct ChunkIndexRecord {
    pub message_start_time: u64,
    pub message_end_time: u64,
    pub chunk_start_offset: u64,
    pub chunk_length: u64,
    /// Channels with a Message Index record after the chunk (0: the chunk has no messages).
    pub message_index_channels: usize,
}

pub(crate) fn chunk_index(body: &[u8]) -> Result<ChunkIndexRecord, ParseError> {
    let mut c = Cursor::new(body);
    let message_start_time = c.u64("message start time")?;
    let message_end_time = c.u64("message end time")?;
    let chunk_start_offset = c.u64("chunk start offset")?;
    let chunk_length = c.u64("chunk length")?;
    let map = c.bytes("message index offsets")?;
    if map.len() % 10 != 0 {
        return Err(format!(
            "message index offsets take {} bytes, not a multiple of 10",
            map.len()
        ));
    }
    c.u64("message index length")?;
    c.string("compression")?;
    c.u64("compressed size")?;
    c.u64("uncompressed size")?;
    Ok(ChunkIndexRecord {
        message_start_time,
        message_end_time,
        chunk_start_offset,
        chunk_length,
        message_index_channels: map.len() / 10,
    })
}

/// Checks that `records` is a whole sequence of `opcode, u64 length, body` records: the framing
/// of an uncompressed chunk, verified before the chunk is handed to the `mcap` reader.
pub(crate) fn check_framing(records: &[u8]) -> Result<(), ParseError> {
    let mut c = Cursor::new(records);
    while c.pos < records.len() {
        let start = c.pos;
        c.take(1, "record opcode")?;
        let len = c.u64("record length")?;
        let len = usize::try_from(len).map_err(|_| format!("record length {len} is too large"))?;
        c.take(len, "record body").map_err(|_| {
            format!(
                "record at chunk byte {start} claims {len} bytes, but only {} remain",
                records.len() - c.pos
            )
        })?;
    }
    Ok(())
}

/// Statistics record: message counts.
pub(crate) struct StatisticsRecord {
    pub message_count: u64,
}

pub(crate) fn statistics(body: &[u8]) -> Result<StatisticsRecord, ParseError> {
    let mut c = Cursor::new(body);
    let message_count = c.u64("message count")?;
    c.u16("schema count")?;
    c.u32("channel count")?;
    c.u32("attachment count")?;
    c.u32("metadata count")?;
    c.u32("chunk count")?;
    c.u64("message start time")?;
    c.u64("message end time")?;
    let map = c.bytes("channel message counts")?;
    if map.len() % 10 != 0 {
        return Err(format!(
            "channel message counts take {} bytes, not a multiple of 10",
            map.len()
        ));
    }
    Ok(StatisticsRecord { message_count })
}
