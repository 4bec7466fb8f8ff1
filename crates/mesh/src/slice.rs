//! Cutting a 4D tet mesh by an axis hyperplane x_k = c into a closed, oriented, welded 3D
//! triangle mesh (the marching paper's §6: docs/methods/marching.md#slicing), and PLY
//! export.
//!
//! A vertex on the plane counts as "+" (at or above c). A tet with vertices on both sides
//! is cut into a triangle (1/3 split) or a quad (2/2 split, two triangles). Each slice point
//! is keyed by the lattice points it comes from: an edge crossing by its two end points,
//! an on-plane vertex by itself; triangles with a repeated key have no area and are
//! dropped. The slice is always closed (every edge is used as often in one direction as in
//! the other) and, for a plane through no mesh vertex, a 2-manifold; a plane through
//! vertices can cut where two sheets of the 4D boundary cross (a saddle), and there an edge
//! may carry four triangles. Keys are global, so slabs can be sliced one at a time as they stream and the
//! pieces weld. Triangles are oriented outward of the 3D section, decided exactly: by which
//! of the tet's vertices lie on which side of the plane and the order they come in (a sign
//! the tet's 4D normal would give, proved in `cut_orientation` and tested against the
//! integer determinant), the normal itself only telling a tet of no volume.
//!
//! If the plane only touches the body (c is the body's lowest coordinate along the axis,
//! e.g. t at its first frame), the "+" rule yields nothing; [`Slicer::finish`] reports that
//! and [`slice_mesh`] then slices again with on-plane vertices counted as "−", which gives the
//! boundary of the touching face: a slice at a frame time always reproduces that frame.

use super::hash::{fast_map, FastMap};
use super::march::TetMesh;
use chronotope_kernel::LatticePoint;
use rayon::prelude::*;
use std::io::{self, Write};

/// A plane coordinate in lattice units, as an exact fraction `num / den` (`den > 0`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlaneValue {
    /// Numerator.
    pub num: i64,
    /// Denominator, positive and at most 2^12 (with lattice scales up to 256 this keeps the
    /// exact orientation test within i128).
    pub den: i64,
}

impl PlaneValue {
    /// An integer lattice coordinate.
    pub fn lattice(v: i64) -> Self {
        Self { num: v, den: 1 }
    }
    /// The nearest multiple of 1/1024 lattice step to a real lattice coordinate.
    pub fn approx(v: f64) -> Self {
        Self {
            num: (v * 1024.0).round() as i64,
            den: 1024,
        }
    }
}

/// A 3D triangle mesh: positions in lattice units of the three remaining axes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions (lattice units, remaining axes in increasing order).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Key {
    Vertex(LatticePoint),
    Edge(LatticePoint, LatticePoint),
}

impl std::hash::Hash for Key {
    /// The coordinates two to a word (a vertex two words, an edge four).
    fn hash<H: std::hash::Hasher>(&self, h: &mut H) {
        let pair = |a: i32, b: i32| u64::from(a as u32) << 32 | u64::from(b as u32);
        match self {
            Key::Vertex(q) => {
                h.write_u64(pair(q[0], q[1]));
                h.write_u64(pair(q[2], q[3]));
            }
            Key::Edge(a, b) => {
                h.write_u64(pair(a[0], a[1]));
                h.write_u64(pair(a[2], a[3]));
                h.write_u64(pair(b[0], b[1]));
                h.write_u64(pair(b[2], b[3]));
            }
        }
    }
}

/// Tets per chunk of [`Slicer::add_par`].
pub const SLICE_CHUNK_TETS: usize = 1 << 15;

/// Streams tets (from any number of slabs or caps) into one slice.
///
/// Each added mesh (or chunk of one) is cut into a [`Part`] whose slice points are keyed by
/// the mesh's vertex ids (one machine word, cheap to hash), then welded into the slice by
/// their lattice [`Key`]s, once per point of the part: the same slice, numbered the same
/// way, as keying every use by lattice points.
#[derive(Debug)]
pub struct Slicer {
    axis: usize,
    c: PlaneValue,
    on_plane_is_plus: bool,
    index: FastMap<Key, u32>,
    mesh: TriMesh,
    /// With [`Slicer::with_sources`]: per triangle, the tet it came from (counted over every
    /// `add`ed mesh in order).
    sources: Option<Vec<u32>>,
    tets_seen: u32,
}

/// The cut of some tets of one mesh: its slice points keyed by the mesh's vertex ids (an
/// edge by its two ids, an on-plane vertex by its id twice), numbered where each first
/// occurs, with their lattice keys.
#[derive(Debug, Default)]
struct Part {
    index: FastMap<u64, u32>,
    keys: Vec<Key>,
    triangles: Vec<[u32; 3]>,
    sources: Vec<u32>,
}

impl Part {
    fn with_capacity(tets: usize) -> Self {
        // About one slice point and one triangle per few tets cut.
        let guess = tets / 8;
        let mut index = fast_map();
        index.reserve(guess);
        Self {
            index,
            keys: Vec::with_capacity(guess),
            triangles: Vec::with_capacity(guess),
            sources: Vec::new(),
        }
    }

    /// The part's number of the slice point `id` (lattice key `key`).
    #[inline]
    fn vertex(&mut self, id: u64, key: Key) -> u32 {
        let next = self.keys.len() as u32;
        *self.index.entry(id).or_insert_with(|| {
            self.keys.push(key);
            next
        })
    }
}

impl Slicer {
    /// A slicer for the hyperplane `x_axis = c` (axis 0..4 = x, y, z, t).
    ///
    /// # Panics
    /// If `axis > 3` or `c.den` is not in 1..=4096 (caller bugs, not input).
    pub fn new(axis: usize, c: PlaneValue) -> Self {
        assert!(axis < 4, "axis {axis} out of range");
        assert!(
            (1..=4096).contains(&c.den),
            "denominator {} out of range",
            c.den
        );
        Self {
            axis,
            c,
            on_plane_is_plus: true,
            index: fast_map(),
            mesh: TriMesh::default(),
            sources: None,
            tets_seen: 0,
        }
    }

    /// The same slicer with on-plane vertices counted as "−": use it (alongside the
    /// default) when the plane may only touch the body, see the module docs.
    pub fn on_plane_below(mut self) -> Self {
        self.on_plane_is_plus = false;
        self
    }

    /// The same slicer, also recording which tet each triangle comes from (see
    /// [`Slicer::finish_with_sources`]).
    pub fn with_sources(mut self) -> Self {
        self.sources = Some(Vec::new());
        self
    }

    /// Cuts every tet of `mesh`.
    pub fn add(&mut self, mesh: &TetMesh) {
        let first = self.tets_seen;
        self.tets_seen = first.wrapping_add(mesh.tets.len() as u32);
        let part = self.cut_part(mesh, &mesh.tets, |j| first.wrapping_add(j as u32));
        self.weld(part);
    }

    /// [`Slicer::add`] on rayon's pool: the tets are cut in chunks of [`SLICE_CHUNK_TETS`],
    /// each into its own part, and the parts welded in order, each slice point numbered
    /// where it first occurs. The result (vertices, their numbering, triangles, sources) is
    /// the one `add` gives, whatever the thread count.
    pub fn add_par(&mut self, mesh: &TetMesh) {
        let n = mesh.tets.len();
        if rayon::current_num_threads() < 2 || n < 2 * SLICE_CHUNK_TETS {
            self.add(mesh);
            return;
        }
        let base = self.tets_seen;
        let this = &*self;
        let parts: Vec<Part> = mesh
            .tets
            .par_chunks(SLICE_CHUNK_TETS)
            .enumerate()
            .map(|(k, tets)| {
                let first = base.wrapping_add((k * SLICE_CHUNK_TETS) as u32);
                this.cut_part(mesh, tets, |j| first.wrapping_add(j as u32))
            })
            .collect();
        self.tets_seen = base.wrapping_add(n as u32);
        for part in parts {
            self.weld(part);
        }
    }

    /// Cuts the tets `ids` of `mesh` (sources: the ids).
    pub fn add_some(&mut self, mesh: &TetMesh, ids: &[u32]) {
        let mut part = Part::with_capacity(ids.len());
        for &i in ids {
            self.cut(mesh, mesh.tets[i as usize], i, &mut part);
        }
        self.weld(part);
    }

    /// The tets `tets` of `mesh` cut into a part (the `j`-th tet's source `source(j)`).
    fn cut_part(&self, mesh: &TetMesh, tets: &[[u32; 4]], source: impl Fn(usize) -> u32) -> Part {
        let mut part = Part::with_capacity(tets.len());
        for (j, &t) in tets.iter().enumerate() {
            self.cut(mesh, t, source(j), &mut part);
        }
        part
    }

    /// Welds `part` into the slice: its points by lattice key, in the part's numbering
    /// (the order they first occur), its triangles renumbered.
    fn weld(&mut self, part: Part) {
        let Part {
            keys,
            triangles,
            sources,
            ..
        } = part;
        let remap: Vec<u32> = keys
            .into_iter()
            .map(|key| {
                let next = self.mesh.vertices.len() as u32;
                match self.index.entry(key) {
                    std::collections::hash_map::Entry::Occupied(e) => *e.get(),
                    std::collections::hash_map::Entry::Vacant(e) => {
                        e.insert(next);
                        let pos = position(key, self.axis, self.c);
                        self.mesh.vertices.push(pos);
                        next
                    }
                }
            })
            .collect();
        self.mesh
            .triangles
            .extend(triangles.iter().map(|t| t.map(|v| remap[v as usize])));
        if let Some(all) = &mut self.sources {
            all.extend(sources);
        }
    }

    fn cut(&self, mesh: &TetMesh, ids: [u32; 4], source: u32, part: &mut Part) {
        let p = ids.map(|v| mesh.vertices[v as usize]);
        // Where each vertex lies: below, on or above the plane.
        let rel = p.map(|q| (i64::from(q[self.axis]) * self.c.den).cmp(&self.c.num));
        let count = |o: std::cmp::Ordering| rel.iter().filter(|&&r| r == o).count();
        let (below, on, above) = (
            count(std::cmp::Ordering::Less),
            count(std::cmp::Ordering::Equal),
            count(std::cmp::Ordering::Greater),
        );
        // The polygon's corners lie on the edges from the "−" vertices to the "+" ones: one
        // key per vertex on the plane (all its edges meet there) and one per edge from below
        // to above, so at most `on + below·above` distinct keys. Fewer than three make no
        // triangle of any area: a tet touching the plane at a vertex or an edge, as most of
        // a slab's tets do at a frame plane, is passed over before its keys are made.
        if on + below * above < 3 {
            return;
        }
        let side = rel.map(|r| {
            if self.on_plane_is_plus {
                r.is_ge()
            } else {
                r.is_gt()
            }
        });
        let plus = side.iter().filter(|&&s| s).count();
        if plus == 0 || plus == 4 {
            return;
        }
        // Slice points in cyclic order around the polygon (no allocation: a triangle or a
        // quad, in fixed arrays).
        let mut pts = [(0usize, 0usize); 4];
        // The polygon's orientation, from the sides alone (see [`cut_orientation`]).
        let turn;
        let n = if plus == 1 || plus == 3 {
            let lone = (0..4).find(|&i| side[i] == (plus == 1)).unwrap_or(0);
            let mut n = 0;
            for i in (0..4).filter(|&i| i != lone) {
                pts[n] = (lone, i);
                n += 1;
            }
            turn = cut_orientation([lone, pts[0].1, pts[1].1, pts[2].1], plus == 3, self.axis);
            3
        } else {
            let (mut pos, mut neg) = ([0usize; 2], [0usize; 2]);
            let (mut np, mut nn) = (0, 0);
            for i in 0..4 {
                if side[i] {
                    pos[np] = i;
                    np += 1;
                } else {
                    neg[nn] = i;
                    nn += 1;
                }
            }
            // (n0,p0) (n0,p1) (n1,p1) (n1,p0) is a cycle of the quad.
            pts = [
                (neg[0], pos[0]),
                (neg[0], pos[1]),
                (neg[1], pos[1]),
                (neg[1], pos[0]),
            ];
            turn = cut_orientation([neg[0], pos[0], pos[1], neg[1]], true, self.axis);
            4
        };
        // A tet of no volume (its normal without the cut axis zero) has no orientation:
        // the exact test says zero, and its triangles are taken reversed, as before.
        let s = if has_normal3(&p, self.axis) { turn } else { 0 };
        // Two corners of the polygon share a key only where a vertex lies on the plane, or
        // two vertices coincide (a tet of no volume): a plane through no lattice point and
        // a tet of volume need not compare them.
        let distinct = s != 0 && self.c.num % self.c.den != 0;
        let mut keys = [(Key::Vertex([0; 4]), 0u64); 4];
        for m in 0..n {
            let (i, j) = pts[m];
            keys[m] = self.key(&p, &ids, i, j);
        }
        let tris: &[[usize; 3]] = if n == 3 {
            &[[0, 1, 2]]
        } else {
            &[[0, 1, 2], [0, 2, 3]]
        };
        for tri in tris {
            let [a, b, c] = *tri;
            if !distinct
                && (keys[a].0 == keys[b].0 || keys[b].0 == keys[c].0 || keys[a].0 == keys[c].0)
            {
                continue;
            }
            let ordered = if s > 0 { [a, b, c] } else { [a, c, b] };
            let ids = ordered.map(|i| part.vertex(keys[i].1, keys[i].0));
            part.triangles.push(ids);
            if self.sources.is_some() {
                part.sources.push(source);
            }
        }
    }

    /// The lattice key of the slice point on edge (i, j) of tet `p` (vertex ids `ids`), and
    /// its key by vertex ids (the same point of the same mesh has the same one).
    #[inline]
    fn key(&self, p: &[LatticePoint; 4], ids: &[u32; 4], i: usize, j: usize) -> (Key, u64) {
        // The ends lie on opposite sides, so at most one of them is on the plane: then the
        // slice point is that vertex itself.
        for (q, id) in [(p[i], ids[i]), (p[j], ids[j])] {
            if i64::from(q[self.axis]) * self.c.den == self.c.num {
                return (Key::Vertex(q), u64::from(id) << 32 | u64::from(id));
            }
        }
        let (a, b) = (p[i].min(p[j]), p[i].max(p[j]));
        let (lo, hi) = (ids[i].min(ids[j]), ids[i].max(ids[j]));
        (Key::Edge(a, b), u64::from(lo) << 32 | u64::from(hi))
    }

    /// The slice. Triangles that occur once in each orientation (a plane containing
    /// lateral triangles of the mesh cuts a zero-volume sheet there) cancel. A plane
    /// through no lattice point (its coordinate not a whole number of lattice steps) holds
    /// no vertex: each triangle of its slice is cut from one tet, on edges that together
    /// meet all four of the tet's vertices, so two triangles alike would come from two tets
    /// on the same four vertices, which the mesher never makes (such a slice is a closed
    /// 2-manifold: tests/it/mesh_closed.rs checks it on random meshes). Nothing cancels
    /// there, and its triangles are kept as they were cut, in tet order, without the sort
    /// that finds the ones that would.
    pub fn finish(self) -> TriMesh {
        self.finish_with_sources().0
    }

    /// [`Slicer::finish`], with the source tet of each triangle (empty unless made
    /// [`Slicer::with_sources`]).
    pub fn finish_with_sources(mut self) -> (TriMesh, Vec<u32>) {
        let src = self.sources.take();
        if self.c.num % self.c.den != 0 {
            return (self.mesh, src.unwrap_or_default());
        }
        let tris = std::mem::take(&mut self.mesh.triangles);
        let mut keyed: Vec<([u32; 3], i8, [u32; 3], u32)> = tris
            .into_iter()
            .enumerate()
            .map(|(i, t)| {
                let (k, s) = crate::validate::canonical_triangle(t);
                (k, s, t, src.as_ref().map_or(0, |v| v[i]))
            })
            .collect();
        // By (canonical triangle, sign, source), compared as two words.
        keyed.sort_unstable_by_key(|x| {
            let (k, s, _, src) = *x;
            (
                u64::from(k[0]) << 32 | u64::from(k[1]),
                u64::from(k[2]) << 33 | u64::from(s > 0) << 32 | u64::from(src),
            )
        });
        let mut out = Vec::with_capacity(keyed.len());
        let mut out_src = Vec::with_capacity(if src.is_some() { keyed.len() } else { 0 });
        for group in keyed.chunk_by(|a, b| a.0 == b.0) {
            // Sorted by sign: the "−" ones first, then the "+" ones; as many of each cancel.
            let m = group.partition_point(|x| x.1 < 0);
            let (minus, plus) = group.split_at(m);
            let n = plus.len().min(minus.len());
            for x in plus[n..].iter().chain(minus[n..].iter()) {
                out.push(x.2);
                if src.is_some() {
                    out_src.push(x.3);
                }
            }
        }
        self.mesh.triangles = out;
        (self.mesh, out_src)
    }
}

/// The exact position of the slice point `key` on the plane `x_axis = c` (independent of
/// which tet produced it).
fn position(key: Key, axis: usize, c: PlaneValue) -> [f64; 3] {
    match key {
        Key::Vertex(q) => drop_axis(&q, axis).map(f64::from),
        Key::Edge(a, b) => {
            let k = axis;
            let t = (c.num as f64 / c.den as f64 - f64::from(a[k])) / f64::from(b[k] - a[k]);
            let (a3, b3) = (drop_axis(&a, k), drop_axis(&b, k));
            [0, 1, 2].map(|m| f64::from(a3[m]) + t * f64::from(b3[m] - a3[m]))
        }
    }
}

/// The three coordinates other than `k`, in order.
fn drop_axis<T: Copy>(p: &[T; 4], k: usize) -> [T; 3] {
    let keep = |m: usize| if m < k { m } else { m + 1 };
    [p[keep(0)], p[keep(1)], p[keep(2)]]
}

/// N with N·x = det[b−a, c−a, d−a, x]: outward for our orientation convention, since
/// orient4(a, b, c, d, inside) < 0; its three components other than `axis`, in order, each
/// computed when asked (so [`has_normal3`] can stop at the first not zero).
fn normal3_components(p: &[LatticePoint; 4], axis: usize) -> impl Iterator<Item = i128> {
    // N_j = det[u; v; w; e_j] = (-1)^(3+j) times the minor of u, v, w without column j.
    let d = |q: &LatticePoint| [0, 1, 2, 3].map(|k| i64::from(q[k]) - i64::from(p[0][k]));
    let (u, v, w) = (d(&p[1]), d(&p[2]), d(&p[3]));
    // Below 2^20 every product of three is below 2^60 and the minor within i64.
    let small = [u, v, w]
        .iter()
        .flatten()
        .all(|x| x.unsigned_abs() < 1 << 20);
    (0..4).filter(move |&j| j != axis).map(move |j| {
        let (a, b, c) = match j {
            0 => (1, 2, 3),
            1 => (0, 2, 3),
            2 => (0, 1, 3),
            _ => (0, 1, 2),
        };
        let minor = if small {
            i128::from(
                u[a] * (v[b] * w[c] - v[c] * w[b]) - u[b] * (v[a] * w[c] - v[c] * w[a])
                    + u[c] * (v[a] * w[b] - v[b] * w[a]),
            )
        } else {
            let (u, v, w) = (u.map(i128::from), v.map(i128::from), w.map(i128::from));
            u[a] * (v[b] * w[c] - v[c] * w[b]) - u[b] * (v[a] * w[c] - v[c] * w[a])
                + u[c] * (v[a] * w[b] - v[b] * w[a])
        };
        if (3 + j) % 2 == 1 {
            -minor
        } else {
            minor
        }
    })
}

/// The three components of N other than `axis` ([`normal3_components`]) at once.
#[cfg(test)]
fn outward_normal3(p: &[LatticePoint; 4], axis: usize) -> [i128; 3] {
    let mut n = normal3_components(p, axis);
    [0; 3].map(|_| n.next().unwrap_or(0))
}

/// Whether N has a component other than `axis` that is not zero: found one at a time, up
/// to the first that is not (most tets stop at the first).
fn has_normal3(p: &[LatticePoint; 4], axis: usize) -> bool {
    normal3_components(p, axis).any(|c| c != 0)
}

/// [`outward_normal3`] from the full 4D determinant (the reference it is tested against).
#[cfg(test)]
fn outward_normal3_by_det4(p: &[LatticePoint; 4], axis: usize) -> [i128; 3] {
    let d = |q: &LatticePoint| [0, 1, 2, 3].map(|k| i128::from(q[k]) - i128::from(p[0][k]));
    let (u, v, w) = (d(&p[1]), d(&p[2]), d(&p[3]));
    let keep = |m: usize| if m < axis { m } else { m + 1 };
    [0, 1, 2].map(|m| {
        let mut e = [0i128; 4];
        e[keep(m)] = 1;
        det4(&u, &v, &w, &e)
    })
}

#[cfg(test)]
fn det4(a: &[i128; 4], b: &[i128; 4], c: &[i128; 4], d: &[i128; 4]) -> i128 {
    let s = |i: usize, j: usize| c[i] * d[j] - c[j] * d[i];
    let t = |i: usize, j: usize| a[i] * b[j] - a[j] * b[i];
    t(0, 1) * s(2, 3) - t(0, 2) * s(1, 3) + t(0, 3) * s(1, 2) + t(1, 2) * s(0, 3)
        - t(1, 3) * s(0, 2)
        + t(2, 3) * s(0, 1)
}

/// The sign of det3[Q−P, R−P, n3] ([`orientation`]) for the cut polygon of a tet of
/// volume, in the polygon's cycle order, from which vertices lie on which side alone.
///
/// `order` lists the tet's four vertex positions (0..4) so that the polygon is cut from
/// the first vertex towards the others in order (a triangle: the lone vertex, then the other
/// three ascending; a quad: the first "−" vertex, the two "+" ones ascending, the second "−"
/// one), and `first_below` says whether that first vertex lies on the "−" side. The sign is
/// `sgn(order) · (−1)^axis`, negated when the first vertex lies on the "+" side.
///
/// Why: let N be the tet's outward normal for the vertex order `order` (N·x = det[v1, v2,
/// v3, x] for its edge vectors v_j from the first vertex; another order multiplies N by that
/// order's sign). det3[Q−P, R−P, n3] is (−1)^(axis+1) det4[Q−P, R−P, N, e_axis]. For a lone
/// first vertex at height h below the plane, the cut points are p0 + λ_j v_j with λ_j > 0,
/// and writing e_axis = Σ α_j v_j + βN gives det4[Q−P, R−P, N, e_axis] = −|N|² λ1λ2λ3
/// (Σ_j α_j (v_j)_axis) / h = −|N|² λ1λ2λ3 (1 − N_axis²/|N|²) / h, negative (N is not
/// along the axis for a tet the plane cuts); above the plane h changes sign. The quad is a
/// convex cycle, so its two triangles turn alike, and the determinant vanishes for no tet of
/// volume cut that way: one configuration fixes its sign. The unit tests compare this with
/// [`orientation`] on random tets.
fn cut_orientation(order: [usize; 4], first_below: bool, axis: usize) -> i128 {
    let inversions = (0..4)
        .flat_map(|i| (i + 1..4).map(move |j| (i, j)))
        .filter(|&(i, j)| order[i] > order[j])
        .count();
    let sign = if (inversions + axis) % 2 == 0 { 1 } else { -1 };
    if first_below {
        sign
    } else {
        -sign
    }
}

/// Sign of det3[Q−P, R−P, n3] for homogeneous P, Q, R (positive weights), `n3` the outward
/// normal without the cut axis (the exact test [`cut_orientation`] is checked against).
#[cfg(test)]
fn orientation(
    p: &([i128; 3], i128),
    q: &([i128; 3], i128),
    r: &([i128; 3], i128),
    n3: &[i128; 3],
) -> i128 {
    let u = [0, 1, 2].map(|i| p.1 * q.0[i] - q.1 * p.0[i]);
    let v = [0, 1, 2].map(|i| p.1 * r.0[i] - r.1 * p.0[i]);
    let c = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    (c[0] * n3[0] + c[1] * n3[1] + c[2] * n3[2]).signum()
}

/// Slices a whole mesh; if the plane only touches it, slices again with on-plane vertices
/// on the "−" side (see the module docs).
pub fn slice_mesh(parts: &[&TetMesh], axis: usize, c: PlaneValue) -> TriMesh {
    let mut s = Slicer::new(axis, c);
    for m in parts {
        s.add(m);
    }
    let out = s.finish();
    if !out.triangles.is_empty() {
        return out;
    }
    let mut s = Slicer::new(axis, c).on_plane_below();
    for m in parts {
        s.add(m);
    }
    s.finish()
}

/// Writes a binary little-endian PLY file of the mesh, with positions mapped by `to_world`.
///
/// # Errors
/// Any I/O error of the writer.
pub fn write_ply<W: Write>(
    mesh: &TriMesh,
    mut w: W,
    to_world: impl Fn(&[f64; 3]) -> [f64; 3],
) -> io::Result<()> {
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment chronotope 4D slice\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        mesh.vertices.len(),
        mesh.triangles.len()
    )?;
    for v in &mesh.vertices {
        for c in to_world(v) {
            w.write_all(&c.to_le_bytes())?;
        }
    }
    for t in &mesh.triangles {
        w.write_all(&[3u8])?;
        for i in t {
            w.write_all(&i.to_le_bytes())?;
        }
    }
    w.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slice point `key` on the plane `x_axis = c`, homogeneous ((coordinates·w, w),
    /// w > 0) relative to `origin`, computed exactly.
    fn exact_point(
        key: Key,
        origin: &LatticePoint,
        axis: usize,
        c: PlaneValue,
    ) -> ([i128; 3], i128) {
        let rel = |q: &LatticePoint| {
            drop_axis(
                &[0, 1, 2, 3].map(|m| i128::from(q[m]) - i128::from(origin[m])),
                axis,
            )
        };
        match key {
            Key::Vertex(q) => (rel(&q), 1),
            Key::Edge(u, v) => {
                let (den, num) = (i128::from(c.den), i128::from(c.num));
                let (mut alpha, mut beta) = (
                    i128::from(v[axis]) * den - num,
                    num - i128::from(u[axis]) * den,
                );
                if alpha + beta < 0 {
                    alpha = -alpha;
                    beta = -beta;
                }
                let (ru, rv) = (rel(&u), rel(&v));
                (
                    [0, 1, 2].map(|m| ru[m] * alpha + rv[m] * beta),
                    alpha + beta,
                )
            }
        }
    }

    /// Every triangle the cut makes of a tet of volume turns as the exact test says
    /// (det3[Q−P, R−P, n3] > 0, the points computed exactly), for random tets small and
    /// large, every axis, planes through lattice points and between them, and on-plane
    /// vertices counted on either side.
    #[test]
    fn the_cut_turns_as_the_exact_test_says() {
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        let (mut checked, mut flat) = (0, 0);
        for round in 0..40_000 {
            let r = if round % 7 == 0 { 256 } else { 4 };
            let p: [LatticePoint; 4] = rng.tet(-r, r);
            let axis = round % 4;
            let scale = i64::from(r.min(8));
            let c = if round % 3 == 0 {
                PlaneValue::lattice(rng.range(-scale, scale))
            } else {
                PlaneValue {
                    num: rng.range(-scale * 1024, scale * 1024),
                    den: 1024,
                }
            };
            let mesh = TetMesh {
                vertices: p.to_vec(),
                tets: vec![[0, 1, 2, 3]],
            };
            let n3 = outward_normal3(&p, axis);
            for below in [false, true] {
                let mut slicer = Slicer::new(axis, c);
                if below {
                    slicer = slicer.on_plane_below();
                }
                let mut part = Part::with_capacity(1);
                slicer.cut(&mesh, [0, 1, 2, 3], 0, &mut part);
                for t in &part.triangles {
                    if n3 == [0; 3] {
                        flat += 1;
                        continue;
                    }
                    let g = t.map(|v| exact_point(part.keys[v as usize], &p[0], axis, c));
                    assert!(
                        orientation(&g[0], &g[1], &g[2], &n3) > 0,
                        "tet {p:?} axis {axis} plane {c:?} below {below}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(
            checked > 10_000,
            "only {checked} triangles checked ({flat} flat)"
        );
    }

    /// The normal from 3x3 minors (in i64 when small) is the 4D determinant's.
    #[test]
    fn normal_by_minors_is_the_determinants() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut next = |r: i64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            ((x % (2 * r as u64 + 1)) as i64 - r) as i32
        };
        for round in 0..4000 {
            // Small coordinates, and now and then large ones (the i128 path).
            let r = if round % 5 == 0 { 1 << 30 } else { 300 };
            let p: [LatticePoint; 4] = std::array::from_fn(|_| std::array::from_fn(|_| next(r)));
            for axis in 0..4 {
                assert_eq!(
                    outward_normal3(&p, axis),
                    outward_normal3_by_det4(&p, axis),
                    "{p:?} axis {axis}"
                );
            }
        }
    }

    #[test]
    fn a_normal_is_found_where_the_minors_give_one() {
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let (mut flat, mut solid) = (0, 0);
        for round in 0..20_000 {
            // Coordinates in -1..=1 often give tets of no volume (coincident, collinear or
            // coplanar vertices); now and then large ones (the i128 path).
            let r = match round % 7 {
                0 => 1 << 29,
                1..=3 => 1,
                _ => 3,
            };
            let mut p: [LatticePoint; 4] =
                std::array::from_fn(|_| std::array::from_fn(|_| rng.range(-r, r) as i32));
            if round % 11 == 0 {
                // The fourth vertex in the plane of the other three.
                p[3] = std::array::from_fn(|k| p[1][k] + p[2][k] - p[0][k]);
            }
            for axis in 0..4 {
                let expected = outward_normal3_by_det4(&p, axis) != [0; 3];
                assert_eq!(has_normal3(&p, axis), expected, "{p:?} axis {axis}");
                if expected {
                    solid += 1;
                } else {
                    flat += 1;
                }
            }
        }
        assert!(flat > 1000 && solid > 1000, "{flat} {solid}");
    }
}
