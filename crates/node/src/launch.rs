//! Launch configs: which nodes run, with which parameters and remappings.
//!
//! The file is a subset of the ROS 2 launch YAML format, so it reads as a ROS user expects:
//!
//! ```yaml
//! launch:
//! - node:
//!     pkg: chronotope
//!     exec: mesher            # mesher | checker | carving | occupancy | recorder | robot
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
use chronotope_yaml::{self as yaml, YamlError, CONFIG_LIMITS};

/// Most nodes one launch config may start (`nodes_per_launch`). Live, each node is a ROS
/// node with about 16 DDS endpoints (rosout, parameter events, six parameter services, its
/// topics) announced to every peer, and each keeps its own state (a mesher's window, a
/// checker's resolution budget of up to 1.5 M tets, a carving workpiece); 64 is four times
/// the largest cell the suite was written for and keeps discovery to about a thousand
/// endpoints.
pub const MAX_NODES: usize = 64;

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

    /// The value as a message shows it: YAML-like, user text and long lists shortened
    /// (`"mesher"`, `1e300`, `[1, 2, 3, … 40 items]`), never a Rust debug dump.
    pub fn shown(&self) -> String {
        fn list<T>(items: &[T], one: impl Fn(&T) -> String) -> String {
            let mut parts: Vec<String> = items.iter().take(4).map(one).collect();
            if items.len() > 4 {
                parts.push(format!("… {} items", items.len()));
            }
            format!("[{}]", parts.join(", "))
        }
        match self {
            Self::Bool(b) => b.to_string(),
            Self::Integer(i) => i.to_string(),
            Self::Double(d) => yaml::number(*d),
            Self::String(s) => yaml::quote(s),
            Self::BoolArray(v) => list(v, bool::to_string),
            Self::IntegerArray(v) => list(v, i64::to_string),
            Self::DoubleArray(v) => list(v, |d| yaml::number(*d)),
            Self::StringArray(v) => list(v, |s| yaml::quote(s)),
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
    /// A robot's URDF and joint states (or a plan) to occupancy frames.
    Robot,
    /// A sensor's OctoMap or point cloud to occupancy frames on a lattice.
    Occupancy,
}

impl NodeKind {
    /// The `exec` name.
    pub fn exec(self) -> &'static str {
        match self {
            Self::Mesher => "mesher",
            Self::Checker => "checker",
            Self::Carving => "carving",
            Self::Recorder => "recorder",
            Self::Robot => "robot",
            Self::Occupancy => "occupancy",
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

/// Parameters every node takes, read by the live executor, not by the node itself.
pub const EXECUTOR_PARAMS: [&str; 3] = ["realtime", "queue_depth", "queue_mb"];

/// Largest `queue_mb` (MiB) a node's queue may be given.
pub const MAX_QUEUE_MB: i64 = 1 << 16;

/// How the live executor runs one node (its `realtime`, `queue_depth` and `queue_mb`
/// parameters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExecutorSpec {
    /// The node's handler runs on a thread nothing else uses, at real-time priority
    /// (SCHED_FIFO) where the system allows, with its own DDS participant for its inputs and
    /// small outputs; it never waits for another node.
    pub realtime: bool,
    /// Messages waiting for the node, all its topics together; beyond it a new message is
    /// dropped and counted (`None`: the launch's `--queue`).
    pub queue_depth: Option<usize>,
    /// Bytes the messages waiting for the node (and the batch it handles) may hold, in MiB
    /// (`None`: the launch's `--queue-mb`).
    pub queue_mb: Option<usize>,
}

impl NodeSpec {
    /// The node's executor parameters.
    ///
    /// # Errors
    /// `realtime` is not a bool, `queue_depth` not an integer in 1..=65536, or `queue_mb`
    /// not one in 1..=[`MAX_QUEUE_MB`].
    pub fn executor(&self) -> Result<ExecutorSpec, LaunchError> {
        let mut p = Params {
            spec: self,
            taken: BTreeSet::new(),
        };
        let realtime = p.bool("realtime", false)?;
        let queue_depth = match self.params.get("queue_depth") {
            None => None,
            Some(_) => Some(p.int("queue_depth", 256, 1..=65536)? as usize),
        };
        let queue_mb = match self.params.get("queue_mb") {
            None => None,
            Some(_) => Some(p.int("queue_mb", 512, 1..=MAX_QUEUE_MB)? as usize),
        };
        Ok(ExecutorSpec {
            realtime,
            queue_depth,
            queue_mb,
        })
    }
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
    /// The text is refused before parsing (a limit of [`chronotope_yaml::CONFIG_LIMITS`], an
    /// alias, not a regular file) or does not parse.
    #[error("{origin}: {source}")]
    Yaml {
        /// The file.
        origin: String,
        /// Why.
        source: YamlError,
    },
    /// The YAML does not parse or has the wrong shape.
    #[error("{where_}: {reason}")]
    Format {
        /// File (and entry).
        where_: String,
        /// What is wrong.
        reason: String,
    },
    /// `launch:` is missing, empty or null.
    #[error("{origin}: the config launches no node (`launch:` is empty); list nodes as `- node: {{pkg: chronotope, exec: mesher}}`")]
    NoNodes {
        /// The file.
        origin: String,
    },
    /// More nodes than [`MAX_NODES`].
    #[error("{origin}: {count} nodes; limit nodes_per_launch = {limit}")]
    TooManyNodes {
        /// The file.
        origin: String,
        /// Nodes in the config.
        count: usize,
        /// [`MAX_NODES`].
        limit: usize,
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
    #[error("{node}: parameter {}: {reason}", yaml::cut(.param))]
    Param {
        /// Node name.
        node: String,
        /// Parameter name.
        param: String,
        /// What is wrong.
        reason: String,
    },
    /// One topic carries two message types: two nodes (or a node and the bag) mean two
    /// different things by it.
    #[error("topic {topic} is used with two message types: {first}, but {second}; give one of them another topic")]
    TopicTypes {
        /// The topic.
        topic: String,
        /// The first use (node, direction, type, parameter).
        first: String,
        /// The conflicting use.
        second: String,
    },
}

#[derive(serde::Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a launch config: a mapping with `launch:`, a list of nodes"
)]
struct FileYaml {
    launch: Option<Vec<serde_yaml_ng::Value>>,
}

// Scalars are taken as YAML values and typed by hand, so that a wrong type is reported with
// its field's name (serde_yaml_ng's `from_value` does not name it).
#[derive(serde::Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a node: a mapping with pkg, exec, name, namespace, param, remap"
)]
struct NodeYaml {
    pkg: serde_yaml_ng::Value,
    exec: serde_yaml_ng::Value,
    #[serde(default)]
    name: serde_yaml_ng::Value,
    #[serde(default)]
    namespace: serde_yaml_ng::Value,
    #[serde(default)]
    param: serde_yaml_ng::Value,
    #[serde(default)]
    remap: serde_yaml_ng::Value,
}

#[derive(serde::Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a parameter: `{name: ..., value: ...}`"
)]
struct ParamYaml {
    name: serde_yaml_ng::Value,
    value: serde_yaml_ng::Value,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields, expecting = "a remapping: `{from: ..., to: ...}`")]
struct RemapYaml {
    from: serde_yaml_ng::Value,
    to: serde_yaml_ng::Value,
}

/// A YAML value as a message shows it.
fn shown(v: &serde_yaml_ng::Value) -> String {
    use serde_yaml_ng::Value as Y;
    match v {
        Y::Null => "nothing".into(),
        Y::Mapping(_) => "a mapping".into(),
        Y::Tagged(_) => "a tagged value".into(),
        Y::Sequence(_) => "a list".into(),
        v => ParamValue::from_yaml(v).map_or_else(|| "a value".into(), |p| p.shown()),
    }
}

/// Field `field` of a launch entry as text (`None` when left out).
fn text_field(
    where_: &str,
    field: &str,
    v: &serde_yaml_ng::Value,
) -> Result<Option<String>, LaunchError> {
    match v {
        serde_yaml_ng::Value::Null => Ok(None),
        serde_yaml_ng::Value::String(s) => Ok(Some(s.clone())),
        v => Err(LaunchError::Format {
            where_: where_.to_owned(),
            reason: format!("{field}: expected text, got {}", shown(v)),
        }),
    }
}

/// Field `field` of a launch entry as a list of `T` (empty when left out).
fn list<T: serde::de::DeserializeOwned>(
    where_: &str,
    field: &str,
    v: &serde_yaml_ng::Value,
) -> Result<Vec<T>, LaunchError> {
    let err = |reason: String| LaunchError::Format {
        where_: where_.to_owned(),
        reason,
    };
    match v {
        serde_yaml_ng::Value::Null => Ok(Vec::new()),
        serde_yaml_ng::Value::Sequence(items) => items
            .iter()
            .enumerate()
            .map(|(i, item)| {
                serde_yaml_ng::from_value(item.clone()).map_err(|e| {
                    err(format!(
                        "{field} item {}: {}",
                        i + 1,
                        yaml::shorten(&e.to_string())
                    ))
                })
            })
            .collect(),
        v => Err(err(format!("{field}: expected a list, got {}", shown(v)))),
    }
}

impl LaunchConfig {
    /// Reads a launch config file (a regular file of at most `config_bytes`).
    ///
    /// # Errors
    /// The file cannot be read or is not a valid config.
    pub fn read(path: &Path) -> Result<Self, LaunchError> {
        let origin = path.display().to_string();
        let text = yaml::read_text(path, &CONFIG_LIMITS).map_err(|source| match source {
            YamlError::Io { source, .. } => LaunchError::Io {
                path: path.to_path_buf(),
                source,
            },
            source => LaunchError::Yaml {
                origin: origin.clone(),
                source,
            },
        })?;
        let mut c = Self::parse(&text, &origin)?;
        c.path = Some(path.to_path_buf());
        Ok(c)
    }

    /// Parses launch config text (`origin` names it in errors). The text is checked against
    /// [`CONFIG_LIMITS`] before it is parsed, and the config against [`MAX_NODES`].
    ///
    /// # Errors
    /// Not a valid config.
    pub fn parse(text: &str, origin: &str) -> Result<Self, LaunchError> {
        let fmt = |where_: String, reason: String| LaunchError::Format { where_, reason };
        let file: FileYaml =
            yaml::from_str(text, &CONFIG_LIMITS).map_err(|source| LaunchError::Yaml {
                origin: origin.to_owned(),
                source,
            })?;
        let entries = file.launch.unwrap_or_default();
        if entries.is_empty() {
            return Err(LaunchError::NoNodes {
                origin: origin.to_owned(),
            });
        }
        if entries.len() > MAX_NODES {
            return Err(LaunchError::TooManyNodes {
                origin: origin.to_owned(),
                count: entries.len(),
                limit: MAX_NODES,
            });
        }
        let mut nodes = Vec::new();
        let mut seen = BTreeSet::new();
        for (i, entry) in entries.into_iter().enumerate() {
            let where_ = format!("{origin}: launch entry {}", i + 1);
            let serde_yaml_ng::Value::Mapping(m) = entry else {
                return Err(fmt(where_, "expected a mapping like `node: {...}`".into()));
            };
            let (key, value) = match m.into_iter().collect::<Vec<_>>().as_slice() {
                [(k, v)] => (k.as_str().map(str::to_owned), v.clone()),
                _ => return Err(fmt(where_, "expected exactly one key (`node`)".into())),
            };
            match key.as_deref() {
                Some("node") => {}
                Some(key) => {
                    return Err(fmt(
                        where_,
                        format!(
                            "{} entries are not supported; only `node`",
                            yaml::quote(key)
                        ),
                    ))
                }
                None => return Err(fmt(where_, "the key is not text; only `node`".into())),
            }
            if let Some(k) = value
                .as_mapping()
                .and_then(|m| m.keys().find(|k| !k.is_string()))
            {
                return Err(fmt(
                    where_,
                    format!(
                        "node: a key that is not text ({}); the keys are pkg, exec, name, \
                         namespace, param, remap",
                        shown(k)
                    ),
                ));
            }
            let n: NodeYaml = serde_yaml_ng::from_value(value)
                .map_err(|e| fmt(where_.clone(), yaml::shorten(&e.to_string())))?;
            let pkg = text_field(&where_, "pkg", &n.pkg)?.unwrap_or_default();
            let exec = text_field(&where_, "exec", &n.exec)?.unwrap_or_default();
            if pkg != "chronotope" {
                return Err(fmt(
                    where_,
                    format!(
                        "pkg {}: only chronotope's nodes run here",
                        yaml::quote(&pkg)
                    ),
                ));
            }
            let kind = match exec.as_str() {
                "mesher" => NodeKind::Mesher,
                "checker" => NodeKind::Checker,
                "carving" => NodeKind::Carving,
                "recorder" => NodeKind::Recorder,
                "robot" => NodeKind::Robot,
                "occupancy" => NodeKind::Occupancy,
                other => {
                    return Err(fmt(
                        where_,
                        format!(
                            "exec {}: one of mesher, checker, carving, occupancy, recorder, robot",
                            yaml::quote(other)
                        ),
                    ))
                }
            };
            let name = text_field(&where_, "name", &n.name)?.unwrap_or_else(|| exec.clone());
            let namespace = text_field(&where_, "namespace", &n.namespace)?;
            let fqn = node_fqn(namespace.as_deref().unwrap_or("/"), &name).map_err(|source| {
                LaunchError::Name {
                    where_: where_.clone(),
                    source,
                }
            })?;
            if !seen.insert(fqn.clone()) {
                return Err(fmt(
                    where_,
                    format!("two nodes are named {fqn}; give one a `name` or a `namespace`"),
                ));
            }
            let mut params = BTreeMap::new();
            for (i, p) in list::<ParamYaml>(&where_, "param", &n.param)?
                .into_iter()
                .enumerate()
            {
                let field = format!("param item {} name", i + 1);
                let pname = text_field(&where_, &field, &p.name)?
                    .ok_or_else(|| fmt(where_.clone(), format!("{field}: missing")))?;
                let v = ParamValue::from_yaml(&p.value).ok_or_else(|| LaunchError::Param {
                    node: fqn.clone(),
                    param: pname.clone(),
                    reason: format!(
                        "{}: not a bool, number, string, or a list of one of them",
                        shown(&p.value)
                    ),
                })?;
                if params.insert(pname.clone(), v).is_some() {
                    return Err(LaunchError::Param {
                        node: fqn.clone(),
                        param: pname,
                        reason: "given twice".into(),
                    });
                }
            }
            let mut remaps = BTreeMap::new();
            for (i, r) in list::<RemapYaml>(&where_, "remap", &n.remap)?
                .into_iter()
                .enumerate()
            {
                let field = |end: &str| format!("remap item {} {end}", i + 1);
                let missing = |f: String| fmt(where_.clone(), format!("{f}: missing"));
                let r_from = text_field(&where_, &field("from"), &r.from)?
                    .ok_or_else(|| missing(field("from")))?;
                let r_to = text_field(&where_, &field("to"), &r.to)?
                    .ok_or_else(|| missing(field("to")))?;
                let name_err = |source| LaunchError::Name {
                    where_: where_.clone(),
                    source,
                };
                let from = resolve_topic(&r_from, &fqn).map_err(name_err)?;
                let to = resolve_topic(&r_to, &fqn).map_err(name_err)?;
                if let Some(before) = remaps.insert(from.clone(), to.clone()) {
                    return Err(fmt(
                        where_,
                        format!("{from} is remapped twice (to {before} and to {to})"),
                    ));
                }
            }
            let spec = NodeSpec {
                kind,
                fqn,
                params,
                remaps,
            };
            // The executor's parameters are checked here: every node kind takes them.
            spec.executor()?;
            nodes.push(spec);
        }
        Ok(Self { path: None, nodes })
    }

    /// The nodes of one kind.
    pub fn of_kind(&self, kind: NodeKind) -> impl Iterator<Item = &NodeSpec> {
        self.nodes.iter().filter(move |n| n.kind == kind)
    }

    /// The files the config's nodes read, as written (carving cut-out images: the path of
    /// each `cutouts` entry "AXIS PATH"), so that a command can keep its outputs off them.
    pub fn input_files(&self) -> Vec<std::path::PathBuf> {
        self.of_kind(NodeKind::Carving)
            .filter_map(|n| match n.params.get("cutouts") {
                Some(ParamValue::StringArray(v)) => Some(v),
                _ => None,
            })
            .flatten()
            .filter_map(|e| e.trim().split_once(char::is_whitespace))
            .map(|(_, p)| std::path::PathBuf::from(p.trim()))
            .collect()
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
    /// The parameters of `spec`. The executor's ([`EXECUTOR_PARAMS`]) count as taken: they
    /// are read by [`NodeSpec::executor`], for every node kind.
    pub fn of(spec: &'a NodeSpec) -> Self {
        Self {
            spec,
            taken: EXECUTOR_PARAMS.iter().copied().collect(),
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
        self.err(
            name,
            format!("expected {want}, got {} {}", got.kind(), got.shown()),
        )
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
                format!(
                    "{} is not in [{}, {}]{}",
                    yaml::number(v),
                    yaml::number(*range.start()),
                    yaml::number(*range.end()),
                    if v.is_finite() {
                        ""
                    } else {
                        " (a finite number is needed)"
                    }
                ),
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
        match arr.iter().position(|x| !x.is_finite()) {
            None => Ok(arr),
            Some(i) => Err(self.err(
                name,
                format!(
                    "number {} is {}: numbers must be finite",
                    i + 1,
                    yaml::number(arr[i])
                ),
            )),
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

    #[test]
    fn every_node_takes_the_executor_parameters_checked_at_load() {
        let cfg = "launch:\n- node: {pkg: chronotope, exec: mesher, param: [{name: realtime, value: true}, {name: queue_depth, value: 8}, {name: queue_mb, value: 64}]}\n";
        let c = LaunchConfig::parse(cfg, "t").unwrap();
        let e = c.nodes[0].executor().unwrap();
        assert!(e.realtime);
        assert_eq!(e.queue_depth, Some(8));
        assert_eq!(e.queue_mb, Some(64));
        for (bad, what) in [
            ("{name: realtime, value: 'yes'}", "realtime"),
            ("{name: queue_depth, value: 0}", "queue_depth"),
            ("{name: queue_depth, value: 1.5}", "queue_depth"),
            ("{name: queue_mb, value: 0}", "queue_mb"),
            ("{name: queue_mb, value: 65537}", "queue_mb"),
        ] {
            let cfg =
                format!("launch:\n- node: {{pkg: chronotope, exec: checker, param: [{bad}]}}\n");
            let e = LaunchConfig::parse(&cfg, "t").unwrap_err().to_string();
            assert!(e.contains(what), "{bad}: {e}");
        }
    }
}
