//! Forward kinematics against closed forms.

use chronotope_robot::{BasePose, Kinematics, LinkPoses, UrdfModel};
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;

fn kin(text: &str) -> Kinematics {
    Kinematics::new(UrdfModel::parse(text).unwrap())
}

fn link_pos(k: &Kinematics, poses: &LinkPoses, name: &str) -> Vector3<f64> {
    poses
        .get(k.model().link_index(name).unwrap())
        .translation
        .vector
}

/// R = Rz(yaw) Ry(pitch) Rx(roll), written out.
fn rpy_matrix(r: f64, p: f64, y: f64) -> Matrix3<f64> {
    let (sr, cr) = r.sin_cos();
    let (sp, cp) = p.sin_cos();
    let (sy, cy) = y.sin_cos();
    let rx = Matrix3::new(1.0, 0.0, 0.0, 0.0, cr, -sr, 0.0, sr, cr);
    let ry = Matrix3::new(cp, 0.0, sp, 0.0, 1.0, 0.0, -sp, 0.0, cp);
    let rz = Matrix3::new(cy, -sy, 0.0, sy, cy, 0.0, 0.0, 0.0, 1.0);
    rz * ry * rx
}

const PLANAR: &str = r#"<robot name="planar">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="tip"/>
  <joint name="q1" type="continuous"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/></joint>
  <joint name="q2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.7 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="t" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.4 0 0"/></joint>
</robot>"#;

proptest! {
    #[test]
    fn a_two_link_planar_arm_matches_its_closed_form(q1 in -4.0..4.0f64, q2 in -4.0..4.0f64) {
        let k = kin(PLANAR);
        let mut poses = LinkPoses::new();
        k.forward(&[q1, q2], &BasePose::IDENTITY, &mut poses);
        let tip = link_pos(&k, &poses, "tip");
        let x = 0.7 * q1.cos() + 0.4 * (q1 + q2).cos();
        let y = 0.7 * q1.sin() + 0.4 * (q1 + q2).sin();
        prop_assert!((tip - Vector3::new(x, y, 0.0)).norm() < 1e-12);
        let r = poses.get(k.model().link_index("tip").unwrap()).rotation.to_rotation_matrix();
        prop_assert!((r.matrix() - rpy_matrix(0.0, 0.0, q1 + q2)).norm() < 1e-12);
    }

    #[test]
    fn the_base_pose_is_rz_ry_rx_then_translation(
        x in -2.0..2.0f64, y in -2.0..2.0f64, z in -2.0..2.0f64,
        roll in -3.0..3.0f64, pitch in -1.5..1.5f64, yaw in -3.0..3.0f64,
        q1 in -3.0..3.0f64,
    ) {
        let k = kin(PLANAR);
        let base = BasePose { x, y, z, roll, pitch, yaw };
        let mut poses = LinkPoses::new();
        k.forward(&[q1, 0.0], &base, &mut poses);
        let r = rpy_matrix(roll, pitch, yaw);
        let local = Vector3::new(1.1 * q1.cos(), 1.1 * q1.sin(), 0.0);
        let expect = r * local + Vector3::new(x, y, z);
        prop_assert!((link_pos(&k, &poses, "tip") - expect).norm() < 1e-12);
        let root = poses.get(k.model().root());
        prop_assert!((root.rotation.to_rotation_matrix().matrix() - r).norm() < 1e-12);
    }
}

#[test]
fn a_prismatic_joint_slides_along_its_axis_in_the_joint_frame() {
    let k = kin(r#"<robot name="p"><link name="a"/><link name="b"/>
  <joint name="s" type="prismatic"><parent link="a"/><child link="b"/>
    <origin xyz="1 0 0" rpy="0 0 1.5707963267948966"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/></joint></robot>"#);
    let mut poses = LinkPoses::new();
    k.forward(&[0.25], &BasePose::IDENTITY, &mut poses);
    // The joint frame is turned 90° about z: its x is the parent's y.
    assert!((link_pos(&k, &poses, "b") - Vector3::new(1.0, 0.25, 0.0)).norm() < 1e-12);
}

#[test]
fn mimic_joints_follow_with_multiplier_and_offset_and_chains_compose() {
    let k = kin(
        r#"<robot name="m"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>
  <joint name="lead" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="follow" type="prismatic"><parent link="a"/><child link="c"/><axis xyz="0 1 0"/>
    <limit lower="-5" upper="5" effort="1" velocity="1"/><mimic joint="lead" multiplier="-2" offset="0.5"/></joint>
  <joint name="follow2" type="prismatic"><parent link="c"/><child link="d"/><axis xyz="0 0 1"/>
    <limit lower="-5" upper="5" effort="1" velocity="1"/><mimic joint="follow" multiplier="3" offset="1"/></joint>
</robot>"#,
    );
    assert_eq!(k.joint_names(), ["lead"]);
    assert!(k.is_mimic("follow") && k.is_mimic("follow2"));
    let mut poses = LinkPoses::new();
    k.forward(&[0.3], &BasePose::IDENTITY, &mut poses);
    let f = -2.0 * 0.3 + 0.5;
    let f2 = 3.0 * f + 1.0;
    assert!((link_pos(&k, &poses, "c") - Vector3::new(0.0, f, 0.0)).norm() < 1e-12);
    assert!((link_pos(&k, &poses, "d") - Vector3::new(0.0, f, f2)).norm() < 1e-12);
}

#[test]
fn fixed_chains_compose_their_origins() {
    let (o1, r1) = ([0.1, -0.2, 0.3], [0.3, -0.7, 1.1]);
    let (o2, r2) = ([-0.5, 0.25, 1.0], [-1.2, 0.4, 2.5]);
    let k = kin(&format!(
        r#"<robot name="f"><link name="a"/><link name="b"/><link name="c"/>
  <joint name="ab" type="fixed"><parent link="a"/><child link="b"/>
    <origin xyz="{} {} {}" rpy="{} {} {}"/></joint>
  <joint name="bc" type="fixed"><parent link="b"/><child link="c"/>
    <origin xyz="{} {} {}" rpy="{} {} {}"/></joint></robot>"#,
        o1[0], o1[1], o1[2], r1[0], r1[1], r1[2], o2[0], o2[1], o2[2], r2[0], r2[1], r2[2]
    ));
    assert_eq!(k.dof(), 0);
    let mut poses = LinkPoses::new();
    k.forward(&[], &BasePose::IDENTITY, &mut poses);
    let (m1, m2) = (
        rpy_matrix(r1[0], r1[1], r1[2]),
        rpy_matrix(r2[0], r2[1], r2[2]),
    );
    let expect_r = m1 * m2;
    let expect_t = Vector3::from(o1) + m1 * Vector3::from(o2);
    let c = poses.get(2);
    assert!((c.rotation.to_rotation_matrix().matrix() - expect_r).norm() < 1e-12);
    assert!((c.translation.vector - expect_t).norm() < 1e-12);
}

#[test]
fn positions_beyond_limits_are_kept_and_reported() {
    let k = kin(PLANAR);
    let mut out = Vec::new();
    k.limit_violations(&[10.0, 3.5], &mut out);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].joint, "q2");
    assert_eq!(out[0].position, 3.5);
    let mut poses = LinkPoses::new();
    k.forward(&[0.0, 3.5], &BasePose::IDENTITY, &mut poses);
    let tip = link_pos(&k, &poses, "tip");
    assert!(
        (tip.x - (0.7 + 0.4 * 3.5f64.cos())).abs() < 1e-12,
        "not clamped"
    );
}
