//! A rigid transform (rotation, then translation) taking a cloud's points into
//! the lattice's frame: `p' = R·p + t`, computed in `f64`.
//!
//! Validated once when built, so applying it cannot fail. Three multiplies and
//! adds per row, left to right, without fused multiply-add, so that a reference
//! computed the same way gives the same bits.

use thiserror::Error;

/// `p' = R·p + t` with `R` a rotation (orthonormal, determinant +1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidTransform {
    rotation: [[f64; 3]; 3],
    translation: [f64; 3],
}

/// Orthonormality tolerance on `RᵀR - I`, entry by entry.
pub const ROTATION_TOLERANCE: f64 = 1e-6;

impl RigidTransform {
    /// The identity.
    pub fn identity() -> Self {
        RigidTransform {
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
        }
    }

    /// From a rotation matrix (rows) and a translation in metres.
    ///
    /// # Errors
    /// [`TransformError::NotFinite`] for a NaN or infinite entry,
    /// [`TransformError::NotRotation`] if `RᵀR` is not the identity within
    /// [`ROTATION_TOLERANCE`] or the determinant is not positive (a reflection).
    pub fn from_matrix(
        rotation: [[f64; 3]; 3],
        translation: [f64; 3],
    ) -> Result<Self, TransformError> {
        if rotation
            .iter()
            .flatten()
            .chain(translation.iter())
            .any(|v| !v.is_finite())
        {
            return Err(TransformError::NotFinite);
        }
        let r = &rotation;
        let mut worst = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                worst = worst.max((dot - want).abs());
            }
        }
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        if worst > ROTATION_TOLERANCE || det <= 0.0 {
            return Err(TransformError::NotRotation {
                deviation: worst,
                determinant: det,
            });
        }
        Ok(RigidTransform {
            rotation,
            translation,
        })
    }

    /// From a quaternion `[x, y, z, w]` (as `geometry_msgs/Quaternion`) and a
    /// translation in metres. The quaternion is normalised; its norm must be
    /// within 1e-3 of 1.
    ///
    /// # Errors
    /// [`TransformError::NotFinite`], or [`TransformError::QuaternionNorm`] for
    /// a quaternion too far from unit length.
    pub fn from_quaternion(q: [f64; 4], translation: [f64; 3]) -> Result<Self, TransformError> {
        if q.iter().chain(translation.iter()).any(|v| !v.is_finite()) {
            return Err(TransformError::NotFinite);
        }
        let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > 1e-3 {
            return Err(TransformError::QuaternionNorm { norm });
        }
        let [x, y, z, w] = q.map(|v| v / norm);
        let rotation = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - z * w),
                2.0 * (x * z + y * w),
            ],
            [
                2.0 * (x * y + z * w),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - x * w),
            ],
            [
                2.0 * (x * z - y * w),
                2.0 * (y * z + x * w),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        Self::from_matrix(rotation, translation)
    }

    /// The rotation matrix, by rows.
    pub fn rotation(&self) -> [[f64; 3]; 3] {
        self.rotation
    }

    /// The translation, metres.
    pub fn translation(&self) -> [f64; 3] {
        self.translation
    }

    /// `R·p + t`, each row as `r0·x + r1·y + r2·z + t` left to right.
    #[inline(always)]
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        let t = &self.translation;
        [
            r[0][0] * p[0] + r[0][1] * p[1] + r[0][2] * p[2] + t[0],
            r[1][0] * p[0] + r[1][1] * p[1] + r[1][2] * p[2] + t[1],
            r[2][0] * p[0] + r[2][1] * p[1] + r[2][2] * p[2] + t[2],
        ]
    }
}

/// Why a transform was refused.
#[derive(Debug, Error, Clone, Copy, PartialEq)]
pub enum TransformError {
    /// An entry is NaN or infinite.
    #[error("transform has a NaN or infinite entry")]
    NotFinite,
    /// The matrix is not a rotation.
    #[error("transform rotation is not a rotation: RᵀR differs from I by {deviation:e} (tolerance 1e-6), determinant {determinant}")]
    NotRotation {
        /// Largest entry of `|RᵀR - I|`.
        deviation: f64,
        /// The determinant.
        determinant: f64,
    },
    /// The quaternion is far from unit length.
    #[error("transform quaternion has norm {norm}: it must be within 1e-3 of 1")]
    QuaternionNorm {
        /// Its norm.
        norm: f64,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quarter_turn_about_z_takes_x_to_y() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let t = RigidTransform::from_quaternion([0.0, 0.0, h, h], [1.0, 0.0, 0.0]).unwrap();
        let p = t.apply([1.0, 0.0, 0.0]);
        assert!((p[0] - 1.0).abs() < 1e-12 && (p[1] - 1.0).abs() < 1e-12 && p[2].abs() < 1e-12);
    }

    #[test]
    fn reflections_and_bad_quaternions_are_refused() {
        let m = [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(matches!(
            RigidTransform::from_matrix(m, [0.0; 3]),
            Err(TransformError::NotRotation { .. })
        ));
        assert!(matches!(
            RigidTransform::from_quaternion([0.0, 0.0, 0.0, 2.0], [0.0; 3]),
            Err(TransformError::QuaternionNorm { .. })
        ));
        assert_eq!(
            RigidTransform::from_quaternion([f64::NAN, 0.0, 0.0, 1.0], [0.0; 3]),
            Err(TransformError::NotFinite)
        );
    }
}
