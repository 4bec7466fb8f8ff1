//! Trajectory sampling as joint_trajectory_controller's splines, refusals, and retiming.

use chronotope_robot::trajectory::{Segment, Spline};
use chronotope_robot::{JointTrajectory, Sample, StartState, TrajectoryError, TrajectoryPoint};
use proptest::prelude::*;

const S: i64 = 1_000_000_000;

fn point(t: f64, p: &[f64], v: &[f64], a: &[f64]) -> TrajectoryPoint {
    TrajectoryPoint {
        positions: p.to_vec(),
        velocities: v.to_vec(),
        accelerations: a.to_vec(),
        time_from_start: t,
    }
}

fn names(n: usize) -> Vec<String> {
    (0..n).map(|i| format!("j{i}")).collect()
}

fn sample(t: &JointTrajectory, at: i64) -> Sample {
    let mut s = Sample::default();
    t.sample(at, None, &mut s).unwrap();
    s
}

/// Checks the values at both ends of segment 0 (the end approached 1 ns before it) and
/// that velocity and acceleration are the derivatives of the sampled positions.
fn check_segment(t: &JointTrajectory, order: usize) {
    let (a, b) = (&t.points()[0], &t.points()[1]);
    let (ta, tb) = (t.point_time(0), t.point_time(1));
    let s = sample(t, ta);
    assert!((s.positions[0] - a.positions[0]).abs() < 1e-12);
    let e = sample(t, tb - 1);
    assert!((e.positions[0] - b.positions[0]).abs() < 1e-6, "{e:?}");
    if order >= 1 {
        assert!((s.velocities[0] - a.velocities[0]).abs() < 1e-9);
        assert!((e.velocities[0] - b.velocities[0]).abs() < 1e-5, "{e:?}");
    }
    if order >= 2 {
        assert!((s.accelerations[0] - a.accelerations[0]).abs() < 1e-9);
        assert!(
            (e.accelerations[0] - b.accelerations[0]).abs() < 1e-4,
            "{e:?}"
        );
    }
    // Derivatives by central differences at an interior time.
    let mid = ta + (tb - ta) / 3;
    let d = 1000; // 1 µs
    let (m, p, n) = (sample(t, mid), sample(t, mid + d), sample(t, mid - d));
    let h = d as f64 * 1e-9;
    let v = (p.positions[0] - n.positions[0]) / (2.0 * h);
    assert!(
        (v - m.velocities[0]).abs() < 1e-5 * (1.0 + v.abs()),
        "{v} vs {}",
        m.velocities[0]
    );
    if order >= 1 {
        let acc = (p.velocities[0] - n.velocities[0]) / (2.0 * h);
        assert!(
            (acc - m.accelerations[0]).abs() < 1e-4 * (1.0 + acc.abs()),
            "{acc} vs {}",
            m.accelerations[0]
        );
    }
}

#[test]
fn positions_only_interpolate_linearly() {
    let t = JointTrajectory::new(
        10 * S,
        names(1),
        vec![point(1.0, &[1.0], &[], &[]), point(3.0, &[5.0], &[], &[])],
    )
    .unwrap();
    assert_eq!(t.spline(0), Spline::Linear);
    check_segment(&t, 0);
    assert!((sample(&t, 12 * S).positions[0] - 3.0).abs() < 1e-12);
    assert_eq!(sample(&t, 12 * S).velocities[0], 2.0);
}

#[test]
fn positions_and_velocities_interpolate_as_cubic_hermite() {
    let t = JointTrajectory::new(
        0,
        names(1),
        vec![
            point(0.5, &[1.0], &[2.0], &[]),
            point(2.0, &[-1.0], &[0.5], &[]),
        ],
    )
    .unwrap();
    assert_eq!(t.spline(0), Spline::Cubic);
    check_segment(&t, 1);
}

#[test]
fn positions_velocities_and_accelerations_interpolate_as_quintic() {
    let t = JointTrajectory::new(
        0,
        names(1),
        vec![
            point(0.0, &[0.0], &[1.0], &[-3.0]),
            point(1.5, &[2.0], &[-0.5], &[4.0]),
        ],
    )
    .unwrap();
    assert_eq!(t.spline(0), Spline::Quintic);
    check_segment(&t, 2);
}

#[test]
fn mixed_points_use_the_lower_spline() {
    let t = JointTrajectory::new(
        0,
        names(1),
        vec![
            point(0.0, &[0.0], &[1.0], &[0.0]),
            point(1.0, &[1.0], &[1.0], &[]),
            point(2.0, &[2.0], &[], &[]),
        ],
    )
    .unwrap();
    assert_eq!((t.spline(0), t.spline(1)), (Spline::Cubic, Spline::Linear));
}

#[test]
fn the_last_point_is_held_after_the_end() {
    let t = JointTrajectory::new(
        0,
        names(2),
        vec![
            point(0.0, &[0.0, 0.0], &[], &[]),
            point(1.0, &[1.0, 2.0], &[0.1, 0.2], &[]),
        ],
    )
    .unwrap();
    let mut s = Sample::default();
    assert_eq!(t.sample(5 * S, None, &mut s).unwrap(), Segment::AfterLast);
    assert_eq!(
        (s.positions.as_slice(), s.velocities.as_slice()),
        ([1.0, 2.0].as_slice(), [0.1, 0.2].as_slice())
    );
    assert_eq!(s.accelerations, [0.0, 0.0]);
}

#[test]
fn before_the_first_point_it_interpolates_from_the_start_state() {
    let t = JointTrajectory::new(
        10 * S,
        names(1),
        vec![point(2.0, &[4.0], &[], &[]), point(3.0, &[5.0], &[], &[])],
    )
    .unwrap();
    let state = StartState {
        time: 11 * S,
        point: point(0.0, &[2.0], &[], &[]),
    };
    let mut s = Sample::default();
    assert_eq!(
        t.sample(11 * S + S / 2, Some(&state), &mut s).unwrap(),
        Segment::BeforeFirst
    );
    assert!((s.positions[0] - 3.0).abs() < 1e-12, "{s:?}");
    let e = t.sample(11 * S, None, &mut s).unwrap_err();
    assert!(matches!(e, TrajectoryError::NoStartState { .. }), "{e:?}");
    let e = t.sample(10 * S, Some(&state), &mut s).unwrap_err();
    assert_eq!(
        e,
        TrajectoryError::BeforeStart {
            time: 10 * S,
            start: 11 * S
        }
    );
}

#[test]
fn bad_trajectories_are_refused() {
    let p = |t| point(t, &[0.0, 0.0], &[], &[]);
    let e = JointTrajectory::new(0, names(2), vec![p(1.0), p(1.0)]).unwrap_err();
    assert!(
        matches!(e, TrajectoryError::NotIncreasing { point: 1, .. }),
        "{e:?}"
    );
    let e =
        JointTrajectory::new(0, names(2), vec![p(1.0), point(2.0, &[0.0], &[], &[])]).unwrap_err();
    assert!(
        matches!(
            e,
            TrajectoryError::LengthMismatch {
                point: 1,
                field: "positions",
                len: 1,
                joints: 2
            }
        ),
        "{e:?}"
    );
    let e =
        JointTrajectory::new(0, names(2), vec![point(0.0, &[0.0, 0.0], &[0.0], &[])]).unwrap_err();
    assert!(
        matches!(
            e,
            TrajectoryError::LengthMismatch {
                field: "velocities",
                ..
            }
        ),
        "{e:?}"
    );
    let e = JointTrajectory::new(
        0,
        names(2),
        vec![point(0.0, &[0.0, f64::INFINITY], &[], &[])],
    )
    .unwrap_err();
    assert!(
        matches!(e, TrajectoryError::NonFinite { ref joint, .. } if joint == "j1"),
        "{e:?}"
    );
    let e = JointTrajectory::new(0, names(2), vec![p(f64::NAN)]).unwrap_err();
    assert!(
        matches!(
            e,
            TrajectoryError::NonFinite {
                field: "time_from_start",
                ..
            }
        ),
        "{e:?}"
    );
    let e = JointTrajectory::new(0, names(2), vec![point(0.0, &[0.0, 0.0], &[], &[1.0, 1.0])])
        .unwrap_err();
    assert!(
        matches!(
            e,
            TrajectoryError::AccelerationsWithoutVelocities { point: 0 }
        ),
        "{e:?}"
    );
    let e = JointTrajectory::new(0, vec!["a".into(), "a".into()], vec![p(0.0)]).unwrap_err();
    assert_eq!(e, TrajectoryError::DuplicateJoint("a".into()));
    assert!(JointTrajectory::new(0, names(2), vec![]).is_err());
    let t = JointTrajectory::new(0, names(2), vec![p(0.0)]).unwrap();
    assert_eq!(
        t.retimed(0, 0.0).unwrap_err(),
        TrajectoryError::BadScale(0.0)
    );
    assert!(t.retimed(0, f64::NAN).is_err());
}

fn arb_trajectory() -> impl Strategy<Value = (JointTrajectory, StartState)> {
    (
        0usize..3,
        prop::collection::vec(
            (0.2..2.0f64, -3.0..3.0f64, -2.0..2.0f64, -5.0..5.0f64),
            2..5,
        ),
        -5.0..5.0f64,
    )
        .prop_map(|(mode, pts, q0)| {
            let mut t = 0.5;
            let points = pts
                .iter()
                .map(|&(dt, p, v, a)| {
                    t += dt;
                    let v: Vec<f64> = if mode >= 1 { vec![v] } else { vec![] };
                    let a: Vec<f64> = if mode >= 2 { vec![a] } else { vec![] };
                    point(t, &[p], &v, &a)
                })
                .collect();
            let state = StartState {
                time: 3 * S,
                point: point(0.0, &[q0], &[], &[]),
            };
            (
                JointTrajectory::new(3 * S, names(1), points).unwrap(),
                state,
            )
        })
}

proptest! {
    #[test]
    fn retiming_samples_the_same_positions_at_mapped_times(
        (traj, state) in arb_trajectory(),
        t0 in 0i64..10 * S,
        scale in 0.25..4.0f64,
        at in 0i64..12 * S,
    ) {
        let retimed = traj.retimed(t0, scale).unwrap();
        let state2 = state.retimed(t0, scale);
        let at = at.max(state.time);
        let mapped = t0 + ((at - t0) as f64 * scale).round() as i64;
        let (mut a, mut b) = (Sample::default(), Sample::default());
        // (At a knot the two may pick neighbouring segments; positions are continuous.)
        traj.sample(at, Some(&state), &mut a).unwrap();
        retimed.sample(mapped, Some(&state2), &mut b).unwrap();
        // Times round to the nanosecond: allow what 2 ns of motion moves.
        let tol = 1e-9 * (1.0 + 10.0 * a.velocities[0].abs().max(1.0));
        prop_assert!((a.positions[0] - b.positions[0]).abs() < tol, "{:?} vs {:?}", a, b);
    }

    #[test]
    fn retiming_by_one_is_the_identity((traj, _) in arb_trajectory(), t0 in 0i64..10 * S) {
        prop_assert_eq!(traj.retimed(t0, 1.0).unwrap(), traj);
    }
}
