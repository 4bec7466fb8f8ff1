//! The summary section of an MCAP file (schemas, channels, chunk indexes, statistics), read
//! without touching the data section. Used only to *find* things (channel definitions that a
//! damaged chunk took with it, where each chunk starts and how long it is); what the bag holds
//! is decided from the data.

use std::io::{Read, Seek, SeekFrom};

use super::records::{self, op, ChannelRecord, ChunkIndexRecord};

/// Footer record (opcode, length, 20-byte body) and the end magic.
pub(crate) const FOOTER_AND_MAGIC: u64 = 1 + 8 + 20 + 8;
pub(crate) const MAGIC: [u8; 8] = [0x89, b'M', b'C', b'A', b'P', 0x30, b'\r', b'\n'];
/// Data End record: opcode, length, 4-byte CRC.
const DATA_END_LEN: u64 = 1 + 8 + 4;

/// A schema listed in the summary.
pub(crate) struct SummarySchema {
    pub id: u16,
    pub name: String,
    pub encoding: String,
    pub data: Vec<u8>,
}

/// What the summary section says, as far as it could be parsed.
#[derive(Default)]
pub(crate) struct Summary {
    /// True if the file ends with a well-formed Footer and the magic.
    pub tail_ok: bool,
    /// Where the summary section starts (the end of the data section), if the footer names a
    /// plausible one, preceded by a Data End record.
    pub summary_start: Option<u64>,
    pub schemas: Vec<SummarySchema>,
    pub channels: Vec<ChannelRecord>,
    /// Chunk indexes that lie within the data section, sorted by offset, non-overlapping.
    pub chunk_indexes: Vec<ChunkIndexRecord>,
    /// The Statistics record's message count (for comparison only).
    pub message_count: Option<u64>,
    /// False if any summary record was malformed (what came before it is kept).
    pub complete: bool,
}

/// Reads the summary of an MCAP file of `len` bytes. Records longer than `limit` are skipped.
///
/// # Errors
///
/// Only I/O errors; a missing or malformed summary gives a `Summary` with what could be read.
pub(crate) fn read_summary(
    file: &mut (impl Read + Seek),
    len: u64,
    limit: usize,
) -> std::io::Result<Summary> {
    let mut summary = Summary::default();
    if len < MAGIC.len() as u64 + FOOTER_AND_MAGIC {
        return Ok(summary);
    }
    let footer_start = len - FOOTER_AND_MAGIC;
    file.seek(SeekFrom::Start(footer_start))?;
    let mut tail = [0u8; FOOTER_AND_MAGIC as usize];
    file.read_exact(&mut tail)?;
    if tail[0] != op::FOOTER || tail[1..9] != 20u64.to_le_bytes() || tail[29..] != MAGIC {
        return Ok(summary);
    }
    summary.tail_ok = true;
    let Ok(footer) = records::footer(&tail[9..29]) else {
        return Ok(summary);
    };
    let start = footer.summary_start;
    if start < MAGIC.len() as u64 + DATA_END_LEN || start > footer_start {
        return Ok(summary);
    }
    // The writer puts a Data End record right before the summary: if it is not there, the
    // footer's offset does not describe this file (bytes were inserted or removed).
    file.seek(SeekFrom::Start(start - DATA_END_LEN))?;
    let mut data_end = [0u8; 9];
    file.read_exact(&mut data_end)?;
    if data_end[0] != op::DATA_END || data_end[1..] != 4u64.to_le_bytes() {
        return Ok(summary);
    }
    summary.summary_start = Some(start);
    file.seek(SeekFrom::Start(start))?;
    let mut section = file.take(footer_start - start);
    let mut complete = true;
    loop {
        let mut prefix = [0u8; 9];
        match section.read_exact(&mut prefix) {
            Ok(()) => {}
            Err(err) if err.kind() == std::io::ErrorKind::UnexpectedEof => {
                // A partial prefix means the last record is cut.
                break;
            }
            Err(err) => return Err(err),
        }
        let opcode = prefix[0];
        let mut len_bytes = [0u8; 8];
        len_bytes.copy_from_slice(&prefix[1..]);
        let body_len = u64::from_le_bytes(len_bytes);
        if body_len > section.limit() || !records::known_opcode(opcode) {
            complete = false;
            break;
        }
        let wanted = matches!(
            opcode,
            op::SCHEMA | op::CHANNEL | op::STATISTICS | op::CHUNK_INDEX
        );
        let body_len_usize = usize::try_from(body_len).unwrap_or(usize::MAX);
        if !wanted || body_len_usize > limit {
            std::io::copy(&mut (&mut section).take(body_len), &mut std::io::sink())?;
            continue;
        }
        // Bounded by the bytes left in the summary section (checked above) and by `limit`.
        let mut body = vec![0u8; body_len_usize];
        section.read_exact(&mut body)?;
        let ok = match opcode {
            op::SCHEMA => records::schema(&body)
                .map(|s| {
                    summary.schemas.push(SummarySchema {
                        id: s.id,
                        name: s.name,
                        encoding: s.encoding,
                        data: s.data.to_vec(),
                    })
                })
                .is_ok(),
            op::CHANNEL => records::channel(&body)
                .map(|c| summary.channels.push(c))
                .is_ok(),
            op::CHUNK_INDEX => records::chunk_index(&body)
                .map(|c| summary.chunk_indexes.push(c))
                .is_ok(),
            _ => records::statistics(&body)
                .map(|s| summary.message_count = Some(s.message_count))
                .is_ok(),
        };
        if !ok {
            complete = false;
            break;
        }
    }
    summary.complete = complete;
    // Keep the chunk indexes that lie inside the data section, in file order, without overlap.
    let data_end = start - DATA_END_LEN;
    summary.chunk_indexes.retain(|c| {
        c.chunk_start_offset >= MAGIC.len() as u64
            && c.chunk_length >= 9
            && c.chunk_start_offset
                .checked_add(c.chunk_length)
                .is_some_and(|end| end <= data_end)
    });
    summary.chunk_indexes.sort_by_key(|c| c.chunk_start_offset);
    let mut end = 0;
    summary.chunk_indexes.retain(|c| {
        let keep = c.chunk_start_offset >= end;
        if keep {
            end = c.chunk_start_offset + c.chunk_length;
        }
        keep
    });
    Ok(summary)
}
