//! Exact answers for spheres moving at constant velocity
//! (docs/methods/interference.md#exact-answers-for-moving-spheres), the test oracle of the
//! accuracy report: shortest 4D translations that separate one sphere from others.
//!
//! A sphere of radius r with centre c + v·t over t ∈ [t0, t1] is a convex set in
//! (x, y, z, c·t) (c the time scale of the metric). A moved by s·u meets B iff some time
//! t_a of A and t_b = t_a + δ of B (δ = s·u_t / c) give spatial centres closer than
//! r_A + r_B, i.e. iff min over t_a of |Δ(t_a)| ≤ r_A + r_B, a one-variable quadratic: closed
//! form. The set of s where A + s·u meets B is an interval (a convex set cut by a line).

/// A sphere moving at constant velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MovingSphere {
    /// Centre at t = 0 (m).
    pub c0: [f64; 3],
    /// Velocity (m/s).
    pub v: [f64; 3],
    /// Radius (m).
    pub r: f64,
    /// Time span (s).
    pub t: (f64, f64),
}

/// Whether A translated by `w` = (dx, dy, dz, dt) meets B.
pub fn meets(a: &MovingSphere, b: &MovingSphere, w: [f64; 4]) -> bool {
    // A moved: centre c0_A + w_xyz + v_A (t − w_t) over t ∈ [t0 + w_t, t1 + w_t].
    // At common time t: Δ(t) = (c0_B + v_B t) − (c0_A + w + v_A (t − w_t)); t must lie in
    // both spans.
    let lo = b.t.0.max(a.t.0 + w[3]);
    let hi = b.t.1.min(a.t.1 + w[3]);
    if lo > hi {
        return false;
    }
    let base = [0, 1, 2].map(|k| b.c0[k] - a.c0[k] - w[k] + a.v[k] * w[3]);
    let dv = [0, 1, 2].map(|k| b.v[k] - a.v[k]);
    let dd: f64 = dv.iter().map(|x| x * x).sum();
    let t_star = if dd > 0.0 {
        -(0..3).map(|k| base[k] * dv[k]).sum::<f64>() / dd
    } else {
        lo
    };
    let t = t_star.clamp(lo, hi);
    let d2: f64 = (0..3).map(|k| (base[k] + dv[k] * t).powi(2)).sum();
    d2 <= (a.r + b.r).powi(2)
}

/// Metric step along unit direction `u` in (x, y, z, c·t): the translation s·u in metric
/// units is (s·u_xyz, s·u_t / c) in metres and seconds.
fn translation(u: &[f64; 4], s: f64, c: f64) -> [f64; 4] {
    [s * u[0], s * u[1], s * u[2], s * u[3] / c]
}

/// How far along `u` (metric units) A must move until it meets none of `others`, walking the
/// union of the intervals in steps of `step` and refining the final exit by bisection.
pub fn exit_along(
    a: &MovingSphere,
    others: &[MovingSphere],
    u: &[f64; 4],
    c: f64,
    step: f64,
    max: f64,
) -> f64 {
    let hit = |s: f64| others.iter().any(|b| meets(a, b, translation(u, s, c)));
    let mut s = 0.0;
    while s < max && hit(s) {
        s += step;
    }
    let (mut lo, mut hi) = ((s - step).max(0.0), s);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if hit(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The shortest translation (metric length, unit direction) that separates A from every
/// body of `others` at once: a dense search over directions, then local refinement.
pub fn shortest_translation(a: &MovingSphere, others: &[MovingSphere], c: f64) -> (f64, [f64; 4]) {
    let scale = a.r * 4.0;
    let step = a.r / 200.0;
    let mut best = (f64::INFINITY, [1.0, 0.0, 0.0, 0.0]);
    // Directions on S^3 from a deterministic low-discrepancy set (Hopf coordinates).
    let n = 6000;
    for i in 0..n {
        let f = (i as f64 + 0.5) / n as f64;
        let eta = (f.sqrt()).asin();
        let x1 = 2.0 * std::f64::consts::PI * ((i as f64 * 0.618_033_988_749_895) % 1.0);
        let x2 = 2.0 * std::f64::consts::PI * ((i as f64 * 0.754_877_666_246_693) % 1.0);
        let u = [
            eta.cos() * x1.cos(),
            eta.cos() * x1.sin(),
            eta.sin() * x2.cos(),
            eta.sin() * x2.sin(),
        ];
        let d = exit_along(a, others, &u, c, step, scale);
        if d < best.0 {
            best = (d, u);
        }
    }
    // Local refinement: random-free coordinate perturbations with shrinking radius.
    let mut radius = 0.05;
    while radius > 1e-6 {
        let mut improved = false;
        for k in 0..4 {
            for sgn in [1.0, -1.0] {
                let mut u = best.1;
                u[k] += sgn * radius;
                let norm = u.iter().map(|x| x * x).sum::<f64>().sqrt();
                let u = u.map(|x| x / norm);
                let d = exit_along(a, others, &u, c, step / 10.0, scale);
                if d < best.0 {
                    best = (d, u);
                    improved = true;
                }
            }
        }
        if !improved {
            radius *= 0.5;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn static_spheres_separate_along_the_centre_line_by_the_depth() {
        let a = MovingSphere {
            c0: [0.0; 3],
            v: [0.0; 3],
            r: 1.0,
            t: (0.0, 1.0),
        };
        let b = MovingSphere {
            c0: [1.5, 0.0, 0.0],
            v: [0.0; 3],
            r: 1.0,
            t: (0.0, 1.0),
        };
        assert!(meets(&a, &b, [0.0; 4]));
        assert!(!meets(&a, &b, [-0.51, 0.0, 0.0, 0.0]));
        // With a cheap time axis (large c) the shortest way out is along time: the spans
        // [0, 1] and [0, 1] separate after a shift of 1 s = c metres.
        let (d, u) = shortest_translation(&a, &[b], 10.0);
        assert!((d - 0.5).abs() < 1e-3, "{d} {u:?}");
        assert!(u[0] < -0.99, "{u:?}");
        let (d, u) = shortest_translation(&a, &[b], 0.1);
        assert!((d - 0.1).abs() < 1e-3, "{d} {u:?}");
        assert!(u[3].abs() > 0.99, "{u:?}");
    }
}
