//! `octomap_msgs/Octomap` onto a lattice: both streams OctoMap writes into the
//! message (`binary` true: `binaryMapToMsg`; false: `fullMapToMsg`), any
//! resolution, leaves at any depth.
//!
//! Rules (README.md has the table):
//! - A leaf is occupied by its binary code, or when its log-odds is at or above
//!   the threshold (default 0, probability 0.5, OctoMap's default).
//! - Space no leaf covers is unknown.
//! - `Bits`: a voxel is occupied when an occupied leaf overlaps it (a coarse
//!   pruned leaf fills every voxel it overlaps; one fine leaf is enough); with
//!   `unknown_occupied`, also when any part of it is unknown.
//! - `Percent`: 255 where no leaf overlaps the voxel at all; elsewhere the part
//!   of its volume that is occupied *or unknown*, in whole percent rounded up
//!   (a partly known voxel errs toward occupied), at least 1 where an occupied
//!   leaf overlaps it.
//! - An inner node whose children are all unknown (a binary `11` code over two
//!   zero bytes) leaves its cube unknown. Leaf children of one node that are
//!   all in one state are rasterised as one leaf of the node's size: the same
//!   voxels, less work.
//!
//! Relies on [`crate::lattice`] and the padded bit rows (`rows.rs`); knows nothing of ROS.

mod free;
mod raster;
mod stream;

pub use stream::{OctreeLeaf, StreamSummary, KEY_OFFSET, TREE_DEPTH};

use crate::lattice::{Encoding, Lattice, LatticeError, Limits, VoxelFrame, RESOLUTION_RANGE};
use crate::rows::BitRows;
use free::FreeFractions;
use raster::MergeLeaves;
use raster::{Batches, FineSpans, KeyLattice, LeafRaster};
use std::sync::mpsc;
use stream::{Leaves, ReadSettings, TreeVisitor};
use thiserror::Error;

/// The fields of one `octomap_msgs/msg/Octomap` message that carry the map.
#[derive(Clone, Copy, Debug)]
pub struct OctomapMsg<'a> {
    /// `binary`: the stream holds only free/occupied leaves (`writeBinaryData`);
    /// otherwise the full tree with every node's value (`writeData`).
    pub binary: bool,
    /// `id`: the tree type, `OcTree`, `OcTreeStamped` or `ColorOcTree`.
    pub id: &'a str,
    /// `resolution`: edge of the finest leaves, metres.
    pub resolution: f64,
    /// `data` (`int8[]` on the wire, the same bytes).
    pub data: &'a [u8],
}

/// The octree types whose stream layout is known here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TreeKind {
    /// `OcTree`: a node is its `f32` log-odds.
    OcTree,
    /// `OcTreeStamped`: in memory a log-odds and a timestamp, but OctoMap
    /// (1.10) writes only the log-odds: its node inherits `OcTreeNode::writeData`.
    OcTreeStamped,
    /// `ColorOcTree`: the log-odds, then the colour as 3 bytes (r, g, b).
    ColorOcTree,
}

impl TreeKind {
    /// The kind an `Octomap.id` names, if known.
    pub fn from_id(id: &str) -> Option<Self> {
        match id {
            "OcTree" => Some(TreeKind::OcTree),
            "OcTreeStamped" => Some(TreeKind::OcTreeStamped),
            "ColorOcTree" => Some(TreeKind::ColorOcTree),
            _ => None,
        }
    }

    /// Bytes a full stream's node carries after its log-odds.
    pub fn extra_bytes(self) -> usize {
        match self {
            TreeKind::OcTree | TreeKind::OcTreeStamped => 0,
            TreeKind::ColorOcTree => 3,
        }
    }

    fn extra_what(self) -> &'static str {
        match self {
            TreeKind::ColorOcTree => "a ColorOcTree node's colour",
            _ => "a node's payload",
        }
    }
}

/// How leaves are read and unknown space is written. Built with
/// [`OctomapOptions::new`] and its setters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OctomapOptions {
    threshold: f32,
    unknown_occupied: bool,
    allow_trailing_bytes: bool,
    parallel: bool,
}

impl Default for OctomapOptions {
    fn default() -> Self {
        OctomapOptions {
            threshold: 0.0,
            unknown_occupied: false,
            allow_trailing_bytes: false,
            parallel: true,
        }
    }
}

impl OctomapOptions {
    /// Threshold log-odds 0 (probability 0.5, OctoMap's default), unknown free
    /// in `Bits`, trailing bytes refused.
    pub fn new() -> Self {
        Self::default()
    }

    /// A full stream's leaf is occupied when its log-odds is at or above
    /// `log_odds` (compared as `f32`, as OctoMap's `isNodeOccupied`). Does not
    /// apply to binary streams, whose leaves say occupied or free.
    pub fn threshold_log_odds(mut self, log_odds: f32) -> Self {
        self.threshold = log_odds;
        self
    }

    /// The threshold as a probability, `log(p / (1 - p))` as OctoMap's `logodds`.
    pub fn threshold_probability(mut self, probability: f64) -> Self {
        self.threshold = (probability / (1.0 - probability)).ln() as f32;
        self
    }

    /// `Bits`: voxels with any unknown part are occupied (the safe side for
    /// collision). `Percent` always writes 255 for wholly unknown voxels and
    /// counts the unknown part of partly known ones as occupied.
    pub fn unknown_occupied(mut self, yes: bool) -> Self {
        self.unknown_occupied = yes;
        self
    }

    /// Accept bytes after the tree's end (counted in the statistics). By
    /// default they are refused: OctoMap itself ignores them, but they mean the
    /// message is not what its fields say.
    pub fn allow_trailing_bytes(mut self, yes: bool) -> Self {
        self.allow_trailing_bytes = yes;
        self
    }

    /// Where free leaves are rasterised (`Percent`, or unknown occupied) and the stream
    /// is at least [`PARALLEL_BYTES`] long: read the stream on a second thread, which
    /// hands its leaves over in batches, while the caller's rasterises them (on by
    /// default, on a machine with more than one core; at most about 3 MB of leaves in
    /// flight). The frame is the same either way: the leaves are rasterised in the
    /// stream's order by one thread.
    pub fn parallel(mut self, on: bool) -> Self {
        self.parallel = on;
        self
    }

    /// The threshold log-odds.
    pub fn threshold(&self) -> f32 {
        self.threshold
    }
}

/// What one rasterised message held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OctomapStats {
    /// The stream: nodes, leaves, depth, bytes.
    pub stream: StreamSummary,
    /// Leaves rasterised because they overlap the lattice: only occupied ones
    /// in `Bits` with unknown free; otherwise after merging the leaf children
    /// of a node that are all in one state into one leaf.
    pub leaves_in_lattice: u64,
    /// Voxels written occupied (`Bits`) or at 50 % and above (`Percent`).
    pub occupied_voxels: u64,
    /// Voxels written 255 (`Percent` only).
    pub unknown_voxels: u64,
}

/// What is wrong with an `Octomap` message. Offsets are byte offsets in `data`.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum OctomapError {
    /// The lattice is invalid or passes a limit.
    #[error(transparent)]
    Lattice(#[from] LatticeError),
    /// `resolution` is not finite or outside 1e-6..=1e6 m.
    #[error("Octomap resolution is {value} m: it must be finite and within 1e-6..=1e6 m")]
    Resolution {
        /// The value given.
        value: f64,
    },
    /// `id` names no tree type whose layout is known here.
    #[error("Octomap id \"{id}\" is not read here: only OcTree, OcTreeStamped and ColorOcTree carry an occupancy whose layout is known")]
    UnknownTreeId {
        /// The id given.
        id: String,
    },
    /// The threshold is NaN.
    #[error("occupancy threshold log-odds is NaN: give a number (0 = probability 0.5)")]
    Threshold,
    /// `data` is longer than [`Limits::max_octree_bytes`].
    #[error("Octomap data has {len} bytes, more than the limit max_octree_bytes = {limit}")]
    TooLarge {
        /// Bytes given.
        len: u64,
        /// The limit.
        limit: u64,
    },
    /// The tree runs past the end of `data`.
    #[error("Octomap data is truncated: {what} needs {needed} bytes at offset {offset}, but data has {len} bytes (a cut message, or the wrong `binary` flag or id)")]
    Truncated {
        /// Where the missing bytes start.
        offset: u64,
        /// Bytes needed there.
        needed: u64,
        /// Length of `data`.
        len: u64,
        /// What was being read.
        what: &'static str,
    },
    /// A node at depth 16 (the resolution's size) has children.
    #[error("Octomap tree is deeper than 16: a node at depth 16 has children (its codes at offset {offset}); the data is not an OctoMap stream, or the `binary` flag is wrong")]
    TooDeep {
        /// Offset of the codes or mask that give the depth-16 node children.
        offset: u64,
    },
    /// More nodes than [`Limits::max_octree_nodes`].
    #[error(
        "Octomap tree has more than max_octree_nodes = {limit} nodes (passed at offset {offset})"
    )]
    TooManyNodes {
        /// The limit.
        limit: u64,
        /// Where the limit was passed.
        offset: u64,
    },
    /// Bytes follow the tree's end.
    #[error("Octomap data has {count} bytes after the tree ends at offset {offset}: the `binary` flag or id may be wrong (allow_trailing_bytes accepts them)")]
    TrailingBytes {
        /// Where the tree ends.
        offset: u64,
        /// Bytes after it.
        count: u64,
    },
    /// A node's log-odds is NaN.
    #[error("Octomap node at offset {offset} has a NaN log-odds")]
    NanLogOdds {
        /// Offset of the value.
        offset: u64,
    },
}

fn check_message(
    msg: &OctomapMsg<'_>,
    options: &OctomapOptions,
    limits: &Limits,
) -> Result<TreeKind, OctomapError> {
    let r = msg.resolution;
    if !r.is_finite() || r < RESOLUTION_RANGE.0 || r > RESOLUTION_RANGE.1 {
        return Err(OctomapError::Resolution { value: r });
    }
    let kind = TreeKind::from_id(msg.id).ok_or_else(|| OctomapError::UnknownTreeId {
        id: msg.id.to_owned(),
    })?;
    if options.threshold.is_nan() {
        return Err(OctomapError::Threshold);
    }
    let len = msg.data.len() as u64;
    if len > limits.max_octree_bytes {
        return Err(OctomapError::TooLarge {
            len,
            limit: limits.max_octree_bytes,
        });
    }
    Ok(kind)
}

/// Calls `leaf` for every leaf of the message's tree, in stream order.
///
/// # Errors
/// Any [`OctomapError`] but `Lattice`: a bad resolution or id, a stream that is
/// truncated, too deep, too large, or followed by bytes. Leaves before the
/// error have been passed to `leaf`.
pub fn read_leaves(
    msg: &OctomapMsg<'_>,
    options: &OctomapOptions,
    limits: &Limits,
    leaf: impl FnMut(&OctreeLeaf),
) -> Result<StreamSummary, OctomapError> {
    visit(msg, options, limits, &mut Leaves(leaf))
}

fn visit(
    msg: &OctomapMsg<'_>,
    options: &OctomapOptions,
    limits: &Limits,
    visitor: &mut impl TreeVisitor,
) -> Result<StreamSummary, OctomapError> {
    let kind = check_message(msg, options, limits)?;
    let settings = ReadSettings {
        threshold: options.threshold,
        max_nodes: limits.max_octree_nodes,
        allow_trailing: options.allow_trailing_bytes,
    };
    if msg.binary {
        stream::read_binary(msg.data, &settings, visitor)
    } else {
        stream::read_full(msg.data, kind, &settings, visitor)
    }
}

/// The shortest stream (bytes) whose leaves are rasterised on a second thread (see
/// [`OctomapOptions::parallel`]): below it, starting the thread costs more than it saves.
pub const PARALLEL_BYTES: usize = 1 << 16;

/// Leaves handed from the reading thread to the rasterising one at a time.
const BATCH_LEAVES: usize = 8192;

/// Reads the stream on a second thread, which merges sibling leaves of one state and hands
/// the leaves over in batches (at most 8 in flight), and rasterises them on the caller's,
/// in the stream's order: `None` if that thread cannot be started (nothing was read then).
fn read_beside(
    msg: &OctomapMsg<'_>,
    options: &OctomapOptions,
    limits: &Limits,
    raster: &mut LeafRaster<'_>,
) -> Option<Result<StreamSummary, OctomapError>> {
    let (full_tx, full_rx) = mpsc::sync_channel::<Vec<OctreeLeaf>>(8);
    let (empty_tx, empty_rx) = mpsc::channel::<Vec<OctreeLeaf>>();
    std::thread::scope(|scope| {
        let reader = std::thread::Builder::new()
            .name("octomap reader".into())
            .spawn_scoped(scope, move || {
                let mut merging = MergeLeaves::new(Batches::new(full_tx, empty_rx, BATCH_LEAVES));
                let result = visit(msg, options, limits, &mut merging);
                merging.inner.flush();
                result
            })
            .ok()?;
        // Ends when the reader is done and has dropped its sender.
        for batch in full_rx.iter() {
            for leaf in &batch {
                raster.leaf(leaf);
            }
            // The reader may be done already: then nobody needs the buffer back.
            let _ = empty_tx.send(batch);
        }
        Some(
            reader
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
        )
    })
}

/// Turns `Octomap` messages into frames, reusing its working buffers.
///
/// ```
/// use chronotope_occupancy::{Encoding, Lattice, OctomapMsg, OctomapOptions, OctomapRasterizer, VoxelFrame};
/// // A binary stream whose root has one occupied child (child 7: x, y, z >= 0),
/// // a leaf of 2^15 cells: it covers the whole positive octant.
/// let data = [0u8, 0b1000_0000];
/// let msg = OctomapMsg { binary: true, id: "OcTree", resolution: 0.1, data: &data };
/// let lattice = Lattice::new([-0.2, 0.0, 0.0], 0.1, [4, 1, 1]).unwrap();
/// let mut raster = OctomapRasterizer::new(OctomapOptions::new());
/// let mut frame = VoxelFrame::new();
/// raster.rasterize(&msg, &lattice, Encoding::Percent, &mut frame).unwrap();
/// assert_eq!(frame.data(), &[255, 255, 100, 100]);
/// ```
#[derive(Debug, Default)]
pub struct OctomapRasterizer {
    options: OctomapOptions,
    limits: Limits,
    rows: BitRows,
    free: FreeFractions,
    fine: FineSpans,
}

impl OctomapRasterizer {
    /// A rasteriser with the default [`Limits`].
    pub fn new(options: OctomapOptions) -> Self {
        Self::with_limits(options, Limits::default())
    }

    /// A rasteriser with the given limits.
    pub fn with_limits(options: OctomapOptions, limits: Limits) -> Self {
        OctomapRasterizer {
            options,
            limits,
            rows: BitRows::default(),
            free: FreeFractions::default(),
            fine: FineSpans::default(),
        }
    }

    /// The options.
    pub fn options(&self) -> &OctomapOptions {
        &self.options
    }

    /// Rasterises `msg` onto `lattice` into `out` (overwritten; its allocation kept).
    ///
    /// # Errors
    /// [`OctomapError`] naming what is wrong; `out` is then left as it was.
    pub fn rasterize(
        &mut self,
        msg: &OctomapMsg<'_>,
        lattice: &Lattice,
        encoding: Encoding,
        out: &mut VoxelFrame,
    ) -> Result<OctomapStats, OctomapError> {
        check_message(msg, &self.options, &self.limits)?;
        let needs_free = encoding == Encoding::Percent || self.options.unknown_occupied;
        let voxels = lattice.voxel_count();
        let work = lattice.row_bytes().saturating_add(if needs_free {
            voxels.saturating_mul(4)
        } else {
            0
        });
        lattice.check(&self.limits, encoding, work)?;

        self.rows.reset(lattice.size());
        if needs_free {
            self.free.prepare(lattice.size());
        }
        let kl = KeyLattice::new(lattice, msg.resolution);
        self.fine.prepare(&kl);
        let mut raster = LeafRaster {
            kl,
            rows: &mut self.rows,
            free: if needs_free {
                Some(&mut self.free)
            } else {
                None
            },
            leaves_in: 0,
            edge_v: kl.edges_by_depth(),
            fine: &self.fine,
        };
        let beside = needs_free
            && self.options.parallel
            && msg.data.len() >= PARALLEL_BYTES
            && crate::several_cores();
        let read = if beside {
            read_beside(msg, &self.options, &self.limits, &mut raster)
        } else {
            None
        };
        // Merging siblings of one state pays where free leaves are
        // accumulated; for occupied bits alone it costs more than it saves.
        let result = match read {
            Some(result) => result,
            None if needs_free => {
                let mut merging = MergeLeaves::new(&mut raster);
                visit(msg, &self.options, &self.limits, &mut merging)
            }
            None => visit(msg, &self.options, &self.limits, &mut raster),
        };
        let leaves_in = raster.leaves_in;
        let summary = match result {
            Ok(summary) => summary,
            Err(e) => {
                if needs_free {
                    self.free.clean();
                }
                return Err(e);
            }
        };
        let leaves_in_lattice = leaves_in;
        let mut stats = OctomapStats {
            stream: summary,
            leaves_in_lattice,
            ..Default::default()
        };

        // Tolerances: none where every overlap is exact, else a little over
        // the rounding of f32 sums.
        let (full_below, percent_slack) = if kl.exact {
            (1.0f32, 0.0)
        } else {
            (1.0 - 1e-4, 1e-2)
        };
        let data = out.begin(*lattice, encoding);
        match encoding {
            Encoding::Bits => {
                if self.options.unknown_occupied {
                    self.free.mark_partly_unknown(&mut self.rows, full_below);
                }
                stats.occupied_voxels = self.rows.count_ones();
                self.rows.pack_bits(data);
            }
            Encoding::Percent => {
                let (occupied, unknown) = self.free.write_percent(&self.rows, percent_slack, data);
                stats.occupied_voxels = occupied;
                stats.unknown_voxels = unknown;
            }
        }
        Ok(stats)
    }
}
