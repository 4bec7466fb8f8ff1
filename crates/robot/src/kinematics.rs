//! Forward kinematics: the pose of every link in the lattice frame, from the positions of
//! the robot's independent joints and the base pose.
//!
//! Independent joints are the movable joints that do not mimic another, in URDF document
//! order; a mimic joint's position is `multiplier · position(followed) + offset`, composed
//! along chains of mimics. Relies on the tree order checked by [`crate::urdf`].

use crate::math::{BasePose, Pose};
use crate::urdf::{JointKind, JointLimits, UrdfModel};
use nalgebra::{Translation3, UnitQuaternion};

/// How one URDF joint gets its position.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Source {
    /// Fixed: no position.
    None,
    /// Its own entry in the independent positions.
    Independent(usize),
    /// `multiplier · positions[index] + offset`.
    Mimic {
        index: usize,
        multiplier: f64,
        offset: f64,
    },
}

/// The robot's kinematic tree, ready to pose links.
#[derive(Clone, Debug)]
pub struct Kinematics {
    model: UrdfModel,
    names: Vec<String>,
    independent: Vec<usize>,
    sources: Vec<Source>,
}

/// A joint position outside the joint's URDF limits (kept, not clamped).
#[derive(Clone, Debug, PartialEq)]
pub struct LimitViolation {
    /// The joint's name.
    pub joint: String,
    /// Its position.
    pub position: f64,
    /// Its limits.
    pub limits: JointLimits,
}

/// The pose of every link in the lattice frame, indexed as [`UrdfModel::links`]. Reused
/// from frame to frame.
#[derive(Clone, Debug, Default)]
pub struct LinkPoses {
    poses: Vec<Pose>,
}

impl LinkPoses {
    /// An empty set, sized on first use.
    pub fn new() -> Self {
        Self::default()
    }

    /// The pose of link `link` (index in [`UrdfModel::links`]).
    ///
    /// # Panics
    /// If `link` is out of range or no forward kinematics has filled the set.
    pub fn get(&self, link: usize) -> &Pose {
        &self.poses[link]
    }

    /// All poses, indexed as the model's links.
    pub fn as_slice(&self) -> &[Pose] {
        &self.poses
    }
}

impl Kinematics {
    /// Builds the kinematics of a checked model.
    pub fn new(model: UrdfModel) -> Self {
        let mut independent = Vec::new();
        let mut names = Vec::new();
        let mut slot = vec![usize::MAX; model.joints.len()];
        for (ji, j) in model.joints.iter().enumerate() {
            if j.kind.is_movable() && j.mimic.is_none() {
                slot[ji] = independent.len();
                independent.push(ji);
                names.push(j.name.clone());
            }
        }
        let sources = (0..model.joints.len())
            .map(|ji| {
                let j = &model.joints[ji];
                if !j.kind.is_movable() {
                    return Source::None;
                }
                let (mut at, mut multiplier, mut offset) = (ji, 1.0, 0.0);
                // Chains were checked acyclic; compose a·(b·q + c) + d.
                while let Some(m) = &model.joints[at].mimic {
                    offset += multiplier * m.offset;
                    multiplier *= m.multiplier;
                    at = m.joint;
                }
                if at == ji {
                    Source::Independent(slot[ji])
                } else {
                    Source::Mimic {
                        index: slot[at],
                        multiplier,
                        offset,
                    }
                }
            })
            .collect();
        Kinematics {
            model,
            names,
            independent,
            sources,
        }
    }

    /// The model.
    pub fn model(&self) -> &UrdfModel {
        &self.model
    }

    /// Names of the independent joints: the order of every position slice this crate takes.
    pub fn joint_names(&self) -> &[String] {
        &self.names
    }

    /// Number of independent joints.
    pub fn dof(&self) -> usize {
        self.independent.len()
    }

    /// Index (in [`joint_names`](Self::joint_names)) of an independent joint.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// Whether `name` is a mimic joint (its position follows another; given values are
    /// ignored, as robot_state_publisher does).
    pub fn is_mimic(&self, name: &str) -> bool {
        self.model
            .joint_index(name)
            .is_some_and(|ji| matches!(self.sources[ji], Source::Mimic { .. }))
    }

    /// URDF joint index of independent joint `i`.
    pub fn urdf_joint(&self, i: usize) -> usize {
        self.independent[i]
    }

    /// The position of URDF joint `joint` (0 for fixed joints), given the independent
    /// positions.
    pub fn joint_position(&self, positions: &[f64], joint: usize) -> f64 {
        match self.sources[joint] {
            Source::None => 0.0,
            Source::Independent(i) => positions[i],
            Source::Mimic {
                index,
                multiplier,
                offset,
            } => multiplier * positions[index] + offset,
        }
    }

    /// Poses every link in the lattice frame: `base` is the root link's pose.
    ///
    /// # Panics
    /// If `positions.len()` differs from [`dof`](Self::dof).
    pub fn forward(&self, positions: &[f64], base: &BasePose, out: &mut LinkPoses) {
        self.forward_from(positions, &base.to_pose(), out);
    }

    /// As [`forward`](Self::forward), with the base pose as a transform.
    ///
    /// # Panics
    /// If `positions.len()` differs from [`dof`](Self::dof).
    pub fn forward_from(&self, positions: &[f64], base: &Pose, out: &mut LinkPoses) {
        assert_eq!(
            positions.len(),
            self.dof(),
            "one position per independent joint"
        );
        out.poses.clear();
        out.poses.resize(self.model.links.len(), Pose::identity());
        out.poses[self.model.root()] = *base;
        for &ji in self.model.joint_order() {
            let j = &self.model.joints[ji];
            let q = self.joint_position(positions, ji);
            let motion = match j.kind {
                JointKind::Fixed => Pose::identity(),
                JointKind::Revolute | JointKind::Continuous => Pose::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_axis_angle(&j.axis, q),
                ),
                JointKind::Prismatic => Pose::from_parts(
                    Translation3::from(j.axis.into_inner() * q),
                    UnitQuaternion::identity(),
                ),
            };
            out.poses[j.child] = out.poses[j.parent] * j.origin * motion;
        }
    }

    /// Positions outside their joint's limits (independent and mimic joints), appended to
    /// `out`. Positions are never clamped; the caller counts and warns.
    pub fn limit_violations(&self, positions: &[f64], out: &mut Vec<LimitViolation>) {
        for (ji, j) in self.model.joints.iter().enumerate() {
            let Some(limits) = j.limits else { continue };
            let q = self.joint_position(positions, ji);
            if q < limits.lower || q > limits.upper {
                out.push(LimitViolation {
                    joint: j.name.clone(),
                    position: q,
                    limits,
                });
            }
        }
    }
}
