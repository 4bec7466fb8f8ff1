//! The `.msg` files under `msgs/` are the source of truth; the Rust types must match them
//! field by field (name, order, type, nesting) and constant by constant, and the interface
//! package must declare what the definitions use.

use std::collections::HashMap;
use std::fmt;
use std::path::Path;

use chronotope::msg::{
    encode_cdr, parse_msg_fields, try_ros2msg_schema, Clock, ColorRGBA, CompressedImage,
    DiagnosticArray, DiagnosticStatus, Duration, Header, JointState, JointTrajectory,
    JointTrajectoryPoint, KeyValue, Marker, MarkerArray, MeshFile, MsgField, Octomap, Point,
    PointCloud2, PointField, Pose, PoseStamped, Quaternion, ResolveSuggestion, ResolveSuggestions,
    RosMessage, RosString, TFMessage, Time, Transform, TransformStamped, UVCoordinate, Vector3,
    VoxelGrid, Wrench, WrenchStamped,
};
use serde::de::{Deserialize, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};
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
    for message in std_messages() {
        defs.insert(
            short_name(message.name),
            parse_msg_fields(message.definition),
        );
        for (name, text) in message.dependencies {
            defs.insert(short_name(name), parse_msg_fields(text));
        }
    }
    defs
}

/// `pkg/msg/Type` -> `pkg/Type`.
fn short_name(name: &str) -> String {
    name.replace("/msg/", "/")
}

/// What `RosMessage` says about one type.
struct MessageInfo {
    name: &'static str,
    definition: &'static str,
    dependencies: Vec<(&'static str, &'static str)>,
}

fn info<M: RosMessage>() -> MessageInfo {
    MessageInfo {
        name: M::TYPE_NAME,
        definition: M::DEFINITION,
        dependencies: M::dependencies(),
    }
}

/// The standard types of `chronotope::msg` (besides those of `VoxelGrid`).
fn std_messages() -> Vec<MessageInfo> {
    vec![
        info::<Duration>(),
        info::<ColorRGBA>(),
        info::<Quaternion>(),
        info::<Vector3>(),
        info::<Pose>(),
        info::<PoseStamped>(),
        info::<Wrench>(),
        info::<WrenchStamped>(),
        info::<KeyValue>(),
        info::<DiagnosticStatus>(),
        info::<DiagnosticArray>(),
        info::<Clock>(),
        info::<PointField>(),
        info::<PointCloud2>(),
        info::<CompressedImage>(),
        info::<UVCoordinate>(),
        info::<MeshFile>(),
        info::<Marker>(),
        info::<MarkerArray>(),
        info::<RosString>(),
        info::<Transform>(),
        info::<TransformStamped>(),
        info::<TFMessage>(),
        info::<JointState>(),
        info::<JointTrajectoryPoint>(),
        info::<JointTrajectory>(),
        info::<Octomap>(),
    ]
}

/// A field type with its package: `Point` in a `geometry_msgs` definition is
/// `geometry_msgs/Point`, `UVCoordinate[]` in `visualization_msgs` is
/// `visualization_msgs/UVCoordinate[]`; primitive and qualified types are unchanged.
fn qualify(field: &MsgField, package: &str) -> String {
    if field.is_primitive() || field.base_type().contains('/') {
        field.ty.clone()
    } else {
        format!("{package}/{}", field.ty)
    }
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
/// in any type, order or nesting, its bytes differ from `encode_cdr`'s. `ty` is a primitive
/// type or a package-qualified message type (`pkg/Type`), with any array suffix: `T[]` and
/// `T[<=N]` are sequences (a `u32` count, then the elements), `T[N]` a fixed array (the
/// elements alone). Types named without a package inside a definition belong to its package.
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
    if let Some((element, bound)) = ty.strip_suffix(']').and_then(|t| t.rsplit_once('[')) {
        let items = value.as_array().expect("array");
        if let Ok(len) = bound.parse::<usize>() {
            assert_eq!(items.len(), len, "fixed array {ty}");
        } else {
            assert!(
                bound.is_empty() || bound.starts_with("<="),
                "array bound {ty}"
            );
            align(out, 4);
            out.extend((items.len() as u32).to_le_bytes());
        }
        for item in items {
            encode_from_definition(element, item, defs, out);
        }
        return;
    }
    // `string<=N` is a string.
    let base = ty.split("<=").next().unwrap_or(ty);
    match base {
        "bool" => out.push(u8::from(value.as_bool().expect("bool"))),
        "byte" | "char" | "uint8" => out.push(value.as_u64().unwrap() as u8),
        "int8" => out.push(value.as_i64().unwrap() as i8 as u8),
        "uint16" => {
            align(out, 2);
            out.extend((value.as_u64().unwrap() as u16).to_le_bytes());
        }
        "int16" => {
            align(out, 2);
            out.extend((value.as_i64().unwrap() as i16).to_le_bytes());
        }
        "uint32" => {
            align(out, 4);
            out.extend((value.as_u64().unwrap() as u32).to_le_bytes());
        }
        "int32" => {
            align(out, 4);
            out.extend((value.as_i64().unwrap() as i32).to_le_bytes());
        }
        "uint64" => {
            align(out, 8);
            out.extend(value.as_u64().unwrap().to_le_bytes());
        }
        "int64" => {
            align(out, 8);
            out.extend(value.as_i64().unwrap().to_le_bytes());
        }
        "float32" => {
            align(out, 4);
            out.extend((value.as_f64().unwrap() as f32).to_le_bytes());
        }
        "float64" => {
            align(out, 8);
            out.extend(value.as_f64().unwrap().to_le_bytes());
        }
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
            let (package, _) = nested.split_once('/').expect("pkg/Type");
            for field in fields.iter().filter(|f| !f.is_constant) {
                let field_value = value
                    .get(&field.name)
                    .unwrap_or_else(|| panic!("{nested}.{} missing in {value}", field.name));
                encode_from_definition(&qualify(field, package), field_value, defs, out);
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
    // Every message of the package is generated (so `ros2 topic echo` knows them all).
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("msgs/msg");
    for e in std::fs::read_dir(&dir).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        if name.ends_with(".msg") {
            assert!(
                cmake.contains(&format!("\"msg/{name}\"")),
                "{name} in CMakeLists.txt"
            );
        }
    }
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

// ---------------------------------------------------------------------------------------------
// The standard types (std_types.rs)

/// A JSON value with object keys in the order they appear (serde_json's `Value` sorts them).
#[derive(Debug)]
enum Ordered {
    Object(Vec<(String, Ordered)>),
    Array(Vec<Ordered>),
    Scalar,
}

impl<'de> Deserialize<'de> for Ordered {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct OrderedVisitor;
        impl<'de> Visitor<'de> for OrderedVisitor {
            type Value = Ordered;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("any JSON value")
            }
            fn visit_bool<E>(self, _: bool) -> Result<Ordered, E> {
                Ok(Ordered::Scalar)
            }
            fn visit_i64<E>(self, _: i64) -> Result<Ordered, E> {
                Ok(Ordered::Scalar)
            }
            fn visit_u64<E>(self, _: u64) -> Result<Ordered, E> {
                Ok(Ordered::Scalar)
            }
            fn visit_f64<E>(self, _: f64) -> Result<Ordered, E> {
                Ok(Ordered::Scalar)
            }
            fn visit_str<E>(self, _: &str) -> Result<Ordered, E> {
                Ok(Ordered::Scalar)
            }
            fn visit_unit<E>(self) -> Result<Ordered, E> {
                Ok(Ordered::Scalar)
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Ordered, A::Error> {
                let mut items = Vec::new();
                while let Some(item) = seq.next_element()? {
                    items.push(item);
                }
                Ok(Ordered::Array(items))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Ordered, A::Error> {
                let mut entries = Vec::new();
                while let Some((key, value)) = map.next_entry()? {
                    entries.push((key, value));
                }
                Ok(Ordered::Object(entries))
            }
        }
        deserializer.deserialize_any(OrderedVisitor)
    }
}

/// Checks that `value` has the non-constant fields of definition `ty` (`pkg/Type`), in order,
/// and so on down every nested message, array elements included. Returns the number of
/// message values checked.
fn check_field_order(
    ty: &str,
    value: &Ordered,
    defs: &HashMap<String, Vec<MsgField>>,
    path: &str,
) -> usize {
    let fields = defs
        .get(ty)
        .unwrap_or_else(|| panic!("no definition for {ty}"));
    let Ordered::Object(entries) = value else {
        panic!("{path}: {ty} is not serialised as an object: {value:?}");
    };
    let keys: Vec<&str> = entries.iter().map(|(k, _)| k.as_str()).collect();
    assert_eq!(keys, field_names(fields), "{path}: fields of {ty}");
    let (package, _) = ty.split_once('/').expect("pkg/Type");
    let mut checked = 1;
    for (field, (_, field_value)) in fields.iter().filter(|f| !f.is_constant).zip(entries) {
        if field.is_primitive() {
            continue;
        }
        let field_ty = qualify(field, package);
        let base = field_ty.split('[').next().unwrap();
        let field_path = format!("{path}.{}", field.name);
        if field_ty.ends_with(']') {
            let Ordered::Array(items) = field_value else {
                panic!("{field_path}: {field_ty} is not serialised as an array");
            };
            for (i, item) in items.iter().enumerate() {
                checked += check_field_order(base, item, defs, &format!("{field_path}[{i}]"));
            }
        } else {
            checked += check_field_order(base, field_value, defs, &field_path);
        }
    }
    checked
}

/// One value of a standard type, as JSON text and as `encode_cdr` bytes.
struct Sample {
    /// `pkg/Type`.
    ty: String,
    json: String,
    cdr: Vec<u8>,
}

fn sample<M: RosMessage>(value: &M) -> Sample {
    Sample {
        ty: short_name(M::TYPE_NAME),
        json: serde_json::to_string(value).unwrap(),
        cdr: encode_cdr(value).unwrap(),
    }
}

fn stamped(frame_id: &str) -> Header {
    Header {
        stamp: Time {
            sec: -3,
            nanosec: 999_999_999,
        },
        frame_id: frame_id.into(),
    }
}

fn point(x: f64, y: f64, z: f64) -> Point {
    Point { x, y, z }
}

/// A marker with every array non-empty, strings of odd lengths, and `frame_id` at the front to
/// move everything after it across alignment boundaries.
fn sample_marker(frame_id: &str) -> Marker {
    Marker {
        header: stamped(frame_id),
        ns: "cell/robot".into(),
        id: -42,
        r#type: Marker::LINE_STRIP,
        action: Marker::DELETEALL,
        pose: Pose {
            position: point(0.5, -1.25, 3.0),
            orientation: Quaternion {
                x: 0.5,
                y: -0.5,
                z: 0.5,
                w: 0.5,
            },
        },
        scale: Vector3::new(0.01, 0.02, 0.03),
        color: ColorRGBA::new(0.1, 0.2, 0.3, 0.4),
        lifetime: Duration {
            sec: -2,
            nanosec: 300_000_000,
        },
        frame_locked: true,
        points: vec![
            point(0.0, 0.0, 0.0),
            point(1.0, 2.0, 3.0),
            point(-1.5, 1e-9, 7.25),
        ],
        colors: vec![
            ColorRGBA::new(1.0, 0.0, 0.0, 1.0),
            ColorRGBA::new(0.0, 1.0, 0.0, 0.5),
            ColorRGBA::new(0.0, 0.0, 1.0, 0.25),
        ],
        texture_resource: "embedded://t".into(),
        texture: CompressedImage {
            header: stamped("camera_optical"),
            format: "jpeg".into(),
            data: vec![0xff, 0xd8, 0xff, 0xe0, 0x00],
        },
        uv_coordinates: vec![
            UVCoordinate { u: 0.0, v: 0.125 },
            UVCoordinate { u: 1.0, v: 0.75 },
            UVCoordinate { u: 0.5, v: 1.0 },
        ],
        text: "TCP".into(),
        mesh_resource: "embedded://gripper".into(),
        mesh_file: MeshFile {
            filename: "gripper.stl".into(),
            data: b"solid g\nendsolid g\n".to_vec(),
        },
        mesh_use_embedded_materials: true,
    }
}

/// A cloud of 3 points with 2 fields (`x y z` as one float32[3] field, and a uint8 label).
fn sample_cloud(frame_id: &str) -> PointCloud2 {
    let data = [
        ([1.0f32, 2.0, 3.0], 7u8),
        ([-4.0, 5.5, 0.0], 9),
        ([0.0, 0.0, -1.0], 255),
    ]
    .iter()
    .flat_map(|(xyz, label)| {
        let mut point: Vec<u8> = xyz.iter().flat_map(|v| v.to_le_bytes()).collect();
        point.push(*label);
        point
    })
    .collect();
    PointCloud2 {
        header: stamped(frame_id),
        height: 1,
        width: 3,
        fields: vec![
            PointField::new("xyz", 0, PointField::FLOAT32, 3),
            PointField::new("label", 12, PointField::UINT8, 1),
        ],
        is_bigendian: false,
        point_step: 13,
        row_step: 39,
        data,
        is_dense: true,
    }
}

fn diagnostic_status() -> DiagnosticStatus {
    DiagnosticStatus {
        level: DiagnosticStatus::WARN,
        name: "/chronotope/mesher".into(),
        message: "2 problems".into(),
        hardware_id: String::new(),
        values: vec![KeyValue {
            key: "received".into(),
            value: "12".into(),
        }],
    }
}

/// A value of every standard type, non-trivial where the type allows it.
fn samples(frame_id: &str) -> Vec<Sample> {
    let wrench = Wrench {
        force: Vector3::new(1.0, -2.0, 9.81),
        torque: Vector3::new(0.0, 0.5, -0.25),
    };
    let pose = Pose {
        position: point(1.0, 2.0, 3.0),
        orientation: Quaternion::IDENTITY,
    };
    vec![
        sample(&Duration {
            sec: -2,
            nanosec: 300_000_000,
        }),
        sample(&ColorRGBA::new(0.25, 0.5, 0.75, 1.0)),
        sample(&Quaternion {
            x: 0.0,
            y: 0.6,
            z: 0.0,
            w: 0.8,
        }),
        sample(&Vector3::new(-1.0, 0.0, 1e300)),
        sample(&pose),
        sample(&PoseStamped {
            header: stamped(frame_id),
            pose,
        }),
        sample(&wrench),
        sample(&WrenchStamped {
            header: stamped(frame_id),
            wrench,
        }),
        sample(&KeyValue {
            key: "dropped".into(),
            value: "3".into(),
        }),
        sample(&diagnostic_status()),
        sample(&DiagnosticArray {
            header: stamped(frame_id),
            status: vec![diagnostic_status(), DiagnosticStatus::default()],
        }),
        sample(&Clock {
            clock: Time {
                sec: 17,
                nanosec: 5,
            },
        }),
        sample(&PointField::new("intensity", 16, PointField::FLOAT32, 1)),
        sample(&sample_cloud(frame_id)),
        sample(&CompressedImage {
            header: stamped(frame_id),
            format: "png".into(),
            data: vec![0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a],
        }),
        sample(&UVCoordinate { u: 0.25, v: 0.5 }),
        sample(&MeshFile {
            filename: "part.obj".into(),
            data: b"v 0 0 0\n".to_vec(),
        }),
        sample(&sample_marker(frame_id)),
        sample(&MarkerArray {
            markers: vec![
                sample_marker(frame_id),
                Marker::default(),
                sample_marker("x"),
            ],
        }),
        // Bytes above 127 are negative `int8`s: the layout is the same.
        sample(&Octomap {
            header: stamped(frame_id),
            binary: true,
            id: "ColorOcTree".into(),
            resolution: 0.05,
            data: vec![0x00, 0x80, 0xff, 0x7f, 0x03],
        }),
        sample(&RosString {
            data: "<robot name=\"r\"/>".into(),
        }),
        sample(&sample_transform("world").transform),
        sample(&TransformStamped {
            header: stamped(frame_id),
            child_frame_id: "base_link".into(),
            transform: sample_transform("x").transform,
        }),
        sample(&TFMessage {
            transforms: vec![sample_transform(frame_id), sample_transform("tool0")],
        }),
        sample(&JointState {
            header: stamped(frame_id),
            name: vec!["joint1".into(), "j2".into(), "finger".into()],
            position: vec![0.5, -1.25, 0.02],
            velocity: vec![0.1, 0.0, -0.3],
            effort: Vec::new(),
        }),
        sample(&sample_point(0.25)),
        sample(&JointTrajectory {
            header: stamped(frame_id),
            joint_names: vec!["a".into(), "joint_b".into()],
            points: vec![
                sample_point(0.0),
                JointTrajectoryPoint::default(),
                sample_point(1.5),
            ],
        }),
    ]
}

fn sample_transform(frame_id: &str) -> TransformStamped {
    TransformStamped {
        header: stamped(frame_id),
        child_frame_id: "link".into(),
        transform: Transform {
            translation: Vector3::new(0.1, -0.2, 0.3),
            rotation: Quaternion {
                x: 0.0,
                y: 0.6,
                z: 0.0,
                w: 0.8,
            },
        },
    }
}

fn sample_point(t: f64) -> JointTrajectoryPoint {
    JointTrajectoryPoint {
        positions: vec![t, -t, 0.5],
        velocities: vec![1.0, 2.0, 3.0],
        accelerations: vec![-1.0],
        effort: vec![7.5],
        time_from_start: Duration::from_nanos((t * 1e9) as i64),
    }
}

#[test]
fn std_types_fields_are_the_msg_fields_in_order_recursively() {
    let defs = definitions();
    let samples = samples("map");
    assert_eq!(samples.len(), std_messages().len());
    for sample in samples {
        let value: Ordered = serde_json::from_str(&sample.json).unwrap();
        let checked = check_field_order(&sample.ty, &value, &defs, &sample.ty);
        assert!(checked >= 1, "{}", sample.ty);
    }
    // The marker check reached the nested arrays' elements.
    let marker: Ordered =
        serde_json::from_str(&serde_json::to_string(&sample_marker("map")).unwrap()).unwrap();
    // The marker; header and stamp; pose, position, orientation; scale; color; lifetime;
    // 3 points; 3 colours; texture, its header and stamp; 3 uv coordinates; mesh_file.
    assert_eq!(
        check_field_order("visualization_msgs/Marker", &marker, &defs, "marker"),
        1 + 2 + 3 + 1 + 1 + 1 + 3 + 3 + 3 + 3 + 1
    );
}

/// The `(type, name, value)` of each constant of a `.msg` text, in order.
fn msg_constants(text: &str) -> Vec<(String, String, String)> {
    parse_msg_fields(text)
        .into_iter()
        .filter(|f| f.is_constant)
        .map(|f| (f.ty, f.name, f.value.unwrap()))
        .collect()
}

/// `(ROS type, name, value)` of Rust associated constants.
macro_rules! rust_constants {
    ($ty:ty: $($name:ident),* $(,)?) => {
        vec![$((
            ros_type_of(&<$ty>::$name).to_owned(),
            stringify!($name).to_owned(),
            <$ty>::$name.to_string(),
        )),*]
    };
}

fn ros_type_of<T>(value: &T) -> &'static str {
    match std::any::type_name_of_val(value) {
        "i8" => "int8",
        "u8" => "uint8",
        "i16" => "int16",
        "u16" => "uint16",
        "i32" => "int32",
        "u32" => "uint32",
        "i64" => "int64",
        "u64" => "uint64",
        other => panic!("no ROS type for {other}"),
    }
}

#[test]
fn std_types_constants_match() {
    let marker = rust_constants!(Marker:
        ARROW, CUBE, SPHERE, CYLINDER, LINE_STRIP, LINE_LIST, CUBE_LIST, SPHERE_LIST, POINTS,
        TEXT_VIEW_FACING, MESH_RESOURCE, TRIANGLE_LIST, ARROW_STRIP, ADD, MODIFY, DELETE,
        DELETEALL,
    );
    assert_eq!(msg_constants(Marker::DEFINITION), marker);
    let point_field = rust_constants!(PointField:
        INT8, UINT8, INT16, UINT16, INT32, UINT32, FLOAT32, FLOAT64,
    );
    assert_eq!(msg_constants(PointField::DEFINITION), point_field);
    // The constants have the type of the field they are values of.
    let field_type = |text: &str, name: &str| {
        parse_msg_fields(text)
            .into_iter()
            .find(|f| !f.is_constant && f.name == name)
            .unwrap()
            .ty
    };
    assert_eq!(field_type(Marker::DEFINITION, "type"), "int32");
    assert_eq!(field_type(Marker::DEFINITION, "action"), "int32");
    assert_eq!(field_type(PointField::DEFINITION, "datatype"), "uint8");
    // `byte` in the .msg is a `u8` in Rust.
    let levels: Vec<(String, String, String)> = rust_constants!(DiagnosticStatus:
        OK, WARN, ERROR, STALE,
    )
    .into_iter()
    .map(|(ty, name, value)| (ty.replace("uint8", "byte"), name, value))
    .collect();
    assert_eq!(msg_constants(DiagnosticStatus::DEFINITION), levels);
    assert_eq!(field_type(DiagnosticStatus::DEFINITION, "level"), "byte");
    // The other types have none.
    let with_constants = [
        Marker::TYPE_NAME,
        PointField::TYPE_NAME,
        DiagnosticStatus::TYPE_NAME,
    ];
    for message in std_messages() {
        if !with_constants.contains(&message.name) {
            assert_eq!(msg_constants(message.definition), [], "{}", message.name);
        }
    }
}

#[test]
fn std_types_cdr_is_the_layout_the_msg_files_define() {
    let defs = definitions();
    for frame_id in ["", "m", "map", "world_frame"] {
        for sample in samples(frame_id) {
            let json: Value = serde_json::from_str(&sample.json).unwrap();
            let mut body = Vec::new();
            encode_from_definition(&sample.ty, &json, &defs, &mut body);
            assert_eq!(sample.cdr[..4], [0, 1, 0, 0]);
            assert_eq!(
                sample.cdr[4..],
                body[..],
                "{} with frame_id {frame_id:?}",
                sample.ty
            );
        }
    }
}

/// The message types a definition refers to, `pkg/Type`, transitively.
fn referenced_closure(name: &str, defs: &HashMap<String, Vec<MsgField>>) -> Vec<String> {
    let mut found: Vec<String> = Vec::new();
    let mut stack = vec![name.to_owned()];
    while let Some(ty) = stack.pop() {
        let (package, _) = ty.split_once('/').unwrap();
        for field in defs[&ty]
            .iter()
            .filter(|f| !f.is_constant && !f.is_primitive())
        {
            let referenced = qualify(field, package);
            let base = referenced.split('[').next().unwrap().to_owned();
            if !found.contains(&base) {
                found.push(base.clone());
                stack.push(base);
            }
        }
    }
    found.sort_unstable();
    found
}

#[test]
fn std_types_name_their_files_and_all_their_dependencies() {
    // Parsed from the files themselves, not from what the types claim.
    let mut file_defs = HashMap::new();
    for dir in std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("msgs/deps")).unwrap() {
        let pkg_dir = dir.unwrap().path();
        let pkg = pkg_dir.file_name().unwrap().to_str().unwrap().to_owned();
        for file in std::fs::read_dir(pkg_dir.join("msg")).unwrap() {
            let path = file.unwrap().path();
            let ty = path.file_stem().unwrap().to_str().unwrap().to_owned();
            let text = std::fs::read_to_string(&path).unwrap();
            file_defs.insert(format!("{pkg}/{ty}"), parse_msg_fields(&text));
        }
    }
    for message in std_messages() {
        let (pkg, ty) = message.name.split_once("/msg/").expect("pkg/msg/Type");
        assert_eq!(
            message.definition,
            read(&format!("msgs/deps/{pkg}/msg/{ty}.msg")),
            "{}",
            message.name
        );
        let mut names = Vec::new();
        for (name, text) in &message.dependencies {
            let (pkg, ty) = name.split_once("/msg/").expect("pkg/msg/Type");
            assert_eq!(
                *text,
                read(&format!("msgs/deps/{pkg}/msg/{ty}.msg")),
                "{name}"
            );
            names.push(short_name(name));
        }
        names.sort_unstable();
        let count = names.len();
        names.dedup();
        assert_eq!(names.len(), count, "{}: listed twice", message.name);
        assert_eq!(
            names,
            referenced_closure(&short_name(message.name), &file_defs),
            "{}: dependencies() must be every type it refers to, transitively",
            message.name
        );
    }
}

#[test]
fn std_types_have_complete_ros2msg_schemas() {
    fn check<M: RosMessage>() -> String {
        try_ros2msg_schema::<M>().unwrap_or_else(|err| panic!("{}: {err}", M::TYPE_NAME))
    }
    for schema in [
        check::<Marker>(),
        check::<MarkerArray>(),
        check::<PointCloud2>(),
        check::<Octomap>(),
        check::<TFMessage>(),
        check::<PoseStamped>(),
        check::<WrenchStamped>(),
    ] {
        assert!(!schema.is_empty());
    }
    check::<Duration>();
    check::<ColorRGBA>();
    check::<Quaternion>();
    check::<Vector3>();
    check::<Pose>();
    check::<Wrench>();
    check::<PointField>();
    check::<CompressedImage>();
    check::<UVCoordinate>();
    check::<MeshFile>();
    check::<RosString>();
    check::<Transform>();
    check::<TransformStamped>();
    check::<TFMessage>();
    check::<JointState>();
    check::<JointTrajectoryPoint>();
    check::<JointTrajectory>();
    // MarkerArray's schema names each of the 12 types it uses once, after its own text.
    let schema = check::<MarkerArray>();
    let msg_lines: Vec<&str> = schema.lines().filter(|l| l.starts_with("MSG: ")).collect();
    assert_eq!(msg_lines.len(), 12, "{msg_lines:?}");
    assert!(schema.starts_with(MarkerArray::DEFINITION));
}

// ---------------------------------------------------------------------------------------------
// The suite's resolve suggestions (suite.rs)

/// A translation, a time scaling and a rotation, as the checker publishes them (finite
/// numbers where the checker puts NaN: JSON has no NaN).
fn sample_suggestions() -> ResolveSuggestions {
    let base = ResolveSuggestion {
        body_id: "/fixture/occupancy".into(),
        kind: ResolveSuggestion::KIND_TRANSLATE,
        translation: Vector3::new(0.25, -0.5, 0.125),
        time_shift_s: 0.3,
        distance: 0.6,
        distance_error_bound_m: 0.01,
        t0_s: 1.5,
        scale: 1.25,
        axis: Vector3::new(0.0, 0.6, 0.8),
        point: point(0.82, 0.64, 0.36),
        angle_rad: -0.125,
        verified_clear: true,
        episode_start_s: 2.35,
        episode_end_s: 3.9,
        unsure_start_s: vec![2.5, 3.0],
        unsure_end_s: vec![2.75, 3.25],
    };
    ResolveSuggestions {
        header: stamped("world"),
        suggestions: vec![
            base.clone(),
            ResolveSuggestion {
                kind: ResolveSuggestion::KIND_TIME_SCALE,
                verified_clear: false,
                ..base.clone()
            },
            ResolveSuggestion {
                kind: ResolveSuggestion::KIND_ROTATE,
                ..base
            },
        ],
    }
}

/// The definitions, with the suggestions' and what they use.
fn suite_definitions() -> HashMap<String, Vec<MsgField>> {
    let mut defs = definitions();
    defs.insert(
        short_name(ResolveSuggestions::TYPE_NAME),
        parse_msg_fields(ResolveSuggestions::DEFINITION),
    );
    for (name, text) in ResolveSuggestions::dependencies() {
        defs.insert(short_name(name), parse_msg_fields(text));
    }
    defs
}

#[test]
fn resolve_suggestions_are_the_msg_files_field_by_field() {
    assert_eq!(
        ResolveSuggestions::TYPE_NAME,
        "chronotope_msgs/msg/ResolveSuggestions"
    );
    assert_eq!(
        ResolveSuggestions::DEFINITION,
        read("msgs/msg/ResolveSuggestions.msg")
    );
    let mut names = Vec::new();
    for (name, text) in ResolveSuggestions::dependencies() {
        let (pkg, ty) = name.split_once("/msg/").expect("pkg/msg/Type");
        let file = if pkg == "chronotope_msgs" {
            format!("msgs/msg/{ty}.msg")
        } else {
            format!("msgs/deps/{pkg}/msg/{ty}.msg")
        };
        assert_eq!(text, read(&file), "{name}");
        names.push(short_name(name));
    }
    names.sort_unstable();
    let defs = suite_definitions();
    assert_eq!(
        names,
        referenced_closure("chronotope_msgs/ResolveSuggestions", &defs),
        "dependencies() must be every type it refers to, transitively"
    );
    // Fields in order, down to every suggestion's axis and point.
    let m = sample_suggestions();
    let value: Ordered = serde_json::from_str(&serde_json::to_string(&m).unwrap()).unwrap();
    let checked = check_field_order(
        "chronotope_msgs/ResolveSuggestions",
        &value,
        &defs,
        "suggestions",
    );
    // The message, header and stamp; per suggestion itself, translation, axis and point.
    assert_eq!(checked, 3 + 3 * 4);
    // The bytes the definitions lay out are the Rust type's.
    let json = serde_json::to_value(&m).unwrap();
    let mut body = Vec::new();
    encode_from_definition(
        "chronotope_msgs/ResolveSuggestions",
        &json,
        &defs,
        &mut body,
    );
    assert_eq!(encode_cdr(&m).unwrap()[4..], body[..]);
    // The kinds.
    let kinds = rust_constants!(ResolveSuggestion: KIND_TRANSLATE, KIND_TIME_SCALE, KIND_ROTATE);
    assert_eq!(
        msg_constants(&read("msgs/msg/ResolveSuggestion.msg")),
        kinds
    );
    try_ros2msg_schema::<ResolveSuggestions>().expect("a complete schema");
}
