//! A robot ready to rasterise: its URDF, kinematics and every link's collision geometry
//! loaded and prepared once; and bodies, the sets of links rasterised into one frame.

use crate::kinematics::Kinematics;
use crate::limits::Limits;
use crate::mesh::{
    load_mesh, Closure, Environment, MeshError, PackageResolver, ProcessEnvironment, TriMesh,
};
use crate::shape::{Shape, ShapeKind, CYLINDER_PRISM_SIDES};
use crate::urdf::{Geometry, UrdfError, UrdfModel};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A robot that could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// The URDF was refused.
    #[error(transparent)]
    Urdf(#[from] UrdfError),
    /// A collision mesh of a link could not be found, read or accepted.
    #[error("link `{link}`: {source}")]
    Mesh {
        /// The link.
        link: String,
        /// What went wrong.
        #[source]
        source: MeshError,
    },
    /// A body names a link the robot does not have.
    #[error("body names link `{0}`, which is not a link of the URDF")]
    UnknownLink(String),
}

/// How to load a robot: where packages are, which directory relative mesh paths are
/// relative to, and the limits.
pub struct LoadOptions {
    package_path: Vec<PathBuf>,
    base_dir: Option<PathBuf>,
    env: Box<dyn Environment>,
    limits: Limits,
}

impl std::fmt::Debug for LoadOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadOptions")
            .field("package_path", &self.package_path)
            .field("base_dir", &self.base_dir)
            .field("limits", &self.limits)
            .finish_non_exhaustive()
    }
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            package_path: Vec::new(),
            base_dir: None,
            env: Box::new(ProcessEnvironment),
            limits: Limits::default(),
        }
    }
}

impl LoadOptions {
    /// Defaults: no package path, no base directory, the process's environment, the
    /// default limits.
    pub fn new() -> Self {
        Self::default()
    }

    /// Directories searched first for `package://` URIs: each either a package directory
    /// or a directory whose child `PKG` is the package (see [`crate::mesh`]).
    pub fn package_path(mut self, dirs: Vec<PathBuf>) -> Self {
        self.package_path = dirs;
        self
    }

    /// The directory plain relative mesh paths are relative to (set by
    /// [`Robot::from_urdf_file`] to the file's directory).
    pub fn base_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.base_dir = Some(dir.into());
        self
    }

    /// Where `AMENT_PREFIX_PATH` and `ROS_PACKAGE_PATH` are read from.
    pub fn environment(mut self, env: Box<dyn Environment>) -> Self {
        self.env = env;
        self
    }

    /// The limits in force.
    pub fn limits(mut self, limits: Limits) -> Self {
        self.limits = limits;
        self
    }
}

/// One mesh file as loaded, for the report.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedMesh {
    /// The URI as written.
    pub uri: String,
    /// The file it resolved to.
    pub path: PathBuf,
    /// The scale applied.
    pub scale: [f64; 3],
    /// Triangles kept.
    pub triangles: usize,
    /// Whether it bounds a volume.
    pub closure: Closure,
    /// Edges bounding a single face (open meshes).
    pub boundary_edges: usize,
    /// Triangles turned over to orient the mesh outwards.
    pub flipped_triangles: usize,
}

/// What loading found, for the caller to log: every mesh, and those that are open.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadReport {
    /// Each distinct (file, scale) loaded.
    pub meshes: Vec<LoadedMesh>,
    /// Triangles of all of them.
    pub triangles: usize,
}

impl LoadReport {
    /// The meshes that are open (rasterised as surfaces only).
    pub fn open_meshes(&self) -> impl Iterator<Item = &LoadedMesh> {
        self.meshes.iter().filter(|m| m.closure == Closure::Open)
    }
}

/// A robot: kinematics and every link's prepared collision geometry.
#[derive(Debug)]
pub struct Robot {
    kinematics: Kinematics,
    shapes: Vec<Vec<Shape>>,
    report: LoadReport,
}

/// A set of links rasterised together into one frame (a whole arm, or a gripper alone).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Body {
    links: Vec<usize>,
}

impl Body {
    /// The links' indices (in [`UrdfModel::links`]).
    pub fn links(&self) -> &[usize] {
        &self.links
    }
}

impl Robot {
    /// Loads a robot from the URDF text (`/robot_description`), resolving meshes with
    /// `options`.
    ///
    /// # Errors
    /// [`RobotError::Urdf`] for a refused URDF, [`RobotError::Mesh`] naming the link for a
    /// mesh that cannot be found, read or accepted.
    pub fn from_urdf_str(text: &str, options: &LoadOptions) -> Result<Robot, RobotError> {
        let model = UrdfModel::parse_with_limits(text, &options.limits)?;
        Self::from_model(model, options)
    }

    /// Loads a robot from a URDF file; relative mesh paths are relative to its directory
    /// unless `options` gives another.
    ///
    /// # Errors
    /// As [`from_urdf_str`](Self::from_urdf_str), and [`UrdfError::Io`].
    pub fn from_urdf_file(path: &Path, options: LoadOptions) -> Result<Robot, RobotError> {
        let model = UrdfModel::from_file(path, &options.limits)?;
        let options = if options.base_dir.is_none() {
            match path.parent() {
                Some(dir) => options.base_dir(dir),
                None => options,
            }
        } else {
            options
        };
        Self::from_model(model, &options)
    }

    /// Loads the collision geometry of a parsed model.
    ///
    /// # Errors
    /// [`RobotError::Mesh`].
    pub fn from_model(model: UrdfModel, options: &LoadOptions) -> Result<Robot, RobotError> {
        let mut resolver = PackageResolver::new(options.package_path.clone(), options.env.as_ref());
        let mut cache: HashMap<(PathBuf, [u64; 3]), Arc<TriMesh>> = HashMap::new();
        let mut report = LoadReport::default();
        let mut shapes = Vec::with_capacity(model.links.len());
        for link in &model.links {
            let mut list = Vec::with_capacity(link.collisions.len());
            for c in &link.collisions {
                let kind = match &c.geometry {
                    Geometry::Box { size } => ShapeKind::Box {
                        half: size.map(|s| 0.5 * s),
                        mesh: Arc::new(TriMesh::cuboid(*size)),
                    },
                    Geometry::Sphere { radius } => ShapeKind::Sphere { radius: *radius },
                    Geometry::Cylinder { radius, length } => ShapeKind::Cylinder {
                        radius: *radius,
                        half_length: 0.5 * length,
                        prism: Arc::new(TriMesh::circumscribed_prism(
                            *radius,
                            *length,
                            CYLINDER_PRISM_SIDES,
                        )),
                    },
                    Geometry::Mesh { filename, scale } => {
                        let mesh_err = |source| RobotError::Mesh {
                            link: link.name.clone(),
                            source,
                        };
                        let path = resolver
                            .resolve(filename, options.base_dir.as_deref())
                            .map_err(mesh_err)?;
                        let key = (path.clone(), scale.map(f64::to_bits));
                        let mesh = match cache.get(&key) {
                            Some(m) => m.clone(),
                            None => {
                                let m =
                                    load_mesh(&path, *scale, &options.limits).map_err(mesh_err)?;
                                let total = report.triangles + m.triangles.len();
                                if total > options.limits.robot_triangles {
                                    return Err(mesh_err(MeshError::RobotTooManyTriangles {
                                        path,
                                        total,
                                        limit: options.limits.robot_triangles,
                                    }));
                                }
                                report.triangles = total;
                                report.meshes.push(LoadedMesh {
                                    uri: filename.clone(),
                                    path: path.clone(),
                                    scale: *scale,
                                    triangles: m.triangles.len(),
                                    closure: m.closure,
                                    boundary_edges: m.boundary_edges,
                                    flipped_triangles: m.flipped_triangles,
                                });
                                let m = Arc::new(m);
                                cache.insert(key, m.clone());
                                m
                            }
                        };
                        ShapeKind::Mesh(mesh)
                    }
                };
                list.push(Shape {
                    origin: c.origin,
                    kind,
                });
            }
            shapes.push(list);
        }
        Ok(Robot {
            kinematics: Kinematics::new(model),
            shapes,
            report,
        })
    }

    /// The kinematics (and through it the model).
    pub fn kinematics(&self) -> &Kinematics {
        &self.kinematics
    }

    /// The parsed URDF.
    pub fn model(&self) -> &UrdfModel {
        self.kinematics.model()
    }

    /// What loading found.
    pub fn load_report(&self) -> &LoadReport {
        &self.report
    }

    /// The prepared collision geometry of link `link`.
    ///
    /// # Panics
    /// If `link` is out of range.
    pub fn shapes(&self, link: usize) -> &[Shape] {
        &self.shapes[link]
    }

    /// A body of the named links.
    ///
    /// # Errors
    /// [`RobotError::UnknownLink`] for a name that is not a link.
    pub fn body<S: AsRef<str>>(&self, links: &[S]) -> Result<Body, RobotError> {
        let mut out = Vec::with_capacity(links.len());
        for name in links {
            let name = name.as_ref();
            let i = self
                .model()
                .link_index(name)
                .ok_or_else(|| RobotError::UnknownLink(name.to_owned()))?;
            if !out.contains(&i) {
                out.push(i);
            }
        }
        Ok(Body { links: out })
    }

    /// A body of every link.
    pub fn whole_body(&self) -> Body {
        Body {
            links: (0..self.model().links.len()).collect(),
        }
    }
}
