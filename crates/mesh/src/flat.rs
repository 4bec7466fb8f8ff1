//! Fewer triangles for display: the flat faces of a slice merged into few triangles.
//!
//! A t-slice of a body's 4D mesh cuts every tet that crosses the plane, so a flat face of a
//! box (a table, a fixture, a machine's head) comes out as thousands of small triangles
//! (about ten per voxel face): correct, closed, and costly to send to a display at every
//! frame period. Here the triangles that lie in one axis-aligned plane, face the same way
//! and carry the same display class (a label colour) are merged: their union's boundary is
//! found by cancelling the edges shared inside it (exactly, by vertex id: the slice is
//! welded), straight runs of the boundary along an axis lose their middle vertices (exactly:
//! the coordinate is shared bit for bit), and the polygons (with their holes) are
//! triangulated again by ear clipping from the same vertices.
//!
//! Nothing is merged that is not provably in one plane (every vertex shares that coordinate
//! bit for bit), and a group whose boundary is not a set of simple loops, whose
//! triangulation fails, or whose area would change is left as it was. So the display shows
//! the same surface, with its seams, orientation and colours, in far fewer triangles; the
//! check never reads these triangles.

use super::slice::TriMesh;

/// Most boundary vertices of one merged group (ear clipping is quadratic in them); a larger
/// group is left as it was.
const MAX_LOOP_VERTICES: usize = 4096;

/// The plane each triangle of a slice lies in, if it lies in an axis-aligned one: what
/// [`merge_flat_with`] groups by. Found once per slice (on rayon's pool), it serves every
/// merge of that slice's triangles (the whole slice, then each labelled part of it).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FlatFaces {
    /// Per triangle: the axis, the coordinate's bits and whether it faces +axis.
    planes: Vec<Option<(u8, u64, bool)>>,
}

impl FlatFaces {
    /// The planes of the triangles of `mesh`.
    pub fn of(mesh: &TriMesh) -> Self {
        use rayon::prelude::*;
        let planes = mesh
            .triangles
            .par_iter()
            .with_min_len(4096)
            .map(|t| {
                let p = t.map(|v| mesh.vertices[v as usize]);
                flat_axis(&p).map(|(k, facing)| (k as u8, p[0][k].to_bits(), facing))
            })
            .collect();
        Self { planes }
    }
}

/// The triangles of `mesh` that `class_of` picks (`Some(class)`, a display class), with the
/// flat faces of each class merged (see the module documentation): the triangles (vertex
/// ids of `mesh`) and their classes.
pub fn merge_flat(
    mesh: &TriMesh,
    class_of: impl Fn(usize) -> Option<u8>,
) -> (Vec<[u32; 3]>, Vec<u8>) {
    merge_flat_with(mesh, &FlatFaces::of(mesh), class_of)
}

/// [`merge_flat`] with the planes of the triangles found before (`flats`, of `mesh`); the
/// groups are merged on rayon's pool (the same triangles in the same order).
///
/// # Panics
/// If `flats` is not of `mesh` (another triangle count).
pub fn merge_flat_with(
    mesh: &TriMesh,
    flats: &FlatFaces,
    class_of: impl Fn(usize) -> Option<u8>,
) -> (Vec<[u32; 3]>, Vec<u8>) {
    use rayon::prelude::*;
    assert_eq!(
        flats.planes.len(),
        mesh.triangles.len(),
        "the flat faces of another mesh"
    );
    // Groups: (axis, coordinate bits, facing +/-, class), each with its triangles in order:
    // sorted as one packed key (axis, bits, facing, class, triangle) from the high bits.
    let mut flat: Vec<u128> = Vec::new();
    let mut out = Vec::new();
    let mut out_class = Vec::new();
    for (i, (t, plane)) in mesh.triangles.iter().zip(&flats.planes).enumerate() {
        let Some(c) = class_of(i) else {
            continue;
        };
        match *plane {
            Some((k, bits, facing)) => flat.push(
                u128::from(k) << 105
                    | u128::from(bits) << 41
                    | u128::from(facing) << 40
                    | u128::from(c) << 32
                    | i as u128,
            ),
            None => {
                out.push(*t);
                out_class.push(c);
            }
        }
    }
    flat.sort_unstable();
    let group = |x: &u128| x >> 32;
    let triangle = |x: &u128| *x as u32;
    let groups: Vec<&[u128]> = flat.chunk_by(|a, b| group(a) == group(b)).collect();
    let merged: Vec<Option<Vec<[u32; 3]>>> = groups
        .par_iter()
        .map(|g| {
            let key = g[0];
            if g.len() > 2 {
                let tris: Vec<u32> = g.iter().map(triangle).collect();
                merge_group(mesh, &tris, (key >> 105) as usize, key >> 40 & 1 == 1)
            } else {
                None
            }
        })
        .collect();
    for (g, m) in groups.iter().zip(merged) {
        match m {
            Some(m) => out.extend(m),
            None => out.extend(g.iter().map(|x| mesh.triangles[triangle(x) as usize])),
        }
        out_class.resize(out.len(), (g[0] >> 32) as u8);
    }
    (out, out_class)
}

/// The axis whose coordinate all three points share exactly, and whether the triangle
/// (counter-clockwise seen from outside) faces +axis.
fn flat_axis(p: &[[f64; 3]; 3]) -> Option<(usize, bool)> {
    for k in 0..3 {
        if p[0][k].to_bits() == p[1][k].to_bits() && p[0][k].to_bits() == p[2][k].to_bits() {
            let (u, v) = plane_axes(k);
            let a = cross2(
                [p[1][u] - p[0][u], p[1][v] - p[0][v]],
                [p[2][u] - p[0][u], p[2][v] - p[0][v]],
            );
            if a == 0.0 {
                return None;
            }
            return Some((k, a > 0.0));
        }
    }
    None
}

/// The two axes of the plane normal to `k`, ordered so that (u, v, k) is right-handed.
fn plane_axes(k: usize) -> (usize, usize) {
    ((k + 1) % 3, (k + 2) % 3)
}

fn cross2(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// The group's triangles merged, or `None` to keep them as they are.
fn merge_group(mesh: &TriMesh, tris: &[u32], k: usize, facing: bool) -> Option<Vec<[u32; 3]>> {
    // Boundary: directed edges whose reverse is not in the group, counted with multiplicity
    // (each undirected edge once, +1 along it, -1 against: sorted, then summed), each as
    // one word: the smaller id, the larger, and a bit for the direction (so ids below 2^31;
    // a slice with more vertices is not merged).
    if mesh.vertices.len() > 1 << 31 {
        return None;
    }
    let mut edges: Vec<u64> = Vec::with_capacity(3 * tris.len());
    for &i in tris {
        let t = mesh.triangles[i as usize];
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            let (lo, hi) = (a.min(b), a.max(b));
            edges.push(u64::from(lo) << 33 | u64::from(hi) << 1 | u64::from(a < b));
        }
    }
    edges.sort_unstable();
    // The boundary edges (from, to), sorted by `from`.
    let mut next: Vec<(u32, u32)> = Vec::new();
    for run in edges.chunk_by(|x, y| x >> 1 == y >> 1) {
        let (a, b) = ((run[0] >> 33) as u32, (run[0] >> 1) as u32);
        match run
            .iter()
            .map(|e| if e & 1 == 1 { 1 } else { -1 })
            .sum::<i32>()
        {
            0 => {}
            1 => next.push((a, b)),
            -1 => next.push((b, a)),
            _ => return None,
        }
    }
    next.sort_unstable();
    if next.windows(2).any(|w| w[0].0 == w[1].0) {
        // Two boundary edges leave one vertex: a pinch; left as it was.
        return None;
    }
    if next.len() > MAX_LOOP_VERTICES {
        return None;
    }
    // 2D coordinates seen from the side the group faces (counter-clockwise = outward).
    let (u, v) = plane_axes(k);
    let xy = |id: u32| {
        let p = mesh.vertices[id as usize];
        if facing {
            [p[u], p[v]]
        } else {
            [p[v], p[u]]
        }
    };
    // Loops, with the middle vertices of straight runs along an axis dropped.
    let mut loops: Vec<Vec<u32>> = Vec::new();
    let mut seen = vec![false; next.len()];
    for s in 0..next.len() {
        if seen[s] {
            continue;
        }
        let mut lp = Vec::new();
        let mut c = next[s].0;
        loop {
            let at = next.binary_search_by_key(&c, |e| e.0).ok()?;
            if std::mem::replace(&mut seen[at], true) {
                break;
            }
            lp.push(c);
            c = next[at].1;
        }
        if c != next[s].0 {
            return None;
        }
        let lp = drop_straight(&lp, &xy);
        if lp.len() < 3 {
            return None;
        }
        loops.push(lp);
    }
    let area = |lp: &[u32]| -> f64 {
        let n = lp.len();
        (0..n)
            .map(|i| cross2(xy(lp[i]), xy(lp[(i + 1) % n])))
            .sum::<f64>()
            / 2.0
    };
    // Each loop's area, found once.
    let (mut outers, holes): (Vec<(f64, Vec<u32>)>, Vec<(f64, Vec<u32>)>) = loops
        .into_iter()
        .map(|lp| (area(&lp), lp))
        .partition(|(a, _)| *a > 0.0);
    // Each hole joins the smallest outer loop holding its first vertex.
    let mut with_holes: Vec<Vec<u32>> = Vec::new();
    outers.sort_by(|a, b| a.0.total_cmp(&b.0));
    let outers: Vec<Vec<u32>> = outers.into_iter().map(|(_, o)| o).collect();
    let mut assigned: Vec<Vec<Vec<u32>>> = vec![Vec::new(); outers.len()];
    for (_, h) in holes {
        let p = xy(h[0]);
        let owner = outers.iter().position(|o| inside(o, p, &xy))?;
        assigned[owner].push(h);
    }
    for (o, hs) in outers.iter().zip(assigned) {
        with_holes.push(bridge(o.clone(), hs, &xy)?);
    }
    let mut out = Vec::new();
    for poly in with_holes {
        ear_clip(&poly, &xy, &mut out)?;
    }
    if out.len() >= tris.len() {
        return None;
    }
    // The same area, or nothing changes. The group's triangles' area is the sum over its
    // boundary edges (every inner edge cancels: Green's theorem, term by term), taken
    // around one of its vertices to keep the products small.
    let tri_area = |t: &[u32; 3]| {
        cross2(
            [xy(t[1])[0] - xy(t[0])[0], xy(t[1])[1] - xy(t[0])[1]],
            [xy(t[2])[0] - xy(t[0])[0], xy(t[2])[1] - xy(t[0])[1]],
        ) / 2.0
    };
    let o = next.first().map_or([0.0; 2], |e| xy(e.0));
    let before: f64 = next
        .iter()
        .map(|&(a, b)| {
            let (a, b) = (xy(a), xy(b));
            cross2([a[0] - o[0], a[1] - o[1]], [b[0] - o[0], b[1] - o[1]])
        })
        .sum::<f64>()
        / 2.0;
    let after: f64 = out.iter().map(tri_area).sum();
    if (before - after).abs() > 1e-9 * before.abs().max(1.0) {
        return None;
    }
    Some(out)
}

/// The loop without the middle vertices of straight runs along an axis (three consecutive
/// vertices sharing an x or a y bit for bit).
fn drop_straight(lp: &[u32], xy: &impl Fn(u32) -> [f64; 2]) -> Vec<u32> {
    let mut cur: Vec<u32> = lp.to_vec();
    loop {
        let n = cur.len();
        if n < 4 {
            return cur;
        }
        let keep: Vec<bool> = (0..n)
            .map(|i| {
                let (a, b, c) = (xy(cur[(i + n - 1) % n]), xy(cur[i]), xy(cur[(i + 1) % n]));
                let same =
                    |m: usize| a[m].to_bits() == b[m].to_bits() && b[m].to_bits() == c[m].to_bits();
                !(same(0) || same(1))
            })
            .collect();
        if keep.iter().all(|&k| k) {
            return cur;
        }
        cur = cur
            .iter()
            .zip(&keep)
            .filter(|(_, &k)| k)
            .map(|(&v, _)| v)
            .collect();
    }
}

/// Whether `p` lies inside the loop (even-odd rule).
fn inside(lp: &[u32], p: [f64; 2], xy: &impl Fn(u32) -> [f64; 2]) -> bool {
    let n = lp.len();
    let mut odd = false;
    for i in 0..n {
        let (a, b) = (xy(lp[i]), xy(lp[(i + 1) % n]));
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if x > p[0] {
                odd = !odd;
            }
        }
    }
    odd
}

/// One polygon from an outer loop and its holes: each hole joined to the outline by a cut
/// from its rightmost vertex to a vertex of the outline it can see (walked there and back).
fn bridge(
    mut outer: Vec<u32>,
    mut holes: Vec<Vec<u32>>,
    xy: &impl Fn(u32) -> [f64; 2],
) -> Option<Vec<u32>> {
    holes.sort_by(|a, b| {
        let m = |h: &Vec<u32>| h.iter().map(|&v| xy(v)[0]).fold(f64::MIN, f64::max);
        m(b).total_cmp(&m(a))
    });
    for h in holes {
        let (hi, _) = h
            .iter()
            .enumerate()
            .max_by(|a, b| xy(*a.1)[0].total_cmp(&xy(*b.1)[0]))?;
        let hp = xy(h[hi]);
        // The nearest outline vertex to the right that the cut reaches without crossing
        // an edge of the outline or of the hole.
        let mut best: Option<(f64, usize)> = None;
        for (j, &o) in outer.iter().enumerate() {
            let op = xy(o);
            let d = (op[0] - hp[0]).hypot(op[1] - hp[1]);
            if best.is_some_and(|(bd, _)| bd <= d) {
                continue;
            }
            if !segment_clear(hp, op, &outer, &h, xy) {
                continue;
            }
            best = Some((d, j));
        }
        let (_, j) = best?;
        let mut merged = Vec::with_capacity(outer.len() + h.len() + 2);
        merged.extend_from_slice(&outer[..=j]);
        for m in 0..=h.len() {
            merged.push(h[(hi + m) % h.len()]);
        }
        merged.push(outer[j]);
        merged.extend_from_slice(&outer[j + 1..]);
        outer = merged;
    }
    Some(outer)
}

/// Whether the open segment p–q crosses no edge of the loops (edges through p or q aside).
fn segment_clear(
    p: [f64; 2],
    q: [f64; 2],
    a: &[u32],
    b: &[u32],
    xy: &impl Fn(u32) -> [f64; 2],
) -> bool {
    for lp in [a, b] {
        let n = lp.len();
        for i in 0..n {
            let (c, d) = (xy(lp[i]), xy(lp[(i + 1) % n]));
            if c == p || c == q || d == p || d == q {
                continue;
            }
            if segments_cross(p, q, c, d) {
                return false;
            }
        }
    }
    true
}

fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    cross2([b[0] - a[0], b[1] - a[1]], [c[0] - a[0], c[1] - a[1]])
}

/// Whether closed segments a–b and c–d meet.
fn segments_cross(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> bool {
    let (o1, o2, o3, o4) = (
        orient(a, b, c),
        orient(a, b, d),
        orient(c, d, a),
        orient(c, d, b),
    );
    if ((o1 > 0.0) != (o2 > 0.0)) && ((o3 > 0.0) != (o4 > 0.0)) && o1 != 0.0 && o2 != 0.0 {
        return true;
    }
    let on = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        orient(p, q, r) == 0.0
            && r[0] >= p[0].min(q[0])
            && r[0] <= p[0].max(q[0])
            && r[1] >= p[1].min(q[1])
            && r[1] <= p[1].max(q[1])
    };
    on(a, b, c) || on(a, b, d) || on(c, d, a) || on(c, d, b)
}

/// Ear clipping of a simple counter-clockwise polygon (holes bridged in); `None` if no ear
/// can be found (a degenerate outline).
fn ear_clip(poly: &[u32], xy: &impl Fn(u32) -> [f64; 2], out: &mut Vec<[u32; 3]>) -> Option<()> {
    let mut v: Vec<u32> = poly.to_vec();
    let mut guard = 0usize;
    while v.len() > 3 {
        let n = v.len();
        let mut clipped = false;
        for i in 0..n {
            let (ia, ib, ic) = ((i + n - 1) % n, i, (i + 1) % n);
            let (a, b, c) = (xy(v[ia]), xy(v[ib]), xy(v[ic]));
            if orient(a, b, c) <= 0.0 {
                continue;
            }
            // No other vertex inside or on the ear (a bridged hole repeats two vertices:
            // copies of the ear's corners are not in the way).
            let blocked = (0..n).any(|j| {
                if j == ia || j == ib || j == ic {
                    return false;
                }
                let p = xy(v[j]);
                if p == a || p == b || p == c {
                    return false;
                }
                orient(a, b, p) >= 0.0 && orient(b, c, p) >= 0.0 && orient(c, a, p) >= 0.0
            });
            if blocked {
                continue;
            }
            out.push([v[ia], v[ib], v[ic]]);
            v.remove(ib);
            clipped = true;
            break;
        }
        if !clipped {
            return None;
        }
        guard += 1;
        if guard > poly.len() * 2 {
            return None;
        }
    }
    let (a, b, c) = (xy(v[0]), xy(v[1]), xy(v[2]));
    if orient(a, b, c) > 0.0 {
        out.push([v[0], v[1], v[2]]);
    } else if orient(a, b, c) < 0.0 {
        return None;
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hash::{fast_map, FastMap as HashMap};

    /// The total signed area per (axis, plane, facing) and the closedness of a triangle set.
    fn check_same_surface(mesh: &TriMesh, a: &[[u32; 3]], b: &[[u32; 3]]) {
        let edges = |tris: &[[u32; 3]]| {
            let mut net: HashMap<(u32, u32), i32> = fast_map();
            for t in tris {
                for (x, y) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                    let (key, s) = if x < y { ((x, y), 1) } else { ((y, x), -1) };
                    *net.entry(key).or_insert(0) += s;
                }
            }
            net.retain(|_, n| *n != 0);
            net
        };
        // A closed surface stays closed (the merged faces' outlines are their old outlines,
        // and straight runs lose vertices only where the neighbour faces are not merged the
        // same way, so compare areas per plane instead of edges).
        assert!(edges(a).is_empty(), "the input is closed");
        let area = |tris: &[[u32; 3]]| {
            let mut per: HashMap<(usize, u64, bool), f64> = fast_map();
            for t in tris {
                let p = t.map(|v| mesh.vertices[v as usize]);
                if let Some((k, f)) = flat_axis(&p) {
                    let (u, v) = plane_axes(k);
                    let ar = cross2(
                        [p[1][u] - p[0][u], p[1][v] - p[0][v]],
                        [p[2][u] - p[0][u], p[2][v] - p[0][v]],
                    )
                    .abs();
                    *per.entry((k, p[0][k].to_bits(), f)).or_default() += ar;
                }
            }
            per
        };
        let (x, y) = (area(a), area(b));
        assert_eq!(x.len(), y.len());
        for (key, v) in x {
            assert!((v - y[&key]).abs() < 1e-9, "{key:?}");
        }
    }

    /// The slice of a static box body: a closed box surface of many small triangles.
    fn box_slice(size: [u32; 3], lo: [usize; 3], hi: [usize; 3]) -> TriMesh {
        use crate::grid::{DecodeOptions, FrameRef};
        let n = (size[0] * size[1] * size[2]) as usize;
        let mut data = vec![0u8; n.div_ceil(8)];
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let i = x + size[0] as usize * (y + size[1] as usize * z);
                    data[i / 8] |= 1 << (i % 8);
                }
            }
        }
        let mut m = crate::Mesher::new(crate::MesherOptions::default()).unwrap();
        let mut slab = None;
        for k in 0..2 {
            let f = FrameRef {
                stamp_ns: k,
                origin: [0.0; 3],
                resolution: 0.1,
                size,
                encoding: 0,
                data: &data,
            };
            slab = m.push(&f).unwrap();
        }
        let _ = DecodeOptions::default();
        let slab = slab.unwrap();
        // A little after the slab's middle (off every lattice vertex), as the markers cut.
        let scale = i64::from(slab.geometry.scale);
        let plane = crate::slice::PlaneValue {
            num: 1024 * scale * slab.index as i64 + 512 * scale + 1,
            den: 1024,
        };
        let mut s = crate::slice::Slicer::new(3, plane);
        s.add(&slab.mesh);
        s.finish()
    }

    #[test]
    fn a_box_face_of_many_triangles_becomes_a_few() {
        let mesh = box_slice([20, 16, 12], [2, 3, 2], [15, 11, 8]);
        assert!(!mesh.triangles.is_empty());
        let (merged, classes) = merge_flat(&mesh, |_| Some(0));
        assert_eq!(merged.len(), classes.len());
        assert!(
            merged.len() * 5 < mesh.triangles.len(),
            "{} -> {}",
            mesh.triangles.len(),
            merged.len()
        );
        check_same_surface(&mesh, &mesh.triangles, &merged);
    }

    #[test]
    fn classes_are_kept_apart() {
        let mesh = box_slice([12, 12, 12], [2, 2, 2], [8, 8, 8]);
        // Every other triangle in another class: no two of a class are neighbours on a
        // face, so nothing merges across classes.
        let (merged, classes) = merge_flat(&mesh, |i| Some((i % 2) as u8));
        let count = |c: u8| classes.iter().filter(|&&x| x == c).count();
        assert!(count(0) > 0 && count(1) > 0);
        assert_eq!(merged.len(), classes.len());
        // A subset only: the others are left out.
        let (some, _) = merge_flat(&mesh, |i| (i % 3 == 0).then_some(0));
        assert!(some.len() <= mesh.triangles.len() / 3 + 1);
    }
}
