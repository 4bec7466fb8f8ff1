//! Merging partial JointState messages, refusals, and interpolation to a frame time.

use chronotope_robot::{HistoryBounds, JointStateError, JointStateHistory, Kinematics, UrdfModel};

const ARM: &str = r#"<robot name="arm">
  <link name="a"/><link name="b"/><link name="c"/><link name="d"/>
  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="continuous"><parent link="b"/><child link="c"/><axis xyz="0 1 0"/></joint>
  <joint name="m" type="continuous"><parent link="c"/><child link="d"/><mimic joint="j2"/></joint>
</robot>"#;

fn history(bounds: HistoryBounds) -> JointStateHistory {
    JointStateHistory::new(&Kinematics::new(UrdfModel::parse(ARM).unwrap()), bounds)
}

const S: i64 = 1_000_000_000;

#[test]
fn partial_messages_merge_by_name() {
    let mut h = history(HistoryBounds::default());
    let mut q = [0.0; 2];
    assert!(
        matches!(h.latest(&mut q), Err(JointStateError::NotKnown { ref joint, .. }) if joint == "j1")
    );
    h.merge(S, &["j1"], &[0.5]).unwrap();
    let e = h.latest(&mut q).unwrap_err();
    assert!(e.to_string().contains("`j2`"), "{e}");
    h.merge(2 * S, &["j2"], &[-0.25]).unwrap();
    h.latest(&mut q).unwrap();
    assert_eq!(q, [0.5, -0.25]);
    h.merge(3 * S, &["j2", "j1"], &[1.0, 0.75]).unwrap();
    h.latest(&mut q).unwrap();
    assert_eq!(q, [0.75, 1.0]);
}

#[test]
fn mimic_names_are_accepted_and_ignored() {
    let mut h = history(HistoryBounds::default());
    let m = h.merge(S, &["j1", "m", "j2"], &[0.1, 99.0, 0.2]).unwrap();
    assert_eq!((m.applied, m.ignored_mimic), (2, 1));
}

#[test]
fn bad_messages_are_refused_whole_and_counted() {
    let mut h = history(HistoryBounds::default());
    h.merge(S, &["j1", "j2"], &[0.1, 0.2]).unwrap();
    let e = h.merge(2 * S, &["j1", "j2"], &[0.3]).unwrap_err();
    assert_eq!(
        e,
        JointStateError::LengthMismatch {
            names: 2,
            positions: 1
        }
    );
    let e = h
        .merge(2 * S, &["j1", "elbow", "wrist"], &[0.3, 0.0, 0.0])
        .unwrap_err();
    assert_eq!(
        e,
        JointStateError::UnknownJoints {
            names: vec!["elbow".into(), "wrist".into()]
        }
    );
    assert!(e.to_string().contains("elbow, wrist"), "{e}");
    let e = h.merge(2 * S, &["j1", "j2"], &[0.3, f64::NAN]).unwrap_err();
    assert!(
        matches!(e, JointStateError::NonFinite { ref joint, .. } if joint == "j2"),
        "{e:?}"
    );
    let e = h.merge(2 * S, &["j1", "j1"], &[0.3, 0.4]).unwrap_err();
    assert!(matches!(e, JointStateError::DuplicateJoint { ref joint } if joint == "j1"));
    let e = h.merge(S / 2, &["j2"], &[0.3]).unwrap_err();
    assert!(matches!(e, JointStateError::OutOfOrder { ref joint, .. } if joint == "j2"));
    // None of the refused messages changed anything: j1 is still 0.1.
    let mut q = [0.0; 2];
    h.latest(&mut q).unwrap();
    assert_eq!(q, [0.1, 0.2]);
    let st = h.stats();
    assert_eq!((st.applied, st.refused, st.non_finite), (1, 5, 1));
}

#[test]
fn positions_beyond_limits_are_kept_and_counted() {
    let mut h = history(HistoryBounds::default());
    let m = h.merge(S, &["j1", "j2"], &[2.0, 100.0]).unwrap();
    assert_eq!(m.beyond_limits, 1); // j2 is continuous: no limit
    let mut q = [0.0; 2];
    h.latest(&mut q).unwrap();
    assert_eq!(q, [2.0, 100.0]);
    assert_eq!(h.stats().beyond_limits, 1);
}

#[test]
fn positions_interpolate_per_joint_and_hold_after_the_last_sample() {
    let mut h = history(HistoryBounds::default());
    h.merge(S, &["j1", "j2"], &[0.0, 0.0]).unwrap();
    h.merge(2 * S, &["j1"], &[1.0]).unwrap();
    h.merge(3 * S, &["j2"], &[-2.0]).unwrap();
    let mut q = [0.0; 2];
    let how = h.positions_at(S + S / 4, &mut q).unwrap();
    assert_eq!(how.held, 0);
    assert!(
        (q[0] - 0.25).abs() < 1e-15 && (q[1] + 0.25).abs() < 1e-15,
        "{q:?}"
    );
    // j1's last sample is at 2 s: held from there.
    let how = h.positions_at(S * 5 / 2, &mut q).unwrap();
    assert_eq!((how.held, how.max_hold), (1, S / 2));
    assert!(
        (q[0] - 1.0).abs() < 1e-15 && (q[1] + 1.5).abs() < 1e-15,
        "{q:?}"
    );
    let e = h.positions_at(S / 2, &mut q).unwrap_err();
    assert!(
        matches!(e, JointStateError::NotKnown { first: Some(f), .. } if f == S),
        "{e:?}"
    );
}

#[test]
fn the_history_is_bounded_by_window_and_count() {
    let mut h = history(HistoryBounds {
        window: 2 * S,
        max_samples: 1000,
    });
    for i in 0..100 {
        h.merge(i * S / 10, &["j1", "j2"], &[i as f64 * 0.001, 0.0])
            .unwrap();
    }
    let mut q = [0.0; 2];
    // Newest is 9.9 s; the window keeps from 7.9 s (one sample at or before it).
    assert!(h.positions_at(79 * S / 10, &mut q).is_ok());
    assert!(h.positions_at(7 * S, &mut q).is_err());
    let mut h = history(HistoryBounds {
        window: 100 * S,
        max_samples: 5,
    });
    for i in 0..20 {
        h.merge(i * S, &["j1", "j2"], &[0.0, 0.0]).unwrap();
    }
    assert!(h.positions_at(15 * S, &mut q).is_ok());
    assert!(h.positions_at(14 * S, &mut q).is_err());
    assert_eq!(h.stats().dropped, 2 * 15);
}
