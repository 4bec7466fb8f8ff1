//! The suite's own output messages (`chronotope_msgs`): 4D mesh pieces, per-tet labels, the
//! interference report and resolve suggestions. Their `.msg` files under `msgs/msg/` are the
//! source of truth (units and meanings are documented there).

use std::sync::Arc;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::{Header, Point, RosMessage, Time, Vector3};
use chronotope_mesh::{GridGeometry, TetMesh};

macro_rules! deps {
    ($($name:literal => $path:literal),* $(,)?) => {
        vec![$(($name, include_str!($path))),*]
    };
}

/// `chronotope_msgs/msg/MeshSlab`: one piece of a body's closed 4D boundary mesh.
///
/// The mesh is held as the mesher made it (`[i32; 4]` vertices, `[u32; 4]` tets) and written
/// as the flat `int32[] vertices` / `uint32[] tets` of the definition, so a piece passed in
/// memory is never converted.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshSlab {
    /// Stamp of the later frame (a cap: its frame); frame of the lattice.
    pub header: Header,
    /// The body (its VoxelGrid topic).
    pub body_id: String,
    /// [`Self::KIND_LATERAL`], [`Self::KIND_CAP_START`] or [`Self::KIND_CAP_END`].
    pub kind: u8,
    /// Lateral: index of the earlier frame; cap: index of its frame.
    pub index: u32,
    /// Time of frame `index`.
    pub stamp_lo: Time,
    /// Time of frame `index + 1` (a cap: `stamp_lo`).
    pub stamp_hi: Time,
    /// Min corner of voxel (0,0,0) (m).
    pub origin: Point,
    /// Voxel edge (m).
    pub resolution: f64,
    /// Voxels along x.
    pub size_x: u32,
    /// Voxels along y.
    pub size_y: u32,
    /// Voxels along z.
    pub size_z: u32,
    /// VoxelGrid encoding of the frames.
    pub encoding: u8,
    /// Lattice steps per voxel edge and per frame period.
    pub scale: i32,
    /// Occupied voxels of the later frame (a cap: of its frame).
    pub occupied_voxels: u64,
    /// A part of the body moves more than its thickness in this frame period.
    pub vanishes: bool,
    /// When `vanishes`: the estimated factor on the frame rate that would join every part
    /// (0: not estimated).
    pub vanish_rate_factor: f32,
    /// How far the body moves between the frames (voxels; see
    /// [`chronotope_mesh::Slab::displacement`]); 0 for a cap.
    pub displacement_voxels: u16,
    /// [`Self::OBSERVED`], [`Self::FILLED`] or [`Self::SPANNED`].
    pub observed: u8,
    /// The tets (lattice coordinates), shared: a node of the process that keeps the piece
    /// (the checker, for its windows and horizons) takes it without a copy.
    pub mesh: Arc<TetMesh>,
}

impl MeshSlab {
    /// Lateral tets between frames `index` and `index + 1`.
    pub const KIND_LATERAL: u8 = 0;
    /// Cap closing the body at its first frame.
    pub const KIND_CAP_START: u8 = 1;
    /// Cap closing the body at its last frame.
    pub const KIND_CAP_END: u8 = 2;
    /// Both frames were received.
    pub const OBSERVED: u8 = 0;
    /// The frames were missing and filled with the union of the frames around the gap.
    pub const FILLED: u8 = 1;
    /// Frames were missing and this slab bridges the gap.
    pub const SPANNED: u8 = 2;

    /// Why the piece does not show every contact, if it does not (see
    /// [`chronotope_mesh::unsure`]).
    pub fn unsure(&self) -> Option<chronotope_mesh::unsure::Unsure> {
        use chronotope_mesh::unsure::Unsure;
        let gap = match self.observed {
            Self::FILLED => Some(Unsure::Filled),
            Self::SPANNED => Some(Unsure::Spanned),
            _ => None,
        };
        let vanish = self.vanishes.then_some(Unsure::Vanishes {
            rate_factor: self.vanish_rate_factor,
        });
        match (gap, vanish) {
            (Some(g), Some(v)) => Some(g.max(v)),
            (g, v) => g.or(v),
        }
    }

    /// Sets `vanishes`, `vanish_rate_factor` and `observed` from `unsure`.
    pub fn set_unsure(&mut self, unsure: Option<chronotope_mesh::unsure::Unsure>) {
        use chronotope_mesh::unsure::Unsure;
        self.vanishes = false;
        self.vanish_rate_factor = 0.0;
        self.observed = Self::OBSERVED;
        match unsure {
            Some(Unsure::Vanishes { rate_factor }) => {
                self.vanishes = true;
                self.vanish_rate_factor = rate_factor;
            }
            Some(Unsure::Filled) => self.observed = Self::FILLED,
            Some(Unsure::Spanned) => self.observed = Self::SPANNED,
            // A pair's doubt, not a slab's: the slab carries `displacement_voxels`.
            Some(Unsure::MovesFast { .. }) | None => {}
        }
    }

    /// The lattice of the piece.
    pub fn geometry(&self) -> GridGeometry {
        GridGeometry {
            origin: [self.origin.x, self.origin.y, self.origin.z],
            resolution: self.resolution,
            size: [self.size_x, self.size_y, self.size_z],
            encoding: self.encoding,
            scale: self.scale,
        }
    }

    /// Sets the lattice fields from `g`.
    pub fn set_geometry(&mut self, g: &GridGeometry) {
        self.origin = Point {
            x: g.origin[0],
            y: g.origin[1],
            z: g.origin[2],
        };
        self.resolution = g.resolution;
        [self.size_x, self.size_y, self.size_z] = g.size;
        self.encoding = g.encoding;
        self.scale = g.scale;
    }
}

/// Serialises `[T; 4]` items as one flat sequence of `4·n` elements.
struct Flat4<'a, T>(&'a [[T; 4]]);

impl<T: Serialize> Serialize for Flat4<'_, T> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        let mut seq = s.serialize_seq(Some(self.0.len() * 4))?;
        for item in self.0 {
            for v in item {
                seq.serialize_element(v)?;
            }
        }
        seq.end()
    }
}

/// Reads a flat sequence of `4·n` elements back into `[T; 4]` items.
struct Unflat4<T>(Vec<[T; 4]>);

impl<'de, T: Deserialize<'de> + Copy + Default> Deserialize<'de> for Unflat4<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de> + Copy + Default> serde::de::Visitor<'de> for V<T> {
            type Value = Unflat4<T>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a sequence of 4·n numbers")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<Self::Value, A::Error> {
                // The decoder has checked the count against the bytes present; capacity is
                // bounded all the same.
                let hint = seq.size_hint().unwrap_or(0).min(1 << 20) / 4;
                let mut out: Vec<[T; 4]> = Vec::with_capacity(hint);
                let mut item = [T::default(); 4];
                let mut k = 0;
                while let Some(v) = seq.next_element::<T>()? {
                    item[k] = v;
                    k += 1;
                    if k == 4 {
                        out.push(item);
                        k = 0;
                    }
                }
                if k != 0 {
                    return Err(serde::de::Error::custom(format!(
                        "{} numbers, not a multiple of 4",
                        out.len() * 4 + k
                    )));
                }
                Ok(Unflat4(out))
            }
        }
        d.deserialize_seq(V(std::marker::PhantomData))
    }
}

#[derive(Serialize)]
struct MeshSlabOut<'a> {
    header: &'a Header,
    body_id: &'a str,
    kind: u8,
    index: u32,
    stamp_lo: Time,
    stamp_hi: Time,
    origin: Point,
    resolution: f64,
    size_x: u32,
    size_y: u32,
    size_z: u32,
    encoding: u8,
    scale: i32,
    occupied_voxels: u64,
    vanishes: bool,
    vanish_rate_factor: f32,
    displacement_voxels: u16,
    observed: u8,
    vertices: Flat4<'a, i32>,
    tets: Flat4<'a, u32>,
}

#[derive(Deserialize)]
struct MeshSlabIn {
    header: Header,
    body_id: String,
    kind: u8,
    index: u32,
    stamp_lo: Time,
    stamp_hi: Time,
    origin: Point,
    resolution: f64,
    size_x: u32,
    size_y: u32,
    size_z: u32,
    encoding: u8,
    scale: i32,
    occupied_voxels: u64,
    vanishes: bool,
    vanish_rate_factor: f32,
    displacement_voxels: u16,
    observed: u8,
    vertices: Unflat4<i32>,
    tets: Unflat4<u32>,
}

impl Serialize for MeshSlab {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        MeshSlabOut {
            header: &self.header,
            body_id: &self.body_id,
            kind: self.kind,
            index: self.index,
            stamp_lo: self.stamp_lo,
            stamp_hi: self.stamp_hi,
            origin: self.origin,
            resolution: self.resolution,
            size_x: self.size_x,
            size_y: self.size_y,
            size_z: self.size_z,
            encoding: self.encoding,
            scale: self.scale,
            occupied_voxels: self.occupied_voxels,
            vanishes: self.vanishes,
            vanish_rate_factor: self.vanish_rate_factor,
            displacement_voxels: self.displacement_voxels,
            observed: self.observed,
            vertices: Flat4(&self.mesh.vertices),
            tets: Flat4(&self.mesh.tets),
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for MeshSlab {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let m = MeshSlabIn::deserialize(d)?;
        Ok(MeshSlab {
            header: m.header,
            body_id: m.body_id,
            kind: m.kind,
            index: m.index,
            stamp_lo: m.stamp_lo,
            stamp_hi: m.stamp_hi,
            origin: m.origin,
            resolution: m.resolution,
            size_x: m.size_x,
            size_y: m.size_y,
            size_z: m.size_z,
            encoding: m.encoding,
            scale: m.scale,
            occupied_voxels: m.occupied_voxels,
            vanishes: m.vanishes,
            vanish_rate_factor: m.vanish_rate_factor,
            displacement_voxels: m.displacement_voxels,
            observed: m.observed,
            mesh: Arc::new(TetMesh {
                vertices: m.vertices.0,
                tets: m.tets.0,
            }),
        })
    }
}

impl RosMessage for MeshSlab {
    const TYPE_NAME: &'static str = "chronotope_msgs/msg/MeshSlab";
    const DEFINITION: &'static str = include_str!("../../../msgs/msg/MeshSlab.msg");
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        deps![
            "std_msgs/msg/Header" => "../../../msgs/deps/std_msgs/msg/Header.msg",
            "builtin_interfaces/msg/Time" => "../../../msgs/deps/builtin_interfaces/msg/Time.msg",
            "geometry_msgs/msg/Point" => "../../../msgs/deps/geometry_msgs/msg/Point.msg",
        ]
    }
}

/// `chronotope_msgs/msg/TetLabels`: the labels of one slab of a body against another body.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TetLabels {
    /// Time of the slab's later frame; frame of the lattice.
    pub header: Header,
    /// The labelled body.
    pub body_id: String,
    /// The body it is labelled against.
    pub other_id: String,
    /// The slab: `body_id`'s LATERAL piece with this index.
    pub index: u32,
    /// Time of frame `index`.
    pub stamp_lo: Time,
    /// Time of frame `index + 1`.
    pub stamp_hi: Time,
    /// The labels begin with the tets of the body's CAP_START piece.
    pub with_cap_start: bool,
    /// The labels end with the tets of the body's CAP_END piece.
    pub with_cap_end: bool,
    /// One per tet: first cap (if any), the slab, last cap (if any).
    #[serde(with = "serde_bytes")]
    pub labels: Vec<u8>,
    /// INTERFERENCE count.
    pub interference: u64,
    /// INSIDE count.
    pub inside: u64,
    /// OUTSIDE count.
    pub outside: u64,
}

impl TetLabels {
    /// Outside the other body.
    pub const OUTSIDE: u8 = 0;
    /// Inside the other body.
    pub const INSIDE: u8 = 1;
    /// Crosses the other body's boundary.
    pub const INTERFERENCE: u8 = 2;
}

impl RosMessage for TetLabels {
    const TYPE_NAME: &'static str = "chronotope_msgs/msg/TetLabels";
    const DEFINITION: &'static str = include_str!("../../../msgs/msg/TetLabels.msg");
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        deps![
            "std_msgs/msg/Header" => "../../../msgs/deps/std_msgs/msg/Header.msg",
            "builtin_interfaces/msg/Time" => "../../../msgs/deps/builtin_interfaces/msg/Time.msg",
        ]
    }
}

/// `chronotope_msgs/msg/BodySummary`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BodySummary {
    /// The body's VoxelGrid topic.
    pub body_id: String,
    /// Frames meshed.
    pub frames: u64,
    /// Frames refused.
    pub skipped_frames: u64,
    /// Tets of the closed mesh.
    pub tets: u64,
    /// Vertices of the mesh.
    pub vertices: u64,
    /// Closed and consistently oriented.
    pub closed: bool,
    /// 4D measure (m³·s).
    pub hypervolume_m3s: f64,
    /// Frame periods in which the body moves more than its thickness.
    pub vanishing_slabs: u64,
}

/// `chronotope_msgs/msg/PairInterference`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PairInterference {
    /// First body.
    pub body_a: String,
    /// Second body.
    pub body_b: String,
    /// [`Self::VERDICT_CLEAR`], [`Self::VERDICT_COLLIDE`] or [`Self::VERDICT_UNSURE`].
    pub verdict: u8,
    /// Unsure span starts (s since the report's time origin).
    pub unsure_start_s: Vec<f64>,
    /// Unsure span ends (s).
    pub unsure_end_s: Vec<f64>,
    /// Per unsure span: the body, why, and what would resolve it.
    pub unsure_reason: Vec<String>,
    /// The interiors overlap somewhere in space-time.
    pub interfering: bool,
    /// Interval starts (s since the report's time origin).
    pub interval_start_s: Vec<f64>,
    /// Interval ends (s).
    pub interval_end_s: Vec<f64>,
    /// First contact (s), NaN if none.
    pub first_contact_s: f64,
    /// Its error bound (s), NaN if unknown.
    pub first_contact_error_bound_s: f64,
    /// Closing speed at first contact (m/s), NaN if unknown.
    pub closing_speed_mps: f64,
    /// Overlap measure (m³·s), NaN if not measured.
    pub overlap_hypervolume_m3s: f64,
    /// Its error bound (m³·s), NaN if not measured.
    pub overlap_hypervolume_error_bound_m3s: f64,
    /// Label counts of body a.
    pub a_interference: u64,
    /// .
    pub a_inside: u64,
    /// .
    pub a_outside: u64,
    /// Label counts of body b.
    pub b_interference: u64,
    /// .
    pub b_inside: u64,
    /// .
    pub b_outside: u64,
}

impl PairInterference {
    /// No interference, and both bodies observed well enough wherever compared.
    pub const VERDICT_CLEAR: u8 = 0;
    /// The bodies interfere.
    pub const VERDICT_COLLIDE: u8 = 1;
    /// No interference found, but in unsure spans a contact can be missed.
    pub const VERDICT_UNSURE: u8 = 2;
}

/// `chronotope_msgs/msg/InterferenceReport`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct InterferenceReport {
    /// Time of the last frame checked; frame of the lattice.
    pub header: Header,
    /// Report times are seconds since this stamp.
    pub time_origin: Time,
    /// c of the 4D metric (m/s).
    pub time_scale_m_per_s: f64,
    /// Voxel edge of the common lattice (m).
    pub voxel_size_m: f64,
    /// The bodies.
    pub bodies: Vec<BodySummary>,
    /// The checked pairs.
    pub pairs: Vec<PairInterference>,
}

impl RosMessage for InterferenceReport {
    const TYPE_NAME: &'static str = "chronotope_msgs/msg/InterferenceReport";
    const DEFINITION: &'static str = include_str!("../../../msgs/msg/InterferenceReport.msg");
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        deps![
            "std_msgs/msg/Header" => "../../../msgs/deps/std_msgs/msg/Header.msg",
            "builtin_interfaces/msg/Time" => "../../../msgs/deps/builtin_interfaces/msg/Time.msg",
            "chronotope_msgs/msg/BodySummary" => "../../../msgs/msg/BodySummary.msg",
            "chronotope_msgs/msg/PairInterference" => "../../../msgs/msg/PairInterference.msg",
        ]
    }
}

/// `chronotope_msgs/msg/ResolveSuggestion`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ResolveSuggestion {
    /// The body to move or retime.
    pub body_id: String,
    /// [`Self::KIND_TRANSLATE`], [`Self::KIND_TIME_SCALE`] or [`Self::KIND_ROTATE`].
    pub kind: u8,
    /// Shift in space (m).
    pub translation: Vector3,
    /// Shift in time (s).
    pub time_shift_s: f64,
    /// 4D length of the shift (m).
    pub distance: f64,
    /// Bound on the distance's excess over the shortest clearing shift (m).
    pub distance_error_bound_m: f64,
    /// Fixed time of the retiming (s since the time origin).
    pub t0_s: f64,
    /// Factor on durations after `t0_s`.
    pub scale: f64,
    /// Unit direction of the axis turned about.
    pub axis: Vector3,
    /// A point on the axis (m).
    pub point: Point,
    /// The turn, right-handed about `axis` (rad).
    pub angle_rad: f64,
    /// Checked again against every other body: clear.
    pub verified_clear: bool,
    /// Start of the contact episode it clears (s since the time origin).
    pub episode_start_s: f64,
    /// End of that episode (s).
    pub episode_end_s: f64,
    /// Spans in which a body is not observed well enough for the check to hold: starts (s).
    pub unsure_start_s: Vec<f64>,
    /// Their ends (s).
    pub unsure_end_s: Vec<f64>,
}

impl ResolveSuggestion {
    /// Move the body.
    pub const KIND_TRANSLATE: u8 = 0;
    /// Retime the body.
    pub const KIND_TIME_SCALE: u8 = 1;
    /// Turn the body about an axis, time fixed.
    pub const KIND_ROTATE: u8 = 2;
}

/// `chronotope_msgs/msg/ContactEvent`: a contact of two bodies as it begins, goes on and ends.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactEvent {
    /// Time of the later frame of the period that found, extended or closed it.
    pub header: Header,
    /// First body (ids in sorted order).
    pub body_a: String,
    /// Second body.
    pub body_b: String,
    /// [`Self::BEGIN`], [`Self::ONGOING`] or [`Self::END`].
    pub event: u8,
    /// The contact's place among the pair's contacts.
    pub contact_index: u64,
    /// Times below are seconds since this stamp.
    pub time_origin: Time,
    /// Interval start (s).
    pub start_s: f64,
    /// Interval end so far (s).
    pub end_s: f64,
    /// Bound on the start's error (s), NaN until known.
    pub start_error_bound_s: f64,
    /// Bound on the end's error (s), NaN before the end.
    pub end_error_bound_s: f64,
    /// The pair's first contact (s).
    pub first_contact_s: f64,
    /// The pair's overlap so far (m³·s), NaN if not measurable.
    pub overlap_hypervolume_m3s: f64,
    /// For unsure spans: the body, why, and what would resolve it; empty otherwise.
    pub unsure_reason: String,
}

impl ContactEvent {
    /// A new contact.
    pub const BEGIN: u8 = 0;
    /// The contact went on through another frame period.
    pub const ONGOING: u8 = 1;
    /// The contact ended.
    pub const END: u8 = 2;
    /// A span the pair cannot be called clear in began.
    pub const UNSURE_BEGIN: u8 = 3;
    /// That span ended.
    pub const UNSURE_END: u8 = 4;
}

impl RosMessage for ContactEvent {
    const TYPE_NAME: &'static str = "chronotope_msgs/msg/ContactEvent";
    const DEFINITION: &'static str = include_str!("../../../msgs/msg/ContactEvent.msg");
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        deps![
            "std_msgs/msg/Header" => "../../../msgs/deps/std_msgs/msg/Header.msg",
            "builtin_interfaces/msg/Time" => "../../../msgs/deps/builtin_interfaces/msg/Time.msg",
        ]
    }
}

/// `chronotope_msgs/msg/ResolveSuggestions`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ResolveSuggestions {
    /// Time of the last frame checked.
    pub header: Header,
    /// The suggestions.
    pub suggestions: Vec<ResolveSuggestion>,
}

impl RosMessage for ResolveSuggestions {
    const TYPE_NAME: &'static str = "chronotope_msgs/msg/ResolveSuggestions";
    const DEFINITION: &'static str = include_str!("../../../msgs/msg/ResolveSuggestions.msg");
    fn dependencies() -> Vec<(&'static str, &'static str)> {
        deps![
            "std_msgs/msg/Header" => "../../../msgs/deps/std_msgs/msg/Header.msg",
            "builtin_interfaces/msg/Time" => "../../../msgs/deps/builtin_interfaces/msg/Time.msg",
            "chronotope_msgs/msg/ResolveSuggestion" => "../../../msgs/msg/ResolveSuggestion.msg",
            "geometry_msgs/msg/Point" => "../../../msgs/deps/geometry_msgs/msg/Point.msg",
            "geometry_msgs/msg/Vector3" => "../../../msgs/deps/geometry_msgs/msg/Vector3.msg",
        ]
    }
}
