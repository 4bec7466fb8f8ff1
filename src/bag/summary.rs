//! The summary section of an MCAP file (channels, schemas, statistics), read without touching
//! the data section; `None` whenever it is missing or unreadable, so callers fall back to a
//! scan.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use super::records::{self, op};

/// Footer record (opcode, length, 20-byte body) and the end magic.
const FOOTER_AND_MAGIC: u64 = 1 + 8 + 20 + 8;
const MAGIC: [u8; 8] = [0x89, b'M', b'C', b'A', b'P', 0x30, b'\r', b'\n'];

/// One channel listed in the summary.
pub(crate) struct SummaryChannel {
    pub topic: String,
    pub schema_name: String,
    /// Messages on the channel, from the Statistics record.
    pub message_count: u64,
}

/// What the summary section says about the bag.
pub(crate) struct Summary {
    pub channels: Vec<SummaryChannel>,
    pub message_count: u64,
}

/// Reads the summary of the MCAP file at `path`, if it has a complete one (with statistics).
/// Records longer than `limit` are skipped.
///
/// # Errors
///
/// Only I/O errors opening or reading the file; a missing or malformed summary is `Ok(None)`.
pub(crate) fn read_summary(path: &Path, limit: usize) -> std::io::Result<Option<Summary>> {
    let file = File::open(path)?;
    let len = file.metadata()?.len();
    let mut file = BufReader::new(file);
    if len < MAGIC.len() as u64 + FOOTER_AND_MAGIC {
        return Ok(None);
    }
    let footer_start = len - FOOTER_AND_MAGIC;
    file.seek(SeekFrom::Start(footer_start))?;
    let mut tail = [0u8; FOOTER_AND_MAGIC as usize];
    file.read_exact(&mut tail)?;
    if tail[0] != op::FOOTER || tail[29..] != MAGIC {
        return Ok(None);
    }
    let Ok(footer) = records::footer(&tail[9..29]) else {
        return Ok(None);
    };
    let start = footer.summary_start;
    if start < MAGIC.len() as u64 || start >= footer_start {
        return Ok(None);
    }
    file.seek(SeekFrom::Start(start))?;
    let mut section = (&mut file).take(footer_start - start);
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut channels = Vec::new();
    let mut statistics = None;
    loop {
        let mut prefix = [0u8; 9];
        match section.read_exact(&mut prefix) {
            Ok(()) => {}
            Err(err) if err.kind() == std::io::ErrorKind::UnexpectedEof => break,
            Err(err) => return Err(err),
        }
        let opcode = prefix[0];
        let body_len = u64::from_le_bytes(prefix[1..].try_into().unwrap_or_default());
        if body_len > section.limit() {
            return Ok(None);
        }
        let wanted = matches!(opcode, op::SCHEMA | op::CHANNEL | op::STATISTICS);
        let body_len_usize = usize::try_from(body_len).unwrap_or(usize::MAX);
        if !wanted || body_len_usize > limit {
            std::io::copy(&mut (&mut section).take(body_len), &mut std::io::sink())?;
            continue;
        }
        // Bounded by the bytes left in the summary section (checked above) and by `limit`.
        let mut body = vec![0u8; body_len_usize];
        section.read_exact(&mut body)?;
        match opcode {
            op::SCHEMA => {
                let Ok(schema) = records::schema(&body) else {
                    return Ok(None);
                };
                schemas.insert(schema.id, schema.name);
            }
            op::CHANNEL => {
                let Ok(channel) = records::channel(&body) else {
                    return Ok(None);
                };
                channels.push(channel);
            }
            _ => {
                let Ok(stats) = records::statistics(&body) else {
                    return Ok(None);
                };
                statistics = Some(stats);
            }
        }
    }
    let Some(statistics) = statistics else {
        return Ok(None);
    };
    let channels = channels
        .into_iter()
        .map(|c| SummaryChannel {
            schema_name: schemas.get(&c.schema_id).cloned().unwrap_or_default(),
            message_count: statistics
                .channel_message_counts
                .get(&c.id)
                .copied()
                .unwrap_or(0),
            topic: c.topic,
        })
        .collect();
    Ok(Some(Summary {
        channels,
        message_count: statistics.message_count,
    }))
}
