//! What one move of the tool removed and exposed ([`CutStats`]): written by the sweeps and the
//! cut-out as they remove points, read by the force models.

use super::math::Vec3;

/// What one move removed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CutStats {
    /// Grid points removed (the seed's `n`, eq. 8).
    pub removed: u64,
    /// Of them, points that were on the surface (had a normal).
    pub removed_surface: u64,
    /// Sum of the outward normals of the removed surface points (`n · n_avg` of eq. 8).
    pub normal_sum: Vec3,
    /// Material points newly exposed or re-oriented (surfels put or moved).
    pub exposed: u64,
    /// Surfels moved onto a chisel edge (eq. 6).
    pub resampled: u64,
    /// Rotation substeps used.
    pub substeps: u32,
    /// Material points in the layer one spacing ahead of the tool after the move
    /// ([`Workpiece::material_ahead`](super::Workpiece::material_ahead)).
    pub ahead: u64,
    /// The cut cross-section read off the material ahead of the tool after the move, with
    /// sub-voxel weights (m², [`Workpiece::section_ahead`](super::Workpiece::section_ahead)): what the `section` force uses.
    pub ahead_area: f64,
    /// Distance swept: the tool origin's displacement plus rotation angle x tool radius (m).
    pub travel: f64,
}
