//! Launch configs: which nodes run, with which parameters and remappings.
//!
//! The file is a subset of the ROS 2 launch YAML format, so it reads as a ROS user expects:
//!
//! ```yaml
//! launch:
//! - node:
//!     pkg: chronotope
//!     exec: mesher            # mesher | checker | carving | recorder
//!     name: mesher            # default: the exec name
//!     namespace: /            # default: /
//!     param:
//!     - {name: bodies, value: [/spindle/occupancy, /table/occupancy]}
//!     - {name: slice_markers, value: true}
//!     remap:
//!     - {from: ~/mesh_slabs, to: /cell/mesh_slabs}
//! ```
//!
//! Parameters are typed the ROS way (bool, integer, double, string, and arrays of each); each
//! node declares the parameters it takes, and an undeclared or mistyped one is an error that
//! names the node, the parameter and what was expected (a typo never passes silently).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use super::names::{node_fqn, resolve_topic, NameError};

/// A parameter value.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    /// `true` / `false`.
    Bool(bool),
    /// An integer.
    Integer(i64),
    /// A floating-point number.
    Double(f64),
    /// A string.
    String(String),
    /// A list of booleans.
    BoolArray(Vec<bool>),
    /// A list of integers.
    IntegerArray(Vec<i64>),
    /// A list of numbers.
    DoubleArray(Vec<f64>),
    /// A list of strings.
    StringArray(Vec<String>),
}

impl ParamValue {
    fn kind(&self) -> &'static str {
        match self {
            Self::Bool(_) => "bool",
            Self::Integer(_) => "integer",
            Self::Double(_) => "double",
            Self::String(_) => "string",
            Self::BoolArray(_) => "bool array",
            Self::IntegerArray(_) => "integer array",
            Self::DoubleArray(_) => "double array",
            Self::StringArray(_) => "string array",
        }
    }

    /// A YAML value as a parameter value (`None` for a mixed list, a map or null).
    pub fn from_yaml(v: &serde_yaml_ng::Value) -> Option<Self> {
        use serde_yaml_ng::Value as Y;
        Some(match v {
            Y::Bool(b) => Self::Bool(*b),
            Y::Number(n) if n.is_i64() => Self::Integer(n.as_i64()?),
            Y::Number(n) => Self::Double(n.as_f64()?),
            Y::String(s) => Self::String(s.clone()),
            Y::Sequence(items) if items.is_empty() => Self::StringArray(Vec::new()),
            Y::Sequence(items) => match &items[0] {
                Y::Bool(_) => Self::BoolArray(items.iter().map(Y::as_bool).collect::<Option<_>>()?),
                Y::String(_) => Self::StringArray(
                    items
                        .iter()
                        .map(|i| i.as_str().map(str::to_owned))
                        .collect::<Option<_>>()?,
                ),
                Y::Number(_) if items.iter().all(|i| i.as_i64().is_some()) => {
                    Self::IntegerArray(items.iter().map(Y::as_i64).collect::<Option<_>>()?)
                }
                Y::Number(_) => {
                    Self::DoubleArray(items.iter().map(Y::as_f64).collect::<Option<_>>()?)
                }
                _ => return None,
            },
            _ => return None,
        })
    }
}

/// The node kinds the suite has.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum NodeKind {
    /// Occupancy frames to 4D mesh pieces.
    Mesher,
    /// Mesh pieces to labels, report, suggestions and markers.
    Checker,
    /// Tool poses to carved workpiece and force.
    Carving,
    /// Which published topics a replay writes to its output bag.
    Recorder,
}

impl NodeKind {
    /// The `exec` name.
    pub fn exec(self) -> &'static str {
        match self {
            Self::Mesher => "mesher",
            Self::Checker => "checker",
            Self::Carving => "carving",
            Self::Recorder => "recorder",
        }
    }
}

/// One node of a launch config.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeSpec {
    /// Its kind.
    pub kind: NodeKind,
    /// Fully qualified name.
    pub fqn: String,
    /// Parameters as given.
    pub params: BTreeMap<String, ParamValue>,
    /// Topic remappings, resolved: from -> to.
    pub remaps: BTreeMap<String, String>,
}

/// A whole launch config.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LaunchConfig {
    /// Where it was read from, if from a file.
    pub path: Option<PathBuf>,
    /// Its nodes, in file order.
    pub nodes: Vec<NodeSpec>,
}

/// What is wrong with a launch config.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The YAML does not parse or has the wrong shape.
    #[error("{where_}: {reason}")]
    Format {
        /// File (and entry).
        where_: String,
        /// What is wrong.
        reason: String,
    },
    /// A malformed name.
    #[error("{where_}: {source}")]
    Name {
        /// File and node.
        where_: String,
        /// The name problem.
        source: NameError,
    },
    /// A parameter is undeclared, mistyped or out of range.
    #[error("{node}: parameter {param}: {reason}")]
    Param {
        /// Node name.
        node: String,
        /// Parameter name.
        param: String,
        /// What is wrong.
        reason: String,
    },
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct FileYaml {
    launch: Vec<serde_yaml_ng::Value>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct NodeYaml {
    pkg: String,
    exec: String,
    name: Option<String>,
    namespace: Option<String>,
    #[serde(default)]
    param: Vec<ParamYaml>,
    #[serde(default)]
    remap: Vec<RemapYaml>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ParamYaml {
    name: String,
    value: serde_yaml_ng::Value,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RemapYaml {
    from: String,
    to: String,
}

/// Largest launch file read (bytes).
const MAX_FILE_BYTES: u64 = 1 << 20;

impl LaunchConfig {
    /// Reads a launch config file.
    ///
    /// # Errors
    /// The file cannot be read or is not a valid config.
    pub fn read(path: &Path) -> Result<Self, LaunchError> {
        let io = |source| LaunchError::Io {
            path: path.to_path_buf(),
            source,
        };
        let len = std::fs::metadata(path).map_err(io)?.len();
        if len > MAX_FILE_BYTES {
            return Err(LaunchError::Format {
                where_: path.display().to_string(),
                reason: format!("{len} bytes: a launch config is at most {MAX_FILE_BYTES}"),
            });
        }
        let text = std::fs::read_to_string(path).map_err(io)?;
        let mut c = Self::parse(&text, &path.display().to_string())?;
        c.path = Some(path.to_path_buf());
        Ok(c)
    }

    /// Parses launch config text (`origin` names it in errors).
    ///
    /// # Errors
    /// Not a valid config.
    pub fn parse(text: &str, origin: &str) -> Result<Self, LaunchError> {
        let fmt = |where_: String, reason: String| LaunchError::Format { where_, reason };
        let file: FileYaml =
            serde_yaml_ng::from_str(text).map_err(|e| fmt(origin.to_owned(), e.to_string()))?;
        let mut nodes = Vec::new();
        let mut seen = BTreeSet::new();
        for (i, entry) in file.launch.into_iter().enumerate() {
            let where_ = format!("{origin}: launch entry {}", i + 1);
            let serde_yaml_ng::Value::Mapping(m) = entry else {
                return Err(fmt(where_, "expected a mapping like `node: {...}`".into()));
            };
            let (key, value) = match m.into_iter().collect::<Vec<_>>().as_slice() {
                [(k, v)] => (k.as_str().unwrap_or_default().to_owned(), v.clone()),
                _ => return Err(fmt(where_, "expected exactly one key (`node`)".into())),
            };
            if key != "node" {
                return Err(fmt(
                    where_,
                    format!("`{key}` entries are not supported; only `node`"),
                ));
            }
            let n: NodeYaml =
                serde_yaml_ng::from_value(value).map_err(|e| fmt(where_.clone(), e.to_string()))?;
            if n.pkg != "chronotope" {
                return Err(fmt(
                    where_,
                    format!("pkg {:?}: only chronotope's nodes run here", n.pkg),
                ));
            }
            let kind = match n.exec.as_str() {
                "mesher" => NodeKind::Mesher,
                "checker" => NodeKind::Checker,
                "carving" => NodeKind::Carving,
                "recorder" => NodeKind::Recorder,
                other => {
                    return Err(fmt(
                        where_,
                        format!("exec {other:?}: one of mesher, checker, carving, recorder"),
                    ))
                }
            };
            let name = n.name.unwrap_or_else(|| n.exec.clone());
            let fqn = node_fqn(n.namespace.as_deref().unwrap_or("/"), &name).map_err(|source| {
                LaunchError::Name {
                    where_: where_.clone(),
                    source,
                }
            })?;
            if !seen.insert(fqn.clone()) {
                return Err(fmt(where_, format!("two nodes are named {fqn}")));
            }
            let mut params = BTreeMap::new();
            for p in n.param {
                let v = ParamValue::from_yaml(&p.value).ok_or_else(|| LaunchError::Param {
                    node: fqn.clone(),
                    param: p.name.clone(),
                    reason: "not a bool, number, string, or a list of one of them".into(),
                })?;
                if params.insert(p.name.clone(), v).is_some() {
                    return Err(LaunchError::Param {
                        node: fqn.clone(),
                        param: p.name,
                        reason: "given twice".into(),
                    });
                }
            }
            let mut remaps = BTreeMap::new();
            for r in n.remap {
                let name_err = |source| LaunchError::Name {
                    where_: where_.clone(),
                    source,
                };
                remaps.insert(
                    resolve_topic(&r.from, &fqn).map_err(name_err)?,
                    resolve_topic(&r.to, &fqn).map_err(name_err)?,
                );
            }
            nodes.push(NodeSpec {
                kind,
                fqn,
                params,
                remaps,
            });
        }
        Ok(Self { path: None, nodes })
    }

    /// The nodes of one kind.
    pub fn of_kind(&self, kind: NodeKind) -> impl Iterator<Item = &NodeSpec> {
        self.nodes.iter().filter(move |n| n.kind == kind)
    }
}

/// Typed access to a node's parameters; every parameter must be taken (declared) by the
/// node, checked by [`Params::finish`].
#[derive(Debug)]
pub struct Params<'a> {
    spec: &'a NodeSpec,
    taken: BTreeSet<&'static str>,
}

impl<'a> Params<'a> {
    /// The parameters of `spec`.
    pub fn of(spec: &'a NodeSpec) -> Self {
        Self {
            spec,
            taken: BTreeSet::new(),
        }
    }

    /// The node's fully qualified name.
    pub fn node(&self) -> &str {
        &self.spec.fqn
    }

    fn err(&self, param: &str, reason: String) -> LaunchError {
        LaunchError::Param {
            node: self.spec.fqn.clone(),
            param: param.to_owned(),
            reason,
        }
    }

    fn get(&mut self, name: &'static str) -> Option<&'a ParamValue> {
        self.taken.insert(name);
        self.spec.params.get(name)
    }

    fn wrong(&self, name: &str, want: &str, got: &ParamValue) -> LaunchError {
        self.err(name, format!("expected {want}, got {} {got:?}", got.kind()))
    }

    /// A bool parameter.
    ///
    /// # Errors
    /// Of another type.
    pub fn bool(&mut self, name: &'static str, default: bool) -> Result<bool, LaunchError> {
        match self.get(name) {
            None => Ok(default),
            Some(ParamValue::Bool(b)) => Ok(*b),
            Some(v) => Err(self.wrong(name, "a bool", v)),
        }
    }

    /// An integer parameter within `range`.
    ///
    /// # Errors
    /// Of another type or out of range.
    pub fn int(
        &mut self,
        name: &'static str,
        default: i64,
        range: std::ops::RangeInclusive<i64>,
    ) -> Result<i64, LaunchError> {
        let v = match self.get(name) {
            None => default,
            Some(ParamValue::Integer(i)) => *i,
            Some(v) => return Err(self.wrong(name, "an integer", v)),
        };
        if range.contains(&v) {
            Ok(v)
        } else {
            Err(self.err(
                name,
                format!("{v} is not in {}..={}", range.start(), range.end()),
            ))
        }
    }

    /// A finite double parameter within `range` (integers are accepted).
    ///
    /// # Errors
    /// Of another type, not finite, or out of range.
    pub fn double(
        &mut self,
        name: &'static str,
        default: f64,
        range: std::ops::RangeInclusive<f64>,
    ) -> Result<f64, LaunchError> {
        let v = match self.get(name) {
            None => default,
            Some(ParamValue::Double(d)) => *d,
            Some(ParamValue::Integer(i)) => *i as f64,
            Some(v) => return Err(self.wrong(name, "a number", v)),
        };
        if v.is_finite() && range.contains(&v) {
            Ok(v)
        } else {
            Err(self.err(
                name,
                format!("{v} is not in {}..={}", range.start(), range.end()),
            ))
        }
    }

    /// A double array of exactly `n` finite numbers.
    ///
    /// # Errors
    /// Of another type or length, or not finite.
    pub fn doubles<const N: usize>(
        &mut self,
        name: &'static str,
        default: [f64; N],
    ) -> Result<[f64; N], LaunchError> {
        let v: Vec<f64> = match self.get(name) {
            None => return Ok(default),
            Some(ParamValue::DoubleArray(d)) => d.clone(),
            Some(ParamValue::IntegerArray(i)) => i.iter().map(|&x| x as f64).collect(),
            Some(v) => return Err(self.wrong(name, "a list of numbers", v)),
        };
        let arr: [f64; N] = v
            .clone()
            .try_into()
            .map_err(|_| self.err(name, format!("expected {N} numbers, got {}", v.len())))?;
        if arr.iter().all(|x| x.is_finite()) {
            Ok(arr)
        } else {
            Err(self.err(name, "numbers must be finite".into()))
        }
    }

    /// A string parameter.
    ///
    /// # Errors
    /// Of another type.
    pub fn string(&mut self, name: &'static str) -> Result<Option<String>, LaunchError> {
        match self.get(name) {
            None => Ok(None),
            Some(ParamValue::String(s)) => Ok(Some(s.clone())),
            Some(v) => Err(self.wrong(name, "a string", v)),
        }
    }

    /// A string array parameter.
    ///
    /// # Errors
    /// Of another type.
    pub fn strings(&mut self, name: &'static str) -> Result<Option<Vec<String>>, LaunchError> {
        match self.get(name) {
            None => Ok(None),
            Some(ParamValue::StringArray(s)) => Ok(Some(s.clone())),
            Some(v) => Err(self.wrong(name, "a list of strings", v)),
        }
    }

    /// A topic parameter (or `default`), resolved for this node and remapped.
    ///
    /// # Errors
    /// Of another type, or not a valid topic name.
    pub fn topic(&mut self, name: &'static str, default: &str) -> Result<String, LaunchError> {
        let t = self.string(name)?.unwrap_or_else(|| default.to_owned());
        self.resolve(name, &t)
    }

    /// A list of topics, resolved and remapped.
    ///
    /// # Errors
    /// Of another type, or a name that is not a valid topic.
    pub fn topics(&mut self, name: &'static str) -> Result<Option<Vec<String>>, LaunchError> {
        let Some(list) = self.strings(name)? else {
            return Ok(None);
        };
        list.iter()
            .map(|t| self.resolve(name, t))
            .collect::<Result<Vec<_>, _>>()
            .map(Some)
    }

    /// `topic` resolved for this node and remapped (for a topic the node publishes or reads
    /// under a fixed name, e.g. `~/report`).
    ///
    /// # Errors
    /// Not a valid topic name.
    pub fn resolve(&self, param: &str, topic: &str) -> Result<String, LaunchError> {
        let r = resolve_topic(topic, &self.spec.fqn).map_err(|e| self.err(param, e.to_string()))?;
        Ok(self.spec.remaps.get(&r).cloned().unwrap_or(r))
    }

    /// Fails on a parameter the node did not take.
    ///
    /// # Errors
    /// [`LaunchError::Param`] naming the first unknown parameter and the known ones.
    pub fn finish(self) -> Result<(), LaunchError> {
        if let Some(unknown) = self
            .spec
            .params
            .keys()
            .find(|k| !self.taken.contains(k.as_str()))
        {
            let known: Vec<&str> = self.taken.iter().copied().collect();
            return Err(self.err(
                unknown,
                format!(
                    "{} does not take it (it takes: {})",
                    self.spec.kind.exec(),
                    known.join(", ")
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CFG: &str = "
launch:
- node:
    pkg: chronotope
    exec: mesher
    namespace: cell
    param:
    - {name: bodies, value: [/a/occupancy, b]}
    - {name: slice_markers, value: true}
    - {name: iso_percent, value: 40}
    remap:
    - {from: ~/mesh_slabs, to: /slabs}
";

    #[test]
    fn a_config_parses_with_names_resolved_and_params_typed() {
        let c = LaunchConfig::parse(CFG, "t").unwrap();
        let n = &c.nodes[0];
        assert_eq!(n.fqn, "/cell/mesher");
        assert_eq!(n.remaps["/cell/mesher/mesh_slabs"], "/slabs");
        let mut p = Params::of(n);
        assert_eq!(
            p.topics("bodies").unwrap().unwrap(),
            ["/a/occupancy", "/cell/b"]
        );
        assert!(p.bool("slice_markers", false).unwrap());
        assert_eq!(p.int("iso_percent", 50, 1..=100).unwrap(), 40);
        assert_eq!(p.resolve("x", "~/mesh_slabs").unwrap(), "/slabs");
        p.finish().unwrap();
    }

    #[test]
    fn mistakes_are_named() {
        let c = LaunchConfig::parse(CFG, "t").unwrap();
        let mut p = Params::of(&c.nodes[0]);
        p.bool("slice_markers", false).unwrap();
        let e = p.finish().unwrap_err().to_string();
        assert!(e.contains("/cell/mesher") && e.contains("bodies"), "{e}");
        let mut p = Params::of(&c.nodes[0]);
        let e = p.bool("iso_percent", false).unwrap_err().to_string();
        assert!(e.contains("expected a bool"), "{e}");
        let mut p = Params::of(&c.nodes[0]);
        assert!(p.int("iso_percent", 50, 50..=100).is_err());
        for (bad, what) in [
            ("launch: [{node: {pkg: other, exec: mesher}}]", "pkg"),
            ("launch: [{node: {pkg: chronotope, exec: nope}}]", "exec"),
            ("launch: [{include: {file: x}}]", "only `node`"),
            ("launch: [{node: {pkg: chronotope, exec: mesher, nmae: x}}]", "nmae"),
            ("launch: [{node: {pkg: chronotope, exec: mesher, name: 'a/b'}}]", "node name"),
            (
                "launch: [{node: {pkg: chronotope, exec: mesher}}, {node: {pkg: chronotope, exec: mesher}}]",
                "two nodes",
            ),
            ("nodes: []", "launch"),
            ("launch: [{node: {pkg: chronotope, exec: mesher, param: [{name: x, value: {a: 1}}]}}]", "not a bool"),
        ] {
            let e = LaunchConfig::parse(bad, "t").unwrap_err().to_string();
            assert!(e.contains(what), "{bad}: {e}");
        }
    }
}
