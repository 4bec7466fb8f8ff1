//! A 4D bounding-volume hierarchy over lattice boxes (one per tet), and its queries.
//!
//! - [`Aabb4`]: closed integer boxes; touching boxes overlap (the exact tet test decides).
//! - [`Bvh`]: a binary tree of boxes in one flat node array with `u32` indices, leaves of
//!   at most [`Bvh::LEAF_SIZE`] items. Built by sorting item centres along a 4D Morton
//!   curve and splitting each range at its highest differing bit, i.e. at the spatial
//!   median of the longest axis of its cell (one scale for all axes, so long axes are
//!   split first). Ranges whose codes tie are re-quantised on their own bounds, so
//!   clustered items far from the rest still get a good tree. All buffers are kept in the
//!   tree and reused by the next [`Bvh::build`].
//! - Queries: [`overlapping_pairs`] (tree against tree, every overlapping item pair
//!   once), [`Bvh::segment_candidates`] and [`Bvh::ray_candidates`] (exact rational slab
//!   test, for the crossing-count inside test of DESIGN §4). Walks use an explicit stack
//!   in a reusable [`TraverseWorkspace`]: no recursion, no allocation after warm-up.
//! - [`Forest`]: a tree grown piece by piece (a subtree per slab as a stream arrives),
//!   joined under a balanced top at the end.
//! - [`top_pairs`] and [`overlapping_pairs_under`] split a tree-against-tree walk into
//!   independent sub-walks (for a later parallel version).
//!
//! Relies only on [`LatticePoint`](crate::LatticePoint); knows nothing of meshes
//! beyond a vertex table and index quadruples.

mod aabb;
mod build;
mod forest;
mod pairs;
mod segment;

pub use aabb::Aabb4;
pub use forest::Forest;
pub use pairs::{
    any_within, overlapping_boxes_under, overlapping_pairs, overlapping_pairs_under, top_pairs,
    try_overlapping_pairs, NodePair,
};

/// Why a tree could not be built.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BvhError {
    /// More items than `u32` node indices can address (a tree of n items has up to
    /// 2n - 1 nodes).
    #[error(
        "{items} items is over the limit of {max} per tree (split the mesh into several trees)"
    )]
    TooManyItems {
        /// Items received.
        items: usize,
        /// [`Bvh::MAX_ITEMS`].
        max: usize,
    },
    /// A tet refers to a vertex that does not exist.
    #[error("tet {tet} refers to vertex {vertex} but there are only {vertices} vertices")]
    VertexOutOfRange {
        /// Index of the tet.
        tet: usize,
        /// The bad vertex index.
        vertex: u32,
        /// Length of the vertex table.
        vertices: usize,
    },
}

/// One tree node: a box and either two children (`count == 0`, children at `first` and
/// `first + 1`) or a leaf's items (`order[first..first + count]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Node {
    /// The box of everything under the node.
    pub aabb: Aabb4,
    /// The first child's index, or the leaf's first slot.
    pub first: u32,
    /// The leaf's number of items; 0 for an internal node.
    pub count: u32,
}

impl Node {
    /// A node to be filled in later (an empty internal node).
    pub(crate) const BLANK: Node = Node {
        aabb: Aabb4::EMPTY,
        first: 0,
        count: 0,
    };

    /// Whether the node is a leaf (it holds items, not children).
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    /// A leaf's slots: indices into [`Bvh::leaf_boxes`] and [`Bvh::order`].
    #[inline]
    pub fn slots(&self) -> std::ops::Range<usize> {
        self.first as usize..(self.first + self.count) as usize
    }
}

/// Buffers used only while building, kept for the next build.
#[derive(Clone, Default)]
struct BuildScratch {
    codes: Vec<u64>,
    codes_tmp: Vec<u64>,
    order_tmp: Vec<u32>,
    /// Pending ranges: (node, lo, hi).
    ranges: Vec<(u32, u32, u32)>,
    /// Boxes of tets for [`Bvh::build_tets`].
    tet_boxes: Vec<Aabb4>,
}

/// A 4D AABB tree over a list of item boxes (item `i` is the `i`-th box given to
/// [`build`](Bvh::build)).
///
/// ```
/// use chronotope_kernel::{overlapping_pairs, Aabb4, Bvh, TraverseWorkspace};
/// let a = Bvh::from_boxes(&[Aabb4::new([0; 4], [1; 4]), Aabb4::new([5; 4], [6; 4])])?;
/// let b = Bvh::from_boxes(&[Aabb4::new([1, 1, 1, 1], [2, 2, 2, 2])])?;
/// let mut ws = TraverseWorkspace::new();
/// let mut pairs = Vec::new();
/// overlapping_pairs(&a, &b, &mut ws, |i, j| pairs.push((i, j)));
/// assert_eq!(pairs, [(0, 0)]); // touching at the corner (1, 1, 1, 1) counts
/// # Ok::<(), chronotope_kernel::BvhError>(())
/// ```
#[derive(Clone, Default)]
pub struct Bvh {
    /// Root first. Children come after their parent in a tree built at once; a
    /// [`Forest`]'s top nodes come after the pieces they join.
    pub(crate) nodes: Vec<Node>,
    /// Item boxes in leaf order (empty boxes replaced by [`Aabb4::EMPTY`]).
    pub(crate) leaf_boxes: Vec<Aabb4>,
    /// Item index of each leaf slot.
    pub(crate) order: Vec<u32>,
    scratch: BuildScratch,
}

impl std::fmt::Debug for BuildScratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BuildScratch")
            .field("capacity", &self.codes.capacity())
            .finish()
    }
}

impl std::fmt::Debug for Bvh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bvh")
            .field("items", &self.len())
            .field("nodes", &self.nodes.len())
            .field("aabb", &self.aabb())
            .finish()
    }
}

impl Bvh {
    /// The nodes, the root first (none for no items): for a walk of one's own, e.g. with
    /// the boxes seen through a motion ([`overlapping_pairs`] walks them as they are).
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The items' boxes in leaf order (slot `s` holds item [`order`](Self::order)`[s]`).
    pub fn leaf_boxes(&self) -> &[Aabb4] {
        &self.leaf_boxes
    }

    /// The item in each leaf slot.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    /// Most items per leaf.
    pub const LEAF_SIZE: usize = 4;

    /// Most items per tree: 2^31, so that the up to 2n - 1 node indices fit in `u32`.
    pub const MAX_ITEMS: usize = 1 << 31;

    /// An empty tree (no allocation until the first build).
    pub fn new() -> Self {
        Self::default()
    }

    /// A tree over `boxes`.
    ///
    /// # Errors
    /// [`BvhError::TooManyItems`] over [`Bvh::MAX_ITEMS`] boxes.
    pub fn from_boxes(boxes: &[Aabb4]) -> Result<Self, BvhError> {
        let mut t = Self::new();
        t.build(boxes)?;
        Ok(t)
    }

    /// A tree over the boxes of `tets` (indices into `vertices`), item `i` being tet `i`.
    /// For a mesh `m` (`chronotope_mesh::TetMesh`, a layer above this one):
    /// `Bvh::from_tets(&m.vertices, &m.tets)`.
    ///
    /// # Errors
    /// [`BvhError::VertexOutOfRange`] for a bad vertex index, [`BvhError::TooManyItems`]
    /// over [`Bvh::MAX_ITEMS`] tets.
    pub fn from_tets(
        vertices: &[crate::LatticePoint],
        tets: &[[u32; 4]],
    ) -> Result<Self, BvhError> {
        let mut t = Self::new();
        t.build_tets(vertices, tets)?;
        Ok(t)
    }

    /// Number of items.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Whether the tree has no items.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// Number of nodes (at most 2·len - 1).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Box of the root: the union of all item boxes ([`Aabb4::EMPTY`] for an empty tree
    /// or one of empty boxes only).
    pub fn aabb(&self) -> Aabb4 {
        self.nodes.first().map_or(Aabb4::EMPTY, |n| n.aabb)
    }

    /// Renumbers the items in leaf order (from now on item `k` is the `k`-th leaf slot) and
    /// returns, for each new index, the item's old index, so that the caller can reorder
    /// its items alike: walks then visit items in memory order.
    pub fn renumber_in_leaf_order(&mut self) -> Vec<u32> {
        let old = std::mem::take(&mut self.order);
        self.order = (0..old.len() as u32).collect();
        old
    }

    /// Becomes the tree of `src`'s items mapped by x_k → mul_k·x_k + add_k on each axis,
    /// reusing this tree's buffers (placing a body again and again allocates nothing).
    /// With every `mul_k > 0` the map is increasing on each axis, so it maps each box onto
    /// the box of the mapped items and keeps every containment: the mapped tree is valid
    /// without a rebuild. Empty boxes stay empty. `false`, with this tree unchanged, if
    /// some `mul_k` is not positive or a coordinate would leave the `i32` range.
    pub fn map_axes_from(&mut self, src: &Bvh, mul: [i64; 4], add: [i64; 4]) -> bool {
        let Some(apply) = axis_map(src, mul, add) else {
            return false;
        };
        self.nodes.clear();
        self.nodes.extend(src.nodes.iter().map(|n| Node {
            aabb: apply(&n.aabb),
            ..*n
        }));
        self.leaf_boxes.clear();
        self.leaf_boxes.extend(src.leaf_boxes.iter().map(apply));
        self.order.clone_from(&src.order);
        true
    }

    /// Becomes `src`'s tree (the same nodes, leaves and leaf order) with every box replaced
    /// by the smallest box holding its image under the affine map x → L·x + b, found by
    /// interval arithmetic (exact: per axis, Σ_j min and max of L_kj·min_j and L_kj·max_j).
    /// The image of a box inside another lies inside the other's image, so every node
    /// still holds its children and items and the tree is valid for the mapped items; its
    /// boxes are a little larger than the items' own (under a rotation, up to √2 across the
    /// turned axes), never smaller. Reuses this tree's buffers. `false`, with this tree
    /// unusable until the next map or build, if an image leaves the `i32` range.
    pub fn map_affine_from(&mut self, src: &Bvh, matrix: [[i64; 4]; 4], shift: [i64; 4]) -> bool {
        // The root's image bounds every other box's: if it fits, every one does.
        if src
            .nodes
            .first()
            .is_some_and(|r| r.aabb.affine_image(&matrix, &shift).is_none())
        {
            return false;
        }
        let image = |b: &Aabb4| b.affine_image(&matrix, &shift).unwrap_or(Aabb4::EMPTY);
        self.nodes.clear();
        self.nodes.extend(src.nodes.iter().map(|n| Node {
            aabb: image(&n.aabb),
            ..*n
        }));
        self.leaf_boxes.clear();
        self.leaf_boxes.extend(src.leaf_boxes.iter().map(image));
        self.order.clone_from(&src.order);
        true
    }

    /// [`map_axes_from`](Self::map_axes_from) this tree itself, in place.
    pub fn map_axes(&mut self, mul: [i64; 4], add: [i64; 4]) -> bool {
        let Some(apply) = axis_map(self, mul, add) else {
            return false;
        };
        for n in &mut self.nodes {
            n.aabb = apply(&n.aabb);
        }
        for b in &mut self.leaf_boxes {
            *b = apply(b);
        }
        true
    }

    /// Removes all items, keeping every buffer for the next build.
    pub fn clear(&mut self) {
        self.nodes.clear();
        self.leaf_boxes.clear();
        self.order.clear();
    }

    /// Frees the buffers used only while building (about 52 bytes per item kept for the
    /// next [`build`](Self::build)); the tree stays usable and the next build allocates
    /// them again.
    pub fn shrink_scratch(&mut self) {
        self.scratch = BuildScratch::default();
    }

    /// Depth of the tree (0 for empty, 1 for a single leaf). Allocates: for diagnostics.
    pub fn depth(&self) -> usize {
        if self.nodes.is_empty() {
            return 0;
        }
        let (mut max, mut stack) = (0, vec![(0u32, 1usize)]);
        while let Some((n, d)) = stack.pop() {
            max = max.max(d);
            let node = &self.nodes[n as usize];
            if !node.is_leaf() {
                stack.push((node.first, d + 1));
                stack.push((node.first + 1, d + 1));
            }
        }
        max
    }
}

/// The map x_k → mul_k·x_k + add_k of boxes, if every `mul_k > 0` and every box of `t`
/// stays in the `i32` range (checked on the root, which bounds them all).
fn axis_map(t: &Bvh, mul: [i64; 4], add: [i64; 4]) -> Option<impl Fn(&Aabb4) -> Aabb4> {
    if mul.iter().any(|&m| m <= 0) {
        return None;
    }
    let map = move |k: usize, c: i32| {
        i64::from(c)
            .checked_mul(mul[k])
            .and_then(|v| v.checked_add(add[k]))
            .and_then(|v| i32::try_from(v).ok())
    };
    let fits = |b: &Aabb4| {
        b.is_empty() || (0..4).all(|k| map(k, b.min[k]).is_some() && map(k, b.max[k]).is_some())
    };
    if !t.nodes.first().is_none_or(|n| fits(&n.aabb)) {
        return None;
    }
    // Every non-empty box lies within the root's, and the map increases on each axis, so
    // each of its coordinates maps between the root's mapped ones: no product or sum below
    // can overflow, and every result fits in i32 (checked once, above).
    Some(move |b: &Aabb4| {
        if b.is_empty() {
            return *b;
        }
        let mut m = *b;
        for k in 0..4 {
            m.min[k] = (i64::from(b.min[k]) * mul[k] + add[k]) as i32;
            m.max[k] = (i64::from(b.max[k]) * mul[k] + add[k]) as i32;
        }
        m
    })
}

/// Stacks reused by tree walks; keep one per thread and pass it to every query.
#[derive(Debug, Clone, Default)]
pub struct TraverseWorkspace {
    pub(crate) nodes: Vec<u32>,
    pub(crate) pairs: Vec<(u32, u32)>,
}

impl TraverseWorkspace {
    /// An empty workspace (grows to the trees' depth on first use, then stays).
    pub fn new() -> Self {
        Self::default()
    }
}
