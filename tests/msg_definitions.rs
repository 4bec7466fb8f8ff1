//! The `.msg` files under `msgs/` are the source of truth; the Rust types must match them
//! field by field (name, order, type, nesting) and constant by constant, and the interface
//! package must declare what the definitions use.

use std::collections::HashMap;
use std::fmt;
use std::path::Path;

use chronotope::msg::{
    encode_cdr, parse_msg_fields, Header, MsgField, Point, RosMessage, Time, VoxelGrid,
};
use serde::de::{Deserializer, IgnoredAny, MapAccess, Visitor};
use serde_json::Value;

fn read(path: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(path))
        .unwrap_or_else(|err| panic!("{path}: {err}"))
}

/// Every definition the crate knows: `pkg/Type` -> fields.
fn definitions() -> HashMap<String, Vec<MsgField>> {
    let mut defs = HashMap::new();
    defs.insert(
        "chronotope_msgs/VoxelGrid".to_owned(),
        parse_msg_fields(&read("msgs/msg/VoxelGrid.msg")),
    );
    for (name, text) in VoxelGrid::dependencies() {
        defs.insert(name.replace("/msg/", "/"), parse_msg_fields(text));
    }
    defs
}

/// The top-level keys of a JSON object, in the order they appear (serde_json's `Value` would
/// sort them).
fn key_order(json: &str) -> Vec<String> {
    struct Keys;
    impl<'de> Visitor<'de> for Keys {
        type Value = Vec<String>;
        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            f.write_str("an object")
        }
        fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Vec<String>, A::Error> {
            let mut keys = Vec::new();
            while let Some(key) = map.next_key::<String>()? {
                map.next_value::<IgnoredAny>()?;
                keys.push(key);
            }
            Ok(keys)
        }
    }
    let mut de = serde_json::Deserializer::from_str(json);
    de.deserialize_map(Keys).unwrap()
}

/// The non-constant field names of a definition, in order.
fn field_names(fields: &[MsgField]) -> Vec<&str> {
    fields
        .iter()
        .filter(|f| !f.is_constant)
        .map(|f| f.name.as_str())
        .collect()
}

#[test]
fn voxel_grid_msg_fields_are_the_rust_fields_in_order() {
    let defs = definitions();
    let msg = &defs["chronotope_msgs/VoxelGrid"];
    let typed: Vec<(&str, &str)> = msg
        .iter()
        .filter(|f| !f.is_constant)
        .map(|f| (f.ty.as_str(), f.name.as_str()))
        .collect();
    assert_eq!(
        typed,
        [
            ("std_msgs/Header", "header"),
            ("geometry_msgs/Point", "origin"),
            ("float64", "resolution"),
            ("uint32", "size_x"),
            ("uint32", "size_y"),
            ("uint32", "size_z"),
            ("uint8", "encoding"),
            ("uint8[]", "data"),
        ]
    );
    let json = serde_json::to_string(&VoxelGrid::default()).unwrap();
    assert_eq!(key_order(&json), field_names(msg));
    // The nested types too.
    let nested: [(&str, String); 3] = [
        (
            "std_msgs/Header",
            serde_json::to_string(&Header::default()).unwrap(),
        ),
        (
            "builtin_interfaces/Time",
            serde_json::to_string(&Time::default()).unwrap(),
        ),
        (
            "geometry_msgs/Point",
            serde_json::to_string(&Point::default()).unwrap(),
        ),
    ];
    for (name, json) in nested {
        assert_eq!(key_order(&json), field_names(&defs[name]), "{name}");
    }
}

#[test]
fn voxel_grid_constants_match() {
    let msg = parse_msg_fields(&read("msgs/msg/VoxelGrid.msg"));
    let constants: Vec<(&str, &str, &str)> = msg
        .iter()
        .filter(|f| f.is_constant)
        .map(|f| (f.ty.as_str(), f.name.as_str(), f.value.as_deref().unwrap()))
        .collect();
    assert_eq!(
        constants,
        [
            ("uint8", "ENCODING_BITS", "0"),
            ("uint8", "ENCODING_PERCENT", "1")
        ]
    );
    assert_eq!(VoxelGrid::ENCODING_BITS.to_string(), constants[0].2);
    assert_eq!(VoxelGrid::ENCODING_PERCENT.to_string(), constants[1].2);
    // The constants' type is the field's type.
    let encoding = msg.iter().find(|f| f.name == "encoding").unwrap();
    assert_eq!(encoding.ty, constants[0].0);
}

/// CDR little-endian body of a JSON value, laid out as the `.msg` definition `ty` says.
///
/// An encoder driven by the definitions alone: if the Rust types disagree with the `.msg` files
/// in any type, order or nesting, its bytes differ from `encode_cdr`'s.
fn encode_from_definition(
    ty: &str,
    value: &Value,
    defs: &HashMap<String, Vec<MsgField>>,
    out: &mut Vec<u8>,
) {
    fn align(out: &mut Vec<u8>, n: usize) {
        while out.len() % n != 0 {
            out.push(0);
        }
    }
    if let Some(element) = ty.strip_suffix("[]") {
        let items = value.as_array().expect("array");
        align(out, 4);
        out.extend((items.len() as u32).to_le_bytes());
        for item in items {
            encode_from_definition(element, item, defs, out);
        }
        return;
    }
    match ty {
        "float64" => {
            align(out, 8);
            out.extend(value.as_f64().unwrap().to_le_bytes());
        }
        "uint32" => {
            align(out, 4);
            out.extend((value.as_u64().unwrap() as u32).to_le_bytes());
        }
        "int32" => {
            align(out, 4);
            out.extend((value.as_i64().unwrap() as i32).to_le_bytes());
        }
        "uint8" => out.push(value.as_u64().unwrap() as u8),
        "string" => {
            let s = value.as_str().unwrap();
            align(out, 4);
            out.extend((s.len() as u32 + 1).to_le_bytes());
            out.extend(s.as_bytes());
            out.push(0);
        }
        nested => {
            let fields = defs
                .get(nested)
                .unwrap_or_else(|| panic!("no definition for {nested}"));
            for field in fields.iter().filter(|f| !f.is_constant) {
                encode_from_definition(&field.ty, &value[&field.name], defs, out);
            }
        }
    }
}

#[test]
fn cdr_of_the_rust_type_is_the_layout_the_msg_files_define() {
    let defs = definitions();
    for frame_id in ["", "m", "map", "world_frame"] {
        let grid = VoxelGrid {
            header: Header {
                stamp: Time {
                    sec: -3,
                    nanosec: 999_999_999,
                },
                frame_id: frame_id.into(),
            },
            origin: Point {
                x: 0.125,
                y: -7.5,
                z: 1e-3,
            },
            resolution: 0.02,
            size_x: 5,
            size_y: 4,
            size_z: 3,
            encoding: VoxelGrid::ENCODING_BITS,
            data: (0..8).collect(),
        };
        let json = serde_json::to_value(&grid).unwrap();
        let mut body = Vec::new();
        encode_from_definition("chronotope_msgs/VoxelGrid", &json, &defs, &mut body);
        assert_eq!(
            encode_cdr(&grid).unwrap()[4..],
            body[..],
            "frame_id {frame_id:?}"
        );
    }
}

#[test]
fn type_names_and_dependencies_name_the_files() {
    assert_eq!(VoxelGrid::TYPE_NAME, "chronotope_msgs/msg/VoxelGrid");
    assert_eq!(VoxelGrid::DEFINITION, read("msgs/msg/VoxelGrid.msg"));
    let mut names = Vec::new();
    for (name, text) in VoxelGrid::dependencies() {
        let (pkg, ty) = name.split_once("/msg/").expect("pkg/msg/Type");
        assert_eq!(
            text,
            read(&format!("msgs/deps/{pkg}/msg/{ty}.msg")),
            "{name}"
        );
        names.push(name);
    }
    names.sort_unstable();
    assert_eq!(
        names,
        [
            "builtin_interfaces/msg/Time",
            "geometry_msgs/msg/Point",
            "std_msgs/msg/Header"
        ]
    );
}

#[test]
fn the_interface_package_declares_what_the_definition_uses() {
    let package = read("msgs/package.xml");
    let cmake = read("msgs/CMakeLists.txt");
    let (pkg_name, _) = VoxelGrid::TYPE_NAME.split_once('/').unwrap();
    assert!(package.contains(&format!("<name>{pkg_name}</name>")));
    assert!(cmake.contains(&format!("project({pkg_name})")));
    assert!(cmake.contains("\"msg/VoxelGrid.msg\""));
    assert!(package.contains("<member_of_group>rosidl_interface_packages</member_of_group>"));
    assert!(package.contains("<buildtool_depend>rosidl_default_generators</buildtool_depend>"));
    // Every package the definitions refer to is a dependency of the interface package.
    let dependencies = cmake
        .split("DEPENDENCIES")
        .nth(1)
        .and_then(|rest| rest.split(')').next())
        .expect("rosidl_generate_interfaces(... DEPENDENCIES ...)");
    for (name, _) in VoxelGrid::dependencies() {
        let (pkg, _) = name.split_once('/').unwrap();
        assert!(
            package.contains(&format!("<depend>{pkg}</depend>")),
            "{pkg} in package.xml"
        );
        assert!(
            dependencies.split_whitespace().any(|d| d == pkg),
            "{pkg} in DEPENDENCIES"
        );
        assert!(
            cmake.contains(&format!("find_package({pkg} REQUIRED)")),
            "{pkg}"
        );
    }
}
