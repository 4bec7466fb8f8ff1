//! Recovery from damaged bags: the summary and chunk indexes are used when intact, a linear
//! scan resynchronises when they are not, losses are counted with their time spans, nothing is
//! delivered twice, Statistics are not trusted, and VoxelGrid channels that cannot be read as
//! such are refused by name. Every damaged bag is built here from the writer's output.

use std::collections::BTreeMap;
use std::path::Path;

use chronotope::bag::{
    voxel_frames, voxel_topics, BagCompression, BagError, BagMessage, BagReader, BagWriteOptions,
    BagWriter, FrameError, LossKind, MAX_CHANNELS,
};
use chronotope::msg::{encode_cdr, ros2msg_schema, Header, Point, RosMessage, Time, VoxelGrid};

const TOPICS: [&str; 2] = ["/a/occupancy", "/b/occupancy"];
const T0: u64 = 1_700_000_000_000_000_000;
/// Frames 0.1 s apart.
const DT: u64 = 100_000_000;

fn grid(k: u64) -> VoxelGrid {
    VoxelGrid {
        header: Header {
            stamp: Time::from_nanos((T0 + k * DT) as i64),
            frame_id: "cell".to_owned(),
        },
        origin: Point {
            x: 0.0,
            y: 0.0,
            z: 0.0,
        },
        resolution: 0.05,
        size_x: 4,
        size_y: 2,
        size_z: 2,
        encoding: VoxelGrid::ENCODING_BITS,
        data: vec![(k as u8).wrapping_mul(31), 0x0f],
    }
}

/// `frames` frames on each of `TOPICS`, interleaved, logged at their stamps.
fn write_bag(path: &Path, options: BagWriteOptions, frames: u64) -> u64 {
    let mut bag = BagWriter::create_with(path, options).unwrap();
    for t in TOPICS {
        bag.add_topic::<VoxelGrid>(t).unwrap();
    }
    for k in 0..frames {
        for t in TOPICS {
            bag.write(t, T0 + k * DT, &grid(k)).unwrap();
        }
    }
    bag.finish().unwrap();
    frames * TOPICS.len() as u64
}

fn small_chunks(compression: Option<BagCompression>) -> BagWriteOptions {
    BagWriteOptions::new()
        .compression(compression)
        .chunk_size(300)
}

/// The (offset, length) of every chunk record, from the summary.
fn chunks(bytes: &[u8]) -> Vec<(usize, usize)> {
    let summary = mcap::Summary::read(bytes).unwrap().unwrap();
    summary
        .chunk_indexes
        .iter()
        .map(|c| (c.chunk_start_offset as usize, c.chunk_length as usize))
        .collect()
}

/// The footer's summary start.
fn summary_start(bytes: &[u8]) -> usize {
    let footer = bytes.len() - 8 - 20;
    u64::from_le_bytes(bytes[footer..footer + 8].try_into().unwrap()) as usize
}

/// Removes the summary: the footer's summary offset becomes 0, so only a scan can read it.
fn drop_summary(bytes: &mut [u8]) {
    let footer = bytes.len() - 8 - 20;
    bytes[footer..footer + 8].fill(0);
}

/// Every top-level record from `from` to the footer: (offset, opcode, body length).
fn records_from(bytes: &[u8], mut at: usize) -> Vec<(usize, u8, usize)> {
    let mut out = Vec::new();
    while at + 9 <= bytes.len() - 8 {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        out.push((at, bytes[at], len));
        if bytes[at] == 0x02 {
            break;
        }
        at += 9 + len;
    }
    out
}

struct Read {
    messages: Vec<BagMessage>,
    errors: Vec<BagError>,
    reader: BagReader,
}

fn read(bytes: Vec<u8>) -> Read {
    let mut reader = BagReader::from_bytes(bytes, "damaged.mcap").unwrap();
    let (mut messages, mut errors) = (Vec::new(), Vec::new());
    for item in reader.by_ref().take(100_000) {
        match item {
            Ok(m) => messages.push(m),
            Err(e) => errors.push(e),
        }
    }
    Read {
        messages,
        errors,
        reader,
    }
}

fn tempbag(bytes: &[u8]) -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bag.mcap");
    std::fs::write(&path, bytes).unwrap();
    (dir, path)
}

fn fresh(options: BagWriteOptions, frames: u64) -> (Vec<u8>, u64) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bag.mcap");
    let n = write_bag(&path, options, frames);
    (std::fs::read(&path).unwrap(), n)
}

/// No message is delivered twice and every one is one the writer wrote.
fn assert_genuine(messages: &[BagMessage]) {
    let mut seen = std::collections::BTreeSet::new();
    for m in messages {
        assert!(TOPICS.contains(&m.topic.as_str()), "{}", m.topic);
        let k = (m.log_time_ns - T0) / DT;
        assert_eq!(m.data, encode_cdr(&grid(k)).unwrap());
        assert!(
            seen.insert((m.topic.clone(), m.log_time_ns)),
            "twice: {m:?}"
        );
    }
}

#[test]
fn a_corrupt_chunk_costs_only_its_own_messages() {
    for compression in [Some(BagCompression::Zstd), Some(BagCompression::Lz4), None] {
        // Chunk 0 holds the Channel records (the summary repeats them); chunk 1 messages.
        for k in [0, 1] {
            let (mut bytes, total) = fresh(small_chunks(compression), 20);
            let chunks = chunks(&bytes);
            assert!(chunks.len() >= 4, "{chunks:?}");
            let (start, len) = chunks[k];
            for at in [start + len - 20, start + len - 30] {
                bytes[at] ^= 0xa5;
            }
            let r = read(bytes);
            let case = format!("{compression:?}, chunk {k}");
            // Only the chunk's error: no "channel 2, which no Channel record defines".
            assert_eq!(r.errors.len(), 1, "{case}: {:?}", r.errors);
            assert!(
                matches!(r.errors[0], BagError::CorruptChunk { offset, .. } if offset == start as u64)
            );
            assert!(r.errors[0].to_string().contains(&format!("byte {start}")));
            assert_genuine(&r.messages);
            let recovery = r.reader.recovery();
            assert!(recovery.summary_used);
            assert_eq!(recovery.losses.len(), 1);
            let loss = &recovery.losses[0];
            assert_eq!(loss.offset, start as u64);
            // The count comes from the chunk's own message index (or the chunk index), and
            // adds up.
            let lost = loss
                .messages
                .unwrap_or_else(|| panic!("{case}: count unknown: {recovery:?}"));
            assert_eq!(r.messages.len() as u64 + lost, total, "{case}");
            assert_eq!(loss.topics.values().sum::<u64>(), lost);
            if lost > 0 {
                let (a, b) = (loss.start_ns.unwrap(), loss.end_ns.unwrap());
                let lost_times: Vec<u64> = (0..20)
                    .map(|i| T0 + i * DT)
                    .filter(|t| r.messages.iter().filter(|m| m.log_time_ns == *t).count() < 2)
                    .collect();
                assert_eq!(
                    (a, b),
                    (lost_times[0], *lost_times.last().unwrap()),
                    "{case}"
                );
            }
            if k == 1 {
                assert!(lost > 0, "{case}");
            }
        }
    }
}

#[test]
fn a_chunk_with_a_bad_length_field_is_read_through_the_index() {
    let (mut bytes, total) = fresh(small_chunks(Some(BagCompression::Zstd)), 20);
    let (start, _) = chunks(&bytes)[1];
    bytes[start + 1..start + 9].copy_from_slice(&(u64::MAX / 3).to_le_bytes());
    let r = read(bytes);
    // The index knows where the chunk ends: nothing is lost.
    assert!(r.errors.is_empty(), "{:?}", r.errors);
    assert_eq!(r.messages.len() as u64, total);
    assert_genuine(&r.messages);
}

#[test]
fn without_an_index_a_bad_length_loses_only_that_chunk() {
    for compression in [Some(BagCompression::Zstd), Some(BagCompression::Lz4), None] {
        let (mut bytes, total) = fresh(small_chunks(compression), 20);
        let chunks = chunks(&bytes);
        let (start, _) = chunks[1];
        drop_summary(&mut bytes);
        bytes[start + 1..start + 9].copy_from_slice(&(1u64 << 40).to_le_bytes());
        let r = read(bytes);
        assert!(!r.reader.recovery().summary_used);
        assert_genuine(&r.messages);
        // Everything after the damaged chunk is read (an uncompressed chunk's own records
        // are found by the scan too).
        let last = r.messages.last().unwrap().log_time_ns;
        assert_eq!(last, T0 + 19 * DT, "{compression:?}");
        assert!(r.messages.len() as u64 >= total - 10, "{compression:?}");
        assert!(r.errors.iter().all(|e| !e.is_fatal()), "{:?}", r.errors);
        assert!(
            r.errors
                .iter()
                .any(|e| e.to_string().contains(&format!("{start}"))),
            "{:?}",
            r.errors
        );
    }
}

#[test]
fn without_an_index_a_corrupt_first_chunk_takes_its_channels_with_it_but_says_so() {
    let (mut bytes, _) = fresh(small_chunks(None), 20);
    let (start, len) = chunks(&bytes)[0];
    drop_summary(&mut bytes);
    bytes[start + 9..start + len].fill(0xee);
    let r = read(bytes);
    // The Channel records were only in that chunk: later messages cannot be attributed, and
    // each channel is reported once (not once per message), its messages counted.
    let unknown = r
        .errors
        .iter()
        .filter(|e| matches!(e, BagError::UnknownChannel { .. }))
        .count();
    assert!(unknown <= TOPICS.len(), "{:?}", r.errors);
    let recovery = r.reader.recovery();
    let undefined: u64 = recovery
        .losses
        .iter()
        .filter(|l| l.kind == LossKind::UndefinedChannel)
        .filter_map(|l| l.messages)
        .sum();
    assert!(undefined > 0);
}

#[test]
fn a_zero_filled_chunk_is_an_error_naming_its_offset() {
    // One chunk among several zeroed, with and without the index.
    for keep_summary in [true, false] {
        let (mut bytes, total) = fresh(small_chunks(Some(BagCompression::Zstd)), 20);
        let (start, len) = chunks(&bytes)[2];
        if !keep_summary {
            drop_summary(&mut bytes);
        }
        bytes[start..start + len].fill(0);
        let r = read(bytes);
        assert_genuine(&r.messages);
        let zero = r
            .reader
            .recovery()
            .losses
            .iter()
            .find(|l| l.kind == LossKind::ZeroFilled)
            .unwrap_or_else(|| panic!("{:?}", r.reader.recovery()));
        assert_eq!(zero.offset, start as u64);
        // The chunk's message index survived: the loss is counted exactly.
        assert_eq!(
            zero.messages.map(|n| n + r.messages.len() as u64),
            Some(total),
            "{zero:?}"
        );
        assert!(
            r.errors
                .iter()
                .any(|e| e.to_string().contains(&format!("{start}"))),
            "{:?}",
            r.errors
        );
    }
    // The only chunk zeroed: no frames, and the error says where and why.
    let (mut bytes, _) = fresh(BagWriteOptions::new(), 5);
    let (start, len) = chunks(&bytes)[0];
    bytes[start..start + len].fill(0);
    let (_dir, path) = tempbag(&bytes);
    let err = voxel_frames(&path).err().unwrap();
    let text = err.to_string();
    assert!(matches!(err, BagError::NoVoxelFrames { .. }), "{text}");
    assert!(text.contains(&format!("byte {start}")), "{text}");
    assert!(text.contains("zero-filled"), "{text}");
    assert!(text.contains("10 messages lost"), "{text}");
}

#[test]
fn the_only_chunk_failing_its_crc_is_named_with_what_it_cost() {
    let (mut bytes, _) = fresh(BagWriteOptions::new(), 6);
    let (start, len) = chunks(&bytes)[0];
    bytes[start + len - 10] ^= 0xff;
    let (_dir, path) = tempbag(&bytes);
    let err = voxel_frames(&path).err().unwrap();
    let text = err.to_string();
    assert!(!text.contains("holds no messages"), "{text}");
    assert!(!text.contains("no messages of type"), "{text}");
    assert!(text.contains("/a/occupancy"), "{text}");
    assert!(text.contains(&format!("byte {start}")), "{text}");
    assert!(
        text.contains("CRC") || text.contains("decompress"),
        "{text}"
    );
    assert!(text.contains("12 messages lost"), "{text}");

    // Without the summary: the channels are only known from the summary section's copies
    // (read last); the error still says where and why.
    drop_summary(&mut bytes);
    std::fs::write(&path, &bytes).unwrap();
    let text = voxel_frames(&path).err().unwrap().to_string();
    assert!(!text.contains("holds no messages"), "{text}");
    assert!(text.contains(&format!("byte {start}")), "{text}");
}

#[test]
fn zeroed_statistics_do_not_empty_an_intact_bag() {
    let (mut bytes, total) = fresh(BagWriteOptions::new(), 6);
    let stats = records_from(&bytes, summary_start(&bytes))
        .into_iter()
        .find(|r| r.1 == 0x0B)
        .unwrap();
    bytes[stats.0 + 9..stats.0 + 9 + stats.2].fill(0);
    let (_dir, path) = tempbag(&bytes);
    let frames: Vec<_> = voxel_frames(&path).unwrap().collect();
    assert_eq!(frames.len() as u64, total);
    assert!(frames.iter().all(Result::is_ok));
}

#[test]
fn a_duplicated_chunk_is_not_delivered_twice() {
    for compression in [Some(BagCompression::Zstd), None] {
        let (bytes, total) = fresh(small_chunks(compression), 20);
        let (start, len) = chunks(&bytes)[1];
        let mut damaged = bytes[..start + len].to_vec();
        damaged.extend_from_slice(&bytes[start..start + len]);
        damaged.extend_from_slice(&bytes[start + len..]);
        let r = read(damaged);
        assert_genuine(&r.messages);
        assert_eq!(r.messages.len() as u64, total, "{compression:?}");
        assert!(
            r.errors
                .iter()
                .any(|e| matches!(e, BagError::Duplicate { offset, .. } if *offset == (start + len) as u64)),
            "{:?}",
            r.errors
        );
    }
}

/// Writes a bag with raw `mcap` calls: one VoxelGrid channel per `(topic, schema text,
/// message encoding)`, `schema_text` `None` for a channel without schema, 3 frames each.
fn raw_bag(path: &Path, channels: &[(&str, Option<String>, &str)]) {
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .create(std::io::BufWriter::new(
            std::fs::File::create(path).unwrap(),
        ))
        .unwrap();
    let mut ids = Vec::new();
    for (topic, schema, encoding) in channels {
        let schema_id = match schema {
            Some(text) => w
                .add_schema(VoxelGrid::TYPE_NAME, "ros2msg", text.as_bytes())
                .unwrap(),
            None => 0,
        };
        ids.push(
            w.add_channel(schema_id, topic, encoding, &BTreeMap::new())
                .unwrap(),
        );
    }
    for k in 0..3u64 {
        for id in &ids {
            let header = mcap::records::MessageHeader {
                channel_id: *id,
                sequence: k as u32,
                log_time: T0 + k * DT,
                publish_time: T0 + k * DT,
            };
            w.write_to_known_channel(&header, &encode_cdr(&grid(k)).unwrap())
                .unwrap();
        }
    }
    w.finish().unwrap();
}

#[test]
fn voxel_channels_that_cannot_be_read_as_such_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("raw.mcap");
    let ours = ros2msg_schema::<VoxelGrid>();
    let other = ours.replacen("float64 resolution", "float32 resolution", 1);
    raw_bag(
        &path,
        &[
            ("/good/occupancy", Some(ours.clone()), "cdr"),
            ("/json/occupancy", Some(ours.clone()), "json"),
            ("/other/occupancy", Some(other), "cdr"),
            ("/bare/occupancy", None, "cdr"),
        ],
    );
    let mut frames = voxel_frames(&path).unwrap();
    let mut good = 0;
    let mut refused = Vec::new();
    for item in frames.by_ref() {
        match item {
            Ok((topic, _)) => {
                assert_eq!(topic, "/good/occupancy");
                good += 1;
            }
            Err(FrameError::Bag(e @ BagError::RefusedChannel { .. })) => {
                assert!(!e.is_fatal());
                refused.push(e.to_string());
            }
            Err(other) => panic!("{other}"),
        }
    }
    assert_eq!(good, 3);
    // Each refused channel once, by name, with the reason in the user's terms.
    assert_eq!(refused.len(), 3, "{refused:?}");
    assert!(refused
        .iter()
        .any(|e| e.contains("/json/occupancy") && e.contains("\"json\"")));
    assert!(refused
        .iter()
        .any(|e| e.contains("/other/occupancy") && e.contains("float32 resolution")));
    assert!(refused
        .iter()
        .any(|e| e.contains("/bare/occupancy") && e.contains("no schema")));
    // Their messages are counted, with their time spans.
    let counted = frames.refused();
    assert_eq!(counted.len(), 3);
    for r in &counted {
        assert_eq!(r.messages, 3, "{r:?}");
        assert_eq!((r.start_ns, r.end_ns), (T0, T0 + 2 * DT));
    }
    assert_eq!(voxel_topics(&path).unwrap(), ["/good/occupancy"]);

    // With only a refused channel, opening says why there are no frames.
    raw_bag(&path, &[("/json/occupancy", Some(ours), "json")]);
    let text = voxel_frames(&path).err().unwrap().to_string();
    assert!(
        text.contains("/json/occupancy") && text.contains("\"json\""),
        "{text}"
    );
}

#[test]
fn channels_beyond_the_limit_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("many.mcap");
    let mut bag = BagWriter::create(&path).unwrap();
    let n = MAX_CHANNELS + 44;
    let topics: Vec<String> = (0..n).map(|i| format!("/b{i:03}/occupancy")).collect();
    for t in &topics {
        bag.add_topic::<VoxelGrid>(t).unwrap();
    }
    for t in &topics {
        bag.write(t, T0, &grid(0)).unwrap();
    }
    bag.finish().unwrap();
    let r = read(std::fs::read(&path).unwrap());
    assert_eq!(r.messages.len(), MAX_CHANNELS);
    let too_many: Vec<_> = r
        .errors
        .iter()
        .filter(|e| matches!(e, BagError::TooManyChannels { .. }))
        .collect();
    assert_eq!(too_many.len(), 1, "{:?}", r.errors);
    assert!(too_many[0].to_string().contains("MAX_CHANNELS = 256"));
    assert_eq!(r.reader.recovery().messages_lost, 44);
    assert_eq!(voxel_topics(&path).unwrap().len(), MAX_CHANNELS);
}

#[test]
fn unchunked_bags_resynchronise_after_a_bad_record_length() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("flat.mcap");
    let mut w = mcap::WriteOptions::new()
        .profile("ros2")
        .use_chunks(false)
        .create(std::io::BufWriter::new(
            std::fs::File::create(&path).unwrap(),
        ))
        .unwrap();
    let schema = ros2msg_schema::<VoxelGrid>();
    let sid = w
        .add_schema(VoxelGrid::TYPE_NAME, "ros2msg", schema.as_bytes())
        .unwrap();
    let cid = w
        .add_channel(sid, TOPICS[0], "cdr", &BTreeMap::new())
        .unwrap();
    for k in 0..20u64 {
        let header = mcap::records::MessageHeader {
            channel_id: cid,
            sequence: k as u32,
            log_time: T0 + k * DT,
            publish_time: T0 + k * DT,
        };
        w.write_to_known_channel(&header, &encode_cdr(&grid(k)).unwrap())
            .unwrap();
    }
    w.finish().unwrap();
    drop(w);
    let mut bytes = std::fs::read(&path).unwrap();
    let messages: Vec<_> = records_from(&bytes, 8)
        .into_iter()
        .filter(|r| r.1 == 0x05)
        .collect();
    assert_eq!(messages.len(), 20);
    let bad = messages[5].0;
    bytes[bad + 1..bad + 9].copy_from_slice(&(1u64 << 20).to_le_bytes());
    let r = read(bytes.clone());
    assert_genuine(&r.messages);
    assert_eq!(r.messages.len(), 19, "{:?}", r.errors);
    assert!(r.errors.iter().all(|e| !e.is_fatal()), "{:?}", r.errors);

    // A duplicated range of messages is delivered once.
    let (a, b) = (messages[3].0, messages[6].0);
    let mut dup = std::fs::read(&path).unwrap()[..b].to_vec();
    dup.extend_from_slice(&std::fs::read(&path).unwrap()[a..]);
    let r = read(dup);
    assert_genuine(&r.messages);
    assert_eq!(r.messages.len(), 20);
    assert_eq!(
        r.errors
            .iter()
            .filter(|e| matches!(e, BagError::Duplicate { .. }))
            .count(),
        3
    );
}

#[test]
fn from_bytes_reads_what_open_reads_and_recovery_serialises() {
    let (mut bytes, _) = fresh(small_chunks(None), 10);
    let (start, len) = chunks(&bytes)[1];
    bytes[start + len - 5] ^= 1;
    let (_dir, path) = tempbag(&bytes);
    let from_file: Vec<_> = BagReader::open(&path)
        .unwrap()
        .map(|i| i.map_err(|e| e.to_string()))
        .collect();
    let r = read(bytes);
    assert_eq!(
        from_file.iter().filter(|i| i.is_ok()).count(),
        r.messages.len()
    );
    let json = serde_json::to_value(r.reader.recovery()).unwrap();
    assert_eq!(json["losses"][0]["kind"], "chunk_crc");
    assert_eq!(json["losses"][0]["offset"], start as u64);
    assert!(json["losses"][0]["messages"].as_u64().unwrap() > 0);
    assert_eq!(json["summary_used"], true);
}

#[test]
fn garbage_after_the_header_never_hangs_or_panics() {
    // Long runs of plausible-looking noise: the scan stays linear and ends.
    let (bytes, _) = fresh(small_chunks(None), 20);
    let mut damaged = bytes[..40].to_vec();
    for i in 0..200_000u32 {
        damaged.push(match i % 9 {
            0 => 0x05,
            1 => 30,
            _ => 0,
        });
    }
    let start = std::time::Instant::now();
    let r = read(damaged);
    assert!(r.messages.is_empty());
    assert!(r.errors.last().is_some_and(BagError::is_fatal));
    assert!(start.elapsed().as_secs() < 10);
}
