//! The in-process transport: nodes in one process, messages passed by reference count.
//!
//! A message put on the bus reaches every node subscribed to its topic, in the order the
//! nodes were added; what they publish is delivered the same way, breadth first, before the
//! next input is taken. Everything is deterministic: the same inputs give the same messages
//! in the same order.

use std::collections::{BTreeMap, VecDeque};
use std::time::{Duration, Instant};

use super::{Message, Node, NodeStatus};

/// Nodes wired by topic.
pub struct Bus {
    nodes: Vec<Box<dyn Node>>,
    routes: BTreeMap<String, Vec<(usize, &'static str)>>,
    /// Wall time each node spent in its handlers (messages, ticks, finishing).
    busy: Vec<Duration>,
}

/// A message that reached a node of the wrong type for its subscription.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Misrouted {
    /// The topic.
    pub topic: String,
    /// The type the subscriber expects.
    pub expected: &'static str,
    /// The type that came.
    pub got: &'static str,
}

impl Bus {
    /// Wires `nodes` by their subscriptions.
    pub fn new(nodes: Vec<Box<dyn Node>>) -> Self {
        let mut routes: BTreeMap<String, Vec<(usize, &'static str)>> = BTreeMap::new();
        for (i, n) in nodes.iter().enumerate() {
            for s in n.subscriptions() {
                routes.entry(s.topic).or_default().push((i, s.type_name));
            }
        }
        let busy = vec![Duration::ZERO; nodes.len()];
        Self {
            nodes,
            routes,
            busy,
        }
    }

    /// Tells each node which of its publications are read: by a node of the bus, or
    /// `recorded` (the output bag). A replay calls this once, before the first message, so
    /// that what it records never depends on it.
    pub fn set_demand(&mut self, recorded: impl Fn(&str) -> bool) {
        for n in &mut self.nodes {
            for p in n.publications() {
                let read = self.routes.contains_key(&p.topic) || recorded(&p.topic);
                n.set_demand(&p.topic, read);
            }
        }
    }

    /// The type subscribers expect on `topic`, if anyone reads it.
    pub fn expected_type(&self, topic: &str) -> Option<&'static str> {
        self.routes.get(topic).and_then(|r| r.first()).map(|r| r.1)
    }

    /// Delivers `msg` and, transitively, what the nodes publish in response; `sink` sees
    /// every published message (not `msg` itself) in delivery order. Returns the messages that
    /// reached a subscriber expecting another type (they are not delivered to it).
    pub fn deliver(&mut self, msg: Message, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        let mut misrouted = Vec::new();
        let mut queue = VecDeque::from([msg]);
        let mut first = true;
        let mut out = Vec::new();
        while let Some(m) = queue.pop_front() {
            if !first {
                sink(&m);
            }
            first = false;
            if let Some(subs) = self.routes.get(&*m.topic) {
                for &(i, ty) in subs {
                    if ty != m.payload.type_name() {
                        misrouted.push(Misrouted {
                            topic: m.topic.to_string(),
                            expected: ty,
                            got: m.payload.type_name(),
                        });
                        continue;
                    }
                    let t = Instant::now();
                    self.nodes[i].on_message(&m, &mut out);
                    self.busy[i] += t.elapsed();
                    queue.extend(out.drain(..));
                }
            }
        }
        misrouted
    }

    /// Tells every node the inputs have ended, in increasing [`Node::rank`] (so a node's
    /// last messages reach the nodes after it first), delivering what they publish.
    pub fn finish(&mut self, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        let mut order: Vec<usize> = (0..self.nodes.len()).collect();
        order.sort_by_key(|&i| (self.nodes[i].rank(), i));
        let mut misrouted = Vec::new();
        for i in order {
            let mut out = Vec::new();
            let t = Instant::now();
            self.nodes[i].finish(&mut out);
            self.busy[i] += t.elapsed();
            for m in out {
                sink(&m);
                // Delivered to subscribers; `deliver` does not pass its own input to `sink`.
                misrouted.extend(self.deliver(m, sink));
            }
        }
        misrouted
    }

    /// Lets every node see the transport's clock (`now_ns`, monotonic), delivering what they
    /// publish in response (a live mesher closes a stream that went idle).
    pub fn tick(&mut self, now_ns: i64, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        let mut misrouted = Vec::new();
        for i in 0..self.nodes.len() {
            let mut out = Vec::new();
            let t = Instant::now();
            self.nodes[i].on_tick(now_ns, &mut out);
            self.busy[i] += t.elapsed();
            for m in out {
                sink(&m);
                misrouted.extend(self.deliver(m, sink));
            }
        }
        misrouted
    }

    /// Name and status of every node.
    pub fn statuses(&self) -> Vec<(&str, &NodeStatus)> {
        self.nodes.iter().map(|n| (n.name(), n.status())).collect()
    }

    /// Sets parameter `name` of the node named `node` while it runs.
    ///
    /// # Errors
    /// No such node, or the node's reason for refusing.
    pub fn set_parameter(
        &mut self,
        node: &str,
        name: &str,
        value: &super::launch::ParamValue,
    ) -> Result<(), String> {
        match self.nodes.iter_mut().find(|n| n.name() == node) {
            Some(n) => n.set_parameter(name, value),
            None => Err(format!("no node {node} here")),
        }
    }

    /// Name of every node and the wall time (s) it spent in its handlers so far (on the
    /// threads it ran on: a node whose work is split over rayon's pool counts its wall time
    /// once, not the pool's CPU time).
    pub fn busy_s(&self) -> Vec<(&str, f64)> {
        self.nodes
            .iter()
            .zip(&self.busy)
            .map(|(n, d)| (n.name(), d.as_secs_f64()))
            .collect()
    }

    /// The nodes.
    pub fn nodes(&self) -> &[Box<dyn Node>] {
        &self.nodes
    }
}
