//! Lattice points (exact), and the map from lattice time to seconds.

/// A point of the integer lattice in (x, y, z, t). Voxel centre (i, j, k) of frame n is
/// `(S·i, S·j, S·k, S·n)` for the lattice scale S; surface vertices lie between, on
/// multiples of 1 (an edge is cut into S steps).
pub type LatticePoint = [i32; 4];

/// A point in metres and seconds (x, y, z, t). Only for measurements: never fed to a
/// predicate.
pub type SpaceTimePoint = [f64; 4];

/// Seconds since `origin_ns` of lattice time `t`, where frame n (stamp `stamps_ns[n]`) is at
/// lattice time `steps_per_frame · n`: piecewise linear between frames, extrapolated with the
/// first or last frame period outside them. 0 with fewer than two stamps.
pub fn stamp_time_s(stamps_ns: &[i64], steps_per_frame: f64, t: f64, origin_ns: i64) -> f64 {
    let n = stamps_ns.len();
    if n < 2 {
        return stamps_ns
            .first()
            .map_or(0.0, |s| (s - origin_ns) as f64 * 1e-9);
    }
    let k = ((t / steps_per_frame).floor().max(0.0) as usize).min(n - 2);
    let frac = t / steps_per_frame - k as f64;
    let (a, b) = (stamps_ns[k] - origin_ns, stamps_ns[k + 1] - origin_ns);
    (a as f64 + frac * (b - a) as f64) * 1e-9
}

#[cfg(test)]
mod tests {
    use super::stamp_time_s;

    #[test]
    fn time_is_piecewise_linear_between_stamps() {
        let stamps = [1_000_000_000, 1_100_000_000, 2_000_000_000];
        let t = |x: f64| stamp_time_s(&stamps, 4.0, x, 1_000_000_000);
        assert_eq!(t(0.0), 0.0);
        assert!((t(2.0) - 0.05).abs() < 1e-12);
        assert!((t(4.0) - 0.1).abs() < 1e-12);
        assert!((t(6.0) - 0.55).abs() < 1e-12);
        assert!((t(8.0) - 1.0).abs() < 1e-12);
        assert!((t(10.0) - 1.45).abs() < 1e-12);
        assert_eq!(stamp_time_s(&[5], 4.0, 3.0, 0), 5e-9);
    }
}
