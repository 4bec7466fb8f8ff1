//! Face adjacency of a closed tet mesh: for each tet and each face (face i omits vertex i),
//! the tet on the other side.

use crate::mesh::TetMesh;

/// No neighbour (the mesh is open there).
pub const NO_NEIGHBOUR: u32 = u32::MAX;

/// Neighbours across each face. Faces shared by more than two tets (never in a closed
/// 2-manifold boundary) are left unlinked, as are faces naming a vertex that does not exist.
///
/// Faces are bucketed by their smallest vertex (a counting sort, linear in the mesh), and
/// within each bucket, a few dozen faces around one vertex, equal faces are paired by a
/// scan (by a sort on the other two vertices in the rare larger bucket).
pub fn face_adjacency(mesh: &TetMesh) -> Vec<[u32; 4]> {
    let nv = mesh.vertices.len();
    let mut adj = vec![[NO_NEIGHBOUR; 4]; mesh.tets.len()];
    // Bucket starts by smallest vertex.
    let mut start = vec![0usize; nv + 1];
    for tet in &mesh.tets {
        for (f, _) in sorted_faces(*tet) {
            if (f[2] as usize) < nv {
                start[f[0] as usize + 1] += 1;
            }
        }
    }
    for v in 0..nv {
        start[v + 1] += start[v];
    }
    // (other two vertices, tet << 2 | face) per bucket slot.
    let mut keys = vec![0u64; start[nv]];
    let mut ids = vec![0u32; start[nv]];
    let mut fill = start.clone();
    for (t, tet) in mesh.tets.iter().enumerate() {
        for (f, i) in sorted_faces(*tet) {
            if (f[2] as usize) < nv {
                let slot = &mut fill[f[0] as usize];
                keys[*slot] = u64::from(f[1]) << 32 | u64::from(f[2]);
                ids[*slot] = (t as u32) << 2 | i;
                *slot += 1;
            }
        }
    }
    let mut link = |x: u32, y: u32| {
        adj[(x >> 2) as usize][(x & 3) as usize] = y >> 2;
        adj[(y >> 2) as usize][(y & 3) as usize] = x >> 2;
    };
    let mut bucket: Vec<(u64, u32)> = Vec::new();
    for v in 0..nv {
        let (lo, hi) = (start[v], start[v + 1]);
        let (keys, ids) = (&mut keys[lo..hi], &ids[lo..hi]);
        if keys.len() <= SCAN_BUCKET {
            // Pair by scanning: each face against the later ones (a few hundred compares
            // in L1 beat a general sort at this size); a key seen is cleared to `SEEN`.
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
                if let (Some(j), 2) = (partner, count) {
                    link(ids[i], ids[j]);
                }
            }
            continue;
        }
        bucket.clear();
        bucket.extend(keys.iter().copied().zip(ids.iter().copied()));
        bucket.sort_unstable();
        for run in bucket.chunk_by(|a, b| a.0 == b.0) {
            if let [(_, x), (_, y)] = run {
                link(*x, *y);
            }
        }
    }
    adj
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
