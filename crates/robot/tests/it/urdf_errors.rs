//! Every refusal of a URDF: its variant, and a message that names the culprit.

use chronotope_robot::limits::Limits;
use chronotope_robot::{UrdfError, UrdfModel};

fn err(text: &str) -> UrdfError {
    UrdfModel::parse(text).expect_err("the URDF must be refused")
}

fn chain(joint_type: &str, extra: &str) -> String {
    format!(
        r#"<robot name="r">
  <link name="base"/>
  <link name="arm"/>
  <joint name="j1" type="{joint_type}">
    <parent link="base"/><child link="arm"/>{extra}
  </joint>
</robot>"#
    )
}

#[test]
fn malformed_xml_is_refused_with_its_line() {
    let e = err("<robot name=\"r\">\n<link name=\"a\">\n</robot>");
    assert!(matches!(e, UrdfError::Xml { line: 3, .. }), "{e:?}");
    assert!(e.to_string().contains("line 3"), "{e}");
}

#[test]
fn a_dtd_is_refused_as_malformed() {
    let e = err("<!DOCTYPE robot [<!ENTITY a \"b\">]><robot name=\"r\"><link name=\"a\"/></robot>");
    assert!(matches!(e, UrdfError::Xml { .. }), "{e:?}");
}

#[test]
fn a_root_other_than_robot_is_not_urdf() {
    let e = err("<model name=\"m\"/>");
    assert!(
        matches!(e, UrdfError::NotUrdf { ref found, .. } if found == "model"),
        "{e:?}"
    );
    assert!(e.to_string().contains("<model>"), "{e}");
}

#[test]
fn xacro_elements_are_refused_with_the_hint_to_run_xacro() {
    let e = err(
        r#"<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <xacro:macro name="m"/>
  <link name="a"/>
</robot>"#,
    );
    assert!(matches!(e, UrdfError::Xacro { line: 2, .. }), "{e:?}");
    let text = e.to_string();
    assert!(
        text.contains("xacro:macro") && text.contains("run xacro"),
        "{text}"
    );
}

#[test]
fn an_undeclared_xacro_prefix_is_refused_as_xacro() {
    let e = err(r#"<robot name="r"><xacro:include filename="a.xacro"/><link name="a"/></robot>"#);
    assert!(matches!(e, UrdfError::Xacro { .. }), "{e:?}");
}

#[test]
fn xacro_attributes_are_refused() {
    let e = err(
        r#"<robot name="r" xmlns:xacro="http://wiki.ros.org/xacro"><link name="a" xacro:if="1"/></robot>"#,
    );
    assert!(
        matches!(e, UrdfError::Xacro { ref what, .. } if what.contains("xacro:if")),
        "{e:?}"
    );
}

#[test]
fn substitutions_are_refused_and_quoted() {
    let e = err(&super::common::one_link(
        r#"<collision><geometry><sphere radius="${radius}"/></geometry></collision>"#,
    ));
    assert!(matches!(e, UrdfError::Xacro { .. }), "{e:?}");
    assert!(e.to_string().contains("${radius}"), "{e}");
    let e = err(&super::common::one_link(
        r#"<collision><geometry><mesh filename="$(find pkg)/m.stl"/></geometry></collision>"#,
    ));
    assert!(e.to_string().contains("$(find pkg)"), "{e}");
}

#[test]
fn the_xacro_namespace_declaration_alone_is_accepted() {
    let m = UrdfModel::parse(
        r#"<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro"><link name="a"/></robot>"#,
    )
    .unwrap();
    assert_eq!(m.links.len(), 1);
}

#[test]
fn floating_and_planar_joints_are_refused_by_name() {
    for kind in ["floating", "planar"] {
        let e = err(&chain(kind, ""));
        assert!(
            matches!(e, UrdfError::UnsupportedJoint { ref joint, kind: ref k, .. } if joint == "j1" && k == kind),
            "{e:?}"
        );
        assert!(e.to_string().contains("`j1`"), "{e}");
    }
}

#[test]
fn a_link_with_two_parents_is_refused() {
    let e = err(r#"<robot name="r">
  <link name="a"/><link name="b"/><link name="c"/>
  <joint name="ab" type="fixed"><parent link="a"/><child link="c"/></joint>
  <joint name="bc" type="fixed"><parent link="b"/><child link="c"/></joint>
</robot>"#);
    assert!(
        matches!(e, UrdfError::TwoParents { ref link, ref first, ref second } if link == "c" && first == "ab" && second == "bc"),
        "{e:?}"
    );
}

#[test]
fn a_kinematic_loop_is_refused() {
    let e = err(r#"<robot name="r">
  <link name="root"/><link name="a"/><link name="b"/>
  <joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>
  <joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint>
</robot>"#);
    assert!(
        matches!(e, UrdfError::Loop { ref link } if link == "a" || link == "b"),
        "{e:?}"
    );
    let e = err(r#"<robot name="r"><link name="a"/>
  <joint name="aa" type="fixed"><parent link="a"/><child link="a"/></joint></robot>"#);
    assert!(matches!(e, UrdfError::Loop { .. }), "{e:?}");
}

#[test]
fn several_roots_are_refused_and_listed() {
    let e = err(r#"<robot name="r"><link name="a"/><link name="b"/></robot>"#);
    assert!(
        matches!(e, UrdfError::SeveralRoots { ref roots } if roots == &["a", "b"]),
        "{e:?}"
    );
    assert!(e.to_string().contains("a, b"), "{e}");
}

#[test]
fn no_link_is_refused() {
    assert!(matches!(err(r#"<robot name="r"/>"#), UrdfError::NoLinks));
}

#[test]
fn a_mimic_of_an_unknown_joint_is_refused_by_both_names() {
    let e = err(&chain(
        "continuous",
        r#"<mimic joint="ghost" multiplier="2"/>"#,
    ));
    assert!(
        matches!(e, UrdfError::MimicUnknownJoint { ref joint, ref target } if joint == "j1" && target == "ghost"),
        "{e:?}"
    );
    assert!(e.to_string().contains("`ghost`"), "{e}");
}

#[test]
fn mimic_cycles_and_mimics_of_fixed_joints_are_refused() {
    let e = err(
        r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
  <joint name="x" type="continuous"><parent link="a"/><child link="b"/><mimic joint="y"/></joint>
  <joint name="y" type="continuous"><parent link="b"/><child link="c"/><mimic joint="x"/></joint></robot>"#,
    );
    assert!(matches!(e, UrdfError::MimicCycle { .. }), "{e:?}");
    let e = err(
        r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
  <joint name="x" type="fixed"><parent link="a"/><child link="b"/></joint>
  <joint name="y" type="continuous"><parent link="b"/><child link="c"/><mimic joint="x"/></joint></robot>"#,
    );
    assert!(
        matches!(e, UrdfError::MimicOfFixed { ref target, .. } if target == "x"),
        "{e:?}"
    );
}

#[test]
fn a_zero_axis_is_refused_by_joint() {
    let e = err(&chain("continuous", r#"<axis xyz="0 0 0"/>"#));
    assert!(
        matches!(e, UrdfError::ZeroAxis { ref joint, .. } if joint == "j1"),
        "{e:?}"
    );
}

#[test]
fn revolute_joints_need_limits_in_order() {
    let e = err(&chain("revolute", ""));
    assert!(
        matches!(e, UrdfError::BadLimits { ref joint, .. } if joint == "j1"),
        "{e:?}"
    );
    let e = err(&chain(
        "revolute",
        r#"<limit lower="1" upper="-1" effort="1" velocity="1"/>"#,
    ));
    assert!(
        e.to_string()
            .contains("lower limit 1 is above upper limit -1"),
        "{e}"
    );
}

#[test]
fn a_joint_naming_an_unknown_link_is_refused() {
    let e = err(r#"<robot name="r"><link name="a"/>
  <joint name="j" type="fixed"><parent link="a"/><child link="nowhere"/></joint></robot>"#);
    assert!(
        matches!(e, UrdfError::UnknownLink { ref joint, role: "child", ref link } if joint == "j" && link == "nowhere"),
        "{e:?}"
    );
}

#[test]
fn duplicate_names_are_refused_with_both_lines() {
    let e = err("<robot name=\"r\">\n<link name=\"a\"/>\n<link name=\"a\"/>\n</robot>");
    assert!(
        matches!(e, UrdfError::Duplicate { what: "link", ref name, first_line: 2, line: 3 } if name == "a"),
        "{e:?}"
    );
}

fn geometry_err(geometry: &str) -> UrdfError {
    err(&super::common::one_link(&format!(
        "<collision><geometry>{geometry}</geometry></collision>"
    )))
}

#[test]
fn zero_negative_and_non_finite_sizes_are_refused_by_attribute() {
    let cases: &[(&str, &str, &str)] = &[
        (r#"<box size="0.1 0 0.1"/>"#, "size", "zero"),
        (r#"<box size="0.1 -1 0.1"/>"#, "size", "negative"),
        (r#"<box size="0.1 0.1"/>"#, "size", "fewer"),
        (r#"<sphere radius="NaN"/>"#, "radius", "not finite"),
        (r#"<sphere radius="-0.5"/>"#, "radius", "negative"),
        (
            r#"<cylinder radius="0.1" length="inf"/>"#,
            "length",
            "not finite",
        ),
        (r#"<cylinder radius="0.1" length="0"/>"#, "length", "zero"),
        (r#"<mesh filename="a.stl" scale="1 0 1"/>"#, "scale", "zero"),
        (
            r#"<mesh filename="a.stl" scale="1 -1 1"/>"#,
            "scale",
            "negative",
        ),
        (r#"<sphere radius="abc"/>"#, "radius", "not a number"),
    ];
    for (geometry, attribute, why) in cases {
        let e = geometry_err(geometry);
        assert!(
            matches!(e, UrdfError::BadValue { attribute: a, .. } if a == *attribute),
            "{geometry}: {e:?}"
        );
        let text = e.to_string();
        assert!(
            text.contains(attribute) && text.contains(why),
            "{geometry}: {text}"
        );
    }
}

#[test]
fn non_finite_origins_are_refused() {
    let e = err(&super::common::one_link(
        r#"<collision><origin xyz="0 inf 0"/><geometry><sphere radius="1"/></geometry></collision>"#,
    ));
    assert!(
        matches!(
            e,
            UrdfError::BadValue {
                attribute: "xyz",
                why: "not finite",
                ..
            }
        ),
        "{e:?}"
    );
}

#[test]
fn unsupported_geometry_is_refused_by_link() {
    let e = geometry_err(r#"<capsule radius="1" length="1"/>"#);
    assert!(
        matches!(e, UrdfError::UnsupportedGeometry { ref link, ref geometry, .. } if link == "base" && geometry == "capsule"),
        "{e:?}"
    );
}

#[test]
fn a_missing_attribute_is_named() {
    let e = geometry_err(r#"<cylinder radius="1"/>"#);
    assert!(
        matches!(
            e,
            UrdfError::MissingAttribute {
                attribute: "length",
                ..
            }
        ),
        "{e:?}"
    );
}

#[test]
fn limits_refuse_by_name() {
    let limits = Limits {
        urdf_bytes: 10,
        ..Limits::default()
    };
    let e = UrdfModel::parse_with_limits(r#"<robot name="r"><link name="a"/></robot>"#, &limits)
        .unwrap_err();
    assert!(e.to_string().contains("MAX_URDF_BYTES = 10"), "{e}");
    let limits = Limits {
        links: 2,
        ..Limits::default()
    };
    let e = UrdfModel::parse_with_limits(
        r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/></robot>"#,
        &limits,
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            UrdfError::TooMany {
                count: 3,
                limit: 2,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("MAX_LINKS = 2"), "{e}");
}

#[test]
fn every_supported_element_is_read() {
    let m = UrdfModel::parse(r#"<robot name="r">
  <link name="base">
    <visual><geometry><box size="9 9 9"/></geometry></visual>
    <collision name="c1"><origin xyz="1 2 3" rpy="0 0 1.5707963267948966"/><geometry><box size="1 2 3"/></geometry></collision>
    <collision><geometry><mesh filename="package://p/m.stl" scale="1 2 3"/></geometry></collision>
  </link>
  <link name="arm"/>
  <joint name="j" type="prismatic"><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 2"/><limit lower="-0.5" upper="0.5" effort="1" velocity="1"/></joint>
  <gazebo reference="base"><material>x</material></gazebo>
</robot>"#)
    .unwrap();
    assert_eq!(m.links[0].collisions.len(), 2);
    assert_eq!(m.links[0].collisions[0].name.as_deref(), Some("c1"));
    let j = &m.joints[0];
    assert_eq!(j.axis.into_inner(), nalgebra::Vector3::z());
    assert_eq!(j.limits.unwrap().lower, -0.5);
    match &m.links[0].collisions[1].geometry {
        chronotope_robot::urdf::Geometry::Mesh { filename, scale } => {
            assert_eq!(filename, "package://p/m.stl");
            assert_eq!(scale, &[1.0, 2.0, 3.0]);
        }
        g => panic!("{g:?}"),
    }
}
