//! The occupancy node: a sensor's or a mapper's occupancy in (`input_topic`:
//! `octomap_msgs/Octomap` as octomap_server publishes it, or `sensor_msgs/PointCloud2` as
//! depth cameras, lidars, octomap_server's voxel centres, nvblox and voxblox publish it),
//! VoxelGrid frames out on `~/occupancy`, on a given lattice, so the mesher and the checker
//! see the sensed thing as a body.
//!
//! The rasterising is `chronotope_occupancy`'s (its README has the rules); this node adds what
//! a cell needs around it:
//!
//! - **The lattice**: `origin`, `resolution`, `size`, or `lattice_from` another body's
//!   VoxelGrid topic (its first frame's origin, resolution, size and frame), so the checker
//!   can compare the two.
//! - **The frame**: a cloud in another frame than the lattice's is placed by the `transform`
//!   parameter or by `/tf_static` (chains of static transforms are composed); an octree, which
//!   is axis-aligned, only by a translation.
//! - **The time lattice**: by default each input message gives one frame at its own stamp.
//!   With `stamps_from` (a body's VoxelGrid topic), a frame is published at each of that
//!   body's frame times instead: the latest input whose stamp is not after it, held for at
//!   most `hold_s`. The checker needs every body's frames on one time lattice
//!   (docs/checker.md), and a sensor rarely runs in phase with the cell.
//!
//! Bad input (a truncated octree, an unknown tree id, fields that do not cover a point, a
//! cloud over the limits, a cloud with no known transform) is refused by name: counted, logged,
//! nothing published for it, the node goes on. NaN points and points outside the lattice are
//! counted (`points_nonfinite`, `points_outside` in the status' counts), never allocated for.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

use chronotope_occupancy::{
    Axis as LatticeAxis, CloudError, CloudOptions, CloudRasterizer, Encoding, Fill, Lattice,
    LatticeError, OctomapError, OctomapMsg, OctomapOptions, OctomapRasterizer, PointCloud2Ref,
    PointField as CloudField, RigidTransform, Toward, TransformError, VoxelFrame,
};

use super::launch::{LaunchError, NodeSpec, ParamValue, Params};
use super::{Message, Node, NodeStatus, ParamError, Payload, TopicRef};
use chronotope_msg::{Header, Octomap, Point, PointCloud2, RosMessage, TFMessage, Time, VoxelGrid};

/// Source frames kept waiting for their first cell frame time (with `stamps_from`); an older
/// one is dropped when a fifth comes (counted as `superseded`).
pub const MAX_WAITING_FRAMES: usize = 4;

/// Frames of `/tf_static` kept; transforms for further frames are refused and counted.
pub const MAX_TF_FRAMES: usize = 1024;

/// Longest chain of static transforms followed from a frame to its root.
pub const MAX_TF_DEPTH: usize = 64;

/// What the node reads on `input_topic`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// `octomap_msgs/msg/Octomap`.
    Octomap,
    /// `sensor_msgs/msg/PointCloud2`.
    Cloud,
}

impl InputKind {
    /// The kind a ROS type names (`pkg/msg/Type` or `pkg/Type`), if it is one the node reads.
    pub fn of_type(type_name: &str) -> Option<Self> {
        match type_name.replace("/msg/", "/").as_str() {
            "octomap_msgs/Octomap" => Some(Self::Octomap),
            "sensor_msgs/PointCloud2" => Some(Self::Cloud),
            _ => None,
        }
    }

    /// The ROS type, `pkg/msg/Type`.
    pub fn type_name(self) -> &'static str {
        match self {
            Self::Octomap => Octomap::TYPE_NAME,
            Self::Cloud => PointCloud2::TYPE_NAME,
        }
    }
}

/// The lattice frames are written on, with its frame.
#[derive(Debug, Clone, PartialEq)]
struct CellLattice {
    lattice: Lattice,
    frame_id: String,
}

/// A frame ready to publish, with the stamp of the input it came from.
#[derive(Debug, Clone)]
struct Held {
    stamp_ns: i64,
    grid: Arc<VoxelGrid>,
    /// Published at least once.
    published: bool,
}

/// How the input is rasterised.
enum Raster {
    Octomap(OctomapRasterizer),
    Cloud {
        raster: CloudRasterizer,
        /// A second rasteriser and frame for the second half of a large cloud.
        half: Box<(CloudRasterizer, VoxelFrame)>,
        /// The options without the transform (set per frame from `transform` or `/tf_static`).
        options: CloudOptions,
        /// The transform the rasterisers were built with.
        transform: Option<RigidTransform>,
        /// Large clouds may be split (no `min_points`).
        split: bool,
    },
}

/// A cloud with at least this many points is rasterised in two halves on rayon's pool (the
/// halves' frames OR-ed), when its options allow it: without `min_points` (a count per voxel
/// does not split). Marking, dilation and column fills distribute over a union, so the frame
/// is the one a single pass gives.
pub const SPLIT_POINTS: u64 = 1 << 18;

/// Rasterises `cloud`, in two halves on rayon's pool when it is large (see [`SPLIT_POINTS`]);
/// returns `VoxelGrid.data` and the statistics.
fn rasterise_cloud(
    split: bool,
    raster: &mut CloudRasterizer,
    half: &mut (CloudRasterizer, VoxelFrame),
    cloud: &PointCloud2Ref<'_>,
    lattice: &Lattice,
    encoding: Encoding,
    out: &mut VoxelFrame,
) -> Result<(Vec<u8>, chronotope_occupancy::CloudStats), CloudError> {
    let points = u64::from(cloud.width) * u64::from(cloud.height);
    let (ps, rs) = (cloud.point_step as usize, cloud.row_step as usize);
    let whole = cloud.height as usize * rs;
    // The halves refuse what the whole would, and nothing else, only when the sizes hold:
    // anything doubtful takes the single pass, which names the fault as always.
    let splittable = split
        && points >= SPLIT_POINTS
        && points <= chronotope_occupancy::Limits::default().max_points
        && rayon::current_num_threads() > 1
        && ps > 0
        && rs >= cloud.width as usize * ps
        && cloud.data.len() >= whole;
    if !splittable {
        let s = raster.rasterize(cloud, lattice, encoding, out)?;
        return Ok((out.data().to_vec(), s));
    }
    let (a, b) = if cloud.height >= 2 {
        let h1 = cloud.height / 2;
        let cut = h1 as usize * rs;
        (
            PointCloud2Ref {
                height: h1,
                data: &cloud.data[..cut],
                ..*cloud
            },
            PointCloud2Ref {
                height: cloud.height - h1,
                data: &cloud.data[cut..],
                ..*cloud
            },
        )
    } else {
        let w1 = cloud.width / 2;
        let cut = w1 as usize * ps;
        (
            PointCloud2Ref {
                width: w1,
                row_step: cut as u32,
                data: &cloud.data[..cut],
                ..*cloud
            },
            PointCloud2Ref {
                width: cloud.width - w1,
                row_step: (rs - cut) as u32,
                data: &cloud.data[cut..],
                ..*cloud
            },
        )
    };
    let (half_raster, half_out) = half;
    let (ra, rb) = rayon::join(
        || raster.rasterize(&a, lattice, encoding, out),
        || half_raster.rasterize(&b, lattice, encoding, half_out),
    );
    let (sa, sb) = (ra?, rb?);
    let mut data = out.data().to_vec();
    match encoding {
        Encoding::Bits => data
            .iter_mut()
            .zip(half_out.data())
            .for_each(|(x, y)| *x |= y),
        Encoding::Percent => data
            .iter_mut()
            .zip(half_out.data())
            .for_each(|(x, y)| *x = (*x).max(*y)),
    }
    let stats = chronotope_occupancy::CloudStats {
        points: sa.points + sb.points,
        nonfinite: sa.nonfinite + sb.nonfinite,
        outside: sa.outside + sb.outside,
        margin_points: sa.margin_points + sb.margin_points,
        trailing_bytes: sb.trailing_bytes,
        ..Default::default()
    };
    Ok((data, stats))
}

/// The fields of a PointCloud2 message as the library reads them.
fn cloud_fields(c: &PointCloud2) -> Vec<CloudField<'_>> {
    c.fields
        .iter()
        .map(|f| CloudField {
            name: &f.name,
            offset: f.offset,
            datatype: f.datatype,
            count: f.count,
        })
        .collect()
}

/// A PointCloud2 message as the library reads it, with its `fields` from [`cloud_fields`].
fn cloud_ref<'a>(c: &'a PointCloud2, fields: &'a [CloudField<'a>]) -> PointCloud2Ref<'a> {
    PointCloud2Ref {
        height: c.height,
        width: c.width,
        fields,
        is_bigendian: c.is_bigendian,
        point_step: c.point_step,
        row_step: c.row_step,
        data: &c.data,
        is_dense: c.is_dense,
    }
}

/// The occupancy node.
pub struct OccupancyNode {
    fqn: String,
    input_topic: String,
    kind: InputKind,
    output_topic: String,
    stamps_from: Option<String>,
    lattice_from: Option<String>,
    tf_topic: Option<String>,
    /// The lattice, once known (at launch, or from `lattice_from`'s first frame).
    lattice: Option<CellLattice>,
    /// `frame_id` as given (`None`: the lattice's body's frame, or the input's own).
    frame_id: Option<String>,
    encoding: Encoding,
    raster: Raster,
    /// `transform`: the input's frame in the lattice's frame, as given.
    transform: Option<RigidTransform>,
    tf: StaticTf,
    hold_ns: i64,
    out: VoxelFrame,
    /// The latest input waiting for the lattice (`lattice_from` not heard yet).
    waiting_lattice: Option<Message>,
    /// With `stamps_from`: the frame published at the cell's frame times, and those to come.
    current: Option<Held>,
    ahead: VecDeque<Held>,
    last_input_ns: Option<i64>,
    last_published_ns: Option<i64>,
    /// The held frame went stale (said once per stop).
    stale: bool,
    status: NodeStatus,
}

/// Reads a lattice axis name with a sign (`-z`, `+x`, `y`).
fn parse_toward(s: &str) -> Option<(LatticeAxis, Toward)> {
    let (toward, axis) = match s.as_bytes() {
        [b'-', a] => (Toward::Min, *a),
        [b'+', a] | [a] => (Toward::Max, *a),
        _ => return None,
    };
    let axis = match axis {
        b'x' => LatticeAxis::X,
        b'y' => LatticeAxis::Y,
        b'z' => LatticeAxis::Z,
        _ => return None,
    };
    Some((axis, toward))
}

impl OccupancyNode {
    /// The node a launch config describes.
    ///
    /// # Errors
    /// A bad, missing or contradictory parameter, naming it.
    pub fn from_spec(spec: &NodeSpec) -> Result<Self, LaunchError> {
        let mut p = Params::of(spec);
        let node = p.node().to_owned();
        let bad = |param: &str, reason: String| LaunchError::Param {
            node: node.clone(),
            param: param.to_owned(),
            reason,
        };
        let Some(input) = p.string("input_topic")? else {
            return Err(bad(
                "input_topic",
                "required: the octomap_msgs/Octomap or sensor_msgs/PointCloud2 topic to read"
                    .into(),
            ));
        };
        let input_topic = p.resolve("input_topic", &input)?;
        let kind = match p.string("input_type")? {
            Some(t) => InputKind::of_type(&t).ok_or_else(|| {
                bad(
                    "input_type",
                    format!(
                        "{}: octomap_msgs/msg/Octomap or sensor_msgs/msg/PointCloud2",
                        chronotope_yaml::quote(&t)
                    ),
                )
            })?,
            None => {
                return Err(bad(
                    "input_type",
                    "required live (a replay takes it from the bag): \
                     octomap_msgs/msg/Octomap or sensor_msgs/msg/PointCloud2"
                        .into(),
                ))
            }
        };
        let lattice_from = match p.string("lattice_from")? {
            Some(t) => Some(p.resolve("lattice_from", &t)?),
            None => None,
        };
        let stamps_from = match p.string("stamps_from")? {
            Some(t) => Some(p.resolve("stamps_from", &t)?),
            None => None,
        };
        let frame_id = p.string("frame_id")?;
        let given = ["origin", "resolution", "size"].map(|n| spec.params.contains_key(n));
        let origin = p.doubles("origin", [0.0; 3])?;
        let resolution = p.double("resolution", 0.05, 1e-6..=1e3)?;
        let size = p.doubles::<3>("size", [1.0; 3])?;
        if given[2]
            && size
                .iter()
                .any(|&n| n.fract() != 0.0 || !(1.0..=1048576.0).contains(&n))
        {
            return Err(bad(
                "size",
                "voxels along x, y and z: whole numbers in 1..=1048576".into(),
            ));
        }
        let lattice = match (&lattice_from, given) {
            (Some(_), [false, false, false]) => None,
            (Some(_), _) => {
                return Err(bad(
                    "lattice_from",
                    "give either lattice_from or origin, resolution and size, not both".into(),
                ))
            }
            (None, [true, true, true]) => {
                let size = size.map(|n| n as u32);
                let lattice = Lattice::new(origin, resolution, size)
                    .map_err(|e| bad("resolution", e.to_string()))?;
                let voxels = lattice.voxel_count();
                let limit = chronotope_occupancy::Limits::default().max_voxels;
                if voxels > limit {
                    return Err(bad(
                        "size",
                        format!("{voxels} voxels, more than the limit max_voxels = {limit}"),
                    ));
                }
                Some(CellLattice {
                    lattice,
                    frame_id: frame_id.clone().unwrap_or_default(),
                })
            }
            (None, _) => {
                let missing: Vec<&str> = ["origin", "resolution", "size"]
                    .into_iter()
                    .zip(given)
                    .filter(|(_, g)| !g)
                    .map(|(n, _)| n)
                    .collect();
                return Err(bad(
                    missing[0],
                    format!(
                        "the lattice needs origin [x, y, z], resolution and size [nx, ny, nz] \
                         (missing: {}), or lattice_from a body's VoxelGrid topic",
                        missing.join(", ")
                    ),
                ));
            }
        };
        let encoding = match p.string("encoding")?.as_deref() {
            None | Some("bits") => Encoding::Bits,
            Some("percent") => Encoding::Percent,
            Some(other) => {
                return Err(bad(
                    "encoding",
                    format!("{}: bits or percent", chronotope_yaml::quote(other)),
                ))
            }
        };
        let hold_s = p.double("hold_s", 1.0, 0.0..=3600.0)?;
        let transform = match spec.params.contains_key("transform") {
            false => None,
            true => Some(p.doubles::<7>("transform", [0.0; 7])?),
        };
        let transform = match transform {
            None => None,
            Some([x, y, z, qx, qy, qz, qw]) => Some(
                RigidTransform::from_quaternion([qx, qy, qz, qw], [x, y, z])
                    .map_err(|e| bad("transform", format!("[x, y, z, qx, qy, qz, qw]: {e}")))?,
            ),
        };
        // Octree parameters.
        let unknown_occupied = p.bool("unknown_occupied", false)?;
        let threshold = p.double("occupancy_threshold", 0.5, 1e-6..=1.0 - 1e-6)?;
        let allow_trailing = p.bool("allow_trailing_bytes", false)?;
        // Cloud parameters.
        let dilate_m = p.double("dilate_m", 0.0, 0.0..=1e3)?;
        let min_points = p.int("min_points", 1, 1..=255)? as u8;
        let fill = match p.string("fill")?.as_deref() {
            None | Some("none") => Fill::None,
            Some("columns") => {
                let toward = p.string("fill_toward")?.unwrap_or_else(|| "-z".into());
                let (axis, toward) = parse_toward(&toward).ok_or_else(|| {
                    bad(
                        "fill_toward",
                        format!(
                            "{}: an axis with its side, -x, +x, -y, +y, -z (the floor) or +z",
                            chronotope_yaml::quote(&toward)
                        ),
                    )
                })?;
                Fill::Columns { axis, toward }
            }
            Some(other) => {
                return Err(bad(
                    "fill",
                    format!("{}: none or columns", chronotope_yaml::quote(other)),
                ))
            }
        };
        if fill == Fill::None && spec.params.contains_key("fill_toward") {
            p.string("fill_toward")?;
            return Err(bad("fill_toward", "only with fill: columns".into()));
        }
        let tf_name = p.string("tf_topic")?;
        let output_topic = p.resolve("~/occupancy", "~/occupancy")?;
        p.finish()?;
        let has = |name: &str| spec.params.contains_key(name);
        match kind {
            InputKind::Octomap => {
                if let Some(n) = ["dilate_m", "min_points", "fill"]
                    .into_iter()
                    .find(|n| has(n))
                {
                    return Err(bad(
                        n,
                        "a point-cloud parameter; the input is an octree".into(),
                    ));
                }
                if let Some(t) = &transform {
                    if t.rotation() != RigidTransform::identity().rotation() {
                        return Err(bad(
                            "transform",
                            "an octree is axis-aligned: it can only be moved by a translation \
                             (quaternion 0, 0, 0, 1)"
                                .into(),
                        ));
                    }
                }
            }
            InputKind::Cloud => {
                if let Some(n) = [
                    "unknown_occupied",
                    "occupancy_threshold",
                    "allow_trailing_bytes",
                ]
                .into_iter()
                .find(|n| has(n))
                {
                    return Err(bad(
                        n,
                        "an octree parameter; the input is a point cloud".into(),
                    ));
                }
            }
        }
        if stamps_from.as_deref() == Some(input_topic.as_str())
            || lattice_from.as_deref() == Some(input_topic.as_str())
        {
            return Err(bad(
                "input_topic",
                "it is also lattice_from or stamps_from: those name a body's VoxelGrid topic"
                    .into(),
            ));
        }
        // Static transforms are read when the input's frame may differ from the lattice's.
        let tf_topic = if transform.is_none() && (frame_id.is_some() || lattice_from.is_some()) {
            Some(p_resolve(
                spec,
                "tf_topic",
                tf_name.as_deref().unwrap_or("/tf_static"),
            )?)
        } else {
            None
        };
        let raster = match kind {
            InputKind::Octomap => Raster::Octomap(OctomapRasterizer::new(
                OctomapOptions::new()
                    .threshold_probability(threshold)
                    .unknown_occupied(unknown_occupied)
                    .allow_trailing_bytes(allow_trailing),
            )),
            InputKind::Cloud => {
                let options = CloudOptions::new()
                    .min_points(min_points)
                    .dilate_m(dilate_m)
                    .fill(fill);
                Raster::Cloud {
                    raster: CloudRasterizer::new(options),
                    half: Box::new((CloudRasterizer::new(options), VoxelFrame::new())),
                    options,
                    transform: None,
                    split: min_points == 1,
                }
            }
        };
        Ok(Self {
            fqn: node,
            input_topic,
            kind,
            output_topic,
            stamps_from,
            lattice_from,
            tf_topic,
            lattice,
            frame_id,
            encoding,
            raster,
            transform,
            tf: StaticTf::default(),
            hold_ns: (hold_s * 1e9).round() as i64,
            out: VoxelFrame::new(),
            waiting_lattice: None,
            current: None,
            ahead: VecDeque::new(),
            last_input_ns: None,
            last_published_ns: None,
            stale: false,
            status: NodeStatus::default(),
        })
    }

    /// The topic of the frames it publishes (`~/occupancy`).
    pub fn occupancy_topic(&self) -> &str {
        &self.output_topic
    }

    /// The topic it reads.
    pub fn input_topic(&self) -> &str {
        &self.input_topic
    }

    /// What it reads there.
    pub fn input_kind(&self) -> InputKind {
        self.kind
    }

    fn count(&mut self, what: &str, n: u64) {
        if n > 0 {
            *self.status.counts.entry(what.to_owned()).or_default() += n;
        }
    }

    /// Takes the lattice from a body's frame (the first one heard).
    fn lattice_of(&mut self, g: &VoxelGrid) {
        if self.lattice.is_some() {
            return;
        }
        let size = [g.size_x, g.size_y, g.size_z];
        match Lattice::new([g.origin.x, g.origin.y, g.origin.z], g.resolution, size) {
            Ok(lattice) => {
                self.lattice = Some(CellLattice {
                    lattice,
                    frame_id: self
                        .frame_id
                        .clone()
                        .unwrap_or_else(|| g.header.frame_id.clone()),
                })
            }
            Err(e) => {
                let text = format!(
                    "{}: its frame cannot be the lattice ({e}); waiting for the next one",
                    self.lattice_from.as_deref().unwrap_or_default()
                );
                self.status
                    .count_quietly(&self.fqn, "lattice_from_refused", 1, || text);
            }
        }
    }

    /// The transform taking the input's `frame` into the lattice's frame `lattice_frame`:
    /// `Ok(None)` for none (the same frame).
    fn placement(
        &self,
        frame: &str,
        lattice_frame: &str,
    ) -> Result<Option<RigidTransform>, TfError> {
        if let Some(t) = self.transform {
            return Ok(Some(t));
        }
        if frame == lattice_frame || lattice_frame.is_empty() || frame.is_empty() {
            return Ok(None);
        }
        match self.tf.lookup(frame, lattice_frame) {
            Some(Ok(t)) => Ok(Some(t)),
            Some(Err(e)) => Err(e),
            None => Err(TfError::Unknown {
                from: frame.to_owned(),
                to: lattice_frame.to_owned(),
                tf_topic: self.tf_topic.clone(),
            }),
        }
    }

    /// Rasterises one input message. `Ok(None)`: refused (counted here).
    fn rasterise(&mut self, msg: &Message) -> Option<Held> {
        let Some(cell) = self.lattice.clone() else {
            self.waiting_lattice = Some(msg.clone());
            return None;
        };
        let (header, what) = match &msg.payload {
            Payload::Octomap(m) => (&m.header, "octree"),
            Payload::PointCloud2(m) => (&m.header, "cloud"),
            _ => return None,
        };
        let stamp = header.stamp.as_nanos();
        let at = format!(
            "{}: {what} at {}",
            self.input_topic,
            stamp_text(header.stamp)
        );
        if header.stamp.nanosec >= 1_000_000_000 {
            self.status.problem(
                &self.fqn,
                "bad_stamp",
                format!("{at}: nanosec ≥ 10^9; refused, nothing published for it"),
            );
            return None;
        }
        if let Some(last) = self.last_input_ns.filter(|&l| stamp <= l) {
            self.status.problem(
                &self.fqn,
                "stamp_order",
                format!(
                    "{at} is not after the last one ({:.3} s); refused, nothing published for it",
                    last as f64 * 1e-9
                ),
            );
            return None;
        }
        // Own frame: with no frame given, the input's.
        let frame_id = if cell.frame_id.is_empty() {
            header.frame_id.clone()
        } else {
            cell.frame_id.clone()
        };
        let placement = match self.placement(&header.frame_id, &frame_id) {
            Ok(p) => p,
            Err(why) => {
                self.status.problem(
                    &self.fqn,
                    "no_transform",
                    format!("{at}: {why}; refused, nothing published for it"),
                );
                return None;
            }
        };
        let encoding = self.encoding;
        let result: Result<Vec<u8>, (&'static str, String)> = match (&mut self.raster, &msg.payload)
        {
            (Raster::Octomap(r), Payload::Octomap(m)) => {
                // An octree moves by a translation only: the lattice moves the other way.
                let lattice = match placement {
                    None => Ok(cell.lattice),
                    Some(t) if t.rotation() != RigidTransform::identity().rotation() => Err((
                        "octomap_rotated",
                        format!(
                            "the octree's frame {} is rotated against the lattice's: an octree \
                             is axis-aligned and is only placed by a translation",
                            chronotope_yaml::quote(&header.frame_id)
                        ),
                    )),
                    Some(t) => {
                        let o = cell.lattice.origin();
                        let d = t.translation();
                        Lattice::new(
                            [o[0] - d[0], o[1] - d[1], o[2] - d[2]],
                            cell.lattice.resolution(),
                            cell.lattice.size(),
                        )
                        .map_err(|e| ("lattice", e.to_string()))
                    }
                };
                lattice.and_then(|lattice| {
                    let map = OctomapMsg {
                        binary: m.binary,
                        id: &m.id,
                        resolution: m.resolution,
                        data: &m.data,
                    };
                    match r.rasterize(&map, &lattice, encoding, &mut self.out) {
                        Ok(s) => {
                            let trailing = s.stream.trailing_bytes;
                            *self
                                .status
                                .counts
                                .entry("octree_leaves".into())
                                .or_default() += s.stream.occupied_leaves + s.stream.free_leaves;
                            if trailing > 0 {
                                *self
                                    .status
                                    .counts
                                    .entry("octree_trailing_bytes".into())
                                    .or_default() += trailing;
                            }
                            Ok(self.out.data().to_vec())
                        }
                        Err(e) => Err((octomap_kind(&e), e.to_string())),
                    }
                })
            }
            (
                Raster::Cloud {
                    raster,
                    half,
                    options,
                    transform,
                    split,
                },
                Payload::PointCloud2(c),
            ) => {
                if *transform != placement {
                    *raster = CloudRasterizer::new(options.transform(placement));
                    half.0 = CloudRasterizer::new(options.transform(placement));
                    *transform = placement;
                }
                let fields = cloud_fields(c);
                let cloud = cloud_ref(c, &fields);
                match rasterise_cloud(
                    *split,
                    raster,
                    half,
                    &cloud,
                    &cell.lattice,
                    encoding,
                    &mut self.out,
                ) {
                    Ok((data, s)) => {
                        for (what, n) in [
                            ("points", s.points),
                            ("points_nonfinite", s.nonfinite),
                            ("points_outside", s.outside),
                            ("points_margin", s.margin_points),
                            ("cloud_trailing_bytes", s.trailing_bytes),
                        ] {
                            if n > 0 {
                                *self.status.counts.entry(what.into()).or_default() += n;
                            }
                        }
                        Ok(data)
                    }
                    Err(e) => Err((cloud_kind(&e), e.to_string())),
                }
            }
            _ => return None,
        };
        let data = match result {
            Ok(data) => data,
            Err((kind, why)) => {
                self.status.problem(
                    &self.fqn,
                    kind,
                    format!("{at} refused: {why}; nothing published for it"),
                );
                return None;
            }
        };
        self.last_input_ns = Some(stamp);
        let l = &cell.lattice;
        let o = l.origin();
        let [sx, sy, sz] = l.size();
        let grid = VoxelGrid {
            header: Header {
                stamp: header.stamp,
                frame_id,
            },
            origin: Point {
                x: o[0],
                y: o[1],
                z: o[2],
            },
            resolution: l.resolution(),
            size_x: sx,
            size_y: sy,
            size_z: sz,
            encoding: encoding.as_u8(),
            data,
        };
        self.count("frames_rasterised", 1);
        Some(Held {
            stamp_ns: stamp,
            grid: Arc::new(grid),
            published: false,
        })
    }

    /// An input message: rasterised, then published at its own stamp, or kept for the cell's
    /// next frame time.
    fn on_input(&mut self, msg: &Message, out: &mut Vec<Message>) {
        let Some(held) = self.rasterise(msg) else {
            return;
        };
        if self.stamps_from.is_none() {
            let stamp = held.stamp_ns;
            self.last_published_ns = Some(stamp);
            out.push(Message::new(
                &self.output_topic,
                stamp,
                Payload::VoxelGrid(held.grid),
            ));
            return;
        }
        self.ahead.push_back(held);
        while self.ahead.len() > MAX_WAITING_FRAMES {
            if let Some(h) = self.ahead.pop_front() {
                self.replace_current(h);
            }
        }
    }

    /// `h` becomes the frame held; the one it replaces counts as superseded if no cell frame
    /// time ever showed it.
    fn replace_current(&mut self, h: Held) {
        if let Some(old) = self.current.replace(h) {
            if !old.published {
                self.count("superseded", 1);
            }
        }
        self.stale = false;
    }

    /// One of the cell's frame times (`stamps_from`'s frame at `t`): publishes the latest
    /// input not after it, if it is not older than `hold_s`.
    fn on_cell_time(&mut self, t: i64, out: &mut Vec<Message>) {
        while self.ahead.front().is_some_and(|h| h.stamp_ns <= t) {
            if let Some(h) = self.ahead.pop_front() {
                self.replace_current(h);
            }
        }
        if self.last_published_ns.is_some_and(|l| t <= l) {
            return;
        }
        let hold_ns = self.hold_ns;
        let Some(cur) = self.current.as_mut() else {
            return;
        };
        let age = t - cur.stamp_ns;
        if age > hold_ns {
            if !self.stale {
                self.stale = true;
                let text = format!(
                    "{}: the latest input ({:.3} s) is {:.3} s older than the cell's frame at \
                     {:.3} s, more than hold_s {:.3} s: no frame is published until the next \
                     input (the mesher sees the stream stop)",
                    self.input_topic,
                    cur.stamp_ns as f64 * 1e-9,
                    age as f64 * 1e-9,
                    t as f64 * 1e-9,
                    hold_ns as f64 * 1e-9
                );
                self.status
                    .count_quietly(&self.fqn, "input_stale", 1, || text);
            }
            return;
        }
        let held = if cur.published {
            1
        } else {
            cur.published = true;
            0
        };
        let mut grid = (*cur.grid).clone();
        grid.header.stamp = Time::from_nanos(t);
        self.last_published_ns = Some(t);
        self.count("frames_held", held);
        out.push(Message::new(
            &self.output_topic,
            t,
            Payload::VoxelGrid(Arc::new(grid)),
        ));
    }

    fn on_tf(&mut self, m: &TFMessage) {
        for t in &m.transforms {
            if let Err(why) = self.tf.insert(t) {
                self.status
                    .count_quietly(&self.fqn, "bad_transform", 1, || {
                        format!(
                            "{}: {why}; ignored",
                            self.tf_topic.as_deref().unwrap_or_default()
                        )
                    });
            }
        }
    }
}

/// `p.resolve` for a parameter read after `finish` (a default that depends on others).
fn p_resolve(spec: &NodeSpec, param: &str, topic: &str) -> Result<String, LaunchError> {
    Params::of(spec).resolve(param, topic)
}

fn stamp_text(t: Time) -> String {
    if t.nanosec >= 1_000_000_000 {
        format!("sec {} nanosec {}", t.sec, t.nanosec)
    } else {
        format!("{:.3} s", t.as_nanos() as f64 * 1e-9)
    }
}

/// The problem kind of an octree refusal: its error's name.
pub fn octomap_kind(e: &OctomapError) -> &'static str {
    match e {
        OctomapError::Lattice(l) => lattice_kind(l),
        OctomapError::Resolution { .. } => "octomap_resolution",
        OctomapError::UnknownTreeId { .. } => "octomap_unknown_tree_id",
        OctomapError::Threshold => "octomap_threshold",
        OctomapError::TooLarge { .. } => "octomap_too_large",
        OctomapError::Truncated { .. } => "octomap_truncated",
        OctomapError::TooDeep { .. } => "octomap_too_deep",
        OctomapError::TooManyNodes { .. } => "octomap_too_many_nodes",
        OctomapError::TrailingBytes { .. } => "octomap_trailing_bytes",
        OctomapError::NanLogOdds { .. } => "octomap_nan_log_odds",
    }
}

/// The problem kind of a cloud refusal: its error's name.
pub fn cloud_kind(e: &CloudError) -> &'static str {
    match e {
        CloudError::Lattice(l) => lattice_kind(l),
        CloudError::MissingField { .. } => "cloud_missing_field",
        CloudError::DuplicateField { .. } => "cloud_duplicate_field",
        CloudError::FieldDatatype { .. } => "cloud_field_datatype",
        CloudError::FieldCount { .. } => "cloud_field_count",
        CloudError::FieldOutsidePoint { .. } => "cloud_field_outside_point",
        CloudError::FieldsOverlap { .. } => "cloud_fields_overlap",
        CloudError::ZeroPointStep => "cloud_zero_point_step",
        CloudError::TooManyPoints { .. } => "cloud_too_many_points",
        CloudError::RowStepTooSmall { .. } => "cloud_row_step_too_small",
        CloudError::DataTooShort { .. } => "cloud_data_too_short",
        CloudError::Dilate { .. } => "cloud_dilate",
        CloudError::DilateTooLarge { .. } => "cloud_dilate_too_large",
    }
}

fn lattice_kind(e: &LatticeError) -> &'static str {
    match e {
        LatticeError::Origin { .. } => "lattice_origin",
        LatticeError::Resolution { .. } => "lattice_resolution",
        LatticeError::EmptySize { .. } => "lattice_empty",
        LatticeError::TooManyVoxels { .. } => "lattice_too_many_voxels",
        LatticeError::TooManyBytes { .. } => "lattice_too_many_bytes",
    }
}

impl Node for OccupancyNode {
    fn as_any(&self) -> &dyn std::any::Any {
        self
    }

    fn name(&self) -> &str {
        &self.fqn
    }

    fn subscriptions(&self) -> Vec<TopicRef> {
        let mut subs = vec![TopicRef {
            topic: self.input_topic.clone(),
            type_name: self.kind.type_name(),
        }];
        let mut bodies: Vec<&String> = self
            .lattice_from
            .iter()
            .chain(self.stamps_from.iter())
            .collect();
        bodies.dedup();
        subs.extend(bodies.into_iter().map(|t| TopicRef {
            topic: t.clone(),
            type_name: VoxelGrid::TYPE_NAME,
        }));
        subs.extend(self.tf_topic.iter().map(|t| TopicRef {
            topic: t.clone(),
            type_name: TFMessage::TYPE_NAME,
        }));
        subs
    }

    fn publications(&self) -> Vec<TopicRef> {
        vec![TopicRef {
            topic: self.output_topic.clone(),
            type_name: VoxelGrid::TYPE_NAME,
        }]
    }

    fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>) {
        self.status.received += 1;
        let before = out.len();
        match &msg.payload {
            Payload::Octomap(_) | Payload::PointCloud2(_) if *msg.topic == *self.input_topic => {
                self.on_input(msg, out)
            }
            Payload::VoxelGrid(g) => {
                if self.lattice_from.as_deref() == Some(&*msg.topic) && self.lattice.is_none() {
                    self.lattice_of(g);
                    if self.lattice.is_some() {
                        if let Some(w) = self.waiting_lattice.take() {
                            self.on_input(&w, out);
                        }
                    }
                }
                if self.stamps_from.as_deref() == Some(&*msg.topic) {
                    self.on_cell_time(g.header.stamp.as_nanos(), out);
                }
            }
            Payload::TFMessage(m) => self.on_tf(m),
            other => self.status.problem(
                &self.fqn,
                "wrong_type",
                format!(
                    "{}: an unexpected {}; ignored",
                    msg.topic,
                    other.type_name()
                ),
            ),
        }
        self.status.published += (out.len() - before) as u64;
    }

    fn finish(&mut self, _out: &mut Vec<Message>) {
        if self.lattice.is_none() {
            if let Some(t) = &self.lattice_from {
                let text = format!(
                    "{t}: no frame came, so there was no lattice to put {} on",
                    self.input_topic
                );
                self.status.problem(&self.fqn, "no_lattice", text);
            }
        }
    }

    fn runtime_parameters(&self) -> Vec<(String, ParamValue)> {
        vec![(
            "hold_s".into(),
            ParamValue::Double(self.hold_ns as f64 * 1e-9),
        )]
    }

    /// `hold_s` can change while the node runs; the rest is taken at start.
    fn set_parameter(&mut self, name: &str, value: &ParamValue) -> Result<(), ParamError> {
        let seconds = match value {
            ParamValue::Double(v) => Some(*v),
            ParamValue::Integer(i) => Some(*i as f64),
            _ => None,
        };
        match (name, seconds) {
            ("hold_s", Some(v)) if (0.0..=3600.0).contains(&v) => {
                self.hold_ns = (v * 1e9).round() as i64;
                Ok(())
            }
            ("hold_s", _) => Err(ParamError::BadValue {
                name: "hold_s",
                value: value.shown(),
                expected: "a number of seconds in [0, 3600]",
            }),
            (other, _) => Err(ParamError::StartOnly {
                name: other.to_owned(),
                node: self.fqn.clone(),
                changeable: Some("hold_s"),
            }),
        }
    }

    fn status(&self) -> &NodeStatus {
        &self.status
    }

    fn rank(&self) -> u8 {
        // Before the mesher, which meshes its frames.
        0
    }
}

/// Why a static transform is refused, or a frame cannot be placed in the lattice's.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum TfError {
    /// Its parent or child frame is empty, or they are the same frame.
    #[error(
        "a transform from {} to {} names no two frames",
        chronotope_yaml::quote(.parent),
        chronotope_yaml::quote(.child)
    )]
    NoTwoFrames { parent: String, child: String },
    /// A non-finite entry, or a quaternion not of unit norm.
    #[error(
        "the transform of {} in {} is not finite or its quaternion is not of unit norm",
        chronotope_yaml::quote(.child),
        chronotope_yaml::quote(.parent)
    )]
    NotRigid { child: String, parent: String },
    /// A new frame beyond [`MAX_TF_FRAMES`].
    #[error("more than {MAX_TF_FRAMES} frames (MAX_TF_FRAMES)")]
    TooManyFrames,
    /// The chain of parents from `frame` is longer than [`MAX_TF_DEPTH`].
    #[error(
        "the static transforms from {} go on for more than {MAX_TF_DEPTH} frames (a loop?)",
        chronotope_yaml::quote(.frame)
    )]
    TooDeep { frame: String },
    /// The composed transform is not a rigid one.
    #[error(transparent)]
    Transform(#[from] TransformError),
    /// No transform heard joins the two frames (and none is given).
    #[error(
        "no transform from {} to the lattice's frame {} is known{}",
        chronotope_yaml::quote(.from),
        chronotope_yaml::quote(.to),
        match .tf_topic {
            Some(t) => format!(" (none on {t} yet; or give `transform`)"),
            None => " (give `transform`, or `frame_id` so that /tf_static is read)".into(),
        }
    )]
    Unknown {
        from: String,
        to: String,
        /// The topic static transforms are read on, if any.
        tf_topic: Option<String>,
    },
}

/// The static transforms heard: each frame's pose in its parent, by child frame.
#[derive(Debug, Default)]
struct StaticTf {
    parents: BTreeMap<String, (String, Rigid)>,
}

/// A rigid transform as a unit quaternion `[x, y, z, w]` and a translation.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rigid {
    q: [f64; 4],
    t: [f64; 3],
}

impl Rigid {
    const IDENTITY: Self = Self {
        q: [0.0, 0.0, 0.0, 1.0],
        t: [0.0; 3],
    };

    fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let [x, y, z, w] = self.q;
        // v + 2w(u × v) + 2u × (u × v), u the vector part.
        let c1 = [
            y * v[2] - z * v[1],
            z * v[0] - x * v[2],
            x * v[1] - y * v[0],
        ];
        let c2 = [
            y * c1[2] - z * c1[1],
            z * c1[0] - x * c1[2],
            x * c1[1] - y * c1[0],
        ];
        [0, 1, 2].map(|i| v[i] + 2.0 * (w * c1[i] + c2[i]))
    }

    /// `self ∘ other`: `other` first.
    fn then_after(&self, other: &Rigid) -> Rigid {
        let [x1, y1, z1, w1] = self.q;
        let [x2, y2, z2, w2] = other.q;
        let q = [
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        ];
        let r = self.rotate(other.t);
        Rigid {
            q,
            t: [r[0] + self.t[0], r[1] + self.t[1], r[2] + self.t[2]],
        }
    }

    fn inverse(&self) -> Rigid {
        let [x, y, z, w] = self.q;
        let inv = Rigid {
            q: [-x, -y, -z, w],
            t: [0.0; 3],
        };
        let r = inv.rotate(self.t);
        Rigid {
            q: inv.q,
            t: [-r[0], -r[1], -r[2]],
        }
    }
}

impl StaticTf {
    fn insert(&mut self, t: &chronotope_msg::TransformStamped) -> Result<(), TfError> {
        let child = t.child_frame_id.trim_start_matches('/').to_owned();
        let parent = t.header.frame_id.trim_start_matches('/').to_owned();
        if child.is_empty() || parent.is_empty() || child == parent {
            return Err(TfError::NoTwoFrames { parent, child });
        }
        let tr = &t.transform;
        let q = [tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w];
        let v = [tr.translation.x, tr.translation.y, tr.translation.z];
        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(q.iter().chain(v.iter()).all(|c| c.is_finite()) && (norm - 1.0).abs() <= 1e-3) {
            return Err(TfError::NotRigid { child, parent });
        }
        if !self.parents.contains_key(&child) && self.parents.len() >= MAX_TF_FRAMES {
            return Err(TfError::TooManyFrames);
        }
        self.parents.insert(
            child,
            (
                parent,
                Rigid {
                    q: q.map(|c| c / norm),
                    t: v,
                },
            ),
        );
        Ok(())
    }

    /// `frame`'s pose in its root, and the root.
    fn to_root(&self, frame: &str) -> Result<(String, Rigid), TfError> {
        let mut pose = Rigid::IDENTITY;
        let mut at = frame.trim_start_matches('/').to_owned();
        for _ in 0..MAX_TF_DEPTH {
            match self.parents.get(&at) {
                None => return Ok((at, pose)),
                Some((parent, t)) => {
                    pose = t.then_after(&pose);
                    at = parent.clone();
                }
            }
        }
        Err(TfError::TooDeep {
            frame: frame.to_owned(),
        })
    }

    /// The transform taking points in `from` into `to`; `None` if the two frames are not
    /// joined by the transforms heard.
    fn lookup(&self, from: &str, to: &str) -> Option<Result<RigidTransform, TfError>> {
        let (ra, a) = match self.to_root(from) {
            Ok(x) => x,
            Err(e) => return Some(Err(e)),
        };
        let (rb, b) = match self.to_root(to) {
            Ok(x) => x,
            Err(e) => return Some(Err(e)),
        };
        if ra != rb {
            return None;
        }
        let t = b.inverse().then_after(&a);
        Some(RigidTransform::from_quaternion(t.q, t.t).map_err(TfError::from))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::launch::LaunchConfig;
    use chronotope_msg::PointField;

    fn node(params: &str) -> Result<OccupancyNode, LaunchError> {
        let text = format!(
            "launch:\n- node: {{pkg: chronotope, exec: occupancy, name: cam, param: [{params}]}}\n"
        );
        let c = LaunchConfig::parse(&text, "t").unwrap();
        OccupancyNode::from_spec(&c.nodes[0])
    }

    const CLOUD: &str = "{name: input_topic, value: /points}, {name: input_type, value: sensor_msgs/msg/PointCloud2}";
    const LATTICE: &str = "{name: origin, value: [0.0, 0.0, 0.0]}, {name: resolution, value: 0.1}, {name: size, value: [4, 4, 4]}";

    fn cloud(stamp_ns: i64, frame: &str, points: &[[f32; 3]]) -> Message {
        let data: Vec<u8> = points
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let c = PointCloud2 {
            header: Header {
                stamp: Time::from_nanos(stamp_ns),
                frame_id: frame.into(),
            },
            height: 1,
            width: points.len() as u32,
            fields: ["x", "y", "z"]
                .iter()
                .enumerate()
                .map(|(i, n)| PointField::new(*n, 4 * i as u32, PointField::FLOAT32, 1))
                .collect(),
            is_bigendian: false,
            point_step: 12,
            row_step: 12 * points.len() as u32,
            data,
            is_dense: false,
        };
        Message::new("/points", stamp_ns, Payload::PointCloud2(Arc::new(c)))
    }

    fn grids(out: &[Message]) -> Vec<Arc<VoxelGrid>> {
        out.iter()
            .filter_map(|m| match &m.payload {
                Payload::VoxelGrid(g) => Some(g.clone()),
                _ => None,
            })
            .collect()
    }

    fn occupied(g: &VoxelGrid) -> Vec<usize> {
        (0..(g.size_x * g.size_y * g.size_z) as usize)
            .filter(|&i| g.data[i / 8] >> (i % 8) & 1 == 1)
            .collect()
    }

    #[test]
    fn a_cloud_becomes_a_frame_at_its_own_stamp() {
        let mut n = node(&format!("{CLOUD}, {LATTICE}")).unwrap();
        let mut out = Vec::new();
        let m = cloud(
            1_000,
            "world",
            &[[0.05, 0.05, 0.05], [f32::NAN, 0.0, 0.0], [9.0, 9.0, 9.0]],
        );
        n.on_message(&m, &mut out);
        let g = grids(&out);
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].header.stamp.as_nanos(), 1_000);
        assert_eq!(g[0].header.frame_id, "world");
        assert_eq!(occupied(&g[0]), [0]);
        assert_eq!(n.status.counts["points_nonfinite"], 1);
        assert_eq!(n.status.counts["points_outside"], 1);
        assert_eq!(n.status.problem_count(), 0);
    }

    #[test]
    fn bad_clouds_are_refused_by_name_and_the_next_one_goes_through() {
        let mut n = node(&format!("{CLOUD}, {LATTICE}")).unwrap();
        let mut out = Vec::new();
        let mut m = cloud(1_000, "world", &[[0.05, 0.05, 0.05]]);
        if let Payload::PointCloud2(c) = &mut m.payload {
            let c = Arc::make_mut(c);
            c.point_step = 8; // z at offset 8 no longer fits in a point
            c.row_step = 8;
        }
        n.on_message(&m, &mut out);
        let mut m = cloud(2_000, "world", &[[0.05, 0.05, 0.05], [0.15, 0.05, 0.05]]);
        if let Payload::PointCloud2(c) = &mut m.payload {
            Arc::make_mut(c).row_step = 12; // width × point_step is 24
        }
        n.on_message(&m, &mut out);
        // An earlier stamp after the refusals: the refused ones did not count.
        n.on_message(&cloud(500, "world", &[[0.05, 0.05, 0.05]]), &mut out);
        assert_eq!(grids(&out).len(), 1);
        assert_eq!(n.status.problems["cloud_field_outside_point"], 1);
        assert_eq!(n.status.problems["cloud_row_step_too_small"], 1);
        n.on_message(&cloud(400, "world", &[[0.05, 0.05, 0.05]]), &mut out);
        assert_eq!(n.status.problems["stamp_order"], 1);
    }

    #[test]
    fn with_stamps_from_the_latest_input_is_held_at_the_cells_frame_times() {
        let mut n = node(&format!(
            "{CLOUD}, {{name: lattice_from, value: /table/occupancy}}, \
             {{name: stamps_from, value: /table/occupancy}}, {{name: hold_s, value: 0.25}}"
        ))
        .unwrap();
        assert_eq!(
            n.subscriptions().len(),
            3,
            "input, the body once, /tf_static"
        );
        let table = |t: i64| {
            let g = VoxelGrid {
                header: Header {
                    stamp: Time::from_nanos(t),
                    frame_id: "world".into(),
                },
                resolution: 0.1,
                size_x: 4,
                size_y: 4,
                size_z: 4,
                encoding: VoxelGrid::ENCODING_BITS,
                data: vec![0; 8],
                ..VoxelGrid::default()
            };
            Message::new("/table/occupancy", t, Payload::VoxelGrid(Arc::new(g)))
        };
        let ms = 1_000_000i64;
        let mut out = Vec::new();
        // A cloud before the lattice is known waits for it.
        n.on_message(&cloud(5 * ms, "world", &[[0.05, 0.05, 0.05]]), &mut out);
        assert!(out.is_empty());
        n.on_message(&table(0), &mut out);
        assert!(grids(&out).is_empty(), "the cloud is after the frame time");
        n.on_message(&table(100 * ms), &mut out);
        n.on_message(&cloud(130 * ms, "world", &[[0.15, 0.05, 0.05]]), &mut out);
        n.on_message(&cloud(160 * ms, "world", &[[0.25, 0.05, 0.05]]), &mut out);
        n.on_message(&table(200 * ms), &mut out);
        n.on_message(&table(300 * ms), &mut out);
        // The input stops: held for hold_s past its stamp, then nothing.
        n.on_message(&table(400 * ms), &mut out);
        n.on_message(&table(500 * ms), &mut out);
        let g = grids(&out);
        let stamps: Vec<i64> = g.iter().map(|g| g.header.stamp.as_nanos() / ms).collect();
        assert_eq!(stamps, [100, 200, 300, 400]);
        assert_eq!(occupied(&g[0]), [0]);
        assert_eq!(occupied(&g[1]), [2], "the latest before 200 ms, at 160 ms");
        assert_eq!(occupied(&g[3]), [2]);
        assert_eq!(n.status.counts["superseded"], 1, "130 ms never showed");
        assert_eq!(n.status.counts["frames_held"], 2);
        assert_eq!(n.status.problems["input_stale"], 1);
    }

    #[test]
    fn a_cloud_in_another_frame_is_placed_by_tf_static_or_refused() {
        let mut n = node(&format!(
            "{CLOUD}, {LATTICE}, {{name: frame_id, value: world}}"
        ))
        .unwrap();
        let mut out = Vec::new();
        n.on_message(&cloud(1, "camera", &[[0.05, 0.05, 0.05]]), &mut out);
        assert_eq!(n.status.problems["no_transform"], 1);
        // camera in base (+0.1 x), base in world (a quarter turn about z, then +0.2 y).
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let tf = |parent: &str, child: &str, t: [f64; 3], q: [f64; 4]| {
            chronotope_msg::TransformStamped {
                header: Header {
                    stamp: Time::default(),
                    frame_id: parent.into(),
                },
                child_frame_id: child.into(),
                transform: chronotope_msg::Transform {
                    translation: chronotope_msg::Vector3::new(t[0], t[1], t[2]),
                    rotation: chronotope_msg::Quaternion {
                        x: q[0],
                        y: q[1],
                        z: q[2],
                        w: q[3],
                    },
                },
            }
        };
        let m = TFMessage {
            transforms: vec![
                tf("base", "camera", [0.1, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]),
                tf("world", "base", [0.0, 0.1, 0.0], [0.0, 0.0, h, h]),
            ],
        };
        n.on_message(
            &Message::new("/tf_static", 0, Payload::TFMessage(Arc::new(m))),
            &mut out,
        );
        // (0.15, -0.05, 0.05) in camera → (0.25, -0.05, 0.05) in base → (0.05, 0.35, 0.05) in world.
        n.on_message(&cloud(2, "camera", &[[0.15, -0.05, 0.05]]), &mut out);
        let g = grids(&out);
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].header.frame_id, "world");
        assert_eq!(occupied(&g[0]), [4 * 3]);
    }

    #[test]
    fn parameters_are_checked_by_name() {
        for (params, what) in [
            ("{name: input_type, value: sensor_msgs/msg/PointCloud2}", "input_topic"),
            ("{name: input_topic, value: /p}", "input_type"),
            (&format!("{{name: input_topic, value: /p}}, {{name: input_type, value: std_msgs/String}}, {LATTICE}") as &str, "input_type"),
            (&format!("{CLOUD}, {{name: origin, value: [0, 0, 0]}}"), "resolution"),
            (&format!("{CLOUD}, {LATTICE}, {{name: lattice_from, value: /a}}"), "lattice_from"),
            (&format!("{CLOUD}, {{name: origin, value: [0, 0, 0]}}, {{name: resolution, value: 0.0}}, {{name: size, value: [4, 4, 4]}}"), "resolution"),
            (&format!("{CLOUD}, {LATTICE}, {{name: unknown_occupied, value: true}}"), "unknown_occupied"),
            (&format!("{CLOUD}, {LATTICE}, {{name: fill, value: columns}}, {{name: fill_toward, value: down}}"), "fill_toward"),
            (&format!("{CLOUD}, {LATTICE}, {{name: transform, value: [0, 0, 0, 0, 0, 0, 2]}}"), "transform"),
            (&format!("{{name: input_topic, value: /m}}, {{name: input_type, value: octomap_msgs/msg/Octomap}}, {LATTICE}, {{name: dilate_m, value: 0.1}}"), "dilate_m"),
            (&format!("{{name: input_topic, value: /m}}, {{name: input_type, value: octomap_msgs/msg/Octomap}}, {LATTICE}, {{name: transform, value: [0, 0, 0, 0, 0, 1, 0]}}"), "transform"),
            (&format!("{CLOUD}, {LATTICE}, {{name: size_x, value: 4}}"), "size_x"),
        ] {
            let e = node(params).err().map(|e| e.to_string()).unwrap_or_default();
            assert!(e.contains(what), "{params}: {e}");
        }
    }

    #[test]
    fn octrees_are_read_and_bad_ones_refused_by_name() {
        let octo =
            "{name: input_topic, value: /map}, {name: input_type, value: octomap_msgs/Octomap}, \
                    {name: origin, value: [-0.2, 0.0, 0.0]}, {name: resolution, value: 0.1}, \
                    {name: size, value: [4, 1, 1]}, {name: encoding, value: percent}";
        let mut n = node(octo).unwrap();
        let map = |t: i64, id: &str, res: f64, data: Vec<u8>| {
            let m = Octomap {
                header: Header {
                    stamp: Time::from_nanos(t),
                    frame_id: "map".into(),
                },
                binary: true,
                id: id.into(),
                resolution: res,
                data,
            };
            Message::new("/map", t, Payload::Octomap(Arc::new(m)))
        };
        let mut out = Vec::new();
        // The root's child 7 (x, y, z ≥ 0) is an occupied leaf of 2^15 cells.
        n.on_message(&map(1, "OcTree", 0.1, vec![0, 0b1000_0000]), &mut out);
        n.on_message(&map(2, "OcTree", 0.1, vec![0, 0b1100_0000]), &mut out);
        n.on_message(
            &map(3, "CountingOcTree", 0.1, vec![0, 0b1000_0000]),
            &mut out,
        );
        n.on_message(&map(4, "OcTree", 0.0, vec![0, 0b1000_0000]), &mut out);
        n.on_message(&map(5, "OcTree", f64::NAN, vec![0, 0b1000_0000]), &mut out);
        let g = grids(&out);
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].data, [255, 255, 100, 100]);
        assert_eq!(g[0].encoding, VoxelGrid::ENCODING_PERCENT);
        for kind in [
            "octomap_truncated",
            "octomap_unknown_tree_id",
            "octomap_resolution",
        ] {
            assert!(
                n.status.problems.contains_key(kind),
                "{kind}: {:?}",
                n.status.problems
            );
        }
        assert_eq!(n.status.problems["octomap_resolution"], 2);
    }

    /// A cloud large enough to be split gives the frame one pass gives, organised or not,
    /// with a margin and a fill, in both encodings.
    #[test]
    fn a_large_cloud_split_in_halves_gives_the_single_pass_frame() {
        let n = SPLIT_POINTS as usize + 1001;
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f32 / (1u64 << 53) as f32
        };
        let points: Vec<[f32; 3]> = (0..n)
            .map(|i| {
                if i % 97 == 0 {
                    [f32::NAN, 0.0, 0.0]
                } else {
                    [next() * 4.4 - 0.2, next() * 4.4 - 0.2, next() * 3.0]
                }
            })
            .collect();
        for (height, encoding) in [(1u32, "bits"), (7, "percent"), (2, "bits")] {
            let params = format!(
                "{CLOUD}, {{name: origin, value: [0.0, 0.0, 0.0]}}, {{name: resolution, value: 0.1}}, \
                 {{name: size, value: [40, 40, 24]}}, {{name: dilate_m, value: 0.1}}, \
                 {{name: fill, value: columns}}, {{name: encoding, value: {encoding}}}"
            );
            let mut node_ = node(&params).unwrap();
            let mut m = cloud(1, "world", &points[..n - n % height as usize]);
            if let Payload::PointCloud2(c) = &mut m.payload {
                let c = Arc::make_mut(c);
                c.height = height;
                c.width /= height;
                c.row_step = c.width * c.point_step;
            }
            let mut out = Vec::new();
            node_.on_message(&m, &mut out);
            let got = grids(&out);
            assert_eq!(got.len(), 1, "{:?}", node_.status.problems);
            // One pass, with the library alone.
            let Payload::PointCloud2(c) = &m.payload else {
                unreachable!()
            };
            let fields = cloud_fields(c);
            let whole = cloud_ref(c, &fields);
            let mut raster = CloudRasterizer::new(
                CloudOptions::new()
                    .dilate_m(0.1)
                    .fill(Fill::down_to_floor()),
            );
            let mut frame = VoxelFrame::new();
            let lattice = Lattice::new([0.0; 3], 0.1, [40, 40, 24]).unwrap();
            let enc = if encoding == "bits" {
                Encoding::Bits
            } else {
                Encoding::Percent
            };
            let stats = raster.rasterize(&whole, &lattice, enc, &mut frame).unwrap();
            assert_eq!(got[0].data, frame.data(), "height {height}, {encoding}");
            assert_eq!(node_.status.counts["points_nonfinite"], stats.nonfinite);
            assert_eq!(node_.status.counts["points_outside"], stats.outside);
        }
    }

    #[test]
    fn composed_static_transforms_invert() {
        let a = Rigid {
            q: [
                0.0,
                0.0,
                std::f64::consts::FRAC_1_SQRT_2,
                std::f64::consts::FRAC_1_SQRT_2,
            ],
            t: [1.0, 2.0, 3.0],
        };
        let id = a.inverse().then_after(&a);
        for (x, y) in id.t.iter().zip([0.0; 3]) {
            assert!((x - y).abs() < 1e-12);
        }
        assert!((id.q[3].abs() - 1.0).abs() < 1e-12);
    }
}
