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
//! Matching a time plane's triangles from its two sides uses two order-independent 128-bit
//! multiset hashes (each a sum of per-triangle hashes from multiply-folding lanes, see
//! `tri_hash`): one adds each triangle's hash with its orientation as sign (a matching
//! pair cancels), the other without sign (both sides must carry the same triangles, as
//! many times each). O(n), no sorting. Only when either check fails are the triangles
//! sorted and paired exactly, and then the report counts exactly what is wrong. What the
//! hashes cannot see is a triangle present k > 1 times on *both* sides with balanced
//! orientations (over-shared but consistent); the exact fallback is not run then. (Were
//! the triangle hash a random function, two different multisets would hash equal with
//! probability about 2^-128.) A slab's interior triangles are checked the same way, by one
//! signed hash of their vertex ids (`FaceHash`), and paired exactly (gathered by their
//! smallest vertex) only when it does not cancel. A cap (a frame's whole volume) is checked
//! with the plane it closes by one signed hash of all its faces, keyed by coordinates: its
//! interior faces cancel in it, and its boundary's cancel the plane's triangles; its faces
//! are paired exactly only when they do not (the same blind spot as for a slab's interior
//! faces). `validate::check_closed`, which the tests run on whole meshes, always pairs exactly.
//!
//! A slab that is one of the latest few distinct ones (`RECENT_SLABS`, 4; a rest counts
//! once) moved by whole periods in time and whole lattice steps in space, compared exactly,
//! adds that slab's figures again without a scan: its interior faces pair as that slab's
//! did, its planes' triangles are that slab's moved (hashed again when moved in space), and
//! its hypervolume is the same (moved in space, only when the slab copied is closed: its two
//! planes then bound, and the hypervolume of a closed slab does not depend on where it
//! lies). A body at rest is scanned once; one stepping by whole voxels at a steady pace
//! about once: its step slabs and its rests after a step are the earlier ones moved.
//!
//! The hypervolume is summed per slab, each slab closed by its caps, in the slab's own
//! physical time scale (frame periods may differ): the flux of the field (0, 0, 0, t) out
//! of the closed slab (its divergence is 1), with t measured from the slab's lower plane, so
//! that the lower cap has none, and the upper cap's follows from its boundary alone (its
//! 3-volume, Σ det3 over its boundary triangles), so caps between slabs are never built.
//! A lateral tet's flux is its vertices' mean time times its normal's time component, one
//! 3×3 determinant of its spatial edges (the cone from the origin took four).

use std::sync::Arc;

use chronotope_kernel::LatticePoint;

use rayon::prelude::*;

use super::grid::GridGeometry;
use super::march::TetMesh;
use super::mesher::Slab;
use super::validate::{
    canonical_tet_faces, canonical_triangle, id_bits, pair_by_first_vertex, pair_plane_faces,
    tet_faces, ClosedReport, FaceParts, FaceShape, PACKED_VERTEX_LIMIT,
};

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
    /// Hypervolume (m³·s).
    pub hypervolume_m3s: f64,
    /// Hypervolume in lattice units (exact, ×24 per slab, summed as f64 for reporting).
    pub hypervolume_lattice: f64,
    /// Milliseconds spent meshing each slab.
    pub slab_ms: Vec<f64>,
    /// Slabs in which the body vanishes between its two frames (see
    /// [`Slab::vanishes`]): the frame rate is too low for its motion there.
    pub vanishing_slabs: u64,
}

impl BodyStats {
    /// Median of the per-slab times (ms) (0 with no slabs).
    pub fn slab_ms_median(&self) -> f64 {
        percentile(&self.slab_ms, 0.5)
    }
    /// 99th percentile of the per-slab times (ms).
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

/// A slab's lateral tets and placement, borrowed (see [`StatsAccumulator::add_lateral`]).
#[derive(Debug, Clone, Copy)]
pub struct LateralRef<'a> {
    /// Index of the slab's first frame.
    pub index: u64,
    /// Stamps of its two frames (ns).
    pub stamps_ns: (i64, i64),
    /// The lattice.
    pub geometry: &'a GridGeometry,
    /// Lateral tets.
    pub mesh: &'a TetMesh,
    /// See [`Slab::unsure`].
    pub unsure: Option<super::unsure::Unsure>,
    /// See [`Slab::displacement`].
    pub displacement: u16,
}

impl LateralRef<'_> {
    /// A part of the body vanishes between the slab's frames.
    pub fn vanishes(&self) -> bool {
        matches!(self.unsure, Some(super::unsure::Unsure::Vanishes { .. }))
    }
}

impl Slab {
    /// The slab's parts, borrowed, as the statistics read them.
    pub fn lateral_ref(&self) -> LateralRef<'_> {
        LateralRef {
            index: self.index,
            stamps_ns: (self.stamp_lo_ns, self.stamp_hi_ns),
            geometry: &self.geometry,
            mesh: &self.mesh,
            unsure: self.unsure,
            displacement: self.displacement,
        }
    }
}

/// Accumulates [`BodyStats`] slab by slab.
#[derive(Debug, Default)]
pub struct StatsAccumulator {
    stats: BodyStats,
    /// The upper plane's triangles of the last slab (shared with its figures when kept).
    prev_hi: Arc<[(PlaneTri, i8)]>,
    prev_hi_hash: PlaneHash,
    scratch: Vec<u64>,
    lateral_vertices: u64,
    shared_vertices: u64,
    /// The latest slabs added through [`StatsAccumulator::add_lateral_shared`] (at most
    /// [`RECENT_SLABS`], newest last), with what a moved copy of one adds again.
    recent: std::collections::VecDeque<Recent>,
    /// Slabs added as copies of one of the latest, unmoved and moved in space.
    copies: [u64; 2],
}

/// How many of the latest slabs a new one is compared with (see
/// [`StatsAccumulator::add_lateral_shared`]); a rest, however long, holds one place (its
/// latest slab). A table stepping by whole voxels now and then repeats its step slab after
/// its next rest, moved.
const RECENT_SLABS: usize = 4;

/// One of the latest slabs (see [`StatsAccumulator::recent`]): its tets, index and lattice
/// step, and its figures.
#[derive(Debug)]
struct Recent {
    mesh: Arc<TetMesh>,
    index: u64,
    scale: i32,
    figures: Arc<SlabFigures>,
}

/// What a slab added to the figures, kept to add again for a copy of it moved (see
/// [`TetMesh::is_moved_copy_of`]): its interior faces' report, its hypervolume, the
/// triangles of its two time planes with their hashes, and the number of vertices in its
/// lower plane.
#[derive(Debug)]
struct SlabFigures {
    interior: ClosedReport,
    vol24: i128,
    lo: Vec<(PlaneTri, i8)>,
    lo_hash: PlaneHash,
    hi: Arc<[(PlaneTri, i8)]>,
    hi_hash: PlaneHash,
    lo_vertices: u64,
}

impl SlabFigures {
    /// The figures of the slab moved by `d` in space: the same faces and hypervolume, its
    /// planes' triangles moved (sorted points stay sorted) and hashed again.
    fn moved(&self, d: [i32; 3]) -> Self {
        let plane = |tris: &[(PlaneTri, i8)]| {
            let mut hash = PlaneHash::default();
            let moved: Vec<(PlaneTri, i8)> = tris
                .iter()
                .map(|(t, s)| {
                    let t = t.map(|p| [p[0] + d[0], p[1] + d[1], p[2] + d[2]]);
                    hash.add(&t, *s);
                    (t, *s)
                })
                .collect();
            (moved, hash)
        };
        let ((lo, lo_hash), (hi, hi_hash)) = (plane(&self.lo), plane(&self.hi));
        Self {
            interior: self.interior,
            vol24: self.vol24,
            lo,
            lo_hash,
            hi: hi.into(),
            hi_hash,
            lo_vertices: self.lo_vertices,
        }
    }
}

impl StatsAccumulator {
    /// A fresh accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// The statistics of the slabs added so far (the caps' tets and vertices, and the
    /// closing plane's faces, count only at [`finish`](Self::finish)).
    pub fn so_far(&self) -> &BodyStats {
        &self.stats
    }

    /// How many slabs were added as copies of one of the latest (see
    /// [`Self::add_lateral_shared`]): moved in time only, and moved in space too.
    pub fn copies(&self) -> [u64; 2] {
        self.copies
    }

    /// Records the meshing time of one slab.
    pub fn record_time(&mut self, ms: f64) {
        self.stats.slab_ms.push(ms);
    }

    /// Adds a slab. For the first slab, `first_cap` must be the cap of its first frame
    /// ([`super::CapSide::Low`]).
    pub fn add_slab(&mut self, slab: &Slab, first_cap: Option<&TetMesh>) {
        self.add_lateral(slab.lateral_ref(), first_cap);
    }

    /// [`Self::add_slab`] for a slab given by its parts (e.g. received as a message).
    pub fn add_lateral(&mut self, slab: LateralRef<'_>, first_cap: Option<&TetMesh>) {
        self.add_lateral_in_chunks(slab, first_cap, SCAN_CHUNK_TETS, None);
    }

    /// [`Self::add_lateral`] for a slab whose tets are `shared` (`slab.mesh` must be
    /// them), kept for the next few slabs: a slab that is one of the latest
    /// `RECENT_SLABS` (4) moved by whole periods in time and whole lattice steps in space
    /// (compared exactly, [`TetMesh::is_moved_copy_of`]) adds its figures again without
    /// scanning its tets: a body at rest, or one stepping by whole voxels. Returns whether
    /// `slab` is the slab before it one period later (the body rests).
    pub fn add_lateral_shared(
        &mut self,
        slab: LateralRef<'_>,
        first_cap: Option<&TetMesh>,
        shared: &Arc<TetMesh>,
    ) -> bool {
        debug_assert!(std::ptr::eq(slab.mesh, &**shared));
        if let Some(at_rest) = self.add_copy(slab, shared) {
            return at_rest;
        }
        self.add_lateral_in_chunks(slab, first_cap, SCAN_CHUNK_TETS, Some(shared));
        false
    }

    /// Adds `slab` as a moved copy of one of the latest slabs, if it is one; whether it is
    /// the last slab one period later.
    fn add_copy(&mut self, slab: LateralRef<'_>, shared: &Arc<TetMesh>) -> Option<bool> {
        let scale = slab.geometry.scale;
        let (k, d) = self.recent.iter().enumerate().rev().find_map(|(k, r)| {
            let periods = i32::try_from(slab.index.checked_sub(r.index)?).ok()?;
            let (p, q) = (slab.mesh.vertices.first()?, r.mesh.vertices.first()?);
            let d = [
                p[0].checked_sub(q[0])?,
                p[1].checked_sub(q[1])?,
                p[2].checked_sub(q[2])?,
                periods.checked_mul(scale)?,
            ];
            // Moved in space, its hypervolume is the same only if it is a closed slab
            // (its interior faces paired, so its two planes bound): else it is scanned.
            let moved = d[..3] != [0, 0, 0];
            (periods > 0
                && r.scale == scale
                && (!moved || r.figures.interior.is_closed())
                && slab.mesh.is_moved_copy_of(&r.mesh, d))
            .then_some((k, d))
        })?;
        let source = &self.recent[k];
        let at_rest = k + 1 == self.recent.len() && d == [0, 0, 0, scale];
        let moved = d[..3] != [0, 0, 0];
        let figures = if !moved {
            source.figures.clone()
        } else {
            Arc::new(source.figures.moved([d[0], d[1], d[2]]))
        };
        // Its interior faces pair as the source's did; its lower plane pairs with the
        // previous slab's upper one, and its upper plane is the next slab's partner.
        self.merge(figures.interior);
        let prev_hi = std::mem::take(&mut self.prev_hi);
        self.match_planes(&prev_hi, self.prev_hi_hash, &figures.lo, figures.lo_hash);
        self.prev_hi = figures.hi.clone();
        self.prev_hi_hash = figures.hi_hash;
        self.copies[usize::from(moved)] += 1;
        self.shared_vertices += figures.lo_vertices;
        self.lateral_vertices += slab.mesh.vertices.len() as u64;
        self.stats.vanishing_slabs += u64::from(slab.vanishes());
        self.stats.tets += slab.mesh.tets.len() as u64;
        self.stats.slabs += 1;
        self.add_volume(
            figures.vol24,
            slab.geometry,
            slab.stamps_ns.1 - slab.stamps_ns.0,
        );
        // The newest slab one period on stands for the rest from here: it takes that slab's
        // place, so that a rest of any length holds one place, and a body stepping every
        // few periods still finds its last step slab among the latest.
        if at_rest {
            self.recent.pop_back();
        }
        self.remember(Recent {
            mesh: shared.clone(),
            index: slab.index,
            scale,
            figures,
        });
        Some(at_rest)
    }

    /// Keeps `r` among the latest slabs.
    fn remember(&mut self, r: Recent) {
        if self.recent.len() == RECENT_SLABS {
            self.recent.pop_front();
        }
        self.recent.push_back(r);
    }

    /// [`Self::add_lateral`], scanning the tets in chunks of `chunk_tets` on rayon's pool.
    fn add_lateral_in_chunks(
        &mut self,
        slab: LateralRef<'_>,
        first_cap: Option<&TetMesh>,
        chunk_tets: usize,
        shared: Option<&Arc<TetMesh>>,
    ) {
        let chunk_tets = chunk_tets.max(1);
        let t_lo = slab.geometry.scale * slab.index as i32;
        let t_hi = t_lo + slab.geometry.scale;
        let m = slab.mesh;
        // Which time plane each vertex lies in: bit 0 lower, bit 1 upper.
        let plane: Vec<u8> = m
            .vertices
            .iter()
            .map(|p| u8::from(p[3] == t_lo) | (u8::from(p[3] == t_hi) << 1))
            .collect();
        // The tets in chunks on rayon's pool: every figure below is an exact sum or an
        // order-independent set, so the result does not depend on the chunking.
        let chunk = |tets: &[[u32; 4]]| {
            let mut c = Scan::default();
            for t in tets {
                let p = t.map(|v| m.vertices[v as usize]);
                c.vol24 += time_flux24(&p, t_lo);
                let (sorted, order) = canonical_tet_faces(*t);
                let flags = order.map(|i| plane[t[i] as usize]);
                for (j, (key, s)) in sorted.into_iter().enumerate() {
                    // The face omits the j-th smallest id (the others in order, as `key`).
                    let f = FACE_CORNERS[j];
                    let on = flags[f[0]] & flags[f[1]] & flags[f[2]];
                    if on != 0 {
                        let (key, parity) = canonical_triangle(f.map(|k| {
                            let q = p[order[k]];
                            [q[0], q[1], q[2]]
                        }));
                        let s = s * parity;
                        if on & 1 != 0 {
                            c.lo_hash.add(&key, s);
                            c.lo.push((key, s));
                        } else {
                            c.hi_cone += i128::from(s) * det3(&key);
                            c.hi_hash.add(&key, s);
                            c.hi.push((key, s));
                        }
                    } else {
                        // Off the time planes: it pairs inside the slab.
                        c.interior.add(&key, s);
                    }
                }
            }
            c
        };
        let scan = || -> Vec<Scan> {
            if m.tets.len() <= chunk_tets {
                vec![chunk(&m.tets)]
            } else {
                m.tets.par_chunks(chunk_tets).map(chunk).collect()
            }
        };
        // The first slab's lower plane pairs with the first cap: its boundary is found
        // while the slab is scanned.
        let cap = first_cap.filter(|_| self.stats.slabs == 0);
        let (parts, cap) = match cap {
            Some(cap) => {
                let (parts, faces) = rayon::join(scan, || CapFaces::of(cap));
                (parts, Some((cap, faces)))
            }
            None => (scan(), None),
        };
        let mut parts = parts.into_iter();
        let Scan {
            mut vol24,
            mut hi_cone,
            mut lo,
            mut hi,
            mut lo_hash,
            mut hi_hash,
            mut interior,
        } = parts.next().unwrap_or_default();
        for c in parts {
            vol24 += c.vol24;
            hi_cone += c.hi_cone;
            lo_hash.merge(&c.lo_hash);
            hi_hash.merge(&c.hi_hash);
            interior.merge(&c.interior);
            lo.extend(c.lo);
            hi.extend(c.hi);
        }
        // Upper cap (in the plane t = T): its flux is 4T times the sum of its tets' signed
        // 3-volumes (×6), which is the sum over its boundary (the upper faces, reversed) of
        // det3[p, q, r].
        vol24 -= 4 * i128::from(t_hi - t_lo) * hi_cone;
        // Every interior face twice, in opposite orientations: by their hash; exactly (each
        // face paired by its ids) only if the hash says otherwise.
        let interior = match interior.paired() {
            Some(report) => report,
            None => pair_interior_faces(m, &plane, chunk_tets, &mut self.scratch),
        };
        self.merge(interior);
        let lo_vertices = plane.iter().filter(|&&f| f & 1 != 0).count() as u64;

        // Lower plane: pairs with the previous slab's upper plane, or the first cap.
        if self.stats.slabs == 0 {
            match cap {
                Some((cap, faces)) => self.close_with_cap(cap, faces, &lo, lo_hash),
                // No opening cap (not built): the first lower plane stays open.
                None => self.merge(pair_plane_faces(lo.clone())),
            }
        } else {
            self.shared_vertices += lo_vertices;
            let prev = std::mem::take(&mut self.prev_hi);
            self.match_planes(&prev, self.prev_hi_hash, &lo, lo_hash);
        }
        let hi: Arc<[(PlaneTri, i8)]> = hi.into();
        if let Some(mesh) = shared {
            self.remember(Recent {
                mesh: mesh.clone(),
                index: slab.index,
                scale: slab.geometry.scale,
                figures: Arc::new(SlabFigures {
                    interior,
                    vol24,
                    lo,
                    lo_hash,
                    hi: hi.clone(),
                    hi_hash,
                    lo_vertices,
                }),
            });
        }
        self.prev_hi = hi;
        self.prev_hi_hash = hi_hash;

        self.lateral_vertices += m.vertices.len() as u64;
        self.stats.vanishing_slabs += u64::from(slab.vanishes());
        self.stats.tets += m.tets.len() as u64;
        self.stats.slabs += 1;
        self.add_volume(vol24, slab.geometry, slab.stamps_ns.1 - slab.stamps_ns.0);
    }

    fn add_volume(&mut self, vol24: i128, g: &GridGeometry, dt_ns: i64) {
        let v = vol24 as f64 / 24.0;
        self.stats.hypervolume_lattice += v;
        let step = g.step_m();
        self.stats.hypervolume_m3s +=
            v * step * step * step * (dt_ns as f64 * 1e-9) / f64::from(g.scale);
    }

    /// Checks that two sides of one time plane carry the same triangles with opposite
    /// orientations: by multiset hash, exactly (sorting) only if the hashes disagree.
    fn match_planes(
        &mut self,
        a: &[(PlaneTri, i8)],
        a_hash: PlaneHash,
        b: &[(PlaneTri, i8)],
        b_hash: PlaneHash,
    ) {
        if a_hash.matches(&b_hash) && a.len() == b.len() {
            self.stats.closed.triangles += a.len() as u64;
        } else {
            self.merge(pair_plane_faces([a, b].concat()));
        }
    }

    /// Checks a cap against the time plane it closes (`plane`: that plane's triangles as
    /// its slab has them, and their hash): every face of the cap, hashed, cancels with the
    /// plane's triangles when the cap's interior faces pair and its boundary is the plane's
    /// triangles reversed; only if they do not are the cap's faces paired exactly (as
    /// [`cap_boundary`] does) and its boundary matched with the plane.
    fn close_with_cap(
        &mut self,
        cap: &TetMesh,
        faces: CapFaces,
        plane: &[(PlaneTri, i8)],
        plane_hash: PlaneHash,
    ) {
        let all = faces.faces + plane.len() as u64;
        if faces.signed.wrapping_add(plane_hash.signed) == 0 && all.is_multiple_of(2) {
            // Its interior faces in pairs and its boundary paired with the plane: as many
            // triangles as half of all.
            self.stats.closed.triangles += all / 2;
        } else {
            let (report, boundary, hash) = cap_boundary(cap);
            self.merge(report);
            self.match_planes(&boundary, hash, plane, plane_hash);
        }
    }

    fn merge(&mut self, r: ClosedReport) {
        let c = &mut self.stats.closed;
        c.triangles += r.triangles;
        c.unpaired += r.unpaired;
        c.overshared += r.overshared;
        c.misoriented += r.misoriented;
    }

    /// Closes the stream: `first_cap` is the number of tets of the first frame's cap (checked
    /// with the first slab), `last_cap` the cap of the last frame, each with their number of
    /// occupied voxels (interior cap vertices). `frames` is the number of accepted frames.
    pub fn finish(
        mut self,
        frames: u64,
        first_cap: Option<(u64, u64)>,
        last_cap: Option<(&TetMesh, u64)>,
    ) -> BodyStats {
        self.stats.frames = frames;
        if self.stats.slabs > 0 {
            let prev = std::mem::take(&mut self.prev_hi);
            match last_cap {
                Some((cap, _)) => {
                    let hash = self.prev_hi_hash;
                    self.close_with_cap(cap, CapFaces::of(cap), &prev, hash);
                }
                // No closing cap (not built): the last upper plane stays open.
                None => self.merge(pair_plane_faces(prev.to_vec())),
            }
            let last_cap = last_cap.map(|(cap, occupied)| (cap.tets.len() as u64, occupied));
            for (tets, occupied) in [first_cap, last_cap].into_iter().flatten() {
                self.stats.tets += tets;
                self.lateral_vertices += occupied;
            }
            self.stats.vertices = self.lateral_vertices - self.shared_vertices;
        }
        self.stats
    }
}

/// 24 times the flux of the field (0, 0, 0, t − `t_lo`) out through a tet of a slab's
/// lateral mesh: the sum of its vertices' times above the slab's lower plane times det3 of
/// its spatial edges (from its first vertex), the time component of its outward normal
/// scaled by six times its 3-volume (a stored tet's `cross4` normal points into the body:
/// its time component is −det3). Summed over a closed slab (the lower cap has no flux: its
/// time is 0; the upper one's is added from its boundary) it is 24 times the slab's
/// hypervolume, as the divergence of that field is 1; against the cone from the origin
/// (`det4` of the four points) it takes one 3×3 determinant, not four.
#[inline]
fn time_flux24(p: &[LatticePoint; 4], t_lo: i32) -> i128 {
    let d = |q: &LatticePoint| [0, 1, 2].map(|k| i64::from(q[k]) - i64::from(p[0][k]));
    let (u, v, w) = (d(&p[1]), d(&p[2]), d(&p[3]));
    let t: i64 = p.iter().map(|q| i64::from(q[3]) - i64::from(t_lo)).sum();
    // Within one lattice hypercube the edges are at most 2^11 and the times 2^10 apart; in
    // i64 while the minor (below 6·2^60) and its product with the times fit, else in i128.
    let small = |x: i64| x.abs() <= 1 << 20;
    if u.iter().chain(&v).chain(&w).all(|&x| small(x)) && small(t) {
        let m = det3_rows(u, v, w);
        return match m.checked_mul(t) {
            Some(x) => i128::from(x),
            None => i128::from(m) * i128::from(t),
        };
    }
    // Exact while the edges and the times are below 2^30, as the kernel's predicates assume
    // (|m·t| < 6·2^90 · 4·2^30); a malformed piece beyond that gets a wrong figure, not a
    // panic.
    let m = det3_rows(u.map(i128::from), v.map(i128::from), w.map(i128::from));
    m.wrapping_mul(i128::from(t))
}

/// det3 of a plane triangle's three points, in i64 where every coordinate is at most 2^20
/// (each of its three terms below 2^61), else in i128.
#[inline]
fn det3(t: &PlaneTri) -> i128 {
    if t.iter().flatten().all(|x| x.abs() <= 1 << 20) {
        return i128::from(det3_rows(
            t[0].map(i64::from),
            t[1].map(i64::from),
            t[2].map(i64::from),
        ));
    }
    det3_rows(
        t[0].map(i128::from),
        t[1].map(i128::from),
        t[2].map(i128::from),
    )
}

/// The determinant of the 3×3 matrix with rows `a`, `b`, `c`, expanded along `a`.
#[inline]
fn det3_rows<T>(a: [T; 3], b: [T; 3], c: [T; 3]) -> T
where
    T: Copy + std::ops::Mul<Output = T> + std::ops::Sub<Output = T> + std::ops::Add<Output = T>,
{
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// The signed hash ([`PlaneHash`]'s `signed`) of every face of a cap's tets, keyed by
/// coordinates with its induced orientation, and their number. The cap's interior faces
/// cancel in it, leaving its boundary's; what [`StatsAccumulator::close_with_cap`] compares
/// with the plane the cap closes, without gathering the faces.
#[derive(Debug, Clone, Copy, Default)]
struct CapFaces {
    signed: u128,
    faces: u64,
}

impl CapFaces {
    /// The faces of `cap`, hashed in chunks on rayon's pool.
    fn of(cap: &TetMesh) -> Self {
        let point = |v: u32| {
            let p = cap.vertices[v as usize];
            [p[0], p[1], p[2]]
        };
        let chunk = |tets: &[[u32; 4]]| {
            let mut signed = 0u128;
            for t in tets {
                for (f, s) in tet_faces(t.map(point)) {
                    let (key, parity) = canonical_triangle(f);
                    let h = tri_hash_signed(&key);
                    signed = if s * parity > 0 {
                        signed.wrapping_add(h)
                    } else {
                        signed.wrapping_sub(h)
                    };
                }
            }
            CapFaces {
                signed,
                faces: 4 * tets.len() as u64,
            }
        };
        cap.tets
            .par_chunks(SCAN_CHUNK_TETS)
            .map(chunk)
            .reduce(CapFaces::default, |a, b| CapFaces {
                signed: a.signed.wrapping_add(b.signed),
                faces: a.faces + b.faces,
            })
    }
}

/// Checks a cap's interior faces (exactly, by packed vertex ids) and returns the report, its
/// boundary triangles keyed by coordinates, and their multiset hash.
fn cap_boundary(cap: &TetMesh) -> (ClosedReport, Vec<(PlaneTri, i8)>, PlaneHash) {
    let point = |v: u32| {
        let p = cap.vertices[v as usize];
        [p[0], p[1], p[2]]
    };
    if cap.vertices.len() > PACKED_VERTEX_LIMIT {
        // Huge caps: group faces by coordinates instead of packed ids.
        let mut all = Vec::with_capacity(cap.tets.len() * 4);
        for t in &cap.tets {
            for (f, s) in tet_faces(*t) {
                let (key, parity) = canonical_triangle(f.map(point));
                all.push((key, s * parity));
            }
        }
        all.sort_unstable_by_key(|f| f.0);
        let mut report = ClosedReport::default();
        let mut boundary = Vec::new();
        let mut hash = PlaneHash::default();
        for group in all.chunk_by(|a, b| a.0 == b.0) {
            match group {
                [(key, s)] => {
                    hash.add(key, *s);
                    boundary.push((*key, *s));
                }
                [(_, s1), (_, s2)] => {
                    report.triangles += 1;
                    if s1 == s2 {
                        report.misoriented += 1;
                    }
                }
                _ => {
                    report.triangles += 1;
                    report.overshared += 1;
                }
            }
        }
        return (report, boundary, hash);
    }
    // A cap fills its body's volume (hundreds of thousands of tets): gathered in chunks and
    // paired in parts on rayon's pool.
    let bits = id_bits(cap.vertices.len());
    let shape = FaceShape::new(cap.vertices.len(), 4 * cap.tets.len());
    let gather = |tets: &[[u32; 4]]| {
        let mut faces = shape.gather(4 * tets.len());
        for t in tets {
            for (k, s) in canonical_tet_faces(*t).0 {
                faces.push(k, s > 0);
            }
        }
        faces
    };
    let gathered = cap.tets.par_chunks(SCAN_CHUNK_TETS).map(gather).collect();
    let (report, single) = FaceParts::pair(gathered, &mut Vec::new(), true);
    let mut boundary = Vec::with_capacity(single.len());
    let mut hash = PlaneHash::default();
    let mask = (1u64 << bits) - 1;
    for key in single {
        // A boundary face of the cap: decode its vertex ids.
        let face = key >> 1;
        let ids = [
            (face >> (2 * bits)) as u32,
            ((face >> bits) & mask) as u32,
            (face & mask) as u32,
        ];
        let s = if key & 1 == 1 { 1 } else { -1 };
        let (tri, parity) = canonical_triangle(ids.map(point));
        hash.add(&tri, s * parity);
        boundary.push((tri, s * parity));
    }
    (report, boundary, hash)
}

/// Tets per chunk of a slab's scan on rayon's pool (smaller slabs are scanned in one piece).
const SCAN_CHUNK_TETS: usize = 1 << 17;

/// The sorted-id positions of a tet's face that omits the j-th smallest id (the order of
/// [`canonical_tet_faces`]).
const FACE_CORNERS: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];

/// The faces of tet `t` that do not lie in one of its slab's time planes (`plane`: each
/// vertex's planes, bit 0 lower, bit 1 upper), as sorted ids with their orientation.
fn interior_faces(t: &[u32; 4], plane: &[u8]) -> impl Iterator<Item = ([u32; 3], i8)> {
    let (sorted, order) = canonical_tet_faces(*t);
    let flags = order.map(|i| plane[t[i] as usize]);
    sorted.into_iter().enumerate().filter_map(move |(j, face)| {
        let f = FACE_CORNERS[j];
        (flags[f[0]] & flags[f[1]] & flags[f[2]] == 0).then_some(face)
    })
}

/// Pairs the faces of a slab's tets that do not lie in one of its time planes (`plane`:
/// each vertex's planes, bit 0 lower, bit 1 upper) exactly, each face by its vertex ids:
/// packed and gathered by their smallest vertex (counted as they come) on rayon's pool in
/// chunks of `chunk_tets` tets, else (too many vertices to pack) by their ids.
fn pair_interior_faces(
    m: &TetMesh,
    plane: &[u8],
    chunk_tets: usize,
    scratch: &mut Vec<u64>,
) -> ClosedReport {
    let faces_of = |t: &[u32; 4]| interior_faces(t, plane);
    if m.vertices.len() > PACKED_VERTEX_LIMIT {
        let wide: Vec<([u32; 3], i8)> = m.tets.iter().flat_map(faces_of).collect();
        return pair_by_first_vertex(&wide, m.vertices.len());
    }
    let shape = FaceShape::new(m.vertices.len(), 4 * m.tets.len());
    let gathered = m
        .tets
        .par_chunks(chunk_tets.max(1))
        .map(|tets| {
            // Most faces are off the time planes: room for all at once, not by doubling.
            let mut faces = shape.gather(4 * tets.len());
            for (key, s) in tets.iter().flat_map(faces_of) {
                faces.push(key, s > 0);
            }
            faces
        })
        .collect();
    FaceParts::pair(gathered, scratch, false).0
}

/// What one chunk of a slab's tets contributes to [`StatsAccumulator::add_lateral`].
#[derive(Default)]
struct Scan {
    vol24: i128,
    hi_cone: i128,
    lo: Vec<(PlaneTri, i8)>,
    hi: Vec<(PlaneTri, i8)>,
    lo_hash: PlaneHash,
    hi_hash: PlaneHash,
    interior: FaceHash,
}

/// An order-independent hash of a slab's interior faces (those off its time planes): the
/// sum of each face's hash with its orientation as sign, and the number of faces. In a
/// closed, consistently oriented slab every face comes twice with opposite orientations, so
/// the sum is zero; a face used once, or twice the same way, leaves its hash in it (as two
/// different multisets of faces hash equal, with probability about 2^-128). A face used
/// 2k > 2 times with balanced orientations (over-shared, consistent) cancels too: the hash
/// cannot see it, as for the time planes (module docs).
#[derive(Debug, Clone, Copy, Default)]
struct FaceHash {
    signed: u128,
    faces: u64,
}

impl FaceHash {
    /// Adds the face of sorted vertex ids `k` with orientation `s`.
    #[inline]
    fn add(&mut self, k: &[u32; 3], s: i8) {
        let h = face_hash(k);
        self.signed = if s > 0 {
            self.signed.wrapping_add(h)
        } else {
            self.signed.wrapping_sub(h)
        };
        self.faces += 1;
    }

    fn merge(&mut self, other: &FaceHash) {
        self.signed = self.signed.wrapping_add(other.signed);
        self.faces += other.faces;
    }

    /// The report of faces that all pair, if the hash says they do.
    fn paired(&self) -> Option<ClosedReport> {
        (self.signed == 0 && self.faces % 2 == 0).then_some(ClosedReport {
            triangles: self.faces / 2,
            ..ClosedReport::default()
        })
    }
}

/// A 128-bit hash of a face's three vertex ids: two 64-bit lanes, each the ids (two words)
/// folded by 64 × 64 → 128-bit multiplications under its own keys (those of [`tri_hash`]).
#[inline]
fn face_hash(k: &[u32; 3]) -> u128 {
    #[inline]
    fn fold(a: u64, b: u64) -> u64 {
        let r = u128::from(a) * u128::from(b);
        (r as u64) ^ ((r >> 64) as u64)
    }
    let (w0, w1) = ((u64::from(k[0]) << 32) | u64::from(k[1]), u64::from(k[2]));
    let lane = |key: &[u64; 7]| {
        let a = fold(w0 ^ key[0], w1 ^ key[1]);
        fold(a ^ key[2], w1 ^ key[3])
    };
    (u128::from(lane(&TRI_HASH_KEYS[0])) << 64) | u128::from(lane(&TRI_HASH_KEYS[1]))
}

/// Order-independent hashes of a set of oriented plane triangles.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct PlaneHash {
    /// Σ ± h(t): orientation as sign.
    signed: u128,
    /// Σ h'(t): multiplicity only.
    unsigned: u128,
}

impl PlaneHash {
    #[inline]
    fn add(&mut self, t: &PlaneTri, s: i8) {
        let (h, g) = tri_hash(t);
        self.signed = if s > 0 {
            self.signed.wrapping_add(h)
        } else {
            self.signed.wrapping_sub(h)
        };
        self.unsigned = self.unsigned.wrapping_add(g);
    }

    /// Adds the triangles `other` hashed (the union of the two multisets).
    fn merge(&mut self, other: &PlaneHash) {
        self.signed = self.signed.wrapping_add(other.signed);
        self.unsigned = self.unsigned.wrapping_add(other.unsigned);
    }

    /// Both sides of one plane: same triangles, opposite orientations.
    fn matches(&self, other: &PlaneHash) -> bool {
        self.signed.wrapping_add(other.signed) == 0 && self.unsigned == other.unsigned
    }
}

/// Two independent 128-bit hashes of a triangle's nine coordinates: four 64-bit lanes, each
/// the coordinates (packed losslessly into five words) folded by 64 × 64 → 128-bit
/// multiplications under its own random keys, as wyhash folds its input.
#[inline]
fn tri_hash(t: &PlaneTri) -> (u128, u128) {
    let words = tri_words(t);
    let h = TRI_HASH_KEYS.each_ref().map(|k| tri_lane(&words, k));
    (
        (u128::from(h[0]) << 64) | u128::from(h[1]),
        (u128::from(h[2]) << 64) | u128::from(h[3]),
    )
}

/// The first of [`tri_hash`]'s two hashes alone (the one signed by orientation).
#[inline]
fn tri_hash_signed(t: &PlaneTri) -> u128 {
    let words = tri_words(t);
    (u128::from(tri_lane(&words, &TRI_HASH_KEYS[0])) << 64)
        | u128::from(tri_lane(&words, &TRI_HASH_KEYS[1]))
}

/// A triangle's nine coordinates packed losslessly into five words.
#[inline]
fn tri_words(t: &PlaneTri) -> [u64; 5] {
    let c = |p: &[i32; 3], k: usize| u64::from(p[k] as u32);
    [
        (c(&t[0], 0) << 32) | c(&t[0], 1),
        (c(&t[1], 0) << 32) | c(&t[1], 1),
        (c(&t[2], 0) << 32) | c(&t[2], 1),
        (c(&t[0], 2) << 32) | c(&t[1], 2),
        c(&t[2], 2),
    ]
}

/// One 64-bit lane of [`tri_hash`]: the words folded under the lane's keys.
#[inline]
fn tri_lane(words: &[u64; 5], k: &[u64; 7]) -> u64 {
    #[inline]
    fn fold(a: u64, b: u64) -> u64 {
        let r = u128::from(a) * u128::from(b);
        (r as u64) ^ ((r >> 64) as u64)
    }
    let a = fold(words[0] ^ k[0], words[1] ^ k[1]);
    let b = fold(words[2] ^ k[2], words[3] ^ k[3]);
    let c = fold(words[4] ^ k[4], a ^ k[5]);
    fold(b ^ k[6], c ^ k[0])
}

/// The keys of [`tri_hash`]'s four lanes: published constants (wyhash's secrets, the golden
/// ratio, SHA-2's initial hash values and round constants), none chosen for these inputs.
const TRI_HASH_KEYS: [[u64; 7]; 4] = [
    [
        0xa076_1d64_78bd_642f,
        0xe703_7ed1_a0b4_28db,
        0x8ebc_6af0_9c88_c6e3,
        0x5899_65cc_7537_4cc3,
        0x1d8e_4e27_c47d_124f,
        0x9e37_79b9_7f4a_7c15,
        0xd6e8_feb8_6659_fd93,
    ],
    [
        0x2d35_8dcc_aa6c_78a5,
        0x8bb8_4b93_962e_acc9,
        0x4b33_a62e_d433_d4a3,
        0x4d5a_2da5_1de1_aa47,
        0xa0b4_28db_e703_7ed1,
        0x6a09_e667_f3bc_c909,
        0xbb67_ae85_84ca_a73b,
    ],
    [
        0x3c6e_f372_fe94_f82b,
        0xa54f_f53a_5f1d_36f1,
        0x510e_527f_ade6_82d1,
        0x9b05_688c_2b3e_6c1f,
        0x1f83_d9ab_fb41_bd6b,
        0x5be0_cd19_137e_2179,
        0xcbbb_9d5d_c105_9ed8,
    ],
    [
        0x629a_292a_367c_d507,
        0x9159_015a_3070_dd17,
        0x152f_ecd8_f70e_5939,
        0x6733_2667_ffc0_0b31,
        0x8eb4_4a87_6858_1511,
        0xdb0c_2e0d_64f9_8fa7,
        0x47b5_481d_befa_4fa4,
    ],
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesher::test_stream;

    /// Scanning a slab in chunks gives the figures of one scan, exactly: on a closed body, and
    /// on one with an open first plane (no opening cap).
    #[test]
    fn chunked_scans_equal_one_scan() {
        // A ball moving along x, with scattered voxels (so slabs have many tets).
        let (m, slabs) = test_stream([10, 9, 8], 4, |k, x, y, z| {
            let r2 = (x - 3 - k as i32).pow(2) + (y - 4).pow(2) + (z - 4).pow(2);
            r2 <= 9 || (x + 2 * y + 3 * z + k as i32) % 11 == 0
        });
        let first = m.first_frame().unwrap().clone();
        let cap = m.cap(&first, crate::CapSide::Low).unwrap();
        assert!(
            slabs[0].mesh.tets.len() > 100,
            "{}",
            slabs[0].mesh.tets.len()
        );
        for opening in [Some(&cap), None] {
            let figures = |chunk: usize| {
                let mut acc = StatsAccumulator::new();
                for s in &slabs {
                    acc.add_lateral_in_chunks(s.lateral_ref(), opening, chunk, None);
                }
                let st = acc.finish(4, opening.map(|c| (c.tets.len() as u64, 0)), None);
                (
                    st.closed,
                    st.tets,
                    st.hypervolume_lattice.to_bits(),
                    st.vanishing_slabs,
                )
            };
            let one = figures(usize::MAX);
            for chunk in [1, 7, 64] {
                assert_eq!(figures(chunk), one, "chunks of {chunk}");
            }
            assert!(one.0.unpaired > 0, "the last plane is open: {:?}", one.0);
        }
    }

    /// The hypervolume of slabs far from the origin, or stretched so that their edges pass
    /// 2^20, where the flux and the upper faces' determinants are taken in i128: moved in
    /// space it is the same, stretched by 2^20 on the three spatial axes it is 2^60 times
    /// as large, bit for bit; a slab's hypervolume checked against the cone from the origin
    /// over the slab closed by both its caps.
    #[test]
    fn far_and_stretched_slabs_add_the_exact_hypervolume() {
        let (_, slabs) = test_stream([10, 9, 8], 4, |k, x, y, z| {
            let r2 = (x - 3 - k as i32).pow(2) + (y - 4).pow(2) + (z - 4).pow(2);
            r2 <= 9 || (x + 2 * y + 3 * z + k as i32) % 11 == 0
        });
        let figures = |f: &dyn Fn(&mut TetMesh)| {
            let mut acc = StatsAccumulator::new();
            for s in &slabs {
                let mut mesh = s.mesh.clone();
                f(&mut mesh);
                let mut slab = s.lateral_ref();
                slab.mesh = &mesh;
                acc.add_lateral(slab, None);
            }
            let st = acc.so_far();
            (st.hypervolume_lattice, st.closed)
        };
        let (near, closed) = figures(&|_| {});
        assert!(near > 100.0, "{near}");
        let far = figures(&|m| m.translate([3 << 20, -(5 << 20), 7 << 20, 0]));
        assert_eq!(far, (near, closed));
        let stretched = figures(&|m| {
            for p in &mut m.vertices {
                for x in &mut p[..3] {
                    *x <<= 20;
                }
            }
        });
        assert_eq!(
            stretched.0.to_bits(),
            (near * (1u64 << 60) as f64).to_bits()
        );
        assert_eq!(stretched.1, closed);
        // A slab closed by the caps of its two frames: its hypervolume as the cone from the
        // origin gives it (the det4 of every tet of the three meshes).
        let (m, slabs) = test_stream([10, 9, 8], 2, |k, x, y, z| {
            let r2 = (x - 3 - 2 * k as i32).pow(2) + (y - 4).pow(2) + (z - 4).pow(2);
            r2 <= 9 || (x + 2 * y + 3 * z + k as i32) % 11 == 0
        });
        let lo = m
            .cap(m.first_frame().unwrap(), crate::CapSide::Low)
            .unwrap();
        let hi = m
            .cap(m.last_frame().unwrap(), crate::CapSide::High)
            .unwrap();
        let cone: i128 = [&lo, &slabs[0].mesh, &hi]
            .into_iter()
            .map(crate::validate::hypervolume24)
            .sum();
        let mut acc = StatsAccumulator::new();
        acc.add_lateral(slabs[0].lateral_ref(), Some(&lo));
        assert!(cone > 0);
        assert_eq!(acc.so_far().hypervolume_lattice, cone as f64 / 24.0);
    }

    /// The hash of a slab's interior faces says they pair exactly when they do, and sends a
    /// slab whose faces do not (a tet missing, a tet turned over) to the exact pairing.
    #[test]
    fn interior_face_hash_agrees_with_exact_pairing() {
        let (_, slabs) = test_stream([9, 8, 7], 3, |k, x, y, z| {
            let r2 = (x - 3 - k as i32).pow(2) + (y - 4).pow(2) + (z - 3).pow(2);
            r2 <= 8 || (x + 2 * y + 3 * z + k as i32) % 7 == 0
        });
        let slab = &slabs[1];
        let t_lo = slab.geometry.scale * slab.index as i32;
        let t_hi = t_lo + slab.geometry.scale;
        let report = |m: &TetMesh| {
            let plane: Vec<u8> = m
                .vertices
                .iter()
                .map(|p| u8::from(p[3] == t_lo) | (u8::from(p[3] == t_hi) << 1))
                .collect();
            let mut hash = FaceHash::default();
            for (key, s) in m.tets.iter().flat_map(|t| interior_faces(t, &plane)) {
                hash.add(&key, s);
            }
            let exact = pair_interior_faces(m, &plane, 64, &mut Vec::new());
            (hash.paired(), exact)
        };
        let (hashed, exact) = report(&slab.mesh);
        assert!(exact.is_closed() && exact.triangles > 100, "{exact:?}");
        assert_eq!(hashed, Some(exact));
        let mut missing = slab.mesh.clone();
        missing.tets.remove(missing.tets.len() / 2);
        let mut turned = slab.mesh.clone();
        let k = turned.tets.len() / 3;
        turned.tets[k].swap(0, 1);
        for broken in [missing, turned] {
            let (hashed, exact) = report(&broken);
            assert_eq!(hashed, None);
            assert!(!exact.is_closed(), "{exact:?}");
        }
    }

    /// A test stream's slabs (see [`test_stream`]) with its opening and closing caps.
    fn capped_stream(
        size: [u32; 3],
        n: u32,
        occ: impl Fn(u32, i32, i32, i32) -> bool,
    ) -> (Vec<Slab>, TetMesh, TetMesh) {
        let (m, slabs) = test_stream(size, n, occ);
        let first = m.first_frame().unwrap().clone();
        let cap = m.cap(&first, crate::CapSide::Low).unwrap();
        let last = m.last_frame().unwrap().clone();
        let end = m.cap(&last, crate::CapSide::High).unwrap();
        (slabs, cap, end)
    }

    /// A cap is checked by one hash of all its faces against the plane it closes: on a closed
    /// stream the report is the exact pairing's of the whole welded mesh, and so it is for a
    /// first or last cap with a tet missing, a tet turned over, or no tets (sent to the exact
    /// pairing); one with a tet twice is found open too.
    #[test]
    fn caps_checked_by_their_faces_hash_report_what_pairing_the_whole_mesh_finds() {
        let (slabs, cap, end) = capped_stream([9, 8, 7], 4, |k, x, y, z| {
            let r2 = (x - 3 - k as i32).pow(2) + (y - 4).pow(2) + (z - 3).pow(2);
            r2 <= 8 || (x + 2 * y + 3 * z + k as i32) % 7 == 0
        });
        assert!(cap.tets.len() > 50 && end.tets.len() > 50);
        // A closed cap's interior faces cancel in its faces' hash: what is left is its
        // boundary's, as its exact pairing finds it.
        for c in [&cap, &end] {
            let (report, boundary, hash) = cap_boundary(c);
            let faces = CapFaces::of(c);
            assert!(report.is_closed() && !boundary.is_empty());
            assert_eq!(faces.signed, hash.signed);
            assert_eq!(faces.faces, 2 * report.triangles + boundary.len() as u64);
        }
        let broken = |c: &TetMesh, how: usize| {
            let mut c = c.clone();
            let k = c.tets.len() / 2;
            match how {
                0 => {}
                1 => {
                    c.tets.remove(k);
                }
                2 => c.tets[k].swap(0, 1),
                3 => c.tets.push(c.tets[k]),
                _ => c.tets.clear(),
            }
            c
        };
        for how in 0..5 {
            for first in [true, false] {
                let (a, b) = if first {
                    (broken(&cap, how), end.clone())
                } else {
                    (cap.clone(), broken(&end, how))
                };
                let mut g = crate::glue::BodyGluer::new();
                g.first_cap(&a, 0);
                for s in &slabs {
                    g.lateral(s.lateral_ref(), None);
                }
                g.last_cap(&b, 0);
                let body = g.finish(5, Vec::new(), None);
                let exact = crate::validate::check_closed(&body.mesh);
                assert_eq!(exact.is_closed(), how == 0, "{exact:?}");
                if how == 3 {
                    // A face of the tet twice in the plane is counted by the plane's
                    // pairing (unpaired, turned) where the whole mesh's counts it shared
                    // too often; both say the mesh is not closed.
                    assert!(!body.stats.closed.is_closed(), "first cap {first}");
                } else {
                    assert_eq!(body.stats.closed, exact, "defect {how}, first cap {first}");
                }
            }
        }
    }

    /// The figures two ways of adding the same slabs must agree on (floats bit for bit).
    fn figures(st: BodyStats) -> (ClosedReport, u64, u64, u64, u64, u64) {
        (
            st.closed,
            st.tets,
            st.vertices,
            st.slabs,
            st.hypervolume_lattice.to_bits(),
            st.hypervolume_m3s.to_bits(),
        )
    }

    /// A body at rest for some periods, then moving, then at rest again: the periods that
    /// copy the one before are recognised (and only they), and the figures equal a full scan
    /// of every slab, on a closed stream and on one whose copied slabs carry a defect.
    #[test]
    fn copies_of_the_last_slab_add_the_same_figures_as_scanning_them() {
        // Rest for frames 0-3, a step at 4, rest for 5-7, a step at 8.
        let place = |k: u32| match k {
            0..=3 => 0,
            4..=7 => 2,
            _ => 3,
        };
        let (slabs, cap, end) = capped_stream([9, 8, 7], 9, |k, x, y, z| {
            let r2 = (x - 3 - place(k)).pow(2) + (y - 4).pow(2);
            r2 + (z - 3).pow(2) <= 6 || (x + 2 * y + 3 * z) % 13 == 0
        });
        // Slabs 1, 2 and 5, 6 copy the slab before them; a defect in slabs 5 and 6 (one
        // tet gone from each, the same one) keeps 6 a copy of 5, but 5 no copy of 4.
        for defect in [false, true] {
            let mut meshes: Vec<Arc<TetMesh>> = Vec::new();
            for (j, s) in slabs.iter().enumerate() {
                let mut mesh = s.mesh.clone();
                if defect && (5..=6).contains(&j) {
                    mesh.tets.remove(7);
                }
                meshes.push(Arc::new(mesh));
            }
            let lateral = |j: usize| LateralRef {
                mesh: &meshes[j],
                ..slabs[j].lateral_ref()
            };
            let mut scan = StatsAccumulator::new();
            let mut shared = StatsAccumulator::new();
            let mut copies = Vec::new();
            for j in 0..slabs.len() {
                scan.add_lateral(lateral(j), Some(&cap));
                if shared.add_lateral_shared(lateral(j), Some(&cap), &meshes[j]) {
                    copies.push(j);
                }
            }
            let expected: &[usize] = if defect { &[1, 2, 6] } else { &[1, 2, 5, 6] };
            assert_eq!(copies, expected, "defect {defect}");
            let (a, b) = (
                figures(scan.finish(9, Some((cap.tets.len() as u64, 0)), Some((&end, 0)))),
                figures(shared.finish(9, Some((cap.tets.len() as u64, 0)), Some((&end, 0)))),
            );
            assert_eq!(a, b, "defect {defect}");
            assert_eq!(a.0.is_closed(), !defect, "{:?}", a.0);
        }
    }

    /// A body stepping by whole voxels every sixth period, at rest between steps: each step
    /// slab is the one before it moved (one voxel, six periods: the rest between holds one
    /// place among the latest slabs), and so is each first slab at rest after a step (the
    /// last one before the step moved), all added as copies with a scan's figures.
    #[test]
    fn a_step_slab_after_a_rest_is_the_step_before_it_moved() {
        let place = |k: u32| (k / 6) as i32;
        let frames = 20;
        let (slabs, cap, end) = capped_stream([16, 9, 8], frames, |k, x, y, z| {
            let x = x - place(k);
            (2..5).contains(&x) && (2..6).contains(&y) && (2..5).contains(&z)
        });
        let meshes: Vec<Arc<TetMesh>> = slabs.iter().map(|s| Arc::new(s.mesh.clone())).collect();
        let mut scan = StatsAccumulator::new();
        let mut shared = StatsAccumulator::new();
        for (s, m) in slabs.iter().zip(&meshes) {
            let lateral = LateralRef {
                mesh: m,
                ..s.lateral_ref()
            };
            scan.add_lateral(lateral, Some(&cap));
            shared.add_lateral_shared(lateral, Some(&cap), m);
        }
        // Slabs 0-4, 6-10, 12-16 and 18 at rest; 5, 11 and 17 step. Moved in time only:
        // 1-4, 7-10, 13-16; moved in space too: 6, 12 and 18 (from 4, 10, 16) and the step
        // slabs 11 and 17 (from 5 and 11).
        assert_eq!(shared.copies(), [12, 5]);
        let last = (
            u64::from(frames),
            Some((cap.tets.len() as u64, 0)),
            Some((&end, 0)),
        );
        assert_eq!(
            figures(scan.finish(last.0, last.1, last.2)),
            figures(shared.finish(last.0, last.1, last.2))
        );
    }

    /// A body stepping by whole voxels every third period: its slabs at rest after a step
    /// are the ones before it moved in space, added as copies with the figures a scan of
    /// each gives; and only while the slab copied is closed (with one tet gone from every
    /// slab, none is copied in space, and the figures are still a scan's).
    #[test]
    fn slabs_moved_in_space_add_the_figures_of_scanning_them() {
        let place = |k: u32| (k / 3) as i32;
        let (slabs, cap, end) = capped_stream([15, 9, 8], 11, |k, x, y, z| {
            let x = x - place(k);
            let ball = (x - 3).pow(2) + (y - 4).pow(2) + (z - 3).pow(2) <= 5;
            ball || (x == 1 && y == 2 && (1..6).contains(&z))
        });
        for defect in [false, true] {
            let meshes: Vec<Arc<TetMesh>> = slabs
                .iter()
                .map(|s| {
                    let mut mesh = s.mesh.clone();
                    if defect {
                        mesh.tets.remove(7);
                    }
                    Arc::new(mesh)
                })
                .collect();
            let lateral = |j: usize| LateralRef {
                mesh: &meshes[j],
                ..slabs[j].lateral_ref()
            };
            let mut scan = StatsAccumulator::new();
            let mut shared = StatsAccumulator::new();
            for j in 0..slabs.len() {
                scan.add_lateral(lateral(j), Some(&cap));
                shared.add_lateral_shared(lateral(j), Some(&cap), &meshes[j]);
            }
            let [unmoved, moved] = shared.copies();
            assert!(unmoved > 0, "defect {defect}: {unmoved} copies in time");
            if defect {
                assert_eq!(moved, 0, "a slab that is not closed is scanned");
            } else {
                assert!(moved >= 2, "{moved} copies moved in space");
            }
            let (a, b) = (
                figures(scan.finish(11, Some((cap.tets.len() as u64, 0)), Some((&end, 0)))),
                figures(shared.finish(11, Some((cap.tets.len() as u64, 0)), Some((&end, 0)))),
            );
            assert_eq!(a, b, "defect {defect}");
            assert_eq!(a.0.is_closed(), !defect, "{:?}", a.0);
        }
    }
}
