//! The workpiece: an equally spaced point grid with OUTSIDE / BOUND / INSIDE flags (seed §5)
//! and one surfel per BOUND point (seed §4).

use super::math::{add, scale, Vec3};
use super::CarveError;

/// A broken invariant of a workpiece ([`Workpiece::validate`], for tests); flags are shown
/// as their numbers ([`Flag`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InvariantError {
    /// A point's flag is not the one its neighbours make it.
    #[error("point {point:?} is {flag}, should be {want}")]
    Flag {
        /// The point's grid coordinates.
        point: [usize; 3],
        /// Its flag.
        flag: u8,
        /// The flag it should have.
        want: u8,
    },
    /// A BOUND point without a surfel, or another point with one.
    #[error("point {point:?} flag {flag} has surfel: {has}")]
    Surfel {
        /// The point's grid coordinates.
        point: [usize; 3],
        /// Its flag.
        flag: u8,
        /// Whether it has a surfel.
        has: bool,
    },
    /// A point's surfel names another point as its owner.
    #[error("surfel of {point:?} has the wrong owner")]
    Owner {
        /// The point's grid coordinates.
        point: [usize; 3],
    },
    /// The material count kept differs from the points that are material.
    #[error("material count {kept} != {counted}")]
    MaterialCount {
        /// The count the workpiece keeps.
        kept: u64,
        /// The material points counted.
        counted: u64,
    },
    /// The surfels and their owners are lists of different lengths.
    #[error("surfels and owners differ in length")]
    Owners,
    /// A point's occupancy bit disagrees with its flag.
    #[error("occupancy bit of {point:?} is stale")]
    StaleBit {
        /// The point's grid coordinates.
        point: [usize; 3],
    },
    /// The surfel cloud's bytes are not the surfels'.
    #[error("the surfel bytes do not match the surfels")]
    StaleCloud,
}

/// Memory a workpiece may need at worst (bytes), with the carving node's display: 4 GiB, the
/// budget of the carving node on the documented machine (2 cores, 8 GB, shared with the
/// mesher and the checker). Only a workpiece whose every point carries a surfel comes near
/// it; the 1.1M-surfel workpiece of the benchmarks touches about 0.5 GB.
pub const WORKPIECE_MEMORY_BYTES: u64 = 4 << 30;

/// Bytes one grid point costs at worst, in eighths of a byte (874 = 109.25 bytes):
/// - its flag (1), surfel slot (4) and occupancy bit (1/8);
/// - a slot in the scratch list of points removed by one substep (4): one substep can
///   remove every point;
/// - a surfel, reserved for every point since every material point can be BOUND (a comb
///   of one-spacing slabs): the `Surfel` (32), its owner (4) and its PointCloud2 bytes (32);
/// - a published frame's copies of the bits (1/8) and of the surfel bytes (32);
/// - the display's share ([`SurfelDelta`]): a changed-slot bit (1/8), the display's copy of
///   the surfel bytes (32), and two deltas of 36 bytes per changed surfel at most (one being
///   applied, one waiting) with the changed surfels' PointCloud2 (32); a changed-byte bit of
///   the occupancy (1/64, counted as 1/8), the display's copy of the bits (1/8), and two
///   deltas of 8 bytes per changed occupancy byte (1 per point).
///
/// The workpiece's part is reserved when it is built, the display's when the display is,
/// so a run never grows past it.
pub const BYTES_PER_POINT_EIGHTHS: u64 =
    8 * (1 + 4 + 4 + 32 + 4 + 32 + 32) + 1 + 1 + 1 + 8 * (32 + 36 + 36 + 32) + 1 + 1 + 16;

/// [`BYTES_PER_POINT_EIGHTHS`] in bytes (247.625).
pub const BYTES_PER_POINT: f64 = BYTES_PER_POINT_EIGHTHS as f64 / 8.0;

/// Most grid points of a workpiece: [`WORKPIECE_MEMORY_BYTES`] / [`BYTES_PER_POINT`]
/// = 17 344 643 (256³ = 16.8M fits; 260³ does not).
pub const MAX_POINTS: u64 = WORKPIECE_MEMORY_BYTES * 8 / BYTES_PER_POINT_EIGHTHS;

/// A vector of `n` copies of `v`, or a typed error if the memory cannot be had.
fn filled<T: Clone>(n: usize, v: T, what: &str) -> Result<Vec<T>, CarveError> {
    let mut out = Vec::new();
    reserve(&mut out, n, what)?;
    out.resize(n, v);
    Ok(out)
}

/// Reserves room for exactly `n` more items of `out`, or a typed error.
fn reserve<T>(out: &mut Vec<T>, n: usize, what: &str) -> Result<(), CarveError> {
    out.try_reserve_exact(n).map_err(|_| {
        CarveError::Workpiece(format!(
            "cannot reserve {:.1} MB for the {what} of {n} items",
            (n as f64) * std::mem::size_of::<T>() as f64 / 1e6
        ))
    })
}

/// Surfel colour of the block's faces (RGB, wood).
pub(crate) const COLOUR_BLOCK: u32 = 0xd8b07a;
/// Surfel colour of faces cut by the knife.
pub(crate) const COLOUR_KNIFE: u32 = 0xc09050;
/// Surfel colour of faces cut by the chisel.
pub(crate) const COLOUR_CHISEL: u32 = 0xa87840;
/// Surfel colour of the chisel's resampled edges (red, as in the seed's Fig. 7).
pub(crate) const COLOUR_EDGE: u32 = 0xd02020;
/// Surfel colour of cut-out sides.
pub(crate) const COLOUR_CUTOUT: u32 = 0xb89060;

/// Classification of a grid point (seed eq. 2 and §5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Flag {
    /// Air: removed, or never material.
    Outside = 0,
    /// Material on the surface (a 6-neighbour is air or off the grid); has a surfel.
    Bound = 1,
    /// Material inside.
    Inside = 2,
}

pub(crate) const OUTSIDE: u8 = Flag::Outside as u8;
pub(crate) const BOUND: u8 = Flag::Bound as u8;
pub(crate) const INSIDE: u8 = Flag::Inside as u8;
pub(crate) const NO_SURFEL: u32 = u32::MAX;

/// A surfel: an oriented disc (seed §4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surfel {
    /// Centre (m).
    pub position: [f32; 3],
    /// Outward unit normal.
    pub normal: [f32; 3],
    /// Radius (m).
    pub radius: f32,
    /// Colour, 0xRRGGBB.
    pub colour: u32,
}

/// Bytes of one surfel in [`Workpiece::surfel_bytes`].
pub const SURFEL_BYTES: usize = 32;

impl Surfel {
    /// Its PointCloud2 bytes: x, y, z, normal, radius (float32), rgb (uint32), little-endian.
    pub fn to_bytes(&self) -> [u8; SURFEL_BYTES] {
        let mut b = [0u8; SURFEL_BYTES];
        let floats = self
            .position
            .iter()
            .chain(&self.normal)
            .chain([&self.radius]);
        for (k, v) in floats.enumerate() {
            b[4 * k..4 * k + 4].copy_from_slice(&v.to_le_bytes());
        }
        b[28..].copy_from_slice(&self.colour.to_le_bytes());
        b
    }
}

/// The workpiece: the point grid (force model) and the surfels of its BOUND points (shape).
///
/// Point `(i, j, k)` is at `origin + spacing · (i, j, k)`; a block from `lo` to `hi` has its
/// points at the centres of the `spacing`-sized cells filling it, so the block's faces lie
/// half a spacing beyond its outermost points (where their surfels are put).
#[derive(Debug, Clone)]
pub struct Workpiece {
    pub(crate) origin: Vec3,
    pub(crate) h: f64,
    pub(crate) dims: [usize; 3],
    pub(crate) flags: Vec<u8>,
    pub(crate) surfel_of: Vec<u32>,
    pub(crate) surfels: Vec<Surfel>,
    pub(crate) owners: Vec<u32>,
    pub(crate) material: u64,
    /// Occupancy kept as it changes, one bit per point (1 = material): a display frame
    /// copies it instead of scanning every point.
    pub(crate) bits: Vec<u8>,
    /// The surfels as PointCloud2 bytes ([`SURFEL_BYTES`] each, in `surfels` order), kept as
    /// they change, for the same reason.
    pub(crate) cloud: Vec<u8>,
    pub(crate) lo: Vec3,
    pub(crate) hi: Vec3,
    /// Scratch: points removed by the current substep.
    pub(crate) removed: Vec<u32>,
    /// Scratch: row spans of a sweep.
    pub(crate) spans: Vec<(usize, usize, usize)>,
    /// Surfel slots written or moved since the last [`Workpiece::take_surfel_delta`], one
    /// bit per slot.
    changed: Vec<u64>,
    /// Words of `changed` below this may have bits set.
    changed_hi: usize,
    /// Bytes of `bits` changed since the last delta, one bit per byte.
    bits_changed: Vec<u64>,
}

/// What changed in the surfel cloud and the occupancy since the last delta: the cloud's new
/// length and the bytes of every slot below it that was written or moved, and the changed
/// bytes of the occupancy bits. Applied in order to copies ([`SurfelDelta::apply`],
/// [`SurfelDelta::apply_bits`]), it gives the workpiece's [`Workpiece::surfel_bytes`] and
/// [`Workpiece::occupancy_bits`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfelDelta {
    /// Surfels in the cloud after the change.
    pub len: usize,
    /// `(slot, its PointCloud2 bytes)` for the changed slots, in slot order.
    pub writes: Vec<(u32, [u8; SURFEL_BYTES])>,
    /// `(byte index, its value)` for the changed bytes of the occupancy bits, in order.
    pub bits: Vec<(u32, u8)>,
}

impl SurfelDelta {
    /// Merges a later delta into this one (the later writes win).
    pub fn merge(&mut self, later: SurfelDelta) {
        self.len = later.len;
        self.writes.extend(later.writes);
        let len = self.len;
        self.writes.retain(|w| (w.0 as usize) < len);
        // Keep the last write of each slot, in slot order.
        self.writes.reverse();
        self.writes.sort_by_key(|w| w.0);
        self.writes.dedup_by_key(|w| w.0);
        self.bits.extend(later.bits);
        self.bits.reverse();
        self.bits.sort_by_key(|b| b.0);
        self.bits.dedup_by_key(|b| b.0);
    }

    /// Applies the occupancy part to `bits` (a copy of the occupancy as of the delta before).
    pub fn apply_bits(&self, bits: &mut [u8]) {
        for &(i, v) in &self.bits {
            if let Some(b) = bits.get_mut(i as usize) {
                *b = v;
            }
        }
    }

    /// Applies the delta to `cloud` (a copy of the surfel bytes as of the delta before).
    /// Slots that appear grow the copy (within its reserved capacity when reserved).
    pub fn apply(&self, cloud: &mut Vec<u8>) {
        cloud.resize(self.len * SURFEL_BYTES, 0);
        for (slot, bytes) in &self.writes {
            let at = *slot as usize * SURFEL_BYTES;
            if let Some(dst) = cloud.get_mut(at..at + SURFEL_BYTES) {
                dst.copy_from_slice(bytes);
            }
        }
    }
}

impl Workpiece {
    /// A block from `lo` to `hi` (m) sampled every `spacing` (m).
    ///
    /// # Errors
    /// [`CarveError::Workpiece`] for a non-finite or non-positive size or spacing, fewer than
    /// one or more than 4096 points along an axis, more than [`MAX_POINTS`] points (checked
    /// before anything is allocated), or memory that cannot be reserved. Everything the
    /// workpiece will ever hold is reserved here ([`BYTES_PER_POINT`] per point but the
    /// frame copies): cutting never allocates.
    pub fn block(lo: Vec3, hi: Vec3, spacing: f64) -> Result<Self, CarveError> {
        if !(spacing.is_finite() && spacing > 0.0) {
            return Err(CarveError::Workpiece(format!(
                "spacing {spacing} is not a positive number"
            )));
        }
        let mut dims = [0usize; 3];
        for a in 0..3 {
            let n = (hi[a] - lo[a]) / spacing;
            if !n.is_finite() || n.round() < 1.0 || n.round() > 4096.0 {
                return Err(CarveError::Workpiece(format!(
                    "the block is {n:.1} spacings along axis {a} (from {} to {} m): 1..=4096 allowed",
                    lo[a], hi[a]
                )));
            }
            dims[a] = n.round() as usize;
        }
        let count = dims.iter().map(|&d| d as u64).product::<u64>();
        if count > MAX_POINTS {
            return Err(CarveError::Workpiece(format!(
                "{}x{}x{} = {count} points at spacing {spacing} m: at most {MAX_POINTS} \
                 (MAX_POINTS: {BYTES_PER_POINT} bytes per point at worst within the \
                 {} GiB workpiece budget, {:.2} GB needed); use a coarser spacing_m or a \
                 smaller block",
                dims[0],
                dims[1],
                dims[2],
                WORKPIECE_MEMORY_BYTES >> 30,
                count as f64 * BYTES_PER_POINT / 1e9
            )));
        }
        let n = count as usize;
        let hi = [0, 1, 2].map(|a| lo[a] + dims[a] as f64 * spacing);
        let mut w = Self {
            origin: lo.map(|v| v + spacing / 2.0),
            h: spacing,
            dims,
            flags: filled(n, INSIDE, "point flags")?,
            surfel_of: filled(n, NO_SURFEL, "surfel slots")?,
            surfels: Vec::new(),
            owners: Vec::new(),
            material: count,
            bits: {
                let mut b = filled(n.div_ceil(8), 0xFFu8, "occupancy bits")?;
                if !n.is_multiple_of(8) {
                    if let Some(last) = b.last_mut() {
                        *last = (1u8 << (n % 8)) - 1;
                    }
                }
                b
            },
            cloud: Vec::new(),
            lo,
            hi,
            removed: Vec::new(),
            spans: Vec::new(),
            changed: filled(n.div_ceil(64), 0u64, "changed-surfel bits")?,
            changed_hi: 0,
            bits_changed: filled(n.div_ceil(8).div_ceil(64), 0u64, "changed-occupancy bits")?,
        };
        // Room for every surfel the workpiece can have (one per point) and for a substep
        // removing every point: cutting never grows a vector, so neither a pose's update
        // (growing a million surfels would copy them) nor the run's memory depends on
        // what is cut. Pages not written are never touched.
        reserve(&mut w.surfels, n, "surfels")?;
        reserve(&mut w.owners, n, "surfel owners")?;
        reserve(&mut w.cloud, n * SURFEL_BYTES, "surfel bytes")?;
        reserve(&mut w.removed, n, "removed-point scratch")?;
        // The six faces: BOUND points with the block's normals, surfels on the true faces.
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let c = [i, j, k];
                    let mut nrm = [0.0; 3];
                    for a in 0..3 {
                        if c[a] == 0 {
                            nrm[a] -= 1.0;
                        }
                        if c[a] + 1 == dims[a] {
                            nrm[a] += 1.0;
                        }
                    }
                    if nrm == [0.0; 3] {
                        continue;
                    }
                    let idx = w.index(i, j, k);
                    let pos = add(w.point(i, j, k), scale(nrm, spacing / 2.0));
                    let len = (nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]).sqrt();
                    w.flags[idx] = BOUND;
                    w.set_surfel(idx, pos, scale(nrm, 1.0 / len), COLOUR_BLOCK);
                }
            }
        }
        Ok(w)
    }

    /// Grid spacing (m).
    pub fn spacing(&self) -> f64 {
        self.h
    }

    /// Points along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Position of point `(0, 0, 0)` (m).
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// The block the workpiece started as: `(lo, hi)` (m).
    pub fn block_bounds(&self) -> (Vec3, Vec3) {
        (self.lo, self.hi)
    }

    /// Flat index of point `(i, j, k)` (x fastest).
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// Position of point `(i, j, k)` (m).
    pub fn point(&self, i: usize, j: usize, k: usize) -> Vec3 {
        [
            self.origin[0] + i as f64 * self.h,
            self.origin[1] + j as f64 * self.h,
            self.origin[2] + k as f64 * self.h,
        ]
    }

    /// The grid 6-neighbours of point `idx` that exist (none off the grid's faces), and
    /// how many there are.
    pub(crate) fn neighbours6(&self, idx: usize) -> ([usize; 6], usize) {
        let c = self.coords(idx);
        let stride = [1, self.dims[0], self.dims[0] * self.dims[1]];
        let (mut out, mut n) = ([0usize; 6], 0);
        for a in 0..3 {
            if c[a] > 0 {
                out[n] = idx - stride[a];
                n += 1;
            }
            if c[a] + 1 < self.dims[a] {
                out[n] = idx + stride[a];
                n += 1;
            }
        }
        (out, n)
    }

    /// Grid coordinates of a flat index.
    pub fn coords(&self, idx: usize) -> [usize; 3] {
        let i = idx % self.dims[0];
        let r = idx / self.dims[0];
        [i, r % self.dims[1], r / self.dims[1]]
    }

    /// The flag of point `idx`.
    pub fn flag(&self, idx: usize) -> Flag {
        match self.flags[idx] {
            OUTSIDE => Flag::Outside,
            BOUND => Flag::Bound,
            _ => Flag::Inside,
        }
    }

    /// Material points left (BOUND or INSIDE).
    pub fn material_points(&self) -> u64 {
        self.material
    }

    /// Material volume left: material points x spacing^3 (m^3).
    pub fn material_volume(&self) -> f64 {
        self.material as f64 * self.h.powi(3)
    }

    /// The surfels (one per BOUND point, in no particular order).
    pub fn surfels(&self) -> &[Surfel] {
        &self.surfels
    }

    /// Radius given to surfels: half the diagonal of a grid cell, so that the discs of a
    /// plane sampled by the grid at any orientation overlap.
    pub fn surfel_radius(&self) -> f64 {
        self.h * 3f64.sqrt() / 2.0
    }

    /// Occupancy, one bit per point (LSB first, x fastest): 1 = material. The layout of a
    /// `VoxelGrid` with `ENCODING_BITS` whose voxels are centred on the points. Kept up to
    /// date by every cut, so this is a copy, not a scan.
    pub fn occupancy_bits(&self) -> &[u8] {
        &self.bits
    }

    /// The surfels as the data of a `sensor_msgs/PointCloud2` with fields x, y, z,
    /// normal_x, normal_y, normal_z, radius (float32) and rgb (uint32), little-endian,
    /// [`SURFEL_BYTES`] per surfel, in [`Workpiece::surfels`] order. Kept up to date by every
    /// cut.
    pub fn surfel_bytes(&self) -> &[u8] {
        &self.cloud
    }

    /// Puts (or moves) the surfel of point `idx`.
    pub(crate) fn set_surfel(&mut self, idx: usize, pos: Vec3, normal: Vec3, colour: u32) {
        let s = Surfel {
            position: pos.map(|v| v as f32),
            normal: normal.map(|v| v as f32),
            radius: self.surfel_radius() as f32,
            colour,
        };
        let slot = self.surfel_of[idx];
        let bytes = s.to_bytes();
        self.mark_changed(if slot == NO_SURFEL {
            self.surfels.len()
        } else {
            slot as usize
        });
        if slot == NO_SURFEL {
            self.surfel_of[idx] = self.surfels.len() as u32;
            self.surfels.push(s);
            self.owners.push(idx as u32);
            self.cloud.extend_from_slice(&bytes);
        } else {
            let at = slot as usize * SURFEL_BYTES;
            self.surfels[slot as usize] = s;
            self.cloud[at..at + SURFEL_BYTES].copy_from_slice(&bytes);
        }
    }

    /// Removes point `idx` (material → OUTSIDE) and its surfel; returns the surfel's normal
    /// if it had one.
    pub(crate) fn remove_point(&mut self, idx: usize) -> Option<[f32; 3]> {
        debug_assert!(self.flags[idx] != OUTSIDE);
        self.flags[idx] = OUTSIDE;
        self.bits[idx / 8] &= !(1u8 << (idx % 8));
        if let Some(w) = self.bits_changed.get_mut(idx / 8 / 64) {
            *w |= 1 << ((idx / 8) % 64);
        }
        self.material -= 1;
        let slot = self.surfel_of[idx];
        if slot == NO_SURFEL {
            return None;
        }
        self.surfel_of[idx] = NO_SURFEL;
        let normal = self.surfels[slot as usize].normal;
        self.surfels.swap_remove(slot as usize);
        self.owners.swap_remove(slot as usize);
        let (at, end) = (
            slot as usize * SURFEL_BYTES,
            self.cloud.len() - SURFEL_BYTES,
        );
        if at != end {
            self.cloud.copy_within(end.., at);
        }
        self.cloud.truncate(end);
        if (slot as usize) < self.surfels.len() {
            let moved = self.owners[slot as usize];
            self.surfel_of[moved as usize] = slot;
            self.mark_changed(slot as usize);
        }
        Some(normal)
    }

    fn mark_changed(&mut self, slot: usize) {
        if let Some(w) = self.changed.get_mut(slot / 64) {
            *w |= 1 << (slot % 64);
            self.changed_hi = self.changed_hi.max(slot / 64 + 1);
        }
    }

    /// The surfel slots written or moved since the last call, with their bytes, and the
    /// cloud's length: what a copy of [`Workpiece::surfel_bytes`] needs to catch up. Costs
    /// a scan of one bit per surfel and a copy of the changed ones.
    pub fn take_surfel_delta(&mut self) -> SurfelDelta {
        let len = self.surfels.len();
        let words = len.div_ceil(64).min(self.changed.len());
        let count: usize = self.changed[..words]
            .iter()
            .map(|w| w.count_ones() as usize)
            .sum();
        let mut writes = Vec::with_capacity(count);
        for (wi, w) in self.changed[..words].iter_mut().enumerate() {
            let mut bits = std::mem::take(w);
            while bits != 0 {
                let slot = wi * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                if slot < len {
                    let at = slot * SURFEL_BYTES;
                    let mut b = [0u8; SURFEL_BYTES];
                    b.copy_from_slice(&self.cloud[at..at + SURFEL_BYTES]);
                    writes.push((slot as u32, b));
                }
            }
        }
        // Bits of slots past the end (surfels removed since) carry nothing.
        let hi = self.changed_hi.min(self.changed.len());
        if hi > words {
            self.changed[words..hi].fill(0);
        }
        self.changed_hi = 0;
        let mut bits = Vec::new();
        for (wi, w) in self.bits_changed.iter_mut().enumerate() {
            let mut set = std::mem::take(w);
            while set != 0 {
                let byte = wi * 64 + set.trailing_zeros() as usize;
                set &= set - 1;
                if let Some(&v) = self.bits.get(byte) {
                    bits.push((byte as u32, v));
                }
            }
        }
        SurfelDelta { len, writes, bits }
    }

    /// Removes material point `idx` by a cut: counted in `stats` (with its surfel's normal
    /// for eq. 8) and remembered in `removed`, whose neighbours the cut then exposes.
    pub(crate) fn cut_point(&mut self, idx: usize, stats: &mut super::CutStats) {
        if let Some(n) = self.remove_point(idx) {
            stats.removed_surface += 1;
            for a in 0..3 {
                stats.normal_sum[a] += f64::from(n[a]);
            }
        }
        stats.removed += 1;
        self.removed.push(idx as u32);
    }

    /// The surfel of point `idx`, if it has one.
    pub fn surfel_at(&self, idx: usize) -> Option<&Surfel> {
        let s = self.surfel_of[idx];
        (s != NO_SURFEL).then(|| &self.surfels[s as usize])
    }

    /// Is `idx` material with a 6-neighbour that is air or off the grid?
    pub fn on_surface(&self, idx: usize) -> bool {
        if self.flags[idx] == OUTSIDE {
            return false;
        }
        let c = self.coords(idx);
        for a in 0..3 {
            if c[a] == 0 || c[a] + 1 == self.dims[a] {
                return true;
            }
        }
        let stride = [1, self.dims[0], self.dims[0] * self.dims[1]];
        stride
            .iter()
            .any(|&s| self.flags[idx - s] == OUTSIDE || self.flags[idx + s] == OUTSIDE)
    }

    /// Checks the invariants (for tests): a point is BOUND iff it is material on the surface;
    /// BOUND points and only they have a surfel; the material count is right.
    ///
    /// # Errors
    /// The first violation ([`InvariantError`]).
    pub fn validate(&self) -> Result<(), InvariantError> {
        let mut material = 0u64;
        for idx in 0..self.flags.len() {
            let f = self.flags[idx];
            if f != OUTSIDE {
                material += 1;
            }
            let want = if f == OUTSIDE {
                OUTSIDE
            } else if self.on_surface(idx) {
                BOUND
            } else {
                INSIDE
            };
            if f != want {
                return Err(InvariantError::Flag {
                    point: self.coords(idx),
                    flag: f,
                    want,
                });
            }
            let has = self.surfel_of[idx] != NO_SURFEL;
            if has != (f == BOUND) {
                return Err(InvariantError::Surfel {
                    point: self.coords(idx),
                    flag: f,
                    has,
                });
            }
            if has && self.owners[self.surfel_of[idx] as usize] as usize != idx {
                return Err(InvariantError::Owner {
                    point: self.coords(idx),
                });
            }
        }
        if material != self.material {
            return Err(InvariantError::MaterialCount {
                kept: self.material,
                counted: material,
            });
        }
        if self.surfels.len() != self.owners.len() {
            return Err(InvariantError::Owners);
        }
        for (idx, &f) in self.flags.iter().enumerate() {
            if (self.bits[idx / 8] >> (idx % 8) & 1 == 1) != (f != OUTSIDE) {
                return Err(InvariantError::StaleBit {
                    point: self.coords(idx),
                });
            }
        }
        let fresh: Vec<u8> = self.surfels.iter().flat_map(Surfel::to_bytes).collect();
        if fresh != self.cloud {
            return Err(InvariantError::StaleCloud);
        }
        Ok(())
    }
}
