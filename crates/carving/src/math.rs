//! Small vector and quaternion helpers (f64).

/// A point or vector (m).
pub type Vec3 = [f64; 3];

pub(crate) fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
pub(crate) fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(crate) fn scale(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
pub(crate) fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(crate) fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub(crate) fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}
pub(crate) fn lerp(a: Vec3, b: Vec3, t: f64) -> Vec3 {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

/// A unit quaternion (rotation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quat {
    /// Scalar part.
    pub w: f64,
    /// Vector part, x.
    pub x: f64,
    /// Vector part, y.
    pub y: f64,
    /// Vector part, z.
    pub z: f64,
}

impl Quat {
    /// No rotation.
    pub const IDENTITY: Self = Self {
        w: 1.0,
        x: 0.0,
        y: 0.0,
        z: 0.0,
    };

    /// Rotation by `angle` (rad) about the unit `axis`.
    pub fn from_axis_angle(axis: Vec3, angle: f64) -> Self {
        let n = norm(axis);
        let (s, c) = (angle / 2.0).sin_cos();
        let a = scale(axis, s / n);
        Self {
            w: c,
            x: a[0],
            y: a[1],
            z: a[2],
        }
    }

    /// The rotation `self` after `other` (Hamilton product `self · other`).
    pub fn mul(&self, b: &Self) -> Self {
        let a = self;
        Self {
            w: a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
            x: a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
            y: a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
            z: a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
        }
    }

    /// Rotates `v`.
    pub fn rotate(&self, v: Vec3) -> Vec3 {
        let u = [self.x, self.y, self.z];
        let t = scale(cross(u, v), 2.0);
        add(add(v, scale(t, self.w)), cross(u, t))
    }

    /// Angle (rad, in [0, pi]) of the rotation from `self` to `other`.
    pub fn angle_to(&self, other: &Self) -> f64 {
        let d = (self.w * other.w + self.x * other.x + self.y * other.y + self.z * other.z)
            .abs()
            .min(1.0);
        2.0 * d.acos()
    }

    /// Spherical interpolation from `self` (t = 0) to `other` (t = 1), the short way.
    pub fn slerp(&self, other: &Self, t: f64) -> Self {
        let mut d = self.w * other.w + self.x * other.x + self.y * other.y + self.z * other.z;
        let mut o = *other;
        if d < 0.0 {
            d = -d;
            o = Self {
                w: -o.w,
                x: -o.x,
                y: -o.y,
                z: -o.z,
            };
        }
        let (a, b) = if d > 0.9995 {
            (1.0 - t, t)
        } else {
            let th = d.min(1.0).acos();
            let s = th.sin();
            (((1.0 - t) * th).sin() / s, (t * th).sin() / s)
        };
        let q = Self {
            w: a * self.w + b * o.w,
            x: a * self.x + b * o.x,
            y: a * self.y + b * o.y,
            z: a * self.z + b * o.z,
        };
        let n = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
        Self {
            w: q.w / n,
            x: q.x / n,
            y: q.y / n,
            z: q.z / n,
        }
    }
}
