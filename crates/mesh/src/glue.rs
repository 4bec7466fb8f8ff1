//! Whole-body 4D meshes: every slab of a stream welded into one closed mesh with its two
//! end caps, for consumers that need the body at once (the interference checker).

use super::grid::GridGeometry;
use super::march::{CapSide, SpatialBounds, TetMesh, Welder};
use super::mesher::{MesherOptions, Slab};
use super::stats::{BodyStats, LateralRef, StatsAccumulator};
use super::stream::{BodyStream, LossLog, LossSpan};
use super::unsure::{UnsureLog, UnsureSpan};
use super::{FrameRef, MeshError, OccupancyGrid};

/// One body's closed 4D mesh over all its frames.
#[derive(Debug, Clone, Default)]
pub struct BodyMesh {
    /// Closed, welded mesh: lateral tets of every slab plus the first and last caps.
    pub mesh: TetMesh,
    /// Where each piece (first cap, each slab, last cap) starts in `mesh.tets`, in the
    /// order they were welded.
    pub pieces: Vec<usize>,
    /// Stamps of the accepted frames (ns); frame n is at lattice time `scale · n`.
    pub stamps_ns: Vec<i64>,
    /// The lattice, once a frame was accepted.
    pub geometry: Option<GridGeometry>,
    /// Decoded frames, if kept (see [`BodyAssembler::keep_frames`]).
    pub frames: Vec<OccupancyGrid>,
    /// Frames refused by the mesher.
    pub skipped: u64,
    /// What the stream lost (refused frames, filled and spanned gaps).
    pub losses: LossLog,
    /// Streaming statistics (closedness, hypervolume in m³·s, counts).
    pub stats: BodyStats,
    /// Where the body is not observed well enough for every contact to show
    /// ([`super::unsure`]).
    pub unsure: UnsureLog,
    /// Each lateral slab's stamps, motion and box, in order: where a pair with the body is
    /// unsure for want of frames ([`super::unsure::Unsure::MovesFast`]).
    pub motions: Vec<SlabMotion>,
}

/// How a body moves in one slab, and where the slab lies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlabMotion {
    /// Stamps of the slab's frames (ns).
    pub stamps_ns: (i64, i64),
    /// How far the body moves between them (voxels; see [`Slab::displacement`]).
    pub displacement: u16,
    /// The box of the slab's vertices on the body's lattice, if it has any.
    pub bounds: Option<SpatialBounds>,
    /// The slab's own doubt, if it has one ([`Slab::unsure`]): it outweighs a fast motion.
    pub unsure: Option<super::unsure::Unsure>,
}

/// Welds the pieces of one body's mesh, as the mesher makes them (the first cap, the lateral
/// slabs in order, the last cap), into a [`BodyMesh`], with its statistics. Used by
/// [`BodyAssembler`] and by consumers that receive the pieces as messages.
#[derive(Debug, Default)]
pub struct BodyGluer {
    body: BodyMesh,
    welder: Welder,
    acc: StatsAccumulator,
    first_cap: Option<(TetMesh, u64)>,
    last_cap: Option<(TetMesh, u64)>,
}

impl BodyGluer {
    /// An empty body.
    pub fn new() -> Self {
        Self::default()
    }

    /// The cap closing the body at its first frame (with that frame's occupied voxel count).
    /// Must come before the first lateral slab.
    pub fn first_cap(&mut self, cap: &TetMesh, occupied: u64) {
        self.body.pieces.push(self.body.mesh.tets.len());
        self.welder.append(&mut self.body.mesh, cap);
        self.first_cap = Some((cap.clone(), occupied));
    }

    /// The next lateral slab, and the time it took to mesh (ms), if known.
    pub fn lateral(&mut self, slab: LateralRef<'_>, meshing_ms: Option<f64>) {
        if let Some(ms) = meshing_ms {
            self.acc.record_time(ms);
        }
        if let Some(why) = slab.unsure {
            self.body.unsure.push(UnsureSpan {
                from_ns: slab.stamps_ns.0,
                to_ns: slab.stamps_ns.1,
                why,
                period_ns: slab.stamps_ns.1 - slab.stamps_ns.0,
            });
        }
        self.body.motions.push(SlabMotion {
            stamps_ns: slab.stamps_ns,
            displacement: slab.displacement,
            bounds: slab.mesh.spatial_bounds(),
            unsure: slab.unsure,
        });
        self.acc
            .add_lateral(slab, self.first_cap.as_ref().map(|c| &c.0));
        self.body.pieces.push(self.body.mesh.tets.len());
        self.welder.append(&mut self.body.mesh, slab.mesh);
    }

    /// The cap closing the body at its last frame.
    pub fn last_cap(&mut self, cap: &TetMesh, occupied: u64) {
        self.body.pieces.push(self.body.mesh.tets.len());
        self.welder.append(&mut self.body.mesh, cap);
        self.last_cap = Some((cap.clone(), occupied));
    }

    /// Tets welded so far.
    pub fn tets(&self) -> usize {
        self.body.mesh.tets.len()
    }

    /// The mesh welded so far (each call above appends one piece's tets).
    pub fn mesh(&self) -> &TetMesh {
        &self.body.mesh
    }

    /// The body, with `frames` accepted frames at `stamps_ns` on `geometry`.
    pub fn finish(
        mut self,
        frames: u64,
        stamps_ns: Vec<i64>,
        geometry: Option<GridGeometry>,
    ) -> BodyMesh {
        self.body.stats = self.acc.finish(
            frames,
            self.first_cap
                .as_ref()
                .map(|(c, o)| (c.tets.len() as u64, *o)),
            self.last_cap.as_ref().map(|(c, o)| (c, *o)),
        );
        self.body.stamps_ns = stamps_ns;
        self.body.geometry = geometry;
        self.body
    }
}

/// What [`BodyAssembler::push`] did besides accepting the frame.
#[derive(Debug, Clone, Default)]
pub struct Pushed {
    /// The gap before the frame, filled or spanned, if there was one.
    pub gap: Option<LossSpan>,
    /// PERCENT voxels of the frame outside the domain, read as 100.
    pub clamped: u64,
}

/// Builds a [`BodyMesh`] from a stream of frames, with the stream rules of
/// [`BodyStream`] (refused frames change nothing; gaps between accepted frames filled).
#[derive(Debug)]
pub struct BodyAssembler {
    stream: BodyStream,
    gluer: BodyGluer,
    stamps_ns: Vec<i64>,
    frames: Vec<OccupancyGrid>,
    keep_frames: bool,
}

impl BodyAssembler {
    /// A new assembler.
    ///
    /// # Errors
    /// Bad mesher options.
    pub fn new(opts: MesherOptions) -> Result<Self, MeshError> {
        Ok(Self {
            stream: BodyStream::new(opts)?,
            gluer: BodyGluer::new(),
            stamps_ns: Vec::new(),
            frames: Vec::new(),
            keep_frames: false,
        })
    }

    /// Also keep every decoded frame (for measures computed from occupancy).
    pub fn keep_frames(mut self, keep: bool) -> Self {
        self.keep_frames = keep;
        self
    }

    /// Feeds one frame (and the frames filling a gap before it, if any).
    ///
    /// # Errors
    /// Why the frame was refused; it is skipped and counted, nothing else changes.
    pub fn push(&mut self, f: &FrameRef<'_>) -> Result<Pushed, MeshError> {
        let accepted = self.stream.push(f)?;
        let n = accepted.frames.len();
        for (i, (stamp_ns, slab)) in accepted.frames.into_iter().enumerate() {
            let grid = if i + 1 < n {
                accepted.fill.clone()
            } else {
                None
            };
            self.after_accept(stamp_ns, slab, grid);
        }
        Ok(Pushed {
            gap: accepted.gap,
            clamped: accepted.clamped,
        })
    }

    /// Feeds a derived frame (see [`BodyStream::push_derived`]): no gap filling.
    ///
    /// # Errors
    /// The mesher's reason for refusing the frame.
    pub fn push_derived(
        &mut self,
        stamp_ns: i64,
        geometry: GridGeometry,
        grid: OccupancyGrid,
    ) -> Result<(), MeshError> {
        let slab = self.stream.push_derived(stamp_ns, geometry, grid)?;
        self.after_accept(stamp_ns, slab, None);
        Ok(())
    }

    /// Records a frame refused before it reached the mesher (see [`BodyStream::refuse`]).
    pub fn refuse(&mut self, stamp_ns: Option<i64>, e: &MeshError) {
        self.stream.refuse(stamp_ns, e);
    }

    /// What the stream lost so far.
    pub fn losses(&self) -> &LossLog {
        self.stream.losses()
    }

    fn after_accept(&mut self, stamp_ns: i64, slab: Option<Slab>, filled: Option<OccupancyGrid>) {
        self.stamps_ns.push(stamp_ns);
        let mesher = self.stream.mesher();
        if self.keep_frames {
            match filled {
                Some(g) => self.frames.push(g),
                None => {
                    if let Some(k) = mesher.last_frame() {
                        self.frames.push(k.grid.clone());
                    }
                }
            }
        }
        if let Some(slab) = slab {
            if slab.index == 0 {
                if let Some(k) = mesher.first_frame() {
                    if let Some(cap) = mesher.cap(k, CapSide::Low) {
                        self.gluer.first_cap(&cap, k.grid.occupied);
                    }
                }
            }
            self.gluer.lateral(slab.lateral_ref(), None);
        }
    }

    /// The mesh welded so far (grows by a piece with each slab).
    pub fn mesh(&self) -> &TetMesh {
        self.gluer.mesh()
    }

    /// Closes the mesh with the last frame's cap and returns the body. With fewer than two
    /// frames the mesh is empty (a body needs a time extent).
    pub fn finish(mut self) -> BodyMesh {
        let mesher = self.stream.mesher();
        if mesher.frames() >= 2 {
            if let Some(k) = mesher.last_frame() {
                if let Some(cap) = mesher.cap(k, CapSide::High) {
                    self.gluer.last_cap(&cap, k.grid.occupied);
                }
            }
        }
        let mut body =
            self.gluer
                .finish(mesher.frames(), self.stamps_ns, mesher.geometry().copied());
        body.frames = self.frames;
        body.skipped = self.stream.losses().refused_frames;
        body.losses = self.stream.losses().clone();
        body
    }
}

/// A body meshed from bit frames of a `size` grid at `origin` with 1 cm voxels, one frame
/// per stamp, voxel `p` of frame `k` occupied where `occupied(k, p)` (for tests).
#[cfg(any(test, feature = "test-support"))]
#[doc(hidden)]
pub fn test_body(
    size: [u32; 3],
    origin: [f64; 3],
    stamps_ns: &[i64],
    occupied: impl Fn(usize, [usize; 3]) -> bool,
) -> BodyMesh {
    let mut a = BodyAssembler::new(MesherOptions::default()).expect("options");
    let s = size.map(|s| s as usize);
    let n = s.iter().product::<usize>();
    for (k, &stamp_ns) in stamps_ns.iter().enumerate() {
        let mut data = vec![0u8; n.div_ceil(8)];
        for i in 0..n {
            if occupied(k, [i % s[0], (i / s[0]) % s[1], i / (s[0] * s[1])]) {
                data[i / 8] |= 1 << (i % 8);
            }
        }
        let f = FrameRef {
            stamp_ns,
            origin,
            resolution: 0.01,
            size,
            encoding: 0,
            data: &data,
        };
        a.push(&f).expect("a valid frame");
    }
    a.finish()
}
