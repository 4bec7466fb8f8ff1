//! The `chronotope` command line: scene generation, meshing, benchmarks.
//!
//! Each subcommand is a plain function over typed options so that tests and benchmarks call
//! the same code the binary runs.

pub mod bench;
pub mod check;
pub mod mesh;
pub mod scene;

use crate::mesh::FrameRef;
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
    /// Benchmarks that print the figures the README quotes.
    Bench(bench::BenchArgs),
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
}

/// Peak resident set size of this process so far (MB) (Linux: VmHWM), 0 if unknown.
pub fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| {
                l.split_whitespace()
                    .nth(1)
                    .and_then(|v| v.parse::<f64>().ok())
            })
        })
        .map(|kb| kb / 1024.0)
        .unwrap_or(0.0)
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
        Command::Bench(a) => bench::run(&a),
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

/// The mesher's view of a VoxelGrid message.
pub fn frame_ref(g: &VoxelGrid) -> FrameRef<'_> {
    FrameRef {
        stamp_ns: g.header.stamp.as_nanos(),
        origin: [g.origin.x, g.origin.y, g.origin.z],
        resolution: g.resolution,
        size: [g.size_x, g.size_y, g.size_z],
        encoding: g.encoding,
        data: &g.data,
    }
}
