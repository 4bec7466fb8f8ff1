//! Rigid translations over time: piecewise-linear between keyframes.

/// A rigid translation as a function of time: linear between keyframes, constant before the
/// first and after the last.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    keys: Vec<Keyframe>,
}

/// The translation of a body at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// Seconds since the scene's first frame.
    pub t: f64,
    /// Translation from the body's rest pose (m).
    pub offset: [f64; 3],
}

impl Motion {
    /// No motion at all.
    pub fn stationary() -> Self {
        Self {
            keys: vec![Keyframe {
                t: 0.0,
                offset: [0.0; 3],
            }],
        }
    }

    /// Moves at `velocity` (m/s) from the rest pose at `t = t0` to `t = t1`, constant outside.
    pub fn constant_velocity(velocity: [f64; 3], t0: f64, t1: f64) -> Self {
        let dt = t1 - t0;
        Self::keyframes(vec![
            Keyframe {
                t: t0,
                offset: [0.0; 3],
            },
            Keyframe {
                t: t1,
                offset: velocity.map(|v| v * dt),
            },
        ])
    }

    /// Linear between `keys`, which are sorted by time here (ties keep their order, so two
    /// keyframes at one instant make a jump). An empty list means no motion.
    pub fn keyframes(mut keys: Vec<Keyframe>) -> Self {
        if keys.is_empty() {
            return Self::stationary();
        }
        keys.sort_by(|a, b| a.t.total_cmp(&b.t));
        Self { keys }
    }

    /// The keyframes, sorted by time.
    pub fn keys(&self) -> &[Keyframe] {
        &self.keys
    }

    /// The translation at time `t` (seconds since the scene's first frame).
    pub fn offset_at(&self, t: f64) -> [f64; 3] {
        let keys = &self.keys;
        let first = keys[0];
        if t <= first.t {
            return first.offset;
        }
        // The first keyframe after t; keys[i - 1].t <= t < keys[i].t.
        let i = keys.partition_point(|k| k.t <= t);
        if i == keys.len() {
            return keys[i - 1].offset;
        }
        let (a, b) = (keys[i - 1], keys[i]);
        let s = (t - a.t) / (b.t - a.t);
        std::array::from_fn(|c| a.offset[c] + (b.offset[c] - a.offset[c]) * s)
    }
}
