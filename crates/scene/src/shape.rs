//! Implicit solids: axis-aligned boxes, axis-aligned capped cylinders and spheres.
//!
//! Each shape is an *open* set (its boundary is not inside) with an exact signed distance
//! (negative inside) and an exact description of where a line parallel to x crosses it
//! ([`Shape::x_interval`]), which is what the rasteriser scans.

/// A coordinate axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    /// The x axis.
    X,
    /// The y axis.
    Y,
    /// The z axis.
    Z,
}

impl Axis {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Self::X => 0,
            Self::Y => 1,
            Self::Z => 2,
        }
    }
}

/// An axis-aligned bounding box `[min, max]` in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: [f64; 3],
    /// Maximum corner.
    pub max: [f64; 3],
}

impl Aabb {
    /// The smallest box holding both.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: std::array::from_fn(|i| self.min[i].min(other.min[i])),
            max: std::array::from_fn(|i| self.max[i].max(other.max[i])),
        }
    }

    /// The box moved by `offset`.
    pub fn translated(&self, offset: [f64; 3]) -> Aabb {
        Aabb {
            min: add(self.min, offset),
            max: add(self.max, offset),
        }
    }
}

/// One implicit solid. All shapes are open sets: a point on the surface is outside.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// The box `min < p < max` (componentwise).
    Cuboid {
        /// Minimum corner (m).
        min: [f64; 3],
        /// Maximum corner (m).
        max: [f64; 3],
    },
    /// A capped cylinder whose axis is parallel to `axis`.
    Cylinder {
        /// Direction of the axis.
        axis: Axis,
        /// Middle of the axis segment (m).
        centre: [f64; 3],
        /// Radius (m).
        radius: f64,
        /// Half the length along the axis (m).
        half_length: f64,
    },
    /// The ball `|p - centre| < radius`.
    Sphere {
        /// Centre (m).
        centre: [f64; 3],
        /// Radius (m).
        radius: f64,
    },
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// The two coordinates other than `axis`, in increasing axis order.
fn others(axis: Axis) -> (usize, usize) {
    match axis {
        Axis::X => (1, 2),
        Axis::Y => (0, 2),
        Axis::Z => (0, 1),
    }
}

impl Shape {
    /// The box with corners `min` and `max`.
    pub fn cuboid(min: [f64; 3], max: [f64; 3]) -> Self {
        Self::Cuboid { min, max }
    }

    /// A cylinder along `axis` from `start` (the centre of one cap) with `length` along the
    /// positive axis direction.
    pub fn cylinder(axis: Axis, start: [f64; 3], length: f64, radius: f64) -> Self {
        let mut centre = start;
        centre[axis.index()] += length / 2.0;
        Self::Cylinder {
            axis,
            centre,
            radius,
            half_length: length / 2.0,
        }
    }

    /// The ball of `radius` around `centre`.
    pub fn sphere(centre: [f64; 3], radius: f64) -> Self {
        Self::Sphere { centre, radius }
    }

    /// The same shape moved by `offset`.
    pub fn translated(&self, offset: [f64; 3]) -> Self {
        match *self {
            Self::Cuboid { min, max } => Self::Cuboid {
                min: add(min, offset),
                max: add(max, offset),
            },
            Self::Cylinder {
                axis,
                centre,
                radius,
                half_length,
            } => Self::Cylinder {
                axis,
                centre: add(centre, offset),
                radius,
                half_length,
            },
            Self::Sphere { centre, radius } => Self::Sphere {
                centre: add(centre, offset),
                radius,
            },
        }
    }

    /// The tight bounding box.
    pub fn aabb(&self) -> Aabb {
        match *self {
            Self::Cuboid { min, max } => Aabb { min, max },
            Self::Cylinder {
                axis,
                centre,
                radius,
                half_length,
            } => {
                let a = axis.index();
                let ext: [f64; 3] =
                    std::array::from_fn(|i| if i == a { half_length } else { radius });
                Aabb {
                    min: std::array::from_fn(|i| centre[i] - ext[i]),
                    max: std::array::from_fn(|i| centre[i] + ext[i]),
                }
            }
            Self::Sphere { centre, radius } => Aabb {
                min: centre.map(|c| c - radius),
                max: centre.map(|c| c + radius),
            },
        }
    }

    /// Volume in m³.
    pub fn volume(&self) -> f64 {
        match *self {
            Self::Cuboid { min, max } => (0..3).map(|i| (max[i] - min[i]).max(0.0)).product(),
            Self::Cylinder {
                radius,
                half_length,
                ..
            } => std::f64::consts::PI * radius * radius * 2.0 * half_length,
            Self::Sphere { radius, .. } => 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3),
        }
    }

    /// Whether `p` is strictly inside.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        match *self {
            Self::Cuboid { min, max } => (0..3).all(|i| min[i] < p[i] && p[i] < max[i]),
            Self::Cylinder {
                axis,
                centre,
                radius,
                half_length,
            } => {
                let (u, v) = others(axis);
                let a = axis.index();
                let (du, dv) = (p[u] - centre[u], p[v] - centre[v]);
                (p[a] - centre[a]).abs() < half_length && du * du + dv * dv < radius * radius
            }
            Self::Sphere { centre, radius } => {
                let d: [f64; 3] = std::array::from_fn(|i| p[i] - centre[i]);
                d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < radius * radius
            }
        }
    }

    /// Exact Euclidean signed distance from `p` to the surface: negative inside, positive outside.
    pub fn signed_distance(&self, p: [f64; 3]) -> f64 {
        match *self {
            Self::Cuboid { min, max } => {
                let q: [f64; 3] = std::array::from_fn(|i| {
                    (p[i] - (min[i] + max[i]) / 2.0).abs() - (max[i] - min[i]) / 2.0
                });
                let outside = q.iter().map(|c| c.max(0.0).powi(2)).sum::<f64>().sqrt();
                outside + q[0].max(q[1]).max(q[2]).min(0.0)
            }
            Self::Cylinder {
                axis,
                centre,
                radius,
                half_length,
            } => {
                let (u, v) = others(axis);
                let a = axis.index();
                let radial = (p[u] - centre[u]).hypot(p[v] - centre[v]) - radius;
                let axial = (p[a] - centre[a]).abs() - half_length;
                radial.max(axial).min(0.0) + radial.max(0.0).hypot(axial.max(0.0))
            }
            Self::Sphere { centre, radius } => {
                let d: [f64; 3] = std::array::from_fn(|i| p[i] - centre[i]);
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - radius
            }
        }
    }

    /// The open interval `(x0, x1)` of the line `{(x, y, z) : x ∈ ℝ}` inside the shape, or
    /// `None` if the line misses it.
    #[inline]
    pub fn x_interval(&self, y: f64, z: f64) -> Option<(f64, f64)> {
        match *self {
            Self::Cuboid { min, max } => {
                (min[1] < y && y < max[1] && min[2] < z && z < max[2]).then_some((min[0], max[0]))
            }
            Self::Cylinder {
                axis: Axis::X,
                centre,
                radius,
                half_length,
            } => {
                let (dy, dz) = (y - centre[1], z - centre[2]);
                (dy * dy + dz * dz < radius * radius)
                    .then_some((centre[0] - half_length, centre[0] + half_length))
            }
            Self::Cylinder {
                axis,
                centre,
                radius,
                half_length,
            } => {
                // Axis Y: the axial coordinate is y and the radial ones x, z; axis Z: z and x, y.
                let (along, across, a) = if axis == Axis::Y {
                    (y, z, 1)
                } else {
                    (z, y, 2)
                };
                let c = if axis == Axis::Y { 2 } else { 1 };
                let d = across - centre[c];
                let s = radius * radius - d * d;
                ((along - centre[a]).abs() < half_length && s > 0.0).then(|| {
                    let h = s.sqrt();
                    (centre[0] - h, centre[0] + h)
                })
            }
            Self::Sphere { centre, radius } => {
                let (dy, dz) = (y - centre[1], z - centre[2]);
                let s = radius * radius - dy * dy - dz * dz;
                (s > 0.0).then(|| {
                    let h = s.sqrt();
                    (centre[0] - h, centre[0] + h)
                })
            }
        }
    }
}
