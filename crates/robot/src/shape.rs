//! A link's collision geometry prepared once for rasterisation, and placed per frame in
//! voxel coordinates (voxel (i, j, k) is the unit cube at (i, j, k)).

use crate::math::Pose;
use crate::mesh::TriMesh;
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

/// Sides of the prism that stands for a cylinder in `bits`: it contains the cylinder and
/// bulges out of it by at most `radius · (1/cos(π/64) − 1)` = 0.12 % of the radius.
pub const CYLINDER_PRISM_SIDES: usize = 64;

/// One collision element, ready to rasterise.
#[derive(Clone, Debug)]
pub struct Shape {
    /// Geometry frame to link frame (the `<collision>` origin).
    pub origin: Pose,
    /// The geometry.
    pub kind: ShapeKind,
}

/// The geometry of a [`Shape`], in its own frame.
#[derive(Clone, Debug)]
pub enum ShapeKind {
    /// A triangle mesh (a mesh file, scaled).
    Mesh(Arc<TriMesh>),
    /// A box of half-edges `half`, with its 12-triangle surface for `bits`.
    Box {
        /// Half edge lengths (m).
        half: [f64; 3],
        /// Its surface.
        mesh: Arc<TriMesh>,
    },
    /// A sphere of radius `radius`.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// A cylinder along z, with the circumscribed prism `bits` uses.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Half length (m).
        half_length: f64,
        /// The prism containing it.
        prism: Arc<TriMesh>,
    },
}

/// An affine map `x ↦ m · x + t`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Affine {
    pub m: Matrix3<f64>,
    pub t: Vector3<f64>,
}

impl Affine {
    pub fn is_finite(&self) -> bool {
        self.m.iter().chain(self.t.iter()).all(|v| v.is_finite())
    }

    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let v = self.m * Vector3::new(p[0], p[1], p[2]) + self.t;
        [v.x, v.y, v.z]
    }

    /// Geometry frame → voxel coordinates: `(pose · p − origin) / h`.
    pub fn to_voxels(pose: &Pose, origin: [f64; 3], h: f64) -> Affine {
        let r = pose.rotation.to_rotation_matrix().into_inner();
        let t = pose.translation.vector;
        Affine {
            m: r / h,
            t: (t - Vector3::from(origin)) / h,
        }
    }

    /// Voxel coordinates → geometry frame: the inverse of [`to_voxels`](Self::to_voxels).
    pub fn from_voxels(pose: &Pose, origin: [f64; 3], h: f64) -> Affine {
        let rt = pose.rotation.to_rotation_matrix().into_inner().transpose();
        let t = pose.translation.vector;
        Affine {
            m: rt * h,
            t: rt * (Vector3::from(origin) - t),
        }
    }
}
