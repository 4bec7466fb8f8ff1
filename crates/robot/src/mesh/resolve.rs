//! From a mesh URI to a file: `package://PKG/PATH`, `file:///ABS` and plain paths.
//!
//! `package://PKG/PATH` is searched, in order, and the first existing file wins:
//! 1. each directory of the caller's `package_path`: the directory itself if it is the
//!    package (its `package.xml` names PKG, or it is called PKG), then its child `PKG`;
//! 2. each prefix of `AMENT_PREFIX_PATH` (`:`-separated): `PREFIX/share/PKG` (ROS 2);
//! 3. each root of `ROS_PACKAGE_PATH` (`:`-separated): the first directory, breadth first
//!    to `MAX_PACKAGE_SEARCH_DEPTH` levels and at most `MAX_PACKAGE_SEARCH_DIRS`
//!    directories, holding a `package.xml` whose `<name>` is PKG (as rospack, a package's
//!    inside is not searched further).
//!
//! The environment is read through [`Environment`] so tests can give their own.

use super::MeshError;
use crate::limits::{MAX_PACKAGE_SEARCH_DEPTH, MAX_PACKAGE_SEARCH_DIRS};
use std::collections::{HashMap, VecDeque};
use std::ffi::OsString;
use std::path::{Path, PathBuf};

/// Where environment variables come from.
pub trait Environment {
    /// The value of variable `name`, if set.
    fn var(&self, name: &str) -> Option<OsString>;
}

/// The process's environment.
#[derive(Clone, Copy, Debug, Default)]
pub struct ProcessEnvironment;

impl Environment for ProcessEnvironment {
    fn var(&self, name: &str) -> Option<OsString> {
        std::env::var_os(name)
    }
}

/// A fixed set of variables (for tests, or to resolve without the process's environment).
#[derive(Clone, Debug, Default)]
pub struct VarsEnvironment(pub Vec<(String, OsString)>);

impl Environment for VarsEnvironment {
    fn var(&self, name: &str) -> Option<OsString> {
        self.0
            .iter()
            .find(|(k, _)| k == name)
            .map(|(_, v)| v.clone())
    }
}

/// Resolves mesh URIs to files; remembers where each package was found.
#[derive(Clone, Debug)]
pub struct PackageResolver {
    package_path: Vec<PathBuf>,
    ament_prefixes: Vec<PathBuf>,
    ros_roots: Vec<PathBuf>,
    found: HashMap<String, Option<PathBuf>>,
}

fn split_paths(value: Option<OsString>) -> Vec<PathBuf> {
    value
        .map(|v| {
            std::env::split_paths(&v)
                .filter(|p| !p.as_os_str().is_empty())
                .collect()
        })
        .unwrap_or_default()
}

/// The `<name>` of a `package.xml`, if the file is there and readable (at most 1 MiB).
fn package_name(dir: &Path) -> Option<String> {
    let path = dir.join("package.xml");
    let meta = std::fs::metadata(&path).ok()?;
    if !meta.is_file() || meta.len() > 1 << 20 {
        return None;
    }
    let text = std::fs::read_to_string(&path).ok()?;
    let doc = roxmltree::Document::parse(&text).ok()?;
    let name = doc
        .root_element()
        .children()
        .find(|n| n.has_tag_name("name"))?
        .text()?
        .trim()
        .to_owned();
    Some(name)
}

impl PackageResolver {
    /// A resolver searching `package_path` first, then the `AMENT_PREFIX_PATH` and
    /// `ROS_PACKAGE_PATH` read from `env` now.
    pub fn new(package_path: Vec<PathBuf>, env: &dyn Environment) -> Self {
        PackageResolver {
            package_path,
            ament_prefixes: split_paths(env.var("AMENT_PREFIX_PATH")),
            ros_roots: split_paths(env.var("ROS_PACKAGE_PATH")),
            found: HashMap::new(),
        }
    }

    /// The file a mesh URI names. `base_dir` is the URDF file's directory, for relative
    /// paths.
    ///
    /// # Errors
    /// [`MeshError::NotFound`] with every path tried, [`MeshError::UnsupportedUri`],
    /// [`MeshError::MalformedUri`], [`MeshError::RelativeWithoutBase`].
    pub fn resolve(&mut self, uri: &str, base_dir: Option<&Path>) -> Result<PathBuf, MeshError> {
        if let Some(rest) = uri.strip_prefix("package://") {
            return self.resolve_package(uri, rest);
        }
        let path = if let Some(rest) = uri.strip_prefix("file://") {
            PathBuf::from(rest)
        } else if uri.contains("://") {
            return Err(MeshError::UnsupportedUri { uri: uri.into() });
        } else {
            PathBuf::from(uri)
        };
        let path = if path.is_absolute() {
            path
        } else {
            match base_dir {
                Some(b) => b.join(path),
                None => return Err(MeshError::RelativeWithoutBase { uri: uri.into() }),
            }
        };
        if path.is_file() {
            Ok(path)
        } else {
            Err(MeshError::NotFound {
                uri: uri.into(),
                tried: vec![path.display().to_string()],
            })
        }
    }

    fn resolve_package(&mut self, uri: &str, rest: &str) -> Result<PathBuf, MeshError> {
        let (package, relative) = rest
            .split_once('/')
            .filter(|(p, r)| !p.is_empty() && !r.is_empty())
            .ok_or_else(|| MeshError::MalformedUri { uri: uri.into() })?;
        let mut tried = Vec::new();
        // 1. The caller's package_path.
        for dir in &self.package_path {
            let is_package = dir.file_name().is_some_and(|n| n == package)
                || package_name(dir).as_deref() == Some(package);
            let mut candidates = Vec::with_capacity(2);
            if is_package {
                candidates.push(dir.join(relative));
            }
            candidates.push(dir.join(package).join(relative));
            for c in candidates {
                if c.is_file() {
                    return Ok(c);
                }
                tried.push(c.display().to_string());
            }
        }
        // 2. AMENT_PREFIX_PATH.
        for prefix in &self.ament_prefixes {
            let c = prefix.join("share").join(package).join(relative);
            if c.is_file() {
                return Ok(c);
            }
            tried.push(c.display().to_string());
        }
        // 3. ROS_PACKAGE_PATH, searched once per package.
        if !self.ros_roots.is_empty() {
            if !self.found.contains_key(package) {
                let dir = self.search_ros_roots(package);
                self.found.insert(package.to_owned(), dir);
            }
            match &self.found[package] {
                Some(dir) => {
                    let c = dir.join(relative);
                    if c.is_file() {
                        return Ok(c);
                    }
                    tried.push(c.display().to_string());
                }
                None => {
                    for root in &self.ros_roots {
                        tried.push(format!(
                            "a package.xml naming `{package}` under {} (ROS_PACKAGE_PATH, {MAX_PACKAGE_SEARCH_DEPTH} levels deep)",
                            root.display()
                        ));
                    }
                }
            }
        }
        Err(MeshError::NotFound {
            uri: uri.into(),
            tried,
        })
    }

    fn search_ros_roots(&self, package: &str) -> Option<PathBuf> {
        let mut visited = 0usize;
        for root in &self.ros_roots {
            let mut queue = VecDeque::from([(root.clone(), 0usize)]);
            while let Some((dir, depth)) = queue.pop_front() {
                visited += 1;
                if visited > MAX_PACKAGE_SEARCH_DIRS {
                    return None;
                }
                if dir.join("package.xml").is_file() {
                    if package_name(&dir).as_deref() == Some(package) {
                        return Some(dir);
                    }
                    continue; // a package's inside is not searched
                }
                if depth == MAX_PACKAGE_SEARCH_DEPTH {
                    continue;
                }
                let Ok(entries) = std::fs::read_dir(&dir) else {
                    continue;
                };
                let mut subdirs: Vec<PathBuf> = entries
                    .filter_map(Result::ok)
                    .filter(|e| e.file_type().is_ok_and(|t| t.is_dir()))
                    .map(|e| e.path())
                    .collect();
                subdirs.sort(); // deterministic whatever the file system's order
                queue.extend(subdirs.into_iter().map(|d| (d, depth + 1)));
            }
        }
        None
    }
}
