//! The `four-spheres` scene (the interference paper's test scene:
//! docs/methods/interference.md#the-test-scene): four equal spheres at constant velocity.
//!
//! A moves along +z, B along -y, C along +x, D along -x. A overlaps C early, B in the middle
//! and D late in the run (the A–C and A–D intervals are disjoint, A–B overlaps both); B, C and
//! D stay at least 0.0536 m apart from each other. Every pairwise answer is exact and
//! available from [`FourSpheresParams`], so the checker and resolver can be tested against
//! it (docs/methods/interference.md#exact-answers-for-moving-spheres). Parameters and
//! intervals: `docs/scenes.md`.

use super::{BodySpec, Motion, Shape};

/// Parameters of the four-spheres scene. Sphere `i` has centre
/// `centres_at_t0[i] + velocities[i]·(t - t_span.0)` for `t ∈ t_span` (seconds since the
/// first frame) and radius `radius`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FourSpheresParams {
    /// Radius of every sphere (m).
    pub radius: f64,
    /// Centres at `t_span.0`, in the order A, B, C, D (m).
    pub centres_at_t0: [[f64; 3]; 4],
    /// Velocities, in the order A, B, C, D (m/s).
    pub velocities: [[f64; 3]; 4],
    /// First and last frame time (s); frames are spread uniformly over it.
    pub t_span: (f64, f64),
    /// Minimum corner of the cubic domain (m).
    pub domain_origin: [f64; 3],
    /// Edge of the cubic domain (m); the voxel edge is `domain_edge / grid`.
    pub domain_edge: f64,
    /// Topics (body ids), in the order A, B, C, D.
    pub topics: [&'static str; 4],
}

/// The four-spheres scene. Radius 1/8 m in a 1 m cube over one second:
///
/// | sphere | centre at t = 0 (m) | velocity (m/s) |
/// |---|---|---|
/// | A | (0.5, 0.5, 0.2)   | (0, 0, 0.6)   |
/// | B | (0.35, 0.7, 0.5)  | (0, -0.4, 0)  |
/// | C | (0.3, 0.35, 0.3)  | (0.45, 0, 0)  |
/// | D | (0.75, 0.65, 0.7) | (-0.45, 0, 0) |
///
/// Overlap intervals (|c_i - c_j| < 2r): A–B `0.5 ± 1/√13`, A–C `(4 ± 2√3)/15`,
/// A–D `(11 ± 2√3)/15`; deepest overlaps 0.1 m (A–B at t = 1/2) and 0.0697 m (A–C at 4/15,
/// A–D at 11/15); overlap hypervolumes 4.769062e-4 m³·s (A–B) and 2.062370e-4 m³·s (A–C, A–D).
pub const FOUR_SPHERES: FourSpheresParams = FourSpheresParams {
    radius: 0.125,
    centres_at_t0: [
        [0.5, 0.5, 0.2],
        [0.35, 0.7, 0.5],
        [0.3, 0.35, 0.3],
        [0.75, 0.65, 0.7],
    ],
    velocities: [
        [0.0, 0.0, 0.6],
        [0.0, -0.4, 0.0],
        [0.45, 0.0, 0.0],
        [-0.45, 0.0, 0.0],
    ],
    t_span: (0.0, 1.0),
    domain_origin: [0.0; 3],
    domain_edge: 1.0,
    topics: [
        "/sphere_a/occupancy",
        "/sphere_b/occupancy",
        "/sphere_c/occupancy",
        "/sphere_d/occupancy",
    ],
};

impl FourSpheresParams {
    /// Centre of sphere `i` (0..4 for A..D) at time `t` (s).
    ///
    /// # Panics
    /// If `i >= 4`.
    pub fn centre(&self, i: usize, t: f64) -> [f64; 3] {
        let dt = t - self.t_span.0;
        std::array::from_fn(|c| self.centres_at_t0[i][c] + self.velocities[i][c] * dt)
    }

    /// Distance between the centres of spheres `i` and `j` at time `t`.
    ///
    /// # Panics
    /// If `i >= 4` or `j >= 4`.
    pub fn centre_distance(&self, i: usize, j: usize, t: f64) -> f64 {
        let (a, b) = (self.centre(i, t), self.centre(j, t));
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    }

    /// The relative position `p` at `t_span.0` and relative velocity `q` of sphere `j` seen
    /// from sphere `i`: `c_j(t) - c_i(t) = p + q (t - t_span.0)`.
    fn relative(&self, i: usize, j: usize) -> ([f64; 3], [f64; 3]) {
        let p = std::array::from_fn(|c| self.centres_at_t0[j][c] - self.centres_at_t0[i][c]);
        let q = std::array::from_fn(|c| self.velocities[j][c] - self.velocities[i][c]);
        (p, q)
    }

    /// The open time interval within `t_span` during which spheres `i` and `j` overlap
    /// (`|c_i(t) - c_j(t)| < 2r`), from the roots of that quadratic in `t`; `None` if they
    /// never do.
    ///
    /// # Panics
    /// If `i >= 4` or `j >= 4`.
    pub fn overlap_interval(&self, i: usize, j: usize) -> Option<(f64, f64)> {
        let (p, q) = self.relative(i, j);
        let dot = |u: [f64; 3], v: [f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
        let (a, b, c) = (
            dot(q, q),
            2.0 * dot(p, q),
            dot(p, p) - 4.0 * self.radius * self.radius,
        );
        let (t0, t1) = self.t_span;
        let (r0, r1) = if a == 0.0 {
            if c < 0.0 {
                (0.0, t1 - t0)
            } else {
                return None;
            }
        } else {
            let disc = b * b - 4.0 * a * c;
            if disc <= 0.0 {
                return None;
            }
            // Cancellation-free roots of a s² + b s + c.
            let h = -0.5 * (b + b.signum() * disc.sqrt());
            let (u, v) = if h == 0.0 {
                (-(-c / a).sqrt(), (-c / a).sqrt())
            } else {
                (h / a, c / h)
            };
            (u.min(v), u.max(v))
        };
        let (lo, hi) = ((t0 + r0).max(t0), (t0 + r1).min(t1));
        (lo < hi).then_some((lo, hi))
    }

    /// The smallest centre distance of spheres `i` and `j` over `t_span`, and when it occurs.
    ///
    /// # Panics
    /// If `i >= 4` or `j >= 4`.
    pub fn closest_approach(&self, i: usize, j: usize) -> (f64, f64) {
        let (p, q) = self.relative(i, j);
        let qq = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
        let pq = p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
        let (t0, t1) = self.t_span;
        let s = if qq == 0.0 {
            0.0
        } else {
            (-pq / qq).clamp(0.0, t1 - t0)
        };
        (self.centre_distance(i, j, t0 + s), t0 + s)
    }

    /// Overlap depth `2r - |c_i(t) - c_j(t)|` at time `t` (negative: the gap between them).
    ///
    /// # Panics
    /// If `i >= 4` or `j >= 4`.
    pub fn depth(&self, i: usize, j: usize, t: f64) -> f64 {
        2.0 * self.radius - self.centre_distance(i, j, t)
    }

    /// Volume of the lens where two balls of this radius with centres `d` apart overlap (m³)
    /// (docs/methods/interference.md#exact-answers-for-moving-spheres with R = r:
    /// `π (2r - d)² (d + 4r) / 12`); 0 when `d >= 2r`.
    pub fn lens_volume(&self, d: f64) -> f64 {
        let r = self.radius;
        if d >= 2.0 * r {
            0.0
        } else {
            std::f64::consts::PI * (2.0 * r - d).powi(2) * (d.max(0.0) + 4.0 * r) / 12.0
        }
    }

    /// The space-time overlap hypervolume of spheres `i` and `j` (m³·s): the integral of
    /// [`Self::lens_volume`] over [`Self::overlap_interval`] (composite Simpson, 4096 steps;
    /// the integrand is smooth on the interval, so this is accurate to ~1e-12 relative).
    ///
    /// # Panics
    /// If `i >= 4` or `j >= 4`.
    pub fn overlap_hypervolume(&self, i: usize, j: usize) -> f64 {
        let Some((t0, t1)) = self.overlap_interval(i, j) else {
            return 0.0;
        };
        const STEPS: usize = 4096;
        let h = (t1 - t0) / STEPS as f64;
        let f = |s: usize| self.lens_volume(self.centre_distance(i, j, t0 + h * s as f64));
        let inner: f64 = (1..STEPS)
            .map(|s| if s % 2 == 1 { 4.0 * f(s) } else { 2.0 * f(s) })
            .sum();
        (f(0) + inner + f(STEPS)) * h / 3.0
    }

    /// The four bodies, A..D.
    pub(crate) fn bodies(&self) -> Vec<BodySpec> {
        let what = [
            "sphere A, moving along +z",
            "sphere B, moving along -y",
            "sphere C, moving along +x",
            "sphere D, moving along -x",
        ];
        (0..4)
            .map(|i| {
                BodySpec::new(
                    self.topics[i],
                    what[i],
                    vec![Shape::sphere(self.centres_at_t0[i], self.radius)],
                    Motion::constant_velocity(self.velocities[i], self.t_span.0, self.t_span.1),
                )
            })
            .collect()
    }
}
