//! Exact segment-box and ray-box tests, and the tree queries built on them.
//!
//! The slab test (Kay and Kajiya 1986) in exact arithmetic: on each axis with a non-zero
//! direction the line `p + s·d` is inside the slab `[min, max]` for `s` in a rational
//! interval `[a/δ, c/δ]` (δ = |d| > 0); the segment meets the box iff the intersection of
//! these intervals with `[0, 1]` (segment) or `[0, ∞)` (ray) is non-empty. Axes with a zero
//! direction need `min <= p <= max`. Numerators and denominators stay below 2^64 for any
//! `i64` end points, so cross-multiplied comparisons are exact in `u128` with a sign split.

use super::{Aabb4, Bvh, TraverseWorkspace};
use std::cmp::Ordering;
use std::ops::ControlFlow;

/// A segment or ray prepared for many box tests.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LineQuery {
    /// Start point.
    p: [i64; 4],
    /// Direction (q - p for a segment; exact in i128).
    d: [i128; 4],
    /// Bounding box of the segment or ray (`i64::MIN`/`MAX` for unbounded ends): a cheap
    /// integer reject before the exact test.
    lo: [i64; 4],
    hi: [i64; 4],
    /// Ray (`s` in `[0, ∞)`) rather than segment (`s` in `[0, 1]`).
    ray: bool,
    /// `p` and 1/d in floating point for the filter of [`LineQuery::hits`], if every
    /// coordinate of `p` and `d` is below 2^50 in magnitude (then each box distance
    /// `min − p` and each `d` is exact in `f64`).
    float: Option<([f64; 4], [f64; 4])>,
}

/// Below this magnitude the filter's inputs are exact in `f64`.
const FLOAT_EXACT: i128 = 1 << 50;

/// Relative margin of the filter: each slab parameter (min − p)·(1/d) carries two
/// roundings, within 2.2e-16 each, so 1e-12 leaves room to spare.
const FLOAT_MARGIN: f64 = 1e-12;

/// `p` and 1/d as `f64` for the filter, if all are below [`FLOAT_EXACT`] in magnitude.
fn float_parts(p: &[i64; 4], d: &[i128; 4]) -> Option<([f64; 4], [f64; 4])> {
    let small = (0..4).all(|k| i128::from(p[k]).abs() < FLOAT_EXACT && d[k].abs() < FLOAT_EXACT);
    small.then(|| {
        (
            p.map(|c| c as f64),
            d.map(|c| if c == 0 { 0.0 } else { 1.0 / c as f64 }),
        )
    })
}

/// `a/b` compared to `c/e`, for `b, e > 0` and `|a|, |c|, b, e < 2^64`.
#[inline]
fn cmp_frac(a: i128, b: u128, c: i128, e: u128) -> Ordering {
    match (a < 0, c < 0) {
        (false, true) => Ordering::Greater,
        (true, false) => Ordering::Less,
        (false, false) => (a.unsigned_abs() * e).cmp(&(c.unsigned_abs() * b)),
        (true, true) => (c.unsigned_abs() * b).cmp(&(a.unsigned_abs() * e)),
    }
}

impl LineQuery {
    /// The closed segment from `p` to `q`.
    pub(crate) fn segment(p: [i64; 4], q: [i64; 4]) -> Self {
        let mut s = Self {
            p,
            d: [0; 4],
            lo: [0; 4],
            hi: [0; 4],
            ray: false,
            float: None,
        };
        for k in 0..4 {
            s.d[k] = i128::from(q[k]) - i128::from(p[k]);
            s.lo[k] = p[k].min(q[k]);
            s.hi[k] = p[k].max(q[k]);
        }
        s.float = float_parts(&p, &s.d);
        s
    }

    /// The closed ray from `p` in direction `d` (a point query if `d = 0`).
    pub(crate) fn ray(p: [i64; 4], d: [i64; 4]) -> Self {
        let bound =
            |k: usize, inf: i64, dir: Ordering| if d[k].cmp(&0) == dir { inf } else { p[k] };
        let d = d.map(i128::from);
        Self {
            p,
            d,
            lo: [0, 1, 2, 3].map(|k| bound(k, i64::MIN, Ordering::Less)),
            hi: [0, 1, 2, 3].map(|k| bound(k, i64::MAX, Ordering::Greater)),
            ray: true,
            float: float_parts(&p, &d),
        }
    }

    /// Whether the segment or ray meets the closed box `b` (exact; false for empty boxes).
    #[inline]
    pub(crate) fn hits(&self, b: &Aabb4) -> bool {
        let mut inside = true;
        for k in 0..4 {
            inside &= i64::from(b.max[k]) >= self.lo[k] && i64::from(b.min[k]) <= self.hi[k];
        }
        if !inside {
            return false;
        }
        if let Some(verdict) = self.float_verdict(b) {
            return verdict;
        }
        self.exact_hits(b)
    }

    /// The slab test in floating point, or `None` where it is too close to call. Each
    /// computed parameter is within a relative [`FLOAT_MARGIN`] of the exact one and the
    /// clamp to 0 is exact, so the running lower end `l` (≥ 0) and upper end `h` are too
    /// (a negative `h` has the exact sign): `h < 0` or `l > h·(1 + margin)` is a miss,
    /// `l·(1 + margin) < h` a hit, anything else goes to the exact test.
    #[inline]
    fn float_verdict(&self, b: &Aabb4) -> Option<bool> {
        let (p, inv) = self.float?;
        let (mut l, mut h) = (0.0f64, if self.ray { f64::INFINITY } else { 1.0 });
        for k in 0..4 {
            if self.d[k] == 0 {
                continue;
            }
            let s0 = (f64::from(b.min[k]) - p[k]) * inv[k];
            let s1 = (f64::from(b.max[k]) - p[k]) * inv[k];
            let (near, far) = if inv[k] > 0.0 { (s0, s1) } else { (s1, s0) };
            l = l.max(near);
            h = h.min(far);
        }
        if h < 0.0 || l > h * (1.0 + FLOAT_MARGIN) {
            Some(false)
        } else if l * (1.0 + FLOAT_MARGIN) < h {
            Some(true)
        } else {
            None
        }
    }

    /// The slab test in exact arithmetic.
    fn exact_hits(&self, b: &Aabb4) -> bool {
        // Running max of the lower ends and min of the upper ends, as fractions.
        let (mut ln, mut ld) = (0i128, 1u128);
        let (mut hn, mut hd, mut h_inf) = (1i128, 1u128, self.ray);
        for k in 0..4 {
            let d = self.d[k];
            if d == 0 {
                // The bounding-box test above already checked min <= p <= max here.
                continue;
            }
            let (p, lo, hi) = (
                i128::from(self.p[k]),
                i128::from(b.min[k]),
                i128::from(b.max[k]),
            );
            let (a, c) = if d > 0 {
                (lo - p, hi - p)
            } else {
                (p - hi, p - lo)
            };
            let den = d.unsigned_abs();
            if cmp_frac(a, den, ln, ld) == Ordering::Greater {
                (ln, ld) = (a, den);
            }
            if h_inf || cmp_frac(c, den, hn, hd) == Ordering::Less {
                (hn, hd, h_inf) = (c, den, false);
            }
        }
        h_inf || cmp_frac(ln, ld, hn, hd) != Ordering::Greater
    }
}

impl Aabb4 {
    /// Whether the closed segment `pq` meets the closed box (exact for any `i64` end
    /// points; `p` and `q` may lie far outside the `i32` lattice range).
    ///
    /// ```
    /// use chronotope_kernel::Aabb4;
    /// let b = Aabb4::new([0; 4], [2; 4]);
    /// assert!(b.intersects_segment([-5, 1, 1, 1], [1 << 40, 1, 1, 1]));
    /// // Passes the corner (2, 2) of the x-y square at s = 1/2 exactly: touching counts.
    /// assert!(b.intersects_segment([0, 4, 1, 1], [4, 0, 1, 1]));
    /// assert!(!b.intersects_segment([1, 5, 1, 1], [5, 1, 1, 1]));
    /// ```
    pub fn intersects_segment(&self, p: [i64; 4], q: [i64; 4]) -> bool {
        LineQuery::segment(p, q).hits(self)
    }

    /// Whether the closed ray from `p` in direction `d` meets the closed box (exact; a
    /// zero `d` tests the point `p`).
    pub fn intersects_ray(&self, p: [i64; 4], d: [i64; 4]) -> bool {
        LineQuery::ray(p, d).hits(self)
    }
}

impl Bvh {
    /// Calls `f` once for every item whose box meets the closed segment `pq`, exactly
    /// (the same set as [`Aabb4::intersects_segment`] over all items, in tree order).
    ///
    /// `p` and `q` may lie anywhere in `i64` space, e.g. `q` a far point outside the
    /// mesh's bounding box for the crossing-count inside test (DESIGN §4). `p = q` is a
    /// point query. No allocation once `ws` has grown to the tree's depth.
    pub fn segment_candidates(
        &self,
        p: [i64; 4],
        q: [i64; 4],
        ws: &mut TraverseWorkspace,
        mut f: impl FnMut(u32),
    ) {
        let query = LineQuery::segment(p, q);
        let _ = self.line_candidates(&query, ws, |i| {
            f(i);
            ControlFlow::<()>::Continue(())
        });
    }

    /// Like [`segment_candidates`](Self::segment_candidates) but `f` may stop the walk
    /// early by returning [`ControlFlow::Break`], whose value is returned.
    pub fn try_segment_candidates<B>(
        &self,
        p: [i64; 4],
        q: [i64; 4],
        ws: &mut TraverseWorkspace,
        f: impl FnMut(u32) -> ControlFlow<B>,
    ) -> ControlFlow<B> {
        self.line_candidates(&LineQuery::segment(p, q), ws, f)
    }

    /// Calls `f` once for every item whose box meets the closed ray `{p + s·d : s >= 0}`,
    /// exactly. A zero `d` is a point query at `p`.
    pub fn ray_candidates(
        &self,
        p: [i64; 4],
        d: [i64; 4],
        ws: &mut TraverseWorkspace,
        mut f: impl FnMut(u32),
    ) {
        let query = LineQuery::ray(p, d);
        let _ = self.line_candidates(&query, ws, |i| {
            f(i);
            ControlFlow::<()>::Continue(())
        });
    }

    /// [`segment_candidates`](Self::segment_candidates) for the tree mapped by
    /// x_k → mul_k·x_k + add_k on each axis (every `mul_k > 0`), without mapping it: each
    /// box is mapped as the walk reaches it. `p` and `q` are in the mapped coordinates. A
    /// box whose mapped corners leave the `i32` range is taken as met (the caller's exact
    /// test of each item decides), so the items given are those a mapped copy of the tree
    /// gives, and perhaps more.
    pub fn segment_candidates_mapped(
        &self,
        p: [i64; 4],
        q: [i64; 4],
        mul: [i64; 4],
        add: [i64; 4],
        ws: &mut TraverseWorkspace,
        mut f: impl FnMut(u32),
    ) {
        let query = LineQuery::segment(p, q);
        let hits = |b: &Aabb4| {
            if b.is_empty() {
                return false;
            }
            let map = |k: usize, c: i32| {
                i64::from(c)
                    .checked_mul(mul[k])
                    .and_then(|v| v.checked_add(add[k]))
                    .and_then(|v| i32::try_from(v).ok())
            };
            let mut m = *b;
            for k in 0..4 {
                match (map(k, b.min[k]), map(k, b.max[k])) {
                    (Some(lo), Some(hi)) => (m.min[k], m.max[k]) = (lo, hi),
                    _ => return true,
                }
            }
            query.hits(&m)
        };
        let Some(root) = self.nodes.first() else {
            return;
        };
        if !hits(&root.aabb) {
            return;
        }
        let stack = &mut ws.nodes;
        stack.clear();
        stack.push(0);
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            let (first, count) = (node.first as usize, node.count as usize);
            if count > 0 {
                for i in first..first + count {
                    if hits(&self.leaf_boxes[i]) {
                        f(self.order[i]);
                    }
                }
            } else {
                for c in [first, first + 1] {
                    if hits(&self.nodes[c].aabb) {
                        stack.push(c as u32);
                    }
                }
            }
        }
    }

    fn line_candidates<B>(
        &self,
        query: &LineQuery,
        ws: &mut TraverseWorkspace,
        mut f: impl FnMut(u32) -> ControlFlow<B>,
    ) -> ControlFlow<B> {
        let Some(root) = self.nodes.first() else {
            return ControlFlow::Continue(());
        };
        if !query.hits(&root.aabb) {
            return ControlFlow::Continue(());
        }
        let stack = &mut ws.nodes;
        stack.clear();
        stack.push(0);
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            let (first, count) = (node.first as usize, node.count as usize);
            if count > 0 {
                for i in first..first + count {
                    if query.hits(&self.leaf_boxes[i]) {
                        f(self.order[i])?;
                    }
                }
            } else {
                for c in [first, first + 1] {
                    if query.hits(&self.nodes[c].aabb) {
                        stack.push(c as u32);
                    }
                }
            }
        }
        ControlFlow::Continue(())
    }
}
