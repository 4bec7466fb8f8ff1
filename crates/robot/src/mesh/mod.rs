//! Collision meshes: finding a mesh file from its URI, loading it within limits, and the
//! welded triangle mesh the rasteriser uses, with whether it is closed.
//!
//! Relies on `mesh-loader` (openrr) for STL (binary and ASCII), COLLADA and OBJ. COLLADA
//! units and node transforms are applied as the loader gives them; its `up_axis` is not
//! applied (mesh-loader ignores it), so a Y-up COLLADA file is read as written.

mod load;
mod resolve;

pub use load::load_mesh;
pub use resolve::{Environment, PackageResolver, ProcessEnvironment, VarsEnvironment};

use std::path::PathBuf;

/// Whether a mesh bounds a volume, which decides how its interior is filled.
///
/// A closed mesh is first made consistently oriented where it can be: each edge-connected
/// part is oriented from one of its faces across the edges shared by two faces, then turned
/// outwards (positive volume). Overlapping parts then make a union under the nonzero
/// winding rule, whatever orientation the file gave them. A part nested in another as a
/// cavity is turned outwards too, so the cavity is filled: a superset, the safe side.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Closure {
    /// Every edge is shared by faces of opposite orientations, every part outwards.
    /// Interior: nonzero winding number (overlapping shells are a union).
    Oriented,
    /// Every edge is shared by an even number of faces but the faces cannot be oriented
    /// consistently (a non-orientable or non-manifold surface). Interior: odd crossing
    /// parity, so where two such shells overlap the overlap reads as outside in the fill
    /// (its voxels are still set where a surface crosses them).
    Unoriented,
    /// Some edges bound a single face: the mesh has holes and no inside. Only the voxels
    /// its surface crosses are occupied (`bits`); it adds no volume to `percent`.
    Open,
}

/// A triangle mesh in its geometry frame (URDF scale applied), vertices welded where their
/// coordinates are bitwise equal, degenerate triangles dropped.
#[derive(Clone, Debug)]
pub struct TriMesh {
    /// Vertex positions (m).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as vertex indices, in the file's orientation.
    pub triangles: Vec<[u32; 3]>,
    /// Whether it bounds a volume.
    pub closure: Closure,
    /// Edges bounding a single face (0 unless [`Closure::Open`]).
    pub boundary_edges: usize,
    /// Triangles turned over to orient the mesh consistently and outwards.
    pub flipped_triangles: usize,
}

impl TriMesh {
    /// Builds a mesh from vertices and triangles: welds equal vertices, drops degenerate
    /// triangles and classifies the closure.
    pub fn new(vertices: &[[f64; 3]], triangles: &[[u32; 3]]) -> TriMesh {
        let mut map = std::collections::HashMap::with_capacity(vertices.len());
        let mut remap = Vec::with_capacity(vertices.len());
        let mut welded: Vec<[f64; 3]> = Vec::new();
        for v in vertices {
            // +0.0 and -0.0 weld together.
            let key = v.map(|c| (c + 0.0).to_bits());
            let id = *map.entry(key).or_insert_with(|| {
                welded.push(*v);
                welded.len() as u32 - 1
            });
            remap.push(id);
        }
        let mut tris = Vec::with_capacity(triangles.len());
        for t in triangles {
            let t = t.map(|i| remap[i as usize]);
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                tris.push(t);
            }
        }
        let (mut closure, boundary_edges) = classify(&tris);
        let mut flipped_triangles = 0;
        if closure == Closure::Unoriented || closure == Closure::Oriented {
            if let Some(flips) = orient(&welded, &tris) {
                for (t, &f) in tris.iter_mut().zip(&flips) {
                    if f {
                        t.swap(1, 2);
                        flipped_triangles += 1;
                    }
                }
                closure = classify(&tris).0;
            }
        }
        TriMesh {
            vertices: welded,
            triangles: tris,
            closure,
            boundary_edges,
            flipped_triangles,
        }
    }

    /// The closed box of edges `size` centred on the origin, as 12 outward triangles.
    pub fn cuboid(size: [f64; 3]) -> TriMesh {
        let h = size.map(|s| 0.5 * s);
        let v: Vec<[f64; 3]> = (0..8)
            .map(|i| {
                [
                    if i & 1 == 0 { -h[0] } else { h[0] },
                    if i & 2 == 0 { -h[1] } else { h[1] },
                    if i & 4 == 0 { -h[2] } else { h[2] },
                ]
            })
            .collect();
        let quads = [
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
        ];
        let mut t = Vec::with_capacity(12);
        for q in quads {
            t.push([q[0], q[1], q[2]]);
            t.push([q[0], q[2], q[3]]);
        }
        TriMesh::new(&v, &t)
    }

    /// A closed prism with `sides` sides circumscribing the cylinder of radius `radius` and
    /// length `length` along z: it contains the cylinder and bulges out of it by at most
    /// `radius · (1 / cos(π / sides) − 1)`.
    pub fn circumscribed_prism(radius: f64, length: f64, sides: usize) -> TriMesh {
        let r = radius / (std::f64::consts::PI / sides as f64).cos();
        let hz = 0.5 * length;
        let mut v = Vec::with_capacity(2 * sides + 2);
        for k in 0..sides {
            let a = 2.0 * std::f64::consts::PI * k as f64 / sides as f64;
            let (s, c) = a.sin_cos();
            v.push([r * c, r * s, -hz]);
            v.push([r * c, r * s, hz]);
        }
        v.push([0.0, 0.0, -hz]);
        v.push([0.0, 0.0, hz]);
        let (bottom, top) = (2 * sides as u32, 2 * sides as u32 + 1);
        let mut t = Vec::with_capacity(4 * sides);
        for k in 0..sides as u32 {
            let n = (k + 1) % sides as u32;
            let (b0, t0, b1, t1) = (2 * k, 2 * k + 1, 2 * n, 2 * n + 1);
            t.push([b0, b1, t1]);
            t.push([b0, t1, t0]);
            t.push([bottom, b1, b0]);
            t.push([top, t0, t1]);
        }
        TriMesh::new(&v, &t)
    }
}

/// Which triangles to turn over so that each edge-connected part is consistently oriented
/// and has positive volume; `None` if some part cannot be oriented consistently.
fn orient(vertices: &[[f64; 3]], tris: &[[u32; 3]]) -> Option<Vec<bool>> {
    // Every edge with its triangle, sorted so that the faces of an edge are adjacent.
    let mut edges: Vec<(u32, u32, u32)> = Vec::with_capacity(tris.len() * 3);
    for (ti, t) in tris.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.push((a.min(b), a.max(b), ti as u32));
        }
    }
    edges.sort_unstable();
    // Neighbours across edges shared by exactly two faces (manifold edges).
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); tris.len()];
    let mut i = 0;
    while i < edges.len() {
        let mut j = i;
        while j < edges.len() && edges[j].0 == edges[i].0 && edges[j].1 == edges[i].1 {
            j += 1;
        }
        if j - i == 2 {
            let (s, t) = (edges[i].2, edges[i + 1].2);
            neighbours[s as usize].push(t);
            neighbours[t as usize].push(s);
        }
        i = j;
    }
    // Whether triangle t walks the edge a→b (true) or b→a (false).
    let walks = |t: [u32; 3], a: u32, b: u32| (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b);
    let mut flip = vec![false; tris.len()];
    let mut seen = vec![false; tris.len()];
    let mut stack = Vec::new();
    let mut part = Vec::new();
    for seed in 0..tris.len() {
        if seen[seed] {
            continue;
        }
        seen[seed] = true;
        stack.push(seed);
        part.clear();
        while let Some(s) = stack.pop() {
            part.push(s);
            let ts = oriented(tris[s], flip[s]);
            for &n in &neighbours[s] {
                let n = n as usize;
                // The shared edge, as s walks it.
                let (a, b) = (0..3)
                    .map(|k| (ts[k], ts[(k + 1) % 3]))
                    .find(|&(a, b)| tris[n].contains(&a) && tris[n].contains(&b))?;
                // Consistent neighbours walk it the other way.
                let need = walks(tris[n], a, b);
                if seen[n] {
                    if flip[n] != need {
                        return None;
                    }
                } else {
                    seen[n] = true;
                    flip[n] = need;
                    stack.push(n);
                }
            }
        }
        let volume: f64 = part
            .iter()
            .map(|&t| {
                let [a, b, c] = oriented(tris[t], flip[t]).map(|i| vertices[i as usize]);
                a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
                    + a[2] * (b[0] * c[1] - b[1] * c[0])
            })
            .sum();
        if volume < 0.0 {
            for &t in &part {
                flip[t] = !flip[t];
            }
        }
    }
    Some(flip)
}

fn oriented(t: [u32; 3], flip: bool) -> [u32; 3] {
    if flip {
        [t[0], t[2], t[1]]
    } else {
        t
    }
}

fn classify(tris: &[[u32; 3]]) -> (Closure, usize) {
    // Per undirected edge: how many faces use it, and the balance of its two directions.
    let mut edges: std::collections::HashMap<(u32, u32), (u32, i32)> =
        std::collections::HashMap::with_capacity(tris.len() * 3 / 2);
    for t in tris {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let e = edges.entry((a.min(b), a.max(b))).or_insert((0, 0));
            e.0 += 1;
            e.1 += if a < b { 1 } else { -1 };
        }
    }
    let boundary = edges.values().filter(|e| e.0 % 2 == 1).count();
    if tris.is_empty() || boundary > 0 {
        (Closure::Open, boundary)
    } else if edges.values().all(|e| e.1 == 0) {
        (Closure::Oriented, 0)
    } else {
        (Closure::Unoriented, 0)
    }
}

/// A mesh that could not be found, read or accepted. Each names the URI or the file.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// A URI scheme other than `package://`, `file://` and plain paths.
    #[error("mesh URI `{uri}`: unsupported scheme (package://, file:// and paths are)")]
    UnsupportedUri {
        /// The URI.
        uri: String,
    },
    /// A `package://` URI without a package name or a path in it.
    #[error("mesh URI `{uri}`: expected package://PACKAGE/PATH")]
    MalformedUri {
        /// The URI.
        uri: String,
    },
    /// A relative path in a URDF given as text, with no directory to resolve it against.
    #[error("mesh URI `{uri}` is a relative path and the URDF came without a directory; give the URDF's directory (base_dir) or an absolute or package:// URI")]
    RelativeWithoutBase {
        /// The URI.
        uri: String,
    },
    /// No file found for the URI.
    #[error("mesh URI `{uri}`: no such file; tried {}", tried_list(.tried))]
    NotFound {
        /// The URI.
        uri: String,
        /// Every path or search tried, in order.
        tried: Vec<String>,
    },
    /// The file could not be read.
    #[error("mesh file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        #[source]
        source: std::io::Error,
    },
    /// The file is over `MAX_MESH_FILE_BYTES`.
    #[error("mesh file {path} is {bytes} bytes, over MAX_MESH_FILE_BYTES = {limit}")]
    FileTooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        bytes: u64,
        /// The limit in force.
        limit: u64,
    },
    /// The file holds more triangles than `MAX_MESH_TRIANGLES`.
    #[error("mesh file {path} has {triangles} triangles, over MAX_MESH_TRIANGLES = {limit}")]
    TooManyTriangles {
        /// The file.
        path: PathBuf,
        /// Its triangles.
        triangles: usize,
        /// The limit in force.
        limit: usize,
    },
    /// The robot's meshes together hold more than `MAX_ROBOT_TRIANGLES`.
    #[error("mesh file {path} brings the robot to {total} triangles, over MAX_ROBOT_TRIANGLES = {limit}")]
    RobotTooManyTriangles {
        /// The file that went over.
        path: PathBuf,
        /// Triangles with it.
        total: usize,
        /// The limit in force.
        limit: usize,
    },
    /// The loader refused the file.
    #[error("mesh file {path} cannot be parsed: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What the loader said.
        message: String,
    },
    /// The file parsed but its contents are unusable.
    #[error("mesh file {path}: {why}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong (no triangles, a non-finite vertex, an index out of range).
        why: String,
    },
}

fn tried_list(tried: &[String]) -> String {
    if tried.is_empty() {
        "nothing (no search path applies)".to_owned()
    } else {
        tried.join(", ")
    }
}
