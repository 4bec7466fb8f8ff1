//! The benchmark programs behind `chronotope bench …`: each prints the figures that
//! docs/performance.md, docs/accuracy.md, docs/carving-accuracy.md and docs/sampler-error.md
//! quote, and some regenerate those pages. The command line (`cli/bench.rs`) parses the
//! arguments and calls these; nothing here parses arguments or knows the command line.

pub mod carve;
pub mod check;
pub mod mesh;
pub mod robot;
pub mod rotate;
pub mod sampler;

use std::path::PathBuf;

/// What ends a benchmark.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A value out of range, or a configuration that does not parse.
    #[error("{0}")]
    Usage(String),
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The scene options are invalid.
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// Bodies cannot be checked against each other.
    #[error(transparent)]
    Check(#[from] crate::checker::CheckError),
    /// The mesher refused a frame or an option.
    #[error(transparent)]
    Mesh(#[from] crate::mesh::MeshError),
    /// A bag could not be read or written.
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
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
