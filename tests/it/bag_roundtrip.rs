//! rosbag2 MCAP writing and reading: round trips, the byte layout of CDR and schemas, and
//! damaged input (truncated or corrupted bags, garbage CDR) giving errors, never panics.
//!
//! `CHRONOTOPE_SAMPLE_BAG=/tmp/sample.mcap cargo test --test it bag_roundtrip::sample_bag` also
//! leaves a small bag there for `tests/py/read_bags.py`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use chronotope::bag::{
    voxel_frames, voxel_topics, BagCompression, BagError, BagMessage, BagReadOptions, BagReader,
    BagWriteOptions, BagWriter, FrameError, OFFERED_QOS_PROFILES,
};
use chronotope::msg::{
    decode_cdr, encode_cdr, ros2msg_schema, CdrError, Header, Point, RosMessage, Time, VoxelGrid,
    SCHEMA_SEPARATOR,
};
use proptest::prelude::*;
use serde::{Deserialize, Serialize};

const TOPICS: [&str; 3] = ["/a/occupancy", "/b/occupancy", "/c/occupancy"];

/// A small grid (3 x 2 x 2 voxels) whose content depends on `k`.
fn grid(k: u32, encoding: u8) -> VoxelGrid {
    let voxels = 12usize;
    let data = if encoding == VoxelGrid::ENCODING_BITS {
        vec![(k as u8).wrapping_mul(37), (k % 16) as u8]
    } else {
        (0..voxels)
            .map(|i| match (i as u32 + k) % 5 {
                4 => VoxelGrid::PERCENT_UNKNOWN,
                r => (r * 25) as u8,
            })
            .collect()
    };
    VoxelGrid {
        header: Header {
            stamp: Time::from_nanos(1_700_000_000_000_000_000 + i64::from(k) * 100_000_000),
            frame_id: format!("cell_{}", k % 2),
        },
        origin: Point {
            x: -0.5,
            y: 0.25 * f64::from(k),
            z: 1.0,
        },
        resolution: 0.05,
        size_x: 3,
        size_y: 2,
        size_z: 2,
        encoding,
        data,
    }
}

/// Frames interleaved over three topics, both encodings: `(topic, log time, grid)`.
fn interleaved(frames_per_topic: u32) -> Vec<(&'static str, u64, VoxelGrid)> {
    let mut out = Vec::new();
    for k in 0..frames_per_topic {
        for (t, topic) in TOPICS.iter().enumerate() {
            let encoding = if (k + t as u32) % 2 == 0 {
                VoxelGrid::ENCODING_BITS
            } else {
                VoxelGrid::ENCODING_PERCENT
            };
            let g = grid(k * 3 + t as u32, encoding);
            let log_time = g.header.stamp.as_nanos() as u64 + t as u64;
            out.push((*topic, log_time, g));
        }
    }
    out
}

fn write_bag(path: &Path, options: BagWriteOptions, frames: &[(&str, u64, VoxelGrid)]) {
    let mut bag = BagWriter::create_with(path, options).unwrap();
    for topic in TOPICS {
        bag.add_topic::<VoxelGrid>(topic).unwrap();
    }
    for (topic, log_time, g) in frames {
        bag.write(topic, *log_time, g).unwrap();
    }
    bag.finish().unwrap();
}

fn read_all(path: &Path) -> Vec<Result<BagMessage, BagError>> {
    BagReader::open(path).unwrap().collect()
}

/// Iterates a possibly damaged bag to its end; returns the messages and the errors.
fn read_lossy(path: &Path) -> (Vec<BagMessage>, Vec<BagError>, Option<BagError>) {
    let reader = match BagReader::open_with(path, BagReadOptions::new().max_record_bytes(1 << 20)) {
        Ok(reader) => reader,
        Err(err) => return (Vec::new(), Vec::new(), Some(err)),
    };
    let (mut messages, mut errors) = (Vec::new(), Vec::new());
    // A fatal error ends the iteration; bound it anyway so a bug cannot hang the test.
    for item in reader.take(100_000) {
        match item {
            Ok(m) => messages.push(m),
            Err(e) => errors.push(e),
        }
    }
    (messages, errors, None)
}

fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

#[test]
fn voxel_grids_round_trip_over_interleaved_topics() {
    let dir = tempdir();
    let frames = interleaved(6);
    for (name, compression, chunk_size) in [
        ("zstd.mcap", Some(BagCompression::Zstd), 1 << 20),
        ("lz4.mcap", Some(BagCompression::Lz4), 300),
        ("plain.mcap", None, 300),
    ] {
        let path = dir.path().join(name);
        let options = BagWriteOptions::new()
            .compression(compression)
            .chunk_size(chunk_size);
        write_bag(&path, options, &frames);

        let reader = BagReader::open(&path).unwrap();
        assert_eq!(reader.profile(), "ros2");
        let messages: Vec<BagMessage> = reader.map(Result::unwrap).collect();
        assert_eq!(messages.len(), frames.len(), "{name}");
        for (m, (topic, log_time, g)) in messages.iter().zip(&frames) {
            assert_eq!(m.topic, *topic);
            assert_eq!(m.schema_name, "chronotope_msgs/msg/VoxelGrid");
            assert_eq!(m.message_encoding, "cdr");
            assert_eq!(m.log_time_ns, *log_time);
            assert_eq!(m.publish_time_ns, *log_time);
            assert_eq!(decode_cdr::<VoxelGrid>(&m.data).unwrap(), *g);
        }
        // Sequence numbers count per channel, from 1.
        let seqs: Vec<u32> = messages
            .iter()
            .filter(|m| m.topic == TOPICS[1])
            .map(|m| m.sequence)
            .collect();
        assert_eq!(seqs, (1..=6).collect::<Vec<u32>>());

        let decoded: Vec<(String, VoxelGrid)> =
            voxel_frames(&path).unwrap().map(Result::unwrap).collect();
        let expected: Vec<(String, VoxelGrid)> = frames
            .iter()
            .map(|(t, _, g)| (t.to_string(), g.clone()))
            .collect();
        assert_eq!(decoded, expected, "{name}");
        assert_eq!(voxel_topics(&path).unwrap(), TOPICS);
    }
}

#[test]
fn an_independent_mcap_reader_sees_a_rosbag2_file() {
    let dir = tempdir();
    let path = dir.path().join("bag.mcap");
    let frames = interleaved(2);
    write_bag(&path, BagWriteOptions::new(), &frames);
    let bytes = std::fs::read(&path).unwrap();

    let header = mcap::read::LinearReader::new(&bytes)
        .unwrap()
        .next()
        .unwrap()
        .unwrap();
    match header {
        mcap::records::Record::Header(h) => assert_eq!(h.profile, "ros2"),
        other => panic!("first record is {other:?}"),
    }

    let summary = mcap::Summary::read(&bytes).unwrap().expect("summary");
    let stats = summary.stats.as_ref().expect("statistics");
    assert_eq!(stats.message_count, frames.len() as u64);
    assert_eq!(summary.schemas.len(), 1, "one schema shared by the topics");
    let schema = summary.schemas.values().next().unwrap();
    assert_eq!(schema.name, "chronotope_msgs/msg/VoxelGrid");
    assert_eq!(schema.encoding, "ros2msg");
    assert_eq!(
        std::str::from_utf8(&schema.data).unwrap(),
        ros2msg_schema::<VoxelGrid>()
    );
    let mut topics: Vec<&str> = summary
        .channels
        .values()
        .map(|c| c.topic.as_str())
        .collect();
    topics.sort_unstable();
    assert_eq!(topics, TOPICS);
    for channel in summary.channels.values() {
        assert_eq!(channel.message_encoding, "cdr");
        assert_eq!(
            channel.metadata,
            BTreeMap::from([(
                "offered_qos_profiles".to_owned(),
                OFFERED_QOS_PROFILES.to_owned()
            )])
        );
    }

    let messages: Vec<_> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(Result::unwrap)
        .collect();
    assert_eq!(messages.len(), frames.len());
    for (m, (topic, log_time, g)) in messages.iter().zip(&frames) {
        assert_eq!(m.channel.topic, *topic);
        assert_eq!(m.log_time, *log_time);
        assert_eq!(m.data.as_ref(), encode_cdr(g).unwrap().as_slice());
    }
}

#[test]
fn cdr_layout_of_a_voxel_grid() {
    let g = VoxelGrid {
        header: Header {
            stamp: Time {
                sec: 0x0102_0304,
                nanosec: 5,
            },
            frame_id: "map".into(),
        },
        origin: Point {
            x: 1.5,
            y: -2.0,
            z: 0.0,
        },
        resolution: 0.25,
        size_x: 2,
        size_y: 3,
        size_z: 4,
        encoding: VoxelGrid::ENCODING_PERCENT,
        data: vec![9; 24],
    };
    let b = encode_cdr(&g).unwrap();
    assert_eq!(b[..4], [0x00, 0x01, 0x00, 0x00], "encapsulation CDR_LE");
    let body = &b[4..];
    assert_eq!(body[0..4], 0x0102_0304i32.to_le_bytes(), "stamp.sec");
    assert_eq!(body[4..8], 5u32.to_le_bytes(), "stamp.nanosec");
    assert_eq!(
        body[8..12],
        4u32.to_le_bytes(),
        "frame_id length counts the NUL"
    );
    assert_eq!(&body[12..16], b"map\0");
    // origin.x is a float64: aligned to 8 in the body, which it already is at 16.
    assert_eq!(body[16..24], 1.5f64.to_le_bytes(), "origin.x");
    assert_eq!(body[24..32], (-2.0f64).to_le_bytes(), "origin.y");
    assert_eq!(body[32..40], 0.0f64.to_le_bytes(), "origin.z");
    assert_eq!(body[40..48], 0.25f64.to_le_bytes(), "resolution");
    assert_eq!(body[48..52], 2u32.to_le_bytes(), "size_x");
    assert_eq!(body[52..56], 3u32.to_le_bytes(), "size_y");
    assert_eq!(body[56..60], 4u32.to_le_bytes(), "size_z");
    assert_eq!(body[60], 1, "encoding");
    assert_eq!(
        body[61..64],
        [0, 0, 0],
        "padding before the sequence length"
    );
    assert_eq!(body[64..68], 24u32.to_le_bytes(), "data length");
    assert_eq!(body[68..], [9; 24]);

    // A frame_id of another length moves the float64s to the next multiple of 8.
    let g2 = VoxelGrid {
        header: Header {
            frame_id: "cell".into(),
            ..g.header.clone()
        },
        ..g.clone()
    };
    let b2 = encode_cdr(&g2).unwrap();
    assert_eq!(&b2[4 + 12..4 + 17], b"cell\0");
    assert_eq!(b2[4 + 17..4 + 24], [0; 7], "padding to 8");
    assert_eq!(b2[4 + 24..4 + 32], 1.5f64.to_le_bytes());
    assert_eq!(decode_cdr::<VoxelGrid>(&b2).unwrap(), g2);
}

#[test]
fn schema_text_is_the_rosbag2_concatenation() {
    let schema = ros2msg_schema::<VoxelGrid>();
    let file =
        |p: &str| std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(p)).unwrap();
    let sep = "=".repeat(80);
    assert_eq!(SCHEMA_SEPARATOR, sep);
    // Dependencies of VoxelGrid sorted (geometry_msgs/Point < std_msgs/Header), each followed
    // depth first by its own (std_msgs/Header -> builtin_interfaces/Time).
    let expected = format!(
        "{}\n{sep}\nMSG: geometry_msgs/Point\n{}\n{sep}\nMSG: std_msgs/Header\n{}\n{sep}\nMSG: builtin_interfaces/Time\n{}",
        file("msgs/msg/VoxelGrid.msg"),
        file("msgs/deps/geometry_msgs/msg/Point.msg"),
        file("msgs/deps/std_msgs/msg/Header.msg"),
        file("msgs/deps/builtin_interfaces/msg/Time.msg"),
    );
    assert_eq!(schema, expected);
    let msg_lines: Vec<&str> = schema.lines().filter(|l| l.starts_with("MSG: ")).collect();
    assert_eq!(
        msg_lines,
        [
            "MSG: geometry_msgs/Point",
            "MSG: std_msgs/Header",
            "MSG: builtin_interfaces/Time"
        ]
    );
    // Every separator is a whole line of exactly 80 '=' preceded by an empty line.
    let lines: Vec<&str> = schema.lines().collect();
    for (i, line) in lines.iter().enumerate().filter(|(_, l)| l.starts_with('=')) {
        assert_eq!(line.len(), 80);
        assert!(line.chars().all(|c| c == '='));
        assert_eq!(lines[i - 1], "");
        assert!(lines[i + 1].starts_with("MSG: "));
    }
}

/// A type with a dependency that is not provided, and one that is provided twice over.
#[derive(Serialize, Deserialize)]
struct Incomplete {
    header: Header,
}

impl RosMessage for Incomplete {
    const TYPE_NAME: &'static str = "test_msgs/msg/Incomplete";
    const DEFINITION: &'static str = "std_msgs/Header header\nLocal a\nLocal b\n";
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        vec![("test_msgs/msg/Local", "int32 x\n")]
    }
}

#[test]
fn schema_dependencies_are_checked_and_listed_once() {
    let err = chronotope::msg::try_ros2msg_schema::<Incomplete>().unwrap_err();
    assert!(err.to_string().contains("std_msgs/Header"), "{err}");
    let schema = ros2msg_schema::<Incomplete>();
    assert_eq!(
        schema,
        format!(
            "{}\n{}\nMSG: test_msgs/Local\nint32 x\n",
            Incomplete::DEFINITION,
            SCHEMA_SEPARATOR
        )
    );
    let dir = tempdir();
    let mut bag = BagWriter::create(dir.path().join("x.mcap")).unwrap();
    assert!(matches!(
        bag.add_topic::<Incomplete>("/x"),
        Err(BagError::Schema { .. })
    ));
}

#[test]
fn garbage_and_truncated_cdr_are_errors() {
    let bytes = encode_cdr(&grid(1, VoxelGrid::ENCODING_PERCENT)).unwrap();
    for cut in 0..bytes.len() {
        let err = decode_cdr::<VoxelGrid>(&bytes[..cut]).unwrap_err();
        if cut < 4 {
            assert_eq!(err, CdrError::TooShort { len: cut });
        } else {
            assert!(
                matches!(err, CdrError::Truncated { .. }),
                "cut {cut}: {err}"
            );
        }
    }
    let mut wrong = bytes.clone();
    wrong[1] = 0x07;
    assert!(matches!(
        decode_cdr::<VoxelGrid>(&wrong),
        Err(CdrError::UnsupportedEncapsulation {
            found: [0x00, 0x07]
        })
    ));
    // A data length of u32::MAX: an error right away, no 4 GiB allocation.
    let mut huge = bytes.clone();
    let len_at = bytes.len() - 12 - 4;
    huge[len_at..len_at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(
        decode_cdr::<VoxelGrid>(&huge),
        Err(CdrError::Truncated {
            needed: 0xffff_ffff,
            ..
        })
    ));
    // A frame_id length of u32::MAX.
    let mut huge = bytes.clone();
    huge[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(matches!(
        decode_cdr::<VoxelGrid>(&huge),
        Err(CdrError::Truncated { .. })
    ));
    // The same message in big endian decodes to the same value.
    let g = grid(2, VoxelGrid::ENCODING_BITS);
    assert_eq!(decode_cdr::<VoxelGrid>(&to_big_endian(&g)).unwrap(), g);
}

/// Hand-made CDR_BE encoding of a VoxelGrid, to check the big-endian reader.
fn to_big_endian(g: &VoxelGrid) -> Vec<u8> {
    let mut body: Vec<u8> = Vec::new();
    let align = |body: &mut Vec<u8>, n: usize| {
        while body.len() % n != 0 {
            body.push(0);
        }
    };
    body.extend(g.header.stamp.sec.to_be_bytes());
    body.extend(g.header.stamp.nanosec.to_be_bytes());
    body.extend((g.header.frame_id.len() as u32 + 1).to_be_bytes());
    body.extend(g.header.frame_id.as_bytes());
    body.push(0);
    for v in [g.origin.x, g.origin.y, g.origin.z, g.resolution] {
        align(&mut body, 8);
        body.extend(v.to_be_bytes());
    }
    for v in [g.size_x, g.size_y, g.size_z] {
        body.extend(v.to_be_bytes());
    }
    body.push(g.encoding);
    align(&mut body, 4);
    body.extend((g.data.len() as u32).to_be_bytes());
    body.extend(&g.data);
    [vec![0, 0, 0, 0], body].concat()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn random_bytes_never_panic_the_cdr_decoder(
        bytes in proptest::collection::vec(any::<u8>(), 0..200),
        le in any::<bool>(),
    ) {
        let mut framed = vec![0, u8::from(le), 0, 0];
        framed.extend(&bytes);
        let _ = decode_cdr::<VoxelGrid>(&framed);
        let _ = decode_cdr::<VoxelGrid>(&bytes);
        let _ = decode_cdr::<Header>(&framed);
    }

    #[test]
    fn flipped_bytes_in_a_valid_message_never_panic(
        k in 0u32..50,
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
    ) {
        let mut bytes = encode_cdr(&grid(k, VoxelGrid::ENCODING_PERCENT)).unwrap();
        for (at, value) in flips {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        if let Ok(g) = decode_cdr::<VoxelGrid>(&bytes) {
            // Whatever decodes re-encodes to a message of at most the same length.
            prop_assert!(encode_cdr(&g).unwrap().len() <= bytes.len());
        }
    }
}

#[test]
fn a_truncated_bag_yields_what_it_has_then_an_error() {
    let dir = tempdir();
    let full = dir.path().join("full.mcap");
    let frames = interleaved(10);
    write_bag(&full, BagWriteOptions::new().chunk_size(1000), &frames);
    let bytes = std::fs::read(&full).unwrap();
    let cut_path = dir.path().join("cut.mcap");
    let mut saw_partial = false;
    for cut in (0..bytes.len()).step_by(37).chain([bytes.len() - 1]) {
        std::fs::write(&cut_path, &bytes[..cut]).unwrap();
        let (messages, errors, open_error) = read_lossy(&cut_path);
        if let Some(err) = open_error {
            assert!(
                matches!(err, BagError::NotMcap { .. } | BagError::Truncated { .. }),
                "cut {cut}: {err}"
            );
            continue;
        }
        let last = errors
            .last()
            .unwrap_or_else(|| panic!("cut {cut}: no error"));
        assert!(last.is_fatal(), "cut {cut}: {last}");
        for (m, (topic, _, g)) in messages.iter().zip(&frames) {
            assert_eq!(m.topic, *topic);
            assert_eq!(decode_cdr::<VoxelGrid>(&m.data).unwrap(), *g);
        }
        saw_partial |= !messages.is_empty() && messages.len() < frames.len();
    }
    assert!(saw_partial);

    // voxel_frames on a bag cut in its data section (no summary): the frames before the cut,
    // then the fatal error.
    let cut = bytes.len() * 2 / 3;
    std::fs::write(&cut_path, &bytes[..cut]).unwrap();
    let items: Vec<_> = voxel_frames(&cut_path).unwrap().collect();
    let (last, firsts) = items.split_last().unwrap();
    assert!(!firsts.is_empty());
    assert!(firsts.iter().all(Result::is_ok));
    match last {
        Err(FrameError::Bag(err @ BagError::Truncated { offset, .. })) => {
            assert_eq!(*offset, cut as u64);
            assert!(err.to_string().contains("truncated"), "{err}");
        }
        other => panic!("{other:?}"),
    }
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

#[test]
fn a_corrupted_chunk_is_skipped_and_reading_goes_on() {
    let dir = tempdir();
    let frames = interleaved(12);
    for compression in [Some(BagCompression::Zstd), None] {
        let path = dir.path().join("bag.mcap");
        write_bag(
            &path,
            BagWriteOptions::new()
                .compression(compression)
                .chunk_size(400),
            &frames,
        );
        let mut bytes = std::fs::read(&path).unwrap();
        let chunks = chunks(&bytes);
        assert!(chunks.len() >= 4, "{chunks:?}");
        let (start, len) = chunks[1];
        // A byte well inside the chunk's records.
        let at = start + len - len / 4;
        bytes[at] ^= 0x5a;
        std::fs::write(&path, &bytes).unwrap();

        let (messages, errors, open_error) = read_lossy(&path);
        assert!(open_error.is_none());
        assert_eq!(errors.len(), 1, "{errors:?}");
        match &errors[0] {
            BagError::CorruptChunk { offset, .. } => assert_eq!(*offset, start as u64),
            other => panic!("{compression:?}: {other}"),
        }
        assert!(!errors[0].is_fatal());
        // Everything outside the damaged chunk was read, in order.
        assert!(messages.len() < frames.len());
        assert!(messages.len() >= frames.len() - frames.len() / 2);
        let expected: Vec<_> = frames.iter().map(|(_, t, _)| *t).collect();
        let mut it = expected.iter();
        for m in &messages {
            assert!(
                it.any(|t| *t == m.log_time_ns),
                "out of order or unknown message"
            );
        }

        // voxel_frames reports the chunk and goes on.
        let items: Vec<_> = voxel_frames(&path).unwrap().collect();
        assert_eq!(items.iter().filter(|i| i.is_err()).count(), 1);
        assert_eq!(items.len(), messages.len() + 1);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn damaged_bags_never_panic(
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in any::<prop::sample::Index>(),
        do_cut in any::<bool>(),
        zstd in any::<bool>(),
    ) {
        let dir = tempdir();
        let path = dir.path().join("bag.mcap");
        let compression = zstd.then_some(BagCompression::Zstd);
        write_bag(
            &path,
            BagWriteOptions::new().compression(compression).chunk_size(500),
            &interleaved(4),
        );
        let mut bytes = std::fs::read(&path).unwrap();
        for (at, value) in flips {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        if do_cut {
            bytes.truncate(cut.index(bytes.len()));
        }
        std::fs::write(&path, &bytes).unwrap();
        let _ = read_lossy(&path);
        if let Ok(frames) = voxel_frames(&path) {
            for item in frames.take(10_000) {
                let _ = item;
            }
        }
        let _ = voxel_topics(&path);
    }
}

/// Writes a file of MCAP records by hand: the magic, a Header, then `records`.
fn handmade_bag(path: &Path, records: &[(u8, Vec<u8>)]) {
    let mut out = vec![0x89, b'M', b'C', b'A', b'P', 0x30, b'\r', b'\n'];
    let mut header = Vec::new();
    for s in ["ros2", "test"] {
        header.extend((s.len() as u32).to_le_bytes());
        header.extend(s.as_bytes());
    }
    for (opcode, body) in std::iter::once(&(0x01, header)).chain(records) {
        out.push(*opcode);
        out.extend((body.len() as u64).to_le_bytes());
        out.extend(body);
    }
    std::fs::write(path, out).unwrap();
}

#[test]
fn bogus_lengths_in_a_bag_are_errors_not_allocations() {
    let dir = tempdir();
    let path = dir.path().join("bogus.mcap");

    // A record claiming 1 TiB: over the reader's limit, skipped, nothing allocated; nothing
    // readable follows and the file has no footer, so it is truncated there.
    let mut bytes = {
        handmade_bag(&path, &[]);
        std::fs::read(&path).unwrap()
    };
    bytes.push(0x03);
    bytes.extend((1u64 << 40).to_le_bytes());
    bytes.extend([0; 16]);
    std::fs::write(&path, &bytes).unwrap();
    let items: Vec<_> = BagReader::open(&path).unwrap().collect();
    assert!(
        matches!(
            items[..],
            [Err(BagError::RecordTooLarge { len, .. }), Err(BagError::Truncated { .. })]
                if len == 1 << 40
        ),
        "{items:?}"
    );
    assert!(!items[0].as_ref().unwrap_err().is_fatal());

    // A record claiming 100 MiB, under the limit but beyond the end of the file: truncated.
    bytes.truncate(bytes.len() - 25);
    bytes.push(0x03);
    bytes.extend((100u64 << 20).to_le_bytes());
    bytes.extend([0; 16]);
    std::fs::write(&path, &bytes).unwrap();
    let items: Vec<_> = BagReader::open(&path).unwrap().collect();
    assert!(
        matches!(items[..], [Err(BagError::Truncated { offset, .. })] if offset == bytes.len() as u64),
        "{items:?}"
    );

    // A schema whose name claims 4 GiB, and a chunk claiming a 1 TiB decompressed size:
    // both are skipped with an error naming where they are, and reading goes on to the end.
    let mut schema = 1u16.to_le_bytes().to_vec();
    schema.extend(u32::MAX.to_le_bytes());
    schema.extend(b"name");
    let mut chunk = Vec::new();
    chunk.extend(0u64.to_le_bytes());
    chunk.extend(0u64.to_le_bytes());
    chunk.extend((1u64 << 40).to_le_bytes());
    chunk.extend(0u32.to_le_bytes());
    chunk.extend(4u32.to_le_bytes());
    chunk.extend(b"zstd");
    chunk.extend(4u64.to_le_bytes());
    chunk.extend([1, 2, 3, 4]);
    handmade_bag(&path, &[(0x03, schema), (0x06, chunk)]);
    let items: Vec<_> = BagReader::open(&path).unwrap().collect();
    assert_eq!(items.len(), 3, "{items:?}");
    let text: Vec<String> = items
        .iter()
        .map(|i| i.as_ref().unwrap_err().to_string())
        .collect();
    assert!(
        text[0].contains("malformed Schema record at byte 33"),
        "{}",
        text[0]
    );
    assert!(
        matches!(items[1], Err(BagError::RecordTooLarge { offset: 52, .. })),
        "{}",
        text[1]
    );
    assert!(
        matches!(items[2], Err(BagError::Truncated { .. })),
        "{}",
        text[2]
    );
}

#[test]
fn files_that_are_not_mcap_are_refused() {
    let dir = tempdir();
    let path = dir.path().join("x.mcap");
    for content in [&b""[..], b"hello", b"not an mcap file at all"] {
        std::fs::write(&path, content).unwrap();
        assert!(matches!(
            BagReader::open(&path),
            Err(BagError::NotMcap { .. })
        ));
        assert!(matches!(voxel_frames(&path), Err(BagError::NotMcap { .. })));
    }
    let missing = dir.path().join("missing.mcap");
    let err = BagReader::open(&missing).err().unwrap();
    assert!(matches!(err, BagError::Io { .. }));
    assert!(err.to_string().contains("missing.mcap"), "{err}");
}

#[test]
fn an_empty_bag_is_reported_as_empty() {
    let dir = tempdir();
    let path = dir.path().join("empty.mcap");
    let mut bag = BagWriter::create(&path).unwrap();
    bag.add_topic::<VoxelGrid>("/a/occupancy").unwrap();
    bag.finish().unwrap();
    assert_eq!(read_all(&path).len(), 0);
    assert!(matches!(
        voxel_frames(&path),
        Err(BagError::EmptyBag { .. })
    ));
    assert_eq!(voxel_topics(&path).unwrap(), ["/a/occupancy"]);

    BagWriter::create(&path).unwrap().finish().unwrap();
    assert!(matches!(
        voxel_frames(&path),
        Err(BagError::EmptyBag { .. })
    ));
    assert!(voxel_topics(&path).unwrap().is_empty());

    // Without its summary (cut after the data section) the scan says the same.
    let bytes = std::fs::read(&path).unwrap();
    let without_summary = PathBuf::from(format!("{}.cut", path.display()));
    std::fs::write(&without_summary, &bytes[..bytes.len() - 60]).unwrap();
    let err = voxel_frames(&without_summary).err().unwrap();
    assert!(
        matches!(err, BagError::EmptyBag { .. } | BagError::Truncated { .. }),
        "{err}"
    );
}

/// `std_msgs/msg/String`, for a bag without VoxelGrid topics.
#[derive(Debug, PartialEq, Serialize, Deserialize)]
struct StringMsg {
    data: String,
}

impl RosMessage for StringMsg {
    const TYPE_NAME: &'static str = "std_msgs/msg/String";
    const DEFINITION: &'static str = "string data\n";
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        Vec::new()
    }
}

#[test]
fn a_bag_without_voxel_topics_names_the_topics_it_has() {
    let dir = tempdir();
    let path = dir.path().join("chatter.mcap");
    let mut bag = BagWriter::create(&path).unwrap();
    bag.add_topic::<StringMsg>("/chatter").unwrap();
    bag.add_topic::<VoxelGrid>("/silent/occupancy").unwrap();
    for i in 0..3u64 {
        let msg = StringMsg {
            data: format!("hello {i}"),
        };
        bag.write("/chatter", 10 + i, &msg).unwrap();
    }
    bag.finish().unwrap();

    let messages: Vec<BagMessage> = read_all(&path).into_iter().map(Result::unwrap).collect();
    assert_eq!(messages.len(), 3);
    assert_eq!(messages[2].schema_name, "std_msgs/msg/String");
    assert_eq!(
        decode_cdr::<StringMsg>(&messages[2].data).unwrap().data,
        "hello 2"
    );
    // A VoxelGrid topic without messages is named as such, not as a missing type.
    match voxel_frames(&path) {
        Err(err @ BagError::NoVoxelFrames { .. }) => {
            let text = err.to_string();
            assert!(text.contains("/silent/occupancy"), "{text}");
            assert!(text.contains("no messages"), "{text}");
            assert!(!text.contains("no messages of type"), "{text}");
        }
        Err(other) => panic!("{other}"),
        Ok(_) => panic!("frames in a bag without frames"),
    }
    assert_eq!(voxel_topics(&path).unwrap(), ["/silent/occupancy"]);

    // Without any VoxelGrid channel: the topics it has are listed.
    let mut bag = BagWriter::create(&path).unwrap();
    bag.add_topic::<StringMsg>("/chatter").unwrap();
    bag.write("/chatter", 10, &StringMsg { data: "hi".into() })
        .unwrap();
    bag.finish().unwrap();
    match voxel_frames(&path) {
        Err(BagError::NoVoxelTopics { topics_seen, .. }) => {
            assert_eq!(topics_seen, ["/chatter (std_msgs/msg/String)"])
        }
        Err(other) => panic!("{other}"),
        Ok(_) => panic!("frames in a bag without frames"),
    }
}

#[test]
fn undecodable_frames_are_errors_and_iteration_goes_on() {
    let dir = tempdir();
    let path = dir.path().join("mixed.mcap");
    let mut bag = BagWriter::create(&path).unwrap();
    bag.add_topic::<VoxelGrid>("/a/occupancy").unwrap();
    bag.write("/a/occupancy", 1, &grid(1, VoxelGrid::ENCODING_BITS))
        .unwrap();
    bag.write_cdr("/a/occupancy", 2, &[0, 1, 0, 0, 7]).unwrap();
    bag.write("/a/occupancy", 3, &grid(3, VoxelGrid::ENCODING_BITS))
        .unwrap();
    bag.finish().unwrap();
    let items: Vec<_> = voxel_frames(&path).unwrap().collect();
    assert_eq!(items.len(), 3);
    assert_eq!(
        items[0].as_ref().unwrap().1,
        grid(1, VoxelGrid::ENCODING_BITS)
    );
    match &items[1] {
        Err(FrameError::Decode {
            topic,
            log_time_ns: 2,
            reason: CdrError::Truncated { .. },
            ..
        }) => assert_eq!(topic, "/a/occupancy"),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        items[2].as_ref().unwrap().1,
        grid(3, VoxelGrid::ENCODING_BITS)
    );
}

#[test]
fn writer_misuse_is_reported() {
    let dir = tempdir();
    let mut bag = BagWriter::create(dir.path().join("w.mcap")).unwrap();
    let g = grid(0, VoxelGrid::ENCODING_BITS);
    assert!(matches!(
        bag.write("/nowhere", 0, &g),
        Err(BagError::UnknownTopic { .. })
    ));
    bag.add_topic::<VoxelGrid>("/a").unwrap();
    bag.add_topic::<VoxelGrid>("/a").unwrap();
    assert!(matches!(
        bag.add_topic::<StringMsg>("/a"),
        Err(BagError::TopicTypeConflict { .. })
    ));
    let s = StringMsg { data: "x".into() };
    assert!(matches!(
        bag.write("/a", 0, &s),
        Err(BagError::TopicTypeConflict { .. })
    ));
    assert!(matches!(
        bag.write_cdr("/a", 0, &[1, 2]),
        Err(BagError::Cdr {
            source: CdrError::TooShort { len: 2 },
            ..
        })
    ));
    // Missing parent directories are made; a parent that is a file is not a directory.
    std::fs::write(dir.path().join("file"), b"x").unwrap();
    assert!(matches!(
        BagWriter::create(dir.path().join("file/w.mcap")),
        Err(BagError::Io { .. })
    ));
}

/// Writes the bag `tests/py/read_bags.py` is checked on: every topic and both encodings.
#[test]
fn sample_bag_for_python_readers() {
    let dir = tempdir();
    let path = match std::env::var_os("CHRONOTOPE_SAMPLE_BAG") {
        Some(path) => PathBuf::from(path),
        None => dir.path().join("sample.mcap"),
    };
    write_bag(&path, BagWriteOptions::new(), &interleaved(5));
    assert_eq!(voxel_frames(&path).unwrap().count(), 15);
}
