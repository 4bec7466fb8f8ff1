//! What `chronotope info` says about a robot recorded the ROS way: its description
//! (`std_msgs/String` on a `…robot_description` topic, parsed as URDF without loading its
//! meshes) and its joint states (`sensor_msgs/JointState`: rate per instant, partial
//! messages), which become a body through a robot node.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::msg::{decode_cdr, JointState, RosMessage, RosString};

/// A robot found in a bag.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct RobotInfo {
    /// The description's topic.
    pub description_topic: String,
    /// The URDF's robot name (`None` when it is refused).
    pub name: Option<String>,
    /// Links of the URDF.
    pub links: usize,
    /// Its movable joints that are not mimics (what joint states give).
    pub joints: usize,
    /// Why the URDF is refused, if it is (the robot node would refuse it too).
    pub refused: Option<String>,
    /// The joint-state topics: topic → what they hold.
    pub joint_states: BTreeMap<String, JointStatesInfo>,
    /// Whether the bag has `/tf_static` (where the robot stands, unless `base_pose` says).
    pub tf_static: bool,
}

/// One joint-state topic.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct JointStatesInfo {
    /// Messages.
    pub messages: u64,
    /// Distinct instants (header stamps): a controller publishing its joints in several
    /// messages per instant has fewer instants than messages.
    pub instants: u64,
    /// Instants per second (`None` below two).
    pub rate_hz: Option<f64>,
    /// Distinct joint names seen (at most 256 kept).
    pub joint_names: Vec<String>,
    /// Messages that do not decode.
    pub undecodable: u64,
}

/// Joint names kept per topic.
const MAX_NAMES: usize = 256;

/// Accumulates robot topics during `info`'s one pass.
#[derive(Default)]
pub(super) struct RobotAcc {
    /// Latest description text per topic (bounded by the URDF limit: a longer one is not kept).
    descriptions: BTreeMap<String, String>,
    joint_states: BTreeMap<String, (JointStatesInfo, Option<i64>, Option<i64>, Option<i64>)>,
    tf_static: bool,
}

impl RobotAcc {
    /// Looks at one message.
    pub fn message(&mut self, topic: &str, schema: &str, data: &[u8]) {
        if schema == crate::msg::TFMessage::TYPE_NAME && topic == "/tf_static" {
            self.tf_static = true;
        }
        if schema == RosString::TYPE_NAME && topic.ends_with("robot_description") {
            if data.len() <= chronotope_robot::limits::MAX_URDF_BYTES + 16 {
                if let Ok(s) = decode_cdr::<RosString>(data) {
                    self.descriptions.insert(topic.to_owned(), s.data);
                }
            }
            return;
        }
        if schema != JointState::TYPE_NAME {
            return;
        }
        let (info, first, last, prev) = self.joint_states.entry(topic.to_owned()).or_default();
        info.messages += 1;
        let Ok(m) = decode_cdr::<JointState>(data) else {
            info.undecodable += 1;
            return;
        };
        let t = m.header.stamp.as_nanos();
        if *prev != Some(t) {
            info.instants += 1;
            *prev = Some(t);
            *first = Some(first.map_or(t, |f| f.min(t)));
            *last = Some(last.map_or(t, |l| l.max(t)));
        }
        for n in m.name {
            if info.joint_names.len() < MAX_NAMES && !info.joint_names.contains(&n) {
                info.joint_names.push(n);
            }
        }
    }

    /// The robots found: one per description topic, with every joint-state topic.
    pub fn finish(self) -> Vec<RobotInfo> {
        let joint_states: BTreeMap<String, JointStatesInfo> = self
            .joint_states
            .into_iter()
            .map(|(topic, (mut info, first, last, _))| {
                if let (Some(f), Some(l)) = (first, last) {
                    if info.instants > 1 && l > f {
                        info.rate_hz = Some((info.instants - 1) as f64 / ((l - f) as f64 * 1e-9));
                    }
                }
                (topic, info)
            })
            .collect();
        self.descriptions
            .into_iter()
            .map(|(topic, text)| {
                let (name, links, joints, refused) = match chronotope_robot::UrdfModel::parse(&text)
                {
                    Ok(m) => {
                        let joints = chronotope_robot::Kinematics::new(m.clone()).dof();
                        (Some(m.name.clone()), m.links.len(), joints, None)
                    }
                    Err(e) => (None, 0, 0, Some(e.to_string())),
                };
                RobotInfo {
                    description_topic: topic,
                    name,
                    links,
                    joints,
                    refused,
                    joint_states: joint_states.clone(),
                    tf_static: self.tf_static,
                }
            })
            .collect()
    }
}

/// The human-readable lines for the robots.
pub(super) fn text(robots: &[RobotInfo]) -> String {
    let mut o = String::new();
    if robots.is_empty() {
        return o;
    }
    o.push_str(&format!(
        "Robots (a robot description and joint states; each becomes a body through a node \
         with `exec: robot`): {}\n",
        robots.len()
    ));
    for r in robots {
        match (&r.name, &r.refused) {
            (Some(n), _) => o.push_str(&format!(
                "  robot: {n} ({}), {} links, {} joints",
                r.description_topic, r.links, r.joints
            )),
            (None, Some(why)) => o.push_str(&format!(
                "  robot on {}: its URDF is refused: {why}",
                r.description_topic
            )),
            (None, None) => {}
        }
        o.push('\n');
        if r.joint_states.is_empty() {
            o.push_str("    no joint states: give a plan (trajectory_topic) to see it move\n");
        }
        for (topic, j) in &r.joint_states {
            let rate = j
                .rate_hz
                .map_or_else(|| "-".to_owned(), |h| format!("{h:.1} Hz"));
            let per = if j.instants > 0 && j.messages > j.instants {
                format!(
                    ", {:.1} messages per instant (partial, merged by name)",
                    j.messages as f64 / j.instants as f64
                )
            } else {
                String::new()
            };
            o.push_str(&format!(
                "    joint states at {rate} on {topic}: {} messages, {} joints named{per}\n",
                j.messages,
                j.joint_names.len()
            ));
        }
        o.push_str(&format!(
            "    where it stands: {}\n",
            if r.tf_static {
                "/tf_static (or the robot node's base_pose)"
            } else {
                "no /tf_static: give the robot node's base_pose"
            }
        ));
    }
    o
}
