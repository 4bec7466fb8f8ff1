//! What can be wrong with a URDF text, each case naming the culprit and where it is.

use std::path::PathBuf;

/// A URDF that was refused. Every variant names what was wrong (the element, attribute,
/// joint or link) and, where the text is at fault, the line it is on.
#[derive(Debug, thiserror::Error)]
pub enum UrdfError {
    /// The URDF file could not be read.
    #[error("cannot read URDF file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        #[source]
        source: std::io::Error,
    },
    /// The text is larger than `MAX_URDF_BYTES` (or the caller's lower limit).
    #[error("URDF text is {bytes} bytes, over MAX_URDF_BYTES = {limit}")]
    TooLarge {
        /// Bytes of the text (or of the file).
        bytes: u64,
        /// The limit in force.
        limit: u64,
    },
    /// The text is not well-formed XML (or uses a DTD, which is refused: entity expansion
    /// is an amplification risk and URDF never needs one).
    #[error("malformed XML at line {line}, column {column}: {message}")]
    Xml {
        /// 1-based line.
        line: u32,
        /// 1-based column.
        column: u32,
        /// What the XML parser said.
        message: String,
    },
    /// The root element is not `<robot>`.
    #[error("not a URDF: the root element is <{found}> (line {line}), expected <robot>")]
    NotUrdf {
        /// The root element's name.
        found: String,
        /// Its line.
        line: u32,
    },
    /// The text still holds xacro macros or substitutions.
    #[error(
        "unexpanded xacro at line {line}: {what}; run xacro first \
         (`ros2 run xacro xacro robot.urdf.xacro > robot.urdf`) and give the expanded URDF"
    )]
    Xacro {
        /// The first xacro construct found (an element, an attribute or a substitution).
        what: String,
        /// Its line.
        line: u32,
    },
    /// A required attribute is missing.
    #[error("<{element}> at line {line} has no `{attribute}` attribute")]
    MissingAttribute {
        /// The element.
        element: String,
        /// The attribute it needs.
        attribute: &'static str,
        /// Its line.
        line: u32,
    },
    /// A required child element is missing.
    #[error("<{element}> at line {line} has no <{child}>")]
    MissingElement {
        /// The element.
        element: String,
        /// The child it needs.
        child: &'static str,
        /// Its line.
        line: u32,
    },
    /// An attribute is not the number or numbers it should be, or is out of its domain
    /// (zero, negative or non-finite sizes, scales, radii and lengths; non-finite poses).
    #[error("<{element}> `{attribute}`=\"{value}\" at line {line}: {why}")]
    BadValue {
        /// The element.
        element: String,
        /// The attribute.
        attribute: &'static str,
        /// The value as written (at most 64 characters).
        value: String,
        /// What is wrong with it.
        why: &'static str,
        /// Its line.
        line: u32,
    },
    /// A geometry other than box, cylinder, sphere and mesh.
    #[error("link `{link}`: unsupported collision geometry <{geometry}> at line {line} (box, cylinder, sphere and mesh are)")]
    UnsupportedGeometry {
        /// The link.
        link: String,
        /// The geometry element found.
        geometry: String,
        /// Its line.
        line: u32,
    },
    /// A floating, planar or unknown joint type.
    #[error("joint `{joint}` at line {line} is of type `{kind}`, which is not supported (revolute, continuous, prismatic and fixed are; a floating base is given as the base pose instead)")]
    UnsupportedJoint {
        /// The joint.
        joint: String,
        /// Its `type`.
        kind: String,
        /// Its line.
        line: u32,
    },
    /// Two links or two joints share a name.
    #[error("{what} `{name}` is defined twice (lines {first_line} and {line})")]
    Duplicate {
        /// `"link"` or `"joint"`.
        what: &'static str,
        /// The name.
        name: String,
        /// Line of the first definition.
        first_line: u32,
        /// Line of the second.
        line: u32,
    },
    /// A joint names a link that is not defined.
    #[error("joint `{joint}` names {role} link `{link}`, which is not defined")]
    UnknownLink {
        /// The joint.
        joint: String,
        /// `"parent"` or `"child"`.
        role: &'static str,
        /// The missing link.
        link: String,
    },
    /// A link is the child of two joints.
    #[error("link `{link}` has two parents: it is the child of joints `{first}` and `{second}`")]
    TwoParents {
        /// The link.
        link: String,
        /// The first joint naming it as child.
        first: String,
        /// The second.
        second: String,
    },
    /// The joints form a loop.
    #[error("kinematic loop: link `{link}` is its own ancestor (URDF describes trees only)")]
    Loop {
        /// A link on the loop.
        link: String,
    },
    /// More than one link has no parent.
    #[error("the URDF has {} roots (links with no parent joint): {}", roots.len(), roots.join(", "))]
    SeveralRoots {
        /// The root links (at most 16 listed).
        roots: Vec<String>,
    },
    /// The robot has no link.
    #[error("the URDF defines no link")]
    NoLinks,
    /// More links or collision elements than the limits allow.
    #[error("the URDF has {count} {what}, over {limit_name} = {limit}")]
    TooMany {
        /// `"links"` or `"collision elements"`.
        what: &'static str,
        /// How many it has.
        count: usize,
        /// The limit's name.
        limit_name: &'static str,
        /// The limit in force.
        limit: usize,
    },
    /// A mimic joint names a joint that does not exist.
    #[error("joint `{joint}` mimics `{target}`, which is not a joint of this URDF")]
    MimicUnknownJoint {
        /// The mimic joint.
        joint: String,
        /// The joint it names.
        target: String,
    },
    /// A mimic joint names a fixed joint, which has no position to follow.
    #[error("joint `{joint}` mimics `{target}`, which is fixed")]
    MimicOfFixed {
        /// The mimic joint.
        joint: String,
        /// The fixed joint it names.
        target: String,
    },
    /// Mimic joints name each other in a cycle.
    #[error("mimic joints form a cycle through `{joint}`")]
    MimicCycle {
        /// A joint on the cycle.
        joint: String,
    },
    /// A joint axis of zero length.
    #[error("joint `{joint}` has an axis of zero length (line {line})")]
    ZeroAxis {
        /// The joint.
        joint: String,
        /// The axis element's line.
        line: u32,
    },
    /// A revolute or prismatic joint without `<limit>`, or with lower > upper.
    #[error("joint `{joint}` (line {line}): {why}")]
    BadLimits {
        /// The joint.
        joint: String,
        /// What is wrong.
        why: String,
        /// The joint's line.
        line: u32,
    },
}
