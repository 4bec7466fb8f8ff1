//! Merging `sensor_msgs/JointState` messages into a bounded, time-stamped history of joint
//! positions, and interpolating it to a frame's time.
//!
//! Merging follows robot_state_publisher: each message may carry only some joints and is
//! merged by name into what earlier messages said. Policy on bad messages: a message is
//! applied whole or not at all. Names that are not movable joints of the URDF, a name given
//! twice, `name` and `position` arrays of different lengths, a non-finite position and a
//! stamp older than a named joint's last sample each refuse the whole message (a typed
//! error, counted), because a partly applied message would pose the robot in a state that no
//! publisher sent (a mix of a wrong robot's joints, or of two instants). Mimic joints given
//! by name are accepted and ignored: their position always follows the joint they mimic.
//! Positions beyond the URDF limits are kept and counted.
//!
//! Interpolation is linear per joint between the two samples of that joint around the frame
//! time. Before a joint's first kept sample the position is not known and the frame cannot
//! be made ([`JointStateError::NotKnown`]); after its last sample the last value is held, and
//! [`Interpolated`] says for how many joints and how long.

use crate::kinematics::Kinematics;
use crate::urdf::JointLimits;
use std::collections::VecDeque;

/// A time stamp or a duration in nanoseconds (`sec · 10⁹ + nanosec` of a ROS header).
pub type Stamp = i64;

/// A refused message or a position that cannot be given.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JointStateError {
    /// `name` and `position` have different lengths.
    #[error("JointState has {names} names but {positions} positions; the message is not applied")]
    LengthMismatch {
        /// Length of `name`.
        names: usize,
        /// Length of `position`.
        positions: usize,
    },
    /// Names that are not movable joints of the URDF.
    #[error("JointState names {} that are not movable joints of the URDF: {}; the message is not applied", names.len(), names.join(", "))]
    UnknownJoints {
        /// The names (at most 16 listed).
        names: Vec<String>,
    },
    /// A name given twice in one message.
    #[error("JointState names joint `{joint}` twice; the message is not applied")]
    DuplicateJoint {
        /// The joint.
        joint: String,
    },
    /// A NaN or infinite position.
    #[error("JointState gives joint `{joint}` the non-finite position {value}; the message is not applied")]
    NonFinite {
        /// The joint.
        joint: String,
        /// The value.
        value: f64,
    },
    /// A stamp older than the joint's last sample.
    #[error("JointState stamped {stamp} ns is older than joint `{joint}`'s last sample at {last} ns; the message is not applied")]
    OutOfOrder {
        /// The joint.
        joint: String,
        /// The message's stamp.
        stamp: Stamp,
        /// The joint's last sample.
        last: Stamp,
    },
    /// The frame time is before the joint's first kept sample (or it has none).
    #[error("joint `{joint}` has no position at {time} ns: {}", match first { Some(f) => format!("its first kept sample is at {f} ns"), None => "no message has given it yet".to_owned() })]
    NotKnown {
        /// The joint.
        joint: String,
        /// The frame time asked.
        time: Stamp,
        /// Its first kept sample, if any.
        first: Option<Stamp>,
    },
}

/// What merging one message did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Merged {
    /// Positions stored.
    pub applied: usize,
    /// Mimic joints named and ignored.
    pub ignored_mimic: usize,
    /// Positions stored that are beyond their joint's limits.
    pub beyond_limits: usize,
}

/// Counters over the history's life.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct JointStateStats {
    /// Messages applied.
    pub applied: u64,
    /// Messages refused, for any reason.
    pub refused: u64,
    /// Non-finite positions seen (in refused messages).
    pub non_finite: u64,
    /// Positions beyond limits stored.
    pub beyond_limits: u64,
    /// Samples dropped by the window or the count bound.
    pub dropped: u64,
}

/// How a position set was made by [`JointStateHistory::positions_at`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Interpolated {
    /// Joints whose last sample is before the time asked: their last value is held.
    pub held: usize,
    /// The longest such hold (ns) (0 if none).
    pub max_hold: Stamp,
}

/// Bounds on the history: samples older than `window` before the newest sample are dropped
/// (one at or before the window's start is kept per joint, so the window's start can still
/// be interpolated), and at most `max_samples` are kept per joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HistoryBounds {
    /// Time kept behind the newest sample (ns).
    pub window: Stamp,
    /// Samples kept per joint.
    pub max_samples: usize,
}

impl Default for HistoryBounds {
    /// Ten seconds and 10 000 samples per joint (100 s at 100 Hz would be cut to the window).
    fn default() -> Self {
        HistoryBounds {
            window: 10_000_000_000,
            max_samples: 10_000,
        }
    }
}

/// The merged joint states of one robot over a bounded window.
#[derive(Clone, Debug)]
pub struct JointStateHistory {
    names: Vec<String>,
    mimic: Vec<String>,
    limits: Vec<Option<JointLimits>>,
    samples: Vec<VecDeque<(Stamp, f64)>>,
    bounds: HistoryBounds,
    newest: Option<Stamp>,
    stats: JointStateStats,
    scratch: Vec<(usize, f64)>,
}

impl JointStateHistory {
    /// An empty history for the independent joints of `kinematics`.
    pub fn new(kinematics: &Kinematics, bounds: HistoryBounds) -> Self {
        let model = kinematics.model();
        let names = kinematics.joint_names().to_vec();
        let limits = (0..names.len())
            .map(|i| model.joints[kinematics.urdf_joint(i)].limits)
            .collect();
        let mimic = model
            .joints
            .iter()
            .filter(|j| j.mimic.is_some() && j.kind.is_movable())
            .map(|j| j.name.clone())
            .collect();
        JointStateHistory {
            samples: vec![VecDeque::new(); names.len()],
            names,
            mimic,
            limits,
            bounds: HistoryBounds {
                window: bounds.window.max(0),
                max_samples: bounds.max_samples.max(1),
            },
            newest: None,
            stats: JointStateStats::default(),
            scratch: Vec::new(),
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> &JointStateStats {
        &self.stats
    }

    /// Merges one message stamped `stamp`: `names[i]` is at `positions[i]`.
    ///
    /// # Errors
    /// Any [`JointStateError`] but `NotKnown`; the message is then not applied at all.
    pub fn merge<S: AsRef<str>>(
        &mut self,
        stamp: Stamp,
        names: &[S],
        positions: &[f64],
    ) -> Result<Merged, JointStateError> {
        let r = self.check(stamp, names, positions);
        match r {
            Ok(merged) => {
                self.stats.applied += 1;
                self.stats.beyond_limits += merged.beyond_limits as u64;
                for k in 0..self.scratch.len() {
                    let (i, q) = self.scratch[k];
                    self.push(i, stamp, q);
                }
                self.newest = Some(self.newest.map_or(stamp, |n| n.max(stamp)));
                self.prune();
                Ok(merged)
            }
            Err(e) => {
                self.stats.refused += 1;
                if matches!(e, JointStateError::NonFinite { .. }) {
                    self.stats.non_finite +=
                        positions.iter().filter(|p| !p.is_finite()).count() as u64;
                }
                Err(e)
            }
        }
    }

    /// Checks a message without changing anything; fills `scratch` with what to store.
    fn check<S: AsRef<str>>(
        &mut self,
        stamp: Stamp,
        names: &[S],
        positions: &[f64],
    ) -> Result<Merged, JointStateError> {
        if names.len() != positions.len() {
            return Err(JointStateError::LengthMismatch {
                names: names.len(),
                positions: positions.len(),
            });
        }
        self.scratch.clear();
        let mut merged = Merged::default();
        let mut unknown = Vec::new();
        for (name, &q) in names.iter().zip(positions) {
            let name = name.as_ref();
            match self.names.iter().position(|n| n == name) {
                Some(i) => self.scratch.push((i, q)),
                None if self.mimic.iter().any(|m| m == name) => merged.ignored_mimic += 1,
                None => {
                    if unknown.len() < 16 {
                        unknown.push(name.to_owned());
                    }
                }
            }
        }
        if !unknown.is_empty() {
            return Err(JointStateError::UnknownJoints { names: unknown });
        }
        for (k, &(i, q)) in self.scratch.iter().enumerate() {
            if self.scratch[..k].iter().any(|&(j, _)| j == i) {
                return Err(JointStateError::DuplicateJoint {
                    joint: self.names[i].clone(),
                });
            }
            if !q.is_finite() {
                return Err(JointStateError::NonFinite {
                    joint: self.names[i].clone(),
                    value: q,
                });
            }
            if let Some(&(last, _)) = self.samples[i].back() {
                if stamp < last {
                    return Err(JointStateError::OutOfOrder {
                        joint: self.names[i].clone(),
                        stamp,
                        last,
                    });
                }
            }
            if let Some(l) = self.limits[i] {
                if q < l.lower || q > l.upper {
                    merged.beyond_limits += 1;
                }
            }
        }
        merged.applied = self.scratch.len();
        Ok(merged)
    }

    fn push(&mut self, i: usize, stamp: Stamp, q: f64) {
        let s = &mut self.samples[i];
        match s.back_mut() {
            Some(last) if last.0 == stamp => last.1 = q, // same instant: the newer message wins
            _ => s.push_back((stamp, q)),
        }
        while s.len() > self.bounds.max_samples {
            s.pop_front();
            self.stats.dropped += 1;
        }
    }

    fn prune(&mut self) {
        let Some(newest) = self.newest else { return };
        let cutoff = newest.saturating_sub(self.bounds.window);
        for s in &mut self.samples {
            while s.len() > 1 && s[1].0 <= cutoff {
                s.pop_front();
                self.stats.dropped += 1;
            }
        }
    }

    /// The latest merged position of every independent joint (robot_state_publisher's
    /// current state).
    ///
    /// # Errors
    /// [`JointStateError::NotKnown`] for the first joint no message has given.
    pub fn latest(&self, out: &mut [f64]) -> Result<(), JointStateError> {
        for (i, s) in self.samples.iter().enumerate() {
            match s.back() {
                Some(&(_, q)) => out[i] = q,
                None => {
                    return Err(JointStateError::NotKnown {
                        joint: self.names[i].clone(),
                        time: self.newest.unwrap_or(0),
                        first: None,
                    })
                }
            }
        }
        Ok(())
    }

    /// Positions of every independent joint at `time`, linear per joint between its two
    /// samples around `time`, held after its last sample.
    ///
    /// # Errors
    /// [`JointStateError::NotKnown`] for the first joint with no sample at or before `time`.
    ///
    /// # Panics
    /// If `out` is shorter than the number of independent joints.
    pub fn positions_at(
        &self,
        time: Stamp,
        out: &mut [f64],
    ) -> Result<Interpolated, JointStateError> {
        let mut how = Interpolated::default();
        for (i, s) in self.samples.iter().enumerate() {
            let not_known = || JointStateError::NotKnown {
                joint: self.names[i].clone(),
                time,
                first: s.front().map(|f| f.0),
            };
            let Some(&(first, _)) = s.front() else {
                return Err(not_known());
            };
            if time < first {
                return Err(not_known());
            }
            // Index of the first sample after `time`.
            let after = s.partition_point(|&(t, _)| t <= time);
            if after == s.len() {
                let (last, q) = s[s.len() - 1];
                out[i] = q;
                if time > last {
                    how.held += 1;
                    how.max_hold = how.max_hold.max(time.saturating_sub(last));
                }
                continue;
            }
            let (t0, q0) = s[after - 1];
            let (t1, q1) = s[after];
            // In i128: stamps far apart cannot overflow.
            let f = (i128::from(time) - i128::from(t0)) as f64
                / (i128::from(t1) - i128::from(t0)) as f64;
            out[i] = q0 + (q1 - q0) * f;
        }
        Ok(how)
    }
}
