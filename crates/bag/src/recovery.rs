//! What reading a damaged bag cost: per damaged region its file offset, what was wrong, and
//! the messages and time span lost when the file still says so ([`Recovery`], [`BagLoss`]).
//!
//! Counts come from the chunk's own Message Index records (which follow the chunk in the file)
//! or from the summary's Chunk Index; time spans from the chunk header, the Chunk Index or the
//! message index entries. When none of these survived the count is `None` ("unknown"), never
//! a guess.

use std::collections::BTreeMap;

use serde::Serialize;

/// Most damaged regions listed one by one in a [`Recovery`]; further ones are only counted
/// (in [`Recovery::losses_not_listed`] and the totals), so a file of nothing but damage costs
/// bounded memory.
pub const MAX_LISTED_LOSSES: usize = 1000;

/// What was wrong with a damaged region of a bag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LossKind {
    /// A chunk's records do not match its CRC.
    ChunkCrc,
    /// A chunk does not decompress (or its compression is unknown).
    ChunkDecompression,
    /// A chunk's header or inner record structure is malformed.
    ChunkMalformed,
    /// A record's length runs past the data present; the bytes up to the next readable record
    /// were skipped.
    BadLength,
    /// A record is larger than the reader's limit ([`BagReadOptions::max_record_bytes`]).
    ///
    /// [`BagReadOptions::max_record_bytes`]: super::BagReadOptions::max_record_bytes
    RecordTooLarge,
    /// A run of zero bytes where a record should be.
    ZeroFilled,
    /// Bytes that are no MCAP record (bad opcode).
    Garbage,
    /// A Schema, Channel or Message record whose content is malformed.
    MalformedRecord,
    /// Messages on a channel that no Channel record (in the data or the summary) defines.
    UndefinedChannel,
    /// Messages on a channel whose schema no Schema record defines.
    UndefinedSchema,
    /// A chunk identical to one already read; its messages were not delivered twice.
    DuplicateChunk,
    /// A message identical to one just read (outside chunks); not delivered twice.
    DuplicateMessage,
    /// A channel beyond [`MAX_CHANNELS`](super::MAX_CHANNELS); its messages are not read.
    TooManyChannels,
    /// The file ends in the middle of a record.
    Truncated,
    /// A split file of a rosbag2 directory that could not be read at all.
    SplitFile,
    /// A rosbag2 SQLite database that could not be read further (its `offset` is the id of
    /// the last message row read).
    Database,
    /// A message that does not decompress (rosbag2 per-message compression).
    Decompression,
    /// A rosbag2 directory's `metadata.yaml` disagrees with what its files hold: messages it
    /// counts that were not read, storage files it does not list, a time span not covered.
    MetadataMismatch,
}

/// One damaged region of a bag and what it cost.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct BagLoss {
    /// File offset where the damage starts (a chunk's or record's opcode).
    pub offset: u64,
    /// Bytes skipped from `offset`, when known.
    pub bytes: Option<u64>,
    /// What was wrong.
    pub kind: LossKind,
    /// The same in words.
    pub reason: String,
    /// Messages lost, when the file still says how many (`None`: unknown).
    pub messages: Option<u64>,
    /// Log time of the first message lost, nanoseconds, when known.
    pub start_ns: Option<u64>,
    /// Log time of the last message lost, nanoseconds, when known.
    pub end_ns: Option<u64>,
    /// Messages lost per topic, when known.
    pub topics: BTreeMap<String, u64>,
}

impl BagLoss {
    /// One line for a log or an error message: where, what, and what it cost.
    pub fn describe(&self) -> String {
        // A loss of a whole file (a split file, the metadata) has no place in a file.
        let mut s = if self.offset == 0 && self.bytes.is_none() {
            self.reason.clone()
        } else {
            format!("byte {}: {}", self.offset, self.reason)
        };
        match self.messages {
            Some(n) => s.push_str(&format!(" ({n} messages lost")),
            None => s.push_str(" (messages lost: unknown"),
        }
        if let (Some(a), Some(b)) = (self.start_ns, self.end_ns) {
            s.push_str(&format!(
                ", log times {:.3}-{:.3} s",
                a as f64 * 1e-9,
                b as f64 * 1e-9
            ));
        }
        if !self.topics.is_empty() {
            let per: Vec<String> = self
                .topics
                .iter()
                .map(|(t, n)| format!("{t}: {n}"))
                .collect();
            s.push_str(&format!("; {}", per.join(", ")));
        }
        s.push(')');
        s
    }
}

/// How a bag was read and what its damage cost; serialisable for a report's `input` section.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Recovery {
    /// True if the summary section (channels, schemas, chunk indexes) was found intact enough
    /// to be used.
    pub summary_used: bool,
    /// Chunks the summary's Chunk Index lists (0 without a usable summary).
    pub indexed_chunks: u64,
    /// Messages delivered.
    pub messages_read: u64,
    /// Messages lost, summed over the regions whose count is known.
    pub messages_lost: u64,
    /// Damaged regions whose message count is unknown.
    pub regions_with_unknown_loss: u64,
    /// What the Statistics record claims, for comparison only (never trusted over the data).
    pub statistics_message_count: Option<u64>,
    /// The damaged regions, in file order (at most [`MAX_LISTED_LOSSES`]).
    pub losses: Vec<BagLoss>,
    /// Damaged regions beyond [`MAX_LISTED_LOSSES`], counted but not listed.
    pub losses_not_listed: u64,
    /// Whether every message read was covered by a checksum that held: `unverified` when
    /// some were read from parts of the bag no checksum covers (listed in `unverified`), so
    /// that damage there could not have been seen and a clean result is not a verified one.
    pub integrity: Integrity,
    /// The messages read that no checksum covered, per file and reason.
    pub unverified: Vec<Unverified>,
}

/// Whether what was read could be checked against the bag's own checksums.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Integrity {
    /// Every message read lay in a part of the bag whose checksum was checked and held.
    #[default]
    Verified,
    /// Some messages lay where the format (or its writer) keeps no checksum.
    Unverified,
}

/// Messages of one file read where no checksum covers them.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Unverified {
    /// The storage file.
    pub file: String,
    /// Why nothing checks them.
    pub reason: &'static str,
    /// How many were read.
    pub messages: u64,
}

/// Files listed one by one in [`Recovery::unverified`]; further files are summed per reason.
pub const MAX_LISTED_UNVERIFIED: usize = 32;

/// The `file` of the entry summing the files beyond [`MAX_LISTED_UNVERIFIED`].
pub const OTHER_FILES: &str = "(the other files)";

/// Why messages of an SQLite file are not verified.
pub(crate) const NO_CRC_SQLITE: &str = "rosbag2's SQLite storage keeps no checksum of the messages";
/// Why messages of an MCAP chunk with CRC 0 are not verified.
pub(crate) const NO_CRC_CHUNK: &str =
    "its chunks carry CRC 0 (their writer did not compute one; PyPI rosbags writes them so)";
/// Why messages outside MCAP chunks are not verified.
pub(crate) const NO_CRC_UNCHUNKED: &str = "messages outside chunks carry no CRC";

impl Recovery {
    /// True if nothing was lost.
    pub fn is_clean(&self) -> bool {
        self.losses.is_empty() && self.losses_not_listed == 0
    }

    /// Counts one message of `file` read where no checksum covers it, for `reason`.
    pub(crate) fn note_unverified(&mut self, file: &std::path::Path, reason: &'static str) {
        self.integrity = Integrity::Unverified;
        if let Some(u) = self.unverified.iter_mut().find(|u| u.reason == reason) {
            u.messages += 1;
            return;
        }
        self.unverified.push(Unverified {
            file: file.display().to_string(),
            reason,
            messages: 1,
        });
    }

    /// Adds the unverified counts of another file's recovery: listed per file up to
    /// [`MAX_LISTED_UNVERIFIED`] entries, then summed per reason under
    /// [`OTHER_FILES`].
    pub(crate) fn add_unverified(&mut self, other: &Recovery) {
        for u in &other.unverified {
            self.integrity = Integrity::Unverified;
            if let Some(v) = self
                .unverified
                .iter_mut()
                .find(|v| v.file == u.file && v.reason == u.reason)
            {
                v.messages += u.messages;
                continue;
            }
            if self.unverified.len() < MAX_LISTED_UNVERIFIED {
                self.unverified.push(u.clone());
                continue;
            }
            match self
                .unverified
                .iter_mut()
                .find(|v| v.file == OTHER_FILES && v.reason == u.reason)
            {
                Some(v) => v.messages += u.messages,
                None => self.unverified.push(Unverified {
                    file: OTHER_FILES.to_owned(),
                    reason: u.reason,
                    messages: u.messages,
                }),
            }
        }
    }

    /// One line for the console if some messages were read unverified ("" if none).
    pub fn describe_unverified(&self) -> String {
        if self.integrity == Integrity::Verified {
            return String::new();
        }
        let total: u64 = self.unverified.iter().map(|u| u.messages).sum();
        let mut parts: Vec<String> = self
            .unverified
            .iter()
            .take(3)
            .map(|u| format!("{}: {} messages: {}", u.file, u.messages, u.reason))
            .collect();
        if self.unverified.len() > 3 {
            parts.push(format!("and {} more files", self.unverified.len() - 3));
        }
        format!(
            "the bag's integrity could not be verified: {total} messages were read where no \
             checksum covers them ({}); damage there would go unseen, so a clean result is not \
             a verified one",
            parts.join("; ")
        )
    }

    /// Adds a loss, listing it if there is room.
    pub(crate) fn push(&mut self, loss: BagLoss) {
        match loss.messages {
            Some(n) => self.messages_lost += n,
            None => self.regions_with_unknown_loss += 1,
        }
        if self.losses.len() < MAX_LISTED_LOSSES {
            self.losses.push(loss);
        } else {
            self.losses_not_listed += 1;
        }
    }

    /// Marks the last listed loss as costing no message (a chunk the index says is empty, a
    /// duplicate).
    pub(crate) fn last_costs_nothing(&mut self) {
        if let Some(loss) = self.losses.last_mut() {
            if loss.messages.is_none() {
                loss.messages = Some(0);
                self.regions_with_unknown_loss = self.regions_with_unknown_loss.saturating_sub(1);
            }
        }
    }

    /// Adds `n` lost messages of `topic` (log times `first..=last`) to the last listed loss.
    pub(crate) fn add_to_last(
        &mut self,
        topic: &str,
        n: u64,
        first: Option<u64>,
        last: Option<u64>,
    ) {
        let Some(loss) = self.losses.last_mut() else {
            return;
        };
        if loss.messages.is_none() {
            loss.messages = Some(0);
            self.regions_with_unknown_loss = self.regions_with_unknown_loss.saturating_sub(1);
        }
        loss.messages = loss.messages.map(|m| m + n);
        self.messages_lost += n;
        if n > 0 {
            *loss.topics.entry(topic.to_owned()).or_default() += n;
        }
        if let Some(f) = first {
            loss.start_ns = Some(loss.start_ns.map_or(f, |s| s.min(f)));
        }
        if let Some(l) = last {
            loss.end_ns = Some(loss.end_ns.map_or(l, |e| e.max(l)));
        }
    }

    /// One line summing up the damage, for error messages ("" if none).
    pub fn describe(&self) -> String {
        let mut parts: Vec<String> = self.losses.iter().take(5).map(BagLoss::describe).collect();
        let more = self.losses.len().saturating_sub(5) as u64 + self.losses_not_listed;
        if more > 0 {
            parts.push(format!("and {more} more damaged regions"));
        }
        parts.join("; ")
    }
}
