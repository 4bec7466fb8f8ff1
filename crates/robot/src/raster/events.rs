//! Where lines along x cross each body: crossing events on sample rows, and the sweep that
//! turns them into the inside of the union.
//!
//! A sample row is the line `y = j + (sy + ½)/K`, `z = k + (sz + ½)/K` (voxel units) for a
//! voxel row (j, k) and `K × K` sub-rows per voxel row (`K = 1`: the rows through voxel
//! centres). Each closed mesh gives an event where a row crosses one of its triangles, with
//! the triangle's winding sign; each analytic solid gives an entry and an exit event.
//!
//! Whether a row crosses a triangle is decided exactly: the triangle's projection on the yz
//! plane and the row's point are snapped to a fixed-point grid of 2⁻²⁴ voxel and tested with
//! integer edge functions and a top-left rule for points on an edge, so that a row passing
//! through an edge or a vertex shared by several triangles crosses exactly one of them (or,
//! on a silhouette, crosses both sides and cancels). Winding numbers and parities are thus
//! exact for the snapped mesh, which lies within 2⁻²⁵ voxel of the true one.

use super::surface::{ceil, floor};
use crate::shape::Affine;

/// Fixed-point bits of the snapped yz coordinates.
const FIX_BITS: i32 = 24;
/// Coordinates beyond this many voxels from the lattice are not snapped (the instance is
/// skipped and counted): products of snapped differences must stay within i128.
pub(crate) const FAR: f64 = (1u64 << 36) as f64;

/// One crossing of a sample row.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Event {
    /// Sample row: `(j + ny·k)·K² + sz·K + sy`.
    pub key: u64,
    /// Where, in voxel units along x.
    pub x: f64,
    /// Which solid (index into the frame's rules).
    pub slot: u32,
    /// Winding change (+1 entering, −1 leaving; +1 for parity solids).
    pub delta: i32,
}

/// How a solid's winding number decides inside.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Rule {
    NonZero,
    Odd,
}

#[derive(Clone, Copy)]
pub(crate) struct Grid {
    pub ny: usize,
    pub nz: usize,
    /// Sub-rows per voxel edge (a power of two, 1..=16).
    pub k: usize,
}

impl Grid {
    /// The first and last global sub-row index (along one axis of `n` voxels) whose
    /// centre is within `[lo, hi]` (voxel units), clamped to the lattice.
    fn rows(&self, lo: f64, hi: f64, n: usize) -> Option<(usize, usize)> {
        if lo.is_nan() || hi.is_nan() {
            return None;
        }
        let k = self.k as f64;
        let a = ceil(lo * k - 0.5).max(0.0);
        let b = floor(hi * k - 0.5).min((n * self.k) as f64 - 1.0);
        (a <= b).then_some((a as usize, b as usize))
    }

    fn key(&self, sy: usize, sz: usize) -> u64 {
        let (j, k) = (sy / self.k, sz / self.k);
        let row = (j + self.ny * k) as u64;
        row * (self.k * self.k) as u64 + ((sz % self.k) * self.k + sy % self.k) as u64
    }

    /// A sub-row centre in fixed point.
    fn fixed_centre(&self, s: usize) -> i64 {
        // (s + 1/2)/K · 2^FIX = (2s + 1) · 2^(FIX-1) / K, exact for K a power of two.
        ((2 * s + 1) as i64) * ((1i64 << (FIX_BITS - 1)) / self.k as i64)
    }
}

fn snap(v: f64) -> i64 {
    (v * f64::from(1u32 << FIX_BITS)).round() as i64
}

/// Edge function of the directed edge u→v at p, exact.
#[inline]
fn edge(u: (i64, i64), v: (i64, i64), p: (i64, i64)) -> i128 {
    (v.0 - u.0) as i128 * (p.1 - u.1) as i128 - (v.1 - u.1) as i128 * (p.0 - u.0) as i128
}

/// Whether a point with edge function `e` on edge u→v of a counter-clockwise triangle
/// counts as inside: strictly left, or on a "top-left" edge. Of the two directions of an
/// edge exactly one is top-left, so two triangles sharing the edge never both take it.
#[inline]
fn takes(e: i128, u: (i64, i64), v: (i64, i64)) -> bool {
    e > 0 || (e == 0 && (v.1 > u.1 || (v.1 == u.1 && v.0 < u.0)))
}

/// Appends the events of a mesh's triangles (vertices already in voxel coordinates).
pub(crate) fn mesh_events(
    verts: &[[f64; 3]],
    tris: &[[u32; 3]],
    slot: u32,
    rule: Rule,
    grid: Grid,
    out: &mut Vec<Event>,
    snapped: &mut Vec<(i64, i64)>,
) {
    snapped.clear();
    snapped.extend(verts.iter().map(|v| (snap(v[1]), snap(v[2]))));
    for t in tris {
        let (ia, ib, ic) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let (mut a, mut b, c) = (snapped[ia], snapped[ib], snapped[ic]);
        let (mut xa, mut xb, xc) = (verts[ia][0], verts[ib][0], verts[ic][0]);
        let area = edge(a, b, c);
        if area == 0 {
            continue; // parallel to x: no row crosses it
        }
        // Winding: a counter-clockwise projection (normal towards +x) is left going +x.
        let mut delta = if area > 0 { -1 } else { 1 };
        if area < 0 {
            std::mem::swap(&mut a, &mut b);
            std::mem::swap(&mut xa, &mut xb);
        }
        if rule == Rule::Odd {
            delta = 1;
        }
        let (ya, yb, yc) = (verts[ia][1], verts[ib][1], verts[ic][1]);
        let (za, zb, zc) = (verts[ia][2], verts[ib][2], verts[ic][2]);
        let Some((sy0, sy1)) = grid.rows(ya.min(yb).min(yc), ya.max(yb).max(yc), grid.ny) else {
            continue;
        };
        let Some((sz0, sz1)) = grid.rows(za.min(zb).min(zc), za.max(zb).max(zc), grid.nz) else {
            continue;
        };
        // x on the triangle's plane, x = x0 + gy·y + gz·z, where the projection is not
        // nearly degenerate; otherwise from the exact barycentric weights. Either way kept
        // within the triangle's x range.
        let (xlo, xhi) = (xa.min(xb).min(xc), xa.max(xb).max(xc));
        let (y_a, z_a, y_b, z_b, y_c, z_c) = if area > 0 {
            (ya, za, yb, zb, yc, zc)
        } else {
            (yb, zb, ya, za, yc, zc)
        };
        let det = (y_b - y_a) * (z_c - z_a) - (z_b - z_a) * (y_c - y_a);
        let plane = det.abs() > 1e-9;
        let (gy, gz) = if plane {
            (
                ((xb - xa) * (z_c - z_a) - (z_b - z_a) * (xc - xa)) / det,
                ((y_b - y_a) * (xc - xa) - (xb - xa) * (y_c - y_a)) / det,
            )
        } else {
            (0.0, 0.0)
        };
        let k = grid.k as f64;
        // Edge functions step by -(v.1 - u.1)·step when p.0 moves one sub-row along y.
        let step = grid.fixed_centre(1) - grid.fixed_centre(0);
        let (d0, d1, d2) = (
            -((c.1 - b.1) as i128) * step as i128,
            -((a.1 - c.1) as i128) * step as i128,
            -((b.1 - a.1) as i128) * step as i128,
        );
        for sz in sz0..=sz1 {
            let pz = grid.fixed_centre(sz);
            let p0 = (grid.fixed_centre(sy0), pz);
            let (mut e0, mut e1, mut e2) = (edge(b, c, p0), edge(c, a, p0), edge(a, b, p0));
            let z = (sz as f64 + 0.5) / k;
            for sy in sy0..=sy1 {
                if takes(e0, b, c) && takes(e1, c, a) && takes(e2, a, b) {
                    let x = if plane {
                        let y = (sy as f64 + 0.5) / k;
                        xa + gy * (y - y_a) + gz * (z - z_a)
                    } else {
                        let (w0, w1, w2) = (e0 as f64, e1 as f64, e2 as f64);
                        (w0 * xa + w1 * xb + w2 * xc) / (w0 + w1 + w2)
                    };
                    out.push(Event {
                        key: grid.key(sy, sz),
                        x: x.clamp(xlo, xhi),
                        slot,
                        delta,
                    });
                }
                e0 += d0;
                e1 += d1;
                e2 += d2;
            }
        }
    }
}

/// A convex solid given by where a line along x enters and leaves it.
pub(crate) enum Convex {
    /// Centre and radius, voxel units.
    Sphere { c: [f64; 3], r: f64 },
    /// Voxel → box frame, and the half edges (m).
    Box { to_local: Affine, half: [f64; 3] },
    /// Voxel → cylinder frame, radius and half length (m).
    Cylinder { to_local: Affine, r: f64, hz: f64 },
}

/// Parameter interval of `lo <= p + x·d <= hi`, intersected with `[t0, t1]`.
fn slab(p: f64, d: f64, lo: f64, hi: f64, t0: &mut f64, t1: &mut f64) {
    if d == 0.0 {
        if p < lo || p > hi {
            *t0 = f64::INFINITY;
        }
        return;
    }
    let (a, b) = ((lo - p) / d, (hi - p) / d);
    *t0 = t0.max(a.min(b));
    *t1 = t1.min(a.max(b));
}

impl Convex {
    /// Where the line `(x, y, z)`, x free, is inside: `[x0, x1]`, if anywhere.
    fn interval(&self, y: f64, z: f64) -> Option<(f64, f64)> {
        match self {
            Convex::Sphere { c, r } => {
                let d2 = (y - c[1]).powi(2) + (z - c[2]).powi(2);
                let h2 = r * r - d2;
                (h2 > 0.0).then(|| {
                    let h = h2.sqrt();
                    (c[0] - h, c[0] + h)
                })
            }
            Convex::Box { to_local, half } => {
                let p = to_local.apply([0.0, y, z]);
                let d = to_local.m.column(0);
                let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
                for a in 0..3 {
                    slab(p[a], d[a], -half[a], half[a], &mut t0, &mut t1);
                }
                (t0 < t1).then_some((t0, t1))
            }
            Convex::Cylinder { to_local, r, hz } => {
                let p = to_local.apply([0.0, y, z]);
                let d = to_local.m.column(0);
                let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
                slab(p[2], d[2], -hz, *hz, &mut t0, &mut t1);
                // (px + t dx)² + (py + t dy)² <= r²
                let qa = d[0] * d[0] + d[1] * d[1];
                let qb = 2.0 * (p[0] * d[0] + p[1] * d[1]);
                let qc = p[0] * p[0] + p[1] * p[1] - r * r;
                if qa == 0.0 {
                    if qc > 0.0 {
                        return None;
                    }
                } else {
                    let disc = qb * qb - 4.0 * qa * qc;
                    if disc <= 0.0 {
                        return None;
                    }
                    let s = disc.sqrt();
                    // Stable roots.
                    let q = -0.5 * (qb + qb.signum() * s);
                    let (mut r0, mut r1) = if q != 0.0 {
                        (q / qa, qc / q)
                    } else {
                        (-s / (2.0 * qa), s / (2.0 * qa))
                    };
                    if r0 > r1 {
                        std::mem::swap(&mut r0, &mut r1);
                    }
                    t0 = t0.max(r0);
                    t1 = t1.min(r1);
                }
                (t0 < t1).then_some((t0, t1))
            }
        }
    }

    /// Appends entry and exit events on every sample row crossing the solid, whose yz
    /// bounds (voxel units) are `lo..hi`.
    pub(crate) fn events(
        &self,
        lo: [f64; 2],
        hi: [f64; 2],
        slot: u32,
        grid: Grid,
        out: &mut Vec<Event>,
    ) {
        let Some((sy0, sy1)) = grid.rows(lo[0], hi[0], grid.ny) else {
            return;
        };
        let Some((sz0, sz1)) = grid.rows(lo[1], hi[1], grid.nz) else {
            return;
        };
        let k = grid.k as f64;
        for sz in sz0..=sz1 {
            let z = (sz as f64 + 0.5) / k;
            for sy in sy0..=sy1 {
                let y = (sy as f64 + 0.5) / k;
                if let Some((x0, x1)) = self.interval(y, z) {
                    let key = grid.key(sy, sz);
                    out.push(Event {
                        key,
                        x: x0,
                        slot,
                        delta: 1,
                    });
                    out.push(Event {
                        key,
                        x: x1,
                        slot,
                        delta: -1,
                    });
                }
            }
        }
    }
}

/// Sorts events by sample row, then x: a counting sort by voxel row (`counts` holds one
/// slot per voxel row, all zero, and is left so), then each row's few events in place.
pub(crate) fn sort(events: &mut Vec<Event>, spare: &mut Vec<Event>, counts: &mut [u32], k2: u64) {
    if events.is_empty() {
        return;
    }
    for e in events.iter() {
        counts[(e.key / k2) as usize] += 1;
    }
    // Exclusive prefix sums over the rows used, remembered as (row, start) runs.
    let mut total = 0u32;
    for c in counts.iter_mut() {
        let n = *c;
        *c = total;
        total += n;
    }
    spare.clear();
    spare.resize(events.len(), events[0]);
    for e in events.iter() {
        let r = (e.key / k2) as usize;
        spare[counts[r] as usize] = *e;
        counts[r] += 1;
    }
    std::mem::swap(events, spare);
    counts.fill(0);
    let mut start = 0;
    while start < events.len() {
        let row = events[start].key / k2;
        let mut end = start + 1;
        while end < events.len() && events[end].key / k2 == row {
            end += 1;
        }
        if end - start > 1 {
            events[start..end].sort_unstable_by(|a, b| a.key.cmp(&b.key).then(a.x.total_cmp(&b.x)));
        }
        start = end;
    }
}

/// Sorts events by sample row, then x, by comparison (for lattices with very many rows).
pub(crate) fn sort_by_comparison(events: &mut [Event]) {
    events.sort_unstable_by(|a, b| a.key.cmp(&b.key).then(a.x.total_cmp(&b.x)));
}

/// Walks sorted events row by row; calls `inside(key, x0, x1)` for each maximal interval of
/// a sample row inside the union of the solids. `winding` must hold one zero per slot; it
/// is left zeroed.
pub(crate) fn sweep(
    events: &[Event],
    rules: &[Rule],
    winding: &mut [i32],
    mut inside: impl FnMut(u64, f64, f64),
) {
    let is_in = |rule: Rule, w: i32| match rule {
        Rule::NonZero => w != 0,
        Rule::Odd => w & 1 == 1,
    };
    let mut start = 0;
    while start < events.len() {
        let key = events[start].key;
        let mut end = start;
        let mut active = 0i32;
        let mut from = 0.0;
        while end < events.len() && events[end].key == key {
            let e = events[end];
            let s = e.slot as usize;
            let before = is_in(rules[s], winding[s]);
            winding[s] += e.delta;
            let after = is_in(rules[s], winding[s]);
            if before != after {
                if after {
                    if active == 0 {
                        from = e.x;
                    }
                    active += 1;
                } else {
                    active -= 1;
                    if active == 0 {
                        inside(key, from, e.x);
                    }
                }
            }
            end += 1;
        }
        // A row that ends inside (an open or clipped solid) closes nothing: reset.
        for e in &events[start..end] {
            winding[e.slot as usize] = 0;
        }
        start = end;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exactly_one_direction_of_an_edge_takes_a_point_on_it() {
        let pts = [(0, 0), (5, 0), (0, 5), (-3, 7), (2, -9)];
        for &u in &pts {
            for &v in &pts {
                if u != v {
                    assert!(takes(0, u, v) != takes(0, v, u), "{u:?} {v:?}");
                }
            }
        }
    }

    #[test]
    fn rows_through_shared_edges_and_vertices_cross_a_closed_surface_consistently() {
        // A square pyramid (apex towards +x over the base square [1.5, 3.5]² at x = 0),
        // closed by its base. Rows through voxel centres hit the apex (2.5, 2.5), the
        // diagonal edges and the base's outline: each row must cross as often entering as
        // leaving, the apex row exactly once each way.
        let grid = Grid { ny: 4, nz: 4, k: 1 };
        let verts = [
            [1.0, 2.5, 2.5],
            [0.0, 1.5, 1.5],
            [0.0, 3.5, 1.5],
            [0.0, 3.5, 3.5],
            [0.0, 1.5, 3.5],
        ];
        let tris = [
            [0, 2, 1],
            [0, 3, 2],
            [0, 4, 3],
            [0, 1, 4],
            [1, 2, 3],
            [1, 3, 4],
        ];
        let mut out = Vec::new();
        mesh_events(
            &verts,
            &tris,
            0,
            Rule::NonZero,
            grid,
            &mut out,
            &mut Vec::new(),
        );
        for key in 0..16u64 {
            let on: Vec<i32> = out
                .iter()
                .filter(|e| e.key == key)
                .map(|e| e.delta)
                .collect();
            assert_eq!(on.iter().sum::<i32>(), 0, "row {key}: {on:?}");
            if key == 2 + 4 * 2 {
                assert_eq!(on.len(), 2, "the apex row");
            }
        }
    }
}
