//! The `periodic` scene: two spheres that meet again and again, for streams of any length.
//!
//! Sphere A (radius 0.15 m, rest centre (0.25, 0.5, 0.5)) swings along +x and back, a
//! triangle wave of amplitude [`PERIODIC_AMPLITUDE`] and period [`PERIODIC_PERIOD_S`]:
//! out for one second, back for one. Sphere B (same radius, centre (0.7, 0.5, 0.5)) stays.
//! Their centres are 0.45 − x(t) apart, so they overlap (closer than 0.3 m) while
//! x(t) > 0.15 m: from 2k + 0.6 s to 2k + 1.4 s for every k, one contact of 0.8 s every two
//! seconds, 0.1 m deep at its deepest. Frames come at [`PERIODIC_FRAME_PERIOD_NS`] (20 Hz) in
//! a 1 m cube.

use super::{BodySpec, Keyframe, Motion, Shape};

/// Radius of both spheres (m).
pub const PERIODIC_RADIUS: f64 = 0.15;
/// How far A swings (m).
pub const PERIODIC_AMPLITUDE: f64 = 0.25;
/// One swing out and back (s).
pub const PERIODIC_PERIOD_S: f64 = 2.0;
/// Frame period (ns): 20 Hz.
pub const PERIODIC_FRAME_PERIOD_NS: i64 = 50_000_000;
/// Edge of the cubic domain (m).
pub const PERIODIC_DOMAIN_EDGE: f64 = 1.0;

/// The contact intervals (s since the first frame) within `[0, span_s]`: open intervals
/// (2k + 0.6, 2k + 1.4), cut at the span's end.
pub fn periodic_contacts(span_s: f64) -> Vec<(f64, f64)> {
    let half = PERIODIC_PERIOD_S / 2.0;
    // x(τ) = A·τ/half on the way out: the centres come within two radii at τ_in.
    let gap = 0.45 - 2.0 * PERIODIC_RADIUS;
    let t_in = gap / PERIODIC_AMPLITUDE * half;
    let mut out = Vec::new();
    let mut k = 0.0;
    while k * PERIODIC_PERIOD_S + t_in < span_s {
        let s = k * PERIODIC_PERIOD_S;
        out.push((s + t_in, (s + PERIODIC_PERIOD_S - t_in).min(span_s)));
        k += 1.0;
    }
    out
}

/// The two bodies over `span_s` seconds.
pub fn bodies(span_s: f64) -> Vec<BodySpec> {
    let half = PERIODIC_PERIOD_S / 2.0;
    let swings = (span_s / PERIODIC_PERIOD_S).ceil().max(1.0) as usize;
    let mut keys = Vec::with_capacity(2 * swings + 1);
    for k in 0..=swings {
        let t = k as f64 * PERIODIC_PERIOD_S;
        keys.push(Keyframe {
            t,
            offset: [0.0; 3],
        });
        if k < swings {
            keys.push(Keyframe {
                t: t + half,
                offset: [PERIODIC_AMPLITUDE, 0.0, 0.0],
            });
        }
    }
    vec![
        BodySpec::new(
            "/swinger/occupancy",
            "sphere A, swinging along x",
            vec![Shape::sphere([0.25, 0.5, 0.5], PERIODIC_RADIUS)],
            Motion::keyframes(keys),
        ),
        BodySpec::new(
            "/post/occupancy",
            "sphere B, at rest",
            vec![Shape::sphere([0.7, 0.5, 0.5], PERIODIC_RADIUS)],
            Motion::stationary(),
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The centres are closer than two radii exactly within the listed intervals.
    #[test]
    fn contacts_are_where_the_centres_come_closer_than_two_radii() {
        let span = 9.0;
        let b = bodies(span);
        let want = periodic_contacts(span);
        assert_eq!(want.len(), 5);
        for i in 0..9000 {
            let t = i as f64 * 1e-3 + 0.0005;
            let a = b[0].offset_at(t)[0] + 0.25;
            let overlap = 0.7 - a < 2.0 * PERIODIC_RADIUS;
            let listed = want.iter().any(|&(s, e)| s < t && t < e);
            assert_eq!(overlap, listed, "t = {t}");
        }
    }
}
