//! Validation of tet meshes: closedness with consistent orientation, and hypervolume.
//!
//! A tet [a, b, c, d] induces on its faces the orientation of its boundary
//! ∂[a,b,c,d] = [b,c,d] − [a,c,d] + [a,b,d] − [a,b,c]. A mesh is closed and consistently
//! oriented when every triangle is shared by exactly two tets that induce opposite
//! orientations on it.
//!
//! Hypervolume by the divergence theorem: with tets oriented so that
//! orient4(a, b, c, d, inside) < 0, V = −(1/24) Σ det[a, b, c, d] (exact in i128).

use super::march::TetMesh;
use crate::kernel::{det4_i128, LatticePoint};

/// The result of a closedness check.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ClosedReport {
    /// Distinct triangles.
    pub triangles: u64,
    /// Triangles used by exactly one tet.
    pub unpaired: u64,
    /// Triangles used by more than two tets.
    pub overshared: u64,
    /// Triangles shared by two tets that induce the same orientation.
    pub misoriented: u64,
}

impl ClosedReport {
    /// True if closed and consistently oriented.
    pub fn is_closed(&self) -> bool {
        self.unpaired == 0 && self.overshared == 0 && self.misoriented == 0
    }
}

/// Sorts a triangle's vertex ids and returns the parity of the sort (+1 / −1).
#[inline]
pub fn canonical_triangle<T: Ord + Copy>(mut t: [T; 3]) -> ([T; 3], i8) {
    let mut sign = 1i8;
    if t[0] > t[1] {
        t.swap(0, 1);
        sign = -sign;
    }
    if t[1] > t[2] {
        t.swap(1, 2);
        sign = -sign;
    }
    if t[0] > t[1] {
        t.swap(0, 1);
        sign = -sign;
    }
    (t, sign)
}

/// The four boundary triangles of a tet with their induced orientation signs.
#[inline]
pub fn tet_faces<T: Copy>(t: [T; 4]) -> [([T; 3], i8); 4] {
    [([t[1], t[2], t[3]], 1), ([t[0], t[2], t[3]], -1), ([t[0], t[1], t[3]], 1), ([t[0], t[1], t[2]], -1)]
}

/// Checks that every triangle is shared by exactly two tets with opposite induced
/// orientation. Works on vertex ids: weld first if vertices may be duplicated.
pub fn check_closed(mesh: &TetMesh) -> ClosedReport {
    let mut faces: Vec<([u32; 3], i8)> = Vec::with_capacity(mesh.tets.len() * 4);
    for t in &mesh.tets {
        for (f, s) in tet_faces(*t) {
            let (k, p) = canonical_triangle(f);
            faces.push((k, s * p));
        }
    }
    pair_faces(faces)
}

/// Groups oriented triangles and counts how they pair up.
pub fn pair_faces<K: Ord + Copy>(mut faces: Vec<(K, i8)>) -> ClosedReport {
    faces.sort_unstable_by(|a, b| a.0.cmp(&b.0));
    let mut r = ClosedReport::default();
    let mut i = 0;
    while i < faces.len() {
        let mut j = i + 1;
        while j < faces.len() && faces[j].0 == faces[i].0 {
            j += 1;
        }
        r.triangles += 1;
        match j - i {
            1 => r.unpaired += 1,
            2 => {
                if faces[i].1 == faces[i + 1].1 {
                    r.misoriented += 1;
                }
            }
            _ => r.overshared += 1,
        }
        i = j;
    }
    r
}

/// 24 × hypervolume in lattice units (exact): −Σ det[a, b, c, d]. Only meaningful for a
/// closed mesh (then it does not depend on the origin).
pub fn hypervolume24(mesh: &TetMesh) -> i128 {
    hypervolume24_about(mesh, [0, 0, 0, 0])
}

/// Like [`hypervolume24`] with coordinates taken relative to `origin` (keeps numbers small).
pub fn hypervolume24_about(mesh: &TetMesh, origin: LatticePoint) -> i128 {
    let rel = |p: &LatticePoint| [p[0] - origin[0], p[1] - origin[1], p[2] - origin[2], p[3] - origin[3]];
    -mesh
        .tets
        .iter()
        .map(|t| {
            let [a, b, c, d] = t.map(|v| rel(&mesh.vertices[v as usize]));
            det4_i128(&a, &b, &c, &d)
        })
        .sum::<i128>()
}

/// 6 × the 3D volume (lattice units) enclosed by oriented triangles in a hyperplane of
/// constant t, each given with its induced sign; `sign_of_outward` is +1 if the induced
/// orientation is the outward one of the enclosed solid.
pub fn volume6_of_triangles(tris: &[([[i32; 3]; 3], i8)]) -> i128 {
    tris.iter()
        .map(|(t, s)| {
            let m = |p: &[i32; 3]| p.map(i128::from);
            let (a, b, c) = (m(&t[0]), m(&t[1]), m(&t[2]));
            let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                + a[2] * (b[0] * c[1] - b[1] * c[0]);
            i128::from(*s) * det
        })
        .sum()
}
