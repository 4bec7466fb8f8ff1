//! Streaming statistics and validation of one body's 4D mesh, slab by slab.
//!
//! The glued mesh of a stream is every slab's lateral tets plus the cap of the first frame
//! and the cap of the last frame (the caps between slabs cancel). It is validated without
//! ever holding more than one slab:
//! - within a slab, every triangle not lying in one of its two time planes is shared by
//!   exactly two tets with opposite induced orientation;
//! - the triangles in the slab's lower time plane pair (with opposite orientation) with the
//!   previous slab's upper-plane triangles, or with the first cap's boundary;
//! - the last slab's upper-plane triangles pair with the last cap's boundary.
//!
//! The hypervolume is summed per slab, each slab closed by its caps, in the slab's own
//! physical time scale (frame periods may differ). The upper cap's contribution to the
//! divergence sum follows from its boundary alone (a 3-chain in a hyperplane contributes
//! Σ det[o, ∂]), so caps between slabs are never built.

use super::march::TetMesh;
use super::mesher::{GridGeometry, Slab};
use super::validate::{canonical_triangle, pair_faces, tet_faces, ClosedReport};
use crate::kernel::det4_i128;

/// A triangle in a plane of constant t: three (x, y, z) points, sorted.
type PlaneTri = [[i32; 3]; 3];

/// Per-body statistics over a stream.
#[derive(Debug, Clone, Default)]
pub struct BodyStats {
    /// Frames accepted.
    pub frames: u64,
    /// Slabs meshed.
    pub slabs: u64,
    /// Tets of the glued mesh (lateral + first and last caps).
    pub tets: u64,
    /// Vertices of the glued mesh.
    pub vertices: u64,
    /// Closedness over the whole glued mesh.
    pub closed: ClosedReport,
    /// Hypervolume [m³·s].
    pub hypervolume_m3s: f64,
    /// Hypervolume in lattice units (exact, ×24 per slab, summed as f64 for reporting).
    pub hypervolume_lattice: f64,
    /// Milliseconds spent meshing each slab.
    pub slab_ms: Vec<f64>,
}

impl BodyStats {
    /// Median of the per-slab times [ms] (0 with no slabs).
    pub fn slab_ms_median(&self) -> f64 {
        percentile(&self.slab_ms, 0.5)
    }
    /// 99th percentile of the per-slab times [ms].
    pub fn slab_ms_p99(&self) -> f64 {
        percentile(&self.slab_ms, 0.99)
    }
}

/// Nearest-rank percentile of unsorted samples.
pub fn percentile(samples: &[f64], q: f64) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    let mut s = samples.to_vec();
    s.sort_by(f64::total_cmp);
    let rank = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len());
    s[rank - 1]
}

/// Accumulates [`BodyStats`] slab by slab.
#[derive(Debug, Default)]
pub struct StatsAccumulator {
    stats: BodyStats,
    prev_hi: Vec<(PlaneTri, i8)>,
    lateral_vertices: u64,
    shared_vertices: u64,
}

impl StatsAccumulator {
    /// A fresh accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records the meshing time of one slab.
    pub fn record_time(&mut self, ms: f64) {
        self.stats.slab_ms.push(ms);
    }

    /// Adds a slab. For the first slab, `first_cap` must be the cap of its first frame
    /// ([`super::CapSide::Low`]).
    pub fn add_slab(&mut self, slab: &Slab, first_cap: Option<&TetMesh>) {
        let (t_lo, t_hi) = (slab.t_lo(), slab.t_hi());
        let m = &slab.mesh;
        let mut interior: Vec<([u32; 3], i8)> = Vec::with_capacity(m.tets.len() * 4);
        let mut lo: Vec<(PlaneTri, i8)> = Vec::new();
        let mut hi: Vec<(PlaneTri, i8)> = Vec::new();
        let mut vol24: i128 = 0;
        let mut hi_cone: i128 = 0;
        for t in &m.tets {
            let p = t.map(|v| m.vertices[v as usize]);
            let local = p.map(|q| [q[0], q[1], q[2], q[3] - t_lo]);
            vol24 -= det4_i128(&local[0], &local[1], &local[2], &local[3]);
            for (f, s) in tet_faces([0usize, 1, 2, 3]) {
                let ts = f.map(|i| p[i][3]);
                if ts.iter().all(|&v| v == t_lo) || ts.iter().all(|&v| v == t_hi) {
                    let (key, parity) = canonical_triangle(f.map(|i| [p[i][0], p[i][1], p[i][2]]));
                    let s = s * parity;
                    if ts[0] == t_lo {
                        lo.push((key, s));
                    } else {
                        hi_cone += i128::from(s) * det3_i128(&key);
                        hi.push((key, s));
                    }
                } else {
                    let (key, parity) = canonical_triangle(f.map(|i| t[i]));
                    interior.push((key, s * parity));
                }
            }
        }
        // Upper cap: Σ det over its tets = Σ over its boundary (the upper faces, reversed)
        // of det[o, p, q, r] with o = (0, 0, 0, T), which is −T·det3[p, q, r].
        vol24 -= i128::from(t_hi - t_lo) * hi_cone;
        self.merge(pair_faces(interior));

        // Lower plane: pairs with the previous slab's upper plane, or the first cap.
        let mut boundary = std::mem::take(&mut self.prev_hi);
        if self.stats.slabs == 0 {
            if let Some(cap) = first_cap {
                boundary = cap_faces(cap);
            }
        } else {
            self.shared_vertices += count_plane_vertices(m, t_lo);
        }
        boundary.extend(lo);
        self.merge(pair_faces(boundary));
        self.prev_hi = hi;

        self.lateral_vertices += m.vertices.len() as u64;
        self.stats.tets += m.tets.len() as u64;
        self.stats.slabs += 1;
        self.add_volume(vol24, &slab.geometry, slab.stamp_hi_ns - slab.stamp_lo_ns);
    }

    fn add_volume(&mut self, vol24: i128, g: &GridGeometry, dt_ns: i64) {
        let v = vol24 as f64 / 24.0;
        self.stats.hypervolume_lattice += v;
        let step = g.step_m();
        self.stats.hypervolume_m3s += v * step * step * step * (dt_ns as f64 * 1e-9) / f64::from(g.scale);
    }

    fn merge(&mut self, r: ClosedReport) {
        let c = &mut self.stats.closed;
        c.triangles += r.triangles;
        c.unpaired += r.unpaired;
        c.overshared += r.overshared;
        c.misoriented += r.misoriented;
    }

    /// Closes the stream: `first_cap` / `last_cap` are the caps of the first and last
    /// frames with their number of occupied voxels (interior cap vertices). `frames` is the
    /// number of accepted frames.
    pub fn finish(
        mut self,
        frames: u64,
        first_cap: Option<(&TetMesh, u64)>,
        last_cap: Option<(&TetMesh, u64)>,
    ) -> BodyStats {
        self.stats.frames = frames;
        if self.stats.slabs > 0 {
            if let Some((cap, _)) = last_cap {
                let mut boundary = std::mem::take(&mut self.prev_hi);
                boundary.extend(cap_faces(cap));
                self.merge(pair_faces(boundary));
            }
            for (cap, occupied) in [first_cap, last_cap].into_iter().flatten() {
                self.stats.tets += cap.tets.len() as u64;
                self.lateral_vertices += occupied;
            }
            self.stats.vertices = self.lateral_vertices - self.shared_vertices;
        }
        self.stats
    }
}

fn det3_i128(t: &PlaneTri) -> i128 {
    let m = |p: &[i32; 3]| p.map(i128::from);
    let (a, b, c) = (m(&t[0]), m(&t[1]), m(&t[2]));
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// Every face of a cap's tets, keyed by coordinates (a cap lies in one t plane).
fn cap_faces(cap: &TetMesh) -> Vec<(PlaneTri, i8)> {
    let mut out = Vec::with_capacity(cap.tets.len() * 4);
    for t in &cap.tets {
        for (f, s) in tet_faces(*t) {
            let (key, parity) = canonical_triangle(f.map(|v| {
                let p = cap.vertices[v as usize];
                [p[0], p[1], p[2]]
            }));
            out.push((key, s * parity));
        }
    }
    out
}

fn count_plane_vertices(m: &TetMesh, t: i32) -> u64 {
    m.vertices.iter().filter(|p| p[3] == t).count() as u64
}
