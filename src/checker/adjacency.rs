//! Face adjacency of a closed tet mesh: for each tet and each face (face i omits vertex i),
//! the tet on the other side.

use crate::mesh::TetMesh;

/// No neighbour (the mesh is open there).
pub const NO_NEIGHBOUR: u32 = u32::MAX;

/// Neighbours across each face. Faces shared by more than two tets (never in a closed
/// 2-manifold boundary) are left unlinked, as are faces naming a vertex that does not exist.
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
    /// This round's faces (pending ones first).
    faces: Vec<([u32; 3], u64)>,
    start: Vec<u32>,
    keys: Vec<u64>,
    ids: Vec<u64>,
    bucket: Vec<(u64, u64)>,
}

impl AdjacencyBuilder {
    /// No tets yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Tets added so far.
    pub fn len(&self) -> usize {
        self.adj.len()
    }

    /// Whether no tet was added.
    pub fn is_empty(&self) -> bool {
        self.adj.is_empty()
    }

    /// Adds `tets` (numbered after the tets added before) over a vertex table of
    /// `vertices` entries, linking them with each other and with the unpaired faces of
    /// earlier tets.
    pub fn add(&mut self, tets: &[[u32; 4]], vertices: usize) {
        let first = self.adj.len() as u64;
        self.adj
            .resize(self.adj.len() + tets.len(), [NO_NEIGHBOUR; 4]);
        self.faces.clear();
        self.faces.append(&mut self.pending);
        for (t, tet) in tets.iter().enumerate() {
            for (f, i) in sorted_faces(*tet) {
                if (f[2] as usize) < vertices {
                    self.faces.push((f, (first + t as u64) << 2 | u64::from(i)));
                }
            }
        }
        let Some(lo) = self.faces.iter().map(|f| f.0[0]).min() else {
            return;
        };
        let hi = self.faces.iter().map(|f| f.0[0]).max().unwrap_or(lo);
        let span = (hi - lo) as usize + 1;
        if span > 4 * self.faces.len() + 64 {
            // Faces spread over far more vertices than there are faces (a piece far from
            // the unpaired faces of an open mesh): sort rather than bucket.
            self.faces.sort_unstable();
            let mut i = 0;
            while i < self.faces.len() {
                let j = i + self.faces[i..]
                    .iter()
                    .take_while(|f| f.0 == self.faces[i].0)
                    .count();
                match j - i {
                    1 => self.pending.push(self.faces[i]),
                    2 => link(&mut self.adj, self.faces[i].1, self.faces[i + 1].1),
                    _ => {}
                }
                i = j;
            }
            return;
        }
        // Bucket starts by smallest vertex.
        self.start.clear();
        self.start.resize(span + 1, 0);
        for (f, _) in &self.faces {
            self.start[(f[0] - lo) as usize + 1] += 1;
        }
        for v in 0..span {
            self.start[v + 1] += self.start[v];
        }
        let n = self.faces.len();
        self.keys.resize(n, 0);
        self.ids.resize(n, 0);
        for (f, id) in &self.faces {
            let slot = &mut self.start[(f[0] - lo) as usize];
            self.keys[*slot as usize] = u64::from(f[1]) << 32 | u64::from(f[2]);
            self.ids[*slot as usize] = *id;
            *slot += 1;
        }
        // `start[v]` is now the end of bucket v.
        let mut begin = 0;
        for v in 0..span {
            let end = self.start[v] as usize;
            let (keys, ids) = (&mut self.keys[begin..end], &self.ids[begin..end]);
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
                        (None, _) => self.pending.push((face(key), ids[i])),
                        _ => {}
                    }
                }
            } else {
                self.bucket.clear();
                self.bucket
                    .extend(keys.iter().copied().zip(ids.iter().copied()));
                self.bucket.sort_unstable();
                for run in self.bucket.chunk_by(|a, b| a.0 == b.0) {
                    match run {
                        [(key, x)] => self.pending.push((face(*key), *x)),
                        [(_, x), (_, y)] => link(&mut self.adj, *x, *y),
                        _ => {}
                    }
                }
            }
            begin = end;
        }
    }

    /// The neighbours of every tet added (faces still unpaired have none).
    pub fn finish(self) -> Vec<[u32; 4]> {
        self.adj
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
    // id << 2 | position: sorting these sorts the ids and carries the positions.
    let mut k = [0, 1, 2, 3].map(|i| u64::from(tet[i]) << 2 | i as u64);
    for (i, j) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
        let (lo, hi) = (k[i].min(k[j]), k[i].max(k[j]));
        (k[i], k[j]) = (lo, hi);
    }
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
        for cut in [1, 7, 50, 199] {
            let mut b = AdjacencyBuilder::new();
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
