//! Closed axis-aligned boxes on the 4D lattice.

use crate::LatticePoint;

/// A closed axis-aligned box `[min, max]` in (x, y, z, t) lattice coordinates.
///
/// Boxes are closed: two boxes that only share a face, an edge or a corner *do* overlap
/// (the exact tet-tet test decides later whether touching is interference, DESIGN §4).
/// Zero extent on some axes is allowed and common (cap tets lie in a `t = const`
/// hyperplane). A box with `min > max` on some axis is *empty*: it contains no point and
/// overlaps nothing; [`Aabb4::EMPTY`] is the canonical one and the identity of
/// [`union`](Aabb4::union).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Aabb4 {
    /// Smallest coordinate on each axis (inclusive).
    pub min: LatticePoint,
    /// Largest coordinate on each axis (inclusive).
    pub max: LatticePoint,
}

impl Default for Aabb4 {
    /// The empty box.
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb4 {
    /// The empty box (`min = i32::MAX`, `max = i32::MIN`): overlaps nothing, identity of union.
    pub const EMPTY: Aabb4 = Aabb4 {
        min: [i32::MAX; 4],
        max: [i32::MIN; 4],
    };

    /// The box `[min, max]` (empty if `min > max` on some axis).
    #[inline]
    pub const fn new(min: LatticePoint, max: LatticePoint) -> Self {
        Self { min, max }
    }

    /// The degenerate box holding the single point `p`.
    #[inline]
    pub const fn from_point(p: LatticePoint) -> Self {
        Self { min: p, max: p }
    }

    /// The smallest box holding all `points` ([`Aabb4::EMPTY`] for none).
    ///
    /// ```
    /// use chronotope_kernel::Aabb4;
    /// let b = Aabb4::from_points(&[[0, 5, 2, 1], [3, -1, 2, 1]]);
    /// assert_eq!(b, Aabb4::new([0, -1, 2, 1], [3, 5, 2, 1]));
    /// assert!(Aabb4::from_points(&[]).is_empty());
    /// ```
    pub fn from_points(points: &[LatticePoint]) -> Self {
        let mut b = Self::EMPTY;
        for p in points {
            b.grow(p);
        }
        b
    }

    /// Whether the box contains no point (`min > max` on some axis).
    #[inline]
    pub fn is_empty(&self) -> bool {
        (0..4).any(|k| self.min[k] > self.max[k])
    }

    /// Extends the box to hold `p`.
    #[inline]
    pub fn grow(&mut self, p: &LatticePoint) {
        for ((lo, hi), &c) in self.min.iter_mut().zip(self.max.iter_mut()).zip(p) {
            *lo = (*lo).min(c);
            *hi = (*hi).max(c);
        }
    }

    /// The smallest box holding both (an empty operand is ignored).
    #[inline]
    pub fn union(&self, other: &Aabb4) -> Aabb4 {
        if self.is_empty() {
            return *other;
        }
        if other.is_empty() {
            return *self;
        }
        self.union_valid(other)
    }

    /// Union of two non-empty boxes, or of anything with [`Aabb4::EMPTY`] (whose
    /// extreme coordinates drop out of min/max).
    #[inline]
    pub(crate) fn union_valid(&self, other: &Aabb4) -> Aabb4 {
        let mut r = *self;
        for k in 0..4 {
            r.min[k] = r.min[k].min(other.min[k]);
            r.max[k] = r.max[k].max(other.max[k]);
        }
        r
    }

    /// The common part (empty if the boxes do not overlap).
    #[inline]
    pub fn intersection(&self, other: &Aabb4) -> Aabb4 {
        let mut r = *self;
        for k in 0..4 {
            r.min[k] = r.min[k].max(other.min[k]);
            r.max[k] = r.max[k].min(other.max[k]);
        }
        r
    }

    /// Whether the closed boxes share at least one point (touching counts; an empty box
    /// overlaps nothing).
    ///
    /// ```
    /// use chronotope_kernel::Aabb4;
    /// let a = Aabb4::new([0; 4], [2; 4]);
    /// let b = Aabb4::new([2, 2, 2, 2], [5, 5, 5, 5]); // shares one corner
    /// assert!(a.overlaps(&b));
    /// assert!(!a.overlaps(&Aabb4::new([3; 4], [5; 4])));
    /// assert!(!a.overlaps(&Aabb4::EMPTY));
    /// ```
    #[inline]
    pub fn overlaps(&self, other: &Aabb4) -> bool {
        // max of mins <= min of maxes on every axis: correct for empty boxes too, and
        // branch-free so that it vectorises.
        let mut ok = true;
        for k in 0..4 {
            ok &= self.min[k].max(other.min[k]) <= self.max[k].min(other.max[k]);
        }
        ok
    }

    /// Whether `p` lies in the closed box.
    #[inline]
    pub fn contains_point(&self, p: &LatticePoint) -> bool {
        (0..4).all(|k| self.min[k] <= p[k] && p[k] <= self.max[k])
    }

    /// Whether `other` lies inside this box (an empty `other` lies in every box).
    #[inline]
    pub fn contains(&self, other: &Aabb4) -> bool {
        other.is_empty()
            || (0..4).all(|k| self.min[k] <= other.min[k] && other.max[k] <= self.max[k])
    }

    /// The smallest box holding the image of this one under the affine map x → L·x + b
    /// (`matrix` L, `shift` b), by interval arithmetic: per axis, b_k plus the sums of the
    /// smaller and of the larger of L_kj·min_j and L_kj·max_j (exact). The image of a box
    /// inside another lies inside the other's image. Empty for an empty box; `None` if a
    /// coordinate leaves the `i32` range.
    pub fn affine_image(&self, matrix: &[[i64; 4]; 4], shift: &[i64; 4]) -> Option<Aabb4> {
        if self.is_empty() {
            return Some(Aabb4::EMPTY);
        }
        let mut out = Aabb4::EMPTY;
        for k in 0..4 {
            let (mut lo, mut hi) = (i128::from(shift[k]), i128::from(shift[k]));
            for j in 0..4 {
                let m = i128::from(matrix[k][j]);
                let (x, y) = (m * i128::from(self.min[j]), m * i128::from(self.max[j]));
                lo += x.min(y);
                hi += x.max(y);
            }
            out.min[k] = i32::try_from(lo).ok()?;
            out.max[k] = i32::try_from(hi).ok()?;
        }
        Some(out)
    }

    /// `min + max` per axis (twice the centre, exact).
    #[inline]
    pub(crate) fn doubled_centre(&self) -> [i64; 4] {
        [0, 1, 2, 3].map(|k| i64::from(self.min[k]) + i64::from(self.max[k]))
    }
}
