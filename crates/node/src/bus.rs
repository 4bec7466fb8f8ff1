//! The in-process transport: nodes in one process, messages passed by reference count.
//!
//! A message put on the bus reaches every node subscribed to its topic, in the order the
//! nodes were added; what they publish is delivered the same way, breadth first, before the
//! next input is taken. Everything is deterministic: the same inputs give the same messages
//! in the same order.
//!
//! A node whose inputs all come from outside the bus can be run ahead on a thread of its own
//! ([`Bus::run_ahead`]): it is handed each input as the input is put on the bus
//! ([`Bus::put`]), while the bus still delivers up to `depth` inputs before it. What it
//! publishes is taken in the input's turn, so the messages and their order are the same.
//!
//! A node whose publications no node of the bus reads (the checker's markers part) can be
//! run behind on a thread of its own ([`Bus::run_behind`]): it is handed each input in its
//! turn and the bus goes on; what it publishes is given to the sink where its turn put it,
//! the messages after it held back until it has answered. Again the messages and their
//! order are the same.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::time::{Duration, Instant};

use std::sync::mpsc;

use super::ahead::{AheadNode, Event, Feed, Reply};
use super::{Message, Node, NodeStatus, ParamError};

/// Nodes wired by topic.
pub struct Bus {
    nodes: Vec<Box<dyn Node>>,
    routes: BTreeMap<String, Vec<(usize, &'static str)>>,
    /// Wall time each node spent in its handlers (messages, ticks, finishing).
    busy: Vec<Duration>,
    /// The nodes run ahead.
    feeds: Vec<Feed>,
    /// Inputs put on the bus and not yet delivered (at most `depth`).
    waiting: VecDeque<Step>,
    depth: usize,
    /// The nodes run behind, by index: their replies, one per event handed over.
    behind: BTreeMap<usize, mpsc::Receiver<Reply>>,
    /// What was published, in delivery order, held back from the sink behind a reply of a
    /// node run behind.
    held: VecDeque<Held>,
    /// Replies awaited in `held`, and how many may be before the bus waits for the oldest.
    awaited: usize,
    behind_max: usize,
}

/// A message held back from the sink, or the place of a node's reply.
enum Held {
    Message(Message),
    /// The reply of node `i` (run behind) to its oldest event not answered.
    Reply(usize),
}

/// An input waiting for its turn.
enum Step {
    Message(Message),
    Tick(i64),
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
            feeds: Vec::new(),
            waiting: VecDeque::new(),
            depth: 0,
            behind: BTreeMap::new(),
            held: VecDeque::new(),
            awaited: 0,
            behind_max: 0,
        }
    }

    /// Runs behind, each on a thread of its own, the nodes whose publications no node of
    /// the bus reads and that agree to it ([`Node::run_behind`]): each is handed its inputs
    /// in their turn and the bus goes on; what it publishes reaches the sink where its turn
    /// put it, the messages published after held back until it has. At most `max` replies
    /// are awaited (then the bus waits for the oldest), which bounds what is held back.
    /// Call it after [`Bus::set_demand`] and before the first input. Returns the nodes'
    /// names.
    ///
    /// The messages published, and their order, are those of the bus without it.
    pub fn run_behind(&mut self, max: usize) -> Vec<String> {
        if max == 0 || !self.behind.is_empty() {
            return Vec::new();
        }
        self.behind_max = max;
        let mut names = Vec::new();
        let nodes = std::mem::take(&mut self.nodes);
        for (i, mut node) in nodes.into_iter().enumerate() {
            let read_here = node
                .publications()
                .iter()
                .any(|p| self.routes.contains_key(&p.topic));
            if node.subscriptions().is_empty() || read_here || !node.run_behind() {
                self.nodes.push(node);
                continue;
            }
            names.push(node.name().to_string());
            let (stand_in, replies) = AheadNode::start_behind(node);
            self.nodes.push(Box::new(stand_in));
            self.behind.insert(i, replies);
        }
        names
    }

    /// Gives `m` to the sink, or holds it back behind a reply awaited.
    fn emit(&mut self, m: &Message, sink: &mut impl FnMut(&Message)) {
        if self.held.is_empty() {
            sink(m);
        } else {
            self.held.push_back(Held::Message(m.clone()));
        }
    }

    /// Node `i` (run behind) was handed an event: its reply goes here in the sink's order.
    fn await_reply(&mut self, i: usize, sink: &mut impl FnMut(&Message)) {
        self.held.push_back(Held::Reply(i));
        self.awaited += 1;
        self.release(self.behind_max, sink);
    }

    /// Gives the sink what is no longer held back, waiting for replies while more than
    /// `keep` are awaited.
    fn release(&mut self, keep: usize, sink: &mut impl FnMut(&Message)) {
        while let Some(front) = self.held.front() {
            let i = match front {
                Held::Reply(i) => *i,
                Held::Message(_) => {
                    if let Some(Held::Message(m)) = self.held.pop_front() {
                        sink(&m);
                    }
                    continue;
                }
            };
            let replies = &self.behind[&i];
            let reply = if self.awaited > keep {
                let t = Instant::now();
                let r = replies.recv().ok();
                self.busy[i] += t.elapsed();
                r
            } else {
                match replies.try_recv() {
                    Ok(r) => Some(r),
                    Err(mpsc::TryRecvError::Empty) => return,
                    Err(mpsc::TryRecvError::Disconnected) => None,
                }
            };
            let Some(reply) = reply else {
                // Its thread is gone: the node panicked. Raise the panic here, as the node's
                // handler would have on the bus's thread.
                let mut none = Vec::new();
                self.nodes[i].finish(&mut none);
                panic!("node {} run behind stopped answering", self.nodes[i].name());
            };
            self.held.pop_front();
            self.awaited -= 1;
            // Nobody on the bus reads them: they only reach the sink, in their place.
            for m in &reply.out {
                sink(m);
            }
        }
    }

    /// Runs ahead, each on a thread of its own, the nodes whose every input comes from
    /// outside the bus (no node of the bus publishes any topic they read), and lets
    /// [`Bus::put`] keep up to `depth` inputs waiting (0: none; nothing runs ahead then).
    /// Call it after [`Bus::set_demand`] and before the first input. Returns the nodes'
    /// names.
    ///
    /// The messages published, and their order, are those of the bus without it. Memory:
    /// up to `depth` inputs and a node's outputs for each wait.
    pub fn run_ahead(&mut self, depth: usize) -> Vec<String> {
        self.depth = depth;
        if depth == 0 || !self.feeds.is_empty() {
            return Vec::new();
        }
        let published: BTreeSet<String> = self
            .nodes
            .iter()
            .flat_map(|n| n.publications())
            .map(|p| p.topic)
            .collect();
        let mut names = Vec::new();
        let nodes = std::mem::take(&mut self.nodes);
        for node in nodes {
            let subs = node.subscriptions();
            if subs.is_empty() || subs.iter().any(|s| published.contains(&s.topic)) {
                self.nodes.push(node);
                continue;
            }
            names.push(node.name().to_string());
            let (stand_in, feed) = AheadNode::start(node);
            self.nodes.push(Box::new(stand_in));
            self.feeds.push(feed);
        }
        names
    }

    /// Puts `msg` on the bus: handed at once to the nodes run ahead that read it, delivered
    /// (as [`Bus::deliver`]) once more than `depth` inputs wait before it. What the inputs
    /// delivered now publish reaches `sink`.
    pub fn put(&mut self, msg: Message, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        self.announce(&Step::Message(msg.clone()));
        self.waiting.push_back(Step::Message(msg));
        self.run_waiting(self.depth, sink)
    }

    /// [`Bus::put`] for the transport's clock (as [`Bus::tick`]).
    pub fn put_tick(&mut self, now_ns: i64, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        self.announce(&Step::Tick(now_ns));
        self.waiting.push_back(Step::Tick(now_ns));
        self.run_waiting(self.depth, sink)
    }

    /// Delivers every waiting input.
    pub fn flush(&mut self, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        self.run_waiting(0, sink)
    }

    /// Delivers waiting inputs, oldest first, until at most `keep` wait.
    fn run_waiting(&mut self, keep: usize, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        let mut misrouted = Vec::new();
        while self.waiting.len() > keep {
            match self.waiting.pop_front() {
                Some(Step::Message(m)) => misrouted.extend(self.deliver_now(m, sink)),
                Some(Step::Tick(now)) => misrouted.extend(self.tick_now(now, sink)),
                None => break,
            }
        }
        self.release(self.behind_max, sink);
        misrouted
    }

    /// Hands an input to the nodes run ahead that take it (as delivering it would).
    fn announce(&self, step: &Step) {
        for f in &self.feeds {
            match step {
                Step::Message(m) => {
                    for _ in 0..f.takes(m) {
                        f.send(Event::Message(m.clone()));
                    }
                }
                Step::Tick(now) => f.send(Event::Tick(*now)),
            }
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
        let mut misrouted = self.flush(sink);
        self.announce(&Step::Message(msg.clone()));
        misrouted.extend(self.deliver_now(msg, sink));
        self.release(self.behind_max, sink);
        misrouted
    }

    /// [`Bus::deliver`] in the input's turn (announced to the nodes run ahead).
    fn deliver_now(&mut self, msg: Message, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        let mut misrouted = Vec::new();
        let mut queue = VecDeque::from([Held::Message(msg)]);
        let mut first = true;
        let mut out = Vec::new();
        while let Some(next) = queue.pop_front() {
            let m = match next {
                Held::Message(m) => m,
                Held::Reply(i) => {
                    self.await_reply(i, sink);
                    continue;
                }
            };
            if !first {
                self.emit(&m, sink);
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
                    if self.behind.contains_key(&i) {
                        queue.push_back(Held::Reply(i));
                    } else {
                        queue.extend(out.drain(..).map(Held::Message));
                    }
                }
            }
        }
        misrouted
    }

    /// Tells every node the inputs have ended, in increasing [`Node::rank`] (so a node's
    /// last messages reach the nodes after it first), delivering what they publish.
    pub fn finish(&mut self, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        let mut misrouted = self.flush(sink);
        let mut order: Vec<usize> = (0..self.nodes.len()).collect();
        order.sort_by_key(|&i| (self.nodes[i].rank(), i));
        for i in order {
            let mut out = Vec::new();
            let t = Instant::now();
            self.nodes[i].finish(&mut out);
            self.busy[i] += t.elapsed();
            if self.behind.contains_key(&i) {
                self.await_reply(i, sink);
            }
            for m in out {
                self.emit(&m, sink);
                // Delivered to subscribers; `deliver` does not pass its own input to `sink`.
                misrouted.extend(self.deliver_now(m, sink));
            }
        }
        self.release(0, sink);
        misrouted
    }

    /// Lets every node see the transport's clock (`now_ns`, monotonic), delivering what they
    /// publish in response (a live mesher closes a stream that went idle).
    pub fn tick(&mut self, now_ns: i64, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        let mut misrouted = self.flush(sink);
        self.announce(&Step::Tick(now_ns));
        misrouted.extend(self.tick_now(now_ns, sink));
        self.release(self.behind_max, sink);
        misrouted
    }

    /// [`Bus::tick`] in its turn (announced to the nodes run ahead).
    fn tick_now(&mut self, now_ns: i64, sink: &mut impl FnMut(&Message)) -> Vec<Misrouted> {
        let mut misrouted = Vec::new();
        for i in 0..self.nodes.len() {
            let mut out = Vec::new();
            let t = Instant::now();
            self.nodes[i].on_tick(now_ns, &mut out);
            self.busy[i] += t.elapsed();
            if self.behind.contains_key(&i) {
                self.await_reply(i, sink);
            }
            for m in out {
                self.emit(&m, sink);
                misrouted.extend(self.deliver_now(m, sink));
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
    ) -> Result<(), ParamError> {
        match self.nodes.iter_mut().find(|n| n.name() == node) {
            Some(n) => n.set_parameter(name, value),
            None => Err(ParamError::NoSuchNode {
                node: node.to_owned(),
            }),
        }
    }

    /// Name of every node and the wall time (s) it spent in its handlers so far (on the
    /// threads it ran on: a node whose work is split over rayon's pool counts its wall time
    /// once, not the pool's CPU time; for a node run ahead, the time the bus waited for
    /// its outputs).
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Payload, TopicRef};
    use chronotope_msg::{Clock, PoseStamped, RosMessage};
    use std::sync::Arc;

    fn clock(topic: &str, stamp: i64) -> Message {
        Message::new(topic, stamp, Payload::Clock(Arc::new(Clock::default())))
    }

    /// Reads `input`, publishes on `output`: per message a count of those so far (its
    /// state) and, every third, a second message; per tick one message; one on finishing.
    /// Optionally sleeps a little so that a node run ahead is caught at various points.
    struct Counter {
        name: String,
        input: &'static str,
        output: &'static str,
        seen: i64,
        sleep_us: u64,
        panic_at: Option<i64>,
        /// Subscriptions to `input` (the bus delivers a message once per subscription).
        copies: usize,
        /// Agrees to run behind.
        behind: bool,
        status: NodeStatus,
    }

    impl Counter {
        fn boxed(name: &str, input: &'static str, output: &'static str) -> Box<Self> {
            Box::new(Self {
                name: name.into(),
                input,
                output,
                seen: 0,
                sleep_us: 0,
                panic_at: None,
                copies: 1,
                behind: false,
                status: NodeStatus::default(),
            })
        }
    }

    impl Node for Counter {
        fn as_any(&self) -> &dyn std::any::Any {
            self
        }
        fn name(&self) -> &str {
            &self.name
        }
        fn subscriptions(&self) -> Vec<TopicRef> {
            vec![
                TopicRef {
                    topic: self.input.into(),
                    type_name: <Clock as RosMessage>::TYPE_NAME,
                };
                self.copies
            ]
        }
        fn publications(&self) -> Vec<TopicRef> {
            vec![TopicRef {
                topic: self.output.into(),
                type_name: <Clock as RosMessage>::TYPE_NAME,
            }]
        }
        fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>) {
            self.seen += 1;
            assert_ne!(
                Some(self.seen),
                self.panic_at,
                "{} fails on purpose",
                self.name
            );
            if self.sleep_us > 0 {
                std::thread::sleep(Duration::from_micros(
                    self.sleep_us * (self.seen % 3) as u64,
                ));
            }
            out.push(clock(self.output, msg.stamp_ns * 1000 + self.seen));
            if self.seen % 3 == 0 {
                out.push(clock(self.output, -self.seen));
            }
        }
        fn on_tick(&mut self, now_ns: i64, out: &mut Vec<Message>) {
            out.push(clock(self.output, now_ns * 7 + self.seen));
        }
        fn finish(&mut self, out: &mut Vec<Message>) {
            self.status.received = self.seen as u64;
            out.push(clock(self.output, 1_000_000 + self.seen));
        }
        fn status(&self) -> &NodeStatus {
            &self.status
        }
        fn rank(&self) -> u8 {
            0
        }
        fn run_behind(&mut self) -> bool {
            self.behind
        }
    }

    /// Two nodes reading only `/in` (both run ahead; the second subscribes twice, so it
    /// gets each message twice) and a node reading the first one's output (so not run
    /// ahead).
    fn nodes(sleep_us: u64) -> Vec<Box<dyn Node>> {
        let mut source = Counter::boxed("/source", "/in", "/mid");
        source.sleep_us = sleep_us;
        let mut other = Counter::boxed("/other", "/in", "/side");
        other.copies = 2;
        let after = Counter::boxed("/after", "/mid", "/out");
        vec![source, other, after]
    }

    /// Inputs: messages on `/in`, a mistyped one, and ticks in between.
    enum Input {
        Msg(Message),
        Tick(i64),
    }

    fn inputs() -> Vec<Input> {
        let mut v = Vec::new();
        for k in 0..40 {
            if k % 7 == 3 {
                v.push(Input::Tick(k));
            }
            if k == 11 {
                v.push(Input::Msg(Message::new(
                    "/in",
                    k,
                    Payload::PoseStamped(Arc::new(PoseStamped::default())),
                )));
            }
            v.push(Input::Msg(clock("/in", k)));
        }
        v
    }

    /// Every message published, in order, with the misrouted count and the final statuses.
    fn run(depth: Option<usize>, sleep_us: u64) -> (Vec<(String, i64)>, usize, Vec<u64>) {
        run_with(nodes(sleep_us), depth, None)
    }

    /// [`run`] of `nodes`, with up to `behind` replies awaited from nodes run behind.
    fn run_with(
        nodes: Vec<Box<dyn Node>>,
        depth: Option<usize>,
        behind: Option<usize>,
    ) -> (Vec<(String, i64)>, usize, Vec<u64>) {
        let mut bus = Bus::new(nodes);
        let ahead = depth.map(|d| bus.run_ahead(d)).unwrap_or_default();
        if depth.is_some_and(|d| d > 0) {
            assert_eq!(ahead, ["/source", "/other"]);
        }
        if let Some(max) = behind {
            let names = bus.run_behind(max);
            assert_eq!(names, if max > 0 { vec!["/after"] } else { vec![] });
        }
        let mut seen = Vec::new();
        let mut sink = |m: &Message| seen.push((m.topic.to_string(), m.stamp_ns));
        let mut misrouted = 0;
        for input in inputs() {
            misrouted += match (input, depth) {
                (Input::Msg(m), Some(_)) => bus.put(m, &mut sink).len(),
                (Input::Tick(t), Some(_)) => bus.put_tick(t, &mut sink).len(),
                (Input::Msg(m), None) => bus.deliver(m, &mut sink).len(),
                (Input::Tick(t), None) => bus.tick(t, &mut sink).len(),
            };
        }
        misrouted += bus.finish(&mut sink).len();
        let received = bus.nodes().iter().map(|n| n.status().received).collect();
        // The node is back home: the transport can read it as before.
        assert!(bus.nodes()[0].as_any().downcast_ref::<Counter>().is_some());
        (seen, misrouted, received)
    }

    #[test]
    fn a_node_run_ahead_publishes_the_same_messages_in_the_same_order() {
        let plain = run(None, 0);
        assert_eq!(
            plain.1, 3,
            "the mistyped message, for each subscription to /in"
        );
        assert_eq!(plain.2, vec![40, 80, plain.2[2]]);
        for depth in [0, 1, 2, 5, 64] {
            for sleep_us in [0, 200] {
                assert_eq!(run(Some(depth), sleep_us), plain, "depth {depth}");
            }
        }
    }

    /// [`nodes`] with `/after` (whose output nobody on the bus reads) agreeing to run
    /// behind, and sleeping a little per message.
    fn nodes_behind(sleep_us: u64) -> Vec<Box<dyn Node>> {
        let mut n = nodes(0);
        let mut after = Counter::boxed("/after", "/mid", "/out");
        after.behind = true;
        after.sleep_us = sleep_us;
        n[2] = after;
        n
    }

    #[test]
    fn a_node_run_behind_publishes_the_same_messages_in_the_same_order() {
        let plain = run(None, 0);
        // Only a node that agrees, and whose outputs nobody on the bus reads, runs behind.
        assert!(Bus::new(nodes(0)).run_behind(4).is_empty());
        let mut reads_after = nodes_behind(0);
        reads_after.push(Counter::boxed("/last", "/out", "/end"));
        assert!(Bus::new(reads_after).run_behind(4).is_empty());
        for depth in [None, Some(0), Some(3)] {
            for max in [0, 1, 2, 7, 100] {
                for sleep_us in [0, 300] {
                    assert_eq!(
                        run_with(nodes_behind(sleep_us), depth, Some(max)),
                        plain,
                        "depth {depth:?}, max {max}, sleep {sleep_us} µs"
                    );
                }
            }
        }
    }

    #[test]
    fn a_node_that_panics_behind_panics_on_the_bus() {
        let mut n = nodes_behind(100);
        let after = Counter {
            panic_at: Some(5),
            behind: true,
            ..*Counter::boxed("/after", "/mid", "/out")
        };
        n[2] = Box::new(after);
        let mut bus = Bus::new(n);
        assert_eq!(bus.run_behind(3), ["/after"]);
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            for k in 0..40 {
                bus.put(clock("/in", k), &mut |_| {});
            }
            bus.finish(&mut |_| {});
        }));
        let panic = r.expect_err("the node's panic reaches the bus");
        let text = panic
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| panic.downcast_ref::<&str>().copied())
            .unwrap_or_default();
        assert!(text.contains("/after fails on purpose"), "{text}");
    }

    #[test]
    fn direct_delivery_still_works_with_a_node_run_ahead() {
        // `deliver` and `tick` run what waits first, then the input, in order.
        let plain = run(None, 0);
        let mut bus = Bus::new(nodes(0));
        bus.run_ahead(4);
        let mut seen = Vec::new();
        let mut sink = |m: &Message| seen.push((m.topic.to_string(), m.stamp_ns));
        for (k, input) in inputs().into_iter().enumerate() {
            match input {
                Input::Msg(m) if k % 2 == 0 => bus.deliver(m, &mut sink),
                Input::Msg(m) => bus.put(m, &mut sink),
                Input::Tick(t) => bus.tick(t, &mut sink),
            };
        }
        bus.finish(&mut sink);
        assert_eq!(seen, plain.0);
    }

    #[test]
    fn a_node_that_panics_ahead_panics_in_its_turn() {
        let mut bus = Bus::new(vec![Box::new(Counter {
            panic_at: Some(5),
            ..*Counter::boxed("/source", "/in", "/mid")
        }) as Box<dyn Node>]);
        bus.run_ahead(3);
        let mut delivered = 0;
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            for k in 0..10 {
                bus.put(clock("/in", k), &mut |_| {});
                delivered = k;
            }
        }));
        let panic = r.expect_err("the node's panic reaches the bus");
        let text = panic.downcast_ref::<String>().cloned().unwrap_or_default();
        assert!(text.contains("fails on purpose"), "{text}");
        // The fifth input (k = 4) fails on the node's thread as soon as it is put; the bus
        // finds out in its turn, when the eighth is put (three wait before it then).
        assert_eq!(delivered, 6);
    }
}
