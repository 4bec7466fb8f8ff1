//! The URDF robot description: the few elements this crate needs (links, their
//! `<collision>` elements, joints with origin, axis, limits and mimic), parsed from the
//! `/robot_description` text or a file and checked to be a tree.
//!
//! Relies on `roxmltree` for XML (DTDs refused, node count bounded). Visual, inertial,
//! material, transmission and extension elements (`<gazebo>`, `<ros2_control>`) are ignored.
//! Everything refused is a [`UrdfError`] naming the culprit.

mod error;
mod parse;
mod tree;

pub use error::UrdfError;

use crate::limits::Limits;
use crate::math::{Pose, Vector};
use nalgebra::Unit;
use std::io::Read;
use std::path::Path;

/// A parsed and checked URDF: links, joints, and the order in which forward kinematics
/// visits the joints.
#[derive(Clone, Debug)]
pub struct UrdfModel {
    /// The robot's `name`.
    pub name: String,
    /// The links, in document order.
    pub links: Vec<Link>,
    /// The joints, in document order.
    pub joints: Vec<Joint>,
    root: usize,
    order: Vec<usize>,
}

/// One link and its collision geometry.
#[derive(Clone, Debug)]
pub struct Link {
    /// The link's name.
    pub name: String,
    /// Its `<collision>` elements, in document order.
    pub collisions: Vec<Collision>,
    /// The joint whose child it is (`None` for the root).
    pub parent_joint: Option<usize>,
}

/// One `<collision>` element.
#[derive(Clone, Debug)]
pub struct Collision {
    /// Its `name`, if any.
    pub name: Option<String>,
    /// Its `<origin>`: geometry frame to link frame.
    pub origin: Pose,
    /// Its geometry.
    pub geometry: Geometry,
}

/// A collision geometry, in its own frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Geometry {
    /// A box centred on the origin, edges `size` along x, y, z (m).
    Box {
        /// Full edge lengths (m).
        size: [f64; 3],
    },
    /// A cylinder centred on the origin, its axis along z.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Length along z (m).
        length: f64,
    },
    /// A sphere centred on the origin.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// A mesh file, scaled about its origin.
    Mesh {
        /// The URI as written (`package://`, `file://` or a path).
        filename: String,
        /// Scale along x, y, z (1 1 1 when absent).
        scale: [f64; 3],
    },
}

/// The joint types supported.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis, with position limits.
    Revolute,
    /// Rotation about the axis, unlimited.
    Continuous,
    /// Translation along the axis, with position limits.
    Prismatic,
    /// No motion.
    Fixed,
}

impl JointKind {
    /// Whether the joint has a position (everything but fixed).
    pub fn is_movable(self) -> bool {
        self != JointKind::Fixed
    }
}

/// Position limits of a revolute or prismatic joint ((rad) or (m)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointLimits {
    /// Lowest position.
    pub lower: f64,
    /// Highest position.
    pub upper: f64,
}

/// A `<mimic>` element: position = multiplier · position(joint) + offset.
#[derive(Clone, Debug, PartialEq)]
pub struct Mimic {
    /// Index (in [`UrdfModel::joints`]) of the joint followed.
    pub joint: usize,
    /// Multiplier (1 when absent).
    pub multiplier: f64,
    /// Offset (0 when absent).
    pub offset: f64,
}

/// One joint.
#[derive(Clone, Debug)]
pub struct Joint {
    /// The joint's name.
    pub name: String,
    /// Its type.
    pub kind: JointKind,
    /// Index of the parent link.
    pub parent: usize,
    /// Index of the child link.
    pub child: usize,
    /// Its `<origin>`: joint frame (at zero position) to parent link frame.
    pub origin: Pose,
    /// Its axis in the joint frame, normalised (1 0 0 when absent).
    pub axis: Unit<Vector>,
    /// Position limits (revolute and prismatic only).
    pub limits: Option<JointLimits>,
    /// Whether, and how, it follows another joint.
    pub mimic: Option<Mimic>,
}

impl UrdfModel {
    /// Parses and checks a URDF text (the `/robot_description` message's text), with the
    /// default [`Limits`].
    ///
    /// # Errors
    /// Any [`UrdfError`]: malformed XML, unexpanded xacro, unsupported joints or geometry,
    /// values out of domain, a graph that is not a tree, bad mimic joints, limits.
    pub fn parse(text: &str) -> Result<Self, UrdfError> {
        Self::parse_with_limits(text, &Limits::default())
    }

    /// As [`parse`](Self::parse), with the caller's limits.
    ///
    /// # Errors
    /// As [`parse`](Self::parse).
    pub fn parse_with_limits(text: &str, limits: &Limits) -> Result<Self, UrdfError> {
        if text.len() > limits.urdf_bytes {
            return Err(UrdfError::TooLarge {
                bytes: text.len() as u64,
                limit: limits.urdf_bytes as u64,
            });
        }
        let parsed = parse::parse(text, limits)?;
        tree::build(parsed)
    }

    /// Reads a URDF file and parses it as [`parse`](Self::parse) does. Relative mesh
    /// paths in it are relative to the file's directory (the robot loader uses it).
    ///
    /// # Errors
    /// [`UrdfError::Io`] if the file cannot be read, [`UrdfError::TooLarge`] over the
    /// limit, and everything [`parse`](Self::parse) refuses.
    pub fn from_file(path: &Path, limits: &Limits) -> Result<Self, UrdfError> {
        let text = read_text_bounded(path, limits.urdf_bytes as u64)?;
        Self::parse_with_limits(&text, limits)
    }

    /// Index of the root link (the one without a parent joint).
    pub fn root(&self) -> usize {
        self.root
    }

    /// Joint indices, each joint after the joint of its parent link: the order forward
    /// kinematics visits them.
    pub fn joint_order(&self) -> &[usize] {
        &self.order
    }

    /// Index of the link of that name.
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.links.iter().position(|l| l.name == name)
    }

    /// Index of the joint of that name.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }
}

impl std::str::FromStr for UrdfModel {
    type Err = UrdfError;

    /// As [`UrdfModel::parse`].
    fn from_str(text: &str) -> Result<Self, UrdfError> {
        Self::parse(text)
    }
}

fn read_text_bounded(path: &Path, limit: u64) -> Result<String, UrdfError> {
    let io = |source| UrdfError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    if len > limit {
        return Err(UrdfError::TooLarge { bytes: len, limit });
    }
    let mut text = String::new();
    // The file may grow between the metadata and the read: read at most limit + 1 bytes.
    file.take(limit + 1).read_to_string(&mut text).map_err(io)?;
    if text.len() as u64 > limit {
        return Err(UrdfError::TooLarge {
            bytes: text.len() as u64,
            limit,
        });
    }
    Ok(text)
}
