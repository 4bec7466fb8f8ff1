//! Parsers for the few MCAP record bodies the bag reader needs, written so that every length
//! field is checked against the bytes actually present before anything is allocated.
//!
//! (The `mcap` crate's own `parse_record` reserves string buffers of the declared length first,
//! up to 4 GiB for a corrupt `u32`; here a bad length is an error string instead.) Layouts are
//! those of the MCAP specification, little endian throughout.

use std::collections::BTreeMap;

/// MCAP opcodes used here.
pub(crate) mod op {
    pub const HEADER: u8 = 0x01;
    pub const FOOTER: u8 = 0x02;
    pub const SCHEMA: u8 = 0x03;
    pub const CHANNEL: u8 = 0x04;
    pub const MESSAGE: u8 = 0x05;
    pub const CHUNK: u8 = 0x06;
    pub const STATISTICS: u8 = 0x0B;
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

/// Schema record, without its data.
pub(crate) struct SchemaRecord {
    pub id: u16,
    pub name: String,
}

pub(crate) fn schema(body: &[u8]) -> Result<SchemaRecord, ParseError> {
    let mut c = Cursor::new(body);
    let id = c.u16("schema id")?;
    let name = c.string("schema name")?;
    c.string("schema encoding")?;
    c.bytes("schema data")?;
    if id == 0 {
        return Err("schema id 0 is reserved for \"no schema\"".to_owned());
    }
    Ok(SchemaRecord { id, name })
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
    pub uncompressed_size: u64,
    pub compression: String,
    pub records: &'a [u8],
}

pub(crate) fn chunk(body: &[u8]) -> Result<ChunkRecord<'_>, ParseError> {
    let mut c = Cursor::new(body);
    c.u64("message start time")?;
    c.u64("message end time")?;
    let uncompressed_size = c.u64("uncompressed size")?;
    c.u32("uncompressed CRC")?;
    let compression = c.string("compression")?;
    let compressed_size = c.u64("compressed size")?;
    let compressed_size = usize::try_from(compressed_size)
        .map_err(|_| format!("compressed size {compressed_size} is too large"))?;
    let records = c.take(compressed_size, "chunk records")?;
    Ok(ChunkRecord {
        uncompressed_size,
        compression,
        records,
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
    pub channel_message_counts: BTreeMap<u16, u64>,
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
    let mut m = Cursor::new(map);
    let mut channel_message_counts = BTreeMap::new();
    while m.pos < map.len() {
        let id = m.u16("channel id")?;
        let count = m.u64("message count")?;
        channel_message_counts.insert(id, count);
    }
    Ok(StatisticsRecord {
        message_count,
        channel_message_counts,
    })
}
