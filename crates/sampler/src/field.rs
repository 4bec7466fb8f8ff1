//! Implicit functions with analytic gradients: the shapes of a scene, their motion in time,
//! and the trait the schemes evaluate.
//!
//! Every function is evaluated on a point `q = (x, y, z, t)` of R^4 ([`Q`]); a 3D figure
//! ignores `t` and returns a zero `t` component of the gradient. Shapes are given in their
//! rest pose; a [`Body`] moves one at constant velocity, so its 4D function is
//! `F(x, y, z, t) = w(p) · f(p - v (t - t_ref))`, with the optional warp factor
//! `w(p) = exp(k · p)` that keeps the zero set and changes everything else (the seed's
//! sampler must not depend on F being a distance).

use serde::{Deserialize, Serialize};

/// A point of R^N, N ≤ 4, padded with zeros: `(x, y, z, t)`.
pub type Q = [f64; 4];

/// A scalar function on R^N with its gradient. Implementations must be pure (the same
/// answer for the same point) and return finite values wherever the point is finite; a
/// gradient may vanish (cone apex, sphere centre), the schemes handle that.
pub trait Field: Send + Sync + std::fmt::Debug {
    /// `F(q)` and `∇F(q)`.
    fn eval(&self, q: &Q) -> (f64, Q);
}

/// A coordinate axis of a shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ShapeAxis {
    /// x.
    X,
    /// y.
    Y,
    /// z (the default).
    #[default]
    Z,
}

impl ShapeAxis {
    fn index(self) -> usize {
        match self {
            Self::X => 0,
            Self::Y => 1,
            Self::Z => 2,
        }
    }
}

/// A solid in 3D, negative inside. Distances where the function is one (sphere, box,
/// torus, capsule); the cone and the seed's surfaces are polynomial or trigonometric.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Shape {
    /// `|p - centre| - radius`.
    Sphere {
        /// Centre (m).
        centre: [f64; 3],
        /// Radius (m), > 0.
        radius: f64,
    },
    /// An axis-aligned box with edges rounded by `rounding`: the signed distance to the
    /// box shrunk by `rounding`, minus `rounding`. With `rounding > 0` the surface is C¹
    /// (flat faces, cylindrical edges, spherical corners) and its gradient is continuous on
    /// it; the kinks of the distance lie on the inner medial axis, away from the surface.
    /// `rounding = 0` gives the exact box, whose edges carry curvature the explicit scheme's
    /// correction term cannot see (the Newton and Metropolis schemes do not need it).
    Box {
        /// Centre (m).
        centre: [f64; 3],
        /// Half the edge lengths (m), each > 0.
        half: [f64; 3],
        /// Edge radius (m), `0 ≤ rounding < min(half)`; default 5% of the smallest half-edge.
        #[serde(default)]
        rounding: Option<f64>,
    },
    /// A torus around `axis` through `centre`: distance to the circle of radius `major`,
    /// minus `minor`.
    Torus {
        /// Centre (m).
        centre: [f64; 3],
        /// Axis of symmetry (default z).
        #[serde(default)]
        axis: ShapeAxis,
        /// Radius of the centre circle (m), > `minor`.
        major: f64,
        /// Radius of the tube (m), > 0.
        minor: f64,
    },
    /// Points within `radius` of the segment `a`-`b`.
    Capsule {
        /// One end of the axis (m).
        a: [f64; 3],
        /// The other end (m).
        b: [f64; 3],
        /// Radius (m), > 0.
        radius: f64,
    },
    /// The double cone `ρ² - (h tan(half_angle))²` around `axis` (ρ: distance to the axis,
    /// h: height above the apex). Its gradient vanishes at the apex.
    Cone {
        /// Apex (m).
        apex: [f64; 3],
        /// Axis (default z).
        #[serde(default)]
        axis: ShapeAxis,
        /// Half opening angle (rad), in (0, π/2).
        half_angle: f64,
    },
    /// The sampling paper's Fig. 1 (docs/methods/sampling.md#figures-of-the-paper): the
    /// open surface `z - x² - x y + (x y)²/2 + 1/4 = 0` (relative to `centre`); bound it
    /// with walls (the seed uses two concentric spheres).
    SeedSaddle {
        /// Origin of the formula (m).
        #[serde(default)]
        centre: [f64; 3],
    },
    /// The sampling paper's Fig. 2 (docs/methods/sampling.md#figures-of-the-paper):
    /// `(9/2) sin²x + 9 cos y cos z + x² + y² + z² - 6 = 0` (relative to `centre`), a
    /// closed surface with dents and holes.
    SeedHoles {
        /// Origin of the formula (m).
        #[serde(default)]
        centre: [f64; 3],
    },
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm3(a: [f64; 3]) -> f64 {
    dot3(a, a).sqrt()
}
fn scale3(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
/// `a / |a|`, or zero for a zero vector (where a distance has no gradient).
fn unit3(a: [f64; 3]) -> [f64; 3] {
    let n = norm3(a);
    if n > 0.0 {
        scale3(a, 1.0 / n)
    } else {
        [0.0; 3]
    }
}

/// `shape: field [x, y, z] m: the y coordinate is NaN; must be finite`, if a coordinate of
/// `p` is not finite.
fn point(shape: &str, field: &str, p: [f64; 3]) -> Option<String> {
    let axis = p.iter().position(|v| !v.is_finite())?;
    Some(format!(
        "{shape}: {field} ({}, {}, {}) m has a non-finite {} coordinate; all must be finite",
        p[0],
        p[1],
        p[2],
        ["x", "y", "z"][axis]
    ))
}

/// `shape: field v m must be a finite number > 0`, unless it is one.
fn positive(shape: &str, field: &str, v: f64) -> Option<String> {
    (!(v > 0.0 && v.is_finite()))
        .then(|| format!("{shape}: {field} {} m must be a finite number > 0", v))
}

impl Shape {
    /// The default box edge radius: 5% of the smallest half-edge.
    pub fn box_rounding(half: [f64; 3], rounding: Option<f64>) -> f64 {
        rounding.unwrap_or(0.05 * half[0].min(half[1]).min(half[2]))
    }

    /// What is wrong with the parameters, if anything: the shape, the field and its value
    /// (lengths in metres, angles in radians).
    pub fn problem(&self) -> Option<String> {
        match *self {
            Self::Sphere { centre, radius } => point("sphere", "centre", centre)
                .or_else(|| positive("sphere", "radius", radius)),
            Self::Box {
                centre,
                half,
                rounding,
            } => point("box", "centre", centre)
                .or_else(|| {
                    half.iter().zip(["x", "y", "z"]).find_map(|(&h, axis)| {
                        (!(h > 0.0 && h.is_finite())).then(|| {
                            format!(
                                "box: half[{axis}] = {} m (half the edge along {axis}) must be a finite number > 0",
                                h
                            )
                        })
                    })
                })
                .or_else(|| {
                    let r = Self::box_rounding(half, rounding);
                    let m = half[0].min(half[1]).min(half[2]);
                    (!(r >= 0.0 && r < m)).then(|| {
                        format!(
                            "box: rounding {} m must be in [0, {m}) (below the smallest half-edge)",
                            r
                        )
                    })
                }),
            Self::Torus {
                centre,
                major,
                minor,
                ..
            } => point("torus", "centre", centre)
                .or_else(|| positive("torus", "minor", minor))
                .or_else(|| positive("torus", "major", major))
                .or_else(|| {
                    (minor >= major).then(|| {
                        format!("torus: minor {minor} m must be below major {major} m")
                    })
                }),
            Self::Capsule { a, b, radius } => point("capsule", "a", a)
                .or_else(|| point("capsule", "b", b))
                .or_else(|| positive("capsule", "radius", radius)),
            Self::Cone {
                apex, half_angle, ..
            } => point("cone", "apex", apex).or_else(|| {
                (!(half_angle > 0.0 && half_angle < std::f64::consts::FRAC_PI_2)).then(|| {
                    format!(
                        "cone: half_angle {} rad must be in (0, π/2)",
                        half_angle
                    )
                })
            }),
            Self::SeedSaddle { centre } => point("seed_saddle", "centre", centre),
            Self::SeedHoles { centre } => point("seed_holes", "centre", centre),
        }
    }

    /// `f(p)` and `∇f(p)` in the rest pose.
    pub fn eval(&self, p: [f64; 3]) -> (f64, [f64; 3]) {
        match *self {
            Self::Sphere { centre, radius } => {
                let d = sub(p, centre);
                (norm3(d) - radius, unit3(d))
            }
            Self::Box {
                centre,
                half,
                rounding,
            } => {
                let r = Self::box_rounding(half, rounding);
                let d = sub(p, centre);
                let q: [f64; 3] = std::array::from_fn(|i| d[i].abs() - (half[i] - r));
                let outer = [q[0].max(0.0), q[1].max(0.0), q[2].max(0.0)];
                let no = norm3(outer);
                if no > 0.0 {
                    let g = std::array::from_fn(|i| outer[i] / no * d[i].signum());
                    (no - r, g)
                } else {
                    // Inside the shrunk box: the distance to the nearest face.
                    let k = (0..3).fold(0, |k, i| if q[i] > q[k] { i } else { k });
                    let mut g = [0.0; 3];
                    g[k] = if d[k] >= 0.0 { 1.0 } else { -1.0 };
                    (q[k] - r, g)
                }
            }
            Self::Torus {
                centre,
                axis,
                major,
                minor,
            } => {
                let d = sub(p, centre);
                let a = axis.index();
                let (i, j) = ((a + 1) % 3, (a + 2) % 3);
                let rho = (d[i] * d[i] + d[j] * d[j]).sqrt();
                let u = rho - major;
                let s = (u * u + d[a] * d[a]).sqrt();
                let mut g = [0.0; 3];
                if s > 0.0 {
                    if rho > 0.0 {
                        g[i] = u / s * d[i] / rho;
                        g[j] = u / s * d[j] / rho;
                    }
                    g[a] = d[a] / s;
                }
                (s - minor, g)
            }
            Self::Capsule { a, b, radius } => {
                let ab = sub(b, a);
                let l2 = dot3(ab, ab);
                let s = if l2 > 0.0 {
                    (dot3(sub(p, a), ab) / l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let c = [a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]];
                let d = sub(p, c);
                (norm3(d) - radius, unit3(d))
            }
            Self::Cone {
                apex,
                axis,
                half_angle,
            } => {
                let d = sub(p, apex);
                let a = axis.index();
                let k2 = half_angle.tan().powi(2);
                let mut g = scale3(d, 2.0);
                g[a] = -2.0 * k2 * d[a];
                let rho2 = dot3(d, d) - d[a] * d[a];
                (rho2 - k2 * d[a] * d[a], g)
            }
            Self::SeedSaddle { centre } => {
                let [x, y, z] = sub(p, centre);
                let f = z - x * x - x * y + 0.5 * (x * y).powi(2) + 0.25;
                let g = [-2.0 * x - y + x * y * y, -x + x * x * y, 1.0];
                (f, g)
            }
            Self::SeedHoles { centre } => {
                let [x, y, z] = sub(p, centre);
                let f =
                    4.5 * x.sin().powi(2) + 9.0 * y.cos() * z.cos() + x * x + y * y + z * z - 6.0;
                let g = [
                    9.0 * x.sin() * x.cos() + 2.0 * x,
                    -9.0 * y.sin() * z.cos() + 2.0 * y,
                    -9.0 * y.cos() * z.sin() + 2.0 * z,
                ];
                (f, g)
            }
        }
    }

    /// A box that holds the shape's zero set (for seeding walkers), or `None` for the
    /// unbounded ones (cone, seed saddle).
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        let around =
            |c: [f64; 3], r: [f64; 3]| Some((sub(c, r), [c[0] + r[0], c[1] + r[1], c[2] + r[2]]));
        match *self {
            Self::Sphere { centre, radius } => around(centre, [radius; 3]),
            Self::Box { centre, half, .. } => around(centre, half),
            Self::Torus {
                centre,
                axis,
                major,
                minor,
            } => {
                let mut r = [major + minor; 3];
                r[axis.index()] = minor;
                around(centre, r)
            }
            Self::Capsule { a, b, radius } => Some((
                std::array::from_fn(|i| a[i].min(b[i]) - radius),
                std::array::from_fn(|i| a[i].max(b[i]) + radius),
            )),
            // |q|² ≤ 6 + 9 = 15 on the zero set.
            Self::SeedHoles { centre } => around(centre, [15f64.sqrt(); 3]),
            Self::Cone { .. } | Self::SeedSaddle { .. } => None,
        }
    }
}

/// A shape moving at constant velocity, optionally warped: the 4D function
/// `F(x, y, z, t) = exp(warp · p) · f(p - velocity (t - t_ref))`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Body {
    /// The shape in its pose at `t = t_ref`.
    pub shape: Shape,
    /// Velocity (m/s); zero for a static body.
    pub velocity: [f64; 3],
    /// The time at which the shape is in its given pose (s).
    pub t_ref: f64,
    /// Warp exponent `k` of `exp(k · p)` (1/m); zero for none.
    pub warp: [f64; 3],
}

impl Body {
    /// A static, unwarped body.
    pub fn fixed(shape: Shape) -> Self {
        Self {
            shape,
            velocity: [0.0; 3],
            t_ref: 0.0,
            warp: [0.0; 3],
        }
    }

    /// The same body moving at `velocity`, in its given pose at `t_ref`.
    pub fn moving(mut self, velocity: [f64; 3], t_ref: f64) -> Self {
        self.velocity = velocity;
        self.t_ref = t_ref;
        self
    }

    /// The same body with the warp factor `exp(k · p)`.
    pub fn warped(mut self, k: [f64; 3]) -> Self {
        self.warp = k;
        self
    }
}

impl Body {
    /// What is wrong with the body, if anything: its shape ([`Shape::problem`]), or a
    /// velocity, warp or `t_ref` that is not finite, named with its value.
    pub fn problem(&self) -> Option<String> {
        if let Some(p) = self.shape.problem() {
            return Some(p);
        }
        for (field, v, unit) in [
            ("velocity", self.velocity, "m/s"),
            ("warp", self.warp, "1/m"),
        ] {
            if let Some(axis) = v.iter().position(|x| !x.is_finite()) {
                return Some(format!(
                    "{field} ({}, {}, {}) {unit} has a non-finite {} component; all must be finite",
                    v[0],
                    v[1],
                    v[2],
                    ["x", "y", "z"][axis]
                ));
            }
        }
        (!self.t_ref.is_finite()).then(|| format!("t_ref {} s must be finite", self.t_ref))
    }
}

impl Field for Body {
    fn eval(&self, q: &Q) -> (f64, Q) {
        let dt = q[3] - self.t_ref;
        let p = [
            q[0] - self.velocity[0] * dt,
            q[1] - self.velocity[1] * dt,
            q[2] - self.velocity[2] * dt,
        ];
        let (f, g) = self.shape.eval(p);
        let ft = -dot3(g, self.velocity);
        if self.warp == [0.0; 3] {
            return (f, [g[0], g[1], g[2], ft]);
        }
        let w = dot3(self.warp, [q[0], q[1], q[2]]).exp();
        (
            w * f,
            [
                w * (g[0] + self.warp[0] * f),
                w * (g[1] + self.warp[1] * f),
                w * (g[2] + self.warp[2] * f),
                w * ft,
            ],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_gradient(b: &Body, q: Q) {
        let (_, g) = b.eval(&q);
        for i in 0..4 {
            let h = 1e-6;
            let mut a = q;
            let mut c = q;
            a[i] += h;
            c[i] -= h;
            let fd = (b.eval(&a).0 - b.eval(&c).0) / (2.0 * h);
            assert!(
                (fd - g[i]).abs() < 1e-5 * (1.0 + g[i].abs()),
                "{b:?} at {q:?}: d{i} {fd} vs {}",
                g[i]
            );
        }
    }

    #[test]
    fn analytic_gradients_match_differences() {
        let shapes = [
            Shape::Sphere {
                centre: [0.1, 0.2, 0.3],
                radius: 0.7,
            },
            Shape::Box {
                centre: [0.0; 3],
                half: [0.5, 0.4, 0.3],
                rounding: Some(0.1),
            },
            Shape::Torus {
                centre: [0.0; 3],
                axis: ShapeAxis::X,
                major: 1.0,
                minor: 0.3,
            },
            Shape::Capsule {
                a: [0.0; 3],
                b: [1.0, 0.5, 0.0],
                radius: 0.2,
            },
            Shape::Cone {
                apex: [0.0; 3],
                axis: ShapeAxis::Y,
                half_angle: 0.5,
            },
            Shape::SeedSaddle { centre: [0.0; 3] },
            Shape::SeedHoles { centre: [0.0; 3] },
        ];
        let pts = [
            [0.31, -0.47, 0.83, 0.2],
            [0.9, 0.12, -0.23, -0.4],
            [-0.2, 0.61, 0.05, 0.7],
        ];
        for s in shapes {
            assert!(s.problem().is_none(), "{s:?}");
            let b = Body::fixed(s)
                .moving([0.3, -0.2, 0.5], 0.1)
                .warped([0.4, 0.0, -0.3]);
            for q in pts {
                check_gradient(&b, q);
            }
        }
    }

    #[test]
    fn bad_parameters_are_named() {
        assert!(Shape::Torus {
            centre: [0.0; 3],
            axis: ShapeAxis::Z,
            major: 0.2,
            minor: 0.3
        }
        .problem()
        .unwrap()
        .contains("minor"));
        assert!(Shape::Sphere {
            centre: [f64::NAN, 0.0, 0.0],
            radius: 1.0
        }
        .problem()
        .is_some());
        assert!(Shape::Box {
            centre: [0.0; 3],
            half: [1.0; 3],
            rounding: Some(1.0)
        }
        .problem()
        .is_some());
    }
}
