//! Octree leaves onto the lattice: each leaf is a cube in key units, cut by the
//! voxel cubes; occupied leaves set the bits of every voxel they overlap, free
//! leaves add the fraction of each voxel they cover.
//!
//! All geometry is done in key units (1 = the tree's resolution, 0 = the tree's
//! min corner), where leaf faces are integers. When the lattice's edge is a
//! power of two of the tree's and its origin lies on the tree's grid (within
//! 1e-9, snapped), every overlap is a dyadic fraction and every sum below is
//! exact; otherwise overlaps thinner than [`SLIVER`] voxel edges are taken as
//! faces touching, not as overlap.

use super::free::FreeFractions;
use super::stream::{OctreeLeaf, TreeVisitor, KEY_OFFSET, TREE_DEPTH};
use crate::lattice::Lattice;
use crate::rows::BitRows;
use std::sync::mpsc::{Receiver, SyncSender};

/// Overlaps thinner than this fraction of a voxel edge count as touching faces.
pub(crate) const SLIVER: f64 = 1e-9;

/// The lattice in the tree's key units.
#[derive(Clone, Copy, Debug)]
pub(crate) struct KeyLattice {
    /// Lattice origin, key units.
    origin: [f64; 3],
    /// 1 / (voxel edge in key units).
    inv_edge: f64,
    n: [usize; 3],
    nf: [f64; 3],
    /// Every overlap is exact (see the module doc).
    pub exact: bool,
}

/// The voxels a leaf overlaps along one axis, and the parts of the first and
/// last of them it covers (the voxels between are covered whole).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Span {
    pub i0: usize,
    pub i1: usize,
    lo: f64,
    hi: f64,
    w0: f64,
    w1: f64,
}

impl Span {
    /// Fraction of voxel `i`'s edge the leaf covers (branch-free: the loops
    /// over a leaf's voxels are too short for a predictor to learn).
    #[inline(always)]
    pub fn weight(&self, i: usize) -> f64 {
        cover(self.lo, self.hi, i)
    }
}

/// Covered part of voxel `i` by the interval `lo .. hi` (voxel units).
#[inline(always)]
fn cover(lo: f64, hi: f64, i: usize) -> f64 {
    // Through i64: one instruction, where usize -> f64 takes several.
    let a = i as i64 as f64;
    (hi.min(a + 1.0) - lo.max(a)).max(0.0)
}

fn snap(value: f64, step: f64) -> (f64, bool) {
    let r = (value / step).round() * step;
    if (value - r).abs() <= 1e-9 * value.abs().max(1.0) {
        (r, true)
    } else {
        (value, false)
    }
}

impl KeyLattice {
    pub(crate) fn new(lattice: &Lattice, tree_resolution: f64) -> Self {
        let raw_edge = lattice.resolution() / tree_resolution;
        let log2 = raw_edge.log2().round();
        let pow2 = log2.exp2();
        let power_of_two =
            (-40.0..=40.0).contains(&log2) && (raw_edge - pow2).abs() <= 1e-9 * raw_edge;
        let edge = if power_of_two { pow2 } else { raw_edge };
        let step = if power_of_two { edge.min(1.0) } else { 1.0 };
        let mut exact = power_of_two;
        let mut origin = [0.0; 3];
        for (a, o) in origin.iter_mut().enumerate() {
            let raw = lattice.origin()[a] / tree_resolution + f64::from(KEY_OFFSET);
            let (v, on_grid) = snap(raw, step);
            *o = v;
            exact &= on_grid;
        }
        let size = lattice.size();
        KeyLattice {
            origin,
            inv_edge: 1.0 / edge,
            n: size.map(|n| n as usize),
            nf: size.map(f64::from),
            exact,
        }
    }

    /// The voxels along `axis` that the key interval `key .. key + len`
    /// overlaps, `len_v` being `len` in voxel units.
    ///
    /// No `floor`/`ceil` calls (library calls on baseline x86-64): the values
    /// are clamped non-negative first, where truncation is floor.
    #[inline(always)]
    pub(crate) fn span(&self, axis: usize, key: u32, len_v: f64) -> Option<Span> {
        let lo = (f64::from(key) - self.origin[axis]) * self.inv_edge;
        let hi = lo + len_v;
        let nf = self.nf[axis];
        if hi <= SLIVER || lo >= nf - SLIVER {
            return None;
        }
        // First voxel: floor(lo + SLIVER), at least 0.
        let i0 = (lo + SLIVER).max(0.0) as i64 as usize;
        // Last voxel: ceil(hi - SLIVER) - 1, at most n - 1; hi - SLIVER > 0 here.
        let top = (hi - SLIVER).min(nf);
        let t = top as i64;
        let i1 = if t as f64 == top { t - 1 } else { t } as usize;
        let i1 = i1.min(self.n[axis] - 1);
        if i1 < i0 {
            return None;
        }
        Some(Span {
            i0,
            i1,
            lo,
            hi,
            w0: cover(lo, hi, i0),
            w1: cover(lo, hi, i1),
        })
    }

    /// Key range of the finest cells that may overlap the lattice along `axis`.
    fn key_range(&self, axis: usize) -> (u32, u32) {
        let lo = self.origin[axis].floor().clamp(0.0, 65536.0);
        let hi = (self.origin[axis] + self.nf[axis] / self.inv_edge)
            .ceil()
            .clamp(0.0, 65536.0);
        (lo as u32, hi as u32)
    }

    /// A leaf's edge in voxel units, by depth.
    pub(crate) fn edges_by_depth(&self) -> [f64; 17] {
        std::array::from_fn(|d| f64::from(1u32 << (16 - d)) * self.inv_edge)
    }
}

/// The spans of every finest cell (depth 16) along each axis, looked up
/// rather than computed for the leaves that are most of a map.
#[derive(Debug, Default)]
pub(crate) struct FineSpans {
    base: [u32; 3],
    spans: [Vec<Option<Span>>; 3],
}

/// Longest table kept per axis; a lattice that spans more cells computes spans.
const FINE_TABLE_MAX: u32 = 1 << 14;

impl FineSpans {
    pub(crate) fn prepare(&mut self, kl: &KeyLattice) {
        let one = kl.edges_by_depth()[TREE_DEPTH as usize];
        for a in 0..3 {
            let (lo, hi) = kl.key_range(a);
            self.base[a] = lo;
            self.spans[a].clear();
            if hi - lo <= FINE_TABLE_MAX {
                self.spans[a].extend((lo..hi).map(|k| kl.span(a, k, one)));
            }
        }
    }

    /// The span of the finest cell at `key`: from the table, or computed
    /// when the table is off; `None` if it misses the lattice.
    #[inline(always)]
    fn get(&self, kl: &KeyLattice, axis: usize, key: u32, one: f64) -> Option<Span> {
        let table = &self.spans[axis];
        if table.is_empty() {
            return kl.span(axis, key, one);
        }
        table
            .get(key.wrapping_sub(self.base[axis]) as usize)
            .copied()
            .flatten()
    }
}

/// Rasterises leaves: sets occupied bits, accumulates free fractions.
pub(crate) struct LeafRaster<'a> {
    pub kl: KeyLattice,
    pub rows: &'a mut BitRows,
    /// Free fraction of each voxel; `None` when free leaves do not matter
    /// (bits with unknown counted free).
    pub free: Option<&'a mut FreeFractions>,
    /// Leaves that overlap the lattice.
    pub leaves_in: u64,
    /// Leaf edge in voxel units by depth ([`KeyLattice::edges_by_depth`]).
    pub edge_v: [f64; 17],
    /// Spans of the finest cells.
    pub fine: &'a FineSpans,
}

impl LeafRaster<'_> {
    #[inline(always)]
    pub(crate) fn leaf(&mut self, leaf: &OctreeLeaf) {
        if !leaf.occupied && self.free.is_none() {
            return;
        }
        let len_v = self.edge_v[leaf.depth as usize];
        let span = |a: usize| {
            if leaf.depth == TREE_DEPTH {
                self.fine.get(&self.kl, a, leaf.key_min[a], len_v)
            } else {
                self.kl.span(a, leaf.key_min[a], len_v)
            }
        };
        let Some(sx) = span(0) else {
            return;
        };
        let Some(sy) = span(1) else {
            return;
        };
        let Some(sz) = span(2) else {
            return;
        };
        self.leaves_in += 1;
        let one_voxel = sx.i0 == sx.i1 && sy.i0 == sy.i1 && sz.i0 == sz.i1;
        if leaf.occupied {
            if one_voxel {
                self.rows.set(sx.i0, sy.i0, sz.i0);
                return;
            }
            for z in sz.i0..=sz.i1 {
                for y in sy.i0..=sy.i1 {
                    let start = self.rows.row_start(y, z);
                    self.rows.set_range(start, sx.i0, sx.i1);
                }
            }
            return;
        }
        let Some(free) = self.free.as_deref_mut() else {
            return;
        };
        if one_voxel {
            // The whole leaf lies in one voxel (common for leaves finer than
            // the lattice): its volume in voxel units, clipped if it pokes out.
            let w = sx.w0 * sy.w0 * sz.w0;
            free.row_mut(sy.i0, sz.i0, sx.i0, sx.i0)[0] += w as f32;
            return;
        }
        let (wx0, wx1) = (sx.w0, sx.w1);
        for z in sz.i0..=sz.i1 {
            let wz = sz.weight(z);
            for y in sy.i0..=sy.i1 {
                let wyz = sy.weight(y) * wz;
                let row = free.row_mut(y, z, sx.i0, sx.i1);
                if let [only] = row {
                    *only += (wyz * wx0) as f32;
                    continue;
                }
                let last = row.len() - 1;
                row[0] += (wyz * wx0) as f32;
                row[last] += (wyz * wx1) as f32;
                let inner = wyz as f32;
                for v in &mut row[1..last] {
                    *v += inner;
                }
            }
        }
    }
}

impl TreeVisitor for LeafRaster<'_> {
    #[inline(always)]
    fn leaf(&mut self, leaf: &OctreeLeaf) {
        LeafRaster::leaf(self, leaf)
    }
}

/// One inner node being merged: its leaf children so far.
#[derive(Clone, Copy)]
struct MergeFrame {
    key: [u32; 3],
    depth: u32,
    /// Min keys of the leaf children so far (at depth `depth + 1`), one array per axis: a
    /// child's key arrives as three 4-byte stores, and a `[u32; 3]` copy read them back with
    /// an 8-byte load that the processor cannot forward from them (a stall per leaf: the
    /// full 5 cm stream onto 128³ `percent` took 10.8 ms with it, 10.5 ms without).
    keys: [[u32; 8]; 3],
    /// Bit `i`: leaf child `i` (in arrival order) is occupied.
    occupied: u8,
    n: u8,
    /// No child so far was an inner node that did not merge.
    whole: bool,
}

/// Merges the leaves of an inner node whose 8 children are all leaves in one
/// state (occupied or free) into one leaf of the node's size before passing
/// them on, bottom-up: the full stream keeps siblings apart when their
/// log-odds differ, but for occupancy they are one cube. Exactly the same
/// voxels, fewer leaves to rasterise; log-odds are not passed on. Buffers at
/// most 8 leaves per level.
pub(crate) struct MergeLeaves<V> {
    pub inner: V,
    stack: [MergeFrame; TREE_DEPTH as usize + 1],
    sp: usize,
}

impl<V: TreeVisitor> MergeLeaves<V> {
    pub(crate) fn new(inner: V) -> Self {
        let frame = MergeFrame {
            key: [0; 3],
            depth: 0,
            keys: [[0; 8]; 3],
            occupied: 0,
            n: 0,
            whole: true,
        };
        MergeLeaves {
            inner,
            stack: [frame; TREE_DEPTH as usize + 1],
            sp: 0,
        }
    }

    #[inline(always)]
    fn push_child(&mut self, key: [u32; 3], occupied: bool) {
        let f = &mut self.stack[self.sp - 1];
        // A node has at most 8 children; a stream cannot make it more.
        if f.n < 8 {
            let n = f.n as usize;
            f.keys[0][n] = key[0];
            f.keys[1][n] = key[1];
            f.keys[2][n] = key[2];
            f.occupied |= u8::from(occupied) << f.n;
            f.n += 1;
        }
    }
}

impl<V: TreeVisitor> TreeVisitor for MergeLeaves<V> {
    #[inline(always)]
    fn leaf(&mut self, leaf: &OctreeLeaf) {
        if self.sp == 0 {
            self.inner.leaf(leaf);
        } else {
            self.push_child(leaf.key_min, leaf.occupied);
        }
    }

    #[inline(always)]
    fn enter(&mut self, key: [u32; 3], depth: u32) {
        if let Some(f) = self.stack.get_mut(self.sp) {
            f.key = key;
            f.depth = depth;
            f.occupied = 0;
            f.n = 0;
            f.whole = true;
            self.sp += 1;
        }
    }

    #[inline(always)]
    fn leave(&mut self) {
        if self.sp == 0 {
            return;
        }
        self.sp -= 1;
        let f = &self.stack[self.sp];
        let (key, depth, n, occupied, whole) = (f.key, f.depth, f.n, f.occupied, f.whole);
        if whole && n == 8 && (occupied == 0 || occupied == 0xff) {
            let merged = OctreeLeaf {
                key_min: key,
                depth,
                occupied: occupied == 0xff,
                log_odds: None,
            };
            self.leaf(&merged);
            return;
        }
        for i in 0..n as usize {
            let keys = &self.stack[self.sp].keys;
            let leaf = OctreeLeaf {
                key_min: [keys[0][i], keys[1][i], keys[2][i]],
                depth: depth + 1,
                occupied: occupied >> i & 1 == 1,
                log_odds: None,
            };
            self.inner.leaf(&leaf);
        }
        if self.sp > 0 {
            self.stack[self.sp - 1].whole = false;
        }
    }
}

/// Leaves gathered into batches and sent to another thread (which sends the emptied
/// buffers back, to be filled again).
pub(crate) struct Batches {
    buf: Vec<OctreeLeaf>,
    full: SyncSender<Vec<OctreeLeaf>>,
    empty: Receiver<Vec<OctreeLeaf>>,
    size: usize,
}

impl Batches {
    pub(crate) fn new(
        full: SyncSender<Vec<OctreeLeaf>>,
        empty: Receiver<Vec<OctreeLeaf>>,
        size: usize,
    ) -> Self {
        Batches {
            buf: Vec::with_capacity(size),
            full,
            empty,
            size: size.max(1),
        }
    }

    /// Sends the leaves gathered so far, if any.
    pub(crate) fn flush(&mut self) {
        if self.buf.is_empty() {
            return;
        }
        let next = match self.empty.try_recv() {
            Ok(mut used) => {
                used.clear();
                used
            }
            Err(_) => Vec::with_capacity(self.size),
        };
        let batch = std::mem::replace(&mut self.buf, next);
        // The receiver only goes away if its thread panicked; that panic is what counts.
        let _ = self.full.send(batch);
    }
}

impl TreeVisitor for Batches {
    #[inline(always)]
    fn leaf(&mut self, leaf: &OctreeLeaf) {
        self.buf.push(*leaf);
        if self.buf.len() >= self.size {
            self.flush();
        }
    }
}
