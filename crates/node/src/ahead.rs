//! A node of the in-process bus run ahead on a thread of its own (see
//! [`Bus::run_ahead`](super::bus::Bus::run_ahead)).
//!
//! A node whose inputs all come from outside the bus (a mesher reading a bag's frames) does
//! not depend on what the other nodes do. The bus can hand it each input as soon as the input
//! is read, so that it works on the next frames while the nodes after it work on the ones
//! before, and take what it published in the input's turn. Nothing changes in what is
//! published or in its order: the node sees the same inputs in the same order, and its
//! outputs are put on the bus exactly where its handler would have put them.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;

use super::{Message, Node, NodeStatus, TopicRef};

/// What the bus hands a node ahead of its turn.
pub(crate) enum Event {
    /// A message on one of its subscriptions.
    Message(Message),
    /// The transport's clock.
    Tick(i64),
    /// The inputs have ended.
    Finish,
}

/// What the node published for one event, and its status after.
pub(crate) struct Reply {
    pub out: Vec<Message>,
    status: NodeStatus,
}

/// Where a node run ahead is fed: the bus keeps one per such node.
pub(crate) struct Feed {
    /// Its subscriptions (topic and type), as the bus routes them.
    pub subscriptions: Vec<TopicRef>,
    events: mpsc::Sender<Event>,
    /// Events sent and not yet answered (shared with the stand-in).
    owed: Arc<AtomicUsize>,
}

impl Feed {
    /// Hands the node `event` ahead of its turn.
    pub fn send(&self, event: Event) {
        self.owed.fetch_add(1, Ordering::Relaxed);
        // A worker that has gone (its node panicked) is found when its reply is taken.
        let _ = self.events.send(event);
    }

    /// How many times the bus delivers `msg` to the node: once per subscription to its
    /// topic with its type (the bus routes each subscription).
    pub fn takes(&self, msg: &Message) -> usize {
        self.subscriptions
            .iter()
            .filter(|s| *s.topic == *msg.topic && s.type_name == msg.payload.type_name())
            .count()
    }
}

/// The node's stand-in on the bus while it runs on its own thread: each handler takes the
/// node's reply to the event the bus announced for that turn. A node run behind (see
/// [`AheadNode::start_behind`]) is only handed its events; the bus takes the replies.
pub(crate) struct AheadNode {
    name: String,
    publications: Vec<TopicRef>,
    rank: u8,
    status: NodeStatus,
    feed: Feed,
    /// The node's replies; `None` for a node run behind (the bus holds them).
    replies: Option<mpsc::Receiver<Reply>>,
    worker: Option<JoinHandle<Box<dyn Node>>>,
    /// The node, back from its thread once it has finished.
    home: Option<Box<dyn Node>>,
}

impl AheadNode {
    /// Moves `node` onto a thread of its own, run behind: its stand-in hands it each event
    /// in the event's turn and returns at once; the node's replies, one per event in order,
    /// come on the receiver returned. The stand-in's status is the node's as it started
    /// until the node has finished.
    pub fn start_behind(node: Box<dyn Node>) -> (Self, mpsc::Receiver<Reply>) {
        let (mut stand_in, _) = Self::start_as(node, "behind");
        let replies = stand_in
            .replies
            .take()
            .expect("a node just started has its replies");
        (stand_in, replies)
    }

    /// Moves `node` onto a thread of its own; returns its stand-in and its feed.
    pub fn start(node: Box<dyn Node>) -> (Self, Feed) {
        Self::start_as(node, "ahead")
    }

    /// [`AheadNode::start`], the thread named `how` and the node's name (15 characters).
    fn start_as(node: Box<dyn Node>, how: &str) -> (Self, Feed) {
        let (events, inbox) = mpsc::channel::<Event>();
        let (outbox, replies) = mpsc::channel::<Reply>();
        let name = node.name().to_string();
        let subscriptions = node.subscriptions();
        let publications = node.publications();
        let rank = node.rank();
        let status = node.status().clone();
        let worker = std::thread::Builder::new()
            .name(format!("{how}{name}").chars().take(15).collect())
            .spawn(move || {
                let mut node = node;
                // Ends when the bus is gone (every sender dropped) or after `Finish`.
                while let Ok(event) = inbox.recv() {
                    let mut out = Vec::new();
                    let last = matches!(event, Event::Finish);
                    match event {
                        Event::Message(m) => node.on_message(&m, &mut out),
                        Event::Tick(now) => node.on_tick(now, &mut out),
                        Event::Finish => node.finish(&mut out),
                    }
                    let reply = Reply {
                        out,
                        status: node.status().clone(),
                    };
                    if outbox.send(reply).is_err() || last {
                        break;
                    }
                }
                node
            })
            .expect("a thread for a node run ahead");
        let feed = Feed {
            subscriptions,
            events,
            owed: Arc::new(AtomicUsize::new(0)),
        };
        let mine = Feed {
            subscriptions: feed.subscriptions.clone(),
            events: feed.events.clone(),
            owed: feed.owed.clone(),
        };
        (
            Self {
                name,
                publications,
                rank,
                status,
                feed: mine,
                replies: Some(replies),
                worker: Some(worker),
                home: None,
            },
            feed,
        )
    }

    /// Takes the node's reply to its next event and pushes what it published; `event` is
    /// handed over first if the bus did not announce it. A node run behind is only handed
    /// the event.
    fn take(&mut self, event: impl FnOnce() -> Event, out: &mut Vec<Message>) {
        if self.replies.is_none() {
            let _ = self.feed.events.send(event());
            return;
        }
        if self.feed.owed.load(Ordering::Relaxed) == 0 {
            self.feed.send(event());
        }
        self.take_reply(out);
    }

    /// Takes the node's reply to the oldest event it was handed.
    fn take_reply(&mut self, out: &mut Vec<Message>) {
        let Some(replies) = &self.replies else {
            return;
        };
        let reply = replies.recv();
        self.feed.owed.fetch_sub(1, Ordering::Relaxed);
        match reply {
            Ok(r) => {
                out.extend(r.out);
                self.status = r.status;
            }
            // The worker is gone: its node panicked. Raise the panic here, as the node's
            // handler would have on the bus's thread.
            Err(_) => {
                if let Some(w) = self.worker.take() {
                    if let Err(panic) = w.join() {
                        std::panic::resume_unwind(panic);
                    }
                }
                panic!("node {} run ahead stopped answering", self.name);
            }
        }
    }

    /// Waits for the node's thread to end and takes the node home; raises its panic if it
    /// panicked.
    pub(crate) fn join(&mut self) {
        if let Some(w) = self.worker.take() {
            match w.join() {
                Ok(node) => self.home = Some(node),
                Err(panic) => std::panic::resume_unwind(panic),
            }
        }
    }
}

impl Node for AheadNode {
    fn as_any(&self) -> &dyn std::any::Any {
        match &self.home {
            Some(n) => n.as_any(),
            None => self,
        }
    }
    fn name(&self) -> &str {
        &self.name
    }
    fn subscriptions(&self) -> Vec<TopicRef> {
        self.feed.subscriptions.clone()
    }
    fn publications(&self) -> Vec<TopicRef> {
        self.publications.clone()
    }
    fn on_message(&mut self, msg: &Message, out: &mut Vec<Message>) {
        self.take(|| Event::Message(msg.clone()), out);
    }
    fn on_tick(&mut self, now_ns: i64, out: &mut Vec<Message>) {
        self.take(|| Event::Tick(now_ns), out);
    }
    fn finish(&mut self, out: &mut Vec<Message>) {
        if self.home.is_some() {
            return;
        }
        if self.replies.is_none() {
            // Run behind: its last reply, like every other, is the bus's to take; the node
            // comes home once it has answered everything (or raises its panic here).
            let _ = self.feed.events.send(Event::Finish);
            self.join();
            return;
        }
        // Replies the bus did not take go out first (there are none: the bus runs every
        // input it announced before its nodes finish).
        while self.feed.owed.load(Ordering::Relaxed) > 0 {
            self.take_reply(out);
        }
        self.feed.send(Event::Finish);
        self.take_reply(out);
        self.join();
    }
    fn status(&self) -> &NodeStatus {
        match &self.home {
            Some(n) => n.status(),
            None => &self.status,
        }
    }
    fn rank(&self) -> u8 {
        self.rank
    }
}
