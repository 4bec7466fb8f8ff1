//! Frames and poses: the aliases that name the space a value lives in, and the ROS
//! roll-pitch-yaw convention.
//!
//! Everything is `f64` and right-handed. A pose maps coordinates of a child frame into its
//! parent frame (`p_parent = pose * p_child`), as URDF `<origin>` and tf do.

use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// A rigid transform, child frame to parent frame.
pub type Pose = Isometry3<f64>;
/// A point in metres, in whatever frame the context names.
pub type Point = Point3<f64>;
/// A vector in metres (or a unit direction), in whatever frame the context names.
pub type Vector = Vector3<f64>;

/// The rotation of a URDF `rpy` triple or of a ROS roll/pitch/yaw:
/// R = Rz(yaw) · Ry(pitch) · Rx(roll), about fixed axes.
pub fn rpy_rotation(roll: f64, pitch: f64, yaw: f64) -> UnitQuaternion<f64> {
    // nalgebra applies roll, then pitch, then yaw about the fixed axes: exactly Rz·Ry·Rx.
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_euler_angles(roll, pitch, yaw))
}

/// A pose from a translation and a roll/pitch/yaw rotation (URDF `<origin xyz rpy>`).
pub fn pose_from_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Pose {
    Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        rpy_rotation(rpy[0], rpy[1], rpy[2]),
    )
}

/// The pose of the URDF's root link in the lattice frame: x, y, z in metres and roll, pitch,
/// yaw in radians, as ROS writes them (R = Rz(yaw) · Ry(pitch) · Rx(roll)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BasePose {
    /// Translation along x (m).
    pub x: f64,
    /// Translation along y (m).
    pub y: f64,
    /// Translation along z (m).
    pub z: f64,
    /// Rotation about the fixed x axis (rad), applied first.
    pub roll: f64,
    /// Rotation about the fixed y axis (rad), applied second.
    pub pitch: f64,
    /// Rotation about the fixed z axis (rad), applied last.
    pub yaw: f64,
}

impl BasePose {
    /// The identity: the root link's frame is the lattice frame.
    pub const IDENTITY: BasePose = BasePose {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        roll: 0.0,
        pitch: 0.0,
        yaw: 0.0,
    };

    /// A base pose from `[x, y, z, roll, pitch, yaw]`.
    pub fn from_array(v: [f64; 6]) -> Self {
        BasePose {
            x: v[0],
            y: v[1],
            z: v[2],
            roll: v[3],
            pitch: v[4],
            yaw: v[5],
        }
    }

    /// Whether all six numbers are finite.
    pub fn is_finite(&self) -> bool {
        [self.x, self.y, self.z, self.roll, self.pitch, self.yaw]
            .iter()
            .all(|v| v.is_finite())
    }

    /// The pose as a rigid transform, root link frame to lattice frame.
    pub fn to_pose(&self) -> Pose {
        pose_from_xyz_rpy([self.x, self.y, self.z], [self.roll, self.pitch, self.yaw])
    }
}
