//! Message definitions compared by meaning: a stored `ros2msg` schema text (an MCAP schema, a
//! rosbag2 SQLite `message_definitions` row) is the same type as ours when it has the same
//! fields, with the same types, in the same order, and the same nested types, however it is
//! laid out.
//!
//! Writers lay the same type out differently: rosbag2 keeps the `.msg` text as written, PyPI
//! `rosbags` regenerates it from its type store with the constants first, others drop the
//! comments or order the dependency sections otherwise, and type names appear as `pkg/Type`
//! or `pkg/msg/Type`. None of that changes the bytes on the wire. So a definition is read into
//! its meaning ([`Definition::parse`]):
//!
//! - the main type and each dependency section (after a line of `=` and a `MSG: pkg/Type`
//!   line), in any order;
//! - per type its fields in order, each a normalised type (`pkg/Type`, a bare `Type` taking
//!   the package of the section that names it, array and bound suffixes kept) and a name;
//! - its constants as a set (type, name, value), wherever they stand;
//! - comments, blank lines, spacing and default values dropped (defaults do not reach the
//!   wire).
//!
//! Two definitions agree ([`Definition::difference`]) when their main types agree and every
//! type reachable from the main type's fields agrees too; sections that nothing reaches are
//! ignored. A line that is neither a field nor a constant, a section naming no type, or a type
//! used but not defined makes a definition refused, never guessed at.

use std::collections::{BTreeMap, BTreeSet};

use super::schema::{parse_msg_fields, MsgField};

/// Primitive (built-in) types of the `.msg` language.
const PRIMITIVES: &[&str] = &[
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
    "uint32", "int64", "uint64", "string", "wstring",
];

/// Most sections (types) a definition may hold; a larger text is refused, not parsed.
pub const MAX_SECTIONS: usize = 4096;

/// Why a definition text is refused ([`Definition::parse`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DefinitionError {
    /// More than [`MAX_SECTIONS`] sections.
    #[error("more than {MAX_SECTIONS} dependency sections")]
    TooManySections,
    /// A dependency section whose first line is not its `MSG: pkg/Type` line.
    #[error(
        "a dependency section starts with `{}` instead of `MSG: pkg/Type`",
        shorten(.line)
    )]
    NoMsgLine {
        /// The line found (its code, comments dropped).
        line: String,
    },
    /// A line of a type that is neither a field nor a constant.
    #[error("in {type_name}: `{}` is neither a field nor a constant", shorten(.line))]
    NotAField {
        /// The type (`pkg/Type`).
        type_name: String,
        /// The line (its code, comments dropped).
        line: String,
    },
    /// A type defined twice, the two differently.
    #[error("{type_name} is defined twice, differently")]
    DefinedTwice {
        /// The type (`pkg/Type`).
        type_name: String,
    },
}

/// One type of a definition, by meaning.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
struct TypeDef {
    /// Fields in order: (normalised type, name).
    fields: Vec<(String, String)>,
    /// Constants: (normalised type, name, value).
    constants: BTreeSet<(String, String, String)>,
}

/// A `ros2msg` definition read into its meaning (see the module documentation).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Definition {
    /// The main type's name, `pkg/Type`.
    name: String,
    /// Every type it holds, the main one included, by `pkg/Type`.
    types: BTreeMap<String, TypeDef>,
}

impl Definition {
    /// Reads the definition of `type_name` (`pkg/msg/Type` or `pkg/Type`) from its text.
    ///
    /// # Errors
    /// [`DefinitionError`]: a line that is neither a field nor a constant, a dependency
    /// section without its `MSG:` line, a type defined twice differently, or more than
    /// [`MAX_SECTIONS`] sections.
    pub fn parse(type_name: &str, text: &str) -> Result<Self, DefinitionError> {
        let main = short_name(type_name);
        let mut sections: Vec<(Option<String>, Vec<&str>)> = vec![(Some(main.clone()), Vec::new())];
        for line in text.lines() {
            let code = line.split('#').next().unwrap_or_default().trim();
            if code.len() >= 3 && code.bytes().all(|b| b == b'=') {
                if sections.len() >= MAX_SECTIONS {
                    return Err(DefinitionError::TooManySections);
                }
                sections.push((None, Vec::new()));
                continue;
            }
            let Some(section) = sections.last_mut() else {
                continue;
            };
            if section.0.is_none() {
                if code.is_empty() {
                    continue;
                }
                let Some(name) = code.strip_prefix("MSG:") else {
                    return Err(DefinitionError::NoMsgLine {
                        line: code.to_owned(),
                    });
                };
                section.0 = Some(short_name(name.trim()));
                continue;
            }
            section.1.push(line);
        }
        let mut types: BTreeMap<String, TypeDef> = BTreeMap::new();
        for (name, lines) in sections {
            let Some(name) = name else {
                // A separator with nothing after it (a trailing one).
                continue;
            };
            let package = name.split('/').next().unwrap_or_default().to_owned();
            let mut def = TypeDef::default();
            for line in &lines {
                let code = line.split('#').next().unwrap_or_default().trim();
                if code.is_empty() {
                    continue;
                }
                let Some(f) = parse_msg_fields(code).into_iter().next() else {
                    return Err(DefinitionError::NotAField {
                        type_name: name,
                        line: code.to_owned(),
                    });
                };
                let ty = normalise_type(&f, &package);
                if f.is_constant {
                    let value = f.value.unwrap_or_default().trim().to_owned();
                    def.constants.insert((ty, f.name, value));
                } else {
                    def.fields.push((ty, f.name));
                }
            }
            match types.get(&name) {
                Some(existing) if *existing != def => {
                    return Err(DefinitionError::DefinedTwice { type_name: name });
                }
                Some(_) => {}
                None => {
                    types.insert(name, def);
                }
            }
        }
        Ok(Self { name: main, types })
    }

    /// The main type's name (`pkg/Type`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// `None` if `other` describes the same type as `self` (see the module documentation),
    /// else the first difference in words, naming the type, field or constant and both sides
    /// (`self` is what is expected, `other` what a bag holds).
    pub fn difference(&self, other: &Definition) -> Option<String> {
        if self.name != other.name {
            return Some(format!("it defines {}, not {}", other.name, self.name));
        }
        let mut todo = vec![self.name.clone()];
        let mut seen = BTreeSet::new();
        while let Some(name) = todo.pop() {
            if !seen.insert(name.clone()) {
                continue;
            }
            let Some(want) = self.types.get(&name) else {
                // Our own definition lacks it: nothing to hold the other to.
                continue;
            };
            let Some(got) = other.types.get(&name) else {
                return Some(format!("it does not define {name}, which its fields use"));
            };
            if let Some(d) = type_difference(&name, want, got) {
                return Some(d);
            }
            for (ty, _) in &want.fields {
                let base = base_of(ty);
                if !PRIMITIVES.contains(&base) {
                    todo.push(base.to_owned());
                }
            }
        }
        None
    }
}

/// The first difference between two definitions of the type `name`.
fn type_difference(name: &str, want: &TypeDef, got: &TypeDef) -> Option<String> {
    let show = |f: Option<&(String, String)>| {
        f.map_or("nothing".to_owned(), |(t, n)| format!("`{t} {n}`"))
    };
    for i in 0..want.fields.len().max(got.fields.len()) {
        let (w, g) = (want.fields.get(i), got.fields.get(i));
        if w != g {
            return Some(format!(
                "field {} of {name}: the bag has {}, expected {}",
                i + 1,
                show(g),
                show(w)
            ));
        }
    }
    if want.constants != got.constants {
        let missing = want.constants.difference(&got.constants).next();
        let extra = got.constants.difference(&want.constants).next();
        let show = |c: Option<&(String, String, String)>| {
            c.map_or("nothing".to_owned(), |(t, n, v)| format!("`{t} {n}={v}`"))
        };
        return Some(format!(
            "constants of {name}: the bag has {} where {} is expected",
            show(extra),
            show(missing)
        ));
    }
    None
}

/// A field's type with its package made explicit and `pkg/msg/Type` shortened: `uint8[]`,
/// `std_msgs/Header`, `geometry_msgs/Point[3]`, `string<=8`.
fn normalise_type(f: &MsgField, package: &str) -> String {
    let ty: String = f.ty.split_whitespace().collect();
    let base = base_of(&ty);
    let suffix = &ty[base.len()..];
    if PRIMITIVES.contains(&base) {
        return ty;
    }
    let full = if base.contains('/') {
        short_name(base)
    } else {
        format!("{package}/{base}")
    };
    format!("{full}{suffix}")
}

/// The type without array suffix or bound.
fn base_of(ty: &str) -> &str {
    &ty[..ty.find(['[', '<']).unwrap_or(ty.len())]
}

/// `pkg/msg/Type` -> `pkg/Type`.
fn short_name(name: &str) -> String {
    let name = name.trim();
    let mut parts = name.split('/');
    match (parts.next(), parts.next(), parts.next(), parts.next()) {
        (Some(pkg), Some("msg"), Some(ty), None) => format!("{pkg}/{ty}"),
        _ => name.to_owned(),
    }
}

/// At most 60 characters of a line, for a message.
fn shorten(s: &str) -> String {
    let cut: String = s.chars().take(60).collect();
    if cut.len() < s.len() {
        cut + "…"
    } else {
        cut
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ros2msg_schema, VoxelGrid};

    fn ours() -> Definition {
        Definition::parse(
            "chronotope_msgs/msg/VoxelGrid",
            &ros2msg_schema::<VoxelGrid>(),
        )
        .unwrap()
    }

    fn theirs(text: &str) -> Option<String> {
        match Definition::parse("chronotope_msgs/msg/VoxelGrid", text) {
            Ok(d) => ours().difference(&d),
            Err(e) => Some(e.to_string()),
        }
    }

    /// Our text with the constants moved first, names spelt `pkg/msg/Type`, comments and
    /// spacing gone, and the dependency sections in the other order: the same type.
    #[test]
    fn layout_does_not_change_meaning() {
        let ours_text = ros2msg_schema::<VoxelGrid>();
        assert_eq!(theirs(&ours_text), None);
        let sep = "=".repeat(80);
        let relaid = format!(
            "uint8 ENCODING_PERCENT = 1\nuint8 ENCODING_BITS=0\n\
             std_msgs/msg/Header header\ngeometry_msgs/msg/Point   origin\nfloat64 resolution 0.1\n\
             uint32 size_x\nuint32 size_y\nuint32 size_z\nuint8 encoding\nuint8[] data\n\
             {sep}\nMSG: geometry_msgs/msg/Point\nfloat64 x\nfloat64 y\nfloat64 z\n\
             {sep}\nMSG: std_msgs/Header\n# comment\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
             {sep}\nMSG: builtin_interfaces/msg/Time\nint32 sec\nuint32 nanosec\n\
             {sep}\nMSG: unused/Extra\nint8 whatever\n"
        );
        assert_eq!(theirs(&relaid), None, "{relaid}");
    }

    #[test]
    fn a_different_field_list_is_refused_by_name() {
        let ours_text = ros2msg_schema::<VoxelGrid>();
        let why =
            theirs(&ours_text.replacen("float64 resolution", "float32 resolution", 1)).unwrap();
        assert!(
            why.contains("float32 resolution") && why.contains("field 3"),
            "{why}"
        );
        let why = theirs(&ours_text.replacen("uint32 size_z\n", "", 1)).unwrap();
        assert!(why.contains("size_z"), "{why}");
        let why = theirs(&ours_text.replacen("float64 z", "float32 z", 1)).unwrap();
        assert!(why.contains("geometry_msgs/Point"), "{why}");
        let why =
            theirs(&ours_text.replacen("ENCODING_PERCENT=1", "ENCODING_PERCENT=2", 1)).unwrap();
        assert!(why.contains("ENCODING_PERCENT"), "{why}");
        // A nested type left undefined is not guessed.
        let main_only = ours_text.split(&"=".repeat(80)).next().unwrap();
        let why = theirs(main_only).unwrap();
        assert!(why.contains("does not define"), "{why}");
        let why = theirs(&ours_text.replacen("uint32 size_x", "uint32 size_x\n!!!", 1)).unwrap();
        assert!(why.contains("neither a field nor a constant"), "{why}");
    }
}
