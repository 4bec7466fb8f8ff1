//! The robot node's parameters, read and checked from its launch entry.

use std::path::PathBuf;

use chronotope_robot::{BasePose, Encoding, HistoryBounds, Lattice};

use super::super::launch::{LaunchError, NodeSpec, Params};

/// Where the URDF comes from.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Description {
    /// The latest message on this topic (`std_msgs/String`, transient local).
    Topic(String),
    /// A file, read at start.
    File(PathBuf),
}

/// Where the lattice comes from.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum LatticeSource {
    /// Given by `origin`, `resolution` and `size`.
    Given(Lattice),
    /// The lattice of another body's first frame (`lattice_from`).
    From(String),
}

/// One published body: its name, topic and links (empty: every link).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BodySpec {
    pub name: String,
    pub topic: String,
    pub links: Vec<String>,
}

/// Everything the node's launch entry says.
#[derive(Debug, Clone)]
pub(super) struct Settings {
    pub fqn: String,
    pub description: Description,
    pub package_path: Vec<PathBuf>,
    pub joint_states_topic: String,
    /// `None` when `base_pose` is given.
    pub tf_static_topic: Option<String>,
    pub base_pose: Option<BasePose>,
    pub frame_id: Option<String>,
    pub lattice: LatticeSource,
    /// Frames at the stamps of the `lattice_from` body's frames (else on the `rate_hz` grid).
    pub follow_stamps: bool,
    pub period_ns: i64,
    pub encoding: Encoding,
    pub subsamples: u32,
    pub bodies: Vec<BodySpec>,
    pub trajectory_topic: Option<String>,
    pub suggestions_topic: Option<String>,
    pub report_topic: Option<String>,
    pub retimed_topic: Option<String>,
    pub history: HistoryBounds,
    pub joint_states_timeout_ns: i64,
}

/// Reads the parameters of a robot node's launch entry.
///
/// # Errors
/// A missing, mistyped, out-of-range or contradictory parameter, named with the reason.
pub(super) fn settings(spec: &NodeSpec) -> Result<Settings, LaunchError> {
    let mut p = Params::of(spec);
    let fqn = p.node().to_owned();
    let bad = |param: &str, reason: String| LaunchError::Param {
        node: fqn.clone(),
        param: param.to_owned(),
        reason,
    };
    let urdf_file = p.string("urdf_file")?;
    let description_topic = p.string("robot_description_topic")?;
    let description = match (urdf_file, description_topic) {
        (Some(_), Some(_)) => {
            return Err(bad(
                "urdf_file",
                "give either urdf_file or robot_description_topic, not both".into(),
            ))
        }
        (Some(f), None) => Description::File(PathBuf::from(f)),
        (None, t) => Description::Topic(p.resolve(
            "robot_description_topic",
            t.as_deref().unwrap_or("/robot_description"),
        )?),
    };
    let package_path = p
        .strings("package_path")?
        .unwrap_or_default()
        .into_iter()
        .map(PathBuf::from)
        .collect();
    let joint_states_topic = p.topic("joint_states_topic", "/joint_states")?;
    let base_pose = match spec.params.get("base_pose") {
        None => {
            p.doubles("base_pose", [0.0; 6])?;
            None
        }
        Some(_) => Some(BasePose::from_array(p.doubles("base_pose", [0.0; 6])?)),
    };
    let tf_static = p.topic("tf_static_topic", "/tf_static")?;
    let tf_static_topic = base_pose.is_none().then_some(tf_static);
    let frame_id = p.string("frame_id")?;
    if frame_id.as_deref() == Some("") {
        return Err(bad("frame_id", "empty: name the lattice's frame".into()));
    }
    let lattice_from = match p.string("lattice_from")? {
        Some(t) => Some(p.resolve("lattice_from", &t)?),
        None => None,
    };
    let given = ["origin", "resolution", "size"]
        .iter()
        .filter(|k| spec.params.contains_key(**k))
        .count();
    let origin = p.doubles("origin", [0.0; 3])?;
    let resolution = p.double("resolution", 0.01, 1e-6..=100.0)?;
    let size = p.doubles("size", [0.0; 3])?;
    let lattice =
        match (lattice_from, given) {
            (Some(_), n) if n > 0 => {
                return Err(bad(
                    "lattice_from",
                    "give either lattice_from or origin, resolution and size, not both".into(),
                ))
            }
            (Some(t), _) => LatticeSource::From(t),
            (None, 3) => {
                let mut s = [0u32; 3];
                for (k, v) in size.iter().enumerate() {
                    if v.fract() != 0.0 || *v < 1.0 || *v > f64::from(u32::MAX) {
                        return Err(bad(
                            "size",
                            format!("{v} is not a whole number of voxels ≥ 1"),
                        ));
                    }
                    s[k] = *v as u32;
                }
                LatticeSource::Given(
                    Lattice::new(origin, resolution, s).map_err(|e| bad("size", e.to_string()))?,
                )
            }
            (None, _) => return Err(bad(
                "lattice_from",
                "no lattice: give lattice_from (another body's VoxelGrid topic, to be compared \
                 with it voxel for voxel) or origin, resolution and size"
                    .into(),
            )),
        };
    let rate_hz = p.double("rate_hz", 30.0, 0.1..=1000.0)?;
    let follow_stamps = p.bool("follow_stamps", matches!(lattice, LatticeSource::From(_)))?;
    if follow_stamps && !matches!(lattice, LatticeSource::From(_)) {
        return Err(bad(
            "follow_stamps",
            "frames follow the stamps of the lattice_from body: give lattice_from".into(),
        ));
    }
    let encoding = match p.string("encoding")?.as_deref() {
        None | Some("percent") => Encoding::Percent,
        Some("bits") => Encoding::Bits,
        Some(other) => return Err(bad("encoding", format!("{other:?}: one of percent, bits"))),
    };
    let subsamples = p.int("subsamples", 4, 1..=16)?;
    if (subsamples as u32).count_ones() != 1 {
        return Err(bad(
            "subsamples",
            format!("{subsamples} is not 1, 2, 4, 8 or 16"),
        ));
    }
    let bodies = body_specs(&mut p, &bad)?;
    let trajectory_topic = match p.string("trajectory_topic")? {
        Some(t) => Some(p.resolve("trajectory_topic", &t)?),
        None => None,
    };
    let suggestions = p.topic("suggestions_topic", "/checker/suggestions")?;
    let report = p.topic("report_topic", "/checker/report")?;
    let retimed = p.resolve("~/retimed_trajectory", "~/retimed_trajectory")?;
    let plans = trajectory_topic.is_some();
    let history_s = p.double("history_s", 10.0, 0.01..=3600.0)?;
    let timeout_s = p.double("joint_states_timeout_s", 0.5, 0.001..=3600.0)?;
    p.finish()?;
    Ok(Settings {
        fqn,
        description,
        package_path,
        joint_states_topic,
        tf_static_topic,
        base_pose,
        frame_id,
        lattice,
        follow_stamps,
        period_ns: (1e9 / rate_hz).round() as i64,
        encoding,
        subsamples: subsamples as u32,
        bodies,
        trajectory_topic,
        suggestions_topic: plans.then_some(suggestions),
        report_topic: plans.then_some(report),
        retimed_topic: plans.then_some(retimed),
        history: HistoryBounds {
            window: (history_s * 1e9) as i64,
            ..HistoryBounds::default()
        },
        joint_states_timeout_ns: (timeout_s * 1e9) as i64,
    })
}

/// The `bodies` parameter: `"NAME: LINK LINK ..."` entries, each published on
/// `~/NAME/occupancy`; none: one body of every link on `~/occupancy`.
fn body_specs(
    p: &mut Params<'_>,
    bad: &dyn Fn(&str, String) -> LaunchError,
) -> Result<Vec<BodySpec>, LaunchError> {
    let Some(entries) = p.strings("bodies")? else {
        return Ok(vec![BodySpec {
            name: String::new(),
            topic: p.resolve("bodies", "~/occupancy")?,
            links: Vec::new(),
        }]);
    };
    if entries.is_empty() {
        return Err(bad(
            "bodies",
            "empty: leave it out for one body of every link".into(),
        ));
    }
    let mut out: Vec<BodySpec> = Vec::new();
    for e in &entries {
        let Some((name, links)) = e.split_once(':') else {
            return Err(bad(
                "bodies",
                format!("{e:?}: expected \"NAME: LINK LINK ...\""),
            ));
        };
        let name = name.trim();
        let links: Vec<String> = links.split_whitespace().map(str::to_owned).collect();
        if links.is_empty() {
            return Err(bad("bodies", format!("{e:?}: names no link")));
        }
        if out.iter().any(|b| b.name == name) {
            return Err(bad("bodies", format!("body {name:?} is named twice")));
        }
        for l in &links {
            if let Some(b) = out.iter().find(|b| b.links.contains(l)) {
                return Err(bad(
                    "bodies",
                    format!("link {l:?} is in bodies {:?} and {name:?}", b.name),
                ));
            }
        }
        let topic = p.resolve("bodies", &format!("~/{name}/occupancy"))?;
        out.push(BodySpec {
            name: name.to_owned(),
            topic,
            links,
        });
    }
    Ok(out)
}
