//! The `chronotope` command line: scene generation, meshing, benchmarks.
//!
//! Each subcommand is a plain function over typed options so that tests and benchmarks call
//! the same code the binary runs.

pub mod bench;
pub mod check;
pub mod info;
pub mod info_robot;
pub mod live;
pub mod mesh;
pub mod param;
pub mod paths;
pub mod render;
pub mod replay;
pub mod sample;
pub mod scene;
pub mod scene_robot;

use crate::msg::{VoxelEncoding, VoxelGrid};
use clap::{Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

/// Space-time (4D) interference checking for robot and machine-tool cells.
#[derive(Debug, Parser)]
#[command(name = "chronotope", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Write a synthetic scene as a rosbag2 MCAP bag (one VoxelGrid topic per body).
    Scene(scene::SceneArgs),
    /// Mesh every VoxelGrid topic of a bag into a closed 4D tet mesh, slab by slab.
    Mesh(mesh::MeshArgs),
    /// Check every pair of bodies of a bag for interference over time; write the report.
    Check(check::CheckArgs),
    /// Run the suite's nodes over a bag in one process; write the report and the output bag.
    Replay(replay::ReplayArgs),
    /// Run the nodes of a launch config on DDS, in this process (until Ctrl-C; a second
    /// Ctrl-C drops what is still queued).
    Launch(live::LaunchArgs),
    /// Run one node of a launch config on DDS (the others may run elsewhere).
    Node(live::NodeArgs),
    /// Draw the checker's labelled slices of one instant from an output bag to a PNG.
    Render(render::RenderArgs),
    /// Say what a bag holds (like `ros2 bag info`) and what the suite sees in it.
    Info(info::InfoArgs),
    /// Publish a bag's topics on DDS with their recorded timing (and /clock).
    Play(live::PlayArgs),
    /// Record live topics into a rosbag2 MCAP bag.
    Record(live::RecordArgs),
    /// Read or set a running node's parameters (the ROS parameter services).
    Param(param::ParamArgs),
    /// Benchmarks that print the figures docs/performance.md and docs/accuracy.md quote.
    Bench(bench::BenchArgs),
    /// Sample points uniformly on an implicit scene (docs/methods/sampling.md); write a
    /// PointCloud2 bag.
    Sample(sample::SampleArgs),
}

/// A failure that ends a command (per-frame problems are counted, not fatal).
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// Reading or writing a bag failed.
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
    /// The scene options are invalid.
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// Bodies cannot be checked against each other.
    #[error(transparent)]
    Check(#[from] crate::checker::CheckError),
    /// Mesher options are invalid.
    #[error(transparent)]
    Mesh(#[from] crate::mesh::MeshError),
    /// A file could not be written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A command-line value is malformed.
    #[error("{0}")]
    Usage(String),
    /// An output path is refused before anything is written (it is an input, another
    /// output, a bag the user did not ask to replace, a special file).
    #[error("{option} {}: {reason}", path.display())]
    Output {
        /// The option naming it (`--out`).
        option: String,
        /// The path.
        path: PathBuf,
        /// Why, and what to do.
        #[source]
        reason: paths::OutputRefusal,
    },
    /// The bag offers no body to check, so the nodes that mesh the bag's bodies cannot run:
    /// why no body could be read, then what the config says.
    #[error("{why}; so {config}")]
    NoBodies {
        /// Why the bag has no body (names the bag and each topic or file).
        why: String,
        /// The launch config's complaint.
        config: String,
    },
    /// An implicit scene cannot be sampled.
    #[error(transparent)]
    Sample(#[from] crate::sampler::scene_file::SceneFileError),
    /// A benchmark failed.
    #[error(transparent)]
    Bench(#[from] crate::bench::BenchError),
}

/// The VoxelGrid frames of a bag with its problems handled once for every command: an
/// undecodable message is logged and yielded as `(topic, None)` (the caller counts it as a
/// skipped frame of that body); a problem with the bag itself is logged and kept in
/// [`Self::errors`], and after a fatal one iteration ends (what was read before it stays).
/// At most [`MAX_BODIES`] topics are read: frames of further topics are refused, and each
/// refused topic is logged once and listed in [`Self::errors`].
pub struct BagFrames {
    inner: crate::bag::VoxelFrames,
    /// Messages yielded (frames and undecodable ones).
    pub messages: u64,
    /// Per topic: messages that did not decode.
    pub undecodable: std::collections::BTreeMap<String, u64>,
    /// Problems with the bag itself, in reading order.
    pub errors: Vec<String>,
    done: bool,
    topics: std::collections::BTreeSet<String>,
    refused: std::collections::BTreeSet<String>,
}

/// What was read from the bag (extra field of the report of `check` and `replay`).
#[derive(Debug, Clone, Default, serde::Serialize, PartialEq)]
pub struct InputCounts {
    /// Messages read.
    pub messages: u64,
    /// Messages given to a node.
    pub delivered: u64,
    /// Messages on topics no node reads.
    pub unused: u64,
    /// Per topic: messages that did not decode as the subscribed type.
    pub undecodable: std::collections::BTreeMap<String, u64>,
    /// Per topic: messages of another type than the node subscribed to expects.
    pub wrong_type: std::collections::BTreeMap<String, u64>,
    /// Problems with the bag itself (a corrupt chunk, a truncated file), in reading order.
    pub bag_errors: Vec<String>,
    /// VoxelGrid topics whose channel was refused (message encoding, schema), with why and
    /// how many messages were skipped.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub refused_topics: Vec<crate::bag::RefusedTopic>,
    /// What reading the bag cost: damaged regions, messages lost and their time spans.
    pub recovery: Option<crate::bag::Recovery>,
}

/// Most bodies (VoxelGrid topics) read from one bag by `check`, `mesh` and `replay`: all
/// pairs of 64 bodies are 2016 pairs, each checked window by window; 256 bodies would be
/// 32 640 pairs, over a minute for even the tiniest bodies.
pub const MAX_BODIES: usize = 64;

impl BagFrames {
    /// Opens a bag's VoxelGrid frames.
    ///
    /// # Errors
    /// The bag cannot be opened, is empty, or has no VoxelGrid topic.
    pub fn open(path: &std::path::Path) -> Result<Self, CliError> {
        Ok(Self {
            inner: crate::bag::voxel_frames(path)?,
            messages: 0,
            undecodable: Default::default(),
            errors: Vec::new(),
            done: false,
            topics: Default::default(),
            refused: Default::default(),
        })
    }
}

impl BagFrames {
    /// What was read, for the report's `input` (complete once iteration has ended).
    pub fn input(&self) -> InputCounts {
        InputCounts {
            messages: self.messages,
            delivered: self.messages - self.undecodable.values().sum::<u64>(),
            unused: 0,
            undecodable: self.undecodable.clone(),
            wrong_type: Default::default(),
            bag_errors: self.errors.clone(),
            refused_topics: self.inner.refused(),
            recovery: Some(self.inner.recovery().clone()),
        }
    }
}

impl Iterator for BagFrames {
    type Item = (String, Option<VoxelGrid>);

    fn next(&mut self) -> Option<Self::Item> {
        use crate::bag::FrameError;
        while !self.done {
            let item = self.inner.next()?;
            let topic = match &item {
                Ok((topic, _)) | Err(FrameError::Decode { topic, .. }) => Some(topic.clone()),
                Err(FrameError::Bag(_)) => None,
            };
            if let Some(topic) = topic {
                if !self.topics.contains(&topic) {
                    if self.topics.len() >= MAX_BODIES {
                        if self.refused.insert(topic.clone()) {
                            let why = format!("{topic}: not read: more than {MAX_BODIES} VoxelGrid topics in one bag");
                            tracing::error!("{why}");
                            self.errors.push(why);
                        }
                        continue;
                    }
                    self.topics.insert(topic);
                }
            }
            match item {
                Ok((topic, grid)) => {
                    self.messages += 1;
                    return Some((topic, Some(grid)));
                }
                Err(FrameError::Decode {
                    topic,
                    log_time_ns,
                    reason,
                }) => {
                    tracing::warn!(topic = %topic, log_time_ns, "skipping frame: does not decode: {reason}");
                    self.messages += 1;
                    *self.undecodable.entry(topic.clone()).or_default() += 1;
                    return Some((topic, None));
                }
                Err(FrameError::Bag(e)) => {
                    self.done = e.is_fatal();
                    let then = if self.done {
                        "; using what was read before it"
                    } else {
                        "; reading on"
                    };
                    tracing::error!("{e}{then}");
                    self.errors.push(e.to_string());
                }
            }
        }
        None
    }
}

/// Writes an output file whole, creating its directory: complete or not at all, and a link
/// at the path is replaced, never followed ([`crate::fsio::write_atomic`]). The caller has
/// checked the path ([`paths::Paths::check`]).
///
/// # Errors
/// The directory or the file cannot be written.
pub fn write_output(path: &std::path::Path, bytes: &[u8]) -> Result<(), CliError> {
    let dir = crate::fsio::parent_dir(path);
    std::fs::create_dir_all(dir).map_err(|source| CliError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    crate::fsio::write_atomic(path, bytes).map_err(|source| CliError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// The console line saying what could not be verified about a bag read, if anything.
pub fn integrity_note(recovery: Option<&crate::bag::Recovery>) -> Option<String> {
    let line = recovery?.describe_unverified();
    (!line.is_empty()).then(|| format!("note: {line}"))
}

/// Runs a parsed command line.
///
/// # Errors
/// The [`CliError`] that ended the command.
pub fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Scene(a) => scene::run(&a),
        Command::Mesh(a) => mesh::run(&a),
        Command::Check(a) => check::run(&a),
        Command::Replay(a) => replay::run(&a),
        Command::Launch(a) => live::launch(&a),
        Command::Node(a) => live::node(&a),
        Command::Info(a) => info::run(&a),
        Command::Render(a) => render::run(&a),
        Command::Play(a) => live::play(&a),
        Command::Record(a) => live::record(&a),
        Command::Param(a) => param::run(&a),
        Command::Bench(a) => bench::run(&a),
        Command::Sample(a) => sample::run(&a),
    }
}

/// Encodings on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EncodingArg {
    /// 1 bit per voxel.
    Bits,
    /// 1 byte per voxel, occupied percent.
    Percent,
}

impl From<EncodingArg> for VoxelEncoding {
    fn from(e: EncodingArg) -> Self {
        match e {
            EncodingArg::Bits => VoxelEncoding::Bits,
            EncodingArg::Percent => VoxelEncoding::Percent,
        }
    }
}
