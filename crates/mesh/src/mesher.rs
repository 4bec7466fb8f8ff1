//! The rolling mesher: fed one frame at a time, it emits each slab as soon as its second
//! frame arrives and keeps only the frames it needs (the previous one, and the first one
//! for the closing cap), so memory does not grow with the sequence (the marching paper's
//! §5: docs/methods/marching.md#slab-by-slab).

use super::grid::{DecodeOptions, Encoding, FrameRef, GridGeometry, OccupancyGrid};
use super::march::{march_cap, CapSide, SlabMarcher, SlabPlacement, TetMesh};
use super::table::{table, Table};
use super::unsure::Unsure;
use super::MeshError;

/// Options of the mesher.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MesherOptions {
    /// How frames are decoded and checked.
    pub decode: DecodeOptions,
    /// Lattice steps per voxel edge for percent frames (a power of two, 2..=256): the
    /// interpolated surface position is snapped to 1/scale of an edge. (Larger scales would
    /// let the exact slice orientation test overflow i128.)
    pub percent_scale: i32,
    /// Most tets one slab (or one cap) may have; a frame whose slab would exceed it is
    /// refused ([`MeshError::SlabTooComplex`]) so that memory stays bounded.
    pub max_slab_tets: usize,
    /// Most tets all the filled frames of one gap may hold together (see
    /// [`super::stream`]); a gap that would need more is spanned by one slab.
    pub max_fill_tets: usize,
}

impl Default for MesherOptions {
    fn default() -> Self {
        Self {
            decode: DecodeOptions::default(),
            percent_scale: 64,
            max_slab_tets: 1 << 24,
            max_fill_tets: 1 << 25,
        }
    }
}

/// The lateral boundary of one slab [frame k, frame k+1].
#[derive(Debug, Clone, PartialEq)]
pub struct Slab {
    /// k: index of the slab's first frame among the accepted frames.
    pub index: u64,
    /// Stamp of frame k (ns).
    pub stamp_lo_ns: i64,
    /// Stamp of frame k+1 (ns).
    pub stamp_hi_ns: i64,
    /// The lattice.
    pub geometry: GridGeometry,
    /// Lateral tets; vertex t ranges over [scale·k, scale·(k+1)].
    pub mesh: TetMesh,
    /// Why the slab does not show every contact, if it does not: a part of the body
    /// vanishes between the frames ([`super::vanish`]: it moved more than its own
    /// thickness in one frame period, the frame rate is too low for it), or the frames were
    /// filled into a gap or the slab bridges one ([`super::stream`]).
    pub unsure: Option<Unsure>,
    /// How far the body moves between the slab's frames, in voxels (the frames' Hausdorff
    /// distance on the grid's axes, at most [`super::vanish::MAX_DISPLACEMENT`]; 1 when every
    /// voxel has one of the other frame next to it). Above 2 what the body passes between
    /// frames lies more than a voxel from both, which the slab does not hold, and the checker
    /// calls a pair near it unsure ([`Unsure::MovesFast`]).
    pub displacement: u16,
}

impl Slab {
    /// A part of the body vanishes between the slab's frames.
    pub fn vanishes(&self) -> bool {
        matches!(self.unsure, Some(Unsure::Vanishes { .. }))
    }

    /// Lattice time of the first frame.
    pub fn t_lo(&self) -> i32 {
        self.geometry.scale * self.index as i32
    }
    /// Lattice time of the second frame.
    pub fn t_hi(&self) -> i32 {
        self.geometry.scale * (self.index as i32 + 1)
    }
}

/// A frame the mesher has accepted, kept for the next slab.
#[derive(Debug, Clone)]
pub struct KeptFrame {
    /// Index among accepted frames.
    pub index: u64,
    /// Stamp (ns).
    pub stamp_ns: i64,
    /// Decoded occupancy.
    pub grid: OccupancyGrid,
}

/// A frame decoded and checked by [`Mesher::prepare`], ready for [`Mesher::push_prepared`].
#[derive(Debug, Clone)]
pub struct PreparedFrame {
    /// Stamp (ns).
    pub stamp_ns: i64,
    /// Its lattice.
    pub geometry: GridGeometry,
    /// Decoded occupancy.
    pub grid: OccupancyGrid,
}

/// What [`Mesher::restore`] puts back.
#[derive(Debug, Clone)]
pub struct MesherSnapshot {
    geometry: Option<GridGeometry>,
    first: Option<KeptFrame>,
    prev: Option<KeptFrame>,
    accepted: u64,
    skipped: u64,
}

/// The slab from `prev` to `grid` (at `stamp_ns`), marched.
fn march(
    marcher: &mut SlabMarcher,
    table: &'static Table,
    opts: &MesherOptions,
    prev: &KeptFrame,
    grid: &OccupancyGrid,
    geometry: GridGeometry,
    stamp_ns: i64,
) -> Result<Slab, MeshError> {
    let mut mesh = TetMesh::default();
    let at = SlabPlacement {
        scale: geometry.scale,
        frame: prev.index as i64,
        iso: opts.decode.iso_percent,
    };
    let limit = opts.max_slab_tets;
    // How the body moved does not depend on the slab's tets: measured beside the marching.
    let (marched, motion) = rayon::join(
        || marcher.march(table, &prev.grid, grid, at, limit, &mut mesh),
        || super::vanish::motion(&prev.grid, grid),
    );
    if !marched {
        return Err(MeshError::SlabTooComplex { limit });
    }
    let unsure = motion.vanishing.map(|v| Unsure::Vanishes {
        rate_factor: v.rate_factor,
    });
    Ok(Slab {
        index: prev.index,
        stamp_lo_ns: prev.stamp_ns,
        stamp_hi_ns: stamp_ns,
        geometry,
        mesh,
        unsure,
        displacement: motion.displacement,
    })
}

/// Whether two decoded frames hold the same occupancy.
fn same_grid(a: &OccupancyGrid, b: &OccupancyGrid) -> bool {
    a.padded == b.padded && a.bits == b.bits && a.values == b.values
}

/// Rolling 4D mesher of one body.
#[derive(Debug)]
pub struct Mesher {
    opts: MesherOptions,
    table: &'static Table,
    marcher: SlabMarcher,
    geometry: Option<GridGeometry>,
    first: Option<KeptFrame>,
    prev: Option<KeptFrame>,
    accepted: u64,
    skipped: u64,
    /// The slab between the last two accepted frames while they are equal (the body at
    /// rest): the next slab between two copies of that frame is this one moved in time,
    /// not marched again (marching is the same at every index but for the lattice time).
    rest: Option<Slab>,
}

impl Mesher {
    /// A mesher with the given options.
    ///
    /// # Errors
    /// [`MeshError::BadOption`] if `percent_scale` is not a power of two in 2..=256.
    pub fn new(opts: MesherOptions) -> Result<Self, MeshError> {
        let s = opts.percent_scale;
        if !(2..=256).contains(&s) || s.count_ones() != 1 {
            return Err(MeshError::BadOption {
                name: "percent_scale",
                reason: format!("{s} is not a power of two in 2..=256"),
            });
        }
        if opts.decode.iso_percent == 0 || opts.decode.iso_percent > 100 {
            return Err(MeshError::BadOption {
                name: "iso_percent",
                reason: format!("{} is not in 1..=100", opts.decode.iso_percent),
            });
        }
        Ok(Self {
            opts,
            table: table(),
            marcher: SlabMarcher::default(),
            geometry: None,
            first: None,
            prev: None,
            accepted: 0,
            skipped: 0,
            rest: None,
        })
    }

    /// Feeds one frame. Returns the slab it completes, if any.
    ///
    /// # Errors
    /// A [`MeshError`] saying why the frame was refused; the frame is then skipped (counted
    /// in [`Self::skipped`]) and the mesher's state is unchanged, so the stream goes on.
    pub fn push(&mut self, f: &FrameRef<'_>) -> Result<Option<Slab>, MeshError> {
        let r = self.try_push(f);
        if r.is_err() {
            self.skipped += 1;
        }
        r
    }

    fn try_push(&mut self, f: &FrameRef<'_>) -> Result<Option<Slab>, MeshError> {
        let p = self.prepare(f)?;
        self.accept(p.stamp_ns, p.geometry, p.grid)
    }

    /// Decodes `f` and runs every check [`Self::push`] would (fields, lattice, stamp order,
    /// frame count) without changing any state: a frame this refuses, `push` refuses too. Only
    /// marching ([`MeshError::SlabTooComplex`]) is left for [`Self::push_prepared`].
    ///
    /// # Errors
    /// Why the frame would be refused.
    pub fn prepare(&self, f: &FrameRef<'_>) -> Result<PreparedFrame, MeshError> {
        let scale = if f.encoding == Encoding::Percent.code() {
            self.opts.percent_scale
        } else {
            2
        };
        let geometry = GridGeometry {
            origin: f.origin,
            resolution: f.resolution,
            size: f.size,
            encoding: f.encoding,
            scale,
        };
        // Lattice coordinates scale·(index + 1) must fit in i32.
        // (Frames over the voxel limit are refused by the decoder with that reason.)
        let max_axis = (i32::MAX / scale - 2) as u32;
        let voxels = f
            .size
            .iter()
            .try_fold(1u64, |n, &v| n.checked_mul(u64::from(v)));
        let within_limit = voxels.is_some_and(|n| n <= self.opts.decode.max_voxels);
        if within_limit && f.size.iter().any(|&v| v > max_axis) {
            return Err(MeshError::LatticeOverflow {
                size: f.size,
                scale,
                max: max_axis,
            });
        }
        // Field checks first (they refuse oversized frames before allocating), then the
        // stream checks.
        let grid = OccupancyGrid::decode(f, &self.opts.decode)?;
        self.check_stream(f.stamp_ns, &geometry)?;
        Ok(PreparedFrame {
            stamp_ns: f.stamp_ns,
            geometry,
            grid,
        })
    }

    /// Feeds a frame [`Self::prepare`] accepted. Returns the slab it completes, if any.
    ///
    /// # Errors
    /// [`MeshError::SlabTooComplex`] (or a stream check, if other frames came in between);
    /// the frame is then skipped and counted, the state unchanged.
    pub fn push_prepared(&mut self, p: PreparedFrame) -> Result<Option<Slab>, MeshError> {
        self.push_decoded(p.stamp_ns, p.geometry, p.grid)
    }

    /// The stream checks of a frame at `stamp_ns` on `geometry`: same lattice as the earlier
    /// frames, stamp after the last one, room for one more frame.
    fn check_stream(&self, stamp_ns: i64, geometry: &GridGeometry) -> Result<(), MeshError> {
        if let Some(g) = &self.geometry {
            if g != geometry {
                return Err(MeshError::LatticeMismatch {
                    expected: Box::new(*g),
                    got: Box::new(*geometry),
                });
            }
        }
        if let Some(p) = &self.prev {
            if stamp_ns <= p.stamp_ns {
                return Err(MeshError::StampNotIncreasing {
                    previous_ns: p.stamp_ns,
                    got_ns: stamp_ns,
                });
            }
        }
        let limit = (i32::MAX / geometry.scale) as u64 - 1;
        if self.accepted >= limit {
            return Err(MeshError::TooManyFrames { limit });
        }
        Ok(())
    }

    /// The state a failed sequence of pushes can be rolled back to (see [`Self::restore`]).
    /// Costs a copy of the last frame.
    pub fn snapshot(&self) -> MesherSnapshot {
        MesherSnapshot {
            geometry: self.geometry,
            first: self.first.clone(),
            prev: self.prev.clone(),
            accepted: self.accepted,
            skipped: self.skipped,
        }
    }

    /// Puts the mesher back to `s`, as if nothing had been pushed since [`Self::snapshot`].
    pub fn restore(&mut self, s: MesherSnapshot) {
        self.geometry = s.geometry;
        self.first = s.first;
        self.prev = s.prev;
        self.accepted = s.accepted;
        self.skipped = s.skipped;
        self.rest = None;
    }

    /// Feeds an already decoded frame (e.g. the intersection of two bodies' frames).
    ///
    /// # Errors
    /// As [`Self::push`] for the stream checks (lattice, stamp order, frame count); the
    /// frame is then skipped and counted.
    pub fn push_decoded(
        &mut self,
        stamp_ns: i64,
        geometry: GridGeometry,
        grid: OccupancyGrid,
    ) -> Result<Option<Slab>, MeshError> {
        let r = self.accept(stamp_ns, geometry, grid);
        if r.is_err() {
            self.skipped += 1;
        }
        r
    }

    fn accept(
        &mut self,
        stamp_ns: i64,
        geometry: GridGeometry,
        grid: OccupancyGrid,
    ) -> Result<Option<Slab>, MeshError> {
        let scale = geometry.scale;
        self.check_stream(stamp_ns, &geometry)?;
        if grid.padded != geometry.size.map(|v| v as usize + 2) {
            return Err(MeshError::LatticeMismatch {
                expected: Box::new(geometry),
                got: Box::new(geometry),
            });
        }
        // March before touching any state, so a refused frame changes nothing.
        let at_rest = self
            .prev
            .as_ref()
            .is_some_and(|prev| same_grid(&prev.grid, &grid));
        // At rest with a rest slab kept: that slab moved in time.
        let moved = self
            .prev
            .as_ref()
            .filter(|_| at_rest)
            .zip(self.rest.as_ref())
            .and_then(|(prev, rest)| {
                let steps = i64::from(scale) * (prev.index as i64 - rest.index as i64);
                let shift = i32::try_from(steps).ok()?;
                if rest.geometry != geometry || steps <= 0 {
                    return None;
                }
                let mut mesh = rest.mesh.clone();
                mesh.translate([0, 0, 0, shift]);
                Some(Slab {
                    index: prev.index,
                    stamp_lo_ns: prev.stamp_ns,
                    stamp_hi_ns: stamp_ns,
                    geometry,
                    mesh,
                    unsure: rest.unsure,
                    displacement: rest.displacement,
                })
            });
        let slab = match (&self.prev, moved) {
            (None, _) => None,
            (Some(_), Some(slab)) => Some(slab),
            (Some(prev), None) => Some(march(
                &mut self.marcher,
                self.table,
                &self.opts,
                prev,
                &grid,
                geometry,
                stamp_ns,
            )?),
        };
        // The first slab of a rest is kept, to be moved for the next ones.
        if !at_rest {
            self.rest = None;
        } else if self.rest.is_none() {
            self.rest = slab.clone();
        }
        self.keep(stamp_ns, geometry, grid);
        Ok(slab)
    }

    /// Keeps an accepted frame as the last one (and the first, if it is).
    fn keep(&mut self, stamp_ns: i64, geometry: GridGeometry, grid: OccupancyGrid) {
        self.geometry = Some(geometry);
        let kept = KeptFrame {
            index: self.accepted,
            stamp_ns,
            grid,
        };
        self.accepted += 1;
        if self.first.is_none() {
            self.first = Some(kept.clone());
        }
        self.prev = Some(kept);
    }

    /// The options.
    pub fn options(&self) -> &MesherOptions {
        &self.opts
    }

    /// Frames accepted so far.
    pub fn frames(&self) -> u64 {
        self.accepted
    }

    /// Frames refused so far.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// The lattice of the accepted frames.
    pub fn geometry(&self) -> Option<&GridGeometry> {
        self.geometry.as_ref()
    }

    /// The first accepted frame.
    pub fn first_frame(&self) -> Option<&KeptFrame> {
        self.first.as_ref()
    }

    /// The latest accepted frame.
    pub fn last_frame(&self) -> Option<&KeptFrame> {
        self.prev.as_ref()
    }

    /// The cap closing the mesh at a kept frame (`Low` for the first frame, `High` for the
    /// last), or `None` before any frame.
    pub fn cap(&self, frame: &KeptFrame, side: CapSide) -> Option<TetMesh> {
        let g = self.geometry?;
        let mut out = TetMesh::default();
        let at = SlabPlacement {
            scale: g.scale,
            frame: frame.index as i64,
            iso: self.opts.decode.iso_percent,
        };
        if !march_cap(
            self.table,
            &frame.grid,
            at,
            side,
            self.opts.max_slab_tets,
            &mut out,
        ) {
            tracing::warn!(
                "cap of frame {} exceeds {} tets: not built, the mesh stays open there",
                frame.index,
                self.opts.max_slab_tets
            );
            return None;
        }
        Some(out)
    }
}

/// Test streams: frame `k` of a `size` grid at 1 cm voxels from the origin, stamped k·0.1 s.
#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
pub fn test_frame(k: u32, size: [u32; 3], encoding: u8, data: &[u8]) -> FrameRef<'_> {
    FrameRef {
        stamp_ns: i64::from(k) * 100_000_000,
        origin: [0.0; 3],
        resolution: 0.01,
        size,
        encoding,
        data,
    }
}

/// The BITS data of a `size` grid whose voxel (x, y, z) is occupied where `occ` says.
#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
pub fn test_bits(size: [u32; 3], occ: impl Fn(i32, i32, i32) -> bool) -> Vec<u8> {
    let [sx, sy, sz] = size.map(|v| v as usize);
    let mut v = vec![0u8; (sx * sy * sz).div_ceil(8)];
    for i in 0..sx * sy * sz {
        let (x, y, z) = (i % sx, (i / sx) % sy, i / (sx * sy));
        if occ(x as i32, y as i32, z as i32) {
            v[i / 8] |= 1 << (i % 8);
        }
    }
    v
}

/// Frames 0..`n` of a `size` grid (frame k's voxel (x, y, z) occupied where `occ(k, x, y, z)`)
/// through a default mesher: the mesher and the slabs it gave.
#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
pub fn test_stream(
    size: [u32; 3],
    n: u32,
    occ: impl Fn(u32, i32, i32, i32) -> bool,
) -> (Mesher, Vec<Slab>) {
    let mut m = Mesher::new(MesherOptions::default()).expect("default options");
    let mut slabs = Vec::new();
    for k in 0..n {
        let data = test_bits(size, |x, y, z| occ(k, x, y, z));
        if let Some(s) = m
            .push(&test_frame(k, size, 0, &data))
            .expect("a valid frame")
        {
            slabs.push(s);
        }
    }
    (m, slabs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A body at rest, moving, at rest again (bit and percent frames, and an empty rest):
    /// every slab equals the one marched from its two frames, whether or not the mesher
    /// moved its rest slab instead; and it did move it where the body rested.
    #[test]
    fn slabs_of_a_body_at_rest_are_the_marched_ones() {
        let size = [9u32, 8, 7];
        // Frame k's ball centre along x; `None`: nothing occupied.
        let place = |k: u32| match k {
            0..=3 => Some(2),
            4 => Some(3),
            5..=7 => Some(4),
            8..=10 => None,
            _ => Some(4),
        };
        for encoding in [0u8, 1] {
            let frame = |k: u32| -> Vec<u8> {
                let r2 = |x: i32, y: i32, z: i32| {
                    place(k).map(|c| (x - c).pow(2) + (y - 4).pow(2) + (z - 3).pow(2))
                };
                if encoding == 0 {
                    test_bits(size, |x, y, z| r2(x, y, z).is_some_and(|r| r <= 5))
                } else {
                    let [sx, sy, sz] = size.map(|v| v as i32);
                    (0..sx * sy * sz)
                        .map(|i| {
                            let r = r2(i % sx, (i / sx) % sy, i / (sx * sy));
                            r.map_or(0, |r| (100 - 12 * r).clamp(0, 100) as u8)
                        })
                        .collect()
                }
            };
            let mut moved = Mesher::new(MesherOptions::default()).unwrap();
            let mut marched = Mesher::new(MesherOptions::default()).unwrap();
            let mut rests = 0;
            for k in 0..14u32 {
                let data = frame(k);
                let f = test_frame(k, size, encoding, &data);
                let had = moved.rest.is_some();
                marched.rest = None;
                let (a, b) = (moved.push(&f).unwrap(), marched.push(&f).unwrap());
                // A rest slab kept before and after: this one was moved from it.
                rests += usize::from(had && moved.rest.is_some());
                let key = |s: &Option<Slab>| {
                    s.as_ref().map(|s| {
                        (
                            s.index,
                            s.stamp_lo_ns,
                            s.stamp_hi_ns,
                            s.unsure,
                            s.mesh.clone(),
                        )
                    })
                };
                assert_eq!(key(&a), key(&b), "encoding {encoding}, frame {k}");
            }
            // Rest slabs moved: frames 2, 3 (rest from 0), 7 (from 5), 10 (empty, from 8),
            // 13 (from 11).
            assert_eq!(rests, 5, "encoding {encoding}");
        }
    }

    /// A frame of a ball-shaped field (centred `dx` voxels right of the middle) with noise
    /// of `amp` percent (`seed`), as percent values and as the bits of the voxels at or
    /// above 50.
    fn noisy_ball(size: [u32; 3], amp: i32, seed: u32, dx: i32) -> (Vec<u8>, Vec<u8>) {
        let [sx, sy, _] = size.map(|v| v as i32);
        let value = |i: u32| {
            let i = i as i32;
            let (x, y, z) = (i % sx, (i / sx) % sy, i / (sx * sy));
            let r = (x - sx / 2 - dx).pow(2) + (y - sy / 2).pow(2) + (z - 5).pow(2);
            let h = (i as u32)
                .wrapping_mul(0x9e37_79b9)
                .wrapping_add(seed.wrapping_mul(0x85eb_ca6b));
            let noise = if amp == 0 {
                0
            } else {
                ((h ^ (h >> 13)) % (2 * amp as u32)) as i32 - amp
            };
            (100 - 5 * r + noise).clamp(0, 100) as u8
        };
        let percent: Vec<u8> = (0..size.iter().product::<u32>()).map(value).collect();
        let bits = test_bits(size, |x, y, z| {
            percent[(x + sx * (y + sy * z)) as usize] >= 50
        });
        (percent, bits)
    }

    /// The signs of the time components of a frame's cap tets' normals: negative, zero,
    /// positive.
    fn cap_signs(data: &[u8], size: [u32; 3], encoding: u8) -> [usize; 3] {
        let mut m = Mesher::new(MesherOptions::default()).unwrap();
        m.push(&test_frame(0, size, encoding, data)).unwrap();
        let cap = m.cap(m.last_frame().unwrap(), CapSide::High).unwrap();
        let mut signs = [0usize; 3];
        for t in &cap.tets {
            let n = chronotope_kernel::float::tet_normal(&t.map(|v| cap.vertices[v as usize]));
            signs[usize::from(n[3] >= 0.0) + usize::from(n[3] > 0.0)] += 1;
        }
        signs
    }

    /// A BITS frame's cap fills its solid without folds: every tet has the same
    /// orientation in the frame's time plane, none flat (vertices at corners and edge
    /// midpoints are where the table's triangulation was made).
    #[test]
    fn bits_caps_never_fold() {
        let size = [12u32, 11, 10];
        for seed in 0..12 {
            let (_, bits) = noisy_ball(size, [0, 10, 20][seed as usize % 3], seed, 0);
            let signs = cap_signs(&bits, size, 0);
            assert!(
                signs[2] > 1000 && signs[..2] == [0, 0],
                "seed {seed}: {signs:?}"
            );
        }
    }

    /// How many PERCENT tets are turned over (a measurement, not a check;
    /// docs/methods/marching.md): the vertices moved along their edges by the interpolation
    /// keep the table's combinatorics, not always its geometry. Caps: the sign of each
    /// tet's time normal. Slabs of a moving ball: each tet against the same tet of the slab
    /// meshed from the same frames as BITS (the same tets, at edge midpoints).
    /// `cargo test -p chronotope-mesh --lib percent_folds -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn percent_folds_counted() {
        let size = [12u32, 11, 10];
        for amp in [0, 4, 10, 20] {
            let (mut tets, mut over, mut caps) = (0, 0, 0);
            for seed in 0..10 {
                let (percent, _) = noisy_ball(size, amp, seed, 0);
                let signs = cap_signs(&percent, size, 1);
                tets += signs.iter().sum::<usize>();
                over += signs[0];
                caps += usize::from(signs[0] > 0);
            }
            let (mut lateral, mut turned) = (0, 0);
            for seed in 0..10 {
                let (p0, b0) = noisy_ball(size, amp, 2 * seed, -1);
                let (p1, b1) = noisy_ball(size, amp, 2 * seed + 1, 0);
                let slab = |encoding: u8, f0: &[u8], f1: &[u8]| {
                    let mut m = Mesher::new(MesherOptions::default()).unwrap();
                    m.push(&test_frame(0, size, encoding, f0)).unwrap();
                    m.push(&test_frame(1, size, encoding, f1))
                        .unwrap()
                        .unwrap()
                        .mesh
                };
                let (p, b) = (slab(1, &p0, &p1), slab(0, &b0, &b1));
                assert_eq!(p.tets, b.tets, "the same tets");
                for t in &p.tets {
                    let normal = |m: &TetMesh| {
                        chronotope_kernel::float::tet_normal(&t.map(|v| m.vertices[v as usize]))
                    };
                    let (np, nb) = (normal(&p), normal(&b));
                    lateral += 1;
                    turned += usize::from((0..4).map(|k| np[k] * nb[k]).sum::<f64>() < 0.0);
                }
            }
            println!(
                "noise ±{amp} %: {over} of {tets} cap tets turned over, in {caps} caps of 10; \
                 {turned} of {lateral} lateral tets of 10 slabs"
            );
        }
    }
}
