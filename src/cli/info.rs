//! `chronotope info BAG [--json]`: what a bag holds, like `ros2 bag info`, and what the suite
//! sees in it: its bodies (VoxelGrid topics) with their grids, encodings, frame rates and gaps,
//! the topics it refuses and why, and any damage.
//!
//! One pass over the bag, with memory bounded per topic: a body's nominal frame period is the
//! median of its first [`PERIODS_FOR_MEDIAN`] periods, and gaps are counted against it.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::PathBuf;

use clap::Args;
use serde::Serialize;

use super::CliError;
use crate::bag::{BagLayout, BagReader, Compression, Recovery};
use crate::msg::{decode_cdr, RosMessage, VoxelEncoding, VoxelGrid};

/// Periods whose median is a body's nominal frame period.
pub const PERIODS_FOR_MEDIAN: usize = 1000;

/// A period longer than this many nominal periods is a gap.
pub const GAP_FACTOR: f64 = 1.5;

/// Most distinct values listed per body (grid sizes, resolutions, frame ids); further ones
/// are counted.
const MAX_DISTINCT: usize = 16;

/// Most bag errors listed; further ones are counted.
const MAX_ERRORS: usize = 100;

/// Options of `chronotope info`.
#[derive(Debug, Clone, Args)]
pub struct InfoArgs {
    /// The bag: a rosbag2 directory (or its metadata.yaml), or an MCAP or SQLite (.db3) file,
    /// zstd-compressed or not.
    pub bag: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// What `chronotope info` says about a bag.
#[derive(Debug, Clone, Serialize)]
pub struct BagInfo {
    /// The path given.
    pub path: PathBuf,
    /// `mcap`, `sqlite3`, or `rosbag2 directory`.
    pub kind: String,
    /// The storage (`mcap`, `sqlite3`).
    pub storage: String,
    /// How it is compressed, beyond MCAP's own chunk compression: `none`, `file`, `message`.
    pub compression: Compression,
    /// A directory's metadata version (`None` for a file, or a directory without metadata).
    pub metadata_version: Option<u64>,
    /// A directory's ROS distribution, if its metadata says.
    pub ros_distro: Option<String>,
    /// A directory's split files, in order, with their sizes (`None`: missing).
    pub files: Vec<FileInfo>,
    /// Log time of the first message, nanoseconds since the epoch.
    pub start_ns: Option<u64>,
    /// Log time of the last message.
    pub end_ns: Option<u64>,
    /// `end - start`, seconds.
    pub duration_s: f64,
    /// Messages read.
    pub messages: u64,
    /// Messages a directory's metadata lists (for comparison).
    pub metadata_messages: Option<u64>,
    /// Every topic read.
    pub topics: Vec<TopicInfo>,
    /// The VoxelGrid topics the suite reads as bodies.
    pub bodies: Vec<BodyInfo>,
    /// OctoMap and PointCloud2 topics: bodies once an occupancy node rasterises them.
    pub sensed_bodies: Vec<SensedInfo>,
    /// VoxelGrid topics the suite refuses, and why.
    pub refused: Vec<RefusedInfo>,
    /// Robots recorded the ROS way (description and joint states): bodies through a robot
    /// node.
    pub robots: Vec<super::info_robot::RobotInfo>,
    /// What reading the bag cost (damage, losses).
    pub recovery: Recovery,
    /// Problems met while reading, in order (at most 100 listed).
    pub errors: Vec<String>,
    /// Problems beyond those listed.
    pub errors_not_listed: u64,
    /// Oddities of a directory (no metadata, a newer version).
    pub warnings: Vec<String>,
}

/// A split file of a directory.
#[derive(Debug, Clone, Serialize)]
pub struct FileInfo {
    /// Its path.
    pub path: PathBuf,
    /// Its size in bytes, `None` if it is missing.
    pub bytes: Option<u64>,
}

/// One topic.
#[derive(Debug, Clone, Serialize)]
pub struct TopicInfo {
    /// The topic.
    pub topic: String,
    /// Its type, empty without a schema.
    #[serde(rename = "type")]
    pub type_name: String,
    /// Its message encoding (`cdr`).
    pub encoding: String,
    /// Messages.
    pub messages: u64,
    /// Bytes of message data.
    pub bytes: u64,
    /// Mean rate from log times, Hz (`None` below two messages).
    pub rate_hz: Option<f64>,
}

/// One body: a VoxelGrid topic read as frames.
#[derive(Debug, Clone, Serialize)]
pub struct BodyInfo {
    /// The topic (the body's id).
    pub topic: String,
    /// Frames that decode.
    pub frames: u64,
    /// Messages that do not decode.
    pub undecodable: u64,
    /// Distinct grid sizes `[x, y, z]` seen, in order of appearance.
    pub sizes: Vec<[u32; 3]>,
    /// Distinct voxel edges (m) seen.
    pub resolutions: Vec<f64>,
    /// Frames per encoding (`bits`, `percent`, or the unknown code).
    pub encodings: BTreeMap<String, u64>,
    /// Distinct `header.frame_id`s seen.
    pub frame_ids: Vec<String>,
    /// First frame stamp, seconds since the epoch.
    pub first_stamp_s: Option<f64>,
    /// Last frame stamp.
    pub last_stamp_s: Option<f64>,
    /// Nominal frame period (median of the first periods), seconds.
    pub period_s: Option<f64>,
    /// `1 / period_s`.
    pub rate_hz: Option<f64>,
    /// Periods longer than 1.5 nominal periods.
    pub gaps: u64,
    /// The longest period, seconds, and the stamp it ends at.
    pub longest_gap: Option<(f64, f64)>,
    /// Frames whose stamp is not after the previous one's.
    pub out_of_order: u64,
    /// Frame periods in which a part of the body vanishes between frames (it moves farther
    /// than its own thickness): no pair with this body can be called clear there.
    pub vanishing_periods: u64,
    /// The first of them: start and end (s since the epoch), and what would resolve it.
    pub vanishing_spans: Vec<VanishingSpan>,
    /// Frame periods in which the body moves more than two voxels: a pair with it is unsure
    /// where the other body is near it then.
    pub fast_periods: u64,
    /// The farthest it moves in one frame period (voxels, at most 64).
    pub max_displacement_voxels: u16,
}

/// A span of frame periods in which a part of a body vanishes between frames.
#[derive(Debug, Clone, Serialize)]
pub struct VanishingSpan {
    /// Start and end, seconds since the epoch.
    pub span_s: [f64; 2],
    /// What would resolve it.
    pub resolve: String,
}

/// Voxels of a frame above which `info` does not look for vanishing parts (the frames are
/// decoded for it; a larger body is left to `check`).
const VANISH_MAX_VOXELS: u64 = 1 << 24;

/// An OctoMap or PointCloud2 topic: a body once an occupancy node rasterises it.
#[derive(Debug, Clone, Serialize)]
pub struct SensedInfo {
    /// The topic.
    pub topic: String,
    /// `octomap_msgs/msg/Octomap` or `sensor_msgs/msg/PointCloud2`.
    #[serde(rename = "type")]
    pub type_name: String,
    /// Messages that decode.
    pub messages: u64,
    /// Messages that do not decode.
    pub undecodable: u64,
    /// Distinct layouts seen: for a cloud `height x width, fields, point_step, byte order`;
    /// for an octree `id, binary or full, resolution`.
    pub layouts: Vec<String>,
    /// Distinct `header.frame_id`s seen.
    pub frame_ids: Vec<String>,
    /// First and last stamp, seconds since the epoch.
    pub stamps_s: Option<[f64; 2]>,
    /// Mean rate from the stamps, Hz (`None` below two messages).
    pub rate_hz: Option<f64>,
    /// Points in all (clouds), and those with a NaN or infinite coordinate.
    pub points: u64,
    /// Points with a NaN or infinite x, y or z (clouds whose layout reads).
    pub points_nonfinite: u64,
    /// How it becomes occupancy, in words.
    pub becomes: String,
}

#[derive(Default)]
struct SensedAcc {
    type_name: String,
    messages: u64,
    undecodable: u64,
    layouts: Vec<String>,
    frame_ids: Vec<String>,
    first: Option<i64>,
    last: Option<i64>,
    points: u64,
    nonfinite: u64,
}

impl SensedAcc {
    fn stamp(&mut self, h: &crate::msg::Header) {
        let t = h.stamp.as_nanos();
        self.first = Some(self.first.map_or(t, |f| f.min(t)));
        self.last = Some(self.last.map_or(t, |l| l.max(t)));
        push_distinct(&mut self.frame_ids, h.frame_id.clone());
        self.messages += 1;
    }

    fn cloud(&mut self, c: &crate::msg::PointCloud2) {
        self.stamp(&c.header);
        let fields: Vec<String> = c
            .fields
            .iter()
            .take(8)
            .map(|f| format!("{}@{}", f.name, f.offset))
            .collect();
        push_distinct(
            &mut self.layouts,
            format!(
                "{}x{} points, fields {}, point_step {}, {}",
                c.height,
                c.width,
                fields.join(" "),
                c.point_step,
                if c.is_bigendian {
                    "big-endian"
                } else {
                    "little-endian"
                }
            ),
        );
        self.points += u64::from(c.height) * u64::from(c.width);
        // NaN points, counted as the occupancy node counts them (on a one-voxel lattice).
        let fields: Vec<chronotope_occupancy::PointField<'_>> = c
            .fields
            .iter()
            .map(|f| chronotope_occupancy::PointField {
                name: &f.name,
                offset: f.offset,
                datatype: f.datatype,
                count: f.count,
            })
            .collect();
        let cloud = chronotope_occupancy::PointCloud2Ref {
            height: c.height,
            width: c.width,
            fields: &fields,
            is_bigendian: c.is_bigendian,
            point_step: c.point_step,
            row_step: c.row_step,
            data: &c.data,
            is_dense: c.is_dense,
        };
        let Ok(lattice) = chronotope_occupancy::Lattice::new([0.0; 3], 1.0, [1, 1, 1]) else {
            return;
        };
        let mut raster =
            chronotope_occupancy::CloudRasterizer::new(chronotope_occupancy::CloudOptions::new());
        let mut frame = chronotope_occupancy::VoxelFrame::new();
        if let Ok(st) = raster.rasterize(
            &cloud,
            &lattice,
            chronotope_occupancy::Encoding::Bits,
            &mut frame,
        ) {
            self.nonfinite += st.nonfinite;
        }
    }

    fn octomap(&mut self, m: &crate::msg::Octomap) {
        self.stamp(&m.header);
        push_distinct(
            &mut self.layouts,
            format!(
                "{} {}, resolution {} m",
                m.id,
                if m.binary { "binary" } else { "full" },
                m.resolution
            ),
        );
    }
}

/// What an occupancy node does with a sensor topic, in words.
fn becomes(
    type_name: &str,
    topic: &str,
    frame_ids: &[String],
    first_body: Option<&String>,
) -> String {
    let node = format!("an occupancy node (exec: occupancy, input_topic: {topic})");
    let mut s = if type_name == crate::msg::Octomap::TYPE_NAME {
        format!(
            "{node} fills every voxel an occupied leaf overlaps (occupied at OctoMap's 0.5, or \
             occupancy_threshold); space no leaf covers is unknown: free with encoding bits \
             (occupied with unknown_occupied), 255 with encoding percent"
        )
    } else {
        format!(
            "{node} marks the voxel of each finite point: what the sensor sees of a surface, a \
             shell, not a solid (fill: columns makes solids; docs/sensors.md)"
        )
    };
    if frame_ids.iter().any(|f| !f.is_empty() && f != "world") {
        s.push_str(&format!(
            "; frame {}: placed in the lattice's frame by /tf_static or `transform`",
            frame_ids.join(", ")
        ));
    }
    match first_body {
        Some(b) => s.push_str(&format!(
            "; replayed without --launch, on the lattice and frame times of {b}"
        )),
        None => s.push_str("; give it a lattice (origin, resolution, size) in a launch config"),
    }
    s
}

/// A topic refused.
#[derive(Debug, Clone, Serialize)]
pub struct RefusedInfo {
    /// The topic.
    pub topic: String,
    /// Why.
    pub reason: String,
    /// Its messages.
    pub messages: u64,
}

/// What a channel's messages are to the suite, decided at its first message (its schema
/// text compared once).
enum ChannelVerdict {
    /// Not a VoxelGrid channel.
    Other,
    /// VoxelGrid frames the suite reads.
    Frames,
    /// A VoxelGrid channel refused, and why.
    Refused(String),
}

#[derive(Default)]
struct TopicAcc {
    type_name: String,
    encoding: String,
    messages: u64,
    bytes: u64,
    first: Option<u64>,
    last: Option<u64>,
}

#[derive(Default)]
struct BodyAcc {
    frames: u64,
    undecodable: u64,
    sizes: Vec<[u32; 3]>,
    resolutions: Vec<f64>,
    encodings: BTreeMap<String, u64>,
    frame_ids: Vec<String>,
    first: Option<i64>,
    prev: Option<i64>,
    /// The first periods (ns), until the median is taken.
    early: Vec<i64>,
    median: Option<i64>,
    gaps: u64,
    longest: Option<(i64, i64)>,
    out_of_order: u64,
    /// The previous frame decoded (to find parts that vanish), with its stamp and lattice.
    last_grid: Option<(i64, [u32; 3], f64, [f64; 3], crate::mesh::OccupancyGrid)>,
    vanishing: crate::mesh::unsure::UnsureLog,
    vanishing_periods: u64,
    fast_periods: u64,
    max_displacement: u16,
}

impl BodyAcc {
    /// Looks for a part of the body that vanishes between the previous frame and `g` (same
    /// lattice, increasing stamps), as the mesher does.
    fn vanishing(&mut self, g: &VoxelGrid, t: i64) {
        let size = [g.size_x, g.size_y, g.size_z];
        let origin = [g.origin.x, g.origin.y, g.origin.z];
        let voxels = size.iter().map(|&n| u64::from(n)).product::<u64>();
        if voxels > VANISH_MAX_VOXELS {
            self.last_grid = None;
            return;
        }
        let Ok(grid) = crate::mesh::OccupancyGrid::decode(
            &g.frame_ref(),
            &crate::mesh::DecodeOptions::default(),
        ) else {
            self.last_grid = None;
            return;
        };
        if let Some((t0, s0, r0, o0, prev)) = &self.last_grid {
            if *s0 == size && *r0 == g.resolution && *o0 == origin && t > *t0 {
                let motion = crate::mesh::vanish::motion(prev, &grid);
                self.max_displacement = self.max_displacement.max(motion.displacement);
                if motion.displacement > crate::mesh::unsure::FAST_VOXELS {
                    self.fast_periods += 1;
                }
                if let Some(v) = motion.vanishing {
                    self.vanishing_periods += 1;
                    self.vanishing.push(crate::mesh::unsure::UnsureSpan {
                        from_ns: *t0,
                        to_ns: t,
                        why: crate::mesh::unsure::Unsure::Vanishes {
                            rate_factor: v.rate_factor,
                        },
                        period_ns: t - t0,
                    });
                }
            }
        }
        self.last_grid = Some((t, size, g.resolution, origin, grid));
    }

    fn frame(&mut self, g: &VoxelGrid) {
        self.frames += 1;
        push_distinct(&mut self.sizes, [g.size_x, g.size_y, g.size_z]);
        push_distinct(&mut self.resolutions, g.resolution);
        push_distinct(&mut self.frame_ids, g.header.frame_id.clone());
        let enc = match VoxelEncoding::from_code(g.encoding) {
            Some(VoxelEncoding::Bits) => "bits".to_owned(),
            Some(VoxelEncoding::Percent) => "percent".to_owned(),
            None => format!("unknown code {}", g.encoding),
        };
        *self.encodings.entry(enc).or_default() += 1;
        let t = i64::from(g.header.stamp.sec) * 1_000_000_000 + i64::from(g.header.stamp.nanosec);
        self.vanishing(g, t);
        self.first.get_or_insert(t);
        if let Some(p) = self.prev {
            let d = t - p;
            if d <= 0 {
                self.out_of_order += 1;
            } else {
                if self.longest.is_none_or(|(l, _)| d > l) {
                    self.longest = Some((d, t));
                }
                match self.median {
                    Some(m) => self.gaps += u64::from(d as f64 > GAP_FACTOR * m as f64),
                    None => {
                        self.early.push(d);
                        if self.early.len() >= PERIODS_FOR_MEDIAN {
                            self.take_median();
                        }
                    }
                }
            }
        }
        if self.prev.is_none_or(|p| t > p) {
            self.prev = Some(t);
        }
    }

    fn take_median(&mut self) {
        if self.median.is_some() || self.early.is_empty() {
            return;
        }
        let mut v = std::mem::take(&mut self.early);
        v.sort_unstable();
        let m = v[v.len() / 2];
        self.median = Some(m);
        self.gaps += v
            .iter()
            .filter(|&&d| d as f64 > GAP_FACTOR * m as f64)
            .count() as u64;
    }
}

fn push_distinct<T: PartialEq>(v: &mut Vec<T>, x: T) {
    if v.len() < MAX_DISTINCT && !v.contains(&x) {
        v.push(x);
    }
}

/// Reads the whole bag and says what it holds.
///
/// # Errors
/// The bag cannot be opened.
pub fn bag_info(path: &std::path::Path) -> Result<BagInfo, CliError> {
    let mut reader = BagReader::open(path)?;
    let mut info = BagInfo {
        path: path.to_path_buf(),
        kind: String::new(),
        storage: String::new(),
        compression: Compression::None,
        metadata_version: None,
        ros_distro: None,
        files: Vec::new(),
        start_ns: None,
        end_ns: None,
        duration_s: 0.0,
        messages: 0,
        metadata_messages: None,
        topics: Vec::new(),
        bodies: Vec::new(),
        sensed_bodies: Vec::new(),
        refused: Vec::new(),
        robots: Vec::new(),
        recovery: Recovery::default(),
        errors: Vec::new(),
        errors_not_listed: 0,
        warnings: Vec::new(),
    };
    match reader.layout() {
        BagLayout::File {
            storage,
            compressed,
        } => {
            info.kind = (*storage).to_owned();
            info.storage = (*storage).to_owned();
            if *compressed {
                info.compression = Compression::File;
            }
        }
        BagLayout::Directory(d) => {
            info.kind = "rosbag2 directory".to_owned();
            info.storage = d.storage.clone();
            info.compression = d.compression;
            info.metadata_version = d.version;
            info.ros_distro = d.ros_distro.clone();
            info.metadata_messages = d.message_count;
            info.warnings = d.warnings.clone();
            info.files = d
                .files
                .iter()
                .map(|f| FileInfo {
                    path: f.clone(),
                    bytes: std::fs::metadata(f).ok().map(|m| m.len()),
                })
                .collect();
        }
    }
    let mut topics: BTreeMap<String, TopicAcc> = BTreeMap::new();
    let mut bodies: BTreeMap<String, BodyAcc> = BTreeMap::new();
    let mut refused: BTreeMap<String, RefusedInfo> = BTreeMap::new();
    let mut sensed: BTreeMap<String, SensedAcc> = BTreeMap::new();
    let mut verdicts: HashMap<u16, ChannelVerdict> = HashMap::new();
    let mut robots = super::info_robot::RobotAcc::default();
    let note = |info: &mut BagInfo, e: String| {
        if info.errors.len() < MAX_ERRORS {
            info.errors.push(e);
        } else {
            info.errors_not_listed += 1;
        }
    };
    for item in reader.by_ref() {
        let m = match item {
            Ok(m) => m,
            Err(e) => {
                let fatal = e.is_fatal();
                note(&mut info, e.to_string());
                if fatal {
                    break;
                }
                continue;
            }
        };
        info.messages += 1;
        let t = m.log_time_ns;
        info.start_ns = Some(info.start_ns.map_or(t, |s| s.min(t)));
        info.end_ns = Some(info.end_ns.map_or(t, |e| e.max(t)));
        let acc = topics.entry(m.topic.clone()).or_default();
        if acc.messages == 0 {
            acc.type_name = m.schema_name.clone();
            acc.encoding = m.message_encoding.clone();
        }
        acc.messages += 1;
        acc.bytes += m.data.len() as u64;
        acc.first = Some(acc.first.map_or(t, |f| f.min(t)));
        acc.last = Some(acc.last.map_or(t, |l| l.max(t)));
        robots.message(&m.topic, &m.schema_name, &m.data);
        if m.schema_name == crate::msg::Octomap::TYPE_NAME
            || m.schema_name == crate::msg::PointCloud2::TYPE_NAME
        {
            let acc = sensed.entry(m.topic.clone()).or_default();
            acc.type_name = m.schema_name.clone();
            let ok = if m.schema_name == crate::msg::Octomap::TYPE_NAME {
                decode_cdr::<crate::msg::Octomap>(&m.data).map(|o| acc.octomap(&o))
            } else {
                decode_cdr::<crate::msg::PointCloud2>(&m.data).map(|c| acc.cloud(&c))
            };
            if ok.is_err() {
                acc.undecodable += 1;
            }
        }
        let verdict = verdicts.entry(m.channel_id).or_insert_with(|| {
            if m.schema_name != VoxelGrid::TYPE_NAME {
                return ChannelVerdict::Other;
            }
            match crate::bag::voxel_channel_refusal(m.schema.as_deref(), &m.message_encoding) {
                Some(reason) => ChannelVerdict::Refused(reason),
                None => ChannelVerdict::Frames,
            }
        });
        match verdict {
            ChannelVerdict::Other => {}
            ChannelVerdict::Refused(reason) => {
                refused
                    .entry(m.topic.clone())
                    .or_insert_with(|| RefusedInfo {
                        topic: m.topic.clone(),
                        reason: reason.clone(),
                        messages: 0,
                    })
                    .messages += 1;
            }
            ChannelVerdict::Frames => {
                let body = bodies.entry(m.topic.clone()).or_default();
                match decode_cdr::<VoxelGrid>(&m.data) {
                    Ok(g) => body.frame(&g),
                    Err(_) => body.undecodable += 1,
                }
            }
        }
    }
    info.recovery = reader.recovery().clone();
    if let (Some(a), Some(b)) = (info.start_ns, info.end_ns) {
        info.duration_s = (b - a) as f64 * 1e-9;
    }
    info.topics = topics
        .into_iter()
        .map(|(topic, a)| TopicInfo {
            topic,
            type_name: a.type_name,
            encoding: a.encoding,
            messages: a.messages,
            bytes: a.bytes,
            rate_hz: match (a.first, a.last) {
                (Some(f), Some(l)) if a.messages > 1 && l > f => {
                    Some((a.messages - 1) as f64 / ((l - f) as f64 * 1e-9))
                }
                _ => None,
            },
        })
        .collect();
    info.bodies = bodies
        .into_iter()
        .map(|(topic, mut b)| {
            b.take_median();
            let s = |ns: i64| ns as f64 * 1e-9;
            BodyInfo {
                topic,
                frames: b.frames,
                undecodable: b.undecodable,
                sizes: b.sizes,
                resolutions: b.resolutions,
                encodings: b.encodings,
                frame_ids: b.frame_ids,
                first_stamp_s: b.first.map(s),
                last_stamp_s: b.prev.map(s),
                period_s: b.median.map(s),
                rate_hz: b.median.filter(|&m| m > 0).map(|m| 1.0 / s(m)),
                gaps: b.gaps,
                longest_gap: b.longest.map(|(d, at)| (s(d), s(at))),
                out_of_order: b.out_of_order,
                vanishing_periods: b.vanishing_periods,
                vanishing_spans: b
                    .vanishing
                    .spans()
                    .take(5)
                    .map(|v| VanishingSpan {
                        span_s: [s(v.from_ns), s(v.to_ns)],
                        resolve: v.why.remedy(s(v.period_ns)),
                    })
                    .collect(),
                fast_periods: b.fast_periods,
                max_displacement_voxels: b.max_displacement,
            }
        })
        .collect();
    info.refused = refused.into_values().collect();
    info.robots = robots.finish();
    let first_body = info.bodies.iter().map(|b| &b.topic).min().cloned();
    info.sensed_bodies = sensed
        .into_iter()
        .map(|(topic, a)| {
            let s = |ns: i64| ns as f64 * 1e-9;
            SensedInfo {
                becomes: becomes(&a.type_name, &topic, &a.frame_ids, first_body.as_ref()),
                topic,
                type_name: a.type_name,
                messages: a.messages,
                undecodable: a.undecodable,
                layouts: a.layouts,
                frame_ids: a.frame_ids,
                stamps_s: a.first.zip(a.last).map(|(f, l)| [s(f), s(l)]),
                rate_hz: match (a.first, a.last) {
                    (Some(f), Some(l)) if a.messages > 1 && l > f => {
                        Some((a.messages - 1) as f64 / s(l - f))
                    }
                    _ => None,
                },
                points: a.points,
                points_nonfinite: a.nonfinite,
            }
        })
        .collect();
    Ok(info)
}

/// `chronotope info`.
///
/// # Errors
/// The bag cannot be opened, or the output cannot be written.
pub fn run(a: &InfoArgs) -> Result<(), CliError> {
    let info = bag_info(&a.bag)?;
    if a.json {
        let text = serde_json::to_string_pretty(&info)
            .map_err(|e| CliError::Usage(format!("cannot write JSON: {e}")))?;
        println!("{text}");
    } else {
        print!("{}", text(&info));
    }
    Ok(())
}

/// The human-readable form.
pub fn text(i: &BagInfo) -> String {
    let mut o = String::new();
    let mut line = |k: &str, v: String| o.push_str(&format!("{k:<14}{v}\n"));
    let mut kind = i.kind.clone();
    if i.kind == "rosbag2 directory" {
        kind.push_str(&format!(
            ", {} storage, {} split file(s)",
            i.storage,
            i.files.len()
        ));
        if let Some(v) = i.metadata_version {
            kind.push_str(&format!(", metadata version {v}"));
        }
        if let Some(d) = &i.ros_distro {
            kind.push_str(&format!(", written by {d}"));
        }
    }
    match i.compression {
        Compression::None => {}
        Compression::File => kind.push_str(", zstd per file"),
        Compression::Message => kind.push_str(", zstd per message"),
    }
    line("Bag:", format!("{} ({kind})", i.path.display()));
    for f in &i.files {
        let size = match f.bytes {
            Some(b) => human_bytes(b),
            None => "MISSING".to_owned(),
        };
        line("  file:", format!("{} ({size})", f.path.display()));
    }
    for w in &i.warnings {
        line("Warning:", w.clone());
    }
    line("Duration:", format!("{:.3} s", i.duration_s));
    if let (Some(a), Some(b)) = (i.start_ns, i.end_ns) {
        line("Start:", format!("{} ({:.9} s)", utc(a), a as f64 * 1e-9));
        line("End:", format!("{} ({:.9} s)", utc(b), b as f64 * 1e-9));
    }
    let mut count = i.messages.to_string();
    if let Some(m) = i.metadata_messages.filter(|&m| m != i.messages) {
        count.push_str(&format!(" (metadata.yaml says {m})"));
    }
    line("Messages:", count);
    o.push_str("Topics:\n");
    let w = i.topics.iter().map(|t| t.topic.len()).max().unwrap_or(0);
    let tw = i
        .topics
        .iter()
        .map(|t| t.type_name.len())
        .max()
        .unwrap_or(0);
    for t in &i.topics {
        let rate = t
            .rate_hz
            .map(|r| format!("{r:.2} Hz"))
            .unwrap_or_else(|| "-".to_owned());
        o.push_str(&format!(
            "  {:<w$}  {:<tw$}  {:>4}  {:>8} msgs  {:>10}  {:>10}\n",
            t.topic,
            if t.type_name.is_empty() {
                "(no schema)"
            } else {
                &t.type_name
            },
            t.encoding,
            t.messages,
            rate,
            human_bytes(t.bytes),
        ));
    }
    o.push_str(&super::info_robot::text(&i.robots));
    o.push_str(&format!(
        "Bodies (VoxelGrid topics the suite reads): {}\n",
        i.bodies.len()
    ));
    for b in &i.bodies {
        let sizes: Vec<String> = b
            .sizes
            .iter()
            .map(|s| format!("{}x{}x{}", s[0], s[1], s[2]))
            .collect();
        let res: Vec<String> = b.resolutions.iter().map(|r| format!("{r} m")).collect();
        let enc: Vec<String> = b
            .encodings
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        o.push_str(&format!("  {}\n", b.topic));
        o.push_str(&format!(
            "    frames {} ({} undecodable); grid {} at {}; encoding {}; frame_id {}\n",
            b.frames,
            b.undecodable,
            sizes.join(", "),
            res.join(", "),
            enc.join(", "),
            b.frame_ids
                .iter()
                .map(|f| format!("{f:?}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        if let (Some(a), Some(z)) = (b.first_stamp_s, b.last_stamp_s) {
            let mut timing = format!("    stamps {a:.3}-{z:.3} s");
            if let (Some(p), Some(r)) = (b.period_s, b.rate_hz) {
                timing.push_str(&format!("; {r:.2} Hz (period {:.1} ms)", p * 1e3));
            }
            timing.push_str(&format!("; gaps over {GAP_FACTOR} periods: {}", b.gaps));
            if let (Some((d, at)), true) = (b.longest_gap, b.gaps > 0) {
                timing.push_str(&format!(
                    " (longest {:.1} ms, ending at {at:.3} s)",
                    d * 1e3
                ));
            }
            if b.out_of_order > 0 {
                timing.push_str(&format!("; {} stamps not increasing", b.out_of_order));
            }
            o.push_str(&timing);
            o.push('\n');
        }
        if b.vanishing_periods > 0 || b.gaps > 0 {
            let mut why = Vec::new();
            if b.vanishing_periods > 0 {
                let spans: Vec<String> = b
                    .vanishing_spans
                    .iter()
                    .map(|v| format!("{:.3}-{:.3} s", v.span_s[0], v.span_s[1]))
                    .collect();
                why.push(format!(
                    "a part of it vanishes between frames in {} period(s) ({}{}; resolve: {})",
                    b.vanishing_periods,
                    spans.join(", "),
                    if b.vanishing_periods as usize > spans.len() {
                        ", …"
                    } else {
                        ""
                    },
                    b.vanishing_spans.first().map_or("", |v| v.resolve.as_str())
                ));
            }
            if b.gaps > 0 {
                why.push(format!("{} gap(s) of missing frames", b.gaps));
            }
            o.push_str(&format!(
                "    unsure: {}: no pair with this body can be called clear there\n",
                why.join("; ")
            ));
        }
        if b.fast_periods > 0 {
            o.push_str(&format!(
                "    moves more than two voxels a frame in {} period(s), up to {} voxels: a pair \
                 with it is unsure where the other body comes that near\n",
                b.fast_periods, b.max_displacement_voxels
            ));
        }
    }
    o.push_str(&format!(
        "Sensed bodies (OctoMap and PointCloud2 topics an occupancy node turns into bodies): {}\n",
        i.sensed_bodies.len()
    ));
    for b in &i.sensed_bodies {
        o.push_str(&format!("  {} ({})\n", b.topic, b.type_name));
        let mut line = format!(
            "    messages {} ({} undecodable); {}",
            b.messages,
            b.undecodable,
            b.layouts.join("; ")
        );
        if b.points > 0 {
            line.push_str(&format!(
                "; {} points, {} not finite",
                b.points, b.points_nonfinite
            ));
        }
        line.push_str(&format!(
            "; frame_id {}",
            b.frame_ids
                .iter()
                .map(|f| format!("{f:?}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        o.push_str(&line);
        o.push('\n');
        if let Some([a, z]) = b.stamps_s {
            let rate = b
                .rate_hz
                .map(|r| format!("; {r:.2} Hz"))
                .unwrap_or_default();
            o.push_str(&format!("    stamps {a:.3}-{z:.3} s{rate}\n"));
        }
        o.push_str(&format!("    becomes occupancy: {}\n", b.becomes));
    }
    if !i.refused.is_empty() {
        o.push_str("Refused topics:\n");
        for r in &i.refused {
            o.push_str(&format!(
                "  {} ({} messages): {}\n",
                r.topic, r.messages, r.reason
            ));
        }
    }
    match i.recovery.integrity {
        crate::bag::Integrity::Verified => o.push_str(
            "Integrity:    verified (every message read lay under a checksum that held)\n",
        ),
        crate::bag::Integrity::Unverified => {
            o.push_str(
                "Integrity:    not verifiable for every message (damage there would go unseen):\n",
            );
            for u in i.recovery.unverified.iter().take(5) {
                o.push_str(&format!(
                    "  {}: {} messages: {}\n",
                    u.file, u.messages, u.reason
                ));
            }
            if i.recovery.unverified.len() > 5 {
                o.push_str(&format!(
                    "  and {} more files\n",
                    i.recovery.unverified.len() - 5
                ));
            }
        }
    }
    if i.recovery.is_clean() && i.errors.is_empty() {
        o.push_str("Damage:       none\n");
    } else {
        o.push_str(&format!(
            "Damage:       {} messages lost, {} damaged regions of unknown loss\n",
            i.recovery.messages_lost, i.recovery.regions_with_unknown_loss
        ));
        let listed: BTreeSet<&String> = i.errors.iter().collect();
        for e in listed.iter().take(20) {
            o.push_str(&format!("  {e}\n"));
        }
        let more = listed.len().saturating_sub(20) as u64 + i.errors_not_listed;
        if more > 0 {
            o.push_str(&format!("  and {more} more\n"));
        }
    }
    o
}

fn human_bytes(b: u64) -> String {
    let b = b as f64;
    if b >= 1e9 {
        format!("{:.2} GB", b / 1e9)
    } else if b >= 1e6 {
        format!("{:.2} MB", b / 1e6)
    } else if b >= 1e3 {
        format!("{:.1} kB", b / 1e3)
    } else {
        format!("{b} B")
    }
}

/// `ns` since the epoch as an ISO 8601 UTC date and time (to the millisecond).
fn utc(ns: u64) -> String {
    let secs = (ns / 1_000_000_000) as i64;
    let ms = (ns / 1_000_000) % 1000;
    let days = secs.div_euclid(86_400);
    let rem = secs.rem_euclid(86_400);
    // Civil date from days since 1970-01-01 (proleptic Gregorian).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{ms:03}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_dates() {
        assert_eq!(utc(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(utc(951_782_400_000_000_000), "2000-02-29T00:00:00.000Z");
        assert_eq!(utc(1_700_000_000_123_000_000), "2023-11-14T22:13:20.123Z");
    }

    #[test]
    fn gaps_are_counted_against_the_median_period() {
        let mut b = BodyAcc::default();
        let mut g = VoxelGrid::default();
        for k in [0i32, 1, 2, 3, 6, 7, 8] {
            g.header.stamp.sec = k;
            b.frame(&g);
        }
        b.take_median();
        assert_eq!(b.median, Some(1_000_000_000));
        assert_eq!(b.gaps, 1);
        assert_eq!(b.longest, Some((3_000_000_000, 6_000_000_000)));
    }
}
