//! `.msg` definitions as rosbag2 stores them: the `ros2msg` schema text of MCAP channels, and a
//! small parser for the field lines of a `.msg` file.
//!
//! rosbag2 (`rosbag2_cpp::LocalMessageDefinitionSource::get_full_text`) writes a type's schema
//! as the type's own `.msg` text followed, for each type it refers to, by
//!
//! ```text
//! \n
//! ================================================================================\n
//! MSG: pkg/Type\n
//! <that type's .msg text>
//! ```
//!
//! The referenced types are found by reading the field types of each definition; those of one
//! definition are visited in sorted order (by `pkg/Type` name), each one recursively before the
//! next (depth first), and every type is written once, at its first appearance. A type named
//! without a package (`Point`) belongs to the package of the definition that names it.
//! [`ros2msg_schema`] follows the same rules, so its output is byte-identical to what
//! `ros2 bag record` writes for the same `.msg` files.

use std::collections::{BTreeSet, HashSet};

use super::RosMessage;

/// The separator line rosbag2 puts before each dependency (80 `=`), without its newline.
pub const SCHEMA_SEPARATOR: &str =
    "================================================================================";

/// Primitive (built-in) field types of the `.msg` language.
const PRIMITIVE_TYPES: &[&str] = &[
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
    "uint32", "int64", "uint64", "string", "wstring",
];

/// One field or constant line of a `.msg` definition.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MsgField {
    /// The type as written, with array or bound suffix: `uint8[]`, `std_msgs/Header`,
    /// `string<=8`, `float64[3]`.
    pub ty: String,
    /// Field or constant name.
    pub name: String,
    /// True for a constant (`uint8 ENCODING_BITS=0`).
    pub is_constant: bool,
    /// The constant's value, or the field's default value if it has one (text as written).
    pub value: Option<String>,
}

impl MsgField {
    /// The type without array suffix or string bound: `uint8` for `uint8[]`, `string` for
    /// `string<=8`, `std_msgs/Header` for `std_msgs/Header[2]`.
    pub fn base_type(&self) -> &str {
        base_type(&self.ty)
    }

    /// True if the base type is a built-in type rather than another message.
    pub fn is_primitive(&self) -> bool {
        PRIMITIVE_TYPES.contains(&self.base_type())
    }
}

/// What is missing for a complete schema.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SchemaError {
    /// A definition refers to a type that `RosMessage::dependencies()` does not provide.
    #[error(
        "{referenced_by} refers to {missing}, whose definition is not among the type's \
         dependencies(); add (\"{missing_full}\", its .msg text) to the list"
    )]
    MissingDependency {
        /// The type that is missing, `pkg/Type`.
        missing: String,
        /// The same as `pkg/msg/Type`.
        missing_full: String,
        /// The definition that refers to it, `pkg/Type`.
        referenced_by: String,
    },
}

/// The rosbag2 `ros2msg` schema text of `M` (see the module documentation for the format).
///
/// A dependency that `M::dependencies()` does not provide is left out; use
/// [`try_ros2msg_schema`] to have that reported.
pub fn ros2msg_schema<M: RosMessage>() -> String {
    build_schema::<M>(false).unwrap_or_else(|_| M::DEFINITION.to_owned())
}

/// Like [`ros2msg_schema`], but fails if a referenced type's definition is not provided.
///
/// # Errors
///
/// [`SchemaError::MissingDependency`] naming the type that is missing and who refers to it.
pub fn try_ros2msg_schema<M: RosMessage>() -> Result<String, SchemaError> {
    build_schema::<M>(true)
}

fn build_schema<M: RosMessage>(strict: bool) -> Result<String, SchemaError> {
    let deps: Vec<(String, &'static str)> = M::dependencies()
        .into_iter()
        .map(|(name, text)| (short_type_name(name), text))
        .collect();
    let root = short_type_name(M::TYPE_NAME);
    let mut out = String::from(M::DEFINITION);
    let mut seen = HashSet::new();
    append_dependencies(&root, M::DEFINITION, &deps, &mut seen, &mut out, strict)?;
    Ok(out)
}

/// Appends, depth first, every not yet seen dependency of `text` (the definition of `name`).
///
/// Recursion depth is bounded by the number of provided dependencies, as each is entered once.
fn append_dependencies(
    name: &str,
    text: &str,
    deps: &[(String, &'static str)],
    seen: &mut HashSet<String>,
    out: &mut String,
    strict: bool,
) -> Result<(), SchemaError> {
    let package = name.split('/').next().unwrap_or_default();
    for dep in referenced_types(text, package) {
        if seen.contains(&dep) {
            continue;
        }
        let Some((_, dep_text)) = deps.iter().find(|(n, _)| *n == dep) else {
            if strict {
                return Err(SchemaError::MissingDependency {
                    missing_full: full_type_name(&dep),
                    missing: dep,
                    referenced_by: name.to_owned(),
                });
            }
            continue;
        };
        seen.insert(dep.clone());
        out.push('\n');
        out.push_str(SCHEMA_SEPARATOR);
        out.push_str("\nMSG: ");
        out.push_str(&dep);
        out.push('\n');
        out.push_str(dep_text);
        append_dependencies(&dep, dep_text, deps, seen, out, strict)?;
    }
    Ok(())
}

/// The message types a definition's fields refer to, as sorted `pkg/Type` names.
fn referenced_types(text: &str, package: &str) -> BTreeSet<String> {
    parse_msg_fields(text)
        .into_iter()
        .filter(|f| !f.is_constant && !f.is_primitive())
        .map(|f| {
            let base = f.base_type();
            if base.contains('/') {
                short_type_name(base)
            } else {
                format!("{package}/{base}")
            }
        })
        .collect()
}

/// `pkg/msg/Type` -> `pkg/Type`; other names unchanged.
fn short_type_name(name: &str) -> String {
    let mut parts = name.split('/');
    match (parts.next(), parts.next(), parts.next(), parts.next()) {
        (Some(pkg), Some("msg"), Some(ty), None) => format!("{pkg}/{ty}"),
        _ => name.to_owned(),
    }
}

/// `pkg/Type` -> `pkg/msg/Type`; other names unchanged.
fn full_type_name(name: &str) -> String {
    match name.split_once('/') {
        Some((pkg, ty)) if !ty.contains('/') => format!("{pkg}/msg/{ty}"),
        _ => name.to_owned(),
    }
}

fn base_type(ty: &str) -> &str {
    let end = ty.find(['[', '<']).unwrap_or(ty.len());
    &ty[..end]
}

/// Parses the field and constant lines of a `.msg` definition, in order.
///
/// Comments (from `#` to the end of the line) and blank lines are skipped. A line is
/// `TYPE NAME`, `TYPE NAME DEFAULT` or `TYPE NAME=VALUE` (a constant; spaces around `=` are
/// allowed). Lines that are none of these are skipped too: this is a reader for tests and
/// schema building, not a validator.
///
/// ```
/// use chronotope_msg::parse_msg_fields;
/// let fields = parse_msg_fields("# comment\nuint8 A=1  # one\nfloat64[] xs\n");
/// assert_eq!(fields.len(), 2);
/// assert!(fields[0].is_constant);
/// assert_eq!(fields[0].value.as_deref(), Some("1"));
/// assert_eq!((fields[1].ty.as_str(), fields[1].name.as_str()), ("float64[]", "xs"));
/// ```
pub fn parse_msg_fields(text: &str) -> Vec<MsgField> {
    text.lines().filter_map(parse_line).collect()
}

fn parse_line(line: &str) -> Option<MsgField> {
    let line = line.split('#').next().unwrap_or_default().trim();
    let (ty, rest) = line.split_once(char::is_whitespace)?;
    let rest = rest.trim();
    // A constant: an identifier, then `=`. (A default value may itself contain `=`, but then
    // what precedes it is `name value...`, not a lone identifier.)
    if let Some((name, value)) = rest.split_once('=') {
        let name = name.trim();
        if is_identifier(name) {
            return Some(MsgField {
                ty: ty.to_owned(),
                name: name.to_owned(),
                is_constant: true,
                value: Some(value.trim().to_owned()),
            });
        }
    }
    let (name, default) = match rest.split_once(char::is_whitespace) {
        Some((name, default)) => (name, Some(default.trim().to_owned())),
        None => (rest, None),
    };
    if !is_identifier(name) {
        return None;
    }
    Some(MsgField {
        ty: ty.to_owned(),
        name: name.to_owned(),
        is_constant: false,
        value: default,
    })
}

fn is_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_convert_both_ways() {
        assert_eq!(short_type_name("std_msgs/msg/Header"), "std_msgs/Header");
        assert_eq!(short_type_name("std_msgs/Header"), "std_msgs/Header");
        assert_eq!(full_type_name("std_msgs/Header"), "std_msgs/msg/Header");
    }

    #[test]
    fn types_without_package_take_the_definitions_package() {
        let deps = referenced_types(
            "Pose pose\nstd_msgs/Header header\nint32 x\n",
            "geometry_msgs",
        );
        let deps: Vec<_> = deps.into_iter().collect();
        assert_eq!(deps, ["geometry_msgs/Pose", "std_msgs/Header"]);
    }

    #[test]
    fn bounded_and_array_types_parse() {
        let f = parse_msg_fields("string<=8 name \"a=b\"\nfloat64[3] v [1, 2, 3]\nint32 X = -4\n");
        assert_eq!(f[0].base_type(), "string");
        assert!(!f[0].is_constant);
        assert_eq!(f[0].value.as_deref(), Some("\"a=b\""));
        assert_eq!(f[1].base_type(), "float64");
        assert_eq!(f[1].value.as_deref(), Some("[1, 2, 3]"));
        assert!(f[2].is_constant);
        assert_eq!(
            (f[2].name.as_str(), f[2].value.as_deref()),
            ("X", Some("-4"))
        );
    }
}
