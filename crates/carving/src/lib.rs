//! Haptic carving of a workpiece (the carving paper, Kishida & Miura:
//! docs/methods/carving.md).
//!
//! The workpiece is an equally spaced point grid whose points are OUTSIDE (air), BOUND
//! (material on the surface) or INSIDE (material inside) — the force model of seed §5 — and
//! the surfels (position, normal, radius, colour; seed §4) of its BOUND points, kept one per
//! BOUND point so their number is bounded by the grid whatever is cut ([`Workpiece`]).
//!
//! Tools ([`Tool`]) are convex prisms in their own frame: the knife (a rectangle, seed §4.2)
//! and the triangular chisel (an isosceles triangle, seed §4.3), both given a thickness so
//! that the solid they sweep has volume. [`Workpiece::carve`] removes the solid a tool sweeps
//! between two poses: exactly for a translation (a point is inside the sweep iff the
//! intervals of the sweep parameter allowed by each face have a common point —
//! docs/methods/carving.md#what-the-project-does-instead), and, for a rotation, by substeps
//! small enough that angle × tool radius < spacing / 2. Only the grid rows crossing the
//! sweep's bounding box are visited, and on each row the range of removed points is solved
//! for rather than searched. The classification uses the seed's band `d_s` (eq. 2):
//! material points next to removed ones become BOUND and take the cutting face's normal
//! (§5.2), their surfel projected onto that face; where a chisel's slanted face meets the
//! old surface, the old surfel slides onto the edge (eq. 6), and [`edge`] lines the edges
//! with the seed's eq. 7 polygons at display rate. The seed's tool surfels classified
//! against the workpiece (eqs. 3-5) are not needed for this; [`toolsurfel`] computes them
//! as a cross-check of the analytic classification.
//!
//! [`ForceRenderer`] turns what a step removed into a force (seed eq. 8, or the rate- and
//! resolution-independent cut cross-section of
//! docs/methods/carving.md#what-the-project-does-instead), low-pass filtered and through a
//! virtual coupling. [`cutout`] cuts the workpiece out along an axis from a binary image
//! (seed §4.1, eq. 1). [`exact`] holds the exact swept solid of a translating box, the
//! oracle of the accuracy benchmark and the tests.
//!
//! Nothing here knows of ROS, MCAP or clocks: the carving node (`chronotope_node::carving`) feeds
//! poses in and publishes what this module computes.
#![warn(missing_docs)]
// Indexing the three axes by number reads like the formulas; `!(a <= b)` is deliberate where
// a NaN must take the refusing branch.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

mod cut_stats;
pub mod cutout;
pub mod edge;
pub mod exact;
mod force;
mod math;
mod sweep;
mod tool;
pub mod toolsurfel;
mod workpiece;

pub use cut_stats::CutStats;
pub use force::{
    ForceModel, ForceParams, ForceRenderer, COUPLING_STABILITY_MARGIN, COUPLING_STEP_S,
    MAX_MOVE_DT_S,
};
pub use math::{Quat, Vec3};
pub use sweep::{MAX_SUBSTEPS, MAX_SWEEP_POINTS_PER_POSE, MAX_SWEEP_ROWS_PER_POSE};
pub use tool::{Tool, ToolKind};
pub use workpiece::{
    Flag, InvariantError, Surfel, SurfelDelta, Workpiece, BYTES_PER_POINT, MAX_POINTS,
    SURFEL_BYTES, WORKPIECE_MEMORY_BYTES,
};

/// Why a workpiece, tool or pose was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CarveError {
    /// A size or spacing that is not a finite positive number, or a grid too big.
    #[error("workpiece: {0}")]
    Workpiece(String),
    /// A tool dimension that is not a finite positive number (or a chisel angle out of range).
    #[error("tool: {0}")]
    Tool(String),
    /// An unknown tool name.
    #[error("unknown tool {0:?}: one of knife, chisel")]
    UnknownTool(String),
    /// An unknown force model name.
    #[error("force model {0:?}: one of count, volume, section")]
    UnknownForceModel(String),
    /// An unknown axis for a cut-out.
    #[error("axis {0:?}: one of x, y, z")]
    UnknownAxis(String),
    /// A pose with a non-finite position or a quaternion that cannot be normalised.
    #[error("pose: {0}")]
    Pose(String),
    /// Force parameters outside their domain, or a virtual coupling that would be unstable.
    #[error("{reason}")]
    Force {
        /// The parameter to change (its launch name).
        param: &'static str,
        /// Why, with the condition and the values.
        reason: String,
    },
    /// A move whose sweep would visit more grid rows or points than one pose may.
    #[error("the move sweeps {what} {got} grid {unit}: at most {max} per pose ({limit}); the tool moved {travel_m:.4} m and turned {angle_deg:.1} deg since the last pose")]
    TooMuchWork {
        /// What was counted ("rows of" or "points in bounding boxes of").
        what: &'static str,
        /// Its count.
        got: u64,
        /// "rows" or "points".
        unit: &'static str,
        /// The limit.
        max: u64,
        /// The limit's name.
        limit: &'static str,
        /// Distance the tool origin moved (m).
        travel_m: f64,
        /// Rotation of the move (degrees).
        angle_deg: f64,
    },
    /// A move needing more rotation substeps than allowed.
    #[error("the move rotates by {angle_deg:.1} deg: {substeps} substeps needed, at most {max}")]
    TooManySubsteps {
        /// Rotation of the move (degrees).
        angle_deg: f64,
        /// Substeps it would need.
        substeps: u64,
        /// The limit.
        max: u64,
    },
}

/// A pose of a tool: the tool frame's origin and orientation in the workpiece's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolPose {
    /// Origin of the tool frame (m).
    pub position: Vec3,
    /// Orientation (unit quaternion).
    pub rotation: Quat,
}

impl ToolPose {
    /// A pose from a position and a quaternion `(x, y, z, w)`; a non-unit quaternion is
    /// normalised.
    ///
    /// # Errors
    /// [`CarveError::Pose`] for a non-finite position or a quaternion whose norm is not a
    /// finite number above 1e-9 (a zero quaternion has no rotation to normalise to).
    pub fn new(position: Vec3, q: [f64; 4]) -> Result<Self, CarveError> {
        if !position.iter().all(|v| v.is_finite()) {
            return Err(CarveError::Pose(format!(
                "position {position:?} is not finite"
            )));
        }
        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !n.is_finite() || n < 1e-9 {
            return Err(CarveError::Pose(format!(
                "orientation quaternion {q:?} has norm {n}: not a rotation"
            )));
        }
        Ok(Self {
            position,
            rotation: Quat {
                w: q[3] / n,
                x: q[0] / n,
                y: q[1] / n,
                z: q[2] / n,
            },
        })
    }

    /// The identity orientation at `position`.
    pub fn at(position: Vec3) -> Self {
        Self {
            position,
            rotation: Quat::IDENTITY,
        }
    }
}
