//! Seed eq. 7: polygons along a chisel's edge (seed §4.3.1, Fig. 6).
//!
//! Eq. 6 slides the surfel of a surface point that a chisel's slanted face cuts into, within
//! its own tangent plane, onto that face: it lands on the edge where the groove meets the old
//! surface (these are the red surfels, [`Workpiece::carve`]). A disc centred on the edge
//! still overhangs it by its radius, and consecutive edge points are as far apart as the
//! lattice makes them, so the edge drawn by discs is scalloped. Eq. 7 lines the edge with
//! polygons instead: for the edge points `x_{i-1}, x_i, x_{i+1}` in order along the edge,
//!
//! - `P1 = (x_{i-1} + x_i) / 2` and `P2 = (x_i + x_{i+1}) / 2`, on the edge, so that the
//!   polygons of consecutive points share a corner and the strip along the edge has no gap;
//! - `P3 = (P1 + P2) / 2 + w v` with `v = N - (N · n_b) n_b` (eq. 6's direction: the face
//!   normal `N` within the old surface's plane, normal `n_b`), on the old surface;
//! - `P4 = (P1 + P2) / 2 + w (v - (v · N) N)`, `v` projected onto the face.
//!
//! Read literally with the tool-outward `N` of eq. 2, `P3` lies on the old surface on the
//! material's side while `P4` lies on the face's plane *above* the edge, in the air (with an
//! inward `N` it is the other way round: `P4` on the groove wall and `P3` over the groove);
//! eq. 2 only compares `f` with 0 and `d_s`, so the seed does not fix the sign. We take the
//! reading that covers the edge: `P3` on the old surface (`v` with the tool-outward `N`) and
//! `P4` on the groove wall (the face direction of `v - (v · N) N` that points into the
//! material). The polygon `P1 P3 P2 P4`, folded along `P1 P2`, is two triangles — one on
//! each side of the edge — each `w` wide ([`EdgePolygon::triangles`]); both vectors are taken
//! unit length, so `w` is the width on each side whatever the groove's angle.
//!
//! Nothing here is kept in the workpiece: the polygons are a function of the surfels, built
//! at display rate from the current (or a snapshot's) surfels, so they can never disagree
//! with them and cost the 1 kHz force path nothing. The face normal `N` that eq. 7 needs is
//! read off the nearest chisel-face surfel (whose normal is `-N`, [`Workpiece::carve`]) whose
//! plane passes through the edge point; an edge surfel with no such neighbour (its groove cut
//! away again since) gets no polygon and is counted.

use std::collections::HashMap;

use super::math::{add, cross, dot, norm, scale, sub, Vec3};
use super::workpiece::{Workpiece, COLOUR_CHISEL, COLOUR_EDGE, NO_SURFEL};
use super::CarveError;

/// Default width `w` of the eq. 7 polygons on each side of the edge, in grid spacings: half a
/// spacing reaches the discs of the neighbouring surface points (radius √3/2 spacing, one
/// spacing away).
pub const EDGE_POLYGON_WIDTH_SPACINGS: f64 = 0.5;

/// How far (grid points along each axis) an edge point's face surfel is looked for.
const REACH: usize = 2;

/// How far (grid points along each axis) an edge point's predecessor and successor along
/// the edge are looked for. Eq. 6 moves only the surfels of points the cut exposes (a
/// 6-neighbour removed), and on a diagonal those are sparse along the edge: at 30° to the
/// grid, one every 2.7 spacings on average (the points within 0.37 spacing of the edge,
/// measured across it). Four points bridges such gaps; a longer one ends the strip.
const REACH_ALONG: usize = 4;

/// One eq. 7 polygon (m): `[P1, P2, P3, P4]`; `P1 P2` on the edge, `P3` on the old surface,
/// `P4` on the cut face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EdgePolygon {
    /// `P1, P2, P3, P4` (m).
    pub vertices: [[f32; 3]; 4],
    /// Index of the edge surfel in [`Workpiece::surfels`] it was built for.
    pub surfel: u32,
}

impl EdgePolygon {
    /// The polygon as two triangles, counter-clockwise seen from outside the material: `P1 P2
    /// P3` on the old surface and `P2 P1 P4` on the cut face (a `TRIANGLE_LIST` marker's
    /// points, six per polygon).
    pub fn triangles(&self) -> [[[f32; 3]; 3]; 2] {
        let [p1, p2, p3, p4] = self.vertices;
        [[p1, p2, p3], [p2, p1, p4]]
    }
}

/// What [`Workpiece::edge_polygons`] found.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EdgeReport {
    /// Edge surfels (those eq. 6 put on a chisel edge).
    pub edge_surfels: usize,
    /// Polygons built (one per edge surfel with a face next to it).
    pub polygons: usize,
    /// Edge surfels with no chisel-face surfel through them within two points: no polygon.
    pub unmatched: usize,
    /// Ends of strips: polygon sides with no neighbour along the edge (the side then reaches
    /// as far as the other side does, or half a spacing for a lone edge point).
    pub strip_ends: usize,
}

/// The nearest edge point on one side along the edge: its distance along it and position.
type Neighbour = Option<(f64, Vec3)>;

/// An edge point: its surfel, face normal `N` and edge direction.
#[derive(Clone, Copy)]
struct EdgePoint {
    slot: u32,
    owner: [usize; 3],
    x: Vec3,
    n: Vec3,
    face: Vec3,
    dir: Vec3,
}

fn unit(v: Vec3) -> Option<Vec3> {
    let l = norm(v);
    (l > 1e-12).then(|| scale(v, 1.0 / l))
}

impl Workpiece {
    /// The seed's eq. 7 polygons along the chisel edges of the current surfels, `width` (m)
    /// on each side of the edge, into `out` (cleared first); see the module documentation.
    ///
    /// At most one polygon per edge surfel, so at most [`Workpiece::surfels`]`.len()`; the
    /// room is reserved before anything is built (52 bytes a polygon, plus about 140 bytes an
    /// edge surfel of scratch). Costs about 850 grid lookups per edge surfel: a display-rate
    /// operation, not for the force path.
    ///
    /// # Errors
    /// [`CarveError::Workpiece`] if `width` is not a finite length in (0, 2 spacings], or
    /// the memory cannot be reserved.
    pub fn edge_polygons(
        &self,
        width: f64,
        out: &mut Vec<EdgePolygon>,
    ) -> Result<EdgeReport, CarveError> {
        out.clear();
        if !(width.is_finite() && width > 0.0 && width <= 2.0 * self.h) {
            return Err(CarveError::Workpiece(format!(
                "edge polygon width {width} m: a length in (0, {}] m (two spacings)",
                2.0 * self.h
            )));
        }
        let mut report = EdgeReport::default();
        let edges = self
            .surfels
            .iter()
            .filter(|s| s.colour == COLOUR_EDGE)
            .count();
        report.edge_surfels = edges;
        if edges == 0 {
            return Ok(report);
        }
        let reserve_err = |what: &str| {
            CarveError::Workpiece(format!("cannot reserve the {what} of {edges} edge surfels"))
        };
        let mut points: Vec<EdgePoint> = Vec::new();
        points
            .try_reserve_exact(edges)
            .map_err(|_| reserve_err("scratch"))?;
        let mut by_slot: HashMap<u32, u32> = HashMap::new();
        by_slot
            .try_reserve(edges)
            .map_err(|_| reserve_err("index"))?;
        out.try_reserve(edges)
            .map_err(|_| reserve_err("polygons"))?;
        // Pass 1: each edge point's face normal N, from the chisel-face surfel nearby whose
        // plane passes closest to it.
        for (slot, s) in self.surfels.iter().enumerate() {
            if s.colour != COLOUR_EDGE {
                continue;
            }
            let owner = self.coords(self.owners[slot] as usize);
            let x = s.position.map(f64::from);
            let n = s.normal.map(f64::from);
            // Chisel-face surfels nearby whose plane passes within a quarter spacing of the
            // edge point; the normal most of them share is the face's (a stray surfel of the
            // chisel's front face may pass close too).
            let mut near = [([0.0; 3], 0.0f64); 32];
            let mut count = 0;
            self.around(owner, REACH, |o| {
                let f = &self.surfels[o];
                if f.colour != COLOUR_CHISEL || count == near.len() {
                    return;
                }
                let nf = f.normal.map(f64::from);
                if dot(nf, n).abs() > 0.94 {
                    return; // the same surface, not a face meeting it at an edge
                }
                let off = dot(nf, sub(x, f.position.map(f64::from))).abs();
                if off <= 0.25 * self.h {
                    near[count] = (nf, off);
                    count += 1;
                }
            });
            let near = &near[..count];
            let support = |nf: Vec3| near.iter().filter(|c| dot(c.0, nf) > 0.999).count();
            let best = near
                .iter()
                .map(|&(nf, off)| (support(nf), -off, nf))
                .max_by(|a, b| {
                    (a.0, a.1)
                        .partial_cmp(&(b.0, b.1))
                        .unwrap_or(std::cmp::Ordering::Equal)
                });
            let face = match best {
                Some((_, _, nf)) => scale(nf, -1.0),
                None => {
                    report.unmatched += 1;
                    continue;
                }
            };
            let Some(dir) = unit(cross(face, n)) else {
                report.unmatched += 1;
                continue;
            };
            by_slot.insert(slot as u32, points.len() as u32);
            points.push(EdgePoint {
                slot: slot as u32,
                owner,
                x,
                n,
                face,
                dir,
            });
        }
        // Pass 2: neighbours along the edge and the polygons.
        let w = width;
        for p in &points {
            // The nearest edge point of the same edge before and after this one.
            let (mut prev, mut next): (Neighbour, Neighbour) = (None, None);
            self.around(p.owner, REACH_ALONG, |o| {
                let Some(&q) = by_slot.get(&(o as u32)) else {
                    return;
                };
                let q = &points[q as usize];
                if q.slot == p.slot || dot(q.n, p.n) < 0.99 || dot(q.face, p.face) < 0.99 {
                    return;
                }
                let r = sub(q.x, p.x);
                let t = dot(r, p.dir);
                let off = norm(sub(r, scale(p.dir, t)));
                if off > 0.5 * self.h || t.abs() < 1e-9 * self.h {
                    return;
                }
                let slot = if t < 0.0 { &mut prev } else { &mut next };
                if slot.is_none_or(|(t0, _)| t.abs() < t0) {
                    *slot = Some((t.abs(), q.x));
                }
            });
            // Half-way to each neighbour; at a strip's end as far as to the neighbour on the
            // other side (half a spacing for a lone edge point).
            let half = |t: Neighbour| t.map(|(d, _)| d / 2.0);
            let reach_prev = half(prev).or(half(next)).unwrap_or(self.h / 2.0);
            let reach_next = half(next).or(half(prev)).unwrap_or(self.h / 2.0);
            let p1 = match prev {
                Some((_, x)) => scale(add(x, p.x), 0.5),
                None => sub(p.x, scale(p.dir, reach_prev)),
            };
            let p2 = match next {
                Some((_, x)) => scale(add(x, p.x), 0.5),
                None => add(p.x, scale(p.dir, reach_next)),
            };
            report.strip_ends += usize::from(prev.is_none()) + usize::from(next.is_none());
            let mid = scale(add(p1, p2), 0.5);
            // Eq. 7's v (eq. 6's direction, into the material along the old surface) and its
            // projection onto the face, taken into the material (down the groove's wall).
            let v = sub(p.face, scale(p.n, dot(p.face, p.n)));
            let along_face = sub(v, scale(p.face, dot(v, p.face)));
            let (Some(v), Some(mut down)) = (unit(v), unit(along_face)) else {
                report.unmatched += 1;
                continue;
            };
            if dot(down, p.n) > 0.0 {
                down = scale(down, -1.0);
            }
            let p3 = add(mid, scale(v, w));
            let p4 = add(mid, scale(down, w));
            // Counter-clockwise from outside: P1 P2 P3 faces along n_b.
            let (p1, p2) = if dot(cross(sub(p2, p1), sub(p3, p1)), p.n) < 0.0 {
                (p2, p1)
            } else {
                (p1, p2)
            };
            out.push(EdgePolygon {
                vertices: [p1, p2, p3, p4].map(|q| q.map(|c| c as f32)),
                surfel: p.slot,
            });
        }
        report.polygons = out.len();
        Ok(report)
    }

    /// Calls `f` with the surfel slot of every grid point within `reach` points of `c`
    /// along each axis that has a surfel.
    pub(crate) fn around(&self, c: [usize; 3], reach: usize, mut f: impl FnMut(usize)) {
        let lo = |a: usize| c[a].saturating_sub(reach);
        let hi = |a: usize| (c[a] + reach).min(self.dims[a] - 1);
        for k in lo(2)..=hi(2) {
            for j in lo(1)..=hi(1) {
                for i in lo(0)..=hi(0) {
                    let s = self.surfel_of[self.index(i, j, k)];
                    if s != NO_SURFEL {
                        f(s as usize);
                    }
                }
            }
        }
    }
}
