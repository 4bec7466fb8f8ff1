//! The `person-cell` scene: a person walks up to the machine-tool cell and reaches into the
//! spindle's path, seen by a depth camera (a `sensor_msgs/PointCloud2` of the points it sees
//! on the person) and mapped by an OctoMap built from the same camera (an
//! `octomap_msgs/Octomap` binary stream), beside the cell's own bodies as VoxelGrid frames.
//!
//! The cell is the machine-tool scene's (spindle, table, fixture: [`super::machine_tool`]),
//! on a larger domain, a cube of [`PERSON_CELL_DOMAIN_EDGE`] m, so the person fits. The camera
//! stands at [`CAMERA_POSITION`], looks at the cell, and publishes an organised cloud in its
//! optical frame (z forward, x right, y down; `camera_optical`), placed in `world` by the
//! `/tf_static` the scene also writes. Pixels whose ray misses the person are NaN: the cloud is
//! the person alone, as after a background filter that removes the static cell. It sees the
//! person's front and top only: a shell. Occlusion between the person's parts is modelled (a
//! ray stops at the first surface).
//!
//! The octree (`OcTree`, 0.04 m, half the default voxel) holds the cells the camera's rays
//! end in as occupied and the cells they cross as free; everything else is unknown. It is
//! written unpruned: every known cell a leaf at depth 16 (a valid stream; octomap_server's
//! are pruned, which changes the bytes, not the map).
//!
//! Timing: the cell's bodies at 10 Hz; the camera at 10 Hz, 33 ms after each cell frame (its
//! latency); the map at 5 Hz, 50 ms after every other cell frame. Pure library code.

use super::{BodySpec, Keyframe, Motion, Rasterizer, Shape, VoxelLattice};
use chronotope_msg::{
    Header, Octomap, Point, PointCloud2, PointField, Quaternion, TFMessage, Time, Transform,
    TransformStamped, Vector3, VoxelEncoding, VoxelGrid,
};

/// Edge of the cubic domain (m), `[0, 2.56]³`: the machine-tool cell and the person beside it.
pub const PERSON_CELL_DOMAIN_EDGE: f64 = 2.56;
/// Time between the cell's frames (ns).
pub const PERSON_CELL_FRAME_PERIOD_NS: i64 = 100_000_000;
/// The camera's latency: its cloud of a cell frame's instant is stamped this much later (ns).
pub const CAMERA_DELAY_NS: i64 = 33_000_000;
/// The map's delay after every other cell frame (ns).
pub const MAP_DELAY_NS: i64 = 50_000_000;
/// Where the camera stands (m), in `world`.
pub const CAMERA_POSITION: [f64; 3] = [2.45, -0.55, 2.2];
/// What the camera looks at (m).
pub const CAMERA_TARGET: [f64; 3] = [1.4, 0.64, 0.9];
/// Pixels of the camera, width × height.
pub const CAMERA_PIXELS: [u32; 2] = [48, 36];
/// Horizontal field of view (degrees).
pub const CAMERA_FOV_DEG: f64 = 75.0;
/// Edge of the octree's finest cells (m).
pub const OCTREE_RESOLUTION: f64 = 0.04;
/// The camera's frame.
pub const CAMERA_FRAME: &str = "camera_optical";
/// Topics of the camera's cloud and the map.
pub const CLOUD_TOPIC: &str = "/camera/points";
/// The map's topic, as octomap_server names it.
pub const OCTOMAP_TOPIC: &str = "/octomap_binary";

/// The person: a body (legs, torso, head) walking along −x towards the cell, and a right arm
/// that reaches out along −x at shoulder height once the person stands at the table (three
/// segments of 0.20 m, Ø 0.10 m, inside the torso until then, sliding out one after the
/// other like a telescope: each part is rigid, their union is the person). Over a run of
/// `duration` seconds.
pub fn person(duration: f64) -> Vec<BodySpec> {
    let key = |u: f64, offset: [f64; 3]| Keyframe {
        t: u * duration,
        offset,
    };
    // At rest the person stands at x = 2.30 (torso centre), facing −x, centred on y = 0.64;
    // it walks 0.85 m, to 0.18 m from the table's edge, and stands.
    let cx = 2.30;
    let walk = |reach: f64| {
        Motion::keyframes(vec![
            key(0.0, [0.0; 3]),
            key(0.55, [-0.85, 0.0, 0.0]),
            key(0.8, [-0.85 - reach, 0.0, 0.0]),
            key(1.0, [-0.85 - reach, 0.0, 0.0]),
        ])
    };
    let mut parts = vec![BodySpec::new(
        "/person",
        "legs, torso and head (1.76 m tall) walking along -x to the table",
        vec![
            Shape::cuboid([cx - 0.07, 0.52, 0.0], [cx + 0.07, 0.62, 0.95]),
            Shape::cuboid([cx - 0.07, 0.66, 0.0], [cx + 0.07, 0.76, 0.95]),
            Shape::cuboid([cx - 0.12, 0.44, 0.95], [cx + 0.12, 0.84, 1.52]),
            Shape::sphere([cx, 0.64, 1.65], 0.11),
        ],
        walk(0.0),
    )];
    for i in 1..=3 {
        parts.push(BodySpec::new(
            format!("/person/arm{i}"),
            "a segment of the right arm at shoulder height",
            vec![Shape::cylinder(
                super::Axis::X,
                [cx - 0.10, 0.53, 1.03],
                0.20,
                0.05,
            )],
            walk(0.18 * f64::from(i)),
        ));
    }
    parts
}

/// The scene, built for `frames` frames of the cell on a `grid`³ lattice.
#[derive(Debug, Clone)]
pub struct PersonCell {
    lattice: VoxelLattice,
    frames: u32,
    /// Time between the cell's frames (ns).
    period_ns: i64,
    cell: Vec<BodySpec>,
    person: Vec<BodySpec>,
    camera: Camera,
}

/// A pinhole camera: position, orientation (its optical axes in `world`) and pixel rays.
#[derive(Debug, Clone, Copy)]
struct Camera {
    position: [f64; 3],
    /// Optical axes in `world`: x right, y down, z forward.
    axes: [[f64; 3]; 3],
    /// Focal length in pixels.
    focal: f64,
    /// Pixels, columns × rows.
    pixels: [u32; 2],
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl Camera {
    fn looking_at(position: [f64; 3], target: [f64; 3], pixels: [u32; 2]) -> Self {
        let z = unit(sub(target, position));
        let x = unit(cross(z, [0.0, 0.0, 1.0]));
        let y = cross(z, x);
        let half = (CAMERA_FOV_DEG.to_radians() / 2.0).tan();
        Self {
            position,
            axes: [x, y, z],
            focal: f64::from(pixels[0]) / 2.0 / half,
            pixels,
        }
    }

    /// The ray through pixel `(u, v)` (column, row), a unit vector in `world`.
    fn ray(&self, u: u32, v: u32) -> [f64; 3] {
        let [w, h] = self.pixels.map(f64::from);
        let a = (f64::from(u) + 0.5 - w / 2.0) / self.focal;
        let b = (f64::from(v) + 0.5 - h / 2.0) / self.focal;
        let [x, y, z] = self.axes;
        unit([0, 1, 2].map(|i| a * x[i] + b * y[i] + z[i]))
    }

    /// A point of `world` in the optical frame.
    fn to_optical(&self, p: [f64; 3]) -> [f64; 3] {
        let d = sub(p, self.position);
        self.axes.map(|a| dot(a, d))
    }

    /// The optical frame's pose in `world` as a quaternion `[x, y, z, w]` (from its axes,
    /// the columns of the rotation).
    fn quaternion(&self) -> [f64; 4] {
        let [x, y, z] = self.axes;
        // R = [x y z] as columns: r[i][j] = axes[j][i].
        let r = |i: usize, j: usize| self.axes[j][i];
        let _ = (x, y, z);
        let trace = r(0, 0) + r(1, 1) + r(2, 2);
        if trace > 0.0 {
            let s = (trace + 1.0).sqrt() * 2.0;
            [
                (r(2, 1) - r(1, 2)) / s,
                (r(0, 2) - r(2, 0)) / s,
                (r(1, 0) - r(0, 1)) / s,
                0.25 * s,
            ]
        } else if r(0, 0) > r(1, 1) && r(0, 0) > r(2, 2) {
            let s = (1.0 + r(0, 0) - r(1, 1) - r(2, 2)).sqrt() * 2.0;
            [
                0.25 * s,
                (r(0, 1) + r(1, 0)) / s,
                (r(0, 2) + r(2, 0)) / s,
                (r(2, 1) - r(1, 2)) / s,
            ]
        } else if r(1, 1) > r(2, 2) {
            let s = (1.0 + r(1, 1) - r(0, 0) - r(2, 2)).sqrt() * 2.0;
            [
                (r(0, 1) + r(1, 0)) / s,
                0.25 * s,
                (r(1, 2) + r(2, 1)) / s,
                (r(0, 2) - r(2, 0)) / s,
            ]
        } else {
            let s = (1.0 + r(2, 2) - r(0, 0) - r(1, 1)).sqrt() * 2.0;
            [
                (r(0, 2) + r(2, 0)) / s,
                (r(1, 2) + r(2, 1)) / s,
                0.25 * s,
                (r(1, 0) - r(0, 1)) / s,
            ]
        }
    }
}

/// Farthest a camera ray is followed (m).
const MAX_RANGE: f64 = 6.0;

impl PersonCell {
    /// The scene with `frames` cell frames (at least 2) on a `grid`³ lattice, a frame every
    /// [`PERSON_CELL_FRAME_PERIOD_NS`], seen by a camera of [`CAMERA_PIXELS`].
    pub fn new(grid: u32, frames: u32) -> Self {
        Self::with_timing(grid, frames, PERSON_CELL_FRAME_PERIOD_NS, CAMERA_PIXELS)
    }

    /// The scene with a frame every `period_ns` (at least 1 ms) and a camera of `pixels`
    /// (columns × rows, each at least 1): the same motion over `frames - 1` periods, so a
    /// faster cell is a shorter recording. The map is built from the rays of a camera of
    /// [`CAMERA_PIXELS`] whatever the cloud's resolution, as a mapper integrates a
    /// downsampled cloud.
    pub fn with_timing(grid: u32, frames: u32, period_ns: i64, pixels: [u32; 2]) -> Self {
        let frames = frames.max(2);
        let period_ns = period_ns.max(1_000_000);
        let pixels = pixels.map(|p| p.max(1));
        let duration = f64::from(frames - 1) * period_ns as f64 * 1e-9;
        Self {
            lattice: VoxelLattice::cube([0.0; 3], PERSON_CELL_DOMAIN_EDGE, grid),
            frames,
            period_ns,
            cell: super::machine_tool::bodies(duration),
            person: person(duration),
            camera: Camera::looking_at(CAMERA_POSITION, CAMERA_TARGET, pixels),
        }
    }

    /// The lattice of the cell's bodies.
    pub fn lattice(&self) -> &VoxelLattice {
        &self.lattice
    }

    /// Cell frames.
    pub fn frame_count(&self) -> u32 {
        self.frames
    }

    /// The cell's bodies (spindle, table, fixture).
    pub fn cell_bodies(&self) -> &[BodySpec] {
        &self.cell
    }

    /// The person's parts (body, three arm segments).
    pub fn person(&self) -> &[BodySpec] {
        &self.person
    }

    /// Stamp of cell frame `k` (ns since the epoch).
    pub fn stamp_ns(&self, k: u32) -> i64 {
        super::SCENE_START_NS + i64::from(k) * self.period_ns
    }

    /// How much later than its cell frame a cloud is stamped: [`CAMERA_DELAY_NS`], or a
    /// third of the frame period if that is shorter.
    pub fn camera_delay_ns(&self) -> i64 {
        CAMERA_DELAY_NS.min(self.period_ns / 3)
    }

    /// How much later than its cell frame a map is stamped: [`MAP_DELAY_NS`], or half the
    /// frame period if that is shorter.
    pub fn map_delay_ns(&self) -> i64 {
        MAP_DELAY_NS.min(self.period_ns / 2)
    }

    fn time_s(&self, k: u32) -> f64 {
        f64::from(k) * self.period_ns as f64 * 1e-9
    }

    /// Cell body `body`'s frame `k`, BITS.
    pub fn cell_frame(&self, body: usize, k: u32, raster: &mut Rasterizer) -> VoxelGrid {
        let spec = &self.cell[body];
        let l = &self.lattice;
        let mut data = Vec::new();
        raster.rasterize(
            &spec.shapes,
            spec.offset_at(self.time_s(k)),
            l,
            VoxelEncoding::Bits,
            &mut data,
        );
        VoxelGrid {
            header: Header {
                stamp: Time::from_nanos(self.stamp_ns(k)),
                frame_id: super::SCENE_FRAME_ID.to_owned(),
            },
            origin: Point {
                x: l.origin[0],
                y: l.origin[1],
                z: l.origin[2],
            },
            resolution: l.resolution,
            size_x: l.size[0],
            size_y: l.size[1],
            size_z: l.size[2],
            encoding: VoxelEncoding::Bits.code(),
            data,
        }
    }

    /// Where the camera's ray through pixel `(u, v)` first meets the person at time `t`, in
    /// `world` (sphere tracing: each step is the distance to the person, so no surface is
    /// stepped over).
    fn hit(&self, camera: &Camera, u: u32, v: u32, t: f64) -> Option<[f64; 3]> {
        let d = camera.ray(u, v);
        let o = camera.position;
        let mut s = 0.0;
        while s < MAX_RANGE {
            let p = [0, 1, 2].map(|i| o[i] + s * d[i]);
            let dist = self
                .person
                .iter()
                .map(|b| b.signed_distance(p, t))
                .fold(f64::INFINITY, f64::min);
            if dist < 1e-4 {
                return Some(p);
            }
            s += dist;
        }
        None
    }

    /// The points the camera sees on the person at the instant of cell frame `k`, row by row
    /// (`None` where a ray misses).
    pub fn camera_points(&self, k: u32) -> Vec<Option<[f64; 3]>> {
        self.points_seen_by(&self.camera, k)
    }

    fn points_seen_by(&self, camera: &Camera, k: u32) -> Vec<Option<[f64; 3]>> {
        use rayon::prelude::*;
        let t = self.time_s(k);
        let [w, h] = camera.pixels;
        (0..h)
            .into_par_iter()
            .flat_map_iter(|v| (0..w).map(move |u| (u, v)))
            .map(|(u, v)| self.hit(camera, u, v, t))
            .collect()
    }

    /// The camera's cloud of cell frame `k`'s instant, stamped [`CAMERA_DELAY_NS`] later: an
    /// organised cloud in [`CAMERA_FRAME`], x, y, z as FLOAT32 and a FLOAT32 `intensity`
    /// (the depth), 16 bytes a point, NaN where the ray misses.
    pub fn cloud(&self, k: u32) -> PointCloud2 {
        let [w, h] = self.camera.pixels;
        let mut data = Vec::with_capacity((w * h * 16) as usize);
        for p in self.camera_points(k) {
            let q = match p {
                Some(p) => {
                    let c = self.camera.to_optical(p);
                    [c[0] as f32, c[1] as f32, c[2] as f32, c[2] as f32]
                }
                None => [f32::NAN; 4],
            };
            data.extend(q.iter().flat_map(|v| v.to_le_bytes()));
        }
        PointCloud2 {
            header: Header {
                stamp: Time::from_nanos(self.stamp_ns(k) + self.camera_delay_ns()),
                frame_id: CAMERA_FRAME.to_owned(),
            },
            height: h,
            width: w,
            fields: ["x", "y", "z", "intensity"]
                .iter()
                .enumerate()
                .map(|(i, n)| PointField::new(*n, 4 * i as u32, PointField::FLOAT32, 1))
                .collect(),
            is_bigendian: false,
            point_step: 16,
            row_step: 16 * w,
            data,
            is_dense: false,
        }
    }

    /// `/tf_static`: the camera's optical frame in `world`.
    pub fn tf_static(&self) -> TFMessage {
        let q = self.camera.quaternion();
        let p = self.camera.position;
        TFMessage {
            transforms: vec![TransformStamped {
                header: Header {
                    stamp: Time::from_nanos(self.stamp_ns(0)),
                    frame_id: super::SCENE_FRAME_ID.to_owned(),
                },
                child_frame_id: CAMERA_FRAME.to_owned(),
                transform: Transform {
                    translation: Vector3::new(p[0], p[1], p[2]),
                    rotation: Quaternion {
                        x: q[0],
                        y: q[1],
                        z: q[2],
                        w: q[3],
                    },
                },
            }],
        }
    }

    /// The map built from the camera's rays at cell frame `k`'s instant, stamped
    /// [`MAP_DELAY_NS`] later: the cells the rays end in occupied, the cells they cross
    /// free (an occupied cell stays occupied).
    pub fn octomap(&self, k: u32) -> Octomap {
        let mut cells: Vec<(u64, bool)> = Vec::new();
        let key = |c: f64| -> Option<u32> {
            let k = (c / OCTREE_RESOLUTION).floor() + 32768.0;
            (0.0..65536.0).contains(&k).then_some(k as u32)
        };
        let keys = |p: [f64; 3]| -> Option<[u32; 3]> { Some([key(p[0])?, key(p[1])?, key(p[2])?]) };
        let o = self.camera.position;
        let mapper = Camera::looking_at(CAMERA_POSITION, CAMERA_TARGET, CAMERA_PIXELS);
        for p in self.points_seen_by(&mapper, k).into_iter().flatten() {
            let d = sub(p, o);
            let len = dot(d, d).sqrt();
            let end = keys(p);
            // Free cells along the ray, sampled at a quarter cell.
            let steps = (len / (OCTREE_RESOLUTION / 4.0)).ceil() as usize;
            for i in 0..steps {
                let s = i as f64 / steps as f64;
                if let Some(kk) = keys([0, 1, 2].map(|a| o[a] + s * d[a])) {
                    if Some(kk) != end {
                        cells.push((morton(kk), false));
                    }
                }
            }
            if let Some(kk) = end {
                cells.push((morton(kk), true));
            }
        }
        // Occupied wins: sort occupied after free, keep the last of each cell.
        cells.sort_unstable();
        let mut known: Vec<(u64, bool)> = Vec::with_capacity(cells.len());
        for c in cells {
            match known.last_mut() {
                Some(last) if last.0 == c.0 => last.1 |= c.1,
                _ => known.push(c),
            }
        }
        let mut data = Vec::new();
        write_binary(&known, 0, &mut data);
        Octomap {
            header: Header {
                stamp: Time::from_nanos(self.stamp_ns(k) + self.map_delay_ns()),
                frame_id: super::SCENE_FRAME_ID.to_owned(),
            },
            binary: true,
            id: "OcTree".into(),
            resolution: OCTREE_RESOLUTION,
            data,
        }
    }
}

/// The Morton code of a cell key: from the root down, 3 bits a level (x in bit 0, y in bit 1,
/// z in bit 2), the order OctoMap numbers a node's children in.
fn morton(k: [u32; 3]) -> u64 {
    let mut code = 0u64;
    for level in (0..16).rev() {
        let digit = (k[0] >> level & 1) | (k[1] >> level & 1) << 1 | (k[2] >> level & 1) << 2;
        code = code << 3 | u64::from(digit);
    }
    code
}

/// Writes the node at `depth` holding the cells of `cells` (sorted by Morton code, all under
/// it) as OctoMap's `writeBinaryNode` does: two bytes of 2-bit child codes (child `i` at bits
/// `2(i % 4)` of byte `i / 4`; `00` unknown, `01` free leaf, `10` occupied leaf, `11` inner),
/// then its inner children, depth first.
fn write_binary(cells: &[(u64, bool)], depth: u32, out: &mut Vec<u8>) {
    let shift = 3 * (15 - depth);
    let digit = |c: &(u64, bool)| (c.0 >> shift & 7) as usize;
    let mut bytes = [0u8; 2];
    let mut children: [&[(u64, bool)]; 8] = [&[]; 8];
    let mut rest = cells;
    for (i, child) in children.iter_mut().enumerate() {
        let n = rest.iter().take_while(|c| digit(c) == i).count();
        *child = &rest[..n];
        rest = &rest[n..];
    }
    for (i, child) in children.iter().enumerate() {
        let code = match (child.first(), depth) {
            (None, _) => 0b00,
            (Some(&(_, occupied)), 15) => {
                if occupied {
                    0b10
                } else {
                    0b01
                }
            }
            (Some(_), _) => 0b11,
        };
        bytes[i / 4] |= code << (2 * (i % 4));
    }
    out.extend_from_slice(&bytes);
    if depth < 15 {
        for child in children.iter().filter(|c| !c.is_empty()) {
            write_binary(child, depth + 1, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronotope_occupancy::{read_leaves, Limits, OctomapMsg, OctomapOptions};

    #[test]
    fn the_map_reads_back_as_the_cells_it_was_written_from() {
        let scene = PersonCell::new(32, 8);
        let map = scene.octomap(4);
        let msg = OctomapMsg {
            binary: true,
            id: &map.id,
            resolution: map.resolution,
            data: &map.data,
        };
        let mut occupied = Vec::new();
        let mut free = 0;
        read_leaves(&msg, &OctomapOptions::new(), &Limits::default(), |l| {
            assert_eq!(l.depth, 16);
            if l.occupied {
                occupied.push(l.key_min);
            } else {
                free += 1;
            }
        })
        .unwrap();
        // Every point the camera sees lies in an occupied cell.
        let pts: Vec<[f64; 3]> = scene.camera_points(4).into_iter().flatten().collect();
        assert!(pts.len() > 100, "{} points", pts.len());
        for p in &pts {
            let k = p.map(|c| ((c / OCTREE_RESOLUTION).floor() + 32768.0) as u32);
            assert!(occupied.contains(&k), "{p:?}");
        }
        assert!(free > occupied.len());
    }

    #[test]
    fn the_cloud_in_the_cameras_frame_comes_back_to_the_person() {
        let scene = PersonCell::new(32, 8);
        let tf = &scene.tf_static().transforms[0].transform;
        let q = [tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w];
        let t = [tf.translation.x, tf.translation.y, tf.translation.z];
        let back = chronotope_occupancy::RigidTransform::from_quaternion(q, t).unwrap();
        let cloud = scene.cloud(6);
        let seen = scene.camera_points(6);
        for (p, chunk) in seen.iter().zip(cloud.data.chunks_exact(16)) {
            let f = |i: usize| f32::from_le_bytes(chunk[4 * i..4 * i + 4].try_into().unwrap());
            match p {
                None => assert!(f(0).is_nan()),
                Some(p) => {
                    let w = back.apply([f(0), f(1), f(2)].map(f64::from));
                    for a in 0..3 {
                        assert!((w[a] - p[a]).abs() < 1e-5, "{w:?} vs {p:?}");
                    }
                }
            }
        }
    }
}
