//! Limits on what a robot description may make the crate allocate.
//!
//! Each is refused by its name and value before the memory it bounds is allocated (a mesh
//! file's size is checked from its metadata and again while it is read; a binary STL's
//! triangle count from its header) or, where the count is only known after parsing (ASCII
//! STL, COLLADA, OBJ), right after the loader returns and before anything is built from it:
//! the file's byte limit bounds what the loader allocates meanwhile.

/// Bytes of one URDF text (`MAX_URDF_BYTES`).
pub const MAX_URDF_BYTES: usize = 16 << 20;
/// XML nodes of one URDF document (`MAX_URDF_NODES`).
pub const MAX_URDF_NODES: u32 = 1 << 20;
/// Links of one robot (`MAX_LINKS`).
pub const MAX_LINKS: usize = 4096;
/// `<collision>` elements of one robot (`MAX_COLLISIONS`).
pub const MAX_COLLISIONS: usize = 16384;
/// Bytes of one mesh file (`MAX_MESH_FILE_BYTES`).
pub const MAX_MESH_FILE_BYTES: u64 = 64 << 20;
/// Triangles of one mesh file (`MAX_MESH_TRIANGLES`).
pub const MAX_MESH_TRIANGLES: usize = 1 << 21;
/// Triangles of all collision meshes of one robot, counted once per mesh file and scale
/// (`MAX_ROBOT_TRIANGLES`).
pub const MAX_ROBOT_TRIANGLES: usize = 1 << 22;
/// Directory levels searched below each `ROS_PACKAGE_PATH` root (`MAX_PACKAGE_SEARCH_DEPTH`).
pub const MAX_PACKAGE_SEARCH_DEPTH: usize = 6;
/// Directories visited in one `ROS_PACKAGE_PATH` search (`MAX_PACKAGE_SEARCH_DIRS`).
pub const MAX_PACKAGE_SEARCH_DIRS: usize = 20_000;
/// Voxels of one lattice (`MAX_VOXELS`), as the mesher's `max_voxels`.
pub const MAX_VOXELS: u64 = 1 << 30;
/// Points of one joint trajectory (`MAX_TRAJECTORY_POINTS`).
pub const MAX_TRAJECTORY_POINTS: usize = 1 << 20;

/// The limits in force for one load. Defaults are the constants of this module; a caller
/// may lower them (tests do, to exercise the refusals without large files).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// See [`MAX_URDF_BYTES`].
    pub urdf_bytes: usize,
    /// See [`MAX_LINKS`].
    pub links: usize,
    /// See [`MAX_COLLISIONS`].
    pub collisions: usize,
    /// See [`MAX_MESH_FILE_BYTES`].
    pub mesh_file_bytes: u64,
    /// See [`MAX_MESH_TRIANGLES`].
    pub mesh_triangles: usize,
    /// See [`MAX_ROBOT_TRIANGLES`].
    pub robot_triangles: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            urdf_bytes: MAX_URDF_BYTES,
            links: MAX_LINKS,
            collisions: MAX_COLLISIONS,
            mesh_file_bytes: MAX_MESH_FILE_BYTES,
            mesh_triangles: MAX_MESH_TRIANGLES,
            robot_triangles: MAX_ROBOT_TRIANGLES,
        }
    }
}
