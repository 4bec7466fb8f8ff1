//! Fuzzing by property tests: hostile bytes and text into every reader of user input.
//!
//! cargo-fuzz needs a nightly toolchain, so the fuzzing here is proptest: each property
//! mutates real input (the bundled bags, messages taken out of them and out of a replay's
//! output, the launch configs, the sampler scenes, the cut-out images) and feeds it to the
//! reader. Every property asks the same three things of the code under test:
//!
//! - it never panics (proptest turns a panic into a failing, shrunk case);
//! - it returns within a time bound ([`TIME_BOUND`]; a hang or a quadratic blow-up fails);
//! - every error it returns formats to a non-empty message that is not a Rust debug dump
//!   (no `Foo { .. }`, no `Foo { field: .. }`).
//!
//! The number of cases per property is modest by default so the whole file runs in well
//! under a minute in a test build; `CHRONOTOPE_FUZZ_CASES=5000 cargo test --release --test
//! fuzz` runs longer. Failing cases are not persisted (`failure_persistence: None`): the
//! shrunk input is printed, and belongs in a regression test next to the code it breaks.
//!
//! The calls into the library are kept in the small helper functions right below, so that a
//! change of a reader's signature touches only them.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use chronotope::bag::{voxel_frames, voxel_topics, BagReader};
use chronotope::carving::cutout::BinaryImage;
use chronotope::mesh::grid::{DecodeOptions, FrameRef, OccupancyGrid};
use chronotope::msg::{RosMessage, VoxelGrid};
use chronotope::node::carving::CarvingNode;
use chronotope::node::checker::CheckerNode;
use chronotope::node::launch::{LaunchConfig, NodeKind};
use chronotope::node::mesher::MesherNode;
use chronotope::node::occupancy::OccupancyNode;
use chronotope::node::{Message, Node, Payload};
use chronotope::sampler::scene_file::SceneFile;
use proptest::prelude::*;
use proptest::test_runner::Config;

// ---------------------------------------------------------------------------------------
// The library's entry points, one helper each. Each returns the formatted errors it met.
// ---------------------------------------------------------------------------------------

/// Most items one read of a bag may yield: a reader that loops forever on damaged input
/// fails here instead of hanging the test.
const MAX_ITEMS: usize = 200_000;

/// Reads every message of the bag at `path` with [`BagReader`], then every VoxelGrid frame
/// with [`voxel_frames`] (decoding each grid as the mesher does), then its body list.
fn read_bag(path: &Path) -> Vec<String> {
    let mut errors = Vec::new();
    match BagReader::open(path) {
        Err(e) => errors.push(e.to_string()),
        Ok(reader) => {
            let mut n = 0;
            for item in reader {
                n += 1;
                assert!(n <= MAX_ITEMS, "BagReader yields without end");
                if let Err(e) = item {
                    errors.push(e.to_string());
                }
            }
        }
    }
    match voxel_frames(path) {
        Err(e) => errors.push(e.to_string()),
        Ok(frames) => {
            let mut n = 0;
            for item in frames {
                n += 1;
                assert!(n <= MAX_ITEMS, "voxel_frames yields without end");
                match item {
                    Ok((_, grid)) => errors.extend(decode_grid(&grid)),
                    Err(e) => errors.push(e.to_string()),
                }
            }
        }
    }
    if let Err(e) = voxel_topics(path) {
        errors.push(e.to_string());
    }
    errors
}

/// Decodes a VoxelGrid's voxels as the mesher does (with limits small enough for a test).
fn decode_grid(grid: &VoxelGrid) -> Option<String> {
    let frame = FrameRef {
        stamp_ns: grid.header.stamp.as_nanos(),
        origin: [grid.origin.x, grid.origin.y, grid.origin.z],
        resolution: grid.resolution,
        size: [grid.size_x, grid.size_y, grid.size_z],
        encoding: grid.encoding,
        data: &grid.data,
    };
    let opts = DecodeOptions {
        max_voxels: 1 << 24,
        max_decoded_bytes: 64 << 20,
        ..DecodeOptions::default()
    };
    OccupancyGrid::decode(&frame, &opts)
        .err()
        .map(|e| e.to_string())
}

/// Decodes CDR bytes as the message type named `type_name` (every type a node reads or
/// publishes); for a VoxelGrid, also its voxels.
fn decode_message(type_name: &str, bytes: &[u8]) -> Vec<String> {
    match Payload::decode(type_name, bytes) {
        Ok(Payload::VoxelGrid(grid)) => decode_grid(&grid).into_iter().collect(),
        Ok(p @ (Payload::Octomap(_) | Payload::PointCloud2(_))) => rasterise(p),
        Ok(_) => Vec::new(),
        Err(e) => vec![e.to_string()],
    }
}

/// Rasterises an OctoMap or a cloud with an occupancy node, as `replay` and `launch` do, on
/// a 24³ lattice of 0.1 m around the origin in the message's own frame, in both encodings
/// (an octree also with unknown space occupied); returns the node's problem texts.
fn rasterise(payload: Payload) -> Vec<String> {
    let (ty, extra) = match &payload {
        Payload::Octomap(_) => (
            "octomap_msgs/msg/Octomap",
            ["{name: unknown_occupied, value: true}", ""],
        ),
        _ => (
            "sensor_msgs/msg/PointCloud2",
            ["{name: dilate_m, value: 0.15}, {name: min_points, value: 2}, {name: fill, value: columns}", ""],
        ),
    };
    let mut texts = Vec::new();
    for (encoding, extra) in [
        ("bits", extra[0]),
        ("percent", extra[1]),
        ("bits", extra[1]),
    ] {
        let params = [
            "{name: input_topic, value: /in}".to_owned(),
            format!("{{name: input_type, value: {ty}}}"),
            "{name: origin, value: [-1.2, -1.2, -1.2]}".into(),
            "{name: resolution, value: 0.1}".into(),
            "{name: size, value: [24, 24, 24]}".into(),
            format!("{{name: encoding, value: {encoding}}}"),
            extra.to_owned(),
        ];
        let text = format!(
            "launch:\n- node: {{pkg: chronotope, exec: occupancy, param: [{}]}}\n",
            params
                .iter()
                .filter(|p| !p.is_empty())
                .cloned()
                .collect::<Vec<_>>()
                .join(", ")
        );
        let config = LaunchConfig::parse(&text, "fuzz").expect("the fuzz config");
        let mut node = OccupancyNode::from_spec(&config.nodes[0]).expect("the fuzz node");
        let mut out = Vec::new();
        node.on_message(&Message::new("/in", 0, payload.clone()), &mut out);
        for m in &out {
            if let Payload::VoxelGrid(g) = &m.payload {
                texts.extend(decode_grid(g));
            }
        }
        texts.extend(node.status().messages.iter().cloned());
    }
    texts
}

/// Parses a launch config and builds each of its nodes from its parameters, as `replay` and
/// `launch` do (the bodies a bag would offer are the machine-tool scene's).
fn parse_launch(text: &str) -> Vec<String> {
    let config = match LaunchConfig::parse(text, "fuzz.yaml") {
        Ok(c) => c,
        Err(e) => return vec![e.to_string()],
    };
    let mut bodies: Vec<String> = [
        "/spindle/occupancy",
        "/table/occupancy",
        "/fixture/occupancy",
    ]
    .map(String::from)
    .to_vec();
    let mut errors = Vec::new();
    for spec in config.of_kind(NodeKind::Carving) {
        match CarvingNode::from_spec(spec) {
            Ok(node) => bodies.push(node.occupancy_topic().to_owned()),
            Err(e) => errors.push(e.to_string()),
        }
    }
    for spec in config.of_kind(NodeKind::Occupancy) {
        match OccupancyNode::from_spec(spec) {
            Ok(node) => bodies.push(node.occupancy_topic().to_owned()),
            Err(e) => errors.push(e.to_string()),
        }
    }
    for spec in config.of_kind(NodeKind::Mesher) {
        if let Err(e) = MesherNode::from_spec(spec, &bodies) {
            errors.push(e.to_string());
        }
    }
    for spec in config.of_kind(NodeKind::Checker) {
        if let Err(e) = CheckerNode::from_spec(spec, &bodies) {
            errors.push(e.to_string());
        }
    }
    errors
}

/// Parses a sampler scene file and builds its figure, as `chronotope sample` does.
fn parse_scene(text: &str) -> Vec<String> {
    match SceneFile::parse(text).and_then(|s| s.build()) {
        Ok(_) => Vec::new(),
        Err(e) => vec![e.to_string()],
    }
}

/// Loads a cut-out image from bytes, through a file as the carving node does.
fn load_image(bytes: &[u8], dir: &Path) -> Vec<String> {
    let path = dir.join("outline.img");
    std::fs::write(&path, bytes).expect("temp file");
    match BinaryImage::load(&path) {
        Ok(image) => {
            assert_eq!(image.black.len(), image.width * image.height);
            Vec::new()
        }
        Err(e) => vec![e.to_string()],
    }
}

// ---------------------------------------------------------------------------------------
// What every property checks.
// ---------------------------------------------------------------------------------------

/// One input must be handled within this (test build, two busy cores): generous, so that
/// only a hang or a super-linear blow-up trips it.
const TIME_BOUND: Duration = Duration::from_secs(10);

/// Cases per property: `CHRONOTOPE_FUZZ_CASES`, or `default`.
fn config(default: u32) -> Config {
    let cases = std::env::var("CHRONOTOPE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default);
    Config {
        cases,
        failure_persistence: None,
        max_shrink_iters: 256,
        ..Config::default()
    }
}

/// Runs `f`, failing if it takes longer than [`TIME_BOUND`] or returns a bad message.
fn check(what: &str, f: impl FnOnce() -> Vec<String>) -> Result<(), TestCaseError> {
    let start = Instant::now();
    let errors = f();
    let took = start.elapsed();
    prop_assert!(
        took <= TIME_BOUND,
        "{what}: took {took:?}, more than {TIME_BOUND:?}"
    );
    for e in errors.iter() {
        if let Some(problem) = message_problem(e) {
            return Err(TestCaseError::fail(format!("{what}: {problem}: {e:?}")));
        }
    }
    Ok(())
}

/// Why `message` is not one a user can act on, if it is not.
fn message_problem(message: &str) -> Option<&'static str> {
    if message.trim().is_empty() {
        return Some("empty error message");
    }
    if message.contains("{ ..") || message.contains("{..}") {
        return Some("debug dump `{ .. }` in an error message");
    }
    // `Name { field: ...`: a struct's Debug output.
    let bytes = message.as_bytes();
    for (i, _) in message.match_indices(" { ") {
        let word: Vec<u8> = bytes[..i]
            .iter()
            .rev()
            .take_while(|b| b.is_ascii_alphanumeric() || **b == b'_')
            .copied()
            .collect();
        let rest = &message[i + 3..];
        let field = rest
            .split(':')
            .next()
            .filter(|f| f.chars().all(|c| c.is_ascii_lowercase() || c == '_'));
        if word.last().is_some_and(u8::is_ascii_uppercase) && field.is_some_and(|f| !f.is_empty()) {
            return Some("debug dump `Type { field: .. }` in an error message");
        }
    }
    None
}

// ---------------------------------------------------------------------------------------
// Seeds: the bundled inputs, read once.
// ---------------------------------------------------------------------------------------

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// The bundled bags' bytes, by name.
fn bags() -> &'static [(String, Vec<u8>)] {
    static BAGS: OnceLock<Vec<(String, Vec<u8>)>> = OnceLock::new();
    BAGS.get_or_init(|| {
        let mut v: Vec<_> = std::fs::read_dir(repo("bags"))
            .expect("bags/")
            .map(|e| e.expect("dir entry").path())
            .filter(|p| p.extension().is_some_and(|e| e == "mcap"))
            .map(|p| {
                let name = p.file_name().unwrap().to_string_lossy().into_owned();
                (name, std::fs::read(&p).expect("bundled bag"))
            })
            .collect();
        v.sort();
        assert!(v.len() >= 6, "the six bundled bags");
        v
    })
}

/// Real messages, `(type name, CDR bytes)`: a few of each type out of the bundled bags, and
/// one of each type the nodes publish, out of a replay of the machine-tool bag and of the
/// carving session (so that every type of `Payload` has a seed).
fn messages() -> &'static [(String, Vec<u8>)] {
    static MESSAGES: OnceLock<Vec<(String, Vec<u8>)>> = OnceLock::new();
    MESSAGES.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        let mut paths: Vec<PathBuf> = bags()
            .iter()
            .map(|(name, _)| repo("bags").join(name))
            .collect();
        for (bag, cfg) in [
            (
                "machine-tool-32-bits.mcap",
                "launch_configs/machine_tool.yaml",
            ),
            (
                "carving-session.mcap",
                "launch_configs/carving_session.yaml",
            ),
            ("robot-cell-32.mcap", "launch_configs/robot_cell.yaml"),
        ] {
            let out = dir.path().join(bag);
            replay_to(&repo("bags").join(bag), &repo(cfg), &out);
            paths.push(out);
        }
        let mut per_type = std::collections::BTreeMap::<String, Vec<Vec<u8>>>::new();
        for path in paths {
            for m in BagReader::open(&path).expect("seed bag").flatten() {
                let kept = per_type.entry(m.schema_name).or_default();
                if kept.len() < 3 {
                    kept.push(m.data);
                }
            }
        }
        let v: Vec<_> = per_type
            .into_iter()
            .flat_map(|(t, ms)| ms.into_iter().map(move |m| (t.clone(), m)))
            .filter(|(t, _)| Payload::schema_of(t).is_some())
            .collect();
        assert!(v.len() >= 8, "seed messages of several types");
        v
    })
}

/// Replays `bag` with `config` in process and writes every published topic to `out`.
fn replay_to(bag: &Path, config: &Path, out: &Path) {
    // The carving config names its images relative to the repository root.
    let text = std::fs::read_to_string(config).expect("launch config");
    let text = text.replace("bags/", &format!("{}/", repo("bags").display()));
    let config = LaunchConfig::parse(&text, "seed config").expect("bundled launch config");
    chronotope::cli::replay::replay(bag, Some(&config), Some(out), false)
        .expect("bundled bag replays");
}

/// The texts of the files in `dir` with extension `yaml`.
fn texts(dir: &str) -> Vec<String> {
    let mut v: Vec<_> = std::fs::read_dir(repo(dir))
        .expect("seed dir")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .map(|p| std::fs::read_to_string(p).expect("seed text"))
        .collect();
    v.sort();
    v
}

fn launch_configs() -> &'static [String] {
    static V: OnceLock<Vec<String>> = OnceLock::new();
    V.get_or_init(|| texts("launch_configs"))
}

fn scene_files() -> &'static [String] {
    static V: OnceLock<Vec<String>> = OnceLock::new();
    V.get_or_init(|| texts("scenes/implicit"))
}

/// The bundled PGM outlines and a PNG of the same kind in each colour type.
fn images() -> &'static [Vec<u8>] {
    static V: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    V.get_or_init(|| {
        let mut v = vec![
            std::fs::read(repo("bags/carving-outline-z.pgm")).expect("bundled outline"),
            std::fs::read(repo("bags/carving-outline-y.pgm")).expect("bundled outline"),
            b"P2\n# a text PGM\n4 3\n255\n0 255 0 255\n255 0 255 0\n0 0 255 255\n".to_vec(),
        ];
        for colour in [
            png::ColorType::Grayscale,
            png::ColorType::GrayscaleAlpha,
            png::ColorType::Rgb,
            png::ColorType::Rgba,
        ] {
            v.push(png_bytes(12, 9, colour, png::BitDepth::Eight, None));
        }
        v.push(png_bytes(
            7,
            5,
            png::ColorType::Grayscale,
            png::BitDepth::Sixteen,
            None,
        ));
        v
    })
}

/// A PNG of `w` × `h` pixels (a diagonal pattern); with `keep`, only that many bytes of its
/// image data are written (a header that promises more than the file holds).
fn png_bytes(
    w: u32,
    h: u32,
    colour: png::ColorType,
    depth: png::BitDepth,
    keep: Option<usize>,
) -> Vec<u8> {
    let channels = match colour {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        _ => 4,
    };
    let bytes_per = channels
        * if depth == png::BitDepth::Sixteen {
            2
        } else {
            1
        };
    // Cut short, only the first rows' data is kept: a few rows are encoded and the header
    // then promises all `h` (an 8192 x 8192 image is not encoded to keep 200 bytes of it).
    let rows = if keep.is_some() { h.min(16) } else { h };
    let data: Vec<u8> = (0..(w * rows) as usize * bytes_per)
        .map(|i| if (i / bytes_per) % 3 == 0 { 0 } else { 255 })
        .collect();
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, w, rows);
        enc.set_color(colour);
        enc.set_depth(depth);
        let mut writer = enc.write_header().expect("png header");
        writer.write_image_data(&data).expect("png data");
    }
    match keep {
        None => out,
        Some(n) => {
            // The IHDR's height (after the signature, the chunk's length and type, and the
            // width); `cut_idat` writes its CRC again.
            out[20..24].copy_from_slice(&h.to_be_bytes());
            cut_idat(&out, n)
        }
    }
}

/// `png` with its image data cut to the first `keep` bytes, chunk lengths and CRCs fixed:
/// a well-formed file whose header promises more pixels than its data holds.
fn cut_idat(png: &[u8], keep: usize) -> Vec<u8> {
    let mut out = png[..8].to_vec();
    let mut pos = 8;
    while pos + 12 <= png.len() {
        let len = u32::from_be_bytes(png[pos..pos + 4].try_into().unwrap()) as usize;
        let kind = &png[pos + 4..pos + 8];
        let mut data = png[pos + 8..pos + 8 + len].to_vec();
        if kind == b"IDAT" {
            data.truncate(keep);
        }
        out.extend((data.len() as u32).to_be_bytes());
        let mut crc_input = kind.to_vec();
        crc_input.extend(&data);
        out.extend(&crc_input);
        out.extend(crc32(&crc_input).to_be_bytes());
        pos += 12 + len;
    }
    out
}

/// CRC-32 (IEEE), as PNG chunks use.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

// ---------------------------------------------------------------------------------------
// Mutations.
// ---------------------------------------------------------------------------------------

/// One change to a byte string; positions and lengths are fractions of its length, so one
/// strategy fits inputs of every size.
#[derive(Debug, Clone)]
enum Mutation {
    /// XOR the byte at `at` with `mask` (non-zero).
    Flip { at: f64, mask: u8 },
    /// Cut the input at `at`.
    Truncate { at: f64 },
    /// Zero `len` bytes from `at`.
    Zero { at: f64, len: usize },
    /// Copy `len` bytes from `from` and insert them again at `to` (a duplicated record or
    /// chunk when the range covers one).
    Duplicate { from: f64, len: usize, to: f64 },
    /// Insert `bytes` at `at`.
    Insert { at: f64, bytes: Vec<u8> },
    /// Overwrite 4 or 8 bytes at `at` with an extreme length-like value.
    Length { at: f64, value: u64, wide: bool },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let frac = 0.0..1.0f64;
    let extreme = prop_oneof![
        Just(0u64),
        Just(1),
        Just(u64::from(u32::MAX)),
        Just(u64::from(u32::MAX) - 3),
        Just(u64::MAX),
        Just(1 << 31),
        Just(1 << 40),
        any::<u64>(),
    ];
    prop_oneof![
        3 => (frac.clone(), 1..=255u8).prop_map(|(at, mask)| Mutation::Flip { at, mask }),
        1 => frac.clone().prop_map(|at| Mutation::Truncate { at }),
        2 => (frac.clone(), 1..4096usize).prop_map(|(at, len)| Mutation::Zero { at, len }),
        1 => (frac.clone(), 1..8192usize, frac.clone())
            .prop_map(|(from, len, to)| Mutation::Duplicate { from, len, to }),
        1 => (frac.clone(), prop::collection::vec(any::<u8>(), 1..32))
            .prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        2 => (frac, extreme, any::<bool>())
            .prop_map(|(at, value, wide)| Mutation::Length { at, value, wide }),
    ]
}

fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    prop::collection::vec(mutation(), 1..4)
}

fn index(at: f64, len: usize) -> usize {
    ((at * len as f64) as usize).min(len)
}

fn mutate(mut data: Vec<u8>, ms: &[Mutation]) -> Vec<u8> {
    for m in ms {
        let n = data.len();
        match m {
            Mutation::Flip { at, mask } => {
                if n > 0 {
                    let i = index(*at, n - 1);
                    data[i] ^= mask;
                }
            }
            Mutation::Truncate { at } => data.truncate(index(*at, n)),
            Mutation::Zero { at, len } => {
                let i = index(*at, n);
                let end = (i + len).min(n);
                data[i..end].fill(0);
            }
            Mutation::Duplicate { from, len, to } => {
                let i = index(*from, n);
                let piece = data[i..(i + len).min(n)].to_vec();
                let j = index(*to, n);
                data.splice(j..j, piece);
            }
            Mutation::Insert { at, bytes } => {
                let i = index(*at, n);
                data.splice(i..i, bytes.iter().copied());
            }
            Mutation::Length { at, value, wide } => {
                let w = if *wide { 8 } else { 4 };
                if n >= w {
                    let i = index(*at, n - w);
                    data[i..i + w].copy_from_slice(&value.to_le_bytes()[..w]);
                }
            }
        }
    }
    data
}

/// Values that break parameters, numbers and YAML in text inputs.
fn hostile_value() -> impl Strategy<Value = String> {
    prop_oneof![
        Just(".nan".to_owned()),
        Just("-.inf".to_owned()),
        Just(".inf".to_owned()),
        Just("-1".to_owned()),
        Just("0".to_owned()),
        Just("1e-5".to_owned()),
        Just("1e308".to_owned()),
        Just("-0.0".to_owned()),
        Just("18446744073709551616".to_owned()),
        Just("9".repeat(300)),
        Just("''".to_owned()),
        Just("[]".to_owned()),
        Just("{}".to_owned()),
        Just("~".to_owned()),
        Just("[.nan, .nan, .nan]".to_owned()),
        Just("[1, 2]".to_owned()),
        Just("&a [*a]".to_owned()),
        Just("/".to_owned()),
        Just("/fixture/occupancy".to_owned()),
        Just("\"x y z\"".to_owned()),
        (1..400usize).prop_map(|d| format!("{}{}", "[".repeat(d), "]".repeat(d))),
        (1..400usize).prop_map(|d| "[".repeat(d)),
        (1..200usize).prop_map(|d| format!("{}1{}", "{a: ".repeat(d), "}".repeat(d))),
        "[a-z_/ ]{0,20}",
    ]
}

/// One change to a YAML text: a scalar after `: ` replaced by a hostile value, a line
/// deleted or duplicated, a line's indentation changed, or a mutation of its bytes.
#[derive(Debug, Clone)]
enum TextEdit {
    Value { at: f64, value: String },
    DeleteLine { at: f64 },
    DuplicateLine { at: f64, times: usize },
    Indent { at: f64, spaces: usize },
    Bytes(Mutation),
}

fn text_edits() -> impl Strategy<Value = Vec<TextEdit>> {
    let frac = 0.0..1.0f64;
    let edit = prop_oneof![
        4 => (frac.clone(), hostile_value()).prop_map(|(at, value)| TextEdit::Value { at, value }),
        1 => frac.clone().prop_map(|at| TextEdit::DeleteLine { at }),
        1 => (frac.clone(), 1..300usize)
            .prop_map(|(at, times)| TextEdit::DuplicateLine { at, times }),
        1 => (frac, 0..9usize).prop_map(|(at, spaces)| TextEdit::Indent { at, spaces }),
        1 => mutation().prop_map(TextEdit::Bytes),
    ];
    prop::collection::vec(edit, 1..4)
}

fn edit_text(text: &str, edits: &[TextEdit]) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let mut bytes_edits = Vec::new();
    for e in edits {
        let n = lines.len();
        if n == 0 {
            break;
        }
        let line = |at: &f64| index(*at, n - 1);
        match e {
            TextEdit::Value { at, value } => {
                // The n-th `: ` of the text, counted over all lines.
                let spots: Vec<(usize, usize)> = lines
                    .iter()
                    .enumerate()
                    .flat_map(|(i, l)| l.match_indices(": ").map(move |(j, _)| (i, j)))
                    .collect();
                if let Some(&(i, j)) = spots.get(index(*at, spots.len().saturating_sub(1))) {
                    let l = &lines[i];
                    let end = l[j + 2..].find([',', '}']).map_or(l.len(), |k| j + 2 + k);
                    lines[i] = format!("{}{}{}", &l[..j + 2], value, &l[end..]);
                }
            }
            TextEdit::DeleteLine { at } => {
                lines.remove(line(at));
            }
            TextEdit::DuplicateLine { at, times } => {
                let i = line(at);
                let l = lines[i].clone();
                lines.splice(i..i, std::iter::repeat_n(l, *times));
            }
            TextEdit::Indent { at, spaces } => {
                let i = line(at);
                lines[i] = format!("{}{}", " ".repeat(*spaces), lines[i].trim_start());
            }
            TextEdit::Bytes(m) => bytes_edits.push(m.clone()),
        }
    }
    let text = lines.join("\n");
    let bytes = mutate(text.into_bytes(), &bytes_edits);
    String::from_utf8_lossy(&bytes).into_owned()
}

// ---------------------------------------------------------------------------------------
// The properties.
// ---------------------------------------------------------------------------------------

proptest! {
    #![proptest_config(config(24))]

    /// A damaged copy of a bundled bag: read, framed and decoded without panic, in time,
    /// with readable errors.
    #[test]
    fn bag_reader_survives_damaged_bags(bag in 0..6usize, ms in mutations()) {
        let (name, bytes) = &bags()[bag % bags().len()];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, mutate(bytes.clone(), &ms)).unwrap();
        check(name, || read_bag(&path))?;
    }
}

proptest! {
    #![proptest_config(config(128))]

    /// A damaged real message, decoded as its own type.
    #[test]
    fn cdr_decoder_survives_damaged_messages(m in 0..1000usize, ms in mutations()) {
        let (type_name, bytes) = &messages()[m % messages().len()];
        let data = mutate(bytes.clone(), &ms);
        check(type_name, || decode_message(type_name, &data))?;
    }

    /// A real message decoded as another type (a topic routed to the wrong meaning).
    #[test]
    fn cdr_decoder_survives_type_confusion(m in 0..1000usize, t in 0..1000usize) {
        let (_, bytes) = &messages()[m % messages().len()];
        let (type_name, _) = &messages()[t % messages().len()];
        check(type_name, || decode_message(type_name, bytes))?;
    }

    /// A VoxelGrid with hostile field values (sizes, resolution, origin, encoding, stamp)
    /// around data of any length: encoded, decoded and its voxels decoded.
    #[test]
    fn voxel_grid_decode_survives_hostile_fields(
        size in prop::array::uniform3(prop_oneof![
            Just(0u32), 1..40u32, Just(8), Just(16384), Just(8192), Just(u32::MAX),
            Just(1 << 16), any::<u32>(),
        ]),
        resolution in prop_oneof![
            Just(f64::NAN), Just(f64::INFINITY), Just(-0.01), Just(0.0), Just(1e-300),
            Just(0.01), Just(1e300), any::<f64>(),
        ],
        origin in prop::array::uniform3(prop_oneof![
            Just(0.0f64), Just(f64::NAN), Just(f64::NEG_INFINITY), Just(1e300), Just(0.005),
            any::<f64>(),
        ]),
        encoding in prop_oneof![Just(0u8), Just(1), any::<u8>()],
        nanosec in prop_oneof![Just(0u32), Just(999_999_999), Just(1_000_000_000), any::<u32>()],
        data in prop::collection::vec(any::<u8>(), 0..600),
    ) {
        let mut grid = VoxelGrid {
            resolution,
            size_x: size[0],
            size_y: size[1],
            size_z: size[2],
            encoding,
            data,
            ..VoxelGrid::default()
        };
        grid.header.stamp.nanosec = nanosec;
        grid.origin.x = origin[0];
        grid.origin.y = origin[1];
        grid.origin.z = origin[2];
        let bytes = chronotope::msg::encode_cdr(&grid).unwrap();
        check("VoxelGrid", || decode_message(<VoxelGrid as RosMessage>::TYPE_NAME, &bytes))?;
    }

    /// A real octree or cloud whose map bytes, layout fields and flags are damaged after
    /// decoding (what survives CDR: a truncated or inconsistent tree, a child count past the
    /// data, a wrong tree id or resolution, fields or steps that do not cover a point):
    /// rasterised without panic, in time, every refusal a sentence.
    #[test]
    fn occupancy_node_survives_damaged_octrees_and_clouds(
        m in 0..1000usize,
        ms in mutations(),
        flip in any::<bool>(),
        id in prop_oneof![Just(None), Just(Some("ColorOcTree")), Just(Some("OcTreeStamped")),
                          Just(Some("CountingOcTree")), Just(Some(""))],
        resolution in prop_oneof![Just(None), Just(Some(0.0)), Just(Some(f64::NAN)),
                                  Just(Some(1e-9)), Just(Some(0.013)), Just(Some(5.0))],
        steps in prop::array::uniform4(prop_oneof![Just(None), Just(Some(0u32)), Just(Some(1)),
                                                   Just(Some(7)), Just(Some(u32::MAX)),
                                                   (0..64u32).prop_map(Some)]),
    ) {
        let seeds: Vec<_> = messages()
            .iter()
            .filter_map(|(t, b)| match Payload::decode(t, b) {
                Ok(p @ (Payload::Octomap(_) | Payload::PointCloud2(_))) => Some(p),
                _ => None,
            })
            .collect();
        prop_assume!(!seeds.is_empty());
        let payload = match seeds[m % seeds.len()].clone() {
            Payload::Octomap(o) => {
                let mut o = (*o).clone();
                o.data = mutate(o.data, &ms);
                o.binary ^= flip;
                if let Some(id) = id {
                    o.id = id.into();
                }
                if let Some(r) = resolution {
                    o.resolution = r;
                }
                Payload::Octomap(std::sync::Arc::new(o))
            }
            Payload::PointCloud2(c) => {
                let mut c = (*c).clone();
                c.data = mutate(c.data, &ms);
                c.is_bigendian ^= flip;
                let [a, b, d, e] = steps;
                c.point_step = a.unwrap_or(c.point_step);
                c.row_step = b.unwrap_or(c.row_step);
                c.width = d.map_or(c.width, |w| w.saturating_mul(c.width.max(1)));
                if let (Some(off), Some(f)) = (e, c.fields.get_mut(m % 4)) {
                    f.offset = off;
                }
                Payload::PointCloud2(std::sync::Arc::new(c))
            }
            _ => unreachable!(),
        };
        check("occupancy", || rasterise(payload))?;
    }

    /// Bytes that are not a message at all, as every type.
    #[test]
    fn cdr_decoder_survives_noise(t in 0..1000usize, data in prop::collection::vec(any::<u8>(), 0..256)) {
        let (type_name, _) = &messages()[t % messages().len()];
        check(type_name, || decode_message(type_name, &data))?;
    }
}

proptest! {
    #![proptest_config(config(64))]

    /// A bundled launch config with hostile values, lines deleted or repeated, indentation
    /// broken or bytes damaged: parsed and its nodes built, in time, with readable errors.
    #[test]
    fn launch_config_survives_hostile_text(c in 0..100usize, edits in text_edits()) {
        let text = edit_text(&launch_configs()[c % launch_configs().len()], &edits);
        check("launch config", || parse_launch(&text))?;
    }

    /// A bundled sampler scene, edited the same way: parsed and its figure built.
    #[test]
    fn scene_file_survives_hostile_text(s in 0..100usize, edits in text_edits()) {
        let text = edit_text(&scene_files()[s % scene_files().len()], &edits);
        check("scene file", || parse_scene(&text))?;
    }

    /// A damaged cut-out image (PGM or PNG), loaded from a file.
    #[test]
    fn image_loader_survives_damaged_images(i in 0..100usize, ms in mutations()) {
        let data = mutate(images()[i % images().len()].clone(), &ms);
        let dir = tempfile::tempdir().unwrap();
        check("image", || load_image(&data, dir.path()))?;
    }

    /// A PGM header with hostile numbers over little or no pixel data.
    #[test]
    fn image_loader_survives_hostile_pgm_headers(
        magic in prop_oneof![Just("P2"), Just("P5"), Just("P6"), Just("P")],
        w in prop_oneof![Just("0".to_owned()), Just("8192".to_owned()), Just("8193".to_owned()),
                         Just("4294967296".to_owned()), Just("9".repeat(300)), Just("-3".to_owned()),
                         (1..64u32).prop_map(|v| v.to_string())],
        h in prop_oneof![Just("0".to_owned()), Just("8192".to_owned()), Just("65536".to_owned()),
                         (1..64u32).prop_map(|v| v.to_string())],
        maxval in prop_oneof![Just("0".to_owned()), Just("1".to_owned()), Just("255".to_owned()),
                              Just("65535".to_owned()), Just("65536".to_owned())],
        body in prop::collection::vec(any::<u8>(), 0..300),
    ) {
        let mut data = format!("{magic}\n{w} {h}\n{maxval}\n").into_bytes();
        data.extend(body);
        let dir = tempfile::tempdir().unwrap();
        check("PGM", || load_image(&data, dir.path()))?;
    }

    /// A valid PNG header (correct CRCs) promising up to 8192 × 8192 pixels over a few bytes
    /// of image data.
    #[test]
    fn image_loader_survives_short_png_data(
        w in prop_oneof![1..64u32, Just(8192u32), Just(8193)],
        h in prop_oneof![1..64u32, Just(8192u32)],
        colour in prop_oneof![Just(png::ColorType::Grayscale), Just(png::ColorType::Rgba)],
        keep in 0..200usize,
    ) {
        let data = png_bytes(w, h, colour, png::BitDepth::Eight, Some(keep));
        let dir = tempfile::tempdir().unwrap();
        check("PNG", || load_image(&data, dir.path()))?;
    }
}

/// The checks themselves must be able to fail: a debug dump and an empty message are caught,
/// a sentence with braces is not.
#[test]
fn message_check_catches_debug_dumps() {
    assert!(message_problem("bad geometry GridGeometry { .. }").is_some());
    assert!(message_problem("frame GridGeometry { origin: [0.0, 0.0, 0.0] }").is_some());
    assert!(message_problem("  ").is_some());
    assert!(message_problem("resolution NaN m: a voxel edge must be a positive number").is_none());
    assert!(message_problem("expected a mapping like `node: {...}`").is_none());
}

/// The mutations do what they say, so that the properties above exercise what they claim.
#[test]
fn mutations_change_the_input() {
    let base: Vec<u8> = (0..100).collect();
    let flipped = mutate(
        base.clone(),
        &[Mutation::Flip {
            at: 0.5,
            mask: 0xff,
        }],
    );
    assert_eq!(flipped.len(), 100);
    assert_ne!(flipped, base);
    assert_eq!(
        mutate(base.clone(), &[Mutation::Truncate { at: 0.25 }]).len(),
        25
    );
    let dup = mutate(
        base.clone(),
        &[Mutation::Duplicate {
            from: 0.0,
            len: 10,
            to: 1.0,
        }],
    );
    assert_eq!(&dup[100..], &base[..10]);
    let zero = mutate(base.clone(), &[Mutation::Zero { at: 0.1, len: 5 }]);
    assert_eq!(&zero[10..15], &[0; 5]);
    let edited = edit_text(
        "a: 1\nb: {name: x, value: 2}\n",
        &[TextEdit::Value {
            at: 1.0,
            value: ".nan".into(),
        }],
    );
    assert_eq!(edited, "a: 1\nb: {name: x, value: .nan}");
}

/// The PNG surgery keeps files valid: an uncut copy decodes to the same image.
#[test]
fn cut_png_keeps_crcs_valid() {
    assert_eq!(crc32(b"IEND"), 0xAE42_6082);
    let whole = png_bytes(12, 9, png::ColorType::Rgb, png::BitDepth::Eight, None);
    let same = cut_idat(&whole, usize::MAX);
    assert_eq!(same, whole);
    assert!(BinaryImage::from_png(&same).is_ok());
    assert!(BinaryImage::from_png(&cut_idat(&whole, 3)).is_err());
}

/// A PNG whose IHDR chunk is damaged: the message must be a sentence, not the `png` crate's
/// `ChunkType { type: IHDR, critical: true, .. }`. Found by
/// `image_loader_survives_damaged_images`; fails on the loader as it is (the fix belongs in
/// `BinaryImage::from_png`, which passes the decoder's `Display` text on).
#[test]
fn png_errors_are_sentences() {
    let mut png = png_bytes(12, 9, png::ColorType::Rgb, png::BitDepth::Eight, None);
    // Zero the IHDR chunk's length field (bytes 8..12).
    png[8..12].fill(0);
    let dir = tempfile::tempdir().unwrap();
    let errors = load_image(&png, dir.path());
    assert_eq!(errors.len(), 1, "a damaged PNG is refused");
    assert_eq!(message_problem(&errors[0]), None, "{}", errors[0]);
}

// ---------------------------------------------------------------------------------------
// The robot node: hostile joint states, plans and descriptions.
// ---------------------------------------------------------------------------------------

/// A robot node on a small lattice with a two-joint robot (one mimic) loaded.
fn robot_node() -> chronotope::node::robot::RobotNode {
    use chronotope::msg::RosString;
    use chronotope::node::{Message, Node};
    let text = "launch:\n- node: {pkg: chronotope, exec: robot, param: [{name: origin, value: [-0.4, -0.4, 0.0]}, {name: resolution, value: 0.1}, {name: size, value: [8, 8, 8]}, {name: rate_hz, value: 10}, {name: base_pose, value: [0, 0, 0, 0, 0, 0]}, {name: trajectory_topic, value: /plan}]}\n";
    let c = LaunchConfig::parse(text, "fuzz").unwrap();
    let spec = c.of_kind(NodeKind::Robot).next().unwrap();
    let mut n = chronotope::node::robot::RobotNode::from_spec(spec).unwrap();
    let urdf = r#"<robot name="t"><link name="b"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link><link name="a"><collision><origin xyz="0.15 0 0"/><geometry><cylinder radius="0.03" length="0.3"/></geometry></collision></link><link name="f"/><joint name="j" type="revolute"><parent link="b"/><child link="a"/><axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint><joint name="k" type="prismatic"><parent link="a"/><child link="f"/><axis xyz="1 0 0"/><limit lower="0" upper="0.1"/><mimic joint="j"/></joint></robot>"#;
    let mut out = Vec::new();
    let text = Payload::Text(std::sync::Arc::new(RosString { data: urdf.into() }));
    n.on_message(&Message::new("/robot_description", 0, text), &mut out);
    n
}

fn hostile_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(-1e300),
        Just(0.5),
        Just(-3.0),
        any::<f64>(),
    ]
}

proptest! {
    #![proptest_config(config(64))]

    /// Joint states and plans with hostile names, lengths, values and stamps, and hostile
    /// URDF texts: the robot node never panics, stays within time, and says what was wrong
    /// in sentences.
    #[test]
    fn robot_node_survives_hostile_joint_states_plans_and_descriptions(
        names in prop::collection::vec(prop_oneof![Just("j".to_owned()), Just("k".to_owned()), Just("x".to_owned()), "[a-z]{0,3}"], 0..4),
        positions in prop::collection::vec(hostile_f64(), 0..4),
        velocities in prop::collection::vec(hostile_f64(), 0..3),
        stamps in prop::collection::vec(prop_oneof![Just(0i64), 0..2_000_000_000i64, any::<i64>()], 1..6),
        times in prop::collection::vec(hostile_f64(), 0..4),
        urdf_edit in 0..200usize,
    ) {
        use chronotope::msg::{Duration, Header, JointState, JointTrajectory, JointTrajectoryPoint, RosString, Time};
        use chronotope::node::{Message, Node};
        use std::sync::Arc;
        check("robot node", || {
            let mut n = robot_node();
            let mut out = Vec::new();
            for &s in &stamps {
                let m = JointState {
                    header: Header { stamp: Time::from_nanos(s), frame_id: String::new() },
                    name: names.clone(),
                    position: positions.clone(),
                    velocity: velocities.clone(),
                    effort: Vec::new(),
                };
                n.on_message(&Message::new("/joint_states", s, Payload::JointState(Arc::new(m))), &mut out);
            }
            let points = times
                .iter()
                .map(|&t| JointTrajectoryPoint {
                    positions: positions.clone(),
                    velocities: velocities.clone(),
                    time_from_start: Duration::from_nanos(if t.is_finite() { (t.clamp(-1e3, 1e3) * 1e9) as i64 } else { 0 }),
                    ..JointTrajectoryPoint::default()
                })
                .collect();
            let plan = JointTrajectory { header: Header::default(), joint_names: names.clone(), points };
            let bytes = chronotope::msg::encode_cdr(&plan).unwrap();
            let mut errors = decode_message(<JointTrajectory as RosMessage>::TYPE_NAME, &bytes);
            n.on_message(&Message::new("/plan", stamps[0], Payload::JointTrajectory(Arc::new(plan))), &mut out);
            n.on_tick(stamps[0].saturating_add(10_000_000_000), &mut out);
            // A description cut anywhere.
            let urdf = r#"<robot name="t"><link name="b"/><link name="c"/><joint name="j" type="revolute"><parent link="b"/><child link="c"/><limit lower="0" upper="1"/></joint></robot>"#;
            let cut = &urdf[..urdf_edit.min(urdf.len())];
            let text = Payload::Text(Arc::new(RosString { data: cut.into() }));
            n.on_message(&Message::new("/robot_description", 0, text), &mut out);
            n.finish(&mut out);
            errors.extend(n.status().messages.iter().cloned());
            errors
        })?;
    }
}
