//! Which topics a launch's nodes read and write, with the message type each expects, and
//! the check that no topic means two things.
//!
//! A topic carries one message type. A config that routes one topic to two meanings — a
//! carving node's `pose_topic` set to a body's VoxelGrid topic, a checker's `mesh_topic` set
//! to a wrench — would make a node take messages meant for another (or drop them all as
//! the wrong type); it is refused with both uses named. The same list lets a replay check a
//! bag's topics against what the nodes read ([`check_bag_types`]).

use std::collections::BTreeMap;

use super::launch::{LaunchConfig, LaunchError, NodeSpec, ParamValue, Params};
use super::Node;

/// One topic a node reads or writes.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct TopicUse {
    /// Fully qualified topic name.
    pub topic: String,
    /// `pkg/msg/Type` the node reads or writes on it.
    pub type_name: &'static str,
    /// The node's fully qualified name.
    pub node: String,
    /// What names the topic: `parameter pose_topic`, `remap from ~/report`, `fixed name`,
    /// or `default` (a parameter left out).
    pub source: String,
    /// Whether the node publishes it (else it reads it).
    pub publishes: bool,
}

impl std::fmt::Display for TopicUse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} {} it as {} ({})",
            self.node,
            if self.publishes { "publishes" } else { "reads" },
            self.type_name,
            self.source
        )
    }
}

/// Every topic the built `nodes` read and write, with what in `config` names it, sorted by
/// topic, node and direction.
pub fn topic_uses(config: &LaunchConfig, nodes: &[Box<dyn Node>]) -> Vec<TopicUse> {
    let mut uses = Vec::new();
    for n in nodes {
        let spec = config.nodes.iter().find(|s| s.fqn == n.name());
        for (publishes, refs) in [(false, n.subscriptions()), (true, n.publications())] {
            for r in refs {
                let source = spec.map_or_else(|| "default".to_owned(), |s| source_of(s, &r.topic));
                uses.push(TopicUse {
                    topic: r.topic,
                    type_name: r.type_name,
                    node: n.name().to_owned(),
                    source,
                    publishes,
                });
            }
        }
    }
    uses.sort();
    uses.dedup();
    uses
}

/// What in `spec` names `topic`: a parameter whose value (or one of its words: a checker's
/// pairs are `"a b"`) resolves to it, a remap to it, the node's fixed name, or a default.
fn source_of(spec: &NodeSpec, topic: &str) -> String {
    let p = Params::of(spec);
    let names = |v: &ParamValue| -> Vec<String> {
        match v {
            ParamValue::String(s) => s.split_whitespace().map(str::to_owned).collect(),
            ParamValue::StringArray(a) => a
                .iter()
                .flat_map(|s| s.split_whitespace().map(str::to_owned))
                .collect(),
            _ => Vec::new(),
        }
    };
    for (param, v) in &spec.params {
        if names(v)
            .iter()
            .any(|t| p.resolve(param, t).is_ok_and(|r| r == topic))
        {
            return format!("parameter {param}");
        }
    }
    if let Some((from, _)) = spec.remaps.iter().find(|(_, to)| *to == topic) {
        return format!("remapped from {from}");
    }
    if topic.starts_with(&format!("{}/", spec.fqn)) {
        return "its fixed name".into();
    }
    "default".into()
}

/// Refuses a topic used with two message types (read or written), naming both uses.
///
/// # Errors
/// [`LaunchError::TopicTypes`] for the first such topic.
pub fn check_topic_types(uses: &[TopicUse]) -> Result<(), LaunchError> {
    let mut first: BTreeMap<&str, &TopicUse> = BTreeMap::new();
    for u in uses {
        match first.get(u.topic.as_str()) {
            None => {
                first.insert(&u.topic, u);
            }
            Some(f) if f.type_name != u.type_name => {
                return Err(LaunchError::TopicTypes {
                    topic: u.topic.clone(),
                    first: f.to_string(),
                    second: u.to_string(),
                });
            }
            Some(_) => {}
        }
    }
    Ok(())
}

/// Refuses a topic a node reads whose messages in a bag are of another type (`bag_topics`:
/// each topic with its schema name, `pkg/msg/Type`).
///
/// # Errors
/// [`LaunchError::TopicTypes`] naming the topic, the node's use and the bag's type.
pub fn check_bag_types<'a>(
    uses: &[TopicUse],
    bag_topics: impl IntoIterator<Item = (&'a str, &'a str)>,
) -> Result<(), LaunchError> {
    for (topic, schema) in bag_topics {
        if let Some(u) = uses
            .iter()
            .find(|u| !u.publishes && u.topic == topic && u.type_name != schema)
        {
            return Err(LaunchError::TopicTypes {
                topic: topic.to_owned(),
                first: format!("the bag carries {}", chronotope_yaml::cut(schema)),
                second: u.to_string(),
            });
        }
    }
    Ok(())
}
