//! Face adjacency of a closed tet mesh: for each tet and each face (face i omits vertex i),
//! the tet on the other side.

use crate::mesh::validate::{canonical_triangle, tet_faces};
use crate::mesh::TetMesh;

/// No neighbour (the mesh is open there).
pub const NO_NEIGHBOUR: u32 = u32::MAX;

/// Neighbours across each face. Faces shared by more than two tets (never in a closed
/// 2-manifold boundary) are left unlinked.
pub fn face_adjacency(mesh: &TetMesh) -> Vec<[u32; 4]> {
    let mut faces: Vec<([u32; 3], u32)> = Vec::with_capacity(mesh.tets.len() * 4);
    for (t, tet) in mesh.tets.iter().enumerate() {
        for (i, (f, _)) in tet_faces(*tet).into_iter().enumerate() {
            faces.push((canonical_triangle(f).0, (t as u32) << 2 | i as u32));
        }
    }
    faces.sort_unstable_by_key(|f| f.0);
    let mut adj = vec![[NO_NEIGHBOUR; 4]; mesh.tets.len()];
    for run in faces.chunk_by(|a, b| a.0 == b.0) {
        if let [(_, x), (_, y)] = run {
            adj[(x >> 2) as usize][(x & 3) as usize] = y >> 2;
            adj[(y >> 2) as usize][(y & 3) as usize] = x >> 2;
        }
    }
    adj
}
