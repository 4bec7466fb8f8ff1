//! Face adjacency of a closed tet mesh: for each tet and each face (face i omits vertex i),
//! the tet on the other side.

use crate::mesh::validate::{canonical_triangle, tet_faces};
use crate::mesh::TetMesh;

/// No neighbour (the mesh is open there).
pub const NO_NEIGHBOUR: u32 = u32::MAX;

/// Neighbours across each face. Faces shared by more than two tets (never in a closed
/// 2-manifold boundary) are left unlinked, as are faces naming a vertex that does not exist.
///
/// Faces are bucketed by their smallest vertex (a counting sort, linear in the mesh), and
/// each bucket, a handful of faces around one vertex, is sorted on the other two vertices.
pub fn face_adjacency(mesh: &TetMesh) -> Vec<[u32; 4]> {
    let nv = mesh.vertices.len();
    let mut adj = vec![[NO_NEIGHBOUR; 4]; mesh.tets.len()];
    // Bucket starts by smallest vertex.
    let mut start = vec![0usize; nv + 1];
    let faces = |tet: [u32; 4]| tet_faces(tet).map(|(f, _)| canonical_triangle(f).0);
    for tet in &mesh.tets {
        for f in faces(*tet) {
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
        for (i, f) in faces(*tet).into_iter().enumerate() {
            if (f[2] as usize) < nv {
                let slot = &mut fill[f[0] as usize];
                keys[*slot] = u64::from(f[1]) << 32 | u64::from(f[2]);
                ids[*slot] = (t as u32) << 2 | i as u32;
                *slot += 1;
            }
        }
    }
    let mut bucket: Vec<(u64, u32)> = Vec::new();
    for v in 0..nv {
        let (lo, hi) = (start[v], start[v + 1]);
        bucket.clear();
        bucket.extend(
            keys[lo..hi]
                .iter()
                .copied()
                .zip(ids[lo..hi].iter().copied()),
        );
        bucket.sort_unstable();
        for run in bucket.chunk_by(|a, b| a.0 == b.0) {
            if let [(_, x), (_, y)] = run {
                adj[(x >> 2) as usize][(x & 3) as usize] = y >> 2;
                adj[(y >> 2) as usize][(y & 3) as usize] = x >> 2;
            }
        }
    }
    adj
}

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
