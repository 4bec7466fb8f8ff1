//! Tree construction: Morton sort of item centres, top-down split at the highest
//! differing bit, bounds bottom-up.
//!
//! Why Morton rather than binned SAH: the items are small tets of similar size spread over
//! a surface, where the spatial median of the longest axis is close to the SAH choice, and
//! a radix sort plus one linear pass is several times faster than O(n log n) binning
//! (1.5 M tets in a few tens of ms).

use super::{Aabb4, BuildScratch, Bvh, BvhError, Node};
use crate::LatticePoint;

/// Bits per axis in a Morton code (4 × 16 = 64).
const BITS: u32 = 16;

/// Spreads the low 16 bits of `v` to every fourth bit.
#[inline]
fn spread4(v: u64) -> u64 {
    let mut x = v & 0xFFFF;
    x = (x | (x << 24)) & 0x0000_00FF_0000_00FF;
    x = (x | (x << 12)) & 0x000F_000F_000F_000F;
    x = (x | (x << 6)) & 0x0303_0303_0303_0303;
    x = (x | (x << 3)) & 0x1111_1111_1111_1111;
    x
}

/// Quantiser of doubled centres: `(c - origin) >> shift` fits in [`BITS`] bits on every
/// axis, with one shift for all axes so that cells are cubes.
#[derive(Clone, Copy)]
struct Quantiser {
    origin: [i64; 4],
    shift: u32,
}

impl Quantiser {
    /// From the bounds of the doubled centres, `None` if all centres coincide.
    fn new(cmin: [i64; 4], cmax: [i64; 4]) -> Option<Self> {
        // Bounds of no centre at all are inverted: saturate rather than overflow.
        let extent = (0..4)
            .map(|k| cmax[k].saturating_sub(cmin[k]))
            .max()
            .unwrap_or(0);
        if extent <= 0 {
            return None;
        }
        let bits = 64 - (extent as u64).leading_zeros();
        Some(Self {
            origin: cmin,
            shift: bits.saturating_sub(BITS),
        })
    }

    /// Morton code of the box centre. Branch-free: an empty box gets some clamped code,
    /// which only affects where it sits in the tree (its centre is within 2^32 of the
    /// origin, so nothing overflows).
    #[inline]
    fn code(&self, b: &Aabb4) -> u64 {
        let c = b.doubled_centre();
        let q = |k: usize| ((c[k] - self.origin[k]) >> self.shift).clamp(0, 0xFFFF) as u64;
        (spread4(q(0)) << 3) | (spread4(q(1)) << 2) | (spread4(q(2)) << 1) | spread4(q(3))
    }
}

/// Bounds of doubled centres (inverted while empty).
#[derive(Clone, Copy)]
pub(super) struct CentreBounds {
    lo: [i64; 4],
    hi: [i64; 4],
}

impl CentreBounds {
    const EMPTY: Self = Self {
        lo: [i64::MAX; 4],
        hi: [i64::MIN; 4],
    };

    /// Adds the centre of `b` unless `b` is empty.
    #[inline]
    fn add(&mut self, b: &Aabb4) {
        if b.is_empty() {
            return;
        }
        let c = b.doubled_centre();
        for ((lo, hi), c) in self.lo.iter_mut().zip(self.hi.iter_mut()).zip(c) {
            *lo = (*lo).min(c);
            *hi = (*hi).max(c);
        }
    }

    pub(super) fn of(boxes: impl Iterator<Item = Aabb4>) -> Self {
        let mut cb = Self::EMPTY;
        boxes.for_each(|b| cb.add(&b));
        cb
    }

    fn quantiser(&self) -> Option<Quantiser> {
        Quantiser::new(self.lo, self.hi)
    }
}

/// Stable LSD radix sort of `codes` (carrying `order`), 8 bits per pass; passes whose
/// digit is the same for all keys are skipped.
fn radix_sort(codes: &mut [u64], order: &mut [u32], codes_tmp: &mut [u64], order_tmp: &mut [u32]) {
    let n = codes.len();
    if n < 2 {
        return;
    }
    let mut hist = [[0u32; 256]; 8];
    for &c in codes.iter() {
        for (d, h) in hist.iter_mut().enumerate() {
            h[((c >> (8 * d)) & 0xFF) as usize] += 1;
        }
    }
    let (codes_tmp, order_tmp) = (&mut codes_tmp[..n], &mut order_tmp[..n]);
    // `in_tmp`: the current data is in the scratch buffers.
    let mut in_tmp = false;
    for (d, h) in hist.iter().enumerate() {
        if h.iter().any(|&c| c as usize == n) {
            continue;
        }
        let mut offset = [0u32; 256];
        let mut sum = 0;
        for (o, &c) in offset.iter_mut().zip(h.iter()) {
            *o = sum;
            sum += c;
        }
        let shift = 8 * d;
        let (src_c, src_o, dst_c, dst_o): (&[u64], &[u32], &mut [u64], &mut [u32]) = if in_tmp {
            (codes_tmp, order_tmp, codes, order)
        } else {
            (codes, order, codes_tmp, order_tmp)
        };
        for (&c, &o) in src_c.iter().zip(src_o.iter()) {
            let slot = &mut offset[((c >> shift) & 0xFF) as usize];
            dst_c[*slot as usize] = c;
            dst_o[*slot as usize] = o;
            *slot += 1;
        }
        in_tmp = !in_tmp;
    }
    if in_tmp {
        codes.copy_from_slice(codes_tmp);
        order.copy_from_slice(order_tmp);
    }
}

impl Bvh {
    /// Rebuilds the tree over `boxes` (item `i` is `boxes[i]`), reusing all buffers of
    /// the previous builds (they only grow, so rebuilding at a steady size does not allocate).
    ///
    /// Empty boxes (`min > max` on some axis) are kept as items that overlap nothing.
    ///
    /// # Errors
    /// [`BvhError::TooManyItems`] over [`Bvh::MAX_ITEMS`] boxes (the tree is then empty).
    pub fn build(&mut self, boxes: &[Aabb4]) -> Result<(), BvhError> {
        self.build_with(boxes, CentreBounds::of(boxes.iter().copied()))
    }

    /// [`build`](Self::build) with the centre bounds of `boxes` already known.
    fn build_with(&mut self, boxes: &[Aabb4], centres: CentreBounds) -> Result<(), BvhError> {
        self.clear();
        check_count(boxes.len())?;
        let Self {
            nodes,
            leaf_boxes,
            order,
            scratch,
        } = self;
        build_into(
            boxes.len(),
            |i| boxes[i],
            centres,
            scratch,
            order,
            nodes,
            leaf_boxes,
            0,
        );
        Ok(())
    }

    /// Rebuilds the tree over the boxes of `tets` (indices into `vertices`), reusing
    /// buffers like [`build`](Self::build).
    ///
    /// # Errors
    /// [`BvhError::VertexOutOfRange`] for a bad vertex index, [`BvhError::TooManyItems`]
    /// over [`Bvh::MAX_ITEMS`] tets (the tree is then empty).
    pub fn build_tets(
        &mut self,
        vertices: &[LatticePoint],
        tets: &[[u32; 4]],
    ) -> Result<(), BvhError> {
        self.clear();
        check_count(tets.len())?;
        // Indices are checked in one pass first, so that the box loop has no error path.
        let bad = tets.iter().enumerate().find_map(|(t, tet)| {
            tet.iter()
                .find(|&&v| v as usize >= vertices.len())
                .map(|&v| (t, v))
        });
        if let Some((tet, vertex)) = bad {
            return Err(BvhError::VertexOutOfRange {
                tet,
                vertex,
                vertices: vertices.len(),
            });
        }
        let mut boxes = std::mem::take(&mut self.scratch.tet_boxes);
        boxes.clear();
        boxes.extend(tets.iter().map(|tet| {
            let mut b = Aabb4::from_point(vertices[tet[0] as usize]);
            for &v in &tet[1..] {
                b.grow(&vertices[v as usize]);
            }
            b
        }));
        let centres = CentreBounds::of(boxes.iter().copied());
        let result = self.build_with(&boxes, centres);
        self.scratch.tet_boxes = boxes;
        result
    }
}

/// Builds a tree over the `n` boxes `box_of(0..n)` at the end of `nodes` and `leaf_boxes`:
/// its root is the first node pushed, children point to absolute node indices, and leaves
/// to absolute leaf slots (`item_base` plus the slot among the `n`). `order` becomes, for
/// each of these slots, the index of the item there. The boxes are asked for, not stored
/// (a caller with tets computes each from four vertices, several times, rather than hold
/// 32 bytes an item). A [`Bvh`] is built this way into its own empty buffers; a
/// [`Forest`](super::Forest) builds each piece into the forest's, so that no piece tree is
/// ever copied. `n` is at most [`Bvh::MAX_ITEMS`].
#[allow(clippy::too_many_arguments)]
pub(super) fn build_into(
    n: usize,
    box_of: impl Fn(usize) -> Aabb4,
    centres: CentreBounds,
    s: &mut BuildScratch,
    order: &mut Vec<u32>,
    nodes: &mut Vec<Node>,
    leaf_boxes: &mut Vec<Aabb4>,
    item_base: u32,
) {
    order.clear();
    if n == 0 {
        return;
    }
    s.codes.clear();
    match centres.quantiser() {
        Some(qz) => s.codes.extend((0..n).map(|i| qz.code(&box_of(i)))),
        None => s.codes.resize(n, 0),
    }
    order.extend(0..n as u32);
    s.codes_tmp.resize(n, 0);
    s.order_tmp.resize(n, 0);
    radix_sort(&mut s.codes, order, &mut s.codes_tmp, &mut s.order_tmp);

    // Top-down: split ranges, creating both children next to each other.
    // At most 2n - 1 nodes, but about 2n / 3 in practice (0.67 n over the 128³
    // machine-tool cell's pieces): room for n is reserved, so the walk below rarely
    // reallocates and a rebuild at the same size rarely allocates, while reserving the
    // bound would hold three times what is used (recycled pages are resident). A forest
    // sized for all its items beforehand (`Forest::reserve_items`) never grows here; one
    // that was not grows by doubling, not piece by piece.
    let root = nodes.len();
    nodes.reserve(n);
    nodes.push(Node::BLANK);
    s.ranges.clear();
    s.ranges.push((root as u32, 0, n as u32));
    while let Some((node, lo, hi)) = s.ranges.pop() {
        let (lo_u, hi_u) = (lo as usize, hi as usize);
        if hi_u - lo_u <= Bvh::LEAF_SIZE {
            nodes[node as usize] = Node {
                aabb: Aabb4::EMPTY,
                first: item_base + lo,
                count: hi - lo,
            };
            continue;
        }
        let mid = lo_u
            + split_range(
                &box_of,
                &mut s.codes[lo_u..hi_u],
                &mut order[lo_u..hi_u],
                &mut s.codes_tmp[lo_u..hi_u],
                &mut s.order_tmp[lo_u..hi_u],
            );
        let child = nodes.len() as u32;
        nodes[node as usize].first = child;
        nodes.push(Node::BLANK);
        nodes.push(Node::BLANK);
        s.ranges.push((child, lo, mid as u32));
        s.ranges.push((child + 1, mid as u32, hi));
    }

    // Leaf boxes in leaf order; then bounds, children before parents.
    leaf_boxes.reserve(n);
    leaf_boxes.extend(order.iter().map(|&i| {
        let b = box_of(i as usize);
        if b.is_empty() {
            Aabb4::EMPTY
        } else {
            b
        }
    }));
    for k in (root..nodes.len()).rev() {
        let node = nodes[k];
        let (first, count) = (node.first as usize, node.count as usize);
        let aabb = if node.is_leaf() {
            leaf_boxes[first..first + count]
                .iter()
                .fold(Aabb4::EMPTY, |a, b| a.union_valid(b))
        } else {
            nodes[first].aabb.union_valid(&nodes[first + 1].aabb)
        };
        nodes[k].aabb = aabb;
    }
}

/// Refuses item counts whose node indices would not fit in `u32`.
fn check_count(items: usize) -> Result<(), BvhError> {
    if items > Bvh::MAX_ITEMS {
        return Err(BvhError::TooManyItems {
            items,
            max: Bvh::MAX_ITEMS,
        });
    }
    Ok(())
}

/// Where to split a range of more than one item (returns `1..len`), sorted by `codes`:
/// at the first item with the highest differing bit set. When all codes tie, the range
/// is re-quantised on its own centre bounds and re-sorted (this always separates items
/// whose centres differ); if all centres coincide, it is halved.
fn split_range(
    box_of: &impl Fn(usize) -> Aabb4,
    codes: &mut [u64],
    order: &mut [u32],
    codes_tmp: &mut [u64],
    order_tmp: &mut [u32],
) -> usize {
    let len = codes.len();
    let (first, last) = (codes[0], codes[len - 1]);
    if first == last {
        let Some(qz) = CentreBounds::of(order.iter().map(|&i| box_of(i as usize))).quantiser()
        else {
            return len / 2;
        };
        for (c, &i) in codes.iter_mut().zip(order.iter()) {
            *c = qz.code(&box_of(i as usize));
        }
        radix_sort(codes, order, codes_tmp, order_tmp);
        if codes[0] == codes[len - 1] {
            // Only empty boxes differ (code 0): cannot happen, but halving is always safe.
            return len / 2;
        }
    }
    let (first, last) = (codes[0], codes[len - 1]);
    let bit = 63 - (first ^ last).leading_zeros();
    let mask = !0u64 << bit;
    let prefix = first & mask;
    // Codes are sorted: those sharing the prefix (bit clear) come first.
    codes
        .partition_point(|&c| c & mask == prefix)
        .clamp(1, len - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_interleaves() {
        assert_eq!(spread4(0b1011), 0b1_0000_0001_0001);
        assert_eq!(spread4(0xFFFF), 0x1111_1111_1111_1111);
    }

    #[test]
    fn count_limit() {
        assert!(check_count(Bvh::MAX_ITEMS).is_ok());
        assert_eq!(
            check_count(Bvh::MAX_ITEMS + 1),
            Err(BvhError::TooManyItems {
                items: Bvh::MAX_ITEMS + 1,
                max: Bvh::MAX_ITEMS
            })
        );
    }

    #[test]
    fn radix_sorts() {
        let mut codes: Vec<u64> = (0..1000u64)
            .map(|i| i.wrapping_mul(0x9E37_79B9_7F4A_7C15))
            .collect();
        let mut order: Vec<u32> = (0..1000).collect();
        let (mut ct, mut ot) = (vec![0; 1000], vec![0; 1000]);
        let mut expect: Vec<(u64, u32)> =
            codes.iter().copied().zip(order.iter().copied()).collect();
        expect.sort();
        radix_sort(&mut codes, &mut order, &mut ct, &mut ot);
        let got: Vec<(u64, u32)> = codes.into_iter().zip(order).collect();
        assert_eq!(got, expect);
    }
}
