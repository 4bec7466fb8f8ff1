//! Generation of the marching-hypercubes table (Bhaniramka, Wenger & Crawfis 2000).
//!
//! This file is compiled twice: by `build.rs` (which writes the binary table into `OUT_DIR`)
//! and by the library (so that tests can regenerate and inspect it). It therefore depends on
//! nothing but `std`.
//!
//! For each of the 2^16 sign patterns of a hypercube's corners, let P be the positive corners
//! plus the midpoints of the edges whose ends differ (doubled lattice: every coordinate is
//! 0, 1 or 2). The isosurface inside the hypercube is made of the facets of conv(P) that do
//! not lie in a facet of the hypercube ("lateral" facets). Because conv(P) ∩ F = conv(P ∩ F)
//! for every face F of the hypercube, neighbouring hypercubes agree on the surface.
//!
//! The facets are mostly not simplices. They are split by a *pulling triangulation in a fixed
//! global order*: v = the lexicographically smallest vertex of the facet (by lattice
//! coordinates (x, y, z, t)); every 2-face not containing v is fanned from its own smallest
//! vertex; those triangles are coned to v. The restriction of this triangulation to any
//! 2-face is that face's own fan from its smallest vertex, so the two hypercubes (or the two
//! facets) sharing a 2-face always split it the same way: the mesh is closed.
//!
//! The hull is computed exactly (integer predicates) by gift wrapping: facets are found by
//! pivoting around ridges (2-faces), ridges by a 3D gift wrap inside each facet, and polygon
//! vertex order by an exact angular sort. Every point of P is a vertex of conv(P) (a corner is
//! a vertex of the cube; an edge point has its three other coordinates at the cube's bounds),
//! which keeps the face lattice free of points lying inside edges.
//!
//! Caps: the 3D solid of one frame inside one cube, conv(P ∩ {t = const}), triangulated by the
//! same pulling rule, closes each slab at its two time ends.

/// A point of the doubled lattice in R^4 (x, y, z, t).
pub type P4 = [i64; 4];
/// A point of the doubled lattice in R^3.
pub type P3 = [i64; 3];

/// Number of hypercube corners.
pub const CORNERS4: usize = 16;
/// Number of hypercube edges.
pub const EDGES4: usize = 32;
/// Number of cube corners.
pub const CORNERS3: usize = 8;
/// Number of cube edges.
pub const EDGES3: usize = 12;

/// Doubled-lattice position of hypercube corner `c` (bit 0 = x, 1 = y, 2 = z, 3 = t).
pub fn corner4(c: usize) -> P4 {
    [
        2 * (c & 1) as i64,
        2 * ((c >> 1) & 1) as i64,
        2 * ((c >> 2) & 1) as i64,
        2 * ((c >> 3) & 1) as i64,
    ]
}

/// The two corners (low, high) of edge `e`, and its direction. Edge `e` runs along axis
/// `e / 8`; the remaining three corner bits are `e % 8` in increasing axis order.
pub fn edge4(e: usize) -> (usize, usize, usize) {
    edge_of(e, 8)
}

/// Index of the edge from corner `c` (with bit `d` clear) along axis `d`.
pub fn edge4_index(c: usize, d: usize) -> usize {
    edge_index_of(c, d, 8)
}

/// Cube (3D) corner position on the doubled lattice.
pub fn corner3(c: usize) -> P3 {
    [
        2 * (c & 1) as i64,
        2 * ((c >> 1) & 1) as i64,
        2 * ((c >> 2) & 1) as i64,
    ]
}

/// The two corners and direction of cube edge `e` (axis `e / 4`).
pub fn edge3(e: usize) -> (usize, usize, usize) {
    edge_of(e, 4)
}

/// Index of the cube edge from corner `c` along axis `d`.
pub fn edge3_index(c: usize, d: usize) -> usize {
    edge_index_of(c, d, 4)
}

fn edge_of(e: usize, per_dir: usize) -> (usize, usize, usize) {
    let d = e / per_dir;
    let r = e % per_dir;
    let low = r & ((1 << d) - 1);
    let high = (r >> d) << (d + 1);
    let c0 = low | high;
    (c0, c0 | (1 << d), d)
}

fn edge_index_of(c: usize, d: usize, per_dir: usize) -> usize {
    let low = c & ((1 << d) - 1);
    let high = (c >> (d + 1)) << d;
    d * per_dir + (low | high)
}

// ---------------------------------------------------------------------------------------
// Exact predicates on small integers.

fn sub4(a: &P4, b: &P4) -> P4 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]]
}

fn sub3(a: &P3, b: &P3) -> P3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn det3(a: &P3, b: &P3, c: &P3) -> i64 {
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

fn det4(r: [P4; 4]) -> i64 {
    // Laplace expansion along the first row with 3x3 minors.
    let mut acc = 0;
    for col in 0..4 {
        let mut m = [[0i64; 3]; 3];
        for row in 1..4 {
            let mut k = 0;
            for (c, v) in r[row].iter().enumerate() {
                if c != col {
                    m[row - 1][k] = *v;
                    k += 1;
                }
            }
        }
        let minor = det3(&m[0], &m[1], &m[2]);
        let term = r[0][col] * minor;
        if col % 2 == 0 {
            acc += term;
        } else {
            acc -= term;
        }
    }
    acc
}

/// det[p1-p0, p2-p0, p3-p0, p4-p0].
pub fn orient4(p: [&P4; 5]) -> i64 {
    det4([
        sub4(p[1], p[0]),
        sub4(p[2], p[0]),
        sub4(p[3], p[0]),
        sub4(p[4], p[0]),
    ])
}

/// det[p1-p0, p2-p0, p3-p0].
pub fn orient3(p0: &P3, p1: &P3, p2: &P3, p3: &P3) -> i64 {
    det3(&sub3(p1, p0), &sub3(p2, p0), &sub3(p3, p0))
}

fn cross3(u: &P3, v: &P3) -> P3 {
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

/// Normal N of the hyperplane spanned by u, v, w (N·x = det[u, v, w, x]).
fn normal4(u: &P4, v: &P4, w: &P4) -> P4 {
    let mut n = [0i64; 4];
    for (k, nk) in n.iter_mut().enumerate() {
        let mut e = [0i64; 4];
        e[k] = 1;
        *nk = det4([*u, *v, *w, e]);
    }
    n
}

fn dot4(a: &P4, b: &P4) -> i64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

// ---------------------------------------------------------------------------------------
// Hulls.

/// A polygon (2-face) as point indices in cyclic order.
type Polygon = Vec<usize>;

/// Orders coplanar points (3D) cyclically around the polygon they span. Exact: sorts by the
/// sign of cross products around the lexicographically smallest point, which is a vertex, so
/// all others lie within an angle below 180 degrees.
fn cyclic_order(pts: &[P3], ids: &mut [usize]) {
    if ids.len() < 3 {
        return;
    }
    let (first, _) = ids
        .iter()
        .enumerate()
        .min_by_key(|(_, &i)| pts[i])
        .expect("non-empty");
    ids.swap(0, first);
    let o = pts[ids[0]];
    // The plane normal tells which way is counter-clockwise.
    let a = sub3(&pts[ids[1]], &o);
    let mut normal = [0i64; 3];
    for &i in &ids[2..] {
        normal = cross3(&a, &sub3(&pts[i], &o));
        if normal != [0, 0, 0] {
            break;
        }
    }
    ids[1..].sort_by(|&p, &q| {
        let c = cross3(&sub3(&pts[p], &o), &sub3(&pts[q], &o));
        let s = c[0] * normal[0] + c[1] * normal[1] + c[2] * normal[2];
        0.cmp(&s)
    });
}

fn mask_of(ids: &[usize]) -> u64 {
    ids.iter().fold(0u64, |m, &i| m | (1u64 << i))
}

/// All 2-faces of a 3-polytope given by its vertices (all points are vertices), starting
/// from a known 2-face. Gift wrapping around edges.
fn hull3_faces(pts: &[P3], start: Polygon) -> Vec<Polygon> {
    let mut faces: Vec<Polygon> = Vec::new();
    let mut seen: Vec<u64> = Vec::new();
    let mut queue = vec![start];
    while let Some(face) = queue.pop() {
        let m = mask_of(&face);
        if seen.contains(&m) {
            continue;
        }
        seen.push(m);
        let n = face.len();
        for k in 0..n {
            let a = face[k];
            let b = face[(k + 1) % n];
            let c = face[(k + 2) % n];
            // Candidates: points off this face's plane.
            let off: Vec<usize> = (0..pts.len())
                .filter(|&q| orient3(&pts[a], &pts[b], &pts[c], &pts[q]) != 0)
                .collect();
            let Some(&first) = off.first() else { continue };
            let mut p = first;
            let sigma = orient3(&pts[a], &pts[b], &pts[c], &pts[p]).signum();
            for &q in &off {
                if orient3(&pts[a], &pts[b], &pts[p], &pts[q]).signum() == sigma {
                    p = q;
                }
            }
            let mut next: Vec<usize> = (0..pts.len())
                .filter(|&q| orient3(&pts[a], &pts[b], &pts[p], &pts[q]) == 0)
                .collect();
            if !seen.contains(&mask_of(&next)) {
                cyclic_order(pts, &mut next);
                queue.push(next);
            }
        }
        faces.push(face);
    }
    faces
}

/// One facet of a 4D hull: its points (indices), its 2-faces (cyclic point lists) and its
/// outward normal with offset (all points satisfy normal·x <= offset).
#[derive(Debug, Clone)]
pub struct Facet4 {
    /// Point indices on the facet.
    pub points: Vec<usize>,
    /// 2-faces as cyclic index lists.
    pub faces: Vec<Vec<usize>>,
    /// Outward normal.
    pub normal: P4,
    /// normal·x on the facet.
    pub offset: i64,
}

/// Projects the points of a facet (normal `n`) to 3D by dropping a coordinate the normal
/// does not vanish in: an affine bijection of the facet's hyperplane, so faces are kept.
fn project(pts: &[P4], ids: &[usize], n: &P4) -> Vec<P3> {
    let k = (0..4).max_by_key(|&k| n[k].abs()).expect("4 coordinates");
    ids.iter()
        .map(|&i| {
            let p = pts[i];
            let mut q = [0i64; 3];
            let mut j = 0;
            for (c, v) in p.iter().enumerate() {
                if c != k {
                    q[j] = *v;
                    j += 1;
                }
            }
            q
        })
        .collect()
}

/// The facets of conv(pts) (all points are vertices, the hull is 4-dimensional), starting
/// from a known facet with a known 2-face of it. Gift wrapping around 2-faces.
fn hull4_facets(pts: &[P4], start_normal: P4, start_face: Vec<usize>) -> Vec<Facet4> {
    let on_plane = |n: &P4, off: i64| -> Vec<usize> {
        (0..pts.len())
            .filter(|&i| dot4(n, &pts[i]) == off)
            .collect()
    };
    let start_offset = pts
        .iter()
        .map(|p| dot4(&start_normal, p))
        .max()
        .expect("points");
    let mut facets: Vec<Facet4> = Vec::new();
    let mut seen: Vec<u64> = Vec::new();
    let mut queue: Vec<(P4, i64, Vec<usize>)> = vec![(start_normal, start_offset, start_face)];
    while let Some((normal, offset, ridge)) = queue.pop() {
        let points = on_plane(&normal, offset);
        let m = mask_of(&points);
        if seen.contains(&m) {
            continue;
        }
        seen.push(m);
        // 2-faces of this facet by a 3D gift wrap in the projected hyperplane. The known
        // ridge is given as global indices; map to facet-local ones.
        let local_pts = project(pts, &points, &normal);
        let mut start: Vec<usize> = ridge
            .iter()
            .map(|g| points.iter().position(|p| p == g).expect("ridge on facet"))
            .collect();
        cyclic_order(&local_pts, &mut start);
        let faces: Vec<Vec<usize>> = hull3_faces(&local_pts, start)
            .into_iter()
            .map(|f| f.into_iter().map(|l| points[l]).collect())
            .collect();
        for face in &faces {
            let (r0, r1) = (face[0], face[1]);
            let r2 = face[2];
            let a = *points
                .iter()
                .find(|&&q| !face.contains(&q))
                .expect("facet spans 3D");
            let off: Vec<usize> = (0..pts.len())
                .filter(|&q| dot4(&normal, &pts[q]) != offset)
                .collect();
            let Some(&first) = off.first() else { continue };
            let mut p = first;
            let o = |x: usize, y: usize| {
                orient4([&pts[r0], &pts[r1], &pts[r2], &pts[x], &pts[y]]).signum()
            };
            let sigma = o(a, p);
            for &q in &off {
                if o(p, q) == sigma {
                    p = q;
                }
            }
            let mut n = normal4(
                &sub4(&pts[r1], &pts[r0]),
                &sub4(&pts[r2], &pts[r0]),
                &sub4(&pts[p], &pts[r0]),
            );
            let g = n.iter().fold(0i64, |g, &v| gcd(g, v.abs()));
            for v in n.iter_mut() {
                *v /= g;
            }
            let mut off_n = dot4(&n, &pts[r0]);
            if dot4(&n, &pts[a]) > off_n {
                n = n.map(|v| -v);
                off_n = -off_n;
            }
            let next_pts = on_plane(&n, off_n);
            if !seen.contains(&mask_of(&next_pts)) {
                queue.push((n, off_n, face.clone()));
            }
        }
        facets.push(Facet4 {
            points,
            faces,
            normal,
            offset,
        });
    }
    facets
}

fn gcd(a: i64, b: i64) -> i64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

// ---------------------------------------------------------------------------------------
// Cases.

/// The point set of a 4D case: point ids 0..16 are corners, 16..48 edge midpoints.
pub fn case_points4(case: u16) -> Vec<(usize, P4)> {
    let pos = |c: usize| (case >> c) & 1 == 1;
    let mut v = Vec::new();
    for c in 0..CORNERS4 {
        if pos(c) {
            v.push((c, corner4(c)));
        }
    }
    for e in 0..EDGES4 {
        let (a, b, _) = edge4(e);
        if pos(a) != pos(b) {
            let (pa, pb) = (corner4(a), corner4(b));
            v.push((CORNERS4 + e, [0, 1, 2, 3].map(|k| (pa[k] + pb[k]) / 2)));
        }
    }
    v
}

/// The full hull of a 4D case (empty for case 0).
pub fn case_hull4(case: u16) -> (Vec<(usize, P4)>, Vec<Facet4>) {
    let pts = case_points4(case);
    if pts.is_empty() {
        return (pts, Vec::new());
    }
    let coords: Vec<P4> = pts.iter().map(|p| p.1).collect();
    // A positive corner u lies on the cube facet x = u.x, which meets P in a 3D set (u plus
    // a point along each of the other axes): a facet. Its face y = u.y is a 2-face.
    let u = coords[0];
    let sx = if u[0] == 0 { -1 } else { 1 };
    let normal = [sx, 0, 0, 0];
    let ridge: Vec<usize> = (0..coords.len())
        .filter(|&i| coords[i][0] == u[0] && coords[i][1] == u[1])
        .collect();
    let facets = hull4_facets(&coords, normal, ridge);
    (pts, facets)
}

/// True if the facet lies in a facet of the hypercube (all points share a bound coordinate).
fn on_cube_boundary(coords: &[P4], ids: &[usize]) -> Option<(usize, i64)> {
    (0..4).find_map(|k| {
        let v = coords[ids[0]][k];
        ((v == 0 || v == 2) && ids.iter().all(|&i| coords[i][k] == v)).then_some((k, v))
    })
}

/// Pulling triangulation of a 3-polytope given by its 2-faces: cone from the smallest
/// vertex `v` over the fans of the 2-faces not containing `v`. Returns unoriented tets as
/// point indices (v first).
fn pull<P: Ord + Copy>(coords: &[P], faces: &[Vec<usize>], all: &[usize]) -> Vec<[usize; 4]> {
    let v = *all
        .iter()
        .min_by_key(|&&i| coords[i])
        .expect("non-empty facet");
    let mut tets = Vec::new();
    for f in faces {
        if f.contains(&v) {
            continue;
        }
        let k = (0..f.len())
            .min_by_key(|&k| coords[f[k]])
            .expect("non-empty face");
        let n = f.len();
        let w0 = f[k];
        for i in 1..n - 1 {
            tets.push([v, w0, f[(k + i) % n], f[(k + i + 1) % n]]);
        }
    }
    tets
}

/// The lateral tets of a 4D case, as point ids (16 + edge index), each oriented outward:
/// orient4(a, b, c, d, interior) < 0. Also returns the cap-facet tets per time side for
/// cross-checks (point ids, unoriented).
pub fn case_tets4(case: u16) -> (Vec<[u8; 4]>, [Vec<[usize; 4]>; 2]) {
    let (pts, facets) = case_hull4(case);
    let coords: Vec<P4> = pts.iter().map(|p| p.1).collect();
    let n = coords.len() as i64;
    let centroid: P4 = [0, 1, 2, 3].map(|k| coords.iter().map(|p| p[k]).sum::<i64>());
    let scaled = |p: &P4| p.map(|v| v * n);
    let mut lateral = Vec::new();
    let mut caps: [Vec<[usize; 4]>; 2] = [Vec::new(), Vec::new()];
    for f in &facets {
        let tets = pull(&coords, &f.faces, &f.points);
        match on_cube_boundary(&coords, &f.points) {
            Some((3, t)) => {
                let side = usize::from(t == 2);
                caps[side].extend(tets.iter().map(|t| t.map(|i| pts[i].0)));
            }
            Some(_) => {}
            None => {
                for t in tets {
                    let [a, b, c, d] = t.map(|i| scaled(&coords[i]));
                    let s = orient4([&a, &b, &c, &d, &centroid]);
                    assert!(s != 0, "degenerate lateral tet in case {case:#06x}");
                    let t = if s < 0 { t } else { [t[0], t[1], t[3], t[2]] };
                    lateral.push(t.map(|i| (pts[i].0 - CORNERS4) as u8));
                }
            }
        }
    }
    (lateral, caps)
}

/// The point set of a 3D (cap) case: ids 0..8 corners, 8..20 edge midpoints.
pub fn case_points3(case: u8) -> Vec<(usize, P3)> {
    let pos = |c: usize| (case >> c) & 1 == 1;
    let mut v = Vec::new();
    for c in 0..CORNERS3 {
        if pos(c) {
            v.push((c, corner3(c)));
        }
    }
    for e in 0..EDGES3 {
        let (a, b, _) = edge3(e);
        if pos(a) != pos(b) {
            let (pa, pb) = (corner3(a), corner3(b));
            v.push((CORNERS3 + e, [0, 1, 2].map(|k| (pa[k] + pb[k]) / 2)));
        }
    }
    v
}

/// The cap tets of a 3D case (point ids: corners 0..8, 8 + edge), oriented with positive
/// 3D volume: orient3(a, b, c, d) > 0.
pub fn case_tets3(case: u8) -> Vec<[u8; 4]> {
    let pts = case_points3(case);
    if pts.is_empty() {
        return Vec::new();
    }
    let coords: Vec<P3> = pts.iter().map(|p| p.1).collect();
    // Start from the face of the cube through a positive corner (2-dimensional: the corner
    // plus a point along each of the two other axes).
    let u = coords[0];
    let mut start: Vec<usize> = (0..coords.len())
        .filter(|&i| coords[i][0] == u[0])
        .collect();
    cyclic_order(&coords, &mut start);
    let faces = hull3_faces(&coords, start);
    let all: Vec<usize> = (0..coords.len()).collect();
    pull(&coords, &faces, &all)
        .into_iter()
        .map(|t| {
            let s = orient3(&coords[t[0]], &coords[t[1]], &coords[t[2]], &coords[t[3]]);
            assert!(s != 0, "degenerate cap tet in case {case:#04x}");
            let t = if s > 0 { t } else { [t[0], t[1], t[3], t[2]] };
            t.map(|i| pts[i].0 as u8)
        })
        .collect()
}

/// Magic bytes of the binary table.
pub const TABLE_MAGIC: &[u8; 8] = b"CHRMC4T1";

/// Builds the binary table: magic, 65537 u32 lateral offsets, lateral tets (4 bytes: edge
/// ids), 257 u32 cap offsets, cap tets (4 bytes: 3D point ids). Little endian.
/// `threads` splits the 2^16 cases.
pub fn build_table(threads: usize) -> Vec<u8> {
    let threads = threads.max(1);
    let chunk = 65536usize.div_ceil(threads);
    let parts: Vec<Vec<Vec<[u8; 4]>>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                s.spawn(move || {
                    (t * chunk..((t + 1) * chunk).min(65536))
                        .map(|c| case_tets4(c as u16).0)
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("table thread"))
            .collect()
    });
    let mut out = Vec::new();
    out.extend_from_slice(TABLE_MAGIC);
    let mut offsets = Vec::with_capacity(65537);
    let mut tets = Vec::new();
    for case in parts.into_iter().flatten() {
        offsets.push(tets.len() as u32);
        tets.extend(case);
    }
    offsets.push(tets.len() as u32);
    for o in offsets {
        out.extend_from_slice(&o.to_le_bytes());
    }
    for t in &tets {
        out.extend_from_slice(t);
    }
    let mut cap_offsets = Vec::with_capacity(257);
    let mut cap_tets = Vec::new();
    for c in 0..256u32 {
        cap_offsets.push(cap_tets.len() as u32);
        cap_tets.extend(case_tets3(c as u8));
    }
    cap_offsets.push(cap_tets.len() as u32);
    for o in cap_offsets {
        out.extend_from_slice(&o.to_le_bytes());
    }
    for t in &cap_tets {
        out.extend_from_slice(t);
    }
    out
}
