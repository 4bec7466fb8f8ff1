//! Face adjacency of a closed tet mesh: for each tet and each face (face i omits vertex i),
//! the tet on the other side.

#[cfg(test)]
use chronotope_mesh::TetMesh;

/// No neighbour (the mesh is open there).
pub const NO_NEIGHBOUR: u32 = u32::MAX;

/// Neighbours across each face. Faces shared by more than two tets (never in a closed
/// 2-manifold boundary) are left unlinked, as are faces naming a vertex that does not exist.
/// (The whole mesh at once: what the pieces' adjacency is tested against.)
#[cfg(test)]
pub fn face_adjacency(mesh: &TetMesh) -> Vec<[u32; 4]> {
    let mut b = AdjacencyBuilder::new();
    b.add(&mesh.tets, mesh.vertices.len());
    b.finish()
}

/// Face adjacency built piece by piece as a mesh arrives (the slabs of a stream): each
/// piece's faces are paired among themselves and with the faces still unpaired from the
/// pieces before (in a slab stack, the body's surface at the slab's first frame).
///
/// Faces are bucketed by their smallest vertex (a counting sort over the range of vertices
/// the round's faces span), and within each bucket, a few dozen faces around one vertex,
/// equal faces are paired by a scan (by a sort on the other two vertices in the rare larger
/// bucket). A face met more than twice in one round is left unlinked; one met a third time
/// in a later round stays unpaired (neither happens in a closed 2-manifold boundary).
#[derive(Debug, Default)]
pub struct AdjacencyBuilder {
    adj: Vec<[u32; 4]>,
    /// Faces not paired yet: sorted vertex triple and `tet << 2 | face`.
    pending: Vec<([u32; 3], u64)>,
    /// Most faces bucketed at once ([`BATCH_FACES`] unless a test says otherwise).
    batch_faces: Option<u32>,
}

impl AdjacencyBuilder {
    /// No tets yet.
    #[cfg(test)]
    pub fn new() -> Self {
        Self::default()
    }

    /// Makes room for `tets` more tets' neighbours (exactly, where growing would double).
    pub fn reserve_tets(&mut self, tets: usize) {
        self.adj.reserve_exact(tets);
    }

    /// Adds `tets` (numbered after the tets added before) over a vertex table of
    /// `vertices` entries, linking them with each other and with the unpaired faces of
    /// earlier tets.
    pub fn add(&mut self, tets: &[[u32; 4]], vertices: usize) {
        let first = self.adj.len() as u64;
        self.adj
            .resize(self.adj.len() + tets.len(), [NO_NEIGHBOUR; 4]);
        // This round's faces are the pending ones and the new tets' faces over existing
        // vertices. They are walked (not stored: they would be the largest buffer here)
        // once for their range, once to count and once to place them in the buckets.
        let pending = std::mem::take(&mut self.pending);
        let (mut lo, mut hi, mut n) = (u32::MAX, 0u32, 0usize);
        round_faces(&pending, tets, first, vertices, &mut |f, _| {
            lo = lo.min(f[0]);
            hi = hi.max(f[0]);
            n += 1;
        });
        if n == 0 {
            self.pending = pending;
            return;
        }
        let span = (hi - lo) as usize + 1;
        if span > 4 * n + 64 {
            // Faces spread over far more vertices than there are faces (a piece far from
            // the unpaired faces of an open mesh): sort rather than bucket.
            let mut faces = Vec::with_capacity(n);
            round_faces(&pending, tets, first, vertices, &mut |f, id| {
                faces.push((f, id))
            });
            faces.sort_unstable();
            self.pending = pending;
            self.pending.clear();
            for run in faces.chunk_by(|a, b| a.0 == b.0) {
                match run {
                    [one] => self.pending.push(*one),
                    [(_, x), (_, y)] => link(&mut self.adj, *x, *y),
                    _ => {}
                }
            }
            return;
        }
        // Bucket starts by smallest vertex. A round's buffers are its own: a body is
        // prepared in a few rounds (a window's two or three pieces), the largest a cap that
        // fills its volume, and nothing is held for a next round.
        let mut start = vec![0u32; span + 1];
        round_faces(&pending, tets, first, vertices, &mut |f, _| {
            start[(f[0] - lo) as usize + 1] += 1
        });
        for v in 0..span {
            start[v + 1] += start[v];
        }
        // The buckets are filled and paired in batches of whole buckets, at most
        // `BATCH_FACES` faces each (a larger bucket alone), each batch walking the faces
        // again: a cap that fills a body's volume has millions of faces, 16 bytes each here.
        // `start[v]` becomes the end of bucket v once its batch is filled.
        let (mut keys_all, mut ids_all, mut bucket) = (Vec::new(), Vec::new(), Vec::new());
        let mut next_pending = Vec::new();
        let mut v0 = 0;
        while v0 < span {
            let base = start[v0];
            let batch = self.batch_faces.unwrap_or(BATCH_FACES);
            let k = start[v0 + 1..=span].partition_point(|&e| e - base <= batch);
            let v1 = (v0 + k).max(v0 + 1);
            let m = (start[v1] - base) as usize;
            keys_all.resize(m, 0u64);
            ids_all.resize(m, 0u64);
            round_faces(&pending, tets, first, vertices, &mut |f, id| {
                let v = (f[0] - lo) as usize;
                if (v0..v1).contains(&v) {
                    let slot = &mut start[v];
                    let at = (*slot - base) as usize;
                    keys_all[at] = u64::from(f[1]) << 32 | u64::from(f[2]);
                    ids_all[at] = id;
                    *slot += 1;
                }
            });
            let mut begin = 0;
            for v in v0..v1 {
                let end = (start[v] - base) as usize;
                let (keys, ids) = (&mut keys_all[begin..end], &ids_all[begin..end]);
                let face = |key: u64| [lo + v as u32, (key >> 32) as u32, key as u32];
                if keys.len() <= SCAN_BUCKET {
                    // Pair by scanning: each face against the later ones (a few hundred
                    // compares in L1 beat a general sort at this size); a key seen is cleared
                    // to `SEEN`.
                    for i in 0..keys.len() {
                        let key = keys[i];
                        if key == SEEN {
                            continue;
                        }
                        let (mut partner, mut count) = (None, 1);
                        for (j, other) in keys.iter_mut().enumerate().skip(i + 1) {
                            if *other == key {
                                partner = Some(j);
                                count += 1;
                                *other = SEEN;
                            }
                        }
                        match (partner, count) {
                            (Some(j), 2) => link(&mut self.adj, ids[i], ids[j]),
                            (None, _) => next_pending.push((face(key), ids[i])),
                            _ => {}
                        }
                    }
                } else {
                    bucket.clear();
                    bucket.extend(keys.iter().copied().zip(ids.iter().copied()));
                    bucket.sort_unstable();
                    for run in bucket.chunk_by(|a, b| a.0 == b.0) {
                        match run {
                            [(key, x)] => next_pending.push((face(*key), *x)),
                            [(_, x), (_, y)] => link(&mut self.adj, *x, *y),
                            _ => {}
                        }
                    }
                }
                begin = end;
            }
            v0 = v1;
        }
        self.pending = next_pending;
    }

    /// The neighbours of every tet added (faces still unpaired have none).
    pub fn finish(self) -> Vec<[u32; 4]> {
        self.adj
    }
}

/// Calls `visit` on each face of a round: the `pending` ones, then each face of `tets`
/// (numbered from `first`) over the `vertices` that exist, with its `tet << 2 | face`.
#[inline]
fn round_faces(
    pending: &[([u32; 3], u64)],
    tets: &[[u32; 4]],
    first: u64,
    vertices: usize,
    visit: &mut impl FnMut([u32; 3], u64),
) {
    for &(f, id) in pending {
        visit(f, id);
    }
    for (t, tet) in tets.iter().enumerate() {
        for (f, i) in sorted_faces(*tet) {
            if (f[2] as usize) < vertices {
                visit(f, (first + t as u64) << 2 | u64::from(i));
            }
        }
    }
}

/// Links the faces `x` and `y` (each `tet << 2 | face`).
#[inline]
fn link(adj: &mut [[u32; 4]], x: u64, y: u64) {
    adj[(x >> 2) as usize][(x & 3) as usize] = (y >> 2) as u32;
    adj[(y >> 2) as usize][(y & 3) as usize] = (x >> 2) as u32;
}

/// The faces of a tet as sorted vertex triples, each with its face index (the position of
/// the vertex it omits): one sorting network over the four ids rather than a sort per face.
fn sorted_faces(tet: [u32; 4]) -> [([u32; 3], u32); 4] {
    let k = chronotope_mesh::validate::sorted_tet_ids(tet);
    let id = |x: u64| (x >> 2) as u32;
    let omit = |j: usize| {
        let mut f = [0; 3];
        for (o, x) in f.iter_mut().zip((0..4).filter(|&i| i != j)) {
            *o = id(k[x]);
        }
        (f, (k[j] & 3) as u32)
    };
    [omit(0), omit(1), omit(2), omit(3)]
}

/// Buckets up to this size are paired by scanning, larger ones by sorting.
const SCAN_BUCKET: usize = 48;

/// Most faces bucketed at once (16 bytes each: 8 MiB).
const BATCH_FACES: u32 = 1 << 19;

/// A key no face has (other two vertex ids both `u32::MAX`, which is no vertex of a
/// mesh with fewer than 2^32 vertices): marks a face already paired in the scan.
const SEEN: u64 = u64::MAX;

#[cfg(test)]
mod tests {
    use super::*;

    /// Fed in pieces of any size, the adjacency is the one built at once, except where a
    /// face is met more than twice.
    #[test]
    fn pieces_give_the_same_adjacency_as_the_whole() {
        // A strip of tets, each sharing a face with the next; two more on face (5, 6, 7)
        // (met four times) and one on (9, 10, 11) through a missing vertex (met three).
        let mut tets = Vec::new();
        for k in 0..200u32 {
            tets.push([k, k + 1, k + 2, k + 3]);
        }
        tets.push([5, 6, 7, 300]);
        tets.push([5, 6, 7, 301]);
        tets.push([9, 10, 11, 999]);
        let mesh = TetMesh {
            vertices: vec![[0; 4]; 302],
            tets: tets.clone(),
        };
        let whole = face_adjacency(&mesh);
        for (cut, batch) in [1, 7, 50, 199]
            .into_iter()
            .zip([None, Some(3), Some(1), Some(40)])
        {
            let mut b = AdjacencyBuilder::new();
            b.batch_faces = batch;
            for piece in tets.chunks(cut) {
                b.add(piece, 302);
            }
            let pieces = b.finish();
            // Faces met three times within one round are unlinked either way; across
            // rounds the first two meet and link. Everything else agrees.
            for (t, (w, p)) in whole.iter().zip(&pieces).enumerate() {
                for f in 0..4 {
                    if w[f] != p[f] {
                        assert!(
                            w[f] == NO_NEIGHBOUR && [4, 5, 8, 9, 200, 201, 202].contains(&t),
                            "cut {cut}, tet {t} face {f}: {} vs {}",
                            w[f],
                            p[f]
                        );
                    }
                }
            }
        }
    }

    /// The Kuhn triangulation of an `n`³ grid of cubes (six tets a cube: every inner face
    /// in two tets, every outer one in one), with its vertices numbered at random.
    fn kuhn_grid(n: u32, next: &mut impl FnMut(u32) -> u32) -> (Vec<[u32; 4]>, usize) {
        let side = n + 1;
        let count = (side * side * side) as usize;
        let mut label: Vec<u32> = (0..count as u32).collect();
        for i in (1..count).rev() {
            label.swap(i, next(i as u32 + 1) as usize);
        }
        let id = |p: [u32; 3]| label[(p[0] + side * (p[1] + side * p[2])) as usize];
        let mut tets = Vec::new();
        for (x, y, z) in
            (0..n).flat_map(|x| (0..n).flat_map(move |y| (0..n).map(move |z| (x, y, z))))
        {
            // One tet per order of the three axes, from the cube's low corner to its high.
            let orders = (0..3usize).flat_map(|a| {
                (0..3)
                    .filter(move |&b| b != a)
                    .map(move |b| [a, b, 3 - a - b])
            });
            for axes in orders {
                let mut p = [x, y, z];
                let mut tet = [id(p); 4];
                for (k, a) in axes.into_iter().enumerate() {
                    p[a] += 1;
                    tet[k + 1] = id(p);
                }
                tets.push(tet);
            }
        }
        // In grid order (the tets of one cube share faces: small pieces pair among
        // themselves) or shuffled.
        if next(2) == 0 {
            for i in (1..tets.len()).rev() {
                tets.swap(i, next(i as u32 + 1) as usize);
            }
        }
        (tets, count)
    }

    /// Fed in random pieces (small ones far apart in vertex numbering take the sorting
    /// path, large ones the buckets), a mesh whose faces are each in at most two tets gets
    /// exactly the adjacency of a plain map from faces to tets, whatever the batches its
    /// buckets are filled in.
    #[test]
    fn random_pieces_link_exactly_the_tets_sharing_a_face() {
        for seed in 1..25u64 {
            let mut s = seed;
            let mut next = move |m: u32| {
                s = s
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                ((s >> 33) % u64::from(m)) as u32
            };
            let (tets, vertices) = kuhn_grid(2 + next(7), &mut next);
            let mut by_face: std::collections::HashMap<[u32; 3], Vec<(usize, usize)>> =
                Default::default();
            for (t, tet) in tets.iter().enumerate() {
                for f in 0..4 {
                    let mut face: Vec<u32> = (0..4).filter(|&i| i != f).map(|i| tet[i]).collect();
                    face.sort_unstable();
                    by_face
                        .entry([face[0], face[1], face[2]])
                        .or_default()
                        .push((t, f));
                }
            }
            let mut expected = vec![[NO_NEIGHBOUR; 4]; tets.len()];
            for uses in by_face.values() {
                assert!(uses.len() <= 2);
                if let [(t, f), (u, g)] = uses[..] {
                    expected[t][f] = u as u32;
                    expected[u][g] = t as u32;
                }
            }
            // Buckets filled in one batch, or in batches of a few faces (a bucket larger
            // than a batch is one of its own).
            for batch in [None, Some(1), Some(7), Some(100)] {
                let mut b = AdjacencyBuilder::new();
                b.batch_faces = batch;
                let mut at = 0;
                while at < tets.len() {
                    let len = [1, 2, 5, 40, 400][next(5) as usize].min(tets.len() - at);
                    b.add(&tets[at..at + len], vertices);
                    at += len;
                }
                assert_eq!(b.finish(), expected, "seed {seed}, batch {batch:?}");
            }
        }
    }

    #[test]
    fn tets_sharing_a_face_are_neighbours_and_missing_vertices_are_unlinked() {
        let mesh = TetMesh {
            vertices: vec![[0; 4]; 5],
            tets: vec![[0, 1, 2, 3], [4, 1, 2, 3], [0, 1, 2, 99]],
        };
        let adj = face_adjacency(&mesh);
        // Tets 0 and 1 share face (1, 2, 3); tets 0 and 2 share (0, 1, 2), and tet 2's
        // faces through the missing vertex 99 are left unlinked.
        assert_eq!(adj[0], [1, NO_NEIGHBOUR, NO_NEIGHBOUR, 2]);
        assert_eq!(adj[1], [0, NO_NEIGHBOUR, NO_NEIGHBOUR, NO_NEIGHBOUR]);
        assert_eq!(adj[2], [NO_NEIGHBOUR, NO_NEIGHBOUR, NO_NEIGHBOUR, 0]);
    }
}
