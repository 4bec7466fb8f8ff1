//! A `trajectory_msgs/JointTrajectory` sampled at any time as ros2_control's
//! joint_trajectory_controller does with its default `interpolation_method: splines`, and
//! retimed by a time scaling.
//!
//! Per segment between two points: linear when either lacks velocities, cubic Hermite when
//! both have positions and velocities, quintic when both also have accelerations. Before the
//! first point the controller interpolates from the state it had when the trajectory arrived
//! (its time and point are given by the caller as a [`StartState`]); after the last point it
//! holds the last point (missing velocities and accelerations read as zero). The polynomial
//! forms are the usual Hermite ones, written in the segment's local time τ ∈ [0, T].

use crate::joint_state::Stamp;
use crate::limits::MAX_TRAJECTORY_POINTS;

/// One point of a trajectory.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TrajectoryPoint {
    /// Positions, one per joint.
    pub positions: Vec<f64>,
    /// Velocities: empty or one per joint.
    pub velocities: Vec<f64>,
    /// Accelerations: empty or one per joint (only with velocities).
    pub accelerations: Vec<f64>,
    /// Time from the trajectory's start (s).
    pub time_from_start: f64,
}

/// The controller's state when the trajectory arrived: what it interpolates from until the
/// first point's time.
#[derive(Clone, Debug, PartialEq)]
pub struct StartState {
    /// When the trajectory arrived (ns).
    pub time: Stamp,
    /// The state then (its `time_from_start` is not read).
    pub point: TrajectoryPoint,
}

impl StartState {
    /// The same state under the time scaling of [`JointTrajectory::retimed`].
    pub fn retimed(&self, t0: Stamp, scale: f64) -> StartState {
        StartState {
            time: map_stamp(self.time, t0, scale),
            point: scale_point(&self.point, scale),
        }
    }
}

/// Positions, velocities and accelerations at one time.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sample {
    /// Positions, one per joint.
    pub positions: Vec<f64>,
    /// Velocities.
    pub velocities: Vec<f64>,
    /// Accelerations.
    pub accelerations: Vec<f64>,
}

/// Which part of the trajectory a sample came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Segment {
    /// Between the start state and the first point.
    BeforeFirst,
    /// Between points `i` and `i + 1`.
    Between(usize),
    /// After the last point: held.
    AfterLast,
}

/// The interpolation used on a segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spline {
    /// Positions only.
    Linear,
    /// Positions and velocities.
    Cubic,
    /// Positions, velocities and accelerations.
    Quintic,
}

/// A refused trajectory, or a time that cannot be sampled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrajectoryError {
    /// No joint names, or no points.
    #[error("the trajectory has no {0}")]
    Empty(&'static str),
    /// More points than `MAX_TRAJECTORY_POINTS`.
    #[error("the trajectory has {points} points, over MAX_TRAJECTORY_POINTS = {limit}")]
    TooManyPoints {
        /// Points given.
        points: usize,
        /// The limit.
        limit: usize,
    },
    /// A joint named twice.
    #[error("the trajectory names joint `{0}` twice")]
    DuplicateJoint(String),
    /// An array whose length is not the number of joints.
    #[error("point {point}: `{field}` has {len} values for {joints} joints")]
    LengthMismatch {
        /// The point's index.
        point: usize,
        /// `positions`, `velocities` or `accelerations`.
        field: &'static str,
        /// Its length.
        len: usize,
        /// Joints named.
        joints: usize,
    },
    /// Accelerations given without velocities.
    #[error("point {point} has accelerations but no velocities")]
    AccelerationsWithoutVelocities {
        /// The point's index.
        point: usize,
    },
    /// A NaN or infinite value.
    #[error("point {point}: `{field}` of joint `{joint}` is not finite")]
    NonFinite {
        /// The point's index (`usize::MAX` for the start state).
        point: usize,
        /// The field.
        field: &'static str,
        /// The joint (or `time_from_start`).
        joint: String,
    },
    /// A `time_from_start` not after the previous point's.
    #[error("point {point}: time_from_start {time} s does not strictly increase (previous {previous} s)")]
    NotIncreasing {
        /// The point's index.
        point: usize,
        /// Its time.
        time: f64,
        /// The previous point's.
        previous: f64,
    },
    /// A time scaling that is not a positive finite number.
    #[error("time scale {0} is not a positive finite number")]
    BadScale(f64),
    /// A time before the first point with no start state to interpolate from.
    #[error("time {time} ns is before the first point ({first} ns) and no start state was given")]
    NoStartState {
        /// The time asked.
        time: Stamp,
        /// The first point's time.
        first: Stamp,
    },
    /// A time before the start state's.
    #[error("time {time} ns is before the start state's time {start} ns")]
    BeforeStart {
        /// The time asked.
        time: Stamp,
        /// The start state's time.
        start: Stamp,
    },
}

/// A checked joint trajectory with its start stamp.
#[derive(Clone, Debug, PartialEq)]
pub struct JointTrajectory {
    start: Stamp,
    joint_names: Vec<String>,
    points: Vec<TrajectoryPoint>,
}

fn map_stamp(t: Stamp, t0: Stamp, scale: f64) -> Stamp {
    // In i128 and saturating: extreme stamps cannot overflow.
    let d = ((i128::from(t) - i128::from(t0)) as f64 * scale).round() as i128;
    (i128::from(t0) + d).clamp(i128::from(Stamp::MIN), i128::from(Stamp::MAX)) as Stamp
}

/// Seconds from `from` to `to`.
fn seconds(from: Stamp, to: Stamp) -> f64 {
    (i128::from(to) - i128::from(from)) as f64 * 1e-9
}

fn scale_point(p: &TrajectoryPoint, scale: f64) -> TrajectoryPoint {
    TrajectoryPoint {
        positions: p.positions.clone(),
        velocities: p.velocities.iter().map(|v| v / scale).collect(),
        accelerations: p
            .accelerations
            .iter()
            .map(|a| a / (scale * scale))
            .collect(),
        time_from_start: p.time_from_start * scale,
    }
}

fn check_point(p: &TrajectoryPoint, index: usize, names: &[String]) -> Result<(), TrajectoryError> {
    let n = names.len();
    for (field, values, may_be_empty) in [
        ("positions", &p.positions, false),
        ("velocities", &p.velocities, true),
        ("accelerations", &p.accelerations, true),
    ] {
        if values.len() != n && !(may_be_empty && values.is_empty()) {
            return Err(TrajectoryError::LengthMismatch {
                point: index,
                field,
                len: values.len(),
                joints: n,
            });
        }
        if let Some(j) = values.iter().position(|v| !v.is_finite()) {
            return Err(TrajectoryError::NonFinite {
                point: index,
                field,
                joint: names[j].clone(),
            });
        }
    }
    if !p.accelerations.is_empty() && p.velocities.is_empty() {
        return Err(TrajectoryError::AccelerationsWithoutVelocities { point: index });
    }
    Ok(())
}

impl JointTrajectory {
    /// Checks a trajectory: `start` is its header stamp (ns) (when the header stamp is zero
    /// the controller starts it at its first sample: pass that time).
    ///
    /// # Errors
    /// [`TrajectoryError`]: no joints or points, a joint named twice, arrays whose lengths
    /// disagree with the names, non-finite values, times that do not strictly increase.
    pub fn new(
        start: Stamp,
        joint_names: Vec<String>,
        points: Vec<TrajectoryPoint>,
    ) -> Result<Self, TrajectoryError> {
        if joint_names.is_empty() {
            return Err(TrajectoryError::Empty("joint names"));
        }
        if points.is_empty() {
            return Err(TrajectoryError::Empty("points"));
        }
        if points.len() > MAX_TRAJECTORY_POINTS {
            return Err(TrajectoryError::TooManyPoints {
                points: points.len(),
                limit: MAX_TRAJECTORY_POINTS,
            });
        }
        for (k, n) in joint_names.iter().enumerate() {
            if joint_names[..k].contains(n) {
                return Err(TrajectoryError::DuplicateJoint(n.clone()));
            }
        }
        for (i, p) in points.iter().enumerate() {
            check_point(p, i, &joint_names)?;
            if !p.time_from_start.is_finite() {
                return Err(TrajectoryError::NonFinite {
                    point: i,
                    field: "time_from_start",
                    joint: "time_from_start".into(),
                });
            }
            if i > 0 && p.time_from_start <= points[i - 1].time_from_start {
                return Err(TrajectoryError::NotIncreasing {
                    point: i,
                    time: p.time_from_start,
                    previous: points[i - 1].time_from_start,
                });
            }
        }
        Ok(JointTrajectory {
            start,
            joint_names,
            points,
        })
    }

    /// The start stamp (ns).
    pub fn start(&self) -> Stamp {
        self.start
    }

    /// The joints, in the order of every array.
    pub fn joint_names(&self) -> &[String] {
        &self.joint_names
    }

    /// The points.
    pub fn points(&self) -> &[TrajectoryPoint] {
        &self.points
    }

    /// The time of point `i` (ns).
    pub fn point_time(&self, i: usize) -> Stamp {
        self.start
            .saturating_add((self.points[i].time_from_start * 1e9).round() as Stamp)
    }

    /// Samples the trajectory at `time` (ns) into `out`.
    ///
    /// # Errors
    /// [`TrajectoryError::BeforeStart`] before the start state's time;
    /// [`TrajectoryError::NoStartState`] before the first point without a start state; a
    /// start state whose arrays do not fit is refused as points are.
    pub fn sample(
        &self,
        time: Stamp,
        start_state: Option<&StartState>,
        out: &mut Sample,
    ) -> Result<Segment, TrajectoryError> {
        let n = self.joint_names.len();
        for v in [
            &mut out.positions,
            &mut out.velocities,
            &mut out.accelerations,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        // Times relative to the start, in seconds: what the points are written in.
        let tau = seconds(self.start, time);
        if let Some(s) = start_state {
            if time < s.time {
                return Err(TrajectoryError::BeforeStart {
                    time,
                    start: s.time,
                });
            }
        }
        let first = &self.points[0];
        if tau < first.time_from_start {
            let Some(s) = start_state else {
                return Err(TrajectoryError::NoStartState {
                    time,
                    first: self.point_time(0),
                });
            };
            check_point(&s.point, usize::MAX, &self.joint_names)?;
            let tau_a = seconds(self.start, s.time);
            interpolate(&s.point, tau_a, first, first.time_from_start, tau, out);
            return Ok(Segment::BeforeFirst);
        }
        // The segment [t_i, t_{i+1}) holding tau.
        let after = self.points.partition_point(|p| p.time_from_start <= tau);
        if after == self.points.len() {
            let last = &self.points[after - 1];
            out.positions.copy_from_slice(&last.positions);
            if !last.velocities.is_empty() {
                out.velocities.copy_from_slice(&last.velocities);
            }
            if !last.accelerations.is_empty() {
                out.accelerations.copy_from_slice(&last.accelerations);
            }
            return Ok(Segment::AfterLast);
        }
        let (a, b) = (&self.points[after - 1], &self.points[after]);
        interpolate(a, a.time_from_start, b, b.time_from_start, tau, out);
        Ok(Segment::Between(after - 1))
    }

    /// The spline used between points `i` and `i + 1`.
    pub fn spline(&self, i: usize) -> Spline {
        spline_of(&self.points[i], &self.points[i + 1])
    }

    /// The trajectory under the time scaling t' = t0 + scale · (t − t0): each point keeps
    /// its positions and arrives at the mapped time, velocities are divided by `scale` and
    /// accelerations by `scale²`, so that sampling the result at t' gives the positions the
    /// original has at t. The start stamp is mapped (rounded to the nanosecond) and
    /// `time_from_start` multiplied by `scale`.
    ///
    /// # Errors
    /// [`TrajectoryError::BadScale`] unless `scale` is positive and finite.
    pub fn retimed(&self, t0: Stamp, scale: f64) -> Result<JointTrajectory, TrajectoryError> {
        if !(scale > 0.0 && scale.is_finite()) {
            return Err(TrajectoryError::BadScale(scale));
        }
        let points: Vec<_> = self.points.iter().map(|p| scale_point(p, scale)).collect();
        JointTrajectory::new(
            map_stamp(self.start, t0, scale),
            self.joint_names.clone(),
            points,
        )
    }
}

fn spline_of(a: &TrajectoryPoint, b: &TrajectoryPoint) -> Spline {
    let vel = !a.velocities.is_empty() && !b.velocities.is_empty();
    let acc = !a.accelerations.is_empty() && !b.accelerations.is_empty();
    match (vel, acc) {
        (true, true) => Spline::Quintic,
        (true, false) => Spline::Cubic,
        _ => Spline::Linear,
    }
}

/// Interpolates between `a` at `ta` and `b` at `tb` (seconds) at `t`, as the controller's
/// spline sampler: the local time is clamped to the segment, and outside it the segment
/// reads as linear (its end values).
fn interpolate(
    a: &TrajectoryPoint,
    ta: f64,
    b: &TrajectoryPoint,
    tb: f64,
    t: f64,
    out: &mut Sample,
) {
    let big_t = tb - ta;
    let mut spline = spline_of(a, b);
    let mut tau = t - ta;
    if tau < 0.0 {
        tau = 0.0;
        spline = Spline::Linear;
    }
    if tau > big_t {
        tau = big_t;
        spline = Spline::Linear;
    }
    for i in 0..a.positions.len() {
        let (p0, p1) = (a.positions[i], b.positions[i]);
        let (p, v, acc) = match spline {
            Spline::Linear => {
                let slope = if big_t != 0.0 { (p1 - p0) / big_t } else { 0.0 };
                (p0 + slope * tau, slope, 0.0)
            }
            Spline::Cubic => {
                let (v0, v1) = (a.velocities[i], b.velocities[i]);
                let c = cubic(p0, v0, p1, v1, big_t);
                eval(&c, tau)
            }
            Spline::Quintic => {
                let (v0, v1) = (a.velocities[i], b.velocities[i]);
                let (a0, a1) = (a.accelerations[i], b.accelerations[i]);
                let c = quintic(p0, v0, a0, p1, v1, a1, big_t);
                eval(&c, tau)
            }
        };
        out.positions[i] = p;
        out.velocities[i] = v;
        out.accelerations[i] = acc;
    }
}

/// Coefficients c0..c3 (c4 = c5 = 0) of the cubic with p(0)=p0, p'(0)=v0, p(T)=p1, p'(T)=v1.
fn cubic(p0: f64, v0: f64, p1: f64, v1: f64, t: f64) -> [f64; 6] {
    if t == 0.0 {
        return [p0, v0, 0.0, 0.0, 0.0, 0.0];
    }
    let d = p1 - p0;
    [
        p0,
        v0,
        (3.0 * d - (2.0 * v0 + v1) * t) / (t * t),
        (-2.0 * d + (v0 + v1) * t) / (t * t * t),
        0.0,
        0.0,
    ]
}

/// Coefficients of the quintic matching position, velocity and acceleration at both ends.
fn quintic(p0: f64, v0: f64, a0: f64, p1: f64, v1: f64, a1: f64, t: f64) -> [f64; 6] {
    if t == 0.0 {
        return [p0, v0, 0.5 * a0, 0.0, 0.0, 0.0];
    }
    let d = p1 - p0;
    let (t2, t3) = (t * t, t * t * t);
    [
        p0,
        v0,
        0.5 * a0,
        (20.0 * d - (12.0 * v0 + 8.0 * v1) * t - (3.0 * a0 - a1) * t2) / (2.0 * t3),
        (-30.0 * d + (16.0 * v0 + 14.0 * v1) * t + (3.0 * a0 - 2.0 * a1) * t2) / (2.0 * t3 * t),
        (12.0 * d - 6.0 * (v0 + v1) * t + (a1 - a0) * t2) / (2.0 * t3 * t2),
    ]
}

/// Position, velocity and acceleration of a quintic (or lower) polynomial at `x`.
fn eval(c: &[f64; 6], x: f64) -> (f64, f64, f64) {
    let p = c[0] + x * (c[1] + x * (c[2] + x * (c[3] + x * (c[4] + x * c[5]))));
    let v = c[1] + x * (2.0 * c[2] + x * (3.0 * c[3] + x * (4.0 * c[4] + x * 5.0 * c[5])));
    let a = 2.0 * c[2] + x * (6.0 * c[3] + x * (12.0 * c[4] + x * 20.0 * c[5]));
    (p, v, a)
}
