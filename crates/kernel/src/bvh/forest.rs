//! A tree grown piece by piece: each piece of items (one slab of a stream) gets its own
//! subtree when it arrives, and [`Forest::finish`] joins the subtrees under a balanced top,
//! so that the cost of building a body's tree is spread over its stream and only the top
//! (one node per piece) is left for the end.
//!
//! The pieces of a 4D mesh come in time order and each covers one frame period, so a top
//! split between consecutive pieces is a split along time: the tree a whole-body build
//! would make splits space and time alike, this one splits time first. Items are numbered
//! in leaf order as they arrive (the tree is born [renumbered](Bvh::renumber_in_leaf_order)).

use super::build::{build_into, CentreBounds};
use super::{Aabb4, BuildScratch, Bvh, BvhError, Node};

/// A tree being grown piece by piece; see the module documentation.
///
/// ```
/// use chronotope_kernel::{overlapping_pairs, Aabb4, Bvh, Forest, TraverseWorkspace};
/// let mut f = Forest::new();
/// // Two pieces; within a piece the items are renumbered in leaf order, so `add` returns
/// // which of the piece's boxes each new item is.
/// let order = f.add(&[Aabb4::new([0; 4], [1; 4]), Aabb4::new([5; 4], [6; 4])])?.to_vec();
/// assert_eq!(order.len(), 2);
/// f.add(&[Aabb4::new([10; 4], [11; 4])])?;
/// let tree = f.finish();
/// let probe = Bvh::from_boxes(&[Aabb4::new([11; 4], [12; 4])])?;
/// let mut pairs = Vec::new();
/// overlapping_pairs(&tree, &probe, &mut TraverseWorkspace::new(), |i, j| pairs.push((i, j)));
/// assert_eq!(pairs, [(2, 0)]);
/// # Ok::<(), chronotope_kernel::BvhError>(())
/// ```
#[derive(Debug, Clone, Default)]
pub struct Forest {
    /// Node 0 is kept for the root; each piece's nodes follow (its own root included).
    tree: Bvh,
    /// Each non-empty piece's root as it will sit in the top (children and items in the
    /// forest's numbering), with its item count and its index in `tree`.
    roots: Vec<(Node, u32, u32)>,
    /// The last piece's items in leaf order, as indices into its boxes.
    piece_order: Vec<u32>,
}

impl Forest {
    /// An empty forest.
    pub fn new() -> Self {
        Self::default()
    }

    /// Items added so far.
    pub fn len(&self) -> usize {
        self.tree.order.len()
    }

    /// Whether no item was added.
    pub fn is_empty(&self) -> bool {
        self.tree.order.is_empty()
    }

    /// Pieces with at least one item added so far.
    pub fn pieces(&self) -> usize {
        self.roots.len()
    }

    /// The pieces grown so far as one tree without a top: walk it from a piece's root
    /// ([`piece_root`](Self::piece_root), e.g. with
    /// [`overlapping_pairs_under`](super::overlapping_pairs_under)), never from node 0.
    pub fn tree_so_far(&self) -> &Bvh {
        &self.tree
    }

    /// The root node (in [`tree_so_far`](Self::tree_so_far)) of the `k`-th non-empty
    /// piece, and its box.
    pub fn piece_root(&self, k: usize) -> Option<(u32, Aabb4)> {
        self.roots.get(k).map(|(n, _, at)| (*at, n.aabb))
    }

    /// Makes room for `items` more items (exactly, where growing would double).
    pub fn reserve_items(&mut self, items: usize) {
        self.tree.leaf_boxes.reserve_exact(items);
        self.tree.order.reserve_exact(items);
        // A piece's build reserves room for one node per item, and uses about two thirds:
        // with room for all the items' nodes (and the root) the pieces never move the
        // nodes built before them.
        self.tree.nodes.reserve_exact(items.saturating_add(1));
    }

    /// Adds a piece: its items become items `len()..len() + boxes.len()` in the piece
    /// tree's leaf order; returns, for each of them, its index in `boxes` (for the caller
    /// to order its own items alike). Nothing is added on error.
    ///
    /// # Errors
    /// [`BvhError::TooManyItems`] if the forest would hold more than [`Bvh::MAX_ITEMS`].
    pub fn add(&mut self, boxes: &[Aabb4]) -> Result<&[u32], BvhError> {
        self.add_with(boxes.len(), |i| boxes[i])
    }

    /// [`add`](Self::add) with the piece's `n` boxes asked for by index rather than stored
    /// (each is asked for a few times).
    ///
    /// # Errors
    /// As [`add`](Self::add).
    pub fn add_with(
        &mut self,
        n: usize,
        box_of: impl Fn(usize) -> Aabb4,
    ) -> Result<&[u32], BvhError> {
        let total = self.len().saturating_add(n);
        if total > Bvh::MAX_ITEMS {
            return Err(BvhError::TooManyItems {
                items: total,
                max: Bvh::MAX_ITEMS,
            });
        }
        // Node indices must stay `u32`: a piece of n items has at most 2n - 1 nodes, and
        // the top two for each piece but one.
        if self.tree.nodes.len() + 2 * n + 2 * (self.roots.len() + 1) > u32::MAX as usize {
            return Err(BvhError::TooManyItems {
                items: total,
                max: Bvh::MAX_ITEMS / 2,
            });
        }
        if n == 0 {
            self.piece_order.clear();
            return Ok(&self.piece_order);
        }
        let t = &mut self.tree;
        if t.nodes.is_empty() {
            t.nodes.push(Node::BLANK);
        }
        let base = t.nodes.len();
        let items = t.order.len() as u32;
        build_into(
            n,
            &box_of,
            CentreBounds::of((0..n).map(&box_of)),
            // Its own buffers: a body is prepared in a few pieces, the largest a cap that
            // fills its volume, and nothing is held for a next piece.
            &mut BuildScratch::default(),
            &mut self.piece_order,
            &mut t.nodes,
            &mut t.leaf_boxes,
            items,
        );
        t.order.extend(items..items + n as u32);
        self.roots.push((t.nodes[base], n as u32, base as u32));
        Ok(&self.piece_order)
    }

    /// The tree over every item added, the pieces joined under a top split at the median
    /// item (one piece: its own tree), its node buffer no larger than its nodes. Each
    /// piece's own root stays as an unused node.
    pub fn finish(self) -> Bvh {
        let Self {
            mut tree, roots, ..
        } = self;
        match roots.len() {
            0 => return Bvh::new(),
            1 => {
                tree.nodes[0] = roots[0].0;
                tree.nodes.shrink_to_fit();
                return tree;
            }
            _ => {}
        }
        // Items before each piece, to split ranges of pieces at their median item.
        let mut before = Vec::with_capacity(roots.len() + 1);
        before.push(0u64);
        for (_, n, _) in &roots {
            before.push(before[before.len() - 1] + u64::from(*n));
        }
        // The top adds two nodes for each piece but one: sized exactly, not doubled.
        tree.nodes.reserve_exact(2 * (roots.len() - 1));
        let mut pending = vec![(0usize, 0usize, roots.len())];
        while let Some((slot, lo, hi)) = pending.pop() {
            if hi - lo == 1 {
                tree.nodes[slot] = roots[lo].0;
                continue;
            }
            let half = (before[lo] + before[hi]) / 2;
            let mid = before[lo..=hi]
                .partition_point(|&b| b <= half)
                .saturating_sub(1)
                .clamp(1, hi - lo - 1)
                + lo;
            let aabb = roots[lo..hi]
                .iter()
                .fold(Aabb4::EMPTY, |a, (r, _, _)| a.union_valid(&r.aabb));
            let child = tree.nodes.len();
            tree.nodes[slot] = Node {
                aabb,
                first: child as u32,
                count: 0,
            };
            tree.nodes.push(Node::BLANK);
            tree.nodes.push(Node::BLANK);
            pending.push((child, lo, mid));
            pending.push((child + 1, mid, hi));
        }
        // Room was made for a node per item, about a third more than a tree uses: given
        // back (glibc shrinks a block in place).
        tree.nodes.shrink_to_fit();
        tree
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{overlapping_pairs, TraverseWorkspace};

    /// Boxes of a pseudo-random stream, in pieces of varying size (empty ones included).
    fn pieces(seed: u64) -> Vec<Vec<Aabb4>> {
        let mut s = seed;
        let mut next = move |m: i32| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((s >> 33) % m as u64) as i32
        };
        (0..9)
            .map(|k| {
                let n = [0, 1, 3, 17, 60][next(5) as usize];
                (0..n)
                    .map(|_| {
                        let lo = [next(40), next(40), next(40), 10 * k + next(3)];
                        let ext = [next(4), next(4), next(4), next(11)];
                        Aabb4::new(lo, [0, 1, 2, 3].map(|i| lo[i] + ext[i]))
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn joined_pieces_find_exactly_the_overlapping_pairs() {
        for seed in 0..40 {
            let ps = pieces(seed);
            let mut f = Forest::new();
            // Items in the forest's numbering, to compare with a brute force.
            let mut items = Vec::new();
            for p in &ps {
                let order = f.add(p).unwrap().to_vec();
                items.extend(order.iter().map(|&i| p[i as usize]));
            }
            assert_eq!(f.len(), items.len());
            let tree = f.finish();
            assert_eq!(tree.len(), items.len());
            let probes: Vec<Aabb4> = pieces(seed + 1000).concat();
            let other = Bvh::from_boxes(&probes).unwrap();
            let mut got = Vec::new();
            overlapping_pairs(&tree, &other, &mut TraverseWorkspace::new(), |i, j| {
                got.push((i, j))
            });
            got.sort_unstable();
            let mut want = Vec::new();
            for (i, a) in items.iter().enumerate() {
                for (j, b) in probes.iter().enumerate() {
                    if a.overlaps(b) {
                        want.push((i as u32, j as u32));
                    }
                }
            }
            assert_eq!(got, want, "seed {seed}");
            // Every node box holds its children's and items' boxes.
            let root = tree.aabb();
            assert!(items.iter().all(|b| root.contains(b)));
        }
    }

    /// A joined tree's top nodes come after the pieces they join: its image under an
    /// affine map holds, at every node, the images of its children and items; under a
    /// positive diagonal map it is the tree mapped on each axis.
    #[test]
    fn a_joined_tree_maps_to_the_images_of_its_boxes() {
        for seed in 0..20 {
            let mut f = Forest::new();
            for p in &pieces(seed) {
                f.add(p).unwrap();
            }
            let tree = f.finish();
            let (mul, add) = ([3, 1, 2, 5], [-7, 11, 0, 4]);
            let mut axes = Bvh::new();
            assert!(axes.map_axes_from(&tree, mul, add));
            let mut diagonal = [[0; 4]; 4];
            for k in 0..4 {
                diagonal[k][k] = mul[k];
            }
            let mut affine = Bvh::new();
            assert!(affine.map_affine_from(&tree, diagonal, add));
            assert_eq!(affine.nodes, axes.nodes, "seed {seed}");
            assert_eq!(affine.leaf_boxes, axes.leaf_boxes);
            assert_eq!(affine.order, axes.order);
            // A turn by 3-4-5 in x-y with time and z scaled by 5.
            let turn = [[3, -4, 0, 0], [4, 3, 0, 0], [0, 0, 5, 0], [0, 0, 0, 5]];
            let mut turned = Bvh::new();
            assert!(turned.map_affine_from(&tree, turn, [1, 2, 3, 4]));
            let mut stack = vec![0usize];
            while let Some(n) = stack.pop() {
                let node = turned.nodes[n];
                let first = node.first as usize;
                if node.is_leaf() {
                    for slot in first..first + node.count as usize {
                        assert!(node.aabb.contains(&turned.leaf_boxes[slot]));
                        let image = tree.leaf_boxes[slot].affine_image(&turn, &[1, 2, 3, 4]);
                        assert_eq!(Some(turned.leaf_boxes[slot]), image);
                    }
                } else {
                    for c in [first, first + 1] {
                        assert!(node.aabb.contains(&turned.nodes[c].aabb), "seed {seed}");
                        stack.push(c);
                    }
                }
            }
        }
    }

    #[test]
    fn no_pieces_or_only_empty_ones_give_an_empty_tree() {
        let mut f = Forest::new();
        f.add(&[]).unwrap();
        let t = f.finish();
        assert!(t.is_empty());
        assert_eq!(t.node_count(), 0);
    }

    #[test]
    fn one_piece_is_its_own_tree() {
        let boxes = pieces(7).concat();
        let mut f = Forest::new();
        f.add(&boxes).unwrap();
        let t = f.finish();
        assert_eq!(t.aabb(), Bvh::from_boxes(&boxes).unwrap().aabb());
        assert_eq!(t.len(), boxes.len());
    }
}
