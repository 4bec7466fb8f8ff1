//! The suite's nodes for a launch config: which node each entry makes, the bodies they
//! share (a bag's, a robot's, a sensor's), the meshers and checkers wired to them, and the
//! recorder's selection. `replay`, `launch` and the benchmarks build their nodes here.

use std::collections::BTreeSet;

use super::carving::CarvingNode;
use super::checker::CheckerNode;
use super::launch::{LaunchConfig, LaunchError, NodeKind, NodeSpec, Params};
use super::mesher::MesherNode;
use super::occupancy::OccupancyNode;
use super::robot::RobotNode;
use super::Node;

/// Which published topics go to the output bag.
#[derive(Debug, Clone, Default)]
pub struct Selection {
    only: Option<BTreeSet<String>>,
    exclude: BTreeSet<String>,
}

impl Selection {
    /// The recorder entry's `topics` and `exclude` parameters.
    ///
    /// # Errors
    /// A bad parameter.
    pub fn from_spec(spec: &NodeSpec) -> Result<Self, LaunchError> {
        let mut p = Params::of(spec);
        let only = p.topics("topics")?.map(|v| v.into_iter().collect());
        let exclude = p
            .topics("exclude")?
            .unwrap_or_default()
            .into_iter()
            .collect();
        p.finish()?;
        Ok(Self { only, exclude })
    }

    /// Whether `topic` goes to the output bag.
    pub fn wants(&self, topic: &str) -> bool {
        let listed = match &self.only {
            Some(o) => o.contains(topic),
            // Hidden topics (between the parts of one node) only when named.
            None => !crate::is_hidden_topic(topic),
        };
        listed && !self.exclude.contains(topic)
    }
}

/// The suite's nodes for `config`, over a bag whose VoxelGrid topics are `bag_bodies`.
///
/// # Errors
/// A bad parameter or an inconsistent config.
pub fn build_nodes(
    config: &LaunchConfig,
    bag_bodies: &[String],
    default_movable_first: bool,
) -> Result<(Vec<Box<dyn Node>>, Selection), LaunchError> {
    let mut nodes: Vec<Box<dyn Node>> = Vec::new();
    let mut bodies: Vec<String> = bag_bodies.to_vec();
    // Bodies seen by a sensor: never the default movable body (no program moves them).
    let mut sensed: Vec<String> = Vec::new();
    for spec in config.of_kind(NodeKind::Carving) {
        let mut c = CarvingNode::from_spec(spec)?;
        let display = c.display().map_err(|e| LaunchError::Param {
            node: spec.fqn.clone(),
            param: "workpiece_max".into(),
            reason: e.to_string(),
        })?;
        bodies.push(c.occupancy_topic().to_owned());
        nodes.push(Box::new(c));
        nodes.push(Box::new(display));
    }
    // A robot's bodies are bodies of the cell like the bag's.
    for spec in config.of_kind(NodeKind::Robot) {
        let r = RobotNode::from_spec(spec)?;
        for t in r.body_topics() {
            if !bodies.iter().any(|b| b == t) {
                bodies.push(t.to_owned());
            }
        }
        nodes.push(Box::new(r));
    }
    for spec in config.of_kind(NodeKind::Occupancy) {
        let n = OccupancyNode::from_spec(spec)?;
        bodies.push(n.occupancy_topic().to_owned());
        sensed.push(n.occupancy_topic().to_owned());
        nodes.push(Box::new(n));
    }
    let mut meshers: Vec<MesherNode> = config
        .of_kind(NodeKind::Mesher)
        .map(|s| MesherNode::from_spec(s, &bodies))
        .collect::<Result<_, _>>()?;
    let meshed: Vec<String> = meshers
        .iter()
        .flat_map(|m| m.bodies().map(str::to_owned))
        .collect();
    let mut checkers = Vec::new();
    for spec in config.of_kind(NodeKind::Checker) {
        let mut spec = spec.clone();
        // (With one body there is no pair, so no movable body by default.)
        if default_movable_first && meshed.len() >= 2 && !spec.params.contains_key("movable") {
            let mut sorted: Vec<String> = meshed
                .iter()
                .filter(|b| !sensed.contains(b))
                .cloned()
                .collect();
            sorted.sort();
            if let Some(first) = sorted.first() {
                spec.params.insert(
                    "movable".into(),
                    crate::launch::ParamValue::StringArray(vec![first.clone()]),
                );
            }
        }
        checkers.push(CheckerNode::from_spec(&spec, &meshed)?);
    }
    // Each checker's markers (if asked for) are sliced by a part of its own, after it.
    let marker_parts: Vec<_> = checkers
        .iter()
        .filter_map(CheckerNode::markers_part)
        .collect();
    if !checkers.is_empty() {
        let used: BTreeSet<String> = checkers
            .iter()
            .flat_map(|c| c.bodies().map(str::to_owned))
            .collect();
        for c in &checkers {
            if let Some(b) = c.bodies().find(|b| !meshed.iter().any(|m| m == b)) {
                return Err(LaunchError::Param {
                    node: c.name().to_owned(),
                    param: "pairs".into(),
                    reason: format!("{b} is meshed by no mesher"),
                });
            }
            if !meshers.iter().any(|m| m.slab_topic() == c.mesh_topic()) {
                return Err(LaunchError::Param {
                    node: c.name().to_owned(),
                    param: "mesh_topic".into(),
                    reason: format!("no mesher publishes {}", c.mesh_topic()),
                });
            }
        }
        for m in &mut meshers {
            let dropped: Vec<String> = m
                .bodies()
                .filter(|b| !used.contains(*b))
                .map(str::to_owned)
                .collect();
            if !dropped.is_empty() && !used.is_empty() {
                tracing::info!(
                    node = m.name(),
                    "not meshed (in no checked pair): {}",
                    dropped.join(", ")
                );
            }
            if !used.is_empty() {
                m.retain_bodies(|b| used.contains(b));
            }
        }
    }
    nodes.extend(meshers.into_iter().map(|m| Box::new(m) as Box<dyn Node>));
    nodes.extend(checkers.into_iter().map(|c| Box::new(c) as Box<dyn Node>));
    nodes.extend(
        marker_parts
            .into_iter()
            .map(|c| Box::new(c) as Box<dyn Node>),
    );
    // One topic, one message type: a config that routes a topic to two meanings is refused.
    let uses = crate::routes::topic_uses(config, &nodes);
    crate::routes::check_topic_types(&uses)?;
    let selection = match config.of_kind(NodeKind::Recorder).next() {
        Some(spec) => Selection::from_spec(spec)?,
        None => Selection::default(),
    };
    Ok((nodes, selection))
}
