//! Rasterisation of a body (a set of links, posed) onto a lattice, in VoxelGrid's two
//! encodings.
//!
//! **`bits` is conservative**: a voxel is 1 iff its closed cube meets the closed solid of a
//! collision geometry, up to an outward margin of [`MARGIN`] voxel edge (so a voxel is
//! never missed, and a voxel set wrongly is within 2⁻²⁰ of a voxel edge of the solid).
//! A voxel meets a solid iff it meets the solid's surface or lies wholly inside it, so:
//! surface voxels come from clipping each triangle to each voxel row (`surface.rs`);
//! the voxels wholly inside are those whose centre is inside, found by the winding number
//! along the rows through voxel centres (`events.rs`). Boxes go through the same path as
//! their 12 triangles, cylinders as a circumscribed 64-sided prism (bulging out by at most
//! 0.12 % of the radius: conservative, not exact), spheres exactly.
//!
//! **`percent`** is the share of the voxel's volume inside the union of the geometries,
//! rounded to the nearest percent. Each voxel row is cut into `K × K` sub-rows (K =
//! [`RasterOptions::subsamples`]); along each sub-row's centre line the inside of the
//! union is found exactly (crossings of each mesh, entry and exit of each box, cylinder and
//! sphere, merged) and its length in each voxel summed. So the fraction is exact along x
//! and a `K × K` midpoint rule across y and z: exact wherever the inside length varies
//! linearly over each sub-square (a plane that does not cut the voxel's x faces within it),
//! and wrong by at most one sub-square's share, `1/K²`, in each sub-square that a kink of
//! the boundary (an edge of the surface, or its trace on the voxel's x faces) crosses.
//! Interior voxels read exactly 100, exterior 0. Measured errors are in the crate README.
//!
//! Open meshes (holes, see [`Closure::Open`](crate::mesh::Closure)) have no inside: in
//! `bits` only the voxels their surface meets are set; in `percent` they add nothing. The
//! robot's load report lists them.
//!
//! Every buffer is kept in the [`Rasterizer`] and reused: a frame allocates nothing once
//! the buffers have grown to the body's needs.

mod bitset;
mod events;
mod lattice;
mod surface;

pub use crate::shape::{Shape, ShapeKind, CYLINDER_PRISM_SIDES};
pub use lattice::{bit_at, Encoding, Lattice, LatticeError};
pub use surface::MARGIN;

use crate::kinematics::LinkPoses;
use crate::mesh::{Closure, TriMesh};
use crate::robot::{Body, Robot};
use crate::shape::Affine;
use events::{Convex, Event, Grid, Rule};
use surface::Dims;

/// Options of a [`Rasterizer`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RasterOptions {
    /// `K`: sub-rows per voxel edge for `percent` (1, 2, 4, 8 or 16; `K²` sample lines per
    /// voxel). Default 4.
    pub subsamples: u32,
}

impl Default for RasterOptions {
    fn default() -> Self {
        RasterOptions { subsamples: 4 }
    }
}

impl RasterOptions {
    /// Sets [`subsamples`](Self::subsamples), rounded up to a power of two within 1..=16.
    pub fn subsamples(mut self, k: u32) -> Self {
        self.subsamples = k.clamp(1, 16).next_power_of_two();
        self
    }
}

/// What one frame held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameStats {
    /// Geometries rasterised.
    pub geometries: usize,
    /// Triangles rasterised (surface pass, `bits`).
    pub triangles: usize,
    /// Crossing events on sample rows.
    pub events: usize,
    /// Open meshes among the geometries (surface only).
    pub open_meshes: usize,
    /// Geometries skipped for lying over 2³⁶ voxels from the lattice.
    pub skipped_far: usize,
    /// Voxels set (`bits`) or above 0 (`percent`).
    pub occupied: usize,
}

/// Makes frames of bodies on one lattice, reusing its buffers.
pub struct Rasterizer {
    lattice: Lattice,
    encoding: Encoding,
    options: RasterOptions,
    words: Vec<u64>,
    data: Vec<u8>,
    verts: Vec<[f64; 3]>,
    snapped: Vec<(i64, i64)>,
    events: Vec<Event>,
    spare: Vec<Event>,
    row_counts: Vec<u32>,
    dirty: Vec<(usize, usize, usize)>,
    rules: Vec<Rule>,
    winding: Vec<i32>,
    acc: Vec<f32>,
}

impl std::fmt::Debug for Rasterizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Rasterizer")
            .field("lattice", &self.lattice)
            .field("encoding", &self.encoding)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

impl Rasterizer {
    /// A rasteriser for `lattice` in `encoding`.
    pub fn new(lattice: Lattice, encoding: Encoding, options: RasterOptions) -> Self {
        let options = options.subsamples(options.subsamples);
        Rasterizer {
            lattice,
            encoding,
            options,
            words: Vec::new(),
            data: Vec::new(),
            verts: Vec::new(),
            snapped: Vec::new(),
            events: Vec::new(),
            spare: Vec::new(),
            row_counts: Vec::new(),
            dirty: Vec::new(),
            rules: Vec::new(),
            winding: Vec::new(),
            acc: Vec::new(),
        }
    }

    /// The lattice.
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// The encoding.
    pub fn encoding(&self) -> Encoding {
        self.encoding
    }

    /// The last frame's data, as VoxelGrid's `data` (`ceil(n/8)` bytes for `bits`, `n` for
    /// `percent`).
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    /// Copies the last frame's data into `out`, touching only what changed when `out` holds
    /// a frame this rasteriser copied there before.
    ///
    /// `written` says which spans of `out` may be non-zero: pass the spans returned by the
    /// previous call with this `out` (or any spans, with an `out` of the wrong length or an
    /// empty one, which is then filled from scratch). On return `out` equals
    /// [`data`](Self::data) and `written` holds its spans. For `percent` only the rows the
    /// two frames cover are written (a robot covers a small part of its lattice); `bits`
    /// copies the whole frame.
    pub fn copy_into(&self, out: &mut Vec<u8>, written: &mut Vec<(usize, usize)>) {
        let n = self.data.len();
        if self.encoding == Encoding::Bits || out.len() != n {
            out.clear();
            out.extend_from_slice(&self.data);
            written.clear();
            written.push((0, n));
            return;
        }
        for &(a, b) in written.iter() {
            out[a..b].fill(0);
        }
        written.clear();
        for &(base, lo, hi) in &self.dirty {
            let span = (base + lo, base + hi + 1);
            out[span.0..span.1].copy_from_slice(&self.data[span.0..span.1]);
            written.push(span);
        }
    }

    /// Rasterises the links of `body`, posed by `poses` (from
    /// [`Kinematics::forward`](crate::Kinematics::forward) on `robot`), into
    /// [`data`](Self::data).
    ///
    /// # Panics
    /// If `poses` or `body` were made for another robot (an index out of range).
    pub fn rasterize(&mut self, robot: &Robot, body: &Body, poses: &LinkPoses) -> FrameStats {
        let mut stats = FrameStats::default();
        let l = self.lattice;
        let [nx, ny, nz] = l.size().map(|s| s as usize);
        let dims = Dims { nx, ny, nz };
        let percent = self.encoding == Encoding::Percent;
        let grid = Grid {
            ny,
            nz,
            k: if percent {
                self.options.subsamples as usize
            } else {
                1
            },
        };
        self.events.clear();
        self.rules.clear();
        if !percent {
            self.words.clear();
            self.words.resize(l.voxels().div_ceil(64), 0);
        }
        for &link in body.links() {
            for shape in robot.shapes(link) {
                let pose = poses.get(link) * shape.origin;
                stats.geometries += 1;
                let to_vox = Affine::to_voxels(&pose, l.origin(), l.resolution());
                let mesh: Option<&TriMesh> = match (&shape.kind, percent) {
                    (ShapeKind::Mesh(m), _) => Some(m),
                    (ShapeKind::Box { mesh, .. }, false) => Some(mesh),
                    (ShapeKind::Cylinder { prism, .. }, false) => Some(prism),
                    _ => None,
                };
                if let Some(mesh) = mesh {
                    self.mesh(mesh, &to_vox, dims, grid, percent, &mut stats);
                    continue;
                }
                let centre = to_vox.apply([0.0; 3]);
                // A non-finite pose, or one absurdly far, places nothing.
                if !to_vox.is_finite() || centre.iter().any(|c| c.abs() > events::FAR) {
                    stats.skipped_far += 1;
                    continue;
                }
                let h = l.resolution();
                let from_vox = Affine::from_voxels(&pose, l.origin(), h);
                // Half extents of the solid's bounding box in voxel units.
                let (convex, ext) = match &shape.kind {
                    ShapeKind::Sphere { radius } => {
                        let r = radius / h;
                        if !percent {
                            surface::rasterize_sphere(centre, r, dims, &mut self.words);
                            continue;
                        }
                        (Convex::Sphere { c: centre, r }, [r; 3])
                    }
                    ShapeKind::Box { half, .. } => (
                        Convex::Box {
                            to_local: from_vox,
                            half: *half,
                        },
                        box_extent(&to_vox, *half),
                    ),
                    ShapeKind::Cylinder {
                        radius,
                        half_length,
                        ..
                    } => (
                        Convex::Cylinder {
                            to_local: from_vox,
                            r: *radius,
                            hz: *half_length,
                        },
                        box_extent(&to_vox, [*radius, *radius, *half_length]),
                    ),
                    ShapeKind::Mesh(_) => continue, // rasterised as a mesh above
                };
                let slot = self.rules.len() as u32;
                self.rules.push(Rule::NonZero);
                convex.events(
                    [centre[1] - ext[1], centre[2] - ext[2]],
                    [centre[1] + ext[1], centre[2] + ext[2]],
                    slot,
                    grid,
                    &mut self.events,
                );
            }
        }
        stats.events = self.events.len();
        // A counting sort by voxel row needs one counter per row of the lattice: used while
        // that stays small next to the frame (a thin lattice could have 2³⁰ rows).
        if ny * nz <= (1 << 22).max(4 * self.events.len()) {
            self.row_counts.resize(ny * nz, 0);
            let k2 = (grid.k * grid.k) as u64;
            events::sort(&mut self.events, &mut self.spare, &mut self.row_counts, k2);
        } else {
            events::sort_by_comparison(&mut self.events);
        }
        self.winding.clear();
        self.winding.resize(self.rules.len(), 0);
        if percent {
            self.fill_percent(&mut stats);
        } else {
            self.fill_centres();
            bitset::to_bytes(&self.words, l.data_len(Encoding::Bits), &mut self.data);
            stats.occupied = self.words.iter().map(|w| w.count_ones() as usize).sum();
        }
        stats
    }

    fn mesh(
        &mut self,
        mesh: &TriMesh,
        to_vox: &Affine,
        dims: Dims,
        grid: Grid,
        percent: bool,
        stats: &mut FrameStats,
    ) {
        self.verts.clear();
        self.verts
            .extend(mesh.vertices.iter().map(|&v| to_vox.apply(v)));
        if self
            .verts
            .iter()
            .flatten()
            .any(|c| c.is_nan() || c.abs() > events::FAR)
        {
            stats.skipped_far += 1;
            return;
        }
        if !percent {
            stats.triangles += mesh.triangles.len();
            for t in &mesh.triangles {
                let tri = t.map(|i| self.verts[i as usize]);
                surface::rasterize_triangle(&tri, dims, &mut self.words);
            }
        }
        let rule = match mesh.closure {
            Closure::Oriented => Rule::NonZero,
            Closure::Unoriented => Rule::Odd,
            Closure::Open => {
                stats.open_meshes += 1;
                return;
            }
        };
        let slot = self.rules.len() as u32;
        self.rules.push(rule);
        events::mesh_events(
            &self.verts,
            &mesh.triangles,
            slot,
            rule,
            grid,
            &mut self.events,
            &mut self.snapped,
        );
    }

    /// `bits`: sets the voxels whose centre is inside the union.
    fn fill_centres(&mut self) {
        let nx = self.lattice.size()[0] as usize;
        let words = &mut self.words;
        events::sweep(
            &self.events,
            &self.rules,
            &mut self.winding,
            |key, x0, x1| {
                // Centres i + 1/2 within [x0, x1].
                let a = (x0 - 0.5).ceil().max(0.0);
                let b = (x1 - 0.5).floor().min(nx as f64 - 1.0);
                if a <= b {
                    let row = key as usize * nx;
                    bitset::set_range(words, row + a as usize, row + b as usize + 1);
                }
            },
        );
    }

    /// `percent`: sums inside lengths per voxel over the sub-rows of each voxel row.
    fn fill_percent(&mut self, stats: &mut FrameStats) {
        let l = self.lattice;
        let nx = l.size()[0] as usize;
        let k2 = (self.options.subsamples * self.options.subsamples) as u64;
        if self.data.len() != l.voxels() {
            self.data.clear();
            self.data.resize(l.voxels(), 0);
            self.dirty.clear();
        }
        // Only what the last frame wrote needs clearing.
        for &(base, lo, hi) in &self.dirty {
            self.data[base + lo..=base + hi].fill(0);
        }
        self.dirty.clear();
        self.acc.clear();
        self.acc.resize(nx, 0.0);
        let (data, acc, dirty) = (&mut self.data, &mut self.acc, &mut self.dirty);
        let scale = 100.0 / k2 as f32;
        let mut current: Option<u64> = None;
        let (mut lo, mut hi) = (usize::MAX, 0usize);
        let mut occupied = 0usize;
        let mut flush = |row: u64, lo: usize, hi: usize, acc: &mut [f32]| {
            if lo > hi {
                return;
            }
            let base = row as usize * nx;
            dirty.push((base, lo, hi));
            for i in lo..=hi {
                let v = (acc[i] * scale).round().min(100.0) as u8;
                acc[i] = 0.0;
                data[base + i] = v;
                occupied += usize::from(v > 0);
            }
        };
        events::sweep(
            &self.events,
            &self.rules,
            &mut self.winding,
            |key, x0, x1| {
                let row = key / k2;
                if current != Some(row) {
                    if let Some(r) = current {
                        flush(r, lo, hi, acc);
                    }
                    current = Some(row);
                    (lo, hi) = (usize::MAX, 0);
                }
                let a = x0.max(0.0);
                let b = x1.min(nx as f64);
                if a >= b {
                    return;
                }
                let (ia, ib) = (a as usize, ((b.ceil() as usize).max(1) - 1).min(nx - 1));
                lo = lo.min(ia);
                hi = hi.max(ib);
                if ia == ib {
                    acc[ia] += (b - a) as f32;
                    return;
                }
                acc[ia] += (ia as f64 + 1.0 - a) as f32;
                for v in &mut acc[ia + 1..ib] {
                    *v += 1.0;
                }
                acc[ib] += (b - ib as f64) as f32;
            },
        );
        if let Some(r) = current {
            flush(r, lo, hi, acc);
        }
        stats.occupied = occupied;
    }
}

/// Half extents, in voxel units, of the box of half edges `half` placed by `to_vox`.
fn box_extent(to_vox: &Affine, half: [f64; 3]) -> [f64; 3] {
    let mut e = [0.0; 3];
    for (r, out) in e.iter_mut().enumerate() {
        *out = (0..3).map(|c| to_vox.m[(r, c)].abs() * half[c]).sum();
    }
    e
}
