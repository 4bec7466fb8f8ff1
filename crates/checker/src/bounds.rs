//! Error bounds of the checker's answers from the lattice: voxel edge h, frame period Δt
//! and the relative speed of the two boundaries (docs/checker.md, "Error bounds").
//!
//! Each body's 4D mesh places its boundary within h/2 of the sampled one in space (a
//! marching-cubes vertex lies on the edge between an occupied and a free sample, where the
//! true boundary crosses too) and within Δt/2 in time (between two frames the surface is
//! interpolated linearly). Everything below is first order in h and Δt.
//!
//! - **Contact times** (first contact, interval ends): the two boundaries approach at the
//!   closing speed v (the sum of the speeds of both boundary patches along their spatial
//!   normals, estimated from the mesh at the contact). A boundary off by h/2 + v_i·Δt/2
//!   per body shifts the contact by (h + v·Δt/2)/v, so |error| ≤ Δt/2 + h/v
//!   = Δt·(1/2 + 1/v') with v' in voxels per frame period. No bound when v ≤ 0 (a grazing
//!   contact: its time is ill-conditioned).
//! - **Overlap hypervolume**: moving a boundary by w changes the enclosed 4-volume by
//!   ∫ w·n̂ dV₃, so |error| ≤ Σ_τ (h/2·|N_s| + Δt/2·|N_t|)/6 over the tets τ of the overlap
//!   body's boundary (N the tet's normal, |N| = 6 × its 3-volume, in m and s).
//! - **Translation distance**: each body's boundary is off by at most
//!   e = √((h/2)² + (c·Δt/2)²) in the metric, so the shortest clearing distance by at most
//!   2e = √(h² + (c·Δt)²), plus the snapping of the vector to the checker lattice.

use chronotope_kernel::float::tet_normal;
use chronotope_mesh::{GridGeometry, TetMesh};

/// Bound (s) on the error of a contact time at closing speed `speed` (voxels per frame
/// period) with frame period `period_s`; `None` unless the boundaries approach.
pub fn contact_time_bound(period_s: f64, speed: Option<f64>) -> Option<f64> {
    let v = speed?;
    (v.is_finite() && v > 1e-6).then(|| period_s * (0.5 + 1.0 / v))
}

/// Bound (m³·s) on the error of the hypervolume enclosed by `mesh` (lattice units of `g`,
/// one frame period `period_s` per `g.scale` time units).
pub fn hypervolume_bound(mesh: &TetMesh, g: &GridGeometry, period_s: f64) -> f64 {
    let s = f64::from(g.scale);
    let (hx, ht) = (g.resolution / s, period_s / s);
    let (space, time) = mesh.tets.iter().fold((0.0, 0.0), |(sp, tm), t| {
        let n = tet_normal(&t.map(|v| mesh.vertices[v as usize]));
        let ns = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        (sp + ns, tm + n[3].abs())
    });
    // N_x etc. carry two spatial edges and one time edge; N_t three spatial edges.
    let (ns_phys, nt_phys) = (space * hx * hx * ht, time * hx * hx * hx);
    (0.5 * g.resolution * ns_phys + 0.5 * period_s * nt_phys) / 6.0
}

/// Bound (m) on the error of a translation distance in the metric (x, y, z, c·t), for
/// voxel edge `voxel_m`, frame period `period_s`, time scale `c` (m/s), plus `snap_m`, the
/// length of one checker lattice step.
pub fn translation_bound(voxel_m: f64, period_s: f64, c: f64, snap_m: f64) -> f64 {
    (voxel_m * voxel_m + (c * period_s).powi(2)).sqrt() + snap_m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_bound_needs_an_approach() {
        assert_eq!(contact_time_bound(0.1, None), None);
        assert_eq!(contact_time_bound(0.1, Some(0.0)), None);
        assert_eq!(contact_time_bound(0.1, Some(-1.0)), None);
        // One voxel per frame: half a frame from time, one from space.
        assert!((contact_time_bound(0.1, Some(1.0)).unwrap() - 0.15).abs() < 1e-12);
    }

    #[test]
    fn side_facets_count_half_a_voxel_and_caps_half_a_frame() {
        // Unit lattice steps of 1 m and 1 s; one tet of the facet x = 0 of a box.
        let g = GridGeometry {
            origin: [0.0; 3],
            resolution: 1.0,
            size: [1, 1, 1],
            encoding: 0,
            scale: 1,
        };
        let mut m = TetMesh::default();
        // One facet x = 0 as a single tet (3-volume 1/6): |N| = 1 along x.
        m.vertices = vec![[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]];
        m.tets = vec![[0, 1, 2, 3]];
        let b = hypervolume_bound(&m, &g, 1.0);
        assert!((b - 0.5 / 6.0).abs() < 1e-12, "{b}");
        // The same tet in the cap t = 0 counts half a frame period instead.
        m.vertices = vec![[0, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]];
        let b = hypervolume_bound(&m, &g, 2.0);
        assert!((b - 1.0 / 6.0).abs() < 1e-12, "{b}");
    }
}
