//! Reading the two octree streams `octomap_msgs` puts in `Octomap.data`, leaf by
//! leaf, with an explicit stack (a hostile stream cannot deepen the call stack)
//! and a node budget (bounded work for any input).
//!
//! The layouts are OctoMap 1.10's (`OccupancyOcTreeBase::writeBinaryNode`,
//! `OcTreeBaseImpl::writeNodesRecurs` and the nodes' `writeData`); README.md of
//! this crate describes them byte by byte.

use super::{OctomapError, TreeKind};

/// Depth of every OctoMap tree: leaves of the resolution's size are at depth 16.
pub const TREE_DEPTH: u32 = 16;
/// Key of the cell whose min corner is at coordinate 0 (`tree_max_val` in OctoMap).
pub const KEY_OFFSET: u32 = 1 << 15;

/// One leaf of an octree, in key units (1 = the tree's resolution).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OctreeLeaf {
    /// Key of the leaf's min corner along x, y, z (0..65536); the leaf covers
    /// `(key - 32768) · resolution .. (key - 32768 + size) · resolution` metres.
    pub key_min: [u32; 3],
    /// Depth of the leaf, 0 (the root) to 16 (a cell of the resolution's size).
    pub depth: u32,
    /// Whether the leaf is occupied: its binary code, or its log-odds at or above
    /// the threshold.
    pub occupied: bool,
    /// The leaf's log-odds in a full stream, `None` in a binary stream.
    pub log_odds: Option<f32>,
}

impl OctreeLeaf {
    /// Edge of the leaf in key units, `2^(16 - depth)`.
    pub fn size(&self) -> u32 {
        1 << (TREE_DEPTH - self.depth)
    }
}

/// What a whole stream held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamSummary {
    /// Nodes read, inner and leaves.
    pub nodes: u64,
    /// Occupied leaves.
    pub occupied_leaves: u64,
    /// Free leaves.
    pub free_leaves: u64,
    /// Deepest depth reached (16 for leaves of the resolution's size).
    pub max_depth: u32,
    /// Bytes the tree took.
    pub bytes_read: u64,
    /// Bytes after the tree (only when trailing bytes are allowed).
    pub trailing_bytes: u64,
}

/// What a stream reader reports, in stream order.
pub(crate) trait TreeVisitor {
    /// A leaf.
    fn leaf(&mut self, leaf: &OctreeLeaf);
    /// An inner node whose children follow, until the matching `leave`.
    fn enter(&mut self, _key: [u32; 3], _depth: u32) {}
    /// The children of the last node entered are done.
    fn leave(&mut self) {}
}

impl<V: TreeVisitor + ?Sized> TreeVisitor for &mut V {
    #[inline(always)]
    fn leaf(&mut self, leaf: &OctreeLeaf) {
        (**self).leaf(leaf)
    }
    #[inline(always)]
    fn enter(&mut self, key: [u32; 3], depth: u32) {
        (**self).enter(key, depth)
    }
    #[inline(always)]
    fn leave(&mut self) {
        (**self).leave()
    }
}

/// A closure as a visitor of leaves alone.
pub(crate) struct Leaves<F>(pub F);

impl<F: FnMut(&OctreeLeaf)> TreeVisitor for Leaves<F> {
    fn leaf(&mut self, leaf: &OctreeLeaf) {
        (self.0)(leaf)
    }
}

#[derive(Clone, Copy, Default)]
struct Frame {
    key: [u32; 3],
    depth: u32,
    /// Binary stream: the remaining 2-bit child codes. Full stream: the
    /// remaining child bits.
    pending: u16,
    /// Offset of the node's child codes (binary) or child mask (full).
    offset: usize,
}

/// Child `child`'s min key from its parent's min key at `parent_depth`.
#[inline(always)]
fn child_key(key: [u32; 3], parent_depth: u32, child: u32) -> [u32; 3] {
    let half = 1u32 << (TREE_DEPTH - parent_depth - 1);
    [
        key[0] + if child & 1 != 0 { half } else { 0 },
        key[1] + if child & 2 != 0 { half } else { 0 },
        key[2] + if child & 4 != 0 { half } else { 0 },
    ]
}

struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
}

impl Cursor<'_> {
    #[inline(always)]
    fn take<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], OctomapError> {
        match self.data.get(self.pos..self.pos + N) {
            Some(b) => {
                self.pos += N;
                Ok(b.try_into().expect("slice of N bytes"))
            }
            None => Err(OctomapError::Truncated {
                offset: self.pos as u64,
                needed: N as u64,
                len: self.data.len() as u64,
                what,
            }),
        }
    }
}

/// Settings of one read.
pub(crate) struct ReadSettings {
    pub threshold: f32,
    pub max_nodes: u64,
    pub allow_trailing: bool,
}

fn count_node(
    summary: &mut StreamSummary,
    max_nodes: u64,
    offset: usize,
) -> Result<(), OctomapError> {
    summary.nodes += 1;
    if summary.nodes > max_nodes {
        return Err(OctomapError::TooManyNodes {
            limit: max_nodes,
            offset: offset as u64,
        });
    }
    Ok(())
}

fn finish(
    cur: &Cursor<'_>,
    summary: &mut StreamSummary,
    allow_trailing: bool,
) -> Result<(), OctomapError> {
    summary.bytes_read = cur.pos as u64;
    let rest = (cur.data.len() - cur.pos) as u64;
    if rest > 0 && !allow_trailing {
        return Err(OctomapError::TrailingBytes {
            offset: cur.pos as u64,
            count: rest,
        });
    }
    summary.trailing_bytes = rest;
    Ok(())
}

/// Reads a binary stream (`writeBinaryData`): per inner node two bytes, two
/// bits per child (`00` unknown, `01` free leaf, `10` occupied leaf, `11` inner
/// node; child `i` at bits `2i..2i+1` of byte `i / 4`), depth first.
pub(crate) fn read_binary(
    data: &[u8],
    settings: &ReadSettings,
    visitor: &mut impl TreeVisitor,
) -> Result<StreamSummary, OctomapError> {
    let mut summary = StreamSummary::default();
    let mut cur = Cursor { data, pos: 0 };
    if data.is_empty() {
        return Ok(summary);
    }
    let mut stack = [Frame::default(); TREE_DEPTH as usize + 1];
    count_node(&mut summary, settings.max_nodes, 0)?;
    let b = cur.take::<2>("the root's child codes")?;
    stack[0] = Frame {
        key: [0; 3],
        depth: 0,
        pending: u16::from_le_bytes(b),
        offset: 0,
    };
    visitor.enter([0; 3], 0);
    let mut sp = 1usize;
    while sp > 0 {
        let f = &mut stack[sp - 1];
        if f.pending == 0 {
            sp -= 1;
            visitor.leave();
            continue;
        }
        let child = f.pending.trailing_zeros() / 2;
        let code = (f.pending >> (2 * child)) & 3;
        f.pending &= !(3 << (2 * child));
        let (key, depth) = (child_key(f.key, f.depth, child), f.depth + 1);
        let code_offset = f.offset + (child / 4) as usize;
        count_node(&mut summary, settings.max_nodes, cur.pos)?;
        summary.max_depth = summary.max_depth.max(depth);
        match code {
            1 | 2 => {
                let occupied = code == 2;
                if occupied {
                    summary.occupied_leaves += 1;
                } else {
                    summary.free_leaves += 1;
                }
                visitor.leaf(&OctreeLeaf {
                    key_min: key,
                    depth,
                    occupied,
                    log_odds: None,
                });
            }
            _ => {
                if depth == TREE_DEPTH {
                    return Err(OctomapError::TooDeep {
                        offset: code_offset as u64,
                    });
                }
                let offset = cur.pos;
                let b = cur.take::<2>("an inner node's child codes")?;
                stack[sp] = Frame {
                    key,
                    depth,
                    pending: u16::from_le_bytes(b),
                    offset,
                };
                sp += 1;
                visitor.enter(key, depth);
            }
        }
    }
    finish(&cur, &mut summary, settings.allow_trailing)?;
    Ok(summary)
}

/// Reads a full stream (`writeData`): per node its value (a little-endian
/// `f32` log-odds, then the kind's extra bytes), then a byte with one bit per
/// existing child, then the children in order, depth first.
pub(crate) fn read_full<V: TreeVisitor>(
    data: &[u8],
    kind: TreeKind,
    settings: &ReadSettings,
    visitor: &mut V,
) -> Result<StreamSummary, OctomapError> {
    let mut summary = StreamSummary::default();
    let mut cur = Cursor { data, pos: 0 };
    if data.is_empty() {
        return Ok(summary);
    }
    let extra = kind.extra_bytes();
    let threshold = settings.threshold;
    // Reads one node: its value and its child mask.
    let node =
        |cur: &mut Cursor<'_>, summary: &mut StreamSummary| -> Result<(f32, u8), OctomapError> {
            count_node(summary, settings.max_nodes, cur.pos)?;
            let at = cur.pos;
            let value = f32::from_le_bytes(cur.take::<4>("a node's log-odds")?);
            if value.is_nan() {
                return Err(OctomapError::NanLogOdds { offset: at as u64 });
            }
            if extra > 0 {
                if cur.pos + extra > cur.data.len() {
                    return Err(OctomapError::Truncated {
                        offset: cur.pos as u64,
                        needed: extra as u64,
                        len: cur.data.len() as u64,
                        what: kind.extra_what(),
                    });
                }
                cur.pos += extra;
            }
            let [mask] = cur.take::<1>("a node's child mask")?;
            Ok((value, mask))
        };
    let emit =
        |visitor: &mut V, summary: &mut StreamSummary, key: [u32; 3], depth: u32, value: f32| {
            let occupied = value >= threshold;
            if occupied {
                summary.occupied_leaves += 1;
            } else {
                summary.free_leaves += 1;
            }
            visitor.leaf(&OctreeLeaf {
                key_min: key,
                depth,
                occupied,
                log_odds: Some(value),
            });
        };
    let (value, mask) = node(&mut cur, &mut summary)?;
    if mask == 0 {
        emit(visitor, &mut summary, [0; 3], 0, value);
        finish(&cur, &mut summary, settings.allow_trailing)?;
        return Ok(summary);
    }
    let mut stack = [Frame::default(); TREE_DEPTH as usize + 1];
    stack[0] = Frame {
        key: [0; 3],
        depth: 0,
        pending: u16::from(mask),
        offset: cur.pos - 1,
    };
    visitor.enter([0; 3], 0);
    let mut sp = 1usize;
    while sp > 0 {
        let f = &mut stack[sp - 1];
        if f.pending == 0 {
            sp -= 1;
            visitor.leave();
            continue;
        }
        let child = f.pending.trailing_zeros();
        f.pending &= f.pending - 1;
        let (key, depth) = (child_key(f.key, f.depth, child), f.depth + 1);
        summary.max_depth = summary.max_depth.max(depth);
        let (value, mask) = node(&mut cur, &mut summary)?;
        if mask == 0 {
            emit(visitor, &mut summary, key, depth, value);
        } else {
            if depth == TREE_DEPTH {
                return Err(OctomapError::TooDeep {
                    offset: (cur.pos - 1) as u64,
                });
            }
            stack[sp] = Frame {
                key,
                depth,
                pending: u16::from(mask),
                offset: cur.pos - 1,
            };
            sp += 1;
            visitor.enter(key, depth);
        }
    }
    finish(&cur, &mut summary, settings.allow_trailing)?;
    Ok(summary)
}
