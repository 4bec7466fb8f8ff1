//! Static transforms (`/tf_static`): where the robot's root link stands in the lattice's
//! frame, found by walking from the root up the transforms to the lattice frame.

use std::collections::BTreeMap;

use chronotope_robot::math::Pose;
use nalgebra::{Quaternion, Translation3, UnitQuaternion};

use chronotope_msg::TFMessage;

/// Child frames kept (`MAX_TF_FRAMES`): a static tree of a cell has tens.
pub const MAX_TF_FRAMES: usize = 4096;

/// Longest chain walked from the root to the lattice frame.
const MAX_CHAIN: usize = 64;

/// The static transforms received so far: each child frame's parent and pose in it.
#[derive(Debug, Default)]
pub(super) struct StaticTree {
    parent: BTreeMap<String, (String, Pose)>,
}

/// What one `/tf_static` message did.
#[derive(Debug, Default, PartialEq, Eq)]
pub(super) struct Added {
    /// Transforms stored (new or replaced).
    pub stored: usize,
    /// Refused: not finite, a zero quaternion, or past `MAX_TF_FRAMES`.
    pub refused: Vec<String>,
}

impl StaticTree {
    /// Stores the message's transforms (a child's newer transform replaces its older one, as
    /// tf2 keeps the latest static transform per child).
    pub fn add(&mut self, m: &TFMessage) -> Added {
        let mut a = Added::default();
        for t in &m.transforms {
            let tr = &t.transform.translation;
            let q = &t.transform.rotation;
            let values = [tr.x, tr.y, tr.z, q.x, q.y, q.z, q.w];
            let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
            if !values.iter().all(|v| v.is_finite()) || norm < 1e-9 {
                a.refused.push(format!(
                    "{} -> {}: not a finite pose with a non-zero quaternion",
                    t.header.frame_id, t.child_frame_id
                ));
                continue;
            }
            if !self.parent.contains_key(&t.child_frame_id) && self.parent.len() >= MAX_TF_FRAMES {
                a.refused.push(format!(
                    "{}: more than MAX_TF_FRAMES = {MAX_TF_FRAMES} child frames",
                    t.child_frame_id
                ));
                continue;
            }
            let pose = Pose::from_parts(
                Translation3::new(tr.x, tr.y, tr.z),
                UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z)),
            );
            self.parent.insert(
                t.child_frame_id.trim_start_matches('/').to_owned(),
                (t.header.frame_id.trim_start_matches('/').to_owned(), pose),
            );
            a.stored += 1;
        }
        a
    }

    /// The pose of frame `child` in frame `root_frame` (`None` while no chain of transforms
    /// joins them; a loop or an over-long chain joins nothing).
    pub fn pose_of(&self, child: &str, root_frame: &str) -> Option<Pose> {
        let (child, root_frame) = (
            child.trim_start_matches('/'),
            root_frame.trim_start_matches('/'),
        );
        let mut pose = Pose::identity();
        let mut at = child;
        for _ in 0..MAX_CHAIN {
            if at == root_frame {
                return Some(pose);
            }
            let (parent, p) = self.parent.get(at)?;
            pose = p * pose;
            at = parent;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronotope_msg::{Quaternion as Q, TransformStamped, Vector3};

    fn t(parent: &str, child: &str, x: f64) -> TransformStamped {
        let mut t = TransformStamped::default();
        t.header.frame_id = parent.into();
        t.child_frame_id = child.into();
        t.transform.translation = Vector3::new(x, 0.0, 0.0);
        t.transform.rotation = Q::IDENTITY;
        t
    }

    #[test]
    fn a_chain_of_static_transforms_gives_the_root_pose_and_loops_give_none() {
        let mut tree = StaticTree::default();
        let a = tree.add(&TFMessage {
            transforms: vec![t("world", "cell", 1.0), t("cell", "base_link", 0.5)],
        });
        assert_eq!(a.stored, 2);
        let p = tree.pose_of("base_link", "world").unwrap();
        assert!((p.translation.vector.x - 1.5).abs() < 1e-12);
        assert!(tree.pose_of("base_link", "map").is_none());
        assert!(tree.pose_of("world", "world").is_some());
        tree.add(&TFMessage {
            transforms: vec![t("base_link", "cell", 0.1)],
        });
        assert!(
            tree.pose_of("base_link", "world").is_none(),
            "a loop joins nothing"
        );
        let mut bad = t("world", "x", f64::NAN);
        bad.transform.rotation = Q::IDENTITY;
        let a = tree.add(&TFMessage {
            transforms: vec![bad],
        });
        assert_eq!(a.refused.len(), 1);
    }
}
