//! Reading one mesh file within the limits, through mesh-loader, into a [`TriMesh`].

use super::{MeshError, TriMesh};
use crate::limits::Limits;
use std::io::Read;
use std::path::Path;

/// mesh-loader reads an OBJ's material library through this: we never need materials, and
/// an unbounded read of another file is what the limits are there to prevent.
fn no_material_files(path: &Path) -> std::io::Result<Vec<u8>> {
    Err(std::io::Error::new(
        std::io::ErrorKind::Unsupported,
        format!("{} not read: materials are not needed", path.display()),
    ))
}

/// Loads the mesh file at `path` and scales it by `scale` (about its origin, per axis).
///
/// `limits.mesh_file_bytes` is checked from the metadata and again while reading;
/// `limits.mesh_triangles` from a binary STL's header before parsing, otherwise right after
/// parsing (the byte limit bounds what the parser allocated meanwhile).
///
/// # Errors
/// [`MeshError::Io`], [`MeshError::FileTooLarge`], [`MeshError::TooManyTriangles`],
/// [`MeshError::Parse`], [`MeshError::Invalid`] (no triangles, a non-finite vertex, an index
/// out of range).
pub fn load_mesh(path: &Path, scale: [f64; 3], limits: &Limits) -> Result<TriMesh, MeshError> {
    let io = |source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    let too_large = |bytes| MeshError::FileTooLarge {
        path: path.to_path_buf(),
        bytes,
        limit: limits.mesh_file_bytes,
    };
    if len > limits.mesh_file_bytes {
        return Err(too_large(len));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(limits.mesh_file_bytes + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > limits.mesh_file_bytes {
        return Err(too_large(bytes.len() as u64));
    }
    // A binary STL says its triangle count at bytes 80..84 and is exactly 84 + 50·n bytes.
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        if 84 + 50 * n == bytes.len() as u64 && n as usize > limits.mesh_triangles {
            return Err(MeshError::TooManyTriangles {
                path: path.to_path_buf(),
                triangles: n as usize,
                limit: limits.mesh_triangles,
            });
        }
    }
    let loader = mesh_loader::Loader::with_custom_reader(no_material_files);
    let scene = loader
        .load_from_slice(&bytes, path)
        .map_err(|e| MeshError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    drop(bytes);
    let triangles: usize = scene.meshes.iter().map(|m| m.faces.len()).sum();
    if triangles > limits.mesh_triangles {
        return Err(MeshError::TooManyTriangles {
            path: path.to_path_buf(),
            triangles,
            limit: limits.mesh_triangles,
        });
    }
    let invalid = |why: String| MeshError::Invalid {
        path: path.to_path_buf(),
        why,
    };
    let mut vertices = Vec::new();
    let mut faces = Vec::with_capacity(triangles);
    for m in &scene.meshes {
        let base = vertices.len() as u32;
        for v in &m.vertices {
            if !v.iter().all(|c| c.is_finite()) {
                return Err(invalid(format!("vertex {v:?} is not finite")));
            }
            vertices.push([
                f64::from(v[0]) * scale[0],
                f64::from(v[1]) * scale[1],
                f64::from(v[2]) * scale[2],
            ]);
        }
        for f in &m.faces {
            if f.iter().any(|&i| i as usize >= m.vertices.len()) {
                return Err(invalid(format!(
                    "a face {f:?} indexes past its {} vertices",
                    m.vertices.len()
                )));
            }
            faces.push(f.map(|i| i + base));
        }
    }
    let mesh = TriMesh::new(&vertices, &faces);
    if mesh.triangles.is_empty() {
        return Err(invalid("no triangle of non-zero size".into()));
    }
    Ok(mesh)
}
