//! Marching hypercubes over one slab (two consecutive frames), and the caps that close it.
//!
//! Hypercubes whose 16 corners agree are skipped 64 at a time: for each row of cubes the
//! eight corner bit rows are OR-ed and AND-ed, and only positions where they differ are
//! visited. Vertices are deduplicated through a cache indexed by edge, kept for two
//! z-layers at a time and cleared by the list of touched entries (no per-slab clear, no
//! hashing, no allocation per cube).

use super::grid::OccupancyGrid;
use super::hash::{fast_map, FastMap};
use super::table::Table;
use super::table_gen::{edge3, edge4};
use chronotope_kernel::LatticePoint;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A set of tetrahedra on shared lattice vertices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TetMesh {
    /// Vertex positions (exact lattice coordinates).
    pub vertices: Vec<LatticePoint>,
    /// Tets as vertex indices, oriented so that orient4(a, b, c, d, inside) < 0.
    pub tets: Vec<[u32; 4]>,
}

impl TetMesh {
    /// Removes all tets and vertices, keeping the buffers.
    pub fn clear(&mut self) {
        self.vertices.clear();
        self.tets.clear();
    }

    /// Appends `other`, merging vertices with equal coordinates (see [`Welder`] to append
    /// many parts without re-indexing).
    pub fn append_welded(&mut self, other: &TetMesh) {
        Welder::of(self).append(self, other);
    }

    /// Translates every vertex by an integer lattice vector.
    pub fn translate(&mut self, d: LatticePoint) {
        for p in &mut self.vertices {
            for k in 0..4 {
                p[k] += d[k];
            }
        }
    }

    /// The box of its vertices on the spatial axes (lowest and highest x, y, z), if it has
    /// any.
    pub fn spatial_bounds(&self) -> Option<SpatialBounds> {
        let first = *self.vertices.first()?;
        // All four lanes at once (they fit one vector register), then the spatial three.
        let (lo, hi) = self.vertices.iter().fold((first, first), |(lo, hi), p| {
            (
                [0, 1, 2, 3].map(|k| lo[k].min(p[k])),
                [0, 1, 2, 3].map(|k| hi[k].max(p[k])),
            )
        });
        Some(([lo[0], lo[1], lo[2]], [hi[0], hi[1], hi[2]]))
    }

    /// Whether this mesh is `earlier` moved by `d`, exactly: the same tets on the same
    /// vertex numbers, every vertex at its place in `earlier` plus `d`. A body at rest
    /// meshes to such a copy each frame period (the slab of two equal frames is the one
    /// before it, one period later), and a body that steps by whole voxels often to one
    /// moved in space too; whatever follows from the coordinates by a translation (tree,
    /// adjacency, normals, closedness) need not be derived again. Compares every tet and
    /// vertex: O(n), no hashing.
    pub fn is_moved_copy_of(&self, earlier: &TetMesh, d: LatticePoint) -> bool {
        self.tets.len() == earlier.tets.len()
            && self.vertices.len() == earlier.vertices.len()
            && self.tets == earlier.tets
            && self
                .vertices
                .iter()
                .zip(&earlier.vertices)
                .all(|(p, q)| (0..4).all(|k| q[k].checked_add(d[k]) == Some(p[k])))
    }
}

/// Lowest and highest lattice coordinates on the spatial axes (x, y, z).
pub type SpatialBounds = ([i32; 3], [i32; 3]);

/// The smallest box holding both.
pub fn union_bounds(a: Option<SpatialBounds>, b: Option<SpatialBounds>) -> Option<SpatialBounds> {
    match (a, b) {
        (Some(a), Some(b)) => Some((
            [0, 1, 2].map(|k| a.0[k].min(b.0[k])),
            [0, 1, 2].map(|k| a.1[k].max(b.1[k])),
        )),
        (a, None) => a,
        (None, b) => b,
    }
}

/// Appends meshes to one mesh, merging vertices with equal lattice coordinates; keeps its
/// index between appends.
#[derive(Debug, Default)]
pub struct Welder {
    index: FastMap<LatticePoint, u32>,
}

impl Welder {
    /// A welder for appending to `mesh` (indexes its current vertices).
    pub fn of(mesh: &TetMesh) -> Self {
        Self {
            index: mesh
                .vertices
                .iter()
                .enumerate()
                .map(|(i, p)| (*p, i as u32))
                .collect(),
        }
    }

    /// Appends `part` to `into` (which must only have grown through this welder since
    /// [`Self::of`]).
    pub fn append(&mut self, into: &mut TetMesh, part: &TetMesh) {
        let remap: Vec<u32> = part
            .vertices
            .iter()
            .map(|p| {
                *self.index.entry(*p).or_insert_with(|| {
                    into.vertices.push(*p);
                    (into.vertices.len() - 1) as u32
                })
            })
            .collect();
        into.tets
            .extend(part.tets.iter().map(|t| t.map(|v| remap[v as usize])));
    }

    /// Appends the tets `which` of `part` (indices, each below its tet count) to `into`,
    /// with only the vertices they use, as [`Self::append`] would.
    pub fn append_tets(&mut self, into: &mut TetMesh, part: &TetMesh, which: &[u32]) {
        let mut remap = vec![NONE; part.vertices.len()];
        into.tets.reserve(which.len());
        for &t in which {
            let tet = part.tets[t as usize].map(|v| {
                let r = &mut remap[v as usize];
                if *r == NONE {
                    let p = part.vertices[v as usize];
                    *r = *self.index.entry(p).or_insert_with(|| {
                        into.vertices.push(p);
                        (into.vertices.len() - 1) as u32
                    });
                }
                *r
            });
            into.tets.push(tet);
        }
    }
}

const NONE: u32 = u32::MAX;

/// Where a slab's vertices go on the lattice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SlabPlacement {
    /// Lattice steps per voxel edge and per frame.
    pub scale: i32,
    /// Index of the slab's first frame (its lattice time is `scale · frame`).
    pub frame: i64,
    /// Percent iso level (graded frames only).
    pub iso: u8,
}

/// Most chunks of z-planes one slab is split into for marching on several cores.
pub const MAX_MARCH_CHUNKS: usize = 4;
/// Fewest z-planes of hypercubes per chunk (thinner chunks would cost more in merging and
/// edge caches than they save).
pub const MIN_CHUNK_PLANES: usize = 16;
/// Most bytes the edge caches of the extra chunks may take in all, per marcher (each chunk
/// has its own two z-layers of edge slots).
pub const MAX_CHUNK_CACHE_BYTES: usize = 64 << 20;

/// Most tets a chunk's mesh buffer keeps its room for between slabs (4 MiB of tets, and
/// as many vertices at most); a bigger chunk's buffers are freed after its slab.
pub const MAX_KEPT_CHUNK_TETS: usize = 1 << 18;

/// Reusable workspace for marching slabs.
///
/// A slab is marched in chunks of consecutive z-planes on rayon's pool when it has threads
/// (at most [`MAX_MARCH_CHUNKS`], each of at least [`MIN_CHUNK_PLANES`] planes, their extra
/// edge caches within [`MAX_CHUNK_CACHE_BYTES`]). The chunks' meshes are joined in order, the
/// vertices of a plane two chunks share merged by their lattice coordinates (a vertex lies
/// inside its edge, so no two edges give the same point): the result is the mesh one
/// sequential sweep gives, vertex for vertex and tet for tet, whatever the thread count.
#[derive(Debug, Default)]
pub struct SlabMarcher {
    main: EdgeCache,
    /// Workspaces and meshes of the chunks after the first, kept between slabs.
    extra: Vec<(EdgeCache, TetMesh)>,
}

/// The edge cache of one sweep: vertex ids by edge for two z-layers, cleared by the list of
/// touched entries.
#[derive(Debug, Default)]
struct EdgeCache {
    cache: [Vec<u32>; 2],
    touched: [Vec<usize>; 2],
}

/// Snapped crossing of an edge from value `a` to value `b` (one inside, one outside):
/// lattice steps from `a`, in `1..scale`.
#[inline]
fn crossing(a: u8, b: u8, iso: u8, scale: i32) -> i32 {
    if scale == 2 {
        return 1;
    }
    let (a, b, iso) = (i64::from(a), i64::from(b), i64::from(iso));
    let (num, den) = if a >= iso {
        (a - iso, a - b)
    } else {
        (iso - a, b - a)
    };
    let s = i64::from(scale);
    // round(s · num / den), then keep it off both end points so no vertex sits on a sample.
    let q = (2 * s * num + den) / (2 * den);
    q.clamp(1, s - 1) as i32
}

/// How many chunks a slab of `planes` z-planes of hypercubes, with edge-cache layers of
/// `layer` slots, is marched in on `threads` threads.
fn chunk_count(planes: usize, layer: usize, threads: usize) -> usize {
    let cache_bytes = layer.saturating_mul(2 * 4).max(1);
    let by_memory = 1 + MAX_CHUNK_CACHE_BYTES / cache_bytes;
    threads
        .min(MAX_MARCH_CHUNKS)
        .min(planes / MIN_CHUNK_PLANES)
        .min(by_memory)
        .max(1)
}

impl SlabMarcher {
    /// Meshes the lateral boundary of the slab between frames `f0` and `f1` (same lattice)
    /// into `out` (cleared first). Stops and returns `false` (with `out` empty) as soon as
    /// the slab would exceed `max_tets`: a noise-like frame pair can produce tets in almost
    /// every hypercube, and memory must stay bounded.
    pub fn march(
        &mut self,
        table: &Table,
        f0: &OccupancyGrid,
        f1: &OccupancyGrid,
        at: SlabPlacement,
        max_tets: usize,
        out: &mut TetMesh,
    ) -> bool {
        let [px, py, pz] = f0.padded;
        let planes = pz - 1;
        let chunks = chunk_count(planes, px * py * 7, rayon::current_num_threads());
        let total = AtomicUsize::new(0);
        let frames = [f0, f1];
        if chunks <= 1 {
            return self
                .main
                .sweep(table, frames, at, 0..planes, max_tets, &total, out);
        }
        if self.extra.len() < chunks - 1 {
            self.extra.resize_with(chunks - 1, Default::default);
        }
        let bounds: Vec<usize> = (0..=chunks).map(|k| k * planes / chunks).collect();
        let main = (&mut self.main, &mut *out);
        let rest = self.extra[..chunks - 1].iter_mut().map(|(c, m)| (c, m));
        let jobs: Vec<(usize, (&mut EdgeCache, &mut TetMesh))> =
            std::iter::once(main).chain(rest).enumerate().collect();
        let ok = jobs
            .into_par_iter()
            .map(|(k, (cache, mesh))| {
                let range = bounds[k]..bounds[k + 1];
                cache.sweep(table, frames, at, range, max_tets, &total, mesh)
            })
            .collect::<Vec<bool>>()
            .into_iter()
            .all(|ok| ok);
        if !ok {
            out.clear();
            self.extra
                .iter_mut()
                .for_each(|(_, m)| *m = TetMesh::default());
            return false;
        }
        // Join the chunks in order; a vertex on the plane a chunk starts at may have been
        // made by the chunk before it.
        let mut shared: FastMap<LatticePoint, u32> = fast_map();
        let mut prev_start = 0;
        for (k, (_, part)) in self.extra[..chunks - 1].iter_mut().enumerate() {
            let plane = at.scale * (bounds[k + 1] as i32 - 1);
            shared.clear();
            shared.extend(
                out.vertices[prev_start..]
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| p[2] == plane)
                    .map(|(i, p)| (*p, (prev_start + i) as u32)),
            );
            prev_start = out.vertices.len();
            let remap: Vec<u32> = part
                .vertices
                .iter()
                .map(|p| match shared.get(p) {
                    Some(&id) => id,
                    None => {
                        out.vertices.push(*p);
                        (out.vertices.len() - 1) as u32
                    }
                })
                .collect();
            out.tets
                .extend(part.tets.iter().map(|t| t.map(|v| remap[v as usize])));
            if part.tets.capacity() > MAX_KEPT_CHUNK_TETS {
                // A big slab's buffers are not kept for the next one.
                *part = TetMesh::default();
            } else {
                part.clear();
            }
        }
        true
    }
}

impl EdgeCache {
    /// Marches the hypercubes of z-planes `planes` of the slab into `out` (cleared first),
    /// adding the tets made to `total` (shared by the chunks of one slab) row by row; stops
    /// with `false` (and `out` empty) once `total` exceeds `max_tets`.
    #[allow(clippy::too_many_arguments)]
    fn sweep(
        &mut self,
        table: &Table,
        frames: [&OccupancyGrid; 2],
        at: SlabPlacement,
        planes: std::ops::Range<usize>,
        max_tets: usize,
        total: &AtomicUsize,
        out: &mut TetMesh,
    ) -> bool {
        out.clear();
        let [px, py, _] = frames[0].padded;
        let words = frames[0].words;
        let layer = px * py * 7;
        for l in 0..2 {
            if self.cache[l].len() != layer {
                self.cache[l] = vec![NONE; layer];
                self.touched[l].clear();
            }
        }
        let s = at.scale;
        let mut counted = 0;
        for z in planes {
            for y in 0..py - 1 {
                let rows: [&[u64]; 8] = std::array::from_fn(|r| {
                    frames[(r >> 2) & 1].row(y + (r & 1), z + ((r >> 1) & 1))
                });
                for w in 0..words - 1 {
                    let mut a = [0u64; 8];
                    let mut b = [0u64; 8];
                    let mut any = 0u64;
                    let mut all = !0u64;
                    for r in 0..8 {
                        a[r] = rows[r][w];
                        b[r] = (rows[r][w] >> 1) | (rows[r][w + 1] << 63);
                        any |= a[r] | b[r];
                        all &= a[r] & b[r];
                    }
                    let mut mixed = any & !all;
                    while mixed != 0 {
                        let bit = mixed.trailing_zeros();
                        mixed &= mixed - 1;
                        let mut case = 0u16;
                        for r in 0..8 {
                            case |= (((a[r] >> bit) & 1) as u16) << (2 * r);
                            case |= (((b[r] >> bit) & 1) as u16) << (2 * r + 1);
                        }
                        let x = w * 64 + bit as usize;
                        self.emit_cube(table, frames, [x, y, z], case, at, s, px, out);
                    }
                }
                let made = out.tets.len() - counted;
                counted = out.tets.len();
                let so_far = if made > 0 {
                    total.fetch_add(made, Ordering::Relaxed) + made
                } else {
                    total.load(Ordering::Relaxed)
                };
                if so_far > max_tets {
                    for l in 0..2 {
                        self.cache[l].iter_mut().for_each(|c| *c = NONE);
                        self.touched[l].clear();
                    }
                    out.clear();
                    return false;
                }
            }
            self.roll();
        }
        self.roll();
        self.roll();
        true
    }

    /// Shifts the two-layer edge cache by one z.
    fn roll(&mut self) {
        self.cache.swap(0, 1);
        self.touched.swap(0, 1);
        // cache[1] now holds the old layer 0: clear what was written there.
        for &i in &self.touched[1] {
            self.cache[1][i] = NONE;
        }
        self.touched[1].clear();
    }

    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn emit_cube(
        &mut self,
        table: &Table,
        frames: [&OccupancyGrid; 2],
        [x, y, z]: [usize; 3],
        case: u16,
        at: SlabPlacement,
        s: i32,
        px: usize,
        out: &mut TetMesh,
    ) {
        let mut local = [NONE; 32];
        for tet in table.lateral(case) {
            let mut ids = [0u32; 4];
            for (k, &e) in tet.iter().enumerate() {
                let e = usize::from(e);
                if local[e] == NONE {
                    let (c0, c1, d) = edge4(e);
                    let (ox, oy, oz, ot) = (c0 & 1, (c0 >> 1) & 1, (c0 >> 2) & 1, (c0 >> 3) & 1);
                    let slot = if ot == 0 { d } else { 4 + d };
                    let idx = ((y + oy) * px + (x + ox)) * 7 + slot;
                    let cached = self.cache[oz][idx];
                    local[e] = if cached != NONE {
                        cached
                    } else {
                        let (gx, gy, gz) = (x + ox, y + oy, z + oz);
                        let mut p: LatticePoint = [
                            s * (gx as i32 - 1),
                            s * (gy as i32 - 1),
                            s * (gz as i32 - 1),
                            s * (at.frame as i32 + ot as i32),
                        ];
                        p[d] += if s == 2 {
                            1
                        } else {
                            let va = frames[ot].value(gx, gy, gz);
                            let (ex, ey, ez, et) =
                                (c1 & 1, (c1 >> 1) & 1, (c1 >> 2) & 1, (c1 >> 3) & 1);
                            let vb = frames[et].value(x + ex, y + ey, z + ez);
                            crossing(va, vb, at.iso, s)
                        };
                        let id = out.vertices.len() as u32;
                        out.vertices.push(p);
                        self.cache[oz][idx] = id;
                        self.touched[oz].push(idx);
                        id
                    };
                }
                ids[k] = local[e];
            }
            out.tets.push(ids);
        }
    }
}

/// Which end of a slab a cap closes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CapSide {
    /// The earlier frame: outward normal along -t.
    Low,
    /// The later frame: outward normal along +t.
    High,
}

/// The 3D solid of one frame as tets in the hyperplane t = scale·frame, oriented as the
/// `side` cap of a slab (outward along -t for [`CapSide::Low`], +t for [`CapSide::High`]).
/// Returns `false` (with `out` empty) if the cap would exceed `max_tets`.
pub fn march_cap(
    table: &Table,
    f: &OccupancyGrid,
    at: SlabPlacement,
    side: CapSide,
    max_tets: usize,
    out: &mut TetMesh,
) -> bool {
    out.clear();
    let s = at.scale;
    let t = s * at.frame as i32;
    // Counted first, without building anything: a cap over the budget (a solid body of
    // millions of voxels) is refused before its vertices and tets are allocated.
    let mut count = 0usize;
    let within = for_each_cap_cube(f, |_, _, _, case| {
        count += table.cap(case).len();
        count <= max_tets
    });
    if !within {
        return false;
    }
    out.tets.reserve(count);
    // Vertices are welded through ids kept per grid corner for two z-layers of corners (the
    // layer of corner z is z mod 2): the corner itself and the edges from it along x, y
    // and z. A vertex lies on its corner or strictly inside its edge, so this merges the
    // same points as welding by coordinates, and numbers them in the same order.
    let [px, py, _] = f.padded;
    let layer = 4 * px * py;
    let mut ids = vec![NONE; 2 * layer];
    let mut touched: [Vec<usize>; 2] = [Vec::new(), Vec::new()];
    let mut at_z: Option<usize> = None;
    for_each_cap_cube(f, |x, y, z, case| {
        if at_z != Some(z) {
            // The layer of corners z + 1 held corners z - 1 (or older): cleared. On a jump
            // over empty planes, the layer of corners z is stale too.
            let stale: &[usize] = if at_z.map(|a| a + 1) == Some(z) {
                &[(z + 1) % 2]
            } else {
                &[0, 1]
            };
            for &l in stale {
                for i in touched[l].drain(..) {
                    ids[i] = NONE;
                }
            }
            at_z = Some(z);
        }
        for tet in table.cap(case) {
            let mut vs = [0u32; 4];
            for (k, &pid) in tet.iter().enumerate() {
                let pid = usize::from(pid);
                let (c0, c1, d, kind) = if pid < 8 {
                    (pid, pid, 0, 0)
                } else {
                    let (a, b, d) = edge3(pid - 8);
                    (a, b, d, 1 + d)
                };
                let (gx, gy, gz) = (x + (c0 & 1), y + ((c0 >> 1) & 1), z + (c0 >> 2));
                let slot = (gz % 2) * layer + (kind * py + gy) * px + gx;
                if ids[slot] == NONE {
                    let mut p: LatticePoint = [
                        s * (gx as i32 - 1),
                        s * (gy as i32 - 1),
                        s * (gz as i32 - 1),
                        t,
                    ];
                    if kind != 0 {
                        p[d] += if s == 2 {
                            1
                        } else {
                            let va = f.value(gx, gy, gz);
                            let vb = f.value(x + (c1 & 1), y + ((c1 >> 1) & 1), z + (c1 >> 2));
                            crossing(va, vb, at.iso, s)
                        };
                    }
                    out.vertices.push(p);
                    ids[slot] = (out.vertices.len() - 1) as u32;
                    touched[gz % 2].push(slot);
                }
                vs[k] = ids[slot];
            }
            out.tets.push(match side {
                CapSide::Low => [vs[0], vs[1], vs[3], vs[2]],
                CapSide::High => vs,
            });
        }
        true
    });
    true
}

/// Calls `visit(x, y, z, case)` for every cube of `f`'s padded grid with an occupied corner
/// (`case`: its corners' bits), in order, until `visit` returns false. Whether it went
/// through.
fn for_each_cap_cube(
    f: &OccupancyGrid,
    mut visit: impl FnMut(usize, usize, usize, u8) -> bool,
) -> bool {
    let [px, py, pz] = f.padded;
    for z in 0..pz - 1 {
        for y in 0..py - 1 {
            let rows: [&[u64]; 4] = std::array::from_fn(|r| f.row(y + (r & 1), z + (r >> 1)));
            // Cubes x whose eight corners are all free are skipped 64 at a time: cube x
            // has corners at x and x + 1.
            let words = f.words;
            let cubes = (0..words).flat_map(|w| {
                let any = |w: usize| {
                    rows.iter()
                        .fold(0u64, |a, r| a | r.get(w).copied().unwrap_or(0))
                };
                let here = any(w);
                let mut mask = here | (here >> 1) | (any(w + 1) << 63);
                std::iter::from_fn(move || {
                    (mask != 0).then(|| {
                        let bit = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        w * 64 + bit
                    })
                })
            });
            for x in cubes.take_while(|&x| x < px - 1) {
                let mut case = 0u8;
                for (r, row) in rows.iter().enumerate() {
                    case |= (((row[x / 64] >> (x % 64)) & 1) as u8) << (2 * r);
                    case |= (((row[(x + 1) / 64] >> ((x + 1) % 64)) & 1) as u8) << (2 * r + 1);
                }
                if case != 0 && !visit(x, y, z, case) {
                    return false;
                }
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::DecodeOptions;
    use crate::mesher::{test_bits, test_frame};
    use crate::table::table;

    /// A cap welded by coordinates through a hash map, as the cap's vertices are defined.
    fn cap_welded_by_coordinates(f: &OccupancyGrid, at: SlabPlacement, side: CapSide) -> TetMesh {
        let (s, t, table) = (at.scale, at.scale * at.frame as i32, table());
        let mut out = TetMesh::default();
        let mut index: FastMap<LatticePoint, u32> = fast_map();
        for_each_cap_cube(f, |x, y, z, case| {
            for tet in table.cap(case) {
                let ids = tet.map(|pid| {
                    let pid = usize::from(pid);
                    let (c0, c1, d) = if pid < 8 {
                        (pid, pid, 3)
                    } else {
                        edge3(pid - 8)
                    };
                    let corner = |c: usize| (x + (c & 1), y + ((c >> 1) & 1), z + (c >> 2));
                    let (gx, gy, gz) = corner(c0);
                    let p = [gx, gy, gz].map(|g| s * (g as i32 - 1));
                    let mut p = [p[0], p[1], p[2], t];
                    if d < 3 {
                        let (hx, hy, hz) = corner(c1);
                        let (va, vb) = (f.value(gx, gy, gz), f.value(hx, hy, hz));
                        p[d] += crossing(va, vb, at.iso, s);
                    }
                    *index.entry(p).or_insert_with(|| {
                        out.vertices.push(p);
                        (out.vertices.len() - 1) as u32
                    })
                });
                out.tets.push(match side {
                    CapSide::Low => [ids[0], ids[1], ids[3], ids[2]],
                    CapSide::High => ids,
                });
            }
            true
        });
        out
    }

    /// Caps welded through the two layers of corner ids equal caps welded by coordinates,
    /// vertex for vertex and tet for tet: random bit and percent frames, with empty planes
    /// between occupied ones (the layers are then both stale) and bodies at the grid's edge.
    #[test]
    fn caps_weld_as_by_coordinates() {
        let size = [11u32, 7, 9];
        let mut rng = chronotope_kernel::intersect::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let n = size.iter().product::<u32>() as usize;
        for round in 0..24u32 {
            let density = 1 + u64::from(round % 4);
            let raw: Vec<u64> = (0..n).map(|_| rng.next()).collect();
            // Planes 3 and 4 stay empty; in half the rounds, so does plane 0.
            let keep = |i: usize| {
                let z = i / (size[0] * size[1]) as usize;
                !(3..5).contains(&z) && (round % 2 == 0 || z != 0)
            };
            for encoding in [0u8, 1] {
                let data: Vec<u8> = if encoding == 0 {
                    test_bits(size, |x, y, z| {
                        let i = (x + size[0] as i32 * (y + size[1] as i32 * z)) as usize;
                        keep(i) && raw[i] % 5 < density
                    })
                } else {
                    (0..n)
                        .map(|i| if keep(i) { (raw[i] % 101) as u8 } else { 0 })
                        .collect()
                };
                let f = test_frame(round, size, encoding, &data);
                let grid = OccupancyGrid::decode(&f, &DecodeOptions::default()).unwrap();
                let scale = if encoding == 0 { 2 } else { 64 };
                let at = SlabPlacement {
                    scale,
                    frame: i64::from(round),
                    iso: 50,
                };
                for side in [CapSide::Low, CapSide::High] {
                    let mut cap = TetMesh::default();
                    assert!(march_cap(table(), &grid, at, side, usize::MAX, &mut cap));
                    assert!(!cap.tets.is_empty());
                    let expected = cap_welded_by_coordinates(&grid, at, side);
                    assert_eq!(cap, expected, "round {round}, encoding {encoding}");
                }
            }
        }
    }

    /// Appending some tets of a part welds exactly as appending the part with only those
    /// tets: the same tets on the same points, and no point the chosen tets do not use.
    #[test]
    fn appending_some_tets_welds_as_appending_them_alone() {
        let part = TetMesh {
            vertices: (0..12).map(|i| [i % 3, i / 3, i % 2, 1]).collect(),
            tets: vec![[0, 1, 2, 3], [3, 4, 5, 6], [6, 7, 8, 9], [9, 10, 11, 0]],
        };
        let base = TetMesh {
            vertices: vec![[0, 0, 0, 1], [2, 1, 0, 1], [9, 9, 9, 9]],
            tets: vec![[0, 1, 2, 2]],
        };
        for which in [vec![], vec![1], vec![0, 3], vec![0, 1, 2, 3]] {
            let (mut a, mut b) = (base.clone(), base.clone());
            Welder::of(&a).append_tets(&mut a, &part, &which);
            let alone = TetMesh {
                vertices: part.vertices.clone(),
                tets: which.iter().map(|&t| part.tets[t as usize]).collect(),
            };
            Welder::of(&b).append(&mut b, &alone);
            let points = |m: &TetMesh| -> Vec<[LatticePoint; 4]> {
                m.tets
                    .iter()
                    .map(|t| t.map(|v| m.vertices[v as usize]))
                    .collect()
            };
            assert_eq!(points(&a), points(&b), "{which:?}");
            let used: std::collections::BTreeSet<u32> = a.tets.iter().flatten().copied().collect();
            assert_eq!(
                used.len(),
                a.vertices.len(),
                "{which:?}: only used points added"
            );
        }
    }
}
