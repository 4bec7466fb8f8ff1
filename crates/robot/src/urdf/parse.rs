//! From XML text to the URDF elements this crate reads, names still unresolved.
//!
//! Reads with roxmltree (no DTD, bounded node count), refuses xacro left in the text, and
//! checks every number where it is read, so that an error points at its line.

use super::{Collision, Geometry, JointKind, JointLimits, UrdfError};
use crate::limits::{Limits, MAX_URDF_NODES};
use crate::math::{pose_from_xyz_rpy, Pose, Vector};
use roxmltree::{Document, Node, ParsingOptions};

/// The xacro namespaces in use (the old and the new wiki address).
const XACRO_NAMESPACES: [&str; 3] = [
    "http://www.ros.org/wiki/xacro",
    "http://ros.org/wiki/xacro",
    "http://wiki.ros.org/xacro",
];

pub(super) struct ParsedLink {
    pub name: String,
    pub line: u32,
    pub collisions: Vec<Collision>,
}

pub(super) struct ParsedJoint {
    pub name: String,
    pub line: u32,
    pub kind: JointKind,
    pub parent: String,
    pub child: String,
    pub origin: Pose,
    pub axis: Vector,
    pub axis_line: u32,
    pub limits: Option<JointLimits>,
    /// (joint named, multiplier, offset)
    pub mimic: Option<(String, f64, f64)>,
}

pub(super) struct Parsed {
    pub name: String,
    pub links: Vec<ParsedLink>,
    pub joints: Vec<ParsedJoint>,
}

pub(super) fn parse(text: &str, limits: &Limits) -> Result<Parsed, UrdfError> {
    let options = ParsingOptions {
        allow_dtd: false,
        nodes_limit: MAX_URDF_NODES,
        ..ParsingOptions::default()
    };
    let doc = Document::parse_with_options(text, options).map_err(xml_error)?;
    let root = doc.root_element();
    refuse_xacro(&doc)?;
    if root.tag_name().name() != "robot" {
        return Err(UrdfError::NotUrdf {
            found: root.tag_name().name().to_owned(),
            line: line_of(&doc, root),
        });
    }
    let mut parsed = Parsed {
        name: root.attribute("name").unwrap_or("").to_owned(),
        links: Vec::new(),
        joints: Vec::new(),
    };
    let mut collisions = 0usize;
    for node in root.children().filter(Node::is_element) {
        match node.tag_name().name() {
            "link" => {
                if parsed.links.len() == limits.links {
                    return Err(UrdfError::TooMany {
                        what: "links",
                        count: root.children().filter(|n| n.has_tag_name("link")).count(),
                        limit_name: "MAX_LINKS",
                        limit: limits.links,
                    });
                }
                let link = parse_link(&doc, node)?;
                collisions += link.collisions.len();
                if collisions > limits.collisions {
                    return Err(UrdfError::TooMany {
                        what: "collision elements",
                        count: collisions,
                        limit_name: "MAX_COLLISIONS",
                        limit: limits.collisions,
                    });
                }
                parsed.links.push(link);
            }
            "joint" => parsed.joints.push(parse_joint(&doc, node)?),
            _ => {} // materials, transmissions, gazebo and ros2_control blocks: not ours
        }
    }
    Ok(parsed)
}

fn xml_error(e: roxmltree::Error) -> UrdfError {
    let pos = e.pos();
    if let roxmltree::Error::UnknownNamespace(prefix, _) = &e {
        if prefix == "xacro" {
            return UrdfError::Xacro {
                what: "an element or attribute with the `xacro:` prefix".into(),
                line: pos.row,
            };
        }
    }
    UrdfError::Xml {
        line: pos.row,
        column: pos.col,
        message: e.to_string(),
    }
}

pub(super) fn line_of(doc: &Document<'_>, node: Node<'_, '_>) -> u32 {
    doc.text_pos_at(node.range().start).row
}

/// Refuses any element or attribute in the xacro namespace and any `${...}` or `$(...)`
/// substitution left in an attribute value or text. A declaration of the xacro namespace
/// alone is accepted: xacro leaves it on `<robot>` in its output.
fn refuse_xacro(doc: &Document<'_>) -> Result<(), UrdfError> {
    for node in doc.descendants() {
        if node.is_element() {
            let tag = node.tag_name();
            if tag
                .namespace()
                .is_some_and(|ns| XACRO_NAMESPACES.contains(&ns))
            {
                return Err(UrdfError::Xacro {
                    what: format!("element <xacro:{}>", tag.name()),
                    line: line_of(doc, node),
                });
            }
            for attr in node.attributes() {
                if attr
                    .namespace()
                    .is_some_and(|ns| XACRO_NAMESPACES.contains(&ns))
                {
                    return Err(UrdfError::Xacro {
                        what: format!("attribute xacro:{} on <{}>", attr.name(), tag.name()),
                        line: line_of(doc, node),
                    });
                }
                if let Some(sub) = substitution(attr.value()) {
                    return Err(UrdfError::Xacro {
                        what: format!(
                            "substitution `{}` in attribute `{}` of <{}>",
                            sub,
                            attr.name(),
                            tag.name()
                        ),
                        line: line_of(doc, node),
                    });
                }
            }
        } else if node.is_text() {
            if let Some(sub) = node.text().and_then(substitution) {
                return Err(UrdfError::Xacro {
                    what: format!("substitution `{sub}` in text"),
                    line: line_of(doc, node),
                });
            }
        }
    }
    Ok(())
}

/// The first `${...}` or `$(...)` in a value, quoted short.
fn substitution(value: &str) -> Option<String> {
    let at = value.find("${").or_else(|| value.find("$("))?;
    Some(short(&value[at..]))
}

fn short(value: &str) -> String {
    const MAX: usize = 64;
    if value.chars().count() <= MAX {
        value.to_owned()
    } else {
        let cut: String = value.chars().take(MAX).collect();
        format!("{cut}…")
    }
}

fn required<'a>(
    doc: &Document<'_>,
    node: Node<'a, '_>,
    attribute: &'static str,
) -> Result<&'a str, UrdfError> {
    node.attribute(attribute)
        .ok_or_else(|| UrdfError::MissingAttribute {
            element: node.tag_name().name().to_owned(),
            attribute,
            line: line_of(doc, node),
        })
}

fn bad_value(
    doc: &Document<'_>,
    node: Node<'_, '_>,
    attribute: &'static str,
    value: &str,
    why: &'static str,
) -> UrdfError {
    UrdfError::BadValue {
        element: node.tag_name().name().to_owned(),
        attribute,
        value: short(value),
        why,
        line: line_of(doc, node),
    }
}

/// Reads `N` whitespace-separated finite numbers.
fn numbers<const N: usize>(
    doc: &Document<'_>,
    node: Node<'_, '_>,
    attribute: &'static str,
    value: &str,
) -> Result<[f64; N], UrdfError> {
    let mut out = [0.0; N];
    let mut count = 0;
    for token in value.split_whitespace() {
        if count == N {
            return Err(bad_value(doc, node, attribute, value, too_many(N)));
        }
        let v: f64 = token
            .parse()
            .map_err(|_| bad_value(doc, node, attribute, value, "not a number"))?;
        if !v.is_finite() {
            return Err(bad_value(doc, node, attribute, value, "not finite"));
        }
        out[count] = v;
        count += 1;
    }
    if count != N {
        return Err(bad_value(doc, node, attribute, value, too_few(N)));
    }
    Ok(out)
}

fn too_many(n: usize) -> &'static str {
    if n == 1 {
        "expected one number"
    } else {
        "expected three numbers, found more"
    }
}

fn too_few(n: usize) -> &'static str {
    if n == 1 {
        "expected one number"
    } else {
        "expected three numbers, found fewer"
    }
}

fn optional_number(
    doc: &Document<'_>,
    node: Node<'_, '_>,
    attribute: &'static str,
) -> Result<Option<f64>, UrdfError> {
    match node.attribute(attribute) {
        None => Ok(None),
        Some(v) => numbers::<1>(doc, node, attribute, v).map(|[x]| Some(x)),
    }
}

/// A strictly positive finite number (sizes, radii, lengths, scales).
fn positive(
    doc: &Document<'_>,
    node: Node<'_, '_>,
    attribute: &'static str,
    values: &[f64],
    text: &str,
) -> Result<(), UrdfError> {
    if values.iter().all(|&v| v > 0.0) {
        Ok(())
    } else if values.contains(&0.0) {
        Err(bad_value(doc, node, attribute, text, "zero"))
    } else {
        Err(bad_value(doc, node, attribute, text, "negative"))
    }
}

fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|n| n.has_tag_name(name))
}

fn parse_origin(doc: &Document<'_>, parent: Node<'_, '_>) -> Result<Pose, UrdfError> {
    let Some(origin) = child(parent, "origin") else {
        return Ok(Pose::identity());
    };
    let xyz = match origin.attribute("xyz") {
        Some(v) => numbers::<3>(doc, origin, "xyz", v)?,
        None => [0.0; 3],
    };
    let rpy = match origin.attribute("rpy") {
        Some(v) => numbers::<3>(doc, origin, "rpy", v)?,
        None => [0.0; 3],
    };
    Ok(pose_from_xyz_rpy(xyz, rpy))
}

fn parse_link(doc: &Document<'_>, node: Node<'_, '_>) -> Result<ParsedLink, UrdfError> {
    let name = required(doc, node, "name")?.to_owned();
    let mut collisions = Vec::new();
    for c in node.children().filter(|n| n.has_tag_name("collision")) {
        let origin = parse_origin(doc, c)?;
        let geometry_node = child(c, "geometry").ok_or_else(|| UrdfError::MissingElement {
            element: format!("collision of link `{name}`"),
            child: "geometry",
            line: line_of(doc, c),
        })?;
        let shape = geometry_node
            .children()
            .find(Node::is_element)
            .ok_or_else(|| UrdfError::MissingElement {
                element: format!("geometry of link `{name}`"),
                child: "box, cylinder, sphere or mesh",
                line: line_of(doc, geometry_node),
            })?;
        let geometry = parse_geometry(doc, &name, shape)?;
        collisions.push(Collision {
            name: c.attribute("name").map(str::to_owned),
            origin,
            geometry,
        });
    }
    Ok(ParsedLink {
        name,
        line: line_of(doc, node),
        collisions,
    })
}

fn parse_geometry(
    doc: &Document<'_>,
    link: &str,
    shape: Node<'_, '_>,
) -> Result<Geometry, UrdfError> {
    match shape.tag_name().name() {
        "box" => {
            let text = required(doc, shape, "size")?;
            let size = numbers::<3>(doc, shape, "size", text)?;
            positive(doc, shape, "size", &size, text)?;
            Ok(Geometry::Box { size })
        }
        "cylinder" => {
            let r = required(doc, shape, "radius")?;
            let radius = numbers::<1>(doc, shape, "radius", r)?[0];
            positive(doc, shape, "radius", &[radius], r)?;
            let l = required(doc, shape, "length")?;
            let length = numbers::<1>(doc, shape, "length", l)?[0];
            positive(doc, shape, "length", &[length], l)?;
            Ok(Geometry::Cylinder { radius, length })
        }
        "sphere" => {
            let r = required(doc, shape, "radius")?;
            let radius = numbers::<1>(doc, shape, "radius", r)?[0];
            positive(doc, shape, "radius", &[radius], r)?;
            Ok(Geometry::Sphere { radius })
        }
        "mesh" => {
            let filename = required(doc, shape, "filename")?.to_owned();
            if filename.trim().is_empty() {
                return Err(bad_value(doc, shape, "filename", &filename, "empty"));
            }
            let scale = match shape.attribute("scale") {
                Some(text) => {
                    let s = numbers::<3>(doc, shape, "scale", text)?;
                    positive(doc, shape, "scale", &s, text)?;
                    s
                }
                None => [1.0; 3],
            };
            Ok(Geometry::Mesh { filename, scale })
        }
        other => Err(UrdfError::UnsupportedGeometry {
            link: link.to_owned(),
            geometry: other.to_owned(),
            line: line_of(doc, shape),
        }),
    }
}

fn parse_joint(doc: &Document<'_>, node: Node<'_, '_>) -> Result<ParsedJoint, UrdfError> {
    let name = required(doc, node, "name")?.to_owned();
    let line = line_of(doc, node);
    let type_text = required(doc, node, "type")?;
    let kind = match type_text {
        "revolute" => JointKind::Revolute,
        "continuous" => JointKind::Continuous,
        "prismatic" => JointKind::Prismatic,
        "fixed" => JointKind::Fixed,
        other => {
            return Err(UrdfError::UnsupportedJoint {
                joint: name,
                kind: short(other),
                line,
            })
        }
    };
    let link_attr = |element: &'static str| -> Result<String, UrdfError> {
        let n = child(node, element).ok_or_else(|| UrdfError::MissingElement {
            element: format!("joint `{name}`"),
            child: element,
            line,
        })?;
        Ok(required(doc, n, "link")?.to_owned())
    };
    let parent = link_attr("parent")?;
    let child_link = link_attr("child")?;
    let origin = parse_origin(doc, node)?;
    let (axis, axis_line) = match child(node, "axis") {
        Some(a) => {
            let text = required(doc, a, "xyz")?;
            (
                Vector::from(numbers::<3>(doc, a, "xyz", text)?),
                line_of(doc, a),
            )
        }
        None => (Vector::x(), line),
    };
    let limits = match kind {
        JointKind::Revolute | JointKind::Prismatic => {
            let Some(l) = child(node, "limit") else {
                return Err(UrdfError::BadLimits {
                    joint: name,
                    why: format!("a {type_text} joint needs <limit lower upper>"),
                    line,
                });
            };
            let lower = optional_number(doc, l, "lower")?.unwrap_or(0.0);
            let upper = optional_number(doc, l, "upper")?.unwrap_or(0.0);
            if lower > upper {
                return Err(UrdfError::BadLimits {
                    joint: name,
                    why: format!("lower limit {lower} is above upper limit {upper}"),
                    line,
                });
            }
            Some(JointLimits { lower, upper })
        }
        _ => None,
    };
    let mimic = match child(node, "mimic") {
        Some(m) => {
            let target = required(doc, m, "joint")?.to_owned();
            let multiplier = optional_number(doc, m, "multiplier")?.unwrap_or(1.0);
            let offset = optional_number(doc, m, "offset")?.unwrap_or(0.0);
            Some((target, multiplier, offset))
        }
        None => None,
    };
    Ok(ParsedJoint {
        name,
        line,
        kind,
        parent,
        child: child_link,
        origin,
        axis,
        axis_line,
        limits,
        mimic,
    })
}
